//! Calibration parameters the recordings do not identify (the damping of a mode they do not
//! excite) are reported as "not identified" with a reason, never as a number.

mod common;

use beamtools::diagnose::effects::{calibration_unidentified, ParamDef, Transform};
use beamtools::truth::TruthOptions;

fn def(name: &'static str, transform: Transform) -> ParamDef {
    ParamDef {
        name,
        transform,
        starts: vec![1.0],
        scale: 1.0,
        zero_is_null: false,
        scan: Vec::new(),
    }
}

#[test]
fn unidentified_calibration_values_are_recognised() {
    let zeta = def("zeta_mode8", Transform::Log);
    // what a 1000 Hz recording printed for a mode it does not excite
    assert!(calibration_unidentified(&zeta, 300.0, f64::NAN).is_some());
    assert!(calibration_unidentified(&zeta, 1.37, 0.01).is_some());
    assert!(calibration_unidentified(&zeta, 1e-9, 1e-10).is_some());
    assert!(calibration_unidentified(&zeta, 0.21, 0.31).is_some());
    assert!(calibration_unidentified(&zeta, 0.02, 0.0).is_some());
    assert!(calibration_unidentified(&zeta, 0.0166, 1.5e-5).is_none());
    let scale = def("stiffness_scale", Transform::Log);
    assert!(calibration_unidentified(&scale, 0.95, 5e-5).is_none());
    // a signed correction within 2 σ of zero is "as nominal", identified
    let mass = def("base_mass_delta_kg", Transform::Linear);
    assert!(calibration_unidentified(&mass, -0.42, 0.26).is_none());
    assert!(calibration_unidentified(&mass, -0.42, f64::NAN).is_some());
}

#[test]
fn a_mode_the_recordings_do_not_excite_has_no_reported_damping() {
    // 1000 Hz, 10 s, tip only: modes up to the band edge are in the model, the highest are not
    // excited by the moves
    let (json, _) = common::diagnose_generated_with(
        "none",
        81_003,
        &TruthOptions {
            duration_s: 10.0,
            rate_hz: 1000.0,
            base_pos: Some(false),
            force: Some(false),
            ..Default::default()
        },
    );
    // the nominal calibration and the one refitted with the named effects follow one rule
    // (the final one is judged on its own fit: session 38's README case reported ζ 6.8e123)
    for key in ["calibration", "final_calibration"] {
        let cal = json[key].as_object().expect("calibration object");
        let unidentified = cal
            .iter()
            .filter(|(name, e)| !reported_as_identified(key, name, e))
            .count();
        assert!(
            unidentified > 0,
            "every mode identified at 1000 Hz? {key} {cal:?}"
        );
    }
}

/// Whether calibration entry `e` of `key` is identified; panics unless it is either a finite
/// value with a positive 1 σ (a damping ratio inside the applied range, 2 σ from zero) or
/// `identified: false` with null values and a reason.
fn reported_as_identified(key: &str, name: &str, e: &serde_json::Value) -> bool {
    if e["identified"] == serde_json::Value::Bool(false) {
        assert!(
            e["value"].is_null() && e["std"].is_null(),
            "{key} {name}: {e}"
        );
        assert!(
            e["reason"].as_str().is_some_and(|r| !r.is_empty()),
            "{key} {e}"
        );
        return false;
    }
    let (Some(v), Some(s)) = (e["value"].as_f64(), e["std"].as_f64()) else {
        panic!("{key} {name}: a number without a finite value and 1 σ: {e}");
    };
    assert!(s > 0.0, "{key} {name}: {e}");
    if name.starts_with("zeta_mode") {
        assert!(
            (1e-5..=0.5).contains(&v) && 2.0 * s < v,
            "{key} {name}: {e}"
        );
    }
    true
}

/// The final calibration's carriage-mass correction of a diagnosed truth case (value, 1 σ) and
/// the truth's (kg), with every channel the case has recorded.
fn carriage_mass(effect: &str, seed: u64, rate_hz: f64) -> (f64, f64, f64, f64) {
    let opts = TruthOptions {
        duration_s: 30.0,
        rate_hz,
        base_pos: Some(true),
        force: Some(true),
        ..Default::default()
    };
    let (j, truth, rig) = common::diagnose_case(effect, seed, &opts);
    let m = &j["final_calibration"]["base_mass_delta_kg"];
    let truth = truth["true_carriage_mass_kg"].as_f64().unwrap() - rig.base.mass_kg;
    (
        m["value"].as_f64().unwrap(),
        m["std"].as_f64().unwrap(),
        truth,
        rig.base.mass_kg,
    )
}

#[test]
fn the_carriage_mass_two_sigma_covers_the_truth_at_50_and_100_hz() {
    // short moves put acceleration steps between samples, which the piecewise-linear drive
    // spreads over three samples; the mass fitted to the averaged force came out heavier than
    // the truth: 91023 (beam, 50 Hz) +0.474 ± 0.022 kg for +0.227 (z 11), 92012 (carriage
    // only, 100 Hz) +0.238 ± 0.010 for +0.176 (z 6). Its 1 σ now includes the cubic-spline
    // reading of the same samples (honesty::add_drive_interpolation_std).
    for (seed, rate) in [(91_023, 50.0), (92_012, 100.0)] {
        let (v, s, truth, rig_mass) = carriage_mass("none", seed, rate);
        assert!(
            (v - truth).abs() <= 2.0 * s,
            "seed {seed}: carriage mass correction {v:.4} ± {s:.4} kg, truth {truth:.4} kg"
        );
        // not by a σ so wide it says nothing: the correction stays resolved
        assert!(s < 0.1 * rig_mass, "seed {seed}: 1 σ {s:.4} kg");
    }
}

#[test]
fn a_null_whose_second_mode_lies_between_the_band_edge_and_nyquist_names_nothing() {
    // held-out 545001 (50 Hz, 30 s): f2 at 22.51 Hz, just above the 22.5 Hz band edge, was
    // left out of the nominal model; a hanging load, pulling f2 below the edge, gained the
    // mode and was named. Every mode below Nyquist is simulated, a count no parameter changes.
    let (json, _) = common::diagnose_generated_with(
        "none",
        545_001,
        &TruthOptions {
            duration_s: 30.0,
            rate_hz: 50.0,
            ..Default::default()
        },
    );
    let named = common::named_effects(&json);
    assert!(named.is_empty(), "named {named:?}");
}
