//! The run-time state the timer interrupt owns: reference source, shaping engine, pending
//! parameter change, step/direction output and DAC mirror.
//!
//! **Parameter changes never jump the setpoint.** A new shaper (or numeric path, tick rate,
//! step size, source) is held as *pending* and takes effect on the first tick at which
//! (a) no internal move is running and (b) the reference has been still for at least the
//! active shaper's duration. At that moment every sample in the active shaper's window
//! equals the current reference `x`, so the old output is exactly `x` (both numeric paths
//! have exact unity DC gain); the history is then reset to `x`, so the new shaper's output
//! is exactly `x` too.
//!
//! Per tick the work is bounded: one reference sample, one O(taps) convolution, a constant
//! amount of bookkeeping. Nothing allocates or panics.

use crate::config::{Settings, Source};
use crate::engine::{Engine, NumericPath, TapTable};
use crate::output::{
    check_move_step_rate, DacMirror, StepCommand, StepOutput, StepRateExceeded,
};
use crate::reference::{
    MoveError, SineSweep, StepDirCounter, SweepError, SweepKind, TrapezoidMove, POSITION_LIMIT,
};

/// History length (samples): 16384 × 4 B = 64 KiB of RAM; 16.4 s of shaper duration at
/// 1 kHz, 1.6 s at 10 kHz.
pub const HISTORY_LEN: usize = 16384;

/// Setpoints the capture buffer holds (16 KiB): at 1 kHz and one sample in 10 ticks, 41 s.
pub const CAPTURE_LEN: usize = 4096;

/// Records the shaped setpoint every `decimation` ticks into a fixed buffer, so that a host
/// can read back the exact setpoints a move produced (`capture` / `dump` on the console).
#[derive(Clone, Debug)]
pub struct Capture {
    buf: [i32; CAPTURE_LEN],
    len: usize,
    decimation: u32,
    phase: u32,
    armed: bool,
}

impl Capture {
    const fn new() -> Self {
        Capture {
            buf: [0; CAPTURE_LEN],
            len: 0,
            decimation: 1,
            phase: 0,
            armed: false,
        }
    }

    /// Starts a new capture of one sample every `decimation` (≥ 1) ticks.
    pub fn arm(&mut self, decimation: u32) {
        self.len = 0;
        self.phase = 0;
        self.decimation = decimation.max(1);
        self.armed = true;
    }

    #[inline]
    fn record(&mut self, setpoint: i32) {
        if !self.armed {
            return;
        }
        if self.phase == 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = setpoint;
                    self.len += 1;
                }
                None => self.armed = false,
            }
        }
        self.phase += 1;
        if self.phase >= self.decimation {
            self.phase = 0;
        }
    }

    /// Samples recorded so far.
    pub fn samples(&self) -> &[i32] {
        self.buf.get(..self.len).unwrap_or(&[])
    }

    /// Ticks between samples.
    pub fn decimation(&self) -> u32 {
        self.decimation
    }

    /// Still recording.
    pub fn armed(&self) -> bool {
        self.armed && self.len < CAPTURE_LEN
    }
}

/// What the glue reads from the hardware each tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickInput {
    /// Raw 16-bit count of the timer in encoder (clock + direction) mode.
    pub stepdir_count: u16,
}

/// What the glue writes to the hardware each tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickOutput {
    /// Reference sample of this tick (nm).
    pub reference_counts: i32,
    /// Shaped servo setpoint (nm).
    pub setpoint_counts: i32,
    /// Step pulses to emit during the next tick.
    pub step: StepCommand,
    /// 12-bit DAC code mirroring the setpoint.
    pub dac_code: u16,
}

/// Parameters applied together at a safe moment.
#[derive(Clone, Debug, PartialEq)]
pub struct RunParams {
    /// The shaper on the tick grid.
    pub taps: TapTable,
    /// Numeric path.
    pub path: NumericPath,
    /// Tick rate (Hz).
    pub tick_rate_hz: u32,
    /// nm per output step.
    pub step_nm: u32,
    /// Maximum output step rate (steps/s).
    pub max_step_rate_hz: u32,
    /// nm per input count of the step/direction pass-through.
    pub input_nm_per_count: u32,
    /// Reference source.
    pub source: Source,
    /// DAC full scale ± (nm).
    pub dac_span_nm: i32,
}

impl RunParams {
    /// Validates `settings` and builds the parameters for a history of [`HISTORY_LEN`].
    pub fn from_settings(settings: &Settings) -> Result<Self, crate::config::ConfigError> {
        let taps = settings.tap_table(HISTORY_LEN)?;
        Ok(RunParams {
            taps,
            path: settings.path,
            tick_rate_hz: settings.tick_rate_hz,
            step_nm: settings.step_nm,
            max_step_rate_hz: settings.max_step_rate_hz,
            input_nm_per_count: settings.input_nm_per_count,
            source: settings.source,
            dac_span_nm: (settings.dac_span_mm as f64 * 1e6) as i32,
        })
    }

    const fn default_const() -> Self {
        RunParams {
            taps: TapTable::identity(),
            path: NumericPath::Fixed,
            tick_rate_hz: 1000,
            step_nm: 1000,
            max_step_rate_hz: 200_000,
            input_nm_per_count: 1000,
            source: Source::Internal,
            dac_span_nm: 100_000_000,
        }
    }

    /// [`check_move_step_rate`] with these parameters' step size and maximum step rate, for
    /// the table `taps` (the runtime passes the table it shapes with).
    pub fn check_move_step_rate(
        &self,
        taps: &TapTable,
        distance_nm: u32,
        speed_nm_s: f32,
        accel_nm_s2: f32,
    ) -> Result<(), StepRateExceeded> {
        check_move_step_rate(
            taps,
            self.step_nm,
            self.max_step_rate_hz,
            distance_nm,
            speed_nm_s,
            accel_nm_s2,
        )
    }

    fn max_pulses_per_tick(&self) -> u32 {
        (self.max_step_rate_hz / self.tick_rate_hz.max(1)).max(1)
    }
}

/// Why a run-time request was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RuntimeError {
    /// A move is running (or the reference is not still, for `zero`).
    Busy,
    /// Moves are refused while the source is the step/direction pass-through.
    Source,
    /// The move profile is invalid or out of range.
    Move(MoveError),
    /// The sweep is invalid, above the tick's frequency limit or leaves the stroke.
    Sweep(SweepError),
    /// The shaped move would exceed the drive's maximum step rate (see
    /// [`crate::output::check_move_step_rate`]).
    StepRate(StepRateExceeded),
}

impl RuntimeError {
    /// Short code for the console.
    pub fn code(&self) -> &'static str {
        match self {
            RuntimeError::Busy => "busy",
            RuntimeError::Source => "source",
            RuntimeError::Move(_) | RuntimeError::Sweep(_) => "range",
            RuntimeError::StepRate(_) => "step-rate",
        }
    }

    /// Message for the console.
    pub fn message(&self) -> &'static str {
        match self {
            RuntimeError::Busy => "a move is running or the reference is not still",
            RuntimeError::Source => "moves need source internal",
            RuntimeError::Move(MoveError::Profile) => {
                "speed and acceleration must be finite and > 0"
            }
            RuntimeError::Move(MoveError::Range) => "target outside +-1073 mm",
            RuntimeError::Move(MoveError::TooLong) => "move too long",
            RuntimeError::Sweep(SweepError::Profile) => {
                "frequencies, amplitude and duration must be finite and > 0, duration <= 3600 s"
            }
            RuntimeError::Sweep(SweepError::Nyquist) => {
                "sweep frequency above tick rate / 10 (fewer than 10 ticks per period)"
            }
            RuntimeError::Sweep(SweepError::Stroke) => {
                "position +- amplitude leaves the stroke (+-1000 mm)"
            }
            RuntimeError::StepRate(_) => "shaped move would exceed the maximum step rate",
        }
    }
}

/// What the internal source is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion {
    /// Holding the reference.
    Idle,
    /// A point-to-point move.
    Move(TrapezoidMove),
    /// A sine sweep.
    Sweep(SineSweep),
}

/// A snapshot for `status`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Status {
    /// Ticks since start.
    pub ticks: u64,
    /// Current reference (nm).
    pub reference_counts: i32,
    /// Current shaped setpoint (nm).
    pub setpoint_counts: i32,
    /// Signed steps emitted.
    pub emitted_steps: i64,
    /// An internal move is running.
    pub moving: bool,
    /// A parameter change waits for the reference to be still.
    pub pending: bool,
    /// Ticks the reference has been still.
    pub still_ticks: u32,
    /// Ticks that exceeded the maximum step rate.
    pub step_rate_faults: u32,
    /// Tick rate in force (Hz).
    pub tick_rate_hz: u32,
    /// Numeric path in force.
    pub path: NumericPath,
    /// Taps in force.
    pub taps: usize,
    /// Duration of the shaper in force (ticks).
    pub duration_ticks: u32,
    /// Source in force.
    pub source: Source,
    /// Parameter changes applied since start.
    pub applied_changes: u32,
}

/// The interrupt-owned state. `const`-constructible so it can live in a `static`.
#[derive(Clone, Debug)]
pub struct Runtime {
    engine: Engine<HISTORY_LEN>,
    params: RunParams,
    pending: Option<RunParams>,
    reference: i32,
    still_ticks: u32,
    motion: Motion,
    stepdir: StepDirCounter,
    /// reference = stepdir_offset + input steps × input_nm_per_count (pass-through).
    stepdir_offset: i64,
    steps: StepOutput,
    dac: DacMirror,
    setpoint: i32,
    ticks: u64,
    applied_changes: u32,
    capture: Capture,
}

impl Default for Runtime {
    fn default() -> Self {
        Self::new()
    }
}

impl Runtime {
    /// Identity shaping at position 0 with default parameters.
    pub const fn new() -> Self {
        let params = RunParams::default_const();
        Runtime {
            engine: Engine::new(0),
            steps: StepOutput::new(1000, 200, 0),
            dac: DacMirror::new(100_000_000),
            params,
            pending: None,
            reference: 0,
            still_ticks: u32::MAX,
            motion: Motion::Idle,
            stepdir: StepDirCounter::new(0),
            stepdir_offset: 0,
            setpoint: 0,
            ticks: 0,
            applied_changes: 0,
            capture: Capture::new(),
        }
    }

    /// Queues parameters; they take effect at the next safe tick (see the module docs).
    /// A newer request replaces an older pending one.
    pub fn request(&mut self, params: RunParams) {
        self.pending = Some(params);
    }

    /// Applies parameters immediately, at boot, before the first tick.
    pub fn configure_at_boot(&mut self, params: RunParams, stepdir_count: u16) {
        self.stepdir = StepDirCounter::new(stepdir_count);
        self.apply(params);
    }

    fn apply(&mut self, p: RunParams) {
        if p.source == Source::StepDir {
            self.stepdir_offset =
                self.reference as i64 - self.stepdir.steps() * p.input_nm_per_count as i64;
        }
        self.engine.install(p.taps.clone(), p.path, self.reference);
        self.steps = StepOutput::new(p.step_nm as i32, p.max_pulses_per_tick(), self.setpoint);
        self.dac = DacMirror::new(p.dac_span_nm);
        self.params = p;
        self.applied_changes = self.applied_changes.wrapping_add(1);
    }

    /// Starts a point-to-point move to `target` (nm) at `speed` (nm/s) and `accel` (nm/s²).
    /// Returns the move's duration in ticks (without the shaper's delay).
    pub fn start_move(&mut self, target: i32, speed: f32, accel: f32) -> Result<u32, RuntimeError> {
        if self.params.source != Source::Internal {
            return Err(RuntimeError::Source);
        }
        if self.motion != Motion::Idle {
            return Err(RuntimeError::Busy);
        }
        let m = TrapezoidMove::new(
            self.reference,
            target,
            speed,
            accel,
            self.params.tick_rate_hz as f32,
        )
        .map_err(RuntimeError::Move)?;
        self.params
            .check_move_step_rate(
                self.engine.taps(),
                (target as i64 - self.reference as i64).unsigned_abs() as u32,
                speed,
                accel,
            )
            .map_err(RuntimeError::StepRate)?;
        let n = m.duration_ticks();
        self.motion = Motion::Move(m);
        Ok(n)
    }

    /// Starts a sine sweep (paper eqs. 33–34, [`SineSweep`]) about the present reference from
    /// `f0_hz` to `f1_hz` with amplitude `amplitude_nm` lasting `duration_s`. Checked before it
    /// starts: the stroke, the tick's frequency limit, and the step-rate rule on the sweep's
    /// peak speed ([`crate::output::check_step_rate`]). Returns its duration in ticks.
    pub fn start_sweep(
        &mut self,
        kind: SweepKind,
        f0_hz: f64,
        f1_hz: f64,
        amplitude_nm: f64,
        duration_s: f64,
    ) -> Result<u32, RuntimeError> {
        if self.params.source != Source::Internal {
            return Err(RuntimeError::Source);
        }
        if self.motion != Motion::Idle {
            return Err(RuntimeError::Busy);
        }
        let sw = SineSweep::new(
            kind,
            self.reference,
            f0_hz,
            f1_hz,
            amplitude_nm,
            duration_s,
            self.params.tick_rate_hz as f64,
        )
        .map_err(RuntimeError::Sweep)?;
        crate::output::check_step_rate(
            self.engine.taps(),
            self.params.step_nm,
            self.params.max_step_rate_hz,
            sw.peak_speed(),
        )
        .map_err(RuntimeError::StepRate)?;
        let n = sw.duration_ticks();
        self.motion = Motion::Sweep(sw);
        Ok(n)
    }

    /// Ends a running move (decelerating at its acceleration, then holding) or sweep (fading
    /// its amplitude out over its fade time, back to its start). Returns the ticks until the
    /// reference is at rest (0 when nothing runs).
    pub fn stop(&mut self) -> u32 {
        match &mut self.motion {
            Motion::Idle => 0,
            Motion::Move(m) => {
                m.stop();
                m.remaining_ticks()
            }
            Motion::Sweep(s) => {
                s.stop();
                s.remaining_ticks()
            }
        }
    }

    /// Declares the current position to be 0 (no pulses are emitted). Refused unless the
    /// reference is still for the active shaper's duration and no move runs.
    pub fn zero(&mut self) -> Result<(), RuntimeError> {
        if self.motion != Motion::Idle || self.still_ticks < self.engine.taps().duration_ticks() {
            return Err(RuntimeError::Busy);
        }
        self.reference = 0;
        self.setpoint = 0;
        self.stepdir_offset = -self.stepdir.steps() * self.params.input_nm_per_count as i64;
        self.engine.reset(0);
        self.steps = StepOutput::new(
            self.params.step_nm as i32,
            self.params.max_pulses_per_tick(),
            0,
        );
        Ok(())
    }

    /// One timer tick. Bounded work, no allocation, no panic.
    pub fn tick(&mut self, input: &TickInput) -> TickOutput {
        self.ticks = self.ticks.wrapping_add(1);
        let steps_in = self.stepdir.update(input.stepdir_count);
        let x = match self.params.source {
            Source::Internal => match &mut self.motion {
                Motion::Idle => self.reference,
                Motion::Move(m) => {
                    let x = m.next();
                    if m.done() {
                        self.motion = Motion::Idle;
                    }
                    x
                }
                Motion::Sweep(s) => {
                    let x = s.next();
                    if s.done() {
                        self.motion = Motion::Idle;
                    }
                    x
                }
            },
            Source::StepDir => {
                let p = self.stepdir_offset + steps_in * self.params.input_nm_per_count as i64;
                p.clamp(-(POSITION_LIMIT as i64), POSITION_LIMIT as i64) as i32
            }
        };
        if x == self.reference {
            self.still_ticks = self.still_ticks.saturating_add(1);
        } else {
            self.still_ticks = 0;
        }
        self.reference = x;
        if self.pending.is_some()
            && self.motion == Motion::Idle
            && self.still_ticks >= self.engine.taps().duration_ticks()
        {
            if let Some(p) = self.pending.take() {
                self.apply(p);
            }
        }
        self.setpoint = self.engine.tick(x);
        self.capture.record(self.setpoint);
        TickOutput {
            reference_counts: x,
            setpoint_counts: self.setpoint,
            step: self.steps.update(self.setpoint),
            dac_code: self.dac.code(self.setpoint),
        }
    }

    /// The setpoint capture buffer.
    pub fn capture(&self) -> &Capture {
        &self.capture
    }

    /// Starts capturing one setpoint every `decimation` ticks.
    pub fn arm_capture(&mut self, decimation: u32) {
        self.capture.arm(decimation);
    }

    /// Tick rate in force (Hz); the glue reprograms its timer when this changes.
    pub fn tick_rate_hz(&self) -> u32 {
        self.params.tick_rate_hz
    }

    /// Parameters in force.
    pub fn params(&self) -> &RunParams {
        &self.params
    }

    /// Pending parameters, if any.
    pub fn pending(&self) -> Option<&RunParams> {
        self.pending.as_ref()
    }

    /// The engine (for inspection).
    pub fn engine(&self) -> &Engine<HISTORY_LEN> {
        &self.engine
    }

    /// The step output (for inspection).
    pub fn step_output(&self) -> &StepOutput {
        &self.steps
    }

    /// A snapshot for the console's `status`.
    pub fn status(&self) -> Status {
        Status {
            ticks: self.ticks,
            reference_counts: self.reference,
            setpoint_counts: self.setpoint,
            emitted_steps: self.steps.emitted(),
            moving: self.motion != Motion::Idle,
            pending: self.pending.is_some(),
            still_ticks: self.still_ticks,
            step_rate_faults: self.steps.rate_faults(),
            tick_rate_hz: self.params.tick_rate_hz,
            path: self.params.path,
            taps: self.engine.taps().taps().len(),
            duration_ticks: self.engine.taps().duration_ticks(),
            source: self.params.source,
            applied_changes: self.applied_changes,
        }
    }
}
