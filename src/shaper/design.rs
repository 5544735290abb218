//! Single-mode input-shaper designs.
//!
//! Notation (paper §4): ω = 2π·f the natural angular frequency (rad/s), ζ the damping
//! ratio, ω_d = ω·√(1−ζ²) the damped angular frequency, T_d = 2π/ω_d the damped period,
//! K = exp(−ζπ/√(1−ζ²)).
//!
//! | kind  | impulses | duration | source |
//! |-------|----------|----------|--------|
//! | ZV    | 2 | T_d/2 | paper eq. (30); Singer & Seering 1990 |
//! | ZVD   | 3 | T_d   | paper eq. (31) |
//! | ZVDD  | 4 | 3T_d/2 | paper eq. (32) |
//! | ZVDDD | 5 | 2T_d  | binomial continuation of eqs. (30)–(32) |
//! | MZV   | 3 | 3T_d/4 | Singhose, "modified ZV" (impulses at 0, 3T_d/8, 3T_d/4) |
//! | EI    | 3 | T_d   | Singhose, Seering & Singer 1994 (extra-insensitive, V_tol) |
//! | 2-hump EI | 4 | 3T_d/2 | Singhose, Porter, Tuttle & Singer 1997 |
//! | 3-hump EI | 5 | 2T_d  | Singhose et al. 1997 |
//! | UM-ZV | 3 (+1, −1, +1) | ≈ T_d/3 | Singhose, Seering & Singer 1990 (unity magnitude) |
//!
//! The EI family uses the closed forms exact for ζ = 0 (V = V_tol at the design
//! frequency, V = 0 at the humps' zeros) with the K-weighting that keeps them near-exact
//! for the light damping of flexible structures (ζ ≲ 0.1). UM-ZV is solved numerically
//! (Newton on the two zero-vibration equations) so it stays exactly zero-vibration at any
//! ζ < 0.3.

use super::{Impulse, Shaper, ShaperError, MAX_IMPULSES};
use core::f64::consts::PI;

/// Which single-mode shaper to design.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ShaperKind {
    /// Zero vibration, 2 impulses (paper eq. 30).
    Zv,
    /// Zero vibration and derivative, 3 impulses (paper eq. 31).
    Zvd,
    /// ZV and two derivatives, 4 impulses (paper eq. 32).
    Zvdd,
    /// ZV and three derivatives, 5 impulses.
    Zvddd,
    /// Modified ZV: 3 impulses over 3/4 of the damped period.
    Mzv,
    /// Extra-insensitive with vibration tolerance `v_tol` (fraction, e.g. 0.05).
    Ei {
        /// Vibration tolerance at the design frequency, as a fraction (0, 0.5).
        v_tol: f64,
    },
    /// Two-hump extra-insensitive.
    Ei2Hump {
        /// Vibration tolerance at the humps, as a fraction (0, 0.5).
        v_tol: f64,
    },
    /// Three-hump extra-insensitive.
    Ei3Hump {
        /// Vibration tolerance at the humps, as a fraction (0, 0.5).
        v_tol: f64,
    },
    /// Unity-magnitude zero-vibration shaper with a negative impulse (+1, −1, +1).
    UmZv,
}

/// Default vibration tolerance of the EI shapers (5 %).
pub const DEFAULT_V_TOL: f64 = 0.05;

impl ShaperKind {
    /// All kinds, with the EI tolerance set to `v_tol`, shortest first-ish order.
    pub fn all(v_tol: f64) -> [ShaperKind; 9] {
        [
            ShaperKind::UmZv,
            ShaperKind::Zv,
            ShaperKind::Mzv,
            ShaperKind::Zvd,
            ShaperKind::Ei { v_tol },
            ShaperKind::Zvdd,
            ShaperKind::Ei2Hump { v_tol },
            ShaperKind::Zvddd,
            ShaperKind::Ei3Hump { v_tol },
        ]
    }

    /// The literature's name, lower case: `zv`, `zvd`, `zvdd`, `zvddd`, `mzv`, `ei`,
    /// `2hei`, `3hei`, `umzv`.
    pub fn name(&self) -> &'static str {
        match self {
            ShaperKind::Zv => "zv",
            ShaperKind::Zvd => "zvd",
            ShaperKind::Zvdd => "zvdd",
            ShaperKind::Zvddd => "zvddd",
            ShaperKind::Mzv => "mzv",
            ShaperKind::Ei { .. } => "ei",
            ShaperKind::Ei2Hump { .. } => "2hei",
            ShaperKind::Ei3Hump { .. } => "3hei",
            ShaperKind::UmZv => "umzv",
        }
    }

    /// Parses a name as printed by [`ShaperKind::name`] (case-insensitive; `ei2`, `ei3`,
    /// `2hump_ei`, `3hump_ei`, `um-zv` are accepted too). `v_tol` is used by the EI kinds.
    pub fn from_name(name: &str, v_tol: f64) -> Option<ShaperKind> {
        let mut buf = [0u8; 16];
        let b = name.as_bytes();
        if b.len() > buf.len() {
            return None;
        }
        for (d, s) in buf.iter_mut().zip(b) {
            *d = s.to_ascii_lowercase();
        }
        Some(match &buf[..b.len()] {
            b"zv" => ShaperKind::Zv,
            b"zvd" => ShaperKind::Zvd,
            b"zvdd" => ShaperKind::Zvdd,
            b"zvddd" => ShaperKind::Zvddd,
            b"mzv" => ShaperKind::Mzv,
            b"ei" => ShaperKind::Ei { v_tol },
            b"2hei" | b"ei2" | b"2hump_ei" | b"2-hump-ei" => ShaperKind::Ei2Hump { v_tol },
            b"3hei" | b"ei3" | b"3hump_ei" | b"3-hump-ei" => ShaperKind::Ei3Hump { v_tol },
            b"umzv" | b"um-zv" | b"um_zv" => ShaperKind::UmZv,
            _ => return None,
        })
    }

    /// The EI vibration tolerance, if this kind has one.
    pub fn v_tol(&self) -> Option<f64> {
        match *self {
            ShaperKind::Ei { v_tol }
            | ShaperKind::Ei2Hump { v_tol }
            | ShaperKind::Ei3Hump { v_tol } => Some(v_tol),
            _ => None,
        }
    }
}

/// Validated design parameters: damped period T_d (s), K, ζω (1/s), ω_d (rad/s).
struct Mode {
    td: f64,
    k: f64,
    sigma: f64,
    wd: f64,
}

fn mode(freq_hz: f64, zeta: f64) -> Result<Mode, ShaperError> {
    if !freq_hz.is_finite() || freq_hz <= 0.0 {
        return Err(ShaperError::Frequency);
    }
    if !zeta.is_finite() || !(0.0..1.0).contains(&zeta) {
        return Err(ShaperError::Damping);
    }
    let w = 2.0 * PI * freq_hz;
    let df = libm::sqrt(1.0 - zeta * zeta);
    let wd = w * df;
    Ok(Mode {
        td: 2.0 * PI / wd,
        k: libm::exp(-zeta * PI / df),
        sigma: zeta * w,
        wd,
    })
}

/// Designs a single-mode shaper for natural frequency `freq_hz` (Hz, > 0) and damping
/// ratio `zeta` (0 ≤ ζ < 1). Amplitudes sum to 1; the first impulse is at t = 0.
///
/// Errors: [`ShaperError::Frequency`], [`ShaperError::Damping`], [`ShaperError::Tolerance`]
/// (EI kinds), [`ShaperError::NoConvergence`] (UM-ZV at ζ ≥ 0.3).
pub fn design(kind: ShaperKind, freq_hz: f64, zeta: f64) -> Result<Shaper, ShaperError> {
    let m = mode(freq_hz, zeta)?;
    if let Some(v) = kind.v_tol() {
        if !v.is_finite() || v <= 0.0 || v >= 0.5 {
            return Err(ShaperError::Tolerance);
        }
    }
    let half = 0.5 * m.td;
    let k = m.k;
    let mut a = [0.0f64; 5];
    let mut t = [0.0f64; 5];
    let n = match kind {
        ShaperKind::Zv => binomial(1, k, half, &mut a, &mut t),
        ShaperKind::Zvd => binomial(2, k, half, &mut a, &mut t),
        ShaperKind::Zvdd => binomial(3, k, half, &mut a, &mut t),
        ShaperKind::Zvddd => binomial(4, k, half, &mut a, &mut t),
        ShaperKind::Mzv => {
            // Impulses at 0, 3T_d/8, 3T_d/4 (phases 0°, 135°, 270°): a2 = √2·a1 cancels
            // the undamped residual; damping weighting K' = exp(−0.75ζπ/√(1−ζ²)).
            let kk = libm::pow(k, 0.75);
            let a1 = 1.0 - core::f64::consts::FRAC_1_SQRT_2;
            a[..3].copy_from_slice(&[a1, (core::f64::consts::SQRT_2 - 1.0) * kk, a1 * kk * kk]);
            t[..3].copy_from_slice(&[0.0, 0.375 * m.td, 0.75 * m.td]);
            3
        }
        ShaperKind::Ei { v_tol } => {
            let a1 = 0.25 * (1.0 + v_tol);
            a[..3].copy_from_slice(&[a1, 0.5 * (1.0 - v_tol) * k, a1 * k * k]);
            t[..3].copy_from_slice(&[0.0, half, m.td]);
            3
        }
        ShaperKind::Ei2Hump { v_tol } => {
            let v2 = v_tol * v_tol;
            let x = libm::cbrt(v2 * (libm::sqrt(1.0 - v2) + 1.0));
            let a1 = (3.0 * x * x + 2.0 * x + 3.0 * v2) / (16.0 * x);
            let a2 = (0.5 - a1) * k;
            a[..4].copy_from_slice(&[a1, a2, a2 * k, a1 * k * k * k]);
            t[..4].copy_from_slice(&[0.0, half, m.td, 3.0 * half]);
            4
        }
        ShaperKind::Ei3Hump { v_tol } => {
            let k2 = k * k;
            let a1 = 0.0625 * (1.0 + 3.0 * v_tol + 2.0 * libm::sqrt(2.0 * (v_tol + 1.0) * v_tol));
            let a2 = 0.25 * (1.0 - v_tol) * k;
            let a3 = (0.5 * (1.0 + v_tol) - 2.0 * a1) * k2;
            a.copy_from_slice(&[a1, a2, a3, a2 * k2, a1 * k2 * k2]);
            t.copy_from_slice(&[0.0, half, m.td, 3.0 * half, 2.0 * m.td]);
            5
        }
        ShaperKind::UmZv => {
            let (t2, t3) = um_zv_times(&m)?;
            a[..3].copy_from_slice(&[1.0, -1.0, 1.0]);
            t[..3].copy_from_slice(&[0.0, t2, t3]);
            3
        }
    };
    // Normalise to unity DC gain (the K-weighted forms sum to 1 only at ζ = 0).
    let sum: f64 = a[..n].iter().sum();
    let mut v: heapless::Vec<Impulse, MAX_IMPULSES> = heapless::Vec::new();
    for i in 0..n {
        let _ = v.push(Impulse {
            amplitude: a[i] / sum,
            time_s: t[i],
        });
    }
    Shaper::from_impulses(&v)
}

/// The ZV family as the binomial expansion of `(1 + K·z^(−T_d/2))^n / (1+K)^n`:
/// A_j = C(n,j)·K^j/(1+K)^n at t_j = j·T_d/2 (eqs. 30–32 for n = 1, 2, 3).
fn binomial(n: usize, k: f64, half: f64, a: &mut [f64; 5], t: &mut [f64; 5]) -> usize {
    let mut c = 1.0f64; // C(n, j)
    let mut kj = 1.0f64; // K^j
    let norm = libm::pow(1.0 + k, n as f64);
    for j in 0..=n {
        a[j] = c * kj / norm;
        t[j] = j as f64 * half;
        c = c * (n - j) as f64 / (j + 1) as f64;
        kj *= k;
    }
    n + 1
}

/// Impulse times (t2, t3) of the damped UM-ZV shaper with amplitudes (+1, −1, +1):
/// Newton's method on `1 − e^{s t2} + e^{s t3} = 0`, s = ζω + iω_d (the zero-vibration
/// condition), started from the undamped solution (T_d/6, T_d/3).
fn um_zv_times(m: &Mode) -> Result<(f64, f64), ShaperError> {
    let (mut t2, mut t3) = (m.td / 6.0, m.td / 3.0);
    let e = |tt: f64| {
        let g = libm::exp(m.sigma * tt);
        (g * libm::cos(m.wd * tt), g * libm::sin(m.wd * tt))
    };
    for _ in 0..50 {
        let (c2, s2) = e(t2);
        let (c3, s3) = e(t3);
        let (rr, ri) = (1.0 - c2 + c3, -s2 + s3);
        if libm::fabs(rr) + libm::fabs(ri) < 1e-14 {
            return if t2 > 0.0 && t3 > t2 {
                Ok((t2, t3))
            } else {
                Err(ShaperError::NoConvergence)
            };
        }
        // d/dt e^{s t} = s e^{s t}, s = σ + iω_d
        let d2 = (-(m.sigma * c2 - m.wd * s2), -(m.sigma * s2 + m.wd * c2));
        let d3 = (m.sigma * c3 - m.wd * s3, m.sigma * s3 + m.wd * c3);
        let det = d2.0 * d3.1 - d3.0 * d2.1;
        if det == 0.0 || !det.is_finite() {
            return Err(ShaperError::NoConvergence);
        }
        let dt2 = (-rr * d3.1 + ri * d3.0) / det;
        let dt3 = (-ri * d2.0 + rr * d2.1) / det;
        t2 += dt2;
        t3 += dt3;
    }
    Err(ShaperError::NoConvergence)
}
