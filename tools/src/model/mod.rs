//! The beam on its moving base (paper §2): rig file, Galerkin model, exact simulation, and the
//! command side (moves and shaping by the firmware's own engine).
//!
//! - [`rig`]: the TOML rig file.
//! - [`basis`]: the clamped–free basis functions and λ_i (eqs. 10–11).
//! - [`galerkin`]: M, K (eqs. 12–20), extensions, Rayleigh damping (eqs. 21–22), modes (eq. 24).
//! - [`sim`]: exact modal time integration, base-motion and base-force driven.
//! - [`statespace`]: continuous and ZOH-discrete state-space forms (both drives).
//! - [`mount`]: the resonance of a mount that carries the beam, as the rig shows it.

pub mod basis;
pub mod galerkin;
pub mod modes_report;
pub mod mount;
pub mod rig;
pub mod sim;
pub mod statespace;

pub use galerkin::{BeamModel, ModelOptions, Orientation};
pub use rig::Rig;
pub use statespace::StateSpace;

use anyhow::{anyhow, Result};
use beamshaper::engine::{Engine, NumericPath, TapTable};
use beamshaper::reference::TrapezoidMove;
use beamshaper::shaper::Shaper;

/// Internal simulation rate (Hz): the firmware's default tick.
pub const SIM_RATE_HZ: f64 = 1000.0;

/// Reference base positions (m) of a trapezoidal move from `start_m` to `target_m` at
/// `speed_m_s`, `accel_m_s2`, sampled at `tick_hz` by the firmware core's own generator
/// (`beamshaper::reference::TrapezoidMove`, nm counts), followed by `hold_s` at the target.
/// Returns the samples and the index of the first sample at the target.
pub fn trapezoid_reference(
    start_m: f64,
    target_m: f64,
    speed_m_s: f64,
    accel_m_s2: f64,
    tick_hz: f64,
    hold_s: f64,
) -> Result<(Vec<f64>, usize)> {
    let nm = |m: f64| (m * 1e9).round() as i32;
    let mut mv = TrapezoidMove::new(
        nm(start_m),
        nm(target_m),
        (speed_m_s * 1e9) as f32,
        (accel_m_s2 * 1e9) as f32,
        tick_hz as f32,
    )
    .map_err(|e| anyhow!("move profile refused: {e:?}"))?;
    let mut v = vec![start_m];
    while !mv.done() {
        v.push(mv.next() as f64 * 1e-9);
    }
    let end = v.len() - 1;
    v.extend(std::iter::repeat(target_m).take((hold_s * tick_hz) as usize));
    Ok((v, end))
}

/// Shapes reference positions (m, one per tick at `tick_hz`) with the firmware core's run-time
/// engine (`beamshaper::engine`, the code the timer interrupt runs), on `path`.
pub fn shape_with_engine(
    shaper: &Shaper,
    tick_hz: f64,
    reference_m: &[f64],
    path: NumericPath,
) -> Result<Vec<f64>> {
    let n = ((shaper.duration_s() * tick_hz) as usize + 4)
        .next_power_of_two()
        .max(2);
    macro_rules! run {
        ($n:expr) => {{
            let taps = TapTable::from_shaper(shaper, tick_hz, $n)
                .map_err(|e| anyhow!("shaper does not fit: {e:?}"))?;
            let x0 = (reference_m[0] * 1e9).round() as i32;
            let mut e: Box<Engine<$n>> = Box::new(Engine::new(x0));
            e.install(taps, path, x0);
            Ok(reference_m
                .iter()
                .map(|&r| e.tick((r * 1e9).round() as i32) as f64 * 1e-9)
                .collect())
        }};
    }
    match n {
        0..=4096 => run!(4096),
        4097..=65536 => run!(65536),
        _ => run!(1_048_576),
    }
}
