//! Bad input to the identification: clear errors (or warnings), never a panic.

use beamtools::ident::protocol::simulate_sweep;
use beamtools::ident::sweep::{SweepKind, SweepSpec};
use beamtools::ident::{identify_recording, IdentOptions};
use beamtools::model::{BeamModel, ModelOptions, Rig};
use beamtools::recording::Recording;

fn rec() -> Recording {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    let m = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
    let spec = SweepSpec {
        tail_s: 5.0,
        ..SweepSpec::paper(SweepKind::Exponential, 7.0)
    };
    simulate_sweep(&m, &spec, 100.0, 0.01, 1).unwrap()
}

fn err(r: &Recording, o: &IdentOptions) -> String {
    format!(
        "{:#}",
        identify_recording(r, o).err().expect("expected an error")
    )
}

#[test]
fn each_bad_input_gives_a_clear_error() {
    let o = IdentOptions {
        band_hz: Some((0.3, 8.0)),
        ..Default::default()
    };
    let good = rec();
    assert!(identify_recording(&good, &o).is_ok());

    let mut r = good.clone();
    r.tip_pos_m.as_mut().unwrap()[100] = f64::NAN;
    assert!(err(&r, &o).contains("not finite"), "{}", err(&r, &o));

    let mut r = good.clone();
    r.time_s[11] = r.time_s[10];
    assert!(err(&r, &o).contains("not strictly increasing"));

    let mut r = good.clone();
    r.time_s[50] += 0.004;
    assert!(err(&r, &o).contains("not uniformly sampled"));

    let mut r = good.clone();
    r.time_s.truncate(100);
    for c in [
        &mut r.base_cmd_m,
        &mut r.base_pos_m,
        &mut r.tip_pos_m,
        &mut r.force_n,
    ] {
        c.as_mut().unwrap().truncate(100);
    }
    assert!(err(&r, &o).contains("at least 256"));

    let o2 = IdentOptions {
        band_hz: Some((0.3, 80.0)),
        ..Default::default()
    };
    assert!(err(&good, &o2).contains("Nyquist"));

    let mut r = good.clone();
    r.tip_pos_m = None;
    assert!(err(&r, &o).contains("tip_pos_m"));
    let mut r = good.clone();
    r.force_n = None;
    let of = IdentOptions {
        input: beamtools::ident::frf::InputChannel::Force,
        ..o.clone()
    };
    assert!(err(&r, &of).contains("force_n"));
}

#[test]
fn a_clipped_output_is_a_warning() {
    let o = IdentOptions {
        band_hz: Some((0.3, 8.0)),
        ..Default::default()
    };
    let mut r = rec();
    let base = r.base_pos_m.clone().unwrap();
    let tip = r.tip_pos_m.as_mut().unwrap();
    let defl_max = tip
        .iter()
        .zip(&base)
        .map(|(t, b)| (t - b).abs())
        .fold(0.0, f64::max);
    let lim = 0.5 * defl_max;
    for (t, b) in tip.iter_mut().zip(&base) {
        *t = b + (*t - b).clamp(-lim, lim);
    }
    let (res, _) = identify_recording(&r, &o).unwrap();
    assert!(
        res.warnings.iter().any(|w| w.contains("clipped")),
        "{:?}",
        res.warnings
    );
}
