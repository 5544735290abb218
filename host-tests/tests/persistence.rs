//! Settings persistence on `sequential-storage` with its mock flash (STM32G4-like: 8-byte
//! words written once, 2 KiB pages): round trip, missing record, corruption, and power loss
//! at every byte of a save.

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::NumericPath;
use beamshaper::shaper::ShaperKind;
use beamshaper::storage::{load_settings, save_settings, StorageError, STORAGE_BUFFER_BYTES};
use futures::executor::block_on;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};

type Flash = MockFlashBase<4, 8, 256>;

fn map(
    flash: Flash,
) -> MapStorage<u8, Flash, sequential_storage::cache::Cache<Uncached, Uncached, Uncached, u8>> {
    MapStorage::new(
        flash,
        const { MapConfig::new(Flash::FULL_FLASH_RANGE) },
        Cache::new_uncached(),
    )
}

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

#[test]
fn missing_record_loads_none_and_round_trip_works() {
    let mut m = map(new_flash(None));
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    assert_eq!(block_on(load_settings(&mut m, &mut buf)), Ok(None));
    let s = tuned(1.1);
    block_on(save_settings(&mut m, &mut buf, &s)).unwrap();
    assert_eq!(
        block_on(load_settings(&mut m, &mut buf)),
        Ok(Some(s.clone()))
    );
    // Many saves: garbage collection across pages keeps the latest.
    for k in 0..200 {
        block_on(save_settings(
            &mut m,
            &mut buf,
            &tuned(1.0 + k as f64 * 0.001),
        ))
        .unwrap();
    }
    assert_eq!(
        block_on(load_settings(&mut m, &mut buf)),
        Ok(Some(tuned(1.199)))
    );
}

#[test]
fn corrupt_record_is_reported_not_used() {
    let mut m = map(new_flash(None));
    let mut buf = [0u8; STORAGE_BUFFER_BYTES];
    block_on(save_settings(&mut m, &mut buf, &tuned(1.1))).unwrap();
    let mut flash = m.destroy().0;
    // Flip bits in the first page's data area (item headers and payload).
    let bytes = flash.as_bytes_mut();
    for b in bytes.iter_mut().skip(64).take(200) {
        if *b != 0xff {
            *b ^= 0x5a;
        }
    }
    let mut m = map(flash);
    match block_on(load_settings(&mut m, &mut buf)) {
        Err(StorageError::Corrupt) | Ok(None) => {}
        other => panic!("corrupted flash must not yield settings: {other:?}"),
    }
}

#[test]
fn power_loss_at_every_byte_of_a_save_keeps_old_or_new() {
    let old = tuned(1.1);
    let new = tuned(2.2);
    // Bytes written by one save into a flash that already holds `old`.
    let mut total = 0u32;
    for cut in 0u32.. {
        let mut m = map(new_flash(None));
        let mut buf = [0u8; STORAGE_BUFFER_BYTES];
        block_on(save_settings(&mut m, &mut buf, &old)).unwrap();
        let mut flash = m.destroy().0;
        flash.bytes_until_shutoff = Some(cut);
        let mut m = map(flash);
        let r = block_on(save_settings(&mut m, &mut buf, &new));
        let mut flash = m.destroy().0;
        flash.bytes_until_shutoff = None;
        let mut m = map(flash);
        let loaded = block_on(load_settings(&mut m, &mut buf));
        match &loaded {
            Ok(Some(s)) if *s == old || *s == new => {}
            other => panic!("power cut after {cut} bytes: loaded {other:?}"),
        }
        if r.is_ok() {
            assert_eq!(loaded, Ok(Some(new.clone())));
            total = cut;
            break;
        }
    }
    assert!(total > 50, "a save writes the whole record ({total} bytes)");
}
