//! `identify` on Klipper's raw accelerometer file of a resonance test (`TEST_RESONANCES …
//! OUTPUT=raw_data`, `raw_data_*.csv`): the spectrum path.
//!
//! Klipper's test drives the toolhead with a sweep of its own: a square wave of acceleration
//! `accel_per_hz · f` whose frequency f rises at `hz_per_sec` from `min_freq` to `max_freq`
//! (v0.13.0 defaults 60 mm/s²/Hz, 1 Hz/s, 5–135 Hz; docs `Measuring_Resonances.md` and
//! `Config_Reference.md` `[resonance_tester]`), plus a slow back-and-forth sweeping motion.
//! The response is forced at the sweep's frequency all the time: an output-only estimator
//! (SSI-cov) sees a non-stationary, forced response, not free vibration, and finds a mode in
//! only a few of its blocks. No input is recorded, so no FRF can be formed either.
//!
//! What the file does measure is the spectrum Klipper calibrates on: the PSD of the response
//! to an input whose acceleration spectrum rises as f² (amplitude ∝ f, one Hz per
//! `1/hz_per_sec` s), so the PSD is `|H(f)|² f²` up to a constant and its peak is the
//! resonance (within O(ζ²) of it). This path:
//! 1. detects the sweep ([`swept_ridge`]): the dominant frequency of successive half-second
//!    windows rises with time (Kendall's trend test at one-sided p < 0.001) over at least an
//!    octave;
//! 2. computes Klipper's PSD of the axis read ([`crate::recording::rawpsd`], Klipper v0.13.0's
//!    method);
//! 3. reports a mode at each distinct peak ([`psd_peaks`]) in Klipper's range (5–200 Hz, within
//!    `--band`): the largest, and every other local maximum above Klipper's vibration threshold
//!    (max / 20) separated from a larger one by a dip below half the smaller (the half-power
//!    criterion); frequency by a parabola through the log PSD at the peak's three bins, damping
//!    from the half-power band, ζ = (f₂ − f₁) / (2 f₀).

use super::identify_types::{rayleigh, IdentPath, Identification, IdentifyOptions, PathChoice};
use super::ModeEstimate;
use crate::recording::klipper::choose_axis;
use crate::recording::psd::{KlipperSpectrum, KLIPPER_MIN_FREQ_HZ};
use crate::recording::rawpsd::{kaiser, raw_spectrum, read_raw, welch_psd, KAISER_BETA};
use crate::recording::{fmt_sig, Axis};
use crate::shaping::klipper::{MAX_FREQ_HZ, SHAPER_VIBRATION_REDUCTION};
use anyhow::{bail, Result};
use std::path::Path;

/// One-sided standard-normal quantile at p = 0.001: the level of the sweep's trend test.
pub const TREND_Z: f64 = 3.09;
/// The dominant frequency must cover at least this ratio (an octave) from its 5 % to its
/// 95 % quantile: a sweep crosses a band, a drifting resonance does not.
pub const SWEEP_SPAN_RATIO: f64 = 2.0;
/// Half-power band: the PSD (a power) falls to half its peak.
pub const HALF_POWER: f64 = 0.5;

/// A peak of a PSD and its half-power band.
#[derive(Clone, Debug, PartialEq)]
pub struct PsdPeak {
    /// Peak frequency (Hz), parabolic interpolation of ln PSD over the peak's three bins.
    pub freq_hz: f64,
    /// The PSD at the peak's bin.
    pub psd: f64,
    /// Half-power crossings (Hz), linearly interpolated; `None` where the PSD does not fall
    /// to half before the band's edge.
    pub half_power_hz: (Option<f64>, Option<f64>),
    /// Bin spacing (Hz).
    pub df_hz: f64,
}

impl PsdPeak {
    /// ζ = (f₂ − f₁) / (2 f₀) from the half-power band; `None` when a side is missing.
    pub fn zeta(&self) -> Option<f64> {
        match self.half_power_hz {
            (Some(a), Some(b)) => Some((b - a) / (2.0 * self.freq_hz)),
            _ => None,
        }
    }
}

/// The sweep check's verdict: `Ok(why)` when the dominant frequency of successive windows of
/// `m` samples of `x` (sample rate `fs` Hz; dominant = the largest bin of the window's
/// Kaiser-windowed periodogram within `band` Hz) rises with time — Kendall's S over the
/// windows at z ≥ [`TREND_Z`] (no-ties variance n(n−1)(2n+5)/18, conservative with ties) —
/// and spans at least [`SWEEP_SPAN_RATIO`]; `Err(why not)` otherwise.
pub fn swept_ridge(
    x: &[f64],
    fs: f64,
    m: usize,
    band: (f64, f64),
) -> std::result::Result<String, String> {
    let windows = x.len() / m.max(1);
    if windows < 8 {
        return Err(format!(
            "{windows} windows of {m} samples: too short to see a sweep"
        ));
    }
    let df = fs / m as f64;
    let ridge: Vec<f64> = (0..windows)
        .map(|w| {
            let p = welch_psd(&x[w * m..(w + 1) * m], fs, m);
            let k = (0..p.len())
                .filter(|&k| (band.0..=band.1).contains(&(k as f64 * df)))
                .max_by(|&a, &b| p[a].total_cmp(&p[b]))
                .unwrap_or(0);
            k as f64 * df
        })
        .collect();
    let n = ridge.len();
    let s: f64 = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .map(|(i, j)| (ridge[j] - ridge[i]).signum())
        .sum();
    let nf = n as f64;
    let z = s / (nf * (nf - 1.0) * (2.0 * nf + 5.0) / 18.0).sqrt();
    let mut sorted = ridge.clone();
    sorted.sort_by(f64::total_cmp);
    let (lo, hi) = (sorted[n / 20], sorted[n - 1 - n / 20]);
    let what = format!(
        "the dominant frequency of {n} windows of {} s runs {}–{} Hz (5–95 %), Kendall's trend z = {}",
        fmt_sig(m as f64 / fs, 3),
        fmt_sig(lo, 3),
        fmt_sig(hi, 3),
        fmt_sig(z, 3)
    );
    match z >= TREND_Z && hi >= SWEEP_SPAN_RATIO * lo.max(df) {
        true => Ok(format!("a swept excitation ({what})")),
        false => Err(format!(
            "no sweep ({what}; a sweep rises at z ≥ {TREND_Z} over an octave)"
        )),
    }
}

/// The half-power crossing of `p` walking from bin `k` by `dir` (±1) within `lo..=hi`,
/// linearly interpolated in frequency (bins at `k·df`); `None` at the band's edge.
fn crossing(p: &[f64], k: usize, dir: isize, lo: usize, hi: usize, df: f64) -> Option<f64> {
    let half = HALF_POWER * p[k];
    let mut i = k;
    loop {
        let j = i as isize + dir;
        if j < lo as isize || j > hi as isize {
            return None;
        }
        let j = j as usize;
        if p[j] < half {
            let t = (p[i] - half) / (p[i] - p[j]);
            return Some((i as f64 + dir as f64 * t) * df);
        }
        i = j;
    }
}

/// The peak at bin `k` of `p` (bins `i·df`) with its half-power band inside `lo..=hi`.
fn peak_at(p: &[f64], k: usize, lo: usize, hi: usize, df: f64) -> PsdPeak {
    let mut f = k as f64 * df;
    if k > lo && k < hi && p[k - 1] > 0.0 && p[k + 1] > 0.0 {
        let (a, b, c) = (p[k - 1].ln(), p[k].ln(), p[k + 1].ln());
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            f += 0.5 * (a - c) / den * df;
        }
    }
    PsdPeak {
        freq_hz: f,
        psd: p[k],
        half_power_hz: (
            crossing(p, k, -1, lo, hi, df),
            crossing(p, k, 1, lo, hi, df),
        ),
        df_hz: df,
    }
}

/// The distinct peaks of the PSD `p` on uniform bins `freq_hz` (from 0 Hz) within `band` Hz,
/// largest first: the largest bin, then every local maximum above max / 20 (Klipper's
/// vibration threshold) whose dip to each kept peak falls below half the smaller of the two
/// (the half-power criterion). Empty when the band holds fewer than 3 bins or no power.
pub fn psd_peaks(freq_hz: &[f64], p: &[f64], band: (f64, f64)) -> Vec<PsdPeak> {
    let inb: Vec<usize> = (0..p.len())
        .filter(|&i| (band.0..=band.1).contains(&freq_hz[i]))
        .collect();
    if inb.len() < 3 || freq_hz.len() < 2 {
        return vec![];
    }
    let (lo, hi) = (inb[0], inb[inb.len() - 1]);
    let df = freq_hz[1] - freq_hz[0];
    let max = inb.iter().map(|&i| p[i]).fold(0.0, f64::max);
    if max <= 0.0 {
        return vec![];
    }
    let th = max / SHAPER_VIBRATION_REDUCTION;
    let cand: Vec<usize> = inb
        .iter()
        .copied()
        .filter(|&i| {
            let left = i == lo || p[i] >= p[i - 1];
            let right = i == hi || p[i] > p[i + 1];
            p[i] > th && left && right
        })
        .collect();
    let kept = crate::numeric::peaks::distinct_peaks(p, cand, HALF_POWER, usize::MAX);
    kept.iter().map(|&k| peak_at(p, k, lo, hi, df)).collect()
}

/// Half-power width (Hz) of the estimator's own spectral window: the Kaiser β 6 window of `m`
/// samples at `fs` Hz, |W(f)|² at half its maximum (zero-padded 16×). A peak whose half-power
/// band is not well above it is resolution-limited.
pub fn window_half_power_hz(m: usize, fs: f64) -> f64 {
    let pad = 16 * m;
    let mut x = kaiser(m, KAISER_BETA);
    x.resize(pad, 0.0);
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(pad);
    let mut out = fft.make_output_vec();
    fft.process(&mut x, &mut out).expect("buffer lengths");
    let p0 = out[0].norm_sqr();
    let k = out
        .iter()
        .position(|c| c.norm_sqr() < HALF_POWER * p0)
        .unwrap_or(out.len());
    2.0 * k as f64 * fs / pad as f64
}

/// The axis of the raw file at `path` to identify, and why: `--axis`; else the axis Klipper's
/// `TEST_RESONANCES` names in the file (`raw_data_x_…`, `raw_data_y_…`: the axis it excited;
/// Klipper writes the accelerations after its `axes_map`, so in the printer's axes); else the
/// one with the most energy (the reader's rule, [`choose_axis`]). A note is added to `warnings`
/// when the named axis is not the one with the most energy.
fn axis_of(
    path: &Path,
    acc: &[Vec<f64>; 3],
    asked: Option<Axis>,
    warnings: &mut Vec<String>,
) -> (Axis, &'static str) {
    let most = choose_axis([&acc[0], &acc[1], &acc[2]], None).0;
    if let Some(a) = asked {
        return (a, "--axis");
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let named = match () {
        _ if name.starts_with("raw_data_x_") => Some(Axis::X),
        _ if name.starts_with("raw_data_y_") => Some(Axis::Y),
        _ => None,
    };
    match named {
        Some(a) => {
            if a != most {
                warnings.push(format!(
                    "axis {} (the test's, from the file name) is read; axis {} holds more energy (choose it with --axis)",
                    a.name(),
                    most.name()
                ));
            }
            (a, "the test's axis, from the file name")
        }
        None => (most, "the axis with the most energy"),
    }
}

/// Identifies Klipper's raw accelerometer file at `path` on the spectrum path (module docs)
/// when the path is asked for (`--path spectrum`) or, under `auto`, when the file holds a
/// sweep. `Ok(None)`: not this path (another path reads the file).
///
/// Errors: the file cannot be read as Klipper's raw CSV; on the asked path, too short for
/// Klipper's PSD (under `auto` such a file goes to the time-domain paths); no power in the
/// band.
pub fn identify_klipper_raw(path: &Path, opts: &IdentifyOptions) -> Result<Option<Identification>> {
    match opts.path {
        PathChoice::Spectrum => spectrum_path(path, opts, Some("spectrum path asked for")),
        PathChoice::Auto => spectrum_path(path, opts, None),
        _ => Ok(None),
    }
}

/// The spectrum path on the raw file at `path`: taken when it holds a sweep, or whatever it
/// holds when `forced` says why (then errors are the caller's). `Ok(None)` when not taken.
pub fn spectrum_path(
    path: &Path,
    opts: &IdentifyOptions,
    forced: Option<&str>,
) -> Result<Option<Identification>> {
    let raw = read_raw(path)?;
    let s = match raw_spectrum(&raw) {
        Ok(s) => s,
        Err(e) if forced.is_some() => bail!("{}: {e}", path.display()),
        Err(_) => return Ok(None), // too short for Klipper's PSD: the time-domain paths
    };
    let mut warnings = vec![];
    let (axis, axis_why) = axis_of(path, &raw.acc_mm_s2, opts.read.axis, &mut warnings);
    let m = 2 * (s.freq_hz.len() - 1);
    let fs = s.freq_hz[1] * m as f64;
    let band = (
        KLIPPER_MIN_FREQ_HZ.max(opts.decay.f_min_hz),
        MAX_FREQ_HZ.min(opts.decay.f_max_hz).min(0.5 * fs),
    );
    let sweep = swept_ridge(&raw.acc_mm_s2[axis.index()], fs, m, band);
    let why = match (&sweep, forced) {
        (Ok(w), _) => w.clone(),
        (Err(w), Some(f)) => format!("{f}; {w}"),
        (Err(_), None) => return Ok(None),
    };
    let why = format!("{why}; axis {}: {axis_why}", axis.name());
    let mut id = spectrum_identification(path, &s, axis, band, why, raw.time_s.len())?;
    id.warnings.splice(0..0, warnings);
    Ok(Some(id))
}

/// The [`Identification`] of the PSD of `axis` in `s` (module docs, step 3).
fn spectrum_identification(
    path: &Path,
    s: &KlipperSpectrum,
    axis: Axis,
    band: (f64, f64),
    why: String,
    rows: usize,
) -> Result<Identification> {
    let p = [&s.psd_x, &s.psd_y, &s.psd_z][axis.index()];
    let peaks = psd_peaks(&s.freq_hz, p, band);
    let Some(top) = peaks.first() else {
        bail!(
            "{}: Klipper's PSD of axis {} has no power in {}–{} Hz",
            path.display(),
            axis.name(),
            fmt_sig(band.0, 3),
            fmt_sig(band.1, 3)
        );
    };
    let df = s.freq_hz[1];
    let m = 2 * (s.freq_hz.len() - 1);
    let fs = df * m as f64;
    let bw = window_half_power_hz(m, fs);
    let mut warnings = vec![];
    let mut modes: Vec<ModeEstimate> = peaks
        .iter()
        .map(|pk| peak_mode(pk, bw, &mut warnings))
        .collect();
    modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    warn_low_frequency(&s.freq_hz, p, band, top, &mut warnings);
    let reason = format!(
        "Klipper raw accelerometer file, {why}: a resonance test (forced throughout, no input recorded: neither an FRF nor output-only SSI applies); the peaks of Klipper's PSD of axis {} ({rows} rows at {} Hz, Kaiser β 6 Welch, {m}-sample segments, Δf {} Hz) in {}–{} Hz: largest {} Hz, damping from the half-power band (the input's acceleration spectrum rises as f², which moves the peak by O(ζ²))",
        axis.name(),
        fmt_sig(fs, 5),
        fmt_sig(df, 4),
        fmt_sig(band.0, 3),
        fmt_sig(band.1, 3),
        fmt_sig(top.freq_hz, 4)
    );
    Ok(Identification {
        rayleigh: rayleigh(&modes, &mut warnings),
        modes,
        path: IdentPath::KlipperPsd,
        reason,
        rejected: vec![],
        warnings,
        span_s: (0.0, rows as f64 / fs),
        sample_rate_hz: fs,
        base: None,
        frf_result: None,
        decay_result: None,
    })
}

/// The mode of one PSD peak: f ± Δf/√12 (the bin's resolution), ζ from the half-power band
/// ± √2·(Δf/√12)/(2f) (each crossing to within a bin); a warning when the band is not
/// resolved (< 2 × the window's own half-power width `bw` Hz: ζ is then an upper bound) or
/// leaves the band (ζ undetermined, NaN).
fn peak_mode(pk: &PsdPeak, bw: f64, warnings: &mut Vec<String>) -> ModeEstimate {
    let sf = pk.df_hz / 12f64.sqrt();
    let zeta = pk.zeta();
    match zeta {
        None => warnings.push(format!(
            "{} Hz: the PSD does not fall to half its peak inside the band; ζ undetermined",
            fmt_sig(pk.freq_hz, 4)
        )),
        Some(z) if 2.0 * z * pk.freq_hz < 2.0 * bw => warnings.push(format!(
            "{} Hz: half-power band {} Hz against the Kaiser window's own {} Hz: resolution-limited, ζ {} is an upper bound",
            fmt_sig(pk.freq_hz, 4),
            fmt_sig(2.0 * z * pk.freq_hz, 3),
            fmt_sig(bw, 3),
            fmt_sig(z, 3)
        )),
        Some(_) => {}
    }
    ModeEstimate {
        freq_hz: pk.freq_hz,
        zeta: zeta.unwrap_or(f64::NAN),
        freq_hz_std: sf,
        zeta_std: std::f64::consts::SQRT_2 * sf / (2.0 * pk.freq_hz),
        method: "Klipper PSD peak + half-power".into(),
    }
}

/// A warning when the PSD below the band (the test's slow sweeping motion, gravity's
/// changes) is larger than the band's largest peak `top`.
fn warn_low_frequency(
    freq_hz: &[f64],
    p: &[f64],
    band: (f64, f64),
    top: &PsdPeak,
    warnings: &mut Vec<String>,
) {
    let below = (1..freq_hz.len())
        .filter(|&i| freq_hz[i] < band.0)
        .max_by(|&a, &b| p[a].total_cmp(&p[b]));
    if let Some(i) = below.filter(|&i| p[i] > top.psd) {
        warnings.push(format!(
            "the PSD at {} Hz, below Klipper's range, exceeds the peak at {} Hz (the test's slow sweeping motion); Klipper attenuates it as low-frequency noise and so does this path",
            fmt_sig(freq_hz[i], 3),
            fmt_sig(top.freq_hz, 4)
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_power_band_of_a_lorentzian_gives_its_damping() {
        let (f0, z, df) = (40.0, 0.05, 0.1);
        let f: Vec<f64> = (0..2000).map(|i| i as f64 * df).collect();
        let p: Vec<f64> = f
            .iter()
            .map(|&x| {
                let r = x / f0;
                1.0 / ((1.0 - r * r).powi(2) + (2.0 * z * r).powi(2))
            })
            .collect();
        let pk = &psd_peaks(&f, &p, (5.0, 150.0))[0];
        assert!((pk.freq_hz - f0).abs() < 0.2, "{pk:?}");
        assert!((pk.zeta().unwrap() / z - 1.0).abs() < 0.02, "{pk:?}");
    }

    #[test]
    fn a_rising_ridge_is_a_sweep_and_a_fixed_tone_is_not() {
        let fs = 1600.0;
        let n = 60 * 1600;
        let sweep: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (2.0 * std::f64::consts::PI * (5.0 * t + t * t)).sin()
            })
            .collect();
        assert!(swept_ridge(&sweep, fs, 1024, (5.0, 200.0)).is_ok());
        let tone: Vec<f64> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 40.0 * i as f64 / fs).sin())
            .collect();
        assert!(swept_ridge(&tone, fs, 1024, (5.0, 200.0)).is_err());
    }
}
