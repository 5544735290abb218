//! Frequency-response functions from an input/output recording (paper §3.1, Step 2).
//!
//! Welch's method: the record is cut into segments of `nperseg` samples overlapping by
//! `overlap`, each detrended and windowed (Hamming by default, as in the paper), and
//! - H1 = S_yx / S_xx (unbiased by output noise),
//! - H2 = S_yy / S_xy (unbiased by input noise),
//! - γ² = |S_xy|² / (S_xx S_yy) (coherence; 1 by construction with a single segment).
//!
//! With `nperseg = None` the whole record is one segment: the transient FRF Y(f)/X(f) of a
//! sweep recorded from rest to rest, exact for a linear system when the ring-down is
//! recorded (use the rectangular window then; the exponential window adds a known decay
//! rate σ_w to every pole, reported in [`Frf::window_decay_s`] and removed by the estimators).
//!
//! Input channels: motor force `force_n`, base acceleration (second difference of
//! `base_pos_m`), base position; outputs: tip deflection `tip_pos_m − base_pos_m` or absolute
//! tip position `tip_pos_m`.

use crate::recording::Recording;
use anyhow::{bail, Context, Result};
use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;
use serde::Serialize;

/// Data window.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Window {
    /// 0.54 − 0.46 cos (paper Step 2).
    Hamming,
    /// 0.5 − 0.5 cos.
    Hann,
    /// No window.
    Rectangular,
    /// e^{−t/τ} with the last sample at `end_fraction` of the first (impact/sweep testing).
    Exponential {
        /// Window value at the last sample (0 < end_fraction ≤ 1).
        end_fraction: f64,
    },
    /// Tukey (tapered cosine): flat, with a Hann half at each end over `taper_fraction` / 2 of
    /// the samples (Harris 1978); keeps full weight on the middle of a record.
    Tukey {
        /// Fraction of the samples tapered, both ends together (0 < taper_fraction ≤ 1).
        taper_fraction: f64,
    },
}

impl Window {
    /// `hamming`, `hann`, `rect`, `exp` (to 1 %), `exp:0.05`, `tukey` (10 %) or `tukey:0.2`.
    pub fn from_name(s: &str) -> Result<Window> {
        let l = s.to_ascii_lowercase();
        Ok(match l.as_str() {
            "hamming" => Window::Hamming,
            "hann" | "hanning" => Window::Hann,
            "rect" | "rectangular" | "boxcar" | "none" => Window::Rectangular,
            "exp" | "exponential" => Window::Exponential { end_fraction: 0.01 },
            "tukey" => Window::Tukey {
                taper_fraction: 0.1,
            },
            _ if l.starts_with("tukey:") => {
                let f: f64 = l["tukey:".len()..]
                    .parse()
                    .with_context(|| format!("window `{s}`: not a number after tukey:"))?;
                if !(f > 0.0 && f <= 1.0) {
                    bail!("window `{s}`: the taper fraction must be in (0, 1]");
                }
                Window::Tukey { taper_fraction: f }
            }
            _ => match l.strip_prefix("exp:") {
                Some(v) => {
                    let e: f64 = v
                        .parse()
                        .with_context(|| format!("window `{s}`: not a number after exp:"))?;
                    if !(e > 0.0 && e <= 1.0) {
                        bail!("window `{s}`: the end fraction must be in (0, 1]");
                    }
                    Window::Exponential { end_fraction: e }
                }
                None => {
                    bail!("unknown window `{s}` (hamming, hann, rect, exp, exp:<end fraction>, tukey, tukey:<taper fraction>)")
                }
            },
        })
    }

    /// The window's n samples.
    pub fn samples(&self, n: usize) -> Vec<f64> {
        let m = (n.max(2) - 1) as f64;
        let c = |k: usize| (2.0 * std::f64::consts::PI * k as f64 / m).cos();
        match *self {
            Window::Hamming => (0..n).map(|k| 0.54 - 0.46 * c(k)).collect(),
            Window::Hann => (0..n).map(|k| 0.5 - 0.5 * c(k)).collect(),
            Window::Rectangular => vec![1.0; n],
            Window::Exponential { end_fraction } => {
                (0..n).map(|k| end_fraction.powf(k as f64 / m)).collect()
            }
            Window::Tukey { taper_fraction } => {
                let edge = (taper_fraction / 2.0 * m).max(1.0);
                (0..n)
                    .map(|k| {
                        let from_end = k.min(n - 1 - k) as f64;
                        if from_end >= edge {
                            1.0
                        } else {
                            (std::f64::consts::FRAC_PI_2 * from_end / edge)
                                .sin()
                                .powi(2)
                        }
                    })
                    .collect()
            }
        }
    }
}

/// Detrending of each segment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Detrend {
    /// Nothing removed.
    None,
    /// Mean removed.
    Mean,
    /// Least-squares straight line removed.
    Linear,
}

impl Detrend {
    /// `none`, `mean`/`constant`, `linear`.
    pub fn from_name(s: &str) -> Result<Detrend> {
        match s.to_ascii_lowercase().as_str() {
            "none" => Ok(Detrend::None),
            "mean" | "constant" => Ok(Detrend::Mean),
            "linear" => Ok(Detrend::Linear),
            _ => bail!("unknown detrend `{s}` (none, mean, linear)"),
        }
    }

    fn apply(&self, x: &mut [f64]) {
        let n = x.len() as f64;
        match self {
            Detrend::None => {}
            Detrend::Mean => {
                let m = x.iter().sum::<f64>() / n;
                x.iter_mut().for_each(|v| *v -= m);
            }
            Detrend::Linear => {
                let mt = (n - 1.0) / 2.0;
                let m = x.iter().sum::<f64>() / n;
                let sxy: f64 = x
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64 - mt) * (v - m))
                    .sum();
                let sxx: f64 = (0..x.len()).map(|k| (k as f64 - mt).powi(2)).sum();
                let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
                x.iter_mut()
                    .enumerate()
                    .for_each(|(k, v)| *v -= m + b * (k as f64 - mt));
            }
        }
    }
}

/// Welch options.
#[derive(Clone, Debug, Serialize)]
pub struct WelchOptions {
    /// Segment length (samples); `None` = the whole record (one segment).
    pub nperseg: Option<usize>,
    /// Overlap fraction of consecutive segments, 0 ≤ overlap < 1.
    pub overlap: f64,
    /// Window.
    pub window: Window,
    /// Detrending.
    pub detrend: Detrend,
    /// Zero padding: FFT length = `pad` × segment length (rounded up to a power of two).
    pub pad: usize,
}

impl Default for WelchOptions {
    /// Paper Step 2: Hamming, 50 % overlap, mean removed, segments of 1/4 of the record.
    fn default() -> Self {
        WelchOptions {
            nperseg: None,
            overlap: 0.5,
            window: Window::Hamming,
            detrend: Detrend::Mean,
            pad: 1,
        }
    }
}

fn ser_complex<S: serde::Serializer>(
    v: &[Complex64],
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut q = s.serialize_seq(Some(v.len()))?;
    for c in v {
        q.serialize_element(&[c.re, c.im])?;
    }
    q.end()
}

/// An estimated FRF on the one-sided frequency grid 0..fs/2.
#[derive(Clone, Debug, Serialize)]
pub struct Frf {
    /// Frequencies (Hz), uniform from 0.
    pub freq_hz: Vec<f64>,
    /// H1 = S_yx / S_xx (serialised as [re, im]).
    #[serde(serialize_with = "ser_complex")]
    pub h1: Vec<Complex64>,
    /// H2 = S_yy / S_xy.
    #[serde(serialize_with = "ser_complex")]
    pub h2: Vec<Complex64>,
    /// Ordinary coherence γ².
    pub coherence: Vec<f64>,
    /// Input auto-spectrum S_xx (one-sided, units²/Hz).
    pub sxx: Vec<f64>,
    /// Output auto-spectrum S_yy.
    pub syy: Vec<f64>,
    /// Segments averaged.
    pub n_averages: usize,
    /// Sample rate (Hz).
    pub sample_rate_hz: f64,
    /// Segment length (samples).
    pub nperseg: usize,
    /// Decay rate σ_w (1/s) the exponential window adds to every pole (0 otherwise).
    pub window_decay_s: f64,
    /// What the input and output are.
    pub input: String,
    /// Output description.
    pub output: String,
}

impl Frf {
    /// Frequency step (Hz).
    pub fn df_hz(&self) -> f64 {
        self.freq_hz.get(1).copied().unwrap_or(f64::NAN)
    }

    /// Indices of the lines with f_lo ≤ f ≤ f_hi.
    pub fn band(&self, f_lo: f64, f_hi: f64) -> std::ops::Range<usize> {
        let a = self
            .freq_hz
            .iter()
            .position(|&f| f >= f_lo)
            .unwrap_or(self.freq_hz.len());
        let b = self
            .freq_hz
            .iter()
            .rposition(|&f| f <= f_hi)
            .map_or(0, |k| k + 1);
        a..b.max(a)
    }
}

/// Checks a uniformly sampled signal: at least `min_len` samples, all finite. Errors name the
/// channel and sample.
pub fn check_signal(name: &str, x: &[f64], min_len: usize) -> Result<()> {
    if x.len() < min_len {
        bail!("{name}: {} samples; at least {min_len} are needed", x.len());
    }
    if let Some(k) = x.iter().position(|v| !v.is_finite()) {
        bail!("{name}: NaN or inf at sample {k}");
    }
    Ok(())
}

/// Fraction of samples sitting at the signal's extreme values (a clipped/saturated sensor
/// shows runs of identical samples at its maximum or minimum). Returns (fraction, value).
pub fn saturation(x: &[f64]) -> (f64, f64) {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if !(hi > lo) {
        return (1.0, hi);
    }
    let tol = 1e-9 * (hi - lo);
    let at_hi = x.iter().filter(|&&v| v >= hi - tol).count();
    let at_lo = x.iter().filter(|&&v| v <= lo + tol).count();
    if at_hi >= at_lo {
        (at_hi as f64 / x.len() as f64, hi)
    } else {
        (at_lo as f64 / x.len() as f64, lo)
    }
}

/// Warns (returns a message) when more than 0.5 % of the samples sit at an extreme value.
pub fn saturation_warning(name: &str, x: &[f64]) -> Option<String> {
    let (frac, v) = saturation(x);
    (frac > 0.005).then(|| format!("{name}: {:.1} % of the samples sit at {v:.6e}: the signal looks clipped/saturated; estimates near the resonances are biased", frac * 100.0))
}

/// Welch H1/H2/coherence of output `y` over input `x`, sampled at `rate_hz`.
///
/// Errors: different lengths, fewer than 16 samples, NaN/inf, a segment longer than the
/// record or shorter than 8, overlap outside [0, 1), an input with no energy.
pub fn welch(x: &[f64], y: &[f64], rate_hz: f64, opts: &WelchOptions) -> Result<Frf> {
    let nseg = check_welch(x, y, rate_hz, opts)?;
    let nfft = (nseg * opts.pad.max(1)).next_power_of_two();
    let nf = nfft / 2 + 1;
    let win = opts.window.samples(nseg);
    let wss: f64 = win.iter().map(|w| w * w).sum();
    let sp = averaged_spectra(x, y, nseg, nfft, &win, opts)?;
    // One-sided PSD scaling (2 / (fs Σw²) per average); the FRF ratios do not depend on it.
    let scale = 2.0 / (rate_hz * wss * sp.count as f64);
    let tiny = 1e-300;
    let mut h1 = Vec::with_capacity(nf);
    let mut h2 = Vec::with_capacity(nf);
    let mut coh = Vec::with_capacity(nf);
    let (sxx, syy, sxy) = (&sp.sxx, &sp.syy, &sp.sxy);
    for k in 0..nf {
        h1.push(sxy[k] / sxx[k].max(tiny));
        h2.push(if sxy[k].norm() > tiny {
            Complex64::new(syy[k], 0.0) / sxy[k].conj()
        } else {
            Complex64::new(f64::NAN, f64::NAN)
        });
        coh.push((sxy[k].norm_sqr() / (sxx[k] * syy[k]).max(tiny)).min(1.0));
    }
    if sxx.iter().all(|&v| v <= tiny) {
        bail!("the input has no energy (constant signal)");
    }
    let window_decay_s = match opts.window {
        Window::Exponential { end_fraction } => {
            -end_fraction.ln() * rate_hz / (nseg.max(2) - 1) as f64
        }
        _ => 0.0,
    };
    Ok(Frf {
        freq_hz: (0..nf).map(|k| k as f64 * rate_hz / nfft as f64).collect(),
        h1,
        h2,
        coherence: coh,
        sxx: sxx.iter().map(|v| v * scale).collect(),
        syy: syy.iter().map(|v| v * scale).collect(),
        n_averages: sp.count,
        sample_rate_hz: rate_hz,
        nperseg: nseg,
        window_decay_s,
        input: "input".into(),
        output: "output".into(),
    })
}

/// Checks the signals and options of [`welch`]; returns the segment length.
fn check_welch(x: &[f64], y: &[f64], rate_hz: f64, opts: &WelchOptions) -> Result<usize> {
    if x.len() != y.len() {
        bail!("input has {} samples, output {}", x.len(), y.len());
    }
    check_signal("input", x, 16)?;
    check_signal("output", y, 16)?;
    if !(rate_hz > 0.0 && rate_hz.is_finite()) {
        bail!("sample rate must be positive (got {rate_hz})");
    }
    if !(0.0..1.0).contains(&opts.overlap) {
        bail!("overlap must be in [0, 1) (got {})", opts.overlap);
    }
    let n = x.len();
    let nseg = opts.nperseg.unwrap_or(n);
    if nseg > n || nseg < 8 {
        bail!("segment length {nseg} must be between 8 and the record length {n}");
    }
    Ok(nseg)
}

/// Unscaled sums over the segments of |X|², |Y|², X̄Y and their number.
struct SpectraSums {
    sxx: Vec<f64>,
    syy: Vec<f64>,
    sxy: Vec<Complex64>,
    count: usize,
}

/// The sums of [`SpectraSums`] over segments of `nseg` samples stepped by the overlap,
/// detrended, windowed by `win`, zero-padded to `nfft`.
fn averaged_spectra(
    x: &[f64],
    y: &[f64],
    nseg: usize,
    nfft: usize,
    win: &[f64],
    opts: &WelchOptions,
) -> Result<SpectraSums> {
    let n = x.len();
    let step = ((nseg as f64 * (1.0 - opts.overlap)).round() as usize).max(1);
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
    let nf = nfft / 2 + 1;
    let mut sums = SpectraSums {
        sxx: vec![0.0; nf],
        syy: vec![0.0; nf],
        sxy: vec![Complex64::new(0.0, 0.0); nf],
        count: 0,
    };
    let (mut bx, mut by) = (fft.make_input_vec(), fft.make_input_vec());
    let (mut fx, mut fy) = (fft.make_output_vec(), fft.make_output_vec());
    let mut start = 0;
    while start + nseg <= n {
        let mut sx = x[start..start + nseg].to_vec();
        let mut sy = y[start..start + nseg].to_vec();
        opts.detrend.apply(&mut sx);
        opts.detrend.apply(&mut sy);
        bx.iter_mut().for_each(|v| *v = 0.0);
        by.iter_mut().for_each(|v| *v = 0.0);
        for k in 0..nseg {
            bx[k] = sx[k] * win[k];
            by[k] = sy[k] * win[k];
        }
        fft.process(&mut bx, &mut fx)
            .map_err(|e| anyhow::anyhow!("FFT: {e}"))?;
        fft.process(&mut by, &mut fy)
            .map_err(|e| anyhow::anyhow!("FFT: {e}"))?;
        for k in 0..nf {
            sums.sxx[k] += fx[k].norm_sqr();
            sums.syy[k] += fy[k].norm_sqr();
            sums.sxy[k] += fx[k].conj() * fy[k];
        }
        sums.count += 1;
        start += step;
    }
    Ok(sums)
}

/// Input channel of an FRF.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum InputChannel {
    /// Motor force `force_n` (N): the paper's input (poles = free-base modes).
    Force,
    /// Base acceleration (m/s²), second difference of `base_pos_m` (or `base_cmd_m`):
    /// poles = clamped-base modes.
    BaseAccel,
    /// Base position (m).
    BasePos,
}

impl InputChannel {
    /// `force`, `accel`/`base_acc`, `pos`/`base_pos`.
    pub fn from_name(s: &str) -> Result<InputChannel> {
        match s.to_ascii_lowercase().as_str() {
            "force" | "force_n" => Ok(InputChannel::Force),
            "accel" | "acc" | "base_acc" | "base_accel" => Ok(InputChannel::BaseAccel),
            "pos" | "base_pos" | "base_pos_m" => Ok(InputChannel::BasePos),
            _ => bail!("unknown input `{s}` (force, accel, pos)"),
        }
    }
}

/// Output channel of an FRF.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum OutputChannel {
    /// Tip deflection `tip_pos_m − base_pos_m` (m).
    TipDeflection,
    /// Absolute tip position `tip_pos_m` (m).
    TipAbsolute,
}

impl OutputChannel {
    /// `deflection`/`tip_defl`, `tip`/`tip_abs`.
    pub fn from_name(s: &str) -> Result<OutputChannel> {
        match s.to_ascii_lowercase().as_str() {
            "deflection" | "defl" | "tip_defl" | "tip_deflection" => {
                Ok(OutputChannel::TipDeflection)
            }
            "tip" | "tip_abs" | "tip_pos" | "tip_pos_m" | "absolute" => {
                Ok(OutputChannel::TipAbsolute)
            }
            _ => bail!("unknown output `{s}` (deflection, tip)"),
        }
    }
}

/// The input and output signals of `rec` (validated), with descriptions and warnings
/// (saturation). Errors: a missing column (named).
pub fn channels(
    rec: &Recording,
    input: InputChannel,
    output: OutputChannel,
) -> Result<(Vec<f64>, Vec<f64>, String, String, Vec<String>)> {
    rec.validate()?;
    let base = rec
        .base_pos_m
        .as_ref()
        .map(|v| (v, "base_pos_m"))
        .or(rec.base_cmd_m.as_ref().map(|v| (v, "base_cmd_m")));
    let dt = rec.sample_interval_s();
    let (x, xd) = match input {
        InputChannel::Force => (
            rec.force_n
                .clone()
                .context("the recording has no force_n column (input = force)")?,
            "motor force force_n (N)".to_string(),
        ),
        InputChannel::BasePos => {
            let (b, name) = base.context(
                "the recording has no base_pos_m or base_cmd_m column (input = base position)",
            )?;
            (b.clone(), format!("base position {name} (m)"))
        }
        InputChannel::BaseAccel => {
            let (b, name) = base.context(
                "the recording has no base_pos_m or base_cmd_m column (input = base acceleration)",
            )?;
            let n = b.len();
            let mut a = vec![0.0; n];
            for k in 1..n.saturating_sub(1) {
                a[k] = (b[k + 1] - 2.0 * b[k] + b[k - 1]) / (dt * dt);
            }
            (
                a,
                format!("base acceleration (second difference of {name}, m/s^2)"),
            )
        }
    };
    let tip = rec
        .tip_pos_m
        .as_ref()
        .context("the recording has no tip_pos_m column (output)")?;
    let (y, yd) = match output {
        OutputChannel::TipAbsolute => (tip.clone(), "absolute tip position tip_pos_m (m)".to_string()),
        OutputChannel::TipDeflection => match base {
            Some((b, name)) => (tip.iter().zip(b).map(|(t, b)| t - b).collect(), format!("tip deflection tip_pos_m - {name} (m)")),
            None => bail!("tip deflection needs base_pos_m or base_cmd_m; the recording has neither (use --output tip)"),
        },
    };
    let mut warnings = Vec::new();
    for (name, v) in [("input", &x), ("output", &y)] {
        if let Some(w) = saturation_warning(name, v) {
            warnings.push(w);
        }
    }
    if let Some(t) = rec.tip_pos_m.as_deref() {
        if let Some(w) = saturation_warning("tip_pos_m", t) {
            warnings.push(w);
        }
    }
    Ok((x, y, xd, yd, warnings))
}

/// FRF of a recording: [`channels`] then [`welch`].
pub fn frf_of_recording(
    rec: &Recording,
    input: InputChannel,
    output: OutputChannel,
    opts: &WelchOptions,
) -> Result<(Frf, Vec<String>)> {
    let (x, y, xd, yd, warnings) = channels(rec, input, output)?;
    let mut f = welch(&x, &y, rec.sample_rate_hz(), opts)?;
    f.input = xd;
    f.output = yd;
    Ok((f, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// y = h * x for a one-pole filter y[k] = a y[k-1] + x[k]: H(e^{iω}) = 1 / (1 − a e^{−iω}).
    #[test]
    fn h1_h2_match_a_known_filter_and_coherence_drops_with_noise() {
        let mut rng = StdRng::seed_from_u64(1);
        let nrm = Normal::new(0.0, 1.0).unwrap();
        let n = 1 << 14;
        let x: Vec<f64> = (0..n).map(|_| nrm.sample(&mut rng)).collect();
        let a = 0.9;
        let mut y = vec![0.0; n];
        for k in 0..n {
            y[k] = x[k] + if k > 0 { a * y[k - 1] } else { 0.0 };
        }
        let opts = WelchOptions {
            nperseg: Some(512),
            ..Default::default()
        };
        let f = welch(&x, &y, 1.0, &opts).unwrap();
        assert!(f.n_averages > 50);
        for k in (5..250).step_by(20) {
            let w = 2.0 * std::f64::consts::PI * f.freq_hz[k];
            let h = Complex64::new(1.0, 0.0)
                / (Complex64::new(1.0, 0.0) - a * Complex64::new(0.0, -w).exp());
            assert!((f.h1[k] - h).norm() / h.norm() < 0.05, "H1 at {k}");
            assert!((f.h2[k] - h).norm() / h.norm() < 0.05, "H2 at {k}");
            assert!(f.coherence[k] > 0.98);
        }
        // Output noise: H1 stays, coherence falls where the output is weak (high f).
        let yn: Vec<f64> = y.iter().map(|v| v + 1.0 * nrm.sample(&mut rng)).collect();
        let g = welch(&x, &yn, 1.0, &opts).unwrap();
        let k = 250;
        assert!(g.coherence[k] < 0.8, "{}", g.coherence[k]);
        let w = 2.0 * std::f64::consts::PI * g.freq_hz[k];
        let h = Complex64::new(1.0, 0.0)
            / (Complex64::new(1.0, 0.0) - a * Complex64::new(0.0, -w).exp());
        assert!((g.h1[k].norm() / h.norm() - 1.0).abs() < 0.25);
        // H2 is biased upwards by output noise.
        assert!(g.h2[k].norm() > 1.1 * h.norm());
    }

    #[test]
    fn detrend_and_windows() {
        let mut v: Vec<f64> = (0..10).map(|k| 3.0 + 2.0 * k as f64).collect();
        Detrend::Linear.apply(&mut v);
        assert!(v.iter().all(|x| x.abs() < 1e-12));
        let h = Window::Hamming.samples(11);
        assert!((h[0] - 0.08).abs() < 1e-12 && (h[5] - 1.0).abs() < 1e-12);
        assert!(
            matches!(Window::from_name("exp:0.1").unwrap(), Window::Exponential { end_fraction } if (end_fraction - 0.1).abs() < 1e-15)
        );
        assert!(Window::from_name("kaiser").is_err());
        let t = Window::Tukey {
            taper_fraction: 0.2,
        }
        .samples(101);
        assert!(t[0] == 0.0 && t[100] == 0.0 && t[10] == 1.0 && t[50] == 1.0 && t[5] < 1.0);
        assert!(Window::from_name("tukey:1.5").is_err());
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let x = vec![1.0; 100];
        let mut y = vec![0.0; 100];
        assert!(welch(&x, &y[..50], 100.0, &WelchOptions::default()).is_err());
        y[10] = f64::NAN;
        assert!(welch(&x, &y, 100.0, &WelchOptions::default())
            .unwrap_err()
            .to_string()
            .contains("sample 10"));
        let opts = WelchOptions {
            nperseg: Some(1000),
            ..Default::default()
        };
        assert!(welch(&x, &x, 100.0, &opts).is_err());
        assert!(welch(&x[..5], &x[..5], 100.0, &WelchOptions::default()).is_err());
        let clipped: Vec<f64> = (0..1000)
            .map(|k| (k as f64 * 0.05).sin().clamp(-0.7, 0.7))
            .collect();
        assert!(saturation_warning("x", &clipped).is_some());
        let clean: Vec<f64> = (0..1000).map(|k| (k as f64 * 0.05).sin()).collect();
        assert!(saturation_warning("x", &clean).is_none());
    }
}
