//! What the final model leaves unexplained on the never-fitted validation recording.
//!
//! A channel's validation residual r is *unexplained* when it is both
//! 1. **structured**: the Ljung–Box statistic over [`LJUNG_BOX_LAGS`] lags exceeds the χ²(20)
//!    0.1 % critical value 45.3 (white noise would exceed it once in a thousand recordings), and
//! 2. **well above the noise**: its rms exceeds [`NOISE_FACTOR`] × the sensor-noise rms, the noise
//!    estimated from the residual itself by the first-difference estimator
//!    σ̂² = mean((r_{k+1} − r_k)²) / 2 (von Neumann 1941; exact for white noise, an upper bound when
//!    the residual has fast structure).
//!
//! It is located, never named: the channel, the band holding half its spectral power around
//! the spectral peak, the 1 s windows where its rms is over twice the median window rms, the
//! NRMSE against the channel's signal, the nearest model mode and the correlation with the
//! commanded speed and acceleration.

use super::fit::CHANNEL_NAMES;
use super::select::{ljung_box, LJUNG_BOX_LAGS};
use super::sim::{Prediction, Prepared};
use crate::ident::spectrum::amplitude_spectrum;
use serde::Serialize;

/// χ²(20) upper 0.1 % point.
pub const LJUNG_BOX_CRITICAL: f64 = 45.3;
/// Residual rms over noise rms that counts as "well above noise".
pub const NOISE_FACTOR: f64 = 3.0;

/// A located residual the catalogue does not explain.
#[derive(Clone, Debug, Serialize)]
pub struct Unexplained {
    /// Channel (`tip_pos_m`, `force_n`, `base_pos_m`).
    pub channel: String,
    /// Band (Hz) holding the residual's spectral peak (half-power edges).
    pub band_hz: [f64; 2],
    /// Time windows (s) where the residual is strongest.
    pub windows: Vec<[f64; 2]>,
    /// rms(residual) / rms(signal − mean) on the validation recording.
    pub nrmse: f64,
    /// rms of the residual over the estimated noise rms.
    pub residual_over_noise: f64,
    /// Ljung–Box Q (20 lags) of the residual.
    pub ljung_box_q: f64,
    /// Nearest model mode (Hz) to the band centre, if any model modes exist.
    pub nearest_model_mode_hz: Option<f64>,
    /// Correlation of the residual with the commanded speed |v|·sign(v) and acceleration.
    pub correlation_velocity: f64,
    /// Correlation with the commanded acceleration.
    pub correlation_acceleration: f64,
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 3 {
        return 0.0;
    }
    let ma = a[..n].iter().sum::<f64>() / n as f64;
    let mb = b[..n].iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let (x, y) = (a[k] - ma, b[k] - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    let d = (saa * sbb).sqrt();
    if d > 0.0 {
        sab / d
    } else {
        0.0
    }
}

/// First-difference noise estimate σ̂ of `r`.
pub fn difference_noise(r: &[f64]) -> f64 {
    if r.len() < 2 {
        return 0.0;
    }
    let s: f64 = r.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
    (s / (2.0 * (r.len() - 1) as f64)).sqrt()
}

/// The channel whose validation residual is most clearly structured and above noise, located;
/// `None` when every channel's residual is white or at the noise level.
pub fn assess(
    d: &Prepared,
    vres: &[Option<Vec<f64>>; 3],
    _pred: &Prediction,
    model_freqs: &[f64],
) -> Option<Unexplained> {
    let rate = 1.0 / d.dt;
    let mut best: Option<Unexplained> = None;
    for c in 0..3 {
        let Some(r) = &vres[c] else { continue };
        if r.len() < 4 * LJUNG_BOX_LAGS {
            continue;
        }
        let noise = difference_noise(r);
        let m = r.iter().sum::<f64>() / r.len() as f64;
        let centred: Vec<f64> = r.iter().map(|x| x - m).collect();
        let e = rms(&centred);
        let ratio = if noise > 0.0 {
            e / noise
        } else {
            f64::INFINITY
        };
        let q = ljung_box(r, LJUNG_BOX_LAGS);
        if !(q > LJUNG_BOX_CRITICAL && ratio > NOISE_FACTOR) {
            continue;
        }
        let sig = super::channel_signal(d, c);
        let ms = sig.iter().sum::<f64>() / sig.len().max(1) as f64;
        let ss = rms(&sig.iter().map(|x| x - ms).collect::<Vec<_>>());
        let nrmse = e / ss.max(1e-300);
        // band: half-power edges around the spectral peak (above 0.05 Hz)
        let (f, a) = amplitude_spectrum(r, rate);
        let (mut ip, mut amax) = (0, 0.0);
        for (i, (&fi, &ai)) in f.iter().zip(&a).enumerate() {
            if fi > 0.05 && ai > amax {
                amax = ai;
                ip = i;
            }
        }
        let half = amax / std::f64::consts::SQRT_2;
        let mut lo = ip;
        while lo > 0 && a[lo - 1] >= half {
            lo -= 1;
        }
        let mut hi = ip;
        while hi + 1 < a.len() && a[hi + 1] >= half {
            hi += 1;
        }
        let band = [f[lo], f[hi]];
        let centre = 0.5 * (band[0] + band[1]);
        let nearest = model_freqs
            .iter()
            .copied()
            .min_by(|x, y| (x - centre).abs().total_cmp(&(y - centre).abs()));
        // windows of 1 s
        let w = (rate.round() as usize).max(1);
        let wr: Vec<f64> = centred.chunks(w).map(rms).collect();
        let mut sorted = wr.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let mut windows: Vec<[f64; 2]> = Vec::new();
        for (i, v) in wr.iter().enumerate() {
            if *v > 2.0 * median {
                let t0 = d.time_s[i * w];
                let t1 = d.time_s[((i + 1) * w).min(d.time_s.len()) - 1];
                match windows.last_mut() {
                    Some(last) if (t0 - last[1]).abs() <= 1.5 / rate => last[1] = t1,
                    _ => windows.push([t0, t1]),
                }
            }
        }
        windows.truncate(5);
        let vel: Vec<f64> = (0..d.cmd_m.len())
            .map(|k| {
                let k1 = (k + 1).min(d.cmd_m.len() - 1);
                (d.cmd_m[k1] - d.cmd_m[k]) * rate
            })
            .collect();
        let acc: Vec<f64> = (0..vel.len())
            .map(|k| {
                let k1 = (k + 1).min(vel.len() - 1);
                (vel[k1] - vel[k]) * rate
            })
            .collect();
        let u = Unexplained {
            channel: CHANNEL_NAMES[c].to_string(),
            band_hz: band,
            windows,
            nrmse,
            residual_over_noise: ratio,
            ljung_box_q: q,
            nearest_model_mode_hz: nearest,
            correlation_velocity: corr(&centred, &vel),
            correlation_acceleration: corr(&centred, &acc),
        };
        if best
            .as_ref()
            .map_or(true, |b| u.residual_over_noise > b.residual_over_noise)
        {
            best = Some(u);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn difference_noise_recovers_white_noise_and_ignores_slow_structure() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let n = Normal::new(0.0, 0.5).unwrap();
        let white: Vec<f64> = (0..20000).map(|_| n.sample(&mut rng)).collect();
        assert!((difference_noise(&white) - 0.5).abs() < 0.02);
        let slow: Vec<f64> = white
            .iter()
            .enumerate()
            .map(|(k, x)| x + 5.0 * (k as f64 * 0.01).sin())
            .collect();
        assert!((difference_noise(&slow) - 0.5).abs() < 0.03);
    }
}
