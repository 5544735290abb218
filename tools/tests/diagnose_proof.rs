//! Diagnosis on concealed effects from the truth generator: a reduced proof (the full one is
//! `beamtool diagnose-proof`, recorded in docs/diagnose.md).

use beamtools::diagnose::diagnose;
use beamtools::diagnose::model::Prepared;
use beamtools::diagnose::proof::{proof_table, run_proof, ProofRow};
use beamtools::model::Rig;

mod common;

/// The reduced proof's cases (seed 1000, 30 s recordings): `effects` one case each, `nulls`
/// null cases. The seeds follow the plan's order ([`beamtools::diagnose::proof::plan`]), so the
/// two tests below share one plan's cases and run side by side.
fn reduced_proof(effects: &[&str], nulls: usize) -> (Vec<ProofRow>, String) {
    let rows = run_proof(
        effects,
        1,
        nulls,
        1000,
        30.0,
        &mut beamtools::progress::Silent,
    )
    .unwrap();
    let table = proof_table(&rows);
    println!("{table}");
    (rows, table)
}

#[test]
fn nulls_give_none() {
    let (rows, table) = reduced_proof(&[], 2);
    assert_eq!(rows.len(), 2, "{table}");
    for r in &rows {
        assert_eq!(r.named, "none", "false discovery on a null case:\n{table}");
    }
}

#[test]
fn clear_effects_are_named() {
    // one case each of effects with a strong signature
    let (rows, table) = reduced_proof(&["sensor_delay", "quadratic_damping", "cogging_ripple"], 0);
    assert_eq!(rows.len(), 3, "{table}");
    // recall: the hidden effect is among those named in at least 2 of the 3 cases (an exact
    // set is not required here: the data-derived guard can add a weak second effect, which the
    // widened proof in docs/diagnose.md counts against precision; a weak cogging ripple at the
    // detection limit may stay unnamed)
    let recalled = rows
        .iter()
        .filter(|r| r.named_raw.iter().any(|n| *n == r.truth))
        .count();
    assert!(recalled >= 2, "{table}");
    // the issue's target: median validation NRMSE reduction >= 30 % where an effect exists
    let mut red: Vec<f64> = rows.iter().map(|r| 1.0 - r.nrmse.1 / r.nrmse.0).collect();
    red.sort_by(|a, b| a.total_cmp(b));
    assert!(red[red.len() / 2] >= 0.3, "{table}");
}

#[test]
fn json_has_the_fields_of_the_issue() {
    let (j, truth) = common::diagnose_generated("sensor_delay", 1500);
    assert!(j["effect"].is_string());
    assert!(j["parameters"].is_object());
    assert!(
        j["validation"]["nrmse_before"].is_number() && j["validation"]["nrmse_after"].is_number()
    );
    assert!(j["effects"].is_array());
    assert!(j["unexplained"].is_null() || j["unexplained"]["channel"].is_string());
    assert!(j["model"]["in_band_modes_hz"].is_array());
    for e in j["effects"].as_array().unwrap() {
        assert!(e["effect"].is_string() && e["parameters"].is_object());
        assert!(e["uncertainty"].is_object() && e["validation"]["nrmse_after"].is_number());
    }
    assert!(j["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .all(|c| c["effect"].is_string() && c["score"].is_number()));
    if j["effect"] == "sensor_delay" {
        let tau = j["parameters"]["sensor_delay_s"].as_f64().unwrap();
        let truth = truth["sensor_delay_s"].as_f64().unwrap();
        assert!((tau - truth).abs() < 0.3 * truth, "{tau} vs {truth}");
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    let rig = Rig::from_toml_str("[base]\nmass_kg = 2.0\n").unwrap();
    let n = 1000;
    let mut rec = beamtools::recording::Recording::with_uniform_time(n, 100.0);
    let ramp: Vec<f64> = (0..n).map(|k| 1e-4 * k as f64).collect();
    rec.tip_pos_m = Some(ramp.clone());
    let e = Prepared::new("x.csv", &rec).unwrap_err().to_string();
    assert!(e.contains("base_cmd_m"), "{e}");
    rec.base_cmd_m = Some(ramp.clone());
    let d = Prepared::new("x.csv", &rec).unwrap();
    let e = diagnose(
        &rig,
        std::slice::from_ref(&d),
        &d,
        &mut beamtools::progress::Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no [beam]") || e.contains("tip"), "{e}");
    // too short: 2 samples
    let mut short = beamtools::recording::Recording::with_uniform_time(2, 100.0);
    short.base_cmd_m = Some(vec![0.0, 1e-3]);
    short.tip_pos_m = Some(vec![0.0, 1e-3]);
    let s = Prepared::new("short.csv", &short).unwrap();
    let e = diagnose(
        &rig,
        std::slice::from_ref(&d),
        &s,
        &mut beamtools::progress::Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("short.csv") && e.contains("too short"), "{e}");
    // a base that never moves carries no information
    let mut still = rec.clone();
    still.base_cmd_m = Some(vec![0.0; n]);
    let s = Prepared::new("still.csv", &still).unwrap();
    let e = diagnose(
        &rig,
        std::slice::from_ref(&s),
        &d,
        &mut beamtools::progress::Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no information"), "{e}");
    let beam_rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    // a tip sensor that records noise only: the model explains nothing of it, with or without
    // the catalogue's effects
    let mut noise = rec.clone();
    let mut state = 12345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let steps: Vec<f64> = (0..n).map(|k| 0.05 * ((k / 250) % 2) as f64).collect();
    noise.base_cmd_m = Some(steps.clone());
    noise.tip_pos_m = Some(steps.iter().map(|x| x + 1e-3 * uniform()).collect());
    let s = Prepared::new("noise.csv", &noise).unwrap();
    let e = diagnose(
        &beam_rig,
        std::slice::from_ref(&s),
        &s,
        &mut beamtools::progress::Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no information"), "{e}");
    // positions in millimetres: a 100 mm move written as 100 "m", and a tip 3 "m" off the base
    // of a 0.5 m beam
    let mut mm = rec.clone();
    mm.base_cmd_m = Some(ramp.iter().map(|x| x * 1e3).collect());
    mm.tip_pos_m = mm.base_cmd_m.clone();
    let s = Prepared::new("mm.csv", &mm).unwrap();
    let run = |s: &Prepared| {
        diagnose(
            &beam_rig,
            std::slice::from_ref(s),
            s,
            &mut beamtools::progress::Silent,
        )
        .unwrap_err()
        .to_string()
    };
    let e = run(&s);
    assert!(e.contains("mm.csv: `base_cmd_m` spans 99.9"), "{e}");
    mm.base_cmd_m = Some(ramp.clone());
    mm.tip_pos_m = Some(ramp.iter().map(|x| x + 3.0).collect());
    let e = run(&Prepared::new("mm.csv", &mm).unwrap());
    assert!(
        e.contains("`tip_pos_m` is up to 3.0000 m from the base"),
        "{e}"
    );
}
