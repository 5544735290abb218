//! The length-series diagnosis on the real aluminium cantilever (40, 50, 60 cm free decays,
//! ADXL357 6 cm from the tip): the uniform beam calibrated on two lengths mispredicts the
//! third; the sensor's mass explains it and halves the held-out error.

use beamtools::cli::diagnose::length_modes;
use beamtools::diagnose::lengths::{diagnose_lengths, to_json, words, LengthEffect, LengthOptions};
use beamtools::model::Rig;
use std::path::Path;

const DIR: &str = "../../shared/data/real/aluminium-cantilever";

#[test]
fn real_aluminium_length_series_names_the_sensor_mass() {
    let files = [
        (0.40, "40cm_adxl_08-12_11-42-08_adxl6cmfromtip2cmID.npy"),
        (0.50, "50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy"),
        (0.60, "60cm_adxl_08-12_21-22-38_4cmID.npy"),
    ];
    if !Path::new(DIR).exists() {
        eprintln!("skipped: {DIR} not present");
        return;
    }
    let data: Vec<_> = files
        .iter()
        .map(|(l, f)| length_modes(*l, &Path::new(DIR).join(f), 0.06, 2).unwrap())
        .collect();
    let rig = Rig::from_toml_file("../rigs/aluminium-cantilever.toml").unwrap();
    let d = diagnose_lengths(&rig, &data, &LengthOptions::default()).unwrap();
    eprintln!("{}", words(&d));
    assert_eq!(d.selected, LengthEffect::TipMass);
    let j = to_json(&d);
    let (before, after) = (
        j["validation"]["nrmse_before"].as_f64().unwrap(),
        j["validation"]["nrmse_after"].as_f64().unwrap(),
    );
    assert!(after < 0.7 * before, "{before} → {after}");
    let ratio = d.fits[2]
        .parameters
        .iter()
        .find(|p| p.0 == "tip_mass_over_beam_mass")
        .unwrap()
        .1;
    assert!(
        (0.01..0.1).contains(&ratio),
        "sensor mass / beam mass {ratio}"
    );
    assert_eq!(j["effect"], "tip_mass");
    assert!(j["parameters"]["tip_mass_kg"].as_f64().unwrap() > 0.0);
}
