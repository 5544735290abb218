//! Model-discrepancy diagnosis: calibrate the nominal model, locate the residual, fit a
//! catalogue of candidate physics, select with a guard against false discovery, report.
//!
//! - [`sim`]: the augmented simulator (nominal model of paper §2 + every extension);
//! - [`effects`]: the candidate catalogue with physical parameters;
//! - [`fit`]: Levenberg–Marquardt ([`crate::numeric::lm`]) on whitened residuals, parameter
//!   uncertainties;
//! - [`locate`]: where/when/at which frequency the residual is structured;
//! - [`saturation`]: samples a sensor held at its rail, left out of every residual;
//! - [`scale_bands`]: a tip sensor's scale on the deflection must scale every mode band alike;
//! - [`select`]: BIC + validation + model-form allowance + whiteness + significance guard;
//! - [`backward`]: after forward selection, each chosen effect must still earn its parameters
//!   beside the others (backward elimination);
//! - [`report`]: JSON, words, SVG plots; [`proof`]: the own-generator proof; [`honesty`]:
//!   long-run 1-σ, parameter stability, residual statistics of the final model;
//! - the commands (`diagnose`, `diagnose-proof`, `diagnose-lengths`) live in `crate::cli::diagnose`;
//!
//! Where a recording is analysed at its own rate with a tip or force channel, the whole
//! diagnosis runs twice in parallel, the drive read piecewise linear and smooth between samples
//! ([`sim::DriveReading`]), and the final model with the lower BIC on the fit recordings is
//! kept ([`ReadingChoice`]).
//!
//! Every fit of one diagnosis draws on one budget of model evaluations
//! ([`WORK_BUDGET_SAMPLE_EVALUATIONS`] divided by the fit recordings' samples), never on the
//! clock, so the same recordings give the same answer on any machine.

pub mod backward;
pub mod decision;
pub mod effects;
pub mod fit;
mod forward;
pub mod honesty;
pub mod lengths;
pub mod load;
pub mod locate;
pub mod lookalike;
pub mod proof;
pub mod rate;
pub mod report;
pub mod saturation;
pub mod scale_bands;
pub mod select;
pub mod sim;
pub mod unexplained;

use crate::model::{BeamModel, ModelOptions, Rig};
use anyhow::{bail, Result};
use effects::{calibration_defs, catalogue, Candidate, Channels, StartHints};
use fit::{channel_rss, fit, residuals, FitResult};
use forward::{Budget, Ctx};
use sim::{Prediction, Prepared};

/// Outcome of one candidate.
#[derive(Clone, Debug)]
pub struct CandidateOutcome {
    /// The effect.
    pub id: crate::effect::Effect,
    /// Index of the candidate in the catalogue of this diagnosis.
    pub cand_index: usize,
    /// Index of this effect's first parameter in `fit.values` (after the calibration and the
    /// effects chosen before it).
    pub param_offset: usize,
    /// Validation NRMSE per channel of the model it was compared with.
    pub nrmse_before: [f64; 3],
    /// Words (incl. orientation).
    pub words: String,
    /// The fit (calibration + effect).
    pub fit: FitResult,
    /// Number of effect parameters (k of the BIC; 1 for an orientation).
    pub k: usize,
    /// ΔBIC on the fit recordings vs the calibrated nominal model.
    pub delta_bic: f64,
    /// Δ(−2 ln L) on the validation recording.
    pub delta_val: f64,
    /// Validation NRMSE per channel (NaN where absent).
    pub val_nrmse: [f64; 3],
    /// Channel helped most on validation.
    pub best_channel: usize,
    /// Relative NRMSE reduction on that channel.
    pub reduction: f64,
    /// The reduction a physics-free correction with as many parameters earns on that channel
    /// (the model-form allowance, [`crate::numeric::arx`]).
    pub allowance: f64,
    /// Ljung–Box Q before/after on that channel's validation residual.
    pub whiteness: (f64, f64),
    /// Largest |value|/σ over null-at-zero parameters (∞ if none).
    pub significance: f64,
    /// The Diebold–Mariano test of its validation prediction against the model it extends
    /// ([`decision`]): the evidence the decision rule reads, `None` without validation residuals.
    pub predictive: Option<crate::numeric::predictive::PredictiveTest>,
    /// Passed the guard.
    pub passed: bool,
    /// Why it lost or passed.
    pub reason: String,
    /// Validation predictions.
    pub val_pred: Prediction,
    /// Why a resonance that passes every other guard cannot be placed where the candidate puts
    /// it (a mount that a loose tip sensor explains as well; [`select`] condition 8), if so.
    pub unplaced: Option<String>,
    /// The effect the recordings cannot tell this one from, if so ([`lookalike`]).
    pub look_alike: Option<lookalike::LookAlike>,
    /// It failed only condition 6 of [`select`]: it removes part, not most, of the structured
    /// residual — what the first effect of a pair does beside the second ([`forward`]'s
    /// pair step).
    pub partial: bool,
    /// It failed only the calibration-matter rule, as a coupled mount whose resonance lies
    /// beside a model mode: apart by more than its half-power half-width (and 2 σ), within the
    /// full width. Such a split-off resonance is judged against a local compliance of the beam
    /// instead ([`forward`]'s `judge_mounts_beside_modes`).
    pub beside_mode: bool,
}

impl CandidateOutcome {
    /// Fails the outcome when [`CandidateOutcome::unplaced`] says so.
    pub(crate) fn apply_placement(&mut self) {
        if let Some(why) = &self.unplaced {
            if self.passed {
                self.passed = false;
                self.reason = why.clone();
            } else if !self.reason.contains(why.as_str()) {
                self.reason = format!("{}; {why}", self.reason);
            }
        }
    }
}

/// The diagnosis.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// Selected effect id or `none`.
    pub effect: String,
    /// Index into `candidates` of the selected one.
    pub selected: Option<usize>,
    /// Calibration of the nominal model (names, values, σ).
    pub calibration: FitResult,
    /// Per calibration parameter, why the recordings do not identify it
    /// ([`effects::calibration_unidentified`]; `None`: identified). Reported in place of its
    /// value.
    pub calibration_unidentified: Vec<Option<String>>,
    /// The same judgement of the calibration refitted with the named effects (the first
    /// parameters of `final_fit`): a damping ratio the joint fit drives out of the applied
    /// range is reported as not identified, not as a number.
    pub final_calibration_unidentified: Vec<Option<String>>,
    /// The stiffness scale the final model applies to EI when a named structural effect (tip
    /// mass, root spring, axial load) fits along the f1-preserving path
    /// ([`fit::params_of_values`]): the reported `stiffness_scale` times that factor. `None`
    /// without one (the reported scale is the applied one).
    pub final_applied_stiffness_scale: Option<f64>,
    /// Channel noise scales σ used for whitening.
    pub sigma: [f64; 3],
    /// Location of the discrepancy.
    pub location: locate::Location,
    /// Validation NRMSE per channel of the calibrated nominal model.
    pub val_nrmse_nominal: [f64; 3],
    /// Nominal validation prediction.
    pub val_pred_nominal: Prediction,
    /// Candidates (best first by validation gain).
    pub candidates: Vec<CandidateOutcome>,
    /// The validation recording (prepared).
    pub validate: Prepared,
    /// Model evaluations the least-squares fits reported, in total.
    pub evaluations: usize,
    /// Everything simulated (fits, validation predictions, refits), in evaluations of the fit
    /// recordings: every simulated sample divided by the fit recordings' samples.
    pub evaluations_simulated: usize,
    /// The Galerkin basis and its convergence for the modes inside the band (with a beam).
    pub basis: Option<sim::BasisChoice>,
    /// Band edge (Hz) of the recordings at their working rate (0.45 × the lowest).
    pub band_edge_hz: f64,
    /// The working rate the recordings were decimated to ([`rate`]).
    pub working_rate: rate::WorkingRate,
    /// How the drive was read between samples, and why.
    pub drive_reading: ReadingChoice,
    /// The effects forward selection added, in order, each as evaluated when it was added
    /// (its own validation gain against the model before it).
    pub effects: Vec<CandidateOutcome>,
    /// Their candidates (catalogue entries), same order.
    pub final_set: Vec<Candidate>,
    /// Joint fit of the calibration and every selected effect.
    pub final_fit: FitResult,
    /// Validation prediction of the final model.
    pub final_val_pred: Prediction,
    /// Validation NRMSE per channel of the final model.
    pub final_val_nrmse: [f64; 3],
    /// Selection rounds run.
    pub rounds: usize,
    /// What the final model leaves unexplained on the validation recording, if anything.
    pub unexplained: Option<unexplained::Unexplained>,
    /// Assumptions made about missing channels.
    pub assumptions: Vec<String>,
    /// Residual statistics, parameter stability and bounds of the final model
    /// ([`honesty`]).
    pub honesty: honesty::Honesty,
    /// The resonance (Hz) and its 1 σ of a named mount that carries the beam, as the rig shows
    /// it (the coupled mount + beam with the carriage held, [`sim::mount_resonance_hz`]): the
    /// reported `mount_frequency_hz` of that effect. `None` without such a mount.
    pub mount_resonance: Option<(f64, f64)>,
    /// Selection trace: every round's candidates with ΔBIC, validation Δ(−2 ln L), reduction,
    /// allowance and verdict, split-refit spreads and backward checks (`DIAG_SELECT=1` makes
    /// `beamtool diagnose` print it).
    pub trace: Vec<String>,
}

/// How the model read the drive between samples ([`sim::DriveReading`]) and the BIC that chose it.
#[derive(Clone, Debug)]
pub struct ReadingChoice {
    /// The reading of this diagnosis.
    pub chosen: sim::DriveReading,
    /// BIC of its final model on the fit recordings, `Σ_c n_c ln(RSS_c / n_c) + k ln n`
    /// (channels c with n_c samples, n in all, k fitted parameters).
    pub fit_bic: f64,
    /// Each reading's BIC when both were run (empty: the reading changes nothing the
    /// recordings hold, every one decimated or without tip and force).
    pub compared: Vec<(sim::DriveReading, f64)>,
}

impl ReadingChoice {
    /// The reading of `ctx` and the BIC of its final model `reference` ([`fit_bic`]).
    fn of(ctx: &Ctx, reference: &forward::Reference) -> ReadingChoice {
        ReadingChoice {
            chosen: ctx.calib.drive_reading,
            fit_bic: fit_bic(reference),
            compared: Vec::new(),
        }
    }
}

/// The recorded signal of channel `c` (0 base position m, 1 tip deflection tip − drive m,
/// 2 force N) that a residual is normalised by; empty when the channel is missing.
pub fn channel_signal(d: &Prepared, c: usize) -> Vec<f64> {
    let drive = d.drive_as_sampled();
    match c {
        0 => d.base_m.clone().unwrap_or_default(),
        1 => d
            .tip_m
            .as_ref()
            .map(|t| t.iter().zip(drive).map(|(a, b)| a - b).collect())
            .unwrap_or_default(),
        _ => d.force_n.clone().unwrap_or_default(),
    }
}

/// Per-channel NRMSE of a prediction: rms(residual) / rms(signal − mean); the tip signal is the
/// deflection tip − base.
pub fn nrmse(d: &Prepared, pred: &Prediction) -> [f64; 3] {
    let r = residuals(d, pred);
    let mut out = [f64::NAN; 3];
    for c in 0..3 {
        let Some(res) = &r[c] else { continue };
        let sig = channel_signal(d, c);
        let m = sig.iter().sum::<f64>() / sig.len() as f64;
        let s = (sig.iter().map(|x| (x - m).powi(2)).sum::<f64>() / sig.len() as f64).sqrt();
        let e = (res.iter().map(|x| x * x).sum::<f64>() / res.len() as f64).sqrt();
        out[c] = e / s.max(1e-300);
    }
    out
}

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
struct Setup {
    channels: Channels,
    band_edge_hz: f64,
    basis: Option<sim::BasisChoice>,
    calib: effects::Calib,
    /// [`drive_quantum_m`] of the recordings as loaded.
    drive_quantum_m: Option<f64>,
}

/// Step of the counts (m) of the position the drive is read from — `base_pos_m` where
/// recorded, else the command — in the fit recordings as loaded (the largest over them;
/// `None` when none is quantised, [`crate::numeric::stats::quantum`]).
fn drive_quantum_m(fit_data: &[Prepared]) -> Option<f64> {
    fit_data
        .iter()
        .filter_map(|d| crate::numeric::stats::quantum(d.base_m.as_ref().unwrap_or(&d.cmd_m)))
        .reduce(f64::max)
}

/// Refuses recordings without information or that the nominal model cannot simulate; the band
/// edge, the converged Galerkin basis and the calibration parameters; `drive_quantum_m` (of the
/// recordings as loaded, [`drive_quantum_m`]) is kept for the guard.
fn setup(
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
        sim::predict(rig, &sim::Params::default(), d, &mut None)
            .map_err(|e| anyhow::anyhow!("{}: {e:#}", d.name))?;
    }
    let channels = channels_of(fit_data);
    let band_edge_hz = fit_data
        .iter()
        .chain(std::iter::once(validate))
        .map(|d| sim::band_edge_hz(d.dt))
        .fold(f64::INFINITY, f64::min);
    let nyquist_hz = fit_data
        .iter()
        .chain(std::iter::once(validate))
        .map(|d| 0.5 / d.dt)
        .fold(0.0, f64::max);
    let basis = match rig.beam {
        Some(_) => Some(sim::converged_basis(rig, 1.0, band_edge_hz, nyquist_hz)?),
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
struct Calibrated {
    fit: FitResult,
    /// Channel noise scales (residual rms of the first calibration).
    sigma: [f64; 3],
    /// Fit-recording predictions and residuals.
    preds: Vec<Prediction>,
    res: Vec<[Option<Vec<f64>>; 3]>,
    params: sim::Params,
    /// The best tip/force NRMSE of the calibrated nominal model on the fit recordings
    /// ([`best_nrmse`]).
    best_nrmse: f64,
}

/// Predictions and residuals of the calibration `cal` on the fit recordings.
fn calibrated_residuals(
    rig: &Rig,
    fit_data: &[Prepared],
    sigma: [f64; 3],
    calib: &effects::Calib,
    cal: &FitResult,
) -> Result<(Vec<Prediction>, Vec<[Option<Vec<f64>>; 3]>)> {
    let problem = fit::Problem::new(rig, fit_data, sigma, calib, &[], cal.x.clone());
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
fn calibrate(
    rig: &Rig,
    fit_data: &[Prepared],
    calib: &effects::Calib,
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
    let problem = fit::Problem::new(rig, fit_data, sigma, calib, &[], cal.x.clone());
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
fn best_nrmse(fit_data: &[Prepared], preds: &[Prediction]) -> f64 {
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
fn check_stiffness_scale(p: &sim::Params) -> Result<()> {
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
fn check_explained(
    ctx: &Ctx,
    set: &[&Candidate],
    sel: &forward::Selection,
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

/// Facts of the calibrated beam the candidates start from.
struct ModelFacts {
    /// Clamped natural frequencies (Hz).
    freqs_hz: Vec<f64>,
    beam_mass_kg: f64,
    /// EI/L at the root (N·m).
    ei_over_l: f64,
    length_m: f64,
}

/// [`ModelFacts`] of the calibrated model (empty for a carriage-only rig).
fn model_facts(rig: &Rig, p: &sim::Params) -> Result<ModelFacts> {
    let Some(b) = &rig.beam else {
        return Ok(ModelFacts {
            freqs_hz: vec![],
            beam_mass_kg: 0.0,
            ei_over_l: 1.0,
            length_m: 0.0,
        });
    };
    let m = BeamModel::new(
        rig,
        &ModelOptions {
            n_modes: p.n_basis,
            stiffness_scale: p.stiffness_scale,
            damping_ratios: p.zeta,
            ..Default::default()
        },
    )?;
    let freqs_hz: Vec<f64> = m
        .clamped_modes()?
        .omega_rad_s
        .iter()
        .map(|w| w / (2.0 * std::f64::consts::PI))
        .collect();
    let prof = rig.profile()?;
    Ok(ModelFacts {
        freqs_hz,
        beam_mass_kg: m.beam_mass_kg,
        ei_over_l: b.youngs_modulus_pa * p.stiffness_scale * prof.inertia(0.0) / b.length_m,
        length_m: b.length_m,
    })
}

/// Pitches of the force residual's ripple scan the cogging fit starts from (the best local
/// maxima, [`locate::ripple_peaks`]).
pub const COGGING_PITCH_STARTS: usize = 3;

/// Starting values of the candidates: friction and cogging from the force residual, the peak
/// deflection and speed, the calibrated model's facts.
fn start_hints(rig: &Rig, fit_data: &[Prepared], cal: &Calibrated, m: &ModelFacts) -> StartHints {
    let (mut fr_r, mut fr_v, mut fr_y, mut fr_m) = (vec![], vec![], vec![], vec![]);
    let mut peak_def: f64 = 0.0;
    let mut speed: f64 = 0.0;
    for (d, r) in fit_data.iter().zip(&cal.res) {
        let drive = d.drive_as_sampled();
        let v = locate::velocity(drive, d.dt);
        speed = speed.max(v.iter().fold(0.0f64, |a, x| a.max(x.abs())));
        if let Some(f) = &r[2] {
            fr_r.extend(f.iter().copied());
            fr_m.extend(v.iter().map(|x| x.abs() > 1e-4));
            fr_v.extend(v);
            fr_y.extend(drive.iter().copied());
        }
        if let Some(p) = d.peak_deflection_m() {
            peak_def = peak_def.max(p);
        }
    }
    let friction = locate::friction_ls(&fr_r, &fr_v);
    let rips = locate::ripple_peaks(&fr_r, &fr_y, &fr_m, COGGING_PITCH_STARTS);
    let rip = rips.first().copied().unwrap_or((0.01, 0.0, 0.0, 0.0));
    StartHints {
        beam_mass_kg: m.beam_mass_kg,
        ei_over_l: m.ei_over_l,
        f2_hz: m.freqs_hz.get(1).copied().unwrap_or(10.0),
        rate_hz: 1.0 / fit_data[0].dt,
        peak_deflection_m: peak_def,
        friction,
        cogging: (rip.1, rip.2, rip.0),
        cogging_pitches_m: rips.iter().map(|p| p.0).collect(),
        mode_freqs_hz: m.freqs_hz.clone(),
        speed_m_s: speed,
        zeta1: cal.params.zeta.map_or(rig.damping_ratios().0, |z| z.0),
        length_m: m.length_m,
        carriage_mass_kg: rig.base.mass_kg,
    }
}

/// Runs the whole diagnosis; every stage is reported to `progress` (a stage name, then
/// `advance(step, total)` over the estimated number of stages).
///
/// Steps: [`setup`] (refuse recordings without information), [`calibrate`], [`locate::locate`],
/// the candidate catalogue from [`start_hints`], [`forward::select_forward`], then
/// [`conclude`] (honest uncertainty, what stays unexplained).
///
/// Errors: recordings the rig cannot simulate (tip channel without a beam, …), a rig the model
/// refuses, a validation recording whose channels differ from every fit recording's, recordings
/// without information.
pub fn diagnose(
    rig: &Rig,
    fit_data: &[Prepared],
    validate: &Prepared,
    progress: &mut dyn crate::progress::Progress,
) -> Result<Diagnosis> {
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        check_information(d)?;
        check_units(rig, d)?;
    }
    let saturated = saturation_words(fit_data, validate);
    for w in &saturated {
        progress.note(w);
    }
    let drive_quantum_m = drive_quantum_m(fit_data);
    let working_rate = rate::choose(fit_data, validate);
    let (fit_w, val_w) = rate::to_working_rate(&working_rate, fit_data, validate);
    if let Some(w) = rate::words(&working_rate) {
        progress.note(&w);
    }
    let (fit_data, validate) = (&fit_w[..], &val_w);
    let su = setup(rig, fit_data, validate, drive_quantum_m)?;
    if !drive_reading_matters(fit_data, validate) {
        let mut d = diagnose_with(rig, fit_data, validate, &su, working_rate, progress)?;
        d.assumptions.extend(saturated);
        return Ok(d);
    }
    // both readings of the drive between samples, side by side
    progress.note(
        "the drive between samples is read both ways (piecewise linear, smooth); the recordings choose",
    );
    let smooth = Setup {
        calib: su.calib.with_reading(sim::DriveReading::FourthOrder),
        ..su.clone()
    };
    // the second reading takes the spare core, so the Jacobians of both run on their own
    let _core = crate::numeric::cores::take();
    let (linear, smooth) = std::thread::scope(|s| {
        let other = s.spawn(|| {
            diagnose_with(
                rig,
                fit_data,
                validate,
                &smooth,
                working_rate.clone(),
                &mut crate::progress::Silent,
            )
        });
        let linear = diagnose_with(rig, fit_data, validate, &su, working_rate.clone(), progress);
        (linear, other.join())
    });
    let smooth = smooth.map_err(|_| anyhow::anyhow!("the smooth-drive diagnosis panicked"))?;
    let mut chosen = choose_reading(linear?, smooth);
    if let Some(words) = chosen.assumptions.last() {
        progress.note(words);
    }
    chosen.assumptions.extend(saturated);
    Ok(chosen)
}

/// The channels held at a sensor's rail, in words (an assumption of the diagnosis: those
/// samples are left out, [`saturation`]), and those that gave no reading for a while.
fn saturation_words(fit_data: &[Prepared], validate: &Prepared) -> Vec<String> {
    let mut out = Vec::new();
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        for (c, r) in d.rails.iter().enumerate() {
            if r.runs.is_empty() {
                continue;
            }
            out.push(format!(
                "{} of {} is held at its sensor's rail ({}) on {} samples ({:.1} %): a clipped reading says only \"at least this far\"; those samples are left out of every residual",
                fit::CHANNEL_NAMES[c],
                d.name,
                r.values_words(),
                r.samples(),
                100.0 * r.samples() as f64 / d.cmd_m.len().max(1) as f64
            ));
        }
        for (c, g) in d
            .gaps
            .iter()
            .enumerate()
            .filter(|(_, g)| !g.runs.is_empty())
        {
            out.push(format!(
                "{} of {} has no reading on {} samples ({:.1} %, {} run(s)): bridged by a straight line and left out of every residual",
                fit::CHANNEL_NAMES[c],
                d.name,
                g.samples(),
                100.0 * g.samples() as f64 / d.cmd_m.len().max(1) as f64,
                g.runs.len()
            ));
        }
    }
    out
}

/// Whether the model's reading of the drive between samples changes what the recordings hold:
/// some recording at its own rate (a decimated one is read band-limited, [`rate`]) with a tip
/// or a force channel.
fn drive_reading_matters(fit_data: &[Prepared], validate: &Prepared) -> bool {
    fit_data
        .iter()
        .chain(std::iter::once(validate))
        .any(|d| d.cmd_identity_m.is_none() && (d.tip_m.is_some() || d.force_n.is_some()))
}

/// The diagnosis of the reading whose final model has the lower BIC on the fit recordings
/// (`Σ_c n_c ln(RSS_c / n_c) + k ln n`, the noise of every channel profiled out, so the two
/// readings' own whitening does not matter); the piecewise-linear one when the smooth
/// reading's diagnosis failed. Both readings have the same parameters, so the BIC's penalty
/// only counts the effects each one needed. The choice and its margin join the assumptions.
fn choose_reading(linear: Diagnosis, smooth: Result<Diagnosis>) -> Diagnosis {
    let smooth = match smooth {
        Ok(s) => s,
        Err(e) => {
            let mut linear = linear;
            linear.assumptions.push(format!(
                "the drive read {} (the smooth reading failed: {e:#})",
                linear.drive_reading.chosen.words()
            ));
            return linear;
        }
    };
    let compared = vec![
        (linear.drive_reading.chosen, linear.drive_reading.fit_bic),
        (smooth.drive_reading.chosen, smooth.drive_reading.fit_bic),
    ];
    let (mut chosen, other) = if smooth.drive_reading.fit_bic < linear.drive_reading.fit_bic {
        (smooth, linear)
    } else {
        (linear, smooth)
    };
    chosen.assumptions.push(format!(
        "the drive read {} (BIC on the fit recordings {:.1} lower than read {})",
        chosen.drive_reading.chosen.words(),
        other.drive_reading.fit_bic - chosen.drive_reading.fit_bic,
        other.drive_reading.chosen.words(),
    ));
    chosen.drive_reading.compared = compared;
    chosen
}

/// One diagnosis with the drive read as `su.calib` says ([`diagnose`]).
fn diagnose_with(
    rig: &Rig,
    fit_data: &[Prepared],
    validate: &Prepared,
    su: &Setup,
    working_rate: rate::WorkingRate,
    progress: &mut dyn crate::progress::Progress,
) -> Result<Diagnosis> {
    let mut budget = Budget::for_samples(fit_data.iter().map(|d| d.cmd_m.len()).sum());
    let total_steps = 12 + 3;
    let cal = calibrate(rig, fit_data, &su.calib, &mut budget, progress, total_steps)?;
    let facts = model_facts(rig, &cal.params)?;
    let location = locate::locate(fit_data, &cal.preds, &facts.freqs_hz);
    let cands: Vec<Candidate> =
        catalogue(rig, &su.channels, &start_hints(rig, fit_data, &cal, &facts));
    let ctx = Ctx {
        rig,
        fit_data,
        validate,
        sigma: cal.sigma,
        calib: &su.calib,
        model_freqs: &facts.freqs_hz,
        drive_quantum_m: su.drive_quantum_m,
        tests: cands.len() * forward::MAX_EFFECTS,
        trace: Default::default(),
    };
    // the reference of the first round: the calibrated nominal model
    let nominal = ctx.reference(&[], cal.fit.clone()).ok_or_else(|| {
        anyhow::anyhow!("the calibrated nominal model cannot simulate the validation recording")
    })?;
    let val_nrmse_nominal = nominal.val_nrmse;
    let vpred0 = nominal.vpred.clone();
    let mut sel = forward::select_forward(&ctx, &cands, nominal.clone(), &mut budget, progress, 2);
    lookalike::resolve(&ctx, &cands, &mut sel, &mut budget);
    backward::eliminate(&ctx, &cands, &mut sel, &mut budget);
    forward::structural_pair_as_crack(&ctx, &cands, &mut sel, nominal, &mut budget);
    let set: Vec<&Candidate> = sel.chosen.iter().map(|&k| &cands[k]).collect();
    let explained = check_explained(&ctx, &set, &sel, cal.best_nrmse)?;
    let earlier = Earlier {
        location,
        val_nrmse_nominal,
        val_pred_nominal: vpred0,
        basis: su.basis.clone(),
        band_edge_hz: su.band_edge_hz,
        working_rate,
    };
    let mut d = conclude(&ctx, &cands, sel, cal.fit, earlier, &mut budget, progress);
    d.assumptions.extend(explained);
    Ok(d)
}

/// Long-run 1-σ of the calibration `cal` and the final model `reference` (replacing their
/// linearised σ), raised to the recordings' disagreement and widened by the discretisation
/// and, without `base_pos_m`, the base-motion assumption ([`honesty`]); the stability of every
/// effect's parameters between the fit recordings, and the residual statistics before and
/// after; and what the significance test of the final model reads
/// ([`forward::NullEvidence`]).
fn measure_final(
    ctx: &Ctx,
    cands: &[Candidate],
    set: &[&Candidate],
    cal: &mut FitResult,
    reference: &mut forward::Reference,
    earlier: &Earlier,
    budget: &mut Budget,
) -> (honesty::Honesty, forward::NullEvidence) {
    let (rig, fit_data, sigma, calib) = (ctx.rig, ctx.fit_data, ctx.sigma, ctx.calib);
    budget.spend(honesty::long_run_std(rig, fit_data, sigma, calib, &[], cal));
    budget.spend(honesty::long_run_std(
        rig,
        fit_data,
        sigma,
        calib,
        set,
        &mut reference.fit,
    ));
    let (refits, used) = honesty::stability(
        rig,
        fit_data,
        sigma,
        calib,
        set,
        &reference.fit,
        budget.share(3),
    );
    budget.spend(used);
    let long_run = reference.fit.std.clone();
    let spread = honesty::spread_std(&refits.values);
    honesty::add_spread_std(&mut reference.fit, &spread);
    // the model's stated accuracy (Type B) belongs to what the recordings give; the
    // alternatives' changes (added in quadrature after it) do not
    honesty::add_model_accuracy_std(rig, fit_data, sigma, calib, set, &mut reference.fit);
    let std = reference.fit.std.clone();
    let alternatives = widen_for_model_form(ctx, cands, set, &mut reference.fit, budget);
    let evidence = forward::NullEvidence { std, alternatives };
    let h = honesty::Honesty {
        nominal: honesty::residual_stats(&residuals(ctx.validate, &earlier.val_pred_nominal)),
        after: honesty::residual_stats(&reference.vres),
        stability: refits.stability,
        at_bound: honesty::at_bound(set, &reference.fit, calib.len()),
        beyond_band: Vec::new(),
        degrees_of_freedom: honesty::effective_dof(
            &long_run,
            &spread,
            refits.values.len(),
            &reference.fit.std,
        ),
    };
    (h, evidence)
}

/// Widens the 1-σ of the final model `f` (calibration + `set`) by what the model's form leaves
/// open: the discretisation, the drive's reading between samples and, without `base_pos_m`,
/// the base-motion assumption, and by the model's stated accuracy carried to every effect
/// parameter read from the response's size ([`honesty`]). Returns the values of every alternative's refit
/// ([`honesty::Alternative`]).
fn widen_for_model_form(
    ctx: &Ctx,
    cands: &[Candidate],
    set: &[&Candidate],
    f: &mut FitResult,
    budget: &mut Budget,
) -> Vec<Vec<f64>> {
    let (rig, fit_data, sigma, calib) = (ctx.rig, ctx.fit_data, ctx.sigma, ctx.calib);
    let mut alternatives = Vec::new();
    let mut keep = |alt: honesty::Alternative, budget: &mut Budget| {
        budget.spend(alt.evaluations);
        alternatives.extend(alt.values);
    };
    if !set.is_empty() {
        let share = budget.share(3);
        let alt = honesty::add_basis_std(rig, fit_data, sigma, calib, set, f, share);
        keep(alt, budget);
    }
    let share = budget.share(3);
    let alt = honesty::add_drive_interpolation_std(rig, fit_data, sigma, calib, set, f, share);
    keep(alt, budget);
    if let Some(servo) = honesty::identity_servo(cands, set, fit_data) {
        let share = budget.share(2);
        let alt =
            honesty::add_base_assumption_std(rig, fit_data, sigma, calib, set, &servo, f, share);
        keep(alt, budget);
    }
    if !set.is_empty() {
        budget.spend(honesty::add_response_accuracy_std(
            rig, fit_data, sigma, calib, set, f,
        ));
    }
    alternatives
}

/// What the steps before selection found, carried into the [`Diagnosis`].
struct Earlier {
    location: locate::Location,
    val_nrmse_nominal: [f64; 3],
    val_pred_nominal: Prediction,
    basis: Option<sim::BasisChoice>,
    band_edge_hz: f64,
    working_rate: rate::WorkingRate,
}

/// The stiffness scale the final model `f` of `set` applies to EI where a structural effect
/// fits along the f1-preserving path ([`Diagnosis::final_applied_stiffness_scale`]); `None`
/// where it is the reported one.
fn applied_stiffness_scale(ctx: &Ctx, set: &[&Candidate], f: &FitResult) -> Option<f64> {
    let applied = fit::params_of_values(ctx.rig, ctx.calib, set, &f.values).stiffness_scale;
    let reported = ctx
        .calib
        .defs
        .iter()
        .position(|d| d.name == "stiffness_scale")
        .map(|i| f.values[i])?;
    ((applied / reported - 1.0).abs() > 1e-9).then_some(applied)
}

/// Per calibration parameter of `cal`, why the recordings do not identify it (`None`:
/// identified; [`effects::calibration_unidentified`]).
fn unidentified_calibration(calib: &effects::Calib, cal: &FitResult) -> Vec<Option<String>> {
    calib
        .defs
        .iter()
        .zip(cal.values.iter().zip(&cal.std))
        .map(|(def, (&v, &s))| effects::calibration_unidentified(def, v, s))
        .collect()
}

/// The diagnosis from a finished selection: long-run 1-σ of the calibration and the final
/// model, parameter stability, what stays unexplained.
fn conclude(
    ctx: &Ctx,
    cands: &[Candidate],
    mut sel: forward::Selection,
    mut cal: FitResult,
    earlier: Earlier,
    budget: &mut Budget,
    progress: &mut dyn crate::progress::Progress,
) -> Diagnosis {
    let (fit_data, sigma) = (ctx.fit_data, ctx.sigma);
    let total_steps = sel.step + 1;
    stage(
        progress,
        sel.step,
        total_steps,
        "uncertainty and stability of the final model",
    );
    let honesty = identified_final(ctx, cands, &mut sel, &mut cal, &earlier, budget, progress);
    let forward::Selection {
        chosen,
        outcomes: chosen_outcomes,
        reference,
        rounds,
        ..
    } = sel;
    let final_set: Vec<Candidate> = chosen.iter().map(|&k| cands[k].clone()).collect();
    let mut unexplained = unexplained::assess(
        ctx.validate,
        &reference.vres,
        &reference.vpred,
        ctx.model_freqs,
    );
    if let (Some(u), Some(o)) = (unexplained.as_mut(), closest_failed(&rounds)) {
        u.closest_catalogue_effect = Some(format!("{}: {}", o.id, o.reason));
    }
    let set: Vec<&Candidate> = final_set.iter().collect();
    let mount_resonance = mount_resonance(ctx, &set, &reference.fit);
    let outcomes = rounds.first().cloned().unwrap_or_default();
    let selected = outcomes
        .iter()
        .position(|o| o.passed && chosen.first() == Some(&o.cand_index));
    stage(progress, total_steps, total_steps, "done");
    let drive_reading = ReadingChoice::of(ctx, &reference);
    Diagnosis {
        final_applied_stiffness_scale: applied_stiffness_scale(ctx, &set, &reference.fit),
        calibration_unidentified: unidentified_calibration(ctx.calib, &cal),
        final_calibration_unidentified: unidentified_calibration(ctx.calib, &reference.fit),
        effect: chosen
            .first()
            .map_or_else(|| "none".to_string(), |&k| cands[k].id.to_string()),
        selected,
        calibration: cal,
        sigma,
        location: earlier.location,
        val_nrmse_nominal: earlier.val_nrmse_nominal,
        val_pred_nominal: earlier.val_pred_nominal,
        candidates: outcomes,
        validate: ctx.validate.clone(),
        evaluations: budget.spent,
        evaluations_simulated: budget.simulated(),
        basis: earlier.basis,
        band_edge_hz: earlier.band_edge_hz,
        effects: chosen_outcomes,
        final_set,
        final_fit: reference.fit,
        final_val_pred: reference.vpred,
        final_val_nrmse: reference.val_nrmse,
        rounds: rounds.len(),
        unexplained,
        assumptions: assumptions(fit_data, ctx.validate)
            .into_iter()
            .chain(rate::words(&earlier.working_rate))
            .collect(),
        working_rate: earlier.working_rate,
        drive_reading,
        honesty,
        mount_resonance,
        trace: ctx.trace.take(),
    }
}

/// BIC on the fit recordings of `reference`: `Σ_c n_c ln(RSS_c / n_c) + k ln n`
/// ([`ReadingChoice::fit_bic`]).
fn fit_bic(reference: &forward::Reference) -> f64 {
    let n: usize = reference.n.iter().sum();
    crate::numeric::stats::neg2ll(&reference.rss, &reference.n)
        + reference.fit.x.len() as f64 * (n.max(1) as f64).ln()
}

/// The honest measurements of the final model ([`measure_final`]), after dropping, one at a
/// time, every effect they show the recordings do not identify
/// ([`forward::unidentified_in_final`], [`drop_effect`]), the selection resumed after each
/// one removed ([`forward::resume_after_drop`], with the look-alike and backward checks when it
/// adds one); `cal` and `sel.reference` carry the honest 1 σ on return, a loop's frequency beyond the recordings' band without one
/// ([`honesty::beyond_band`], after the identification check, which it does not change).
fn identified_final(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut forward::Selection,
    cal: &mut FitResult,
    earlier: &Earlier,
    budget: &mut Budget,
    progress: &mut dyn crate::progress::Progress,
) -> honesty::Honesty {
    loop {
        let set: Vec<&Candidate> = sel.chosen.iter().map(|&k| &cands[k]).collect();
        let (mut cal_h, mut reference_h) = (cal.clone(), sel.reference.clone());
        let (h, evidence) = measure_final(
            ctx,
            cands,
            &set,
            &mut cal_h,
            &mut reference_h,
            earlier,
            budget,
        );
        match forward::unidentified_in_final(&set, &reference_h.fit, &evidence, ctx.calib.len()) {
            Some((i, why)) if drop_effect(ctx, cands, sel, i, &why, budget) => {
                if sel.chosen.len() < set.len()
                    && forward::resume_after_drop(ctx, cands, sel, budget, progress)
                {
                    lookalike::resolve(ctx, cands, sel, budget);
                    backward::eliminate(ctx, cands, sel, budget);
                }
            }
            _ => {
                *cal = cal_h;
                sel.reference = reference_h;
                let rate_hz = ctx.fit_data.iter().map(|d| 1.0 / d.dt).fold(0.0, f64::max);
                let fit = &mut sel.reference.fit;
                let beyond_band = honesty::beyond_band(&set, fit, ctx.calib.len(), rate_hz);
                return honesty::Honesty { beyond_band, ..h };
            }
        }
    }
}

/// Drops effect `i` (its index in `sel.chosen`) from the final model, which the recordings
/// do not identify (`why`, [`forward::unidentified_in_final`]), or puts its nested simpler form
/// in its place ([`simpler_form`]: a cubic clamp whose cubic term is not identified is a linear
/// root spring, whose stiffness may well be): the rest refitted from the joint optimum (the
/// simpler form from the parameters it shares; for the last effect chosen, from the rest's own
/// optimum of the round before it where that fits better), its outcome in the round that chose it marked
/// failed with `why`. False (nothing changed) when the result cannot be simulated.
fn drop_effect(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut forward::Selection,
    i: usize,
    why: &str,
    budget: &mut Budget,
) -> bool {
    let k = sel.chosen[i];
    let off = ctx.calib.len()
        + sel.chosen[..i]
            .iter()
            .map(|&c| cands[c].params.len())
            .sum::<usize>();
    let simpler = simpler_form(cands, &sel.rounds, k);
    let x = &sel.reference.fit.x;
    let mut warm: Vec<f64> = x.iter().take(off).copied().collect();
    if let Some((s, _)) = &simpler {
        for q in &cands[*s].params {
            let j = cands[k].params.iter().position(|d| d.name == q.name);
            warm.push(j.map_or(q.repr(q.starts[0]), |j| x[off + j]));
        }
    }
    warm.extend(x.iter().skip(off + cands[k].params.len()));
    let mut chosen = sel.chosen.clone();
    match &simpler {
        Some((s, _)) => chosen[i] = *s,
        None => {
            chosen.remove(i);
        }
    }
    let set: Vec<&Candidate> = chosen.iter().map(|&c| &cands[c]).collect();
    let mut warm = nalgebra::DVector::from_vec(warm);
    // the last effect dropped: the rest's own optimum from the round before it came in is the
    // other warm point (the joint optimum without it may lie far from any optimum of the rest)
    if simpler.is_none() && i > 0 && i + 1 == sel.chosen.len() {
        let before = &sel.outcomes[i - 1].fit.x;
        let cost = |x: &nalgebra::DVector<f64>| ctx.fit_problem(&set, x.clone()).cost_at(x);
        if before.len() == warm.len() && cost(before) < cost(&warm) {
            warm = before.clone();
        }
    }
    let f = ctx.fit(&set, Some(&warm), budget.share(2));
    budget.spend(f.evaluations);
    let Some(reference) = ctx.reference(&set, f) else {
        return false;
    };
    ctx.trace(format!("final model: {} dropped, {why}", cands[k].id));
    sel.reference = reference;
    sel.chosen = chosen;
    match simpler {
        Some((_, mut o)) => {
            o.passed = true;
            o.reason = format!("in place of {}: {why}", cands[k].id);
            if let Some(slot) = sel.outcomes.iter_mut().find(|e| e.cand_index == k) {
                *slot = o;
            }
        }
        None => {
            sel.outcomes.retain(|o| o.cand_index != k);
            sel.dropped.push(cands[k].id);
        }
    }
    for o in sel.rounds.iter_mut().flatten() {
        if o.cand_index == k && o.passed {
            o.passed = false;
            o.reason = why.to_string();
        }
    }
    true
}

/// The catalogue effect closest to an unexplained residual: of the last round's failed
/// candidates, one the recordings placed elsewhere (a resonance at the tip sensor, a spring
/// along the beam: that says most of what the residual is), else the best that failed.
fn closest_failed(rounds: &[Vec<CandidateOutcome>]) -> Option<&CandidateOutcome> {
    let last = rounds.last()?;
    last.iter()
        .find(|o| !o.passed && o.unplaced.is_some())
        .or_else(|| last.iter().find(|o| !o.passed))
}

/// The nested simpler form of chosen effect `k` — a linear root spring for a cubic clamp (the
/// cubic term at zero) — with its outcome in the round of `rounds` that chose `k`: its
/// catalogue index and that outcome. `None` for other effects, or when the simpler form was not
/// fitted then or did not pass the guard itself (a root spring within the model's accuracy,
/// or placed along the beam, does not come back in through a cubic clamp whose cubic term the
/// final model does not identify: second simulator, seed 3, case14, docs/diagnose.md,
/// session 29), or when another effect that passed in that round gained more on validation
/// than the root spring: the round's choice made without the cubic clamp would not be the
/// root spring, and the selection resumes instead (second simulator, seed 20, case10: a 5 g
/// tip mass, Δval −809 in round 1 against the root spring's −677, was reported as the root
/// spring that replaced an unidentified cubic clamp).
fn simpler_form(
    cands: &[Candidate],
    rounds: &[Vec<CandidateOutcome>],
    k: usize,
) -> Option<(usize, CandidateOutcome)> {
    use crate::effect::Effect;
    if cands[k].id != Effect::CubicStiffness {
        return None;
    }
    let s = cands.iter().position(|c| c.id == Effect::RootCompliance)?;
    let round = rounds
        .iter()
        .find(|r| r.iter().any(|o| o.cand_index == k && o.passed))?;
    let o = round
        .iter()
        .find(|o| o.cand_index == s && o.passed)?
        .clone();
    // the round's choice made again without the cubic clamp: the root spring only when it
    // would have been chosen (the largest validation gain of the rest that passed)
    let beaten = round
        .iter()
        .any(|x| x.passed && x.cand_index != k && x.cand_index != s && x.delta_val < o.delta_val);
    (!beaten).then_some((s, o))
}

/// The resonance of a coupled mount among `set` as the rig shows it, with 1 σ, for the final
/// fit `f` ([`sim::mount_resonance_hz`]); the σ moves the mount's frequency and mass by their
/// own 1 σ each and adds the changes in quadrature (NaN where one is not identified). `None`
/// without a mount that carries the beam.
pub(crate) fn mount_resonance(ctx: &Ctx, set: &[&Candidate], f: &FitResult) -> Option<(f64, f64)> {
    let p = ctx.fit_problem(set, f.x.clone()).params_of(&f.x);
    let dt = ctx.fit_data.first()?.dt;
    let at = |q: &sim::Params| sim::mount_resonance_hz(ctx.rig, q, dt);
    let resonance = at(&p)?;
    let std_of = |name: &str| {
        f.names
            .iter()
            .position(|n| *n == name)
            .map_or(f64::NAN, |i| f.std[i])
    };
    let (fm, zm) = p.mount?;
    let mut moved_f = p.clone();
    moved_f.mount = Some((fm + std_of("mount_frequency_hz"), zm));
    let mut moved_m = p.clone();
    moved_m.mount_mass_kg += std_of("mount_mass_kg");
    let change = |q: &sim::Params| at(q).map_or(f64::NAN, |g| g - resonance);
    Some((resonance, change(&moved_f).hypot(change(&moved_m))))
}

/// Reports a stage `name` as step `step` of `total`.
pub(crate) fn stage(
    progress: &mut dyn crate::progress::Progress,
    step: usize,
    total: usize,
    name: &str,
) {
    progress.stage(name);
    progress.advance(step as u64, total as u64);
}

/// Alternative forms of one effect (the servo loop's orders, the mount's forms, the two
/// orientations) describe the same physics: of those that pass, only the one with the lowest
/// ΔBIC on the fit recordings stays a contender (the order is chosen by the information
/// criterion, not by the validation recording).
pub(super) fn keep_lowest_bic_form(outs: &mut [CandidateOutcome]) {
    for i in 0..outs.len() {
        if !outs[i].passed {
            continue;
        }
        let best = outs
            .iter()
            .filter(|o| o.passed && o.id == outs[i].id)
            .map(|o| o.delta_bic)
            .fold(f64::INFINITY, f64::min);
        if outs[i].delta_bic > best {
            outs[i].passed = false;
            outs[i].reason = format!(
                "another form of {} has the lower BIC (ΔBIC {:.1} against {:.1})",
                outs[i].id, best, outs[i].delta_bic
            );
        }
    }
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
fn check_information(d: &Prepared) -> Result<()> {
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
fn check_units(rig: &Rig, d: &Prepared) -> Result<()> {
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

pub use forward::MAX_EFFECTS;

/// Explicit assumptions the diagnosis had to make about the recordings.
fn assumptions(fit_data: &[Prepared], validate: &Prepared) -> Vec<String> {
    let mut v = Vec::new();
    let all: Vec<&Prepared> = fit_data.iter().chain(std::iter::once(validate)).collect();
    let no_base: Vec<&str> = all
        .iter()
        .filter(|d| d.base_m.is_none() && d.drive_m.is_none())
        .map(|d| d.name.as_str())
        .collect();
    if !no_base.is_empty() {
        v.push(format!(
            "base_pos_m not recorded in {}: the carriage is assumed to follow base_cmd_m exactly unless servo_lag is named (then it follows the fitted loop)",
            no_base.join(", ")
        ));
    }
    let no_cmd: Vec<&str> = all
        .iter()
        .filter(|d| d.base_m.is_none() && d.drive_m.is_some())
        .map(|d| d.name.as_str())
        .collect();
    if !no_cmd.is_empty() {
        v.push(format!(
            "base_cmd_m not recorded in {}: the measured base drives the model and servo_lag cannot be tested",
            no_cmd.join(", ")
        ));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effect::Effect;

    fn cand(id: Effect) -> Candidate {
        Candidate {
            id,
            words: "",
            orientation: None,
            params: vec![],
        }
    }

    fn row(cand_index: usize, id: Effect, passed: bool) -> CandidateOutcome {
        let mut o = forward::tests::outcome(-100.0, passed, "");
        o.cand_index = cand_index;
        o.id = id;
        o
    }

    #[test]
    fn a_cubic_clamp_falls_back_to_the_root_spring_fitted_in_its_round() {
        let cands = [
            cand(Effect::ServoLag),
            cand(Effect::RootCompliance),
            cand(Effect::CubicStiffness),
        ];
        // round 1 chose the loop; round 2 chose the cubic clamp beside a (passing) root spring
        let rounds = vec![
            vec![
                row(0, Effect::ServoLag, true),
                row(1, Effect::RootCompliance, false),
            ],
            vec![
                row(2, Effect::CubicStiffness, true),
                row(1, Effect::RootCompliance, true),
            ],
        ];
        let (s, o) = simpler_form(&cands, &rounds, 2).expect("a simpler form");
        assert_eq!((s, o.id, o.passed), (1, Effect::RootCompliance, true));
        // other effects have none; nor does a clamp whose round never fitted the spring
        assert!(simpler_form(&cands, &rounds, 0).is_none());
        let alone = vec![vec![row(2, Effect::CubicStiffness, true)]];
        assert!(simpler_form(&cands, &alone, 2).is_none());
        // nor one whose root spring failed the guard in that round (within the model's
        // accuracy): the clamp is dropped, not replaced by it
        let refused = vec![vec![
            row(2, Effect::CubicStiffness, true),
            row(1, Effect::RootCompliance, false),
        ]];
        assert!(simpler_form(&cands, &refused, 2).is_none());
        // nor one whose round had another effect that passed with a larger validation gain
        // than the spring (Δ(−2lnL) −809 against −677): the round chosen again without the
        // clamp would not take the spring
        let mut tip = row(3, Effect::TipMass, true);
        tip.delta_val = -809.0;
        let mut spring = row(1, Effect::RootCompliance, true);
        spring.delta_val = -677.0;
        let mut clamp = row(2, Effect::CubicStiffness, true);
        clamp.delta_val = -951.0;
        let beaten = vec![vec![clamp.clone(), tip.clone(), spring.clone()]];
        assert!(simpler_form(&cands, &beaten, 2).is_none());
        // the same round with the spring ahead of the tip mass keeps it
        tip.delta_val = -600.0;
        let ahead = vec![vec![clamp, tip, spring]];
        assert_eq!(simpler_form(&cands, &ahead, 2).map(|(s, _)| s), Some(1));
    }
}
