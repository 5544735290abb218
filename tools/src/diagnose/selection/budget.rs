//! The work budget of one diagnosis ([`Budget`]): model evaluations, counted in samples
//! simulated and never on the clock, so the same recordings give the same answer on any machine.

/// Work budget of one diagnosis in *sample-evaluations*: model evaluations × samples of the fit
/// recordings simulated per evaluation. Counted, not timed, so the answer does not depend on
/// the machine or its load; sized so that three 60–90 s recordings with four effects stay
/// under a minute on a 2-core machine (the measured run times: docs/diagnose.md, "Run time"
/// and "Session 17").
pub const WORK_BUDGET_SAMPLE_EVALUATIONS: f64 = 2.0e8;

/// Bounds of the resulting number of model evaluations of one diagnosis.
pub const EVALUATION_BUDGET_RANGE: (usize, usize) = (2_000, 40_000);

/// The model-evaluation budget of one diagnosis and what has been spent of it: the evaluations
/// the fits report ([`Budget::spend`]). Every sample the simulator runs on this thread is
/// counted besides ([`crate::diagnose::model::simulated_samples`], [`Budget::simulated`]) to show how much
/// simulation happens outside the fits (on the README's run-time case, everything simulated came
/// to 3 157 evaluations against the fits' 3 197: the run time is the cost per evaluation, not
/// uncounted work; docs/diagnose.md, "Session 36").
pub(crate) struct Budget {
    /// Evaluations of the fit recordings the diagnosis may spend.
    pub(crate) total: usize,
    /// Evaluations the fits reported.
    pub(crate) spent: usize,
    /// Samples of one evaluation of the fit recordings.
    fit_samples: u64,
    /// [`crate::diagnose::model::simulated_samples`] when the budget was made.
    start: u64,
}

impl Budget {
    /// The budget for fit recordings of `fit_samples` samples in total.
    pub(crate) fn for_samples(fit_samples: usize) -> Budget {
        let (lo, hi) = EVALUATION_BUDGET_RANGE;
        let total = (WORK_BUDGET_SAMPLE_EVALUATIONS / fit_samples.max(1) as f64) as usize;
        Budget {
            total: total.clamp(lo, hi),
            spent: 0,
            fit_samples: fit_samples.max(1) as u64,
            start: crate::diagnose::model::simulated_samples(),
        }
    }

    /// Everything simulated on this thread since the budget was made (fits, validation
    /// predictions, refits), in evaluations of the fit recordings.
    pub(crate) fn simulated(&self) -> usize {
        ((crate::diagnose::model::simulated_samples() - self.start) / self.fit_samples) as usize
    }

    /// An equal share of what is left for one of `parts` remaining fits (at least 1/200 of the
    /// budget, so that a late fit still gets a few iterations).
    pub(crate) fn share(&self, parts: usize) -> usize {
        (self.total.saturating_sub(self.spent) / parts.max(1)).max(self.total / 200)
    }

    pub(crate) fn spend(&mut self, evaluations: usize) {
        self.spent += evaluations;
    }

    /// Adds a third of the budget to what is left (the spent part counted as at most the
    /// total): the work of a selection resumed after the final model dropped an effect
    /// ([`resume_after_drop`]), which the first selection, unaware of it, may have used up.
    pub(crate) fn extend_for_resumption(&mut self) {
        self.total = self.total.max(self.spent) + self.total / 3;
    }

    pub(crate) fn fraction_spent(&self) -> f64 {
        self.spent as f64 / self.total as f64
    }
}
