//! Physics outside the catalogue is answered `unexplained` (located), not with a catalogue
//! name: a mid-span crack moves the beam's second mode off the frequency ratio of the model;
//! a heavily damped "mount resonance" whose half-power band holds that model mode is the mode
//! moved (a calibration matter), not a new resonance.

mod common;

use beamtools::truth::unmodelled::Unmodelled;
use beamtools::truth::TruthOptions;

#[test]
fn a_crack_is_not_a_heavily_damped_mount_at_a_model_mode() {
    // 50 Hz, tip + force (the conditions of `diagnose-proof`'s out-of-catalogue cases): before,
    // a coupled mount at 18.1 Hz with ζ 0.20 next to the 20.3 Hz model mode was named
    let (json, _) = common::diagnose_generated_with(
        "none",
        66_001,
        &TruthOptions {
            duration_s: 30.0,
            rate_hz: 50.0,
            unmodelled: Some(Unmodelled::Crack),
            ..Default::default()
        },
    );
    let named = common::named_effects(&json);
    assert!(named.is_empty(), "named {named:?}");
    // At 50 Hz this crack leaves the tip below its noise (structured rms 0.76 × the noise
    // rms); what stood out before was the force at 23.9 Hz, beyond the working band's pass
    // edge (22.5 Hz), where the nulls of the same rate show it too (own generator, null seed
    // 996001: 24.1 Hz). An `unexplained` report, if any, lies inside the working band, where the
    // beam is recorded: tip_pos_m near f1's compromise or force_n at the displaced f2 (the crack
    // lowers f1 by 13 %, f2 less).
    let u = &json["unexplained"];
    if u.is_object() {
        let ch = u["channel"].as_str().unwrap();
        assert!(ch == "tip_pos_m" || ch == "force_n", "{u}");
        let band = u["band_hz"].as_array().unwrap();
        let (lo, hi) = (band[0].as_f64().unwrap(), band[1].as_f64().unwrap());
        assert!(lo < 22.5 && hi > 2.0, "band {band:?}");
    }
}

#[test]
fn a_crack_left_with_a_loop_that_rings_alone_names_nothing() {
    // held-out 543001 (50 Hz, 30 s, tip only): an axial load on trial, then a position loop
    // beside it; the backward elimination dropped the load and left the loop named, though
    // alone it rang 17 dB (no drive is tuned so): an effect left alone by a drop must pass
    // alone
    let (json, _) = common::diagnose_generated_with(
        "none",
        543_001,
        &TruthOptions {
            duration_s: 30.0,
            rate_hz: 50.0,
            unmodelled: Some(Unmodelled::Crack),
            ..Default::default()
        },
    );
    let effects = json["effects"].as_array().unwrap();
    assert!(effects.is_empty(), "named {effects:?}");
    assert!(json["unexplained"].is_object(), "no unexplained report");
}

#[test]
fn a_crack_is_not_a_mount_with_a_compliant_clamp() {
    // held-out 553001 (50 Hz, 30 s, tip and force): a crack at 0.41 of the length had been
    // named a massless mount and a compliant clamp in two ordinary rounds; a rotational spring
    // along the beam, its ladder anchored inside the root spring's scan, explains the
    // recordings better than the pair (forward::structural_pair_as_crack)
    let (json, truth) = common::diagnose_generated_with(
        "none",
        553_001,
        &TruthOptions {
            duration_s: 30.0,
            rate_hz: 50.0,
            unmodelled: Some(Unmodelled::Crack),
            ..Default::default()
        },
    );
    assert!(truth["crack_position_m"].is_number(), "{truth}");
    let effects = json["effects"].as_array().unwrap();
    assert!(effects.is_empty(), "named {effects:?}");
    assert_eq!(
        json["unexplained"]["channel"], "tip_pos_m",
        "{}",
        json["unexplained"]
    );
}

#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn a_crack_is_not_an_axial_load_with_a_compliant_clamp() {
    // held-out 462000 (100 Hz, 30 s): a crack had been named a hanging beam with a compliant
    // clamp, a pair that reshapes the frequency pattern as the crack does; a rotational spring
    // along the beam explains the recordings better than the pair (forward::crack_in_disguise)
    let (json, _) = common::diagnose_generated_with(
        "none",
        462_000,
        &TruthOptions {
            duration_s: 30.0,
            rate_hz: 100.0,
            unmodelled: Some(Unmodelled::Crack),
            ..Default::default()
        },
    );
    let named = common::named_effects(&json);
    assert!(named.is_empty(), "named {named:?}");
    assert!(json["unexplained"].is_object(), "no unexplained report");
}
