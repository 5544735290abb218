//! Sensor zeros, from the rest before the first move.
//!
//! While the command has not yet moved, the beam hangs straight and the carriage stands where
//! it was told to: `base_pos_m` equals `base_cmd_m`, and `tip_pos_m` equals the base (the
//! format's lab frame). A sensor zeroed elsewhere (a camera whose origin is not the beam's
//! root, an encoder referenced to another home) shows there as a constant offset, which no
//! model of the beam can produce: a 3 mm camera offset alone leaves a 20 % validation NRMSE on
//! the tip and hides every effect under it. The offset is removed when it stands out of the
//! rest's own scatter by more than [`OFFSET_STANDARD_ERRORS`] standard errors, with a note; a
//! recording whose sensors agree at rest is returned unchanged.
//!
//! The rest is the leading run of samples whose command stays within [`REST_TOLERANCE_M`] of
//! its first value; without `base_cmd_m` nothing is changed, and with fewer than
//! [`MIN_REST_SAMPLES`] of them nothing but a note that the recording does not start at rest; a tip that rings
//! over the rest (a logger started after a move) is named too, since the model starts every
//! recording at rest. `force_n` is left alone: at rest the drive may hold a force inside the
//! guide's static friction, which is physics, not an offset.

use super::{fmt_sig, Recording};

/// How far the command may be from its first value and still count as "not yet moved" (m):
/// a 1 µm encoder count.
pub const REST_TOLERANCE_M: f64 = 1e-6;

/// The tip's rms motion about the base over the rest, in multiples of its noise, above which
/// the beam counts as still ringing when the recording starts.
pub const RINGING_NOISE_MULTIPLE: f64 = 5.0;

/// The tip's rms motion about the base over the rest, as a share of the deflection's largest
/// value over the recording, above which the beam counts as still ringing: the truth
/// generator's rests (sensor noise with slow components, camera counts) reach 0.03 mm against
/// deflections of tens of mm; a logger started 9 s into independent case03 shows 22 mm.
pub const RINGING_SHARE: f64 = 0.02;

/// The fewest rest samples from which an offset is estimated.
pub const MIN_REST_SAMPLES: usize = 10;

/// An offset is removed when its mean over the rest exceeds this many standard errors of
/// that mean (the rest's standard deviation over √n).
pub const OFFSET_STANDARD_ERRORS: f64 = 4.0;

/// `rec` with the constant offsets of `base_pos_m` (against the command) and of `tip_pos_m`
/// (against the base) over the rest before the first move removed where they are
/// significant; a note names each. Unchanged without `base_cmd_m` or without a rest.
pub fn zero_at_rest(mut rec: Recording) -> Recording {
    let Some(cmd) = rec.base_cmd_m.clone() else {
        return rec;
    };
    let n = rest_samples(&cmd);
    if n < MIN_REST_SAMPLES {
        rec.notes.push(format!(
            "the command moves within the first {n} samples: the recording does not start at rest, as the diagnosis's model starts it; where the rig has a beam, its modes' free response from an unknown initial state is fitted with it (start the logger before the first move)"
        ));
        return rec;
    }
    let rest_s = n as f64 * rec.sample_interval_s();
    if let Some(base) = rec.base_pos_m.as_mut() {
        if let Some(off) = significant_offset(&base[..n], &cmd[..n]) {
            base.iter_mut().for_each(|b| *b -= off);
            rec.notes
                .push(offset_note("base_pos_m", "base_cmd_m", off, rest_s));
        }
    }
    let reference = rec.base_pos_m.clone().unwrap_or(cmd);
    if let Some(note) = rec
        .tip_pos_m
        .as_deref()
        .and_then(|tip| still_ringing(tip, &reference, n, rest_s))
    {
        rec.notes.push(note);
    }
    if let Some(tip) = rec.tip_pos_m.as_mut() {
        if let Some(off) = significant_offset(&tip[..n], &reference[..n]) {
            tip.iter_mut().for_each(|t| *t -= off);
            rec.notes
                .push(offset_note("tip_pos_m", "the base", off, rest_s));
        }
    }
    rec
}

/// Whether `rec` starts at rest, as the diagnosis's model starts every recording: its command
/// rests for at least [`MIN_REST_SAMPLES`] samples and the tip does not ring about the base
/// over that rest (see [`zero_at_rest`]). True without `base_cmd_m` (nothing tells).
pub fn starts_at_rest(rec: &Recording) -> bool {
    let Some(cmd) = rec.base_cmd_m.as_deref() else {
        return true;
    };
    let n = rest_samples(cmd);
    if n < MIN_REST_SAMPLES {
        return false;
    }
    let reference = rec.base_pos_m.as_deref().unwrap_or(cmd);
    rec.tip_pos_m.as_deref().map_or(true, |tip| {
        still_ringing(tip, reference, n, n as f64 * rec.sample_interval_s()).is_none()
    })
}

/// Samples in the leading run whose command stays within [`REST_TOLERANCE_M`] of its first value.
fn rest_samples(cmd: &[f64]) -> usize {
    cmd.iter()
        .position(|c| (c - cmd[0]).abs() > REST_TOLERANCE_M)
        .unwrap_or(cmd.len())
}

/// A note when the tip moves about the base over the rest (its first `n` samples) by more
/// than [`RINGING_NOISE_MULTIPLE`] × its noise (σ = 1.4826 MAD(Δ²x)/√6, which a ring well
/// below the sample rate hardly reaches) and more than [`RINGING_SHARE`] of the deflection's
/// largest value over the recording: the beam still rings from a motion before the recording.
fn still_ringing(tip: &[f64], reference: &[f64], n: usize, rest_s: f64) -> Option<String> {
    let largest = tip
        .iter()
        .zip(reference)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let d: Vec<f64> = tip[..n]
        .iter()
        .zip(&reference[..n])
        .map(|(a, b)| a - b)
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let rms = (d.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    let noise = crate::numeric::stats::second_difference_noise(&d);
    if !noise.is_finite() {
        return None;
    }
    (rms > RINGING_NOISE_MULTIPLE * noise && rms > RINGING_SHARE * largest).then(|| {
        format!(
            "the tip moves about the base by {} mm rms over the rest before the first move ({} s; its noise {} mm): the beam still rings from a motion before the recording, which the diagnosis's model starts at rest; the beam modes' free response from an unknown initial state is fitted with it (start the logger with the beam at rest)",
            fmt_sig(rms * 1e3, 3),
            fmt_sig(rest_s, 3),
            fmt_sig(noise * 1e3, 2)
        )
    })
}

/// The mean of `x − reference` when it exceeds [`OFFSET_STANDARD_ERRORS`] standard errors.
fn significant_offset(x: &[f64], reference: &[f64]) -> Option<f64> {
    let d: Vec<f64> = x.iter().zip(reference).map(|(a, b)| a - b).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    (mean.abs() > OFFSET_STANDARD_ERRORS * (var / n).sqrt()).then_some(mean)
}

fn offset_note(channel: &str, against: &str, off: f64, rest_s: f64) -> String {
    format!(
        "{channel}: offset {} mm against {against} over the rest before the first move ({} s) removed (sensor zero)",
        fmt_sig(off * 1e3, 3),
        fmt_sig(rest_s, 3)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 100 Hz: at rest for 0.5 s, then a ramp; tip and base with a deterministic ±20 µm
    /// scatter about their true values.
    fn recording() -> Recording {
        let n = 400;
        let cmd: Vec<f64> = (0..n)
            .map(|k| if k < 50 { 0.0 } else { (k - 50) as f64 * 1e-4 })
            .collect();
        let scatter = |k: usize, s: f64| 2e-5 * ((k as f64 * s).sin());
        let mut r = Recording::with_uniform_time(n, 100.0);
        r.base_pos_m = Some(
            cmd.iter()
                .enumerate()
                .map(|(k, c)| c + 0.1 * scatter(k, 2.3))
                .collect(),
        );
        r.tip_pos_m = Some(
            cmd.iter()
                .enumerate()
                .map(|(k, c)| c + scatter(k, 1.7))
                .collect(),
        );
        r.base_cmd_m = Some(cmd);
        r
    }

    #[test]
    fn sensors_that_agree_at_rest_are_left_alone() {
        let r = recording();
        assert_eq!(zero_at_rest(r.clone()), r);
    }

    #[test]
    fn a_camera_and_an_encoder_zeroed_elsewhere_are_brought_back() {
        let truth = recording();
        let mut r = truth.clone();
        r.tip_pos_m
            .as_mut()
            .unwrap()
            .iter_mut()
            .for_each(|t| *t += 3e-3);
        r.base_pos_m
            .as_mut()
            .unwrap()
            .iter_mut()
            .for_each(|b| *b -= 2e-4);
        let z = zero_at_rest(r);
        let worst = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        // the estimate is the rest's mean: off by the scatter's mean over it, a few µm
        assert!(
            worst(
                z.tip_pos_m.as_ref().unwrap(),
                truth.tip_pos_m.as_ref().unwrap()
            ) < 5e-6
        );
        assert!(
            worst(
                z.base_pos_m.as_ref().unwrap(),
                truth.base_pos_m.as_ref().unwrap()
            ) < 1e-6
        );
        assert_eq!(z.notes.len(), 2, "{:?}", z.notes);
        assert!(
            z.notes[1].starts_with("tip_pos_m: offset 3.00 mm"),
            "{:?}",
            z.notes
        );
    }

    #[test]
    fn without_a_rest_nothing_is_changed_but_a_note() {
        let mut r = recording();
        let cmd = r.base_cmd_m.as_mut().unwrap();
        for (k, c) in cmd.iter_mut().enumerate() {
            *c = k as f64 * 1e-4;
        }
        r.tip_pos_m
            .as_mut()
            .unwrap()
            .iter_mut()
            .for_each(|t| *t += 3e-3);
        let z = zero_at_rest(r.clone());
        assert_eq!(
            (&z.time_s, &z.base_pos_m, &z.tip_pos_m),
            (&r.time_s, &r.base_pos_m, &r.tip_pos_m)
        );
        assert_eq!(z.notes.len(), 1);
        assert!(
            z.notes[0].contains("does not start at rest"),
            "{:?}",
            z.notes
        );
    }

    #[test]
    fn a_beam_still_ringing_when_the_recording_starts_is_named() {
        // a 1 mm ring at 1.5 Hz decaying slowly over the rest, under the ±20 µm scatter
        let mut r = recording();
        for (k, t) in r.tip_pos_m.as_mut().unwrap().iter_mut().enumerate() {
            let s = k as f64 / 100.0;
            *t += 1e-3 * (-0.1 * s).exp() * (2.0 * std::f64::consts::PI * 1.5 * s).cos();
        }
        let z = zero_at_rest(r);
        assert!(
            z.notes.iter().any(|n| n.contains("still rings")),
            "{:?}",
            z.notes
        );
        // the scatter alone is not a ring
        assert!(zero_at_rest(recording()).notes.is_empty());
    }
}
