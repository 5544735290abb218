//! ADXL345 3-axis accelerometer over 4-wire SPI: register map, init sequence, device-id
//! check, FIFO reading in stream mode, raw LSB → m/s² and saturation.
//!
//! Source: Analog Devices, *ADXL345 Digital Accelerometer*, data sheet Rev. G (D07925-0-5/13):
//! "Serial Communications → SPI" (mode 3, ≤ 5 MHz, read bit 7, multi-byte bit 6; ≥ 2 MHz
//! recommended at 3 200 Hz and 1 600 Hz), Table 19 "Register Map" and "Register Definitions"
//! (0x2C BW_RATE, 0x2D POWER_CTL, 0x31 DATA_FORMAT, 0x38 FIFO_CTL, 0x39 FIFO_STATUS),
//! "FIFO" (stream mode, 32 entries, "Retrieving Data from FIFO": each entry is one 6-byte
//! multi-byte read of DATAX0..DATAZ1, and at least 5 µs must pass between the end of reading
//! the data registers and the next read of the FIFO or of FIFO_STATUS) and Table 1
//! (full-resolution scale factor 3.9 mg/LSB typical at every range).
//!
//! The chip runs as Klipper runs it: full resolution, ±16 g (DATA_FORMAT = 0x0B), 3 200 Hz
//! (BW_RATE = 0x0F), FIFO in stream mode. **Why ±16 g:** in full-resolution mode the scale
//! factor is 3.9 mg/LSB at *every* range (the output grows from 10 to 13 bits instead), so the
//! widest range costs no resolution and leaves the most headroom before a reading saturates.
//!
//! **Why `embedded-hal-async`'s `SpiDevice`:** on the board the reader is an embassy task
//! whose SPI transfers run by DMA; an async device lets the executor run other tasks while
//! a FIFO burst (≈ 32 × 7 bytes at 5 MHz) is on the bus, and the blocking adapters of
//! embedded-hal 1.0 would busy-wait instead. On the host the same code runs on a mock with
//! any `block_on`.
//!
//! The driver never panics and holds no buffer beyond one 7-byte transfer; every result
//! reaches the caller as a [`SensorEvent`] through a sink closure, in order.

use super::{AccelConfig, AccelSample, SensorEvent};
use embedded_hal_async::spi::{Operation, SpiDevice};

/// Register addresses (data sheet Table 19).
pub mod reg {
    /// Device ID, reads [`super::DEVICE_ID`].
    pub const DEVID: u8 = 0x00;
    /// Data rate and power mode control.
    pub const BW_RATE: u8 = 0x2C;
    /// Power-saving features control (bit 3 = Measure).
    pub const POWER_CTL: u8 = 0x2D;
    /// Interrupt enable control.
    pub const INT_ENABLE: u8 = 0x2E;
    /// Data format control (self test, SPI mode, full resolution, justify, range).
    pub const DATA_FORMAT: u8 = 0x31;
    /// X-axis data 0 (low byte); DATAX1, DATAY0, DATAY1, DATAZ0, DATAZ1 follow.
    pub const DATAX0: u8 = 0x32;
    /// FIFO control (mode, trigger, samples = watermark).
    pub const FIFO_CTL: u8 = 0x38;
    /// FIFO status (bit 7 = trigger, bits 5:0 = entries).
    pub const FIFO_STATUS: u8 = 0x39;
}

/// The fixed device ID of the ADXL345 (register 0x00).
pub const DEVICE_ID: u8 = 0xE5;
/// Address byte bit 7: read.
pub const SPI_READ: u8 = 0x80;
/// Address byte bit 6: multi-byte transfer.
pub const SPI_MULTI: u8 = 0x40;
/// POWER_CTL value that starts measuring (Measure bit, no sleep or auto-sleep).
pub const POWER_MEASURE: u8 = 0x08;
/// DATA_FORMAT value: 4-wire SPI, active-high interrupts, FULL_RES, right-justified, ±16 g.
pub const FORMAT_FULL_RES_16G: u8 = 0x0B;
/// FIFO_CTL mode bits for stream mode (bits 7:6 = 10).
pub const FIFO_STREAM: u8 = 0x80;
/// Entries the FIFO holds ("FIFO": 32, plus one more held at the output, so up to 33 can
/// be read at a time). FIFO_STATUS at 32 or more means the FIFO is full.
pub const FIFO_ENTRIES: u8 = 32;
/// The most entries FIFO_STATUS can plausibly report (32 in the FIFO + 1 at the output).
pub const FIFO_MAX_READABLE: u8 = 33;
/// Data sheet minimum between the end of a FIFO data read and the next FIFO or FIFO_STATUS
/// read (ns); appended to every FIFO pop as an `Operation::DelayNs`.
pub const FIFO_POP_GAP_NS: u32 = 5_000;
/// Standard gravity (m/s²) for the mg → m/s² conversion.
pub const G0_M_S2: f32 = 9.806_65;
/// Full-resolution scale factor, typical (g/LSB): 3.9 mg/LSB (Table 1).
pub const FULL_RES_G_PER_LSB: f32 = 0.0039;
/// The 13-bit range of a ±16 g full-resolution reading: −4096 ..= 4095 LSB.
pub const RAW_MIN: i16 = -4096;
/// See [`RAW_MIN`].
pub const RAW_MAX: i16 = 4095;

/// Output data rates (BW_RATE rate code, data sheet Table 7, normal power).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rate {
    /// 3 200 Hz (code 0x0F; bandwidth 1 600 Hz).
    Hz3200,
    /// 1 600 Hz (0x0E).
    Hz1600,
    /// 800 Hz (0x0D).
    Hz800,
    /// 400 Hz (0x0C).
    Hz400,
    /// 200 Hz (0x0B).
    Hz200,
    /// 100 Hz (0x0A).
    Hz100,
}

impl Rate {
    /// The BW_RATE register value (LOW_POWER = 0).
    pub fn code(self) -> u8 {
        match self {
            Rate::Hz3200 => 0x0F,
            Rate::Hz1600 => 0x0E,
            Rate::Hz800 => 0x0D,
            Rate::Hz400 => 0x0C,
            Rate::Hz200 => 0x0B,
            Rate::Hz100 => 0x0A,
        }
    }

    /// The output data rate (Hz).
    pub fn hz(self) -> f32 {
        match self {
            Rate::Hz3200 => 3200.0,
            Rate::Hz1600 => 1600.0,
            Rate::Hz800 => 800.0,
            Rate::Hz400 => 400.0,
            Rate::Hz200 => 200.0,
            Rate::Hz100 => 100.0,
        }
    }
}

/// A chip axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// X (DATAX0/1).
    X,
    /// Y (DATAY0/1).
    Y,
    /// Z (DATAZ0/1).
    Z,
}

/// How the driver runs the chip and which axis it reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adxl345Config {
    /// Output data rate.
    pub rate: Rate,
    /// The chip axis along the beam's bending direction (the watched axis).
    pub axis: Axis,
    /// Negate the watched axis, so that positive is the beam's positive direction.
    pub invert: bool,
    /// Scale factor (m/s² per LSB); default 3.9 mg/LSB × g₀ = 0.038 246 m/s².
    pub lsb_m_s2: f32,
    /// Consecutive FIFO reads that found it empty before the chip counts as stopped
    /// ([`Adxl345Error::Stalled`]). The caller chooses it from its read period: at 3 200 Hz
    /// and a 4 ms period, 3 empty reads (12 ms) exceed what the 32-entry FIFO holds (10 ms).
    pub stall_after_empty_reads: u8,
}

impl Adxl345Config {
    /// 3 200 Hz, watched axis X, not inverted, typical scale, stalled after 3 empty reads.
    pub const DEFAULT: Adxl345Config = Adxl345Config {
        rate: Rate::Hz3200,
        axis: Axis::X,
        invert: false,
        lsb_m_s2: FULL_RES_G_PER_LSB * G0_M_S2,
        stall_after_empty_reads: 3,
    };

    /// The [`AccelConfig`] of the sample stream: rate (Hz), full scale = 4 096 LSB (m/s²),
    /// one LSB (m/s²).
    pub fn accel_config(&self) -> AccelConfig {
        AccelConfig {
            rate_hz: self.rate.hz(),
            full_scale_m_s2: 4096.0 * self.lsb_m_s2,
            lsb_m_s2: self.lsb_m_s2,
        }
    }
}

/// What went wrong. Every error means the sample stream is broken: the caller reports
/// [`SensorEvent::Lost`] (see [`Adxl345Error::event`]) and runs [`Adxl345::init`] again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Adxl345Error<E> {
    /// The SPI device reported an error.
    Bus(E),
    /// Register 0x00 did not read 0xE5 (the byte found): no chip, another chip, or a bus
    /// stuck at 0x00/0xFF.
    WrongId(u8),
    /// A configuration register read back differently (register, written, read).
    Readback {
        /// Register address.
        reg: u8,
        /// Value written.
        wrote: u8,
        /// Value read back.
        read: u8,
    },
    /// FIFO_STATUS reported more than 33 entries (the byte read): the bus is not talking to
    /// an ADXL345.
    Status(u8),
    /// The FIFO was empty on [`Adxl345Config::stall_after_empty_reads`] reads in a row:
    /// the chip is not measuring (reset, power loss, or no chip on a bus stuck at 0x00).
    Stalled,
}

impl<E> Adxl345Error<E> {
    /// The event that marks this error in the sample stream: always [`SensorEvent::Lost`].
    pub fn event(&self) -> SensorEvent {
        SensorEvent::Lost
    }
}

/// What one [`Adxl345::read_fifo`] delivered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FifoRead {
    /// Samples delivered (0 ..= 33).
    pub samples: u8,
    /// The FIFO was full (32 or 33 entries): in stream mode the oldest entries may have been
    /// overwritten, so a [`SensorEvent::Lost`] was delivered before the samples.
    pub overrun: bool,
    /// Samples at or beyond full scale on the watched axis.
    pub saturated: u8,
}

/// ADXL345 on an async SPI device (mode 3, ≤ 5 MHz).
pub struct Adxl345<S> {
    spi: S,
    config: Adxl345Config,
    empty_reads: u8,
}

impl<S: SpiDevice> Adxl345<S> {
    /// A driver for the chip behind `spi`; nothing is sent until [`Adxl345::init`].
    pub fn new(spi: S, config: Adxl345Config) -> Self {
        Adxl345 {
            spi,
            config,
            empty_reads: 0,
        }
    }

    /// The driver's configuration.
    pub fn config(&self) -> &Adxl345Config {
        &self.config
    }

    /// Gives the SPI device back.
    pub fn release(self) -> S {
        self.spi
    }

    /// Reads one register (one transaction: address byte with the read bit, one data byte).
    ///
    /// Errors: [`Adxl345Error::Bus`].
    pub async fn read_register(&mut self, reg: u8) -> Result<u8, Adxl345Error<S::Error>> {
        let mut buf = [SPI_READ | (reg & 0x3F), 0];
        self.spi
            .transfer_in_place(&mut buf)
            .await
            .map_err(Adxl345Error::Bus)?;
        Ok(buf[1])
    }

    /// Writes one register (one transaction: address byte, data byte).
    ///
    /// Errors: [`Adxl345Error::Bus`].
    pub async fn write_register(
        &mut self,
        reg: u8,
        value: u8,
    ) -> Result<(), Adxl345Error<S::Error>> {
        self.spi
            .write(&[reg & 0x3F, value])
            .await
            .map_err(Adxl345Error::Bus)
    }

    /// Reads register 0x00: 0xE5 for an ADXL345 (anything else: not one, or no chip).
    ///
    /// Errors: [`Adxl345Error::Bus`].
    pub async fn device_id(&mut self) -> Result<u8, Adxl345Error<S::Error>> {
        self.read_register(reg::DEVID).await
    }

    /// Checks the device id and configures the chip: standby, DATA_FORMAT = 0x0B (full
    /// resolution, ±16 g), BW_RATE = the rate code, interrupts off, FIFO bypass (clears it)
    /// then stream mode, both format and rate read back, then Measure. Can be called again at
    /// any time (after an error) to restart the stream.
    ///
    /// Returns the [`AccelConfig`] of the samples that follow. Errors:
    /// [`Adxl345Error::WrongId`], [`Adxl345Error::Readback`], [`Adxl345Error::Bus`].
    pub async fn init(&mut self) -> Result<AccelConfig, Adxl345Error<S::Error>> {
        self.empty_reads = 0;
        let id = self.device_id().await?;
        if id != DEVICE_ID {
            return Err(Adxl345Error::WrongId(id));
        }
        self.write_register(reg::POWER_CTL, 0).await?;
        self.write_register(reg::DATA_FORMAT, FORMAT_FULL_RES_16G)
            .await?;
        self.write_register(reg::BW_RATE, self.config.rate.code())
            .await?;
        self.write_register(reg::INT_ENABLE, 0).await?;
        self.write_register(reg::FIFO_CTL, 0).await?;
        self.write_register(reg::FIFO_CTL, FIFO_STREAM).await?;
        for (r, wrote) in [
            (reg::DATA_FORMAT, FORMAT_FULL_RES_16G),
            (reg::BW_RATE, self.config.rate.code()),
        ] {
            let read = self.read_register(r).await?;
            if read != wrote {
                return Err(Adxl345Error::Readback {
                    reg: r,
                    wrote,
                    read,
                });
            }
        }
        self.write_register(reg::POWER_CTL, POWER_MEASURE).await?;
        Ok(self.config.accel_config())
    }

    /// Puts the chip in standby (POWER_CTL = 0).
    ///
    /// Errors: [`Adxl345Error::Bus`].
    pub async fn standby(&mut self) -> Result<(), Adxl345Error<S::Error>> {
        self.write_register(reg::POWER_CTL, 0).await
    }

    /// Drains the FIFO once: reads FIFO_STATUS, then each of its entries (one 6-byte
    /// multi-byte read of DATAX0..DATAZ1 per entry, each followed by the 5 µs gap), and hands
    /// `sink` one [`SensorEvent::Sample`] per entry, oldest first. A full FIFO (≥ 32 entries)
    /// may have overwritten samples: `sink` gets [`SensorEvent::Lost`] first. At most 33
    /// entries per call, so the work is bounded; call it at least once per 32 sample periods
    /// (10 ms at 3 200 Hz).
    ///
    /// Errors (the caller reports [`SensorEvent::Lost`] and calls [`Adxl345::init`]):
    /// [`Adxl345Error::Bus`]; [`Adxl345Error::Status`] (more than 33 entries);
    /// [`Adxl345Error::Stalled`] (empty too many times in a row). Samples delivered before a
    /// bus error mid-burst are valid.
    pub async fn read_fifo(
        &mut self,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<FifoRead, Adxl345Error<S::Error>> {
        let status = self.read_register(reg::FIFO_STATUS).await?;
        let entries = status & 0x3F;
        if entries > FIFO_MAX_READABLE {
            return Err(Adxl345Error::Status(status));
        }
        if entries == 0 {
            self.empty_reads = self.empty_reads.saturating_add(1);
            if self.empty_reads >= self.config.stall_after_empty_reads.max(1) {
                self.empty_reads = 0;
                return Err(Adxl345Error::Stalled);
            }
            return Ok(FifoRead::default());
        }
        self.empty_reads = 0;
        let mut read = FifoRead {
            overrun: entries >= FIFO_ENTRIES,
            ..FifoRead::default()
        };
        if read.overrun {
            sink(SensorEvent::Lost);
        }
        for _ in 0..entries {
            let raw = self.read_entry().await?;
            let sample = self.convert(raw);
            read.samples += 1;
            read.saturated += sample.saturated as u8;
            sink(SensorEvent::Sample(sample));
        }
        Ok(read)
    }

    /// Pops one FIFO entry: the raw X, Y, Z readings (LSB, sign-extended right-justified).
    async fn read_entry(&mut self) -> Result<[i16; 3], Adxl345Error<S::Error>> {
        let mut buf = [0u8; 7];
        buf[0] = SPI_READ | SPI_MULTI | reg::DATAX0;
        self.spi
            .transaction(&mut [
                Operation::TransferInPlace(&mut buf),
                Operation::DelayNs(FIFO_POP_GAP_NS),
            ])
            .await
            .map_err(Adxl345Error::Bus)?;
        Ok([
            i16::from_le_bytes([buf[1], buf[2]]),
            i16::from_le_bytes([buf[3], buf[4]]),
            i16::from_le_bytes([buf[5], buf[6]]),
        ])
    }

    /// The watched axis of one raw entry, in m/s², with its saturation flag.
    pub fn convert(&self, raw: [i16; 3]) -> AccelSample {
        convert_raw(&self.config, raw)
    }
}

/// The watched axis of one raw entry `[x, y, z]` (LSB, ±16 g full resolution) in m/s²:
/// `raw × lsb_m_s2`, negated if `invert`. Saturated when the raw value is at either end of
/// the 13-bit range (≤ −4096 or ≥ 4095 LSB, i.e. at or beyond ≈ ±16 g).
pub fn convert_raw(config: &Adxl345Config, raw: [i16; 3]) -> AccelSample {
    let v = match config.axis {
        Axis::X => raw[0],
        Axis::Y => raw[1],
        Axis::Z => raw[2],
    };
    let acc = v as f32 * config.lsb_m_s2;
    AccelSample {
        acc_m_s2: if config.invert { -acc } else { acc },
        saturated: v <= RAW_MIN || v >= RAW_MAX,
    }
}
