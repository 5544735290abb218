//! Power-fail-safe persistence of [`Settings`] in internal flash, on `sequential-storage`'s
//! map (a key–value log across ≥ 2 flash pages; each item carries a CRC, and an interrupted
//! write leaves the previous item readable).
//!
//! The record itself is [`Settings::encode`]: magic, format version, the settings in postcard
//! and a CRC-32, validated again on load ([`Settings::decode`]), so a record that survives the
//! flash layer but is invalid or out of range is still refused ([`StorageError::Corrupt`]), and
//! an intact record of another format version (the old hand-written version 1) is refused
//! as [`StorageError::Version`].
//!
//! `sequential-storage` silently skips an item whose own CRC fails. So that a damaged record
//! is reported as [`StorageError::Corrupt`] rather than "never saved", [`load_settings`]
//! answers `Ok(None)` only when the whole settings range is erased (all `0xFF`); written
//! flash without a valid record (bit rot, or power lost during the very first save) is
//! `Corrupt`.

use crate::config::{ConfigError, Settings, SETTINGS_MAX_BYTES, SETTINGS_VERSION};
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
    /// The record (or the flash log) is corrupt, or the record is out of range.
    Corrupt,
    /// The record is intact but of another format version (the version found).
    Version(u8),
    /// No space left even after garbage collection.
    Full,
    /// The flash range is not whole erase pages, or fewer than two.
    Range,
    /// Any other error of the storage layer.
    Other,
}

impl StorageError {
    /// Short code for the console (`err <code>: …`): `version` for [`StorageError::Version`],
    /// `corrupt` for a corrupt record, `storage` otherwise.
    pub fn code(&self) -> &'static str {
        match self {
            StorageError::Version(_) => "version",
            StorageError::Corrupt => "corrupt",
            _ => "storage",
        }
    }
}

/// A record the settings codec refused: another format version or anything else (corrupt).
impl From<ConfigError> for StorageError {
    fn from(e: ConfigError) -> Self {
        match e {
            ConfigError::Version { found } => StorageError::Version(found),
            _ => StorageError::Corrupt,
        }
    }
}

impl core::fmt::Display for StorageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if let StorageError::Version(found) = self {
            return write!(
                f,
                "stored settings are format version {found}, this firmware reads version \
                 {SETTINGS_VERSION} (save to replace them)"
            );
        }
        f.write_str(match self {
            StorageError::Flash => "flash driver error",
            StorageError::Corrupt => "stored settings corrupt",
            StorageError::Full => "settings storage full",
            StorageError::Range => "settings flash range is not at least two whole pages",
            StorageError::Version(_) | StorageError::Other => "settings storage error",
        })
    }
}

fn map_err<E>(e: sequential_storage::Error<E>) -> StorageError {
    match e {
        sequential_storage::Error::Storage { .. } => StorageError::Flash,
        sequential_storage::Error::Corrupted { .. } => StorageError::Corrupt,
        sequential_storage::Error::SerializationError(SerializationError::Custom(code)) => {
            StorageError::Version(code as u8)
        }
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
            .map_err(|e| match e {
                // The only custom code: the version byte of an intact record of another format.
                ConfigError::Version { found } => SerializationError::Custom(found as i32),
                _ => SerializationError::InvalidFormat,
            })
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
/// was ever saved), `Err(Version(v))` if the newest record is intact but of format version
/// `v` ≠ [`SETTINGS_VERSION`], `Err(Corrupt)` if it holds data but no valid settings record.
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
