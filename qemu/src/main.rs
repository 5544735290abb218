//! Runs the beamshaper core on an emulated Cortex-M4F and prints, over semihosting:
//! 1. the golden vectors (`beamshaper::golden`), which CI compares byte for byte with the
//!    host's output of the same function;
//! 2. after the `end` line, `tick-cost` lines: the instructions of one run-time tick during a
//!    move (two-mode ZVDD as in the host benchmark, and the interrupt's worst case, a
//!    three-mode ZVDD with 128 taps), both numeric paths, measured with SysTick under
//!    `-icount shift=0` (1 instruction = 1 ns of virtual time; SysTick runs at the 25 MHz
//!    system clock, so one count = 40 instructions, checked by a calibration loop of a known
//!    instruction count).
#![no_std]
#![no_main]

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::NumericPath;
use beamshaper::runtime::{RunParams, Runtime, TickInput};
use beamshaper::shaper::ShaperKind;
use core::fmt::Write;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};

/// The runtime in `.bss`, initialised in place as the firmware does.
static mut RT: core::mem::MaybeUninit<Runtime> = core::mem::MaybeUninit::zeroed();

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

    // The cost of one run-time tick during a move, for the benchmark's two-mode ZVDD and for
    // the interrupt's worst case (a three-mode ZVDD: 64 impulses, each split over two ticks).
    let mut cp = match cortex_m::Peripherals::take() {
        Some(cp) => cp,
        None => fail(),
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00ff_ffff);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();
    // Calibration: a loop of exactly 12 instructions × 10 000 iterations (10 nop, subs, bne).
    let t0 = cortex_m::peripheral::SYST::get_current();
    // SAFETY: register-only loop, no memory access.
    unsafe {
        core::arch::asm!(
            "2:",
            "nop", "nop", "nop", "nop", "nop", "nop", "nop", "nop", "nop", "nop",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) 10_000u32 => _,
            options(nomem, nostack),
        );
    }
    let t1 = cortex_m::peripheral::SYST::get_current();
    let _ = writeln!(
        buf,
        "tick-cost calibration instructions=120000 systick_counts={} instructions_per_count~{}",
        t0.wrapping_sub(t1) & 0x00ff_ffff,
        120_000 / (t0.wrapping_sub(t1) & 0x00ff_ffff).max(1)
    );
    let zvdd = |f: f64| {
        Some(ModeSetting {
            kind: ShaperKind::Zvdd,
            freq_hz: f,
            zeta: 0.0074,
        })
    };
    let two_mode = [zvdd(1.1), zvdd(6.9), None, None];
    let three_mode = [zvdd(1.1), zvdd(6.9), zvdd(17.3), None];
    for (label, modes, path) in [
        ("2-mode-zvdd", two_mode, NumericPath::Fixed),
        ("2-mode-zvdd", two_mode, NumericPath::F32),
        ("3-mode-zvdd", three_mode, NumericPath::Fixed),
        ("3-mode-zvdd", three_mode, NumericPath::F32),
    ] {
        let mut s = Settings::DEFAULT;
        s.modes = modes;
        s.path = path;
        tick_cost(&mut buf, label, &s);
    }
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {}
}

/// Prints the mean instructions per tick over 1000 ticks of a 0 → 100 mm move (50 mm/s,
/// 500 mm/s²: the reference and the shaped setpoint both move during all of them), started
/// once the runtime has been still for the shaper's duration after boot (steady state), and
/// then over 1000 ticks of the same move with the shaper changed mid-move (the transition:
/// the old and the new table both run, see `beamshaper::engine`).
fn tick_cost(buf: &mut Buffered<'_>, label: &str, s: &Settings) {
    let p = match RunParams::from_settings(s) {
        Ok(p) => p,
        Err(_) => {
            let _ = writeln!(buf, "tick-cost {label} err");
            return;
        }
    };
    let taps = p.taps.taps().len();
    // SAFETY: single-threaded bare-metal program, no interrupts touch RT.
    #[allow(static_mut_refs)]
    let rt = Runtime::init_in_place(unsafe { &mut RT });
    rt.configure_at_boot(p, 0);
    for _ in 0..=rt.engine().settle_ticks() {
        rt.tick(&TickInput::default());
    }
    if rt.start_move(100_000_000, 5.0e7, 5.0e8).is_err() {
        let _ = writeln!(buf, "tick-cost {label} move-err");
        return;
    }
    for _ in 0..50 {
        rt.tick(&TickInput::default());
    }
    let (counts, moving) = measure(rt, 1000);
    let _ = writeln!(
        buf,
        "tick-cost {label} path={} taps={taps} ticks=1000 moving={moving} systick_counts={counts} instructions_per_tick~{}",
        s.path.name(),
        counts as u64 * 40 / 1000
    );
    // The same shaper 3 % lower in frequency, switched in mid-move.
    let mut t = s.clone();
    for m in t.modes.iter_mut().flatten() {
        m.freq_hz *= 0.97;
    }
    let switched = RunParams::from_settings(&t).map(|q| rt.request(q));
    rt.tick(&TickInput::default());
    let stages = rt.status().stages;
    let in_flight = rt.status().taps_in_flight;
    let (counts, moving) = measure(rt, 1000);
    let _ = writeln!(
        buf,
        "tick-cost {label} path={} transition taps_in_flight={in_flight} stages={stages} ticks=1000 moving={moving} accepted={} systick_counts={counts} instructions_per_tick~{}",
        s.path.name(),
        matches!(switched, Ok(Ok(_))),
        counts as u64 * 40 / 1000
    );
    buf.flush();
}

/// SysTick counts of `n` ticks, and whether the move still runs after them.
fn measure(rt: &mut Runtime, n: u32) -> (u32, bool) {
    let t0 = cortex_m::peripheral::SYST::get_current();
    for _ in 0..n {
        core::hint::black_box(rt.tick(core::hint::black_box(&TickInput::default())));
    }
    let t1 = cortex_m::peripheral::SYST::get_current();
    (t0.wrapping_sub(t1) & 0x00ff_ffff, rt.status().moving)
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
