//! Power-fail-safe persistence of [`Settings`] in internal flash, on `sequential-storage`'s
//! map (key–value log across ≥ 2 flash pages; each item carries a CRC, and an interrupted
//! write leaves the previous item readable).
//!
//! The record itself is [`Settings::encode`]: magic, version, fields and a CRC-32, validated
//! again on load ([`Settings::decode`]), so a record that survives the flash layer but is
//! out of range is still refused.

use crate::config::{Settings, SETTINGS_MAX_BYTES};
use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::CacheImpl;
use sequential_storage::map::{MapStorage, SerializationError, Value};

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
    /// Any other error of the storage layer.
    Other,
}

impl core::fmt::Display for StorageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            StorageError::Flash => "flash driver error",
            StorageError::Corrupt => "stored settings corrupt",
            StorageError::Full => "settings storage full",
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

/// Stores `settings` (a new item; the old one stays until garbage collection erases its
/// page, so power loss at any byte leaves either the old or the new record).
pub async fn save_settings<S: NorFlash, C: CacheImpl<u8>>(
    map: &mut MapStorage<u8, S, C>,
    buffer: &mut [u8; STORAGE_BUFFER_BYTES],
    settings: &Settings,
) -> Result<(), StorageError> {
    map.store_item(buffer, &SETTINGS_KEY, &Record(settings.clone()))
        .await
        .map_err(map_err)
}

/// Loads the settings: `Ok(None)` if none were ever saved, `Err(Corrupt)` if the record is
/// unreadable or invalid.
pub async fn load_settings<S: NorFlash, C: CacheImpl<u8>>(
    map: &mut MapStorage<u8, S, C>,
    buffer: &mut [u8; STORAGE_BUFFER_BYTES],
) -> Result<Option<Settings>, StorageError> {
    map.fetch_item::<Record>(buffer, &SETTINGS_KEY)
        .await
        .map(|r| r.map(|r| r.0))
        .map_err(map_err)
}
