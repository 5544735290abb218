//! Settings persistence on `sequential-storage` with its mock flash (STM32G4-like: 8-byte
//! words written once, 4 pages of 2 KiB): round trip, missing record, corruption (in the
//! flash log and in the record itself), and power loss at every byte of a save.

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::NumericPath;
use beamshaper::shaper::ShaperKind;
use beamshaper::storage::{
    load_settings, save_settings, StorageError, SETTINGS_KEY, STORAGE_BUFFER_BYTES,
};
use futures::executor::block_on;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};

type Flash = MockFlashBase<4, 8, 256>;
const RANGE: core::ops::Range<u32> = Flash::FULL_FLASH_RANGE;

fn new_flash(shutoff: Option<u32>) -> Flash {
    Flash::new(WriteCountCheck::OnceOnly, shutoff, true)
}

fn tuned(freq_hz: f64) -> Settings {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz,
        zeta: 0.0074,
    });
    s.modes[1] = Some(ModeSetting {
        kind: ShaperKind::Ei { v_tol: 0.03 },
        freq_hz: 6.9,
        zeta: 0.0074,
    });
    s.path = NumericPath::F32;
    s.tick_rate_hz = 2000;
    s
}

fn save(flash: &mut Flash, s: &Settings) -> Result<(), StorageError> {
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    block_on(save_settings(flash, RANGE, &mut buf, s))
}

fn load(flash: &mut Flash) -> Result<Option<Settings>, StorageError> {
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    block_on(load_settings(flash, RANGE, &mut buf))
}

/// Stores raw bytes under the settings key, bypassing the settings codec.
fn store_raw(flash: &mut Flash, bytes: &[u8]) {
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    let mut map = MapStorage::<u8, _, _>::new(flash, MapConfig::new(RANGE), Cache::new_uncached());
    block_on(map.store_item(&mut buf, &SETTINGS_KEY, &bytes)).unwrap();
}

#[test]
fn missing_record_loads_none_and_round_trip_works() {
    let mut flash = new_flash(None);
    assert_eq!(load(&mut flash), Ok(None));
    let s = tuned(1.1);
    save(&mut flash, &s).unwrap();
    assert_eq!(load(&mut flash), Ok(Some(s)));
    // Many saves: garbage collection across pages keeps the latest.
    for k in 0..200 {
        save(&mut flash, &tuned(1.0 + k as f64 * 0.001)).unwrap();
    }
    assert_eq!(load(&mut flash), Ok(Some(tuned(1.199))));
}

#[test]
fn bad_flash_range_is_an_error_not_a_panic() {
    let mut flash = new_flash(None);
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    // Not page aligned, and a single page.
    for range in [100..RANGE.end, 0..256] {
        assert_eq!(
            block_on(load_settings(&mut flash, range.clone(), &mut buf)),
            Err(StorageError::Range)
        );
        assert_eq!(
            block_on(save_settings(&mut flash, range, &mut buf, &tuned(1.1))),
            Err(StorageError::Range)
        );
    }
}

#[test]
fn bit_flips_in_the_flash_log_are_reported_corrupt() {
    let mut flash = new_flash(None);
    save(&mut flash, &tuned(1.1)).unwrap();
    // Flip bits in the first page's data area (item headers and payload).
    for b in flash.as_bytes_mut().iter_mut().skip(64).take(200) {
        if *b != 0xff {
            *b ^= 0x5a;
        }
    }
    assert_eq!(load(&mut flash), Err(StorageError::Corrupt));
}

#[test]
fn every_single_bit_flip_of_a_saved_record_is_caught() {
    let mut clean = new_flash(None);
    save(&mut clean, &tuned(1.1)).unwrap();
    let written: Vec<usize> = (0..clean.as_bytes().len())
        .filter(|&i| clean.as_bytes()[i] != 0xff)
        .collect();
    assert!(written.len() > 50, "{} bytes written", written.len());
    for &i in &written {
        for bit in 0..8 {
            let mut flash = clean.clone();
            flash.as_bytes_mut()[i] ^= 1 << bit;
            match load(&mut flash) {
                Err(StorageError::Corrupt) => {}
                Ok(Some(s)) if s == tuned(1.1) => {} // a flip in padding or a state marker
                other => panic!("bit {bit} of byte {i} flipped: loaded {other:?}"),
            }
        }
    }
}

#[test]
fn record_intact_in_flash_but_invalid_as_settings_is_corrupt() {
    // The flash layer's item CRC is fine, but the payload is not a valid settings record:
    // a truncated record, a record with one payload bit flipped (our CRC-32 catches it),
    // and plain garbage.
    let mut rec = [0u8; STORAGE_BUFFER_BYTES];
    let n = tuned(1.1).encode(&mut rec).unwrap();
    let mut flipped = rec;
    flipped[n / 2] ^= 0x10;
    let cases: [&[u8]; 3] = [&rec[..n - 1], &flipped[..n], b"not a settings record"];
    for bytes in cases {
        let mut flash = new_flash(None);
        store_raw(&mut flash, bytes);
        assert_eq!(load(&mut flash), Err(StorageError::Corrupt));
    }
    // A valid record stored later replaces the bad one.
    let mut flash = new_flash(None);
    store_raw(&mut flash, b"garbage");
    save(&mut flash, &tuned(2.0)).unwrap();
    assert_eq!(load(&mut flash), Ok(Some(tuned(2.0))));
}

#[test]
fn power_loss_at_every_byte_of_a_save_keeps_old_or_new() {
    let old = tuned(1.1);
    let new = tuned(2.2);
    let mut total = None;
    for cut in 0u32..10_000 {
        let mut flash = new_flash(None);
        save(&mut flash, &old).unwrap();
        flash.bytes_until_shutoff = Some(cut);
        let r = save(&mut flash, &new);
        flash.bytes_until_shutoff = None;
        let loaded = load(&mut flash);
        match &loaded {
            Ok(Some(s)) if *s == old || *s == new => {}
            other => panic!("power cut after {cut} bytes: loaded {other:?}"),
        }
        // The next save after the cut works and wins.
        save(&mut flash, &tuned(3.3)).unwrap();
        assert_eq!(
            load(&mut flash),
            Ok(Some(tuned(3.3))),
            "save after a cut at {cut}"
        );
        if r.is_ok() {
            assert_eq!(loaded, Ok(Some(new.clone())));
            total = Some(cut);
            break;
        }
    }
    let total = total.expect("a save completes within 10 000 bytes");
    assert!(total > 50, "a save writes the whole record ({total} bytes)");
}

#[test]
fn power_loss_during_the_first_save_never_yields_garbage() {
    for cut in 0u32..10_000 {
        let mut flash = new_flash(Some(cut));
        let r = save(&mut flash, &tuned(1.1));
        flash.bytes_until_shutoff = None;
        let loaded = load(&mut flash);
        match &loaded {
            Ok(None) => assert_eq!(cut, 0, "flash written before the cut"),
            Err(StorageError::Corrupt) => assert!(r.is_err()),
            Ok(Some(s)) => assert_eq!(*s, tuned(1.1), "cut at {cut}"),
            other => panic!("power cut after {cut} bytes of the first save: {other:?}"),
        }
        if r.is_ok() {
            assert_eq!(loaded, Ok(Some(tuned(1.1))));
            return;
        }
    }
    panic!("the first save never completed");
}
