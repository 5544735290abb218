//! Tip accelerometer readings, as a sensor driver delivers them and the watch consumes them.
//!
//! This module is the contract between the two: a driver (for example the ADXL345 over SPI,
//! read by a task into a ring buffer, never in the tick interrupt) produces [`SensorEvent`]s at
//! the chip's output data rate described by [`AccelConfig`]; the drift watch consumes them.
//! Units are SI: accelerations in m/s², rates in Hz.
//!
//! - [`adxl345`]: the ADXL345 driver (SPI, FIFO in stream mode, 3 200 Hz, ±16 g).
//! - [`adxl357`]: the ADXL357 driver (SPI, 20 bits, FIFO, 4 000 Hz, ±10 g), host-tested;
//!   the firmware reads the ADXL345.
//! - [`FifoAccelerometer`]: what a reader loop needs of either driver.
//! - [`EventGate`]: the producer's side of a bounded queue of events: a sample that does not
//!   fit marks the stream broken ([`SensorEvent::Lost`]) instead of vanishing.
//! - [`SensorHealth`]: counters over a stream of events (the firmware's consumer until the
//!   watch drains the stream).

pub mod adxl345;
pub mod adxl357;

/// How the chip is configured: what one sample means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelConfig {
    /// Output data rate (Hz), e.g. 3 200 for the ADXL345 at its fastest.
    pub rate_hz: f32,
    /// Full-scale range (m/s²): readings at ±this are saturated.
    pub full_scale_m_s2: f32,
    /// One least-significant bit of a reading (m/s²): the chip's resolution.
    pub lsb_m_s2: f32,
}

/// One sample of the watched axis (the beam's bending direction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelSample {
    /// Acceleration along the watched axis (m/s²), gravity included as the chip reads it.
    pub acc_m_s2: f32,
    /// The chip was at (or beyond) its full-scale range on the watched axis.
    pub saturated: bool,
}

/// What a driver delivers, in order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensorEvent {
    /// One sample, at the configured rate after the previous one.
    Sample(AccelSample),
    /// The chip stopped answering (wrong device id, no data for longer than its FIFO holds,
    /// a bus error) or samples were lost (FIFO overrun): the sample stream is broken here.
    Lost,
}

/// A chip that a reader loop (re)initialises and drains: implemented by
/// [`adxl345::Adxl345`] and [`adxl357::Adxl357`] on any async SPI device.
#[allow(async_fn_in_trait)] // used with concrete types on one executor; no `Send` bound needed
pub trait FifoAccelerometer {
    /// Why a call failed; any error breaks the stream (the reader reports
    /// [`SensorEvent::Lost`] and calls [`FifoAccelerometer::init`] again).
    type Error;
    /// Checks the device id and configures the chip; the [`AccelConfig`] of what follows.
    async fn init(&mut self) -> Result<AccelConfig, Self::Error>;
    /// Drains the chip's FIFO once (bounded: one FIFO's worth), events to `sink` in order.
    async fn read_fifo(
        &mut self,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<adxl345::FifoRead, Self::Error>;
}

impl<S: embedded_hal_async::spi::SpiDevice> FifoAccelerometer for adxl345::Adxl345<S> {
    type Error = adxl345::Adxl345Error<S::Error>;
    async fn init(&mut self) -> Result<AccelConfig, Self::Error> {
        adxl345::Adxl345::init(self).await
    }
    async fn read_fifo(
        &mut self,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<adxl345::FifoRead, Self::Error> {
        adxl345::Adxl345::read_fifo(self, sink).await
    }
}

impl<S: embedded_hal_async::spi::SpiDevice> FifoAccelerometer for adxl357::Adxl357<S> {
    type Error = adxl345::Adxl345Error<S::Error>;
    async fn init(&mut self) -> Result<AccelConfig, Self::Error> {
        adxl357::Adxl357::init(self).await
    }
    async fn read_fifo(
        &mut self,
        sink: &mut impl FnMut(SensorEvent),
    ) -> Result<adxl345::FifoRead, Self::Error> {
        adxl357::Adxl357::read_fifo(self, sink).await
    }
}

/// The producer's side of a bounded event queue (e.g. a channel of 512 events): pushes
/// through a `try_send` that may refuse, and never lets a refused event vanish silently.
/// After a refusal the next event that fits is preceded by one [`SensorEvent::Lost`], so
/// the consumer sees where the stream broke.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EventGate {
    /// A [`SensorEvent::Lost`] is owed to the consumer (queue was full).
    pending_lost: bool,
    /// Events refused by the queue since start (count; wraps at `u32::MAX`).
    pub dropped: u32,
}

impl EventGate {
    /// A gate with nothing owed.
    pub const fn new() -> Self {
        EventGate {
            pending_lost: false,
            dropped: 0,
        }
    }

    /// Offers `event` to `try_send` (which answers whether the queue took it), first the
    /// owed [`SensorEvent::Lost`] if there is one. Returns whether `event` was queued.
    pub fn push(
        &mut self,
        event: SensorEvent,
        mut try_send: impl FnMut(SensorEvent) -> bool,
    ) -> bool {
        if self.pending_lost {
            if !try_send(SensorEvent::Lost) {
                self.dropped = self.dropped.wrapping_add(1);
                return false;
            }
            self.pending_lost = false;
            if event == SensorEvent::Lost {
                return true;
            }
        }
        if try_send(event) {
            return true;
        }
        self.dropped = self.dropped.wrapping_add(1);
        self.pending_lost = true;
        false
    }
}

/// Counters over a stream of [`SensorEvent`]s: what a consumer saw (all counts wrap at
/// `u32::MAX`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensorHealth {
    /// Samples received.
    pub samples: u32,
    /// [`SensorEvent::Lost`] events received.
    pub lost: u32,
    /// Samples flagged saturated.
    pub saturated: u32,
    /// The last sample's acceleration (m/s²), 0 before the first.
    pub last_m_s2: f32,
    /// Samples since the last [`SensorEvent::Lost`] (the current unbroken run).
    pub run: u32,
}

impl SensorHealth {
    /// No events seen.
    pub const fn new() -> Self {
        SensorHealth {
            samples: 0,
            lost: 0,
            saturated: 0,
            last_m_s2: 0.0,
            run: 0,
        }
    }

    /// Counts one event.
    pub fn record(&mut self, event: &SensorEvent) {
        match event {
            SensorEvent::Sample(s) => {
                self.samples = self.samples.wrapping_add(1);
                self.run = self.run.wrapping_add(1);
                self.saturated = self.saturated.wrapping_add(s.saturated as u32);
                self.last_m_s2 = s.acc_m_s2;
            }
            SensorEvent::Lost => {
                self.lost = self.lost.wrapping_add(1);
                self.run = 0;
            }
        }
    }
}
