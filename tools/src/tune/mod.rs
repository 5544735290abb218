//! The main job, transactional: recording → modes → shaper → board → a verification move
//! **measured** → save only if it passed.
//!
//! [`tune`] is a pipeline of typed steps; each returns a value the next takes:
//! 1. [`inputs::check_inputs`]: every option validated and every file read before the board is
//!    touched (rig TOML, or the embedded reference rig; the recording must exist) → [`Inputs`].
//! 2. [`identify_step`] on the user's recording, before the board is touched →
//!    [`IdentifiedModes`].
//! 3. [`inputs::connect`]: a real port, or the virtual board on a PTY with a virtual rig
//!    ([`crate::board::rig`]) whose camera writes what it saw → [`Bench`].
//! 4. [`crate::board::steps::read_board`]: the running configuration and position (to plan
//!    against and to restore) → [`BoardState`].
//! 5. Without a recording, on the virtual rig: [`inputs::excite`] runs the paper's exponential
//!    sweep on the board, the camera records it, [`identify_step`] identifies that recording.
//! 6. [`design`]: the shortest robust shaper ([`crate::shaping::choose`]) whose verification
//!    move the board can run (step-rate rule with margin, capture), and which leaves the
//!    recorded free vibration (if any) within the tolerance → [`Design`].
//! 7. [`crate::board::steps::program`]: program and read back the impulse table.
//! 8. [`verify::verify`]: with a sensor, an unshaped and a shaped move measured by it; with a
//!    user recording and no sensor, the shaper applied to the recorded vibration by
//!    superposition (model-free) → [`Verification`].
//! 9. `save` only if the check passed; otherwise the board's previous running configuration is
//!    restored and the run fails with [`TuneError::VerificationFailed`].
//!
//! Nothing here prints or writes reports: a [`TuneView`] is told each step's value as it is
//! produced (the CLI prints, plots and writes `tune.json` from it). The only files written are
//! the bench's own: the virtual board's flash, the virtual rig's camera log and the recording
//! of the excitation it made, all in [`TuneOptions::work_dir`].

pub mod inputs;
pub mod recorded;
pub mod spectrum;
pub mod verify;

pub use inputs::{check_inputs, connect, Bench, Excitation, Inputs};
pub use recorded::{free_vibration, generate_recording, recorded_free_position};
pub use verify::{Outcome, Verification};

use crate::board::plan::{plan_move, MovePlan, PlanError};
use crate::board::steps::{program, read_board, restore, BoardState, StepError};
use crate::ident::ModeEstimate;
use crate::shaping::{
    choose, settings_with, Candidate, ChoiceRules, NoShaperFits, RecordedVibration,
};
use beamshaper::config::{Certificate, Verified, MAX_MODES};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Default excitation: exponential sweep band (Hz), the paper's §5.2 input (eq. 34).
pub const SWEEP_BAND_HZ: (f64, f64) = (0.3, 15.0);
/// Largest sweep amplitude (mm); the step-rate rule may lower it.
pub const SWEEP_AMPLITUDE_MM: f64 = 5.0;
/// Sweep duration (s) and the ring-down recorded after it (s).
pub const SWEEP_DURATION_S: f64 = 90.0;
/// See [`SWEEP_DURATION_S`].
pub const SWEEP_TAIL_S: f64 = 20.0;

/// The reference rig (`rigs/paper.toml`), embedded so every command works from any directory.
pub const DEFAULT_RIG_TOML: &str = include_str!("../../../rigs/paper.toml");

/// An error from a module that reports untyped errors (identification, recording, model).
pub type Foreign = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What a recording's vibration signal measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// `.npy` → acceleration, CSV → position.
    Auto,
    /// Tip position or deflection.
    Position,
    /// Tip acceleration (integrated twice for the model-free check).
    Acceleration,
}

/// The job's options (units in the names; see `beamtool tune --help` for each).
#[derive(Clone, Debug, PartialEq)]
pub struct TuneOptions {
    /// The user's recording; `None`: the virtual rig's camera records an excitation.
    pub recording: Option<PathBuf>,
    /// Rig file (virtual rig and model prediction); `None`: the embedded reference rig.
    pub rig: Option<PathBuf>,
    /// Percentage-vibration tolerance (%), 0.2..=50.
    pub tolerance_pct: f64,
    /// Minimum half-width of the checked frequency band (% of each frequency), 0..=50.
    pub min_band_pct: f64,
    /// Serial port of a real board; `None`: a virtual board on a PTY.
    pub port: Option<String>,
    /// Verification move (mm, either sign), peak speed (mm/s), acceleration (mm/s²).
    pub move_mm: f64,
    /// See [`TuneOptions::move_mm`].
    pub speed_mm_s: f64,
    /// See [`TuneOptions::move_mm`].
    pub accel_mm_s2: f64,
    /// Directory of the bench's files (virtual flash, camera log, excitation recording).
    pub work_dir: PathBuf,
    /// Camera log of a board with a rig attached (the verification moves are measured on it).
    pub camera_log: Option<PathBuf>,
    /// What the recording's vibration signal is.
    pub signal: Signal,
    /// Virtual board speed-up over real time, 1..=1000.
    pub time_scale: f64,
    /// How the user's recording is read (`--columns`, `--axis`).
    pub read: crate::recording::ReadOptions,
    /// When nothing can measure the shaper, save it on the identified modes' prediction
    /// alone (within the tolerance), recorded as `predicted-only` on the board.
    pub accept_predicted: bool,
    /// Also store the tuned frequencies as this entry of the board's payload schedule
    /// (`payload N store`, before `save`).
    pub payload: Option<u8>,
}

impl TuneOptions {
    /// The defaults of `beamtool tune` with `recording` and work directory `dir`.
    pub fn new(recording: Option<PathBuf>, dir: &Path) -> Self {
        TuneOptions {
            recording,
            rig: None,
            tolerance_pct: 2.0,
            min_band_pct: 2.0,
            port: None,
            move_mm: 50.0,
            speed_mm_s: 150.0,
            accel_mm_s2: 2000.0,
            work_dir: dir.to_path_buf(),
            camera_log: None,
            signal: Signal::Auto,
            time_scale: 200.0,
            read: Default::default(),
            accept_predicted: false,
            payload: None,
        }
    }
}

/// Why the job stopped. Every error after the board was changed is [`TuneError::Restored`]
/// (or [`TuneError::VerificationFailed`]): the board runs its previous configuration again.
#[derive(Debug, Error)]
pub enum TuneError {
    /// An option is out of range (the message names the option).
    #[error("{0}")]
    Argument(String),
    /// A file or step of another module failed (`what` says which).
    #[error("{what}")]
    Failed {
        /// What was being done.
        what: String,
        /// Why it failed.
        #[source]
        source: Foreign,
    },
    /// An identification, recording or model error, as is.
    #[error(transparent)]
    Other(Foreign),
    /// No mode was identified in the recording.
    #[error("no mode identified in {0}")]
    NoMode(PathBuf),
    /// A board step failed.
    #[error(transparent)]
    Board(#[from] StepError),
    /// A move or the excitation cannot be planned.
    #[error("{what}: {source}")]
    Plan {
        /// Which move.
        what: &'static str,
        /// Why.
        source: PlanError,
    },
    /// No shaper satisfies the tolerance on this board.
    #[error(transparent)]
    NoShaper(#[from] NoShaperFits),
    /// A [`TuneView`] failed (e.g. could not write its report).
    #[error(transparent)]
    View(Foreign),
    /// The verification did not pass; `restored` says what was done with the board.
    #[error("verification failed: {}; {restored}", why_failed(report, *tolerance_pct))]
    VerificationFailed {
        /// The tolerance (%).
        tolerance_pct: f64,
        /// The result of restoring the board (a sentence).
        restored: String,
        /// What was found.
        report: Box<TuneReport>,
    },
    /// A step failed after the board was touched; `restored` says what was done with it.
    #[error("{restored}")]
    Restored {
        /// The result of restoring the board (a sentence).
        restored: String,
        /// The step's error.
        #[source]
        source: Box<TuneError>,
    },
}

/// Why a verification failed, as a clause: what exceeded the tolerance, or why nothing could
/// measure the shaper (and how to save it on the prediction alone).
pub fn why_failed(r: &TuneReport, tolerance_pct: f64) -> String {
    let v = &r.verification;
    match v.outcome(tolerance_pct) {
        Outcome::Exceeded => {
            let named = [
                ("measured", v.measured_pct),
                ("on the recorded vibration", v.superposed_pct),
                ("rig model", v.rig_model_pct),
            ];
            let over: Vec<String> = named
                .iter()
                .filter_map(|(n, p)| p.filter(|&p| p > tolerance_pct).map(|p| format!("{n} {p:.2} %")))
                .collect();
            format!(
                "the percentage vibration exceeds the tolerance {tolerance_pct} % ({})",
                over.join(", ")
            )
        }
        Outcome::Unmeasured if v.predicted_pct > tolerance_pct => format!(
            "nothing could measure the shaper ({}), and the identified modes predict {:.2} %, over the tolerance {tolerance_pct} %",
            v.unmeasured_because.join("; "),
            v.predicted_pct
        ),
        Outcome::Unmeasured => format!(
            "nothing could measure the shaper ({}); the identified modes predict {:.2} % — pass --accept-predicted to save it on that prediction alone (the board then reports verified=predicted-only)",
            v.unmeasured_because.join("; "),
            v.predicted_pct
        ),
        Outcome::Passed => "the checks passed but the board did not save".to_string(),
    }
}

impl TuneError {
    /// Wraps a foreign error with what was being done.
    pub fn failed(what: impl Into<String>, source: impl Into<Foreign>) -> Self {
        TuneError::Failed {
            what: what.into(),
            source: source.into(),
        }
    }
}

/// The identified modes and how they were found.
#[derive(Clone, Debug)]
pub struct IdentifiedModes {
    /// Physical modes, ascending in frequency, with 1-σ.
    pub modes: Vec<ModeEstimate>,
    /// The path taken and why, the mode table, rejected estimates and warnings (text).
    pub description: String,
}

impl IdentifiedModes {
    /// The modes the shaper is designed for: the first two.
    pub fn shaped_modes(&self) -> &[ModeEstimate] {
        &self.modes[..self.modes.len().min(2)]
    }
}

/// The chosen shaper and the moves planned for it.
#[derive(Clone, Debug)]
pub struct Design {
    /// Winner.
    pub best: Candidate,
    /// Feasible runners-up (by duration).
    pub runners_up: Vec<Candidate>,
    /// Shaped verification move (from the far end back to the start position).
    pub shaped: MovePlan,
    /// Unshaped reference move (from the start position to the far end).
    pub unshaped: MovePlan,
    /// Settling window observed after each move (s).
    pub window_s: f64,
    /// The board's maximum output step rate the moves were planned against (steps/s).
    pub max_step_rate_hz: u32,
    /// Shorter candidates refused because they leave more than the tolerance of the recorded
    /// free vibration (model-free superposition), with that percentage.
    pub refused_on_recording: Vec<String>,
}

/// Everything the job found: the result of every step.
#[derive(Clone, Debug)]
pub struct TuneReport {
    /// The check passed (and the board saved).
    pub passed: bool,
    /// How the saved shaper was checked: `Measured`, or `PredictedOnly` (accepted with
    /// [`TuneOptions::accept_predicted`] when nothing could measure); `Unknown` when not saved.
    pub verified: Verified,
    /// The recording identified (the user's or the excitation's).
    pub input: PathBuf,
    /// The board's port.
    pub port: String,
    /// Where the rig of the model prediction came from.
    pub rig_label: String,
    /// The recording's vibration signal was an acceleration (integrated twice).
    pub acceleration: bool,
    /// Identification.
    pub id: IdentifiedModes,
    /// The chosen shaper and moves.
    pub design: Design,
    /// The checks.
    pub verification: Verification,
}

/// Told each step's value as the job produces it (the CLI prints, plots and writes files).
/// Every method defaults to doing nothing.
pub trait TuneView {
    /// The board was connected and read.
    fn board(&mut self, _port: &str, _before: &BoardState) {}
    /// The virtual rig recorded an excitation run on the board.
    fn excited(&mut self, _e: &Excitation) {}
    /// The recording at `input` was identified.
    fn identified(&mut self, _input: &Path, _id: &IdentifiedModes) {}
    /// A shaper was chosen for `modes`. An error stops the job (the board is restored).
    fn designed(&mut self, _modes: &[ModeEstimate], _d: &Design) -> Result<(), Foreign> {
        Ok(())
    }
    /// The shaper was programmed on the board at `port` and read back.
    fn programmed(&mut self, _port: &str, _c: &Candidate) {}
    /// The verification ran (before `save`). An error stops the job (the board is restored).
    fn verified(&mut self, _r: &TuneReport) -> Result<(), Foreign> {
        Ok(())
    }
    /// The board saved its configuration.
    fn saved(&mut self) {}
}

/// A [`TuneView`] that shows nothing.
pub struct Quiet;
impl TuneView for Quiet {}

/// `beamtool tune`: the whole job (see the module docs). Errors after the board was changed
/// restore it first and say so.
pub fn tune(o: &TuneOptions, view: &mut dyn TuneView) -> Result<TuneReport, TuneError> {
    let inputs = check_inputs(o)?;
    let pre = match &inputs.recording {
        Some(p) => Some(identify_step(p, &o.read)?),
        None => None,
    };
    let mut bench = connect(o, &inputs)?;
    let before = read_board(&mut bench.session)?;
    view.board(&bench.port, &before);
    match run_job(o, &inputs, &mut bench, &before, pre, view) {
        Ok(r) if r.passed => Ok(r),
        Ok(r) => Err(TuneError::VerificationFailed {
            tolerance_pct: o.tolerance_pct,
            restored: restore(&mut bench.session, &before),
            report: Box::new(r),
        }),
        Err(e) => Err(TuneError::Restored {
            restored: restore(&mut bench.session, &before),
            source: Box::new(e),
        }),
    }
}

/// Steps 5–9 on a connected board: recording → ident → shaping → board → verify → save.
fn run_job(
    o: &TuneOptions,
    inputs: &Inputs,
    bench: &mut Bench,
    before: &BoardState,
    pre: Option<IdentifiedModes>,
    view: &mut dyn TuneView,
) -> Result<TuneReport, TuneError> {
    let (input, id) = recording_and_modes(o, bench, before, pre, view)?;
    let f_max = id.modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max);
    let recorded = recorded_free_position(inputs, id.modes[0].freq_hz, f_max);
    let design = design(o, id.shaped_modes(), before, recorded.as_ref().ok())?;
    view.designed(id.shaped_modes(), &design)
        .map_err(TuneError::View)?;
    program(&mut bench.session, &design.best)?;
    view.programmed(&bench.port, &design.best);
    let recorded = recorded.as_ref().map_err(String::as_str);
    let verification = verify::verify(o, bench, inputs, &id, &design, recorded, before)?;
    let verified = match verification.outcome(o.tolerance_pct) {
        Outcome::Passed => Verified::Measured,
        Outcome::Unmeasured
            if o.accept_predicted && verification.predicted_pct <= o.tolerance_pct =>
        {
            Verified::PredictedOnly
        }
        _ => Verified::Unknown,
    };
    let report = TuneReport {
        passed: verified != Verified::Unknown,
        verified,
        input,
        port: bench.port.clone(),
        rig_label: inputs.rig_label.clone(),
        acceleration: inputs.acceleration,
        id,
        design,
        verification,
    };
    view.verified(&report).map_err(TuneError::View)?;
    if report.passed {
        let c = certificate(o, &report);
        bench.session.certify(&c).map_err(StepError::from)?;
        if let Some(n) = o.payload {
            bench.session.payload_store(n).map_err(StepError::from)?;
        }
        bench.session.save().map_err(StepError::from)?;
        view.saved();
    }
    Ok(report)
}

/// The certificate `tune` leaves on the board with the saved shaper: how it was verified and,
/// per shaped mode (slots 1, 2, …), the band its worst case was certified over
/// ([`crate::shaping::band`]).
pub fn certificate(o: &TuneOptions, r: &TuneReport) -> Certificate {
    let mut c = Certificate {
        verified: r.verified,
        band_hz: [None; MAX_MODES],
    };
    let modes = r.id.shaped_modes().iter().take(r.design.best.modes.len());
    for (slot, m) in c.band_hz.iter_mut().zip(modes) {
        let b = crate::shaping::band(m, o.min_band_pct / 100.0);
        *slot = Some((b.freq_hz.0 as f32, b.freq_hz.1 as f32));
    }
    c
}

/// The recording and its modes: the user's (identified before the board was touched), or an
/// excitation recorded on the virtual rig and identified now. Errors: no mode identified.
fn recording_and_modes(
    o: &TuneOptions,
    bench: &mut Bench,
    before: &BoardState,
    pre: Option<IdentifiedModes>,
    view: &mut dyn TuneView,
) -> Result<(PathBuf, IdentifiedModes), TuneError> {
    let (input, id) = match pre {
        Some(id) => (o.recording.clone().unwrap_or_default(), id),
        None => {
            let e = inputs::excite(o, bench, before)?;
            view.excited(&e);
            let id = identify_step(&e.recording, &Default::default())?;
            (e.recording, id)
        }
    };
    if id.modes.is_empty() {
        return Err(TuneError::NoMode(input));
    }
    view.identified(&input, &id);
    Ok((input, id))
}

/// The identification step: the recording at `path` (CSV, `.npy`, `.lvm` spectrum; a sweep,
/// a free decay or moves + ring-down, with gaps) → its physical modes
/// ([`crate::ident::identify::identify_file`] with default options, the file read as `read`
/// says).
pub fn identify_step(
    path: &Path,
    read: &crate::recording::ReadOptions,
) -> Result<IdentifiedModes, TuneError> {
    let opts = crate::ident::IdentifyOptions {
        read: read.clone(),
        ..Default::default()
    };
    let id = crate::ident::identify::identify_file(path, &opts, &mut |_| {})
        .map_err(|e| TuneError::Other(e.into()))?;
    Ok(IdentifiedModes {
        description: crate::ident::report::identification_table(&id),
        modes: id.modes,
    })
}

/// Step 6: the shortest robust shaper ([`choose`]) whose verification move the board can run
/// and, when the input holds a recorded free vibration, that leaves that vibration within the
/// tolerance (model-free superposition): the data, not only the identified modes, must agree.
pub fn design(
    o: &TuneOptions,
    modes: &[ModeEstimate],
    board: &BoardState,
    recorded: Option<&RecordedVibration>,
) -> Result<Design, TuneError> {
    let window_s = (6.0 / modes[0].freq_hz).clamp(2.0, 20.0);
    let start = board.position_mm;
    let (speed, accel) = (o.speed_mm_s, o.accel_mm_s2);
    let unshaped = plan_move(
        &board.unshaped_settings(),
        start,
        o.move_mm,
        speed,
        accel,
        window_s,
    )
    .map_err(|source| TuneError::Plan {
        what: "unshaped reference move",
        source,
    })?;
    let rules = ChoiceRules {
        tolerance_pct: o.tolerance_pct,
        min_band: o.min_band_pct / 100.0,
        recorded,
        window_s,
    };
    let back = |c: &Candidate| {
        let s = settings_with(&board.settings, c);
        plan_move(&s, start + o.move_mm, -o.move_mm, speed, accel, window_s)
            .map_err(|e| e.to_string())
    };
    let choice = choose(modes, &rules, back)?;
    Ok(Design {
        best: choice.best,
        runners_up: choice.runners_up,
        shaped: choice.best_runs,
        unshaped,
        window_s,
        max_step_rate_hz: board.config.max_step_rate_hz,
        refused_on_recording: choice.refused_on_recording,
    })
}
