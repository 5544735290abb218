//! Free-decay identification on synthetic decays of known modes (noise, non-uniform time),
//! on the real aluminium-cantilever recordings, and bad input.

use beamtools::ident::freedecay::{identify_free_decay, FreeDecayOptions};
use beamtools::recording::Recording;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

fn decay(t: &[f64], modes: &[(f64, f64, f64)], noise: f64, seed: u64) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let n = Normal::new(0.0, noise.max(1e-300)).unwrap();
    t.iter()
        .map(|&t| {
            modes
                .iter()
                .map(|&(f, z, a)| {
                    let w = 2.0 * PI * f;
                    a * (-z * w * t).exp() * (w * (1.0 - z * z).sqrt() * t).cos()
                })
                .sum::<f64>()
                + n.sample(&mut rng)
        })
        .collect()
}

#[test]
fn recovers_frequency_and_damping_of_two_modes_with_noise() {
    // Vary frequency, damping, noise and sample rate widely.
    for &(f1, z1, f2, z2, rate, noise, secs) in &[
        (1.1, 0.0074, 6.9, 0.0074, 100.0, 0.01, 40.0),
        (4.3, 0.011, 27.6, 0.004, 2000.0, 0.02, 20.0),
        (0.35, 0.03, 2.4, 0.02, 50.0, 0.005, 120.0),
        (12.0, 0.002, 75.0, 0.003, 1000.0, 0.002, 30.0),
    ] {
        let t: Vec<f64> = (0..(rate * secs) as usize)
            .map(|k| k as f64 / rate)
            .collect();
        let x = decay(&t, &[(f1, z1, 1.0), (f2, z2, 0.05)], noise, 1);
        let r = identify_free_decay(&t, &x, &FreeDecayOptions::default()).unwrap();
        let m = &r.modes[0];
        assert!(
            (m.freq_hz / f1 - 1.0).abs() < 2e-3,
            "f1 {} vs {f1}",
            m.freq_hz
        );
        assert!(
            (m.zeta / z1 - 1.0).abs() < 0.15,
            "zeta1 {} vs {z1} (f1 {f1})",
            m.zeta
        );
        let m2 = r
            .modes
            .get(1)
            .unwrap_or_else(|| panic!("mode 2 at {f2} Hz not found: {:?}", r.other_peaks_hz));
        assert!(
            (m2.freq_hz / f2 - 1.0).abs() < 5e-3,
            "f2 {} vs {f2}",
            m2.freq_hz
        );
        assert!(
            (m2.zeta / z2 - 1.0).abs() < 0.25,
            "zeta2 {} vs {z2}",
            m2.zeta
        );
    }
}

#[test]
fn non_uniform_time_is_resampled_with_a_warning() {
    let mut t = Vec::new();
    let mut tt = 0.0;
    for k in 0..40_000 {
        tt += if k % 997 == 0 { 0.006 } else { 0.00025 };
        t.push(tt);
    }
    let x = decay(&t, &[(6.05, 0.004, 1.0)], 0.001, 2);
    let r = identify_free_decay(&t, &x, &FreeDecayOptions::default()).unwrap();
    assert!(r.warnings.iter().any(|w| w.contains("non-uniform")));
    assert!(
        (r.mode.freq_hz / 6.05 - 1.0).abs() < 2e-3 && (r.mode.zeta / 0.004 - 1.0).abs() < 0.15,
        "{:?}",
        r.mode
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
    let mut x = decay(&t, &[(2.0, 0.01, 1.0)], 0.0, 3);
    assert!(
        identify_free_decay(&t[..10], &x[..10], &FreeDecayOptions::default())
            .unwrap_err()
            .to_string()
            .contains("at least 64")
    );
    x[500] = f64::NAN;
    assert!(identify_free_decay(&t, &x, &FreeDecayOptions::default())
        .unwrap_err()
        .to_string()
        .contains("NaN"));
    let mut t2 = t.clone();
    t2[300] = t2[299];
    let x2 = decay(&t, &[(2.0, 0.01, 1.0)], 0.0, 3);
    assert!(identify_free_decay(&t2, &x2, &FreeDecayOptions::default())
        .unwrap_err()
        .to_string()
        .contains("not strictly increasing"));
    let flat = vec![0.0; 1000];
    assert!(identify_free_decay(&t, &flat, &FreeDecayOptions::default()).is_err());
}

#[test]
fn real_aluminium_free_decays() {
    let dir = "../../shared/data/real/aluminium-cantilever";
    let mut f = Vec::new();
    for (name, lo, hi) in [
        ("40cm_adxl_08-12_11-42-08_adxl6cmfromtip2cmID.npy", 9.2, 9.6),
        ("50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy", 5.9, 6.2),
        ("60cm_adxl_08-12_21-22-38_4cmID.npy", 4.1, 4.4),
    ] {
        let (t, x) = Recording::read_npy(format!("{dir}/{name}")).unwrap();
        let r = identify_free_decay(&t, &x, &FreeDecayOptions::default()).unwrap();
        println!(
            "{name}: f1 = {:.4} Hz +- {:.4}, zeta1 = {:.5} +- {:.5}",
            r.mode.freq_hz, r.mode.freq_hz_std, r.mode.zeta, r.mode.zeta_std
        );
        assert!((lo..hi).contains(&r.mode.freq_hz));
        assert!(r.mode.zeta > 0.0005 && r.mode.zeta < 0.05);
        f.push(r.mode.freq_hz);
    }
    // Shorter beams ring faster.
    assert!(f[0] > f[1] && f[1] > f[2]);
}

#[test]
fn recording_csv_errors_name_row_and_column() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let p = dir.join("bad.csv");
    std::fs::write(&p, "time_s,tip_pos_m\n0,0\n0.01,abc\n").unwrap();
    let e = format!("{:#}", Recording::read_csv(&p).unwrap_err());
    assert!(e.contains("row 2") && e.contains("tip_pos_m"), "{e}");
    // a NaN or blank cell is a missing value, filled with a note (recording::regular)
    let mut csv = String::from("time_s,tip_pos_m\n");
    for k in 0..30 {
        let v = match k {
            3 => "NaN",
            7 => "",
            _ => "0",
        };
        csv.push_str(&format!("{},{v}\n", k as f64 / 100.0));
    }
    std::fs::write(&p, csv).unwrap();
    let r = Recording::read_csv(&p).unwrap();
    assert_eq!(r.tip_pos_m.as_deref(), Some(&[0.0; 30][..]));
    assert!(r
        .notes
        .iter()
        .any(|n| n.contains("tip_pos_m: 2 missing values filled")));
    // a gap longer than the filled runs is refused with where it is
    std::fs::write(&p, "time_s,tip_pos_m\n0,0\n0.01,0\n0.20,0\n0.21,0\n").unwrap();
    let e = format!("{:#}", Recording::read_csv(&p).unwrap_err());
    assert!(
        e.contains("18 consecutive samples missing after 0.01"),
        "{e}"
    );
    // a row written one place late is put in order; a clock reset is refused where it is
    std::fs::write(&p, "time_s,tip_pos_m\n0,0\n0.02,0\n0.01,0\n").unwrap();
    let r = Recording::read_csv(&p).unwrap();
    assert_eq!(r.time_s, [0.0, 0.01, 0.02]);
    assert!(r.notes[0].contains("out of time order"), "{:?}", r.notes);
    let reset: String = (0..30)
        .chain(0..15)
        .map(|k| format!("{},0\n", k as f64 / 100.0))
        .collect();
    std::fs::write(&p, format!("time_s,tip_pos_m\n{reset}")).unwrap();
    let e = format!("{:#}", Recording::read_csv(&p).unwrap_err());
    assert!(e.contains("goes backwards at data row 31"), "{e}");
    std::fs::write(&p, "t,tip_pos_m\n0,0\n").unwrap();
    assert!(format!("{:#}", Recording::read_csv(&p).unwrap_err()).contains("time_s"));
}

/// The real steel cantilever's impact-test magnitude spectrum (`.lvm`): the first two bending
/// modes near the source's 6.6 and 41.4 Hz, damping flagged as resolution-limited (the peaks
/// are one or two lines of 0.085 Hz wide), higher modes in the bending-mode ratios.
#[test]
fn real_steel_impact_spectrum() {
    use beamtools::ident::magspec::{identify_magnitude_spectrum, read_lvm};
    let path =
        std::path::Path::new("../../shared/data/real/steel-cantilever/FFT_data_impulse_test.lvm");
    if !path.exists() {
        eprintln!("skipped: {} not present", path.display());
        return;
    }
    let s = read_lvm(path).unwrap();
    assert_eq!(s.freq_hz.len(), 150000);
    assert_eq!(s.unit, "g");
    let m = identify_magnitude_spectrum(&s, 1.0, 1000.0, 10.0, 6).unwrap();
    eprintln!("{m:#?}");
    assert!((m[0].freq_hz - 6.6).abs() < 0.1, "{:?}", m[0]);
    assert!((m[1].freq_hz - 41.4).abs() < 0.2, "{:?}", m[1]);
    assert!(m[0].resolution_limited && m[0].zeta < 0.02);
    // Third and fourth bending modes: uniform-beam ratios 17.55 and 34.39, within 3 %.
    assert!((m[2].freq_hz / m[0].freq_hz / 17.547 - 1.0).abs() < 0.03);
    assert!((m[3].freq_hz / m[0].freq_hz / 34.386 - 1.0).abs() < 0.03);
}

/// A broken `.lvm` is a clear error naming the line.
#[test]
fn bad_lvm_is_a_clear_error() {
    use beamtools::ident::magspec::read_lvm;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let head = "LabVIEW Measurement\t\n***End_of_Header***\t\nDelta_X\t0.5\t\n***End_of_Header***\t\t\nX_Value\tAcceleration\tComment\n";
    let good: String = (0..40)
        .map(|k| format!("{}\t-80.0\n", 0.5 * k as f64))
        .collect();
    let cases = [
        ("no-header.lvm", good.clone(), "End_of_Header"),
        (
            "nan.lvm",
            format!("{head}{good}20.0\tabc\n"),
            "not a number",
        ),
        (
            "short.lvm",
            format!("{head}0\t-1\n0.5\t-2\n"),
            "at least 16",
        ),
        (
            "grid.lvm",
            format!("{head}{good}30.0\t-80\n"),
            "non-uniform",
        ),
    ];
    for (name, body, want) in cases {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        let e = format!("{:#}", read_lvm(&p).unwrap_err());
        assert!(e.contains(want), "{name}: {e}");
    }
    let p = dir.join("ok.lvm");
    std::fs::write(&p, format!("{head}{good}")).unwrap();
    assert_eq!(read_lvm(&p).unwrap().freq_hz.len(), 40);
}
