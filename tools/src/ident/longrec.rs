//! Long recordings at the cost of their information, not of their length (issue 70, item 6).
//!
//! Specification:
//! - **Decimation to the band** ([`decimation_factor`]): an input/output recording is
//!   decimated (anti-aliased FIR, [`crate::recording::decimate_fir`]) so that its new Nyquist
//!   frequency stays ≥ [`NYQUIST_OVER_BAND`] × the top of the band of interest (the asked band,
//!   or where the base acceleration has energy), keeping at least [`MIN_DECIMATED_SAMPLES`]
//!   samples. Input and output pass the same linear filter, so their ratio, the FRF, is kept
//!   in the band (the filter's pass band reaches 0.8 × the new Nyquist frequency).
//!   Free-decay paths decimate only recordings longer than [`MAX_FULL_RATE_SAMPLES`], to
//!   `opts.decay.f_max_hz`.
//! - **Welch segments from resolution** ([`segment_for_resolution`]): the segment length is
//!   set by the frequency resolution the modes need, not by the record's length. A first pass
//!   resolves the band into [`EXPLORE_LINES`] lines ([`explore_resolution_hz`]); the lowest
//!   physical mode it finds then sets the final resolution: [`LINES_PER_HALF_POWER`] lines in
//!   its half-power band 2ζf ([`half_power_resolution_hz`]). A record shorter than twice that
//!   segment is one segment (the transient FRF of a sweep from rest to rest).

use super::frf::{welch, Detrend, WelchOptions, Window};
use super::pipeline::IdentOptions;
use super::ModeEstimate;
use crate::recording::{fmt_sig, Recording};

/// FRF lines across the lowest mode's half-power band 2ζf. Bendat & Piersol's resolution bias
/// of a resonance peak of a windowed spectral estimate is ≈ −(B_e / B_r)² / 3 (B_e the
/// window's effective bandwidth, 1.36 lines for Hamming; B_r the half-power band): 16 lines
/// make it 0.24 %, a tenth of the 2.5 % damping accuracy the identification is held to.
pub const LINES_PER_HALF_POWER: f64 = 16.0;

/// Lines across the band in the first (exploring) pass of a long record: the cost of the
/// estimators grows with the lines in the band; 4096 lines put a mode at 1/100 of the band's
/// top with ζ = 0.5 % into a half-power band of 4 lines, enough for LSCF to place its pole.
pub const EXPLORE_LINES: f64 = 4096.0;

/// After decimation the new Nyquist frequency is at least this multiple of the band's top:
/// the band then sits within the lower quarter, far inside the FIR's pass band (0.8 ×
/// Nyquist), and the second difference that makes the base acceleration stays within 5 % of
/// the true derivative there (sinc² (π/8) = 0.95).
pub const NYQUIST_OVER_BAND: f64 = 4.0;

/// Samples kept at least after decimation (the input band's own Welch estimate uses segments
/// of this length).
pub const MIN_DECIMATED_SAMPLES: usize = 1 << 16;

/// Free-decay recordings longer than this are decimated when their content allows.
pub const MAX_FULL_RATE_SAMPLES: usize = 1 << 20;

/// Decimation factor for `rec` (uniform, Hz from its median step) before the path `frf_path`
/// (`true`: input/output FRF; `false`: a free decay).
///
/// FRF path: `floor(fs / (2 × 4 × f_top))` with f_top the top of `band_hz` or, without it,
/// of the band where the base acceleration (from the command when recorded) has energy
/// ([`input_band_top_hz`]); 1 when there is no base channel. Free decay: only above
/// [`MAX_FULL_RATE_SAMPLES`] samples, to `decay_f_max_hz`. Never fewer than
/// [`MIN_DECIMATED_SAMPLES`] samples are left.
pub fn decimation_factor(
    rec: &Recording,
    frf_path: bool,
    band_hz: Option<(f64, f64)>,
    decay_f_max_hz: f64,
) -> usize {
    let n = rec.len();
    if n < 2 * MIN_DECIMATED_SAMPLES {
        return 1;
    }
    let rate = rec.sample_rate_hz();
    let f_keep = if frf_path {
        let top = match (band_hz, input_band_top_hz(rec)) {
            (Some(b), Some(f)) => b.1.max(f),
            (Some(b), None) => b.1,
            (None, Some(f)) => f,
            (None, None) => return 1,
        };
        NYQUIST_OVER_BAND * top
    } else {
        if n <= MAX_FULL_RATE_SAMPLES {
            return 1;
        }
        decay_f_max_hz
    };
    let q = (0.5 * rate / f_keep).floor() as usize;
    q.min(n / MIN_DECIMATED_SAMPLES).max(1)
}

/// Top of the band (Hz) where the base acceleration's Welch spectrum (Hamming segments of
/// [`MIN_DECIMATED_SAMPLES`] samples, or the whole record when shorter) is within 30 dB of its
/// maximum; from `base_cmd_m` when recorded, else `base_pos_m`. `None` without a base channel
/// or when the base does not move.
pub fn input_band_top_hz(rec: &Recording) -> Option<f64> {
    let x = rec.base_cmd_m.as_deref().or(rec.base_pos_m.as_deref())?;
    let rate = rec.sample_rate_hz();
    let a: Vec<f64> = x
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]) * rate * rate)
        .collect();
    let wo = WelchOptions {
        nperseg: Some(MIN_DECIMATED_SAMPLES.min(a.len())),
        overlap: 0.5,
        window: Window::Hamming,
        detrend: Detrend::Mean,
        pad: 1,
    };
    let f = welch(&a, &a, rate, &wo).ok()?;
    let top = f.sxx.iter().skip(1).cloned().fold(0.0, f64::max);
    let k = f.sxx.iter().rposition(|v| *v >= 1e-3 * top)?;
    Some(f.freq_hz[k].max(f.df_hz()))
}

/// Frequency resolution (Hz) that puts [`LINES_PER_HALF_POWER`] lines into the half-power
/// band 2ζf of a mode at `freq_hz` with damping ratio `zeta`.
pub fn half_power_resolution_hz(freq_hz: f64, zeta: f64) -> f64 {
    2.0 * zeta * freq_hz / LINES_PER_HALF_POWER
}

/// Frequency resolution (Hz) of the exploring pass: [`EXPLORE_LINES`] lines up to the band's
/// top `band_top_hz`.
pub fn explore_resolution_hz(band_top_hz: f64) -> f64 {
    band_top_hz / EXPLORE_LINES
}

/// Welch segment length (samples) for a resolution of `df_hz` at `rate_hz`: the power of two
/// at or above `rate_hz / df_hz`, at most `max_len` (the record, or a memory bound), at least
/// 16. A non-positive or non-finite `df_hz` asks for `max_len`.
pub fn segment_for_resolution(rate_hz: f64, df_hz: f64, max_len: usize) -> usize {
    if !(df_hz > 0.0 && df_hz.is_finite() && rate_hz > 0.0) {
        return max_len;
    }
    let want = (rate_hz / df_hz).ceil();
    if want >= max_len as f64 {
        return max_len;
    }
    (want as usize).next_power_of_two().clamp(16, max_len)
}

/// `fo` with Hamming-windowed Welch segments of `l` samples (50 % overlap); with `fo`'s own
/// window over the whole record when `l` exceeds half of the `n` samples and `n` ≤
/// `max_segment` (else Hamming segments of `max_segment`, with a warning).
pub fn segmented(
    fo: &IdentOptions,
    l: usize,
    n: usize,
    max_segment: usize,
    warnings: &mut Vec<String>,
) -> IdentOptions {
    let mut o = fo.clone();
    let l = if 2 * l > n { n } else { l };
    if l == n && n <= max_segment {
        return o;
    }
    let l = l.min(max_segment);
    if l == max_segment {
        warnings.push(format!(
            "long recording ({n} samples): FRF averaged over Hamming-windowed segments of {l} samples (50 % overlap)"
        ));
    }
    o.welch.nperseg = Some(l);
    o.welch.window = Window::Hamming;
    o.welch.overlap = 0.5;
    o
}

/// What set the FRF's resolution: the lowest mode's half-power band in lines.
pub fn resolution_note(lowest: Option<&ModeEstimate>, nperseg: usize, rate: f64) -> String {
    let df = rate / nperseg as f64;
    match lowest {
        Some(m) => format!(
            "FRF resolution from the lowest mode ({} Hz, ζ {}): Welch segments of {nperseg} samples, Δf = {} Hz, {} lines in its half-power band ({} wanted)",
            fmt_sig(m.freq_hz, 5),
            fmt_sig(m.zeta, 3),
            fmt_sig(df, 3),
            fmt_sig(2.0 * m.zeta * m.freq_hz / df, 3),
            LINES_PER_HALF_POWER
        ),
        None => format!(
            "no physical mode at the band's exploring resolution: FRF of segments of {nperseg} samples, Δf = {} Hz",
            fmt_sig(df, 3)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_length_follows_the_resolution_the_mode_needs() {
        let rate = 100.0;
        // f = 1.1 Hz, ζ = 0.0074: half-power band 0.01628 Hz, 16 lines → Δf ≤ 1.02 mHz.
        let df = half_power_resolution_hz(1.1, 0.0074);
        assert!((df - 2.0 * 0.0074 * 1.1 / 16.0).abs() < 1e-15);
        let n = segment_for_resolution(rate, df, 1 << 24);
        assert!(n.is_power_of_two());
        let lines = 2.0 * 0.0074 * 1.1 / (rate / n as f64);
        assert!(
            (16.0..32.0).contains(&lines),
            "{lines} lines in the half-power band"
        );
        // Half the damping → twice the segment; ten times the frequency → a tenth (power of 2).
        assert_eq!(
            segment_for_resolution(rate, half_power_resolution_hz(1.1, 0.0037), 1 << 24),
            2 * n
        );
        let n10 = segment_for_resolution(rate, half_power_resolution_hz(11.0, 0.0074), 1 << 24);
        assert!(n10 <= n / 8 && n10 >= n / 16, "{n10} vs {n}");
        // Not from the record's length: a longer record does not change it; a shorter caps it.
        assert_eq!(segment_for_resolution(rate, df, 1 << 26), n);
        assert_eq!(segment_for_resolution(rate, df, 5000), 5000);
        assert_eq!(segment_for_resolution(rate, f64::NAN, 5000), 5000);
        // The exploring pass: the band's top into 4096 lines.
        let n1 = segment_for_resolution(rate, explore_resolution_hz(10.0), 1 << 24);
        assert!(rate / n1 as f64 <= 10.0 / 4096.0 && rate / n1 as f64 > 5.0 / 4096.0);
    }

    #[test]
    fn decimation_keeps_four_times_the_band_and_enough_samples() {
        let rate = 1000.0;
        let n = 400_000;
        // A base oscillating at 2–5 Hz: the acceleration has energy to ~5 Hz.
        let t: Vec<f64> = (0..n).map(|k| k as f64 / rate).collect();
        let b: Vec<f64> = t
            .iter()
            .map(|t| 0.01 * (2.0 * std::f64::consts::PI * (2.0 + 0.0075 * t) * t).sin())
            .collect();
        let rec = Recording {
            time_s: t,
            base_cmd_m: Some(b.clone()),
            base_pos_m: Some(b.clone()),
            tip_pos_m: Some(b),
            ..Default::default()
        };
        let top = input_band_top_hz(&rec).unwrap();
        assert!(top > 4.0 && top < 12.0, "{top}");
        let q = decimation_factor(&rec, true, None, 500.0);
        assert_eq!(
            q,
            ((0.5 * rate / (4.0 * top)).floor() as usize).min(n >> 16)
        );
        assert!(0.5 * rate / q as f64 >= 4.0 * top && n / q >= MIN_DECIMATED_SAMPLES);
        // An asked band above the input's energy widens what is kept.
        assert!(decimation_factor(&rec, true, Some((0.1, 40.0)), 500.0) <= 3);
        // A free decay of this length is kept at full rate.
        assert_eq!(decimation_factor(&rec, false, None, 500.0), 1);
    }
}
