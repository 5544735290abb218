//! ADXL357 3-axis accelerometer (20-bit, ±10/20/40 g) over SPI: register map, init sequence,
//! device-id check, FIFO reading, raw LSB → m/s² and saturation. The chip of the real
//! cantilever recordings.
//!
//! Source: Analog Devices, *ADXL356/ADXL357 Low Noise, Low Drift, Low Power, 3-Axis MEMS
//! Accelerometers*, data sheet Rev. A: "SPI Protocol" (mode 0, ≤ 10 MHz; the command byte is
//! the register address shifted left by one with the read bit in bit 0; multi-byte reads
//! auto-increment, except at FIFO_DATA, which returns successive FIFO entries),
//! "Register Map" (0x00 DEVID_AD = 0xAD, 0x01 DEVID_MST = 0x1D, 0x02 PARTID = 0xED, 0x04 STATUS,
//! 0x05 FIFO_ENTRIES, 0x11 FIFO_DATA, 0x28 FILTER, 0x2C RANGE, 0x2D POWER_CTL), "Data Format"
//! (20-bit two's complement, left-justified in three bytes DATA3..DATA1; in FIFO data bit 0 of
//! the third byte marks an x-axis entry and bit 1 an empty FIFO) and "Specifications"
//! (sensitivity 51 200 / 25 600 / 12 800 LSB/g at ±10 / 20 / 40 g, i.e. 19.5 / 39 / 78 µg).
//!
//! The FIFO holds 96 axis entries = 32 samples (x, y, z); the driver reads one sample (9
//! bytes) per transaction and checks the x marker, so a stream that lost its alignment is
//! re-synchronised on the next x entry and reported as [`SensorEvent::Lost`].
//! **Default range ±10 g:** unlike the ADXL345, a wider range here costs resolution (the
//! output is always 20 bits), and a beam tip in a shaped move stays far below 10 g.
//! Same async `SpiDevice` choice as [`super::adxl345`] (DMA on the board, mock on the host).

use super::adxl345::{Adxl345Error, Axis, FifoRead, G0_M_S2};
use super::{AccelConfig, AccelSample, SensorEvent};
use embedded_hal_async::spi::{Operation, SpiDevice};

/// Register addresses (data sheet "Register Map").
pub mod reg {
    /// Analog Devices ID, reads 0xAD.
    pub const DEVID_AD: u8 = 0x00;
    /// Status (bit 2 = FIFO_OVR, bit 1 = FIFO_FULL, bit 0 = DATA_RDY).
    pub const STATUS: u8 = 0x04;
    /// FIFO_ENTRIES: valid axis entries in the FIFO (0 ..= 96); follows STATUS.
    pub const FIFO_ENTRIES: u8 = 0x05;
    /// FIFO_DATA: reading it pops FIFO entries (no address auto-increment).
    pub const FIFO_DATA: u8 = 0x11;
    /// Filter: high-pass corner (bits 6:4), output data rate and low-pass (bits 3:0).
    pub const FILTER: u8 = 0x28;
    /// Range (bits 1:0).
    pub const RANGE: u8 = 0x2C;
    /// Power control (bit 0 = standby, bit 1 = temperature off).
    pub const POWER_CTL: u8 = 0x2D;
}

/// DEVID_AD, DEVID_MST, PARTID of the ADXL357 (registers 0x00..0x02).
pub const DEVICE_ID: [u8; 3] = [0xAD, 0x1D, 0xED];
/// Axis entries the FIFO holds (32 samples × 3 axes).
pub const FIFO_AXIS_ENTRIES: u8 = 96;
/// STATUS bit: the FIFO overran (samples were lost).
pub const STATUS_FIFO_OVR: u8 = 0x04;
/// POWER_CTL value for measuring with the temperature sensor off.
pub const POWER_MEASURE: u8 = 0x02;
/// The nominal range in LSB, the same at every range (data sheet sensitivities).
pub const NOMINAL_RANGE_LSB: u32 = 512_000;
/// POWER_CTL value for standby.
pub const POWER_STANDBY: u8 = 0x01;

/// Measurement ranges (RANGE bits 1:0) with their sensitivity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// ±10 g, 51 200 LSB/g (code 01).
    G10,
    /// ±20 g, 25 600 LSB/g (code 10).
    G20,
    /// ±40 g, 12 800 LSB/g (code 11).
    G40,
}

impl Range {
    /// The RANGE register value.
    pub fn code(self) -> u8 {
        match self {
            Range::G10 => 0x01,
            Range::G20 => 0x02,
            Range::G40 => 0x03,
        }
    }

    /// The nominal range (g).
    pub fn g(self) -> f32 {
        match self {
            Range::G10 => 10.0,
            Range::G20 => 20.0,
            Range::G40 => 40.0,
        }
    }

    /// One LSB (m/s²): g₀ / sensitivity (typical) = g₀ × range / 512 000 (the nominal range
    /// is 512 000 LSB at every range: 10 g × 51 200, 20 g × 25 600, 40 g × 12 800).
    pub fn lsb_m_s2(self) -> f32 {
        G0_M_S2 * self.g() / NOMINAL_RANGE_LSB as f32
    }
}

/// Output data rates (FILTER bits 3:0; the low-pass corner is a quarter of the rate).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Odr {
    /// 4 000 Hz (code 0000).
    Hz4000,
    /// 2 000 Hz (0001).
    Hz2000,
    /// 1 000 Hz (0010).
    Hz1000,
    /// 500 Hz (0011).
    Hz500,
}

impl Odr {
    /// The FILTER register value (high-pass filter off).
    pub fn code(self) -> u8 {
        match self {
            Odr::Hz4000 => 0,
            Odr::Hz2000 => 1,
            Odr::Hz1000 => 2,
            Odr::Hz500 => 3,
        }
    }

    /// The output data rate (Hz).
    pub fn hz(self) -> f32 {
        match self {
            Odr::Hz4000 => 4000.0,
            Odr::Hz2000 => 2000.0,
            Odr::Hz1000 => 1000.0,
            Odr::Hz500 => 500.0,
        }
    }
}

/// How the driver runs the chip and which axis it reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adxl357Config {
    /// Output data rate.
    pub odr: Odr,
    /// Measurement range.
    pub range: Range,
    /// The chip axis along the beam's bending direction.
    pub axis: Axis,
    /// Negate the watched axis.
    pub invert: bool,
    /// Consecutive empty FIFO reads before [`Adxl345Error::Stalled`] (as for the ADXL345:
    /// at 4 000 Hz the 32-sample FIFO holds 8 ms).
    pub stall_after_empty_reads: u8,
}

impl Adxl357Config {
    /// 4 000 Hz, ±10 g, watched axis X, not inverted, stalled after 3 empty reads.
    pub const DEFAULT: Adxl357Config = Adxl357Config {
        odr: Odr::Hz4000,
        range: Range::G10,
        axis: Axis::X,
        invert: false,
        stall_after_empty_reads: 3,
    };

    /// The [`AccelConfig`] of the stream: rate (Hz), nominal range (m/s²), one LSB (m/s²).
    pub fn accel_config(&self) -> AccelConfig {
        AccelConfig {
            rate_hz: self.odr.hz(),
            full_scale_m_s2: self.range.g() * G0_M_S2,
            lsb_m_s2: self.range.lsb_m_s2(),
        }
    }
}

/// The 20-bit reading of one 3-byte entry (DATA3, DATA2, DATA1), sign-extended (LSB).
pub fn raw20(b: [u8; 3]) -> i32 {
    let v = ((b[0] as u32) << 24) | ((b[1] as u32) << 16) | (((b[2] & 0xF0) as u32) << 8);
    (v as i32) >> 12
}

/// The watched axis of one sample `[x, y, z]` (LSB) in m/s². Saturated at or beyond the
/// nominal range (|raw| ≥ [`NOMINAL_RANGE_LSB`], e.g. ≥ 10 g at ±10 g), where the data sheet
/// no longer specifies the reading (the 20-bit code itself ends at ±524 288).
pub fn convert_raw(config: &Adxl357Config, raw: [i32; 3]) -> AccelSample {
    let v = match config.axis {
        Axis::X => raw[0],
        Axis::Y => raw[1],
        Axis::Z => raw[2],
    };
    let acc = v as f32 * config.range.lsb_m_s2();
    AccelSample {
        acc_m_s2: if config.invert { -acc } else { acc },
        saturated: v.unsigned_abs() >= NOMINAL_RANGE_LSB,
    }
}

/// ADXL357 on an async SPI device (mode 0, ≤ 10 MHz).
pub struct Adxl357<S> {
    spi: S,
    config: Adxl357Config,
    empty_reads: u8,
}

impl<S: SpiDevice> Adxl357<S> {
    /// A driver for the chip behind `spi`; nothing is sent until [`Adxl357::init`].
    pub fn new(spi: S, config: Adxl357Config) -> Self {
        Adxl357 {
            spi,
            config,
            empty_reads: 0,
        }
    }

    /// Gives the SPI device back.
    pub fn release(self) -> S {
        self.spi
    }

    /// Reads `buf.len()` bytes from `reg` on (one transaction; auto-increment, except at
    /// FIFO_DATA). Errors: [`Adxl345Error::Bus`].
    async fn read(&mut self, reg: u8, buf: &mut [u8]) -> Result<(), Adxl345Error<S::Error>> {
        let cmd = [(reg << 1) | 1];
        self.spi
            .transaction(&mut [Operation::Write(&cmd), Operation::Read(buf)])
            .await
            .map_err(Adxl345Error::Bus)
    }

    /// Writes one register. Errors: [`Adxl345Error::Bus`].
    pub async fn write_register(
        &mut self,
        reg: u8,
        value: u8,
    ) -> Result<(), Adxl345Error<S::Error>> {
        self.spi
            .write(&[reg << 1, value])
            .await
            .map_err(Adxl345Error::Bus)
    }

    /// Reads DEVID_AD, DEVID_MST and PARTID: [`DEVICE_ID`] for an ADXL357 (the ADXL355 reads
    /// the same; it differs in range). Errors: [`Adxl345Error::Bus`].
    pub async fn device_id(&mut self) -> Result<[u8; 3], Adxl345Error<S::Error>> {
        let mut id = [0; 3];
        self.read(reg::DEVID_AD, &mut id).await?;
        Ok(id)
    }

    /// Checks the ids and configures the chip: standby, RANGE, FILTER (rate, high-pass off),
    /// both read back, then measure (temperature off). Returns the stream's
    /// [`AccelConfig`]. Errors: [`Adxl345Error::WrongId`] (the DEVID_AD or the first
    /// mismatching id byte), [`Adxl345Error::Readback`], [`Adxl345Error::Bus`].
    pub async fn init(&mut self) -> Result<AccelConfig, Adxl345Error<S::Error>> {
        self.empty_reads = 0;
        let id = self.device_id().await?;
        if let Some(i) = (0..3).find(|&i| id[i] != DEVICE_ID[i]) {
            return Err(Adxl345Error::WrongId(id[i]));
        }
        self.write_register(reg::POWER_CTL, POWER_STANDBY).await?;
        let writes = [
            (reg::RANGE, self.config.range.code()),
            (reg::FILTER, self.config.odr.code()),
        ];
        for (r, v) in writes {
            self.write_register(r, v).await?;
        }
        for (r, wrote) in writes {
            let mut read = [0];
            self.read(r, &mut read).await?;
            // RANGE bits 7:6 (I2C speed, interrupt polarity) are not ours to check.
            let read = if r == reg::RANGE {
                read[0] & 0x03
            } else {
                read[0]
            };
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

    /// Drains the FIFO once: reads STATUS and FIFO_ENTRIES, then each whole sample (9 bytes
    /// of FIFO_DATA, x entry first) and hands `sink` one [`SensorEvent::Sample`] per sample,
    /// oldest first. An overrun (STATUS.FIFO_OVR) or a sample whose x marker is missing
    /// (the stream lost its alignment; re-synchronised on the next x entry, at most the
    /// entries counted) gives a [`SensorEvent::Lost`] first. At most 32 samples per call.
    ///
    /// Errors: as [`super::adxl345::Adxl345::read_fifo`] (bus, FIFO_ENTRIES > 96, stalled).
    pub async fn read_fifo(
        &mut self,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<FifoRead, Adxl345Error<S::Error>> {
        let mut st = [0u8; 2];
        self.read(reg::STATUS, &mut st).await?;
        let entries = st[1] & 0x7F;
        if entries > FIFO_AXIS_ENTRIES {
            return Err(Adxl345Error::Status(st[1]));
        }
        if entries < 3 {
            self.empty_reads = self.empty_reads.saturating_add(1);
            if self.empty_reads >= self.config.stall_after_empty_reads.max(1) {
                self.empty_reads = 0;
                return Err(Adxl345Error::Stalled);
            }
            return Ok(FifoRead::default());
        }
        self.empty_reads = 0;
        let mut out = FifoRead {
            overrun: st[0] & STATUS_FIFO_OVR != 0,
            ..FifoRead::default()
        };
        if out.overrun {
            sink(SensorEvent::Lost);
        }
        let mut left = entries;
        while left >= 3 {
            let Some(raw) = self.read_sample(&mut left, sink).await? else {
                break;
            };
            let s = convert_raw(&self.config, raw);
            out.samples += 1;
            out.saturated += s.saturated as u8;
            sink(SensorEvent::Sample(s));
        }
        Ok(out)
    }

    /// Pops one sample (x, y, z) from the FIFO, `left` counting the axis entries still in
    /// it. A sample without the x marker on its first entry is dropped entry by entry until
    /// an x entry (one [`SensorEvent::Lost`] to `sink`); `None` when the FIFO reads empty
    /// or too few entries remain.
    async fn read_sample(
        &mut self,
        left: &mut u8,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<Option<[i32; 3]>, Adxl345Error<S::Error>> {
        let mut b = [0u8; 9];
        self.read(reg::FIFO_DATA, &mut b).await?;
        *left -= 3;
        let mut lost = false;
        let empty = |b: &[u8; 9]| b[2] & 0x02 != 0 || b[5] & 0x02 != 0 || b[8] & 0x02 != 0;
        let aligned = |b: &[u8; 9]| b[2] & 0x01 != 0 && b[5] & 0x01 == 0 && b[8] & 0x01 == 0;
        // Re-synchronise: shift in single entries until the first of the three is an x entry.
        while !aligned(&b) {
            if empty(&b) || *left == 0 {
                return Ok(None);
            }
            if !lost {
                sink(SensorEvent::Lost);
                lost = true;
            }
            b.copy_within(3.., 0);
            let mut e = [0u8; 3];
            self.read(reg::FIFO_DATA, &mut e).await?;
            b[6..].copy_from_slice(&e);
            *left -= 1;
        }
        if empty(&b) {
            return Ok(None);
        }
        Ok(Some([
            raw20([b[0], b[1], b[2]]),
            raw20([b[3], b[4], b[5]]),
            raw20([b[6], b[7], b[8]]),
        ]))
    }
}
