//! Model-discrepancy diagnosis: calibrate the nominal model, locate the residual, fit a
//! catalogue of candidate physics, select with a guard against false discovery, report.
//!
//! - [`sim`]: the augmented simulator (nominal model of paper §2 + every extension);
//! - [`effects`]: the candidate catalogue with physical parameters;
//! - [`fit`]: Levenberg–Marquardt ([`crate::numeric::lm`]) on whitened residuals, parameter
//!   uncertainties;
//! - [`locate`]: where/when/at which frequency the residual is structured;
//! - [`select`]: BIC + validation + model-form allowance + whiteness + significance guard;
//! - [`report`]: JSON, words, SVG plots; [`cli`]: `diagnose`, `diagnose-proof`;
//!
//! Every fit of one diagnosis draws on one budget of model evaluations
//! ([`WORK_BUDGET_SAMPLE_EVALUATIONS`] divided by the fit recordings' samples), never on the
//! clock, so the same recordings give the same answer on any machine.

pub mod cli;
pub mod effects;
pub mod fit;
pub mod lengths;
pub mod locate;
pub mod proof;
pub mod report;
pub mod select;
pub mod sim;
pub mod unexplained;

use crate::model::{BeamModel, ModelOptions, Rig};
use crate::numeric::arx;
use anyhow::{bail, Result};
use effects::{calibration_defs, catalogue, Candidate, Channels, StartHints};
use fit::{channel_rss, fit, residuals, FitResult};
use select::*;
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
    /// Passed the guard.
    pub passed: bool,
    /// Why it lost or passed.
    pub reason: String,
    /// Validation predictions.
    pub val_pred: Prediction,
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
    /// Model evaluations in total.
    pub evaluations: usize,
    /// The Galerkin basis and its convergence for the modes inside the band (with a beam).
    pub basis: Option<sim::BasisChoice>,
    /// Band edge (Hz) of the recordings (0.45 × the lowest sample rate).
    pub band_edge_hz: f64,
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
}

/// The recorded signal of channel `c` (0 base position m, 1 tip deflection tip − drive m,
/// 2 force N) that a residual is normalised by; empty when the channel is missing.
pub fn channel_signal(d: &Prepared, c: usize) -> Vec<f64> {
    let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
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

/// Work budget of one diagnosis in *sample-evaluations*: model evaluations × samples of the fit
/// recordings simulated per evaluation. Counted, not timed, so the answer does not depend on
/// the machine or its load; 2e8 is about 35 s of one core for a 4-basis-function beam
/// (2.4 ms per evaluation of 13 800 samples, measured on case13 of the independent set), so
/// that three 60–90 s recordings with four effects stay under a minute on a loaded 2-core
/// machine.
pub const WORK_BUDGET_SAMPLE_EVALUATIONS: f64 = 2.0e8;
/// Bounds of the resulting number of model evaluations of one diagnosis.
pub const EVALUATION_BUDGET_RANGE: (usize, usize) = (2_000, 40_000);

/// The model-evaluation budget of one diagnosis and what has been spent of it.
struct Budget {
    total: usize,
    spent: usize,
}

impl Budget {
    /// The budget for fit recordings of `fit_samples` samples in total.
    fn for_samples(fit_samples: usize) -> Budget {
        let (lo, hi) = EVALUATION_BUDGET_RANGE;
        let total = (WORK_BUDGET_SAMPLE_EVALUATIONS / fit_samples.max(1) as f64) as usize;
        Budget {
            total: total.clamp(lo, hi),
            spent: 0,
        }
    }

    /// An equal share of what is left for one of `parts` remaining fits (at least 1/200 of the
    /// budget, so that a late fit still gets a few iterations).
    fn share(&self, parts: usize) -> usize {
        (self.total.saturating_sub(self.spent) / parts.max(1)).max(self.total / 200)
    }

    fn spend(&mut self, evaluations: usize) {
        self.spent += evaluations;
    }

    fn fraction_spent(&self) -> f64 {
        self.spent as f64 / self.total as f64
    }
}

/// Runs the whole diagnosis. `progress` is called with (step, total, message).
///
/// Errors: recordings the rig cannot simulate (tip channel without a beam, …), a rig the model
/// refuses, a validation recording whose channels differ from every fit recording's.
pub fn diagnose(
    rig: &Rig,
    fit_data: &[Prepared],
    validate: &Prepared,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Diagnosis> {
    if fit_data.is_empty() {
        bail!("at least one --fit recording is needed");
    }
    let mut budget = Budget::for_samples(fit_data.iter().map(|d| d.cmd_m.len()).sum());
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        check_information(d)?;
    }
    // the nominal model must be able to simulate every recording: report why not, by name
    for d in fit_data.iter().chain(std::iter::once(validate)) {
        sim::predict(rig, &sim::Params::default(), d, &mut None)
            .map_err(|e| anyhow::anyhow!("{}: {e:#}", d.name))?;
    }
    let ch = channels_of(fit_data);
    let band_edge = fit_data
        .iter()
        .chain(std::iter::once(validate))
        .map(|d| sim::band_edge_hz(d.dt))
        .fold(f64::INFINITY, f64::min);
    let basis = match rig.beam {
        Some(_) => Some(sim::converged_basis(rig, 1.0, band_edge)?),
        None => None,
    };
    let calib = calibration_defs(
        rig,
        &ch,
        basis.as_ref().map_or(0, |b| b.freqs_hz.len()),
        basis.as_ref().map_or(4, |b| b.n_basis),
    );
    // initial whitening: a fraction of each channel's signal scale
    let mut sigma = [1e-6, 1e-4, 0.1];
    {
        let mut acc: [Vec<f64>; 3] = [vec![], vec![], vec![]];
        for d in fit_data {
            if let Some(b) = &d.base_m {
                acc[0].extend(b.iter().zip(&d.cmd_m).map(|(a, c)| a - c));
            }
            if let Some(t) = &d.tip_m {
                let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
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
    }
    let n_cand_est = 12;
    let total_steps = n_cand_est + 3;
    progress(0, total_steps, "calibrating the nominal model");
    let mut cal = fit(
        rig,
        fit_data,
        sigma,
        &calib,
        &[],
        None,
        budget.share(4),
        true,
    );
    budget.spend(cal.evaluations);
    let problem = fit::Problem::new(rig, fit_data, sigma, &calib, &[], cal.x.clone());
    let preds0 = problem
        .predictions(&cal.x)
        .ok_or_else(|| anyhow::anyhow!("the calibrated nominal model cannot be simulated"))?;
    let res0: Vec<_> = fit_data
        .iter()
        .zip(&preds0)
        .map(|(d, p)| residuals(d, p))
        .collect();
    let (rss0, n0) = channel_rss(&res0);
    for c in 0..3 {
        if n0[c] > 0 {
            sigma[c] = (rss0[c] / n0[c] as f64).sqrt().max(1e-12);
        }
    }
    progress(
        1,
        total_steps,
        "recalibrating with the residual noise scales",
    );
    cal = fit(
        rig,
        fit_data,
        sigma,
        &calib,
        &[],
        Some(&cal.x),
        budget.share(3),
        true,
    );
    budget.spend(cal.evaluations);
    let problem = fit::Problem::new(rig, fit_data, sigma, &calib, &[], cal.x.clone());
    let preds0 = problem
        .predictions(&cal.x)
        .ok_or_else(|| anyhow::anyhow!("the calibrated nominal model cannot be simulated"))?;
    let res0: Vec<_> = fit_data
        .iter()
        .zip(&preds0)
        .map(|(d, p)| residuals(d, p))
        .collect();
    let p_nom = problem.params_of(&cal.x);
    {
        let best = fit_data
            .iter()
            .zip(&preds0)
            .flat_map(|(d, p)| {
                let v = nrmse(d, p);
                [v[1], v[2]]
            })
            .filter(|v| v.is_finite())
            .fold(f64::INFINITY, f64::min);
        if !(best < MAX_CALIBRATED_NRMSE) {
            bail!(
                "no information: even calibrated, the rig model explains almost nothing of the fit recordings (best tip/force channel NRMSE {best:.2} ≥ {MAX_CALIBRATED_NRMSE}); a recording of another rig, or noise only?"
            );
        }
        if p_nom.stiffness_scale < 0.25 || p_nom.stiffness_scale > 4.0 {
            bail!(
                "the recordings do not match this rig: the calibration needs {:.2} × the rig's Young's modulus (frequencies off by {:.0} %); check the rig file",
                p_nom.stiffness_scale,
                100.0 * (p_nom.stiffness_scale.sqrt() - 1.0)
            );
        }
    }
    // model frequencies and hints
    let (model_freqs, beam_mass, ei_over_l, length_m) = match &rig.beam {
        Some(b) => {
            let m = BeamModel::new(
                rig,
                &ModelOptions {
                    n_modes: p_nom.n_basis,
                    stiffness_scale: p_nom.stiffness_scale,
                    damping_ratios: p_nom.zeta,
                    ..Default::default()
                },
            )?;
            let f: Vec<f64> = m
                .clamped_modes()?
                .omega_rad_s
                .iter()
                .map(|w| w / (2.0 * std::f64::consts::PI))
                .collect();
            let prof = rig.profile()?;
            (
                f,
                m.beam_mass_kg,
                b.youngs_modulus_pa * p_nom.stiffness_scale * prof.inertia(0.0) / b.length_m,
                b.length_m,
            )
        }
        None => (vec![], 0.0, 1.0, 0.0),
    };
    let location = locate::locate(fit_data, &preds0, &model_freqs);
    // friction / cogging starts from the force residual
    let (mut fr_r, mut fr_v, mut fr_y, mut fr_m) = (vec![], vec![], vec![], vec![]);
    let mut peak_def: f64 = 0.0;
    let mut speed: f64 = 0.0;
    for (d, r) in fit_data.iter().zip(&res0) {
        let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
        let v = locate::velocity(drive, d.dt);
        speed = speed.max(v.iter().fold(0.0f64, |a, x| a.max(x.abs())));
        if let Some(f) = &r[2] {
            fr_r.extend(f.iter().copied());
            fr_m.extend(v.iter().map(|x| x.abs() > 1e-4));
            fr_v.extend(v);
            fr_y.extend(drive.iter().copied());
        }
        if let Some(t) = &d.tip_m {
            peak_def = peak_def.max(
                t.iter()
                    .zip(drive)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max),
            );
        }
    }
    let friction = locate::friction_ls(&fr_r, &fr_v);
    let rip = locate::ripple_scan(&fr_r, &fr_y, &fr_m);
    let hints = StartHints {
        beam_mass_kg: beam_mass,
        ei_over_l,
        f2_hz: model_freqs.get(1).copied().unwrap_or(10.0),
        rate_hz: 1.0 / fit_data[0].dt,
        peak_deflection_m: peak_def,
        friction,
        cogging: (rip.1, rip.2, rip.0),
        mode_freqs_hz: model_freqs.clone(),
        speed_m_s: speed,
        zeta1: p_nom.zeta.map_or(rig.damping_ratios().0, |z| z.0),
        length_m,
        carriage_mass_kg: rig.base.mass_kg,
    };
    let cands: Vec<Candidate> = catalogue(rig, &ch, &hints);
    let ctx = Ctx {
        rig,
        fit_data,
        validate,
        sigma,
        calib: &calib,
        model_freqs: &model_freqs,
    };
    // the reference of the first round: the calibrated nominal model
    let nominal = ctx.reference(&[], cal.clone()).ok_or_else(|| {
        anyhow::anyhow!("the calibrated nominal model cannot simulate the validation recording")
    })?;
    let val_nrmse_nominal = nominal.val_nrmse;
    let vpred0 = nominal.vpred.clone();
    // forward selection: add the best candidate that passes every guard against the current
    // model, re-fit the rest on the augmented model, stop when none passes
    let mut chosen: Vec<usize> = Vec::new();
    let mut chosen_outcomes: Vec<CandidateOutcome> = Vec::new();
    let mut reference = nominal;
    let mut rounds: Vec<Vec<CandidateOutcome>> = Vec::new();
    let mut step = 2;
    for round in 0..MAX_EFFECTS {
        let pool: Vec<usize> = (0..cands.len())
            .filter(|&i| {
                chosen
                    .iter()
                    .all(|&k| !cands[k].id.conflicts_with(cands[i].id))
            })
            .collect();
        if pool.is_empty() || (round > 0 && budget.fraction_spent() > 0.8) {
            break;
        }
        if round > 0 {
            // refit the current model alone first, so that a better joint optimum of what is
            // already chosen is never credited to the next candidate
            let set: Vec<&Candidate> = chosen.iter().map(|&k| &cands[k]).collect();
            let f = fit(
                rig,
                fit_data,
                sigma,
                &calib,
                &set,
                Some(&reference.fit.x),
                budget.share(pool.len() + 2),
                false,
            );
            budget.spend(f.evaluations);
            if f.cost < reference.fit.cost {
                if let Some(r) = ctx.reference(&set, f) {
                    reference = r;
                }
            }
        }
        {
            let set: Vec<&Candidate> = chosen.iter().map(|&k| &cands[k]).collect();
            let (split, used) = ctx.split_spread(&set, &reference, budget.share(pool.len() + 2));
            budget.spend(used);
            reference.split = split;
        }
        let mut outs = Vec::new();
        for (j, &ci) in pool.iter().enumerate() {
            let total_steps = step + pool.len() - j + 1;
            progress(
                step,
                total_steps,
                &format!("round {}: fitting {}", round + 1, cands[ci].id),
            );
            step += 1;
            let set: Vec<&Candidate> = chosen
                .iter()
                .map(|&k| &cands[k])
                .chain(std::iter::once(&cands[ci]))
                .collect();
            let share = budget.share(pool.len() - j + 1);
            if let Some(o) = ctx.evaluate(&set, ci, &reference, share, round == 0) {
                budget.spend(o.fit.evaluations);
                outs.push(o);
            }
        }
        outs.sort_by(|a, b| a.delta_val.total_cmp(&b.delta_val));
        keep_lowest_bic_form(&mut outs);
        let mut pick = outs.iter().position(|o| o.passed);
        // Backward check: the effects already chosen, refitted from the joint optimum without
        // the newcomer. If they alone do better there than the reference, part of the
        // newcomer's gain was only a better optimum of what was already chosen: every passing
        // candidate is judged again against that better reference.
        let mut checked: Vec<usize> = Vec::new();
        while round > 0 && checked.len() < 3 {
            let Some(s) = pick else { break };
            if checked.contains(&outs[s].cand_index) {
                break;
            }
            checked.push(outs[s].cand_index);
            let prev: Vec<&Candidate> = chosen.iter().map(|&k| &cands[k]).collect();
            let warm = outs[s].fit.x.rows(0, reference.fit.x.len()).into_owned();
            let f = fit(
                rig,
                fit_data,
                sigma,
                &calib,
                &prev,
                Some(&warm),
                budget.share(pool.len() + 1),
                false,
            );
            budget.spend(f.evaluations);
            if std::env::var_os("DIAG_SELECT").is_some() {
                eprintln!(
                    "backward check of {}: chosen effects alone from the joint optimum cost {:.6e} (reference {:.6e}, with it {:.6e})\n  reference {:?}\n  joint     {:?}\n  refit     {:?}",
                    outs[s].id, f.cost, reference.fit.cost, outs[s].fit.cost,
                    reference.fit.values, outs[s].fit.values, f.values
                );
            }
            if !(f.cost < reference.fit.cost) {
                break;
            }
            let Some(mut better) = ctx.reference(&prev, f) else {
                break;
            };
            better.split = reference.split;
            reference = better;
            for o in outs.iter_mut().filter(|o| o.passed) {
                let set: Vec<&Candidate> = prev
                    .iter()
                    .copied()
                    .chain(std::iter::once(&cands[o.cand_index]))
                    .collect();
                if let Some(r) = ctx.reference(&set, o.fit.clone()) {
                    *o = ctx.assess(&set, o.cand_index, r, &reference);
                }
            }
            outs.sort_by(|a, b| a.delta_val.total_cmp(&b.delta_val));
            keep_lowest_bic_form(&mut outs);
            pick = outs.iter().position(|o| o.passed);
        }
        if std::env::var_os("DIAG_SELECT").is_some() {
            for o in &outs {
                eprintln!(
                    "round {} {}: ΔBIC {:.1} Δval {:.1} reduction {:.3} allowance {:.3} {}",
                    round + 1,
                    o.id,
                    o.delta_bic,
                    o.delta_val,
                    o.reduction,
                    o.allowance,
                    o.reason
                );
            }
        }
        if let Some(s) = pick {
            for (i, o) in outs.iter_mut().enumerate() {
                if i != s && o.passed {
                    o.reason =
                        "passes the guard but gains less on validation than the selected effect"
                            .into();
                }
            }
            let o = outs[s].clone();
            chosen.push(o.cand_index);
            let set: Vec<&Candidate> = chosen.iter().map(|&k| &cands[k]).collect();
            match ctx.reference(&set, o.fit.clone()) {
                Some(r) => reference = r,
                None => break,
            }
            chosen_outcomes.push(o);
        }
        rounds.push(outs);
        if pick.is_none() {
            break;
        }
    }
    let total_steps = step + 1;
    let final_set: Vec<Candidate> = chosen.iter().map(|&k| cands[k].clone()).collect();
    let unexplained =
        unexplained::assess(validate, &reference.vres, &reference.vpred, &model_freqs);
    let outcomes = rounds.first().cloned().unwrap_or_default();
    let selected = outcomes
        .iter()
        .position(|o| o.passed && chosen.first() == Some(&o.cand_index));
    progress(total_steps, total_steps, "done");
    Ok(Diagnosis {
        effect: chosen
            .first()
            .map_or_else(|| "none".to_string(), |&k| cands[k].id.to_string()),
        selected,
        calibration: cal,
        sigma,
        location,
        val_nrmse_nominal,
        val_pred_nominal: vpred0,
        candidates: outcomes,
        validate: validate.clone(),
        evaluations: budget.spent,
        basis,
        band_edge_hz: band_edge,
        effects: chosen_outcomes,
        final_set,
        final_fit: reference.fit,
        final_val_pred: reference.vpred,
        final_val_nrmse: reference.val_nrmse,
        rounds: rounds.len(),
        unexplained,
        assumptions: assumptions(fit_data, validate),
    })
}

/// Alternative forms of one effect (the servo loop's orders, the mount's forms, the two
/// orientations) describe the same physics: of those that pass, only the one with the lowest
/// ΔBIC on the fit recordings stays a contender (the order is chosen by the information
/// criterion, not by the validation recording).
fn keep_lowest_bic_form(outs: &mut [CandidateOutcome]) {
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
    let span = |v: &[f64]| {
        v.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
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

/// Largest NRMSE (on the channel the model predicts best) at which the calibrated nominal
/// model is still taken to describe the recordings: below it the model explains at least
/// 1 − 0.9² = 19 % of that channel's variance.
pub const MAX_CALIBRATED_NRMSE: f64 = 0.9;

/// Most effects forward selection adds.
pub const MAX_EFFECTS: usize = 4;

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

/// The model a round compares against: its fit and residuals on fit and validation data.
#[derive(Clone, Debug)]
struct Reference {
    fit: FitResult,
    rss: [f64; 3],
    vres: [Option<Vec<f64>>; 3],
    vrss: [f64; 3],
    vn: [usize; 3],
    vpred: Prediction,
    val_nrmse: [f64; 3],
    /// Per channel, the normal equations of the physics-free correction of this model's
    /// residual on the fit recordings and on the validation recording.
    generic: [Option<(arx::Normal, arx::Normal)>; 3],
    /// Per channel, the integrated autocorrelation time of this model's residual on the fit
    /// recordings (length-weighted mean) and on the validation recording.
    tau_fit: [f64; 3],
    tau_val: [f64; 3],
    /// Per channel, how much the validation rms residual changes when this model is refitted
    /// to one fit recording alone (the smallest |relative change| over the fit recordings;
    /// [`Ctx::split_spread`]), 0 until computed.
    split: [f64; 3],
}

/// Most lags summed for an autocorrelation time.
const MAX_TAU_LAG: usize = 2000;

/// What every evaluation shares.
struct Ctx<'a> {
    rig: &'a Rig,
    fit_data: &'a [Prepared],
    validate: &'a Prepared,
    sigma: [f64; 3],
    calib: &'a effects::Calib,
    model_freqs: &'a [f64],
}

impl Ctx<'_> {
    fn reference(&self, set: &[&Candidate], f: FitResult) -> Option<Reference> {
        let prob = fit::Problem::new(
            self.rig,
            self.fit_data,
            self.sigma,
            self.calib,
            set,
            f.x.clone(),
        );
        let preds = prob.predictions(&f.x)?;
        let res: Vec<_> = self
            .fit_data
            .iter()
            .zip(&preds)
            .map(|(d, p)| residuals(d, p))
            .collect();
        let (rss, _) = channel_rss(&res);
        let vdata = std::slice::from_ref(self.validate);
        let vprob = fit::Problem::new(self.rig, vdata, self.sigma, self.calib, set, f.x.clone());
        let vpred = vprob.predictions(&f.x)?.remove(0);
        let vres = residuals(self.validate, &vpred);
        let (vrss, vn) = channel_rss(std::slice::from_ref(&vres));
        let val_nrmse = nrmse(self.validate, &vpred);
        let generic = std::array::from_fn(|c| {
            let m = generic_signal_count(c);
            let (mut fit_ne, mut val_ne) = (arx::Normal::new(m), arx::Normal::new(m));
            for ((d, p), r) in self.fit_data.iter().zip(&preds).zip(&res) {
                if let (Some(r), Some(s)) = (&r[c], generic_signals(d, p, c)) {
                    fit_ne.add(r, &s.iter().map(|v| v.as_slice()).collect::<Vec<_>>());
                }
            }
            let (Some(r), Some(s)) = (&vres[c], generic_signals(self.validate, &vpred, c)) else {
                return None;
            };
            val_ne.add(r, &s.iter().map(|v| v.as_slice()).collect::<Vec<_>>());
            (fit_ne.rss() > 0.0).then_some((fit_ne, val_ne))
        });
        let tau_fit = std::array::from_fn(|c| {
            let (mut acc, mut n) = (0.0, 0usize);
            for r in res.iter().filter_map(|r| r[c].as_ref()) {
                acc += r.len() as f64 * autocorrelation_time(r, MAX_TAU_LAG);
                n += r.len();
            }
            if n > 0 {
                acc / n as f64
            } else {
                1.0
            }
        });
        let tau_val = std::array::from_fn(|c| {
            vres[c]
                .as_ref()
                .map_or(1.0, |r| autocorrelation_time(r, MAX_TAU_LAG))
        });
        Some(Reference {
            split: [0.0; 3],
            generic,
            tau_fit,
            tau_val,
            fit: f,
            rss,
            vres,
            vrss,
            vn,
            vpred,
            val_nrmse,
        })
    }

    /// The split-refit spread of `base` (model `set`): refitted to each fit recording alone
    /// (warm from `base`, `max_evaluations` shared), the relative change of the validation rms
    /// residual per channel; its smallest magnitude over the recordings is how much re-tuning
    /// the existing parameters to other excitation at least moves the validation error — a gain
    /// within it is not evidence of new physics (the smallest, because one recording alone may
    /// leave the model undetermined). Zero with a single fit recording. Returns it and the model
    /// evaluations used.
    fn split_spread(
        &self,
        set: &[&Candidate],
        base: &Reference,
        max_evaluations: usize,
    ) -> ([f64; 3], usize) {
        let mut spread = [f64::INFINITY; 3];
        let mut used = 0;
        if self.fit_data.len() < 2 {
            return ([0.0; 3], 0);
        }
        let share = max_evaluations / self.fit_data.len();
        for i in 0..self.fit_data.len() {
            let one = std::slice::from_ref(&self.fit_data[i]);
            let f = fit(
                self.rig,
                one,
                self.sigma,
                self.calib,
                set,
                Some(&base.fit.x),
                share,
                false,
            );
            used += f.evaluations;
            let vdata = std::slice::from_ref(self.validate);
            let vprob =
                fit::Problem::new(self.rig, vdata, self.sigma, self.calib, set, f.x.clone());
            let Some(mut vp) = vprob.predictions(&f.x) else {
                continue;
            };
            let vres = residuals(self.validate, &vp.remove(0));
            let (vrss, _) = channel_rss(std::slice::from_ref(&vres));
            for c in 0..3 {
                if base.vn[c] > 0 && base.vrss[c] > 0.0 {
                    let change = 1.0 - (vrss[c] / base.vrss[c]).sqrt();
                    if change.is_finite() {
                        spread[c] = spread[c].min(change.abs());
                    }
                }
            }
        }
        for v in spread.iter_mut().filter(|v| !v.is_finite()) {
            *v = 0.0;
        }
        if std::env::var_os("DIAG_SELECT").is_some() {
            eprintln!("split-refit spread of the validation residual per channel: {spread:?}");
        }
        (spread, used)
    }

    /// Fits `set` (the effects chosen so far + candidate `ci`, last) jointly with the calibration
    /// and applies every guard against `base`.
    fn evaluate(
        &self,
        set: &[&Candidate],
        ci: usize,
        base: &Reference,
        max_evaluations: usize,
        explore: bool,
    ) -> Option<CandidateOutcome> {
        set.last()?;
        let f = fit(
            self.rig,
            self.fit_data,
            self.sigma,
            self.calib,
            set,
            Some(&base.fit.x),
            max_evaluations,
            explore,
        );
        let r = self.reference(set, f)?;
        Some(self.assess(set, ci, r, base))
    }

    /// Applies every guard ([`select::guard`] and the calibration-matter rules) to candidate
    /// `ci` (last of `set`), fitted as `r`, against the model `base` it extends.
    fn assess(
        &self,
        set: &[&Candidate],
        ci: usize,
        r: Reference,
        base: &Reference,
    ) -> CandidateOutcome {
        let cand = *set.last().expect("a candidate");
        let f = r.fit.clone();
        let k = cand.params.len().max(1);
        // likelihood ratios with the samples counted as independent ones: n / τ per channel,
        // τ of the residual under the null (the model this candidate extends)
        let n_fit = n_of(self.fit_data);
        let n_eff: f64 = (0..3).map(|c| n_fit[c] as f64 / base.tau_fit[c]).sum();
        let delta_bic = delta_neg2ll_effective(&r.rss, &base.rss, &n_fit, &base.tau_fit)
            + k as f64 * n_eff.max(1.0).ln();
        if std::env::var_os("DIAG_DEBUG").is_some() {
            eprintln!(
                "{}: fit rss {:?} vs reference {:?}; values {:?}",
                cand.id, r.rss, base.rss, f.values
            );
        }
        let delta_val = delta_neg2ll_effective(&r.vrss, &base.vrss, &base.vn, &base.tau_val);
        let vn = base.vn;
        let mut best_channel = 0;
        let mut reduction = f64::NEG_INFINITY;
        for c in 0..3 {
            if vn[c] > 0 {
                let red = 1.0 - (r.vrss[c] / base.vrss[c].max(1e-300)).sqrt();
                if red > reduction {
                    reduction = red;
                    best_channel = c;
                }
            }
        }
        let q_before = base.vres[best_channel]
            .as_ref()
            .map_or(0.0, |r| ljung_box(r, LJUNG_BOX_LAGS));
        let q_after = r.vres[best_channel]
            .as_ref()
            .map_or(0.0, |r| ljung_box(r, LJUNG_BOX_LAGS));
        let off = f.values.len() - cand.params.len();
        let significance = cand
            .params
            .iter()
            .enumerate()
            .filter(|(_, d)| d.zero_is_null)
            .map(|(i, _)| f.values[off + i].abs() / f.std[off + i].max(1e-300))
            .map(|z| if z.is_nan() { 0.0 } else { z })
            .fold(f64::NEG_INFINITY, f64::max);
        let significance = if significance == f64::NEG_INFINITY {
            f64::INFINITY
        } else {
            significance
        };
        let sp = |v: &Option<Vec<f64>>| {
            v.as_ref()
                .map_or(0.0, |r| structured_power(r, LJUNG_BOX_LAGS))
        };
        let allowance = base.generic[best_channel]
            .as_ref()
            .and_then(|(fit_ne, val_ne)| arx::best_correction(fit_ne, val_ne, k))
            .map_or(0.0, |c| c.val_reduction())
            .max(base.split[best_channel]);
        let mut fails = guard(&Evidence {
            delta_bic,
            delta_val,
            reduction,
            allowance,
            structured: Some((sp(&base.vres[best_channel]), sp(&r.vres[best_channel]))),
            significance,
        });
        // a lightly damped servo loop is a resonance of the base motion: the same rule as a mount
        if let (Some(i), Some(j)) = (
            cand.params
                .iter()
                .position(|q| q.name == "servo_bandwidth_hz"),
            cand.params
                .iter()
                .position(|q| q.name == "servo_damping_ratio"),
        ) {
            let (fs, zs, sf) = (f.values[off + i], f.values[off + j], f.std[off + i]);
            if zs < 0.3 {
                let tol = 2.0 * if sf.is_finite() { sf } else { 0.0 } + zs * fs;
                if let Some(fr) = self.model_freqs.iter().find(|fr| (fs - **fr).abs() <= tol) {
                    fails.push(format!(
                        "a resonant servo loop (ζ {zs:.2}) at {fs:.2} Hz coincides with the model's own mode at {fr:.2} Hz: a calibration matter"
                    ));
                }
            }
        }
        for (i, d) in cand.params.iter().enumerate() {
            if d.name == "mount_frequency_hz" {
                // A residual at one of the model's own modes is a calibration matter (that mode's
                // damping or the stiffness scale), never a new resonance: the mount frequency
                // must be separated from every in-band model mode by more than its own 2 σ and
                // the mount's half-power half-width ζ_m f_m (ζ_m capped at 0.1).
                let fm = f.values[off + i];
                let sf = f.std[off + i];
                let zm = cand
                    .params
                    .iter()
                    .position(|q| q.name == "mount_damping_ratio")
                    .map_or(0.05, |j| f.values[off + j]);
                let tol = 2.0 * if sf.is_finite() { sf } else { 0.0 } + zm.min(0.1) * fm;
                if let Some(fr) = self.model_freqs.iter().find(|fr| (fm - **fr).abs() <= tol) {
                    fails.push(format!(
                        "mount frequency {fm:.2} Hz coincides with the model's own mode at {fr:.2} Hz (within {tol:.2} Hz): a calibration matter, not a new resonance"
                    ));
                }
                // A resonance fitted at the ceiling of its search range (0.4 × the sample rate)
                // is not identified: the recording holds no information there.
                let ceiling = d.starts.iter().cloned().fold(0.0, f64::max);
                if fm >= 0.95 * ceiling {
                    fails.push(format!(
                        "mount frequency {fm:.1} Hz at the edge of the observable band ({ceiling:.1} Hz): not identified"
                    ));
                }
            }
        }
        let passed = fails.is_empty();
        CandidateOutcome {
            id: cand.id,
            words: cand.words.to_string(),
            cand_index: ci,
            param_offset: off,
            k,
            delta_bic,
            delta_val,
            val_nrmse: r.val_nrmse,
            nrmse_before: base.val_nrmse,
            best_channel,
            reduction,
            whiteness: (q_before, q_after),
            significance,
            passed,
            reason: if passed {
                "passes every guard".into()
            } else {
                fails.join("; ")
            },
            val_pred: r.vpred,
            fit: f,
            allowance,
        }
    }
}

/// Signals of the physics-free correction of channel `c` ([`crate::numeric::arx`]): base —
/// the predicted base and the command; tip — the predicted tip, the predicted *deflection*
/// (tip − drive, what a filter between the base and the beam root changes) and the drive
/// (measured base, else the command); force — the predicted force and the drive.
fn generic_signals(d: &Prepared, p: &Prediction, c: usize) -> Option<Vec<Vec<f64>>> {
    let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
    match c {
        0 => Some(vec![p.base_m.clone()?, d.cmd_m.clone()]),
        1 => {
            let tip = p.tip_m.clone()?;
            let deflection = tip.iter().zip(drive).map(|(a, b)| a - b).collect();
            Some(vec![tip, deflection, drive.clone()])
        }
        _ => Some(vec![p.force_n.clone()?, drive.clone()]),
    }
}

/// Number of signals [`generic_signals`] gives for channel `c`.
fn generic_signal_count(c: usize) -> usize {
    if c == 1 {
        3
    } else {
        2
    }
}

fn n_of(data: &[Prepared]) -> [usize; 3] {
    let mut n = [0; 3];
    for d in data {
        let m = d.cmd_m.len();
        if d.base_m.is_some() {
            n[0] += m;
        }
        if d.tip_m.is_some() {
            n[1] += m;
        }
        if d.force_n.is_some() {
            n[2] += m;
        }
    }
    n
}
