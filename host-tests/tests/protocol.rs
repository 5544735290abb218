//! The console protocol (`beamshaper::protocol`), one definition for board and host: every
//! command written by `Display` parses back to itself (proptest), and every typed reply the
//! host reads parses from what the console really answers.

use beamshaper::config::{ModeSetting, Source, MAX_CUSTOM_IMPULSES};
use beamshaper::engine::NumericPath;
use beamshaper::protocol::{
    CaptureReply, Command, ConfigReply, DumpReply, ErrorCode, ModeLine, MoveReply, ReplyLine,
    ShaperReply, StatusReply, SweepArgs, SweepReply,
};
use beamshaper::reference::SweepKind;
use beamshaper::shaper::{Impulse, ShaperKind};
use beamshaper_host_tests::Board;
use proptest::prelude::*;

fn last(out: &str) -> &str {
    out.lines().last().unwrap()
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6f64..1e6,
        (-1e3f64..1e3).prop_map(|v| v * 1e-9),
        Just(0.0),
        Just(1.1),
        Just(0.0074),
    ]
}

fn kind() -> impl Strategy<Value = ShaperKind> {
    (0usize..9, 0.001f64..0.499).prop_map(|(k, v_tol)| match k {
        0 => ShaperKind::Zv,
        1 => ShaperKind::Zvd,
        2 => ShaperKind::Zvdd,
        3 => ShaperKind::Zvddd,
        4 => ShaperKind::Mzv,
        5 => ShaperKind::Ei { v_tol },
        6 => ShaperKind::Ei2Hump { v_tol },
        7 => ShaperKind::Ei3Hump { v_tol },
        _ => ShaperKind::UmZv,
    })
}

/// Commands as the parser can produce them (slots 1..4, finite numbers, times ≥ 0, …).
fn command() -> impl Strategy<Value = Command> {
    let mode = (1usize..=4, kind(), finite(), finite()).prop_map(|(slot, kind, f, z)| {
        Command::Mode(
            slot,
            ModeSetting {
                kind,
                freq_hz: f,
                zeta: z,
            },
        )
    });
    let custom = proptest::collection::vec((finite(), 0.0f64..10.0), 0..=MAX_CUSTOM_IMPULSES)
        .prop_map(|v| {
            Command::Custom(
                v.into_iter()
                    .map(|(amplitude, time_s)| Impulse { amplitude, time_s })
                    .collect(),
            )
        });
    let mv =
        (finite(), proptest::option::of(finite()), finite()).prop_map(|(t, s, a)| Command::Move {
            target_mm: t,
            speed_mm_s: s,
            accel_mm_s2: s.map(|_| a),
        });
    let sweep = (any::<bool>(), finite(), finite(), 1e-3f64..1000.0, finite()).prop_map(
        |(exp, f0_hz, f1_hz, amplitude_mm, duration_s)| {
            Command::Sweep(SweepArgs {
                kind: if exp {
                    SweepKind::Exponential
                } else {
                    SweepKind::Linear
                },
                f0_hz,
                f1_hz,
                amplitude_mm,
                duration_s,
            })
        },
    );
    prop_oneof![
        Just(Command::Help),
        Just(Command::Status),
        Just(Command::Shaper),
        Just(Command::Config),
        Just(Command::Stop),
        Just(Command::Zero),
        Just(Command::Save),
        Just(Command::Load),
        Just(Command::Defaults),
        mode,
        proptest::option::of(1usize..=4).prop_map(Command::Clear),
        custom,
        any::<bool>().prop_map(Command::Shaping),
        any::<bool>().prop_map(|f| Command::Path(if f {
            NumericPath::F32
        } else {
            NumericPath::Fixed
        })),
        any::<bool>().prop_map(|s| Command::Source(if s {
            Source::StepDir
        } else {
            Source::Internal
        })),
        any::<u32>().prop_map(Command::Rate),
        any::<u32>().prop_map(Command::Step),
        any::<u32>().prop_map(Command::MaxRate),
        any::<u32>().prop_map(Command::Input),
        finite().prop_map(Command::Speed),
        finite().prop_map(Command::Accel),
        mv,
        sweep,
        (1u32..=10_000).prop_map(Command::Capture),
        (any::<usize>(), 0usize..=32).prop_map(|(first, count)| Command::Dump { first, count }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn every_command_line_parses_back_to_the_same_command(c in command()) {
        let line = c.to_string();
        prop_assert!(!line.contains('\n') && line.len() <= 2000, "{}", line);
        prop_assert_eq!(Command::parse(&line), Ok(c), "{}", line);
    }
}

#[test]
fn status_config_and_shaper_replies_read_back_what_the_board_holds() {
    let mut b = Board::new();
    b.ok("mode 1 ei 1.1 0.0074 0.03");
    b.ok("mode 3 zvd 6.9 0.01");
    b.ok("custom 0.5@0 0.5@0.01");
    b.ok("speed 150.5");
    b.run(3);
    let out = b.ok("config");
    let modes: Vec<ModeLine> = out
        .lines()
        .filter_map(|l| l.strip_prefix("# "))
        .map(|l| ModeLine::parse(l).unwrap())
        .collect();
    let set = b.console.settings().clone();
    assert_eq!(modes.len(), 4);
    for (i, m) in modes.iter().enumerate() {
        assert_eq!((m.slot, m.mode), (i + 1, set.modes[i]));
        assert_eq!(format!("# {m}"), out.lines().nth(i).unwrap());
    }
    let cfg = ConfigReply::parse(last(&out)).unwrap();
    assert_eq!(cfg, ConfigReply::new(&set));
    assert_eq!(cfg.to_string(), last(&out));
    assert_eq!((cfg.speed_mm_s, cfg.custom), (150.5, 2));

    let out = b.ok("status");
    let st = StatusReply::parse(last(&out)).unwrap();
    assert_eq!(st.to_string(), last(&out));
    assert_eq!(st, StatusReply::new(&b.rt.status(), b.console.settings()));

    let out = b.ok("shaper");
    let sh = ShaperReply::parse(last(&out)).unwrap();
    let imps: Vec<Impulse> = ShaperReply::impulses(last(&out))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    let expected = set.shaper().unwrap();
    assert_eq!(imps, expected.impulses());
    assert_eq!(
        (sh.n, sh.duration_s, sh.pending),
        (imps.len(), expected.duration_s(), false)
    );
}

#[test]
fn move_sweep_capture_and_dump_replies_parse() {
    let mut b = Board::new();
    let out = b.ok("capture 2");
    let cap = CaptureReply::parse(last(&out)).unwrap();
    assert_eq!((cap.every_ticks, cap.sample_rate_hz), (2, 500.0));
    let out = b.ok("move 12.5 100 1000");
    let mv = MoveReply::parse(last(&out)).unwrap();
    assert_eq!(mv.target_mm, 12.5);
    assert!(mv.ticks > 100);
    b.run(mv.ticks as usize + 10);
    let st = StatusReply::parse(last(&b.ok("status"))).unwrap();
    assert!(!st.moving && st.setpoint_mm == 12.5, "{st:?}");
    let out = b.ok("dump 3 32");
    let d = DumpReply::parse(last(&out)).unwrap();
    assert_eq!((d.first, d.n), (3, 32));
    assert!(d.total >= 35 && d.armed);
    let v: Vec<i32> = DumpReply::values(last(&out))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(v.len(), 32);
    assert_eq!(v, &b.rt.capture().samples()[3..35]);
    let out = b.ok("sweep exp 0.5 5 2 10");
    let sw = SweepReply::parse(last(&out)).unwrap();
    assert_eq!(sw.args.kind, SweepKind::Exponential);
    assert_eq!(
        (sw.args.f0_hz, sw.args.f1_hz, sw.args.amplitude_mm),
        (0.5, 5.0, 2.0)
    );
    assert_eq!(sw.ticks, 10_000);
}

#[test]
fn reply_lines_are_classified_with_typed_error_codes() {
    let mut b = Board::new();
    let (out, _) = b.cmd("mode 5 zv 1 0.01");
    assert_eq!(
        ReplyLine::parse(last(&out)),
        ReplyLine::Err(Some(ErrorCode::Range), "mode slot must be 1..4")
    );
    let (out, _) = b.cmd("save now");
    assert_eq!(last(&out), "err syntax: save takes no arguments");
    assert_eq!(ReplyLine::parse("# x"), ReplyLine::Info("x"));
    assert_eq!(ReplyLine::parse("ok"), ReplyLine::Ok("ok"));
    assert_eq!(ReplyLine::parse("okay"), ReplyLine::Other("okay"));
    assert_eq!(ReplyLine::parse("err frob: x"), ReplyLine::Err(None, "x"));
    for code in [
        "unknown",
        "syntax",
        "range",
        "shaper",
        "too-long",
        "busy",
        "source",
        "step-rate",
        "budget",
        "garbage",
        "line-too-long",
        "storage",
        "corrupt",
        "version",
    ] {
        assert_eq!(ErrorCode::from_name(code).unwrap().name(), code);
    }
}

#[test]
fn a_command_built_with_an_invalid_slot_is_refused_not_a_panic() {
    let mut b = Board::new();
    let m = ModeSetting {
        kind: ShaperKind::Zv,
        freq_hz: 2.0,
        zeta: 0.01,
    };
    for slot in [0, 5, usize::MAX] {
        b.err(&Command::Mode(slot, m).to_string(), "range");
        b.err(&Command::Clear(Some(slot)).to_string(), "range");
    }
}
