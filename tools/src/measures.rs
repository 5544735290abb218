//! The paper's performance measures (§5.3, Table 2) of a move's tip response.
//!
//! Definitions (the paper does not spell them out; these reproduce its Table 2 structure):
//! - **overshoot (%)** = 100 · max over the record of (tip − target)·sign(move) / |move|;
//! - **residual vibration amplitude** = max |tip − target| after the *command* (the shaped
//!   setpoint) has reached the target;
//! - **percentage vibration (%)** = 100 · residual amplitude of the shaped move / that of the
//!   unshaped move (the same ratio the shaper design's V(ω, ζ) predicts);
//! - **settling time (s)** = time from the end of the *unshaped* reference move until the tip
//!   stays within ±`band` (default 2 % of |move|) of the target (so a longer shaper costs its
//!   extra delay, as in the paper's discussion of ZVDD vs ZV).

/// Measures of one response.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveMeasures {
    /// Overshoot (% of the move).
    pub overshoot_pct: f64,
    /// Residual vibration amplitude (m).
    pub residual_m: f64,
    /// Settling time after the end of the unshaped reference (s); `None` if the tip never
    /// stays inside the band within the record.
    pub settling_s: Option<f64>,
}

/// Measures a tip response `tip_m` sampled at `time_s` for a move from `start_m` to `target_m`.
/// `command_end_s`: when the shaped command reached the target; `reference_end_s`: when the
/// unshaped reference did; `band_m`: settling band half-width.
pub fn measure(
    time_s: &[f64],
    tip_m: &[f64],
    start_m: f64,
    target_m: f64,
    command_end_s: f64,
    reference_end_s: f64,
    band_m: f64,
) -> MoveMeasures {
    let dist = target_m - start_m;
    let sign = dist.signum();
    let over = tip_m
        .iter()
        .map(|&p| (p - target_m) * sign)
        .fold(f64::NEG_INFINITY, f64::max);
    let residual = time_s
        .iter()
        .zip(tip_m)
        .filter(|(t, _)| **t >= command_end_s)
        .map(|(_, p)| (p - target_m).abs())
        .fold(0.0, f64::max);
    let last_out = time_s
        .iter()
        .zip(tip_m)
        .rposition(|(_, p)| (p - target_m).abs() > band_m);
    let settling = match last_out {
        None => Some(0.0),
        Some(k) if k + 1 < time_s.len() => Some((time_s[k + 1] - reference_end_s).max(0.0)),
        Some(_) => None,
    };
    MoveMeasures {
        overshoot_pct: 100.0 * over.max(0.0) / dist.abs(),
        residual_m: residual,
        settling_s: settling,
    }
}

/// Percentage vibration (%): shaped residual amplitude relative to the unshaped one.
pub fn percentage_vibration(shaped: &MoveMeasures, unshaped: &MoveMeasures) -> f64 {
    100.0 * shaped.residual_m / unshaped.residual_m
}
