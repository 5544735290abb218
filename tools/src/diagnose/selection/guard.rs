//! Selection with a guard against false discovery, shared by `diagnose` (recordings) and
//! `diagnose-lengths` (length series).
//!
//! A candidate with k free parameters is *named* only if all of these hold ([`guard`]):
//! 1. **Information criterion** on the fit data: ΔBIC = Δ(−2 ln L) + k ln N < −[`BIC_MARGIN`],
//!    with the Gaussian profile likelihood per channel, −2 ln L = Σ_c n_c ln(RSS_c / n_c)
//!    (Schwarz 1978; Kass & Raftery 1995: ΔBIC < −10 is "very strong" evidence). A residual
//!    is not white: its samples are counted as n_c / τ_c independent ones, τ_c the integrated
//!    autocorrelation time of the fit residual of the model *with* the candidate (the
//!    alternative; [`autocorrelation_time`]), so N = Σ n_c / τ_c; otherwise a slow model-form
//!    residual sampled fast makes any small gain "very strong". The alternative's τ, as a
//!    heteroscedasticity-and-autocorrelation-consistent test scales by the unrestricted
//!    model's residual (Newey & West 1987): the null's residual holds the very signature the
//!    candidate is tested for, and a slow one (friction's sign(v) square wave, a 0.02–0.08 Hz
//!    force drift beside a cogging ripple) set τ to seconds and the candidate's own evidence to
//!    a handful of samples;
//! 2. **validation** (data never fitted): the likelihood-ratio statistic Δ(−2 ln L)_val, with
//!    the effective sample count of the alternative's validation residual,
//!    < −[`VALIDATION_MARGIN`];
//! 3. **model-form allowance estimated from the data**: the relative rms reduction of the
//!    validation residual on the channel it helps most must exceed what a *physics-free*
//!    correction with the same number k of free coefficients, fitted on the fit data only,
//!    earns on the same validation residual ([`crate::numeric::arx`] for recordings: the best
//!    k-term linear filter of the model's prediction and the base motion — on `force_n` without
//!    the carriage velocity, which is not model-form freedom but viscous friction, a catalogue
//!    effect: a yardstick made of the candidate's own physics can never be beaten by it, see
//!    `allowance::FORCE_WITHOUT`; on `base_pos_m` of a model without a loop without the
//!    command's derivatives, a lag of the command being a position loop's physics,
//!    `allowance::BASE_WITHOUT_LOOP`; a correction larger than the dictionary's rank counts as
//!    the largest solvable one; for a length series
//!    the best k-term smooth trend of the relative frequency error in the length); for
//!    recordings also at least the *split-refit gain*: how much the validation rms residual
//!    drops when the model so far is refitted to one fit recording alone (the smallest such
//!    gain over the fit recordings, 0 where a refit predicts worse): a gain that re-tuning the
//!    existing parameters to other excitation also produces is no evidence of new physics. This replaces
//!    a fixed percentage chosen on one generator's floor: the allowance is large where generic
//!    model-form freedom explains much, ≈ 0 where the residual is white or unrelated to the
//!    model's input and output;
//! 4. **whiteness** (recordings): the correlated part of that validation residual (Σ of the
//!    squared autocovariances over [`LJUNG_BOX_LAGS`] lags, the Ljung–Box numerator) decreases;
//! 5. **significance**: an effect parameter whose zero means "no effect" is ≥ [`MIN_SIGMAS`] σ
//!    from zero;
//! 6. **it accounts for the structure** (recordings): on that channel the *structured* part of
//!    the validation residual — its variance above the white-noise floor, S = var(r) − σ̂², σ̂ the
//!    first-difference noise estimate of [`super::unexplained::difference_noise`] (the smaller
//!    of the two residuals' estimates) — falls by at least [`MIN_STRUCTURE_EXPLAINED`] (most of
//!    it). An effect that removes a sliver of a large structured residual is not what that
//!    residual is; the residual is reported unexplained instead of being given its name. The
//!    share is also taken in the effect's own band (the bins holding 90 % of the change it makes,
//!    `evidence::share_in_effect_band`) and the larger stands, when what the effect leaves outside
//!    that band is no response to the motion (coherent with neither the command nor the model's
//!    prediction, `evidence::driven_share`): a drive's loop hunting near the Nyquist rate beside
//!    friction on a real axis is another thing, reported unexplained; a loose sensor's ring
//!    driven by every move is the rest of the same signature, and the whole band decides. On
//!    `force_n` conditions 4 and 6 are judged outside the residual's bursts (samples beyond 6
//!    robust σ, `evidence::judged`): a drive's loop transient at an acceleration step, which the
//!    samples do not resolve and no catalogue effect models, is not what a force effect must
//!    account for. In
//!    `diagnose` the explanation may be a pair: an effect failing only this condition goes in on
//!    trial when it is a round's best, and is named with the next round's passing effect if
//!    the two together remove most of that structure (`pairs::pair_step`);
//! 7. **physically possible** (recordings): no parameter sits on the wrong side of a physical
//!    limit by more than 2 σ (a negative sensor delay — the sensor reporting before the motion —,
//!    or negative Coulomb friction), and no parameter sits at a search limit of
//!    its range (within 1 % of a bound of a bounded parameter, except a bound at 0, which means
//!    "absent"): there the fit did not find the effect, it ran out of room; and no position loop
//!    is slower than the lowest frequency the fit recordings resolve (1 / duration): as its
//!    bandwidth → 0 a loop becomes a constant gain on the command, which is not a loop (a
//!    tip-sensor scale error looked like one);
//! 8. **placed** (recordings, `mount_resonance`): the mount must beat the same resonance placed
//!    between the tip and its sensor (fitted likewise) by the margins of conditions 1–2: on
//!    `tip_pos_m` a massless mount and a loose tip sensor are the same linear filter (filters in
//!    series commute) and neither changes `base_pos_m`; only `force_n` sees the beam root move.
//!    Without that evidence the recordings cannot place the resonance and it is reported
//!    unexplained, not named;
//! 9. **placed at the clamp** (recordings, `root_compliance`): the same rotational spring free
//!    to sit anywhere along the beam nests the root spring; when it wins by the margins of
//!    conditions 1–2 at a position whose 2 σ interval lies beyond the clamp's region, the
//!    recordings reject the clamp as its place: a local compliance of the beam (a crack), outside
//!    the catalogue, reported unexplained with its position (`compliance`, `Ctx::compliance_placement`).
//!
//! Among those, the largest validation likelihood gain wins; if none passes, the answer is
//! `none`. In `diagnose` forward selection applies the guard once per round against the model
//! chosen so far; an effect whose look-alike (an effect the recorded channels see as the same
//! filter) passed in the same round is settled on the final model by the margins of conditions
//! 1–3, or reported indistinguishable from it ([`super::lookalike`]).

pub use crate::numeric::stats::{
    autocorrelation_time, delta_bic, delta_neg2ll, delta_neg2ll_effective, ljung_box, neg2ll,
    structured_power,
};

/// BIC margin (see module docs).
pub const BIC_MARGIN: f64 = 10.0;
/// Validation likelihood margin.
pub const VALIDATION_MARGIN: f64 = 10.0;
/// Minimum significance of a null-at-zero parameter.
pub const MIN_SIGMAS: f64 = 3.0;
/// Ljung–Box lags.
pub const LJUNG_BOX_LAGS: usize = 20;
/// Least fraction of the structured validation residual an effect must remove (condition 6).
pub const MIN_STRUCTURE_EXPLAINED: f64 = 0.5;

/// What a candidate brought, in the terms of the guard (module docs).
#[derive(Clone, Debug)]
pub struct Evidence {
    /// ΔBIC on the fit data against the model it extends.
    pub delta_bic: f64,
    /// Δ(−2 ln L) on the never-fitted data.
    pub delta_val: f64,
    /// Relative rms reduction of the never-fitted residual (the channel it helps most).
    pub reduction: f64,
    /// The model-form allowance: the same reduction earned by the physics-free correction with
    /// as many coefficients (or, for recordings, the larger split-refit gain).
    pub allowance: f64,
    /// Structured power of that residual before and after (`None`: not a time series).
    pub structured: Option<(f64, f64)>,
    /// Largest |value|/σ of a null-at-zero parameter (∞ if it has none).
    pub significance: f64,
    /// Fraction of the structured residual the candidate removes (`None`: not a time series).
    pub structure_explained: Option<f64>,
    /// Physical limits the fit violates, in words (condition 7).
    pub implausible: Vec<String>,
}

/// The guard of the module docs: the list of failed conditions, in words (empty: named).
pub fn guard(e: &Evidence) -> Vec<String> {
    let mut fails = Vec::new();
    if !(e.delta_bic < -BIC_MARGIN) {
        fails.push(format!("ΔBIC {:+.1} not < −{BIC_MARGIN}", e.delta_bic));
    }
    if !(e.delta_val < -VALIDATION_MARGIN) {
        fails.push(format!(
            "validation Δ(−2lnL) {:+.1} not < −{VALIDATION_MARGIN}",
            e.delta_val
        ));
    }
    if !(e.reduction > e.allowance.max(0.0)) {
        fails.push(format!(
            "validation reduction {:.1} % does not beat the model-form allowance {:.1} % (a physics-free correction with as many parameters, or a refit of the model so far to one fit recording)",
            100.0 * e.reduction,
            100.0 * e.allowance.max(0.0)
        ));
    }
    if let Some((before, after)) = e.structured {
        if !(after < before) {
            fails.push(format!(
                "correlated residual not reduced (Σc_k² {before:.2e} → {after:.2e})"
            ));
        }
    }
    if !(e.significance >= MIN_SIGMAS) {
        fails.push(format!(
            "effect parameter only {:.1} σ from zero",
            e.significance
        ));
    }
    if let Some(f) = e.structure_explained {
        if !(f >= MIN_STRUCTURE_EXPLAINED) {
            fails.push(format!(
                "removes only {:.1} % of the structured residual (less than {:.0} %): it does not account for it",
                100.0 * f,
                100.0 * MIN_STRUCTURE_EXPLAINED
            ));
        }
    }
    fails.extend(e.implausible.iter().cloned());
    fails
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strong() -> Evidence {
        Evidence {
            delta_bic: -500.0,
            delta_val: -300.0,
            reduction: 0.4,
            allowance: 0.05,
            structured: Some((2.0, 1.0)),
            significance: 12.0,
            structure_explained: Some(0.9),
            implausible: vec![],
        }
    }

    #[test]
    fn every_condition_can_fail_alone() {
        assert!(guard(&strong()).is_empty());
        let cases: [fn(&mut Evidence); 7] = [
            |e| e.delta_bic = -5.0,
            |e| e.delta_val = 3.0,
            |e| e.allowance = 0.45,
            |e| e.structured = Some((1.0, 1.5)),
            |e| e.significance = 2.0,
            |e| e.structure_explained = Some(0.2),
            |e| e.implausible = vec!["negative delay".into()],
        ];
        for f in cases {
            let mut e = strong();
            f(&mut e);
            assert_eq!(guard(&e).len(), 1, "{e:?}");
        }
        // no reduction at all fails even with a zero allowance
        let mut e = strong();
        e.reduction = 0.0;
        e.allowance = -0.1;
        assert_eq!(guard(&e).len(), 1);
    }
}
