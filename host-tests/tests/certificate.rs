//! The shaper's certificate (settings format version 3): `certify` records how `tune` checked
//! the installed shaper and the band it certified per mode slot; `status` and `config` show
//! it; a new shaper voids it; it persists; and a record of format version 2, written by the
//! previous firmware, is migrated with the user's shaper intact (verification `unknown`).

use beamshaper::config::{
    Certificate, ModeSetting, Settings, Source, Verified, SETTINGS_MAX_BYTES, SETTINGS_VERSION,
};
use beamshaper::console::Console;
use beamshaper::engine::NumericPath;
use beamshaper::protocol::{Command, ConfigReply, StatusReply};
use beamshaper::runtime::Runtime;
use beamshaper::shaper::{Impulse, ShaperKind};
use beamshaper::storage::{load_settings, SETTINGS_KEY, STORAGE_BUFFER_BYTES};
use beamshaper_host_tests::Board;
use futures::executor::block_on;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};

type Flash = MockFlashBase<4, 8, 256>;
const RANGE: core::ops::Range<u32> = Flash::FULL_FLASH_RANGE;

/// The record the format-2 firmware (commit 873f980) saved for [`tuned`], byte for byte
/// (printed by that firmware's `Settings::encode`).
const V2_RECORD_HEX: &str = "4253480201029a9999999999f13facadd85f764f7e3f000105b81e85eb51b89e3f9a99999999991b407b14ae47e17a843f0002000000000000e03f0000000000000000000000000000e03f7b14ae47e17a843f0101d00fe807c09a0ce807010080164300007a440000c8426f70482e";

fn v2_record() -> Vec<u8> {
    (0..V2_RECORD_HEX.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&V2_RECORD_HEX[i..i + 2], 16).unwrap())
        .collect()
}

/// The settings of that record.
fn tuned() -> Settings {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 1.1,
        zeta: 0.0074,
    });
    s.modes[2] = Some(ModeSetting {
        kind: ShaperKind::Ei { v_tol: 0.03 },
        freq_hz: 6.9,
        zeta: 0.01,
    });
    s.custom
        .extend_from_slice(&[
            Impulse {
                amplitude: 0.5,
                time_s: 0.0,
            },
            Impulse {
                amplitude: 0.5,
                time_s: 0.01,
            },
        ])
        .unwrap();
    s.path = NumericPath::F32;
    s.source = Source::StepDir;
    s.tick_rate_hz = 2000;
    s.move_speed_mm_s = 150.5;
    s
}

fn store_raw(flash: &mut Flash, bytes: &[u8]) {
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    let mut map = MapStorage::<u8, _, _>::new(flash, MapConfig::new(RANGE), Cache::new_uncached());
    block_on(map.store_item(&mut buf, &SETTINGS_KEY, &bytes)).unwrap();
}

fn last(out: &str) -> &str {
    out.lines().last().unwrap_or("")
}

#[test]
fn a_record_of_the_previous_firmware_is_migrated_with_the_shaper_intact() {
    assert_eq!(SETTINGS_VERSION, 3);
    let v2 = v2_record();
    assert_eq!(v2[3], 2, "the fixture is a format-2 record");
    let s = Settings::decode(&v2).expect("a format-2 record is read");
    assert_eq!(s, tuned());
    assert_eq!(s.certificate, Certificate::NONE);
    // Through the flash layer and the boot path, as a firmware update meets it.
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &v2);
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    let loaded = block_on(load_settings(&mut flash, RANGE, &mut buf));
    assert_eq!(loaded, Ok(Some(tuned())));
    let mut rt = Box::new(Runtime::new());
    let mut out = String::new();
    let console = Console::boot(loaded, &mut *rt, 0, &mut out);
    assert!(out.contains("# boot: settings loaded from flash"), "{out}");
    assert_eq!(console.settings(), &tuned());
    // Saved again, it is written in the current format.
    let mut rec = [0u8; SETTINGS_MAX_BYTES];
    let n = console.settings().encode(&mut rec).unwrap();
    assert_eq!(rec[3], SETTINGS_VERSION);
    assert_eq!(Settings::decode(&rec[..n]), Ok(tuned()));
    // A format-2 record with a flipped bit is still corrupt, not migrated.
    let mut bad = v2.clone();
    bad[12] ^= 1;
    assert!(Settings::decode(&bad).is_err());
}

#[test]
fn certify_shows_on_status_and_config_and_persists() {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("mode 2 zv 6.9 0.0074");
    let st = StatusReply::parse(last(&b.ok("status"))).unwrap();
    assert_eq!(st.verified, Verified::Unknown);
    b.ok("certify predicted 1.078 1.122 6.76 7.04");
    let out = b.ok("status");
    assert!(last(&out).ends_with(" verified=predicted-only"), "{out}");
    assert_eq!(
        StatusReply::parse(last(&out)).unwrap().verified,
        Verified::PredictedOnly
    );
    let cfg = ConfigReply::parse(last(&b.ok("config"))).unwrap();
    assert_eq!(cfg.certificate.verified, Verified::PredictedOnly);
    assert_eq!(
        cfg.certificate.band_hz,
        [Some((1.078, 1.122)), Some((6.76, 7.04)), None, None]
    );
    // The record keeps it.
    let mut rec = [0u8; SETTINGS_MAX_BYTES];
    let n = b.console.settings().encode(&mut rec).unwrap();
    let back = Settings::decode(&rec[..n]).unwrap();
    assert_eq!(back.certificate, b.console.settings().certificate);
    // `measured` replaces it; the command line round-trips through the host's writer.
    let c = Command::parse("certify measured 1.078 1.122").unwrap();
    assert_eq!(c.to_string(), "certify measured 1.078 1.122");
    b.ok(&c.to_string());
    assert!(last(&b.ok("status")).ends_with(" verified=measured"));
}

#[test]
fn a_new_shaper_voids_the_certificate() {
    for change in ["mode 1 zvd 1.2 0.0074", "clear 2", "clear all", "custom 0.5@0 0.5@0.01"] {
        let mut b = Board::new();
        b.ok("mode 1 zv 1.1 0.0074");
        b.ok("mode 2 zv 6.9 0.0074");
        b.ok("certify measured 1.07 1.13 6.7 7.1");
        b.ok(change);
        let st = StatusReply::parse(last(&b.ok("status"))).unwrap();
        assert_eq!(st.verified, Verified::Unknown, "after `{change}`");
        assert_eq!(b.console.settings().certificate, Certificate::NONE);
    }
    // Settings that do not change the shaper keep it.
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("certify measured 1.07 1.13");
    b.ok("speed 120");
    assert_eq!(
        b.console.settings().certificate.verified,
        Verified::Measured
    );
}

#[test]
fn bad_certificates_are_refused_and_change_nothing() {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.err("certify", "syntax");
    b.err("certify maybe", "syntax");
    b.err("certify measured 1.07", "syntax");
    b.err("certify measured 1.13 1.07", "range");
    b.err("certify measured -1 1.07", "range");
    b.err("certify measured 1.07 inf", "range");
    // A band for slot 2, which holds no mode.
    b.err("certify measured 1.07 1.13 6.7 7.1", "range");
    // `unknown` carries no band.
    b.err("certify unknown 1.07 1.13", "range");
    b.ok("certify unknown");
    assert_eq!(b.console.settings().certificate, Certificate::NONE);
}

#[test]
fn the_status_of_an_earlier_firmware_reads_as_unknown() {
    let mut b = Board::new();
    let line = last(&b.ok("status")).to_string();
    let old = line.replace(" verified=unknown", "");
    assert_ne!(old, line);
    assert_eq!(
        StatusReply::parse(&old).unwrap().verified,
        Verified::Unknown
    );
    let cfg = last(&b.ok("config")).to_string();
    let old = cfg[..cfg.find(" verified=").unwrap()].to_string();
    assert_eq!(
        ConfigReply::parse(&old).unwrap().certificate,
        Certificate::NONE
    );
}
