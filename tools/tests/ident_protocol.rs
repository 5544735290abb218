//! The paper's protocol on the simulated reference rig: accuracy on a 100 Hz exponential
//! sweep of 120 s (0.1–8 Hz, β = 3.16 octaves/min, eq. 34) followed by 20 s of ring-down, with
//! 5 % noise on every measured channel (base position, tip position, force).

use beamtools::ident::frf::InputChannel;
use beamtools::ident::protocol::{simulate_sweep, truth};
use beamtools::ident::sweep::{SweepKind, SweepSpec};
use beamtools::ident::{identify_recording, IdentOptions, Method};
use beamtools::model::{BeamModel, ModelOptions, Rig};

fn model() -> BeamModel {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    BeamModel::new(&rig, &ModelOptions::default()).unwrap()
}

/// β such that 0.1–8 Hz takes 120 s (eq. 34).
pub fn beta_120s() -> f64 {
    60.0 * (8.0f64 / 0.1).log2() / 120.0
}

#[test]
fn exponential_sweep_120s_5pct_noise_meets_the_accuracy_target() {
    let m = model();
    let tr = truth(&m).unwrap();
    let spec = SweepSpec {
        tail_s: 20.0,
        ..SweepSpec::paper(SweepKind::Exponential, beta_120s())
    };
    for seed in [7, 8] {
        let rec = simulate_sweep(&m, &spec, 100.0, 0.05, seed).unwrap();
        let opts = IdentOptions {
            methods: vec![Method::Lscf],
            input: InputChannel::BaseAccel,
            band_hz: Some((0.3, 8.0)),
            n_modes: Some(2),
            ..Default::default()
        };
        let (r, _) = identify_recording(&rec, &opts).unwrap();
        assert_eq!(r.modes.len(), 2, "{:?}", r.modes);
        for (m, t) in r.modes.iter().zip(tr.for_input(InputChannel::BaseAccel)) {
            let (ef, ez) = (m.freq_hz / t.0 - 1.0, m.zeta / t.1 - 1.0);
            eprintln!(
                "seed {seed}: f {:.4} (truth {:.4}, {:+.3} %), zeta {:.5} (truth {:.5}, {:+.1} %)",
                m.freq_hz,
                t.0,
                100.0 * ef,
                m.zeta,
                t.1,
                100.0 * ez
            );
            assert!(ef.abs() < 0.002, "frequency error {ef}");
            assert!(ez.abs() < 0.15, "damping error {ez}");
        }
        assert!(r.rayleigh.is_some());
    }
}

#[test]
fn without_the_tracking_filter_input_noise_spoils_mode_2_damping() {
    // The control experiment for the tracking filter: same data, filter off.
    let m = model();
    let spec = SweepSpec {
        tail_s: 20.0,
        ..SweepSpec::paper(SweepKind::Exponential, beta_120s())
    };
    let rec = simulate_sweep(&m, &spec, 100.0, 0.05, 7).unwrap();
    let opts = IdentOptions {
        track_input: false,
        input: InputChannel::BaseAccel,
        band_hz: Some((0.3, 8.0)),
        n_modes: Some(2),
        ..Default::default()
    };
    let ok = match identify_recording(&rec, &opts) {
        Ok((r, _)) => r.modes.len() == 2 && (r.modes[1].zeta / 0.0074 - 1.0).abs() < 0.15,
        Err(_) => false,
    };
    assert!(!ok, "expected a failure without the tracking filter");
}
