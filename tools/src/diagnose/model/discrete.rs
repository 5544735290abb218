//! Exact discretisation shared by the blocks: a damped second-order filter of a piecewise-linear
//! input ([`second_order`]), the sampled state advance ([`advance`]) and its bounded matrix
//! exponential, values below [`FLUSH_TO_ZERO`] held at exact zero, and the drive's
//! acceleration between samples ([`accel_at`], [`spline_accel`]).

use crate::model::sim::mode_zoh;
use nalgebra::Vector2;

/// y = u + e with `ë + 2ζωė + ω²e = −g_a ü − g_v 2ζω u̇` for a piecewise-linear u: exact
/// (velocity kicks at the samples, constant forcing in between). `g_a = g_v = 1` is the plain
/// 2nd-order low-pass `ÿ + 2ζωẏ + ω²y = 2ζω… = ω² u`; a position loop with velocity and
/// acceleration feed-forward fractions k_v, k_a has `g_v = 1 − k_v`, `g_a = 1 − k_a`; a spring–
/// damper mount driven by its base has `g_a = 1, g_v = 0`.
pub(crate) fn second_order(
    u: &[f64],
    dt: f64,
    omega: f64,
    zeta: f64,
    g_v: f64,
    g_a: f64,
) -> Vec<f64> {
    let (phi, gam) = mode_zoh(omega, zeta, dt);
    let n = u.len();
    let mut x = Vector2::zeros();
    let mut y = Vec::with_capacity(n);
    for k in 0..n {
        let vb = if k == 0 { 0.0 } else { (u[k] - u[k - 1]) / dt };
        let va = if k + 1 < n {
            (u[k + 1] - u[k]) / dt
        } else {
            0.0
        };
        y.push(u[k] + x[0]);
        x[1] -= g_a * (va - vb);
        let f = -g_v * 2.0 * zeta * omega * va;
        x = (phi * x + gam * f).map(at_rest);
    }
    y
}

/// A state or transition element below 1e-200 (SI units) is zero ([`at_rest`]): far below any
/// sensor, far above the subnormal range (below 2.2e-308), where one floating-point operation
/// costs about a hundred cycles. A mode that has rung down while the drive stands still (a
/// heavily damped high mode, a few seconds) would otherwise spend the rest of the recording
/// there: measured, half the run time of a 1000 Hz diagnosis (docs/diagnose.md, session 27).
const FLUSH_TO_ZERO: f64 = 1e-200;

/// `v`, or 0 when |v| < [`FLUSH_TO_ZERO`].
#[inline]
pub(crate) fn at_rest(v: f64) -> f64 {
    if v.abs() < FLUSH_TO_ZERO {
        0.0
    } else {
        v
    }
}

/// One interval of a sampled state-space model: `z ← Φ z` (Φ `dim × dim`, `z` and the scratch
/// `tmp` of length `dim`), without allocating. The sums run column by column as nalgebra's
/// matrix–vector product does, so the result is the same to the bit, but for components held
/// [`at_rest`]. Compiled for AVX as well and chosen at run time where the processor has it
/// (`multiversion`): the same arithmetic four lanes wide, so the same result.
#[multiversion::multiversion(targets("x86_64+avx"))]
pub(crate) fn advance(phi: &nalgebra::DMatrix<f64>, z: &mut [f64], tmp: &mut [f64]) {
    let dim = z.len();
    let a = phi.as_slice();
    tmp.iter_mut().for_each(|v| *v = 0.0);
    for (j, &zj) in z.iter().enumerate() {
        let col = &a[j * dim..(j + 1) * dim];
        for (t, c) in tmp.iter_mut().zip(col) {
            *t += c * zj;
        }
    }
    z.iter_mut()
        .zip(tmp.iter())
        .for_each(|(z, t)| *z = at_rest(*t));
}

/// exp(A·dt), or `None` for a generator far outside the band (largest element of A dt ≥
/// `limit`) or non-finite (the scaling-and-squaring would not end on an infinite norm).
pub(crate) fn bounded_expm(
    a: nalgebra::DMatrix<f64>,
    dt: f64,
    limit: f64,
) -> Option<nalgebra::DMatrix<f64>> {
    let ad = a * dt;
    let norm = ad.amax();
    if !(norm.is_finite() && norm < limit) {
        return None;
    }
    let phi = ad.exp().map(at_rest);
    phi.iter().all(|v| v.is_finite()).then_some(phi)
}

/// Acceleration (m/s²) at sample k of a piecewise-linear path: the velocity step there / dt.
/// The path starts from rest and keeps its last velocity after the last sample (a recording
/// that ends mid-move says nothing of a stop; assuming one put a −v/dt spike of tens of N into
/// the last force sample, which the force calibration then bent its mass and latency to).
pub fn accel_at(y: &[f64], k: usize, dt: f64) -> f64 {
    velocity_step(y, k, dt) / dt
}

/// The velocity step (m/s) at sample k of the piecewise-linear path through `y` ([`accel_at`]
/// times dt): from rest before the first sample, none after the last.
pub(crate) fn velocity_step(y: &[f64], k: usize, dt: f64) -> f64 {
    let n = y.len();
    let vb = if k == 0 { 0.0 } else { (y[k] - y[k - 1]) / dt };
    let va = if k + 1 < n {
        (y[k + 1] - y[k]) / dt
    } else {
        vb
    };
    va - vb
}

/// Acceleration (m/s²) at every sample of the cubic spline through the samples `y` (spacing
/// `dt` s): its second derivatives M at the knots, `(M_{k−1} + 4 M_k + M_{k+1}) / 6 = a_k` with
/// a_k the piecewise-linear path's [`accel_at`] (the spline's continuity conditions; the rows of
/// the end samples keep only their inner neighbour). Both paths pass through every sample; the
/// linear one spreads a step of acceleration between two samples over three samples, the
/// spline recovers more of it (at Nyquist its gain is 3× the linear path's, exact
/// acceleration 2.47×), so the two bracket what the samples cannot say about the motion
/// between them (de Boor, *A Practical Guide to Splines*, ch. IV).
pub fn spline_accel(y: &[f64], dt: f64) -> Vec<f64> {
    let n = y.len();
    if n < 3 {
        return (0..n).map(|k| accel_at(y, k, dt)).collect();
    }
    // Thomas algorithm on the symmetric (1, 4, 1) / 6 system
    let mut c = vec![0.0; n];
    let mut m: Vec<f64> = (0..n).map(|k| accel_at(y, k, dt)).collect();
    let (off, diag) = (1.0 / 6.0, 4.0 / 6.0);
    c[0] = off / diag;
    m[0] /= diag;
    for k in 1..n {
        let den = diag - off * c[k - 1];
        c[k] = off / den;
        m[k] = (m[k] - off * m[k - 1]) / den;
    }
    for k in (0..n - 1).rev() {
        m[k] -= c[k] * m[k + 1];
    }
    m
}
