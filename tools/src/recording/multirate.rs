//! A channel logged at a lower rate than the others, in one file.
//!
//! A logger that writes a row per encoder sample leaves a slower sensor's cells blank between
//! its samples: a 100 Hz camera beside a 1 kHz drive fills one row in ten. Those blanks are not
//! missing values to interpolate (they are 90 % of the channel, and the camera never saw what
//! happened between its frames): the recording holds the slow channel at its own rate.
//!
//! [`to_slowest_rate`] finds such a channel — its valid samples on every k-th row (k ≥ 2), every
//! step a multiple of k and at least [`MIN_REGULAR_SHARE`] of them exactly k — and reads the
//! whole recording at that rate: the rows where the slow channel was sampled are kept with
//! every channel's value as recorded there, as a sampler at that rate would have taken them.
//! The other channels are **not** low-passed: the model predicts each sample as it was taken,
//! and its drive is the carriage's motion at the sample instants; a filter would take real
//! content of the drive away from the model (a 20 Hz cut-off at 50 Hz hid the beam's 22 Hz
//! mode from it and turned independent case12's servo lag into `none`, docs/diagnose.md,
//! session 23). A frame the slow channel missed stays a missing value for [`super::regular`]
//! to fill. Only a uniform time base is read this way (jittering or dropped rows with a slow
//! channel are refused by [`super::regular`] as before).

use super::{Recording, CHANNELS};
use anyhow::{bail, Result};

/// The smallest share of the steps between a slow channel's samples that must be the same
/// whole number of rows.
pub const MIN_REGULAR_SHARE: f64 = 0.9;

/// The slowest channel's period in rows and the row of its first sample, when some channel is
/// logged on every k-th row (k ≥ 2); `None` when every channel is at the rows' rate.
fn slow_period(rec: &Recording) -> Option<(usize, usize, &'static str)> {
    let mut slowest: Option<(usize, usize, &'static str)> = None;
    for name in CHANNELS {
        let Some(values) = rec.channel(name) else {
            continue;
        };
        let rows: Vec<usize> = (0..values.len())
            .filter(|&k| values[k].is_finite())
            .collect();
        if rows.len() < 3 || !at_most_half(rows.len(), values.len()) {
            continue;
        }
        let steps: Vec<usize> = rows.windows(2).map(|w| w[1] - w[0]).collect();
        let mut sorted = steps.clone();
        sorted.sort_unstable();
        let k = sorted[sorted.len() / 2];
        let regular = steps.iter().filter(|&&s| s % k == 0).count();
        let exact = steps.iter().filter(|&&s| s == k).count();
        if k < 2 || regular < steps.len() || (exact as f64) < MIN_REGULAR_SHARE * steps.len() as f64
        {
            continue;
        }
        if slowest.is_none_or(|(k0, _, _)| k > k0) {
            slowest = Some((k, rows[0] % k, name));
        }
    }
    slowest
}

/// True when `rec` has the pattern read here: a uniform time base and some channel logged on
/// every k-th row (k ≥ 2).
pub(super) fn holds_pattern(rec: &Recording) -> bool {
    rec.len() >= 2 && rec.is_uniform() && slow_period(rec).is_some()
}

/// `rec` at its slowest channel's rate (see the module header), with a note; `rec` unchanged
/// when every channel is at the rows' rate or the time base is not uniform.
///
/// Errors: two slow channels whose samples do not fall on one set of rows.
pub fn to_slowest_rate(rec: Recording) -> Result<Recording> {
    let n = rec.len();
    let lengths_agree = CHANNELS
        .iter()
        .filter_map(|c| rec.channel(c))
        .all(|v| v.len() == n);
    if n < 2 || !lengths_agree || !rec.is_uniform() {
        return Ok(rec);
    }
    let Some((k, phase, slow)) = slow_period(&rec) else {
        return Ok(rec);
    };
    let kept: Vec<usize> = (phase..n).step_by(k).collect();
    let mut out = Recording {
        time_s: kept.iter().map(|&j| rec.time_s[j]).collect(),
        notes: rec.notes.clone(),
        ..Default::default()
    };
    let mut slow_names = Vec::new();
    for name in CHANNELS {
        let Some(values) = rec.channel(name) else {
            continue;
        };
        let finite = values.iter().filter(|v| v.is_finite()).count();
        if at_most_half(finite, n) {
            let off_rows = (0..n)
                .filter(|j| values[*j].is_finite() && j % k != phase)
                .count();
            if off_rows > 0 {
                bail!(
                    "column {name} is logged at a lower rate than the rows, but {off_rows} of its \
                     samples fall between those of {slow} (every {} row): write each \
                     sensor's samples on the rows where it was sampled, or one file per rate",
                    ordinal(k)
                );
            }
            slow_names.push(name);
        }
        *out.channel_slot(name).expect("known channel") =
            Some(kept.iter().map(|&j| values[j]).collect());
    }
    let rate = rec.sample_rate_hz();
    out.notes.push(format!(
        "{} logged on every {} row ({} Hz of {} Hz): the recording read at that rate, every \
         channel as recorded on those rows",
        slow_names.join(" and "),
        ordinal(k),
        plain_hz(rate / k as f64),
        plain_hz(rate),
    ));
    Ok(out)
}

/// Whether `valid` samples of `n` rows are at most every other row (⌈n/2⌉: an odd row count
/// holds one more sample of a channel on every 2nd row than half).
fn at_most_half(valid: usize, n: usize) -> bool {
    2 * valid <= n + 1
}

/// A rate in Hz to the millihertz, without trailing zeros (`100`, `33.333`).
fn plain_hz(x: f64) -> String {
    format!("{}", (x * 1e3).round() / 1e3)
}

/// `2nd`, `3rd`, `10th`, … (k ≥ 2).
fn ordinal(k: usize) -> String {
    let suffix = match (k % 10, k % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{k}{suffix}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tip camera at 100 Hz beside a 1 kHz command in one file: read at 100 Hz, every
    /// channel's value on the camera's rows as recorded (a filter would take the drive's real
    /// content from the model).
    #[test]
    fn a_camera_logged_on_every_tenth_row_sets_the_rate_of_the_recording() {
        let n = 5001;
        let mut rec = Recording::with_uniform_time(n, 1000.0);
        let tone = |f: f64, t: f64| (2.0 * std::f64::consts::PI * f * t).sin();
        rec.base_cmd_m = Some(
            rec.time_s
                .iter()
                .map(|&t| 0.1 * tone(5.0, t) + 0.01 * tone(300.0, t))
                .collect(),
        );
        rec.tip_pos_m = Some(
            rec.time_s
                .iter()
                .enumerate()
                .map(|(j, &t)| {
                    if j % 10 == 3 {
                        0.2 * tone(5.0, t)
                    } else {
                        f64::NAN
                    }
                })
                .collect(),
        );
        let out = to_slowest_rate(rec.clone()).unwrap();
        assert_eq!(out.len(), 500);
        // on every 2nd row of an odd count the camera holds one sample more than half the rows
        let mut every_other = rec.clone();
        every_other.tip_pos_m = Some(
            (0..n)
                .map(|j| if j % 2 == 0 { 0.0 } else { f64::NAN })
                .collect(),
        );
        assert_eq!(to_slowest_rate(every_other).unwrap().len(), 2501);
        assert!((out.sample_rate_hz() - 100.0).abs() < 1e-9);
        assert!((out.time_s[0] - 0.003).abs() < 1e-12);
        let tip = out.tip_pos_m.as_ref().unwrap();
        let cmd = out.base_cmd_m.as_ref().unwrap();
        for (j, &t) in out.time_s.iter().enumerate() {
            assert_eq!(tip[j], 0.2 * tone(5.0, t));
            assert_eq!(cmd[j], rec.base_cmd_m.as_ref().unwrap()[10 * j + 3]);
        }
        assert!(
            out.notes[0].starts_with("tip_pos_m logged on every 10th row (100 Hz of 1000 Hz)"),
            "{:?}",
            out.notes
        );
        // a second slow channel on other rows is refused by name
        let mut two = rec.clone();
        two.force_n = Some(
            (0..n)
                .map(|j| if j % 10 == 5 { 1.0 } else { f64::NAN })
                .collect(),
        );
        let e = to_slowest_rate(two).unwrap_err().to_string();
        assert!(
            e.contains("column force_n is logged at a lower rate"),
            "{e}"
        );
        // a few lost values in an otherwise complete channel are not a slower channel
        let mut lost = rec;
        lost.tip_pos_m = lost.base_cmd_m.clone();
        lost.tip_pos_m.as_mut().unwrap()[100] = f64::NAN;
        let kept = to_slowest_rate(lost).unwrap();
        assert_eq!(kept.len(), n);
        assert!(kept.notes.is_empty());
    }
}
