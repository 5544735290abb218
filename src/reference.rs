//! Reference sources: the firmware's own point-to-point moves, and the pass-through of an
//! upstream step/direction stream.

/// A point-to-point move with a trapezoidal velocity profile (triangular when the distance
/// is too short to reach the speed), sampled once per tick.
///
/// Positions are integer counts (nm); the profile is evaluated in closed form per phase in
/// f32 relative to the phase start (no accumulation, so no drift), rounded to counts, and the
/// last sample is exactly the target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrapezoidMove {
    start: i32,
    target: i32,
    /// +1 or −1.
    dir: f32,
    accel: f32,
    /// Peak speed reached (counts/s).
    v_peak: f32,
    /// Duration of the acceleration (= deceleration) phase, s.
    t_acc: f32,
    /// Duration of the constant-speed phase, s.
    t_flat: f32,
    /// Tick period, s.
    dt: f32,
    /// Ticks elapsed.
    n: u32,
    /// Total ticks of the move (last sample = target).
    n_total: u32,
}

/// Why a move cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveError {
    /// Speed, acceleration or tick rate not finite or ≤ 0.
    Profile,
    /// Target outside ±2³⁰ counts.
    Range,
    /// The move would take more than 2³² ticks.
    TooLong,
}

/// Positions are limited to ±2³⁰ counts (±1.07 m in nm) so that the i64 accumulation of the
/// fixed-point engine cannot overflow.
pub const POSITION_LIMIT: i32 = 1 << 30;

impl TrapezoidMove {
    /// Plans a move from `start` to `target` (counts) with peak speed `speed` (counts/s)
    /// and acceleration `accel` (counts/s²), sampled at `tick_rate_hz`.
    pub fn new(
        start: i32,
        target: i32,
        speed: f32,
        accel: f32,
        tick_rate_hz: f32,
    ) -> Result<Self, MoveError> {
        if !(speed.is_finite() && speed > 0.0 && accel.is_finite() && accel > 0.0)
            || !(tick_rate_hz.is_finite() && tick_rate_hz > 0.0)
        {
            return Err(MoveError::Profile);
        }
        if target.unsigned_abs() > POSITION_LIMIT as u32
            || start.unsigned_abs() > POSITION_LIMIT as u32
        {
            return Err(MoveError::Range);
        }
        let d = (target as i64 - start as i64).unsigned_abs() as f32;
        let (v_peak, t_acc, t_flat) = if d >= speed * speed / accel {
            (speed, speed / accel, (d - speed * speed / accel) / speed)
        } else {
            let v = libm::sqrtf(d * accel);
            (v, v / accel, 0.0)
        };
        let total_s = 2.0 * t_acc + t_flat;
        let n_total = libm::ceilf(total_s * tick_rate_hz);
        if !(n_total < 4.0e9) {
            return Err(MoveError::TooLong);
        }
        Ok(TrapezoidMove {
            start,
            target,
            dir: if target >= start { 1.0 } else { -1.0 },
            accel,
            v_peak,
            t_acc,
            t_flat,
            dt: 1.0 / tick_rate_hz,
            n: 0,
            n_total: n_total as u32,
        })
    }

    /// Distance travelled (counts, ≥ 0) at time `t` (s) into the move.
    fn distance(&self, t: f32) -> f32 {
        let a = self.accel;
        if t <= self.t_acc {
            0.5 * a * t * t
        } else if t <= self.t_acc + self.t_flat {
            0.5 * self.v_peak * self.t_acc + self.v_peak * (t - self.t_acc)
        } else {
            let total = 2.0 * self.t_acc + self.t_flat;
            let r = (total - t).max(0.0);
            // distance = full − ½ a r²
            let full = self.v_peak * (self.t_acc + self.t_flat);
            full - 0.5 * a * r * r
        }
    }

    /// Advances one tick and returns the reference (counts). After the last tick the
    /// target, exactly.
    pub fn next(&mut self) -> i32 {
        if self.n >= self.n_total {
            return self.target;
        }
        self.n += 1;
        if self.n >= self.n_total {
            return self.target;
        }
        let s = self.distance(self.n as f32 * self.dt);
        let p = self.start as f32 + self.dir * s;
        let p = libm::roundf(p) as i64;
        // Never overshoot the target because of f32 rounding.
        let (lo, hi) = if self.target >= self.start {
            (self.start, self.target)
        } else {
            (self.target, self.start)
        };
        p.clamp(lo as i64, hi as i64) as i32
    }

    /// True once the last sample (the target) has been produced.
    pub fn done(&self) -> bool {
        self.n >= self.n_total
    }

    /// Target (counts).
    pub fn target(&self) -> i32 {
        self.target
    }

    /// Peak speed of the profile (counts/s).
    pub fn peak_speed(&self) -> f32 {
        self.v_peak
    }

    /// Duration of the move in ticks.
    pub fn duration_ticks(&self) -> u32 {
        self.n_total
    }
}

/// Extends the 16-bit count of a timer in encoder (clock + direction) mode, which counts the
/// upstream controller's step/direction pulses, to a position in counts.
///
/// Correct as long as fewer than 32768 input steps arrive between two ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepDirCounter {
    last_raw: u16,
    /// Accumulated input steps since the last re-base.
    steps: i64,
}

impl StepDirCounter {
    /// A counter whose current raw timer value is `raw`.
    pub const fn new(raw: u16) -> Self {
        StepDirCounter {
            last_raw: raw,
            steps: 0,
        }
    }

    /// Takes the timer's raw count; returns the input steps accumulated since creation.
    #[inline]
    pub fn update(&mut self, raw: u16) -> i64 {
        let delta = raw.wrapping_sub(self.last_raw) as i16;
        self.last_raw = raw;
        self.steps += delta as i64;
        self.steps
    }

    /// Input steps accumulated so far.
    pub fn steps(&self) -> i64 {
        self.steps
    }
}
