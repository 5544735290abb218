//! The board operations of a job, over a typed [`Session`]: read what the board runs (to plan
//! against and to restore), program a shaper and check it by read-back, run a planned move or
//! sweep and wait for it in board time, restore the configuration read at the start.
//!
//! Waiting is in **board time** (the `ticks` of `status`) with a wall-clock timeout, so a
//! virtual board running `time_scale` times faster than real time is waited for correctly.
//! Nothing here prints; every failure is a [`StepError`].

use super::plan::{plan_sweep, MovePlan, PlanError, SweepPlan};
use super::session::{BoardConfig, Command, Session, SessionError};
use crate::shaping::Candidate;
use beamshaper::config::Settings;
use beamshaper::reference::SweepKind;
use beamshaper::shaper::Impulse;
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why a board step failed.
#[derive(Debug, Error)]
pub enum StepError {
    /// The session failed (transport, `err` reply, malformed reply).
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The board is not in a state the job can start from.
    #[error("{0}")]
    NotReady(&'static str),
    /// The board did not become still in time (wall clock, s).
    #[error("the board did not finish within {0:.0} s (wall clock)")]
    Timeout(f64),
    /// The capture holds fewer setpoints than the move needs.
    #[error("the board captured fewer setpoints than the move needs")]
    ShortCapture,
    /// The read-back table differs from the designed one.
    #[error("{0}")]
    ReadBack(String),
    /// The request is unusable (the message says why).
    #[error("{0}")]
    Request(&'static str),
    /// A move or sweep cannot be planned.
    #[error(transparent)]
    Plan(#[from] PlanError),
}

/// The board as found: to plan against and to restore.
pub struct BoardState {
    /// `config` reply.
    pub config: BoardConfig,
    /// The custom impulse list (read from `shaper` when no mode is set).
    pub custom: Vec<Impulse>,
    /// Settings equivalent for planning.
    pub settings: Settings,
    /// Setpoint (mm).
    pub position_mm: f64,
}

impl BoardState {
    /// The settings with shaping off (the unshaped reference moves and the excitation).
    pub fn unshaped_settings(&self) -> Settings {
        Settings {
            shaping_enabled: false,
            ..self.settings.clone()
        }
    }

    /// Tick rate (Hz).
    pub fn tick_hz(&self) -> f64 {
        self.config.tick_hz as f64
    }
}

/// Reads the running configuration and position. Changes nothing. Errors: the board moves,
/// or follows its step/direction input.
pub fn read_board(s: &mut Session) -> Result<BoardState, StepError> {
    let config = s.config()?;
    let status = s.status()?;
    if status.moving {
        return Err(StepError::NotReady(
            "the board is moving; run tune when it is still",
        ));
    }
    if !config.source_internal {
        return Err(StepError::NotReady("the board follows its step/direction input (`source stepdir`); tune needs `source internal`"));
    }
    let mut custom = Vec::new();
    if config.custom_len > 0 && config.modes.iter().all(Option::is_none) && config.shaping {
        custom = s.impulses()?;
    }
    let mut settings = Settings {
        modes: config.modes,
        shaping_enabled: config.shaping,
        tick_rate_hz: config.tick_hz,
        step_nm: config.step_nm,
        max_step_rate_hz: config.max_step_rate_hz,
        ..Settings::DEFAULT
    };
    for i in &custom {
        let _ = settings.custom.push(*i);
    }
    Ok(BoardState {
        config,
        custom,
        settings,
        position_mm: status.setpoint_mm,
    })
}

/// Polls until the board is still and `until_tick` has passed (board time); returns the tick.
pub fn wait_board(s: &mut Session, until_tick: u64, timeout: Duration) -> Result<u64, StepError> {
    let end = Instant::now() + timeout;
    loop {
        let st = s.status()?;
        if !st.moving && !st.pending && st.ticks >= until_tick {
            return Ok(st.ticks);
        }
        if Instant::now() > end {
            return Err(StepError::Timeout(timeout.as_secs_f64()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Longest wait (s, wall clock) for a board to become quiet before it is restored: the
/// longest shaper the board holds (its history, a few seconds) at real time, with margin.
pub const RESTORE_WAIT_S: u64 = 60;

/// Polls until the board is still, has no pending change and at most one shaper in flight
/// (no transition running), so that a new configuration is accepted.
pub fn wait_quiet(s: &mut Session, timeout: Duration) -> Result<(), StepError> {
    let end = Instant::now() + timeout;
    loop {
        let st = s.status()?;
        if !st.moving && !st.pending && st.stages <= 1 {
            return Ok(());
        }
        if Instant::now() > end {
            return Err(StepError::Timeout(timeout.as_secs_f64()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A move run by [`run_move`].
#[derive(Clone, Debug, PartialEq)]
pub struct MoveRun {
    /// The captured setpoints (m), one every `capture_every` ticks from the move's start.
    pub setpoints_m: Vec<f64>,
    /// Board time (s) just before the move was sent: the move starts after it.
    pub sent_s: f64,
    /// Board time (s) the observation ran to: the move, its shaper and the settling window,
    /// counted from a tick at which the move had already started.
    pub observed_until_s: f64,
}

/// Runs `plan` and waits for its observation window, counted from a tick at which the move
/// had started (the console's round trips take board time, more on a loaded host with a fast
/// virtual board); returns the captured setpoints and the board times that bracket the move.
pub fn run_move(
    s: &mut Session,
    plan: &MovePlan,
    tick_hz: f64,
    time_scale: f64,
) -> Result<MoveRun, StepError> {
    let sent = s.status()?.ticks;
    let cap = s.capture(plan.capture_every)?;
    s.start_move(plan.target_mm, plan.speed_mm_s, plan.accel_mm_s2)?;
    let started = s.status()?.ticks;
    let until = started + plan.observe_ticks + (0.1 * tick_hz) as u64;
    let wall = Duration::from_secs_f64(plan.observe_ticks as f64 / tick_hz / time_scale + 10.0);
    wait_board(s, until, wall)?;
    let want = (plan.observe_ticks / plan.capture_every as u64).min(cap.capacity as u64) as usize;
    if s.captured()? < want {
        return Err(StepError::ShortCapture);
    }
    Ok(MoveRun {
        setpoints_m: s.dump_all(|_| {})?,
        sent_s: sent as f64 / tick_hz,
        observed_until_s: until as f64 / tick_hz,
    })
}

/// Waits `seconds` of board time for the beam to ring down.
pub fn ring_down(
    s: &mut Session,
    seconds: f64,
    tick_hz: f64,
    time_scale: f64,
) -> Result<(), StepError> {
    let st = s.status()?;
    let wall = Duration::from_secs_f64(seconds / time_scale + 10.0);
    wait_board(s, st.ticks + (seconds * tick_hz) as u64, wall).map(|_| ())
}

/// Runs `plan` (a sweep) on the board, then waits `tail_s` more of board time (wall-clock
/// timeout: the board time over `time_scale`, plus `slack_s`). Returns the board times (s) at
/// which the sweep was sent and at which the wait ended.
pub fn run_sweep(
    s: &mut Session,
    plan: &SweepPlan,
    tail_s: f64,
    time_scale: f64,
    slack_s: f64,
) -> Result<(f64, f64), StepError> {
    let st = s.status()?;
    let tick_hz = f64::from(st.tick_hz);
    let t0 = st.ticks as f64 / tick_hz;
    let ticks = s.sweep(plan)?;
    let end = t0 + ticks as f64 / tick_hz + tail_s;
    let wall = Duration::from_secs_f64((end - t0) / time_scale + slack_s);
    wait_board(s, (end * tick_hz) as u64, wall)?;
    Ok((t0, end))
}

/// Turns shaping off and waits until the board is still (before an unshaped excitation).
pub fn shaping_off(s: &mut Session) -> Result<(), StepError> {
    s.send(&Command::Shaping(false))?;
    let st = s.status()?;
    wait_board(s, st.ticks, Duration::from_secs(10)).map(|_| ())
}

/// Programs the candidate and compares the read-back table impulse by impulse (1e-12).
pub fn program(s: &mut Session, c: &Candidate) -> Result<(), StepError> {
    s.program(&c.modes, &[], true)?;
    let back = s.impulses()?;
    if back.len() != c.shaper.len() {
        return Err(StepError::ReadBack(format!(
            "read-back table has {} impulses, designed {}",
            back.len(),
            c.shaper.len()
        )));
    }
    for (b, i) in back.iter().zip(c.shaper.impulses()) {
        if (b.amplitude - i.amplitude).abs() > 1e-12 || (b.time_s - i.time_s).abs() > 1e-12 {
            return Err(StepError::ReadBack(format!(
                "read-back impulse {:.6} at {:.6} s differs from the designed {:.6} at {:.6} s",
                b.amplitude, b.time_s, i.amplitude, i.time_s
            )));
        }
    }
    Ok(())
}

/// Restores the configuration read at the start; returns what was done, as a sentence.
pub fn restore(s: &mut Session, before: &BoardState) -> String {
    match restore_config(s, before) {
        Ok(how) => format!("the board runs its previous configuration again ({how}); nothing was saved"),
        Err(e) => format!("COULD NOT RESTORE the board's previous configuration ({}); its flash still holds the last saved one: power-cycle or send `load`", super::error_chain(&e)),
    }
}

/// [`restore`]'s steps: `load` (when modes and a custom list were both set) or reprogram,
/// then compare the running configuration with the one read at the start.
fn restore_config(s: &mut Session, before: &BoardState) -> Result<&'static str, StepError> {
    // A failed job may leave a move or a shaper transition running; the board refuses a new
    // shaper while its transition budget is taken, so wait until it is quiet first.
    wait_quiet(s, Duration::from_secs(RESTORE_WAIT_S))?;
    let modes: Vec<_> = before.config.modes.iter().flatten().copied().collect();
    let how = if before.config.custom_len > 0 && !modes.is_empty() {
        s.load()
            .map(|_| "reloaded the saved configuration (`load`)")?
    } else {
        s.program(&modes, &before.custom, before.config.shaping)
            .map(|_| "reprogrammed the configuration read at the start")?
    };
    if before.config.certificate != beamshaper::config::Certificate::NONE {
        s.certify(&before.config.certificate)?;
    }
    let now = s.config()?;
    if now.modes != before.config.modes
        || now.shaping != before.config.shaping
        || now.certificate != before.config.certificate
    {
        return Err(StepError::NotReady(
            "the board's configuration after restoring differs from the one read at the start",
        ));
    }
    Ok(how)
}

/// A sweep (eq. 33 linear, eq. 34 exponential) between `f_a_hz` < `f_b_hz`, swept at `rate`
/// (octaves/min for exponential, Hz/s for linear; negative = downwards), within a stroke
/// (mm, amplitude) and a base acceleration limit (m/s² at the top frequency).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepRequest {
    /// Kind.
    pub kind: SweepKind,
    /// Lower and upper frequencies (Hz).
    pub f_a_hz: f64,
    /// See [`SweepRequest::f_a_hz`].
    pub f_b_hz: f64,
    /// Sweep rate (sign = direction).
    pub rate: f64,
    /// Largest amplitude (mm).
    pub stroke_mm: f64,
    /// Largest base acceleration (m/s²).
    pub accel_max_m_s2: f64,
}

/// Runs the sweep of `r` on a board through its own reference generator, about its present
/// position, so that the user's camera can record it: the amplitude is the largest within
/// the stroke, the acceleration limit at the top frequency and the board's step-rate rule
/// with the 5 % margin ([`plan_sweep`]). Waits until the sweep has ended. Changes no setting.
pub fn sweep_on_board(s: &mut Session, r: &SweepRequest) -> Result<SweepPlan, StepError> {
    let (fa, fb) = (r.f_a_hz, r.f_b_hz);
    if !(fa > 0.0 && fb > fa && r.rate.is_finite() && r.rate != 0.0) {
        return Err(StepError::Request(
            "need 0 < --f-a-hz < --f-b-hz and a non-zero --rate",
        ));
    }
    let duration_s = match r.kind {
        SweepKind::Exponential => (fb / fa).log2() * 60.0 / r.rate.abs(),
        SweepKind::Linear => (fb - fa) / r.rate.abs(),
    };
    let (f0, f1) = if r.rate > 0.0 { (fa, fb) } else { (fb, fa) };
    let accel_limited_mm = r.accel_max_m_s2 / (2.0 * std::f64::consts::PI * fb).powi(2) * 1e3;
    let board = read_board(s)?;
    let amplitude_mm = r.stroke_mm.min(accel_limited_mm);
    let plan = plan_sweep(&board.settings, r.kind, f0, f1, amplitude_mm, duration_s)?;
    run_sweep(s, &plan, 0.0, 1.0, 30.0)?;
    Ok(plan)
}
