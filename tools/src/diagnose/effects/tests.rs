//! Tests of the candidate catalogue and of how a candidate's values enter the model.

use super::*;

#[test]
fn a_root_spring_has_a_placement_along_the_beam_and_nothing_else_has() {
    let root = Candidate {
        id: Effect::RootCompliance,
        words: "",
        orientation: None,
        params: vec![def(
            "root_stiffness_nm_per_rad",
            Transform::Log,
            vec![10.0],
            1.0,
            false,
        )],
    };
    let along = along_beam_of(&root, 0.8).unwrap();
    assert_eq!(along.id, Effect::RootCompliance);
    let pos = along.params.last().unwrap();
    assert_eq!(pos.name, "spring_position_m");
    assert!(
        matches!(pos.transform, Transform::Bounded(lo, hi) if lo == 0.0 && (hi - 0.72).abs() < 1e-12)
    );
    let mut p = Params::default();
    apply_effect(&along, &[25.0, 0.3], &mut p);
    assert_eq!(
        (p.root_stiffness_nm_per_rad, p.spring_position_m),
        (Some(25.0), 0.3)
    );
    apply_effect(&root, &[25.0], &mut p);
    assert_eq!(p.spring_position_m, 0.0);
    assert!(along_beam_of(
        &Candidate {
            id: Effect::TipMass,
            ..root.clone()
        },
        0.8
    )
    .is_none());
    assert!(along_beam_of(&root, 0.0).is_none());
}

/// A rig file may list a damping ratio per mode (the way a modal test reports them): the
/// model's Rayleigh pair takes modes 1 and 2, and the diagnosis starts each in-band mode's
/// ratio from its own entry, the last repeated beyond the list.
#[test]
fn a_damping_ratio_listed_per_mode_starts_that_modes_calibration() {
    let text = "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\n\
        stations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 },\n\
                     { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]\n\
        [base]\nmass_kg = 2.5\n[damping]\nratios = [0.007, 0.005, 0.012, 0.02]\n";
    let rig = Rig::from_toml_str(text).expect("four ratios are a valid rig");
    assert_eq!(rig.damping_ratios(), (0.007, 0.005));
    let ch = Channels {
        tip: true,
        ..Default::default()
    };
    let calib = calibration_defs(&rig, &ch, 6, 12);
    let starts: Vec<(&str, f64)> = calib
        .defs
        .iter()
        .filter(|d| d.name.starts_with("zeta"))
        .map(|d| (d.name, d.starts[0]))
        .collect();
    let expected = [0.007, 0.005, 0.012, 0.02, 0.02, 0.02];
    assert_eq!(starts.len(), expected.len(), "{starts:?}");
    for ((name, z), want) in starts.iter().zip(expected) {
        assert_eq!(*z, want, "{name}");
    }
    let empty = text.replace("[0.007, 0.005, 0.012, 0.02]", "[]");
    let err = Rig::from_toml_str(&empty).unwrap_err().to_string();
    assert!(err.contains("damping.ratios"), "{err}");
}

/// The friction law's model-form alternative (`honesty::add_friction_law_std`) appends a
/// `base_friction` candidate with the law's width alone: applied after the named friction, it
/// sets the width and leaves the Coulomb force and the viscous term the fit reads.
#[test]
fn the_friction_laws_width_alone_leaves_the_friction_it_smooths() {
    let friction = Candidate {
        id: Effect::BaseFriction,
        words: "",
        orientation: None,
        params: vec![
            def("friction_n", Transform::Linear, vec![0.0], 0.1, true),
            def("viscous_n_s_per_m", Transform::Linear, vec![0.0], 1.0, true),
        ],
    };
    let law = Candidate {
        params: vec![def(
            super::super::honesty::FRICTION_WIDTH,
            Transform::Log,
            vec![1e-3],
            1.0,
            false,
        )],
        ..friction.clone()
    };
    let mut p = Params::default();
    assert_eq!(
        p.friction_smoothing_m_s,
        super::super::model::FRICTION_SMOOTHING_M_S
    );
    apply_effect(&friction, &[0.5, 2.0], &mut p);
    apply_effect(&law, &[4e-3], &mut p);
    assert_eq!(
        (p.friction_n, p.viscous_n_s_per_m, p.friction_smoothing_m_s),
        (0.5, 2.0, 4e-3)
    );
    let load = super::super::model::CarriageLoad::of(&p).expect("friction is a load");
    let v = 2e-3;
    assert!((load.force_n(0.0, v) - (0.5 * (v / 4e-3f64).tanh() + 2.0 * v)).abs() < 1e-15);
}
