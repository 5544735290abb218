//! Percentage residual vibration of an impulse sequence (paper §4; Singer & Seering 1990).
//!
//! For a mode of natural frequency ω (rad/s) and damping ratio ζ, the residual vibration
//! after the last impulse t_N of a sequence (A_i, t_i), relative to the vibration a single
//! unit impulse causes, is
//!
//! `V(ω, ζ) = e^{−ζω t_N} · √( (Σ A_i e^{ζω t_i} cos ω_d t_i)² + (Σ A_i e^{ζω t_i} sin ω_d t_i)² )`
//!
//! with ω_d = ω√(1−ζ²). V = 1 (100 %) for the identity shaper; V = 0 at the design
//! frequency of ZV, ZVD, ZVDD.

use super::Shaper;
use core::f64::consts::PI;

/// Percentage residual vibration `V` of `shaper` for a mode of natural frequency `freq_hz`
/// (Hz) and damping ratio `zeta`, as a **fraction** (0.05 = 5 %).
///
/// Returns NaN for `freq_hz <= 0`, non-finite inputs or `zeta` outside [0, 1).
pub fn residual_vibration(shaper: &Shaper, freq_hz: f64, zeta: f64) -> f64 {
    if !(freq_hz > 0.0) || !freq_hz.is_finite() || !(0.0..1.0).contains(&zeta) {
        return f64::NAN;
    }
    let w = 2.0 * PI * freq_hz;
    let wd = w * libm::sqrt(1.0 - zeta * zeta);
    let sigma = zeta * w;
    let tn = shaper.duration_s();
    let (mut c, mut s) = (0.0f64, 0.0f64);
    for imp in shaper.impulses() {
        // e^{σ(t_i − t_N)} keeps the exponent ≤ 0: no overflow for long shapers.
        let g = imp.amplitude * libm::exp(sigma * (imp.time_s - tn));
        c += g * libm::cos(wd * imp.time_s);
        s += g * libm::sin(wd * imp.time_s);
    }
    libm::sqrt(c * c + s * s)
}

/// The insensitivity band around `freq_hz`: the widest interval `[lo_hz, hi_hz]` that
/// contains `freq_hz` on which `V ≤ v_tol` (fraction) for damping ratio `zeta`.
///
/// Scans in steps of 0.1 % of `freq_hz` from `freq_hz` outwards (up to ×0.02 … ×3) and
/// refines each edge by bisection to 1e-6 relative. Returns `None` if `V(freq_hz) > v_tol`.
pub fn insensitivity_band(
    shaper: &Shaper,
    freq_hz: f64,
    zeta: f64,
    v_tol: f64,
) -> Option<(f64, f64)> {
    let ok = |f: f64| residual_vibration(shaper, f, zeta) <= v_tol;
    if !ok(freq_hz) {
        return None;
    }
    let step = 1e-3 * freq_hz;
    let edge = |dir: f64, limit: f64| -> f64 {
        let mut inside = freq_hz;
        loop {
            let next = inside + dir * step;
            if (dir < 0.0 && next <= limit) || (dir > 0.0 && next >= limit) {
                return limit;
            }
            if !ok(next) {
                // bisect between inside (ok) and next (not ok)
                let (mut a, mut b) = (inside, next);
                while libm::fabs(b - a) > 1e-6 * freq_hz {
                    let m = 0.5 * (a + b);
                    if ok(m) {
                        a = m
                    } else {
                        b = m
                    }
                }
                return a;
            }
            inside = next;
        }
    };
    Some((edge(-1.0, 0.02 * freq_hz), edge(1.0, 3.0 * freq_hz)))
}
