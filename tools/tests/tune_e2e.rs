//! The main job end to end over pseudo-terminals, and its failure modes. Every check that
//! fails leaves the board's flash as it was and its running configuration as it was found.

use beamtools::board::client::BoardClient;
use beamtools::board::rig::{RigSensors, VirtualRig};
use beamtools::board::{load_flash, spawn_on_pty_with_rig, VirtualBoard};
use beamtools::cli::tune::{tune, TuneArgs};
use beamtools::model::Rig;
use beamtools::tune::DEFAULT_RIG_TOML;
use clap::Parser;
use serialport::SerialPort;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

const REAL: &str = "../../shared/data/real/aluminium-cantilever";

fn real(prefix: &str) -> PathBuf {
    let dir =
        std::fs::read_dir(REAL).unwrap_or_else(|e| panic!("real data missing at {REAL}: {e}"));
    dir.filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
        .unwrap()
}

/// A fresh directory, removed when the returned guard is dropped (also when the test fails).
fn tmpdir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("beamshaper-test-{name}-"))
        .tempdir()
        .unwrap()
}

fn json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap()
}

/// The board's `config` reply lines (modes and settings), to compare running configurations.
fn config_lines(port: &str) -> Vec<String> {
    let mut c = BoardClient::open(port).unwrap();
    let r = c.command("config").unwrap();
    let mut v = r.info.clone();
    v.push(r.ok);
    v
}

/// A virtual board with a flash that holds `mode 1 zv 3.0 0.01` and runs, unsaved,
/// `mode 1 zvd 2.5 0.02`; with the reference rig attached when `camera` is given.
fn board_with_unsaved_change(dir: &Path, camera: Option<&Path>) -> (String, PathBuf, Vec<u8>) {
    let flash = dir.join("flash.bin");
    let mut boot = String::new();
    let mut b = VirtualBoard::boot(Some(flash.clone()), &mut boot);
    assert!(b.receive(b"mode 1 zv 3.0 0.01\nsave\n").contains("ok save"));
    let bytes = std::fs::read(&flash).unwrap();
    let rig = camera.map(|log| {
        let rig = Rig::from_toml_str(DEFAULT_RIG_TOML).unwrap();
        VirtualRig::new(&rig, RigSensors::camera(&rig), 1000.0, log).unwrap()
    });
    let port = spawn_on_pty_with_rig(Some(flash.clone()), 200.0, rig).unwrap();
    let mut c = BoardClient::open(&port).unwrap();
    c.command("mode 1 zvd 2.5 0.02").unwrap();
    (port, flash, bytes)
}

/// The paper's exponential sweep (eq. 34) of model `m`, simulated at 100 Hz without noise.
fn paper_sweep(m: &beamtools::model::BeamModel) -> beamtools::recording::Recording {
    use beamtools::ident::protocol::simulate_sweep;
    use beamtools::ident::sweep::{SweepKind, SweepSpec};
    simulate_sweep(
        m,
        &SweepSpec::paper(SweepKind::Exponential, 3.0),
        100.0,
        0.0,
        1,
    )
    .unwrap()
}

#[test]
fn default_run_sweeps_on_the_board_identifies_from_the_camera_and_saves_after_the_measured_check() {
    let tmp = tmpdir("tune");
    let out = tmp.path().to_path_buf();
    let outcome = tune(TuneArgs::new(None, &out)).unwrap();
    assert!(outcome.passed);
    let r = json(&out);
    assert_eq!(r["passed"], true);
    let measured = r["verification"]["measured_vibration_pct"]
        .as_f64()
        .unwrap();
    assert!(measured < 2.0, "measured percentage vibration {measured} %");
    let f1 = r["modes"][0]["freq_hz"].as_f64().unwrap();
    let f2 = r["modes"][1]["freq_hz"].as_f64().unwrap();
    assert!((f1 / 1.10466 - 1.0).abs() < 0.002, "identified f1 {f1}");
    assert!((f2 / 6.9228 - 1.0).abs() < 0.002, "identified f2 {f2}");
    for k in 0..2 {
        let z = r["modes"][k]["zeta"].as_f64().unwrap();
        assert!(
            (z / 0.0074 - 1.0).abs() < 0.10,
            "identified zeta{} {z}",
            k + 1
        );
    }
    assert!(r["impulses"].as_array().unwrap().len() >= 2);
    assert!(r["port"].as_str().unwrap().starts_with("/dev/"));
    assert!(r["units"]["freq_hz"].is_string());
    let saved = load_flash(&out.join("vboard-flash.bin"))
        .unwrap()
        .expect("saved settings");
    assert!(saved.modes[0].is_some());
    // The board keeps how the shaper was checked and the band it was certified over.
    assert_eq!(
        saved.certificate.verified,
        beamshaper::config::Verified::Measured
    );
    let (lo, hi) = saved.certificate.band_hz[0].expect("mode 1's certified band");
    assert!(
        lo < f1 as f32 && (f1 as f32) < hi,
        "band {lo}..{hi} around {f1}"
    );
    assert_eq!(r["verified"], "measured");
    for f in [
        "verification.svg",
        "sensitivity.svg",
        "sweep-recording.csv",
        "vboard-camera.csv",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
}

/// Repro: `tune <40 cm decay>.npy --rig rigs/paper.toml` simulated 97.9 % and saved. Now the
/// camera of the rig measures it, the run fails, nothing is saved and the board runs the
/// configuration it ran before (an unsaved one, so `load` would not have been right).
#[test]
fn a_failed_verification_exits_with_an_error_saves_nothing_and_restores_the_running_configuration()
{
    let tmp = tmpdir("fail");
    let dir = tmp.path().to_path_buf();
    let camera = dir.join("camera.csv");
    let (port, flash, saved_before) = board_with_unsaved_change(&dir, Some(&camera));
    let running_before = config_lines(&port);
    let mut a = TuneArgs::new(Some(real("40cm")), &dir.join("out"));
    a.rig = Some(PathBuf::from("../rigs/paper.toml"));
    a.port = Some(port.clone());
    a.camera_log = Some(camera);
    let err = format!("{:#}", tune(a).err().expect("must fail"));
    assert!(err.contains("verification failed"), "{err}");
    assert!(err.contains("previous configuration"), "{err}");
    assert_eq!(
        std::fs::read(&flash).unwrap(),
        saved_before,
        "flash changed"
    );
    assert_eq!(
        config_lines(&port),
        running_before,
        "running configuration not restored"
    );
    let r = json(&dir.join("out"));
    assert_eq!(r["passed"], false);
    assert!(
        r["verification"]["measured_vibration_pct"]
            .as_f64()
            .unwrap()
            > 50.0
    );
}

#[test]
fn the_real_aluminium_decays_pass_the_model_free_check() {
    for (len, f_lo, f_hi) in [("40cm", 9.3, 9.5), ("50cm", 5.9, 6.2), ("60cm", 4.1, 4.4)] {
        let tmp = tmpdir(&format!("real-{len}"));
        let out = tmp.path().to_path_buf();
        tune(TuneArgs::new(Some(real(len)), &out)).unwrap();
        let r = json(&out);
        let f1 = r["modes"][0]["freq_hz"].as_f64().unwrap();
        assert!((f_lo..f_hi).contains(&f1), "{len}: f1 {f1}");
        let v = r["verification"]["superposed_vibration_pct"]
            .as_f64()
            .unwrap();
        assert!(v < 2.0, "{len}: {v} %");
    }
}

#[test]
fn an_unreachable_board_is_a_clear_error_and_arguments_are_checked_first() {
    let tmp = tmpdir("unreachable");
    let out = tmp.path().to_path_buf();
    let mut a = TuneArgs::new(Some(real("50cm")), &out);
    a.port = Some("/dev/does-not-exist".into());
    let err = format!("{:#}", tune(a.clone()).err().unwrap());
    assert!(err.contains("/dev/does-not-exist"), "{err}");
    // A bad argument is refused before the port is even opened.
    a.move_mm = 2000.0;
    let err = format!("{:#}", tune(a.clone()).err().unwrap());
    assert!(err.contains("--move-mm"), "{err}");
    a.move_mm = 50.0;
    a.rig = Some(out.join("missing.toml"));
    let err = format!("{:#}", tune(a).err().unwrap());
    assert!(err.contains("missing.toml"), "{err}");
}

/// A PTY nobody answers on, or one that answers like the board for `good_lines` lines and
/// then sends garbage.
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

#[test]
fn a_silent_board_is_a_clear_error_and_nothing_moves() {
    let tmp = tmpdir("silent");
    let dir = tmp.path().to_path_buf();
    let port = faulty_board(dir.join("flash.bin"), 0, false);
    let mut a = TuneArgs::new(Some(real("50cm")), &dir);
    a.port = Some(port);
    let err = format!("{:#}", tune(a).err().unwrap());
    assert!(err.contains("stopped answering"), "{err}");
}

#[test]
fn a_malformed_reply_while_programming_is_a_clear_error_and_the_flash_is_unchanged() {
    let tmp = tmpdir("malformed");
    let dir = tmp.path().to_path_buf();
    let flash = dir.join("flash.bin");
    let mut boot = String::new();
    let mut b = VirtualBoard::boot(Some(flash.clone()), &mut boot);
    assert!(b.receive(b"mode 1 zv 3.0 0.01\nsave\n").contains("ok save"));
    let before = std::fs::read(&flash).unwrap();
    // config + status + shaper… are answered, then garbage from the programming on.
    let port = faulty_board(flash.clone(), 4, true);
    let mut a = TuneArgs::new(Some(real("50cm")), &dir.join("out"));
    a.port = Some(port);
    let err = format!("{:#}", tune(a).err().unwrap());
    assert!(err.contains("malformed reply"), "{err}");
    assert!(
        err.contains("COULD NOT RESTORE") || err.contains("previous configuration"),
        "{err}"
    );
    assert_eq!(std::fs::read(&flash).unwrap(), before);
}

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    a: TuneArgs,
}

/// Repro: `--move-mm -50` failed ("unexpected argument '-5'"), `--tolerance-pct nan` was
/// accepted; `--move-mm 0`, `--speed-mm-s 0` and a tolerance below what can be verified
/// are refused before any board is touched.
#[test]
fn options_accept_negative_numbers_refuse_non_finite_and_impossible_values() {
    let p =
        |args: &[&str]| Cli::try_parse_from(std::iter::once("tune").chain(args.iter().copied()));
    assert_eq!(p(&["--move-mm", "-50"]).unwrap().a.move_mm, -50.0);
    assert!(p(&["--tolerance-pct", "nan"]).is_err());
    assert!(p(&["--speed-mm-s", "inf"]).is_err());
    let tmp = tmpdir("opts");
    let out = tmp.path().to_path_buf();
    for bad in [
        ["--move-mm", "0"],
        ["--speed-mm-s", "0"],
        ["--accel-mm-s2", "-3"],
        ["--tolerance-pct", "0.01"],
    ] {
        let mut a = p(&bad).unwrap().a;
        a.out = out.clone();
        a.port = Some("/dev/does-not-exist".into());
        let err = format!("{:#}", tune(a).err().unwrap());
        assert!(err.contains(bad[0]), "{bad:?}: {err}");
    }
}

/// Issue 11 acceptance: `tune` on the paper's exponential sweep (eq. 34, noise-free: with 1 % sensor
/// noise its ring-down tail no longer resolves the tolerance and `tune` refuses to claim a
/// check, see the closing note) and on a 20 mm move + 40 s ring-down whose servo-held base dithers by ±2 µm on a 1 µm
/// encoder: both succeed, f1 and f2 within 0.2 % of the model's clamped modes and ζ within
/// 10 %, checked on the user's recorded vibration (no rig, no camera).
#[test]
fn tune_succeeds_on_a_sweep_and_on_a_dithering_move_with_ring_down() {
    use beamtools::ident::protocol::{add_noise, truth};
    use beamtools::model::sim::BaseMotionSim;
    use beamtools::model::{trapezoid_reference, BeamModel, ModelOptions};
    use rand::{Rng, SeedableRng};
    let rig = Rig::from_toml_str(DEFAULT_RIG_TOML).unwrap();
    let m = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
    let tr = truth(&m).unwrap().clamped;
    let tmp = tmpdir("tune-user-recordings");
    let dir = tmp.path().to_path_buf();
    let sweep = paper_sweep(&m);
    sweep.write_csv(dir.join("sweep.csv")).unwrap();
    let sim = BaseMotionSim::new(&m, 1e-3).unwrap();
    let (y, _) = trapezoid_reference(0.0, 0.02, 0.2, 2.0, 1000.0, 40.0).unwrap();
    let mut mv = beamtools::recording::decimate(&sim.recording(&y, 0.0), 100.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for v in mv.base_pos_m.as_mut().unwrap().iter_mut() {
        *v = ((*v + rng.gen_range(-2e-6..=2e-6)) * 1e6).round() * 1e-6;
    }
    add_noise(&mut mv, 0.0, 2);
    for v in mv.tip_pos_m.as_mut().unwrap().iter_mut() {
        *v += rng.gen_range(-20e-6..20e-6);
    }
    mv.write_csv(dir.join("move-dither.csv")).unwrap();
    for name in ["sweep.csv", "move-dither.csv"] {
        let out = dir.join(format!("out-{name}"));
        tune(TuneArgs::new(Some(dir.join(name)), &out)).unwrap_or_else(|e| panic!("{name}: {e:#}"));
        let r = json(&out);
        assert_eq!(r["passed"], serde_json::Value::Bool(true), "{name}");
        for (k, (f, z)) in tr.iter().take(2).enumerate() {
            let fi = r["modes"][k]["freq_hz"].as_f64().unwrap();
            let zi = r["modes"][k]["zeta"].as_f64().unwrap();
            assert!(
                (fi / f - 1.0).abs() < 0.002,
                "{name} mode {}: f {fi} vs {f}",
                k + 1
            );
            assert!(
                (zi / z - 1.0).abs() < 0.10,
                "{name} mode {}: ζ {zi} vs {z}",
                k + 1
            );
        }
    }
}

/// A recording with no free vibration in it (a sweep cut while the base still moves), on a
/// board without a sensor: nothing can measure the shaper. `tune` says exactly that (not
/// "exceeds the tolerance"), saves nothing and exits with an error; with `--accept-predicted`
/// it saves, and `tune.json` and the board's stored certificate say "predicted only".
#[test]
fn a_shaper_nothing_can_measure_is_refused_or_saved_as_predicted_only() {
    use beamtools::model::{BeamModel, ModelOptions};
    let rig = Rig::from_toml_str(DEFAULT_RIG_TOML).unwrap();
    let m = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
    let sweep = paper_sweep(&m);
    // Cut where the base is moving fastest in the last third: no ring-down follows.
    let b = sweep.base_pos_m.clone().unwrap();
    let n = b.len();
    let cut = (2 * n / 3..n - 1)
        .max_by(|&i, &j| (b[i + 1] - b[i]).abs().total_cmp(&(b[j + 1] - b[j]).abs()))
        .unwrap();
    let rec = sweep.slice(0..cut + 1);
    let tmp = tmpdir("tune-unmeasured");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("sweep-cut.csv");
    rec.write_csv(&path).unwrap();

    let out = dir.join("refused");
    let err = tune(TuneArgs::new(Some(path.clone()), &out)).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("nothing could measure the shaper"), "{msg}");
    assert!(msg.contains("--accept-predicted"), "{msg}");
    assert!(!msg.contains("exceeds"), "{msg}");
    let r = json(&out);
    assert_eq!(r["passed"], false);
    assert!(r["verified"].is_null());
    assert_eq!(
        load_flash(&out.join("vboard-flash.bin")).unwrap(),
        None,
        "nothing saved"
    );

    let out = dir.join("accepted");
    let mut args = TuneArgs::new(Some(path), &out);
    args.accept_predicted = true;
    let report = tune(args).unwrap();
    assert!(report.passed);
    let r = json(&out);
    assert_eq!(r["verified"], "predicted only");
    assert!(r["verification"]["measured_vibration_pct"].is_null());
    assert!(r["verification"]["superposed_vibration_pct"].is_null());
    let saved = load_flash(&out.join("vboard-flash.bin"))
        .unwrap()
        .expect("saved settings");
    assert_eq!(
        saved.certificate.verified,
        beamshaper::config::Verified::PredictedOnly
    );
    assert!(saved.certificate.band_hz[0].is_some());
}
