//! The working rate of a diagnosis: recordings sampled faster than their content needs are
//! low-pass filtered without delay and decimated before anything is fitted.
//!
//! Why: every model evaluation costs in proportion to samples × in-band modes, and a 1000 Hz
//! recording of a beam whose motion stands above the sensor noise only up to a few tens of Hz
//! carries the same information at 500 Hz; the extra samples and modes only add noise, run
//! time and parameters the data cannot determine (damping ratios of modes nobody excited).
//!
//! The rule: the lowest rate that adds no model-form error a candidate effect could feed on.
//! 1. **Spectra**: per recording, the channels the model is compared with — following error
//!    `base_pos_m − base_cmd_m`, tip deflection `tip_pos_m − drive`, `force_n` — as Welch
//!    power spectra (Hann, 50 % overlap, ≈ 0.5 Hz bins, at least 15 segments). The noise floor
//!    is the [`FLOOR_QUANTILE`] quantile of the bins (above its last excited mode a beam
//!    recording is mostly noise; a low quantile stays robust when content fills much of the
//!    band and errs towards keeping bandwidth: coloured noise counts as content); a bin is
//!    content when it stands [`CONTENT_SNR`] above the floor. A channel without noise (exact
//!    simulator output) or too short to tell (< 512 samples) keeps its recording's rate.
//! 2. **Error a working rate r_w adds**, in units of the noise power the working band keeps:
//!    (a) the content beyond the band edge 0.45 r_w, which the filter removes (for `force_n`
//!    the lower of its own and that of the force less its least-squares fit by a rigid
//!    carriage following the command, [`force_beyond_rigid_body`]: the broadband spectrum of
//!    acceleration and friction steps is what the model computes from the command, filtered
//!    by the same zero-phase filter, so it needs no bandwidth), plus (b) the extra
//!    interpolation error of the content inside it. The model takes its inputs as piecewise
//!    linear between samples (exact integration of the beam for such a base, second
//!    difference for the motor force), a triangle kernel whose gain is sinc²(f/r)
//!    ([`interpolation_error`]: 7 % low at 0.15 r). Decimated inputs (`base_cmd_m`, the
//!    measured base that drives the beam) are therefore [emphasised](emphasis_taps) by a
//!    13-tap FIR ≈ 1/sinc², maximally flat at DC ([`emphasised_error`] < 1e-8 to 0.1 r, 1e-3
//!    to 0.25 r), the recorded outputs are not; the command and drive as recorded stay the
//!    base positions (a model without a servo loop, the absolute tip, the physics-free
//!    correction). At the recording's own rate this emphasis is not applied: tried in session 9, a
//!    boosted command let a lightly damped position loop take a loose tip sensor's resonance
//!    on tip-only 50 Hz recordings (docs/diagnose.md); there the recordings choose between the
//!    piecewise-linear reading and a milder three-tap one ([`super::model::DriveReading`]). (b) is what the emphasis leaves at r_w beyond the
//!    recording's own interpolation error. Measured without the emphasis: a 1000 Hz sensor-delay case (tip
//!    content to 27 Hz) decimated to 200 Hz got a spurious 60 Hz `mount_resonance` (ζ 0.06, a
//!    resonant boost that undoes the droop) worth 10 % of the noise power, as (b) predicted;
//!    with it, none.
//! 3. **Working rate**: per recording at rate r, the largest integer factor q (samples stay on
//!    the recording's own clock; never above its rate) with r/q ≥ [`MIN_WORKING_RATE_HZ`] whose
//!    added error, times the samples at r/q, is at most [`MAX_ADDED_NEG2LL`] (an added
//!    Δ(−2 ln L) no extra parameter could earn). The recordings share the highest of these
//!    rates. The floor of 400 Hz keeps what the spectra cannot show: the catalogue's
//!    non-smooth effects (backlash take-up, friction reversals) happen between samples and the
//!    model places them to a sample, so their timing error grows with the interval (measured:
//!    a 1000 Hz backlash case decimated to 200 Hz got a spurious `servo_lag`, at 500 Hz not);
//!    the servo loop's and the mount's frequencies are searched up to 0.4 × the rate (160 Hz
//!    and more), and a sensor latency of 1 ms stays half a sample (fitted continuously, by
//!    interpolation). So recordings at 1000 Hz are analysed at 500 Hz at most, those below
//!    800 Hz as recorded.
//! 4. **Filter**: a Kaiser-windowed sinc (β 7.86, stop-band ≥ 80 dB, pass-band ripple ≤ 1e-4)
//!    with its −6 dB point at the new Nyquist rate, pass band to 0.45 × the working rate
//!    (the band edge), stop band from 0.55 ×; 50 q + 1 taps centred on the kept sample, so its
//!    phase is exactly zero (no delay: a delay would look like the catalogue's
//!    `sensor_delay`). It is evaluated at the kept samples only (≈ 51 multiply-adds per input
//!    sample); the ends are held at their first/last values.
//!    Kaiser, "Nonrecursive digital filter design using the I0-sinh window function", 1974.

use super::model::prepared::Prepared;
use crate::recording::windowed_sinc;

/// Lowest working rate (Hz): see the module header, step 2.
pub const MIN_WORKING_RATE_HZ: f64 = 400.0;
/// Largest model-form error a working rate may add to a recording, as Δ(−2 ln L) over its
/// samples at that rate (≈ samples × error power / noise power): 2, what one extra parameter
/// must earn under AIC, so no candidate effect can feed on it.
pub const MAX_ADDED_NEG2LL: f64 = 2.0;
/// A spectral bin is content when its power exceeds this multiple of the noise floor (6 dB):
/// with ≥ 15 Welch segments a noise-only bin exceeds it with probability < 1e-6.
pub const CONTENT_SNR: f64 = 4.0;
/// Content power a working band may leave out, as a fraction of the noise power it keeps:
/// 0.1 raises the rms residual by at most √1.1 − 1 ≈ 5 % of the noise.
pub const LOST_POWER: f64 = 0.1;
/// Quantile of a channel's spectral bins taken as its noise floor.
pub const FLOOR_QUANTILE: f64 = 0.1;
/// Fraction of the working rate up to which the decimation filter passes (the band edge).
pub const PASS_EDGE: f64 = 0.45;
/// Kaiser β for 80 dB stop-band attenuation (0.1102 (A − 8.7)).
const KAISER_BETA: f64 = 7.857;

/// The working rate of one diagnosis and how it was chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct WorkingRate {
    /// Lowest working rate over the recordings (Hz).
    pub rate_hz: f64,
    /// Content edge (Hz): highest frequency standing above the noise in any recording
    /// ([`Spectrum::content_edge_hz`]).
    pub content_edge_hz: f64,
    /// Lowest rate (Hz) every recording accepts (module header, step 3).
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

/// The recorded channels of `d` that decide its working rate, as pairs of alternatives (the
/// lower added error counts): following error, tip deflection, force — the force also less
/// its rigid-carriage fit ([`force_beyond_rigid_body`]), module header, step 2.
fn channels(d: &Prepared) -> Vec<(Vec<f64>, Option<Vec<f64>>)> {
    let mut v = Vec::new();
    if let Some(b) = &d.base_m {
        v.push((b.iter().zip(&d.cmd_m).map(|(a, c)| a - c).collect(), None));
    }
    if let Some(t) = &d.tip_m {
        let drive = d.drive_m.as_ref().unwrap_or(&d.cmd_m);
        v.push((t.iter().zip(drive).map(|(a, c)| a - c).collect(), None));
    }
    if let Some(f) = &d.force_n {
        v.push((f.clone(), force_beyond_rigid_body(f, &d.cmd_m, d.dt)));
    }
    v
}

/// `force` less its least-squares fit by the commanded rigid carriage: a constant, the
/// commanded acceleration (second difference / dt², as the model's piecewise-linear path),
/// velocity and smoothed sign of velocity (friction, as [`super::model`]'s carriage forces).
/// What is left is what the model cannot get from the command as a rigid body. `None` when
/// the fit is singular.
pub fn force_beyond_rigid_body(force: &[f64], cmd: &[f64], dt: f64) -> Option<Vec<f64>> {
    let n = force.len().min(cmd.len());
    if n < 3 {
        return None;
    }
    let regressors = |k: usize| -> nalgebra::Vector4<f64> {
        let vb = if k == 0 {
            0.0
        } else {
            (cmd[k] - cmd[k - 1]) / dt
        };
        let va = if k + 1 < n {
            (cmd[k + 1] - cmd[k]) / dt
        } else {
            0.0
        };
        let v = 0.5 * (va + vb);
        nalgebra::Vector4::new(1.0, (va - vb) / dt, v, (v / 1e-3).tanh())
    };
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut atb = nalgebra::Vector4::<f64>::zeros();
    for k in 0..n {
        let a = regressors(k);
        ata += a * a.transpose();
        atb += a * force[k];
    }
    // scaled to a unit diagonal for conditioning
    let s = nalgebra::Vector4::from_fn(|i, _| 1.0 / ata[(i, i)].max(1e-300).sqrt());
    let scaled = ata.component_mul(&(s * s.transpose()));
    let c = (scaled.try_inverse()? * atb.component_mul(&s)).component_mul(&s);
    Some((0..n).map(|k| force[k] - regressors(k).dot(&c)).collect())
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

/// A channel's power spectrum with its noise floor (module header, step 1).
#[derive(Clone, Debug)]
pub struct Spectrum {
    /// Welch power per bin (bin k at k × `bin_hz`).
    pub power: Vec<f64>,
    /// Noise floor (same units): the [`FLOOR_QUANTILE`] quantile of the bins above DC.
    pub floor: f64,
    /// Bin width (Hz).
    pub bin_hz: f64,
}

impl Spectrum {
    /// The spectrum of `x` sampled at `rate_hz`; `None` when too short to tell content from
    /// noise (fewer than 512 samples) or without noise (exact arithmetic): such a recording
    /// keeps its rate.
    pub fn of(x: &[f64], rate_hz: f64) -> Option<Spectrum> {
        let n = x.len();
        // ≈ 0.5 Hz bins, at least 15 half-overlapping segments, at least 64 samples
        let mut nseg = ((2.0 * rate_hz).ceil() as usize).next_power_of_two();
        while nseg > 64 && n < 8 * nseg {
            nseg /= 2;
        }
        if n < 8 * nseg {
            return None;
        }
        let power = welch_power(x, nseg);
        let mut sorted: Vec<f64> = power[1..].to_vec();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let floor = sorted[((sorted.len() - 1) as f64 * FLOOR_QUANTILE) as usize];
        let top = sorted.last().copied().unwrap_or(0.0);
        (top > 0.0 && floor > top * 1e-24).then_some(Spectrum {
            power,
            floor,
            bin_hz: rate_hz / nseg as f64,
        })
    }

    /// Content power of bin k: its power less the floor when it stands [`CONTENT_SNR`] above
    /// the floor, else 0.
    fn excess(&self, k: usize) -> f64 {
        let p = self.power[k];
        if p > CONTENT_SNR * self.floor {
            p - self.floor
        } else {
            0.0
        }
    }

    /// Highest frequency (Hz) with content: the lowest edge above which the content power is
    /// at most [`LOST_POWER`] × the noise power below it.
    pub fn content_edge_hz(&self) -> f64 {
        let n = self.power.len();
        let mut above = vec![0.0; n + 1];
        for k in (1..n).rev() {
            above[k] = above[k + 1] + self.excess(k);
        }
        let k = (1..n)
            .find(|&k| above[k + 1] <= LOST_POWER * self.floor * k as f64)
            .unwrap_or(n - 1);
        k as f64 * self.bin_hz
    }

    /// The model-form error a working rate `rate_w_hz` adds to a recording at `rate_hz`, in
    /// units of the noise power the working band keeps (module header, step 2): the content
    /// beyond the band edge, which the filter removes, plus the content's extra
    /// interpolation error [`interpolation_error`] at the coarser sample interval.
    pub fn added_error(&self, rate_hz: f64, rate_w_hz: f64) -> f64 {
        let (edge, nyquist) = (PASS_EDGE * rate_w_hz, 0.5 * rate_w_hz);
        let (mut err, mut kept) = (0.0, 0usize);
        let taps = emphasis_taps();
        for k in 1..self.power.len() {
            let f = k as f64 * self.bin_hz;
            kept += usize::from(f <= nyquist);
            let e = self.excess(k);
            err += if f > edge {
                e
            } else {
                e * (emphasised_error_of(&taps, f / rate_w_hz).powi(2)
                    - interpolation_error(f, rate_hz).powi(2))
                .max(0.0)
            };
        }
        err / (self.floor * kept.max(1) as f64)
    }
}

/// Relative amplitude error 1 − sinc²(f/r) at `f_hz` of a model sampled at `rate_hz` that
/// takes its input as piecewise linear between samples (the beam's exact zero-order-hold
/// integration, the force's second difference, the sensor latency's interpolation): the
/// triangle (linear-interpolation) kernel's transfer function (Oppenheim & Schafer,
/// *Discrete-Time Signal Processing*, 3rd ed., §4.6.3).
pub fn interpolation_error(f_hz: f64, rate_hz: f64) -> f64 {
    let x = std::f64::consts::PI * f_hz / rate_hz;
    if x.abs() < 1e-12 {
        return 0.0;
    }
    1.0 - (x.sin() / x).powi(2)
}

/// Half-length M of the [`emphasis_taps`] (2M + 1 taps).
const EMPHASIS_HALF: usize = 6;

/// A symmetric FIR (2M + 1 taps at the working rate) whose response E approximates
/// 1 / sinc²(f/r), maximally flat at DC (its Taylor series in f matches to order 2M):
/// applied to the model's input channels (command, measured base) after decimation, the
/// model's piecewise-linear treatment of them (gain sinc², [`interpolation_error`]) is
/// undone, so the coarser working rate adds (almost) no interpolation error
/// ([`emphasised_error`]).
pub fn emphasis_taps() -> Vec<f64> {
    emphasis_taps_of(EMPHASIS_HALF)
}

/// [`emphasis_taps`] with half-length `m`.
pub fn emphasis_taps_of(m: usize) -> Vec<f64> {
    // Taylor coefficients in x² (x = πf/r) of sin x / x, squared, then inverted
    let mut sinc = vec![0.0; m + 1];
    let mut fact = 1.0;
    for (k, v) in sinc.iter_mut().enumerate() {
        if k > 0 {
            fact *= (2 * k) as f64 * (2 * k + 1) as f64;
        }
        *v = if k % 2 == 0 { 1.0 } else { -1.0 } / fact;
    }
    let sq: Vec<f64> = (0..=m)
        .map(|k| (0..=k).map(|i| sinc[i] * sinc[k - i]).sum())
        .collect();
    let mut inv = vec![0.0; m + 1];
    for k in 0..=m {
        let acc: f64 = (1..=k).map(|i| sq[i] * inv[k - i]).sum();
        inv[k] = (f64::from(u8::from(k == 0)) - acc) / sq[0];
    }
    // E(x) = c0 + 2 Σ c_j cos(2jx): the x^(2k) coefficient is (−1)^k/(2k)! Σ_j w_j c_j (2j)^(2k)
    // (w_0 = 1, w_j = 2); matched to inv[k] for k = 0..=M
    let mut kfact = 1.0;
    let mut a = nalgebra::DMatrix::<f64>::zeros(m + 1, m + 1);
    let mut b = nalgebra::DVector::<f64>::zeros(m + 1);
    for k in 0..=m {
        if k > 0 {
            kfact *= (2 * k - 1) as f64 * (2 * k) as f64;
        }
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        for j in 0..=m {
            let w = if j == 0 { 1.0 } else { 2.0 };
            a[(k, j)] = sign * w * ((2 * j) as f64).powi(2 * k as i32) / kfact;
        }
        b[k] = inv[k];
    }
    let c = a
        .lu()
        .solve(&b)
        .unwrap_or_else(|| nalgebra::DVector::from_fn(m + 1, |j, _| f64::from(u8::from(j == 0))));
    (0..=2 * m).map(|i| c[i.abs_diff(m)]).collect()
}

/// Relative error |E(f) sinc²(f) − 1| at `f` (cycles per working-rate sample) left after the
/// emphasis E ([`emphasis_taps`]) and the piecewise-linear input: below 1e-8 up to 0.1, 1e-3 up to 0.25,
/// 1e-2 up to 0.3.
pub fn emphasised_error(f: f64) -> f64 {
    emphasised_error_of(&emphasis_taps(), f)
}

/// [`emphasised_error`] with the taps given.
fn emphasised_error_of(taps: &[f64], f: f64) -> f64 {
    let m = EMPHASIS_HALF as f64;
    let e: f64 = taps
        .iter()
        .enumerate()
        .map(|(i, c)| c * (2.0 * std::f64::consts::PI * f * (i as f64 - m)).cos())
        .sum();
    (e * (1.0 - interpolation_error(f, 1.0)) - 1.0).abs()
}

/// `x` (at the working rate) through the [`emphasis_taps`], ends held.
pub fn emphasise(x: &[f64]) -> Vec<f64> {
    emphasise_of(x, EMPHASIS_HALF)
}

/// [`emphasise`] with half-length `half`.
pub fn emphasise_of(x: &[f64], half: usize) -> Vec<f64> {
    let h = emphasis_taps_of(half);
    let n = x.len();
    (0..n)
        .map(|c| {
            h.iter()
                .enumerate()
                .map(|(i, hv)| hv * x[(c + i).saturating_sub(half).min(n - 1)])
                .sum()
        })
        .collect()
}

/// Highest frequency (Hz) at which `x`, sampled at `rate_hz`, stands above its own noise
/// ([`Spectrum::content_edge_hz`]); its Nyquist frequency when too short to tell or without
/// noise.
pub fn content_edge_hz(x: &[f64], rate_hz: f64) -> f64 {
    Spectrum::of(x, rate_hz).map_or(0.5 * rate_hz, |s| s.content_edge_hz())
}

/// Lowest working rate (Hz) recording `d` accepts (module header, step 3) and its content edge.
fn lowest_rate(d: &Prepared) -> (f64, f64) {
    let r = 1.0 / d.dt;
    let n = d.cmd_m.len() as f64;
    let mut spectra: Vec<Vec<Spectrum>> = Vec::new();
    for (x, alt) in channels(d) {
        let Some(own) = Spectrum::of(&x, r) else {
            return (r, 0.5 * r);
        };
        spectra.push(
            std::iter::once(own)
                .chain(alt.and_then(|a| Spectrum::of(&a, r)))
                .collect(),
        );
    }
    let edge = spectra
        .iter()
        .map(|alts| {
            alts.iter()
                .map(|s| s.content_edge_hz())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    let q_max = (r / MIN_WORKING_RATE_HZ * (1.0 + 1e-9)).floor().max(1.0) as usize;
    let q = (2..=q_max)
        .rev()
        .find(|&q| {
            spectra.iter().all(|alts| {
                alts.iter()
                    .map(|s| s.added_error(r, r / q as f64))
                    .fold(f64::INFINITY, f64::min)
                    * n
                    / q as f64
                    <= MAX_ADDED_NEG2LL
            })
        })
        .unwrap_or(1);
    (r / q as f64, edge)
}

/// The working rate for `fit_data` and `validate` (module header).
pub fn choose(fit_data: &[Prepared], validate: &Prepared) -> WorkingRate {
    let all: Vec<&Prepared> = fit_data.iter().chain(std::iter::once(validate)).collect();
    let lowest: Vec<(f64, f64)> = all.iter().map(|d| lowest_rate(d)).collect();
    let needed_rate_hz = lowest.iter().map(|l| l.0).fold(0.0, f64::max);
    // rates to a µHz (the time column's rounding)
    let round = |r: f64| (r * 1e6).round() / 1e6;
    let content_edge_hz = lowest.iter().map(|l| l.1).fold(0.0, f64::max);
    let recordings: Vec<(String, f64, usize)> = all
        .iter()
        .map(|d| {
            let r = 1.0 / d.dt;
            let q = ((r / needed_rate_hz) * (1.0 + 1e-9)).floor().max(1.0) as usize;
            (d.name.clone(), round(r), q)
        })
        .collect();
    let rate_hz = recordings
        .iter()
        .map(|(_, r, q)| round(r / *q as f64))
        .fold(f64::INFINITY, f64::min);
    WorkingRate {
        rate_hz,
        content_edge_hz,
        needed_rate_hz,
        recordings,
    }
}

/// Zeroth-order modified Bessel function of the first kind (power series; |x| ≲ 20).
pub(crate) fn bessel_i0(x: f64) -> f64 {
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
    windowed_sinc(half, fc, |i| {
        let r = (i as f64 - half as f64) / half as f64;
        bessel_i0(KAISER_BETA * (1.0 - r * r).max(0.0).sqrt()) / bessel_i0(KAISER_BETA)
    })
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

/// `d` at its working rate: every channel [decimated](decimate_zero_phase) by `q` (`q` ≤ 1:
/// `d` as recorded, nothing emphasised), the time base kept at every `q`-th sample; the model's
/// inputs (`cmd_m`, `drive_m`) then [emphasised](emphasise) so its piecewise-linear treatment
/// of them costs no more accuracy than at the recording's own rate, the command and drive as
/// sampled kept in `cmd_identity_m` and `drive_identity_m` (the base positions: a model
/// without a servo loop, the absolute tip, the physics-free correction).
pub fn decimate_prepared(d: &Prepared, q: usize) -> Prepared {
    if q <= 1 {
        return d.clone();
    }
    let dec = |c: &Option<Vec<f64>>| c.as_ref().map(|v| decimate_zero_phase(v, q));
    let cmd = decimate_zero_phase(&d.cmd_m, q);
    Prepared {
        name: d.name.clone(),
        dt: d.dt * q as f64,
        time_s: d.time_s.iter().step_by(q).copied().collect(),
        cmd_m: emphasise(&cmd),
        cmd_identity_m: Some(cmd),
        base_m: dec(&d.base_m),
        drive_m: dec(&d.drive_m).map(|v| emphasise(&v)),
        drive_identity_m: dec(&d.drive_m),
        tip_m: dec(&d.tip_m),
        force_n: dec(&d.force_n),
        rails: d
            .rails
            .clone()
            .map(|r| r.decimated(q, RAIL_MARGIN, d.cmd_m.len().div_ceil(q))),
        gaps: d
            .gaps
            .clone()
            .map(|r| r.decimated(q, RAIL_MARGIN, d.cmd_m.len().div_ceil(q))),
        free_start: d.free_start,
    }
}

/// Kept samples on each side of a decimated run of rail samples also left out: the filter's
/// main lobe (±1 kept sample at its −6 dB point) and a sample more of its first side lobes.
const RAIL_MARGIN: usize = 2;

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
        "recordings analysed at a working rate of {:.1} Hz ({}; zero-phase FIR low-pass, Kaiser, 80 dB, no delay, then decimation): the lowest rate ≥ {MIN_WORKING_RATE_HZ} Hz whose discarded content and interpolation error add Δ(−2lnL) ≤ {MAX_ADDED_NEG2LL} (content above the noise ends at {:.1} Hz); band edge {:.1} Hz",
        w.rate_hz,
        list.join(", "),
        w.content_edge_hz,
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
            cmd_identity_m: None,
            base_m: None,
            drive_m: None,
            drive_identity_m: None,
            tip_m: Some(tip),
            force_n: None,
            rails: Default::default(),
            gaps: Default::default(),
            free_start: false,
        }
    }

    #[test]
    fn working_rate_keeps_what_the_model_would_get_wrong_and_no_more() {
        // slow content (2 Hz) over noise at 1000 Hz: the floor (400 Hz) decides, q = 2
        let d = prepared(noisy(&[2.0], 1000.0, 40.0, 0.3, 1), 1000.0);
        let edge = content_edge_hz(d.tip_m.as_ref().unwrap(), 1000.0);
        assert!(edge > 1.9 && edge < 4.0, "content edge {edge}");
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!((w.recordings[0].2, w.rate_hz), (2, 500.0));
        assert!(words(&w).is_some());
        // content at 240 Hz: beyond the band edge of 500 Hz (225 Hz), inside 1000 Hz's
        let d = prepared(noisy(&[2.0, 240.0], 1000.0, 40.0, 0.3, 2), 1000.0);
        let s = Spectrum::of(d.tip_m.as_ref().unwrap(), 1000.0).unwrap();
        assert!(s.added_error(1000.0, 500.0) > 1.0);
        assert!(s.added_error(1000.0, 1000.0) < 1e-6);
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!(w.recordings[0].2, 1, "{w:?}");
        // a 2 kHz recording of slow content goes to 400 Hz (q = 5)
        let d = prepared(noisy(&[2.0], 2000.0, 20.0, 0.3, 5), 2000.0);
        assert_eq!(choose(std::slice::from_ref(&d), &d).recordings[0].2, 5);
        // without the emphasis the interpolation error at 0.3 of the rate would be 26 %
        assert!((interpolation_error(60.0, 200.0) - 0.26).abs() < 0.01);
        // a 100 Hz recording is never decimated (never above the recording's rate)
        let d = prepared(noisy(&[2.0], 100.0, 60.0, 0.3, 3), 100.0);
        let w = choose(std::slice::from_ref(&d), &d);
        assert_eq!((w.recordings[0].2, w.rate_hz), (1, 100.0));
        assert!(words(&w).is_none());
        // no noise at all: nothing can be judged, nothing is decimated
        let d = prepared(noisy(&[2.0], 1000.0, 40.0, 0.0, 4), 1000.0);
        assert_eq!(choose(std::slice::from_ref(&d), &d).recordings[0].2, 1);
    }

    #[test]
    fn emphasis_undoes_the_piecewise_linear_input_across_the_band() {
        for i in 0..=30 {
            let f = 0.01 * i as f64;
            let bound = if f <= 0.1 {
                1e-8
            } else if f <= 0.25 {
                1e-3
            } else {
                1e-2
            };
            assert!(emphasised_error(f) < bound, "{f}: {}", emphasised_error(f));
        }
        // without it the error at 0.15 of the rate is 7 %
        assert!((interpolation_error(0.15, 1.0) - 0.072).abs() < 0.002);
        let taps = emphasis_taps();
        assert!((taps.iter().sum::<f64>() - 1.0).abs() < 1e-6);
    }
}
