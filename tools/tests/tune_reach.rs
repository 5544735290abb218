//! `tune` on recordings shaped like other machines' logs: a gantry crane's free swing logged
//! row-wise (a ROS bag exported to CSV), the sway angle a 22 Hz sample-and-hold staircase of
//! 1 mrad steps in a ~100 Hz log with a jittering update clock. The model-free check reads
//! the swing at the sensor's own update rate and resolves a 2 % tolerance on it.

use beamtools::cli::tune::{tune, TuneArgs};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::fmt::Write as _;
use std::path::Path;

/// Rope length (m): the angle times it is the payload's deflection.
const ROPE_M: f64 = 0.45;
/// The swing's natural frequency (Hz) and damping ratio.
const SWING_HZ: f64 = 0.735;
const SWING_ZETA: f64 = 0.005;

/// A crane log: the trolley moves 0.3 m in 2 s (a cycloid) and stops; the payload swings
/// (linearised pendulum on the moving support, θ'' + 2ζωθ' + ω²θ = −a/L) free for 14 s.
/// Rows: the trolley at 100 Hz, the angle at 22 Hz (its clock jittering by 2 ms a period),
/// each row one topic, stamps jittered by 0.5 ms; angle rounded to 1 mrad. Columns in the
/// project's names and SI (tip = L·θ), so no column map is needed.
fn crane_log(path: &Path, seed: u64) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let stamp = Normal::new(0.0, 0.0005).unwrap();
    let clock = Normal::new(0.0, 0.002).unwrap();
    let w = 2.0 * std::f64::consts::PI * SWING_HZ;
    let (x_move, t_move, dt) = (0.30, 2.0, 1e-4);
    let trolley = |t: f64| -> (f64, f64) {
        if t <= 0.0 {
            return (0.0, 0.0);
        }
        if t >= t_move {
            return (x_move, 0.0);
        }
        let u = t / t_move;
        let two_pi = 2.0 * std::f64::consts::PI;
        (
            x_move * (u - (two_pi * u).sin() / two_pi),
            x_move * two_pi / (t_move * t_move) * (two_pi * u).sin(),
        )
    };
    let (mut th, mut om, mut t) = (0.0f64, 0.0f64, -0.5f64);
    let (mut next_trolley, mut next_angle) = (-0.5, -0.5 + rng.gen_range(0.0..0.045));
    let mut rows: Vec<(f64, String)> = Vec::new();
    while t < 16.5 {
        let (x, a) = trolley(t);
        let acc = -2.0 * SWING_ZETA * w * om - w * w * th - a / ROPE_M;
        om += acc * dt;
        th += om * dt;
        t += dt;
        if t >= next_trolley {
            rows.push((t + stamp.sample(&mut rng), format!("{x:.6},")));
            next_trolley += 0.01;
        }
        if t >= next_angle {
            let q = (th / 0.001).round() * 0.001 * ROPE_M;
            rows.push((t + stamp.sample(&mut rng), format!(",{q:.6}")));
            next_angle += 1.0 / 22.0 + clock.sample(&mut rng);
        }
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut s = String::from("time_s,base_pos_m,tip_pos_m\n");
    for (t, r) in rows {
        writeln!(s, "{t:.4},{r}").unwrap();
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_crane_swing_logged_row_wise_at_22_hz_is_checked_on_itself_and_saved() {
    let tmp = tempfile::Builder::new()
        .prefix("beamshaper-test-crane-")
        .tempdir()
        .unwrap();
    for seed in 1..=3 {
        let log = tmp.path().join(format!("crane{seed}.csv"));
        crane_log(&log, seed);
        let out = tmp.path().join(format!("out{seed}"));
        let report = tune(TuneArgs::new(Some(log.clone()), &out))
            .unwrap_or_else(|e| panic!("seed {seed}: {e:#}"));
        assert!(report.passed, "seed {seed}");
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
        assert_eq!(r["verified"], "measured", "seed {seed}");
        let f = r["modes"][0]["freq_hz"].as_f64().unwrap();
        assert!((f / SWING_HZ - 1.0).abs() < 0.01, "seed {seed}: f {f}");
        let v = r["verification"]["superposed_vibration_pct"]
            .as_f64()
            .expect("the recorded swing checks the shaper");
        assert!(v <= 2.0, "seed {seed}: {v} % on the recording");
        let note = report
            .verification
            .recorded_note
            .clone()
            .unwrap_or_default();
        assert!(note.contains("staircase"), "seed {seed}: {note}");
    }
}
