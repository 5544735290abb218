//! Continuous and discrete (zero-order-hold) state-space forms of the reduced model, for
//! callers that put base-side effects (friction, a servo loop) around the beam, and for the
//! benchmark against `scipy.signal.lsim`.
//!
//! Two forms, matching the two simulators of [`super::sim`] exactly:
//! - **force-driven, free base** (eqs. 12, 23): `x = [z, ż]`, `z = [y, (θ), q_1 … q_n]`,
//!   input the motor force u (N), outputs `[y, w(l), y + w(l)]` (m).
//! - **base-acceleration-driven** (position-controlled carriage): `x = [q_b, q̇_b]` over the beam
//!   coordinates `q_b = [(θ), q]`, input ÿ (m/s²), outputs `[w(l) (m), u (N)]` with u from eq. (5):
//!   `u = J ÿ + hᵀ q̈_b`.
//!
//! Damping. Eq. (21) applies `C = α1 M + α2 K` to the whole (n+1)-DOF system; with the full M
//! that would also put a viscous drag `α1·J·ẏ` on the carriage's rigid-body motion, which the
//! beam's structural damping cannot cause. We therefore apply eq. (21) to the beam block
//! (relative coordinates) in the base-acceleration form, and in the force-driven form we give
//! each flexible mode of the free-base system the ratio eq. (22) assigns to its frequency and
//! leave the rigid-body mode undamped: `C = M Φ diag(2 ζ_r ω_r) Φᵀ M` (Φ M-orthonormal).

use super::galerkin::{generalized_eigen, BeamModel};
use anyhow::{bail, Context, Result};
use nalgebra::DMatrix;

/// A linear time-invariant system `ẋ = A x + B u`, `y = C x + D u` (or its discrete
/// counterpart `x[k+1] = A x[k] + B u[k]`).
#[derive(Clone, Debug)]
pub struct StateSpace {
    /// A (n_x × n_x).
    pub a: DMatrix<f64>,
    /// B (n_x × n_u).
    pub b: DMatrix<f64>,
    /// C (n_y × n_x).
    pub c: DMatrix<f64>,
    /// D (n_y × n_u).
    pub d: DMatrix<f64>,
    /// Names of the inputs, with units.
    pub inputs: Vec<String>,
    /// Names of the outputs, with units.
    pub outputs: Vec<String>,
}

impl StateSpace {
    /// Exact zero-order-hold discretisation over `dt` (s): `A_d = e^{A dt}`,
    /// `B_d = ∫_0^dt e^{A s} ds B`, both from one exponential of the augmented matrix
    /// `[[A, B], [0, 0]]·dt` (Van Loan). C and D are unchanged.
    /// Errors: `dt` not finite and > 0.
    pub fn discretize_zoh(&self, dt: f64) -> Result<StateSpace> {
        if !(dt > 0.0 && dt.is_finite()) {
            bail!("sample interval must be > 0 (got {dt})");
        }
        let (nx, nu) = (self.a.nrows(), self.b.ncols());
        let mut aug = DMatrix::zeros(nx + nu, nx + nu);
        aug.view_mut((0, 0), (nx, nx)).copy_from(&(&self.a * dt));
        aug.view_mut((0, nx), (nx, nu)).copy_from(&(&self.b * dt));
        let e = aug.exp();
        Ok(StateSpace {
            a: e.view((0, 0), (nx, nx)).into_owned(),
            b: e.view((0, nx), (nx, nu)).into_owned(),
            c: self.c.clone(),
            d: self.d.clone(),
            inputs: self.inputs.clone(),
            outputs: self.outputs.clone(),
        })
    }

    /// Simulates the DISCRETE system from `x0` for inputs `u` (one row per sample, n_u
    /// columns): outputs, one row per sample (`y[k] = C x[k] + D u[k]`).
    pub fn simulate_discrete(&self, x0: &nalgebra::DVector<f64>, u: &DMatrix<f64>) -> DMatrix<f64> {
        let mut x = x0.clone();
        let mut out = DMatrix::zeros(u.nrows(), self.c.nrows());
        for k in 0..u.nrows() {
            let uk = u.row(k).transpose();
            out.set_row(k, &(&self.c * &x + &self.d * &uk).transpose());
            x = &self.a * &x + &self.b * &uk;
        }
        out
    }
}

impl BeamModel {
    /// Damping matrix of the free-base system (see the module doc): Rayleigh ratios (eq. 22
    /// with this model's α1, α2) on the flexible modes, none on the rigid-body mode.
    pub fn free_base_damping(&self) -> Result<DMatrix<f64>> {
        let (w2, phi) = generalized_eigen(&self.stiffness, &self.mass)?;
        let (a1, a2) = self.rayleigh;
        let d = DMatrix::from_fn(w2.len(), w2.len(), |i, j| {
            if i != j || i == 0 {
                0.0
            } else {
                let w = w2[i].max(0.0).sqrt();
                2.0 * 0.5 * (a1 / w + a2 * w) * w
            }
        });
        let mp = &self.mass * &phi;
        Ok(&mp * d * mp.transpose())
    }

    /// Beam-block damping `α1 M_bb + α2 K_bb` (eq. 21 on the relative coordinates).
    pub fn beam_damping(&self) -> DMatrix<f64> {
        let nb = self.n_beam();
        let m = self.mass.view((1, 1), (nb, nb));
        let k = self.stiffness.view((1, 1), (nb, nb));
        m * self.rayleigh.0 + k * self.rayleigh.1
    }

    /// Force-driven free-base state space (eqs. 12, 23): state `[z, ż]` (2(1+r+n)), input u
    /// (N), outputs `[y (m), w(l) (m), y + w(l) (m)]`.
    pub fn state_space_force(&self) -> Result<StateSpace> {
        let dim = self.mass.nrows();
        let minv = self
            .mass
            .clone()
            .try_inverse()
            .context("mass matrix is singular")?;
        let c = self.free_base_damping()?;
        let mut a = DMatrix::zeros(2 * dim, 2 * dim);
        a.view_mut((0, dim), (dim, dim)).fill_with_identity();
        a.view_mut((dim, 0), (dim, dim))
            .copy_from(&(-&minv * &self.stiffness));
        a.view_mut((dim, dim), (dim, dim)).copy_from(&(-&minv * &c));
        let mut b = DMatrix::zeros(2 * dim, 1);
        b.view_mut((dim, 0), (dim, 1)).copy_from(&minv.column(0));
        let mut cc = DMatrix::zeros(3, 2 * dim);
        cc[(0, 0)] = 1.0;
        for i in 0..dim {
            cc[(1, i)] = self.tip[i];
            cc[(2, i)] = self.tip[i] + if i == 0 { 1.0 } else { 0.0 };
        }
        Ok(StateSpace {
            a,
            b,
            c: cc,
            d: DMatrix::zeros(3, 1),
            inputs: vec!["force_n".into()],
            outputs: vec!["base_pos_m".into(), "tip_defl_m".into(), "tip_pos_m".into()],
        })
    }

    /// Base-acceleration-driven state space: state `[q_b, q̇_b]` (2(r+n)), input ÿ (m/s²),
    /// outputs `[w(l) (m), u (N)]`, u the force the motor must deliver (eq. 5).
    pub fn state_space_base_acceleration(&self) -> Result<StateSpace> {
        let nb = self.n_beam();
        let m = self.mass.view((1, 1), (nb, nb)).into_owned();
        let k = self.stiffness.view((1, 1), (nb, nb)).into_owned();
        let h = self.mass.view((1, 0), (nb, 1)).into_owned();
        let minv = m.try_inverse().context("beam mass matrix is singular")?;
        let c = self.beam_damping();
        let mut a = DMatrix::zeros(2 * nb, 2 * nb);
        a.view_mut((0, nb), (nb, nb)).fill_with_identity();
        let ak = -&minv * &k;
        let ac = -&minv * &c;
        a.view_mut((nb, 0), (nb, nb)).copy_from(&ak);
        a.view_mut((nb, nb), (nb, nb)).copy_from(&ac);
        let bq = -&minv * &h; // q̈_b per unit ÿ
        let mut b = DMatrix::zeros(2 * nb, 1);
        b.view_mut((nb, 0), (nb, 1)).copy_from(&bq);
        let mut cc = DMatrix::zeros(2, 2 * nb);
        for i in 0..nb {
            cc[(0, i)] = self.tip[1 + i];
        }
        // u = J ÿ + hᵀ q̈_b = J ÿ + hᵀ (A_lower x + bq ÿ).
        let ht = h.transpose();
        cc.view_mut((1, 0), (1, nb)).copy_from(&(&ht * &ak));
        cc.view_mut((1, nb), (1, nb)).copy_from(&(&ht * &ac));
        let d = DMatrix::from_column_slice(2, 1, &[0.0, self.mass[(0, 0)] + (&ht * &bq)[(0, 0)]]);
        Ok(StateSpace {
            a,
            b,
            c: cc,
            d,
            inputs: vec!["base_acc_m_s2".into()],
            outputs: vec!["tip_defl_m".into(), "force_n".into()],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::sim::ForceSim;
    use crate::model::{ModelOptions, Rig};

    fn model(n: usize) -> BeamModel {
        let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
        BeamModel::new(
            &rig,
            &ModelOptions {
                n_modes: n,
                ..Default::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn force_state_space_matches_the_modal_simulator() {
        let m = model(4);
        let dt = 1e-3;
        let ss = m.state_space_force().unwrap().discretize_zoh(dt).unwrap();
        let u: Vec<f64> = (0..3000)
            .map(|k| {
                if k < 300 {
                    5.0
                } else if k < 600 {
                    -5.0
                } else {
                    0.0
                }
            })
            .collect();
        let out = ss.simulate_discrete(
            &nalgebra::DVector::zeros(ss.a.nrows()),
            &DMatrix::from_column_slice(u.len(), 1, &u),
        );
        let (y, w) = ForceSim::new(&m, dt, false).unwrap().run(&u);
        let scale = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for k in 0..u.len() {
            assert!(
                (out[(k, 0)] - y[k]).abs() < 1e-9 * scale,
                "y at {k}: {} vs {}",
                out[(k, 0)],
                y[k]
            );
            assert!(
                (out[(k, 1)] - w[k]).abs() < 1e-9 * scale,
                "w at {k}: {} vs {}",
                out[(k, 1)],
                w[k]
            );
        }
    }

    #[test]
    fn base_acceleration_state_space_has_the_static_gains_of_eq_5() {
        let m = model(3);
        let ss = m.state_space_base_acceleration().unwrap();
        // Static gain: x = −A⁻¹ B; deflection per ÿ equals −tipᵀ K_bb⁻¹ h, force = total mass.
        let x = -ss.a.clone().try_inverse().unwrap() * &ss.b;
        let g = &ss.c * &x + &ss.d;
        let nb = m.n_beam();
        let k = m.stiffness.view((1, 1), (nb, nb)).into_owned();
        let h = m.mass.view((1, 0), (nb, 1)).into_owned();
        let w_static = -(m.tip.rows(1, nb).transpose() * k.try_inverse().unwrap() * h)[(0, 0)];
        assert!(
            (g[(0, 0)] / w_static - 1.0).abs() < 1e-9,
            "{} vs {w_static}",
            g[(0, 0)]
        );
        assert!(
            (g[(1, 0)] / m.mass[(0, 0)] - 1.0).abs() < 1e-9,
            "{} vs {}",
            g[(1, 0)],
            m.mass[(0, 0)]
        );
    }
}
