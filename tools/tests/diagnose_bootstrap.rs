//! The parametric bootstrap of the no-effect model (`beamtool diagnose-bootstrap`): a replicate
//! of a recording with a tip mass holds no tip mass, and the diagnosis of it names nothing.

mod common;

use beamtools::diagnose::bootstrap::{null_model, NoiseFrom};
use beamtools::diagnose::diagnose;
use rand::SeedableRng;

#[test]
fn a_replicate_leaves_out_what_the_recordings_named_and_names_nothing() {
    let (rig, fit, val, _) = common::short_tip_mass_case();
    let null = null_model(&rig, &fit, &val, NoiseFrom::Final).unwrap();
    assert_eq!(null.named.as_deref(), Some(&["tip_mass".to_string()][..]));
    // every recorded channel has a noise model, at most the order cap
    assert_eq!(null.noise.len(), 3);
    for m in null.noise.iter().flatten().flatten() {
        assert!(m.coefficients.len() <= beamtools::diagnose::bootstrap::MAX_NOISE_ORDER);
        assert!(m.innovation_variance > 0.0);
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let (rf, rv) = null.replicate(&mut rng);
    let d = diagnose(&rig, &rf, &rv, &mut beamtools::progress::Silent).unwrap();
    let named: Vec<String> = d.effects.iter().map(|e| e.id.to_string()).collect();
    assert!(named.is_empty(), "{named:?}");
    assert!(d.unexplained.is_none());
}
