//! Where a base that has stopped its move stops *exciting* the tip: the start of the ring-down
//! judged by what the mode sees of the base's motion, not by the base's position alone.
//!
//! **The criterion** (stated once; [`quiet_start`]). A mode of angular frequency ω sees the
//! base through its acceleration only (ÿ + 2ζωẏ + ω²y = −ẍ for the tip deflection y). Writing
//! u = ẏ + iωy, the undamped mode obeys d(u e^{−iωt})/dt = −ẍ e^{−iωt}, so a base increment
//! Δx at time t changes the complex amplitude u/ω by Δx·e^{−iωt} (a step of Δx rings with
//! amplitude Δx), and the base's motion between t₀ and s changes the mode's amplitude by
//! exactly |Σ_{t₀<tⱼ≤s} Δxⱼ e^{−iωtⱼ}| (damping only lessens the older increments' share).
//! The **excitation** after t₀ is E(t₀) = max over s of that sum. It is small for the motions
//! that do not excite the mode: a constant velocity (the phasors turn a full circle every
//! period: |Σ| ≤ 2v/ω whatever the duration), a creep far slower than the mode
//! (quasi-static), a sensor's white noise or staircase quantum dithering about a value
//! (increments that cancel); it is the full step for a slip. While the base accelerates the
//! deflection also holds the quasi-static part −ẍ/ω²: Q(t₀), its largest value after t₀ from
//! the base's mean acceleration over a period, is added to E. The ring-down starts at the
//! first t₀ after the base's move where E(t₀) + Q(t₀) is smaller than the decay the tip
//! deflection shows after t₀, A(t₀) − A_end (amplitudes √2 × RMS over one period at t₀ and
//! at the end): then the base can account for less than the whole of the decay being
//! measured, and the free decay's damping is determined. The bound is carried into the
//! mode's 1-σ ([`widen_for_excitation`]): E changes ln A by at most E/A_end and the phase by
//! at most E/A_end rad over the ring-down's n = f·T cycles, so Δζ ≤ (E/A_end)/(2πn) and
//! Δf ≤ (E/A_end)/(2πT), each added in quadrature as a uniform error's σ (bound/√3).
//!
//! Without this, a trolley creeping 3 mm in 0.06 mm encoder steps after a 0.82 m move (a
//! real gantry crane, docs/ident.md, "Real recordings of other machines") counted as motion
//! until 1 s before the end and the free swing was lost.

use super::spectrum::{amplitude_spectrum, peaks};
use super::ModeEstimate;
use crate::recording::{fmt_sig, F_MIN_HZ};
use serde::Serialize;

/// The ring-down's start by the base's excitation of the tip's dominant mode ([`quiet_start`]).
#[derive(Clone, Debug, Serialize)]
pub struct QuietStart {
    /// First sample of the ring-down.
    pub from: usize,
    /// The tip deflection's dominant frequency (Hz) after the base's move.
    pub freq_hz: f64,
    /// E + Q: the largest amplitude (m) the base's motion after `from` can put into or take
    /// from an undamped mode at `freq_hz`, plus the largest quasi-static deflection it forces.
    pub excitation_m: f64,
    /// The tip deflection's amplitude (m, √2 × RMS over one period) at `from`.
    pub amplitude_start_m: f64,
    /// The same over the recording's last period (m).
    pub amplitude_end_m: f64,
    /// The ring-down's length (s).
    pub length_s: f64,
    /// The base's net travel after `from` (m).
    pub travel_m: f64,
}

impl QuietStart {
    /// The reason line: the excitation against the decay; `t0_s` is the ring-down's start
    /// (s from the recording's first sample).
    pub fn describe(&self, t0_s: f64) -> String {
        format!(
            "after its move the base still travels {} mm, but from {} s into the recording its motion can change the tip's {} Hz mode by at most {} mm (E + Q: max |Σ Δx e^(-iωt)|, the base's increments as the mode sees them, plus its quasi-static deflection), less than the decay the tip shows from there ({} -> {} mm): free decay of the tip deflection for {} s, its 1-σ widened by that bound",
            fmt_sig(1e3 * self.travel_m.abs(), 3),
            fmt_sig(t0_s, 4),
            fmt_sig(self.freq_hz, 4),
            fmt_sig(1e3 * self.excitation_m, 3),
            fmt_sig(1e3 * self.amplitude_start_m, 3),
            fmt_sig(1e3 * self.amplitude_end_m, 3),
            fmt_sig(self.length_s, 3)
        )
    }
}

/// Number of directions of the support function that bounds |S(s) − S(t₀)| (the farthest
/// point of a set of phasors from one of them): 32 directions underestimate the distance by at
/// most 1/cos(π/32) − 1 = 0.5 %.
const DIRECTIONS: usize = 32;

/// The ring-down's start of a recording at `rate_hz` whose base `base` (m) moved and stopped,
/// from the tip deflection `defl` (m, same samples): the module's criterion. `move_end` is
/// the first sample after the base's last excursion beyond 1 % of its range `range_m` from its
/// final value `final_m` (the locator of the search, not the decision); the tip's dominant
/// frequency is the strongest spectral peak of the deflection from there.
///
/// `None` when fewer than 3 periods of that frequency follow the move, no peak is found, or no
/// sample satisfies the criterion.
pub fn quiet_start(
    base: &[f64],
    defl: &[f64],
    rate_hz: f64,
    final_m: f64,
    range_m: f64,
) -> Option<QuietStart> {
    let n = base.len().min(defl.len());
    let move_end = base[..n]
        .iter()
        .rposition(|v| (v - final_m).abs() > 0.01 * range_m)
        .map_or(0, |k| k + 1);
    let tail = &defl[move_end..n];
    if tail.len() < 64 {
        return None;
    }
    let (f, mag) = amplitude_spectrum(tail, rate_hz);
    let freq_hz = peaks(&f, &mag, F_MIN_HZ, 0.45 * rate_hz).first()?.0;
    let period = (rate_hz / freq_hz).round() as usize;
    if period < 2 || tail.len() < 3 * period {
        return None;
    }
    let excitation = excitation_after(&base[move_end..n], freq_hz / rate_hz);
    let quasi_static = quasi_static_after(&base[..n], period / 2, move_end);
    let amp = period_amplitudes(tail, period);
    let a_end = amp[amp.len() - 1];
    let last = tail.len() - 3 * period;
    let bound = |k: usize| excitation[k] + quasi_static[k];
    let k = (0..=last).find(|&k| bound(k) < amp[k] - a_end)?;
    let from = move_end + k;
    Some(QuietStart {
        from,
        freq_hz,
        excitation_m: bound(k),
        amplitude_start_m: amp[k],
        amplitude_end_m: a_end,
        length_s: (n - from) as f64 / rate_hz,
        travel_m: base[n - 1] - base[from],
    })
}

/// E(k) for every sample k of `b`: max over s ≥ k of |Σ_{k<j≤s} (b_j − b_{j−1}) e^{−i2πνj}|,
/// ν in cycles per sample; by the support function of the partial sums in [`DIRECTIONS`]
/// directions, scanned backwards (O(n · directions)).
fn excitation_after(b: &[f64], nu: f64) -> Vec<f64> {
    let n = b.len();
    let w = 2.0 * std::f64::consts::PI * nu;
    let mut s = vec![(0.0f64, 0.0f64); n];
    for j in 1..n {
        let d = b[j] - b[j - 1];
        let ph = w * j as f64;
        s[j] = (s[j - 1].0 + d * ph.cos(), s[j - 1].1 - d * ph.sin());
    }
    let dirs: Vec<(f64, f64)> = (0..DIRECTIONS)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / DIRECTIONS as f64;
            (a.cos(), a.sin())
        })
        .collect();
    let mut support = vec![f64::NEG_INFINITY; DIRECTIONS];
    let mut out = vec![0.0; n];
    for k in (0..n).rev() {
        let mut e = 0.0f64;
        for (h, d) in support.iter_mut().zip(&dirs) {
            let p = s[k].0 * d.0 + s[k].1 * d.1;
            *h = h.max(p);
            e = e.max(*h - p);
        }
        out[k] = e;
    }
    out
}

/// Q(k) for the samples k ≥ `from` of `b`: the largest quasi-static deflection −ā/ω² the
/// base's mean acceleration over a period ā = (b[j+h] − 2b[j] + b[j−h])/h² (h = `half`
/// samples, half a period, so ω²h² = π²) forces at any j ≥ k: max |Δ²ₕb|/π². A staircase's
/// quantum q gives at most 2q/π².
fn quasi_static_after(b: &[f64], half: usize, from: usize) -> Vec<f64> {
    let n = b.len();
    let h = half.max(1);
    let pi2 = std::f64::consts::PI * std::f64::consts::PI;
    let mut out = vec![0.0; n - from];
    let mut m = 0.0f64;
    for j in (from..n).rev() {
        if j >= h && j + h < n {
            m = m.max((b[j + h] - 2.0 * b[j] + b[j - h]).abs() / pi2);
        }
        out[j - from] = m;
    }
    out
}

/// √2 × RMS (about the mean of `y`) over the `period` samples from each k (the last period
/// for the samples closer than a period to the end).
fn period_amplitudes(y: &[f64], period: usize) -> Vec<f64> {
    let n = y.len();
    let mean = y.iter().sum::<f64>() / n as f64;
    let mut c1 = vec![0.0; n + 1];
    let mut c2 = vec![0.0; n + 1];
    for (i, v) in y.iter().enumerate() {
        let d = v - mean;
        c1[i + 1] = c1[i] + d;
        c2[i + 1] = c2[i] + d * d;
    }
    (0..n)
        .map(|k| {
            let a = k.min(n - period);
            let m = (c1[a + period] - c1[a]) / period as f64;
            let var = (c2[a + period] - c2[a]) / period as f64 - m * m;
            (2.0 * var.max(0.0)).sqrt()
        })
        .collect()
}

/// Widens the 1-σ of the mode of `modes` nearest `q.freq_hz` (within 10 %) by the bound of the
/// base's excitation (module doc): Δζ = (E/A_end)/(2π f T), Δf = (E/A_end)/(2π T), each /√3,
/// in quadrature.
pub fn widen_for_excitation(modes: &mut [ModeEstimate], q: &QuietStart) {
    let Some(m) = modes
        .iter_mut()
        .filter(|m| (m.freq_hz / q.freq_hz - 1.0).abs() < 0.1)
        .min_by(|a, b| {
            (a.freq_hz - q.freq_hz)
                .abs()
                .total_cmp(&(b.freq_hz - q.freq_hz).abs())
        })
    else {
        return;
    };
    let rel = q.excitation_m / q.amplitude_end_m.max(f64::MIN_POSITIVE);
    let two_pi_t = 2.0 * std::f64::consts::PI * q.length_s;
    let df = rel / two_pi_t / 3f64.sqrt();
    let dz = rel / (two_pi_t * m.freq_hz) / 3f64.sqrt();
    m.freq_hz_std = m.freq_hz_std.hypot(df);
    m.zeta_std = m.zeta_std.hypot(dz);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_excites_its_size_a_constant_velocity_and_a_dither_next_to_nothing() {
        let nu = 0.8 / 30.0;
        let mut step = vec![0.0; 300];
        step[150..].iter_mut().for_each(|v| *v = 0.002);
        assert!((excitation_after(&step, nu)[0] - 0.002).abs() < 1e-5);
        assert!(excitation_after(&step, nu)[151] < 1e-12);
        // 3 mm at constant velocity over 10 s: |Σ| ≤ 2v/ω
        let ramp: Vec<f64> = (0..300).map(|k| 0.003 * k as f64 / 300.0).collect();
        let v = 0.003 / 10.0;
        let bound = 2.0 * v / (2.0 * std::f64::consts::PI * 0.8);
        assert!(excitation_after(&ramp, nu)[0] <= bound * 1.05, "{bound}");
        // a quantum dithering back and forth
        let dither: Vec<f64> = (0..300).map(|k| 5.6e-5 * ((k / 7) % 2) as f64).collect();
        assert!(excitation_after(&dither, nu)[0] < 2.0 * 5.6e-5);
    }
}
