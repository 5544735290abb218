//! Galerkin reduction of the beam on a moving base (paper eqs. 9–20) with the structural
//! extensions the diagnosis needs, and the modal analysis (eq. 24).
//!
//! Generalised coordinates `[y, (θ), q_1 … q_n]`: base position y (m), optionally the rigid
//! rotation θ (rad) of a compliant clamp (`root_stiffness_nm_per_rad`; or of the outer part
//! about a hinge spring at x_h, `spring_position_m`), and the modal amplitudes q_i of the
//! basis ([`super::basis`]); the deflection is `w(x) = (x − x_h)₊ θ + Σ q_i φ_i(x)` (x_h = 0
//! at the clamp).
//!
//! Mass (eqs. 13, 17–19) and stiffness (eq. 20) by Gauss–Legendre quadrature over A(x), I(x),
//! done once per beam and basis ([`BeamIntegrals`]): a model is assembled from those integrals
//! for any stiffness scale, carriage mass, damping and lumped mass.
//! Eq. (20) is evaluated in its symmetric weak form `k_ij = E∫ I φ_i'' φ_j'' dx`: integrating the
//! printed strong form by parts twice gives it, because the boundary terms vanish for
//! φ(0) = φ'(0) = 0 and φ''(l) = φ'''(l) = 0. Extensions: a lumped tip mass adds to J, h_i and
//! m_ij; an axial load N(x) (gravity on a hanging (+, tension) or upright (−) beam) adds the
//! geometric stiffness `∫ N φ_i' φ_j' dx`, `N(x) = ±g(ρ∫_x^l A ds + m_tip)`.

use super::basis::BasisFn;
use super::rig::{BeamSection, Rig, SectionProfile};
use anyhow::{bail, Context, Result};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Gravity (m/s²).
pub const G_M_S2: f64 = 9.80665;

/// Orientation of the beam for the gravity axial load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Orientation {
    /// Beam hangs below the clamp: tension, frequencies rise.
    Hanging,
    /// Beam stands above the clamp: compression, frequencies fall.
    Upright,
}

/// Model options; `Default` is the paper's nominal model with 4 basis functions.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelOptions {
    /// Number of basis functions n.
    pub n_modes: usize,
    /// Multiplies E (calibration).
    pub stiffness_scale: f64,
    /// Added to the carriage mass (kg, calibration).
    pub base_mass_delta_kg: f64,
    /// Lumped mass at the tip (kg).
    pub tip_mass_kg: f64,
    /// Rotational spring at the clamp (N·m/rad); `None` = rigid clamp.
    pub root_stiffness_nm_per_rad: Option<f64>,
    /// Where that rotational spring sits (m from the clamp, `0 ≤ x_h < l`): 0 is a compliant
    /// clamp; x_h > 0 a hinge in the beam, the part beyond it turning rigidly about x_h,
    /// `w = (x − x_h)₊ θ + Σ q_i φ_i` (a crack or a loose joint idealised as a rotational spring,
    /// the local-flexibility model of Dimarogonas, Eng. Fract. Mech. 55, 1996). Not one of the
    /// paper's terms: the alternative placement a root spring is tested against.
    pub spring_position_m: f64,
    /// A lumped mass `(x_m, kg)` on the beam at distance x from the clamp (e.g. an
    /// accelerometer); `None` = none.
    pub point_mass: Option<(f64, f64)>,
    /// Gravity axial load; `None` = horizontal beam.
    pub axial_load: Option<Orientation>,
    /// Damping ratios of the first two flexible modes (→ Rayleigh α1, α2); `None` = the rig's.
    pub damping_ratios: Option<(f64, f64)>,
    /// Adds the static deflection under a tip load, ψ(x) = (3s² − s³)/2 with s = x/l, to the
    /// basis. Every clamped–free function has φ'''(l) = 0, so alone they converge slowly
    /// (algebraically) when a tip mass puts a shear force at the tip; ψ carries that shear.
    /// For a uniform beam without tip mass the lowest `n_modes` frequencies do not change
    /// (Rayleigh–Ritz on a larger space, the old ones already exact).
    pub tip_load_shape: bool,
}

impl Default for ModelOptions {
    fn default() -> Self {
        ModelOptions {
            n_modes: 4,
            stiffness_scale: 1.0,
            base_mass_delta_kg: 0.0,
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            spring_position_m: 0.0,
            point_mass: None,
            axial_load: None,
            damping_ratios: None,
            tip_load_shape: false,
        }
    }
}

/// The assembled model.
#[derive(Clone, Debug)]
pub struct BeamModel {
    /// Mass matrix M, (1 + r + n)², coordinates `[y, (θ), q]` (kg, kg·m, …).
    pub mass: DMatrix<f64>,
    /// Stiffness matrix K (N/m, …); row/column 0 (the base) is zero.
    pub stiffness: DMatrix<f64>,
    /// w(l) = tip · coordinates (the entry for y is 0: deflection is relative to the base).
    pub tip: DVector<f64>,
    /// Beam length (m).
    pub length_m: f64,
    /// Beam mass (kg).
    pub beam_mass_kg: f64,
    /// Carriage mass incl. correction (kg).
    pub base_mass_kg: f64,
    /// Rayleigh α1 (1/s) and α2 (s) (eqs. 21–22).
    pub rayleigh: (f64, f64),
    /// Damping ratios they were computed from.
    pub damping_ratios: (f64, f64),
    /// The coordinates' shapes (evaluated by [`BeamModel::coordinate_deflections`]).
    shapes: Shapes,
}

/// Modes of the beam on a clamped (immobile) base: natural frequencies and mass-normalised
/// shapes of the beam block, with their participation in base acceleration.
#[derive(Clone, Debug)]
pub struct ClampedModes {
    /// Natural angular frequencies ω_r (rad/s), ascending.
    pub omega_rad_s: Vec<f64>,
    /// Mass-normalised mode shapes (columns) in the beam coordinates `[(θ), q]`.
    pub shapes: DMatrix<f64>,
    /// Modal participation factors Γ_r = Φ_rᵀ h (kg^½): the modal force is −Γ_r ÿ.
    pub participation: Vec<f64>,
    /// Tip deflection per unit modal coordinate (m / kg^½).
    pub tip: Vec<f64>,
    /// Damping ratio of each mode (Rayleigh, eq. 22).
    pub zeta: Vec<f64>,
}

/// Nodes and weights of 5-point Gauss–Legendre on [−1, 1].
const GL5: [(f64, f64); 5] = [
    (0.0, 0.568_888_888_888_888_9),
    (-0.538_469_310_105_683, 0.478_628_670_499_366_5),
    (0.538_469_310_105_683, 0.478_628_670_499_366_5),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
    (0.906_179_845_938_664, 0.236_926_885_056_189_1),
];

/// Quadrature points (x, weight) over [0, l]: `intervals` × 5-point Gauss–Legendre.
pub fn quadrature(length_m: f64, intervals: usize) -> Vec<(f64, f64)> {
    let h = length_m / intervals as f64;
    let mut pts = Vec::with_capacity(intervals * 5);
    for k in 0..intervals {
        let c = (k as f64 + 0.5) * h;
        for &(xi, w) in GL5.iter() {
            pts.push((c + 0.5 * h * xi, 0.5 * h * w));
        }
    }
    pts
}

/// The beam's mass beyond every quadrature point of `pts`, `∫_x^l ρA ds` (kg), for the
/// gravity axial load; `line_density_kg_m(x)` is ρA at x. `pts` is in [`quadrature`] order:
/// five Gauss–Legendre points per interval, the middle one first (so not ascending): each
/// point's value is the mass of the intervals after its own plus a 5-point Gauss–Legendre
/// integral from the point to its interval's end, exact for a section polynomial of degree ≤ 9
/// between stations (a running sum over the points would be first order in the interval and,
/// in this order, wrong by a slice).
fn mass_beyond(pts: &[(f64, f64)], line_density_kg_m: impl Fn(f64) -> f64) -> Vec<f64> {
    debug_assert_eq!(pts.len() % GL5.len(), 0);
    let ends: Vec<f64> = pts
        .chunks(GL5.len())
        .map(|c| c[0].0 + 0.5 * c.iter().map(|p| p.1).sum::<f64>())
        .collect();
    let mass_between = |a: f64, b: f64| -> f64 {
        let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
        GL5.iter()
            .map(|&(xi, w)| half * w * line_density_kg_m(mid + half * xi))
            .sum()
    };
    // mass of every interval after interval j
    let mut after = vec![0.0; ends.len()];
    let mut acc = 0.0;
    for (j, c) in pts.chunks(GL5.len()).enumerate().rev() {
        after[j] = acc;
        acc += c
            .iter()
            .map(|&(x, w)| w * line_density_kg_m(x))
            .sum::<f64>();
    }
    pts.iter()
        .enumerate()
        .map(|(k, &(x, _))| {
            let j = k / GL5.len();
            after[j] + mass_between(x, ends[j])
        })
        .collect()
}

/// [`quadrature`] with a break at `break_m` (0 < break_m < l): the intervals shared between
/// [0, break_m] and [break_m, l] in proportion (at least one each), so that a shape with a kink
/// there ([`ModelOptions::spring_position_m`]) is integrated piecewise smooth. Without a break
/// inside (0, l), [`quadrature`].
pub fn quadrature_with_break(length_m: f64, intervals: usize, break_m: f64) -> Vec<(f64, f64)> {
    if !(break_m > 0.0 && break_m < length_m) {
        return quadrature(length_m, intervals);
    }
    let below =
        ((intervals as f64 * break_m / length_m).round() as usize).clamp(1, intervals.max(2) - 1);
    let above = intervals.max(2) - below;
    let mut pts = quadrature(break_m, below);
    pts.extend(
        quadrature(length_m - break_m, above)
            .into_iter()
            .map(|(x, w)| (break_m + x, w)),
    );
    pts
}

/// Rayleigh coefficients (α1, α2) giving damping ratios ζ1, ζ2 at ω1, ω2 (rad/s), eq. (22):
/// ζ_r = ½(α1/ω_r + α2 ω_r).
pub fn rayleigh_coefficients(omega1: f64, zeta1: f64, omega2: f64, zeta2: f64) -> (f64, f64) {
    if (omega2 - omega1).abs() < 1e-12 * omega1 {
        return (2.0 * zeta1 * omega1, 0.0);
    }
    let det = omega2 / omega1 - omega1 / omega2;
    let a1 = 2.0 * (zeta1 * omega2 - zeta2 * omega1) / det;
    let a2 = 2.0 * (zeta2 / omega1 - zeta1 / omega2) / det;
    (a1, a2)
}

/// Checks the options against the beam of length `length_m`.
/// (The number of basis functions is checked where the beam is integrated,
/// [`BeamIntegrals::new`].)
fn check_options(opts: &ModelOptions, length_m: f64) -> Result<()> {
    if !(opts.stiffness_scale > 0.0) || !(opts.tip_mass_kg >= 0.0) {
        bail!("stiffness scale must be > 0 and tip mass >= 0");
    }
    if !(0.0..length_m).contains(&opts.spring_position_m) {
        bail!(
            "rotational spring must sit on the beam (0..{length_m} m from the clamp); got {} m",
            opts.spring_position_m
        );
    }
    let (pm_x, pm_kg) = opts.point_mass.unwrap_or((0.0, 0.0));
    if !(pm_kg >= 0.0) || !(0.0..=length_m).contains(&pm_x) {
        bail!(
            "point mass must be >= 0 kg and on the beam (0..={length_m} m); got {pm_kg} kg at {pm_x} m"
        );
    }
    Ok(())
}

/// The generalised coordinates' shape at a point: `[0 (y), ((x − x_h)₊ if a rotational spring
/// at x_h), φ_i, (ψ if the tip-load shape)]` for w, and their first and second derivatives.
#[derive(Clone, Debug)]
struct Shapes {
    /// 1 with a rotational spring (the rigid rotation about it is a coordinate), else 0.
    r: usize,
    /// Where that spring sits (m from the clamp).
    spring_m: f64,
    basis: Vec<BasisFn>,
    /// Beam length (m) when the tip-load shape ψ is the last coordinate.
    tip_shape_l: Option<f64>,
    vals: Vec<f64>,
    d1: Vec<f64>,
    d2: Vec<f64>,
}

impl Shapes {
    fn new(l: f64, n: usize, root_spring: Option<f64>, tip_shape: bool) -> Self {
        let r = usize::from(root_spring.is_some());
        let dim = 1 + r + n + usize::from(tip_shape);
        Shapes {
            r,
            spring_m: root_spring.unwrap_or(0.0),
            basis: (1..=n).map(|i| BasisFn::new(i, l)).collect(),
            tip_shape_l: tip_shape.then_some(l),
            vals: vec![0.0; dim],
            d1: vec![0.0; dim],
            d2: vec![0.0; dim],
        }
    }

    fn dim(&self) -> usize {
        self.vals.len()
    }

    /// Evaluates the shapes at `x` into `vals`, `d1`, `d2`.
    fn at(&mut self, x: f64) {
        let r = self.r;
        if r == 1 {
            let beyond = x > self.spring_m;
            self.vals[1] = if beyond { x - self.spring_m } else { 0.0 };
            self.d1[1] = if beyond { 1.0 } else { 0.0 };
            self.d2[1] = 0.0;
        }
        for (i, b) in self.basis.iter().enumerate() {
            let (p, p1, p2) = b.eval(x);
            self.vals[1 + r + i] = p;
            self.d1[1 + r + i] = p1;
            self.d2[1 + r + i] = p2;
        }
        if let Some(l) = self.tip_shape_l {
            let (s, k) = (x / l, self.vals.len() - 1);
            self.vals[k] = 0.5 * s * s * (3.0 - s);
            self.d1[k] = 1.5 * s * (2.0 - s) / l;
            self.d2[k] = 3.0 * (1.0 - s) / (l * l);
        }
    }

    /// Adds a point mass `kg` at the point last evaluated to the upper triangle of `mass`.
    fn add_point_mass(&self, mass: &mut DMatrix<f64>, kg: f64) {
        let vals = &self.vals;
        for i in 1..self.dim() {
            mass[(0, i)] += kg * vals[i];
            for j in i..self.dim() {
                mass[(i, j)] += kg * vals[i] * vals[j];
            }
        }
    }
}

/// The quadrature integrals of one beam and basis: everything of M and K that the calibration
/// (stiffness scale, carriage mass, damping) and the lumped masses do not change, so that a
/// fit that moves only those assembles its model from them without integrating again.
///
/// Upper triangles, coordinates `[y, (θ), q, (ψ)]`: `mass` holds h_i (eq. 18, row 0) and m_ij
/// (eq. 19) of the beam alone (J is left 0); `stiff_ei` holds k_ij (eq. 20) at the rig's E;
/// `geo_own` holds `∫ ρ(∫_x^l A ds) φ_i' φ_j' dx` and `geo_unit` `∫ φ_i' φ_j' dx`, so that the
/// geometric stiffness of the axial load ±g(ρ∫_x^l A ds + m_tip) is
/// `±g (geo_own + m_tip · geo_unit)`.
#[derive(Clone, Debug)]
pub struct BeamIntegrals {
    beam: BeamSection,
    n_modes: usize,
    /// Where the rotational spring sits (m from the clamp); `None`: no spring coordinate.
    root_spring: Option<f64>,
    tip_shape: bool,
    shapes: Shapes,
    pts: Vec<(f64, f64)>,
    mass: DMatrix<f64>,
    stiff_ei: DMatrix<f64>,
    geo_own: DMatrix<f64>,
    geo_unit: DMatrix<f64>,
    beam_mass_kg: f64,
    /// The coordinates' deflections at the tip (entry 0, for y, is 0).
    tip: DVector<f64>,
}

/// Integrals kept per thread ([`BeamIntegrals::shared`]); a diagnosis uses a handful at once
/// (basis sizes × root spring × tip-load shape).
const SHARED_INTEGRALS: usize = 8;

thread_local! {
    static INTEGRALS: std::cell::RefCell<Vec<std::rc::Rc<BeamIntegrals>>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

impl BeamIntegrals {
    /// Integrates the beam of `rig` on `n_modes` clamped–free functions, plus the rigid
    /// rotation θ about a rotational spring at `root_spring` (m from the clamp; 0 a compliant
    /// clamp) if given and the tip-load shape ψ if `tip_shape` ([`ModelOptions`]), by
    /// `40 + 20 n_modes` intervals of 5-point Gauss–Legendre (broken at the spring,
    /// [`quadrature_with_break`]).
    ///
    /// Errors: no `[beam]`, an invalid profile, `n_modes` outside 1..=12.
    pub fn new(
        rig: &Rig,
        n_modes: usize,
        root_spring: Option<f64>,
        tip_shape: bool,
    ) -> Result<BeamIntegrals> {
        let beam = rig
            .beam
            .as_ref()
            .context("the rig has no [beam] section: no beam model")?;
        let profile: SectionProfile = rig.profile()?;
        if !(1..=12).contains(&n_modes) {
            bail!("number of basis functions must be 1..12 (got {n_modes})");
        }
        let (l, rho, e) = (beam.length_m, beam.density_kg_m3, beam.youngs_modulus_pa);
        let mut shapes = Shapes::new(l, n_modes, root_spring, tip_shape);
        let dim = shapes.dim();
        let pts = quadrature_with_break(l, 40 + 20 * n_modes, root_spring.unwrap_or(0.0));
        // the mass of each quadrature point's slice of beam (kg)
        let slice_kg: Vec<f64> = pts
            .iter()
            .map(|&(x, w)| w * rho * profile.area(x))
            .collect();
        let beam_mass_kg: f64 = slice_kg.iter().sum();
        let beyond = mass_beyond(&pts, |x| rho * profile.area(x));
        let zero = || DMatrix::zeros(dim, dim);
        let (mut mass, mut stiff_ei, mut geo_own, mut geo_unit) = (zero(), zero(), zero(), zero());
        for (k, &(x, w)) in pts.iter().enumerate() {
            shapes.at(x);
            let (vals, d1, d2) = (&shapes.vals, &shapes.d1, &shapes.d2);
            let ei = w * e * profile.inertia(x);
            for i in 1..dim {
                mass[(0, i)] += slice_kg[k] * vals[i]; // h_i (eq. 18)
                for j in i..dim {
                    mass[(i, j)] += slice_kg[k] * vals[i] * vals[j]; // m_ij (eq. 19)
                    stiff_ei[(i, j)] += ei * d2[i] * d2[j]; // k_ij (eq. 20)
                    geo_unit[(i, j)] += w * d1[i] * d1[j];
                    geo_own[(i, j)] += w * beyond[k] * d1[i] * d1[j];
                }
            }
        }
        shapes.at(l);
        let tip = DVector::from_fn(dim, |i, _| if i == 0 { 0.0 } else { shapes.vals[i] });
        Ok(BeamIntegrals {
            beam: beam.clone(),
            n_modes,
            root_spring,
            tip_shape,
            shapes,
            pts,
            mass,
            stiff_ei,
            geo_own,
            geo_unit,
            beam_mass_kg,
            tip,
        })
    }

    /// [`Self::new`], or the same integrals computed earlier on this thread for the same beam
    /// and basis (the last [`SHARED_INTEGRALS`] kept).
    ///
    /// Errors: as [`Self::new`].
    pub fn shared(
        rig: &Rig,
        n_modes: usize,
        root_spring: Option<f64>,
        tip_shape: bool,
    ) -> Result<std::rc::Rc<BeamIntegrals>> {
        let same = |b: &BeamIntegrals| {
            b.n_modes == n_modes
                && b.root_spring == root_spring
                && b.tip_shape == tip_shape
                && rig.beam.as_ref() == Some(&b.beam)
        };
        if let Some(b) = INTEGRALS.with(|c| c.borrow().iter().find(|b| same(b)).cloned()) {
            return Ok(b);
        }
        let b = std::rc::Rc::new(BeamIntegrals::new(rig, n_modes, root_spring, tip_shape)?);
        INTEGRALS.with(|c| {
            let mut c = c.borrow_mut();
            if c.len() == SHARED_INTEGRALS {
                c.remove(0);
            }
            c.push(b.clone());
        });
        Ok(b)
    }

    /// `∫_0^x φ_i' φ_j' dx` (upper triangle): the geometric stiffness per newton of an axial
    /// force that acts only between the clamp and `x_m` (a point mass's weight).
    fn geo_unit_below(&self, x_m: f64) -> DMatrix<f64> {
        let mut shapes = self.shapes.clone();
        let dim = shapes.dim();
        let mut g = DMatrix::zeros(dim, dim);
        // the points are not ascending within an interval ([`quadrature`]): filter, not take_while
        for &(x, w) in self.pts.iter().filter(|p| p.0 < x_m) {
            shapes.at(x);
            for i in 1..dim {
                for j in i..dim {
                    g[(i, j)] += w * shapes.d1[i] * shapes.d1[j];
                }
            }
        }
        g
    }
}

/// Copies the upper triangle of `m` into the lower.
fn symmetrise(m: &mut DMatrix<f64>) {
    for i in 0..m.nrows() {
        for j in 0..i {
            m[(i, j)] = m[(j, i)];
        }
    }
}

impl BeamModel {
    /// Assembles the model of `rig` with `opts` (the integrals from
    /// [`BeamIntegrals::shared`]).
    ///
    /// Errors: no `[beam]`, invalid profile, `n_modes` outside 1..=12, non-positive options,
    /// an upright beam that buckles under its own weight.
    pub fn new(rig: &Rig, opts: &ModelOptions) -> Result<BeamModel> {
        let beam = rig
            .beam
            .as_ref()
            .context("the rig has no [beam] section: no beam model")?;
        check_options(opts, beam.length_m)?;
        let b = BeamIntegrals::shared(
            rig,
            opts.n_modes,
            opts.root_stiffness_nm_per_rad
                .map(|_| opts.spring_position_m),
            opts.tip_load_shape,
        )?;
        let (pm_x, pm_kg) = opts.point_mass.unwrap_or((0.0, 0.0));
        let mut mass = b.mass.clone();
        let mut stiff = &b.stiff_ei * opts.stiffness_scale;
        if let Some(o) = opts.axial_load {
            let sign = if o == Orientation::Hanging { 1.0 } else { -1.0 };
            let mut geo = &b.geo_own + &b.geo_unit * opts.tip_mass_kg;
            if pm_kg > 0.0 && pm_x > 0.0 {
                geo += b.geo_unit_below(pm_x) * pm_kg;
            }
            stiff += geo * (sign * G_M_S2);
        }
        let base_mass = rig.base.mass_kg + opts.base_mass_delta_kg;
        if !(base_mass > 0.0) {
            bail!("carriage mass must stay > 0 (got {base_mass} kg)");
        }
        let mut shapes = b.shapes.clone();
        mass[(0, 0)] = base_mass + b.beam_mass_kg + opts.tip_mass_kg + pm_kg; // J (eq. 17)
        if pm_kg > 0.0 {
            shapes.at(pm_x);
            shapes.add_point_mass(&mut mass, pm_kg);
        }
        shapes.at(beam.length_m);
        shapes.add_point_mass(&mut mass, opts.tip_mass_kg);
        if let Some(kr) = opts.root_stiffness_nm_per_rad {
            if !(kr > 0.0) {
                bail!("root stiffness must be > 0 N·m/rad (got {kr})");
            }
            stiff[(1, 1)] += kr;
        }
        symmetrise(&mut mass);
        symmetrise(&mut stiff);
        let zetas = opts.damping_ratios.unwrap_or_else(|| rig.damping_ratios());
        let mut model = BeamModel {
            mass,
            stiffness: stiff,
            tip: b.tip.clone(),
            length_m: beam.length_m,
            beam_mass_kg: b.beam_mass_kg,
            base_mass_kg: base_mass,
            rayleigh: (0.0, 0.0),
            damping_ratios: zetas,
            shapes,
        };
        let w = model.clamped_omegas()?;
        model.rayleigh = if w.len() >= 2 {
            rayleigh_coefficients(w[0], zetas.0, w[1], zetas.1)
        } else {
            (2.0 * zetas.0 * w[0], 0.0)
        };
        Ok(model)
    }

    /// The deflection w(x) (m per unit coordinate) of each beam coordinate `[(θ), q_1 … q_n,
    /// (ψ)]` at `x` (m from the clamp): a mode shape of [`ClampedModes::shapes`] is
    /// `w_r(x) = Σ_i shapes[(i, r)] · coordinate_deflections(x)[i]`. Length [`Self::n_beam`].
    pub fn coordinate_deflections(&self, x: f64) -> Vec<f64> {
        let mut s = self.shapes.clone();
        s.at(x);
        s.vals[1..].to_vec()
    }

    /// Number of beam coordinates (excluding y).
    pub fn n_beam(&self) -> usize {
        self.mass.nrows() - 1
    }

    fn clamped_omegas(&self) -> Result<Vec<f64>> {
        let nb = self.n_beam();
        let m = self.mass.view((1, 1), (nb, nb)).into_owned();
        let k = self.stiffness.view((1, 1), (nb, nb)).into_owned();
        let (w2, _) = generalized_eigen(&k, &m)?;
        if w2[0] <= 0.0 {
            bail!(
                "the beam buckles under the axial load (lowest eigenvalue {:.3e} <= 0)",
                w2[0]
            );
        }
        Ok(w2.iter().map(|v| v.sqrt()).collect())
    }

    /// Modes with the base clamped (eq. 24 on the beam block).
    pub fn clamped_modes(&self) -> Result<ClampedModes> {
        let nb = self.n_beam();
        let m = self.mass.view((1, 1), (nb, nb)).into_owned();
        let k = self.stiffness.view((1, 1), (nb, nb)).into_owned();
        let (w2, shapes) = generalized_eigen(&k, &m)?;
        if w2[0] <= 0.0 {
            bail!("the beam buckles under the axial load");
        }
        let h = self.mass.view((1, 0), (nb, 1)).into_owned();
        let tipb = self.tip.rows(1, nb).into_owned();
        let omega: Vec<f64> = w2.iter().map(|v| v.sqrt()).collect();
        let (a1, a2) = self.rayleigh;
        Ok(ClampedModes {
            participation: (0..nb)
                .map(|r| shapes.column(r).dot(&h.column(0)))
                .collect(),
            tip: (0..nb).map(|r| shapes.column(r).dot(&tipb)).collect(),
            zeta: omega.iter().map(|w| 0.5 * (a1 / w + a2 * w)).collect(),
            omega_rad_s: omega,
            shapes,
        })
    }

    /// Natural frequencies (Hz) of the free-base system (base force-driven, eq. 12): the
    /// non-zero roots of det(K − ω²M) = 0 over all coordinates (the rigid-body mode at 0 is
    /// dropped).
    pub fn free_base_freqs_hz(&self) -> Result<Vec<f64>> {
        let (w2, _) = generalized_eigen(&self.stiffness, &self.mass)?;
        Ok(w2
            .iter()
            .skip(1)
            .map(|v| v.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect())
    }
}

/// Solves K v = λ M v for symmetric K and symmetric positive-definite M: eigenvalues ascending
/// and M-orthonormal eigenvectors (columns), via Cholesky M = L Lᵀ.
pub fn generalized_eigen(k: &DMatrix<f64>, m: &DMatrix<f64>) -> Result<(Vec<f64>, DMatrix<f64>)> {
    let chol = m
        .clone()
        .cholesky()
        .context("mass matrix is not positive definite")?;
    let l = chol.l();
    let linv = l.clone().try_inverse().context("mass matrix is singular")?;
    let c = &linv * k * linv.transpose();
    let c = 0.5 * (&c + c.transpose());
    let eig = SymmetricEigen::new(c);
    let mut idx: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let vals: Vec<f64> = idx.iter().map(|&i| eig.eigenvalues[i]).collect();
    let mut vecs = DMatrix::zeros(k.nrows(), idx.len());
    let lt_inv = linv.transpose();
    for (c_out, &i) in idx.iter().enumerate() {
        let v = &lt_inv * eig.eigenvectors.column(i);
        vecs.set_column(c_out, &v);
    }
    Ok((vals, vecs))
}
