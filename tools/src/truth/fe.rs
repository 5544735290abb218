//! Hermite-cubic finite-element cantilever: the truth generator's beam, written independently of
//! the Galerkin model (`crate::model`) so that the diagnosis is tested against a different
//! discretisation.
//!
//! Euler–Bernoulli elements with nodal (w, θ) and the textbook matrices (Przemieniecki 1968,
//! ch. 11; Cook et al., *Concepts and Applications of FEA*, §16): element stiffness
//! `EI/h³·[12 6h −12 6h; …]`, consistent mass `ρAh/420·[156 22h 54 −13h; …]` and the geometric
//! (axial-load) stiffness `N/(30h)·[36 3h −36 3h; …]`, with A, I and N taken at the element
//! midpoint. Extensions: a lumped tip mass at the last node, a rotational spring at the root (the
//! root rotation θ₀ is then a degree of freedom), and the gravity axial load
//! `N(x) = ±g (ρ∫_x^l A ds + m_tip)` (+ hanging, tension; − upright, compression), the same physics
//! as the paper's eq. (20) extended by the geometric stiffness.
//!
//! Base motion enters through the rigid-body influence vector r (1 on every w, 0 on every θ):
//! `M q̈ + C q̇ + K q = −M r ÿ + f`, q relative to the base (paper eq. 12 in FE form).

use anyhow::{bail, Context, Result};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Gravity (m/s²).
pub const G_M_S2: f64 = 9.80665;

/// A fine FE beam description.
#[derive(Clone, Debug)]
pub struct FeBeam {
    /// Length (m).
    pub length_m: f64,
    /// Density (kg/m³).
    pub density_kg_m3: f64,
    /// Young's modulus (Pa).
    pub youngs_modulus_pa: f64,
    /// Width at root and tip (m), linear in between.
    pub width_m: (f64, f64),
    /// Thickness at root and tip (m), linear in between.
    pub thickness_m: (f64, f64),
    /// Lumped tip mass (kg).
    pub tip_mass_kg: f64,
    /// Root rotational spring (N·m/rad); `None` = rigid clamp.
    pub root_stiffness_nm_per_rad: Option<f64>,
    /// Gravity axial load: +1 hanging (tension), −1 upright (compression), 0 none.
    pub gravity_sign: f64,
    /// Number of elements.
    pub elements: usize,
}

/// Modal model of the FE beam (mass-normalised modes, ascending).
#[derive(Clone, Debug)]
pub struct FeModes {
    /// Natural angular frequencies (rad/s).
    pub omega_rad_s: Vec<f64>,
    /// Participation Γ_r = φ_rᵀ M r (kg^½).
    pub participation: Vec<f64>,
    /// Translational displacement of every node 0..=elements per unit modal coordinate:
    /// `node_w[r][j]` (m / kg^½); node 0 is the root (0).
    pub node_w: Vec<Vec<f64>>,
    /// Root rotation θ₀ per unit modal coordinate (rad / kg^½); 0 for a rigid clamp.
    pub root_theta: Vec<f64>,
    /// Static response to a unit moment at the compliant clamp, over every DOF (K⁻¹ e_θ₀):
    /// root rotation (rad / N·m) and tip deflection (m / N·m); 0 for a rigid clamp. Less what
    /// the kept modes carry it is the quasi-static part of the modes left out.
    pub root_moment_static: (f64, f64),
    /// Beam (+ tip) translational mass rᵀ M r (kg).
    pub beam_mass_kg: f64,
}

impl FeBeam {
    /// Cross-section (area m², second moment m⁴) at `x` m from the root.
    pub fn section(&self, x: f64) -> (f64, f64) {
        let a = x / self.length_m;
        let b = self.width_m.0 + a * (self.width_m.1 - self.width_m.0);
        let h = self.thickness_m.0 + a * (self.thickness_m.1 - self.thickness_m.0);
        (b * h, b * h * h * h / 12.0)
    }

    /// Assembles (M, K) over the free DOFs: `[θ₀ (if compliant root), w₁, θ₁, …, w_n, θ_n]`,
    /// and the influence vector r. Errors: non-positive sizes, a buckled upright beam is
    /// reported by [`FeBeam::modes`].
    pub fn assemble(&self) -> Result<(DMatrix<f64>, DMatrix<f64>, DVector<f64>)> {
        if !(self.length_m > 0.0
            && self.density_kg_m3 > 0.0
            && self.youngs_modulus_pa > 0.0
            && self.elements >= 2)
        {
            bail!("FE beam needs positive length, density, modulus and >= 2 elements");
        }
        let ne = self.elements;
        let h = self.length_m / ne as f64;
        let nd = 2 * (ne + 1);
        let mut m = DMatrix::zeros(nd, nd);
        let mut k = DMatrix::zeros(nd, nd);
        // Axial force at element midpoints: N(x) = sign·g·(ρ ∫_x^l A + m_tip).
        for e in 0..ne {
            let xm = (e as f64 + 0.5) * h;
            let (a, i) = self.section(xm);
            let ei = self.youngs_modulus_pa * i;
            let rho_a = self.density_kg_m3 * a;
            // weight below xm by 8-point midpoint sum
            let mut w_below = self.tip_mass_kg;
            let steps = 16;
            let ds = (self.length_m - xm) / steps as f64;
            for s in 0..steps {
                let xs = xm + (s as f64 + 0.5) * ds;
                w_below += self.density_kg_m3 * self.section(xs).0 * ds;
            }
            let n_ax = self.gravity_sign * G_M_S2 * w_below;
            let ke = [
                [12.0, 6.0 * h, -12.0, 6.0 * h],
                [6.0 * h, 4.0 * h * h, -6.0 * h, 2.0 * h * h],
                [-12.0, -6.0 * h, 12.0, -6.0 * h],
                [6.0 * h, 2.0 * h * h, -6.0 * h, 4.0 * h * h],
            ];
            let me = [
                [156.0, 22.0 * h, 54.0, -13.0 * h],
                [22.0 * h, 4.0 * h * h, 13.0 * h, -3.0 * h * h],
                [54.0, 13.0 * h, 156.0, -22.0 * h],
                [-13.0 * h, -3.0 * h * h, -22.0 * h, 4.0 * h * h],
            ];
            let kg = [
                [36.0, 3.0 * h, -36.0, 3.0 * h],
                [3.0 * h, 4.0 * h * h, -3.0 * h, -h * h],
                [-36.0, -3.0 * h, 36.0, -3.0 * h],
                [3.0 * h, -h * h, -3.0 * h, 4.0 * h * h],
            ];
            let base = 2 * e;
            for p in 0..4 {
                for q in 0..4 {
                    k[(base + p, base + q)] +=
                        ei / (h * h * h) * ke[p][q] + n_ax / (30.0 * h) * kg[p][q];
                    m[(base + p, base + q)] += rho_a * h / 420.0 * me[p][q];
                }
            }
        }
        m[(nd - 2, nd - 2)] += self.tip_mass_kg;
        // Root: w0 always fixed; θ0 fixed unless a rotational spring is given.
        let mut keep: Vec<usize> = Vec::new();
        if let Some(kr) = self.root_stiffness_nm_per_rad {
            if !(kr > 0.0) {
                bail!("root stiffness must be > 0");
            }
            k[(1, 1)] += kr;
            keep.push(1);
        }
        keep.extend(2..nd);
        let mr = DMatrix::from_fn(keep.len(), keep.len(), |i, j| m[(keep[i], keep[j])]);
        let kr = DMatrix::from_fn(keep.len(), keep.len(), |i, j| k[(keep[i], keep[j])]);
        let r = DVector::from_fn(keep.len(), |i, _| if keep[i] % 2 == 0 { 1.0 } else { 0.0 });
        Ok((mr, kr, r))
    }

    /// The lowest `n_keep` modes (mass-normalised). Errors: the beam buckles.
    pub fn modes(&self, n_keep: usize) -> Result<FeModes> {
        let (m, k, r) = self.assemble()?;
        self.modes_of(&m, &k, &r, n_keep)
    }

    /// The lowest `n_keep` modes of assembled matrices `(m, k, r)` of this beam's DOF layout
    /// (as returned by [`FeBeam::assemble`], possibly modified, e.g. a local stiffness loss).
    /// Errors: `k` not positive definite (the beam buckles).
    pub fn modes_of(
        &self,
        m: &DMatrix<f64>,
        k: &DMatrix<f64>,
        r: &DVector<f64>,
        n_keep: usize,
    ) -> Result<FeModes> {
        let chol = m
            .clone()
            .cholesky()
            .context("FE mass matrix not positive definite")?;
        let linv = chol.l().try_inverse().context("FE mass matrix singular")?;
        let c = &linv * k * linv.transpose();
        let c = 0.5 * (&c + c.transpose());
        let eig = SymmetricEigen::new(c);
        let mut idx: Vec<usize> = (0..eig.eigenvalues.len()).collect();
        idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        if eig.eigenvalues[idx[0]] <= 0.0 {
            bail!("the FE beam buckles under its own weight");
        }
        let compliant = self.root_stiffness_nm_per_rad.is_some();
        let off = usize::from(compliant);
        let ne = self.elements;
        let mr = m * r;
        let mut out = FeModes {
            omega_rad_s: vec![],
            participation: vec![],
            node_w: vec![],
            root_theta: vec![],
            beam_mass_kg: r.dot(&mr),
            root_moment_static: (0.0, 0.0),
        };
        if compliant {
            let mut e = DVector::zeros(k.nrows());
            e[0] = 1.0;
            let x = k
                .clone()
                .cholesky()
                .context("FE stiffness matrix not positive definite")?
                .solve(&e);
            out.root_moment_static = (x[0], x[off + 2 * (ne - 1)]);
        }
        for &i in idx.iter().take(n_keep) {
            let v = linv.transpose() * eig.eigenvectors.column(i);
            out.omega_rad_s.push(eig.eigenvalues[i].sqrt());
            out.participation.push(v.dot(&mr));
            let mut w = vec![0.0; ne + 1];
            for (j, wj) in w.iter_mut().enumerate().skip(1) {
                *wj = v[off + 2 * (j - 1)];
            }
            out.node_w.push(w);
            out.root_theta.push(if compliant { v[0] } else { 0.0 });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strip() -> FeBeam {
        FeBeam {
            length_m: 0.9,
            density_kg_m3: 8190.0,
            youngs_modulus_pa: 1.9e11,
            width_m: (0.025, 0.025),
            thickness_m: (0.00115, 0.00115),
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            gravity_sign: 0.0,
            elements: 30,
        }
    }

    #[test]
    fn uniform_cantilever_matches_euler_bernoulli() {
        let b = strip();
        let m = b.modes(3).unwrap();
        let ei = b.youngs_modulus_pa * 0.025 * 0.00115f64.powi(3) / 12.0;
        let rho_a = b.density_kg_m3 * 0.025 * 0.00115;
        for (r, bl) in [1.875_104_07, 4.694_091_13, 7.854_757_44]
            .iter()
            .enumerate()
        {
            let exact = bl * bl / (b.length_m * b.length_m) * (ei / rho_a).sqrt();
            assert!(
                (m.omega_rad_s[r] / exact - 1.0).abs() < 1e-4,
                "mode {r}: {} vs {exact}",
                m.omega_rad_s[r]
            );
        }
        // all modes together carry the whole beam mass
        let all = b.modes(60).unwrap();
        let s: f64 = all.participation.iter().map(|g| g * g).sum();
        assert!((s / all.beam_mass_kg - 1.0).abs() < 1e-9);
    }

    #[test]
    fn extensions_move_frequencies_the_right_way() {
        let f1 = |b: &FeBeam| b.modes(1).unwrap().omega_rad_s[0];
        let nominal = f1(&strip());
        assert!(
            f1(&FeBeam {
                tip_mass_kg: 0.01,
                ..strip()
            }) < nominal
        );
        assert!(
            f1(&FeBeam {
                root_stiffness_nm_per_rad: Some(5.0),
                ..strip()
            }) < nominal
        );
        assert!(
            f1(&FeBeam {
                gravity_sign: 1.0,
                ..strip()
            }) > nominal
        );
        assert!(
            f1(&FeBeam {
                gravity_sign: -1.0,
                ..strip()
            }) < nominal
        );
        assert!(
            (f1(&FeBeam {
                root_stiffness_nm_per_rad: Some(1e9),
                ..strip()
            }) / nominal
                - 1.0)
                .abs()
                < 1e-5
        );
    }
}
