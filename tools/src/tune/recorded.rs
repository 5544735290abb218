//! The vibration a recording holds, for the model-free check ([`free_vibration`],
//! [`recorded_free_position`]), and the reference-rig recording of the earlier `tune`
//! ([`generate_recording`], kept for the identification tests).

use super::Inputs;
use crate::measures::displacement_from_acceleration;
use crate::model::sim::BaseMotionSim;
use crate::model::{BeamModel, ModelOptions, Rig};
use crate::recording::{ReadOptions, Recording};
use crate::shaping::RecordedVibration;
use std::path::Path;

/// The free vibration in a recording read as `read` says, for the model-free check: tip (minus
/// base, when there is one) after the base last left its final position by more than 20 µm,
/// from the largest excursion on, resampled to its median step. A recording with a tip
/// accelerometer and no tip position gives the acceleration (m/s²; the base is not
/// subtracted). Returns (signal, step s, the signal is that acceleration); `None` when there
/// is none (e.g. a sweep that ends moving) or the file cannot be read.
pub fn free_vibration(path: &Path, read: &ReadOptions) -> Option<(Vec<f64>, f64, bool)> {
    let rec = Recording::read_any_with(path, read, &mut |_| {}).ok()?;
    if rec.tip_pos_m.is_none() {
        let acc = rec.tip_acc_m_s2.as_ref()?;
        let (x, dt) = from_largest_excursion(&rec.time_s, acc)?;
        return Some((x, dt, true));
    }
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
    let (x, dt) = from_largest_excursion(&rec.time_s[start..], &sig[start..])?;
    Some((x, dt, false))
}

/// `x` at times `t` resampled to its median step, from its largest excursion (in its first
/// half) on; `None` for fewer than 64 samples.
fn from_largest_excursion(t: &[f64], x: &[f64]) -> Option<(Vec<f64>, f64)> {
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

/// The user's recorded free vibration as tip position (m) at a uniform step (s), for the
/// model-free check: an accelerometer's signal integrated twice (high-passed at half the first
/// identified natural frequency). `None` when the input has none (generated sweep, or a
/// recording that ends moving).
pub fn recorded_free_position(inputs: &Inputs, f1_hz: f64) -> Option<RecordedVibration> {
    let (x, dt, acc) = free_vibration(inputs.recording.as_deref()?, &inputs.read)?;
    let pos = match inputs.acceleration || acc {
        true => displacement_from_acceleration(&x, dt, 0.5 * f1_hz),
        false => x,
    };
    Some(RecordedVibration {
        position_m: pos,
        dt_s: dt,
    })
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
