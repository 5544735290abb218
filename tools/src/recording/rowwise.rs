//! Row-wise logs: each row updates only some columns.
//!
//! A ROS bag exported row-wise writes one row per message, with the cells of that message's
//! topic filled and every other cell blank; loggers that write a row whenever any sensor
//! reports do the same. A channel blank on most rows is then not *missing*: it is held at its
//! last value between its updates (the sensor's sample-and-hold), so each channel is
//! forward-filled from its last value ([`forward_fill`]).
//!
//! Told apart from the other readings of blank cells:
//! - [`super::regular`] fills short runs of missing values (a marker lost for a moment): at
//!   most [`super::regular::MAX_FILL_FRACTION`] of a channel;
//! - [`super::multirate`] reads a channel logged on exactly every k-th row (a slower sensor on a
//!   uniform log) at its own rate.
//!
//! A recording is row-wise ([`is_rowwise`]) when some channel is blank on more than half of
//! the rows and the multirate pattern does not hold. Forward-filling is refused where a
//! channel has no value for longer than [`super::regular::MAX_FILL_RUN`] of its own median
//! update intervals (a lost sensor, not a row-wise log). Rows before every channel has had a
//! value are dropped (nothing to hold yet), rows with no channel's value are dropped, and rows
//! with one time stamp are merged (a message of each of two topics at one instant).

use super::regular::MAX_FILL_RUN;
use super::{fmt_sig, Recording, CHANNELS};
use anyhow::{bail, Result};

/// True when `rec` (channels with NaN for blank cells) is a row-wise log (see the module
/// header).
pub fn is_rowwise(rec: &Recording) -> bool {
    let n = rec.len();
    let mostly_blank = CHANNELS.iter().filter_map(|c| rec.channel(c)).any(|v| {
        let valid = v.iter().filter(|x| !x.is_nan()).count();
        2 * valid < n
    });
    mostly_blank && !super::multirate::holds_pattern(rec)
}

/// `rec` with rows of one time merged, rows without any channel's value and rows before every
/// channel has had a value dropped, and each channel's blanks held at its last value; with a
/// note. Time must be finite and non-decreasing.
///
/// Errors: time going backwards (row named); a channel without a value for longer than
/// [`MAX_FILL_RUN`] of its median update intervals (channel, time and length named); fewer
/// than 2 rows where every channel has a value.
pub fn forward_fill(rec: Recording) -> Result<Recording> {
    let names: Vec<&'static str> = CHANNELS
        .iter()
        .copied()
        .filter(|c| rec.channel(c).is_some())
        .collect();
    let cols: Vec<&[f64]> = names.iter().map(|c| rec.channel(c).unwrap()).collect();
    let n = rec.len();
    let update_share: Vec<f64> = cols
        .iter()
        .map(|v| v.iter().filter(|x| !x.is_nan()).count() as f64 / n.max(1) as f64)
        .collect();
    let (time, mut rows, merged, empty) = merge_rows(&rec.time_s, &cols)?;
    // the first row where every channel has had a value
    let start = rows
        .iter()
        .map(|r| r.iter().position(|v| !v.is_nan()).unwrap_or(usize::MAX))
        .max()
        .unwrap_or(0);
    if start == usize::MAX || time.len().saturating_sub(start) < 2 {
        bail!("row-wise log: fewer than 2 rows after every channel has had a value");
    }
    for (name, r) in names.iter().zip(rows.iter_mut()) {
        check_holds(name, &time, r, start)?;
        let mut last = f64::NAN;
        for v in r.iter_mut() {
            if v.is_nan() {
                *v = last;
            } else {
                last = *v;
            }
        }
    }
    let mut out = Recording {
        time_s: time[start..].to_vec(),
        notes: rec.notes.clone(),
        ..Default::default()
    };
    for (name, r) in names.iter().zip(rows) {
        *out.channel_slot(name).expect("known channel") = Some(r[start..].to_vec());
    }
    let shares: Vec<String> = names
        .iter()
        .zip(&update_share)
        .map(|(c, s)| format!("{c} on {:.0} %", 100.0 * s))
        .collect();
    let mut note = format!(
        "row-wise log (each row updates only some columns: {} of the rows): each channel held at its last value between its updates (forward-filled)",
        shares.join(", ")
    );
    if start > 0 {
        note += &format!("; {start} rows before every channel had a value dropped");
    }
    if empty > 0 {
        note += &format!("; {empty} rows without a value of a read channel dropped");
    }
    if merged > 0 {
        note += &format!("; {merged} rows of an earlier row's time merged into it");
    }
    out.notes.push(note);
    Ok(out)
}

/// Rows of one time merged (later cells win) and rows with no value dropped: (time, each
/// channel's values with NaN where blank, rows merged, rows dropped).
/// Errors: time going backwards (row named).
#[allow(clippy::type_complexity)]
fn merge_rows(time_s: &[f64], cols: &[&[f64]]) -> Result<(Vec<f64>, Vec<Vec<f64>>, usize, usize)> {
    let n = time_s.len();
    let mut time: Vec<f64> = Vec::with_capacity(n);
    let mut rows: Vec<Vec<f64>> = cols.iter().map(|_| Vec::with_capacity(n)).collect();
    let (mut merged, mut empty) = (0usize, 0usize);
    for k in 0..n {
        let t = time_s[k];
        if k > 0 && t < time_s[k - 1] {
            bail!(
                "time_s goes backwards at data row {} ({} -> {t}) in a row-wise log",
                k + 1,
                time_s[k - 1]
            );
        }
        if cols.iter().all(|c| c[k].is_nan()) {
            empty += 1;
            continue;
        }
        if time.last() == Some(&t) {
            merged += 1;
            for (r, c) in rows.iter_mut().zip(cols) {
                if !c[k].is_nan() {
                    *r.last_mut().expect("a row") = c[k];
                }
            }
            continue;
        }
        time.push(t);
        for (r, c) in rows.iter_mut().zip(cols) {
            r.push(c[k]);
        }
    }
    Ok((time, rows, merged, empty))
}

/// Refuses a hold longer than [`MAX_FILL_RUN`] median update intervals of channel `name`
/// (values `r` at `time`, NaN where blank) after row `start`.
fn check_holds(name: &str, time: &[f64], r: &[f64], start: usize) -> Result<()> {
    let updates: Vec<f64> = (start..r.len())
        .filter(|&k| !r[k].is_nan())
        .map(|k| time[k])
        .collect();
    if updates.len() < 3 {
        return Ok(());
    }
    let mut steps: Vec<f64> = updates.windows(2).map(|w| w[1] - w[0]).collect();
    let end_hold = time[time.len() - 1] - updates[updates.len() - 1];
    let longest = steps
        .iter()
        .copied()
        .enumerate()
        .fold((0, 0.0), |a, (k, s)| if s > a.1 { (k, s) } else { a });
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    let limit = MAX_FILL_RUN as f64 * median;
    if longest.1 > limit {
        bail!(
            "row-wise log: {name} has no value for {} s after t = {} s, more than {MAX_FILL_RUN} of its update intervals ({} s): a lost sensor, not a row-wise log; cut the recording there",
            fmt_sig(longest.1, 3),
            fmt_sig(updates[longest.0], 6),
            fmt_sig(median, 3)
        );
    }
    if end_hold > limit {
        bail!(
            "row-wise log: {name} has no value for the last {} s of the recording, more than {MAX_FILL_RUN} of its update intervals ({} s): cut the recording at t = {} s",
            fmt_sig(end_hold, 3),
            fmt_sig(median, 3),
            fmt_sig(updates[updates.len() - 1], 6)
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two topics, one per row, at different rates; a leading row of one topic only.
    #[test]
    fn each_channel_is_held_at_its_last_value() {
        let nan = f64::NAN;
        let rec = Recording {
            time_s: vec![0.0, 0.01, 0.02, 0.02, 0.03, 0.04, 0.05, 0.06],
            base_pos_m: Some(vec![1.0, nan, 2.0, nan, 3.0, nan, 4.0, nan]),
            tip_pos_m: Some(vec![nan, 10.0, nan, 11.0, nan, nan, nan, 12.0]),
            ..Default::default()
        };
        assert!(is_rowwise(&rec));
        let out = forward_fill(rec).unwrap();
        assert_eq!(out.time_s, vec![0.01, 0.02, 0.03, 0.05, 0.06]);
        assert_eq!(out.base_pos_m.unwrap(), vec![1.0, 2.0, 3.0, 4.0, 4.0]);
        assert_eq!(out.tip_pos_m.unwrap(), vec![10.0, 11.0, 11.0, 11.0, 12.0]);
        let note = &out.notes[0];
        assert!(note.starts_with("row-wise log"), "{note}");
        assert!(
            note.contains("1 rows before every channel had a value dropped"),
            "{note}"
        );
        assert!(note.contains("1 rows without a value"), "{note}");
        assert!(
            note.contains("1 rows of an earlier row's time merged"),
            "{note}"
        );
    }

    #[test]
    fn a_sensor_lost_for_long_is_refused() {
        let n = 200;
        let rec = Recording {
            time_s: (0..n).map(|k| k as f64 * 0.01).collect(),
            base_pos_m: Some(
                (0..n)
                    .map(|k| if k % 2 == 0 { k as f64 } else { f64::NAN })
                    .collect(),
            ),
            tip_pos_m: Some(
                (0..n)
                    .map(|k| {
                        if k % 2 == 1 && !(50..150).contains(&k) {
                            1.0
                        } else {
                            f64::NAN
                        }
                    })
                    .collect(),
            ),
            ..Default::default()
        };
        let e = forward_fill(rec).unwrap_err().to_string();
        assert!(
            e.contains("tip_pos_m has no value for 1.02 s after t = 0.49"),
            "{e}"
        );
    }
}
