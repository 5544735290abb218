//! Sweep-tracking denoising of a swept-sine *input* (a tracking filter, as swept-sine
//! analysers use). At any instant a sweep holds energy only near its instantaneous frequency,
//! while sensor noise is broadband: a short-time Fourier transform (Hann, 75 % overlap), a
//! mask keeping the bins within ±B of each frame's spectral ridge (B = half the frequency span
//! the ridge covers in one frame + 3 bins), and the weighted overlap-add inverse remove most of
//! the input noise. Only the input is filtered: the output's free ring-down stays at the
//! resonance after the sweep has passed, so masking the output would bias the damping. With
//! a clean input, H1 is unbiased by the remaining (output) noise.
//!
//! When the recording also holds the noise-free command, [`base_from_command`] does better:
//! the base position predicted from the command by a fitted FIR servo model.

use anyhow::Result;
use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;

/// Result of [`track_sweep`].
#[derive(Clone, Debug)]
pub struct Tracked {
    /// The filtered signal (same length).
    pub x: Vec<f64>,
    /// Fraction of the input energy in the search band that is inside the mask (≈ 1 for a
    /// clean sweep).
    pub kept_energy: f64,
    /// Fraction of the time-frequency bins inside the mask (white noise keeps this much).
    pub kept_bins: f64,
}

impl Tracked {
    /// A sweep concentrates its energy: the mask keeps at least half the in-band energy and
    /// at least 2× what white noise would (its share of bins).
    pub fn is_sweep(&self) -> bool {
        self.kept_energy >= 0.5 && self.kept_energy >= 2.0 * self.kept_bins
    }
}

/// Tracking filter of `x` (sampled at `rate_hz`) with frames of about `frame_s` seconds; the
/// ridge is searched inside `band_hz` (the sweep's band).
pub fn track_sweep(x: &[f64], rate_hz: f64, frame_s: f64, band_hz: (f64, f64)) -> Result<Tracked> {
    let n = x.len();
    let l = ((frame_s * rate_hz) as usize)
        .next_power_of_two()
        .clamp(16, n.next_power_of_two().max(16));
    let hop = l / 4;
    let win: Vec<f64> = (0..l)
        .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / l as f64).cos())
        .collect();
    let pad = l;
    let total = n + 2 * pad;
    let mut xp = vec![0.0; total];
    xp[pad..pad + n].copy_from_slice(x);
    let frames: Vec<usize> = (0..)
        .map(|i| i * hop)
        .take_while(|&s| s + l <= total)
        .collect();
    let nb = l / 2 + 1;
    let df = rate_hz / l as f64;
    let mut specs = stft(&xp, &frames, &win)?;
    let k_lo = ((band_hz.0 / df).floor() as usize).clamp(1, nb - 1);
    let k_hi = ((band_hz.1 / df).ceil() as usize).clamp(k_lo, nb - 1);
    let ridge = ridge_hz(&specs, k_lo, k_hi, df);
    let hop_s = hop as f64 / rate_hz;
    let mut kept = Kept::default();
    for (i, sp) in specs.iter_mut().enumerate() {
        let (a, b) = (i.saturating_sub(2), (i + 2).min(frames.len() - 1));
        let rate = if b > a {
            (ridge[b] - ridge[a]).abs() / ((b - a) as f64 * hop_s)
        } else {
            0.0
        };
        let half = 0.5 * rate * (l as f64 / rate_hz) + 3.0 * df;
        mask_frame(sp, ridge[i], half, df, (k_lo, k_hi), &mut kept);
    }
    let (out, norm) = overlap_add(&mut specs, &frames, &win, total)?;
    let x: Vec<f64> = (pad..pad + n)
        .map(|k| {
            if norm[k] > 1e-9 {
                out[k] / norm[k]
            } else {
                0.0
            }
        })
        .collect();
    Ok(Tracked {
        x,
        kept_energy: if kept.e_all > 0.0 {
            kept.e_kept / kept.e_all
        } else {
            0.0
        },
        kept_bins: kept.b_kept as f64 / kept.b_all.max(1) as f64,
    })
}

/// Spectra of the frames of `xp` starting at `frames`, windowed by `win` (its length is the
/// frame length).
fn stft(xp: &[f64], frames: &[usize], win: &[f64]) -> Result<Vec<Vec<Complex64>>> {
    let l = win.len();
    let fwd = RealFftPlanner::<f64>::new().plan_fft_forward(l);
    let mut specs: Vec<Vec<Complex64>> = Vec::with_capacity(frames.len());
    let mut buf = fwd.make_input_vec();
    for &s in frames {
        for k in 0..l {
            buf[k] = xp[s + k] * win[k];
        }
        let mut sp = fwd.make_output_vec();
        fwd.process(&mut buf, &mut sp)
            .map_err(|e| anyhow::anyhow!("STFT: {e}"))?;
        specs.push(sp);
    }
    Ok(specs)
}

/// The ridge (Hz) of every frame: the strongest bin in `k_lo..=k_hi`, then a 5-frame median.
fn ridge_hz(specs: &[Vec<Complex64>], k_lo: usize, k_hi: usize, df: f64) -> Vec<f64> {
    let raw: Vec<f64> = specs
        .iter()
        .map(|sp| {
            (k_lo..=k_hi)
                .max_by(|&a, &b| sp[a].norm_sqr().total_cmp(&sp[b].norm_sqr()))
                .unwrap_or(k_lo) as f64
                * df
        })
        .collect();
    (0..raw.len())
        .map(|i| {
            let mut w: Vec<f64> = raw[i.saturating_sub(2)..(i + 3).min(raw.len())].to_vec();
            w.sort_by(|a, b| a.total_cmp(b));
            w[w.len() / 2]
        })
        .collect()
}

/// Energy and bins of the search band, all and inside the mask.
#[derive(Default)]
struct Kept {
    e_all: f64,
    e_kept: f64,
    b_all: usize,
    b_kept: usize,
}

/// Zeroes the bins of `sp` farther than `half` Hz from `ridge` Hz, counting the search band
/// `k_band` (inclusive) into `kept`; makes DC and Nyquist real.
fn mask_frame(
    sp: &mut [Complex64],
    ridge: f64,
    half: f64,
    df: f64,
    k_band: (usize, usize),
    kept: &mut Kept,
) {
    for (k, c) in sp.iter_mut().enumerate() {
        let e = c.norm_sqr();
        let in_band = (k_band.0..=k_band.1).contains(&k);
        if in_band {
            kept.e_all += e;
            kept.b_all += 1;
        }
        if ((k as f64 * df) - ridge).abs() <= half {
            if in_band {
                kept.e_kept += e;
                kept.b_kept += 1;
            }
        } else {
            *c = Complex64::new(0.0, 0.0);
        }
    }
    let nb = sp.len();
    sp[0].im = 0.0;
    sp[nb - 1].im = 0.0;
}

/// Weighted overlap-add of the inverse spectra (window `win` again) into `total` samples, and
/// the sum of squared windows to normalise by.
fn overlap_add(
    specs: &mut [Vec<Complex64>],
    frames: &[usize],
    win: &[f64],
    total: usize,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let l = win.len();
    let inv = RealFftPlanner::<f64>::new().plan_fft_inverse(l);
    let mut out = vec![0.0; total];
    let mut norm = vec![0.0; total];
    for (&s, sp) in frames.iter().zip(specs.iter_mut()) {
        let mut o = inv.make_output_vec();
        inv.process(sp, &mut o)
            .map_err(|e| anyhow::anyhow!("ISTFT: {e}"))?;
        for k in 0..l {
            out[s + k] += o[k] / l as f64 * win[k];
            norm[s + k] += win[k] * win[k];
        }
    }
    Ok((out, norm))
}

/// Fraction of the variance of `x` (mean removed) above `f_hz`: ≈ 0 for a generated command
/// band-limited below `f_hz`, ≈ (1 − 2f/rate) × the noise share for white sensor noise.
pub fn broadband_fraction(x: &[f64], rate_hz: f64, f_hz: f64) -> f64 {
    let n = x.len();
    if n < 4 {
        return 0.0;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut buf: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let mut sp = fft.make_output_vec();
    if fft.process(&mut buf, &mut sp).is_err() {
        return 0.0;
    }
    let k0 = ((f_hz / rate_hz) * n as f64).ceil() as usize;
    let total: f64 = sp.iter().skip(1).map(|c| c.norm_sqr()).sum();
    let high: f64 = sp.iter().skip(k0.max(1)).map(|c| c.norm_sqr()).sum();
    if total > 0.0 {
        high / total
    } else {
        0.0
    }
}

/// Result of [`base_from_command`].
#[derive(Clone, Debug)]
pub struct CommandModel {
    /// The base position the fitted servo model predicts from the command (same length).
    pub base: Vec<f64>,
    /// Fraction of the measured base position's variance the model explains.
    pub r2: f64,
    /// Taps (lead, lag) of the FIR model.
    pub taps: (usize, usize),
}

/// Noise-free estimate of the base position from the (noise-free) command: a least-squares
/// FIR model `b[k] ≈ Σ_{j=−lead..lag} h_j · cmd[k−j] + c` of the servo (delay, finite
/// bandwidth, the beam's reaction on the carriage) fitted on the measured base position.
/// The sensor noise of `base` is the *output* error of that regression, so the estimate is
/// consistent and its noise variance is about (taps / N) of the sensor's: an instrumental
/// variable for the errors-in-variables problem of a noisy measured input (Söderström,
/// *Errors-in-variables methods in system identification*, Automatica 43, 2007, §6).
///
/// Errors: different lengths, fewer than 20 samples per tap, a constant command.
///
/// [`base_from_command_bic`] chooses the taps.
pub fn base_from_command(
    cmd: &[f64],
    base: &[f64],
    lead: usize,
    lag: usize,
) -> Result<CommandModel> {
    let n = cmd.len();
    if base.len() != n {
        anyhow::bail!(
            "base_cmd_m and base_pos_m differ in length ({n} vs {})",
            base.len()
        );
    }
    let p = lead + lag + 2;
    if n < 20 * p {
        anyhow::bail!("{n} samples are too few for a {p}-parameter servo model");
    }
    let c_mean = cmd.iter().sum::<f64>() / n as f64;
    let c_var = cmd.iter().map(|v| (v - c_mean).powi(2)).sum::<f64>();
    if !(c_var > 0.0) {
        anyhow::bail!("the command base_cmd_m is constant");
    }
    let at = |k: isize| cmd[k.clamp(0, n as isize - 1) as usize];
    let mut a = nalgebra::DMatrix::<f64>::zeros(n, p);
    for k in 0..n {
        for j in 0..=(lead + lag) {
            a[(k, j)] = at(k as isize + lead as isize - j as isize) - c_mean;
        }
        a[(k, p - 1)] = 1.0;
    }
    let y = nalgebra::DVector::from_column_slice(base);
    let h = a
        .clone()
        .svd(true, true)
        .solve(&y, 1e-12)
        .map_err(|e| anyhow::anyhow!("servo model least squares: {e}"))?;
    let fit = &a * h;
    let b_mean = base.iter().sum::<f64>() / n as f64;
    let b_var = base.iter().map(|v| (v - b_mean).powi(2)).sum::<f64>();
    let r_var = (&y - &fit).norm_squared();
    Ok(CommandModel {
        base: fit.iter().copied().collect(),
        r2: if b_var > 0.0 {
            1.0 - r_var / b_var
        } else {
            0.0
        },
        taps: (lead, lag),
    })
}

/// [`base_from_command`] with the taps chosen by the Bayesian information criterion
/// n ln(RSS/n) + p ln n over lead ∈ {0, `lead_max`} and lag ∈ {0, 1, 2, 4, …, `lag_max`} (for
/// each lead the lags ascend until two in a row do not improve the BIC): a
/// base that follows its command needs one tap, a servo a few; every needless tap adds the
/// sensor noise's projection to the prediction (measured effect on ζ2: docs/ident.md, "Numbers
/// behind the design choices").
pub fn base_from_command_bic(
    cmd: &[f64],
    base: &[f64],
    lead_max: usize,
    lag_max: usize,
) -> Result<CommandModel> {
    let n = base.len() as f64;
    let b_mean = base.iter().sum::<f64>() / n;
    let b_var = base.iter().map(|v| (v - b_mean).powi(2)).sum::<f64>();
    let mut lags = vec![0usize];
    let mut l = 1;
    while l < lag_max {
        lags.push(l);
        l *= 2;
    }
    lags.push(lag_max);
    let leads: Vec<usize> = if lead_max > 0 {
        vec![0, lead_max]
    } else {
        vec![0]
    };
    let mut best: Option<(f64, CommandModel)> = None;
    for &lead in &leads {
        // Lags ascend; stop after two that do not improve this lead's BIC.
        let (mut lead_best, mut worse) = (f64::INFINITY, 0);
        for &lag in &lags {
            let Ok(m) = base_from_command(cmd, base, lead, lag) else {
                continue;
            };
            let rss = ((1.0 - m.r2) * b_var).max(1e-300);
            let bic = n * (rss / n).ln() + (lead + lag + 2) as f64 * n.ln();
            if bic < lead_best {
                lead_best = bic;
                worse = 0;
            } else {
                worse += 1;
            }
            if best.as_ref().map_or(true, |(b, _)| bic < *b) {
                best = Some((bic, m));
            }
            if worse >= 2 {
                break;
            }
        }
    }
    best.map(|(_, m)| m)
        .ok_or_else(|| anyhow::anyhow!("no servo model could be fitted (too few samples?)"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// A base behind a 20 Hz first-order servo lag plus 5 % sensor noise: the BIC model is
    /// several taps long, and its prediction is 10× closer to the true base than the sensor.
    #[test]
    fn servo_model_from_the_command_removes_sensor_noise() {
        let rate = 100.0;
        let n = 12000;
        let cmd: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / rate;
                0.02 * (2.0 * std::f64::consts::PI * (0.1 * t + 0.03 * t * t)).sin()
            })
            .collect();
        let a = (-2.0 * std::f64::consts::PI * 20.0 / rate).exp();
        let mut truth = vec![0.0; n];
        for k in 1..n {
            truth[k] = a * truth[k - 1] + (1.0 - a) * cmd[k - 1];
        }
        let rms = (truth.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let mut rng = StdRng::seed_from_u64(5);
        let nrm = Normal::new(0.0, 0.05 * rms).unwrap();
        let meas: Vec<f64> = truth.iter().map(|v| v + nrm.sample(&mut rng)).collect();
        let m = base_from_command_bic(&cmd, &meas, 10, 100).unwrap();
        assert!(m.taps.1 >= 2, "{:?}", m.taps);
        let err = (m
            .base
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        assert!(
            err < 0.1 * 0.05 * rms,
            "prediction error {err} vs sensor noise {}",
            0.05 * rms
        );
        assert!(base_from_command(&cmd, &meas[..100], 0, 4).is_err());
    }

    #[test]
    fn removes_most_noise_from_an_exponential_sweep() {
        let fs = 100.0;
        let n = 12000;
        let k = 3.0 * std::f64::consts::LN_2 / 60.0;
        let clean: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (2.0 * std::f64::consts::PI * 0.1 * (k * t).exp_m1() / k).sin()
            })
            .collect();
        let mut rng = StdRng::seed_from_u64(3);
        let d = Normal::new(0.0, 0.2).unwrap();
        let noisy: Vec<f64> = clean.iter().map(|v| v + d.sample(&mut rng)).collect();
        let r = track_sweep(&noisy, fs, 4.0, (0.05, 49.0)).unwrap();
        let err = |v: &[f64]| {
            (v.iter()
                .zip(&clean)
                .skip(500)
                .take(n - 1000)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / (n - 1000) as f64)
                .sqrt()
        };
        assert!(
            err(&r.x) < 0.3 * err(&noisy),
            "{} vs {}",
            err(&r.x),
            err(&noisy)
        );
        assert!(r.is_sweep(), "{r:?}");
        let noise_only: Vec<f64> = (0..n).map(|_| d.sample(&mut rng)).collect();
        assert!(!track_sweep(&noise_only, fs, 4.0, (0.05, 49.0))
            .unwrap()
            .is_sweep());
    }
}
