//! The one identification entry point (`ident::identify`) on every kind of recording of
//! issue 11: tune's generated recording, a move + ring-down with a dithering servo, the
//! paper's exponential sweep, a decay with a logging gap, a 1 kHz step, the real decays, and
//! the recording formats (float32/int `.npy`, time in ms, NaN).

use beamtools::ident::identify::{identify, identify_file, IdentPath, IdentifyOptions, PathChoice};
use beamtools::ident::protocol::{add_noise, simulate_sweep, truth};
use beamtools::ident::sweep::{SweepKind, SweepSpec};
use beamtools::ident::Identification;
use beamtools::model::sim::BaseMotionSim;
use beamtools::model::{trapezoid_reference, BeamModel, ModelOptions, Rig};
use beamtools::recording::Recording;
use rand::{Rng, SeedableRng};
use std::path::PathBuf;

fn model() -> BeamModel {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    BeamModel::new(&rig, &ModelOptions::default()).unwrap()
}

/// A path `name` in a fresh directory, removed when the returned guard is dropped.
fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join(name);
    (d, p)
}

/// Every identified mode is within 1 % of a true mode (no spurious mode), and the first
/// `n_checked` true modes are found with f within `f_tol` and ζ within `z_tol` (relative).
fn check(id: &Identification, truth: &[(f64, f64)], n_checked: usize, f_tol: f64, z_tol: f64) {
    let table = beamtools::ident::report::identification_table(id);
    for m in &id.modes {
        assert!(
            truth
                .iter()
                .any(|(f, _)| (m.freq_hz / f - 1.0).abs() < 0.01),
            "spurious mode {} Hz\n{table}",
            m.freq_hz
        );
    }
    for (f, z) in &truth[..n_checked] {
        let m = id
            .modes
            .iter()
            .find(|m| (m.freq_hz / f - 1.0).abs() < 0.01)
            .unwrap_or_else(|| panic!("mode {f} Hz missing\n{table}"));
        assert!(
            (m.freq_hz / f - 1.0).abs() < f_tol,
            "f {} vs {f}\n{table}",
            m.freq_hz
        );
        assert!(
            (m.zeta / z - 1.0).abs() < z_tol,
            "ζ {} vs {z}\n{table}",
            m.zeta
        );
    }
}

fn no_progress() -> impl FnMut(beamtools::ident::Stage) {
    |_| {}
}

/// Repro: `identify` on tune's generated recording reported five spurious modes, dropped
/// 1.105 and 6.92 Hz and printed a negative Rayleigh α1.
#[test]
fn tunes_generated_recording_has_only_physical_modes() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    let (_dir, p) = tmp("generated-recording.csv");
    beamtools::tune::generate_recording(&rig, &p).unwrap();
    let id = identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::RingDown, "{}", id.reason);
    check(&id, &tr, 2, 0.002, 0.10);
    let (a1, a2) = id.rayleigh.unwrap();
    assert!(a1 > 0.0 && a2 > 0.0);
    // The FRF path on the same step recording: the 1.1 Hz mode (stable at 29 orders) is in
    // the table and nothing spurious is.
    let o = IdentifyOptions {
        path: PathChoice::Frf,
        ..Default::default()
    };
    let id = identify_file(&p, &o, &mut no_progress()).unwrap();
    // ζ1 on this path measures +21 % (one step, one average: the ring-down path is the one
    // `auto` takes, above); the check here is the table's content.
    check(&id, &tr, 1, 0.002, 0.3);
    assert!(!id.rejected.is_empty());
}

/// Repro: a 20 mm move followed by 40 s of ring-down, the servo-held base dithering by
/// ±2 µm: "only 41 samples after the base stopped moving", spurious 15/20/30 Hz modes.
#[test]
fn move_and_ring_down_with_a_dithering_servo() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let sim = BaseMotionSim::new(&m, 1e-3).unwrap();
    let (y, _) = trapezoid_reference(0.0, 0.02, 0.2, 2.0, 1000.0, 40.0).unwrap();
    let mut rec = beamtools::recording::decimate(&sim.recording(&y, 0.0), 100.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    // Encoder quantisation of 1 µm and a servo wandering by up to ±2 µm.
    for v in rec.base_pos_m.as_mut().unwrap().iter_mut() {
        *v = ((*v + rng.gen_range(-2e-6..=2e-6)) * 1e6).round() * 1e-6;
    }
    add_noise(&mut rec, 0.0, 1);
    for v in rec.tip_pos_m.as_mut().unwrap().iter_mut() {
        *v += rng.gen_range(-20e-6..20e-6);
    }
    rec.force_n = None;
    let id = identify(&rec, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::RingDown, "{}", id.reason);
    check(&id, &tr, 2, 0.002, 0.10);
    let b = id.base.as_ref().unwrap();
    assert!(b.still_band_m > 2e-6 && b.still_band_m < 2e-5, "{b:?}");
}

/// Repro: `tune` refused the paper's exponential sweep ("only 27 samples after the base
/// stopped moving"). Acceptance: f within 0.2 %, ζ within 5 %.
#[test]
fn exponential_sweep_goes_through_the_frf() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let spec = SweepSpec::paper(SweepKind::Exponential, 3.0);
    let rec = simulate_sweep(&m, &spec, 100.0, 0.05, 1).unwrap();
    let id = identify(&rec, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::Frf, "{}", id.reason);
    check(&id, &tr, 2, 0.002, 0.05);
}

fn decay_6hz(rate: f64, dur: f64) -> (Vec<f64>, Vec<f64>) {
    let (f, z) = (6.0, 0.005);
    let w = 2.0 * std::f64::consts::PI * f;
    let wd = w * (1.0f64 - z * z).sqrt();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    (0..(dur * rate) as usize)
        .map(|k| {
            let t = k as f64 / rate;
            (
                t,
                1e-3 * (-z * w * t).exp() * (wd * t).cos() + rng.gen_range(-2e-6..2e-6),
            )
        })
        .unzip()
}

/// Repro: a clean 6 Hz decay with a 500 ms logging gap gave f −8.6 % and ζ 13× too high.
#[test]
fn a_logging_gap_splits_the_recording() {
    let (t, x) = decay_6hz(100.0, 20.5);
    let keep: Vec<usize> = (0..t.len()).filter(|&k| !(200..250).contains(&k)).collect();
    let rec = Recording {
        time_s: keep.iter().map(|&k| t[k]).collect(),
        tip_pos_m: Some(keep.iter().map(|&k| x[k]).collect()),
        ..Default::default()
    };
    let id = identify(&rec, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::FreeDecay);
    check(&id, &[(6.0, 0.005)], 1, 0.002, 0.10);
    assert!(
        id.warnings.iter().any(|w| w.contains("logging gap")),
        "{:?}",
        id.warnings
    );
    assert!(id.span_s.0 > 2.4, "{:?}", id.span_s);
}

/// Repro: "no mode found" on 1 kHz step recordings.
#[test]
fn step_recorded_at_1_khz() {
    let m = model();
    let tr = truth(&m).unwrap().clamped;
    let sim = BaseMotionSim::new(&m, 1e-3).unwrap();
    let (y, _) = trapezoid_reference(0.0, 0.05, 0.2, 2.0, 1000.0, 30.0).unwrap();
    let mut rec = sim.recording(&y, 0.0);
    rec.force_n = None;
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    for v in rec.tip_pos_m.as_mut().unwrap().iter_mut() {
        *v += rng.gen_range(-20e-6..20e-6);
    }
    let id = identify(&rec, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::RingDown, "{}", id.reason);
    check(&id, &tr, 2, 0.002, 0.10);
}

/// The three real accelerometer decays (no truth: README values f1 9.41, 6.05, 4.26 Hz).
#[test]
fn real_aluminium_decays() {
    let dir = "../../shared/data/real/aluminium-cantilever";
    if !std::path::Path::new(dir).exists() {
        eprintln!("skipped: {dir} not present");
        return;
    }
    for (name, f1) in [
        ("40cm_adxl_08-12_11-42-08_adxl6cmfromtip2cmID.npy", 9.4065),
        ("50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy", 6.0545),
        ("60cm_adxl_08-12_21-22-38_4cmID.npy", 4.2588),
    ] {
        let p = PathBuf::from(dir).join(name);
        let id = identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap();
        assert_eq!(id.path, IdentPath::FreeDecay);
        assert!(
            (id.modes[0].freq_hz / f1 - 1.0).abs() < 0.002,
            "{name}: {:?}",
            id.modes
        );
        // Second mode near the cantilever ratio (6.3-6.6 × f1).
        let r = id.modes[1].freq_hz / id.modes[0].freq_hz;
        assert!((6.2..6.7).contains(&r), "{name}: ratio {r}");
    }
}

fn write_npy(
    path: &PathBuf,
    descr: &str,
    bytes_per: usize,
    t: &[f64],
    x: &[f64],
    enc: fn(f64) -> Vec<u8>,
) {
    let mut h = format!(
        "{{'descr': '{descr}', 'fortran_order': False, 'shape': (2, {}), }}",
        t.len()
    );
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((h.len() as u16).to_le_bytes());
    b.extend(h.as_bytes());
    for v in t.iter().chain(x) {
        let e = enc(*v);
        assert_eq!(e.len(), bytes_per);
        b.extend(e);
    }
    std::fs::write(path, b).unwrap();
}

/// `.npy` in float32 and int16 (time in µs-scaled ints refused as ms-like? no: scaled here),
/// a CSV time column in ms, a unit-less time column, NaN, a time base in ms read as s.
#[test]
fn recording_formats_and_messages() {
    let (t, x) = decay_6hz(200.0, 15.0);
    let (_dir, p) = tmp("f32.npy");
    write_npy(&p, "<f4", 4, &t, &x, |v| (v as f32).to_le_bytes().to_vec());
    let id = identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert!(
        (id.modes[0].freq_hz / 6.0 - 1.0).abs() < 0.002,
        "{:?}",
        id.modes
    );
    // int16: time in ms (integers), signal in µm: refused with the ms hint.
    let (_dir, p) = tmp("i16.npy");
    let ti: Vec<f64> = t.iter().map(|v| (v * 1000.0).round()).collect();
    let xi: Vec<f64> = x.iter().map(|v| (v * 1e6).round()).collect();
    write_npy(&p, "<i2", 2, &ti[..3000], &xi[..3000], |v| {
        (v as i16).to_le_bytes().to_vec()
    });
    let e = format!(
        "{:#}",
        identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap_err()
    );
    assert!(e.contains("milliseconds"), "{e}");
    // CSV with time_ms: recognised.
    let (_dir, p) = tmp("ms.csv");
    let mut s = String::from("time_ms,tip_pos_m\n");
    for (a, b) in t.iter().zip(&x) {
        s += &format!("{},{}\n", a * 1000.0, b);
    }
    std::fs::write(&p, &s).unwrap();
    let id = identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    assert!((id.modes[0].freq_hz / 6.0 - 1.0).abs() < 0.002);
    // Unit-less time column: refused with the hint; no debug text.
    std::fs::write(&p, s.replacen("time_ms", "time", 1)).unwrap();
    let e = format!(
        "{:#}",
        identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap_err()
    );
    assert!(e.contains("time_ms") && !e.contains("StringRecord"), "{e}");
    std::fs::write(&p, "a,b\n1,2\n").unwrap();
    let e = format!(
        "{:#}",
        identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap_err()
    );
    assert!(
        e.contains("no `time_s` column (header: a, b)") && !e.contains("StringRecord"),
        "{e}"
    );
    // NaN refused with the row named.
    std::fs::write(
        &p,
        s.replacen("\n5,", "\nNaN,", 1)
            .replacen("time_ms", "time_s", 1),
    )
    .unwrap();
    let e = format!(
        "{:#}",
        identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap_err()
    );
    assert!(
        e.contains("not finite") || e.contains("not a number"),
        "{e}"
    );
    // A time base in ms named time_s: refused with the hint.
    std::fs::write(&p, s.replacen("time_ms", "time_s", 1)).unwrap();
    let e = format!(
        "{:#}",
        identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap_err()
    );
    assert!(e.contains("milliseconds"), "{e}");
}

/// `.lvm` works wherever a recording is read: the entry point reads it as a spectrum.
#[test]
fn lvm_spectrum_through_the_entry_point() {
    let p = PathBuf::from("../../shared/data/real/steel-cantilever/FFT_data_impulse_test.lvm");
    if !p.exists() {
        eprintln!("skipped: {} not present", p.display());
        return;
    }
    let o = IdentifyOptions {
        decay: beamtools::ident::freedecay::FreeDecayOptions {
            f_min_hz: 1.0,
            f_max_hz: 1000.0,
            ..Default::default()
        },
        ..Default::default()
    };
    let id = identify_file(&p, &o, &mut no_progress()).unwrap();
    assert_eq!(id.path, IdentPath::Spectrum);
    assert!((id.modes[0].freq_hz - 6.6).abs() < 0.05, "{:?}", id.modes);
    // The free-decay signal of a dithering move starts where the base is still.
    let m = model();
    let sim = BaseMotionSim::new(&m, 1e-3).unwrap();
    let (y, _) = trapezoid_reference(0.0, 0.02, 0.2, 2.0, 1000.0, 10.0).unwrap();
    let mut rec = beamtools::recording::decimate(&sim.recording(&y, 0.0), 100.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    for v in rec.base_pos_m.as_mut().unwrap().iter_mut() {
        *v += rng.gen_range(-2e-6..2e-6);
    }
    let (t, _, what) = beamtools::ident::identify::free_decay_signal(&rec).unwrap();
    assert!((0.15..0.3).contains(&t[0]), "{} {what}", t[0]);
}

/// A decay logged to CSV with blank cells where the sensor dropped out: identified as the
/// clean one, and the fill is reported (before: `column tip_pos_m is not finite`).
#[test]
fn blank_cells_in_a_csv_are_filled_and_reported() {
    let (t, x) = decay_6hz(100.0, 20.5);
    let mut csv = String::from("time_s,tip_pos_m\n");
    for (k, (t, x)) in t.iter().zip(&x).enumerate() {
        let v = if k % 150 == 75 || k == 400 || k == 401 {
            String::new()
        } else {
            format!("{x}")
        };
        csv.push_str(&format!("{t},{v}\n"));
    }
    let (_dir, p) = tmp("decay-with-blanks.csv");
    std::fs::write(&p, csv).unwrap();
    let id = identify_file(&p, &IdentifyOptions::default(), &mut no_progress()).unwrap();
    check(&id, &[(6.0, 0.005)], 1, 0.002, 0.10);
    assert!(
        id.warnings
            .iter()
            .any(|w| w.contains("tip_pos_m: 16 missing values filled")),
        "{:?}",
        id.warnings
    );
}
