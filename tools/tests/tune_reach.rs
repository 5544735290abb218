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

/// The real crane's difficulty (docs/ident.md, "Real recordings of other machines"): the
/// trolley runs 0.8 m at up to 0.2 m/s and stops within 0.2 s, then creeps 3 mm ever more
/// slowly (friction: the creep's speed falls as e^(−t/3 s)) in 0.056 mm encoder steps at
/// 29 Hz, so it takes its last step about a second before the log ends; the sway angle in
/// degrees at 30 Hz (0.00025° steps); each topic on its own rows with epoch stamps, the real
/// export's column names. The swing: 0.80 Hz, ζ 0.005, 7.4 mm of deflection per degree
/// (y'' + 2ζωy' + ω²y = −a, a the trolley's acceleration).
const CREEP_SWING_HZ: f64 = 0.80;
const MM_PER_DEG: f64 = 7.4;

/// The creeping crane's trolley velocity (m/s) at `t` s (continuous; see above).
fn creeping_trolley_velocity(t: f64) -> f64 {
    let (v0, t_stop) = (0.2, 4.65);
    if t <= 0.0 {
        0.0
    } else if t < 1.5 {
        v0 * (1.0 - (std::f64::consts::PI * t / 1.5).cos()) / 2.0
    } else if t < t_stop {
        v0
    } else if t < t_stop + 0.2 {
        v0 * (1.0 - (t - t_stop) / 0.2)
    } else {
        let s = t - t_stop - 0.2;
        -0.001 * (-s / 3.0).exp() * (1.0 - (-s / 0.2).exp())
    }
}

fn creeping_crane_log(path: &Path, seed: u64) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let stamp = Normal::new(0.0, 0.001).unwrap();
    let w = 2.0 * std::f64::consts::PI * CREEP_SWING_HZ;
    let (dt, q) = (1e-4, 5.6e-5);
    let (mut x, mut y, mut v, mut t) = (0.0f64, 0.0f64, 0.0f64, -0.5f64);
    let (mut next_trolley, mut next_angle) = (-0.5, -0.5 + rng.gen_range(0.0..0.03));
    let mut rows: Vec<(f64, String)> = Vec::new();
    while t < 15.0 {
        let a = (creeping_trolley_velocity(t + dt) - creeping_trolley_velocity(t)) / dt;
        let acc = -2.0 * SWING_ZETA * w * v - w * w * y - a;
        v += acc * dt;
        y += v * dt;
        x += creeping_trolley_velocity(t) * dt;
        t += dt;
        if t >= next_trolley {
            let xq = (x / q).round() * q;
            rows.push((t + stamp.sample(&mut rng), format!(",{xq:.9}")));
            next_trolley += 1.0 / 29.0;
        }
        if t >= next_angle {
            let deg = (y * 1e3 / MM_PER_DEG / 0.00025).round() * 0.00025;
            rows.push((t + stamp.sample(&mut rng), format!("{deg:.9},")));
            next_angle += 1.0 / 30.0;
        }
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut s = String::from("__time,/sway_angle/data,/trolley_position/data\n");
    for (t, r) in rows {
        writeln!(s, "{:.6},{r}", 1_717_494_492.0 + t).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_crane_whose_trolley_creeps_in_encoder_steps_after_the_stop_rings_down_and_is_saved() {
    let tmp = tempfile::Builder::new()
        .prefix("beamshaper-test-creep-")
        .tempdir()
        .unwrap();
    let columns = beamtools::recording::ColumnMap::parse(&format!(
        "time_s=__time,base_pos_m=/trolley_position/data,tip_defl_m=/sway_angle/data:{}",
        MM_PER_DEG * 1e-3
    ))
    .unwrap();
    for seed in 1..=2 {
        let log = tmp.path().join(format!("creep{seed}.csv"));
        creeping_crane_log(&log, seed);
        let mut opts = beamtools::ident::IdentifyOptions::default();
        opts.read.columns = Some(columns.clone());
        let id = beamtools::ident::identify::identify_file(&log, &opts, &mut |_| {})
            .unwrap_or_else(|e| panic!("seed {seed}: {e:#}"));
        assert_eq!(
            id.path,
            beamtools::ident::IdentPath::RingDown,
            "{}",
            id.reason
        );
        assert!(id.base.as_ref().unwrap().quiet.is_some(), "{}", id.reason);
        let m = &id.modes[0];
        assert!(
            (m.freq_hz - CREEP_SWING_HZ).abs() < (3.0 * m.freq_hz_std).max(0.004),
            "seed {seed}: f {} ± {}",
            m.freq_hz,
            m.freq_hz_std
        );
        assert!(
            (m.zeta - SWING_ZETA).abs() < 3.0 * m.zeta_std,
            "seed {seed}: ζ {} ± {}",
            m.zeta,
            m.zeta_std
        );
        let out = tmp.path().join(format!("out{seed}"));
        let mut args = TuneArgs::new(Some(log.clone()), &out);
        args.read.columns = Some(columns.clone());
        let report = tune(args).unwrap_or_else(|e| panic!("seed {seed}: {e:#}"));
        assert!(report.passed, "seed {seed}");
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
        assert_eq!(r["verified"], "measured", "seed {seed}");
    }
}
