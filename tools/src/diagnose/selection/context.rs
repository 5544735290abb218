//! The context of one selection ([`Ctx`]): the rig, the recordings, the calibration and the
//! trace; fitting a set of candidates, turning a fit into a [`Reference`], the split-refit
//! spread, and evaluating a candidate (fit, then [`Ctx::assess`]).

use super::allowance::{generic_column_count, generic_columns, split_gain};
use super::guard::*;
use super::state::Reference;
use crate::diagnose::effects::{Calib, Candidate};
use crate::diagnose::fit::{self, channel_rss, residuals, FitResult};
use crate::diagnose::model::Prepared;
use crate::diagnose::{nrmse, CandidateOutcome};
use crate::model::Rig;
use crate::numeric::arx;

/// Most lags summed for an autocorrelation time.
const MAX_TAU_LAG: usize = 2000;

/// What every evaluation shares.
pub(crate) struct Ctx<'a> {
    pub(crate) rig: &'a Rig,
    pub(crate) fit_data: &'a [Prepared],
    pub(crate) validate: &'a Prepared,
    pub(crate) sigma: [f64; 3],
    pub(crate) calib: &'a Calib,
    pub(crate) model_freqs: &'a [f64],
    /// Step of the counts of the position sensor the drive is read from (`base_pos_m`, else
    /// the command), m; `None` when not quantised ([`crate::numeric::stats::quantum`]).
    pub(crate) drive_quantum_m: Option<f64>,
    /// Tests of one diagnosis, the family of the decision rule's level
    /// ([`super::decision::per_test_level`]): the catalogue's candidates × [`super::MAX_EFFECTS`].
    pub(crate) tests: usize,
    /// Selection trace, one entry per line ([`crate::diagnose::Diagnosis::trace`]).
    pub(crate) trace: std::cell::RefCell<Vec<String>>,
}

impl Ctx<'_> {
    pub(crate) fn trace(&self, line: String) {
        self.trace.borrow_mut().push(line);
    }

    /// The calibration and the effects `set` fitted to the fit recordings from `warm` (or the
    /// defaults), at most `max_evaluations` model evaluations, no exploratory starts
    /// ([`fit::fit`]).
    pub(crate) fn fit(
        &self,
        set: &[&Candidate],
        warm: Option<&nalgebra::DVector<f64>>,
        max_evaluations: usize,
    ) -> FitResult {
        fit::fit(
            self.rig,
            self.fit_data,
            self.sigma,
            self.calib,
            set,
            warm,
            &[],
            max_evaluations,
            false,
        )
    }

    /// The least-squares problem of the calibration and the effects `set` on the fit
    /// recordings, at representation `x`.
    pub(crate) fn fit_problem<'s>(
        &'s self,
        set: &[&'s Candidate],
        x: nalgebra::DVector<f64>,
    ) -> fit::Problem<'s> {
        fit::Problem::new(self.rig, self.fit_data, self.sigma, self.calib, set, x)
    }

    pub(crate) fn reference(&self, set: &[&Candidate], f: FitResult) -> Option<Reference> {
        let prob = self.fit_problem(set, f.x.clone());
        let preds = prob.predictions(&f.x)?;
        let res: Vec<_> = self
            .fit_data
            .iter()
            .zip(&preds)
            .map(|(d, p)| residuals(d, p))
            .collect();
        let (rss, n) = channel_rss(&res);
        let vdata = std::slice::from_ref(self.validate);
        let vprob = fit::Problem::new(self.rig, vdata, self.sigma, self.calib, set, f.x.clone());
        let vpred = vprob.predictions(&f.x)?.remove(0);
        let vres = residuals(self.validate, &vpred);
        let (vrss, vn) = channel_rss(std::slice::from_ref(&vres));
        let val_nrmse = nrmse(self.validate, &vpred);
        let has_loop = set.iter().any(|c| c.id == crate::effect::Effect::ServoLag);
        let generic = std::array::from_fn(|c| {
            let m = generic_column_count(c, has_loop);
            let (mut fit_ne, mut val_ne) = (arx::Normal::new(m), arx::Normal::new(m));
            for ((d, p), r) in self.fit_data.iter().zip(&preds).zip(&res) {
                if let (Some(r), Some(phi)) = (&r[c], generic_columns(d, p, c, has_loop)) {
                    fit_ne.add(r, &phi);
                }
            }
            let vphi = generic_columns(self.validate, &vpred, c, has_loop);
            let (Some(r), Some(phi)) = (&vres[c], vphi) else {
                return None;
            };
            val_ne.add(r, &phi);
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
            fres: res,
            tau_val,
            fit: f,
            rss,
            n,
            vres,
            vrss,
            vn,
            vpred,
            val_nrmse,
        })
    }

    /// The split-refit gain of `base` (model `set`): refitted to each fit recording alone
    /// (warm from `base`, `max_evaluations` shared), the reduction of the validation rms
    /// residual per channel ([`split_gain`], 0 for a worsening); its smallest over the
    /// recordings is what re-tuning the existing parameters to other excitation earns whichever
    /// recording it is tuned to — a gain within it is not evidence of new physics (the smallest,
    /// because one recording alone may leave the model undetermined and gain by chance). Zero
    /// with a single fit recording. Returns it and the model evaluations used.
    pub(crate) fn split_refit_gain(
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
            let f = fit::fit(
                self.rig,
                one,
                self.sigma,
                self.calib,
                set,
                Some(&base.fit.x),
                &[],
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
                    let change = split_gain((vrss[c] / base.vrss[c]).sqrt());
                    if change.is_finite() {
                        spread[c] = spread[c].min(change);
                    }
                }
            }
        }
        for v in spread.iter_mut().filter(|v| !v.is_finite()) {
            *v = 0.0;
        }
        self.trace(format!(
            "split-refit gain on the validation residual per channel: {spread:?}"
        ));
        (spread, used)
    }

    /// Fits `set` (the effects chosen so far + candidate `ci`, last) jointly with the calibration,
    /// from `seeds` first ([`fit::fit`]), and applies every guard against `base`.
    pub(crate) fn evaluate(
        &self,
        set: &[&Candidate],
        ci: usize,
        base: &Reference,
        max_evaluations: usize,
        explore: bool,
        seeds: &[nalgebra::DVector<f64>],
    ) -> Option<CandidateOutcome> {
        set.last()?;
        let f = fit::fit(
            self.rig,
            self.fit_data,
            self.sigma,
            self.calib,
            set,
            Some(&base.fit.x),
            seeds,
            max_evaluations,
            explore,
        );
        let r = self.reference(set, f)?;
        Some(self.assess(set, ci, r, base))
    }

    /// What drives channel `c` of the validation recording under model `r`: its command and
    /// `r`'s prediction of the channel (the inputs [`driven_share`] judges coherence with).
    pub(crate) fn driving<'a>(&'a self, r: &'a Reference, c: usize) -> Vec<&'a [f64]> {
        let predicted = [&r.vpred.base_m, &r.vpred.tip_m, &r.vpred.force_n][c];
        std::iter::once(self.validate.cmd_as_sampled())
            .chain(predicted.as_deref())
            .collect()
    }
}

impl Ctx<'_> {
    /// What the recordings resolve, as [`implausible`] takes it: the lowest frequency
    /// ([`Ctx::lowest_resolved_hz`]) and one count of the drive's position sensor.
    pub(crate) fn resolution(&self) -> (f64, Option<f64>) {
        (self.lowest_resolved_hz(), self.drive_quantum_m)
    }

    /// The lowest frequency (Hz) every fit recording resolves: 1 / the shortest one's duration.
    pub(crate) fn lowest_resolved_hz(&self) -> f64 {
        self.fit_data
            .iter()
            .map(|d| 1.0 / (d.cmd_m.len().max(1) as f64 * d.dt))
            .fold(0.0, f64::max)
    }
}
