//! Exact time integration of the reduced model by modal superposition.
//!
//! - **Prescribed base motion** (the linear motor is position-controlled): the beam sees the
//!   base acceleration. Each clamped-base mode r obeys `η̈ + 2ζ_rω_r η̇ + ω_r² η = −Γ_r ÿ`
//!   (Rayleigh damping, eqs. 21–22, on the beam's relative coordinates). The base position is
//!   taken piecewise linear between samples, so ÿ is a train of velocity steps Δv_k at the
//!   samples: each one kicks η̇ by −Γ_r Δv_k and the free motion in between is propagated with
//!   the exact 2×2 matrix exponential. No integration error; only the input interpolation.
//!   The motor force follows from eq. (5): `u = J ÿ + hᵀ q̈`.
//! - **Base force u(t)** (free base, eqs. 12/23): modes of the full (n+1) system, the rigid-body
//!   mode undamped, zero-order hold on u, exact discretisation per mode.

use super::galerkin::{generalized_eigen, BeamModel, ClampedModes};
use crate::recording::Recording;
use anyhow::{bail, Result};
use nalgebra::{DVector, Matrix2, Matrix3, Matrix4, Vector2};

/// Exact discretisation of `ẍ + 2ζω ẋ + ω² x = f` over `dt`: the free propagator Φ (2×2) and
/// the zero-order-hold input vector Γ (response to a unit f held for dt).
/// Φ = 0, Γ = (1/ω², 0) when ζω dt > 745 (decayed to 0 in f64 within the interval); NaN (both)
/// when otherwise |ω dt| or |2ζω dt| > 1e6 or either is not finite.
pub fn mode_zoh(omega: f64, zeta: f64, dt: f64) -> (Matrix2<f64>, Vector2<f64>) {
    // A generator far outside any band (a fit that ran away, e.g. a mount at 10¹⁴ Hz) must not
    // reach nalgebra's `exp`: its power estimate overflows and it squares without end. A mode
    // that decays by e^(−ζω dt) < e^(−745) (0 in f64) within the interval has Φ = 0 and
    // Γ = (1/ω², 0) exactly; any other non-finite or |ω dt| > 1e6 generator gets NaN.
    let (wd, cd) = (omega * dt, 2.0 * zeta * omega * dt);
    if cd.is_finite() && 0.5 * cd > 745.0 && (omega * omega).is_finite() {
        return (Matrix2::zeros(), Vector2::new(1.0 / (omega * omega), 0.0));
    }
    if !(wd.abs() <= 1e6 && cd.abs() <= 1e6) {
        return (
            Matrix2::from_element(f64::NAN),
            Vector2::from_element(f64::NAN),
        );
    }
    let a = Matrix3::new(
        0.0,
        1.0,
        0.0,
        -omega * omega,
        -2.0 * zeta * omega,
        1.0,
        0.0,
        0.0,
        0.0,
    );
    let e = (a * dt).exp();
    (
        Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
        Vector2::new(e[(0, 2)], e[(1, 2)]),
    )
}

/// Exact response of `ẍ + 2ζω ẋ + ω² x = f` at time `h` to an input ramping linearly from
/// f₀ at 0 to f₁ at `dt` (first-order hold; Franklin, Powell & Workman, *Digital Control of
/// Dynamic Systems*, 3rd ed., §6.3.2): `x(h) = Φ x(0) + a f₀ + b (f₁ − f₀)` with Φ (2×2) and
/// the vectors a (the held part, [`mode_zoh`]'s Γ at h = dt) and b (the ramp). For f = −s M(t)
/// of a smooth moment this keeps the quasi-static response of modes far above the sample rate
/// (b → a → (1/ω², 0)), which a per-sample impulse misses: its static gain is
/// (ωdt/2) cot(ωdt/2), 54 % at ω dt = 2.2. Guards as [`mode_zoh`] (NaN when `dt` ≤ 0).
pub fn mode_ramp(
    omega: f64,
    zeta: f64,
    h: f64,
    dt: f64,
) -> (Matrix2<f64>, Vector2<f64>, Vector2<f64>) {
    let (wd, cd) = (omega * h, 2.0 * zeta * omega * h);
    let nan = Vector2::from_element(f64::NAN);
    if cd.is_finite() && 0.5 * cd > 745.0 && (omega * omega).is_finite() && dt > 0.0 {
        // decayed within the interval: the static response to the input at h
        let w2 = omega * omega;
        return (
            Matrix2::zeros(),
            Vector2::new(1.0 / w2, 0.0),
            Vector2::new(h / dt / w2, 0.0),
        );
    }
    if !(wd.abs() <= 1e6 && cd.abs() <= 1e6 && dt > 0.0) {
        return (Matrix2::from_element(f64::NAN), nan, nan);
    }
    // state [x, ẋ, f, ḟ dt]: f' = ḟ, (ḟ dt)' = 0
    let mut g = Matrix4::zeros();
    g[(0, 1)] = 1.0;
    g[(1, 0)] = -omega * omega;
    g[(1, 1)] = -2.0 * zeta * omega;
    g[(1, 2)] = 1.0;
    g[(2, 3)] = 1.0 / dt;
    let e = (g * h).exp();
    (
        Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
        Vector2::new(e[(0, 2)], e[(1, 2)]),
        Vector2::new(e[(0, 3)], e[(1, 3)]),
    )
}

/// A simulator of the beam on a position-controlled base, precomputed for one sample interval.
#[derive(Clone, Debug)]
pub struct BaseMotionSim {
    modes: ClampedModes,
    phi: Vec<Matrix2<f64>>,
    dt: f64,
    total_mass_kg: f64,
}

impl BaseMotionSim {
    /// Precomputes the modal propagators of `model` for sample interval `dt` (s).
    pub fn new(model: &BeamModel, dt: f64) -> Result<Self> {
        if !(dt > 0.0 && dt.is_finite()) {
            bail!("sample interval must be > 0 (got {dt})");
        }
        let modes = model.clamped_modes()?;
        let phi = modes
            .omega_rad_s
            .iter()
            .zip(&modes.zeta)
            .map(|(&w, &z)| mode_zoh(w, z, dt).0)
            .collect();
        Ok(BaseMotionSim {
            modes,
            phi,
            dt,
            total_mass_kg: model.mass[(0, 0)],
        })
    }

    /// The clamped-base modes used.
    pub fn modes(&self) -> &ClampedModes {
        &self.modes
    }

    /// Simulates base positions `y_m` (one per sample, uniform dt, at rest before the first
    /// sample). Returns (tip deflection w(l) (m), base force u (N)) per sample.
    pub fn run(&self, y_m: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let n = y_m.len();
        let nm = self.phi.len();
        let mut x = vec![Vector2::zeros(); nm];
        let mut w = Vec::with_capacity(n);
        let mut u = Vec::with_capacity(n);
        let g = &self.modes.participation;
        let sum_g2: f64 = g.iter().map(|v| v * v).sum();
        for k in 0..n {
            let v_before = if k == 0 {
                0.0
            } else {
                (y_m[k] - y_m[k - 1]) / self.dt
            };
            let v_after = if k + 1 < n {
                (y_m[k + 1] - y_m[k]) / self.dt
            } else {
                0.0
            };
            let dv = v_after - v_before;
            let acc = dv / self.dt;
            let mut tip = 0.0;
            let mut f = (self.total_mass_kg - sum_g2) * acc;
            for r in 0..nm {
                let (om, z) = (self.modes.omega_rad_s[r], self.modes.zeta[r]);
                tip += self.modes.tip[r] * x[r][0];
                f += g[r] * (-2.0 * z * om * x[r][1] - om * om * x[r][0]);
                x[r][1] -= g[r] * dv;
                x[r] = self.phi[r] * x[r];
            }
            w.push(tip);
            u.push(f);
        }
        (w, u)
    }

    /// Simulates and packs a [`Recording`]: `base_cmd_m` = `base_pos_m` = y (ideal servo),
    /// `tip_pos_m` = y + w(l), `force_n` = u; `t0` the first time stamp.
    pub fn recording(&self, y_m: &[f64], t0: f64) -> Recording {
        let (w, u) = self.run(y_m);
        let mut rec = Recording::with_uniform_time(y_m.len(), 1.0 / self.dt);
        rec.time_s.iter_mut().for_each(|t| *t += t0);
        rec.tip_pos_m = Some(y_m.iter().zip(&w).map(|(y, w)| y + w).collect());
        rec.base_cmd_m = Some(y_m.to_vec());
        rec.base_pos_m = Some(y_m.to_vec());
        rec.force_n = Some(u);
        rec
    }
}

/// The modal state `[η_r, η̇_r]` of the beam on a position-controlled base, advanced one
/// sample at a time by [`BaseMotionSim::step`] (e.g. by the virtual rig, whose base follows a
/// servo tick by tick). Same modes, propagators and velocity-kick scheme as
/// [`BaseMotionSim::run`].
#[derive(Clone, Debug, PartialEq)]
pub struct BaseMotionState {
    eta: Vec<Vector2<f64>>,
}

impl BaseMotionState {
    /// Copies the modal coordinates of `other` (mode by mode, as many as both have): a state
    /// carried over to a rebuilt simulator (the virtual rig's drift).
    pub fn copy_from(&mut self, other: &BaseMotionState) {
        for (a, b) in self.eta.iter_mut().zip(&other.eta) {
            *a = *b;
        }
    }
}

impl BaseMotionSim {
    /// The beam at rest on the base.
    pub fn rest(&self) -> BaseMotionState {
        BaseMotionState {
            eta: vec![Vector2::zeros(); self.phi.len()],
        }
    }

    /// One sample interval: the base velocity changes by `dv_m_s` (m/s) at its start — each
    /// mode's η̇_r is kicked by −Γ_r Δv — then the free motion over dt (exact propagator).
    pub fn step(&self, state: &mut BaseMotionState, dv_m_s: f64) {
        let g = &self.modes.participation;
        for (r, x) in state.eta.iter_mut().enumerate() {
            x[1] -= g[r] * dv_m_s;
            *x = self.phi[r] * *x;
        }
    }

    /// Tip position (m) of a state on a base at `base_m` (m): `base_m + Σ_r φ_r(l) η_r`.
    pub fn tip_m(&self, state: &BaseMotionState, base_m: f64) -> f64 {
        self.modes
            .tip
            .iter()
            .zip(&state.eta)
            .fold(base_m, |acc, (t, x)| acc + t * x[0])
    }
}

/// The free-base system driven by the motor force (eqs. 12, 23) in modal coordinates.
#[derive(Clone, Debug)]
pub struct ForceSim {
    /// Natural angular frequencies (rad/s), the first is the rigid-body mode (0).
    pub omega_rad_s: Vec<f64>,
    /// Damping ratios per mode (0 for the rigid-body mode).
    pub zeta: Vec<f64>,
    /// Mass-normalised modes (columns) over `[y, (θ), q]`.
    pub shapes: nalgebra::DMatrix<f64>,
    phi: Vec<Matrix2<f64>>,
    gam: Vec<Vector2<f64>>,
    tip: DVector<f64>,
}

impl ForceSim {
    /// Precomputes for sample interval `dt`. `undamped` drops Rayleigh damping (for the
    /// conservation tests).
    pub fn new(model: &BeamModel, dt: f64, undamped: bool) -> Result<Self> {
        let (w2, shapes) = generalized_eigen(&model.stiffness, &model.mass)?;
        let omega: Vec<f64> = w2.iter().map(|v| v.max(0.0).sqrt()).collect();
        let (a1, a2) = model.rayleigh;
        let zeta: Vec<f64> = omega
            .iter()
            .enumerate()
            .map(|(i, &w)| {
                if i == 0 || undamped {
                    0.0
                } else {
                    0.5 * (a1 / w + a2 * w)
                }
            })
            .collect();
        let (phi, gam) = omega
            .iter()
            .zip(&zeta)
            .map(|(&w, &z)| mode_zoh(w, z, dt))
            .unzip();
        Ok(ForceSim {
            omega_rad_s: omega,
            zeta,
            shapes,
            phi,
            gam,
            tip: model.tip.clone(),
        })
    }

    /// Propagates the modal state `eta` (per mode [η, η̇]) one step with force `u` (N) held.
    pub fn step(&self, eta: &mut [Vector2<f64>], u: f64) {
        for r in 0..eta.len() {
            let f = self.shapes[(0, r)] * u;
            eta[r] = self.phi[r] * eta[r] + self.gam[r] * f;
        }
    }

    /// Physical coordinates and velocities `[y, (θ), q]` of a modal state.
    pub fn physical(&self, eta: &[Vector2<f64>]) -> (DVector<f64>, DVector<f64>) {
        let p = DVector::from_iterator(eta.len(), eta.iter().map(|e| e[0]));
        let v = DVector::from_iterator(eta.len(), eta.iter().map(|e| e[1]));
        (&self.shapes * p, &self.shapes * v)
    }

    /// Modal state of physical coordinates/velocities (Φᵀ M x, since Φᵀ M Φ = I).
    pub fn modal(
        &self,
        model: &BeamModel,
        q: &DVector<f64>,
        qd: &DVector<f64>,
    ) -> Vec<Vector2<f64>> {
        let a = self.shapes.transpose() * &model.mass * q;
        let b = self.shapes.transpose() * &model.mass * qd;
        (0..a.len()).map(|r| Vector2::new(a[r], b[r])).collect()
    }

    /// Simulates a force history `u_n` (N, ZOH, uniform dt, from rest) and packs a
    /// [`Recording`] at `1/dt`: `base_pos_m` = y, `tip_pos_m` = y + w(l), `force_n` = u;
    /// no `base_cmd_m` (the carriage is not position-controlled here).
    pub fn recording(&self, u_n: &[f64], dt: f64) -> Recording {
        let (y, w) = self.run(u_n);
        let mut rec = Recording::with_uniform_time(u_n.len(), 1.0 / dt);
        rec.tip_pos_m = Some(y.iter().zip(&w).map(|(y, w)| y + w).collect());
        rec.base_pos_m = Some(y);
        rec.force_n = Some(u_n.to_vec());
        rec
    }

    /// Simulates a force history (ZOH, uniform dt) from rest: (base position, tip deflection).
    pub fn run(&self, u_n: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut eta = vec![Vector2::zeros(); self.omega_rad_s.len()];
        let mut y = Vec::with_capacity(u_n.len());
        let mut w = Vec::with_capacity(u_n.len());
        for &u in u_n {
            let (q, _) = self.physical(&eta);
            y.push(q[0]);
            w.push(self.tip.dot(&q));
            self.step(&mut eta, u);
        }
        (y, w)
    }
}
