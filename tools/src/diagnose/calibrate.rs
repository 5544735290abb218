//! Before any candidate: the recordings checked (enough information, plausible units), the
//! diagnosis set up ([`setup`]: the nominal model, the drive's quantum), and the nominal model
//! calibrated to the fit recordings ([`calibrate`]), its residual required to be within
//! [`MAX_CALIBRATED_NRMSE`] and the stiffness scale plausible.

use super::effects::{calibration_defs, Candidate, Channels};
use super::fit::{channel_rss, fit, residuals, FitResult};
use super::model::{Prediction, Prepared};
use super::selection::{Budget, Ctx};
use super::{nrmse, stage};
use crate::model::Rig;
use anyhow::{bail, Result};

fn channels_of(data: &[Prepared]) -> Channels {
    Channels {
        base: data.iter().any(|d| d.base_m.is_some()),
        tip: data.iter().any(|d| d.tip_m.is_some()),
        force: data.iter().any(|d| d.force_n.is_some()),
        cmd_drives_beam: data.iter().any(|d| d.drive_m.is_none()),
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// What the preparation of a diagnosis found out about the recordings and the rig.
#[derive(Clone)]
pub(crate) struct Setup {
    pub(crate) channels: Channels,
    pub(crate) band_edge_hz: f64,
    pub(crate) basis: Option<crate::diagnose::model::BasisChoice>,
    pub(crate) calib: crate::diagnose::effects::Calib,
    /// [`drive_quantum_m`] of the recordings as loaded.
    pub(crate) drive_quantum_m: Option<f64>,
}

/// Step of the counts (m) of the position the drive is read from — `base_pos_m` where
/// recorded, else the command — in the fit recordings as loaded (the largest over them;
/// `None` when none is quantised, [`crate::numeric::stats::quantum`]).
pub(crate) fn drive_quantum_m(fit_data: &[Prepared]) -> Option<f64> {
    fit_data
        .iter()
        .filter_map(|d| crate::numeric::stats::quantum(d.base_m.as_ref().unwrap_or(&d.cmd_m)))
        .reduce(f64::max)
}

/// Refuses recordings without information or that the nominal model cannot simulate; the band
/// edge, the converged Galerkin basis and the calibration parameters; `drive_quantum_m` (of the
/// recordings as loaded, [`drive_quantum_m`]) is kept for the guard.
pub(crate) fn setup(
    rig: &Rig,
    fit_data: &[Prepared],
    validate: &Prepared,
    drive_quantum_m: Option<f64>,
) -> Result<Setup> {
    if fit_data.is_empty() {
        bail!("at least one --fit recording is needed");
    }
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        check_information(d)?;
    }
    // the nominal model must be able to simulate every recording: report why not, by name
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        crate::diagnose::model::predict(
            rig,
            &crate::diagnose::model::Params::default(),
            d,
            &mut None,
        )
        .map_err(|e| anyhow::anyhow!("{}: {e:#}", d.name))?;
    }
    let channels = channels_of(fit_data);
    let band_edge_hz = fit_data
        .iter()
        .chain(std::iter::once(validate))
        .map(|d| crate::diagnose::model::band_edge_hz(d.dt))
        .fold(f64::INFINITY, f64::min);
    let nyquist_hz = fit_data
        .iter()
        .chain(std::iter::once(validate))
        .map(|d| 0.5 / d.dt)
        .fold(0.0, f64::max);
    let basis = match rig.beam {
        Some(_) => Some(crate::diagnose::model::converged_basis(
            rig,
            1.0,
            band_edge_hz,
            nyquist_hz,
        )?),
        None => None,
    };
    let mut calib = calibration_defs(
        rig,
        &channels,
        basis.as_ref().map_or(0, |b| b.freqs_hz.len()),
        basis.as_ref().map_or(4, |b| b.n_basis),
    );
    calib.simulated_modes = basis.as_ref().map(|b| b.simulated_modes);
    Ok(Setup {
        channels,
        band_edge_hz,
        basis,
        calib,
        drive_quantum_m,
    })
}

/// Initial whitening: a tenth of each channel's signal rms (base: base − command; tip:
/// deflection).
fn initial_sigma(fit_data: &[Prepared]) -> [f64; 3] {
    let mut sigma = [1e-6, 1e-4, 0.1];
    let mut acc: [Vec<f64>; 3] = [vec![], vec![], vec![]];
    for d in fit_data {
        if let Some(b) = &d.base_m {
            acc[0].extend(b.iter().zip(d.cmd_as_sampled()).map(|(a, c)| a - c));
        }
        if let Some(t) = &d.tip_m {
            let drive = d.drive_as_sampled();
            acc[1].extend(t.iter().zip(drive).map(|(a, c)| a - c));
        }
        if let Some(f) = &d.force_n {
            acc[2].extend(f.iter().copied());
        }
    }
    for c in 0..3 {
        if !acc[c].is_empty() {
            sigma[c] = (0.1 * rms(&acc[c])).max(1e-12);
        }
    }
    sigma
}

/// The calibrated nominal model.
pub(crate) struct Calibrated {
    pub(crate) fit: FitResult,
    /// Channel noise scales (residual rms of the first calibration).
    pub(crate) sigma: [f64; 3],
    /// Fit-recording predictions and residuals.
    pub(crate) preds: Vec<Prediction>,
    pub(crate) res: Vec<[Option<Vec<f64>>; 3]>,
    pub(crate) params: crate::diagnose::model::Params,
    /// The best tip/force NRMSE of the calibrated nominal model on the fit recordings
    /// ([`best_nrmse`]).
    pub(crate) best_nrmse: f64,
}

/// Predictions and residuals of the calibration `cal` on the fit recordings.
fn calibrated_residuals(
    rig: &Rig,
    fit_data: &[Prepared],
    sigma: [f64; 3],
    calib: &crate::diagnose::effects::Calib,
    cal: &FitResult,
) -> Result<(Vec<Prediction>, Vec<[Option<Vec<f64>>; 3]>)> {
    let problem =
        crate::diagnose::fit::Problem::new(rig, fit_data, sigma, calib, &[], cal.x.clone());
    let preds = problem.predictions(&cal.x).ok_or_else(|| {
        let why = problem.refusals.borrow().first().cloned().unwrap_or_default();
        anyhow::anyhow!(
            "no information: calibrated to the fit recordings, the rig model leaves what it can simulate ({why}; stiffness scale {:.3}); a recording of another rig, or noise only?",
            problem.params_of(&cal.x).stiffness_scale
        )
    })?;
    let res = fit_data
        .iter()
        .zip(&preds)
        .map(|(d, p)| residuals(d, p))
        .collect();
    Ok((preds, res))
}

/// Calibrates the nominal model twice: with [`initial_sigma`], then whitened by the residual
/// rms of that calibration; refuses a stiffness scale no rig of this file can have (as "no
/// information" when the model explains almost nothing of the recordings either).
pub(crate) fn calibrate(
    rig: &Rig,
    fit_data: &[Prepared],
    calib: &crate::diagnose::effects::Calib,
    budget: &mut Budget,
    progress: &mut dyn crate::progress::Progress,
    total_steps: usize,
) -> Result<Calibrated> {
    let mut sigma = initial_sigma(fit_data);
    stage(progress, 0, total_steps, "calibrating the nominal model");
    let cal = fit(
        rig,
        fit_data,
        sigma,
        calib,
        &[],
        None,
        &[],
        budget.share(4),
        true,
    );
    budget.spend(cal.evaluations);
    let (_, res0) = calibrated_residuals(rig, fit_data, sigma, calib, &cal)?;
    let (rss0, n0) = channel_rss(&res0);
    for c in 0..3 {
        if n0[c] > 0 {
            sigma[c] = (rss0[c] / n0[c] as f64).sqrt().max(1e-12);
        }
    }
    stage(
        progress,
        1,
        total_steps,
        "recalibrating with the residual noise scales",
    );
    let cal = fit(
        rig,
        fit_data,
        sigma,
        calib,
        &[],
        Some(&cal.x),
        &[],
        budget.share(3),
        true,
    );
    budget.spend(cal.evaluations);
    let (preds, res) = calibrated_residuals(rig, fit_data, sigma, calib, &cal)?;
    let problem =
        crate::diagnose::fit::Problem::new(rig, fit_data, sigma, calib, &[], cal.x.clone());
    let params = problem.params_of(&cal.x);
    let best_nrmse = best_nrmse(fit_data, &preds);
    if !(best_nrmse < MAX_CALIBRATED_NRMSE) && check_stiffness_scale(&params).is_err() {
        // a stiffness scale fitted to nothing says nothing of the rig
        bail!(
            "no information: even calibrated, the rig model explains almost nothing of the fit recordings (best tip/force channel NRMSE {best_nrmse:.2} ≥ {MAX_CALIBRATED_NRMSE}); a recording of another rig, or noise only?"
        );
    }
    check_stiffness_scale(&params)?;
    Ok(Calibrated {
        fit: cal,
        sigma,
        best_nrmse,
        preds,
        res,
        params,
    })
}

/// The best NRMSE ([`nrmse`]) of `preds` over every tip and force channel of `fit_data` (of the
/// base channel when a recording has neither); ∞ when none is finite.
pub(crate) fn best_nrmse(fit_data: &[Prepared], preds: &[Prediction]) -> f64 {
    fit_data
        .iter()
        .zip(preds)
        .flat_map(|(d, p)| {
            let v = nrmse(d, p);
            // the beam's channels; a carriage-only recording with neither has its base
            if v[1].is_finite() || v[2].is_finite() {
                [v[1], v[2]]
            } else {
                [v[0], f64::NAN]
            }
        })
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min)
}

/// Refuses a calibration that needs a stiffness scale outside 0.25–4 (another rig).
fn check_stiffness_scale(p: &crate::diagnose::model::Params) -> Result<()> {
    if p.stiffness_scale < 0.25 || p.stiffness_scale > 4.0 {
        bail!(
            "the recordings do not match this rig: the calibration needs {:.2} × the rig's Young's modulus (frequencies off by {:.0} %); check the rig file",
            p.stiffness_scale,
            100.0 * (p.stiffness_scale.sqrt() - 1.0)
        );
    }
    Ok(())
}

/// Refuses recordings that the final model — the calibrated nominal model with every effect
/// the selection chose — explains almost nothing of (best tip/force NRMSE ≥
/// [`MAX_CALIBRATED_NRMSE`] on the fit recordings: another rig, noise only); when the nominal
/// model alone explained almost nothing (`nominal_best`) and the effects do, says so. The check
/// follows the selection because a large effect (a play of millimetres) leaves the nominal
/// model explaining nothing of recordings its catalogue explains (held-out 274060: a 5.1 mm
/// play at noise ×2, nominal NRMSE 0.99, play and tip mass found).
pub(crate) fn check_explained(
    ctx: &Ctx,
    set: &[&Candidate],
    sel: &crate::diagnose::selection::Selection,
    nominal_best: f64,
) -> Result<Option<String>> {
    if nominal_best < MAX_CALIBRATED_NRMSE {
        return Ok(None);
    }
    let x = &sel.reference.fit.x;
    let best = ctx
        .fit_problem(set, x.clone())
        .predictions(x)
        .map_or(f64::INFINITY, |p| best_nrmse(ctx.fit_data, &p));
    if !(best < MAX_CALIBRATED_NRMSE) {
        bail!(
            "no information: even calibrated and with the catalogue's effects, the rig model explains almost nothing of the fit recordings (best tip/force channel NRMSE {:.2} ≥ {MAX_CALIBRATED_NRMSE}); a recording of another rig, or noise only?",
            best.min(nominal_best)
        );
    }
    Ok(Some(format!(
        "the calibrated nominal model alone explains almost nothing of the fit recordings (best tip/force channel NRMSE {nominal_best:.2}); the effects named account for them (NRMSE {best:.2})"
    )))
}

/// Fewest samples and seconds a recording needs: 100 samples and 5 s (several periods of a
/// slow first mode; the whiteness test uses 20 lags).
pub const MIN_SAMPLES: usize = 100;

/// See [`MIN_SAMPLES`].
pub const MIN_DURATION_S: f64 = 5.0;

/// Largest minus smallest value of `v` (NaN-free).
fn span(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - v.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// Refuses a recording that cannot inform a diagnosis: too short, a command that does not move,
/// or a recorded channel that is constant.
pub(crate) fn check_information(d: &Prepared) -> Result<()> {
    let n = d.cmd_m.len();
    let dur = n as f64 * d.dt;
    if n < MIN_SAMPLES || dur < MIN_DURATION_S {
        bail!(
            "{}: too short for a diagnosis ({n} samples, {dur:.2} s): at least {MIN_SAMPLES} samples and {MIN_DURATION_S} s are needed",
            d.name
        );
    }
    let drive = d.drive_as_sampled();
    if !(span(drive) > 0.0) {
        bail!(
            "{}: no information: the base does not move (constant position), so nothing excites the model",
            d.name
        );
    }
    for (name, ch) in [
        ("base_pos_m", &d.base_m),
        ("tip_pos_m", &d.tip_m),
        ("force_n", &d.force_n),
    ] {
        if let Some(v) = ch {
            if !(span(v) > 0.0) {
                bail!(
                    "{}: no information: `{name}` is constant while the base moves (sensor not connected?)",
                    d.name
                );
            }
        }
    }
    Ok(())
}

/// The longest stroke a recording's base may span (m): a lab linear axis moves metres, not tens
/// of metres; a longer one is a file in millimetres.
pub const MAX_STROKE_M: f64 = 10.0;

/// Refuses positions that cannot be metres on this rig: a base that spans more than
/// [`MAX_STROKE_M`], or a tip farther from the base than the beam is long (positions in mm, or
/// channels mixed up), naming the file, the channel and the figure.
pub(crate) fn check_units(rig: &Rig, d: &Prepared) -> Result<()> {
    let base = d.base_m.as_deref().unwrap_or(&d.cmd_m);
    for (name, v) in [("base_cmd_m", &d.cmd_m[..]), ("base_pos_m", base)] {
        if span(v) > MAX_STROKE_M {
            bail!(
                "{}: `{name}` spans {:.4} m, more than any lab axis's stroke ({MAX_STROKE_M} m): positions are in metres (a file in millimetres?)",
                d.name,
                span(v)
            );
        }
    }
    if let (Some(beam), Some(tip)) = (&rig.beam, &d.tip_m) {
        let off = tip
            .iter()
            .zip(base)
            .map(|(t, b)| (t - b).abs())
            .fold(0.0, f64::max);
        if off > beam.length_m {
            bail!(
                "{}: `tip_pos_m` is up to {off:.4} m from the base, more than the beam's length ({} m): positions are in metres along the base axis (millimetres, or another channel?)",
                d.name,
                beam.length_m
            );
        }
    }
    Ok(())
}

/// Largest NRMSE (on the channel the model predicts best) at which the calibrated nominal
/// model is still taken to describe the recordings: below it the model explains at least
/// 1 − 0.9² = 19 % of that channel's variance.
pub const MAX_CALIBRATED_NRMSE: f64 = 0.9;
