//! The serial console: replies, errors that change nothing, and random lines (proptest).

use beamshaper::config::Settings;
use beamshaper::console::{Action, LineBuffer, LineError, LINE_MAX};
use beamshaper::runtime::TickInput;
use beamshaper::storage::StorageError;
use beamshaper_host_tests::Board;
use proptest::prelude::*;

#[test]
fn set_show_and_move() {
    let mut b = Board::new();
    b.ok("help");
    let out = b.ok("mode 1 zvd 1.1 0.0074");
    assert!(out.contains("taps="));
    b.ok("mode 2 zvd 6.9 0.0074");
    b.run(2);
    let out = b.ok("shaper");
    assert!(out.contains("ok shaper n=9"), "{out}");
    assert!(out.contains("# mode 1 zvd freq_hz=1.1"), "{out}");
    // Read-back of the table is exact (shortest round-trip formatting of f64).
    let line = out.lines().last().unwrap();
    let imps = line.split("impulses=").nth(1).unwrap();
    let sum: f64 = imps
        .split(',')
        .map(|p| p.split('@').next().unwrap().parse::<f64>().unwrap())
        .sum();
    assert!((sum - 1.0).abs() < 1e-12);
    let out = b.ok("move 50 200 2000");
    assert!(out.contains("ticks="), "{out}");
    b.err("move 10", "busy");
    b.run(3000);
    let st = b.ok("status");
    assert!(st.contains("setpoint_mm=50 "), "{st}");
    assert!(st.contains("emitted_steps=50000 "), "{st}");
    b.ok("zero");
    assert!(b.ok("status").contains("reference_mm=0 "));
}

#[test]
fn bad_input_gets_an_error_and_changes_nothing() {
    let mut b = Board::new();
    b.ok("mode 1 zv 2 0.01");
    b.run(5);
    b.err("frobnicate", "unknown");
    b.err("mode", "syntax");
    b.err("mode 5 zv 1 0.01", "range");
    b.err("mode 1 zz 1 0.01", "syntax");
    b.err("mode 1 zv nan 0.01", "range");
    b.err("mode 1 zv 1 NaN", "range");
    b.err("mode 1 zv -1 0.01", "range");
    b.err("mode 1 zv 0 0.01", "range");
    b.err("mode 1 zvd 1 1.0", "range");
    b.err("mode 1 zvd 1 1.5", "range");
    b.err("mode 1 ei 1 0.01 0.7", "range");
    b.err("mode 1 zv 1 0.01 0.05", "syntax");
    b.err("mode 1 zv 1e400 0.01", "range");
    b.err("clear 0", "range");
    b.err("custom 0.5@0 0.4@0.1", "shaper");
    b.err("custom 1@-1", "range");
    b.err("custom 1", "syntax");
    b.err("shaping maybe", "syntax");
    b.err("path f16", "syntax");
    b.err("rate 20000", "range");
    b.err("rate -5", "syntax");
    b.err("step 0", "range");
    b.err("move abc", "syntax");
    b.err("move 5000", "range");
    b.err("move 10 0", "range");
    b.err("save now", "syntax");
    // A shaper longer than the buffer at the tick rate: 0.2 Hz ZVDD lasts 7.5 s; at 10 kHz
    // the 16384-sample buffer holds 1.64 s.
    b.ok("rate 10000");
    b.run(5);
    b.err("mode 1 zvdd 0.2 0.0074", "too-long");
    // The same shaper at 1 kHz is fine.
    b.ok("rate 1000");
    b.run(5);
    b.ok("mode 1 zvdd 0.2 0.0074");
    // Garbage bytes.
    let before = b.console.settings().clone();
    let mut out = String::new();
    b.console
        .handle_line(&[0xff, 0xfe, b'x'], &mut *b.rt, &mut out);
    assert!(out.starts_with("err garbage:"), "{out}");
    assert_eq!(&before, b.console.settings());
}

#[test]
fn moves_refused_on_stepdir_source_and_over_step_rate() {
    let mut b = Board::new();
    b.ok("maxrate 1000");
    b.run(2);
    b.err("move 50 200 2000", "step-rate");
    b.ok("source stepdir");
    b.run(2);
    b.err("move 1", "source");
}

#[test]
fn save_and_load_are_delegated_to_the_glue() {
    let mut b = Board::new();
    b.ok("mode 1 zvd 1.1 0.0074");
    let (_, a) = b.cmd("save");
    assert_eq!(a, Action::Save);
    let mut out = String::new();
    b.console.finish_save::<&str>(Ok(()), &mut out);
    assert_eq!(out, "ok save\n");
    let (_, a) = b.cmd("load");
    assert_eq!(a, Action::Load);
    // A corrupt record leaves the settings unchanged.
    let before = b.console.settings().clone();
    let mut out = String::new();
    b.console
        .finish_load(Err(StorageError::Corrupt), &mut *b.rt, &mut out);
    assert!(
        out.lines().last().unwrap().starts_with("err corrupt:"),
        "{out}"
    );
    assert_eq!(&before, b.console.settings());
    let mut out = String::new();
    b.console
        .finish_load(Ok(Some(Settings::DEFAULT)), &mut *b.rt, &mut out);
    assert!(out.starts_with("ok load"), "{out}");
    assert_eq!(b.console.settings(), &Settings::DEFAULT);
}

/// A stored record refused at boot or by `load` is reported by `status` until a `save`
/// replaces it; an accepted record or none is not mentioned.
#[test]
fn status_reports_a_refused_stored_record_until_save() {
    let mut b = Board::new();
    assert!(!b.ok("status").contains("refused"));
    let mut boot = String::new();
    b.console =
        beamshaper::console::Console::boot(Err(StorageError::Version(1)), &mut *b.rt, 0, &mut boot);
    assert_eq!(b.console.refused_record(), Some(StorageError::Version(1)));
    let st = b.ok("status");
    let first = st.lines().next().unwrap();
    assert!(
        first.starts_with("# stored record refused: stored settings are format version 1"),
        "{st}"
    );
    assert!(st.lines().last().unwrap().starts_with("ok status"), "{st}");
    let mut out = String::new();
    b.console
        .finish_save::<&str>(Err("flash driver error"), &mut out);
    assert!(
        b.ok("status").contains("refused"),
        "a failed save replaces nothing"
    );
    b.console.finish_save::<&str>(Ok(()), &mut out);
    assert!(!b.ok("status").contains("refused"));
    b.console
        .finish_load(Err(StorageError::Corrupt), &mut *b.rt, &mut out);
    assert!(b
        .ok("status")
        .contains("# stored record refused: stored settings corrupt"));
    b.console
        .finish_load(Ok(Some(Settings::DEFAULT)), &mut *b.rt, &mut out);
    assert!(
        !b.ok("status").contains("refused"),
        "the stored record was accepted"
    );
}

#[test]
fn line_buffer_handles_crlf_and_overlong_lines() {
    let mut lb = LineBuffer::new();
    let mut lines = vec![];
    for &c in b"status\r\n\r\nhelp\n" {
        if let Some(l) = lb.push(c) {
            lines.push(l.map(|l| String::from_utf8(l.to_vec()).unwrap()));
        }
    }
    // `\r\n` ends one line; the empty line between is a line (it gets a reply).
    assert_eq!(
        lines,
        vec![
            Ok("status".to_string()),
            Ok(String::new()),
            Ok("help".to_string())
        ]
    );
    for _ in 0..LINE_MAX + 10 {
        assert!(lb.push(b'a').is_none());
    }
    assert_eq!(
        lb.push(b'\n').map(|r| r.map(|_| ())),
        Some(Err(LineError::TooLong))
    );
    // The next line is fine again.
    for &c in b"ok" {
        lb.push(c);
    }
    assert!(matches!(lb.push(b'\n'), Some(Ok(_))));
}

#[test]
fn settings_encode_decode_round_trip_and_detect_corruption() {
    let mut b = Board::new();
    b.ok("mode 1 ei 1.1 0.0074 0.03");
    b.ok("mode 3 umzv 6.9 0.01");
    b.ok("custom 0.5@0 0.5@0.01");
    b.ok("path f32");
    let s = b.console.settings().clone();
    let mut buf = [0u8; beamshaper::config::SETTINGS_MAX_BYTES];
    let n = s.encode(&mut buf).unwrap();
    assert_eq!(Settings::decode(&buf[..n]).unwrap(), s);
    for i in 0..n {
        let mut c = buf;
        c[i] ^= 0x10;
        assert!(
            Settings::decode(&c[..n]).is_err(),
            "flip at byte {i} not detected"
        );
    }
    assert!(Settings::decode(&buf[..n - 1]).is_err());
}

const WORDS: &[&str] = &[
    "help", "status", "shaper", "config", "mode", "clear", "custom", "shaping", "path", "rate",
    "step", "maxrate", "input", "speed", "accel", "source", "move", "zero", "defaults", "save",
    "load", "zv", "zvd", "zvdd", "ei", "umzv", "on", "off", "fixed", "f32", "all", "1", "2", "4",
    "5", "0", "-1", "1.1", "0.0074", "nan", "inf", "1e9", "0.5@0", "1@0.01", "stepdir", "internal",
    "50",
];

fn line_strategy() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..300),
        proptest::collection::vec(proptest::sample::select(WORDS), 0..7)
            .prop_map(|w| w.join(" ").into_bytes()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Random lines: the console never panics, always ends its reply with `ok …` or `err …`,
    /// and on `err` neither the settings nor the runtime change.
    #[test]
    fn random_lines_never_panic_and_err_changes_nothing(lines in proptest::collection::vec(line_strategy(), 1..6)) {
        let mut b = Board::new();
        for line in lines {
            let before = (b.console.settings().clone(), b.rt.pending().cloned(), b.rt.status());
            let mut out = String::new();
            let mut lb = LineBuffer::new();
            let mut bytes = line.clone();
            bytes.push(b'\n');
            for c in bytes {
                if let Some(Ok(l)) = lb.push(c) {
                    b.console.handle_line(&l, &mut *b.rt, &mut out);
                }
            }
            if let Some(last) = out.lines().last() {
                prop_assert!(last.starts_with("ok ") || last.starts_with("err "), "reply {:?}", out);
                if last.starts_with("err ") {
                    let after = (b.console.settings().clone(), b.rt.pending().cloned(), b.rt.status());
                    prop_assert_eq!(before, after);
                }
            }
            b.rt.tick(&TickInput::default());
        }
    }
}

/// The console defects a new user ran into (issue: empty lines, extra arguments, Nyquist,
/// number formatting, validation while shaping is off, still_ticks before the first move).
#[test]
fn every_line_gets_a_reply_and_commands_are_consistent() {
    let mut b = Board::new();
    for line in ["", "   ", "\t"] {
        b.err(line, "syntax");
    }
    // Extra arguments are refused alike by every command that takes none.
    for line in [
        "status extra",
        "zero extra",
        "defaults 1",
        "save extra",
        "load x",
        "help me",
        "config x",
        "shaper x",
        "stop now",
    ] {
        b.err(line, "syntax");
    }
    // A mode at or above the tick's Nyquist frequency.
    b.err("mode 1 zvd 5000 0.01", "range");
    b.err("mode 1 zvd 500 0.01", "range");
    b.ok("mode 1 zvd 499 0.01");
    b.ok("clear 1");
    // An absurd frequency gets a short error, not a 300-digit duration.
    let (out, _) = b.cmd("mode 1 zvd 1e-308 0.01");
    assert!(out.lines().last().unwrap().starts_with("err "), "{out}");
    assert!(out.lines().all(|l| l.len() < 160), "{out}");
    // Modes are validated when accepted, even while shaping is off.
    b.ok("shaping off");
    b.ok("mode 1 zvddd 1.1 0.01");
    b.ok("mode 2 zvddd 6.9 0.01");
    b.err("mode 3 zvddd 17.3 0.01", "shaper");
    b.ok("shaping on");
}

#[test]
fn status_before_the_first_move_and_number_formatting() {
    let mut b = Board::new();
    b.run(3);
    let st = b.ok("status");
    assert!(st.contains("still_ticks=3 "), "{st}");
    assert!(
        st.contains("waiting=none") && st.contains("stages=1"),
        "{st}"
    );
    b.ok("move 68.04");
    b.run(3000);
    let st = b.ok("status");
    assert!(
        st.contains("reference_mm=68.04 ") && st.contains("setpoint_mm=68.04 "),
        "{st}"
    );
    b.ok("speed 123.4");
    let cfg = b.ok("config");
    assert!(cfg.contains("speed_mm_s=123.4 "), "{cfg}");
    // A rate change waits for standstill and says so.
    b.ok("move 0");
    b.run(10);
    let out = b.ok("rate 2000");
    assert!(out.contains("applies=when-still waiting=rate"), "{out}");
    let st = b.ok("status");
    assert!(
        st.contains("waiting=rate") && st.contains("pending=1"),
        "{st}"
    );
    b.run(3000);
    let st = b.ok("status");
    assert!(
        st.contains("tick_hz=2000") && st.contains("waiting=none"),
        "{st}"
    );
}
