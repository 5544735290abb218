//! The binary from any directory: the default rig is found, failures exit non-zero with a
//! plain message (no Rust Debug text, no backtrace), negative values are accepted.

use std::process::Command;

/// Runs the binary with `args` from `dir` (a directory outside the checkout).
fn beamtool(dir: &std::path::Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_beamtool"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

#[test]
fn commands_run_from_any_directory_and_fail_with_plain_messages() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let m = beamtool(dir, &["modes"]);
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let rec = std::fs::read_dir("../../shared/data/real/aluminium-cantilever")
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.file_name().unwrap().to_string_lossy().starts_with("50cm"))
        .unwrap();
    let rec = std::fs::canonicalize(rec).unwrap();
    let rec = rec.to_str().unwrap();
    let out = dir.join("out");
    let t = beamtool(
        dir,
        &[
            "tune",
            rec,
            "--move-mm",
            "-50",
            "--port",
            "/dev/does-not-exist",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let err = String::from_utf8_lossy(&t.stderr);
    assert_eq!(t.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("/dev/does-not-exist"),
        "{err}"
    );
    assert!(
        !err.contains("Error {") && !err.contains("backtrace") && !err.contains("Os {"),
        "{err}"
    );
    let n = beamtool(dir, &["tune", "--tolerance-pct", "nan"]);
    assert!(!n.status.success());
    assert!(String::from_utf8_lossy(&n.stderr).contains("not a finite number"));
}
