//! Block 6 of the chain, the tip sensor: latency τ, `tip(t − τ)` by a band-limited fractional
//! delay ([`delayed`]; `sensor_delay`); scale g (camera calibration): `g · tip` (`sensor_gain`),
//! or, for a sensor riding on the carriage, on the deflection only: `y + g · w`; a resonance
//! between the tip and its sensor ([`tip_sensor`]).

use super::discrete::second_order;
use super::params::Params;

/// Half-length (samples) of the [`delayed`] interpolation kernel (2 × this many taps).
const DELAY_HALF: usize = 8;

/// Kaiser window shape β of the [`delayed`] kernel.
const DELAY_BETA: f64 = 5.0;

/// `x(t − τ)` between samples by a band-limited fractional delay (held at the ends): a
/// Kaiser-windowed sinc (β [`DELAY_BETA`], 2 × [`DELAY_HALF`] taps, weights scaled to unit DC
/// gain), flat within 0.3 % in amplitude up to 0.4 × the sample rate at every fraction.
/// Linear interpolation, used before, is a low-pass whose gain depends on the fraction
/// (half a sample: cos(πf/r), 0.51 at 0.33 r): at 50–100 Hz a latency of a few ms then also
/// removed 10–50 % of the beam's second mode from the prediction, so the tip latency of
/// `sensor_delay` lost to a position loop (exact between samples) and the force channel's
/// calibrated half-sample latency took its modes' content out of the model (Laakso et al.,
/// "Splitting the unit delay", IEEE Signal Processing Magazine 13(1), 1996).
pub fn delayed(x: &[f64], delay_s: f64, dt: f64) -> Vec<f64> {
    let n = x.len();
    let s = delay_s / dt;
    // x(k − s) = Σ_j w_j x[k + shift + j − h + 1]: the fraction, hence the weights, is the
    // same for every k
    let shift = (-s).floor();
    let a = -s - shift;
    let h = DELAY_HALF as i64;
    let w: Vec<f64> = if a < 1e-12 {
        vec![]
    } else {
        let i0b = crate::diagnose::rate::bessel_i0(DELAY_BETA);
        let raw: Vec<f64> = (0..2 * h)
            .map(|j| {
                let t = a - (j - h + 1) as f64;
                let r = t / h as f64;
                let pt = std::f64::consts::PI * t;
                pt.sin() / pt
                    * crate::diagnose::rate::bessel_i0(DELAY_BETA * (1.0 - r * r).max(0.0).sqrt())
                    / i0b
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|v| v / sum).collect()
    };
    let shift = shift as i64;
    let at = |i: i64| x[i.clamp(0, n as i64 - 1) as usize];
    (0..n as i64)
        .map(|k| {
            let pos = k as f64 - s;
            if pos <= 0.0 {
                x[0]
            } else if pos >= (n - 1) as f64 {
                x[n - 1]
            } else if w.is_empty() {
                at(k + shift)
            } else {
                // the taps' first sample; inside the record, the same sum without the clamps
                let first = k + shift - h + 1;
                if first >= 0 && first + 2 * h <= n as i64 {
                    let taps = &x[first as usize..(first + 2 * h) as usize];
                    w.iter().zip(taps).map(|(wj, xj)| wj * xj).sum()
                } else {
                    let taps = (0..2 * h).map(|j| at(first + j));
                    w.iter().zip(taps).map(|(wj, xj)| wj * xj).sum()
                }
            }
        })
        .collect()
}

/// The tip sensor: absolute tip (root + deflection `w`, the deflection scaled by a sensor on
/// the carriage's gain), late by the sensor latency and scaled by its gain.
pub(crate) fn tip_sensor(p: &Params, root: &[f64], w: &[f64], dt: f64) -> Vec<f64> {
    let g_w = 1.0 + p.sensor_deflection_gain_error;
    let tip: Vec<f64> = root.iter().zip(w).map(|(y, w)| y + g_w * w).collect();
    let tip = match p.tip_filter {
        Some((f, z)) => second_order(&tip, dt, 2.0 * std::f64::consts::PI * f, z, 0.0, 1.0),
        None => tip,
    };
    let tip = if p.sensor_delay_s != 0.0 {
        delayed(&tip, p.sensor_delay_s, dt)
    } else {
        tip
    };
    if p.sensor_gain_error != 0.0 {
        tip.iter()
            .map(|v| (1.0 + p.sensor_gain_error) * v)
            .collect()
    } else {
        tip
    }
}
