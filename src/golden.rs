//! Golden vectors: the same text on the host and on the Cortex-M4 (QEMU `mps2-an386`), so CI
//! can prove the core computes bit-identical results on both.
//!
//! Every floating-point value is printed as its exact bit pattern (hex). Covers the shaper
//! tables of every kind (incl. 0.2 Hz and multi-mode convolutions), their residual vibration,
//! the tap tables (Q2.30 and f32) and full shaped moves through the run-time engine on both
//! numeric paths (every setpoint hashed, every 100th printed).

use crate::config::{ModeSetting, Settings};
use crate::engine::NumericPath;
use crate::runtime::{RunParams, Runtime, TickInput};
use crate::shaper::{design, residual_vibration, Shaper, ShaperKind};
use core::fmt::{Result, Write};

/// Cases of the shaper-table vectors: (natural frequency Hz, damping ratio).
pub const DESIGN_CASES: [(f64, f64); 4] = [(0.2, 0.0074), (1.1, 0.0074), (6.9, 0.02), (50.0, 0.1)];

fn shaper_lines(out: &mut impl Write, tag: &str, s: &Shaper, f: f64, z: f64) -> Result {
    write!(out, "{tag} n={}", s.len())?;
    for i in s.impulses() {
        write!(
            out,
            " {:016x}@{:016x}",
            i.amplitude.to_bits(),
            i.time_s.to_bits()
        )?;
    }
    writeln!(out)?;
    writeln!(
        out,
        "{tag} V {:016x} {:016x} {:016x}",
        residual_vibration(s, 0.9 * f, z).to_bits(),
        residual_vibration(s, f, z).to_bits(),
        residual_vibration(s, 1.1 * f, z).to_bits()
    )
}

/// FNV-1a over the setpoints.
fn fnv(h: u64, v: i32) -> u64 {
    let mut h = h;
    for b in v.to_le_bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// Writes all golden vectors to `out`. Builds its runtime (~90 KiB) on the stack: fine on
/// the host and under QEMU; on the 128 KiB G474 use [`write_golden_in`].
pub fn write_golden(out: &mut impl Write) -> Result {
    let mut slot = core::mem::MaybeUninit::uninit();
    write_golden_in(out, &mut slot)
}

/// [`write_golden`] with the runtime in `slot` (e.g. a `.bss` static, as the firmware keeps
/// it), initialised in place for each case ([`Runtime::init_in_place`], the same state as
/// [`Runtime::new`]), so the stack stays small.
pub fn write_golden_in(out: &mut impl Write, slot: &mut core::mem::MaybeUninit<Runtime>) -> Result {
    for &(f, z) in DESIGN_CASES.iter() {
        for kind in ShaperKind::all(0.05) {
            match design(kind, f, z) {
                Ok(s) => shaper_lines(out, kind.name(), &s, f, z)?,
                Err(e) => writeln!(out, "{} err {:?}", kind.name(), e)?,
            }
        }
    }
    let pairs = [
        (ShaperKind::Zv, 1.1, 6.9),
        (ShaperKind::Zvd, 1.1, 6.9),
        (ShaperKind::Zvdd, 1.1, 6.9),
        (ShaperKind::Zvd, 0.2, 0.6),
    ];
    for (kind, f1, f2) in pairs {
        let s = design(kind, f1, 0.0074).and_then(|a| a.convolve(&design(kind, f2, 0.0074)?));
        match s {
            Ok(s) => shaper_lines(out, "two-mode", &s, f1, 0.0074)?,
            Err(e) => writeln!(out, "two-mode err {:?}", e)?,
        }
    }
    for (rate, path) in [
        (1000u32, NumericPath::Fixed),
        (1000, NumericPath::F32),
        (3333, NumericPath::Fixed),
        (10_000, NumericPath::F32),
    ] {
        let mut s = Settings::DEFAULT;
        s.modes[0] = Some(ModeSetting {
            kind: ShaperKind::Zvd,
            freq_hz: 1.1,
            zeta: 0.0074,
        });
        s.modes[1] = Some(ModeSetting {
            kind: ShaperKind::Zvd,
            freq_hz: 6.9,
            zeta: 0.0074,
        });
        s.tick_rate_hz = rate;
        s.path = path;
        s.max_step_rate_hz = 2_000_000;
        let params = match RunParams::from_settings(&s) {
            Ok(p) => p,
            Err(e) => {
                writeln!(out, "move err {:?}", e)?;
                continue;
            }
        };
        write!(out, "taps rate={rate}")?;
        for t in params.taps.taps() {
            write!(out, " {}:{}:{:08x}", t.delay, t.w_q30, t.w_f32.to_bits())?;
        }
        writeln!(out)?;
        let rt = Runtime::init_in_place(slot);
        rt.configure_at_boot(params, 0);
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        write!(out, "move rate={rate} path={}", path.name())?;
        let ticks = (4 * rate) as usize;
        for (target, speed, accel) in [
            (50_000_000, 2.0e8f32, 2.0e9f32),
            (-12_345_678, 3.0e8, 5.0e9),
        ] {
            if rt.start_move(target, speed, accel).is_err() {
                write!(out, " start-err")?;
            }
            for k in 0..ticks {
                let o = rt.tick(&TickInput::default());
                h = fnv(h, o.setpoint_counts);
                h = fnv(h, o.step.pulses as i32);
                if k % 100 == 0 {
                    write!(out, " {}", o.setpoint_counts)?;
                }
            }
            write!(out, " final={}", rt.status().setpoint_counts)?;
        }
        writeln!(out, " hash={h:016x}")?;
    }
    // A shaper change mid-move (superposition, both paths) and a sine sweep through it.
    for path in [NumericPath::Fixed, NumericPath::F32] {
        let zvd = |f: f64| {
            Some(ModeSetting {
                kind: ShaperKind::Zvd,
                freq_hz: f,
                zeta: 0.0074,
            })
        };
        let mut a = Settings::DEFAULT;
        a.modes[0] = zvd(1.0);
        a.modes[1] = zvd(6.5);
        a.path = path;
        a.max_step_rate_hz = 2_000_000;
        let mut b = a.clone();
        b.modes[0] = Some(ModeSetting {
            kind: ShaperKind::Zvdd,
            freq_hz: 1.1,
            zeta: 0.0074,
        });
        b.modes[1] = zvd(6.9);
        let (Ok(pa), Ok(pb)) = (RunParams::from_settings(&a), RunParams::from_settings(&b)) else {
            writeln!(out, "switch err")?;
            continue;
        };
        let rt = Runtime::init_in_place(slot);
        rt.configure_at_boot(pa.clone(), 0);
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        write!(out, "switch path={}", path.name())?;
        let _ = rt.start_move(80_000_000, 2.0e8, 2.0e9);
        for k in 0..6000u32 {
            if k == 250 && rt.request(pb.clone()).is_err() {
                write!(out, " refused")?;
            }
            if k == 3000 {
                let _ = rt.request(pa.clone());
                let _ = rt.start_sweep(
                    crate::reference::SweepKind::Exponential,
                    0.5,
                    9.0,
                    3.0e6,
                    2.5,
                );
            }
            let o = rt.tick(&TickInput::default());
            h = fnv(h, o.setpoint_counts);
            h = fnv(h, o.step.pulses as i32);
            if k % 250 == 0 {
                write!(out, " {}", o.setpoint_counts)?;
            }
        }
        writeln!(out, " final={} hash={h:016x}", rt.status().setpoint_counts)?;
    }
    writeln!(out, "end")
}
