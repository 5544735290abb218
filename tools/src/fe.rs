//! An independent Hermite-cubic finite-element model of the same non-uniform cantilever
//! (Euler–Bernoulli elements), used to check the Galerkin model of [`crate::model`] and as a
//! high-fidelity "truth" model.
//!
//! Independence from the Galerkin model: local cubic Hermite shape functions instead of global
//! clamped–free functions, and **absolute** lateral displacements as coordinates (the Galerkin
//! model uses the base position plus the deflection relative to the base, eq. 9). Both
//! discretise the same energy functionals, eqs. (6)–(8) of the paper:
//! `T = ½ m ẏ² + ½∫ ρA (ẏ + ẇ)² dx + ½ m_tip (ẏ + ẇ(l))²`, `V = ½∫ EI w''² dx + ½∫ N w'² dx
//! (+ ½ k_r w'(0)²)`.
//!
//! Degrees of freedom (DOFs): nodes `0..=elements` at `x_k = k·l/elements`, two DOFs per node,
//! lateral displacement v_k (m, absolute, lab frame) and slope v'_k (rad), in the order
//! `[v_0, v'_0, v_1, v'_1, …]`, minus the ones the root condition removes:
//! - [`FeRoot::Clamped`]: v_0 = v'_0 = 0 removed (immobile base). `dof(0)` is `v_1`.
//! - [`FeRoot::FreeBase`]: v_0 is the carriage position y (carriage mass on it); v'_0 = 0
//!   removed unless a root spring is given. The system has a rigid-body mode at 0 Hz.
//!
//! A root rotational spring `root_stiffness_nm_per_rad` keeps v'_0 as a DOF tied to the
//! carriage's (zero) rotation by `k_r`. Element matrices are integrated with 4-point
//! Gauss–Legendre over the linearly interpolated A(x), I(x) (exact for a linear A and a cubic
//! I in x; converges as the mesh is refined otherwise).

use crate::model::galerkin::{generalized_eigen, rayleigh_coefficients, Orientation, G_M_S2};
use crate::model::rig::{Rig, SectionProfile};
use anyhow::{bail, Context, Result};
use nalgebra::DMatrix;

/// Root boundary condition.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FeRoot {
    /// Immobile clamp (v = 0, v' = 0 unless a root spring is given).
    Clamped,
    /// Root on a carriage of `mass_kg` (without the beam) that moves freely along the beam's
    /// lateral direction (force-driven base, paper eq. 12).
    FreeBase {
        /// Carriage mass (kg).
        mass_kg: f64,
    },
}

/// Options of the finite-element model. `Default`: 200 elements, clamped root, no tip mass,
/// rigid clamp, horizontal beam, nominal E.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeOptions {
    /// Number of equal elements (≥ 1).
    pub elements: usize,
    /// Root condition.
    pub root: FeRoot,
    /// Lumped tip mass at x = l (kg).
    pub tip_mass_kg: f64,
    /// Rotational spring at the clamp (N·m/rad); `None` = rigid clamp.
    pub root_stiffness_nm_per_rad: Option<f64>,
    /// Gravity axial load (hanging = tension, upright = compression); `None` = horizontal.
    pub axial_load: Option<Orientation>,
    /// Multiplies E.
    pub stiffness_scale: f64,
}

impl Default for FeOptions {
    fn default() -> Self {
        FeOptions {
            elements: 200,
            root: FeRoot::Clamped,
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            axial_load: None,
            stiffness_scale: 1.0,
        }
    }
}

/// An assembled finite-element beam.
#[derive(Clone, Debug)]
pub struct FeBeam {
    /// Mass matrix (n_dof × n_dof; kg for translations, kg·m² for slopes, kg·m mixed).
    pub mass: DMatrix<f64>,
    /// Stiffness matrix (n_dof × n_dof; N/m, N·m/rad, N/rad).
    pub stiffness: DMatrix<f64>,
    /// Index of the carriage translation y (`Some(0)` for [`FeRoot::FreeBase`]).
    pub base_dof: Option<usize>,
    /// Index of the root slope v'_0, if it is a DOF (root spring given).
    pub root_slope_dof: Option<usize>,
    /// Index of the tip translation v(l) (absolute, m).
    pub tip_dof: usize,
    /// Node positions (m), `elements + 1` of them.
    pub node_x_m: Vec<f64>,
    /// For each full-mesh DOF `2k` (v_k) / `2k+1` (v'_k): its index in the reduced system, or
    /// `None` if the root condition removed it.
    pub dof_map: Vec<Option<usize>>,
    /// Beam mass (kg).
    pub beam_mass_kg: f64,
}

/// Cubic Hermite shape functions at s ∈ [0, 1] on an element of length `le`: values, first
/// and second derivatives with respect to x, for the DOFs [v_a, v'_a, v_b, v'_b].
fn hermite(s: f64, le: f64) -> ([f64; 4], [f64; 4], [f64; 4]) {
    let (s2, s3) = (s * s, s * s * s);
    (
        [
            1.0 - 3.0 * s2 + 2.0 * s3,
            le * (s - 2.0 * s2 + s3),
            3.0 * s2 - 2.0 * s3,
            le * (s3 - s2),
        ],
        [
            (-6.0 * s + 6.0 * s2) / le,
            1.0 - 4.0 * s + 3.0 * s2,
            (6.0 * s - 6.0 * s2) / le,
            3.0 * s2 - 2.0 * s,
        ],
        [
            (-6.0 + 12.0 * s) / (le * le),
            (-4.0 + 6.0 * s) / le,
            (6.0 - 12.0 * s) / (le * le),
            (-2.0 + 6.0 * s) / le,
        ],
    )
}

/// 4-point Gauss–Legendre on [−1, 1].
const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

impl FeBeam {
    /// Assembles the model of the beam in `rig` (needs a `[beam]` section). For
    /// [`FeRoot::FreeBase`] pass the carriage mass yourself (e.g. `rig.base.mass_kg`).
    pub fn from_rig(rig: &Rig, opts: &FeOptions) -> Result<FeBeam> {
        let b = rig
            .beam
            .as_ref()
            .context("the rig has no [beam] section: no beam to model")?;
        FeBeam::new(
            &rig.profile()?,
            b.length_m,
            b.density_kg_m3,
            b.youngs_modulus_pa,
            opts,
        )
    }

    /// Assembles the model of a beam of `length_m` (m), density `density_kg_m3`, Young's
    /// modulus `youngs_modulus_pa` and sections `profile` (A(x) m², I(x) m⁴).
    ///
    /// Errors: non-positive sizes, zero elements, negative tip mass or carriage mass,
    /// non-positive root stiffness.
    pub fn new(
        profile: &SectionProfile,
        length_m: f64,
        density_kg_m3: f64,
        youngs_modulus_pa: f64,
        opts: &FeOptions,
    ) -> Result<FeBeam> {
        if !(length_m > 0.0
            && density_kg_m3 > 0.0
            && youngs_modulus_pa > 0.0
            && opts.stiffness_scale > 0.0)
        {
            bail!("FE beam: length, density, Young's modulus and stiffness scale must be > 0");
        }
        if opts.elements == 0 {
            bail!("FE beam: needs at least one element");
        }
        if !(opts.tip_mass_kg >= 0.0) {
            bail!(
                "FE beam: tip mass must be >= 0 kg (got {})",
                opts.tip_mass_kg
            );
        }
        if let Some(kr) = opts.root_stiffness_nm_per_rad {
            if !(kr > 0.0 && kr.is_finite()) {
                bail!("FE beam: root stiffness must be > 0 N·m/rad (got {kr})");
            }
        }
        if let FeRoot::FreeBase { mass_kg } = opts.root {
            if !(mass_kg > 0.0) {
                bail!("FE beam: carriage mass must be > 0 kg (got {mass_kg})");
            }
        }
        let ne = opts.elements;
        let le = length_m / ne as f64;
        let e = youngs_modulus_pa * opts.stiffness_scale;
        let nfull = 2 * (ne + 1);
        let mut kf = DMatrix::zeros(nfull, nfull);
        let mut mf = DMatrix::zeros(nfull, nfull);
        // Axial force at x (positive = tension): weight of the beam beyond x plus the tip mass.
        // The beam mass beyond x is integrated element by element (same quadrature).
        let elem_mass: Vec<f64> = (0..ne)
            .map(|el| {
                GL4.iter()
                    .map(|&(xi, w)| {
                        0.5 * le
                            * w
                            * density_kg_m3
                            * profile.area((el as f64 + 0.5 * (xi + 1.0)) * le)
                    })
                    .sum()
            })
            .collect();
        let beam_mass: f64 = elem_mass.iter().sum();
        let sign = match opts.axial_load {
            None => 0.0,
            Some(Orientation::Hanging) => 1.0,
            Some(Orientation::Upright) => -1.0,
        };
        for el in 0..ne {
            let x0 = el as f64 * le;
            let beyond: f64 = elem_mass[el + 1..].iter().sum();
            let mut ke = [[0.0; 4]; 4];
            let mut me = [[0.0; 4]; 4];
            for &(xi, w) in &GL4 {
                let s = 0.5 * (xi + 1.0);
                let x = x0 + s * le;
                let (n, d1, d2) = hermite(s, le);
                let jw = 0.5 * le * w;
                let ra = density_kg_m3 * profile.area(x);
                let ei = e * profile.inertia(x);
                // Mass of the element's part beyond x, by linear interpolation of ρA over the
                // rest of the element (adequate: N(x) is smooth and enters only the geometric term).
                let within = 0.5 * (ra + density_kg_m3 * profile.area(x0 + le)) * (x0 + le - x);
                let axial = sign * G_M_S2 * (beyond + within + opts.tip_mass_kg);
                for i in 0..4 {
                    for j in 0..4 {
                        ke[i][j] += jw * (ei * d2[i] * d2[j] + axial * d1[i] * d1[j]);
                        me[i][j] += jw * ra * n[i] * n[j];
                    }
                }
            }
            for i in 0..4 {
                for j in 0..4 {
                    kf[(2 * el + i, 2 * el + j)] += ke[i][j];
                    mf[(2 * el + i, 2 * el + j)] += me[i][j];
                }
            }
        }
        let tip_full = 2 * ne;
        mf[(tip_full, tip_full)] += opts.tip_mass_kg;
        if let FeRoot::FreeBase { mass_kg } = opts.root {
            mf[(0, 0)] += mass_kg;
        }
        if let Some(kr) = opts.root_stiffness_nm_per_rad {
            kf[(1, 1)] += kr;
        }
        // Keep: v_0 only on a free base; v'_0 only with a root spring.
        let keep_v0 = matches!(opts.root, FeRoot::FreeBase { .. });
        let keep_s0 = opts.root_stiffness_nm_per_rad.is_some();
        let mut dof_map = vec![None; nfull];
        let mut kept = Vec::with_capacity(nfull);
        for (d, slot) in dof_map.iter_mut().enumerate() {
            if (d == 0 && !keep_v0) || (d == 1 && !keep_s0) {
                continue;
            }
            *slot = Some(kept.len());
            kept.push(d);
        }
        let n = kept.len();
        let mass = DMatrix::from_fn(n, n, |i, j| mf[(kept[i], kept[j])]);
        let stiffness = DMatrix::from_fn(n, n, |i, j| kf[(kept[i], kept[j])]);
        Ok(FeBeam {
            mass,
            stiffness,
            base_dof: dof_map[0],
            root_slope_dof: dof_map[1],
            tip_dof: dof_map[tip_full].expect("tip DOF is always kept"),
            node_x_m: (0..=ne).map(|k| k as f64 * le).collect(),
            dof_map,
            beam_mass_kg: beam_mass,
        })
    }

    /// Number of DOFs.
    pub fn n_dof(&self) -> usize {
        self.mass.nrows()
    }

    /// All eigenvalues ω² (rad²/s², ascending) and M-orthonormal mode shapes (columns) of
    /// K φ = ω² M φ. On a free base the first one is the rigid-body mode (ω² ≈ 0).
    /// Errors: M not positive definite.
    pub fn eigen(&self) -> Result<(Vec<f64>, DMatrix<f64>)> {
        generalized_eigen(&self.stiffness, &self.mass)
    }

    /// The lowest `count` flexible natural frequencies (Hz), ascending; on a free base the
    /// rigid-body mode is skipped. Errors: buckling (a non-positive flexible eigenvalue).
    pub fn natural_frequencies_hz(&self, count: usize) -> Result<Vec<f64>> {
        let (w2, _) = self.eigen()?;
        let skip = usize::from(self.base_dof.is_some());
        let f: Vec<f64> = w2.iter().skip(skip).take(count).copied().collect();
        if f.first().is_some_and(|v| *v <= 0.0) {
            bail!(
                "FE beam buckles under the axial load (lowest flexible eigenvalue {:.3e})",
                f[0]
            );
        }
        Ok(f.iter()
            .map(|v| v.sqrt() / (2.0 * std::f64::consts::PI))
            .collect())
    }

    /// Rayleigh damping matrix C = α1 M + α2 K (paper eqs. 21–22) giving damping ratios
    /// `zeta1`, `zeta2` at the first two flexible modes; returns (C, α1 (1/s), α2 (s)). On a free
    /// base the rigid-body mode is left undamped (see the body).
    pub fn rayleigh_damping(&self, zeta1: f64, zeta2: f64) -> Result<(DMatrix<f64>, f64, f64)> {
        let two_pi = 2.0 * std::f64::consts::PI;
        let f = self.natural_frequencies_hz(2)?;
        if f.len() < 2 {
            bail!("Rayleigh damping needs two flexible modes (use more elements)");
        }
        let (a1, a2) = rayleigh_coefficients(two_pi * f[0], zeta1, two_pi * f[1], zeta2);
        let mut c = &self.mass * a1 + &self.stiffness * a2;
        if self.base_dof.is_some() {
            // No damping force on a rigid translation r of the whole system (the Galerkin model
            // damps only the deflection relative to the base): α1·M would damp the rigid-body
            // mode, so subtract its projection α1·(M r)(M r)ᵀ/(rᵀ M r). C stays symmetric and
            // positive semi-definite, and C r = 0.
            let ones = self.rigid_translation();
            let mr = &self.mass * &ones;
            let total = ones.dot(&mr);
            c -= (&mr * mr.transpose()) * (a1 / total);
        }
        Ok((c, a1, a2))
    }

    /// The rigid translation of the whole system by 1 m (all v_k = 1, slopes 0) in the reduced
    /// DOFs (meaningful on a free base).
    pub fn rigid_translation(&self) -> nalgebra::DVector<f64> {
        let mut v = nalgebra::DVector::zeros(self.n_dof());
        for (d, slot) in self.dof_map.iter().enumerate() {
            if let (Some(i), true) = (slot, d % 2 == 0) {
                v[*i] = 1.0;
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn uniform(b: f64, h: f64, l: f64) -> SectionProfile {
        SectionProfile {
            x_m: vec![0.0, l],
            area_m2: vec![b * h; 2],
            inertia_m4: vec![b * h.powi(3) / 12.0; 2],
        }
    }

    #[test]
    fn uniform_clamped_beam_matches_euler_bernoulli() {
        let (b, h, l, rho, e) = (0.025, 0.00115, 0.9, 8190.0, 1.9e11);
        let fe = FeBeam::new(
            &uniform(b, h, l),
            l,
            rho,
            e,
            &FeOptions {
                elements: 60,
                ..Default::default()
            },
        )
        .unwrap();
        let f = fe.natural_frequencies_hz(3).unwrap();
        let c = (e * b * h.powi(3) / 12.0 / (rho * b * h)).sqrt() / (2.0 * PI * l * l);
        for (i, bl) in [
            1.875_104_068_711_961f64,
            4.694_091_132_974_175,
            7.854_757_438_237_613,
        ]
        .iter()
        .enumerate()
        {
            let rel = f[i] / (bl * bl * c) - 1.0;
            assert!(rel.abs() < 1e-5, "mode {}: {rel:e}", i + 1);
        }
    }

    #[test]
    fn tip_mass_equal_to_beam_mass_gives_the_classical_root() {
        // Clamped–free beam with a tip mass equal to its own mass: β1·l = 1.24792 (Blevins,
        // Formulas for natural frequency and mode shape, table 8-8 root of
        // 1 + cos x cosh x + (m_t/m_b) x (cos x sinh x − sin x cosh x) = 0).
        let (b, h, l, rho, e) = (0.025, 0.00115, 0.9, 8190.0, 1.9e11);
        let mb = rho * b * h * l;
        let fe = FeBeam::new(
            &uniform(b, h, l),
            l,
            rho,
            e,
            &FeOptions {
                elements: 40,
                tip_mass_kg: mb,
                ..Default::default()
            },
        )
        .unwrap();
        let g = |x: f64| 1.0 + x.cos() * x.cosh() + x * (x.cos() * x.sinh() - x.sin() * x.cosh());
        let (mut lo, mut hi) = (1.0, 1.8);
        for _ in 0..100 {
            let m = 0.5 * (lo + hi);
            if g(m).signum() == g(lo).signum() {
                lo = m
            } else {
                hi = m
            }
        }
        let c = (e * b * h.powi(3) / 12.0 / (rho * b * h)).sqrt() / (2.0 * PI * l * l);
        let f = fe.natural_frequencies_hz(1).unwrap();
        assert!((lo - 1.247_92).abs() < 1e-4, "{lo}");
        assert!(
            (f[0] / (lo * lo * c) - 1.0).abs() < 1e-6,
            "{} vs {}",
            f[0],
            lo * lo * c
        );
    }

    #[test]
    fn free_base_has_a_rigid_mode_and_undamped_translation() {
        let (b, h, l) = (0.025, 0.00115, 0.9);
        let fe = FeBeam::new(
            &uniform(b, h, l),
            l,
            8190.0,
            1.9e11,
            &FeOptions {
                elements: 20,
                root: FeRoot::FreeBase { mass_kg: 2.5 },
                ..Default::default()
            },
        )
        .unwrap();
        let (w2, _) = fe.eigen().unwrap();
        assert!(w2[0].abs() < 1e-6 * w2[1], "{} vs {}", w2[0], w2[1]);
        let (c, _, _) = fe.rayleigh_damping(0.0074, 0.0074).unwrap();
        let r = fe.rigid_translation();
        assert!(
            (&c * &r).amax() < 1e-12 * c.amax(),
            "rigid translation must not be damped"
        );
        assert_eq!(fe.base_dof, Some(0));
        // Total mass seen by a rigid translation = carriage + beam.
        assert!((r.dot(&(&fe.mass * &r)) - (2.5 + fe.beam_mass_kg)).abs() < 1e-12);
    }

    #[test]
    fn bad_options_are_errors() {
        let p = uniform(0.025, 0.00115, 0.9);
        assert!(FeBeam::new(
            &p,
            0.9,
            8190.0,
            1.9e11,
            &FeOptions {
                elements: 0,
                ..Default::default()
            }
        )
        .is_err());
        assert!(FeBeam::new(
            &p,
            0.9,
            8190.0,
            1.9e11,
            &FeOptions {
                tip_mass_kg: -1.0,
                ..Default::default()
            }
        )
        .is_err());
        assert!(FeBeam::new(
            &p,
            0.9,
            8190.0,
            1.9e11,
            &FeOptions {
                root_stiffness_nm_per_rad: Some(0.0),
                ..Default::default()
            }
        )
        .is_err());
    }
}
