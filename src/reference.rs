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
    /// End of the constant-speed phase (s): t_acc + t_flat.
    t_flat_end: f32,
    /// Distance at the end of the acceleration phase: ½·v_peak·t_acc.
    s_acc: f32,
    /// Full distance: v_peak·(t_acc + t_flat).
    s_full: f32,
    /// Duration (s): 2·t_acc + t_flat.
    total_s: f32,
    /// After [`TrapezoidMove::stop`]: time (s), distance (counts) and speed (counts/s) at
    /// which the deceleration to rest began.
    stop: Option<(f32, f32, f32)>,
}

/// Why a move cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveError {
    /// Speed, acceleration or tick rate not finite or ≤ 0.
    Profile,
    /// Target outside ±[`POSITION_LIMIT`] counts.
    Range,
    /// The move would take more than 2³² ticks.
    TooLong,
}

/// Positions are limited to ±(2³⁰ − 1) counts (±1.07 m in nm) so that the i64 accumulation of
/// the fixed-point engine cannot overflow and the f32 path's differences fit an `i32`.
pub const POSITION_LIMIT: i32 = (1 << 30) - 1;

/// Peak speed (counts/s) of a trapezoidal move over `distance` (counts, ≥ 0) with speed limit
/// `speed` (counts/s) and acceleration `accel` (counts/s²): `speed` when the distance allows
/// it to be reached (`distance ≥ speed²/accel`), else the triangular profile's `√(distance·accel)`.
/// Exactly the f32 arithmetic [`TrapezoidMove::new`] uses.
pub fn trapezoid_peak_speed(distance: f32, speed: f32, accel: f32) -> f32 {
    if distance >= speed * speed / accel {
        speed
    } else {
        libm::sqrtf(distance * accel)
    }
}

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
        let v_peak = trapezoid_peak_speed(d, speed, accel);
        let (t_acc, t_flat) = if d >= speed * speed / accel {
            (speed / accel, (d - speed * speed / accel) / speed)
        } else {
            (v_peak / accel, 0.0)
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
            t_flat_end: t_acc + t_flat,
            s_acc: 0.5 * v_peak * t_acc,
            s_full: v_peak * (t_acc + t_flat),
            total_s,
            stop: None,
        })
    }

    /// Distance travelled (counts, ≥ 0) at time `t` (s) into the move.
    fn distance(&self, t: f32) -> f32 {
        let a = self.accel;
        if let Some((t0, s0, v0)) = self.stop {
            let (tau, t_stop) = (t - t0, v0 / a);
            let tau = if tau < 0.0 {
                0.0
            } else if tau > t_stop {
                t_stop
            } else {
                tau
            };
            return s0 + v0 * tau - 0.5 * a * tau * tau;
        }
        if t <= self.t_acc {
            0.5 * a * t * t
        } else if t <= self.t_flat_end {
            self.s_acc + self.v_peak * (t - self.t_acc)
        } else {
            let r = self.total_s - t;
            let r = if r > 0.0 { r } else { 0.0 };
            // distance = full − ½ a r²
            self.s_full - 0.5 * a * r * r
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
        let p = crate::engine::round_f32(self.start as f32 + self.dir * s);
        // Never overshoot the target because of f32 rounding.
        if self.dir > 0.0 {
            p.max(self.start).min(self.target)
        } else {
            p.min(self.start).max(self.target)
        }
    }

    /// True once the last sample (the target) has been produced.
    pub fn done(&self) -> bool {
        self.n >= self.n_total
    }

    /// Speed (counts/s, ≥ 0) at time `t` (s) into the (unstopped) profile.
    fn speed_at(&self, t: f32) -> f32 {
        if t <= self.t_acc {
            self.accel * t
        } else if t <= self.t_flat_end {
            self.v_peak
        } else {
            let v = self.accel * (self.total_s - t);
            if v > 0.0 {
                v
            } else {
                0.0
            }
        }
    }

    /// Ends the move early: from the present speed it decelerates at the move's own
    /// acceleration to rest and holds there (the new target). No effect once the planned
    /// deceleration has begun (it already ends at rest) or after a stop.
    pub fn stop(&mut self) {
        if self.done() || self.stop.is_some() {
            return;
        }
        let t0 = self.n as f32 * self.dt;
        if t0 >= self.t_flat_end {
            return;
        }
        let s0 = self.distance(t0);
        let v0 = self.speed_at(t0);
        let rest = s0 + 0.5 * v0 * v0 / self.accel;
        let p = self.start as f64 + self.dir as f64 * libm::round(rest as f64);
        self.target = p.clamp(-(POSITION_LIMIT as f64), POSITION_LIMIT as f64) as i32;
        self.stop = Some((t0, s0, v0));
        let ticks = libm::ceilf(v0 / self.accel / self.dt).max(1.0);
        self.n_total = self.n.saturating_add(ticks as u32);
    }

    /// Ticks until the last sample.
    pub fn remaining_ticks(&self) -> u32 {
        self.n_total - self.n.min(self.n_total)
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

/// Largest position (counts, nm) a console move or sweep may reach: ±1000 mm, the stroke.
pub const STROKE_LIMIT: i32 = 1_000_000_000;

/// Frequency law of a [`SineSweep`] (paper §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepKind {
    /// f(t) = f₀ + (f₁ − f₀)·t/T: constant rate β = (f₁ − f₀)/T Hz/s (eq. 33).
    Linear,
    /// f(t) = f₀·(f₁/f₀)^(t/T): constant rate β = log₂(f₁/f₀)·60/T octaves/min (eq. 34).
    Exponential,
}

impl SweepKind {
    /// `lin` or `exp`.
    pub fn name(self) -> &'static str {
        match self {
            SweepKind::Linear => "lin",
            SweepKind::Exponential => "exp",
        }
    }
}

/// Why a sweep cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepError {
    /// Frequencies, amplitude or duration not finite and > 0, or the duration above an hour.
    Profile,
    /// A frequency has fewer than [`SWEEP_MIN_TICKS_PER_PERIOD`] ticks per period.
    Nyquist,
    /// start ± amplitude leaves the stroke (±[`STROKE_LIMIT`]).
    Stroke,
}

/// A sweep's highest frequency must have at least this many ticks per period.
pub const SWEEP_MIN_TICKS_PER_PERIOD: f64 = 10.0;
/// Fraction of the sweep spent fading in (and again fading out): raised cosine.
pub const SWEEP_FADE_FRACTION: f64 = 0.1;

/// A sine sweep about the start position, sampled once per tick:
/// `x(t) = x₀ + A·g(t)·sin(2π·c(t))`, with the cycle count `c(t) = ∫f dt` in closed form
///
/// - linear (eq. 33): `c(t) = f₀t + (f₁ − f₀)t²/(2T)`;
/// - exponential (eq. 34): `c(t) = f₀T/ln r · (r^(t/T) − 1)`, `r = f₁/f₀`;
///
/// and a raised-cosine envelope `g` rising over the first and falling over the last
/// [`SWEEP_FADE_FRACTION`]·T, so the reference starts and ends at rest at x₀ (position and
/// velocity continuous). The last sample is x₀ exactly.
///
/// Per tick: a fixed number of f64 operations (c(t) from the tick index, no accumulation, so
/// no drift), one `sinf` and at most one `cosf`; no heap. Its speed never exceeds
/// [`SineSweep::peak_speed`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SineSweep {
    start: i32,
    amplitude: f32,
    kind: SweepKind,
    f0: f64,
    f1: f64,
    /// ln(f₁/f₀) (exponential).
    ln_ratio: f64,
    duration_s: f64,
    dt: f64,
    n: u32,
    n_total: u32,
    fade_ticks: u32,
    /// Set by [`SineSweep::stop`]: tick at which the fade-out began and the envelope then.
    stop: Option<(u32, f32)>,
}

impl SineSweep {
    /// Plans a sweep from `f0_hz` to `f1_hz` (either order) of `amplitude` counts about `start`
    /// lasting `duration_s`, sampled at `tick_rate_hz`.
    pub fn new(
        kind: SweepKind,
        start: i32,
        f0_hz: f64,
        f1_hz: f64,
        amplitude: f64,
        duration_s: f64,
        tick_rate_hz: f64,
    ) -> Result<Self, SweepError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(f0_hz)
            && pos(f1_hz)
            && pos(amplitude)
            && pos(duration_s)
            && duration_s <= 3600.0
            && pos(tick_rate_hz))
        {
            return Err(SweepError::Profile);
        }
        if f0_hz.max(f1_hz) * SWEEP_MIN_TICKS_PER_PERIOD > tick_rate_hz {
            return Err(SweepError::Nyquist);
        }
        if start.unsigned_abs() as f64 + amplitude > STROKE_LIMIT as f64 {
            return Err(SweepError::Stroke);
        }
        let n_total = libm::round(duration_s * tick_rate_hz);
        if !(2.0..4.0e9).contains(&n_total) {
            return Err(SweepError::Profile);
        }
        let n_total = n_total as u32;
        Ok(SineSweep {
            start,
            amplitude: amplitude as f32,
            kind,
            f0: f0_hz,
            f1: f1_hz,
            ln_ratio: libm::log(f1_hz / f0_hz),
            duration_s,
            dt: 1.0 / tick_rate_hz,
            n: 0,
            n_total,
            fade_ticks: (libm::round(SWEEP_FADE_FRACTION * n_total as f64) as u32).max(1),
            stop: None,
        })
    }

    /// Bound on the reference speed (counts/s): `A·(π/(2τ) + 2π·max(f₀, f₁))`, τ the fade time
    /// (|d/dt (g·sin 2πc)| ≤ |g′| + g·2πf and |g′| ≤ π/(2τ)). What the step-rate rule checks.
    pub fn peak_speed(&self) -> f32 {
        let tau = self.fade_ticks as f64 * self.dt;
        let pi = core::f64::consts::PI;
        (self.amplitude as f64 * (pi / (2.0 * tau) + 2.0 * pi * self.f0.max(self.f1))) as f32
    }

    /// Cycles completed at time `t` (s): c(t) above.
    fn cycles(&self, t: f64) -> f64 {
        match self.kind {
            SweepKind::Linear => self.f0 * t + 0.5 * (self.f1 - self.f0) * t * t / self.duration_s,
            SweepKind::Exponential => {
                if libm::fabs(self.ln_ratio) < 1e-12 {
                    self.f0 * t
                } else {
                    let k = self.ln_ratio / self.duration_s;
                    self.f0 * libm::expm1(k * t) / k
                }
            }
        }
    }

    /// Raised-cosine ramp 0 → 1 over `len` ticks, at tick `i`.
    fn ramp(i: u32, len: u32) -> f32 {
        if i >= len {
            return 1.0;
        }
        0.5 * (1.0 - libm::cosf(core::f32::consts::PI * i as f32 / len as f32))
    }

    fn envelope(&self, n: u32) -> f32 {
        let fade_out = Self::ramp(self.n_total - n.min(self.n_total), self.fade_ticks);
        let g = Self::ramp(n, self.fade_ticks).min(fade_out);
        match self.stop {
            None => g,
            Some((m, g_m)) => g_m * (1.0 - Self::ramp(n.saturating_sub(m), self.fade_ticks)),
        }
    }

    /// Advances one tick and returns the reference (counts); x₀ exactly once done.
    #[inline(never)]
    pub fn next(&mut self) -> i32 {
        if self.done() {
            return self.start;
        }
        self.n += 1;
        if self.done() {
            return self.start;
        }
        let c = self.cycles(self.n as f64 * self.dt);
        let frac = (c - libm::floor(c)) as f32;
        let s = libm::sinf(2.0 * core::f32::consts::PI * frac);
        let d = libm::roundf(self.amplitude * self.envelope(self.n) * s) as i64;
        (self.start as i64 + d).clamp(-(STROKE_LIMIT as i64), STROKE_LIMIT as i64) as i32
    }

    /// Ends the sweep early: the envelope fades from its present value to 0 over one fade time
    /// (never faster than the planned fade-out), then the reference holds x₀.
    pub fn stop(&mut self) {
        if self.stop.is_some() || self.done() {
            return;
        }
        if self.n_total - self.n <= self.fade_ticks {
            return; // already fading out
        }
        let g = self.envelope(self.n);
        self.stop = Some((self.n, g));
        self.n_total = self.n + self.fade_ticks;
    }

    /// True once the last sample (x₀) has been produced.
    pub fn done(&self) -> bool {
        self.n >= self.n_total
    }

    /// Ticks until the last sample.
    pub fn remaining_ticks(&self) -> u32 {
        self.n_total - self.n.min(self.n_total)
    }

    /// Ticks of the sweep.
    pub fn duration_ticks(&self) -> u32 {
        self.n_total
    }

    /// Start (= final) position (counts).
    pub fn start(&self) -> i32 {
        self.start
    }

    /// Frequency law.
    pub fn kind(&self) -> SweepKind {
        self.kind
    }
}
