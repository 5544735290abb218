//! How a channel was really sampled: its quantisation step ([`quantum`]) and whether it is a
//! sample-and-hold staircase of a slower sensor ([`staircase`]).
//!
//! **Quantum.** A sensor that counts (an encoder, a camera's pixels, an ADC, a value printed to
//! a fixed number of decimals) moves in whole steps: every difference between consecutive
//! samples is a multiple of the step. The step is found as the smallest non-zero |difference|
//! d_min, or d_min / k (k ≤ [`MAX_QUANTUM_DIVISOR`], for a signal that never moves by a single
//! step) — the largest such q that at least [`MIN_ON_GRID_SHARE`] of the non-zero differences
//! are multiples of, each within [`QUANTUM_TOLERANCE`] of a step.
//!
//! **Staircase.** A slow sensor logged in a fast log (a 22 Hz angle in a 100 Hz log, or a
//! channel forward-filled in a row-wise log) repeats its value for several rows and changes only
//! when the sensor updates. That is a pattern of the *times* of the changes, not of their sizes:
//! a quantised signal that drifts slowly also repeats its value for many rows, but it changes
//! by one step whenever it crosses one, at any row. A channel is read as a staircase when
//! - at least [`MIN_REPEAT_SHARE`] of its samples exactly repeat the one before (updates at
//!   most half the log's rate repeat half the rows, less the early changes allowed below: a
//!   sensor at exactly half the rate of a jittering log, two topics of one rate interleaved in
//!   a row-wise log, repeats on 48–50 %);
//! - changes never come sooner than two log steps after the one before, except for at most
//!   [`MAX_EARLY_SHARE`] of them (a value that changes at the log's rate is sampled at it);
//! - the changes are not explained by quantisation: with a quantum q known, at least
//!   [`MIN_MULTI_STEP_SHARE`] of the changes jump by more than one step (a sensor read every T
//!   moves by several steps between its readings while the signal moves; a quantised signal
//!   at the full rate that is slower than a step per row moves by exactly one).
//!
//! The update period T is the mean of the intervals between changes up to 1.5 times the
//! shortest typical one (the [`EARLY_QUANTILE`] quantile): a change is seen on the first row
//! after the update, so each interval is off by less than one log step, and the mean of
//! many is the period. The update rate is 1 / T. At least [`MIN_CHANGES`] changes are needed
//! for either estimate.

use super::fmt_sig;

/// The fewest changes of value from which a quantum or a staircase is estimated.
pub const MIN_CHANGES: usize = 20;

/// Largest k tried in q = d_min / k (a signal that only moves by 2, 3 or 4 steps at a time).
pub const MAX_QUANTUM_DIVISOR: usize = 4;

/// Largest distance of a difference from a whole number of steps (in steps) that counts as on
/// the grid: far above the rounding of values printed to their decimals (10⁻⁶ of a step and
/// less), far below a half step.
pub const QUANTUM_TOLERANCE: f64 = 0.01;

/// Smallest share of the non-zero differences on the grid of a quantum (a few outliers, such as
/// an unquantised first sample or a logger's rounding, allowed).
pub const MIN_ON_GRID_SHARE: f64 = 0.99;

/// Largest share of the changes that may come sooner than two log steps after the one before
/// in a staircase (a rare glitch or a rounding flip).
pub const MAX_EARLY_SHARE: f64 = 0.05;

/// Smallest share of the samples that repeat the one before in a staircase: changes at
/// least two log steps apart repeat every other row, except for the [`MAX_EARLY_SHARE`] of
/// changes that may come sooner.
pub const MIN_REPEAT_SHARE: f64 = (1.0 - MAX_EARLY_SHARE) / 2.0;

/// The quantile of the intervals between changes taken as the shortest typical interval.
pub const EARLY_QUANTILE: f64 = 0.05;

/// Smallest share of changes by more than one quantum in a staircase of a quantised channel.
pub const MIN_MULTI_STEP_SHARE: f64 = 0.1;

/// A channel's quantisation step, if it has one: see the module header. `None` for fewer than
/// [`MIN_CHANGES`] changes or values not on a grid. NaN samples are skipped.
pub fn quantum(x: &[f64]) -> Option<f64> {
    let d: Vec<f64> = x
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if d.len() < MIN_CHANGES {
        return None;
    }
    let d_min = d.iter().copied().fold(f64::INFINITY, f64::min);
    (1..=MAX_QUANTUM_DIVISOR).find_map(|k| {
        let q = d_min / k as f64;
        // stop at the first difference past the allowed share off the grid
        let allowed = ((1.0 - MIN_ON_GRID_SHARE) * d.len() as f64) as usize;
        let on_grid = d
            .iter()
            .filter(|&&v| {
                let m = v / q;
                (m - m.round()).abs() > QUANTUM_TOLERANCE
            })
            .nth(allowed)
            .is_none();
        on_grid.then(|| {
            // the mean step of the single-step differences (rounding of d_min averaged out)
            let singles: Vec<f64> = d
                .iter()
                .copied()
                .filter(|v| (v / q).round() == 1.0)
                .collect();
            if singles.is_empty() {
                q
            } else {
                singles.iter().sum::<f64>() / singles.len() as f64
            }
        })
    })
}

/// A sample-and-hold staircase ([`staircase`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Staircase {
    /// The sensor's update period (s).
    pub period_s: f64,
    /// Its update rate (Hz), 1 / `period_s`.
    pub update_rate_hz: f64,
    /// The log's row rate (Hz): 1 / the median step of the time base.
    pub row_rate_hz: f64,
    /// Share of the samples that repeat the one before.
    pub repeat_share: f64,
    /// Number of changes of value it was estimated from.
    pub changes: usize,
}

/// The channel `x` at times `t` read as a staircase (see the module header), or `None`.
/// `quantum` is the channel's [`quantum`], when it has one. NaN samples are skipped.
pub fn staircase(t: &[f64], x: &[f64], quantum: Option<f64>) -> Option<Staircase> {
    let n = t.len().min(x.len());
    if n < 2 * MIN_CHANGES {
        return None;
    }
    // enough samples repeat the one before: counted first, it rules out most channels
    let repeats = (1..n).filter(|&k| x[k] == x[k - 1]).count();
    if (repeats as f64) < MIN_REPEAT_SHARE * (n - 1) as f64 {
        return None;
    }
    let mut steps: Vec<f64> = t[..n].windows(2).map(|w| w[1] - w[0]).collect();
    let mid = steps.len() / 2;
    let h = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
    if !(h > 0.0) {
        return None;
    }
    let (mut pairs, mut repeats) = (0usize, 0usize);
    let mut change_t: Vec<f64> = Vec::new();
    let mut jumps: Vec<f64> = Vec::new();
    for k in 1..n {
        if !(x[k].is_finite() && x[k - 1].is_finite()) {
            continue;
        }
        pairs += 1;
        if x[k] == x[k - 1] {
            repeats += 1;
        } else {
            change_t.push(t[k]);
            jumps.push((x[k] - x[k - 1]).abs());
        }
    }
    let repeat_share = repeats as f64 / pairs.max(1) as f64;
    if change_t.len() < MIN_CHANGES || (repeats as f64) < MIN_REPEAT_SHARE * pairs as f64 {
        return None;
    }
    let mut gaps: Vec<f64> = change_t.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort_by(f64::total_cmp);
    let early = gaps.iter().filter(|&&g| g < 1.5 * h).count();
    if early as f64 > MAX_EARLY_SHARE * gaps.len() as f64 {
        return None;
    }
    if let Some(q) = quantum {
        let multi = jumps.iter().filter(|&&j| j > 1.5 * q).count();
        if (multi as f64) < MIN_MULTI_STEP_SHARE * jumps.len() as f64 {
            return None;
        }
    }
    let shortest = gaps[((EARLY_QUANTILE * gaps.len() as f64) as usize).min(gaps.len() - 1)];
    let typical: Vec<f64> = gaps
        .iter()
        .copied()
        .filter(|&g| g >= 1.5 * h && g <= 1.5 * shortest.max(2.0 * h))
        .collect();
    if typical.is_empty() {
        return None;
    }
    let period_s = typical.iter().sum::<f64>() / typical.len() as f64;
    Some(Staircase {
        period_s,
        update_rate_hz: 1.0 / period_s,
        row_rate_hz: 1.0 / h,
        repeat_share,
        changes: change_t.len(),
    })
}

/// The reading notes on channel `name` (values `x` at times `t`): a staircase, and a quantum
/// whose quantisation noise (q/√12) exceeds 0.1 % of the channel's standard deviation (a
/// sensor's resolution that shows in its spectrum, −60 dB).
pub fn notes(name: &str, t: &[f64], x: &[f64]) -> Vec<String> {
    let mut out = Vec::new();
    let q = quantum(x);
    if let Some(s) = staircase(t, x, q) {
        out.push(format!(
            "{name} is a staircase (sample-and-hold): it repeats its value on {:.0} % of the rows and changes only every {} s, a sensor updating at ~{} Hz in a {} Hz log; its content above {} Hz was not measured",
            100.0 * s.repeat_share,
            fmt_sig(s.period_s, 3),
            fmt_sig(s.update_rate_hz, 3),
            fmt_sig(s.row_rate_hz, 3),
            fmt_sig(0.5 * s.update_rate_hz, 3)
        ));
    }
    if let Some(q) = q {
        let v: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|a| (a - mean) * (a - mean)).sum::<f64>() / v.len() as f64).sqrt();
        if q / 12f64.sqrt() > 1e-3 * sd {
            out.push(format!(
                "{name} is quantised in steps of {} (quantisation noise {:.2} % of its standard deviation)",
                fmt_sig(q, 4),
                100.0 * q / 12f64.sqrt() / sd
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn swing(f_hz: f64, amp: f64, rate_hz: f64, n: usize) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 / rate_hz).collect();
        let x = t
            .iter()
            .map(|t| amp * (2.0 * std::f64::consts::PI * f_hz * t).sin())
            .collect();
        (t, x)
    }

    /// A 22 Hz angle sensor (0.001 rad steps) held in a 100 Hz log: a staircase at ~22 Hz.
    #[test]
    fn a_slow_sensor_held_in_a_fast_log_is_a_staircase_at_its_rate() {
        let (t, _) = swing(0.735, 0.05, 100.0, 3000);
        let x: Vec<f64> = t
            .iter()
            .map(|&t| {
                let held = (t * 22.0).floor() / 22.0; // the last update
                (0.05 * (2.0 * std::f64::consts::PI * 0.735 * held).sin() / 1e-3).round() * 1e-3
            })
            .collect();
        let q = quantum(&x).unwrap();
        assert!((q - 1e-3).abs() < 1e-9, "{q}");
        let s = staircase(&t, &x, Some(q)).unwrap();
        assert!((s.update_rate_hz - 22.0).abs() < 0.5, "{s:?}");
        assert!((s.row_rate_hz - 100.0).abs() < 1e-6);
    }

    /// A 1 mm-quantised deflection at 1 kHz, ±20 mm at 1.75 Hz: it repeats most values but is
    /// no staircase (it changes by one step at whatever row it crosses one).
    #[test]
    fn a_quantised_slow_signal_is_not_a_staircase() {
        let (t, x) = swing(1.75, 0.02, 1000.0, 5000);
        let x: Vec<f64> = x.iter().map(|v| (v / 1e-3).round() * 1e-3).collect();
        let q = quantum(&x).unwrap();
        assert!((q - 1e-3).abs() < 1e-9, "{q}");
        assert!(staircase(&t, &x, Some(q)).is_none());
        // a continuous signal has no quantum and no staircase
        let (t, x) = swing(1.75, 0.02, 1000.0, 5000);
        assert_eq!(quantum(&x), None);
        assert!(staircase(&t, &x, None).is_none());
        // the same signal held at 100 Hz (every 10th row) is one
        let held: Vec<f64> = (0..x.len()).map(|k| x[k - k % 10]).collect();
        let s = staircase(&t, &held, quantum(&held)).unwrap();
        assert!((s.update_rate_hz - 100.0).abs() < 1.0, "{s:?}");
    }
}
