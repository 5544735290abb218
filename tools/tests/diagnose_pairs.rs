//! Friction beside another effect (issue 10, "several effects at once"). The force channel's
//! model-form allowance once held the carriage velocity, i.e. viscous friction itself, so
//! friction never beat it and went unnamed beside a tip mass; and with the budget mostly spent
//! after the first effect, the second round was skipped. Measured more widely in
//! docs/diagnose.md ("Friction credit and look-alikes").

mod common;

use beamtools::truth::TruthOptions;

/// 150 Hz (a rate the proof does not use), seed outside the tuning sets: both effects named,
/// each with its parameter of the right size.
#[test]
fn friction_beside_a_tip_mass_is_named_too() {
    let opts = TruthOptions {
        duration_s: 30.0,
        rate_hz: 150.0,
        ..Default::default()
    };
    let (j, truth) = common::diagnose_generated_with("base_friction+tip_mass", 81001, &opts);
    let channels = truth["channels"].to_string();
    assert!(channels.contains("force_n"), "{channels}");
    assert_eq!(
        common::named_effects(&j),
        ["base_friction", "tip_mass"],
        "{}",
        j["effects"]
    );
    let param = |name: &str| {
        j["effects"]
            .as_array()
            .unwrap()
            .iter()
            .find_map(|e| e["parameters"][name].as_f64())
            .unwrap()
    };
    let (fc, m) = (param("friction_n"), param("tip_mass_kg"));
    let (fc_true, m_true) = (
        truth["friction_n"].as_f64().unwrap(),
        truth["tip_mass_kg"].as_f64().unwrap(),
    );
    assert!(
        fc > 0.5 * fc_true && fc < 2.0 * fc_true,
        "{fc} vs {fc_true}"
    );
    assert!((m - m_true).abs() < 0.1 * m_true, "{m} vs {m_true}");
}

/// A cogging ripple beside distributed drag (500 Hz, noise ×0.5; a seed no tuning looked at).
/// The force residual the ripple leaves is dominated by a slow (0.02–0.08 Hz) component it does
/// not touch; counting the guard's effective samples with the autocorrelation time of the
/// model *without* the ripple gave its 40 % force gain ΔBIC −1.1, and only the drag was named
/// (`select` module docs, 1). Both are named, the ripple with its pitch.
#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn a_cogging_ripple_beside_drag_is_named_too() {
    let opts = TruthOptions {
        duration_s: 20.0,
        rate_hz: 500.0,
        noise_scale: 0.5,
        ..Default::default()
    };
    let (j, truth) =
        common::diagnose_generated_with("cogging_ripple+quadratic_damping", 108040, &opts);
    assert_eq!(
        common::named_effects(&j),
        ["cogging_ripple", "quadratic_damping"],
        "{}",
        j["effects"]
    );
    let pitch = j["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|e| e["parameters"]["cogging_pitch_m"].as_f64())
        .unwrap();
    let pitch_true = truth["cogging_pitch_m"].as_f64().unwrap();
    assert!(
        (pitch - pitch_true).abs() < 0.05 * pitch_true,
        "{pitch} vs {pitch_true}"
    );
}

/// A play of millimetres beside a tip mass at noise ×2 (held-out case 274060 of session 18, the
/// only draw of ~60 tried where it happens): the beam rattles in a 5.1 mm play, and the
/// calibrated nominal model explains almost nothing of the tip (NRMSE 0.99). That once refused
/// the recordings as another rig's before any effect was tried; the refusal now follows the
/// selection, which finds the play (and says the nominal model alone explained nothing).
#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn a_play_the_nominal_model_explains_nothing_of_is_still_found() {
    let opts = TruthOptions {
        duration_s: 30.0,
        noise_scale: 2.0,
        ..Default::default()
    };
    let (j, truth) = common::diagnose_generated_with("backlash+tip_mass", 274060, &opts);
    let named = common::named_effects(&j);
    assert!(named.iter().any(|e| e == "backlash"), "{named:?}");
    let play = j["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|e| e["parameters"]["backlash_m"].as_f64())
        .unwrap();
    let play_true = truth["backlash_m"].as_f64().unwrap();
    assert!(
        (play - play_true).abs() < 0.1 * play_true,
        "{play} vs {play_true}"
    );
    let assumptions = j["assumptions"].to_string();
    assert!(
        assumptions.contains("nominal model alone explains almost nothing"),
        "{assumptions}"
    );
}

/// A small play beside a small tip mass, tip only, noise ×2 (held-out case 285060 of session
/// 19): the play alone removes 42 % of the structured tip residual and the tip mass the rest,
/// so the play failed condition 6 ("it does not account for it") and nothing was named. Read
/// for a pair, the play goes in on trial, the tip mass then passes every guard, and together
/// they remove all of the structure: both are named.
#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn the_first_of_a_pair_that_leaves_the_seconds_share_is_named_with_it() {
    let opts = TruthOptions {
        duration_s: 30.0,
        noise_scale: 2.0,
        ..Default::default()
    };
    let (j, truth) = common::diagnose_generated_with("backlash+tip_mass", 285060, &opts);
    assert_eq!(
        common::named_effects(&j),
        ["backlash", "tip_mass"],
        "{}",
        j["effects"]
    );
    let play = j["effects"][0]["parameters"]["backlash_m"]
        .as_f64()
        .unwrap();
    let play_true = truth["backlash_m"].as_f64().unwrap();
    assert!(
        (play - play_true).abs() < 0.2 * play_true,
        "{play} vs {play_true}"
    );
    let words = j["effects"][0]["words"].to_string() + &j["candidates"].to_string();
    assert!(words.contains("together they remove"), "{words}");
}
