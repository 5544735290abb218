//! The decision rule: when a candidate's gain is evidence of new physics.
//!
//! **One statistical test, calibrated on the recording itself** ([`Rule::Predictive`]): a
//! candidate is evidence only if the model with it predicts the recordings better than the model
//! it extends, by the Diebold–Mariano test of equal predictive accuracy
//! ([`crate::numeric::predictive`]): the per-sample drop of the squared residual, every recorded
//! channel of the fit recordings and of the never-fitted validation recording pooled (the fit
//! recordings' part less the gain k parameters earn on noise, [`in_sample_optimism`]),
//! standardised by its own long-run (HAC) variance. The validation recording alone holds a few
//! independent moves: a loop that removed 94 % of its residual reached only z 3.5 there
//! (independent-v2 case10), below any family-wise level. The residual's
//! autocorrelation — the model-form error a rig always leaves, sampled fast — sets the scale,
//! so the statistic's null distribution is N(0, 1) on this recording, whatever its noise colour
//! (the p-values' uniformity under the null is a unit test of that module). The level is
//! family-wise: [`FAMILY_WISE_LEVEL`] over every test of one diagnosis (Bonferroni: the
//! catalogue's candidates × the rounds of forward selection, [`per_test_level`]), so zero false
//! alarms over ~60 null recordings is the expected outcome (0.999⁶⁰ ≈ 94 %).
//!
//! Beside the test stand only comparisons and physical bounds, no tuned margin:
//! - the **model-form comparison** (condition 3 of [`super::guard`]): the candidate must gain
//!   more on the validation recording than a physics-free correction with as many coefficients
//!   fitted on the same data (a yardstick measured on this recording, not a constant);
//! - the **Wald test** of an effect parameter whose zero means "no effect", at the same per-test
//!   level ([`wald_critical_sigmas`]);
//! - **physical bounds** (condition 7: wrong sign, at a search limit, slower than the recordings
//!   resolve; the model's stated accuracy; a resonance the channels cannot place).
//!
//! [`Rule::Guard`] is the earlier conjunction ([`super::guard`]: ΔBIC and validation margins of 10, a decreasing
//! Ljung–Box numerator, ≥ 50 % of the structured residual, a 3 σ parameter), kept for the
//! ablation table in `docs/diagnose.md`; `DIAG_RULE=guard` selects it.

use crate::numeric::predictive::{diebold_mariano, one_sided_critical, PredictiveTest};

/// Family-wise false-alarm level of one diagnosis (one recording set): the probability that any
/// candidate is named on a rig without any of them.
pub const FAMILY_WISE_LEVEL: f64 = 1e-3;

/// Which decision rule selection applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// The predictive-accuracy test at a family-wise level (module docs).
    Predictive,
    /// The earlier conjunction of margins (module docs).
    Guard,
}

/// The rule of this process: [`Rule::Predictive`] unless the environment sets
/// `DIAG_RULE=guard` (for the ablation).
pub fn rule() -> Rule {
    match std::env::var("DIAG_RULE").as_deref() {
        Ok("guard") => Rule::Guard,
        _ => Rule::Predictive,
    }
}

/// The elements of the rule beside the test that the ablation table removes one at a time:
/// `DIAG_ABLATE` lists them, comma-separated (`model_accuracy`: the model's stated accuracy
/// bound on tip mass, root spring, cubic clamp and sensor gain; `observable_band`: a mount
/// resonance at or beyond the band edge not identified, and a final model's mount whose
/// frequency + 2 σ reaches the edge dropped ([`super::unplaced_in_final`]); `identified_parameters`: a parameter
/// inside its range with an undefined 1 σ fails its candidate; `final_identification`: an
/// effect the final model's honest 1 σ does not hold 3 σ from "no effect" is dropped;
/// `zero_drift_calibration`: `unexplained`'s zero-drift test read on its χ² tail without the
/// bootstrap Bartlett correction, [`crate::diagnose::unexplained::ZERO_DRIFT_REPLICATES`];
/// `quantisation_floor`: `unexplained`'s noise rms no longer at least the channel's q/√12;
/// `drive_sensitivities`: `unexplained`'s residual–input test on the commanded motion's lags
/// alone, prewhitened by Yule–Walker, without the final model's sensitivities).
/// Unset: every element applies.
pub fn ablated(element: &str) -> bool {
    std::env::var("DIAG_ABLATE")
        .map(|v| v.split(',').any(|e| e.trim() == element))
        .unwrap_or(false)
}

/// The level of one test among `tests` tests of one diagnosis (Bonferroni; selection counts
/// the catalogue's candidates × its most rounds).
pub fn per_test_level(tests: usize) -> f64 {
    FAMILY_WISE_LEVEL / tests.max(1) as f64
}

/// The two-sided Wald critical value (in σ) of an effect parameter at the per-test level.
pub fn wald_critical_sigmas(tests: usize) -> f64 {
    one_sided_critical(per_test_level(tests) / 2.0)
}

/// Residuals of one recording per channel (base, tip, force), `None` where not recorded.
pub type ChannelResiduals = [Option<Vec<f64>>; 3];

/// The Diebold–Mariano test of the residuals `with` (the model with the candidate) against
/// `without` (the model it extends): `[fit recordings, validation recording]` each, every
/// recorded channel of every recording an independent series, `optimism` the in-sample gain
/// expected of the candidate's parameters on noise ([`in_sample_optimism`]). `None` when no
/// channel has residuals of both.
pub fn predictive_test(
    with: [&[ChannelResiduals]; 2],
    without: [&[ChannelResiduals]; 2],
    optimism: f64,
) -> Option<PredictiveTest> {
    let mut pairs: Vec<(&[f64], &[f64])> = Vec::new();
    for (w, wo) in with.iter().zip(&without) {
        for (a, b) in wo.iter().zip(w.iter()) {
            for c in 0..3 {
                if let (Some(a), Some(b)) = (&a[c], &b[c]) {
                    if a.len() == b.len() {
                        pairs.push((a.as_slice(), b.as_slice()));
                    }
                }
            }
        }
    }
    diebold_mariano(&pairs, optimism)
}

/// The in-sample gain Σ d that `k` parameters fitted to noise earn on the fit recordings: χ²_k
/// has mean k for independent samples; a residual with integrated autocorrelation time τ
/// counts each independent sample τ times, so k·τ, τ the largest of the null's channels'
/// (`tau_fit`, [`crate::numeric::stats::autocorrelation_time`]).
pub fn in_sample_optimism(k: usize, tau_fit: &[f64; 3]) -> f64 {
    k as f64 * tau_fit.iter().copied().fold(1.0, f64::max)
}

/// The failure of the predictive test at the per-test level, in words (`None`: passed).
pub fn predictive_failure(t: Option<&PredictiveTest>, tests: usize) -> Option<String> {
    let level = per_test_level(tests);
    match t {
        None => Some("no validation residual to test".into()),
        Some(t) if t.p_value < level => None,
        Some(t) => Some(format!(
            "predicts the validation recording no better than the model it extends at the family-wise level {FAMILY_WISE_LEVEL} (Diebold–Mariano z {:.1}, p {:.1e} ≥ {:.1e})",
            t.z, t.p_value, level
        )),
    }
}

/// The conditions of [`Rule::Predictive`] on one candidate (module docs), in words (empty:
/// evidence of new physics): the predictive test, the model-form comparison, the Wald test of
/// an effect parameter at the per-test level of `tests` tests, and the physical bounds.
pub fn predictive_guard(
    e: &super::guard::Evidence,
    t: Option<&PredictiveTest>,
    tests: usize,
) -> Vec<String> {
    let mut fails: Vec<String> = predictive_failure(t, tests).into_iter().collect();
    if !(e.reduction > e.allowance.max(0.0)) {
        fails.push(format!(
            "validation reduction {:.1} % does not beat the model-form allowance {:.1} % (a physics-free correction with as many parameters, or a refit of the model so far to one fit recording)",
            100.0 * e.reduction,
            100.0 * e.allowance.max(0.0)
        ));
    }
    let z = wald_critical_sigmas(tests);
    if !(e.significance >= z) {
        fails.push(format!(
            "effect parameter only {:.1} σ from zero (the per-test level asks {z:.1} σ)",
            e.significance
        ));
    }
    fails.extend(e.implausible.iter().cloned());
    fails
}
