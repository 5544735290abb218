//! Klipper's metrics (v0.13.0 method, `shaping::klipper`), the spectrum reader
//! (`recording::psd`), the spectrum design (`shaping::spectrum`) and the CLI on a spectrum.
//!
//! `data/klipper_resonances_two_modes.csv` is synthetic, in Klipper's resonances format: two
//! modes (42 Hz ζ 0.06 mostly along X, 98 Hz ζ 0.05 mostly along Y) as
//! `Σ g·f⁴/((f_m² − f²)² + (2ζ_m f_m f)²)` plus a flat noise floor, on Klipper's bins
//! (1.5625 Hz up to 200 Hz), written `%.1f,%.3e`. `KLIPPER_OUTPUT` is what Klipper v0.13.0's
//! own `scripts/calibrate_shaper.py` printed for that file (run once outside the repository).

use beamtools::recording::psd::{parse_spectrum, read_spectrum};
use beamtools::shaping::klipper::{
    max_accel_mm_s2, recommend, remaining_vibrations, response, smoothing_mm, FitSpectrum,
    KlipperShaper, TARGET_SMOOTHING_MM,
};
use beamtools::shaping::spectrum::{
    design_for_spectrum, metrics, verdict, Objective, VIBRATION_MARGIN,
};
use std::path::{Path, PathBuf};
use std::process::Command;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/klipper_resonances_two_modes.csv")
}

/// Klipper v0.13.0 `calibrate_shaper.py data/klipper_resonances_two_modes.csv`.
const KLIPPER_OUTPUT: [&str; 11] = [
    "Fitted shaper 'zv' frequency = 41.2 Hz (vibrations = 12.2%, smoothing ~= 0.095)",
    "To avoid too much smoothing with 'zv', suggested max_accel <= 6600 mm/sec^2",
    "Fitted shaper 'mzv' frequency = 26.6 Hz (vibrations = 1.2%, smoothing ~= 0.288)",
    "To avoid too much smoothing with 'mzv', suggested max_accel <= 2100 mm/sec^2",
    "Fitted shaper 'ei' frequency = 37.4 Hz (vibrations = 0.0%, smoothing ~= 0.230)",
    "To avoid too much smoothing with 'ei', suggested max_accel <= 2600 mm/sec^2",
    "Fitted shaper '2hump_ei' frequency = 65.4 Hz (vibrations = 0.0%, smoothing ~= 0.126)",
    "To avoid too much smoothing with '2hump_ei', suggested max_accel <= 4800 mm/sec^2",
    "Fitted shaper '3hump_ei' frequency = 78.4 Hz (vibrations = 0.0%, smoothing ~= 0.133)",
    "To avoid too much smoothing with '3hump_ei', suggested max_accel <= 4500 mm/sec^2",
    "Recommended shaper is 2hump_ei @ 65.4 Hz",
];

/// ZV at ζ_d = 0.1 by hand: A = [1, K]/(1 + K), t = [0, T_d/2], K = exp(−ζπ/√(1−ζ²)).
fn zv_by_hand(f_hz: f64) -> ([f64; 2], [f64; 2]) {
    let z: f64 = 0.1;
    let df = (1.0 - z * z).sqrt();
    let k = (-z * std::f64::consts::PI / df).exp();
    ([1.0 / (1.0 + k), k / (1.0 + k)], [0.0, 0.5 / (f_hz * df)])
}

#[test]
fn zv_leaves_nothing_at_its_design_frequency_and_the_hand_value_off_its_damping() {
    let f0 = 50.0;
    let zv = KlipperShaper::Zv.design(f0);
    assert!(response(&zv, &[f0], 0.1)[0] < 1e-12);
    // One bin of power P at f0: threshold P/20, so R(ζ) = max(V(f0, ζ) − 1/20, 0) / (1 − 1/20).
    // V by hand at ζ = 0.15 (two impulses: |A1 e^{−ζω t2} + A2 e^{iω_d t2}|).
    let (a, t) = zv_by_hand(f0);
    let v_at = |z: f64| {
        let w = 2.0 * std::f64::consts::PI * f0;
        let wd = w * (1.0 - z * z).sqrt();
        let g = a[0] * (-z * w * t[1]).exp();
        ((g + a[1] * (wd * t[1]).cos()).powi(2) + (a[1] * (wd * t[1]).sin()).powi(2)).sqrt()
    };
    let expected = [0.075, 0.1, 0.15]
        .map(|z| (v_at(z) - 0.05).max(0.0) / 0.95)
        .into_iter()
        .fold(0.0, f64::max);
    assert!(
        expected > 0.005,
        "the check must see a non-zero value: {expected}"
    );
    let spec = FitSpectrum {
        freq_hz: vec![f0 - 10.0, f0, f0 + 10.0],
        psd: vec![0.0, 1.0, 0.0],
    };
    let got = remaining_vibrations(&zv, &spec);
    assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
}

#[test]
fn smoothing_and_max_accel_of_a_zv_by_hand() {
    let (f, accel, scv) = (40.0, 5000.0, 5.0);
    let (a, t) = zv_by_hand(f);
    // Centre t̄ = A2·t2; only the second impulse lies after it.
    let ts = a[1] * t[1];
    let d = t[1] - ts;
    let s90 = 2f64.sqrt() * a[1] * (scv + 0.5 * accel * d) * d;
    let s180 = 0.5 * accel * (a[0] * ts * ts + a[1] * d * d);
    let zv = KlipperShaper::Zv.design(f);
    let got = smoothing_mm(&zv, accel, scv);
    assert!((got - s90.max(s180)).abs() < 1e-12, "{got}");
    let m = max_accel_mm_s2(&zv, scv);
    assert!((smoothing_mm(&zv, m, scv) - TARGET_SMOOTHING_MM).abs() < 1e-9);
    assert!(smoothing_mm(&zv, 1.01 * m, scv) > TARGET_SMOOTHING_MM);
}

#[test]
fn klipper_recommendation_matches_klipper_own_output() {
    let s = read_spectrum(&data()).unwrap();
    assert!(!s.normalized);
    let fit = FitSpectrum::from_spectrum(&s);
    let r = recommend(&fit);
    let mut lines = vec![];
    for f in &r.fitted {
        lines.push(format!(
            "Fitted shaper '{}' frequency = {:.1} Hz (vibrations = {:.1}%, smoothing ~= {:.3})",
            f.kind.name(),
            f.freq_hz,
            f.vibrations * 100.0,
            f.smoothing_mm
        ));
        lines.push(format!(
            "To avoid too much smoothing with '{}', suggested max_accel <= {:.0} mm/sec^2",
            f.kind.name(),
            (f.max_accel_mm_s2 / 100.0).round() * 100.0
        ));
    }
    lines.push(format!(
        "Recommended shaper is {} @ {:.1} Hz",
        r.best.kind.name(),
        r.best.freq_hz
    ));
    assert_eq!(lines, KLIPPER_OUTPUT);
}

#[test]
fn the_design_finds_both_modes_and_is_not_worse_than_klipper() {
    let fit = FitSpectrum::from_spectrum(&read_spectrum(&data()).unwrap());
    for o in [Objective::LeastSmoothing, Objective::KlipperScore] {
        let c = design_for_spectrum(&fit, o, VIBRATION_MARGIN);
        assert_eq!(c.peaks_hz.len(), 2, "{:?}", c.peaks_hz);
        assert!((c.peaks_hz[0] - 42.0).abs() < 2.0 && (c.peaks_hz[1] - 98.0).abs() < 2.0);
        let k = metrics(&c.klipper.best.shaper, &fit);
        let (not_worse, better) = verdict(&c.ours.metrics, &k);
        assert!(not_worse, "{} {:?} vs {k:?}", c.ours.name, c.ours.metrics);
        // Two modes: a convolution of one short shaper per mode beats Klipper's single
        // robust shaper on smoothing.
        assert_eq!(c.ours.modes.len(), 2, "{}", c.ours.name);
        assert!(better);
        // The metrics reported are the shaper's.
        assert_eq!(metrics(&c.ours.shaper, &fit), c.ours.metrics);
    }
}

#[test]
fn reading_errors_name_the_problem() {
    let h = "freq,psd_x,psd_y,psd_z,psd_xyz\n";
    let e = parse_spectrum(&format!("{h}1,1,1,1,1\n2,1,1,nan,1\n")).unwrap_err();
    assert!(e.to_string().contains("line 3, column `psd_z`"), "{e}");
    let e = parse_spectrum("#time,accel_x,accel_y,accel_z\n0,1,2,3\n").unwrap_err();
    assert!(e.to_string().contains("not a Klipper spectrum"), "{e}");
    let e = read_spectrum(Path::new("/nonexistent/resonances_x.csv")).unwrap_err();
    assert!(
        format!("{e:#}").contains("cannot read the spectrum file"),
        "{e:#}"
    );
}

fn beamtool(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_beamtool"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

#[test]
fn cli_compares_designs_and_refuses_a_broken_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = data();
    let ok = beamtool(&["klipper-compare", d.to_str().unwrap()], tmp.path());
    let out = String::from_utf8_lossy(&ok.stdout);
    assert!(
        ok.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(out.contains("1 files: not worse 1/1"), "{out}");
    let bad = tmp.path().join("resonances_x_bad.csv");
    std::fs::write(
        &bad,
        "freq,psd_x,psd_y,psd_z,psd_xyz\n1,1,1,1,1\n0.5,1,1,1,1\n2,1,1,1,1\n",
    )
    .unwrap();
    let t = beamtool(
        &[
            "tune",
            bad.to_str().unwrap(),
            "--out",
            tmp.path().join("o").to_str().unwrap(),
        ],
        tmp.path(),
    );
    let err = String::from_utf8_lossy(&t.stderr);
    assert!(!t.status.success());
    assert!(err.contains("does not increase"), "{err}");
}

#[test]
fn tune_on_a_spectrum_designs_plots_reports_and_programs_the_virtual_board() {
    let tmp = tempfile::tempdir().unwrap();
    let d = data();
    // Without --accept-predicted: designed, plotted and reported; the board is not touched,
    // and the run fails saying that nothing can measure a spectrum's shaper.
    let out = tmp.path().join("refused");
    let t = beamtool(
        &["tune", d.to_str().unwrap(), "--out", out.to_str().unwrap()],
        tmp.path(),
    );
    let (so, se) = (
        String::from_utf8_lossy(&t.stdout),
        String::from_utf8_lossy(&t.stderr),
    );
    assert!(!t.status.success(), "{so}{se}");
    assert!(se.contains("nothing can measure"), "{se}");
    assert!(se.contains("--accept-predicted"), "{se}");
    assert!(!so.contains("read the table back"), "{so}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    assert_eq!(j["passed"], false);
    assert!(j["board"].is_null());
    assert!(!out.join("vboard-flash.bin").exists());
    // With it: programmed, read back, saved as predicted-only.
    let out = tmp.path().join("out");
    let t = beamtool(
        &[
            "tune",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--accept-predicted",
        ],
        tmp.path(),
    );
    let so = String::from_utf8_lossy(&t.stdout);
    assert!(
        t.status.success(),
        "{so}{}",
        String::from_utf8_lossy(&t.stderr)
    );
    assert!(
        so.contains("Recommended shaper is 2hump_ei @ 65.4 Hz"),
        "{so}"
    );
    assert!(so.contains("read the table back"), "{so}");
    assert!(std::fs::read_to_string(out.join("spectrum.svg"))
        .unwrap()
        .contains("<svg"));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    assert_eq!(j["klipper"]["shaper"], "2hump_ei");
    assert_eq!(j["not_worse"], true);
    assert_eq!(j["board"]["saved"], true);
    assert_eq!(j["verified"], "predicted only");
    let saved = beamtools::board::load_flash(&out.join("vboard-flash.bin"))
        .unwrap()
        .expect("saved settings");
    assert_eq!(
        saved.certificate.verified,
        beamshaper::config::Verified::PredictedOnly
    );
}
