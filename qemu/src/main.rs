//! Runs the beamshaper core on an emulated Cortex-M4F and prints, over semihosting:
//! 1. the golden vectors (`beamshaper::golden`), which CI compares byte for byte with the
//!    host's output of the same function;
//! 2. after the `end` line, the cost of one run-time tick (two-mode ZVDD, fixed point, during
//!    a move) measured with SysTick under `-icount shift=0` (1 instruction = 1 ns of virtual
//!    time; SysTick runs at the 25 MHz system clock, so one count = 40 instructions).
#![no_std]
#![no_main]

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::runtime::{RunParams, Runtime, TickInput};
use beamshaper::shaper::ShaperKind;
use core::fmt::Write;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};

static mut RT: Runtime = Runtime::new();

#[entry]
fn main() -> ! {
    let mut out = match hio::hstdout() {
        Ok(o) => o,
        Err(_) => fail(),
    };
    let mut buf = Buffered {
        out: &mut out,
        buf: [0; 512],
        len: 0,
    };
    let ok = beamshaper::golden::write_golden(&mut buf).is_ok();
    buf.flush();

    // One tick of a two-mode ZVDD (1.1 Hz, 6.9 Hz, ζ = 0.0074) at 1 kHz, fixed point.
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 1.1,
        zeta: 0.0074,
    });
    s.modes[1] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 6.9,
        zeta: 0.0074,
    });
    // SAFETY: single-threaded bare-metal program, no interrupts touch RT.
    #[allow(static_mut_refs)]
    let rt = unsafe { &mut RT };
    if let Ok(p) = RunParams::from_settings(&s) {
        let taps = p.taps.taps().len();
        rt.configure_at_boot(p, 0);
        let _ = rt.start_move(50_000_000, 2.0e8, 2.0e9);
        for _ in 0..2000 {
            rt.tick(&TickInput::default());
        }
        let mut cp = match cortex_m::Peripherals::take() {
            Some(cp) => cp,
            None => fail(),
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00ff_ffff);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();
        let n = 1000u32;
        let t0 = cortex_m::peripheral::SYST::get_current();
        for _ in 0..n {
            core::hint::black_box(rt.tick(core::hint::black_box(&TickInput::default())));
        }
        let t1 = cortex_m::peripheral::SYST::get_current();
        let counts = t0.wrapping_sub(t1) & 0x00ff_ffff;
        let _ = writeln!(
            buf,
            "tick-cost taps={taps} ticks={n} systick_counts={counts} instructions_per_tick~{}",
            counts as u64 * 40 / n as u64
        );
        buf.flush();
    }
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {}
}

fn fail() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}

/// Semihosting calls are slow: batch the text into 512-byte writes.
struct Buffered<'a> {
    out: &'a mut hio::HostStream,
    buf: [u8; 512],
    len: usize,
}

impl Buffered<'_> {
    fn flush(&mut self) {
        let _ = self.out.write_all(&self.buf[..self.len]);
        self.len = 0;
    }
}

impl Write for Buffered<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len == self.buf.len() {
                self.flush();
            }
            self.buf[self.len] = b;
            self.len += 1;
        }
        Ok(())
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}
