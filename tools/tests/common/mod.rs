//! Shared by the diagnosis integration tests: one generated case, diagnosed.

use beamtools::diagnose::diagnose;
use beamtools::diagnose::model::Prepared;
use beamtools::diagnose::report::to_json;
use beamtools::model::Rig;
use beamtools::truth::{generate, TruthOptions};

/// Generates `effect` at `seed` with 30 s recordings and diagnoses it (two fit recordings, one
/// validation); returns the diagnosis JSON and the generator's truth (`truth.json`'s `truth`).
#[allow(dead_code)] // each test binary uses one of the two entries
pub fn diagnose_generated(effect: &str, seed: u64) -> (serde_json::Value, serde_json::Value) {
    diagnose_generated_with(
        effect,
        seed,
        &TruthOptions {
            duration_s: 30.0,
            ..Default::default()
        },
    )
}

/// As [`diagnose_generated`], with the generator's options given.
#[allow(dead_code)]
pub fn diagnose_generated_with(
    effect: &str,
    seed: u64,
    opts: &TruthOptions,
) -> (serde_json::Value, serde_json::Value) {
    let (j, truth, _) = diagnose_case(effect, seed, opts);
    (j, truth)
}

/// As [`diagnose_generated_with`], also returning the rig file handed to the diagnosis (what
/// the user believes, e.g. its carriage mass).
#[allow(dead_code)]
pub fn diagnose_case(
    effect: &str,
    seed: u64,
    opts: &TruthOptions,
) -> (serde_json::Value, serde_json::Value, Rig) {
    let (rig, fit, val, truth) = prepared_case(effect, seed, opts);
    let d = diagnose(&rig, &fit, &val, &mut beamtools::progress::Silent).unwrap();
    (to_json(&d), truth, rig)
}

/// The generator's case `effect` at `seed` as the diagnosis reads it: the rig handed over, the
/// two fit recordings and the validation recording prepared, and the truth.
#[allow(dead_code)]
pub fn prepared_case(
    effect: &str,
    seed: u64,
    opts: &TruthOptions,
) -> (Rig, Vec<Prepared>, Prepared, serde_json::Value) {
    let case = generate(effect, seed, opts).unwrap();
    let rig = Rig::from_toml_str(&case.rig_toml).unwrap();
    let fit: Vec<Prepared> = case
        .fit
        .iter()
        .map(|r| Prepared::new("fit", r).unwrap())
        .collect();
    let val = Prepared::new("validate", &case.validate).unwrap();
    let truth = serde_json::to_value(&case.truth).unwrap();
    (rig, fit, val, truth)
}

/// A short generated tip-mass case (seed 7, 20 s recordings): [`prepared_case`] for tests that
/// need any diagnosis that names something, quickly.
#[allow(dead_code)]
pub fn short_tip_mass_case() -> (Rig, Vec<Prepared>, Prepared, serde_json::Value) {
    let opts = TruthOptions {
        duration_s: 20.0,
        ..Default::default()
    };
    prepared_case("tip_mass", 7, &opts)
}

/// Catalogue effects named in a diagnosis JSON, sorted; `servo_lag` left out (every generated
/// rig has a finite position loop, the proof's convention).
#[allow(dead_code)]
pub fn named_effects(j: &serde_json::Value) -> Vec<String> {
    let mut v: Vec<String> = j["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["effect"].as_str().unwrap().to_string())
        .filter(|e| e != "servo_lag")
        .collect();
    v.sort();
    v
}
