//! Firmware glue (embassy) for the tip accelerometer: the SPI device, the reader loop and the
//! queue of [`SensorEvent`]s it fills. Not part of the `no_std` core library (`src/lib.rs`
//! does not declare `fw`): the firmware binary (`src/main.rs`) and the on-target test suite
//! (`tests/on_target.rs`) include it with `#[path]`. The chip logic is the core's
//! [`beamshaper::sensor::adxl345`].
//!
//! Wiring (docs/firmware.md): SPI2, PB13 = SCK, PB14 = MISO (pull-up: no chip reads 0xFF),
//! PB15 = MOSI (AF5), PB12 = CS (GPIO), mode 3, 4 MHz requested → 170 MHz / 64 = 2.66 MHz
//! (ADXL345: ≤ 5 MHz, ≥ 2 MHz recommended at 3 200 Hz); DMA1 channels 1 (RX) and 2 (TX).
//!
//! The reader runs in its own task, never in the tick interrupt (TIM6): [`run`] polls the
//! FIFO every [`POLL_PERIOD`] (4 ms = 12.8 samples at 3 200 Hz; the 32-entry FIFO holds
//! 10 ms) and pushes each event into [`ACCEL_EVENTS`] through an [`EventGate`], so a full
//! queue becomes a [`SensorEvent::Lost`] in the stream, never a silent gap.
//!
//! **Consumer (the drift watch):** drain [`accel_events`] in thread mode (`receive().await`
//! or `try_receive()`), with [`accel_config`] for what one sample means.

use beamshaper::sensor::{AccelConfig, EventGate, FifoAccelerometer, SensorEvent};
use core::cell::Cell;
use embassy_stm32::gpio::{Output, Pull};
use embassy_stm32::mode::Async;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::{Channel, Receiver};
use embassy_time::{Duration, Ticker, Timer};
use embedded_hal_async::spi::{ErrorType, Operation, SpiBus, SpiDevice};

/// Events the queue holds: 512 × 8 bytes = 4 KiB of RAM, 160 ms at 3 200 Hz (a settings
/// `save` blocks thread mode for ~22 ms per page erased).
pub const ACCEL_QUEUE_LEN: usize = 512;

/// The accelerometer's events, oldest first (producer: [`run`]; consumer: the watch).
pub static ACCEL_EVENTS: Channel<CriticalSectionRawMutex, SensorEvent, ACCEL_QUEUE_LEN> =
    Channel::new();

/// What one sample means, set each time the chip is (re)initialised; `None` while no chip
/// answers.
static ACCEL_CONFIG: Mutex<CriticalSectionRawMutex, Cell<Option<AccelConfig>>> =
    Mutex::new(Cell::new(None));

/// How often [`run`] drains the chip's FIFO.
pub const POLL_PERIOD: Duration = Duration::from_millis(4);
/// How long [`run`] waits before trying a chip that failed again.
pub const RETRY_PERIOD: Duration = Duration::from_millis(500);

/// The consumer's end of [`ACCEL_EVENTS`]: samples at [`accel_config`]'s rate, and
/// [`SensorEvent::Lost`] wherever the stream broke (no chip, bus error, FIFO overrun, queue
/// full). Drain it in thread mode.
pub fn accel_events() -> Receiver<'static, CriticalSectionRawMutex, SensorEvent, ACCEL_QUEUE_LEN> {
    ACCEL_EVENTS.receiver()
}

/// The configuration of the stream (rate Hz, full scale m/s², LSB m/s²), `None` while no
/// chip is running.
pub fn accel_config() -> Option<AccelConfig> {
    ACCEL_CONFIG.lock(|c| c.get())
}

/// SPI settings for the ADXL345: mode 3, 4 MHz requested (embassy's divider picks 170 MHz
/// / 64 = 2.66 MHz; 5 MHz would pick / 32 = 5.31 MHz, over the chip's 5 MHz), pull-up on
/// MISO so an absent chip reads 0xFF.
pub fn spi_config() -> spi::Config {
    let mut c = spi::Config::default();
    c.mode = spi::MODE_3;
    c.frequency = Hertz(4_000_000);
    c.miso_pull = Pull::Up;
    c
}

/// SPI settings for the ADXL357 (firmware feature `adxl357`): mode 0, 5 MHz requested
/// (170 MHz / 32 = 5.31 MHz; the chip allows 10 MHz, and 8 MHz would pick / 16 = 10.6 MHz),
/// pull-up on MISO.
#[allow(dead_code)]
pub fn spi_config_adxl357() -> spi::Config {
    let mut c = spi_config();
    c.mode = spi::MODE_0;
    c.frequency = Hertz(5_000_000);
    c
}

/// An SPI bus with one device on it and its chip select (active low).
pub struct ExclusiveSpi {
    bus: Spi<'static, Async, spi::mode::Master>,
    cs: Output<'static>,
}

impl ExclusiveSpi {
    /// `cs` must be high (deselected) when given.
    pub fn new(bus: Spi<'static, Async, spi::mode::Master>, cs: Output<'static>) -> Self {
        ExclusiveSpi { bus, cs }
    }
}

impl ErrorType for ExclusiveSpi {
    type Error = spi::Error;
}

impl SpiDevice for ExclusiveSpi {
    /// CS low, the operations in order (DMA), CS high, even after an error.
    async fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), spi::Error> {
        self.cs.set_low();
        let mut result = Ok(());
        for op in ops.iter_mut() {
            result = match op {
                Operation::Read(buf) => SpiBus::read(&mut self.bus, buf).await,
                Operation::Write(buf) => SpiBus::write(&mut self.bus, buf).await,
                Operation::Transfer(r, w) => SpiBus::transfer(&mut self.bus, r, w).await,
                Operation::TransferInPlace(buf) => {
                    SpiBus::transfer_in_place(&mut self.bus, buf).await
                }
                Operation::DelayNs(ns) => {
                    Timer::after_nanos(*ns as u64).await;
                    Ok(())
                }
            };
            if result.is_err() {
                break;
            }
        }
        self.cs.set_high();
        result
    }
}

/// Pushes one event into [`ACCEL_EVENTS`] through `gate`.
fn push(gate: &mut EventGate, event: SensorEvent) {
    gate.push(event, |e| ACCEL_EVENTS.try_send(e).is_ok());
}

/// The reader: initialises the chip (retrying every [`RETRY_PERIOD`] while it fails), then
/// drains its FIFO every [`POLL_PERIOD`]; an error is one [`SensorEvent::Lost`] (a chip absent
/// at boot: one Lost, not one per retry) and a fresh init. Never returns.
pub async fn run<C: FifoAccelerometer>(chip: &mut C) -> ! {
    let mut gate = EventGate::new();
    // One Lost per break: a chip that stays absent is not a Lost every retry.
    let mut broken = false;
    loop {
        match chip.init().await {
            Ok(config) => ACCEL_CONFIG.lock(|c| c.set(Some(config))),
            Err(_) => {
                ACCEL_CONFIG.lock(|c| c.set(None));
                if !broken {
                    push(&mut gate, SensorEvent::Lost);
                    broken = true;
                }
                Timer::after(RETRY_PERIOD).await;
                continue;
            }
        }
        let mut ticker = Ticker::every(POLL_PERIOD);
        loop {
            ticker.next().await;
            if chip.read_fifo(&mut |ev| push(&mut gate, ev)).await.is_err() {
                push(&mut gate, SensorEvent::Lost);
                broken = true;
                break;
            }
        }
    }
}
