//! Model-discrepancy diagnosis: calibrate the nominal model, locate the residual, fit a
//! catalogue of candidate physics, select with a guard against false discovery, report.
//!
//! The layout follows the diagnosis:
//! - [`load`]: reading and preparing a recording;
//! - [`model`]: the augmented model the diagnosis fits (nominal model of paper §2 + every
//!   extension), one file per block of the signal chain (servo, carriage, mount, beam, sensor),
//!   composed by [`model::predict()`];
//! - [`effects`]: the candidate catalogue with physical parameters;
//! - [`fit`]: Levenberg–Marquardt ([`crate::numeric::lm`]) on whitened residuals, parameter
//!   uncertainties ([`fit_problem`]: the least-squares problem, [`fit_starts`]: its starts);
//! - [`calibrate`]: the recordings checked and the nominal model calibrated;
//! - [`locate`]: where/when/at which frequency the residual is structured;
//! - [`saturation`]: samples a sensor held at its rail, left out of every residual;
//! - [`scale_bands`]: a tip sensor's scale on the deflection must scale every mode band alike;
//! - [`selection`]: which candidates are named, in one folder by job: the decision rule
//!   ([`selection::guard`]: BIC + validation + model-form allowance + whiteness + significance),
//!   the evidence measures, the rounds, pairs, placement, look-alikes
//!   ([`selection::lookalike`]) and the backward step ([`selection::backward`]);
//! - [`bootstrap`]: a parametric bootstrap of the calibrated no-effect model (the decision
//!   rule checked on nulls made from the user's own recordings);
//! - [`conclude`]: the final model measured, its effects required to be identified, the
//!   [`Diagnosis`] assembled;
//! - [`report`]: JSON, words, SVG plots; [`proof`]: the own-generator proof; [`honesty`]:
//!   long-run 1-σ, parameter stability, residual statistics of the final model; [`lengths`]:
//!   the diagnosis of a length series;
//! - the commands (`diagnose`, `diagnose-proof`, `diagnose-lengths`) live in `crate::cli::diagnose`;
//!
//! Where a recording is analysed at its own rate with a tip or force channel, the whole
//! diagnosis runs twice in parallel, the drive read piecewise linear and smooth between samples
//! ([`model::DriveReading`]), and the final model with the lower BIC on the fit recordings is
//! kept ([`ReadingChoice`]).
//!
//! Every fit of one diagnosis draws on one budget of model evaluations
//! ([`WORK_BUDGET_SAMPLE_EVALUATIONS`](selection::WORK_BUDGET_SAMPLE_EVALUATIONS) divided by the
//! fit recordings' samples), never on the clock, so the same recordings give the same answer on
//! any machine.

pub mod bootstrap;
pub mod calibrate;
pub mod conclude;
pub mod effects;
pub mod fit;
pub mod fit_problem;
pub mod fit_starts;
pub mod honesty;
pub mod lengths;
pub mod load;
pub mod locate;
pub mod model;
pub mod proof;
pub mod rate;
pub mod report;
pub mod saturation;
pub mod scale_bands;
pub mod selection;
pub mod unexplained;

pub use calibrate::{MAX_CALIBRATED_NRMSE, MAX_STROKE_M, MIN_DURATION_S, MIN_SAMPLES};
pub use selection::MAX_EFFECTS;

use crate::model::{BeamModel, ModelOptions, Rig};
use anyhow::Result;
use calibrate::{
    calibrate, check_explained, check_information, check_units, drive_quantum_m, setup, Calibrated,
    Setup,
};
use conclude::{conclude, fit_bic, Earlier};
use effects::{catalogue, Candidate, StartHints};
use fit::{residuals, FitResult};
use model::{Prediction, Prepared};
use selection::{Budget, Ctx};

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
    /// it (a mount that a loose tip sensor explains as well; [`selection::guard`] condition 8), if so.
    pub unplaced: Option<String>,
    /// The effect the recordings cannot tell this one from, if so ([`selection::lookalike`]).
    pub look_alike: Option<selection::lookalike::LookAlike>,
    /// It failed only condition 6 of [`selection::guard`]: it removes part, not most, of the structured
    /// residual — what the first effect of a pair does beside the second ([`selection`]'s
    /// pair step).
    pub partial: bool,
    /// It failed only the calibration-matter rule, as a coupled mount whose resonance lies
    /// beside a model mode: apart by more than its half-power half-width (and 2 σ), within the
    /// full width. Such a split-off resonance is judged against a local compliance of the beam
    /// instead (`selection::placement::judge_mounts_beside_modes`).
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
    pub basis: Option<model::BasisChoice>,
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
    /// it (the coupled mount + beam with the carriage held, [`model::mount_resonance_hz`]): the
    /// reported `mount_frequency_hz` of that effect. `None` without such a mount.
    pub mount_resonance: Option<(f64, f64)>,
    /// Selection trace: every round's candidates with ΔBIC, validation Δ(−2 ln L), reduction,
    /// allowance and verdict, split-refit gains and backward checks (`DIAG_SELECT=1` makes
    /// `beamtool diagnose` print it).
    pub trace: Vec<String>,
}

/// How the model read the drive between samples ([`model::DriveReading`]) and the BIC that chose it.
#[derive(Clone, Debug)]
pub struct ReadingChoice {
    /// The reading of this diagnosis.
    pub chosen: model::DriveReading,
    /// BIC of its final model on the fit recordings, `Σ_c n_c ln(RSS_c / n_c) + k ln n`
    /// (channels c with n_c samples, n in all, k fitted parameters).
    pub fit_bic: f64,
    /// Each reading's BIC when both were run (empty: the reading changes nothing the
    /// recordings hold, every one decimated or without tip and force).
    pub compared: Vec<(model::DriveReading, f64)>,
}

impl ReadingChoice {
    /// The reading of `ctx` and the BIC of its final model `reference` ([`fit_bic`]).
    fn of(ctx: &Ctx, reference: &selection::Reference) -> ReadingChoice {
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
fn model_facts(rig: &Rig, p: &model::Params) -> Result<ModelFacts> {
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
/// the candidate catalogue from [`start_hints`], [`selection::select_forward`], then
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
        calib: su.calib.with_reading(model::DriveReading::FourthOrder),
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
        tests: cands.len() * selection::MAX_EFFECTS,
        trace: Default::default(),
    };
    // the reference of the first round: the calibrated nominal model
    let nominal = ctx.reference(&[], cal.fit.clone()).ok_or_else(|| {
        anyhow::anyhow!("the calibrated nominal model cannot simulate the validation recording")
    })?;
    let val_nrmse_nominal = nominal.val_nrmse;
    let vpred0 = nominal.vpred.clone();
    let mut sel =
        selection::select_forward(&ctx, &cands, nominal.clone(), &mut budget, progress, 2);
    selection::lookalike::resolve(&ctx, &cands, &mut sel, &mut budget);
    selection::backward::eliminate(&ctx, &cands, &mut sel, &mut budget);
    selection::structural_pair_as_crack(&ctx, &cands, &mut sel, nominal, &mut budget);
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

/// The resonance of a coupled mount among `set` as the rig shows it, with 1 σ, for the final
/// fit `f` ([`model::mount_resonance_hz`]); the σ moves the mount's frequency and mass by their
/// own 1 σ each and adds the changes in quadrature (NaN where one is not identified). `None`
/// without a mount that carries the beam.
pub(crate) fn mount_resonance(ctx: &Ctx, set: &[&Candidate], f: &FitResult) -> Option<(f64, f64)> {
    let p = ctx.fit_problem(set, f.x.clone()).params_of(&f.x);
    let dt = ctx.fit_data.first()?.dt;
    let at = |q: &model::Params| model::mount_resonance_hz(ctx.rig, q, dt);
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
    let change = |q: &model::Params| at(q).map_or(f64::NAN, |g| g - resonance);
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

    use crate::diagnose::conclude::*;
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
        let mut o = selection::tests::outcome(-100.0, passed, "");
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
