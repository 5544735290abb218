//! Issue 72's proof on the virtual board: the reference rig (rigs/paper.toml) with a simulated
//! ADXL345 on its tip, a two-mode ZV*ZV shaper at the rig's nominal f1, f2 and `watch on`:
//! `state=ok` with f1 within 1 % before a 0.01 kg tip mass appears; within three moves after
//! it `state=drift` with f1 within 2 % of the new rig's; with `watch auto on` the board retunes
//! mode 1 to the measured f1, says `state=ok`, and the residual ratio is back to what it was
//! before the drift. The watch learns about the rig only through the simulated accelerometer.

use beamshaper::protocol::WatchReply;
use beamtools::board::accel::{adxl345, AccelSim, Drift, DriftChange, ADXL345_NOISE_M_S2};
use beamtools::board::rig::{RigSensors, VirtualRig};
use beamtools::board::VirtualBoard;
use beamtools::model::{BeamModel, ModelOptions, Rig};

const TICK_HZ: f64 = 1000.0;
/// Board time (s) at which the tip mass appears.
const DRIFT_AT_S: f64 = 20.0;
const TIP_MASS_KG: f64 = 0.01;

/// First two clamped-base natural frequencies (Hz) of `rig` with a tip mass.
fn rig_modes(rig: &Rig, tip_mass_kg: f64) -> (f64, f64) {
    let opts = ModelOptions {
        tip_mass_kg,
        ..Default::default()
    };
    let m = BeamModel::new(rig, &opts).unwrap().clamped_modes().unwrap();
    let f = |w: f64| w / (2.0 * std::f64::consts::PI);
    (f(m.omega_rad_s[0]), f(m.omega_rad_s[1]))
}

fn send(b: &mut VirtualBoard, line: &str) -> String {
    let r = b.receive(format!("{line}\n").as_bytes());
    let last = r.lines().last().unwrap_or("").to_string();
    assert!(last.starts_with("ok"), "`{line}` -> {r}");
    r
}

fn watch(b: &mut VirtualBoard) -> (WatchReply, String) {
    let r = send(b, "watch");
    (WatchReply::parse(r.lines().last().unwrap()).unwrap(), r)
}

/// One move to `target_mm`, then ticks until the watch has measured it.
fn one_move(b: &mut VirtualBoard, target_mm: f64) -> WatchReply {
    let before = watch(b).0.moves;
    send(b, &format!("move {target_mm} 150 2000"));
    for _ in 0..20_000 {
        b.tick(10);
        if watch(b).0.moves > before {
            break;
        }
    }
    let (w, text) = watch(b);
    let t = b.runtime().status().ticks as f64 / TICK_HZ;
    println!("t={t:.2} s {}", text.trim_end().replace('\n', " | "));
    w
}

fn board(rig: &Rig, log: &std::path::Path) -> VirtualBoard {
    let mut vr = VirtualRig::new(rig, RigSensors::camera(rig), TICK_HZ, log).unwrap();
    vr.attach_accel(AccelSim::new(
        adxl345(),
        ADXL345_NOISE_M_S2,
        0.3,
        1.0 / TICK_HZ,
        7,
    ));
    vr.schedule_drifts(&[Drift {
        at_s: DRIFT_AT_S,
        change: DriftChange::TipMassKg(TIP_MASS_KG),
    }]);
    let mut boot = String::new();
    let mut b = VirtualBoard::boot(None, &mut boot);
    b.attach_rig(vr);
    b
}

#[test]
fn the_watch_sees_a_tip_mass_and_retunes() {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    let (f1, f2) = rig_modes(&rig, 0.0);
    let (g1, _) = rig_modes(&rig, TIP_MASS_KG);
    println!(
        "rig f1 = {f1:.4} Hz, f2 = {f2:.4} Hz; with {TIP_MASS_KG} kg at the tip f1 = {g1:.4} Hz"
    );
    let dir = tempfile::tempdir().unwrap();
    let mut b = board(&rig, &dir.path().join("camera.csv"));
    send(&mut b, &format!("mode 1 zv {f1} 0.0074"));
    send(&mut b, &format!("mode 2 zv {f2} 0.0074"));
    send(&mut b, "watch on");
    let mut target = 100.0;
    let mut before = Vec::new();
    while (b.runtime().status().ticks as f64) < (DRIFT_AT_S - 5.0) * TICK_HZ {
        before.push(one_move(&mut b, target));
        target = 100.0 - target;
    }
    for w in &before {
        assert_eq!(w.state.name(), "ok");
        let m = w.f1_hz.unwrap();
        assert!((m / f1 - 1.0).abs() < 0.01, "f1 {m} vs {f1}");
    }
    let ratio_before = before
        .iter()
        .filter_map(|w| w.residual_ratio)
        .fold(0.0, f64::max);
    // Idle until the tip mass has appeared.
    while (b.runtime().status().ticks as f64) < (DRIFT_AT_S + 0.5) * TICK_HZ {
        b.tick(100);
    }
    let mut drifted = None;
    for _ in 0..3 {
        let w = one_move(&mut b, target);
        target = 100.0 - target;
        if w.state.name() == "drift" {
            drifted = Some(w);
            break;
        }
    }
    let w = drifted.expect("state=drift within three moves after the tip mass");
    let m = w.f1_hz.unwrap();
    assert!((m / g1 - 1.0).abs() < 0.02, "f1 {m} vs the new rig's {g1}");
    let ratio_drift = w.residual_ratio.unwrap();
    send(&mut b, "watch limits 0.5 10");
    let r = send(&mut b, "watch auto on");
    assert!(r.contains("no setpoint jump"), "{r}");
    let mut after = Vec::new();
    for _ in 0..6 {
        after.push(one_move(&mut b, target));
        target = 100.0 - target;
        // Mode 1 retuned (after two moves that agree on its frequency).
        if (after.last().unwrap().shaper_f1_hz.unwrap() / f1 - 1.0).abs() > 0.02 {
            break;
        }
    }
    // The vibration the mistuned moves left decays (ζ1 ≈ 0.0074: 1/(ζω) ≈ 21 s); then moves
    // with the retuned shaper.
    let idle_until = b.runtime().status().ticks as f64 + 90.0 * TICK_HZ;
    while (b.runtime().status().ticks as f64) < idle_until {
        b.tick(100);
    }
    for _ in 0..2 {
        after.push(one_move(&mut b, target));
        target = 100.0 - target;
    }
    let last = after.last().unwrap();
    assert!(last.retunes >= 1, "no retune");
    assert_eq!(last.state.name(), "ok");
    let shaper_f1 = last.shaper_f1_hz.unwrap();
    assert!(
        (shaper_f1 / g1 - 1.0).abs() < 0.02,
        "shaper f1 {shaper_f1} vs {g1}"
    );
    let ratio_after = last.residual_ratio.unwrap();
    println!(
        "residual ratio: before the drift <= {ratio_before:.3}, drifted {ratio_drift:.3}, after the retune {ratio_after:.3}"
    );
    // Measured (README): before the drift <= 1.023, drifted 8.45, after the retune 0.874.
    assert!(
        ratio_drift > 3.0 * ratio_before,
        "the drift must show in the residual"
    );
    assert!(ratio_after <= 1.2 * ratio_before, "residual ratio not back");
}
