//! Is a residual independent of the input that drove the recording? The residual–input
//! cross-correlation test of system identification (Ljung 1999, *System Identification*, 2nd
//! ed., §16.6; Box & Jenkins 1976, §11.3: prewhitening).
//!
//! A model that leaves out part of the physics leaves a residual that the drive predicts; noise,
//! however coloured, does not correlate with a drive it does not see. The whiteness of the
//! residual alone (Ljung–Box) cannot tell the two apart: a sensor's coloured noise or a loop's
//! stationary jitter is structured in time but carries no information about the input.
//!
//! Method: the residual ε (mean removed) is fitted by an autoregressive model A(q) (order by
//! Akaike's criterion up to the caller's bound, [`crate::numeric::stats::Autoregressive`]);
//! the same filter is applied to the residual and to every input (e = A(q) ε, ũ_i = A(q) u_i),
//! so that under the hypothesis "ε is noise independent of u" e is white and its regression on
//! the filtered inputs' lags 0 … L − 1 explains nothing but chance. The Lagrange-multiplier
//! form of that regression's significance, n R² (Breusch & Godfrey's auxiliary regression), is
//! χ² with as many degrees of freedom as the lagged inputs' rank (Ljung's ζ of §16.6 with the
//! residual prewhitened). Columns are scaled to unit rms and solved by SVD, so collinear lags
//! (a trapezoid's piecewise-constant acceleration) lose degrees of freedom, not accuracy.
//!
//! The one discrepancy a drive does not excite and a model should still not leave is a slow
//! change of a sensor's zero (a thermal drift, a camera mount settling): [`slow_trend_test`]
//! tests the residual's polynomial trend against its own stationary long-run variance.

use nalgebra::{DMatrix, DVector};

/// The residual–input test's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct InputIndependence {
    /// n R² of the prewhitened residual's regression on the prewhitened inputs' lags
    /// (χ²(`degrees_of_freedom`) under independence).
    pub statistic: f64,
    /// Rank of the lagged inputs (at most inputs × lags).
    pub degrees_of_freedom: usize,
    /// Upper-tail probability of `statistic` under independence.
    pub p_value: f64,
    /// Order of the prewhitening autoregression.
    pub prewhitening_order: usize,
}

/// Tests whether `residual` is independent of `inputs` (each as long as the residual, same
/// sampling) over lags 0 … `lags` − 1 of every input, the residual prewhitened by an
/// autoregression of order ≤ `max_order` (module docs). `None` when the residual is constant,
/// shorter than `max_order + lags + 2 × inputs × lags` samples, an input's length differs, or
/// no input varies.
pub fn residual_input_test(
    residual: &[f64],
    inputs: &[&[f64]],
    lags: usize,
    max_order: usize,
) -> Option<InputIndependence> {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    let n = residual.len();
    let k = inputs.len() * lags;
    if lags == 0 || k == 0 || n < max_order + lags + 2 * k || inputs.iter().any(|u| u.len() != n) {
        return None;
    }
    let centred = |x: &[f64]| -> Vec<f64> {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        x.iter().map(|v| v - m).collect()
    };
    let eps = centred(residual);
    let ar = crate::numeric::stats::Autoregressive::fit_aic(&eps, max_order)?;
    let a = &ar.coefficients;
    let p = a.len();
    let filter = |x: &[f64]| -> Vec<f64> {
        (p..n)
            .map(|t| x[t] - (1..=p).map(|j| a[j - 1] * x[t - j]).sum::<f64>())
            .collect()
    };
    let e = filter(&eps);
    let u: Vec<Vec<f64>> = inputs.iter().map(|x| filter(&centred(x))).collect();
    // rows t = lags − 1 … (the filtered series' index), columns ũ_i(t − τ)
    let rows = e.len() - (lags - 1);
    let mut x = DMatrix::<f64>::zeros(rows, k);
    for (i, ui) in u.iter().enumerate() {
        for tau in 0..lags {
            let col: Vec<f64> = (0..rows).map(|r| ui[r + lags - 1 - tau]).collect();
            let s = (col.iter().map(|v| v * v).sum::<f64>() / rows as f64).sqrt();
            if s > 0.0 {
                for (r, v) in col.into_iter().enumerate() {
                    x[(r, i * lags + tau)] = v / s;
                }
            }
        }
    }
    let y = DVector::from_iterator(rows, e[lags - 1..].iter().copied());
    let syy = y.norm_squared();
    if !(syy > 0.0) {
        return None;
    }
    // the projection of y on the columns' span: Σ (u_i · y)² over the left singular vectors
    // of the singular values above the rank tolerance
    let svd = x.svd(true, false);
    let smax = svd.singular_values.max();
    let u_left = svd.u.as_ref()?;
    if !(smax > 0.0) {
        return None;
    }
    let tol = smax * 1e-8;
    let mut rank = 0;
    let mut explained = 0.0;
    for (i, &s) in svd.singular_values.iter().enumerate() {
        if s > tol {
            rank += 1;
            explained += u_left.column(i).dot(&y).powi(2);
        }
    }
    let statistic = rows as f64 * explained / syy;
    let p_value = ChiSquared::new(rank.max(1) as f64).map_or(f64::NAN, |d| 1.0 - d.cdf(statistic));
    Some(InputIndependence {
        statistic,
        degrees_of_freedom: rank,
        p_value,
        prewhitening_order: p,
    })
}

/// A slow change of a residual's zero over the recording: its least-squares polynomial in time
/// of degree ≤ `degree` (offset, ramp, bow, …: Legendre polynomials on the recording's span)
/// against the stationary noise it would otherwise be. The Wald statistic ‖X β̂‖² / Ω̂ is
/// χ²(`degree` + 1) under "the residual is stationary noise with zero mean", Ω̂ the long-run
/// variance (the autoregressive spectral estimator at zero, order by AIC up to `max_order`,
/// Berk 1974) of the residual less its trend (for regressors that vary slowly the least-squares
/// coefficients' covariance is Ω (XᵀX)⁻¹; Grenander 1954). Noise coloured at low frequency raises
/// Ω̂ and so the bar; a thermal drift of a sensor's zero is what clears it. Like every test
/// on a long-run variance it is liberal where the noise's memory is long against the record
/// (an AR(1) at 0.98, 3000 samples: 19 of 200 below 5 %, 2 below 0.1 %).
#[derive(Clone, Debug, PartialEq)]
pub struct SlowTrend {
    /// ‖X β̂‖² / Ω̂.
    pub statistic: f64,
    /// `degree` + 1.
    pub degrees_of_freedom: usize,
    /// Upper-tail probability under stationary zero-mean noise.
    pub p_value: f64,
    /// rms of the fitted trend (the residual's unit).
    pub trend_rms: f64,
}

/// [`SlowTrend`] of `residual`; `None` for fewer than `max_order + degree + 3` samples or a
/// residual whose detrended part is constant.
pub fn slow_trend_test(residual: &[f64], degree: usize, max_order: usize) -> Option<SlowTrend> {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    let n = residual.len();
    if n < max_order + degree + 3 {
        return None;
    }
    let k = degree + 1;
    // Legendre polynomials by their recurrence on x ∈ [−1, 1]
    let x = DMatrix::<f64>::from_fn(n, k, |i, j| {
        let t = 2.0 * i as f64 / (n - 1) as f64 - 1.0;
        let (mut p0, mut p1) = (1.0, t);
        match j {
            0 => 1.0,
            1 => t,
            _ => {
                for m in 1..j {
                    let p2 = ((2 * m + 1) as f64 * t * p1 - m as f64 * p0) / (m + 1) as f64;
                    p0 = p1;
                    p1 = p2;
                }
                p1
            }
        }
    });
    let y = DVector::from_column_slice(residual);
    let beta = x.clone().svd(true, true).solve(&y, 1e-12).ok()?;
    let fitted = &x * beta;
    let detrended: Vec<f64> = (0..n).map(|i| y[i] - fitted[i]).collect();
    let omega =
        crate::numeric::stats::Autoregressive::fit_aic(&detrended, max_order)?.spectrum_at_zero();
    if !(omega > 0.0) {
        return None;
    }
    let explained = fitted.norm_squared();
    let statistic = explained / omega;
    let p_value = ChiSquared::new(k as f64).map_or(f64::NAN, |d| 1.0 - d.cdf(statistic));
    Some(SlowTrend {
        statistic,
        degrees_of_freedom: k,
        p_value,
        trend_rms: (explained / n as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A trapezoid move's commanded velocity and acceleration repeated, 100 Hz: moves of 1 s,
    /// rests of 2 s.
    fn drive(n: usize) -> (Vec<f64>, Vec<f64>) {
        let rate = 100.0;
        let vel: Vec<f64> = (0..n)
            .map(|i| {
                let t = (i as f64 / rate) % 3.0;
                let sign = if ((i as f64 / rate) / 3.0) as usize % 2 == 0 {
                    1.0
                } else {
                    -1.0
                };
                sign * (t / 0.2).min(1.0).min(((1.0 - t) / 0.2).max(0.0))
            })
            .collect();
        let acc: Vec<f64> = (0..n)
            .map(|i| (vel[(i + 1).min(n - 1)] - vel[i]) * rate)
            .collect();
        (vel, acc)
    }

    /// `n` independent N(0, 1) draws.
    fn white(rng: &mut rand::rngs::StdRng, n: usize) -> Vec<f64> {
        let normal = Normal::new(0.0, 1.0).unwrap();
        (0..n).map(|_| normal.sample(rng)).collect()
    }

    /// Lightly damped resonance (2 Hz at 100 Hz, ζ 0.02) driven by `w`: what a residual that
    /// rings looks like.
    fn ring(w: &[f64]) -> Vec<f64> {
        let (f, zeta, dt) = (2.0, 0.02, 0.01);
        let wn = 2.0 * std::f64::consts::PI * f;
        let r = (-zeta * wn * dt).exp();
        let (a1, a2) = (2.0 * r * (wn * dt).cos(), -r * r);
        let mut y = vec![0.0; w.len()];
        for t in 2..w.len() {
            y[t] = a1 * y[t - 1] + a2 * y[t - 2] + w[t];
        }
        y
    }

    #[test]
    fn ringing_noise_that_does_not_see_the_drive_is_independent_of_it() {
        // Ljung–Box calls this structure every time; the test holds its level
        let n = 4000;
        let (vel, acc) = drive(n);
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut rejections = 0;
        let trials = 200;
        for _ in 0..trials {
            let eps = ring(&white(&mut rng, n));
            let q = crate::numeric::stats::ljung_box(&eps, 20);
            assert!(q > 45.3, "the noise is structured in time: Q {q}");
            let t = residual_input_test(&eps, &[&vel, &acc], 20, 50).unwrap();
            if t.p_value < 0.05 {
                rejections += 1;
            }
        }
        // binomial(200, 0.05): P(≥ 19) ≈ 0.03 (11 with this seed)
        assert!(rejections < 19, "{rejections} of {trials} rejected at 5 %");
    }

    #[test]
    fn a_residual_the_drive_excites_is_not_independent_of_it() {
        let n = 4000;
        let (vel, acc) = drive(n);
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let noise = ring(&white(&mut rng, n));
        let noise_rms = (noise.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        // a ringing response to the acceleration a fifth of the noise's rms
        let driven = ring(&acc);
        let driven_rms = (driven.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let eps: Vec<f64> = noise
            .iter()
            .zip(&driven)
            .map(|(a, b)| a + 0.2 * noise_rms / driven_rms * b)
            .collect();
        let t = residual_input_test(&eps, &[&vel, &acc], 20, 50).unwrap();
        assert!(t.p_value < 1e-6, "{t:?}");
    }

    #[test]
    fn low_frequency_noise_is_not_a_drift_and_a_ramp_is() {
        // noise with a memory of ten samples: its trend is what its own long-run variance
        // allows; the same noise with a ramp of its own rms is a drift
        let n = 3000;
        let mut rng = rand::rngs::StdRng::seed_from_u64(13);
        let mut rejections = 0;
        let trials = 200;
        let slow = |w: &[f64]| -> Vec<f64> {
            let mut y = vec![0.0; w.len()];
            for t in 1..w.len() {
                y[t] = 0.9 * y[t - 1] + w[t];
            }
            y
        };
        for _ in 0..trials {
            let t = slow_trend_test(&slow(&white(&mut rng, n)), 2, 50).unwrap();
            if t.p_value < 0.05 {
                rejections += 1;
            }
        }
        // binomial(200, 0.05): P(≥ 19) ≈ 0.03
        assert!(rejections < 19, "{rejections} of {trials} rejected at 5 %");
        let noise = slow(&white(&mut rng, n));
        let s = (noise.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let ramp: Vec<f64> = noise
            .iter()
            .enumerate()
            .map(|(i, v)| v + s * 3f64.sqrt() * (2.0 * i as f64 / n as f64 - 1.0))
            .collect();
        let t = slow_trend_test(&ramp, 2, 50).unwrap();
        assert!(t.p_value < 1e-6, "{t:?}");
        assert!((t.trend_rms / s - 1.0).abs() < 0.3, "{t:?}");
    }

    #[test]
    fn too_short_or_mismatched_gives_nothing() {
        let (vel, acc) = drive(100);
        let r = vec![1.0; 100];
        assert!(residual_input_test(&r, &[&vel, &acc], 20, 50).is_none());
        let r: Vec<f64> = (0..4000).map(|i| (i as f64).sin()).collect();
        assert!(residual_input_test(&r, &[&vel], 20, 50).is_none());
    }
}
