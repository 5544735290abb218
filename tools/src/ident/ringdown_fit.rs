//! The joint fit of [`super::ringdowns`]: the forced response of the base-excited mode to the
//! measured base (first-order hold), the projection of the tip deflection onto the linear
//! parameters (variable projection, Golub & Pereyra 1973) and the Levenberg–Marquardt fit of
//! (f, ζ). The model and its state are described in the module doc of [`super::ringdowns`].
//!
//! The linear parameters are two shared (the forced response z₁ and the base b) and three per
//! segment (free decay e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t, offset). The projection uses that
//! block structure: each segment's three columns are orthonormalised (modified Gram–Schmidt,
//! twice), projected out of the shared columns and the data, and the two shared coefficients
//! solved last, O(rows) per evaluation instead of an SVD of the whole design matrix.

use crate::numeric::lm::{minimize, LmOptions};
use nalgebra::{DMatrix, DVector};
use std::f64::consts::PI;
use std::ops::Range;

/// The forced response z₁ of the model to base `b` (sample interval `dt` s, angular frequency
/// `w` rad/s, damping ratio `z`), from rest at the first base position; same length as `b`.
pub(crate) fn forced(b: &[f64], dt: f64, w: f64, z: f64) -> Vec<f64> {
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * z * w]);
    let bb = DMatrix::from_column_slice(2, 1, &[2.0 * z * w, w * w - 4.0 * z * z * w * w]);
    // First-order hold (the base linear between samples, ramp-invariant):
    // exp([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]) gives Φ, Γ₁ (value) and Γ₂ (ramp).
    let mut m = DMatrix::<f64>::zeros(4, 4);
    m.view_mut((0, 0), (2, 2)).copy_from(&(a * dt));
    m.view_mut((0, 2), (2, 1)).copy_from(&(bb * dt));
    m[(2, 3)] = 1.0;
    let e = m.exp();
    let (p00, p01, p10, p11) = (e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]);
    let (g0, g1, h0, h1) = (e[(0, 2)], e[(1, 2)], e[(0, 3)], e[(1, 3)]);
    let u = hold_input(b);
    let (mut x0, mut x1) = (b[0], 0.0); // start at rest at the first base position
    (0..b.len())
        .map(|k| {
            let y = x0;
            let du = u.get(k + 1).map_or(0.0, |v| v - u[k]);
            let u = u[k];
            let n0 = p00 * x0 + p01 * x1 + g0 * u + h0 * du;
            let n1 = p10 * x0 + p11 * x1 + g1 * u + h1 * du;
            x0 = n0;
            x1 = n1;
            y
        })
        .collect()
}

/// The samples of the first-order hold's input: `b` corrected by −Δ²b/12 (the end samples
/// kept). Lines between the raw samples of a band-limited base pass a tone of ω at
/// (sin x/x)², x = ωΔt/2, i.e. 1 − (ωΔt)²/12 (0.8 % low at 20 samples per period, which biased
/// ζ by −1.0·10⁻⁴ on the unquantised link of `tools/tests/ident_closed_loop.rs` at Kp 1); the
/// three-tap correction has the gain 1 + sin²x/3, so that the product is 1 − 8x⁴/45 (the
/// correction of cubic-spline interpolation to fourth order, e.g. Unser, IEEE Signal
/// Process. Mag. 16 (1999) 22–38).
fn hold_input(b: &[f64]) -> Vec<f64> {
    let n = b.len();
    (0..n)
        .map(|k| {
            if k == 0 || k + 1 >= n {
                b[k]
            } else {
                b[k] - (b[k + 1] - 2.0 * b[k] + b[k - 1]) / 12.0
            }
        })
        .collect()
}

/// The linear parameters of the joint fit at one (f, ζ): shared (z₁, b) and per segment
/// (cos, sin, offset) coefficients, in the data's units.
#[derive(Clone, Debug)]
pub(crate) struct Linear {
    /// Coefficients of the forced response z₁ and of the base b.
    pub shared: [f64; 2],
    /// Per segment: coefficients of e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t and 1 (t from the
    /// segment's start).
    pub local: Vec<[f64; 3]>,
}

/// Orthonormalises the columns of `c` (rows × 3) in place by modified Gram–Schmidt applied
/// twice; returns R (upper triangular, c_in = Q R) and which columns were kept (norm above
/// 1e-12 of the largest).
fn mgs2(c: &mut [[f64; 3]]) -> ([[f64; 3]; 3], [bool; 3]) {
    let mut r = [[0.0; 3]; 3];
    let mut keep = [true; 3];
    let norm = |c: &[[f64; 3]], j: usize| c.iter().map(|v| v[j] * v[j]).sum::<f64>().sqrt();
    let big = (0..3).map(|j| norm(c, j)).fold(0.0, f64::max).max(1e-300);
    for j in 0..3 {
        for _pass in 0..2 {
            for i in 0..j {
                if !keep[i] {
                    continue;
                }
                let d: f64 = c.iter().map(|v| v[i] * v[j]).sum();
                r[i][j] += d;
                c.iter_mut().for_each(|v| v[j] -= d * v[i]);
            }
        }
        let n = norm(c, j);
        if n <= 1e-12 * big {
            keep[j] = false;
            c.iter_mut().for_each(|v| v[j] = 0.0);
            continue;
        }
        r[j][j] = n;
        c.iter_mut().for_each(|v| v[j] /= n);
    }
    (r, keep)
}

/// Removes from `x` its projection onto the orthonormal columns `q` (kept ones); returns the
/// projection coefficients.
fn deflate(q: &[[f64; 3]], keep: &[bool; 3], x: &mut [f64]) -> [f64; 3] {
    let mut d = [0.0; 3];
    for j in 0..3 {
        if keep[j] {
            d[j] = q.iter().zip(x.iter()).map(|(v, xv)| v[j] * xv).sum();
            x.iter_mut().zip(q).for_each(|(xv, v)| *xv -= d[j] * v[j]);
        }
    }
    d
}

/// The two shared coefficients (of the deflated columns `g0`, `g1` against the deflated data
/// `yy`): 2 × 2 normal equations of the unit-scaled columns; `None` when they are (nearly)
/// collinear.
fn shared_coefficients(g0: &[f64], g1: &[f64], yy: &[f64]) -> Option<(f64, f64)> {
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
    let (s0, s1) = (
        dot(g0, g0).sqrt().max(1e-300),
        dot(g1, g1).sqrt().max(1e-300),
    );
    let (a, bo, c) = (
        dot(g0, g0) / (s0 * s0),
        dot(g0, g1) / (s0 * s1),
        dot(g1, g1) / (s1 * s1),
    );
    let (r0, r1) = (dot(g0, yy) / s0, dot(g1, yy) / s1);
    let det = a * c - bo * bo;
    if !(det > 1e-14) {
        return None;
    }
    let c0 = (c * r0 - bo * r1) / det / s0;
    let c1 = (a * r1 - bo * r0) / det / s1;
    Some((c0, c1))
}

/// Projected residual of the joint fit at (f, ζ) over the segments `segs` of (b, y) (sample
/// interval `dt` s): (residual over the segments' rows in order, its sum of squares, the
/// linear parameters). `None` outside 0 < ζ < 0.9, f > 0 or for a degenerate design.
pub(crate) fn project(
    b: &[f64],
    y: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f: f64,
    z: f64,
) -> Option<(DVector<f64>, f64, Linear)> {
    if !(f > 0.0 && z > 0.0 && z < 0.9) {
        return None;
    }
    let w = 2.0 * PI * f;
    let wd = w * (1.0 - z * z).sqrt();
    let zf = forced(b, dt, w, z);
    let m: usize = segs.iter().map(|s| s.len()).sum();
    let (mut g0, mut g1, mut yy) = (Vec::with_capacity(m), Vec::with_capacity(m), Vec::new());
    let mut bases = Vec::with_capacity(segs.len());
    for s in segs {
        let mut q: Vec<[f64; 3]> = (0..s.len())
            .map(|i| {
                let t = i as f64 * dt;
                let e = (-z * w * t).exp();
                [e * (wd * t).cos(), e * (wd * t).sin(), 1.0]
            })
            .collect();
        let (r, keep) = mgs2(&mut q);
        let (mut a0, mut a1, mut ay) = (
            zf[s.clone()].to_vec(),
            b[s.clone()].to_vec(),
            y[s.clone()].to_vec(),
        );
        let d0 = deflate(&q, &keep, &mut a0);
        let d1 = deflate(&q, &keep, &mut a1);
        let dy = deflate(&q, &keep, &mut ay);
        g0.extend(a0);
        g1.extend(a1);
        yy.extend(ay);
        bases.push((r, keep, d0, d1, dy));
    }
    let (c0, c1) = shared_coefficients(&g0, &g1, &yy)?;
    let r = DVector::from_iterator(m, (0..m).map(|k| yy[k] - c0 * g0[k] - c1 * g1[k]));
    let ss = r.norm_squared();
    let local = bases
        .iter()
        .map(|(rr, keep, d0, d1, dy)| {
            // R a = Qᵀ(y − c0 z₁ − c1 b), back substitution over the kept columns
            let rhs: Vec<f64> = (0..3).map(|j| dy[j] - c0 * d0[j] - c1 * d1[j]).collect();
            let mut a = [0.0; 3];
            for j in (0..3).rev() {
                if keep[j] {
                    let s: f64 = (j + 1..3).map(|i| rr[j][i] * a[i]).sum();
                    a[j] = (rhs[j] - s) / rr[j][j];
                }
            }
            a
        })
        .collect();
    Some((
        r,
        ss,
        Linear {
            shared: [c0, c1],
            local,
        },
    ))
}

/// LM fit of (f, ζ) over `segs` from (f0, ζ0) on (ln f, ln ζ): (f, ζ, residual sum of
/// squares, linear parameters); `None` when the model cannot be evaluated at the optimum.
pub(crate) fn fit(
    b: &[f64],
    y: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f0: f64,
    z0: f64,
) -> Option<(f64, f64, f64, Linear)> {
    let m: usize = segs.iter().map(|s| s.len()).sum();
    let res = |x: &DVector<f64>| {
        project(b, y, segs, dt, x[0].exp(), x[1].exp())
            .map(|r| r.0)
            .or_else(|| Some(DVector::from_element(m, 1e10)))
    };
    let mut o = LmOptions::new(vec![1e-5, 1e-4]);
    o.max_evaluations = 400;
    let fitr = minimize(&res, DVector::from_vec(vec![f0.ln(), z0.ln()]), &o);
    let (f, z) = (fitr.x[0].exp(), fitr.x[1].exp());
    let (_, ss, lin) = project(b, y, segs, dt, f, z)?;
    Some((f, z, ss, lin))
}

/// The coarse start of the pooled fit: the (residual, f, ζ) of the grid over f in
/// 0.5–2 × `f_peak` (41 log steps, inside `band`) and ζ in {0.005 … 0.1} that leaves the
/// least residual.
pub(crate) fn coarse_start(
    bd: &[f64],
    yd: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f_peak: f64,
    band: (f64, f64),
) -> (f64, f64, f64) {
    let (f_min, f_max) = band;
    let mut best = (f64::INFINITY, f_peak, 0.02);
    for i in 0..41 {
        let f = f_peak * 2f64.powf(-1.0 + i as f64 / 20.0);
        if f < f_min || f > f_max {
            continue;
        }
        for z in [0.005, 0.01, 0.02, 0.05, 0.1] {
            if let Some((_, ss, _)) = project(bd, yd, segs, dt, f, z) {
                if ss < best.0 {
                    best = (ss, f, z);
                }
            }
        }
    }
    best
}

/// The fitted model's tip deflection at the full rate: base `b` (full rate, interval `dt` s),
/// segments `segs_full` (full-rate rows, each the decimated segment × the decimation factor),
/// mode (f, ζ) and linear parameters `lin`. Rows outside the segments get the forced part only.
pub(crate) fn model_tip(
    b: &[f64],
    dt: f64,
    segs_full: &[Range<usize>],
    f: f64,
    z: f64,
    lin: &Linear,
) -> Vec<f64> {
    let w = 2.0 * PI * f;
    let wd = w * (1.0 - z * z).sqrt();
    let zf = forced(b, dt, w, z);
    let mut out: Vec<f64> = zf
        .iter()
        .zip(b)
        .map(|(zv, bv)| lin.shared[0] * zv + lin.shared[1] * bv)
        .collect();
    for (s, a) in segs_full.iter().zip(&lin.local) {
        for k in s.clone() {
            let t = (k - s.start) as f64 * dt;
            let e = (-z * w * t).exp();
            out[k] += a[0] * e * (wd * t).cos() + a[1] * e * (wd * t).sin() + a[2];
        }
    }
    out
}
