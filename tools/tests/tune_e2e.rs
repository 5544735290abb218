//! The main job end to end over a pseudo-terminal, and its failure modes: a malformed reply
//! and a board that stops answering leave the board's saved configuration unchanged.

use beamtools::board::client::BoardClient;
use beamtools::board::{load_flash, VirtualBoard};
use beamtools::ident::ModeEstimate;
use beamtools::tune::{candidates, program, tune, TuneArgs};
use serialport::SerialPort;
use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::Duration;

/// The defaults of `beamtool tune` (2 % tolerance, 0 -> 50 mm at 200 mm/s, 2000 mm/s²,
/// virtual board) with `recording` and output directory `out`.
fn args(recording: Option<PathBuf>, out: &std::path::Path) -> TuneArgs {
    TuneArgs {
        recording,
        rig: None,
        tolerance_pct: 2.0,
        min_band_pct: 2.0,
        port: None,
        move_mm: 50.0,
        speed_mm_s: 200.0,
        accel_mm_s2: 2000.0,
        out: out.to_path_buf(),
    }
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("beamshaper-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn tune_generates_identifies_programs_and_verifies_on_the_virtual_board() {
    let out = tmpdir("tune");
    tune(args(None, &out)).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    let pv = report["verification"]["percentage_vibration_pct"]
        .as_f64()
        .unwrap();
    assert!(pv < 2.0, "verified percentage vibration {pv} %");
    let f1 = report["modes"][0]["freq_hz"].as_f64().unwrap();
    assert!((f1 / 1.10466 - 1.0).abs() < 0.002, "identified f1 {f1}");
    // The board saved what was programmed.
    let saved = load_flash(&out.join("vboard-flash.bin"))
        .unwrap()
        .expect("saved settings");
    assert!(saved.modes[0].is_some());
    assert!(out.join("verification.svg").exists() && out.join("sensitivity.svg").exists());
}

#[test]
fn tune_runs_on_a_real_aluminium_free_decay() {
    let out = tmpdir("tune-real");
    let rec = PathBuf::from("../../shared/data/real/aluminium-cantilever/50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy");
    if !rec.exists() {
        panic!("real data missing at {}", rec.display());
    }
    tune(args(Some(rec), &out)).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    let f1 = report["modes"][0]["freq_hz"].as_f64().unwrap();
    assert!((5.9..6.2).contains(&f1), "f1 {f1}");
    assert!(
        report["verification"]["percentage_vibration_pct"]
            .as_f64()
            .unwrap()
            < 2.0
    );
}

/// A board on a PTY that behaves like the virtual board for `good_lines` command lines, then
/// either sends `garbage` (a malformed reply) or nothing at all.
fn faulty_board(flash: PathBuf, good_lines: usize, garbage: bool) -> String {
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    let path = slave.name().unwrap();
    std::thread::spawn(move || {
        let _keep = slave;
        let mut boot = String::new();
        let mut b = VirtualBoard::boot(Some(flash), &mut boot);
        master.set_timeout(Duration::from_millis(5)).unwrap();
        let mut lines = 0;
        let mut buf = [0u8; 256];
        loop {
            match master.read(&mut buf) {
                Ok(n) if n > 0 => {
                    lines += buf[..n].iter().filter(|&&c| c == b'\n').count();
                    if lines <= good_lines {
                        let r = b.receive(&buf[..n]);
                        let _ = master.write_all(r.as_bytes());
                    } else if garbage {
                        let _ = master.write_all(b"\x07?? ready\n");
                    }
                }
                _ => b.tick(5),
            }
        }
    });
    path
}

fn modes() -> Vec<ModeEstimate> {
    vec![
        ModeEstimate {
            freq_hz: 1.1,
            zeta: 0.0074,
            freq_hz_std: 0.001,
            zeta_std: 0.0005,
            method: "test".into(),
        },
        ModeEstimate {
            freq_hz: 6.9,
            zeta: 0.0074,
            freq_hz_std: 0.01,
            zeta_std: 0.0005,
            method: "test".into(),
        },
    ]
}

fn saved_flash(dir: &PathBuf) -> (PathBuf, Vec<u8>) {
    // A board whose flash already holds a configuration.
    let flash = dir.join("flash.bin");
    let mut boot = String::new();
    let mut b = VirtualBoard::boot(Some(flash.clone()), &mut boot);
    let r = b.receive(b"mode 1 zv 3.0 0.01\nsave\n");
    assert!(r.contains("ok save"), "{r}");
    let bytes = std::fs::read(&flash).unwrap();
    (flash, bytes)
}

#[test]
fn a_malformed_reply_is_a_clear_error_and_the_saved_configuration_is_unchanged() {
    let dir = tmpdir("malformed");
    let (flash, before) = saved_flash(&dir);
    let port = faulty_board(flash.clone(), 2, true);
    let mut c = BoardClient::open(&port).unwrap();
    c.set_timeout(Duration::from_millis(800));
    let best = &candidates(&modes(), 0.02, 0.02)[0];
    let err = format!("{:#}", program(&mut c, best).unwrap_err());
    assert!(err.contains("malformed reply"), "{err}");
    assert_eq!(std::fs::read(&flash).unwrap(), before);
}

#[test]
fn a_board_that_stops_answering_is_a_clear_error_and_the_saved_configuration_is_unchanged() {
    let dir = tmpdir("silent");
    let (flash, before) = saved_flash(&dir);
    let port = faulty_board(flash.clone(), 3, false);
    let mut c = BoardClient::open(&port).unwrap();
    c.set_timeout(Duration::from_millis(800));
    let best = &candidates(&modes(), 0.02, 0.02)[0];
    let err = format!("{:#}", program(&mut c, best).unwrap_err());
    assert!(err.contains("stopped answering"), "{err}");
    assert_eq!(std::fs::read(&flash).unwrap(), before);
}
