//! The vibration a recording holds, for the model-free check ([`free_vibration`],
//! [`recorded_free_position`]), and the reference-rig recording of the earlier `tune`
//! ([`generate_recording`], kept for the identification tests).

use super::Inputs;
use crate::measures::displacement_from_acceleration;
use crate::model::sim::BaseMotionSim;
use crate::model::{BeamModel, ModelOptions, Rig};
use crate::recording::{hold, ReadOptions, Recording};
use crate::shaping::RecordedVibration;
use std::path::Path;

/// A recording's free vibration, as its sensor sampled it ([`free_vibration`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FreeVibration {
    /// Samples (the channel's unit: m, or m/s² for an acceleration), uniform.
    pub x: Vec<f64>,
    /// Sample step (s): the sensor's update period when the log holds its samples.
    pub dt_s: f64,
    /// Quantisation step of the samples (0 when continuous).
    pub quantum: f64,
    /// The signal is the tip acceleration (`tip_acc_m_s2`), not a position.
    pub acceleration: bool,
    /// What was done to reach the sensor's own samples (for the user), if anything.
    pub note: Option<String>,
}

/// The free vibration in a recording, for the model-free check: tip position (minus base,
/// when there is one) — or the tip acceleration when the recording has no position — after
/// the base last left its final position by more than 20 µm, from the largest excursion on,
/// at the sensor's own samples:
/// - a sample-and-hold staircase (a slow sensor in a fast log, or a row-wise log
///   forward-filled; [`crate::recording::hold::staircase`]) is read back at its update
///   period, one value from the middle of each hold (robust to an update jitter below half a
///   period), so the log's repeated rows are not mistaken for smooth samples;
/// - otherwise resampled to the median step;
/// - the quantisation step ([`crate::recording::hold::quantum`]) is kept for the noise
///   bound of the check.
///
/// Errors (a sentence for the user): the file cannot be read, has no tip channel, or holds no
/// free vibration (fewer than 64 samples after the base's last move, e.g. a sweep that ends
/// moving).
pub fn free_vibration(path: &Path, opts: &ReadOptions) -> Result<FreeVibration, String> {
    let rec = Recording::read_any_with(path, opts, &mut |_| {}).map_err(|e| format!("{e:#}"))?;
    free_vibration_of(&rec)
}

/// [`free_vibration`] of a recording already read (e.g. one built from arrays by the Python
/// package). Errors: as [`free_vibration`], except reading.
pub fn free_vibration_of(rec: &Recording) -> Result<FreeVibration, String> {
    let (tip, acceleration) = match (&rec.tip_pos_m, &rec.tip_acc_m_s2) {
        (Some(p), _) => (p, false),
        (None, Some(a)) => (a, true),
        (None, None) => {
            return Err("the recording has no tip channel (tip_pos_m or tip_acc_m_s2)".into())
        }
    };
    let base = rec.base_pos_m.as_ref().or(rec.base_cmd_m.as_ref());
    let (sig, start): (Vec<f64>, usize) = match base {
        Some(b) if !acceleration => {
            let last = *b.last().ok_or("the recording is empty")?;
            let moved = b
                .iter()
                .rposition(|v| (v - last).abs() > 20e-6)
                .map_or(0, |k| k + 1);
            // a base that creeps after its move but no longer excites the tip: the free
            // vibration starts where identification's ring-down does (ident::quiet)
            let quiet = crate::ident::identify::quiet_ring_down_start(rec).unwrap_or(moved);
            (
                tip.iter().zip(b).map(|(t, b)| t - b).collect(),
                moved.min(quiet),
            )
        }
        Some(b) => {
            let last = *b.last().ok_or("the recording is empty")?;
            let moved = b
                .iter()
                .rposition(|v| (v - last).abs() > 20e-6)
                .map_or(0, |k| k + 1);
            (tip.clone(), moved)
        }
        None => (tip.clone(), 0),
    };
    let (t, x) = (&rec.time_s[start..], &sig[start..]);
    if t.len() < 64 {
        return Err(format!(
            "only {} samples follow the base's last move: no free vibration to apply the shaper to",
            t.len()
        ));
    }
    // The sensor's step is the tip channel's own (the base is at rest here).
    let quantum = hold::quantum(&tip[start..]);
    let b = base.filter(|_| !acceleration).map(|b| &b[start..]);
    let (xu, dt, note) = sensor_samples(t, x, &tip[start..], b, quantum);
    if xu.len() < 16 {
        return Err(format!(
            "only {} sensor samples of free vibration",
            xu.len()
        ));
    }
    let mean = xu.iter().sum::<f64>() / xu.len() as f64;
    let half = &xu[..xu.len() / 2];
    let k = (0..half.len())
        .max_by(|&i, &j| (half[i] - mean).abs().total_cmp(&(half[j] - mean).abs()))
        .ok_or("no free vibration")?;
    Ok(FreeVibration {
        x: xu[k..].to_vec(),
        dt_s: dt,
        quantum: quantum.unwrap_or(0.0),
        acceleration,
        note,
    })
}

/// The free vibration `x` (at times `t`) as the tip's sensor sampled it: a sample-and-hold
/// staircase read at its update rate ([`held_samples`]), else resampled at the median step.
/// The staircase is looked for in `x`, then in the tip channel `tip` (a base `base` that still
/// creeps changes the deflection on other rows; the base is then interpolated at the tip's
/// samples and subtracted). Returns (samples, step s, note).
fn sensor_samples(
    t: &[f64],
    x: &[f64],
    tip: &[f64],
    base: Option<&[f64]>,
    quantum: Option<f64>,
) -> (Vec<f64>, f64, Option<String>) {
    let staircase = match hold::staircase(t, x, quantum) {
        Some(st) => Some((st, None)),
        None => base.and_then(|b| hold::staircase(t, tip, quantum).map(|st| (st, Some(b)))),
    };
    let Some((st, b)) = staircase else {
        let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        let dt = steps[steps.len() / 2];
        let (_, xu, _) = crate::recording::resample_uniform(t, x, 1.0 / dt);
        return (xu, dt, None);
    };
    let held = match b {
        None => held_samples(t, x, st.period_s).1,
        Some(b) => {
            let (tg, mut held) = held_samples(t, tip, st.period_s);
            for (h, tk) in held.iter_mut().zip(&tg) {
                *h -= interpolate(t, b, *tk);
            }
            held
        }
    };
    let note = format!(
        "the tip channel is a sample-and-hold staircase: {} samples at its update rate {} Hz (log rows at {} Hz){}",
        held.len(),
        crate::recording::fmt_sig(st.update_rate_hz, 3),
        crate::recording::fmt_sig(st.row_rate_hz, 3),
        if b.is_some() { ", the base interpolated at them" } else { "" }
    );
    (held, st.period_s, Some(note))
}

/// The sensor's samples in a sample-and-hold log (`x` at times `t`, updated every
/// `period_s` on average): each change of value is an update, seen on the first row after
/// it; a gap of m periods between changes holds m − 1 updates that repeated the value (a
/// quantised signal at a turning point), placed evenly in it. These (time, value) samples
/// are resampled to the uniform step `period_s` by linear interpolation — the sensor's own
/// time stamps kept, so a jittering update clock does not shift the samples.
/// Returns the uniform grid's times (s) and values.
fn held_samples(t: &[f64], x: &[f64], period_s: f64) -> (Vec<f64>, Vec<f64>) {
    let mut ts: Vec<f64> = Vec::new();
    let mut xs: Vec<f64> = Vec::new();
    for k in 1..x.len() {
        if x[k] == x[k - 1] {
            continue;
        }
        if let Some(&last) = ts.last() {
            let m = ((t[k] - last) / period_s).round().max(1.0) as usize;
            let held = xs[xs.len() - 1];
            for j in 1..m {
                ts.push(last + (t[k] - last) * j as f64 / m as f64);
                xs.push(held);
            }
        }
        ts.push(t[k]);
        xs.push(x[k]);
    }
    if ts.len() < 2 {
        return (ts, xs);
    }
    let (tu, xu, _) = crate::recording::resample_uniform(&ts, &xs, 1.0 / period_s);
    (tu, xu)
}

/// `x` (at increasing times `t`) at time `tk` by linear interpolation, held at the ends.
fn interpolate(t: &[f64], x: &[f64], tk: f64) -> f64 {
    let j = t.partition_point(|v| *v <= tk);
    if j == 0 {
        return x[0];
    }
    if j >= t.len() {
        return x[t.len() - 1];
    }
    let a = (tk - t[j - 1]) / (t[j] - t[j - 1]);
    (1.0 - a) * x[j - 1] + a * x[j]
}

/// The user's recorded free vibration as tip position (m) at a uniform step (s), for the
/// model-free check: an accelerometer's signal integrated twice (high-passed at half the first
/// identified natural frequency `f1_hz`; `f_max_hz` the highest identified one). Errors (a
/// sentence): no recording (a generated sweep), or [`free_vibration`]'s reasons.
pub fn recorded_free_position(
    inputs: &Inputs,
    f1_hz: f64,
    f_max_hz: f64,
) -> Result<RecordedVibration, String> {
    let path = inputs
        .recording
        .as_deref()
        .ok_or("no user recording (the excitation was generated)")?;
    let fv = free_vibration(path, &inputs.read)?;
    Ok(recorded_position(fv, inputs.acceleration, f1_hz, f_max_hz))
}

/// A [`FreeVibration`] as tip position (m) for the model-free check: integrated twice
/// (high-passed at half `f1_hz`) when `acceleration` or the signal is the tip acceleration;
/// `f_max_hz` the highest identified natural frequency ([`recorded_free_position`]).
pub fn recorded_position(
    fv: FreeVibration,
    acceleration: bool,
    f1_hz: f64,
    f_max_hz: f64,
) -> RecordedVibration {
    let (pos, quantum_m) = match acceleration || fv.acceleration {
        // the quantum of an acceleration does not carry over to its double integral
        true => (
            displacement_from_acceleration(&fv.x, fv.dt_s, 0.5 * f1_hz),
            0.0,
        ),
        false => (fv.x, fv.quantum),
    };
    RecordedVibration {
        position_m: pos,
        dt_s: fv.dt_s,
        quantum_m,
        content_hz: f_max_hz,
        lowest_hz: f1_hz,
        note: fv.note,
    }
}

/// The reference-rig recording the earlier `tune` generated (unshaped 0 → 50 mm move and 30 s
/// of ring-down, ideal base, 100 Hz, 20 µm noise on the tip); kept for the identification
/// tests' repro of issue 11. The default `tune` now records its own excitation on the
/// virtual rig instead.
pub fn generate_recording(rig: &Rig, path: &Path) -> anyhow::Result<()> {
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
    let noise = Normal::new(0.0, 20e-6).map_err(|e| anyhow::anyhow!("{e}"))?;
    for v in rec.tip_pos_m.iter_mut().flatten() {
        *v += noise.sample(&mut rng);
    }
    rec.write_csv(path)
}
