//! The job's inputs and bench: options checked and files read before any board is touched
//! ([`check_inputs`]), the board connected — a real port, or the virtual board with the virtual
//! rig attached ([`connect`]) — and, without a user recording, the excitation the virtual rig's
//! camera records ([`excite`]).

use super::{Signal, TuneError, TuneOptions, DEFAULT_RIG_TOML};
use super::{SWEEP_AMPLITUDE_MM, SWEEP_BAND_HZ, SWEEP_DURATION_S, SWEEP_TAIL_S};
use crate::board::client::BoardClient;
use crate::board::plan::{
    plan_sweep, SweepPlan, ACCEL_LIMIT_MM_S2, SPEED_LIMIT_MM_S, TARGET_LIMIT_MM,
};
use crate::board::rig::{read_sensor_log, RigSensors, VirtualRig};
use crate::board::session::Session;
use crate::board::steps::{run_sweep, shaping_off, BoardState, StepError};
use crate::model::{BeamModel, ModelOptions, Rig};
use beamshaper::config::Settings;
use beamshaper::reference::SweepKind;
use std::path::PathBuf;

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
    /// How the recording is read (`--columns`, `--axis`).
    pub read: crate::recording::ReadOptions,
}

/// Refuses an option out of its range; the message names the option.
fn check_numbers(o: &TuneOptions) -> Result<(), TuneError> {
    let bad = |m: String| Err(TuneError::Argument(m));
    if !(o.tolerance_pct >= 0.2 && o.tolerance_pct <= 50.0) {
        return bad(format!("--tolerance-pct must be between 0.2 and 50 % (got {}); a tighter tolerance cannot be verified against sensor noise", o.tolerance_pct));
    }
    if !(0.0..=50.0).contains(&o.min_band_pct) {
        return bad(format!(
            "--min-band-pct must be between 0 and 50 % (got {})",
            o.min_band_pct
        ));
    }
    if o.move_mm.abs() < 1e-3 || o.move_mm.abs() > TARGET_LIMIT_MM {
        return bad(format!("--move-mm {} cannot be verified: the move must be between 0.001 and 1000 mm long (either sign) and end within the board's ±1000 mm", o.move_mm));
    }
    if !(o.speed_mm_s > 0.0 && o.speed_mm_s <= SPEED_LIMIT_MM_S) {
        return bad(format!(
            "--speed-mm-s must be > 0 and at most 10000 mm/s (got {})",
            o.speed_mm_s
        ));
    }
    if !(o.accel_mm_s2 > 0.0 && o.accel_mm_s2 <= ACCEL_LIMIT_MM_S2) {
        return bad(format!(
            "--accel-mm-s2 must be > 0 and at most 1e6 mm/s² (got {})",
            o.accel_mm_s2
        ));
    }
    if !(o.time_scale >= 1.0 && o.time_scale <= 1000.0) {
        return bad(format!(
            "--time-scale must be between 1 and 1000 (got {})",
            o.time_scale
        ));
    }
    Ok(())
}

/// The rig of `--rig`, or the embedded reference rig, with its label; it must give a usable
/// beam model.
fn read_rig(o: &TuneOptions) -> Result<(Rig, String), TuneError> {
    let (rig, label) = match &o.rig {
        Some(p) => (
            Rig::from_toml_file(p)
                .map_err(|e| TuneError::failed(format!("rig file {}", p.display()), e))?,
            p.display().to_string(),
        ),
        None => (
            Rig::from_toml_str(DEFAULT_RIG_TOML).map_err(|e| TuneError::Other(e.into()))?,
            "the reference rig (rigs/paper.toml, built in)".to_string(),
        ),
    };
    BeamModel::new(&rig, &ModelOptions::default())
        .map_err(|e| TuneError::failed(format!("rig {label}: no usable beam model"), e))?;
    Ok((rig, label))
}

/// Step 1: validates every option and reads every file, before the board is touched.
/// Errors: an option out of range, an unreadable rig or recording, `--port` without a
/// recording (tune cannot measure a real rig by itself), an uncreatable work directory.
pub fn check_inputs(o: &TuneOptions) -> Result<Inputs, TuneError> {
    check_numbers(o)?;
    let (rig, rig_label) = read_rig(o)?;
    if let Some(r) = &o.recording {
        std::fs::File::open(r).map_err(|e| {
            TuneError::failed(format!("cannot read the recording {}", r.display()), e)
        })?;
    }
    if o.recording.is_none() && o.port.is_some() {
        return Err(TuneError::Argument("with --port, give the recording your sensor made (run `beamtool sweep --port …` or a move while it records): tune cannot measure a real rig by itself".into()));
    }
    std::fs::create_dir_all(&o.work_dir)
        .map_err(|e| TuneError::failed(format!("cannot create {}", o.work_dir.display()), e))?;
    Ok(Inputs {
        rig,
        rig_label,
        recording: o.recording.clone(),
        rig_declared: o.rig.is_some() || o.recording.is_none(),
        acceleration: match o.signal {
            Signal::Acceleration => true,
            Signal::Position => false,
            Signal::Auto => o
                .recording
                .as_ref()
                .is_some_and(|p| p.extension().is_some_and(|e| e == "npy")),
        },
        read: o.read.clone(),
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

/// Step 3: opens `--port`, or starts the virtual board (with the rig attached when the rig
/// describes the beam being tuned).
pub fn connect(o: &TuneOptions, inputs: &Inputs) -> Result<Bench, TuneError> {
    if let Some(p) = &o.port {
        let session = Session::open(p).map_err(StepError::from)?;
        return Ok(Bench {
            session,
            port: p.clone(),
            sensor_log: o.camera_log.clone(),
            time_scale: 1.0,
        });
    }
    let flash = Some(o.work_dir.join("vboard-flash.bin"));
    // A user recording of some other beam: a virtual board without a rig; the check is the
    // model-free superposition on that recording.
    let (rig, sensor_log) = match inputs.rig_declared {
        false => (None, None),
        true => {
            let log = o.work_dir.join("vboard-camera.csv");
            let sensors = RigSensors::camera(&inputs.rig);
            let tick_hz = Settings::DEFAULT.tick_rate_hz as f64;
            let rig = VirtualRig::new(&inputs.rig, sensors, tick_hz, &log)
                .map_err(|e| TuneError::Other(e.into()))?;
            (Some(rig), Some(log))
        }
    };
    let port = crate::board::spawn_on_pty_with_rig(flash, o.time_scale, rig)
        .map_err(|e| TuneError::Other(e.into()))?;
    let client = BoardClient::open(&port).map_err(|e| StepError::Session(e.into()))?;
    Ok(Bench {
        session: Session::new(client),
        port,
        sensor_log,
        time_scale: o.time_scale,
    })
}

/// An excitation run on the board and recorded by the rig's camera.
#[derive(Clone, Debug)]
pub struct Excitation {
    /// The sweep run.
    pub plan: SweepPlan,
    /// Board time recorded (s).
    pub recorded_s: f64,
    /// The recording (CSV in the work directory).
    pub recording: PathBuf,
}

/// Step 5: the paper's exponential sine sweep (eq. 34) on the board, unshaped, through its
/// own reference generator, recorded by the virtual rig's camera with [`SWEEP_TAIL_S`] of
/// ring-down; the recording is written to `sweep-recording.csv` in the work directory.
pub fn excite(
    o: &TuneOptions,
    bench: &mut Bench,
    before: &BoardState,
) -> Result<Excitation, TuneError> {
    let log = bench
        .sensor_log
        .clone()
        .ok_or_else(|| TuneError::Argument("no sensor to record the excitation".into()))?;
    let (f0, f1) = SWEEP_BAND_HZ;
    let plan = plan_sweep(
        &before.unshaped_settings(),
        SweepKind::Exponential,
        f0,
        f1,
        SWEEP_AMPLITUDE_MM,
        SWEEP_DURATION_S,
    )
    .map_err(|source| TuneError::Plan {
        what: "excitation sweep",
        source,
    })?;
    shaping_off(&mut bench.session)?;
    let (t0, end) = run_sweep(
        &mut bench.session,
        &plan,
        SWEEP_TAIL_S,
        bench.time_scale,
        10.0,
    )?;
    let rec = read_sensor_log(&log, t0 - 1.0, end).map_err(|e| TuneError::Other(e.into()))?;
    let recording = o.work_dir.join("sweep-recording.csv");
    rec.write_csv(&recording)
        .map_err(|e| TuneError::Other(e.into()))?;
    Ok(Excitation {
        plan,
        recorded_s: end - t0 + 1.0,
        recording,
    })
}
