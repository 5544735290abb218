//! The console's number reader (`protocol::parse_f64` through `speed <v>`), which the firmware
//! uses instead of core's float parser (13 kB of tables): it must read what std reads, bit for
//! bit, wherever the text is a double's shortest representation (what the host and the board
//! print) or within Clinger's fast path, and within a few ulp otherwise.

use beamshaper::protocol::Command;
use proptest::prelude::*;

fn read(text: &str) -> Option<f64> {
    match Command::parse(&format!("speed {text}")) {
        Ok(Command::Speed(v)) => Some(v),
        _ => None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn shortest_representations_read_back_exactly(bits in 0x0010_0000_0000_0000u64..0x7fef_ffff_ffff_ffff, neg in any::<bool>()) {
        let v = f64::from_bits(bits) * if neg { -1.0 } else { 1.0 };
        for text in [format!("{v:e}"), format!("{v:E}")] {
            prop_assert_eq!(read(&text).map(f64::to_bits), Some(v.to_bits()), "{}", text);
        }
        if v.abs() > 1e-30 && v.abs() < 1e30 {
            let plain = format!("{v}");
            prop_assert_eq!(read(&plain).map(f64::to_bits), Some(v.to_bits()), "{}", plain);
        }
    }

    #[test]
    fn typed_numbers_read_as_std_reads_them(m in 0u64..1_000_000_000_000_000, e in -30i32..30, neg in any::<bool>()) {
        let text = format!("{}{m}e{e}", if neg { "-" } else { "" });
        let want: f64 = text.parse().unwrap();
        let got = read(&text).unwrap();
        let ulp = (want.to_bits() as i64 - got.to_bits() as i64).abs();
        prop_assert!(ulp <= 16, "{} read {} against {}", text, got, want);
        if m < (1 << 53) && e.abs() <= 22 {
            prop_assert_eq!(got.to_bits(), want.to_bits(), "{}", text);
        }
    }
}

#[test]
fn forms_a_user_types() {
    for (text, v) in [
        ("1.1047", 1.1047),
        ("0.001", 0.001),
        (".5", 0.5),
        ("5.", 5.0),
        ("+2e-3", 2e-3),
        ("-0", -0.0),
        ("1E3", 1000.0),
        ("0.0074", 0.0074),
    ] {
        assert_eq!(read(text), Some(v), "{text}");
    }
    // more digits than a double holds: not a shortest representation, read within a few ulp
    let long = read("123456789012345678901234").unwrap();
    let want = 123456789012345678901234.0f64;
    assert!(
        (long.to_bits() as i64 - want.to_bits() as i64).abs() <= 4,
        "{long}"
    );
    for bad in [
        "", "-", ".", "e5", "1e", "1e+", "1..2", "0x10", "1,5", "abc",
    ] {
        assert_eq!(read(bad), None, "{bad:?}");
    }
    for not_finite in ["inf", "-Infinity", "NaN", "1e400"] {
        let refused = Command::parse(&format!("speed {not_finite}")).unwrap_err();
        assert_eq!(refused.code, "range", "{not_finite}");
    }
}
