//! The power spectral density Klipper computes from a raw accelerometer file
//! (`raw_data_*.csv`, `adxl345-*.csv`: `#time,accel_x,accel_y,accel_z`, s and mm/s²), so that a
//! raw file designs the same shaper as the `resonances_*.csv` Klipper writes from it.
//!
//! Method: Klipper v0.13.0's `ShaperCalibrate.calc_freq_response` and `_psd`
//! (`klippy/extras/shaper_calibrate.py`; docs `Measuring_Resonances.md`, "Input Shaper
//! auto-calibration" and the offline `calibrate_shaper.py` of raw data), reimplemented from its
//! description (Klipper is GPL-3; none of its code is here):
//! 1. the samples are taken as uniform at the mean rate `fs = N / (t_last − t_first)` (Klipper's
//!    estimate; the stamps are not otherwise used);
//! 2. the segment `M` is the power of two above `⌊fs · 0.5 s − 1⌋` (the first power of two
//!    holding half a second of samples: 2048 at 3.2 kHz, 1024 at 1.6 kHz);
//! 3. per axis, Welch's method: segments of `M` samples every `M − ⌊M/2⌋` (50 % overlap; only
//!    whole segments, `⌊(N − ⌊M/2⌋) / (M − ⌊M/2⌋)⌋` of them), each detrended by its mean and
//!    multiplied by the symmetric Kaiser window of β = 6, FFT'd (`realfft`), `|X_k|²` scaled by
//!    `1 / (fs Σ w²)` (density) and doubled except at 0 Hz and at the last bin (Nyquist), then
//!    averaged over the segments;
//! 4. bins `k fs / M`, k = 0 … M/2, the same for X, Y, Z; `psd_xyz` = their sum.
//!
//! The result is a [`KlipperSpectrum`] before Klipper's division by frequency (`normalized`
//! false), as a `resonances_*.csv` holds it; [`format_spectrum_csv`] writes it in that format
//! (`%.1f` Hz, `%.3e` PSDs, bins below 200 Hz).

use super::csvread::{layout, read_columns, Wanted};
use super::klipper::{is_klipper_header, HEADER};
use super::psd::{KlipperSpectrum, SPECTRUM_HEADER};
use anyhow::{bail, Result};
use realfft::RealFftPlanner;
use std::path::Path;

/// Klipper's `WINDOW_T_SEC` (s): the Welch segment holds the first power of two of samples
/// beyond this duration.
pub const WINDOW_T_SEC: f64 = 0.5;
/// The Kaiser window's β in Klipper's PSD.
pub const KAISER_BETA: f64 = 6.0;
/// Klipper's `MAX_FREQ` (Hz): the spectrum files hold bins below it.
pub const FILE_MAX_FREQ_HZ: f64 = 200.0;

/// A raw accelerometer file as recorded: time (s) and the three axes (mm/s²), one row each.
#[derive(Clone, Debug, PartialEq)]
pub struct RawAccel {
    /// Sample times (s, the printer's clock), as written.
    pub time_s: Vec<f64>,
    /// Accelerations along the chip's x, y, z (mm/s²).
    pub acc_mm_s2: [Vec<f64>; 3],
}

/// True when `path` is a CSV whose header is Klipper's raw accelerometer header
/// (`#time,accel_x,accel_y,accel_z`); false when it is anything else or cannot be read.
pub fn is_raw_file(path: &Path) -> bool {
    layout(path).is_ok_and(|l| {
        let names: Vec<&str> = l.names.iter().map(String::as_str).collect();
        is_klipper_header(&names)
    })
}

/// Reads Klipper's raw accelerometer file at `path` as written (no mending, no unit change).
///
/// Errors (file named): unreadable; not Klipper's raw header (the header found is named); a
/// cell that is not a finite number (row named); fewer than 2 rows; time not increasing
/// overall (last stamp ≤ first).
pub fn read_raw(path: &Path) -> Result<RawAccel> {
    let l = layout(path)?;
    let names: Vec<&str> = l.names.iter().map(String::as_str).collect();
    if !is_klipper_header(&names) {
        bail!(
            "{}: not Klipper's raw accelerometer CSV: the header is `{}`, expected `#{}`",
            path.display(),
            names.join(","),
            HEADER.join(",")
        );
    }
    let wanted: Vec<Wanted<'_>> = (0..4)
        .map(|index| Wanted {
            index,
            name: HEADER[index],
            scale: 1.0,
            required: true,
        })
        .collect();
    let mut cols = read_columns(path, &l, &wanted, &mut |_| {})?.into_iter();
    let time_s = cols.next().unwrap_or_default();
    let acc: Vec<Vec<f64>> = cols.collect();
    for (c, name) in std::iter::once(&time_s).chain(&acc).zip(HEADER) {
        if let Some(i) = c.iter().position(|v| !v.is_finite()) {
            bail!(
                "{}: data row {}, column {name}: not a finite number",
                path.display(),
                i + 1
            );
        }
    }
    let n = time_s.len();
    if n < 2 || time_s[n - 1] <= time_s[0] {
        bail!(
            "{}: {n} rows spanning no time: a raw accelerometer file needs increasing time stamps",
            path.display()
        );
    }
    let [x, y, z]: [Vec<f64>; 3] = acc.try_into().expect("three axes");
    Ok(RawAccel {
        time_s,
        acc_mm_s2: [x, y, z],
    })
}

/// The zeroth-order modified Bessel function of the first kind, I₀(x), by its power series
/// Σ ((x/2)^k / k!)² (terms added until they no longer change the sum; exact to rounding for
/// the |x| ≤ 6 the Kaiser window needs).
pub fn bessel_i0(x: f64) -> f64 {
    let q = 0.25 * x * x;
    let (mut term, mut sum, mut k) = (1.0f64, 1.0f64, 0.0f64);
    loop {
        k += 1.0;
        term *= q / (k * k);
        if term < sum * f64::EPSILON {
            return sum + term;
        }
        sum += term;
    }
}

/// The symmetric Kaiser window of `n` points and shape `beta`:
/// `w_i = I₀(β √(1 − (2i/(n−1) − 1)²)) / I₀(β)` (the definition of NumPy's `kaiser`, which
/// Klipper uses); `[1]` for n = 1, empty for n = 0.
pub fn kaiser(n: usize, beta: f64) -> Vec<f64> {
    if n <= 1 {
        return vec![1.0; n];
    }
    let d = bessel_i0(beta);
    (0..n)
        .map(|i| {
            let r = 2.0 * i as f64 / (n - 1) as f64 - 1.0;
            bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / d
        })
        .collect()
}

/// Klipper's sample rate (Hz) and Welch segment (samples) for `n` samples spanning `span_s`
/// seconds: `fs = n / span_s`, `M = 2^bitlen(⌊fs·0.5 − 1⌋)`. `None` when the record holds no
/// more than one segment (Klipper then has no spectrum) or the span is not positive.
pub fn klipper_segment(n: usize, span_s: f64) -> Option<(f64, usize)> {
    if !(span_s > 0.0) || n < 2 {
        return None;
    }
    let fs = n as f64 / span_s;
    let k = (fs * WINDOW_T_SEC - 1.0).max(0.0).floor() as u64;
    let m = 1usize << (64 - k.leading_zeros());
    (n > m).then_some((fs, m))
}

/// Welch's one-sided PSD of `x` (unit²/Hz) at sample rate `fs` (Hz) with segments of `nfft`
/// samples as Klipper takes them (module docs, step 3); `nfft/2 + 1` bins at `k fs / nfft`.
/// Empty when `x` is shorter than one segment or `nfft < 2`.
pub fn welch_psd(x: &[f64], fs: f64, nfft: usize) -> Vec<f64> {
    if nfft < 2 || x.len() < nfft {
        return vec![];
    }
    let w = kaiser(nfft, KAISER_BETA);
    let scale = 1.0 / (fs * w.iter().map(|v| v * v).sum::<f64>());
    let overlap = nfft / 2;
    let step = nfft - overlap;
    let segments = (x.len() - overlap) / step;
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
    let (mut buf, mut spec) = (fft.make_input_vec(), fft.make_output_vec());
    let mut acc = vec![0.0; nfft / 2 + 1];
    for s in 0..segments {
        let seg = &x[s * step..s * step + nfft];
        let mean = seg.iter().sum::<f64>() / nfft as f64;
        for ((b, v), wi) in buf.iter_mut().zip(seg).zip(&w) {
            *b = (v - mean) * wi;
        }
        fft.process(&mut buf, &mut spec).expect("buffer lengths");
        for (a, c) in acc.iter_mut().zip(&spec) {
            *a += c.norm_sqr();
        }
    }
    let last = acc.len() - 1;
    for (k, a) in acc.iter_mut().enumerate() {
        let one_sided = if k == 0 || k == last { 1.0 } else { 2.0 };
        *a *= one_sided * scale / segments as f64;
    }
    acc
}

/// Klipper's spectrum of a raw accelerometer record (module docs): per-axis Welch PSDs
/// ((mm/s²)²/Hz) and their sum on the bins `k fs / M` up to the Nyquist frequency, not
/// divided by frequency (`normalized` false).
///
/// Errors: the record holds no more than one Welch segment (M samples, about 0.5 s), as
/// Klipper refuses it.
pub fn raw_spectrum(raw: &RawAccel) -> Result<KlipperSpectrum> {
    let n = raw.time_s.len();
    let span = raw.time_s[n.max(1) - 1] - raw.time_s[0];
    let Some((fs, m)) = klipper_segment(n, span) else {
        bail!(
            "{n} samples over {span:.3} s: Klipper's PSD needs more than one segment of half a second of samples"
        );
    };
    let [px, py, pz] = [0, 1, 2].map(|a| welch_psd(&raw.acc_mm_s2[a], fs, m));
    let psd_sum = (0..px.len()).map(|k| px[k] + py[k] + pz[k]).collect();
    Ok(KlipperSpectrum {
        freq_hz: (0..px.len()).map(|k| k as f64 * fs / m as f64).collect(),
        psd_x: px,
        psd_y: py,
        psd_z: pz,
        psd_sum,
        normalized: false,
        shaper_columns: vec![],
    })
}

/// [`read_raw`] then [`raw_spectrum`]. Errors: those of both, with the file named.
pub fn read_raw_spectrum(path: &Path) -> Result<KlipperSpectrum> {
    let raw = read_raw(path)?;
    raw_spectrum(&raw).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// One line saying how the raw file's spectrum `s` (from [`raw_spectrum`]) was computed:
/// rate, segment, resolution.
pub fn spectrum_note(s: &KlipperSpectrum) -> String {
    let m = 2 * (s.freq_hz.len().max(2) - 1);
    let df = s.freq_hz.get(1).copied().unwrap_or(f64::NAN);
    format!(
        "PSD computed as Klipper v0.13.0 does from a raw file: {} Hz (N / span), Welch with a Kaiser β 6 window, {m}-sample segments (Δf {} Hz), 50 % overlap, mean detrend, density, summed over x, y, z",
        super::fmt_sig(df * m as f64, 5),
        super::fmt_sig(df, 4),
    )
}

/// The spectrum `s` in Klipper's file format (`save_calibration_data`): the header
/// `freq,psd_x,psd_y,psd_z,psd_xyz` plus one name per extra column, then one row per bin
/// below [`FILE_MAX_FREQ_HZ`]: `%.1f` Hz, `%.3e` PSDs, `%.3f` for each extra column (a
/// shaper's response per bin, as a `calibration_data_*.csv` holds). The PSDs are written as
/// they are in `s` (divide them by frequency first for a calibration file). Shapes: each
/// extra column has one value per bin of `s`.
pub fn format_spectrum_csv(s: &KlipperSpectrum, extra: &[(String, Vec<f64>)]) -> String {
    let mut out = String::from(SPECTRUM_HEADER);
    for (name, _) in extra {
        out += &format!(",{name}");
    }
    out.push('\n');
    for (i, &f) in s.freq_hz.iter().enumerate() {
        if f >= FILE_MAX_FREQ_HZ {
            break;
        }
        out += &format!(
            "{f:.1},{},{},{},{}",
            sci3(s.psd_x[i]),
            sci3(s.psd_y[i]),
            sci3(s.psd_z[i]),
            sci3(s.psd_sum[i])
        );
        for (_, v) in extra {
            out += &format!(",{:.3}", v[i]);
        }
        out.push('\n');
    }
    out
}

/// `v` as C's `%.3e` writes it (`1.234e+05`).
fn sci3(v: f64) -> String {
    let s = format!("{v:.3e}");
    match s.split_once('e') {
        Some((m, e)) => {
            let (sign, digits) = match e.strip_prefix('-') {
                Some(d) => ('-', d),
                None => ('+', e),
            };
            format!("{m}e{sign}{digits:0>2}")
        }
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kaiser_window_matches_its_definition_values() {
        // I0(6) = 67.23440697647797 (Abramowitz & Stegun table 9.8: e^6 · 0.16665 = 67.23)
        assert!((bessel_i0(6.0) - 67.234_406_976_477_97).abs() < 1e-10);
        let w = kaiser(5, 6.0);
        assert!((w[2] - 1.0).abs() < 1e-15 && (w[0] - 1.0 / bessel_i0(6.0)).abs() < 1e-15);
        assert!((w[1] - bessel_i0(6.0 * 0.75f64.sqrt()) / bessel_i0(6.0)).abs() < 1e-15);
        assert_eq!(w[0], w[4]);
    }

    #[test]
    fn segment_is_the_power_of_two_of_half_a_second() {
        assert_eq!(
            klipper_segment(10_000, 10_000.0 / 3200.0),
            Some((3200.0, 2048))
        );
        assert_eq!(klipper_segment(10_000, 10_000.0 / 1600.0).unwrap().1, 1024);
        assert_eq!(klipper_segment(2048, 0.64), None);
    }

    #[test]
    fn welch_psd_integrates_to_the_variance_and_peaks_at_a_sine() {
        let fs = 3200.0;
        let x: Vec<f64> = (0..32_000)
            .map(|i| 100.0 * (2.0 * std::f64::consts::PI * 50.0 * i as f64 / fs).sin() + 7.0)
            .collect();
        let p = welch_psd(&x, fs, 2048);
        let df = fs / 2048.0;
        let k = (0..p.len()).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
        assert!((k as f64 * df - 50.0).abs() <= df);
        // Parseval with the density scaling: Σ P Δf ≈ variance (5000) to the window's leakage
        let total: f64 = p.iter().sum::<f64>() * df;
        assert!((total / 5000.0 - 1.0).abs() < 0.01, "{total}");
    }

    #[test]
    fn writes_klippers_number_format() {
        assert_eq!(sci3(12344.0), "1.234e+04");
        assert_eq!(sci3(0.000_123_4), "1.234e-04");
        assert_eq!(sci3(0.0), "0.000e+00");
    }
}
