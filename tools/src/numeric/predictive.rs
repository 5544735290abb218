//! Equal predictive accuracy of two models on data neither was fitted to: the Diebold–Mariano
//! test (Diebold & Mariano 1995) with a heteroscedasticity-and-autocorrelation-consistent
//! long-run variance (the autoregressive spectral estimator at frequency zero, order by AIC:
//! Berk 1974, den Haan & Levin 1997).
//!
//! The loss differential of sample t is d_t = (r0_t² − r1_t²) / s0², the drop of the squared
//! residual from model 0 (the null) to model 1 (the alternative) in units of model 0's residual
//! variance s0² = Σ r0² / n: Σ_t d_t ≈ −n ln(RSS1/RSS0), the Gaussian profile log-likelihood
//! ratio of the two predictions. With δ = r0 − r1 the change of the prediction,
//! d_t = (2 r1_t δ_t + δ_t²) / s0²: the δ² part is the change itself, deterministic, and only the
//! cross term is what noise makes of it. So Σ d is standardised by the cross term's long-run
//! variance, Var(Σ d) = 4 n Ω̂(r1 δ) / s0⁴ — the alternative's residual along the change, as a
//! heteroscedasticity-and-autocorrelation-consistent test scales by the unrestricted model's
//! residual (Newey & West 1987). (Diebold & Mariano's Ω̂(d) also counts the deterministic
//! variation of δ² between moves as noise: a loop that removed 84 % of a validation residual
//! held z < 4.) Under the null "model 1 predicts no better" z = Σ d / √Var is at most N(0, 1)
//! on data model 1 was not fitted to; the residual's own autocorrelation sets the scale, so a
//! slow model-form residual sampled fast is not counted as many independent samples. Series
//! (channels, recordings) are pooled as independent: z = Σ Σ_t d / √(Σ Var) (their covariance
//! is not estimated).

use statrs::distribution::{ContinuousCDF, Normal};

/// The test's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictiveTest {
    /// The standardised mean loss differential (positive: the alternative predicts better).
    pub z: f64,
    /// One-sided p-value of the null "the alternative predicts no better", 1 − Φ(z).
    pub p_value: f64,
    /// Σ_t d_t over every channel: ≈ −Δ(−2 ln L) of the two predictions, counting every sample
    /// as independent (before the autocorrelation correction that `z` makes).
    pub gain: f64,
}

/// Long-run variance of `d` (mean removed; 2π × its spectral density at zero): the
/// autoregressive spectral estimator (Berk 1974; den Haan & Levin 1997, "VARHAC"), the order
/// chosen by AIC up to ⌊√n⌋ ([`crate::numeric::stats::Autoregressive::fit_aic`]). The cap grows
/// with the series (p → ∞, p/n → 0: consistent, Berk 1974) so that a lightly damped residual's
/// long, oscillating memory fits; a kernel estimator with Andrews' (1991) AR(1) plug-in bandwidth
/// undercounts exactly that memory (the module's test: a residual ringing at 0.5 % damping along
/// a ringing change gave z with standard deviation 1.7 against 1.0; docs/diagnose.md, "The
/// decision rule"). 0 for a constant `d`, NaN for fewer than two samples.
pub fn long_run_variance(d: &[f64]) -> f64 {
    let n = d.len();
    if n < 2 {
        return f64::NAN;
    }
    let max_order = ((n as f64).sqrt() as usize).min(n - 2);
    crate::numeric::stats::Autoregressive::fit_aic(d, max_order)
        .map_or(0.0, |m| m.spectrum_at_zero())
}

/// The Diebold–Mariano test over series: `pairs[i] = (r0, r1)`, the null's and the
/// alternative's residuals of one channel of one recording on the same samples (equal
/// lengths; series with fewer than two samples are skipped), each its own independent series;
/// `optimism` (in units of d) is subtracted from Σ d before standardising: the expected gain of
/// the alternative's extra parameters fitted to noise on series that were fitted (0 when every
/// series is out of sample). `None` when no series has data or the long-run variance vanishes
/// (identical predictions).
pub fn diebold_mariano(pairs: &[(&[f64], &[f64])], optimism: f64) -> Option<PredictiveTest> {
    let (mut sum, mut var) = (-optimism, 0.0);
    for (r0, r1) in pairs {
        let n = r0.len().min(r1.len());
        if n < 2 {
            continue;
        }
        let s0 = r0[..n].iter().map(|v| v * v).sum::<f64>() / n as f64;
        if !(s0 > 0.0) {
            continue;
        }
        // d_t = (r0² − r1²)/s0² = (2 r1 δ + δ²)/s0² with δ = r0 − r1 the change of the
        // prediction: δ² is the change itself, not noise; what noise makes of Σ d is the cross
        // term, whose variance is 4 n Ω(r1 δ) / s0⁴
        let cross: Vec<f64> = (0..n).map(|t| r1[t] * (r0[t] - r1[t])).collect();
        sum += (0..n).map(|t| r0[t] * r0[t] - r1[t] * r1[t]).sum::<f64>() / s0;
        var += 4.0 * n as f64 * long_run_variance(&cross) / (s0 * s0);
    }
    if !(var > 0.0) || !var.is_finite() {
        return None;
    }
    let z = sum / var.sqrt();
    let normal = Normal::standard();
    Some(PredictiveTest {
        z,
        p_value: normal.sf(z),
        gain: sum,
    })
}

/// The standard normal quantile z with 1 − Φ(z) = `p` (the one-sided critical value of a level).
pub fn one_sided_critical(p: f64) -> f64 {
    Normal::standard().inverse_cdf(1.0 - p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    /// AR(1) noise with coefficient `a`.
    fn ar1(n: usize, a: f64, rng: &mut rand::rngs::StdRng) -> Vec<f64> {
        let mut x = 0.0;
        (0..n)
            .map(|_| {
                x = a * x + rng.sample::<f64, _>(StandardNormal);
                x
            })
            .collect()
    }

    #[test]
    fn long_run_variance_of_ar1_is_its_spectrum_at_zero() {
        // AR(1) with a = 0.9 and unit innovations: long-run variance 1 / (1 − a)² = 100
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let x = ar1(200_000, 0.9, &mut rng);
        let lrv = long_run_variance(&x);
        assert!((lrv / 100.0 - 1.0).abs() < 0.15, "{lrv}");
    }

    #[test]
    fn p_values_are_uniform_under_the_null_with_coloured_residuals() {
        // two predictions equally good: each residual is the same coloured noise plus its own
        // independent coloured error of equal size; the one-sided test must reject at its level
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let trials = 400;
        let mut below = [0usize; 2];
        for _ in 0..trials {
            let common = ar1(3000, 0.95, &mut rng);
            let e0 = ar1(3000, 0.95, &mut rng);
            let e1 = ar1(3000, 0.95, &mut rng);
            let r0: Vec<f64> = common.iter().zip(&e0).map(|(c, e)| c + 0.5 * e).collect();
            let r1: Vec<f64> = common.iter().zip(&e1).map(|(c, e)| c + 0.5 * e).collect();
            let t = diebold_mariano(&[(&r0, &r1)], 0.0).unwrap();
            below[0] += (t.p_value < 0.05) as usize;
            below[1] += (t.p_value < 0.5) as usize;
        }
        let rate = below[0] as f64 / trials as f64;
        assert!(rate < 0.10, "rejection rate at 5 %: {rate}");
        let half = below[1] as f64 / trials as f64;
        assert!((half - 0.5).abs() < 0.1, "rate below the median: {half}");
    }

    #[test]
    fn the_scale_holds_for_a_lightly_damped_residual_along_a_ringing_change() {
        // the residual rings at 3.4 Hz sampled at 100 Hz (poles at radius 0.995: 0.5 % of
        // critical damping per cycle ~ a beam mode's leftover); the change is a ringing after a
        // move every 10 s, at the same frequency. Equal accuracy in expectation (the change is
        // added to and taken from the residual alike), so z should have unit spread.
        use crate::numeric::stats::Autoregressive;
        let (n, fs, f) = (6000usize, 100.0, 3.4);
        let th = 2.0 * std::f64::consts::PI * f / fs;
        let ar = Autoregressive {
            coefficients: vec![2.0 * 0.995 * th.cos(), -0.995 * 0.995],
            innovation_variance: 1.0,
        };
        let change: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / fs;
                let tt = (t - 1.0).rem_euclid(10.0);
                if t < 1.0 {
                    0.0
                } else {
                    (-0.3 * tt).exp() * (2.0 * std::f64::consts::PI * f * tt).sin()
                }
            })
            .collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let trials = 200;
        let zs: Vec<f64> = (0..trials)
            .map(|_| {
                let r = ar.simulate(n, || rng.sample(StandardNormal));
                // r0 = r + δ/2, r1 = r − δ/2: the same size, the change's sign by chance
                let r0: Vec<f64> = r.iter().zip(&change).map(|(r, c)| r + 0.5 * c).collect();
                let r1: Vec<f64> = r.iter().zip(&change).map(|(r, c)| r - 0.5 * c).collect();
                diebold_mariano(&[(&r0, &r1)], 0.0).unwrap().z
            })
            .collect();
        let sd = (zs.iter().map(|z| z * z).sum::<f64>() / trials as f64).sqrt();
        assert!(sd < 1.3, "spread of z: {sd}");
    }

    #[test]
    fn a_better_prediction_is_found() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let noise = ar1(5000, 0.8, &mut rng);
        let signal: Vec<f64> = (0..5000).map(|t| (t as f64 * 0.01).sin()).collect();
        let r0: Vec<f64> = noise.iter().zip(&signal).map(|(n, s)| n + s).collect();
        let t = diebold_mariano(&[(&r0, &noise)], 0.0).unwrap();
        assert!(t.z > 5.0 && t.p_value < 1e-6, "{t:?}");
        let back = diebold_mariano(&[(&noise, &r0)], 0.0).unwrap();
        assert!(back.z < 0.0 && back.p_value > 0.5, "{back:?}");
    }
}
