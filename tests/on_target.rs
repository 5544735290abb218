//! On-target test suite for the NUCLEO-G474RE (embedded-test + probe-rs).
//!
//! `cargo test --release --no-run` at the repository root builds it (CI, no board);
//! `cargo test --release` with the board on USB flashes it and runs each test after a reset
//! (the runner is `probe-rs run --chip STM32G474RETx`, `.cargo/config.toml`).
//!
//! - the core's golden vectors (`beamshaper::golden::write_golden_in`, its runtime in
//!   `.bss`) computed on the G474
//!   and compared byte for byte with the host's output, `tests/golden-host.txt` (the host test
//!   `host-tests/tests/golden_file.rs` keeps that file current);
//! - the tick: a two-mode ZVDD move timed with the DWT cycle counter;
//! - the console: boot, commands and their replies;
//! - the flash settings in a scratch range of bank 2 (never the user's settings): round trip,
//!   and power loss during a save (the writes cut after N bytes) always loads the previous
//!   record, and a later save works;
//! - the ADXL345 on SPI2: the device id, and the reader's event stream; without a chip the
//!   tests check the driver reports it cleanly (`WrongId`, one `Lost`) and log that the
//!   chip's own checks were skipped.
#![no_std]
#![no_main]

#[path = "../src/fw/accel.rs"]
#[allow(dead_code)]
mod accel;
#[path = "../src/fw/board.rs"]
mod board;

use defmt_rtt as _;

/// The host's golden vectors (`cd host-tests && cargo run --release --bin golden`).
const GOLDEN_HOST: &str = include_str!("golden-host.txt");

/// A scratch range of bank 2 for the flash tests: 16 KiB (eight 2 KiB pages) just below the
/// settings (0x08074000..0x08078000), so the board's saved settings survive the tests.
const SCRATCH_FLASH: core::ops::Range<u32> = (512 - 48) * 1024..(512 - 32) * 1024;
const _: () = assert!(SCRATCH_FLASH.end <= board::SETTINGS_FLASH.start);

embassy_stm32::bind_interrupts!(struct Irqs {
    DMA1_CHANNEL1 => embassy_stm32::dma::InterruptHandler<embassy_stm32::peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => embassy_stm32::dma::InterruptHandler<embassy_stm32::peripherals::DMA1_CH2>;
});

/// A `core::fmt::Write` that compares what is written with an expected text.
struct Compare {
    expected: &'static str,
    at: usize,
    mismatch: Option<usize>,
}

impl core::fmt::Write for Compare {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        if self.mismatch.is_none() {
            let end = self.at + s.len();
            if self.expected.get(self.at..end) != Some(s) {
                self.mismatch = Some(self.at);
            }
        }
        self.at += s.len();
        Ok(())
    }
}

/// A `core::fmt::Write` into a fixed buffer (the rest is dropped, `overflow` set).
struct Text {
    buf: heapless::String<4096>,
    overflow: bool,
}

impl core::fmt::Write for Text {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        if self.buf.push_str(s).is_err() {
            self.overflow = true;
        }
        Ok(())
    }
}

/// A NOR flash whose power is cut after `budget` bytes of writes: the write in progress
/// programs only its words before the cut (real flash, partly written), and it and every
/// later write or erase fails.
struct CutFlash<F> {
    inner: F,
    budget: usize,
}

#[derive(Debug)]
enum CutError {
    Cut,
    Inner,
}

impl embedded_storage_async::nor_flash::NorFlashError for CutError {
    fn kind(&self) -> embedded_storage_async::nor_flash::NorFlashErrorKind {
        embedded_storage_async::nor_flash::NorFlashErrorKind::Other
    }
}

impl<F: embedded_storage_async::nor_flash::NorFlash> embedded_storage_async::nor_flash::ErrorType
    for CutFlash<F>
{
    type Error = CutError;
}

impl<F: embedded_storage_async::nor_flash::NorFlash> embedded_storage_async::nor_flash::ReadNorFlash
    for CutFlash<F>
{
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), CutError> {
        self.inner
            .read(offset, bytes)
            .await
            .map_err(|_| CutError::Inner)
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl<F: embedded_storage_async::nor_flash::NorFlash> embedded_storage_async::nor_flash::NorFlash
    for CutFlash<F>
{
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), CutError> {
        if self.budget == 0 {
            return Err(CutError::Cut);
        }
        self.inner
            .erase(from, to)
            .await
            .map_err(|_| CutError::Inner)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), CutError> {
        if bytes.len() <= self.budget {
            self.budget -= bytes.len();
            return self
                .inner
                .write(offset, bytes)
                .await
                .map_err(|_| CutError::Inner);
        }
        let part = self.budget / F::WRITE_SIZE * F::WRITE_SIZE;
        self.budget = 0;
        if part > 0 {
            let _ = self.inner.write(offset, &bytes[..part]).await;
        }
        Err(CutError::Cut)
    }
}

/// Stack depth, measured: the G474 has no stack guard (an overflow would run silently into
/// `.bss`, and the runtime alone takes 91 KiB of the 128), so [`stack::paint`] fills the free
/// stack region with a pattern before each test and [`stack::check`] at its end logs how deep
/// the stack went and fails with less than 1 KiB to spare.
mod stack {
    extern "C" {
        /// Bottom of the stack region = end of `.uninit` (cortex-m-rt's `link.x`).
        static _stack_end: u32;
        /// Top of the stack region (end of RAM).
        static _stack_start: u32;
    }

    const PAINT: u32 = 0xA5A5_5A5A;

    fn bounds() -> (usize, usize) {
        // Only the addresses of the linker symbols are taken, never their values.
        (
            core::ptr::addr_of!(_stack_end) as usize,
            core::ptr::addr_of!(_stack_start) as usize,
        )
    }

    /// Fills the stack region from its bottom to 512 bytes below the current stack pointer,
    /// with interrupts masked (no handler's frame can be below the stack pointer meanwhile).
    pub fn paint() {
        cortex_m::interrupt::free(|_| {
            let (bottom, _) = bounds();
            let sp = cortex_m::register::msp::read() as usize;
            let mut p = bottom;
            while p + 512 < sp {
                // SAFETY: `p` is word-aligned RAM between the end of `.uninit` and the stack
                // pointer minus 512 bytes: no live data (interrupts are masked).
                unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
                p += 4;
            }
        });
    }

    /// Logs the deepest stack use since [`paint`] (bytes) and asserts ≥ 1 KiB never touched.
    pub fn check(test: &str) {
        let (bottom, top) = bounds();
        let mut p = bottom;
        // SAFETY: reads of word-aligned RAM inside the stack region.
        while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
            p += 4;
        }
        let untouched = p - bottom;
        defmt::info!(
            "{}: stack used {} of {} bytes",
            test,
            top - bottom - untouched,
            top - bottom
        );
        assert!(untouched >= 1024, "{}: stack nearly exhausted", test);
    }
}

#[cfg(test)]
#[embedded_test::tests]
mod tests {
    use super::*;
    use beamshaper::config::{ModeSetting, Settings};
    use beamshaper::console::{Action, Console};
    use beamshaper::engine::NumericPath;
    use beamshaper::runtime::{RunParams, Runtime, TickInput};
    use beamshaper::sensor::adxl345::{Adxl345, Adxl345Config, Adxl345Error, DEVICE_ID};
    use beamshaper::sensor::SensorHealth;
    use beamshaper::shaper::ShaperKind;
    use beamshaper::storage::{load_settings, save_settings, STORAGE_BUFFER_BYTES};
    use embassy_embedded_hal::adapter::BlockingAsync;
    use embassy_futures::select::{select, Either};
    use embassy_stm32::flash::{Blocking, Flash};
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_stm32::spi::Spi;
    use embassy_stm32::Peripherals;
    use embassy_time::{Duration, Instant, Timer};
    use embedded_storage_async::nor_flash::NorFlash;
    use static_cell::StaticCell;

    /// The runtime in `.bss`, initialised in place as the firmware does (80 KiB of buffers).
    static RUNTIME_CELL: StaticCell<Runtime> = StaticCell::new();

    #[init]
    fn init() -> Peripherals {
        stack::paint();
        embassy_stm32::init(board::clock_config())
    }

    /// The golden vectors on the G474 are the host's, byte for byte.
    #[test]
    #[timeout(60)]
    fn golden_vectors_match_the_host() {
        let mut c = Compare {
            expected: GOLDEN_HOST,
            at: 0,
            mismatch: None,
        };
        assert!(beamshaper::golden::write_golden_in(&mut c, RUNTIME_CELL.uninit()).is_ok());
        if let Some(at) = c.mismatch {
            let line = GOLDEN_HOST[..at].lines().count();
            defmt::panic!("golden vectors differ from the host's at line {}", line);
        }
        assert_eq!(
            c.at,
            GOLDEN_HOST.len(),
            "golden output has a different length"
        );
        defmt::info!("golden vectors bit-identical ({} bytes)", c.at);
        stack::check("golden");
    }

    fn zvdd(f: f64) -> Option<ModeSetting> {
        Some(ModeSetting {
            kind: ShaperKind::Zvdd,
            freq_hz: f,
            zeta: 0.0074,
        })
    }

    /// One whole tick of a two-mode ZVDD during a move, timed with the DWT cycle counter:
    /// the worst of 1000 ticks stays under 10 % of the 1 kHz period (17 000 cycles).
    #[test]
    fn tick_during_a_move_fits_the_period() {
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            defmt::panic!("core peripherals taken");
        };
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        let rt = Runtime::init_in_place(RUNTIME_CELL.uninit());
        let mut s = Settings::DEFAULT;
        s.modes = [zvdd(1.1), zvdd(6.9), None, None];
        s.path = NumericPath::Fixed;
        let Ok(params) = RunParams::from_settings(&s) else {
            defmt::panic!("settings refused");
        };
        rt.configure_at_boot(params, 0);
        assert!(rt.start_move(100_000_000, 5.0e7, 5.0e8).is_ok());
        let (mut worst, mut total) = (0u32, 0u64);
        for k in 0..1050 {
            let t0 = cortex_m::peripheral::DWT::cycle_count();
            let _ = rt.tick(&TickInput::default());
            let dt = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(t0);
            if k >= 50 {
                worst = worst.max(dt);
                total += dt as u64;
            }
        }
        defmt::info!(
            "tick 2-mode ZVDD fixed: mean {} cycles, worst {} cycles (170 MHz)",
            total / 1000,
            worst
        );
        assert!(worst < 17_000, "tick too slow: {} cycles", worst);
        stack::check("tick");
    }

    /// The console boots on the defaults (`ok boot`), answers `help`, `mode` (5 taps for a
    /// ZVD at 1 kHz), `status`, refuses an unknown command, and asks the firmware to `save`.
    #[test]
    fn console_boots_and_answers() {
        let rt = Runtime::init_in_place(RUNTIME_CELL.uninit());
        let mut out = Text {
            buf: heapless::String::new(),
            overflow: false,
        };
        let mut console = Console::boot(Ok(None), rt, 0, &mut out);
        assert!(out.buf.contains("ok boot"));
        for (line, want) in [
            ("help", "ok"),
            ("mode 1 zvd 1.1 0.0074", "ok mode taps=5"),
            ("frobnicate", "err unknown"),
            ("status", "ok status"),
        ] {
            out.buf.clear();
            let action = console.handle_line(line.as_bytes(), rt, &mut out);
            assert!(matches!(action, Action::None));
            let last = out.buf.lines().last().unwrap_or("");
            assert!(
                last.starts_with(want),
                "`{}` answered `{}`",
                line,
                out.buf.as_str()
            );
        }
        out.buf.clear();
        let action = console.handle_line(b"save", rt, &mut out);
        assert!(matches!(action, Action::Save));
        assert!(!out.overflow);
        assert!(console.settings().modes[0].is_some());
        stack::check("console");
    }

    fn settings_at(f1: f64) -> Settings {
        let mut s = Settings::DEFAULT;
        s.modes[0] = zvdd(f1);
        s
    }

    async fn erase_scratch(flash: &mut BlockingAsync<Flash<'static, Blocking>>) {
        assert!(flash
            .erase(SCRATCH_FLASH.start, SCRATCH_FLASH.end)
            .await
            .is_ok());
    }

    /// Settings round trip in real flash; an erased range loads as "nothing saved".
    #[test]
    #[timeout(120)]
    async fn settings_round_trip_in_flash(p: Peripherals) {
        let mut flash = BlockingAsync::new(Flash::new_blocking(p.FLASH));
        let mut buf = [0u8; STORAGE_BUFFER_BYTES];
        erase_scratch(&mut flash).await;
        assert_eq!(
            load_settings(&mut flash, SCRATCH_FLASH, &mut buf).await,
            Ok(None)
        );
        // 72 bytes of flash per save (measured on the host's mock flash: the 42-byte record,
        // key and item header in 8-byte words), ~28 per 2 KiB page: 400 saves go round the
        // eight pages, so pages are erased (garbage collection).
        for k in 0..400 {
            let s = settings_at(1.0 + k as f64 * 0.001);
            assert!(save_settings(&mut flash, SCRATCH_FLASH, &mut buf, &s)
                .await
                .is_ok());
            assert_eq!(
                load_settings(&mut flash, SCRATCH_FLASH, &mut buf).await,
                Ok(Some(s))
            );
        }
        stack::check("settings");
    }

    /// Power lost during a save: the save of B over A is cut after 0, 8, 16, …, 160 bytes of
    /// writes (a save writes 72 bytes; the cut write leaves its first double-words
    /// programmed); the load then gives A, or B once B was completely written, never anything
    /// else or an error; a full save after it works.
    #[test]
    #[timeout(180)]
    async fn power_loss_during_save_keeps_the_previous_record(p: Peripherals) {
        let mut flash = BlockingAsync::new(Flash::new_blocking(p.FLASH));
        let mut buf = [0u8; STORAGE_BUFFER_BYTES];
        let (a, b) = (settings_at(1.1), settings_at(1.3));
        let (mut kept_a, mut got_b) = (0u32, 0u32);
        for cut in (0..=160usize).step_by(8) {
            erase_scratch(&mut flash).await;
            assert!(save_settings(&mut flash, SCRATCH_FLASH, &mut buf, &a)
                .await
                .is_ok());
            let mut cutting = CutFlash {
                inner: &mut flash,
                budget: cut,
            };
            let _ = save_settings(&mut cutting, SCRATCH_FLASH, &mut buf, &b).await;
            let loaded = load_settings(&mut flash, SCRATCH_FLASH, &mut buf).await;
            match loaded {
                Ok(Some(s)) if s == a => kept_a += 1,
                Ok(Some(s)) if s == b => got_b += 1,
                _ => defmt::panic!(
                    "cut after {} bytes: neither the old nor the new record",
                    cut
                ),
            }
            assert!(save_settings(&mut flash, SCRATCH_FLASH, &mut buf, &b)
                .await
                .is_ok());
            assert_eq!(
                load_settings(&mut flash, SCRATCH_FLASH, &mut buf).await,
                Ok(Some(b.clone()))
            );
        }
        defmt::info!(
            "power cuts: old record kept {} times, new record complete {} times",
            kept_a,
            got_b
        );
        assert!(kept_a > 0 && got_b > 0);
        stack::check("power loss");
    }

    fn adxl345(p: Peripherals) -> Adxl345<accel::ExclusiveSpi> {
        let bus = Spi::new(
            p.SPI2,
            p.PB13,
            p.PB15,
            p.PB14,
            p.DMA1_CH2,
            p.DMA1_CH1,
            Irqs,
            accel::spi_config(),
        );
        let cs = Output::new(p.PB12, Level::High, Speed::VeryHigh);
        Adxl345::new(accel::ExclusiveSpi::new(bus, cs), Adxl345Config::DEFAULT)
    }

    /// The device id over SPI2 (DMA). With a chip: 0xE5, init and one FIFO drain with
    /// samples. Without (the MISO pull-up reads 0xFF): init refuses with `WrongId`, and the
    /// chip checks are reported skipped.
    #[test]
    async fn accel_device_id(p: Peripherals) {
        let mut chip = adxl345(p);
        let Ok(id) = chip.device_id().await else {
            defmt::panic!("SPI2 transfer failed");
        };
        if id != DEVICE_ID {
            defmt::warn!(
                "no ADXL345 on SPI2 (device id {=u8:#x}): chip checks skipped",
                id
            );
            assert_eq!(chip.init().await, Err(Adxl345Error::WrongId(id)));
            stack::check("accel id");
            return;
        }
        let Ok(cfg) = chip.init().await else {
            defmt::panic!("ADXL345 init failed");
        };
        assert_eq!(cfg.rate_hz, 3200.0);
        Timer::after_millis(5).await;
        let mut health = SensorHealth::new();
        let Ok(r) = chip.read_fifo(&mut |e| health.record(&e)).await else {
            defmt::panic!("FIFO read failed");
        };
        defmt::info!(
            "ADXL345: {} samples in 5 ms, last {} m/s2",
            r.samples,
            health.last_m_s2
        );
        assert!(r.samples >= 8 && !r.overrun, "{} samples", r.samples);
        stack::check("accel id");
    }

    /// The reader (`accel::run`, as the firmware runs it) for 1.5 s, its queue drained
    /// concurrently: with a chip, about 3 200 samples per second (4 000..5 300 in 1.5 s: init
    /// included, and the chip's own oscillator sets the rate within some %) and no `Lost`;
    /// without, exactly one `Lost` and no samples.
    #[test]
    async fn accel_reader_stream(p: Peripherals) {
        let mut chip = adxl345(p);
        let present = chip.device_id().await == Ok(DEVICE_ID);
        let deadline = Instant::now() + Duration::from_millis(1500);
        let drain = async {
            let mut health = SensorHealth::new();
            loop {
                match select(accel::accel_events().receive(), Timer::at(deadline)).await {
                    Either::First(e) => health.record(&e),
                    Either::Second(()) => return health,
                }
            }
        };
        let health = match select(accel::run(&mut chip), drain).await {
            Either::First(never) => never,
            Either::Second(h) => h,
        };
        defmt::info!(
            "reader 1.5 s: samples={} lost={} saturated={}",
            health.samples,
            health.lost,
            health.saturated
        );
        if present {
            assert!(accel::accel_config().is_some());
            assert!(health.samples >= 4000 && health.samples <= 5300);
            assert_eq!(health.lost, 0);
        } else {
            defmt::warn!("no ADXL345 on SPI2: checked the absent-chip report only");
            assert!(accel::accel_config().is_none());
            assert_eq!((health.samples, health.lost), (0, 1));
            assert!(accel::accel_events().try_receive().is_err());
        }
        stack::check("accel reader");
    }
}
