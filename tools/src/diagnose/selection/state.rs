//! What the selection holds: a fitted model as a round compares with it ([`Reference`]), the
//! selection so far ([`Selection`]), and the sets of candidates a fit is made of.

use crate::diagnose::effects::Candidate;
use crate::diagnose::fit::FitResult;
use crate::diagnose::model::{Prediction, Prepared};
use crate::diagnose::CandidateOutcome;
use crate::effect::Effect;
use crate::numeric::arx;

/// The model a round compares against: its fit and residuals on fit and validation data.
#[derive(Clone, Debug)]
pub(crate) struct Reference {
    pub(crate) fit: FitResult,
    pub(crate) rss: [f64; 3],
    /// Samples per channel on the fit recordings (of `rss`).
    pub(crate) n: [usize; 3],
    pub(crate) vres: [Option<Vec<f64>>; 3],
    pub(crate) vrss: [f64; 3],
    pub(crate) vn: [usize; 3],
    pub(crate) vpred: Prediction,
    pub(crate) val_nrmse: [f64; 3],
    /// Per channel, the normal equations of the physics-free correction of this model's
    /// residual on the fit recordings and on the validation recording.
    pub(crate) generic: [Option<(arx::Normal, arx::Normal)>; 3],
    /// Per channel, the integrated autocorrelation time of this model's residual on the fit
    /// recordings (length-weighted mean) and on the validation recording.
    pub(crate) tau_fit: [f64; 3],
    /// Per fit recording, this model's residuals per channel (the decision rule's in-sample
    /// part, [`super::decision::predictive_test`]).
    pub(crate) fres: Vec<[Option<Vec<f64>>; 3]>,
    pub(crate) tau_val: [f64; 3],
    /// Per channel, how much the validation rms residual drops when this model is refitted to
    /// one fit recording alone (the smallest relative gain over the fit recordings, 0 for a
    /// worsening; [`Ctx::split_refit_gain`]), 0 until computed.
    pub(crate) split: [f64; 3],
}

impl Reference {
    /// The predictive test of this model against `without`, the model it is compared with
    /// ([`super::decision::predictive_test`]: fit and validation residuals, every recorded
    /// channel), charging this model the in-sample gain of its `extra_params` parameters beyond
    /// `without`'s ([`super::decision::in_sample_optimism`], at `without`'s autocorrelation time).
    pub(crate) fn predictive_test_against(
        &self,
        without: &Reference,
        extra_params: usize,
    ) -> Option<crate::numeric::predictive::PredictiveTest> {
        super::decision::predictive_test(
            [&self.fres[..], std::slice::from_ref(&self.vres)],
            [&without.fres[..], std::slice::from_ref(&without.vres)],
            super::decision::in_sample_optimism(extra_params, &without.tau_fit),
        )
    }
}

/// What forward selection ends with.
#[derive(Clone)]
pub(crate) struct Selection {
    /// Catalogue indices of the chosen effects, in order.
    pub(crate) chosen: Vec<usize>,
    /// Each chosen effect as evaluated when it was added.
    pub(crate) outcomes: Vec<CandidateOutcome>,
    /// The final model (calibration + chosen effects, jointly refitted).
    pub(crate) reference: Reference,
    /// Every round's candidates (best validation gain first).
    pub(crate) rounds: Vec<Vec<CandidateOutcome>>,
    /// Progress steps used.
    pub(crate) step: usize,
    /// Effects the final model dropped as not identified: never offered again.
    pub(crate) dropped: Vec<Effect>,
}

/// Candidates that do not conflict with any chosen effect and were not dropped.
pub(crate) fn pool_of(cands: &[Candidate], sel: &Selection) -> Vec<usize> {
    (0..cands.len())
        .filter(|&i| {
            sel.chosen
                .iter()
                .all(|&k| !cands[k].id.conflicts_with(cands[i].id))
                && !sel.dropped.contains(&cands[i].id)
        })
        .collect()
}

/// The candidates of `chosen`.
pub(crate) fn set_of<'c>(cands: &'c [Candidate], chosen: &[usize]) -> Vec<&'c Candidate> {
    chosen.iter().map(|&k| &cands[k]).collect()
}

/// Candidate `ci` on top of the effects `chosen`.
pub(crate) fn joint_set<'c>(
    cands: &'c [Candidate],
    chosen: &[usize],
    ci: usize,
) -> Vec<&'c Candidate> {
    set_of(cands, chosen)
        .into_iter()
        .chain(std::iter::once(&cands[ci]))
        .collect()
}

/// Samples per channel of `data` (0 where a channel is not recorded).
pub(crate) fn n_of(data: &[Prepared]) -> [usize; 3] {
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
