//! Tip accelerometer readings, as a sensor driver delivers them and the watch consumes them.
//!
//! This module is the contract between the two: a driver (for example the ADXL345 over SPI,
//! read by a task into a ring buffer, never in the tick interrupt) produces [`SensorEvent`]s at
//! the chip's output data rate described by [`AccelConfig`]; the drift watch consumes them.
//! Units are SI: accelerations in m/s², rates in Hz.

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
