//! Selection with a guard against false discovery.
//!
//! A candidate is *named* only if all of these hold:
//! 1. **Information criterion** on the fit recordings: ΔBIC = Δ(−2 ln L) + k ln N < −[`BIC_MARGIN`],
//!    with the Gaussian profile likelihood per channel, −2 ln L = Σ_c n_c ln(RSS_c / n_c)
//!    (Schwarz 1978; Kass & Raftery 1995: ΔBIC < −10 is "very strong" evidence);
//! 2. **validation** (a recording never fitted): Δ(−2 ln L)_val < −[`VALIDATION_MARGIN`] *and* the
//!    NRMSE of the channel it helps most falls by at least [`MIN_VALIDATION_REDUCTION`];
//! 3. **whiteness**: the Ljung–Box statistic (Ljung & Box 1978) of that validation residual
//!    (20 lags) decreases;
//! 4. **significance**: an effect parameter whose zero means "no effect" is ≥ [`MIN_SIGMAS`] σ
//!    from zero.
//!
//! Among those, the largest validation likelihood gain wins; if none passes, the answer is
//! `none`.

/// BIC margin (see module docs).
pub const BIC_MARGIN: f64 = 10.0;
/// Validation likelihood margin.
pub const VALIDATION_MARGIN: f64 = 10.0;
/// Minimum relative NRMSE reduction on the validation recording.
pub const MIN_VALIDATION_REDUCTION: f64 = 0.06;
/// Minimum significance of a null-at-zero parameter.
pub const MIN_SIGMAS: f64 = 3.0;
/// Ljung–Box lags.
pub const LJUNG_BOX_LAGS: usize = 20;

/// −2 ln L of the per-channel Gaussian profile likelihood.
pub fn neg2ll(rss: &[f64; 3], n: &[usize; 3]) -> f64 {
    (0..3)
        .filter(|&c| n[c] > 0)
        .map(|c| n[c] as f64 * (rss[c].max(1e-300) / n[c] as f64).ln())
        .sum()
}

/// Δ(−2 ln L) of `rss` against `rss0` (same samples).
pub fn delta_neg2ll(rss: &[f64; 3], rss0: &[f64; 3], n: &[usize; 3]) -> f64 {
    (0..3)
        .filter(|&c| n[c] > 0)
        .map(|c| n[c] as f64 * (rss[c].max(1e-300) / rss0[c].max(1e-300)).ln())
        .sum()
}

/// Structured (correlated) power of `r`: Σ_{k=1..lags} c_k² with the autocovariances c_k, i.e.
/// the Ljung–Box statistic's numerator before normalising by the variance: it falls when a
/// model removes correlated residual, whatever happens to the white part.
pub fn structured_power(r: &[f64], lags: usize) -> f64 {
    let n = r.len();
    if n <= lags + 1 {
        return 0.0;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    (1..=lags)
        .map(|k| ((k..n).map(|i| (r[i] - m) * (r[i - k] - m)).sum::<f64>() / n as f64).powi(2))
        .sum()
}

/// Ljung–Box Q over `lags` lags of `r`.
pub fn ljung_box(r: &[f64], lags: usize) -> f64 {
    let n = r.len();
    if n <= lags + 1 {
        return 0.0;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    let c0: f64 = r.iter().map(|x| (x - m).powi(2)).sum();
    if c0 <= 0.0 {
        return 0.0;
    }
    let mut q = 0.0;
    for k in 1..=lags {
        let ck: f64 = (k..n).map(|i| (r[i] - m) * (r[i - k] - m)).sum();
        let rho = ck / c0;
        q += rho * rho / (n - k) as f64;
    }
    q * n as f64 * (n + 2) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn ljung_box_separates_white_from_structured() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let d = Normal::new(0.0, 1.0).unwrap();
        let white: Vec<f64> = (0..5000).map(|_| d.sample(&mut rng)).collect();
        let q = ljung_box(&white, 20);
        // chi-square with 20 dof: 99.9 % quantile 45.3
        assert!(q < 45.3, "{q}");
        let colored: Vec<f64> = white
            .iter()
            .enumerate()
            .map(|(k, x)| x + (k as f64 * 0.3).sin())
            .collect();
        assert!(ljung_box(&colored, 20) > 10.0 * q);
    }

    #[test]
    fn likelihood_deltas() {
        let n = [100, 0, 100];
        assert_eq!(delta_neg2ll(&[1.0, 0.0, 2.0], &[1.0, 0.0, 2.0], &n), 0.0);
        assert!(
            (delta_neg2ll(&[0.5, 0.0, 2.0], &[1.0, 0.0, 2.0], &n) - 100.0 * 0.5f64.ln()).abs()
                < 1e-12
        );
        assert!((neg2ll(&[100.0, 0.0, 100.0], &n)).abs() < 1e-12);
    }
}
