//! Long recordings (issue 70, item 6): decimation to the band before the FRF keeps the modes,
//! and a long 1 kHz sweep goes through `identify` decimated with its modes right.

use beamtools::ident::identify::{decimation_factor, identify, IdentPath, IdentifyOptions};
use beamtools::ident::protocol::{simulate_sweep, truth};
use beamtools::ident::sweep::{SweepKind, SweepSpec};
use beamtools::ident::{identify_recording, IdentOptions, ModeEstimate};
use beamtools::model::{BeamModel, ModelOptions, Rig};

fn model() -> BeamModel {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    BeamModel::new(&rig, &ModelOptions::default()).unwrap()
}

fn near(modes: &[ModeEstimate], f: f64) -> &ModeEstimate {
    modes
        .iter()
        .find(|m| (m.freq_hz / f - 1.0).abs() < 0.01)
        .unwrap_or_else(|| panic!("no mode near {f} Hz in {modes:?}"))
}

/// The paper's exponential sweep (3 octaves/min, 5 % noise) at 250 Hz: the FRF estimators on
/// the full-rate record and on the record decimated by 3 (anti-aliased FIR, 83.3 Hz, Nyquist
/// 5 × the 8 Hz band top) give the same modes within their 1-σ.
#[test]
fn decimation_before_the_frf_keeps_the_modes_within_their_sigma() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let spec = SweepSpec::paper(SweepKind::Exponential, 3.0);
    let rec = simulate_sweep(&m, &spec, 250.0, 0.05, 3).unwrap();
    let opts = IdentOptions::default();
    let (full, _) = identify_recording(&rec, &opts).unwrap();
    let (dec, frf) = identify_recording(&rec.decimated(3), &opts).unwrap();
    assert!((frf.sample_rate_hz - 250.0 / 3.0).abs() < 1e-6);
    for (f, z) in &tr[..2] {
        let (a, b) = (near(&full.modes, *f), near(&dec.modes, *f));
        let sf = a.freq_hz_std.hypot(b.freq_hz_std);
        let sz = a.zeta_std.hypot(b.zeta_std);
        assert!(sf > 0.0 && sz > 0.0, "{a:?} {b:?}");
        assert!(
            (a.freq_hz - b.freq_hz).abs() <= sf,
            "f {a:?} vs decimated {b:?}"
        );
        assert!((a.zeta - b.zeta).abs() <= sz, "ζ {a:?} vs decimated {b:?}");
        // and both right: f within 0.2 %, ζ within 5 % of the model's
        for e in [a, b] {
            assert!((e.freq_hz / f - 1.0).abs() < 0.002, "{e:?} vs {f}");
            assert!((e.zeta / z - 1.0).abs() < 0.05, "{e:?} vs {z}");
        }
    }
}

/// A 400 s sweep recorded at 1 kHz (402 000 samples) is decimated before the FRF (by 6: at
/// least 2¹⁶ samples are kept) and its two modes come out within 0.2 % / 5 % of the model's.
#[test]
fn a_long_1khz_sweep_is_decimated_and_identified() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let spec = SweepSpec::paper(SweepKind::Exponential, 1.0);
    let rec = simulate_sweep(&m, &spec, 1000.0, 0.05, 5).unwrap();
    let opts = IdentifyOptions::default();
    let q = decimation_factor(&rec, IdentPath::Frf, &opts);
    assert_eq!(q, rec.len() >> 16, "{} samples", rec.len());
    let id = identify(&rec, &opts, &mut |_| {}).unwrap();
    assert_eq!(id.path, IdentPath::Frf, "{}", id.reason);
    assert!((id.sample_rate_hz - 1000.0 / q as f64).abs() < 1e-6);
    assert!(
        id.warnings
            .iter()
            .any(|w| w.contains(&format!("decimated by {q}"))),
        "{:?}",
        id.warnings
    );
    for (f, z) in &tr[..2] {
        let e = near(&id.modes, *f);
        assert!((e.freq_hz / f - 1.0).abs() < 0.002, "{e:?} vs {f}");
        assert!((e.zeta / z - 1.0).abs() < 0.05, "{e:?} vs {z}");
    }
}
