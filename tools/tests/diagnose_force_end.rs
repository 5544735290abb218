//! A recording that ends while the carriage moves: the model's motor force at the last sample
//! is the force of the motion, not of a stop that never happened (a −v/dt kick there bent the
//! force calibration's mass and latency).

use beamtools::diagnose::model::{predict, Params, Prepared};
use beamtools::model::Rig;
use beamtools::recording::Recording;

const CARRIAGE: &str = "[base]\nmass_kg = 4.0\n[sensors]\nsample_rate_hz = 50\n";
const WITH_BEAM: &str = "[beam]\nlength_m = 0.5\ndensity_kg_m3 = 7900.0\nyoungs_modulus_pa = 2.0e11\nstations = [\n  { x_m = 0.0, width_m = 0.02, thickness_m = 0.002 },\n  { x_m = 0.5, width_m = 0.02, thickness_m = 0.002 },\n]\n[base]\nmass_kg = 4.0\n[damping]\nratios = [0.01, 0.02]\n[sensors]\nsample_rate_hz = 50\n";

/// 4 s at 50 Hz: at rest for 1 s, then a smooth (cosine) acceleration to 0.1 m/s over 1 s,
/// then constant speed until the recording ends.
fn moving_at_the_end() -> Recording {
    let rate = 50.0;
    let n = 200;
    let mut rec = Recording::with_uniform_time(n, rate);
    let pos: Vec<f64> = (0..=n)
        .scan((0.0f64, 0.0f64), |(x, v), k| {
            let t = k as f64 / rate;
            let a = if (1.0..2.0).contains(&t) {
                0.1 * (1.0 - (2.0 * std::f64::consts::PI * (t - 1.0)).cos())
            } else {
                0.0
            };
            let out = *x;
            *v += a / rate;
            *x += *v / rate;
            Some(out)
        })
        .take(n)
        .collect();
    rec.base_cmd_m = Some(pos.clone());
    rec.base_pos_m = Some(pos);
    rec.force_n = Some(vec![0.0; n]);
    rec
}

fn last_forces(rig_toml: &str) -> (f64, f64) {
    let rig = Rig::from_toml_str(rig_toml).unwrap();
    let d = Prepared::new("moving", &moving_at_the_end()).unwrap();
    let mut cache = None;
    let f = predict(&rig, &Params::default(), &d, &mut cache)
        .unwrap()
        .force_n
        .unwrap();
    let n = f.len();
    (f[n - 2], f[n - 1])
}

#[test]
fn the_last_force_sample_of_a_carriage_still_moving_has_no_stop_spike() {
    // a stop within one sample would be 4 kg × 0.1 m/s / 0.02 s = 20 N
    let (before, last) = last_forces(CARRIAGE);
    assert!(before.abs() < 0.05, "cruise force {before}");
    assert!(last.abs() < 0.05, "last sample {last}");
}

#[test]
fn the_last_force_sample_with_a_beam_has_no_stop_spike() {
    let (before, last) = last_forces(WITH_BEAM);
    // the beam still rings after the acceleration; the last sample is like the one before it
    assert!((last - before).abs() < 1.0, "before {before}, last {last}");
}
