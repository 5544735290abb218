//! Planning a move before it is sent: the board's step-rate rule with a margin, the console's
//! target range, and a capture decimation so the whole move, the shaper's tail and a settling
//! window fit the board's capture buffer. Nothing here talks to the board: a move that
//! cannot be captured or that the board would refuse is rejected before any motion starts.

use beamshaper::config::Settings;
use beamshaper::engine::TapTable;
use beamshaper::output::{check_move_step_rate, check_step_rate};
use beamshaper::reference::{trapezoid_peak_speed, MoveError, SineSweep, SweepKind, TrapezoidMove};
use beamshaper::runtime::{CAPTURE_LEN, HISTORY_LEN};
use thiserror::Error;

/// Fraction of the board's maximum step rate a planned move may use (5 % margin).
pub const STEP_RATE_USE: f64 = 0.95;
/// The console's target range (mm): `move` refuses targets outside ±1000 mm.
pub const TARGET_LIMIT_MM: f64 = 1000.0;
/// The console's speed (mm/s) and acceleration (mm/s²) ranges.
pub const SPEED_LIMIT_MM_S: f64 = 10_000.0;
/// See [`SPEED_LIMIT_MM_S`].
pub const ACCEL_LIMIT_MM_S2: f64 = 1.0e6;

/// True when `observe_ticks` sampled every `every` ticks fit the board's capture buffer.
pub fn capture_fits(observe_ticks: u64, every: u32) -> bool {
    observe_ticks.div_ceil(every.max(1) as u64) <= CAPTURE_LEN as u64
}

/// A planned move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovePlan {
    /// Start and target (mm, absolute board coordinates).
    pub start_mm: f64,
    /// Target (mm).
    pub target_mm: f64,
    /// Peak speed (mm/s) and acceleration (mm/s²) sent with `move`.
    pub speed_mm_s: f64,
    /// Acceleration (mm/s²).
    pub accel_mm_s2: f64,
    /// Duration of the reference move (ticks).
    pub move_ticks: u64,
    /// Ticks to observe: move + shaper + settling window.
    pub observe_ticks: u64,
    /// Capture decimation (`capture <every>`).
    pub capture_every: u32,
    /// Shaped peak step rate (steps/s) by the board's rule.
    pub peak_step_rate_hz: f64,
}

/// Why a move cannot be planned.
#[derive(Debug, Error, PartialEq)]
pub enum PlanError {
    /// Distance, speed or acceleration unusable.
    #[error("{0}")]
    Argument(String),
    /// The board's settings with this shaper are invalid.
    #[error("the board cannot run this shaper: {0}")]
    Shaper(String),
    /// Shaped peak step rate above the board's limit minus the margin.
    #[error("the shaped move needs {need:.0} steps/s, more than {pct:.0} % of the board's {max} steps/s; use --speed-mm-s {speed_ok:.1} or less")]
    StepRate {
        /// Steps/s the move needs.
        need: f64,
        /// Board maximum (steps/s).
        max: u32,
        /// Allowed fraction in %.
        pct: f64,
        /// Largest speed that fits (mm/s).
        speed_ok: f64,
    },
    /// Too long to capture even at the coarsest decimation.
    #[error("the move and its settling window last {0:.0} s, longer than the board can capture")]
    Capture(f64),
}

/// Plans `start_mm → start_mm + move_mm` on a board running `settings` (the shaper it will
/// run during the move), observing `settle_s` after the shaped command ends.
pub fn plan_move(
    settings: &Settings,
    start_mm: f64,
    move_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
    settle_s: f64,
) -> Result<MovePlan, PlanError> {
    let target_mm = start_mm + move_mm;
    check_move_arguments(move_mm, target_mm, speed_mm_s, accel_mm_s2)?;
    let taps = settings
        .tap_table(HISTORY_LEN)
        .map_err(|e| PlanError::Shaper(e.to_string()))?;
    let tick_hz = settings.tick_rate_hz as f64;
    let mv = trapezoid(start_mm, target_mm, speed_mm_s, accel_mm_s2, tick_hz)?;
    let need = check_step_rate_of_move(
        settings,
        &taps,
        start_mm,
        target_mm,
        speed_mm_s,
        accel_mm_s2,
    )?;
    let move_ticks = mv.duration_ticks() as u64;
    let observe_ticks =
        move_ticks + taps.duration_ticks() as u64 + (settle_s.max(0.0) * tick_hz).ceil() as u64;
    let every = observe_ticks.div_ceil(CAPTURE_LEN as u64 - 16).max(1);
    if every > 10_000 {
        return Err(PlanError::Capture(observe_ticks as f64 / tick_hz));
    }
    Ok(MovePlan {
        start_mm,
        target_mm,
        speed_mm_s,
        accel_mm_s2,
        move_ticks,
        observe_ticks,
        capture_every: every as u32,
        peak_step_rate_hz: need,
    })
}

/// Position in the board's counts (nm) of `mm`.
fn nm(mm: f64) -> i32 {
    (mm * 1e6).round() as i32
}

/// Refuses a zero or non-finite move, a target outside the console's range, a speed or
/// acceleration outside the console's ranges.
fn check_move_arguments(
    move_mm: f64,
    target_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
) -> Result<(), PlanError> {
    let arg = |m: String| Err(PlanError::Argument(m));
    if !move_mm.is_finite() || move_mm.abs() < 1e-3 {
        return arg(format!(
            "the verification move must be at least 0.001 mm (got {move_mm} mm): a zero move has no residual vibration to measure"
        ));
    }
    if !(target_mm.abs() <= TARGET_LIMIT_MM) {
        return arg(format!(
            "the verification move would end at {target_mm:.3} mm, outside the board's ±{TARGET_LIMIT_MM} mm"
        ));
    }
    if !(speed_mm_s > 0.0 && speed_mm_s <= SPEED_LIMIT_MM_S) {
        return arg(format!(
            "speed must be > 0 and ≤ {SPEED_LIMIT_MM_S} mm/s (got {speed_mm_s})"
        ));
    }
    if !(accel_mm_s2 > 0.0 && accel_mm_s2 <= ACCEL_LIMIT_MM_S2) {
        return arg(format!(
            "acceleration must be > 0 and ≤ {ACCEL_LIMIT_MM_S2} mm/s² (got {accel_mm_s2})"
        ));
    }
    Ok(())
}

/// The core's trapezoid of the move (as the board will run it).
fn trapezoid(
    start_mm: f64,
    target_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
    tick_hz: f64,
) -> Result<TrapezoidMove, PlanError> {
    TrapezoidMove::new(
        nm(start_mm),
        nm(target_mm),
        (speed_mm_s * 1e6) as f32,
        (accel_mm_s2 * 1e6) as f32,
        tick_hz as f32,
    )
    .map_err(|e| {
        PlanError::Argument(
            match e {
                MoveError::Profile => "speed or acceleration not usable",
                MoveError::Range => "target outside the board's position range",
                MoveError::TooLong => "the move would take more than 2^32 ticks",
            }
            .to_string(),
        )
    })
}

/// The board's own step-rate rule (core `output::check_move_step_rate`) against its limit
/// minus the margin; returns the shaped peak step rate (steps/s) the move needs.
fn check_step_rate_of_move(
    settings: &Settings,
    taps: &TapTable,
    start_mm: f64,
    target_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
) -> Result<f64, PlanError> {
    let max = settings.max_step_rate_hz;
    let with_margin = (STEP_RATE_USE * max as f64).floor() as u32;
    let distance_nm = (nm(target_mm) as i64 - nm(start_mm) as i64).unsigned_abs() as u32;
    let (speed_nm_s, accel_nm_s2) = ((speed_mm_s * 1e6) as f32, (accel_mm_s2 * 1e6) as f32);
    let need = trapezoid_peak_speed(distance_nm as f32, speed_nm_s, accel_nm_s2) as f64
        * taps.abs_weight_sum() as f64
        / settings.step_nm.max(1) as f64;
    check_move_step_rate(
        taps,
        settings.step_nm,
        with_margin,
        distance_nm,
        speed_nm_s,
        accel_nm_s2,
    )
    .map_err(|e| PlanError::StepRate {
        need: e.shaped_peak_steps_s as f64,
        max,
        pct: 100.0 * STEP_RATE_USE,
        speed_ok: (e.max_reference_speed_nm_s as f64 * 1e-6 * 0.999 * 10.0).floor() / 10.0,
    })?;
    Ok(need)
}

/// A planned sweep (`sweep lin|exp <f0> <f1> <amplitude_mm> <duration_s>`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepPlan {
    /// Kind (eq. 33 linear, eq. 34 exponential).
    pub kind: SweepKind,
    /// Start and end frequencies (Hz).
    pub f0_hz: f64,
    /// End frequency (Hz).
    pub f1_hz: f64,
    /// Amplitude (mm) about the present position.
    pub amplitude_mm: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// Shaped peak step rate bound (steps/s) by the board's rule.
    pub peak_step_rate_hz: f64,
}

/// Plans a sweep from `f0_hz` to `f1_hz` over `duration_s` with the largest amplitude up to
/// `amplitude_max_mm` that the board's step-rate rule (core `output::check_step_rate`,
/// with the margin) allows under `settings`' shaper.
pub fn plan_sweep(
    settings: &Settings,
    kind: SweepKind,
    f0_hz: f64,
    f1_hz: f64,
    amplitude_max_mm: f64,
    duration_s: f64,
) -> Result<SweepPlan, PlanError> {
    let taps = settings
        .tap_table(HISTORY_LEN)
        .map_err(|e| PlanError::Shaper(e.to_string()))?;
    let tick_hz = settings.tick_rate_hz as f64;
    let sweep = |amp_mm: f64| {
        SineSweep::new(kind, 0, f0_hz, f1_hz, amp_mm * 1e6, duration_s, tick_hz).map_err(|e| {
            PlanError::Argument(format!(
                "the board cannot run this sweep ({})",
                match e {
                    beamshaper::reference::SweepError::Nyquist =>
                        "a frequency above a tenth of the tick rate",
                    beamshaper::reference::SweepError::Stroke => "amplitude beyond the stroke",
                    _ => "frequencies, amplitude and duration must be > 0, duration ≤ 3600 s",
                }
            ))
        })
    };
    let per_mm = sweep(1.0)?.peak_speed() as f64 * taps.abs_weight_sum() as f64
        / settings.step_nm.max(1) as f64;
    let max = settings.max_step_rate_hz;
    let amplitude_mm = amplitude_max_mm.min(STEP_RATE_USE * max as f64 / per_mm * 0.999);
    let sw = sweep(amplitude_mm)?;
    let with_margin = (STEP_RATE_USE * max as f64).floor() as u32;
    check_step_rate(&taps, settings.step_nm, with_margin, sw.peak_speed()).map_err(|e| {
        PlanError::StepRate {
            need: e.shaped_peak_steps_s as f64,
            max,
            pct: 100.0 * STEP_RATE_USE,
            speed_ok: e.max_reference_speed_nm_s as f64 * 1e-6,
        }
    })?;
    Ok(SweepPlan {
        kind,
        f0_hz,
        f1_hz,
        amplitude_mm,
        duration_s,
        peak_step_rate_hz: amplitude_mm * per_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_speed_has_no_margin_and_is_refused_with_a_speed_that_fits() {
        let s = Settings::DEFAULT;
        let e = plan_move(&s, 0.0, 50.0, 200.0, 2000.0, 5.0).unwrap_err();
        let PlanError::StepRate { speed_ok, .. } = e else {
            panic!("{e}")
        };
        assert!(speed_ok < 190.0 && speed_ok > 180.0, "{speed_ok}");
        assert!(plan_move(&s, 0.0, 50.0, speed_ok, 2000.0, 5.0).is_ok());
    }

    #[test]
    fn bad_moves_are_refused_and_slow_moves_are_decimated_to_fit_the_capture() {
        let s = Settings::DEFAULT;
        assert!(plan_move(&s, 0.0, 0.0, 100.0, 2000.0, 5.0).is_err());
        assert!(plan_move(&s, 0.0, 2000.0, 100.0, 2000.0, 5.0).is_err());
        assert!(plan_move(&s, 0.0, 50.0, 0.0, 2000.0, 5.0).is_err());
        let p = plan_move(&s, 0.0, -50.0, 100.0, 1.0, 5.0).unwrap();
        assert!(p.capture_every > 1);
        assert!(p.observe_ticks / p.capture_every as u64 <= CAPTURE_LEN as u64);
    }
}
