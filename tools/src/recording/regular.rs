//! An imperfect recording onto one uniform time base.
//!
//! Every model and estimator of the project assumes uniform sampling. What a camera or a PC
//! logger hands over is often not quite that:
//! - **rows written out of time order** (a buffered logger flushing a row late): put in order
//!   when no row is more than [`MAX_REORDER_ROWS`] rows from its place;
//! - **duplicated rows** (the same time and values written twice): dropped;
//! - **dropped frames** (a step of 2, 3, … sample intervals): the missing samples are filled;
//! - **blank or `nan` cells** where a sensor lost its target: filled the same way;
//! - **time stamps that jitter** about the sample grid: where the samples were taken at the
//!   stamped times, every channel is resampled onto the grid at its recorded times; where the
//!   samples are uniform and only the stamps are noisy (a PC clock stamping a device's
//!   samples), the values stay and their times go onto the grid. The smoothest channel (the
//!   command where recorded) decides: it is smoother read the way it was sampled.
//! - **an irregular sampler** (a PC polling a drive: every step between 0.8 and 1.5 median
//!   steps, at random, and no grid fits): every channel is resampled at its recorded times
//!   onto a uniform grid of the mean step ([`irregular_grid`]), when the local rate holds
//!   within [`MAX_LOCAL_RATE_CHANGE`] throughout (a rate that changes is still refused).
//!
//! The grid is the least-squares line through (grid index, time) of the kept rows, the grid
//! index of a row being its time over the median step, rounded. Values are filled or
//! resampled by local Lagrange interpolation of degree 5 through the channel's valid samples
//! ([`lagrange_at`]: in a component at 9 % of the sample rate one missing sample is filled to
//! 0.14 % of its amplitude, three in a row to 1.3 %). Rows at either end where a channel is missing are cut, never extrapolated.
//!
//! Refused, with the row and the reason: time that goes backwards further than a late row (a
//! clock reset, or two recordings in one file); one time with two different
//! rows; rows closer than half a step; a row more than [`MAX_JITTER_STEPS`] steps off the
//! grid (a varying sample rate, not jitter); a run of more than [`MAX_FILL_RUN`] missing
//! samples in a channel, or more than [`MAX_FILL_FRACTION`] of it missing (cut the recording
//! there, or split it). A recording that is already uniform and complete is returned as it is.
//! A channel logged on every k-th row (a slower sensor) sets the rate of the whole recording
//! first ([`super::multirate`]).

use super::{fmt_sig, Recording, CHANNELS, UNIFORM_TOLERANCE};
use anyhow::{bail, Result};

/// The longest run of consecutive missing samples that is filled (dropped frames, a marker
/// lost for a moment: 0.1 s at 100 Hz); a longer gap is refused. A gap this long across a
/// mode at a tenth of the sample rate is filled only to its trend, an error of a handful of
/// samples that the diagnosis reads as noise.
pub const MAX_FILL_RUN: usize = 10;

/// The farthest a row written out of time order may be from its place (rows) and still be put
/// in order; farther, time going backwards is a clock reset or two recordings in one file.
pub const MAX_REORDER_ROWS: usize = 10;

/// The largest share of a channel's samples that may be filled.
pub const MAX_FILL_FRACTION: f64 = 0.1;

/// The largest share of a channel's samples that may lie in gaps left out of every comparison
/// ([`regularise_leaving_gaps`]): with more, too little of the motion was recorded (the share
/// a sensor may also spend at its rails in the diagnosis).
pub const MAX_GAP_FRACTION: f64 = 0.25;

/// The largest offset of a row's time from the fitted grid, in sample steps, that counts as
/// jitter (a larger one is a varying sample rate).
pub const MAX_JITTER_STEPS: f64 = 0.3;

/// Where the rows of a recording sit on its sample grid.
struct Grid {
    /// Time of grid index 0 (s).
    t0_s: f64,
    /// Sample interval (s).
    dt_s: f64,
    /// Position of each row in grid steps: its grid index when the time stamps are on the
    /// grid, its recorded time in steps when they jitter.
    pos: Vec<f64>,
    /// Largest offset of a row's time from its grid point (s) and the RMS offset (s).
    jitter_max_s: f64,
    jitter_rms_s: f64,
    /// Grid points with no row (dropped frames).
    missing: usize,
    /// The longest run of grid points with no row.
    longest_missing: usize,
    /// How the stamps jitter by more than [`UNIFORM_TOLERANCE`] of a step, if they do.
    jitter: Option<Jitter>,
}

/// Which of two readings of jittering time stamps the data support better.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Jitter {
    /// The samples were taken at the stamped times: every channel is resampled onto the grid
    /// at its recorded times.
    OfTheSamples,
    /// The samples are uniform and only the stamps are noisy (a PC clock stamping a device's
    /// samples): the values stay, their times go onto the grid.
    OfTheStamps,
    /// No grid fits: the samples were taken at irregular times (shortest and longest step,
    /// s) and every channel is resampled at its recorded times ([`irregular_grid`]).
    Irregular { min_step_s: f64, max_step_s: f64 },
}

/// Brings `rec` (finite strictly increasing time allowed to jitter or skip samples; channels
/// that may hold NaN for a missing value) onto a uniform, complete time base, and says what
/// was done in `rec.notes`. Returns `rec` unchanged when it is already uniform and complete.
///
/// Errors: see the module header; each names the data row (1-based) or the channel.
pub fn regularise(rec: Recording) -> Result<Recording> {
    regularise_leaving_gaps(rec, &[]).map(|(rec, _)| rec)
}

/// Runs of samples `[start, end)` (indices of the regularised recording) where a channel had
/// no reading: a sensor that lost its target for longer than [`MAX_FILL_RUN`] samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gaps {
    /// Per channel of [`CHANNELS`] (by name), its runs, ascending.
    pub runs: Vec<(&'static str, Vec<(usize, usize)>)>,
}

impl Gaps {
    /// The runs of channel `name` (empty when it has none).
    pub fn of(&self, name: &str) -> &[(usize, usize)] {
        self.runs
            .iter()
            .find(|(n, _)| *n == name)
            .map_or(&[], |(_, r)| r.as_slice())
    }
}

/// [`regularise`], except that in the channels named in `gappy` (sensors a model is compared
/// with, never one that drives it) a run of more than [`MAX_FILL_RUN`] missing samples is not
/// refused: it is filled by a straight line between the readings on either side (a value for
/// the signal's continuity, not a measurement) and returned in [`Gaps`], for the caller to
/// leave out of every comparison. Such runs may hold up to [`MAX_GAP_FRACTION`] of a channel.
pub fn regularise_leaving_gaps(rec: Recording, gappy: &[&str]) -> Result<(Recording, Gaps)> {
    let complete = CHANNELS
        .iter()
        .filter_map(|n| rec.channel(n))
        .all(|c| c.iter().all(|v| v.is_finite()));
    if complete && rec.validate().is_ok() {
        return Ok((rec, Gaps::default()));
    }
    let rec = in_time_order(rec)?;
    let rec = drop_duplicate_rows(rec)?;
    let mut rec = super::multirate::to_slowest_rate(rec)?;
    if rec.len() < 2 {
        bail!(
            "recording has {} distinct samples; at least 2 are needed",
            rec.len()
        );
    }
    let smooth = CHANNELS
        .iter()
        .find_map(|n| rec.channel(n).map(|c| (*n, c)));
    let grid = fit_grid(&rec.time_s, smooth.map(|s| s.1))?;
    grid_notes(&grid, smooth.map_or("", |s| s.0), &mut rec.notes);
    let (first, last) = common_span(&rec, &grid)?;
    let cut = (
        first - grid.pos[0].ceil().max(0.0) as usize,
        grid.pos[grid.pos.len() - 1].floor() as usize - last,
    );
    let mut out = Recording {
        time_s: (first..=last)
            .map(|j| grid.t0_s + j as f64 * grid.dt_s)
            .collect(),
        notes: std::mem::take(&mut rec.notes),
        ..Default::default()
    };
    let mut gaps = Gaps::default();
    for name in CHANNELS {
        let Some(values) = rec.channel(name) else {
            continue;
        };
        let span = Span {
            first,
            last,
            gaps_allowed: gappy.contains(&name),
        };
        let (filled, runs, note) = fill_channel(name, values, &grid, span)?;
        out.notes.extend(note);
        if !runs.is_empty() {
            gaps.runs.push((name, runs));
        }
        *out.channel_slot(name).expect("known channel") = Some(filled);
    }
    if cut != (0, 0) {
        out.notes.push(format!(
            "{} leading and {} trailing samples cut where a channel was missing",
            cut.0, cut.1
        ));
    }
    out.validate()?;
    Ok((out, gaps))
}

/// `rec` with rows written out of time order put in order (a stable sort by time) when none
/// moves more than [`MAX_REORDER_ROWS`] rows, with a note; unchanged when already in order.
/// Errors: time going backwards further (named by its row, with the jump).
fn in_time_order(mut rec: Recording) -> Result<Recording> {
    let t = &rec.time_s;
    let Some(first) = (1..t.len()).find(|&k| t[k] < t[k - 1]) else {
        return Ok(rec);
    };
    let mut order: Vec<usize> = (0..t.len()).collect();
    order.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
    let moved = order
        .iter()
        .enumerate()
        .map(|(place, &row)| place.abs_diff(row))
        .max()
        .unwrap_or(0);
    if moved > MAX_REORDER_ROWS {
        bail!(
            "time_s goes backwards at data row {} ({} -> {}) and a row would move {moved} rows to its place (at most {MAX_REORDER_ROWS} are put in order): a clock reset, or two recordings in one file? Split the file there",
            first + 1,
            t[first - 1],
            t[first]
        );
    }
    let late = order
        .iter()
        .enumerate()
        .filter(|(place, &row)| *place != row)
        .count();
    rec.time_s = order.iter().map(|&k| rec.time_s[k]).collect();
    for name in CHANNELS {
        if let Some(c) = rec.channel_slot(name).expect("known channel") {
            *c = order.iter().map(|&k| c[k]).collect();
        }
    }
    rec.notes.push(format!(
        "{late} rows written out of time order (none more than {moved} rows from its place): put in order"
    ));
    Ok(rec)
}

/// Drops rows that repeat the previous row's time and values (a logger writing a sample
/// twice). Errors: time going backwards, or one time with two different rows.
fn drop_duplicate_rows(rec: Recording) -> Result<Recording> {
    let present: Vec<&[f64]> = CHANNELS.iter().filter_map(|n| rec.channel(n)).collect();
    let same = |a: f64, b: f64| a == b || (a.is_nan() && b.is_nan());
    let mut keep = vec![true; rec.len()];
    for k in 1..rec.len() {
        let (t0, t1) = (rec.time_s[k - 1], rec.time_s[k]);
        if t1 < t0 {
            bail!("time_s goes backwards at data row {} ({t0} -> {t1})", k + 1);
        }
        if t1 == t0 {
            if !present.iter().all(|c| same(c[k], c[k - 1])) {
                bail!(
                    "time_s repeats at data row {} ({t1} s) with other values: two samples at one time",
                    k + 1
                );
            }
            keep[k] = false;
        }
    }
    let dropped = keep.iter().filter(|k| !**k).count();
    if dropped == 0 {
        return Ok(rec);
    }
    let pick = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| *x)
            .collect()
    };
    let mut out = rec.map_channels(pick(&rec.time_s), pick);
    out.notes.push(format!(
        "{dropped} duplicated rows dropped (same time and values as the row before)"
    ));
    Ok(out)
}

/// The sample grid of a strictly increasing time base: each step as a whole number of median
/// steps, the least-squares line time = t0 + dt · index through those indices, every row's
/// index again from that line (no drift over a long recording), and the line refitted. When
/// the stamps jitter, `smooth` (the smoothest channel: the command where recorded) decides
/// whether the samples or only the stamps jitter ([`stamps_are_noisy`]).
fn fit_grid(time_s: &[f64], smooth: Option<&[f64]>) -> Result<Grid> {
    fit_uniform_grid(time_s, smooth).or_else(|e| irregular_grid(time_s).ok_or(e))
}

/// [`fit_grid`] when the rows sit on one grid (jitter within [`MAX_JITTER_STEPS`]).
fn fit_uniform_grid(time_s: &[f64], smooth: Option<&[f64]>) -> Result<Grid> {
    let mut steps: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let step = steps[steps.len() / 2];
    let mut index = vec![0.0; time_s.len()];
    for k in 1..time_s.len() {
        index[k] = index[k - 1] + ((time_s[k] - time_s[k - 1]) / step).round();
    }
    let (t0_s, dt_s) = line_fit(&index, time_s);
    let first = ((time_s[0] - t0_s) / dt_s).round();
    let index: Vec<f64> = time_s
        .iter()
        .map(|t| ((t - t0_s) / dt_s).round() - first)
        .collect();
    if let Some(k) = index.windows(2).position(|w| w[1] <= w[0]) {
        bail!(
            "time_s steps by {} s at data row {}, less than half the usual {} s: not one sample rate",
            fmt_sig(time_s[k + 1] - time_s[k], 3),
            k + 2,
            fmt_sig(step, 4)
        );
    }
    let (t0_s, dt_s) = line_fit(&index, time_s);
    let offset: Vec<f64> = index
        .iter()
        .zip(time_s)
        .map(|(m, t)| t - (t0_s + dt_s * m))
        .collect();
    let (k_max, jitter_max_s) = offset
        .iter()
        .map(|e| e.abs())
        .enumerate()
        .fold((0, 0.0), |a, (k, e)| if e > a.1 { (k, e) } else { a });
    if jitter_max_s > MAX_JITTER_STEPS * dt_s {
        bail!(
            "time_s at data row {} is {} s off a uniform {} Hz grid ({:.0} % of a step): a varying \
             sample rate, not jitter; resample the recording first",
            k_max + 1,
            fmt_sig(offset[k_max], 3),
            fmt_sig(1.0 / dt_s, 4),
            100.0 * jitter_max_s / dt_s
        );
    }
    let jitter_rms_s = (offset.iter().map(|e| e * e).sum::<f64>() / offset.len() as f64).sqrt();
    let jitter = (jitter_max_s > UNIFORM_TOLERANCE * dt_s).then(|| {
        match smooth.is_some_and(|x| stamps_are_noisy(time_s, &index, x, dt_s)) {
            true => Jitter::OfTheStamps,
            false => Jitter::OfTheSamples,
        }
    });
    let pos = if jitter == Some(Jitter::OfTheSamples) {
        time_s.iter().map(|t| (t - t0_s) / dt_s).collect()
    } else {
        index.clone()
    };
    let runs = index.windows(2).map(|w| (w[1] - w[0]) as usize - 1);
    Ok(Grid {
        t0_s,
        dt_s,
        pos,
        jitter_max_s,
        jitter_rms_s,
        missing: runs.clone().sum(),
        longest_missing: runs.max().unwrap_or(0),
        jitter,
    })
}

/// The largest relative change of the local sample interval (the median step over
/// [`IRREGULAR_WINDOW`] rows against the whole recording's) that still counts as one
/// irregular sampler rather than a sample rate that changes.
pub const MAX_LOCAL_RATE_CHANGE: f64 = 0.2;

/// Rows over which the local sample interval of an irregular sampler is taken.
pub const IRREGULAR_WINDOW: usize = 50;

/// The grid of an **irregular sampler**: stamps that fit no uniform grid (steps from 0.8 to
/// 1.5 median steps at random, a PC polling a drive over a serial or field bus), but whose local
/// sample interval — the median step of every [`IRREGULAR_WINDOW`] rows — stays within
/// [`MAX_LOCAL_RATE_CHANGE`] of the whole recording's, and with no step over 2 median steps (a
/// gap) or of zero. The grid has the mean step (as many samples as rows), and every row sits at
/// its recorded time ([`Jitter::Irregular`]): every channel is resampled onto the grid like
/// jittering samples (degree-5 interpolation at the recorded times, [`lagrange_at`]). `None`
/// otherwise: a rate that changes, or too few rows to tell (fewer than 2 windows).
fn irregular_grid(time_s: &[f64]) -> Option<Grid> {
    use crate::numeric::stats::median;
    let n = time_s.len();
    if n < 2 * IRREGULAR_WINDOW {
        return None;
    }
    let steps: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).collect();
    let typical = median(&steps);
    if !(typical > 0.0) || steps.iter().any(|h| !(*h > 0.0 && *h <= 2.0 * typical)) {
        return None;
    }
    let local_ok = steps
        .windows(IRREGULAR_WINDOW)
        .step_by(IRREGULAR_WINDOW / 2)
        .all(|w| (median(w) / typical - 1.0).abs() <= MAX_LOCAL_RATE_CHANGE);
    if !local_ok {
        return None;
    }
    let dt_s = (time_s[n - 1] - time_s[0]) / (n - 1) as f64;
    let pos: Vec<f64> = time_s.iter().map(|t| (t - time_s[0]) / dt_s).collect();
    let offset: Vec<f64> = pos
        .iter()
        .enumerate()
        .map(|(k, p)| (p - k as f64) * dt_s)
        .collect();
    let fold = |a: (f64, f64), h: &f64| (a.0.min(*h), a.1.max(*h));
    let (min_step_s, max_step_s) = steps.iter().fold((f64::INFINITY, 0.0), fold);
    Some(Grid {
        t0_s: time_s[0],
        dt_s,
        // the last row is the grid's last point (rounding would put it a hair before)
        pos: pos
            .iter()
            .enumerate()
            .map(|(k, p)| if k + 1 == n { (n - 1) as f64 } else { *p })
            .collect(),
        jitter_max_s: offset.iter().fold(0.0, |a, e| a.max(e.abs())),
        jitter_rms_s: (offset.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
        missing: 0,
        longest_missing: 0,
        jitter: Some(Jitter::Irregular {
            min_step_s,
            max_step_s,
        }),
    })
}

/// True when `x` is smoother against the grid than against its stamps: the sum of squared
/// second differences over rows on consecutive grid points is smaller with the uniform step
/// than with the stamped steps. A smooth signal sampled on the grid gains a roughness
/// x′·δ/dt² from each stamp error δ when read at the stamps, and one sampled at the stamps
/// gains the same when read on the grid, so the smaller sum names the reading the data
/// support. Rows with a missing value are skipped.
fn stamps_are_noisy(time_s: &[f64], index: &[f64], x: &[f64], dt_s: f64) -> bool {
    let (mut on_grid, mut at_stamps) = (0.0, 0.0);
    for k in 1..time_s.len().saturating_sub(1) {
        let consecutive = index[k + 1] - index[k] == 1.0 && index[k] - index[k - 1] == 1.0;
        if !consecutive || !(x[k - 1] + x[k] + x[k + 1]).is_finite() {
            continue;
        }
        let (h0, h1) = (time_s[k] - time_s[k - 1], time_s[k + 1] - time_s[k]);
        let d2_stamps = 2.0 * ((x[k + 1] - x[k]) / h1 - (x[k] - x[k - 1]) / h0) / (h0 + h1);
        let d2_grid = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (dt_s * dt_s);
        on_grid += d2_grid * d2_grid;
        at_stamps += d2_stamps * d2_stamps;
    }
    on_grid < at_stamps
}

/// Least-squares intercept and slope of y against x.
fn line_fit(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let slope = sxy / sxx;
    (my - slope * mx, slope)
}

/// The user's notes on the time base.
fn grid_notes(grid: &Grid, judged_on: &str, notes: &mut Vec<String>) {
    let rate = format!("{:.3}", 1.0 / grid.dt_s);
    let rate = rate.trim_end_matches('0').trim_end_matches('.');
    if grid.missing > 0 {
        notes.push(format!(
            "time_s: {} samples missing from the {rate} Hz grid (dropped frames; longest run {})",
            grid.missing, grid.longest_missing
        ));
    }
    let jitter = format!(
        "time_s jitters by {} s RMS (at most {}) about a {rate} Hz grid",
        fmt_sig(grid.jitter_rms_s, 2),
        fmt_sig(grid.jitter_max_s, 2)
    );
    match grid.jitter {
        Some(Jitter::OfTheSamples) => notes.push(format!(
            "{jitter}; `{judged_on}` is smoother at the stamps than on the grid, so the samples \
             were taken at the stamps: every channel resampled onto the grid at its recorded times"
        )),
        Some(Jitter::Irregular {
            min_step_s,
            max_step_s,
        }) => notes.push(format!(
            "time_s steps irregularly, from {} to {} s (no uniform grid fits: a logger polling \
             the drive); every channel resampled at its recorded times onto a uniform {rate} Hz \
             grid of the mean step",
            fmt_sig(min_step_s, 3),
            fmt_sig(max_step_s, 3)
        )),
        Some(Jitter::OfTheStamps) => notes.push(format!(
            "{jitter}; `{judged_on}` is smoother on the grid than at the stamps, so the samples \
             are uniform and the stamps noisy: values kept, times put on the grid"
        )),
        None => {}
    }
}

/// The grid indices `first..=last` that every channel covers with valid samples.
fn common_span(rec: &Recording, grid: &Grid) -> Result<(usize, usize)> {
    let mut first = grid.pos[0].ceil().max(0.0);
    let mut last = grid.pos[grid.pos.len() - 1].floor();
    for name in CHANNELS {
        let Some(values) = rec.channel(name) else {
            continue;
        };
        let valid = || grid.pos.iter().zip(values).filter(|(_, v)| v.is_finite());
        match (valid().next(), valid().last()) {
            (Some((a, _)), Some((b, _))) => {
                first = first.max(a.ceil());
                last = last.min(b.floor());
            }
            _ => bail!("column {name} has no value"),
        }
    }
    if last - first < 1.0 {
        bail!("fewer than 2 samples where every channel has a value");
    }
    Ok((first as usize, last as usize))
}

/// The grid indices `first..=last` a channel is put on, and whether it may keep gaps.
#[derive(Clone, Copy)]
struct Span {
    first: usize,
    last: usize,
    gaps_allowed: bool,
}

/// One channel on grid indices `span.first..=span.last`, its gaps (runs of more than
/// [`MAX_FILL_RUN`] missing samples, `[start, end)` from `span.first`, filled by a straight
/// line; only where `span.gaps_allowed`) and a note when values were filled.
/// Errors: a run of missing samples over [`MAX_FILL_RUN`] where gaps are not allowed, gaps
/// over [`MAX_GAP_FRACTION`] of the channel, or other missing samples over
/// [`MAX_FILL_FRACTION`] filled.
fn fill_channel(
    name: &str,
    values: &[f64],
    grid: &Grid,
    span: Span,
) -> Result<(Vec<f64>, Vec<(usize, usize)>, Option<String>)> {
    let Span { first, last, .. } = span;
    let (u, x): (Vec<f64>, Vec<f64>) = grid
        .pos
        .iter()
        .zip(values)
        .filter(|(_, v)| v.is_finite())
        .map(|(p, v)| (*p, *v))
        .unzip();
    let mut longest = 0usize;
    let mut gaps: Vec<(usize, usize, usize)> = Vec::new();
    for (k, w) in u.windows(2).enumerate() {
        let run = ((w[1] - w[0]).round() as usize).saturating_sub(1);
        if run > MAX_FILL_RUN && w[1] > first as f64 && w[0] < last as f64 {
            if !span.gaps_allowed {
                bail!(
                    "column {name}: {run} consecutive samples missing after {} s (more than {MAX_FILL_RUN} \
                     are not filled): cut the recording there",
                    fmt_sig(grid.t0_s + u[k] * grid.dt_s, 4)
                );
            }
            let a = (w[0].round() as usize + 1).max(first) - first;
            let b = (w[1].round() as usize).min(last + 1) - first;
            gaps.push((k, a, b));
            continue;
        }
        longest = longest.max(run);
    }
    let n_grid = last - first + 1;
    let in_gaps: usize = gaps.iter().map(|(_, a, b)| b - a).sum();
    if in_gaps as f64 > MAX_GAP_FRACTION * n_grid as f64 {
        bail!(
            "column {name}: no reading on {in_gaps} of {n_grid} samples in runs of more than {MAX_FILL_RUN} ({:.0} %, more than {:.0} %): too little of the motion was recorded",
            100.0 * in_gaps as f64 / n_grid as f64,
            100.0 * MAX_GAP_FRACTION
        );
    }
    let n_valid = u
        .iter()
        .filter(|p| **p >= first as f64 - 1e-9 && **p <= last as f64 + 1e-9)
        .count();
    let filled = n_grid.saturating_sub(n_valid + in_gaps);
    if filled as f64 > MAX_FILL_FRACTION * n_grid as f64 {
        bail!(
            "column {name}: {filled} of {n_grid} samples missing ({:.0} %, more than {:.0} %)",
            100.0 * filled as f64 / n_grid as f64,
            100.0 * MAX_FILL_FRACTION
        );
    }
    let mut out = lagrange_at(&u, &x, (first..=last).map(|j| j as f64));
    bridge_gaps(&mut out, (&u, &x), &gaps, first);
    let mut notes = Vec::new();
    if filled > 0 && values.iter().any(|v| !v.is_finite()) {
        notes.push(format!(
            "{filled} missing values filled (degree-5 interpolation, longest run {longest})"
        ));
    }
    if !gaps.is_empty() {
        let widest = gaps.iter().map(|(_, a, b)| b - a).max().unwrap_or(0);
        notes.push(format!(
            "no reading on {in_gaps} samples in {} run(s) of more than {MAX_FILL_RUN} (longest {} s): bridged by a straight line and left out of every comparison",
            gaps.len(),
            fmt_sig(widest as f64 * grid.dt_s, 3)
        ));
    }
    let note = (!notes.is_empty()).then(|| format!("{name}: {}", notes.join("; ")));
    Ok((
        out,
        gaps.into_iter().map(|(_, a, b)| (a, b)).collect(),
        note,
    ))
}

/// Overwrites the samples of each gap `(k, a, b)` of `out` (`[a, b)` counted from grid index
/// `first`, between the valid samples `k` and `k + 1` of `(u, x)`) with the straight line
/// between those two readings: no polynomial across a gap.
fn bridge_gaps(
    out: &mut [f64],
    (u, x): (&[f64], &[f64]),
    gaps: &[(usize, usize, usize)],
    first: usize,
) {
    for &(k, a, b) in gaps {
        let (u0, u1) = (u[k] - first as f64, u[k + 1] - first as f64);
        for (j, v) in out.iter_mut().enumerate().take(b).skip(a) {
            *v = x[k] + (x[k + 1] - x[k]) * (j as f64 - u0) / (u1 - u0);
        }
    }
}

/// Local Lagrange interpolation through (`u`, `x`) (strictly increasing `u`, at least 2
/// points): at each point of `at` (increasing, inside [u₀, u_last]) the polynomial through
/// the [`LAGRANGE_SIDE`] valid samples on either side (at the ends the six nearest), degree 5. At a point equal to a knot it returns the knot's value.
///
/// Degree 5 keeps a band-limited signal well below the Nyquist rate: a component at 9 % of
/// the sample rate is filled across one missing sample to 0.1 % of its amplitude, where a
/// cubic Hermite with three-point slopes misses by 1.5 % and a straight line by 16 %.
pub fn lagrange_at(u: &[f64], x: &[f64], at: impl Iterator<Item = f64>) -> Vec<f64> {
    let n = u.len();
    let mut i = 0;
    at.map(|p| {
        while i + 2 < n && u[i + 1] <= p {
            i += 1;
        }
        if p == u[i] {
            return x[i];
        }
        if p == u[i + 1] {
            return x[i + 1];
        }
        let width = (2 * LAGRANGE_SIDE).min(n);
        let lo = (i + 1).saturating_sub(LAGRANGE_SIDE).min(n - width);
        let hi = lo + width - 1;
        (lo..=hi)
            .map(|j| {
                let w: f64 = (lo..=hi)
                    .filter(|&m| m != j)
                    .map(|m| (p - u[m]) / (u[j] - u[m]))
                    .product();
                w * x[j]
            })
            .sum()
    })
    .collect()
}

/// Valid samples taken on each side of a point by [`lagrange_at`].
pub const LAGRANGE_SIDE: usize = 3;

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-mode signal (1.1 and 9 Hz) at `rate` Hz on times `t`.
    fn signal(t: &[f64]) -> Vec<f64> {
        t.iter()
            .map(|t| {
                (2.0 * std::f64::consts::PI * 1.1 * t).sin()
                    + 0.3 * (2.0 * std::f64::consts::PI * 9.0 * t + 0.4).cos()
            })
            .collect()
    }

    fn recording(t: Vec<f64>) -> Recording {
        let x = signal(&t);
        Recording {
            time_s: t,
            tip_pos_m: Some(x.clone()),
            base_cmd_m: Some(x.iter().map(|v| 0.5 * v).collect()),
            ..Default::default()
        }
    }

    fn grid_times(n: usize, rate: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 / rate).collect()
    }

    #[test]
    fn a_uniform_complete_recording_is_returned_as_it_is() {
        let r = recording(grid_times(500, 100.0));
        assert_eq!(regularise(r.clone()).unwrap(), r);
    }

    #[test]
    fn dropped_frames_and_blank_cells_are_filled_close_to_the_truth() {
        let full = recording(grid_times(2000, 100.0));
        let mut r = full.clone();
        // frames 100, 500–501 and 1500–1502 dropped; the tip lost at 800–801
        let drop = |k: usize| k == 100 || (500..=501).contains(&k) || (1500..=1502).contains(&k);
        let keep: Vec<usize> = (0..2000).filter(|k| !drop(*k)).collect();
        let pick = |v: &[f64]| keep.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        r.time_s = pick(&full.time_s);
        r.base_cmd_m = full.base_cmd_m.as_deref().map(pick);
        let mut tip = pick(full.tip_pos_m.as_deref().unwrap());
        let lost = keep.iter().position(|&k| k == 800).unwrap();
        tip[lost] = f64::NAN;
        tip[lost + 1] = f64::NAN;
        r.tip_pos_m = Some(tip);
        let out = regularise(r).unwrap();
        assert_eq!(out.len(), 2000);
        let (a, b) = (out.tip_pos_m.unwrap(), full.tip_pos_m.unwrap());
        let err = |k: usize| (a[k] - b[k]).abs();
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        // one dropped frame: within 0.3 % of the 9 Hz component (amplitude 0.3; a cubic Hermite
        // with three-point slopes misses by 1.5 %, a straight line by 16 %); three in a row (a
        // gap of 0.36 of its period): within 2 % (measured 0.14 % and 1.3 %; Hermite 7.6 %)
        assert!(err(100) < 0.3 * 0.003, "one-sample fill error {}", err(100));
        assert!(worst < 0.3 * 0.02, "worst fill error {worst}");
        assert!(
            out.notes.iter().any(|n| n.contains("6 samples missing")),
            "{:?}",
            out.notes
        );
        assert!(
            out.notes
                .iter()
                .any(|n| n.starts_with("tip_pos_m: 8 missing")),
            "{:?}",
            out.notes
        );
        let t_err = out
            .time_s
            .iter()
            .zip(&full.time_s)
            .map(|(a, b)| (a - b).abs());
        assert!(t_err.fold(0.0, f64::max) < 1e-9);
    }

    #[test]
    fn jittered_time_stamps_are_resampled_onto_the_grid() {
        // stamps off the 100 Hz grid by up to ±0.5 ms, values taken at the stamped times
        let t: Vec<f64> = (0..3000)
            .map(|k| k as f64 / 100.0 + 5e-4 * ((k as f64 * 1.7).sin()))
            .collect();
        let out = regularise(recording(t)).unwrap();
        let truth = signal(&out.time_s);
        let worst = out
            .tip_pos_m
            .as_ref()
            .unwrap()
            .iter()
            .zip(&truth)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2e-3, "worst resampling error {worst}");
        assert!(out.is_uniform());
        assert!((out.sample_rate_hz() - 100.0).abs() < 1e-6);
        assert!(
            out.notes
                .iter()
                .any(|n| n.contains("resampled onto the grid")),
            "{:?}",
            out.notes
        );
    }

    #[test]
    fn noisy_stamps_of_uniform_samples_keep_the_values_and_go_onto_the_grid() {
        // a device sampling at 100 Hz, a PC clock stamping it ±0.5 ms late or early
        let grid = grid_times(3000, 100.0);
        let mut r = recording(grid.clone());
        r.time_s = grid
            .iter()
            .enumerate()
            .map(|(k, t)| t + 5e-4 * (k as f64 * 1.7).sin())
            .collect();
        let out = regularise(r.clone()).unwrap();
        assert_eq!(out.tip_pos_m, r.tip_pos_m);
        let t_err = out.time_s.iter().zip(&grid).map(|(a, b)| (a - b).abs());
        assert!(t_err.fold(0.0, f64::max) < 1e-6);
        assert!(
            out.notes.iter().any(|n| n.contains("the stamps noisy")),
            "{:?}",
            out.notes
        );
    }

    #[test]
    fn rows_written_late_are_put_in_order_and_a_clock_reset_refused() {
        let truth = recording(grid_times(1000, 100.0));
        let mut late = truth.clone();
        let swap = |r: &mut Recording, a: usize, b: usize| {
            r.time_s.swap(a, b);
            for c in [&mut r.tip_pos_m, &mut r.base_cmd_m] {
                c.as_mut().unwrap().swap(a, b);
            }
        };
        // each 100th row flushed three rows late
        for k in (100..900).step_by(100) {
            swap(&mut late, k, k + 3);
        }
        let out = regularise(late).unwrap();
        let worst = |a: &[f64], b: &[f64]| {
            assert_eq!(a.len(), b.len());
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&out.time_s, &truth.time_s) < 1e-9);
        let tip = (out.tip_pos_m.as_ref(), truth.tip_pos_m.as_ref());
        assert!(worst(tip.0.unwrap(), tip.1.unwrap()) < 1e-9);
        assert!(
            out.notes[0].contains("out of time order (none more than 3 rows"),
            "{:?}",
            out.notes
        );
        // the clock reset after 500 rows: two recordings, not late rows
        let mut reset = truth.clone();
        for t in &mut reset.time_s[500..] {
            *t -= 5.0;
        }
        let e = regularise(reset).unwrap_err().to_string();
        assert!(
            e.contains("data row 501") && e.contains("clock reset"),
            "{e}"
        );
    }

    #[test]
    fn duplicated_rows_are_dropped_and_contradicting_ones_refused() {
        let mut r = recording(grid_times(100, 50.0));
        for c in [&mut r.tip_pos_m, &mut r.base_cmd_m] {
            let v = c.as_mut().unwrap();
            v.insert(41, v[40]);
        }
        r.time_s.insert(41, r.time_s[40]);
        let out = regularise(r.clone()).unwrap();
        assert_eq!(out.len(), 100);
        assert!(out.notes[0].contains("1 duplicated rows dropped"));
        r.tip_pos_m.as_mut().unwrap()[41] += 1e-3;
        let e = regularise(r).unwrap_err().to_string();
        assert!(e.contains("repeats at data row 42"), "{e}");
    }

    #[test]
    fn a_logger_polling_at_irregular_intervals_is_resampled_at_its_recorded_times() {
        use rand::{Rng, SeedableRng};
        // a PC polling a drive: steps of 12-21 ms at random about a 14 ms median (the real
        // LinB axis of docs/diagnose.md, session 24); no grid fits the stamps
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let mut t = vec![0.0];
        for _ in 1..1200 {
            let h = if rng.gen_bool(0.15) {
                rng.gen_range(0.017..0.021)
            } else {
                rng.gen_range(0.012..0.015)
            };
            t.push(t[t.len() - 1] + (h * 1e3_f64).round() / 1e3);
        }
        let out = regularise(recording(t.clone())).unwrap();
        assert_eq!(out.len(), t.len());
        out.validate().unwrap();
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        assert!((out.time_s[1] - out.time_s[0] - dt).abs() < 1e-12);
        let want = signal(&out.time_s);
        let worst = out
            .tip_pos_m
            .as_ref()
            .unwrap()
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 5e-3, "{worst}");
        assert!(
            out.notes
                .iter()
                .any(|n| n.contains("steps irregularly, from 0.0120 to 0.0210 s")),
            "{:?}",
            out.notes
        );
        // the same logger slowing to half its rate half-way is a rate that changes: refused
        let mut slowed = t.clone();
        for k in 600..slowed.len() {
            slowed[k] = t[600] + 2.0 * (t[k] - t[600]);
        }
        assert!(regularise(recording(slowed)).is_err());
    }

    #[test]
    fn long_gaps_too_many_blanks_and_varying_rates_are_refused_by_name() {
        let mut r = recording(grid_times(400, 100.0));
        r.tip_pos_m.as_mut().unwrap()[200..212].fill(f64::NAN);
        let e = regularise(r).unwrap_err().to_string();
        assert!(
            e.contains("tip_pos_m: 12 consecutive samples missing after 1.990 s"),
            "{e}"
        );
        let mut r = recording(grid_times(400, 100.0));
        for k in (10..400).step_by(8) {
            r.tip_pos_m.as_mut().unwrap()[k] = f64::NAN;
        }
        let e = regularise(r).unwrap_err().to_string();
        // 12 % single blanks: every run is short, the share is not
        assert!(e.contains("tip_pos_m: 49 of 400 samples missing"), "{e}");
        let t: Vec<f64> = (0..400).map(|k| (k as f64 / 100.0).powf(1.2)).collect();
        let e = regularise(recording(t)).unwrap_err().to_string();
        assert!(
            e.contains("varying sample rate") || e.contains("not one sample rate"),
            "{e}"
        );
    }

    #[test]
    fn a_long_gap_in_a_compared_channel_is_bridged_and_returned_only_where_allowed() {
        // a camera that lost its marker for 0.6 s (60 samples) and, later, for 0.15 s
        let mut r = recording(grid_times(1000, 100.0));
        let tip = r.tip_pos_m.as_mut().unwrap();
        tip[300..360].fill(f64::NAN);
        tip[700..715].fill(f64::NAN);
        tip[500] = f64::NAN;
        assert!(regularise(r.clone()).is_err());
        assert!(regularise_leaving_gaps(r.clone(), &["force_n"]).is_err());
        let (out, gaps) = regularise_leaving_gaps(r.clone(), &["tip_pos_m"]).unwrap();
        assert_eq!(out.len(), 1000);
        assert_eq!(gaps.of("tip_pos_m"), &[(300, 360), (700, 715)]);
        assert!(gaps.of("base_cmd_m").is_empty());
        // the gaps are a straight line between the readings on either side; the single blank
        // is filled as before
        let (a, want) = (out.tip_pos_m.unwrap(), signal(&grid_times(1000, 100.0)));
        let line = |k: usize| want[299] + (want[360] - want[299]) * (k - 299) as f64 / 61.0;
        assert!((300..360).all(|k| (a[k] - line(k)).abs() < 1e-12));
        assert!((a[500] - want[500]).abs() < 0.3 * 0.003);
        assert!(out
            .notes
            .iter()
            .any(|n| n.contains("tip_pos_m: 1 missing values filled")
                && n.contains("no reading on 75 samples in 2 run(s)")));
        // a quarter of the channel without a reading says too little
        let tip = r.tip_pos_m.as_mut().unwrap();
        tip[100..400].fill(f64::NAN);
        let e = regularise_leaving_gaps(r, &["tip_pos_m"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no reading on 315 of 1000 samples"), "{e}");
    }

    #[test]
    fn leading_and_trailing_blanks_cut_the_recording_instead_of_extrapolating() {
        let mut r = recording(grid_times(300, 100.0));
        let tip = r.tip_pos_m.as_mut().unwrap();
        tip[0] = f64::NAN;
        tip[1] = f64::NAN;
        tip[299] = f64::NAN;
        let out = regularise(r.clone()).unwrap();
        assert_eq!(out.len(), 297);
        assert_eq!(out.time_s[0], r.time_s[2]);
        assert_eq!(
            out.tip_pos_m.as_ref().unwrap()[0],
            r.tip_pos_m.as_ref().unwrap()[2]
        );
        assert!(
            out.notes
                .iter()
                .any(|n| n.contains("2 leading and 1 trailing")),
            "{:?}",
            out.notes
        );
    }

    #[test]
    fn the_interpolation_is_exact_on_a_quintic_at_uneven_knots() {
        let u = [0.0, 0.7, 1.9, 2.2, 4.0, 4.5, 6.1];
        let q = |p: f64| 0.3 * p * p - 1.1 * p + 2.0 + 0.01 * p.powi(5) - 0.02 * p.powi(4);
        let x: Vec<f64> = u.iter().map(|p| q(*p)).collect();
        let at = [0.0, 0.35, 1.0, 2.0, 3.3, 4.0, 5.0, 6.1];
        for (p, v) in at.iter().zip(lagrange_at(&u, &x, at.iter().copied())) {
            assert!((v - q(*p)).abs() < 1e-9, "{p}: {v} vs {}", q(*p));
        }
    }
}
