//! Free-decay identification: logarithmic decrement (paper eqs. 28–29) and a least-squares
//! damped-sinusoid fit, on a segment found automatically.
//!
//! Steps: resample onto a uniform grid if the time base is not uniform (warning about gaps);
//! pick the first mode as the lowest spectral peak at least `mode_fraction` of the strongest
//! (Hamming window); isolate it with a zero-phase FFT band-pass (0.7–1.3 f); take the decay
//! from the largest positive peak to where the peaks fall below 5 % of it (or into the
//! noise); then
//! - **log decrement**: straight-line fit of ln(peak) against cycle number, slope −δ,
//!   ζ = 1/√(1 + (2π/δ)²) (eq. 28), damped frequency from the mean peak spacing;
//! - **damped sinusoid**: Levenberg–Marquardt fit of A e^{−σt} cos(ω_d t + φ) (σ = ζω_n,
//!   ω_d = ω_n√(1−ζ²)) to the band-passed segment.
//! The estimate is their mean; the uncertainty combines their difference and the spread of
//! the log decrement over three sub-windows.

use super::spectrum::{amplitude_spectrum, peaks};
use super::{std_dev, ModeEstimate};
use crate::numeric::lm::{minimize_with_jacobian, LmOptions};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use realfft::RealFftPlanner;
use serde::Serialize;
use std::f64::consts::PI;

/// Options.
#[derive(Clone, Debug)]
pub struct FreeDecayOptions {
    /// Lowest frequency considered (Hz).
    pub f_min_hz: f64,
    /// Highest frequency considered (Hz; capped at 0.45 × sample rate).
    pub f_max_hz: f64,
    /// The first mode is the lowest peak of at least this fraction of the strongest peak.
    pub mode_fraction: f64,
    /// Higher modes: peaks above 2 f1 (a cantilever's second mode is ~6 f1) of at least this fraction of the strongest peak
    /// (a displacement record's second mode decays ~6× faster and starts ~1 % as large,
    /// so its spectral peak can be 0.2 % of the first's). Candidates must also decay clearly
    /// above the noise floor to count.
    pub higher_mode_fraction: f64,
}

impl Default for FreeDecayOptions {
    fn default() -> Self {
        FreeDecayOptions {
            f_min_hz: 0.2,
            f_max_hz: 500.0,
            mode_fraction: 0.1,
            higher_mode_fraction: 0.001,
        }
    }
}

/// Result of a free-decay identification.
#[derive(Clone, Debug, Serialize)]
pub struct FreeDecayResult {
    /// Combined estimate of the first mode.
    pub mode: ModeEstimate,
    /// Every mode found (the first and the other significant peaks), by frequency.
    pub modes: Vec<ModeEstimate>,
    /// Logarithmic decrement: (natural frequency Hz, damping ratio, peaks used).
    pub log_decrement: (f64, f64, usize),
    /// Damped-sinusoid fit: (natural frequency Hz, damping ratio).
    pub sinusoid_fit: (f64, f64),
    /// Decay segment used (s).
    pub segment_s: (f64, f64),
    /// Sample rate used (Hz).
    pub sample_rate_hz: f64,
    /// Other spectral peaks (Hz), strongest first.
    pub other_peaks_hz: Vec<f64>,
    /// Warnings (gaps, short decays, …).
    pub warnings: Vec<String>,
}

/// Zero-phase band-pass by FFT masking with raised-cosine edges (±10 % of the band, and at
/// least two lines of the record's resolution, 2/T: a narrower edge rings for ~1/edge, over
/// the whole of a short record, and ripples its peaks).
pub fn band_pass(x: &[f64], rate_hz: f64, lo_hz: f64, hi_hz: f64) -> Vec<f64> {
    let n = x.len();
    let nfft = n.next_power_of_two() * 2;
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut buf = vec![0.0; nfft];
    for k in 0..n {
        buf[k] = x[k] - mean;
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(nfft);
    let inv = planner.plan_fft_inverse(nfft);
    let mut spec = fwd.make_output_vec();
    let _ = fwd.process(&mut buf, &mut spec);
    let edge = (0.1 * (hi_hz - lo_hz)).max(2.0 * rate_hz / n as f64);
    for (k, c) in spec.iter_mut().enumerate() {
        let f = k as f64 * rate_hz / nfft as f64;
        let g = if f < lo_hz - edge || f > hi_hz + edge {
            0.0
        } else if f < lo_hz {
            0.5 - 0.5 * (PI * (f - lo_hz + edge) / edge).cos()
        } else if f > hi_hz {
            0.5 + 0.5 * (PI * (f - hi_hz) / edge).cos()
        } else {
            1.0
        };
        *c *= g / nfft as f64;
    }
    let mut out = inv.make_output_vec();
    let _ = inv.process(&mut spec, &mut out);
    out.truncate(n);
    out
}

/// Residuals A e^{−σt} cos(ω_d t + φ) − x of p = (A, σ, ω_d, φ) on the samples (t, x).
fn sinusoid_residuals(t: &[f64], x: &[f64], p: &DVector<f64>) -> Option<DVector<f64>> {
    let (a, s, w, ph) = (p[0], p[1], p[2], p[3]);
    Some(DVector::from_iterator(
        t.len(),
        t.iter()
            .zip(x)
            .map(|(&t, &x)| a * (-s * t).exp() * (w * t + ph).cos() - x),
    ))
}

/// The analytic Jacobian of [`sinusoid_residuals`] (len(t) × 4).
fn sinusoid_jacobian(t: &[f64], p: &DVector<f64>) -> Option<DMatrix<f64>> {
    let (a, s, w, ph) = (p[0], p[1], p[2], p[3]);
    let mut j = DMatrix::<f64>::zeros(t.len(), 4);
    for (k, &t) in t.iter().enumerate() {
        let e = (-s * t).exp();
        let (sn, cs) = (w * t + ph).sin_cos();
        j[(k, 0)] = e * cs;
        j[(k, 1)] = -a * t * e * cs;
        j[(k, 2)] = -a * e * sn * t;
        j[(k, 3)] = -a * e * sn;
    }
    Some(j)
}

/// Positive peaks (index, value) of `x`, parabolically refined in time.
fn positive_peaks(x: &[f64]) -> Vec<(f64, f64)> {
    let mut v = Vec::new();
    for k in 1..x.len().saturating_sub(1) {
        if x[k] > 0.0 && x[k] > x[k - 1] && x[k] >= x[k + 1] {
            let d = x[k - 1] - 2.0 * x[k] + x[k + 1];
            let p = if d != 0.0 {
                (0.5 * (x[k - 1] - x[k + 1]) / d).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            v.push((k as f64 + p, x[k] - 0.25 * (x[k - 1] - x[k + 1]) * p));
        }
    }
    v
}

/// ζ from the logarithmic decrement δ per cycle (eq. 28).
pub fn zeta_from_log_decrement(delta: f64) -> f64 {
    1.0 / (1.0 + (2.0 * PI / delta).powi(2)).sqrt()
}

/// Log-decrement line fit over peaks: returns (δ, mean period in samples).
fn log_decrement(pk: &[(f64, f64)]) -> (f64, f64) {
    let n = pk.len() as f64;
    let xs: Vec<f64> = (0..pk.len()).map(|i| i as f64).collect();
    let ys: Vec<f64> = pk.iter().map(|p| p.1.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let period = (pk[pk.len() - 1].0 - pk[0].0) / (n - 1.0);
    (-sxy / sxx, period)
}

/// Identifies the first mode from a free decay `signal` at times `time_s` (any unit of the
/// signal: displacement, velocity or acceleration; the time base may be non-uniform).
///
/// Errors: fewer than 64 samples, non-finite values, no spectral peak in the band, a decay
/// with fewer than 4 cycles.
pub fn identify_free_decay(
    time_s: &[f64],
    signal: &[f64],
    opts: &FreeDecayOptions,
) -> Result<FreeDecayResult> {
    check_decay_input(time_s, signal)?;
    let mut warnings = Vec::new();
    let (t, x, rate) = uniform_time(time_s, signal, &mut warnings);
    let (f1, other) = mode_candidates(&x, rate, opts)?;
    let first = analyse_mode(&x, rate, f1, &mut warnings)?;
    let modes = higher_modes(&x, rate, &first.mode, &other, &mut warnings);
    let (log_decrement, sinusoid_fit, segment_s) = (
        first.log_decrement,
        first.sinusoid_fit,
        (t[0] + first.segment_s.0, t[0] + first.segment_s.1),
    );
    Ok(FreeDecayResult {
        mode: first.mode,
        modes,
        log_decrement,
        sinusoid_fit,
        segment_s,
        sample_rate_hz: rate,
        other_peaks_hz: other,
        warnings,
    })
}

/// Equal lengths ≥ 64, finite values, strictly increasing time.
fn check_decay_input(time_s: &[f64], signal: &[f64]) -> Result<()> {
    if time_s.len() != signal.len() || time_s.len() < 64 {
        bail!(
            "a free decay needs at least 64 samples of time and signal (got {} and {})",
            time_s.len(),
            signal.len()
        );
    }
    if let Some(k) = time_s
        .iter()
        .zip(signal)
        .position(|(t, x)| !t.is_finite() || !x.is_finite())
    {
        bail!("NaN or inf at sample {k}");
    }
    if let Some(k) = time_s.windows(2).position(|w| w[1] <= w[0]) {
        bail!("time not strictly increasing at sample {}", k + 1);
    }
    Ok(())
}

/// (time, signal, rate): as given when the steps are uniform within 1 %, else resampled at the
/// median step by linear interpolation (with a warning).
fn uniform_time(
    time_s: &[f64],
    signal: &[f64],
    warnings: &mut Vec<String>,
) -> (Vec<f64>, Vec<f64>, f64) {
    let mut dts: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(|a, b| a.total_cmp(b));
    let dt = dts[dts.len() / 2];
    let rate = 1.0 / dt;
    let (t, x) = if dts[dts.len() - 1] > 1.01 * dt || dts[0] < 0.99 * dt {
        let (tu, xu, gap) = crate::recording::resample_uniform(time_s, signal, rate);
        warnings.push(format!(
            "non-uniform time base (steps {:.3e}..{:.3e} s): resampled to {:.1} Hz by linear interpolation; longest gap {:.2} ms",
            dts[0], dts[dts.len() - 1], rate, gap * 1e3
        ));
        (tu, xu)
    } else {
        (time_s.to_vec(), signal.to_vec())
    };
    (t, x, rate)
}

/// The first mode's spectral peak f1 (the lowest peak within `mode_fraction` of the
/// strongest) and the higher-mode candidates (Hz).
fn mode_candidates(x: &[f64], rate: f64, opts: &FreeDecayOptions) -> Result<(f64, Vec<f64>)> {
    let f_max = opts.f_max_hz.min(0.45 * rate);
    let (f, mag) = amplitude_spectrum(x, rate);
    let pk = peaks(&f, &mag, opts.f_min_hz, f_max);
    let strongest = pk.first().map(|p| p.1).ok_or_else(|| {
        anyhow::anyhow!("no spectral peak between {} and {f_max} Hz", opts.f_min_hz)
    })?;
    let f1 = pk
        .iter()
        .filter(|p| p.1 >= opts.mode_fraction * strongest)
        .map(|p| p.0)
        .fold(f64::INFINITY, f64::min);
    // Higher-mode candidates must stand out of the spectrum around them (×3 over the level
    // at ±15 %): wiggles on the skirt of a strong mode and filter ringing do not.
    let df = f[1] - f[0];
    let level = |fq: f64| mag.get((fq / df).round() as usize).copied().unwrap_or(0.0);
    let other: Vec<f64> = pk
        .iter()
        .filter(|p| p.1 >= opts.higher_mode_fraction * strongest && p.0 > 2.0 * f1)
        .filter(|p| p.1 > 3.0 * level(0.85 * p.0).max(level(1.15 * p.0)))
        .map(|p| p.0)
        .take(16)
        .collect();
    Ok((f1, other))
}

/// The first mode and those of the candidates `other` that decay like a mode at their own
/// frequency, ascending; a warning names the candidates that do not decay.
fn higher_modes(
    x: &[f64],
    rate: f64,
    first: &ModeEstimate,
    other: &[f64],
    warnings: &mut Vec<String>,
) -> Vec<ModeEstimate> {
    let mut modes = vec![first.clone()];
    let mut not_decaying = Vec::new();
    for &fo in other {
        match analyse_mode(x, rate, fo, &mut Vec::new()) {
            // A genuine mode decays at the frequency of its own peak; a sidelobe or noise
            // peak analysed in its band locks onto leakage of a stronger mode instead.
            Ok(m)
                if (m.mode.freq_hz / fo - 1.0).abs() < 0.03
                    && m.r2 > 0.5
                    && modes
                        .iter()
                        .all(|e| (e.freq_hz / m.mode.freq_hz - 1.0).abs() > 0.2) =>
            {
                modes.push(m.mode)
            }
            Ok(_) => {}
            Err(_) => not_decaying.push(fo),
        }
    }
    if !not_decaying.is_empty() {
        let (lo, hi) = not_decaying
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), f| (l.min(*f), h.max(*f)));
        warnings.push(format!(
            "{} spectral peak(s) at {lo:.3}..{hi:.3} Hz do not decay like a mode above the noise: not modes",
            not_decaying.len()
        ));
    }
    modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    modes
}

struct ModeAnalysis {
    mode: ModeEstimate,
    /// Fraction of the band-passed segment's energy the damped sinusoid explains.
    r2: f64,
    log_decrement: (f64, f64, usize),
    sinusoid_fit: (f64, f64),
    segment_s: (f64, f64),
}

/// The decay of the mode near `f1` (Hz): the band-passed signal and its positive peaks
/// (sample index, value) from the largest until they sink below 5 % of it or 3 × the in-band
/// noise.
fn decay_segment(
    x: &[f64],
    rate: f64,
    f1: f64,
    warnings: &mut Vec<String>,
) -> Result<(Vec<f64>, Vec<(f64, f64)>)> {
    let xb = band_pass(x, rate, 0.7 * f1, 1.3 * f1);
    let all = positive_peaks(&xb);
    if all.len() < 6 {
        bail!("fewer than 6 cycles of the {f1:.3} Hz mode in the record");
    }
    let (i0, a0) =
        all.iter().enumerate().fold(
            (0, 0.0),
            |(bi, bv), (i, p)| if p.1 > bv { (i, p.1) } else { (bi, bv) },
        );
    // Noise floor inside the band, from a band near Nyquist (0.35–0.45 × rate, assumed
    // free of modes) scaled by the bandwidth ratio (white noise); as a peak amplitude (×√2).
    let hb = band_pass(x, rate, 0.35 * rate, 0.45 * rate);
    let hb_rms = (hb.iter().map(|v| v * v).sum::<f64>() / hb.len() as f64).sqrt();
    let noise = hb_rms * ((0.6 * f1) / (0.1 * rate)).sqrt() * 2f64.sqrt();
    if a0 < 10.0 * noise {
        bail!("the {f1:.3} Hz peak never rises 10x above the in-band noise");
    }
    let start = i0 + 1;
    let mut end = start;
    while end + 1 < all.len() && all[end + 1].1 > (0.05 * a0).max(3.0 * noise) {
        end += 1;
    }
    let seg = &all[start.min(all.len() - 1)..=end.min(all.len() - 1)];
    if seg.len() < 4 {
        bail!("the decay of the {f1:.3} Hz mode lasts fewer than 4 cycles above the noise");
    }
    if seg.len() < 10 {
        warnings.push(format!("short decay: {} cycles", seg.len()));
    }
    Ok((xb, seg.to_vec()))
}

/// Least-squares damped sinusoid A e^{−σt} cos(ω_d t + φ) on the band-passed decay `xb` over
/// the peaks `seg` (≤ 40 points per `period` samples), from the log decrement's (f_n, ζ):
/// its (f_n, ζ), the fraction of the energy it explains, whether the minimiser converged and
/// why it stopped.
fn sinusoid_fit(
    xb: &[f64],
    seg: &[(f64, f64)],
    rate: f64,
    period: f64,
    fn_ld: f64,
    zeta_ld: f64,
) -> (f64, f64, f64, bool, String) {
    let fd = rate / period;
    let (k0, k1) = (seg[0].0 as usize, seg[seg.len() - 1].0 as usize);
    let step = ((period / 40.0) as usize).max(1);
    let ts: Vec<f64> = (k0..=k1)
        .step_by(step)
        .map(|k| (k - k0) as f64 / rate)
        .collect();
    let xs: Vec<f64> = (k0..=k1).step_by(step).map(|k| xb[k]).collect();
    let wd0 = 2.0 * PI * fd;
    let p0 = DVector::from_vec(vec![seg[0].1, zeta_ld * 2.0 * PI * fn_ld, wd0, 0.0]);
    let res = |p: &DVector<f64>| sinusoid_residuals(&ts, &xs, p);
    let jac = |p: &DVector<f64>| sinusoid_jacobian(&ts, p);
    // The adapter's finite-difference steps are unused with an analytic Jacobian.
    let fit = minimize_with_jacobian(&res, &jac, p0, &LmOptions::new(vec![0.0; 4]));
    let (sigma, wd) = (fit.x[1], fit.x[2]);
    let wn = (wd * wd + sigma * sigma).sqrt();
    let ss: f64 = xs.iter().map(|v| v * v).sum();
    let r2 = 1.0 - fit.cost / ss.max(1e-300);
    (wn / (2.0 * PI), sigma / wn, r2, fit.converged, fit.reason)
}

/// Log decrement and damped-sinusoid fit of the mode near `f1` (Hz).
fn analyse_mode(x: &[f64], rate: f64, f1: f64, warnings: &mut Vec<String>) -> Result<ModeAnalysis> {
    let (xb, seg) = decay_segment(x, rate, f1, warnings)?;
    let seg = &seg[..];
    let (delta, period) = log_decrement(seg);
    let zeta_ld = zeta_from_log_decrement(delta.max(1e-9));
    let fd = rate / period;
    let fn_ld = fd / (1.0 - zeta_ld * zeta_ld).sqrt();
    let thirds: Vec<f64> = seg
        .chunks((seg.len() / 3).max(3))
        .filter(|c| c.len() >= 3)
        .map(|c| zeta_from_log_decrement(log_decrement(c).0.max(1e-9)))
        .collect();
    let (fn_fit, zeta_fit, r2, converged, reason) =
        sinusoid_fit(&xb, seg, rate, period, fn_ld, zeta_ld);
    let fit_ok =
        converged && zeta_fit.is_finite() && zeta_fit >= 0.0 && (fn_fit / fn_ld - 1.0).abs() < 0.05;
    if !fit_ok {
        warnings.push(format!(
            "damped-sinusoid fit rejected ({}; f {:.4} Hz, zeta {:.5}); log decrement only",
            reason, fn_fit, zeta_fit
        ));
    }
    let (freq, zeta) = if fit_ok {
        (0.5 * (fn_ld + fn_fit), 0.5 * (zeta_ld + zeta_fit))
    } else {
        (fn_ld, zeta_ld)
    };
    // Floor: a 0.1-sample error of the first and last peak times over the segment.
    let f_std = (if fit_ok {
        (fn_ld - fn_fit).abs() / 2f64.sqrt()
    } else {
        0.0
    })
    .max(fd * 0.1 / (seg.len() as f64 * period));
    let z_std = (if fit_ok {
        (zeta_ld - zeta_fit).abs() / 2f64.sqrt()
    } else {
        0.0
    })
    .hypot(std_dev(&thirds));
    Ok(ModeAnalysis {
        r2,
        mode: ModeEstimate {
            freq_hz: freq,
            zeta,
            freq_hz_std: f_std,
            zeta_std: z_std,
            method: "free decay: log decrement + damped-sinusoid fit".into(),
        },
        log_decrement: (fn_ld, zeta_ld, seg.len()),
        sinusoid_fit: (fn_fit, zeta_fit),
        segment_s: (seg[0].0 / rate, seg[seg.len() - 1].0 / rate),
    })
}
