//! The working rate of a diagnosis: recordings sampled faster than their content needs are
//! low-pass filtered without delay and decimated before anything is fitted.
//!
//! Why: every model evaluation costs in proportion to samples × in-band modes, and a 1000 Hz
//! recording of a beam whose motion stands above the sensor noise only up to a few tens of Hz
//! carries the same information at 200 Hz; the extra samples and modes only add noise, run
//! time and parameters the data cannot determine (damping ratios of modes nobody excited).
//!
//! The rule (per recording, the content measured over all recordings together):
//! 1. **Content edge** f_c: up to where the recorded channels — following error
//!    `base_pos_m − base_cmd_m`, tip deflection `tip_pos_m − drive`, `force_n` — carry signal
//!    above their own noise. Per channel, a Welch power spectrum (Hann, 50 % overlap, ≈ 0.5 Hz
//!    bins, at least 15 segments); its noise floor is the [`FLOOR_QUANTILE`] quantile of the
//!    bins (a beam recording's bins are mostly noise above its last excited mode; a low
//!    quantile stays robust when content fills much of the band, and errs towards keeping
//!    bandwidth: coloured noise counts as content); a bin is content when it stands
//!    [`CONTENT_SNR`] above the floor. f_c is the lowest frequency above which the content
//!    power (less the floor) is at most [`LOST_POWER`] × the noise power below it: what the
//!    decimation discards then raises the rms residual by at most 5 % of the noise. This keeps
//!    a lightly damped mode or a mount resonance that stands clearly above the noise (its
//!    power is many noise bins' worth) and lets go of the thin tail of broadband content
//!    (friction and acceleration steps in `force_n`, which the model reproduces from the
//!    command filtered the same way). f_c is the largest over channels and recordings; a
//!    channel without noise (exact simulator output) or too short to tell (< 512 samples) has
//!    f_c at its Nyquist frequency (nothing is decimated).
//! 2. **Needed rate** `r_need = max(MIN_WORKING_RATE_HZ, 2.5 f_c)`: the diagnosis band edge
//!    ([`super::sim::band_edge_hz`], 0.45 × rate) sits [`CONTENT_MARGIN`] (12.5 %) above the
//!    content. The floor of 200 Hz keeps what a fit needs beyond the visible content: the servo
//!    loop's and the mount's frequencies are searched up to 0.4 × the rate (so at least to
//!    80 Hz), friction steps and cogging harmonics keep their shape, and a sensor latency of
//!    1 ms is still a fifth of a sample (it is fitted continuously, by interpolation).
//! 3. **Decimation factor** `q = ⌊r / r_need⌋ ≥ 1` for a recording at rate r (an integer, so
//!    samples stay on the recording's own clock; never above the recording's rate). Recordings
//!    at 100–399 Hz are therefore analysed as recorded.
//! 4. **Filter**: a Kaiser-windowed sinc (β 7.86, stop-band ≥ 80 dB, pass-band ripple ≤ 1e-4)
//!    with its −6 dB point at the new Nyquist rate, pass band to 0.45 × the working rate
//!    (the band edge), stop band from 0.55 ×; 50 q + 1 taps centred on the kept sample, so its
//!    phase is exactly zero (no delay: a delay would look like the catalogue's
//!    `sensor_delay`). It is evaluated at the kept samples only (≈ 51 multiply-adds per input
//!    sample); the ends are held at their first/last values.
//!    Kaiser, "Nonrecursive digital filter design using the I0-sinh window function", 1974.

use super::sim::Prepared;

/// Lowest working rate (Hz): see the module header, step 2.
pub const MIN_WORKING_RATE_HZ: f64 = 200.0;
/// The band edge (0.45 × working rate) is at least this multiple of the content edge: the
/// working rate is at least 2.5 × the content edge.
pub const CONTENT_MARGIN: f64 = 1.125;
/// A spectral bin is content when its power exceeds this multiple of the noise floor (6 dB):
/// with ≥ 15 Welch segments a noise-only bin exceeds it with probability < 1e-6.
pub const CONTENT_SNR: f64 = 4.0;
/// Content power a working band may leave out, as a fraction of the noise power it keeps:
/// 0.1 raises the rms residual by at most √1.1 − 1 ≈ 5 % of the noise.
pub const LOST_POWER: f64 = 0.1;
/// Quantile of a channel's spectral bins taken as its noise floor.
pub const FLOOR_QUANTILE: f64 = 0.1;
/// Fraction of the working rate up to which the decimation filter passes (the band edge).
const PASS_EDGE: f64 = 0.45;
/// Kaiser β for 80 dB stop-band attenuation (0.1102 (A − 8.7)).
const KAISER_BETA: f64 = 7.857;

/// The working rate of one diagnosis and how it was chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct WorkingRate {
    /// Lowest working rate over the recordings (Hz).
    pub rate_hz: f64,
    /// Content edge f_c (Hz): highest frequency standing above the noise in any recording.
    pub content_edge_hz: f64,
    /// Rate the content needs (Hz), `max(MIN_WORKING_RATE_HZ, CONTENT_MARGIN f_c / 0.45)`
    /// (= 2.5 f_c).
    pub needed_rate_hz: f64,
    /// Per recording (fit recordings, then the validation recording): name, recorded rate (Hz),
    /// decimation factor.
    pub recordings: Vec<(String, f64, usize)>,
}

impl WorkingRate {
    /// Whether any recording is decimated.
    pub fn decimates(&self) -> bool {
        self.recordings.iter().any(|r| r.2 > 1)
    }
}

/// The channels whose spectra decide the content edge of `d`: following error, tip
/// deflection, force (those recorded).
fn content_channels(d: &Prepared) -> Vec<Vec<f64>> {
    let mut v = Vec::new();
    if let Some(b) = &d.base_m {
        v.push(b.iter().zip(&d.cmd_m).map(|(a, c)| a - c).collect());
    }
    if let Some(t) = &d.tip_m {
        let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
        v.push(t.iter().zip(drive).map(|(a, c)| a - c).collect());
    }
    if let Some(f) = &d.force_n {
        v.push(f.clone());
    }
    v
}

/// Welch power spectrum of `x` (Hann window, 50 % overlap, segment mean removed) with
/// segments of `nseg` samples: one value per bin 0..=nseg/2 (arbitrary common scale).
pub fn welch_power(x: &[f64], nseg: usize) -> Vec<f64> {
    use realfft::RealFftPlanner;
    let nseg = nseg.max(4).min(x.len().max(4));
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nseg);
    let w: Vec<f64> = (0..nseg)
        .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / nseg as f64).cos())
        .collect();
    let mut acc = vec![0.0; nseg / 2 + 1];
    let mut buf = vec![0.0; nseg];
    let mut spec = fft.make_output_vec();
    let mut count = 0usize;
    let mut start = 0;
    while start + nseg <= x.len() {
        let seg = &x[start..start + nseg];
        let m = seg.iter().sum::<f64>() / nseg as f64;
        for k in 0..nseg {
            buf[k] = (seg[k] - m) * w[k];
        }
        if fft.process(&mut buf, &mut spec).is_ok() {
            for (a, s) in acc.iter_mut().zip(&spec) {
                *a += s.norm_sqr();
            }
            count += 1;
        }
        start += nseg / 2;
    }
    acc.iter_mut().for_each(|a| *a /= count.max(1) as f64);
    acc
}

/// Highest frequency (Hz) at which `x`, sampled at `rate_hz`, stands above its own noise
/// (module header, step 1); 0 for a channel without content; its Nyquist frequency when it is
/// too short to tell (fewer than 512 samples) or has no noise floor at all.
pub fn content_edge_hz(x: &[f64], rate_hz: f64) -> f64 {
    let n = x.len();
    // ≈ 0.5 Hz bins, at least 15 half-overlapping segments, at least 64 samples
    let mut nseg = ((2.0 * rate_hz).ceil() as usize).next_power_of_two();
    while nseg > 64 && n < 8 * nseg {
        nseg /= 2;
    }
    if n < 8 * nseg {
        // too short to tell content from noise: keep the whole band
        return 0.5 * rate_hz;
    }
    let p = welch_power(x, nseg);
    // bins 1.. (DC is the mean): the floor is a low quantile of them
    let mut sorted: Vec<f64> = p[1..].to_vec();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let floor = sorted[((sorted.len() - 1) as f64 * FLOOR_QUANTILE) as usize];
    let top = sorted.last().copied().unwrap_or(0.0);
    if !(top > 0.0) {
        return 0.0;
    }
    if !(floor > top * 1e-24) {
        // no noise at all (exact arithmetic): everything up to Nyquist is content
        return 0.5 * rate_hz;
    }
    // content power above each bin (bins standing CONTENT_SNR above the floor, less the floor)
    let excess: Vec<f64> = p
        .iter()
        .map(|&v| {
            if v > CONTENT_SNR * floor {
                v - floor
            } else {
                0.0
            }
        })
        .collect();
    let mut above = vec![0.0; p.len() + 1];
    for k in (1..p.len()).rev() {
        above[k] = above[k + 1] + excess[k];
    }
    // the lowest edge whose discarded content is at most LOST_POWER × the noise kept below it
    let k = (1..p.len())
        .find(|&k| above[k + 1] <= LOST_POWER * floor * k as f64)
        .unwrap_or(p.len() - 1);
    k as f64 * rate_hz / nseg as f64
}

/// The working rate for `fit_data` and `validate` (module header).
pub fn choose(fit_data: &[Prepared], validate: &Prepared) -> WorkingRate {
    let all: Vec<&Prepared> = fit_data.iter().chain(std::iter::once(validate)).collect();
    let content_edge_hz = all
        .iter()
        .flat_map(|d| {
            content_channels(d)
                .into_iter()
                .map(move |x| content_edge_hz(&x, 1.0 / d.dt))
        })
        .fold(0.0, f64::max);
    let needed_rate_hz = MIN_WORKING_RATE_HZ.max(CONTENT_MARGIN * content_edge_hz / PASS_EDGE);
    let recordings: Vec<(String, f64, usize)> = all
        .iter()
        .map(|d| {
            let r = 1.0 / d.dt;
            let q = ((r / needed_rate_hz) * (1.0 + 1e-9)).floor().max(1.0) as usize;
            (d.name.clone(), r, q)
        })
        .collect();
    let rate_hz = recordings
        .iter()
        .map(|(_, r, q)| r / *q as f64)
        .fold(f64::INFINITY, f64::min);
    WorkingRate {
        rate_hz,
        content_edge_hz,
        needed_rate_hz,
        recordings,
    }
}

/// Zeroth-order modified Bessel function of the first kind (power series; |x| ≲ 20).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term) = (1.0, 1.0);
    let y = 0.25 * x * x;
    for k in 1..60 {
        term *= y / (k * k) as f64;
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum
}

/// The zero-phase decimation filter for factor `q` (module header, step 4): `50 q + 1`
/// Kaiser-windowed sinc taps, unit DC gain.
pub fn decimation_taps(q: usize) -> Vec<f64> {
    let half = 25 * q;
    let fc = 0.5 / q as f64; // cycles per input sample: the new Nyquist rate
    let mut h: Vec<f64> = (0..=2 * half)
        .map(|i| {
            let k = i as f64 - half as f64;
            let sinc = if k == 0.0 {
                2.0 * fc
            } else {
                (2.0 * std::f64::consts::PI * fc * k).sin() / (std::f64::consts::PI * k)
            };
            let r = k / half as f64;
            sinc * bessel_i0(KAISER_BETA * (1.0 - r * r).max(0.0).sqrt()) / bessel_i0(KAISER_BETA)
        })
        .collect();
    let s: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= s);
    h
}

/// `x` low-pass filtered by [`decimation_taps`] and kept at every `q`-th sample (from the
/// first), without delay; `q` ≤ 1 returns a copy.
pub fn decimate_zero_phase(x: &[f64], q: usize) -> Vec<f64> {
    if q <= 1 || x.is_empty() {
        return x.to_vec();
    }
    let h = decimation_taps(q);
    let half = (h.len() - 1) / 2;
    let n = x.len();
    (0..n)
        .step_by(q)
        .map(|c| {
            if c >= half && c + half < n {
                h.iter()
                    .zip(&x[c - half..=c + half])
                    .map(|(a, b)| a * b)
                    .sum()
            } else {
                // the ends: the signal held at its first/last value
                h.iter()
                    .enumerate()
                    .map(|(i, hv)| hv * x[(c + i).saturating_sub(half).min(n - 1)])
                    .sum()
            }
        })
        .collect()
}

/// `d` at its working rate: every channel [decimated](decimate_zero_phase) by `q`, the time
/// base kept at every `q`-th sample.
pub fn decimate_prepared(d: &Prepared, q: usize) -> Prepared {
    if q <= 1 {
        return d.clone();
    }
    let dec = |c: &Option<Vec<f64>>| c.as_ref().map(|v| decimate_zero_phase(v, q));
    Prepared {
        name: d.name.clone(),
        dt: d.dt * q as f64,
        time_s: d.time_s.iter().step_by(q).copied().collect(),
        cmd_m: decimate_zero_phase(&d.cmd_m, q),
        base_m: dec(&d.base_m),
        drive_m: dec(&d.drive_m),
        tip_m: dec(&d.tip_m),
        force_n: dec(&d.force_n),
    }
}

/// The recordings at the working rate `w` ([`choose`]): fit recordings, validation recording.
pub fn to_working_rate(
    w: &WorkingRate,
    fit_data: &[Prepared],
    validate: &Prepared,
) -> (Vec<Prepared>, Prepared) {
    let q = |i: usize| w.recordings.get(i).map_or(1, |r| r.2);
    let fit = fit_data
        .iter()
        .enumerate()
        .map(|(i, d)| decimate_prepared(d, q(i)))
        .collect();
    (fit, decimate_prepared(validate, q(fit_data.len())))
}

/// The working rate in words (an assumption of the diagnosis), `None` when nothing is
/// decimated.
pub fn words(w: &WorkingRate) -> Option<String> {
    if !w.decimates() {
        return None;
    }
    let list: Vec<String> = w
        .recordings
        .iter()
        .map(|(name, r, q)| format!("{name} {r:.0} Hz ÷ {q}"))
        .collect();
    Some(format!(
        "recordings analysed at a working rate of {:.1} Hz ({}): content above the noise ends at {:.1} Hz, the rate it needs is max(200 Hz, 2.5 × {:.1} Hz) = {:.1} Hz; zero-phase FIR low-pass (Kaiser, 80 dB, no delay) before decimation; band edge {:.1} Hz",
        w.rate_hz,
        list.join(", "),
        w.content_edge_hz,
        w.content_edge_hz,
        w.needed_rate_hz,
        PASS_EDGE * w.rate_hz
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(f: f64, rate: f64, n: usize, phase: f64) -> Vec<f64> {
        (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * f * k as f64 / rate + phase).sin())
            .collect()
    }

    /// Amplitude and delay (in output samples) of a tone `f` in `y` sampled at `rate`
    /// (least squares on sin/cos, the ends left out).
    fn amp_delay(y: &[f64], f: f64, rate: f64) -> (f64, f64) {
        let w = 2.0 * std::f64::consts::PI * f / rate;
        let (mut s, mut c, mut n) = (0.0, 0.0, 0.0);
        for (k, v) in y.iter().enumerate().skip(100).take(y.len() - 200) {
            s += v * (w * k as f64).sin();
            c += v * (w * k as f64).cos();
            n += 1.0;
        }
        let (a, b) = (2.0 * s / n, 2.0 * c / n);
        // y ≈ a sin + b cos = A sin(wk + φ): delay = −φ / w samples
        ((a * a + b * b).sqrt(), -b.atan2(a) / w)
    }

    #[test]
    fn decimation_passes_the_band_without_delay_and_removes_what_would_alias() {
        let (rate, q, n) = (1000.0, 5, 40_000);
        let out_rate = rate / q as f64;
        // 0.43 × the working rate (inside the band edge 0.45 ×): unit gain, no delay
        for f in [3.0, 27.0, 0.43 * out_rate] {
            let y = decimate_zero_phase(&tone(f, rate, n, 0.3), q);
            assert_eq!(y.len(), n / q);
            let (a, d) = amp_delay(&y, f, out_rate);
            let d = d + 0.3 / (2.0 * std::f64::consts::PI * f / out_rate);
            assert!((a - 1.0).abs() < 1e-3, "{f} Hz: gain {a}");
            assert!(d.abs() < 1e-3, "{f} Hz: delay {d} samples");
        }
        // 0.57 × the working rate would alias to 0.43 ×: attenuated by ≥ 60 dB
        let f = 0.57 * out_rate;
        let y = decimate_zero_phase(&tone(f, rate, n, 0.0), q);
        let rms = (y[100..y.len() - 100].iter().map(|v| v * v).sum::<f64>()
            / (y.len() - 200) as f64)
            .sqrt();
        assert!(rms < 1e-3, "{f} Hz leaks {rms}");
        // q = 1 is the identity
        assert_eq!(
            decimate_zero_phase(&[1.0, 2.0, 3.0], 1),
            vec![1.0, 2.0, 3.0]
        );
    }

    fn noisy(tones: &[f64], rate: f64, secs: f64, noise: f64, seed: u64) -> Vec<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let n = (rate * secs) as usize;
        (0..n)
            .map(|k| {
                let t = k as f64 / rate;
                tones
                    .iter()
                    .map(|f| (2.0 * std::f64::consts::PI * f * t).sin())
                    .sum::<f64>()
                    + noise * (rng.gen::<f64>() - 0.5)
            })
            .collect()
    }

    fn prepared(tip: Vec<f64>, rate: f64) -> Prepared {
        let n = tip.len();
        Prepared {
            name: "r".into(),
            dt: 1.0 / rate,
            time_s: (0..n).map(|k| k as f64 / rate).collect(),
            cmd_m: vec![0.0; n],
            base_m: None,
            drive_m: None,
            tip_m: Some(tip),
            force_n: None,
        }
    }

    #[test]
    fn working_rate_follows_the_content_above_the_noise_with_a_floor() {
        // content at 2 and 30 Hz over noise at 1000 Hz: the floor (200 Hz) decides, q = 5
        let d = prepared(noisy(&[2.0, 30.0], 1000.0, 40.0, 0.1, 1), 1000.0);
        let edge = content_edge_hz(d.tip_m.as_ref().unwrap(), 1000.0);
        assert!(edge > 29.0 && edge < 36.0, "content edge {edge}");
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!(w.recordings[0].2, 5);
        assert_eq!(w.rate_hz, 200.0);
        // content at 150 Hz needs 2.5 × 150 = 375 Hz: q = 2
        let d = prepared(noisy(&[2.0, 150.0], 1000.0, 40.0, 0.1, 2), 1000.0);
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!((w.recordings[0].2, w.rate_hz), (2, 500.0));
        // a 100 Hz recording is never decimated (never above the recording's rate)
        let d = prepared(noisy(&[2.0], 100.0, 60.0, 0.1, 3), 100.0);
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!((w.recordings[0].2, w.rate_hz), (1, 100.0));
        assert!(words(&w).is_none());
        // no noise at all: every frequency counts, nothing is decimated
        let d = prepared(noisy(&[2.0], 1000.0, 40.0, 0.0, 4), 1000.0);
        assert_eq!(choose(std::slice::from_ref(&d), &d).recordings[0].2, 1);
    }
}
