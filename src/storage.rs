//! Power-fail-safe persistence of [`Settings`] in internal flash, on `sequential-storage`'s
//! map (a key–value log across ≥ 2 flash pages; each item carries a CRC, and an interrupted
//! write leaves the previous item readable).
//!
//! The record itself is [`Settings::encode`]: magic, version, fields and a CRC-32, validated
//! again on load ([`Settings::decode`]), so a record that survives the flash layer but is
//! invalid or out of range is still refused.
//!
//! `sequential-storage` silently skips an item whose own CRC fails. So that a damaged record
//! is reported as [`StorageError::Corrupt`] rather than "never saved", [`load_settings`]
//! answers `Ok(None)` only when the whole settings range is erased (all `0xFF`); written
//! flash without a valid record (bit rot, or power lost during the very first save) is
//! `Corrupt`.

use crate::config::{Settings, SETTINGS_MAX_BYTES};
use core::ops::Range;
use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage, SerializationError, Value};

/// Map key of the settings record.
pub const SETTINGS_KEY: u8 = 1;

/// Bytes of the work buffer the storage functions need (record + key, word-rounded).
pub const STORAGE_BUFFER_BYTES: usize = SETTINGS_MAX_BYTES + 16;

/// Why a save or load failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StorageError {
    /// The flash driver reported an error.
    Flash,
    /// The record (or the flash log) is corrupt.
    Corrupt,
    /// No space left even after garbage collection.
    Full,
    /// The flash range is not whole erase pages, or fewer than two.
    Range,
    /// Any other error of the storage layer.
    Other,
}

impl core::fmt::Display for StorageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            StorageError::Flash => "flash driver error",
            StorageError::Corrupt => "stored settings corrupt",
            StorageError::Full => "settings storage full",
            StorageError::Range => "settings flash range is not at least two whole pages",
            StorageError::Other => "settings storage error",
        })
    }
}

fn map_err<E>(e: sequential_storage::Error<E>) -> StorageError {
    match e {
        sequential_storage::Error::Storage { .. } => StorageError::Flash,
        sequential_storage::Error::Corrupted { .. } => StorageError::Corrupt,
        sequential_storage::Error::SerializationError(_) => StorageError::Corrupt,
        sequential_storage::Error::FullStorage => StorageError::Full,
        _ => StorageError::Other,
    }
}

/// [`Settings`] as a `sequential-storage` value.
struct Record(Settings);

impl<'a> Value<'a> for Record {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        self.0
            .encode(buffer)
            .map_err(|_| SerializationError::BufferTooSmall)
    }

    fn deserialize_from(buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        Settings::decode(buffer)
            .map(|s| (Record(s), buffer.len()))
            .map_err(|_| SerializationError::InvalidFormat)
    }
}

type Map<'f, S> = MapStorage<
    u8,
    &'f mut S,
    Cache<
        sequential_storage::cache::Uncached,
        sequential_storage::cache::Uncached,
        sequential_storage::cache::Uncached,
        u8,
    >,
>;

fn open<S: NorFlash>(flash: &mut S, range: Range<u32>) -> Result<Map<'_, S>, StorageError> {
    let config = MapConfig::try_new(range).map_err(|_| StorageError::Range)?;
    Ok(MapStorage::new(flash, config, Cache::new_uncached()))
}

/// Stores `settings` in `range` of `flash` (byte offsets, whole erase pages, at least two).
/// A new item is appended; the old one stays until garbage collection erases its page, so a
/// power loss at any byte leaves either the old or the new record.
///
/// Errors: [`StorageError::Range`], `Flash`, `Full`, `Corrupt` (the log could not be read).
pub async fn save_settings<S: NorFlash>(
    flash: &mut S,
    range: Range<u32>,
    buffer: &mut [u8; STORAGE_BUFFER_BYTES],
    settings: &Settings,
) -> Result<(), StorageError> {
    let mut map = open(flash, range)?;
    map.store_item(buffer, &SETTINGS_KEY, &Record(settings.clone()))
        .await
        .map_err(map_err)
}

/// Loads the settings from `range` of `flash`: `Ok(None)` if the range is erased (nothing
/// was ever saved), `Err(Corrupt)` if it holds data but no valid settings record.
pub async fn load_settings<S: NorFlash>(
    flash: &mut S,
    range: Range<u32>,
    buffer: &mut [u8; STORAGE_BUFFER_BYTES],
) -> Result<Option<Settings>, StorageError> {
    let found = {
        let mut map = open(flash, range.clone())?;
        map.fetch_item::<Record>(buffer, &SETTINGS_KEY)
            .await
            .map_err(map_err)?
    };
    match found {
        Some(r) => Ok(Some(r.0)),
        None if is_erased(flash, range, buffer).await? => Ok(None),
        None => Err(StorageError::Corrupt),
    }
}

/// Whether every byte of `range` reads `0xFF`.
async fn is_erased<S: NorFlash>(
    flash: &mut S,
    range: Range<u32>,
    buffer: &mut [u8; STORAGE_BUFFER_BYTES],
) -> Result<bool, StorageError> {
    // Reads in chunks that are a multiple of the read size.
    let read = S::READ_SIZE.max(1);
    let chunk = (buffer.len() / read) * read;
    if chunk == 0 {
        return Err(StorageError::Other);
    }
    let mut at = range.start;
    while at < range.end {
        let n = chunk.min((range.end - at) as usize);
        flash
            .read(at, &mut buffer[..n])
            .await
            .map_err(|_| StorageError::Flash)?;
        if buffer[..n].iter().any(|&b| b != 0xff) {
            return Ok(false);
        }
        at += n as u32;
    }
    Ok(true)
}
