//! Host-side helpers shared by the tests and benchmarks of the beamshaper core.
//!
//! The reference implementations here are deliberately independent of the core's
//! optimised code paths: plain f64 arithmetic straight from the definitions.

use beamshaper::shaper::Shaper;

/// Exact f64 convolution of integer reference samples with a shaper sampled by linear
/// interpolation between ticks: `y[n] = Σ_i A_i · x((n − t_i·f_tick))`, with `x` linear
/// between samples and `x[k] = x[0]` for k < 0.
pub fn shaped_f64(shaper: &Shaper, tick_rate_hz: f64, x: &[i32]) -> Vec<f64> {
    let at = |pos: f64| -> f64 {
        if pos <= 0.0 {
            return x[0] as f64;
        }
        let k = pos.floor() as usize;
        let frac = pos - k as f64;
        let a = x[k.min(x.len() - 1)] as f64;
        let b = x[(k + 1).min(x.len() - 1)] as f64;
        a + frac * (b - a)
    };
    (0..x.len())
        .map(|n| {
            shaper
                .impulses()
                .iter()
                .map(|i| i.amplitude * at(n as f64 - i.time_s * tick_rate_hz))
                .sum()
        })
        .collect()
}
