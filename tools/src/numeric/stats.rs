//! Likelihood, information-criterion and whiteness statistics of residuals.
//!
//! - Gaussian profile likelihood per channel: −2 ln L = Σ_c n_c ln(RSS_c / n_c) (the noise
//!   variance of every channel maximised out);
//! - Schwarz's BIC penalty k ln N (Schwarz 1978; Kass & Raftery 1995: ΔBIC < −10 is "very
//!   strong" evidence);
//! - Ljung–Box portmanteau statistic Q = n(n+2) Σ_{k=1..h} ρ_k²/(n−k) (Ljung & Box 1978), χ²(h)
//!   under whiteness; and the structured power Σ_k c_k² (its numerator before normalising).

/// −2 ln L of the per-channel Gaussian profile likelihood (`rss[c]` over `n[c]` samples;
/// channels with `n[c] = 0` are absent).
pub fn neg2ll(rss: &[f64; 3], n: &[usize; 3]) -> f64 {
    (0..3)
        .filter(|&c| n[c] > 0)
        .map(|c| n[c] as f64 * (rss[c].max(1e-300) / n[c] as f64).ln())
        .sum()
}

/// Quantisation step of the sampled signal `x` (its unit): the smallest non-zero increment
/// between successive samples, when at least 95 % of the non-zero increments are whole
/// multiples of it (to 5 % of a step), as an encoder's or a camera's counts are. `None` with
/// fewer than 20 non-zero increments or increments on no such grid (continuous noise).
/// Increments below 1e-12 of the largest |x| count as zero.
pub fn quantum(x: &[f64]) -> Option<f64> {
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let steps: Vec<f64> = x
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 1e-12 * scale)
        .collect();
    if steps.len() < 20 {
        return None;
    }
    let q = steps.iter().cloned().fold(f64::INFINITY, f64::min);
    let on_grid = steps
        .iter()
        .filter(|d| {
            let m = *d / q;
            (m - m.round()).abs() <= 0.05
        })
        .count();
    (on_grid as f64 >= 0.95 * steps.len() as f64).then_some(q)
}

/// Δ(−2 ln L) of `rss` against `rss0` (same samples): the likelihood-ratio statistic.
pub fn delta_neg2ll(rss: &[f64; 3], rss0: &[f64; 3], n: &[usize; 3]) -> f64 {
    (0..3)
        .filter(|&c| n[c] > 0)
        .map(|c| n[c] as f64 * (rss[c].max(1e-300) / rss0[c].max(1e-300)).ln())
        .sum()
}

/// ΔBIC of a model with `k` more parameters whose likelihood-ratio statistic is `delta_neg2ll`
/// on `n` samples.
pub fn delta_bic(delta_neg2ll: f64, k: usize, n: usize) -> f64 {
    delta_neg2ll + k as f64 * (n.max(1) as f64).ln()
}

/// Integrated autocorrelation time τ = 1 + 2 Σ_{k≥1} ρ_k of `r`, summed by Geyer's (1992)
/// initial monotone sequence (pairs ρ_{2m} + ρ_{2m+1} while positive, each capped by the one
/// before; at most `max_lag` lags),
/// so an oscillating autocorrelation does not blow up the sum. n/τ is the effective number of
/// independent samples: a likelihood-ratio statistic computed as if the n samples were
/// independent is too large by about τ (≥ 1; 1 for white noise or fewer than 3 samples).
pub fn autocorrelation_time(r: &[f64], max_lag: usize) -> f64 {
    let n = r.len();
    if n < 3 {
        return 1.0;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    // deviations once (the same values and sums as computing them in every lag's product)
    let dev: Vec<f64> = r.iter().map(|x| x - m).collect();
    let c0: f64 = dev.iter().map(|x| x * x).sum();
    if !(c0 > 0.0) {
        return 1.0;
    }
    let rho = |k: usize| -> f64 {
        if k >= n {
            return 0.0;
        }
        dev[k..].iter().zip(&dev).map(|(a, b)| a * b).sum::<f64>() / c0
    };
    let mut tau = -1.0;
    let mut k = 0;
    let mut last = f64::INFINITY;
    while k < max_lag.min(n - 1) {
        // initial monotone sequence: pairs positive and non-increasing
        let pair = (rho(k) + rho(k + 1)).min(last);
        if !(pair > 0.0) {
            break;
        }
        tau += 2.0 * pair;
        last = pair;
        k += 2;
    }
    tau.max(1.0)
}

/// Δ(−2 ln L) of `rss` against `rss0` with every channel's samples counted as `n[c] / tau[c]`
/// independent ones (`tau`: [`autocorrelation_time`] of a residual; the diagnosis's guard gives
/// the alternative model's, see `diagnose::select`).
pub fn delta_neg2ll_effective(
    rss: &[f64; 3],
    rss0: &[f64; 3],
    n: &[usize; 3],
    tau: &[f64; 3],
) -> f64 {
    (0..3)
        .filter(|&c| n[c] > 0)
        .map(|c| n[c] as f64 / tau[c].max(1.0) * (rss[c].max(1e-300) / rss0[c].max(1e-300)).ln())
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

/// One-step prediction-error (innovation) variance of `r` under its best linear predictor from
/// the `order` samples before (an autoregressive fit by Levinson–Durbin on the biased sample
/// autocovariances; Box & Jenkins, §3.2). What it leaves is the part of `r` its own past cannot
/// predict: for white noise plus a structure that is smooth *or* oscillatory it estimates the
/// white-noise variance, where the first-difference estimator counts fast structure as noise.
/// `var(r) − innovation_variance` is the predictable (structured) variance. 0 for fewer than
/// `order + 2` samples or a constant `r`.
pub fn innovation_variance(r: &[f64], order: usize) -> f64 {
    let mut last = 0.0;
    levinson_durbin(r, order, |p, _, e| {
        if p == order {
            last = e;
        }
    });
    last
}

/// An autoregressive model x_t = Σ_{j=1..p} a_j x_{t−j} + e_t, e_t white with variance
/// `innovation_variance` (units of x squared).
#[derive(Clone, Debug, PartialEq)]
pub struct Autoregressive {
    /// a_1 … a_p.
    pub coefficients: Vec<f64>,
    /// Variance of e_t.
    pub innovation_variance: f64,
}

impl Autoregressive {
    /// Fits `r` (mean removed) by Levinson–Durbin on its biased sample autocovariances (Yule–Walker;
    /// Box & Jenkins, §3.2; the model is then stable) with the order 0 … `max_order` of least
    /// Akaike information n ln σ̂²_p + 2p (Akaike 1974). `None` for fewer than `max_order + 2`
    /// samples or a constant `r`.
    pub fn fit_aic(r: &[f64], max_order: usize) -> Option<Self> {
        let n = r.len() as f64;
        let mut best: Option<(f64, Self)> = None;
        levinson_durbin(r, max_order, |p, a, e| {
            let aic = n * e.ln() + 2.0 * p as f64;
            if best.as_ref().map_or(true, |(b, _)| aic < *b) {
                let model = Self {
                    coefficients: a[1..=p].to_vec(),
                    innovation_variance: e,
                };
                best = Some((aic, model));
            }
        });
        best.map(|(_, m)| m)
    }

    /// Fits `r` (mean removed) by least squares on its own lags (the covariance method:
    /// x_t on x_{t−1} … x_{t−p} over the common rows t = `max_order` … n − 1, one QR for every
    /// order) with the order 0 … `max_order` of least Akaike information m ln σ̂²_p + 2p (m the
    /// rows). Yule–Walker's windowed autocovariances ([`Autoregressive::fit_aic`]) bias poles
    /// near the unit circle towards the origin — a lightly damped ring is whitened short of its
    /// peak (Kay & Marple 1981, *Proc. IEEE* 69: 1380–1419, §IV; Ulrych & Clayton 1976) — where
    /// least squares is asymptotically unbiased; the model need not be stable. `None` for fewer
    /// than 2 `max_order` + 2 samples or a constant `r`.
    pub fn fit_aic_least_squares(r: &[f64], max_order: usize) -> Option<Self> {
        use nalgebra::{DMatrix, DVector};
        let n = r.len();
        if n < 2 * max_order + 2 {
            return None;
        }
        let mean = r.iter().sum::<f64>() / n as f64;
        let x: Vec<f64> = r.iter().map(|v| v - mean).collect();
        let m = n - max_order;
        let y = DVector::from_iterator(m, x[max_order..].iter().copied());
        let yy = y.norm_squared();
        if !(yy > 0.0) {
            return None;
        }
        let design = DMatrix::from_fn(m, max_order, |i, j| x[max_order + i - j - 1]);
        let qr = design.qr();
        let (q, rf) = (qr.q(), qr.r());
        let qty = q.transpose() * &y;
        let mut best: Option<(f64, usize, f64)> = None;
        let mut rss = yy;
        for p in 0..=max_order {
            if p > 0 {
                if !(rf[(p - 1, p - 1)].abs() > 1e-12 * rf[(0, 0)].abs()) {
                    break;
                }
                rss -= qty[p - 1] * qty[p - 1];
            }
            let var = (rss / m as f64).max(f64::MIN_POSITIVE);
            let aic = m as f64 * var.ln() + 2.0 * p as f64;
            if best.map_or(true, |(b, _, _)| aic < b) {
                best = Some((aic, p, var));
            }
        }
        let (_, p, var) = best?;
        let mut a = vec![0.0; p];
        for i in (0..p).rev() {
            let tail: f64 = (i + 1..p).map(|j| rf[(i, j)] * a[j]).sum();
            a[i] = (qty[i] - tail) / rf[(i, i)];
        }
        Some(Self {
            coefficients: a,
            innovation_variance: var,
        })
    }

    /// `n` samples of the stationary process driven by `white` (independent N(0, 1) draws,
    /// scaled by the innovation standard deviation), after a burn-in as long as the output
    /// (from rest, so every pole of the stable model has decayed by its share of 2n samples).
    pub fn simulate(&self, n: usize, mut white: impl FnMut() -> f64) -> Vec<f64> {
        let s = self.innovation_variance.sqrt();
        let p = self.coefficients.len();
        let mut x = vec![0.0; 2 * n + p];
        for t in p..x.len() {
            let past: f64 = (1..=p).map(|j| self.coefficients[j - 1] * x[t - j]).sum();
            x[t] = past + s * white();
        }
        x.split_off(n + p)
    }
}

/// The biased sample autocovariances c_k = Σ_{i≥k} (x_i − x̄)(x_{i−k} − x̄) / n of `x` for lags
/// 0 … `max_lag` (`max_lag` < n). Summed directly up to lag [`DIRECT_AUTOCOVARIANCE_LAGS`], through
/// a zero-padded real FFT beyond (the Wiener–Khinchin relation; O(n log n) instead of
/// O(n · max_lag)).
pub fn autocovariances(x: &[f64], max_lag: usize) -> Vec<f64> {
    let n = x.len();
    let m = x.iter().sum::<f64>() / n.max(1) as f64;
    if max_lag <= DIRECT_AUTOCOVARIANCE_LAGS {
        return (0..=max_lag)
            .map(|k| (k..n).map(|i| (x[i] - m) * (x[i - k] - m)).sum::<f64>() / n as f64)
            .collect();
    }
    let len = (2 * n).next_power_of_two();
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(len), planner.plan_fft_inverse(len));
    let mut buf: Vec<f64> = x.iter().map(|v| v - m).collect();
    buf.resize(len, 0.0);
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec)
        .expect("sizes from the planner");
    for z in spec.iter_mut() {
        *z = realfft::num_complex::Complex::new(z.norm_sqr(), 0.0);
    }
    inv.process(&mut spec, &mut buf)
        .expect("sizes from the planner");
    buf.truncate(max_lag + 1);
    buf.iter().map(|v| v / (len as f64 * n as f64)).collect()
}

/// Lags up to which [`autocovariances`] sums directly (below it the FFT saves nothing).
const DIRECT_AUTOCOVARIANCE_LAGS: usize = 64;

impl Autoregressive {
    /// The process' long-run variance, 2π × its spectral density at frequency zero:
    /// σ²_e / (1 − Σ a_j)² (the autoregressive spectral estimator, Berk 1974; den Haan & Levin
    /// 1997). ∞ for a unit root.
    pub fn spectrum_at_zero(&self) -> f64 {
        let g = 1.0 - self.coefficients.iter().sum::<f64>();
        self.innovation_variance / (g * g)
    }
}

/// The Levinson–Durbin recursion on the biased sample autocovariances of `r` (mean removed),
/// calling `each(p, a, e_p)` for every order p = 0 … `max_order` with the coefficients
/// `a[1..=p]` and the innovation variance e_p; stops early (without calling) on fewer than
/// `max_order + 2` samples, a constant `r` or a non-positive e_p.
fn levinson_durbin(r: &[f64], max_order: usize, mut each: impl FnMut(usize, &[f64], f64)) {
    if r.len() < max_order + 2 {
        return;
    }
    let c = autocovariances(r, max_order);
    if !(c[0] > 0.0) {
        return;
    }
    let mut a = vec![0.0; max_order + 1];
    let mut e = c[0];
    each(0, &a, e);
    for k in 1..=max_order {
        let acc: f64 = (1..k).map(|j| a[j] * c[k - j]).sum();
        let kappa = (c[k] - acc) / e;
        let prev = a.clone();
        a[k] = kappa;
        for j in 1..k {
            a[j] = prev[j] - kappa * prev[k - j];
        }
        e *= 1.0 - kappa * kappa;
        if !(e > 0.0) {
            return;
        }
        each(k, &a, e);
    }
}

/// The one-sample Kolmogorov–Smirnov statistic D = sup |F_n(p) − p| of `p` against the uniform
/// distribution on [0, 1] (Massey 1951), with its large-sample 5 % critical value 1.36/√n.
/// `None` for no values.
pub fn ks_uniform(p: &[f64]) -> Option<(f64, f64)> {
    if p.is_empty() {
        return None;
    }
    let mut s = p.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len() as f64;
    let d = s
        .iter()
        .enumerate()
        .map(|(i, &x)| ((i + 1) as f64 / n - x).max(x - i as f64 / n))
        .fold(0.0, f64::max);
    Some((d, 1.36 / n.sqrt()))
}

/// White-noise variance of `r` from its spectral floor: the median of the periodogram
/// |X_k|²/n over the frequencies strictly between 0 and Nyquist, divided by ln 2 (for white
/// noise of variance σ² the periodogram ordinates are independent exponential variables of
/// mean σ², whose median is σ² ln 2). A structure confined to less than half of the band
/// (a ringing mode, a line) does not move the median, so unlike [`innovation_variance`] it is
/// not inflated by the part of a decaying oscillation its own noisy past cannot predict; a
/// structure spread over more than half of the band raises it. 0 for fewer than 8 samples.
pub fn spectral_floor_variance(r: &[f64]) -> f64 {
    let n = r.len();
    if n < 8 {
        return 0.0;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<f64> = r.iter().map(|x| x - m).collect();
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    if fft.process(&mut buf, &mut spec).is_err() {
        return 0.0;
    }
    let mut p: Vec<f64> = spec[1..(n + 1) / 2]
        .iter()
        .map(|c| c.norm_sqr() / n as f64)
        .collect();
    if p.is_empty() {
        return 0.0;
    }
    p.sort_by(f64::total_cmp);
    p[p.len() / 2] / std::f64::consts::LN_2
}

/// `x` with its white noise removed: a zero-phase Wiener filter whose gain per frequency is
/// `max(0, 1 − α σ²/S(f))`, S the periodogram |X_k|²/n averaged over ±[`WIENER_SMOOTH_BINS`]
/// bins, σ² the spectral floor ([`spectral_floor_variance`]) and α
/// [`WIENER_OVERSUBTRACTION`] — spectral subtraction with over-subtraction (Boll 1979; Berouti
/// et al. 1979): a bin holding only noise has S/σ² distributed as χ²(2m)/(2m) over its m
/// averaged ordinates, so with α its upper 0.1 % point it is removed, not left at a fraction
/// (which, differentiated twice, would still be most of the noise). The straight line through the first and last samples is taken out before the
/// transform and put back after it, so the circular transform sees no jump at the ends.
/// Where the signal stands above the floor it passes nearly unchanged; where only noise is it
/// is removed. Returns `x` unchanged for fewer than 8 samples.
pub fn wiener_denoise(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    if n < 8 {
        return x.to_vec();
    }
    let (x0, x1) = (x[0], x[n - 1]);
    let line = |k: usize| x0 + (x1 - x0) * k as f64 / (n - 1) as f64;
    let mut buf: Vec<f64> = x.iter().enumerate().map(|(k, v)| v - line(k)).collect();
    let floor = spectral_floor_variance(&buf);
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut buf, &mut spec).is_err() || !(floor > 0.0) {
        return x.to_vec();
    }
    let p: Vec<f64> = spec.iter().map(|c| c.norm_sqr() / n as f64).collect();
    let m = spec.len();
    let gains: Vec<f64> = (0..m)
        .map(|k| {
            let (lo, hi) = (
                k.saturating_sub(WIENER_SMOOTH_BINS),
                (k + WIENER_SMOOTH_BINS + 1).min(m),
            );
            let s = p[lo..hi].iter().sum::<f64>() / (hi - lo) as f64;
            if k == 0 {
                1.0
            } else {
                (1.0 - WIENER_OVERSUBTRACTION * floor / s.max(1e-300)).max(0.0)
            }
        })
        .collect();
    for (c, g) in spec.iter_mut().zip(&gains) {
        *c *= *g;
    }
    // the inverse of a real transform needs real end bins
    spec[0].im = 0.0;
    if n % 2 == 0 {
        spec[m - 1].im = 0.0;
    }
    let mut out = inv.make_output_vec();
    if inv.process(&mut spec, &mut out).is_err() {
        return x.to_vec();
    }
    out.iter()
        .enumerate()
        .map(|(k, v)| v / n as f64 + line(k))
        .collect()
}

/// Half-width (bins) of the periodogram average of [`wiener_denoise`].
pub const WIENER_SMOOTH_BINS: usize = 4;
/// Over-subtraction of [`wiener_denoise`]: the upper 0.1 % point of χ²(18)/18 (an average of
/// 2 × [`WIENER_SMOOTH_BINS`] + 1 = 9 noise-only periodogram ordinates, each χ²(2)/2).
pub const WIENER_OVERSUBTRACTION: f64 = 42.31 / 18.0;

/// The white-noise σ of a sampled signal from its second differences: 1.4826 × the median
/// of |Δ²x| / √6 (white noise of σ has Δ² of variance 6σ²; 1.4826 × MAD is σ for a Gaussian,
/// Hampel 1974), which a signal well below the sample rate hardly reaches. NaN for fewer than
/// 3 samples.
pub fn second_difference_noise(x: &[f64]) -> f64 {
    let d2: Vec<f64> = x
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    1.4826 * median(&d2) / 6f64.sqrt()
}

/// Median of `v` (the mean of the two middle values for an even length; NaN when empty).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut sorted = v.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

/// The white-noise variance of a residual `r`: the smaller of its innovation variance
/// ([`innovation_variance`], `order` lags) and its spectral floor
/// ([`spectral_floor_variance`]). Both estimate σ² for white noise; structure biases each
/// upwards in its own way (unpredictable ringing the first, broadband structure the second), so
/// the smaller is the tighter bound.
pub fn noise_variance(r: &[f64], order: usize) -> f64 {
    innovation_variance(r, order).min(spectral_floor_variance(r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_autoregressive_fit_finds_the_order_and_coefficients_it_was_simulated_with() {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        // a resonant AR(2): poles at radius 0.95, ±0.3 rad; innovation variance 4
        let truth = Autoregressive {
            coefficients: vec![2.0 * 0.95 * 0.3f64.cos(), -0.95 * 0.95],
            innovation_variance: 4.0,
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = rand_distr::StandardNormal;
        let x = truth.simulate(20_000, || normal.sample(&mut rng));
        assert_eq!(x.len(), 20_000);
        let fit = Autoregressive::fit_aic(&x, 20).expect("fits");
        assert!(fit.coefficients.len() >= 2, "{fit:?}");
        for (a, b) in fit.coefficients.iter().zip(&truth.coefficients) {
            assert!((a - b).abs() < 0.03, "{fit:?}");
        }
        // AIC leaves out what the process does not have: the extra coefficients are small
        assert!(
            fit.coefficients[2..].iter().all(|a| a.abs() < 0.03),
            "{fit:?}"
        );
        assert!(
            (fit.innovation_variance / 4.0 - 1.0).abs() < 0.05,
            "{fit:?}"
        );
        assert_eq!(Autoregressive::fit_aic(&[1.0; 50], 4), None);
    }

    #[test]
    fn autocovariances_through_the_fft_are_the_direct_sums() {
        let x: Vec<f64> = (0..1000)
            .map(|k| (k as f64 * 0.37).sin() + (k % 7) as f64)
            .collect();
        let fft = autocovariances(&x, 200);
        let m = x.iter().sum::<f64>() / 1000.0;
        for k in [0, 1, 65, 200] {
            let direct = (k..1000).map(|i| (x[i] - m) * (x[i - k] - m)).sum::<f64>() / 1000.0;
            assert!(
                (fft[k] - direct).abs() < 1e-9 * direct.abs().max(1.0),
                "{k}"
            );
        }
        assert_eq!(autocovariances(&x, 10).len(), 11);
    }

    #[test]
    fn the_kolmogorov_smirnov_statistic_is_small_on_a_uniform_grid_and_large_on_a_pile() {
        let grid: Vec<f64> = (0..100).map(|i| (i as f64 + 0.5) / 100.0).collect();
        let (d, crit) = ks_uniform(&grid).unwrap();
        assert!(
            (d - 0.005).abs() < 1e-12 && (crit - 0.136).abs() < 1e-12,
            "{d} {crit}"
        );
        let pile = vec![0.01; 50];
        assert!((ks_uniform(&pile).unwrap().0 - 0.99).abs() < 1e-12);
        assert_eq!(ks_uniform(&[]), None);
    }

    #[test]
    fn an_encoders_counts_have_a_quantum_and_noise_has_none() {
        // a 1 µm encoder on a slow sine, parsed from seven decimals
        let counts: Vec<f64> = (0..2000)
            .map(|k| (2e-3 * (k as f64 * 0.01).sin() * 1e6).round() * 1e-6)
            .map(|v: f64| format!("{v:.7}").parse().unwrap())
            .collect();
        let q = quantum(&counts).expect("quantised");
        assert!((q - 1e-6).abs() < 1e-9, "{q}");
        // continuous: a sine with an irrational phase step has no grid
        let smooth: Vec<f64> = (0..2000).map(|k| (k as f64 * 0.0123).sin()).collect();
        assert_eq!(quantum(&smooth), None);
        // too few moves to tell
        assert_eq!(quantum(&[0.0, 1e-6, 2e-6]), None);
    }
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
        assert!(structured_power(&colored, 20) > 10.0 * structured_power(&white, 20));
    }

    #[test]
    fn autocorrelation_time_of_white_and_smooth_noise() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(2);
        let d = Normal::new(0.0, 1.0).unwrap();
        let white: Vec<f64> = (0..20000).map(|_| d.sample(&mut rng)).collect();
        let t = autocorrelation_time(&white, 200);
        assert!(t < 1.2, "{t}");
        // AR(1) with a = 0.9: τ = (1 + a)/(1 − a) = 19
        let long: Vec<f64> = (0..200_000).map(|_| d.sample(&mut rng)).collect();
        let mut ar = vec![0.0; long.len()];
        for i in 1..ar.len() {
            ar[i] = 0.9 * ar[i - 1] + long[i];
        }
        let t = autocorrelation_time(&ar, 500);
        assert!((t - 19.0).abs() < 4.0, "{t}");
        let e = delta_neg2ll_effective(
            &[1.0, 0.0, 0.5],
            &[1.0, 0.0, 1.0],
            &[100, 0, 100],
            &[1.0, 1.0, 10.0],
        );
        assert!((e - 10.0 * 0.5f64.ln()).abs() < 1e-12);
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
        assert!((delta_bic(-10.0, 2, 100) - (-10.0 + 2.0 * 100f64.ln())).abs() < 1e-12);
    }

    #[test]
    fn innovation_variance_sees_fast_structure_as_structure() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let n = Normal::new(0.0, 1.0).unwrap();
        let white: Vec<f64> = (0..20000).map(|_| n.sample(&mut rng)).collect();
        assert!((innovation_variance(&white, 20) - 1.0).abs() < 0.05);
        // a sine at 0.4 × the sample rate of amplitude 3 (variance 4.5) on top
        let fast: Vec<f64> = white
            .iter()
            .enumerate()
            .map(|(k, x)| x + 3.0 * (2.0 * std::f64::consts::PI * 0.4 * k as f64).sin())
            .collect();
        let e = innovation_variance(&fast, 20);
        assert!((e - 1.0).abs() < 0.15, "{e}");
    }

    #[test]
    fn the_spectral_floor_sees_through_a_ringing_mode() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let d = Normal::new(0.0, 1.0).unwrap();
        let n = 3000;
        let white: Vec<f64> = (0..n).map(|_| d.sample(&mut rng)).collect();
        assert!((spectral_floor_variance(&white) - 1.0).abs() < 0.1);
        // decaying rings at 0.137 × the sample rate (ζ 0.05), rms equal to the noise, every
        // 300 samples
        let w = 2.0 * std::f64::consts::PI * 0.137;
        let mut ring: Vec<f64> = (0..n)
            .map(|i| {
                let k = (i % 300) as f64;
                (-0.05 * w * k).exp() * (w * k).sin()
            })
            .collect();
        let rms = (ring.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
        ring.iter_mut().for_each(|x| *x /= rms);
        let r: Vec<f64> = white.iter().zip(&ring).map(|(a, b)| a + b).collect();
        let (floor, innov) = (spectral_floor_variance(&r), innovation_variance(&r, 20));
        assert!((floor - 1.0).abs() < 0.15, "floor {floor}");
        assert!(innov > floor + 0.05, "innovation {innov}, floor {floor}");
        assert!(noise_variance(&r, 20) == floor);
    }

    #[test]
    fn the_wiener_filter_removes_white_noise_and_keeps_a_slow_signal() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let d = Normal::new(0.0, 0.01).unwrap();
        let n = 4000;
        let signal: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * k as f64 / 800.0).sin() + 0.3)
            .collect();
        let noisy: Vec<f64> = signal.iter().map(|s| s + d.sample(&mut rng)).collect();
        let clean = wiener_denoise(&noisy);
        let rms = |a: &[f64], b: &[f64]| {
            (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
        };
        assert!(rms(&noisy, &signal) > 0.009);
        assert!(rms(&clean, &signal) < 0.003, "{}", rms(&clean, &signal));
        // second differences (an acceleration) lose the noise the differences amplify
        let dd =
            |v: &[f64]| -> Vec<f64> { v.windows(3).map(|w| w[2] - 2.0 * w[1] + w[0]).collect() };
        assert!(rms(&dd(&clean), &dd(&signal)) < 0.05 * rms(&dd(&noisy), &dd(&signal)));
    }
}
