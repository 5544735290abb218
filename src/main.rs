//! Firmware for the drive-interface MCU (NUCLEO-G474RE, STM32G474RE, Cortex-M4F @ 170 MHz).
//!
//! Thin glue around the `beamshaper` core:
//! - **TIM6 update interrupt** (highest priority, raw handler): one [`Runtime::tick`] per
//!   period (default 1 kHz): reads the upstream step/direction count (TIM4), shapes, programs
//!   the step pulse train (TIM8), sets the direction pin and the DAC mirror.
//! - **Console task** (thread mode): LPUART1 on PA2/PA3 (ST-LINK virtual COM port, 115200 8N1),
//!   lines into the core's [`Console`]; shaper design runs here, outside the interrupt.
//! - **Settings** in the last 16 KiB of flash (bank 2) via `sequential-storage` (see
//!   `memory.x`); loaded at boot, the console says whether defaults were used and why.
//!
//! - **Accelerometer task** (interrupt executor on the otherwise unused `UART4` vector at
//!   priority P2, below the tick and the UART): ADXL345 (ADXL357 with the feature `adxl357`)
//!   on SPI2 with DMA, its FIFO drained
//!   every 4 ms into the queue `accel::ACCEL_EVENTS` (`src/fw/accel.rs`); the console loop
//!   hands the queue to the drift watch between lines (`serve_watch`, thread mode).
//!
//! Pins: PC6 = STEP (TIM8_CH1, one-pulse train of N pulses per tick using the repetition
//! counter), PC7 = DIR, PB6 = upstream DIR in (TIM4_CH1 = direction input of the timer's
//! clock + direction encoder mode), PB7 = upstream STEP in (TIM4_CH2 = clock input),
//! PA4 = DAC1_OUT1 (setpoint mirror), PA2/PA3 = console, PB12 = accelerometer CS,
//! PB13/PB14/PB15 = SPI2 SCK/MISO/MOSI (AF5).
//!
//! Timers: TIM6 = tick, TIM4 = step/dir input counter, TIM8 = step pulse train, TIM15 = the
//! embassy time driver (feature `time-driver-tim15`, pinned so it can never take TIM4/TIM8).
//! Interrupt priorities: TIM6 at P0 (pre-empts everything else), LPUART1, TIM15 and the DMA
//! channels at P1, the accelerometer's executor (UART4 vector) at P2.
#![no_std]
#![no_main]

#[path = "fw/accel.rs"]
mod accel;
#[path = "fw/board.rs"]
mod board;

use beamshaper::console::{Action, Console, LineBuffer, RuntimeAccess};
use beamshaper::protocol::LINE_TOO_LONG;
use beamshaper::runtime::{Runtime, TickInput, TickOutput};
#[cfg(not(feature = "adxl357"))]
use beamshaper::sensor::adxl345::{Adxl345 as Chip, Adxl345Config as ChipConfig};
#[cfg(feature = "adxl357")]
use beamshaper::sensor::adxl357::{Adxl357 as Chip, Adxl357Config as ChipConfig};
use beamshaper::sensor::AccelConfig;
use beamshaper::storage::{load_settings, save_settings, STORAGE_BUFFER_BYTES};
use core::cell::RefCell;
use core::fmt::Write as _;
use embassy_embedded_hal::adapter::BlockingAsync;
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_stm32::dac::{DacChannel, Value};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::mode::Blocking as BlockingMode;
use embassy_stm32::pac;
use embassy_stm32::spi::Spi;
use embassy_stm32::usart::{BufferedUart, BufferedUartTx, Config as UartConfig};
use embassy_stm32::{bind_interrupts, dma, peripherals, usart};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{with_timeout, Duration, Instant};
use embedded_io_async::Read;
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

/// Timer kernel clock of TIM6/TIM4/TIM8 (APB1/APB2 prescaler 1 at 170 MHz).
const TIMER_CLOCK_HZ: u32 = 170_000_000;

/// Storage of the runtime: uninitialised, so it sits in `.bss` (its 80 KiB of buffers are
/// never an image in flash); [`Runtime::init_in_place`] initialises it where it is, at boot.
static RUNTIME_CELL: StaticCell<Runtime> = StaticCell::new();

/// The interrupt-owned state, shared with the console through a critical section. `None`
/// only before boot has initialised it (the tick interrupt is enabled after that).
static RUNTIME: Mutex<CriticalSectionRawMutex, RefCell<Option<&'static mut Runtime>>> =
    Mutex::new(RefCell::new(None));

/// The console's handle on [`RUNTIME`].
struct Shared;

impl RuntimeAccess for Shared {
    fn with<T>(&mut self, f: impl FnOnce(&mut Runtime) -> T) -> T {
        RUNTIME.lock(|r| match r.borrow_mut().as_deref_mut() {
            Some(rt) => f(rt),
            None => defmt::panic!("runtime used before boot initialised it"),
        })
    }
}

bind_interrupts!(struct Irqs {
    LPUART1 => usart::BufferedInterruptHandler<peripherals::LPUART1>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// The accelerometer's executor: runs on the (otherwise unused) UART4 vector at P2, so the
/// reader pre-empts thread mode (a settings `save` busy-waits there for ~22 ms per page
/// erase) but never the tick (P0).
static ACCEL_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: the vector is used by nothing else; `start` bound it to this executor.
    unsafe { ACCEL_EXECUTOR.on_interrupt() }
}

/// The accelerometer reader (`accel::run`), on [`ACCEL_EXECUTOR`]: the ADXL345, or the
/// ADXL357 with the `adxl357` feature.
#[embassy_executor::task]
async fn accel_task(mut chip: Chip<accel::ExclusiveSpi>) -> ! {
    accel::run(&mut chip).await
}

/// Serves the drift watch between console lines (thread mode, never in the tick): hands the
/// console the chip's configuration when it changes (`None`: no chip, `state=no_sensor`), every
/// queued `SensorEvent` in order, and a poll at least every [`WATCH_POLL`] (the setpoints the
/// tick wrote; the fit at the end of a move runs here, outside any critical section).
fn serve_watch(console: &mut Console, known: &mut Option<AccelConfig>, next_poll: &mut Instant) {
    let config = accel::accel_config();
    if config != *known {
        *known = config;
        console.set_accel(config, &mut Shared);
    }
    let events = accel::accel_events();
    while let Ok(event) = events.try_receive() {
        console.watch_event(event);
    }
    if Instant::now() >= *next_poll {
        *next_poll = Instant::now() + WATCH_POLL;
        let _ = console.watch_poll(&mut Shared);
    }
}

/// Longest wait for a console byte before the watch is served again: the queue holds
/// `accel::ACCEL_QUEUE_LEN` samples (160 ms at 3 200 Hz), the watch wants a poll every 0.2 s.
const WATCH_POLL: Duration = Duration::from_millis(20);

/// Starts the accelerometer reader on SPI2 (PB13 SCK, PB14 MISO, PB15 MOSI, PB12 CS; DMA1
/// channels 2 TX / 1 RX) on its interrupt executor; the console loop consumes its queue
/// ([`serve_watch`]).
fn start_accel(
    spi2: embassy_stm32::Peri<'static, peripherals::SPI2>,
    pins: (
        embassy_stm32::Peri<'static, peripherals::PB13>,
        embassy_stm32::Peri<'static, peripherals::PB14>,
        embassy_stm32::Peri<'static, peripherals::PB15>,
        embassy_stm32::Peri<'static, peripherals::PB12>,
    ),
    dma: (
        embassy_stm32::Peri<'static, peripherals::DMA1_CH2>,
        embassy_stm32::Peri<'static, peripherals::DMA1_CH1>,
    ),
) {
    let (sck, miso, mosi, cs) = pins;
    #[cfg(not(feature = "adxl357"))]
    let spi_config = accel::spi_config();
    #[cfg(feature = "adxl357")]
    let spi_config = accel::spi_config_adxl357();
    let bus = Spi::new(spi2, sck, mosi, miso, dma.0, dma.1, Irqs, spi_config);
    let cs = Output::new(cs, Level::High, Speed::VeryHigh);
    let chip = Chip::new(accel::ExclusiveSpi::new(bus, cs), ChipConfig::DEFAULT);
    interrupt::UART4.set_priority(Priority::P2);
    match accel_task(chip) {
        Ok(token) => ACCEL_EXECUTOR.start(interrupt::UART4).spawn(token),
        Err(_) => defmt::panic!("accelerometer task already running"),
    }
}

/// Console replies, streamed to the UART while they are formatted (blocking while the TX
/// ring is full; the UART interrupt drains it), so a reply of any length goes out whole
/// (a 64-impulse `shaper` table is ~7.3 kB) without a reply buffer.
struct UartOut<'a, 'd>(&'a mut BufferedUartTx<'d>);

impl core::fmt::Write for UartOut<'_, '_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        // Never wait with interrupts masked (inside a critical section): the UART interrupt
        // could not drain the ring. The console does not write there; this keeps it so.
        if cortex_m::register::primask::read().is_inactive() {
            return Err(core::fmt::Error);
        }
        embedded_io::Write::write_all(self.0, s.as_bytes()).map_err(|_| core::fmt::Error)
    }
}

/// Programs TIM6 to update at `rate_hz`.
fn set_tick_rate(rate_hz: u32) {
    let t = pac::TIM6;
    // 170 MHz / (PSC+1) / (ARR+1); PSC = 16 gives 10 MHz counts, exact for 0.5–10 kHz.
    t.psc().write_value(16);
    t.arr()
        .write(|w| w.set_arr((10_000_000 / rate_hz.max(1)).saturating_sub(1) as u16));
}

/// Emits `out.step` during the next tick: DIR first, then N pulses on TIM8_CH1 in one-pulse
/// mode with the repetition counter (REP = N − 1, N ≤ 65536), period P = 80 % of the tick / N
/// (≥ 4 timer counts). PWM mode 2: each pulse is low for the first P/2 and high for the
/// second, so DIR is set up at least P/2 before the first rising STEP edge, and the train
/// ends (counter stopped by OPM, output low) before the next tick programs another.
/// The core's step-rate check keeps N within the drive's maximum step rate.
fn emit(
    out: &TickOutput,
    dir: &mut Output<'static>,
    dac: &mut DacChannel<'static, BlockingMode>,
    tick_hz: u32,
) {
    dir.set_level(if out.step.forward {
        Level::High
    } else {
        Level::Low
    });
    dac.set(Value::Bit12Right(out.dac_code));
    let n = out.step.pulses.min(65_536);
    if n == 0 {
        return;
    }
    let t = pac::TIM8;
    let period = ((TIMER_CLOCK_HZ / tick_hz.max(1)) * 4 / 5 / n).clamp(4, 65_535);
    t.arr().write(|w| w.set_arr(period as u16 - 1));
    t.ccr(0).write(|w| w.set_ccr(period as u16 / 2));
    t.rcr().write(|w| w.set_rep((n - 1) as u16));
    t.egr().write(|w| w.set_ug(true));
    t.cr1().modify(|w| {
        w.set_opm(true);
        w.set_cen(true)
    });
}

/// The outputs the interrupt drives (moved here once at boot).
struct Outputs {
    dir: Output<'static>,
    dac: DacChannel<'static, BlockingMode>,
}

static OUTPUTS: Mutex<CriticalSectionRawMutex, RefCell<Option<Outputs>>> =
    Mutex::new(RefCell::new(None));

#[interrupt]
fn TIM6_DAC() {
    pac::TIM6.sr().modify(|w| w.set_uif(false));
    let input = TickInput {
        stepdir_count: pac::TIM4.cnt().read().cnt() as u16,
    };
    RUNTIME.lock(|r| {
        let mut guard = r.borrow_mut();
        let Some(rt) = guard.as_deref_mut() else {
            return;
        };
        let before = rt.tick_rate_hz();
        let out = rt.tick(&input);
        let after = rt.tick_rate_hz();
        OUTPUTS.lock(|o| {
            if let Some(o) = o.borrow_mut().as_mut() {
                emit(&out, &mut o.dir, &mut o.dac, after);
            }
        });
        if after != before {
            set_tick_rate(after);
        }
    });
}

fn init_timers() {
    // TIM4: clock + direction encoder mode, x1 (SMS = 0b1011, RM0440 "clock plus direction"):
    // clock on TI2 (PB7), direction on TI1 (PB6, high = up). Both channels as inputs on their
    // own pins, filtered over 8 samples at 170 MHz (47 ns).
    let t4 = pac::TIM4;
    t4.arr().write(|w| w.set_arr(0xffff));
    t4.ccmr_input(0).modify(|w| {
        for ch in 0..2 {
            w.set_ccs(ch, pac::timer::vals::CcmrInputCcs::TI4);
            w.set_icf(ch, pac::timer::vals::FilterValue::FCK_INT_N8);
        }
    });
    t4.smcr()
        .modify(|w| w.set_sms(pac::timer::vals::Sms::from_bits(0b1011)));
    t4.cr1().modify(|w| w.set_cen(true));
    // TIM8_CH1: PWM mode 2, main output enabled; started per tick by `emit`.
    let t8 = pac::TIM8;
    t8.ccmr_output(0)
        .modify(|w| w.set_ocm(0, pac::timer::vals::Ocm::PWM_MODE2));
    t8.ccer().modify(|w| w.set_cce(0, true));
    t8.bdtr().modify(|w| w.set_moe(true));
    // TIM6: the tick.
    set_tick_rate(1000);
    pac::TIM6.dier().modify(|w| w.set_uie(true));
    pac::TIM6.cr1().modify(|w| w.set_cen(true));
}

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let config = board::clock_config();
    let p = embassy_stm32::init(config);

    // Peripheral clocks and pin functions for the raw timers and the DAC.
    pac::RCC.apb1enr1().modify(|w| {
        w.set_tim6en(true);
        w.set_tim4en(true)
    });
    pac::RCC.apb2enr().modify(|w| w.set_tim8en(true));
    // Claim the upstream DIR (PB6) and STEP (PB7) pins, then hand them to TIM4 (AF2).
    let _dir_in = embassy_stm32::gpio::Flex::new(p.PB6);
    let _step_in = embassy_stm32::gpio::Flex::new(p.PB7);
    pac::GPIOB.moder().modify(|w| {
        w.set_moder(6, pac::gpio::vals::Moder::ALTERNATE);
        w.set_moder(7, pac::gpio::vals::Moder::ALTERNATE)
    });
    pac::GPIOB.afr(0).modify(|w| {
        w.set_afr(6, 2);
        w.set_afr(7, 2)
    });
    pac::GPIOC
        .moder()
        .modify(|w| w.set_moder(6, pac::gpio::vals::Moder::ALTERNATE));
    pac::GPIOC.afr(0).modify(|w| w.set_afr(6, 4));
    let dir = Output::new(p.PC7, Level::Low, Speed::VeryHigh);
    // DAC1 channel 1 on PA4: embassy enables its clock, sets HFSEL for the 170 MHz bus and
    // makes the pin analog; the interrupt then only writes DHR12R1.
    let dac = DacChannel::new_blocking(p.DAC1, p.PA4);
    OUTPUTS.lock(|o| *o.borrow_mut() = Some(Outputs { dir, dac }));

    // Console UART.
    static TX_BUF: StaticCell<[u8; 2048]> = StaticCell::new();
    static RX_BUF: StaticCell<[u8; 256]> = StaticCell::new();
    let mut ucfg = UartConfig::default();
    ucfg.baudrate = 115_200;
    let uart = match BufferedUart::new(
        p.LPUART1,
        p.PA3,
        p.PA2,
        TX_BUF.init([0; 2048]),
        RX_BUF.init([0; 256]),
        Irqs,
        ucfg,
    ) {
        Ok(u) => u,
        Err(_) => defmt::panic!("LPUART1 configuration refused"),
    };
    let (mut tx, mut rx) = uart.split();

    // Settings from flash, then the tick.
    let mut flash: BlockingAsync<Flash<'static, Blocking>> =
        BlockingAsync::new(Flash::new_blocking(p.FLASH));
    let mut sbuf = [0u8; STORAGE_BUFFER_BYTES];
    let loaded = load_settings(&mut flash, board::SETTINGS_FLASH, &mut sbuf).await;
    let rt = Runtime::init_in_place(RUNTIME_CELL.uninit());
    RUNTIME.lock(|r| *r.borrow_mut() = Some(rt));
    let stepdir_now = pac::TIM4.cnt().read().cnt() as u16;
    let mut console = Console::boot(loaded, &mut Shared, stepdir_now, &mut UartOut(&mut tx));
    init_timers();
    set_tick_rate(Shared.with(|r| r.tick_rate_hz()));
    // The tick pre-empts the console UART and the embassy time driver (TIM15).
    interrupt::LPUART1.set_priority(Priority::P1);
    interrupt::TIM1_BRK_TIM15.set_priority(Priority::P1);
    interrupt::TIM6_DAC.set_priority(Priority::P0);
    interrupt::TIM6_DAC.unpend();
    // SAFETY: the handler only touches RUNTIME/OUTPUTS through critical-section mutexes.
    unsafe { interrupt::TIM6_DAC.enable() };
    start_accel(
        p.SPI2,
        (p.PB13, p.PB14, p.PB15, p.PB12),
        (p.DMA1_CH2, p.DMA1_CH1),
    );
    defmt::info!("beamshaper firmware up");

    let mut lines = LineBuffer::new();
    let mut byte = [0u8; 1];
    let (mut accel_known, mut next_poll) = (None, Instant::now());
    loop {
        serve_watch(&mut console, &mut accel_known, &mut next_poll);
        match with_timeout(WATCH_POLL, rx.read_exact(&mut byte)).await {
            Ok(Ok(())) => {}
            _ => continue,
        }
        let Some(line) = lines.push(byte[0]) else {
            continue;
        };
        let mut out = UartOut(&mut tx);
        match line {
            Err(_) => {
                let _ = writeln!(out, "{LINE_TOO_LONG}");
            }
            Ok(line) => match console.handle_line(&line, &mut Shared, &mut out) {
                Action::None => {}
                Action::Save => {
                    let r = save_settings(
                        &mut flash,
                        board::SETTINGS_FLASH,
                        &mut sbuf,
                        console.settings(),
                    )
                    .await;
                    console.finish_save(r, &mut out);
                }
                Action::Load => {
                    let r = load_settings(&mut flash, board::SETTINGS_FLASH, &mut sbuf).await;
                    console.finish_load(r, &mut Shared, &mut out);
                }
            },
        }
    }
}
