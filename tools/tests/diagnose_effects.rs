//! The catalogue additions of issue 10 end to end: a truth case with the effect hidden (the
//! truth plant's own physics, not the diagnosis model), then the diagnosis names it with its
//! parameter. The wider measurement is `diagnose-proof --only backlash,cubic_stiffness` in
//! docs/diagnose.md.

mod common;

/// Generates `effect` at `seed` (30 s recordings), diagnoses it and returns (named effects,
/// fitted value of `param`, true value).
fn round_trip(effect: &str, seed: u64, param: &str) -> (Vec<String>, f64, f64) {
    let (j, truth) = common::diagnose_generated(effect, seed);
    let named = common::named_effects(&j);
    let fitted = j["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|e| e["parameters"][param].as_f64())
        .unwrap_or(f64::NAN);
    (named, fitted, truth[param].as_f64().unwrap())
}

#[test]
fn backlash_is_named_with_its_play() {
    let (named, b, truth) = round_trip("backlash", 1000, "backlash_m");
    assert_eq!(named, ["backlash"], "{named:?}");
    assert!((b - truth).abs() < 0.3 * truth, "{b} vs {truth}");
}

#[test]
fn cubic_stiffness_is_named_with_its_cubic_compliance() {
    let (named, c3, truth) =
        round_trip("cubic_stiffness", 1100, "cubic_root_compliance_rad_per_nm3");
    assert_eq!(named, ["cubic_stiffness"], "{named:?}");
    assert!((c3 - truth).abs() < 0.3 * truth.abs(), "{c3} vs {truth}");
}

/// A mount at the top of the band the model's own modes cover (40.0 Hz on 100 Hz recordings:
/// the truth generator's ceiling, 0.4 × the rate; held-out seed 118700) is a mount, not "beyond
/// the observable band": the mount's search reaches the band edge of the calibration, 0.45 × the
/// rate ([`beamtools::diagnose::model::band_edge_hz`]). Before, the fit at 40.9 Hz was refused
/// and the diagnosis was `none`. The frequency compared is the resonance as the rig shows it
/// (the coupled mount + beam with the carriage held, [`beamtools::model::mount`]): 44.2 Hz in
/// the truth, 43.5 ± 1.2 Hz reported.
#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn a_mount_at_the_top_of_the_band_is_named() {
    let (named, f, truth) = round_trip("mount_resonance", 118700, "mount_frequency_hz");
    assert_eq!(named, ["mount_resonance"], "{named:?}");
    assert!((f - truth).abs() < 0.1 * truth, "{f} vs {truth}");
}

/// A mount that carries the beam, tuned next to one of the beam's modes (held-out seed 437700:
/// rigid-beam frequency 31.47 Hz beside the beam's 32.0 Hz third mode; the rig shows the mount
/// at 35.7 Hz, because the mount + beam split that mode) is a mount, not a calibration matter:
/// the rule compares the resonance the rig shows with the model's modes, not the rigid-beam
/// frequency the form is parametrised by. Before, the coupled form was refused as "coinciding
/// with the model's own mode at 32.01 Hz" and a PID loop named instead.
#[test]
#[cfg_attr(not(feature = "slow-tests"), ignore = "slow tier: ./test.sh --full")]
fn a_coupled_mount_beside_a_beam_mode_is_named() {
    let (named, f, truth) = round_trip("mount_resonance", 437700, "mount_frequency_hz");
    assert_eq!(named, ["mount_resonance"], "{named:?}");
    assert!((f - truth).abs() < 0.05 * truth, "{f} vs {truth}");
}
