//! The move fit: the natural frequency and damping ratio of each watched mode from one whole
//! move, by variable projection (Golub & Pereyra, SIAM J. Numer. Anal. 10, 1973) over a
//! modal output model. No heap, no panic, bounded work.
//!
//! Model, on the decimated samples `k` of the move (rate `fs`):
//!
//! `y[k] = b_0 u[k] + b_1 Δu[k] + b_2 Δ²u[k] + Σ_r (c_r h_r[k] + d_r Δh_r[k] + g_r[k]) + e`
//!
//! `y` the tip acceleration, `u` the setpoint's acceleration (m/s²), `Δ` the backward
//! difference, and `h_r = H_r(q) u` the relative-acceleration response of mode r,
//! `H_r(s) = s² / (s² + 2ζ_r ω_r s + ω_r²)` (a clamped beam on a moving base: each mode's
//! coordinate obeys `η̈ + 2ζω η̇ + ω² η = −Γ ÿ_base`), discretised by the bilinear transform
//! prewarped at ω_r. The `b` terms carry the carriage (the drive follows the setpoint with a
//! lag), the `d_r` terms a small delay of each mode's response, `g_r` (any combination of two
//! free responses of the mode's recursion) the vibration the move started with. For given (ω_r, ζ_r) the model is
//! linear in the rest: its least-squares residual is the cost, and (ω_r, ζ_r) are searched,
//! mode by mode, on a grid within ±[`super::MATCH_RANGE`] of the shaper's frequency (then a
//! parabola through the best three points). The shaped setpoint hardly excites the modes at
//! their frequencies (that is what the shaper is for), but the beam still bends and rings
//! *during* the move; the whole move carries the modes, the residual after it does not.

use super::MATCH_RANGE;
use crate::config::MAX_MODES;

/// Decimated samples one move can hold (at 50 Hz, 20.5 s).
pub const MOVE_LEN: usize = 1024;
/// Frequency grid points per mode and pass.
pub const FREQ_GRID: usize = 15;
/// Zoom stages after the coarse grid (each 4 more evaluations at half the spacing).
pub const ZOOMS: usize = 2;
/// Damping grid points per mode and pass.
pub const ZETA_GRID: usize = 5;
/// Damping ratio search range.
pub const ZETA_RANGE: (f32, f32) = (0.002, 0.2);
/// Passes over the modes.
pub const PASSES: usize = 2;
const P_MAX: usize = 3 + 4 * MAX_MODES + 1;

/// The decimated setpoint acceleration and tip acceleration of one move.
#[derive(Clone, Debug)]
pub struct MoveBuffer {
    u: [f32; MOVE_LEN],
    y: [f32; MOVE_LEN],
    len: usize,
}

impl Default for MoveBuffer {
    fn default() -> Self {
        Self::new()
    }
}

impl MoveBuffer {
    /// Empty.
    pub const fn new() -> Self {
        MoveBuffer {
            u: [0.0; MOVE_LEN],
            y: [0.0; MOVE_LEN],
            len: 0,
        }
    }

    /// Forgets the samples.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Full.
    pub fn is_full(&self) -> bool {
        self.len >= MOVE_LEN
    }

    /// Keeps the first `len` samples.
    pub fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }

    /// Appends one pair (ignored when full).
    pub fn push(&mut self, u_m_s2: f32, y_m_s2: f32) {
        if let (Some(u), Some(y)) = (self.u.get_mut(self.len), self.y.get_mut(self.len)) {
            *u = u_m_s2;
            *y = y_m_s2;
            self.len += 1;
        }
    }
}

/// One mode of the model: natural frequency (Hz) and damping ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModalGuess {
    /// Natural frequency (Hz).
    pub freq_hz: f32,
    /// Damping ratio.
    pub zeta: f32,
}

/// Bilinear (prewarped) biquad of `s²/(s² + 2ζωs + ω²)` at rate `fs`: `(b0, b1, b2, a1, a2)`.
fn biquad(m: ModalGuess, fs: f32) -> [f32; 5] {
    let w = 2.0 * core::f32::consts::PI * m.freq_hz;
    let k = w / tan_small(w / (2.0 * fs));
    let (k2, w2, zk) = (k * k, w * w, 2.0 * m.zeta * w * k);
    let a0 = k2 + zk + w2;
    [
        k2 / a0,
        -2.0 * k2 / a0,
        k2 / a0,
        (2.0 * w2 - 2.0 * k2) / a0,
        (k2 - zk + w2) / a0,
    ]
}

/// `tan x` for `0 ≤ x < 1.5` (below Nyquist: `x = π f / fs`) by the Taylor series of sin and
/// cos to x¹³ and x¹⁴ (error below 1e-7 there), without the general range reduction of libm's
/// `tanf` (its code is larger than the watch's fit).
fn tan_small(x: f32) -> f32 {
    let x2 = x * x;
    let mut sin = 1.0f32;
    let mut cos = 1.0f32;
    // Horner from the highest term: sin x = x(1 − x²/(2·3)(1 − x²/(4·5)(…))).
    for k in (1..=6).rev() {
        let k = k as f32;
        sin = 1.0 - x2 / ((2.0 * k) * (2.0 * k + 1.0)) * sin;
        cos = 1.0 - x2 / ((2.0 * k - 1.0) * (2.0 * k)) * cos;
    }
    x * sin / cos
}

/// The least-squares residual `Σe²` of the model with `modes` on `buf` (f32 sums, f64
/// solve), or `None` if singular.
pub fn cost(buf: &MoveBuffer, modes: &[ModalGuess], fs: f32) -> Option<f64> {
    let m = modes.len().min(MAX_MODES);
    let p = 3 + 4 * m + 1;
    let mut coef = [[0.0f32; 5]; MAX_MODES];
    for (c, g) in coef.iter_mut().zip(modes.iter()) {
        *c = biquad(*g, fs);
    }
    // Filter states (direct form II transposed) and previous outputs, per mode.
    let mut st = [[0.0f32; 2]; MAX_MODES];
    let mut h_prev = [0.0f32; MAX_MODES];
    // Free responses of each mode from two initial states (the beam need not start at rest):
    // x[k] = −a1 x[k−1] − a2 x[k−2], newest first.
    let mut free = [[[1.0f32, 0.0], [0.0, 1.0]]; MAX_MODES];
    let (mut u1, mut u2) = (0.0f32, 0.0f32);
    let mut r = [[0.0f32; P_MAX]; P_MAX];
    let mut q = [0.0f32; P_MAX];
    let mut yy = 0.0f64;
    for (&u, &y) in buf.u.iter().zip(buf.y.iter()).take(buf.len) {
        let mut phi = [0.0f32; P_MAX];
        phi[0] = u;
        phi[1] = u - u1;
        phi[2] = u - 2.0 * u1 + u2;
        (u2, u1) = (u1, u);
        for r_ in 0..m {
            let c = coef[r_];
            let s = &mut st[r_];
            let h = c[0] * u + s[0];
            s[0] = c[1] * u - c[3] * h + s[1];
            s[1] = c[2] * u - c[4] * h;
            phi[3 + 4 * r_] = h;
            phi[4 + 4 * r_] = h - h_prev[r_];
            h_prev[r_] = h;
            for (j, x) in free[r_].iter_mut().enumerate() {
                let next = -c[3] * x[0] - c[4] * x[1];
                *x = [next, x[0]];
                phi[5 + 4 * r_ + j] = next;
            }
        }
        phi[p - 1] = 1.0;
        for i in 0..p {
            for j in i..p {
                r[i][j] += phi[i] * phi[j];
            }
            q[i] += phi[i] * y;
        }
        yy += (y as f64) * (y as f64);
    }
    solve_residual(&r, &q, yy, p)
}

/// `Σy² − θᵀq` of the Jacobi-scaled normal equations (Cholesky in f32 with a 1e-6 ridge on
/// the unit diagonal: the M4's FPU is single precision).
fn solve_residual(r: &[[f32; P_MAX]; P_MAX], q: &[f32; P_MAX], yy: f64, p: usize) -> Option<f64> {
    let mut scale = [0.0f32; P_MAX];
    for i in 0..p {
        let d = r[i][i];
        scale[i] = if d > 0.0 { 1.0 / libm::sqrtf(d) } else { 0.0 };
    }
    let mut l = [[0.0f32; P_MAX]; P_MAX];
    for i in 0..p {
        for j in 0..=i {
            let mut s = r[j][i] * scale[i] * scale[j] + if i == j { 1e-6 } else { 0.0 };
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if !(s > 0.0) {
                    return None;
                }
                l[i][i] = libm::sqrtf(s);
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // θᵀq = ‖L⁻¹ q_scaled‖².
    let mut z = [0.0f32; P_MAX];
    let mut tq = 0.0f64;
    for i in 0..p {
        let mut s = q[i] * scale[i];
        for k in 0..i {
            s -= l[i][k] * z[k];
        }
        z[i] = s / l[i][i];
        tq += (z[i] as f64) * (z[i] as f64);
    }
    let c = yy - tq;
    c.is_finite().then_some(c.max(0.0))
}

/// Minimum of a parabola through `(−1, c0), (0, c1), (1, c2)` (offset in grid steps, within
/// ±0.5 when `c1` is the smallest).
fn parabola(c0: f64, c1: f64, c2: f64) -> f32 {
    let den = c0 - 2.0 * c1 + c2;
    if den > 0.0 {
        (0.5 * (c0 - c2) / den).clamp(-0.5, 0.5) as f32
    } else {
        0.0
    }
}

/// A search grid of one parameter: `n` points from `lo` in ratios of `ratio`, then [`ZOOMS`]
/// stages of 5 points in ratios of `zoom[i]` around the best, then a parabola through the best
/// three (its offset applied as `exp(off·ln zoom[last])` to second order, `ln_last`).
struct Grid {
    lo: f32,
    ratio: f32,
    n: usize,
    zoom: [f32; ZOOMS],
    ln_last: f32,
}

/// The frequency grid: ±[`MATCH_RANGE`] (0.65 … 1.35 × the shaper's frequency) in
/// [`FREQ_GRID`] = 15 points, ratio (1.35/0.65)^(1/14) = 1.053593, zooms 1.026447 and
/// 1.013137 (its square and fourth roots), ln 1.013137 = 0.013051 (checked by a host test).
pub const FREQ_RATIOS: (f32, [f32; ZOOMS], f32) = (1.053_593, [1.026_447, 1.013_137], 0.013_051);
/// The damping grid: [`ZETA_RANGE`] 0.002 … 0.2 in [`ZETA_GRID`] = 5 points, ratio
/// 100^(1/4) = 3.162278, zooms 1.778279 and 1.333521, ln 1.333521 = 0.287823.
pub const ZETA_RATIOS: (f32, [f32; ZOOMS], f32) = (3.162_278, [1.778_279, 1.333_521], 0.287_823);

/// Searches one parameter of mode `idx` on `grid`; writes the best into `modes`. Returns
/// false if the best of the coarse grid lies on its edge.
fn search(
    buf: &MoveBuffer,
    modes: &mut [ModalGuess],
    idx: usize,
    fs: f32,
    grid: &Grid,
    set: fn(&mut ModalGuess, f32),
) -> bool {
    let m = modes.len().min(MAX_MODES);
    let mut trial = [ModalGuess {
        freq_hz: 1.0,
        zeta: 0.01,
    }; MAX_MODES];
    trial[..m].copy_from_slice(&modes[..m]);
    let mut eval = |v: f32| {
        if let Some(t) = trial.get_mut(idx) {
            set(t, v);
        }
        cost(buf, &trial[..m], fs).unwrap_or(f64::INFINITY)
    };
    let n = grid.n.max(3);
    let (mut best_v, mut best_c, mut best_i) = (grid.lo, f64::INFINITY, 0);
    let mut v = grid.lo;
    for i in 0..n {
        let c = eval(v);
        if c < best_c {
            (best_v, best_c, best_i) = (v, c, i);
        }
        v *= grid.ratio;
    }
    let inside = best_i > 0 && best_i + 1 < n;
    let mut side = [f64::INFINITY; 2];
    for &r in grid.zoom.iter() {
        let center = best_v;
        let points = [
            center / (r * r),
            center / r,
            center,
            center * r,
            center * r * r,
        ];
        let mut costs = [f64::INFINITY; 5];
        for (k, (c, &p)) in costs.iter_mut().zip(points.iter()).enumerate() {
            *c = if k == 2 { best_c } else { eval(p) };
        }
        let mut k_best = 2;
        for k in 0..5 {
            if costs[k] < costs[k_best] {
                k_best = k;
            }
        }
        best_v = points[k_best];
        best_c = costs[k_best];
        side = [
            costs
                .get(k_best.wrapping_sub(1))
                .copied()
                .unwrap_or(f64::INFINITY),
            costs.get(k_best + 1).copied().unwrap_or(f64::INFINITY),
        ];
    }
    let off = if side[0].is_finite() && side[1].is_finite() {
        parabola(side[0], best_c, side[1])
    } else {
        0.0
    };
    let x = off * grid.ln_last;
    if let Some(t) = modes.get_mut(idx) {
        set(t, best_v * (1.0 + x + 0.5 * x * x));
    }
    inside
}

/// Fits the modes (starting from `modes`, the shaper's) to the move in `buf`; returns, per
/// mode, the fitted mode or `None` where the best frequency lies at the edge of the search
/// range (no mode there).
pub fn fit_modes(
    buf: &MoveBuffer,
    modes: &[ModalGuess],
    fs: f32,
) -> [Option<ModalGuess>; MAX_MODES] {
    let m = modes.len().min(MAX_MODES);
    let mut cur = [ModalGuess {
        freq_hz: 1.0,
        zeta: 0.01,
    }; MAX_MODES];
    cur[..m].copy_from_slice(&modes[..m]);
    let mut inside = [false; MAX_MODES];
    let r = MATCH_RANGE as f32;
    for _ in 0..PASSES {
        for i in 0..m {
            let f_grid = Grid {
                lo: modes[i].freq_hz * (1.0 - r),
                ratio: FREQ_RATIOS.0,
                n: FREQ_GRID,
                zoom: FREQ_RATIOS.1,
                ln_last: FREQ_RATIOS.2,
            };
            inside[i] = search(buf, &mut cur[..m], i, fs, &f_grid, |g, v| g.freq_hz = v);
            let z_grid = Grid {
                lo: ZETA_RANGE.0,
                ratio: ZETA_RATIOS.0,
                n: ZETA_GRID,
                zoom: ZETA_RATIOS.1,
                ln_last: ZETA_RATIOS.2,
            };
            search(buf, &mut cur[..m], i, fs, &z_grid, |g, v| g.zeta = v);
        }
    }
    let mut out = [None; MAX_MODES];
    for i in 0..m {
        if inside[i] {
            out[i] = Some(cur[i]);
        }
    }
    out
}
