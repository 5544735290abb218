//! The settings record (format version 4: magic, version, postcard body, CRC-32; versions 3 and 2
//! are migrated, see tests/certificate.rs and the format-3 golden record below): round trip
//! of any settings (proptest), every corrupted or truncated record refused as corrupt, and
//! an intact record of the old hand-written version 1 (or of an unknown version) refused
//! with its version named — by the codec, by the flash storage and by the console, with the
//! defaults (at boot) or the settings in force (on `load`) kept.

use beamshaper::config::{
    Certificate, ConfigError, ModeSetting, Settings, Source, Verified, MAX_CUSTOM_IMPULSES,
    SETTINGS_MAX_BYTES, SETTINGS_VERSION,
};
use beamshaper::console::Console;
use beamshaper::engine::NumericPath;
use beamshaper::runtime::Runtime;
use beamshaper::shaper::{Impulse, ShaperKind};
use beamshaper::storage::{load_settings, StorageError, SETTINGS_KEY, STORAGE_BUFFER_BYTES};
use beamshaper_host_tests::Board;
use futures::executor::block_on;
use proptest::prelude::*;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};

type Flash = MockFlashBase<4, 8, 256>;
const RANGE: core::ops::Range<u32> = Flash::FULL_FLASH_RANGE;

fn encode(s: &Settings) -> Vec<u8> {
    let mut buf = [0u8; SETTINGS_MAX_BYTES];
    let n = s.encode(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// A record of the version-1 format (the hand-written layout this codec replaced), written
/// here byte by byte from its specification: `BSH`, 1, per mode slot a kind code (0 = none)
/// then v_tol, freq_hz, zeta as f64; the custom count and (amplitude, time_s) f64 pairs;
/// shaping, path, four u32, source; three f32; CRC-32/ISO-HDLC; all little-endian.
fn v1_record(s: &Settings) -> Vec<u8> {
    let mut r = b"BSH\x01".to_vec();
    for m in &s.modes {
        let Some(m) = m else {
            r.push(0);
            continue;
        };
        let code = [
            "zv", "zvd", "zvdd", "zvddd", "mzv", "ei", "2hei", "3hei", "umzv",
        ]
        .iter()
        .position(|&n| n == m.kind.name())
        .unwrap() as u8
            + 1;
        r.push(code);
        for v in [m.kind.v_tol().unwrap_or(0.0), m.freq_hz, m.zeta] {
            r.extend_from_slice(&v.to_le_bytes());
        }
    }
    r.push(s.custom.len() as u8);
    for i in &s.custom {
        r.extend_from_slice(&i.amplitude.to_le_bytes());
        r.extend_from_slice(&i.time_s.to_le_bytes());
    }
    r.push(s.shaping_enabled as u8);
    r.push((s.path == NumericPath::F32) as u8);
    for v in [
        s.tick_rate_hz,
        s.step_nm,
        s.max_step_rate_hz,
        s.input_nm_per_count,
    ] {
        r.extend_from_slice(&v.to_le_bytes());
    }
    r.push((s.source == Source::StepDir) as u8);
    for v in [s.move_speed_mm_s, s.move_accel_mm_s2, s.dac_span_mm] {
        r.extend_from_slice(&v.to_le_bytes());
    }
    with_crc(r)
}

/// Appends the record's CRC-32/ISO-HDLC (the same in versions 1 and 2).
fn with_crc(mut r: Vec<u8>) -> Vec<u8> {
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&r);
    r.extend_from_slice(&crc.to_le_bytes());
    r
}

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

fn load(flash: &mut Flash) -> Result<Option<Settings>, StorageError> {
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    block_on(load_settings(flash, RANGE, &mut buf))
}

fn kind() -> impl Strategy<Value = ShaperKind> {
    (0usize..9, 0.01f64..0.3).prop_map(|(k, v_tol)| match k {
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

fn mode() -> impl Strategy<Value = Option<ModeSetting>> {
    proptest::option::of(
        (kind(), 0.5f64..40.0, 0.0f64..0.3).prop_map(|(kind, freq_hz, zeta)| ModeSetting {
            kind,
            freq_hz,
            zeta,
        }),
    )
}

/// Any settings with finite numbers, in range or not (decode must then refuse them).
fn any_settings() -> impl Strategy<Value = Settings> {
    let custom = proptest::collection::vec((-1.0f64..2.0, 0.0f64..0.5), 0..=MAX_CUSTOM_IMPULSES);
    (
        proptest::array::uniform4(mode()),
        custom,
        any::<bool>(),
        any::<bool>(),
        (
            0u32..12_000,
            0u32..2_000_000,
            0u32..60_000_000,
            0u32..2_000_000,
        ),
        any::<bool>(),
        (-10.0f32..20_000.0, -10.0f32..2.0e6, -10.0f32..2000.0),
        (
            0usize..3,
            proptest::array::uniform4(proptest::option::of((-1.0f32..50.0, -1.0f32..50.0))),
        ),
    )
        .prop_map(
            |(modes, custom, shaping, f32_path, ints, stepdir, floats, cert)| {
                let mut s = Settings::DEFAULT;
                s.modes = modes;
                // Half of the lists are normalised to sum 1 (a usable custom shaper).
                let sum: f64 = custom.iter().map(|c| c.0).sum();
                let normalise = custom.len() % 2 == 1 && sum.abs() > 0.1;
                for (a, t) in custom {
                    let amplitude = if normalise { a / sum } else { a };
                    s.custom
                        .push(Impulse {
                            amplitude,
                            time_s: t,
                        })
                        .unwrap();
                }
                s.shaping_enabled = shaping;
                s.path = if f32_path {
                    NumericPath::F32
                } else {
                    NumericPath::Fixed
                };
                (
                    s.tick_rate_hz,
                    s.step_nm,
                    s.max_step_rate_hz,
                    s.input_nm_per_count,
                ) = ints;
                s.source = if stepdir {
                    Source::StepDir
                } else {
                    Source::Internal
                };
                (s.move_speed_mm_s, s.move_accel_mm_s2, s.dac_span_mm) = floats;
                s.certificate = Certificate {
                    verified: [
                        Verified::Unknown,
                        Verified::Measured,
                        Verified::PredictedOnly,
                    ][cert.0],
                    band_hz: cert.1,
                };
                s
            },
        )
}

/// What decoding a record of `s` must give: `s` itself if it is valid, else its error.
fn expected(s: &Settings) -> Result<Settings, ConfigError> {
    s.validate()?;
    s.shaper()?;
    Ok(s.clone())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn any_settings_round_trip_or_are_refused_as_invalid(s in any_settings()) {
        let rec = encode(&s);
        prop_assert!(rec.len() <= SETTINGS_MAX_BYTES);
        prop_assert_eq!(&rec[..4], &[b'B', b'S', b'H', SETTINGS_VERSION]);
        prop_assert_eq!(Settings::decode(&rec), expected(&s));
    }

    #[test]
    fn valid_settings_round_trip_exactly(
        modes in proptest::array::uniform4(mode()),
        tick_rate_hz in 500u32..=10_000,
        speed in 0.001f32..10_000.0,
    ) {
        let mut s = Settings::DEFAULT;
        s.modes = modes;
        s.tick_rate_hz = tick_rate_hz;
        s.move_speed_mm_s = speed;
        prop_assume!(s.shaper().is_ok());
        prop_assert_eq!(Settings::decode(&encode(&s)), Ok(s));
    }
}

#[test]
fn a_record_of_the_largest_settings_fits_the_buffer() {
    let mut s = tuned();
    for m in s.modes.iter_mut() {
        *m = Some(ModeSetting {
            kind: ShaperKind::Ei3Hump { v_tol: 0.05 },
            freq_hz: 3.0,
            zeta: 0.01,
        });
    }
    s.custom.clear();
    for k in 0..MAX_CUSTOM_IMPULSES {
        s.custom
            .push(Impulse {
                amplitude: 1.0 / MAX_CUSTOM_IMPULSES as f64,
                time_s: k as f64 * 1e-3,
            })
            .unwrap();
    }
    (s.tick_rate_hz, s.step_nm, s.max_step_rate_hz) = (u32::MAX, u32::MAX, u32::MAX);
    let mut buf = [0u8; SETTINGS_MAX_BYTES];
    let n = s.encode(&mut buf).unwrap();
    assert!(n <= SETTINGS_MAX_BYTES, "{n} bytes");
    // Too small a buffer is an error, never a panic.
    for len in 0..n {
        assert_eq!(
            s.encode(&mut buf[..len]),
            Err(ConfigError::Buffer),
            "{len} B"
        );
    }
}

#[test]
fn a_corrupt_byte_at_every_position_and_every_truncation_is_refused_as_corrupt() {
    let rec = encode(&tuned());
    for i in 0..rec.len() {
        for pattern in [0x01u8, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80, 0xff, 0x5a] {
            let mut bad = rec.clone();
            bad[i] ^= pattern;
            assert_eq!(
                Settings::decode(&bad),
                Err(ConfigError::Corrupt),
                "byte {i} ^ {pattern:#x}"
            );
        }
    }
    for len in 0..rec.len() {
        assert_eq!(
            Settings::decode(&rec[..len]),
            Err(ConfigError::Corrupt),
            "{len} B"
        );
    }
    // A byte appended (with a matching CRC) is an undecodable body, not a longer record.
    let mut longer = rec[..rec.len() - 4].to_vec();
    longer.push(0);
    assert_eq!(
        Settings::decode(&with_crc(longer)),
        Err(ConfigError::Corrupt)
    );
    // Another magic with a valid CRC.
    let mut other = rec[..rec.len() - 4].to_vec();
    other[0] = b'X';
    assert_eq!(
        Settings::decode(&with_crc(other)),
        Err(ConfigError::Corrupt)
    );
}

#[test]
fn an_intact_record_that_fails_validation_is_refused_with_the_validation_error() {
    let mut s = tuned();
    s.tick_rate_hz = 20_000;
    assert_eq!(
        Settings::decode(&encode(&s)),
        Err(ConfigError::Range("tick rate (500..10000 Hz)"))
    );
    let mut s = tuned();
    s.modes[1] = Some(ModeSetting {
        kind: ShaperKind::Zvd,
        freq_hz: -1.0,
        zeta: 0.01,
    });
    assert!(matches!(
        Settings::decode(&encode(&s)),
        Err(ConfigError::Shaper(_))
    ));
    // In flash: refused as corrupt, the defaults stay (nothing is loaded).
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &encode(&s));
    assert_eq!(load(&mut flash), Err(StorageError::Corrupt));
}

#[test]
fn a_version_1_record_is_refused_with_its_version_by_codec_and_storage() {
    let v1 = v1_record(&tuned());
    assert_eq!(
        Settings::decode(&v1),
        Err(ConfigError::Version { found: 1 })
    );
    assert_eq!(ConfigError::Version { found: 1 }.code(), "version");
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &v1);
    assert_eq!(load(&mut flash), Err(StorageError::Version(1)));
    // An unknown (future) version with a valid CRC, too.
    let mut v9 = encode(&tuned());
    v9.truncate(v9.len() - 4);
    v9[3] = 9;
    let v9 = with_crc(v9);
    assert_eq!(
        Settings::decode(&v9),
        Err(ConfigError::Version { found: 9 })
    );
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &v9);
    assert_eq!(load(&mut flash), Err(StorageError::Version(9)));
    // A v1 record with a bit flipped is corrupt, not "version 1".
    let mut bad = v1.clone();
    bad[20] ^= 4;
    assert_eq!(Settings::decode(&bad), Err(ConfigError::Corrupt));
}

#[test]
fn at_boot_a_version_1_record_leaves_the_defaults_and_the_console_names_the_version() {
    let mut rt = Box::new(Runtime::new());
    let mut out = String::new();
    let console = Console::boot(Err(StorageError::Version(1)), &mut *rt, 0, &mut out);
    assert_eq!(console.settings(), &Settings::DEFAULT);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines,
        [
            "# boot: stored settings unusable (stored settings are format version 1, this \
             firmware reads version 4 (save to replace them))",
            "# boot: using defaults",
            "ok boot",
        ],
        "{out}"
    );
}

#[test]
fn load_of_a_version_1_record_keeps_the_settings_in_force_and_answers_err_version() {
    let mut b = Board::new();
    b.ok("mode 1 zvd 1.1 0.0074");
    b.run(5);
    let before = (
        b.console.settings().clone(),
        b.rt.pending().cloned(),
        b.rt.status(),
    );
    let mut out = String::new();
    b.console
        .finish_load(Err(StorageError::Version(1)), &mut *b.rt, &mut out);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert!(lines[0].starts_with("# load: stored settings are format version 1"));
    assert!(lines[1].starts_with("err version: "), "{out}");
    let after = (
        b.console.settings().clone(),
        b.rt.pending().cloned(),
        b.rt.status(),
    );
    assert_eq!(before, after);
}

/// The record the format-2 firmware (commit 873f980) saved for [`tuned`], byte for byte
/// (printed by that firmware's `Settings::encode`).
const V2_RECORD_HEX: &str = "4253480201029a9999999999f13facadd85f764f7e3f000105b81e85eb51b89e3f9a99999999991b407b14ae47e17a843f0002000000000000e03f0000000000000000000000000000e03f7b14ae47e17a843f0101d00fe807c09a0ce807010080164300007a440000c8426f70482e";

fn v2_record() -> Vec<u8> {
    (0..V2_RECORD_HEX.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&V2_RECORD_HEX[i..i + 2], 16).unwrap())
        .collect()
}

#[test]
fn a_record_of_the_previous_firmware_is_migrated_with_the_shaper_intact() {
    assert_eq!(SETTINGS_VERSION, 4);
    let v2 = v2_record();
    assert_eq!(v2[3], 2, "the fixture is a format-2 record");
    let s = Settings::decode(&v2).expect("a format-2 record is read");
    assert_eq!(s, tuned());
    assert_eq!(s.certificate, Certificate::NONE);
    // Through the flash layer and the boot path, as a firmware update meets it.
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &v2);
    let loaded = load(&mut flash);
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

/// The record the format-3 firmware (commit fa3fe4c) saved for [`tuned`] with a certificate,
/// byte for byte (printed by that commit's `Settings::encode`, built from its tree).
const V3_RECORD_HEX: &str = "4253480301029a9999999999f13facadd85f764f7e3f000105b81e85eb51b89e3f9a99999999991b407b14ae47e17a843f0002000000000000e03f0000000000000000000000000000e03f7b14ae47e17a843f0101d00fe807c09a0ce807010080164300007a440000c84201016666863fe17a943f00010000d0409a99e940006850a7df";

fn tuned_v3() -> Settings {
    let mut s = tuned();
    s.certificate = Certificate {
        verified: Verified::Measured,
        band_hz: [Some((1.05, 1.16)), None, Some((6.5, 7.3)), None],
    };
    s
}

#[test]
fn a_format_3_record_is_migrated_with_shaper_and_certificate_intact_and_the_watch_off() {
    let v3: Vec<u8> = (0..V3_RECORD_HEX.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&V3_RECORD_HEX[i..i + 2], 16).unwrap())
        .collect();
    assert_eq!(v3[3], 3, "the fixture is a format-3 record");
    let s = Settings::decode(&v3).expect("a format-3 record is read");
    assert_eq!(s, tuned_v3());
    assert_eq!(s.watch, beamshaper::config::WatchSettings::OFF);
    // Through the flash layer and the boot path, as a firmware update meets it.
    let mut flash = Flash::new(WriteCountCheck::OnceOnly, None, true);
    store_raw(&mut flash, &v3);
    let loaded = load(&mut flash);
    assert_eq!(loaded, Ok(Some(tuned_v3())));
    let mut rt = Box::new(Runtime::new());
    let mut out = String::new();
    let console = Console::boot(loaded, &mut *rt, 0, &mut out);
    assert!(out.contains("# boot: settings loaded from flash"), "{out}");
    // Saved again, it is format 4 and reads back the same.
    let mut rec = [0u8; SETTINGS_MAX_BYTES];
    let n = console.settings().encode(&mut rec).unwrap();
    assert_eq!(rec[3], 4);
    assert_eq!(Settings::decode(&rec[..n]), Ok(tuned_v3()));
    // A flipped bit is still corrupt, not migrated.
    let mut bad = v3.clone();
    bad[12] ^= 1;
    assert!(Settings::decode(&bad).is_err());
}

/// The watch's settings and the payload schedule survive a save (format 4), at their largest.
#[test]
fn watch_settings_and_a_full_schedule_round_trip() {
    let mut s = tuned_v3();
    s.watch = beamshaper::config::WatchSettings {
        enabled: true,
        auto: true,
        limits_hz: (0.5, 10.0),
        payload: Some(7),
        schedule: [[1.234_567_9; 4]; beamshaper::config::PAYLOAD_ENTRIES],
    };
    let rec = encode(&s);
    assert!(rec.len() <= SETTINGS_MAX_BYTES);
    assert_eq!(Settings::decode(&rec), Ok(s));
}
