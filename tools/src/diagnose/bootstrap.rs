//! Parametric bootstrap of the calibrated no-effect model: what the decision rule does on
//! recordings that hold nothing the catalogue names, made from the user's own recordings.
//!
//! The decision rule's test ([`crate::numeric::predictive`], docs/diagnose.md "The decision rule")
//! is calibrated asymptotically: its scale is the residual's own long-run variance and the fit's
//! optimism is charged as k·τ. Whether that holds after the candidates are *fitted* — on these
//! recordings, with this noise colour, at this length — is what a parametric bootstrap answers
//! (Efron & Tibshirani 1993, §6.5):
//!
//! 1. the recordings are prepared and brought to the working rate as [`super::diagnose`] does,
//!    and the nominal model is calibrated to the fit recordings ([`super::calibrate`]);
//! 2. every recorded channel of every recording (fit and validation) gets a noise model: an
//!    autoregressive process ([`crate::numeric::stats::Autoregressive::fit_aic`], order by AIC
//!    up to [`MAX_NOISE_ORDER`]) fitted to what the model leaves — by default the residual of
//!    the diagnosis' own final model of these recordings ([`NoiseFrom::Final`]: what the named
//!    effects explain is physics, not noise), or the calibrated nominal model's residual
//!    ([`NoiseFrom::Calibrated`]: every effect of the rig counted as noise) — the residual's
//!    own spectrum, model-form error included, as stationary Gaussian noise;
//! 3. a replicate is the calibrated model's prediction on the recording's own inputs (command,
//!    and the measured base where the beam is driven by it) plus one draw of that noise, on
//!    every channel; samples left out of the recording (a rail, no reading) stay left out;
//! 4. the whole diagnosis runs on each replicate. Its truth is "no effect": a catalogue effect
//!    named, or `unexplained`, is a false alarm, and the candidates' p-values should be uniform.
//!
//! What it does not reproduce: model-form error that is coherent with the motion (a loop's
//! tracking error, a beam model's small frequency error) — the replicate's noise has the
//! residual's spectrum but not its phase to the input. Those are the model-form comparison's
//! job, not the level's.

use super::effects::Calib;
use super::fit::{self, residuals, FitResult};
use super::model::{Prediction, Prepared};
use super::selection::Budget;
use crate::model::Rig;
use crate::numeric::stats::Autoregressive;
use anyhow::{anyhow, Result};
use rand::Rng;
use rand_distr::StandardNormal;

/// Highest order of a channel's noise model: the order bound the `unexplained` test prewhitens a
/// residual by ([`super::unexplained::PREWHITENING_MAX_ORDER`], its reason there), so the
/// replicates' noise is of the family that test assumes. The order is chosen below it by AIC.
pub const MAX_NOISE_ORDER: usize = super::unexplained::PREWHITENING_MAX_ORDER;

/// The calibrated no-effect model of a set of recordings, ready to draw replicates from.
pub struct NullModel {
    /// Fit recordings at the working rate.
    fit: Vec<Prepared>,
    /// Validation recording at the working rate.
    validate: Prepared,
    /// The calibrated model's prediction of each recording (the fit recordings, then the
    /// validation recording).
    preds: Vec<Prediction>,
    /// Noise model of each recording's base, tip and force channel (`None`: not recorded).
    pub noise: Vec<[Option<Autoregressive>; 3]>,
    /// Recording names, in the order of `noise`.
    pub names: Vec<String>,
    /// The effects the diagnosis of the recordings named ([`NoiseFrom::Final`]; `None` with
    /// [`NoiseFrom::Calibrated`]): left out of every replicate.
    pub named: Option<Vec<String>>,
}

/// Where a channel's noise model is read (module header, step 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseFrom {
    /// The residual of the diagnosis' final model of the recordings.
    Final,
    /// The residual of the calibrated nominal model.
    Calibrated,
}

/// Calibrates the nominal model to `fit_data` (brought to the working rate first, the drive
/// read as the diagnosis of the recordings chooses) and fits each channel's noise model to the
/// residual `from` says (module header, steps 1–2).
///
/// Errors: as [`super::diagnose`] (recordings without information, a rig the model refuses),
/// or a channel whose residual has no noise to model (constant).
pub fn null_model(
    rig: &Rig,
    fit_data: &[Prepared],
    validate: &Prepared,
    from: NoiseFrom,
) -> Result<NullModel> {
    let working_rate = super::rate::choose(fit_data, validate);
    let (fit_w, val_w) = super::rate::to_working_rate(&working_rate, fit_data, validate);
    let quantum = super::calibrate::drive_quantum_m(&fit_w);
    let su = super::calibrate::setup(rig, &fit_w, &val_w, quantum)?;
    let mut silent = crate::progress::Silent;
    // the no-effect model's predictions (fit recordings, then validation) and what is left as
    // noise: the diagnosis' own calibration and final model, or a calibration alone
    let (preds, left, named) = match from {
        NoiseFrom::Final => {
            let d = super::diagnose(rig, fit_data, validate, &mut silent)?;
            let calib = su.calib.with_reading(d.drive_reading.chosen);
            let set: Vec<&super::effects::Candidate> = d.final_set.iter().collect();
            let mut preds = predictions(rig, &fit_w, d.sigma, &calib, &[], &d.calibration)?;
            preds.push(d.val_pred_nominal.clone());
            let mut left = predictions(rig, &fit_w, d.sigma, &calib, &set, &d.final_fit)?;
            left.push(d.final_val_pred.clone());
            (
                preds,
                left,
                Some(d.effects.iter().map(|e| e.id.to_string()).collect()),
            )
        }
        NoiseFrom::Calibrated => {
            let mut budget = Budget::for_samples(fit_w.iter().map(|d| d.cmd_m.len()).sum());
            let cal =
                super::calibrate::calibrate(rig, &fit_w, &su.calib, &mut budget, &mut silent, 1)?;
            let mut preds = cal.preds;
            let val = std::slice::from_ref(&val_w);
            preds.extend(predictions(rig, val, cal.sigma, &su.calib, &[], &cal.fit)?);
            (preds.clone(), preds, None)
        }
    };
    let noise = fit_w
        .iter()
        .chain(std::iter::once(&val_w))
        .zip(&left)
        .map(|(d, p)| channel_noise(d, p))
        .collect::<Result<Vec<_>>>()?;
    Ok(NullModel {
        names: fit_w
            .iter()
            .chain(std::iter::once(&val_w))
            .map(|d| d.name.clone())
            .collect(),
        named,
        fit: fit_w,
        validate: val_w,
        preds,
        noise,
    })
}

/// The predictions of the model `set` fitted as `f` on `data` (`calib`, `sigma`: as fitted).
fn predictions(
    rig: &Rig,
    data: &[Prepared],
    sigma: [f64; 3],
    calib: &Calib,
    set: &[&super::effects::Candidate],
    f: &FitResult,
) -> Result<Vec<Prediction>> {
    fit::Problem::new(rig, data, sigma, calib, set, f.x.clone())
        .predictions(&f.x)
        .ok_or_else(|| anyhow!("the fitted model cannot simulate the recordings"))
}

/// The noise model of each recorded channel of `d` under the prediction `p`.
fn channel_noise(d: &Prepared, p: &Prediction) -> Result<[Option<Autoregressive>; 3]> {
    let res = residuals(d, p);
    let mut out: [Option<Autoregressive>; 3] = Default::default();
    for (c, r) in res.iter().enumerate() {
        if let Some(r) = r {
            out[c] = Some(Autoregressive::fit_aic(r, MAX_NOISE_ORDER).ok_or_else(|| {
                anyhow!(
                    "{}: the calibrated residual of {} has no noise to model (constant or too short)",
                    d.name,
                    fit::CHANNEL_NAMES[c]
                )
            })?);
        }
    }
    Ok(out)
}

impl NullModel {
    /// One replicate (module header, step 3): the fit recordings and the validation recording,
    /// each channel the calibrated prediction plus a draw of its noise model from `rng`.
    pub fn replicate(&self, rng: &mut impl Rng) -> (Vec<Prepared>, Prepared) {
        let mut all: Vec<Prepared> = self
            .fit
            .iter()
            .chain(std::iter::once(&self.validate))
            .zip(self.preds.iter().zip(&self.noise))
            .map(|(d, (p, noise))| {
                let mut d = d.clone();
                let draw = |pred: &Option<Vec<f64>>, c: usize, rng: &mut dyn rand::RngCore| {
                    let (Some(pred), Some(ar)) = (pred, &noise[c]) else {
                        return None;
                    };
                    let e = ar.simulate(pred.len(), || rng.sample(StandardNormal));
                    Some(pred.iter().zip(e).map(|(y, e)| y + e).collect())
                };
                d.base_m = d.base_m.as_ref().and(draw(&p.base_m, 0, rng));
                d.tip_m = d.tip_m.as_ref().and(draw(&p.tip_m, 1, rng));
                d.force_n = d.force_n.as_ref().and(draw(&p.force_n, 2, rng));
                d.name = format!("{} (null replicate)", d.name);
                d
            })
            .collect();
        let validate = all.pop().expect("the validation recording is last");
        (all, validate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::model::Params;
    use rand::SeedableRng;

    /// The paper's rig (a 0.9 m steel strip on a 2.5 kg carriage).
    fn rig() -> Rig {
        Rig::from_toml_str(
            "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\nstations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 }, { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]\n[base]\nmass_kg = 2.5\n",
        )
        .unwrap()
    }

    /// A 100 Hz recording: a 2 s rest, a 50 mm move in 1 s, 6 s of ringing; every channel the
    /// nominal model's prediction plus white noise.
    fn recording(rig: &Rig, seed: u64) -> Prepared {
        let rate = 100.0;
        let n = 900;
        let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
        let cmd: Vec<f64> = (0..n)
            .map(|k| {
                let t = (k as f64 / rate - 2.0).clamp(0.0, 1.0);
                let w = 2.0 * std::f64::consts::PI;
                0.05 * (t - (w * t).sin() / w)
            })
            .collect();
        rec.base_cmd_m = Some(cmd.clone());
        rec.base_pos_m = Some(cmd.clone());
        rec.tip_pos_m = Some(cmd.clone());
        rec.force_n = Some(vec![0.0; n]);
        let clean = Prepared::new("r", &rec).unwrap();
        let p =
            crate::diagnose::model::predict(rig, &Params::default(), &clean, &mut None).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut noisy = |v: &[f64], s: f64| -> Vec<f64> {
            v.iter()
                .map(|x| x + s * rng.sample::<f64, _>(StandardNormal))
                .collect()
        };
        rec.tip_pos_m = Some(noisy(p.tip_m.as_ref().unwrap(), 1e-4));
        rec.force_n = Some(noisy(p.force_n.as_ref().unwrap(), 0.05));
        rec.base_pos_m = Some(noisy(&cmd, 1e-6));
        Prepared::new("r", &rec).unwrap()
    }

    #[test]
    fn a_replicate_is_the_calibrated_prediction_plus_noise_of_the_residuals_size() {
        let rig = rig();
        let fit = vec![recording(&rig, 1), recording(&rig, 2)];
        let val = recording(&rig, 3);
        let null = null_model(&rig, &fit, &val, NoiseFrom::Calibrated).expect("calibrates");
        assert_eq!(null.noise.len(), 3);
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let (rf, rv) = null.replicate(&mut rng);
        assert_eq!(rf.len(), 2);
        for (orig, rep) in fit.iter().chain([&val]).zip(rf.iter().chain([&rv])) {
            let tip0 = orig.tip_m.as_ref().unwrap();
            let tip1 = rep.tip_m.as_ref().unwrap();
            assert_eq!(tip0.len(), tip1.len());
            // the replicate differs from the recording by about √2 × the noise (two draws)
            let diff = (tip0
                .iter()
                .zip(tip1)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / tip0.len() as f64)
                .sqrt();
            assert!(diff > 1e-4 && diff < 2e-4, "{diff}");
            // inputs untouched
            assert_eq!(orig.cmd_m, rep.cmd_m);
            assert_eq!(orig.drive_m, rep.drive_m);
        }
        // every channel's noise model is white noise of the size it was drawn with
        for ch in &null.noise {
            let tip = ch[1].as_ref().unwrap();
            assert!(
                (tip.innovation_variance.sqrt() / 1e-4 - 1.0).abs() < 0.15,
                "{tip:?}"
            );
        }
    }
}
