//! Block 4 of the chain, the beam's structural model: clamped-base modes of [`BeamModel`] (M, K
//! of eqs. 13–20 with tip mass, root spring, gravity axial load and the calibration scale) kept
//! in a [`BeamCache`] per structural parameter set, with the maps of a compliant clamp
//! ([`ResidualFlexibility`]), the generator of modes on a moving root ([`root_transition`]), the
//! band edge and the Galerkin basis that converges below it ([`converged_basis`]), and the
//! frequency shifts the structural parameters cause ([`frequency_shift_rel`]). How the modes
//! respond to a drive is [`super::beam_response`].

use super::discrete::bounded_expm;
use super::params::Params;
use crate::model::sim::{mode_ramp, mode_zoh};
use crate::model::{BeamModel, ModelOptions, Orientation, Rig};
use anyhow::Result;
use nalgebra::Vector2;

/// One sample interval's transition matrix exp(A·dt) of a beam root driven through a coupled
/// carriage: state z = [y_r, ẏ_r, (η_j, η̇_j)…, u, u̇] where `acc_row` gives ÿ_r as a linear
/// form of z (the caller sets the carriage terms; the beam's reaction
/// Σ Γ_j (ω_j² η_j + 2ζ_jω_j η̇_j) / m_eff is filled in here), each mode obeys η̈_j + 2ζ_jω_j η̇_j + ω_j² η_j = −Γ_j ÿ_r, and the drive u moves
/// at constant u̇ over the interval. `None` for a parameter set far outside the band (ω·dt ≫ 1)
/// or non-finite (the matrix exponential's scaling-and-squaring would not end on an infinite
/// norm).
pub(crate) fn root_transition(
    acc_row: &mut [f64],
    m_eff: f64,
    c: &BeamCache,
    dt: f64,
) -> Option<nalgebra::DMatrix<f64>> {
    bounded_expm(root_generator(acc_row, m_eff, Some(c)), dt, 1e4)
}

/// The generator A of [`root_transition`] (dimension `acc_row.len()`; rows of states other
/// than the root, the modes and the drive are left zero for the caller). Without a beam
/// (`c = None`) the root is a rigid mass: `acc_row` alone.
pub(crate) fn root_generator(
    acc_row: &mut [f64],
    m_eff: f64,
    c: Option<&BeamCache>,
) -> nalgebra::DMatrix<f64> {
    let dim = acc_row.len();
    let nm = c.map_or(0, |c| c.omega.len());
    if let Some(c) = c {
        for j in 0..nm {
            let (om, z) = (c.omega[j], c.zeta[j]);
            acc_row[2 + 2 * j] = c.gamma[j] * om * om / m_eff;
            acc_row[3 + 2 * j] = c.gamma[j] * 2.0 * z * om / m_eff;
        }
    }
    let mut a = nalgebra::DMatrix::<f64>::zeros(dim, dim);
    a[(0, 1)] = 1.0;
    for i in 0..dim {
        a[(1, i)] = acc_row[i];
    }
    if let Some(c) = c {
        for j in 0..nm {
            let (om, z) = (c.omega[j], c.zeta[j]);
            let (q, qd) = (2 + 2 * j, 3 + 2 * j);
            a[(q, qd)] = 1.0;
            for i in 0..dim {
                a[(qd, i)] = -c.gamma[j] * acc_row[i];
            }
            a[(qd, qd)] -= 2.0 * z * om;
            a[(qd, q)] -= om * om;
        }
    }
    a[(dim - 2, dim - 1)] = 1.0;
    a
}

/// Cached structural model (rebuilt only when a structural parameter changes).
#[derive(Clone, Debug)]
pub struct BeamCache {
    pub(crate) key: Vec<f64>,
    pub(crate) omega: Vec<f64>,
    pub(crate) zeta: Vec<f64>,
    pub(crate) gamma: Vec<f64>,
    pub(crate) tip: Vec<f64>,
    /// root rotation per unit modal coordinate (0 without a compliant clamp)
    pub(crate) root_rot: Vec<f64>,
    /// the modes beyond `keep`, quasi-static: root rotation (rad) and tip deflection (m) per
    /// unit moment at the compliant clamp (N·m), [`ResidualFlexibility`]
    pub(crate) residual: ResidualFlexibility,
    /// mode shapes at the drag points: shape[r][j]
    pub(crate) shape: Vec<Vec<f64>>,
    pub(crate) weights: Vec<f64>,
    pub(crate) total_mass: f64,
    pub(crate) base_mass: f64,
    /// each mode's transition over half a sample interval (two make one)
    pub(crate) phi_half: Vec<nalgebra::Matrix2<f64>>,
    /// each mode's response to a linearly ramping force ([`mode_ramp`]); empty without a
    /// compliant clamp
    pub(crate) ramp: Vec<RampMaps>,
}

/// [`mode_ramp`] of one mode for a force ramping over a sample interval: at its end (`full`)
/// and at its middle (`half`); `quasi_static` for a mode of ω dt ≥ [`RAMP_LIMIT_RAD`], which
/// answers the clamp moment through [`ResidualFlexibility`] instead (its state takes none).
#[derive(Clone, Debug)]
pub(crate) struct RampMaps {
    full: (nalgebra::Matrix2<f64>, Vector2<f64>, Vector2<f64>),
    half: (nalgebra::Matrix2<f64>, Vector2<f64>, Vector2<f64>),
    pub(crate) quasi_static: bool,
}

/// ω dt (rad) from which a simulated mode answers a clamp moment quasi-statically: the ramp's
/// explicit part (the moment at the interval's start) feeds back through the clamp's tangent
/// stiffness, and with every simulated mode ramping (ω dt up to π) a hardening clamp at
/// 250 Hz diverged; with the limit at 2.6 or 2.0 it does not. At 1.0 a 100 Hz recording's
/// second mode (ω dt 1.22) lost its own amplitude-dependent frequency and the cubic fit moved
/// 2.3 % (docs/diagnose.md, session 52). The moment's content, a few times the lowest modes'
/// frequencies, lies well below a mode of ω dt ≥ 2.
const RAMP_LIMIT_RAD: f64 = 2.0;

impl RampMaps {
    /// The state at the end (`half` false) or middle of the interval from `x` (after the
    /// sample's impulses) with the modal force ramping from `f` to `f_next`.
    pub(crate) fn step(&self, half: bool, x: &Vector2<f64>, f: f64, f_next: f64) -> Vector2<f64> {
        let (phi, a, b) = if half { &self.half } else { &self.full };
        if self.quasi_static {
            phi * x
        } else {
            phi * x + (a - b) * f + b * f_next
        }
    }

    /// The displacement per unit force at the interval's end that [`RampMaps::step`] adds.
    pub(crate) fn next_gain(&self) -> f64 {
        if self.quasi_static {
            0.0
        } else {
            self.full.2[0]
        }
    }
}

pub(crate) fn beam_cache(rig: &Rig, p: &Params, dt: f64) -> Result<BeamCache> {
    let opts = ModelOptions {
        n_modes: p.n_basis.clamp(1, 12),
        stiffness_scale: p.stiffness_scale,
        base_mass_delta_kg: p.base_mass_delta_kg,
        tip_mass_kg: p.tip_mass_kg,
        root_stiffness_nm_per_rad: p.root_stiffness_nm_per_rad,
        spring_position_m: p.spring_position_m,
        axial_load: p.orientation,
        point_mass: None,
        damping_ratios: p.zeta,
        tip_load_shape: p.tip_load_shape(),
    };
    let model = BeamModel::new(rig, &opts)?;
    let modes = model.clamped_modes()?;
    // the diagnosis's fixed mode count, else the modes below the band edge (0.45 × the sample
    // rate); the exact discretisation holds for any mode
    let edge = band_edge_hz(dt) * 2.0 * std::f64::consts::PI;
    let keep = p
        .simulated_modes
        .unwrap_or_else(|| modes.omega_rad_s.iter().take_while(|w| **w < edge).count())
        .clamp(1, modes.omega_rad_s.len());
    let l = model.length_m;
    let npts = 16;
    let off = usize::from(p.root_stiffness_nm_per_rad.is_some());
    let coords: Vec<Vec<f64>> = (0..npts)
        .map(|j| model.coordinate_deflections((j as f64 + 0.5) * l / npts as f64))
        .collect();
    let shape: Vec<Vec<f64>> = (0..keep)
        .map(|r| {
            coords
                .iter()
                .map(|c| {
                    c.iter()
                        .enumerate()
                        .map(|(i, v)| modes.shapes[(i, r)] * v)
                        .sum()
                })
                .collect()
        })
        .collect();
    let zeta: Vec<f64> = modes.zeta[..keep]
        .iter()
        .enumerate()
        .map(|(r, z)| {
            p.zeta_modes
                .as_ref()
                .and_then(|v| v.get(r).copied())
                .unwrap_or(*z)
                .clamp(0.0, 0.95)
        })
        .collect();
    let phi_half = (0..keep)
        .map(|r| mode_zoh(modes.omega_rad_s[r], zeta[r], 0.5 * dt).0)
        .collect();
    let (residual, ramp) = clamp_maps(&modes, &zeta, keep, dt, off == 1);
    Ok(BeamCache {
        key: structural_key(p, dt),
        omega: modes.omega_rad_s[..keep].to_vec(),
        zeta,
        gamma: modes.participation[..keep].to_vec(),
        tip: modes.tip[..keep].to_vec(),
        root_rot: (0..keep)
            .map(|r| if off == 1 { modes.shapes[(0, r)] } else { 0.0 })
            .collect(),
        residual,
        ramp,
        shape,
        weights: vec![l / npts as f64; npts],
        total_mass: model.mass[(0, 0)],
        base_mass: model.base_mass_kg,
        phi_half,
    })
}

/// The quasi-static response of the modes a simulation leaves out (residual flexibility, the
/// static correction of the mode-displacement method; Craig & Kurdila, *Fundamentals of
/// Structural Dynamics*, 2nd ed., §14.5) to a moment M at the compliant clamp: root rotation
/// `−root_rad_per_nm · M` and tip deflection `−tip_m_per_nm · M` beyond what the kept modes
/// carry.
///
/// Why: a root moment excites the clamp's own rotation, whose compliance lies mostly in modes
/// far above any sample rate (for a clamp 20 × stiffer than EI/l the first mode holds 17 % of
/// the static 1/k_r, the modes below 250 Hz 52 %, docs/diagnose.md session 52). A cubic clamp
/// moment applied to the kept modes only moves the root by a third to a half of what it does,
/// and the fitted k₃ grows to make up for it (2.6 % at 250 Hz, 4.9 % at 100 Hz on a noise-free
/// case).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ResidualFlexibility {
    /// Σ_{r ≥ keep} s_r² / ω_r² (rad / (N·m)).
    pub root_rad_per_nm: f64,
    /// Σ_{r ≥ keep} t_r s_r / ω_r² (m / (N·m)).
    pub tip_m_per_nm: f64,
}

impl ResidualFlexibility {
    /// From the mass-normalised modes of a complete (Galerkin or FE) eigen-solution: angular
    /// frequencies `omega_rad_s` (rad/s), tip deflection `tip` and root rotation `root_rot` per
    /// unit modal coordinate; `static_mode(r)` names the modes that answer quasi-statically
    /// (those not simulated, and those too fast for the sample interval). Over every mode the
    /// sums are the model's static compliance (K⁻¹), so the correction converges.
    pub fn of_modes(
        omega_rad_s: &[f64],
        tip: &[f64],
        root_rot: &[f64],
        static_mode: impl Fn(usize) -> bool,
    ) -> Self {
        let mut r = Self::default();
        for (i, ((w, t), s)) in omega_rad_s.iter().zip(tip).zip(root_rot).enumerate() {
            if static_mode(i) {
                r.root_rad_per_nm += s * s / (w * w);
                r.tip_m_per_nm += t * s / (w * w);
            }
        }
        r
    }
}

/// The compliant clamp's part of a [`BeamCache`] (`compliant`; defaults otherwise): the
/// quasi-static flexibility of the modes that do not simulate a clamp moment and the ramp
/// maps of the `keep` simulated ones with damping ratios `zeta`, at sample interval `dt`.
fn clamp_maps(
    modes: &crate::model::galerkin::ClampedModes,
    zeta: &[f64],
    keep: usize,
    dt: f64,
    compliant: bool,
) -> (ResidualFlexibility, Vec<RampMaps>) {
    if !compliant {
        return (ResidualFlexibility::default(), Vec::new());
    }
    let w = &modes.omega_rad_s;
    let residual = ResidualFlexibility::of_modes(
        w,
        &modes.tip,
        &modes.shapes.row(0).iter().copied().collect::<Vec<_>>(),
        |r| r >= keep || w[r] * dt >= RAMP_LIMIT_RAD,
    );
    let ramp = (0..keep)
        .map(|r| RampMaps {
            full: mode_ramp(w[r], zeta[r], dt, dt),
            half: mode_ramp(w[r], zeta[r], 0.5 * dt, dt),
            quasi_static: w[r] * dt >= RAMP_LIMIT_RAD,
        })
        .collect();
    (residual, ramp)
}

pub(crate) fn structural_key(p: &Params, dt: f64) -> Vec<f64> {
    let (z1, z2) = p.zeta.unwrap_or((-1.0, -1.0));
    let mut key = vec![
        p.stiffness_scale,
        z1,
        z2,
        p.base_mass_delta_kg,
        p.tip_mass_kg,
        p.root_stiffness_nm_per_rad.unwrap_or(-1.0),
        p.spring_position_m,
        match p.orientation {
            None => 0.0,
            Some(Orientation::Hanging) => 1.0,
            Some(Orientation::Upright) => -1.0,
        },
        dt,
        p.n_basis as f64,
        p.simulated_modes.map_or(-1.0, |n| n as f64),
    ];
    key.extend(p.zeta_modes.iter().flatten());
    key
}

/// The band edge (Hz) of a recording sampled every `dt` s: [`crate::diagnose::rate::PASS_EDGE`] (0.45) ×
/// the sample rate (90 % of Nyquist), the working band's pass edge. Modes below it are in the
/// model with their own damping ratio.
pub fn band_edge_hz(dt: f64) -> f64 {
    crate::diagnose::rate::PASS_EDGE / dt
}

/// The model's stated accuracy of its in-band natural frequencies (relative): [`converged_basis`]
/// adds basis functions until none of them moves by more than this when one more is added.
pub const BASIS_CONVERGENCE_REL: f64 = 1e-3;

/// How far the beam's structural parameters of `p` that `without` lacks (a tip mass, a root
/// spring) move the clamped natural frequencies below the band edge of sample interval `dt`:
/// the largest |f_r(p) / f_r(without) − 1| over the modes both have there (relative; the same
/// stiffness scale, so a shift common to every mode counts). `None` when either model is
/// refused or without a beam.
pub fn frequency_shift_rel(rig: &Rig, p: &Params, without: &Params, dt: f64) -> Option<f64> {
    frequency_ratios(rig, p, without, dt)?
        .iter()
        .map(|r| (r - 1.0).abs())
        .reduce(f64::max)
}

/// How far the cubic clamp of `p` (k₃, [`Params::cubic_root_stiffness_nm_per_rad3`], beside
/// its linear stiffness k_r) moves the clamped natural frequencies below the band edge of
/// sample interval `dt` between small motion and the recordings' peak: the shift
/// ([`frequency_shift_rel`]) from the linear clamp k_r to the describing-function stiffness
/// k_r + ¾ k₃ θ² of a root swinging with amplitude θ (Krylov–Bogoliubov first harmonic of
/// M = k_r θ + k₃ θ³). θ is read from `peak_deflection_m` (m, the largest tip deflection
/// relative to the carriage in the recordings) through the first mode's ratio of root
/// rotation to tip deflection. Relative; `None` without a beam, a compliant clamp or a
/// first mode with a tip deflection, or when a model is refused. A softening clamp that
/// loses its stiffness at the peak counts as an unbounded shift.
pub fn cubic_frequency_shift_rel(
    rig: &Rig,
    p: &Params,
    dt: f64,
    peak_deflection_m: f64,
) -> Option<f64> {
    let kr = p.root_stiffness_nm_per_rad?;
    let c = beam_cache(rig, p, dt).ok()?;
    let (s1, t1) = (*c.root_rot.first()?, *c.tip.first()?);
    if t1 == 0.0 || !(kr > 0.0) {
        return None;
    }
    let theta = peak_deflection_m * (s1 / t1).abs();
    let k_eq = kr + 0.75 * p.cubic_root_stiffness_nm_per_rad3 * theta * theta;
    if !(k_eq > 0.0) {
        return Some(f64::INFINITY);
    }
    let linear = Params {
        cubic_root_stiffness_nm_per_rad3: 0.0,
        ..p.clone()
    };
    let at_peak = Params {
        root_stiffness_nm_per_rad: Some(k_eq),
        ..linear.clone()
    };
    frequency_shift_rel(rig, &at_peak, &linear, dt)
}

/// f_r(p) / f_r(without) of the clamped modes both models keep below the band edge of `dt`;
/// `None` without a beam or when either model is refused.
fn frequency_ratios(rig: &Rig, p: &Params, without: &Params, dt: f64) -> Option<Vec<f64>> {
    rig.beam.as_ref()?;
    let (a, b) = (
        beam_cache(rig, p, dt).ok()?,
        beam_cache(rig, without, dt).ok()?,
    );
    Some(
        a.omega
            .iter()
            .zip(&b.omega)
            .map(|(wa, wb)| wa / wb)
            .collect(),
    )
}

/// The part of [`frequency_shift_rel`] that one stiffness scale cannot absorb: with d_r =
/// ln(f_r(p) / f_r(without)) over the modes below the band edge, the largest |d_r − c| for the
/// best common c, i.e. half the range of d_r (relative). Every natural frequency of a beam
/// without axial load scales with √(stiffness scale), so a shift common to every mode is a
/// recalibration, not evidence of the parameter. With a single in-band mode there is no ratio
/// to read: the plain shift of that mode. `None` as [`frequency_shift_rel`].
pub fn frequency_shift_beyond_scale_rel(
    rig: &Rig,
    p: &Params,
    without: &Params,
    dt: f64,
) -> Option<f64> {
    let d: Vec<f64> = frequency_ratios(rig, p, without, dt)?
        .iter()
        .map(|r| r.ln())
        .collect();
    let (lo, hi) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    match d.len() {
        0 => None,
        1 => Some(d[0].abs()),
        _ => Some(0.5 * (hi - lo)),
    }
}

/// Galerkin convergence of the modes below a band edge.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisChoice {
    /// Basis functions used.
    pub n_basis: usize,
    /// Clamped natural frequencies (Hz) of the modes below the band edge.
    pub freqs_hz: Vec<f64>,
    /// Largest relative change of those frequencies from `n_basis` to `n_basis + 1` functions.
    pub convergence_rel: f64,
    /// Lowest clamped modes simulated: every mode of the nominal model below the Nyquist
    /// frequency given (capped at the basis size), those between the band edge and Nyquist
    /// included (the sampled recordings show them). The count is fixed for a diagnosis, so no
    /// fitted parameter adds or removes a mode by moving it across a truncation (held-out
    /// 545001, a null at 50 Hz: its second mode at 22.51 Hz lay just above the 22.5 Hz band
    /// edge, and a hanging load, pulling it below, gained the mode and was named).
    pub simulated_modes: usize,
}

/// The smallest number of basis functions (4–11) for which every clamped mode below
/// `band_edge_hz` moves by less than [`BASIS_CONVERGENCE_REL`] when one more function is added,
/// and the modes to simulate for recordings whose highest Nyquist frequency is `nyquist_hz`.
///
/// Errors: the rig has no beam or the model refuses it.
pub fn converged_basis(
    rig: &Rig,
    stiffness_scale: f64,
    band_edge_hz: f64,
    nyquist_hz: f64,
) -> Result<BasisChoice> {
    let freqs = |n: usize| -> Result<Vec<f64>> {
        let m = BeamModel::new(
            rig,
            &ModelOptions {
                n_modes: n,
                stiffness_scale,
                ..Default::default()
            },
        )?;
        Ok(m.clamped_modes()?
            .omega_rad_s
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect())
    };
    let mut prev = freqs(4)?;
    let mut last = None;
    for n in 4..12 {
        let next = freqs(n + 1)?;
        let below = prev
            .iter()
            .take_while(|f| **f < band_edge_hz)
            .count()
            .max(1);
        let rel = (0..below.min(prev.len()))
            .map(|r| (prev[r] - next[r]).abs() / next[r])
            .fold(0.0, f64::max);
        let choice = BasisChoice {
            // one function more than the in-band modes so the last one is not the worst
            n_basis: n,
            freqs_hz: prev[..below.min(prev.len())].to_vec(),
            convergence_rel: rel,
            simulated_modes: prev
                .iter()
                .take_while(|f| **f < nyquist_hz)
                .count()
                .clamp(1, prev.len()),
        };
        if rel < BASIS_CONVERGENCE_REL && below < n {
            return Ok(choice);
        }
        last = Some(choice);
        prev = next;
    }
    Ok(last.expect("at least one basis size"))
}
