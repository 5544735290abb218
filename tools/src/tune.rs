//! The main job, transactional: recording → modes → shaper → board → a verification move
//! **measured** → save only if it passed.
//!
//! Steps (each returns a value the next takes):
//! 0. [`check_inputs`]: every argument validated and every file read before the board is
//!    touched (rig TOML, or the embedded reference rig; the recording must exist).
//! 1. [`connect`]: a real port, or the virtual board on a PTY with a virtual rig
//!    ([`crate::board::rig`]) whose camera writes what it saw.
//! 2. [`read_board`]: the running configuration and position (to restore on failure).
//! 3. Excitation (only without a recording, on the virtual rig): an unshaped move on the
//!    board and its ring-down, recorded by the camera.
//! 4. [`identify_step`]: one call to the identification (modes with 1-σ, path taken).
//! 5. [`design`]: the shortest robust shaper ([`crate::shaping`]) whose verification move
//!    the board can run (step-rate rule with margin, capture) — planned before any motion.
//! 6. Program and read back the impulse table.
//! 7. [`verify`]: with a sensor, an unshaped and a shaped move measured by it (percentage
//!    vibration = shaped / unshaped residual); with a user recording and no sensor, the
//!    shaper applied to the recorded vibration by superposition (model-free, so a
//!    misidentified mode shows). The model's prediction is printed beside.
//! 8. `save` only if the check passed; otherwise the board's previous running configuration
//!    is restored, the user is told, and the run fails (non-zero exit).

use crate::board::client::BoardClient;
use crate::board::plan::{plan_move, plan_sweep, MovePlan};
use crate::board::rig::{read_sensor_log, RigSensors, VirtualRig};
use crate::board::session::{BoardConfig, Session};
use crate::ident::ModeEstimate;
use crate::measures::{
    cut_move, displacement_from_acceleration, superposed_vibration_worst_pct, MeasuredMove,
};
use crate::model::sim::BaseMotionSim;
use crate::model::{BeamModel, ModelOptions, Rig};
use crate::plot::{lines_marked, Marks, Series};
use crate::recording::Recording;
use crate::shaping::{band, candidates, sensitivity, settings_with, Candidate};
use anyhow::{anyhow, bail, Context, Result};
use beamshaper::config::Settings;
use beamshaper::reference::SweepKind;
use beamshaper::shaper::{residual_vibration, Impulse};
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Default excitation: exponential sweep band (Hz), the paper's §5.2 input (eq. 34).
pub const SWEEP_BAND_HZ: (f64, f64) = (0.3, 15.0);
/// Largest sweep amplitude (mm); the step-rate rule may lower it.
pub const SWEEP_AMPLITUDE_MM: f64 = 5.0;
/// Sweep duration (s) and the ring-down recorded after it (s).
pub const SWEEP_DURATION_S: f64 = 90.0;
/// See [`SWEEP_DURATION_S`].
pub const SWEEP_TAIL_S: f64 = 20.0;

/// The reference rig (`rigs/paper.toml`), embedded so every command works from any directory.
pub const DEFAULT_RIG_TOML: &str = include_str!("../../rigs/paper.toml");

/// A finite number (clap value parser): refuses NaN and ±inf with a clear message.
pub fn finite_f64(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("`{s}` is not a finite number")),
        Err(_) => Err(format!("`{s}` is not a number")),
    }
}

/// What a recording's vibration signal measures.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// `.npy` → acceleration, CSV → position.
    Auto,
    /// Tip position or deflection.
    Position,
    /// Tip acceleration (integrated twice for the model-free check).
    Acceleration,
}

/// `tune` arguments.
#[derive(Args, Debug, Clone)]
pub struct TuneArgs {
    /// Recording (CSV, .npy free decay). Without it, the virtual rig's camera records an
    /// excitation run on the board.
    pub recording: Option<PathBuf>,
    /// Rig file: the virtual rig's beam (without --port) and the model prediction (default:
    /// the embedded reference rig rigs/paper.toml).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Percentage-vibration tolerance (%), over the whole uncertainty band and measured.
    #[arg(long, default_value_t = 2.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub tolerance_pct: f64,
    /// Minimum half-width of the frequency band checked (% of each frequency).
    #[arg(long, default_value_t = 2.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub min_band_pct: f64,
    /// Serial port of a real board (e.g. /dev/ttyACM0); default: a virtual board on a PTY.
    #[arg(long)]
    pub port: Option<String>,
    /// Verification move distance (mm) from the current position (negative = backwards).
    #[arg(long, default_value_t = 50.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub move_mm: f64,
    /// Verification move peak speed (mm/s).
    #[arg(long, default_value_t = 150.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub speed_mm_s: f64,
    /// Verification move acceleration (mm/s²).
    #[arg(long, default_value_t = 2000.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub accel_mm_s2: f64,
    /// Output directory (recordings, plots, report JSON, virtual flash).
    #[arg(long, default_value = "tune-out")]
    pub out: PathBuf,
    /// Camera log of a board with a rig attached (`beamtool vboard --rig … --sensor-out FILE`):
    /// the verification moves are then measured on it.
    #[arg(long)]
    pub camera_log: Option<PathBuf>,
    /// What the recording's vibration signal is, for the model-free check: `auto` = an
    /// acceleration in a `.npy` (the accelerometer decays of shared/data/real), a position in
    /// a recording CSV (`tip_pos_m`).
    #[arg(long, value_enum, default_value_t = Signal::Auto)]
    pub signal: Signal,
    /// Virtual board speed-up over real time.
    #[arg(long, default_value_t = 200.0, value_parser = finite_f64)]
    pub time_scale: f64,
}

impl TuneArgs {
    /// The defaults of `beamtool tune` with `recording` and output directory `out`.
    pub fn new(recording: Option<PathBuf>, out: &Path) -> Self {
        TuneArgs {
            recording,
            rig: None,
            tolerance_pct: 2.0,
            min_band_pct: 2.0,
            port: None,
            move_mm: 50.0,
            speed_mm_s: 150.0,
            accel_mm_s2: 2000.0,
            out: out.to_path_buf(),
            camera_log: None,
            signal: Signal::Auto,
            time_scale: 200.0,
        }
    }
}

/// Validated inputs.
pub struct Inputs {
    /// The rig (virtual rig and model prediction).
    pub rig: Rig,
    /// Where it came from.
    pub rig_label: String,
    /// The user's recording, if any (exists and is a file).
    pub recording: Option<PathBuf>,
    /// The rig describes the beam being tuned: `--rig` given, or no recording (the virtual
    /// rig made it).
    pub rig_declared: bool,
    /// The recording's vibration signal is an acceleration (integrated twice for the
    /// model-free check).
    pub acceleration: bool,
}

/// Step 0: validates every argument and reads every file, before the board is touched.
pub fn check_inputs(a: &TuneArgs) -> Result<Inputs> {
    if !(a.tolerance_pct >= 0.2 && a.tolerance_pct <= 50.0) {
        bail!("--tolerance-pct must be between 0.2 and 50 % (got {}); a tighter tolerance cannot be verified against sensor noise", a.tolerance_pct);
    }
    if !(0.0..=50.0).contains(&a.min_band_pct) {
        bail!(
            "--min-band-pct must be between 0 and 50 % (got {})",
            a.min_band_pct
        );
    }
    if a.move_mm.abs() < 1e-3 || a.move_mm.abs() > crate::board::plan::TARGET_LIMIT_MM {
        bail!("--move-mm {} cannot be verified: the move must be between 0.001 and 1000 mm long (either sign) and end within the board's ±1000 mm", a.move_mm);
    }
    if !(a.speed_mm_s > 0.0 && a.speed_mm_s <= crate::board::plan::SPEED_LIMIT_MM_S) {
        bail!(
            "--speed-mm-s must be > 0 and at most 10000 mm/s (got {})",
            a.speed_mm_s
        );
    }
    if !(a.accel_mm_s2 > 0.0 && a.accel_mm_s2 <= crate::board::plan::ACCEL_LIMIT_MM_S2) {
        bail!(
            "--accel-mm-s2 must be > 0 and at most 1e6 mm/s² (got {})",
            a.accel_mm_s2
        );
    }
    if !(a.time_scale >= 1.0 && a.time_scale <= 1000.0) {
        bail!(
            "--time-scale must be between 1 and 1000 (got {})",
            a.time_scale
        );
    }
    let (rig, rig_label) = match &a.rig {
        Some(p) => (
            Rig::from_toml_file(p).with_context(|| format!("rig file {}", p.display()))?,
            p.display().to_string(),
        ),
        None => (
            Rig::from_toml_str(DEFAULT_RIG_TOML)?,
            "the reference rig (rigs/paper.toml, built in)".to_string(),
        ),
    };
    BeamModel::new(&rig, &ModelOptions::default())
        .with_context(|| format!("rig {rig_label}: no usable beam model"))?;
    if let Some(r) = &a.recording {
        std::fs::File::open(r)
            .with_context(|| format!("cannot read the recording {}", r.display()))?;
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    Ok(Inputs {
        rig,
        rig_label,
        recording: a.recording.clone(),
        rig_declared: a.rig.is_some() || a.recording.is_none(),
        acceleration: match a.signal {
            Signal::Acceleration => true,
            Signal::Position => false,
            Signal::Auto => a
                .recording
                .as_ref()
                .is_some_and(|p| p.extension().is_some_and(|e| e == "npy")),
        },
    })
}

/// A connected board, with the virtual rig's sensor log when there is one.
pub struct Bench {
    /// The typed session.
    pub session: Session,
    /// The port's name.
    pub port: String,
    /// The camera log of the rig (the virtual rig's, or `--camera-log`).
    pub sensor_log: Option<PathBuf>,
    /// Board time per wall-clock time (1 for a real board), for timeouts.
    pub time_scale: f64,
}

/// Step 1: opens `--port`, or starts the virtual board with the rig attached.
pub fn connect(a: &TuneArgs, inputs: &Inputs) -> Result<Bench> {
    if let Some(p) = &a.port {
        let session = Session::open(p)?;
        return Ok(Bench {
            session,
            port: p.clone(),
            sensor_log: a.camera_log.clone(),
            time_scale: 1.0,
        });
    }
    if !inputs.rig_declared {
        // A user recording of some other beam: a virtual board without a rig; the check is
        // the model-free superposition on that recording.
        let flash = a.out.join("vboard-flash.bin");
        let port = crate::board::spawn_on_pty(Some(flash), a.time_scale)?;
        return Ok(Bench {
            session: Session::new(BoardClient::open(&port)?),
            port,
            sensor_log: None,
            time_scale: a.time_scale,
        });
    }
    let log = a.out.join("vboard-camera.csv");
    let rig = VirtualRig::new(
        &inputs.rig,
        RigSensors::camera(&inputs.rig),
        Settings::DEFAULT.tick_rate_hz as f64,
        &log,
    )?;
    let flash = a.out.join("vboard-flash.bin");
    let port = crate::board::spawn_on_pty_with_rig(Some(flash), a.time_scale, Some(rig))?;
    Ok(Bench {
        session: Session::new(BoardClient::open(&port)?),
        port,
        sensor_log: Some(log),
        time_scale: a.time_scale,
    })
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

/// Step 2: reads the running configuration and position. Changes nothing.
pub fn read_board(s: &mut Session) -> Result<BoardState> {
    let config = s.config().context("reading the board's configuration")?;
    let status = s.status().context("reading the board's status")?;
    if status.moving {
        bail!("the board is moving; run tune when it is still");
    }
    if !config.source_internal {
        bail!("the board follows its step/direction input (`source stepdir`); tune needs `source internal`");
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

/// The identified modes and how they were found.
pub struct IdentifiedModes {
    /// Physical modes, ascending in frequency, with 1-σ.
    pub modes: Vec<ModeEstimate>,
    /// The path taken and why, the mode table, rejected estimates and warnings (text).
    pub description: String,
}

/// The identification step: the recording at `path` (CSV, `.npy`, `.lvm` spectrum; a sweep,
/// a free decay or moves + ring-down, with gaps) → its physical modes
/// ([`crate::ident::identify::identify_file`] with default options).
pub fn identify_step(path: &Path) -> Result<IdentifiedModes> {
    let id = crate::ident::identify::identify_file(
        path,
        &crate::ident::IdentifyOptions::default(),
        &mut |_| {},
    )?;
    Ok(IdentifiedModes {
        description: crate::ident::report::identification_table(&id),
        modes: id.modes,
    })
}

/// The free vibration in a recording, for the model-free check: tip (minus base, when there
/// is one) after the base last left its final position by more than 20 µm, from the largest
/// excursion on, resampled to its median step. `None` when there is none (e.g. a sweep that
/// ends moving) or the file cannot be read.
pub fn free_vibration(path: &Path) -> Option<(Vec<f64>, f64)> {
    let rec = Recording::read_any(path, &mut |_| {}).ok()?;
    let tip = rec.tip_pos_m.as_ref()?;
    let base = rec.base_pos_m.as_ref().or(rec.base_cmd_m.as_ref());
    let (sig, start): (Vec<f64>, usize) = match base {
        Some(b) => {
            let last = *b.last()?;
            let moved = b
                .iter()
                .rposition(|v| (v - last).abs() > 20e-6)
                .map_or(0, |k| k + 1);
            (tip.iter().zip(b).map(|(t, b)| t - b).collect(), moved)
        }
        None => (tip.clone(), 0),
    };
    let (t, x) = (&rec.time_s[start..], &sig[start..]);
    if t.len() < 64 {
        return None;
    }
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let dt = steps[steps.len() / 2];
    let (_, xu, _) = crate::recording::resample_uniform(t, x, 1.0 / dt);
    let mean = xu.iter().sum::<f64>() / xu.len() as f64;
    let half = &xu[..xu.len() / 2];
    let k = (0..half.len())
        .max_by(|&i, &j| (half[i] - mean).abs().total_cmp(&(half[j] - mean).abs()))?;
    Some((xu[k..].to_vec(), dt))
}

/// The chosen shaper and the moves planned for it.
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
    /// Shorter candidates refused because they leave more than the tolerance of the recorded
    /// free vibration (model-free superposition), with that percentage.
    pub refused_on_recording: Vec<String>,
}

/// The user's recorded free vibration as tip position (m) at a uniform step (s), for the
/// model-free check: an accelerometer's signal integrated twice (high-passed at half the first
/// identified natural frequency). `None` when the input has none (generated sweep, or a
/// recording that ends moving).
pub fn recorded_free_position(inputs: &Inputs, f1_hz: f64) -> Option<(Vec<f64>, f64)> {
    let (x, dt) = inputs.recording.as_deref().and_then(free_vibration)?;
    let pos = match inputs.acceleration {
        true => displacement_from_acceleration(&x, dt, 0.5 * f1_hz),
        false => x,
    };
    Some((pos, dt))
}

/// The shaper applied to a recorded free vibration by superposition (model-free), in %.
fn superposed_pct(
    recorded: &(Vec<f64>, f64),
    shaper: &Candidate,
    window_s: f64,
    tol: f64,
) -> Option<f64> {
    let imps: Vec<(f64, f64)> = shaper
        .shaper
        .impulses()
        .iter()
        .map(|i| (i.amplitude, i.time_s))
        .collect();
    superposed_vibration_worst_pct(&recorded.0, recorded.1, &imps, window_s, tol / 2.0)
}

/// Step 5: the shortest robust shaper whose verification move the board can run and, when the
/// input holds a recorded free vibration, that leaves that vibration within the tolerance
/// (model-free superposition): the data, not only the identified modes, must agree.
pub fn design(
    a: &TuneArgs,
    modes: &[ModeEstimate],
    board: &BoardState,
    recorded: Option<&(Vec<f64>, f64)>,
) -> Result<Design> {
    let tol = a.tolerance_pct;
    let f1 = modes[0].freq_hz;
    let window_s = (6.0 / f1).clamp(2.0, 20.0);
    let off = Settings {
        shaping_enabled: false,
        ..board.settings.clone()
    };
    let start = board.position_mm;
    let unshaped = plan_move(
        &off,
        start,
        a.move_mm,
        a.speed_mm_s,
        a.accel_mm_s2,
        window_s,
    )
    .map_err(|e| anyhow!("unshaped reference move: {e}"))?;
    let mut feasible = Vec::new();
    let mut why = Vec::new();
    let mut refused_on_recording = Vec::new();
    for c in candidates(modes, tol / 100.0, a.min_band_pct / 100.0) {
        if c.worst_pct > tol {
            continue;
        }
        if let Some(p) = recorded.and_then(|r| superposed_pct(r, &c, window_s, tol)) {
            if p > tol {
                let line = format!("{}: leaves {p:.2} % of the recorded vibration", c.name);
                if feasible.is_empty() {
                    refused_on_recording.push(line.clone());
                }
                why.push(line);
                continue;
            }
        }
        match plan_move(
            &settings_with(&board.settings, &c),
            start + a.move_mm,
            -a.move_mm,
            a.speed_mm_s,
            a.accel_mm_s2,
            window_s,
        ) {
            Ok(p) => feasible.push((c, p)),
            Err(e) => why.push(format!("{}: {e}", c.name)),
        }
    }
    if feasible.is_empty() {
        bail!(
            "no shaper keeps the percentage vibration under {tol} % over the band and runs on this board{}{}",
            if why.is_empty() { "; loosen --tolerance-pct".to_string() } else { ":\n  ".to_string() },
            why.iter().take(3).cloned().collect::<Vec<_>>().join("\n  ")
        );
    }
    let (best, shaped) = feasible.remove(0);
    Ok(Design {
        best,
        runners_up: feasible.into_iter().take(5).map(|(c, _)| c).collect(),
        shaped,
        unshaped,
        window_s,
        refused_on_recording,
    })
}

/// Polls until the board is still and `until_tick` has passed (board time).
fn wait_board(s: &mut Session, until_tick: u64, timeout: Duration) -> Result<u64> {
    let end = Instant::now() + timeout;
    loop {
        let st = s.status()?;
        if !st.moving && !st.pending && st.ticks >= until_tick {
            return Ok(st.ticks);
        }
        if Instant::now() > end {
            bail!(
                "the board did not finish within {:.0} s (wall clock)",
                timeout.as_secs_f64()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `plan` and waits for its observation window; returns the captured setpoints (m) and
/// the board time (s) at which the move was sent.
fn run_move(
    s: &mut Session,
    plan: &MovePlan,
    tick_hz: f64,
    time_scale: f64,
) -> Result<(Vec<f64>, f64)> {
    let st = s.status()?;
    let cap = s.capture(plan.capture_every)?;
    s.start_move(plan.target_mm, plan.speed_mm_s, plan.accel_mm_s2)
        .with_context(|| format!("starting the move to {} mm", plan.target_mm))?;
    let until = st.ticks + plan.observe_ticks + (0.1 * tick_hz) as u64;
    let wall = Duration::from_secs_f64(plan.observe_ticks as f64 / tick_hz / time_scale + 10.0);
    wait_board(s, until, wall)?;
    let want = (plan.observe_ticks / plan.capture_every as u64).min(cap.capacity as u64) as usize;
    if s.captured()? < want {
        bail!("the board captured fewer setpoints than the move needs");
    }
    Ok((s.dump_all(|_| {})?, st.ticks as f64 / tick_hz))
}

/// Waits `seconds` of board time for the beam to ring down.
fn ring_down(s: &mut Session, seconds: f64, tick_hz: f64, time_scale: f64) -> Result<()> {
    let st = s.status()?;
    let wall = Duration::from_secs_f64(seconds / time_scale + 10.0);
    wait_board(s, st.ticks + (seconds * tick_hz) as u64, wall).map(|_| ())
}

/// The checks of the verification (each a percentage vibration, %) and the prediction.
pub struct Verification {
    /// Measured by the sensor: shaped / unshaped residual of two board moves.
    pub measured_pct: Option<f64>,
    /// The shaper applied to the user's recorded vibration by superposition (model-free).
    pub superposed_pct: Option<f64>,
    /// The rig model driven by the board's captured setpoints (when a rig is declared).
    pub rig_model_pct: Option<f64>,
    /// Unshaped and shaped measured moves (sensor).
    pub moves: Option<(MeasuredMove, MeasuredMove)>,
    /// The design's V at the identified modes (%): the identified model's prediction.
    pub predicted_pct: f64,
}

impl Verification {
    /// Passed: at least one check that does not rest on the identified modes (sensor or
    /// superposition) exists, and every check is within `tol`.
    pub fn passed(&self, tol: f64) -> bool {
        let checks = [self.measured_pct, self.superposed_pct, self.rig_model_pct];
        (self.measured_pct.is_some() || self.superposed_pct.is_some())
            && checks.iter().flatten().all(|&v| v <= tol)
    }
}

/// Step 7: verification (see the module docs). Ends with the carriage where it started.
pub fn verify(
    tol: f64,
    bench: &mut Bench,
    inputs: &Inputs,
    id: &IdentifiedModes,
    d: &Design,
    recorded: Option<&(Vec<f64>, f64)>,
    tick_hz: f64,
) -> Result<Verification> {
    let predicted_pct = id
        .modes
        .iter()
        .take(d.best.modes.len())
        .map(|m| 100.0 * residual_vibration(&d.best.shaper, m.freq_hz, m.zeta))
        .fold(0.0, f64::max);
    let superposed_pct = recorded.and_then(|r| superposed_pct(r, &d.best, d.window_s, tol));
    let ts = bench.time_scale;
    let m1 = &id.modes[0];
    let settle = (1000f64.ln() / (2.0 * std::f64::consts::PI * m1.freq_hz * m1.zeta.max(1e-4)))
        .clamp(5.0, 400.0);
    let s = &mut bench.session;
    let here = s.status()?.setpoint_mm;
    let log = bench.sensor_log.clone();
    let (moves, sp) = match &log {
        None => {
            // Out unshaped-free: the shaped shaper both ways, captured on the way back.
            let out = MovePlan {
                start_mm: here,
                target_mm: d.shaped.start_mm,
                ..d.shaped
            };
            run_move(s, &out, tick_hz, ts)?;
            (None, run_move(s, &d.shaped, tick_hz, ts)?.0)
        }
        Some(log) => {
            // Unshaped reference (shaping off) from the start position, then the shaped move back.
            s.send(&crate::board::session::Command::Shaping(false))?;
            if (here - d.unshaped.start_mm).abs() > 1e-6 {
                let back = MovePlan {
                    start_mm: here,
                    target_mm: d.unshaped.start_mm,
                    ..d.unshaped
                };
                run_move(s, &back, tick_hz, ts)?;
            }
            ring_down(s, settle, tick_hz, ts)?;
            let (_, t_u) = run_move(s, &d.unshaped, tick_hz, ts)?;
            ring_down(s, settle, tick_hz, ts)?;
            program(s, &d.best)?;
            let (sp, t_s) = run_move(s, &d.shaped, tick_hz, ts)?;
            let cut = |t0: f64, p: &MovePlan| -> Result<MeasuredMove> {
                let rec =
                    read_sensor_log(log, t0 - 0.05, t0 + p.observe_ticks as f64 / tick_hz + 1.0)?;
                let (t, c, tip) = (
                    &rec.time_s,
                    rec.base_cmd_m.as_deref().unwrap_or(&[]),
                    rec.tip_pos_m.as_deref().unwrap_or(&[]),
                );
                cut_move(t, c, tip, p.start_mm * 1e-3, p.target_mm * 1e-3, d.window_s).ok_or_else(
                    || {
                        anyhow!(
                            "the camera log {} does not contain the move to {} mm",
                            log.display(),
                            p.target_mm
                        )
                    },
                )
            };
            (Some((cut(t_u, &d.unshaped)?, cut(t_s, &d.shaped)?)), sp)
        }
    };
    let rig_model_pct = match inputs.rig_declared {
        true => Some(rig_model_pct(inputs, &sp, d, tick_hz)?),
        false => None,
    };
    Ok(Verification {
        measured_pct: moves
            .as_ref()
            .map(|(mu, ms)| 100.0 * ms.residual_m / mu.residual_m),
        superposed_pct,
        rig_model_pct,
        moves,
        predicted_pct,
    })
}

/// V (%) of the rig model driven by the board's captured setpoints (shaped) and by the
/// unshaped trapezoid: the model's prediction of the same move.
fn rig_model_pct(inputs: &Inputs, sp: &[f64], d: &Design, tick_hz: f64) -> Result<f64> {
    let dt = d.shaped.capture_every as f64 / tick_hz;
    let model = BeamModel::new(&inputs.rig, &ModelOptions::default())?;
    let sim = BaseMotionSim::new(&model, dt)?;
    let (s0, s1) = (d.shaped.start_mm * 1e-3, d.shaped.target_mm * 1e-3);
    let (refm, _) = crate::model::trapezoid_reference(
        s0,
        s1,
        d.shaped.speed_mm_s * 1e-3,
        d.shaped.accel_mm_s2 * 1e-3,
        1.0 / dt,
        d.window_s + d.best.shaper.duration_s(),
    )?;
    let k0 = sp
        .iter()
        .position(|v| (v - s0).abs() > 1e-6)
        .unwrap_or(0)
        .saturating_sub(1);
    let shaped = &sp[k0..];
    let resid = |y: &[f64]| -> f64 {
        let (w, _) = sim.run(y);
        let end = y
            .iter()
            .rposition(|v| (v - s1).abs() > 1e-9)
            .map_or(0, |k| k + 1);
        w[end..]
            .iter()
            .zip(&y[end..])
            .map(|(w, y)| (y + w - s1).abs())
            .fold(0.0, f64::max)
    };
    Ok(100.0 * resid(shaped) / resid(&refm))
}

/// Step 6: programs the candidate and compares the read-back table impulse by impulse.
pub fn program(s: &mut Session, c: &Candidate) -> Result<()> {
    s.program(&c.modes, &[], true)
        .context("programming the board")?;
    let back = s.impulses().context("reading the table back")?;
    if back.len() != c.shaper.len() {
        bail!(
            "read-back table has {} impulses, designed {}",
            back.len(),
            c.shaper.len()
        );
    }
    for (b, i) in back.iter().zip(c.shaper.impulses()) {
        if (b.amplitude - i.amplitude).abs() > 1e-12 || (b.time_s - i.time_s).abs() > 1e-12 {
            bail!(
                "read-back impulse {:.6} at {:.6} s differs from the designed {:.6} at {:.6} s",
                b.amplitude,
                b.time_s,
                i.amplitude,
                i.time_s
            );
        }
    }
    Ok(())
}

/// Restores the configuration read at the start; says what was done.
fn restore(s: &mut Session, before: &BoardState) -> String {
    let modes: Vec<_> = before.config.modes.iter().flatten().copied().collect();
    let r = if before.config.custom_len > 0 && !modes.is_empty() {
        s.load()
            .map(|_| "reloaded the saved configuration (`load`)")
    } else {
        s.program(&modes, &before.custom, before.config.shaping)
            .map(|_| "reprogrammed the configuration read at the start")
    };
    match r.map_err(anyhow::Error::from).and_then(|how| {
        let now = s.config()?;
        if now.modes != before.config.modes || now.shaping != before.config.shaping {
            bail!("the board's configuration after restoring differs from the one read at the start");
        }
        Ok(how)
    }) {
        Ok(how) => format!("the board runs its previous configuration again ({how}); nothing was saved"),
        Err(e) => format!("COULD NOT RESTORE the board's previous configuration ({e:#}); its flash still holds the last saved one: power-cycle or send `load`"),
    }
}

/// What `tune` did.
pub struct TuneOutcome {
    /// The check passed and the board saved.
    pub passed: bool,
}

/// `beamtool tune`: the whole job. Errors after the board was changed restore it first.
pub fn tune(a: TuneArgs) -> Result<TuneOutcome> {
    let t0 = Instant::now();
    let inputs = check_inputs(&a)?;
    // A user recording is identified before the board is touched.
    let pre = match &inputs.recording {
        Some(p) => Some(identify_step(p)?),
        None => None,
    };
    if pre.is_none() && a.port.is_some() {
        bail!("with --port, give the recording your sensor made (run `beamtool sweep --port …` or a move while it records): tune cannot measure a real rig by itself");
    }
    let mut bench = connect(&a, &inputs)?;
    let before = read_board(&mut bench.session)?;
    println!(
        "board {}: tick {} Hz, step {} nm, max {} steps/s, at {:.3} mm, shaping {}",
        bench.port,
        before.config.tick_hz,
        before.config.step_nm,
        before.config.max_step_rate_hz,
        before.position_mm,
        if before.config.shaping { "on" } else { "off" }
    );
    let result = run_job(&a, &inputs, &mut bench, &before, pre);
    match result {
        Ok(true) => {
            println!("done in {:.1} s", t0.elapsed().as_secs_f64());
            Ok(TuneOutcome { passed: true })
        }
        Ok(false) => {
            let said = restore(&mut bench.session, &before);
            println!("{said}");
            bail!("verification failed: the measured percentage vibration exceeds --tolerance-pct {} % (see {}); {said}", a.tolerance_pct, a.out.join("tune.json").display())
        }
        Err(e) => {
            let said = restore(&mut bench.session, &before);
            Err(e.context(said))
        }
    }
}

fn run_job(
    a: &TuneArgs,
    inputs: &Inputs,
    bench: &mut Bench,
    before: &BoardState,
    pre: Option<IdentifiedModes>,
) -> Result<bool> {
    let tick_hz = before.config.tick_hz as f64;
    let (input_path, id) = match pre {
        Some(id) => (inputs.recording.clone().unwrap_or_default(), id),
        None => {
            let p = excite(a, bench, before, tick_hz)?;
            (p.clone(), identify_step(&p)?)
        }
    };
    if id.modes.is_empty() {
        bail!("no mode identified in {}", input_path.display());
    }
    println!("identified from {}:", input_path.display());
    for line in id.description.lines() {
        println!("  {line}");
    }
    let shaped_modes: Vec<ModeEstimate> = id.modes.iter().take(2).cloned().collect();
    let recorded = recorded_free_position(inputs, id.modes[0].freq_hz);
    let d = design(a, &shaped_modes, before, recorded.as_ref())?;
    println!(
        "shaper: {} — {} impulses, {:.4} s, worst-case V {:.2} % (tolerance {} % over f ± max(2σ, {} %), ζ ± 2σ); verification move {:.1} -> {:.1} mm at {} mm/s, {:.0} steps/s of {}",
        d.best.name, d.best.shaper.len(), d.best.shaper.duration_s(), d.best.worst_pct, a.tolerance_pct, a.min_band_pct,
        d.shaped.start_mm, d.shaped.target_mm, d.shaped.speed_mm_s, d.shaped.peak_step_rate_hz, before.config.max_step_rate_hz
    );
    for c in &d.runners_up {
        println!(
            "  runner-up {:<40} {:.4} s, worst V {:.2} %",
            c.name,
            c.shaper.duration_s(),
            c.worst_pct
        );
    }
    for r in &d.refused_on_recording {
        println!("  refused (shorter) {r}");
    }
    sensitivity_plot(a, &shaped_modes, &d)?;
    program(&mut bench.session, &d.best)?;
    println!(
        "programmed {} and read the table back: {} impulses identical",
        bench.port,
        d.best.shaper.len()
    );
    let v = verify(
        a.tolerance_pct,
        bench,
        inputs,
        &id,
        &d,
        recorded.as_ref(),
        tick_hz,
    )?;
    let passed = v.passed(a.tolerance_pct);
    let fmt = |p: Option<f64>| p.map_or("-".to_string(), |p| format!("{p:.2} %"));
    println!(
        "verification (percentage vibration, tolerance {} %):",
        a.tolerance_pct
    );
    println!("  measured by the camera          {}", fmt(v.measured_pct));
    println!(
        "  shaper on the recorded vibration {} (model-free superposition{}; - = no free vibration that resolves {} %)",
        fmt(v.superposed_pct),
        if inputs.acceleration { ", acceleration integrated twice" } else { "" },
        a.tolerance_pct / 2.0
    );
    println!(
        "  rig model ({})  {}",
        inputs.rig_label,
        fmt(v.rig_model_pct)
    );
    println!(
        "  predicted at the identified modes {:.2} %",
        v.predicted_pct
    );
    println!(
        "  -> {}",
        if passed {
            "PASS"
        } else if v.measured_pct.is_none() && v.superposed_pct.is_none() {
            "FAIL: nothing measured the shaper (no camera log and no recorded free vibration)"
        } else {
            "FAIL"
        }
    );
    if let Some((mu, ms)) = &v.moves {
        println!(
            "  residual after the command: unshaped {:.3} mm, shaped {:.3} mm",
            mu.residual_m * 1e3,
            ms.residual_m * 1e3
        );
        verification_plot(a, mu, ms)?;
    }
    report(a, bench, &input_path, &id, &d, &v, passed)?;
    if passed {
        bench
            .session
            .save()
            .context("saving the configuration on the board")?;
        println!(
            "saved on the board; report {}",
            a.out.join("tune.json").display()
        );
    }
    Ok(passed)
}

/// Step 3: the paper's exponential sine sweep (eq. 34) on the board, through its own
/// reference generator, recorded by the virtual rig's camera, then 30 s of ring-down.
fn excite(a: &TuneArgs, bench: &mut Bench, before: &BoardState, tick_hz: f64) -> Result<PathBuf> {
    let log = bench
        .sensor_log
        .clone()
        .ok_or_else(|| anyhow!("no sensor to record the excitation"))?;
    let off = Settings {
        shaping_enabled: false,
        ..before.settings.clone()
    };
    let plan = plan_sweep(
        &off,
        SweepKind::Exponential,
        SWEEP_BAND_HZ.0,
        SWEEP_BAND_HZ.1,
        SWEEP_AMPLITUDE_MM,
        SWEEP_DURATION_S,
    )
    .map_err(|e| anyhow!("excitation sweep: {e}"))?;
    let s = &mut bench.session;
    s.send(&crate::board::session::Command::Shaping(false))?;
    let st = s.status()?;
    wait_board(s, st.ticks, Duration::from_secs(10))?;
    let t0 = s.status()?.ticks as f64 / tick_hz;
    let ticks = s.sweep(&plan).context("starting the sweep")?;
    let end = t0 + ticks as f64 / tick_hz + SWEEP_TAIL_S;
    let wall = Duration::from_secs_f64((end - t0) / bench.time_scale + 10.0);
    wait_board(s, (end * tick_hz) as u64, wall)?;
    let rec = read_sensor_log(&log, t0 - 1.0, end)?;
    let p = a.out.join("sweep-recording.csv");
    rec.write_csv(&p)?;
    println!(
        "excitation: exponential sweep {}-{} Hz, {:.3} mm, {} s on the board (eq. 34, its own reference generator; {:.0} steps/s peak), {:.0} s recorded by the virtual rig's camera -> {}",
        plan.f0_hz, plan.f1_hz, plan.amplitude_mm, plan.duration_s, plan.peak_step_rate_hz, end - t0 + 1.0, p.display()
    );
    Ok(p)
}

fn sensitivity_plot(a: &TuneArgs, modes: &[ModeEstimate], d: &Design) -> Result<()> {
    let fmax = modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max) * 1.3;
    let f: Vec<f64> = (1..=800).map(|i| fmax * i as f64 / 800.0).collect();
    let z = modes[0].zeta;
    let v_best = sensitivity(&d.best.shaper, &f, z);
    let mut series = vec![Series {
        label: format!("{} (chosen)", d.best.name),
        x: &f,
        y: &v_best,
    }];
    let v_r = d
        .runners_up
        .first()
        .map(|r| (r.name.clone(), sensitivity(&r.shaper, &f, z)));
    if let Some((n, v)) = &v_r {
        series.push(Series {
            label: n.clone(),
            x: &f,
            y: v,
        });
    }
    let marks = Marks {
        hlines: vec![(a.tolerance_pct, format!("tolerance {} %", a.tolerance_pct))],
        shaded_x: modes
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let b = band(m, a.min_band_pct / 100.0);
                (
                    b.freq_hz.0,
                    b.freq_hz.1,
                    format!("checked band, mode {}", i + 1),
                )
            })
            .collect(),
        y_range: Some((
            0.0,
            100.0f64
                .min(8.0 * a.tolerance_pct)
                .max(2.0 * a.tolerance_pct),
        )),
    };
    let clip = |v: &[f64]| {
        v.iter()
            .map(|x| x.min(marks.y_range.unwrap().1))
            .collect::<Vec<_>>()
    };
    let (c0, c1) = (clip(&v_best), v_r.as_ref().map(|(_, v)| clip(v)));
    series[0].y = &c0;
    if let (Some(c1), Some(s)) = (&c1, series.get_mut(1)) {
        s.y = c1;
    }
    lines_marked(
        &a.out.join("sensitivity.svg"),
        &format!("percentage vibration V(f) at zeta {z:.4}"),
        "frequency (Hz)",
        "percentage vibration V (%)",
        &series,
        false,
        &marks,
    )
}

fn verification_plot(a: &TuneArgs, mu: &MeasuredMove, ms: &MeasuredMove) -> Result<()> {
    let target_u = *mu.command_m.last().unwrap_or(&0.0);
    let target_s = *ms.command_m.last().unwrap_or(&0.0);
    let band_mm = 0.02 * a.move_mm.abs();
    let tol_mm = a.tolerance_pct / 100.0 * mu.residual_m * 1e3;
    let lim = (3.0 * band_mm)
        .max(3.0 * tol_mm)
        .max(1.3 * ms.residual_m * 1e3);
    // Both residuals with the sign of the shaped move, clipped to the visible range.
    let sgn = a.move_mm.signum();
    let res = |m: &MeasuredMove, tgt: f64, s: f64| -> Vec<f64> {
        m.tip_m
            .iter()
            .map(|p| ((p - tgt) * s * 1e3).clamp(-lim, lim))
            .collect()
    };
    let (ru, rs) = (res(mu, target_u, sgn), res(ms, target_s, -sgn));
    let marks = Marks {
        hlines: vec![
            (
                band_mm,
                format!("±{band_mm:.2} mm settling band (2 % of the move)"),
            ),
            (
                -band_mm,
                format!("±{band_mm:.2} mm settling band (2 % of the move)"),
            ),
            (
                tol_mm,
                format!("±tolerance: {} % of the unshaped residual", a.tolerance_pct),
            ),
            (
                -tol_mm,
                format!("±tolerance: {} % of the unshaped residual", a.tolerance_pct),
            ),
        ],
        shaded_x: vec![],
        y_range: Some((-lim, lim)),
    };
    lines_marked(
        &a.out.join("verification.svg"),
        "verification moves measured by the camera: tip − target (clipped)",
        "time since the command started (s)",
        "tip − target (mm)",
        &[
            Series {
                label: format!("unshaped (residual {:.2} mm)", mu.residual_m * 1e3),
                x: &mu.time_s,
                y: &ru,
            },
            Series {
                label: format!("shaped (residual {:.3} mm)", ms.residual_m * 1e3),
                x: &ms.time_s,
                y: &rs,
            },
        ],
        false,
        &marks,
    )
}

fn report(
    a: &TuneArgs,
    bench: &Bench,
    input: &Path,
    id: &IdentifiedModes,
    d: &Design,
    v: &Verification,
    passed: bool,
) -> Result<()> {
    let imps: Vec<_> = d
        .best
        .shaper
        .impulses()
        .iter()
        .map(|i| serde_json::json!({"amplitude": i.amplitude, "time_s": i.time_s}))
        .collect();
    let r = serde_json::json!({
        "passed": passed,
        "input": input.display().to_string(),
        "port": bench.port,
        "identification": id.description,
        "modes": id.modes,
        "shaper": d.best.name,
        "impulses": imps,
        "duration_s": d.best.shaper.duration_s(),
        "worst_case_vibration_pct": d.best.worst_pct,
        "tolerance_pct": a.tolerance_pct,
        "verification": {
            "measured_vibration_pct": v.measured_pct,
            "superposed_vibration_pct": v.superposed_pct,
            "predicted_vibration_pct": v.predicted_pct,
            "rig_model_vibration_pct": v.rig_model_pct,
            "residual_unshaped_m": v.moves.as_ref().map(|m| m.0.residual_m),
            "residual_shaped_m": v.moves.as_ref().map(|m| m.1.residual_m),
            "move": {"start_mm": d.shaped.start_mm, "target_mm": d.shaped.target_mm, "speed_mm_s": d.shaped.speed_mm_s, "accel_mm_s2": d.shaped.accel_mm_s2, "peak_step_rate_hz": d.shaped.peak_step_rate_hz},
        },
        "units": {"freq_hz": "Hz", "zeta": "1", "amplitude": "1", "time_s": "s", "vibration_pct": "% of the unshaped residual", "residual_m": "m", "mm": "mm"},
    });
    std::fs::write(a.out.join("tune.json"), serde_json::to_string_pretty(&r)?)
        .with_context(|| format!("cannot write {}", a.out.join("tune.json").display()))
}

/// Reads a recording written by [`excite`] (for tests and tools).
pub fn read_excitation(p: &Path) -> Result<Recording> {
    Recording::read_csv(p)
}

/// The reference-rig recording the earlier `tune` generated (unshaped 0 → 50 mm move and 30 s
/// of ring-down, ideal base, 100 Hz, 20 µm noise on the tip); kept for the identification
/// tests' repro of issue 11. The default `tune` now records its own excitation on the
/// virtual rig instead.
pub fn generate_recording(rig: &Rig, path: &Path) -> Result<()> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    const SIM_RATE_HZ: f64 = 1000.0;
    let model = BeamModel::new(rig, &ModelOptions::default())?;
    let sim = BaseMotionSim::new(&model, 1.0 / SIM_RATE_HZ)?;
    let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, SIM_RATE_HZ, 30.0)?;
    let full = sim.recording(&y, 0.0);
    let every = (SIM_RATE_HZ / rig.sample_rate_hz()).round().max(1.0) as usize;
    let pick = |v: &Option<Vec<f64>>| {
        v.as_ref()
            .map(|v| v.iter().step_by(every).copied().collect::<Vec<_>>())
    };
    let mut rec = Recording {
        time_s: full.time_s.iter().step_by(every).copied().collect(),
        base_cmd_m: pick(&full.base_cmd_m),
        base_pos_m: pick(&full.base_pos_m),
        tip_pos_m: pick(&full.tip_pos_m),
        ..Default::default()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let noise = Normal::new(0.0, 20e-6).map_err(|e| anyhow!("{e}"))?;
    for v in rec.tip_pos_m.iter_mut().flatten() {
        *v += noise.sample(&mut rng);
    }
    rec.write_csv(path)
}

/// `beamtool sweep --port …`: runs the sweep of `a` (eq. 33 or 34, band, rate) on a board
/// through its own reference generator, about its present position, so that the user's
/// camera can record it for `tune --port … <recording>`. The amplitude is the largest within
/// `--stroke-mm`, the base acceleration `--accel-max` at the top frequency and the board's
/// step-rate rule with the 5 % margin. Waits until the sweep has ended. Changes no setting.
pub fn board_sweep(
    a: &crate::ident::sweep::SweepSpec,
    port: &str,
) -> Result<crate::board::plan::SweepPlan> {
    let kind = match a.kind {
        crate::ident::sweep::SweepKind::Exponential => SweepKind::Exponential,
        crate::ident::sweep::SweepKind::Linear => SweepKind::Linear,
    };
    let (fa, fb) = (a.f_a_hz, a.f_b_hz);
    if !(fa > 0.0 && fb > fa && a.rate.is_finite() && a.rate != 0.0) {
        bail!("need 0 < --f-a-hz < --f-b-hz and a non-zero --rate");
    }
    let duration_s = match kind {
        SweepKind::Exponential => (fb / fa).log2() * 60.0 / a.rate.abs(),
        SweepKind::Linear => (fb - fa) / a.rate.abs(),
    };
    let (f0, f1) = if a.rate > 0.0 { (fa, fb) } else { (fb, fa) };
    let accel_limited_mm = a.accel_max_m_s2 / (2.0 * std::f64::consts::PI * fb).powi(2) * 1e3;
    let mut s = Session::open(port)?;
    let board = read_board(&mut s)?;
    let plan = plan_sweep(
        &board.settings,
        kind,
        f0,
        f1,
        (a.stroke_max_m * 1e3).min(accel_limited_mm),
        duration_s,
    )
    .map_err(|e| anyhow!("{e}"))?;
    let st = s.status()?;
    let ticks = s.sweep(&plan).context("starting the sweep")?;
    wait_board(
        &mut s,
        st.ticks + ticks,
        Duration::from_secs_f64(ticks as f64 / f64::from(st.tick_hz) + 30.0),
    )?;
    Ok(plan)
}
