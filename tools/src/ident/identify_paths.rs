//! The output-only and pooled ring-down paths of [`super::identify()`] (split from
//! `identify.rs`): the response they use and how their results enter the [`Identification`].

use super::identify::{base_channel, tip_signal, IdentifyOptions, Identification, RejectedMode, Stage};
use super::ModeEstimate;
use crate::recording::{fmt_sig, Recording};
use anyhow::{bail, Result};

/// `Ok(why)` when the tip response of `rec` is a stationary response for the output-only
/// path ([`super::ssi::stationary_response`] in `opts.decay`'s band), else `Err(why not)`.
pub(crate) fn output_only_reason(rec: &Recording, opts: &IdentifyOptions) -> std::result::Result<String, String> {
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
    let name = if base_channel(rec).is_some() {
        "tip deflection (tip_pos_m - base)"
    } else {
        "tip_pos_m"
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
        bail!("no tip channel (tip_pos_m) to identify from");
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

