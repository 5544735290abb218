//! The paths of [`super::identify()`] besides the FRF and free decay (split from
//! `identify.rs`): the tip response every path uses ([`tip_signal`], [`base_channel`]), the
//! output-only and pooled ring-down paths and how their results enter the
//! [`Identification`], and a magnitude-spectrum file (`.lvm`).

use super::identify_types::{
    rayleigh, IdentPath, Identification, IdentifyOptions, RejectedMode, Stage,
};
use super::ModeEstimate;
use crate::recording::{fmt_sig, Recording};
use anyhow::{bail, Result};

/// `Ok(why)` when the tip response of `rec` is a stationary response for the output-only
/// path ([`super::ssi::stationary_response`] in `opts.decay`'s band), else `Err(why not)`.
pub(crate) fn output_only_reason(
    rec: &Recording,
    opts: &IdentifyOptions,
) -> std::result::Result<String, String> {
    let (_, x) = response_signal(rec);
    super::ssi::stationary_response(
        &x,
        rec.sample_rate_hz(),
        opts.decay.f_min_hz,
        opts.decay.f_max_hz,
    )
}

/// The response of the output-only path: the tip deflection (tip − base, [`tip_signal`]) or
/// the tip alone, and its name. (A tip accelerometer channel goes here when recordings carry
/// one.)
pub(crate) fn response_signal(rec: &Recording) -> (&'static str, Vec<f64>) {
    let name = match (rec.tip_pos_m.is_some(), base_channel(rec).is_some()) {
        (true, true) => "tip deflection (tip_pos_m - base)",
        (true, false) => "tip_pos_m",
        (false, _) => "tip_acc_m_s2",
    };
    (name, tip_signal(rec, 0).1)
}

/// The output-only path: [`super::ssi::identify_output_only`] of the tip response, into `out`.
pub(crate) fn output_only_path(
    seg: &Recording,
    opts: &IdentifyOptions,
    out: &mut Identification,
    progress: &mut dyn FnMut(Stage),
) -> Result<()> {
    let (name, y) = response_signal(seg);
    if y.is_empty() {
        bail!("no tip channel (tip_pos_m or tip_acc_m_s2) to identify from");
    }
    progress(Stage::Estimating(out.path, y.len()));
    let so = super::ssi::SsiOptions {
        f_min_hz: opts.decay.f_min_hz,
        f_max_hz: opts.decay.f_max_hz,
        zeta_max: opts.frf.zeta_max,
        ..Default::default()
    };
    let r = super::ssi::identify_output_only(&y, seg.sample_rate_hz(), &so)?;
    out.reason = format!(
        "{}; response: {name}, decimated by {} to {} Hz (band top {} Hz), {} block rows, orders 2..{}, 1-σ from {} blocks",
        out.reason,
        r.decimation,
        fmt_sig(r.sample_rate_hz, 4),
        fmt_sig(r.band_top_hz, 3),
        r.block_rows,
        so.max_order,
        r.n_blocks
    );
    out.warnings.extend(r.warnings.iter().cloned());
    out.rejected = r
        .rejected
        .iter()
        .map(|j| RejectedMode {
            mode: ModeEstimate {
                freq_hz: j.freq_hz,
                zeta: j.zeta,
                freq_hz_std: f64::NAN,
                zeta_std: f64::NAN,
                method: "output-only SSI-cov".into(),
            },
            reason: j.reason.clone(),
        })
        .collect();
    out.modes = r.modes;
    Ok(())
}

/// The pooled ring-down path: [`super::ringdowns::identify_ringdowns`] of the base and the
/// tip deflection (tip − base), into `out`.
pub(crate) fn ringdowns_path(
    seg: &Recording,
    opts: &IdentifyOptions,
    out: &mut Identification,
    progress: &mut dyn FnMut(Stage),
) -> Result<()> {
    let b = base_channel(seg).ok_or_else(|| anyhow::anyhow!("no base channel"))?;
    let (_, y) = tip_signal(seg, 0);
    progress(Stage::Estimating(out.path, y.len()));
    let r = super::ringdowns::identify_ringdowns(
        b,
        &y,
        seg.sample_rate_hz(),
        opts.decay.f_min_hz,
        opts.decay.f_max_hz,
        opts.frf.zeta_max,
    )?;
    out.reason = format!(
        "{}; {} segments at {} Hz, the model explains {} % of the tip deflection's variance",
        out.reason,
        r.segments,
        fmt_sig(r.sample_rate_hz, 4),
        fmt_sig(100.0 * r.r2, 3)
    );
    out.modes = vec![r.mode];
    Ok(())
}

/// The base position channel: measured if present, else the command.
pub(crate) fn base_channel(rec: &Recording) -> Option<&[f64]> {
    rec.base_pos_m.as_deref().or(rec.base_cmd_m.as_deref())
}

/// The tip response of `rec` from sample `from`: (time s, signal). The tip deflection
/// (tip − base) when both channels exist, else the tip alone; a recording with a tip
/// accelerometer (`tip_acc_m_s2`) and no tip position gives that acceleration (its free decay
/// and its output-only response have the same natural frequencies and damping ratios).
pub(crate) fn tip_signal(rec: &Recording, from: usize) -> (Vec<f64>, Vec<f64>) {
    let t = rec.time_s[from..].to_vec();
    let x = match (
        rec.tip_pos_m.as_deref(),
        base_channel(rec),
        rec.tip_acc_m_s2.as_deref(),
    ) {
        (Some(tip), Some(b), _) => tip[from..]
            .iter()
            .zip(&b[from..])
            .map(|(t, b)| t - b)
            .collect(),
        (Some(tip), None, _) => tip[from..].to_vec(),
        (None, _, Some(acc)) => acc[from..].to_vec(),
        (None, _, None) => vec![],
    };
    (t, x)
}

/// Identifies the LabVIEW `.lvm` magnitude spectrum at `path` ([`super::magspec`]: at most 6
/// peaks >= 10 dB prominent in `opts.decay`'s band), as `identify_file` does for an `.lvm`.
///
/// Errors: the file cannot be read or parsed, no prominent peak in the band.
pub fn identify_spectrum_file(
    path: &std::path::Path,
    opts: &IdentifyOptions,
) -> Result<Identification> {
    let s = super::magspec::read_lvm(path)?;
    let mm = super::magspec::identify_magnitude_spectrum(
        &s,
        opts.decay.f_min_hz,
        opts.decay.f_max_hz,
        10.0,
        6,
    )?;
    let mut warnings = Vec::new();
    let modes: Vec<ModeEstimate> = mm
        .iter()
        .map(|m| {
            if m.resolution_limited {
                warnings.push(format!(
                    "{} Hz: damping resolution-limited (half-power band {} lines); ζ is an upper bound",
                    fmt_sig(m.freq_hz, 5),
                    fmt_sig(m.half_power_lines, 2)
                ));
            }
            ModeEstimate {
                freq_hz: m.freq_hz,
                zeta: m.zeta,
                freq_hz_std: m.freq_hz_std,
                zeta_std: m.zeta_std,
                method: "magnitude spectrum".into(),
            }
        })
        .collect();
    if modes.is_empty() {
        bail!(
            "{}: no peak ≥ 10 dB prominent in the spectrum",
            path.display()
        );
    }
    let df = s.freq_hz[1] - s.freq_hz[0];
    Ok(Identification {
        rayleigh: rayleigh(&modes, &mut warnings),
        modes,
        path: IdentPath::Spectrum,
        reason: format!(
            "a LabVIEW `.lvm` magnitude spectrum ({} lines, Δf = {} Hz): single-mode accelerance fits of its peaks",
            s.freq_hz.len(),
            fmt_sig(df, 3)
        ),
        rejected: vec![],
        warnings,
        span_s: (0.0, 1.0 / df),
        sample_rate_hz: f64::NAN,
        base: None,
        frf_result: None,
        decay_result: None,
    })
}
