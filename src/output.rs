//! Outputs of a tick: step/direction pulses to the servo drive, and a DAC mirror of the
//! setpoint for a scope.

/// Step/direction output with exact accounting: after every tick the number of steps
/// emitted (signed) equals the shaped setpoint divided by the step size, rounded toward −∞.
/// Steps are never dropped; a tick that needs more pulses than the drive's maximum step rate
/// allows is still emitted in full and counted as a step-rate fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepOutput {
    /// Signed steps emitted since the last re-base (|setpoint| < 2³¹ and step ≥ 1: fits).
    emitted: i32,
    /// Step size (counts per step, nm).
    counts_per_step: i32,
    /// Pulses one tick may carry at the drive's maximum step rate.
    max_pulses_per_tick: u32,
    /// Ticks that needed more pulses than the maximum.
    rate_faults: u32,
}

/// Pulses to emit during the next tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct StepCommand {
    /// Number of step pulses.
    pub pulses: u32,
    /// Direction pin: true = forward (positive).
    pub forward: bool,
}

impl StepOutput {
    /// Output for `counts_per_step` (≥ 1) with at most `max_pulses_per_tick` pulses a tick,
    /// at `position` (counts).
    pub const fn new(counts_per_step: i32, max_pulses_per_tick: u32, position: i32) -> Self {
        let c = if counts_per_step < 1 {
            1
        } else {
            counts_per_step
        };
        StepOutput {
            emitted: position.div_euclid(c),
            counts_per_step: c,
            max_pulses_per_tick,
            rate_faults: 0,
        }
    }

    /// Changes the pulses one tick may carry (the fault count is kept).
    pub fn set_max_pulses_per_tick(&mut self, max_pulses_per_tick: u32) {
        self.max_pulses_per_tick = max_pulses_per_tick;
    }

    /// The steps that must have been emitted for `setpoint` (counts): ⌊setpoint / step⌋
    /// (one 32-bit division; the step size is ≥ 1, so the fallback never happens).
    #[inline]
    pub fn steps_for(&self, setpoint: i32) -> i64 {
        self.steps32(setpoint) as i64
    }

    #[inline(always)]
    fn steps32(&self, setpoint: i32) -> i32 {
        setpoint
            .checked_div_euclid(self.counts_per_step)
            .unwrap_or(setpoint)
    }

    /// Pulses for this tick so that the emitted count equals the setpoint's step count.
    #[inline]
    pub fn update(&mut self, setpoint: i32) -> StepCommand {
        let want = self.steps32(setpoint);
        let delta = want.wrapping_sub(self.emitted);
        self.emitted = want;
        let pulses = delta.unsigned_abs();
        if pulses > self.max_pulses_per_tick {
            self.rate_faults = self.rate_faults.saturating_add(1);
        }
        StepCommand {
            pulses,
            forward: delta >= 0,
        }
    }

    /// Signed steps emitted.
    pub fn emitted(&self) -> i64 {
        self.emitted as i64
    }

    /// Ticks that exceeded the maximum step rate.
    pub fn rate_faults(&self) -> u32 {
        self.rate_faults
    }

    /// Counts per step.
    pub fn counts_per_step(&self) -> i32 {
        self.counts_per_step
    }
}

/// Maps the setpoint onto a 12-bit DAC: code 2048 at position 0, full scale at ±`span`
/// counts, clamped: `2048 + ⌊setpoint · k / 2³²⌋` with `k = ⌊2048 · 2³² / span⌋` precomputed
/// (one SMULL per tick instead of a 64-bit division; within one code of
/// `2048 + setpoint·2048/span`). Spans below 4096 counts act as 4096.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DacMirror {
    k: i32,
}

impl DacMirror {
    /// Mirror with full scale ±`span_counts`.
    pub const fn new(span_counts: i32) -> Self {
        let span = if span_counts < 4096 {
            4096
        } else {
            span_counts
        } as i64;
        DacMirror {
            k: ((2048i64 << 32) / span) as i32,
        }
    }

    /// DAC code (0..=4095) of `setpoint`.
    #[inline]
    pub fn code(&self, setpoint: i32) -> u16 {
        let c = 2048 + ((setpoint as i64 * self.k as i64) >> 32) as i32;
        c.clamp(0, 4095) as u16
    }
}

/// The limit a shaped reference breaks: its shaped peak step rate exceeds the drive's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepRateExceeded {
    /// Bound on the shaped setpoint's peak step rate (steps/s): reference peak speed × Σ|w| /
    /// step size.
    pub shaped_peak_steps_s: f32,
    /// The drive's maximum step rate (steps/s), `maxrate`.
    pub max_step_rate_hz: u32,
    /// Highest reference peak speed (nm/s) that passes with this shaper and step size.
    pub max_reference_speed_nm_s: f32,
}

/// **The step-rate rule** for any reference whose speed never exceeds `peak_speed_nm_s`
/// (nm/s): the shaped setpoint `y = Σ wᵢ·x(t − tᵢ)` moves at most `Σ|wᵢ|` times as fast as the
/// reference, so its step rate is bounded by `peak_speed_nm_s · Σ|wᵢ| / step_nm`; the reference
/// is refused when that bound exceeds `max_step_rate_hz` (the drive's `maxrate`, steps/s).
///
/// `taps` is the table the runtime shapes with (`Settings::tap_table(HISTORY_LEN)`), `step_nm`
/// the output step size (nm). Computed in f32, exactly as the runtime does when it answers
/// `err step-rate`.
pub fn check_step_rate(
    taps: &crate::engine::TapTable,
    step_nm: u32,
    max_step_rate_hz: u32,
    peak_speed_nm_s: f32,
) -> Result<(), StepRateExceeded> {
    check_step_rate_gain(
        taps.abs_weight_sum(),
        step_nm,
        max_step_rate_hz,
        peak_speed_nm_s,
    )
}

/// [`check_step_rate`] with the gain `Σ|w|` given (e.g. a transition's, see
/// [`crate::engine::EngineState::transition_gain`]).
pub fn check_step_rate_gain(
    gain: f32,
    step_nm: u32,
    max_step_rate_hz: u32,
    peak_speed_nm_s: f32,
) -> Result<(), StepRateExceeded> {
    let step = step_nm.max(1) as f32;
    let shaped_peak_steps_s = peak_speed_nm_s * gain / step;
    if shaped_peak_steps_s > max_step_rate_hz as f32 {
        return Err(StepRateExceeded {
            shaped_peak_steps_s,
            max_step_rate_hz,
            max_reference_speed_nm_s: max_step_rate_hz as f32 * step / gain,
        });
    }
    Ok(())
}

/// **The step-rate rule for a point-to-point move** (what `move` answers `err step-rate` with,
/// and what a planner must respect): a trapezoidal move over `distance_nm` (nm) with speed limit
/// `speed_nm_s` (nm/s) and acceleration `accel_nm_s2` (nm/s²) reaches the peak speed
/// [`crate::reference::trapezoid_peak_speed`]; [`check_step_rate`] decides.
///
/// Inputs as the console passes them (`move <mm> <mm/s> <mm/s²>` → `(mm·1e6) as f32`).
/// Returns the limit the move breaks, if any.
pub fn check_move_step_rate(
    taps: &crate::engine::TapTable,
    step_nm: u32,
    max_step_rate_hz: u32,
    distance_nm: u32,
    speed_nm_s: f32,
    accel_nm_s2: f32,
) -> Result<(), StepRateExceeded> {
    let v = crate::reference::trapezoid_peak_speed(distance_nm as f32, speed_nm_s, accel_nm_s2);
    check_step_rate(taps, step_nm, max_step_rate_hz, v)
}
