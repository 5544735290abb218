//! Tests of the honesty measures: long-run σ, the model-accuracy terms, stability.

use super::*;

#[test]
fn the_base_assumption_leaves_a_latency_its_look_alike_to_the_lookalike_check() {
    // calibration of 2 parameters, then a tip mass (1) and a tip latency (1): only the
    // latency's parameter is the loop's alternative explanation
    let param = |id, name| {
        let mut c = crate::diagnose::effects::servo_candidate(1, 100.0);
        c.id = id;
        c.params.truncate(1);
        c.params[0].name = name;
        c
    };
    let calib = Calib {
        defs: crate::diagnose::effects::servo_candidate(1, 100.0).params,
        n_basis: 4,
        simulated_modes: None,
        smooth_drive: false,
        drive_reading: crate::diagnose::model::DriveReading::PiecewiseLinear,
    };
    let tip = param(crate::effect::Effect::TipMass, "tip_mass_kg");
    let delay = param(crate::effect::Effect::SensorDelay, "sensor_delay_s");
    assert_eq!(look_alike_params(&calib, &[&tip, &delay]), vec![3]);
    assert!(look_alike_params(&calib, &[&tip]).is_empty());
}

/// A loop fitted beyond 0.45 × the rate is a lower bound (σ NaN); one inside keeps its σ;
/// a tip mass is never band-limited.
#[test]
fn a_loop_beyond_the_recordings_band_is_a_lower_bound() {
    let servo = crate::diagnose::effects::servo_candidate(2, 100.0);
    let mut tip = crate::diagnose::effects::servo_candidate(1, 100.0);
    tip.id = crate::effect::Effect::TipMass;
    tip.params.truncate(1);
    tip.params[0].name = "tip_mass_kg";
    let fit = |fb: f64| FitResult {
        x: DVector::zeros(6),
        values: vec![1.0, fb, 0.7, 0.0, 0.0, 50.0],
        std: vec![0.1; 6],
        names: vec![],
        cost: 0.0,
        evaluations: 0,
        trace: vec![],
    };
    assert_eq!(servo.params[0].name, "servo_bandwidth_hz");
    assert_eq!(servo.params.len(), 4);
    let (mut beyond, mut inside) = (fit(47.3), fit(40.1));
    let marked = beyond_band(&[&servo, &tip], &mut beyond, 1, 100.0);
    assert_eq!(
        marked,
        vec![(
            "servo_lag".to_string(),
            "servo_bandwidth_hz".to_string(),
            45.0
        )]
    );
    assert!(beyond.std[1].is_nan());
    assert!(beyond
        .std
        .iter()
        .enumerate()
        .all(|(i, s)| i == 1 || *s == 0.1));
    assert!(beyond_band(&[&servo, &tip], &mut inside, 1, 100.0).is_empty());
    assert!(inside.std.iter().all(|s| *s == 0.1));
}

/// A uniform steel beam of 0.9 m × 30 mm × 1.5 mm (318 g, EI/L = 20.5 N·m/rad).
fn uniform_steel_beam() -> Rig {
    Rig::from_toml_str(
        "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 7850.0\nyoungs_modulus_pa = 2.0e11\nstations = [ { x_m = 0.0, width_m = 0.03, thickness_m = 0.0015 }, { x_m = 0.9, width_m = 0.03, thickness_m = 0.0015 } ]\n[base]\nmass_kg = 2.0\n",
    )
    .unwrap()
}

#[test]
fn a_root_spring_much_stiffer_than_the_beam_rests_on_a_sliver_of_the_frequency_pattern() {
    // uniform steel beam, EI/L = 20.5 N·m/rad; 1 kHz samples (several modes in band)
    let rig = uniform_steel_beam();
    let rel = |k: f64| {
        let p = crate::diagnose::model::Params {
            root_stiffness_nm_per_rad: Some(k),
            ..Default::default()
        };
        root_spring_accuracy_rel(&rig, &p, 1e-3).unwrap()
    };
    let (soft, matched, stiff) = (rel(0.2), rel(20.0), rel(2e3));
    // k L/EI = 0.01 and 1: the pattern moves by per cents per unit ln k, σ under 1 %
    assert!(soft < 0.01 && matched < 0.01, "{soft} {matched}");
    // k L/EI = 100: nearly clamped, the pattern barely moves, the σ is many times larger
    assert!(stiff > 10.0 * matched, "{stiff} vs {matched}");
    let none = crate::diagnose::model::Params::default();
    assert!(root_spring_accuracy_rel(&rig, &none, 1e-3).is_none());
}

#[test]
fn a_small_tip_mass_has_an_absolute_floor_from_the_frequency_pattern() {
    // uniform steel beam of 318 g; 1 kHz samples (several modes in band)
    let rig = uniform_steel_beam();
    let sigma_kg = |m: f64| {
        let p = crate::diagnose::model::Params {
            tip_mass_kg: m,
            ..Default::default()
        };
        m * tip_mass_accuracy_rel(&rig, &p, 1e-3).unwrap()
    };
    // 1 g and 2 g (0.3 % and 0.6 % of the beam): the pattern moves in proportion to the
    // mass, so the 1 σ in kilograms is about the same, a fraction of a gram
    let (one, two) = (sigma_kg(1e-3), sigma_kg(2e-3));
    assert!(one > 0.0 && one < 1e-3, "{one}");
    assert!((two / one - 1.0).abs() < 0.3, "{one} {two}");
    // a heavy one (a third of the beam) is read to a few per cent of itself
    let heavy = sigma_kg(0.1) / 0.1;
    assert!(heavy < 0.05, "{heavy}");
    let none = crate::diagnose::model::Params::default();
    assert!(tip_mass_accuracy_rel(&rig, &none, 1e-3).is_none());
}

#[test]
fn a_parameter_read_from_the_response_size_is_known_to_the_models_accuracy() {
    // a deflection of 1 mm rms; a 5 % step of the parameter changes it by 1 % of itself
    // (s = 0.01/ln 1.05 = 0.205: a drag read from the envelope) or by 50 % (a latency)
    let deflection: Vec<f64> = (0..1000).map(|k| 1e-3 * (0.05 * k as f64).sin()).collect();
    let signal = vec![[None, Some(deflection.clone()), None]];
    let scaled = |g: f64| vec![[None, Some(deflection.iter().map(|v| g * v).collect()), None]];
    let slight = response_sensitivity(&scaled(1.01), &signal, 1.05);
    let strong = response_sensitivity(&scaled(1.5), &signal, 1.05);
    assert!((slight - 0.01 / 1.05f64.ln()).abs() < 1e-9, "{slight}");
    // σ(ln θ) = a/(√3 s): 0.28 % for the slight one, 50 × less for the strong one
    let rel = |s: f64| stated_accuracy_rel(s).unwrap();
    assert!((rel(slight) - 2.82e-3).abs() < 1e-5, "{}", rel(slight));
    assert!((rel(slight) / rel(strong) - 50.0).abs() < 1e-6);
    // the most sensitive channel sets it; a channel without signal says nothing
    let both = vec![[None, Some(deflection.clone()), Some(vec![0.0; 1000])]];
    let moved = vec![[
        None,
        Some(scaled(1.01)[0][1].clone().unwrap()),
        Some(vec![1.0; 1000]),
    ]];
    assert_eq!(response_sensitivity(&moved, &both, 1.05), slight);
    assert_eq!(response_sensitivity(&signal, &signal, 0.95), 0.0);
    assert!(stated_accuracy_rel(0.0).is_none());
}

#[test]
fn a_sigma_resting_on_two_recordings_disagreement_has_one_degree_of_freedom() {
    // σ_lr 1, spread 10 (the σ is the spread): ν ≈ 1, k = t₀.₉₇₅(1) = 12.71; spread within
    // the noise: ν infinite, k = 1.96; spread 2 × σ_lr: ν = 16/9 · … > 1
    let nu = effective_dof(&[1.0, 1.0, 1.0], &[10.0, 0.5, 2.0], 2, &[10.0, 1.0, 2.0]);
    assert!((nu[0] - 10f64.powi(4) / 99f64.powi(2)).abs() < 1e-12);
    assert!(nu[1].is_infinite());
    assert!((nu[2] - 16.0 / 9.0).abs() < 1e-12);
    assert!((coverage_factor_95(1.0) - 12.706).abs() < 1e-3);
    assert!((coverage_factor_95(2.0) - 4.303).abs() < 1e-3);
    assert!((coverage_factor_95(f64::INFINITY) - 1.960).abs() < 1e-3);
    // a disagreement barely beyond the noise (seed 8 case13: ν 1.6·10⁹) is no finite ν
    assert!(!dof_is_finite(1.6e9) && !dof_is_finite(f64::INFINITY) && dof_is_finite(3.0));
    assert_eq!(coverage_factor_95(1.6e9), coverage_factor_95(f64::INFINITY));
    // one recording: no disagreement measured
    assert!(effective_dof(&[1.0], &[], 1, &[1.0])[0].is_infinite());
}

#[test]
fn spread_is_the_standard_error_of_the_per_recording_mean() {
    // two recordings: |θ₁ − θ₂|/2; three: s/√3; a parameter they agree on: 0
    let two = spread_std(&[vec![1.0, 5.0], vec![3.0, 5.0]]);
    assert_eq!(two, vec![1.0, 0.0]);
    let three = spread_std(&[vec![1.0], vec![2.0], vec![3.0]]);
    assert!((three[0] - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    assert!(spread_std(&[vec![1.0]]).is_empty());
}

#[test]
fn the_recordings_disagreement_raises_a_smaller_sigma_only() {
    let mut f = FitResult {
        x: DVector::zeros(2),
        values: vec![0.3, 1.0],
        std: vec![0.005, 0.5],
        names: vec!["friction_n", "viscous_n_s_per_m"],
        cost: 1.0,
        evaluations: 0,
        trace: vec![],
    };
    // friction 0.320 and 0.285 from the two recordings (seed 74000): σ 0.005 → 0.0175
    let spread = spread_std(&[vec![0.320, 1.1], vec![0.285, 1.2]]);
    add_spread_std(&mut f, &spread);
    assert!((f.std[0] - 0.0175).abs() < 1e-12);
    assert_eq!(f.std[1], 0.5);
}
