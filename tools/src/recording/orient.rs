//! Sensor directions, from the motion below the beam's first natural frequency.
//!
//! Every channel of the format lies along the carriage's one axis, positive the same way, and
//! `tip_pos_m` is in the lab frame. Well below the first natural frequency the beam moves with
//! its carriage as a rigid body, so the channels agree there whatever the physics:
//! - `base_pos_m` follows `base_cmd_m` (low-pass slope ≈ 1);
//! - `tip_pos_m` follows the base (slope ≈ 1);
//! - `force_n` accelerates carriage and beam, `F ≈ (m_c + m_beam) ÿ`, so it correlates
//!   positively with the base's acceleration once the friction is taken out (0.85–1.00 over
//!   the 16 independent cases' recordings with a force, cogging included).
//!
//! A sensor mounted or wired the other way round (an encoder counting down, a camera whose axis
//! points back, a drive whose current sign is the opposite) shows a slope near −1 (for the
//! force, a negative correlation); a camera riding on the carriage, which sees the beam's
//! deflection rather than its lab position, shows a tip slope near 0 (so does a sensor that does not see the beam). No model of the beam
//! produces either, and either hides every effect (a reversed tip alone makes the calibration
//! ask for 17.6 × the rig's Young's modulus). A reversed channel is negated, with a note naming
//! it. A tip that does not follow is only named in a note: a deflection's own sign is not
//! readable at low frequency (the quasi-static deflection is small and the first mode's ring
//! leaks through any short low-pass), so the user is asked rather than guessed for. A channel that fits none of these pictures
//! clearly (a weak or ambiguous slope) is left as recorded: the fit and its residuals will say.
//!
//! Low-pass: a centred moving average applied twice (a triangular window), `w` samples long;
//! slopes are least squares on the filtered, mean-removed channels.

use super::Recording;

/// A slope counts as "≈ 1" (or "≈ −1") within this much.
pub const SLOPE_TOLERANCE: f64 = 0.5;
/// The least |correlation| for a low-frequency slope to be read at all.
pub const MIN_CORRELATION: f64 = 0.5;
/// The least share of a channel's motion (rms of its low-passed part over its rms) from which
/// its low-frequency slope is read: a sweep starting near the first natural frequency has
/// almost none, and the little its low-pass lets through comes from above the resonance,
/// where the tip moves against the base (the independent cases' sweeps keep 4–10 %, their
/// moves 80–90 %; a triangular window leaks 0.3 % at 1.5 × the first natural frequency).
pub const MIN_SLOW_SHARE: f64 = 0.02;
/// A tip slope below this is named: the tip does not follow its carriage.
pub const DEFLECTION_SLOPE: f64 = 0.25;

/// `rec` with its sensors brought to the format's directions (see the module header); a note
/// names each change. `low_hz` is the low-pass corner for "well below the first natural
/// frequency" (a quarter of the rig's first clamped natural frequency is what the diagnosis
/// passes); `force_hz` the corner for the force–acceleration correlation (the band the beam's
/// modes occupy). Unchanged without a base channel or when the recording is shorter than
/// three low-pass windows; positions are left alone when the base hardly moves below `low_hz`
/// ([`MIN_SLOW_SHARE`]).
pub fn orient(mut rec: Recording, low_hz: f64, force_hz: f64) -> Recording {
    let fs = rec.sample_rate_hz();
    let n = rec.len();
    let w_low = window(fs, low_hz);
    if !(fs.is_finite() && fs > 0.0) || n < 3 * w_low {
        return rec;
    }
    if let (Some(cmd), Some(base)) = (rec.base_cmd_m.as_ref(), rec.base_pos_m.as_mut()) {
        let (s, r) = low_slope(cmd, base, w_low);
        if moves_slowly(cmd, w_low) && reversed(s, r) {
            base.iter_mut().for_each(|b| *b = -*b);
            rec.notes.push(reversed_note("base_pos_m", "base_cmd_m", s));
        }
    }
    let Some(base) = rec.base_pos_m.clone().or_else(|| rec.base_cmd_m.clone()) else {
        return rec;
    };
    let against = if rec.base_pos_m.is_some() {
        "base_pos_m"
    } else {
        "base_cmd_m"
    };
    let slow = moves_slowly(&base, w_low);
    if let (Some(tip), true) = (rec.tip_pos_m.as_mut(), slow) {
        let (s, r) = low_slope(&base, tip, w_low);
        if reversed(s, r) {
            tip.iter_mut().for_each(|t| *t = -*t);
            rec.notes.push(reversed_note("tip_pos_m", against, s));
        } else if s.abs() < DEFLECTION_SLOPE {
            rec.notes.push(format!(
                "tip_pos_m does not follow {against} below the beam's first natural frequency (low-frequency slope {s:+.2}; a lab-frame tip position follows its carriage there, slope 1): the deflection seen from the carriage (the format wants the lab-frame position, the base added), or a sensor that does not see the beam? Left as recorded"
            ));
        }
    }
    if let Some(force) = rec.force_n.as_mut() {
        let r = force_acceleration_correlation(&base, force, window(fs, force_hz), fs);
        if r < -MIN_CORRELATION {
            force.iter_mut().for_each(|f| *f = -*f);
            rec.notes.push(format!(
                "force_n opposes the acceleration of {against} (correlation {r:+.2}; a drive's force accelerates its carriage): read as the drive's force with the opposite sign convention, and negated"
            ));
        }
    }
    rec
}

/// Samples of the moving average whose two passes make a low-pass at `corner_hz` (at least 1).
fn window(fs: f64, corner_hz: f64) -> usize {
    let w = fs / corner_hz;
    if w.is_finite() && w >= 1.0 {
        w.round() as usize
    } else {
        1
    }
}

/// Whether at least [`MIN_SLOW_SHARE`] of `x`'s motion is below the low-pass corner.
fn moves_slowly(x: &[f64], w: usize) -> bool {
    let (all, _, _) = moments(x, x);
    let low = smooth(x, w);
    let (slow, _, _) = moments(&low, &low);
    (slow / all).sqrt() >= MIN_SLOW_SHARE
}

fn reversed(slope: f64, corr: f64) -> bool {
    (slope + 1.0).abs() < SLOPE_TOLERANCE && corr < -MIN_CORRELATION
}

fn reversed_note(channel: &str, against: &str, slope: f64) -> String {
    format!(
        "{channel} moves against {against} below the beam's first natural frequency (low-frequency slope {slope:+.2}; the format's channels share one direction): read as a sensor mounted the other way round, and negated"
    )
}

/// Least-squares slope of low-passed `y` on low-passed `x`, and their correlation (NaN when
/// `x` does not move).
fn low_slope(x: &[f64], y: &[f64], w: usize) -> (f64, f64) {
    let (x, y) = (smooth(x, w), smooth(y, w));
    let (sxx, syy, sxy) = moments(&x, &y);
    (sxy / sxx, sxy / (sxx * syy).sqrt())
}

/// The partial correlation of the low-passed force with the base's acceleration, friction
/// taken out: both are first cleared (least squares) of the friction's regressors, the smoothed
/// sign of the velocity (over 1 mm/s), the velocity and a constant. A Coulomb friction of 1.9 N
/// (independent case02) otherwise halves the plain correlation of a slow sweep (0.50 against
/// 0.85 with it taken out).
fn force_acceleration_correlation(base: &[f64], force: &[f64], w: usize, fs: f64) -> f64 {
    use nalgebra::{DMatrix, DVector};
    let base = smooth(base, w);
    let n = base.len();
    let acc = second_difference(&base, fs);
    let vel: Vec<f64> = (0..n)
        .map(|k| (base[(k + 1).min(n - 1)] - base[k.saturating_sub(1)]) * fs / 2.0)
        .collect();
    let friction = DMatrix::from_fn(n, 3, |k, j| match j {
        0 => (vel[k] / 1e-3).tanh(),
        1 => vel[k],
        _ => 1.0,
    });
    let svd = friction.clone().svd(true, true);
    let cleared = |y: Vec<f64>| -> Vec<f64> {
        let y = DVector::from_vec(y);
        match svd.solve(&y, 1e-12) {
            Ok(c) => (y - &friction * c).iter().copied().collect(),
            Err(_) => y.iter().copied().collect(),
        }
    };
    correlation(&cleared(acc), &cleared(smooth(force, w)))
}

fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let (sxx, syy, sxy) = moments(x, y);
    sxy / (sxx * syy).sqrt()
}

/// Centred second moments (Σ(x−x̄)², Σ(y−ȳ)², Σ(x−x̄)(y−ȳ)).
fn moments(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len().min(y.len()) as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    x.iter().zip(y).fold((0.0, 0.0, 0.0), |(a, b, c), (p, q)| {
        let (dp, dq) = (p - mx, q - my);
        (a + dp * dp, b + dq * dq, c + dp * dq)
    })
}

/// The centred moving average of `w` samples applied twice (shortened at the ends).
fn smooth(x: &[f64], w: usize) -> Vec<f64> {
    let pass = |x: &[f64]| -> Vec<f64> {
        let mut prefix = Vec::with_capacity(x.len() + 1);
        prefix.push(0.0);
        for v in x {
            prefix.push(prefix.last().unwrap() + v);
        }
        let h = w / 2;
        (0..x.len())
            .map(|i| {
                let (a, b) = (i.saturating_sub(h), (i + h + 1).min(x.len()));
                (prefix[b] - prefix[a]) / (b - a) as f64
            })
            .collect()
    };
    if w <= 1 {
        return x.to_vec();
    }
    pass(&pass(x))
}

/// Central second difference × fs² (one-sided at the ends: the neighbour repeated).
fn second_difference(x: &[f64], fs: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| (x[(i + 1).min(n - 1)] - 2.0 * x[i] + x[i.saturating_sub(1)]) * fs * fs)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 200 Hz, 20 s: a carriage making smooth back-and-forth moves of 0.1 m (period 2 s, peak
    /// acceleration 0.49 m/s²), a beam of first natural frequency 2 Hz (ζ 0.02) riding on it,
    /// the drive's force (m 3 kg) plus 0.5 N of friction, each channel with its own small noise.
    fn rig_recording() -> Recording {
        recording_of(|t| 0.05 * (1.0 - (std::f64::consts::PI * t).cos()))
    }

    /// [`rig_recording`]'s rig driven by the command `cmd(t)` (m).
    fn recording_of(cmd: impl Fn(f64) -> f64) -> Recording {
        let fs = 200.0;
        let n = 4000;
        let mut r = Recording::with_uniform_time(n, fs);
        let dt = 1.0 / fs;
        let cmd: Vec<f64> = (0..n).map(|k| cmd(k as f64 * dt)).collect();
        // the beam's first mode as a base-excited oscillator, semi-implicit Euler
        let (wn, z) = (2.0 * std::f64::consts::PI * 2.0, 0.02);
        let (mut q, mut qd) = (0.0, 0.0);
        let mut tip = Vec::with_capacity(n);
        let acc = second_difference(&cmd, fs);
        for k in 0..n {
            qd += dt * (-acc[k] - 2.0 * z * wn * qd - wn * wn * q);
            q += dt * qd;
            tip.push(cmd[k] + 1.4 * q);
        }
        let noise = |k: usize, s: f64, a: f64| a * (k as f64 * s).sin();
        r.base_pos_m = Some(
            cmd.iter()
                .enumerate()
                .map(|(k, c)| c + noise(k, 2.1, 1e-6))
                .collect(),
        );
        r.tip_pos_m = Some(
            tip.iter()
                .enumerate()
                .map(|(k, t)| t + noise(k, 1.3, 5e-5))
                .collect(),
        );
        let vel: Vec<f64> = (0..n)
            .map(|k| (cmd[(k + 1).min(n - 1)] - cmd[k.saturating_sub(1)]) * fs / 2.0)
            .collect();
        r.force_n = Some(
            (0..n)
                .map(|k| 3.0 * acc[k] + 0.5 * (vel[k] / 1e-3).tanh() + noise(k, 0.7, 0.05))
                .collect(),
        );
        r.base_cmd_m = Some(cmd);
        r
    }

    fn negate(x: &mut Option<Vec<f64>>) {
        x.as_mut().unwrap().iter_mut().for_each(|v| *v = -*v);
    }

    #[test]
    fn channels_that_share_one_direction_are_left_alone() {
        let r = rig_recording();
        assert_eq!(orient(r.clone(), 0.5, 20.0), r);
    }

    #[test]
    fn each_channel_mounted_the_other_way_round_is_negated_with_a_note() {
        let truth = rig_recording();
        let mut r = truth.clone();
        negate(&mut r.base_pos_m);
        negate(&mut r.tip_pos_m);
        negate(&mut r.force_n);
        let o = orient(r, 0.5, 20.0);
        assert!(o.base_pos_m == truth.base_pos_m, "{:?}", o.notes);
        assert!(o.tip_pos_m == truth.tip_pos_m, "{:?}", o.notes);
        assert!(o.force_n == truth.force_n, "{:?}", o.notes);
        for channel in ["base_pos_m", "tip_pos_m", "force_n"] {
            assert!(
                o.notes.iter().any(|n| n.starts_with(channel)),
                "{channel}: {:?}",
                o.notes
            );
        }
    }

    #[test]
    fn a_sweep_from_above_the_first_natural_frequency_is_left_alone() {
        // 3 → 8 Hz (the beam's first mode at 2 Hz) under a smooth envelope: above its
        // resonance the tip moves against the base, and almost nothing is below 0.5 Hz
        let r = recording_of(|t| {
            let f = 3.0 + 0.25 * t;
            let envelope = (std::f64::consts::PI * t / 20.0).sin().powi(2);
            2e-3 * envelope * (2.0 * std::f64::consts::PI * f * t).sin()
        });
        assert_eq!(orient(r.clone(), 0.5, 20.0), r);
    }

    #[test]
    fn a_tip_that_does_not_follow_its_carriage_is_named_and_left_as_recorded() {
        let truth = rig_recording();
        let base = truth.base_pos_m.clone().unwrap();
        let deflection: Vec<f64> = truth
            .tip_pos_m
            .as_ref()
            .unwrap()
            .iter()
            .zip(&base)
            .map(|(t, b)| t - b)
            .collect();
        let unrelated: Vec<f64> = (0..truth.len())
            .map(|k| 1e-3 * (k as f64 * 0.37).sin())
            .collect();
        for tip in [deflection, unrelated] {
            let mut r = truth.clone();
            r.tip_pos_m = Some(tip);
            let o = orient(r.clone(), 0.5, 20.0);
            assert!(o.tip_pos_m == r.tip_pos_m);
            assert_eq!(o.notes.len(), 1, "{:?}", o.notes);
            assert!(o.notes[0].starts_with("tip_pos_m does not follow"));
        }
    }
}
