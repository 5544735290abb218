//! The operator's settings: what the console edits and the flash stores.
//!
//! [`Settings`] is plain data (the "configuration"); the run-time state lives in
//! [`crate::runtime::Runtime`]. Every field is validated by [`Settings::validate`] and the
//! shaper they describe by [`Settings::tap_table`] before anything is applied.
//!
//! Units: positions in nm (the engine's counts), speeds in mm/s at the console.

use crate::engine::{NumericPath, TapError, TapTable};
use crate::shaper::{design, Impulse, Shaper, ShaperError, ShaperKind};

/// Shaper slots (modes) that can be convolved.
pub const MAX_MODES: usize = 4;
/// Impulses of a custom list loaded by the host.
pub const MAX_CUSTOM_IMPULSES: usize = 16;
/// Bytes of an encoded [`Settings`] record, at most.
pub const SETTINGS_MAX_BYTES: usize = 512;
/// Accepted tick rates (Hz).
pub const TICK_RATE_RANGE_HZ: (u32, u32) = (500, 10_000);

/// One mode's shaper: kind, natural frequency (Hz) and damping ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeSetting {
    /// Shaper kind (EI kinds carry V_tol).
    pub kind: ShaperKind,
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
}

/// Where the reference comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Point-to-point moves commanded from the console.
    Internal,
    /// The upstream controller's step/direction stream (timer in encoder mode).
    StepDir,
}

impl Source {
    /// `internal` or `stepdir`.
    pub fn name(self) -> &'static str {
        match self {
            Source::Internal => "internal",
            Source::StepDir => "stepdir",
        }
    }
}

/// All persistent parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Shaper per mode slot (convolved in slot order).
    pub modes: [Option<ModeSetting>; MAX_MODES],
    /// Custom impulse list from the host, convolved after the modes (empty = none).
    pub custom: heapless::Vec<Impulse, MAX_CUSTOM_IMPULSES>,
    /// Shaping on; off = identity.
    pub shaping_enabled: bool,
    /// Numeric path of the tick.
    pub path: NumericPath,
    /// Tick rate (Hz).
    pub tick_rate_hz: u32,
    /// Output resolution: nm per step pulse (default 1000 = 1 µm).
    pub step_nm: u32,
    /// Drive's maximum step input rate (steps/s).
    pub max_step_rate_hz: u32,
    /// Input resolution of the step/direction pass-through: nm per input count.
    pub input_nm_per_count: u32,
    /// Reference source.
    pub source: Source,
    /// Default move speed (mm/s).
    pub move_speed_mm_s: f32,
    /// Default move acceleration (mm/s²).
    pub move_accel_mm_s2: f32,
    /// DAC mirror full scale ± (mm).
    pub dac_span_mm: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings::DEFAULT
    }
}

/// Why settings were refused or could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConfigError {
    /// A shaper could not be designed.
    Shaper(ShaperError),
    /// The shaper cannot run at the tick rate / history.
    Taps(TapError),
    /// A field out of its range; names the field.
    Range(&'static str),
    /// Encoded record: wrong magic/version, truncated, or checksum mismatch.
    Corrupt,
    /// Buffer too small to encode.
    Buffer,
}

impl ConfigError {
    /// Short code for the console (`err <code>: …`).
    pub fn code(&self) -> &'static str {
        match self {
            ConfigError::Shaper(_) => "shaper",
            ConfigError::Taps(TapError::TooLong { .. }) => "too-long",
            ConfigError::Taps(_) => "shaper",
            ConfigError::Range(_) => "range",
            ConfigError::Corrupt => "corrupt",
            ConfigError::Buffer => "buffer",
        }
    }
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Shaper(e) => f.write_str(e.message()),
            ConfigError::Taps(TapError::TooLong { duration_s, max_s }) => write!(
                f,
                "shaper lasts {} s, the buffer holds {} s at this tick rate",
                crate::console::Num(*duration_s, 4),
                crate::console::Num(*max_s, 4)
            ),
            ConfigError::Taps(TapError::TickRate) => f.write_str("tick rate invalid"),
            ConfigError::Taps(TapError::AmplitudeRange) => {
                f.write_str("sum of |amplitudes| above 3.9")
            }
            ConfigError::Range(field) => write!(f, "{field} out of range"),
            ConfigError::Corrupt => {
                f.write_str("stored settings corrupt (magic, version or checksum)")
            }
            ConfigError::Buffer => f.write_str("buffer too small"),
        }
    }
}

impl Settings {
    /// Factory defaults: no mode set, shaping on, fixed point, 1 kHz, 1 µm per step,
    /// 200 kHz max step rate, internal moves at 100 mm/s and 1000 mm/s², DAC ±100 mm.
    pub const DEFAULT: Settings = Settings {
        modes: [None; MAX_MODES],
        custom: heapless::Vec::new(),
        shaping_enabled: true,
        path: NumericPath::Fixed,
        tick_rate_hz: 1000,
        step_nm: 1000,
        max_step_rate_hz: 200_000,
        input_nm_per_count: 1000,
        source: Source::Internal,
        move_speed_mm_s: 100.0,
        move_accel_mm_s2: 1000.0,
        dac_span_mm: 100.0,
    };

    /// Checks every scalar field's range (not the shaper; see [`Settings::tap_table`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let (lo, hi) = TICK_RATE_RANGE_HZ;
        if !(lo..=hi).contains(&self.tick_rate_hz) {
            return Err(ConfigError::Range("tick rate (500..10000 Hz)"));
        }
        if !(1..=1_000_000).contains(&self.step_nm) {
            return Err(ConfigError::Range("step size (1..1000000 nm)"));
        }
        if !(1..=1_000_000).contains(&self.input_nm_per_count) {
            return Err(ConfigError::Range("input resolution (1..1000000 nm)"));
        }
        if !(1..=50_000_000).contains(&self.max_step_rate_hz) {
            return Err(ConfigError::Range("max step rate (1..50000000 steps/s)"));
        }
        let pos = |v: f32| v.is_finite() && v > 0.0;
        if !pos(self.move_speed_mm_s) || self.move_speed_mm_s > 10_000.0 {
            return Err(ConfigError::Range("move speed (0..10000 mm/s)"));
        }
        if !pos(self.move_accel_mm_s2) || self.move_accel_mm_s2 > 1.0e6 {
            return Err(ConfigError::Range("move acceleration (0..1e6 mm/s^2)"));
        }
        if !pos(self.dac_span_mm) || self.dac_span_mm > 1000.0 {
            return Err(ConfigError::Range("dac span (0..1000 mm)"));
        }
        Ok(())
    }

    /// The shaper these settings describe: the convolution of every set mode, then the
    /// custom list (paper §4, multi-mode by convolution); the identity when shaping is off
    /// or nothing is set.
    pub fn shaper(&self) -> Result<Shaper, ConfigError> {
        let mut s = Shaper::identity();
        if !self.shaping_enabled {
            return Ok(s);
        }
        for m in self.modes.iter().flatten() {
            let one = design(m.kind, m.freq_hz, m.zeta).map_err(ConfigError::Shaper)?;
            s = s.convolve(&one).map_err(ConfigError::Shaper)?;
        }
        if !self.custom.is_empty() {
            let c = Shaper::from_impulses(&self.custom).map_err(ConfigError::Shaper)?;
            s = s.convolve(&c).map_err(ConfigError::Shaper)?;
        }
        Ok(s)
    }

    /// Validates everything and returns the tap table for a history of `history_len`
    /// samples at the settings' tick rate.
    ///
    /// Errors also when a set mode's natural frequency is at or above the tick's Nyquist
    /// frequency (tick rate / 2): the tick cannot represent it, the shaper would be meaningless.
    pub fn tap_table(&self, history_len: usize) -> Result<TapTable, ConfigError> {
        self.validate()?;
        let nyquist_hz = 0.5 * self.tick_rate_hz as f64;
        let below = |f: f64| f < nyquist_hz; // false for NaN too
        if self.modes.iter().flatten().any(|m| !below(m.freq_hz)) {
            return Err(ConfigError::Range(
                "mode frequency (must be below the tick's Nyquist frequency, tick rate / 2)",
            ));
        }
        let s = self.shaper()?;
        TapTable::from_shaper(&s, self.tick_rate_hz as f64, history_len).map_err(ConfigError::Taps)
    }

    /// Serialises into `buf` (little-endian, magic `BSH`, version, fields, CRC-32/ISO-HDLC
    /// of everything before it). Returns the number of bytes written.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, ConfigError> {
        let mut w = Writer { buf, pos: 0 };
        w.bytes(&MAGIC)?;
        w.u8(VERSION)?;
        for m in self.modes.iter() {
            match m {
                None => w.u8(0)?,
                Some(m) => {
                    w.u8(kind_code(m.kind))?;
                    w.f64(m.kind.v_tol().unwrap_or(0.0))?;
                    w.f64(m.freq_hz)?;
                    w.f64(m.zeta)?;
                }
            }
        }
        w.u8(self.custom.len() as u8)?;
        for i in self.custom.iter() {
            w.f64(i.amplitude)?;
            w.f64(i.time_s)?;
        }
        w.u8(self.shaping_enabled as u8)?;
        w.u8(match self.path {
            NumericPath::Fixed => 0,
            NumericPath::F32 => 1,
        })?;
        w.u32(self.tick_rate_hz)?;
        w.u32(self.step_nm)?;
        w.u32(self.max_step_rate_hz)?;
        w.u32(self.input_nm_per_count)?;
        w.u8(match self.source {
            Source::Internal => 0,
            Source::StepDir => 1,
        })?;
        w.f32(self.move_speed_mm_s)?;
        w.f32(self.move_accel_mm_s2)?;
        w.f32(self.dac_span_mm)?;
        let crc = CRC.checksum(w.buf.get(..w.pos).ok_or(ConfigError::Buffer)?);
        w.u32(crc)?;
        Ok(w.pos)
    }

    /// Parses a record written by [`Settings::encode`] and validates it (including the
    /// shaper design). Errors: [`ConfigError::Corrupt`] for a bad magic, version, length or
    /// checksum; any validation error for a record that decodes but is out of range.
    pub fn decode(bytes: &[u8]) -> Result<Settings, ConfigError> {
        if bytes.len() < 8 {
            return Err(ConfigError::Corrupt);
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        let crc = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if CRC.checksum(body) != crc {
            return Err(ConfigError::Corrupt);
        }
        let mut r = Reader { buf: body, pos: 0 };
        if r.take(3)? != MAGIC || r.u8()? != VERSION {
            return Err(ConfigError::Corrupt);
        }
        let mut s = Settings::DEFAULT;
        for slot in s.modes.iter_mut() {
            let code = r.u8()?;
            if code != 0 {
                let v_tol = r.f64()?;
                let kind = kind_from_code(code, v_tol).ok_or(ConfigError::Corrupt)?;
                *slot = Some(ModeSetting {
                    kind,
                    freq_hz: r.f64()?,
                    zeta: r.f64()?,
                });
            }
        }
        let n = r.u8()? as usize;
        for _ in 0..n {
            let imp = Impulse {
                amplitude: r.f64()?,
                time_s: r.f64()?,
            };
            s.custom.push(imp).map_err(|_| ConfigError::Corrupt)?;
        }
        s.shaping_enabled = r.u8()? != 0;
        s.path = match r.u8()? {
            0 => NumericPath::Fixed,
            1 => NumericPath::F32,
            _ => return Err(ConfigError::Corrupt),
        };
        s.tick_rate_hz = r.u32()?;
        s.step_nm = r.u32()?;
        s.max_step_rate_hz = r.u32()?;
        s.input_nm_per_count = r.u32()?;
        s.source = match r.u8()? {
            0 => Source::Internal,
            1 => Source::StepDir,
            _ => return Err(ConfigError::Corrupt),
        };
        s.move_speed_mm_s = r.f32()?;
        s.move_accel_mm_s2 = r.f32()?;
        s.dac_span_mm = r.f32()?;
        if r.pos != body.len() {
            return Err(ConfigError::Corrupt);
        }
        s.validate()?;
        s.shaper()?;
        Ok(s)
    }
}

const MAGIC: [u8; 3] = *b"BSH";
const VERSION: u8 = 1;
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

fn kind_code(k: ShaperKind) -> u8 {
    match k {
        ShaperKind::Zv => 1,
        ShaperKind::Zvd => 2,
        ShaperKind::Zvdd => 3,
        ShaperKind::Zvddd => 4,
        ShaperKind::Mzv => 5,
        ShaperKind::Ei { .. } => 6,
        ShaperKind::Ei2Hump { .. } => 7,
        ShaperKind::Ei3Hump { .. } => 8,
        ShaperKind::UmZv => 9,
    }
}

fn kind_from_code(c: u8, v_tol: f64) -> Option<ShaperKind> {
    Some(match c {
        1 => ShaperKind::Zv,
        2 => ShaperKind::Zvd,
        3 => ShaperKind::Zvdd,
        4 => ShaperKind::Zvddd,
        5 => ShaperKind::Mzv,
        6 => ShaperKind::Ei { v_tol },
        7 => ShaperKind::Ei2Hump { v_tol },
        8 => ShaperKind::Ei3Hump { v_tol },
        9 => ShaperKind::UmZv,
        _ => return None,
    })
}

struct Writer<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) -> Result<(), ConfigError> {
        let end = self.pos + b.len();
        self.buf
            .get_mut(self.pos..end)
            .ok_or(ConfigError::Buffer)?
            .copy_from_slice(b);
        self.pos = end;
        Ok(())
    }
    fn u8(&mut self, v: u8) -> Result<(), ConfigError> {
        self.bytes(&[v])
    }
    fn u32(&mut self, v: u32) -> Result<(), ConfigError> {
        self.bytes(&v.to_le_bytes())
    }
    fn f32(&mut self, v: f32) -> Result<(), ConfigError> {
        self.bytes(&v.to_le_bytes())
    }
    fn f64(&mut self, v: f64) -> Result<(), ConfigError> {
        self.bytes(&v.to_le_bytes())
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], ConfigError> {
        let s = self
            .buf
            .get(self.pos..self.pos + n)
            .ok_or(ConfigError::Corrupt)?;
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, ConfigError> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, ConfigError> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn f32(&mut self) -> Result<f32, ConfigError> {
        Ok(f32::from_bits(self.u32()?))
    }
    fn f64(&mut self) -> Result<f64, ConfigError> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }
}
