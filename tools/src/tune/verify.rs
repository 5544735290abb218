//! Step 8 of the job: the verification of the programmed shaper, each check a percentage
//! vibration (%, shaped / unshaped residual, the paper's V of eq. 27 measured):
//! - **measured**: with a sensor (the virtual rig's camera, or `--camera-log`), an unshaped
//!   reference move and the shaped move back, cut from the camera log ([`measure_pair`]);
//! - **superposed**: the shaper applied to the user's recorded free vibration (model-free,
//!   [`crate::shaping::superposed_pct`]), so a misidentified mode shows;
//! - **rig model**: the declared rig's model driven by the board's captured setpoints
//!   ([`rig_model_pct`]);
//! - **predicted**: the design's V at the identified modes (the identified model's claim,
//!   shown, never a check — unless the user accepts it with `--accept-predicted` when nothing
//!   could measure, and the board then says `verified=predicted-only`).
//!
//! The verdict ([`Outcome`]) tells "a check exceeded the tolerance" from "nothing could
//! measure the shaper", and says why each measuring check was unavailable.
//!
//! Every path ends with the carriage where it started.

use super::{Bench, Design, IdentifiedModes, Inputs, TuneError, TuneOptions};
use crate::board::plan::MovePlan;
use crate::board::rig::read_sensor_log;
use crate::board::session::{Command, Session};
use crate::board::steps::{program, ring_down, run_move, BoardState, MoveRun, StepError};
use crate::measures::{cut_move, MeasuredMove};
use crate::model::sim::BaseMotionSim;
use crate::model::{BeamModel, ModelOptions};
use crate::shaping::{superposed_check, RecordedVibration};
use beamshaper::shaper::residual_vibration;
use std::path::Path;

/// The checks of the verification (each a percentage vibration, %) and the prediction.
#[derive(Clone, Debug)]
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
    /// Why each measuring check that did not run could not (sentences; empty when one ran).
    pub unmeasured_because: Vec<String>,
    /// How the recorded vibration was sampled, when that needs saying.
    pub recorded_note: Option<String>,
}

/// The verdict of the checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// A measuring check (sensor or superposition) ran, and every check is within tolerance.
    Passed,
    /// A check (measured, superposed or the rig model) exceeds the tolerance.
    Exceeded,
    /// Nothing measured the shaper (no sensor, no recorded free vibration that resolves the
    /// tolerance); no check that ran exceeds it.
    Unmeasured,
}

impl Verification {
    /// The verdict at tolerance `tol` (%).
    pub fn outcome(&self, tol: f64) -> Outcome {
        let checks = [self.measured_pct, self.superposed_pct, self.rig_model_pct];
        if checks.iter().flatten().any(|&v| v > tol) {
            Outcome::Exceeded
        } else if self.measured_pct.is_none() && self.superposed_pct.is_none() {
            Outcome::Unmeasured
        } else {
            Outcome::Passed
        }
    }

    /// Passed: at least one check that does not rest on the identified modes (sensor or
    /// superposition) exists, and every check is within `tol` (%).
    pub fn passed(&self, tol: f64) -> bool {
        self.outcome(tol) == Outcome::Passed
    }
}

/// Runs the verification moves and computes every check (see the module docs). `recorded`
/// is the user's free vibration, or why there is none.
pub fn verify(
    o: &TuneOptions,
    bench: &mut Bench,
    inputs: &Inputs,
    id: &IdentifiedModes,
    d: &Design,
    recorded: Result<&RecordedVibration, &str>,
    before: &BoardState,
) -> Result<Verification, TuneError> {
    let tick_hz = before.tick_hz();
    let predicted_pct = id
        .modes
        .iter()
        .take(d.best.modes.len())
        .map(|m| 100.0 * residual_vibration(&d.best.shaper, m.freq_hz, m.zeta))
        .fold(0.0, f64::max);
    let mut unmeasured_because = Vec::new();
    let mut recorded_note = recorded.ok().and_then(|r| r.note.clone());
    let superposed = match recorded {
        Ok(r) => {
            let mut c = superposed_check(r, &d.best.shaper, d.window_s, o.tolerance_pct);
            if let Some((w, short)) = shorter_window_check(r, d, id, o.tolerance_pct, &c) {
                let note = format!(
                    "the recorded free vibration holds no {} s settling window after the shaper: checked over {} s ({} periods of mode 1)",
                    crate::recording::fmt_sig(d.window_s, 3),
                    crate::recording::fmt_sig(w, 3),
                    crate::recording::fmt_sig(w * id.modes[0].freq_hz, 2)
                );
                recorded_note =
                    Some(recorded_note.map_or(note.clone(), |n| format!("{n}; {note}")));
                c = short;
            }
            if let Some(why) = c.why_not(o.tolerance_pct / 2.0) {
                unmeasured_because.push(format!(
                    "the recorded free vibration cannot check it: {why}"
                ));
            }
            c.pct
        }
        Err(why) => {
            unmeasured_because.push(format!("no recorded free vibration: {why}"));
            None
        }
    };
    let here = bench.session.status().map_err(StepError::from)?.setpoint_mm;
    let (moves, setpoints) = match bench.sensor_log.clone() {
        None => {
            unmeasured_because.push(
                "no sensor watches the board's moves (no --camera-log, and the board is not the virtual rig)".into(),
            );
            (None, shaped_both_ways(bench, here, d, tick_hz)?)
        }
        Some(log) => {
            let (mu, ms, sp) = measure_pair(bench, here, id, d, &log, tick_hz)?;
            (Some((mu, ms)), sp)
        }
    };
    let rig_model_pct = match inputs.rig_declared {
        true => Some(rig_model_pct(inputs, &setpoints, d, tick_hz)?),
        false => None,
    };
    let measured_pct = moves
        .as_ref()
        .map(|(mu, ms)| 100.0 * ms.residual_m / mu.residual_m);
    if measured_pct.is_some() || superposed.is_some() {
        unmeasured_because.clear();
    }
    Ok(Verification {
        measured_pct,
        superposed_pct: superposed,
        rig_model_pct,
        moves,
        predicted_pct,
        unmeasured_because,
        recorded_note,
    })
}

/// When no settling window of `d.window_s` fits in the recorded free vibration after the
/// shaper (`c.windows == 0`), the check over the longest window that does (from the first
/// offset, a tenth of the record in), if it spans at least three periods of mode 1: the
/// percentage vibration is a ratio of peaks, which a lightly damped mode shows within one
/// period, and three let the modes' beat show. Returns that window (s) and its check.
fn shorter_window_check(
    r: &RecordedVibration,
    d: &Design,
    id: &IdentifiedModes,
    tolerance_pct: f64,
    c: &crate::measures::SuperposedCheck,
) -> Option<(f64, crate::measures::SuperposedCheck)> {
    let f1 = id.modes.first()?.freq_hz;
    let len_s = r.position_m.len() as f64 * r.dt_s;
    let w = 0.9 * len_s - d.best.shaper.duration_s() - r.equilibrium_period_s() - 3.0 * r.dt_s;
    (c.windows == 0 && w >= 3.0 / f1 && w < d.window_s)
        .then(|| (w, superposed_check(r, &d.best.shaper, w, tolerance_pct)))
}

/// Without a sensor: out to the far end and back, both shaped; the captured setpoints (m)
/// of the way back.
fn shaped_both_ways(
    bench: &mut Bench,
    here: f64,
    d: &Design,
    tick_hz: f64,
) -> Result<Vec<f64>, TuneError> {
    let (s, ts) = (&mut bench.session, bench.time_scale);
    let out = MovePlan {
        start_mm: here,
        target_mm: d.shaped.start_mm,
        ..d.shaped
    };
    run_move(s, &out, tick_hz, ts)?;
    Ok(run_move(s, &d.shaped, tick_hz, ts)?.setpoints_m)
}

/// Time (s) for mode 1 to ring down by 1000× (clamped to 5..400 s).
fn settle_s(id: &IdentifiedModes) -> f64 {
    let m1 = &id.modes[0];
    (1000f64.ln() / (2.0 * std::f64::consts::PI * m1.freq_hz * m1.zeta.max(1e-4))).clamp(5.0, 400.0)
}

/// With a sensor: the unshaped reference (shaping off) from the start position, then the
/// shaped move back, each after a ring-down, each cut from the camera log; the carriage is
/// at `here` (mm). Returns the two measured moves and the captured setpoints (m) of the
/// shaped one.
fn measure_pair(
    bench: &mut Bench,
    here: f64,
    id: &IdentifiedModes,
    d: &Design,
    log: &Path,
    tick_hz: f64,
) -> Result<(MeasuredMove, MeasuredMove, Vec<f64>), TuneError> {
    let (s, ts) = (&mut bench.session, bench.time_scale);
    let settle = settle_s(id);
    back_to_start(s, here, d, tick_hz, ts)?;
    ring_down(s, settle, tick_hz, ts)?;
    let run_u = run_move(s, &d.unshaped, tick_hz, ts)?;
    ring_down(s, settle, tick_hz, ts)?;
    program(s, &d.best)?;
    let run_s = run_move(s, &d.shaped, tick_hz, ts)?;
    let unshaped = cut_measured(log, &run_u, &d.unshaped, d.window_s)?;
    let shaped = cut_measured(log, &run_s, &d.shaped, d.window_s)?;
    Ok((unshaped, shaped, run_s.setpoints_m))
}

/// Shaping off, and from `here` (mm) back to the unshaped move's start if that is elsewhere.
fn back_to_start(
    s: &mut Session,
    here: f64,
    d: &Design,
    tick_hz: f64,
    ts: f64,
) -> Result<(), StepError> {
    s.send(&Command::Shaping(false))?;
    if (here - d.unshaped.start_mm).abs() > 1e-6 {
        let back = MovePlan {
            start_mm: here,
            target_mm: d.unshaped.start_mm,
            ..d.unshaped
        };
        run_move(s, &back, tick_hz, ts)?;
    }
    Ok(())
}

/// The move `p`, run as `run`, cut from the camera log.
fn cut_measured(
    log: &Path,
    run: &MoveRun,
    p: &MovePlan,
    window_s: f64,
) -> Result<MeasuredMove, TuneError> {
    let rec = read_sensor_log(log, run.sent_s - 0.05, run.observed_until_s + 1.0)
        .map_err(|e| TuneError::Other(e.into()))?;
    let (t, c, tip) = (
        &rec.time_s,
        rec.base_cmd_m.as_deref().unwrap_or(&[]),
        rec.tip_pos_m.as_deref().unwrap_or(&[]),
    );
    cut_move(t, c, tip, p.start_mm * 1e-3, p.target_mm * 1e-3, window_s).ok_or_else(|| {
        TuneError::Argument(format!(
            "the camera log {} does not contain the move to {} mm",
            log.display(),
            p.target_mm
        ))
    })
}

/// V (%) of the rig model driven by the board's captured setpoints `sp` (m, shaped) and by
/// the unshaped trapezoid: the model's prediction of the same move.
pub fn rig_model_pct(
    inputs: &Inputs,
    sp: &[f64],
    d: &Design,
    tick_hz: f64,
) -> Result<f64, TuneError> {
    let other = |e: anyhow::Error| TuneError::Other(e.into());
    let dt = d.shaped.capture_every as f64 / tick_hz;
    let model = BeamModel::new(&inputs.rig, &ModelOptions::default()).map_err(other)?;
    let sim = BaseMotionSim::new(&model, dt).map_err(other)?;
    let (s0, s1) = (d.shaped.start_mm * 1e-3, d.shaped.target_mm * 1e-3);
    let (refm, _) = crate::model::trapezoid_reference(
        s0,
        s1,
        d.shaped.speed_mm_s * 1e-3,
        d.shaped.accel_mm_s2 * 1e-3,
        1.0 / dt,
        d.window_s + d.best.shaper.duration_s(),
    )
    .map_err(other)?;
    let k0 = sp
        .iter()
        .position(|v| (v - s0).abs() > 1e-6)
        .unwrap_or(0)
        .saturating_sub(1);
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
    Ok(100.0 * resid(&sp[k0..]) / resid(&refm))
}
