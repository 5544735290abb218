//! What loggers write, read (docs/recording-formats.md): the example files of
//! `tests/data/formats/` (written by its `make_examples.py`) read through the library and the
//! command line, with their values checked against the file's text, and the errors of a bad
//! `--columns`.

use beamtools::recording::{Axis, ColumnMap, ReadOptions, Recording};
use std::path::{Path, PathBuf};
use std::process::Command;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/formats")
        .join(name)
}

/// The file's data rows as cells (comment lines and the header skipped).
fn rows(name: &str) -> Vec<Vec<String>> {
    std::fs::read_to_string(data(name))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(usize::from(!name.starts_with("klipper")))
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

fn num(s: &str) -> f64 {
    s.parse().unwrap()
}

fn columns(spec: &str) -> ReadOptions {
    ReadOptions {
        columns: Some(ColumnMap::parse(spec).unwrap()),
        axis: None,
    }
}

#[test]
fn klipper_raw_accelerometer_csv_reads_its_liveliest_axis_in_m_s2() {
    let cells = rows("klipper_raw.csv");
    // as recorded (time base not mended): the exact values of the file's accel_y, in m/s²
    let raw = Recording::read_csv_gapped(&data("klipper_raw.csv"), &mut |_| {}).unwrap();
    assert_eq!(raw.len(), cells.len());
    let acc = raw.tip_acc_m_s2.as_ref().unwrap();
    for (k, c) in cells.iter().enumerate() {
        assert_eq!(raw.time_s[k], num(&c[0]));
        assert!((acc[k] - num(&c[2]) * 1e-3).abs() < 1e-12, "row {k}");
    }
    assert!(raw.tip_pos_m.is_none() && raw.base_pos_m.is_none());
    assert!(
        raw.notes
            .iter()
            .any(|n| n.contains("axis y read as tip_acc_m_s2") && n.contains("most energy")),
        "{:?}",
        raw.notes
    );
    // the ADXL345's 3.9 mg step is found
    let q = raw.quantum("tip_acc_m_s2").unwrap();
    assert!((q - 0.0039 * 9.80665).abs() < 1e-6, "{q}");
    // read for identification: onto a uniform grid at the chip's rate, with a note
    let rec = Recording::read_any(&data("klipper_raw.csv"), &mut |_| {}).unwrap();
    assert!(rec.is_uniform());
    assert!(
        (rec.sample_rate_hz() - 3200.0).abs() < 5.0,
        "{}",
        rec.sample_rate_hz()
    );
    assert!(
        rec.notes.iter().any(|n| n.contains("time base mended")),
        "{:?}",
        rec.notes
    );
    // --axis z: gravity's mean is in it
    let z = Recording::read_any_with(
        &data("klipper_raw.csv"),
        &ReadOptions {
            axis: Some(Axis::Z),
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let zacc = z.tip_acc_m_s2.unwrap();
    let mean = zacc.iter().sum::<f64>() / zacc.len() as f64;
    assert!((mean - 9.80665).abs() < 0.1, "{mean}");
}

#[test]
fn a_row_wise_ros_export_is_forward_filled_and_its_slow_topic_is_a_staircase() {
    let opts = columns(
        "time_s=%time:1e-9,base_pos_m=field.trolley_mm:0.001,tip_pos_m=field.sway_rad:0.45",
    );
    let rec = Recording::read_any_with(&data("rowwise_ros.csv"), &opts, &mut |_| {}).unwrap();
    assert!(
        rec.notes.iter().any(|n| n.starts_with("row-wise log")),
        "{:?}",
        rec.notes
    );
    // every output row holds each topic's last message at or before it
    let cells = rows("rowwise_ros.csv");
    let last_at = |col: usize, t: f64| {
        cells
            .iter()
            .filter(|c| !c[col].is_empty() && num(&c[0]) * 1e-9 <= t + 1e-9)
            .last()
            .map(|c| num(&c[col]))
            .unwrap()
    };
    let (base, tip) = (
        rec.base_pos_m.as_ref().unwrap(),
        rec.tip_pos_m.as_ref().unwrap(),
    );
    for (k, &t) in rec.time_s.iter().enumerate() {
        assert!((base[k] - last_at(1, t) * 1e-3).abs() < 1e-12, "row {k}");
        assert!((tip[k] - last_at(2, t) * 0.45).abs() < 1e-12, "row {k}");
    }
    // the first row is where both topics have spoken
    assert!(rec.len() < cells.len());
    // the angle topic's rate (22 Hz) is found from its changes; the trolley's is the log's
    let rate = rec.update_rate_hz("tip_pos_m").unwrap();
    assert!((rate - 22.0).abs() < 1.0, "{rate}");
    assert_eq!(rec.update_rate_hz("base_pos_m"), None);
    let q = rec.quantum("tip_pos_m").unwrap();
    assert!((q - 0.45e-3).abs() < 1e-9, "{q}");
}

#[test]
fn a_sample_and_hold_staircase_is_recognised_with_its_update_rate() {
    let rec = Recording::read_csv_gapped(&data("staircase.csv"), &mut |_| {}).unwrap();
    let s = rec.staircase("tip_pos_m").unwrap();
    assert!((s.update_rate_hz - 22.0).abs() < 1.0, "{s:?}");
    assert!((s.row_rate_hz - 100.0).abs() < 0.5, "{s:?}");
    assert!(rec.staircase("base_pos_m").is_none());
    assert!(
        rec.notes
            .iter()
            .any(|n| n.starts_with("tip_pos_m is a staircase") && n.contains("~22")),
        "{:?}",
        rec.notes
    );
}

#[test]
fn mapped_columns_are_scaled_to_si_and_unmapped_ones_ignored() {
    let opts = columns("time_s=t:0.001,base_pos_m=theta:0.45,tip_pos_m=defl:0.001");
    let rec = Recording::read_csv_with(data("scaled_columns.csv"), &opts).unwrap();
    let cells = rows("scaled_columns.csv");
    assert_eq!(rec.len(), cells.len());
    for (k, c) in cells.iter().enumerate() {
        assert!((rec.time_s[k] - num(&c[0]) * 1e-3).abs() < 1e-12);
        assert!((rec.base_pos_m.as_ref().unwrap()[k] - num(&c[1]) * 0.45).abs() < 1e-12);
        assert!((rec.tip_pos_m.as_ref().unwrap()[k] - num(&c[2]) * 1e-3).abs() < 1e-12);
    }
    assert!(
        rec.notes
            .iter()
            .any(|n| n.contains("1 unmapped columns ignored (status)")),
        "{:?}",
        rec.notes
    );
    // a 1 mm-quantised swing at the full rate: a quantum, not a staircase
    let q = rec.quantum("tip_pos_m").unwrap();
    assert!((q - 1e-3).abs() < 1e-12, "{q}");
    assert_eq!(rec.update_rate_hz("tip_pos_m"), None);
    // without the map, the unit-less time column is refused with the hint
    let e = Recording::read_csv(data("scaled_columns.csv"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("`t` has no unit") && e.contains("--columns"),
        "{e}"
    );
}

fn beamtool(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_beamtool"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_bad_columns_map_is_refused_by_name_on_the_command_line() {
    let file = data("scaled_columns.csv");
    let f = file.to_str().unwrap();
    for (cols, want) in [
        (
            "tip=defl",
            "unknown channel `tip` (channels: time_s, base_cmd_m",
        ),
        ("tip_pos_m=defl:mm", "bad scale `mm`"),
        (
            "tip_pos_m=defl,tip_pos_m=theta",
            "channel `tip_pos_m` given twice",
        ),
        (
            "time_s=t:0.001,tip_pos_m=deflection",
            "no column `deflection` (for tip_pos_m); its columns: t, theta, defl, status",
        ),
    ] {
        for cmd in ["identify", "frf"] {
            let (ok, err) = beamtool(&[cmd, f, "--columns", cols]);
            assert!(!ok, "{cmd} --columns {cols}");
            assert!(err.contains(want), "{cmd} --columns {cols}: {err}");
        }
    }
    let (ok, err) = beamtool(&["identify", f, "--axis", "x"]);
    assert!(!ok);
    assert!(
        err.contains("--axis applies to Klipper's raw accelerometer CSV"),
        "{err}"
    );
    let (ok, err) = beamtool(&["identify", f, "--axis", "w"]);
    assert!(!ok);
    assert!(err.contains("want x, y or z"), "{err}");
}

/// A recording of the truth generator in the project's names, and the same recording as a
/// logger might write it (time in ms, positions in mm, its own column names, another order).
fn truth_recording_and_its_foreign_twin(dir: &Path) -> (PathBuf, PathBuf) {
    let out = dir.to_str().unwrap();
    let (ok, err) = beamtool(&["truth", "--out", out, "--duration-s", "20", "--n-fit", "1"]);
    assert!(ok, "{err}");
    let ours = dir.join("fit1.csv");
    let text = std::fs::read_to_string(&ours).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "time_s,base_cmd_m,base_pos_m,tip_pos_m,force_n"
    );
    let mut foreign = String::from("F,tip mm,t,pos,cmd\n");
    for l in lines {
        let c: Vec<f64> = l.split(',').map(num).collect();
        let row = [c[4], c[3] * 1e3, c[0] * 1e3, c[2] * 1e3, c[1] * 1e3];
        let cells: Vec<String> = row.iter().map(|v| format!("{v:e}")).collect();
        foreign.push_str(&cells.join(","));
        foreign.push('\n');
    }
    let theirs = dir.join("logger.csv");
    std::fs::write(&theirs, foreign).unwrap();
    (ours, theirs)
}

#[test]
fn the_diagnosis_reads_a_loggers_columns_as_the_project_names_them() {
    use beamtools::diagnose::load::{load, load_with};
    let dir = std::env::temp_dir().join(format!("beamtool-diag-columns-{}", std::process::id()));
    let (ours, theirs) = truth_recording_and_its_foreign_twin(&dir);
    let rig = beamtools::model::Rig::from_toml_file(dir.join("rig.toml")).unwrap();
    let a = load(&ours, &rig).unwrap().prepared;
    let map =
        "time_s=t:0.001,base_cmd_m=cmd:0.001,base_pos_m=pos:0.001,tip_pos_m=tip mm:0.001,force_n=F";
    let b = load_with(&theirs, &rig, &columns(map)).unwrap().prepared;
    let close = |x: &[f64], y: &[f64], what: &str| {
        assert_eq!(x.len(), y.len(), "{what}");
        let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        let worst = x
            .iter()
            .zip(y)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(
            worst <= 1e-9 * scale,
            "{what}: differs by {worst:e} of {scale:e}"
        );
    };
    assert!((a.dt - b.dt).abs() <= 1e-12 * a.dt);
    close(&a.time_s, &b.time_s, "time_s");
    close(&a.cmd_m, &b.cmd_m, "base_cmd_m");
    close(
        a.base_m.as_ref().unwrap(),
        b.base_m.as_ref().unwrap(),
        "base_pos_m",
    );
    close(
        a.tip_m.as_ref().unwrap(),
        b.tip_m.as_ref().unwrap(),
        "tip_pos_m",
    );
    close(
        a.force_n.as_ref().unwrap(),
        b.force_n.as_ref().unwrap(),
        "force_n",
    );
    // Without the map the logger's file is refused by name, not misread.
    let e = format!("{:#}", load(&theirs, &rig).err().expect("refused"));
    assert!(e.contains("time"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
