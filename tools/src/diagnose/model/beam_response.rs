//! Block 4 of the chain, the beam's response: `η̈_r + 2ζ_rω_r η̇_r + ω_r² η_r = −Γ_r ÿ_r + f_r`,
//! integrated exactly between samples for a piecewise-linear base (as `model::sim`), with the
//! quadratic drag applied as a per-sample impulse (`quadratic_damping`), distributed
//! `f_r = −c_d ∫ φ_r |v| v dx` or on a body at the tip `f_r = −c_t φ_r(l) |v_l| v_l`; a cubic
//! clamp moment `M₃ = k₃ θ³` on the root rotation θ = Σ s_r η_r − c M₃ of the compliant clamp
//! (s_r the root rotation of mode r, c the residual flexibility of the modes not simulated,
//! [`super::beam::ResidualFlexibility`]) as a per-sample modal impulse `f_r = −s_r M₃`
//! ([`cubic_moment`], bounded; `cubic_stiffness`, with the linear k_r in the modes), the tip
//! moved by the same static correction; motor force from eq. (5), `u = J ÿ + hᵀ q̈ − ∫ drag`.

use super::beam::BeamCache;
use super::discrete::{accel_at, at_rest, velocity_step};
use super::params::Params;
use nalgebra::Vector2;

/// Cubic part of a clamp moment, `k₃ θ · min(θ², θ_c²)` (N·m): exactly k₃θ³ up to the bound
/// θ_c and linear beyond it, so the model stays stable and its cost per sample fixed whatever
/// the fitted values. `theta_cap2` (rad²) comes from [`cubic_cap2`].
pub fn cubic_moment(k3: f64, theta: f64, theta_cap2: f64) -> f64 {
    k3 * theta * (theta * theta).min(theta_cap2)
}

/// The bound θ_c² of [`cubic_moment`] for linear clamp stiffness `k_r` (N·m/rad): softening
/// stops where the tangent stiffness k_r + 3k₃θ² would fall below k_r/10 (θ_c² = 0.3 k_r / |k₃|);
/// hardening where it would exceed 10 k_r (θ_c² = 3 k_r / k₃) or where the per-sample impulse
/// of the added stiffness would no longer be stable (3 k₃ θ² Σs_r² dt² ≤ 3, s_r the root
/// rotation of mode r per unit mass-normalised coordinate).
pub fn cubic_cap2(k3: f64, k_r: f64, sum_s2: f64, dt: f64) -> f64 {
    if k3 == 0.0 {
        return f64::INFINITY;
    }
    if k3 < 0.0 {
        0.3 * k_r / -k3
    } else {
        (3.0 * k_r / k3).min(3.0 / (3.0 * k3 * sum_s2.max(1e-300) * dt * dt))
    }
}

/// The beam's modes driven by the root motion (exact per sample for a piecewise-linear root,
/// with the drag and cubic-clamp impulses): the tip deflection (m) and the motor force (N) of
/// eq. (5), the carriage (less a mount mass) moving with `drive`.
///
/// The force is the drive's reading of it: its mean over the sample period, here the interval
/// centred on the sample (the force channel's calibrated latency places it). For the beam that
/// is its momentum change between the half-sample instants over dt, `[M ẏ_r + Σ Γ_r η̇_r]/dt`,
/// exact for the piecewise-linear root — the convention of the carriage's own second
/// difference ([`accel_at`]) and of the coupled mount ([`coupled_mount`]). The instantaneous
/// modal force at the sample would carry a mode at f at 1/sinc(f dt) of what the drive
/// reports: 8 % high for a 22 Hz mode at 100 Hz, 32 % for a 20 Hz mode at 50 Hz, where the
/// calibration can absorb neither (docs/diagnose.md, session 20).
pub(crate) fn beam_response(
    p: &Params,
    root: &[f64],
    drive: &[f64],
    dt: f64,
    c: &BeamCache,
) -> (Vec<f64>, Vec<f64>) {
    let n = root.len();
    let mount_mass = if p.mount.is_some() {
        p.mount_mass_kg
    } else {
        0.0
    };
    let dv: Vec<f64> = (0..n).map(|k| velocity_step(root, k, dt)).collect();
    let k3 = match p.root_stiffness_nm_per_rad {
        Some(_) => p.cubic_root_stiffness_nm_per_rad3,
        None => 0.0,
    };
    let (w, beam_force) = if p.has_drag() || k3 != 0.0 {
        nonlinear_modes(p, k3, root, &dv, dt, c)
    } else {
        let (w, momentum_step) = linear_modes(c, &dv);
        (w, momentum_step.iter().map(|m| m / dt).collect())
    };
    let force = (0..n)
        .map(|k| {
            let acc = dv[k] / dt;
            // the carriage itself moves with the drive, not with the mount
            c.total_mass * acc
                + beam_force[k]
                + (c.base_mass - mount_mass) * (accel_at(drive, k, dt) - acc)
        })
        .collect();
    (w, force)
}

/// Modes driven through at once in [`linear_modes`] (independent chains the processor overlaps).
const MODE_LANES: usize = 4;

/// The linear modes of [`beam_response`] (no drag, no cubic clamp) for the root's velocity
/// steps `dv` (m/s, one per sample): the tip deflection `w` (m) and the modes' momentum change
/// `Σ Γ_r (η̇_r(k+½) − η̇_r(k−½))` (kg m/s) per sample. Each mode is independent of the others,
/// so [`MODE_LANES`] of them run side by side through the samples with their states in
/// registers; the arithmetic per mode is that of [`nonlinear_modes`] without its impulses.
fn linear_modes(c: &BeamCache, dv: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = dv.len();
    let nm = c.omega.len();
    let mut w = vec![0.0; n];
    let mut momentum_step = vec![0.0; n];
    for first in (0..nm).step_by(MODE_LANES) {
        // padding lanes: identity transition, no participation, no tip deflection
        let mut a = [[1.0, 0.0, 0.0, 1.0]; MODE_LANES];
        let (mut g, mut t) = ([0.0; MODE_LANES], [0.0; MODE_LANES]);
        for (j, r) in (first..nm.min(first + MODE_LANES)).enumerate() {
            let m = &c.phi_half[r];
            a[j] = [m[(0, 0)], m[(1, 0)], m[(0, 1)], m[(1, 1)]];
            (g[j], t[j]) = (c.gamma[r], c.tip[r]);
        }
        let (mut x0, mut x1, mut rate_before) =
            ([0.0; MODE_LANES], [0.0; MODE_LANES], [0.0; MODE_LANES]);
        for k in 0..n {
            let (mut tip, mut step) = (0.0, 0.0);
            for j in 0..MODE_LANES {
                tip += t[j] * x0[j];
                x1[j] += -g[j] * dv[k];
                let h0 = a[j][0] * x0[j] + a[j][2] * x1[j];
                let h1 = a[j][1] * x0[j] + a[j][3] * x1[j];
                step += g[j] * (h1 - rate_before[j]);
                rate_before[j] = h1;
                x0[j] = a[j][0] * h0 + a[j][2] * h1;
                x1[j] = a[j][1] * h0 + a[j][3] * h1;
            }
            w[k] += tip;
            momentum_step[k] += step;
            // a mode rung down is held at rest before it reaches the subnormal range
            if k % 64 == 0 {
                x0.iter_mut()
                    .chain(x1.iter_mut())
                    .for_each(|v| *v = at_rest(*v));
            }
        }
    }
    (w, momentum_step)
}

/// The modes of [`beam_response`] with the distributed drag and the cubic clamp's moment
/// (`k3`, N m/rad³), which couple them at every sample, for the root positions `root` (m) and
/// their velocity steps `dv` (m/s): the tip deflection (m) and the modes' force
/// `Σ Γ_r Δη̇_r / dt − drag` (N) per sample.
///
/// The drag acts as a per-sample impulse. The clamp moment M₃ is smooth (the cube of the
/// rotation) and ramps linearly between its values at the samples ([`mode_ramp`], exact per
/// mode), the one at the end of the interval solved with the rotation it produces
/// ([`cubic_step`]); the modes left out answer it quasi-statically ([`ResidualFlexibility`]).
fn nonlinear_modes(
    p: &Params,
    k3: f64,
    root: &[f64],
    dv: &[f64],
    dt: f64,
    c: &BeamCache,
) -> (Vec<f64>, Vec<f64>) {
    let n = dv.len();
    let nm = c.omega.len();
    let mut x = vec![Vector2::<f64>::zeros(); nm];
    // modal velocities at the half-sample instant before the sample (at rest before the first)
    let mut rate_before = vec![0.0; nm];
    let mut w = Vec::with_capacity(n);
    let mut force = Vec::with_capacity(n);
    let mut modal_f = vec![0.0; nm];
    let cubic = (k3 != 0.0).then(|| CubicClamp {
        k3,
        // the explicit part's stability: the modes that ramp
        cap2: cubic_cap2(
            k3,
            p.root_stiffness_nm_per_rad.unwrap_or(0.0),
            (0..nm)
                .filter(|&r| !c.ramp[r].quasi_static)
                .map(|r| c.root_rot[r] * c.root_rot[r])
                .sum(),
            dt,
        ),
        // the response to the interval's end moment, and the modes left out
        flexibility: c.residual.root_rad_per_nm
            + (0..nm)
                .map(|r| c.root_rot[r] * c.root_rot[r] * c.ramp[r].next_gain())
                .sum::<f64>(),
    });
    // the clamp moment at the current sample (at rest: 0)
    let mut m3 = 0.0;
    for (k, &dv) in dv.iter().enumerate() {
        // the root's velocity over the interval before the sample
        let vb = if k == 0 {
            0.0
        } else {
            (root[k] - root[k - 1]) / dt
        };
        modal_f.iter_mut().for_each(|f| *f = 0.0);
        let drag_total = if p.has_drag() {
            drag_impulses(p, vb, &x, c, &mut modal_f)
        } else {
            0.0
        };
        let mut f = -drag_total;
        let mut tip = -c.residual.tip_m_per_nm * m3;
        for r in 0..nm {
            tip += c.tip[r] * x[r][0];
            x[r][1] += -c.gamma[r] * dv + modal_f[r] * dt;
        }
        let m3_next = match &cubic {
            Some(cl) => cubic_step(cl, &x, m3, c),
            None => 0.0,
        };
        for r in 0..nm {
            let (now, next) = (-c.root_rot[r] * m3, -c.root_rot[r] * m3_next);
            let half = if cubic.is_some() {
                c.ramp[r].step(true, &x[r], now, next)
            } else {
                c.phi_half[r] * x[r]
            };
            f += c.gamma[r] * (half[1] - rate_before[r]) / dt;
            rate_before[r] = half[1];
            x[r] = if cubic.is_some() {
                c.ramp[r].step(false, &x[r], now, next).map(at_rest)
            } else {
                (c.phi_half[r] * half).map(at_rest)
            };
        }
        m3 = m3_next;
        w.push(tip);
        force.push(f);
    }
    (w, force)
}

/// A cubic clamp in [`nonlinear_modes`]: k₃ (N·m/rad³), the bound θ_c² of [`cubic_moment`]
/// (rad²) and the root rotation per unit end-of-interval moment that the moment itself adds
/// (rad / N·m: the kept modes' ramp response plus the residual flexibility).
struct CubicClamp {
    k3: f64,
    cap2: f64,
    flexibility: f64,
}

impl CubicClamp {
    /// The cubic moment M₃ (N·m, [`cubic_moment`]) where the modes alone would turn the root
    /// by `theta_free` (rad): at the root of θ + c M₃(θ) = θ_free (c = `flexibility`), by Newton
    /// from θ_free. θ + c M₃(θ) rises monotonically (softening keeps the tangent stiffness
    /// above k_r/10 and c < 1/k_r), so a few steps converge.
    fn moment(&self, theta_free: f64) -> f64 {
        let (c, k3, cap2) = (self.flexibility, self.k3, self.cap2);
        let mut theta = theta_free;
        if c > 0.0 {
            for _ in 0..8 {
                let m = cubic_moment(k3, theta, cap2);
                // dM₃/dθ / k₃: 3θ² below the bound, θ_c² beyond it
                let d = if theta * theta < cap2 {
                    3.0 * theta * theta
                } else {
                    cap2
                };
                let slope = 1.0 + c * k3 * d;
                let step = (theta + c * m - theta_free) / slope.max(0.05);
                theta -= step;
                if step.abs() <= 1e-12 * theta.abs().max(1e-12) {
                    break;
                }
            }
        }
        cubic_moment(k3, theta, cap2)
    }
}

/// The clamp moment M₃ (N·m) at the end of the interval that starts in the modal state `x`
/// (after the sample's impulses) with moment `m3`: the root of θ + c M₃(θ) = θ_free, θ_free
/// the rotation the modes reach with the moment held at `m3` less its ramp part, c the
/// clamp's `flexibility` ([`CubicClamp::moment`]).
fn cubic_step(cl: &CubicClamp, x: &[Vector2<f64>], m3: f64, c: &BeamCache) -> f64 {
    let theta_free: f64 = (0..x.len())
        .map(|r| {
            let s = c.root_rot[r];
            s * c.ramp[r].step(false, &x[r], -s * m3, 0.0)[0]
        })
        .sum();
    cl.moment(theta_free)
}

/// The quadratic drag of `p` as modal impulses, added to the modal forces `modal_f`; returns
/// the total drag force (N). Absolute velocity v = root velocity `v_root` + the modes'
/// velocities `x[r][1]` at each point:
/// - distributed, `−c_d |v| v` per unit length at the drag points (`drag_kg_per_m2`);
/// - on a body at the tip, `−c_t |v| v` at the tip (`tip_drag_kg_per_m`).
fn drag_impulses(
    p: &Params,
    v_root: f64,
    x: &[Vector2<f64>],
    c: &BeamCache,
    modal_f: &mut [f64],
) -> f64 {
    let mut total = 0.0;
    if p.drag_kg_per_m2 > 0.0 {
        for j in 0..c.weights.len() {
            let coef = p.drag_kg_per_m2 * c.weights[j];
            total += drag_at(coef, v_root, x, |r| c.shape[r][j], modal_f);
        }
    }
    if p.tip_drag_kg_per_m > 0.0 {
        total += drag_at(p.tip_drag_kg_per_m, v_root, x, |r| c.tip[r], modal_f);
    }
    total
}

/// The drag `−coef |v| v` (N) at one point whose mode shapes are `shape(r)`, added to the
/// modal forces `modal_f` ([`drag_impulses`]).
fn drag_at(
    coef: f64,
    v_root: f64,
    x: &[Vector2<f64>],
    shape: impl Fn(usize) -> f64,
    modal_f: &mut [f64],
) -> f64 {
    let v = v_root + (0..x.len()).map(|r| shape(r) * x[r][1]).sum::<f64>();
    let f = -coef * v.abs() * v;
    for (r, m) in modal_f.iter_mut().enumerate().take(x.len()) {
        *m += shape(r) * f;
    }
    f
}
