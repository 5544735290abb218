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
        tick_cost(&mut buf, label, &s, 0);
    }
    // The tick with the drift watch's setpoint ring armed (one setpoint every 20 ticks: the
    // 50 Hz of a two-mode watch at 1 kHz).
    let mut s = Settings::DEFAULT;
    s.modes = two_mode;
    tick_cost(&mut buf, "2-mode-zvdd", &s, 20);
    watch_cost(&mut buf);
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
fn tick_cost(buf: &mut Buffered<'_>, label: &str, s: &Settings, watch_decimation: u32) {
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
    rt.arm_watch_ring(watch_decimation);
    let watch = if watch_decimation > 0 {
        " watch=on"
    } else {
        ""
    };
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
        "tick-cost {label} path={}{watch} taps={taps} ticks=1000 moving={moving} systick_counts={counts} instructions_per_tick~{}",
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
        "tick-cost {label} path={}{watch} transition taps_in_flight={in_flight} stages={stages} ticks=1000 moving={moving} accepted={} systick_counts={counts} instructions_per_tick~{}",
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

/// A two-mode beam on the carriage (1.1 Hz and 6.9 Hz, ζ = 0.0074, participation 1.57 and
/// 0.87, semi-implicit Euler at the tick), its tip acceleration sampled at 3 200 Hz by a
/// simulated ADXL345 (3.9 mg steps, ±3 steps of pseudo-random noise), for the watch's cost.
struct Beam {
    eta: [(f32, f32); 2],
    sp: [i32; 2],
    noise: u32,
}

impl Beam {
    const MODES: [(f32, f32); 2] = [(1.1, 1.57), (6.9, 0.87)];

    /// One tick (1 ms) with the shaped setpoint (nm): the tip acceleration (m/s²).
    fn tick(&mut self, sp_nm: i32) -> f32 {
        let a = (sp_nm - 2 * self.sp[0] + self.sp[1]) as f32 * 1e-9 * 1e6;
        self.sp = [sp_nm, self.sp[0]];
        let mut acc = a;
        for (e, (f, g)) in self.eta.iter_mut().zip(Self::MODES) {
            let w = 2.0 * core::f32::consts::PI * f;
            let dd = -g * a - 2.0 * 0.0074 * w * e.1 - w * w * e.0;
            e.1 += dd * 1e-3;
            e.0 += e.1 * 1e-3;
            acc += dd;
        }
        acc
    }

    fn sample(&mut self, acc: f32) -> beamshaper::sensor::SensorEvent {
        self.noise = self
            .noise
            .wrapping_mul(1_664_525)
            .wrapping_add(1_013_904_223);
        let n = ((self.noise >> 29) as f32 - 3.5) * 0.0383;
        let q = libm_round((acc + n) / 0.0383) * 0.0383;
        beamshaper::sensor::SensorEvent::Sample(beamshaper::sensor::AccelSample {
            acc_m_s2: q,
            saturated: false,
        })
    }
}

fn libm_round(x: f32) -> f32 {
    (x + if x >= 0.0 { 0.5 } else { -0.5 }) as i32 as f32
}

/// The drift watch's cost per accelerometer sample: a ZV*ZV shaper at 1.1 and 6.9 Hz, the
/// watch on, three 100 mm moves (200 mm/s, 2 m/s²) each followed by the watch's settle
/// window; every accelerometer sample (3 200 Hz, 16 per 5 ticks) is pushed and the watch is
/// polled every 10 ticks. Only the watch's calls are timed (SysTick read before and after each
/// group of calls); the longest poll (the one that fits a move) is reported too.
fn watch_cost(buf: &mut Buffered<'_>) {
    use beamshaper::watch::Watch;
    let zv = |f: f64| {
        Some(ModeSetting {
            kind: ShaperKind::Zv,
            freq_hz: f,
            zeta: 0.0074,
        })
    };
    let mut s = Settings::DEFAULT;
    s.modes = [zv(1.1), zv(6.9), None, None];
    s.watch.enabled = true;
    let Ok(p) = RunParams::from_settings(&s) else {
        let _ = writeln!(buf, "tick-cost watch-estimator err");
        return;
    };
    #[allow(static_mut_refs)]
    let rt = Runtime::init_in_place(unsafe { &mut RT });
    rt.configure_at_boot(p, 0);
    let mut w = Watch::new();
    w.set_accel(Some(beamshaper::sensor::AccelConfig {
        rate_hz: 3200.0,
        full_scale_m_s2: 156.9,
        lsb_m_s2: 0.0383,
    }));
    let dec = w.configure(&s, 1000);
    rt.arm_watch_ring(dec);
    let mut beam = Beam {
        eta: [(0.0, 0.0); 2],
        sp: [0; 2],
        noise: 1,
    };
    let (mut total, mut worst, mut samples, mut moves) = (0u64, 0u32, 0u64, 0u32);
    let mut acc_prev = 0.0f32;
    for k in 0..15_000u32 {
        if k % 5000 == 0 {
            let target = if (k / 5000) % 2 == 0 { 100_000_000 } else { 0 };
            let _ = rt.start_move(target, 2.0e8, 2.0e9);
        }
        let out = rt.tick(&TickInput::default());
        let acc = beam.tick(out.setpoint_counts);
        // 3.2 samples per tick: 16 per 5 ticks, the last sample of each tick at its end.
        let n = 3 + u32::from(k % 5 == 4);
        let mut evs = [beamshaper::sensor::SensorEvent::Lost; 4];
        for (i, e) in evs.iter_mut().enumerate().take(n as usize) {
            let x = acc_prev + (acc - acc_prev) * (i as f32 + 1.0) / n as f32;
            *e = beam.sample(x);
        }
        acc_prev = acc;
        let t0 = cortex_m::peripheral::SYST::get_current();
        for e in evs.iter().take(n as usize) {
            w.push(*e);
        }
        let t1 = cortex_m::peripheral::SYST::get_current();
        total += (t0.wrapping_sub(t1) & 0x00ff_ffff) as u64;
        samples += n as u64;
        if k % 10 == 9 {
            let t0 = cortex_m::peripheral::SYST::get_current();
            let r = w.poll_ring(rt.watch_ring());
            let t1 = cortex_m::peripheral::SYST::get_current();
            let c = t0.wrapping_sub(t1) & 0x00ff_ffff;
            total += c as u64;
            worst = worst.max(c);
            moves += u32::from(r.is_some());
        }
    }
    let f1 = w.report().modes[0]
        .and_then(|m| m.measured)
        .map_or(0.0, |m| m.freq_hz);
    let _ = writeln!(
        buf,
        "tick-cost watch-estimator samples={samples} moves={moves} state={} f1_hz~{} systick_counts={total} instructions_per_sample~{} longest_poll_instructions~{}",
        w.report().state.name(),
        (f1 * 1000.0) as u32 as f64 / 1000.0,
        total * 40 / samples.max(1),
        worst as u64 * 40
    );
    buf.flush();
}
