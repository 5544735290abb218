//! The identification pipeline: recording → FRF → estimators (LSCF, LSCE, peak picking) with
//! stabilisation over model orders, plus free decays found automatically → combined modes with
//! uncertainty and Rayleigh coefficients (eq. 22).

use super::estimator::{frf_estimators, FrfContext};
use super::freedecay::{identify_free_decay, FreeDecayOptions};
use super::frf::{frf_of_recording, Frf, InputChannel};
pub use super::options::{IdentOptions, Method, MethodResult};
use super::{std_dev, ModeEstimate};
use crate::progress::{Progress, Silent};
use crate::recording::Recording;
use anyhow::{bail, Result};
use serde::Serialize;

/// Identification result.
#[derive(Clone, Debug, Serialize)]
pub struct IdentResult {
    /// Modes of the primary method, ascending in frequency. `freq_hz_std`, `zeta_std`: 1-σ,
    /// the primary method's own spread (over model orders or segments) combined in quadrature
    /// with the standard deviation of the estimates of the other methods that found the mode
    /// (within 3 % in frequency).
    pub modes: Vec<ModeEstimate>,
    /// Every method's own result.
    pub methods: Vec<MethodResult>,
    /// Rayleigh α1 (1/s), α2 (s) from the first two modes (eq. 22).
    pub rayleigh: Option<(f64, f64)>,
    /// Band used (Hz).
    pub band_hz: (f64, f64),
    /// FRF line spacing (Hz) and segments averaged.
    pub df_hz: f64,
    /// Welch averages.
    pub n_averages: usize,
    /// FRF input and output.
    pub input: String,
    /// FRF output.
    pub output: String,
    /// Warnings (clipping, resolution, …).
    pub warnings: Vec<String>,
}

/// Band where the smoothed input auto-spectrum is within 30 dB of its maximum, clipped to
/// [5 Δf, 0.4 fs].
pub fn auto_band(frf: &Frf) -> (f64, f64) {
    let n = frf.sxx.len();
    let w = (n / 200).max(1);
    let sm: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(w), (k + w + 1).min(n));
            frf.sxx[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    let top = sm.iter().skip(1).cloned().fold(0.0, f64::max);
    let ok: Vec<usize> = (1..n).filter(|&k| sm[k] >= 1e-3 * top).collect();
    let df = frf.df_hz();
    let lo = ok
        .first()
        .map_or(5.0 * df, |&k| frf.freq_hz[k])
        .max(5.0 * df);
    let hi = ok
        .last()
        .map_or(0.4 * frf.sample_rate_hz, |&k| frf.freq_hz[k])
        .min(0.4 * frf.sample_rate_hz);
    (lo, hi)
}

/// Free-decay segments of a recording: stretches of at least `min_s` seconds over which the
/// base (command if present, else measured position) does not move, that follow motion.
/// Returns sample ranges.
pub fn free_decay_segments(rec: &Recording, min_s: f64) -> Vec<std::ops::Range<usize>> {
    let Some(b) = rec.base_cmd_m.as_ref().or(rec.base_pos_m.as_ref()) else {
        return vec![];
    };
    let range = b.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
        - b.iter().fold(f64::INFINITY, |m, v| m.min(*v));
    let tol = (1e-9f64).max(1e-7 * range);
    let min_n = ((min_s * rec.sample_rate_hz()) as usize).max(64);
    let mut out = Vec::new();
    let mut k = 1;
    let n = b.len();
    let mut moved = false;
    while k < n {
        if (b[k] - b[k - 1]).abs() > tol {
            moved = true;
            k += 1;
            continue;
        }
        let s = k;
        while k < n && (b[k] - b[k - 1]).abs() <= tol {
            k += 1;
        }
        if moved && k - s >= min_n {
            out.push(s..k);
        }
    }
    out
}

/// Log decrement + damped sinusoid on every free-decay segment of `rec`; modes combined across
/// segments (mean; 1-σ = hypot(mean per-segment σ, spread across segments)).
pub fn identify_segments(
    rec: &Recording,
    opts: &FreeDecayOptions,
    warnings: &mut Vec<String>,
) -> Result<Vec<ModeEstimate>> {
    let segs = free_decay_segments(rec, 3.0);
    if segs.is_empty() {
        bail!("no free-decay segment (base still for >= 3 s after moving) in the recording");
    }
    let tip = rec
        .tip_pos_m
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("no tip_pos_m column for the free decays"))?;
    let base = rec.base_pos_m.as_ref().or(rec.base_cmd_m.as_ref());
    let mut per: Vec<ModeEstimate> = Vec::new();
    for s in &segs {
        let t = &rec.time_s[s.clone()];
        let x: Vec<f64> = match base {
            Some(b) => s.clone().map(|k| tip[k] - b[k]).collect(),
            None => tip[s.clone()].to_vec(),
        };
        match identify_free_decay(t, &x, opts) {
            Ok(r) => per.push(r.mode),
            Err(e) => warnings.push(format!(
                "free decay {:.2}..{:.2} s: {e}",
                t[0],
                t[t.len() - 1]
            )),
        }
    }
    if per.is_empty() {
        bail!(
            "none of the {} free-decay segments could be analysed",
            segs.len()
        );
    }
    let f: Vec<f64> = per.iter().map(|m| m.freq_hz).collect();
    let z: Vec<f64> = per.iter().map(|m| m.zeta).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let fs = mean(&per.iter().map(|m| m.freq_hz_std).collect::<Vec<_>>());
    let zs = mean(&per.iter().map(|m| m.zeta_std).collect::<Vec<_>>());
    Ok(vec![ModeEstimate {
        freq_hz: mean(&f),
        zeta: mean(&z),
        freq_hz_std: fs.hypot(std_dev(&f)),
        zeta_std: zs.hypot(std_dev(&z)),
        method: format!("logdec ({} free-decay segments)", per.len()),
    }])
}

/// The band of `opts.band_hz` checked against `frf` (0 ≤ lo < hi ≤ Nyquist), or
/// [`auto_band`]; at least 16 FRF lines in it.
pub fn frf_band(frf: &Frf, opts: &IdentOptions) -> Result<(f64, f64)> {
    let nyq = 0.5 * frf.sample_rate_hz;
    let (f_lo, f_hi) = match opts.band_hz {
        Some((a, b)) => {
            if !(a >= 0.0 && b > a) {
                bail!("band {a}..{b} Hz: need 0 <= f_lo < f_hi");
            }
            if b > nyq {
                bail!("band upper limit {b} Hz is beyond the Nyquist frequency {nyq} Hz of the recording");
            }
            (a, b)
        }
        None => auto_band(frf),
    };
    let n = frf.band(f_lo, f_hi).len();
    if n < 16 {
        bail!("only {n} FRF lines in the band {f_lo:.3}..{f_hi:.3} Hz (line spacing {:.4} Hz): record longer or widen the band", frf.df_hz());
    }
    Ok((f_lo, f_hi))
}

/// Runs the FRF estimators of `opts` ([`frf_estimators`]: the first refined by maximum
/// likelihood when `opts.ml_refine`) on `frf` in [`frf_band`]. `warnings` collects resolution
/// warnings; `progress` is told each stabilisation diagram's orders. Returns the results in
/// the order of `opts.methods` and the band.
pub fn identify_frf(
    frf: &Frf,
    opts: &IdentOptions,
    warnings: &mut Vec<String>,
    progress: &mut dyn Progress,
) -> Result<(Vec<MethodResult>, (f64, f64))> {
    let cx = FrfContext {
        frf,
        band_hz: frf_band(frf, opts)?,
        opts,
    };
    let mut out = Vec::new();
    for e in frf_estimators(opts) {
        out.push(e.estimate(&cx, warnings, progress)?);
    }
    Ok((out, cx.band_hz))
}

/// Combines: the primary method's modes, uncertainty widened by the other methods' spread.
pub fn combine(methods: &[MethodResult]) -> Vec<ModeEstimate> {
    let Some(primary) = methods.iter().find(|m| !m.modes.is_empty()) else {
        return vec![];
    };
    primary
        .modes
        .iter()
        .map(|m| {
            let others: Vec<&ModeEstimate> = methods
                .iter()
                .flat_map(|r| r.modes.iter())
                .filter(|o| (o.freq_hz / m.freq_hz - 1.0).abs() < 0.03)
                .collect();
            let f: Vec<f64> = others.iter().map(|o| o.freq_hz).collect();
            let z: Vec<f64> = others.iter().map(|o| o.zeta).collect();
            let names: Vec<String> = methods
                .iter()
                .filter(|r| {
                    r.modes
                        .iter()
                        .any(|o| (o.freq_hz / m.freq_hz - 1.0).abs() < 0.03)
                })
                .map(|r| r.method.name().to_string())
                .collect();
            ModeEstimate {
                freq_hz: m.freq_hz,
                zeta: m.zeta,
                freq_hz_std: m.freq_hz_std.hypot(std_dev(&f)),
                zeta_std: m.zeta_std.hypot(std_dev(&z)),
                method: if names.len() > 1 {
                    format!("{} (spread over {})", m.method, names.join("+"))
                } else {
                    m.method.clone()
                },
            }
        })
        .collect()
}

/// The FRF [`identify_recording`] uses: channels, optional tracking filter, Welch.
///
/// With a kinematic input (base acceleration or position) and `track_input`, the *measured base
/// position* is cleaned once and that clean base position feeds both the input (its second
/// difference for base acceleration) and the output's tip deflection (tip − base): predicted
/// from the noise-free command `base_cmd_m` by a fitted servo model
/// ([`super::denoise::base_from_command`]) when the recording has one and the model explains
/// ≥ 90 % of the base variance, else tracking-filtered ([`super::denoise::track_sweep`]). Filtering only the input left the base sensor's noise in the output, the same
/// noise twice: an errors-in-variables error that H1 cannot average out in one record
/// (docs/ident.md, "Numbers behind the design choices"). Force input is never filtered (it also
/// carries the beam's reaction at its resonances).
pub fn frf_with_options(rec: &Recording, opts: &IdentOptions) -> Result<(Frf, Vec<String>)> {
    if !opts.track_input || opts.input == InputChannel::Force {
        return frf_of_recording(rec, opts.input, opts.output, &opts.welch);
    }
    rec.validate()?;
    let rate = rec.sample_rate_hz();
    let band = match opts.band_hz {
        Some(b) => b,
        None => {
            let (x, y, _, _, _) = super::frf::channels(rec, opts.input, opts.output)?;
            auto_band(&super::frf::welch(&x, &y, rate, &opts.welch)?)
        }
    };
    let mut warnings = Vec::new();
    let mut filtered = rec.clone();
    let noisy_cmd = rec
        .base_cmd_m
        .as_deref()
        .is_some_and(|c| command_is_noisy(c, rate, band));
    if noisy_cmd {
        warnings.push(NOISY_COMMAND.into());
    }
    let predicted = match (rec.base_pos_m.as_deref(), rec.base_cmd_m.as_deref()) {
        (Some(b), Some(c)) if !noisy_cmd => predict_base(b, c, rate, &mut warnings),
        _ => None,
    };
    let suffix = match (
        predicted,
        rec.base_pos_m.as_deref(),
        rec.base_cmd_m.as_deref(),
    ) {
        (Some((x, s)), _, _) => {
            filtered.base_pos_m = Some(x);
            s
        }
        (None, Some(b), _) => track_into(
            &mut filtered.base_pos_m,
            b,
            rate,
            band,
            "base_pos_m",
            &mut warnings,
        )?,
        (None, None, Some(c)) if noisy_cmd => track_into(
            &mut filtered.base_cmd_m,
            c,
            rate,
            band,
            "base_cmd_m",
            &mut warnings,
        )?,
        // A clean command alone: nothing to filter.
        _ => String::new(),
    };
    // Saturation is judged on the measured channels, not the cleaned ones.
    let (_, _, _, _, w) = super::frf::channels(rec, opts.input, opts.output)?;
    warnings.extend(w);
    let (x, y, xd, yd, _) = super::frf::channels(&filtered, opts.input, opts.output)?;
    let mut f = super::frf::welch(&x, &y, rate, &opts.welch)?;
    f.input = format!("{xd}{suffix}");
    f.output = yd;
    Ok((f, warnings))
}

/// The base position predicted from a clean command (BIC-sized FIR servo model) and its
/// description, when the model explains ≥ 90 % of the measured base's variance; otherwise
/// `None` (with a warning when the fit ran but explained too little).
fn predict_base(
    b: &[f64],
    c: &[f64],
    rate_hz: f64,
    warnings: &mut Vec<String>,
) -> Option<(Vec<f64>, String)> {
    // Taps up to 0.1 s lead (time-stamp offsets) and 1 s lag (servo, reaction).
    let lead = (0.1 * rate_hz).ceil() as usize;
    let lag = (1.0 * rate_hz).ceil() as usize;
    let m = super::denoise::base_from_command_bic(c, b, lead, lag).ok()?;
    if m.r2 < 0.9 {
        warnings.push(format!("the command explains only {:.0} % of the base position's variance: base_pos_m tracking-filtered instead", 100.0 * m.r2));
        return None;
    }
    let s = format!(
        ", base_pos_m predicted from base_cmd_m by a least-squares FIR servo model (taps {}..{} samples, BIC; R² = {:.4})",
        -(m.taps.0 as isize),
        m.taps.1,
        m.r2
    );
    Some((m.base, s))
}

const NOISY_COMMAND: &str = "base_cmd_m carries broadband noise (a recorded, not a generated, command?): the base is tracking-filtered instead of predicted from it";

/// A generated command is band-limited: more than 10⁻⁶ of its variance above twice the band's
/// upper edge is sensor noise (the limit sits near 0.1 % noise; the measurements behind it are
/// in docs/ident.md, "Numbers behind the design choices"). Not testable when 2 × the band
/// reaches 0.8 × Nyquist.
fn command_is_noisy(c: &[f64], rate_hz: f64, band_hz: (f64, f64)) -> bool {
    let f = 2.0 * band_hz.1;
    f < 0.4 * rate_hz && super::denoise::broadband_fraction(c, rate_hz, f) > 1e-6
}

/// Tracking filter ([`super::denoise::track_sweep`]) of the base position `b` about its mean
/// (the sweep oscillates about a rest position the ridge mask would otherwise remove), written
/// into `slot` when `b` is a sweep; returns the description suffix (or pushes a warning).
fn track_into(
    slot: &mut Option<Vec<f64>>,
    b: &[f64],
    rate_hz: f64,
    band_hz: (f64, f64),
    name: &str,
    warnings: &mut Vec<String>,
) -> Result<String> {
    let mean = b.iter().sum::<f64>() / b.len() as f64;
    let centred: Vec<f64> = b.iter().map(|v| v - mean).collect();
    if centred.iter().all(|v| *v == 0.0) {
        return Ok(String::new());
    }
    let tr = super::denoise::track_sweep(&centred, rate_hz, 4.0, band_hz)?;
    if tr.is_sweep() {
        *slot = Some(tr.x.iter().map(|v| v + mean).collect());
        Ok(format!(
            ", {name} sweep-tracking filtered ({:.0} % of its energy in {:.1} % of the bins)",
            100.0 * tr.kept_energy,
            100.0 * tr.kept_bins
        ))
    } else {
        warnings.push(format!(
            "{name} is not a sweep ({:.0} % of its energy in {:.1} % of the bins): no tracking filter",
            100.0 * tr.kept_energy,
            100.0 * tr.kept_bins
        ));
        Ok(String::new())
    }
}

/// Identifies the modes of a recording (uniform time, validated): FRF of `opts.input` →
/// `opts.output`, the FRF estimators of `opts.methods`, and the free decays after each move
/// when `Method::LogDec` is asked for. Returns the FRF too (for plots).
///
/// Errors: a missing column, NaN, non-uniform or non-increasing time (from
/// [`Recording::validate`]), a band beyond Nyquist, too few lines in the band, no method
/// producing a mode. Clipped signals give warnings.
pub fn identify_recording(rec: &Recording, opts: &IdentOptions) -> Result<(IdentResult, Frf)> {
    identify_recording_with(rec, opts, &mut Silent)
}

/// [`identify_recording`] telling `progress` the estimators' stages.
pub fn identify_recording_with(
    rec: &Recording,
    opts: &IdentOptions,
    progress: &mut dyn Progress,
) -> Result<(IdentResult, Frf)> {
    rec.validate()?;
    if rec.len() < 256 {
        bail!(
            "the recording has {} samples; identification needs at least 256",
            rec.len()
        );
    }
    let (frf, warnings) = frf_with_options(rec, opts)?;
    let res = estimate_on_frf(rec, &frf, warnings, opts, progress)?;
    Ok((res, frf))
}

/// The estimator half of [`identify_recording_with`]: the FRF estimators of `opts.methods` on
/// `frf` (of `rec`), the free decays of `rec` when `Method::LogDec` is asked for, combined;
/// `warnings` (from the FRF) are carried into the result.
///
/// Errors: a band beyond Nyquist, too few lines in the band, no method producing a mode.
pub fn estimate_on_frf(
    rec: &Recording,
    frf: &Frf,
    mut warnings: Vec<String>,
    opts: &IdentOptions,
    progress: &mut dyn Progress,
) -> Result<IdentResult> {
    let frf_methods = opts.methods.iter().any(|m| *m != Method::LogDec);
    let (mut methods, band) = if frf_methods {
        identify_frf(frf, opts, &mut warnings, progress)?
    } else {
        (vec![], auto_band(frf))
    };
    if opts.methods.contains(&Method::LogDec) {
        let fd = FreeDecayOptions {
            f_min_hz: band.0,
            f_max_hz: band.1,
            ..Default::default()
        };
        match identify_segments(rec, &fd, &mut warnings) {
            Ok(m) => {
                let r = MethodResult {
                    method: Method::LogDec,
                    modes: m,
                    diagram: None,
                };
                let pos = opts
                    .methods
                    .iter()
                    .position(|m| *m == Method::LogDec)
                    .unwrap_or(0)
                    .min(methods.len());
                methods.insert(pos, r);
            }
            Err(e) => warnings.push(format!("logdec: {e}")),
        }
    }
    let modes = combine(&methods);
    if modes.is_empty() {
        bail!("no mode found in {:.3}..{:.3} Hz by {}; check the band, the excitation and the channels", band.0, band.1, opts.methods.iter().map(|m| m.name()).collect::<Vec<_>>().join(", "));
    }
    let rayleigh = (modes.len() >= 2).then(|| {
        let w = |m: &ModeEstimate| 2.0 * std::f64::consts::PI * m.freq_hz;
        crate::model::galerkin::rayleigh_coefficients(
            w(&modes[0]),
            modes[0].zeta,
            w(&modes[1]),
            modes[1].zeta,
        )
    });
    Ok(IdentResult {
        modes,
        methods,
        rayleigh,
        band_hz: band,
        df_hz: frf.df_hz(),
        n_averages: frf.n_averages,
        input: frf.input.clone(),
        output: frf.output.clone(),
        warnings,
    })
}

/// [`identify_free_decay`] as an [`IdentResult`] (modes of the free decay; no FRF).
pub fn identify_decay(
    time_s: &[f64],
    signal: &[f64],
    opts: &FreeDecayOptions,
) -> Result<IdentResult> {
    let r = identify_free_decay(time_s, signal, opts)?;
    let rayleigh = (r.modes.len() >= 2).then(|| {
        let w = |m: &ModeEstimate| 2.0 * std::f64::consts::PI * m.freq_hz;
        crate::model::galerkin::rayleigh_coefficients(
            w(&r.modes[0]),
            r.modes[0].zeta,
            w(&r.modes[1]),
            r.modes[1].zeta,
        )
    });
    Ok(IdentResult {
        modes: r.modes.clone(),
        methods: vec![MethodResult {
            method: Method::LogDec,
            modes: r.modes.clone(),
            diagram: None,
        }],
        rayleigh,
        band_hz: (opts.f_min_hz, opts.f_max_hz.min(0.45 * r.sample_rate_hz)),
        df_hz: f64::NAN,
        n_averages: 0,
        input: "none (free decay)".into(),
        output: "signal".into(),
        warnings: r.warnings,
    })
}
