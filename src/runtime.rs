//! The run-time state the timer interrupt owns: reference source, shaping engine, pending
//! parameter change, step/direction output and DAC mirror.
//!
//! **Parameter changes never jump the setpoint.**
//! - A change of the shaper table alone (`mode`, `clear`, `custom`, `shaping on|off`; with
//!   `maxrate` and the DAC span, which need no care) applies at the **next tick**, moving or
//!   not, with the internal source or the step/direction pass-through, by superposition
//!   ([`crate::engine`]): the old table finishes shaping the reference up to the switch, the new
//!   one shapes what comes after. It is refused when the transition would exceed the per-tick
//!   tap budget ([`crate::engine::TAP_BUDGET`] taps over all tables in flight).
//! - A change of the tick rate, numeric path, step size, source or input resolution
//!   **waits for standstill**: it takes effect on the first tick at which no internal move
//!   runs and the reference has been still for the longest duration of the tables in flight.
//!   Then every sample in every window equals the current reference `x`, so the output is
//!   exactly `x` (both numeric paths have exact unity DC gain); the history is reset to `x`,
//!   so the new output is exactly `x` too. [`Status::waiting`] says what waits.
//!
//! Per tick the work is bounded: one reference sample, the convolution of the tables in
//! flight (≤ [`crate::engine::TAP_BUDGET`] taps), a constant amount of bookkeeping. Nothing allocates or
//! panics.
//!
//! **Memory.** The history and capture buffers (80 KiB) live in [`Buffers`], apart from the
//! small state, so that the firmware keeps them in `.bss` and initialises them in place
//! ([`Runtime::init_in_place`]) instead of copying an 85 KiB zero image from flash.

use crate::config::{Settings, Source};
use crate::engine::{EngineState, NumericPath, SwitchError, TapTable};
use crate::output::{check_move_step_rate, DacMirror, StepCommand, StepOutput, StepRateExceeded};
use crate::reference::{
    MoveError, SineSweep, StepDirCounter, SweepError, SweepKind, TrapezoidMove, POSITION_LIMIT,
};
use crate::watch::ring::SetpointRing;

/// History length (samples): 16384 × 4 B = 64 KiB of RAM; 16.4 s of shaper duration at
/// 1 kHz, 1.6 s at 10 kHz.
pub const HISTORY_LEN: usize = 16384;

/// Setpoints the capture buffer holds (16 KiB): at 1 kHz and one sample in 10 ticks, 41 s.
pub const CAPTURE_LEN: usize = 4096;

/// The runtime's large buffers: reference history and setpoint capture. All-zero is their
/// initial state, so a `static` of them sits in `.bss`.
#[derive(Clone, Debug)]
pub struct Buffers {
    history: [i32; HISTORY_LEN],
    capture: [i32; CAPTURE_LEN],
    /// Decimated setpoints for the drift watch ([`crate::watch`]), off until armed.
    watch: SetpointRing,
}

impl Buffers {
    const fn new() -> Self {
        Buffers {
            history: [0; HISTORY_LEN],
            capture: [0; CAPTURE_LEN],
            watch: SetpointRing::new(),
        }
    }
}

/// Records the shaped setpoint every `decimation` ticks into the capture buffer, so that a
/// host can read back the exact setpoints a move produced (`capture` / `dump` on the console).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct CaptureState {
    len: usize,
    decimation: u32,
    phase: u32,
    armed: bool,
}

impl CaptureState {
    const fn new() -> Self {
        CaptureState {
            len: 0,
            decimation: 1,
            phase: 0,
            armed: false,
        }
    }

    fn arm(&mut self, decimation: u32) {
        self.len = 0;
        self.phase = 0;
        self.decimation = decimation.max(1);
        self.armed = true;
    }

    #[inline(always)]
    fn record(&mut self, buf: &mut [i32; CAPTURE_LEN], setpoint: i32) {
        if !self.armed {
            return;
        }
        if self.phase == 0 {
            match buf.get_mut(self.len) {
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
}

/// A view of the setpoint capture.
#[derive(Clone, Copy, Debug)]
pub struct Capture<'a> {
    state: CaptureState,
    buf: &'a [i32; CAPTURE_LEN],
}

impl Capture<'_> {
    /// Samples recorded so far.
    pub fn samples(&self) -> &[i32] {
        self.buf.get(..self.state.len).unwrap_or(&[])
    }

    /// Ticks between samples.
    pub fn decimation(&self) -> u32 {
        self.state.decimation
    }

    /// Still recording.
    pub fn armed(&self) -> bool {
        self.state.armed && self.state.len < CAPTURE_LEN
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

    /// Output pulses one tick may carry at the maximum step rate.
    pub fn max_pulses_per_tick(&self) -> u32 {
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
    /// A shaper change now would exceed the per-tick tap budget or the tables in flight.
    Switch(SwitchError),
}

impl RuntimeError {
    /// Short code for the console.
    pub fn code(&self) -> &'static str {
        match self {
            RuntimeError::Busy => "busy",
            RuntimeError::Source => "source",
            RuntimeError::Move(_) | RuntimeError::Sweep(_) => "range",
            RuntimeError::StepRate(_) => "step-rate",
            RuntimeError::Switch(_) => "budget",
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
            RuntimeError::StepRate(_) => {
                "the shaped reference would exceed the maximum step rate (maxrate)"
            }
            RuntimeError::Switch(SwitchError::Budget { .. }) => {
                "old and new shaper together would exceed the tap budget of 256 taps per tick; \
                 retry when the running transition has ended"
            }
            RuntimeError::Switch(SwitchError::Stages) => {
                "4 shapers already in flight; retry when a transition has ended"
            }
            RuntimeError::Switch(SwitchError::TooLong) => "shaper longer than the history",
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

/// What waits for standstill (see the module docs); all false when nothing does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Waiting {
    /// Tick rate change.
    pub tick_rate: bool,
    /// Numeric path change.
    pub path: bool,
    /// Output step size change.
    pub step: bool,
    /// Source change.
    pub source: bool,
    /// Input resolution change.
    pub input: bool,
    /// The shaper table (it comes with one of the above, so it waits with it).
    pub shaper: bool,
}

impl Waiting {
    fn between(old: &RunParams, new: &RunParams, old_taps: &TapTable) -> Waiting {
        let mut w = Waiting {
            tick_rate: old.tick_rate_hz != new.tick_rate_hz,
            path: old.path != new.path,
            step: old.step_nm != new.step_nm,
            source: old.source != new.source,
            input: old.input_nm_per_count != new.input_nm_per_count,
            shaper: false,
        };
        w.shaper = w.any() && *old_taps != new.taps;
        w
    }

    /// Something waits.
    pub fn any(&self) -> bool {
        self.tick_rate || self.path || self.step || self.source || self.input || self.shaper
    }

    /// Comma-separated names (`rate,path,step,source,input,shaper`), or `none`.
    pub fn names(&self) -> WaitingNames {
        WaitingNames(*self)
    }
}

/// Display of [`Waiting::names`].
pub struct WaitingNames(Waiting);

impl core::fmt::Display for WaitingNames {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let w = self.0;
        let mut first = true;
        for (on, name) in [
            (w.tick_rate, "rate"),
            (w.path, "path"),
            (w.step, "step"),
            (w.source, "source"),
            (w.input, "input"),
            (w.shaper, "shaper"),
        ] {
            if on {
                if !first {
                    f.write_str(",")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

/// When a requested change takes effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Applies {
    /// At the next tick (shaper table by superposition, or nothing that needs care).
    NextTick,
    /// At standstill: see [`Waiting`].
    WhenStill,
}

impl Applies {
    /// `next-tick` or `when-still`.
    pub fn name(self) -> &'static str {
        match self {
            Applies::NextTick => "next-tick",
            Applies::WhenStill => "when-still",
        }
    }
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
    /// An internal move or sweep is running.
    pub moving: bool,
    /// A parameter change is pending (next tick or at standstill).
    pub pending: bool,
    /// What of the pending change waits for standstill.
    pub waiting: Waiting,
    /// Shaper tables in flight (1 = steady, more during a mid-move change).
    pub stages: usize,
    /// Taps evaluated per tick now (≤ [`crate::engine::TAP_BUDGET`]).
    pub taps_in_flight: usize,
    /// Ticks the reference has been still (0 until it has been still for a tick).
    pub still_ticks: u32,
    /// Ticks that exceeded the maximum step rate.
    pub step_rate_faults: u32,
    /// Tick rate in force (Hz).
    pub tick_rate_hz: u32,
    /// Numeric path in force.
    pub path: NumericPath,
    /// Taps of the newest table.
    pub taps: usize,
    /// Duration of the newest table (ticks).
    pub duration_ticks: u32,
    /// Source in force.
    pub source: Source,
    /// Parameter changes applied since start.
    pub applied_changes: u32,
}

/// The interrupt-owned state: [`Buffers`] plus the small state. `const`-constructible for
/// host use; the firmware uses [`Runtime::init_in_place`] on a zeroed `static`.
#[derive(Clone, Debug)]
pub struct Runtime {
    bufs: Buffers,
    st: State,
}

/// Everything but the buffers.
#[derive(Clone, Debug)]
struct State {
    engine: EngineState<HISTORY_LEN>,
    params: RunParams,
    pending: Option<(RunParams, Applies)>,
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
    capture: CaptureState,
}

impl Default for Runtime {
    fn default() -> Self {
        Self::new()
    }
}

impl State {
    const fn new() -> Self {
        let params = RunParams::default_const();
        State {
            engine: EngineState::new(0),
            steps: StepOutput::new(1000, 200, 0),
            dac: DacMirror::new(100_000_000),
            params,
            pending: None,
            reference: 0,
            still_ticks: 0,
            motion: Motion::Idle,
            stepdir: StepDirCounter::new(0),
            stepdir_offset: 0,
            setpoint: 0,
            ticks: 0,
            applied_changes: 0,
            capture: CaptureState::new(),
        }
    }

    /// Full apply at standstill or boot: installs the table and resets the history to the
    /// reference.
    fn apply(&mut self, p: RunParams) {
        if p.source == Source::StepDir {
            self.stepdir_offset =
                self.reference as i64 - self.stepdir.steps() * p.input_nm_per_count as i64;
        }
        if self
            .engine
            .install(p.taps.clone(), p.path, self.reference)
            .is_err()
        {
            let _ = self
                .engine
                .install(TapTable::identity(), p.path, self.reference);
        }
        self.steps = StepOutput::new(p.step_nm as i32, p.max_pulses_per_tick(), self.setpoint);
        self.dac = DacMirror::new(p.dac_span_nm);
        self.params = p;
        self.applied_changes = self.applied_changes.wrapping_add(1);
    }

    /// Applies the pending change if it is due (next tick, or at standstill). Out of line:
    /// rare, and it moves whole tap tables.
    /// `stepdir_count` is this tick's raw input count (the pass-through counts from it when
    /// it becomes the source: the input is only counted while it is the source).
    #[inline(never)]
    fn apply_pending(&mut self, stepdir_count: u16) {
        let ready = match &self.pending {
            None => false,
            Some((_, Applies::NextTick)) => true,
            Some((_, Applies::WhenStill)) => {
                self.motion == Motion::Idle && self.still_ticks >= self.engine.settle_ticks()
            }
        };
        if !ready {
            return;
        }
        if let Some((p, applies)) = self.pending.take() {
            match applies {
                Applies::WhenStill => {
                    if p.source == Source::StepDir && self.params.source != Source::StepDir {
                        self.stepdir = StepDirCounter::new(stepdir_count);
                    }
                    self.apply(p)
                }
                Applies::NextTick => {
                    if let Err(p) = self.apply_now(p) {
                        self.pending = Some((p, applies));
                    }
                }
            }
        }
    }

    /// Next-tick apply: the table by superposition, the step-rate limit and DAC span as they
    /// are. Gives `p` back (nothing changed) if the engine refuses the switch.
    #[allow(clippy::result_large_err)] // the parameters themselves, handed back to stay pending
    fn apply_now(&mut self, p: RunParams) -> Result<(), RunParams> {
        if *self.engine.taps() != p.taps && self.engine.switch(p.taps.clone()).is_err() {
            return Err(p);
        }
        self.steps.set_max_pulses_per_tick(p.max_pulses_per_tick());
        self.dac = DacMirror::new(p.dac_span_nm);
        self.params = p;
        self.applied_changes = self.applied_changes.wrapping_add(1);
        Ok(())
    }
}

impl Runtime {
    /// Identity shaping at position 0 with default parameters.
    pub const fn new() -> Self {
        Runtime {
            bufs: Buffers::new(),
            st: State::new(),
        }
    }

    /// Initialises a runtime in place in `slot` (e.g. a zeroed `static`) without building it
    /// on the stack or copying an image: the buffers are zero-filled where they are, the
    /// small state (~10 KiB) is written by value. Returns the initialised runtime.
    #[allow(unsafe_code)]
    pub fn init_in_place(slot: &mut core::mem::MaybeUninit<Runtime>) -> &mut Runtime {
        let p = slot.as_mut_ptr();
        // SAFETY: `p` is valid for writes and properly aligned (it comes from a
        // `&mut MaybeUninit<Runtime>`). Both fields of `Runtime` are written before the
        // reference is created: `bufs` (arrays of i32 and the watch's ring of i32/u32, for
        // which all-zero bytes are a valid value: empty and off) by `write_bytes`, `st` by value. `addr_of_mut!` creates no intermediate
        // reference to uninitialised memory.
        unsafe {
            core::ptr::addr_of_mut!((*p).bufs).write_bytes(0, 1);
            core::ptr::addr_of_mut!((*p).st).write(State::new());
            &mut *p
        }
    }

    /// Requests new parameters. A change of the shaper table (and of `maxrate` / DAC span)
    /// applies at the next tick by superposition, moving or not; one that also changes the
    /// tick rate, numeric path, step size, source or input resolution waits for standstill
    /// (module docs). A newer request replaces an older pending one.
    ///
    /// Errors (nothing changes): [`RuntimeError::StepRate`] if a move or sweep is running and
    /// the transition could exceed the maximum step rate
    /// ([`crate::engine::EngineState::transition_gain`] × its peak speed);
    /// [`RuntimeError::Switch`] if the transition would exceed the
    /// per-tick tap budget ([`crate::engine::TAP_BUDGET`]) or the number of tables in flight.
    pub fn request(&mut self, params: RunParams) -> Result<Applies, RuntimeError> {
        let st = &mut self.st;
        let waiting = Waiting::between(&st.params, &params, st.engine.taps());
        let applies = if waiting.any() {
            Applies::WhenStill
        } else {
            if *st.engine.taps() != params.taps {
                st.engine
                    .can_switch(&params.taps)
                    .map_err(RuntimeError::Switch)?;
                // During a move or sweep the transition may move the setpoint faster than
                // either table alone: the step-rate rule with the transition's gain.
                let peak = match &st.motion {
                    Motion::Idle => None,
                    Motion::Move(m) => Some(m.peak_speed()),
                    Motion::Sweep(s) => Some(s.peak_speed()),
                };
                if let Some(v) = peak {
                    let gain = st.engine.transition_gain(&params.taps);
                    crate::output::check_step_rate_gain(
                        gain,
                        params.step_nm,
                        params.max_step_rate_hz,
                        v,
                    )
                    .map_err(RuntimeError::StepRate)?;
                }
            }
            Applies::NextTick
        };
        st.pending = Some((params, applies));
        Ok(applies)
    }

    /// Applies parameters immediately, at boot, before the first tick.
    pub fn configure_at_boot(&mut self, params: RunParams, stepdir_count: u16) {
        self.st.stepdir = StepDirCounter::new(stepdir_count);
        self.st.pending = None;
        self.st.apply(params);
    }

    /// Starts a point-to-point move to `target` (nm) at `speed` (nm/s) and `accel` (nm/s²).
    /// Returns the move's duration in ticks (without the shaper's delay). Refused with
    /// [`RuntimeError::StepRate`] by the step-rate rule ([`check_move_step_rate`]).
    pub fn start_move(&mut self, target: i32, speed: f32, accel: f32) -> Result<u32, RuntimeError> {
        let st = &mut self.st;
        if st.params.source != Source::Internal {
            return Err(RuntimeError::Source);
        }
        if st.motion != Motion::Idle {
            return Err(RuntimeError::Busy);
        }
        let m = TrapezoidMove::new(
            st.reference,
            target,
            speed,
            accel,
            st.params.tick_rate_hz as f32,
        )
        .map_err(RuntimeError::Move)?;
        st.params
            .check_move_step_rate(
                st.engine.taps(),
                (target as i64 - st.reference as i64).unsigned_abs() as u32,
                speed,
                accel,
            )
            .map_err(RuntimeError::StepRate)?;
        let n = m.duration_ticks();
        st.motion = Motion::Move(m);
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
        let st = &mut self.st;
        if st.params.source != Source::Internal {
            return Err(RuntimeError::Source);
        }
        if st.motion != Motion::Idle {
            return Err(RuntimeError::Busy);
        }
        let sw = SineSweep::new(
            kind,
            st.reference,
            f0_hz,
            f1_hz,
            amplitude_nm,
            duration_s,
            st.params.tick_rate_hz as f64,
        )
        .map_err(RuntimeError::Sweep)?;
        crate::output::check_step_rate(
            st.engine.taps(),
            st.params.step_nm,
            st.params.max_step_rate_hz,
            sw.peak_speed(),
        )
        .map_err(RuntimeError::StepRate)?;
        let n = sw.duration_ticks();
        st.motion = Motion::Sweep(sw);
        Ok(n)
    }

    /// Ends a running move (decelerating at its acceleration, then holding) or sweep (fading
    /// its amplitude out over its fade time, back to its start). Returns the ticks until the
    /// reference is at rest (0 when nothing runs).
    pub fn stop(&mut self) -> u32 {
        match &mut self.st.motion {
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
    /// reference is still for the duration of every table in flight and no move runs.
    pub fn zero(&mut self) -> Result<(), RuntimeError> {
        let st = &mut self.st;
        if st.motion != Motion::Idle || st.still_ticks < st.engine.settle_ticks() {
            return Err(RuntimeError::Busy);
        }
        st.reference = 0;
        st.setpoint = 0;
        st.stepdir_offset = -st.stepdir.steps() * st.params.input_nm_per_count as i64;
        st.engine.reset(0);
        st.steps = StepOutput::new(st.params.step_nm as i32, st.params.max_pulses_per_tick(), 0);
        Ok(())
    }

    /// One timer tick. Bounded work, no allocation, no panic.
    #[inline]
    pub fn tick(&mut self, input: &TickInput) -> TickOutput {
        let st = &mut self.st;
        st.ticks = st.ticks.wrapping_add(1);
        let x = match st.params.source {
            Source::Internal => match &mut st.motion {
                Motion::Idle => st.reference,
                Motion::Move(m) => {
                    let x = m.next();
                    if m.done() {
                        st.motion = Motion::Idle;
                    }
                    x
                }
                Motion::Sweep(s) => {
                    let x = s.next();
                    if s.done() {
                        st.motion = Motion::Idle;
                    }
                    x
                }
            },
            Source::StepDir => {
                let steps_in = st.stepdir.update(input.stepdir_count);
                let p = st.stepdir_offset + steps_in * st.params.input_nm_per_count as i64;
                p.clamp(-(POSITION_LIMIT as i64), POSITION_LIMIT as i64) as i32
            }
        };
        if x == st.reference {
            st.still_ticks = st.still_ticks.saturating_add(1);
        } else {
            st.still_ticks = 0;
        }
        st.reference = x;
        if st.pending.is_some() {
            st.apply_pending(input.stepdir_count);
        }
        let previous = st.setpoint;
        st.setpoint = st.engine.tick(&mut self.bufs.history, x);
        st.capture.record(&mut self.bufs.capture, st.setpoint);
        self.bufs.watch.record(st.setpoint, previous);
        TickOutput {
            reference_counts: x,
            setpoint_counts: st.setpoint,
            step: st.steps.update(st.setpoint),
            dac_code: st.dac.code(st.setpoint),
        }
    }

    /// The setpoint capture.
    pub fn capture(&self) -> Capture<'_> {
        Capture {
            state: self.st.capture,
            buf: &self.bufs.capture,
        }
    }

    /// Starts capturing one setpoint every `decimation` ticks.
    pub fn arm_capture(&mut self, decimation: u32) {
        self.st.capture.arm(decimation);
    }

    /// The drift watch's setpoint ring (read in thread mode by [`crate::watch::Watch::poll`]).
    pub fn watch_ring(&self) -> &SetpointRing {
        &self.bufs.watch
    }

    /// Arms the watch's setpoint ring: one setpoint every `decimation` ticks (0 = off); its
    /// count restarts at 0.
    pub fn arm_watch_ring(&mut self, decimation: u32) {
        self.bufs.watch.arm(decimation);
    }

    /// Tick rate in force (Hz); the glue reprograms its timer when this changes.
    pub fn tick_rate_hz(&self) -> u32 {
        self.st.params.tick_rate_hz
    }

    /// Parameters in force.
    pub fn params(&self) -> &RunParams {
        &self.st.params
    }

    /// Pending parameters, if any.
    pub fn pending(&self) -> Option<&RunParams> {
        self.st.pending.as_ref().map(|(p, _)| p)
    }

    /// The engine state (for inspection).
    pub fn engine(&self) -> &EngineState<HISTORY_LEN> {
        &self.st.engine
    }

    /// The step output (for inspection).
    pub fn step_output(&self) -> &StepOutput {
        &self.st.steps
    }

    /// A snapshot for the console's `status`.
    pub fn status(&self) -> Status {
        let st = &self.st;
        let waiting = match &st.pending {
            Some((p, Applies::WhenStill)) => Waiting::between(&st.params, p, st.engine.taps()),
            _ => Waiting::default(),
        };
        Status {
            ticks: st.ticks,
            reference_counts: st.reference,
            setpoint_counts: st.setpoint,
            emitted_steps: st.steps.emitted(),
            moving: st.motion != Motion::Idle,
            pending: st.pending.is_some(),
            waiting,
            stages: st.engine.stages(),
            taps_in_flight: st.engine.taps_in_flight(),
            still_ticks: st.still_ticks,
            step_rate_faults: st.steps.rate_faults(),
            tick_rate_hz: st.params.tick_rate_hz,
            path: st.params.path,
            taps: st.engine.taps().len(),
            duration_ticks: st.engine.taps().duration_ticks(),
            source: st.params.source,
            applied_changes: st.applied_changes,
        }
    }
}
