//! Diagnosis across a *length series*: one beam clamped at several free lengths, each
//! recorded as a free decay (no excitation channel, e.g. an accelerometer near the tip).
//!
//! The time-domain diagnosis ([`super::diagnose`]) needs the base motion that drives the
//! beam; a plucked beam has none. What such a series does carry is the natural frequencies
//! f_i(L) of every length, and a uniform Euler–Bernoulli cantilever fixes them completely up to
//! one stiffness scale: f_i = (β_iL)² / (2π L²) · √(EI/ρA), so f1·L² is constant and
//! f2/f1 = 6.267 at every length (paper eqs. 9–10, clamped base). The diagnosis follows the
//! same steps as for recordings:
//!
//! 1. **Calibrate** one stiffness scale (E) on the fit lengths; nothing per mode.
//! 2. **Locate**: the residual per length and mode, the trend of f1·L² with L and the ratio
//!    f2/f1 against the uniform beam's.
//! 3. **Hypothesise and fit** (Levenberg–Marquardt, jointly with the scale) on the Galerkin
//!    model ([`crate::model`]): `root_compliance` (rotational spring at the clamp, one k_θ for
//!    every length: a softer clamp lowers f1 more on a short beam), `tip_mass` (the sensor's
//!    mass at its position near the tip: relatively heavier on a short beam),
//!    `gravity_axial_load` (hanging or upright: no free parameter once the scale is fitted;
//!    the effect grows with L³), and the pair root compliance + sensor mass.
//! 4. **Select** with the guard of `diagnose` ([`super::selection::guard::guard`]): leave-one-length-out
//!    — each length is predicted by the model fitted on the others, never on itself (the
//!    never-fitted data); a hypothesis is named only if its BIC on all lengths is lower by more
//!    than 10, its held-out χ² is lower by more than 10, its held-out RMS frequency error falls
//!    by more than a physics-free correction with as many coefficients earns (per mode a
//!    constant and a trend in ln L of the relative error, [`generic_heldout_reduction`]), and
//!    its parameter is ≥ 3 σ from zero; the lowest held-out error wins, except that the
//!    two-effect model must beat a qualifying single effect by more than 20 %. Else `none`.
//!
//! Physical units: the spring (N·m/rad) and the mass (kg) need EI and ρA, i.e. the rig's
//! section; the dimensionless k_θ·L/EI and m/(ρA·L) do not and are reported too.

use super::selection::guard::{guard, Evidence};
use crate::numeric::lm::{self, Difference, LmOptions};
use anyhow::{bail, Context, Result};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::effect::Effect;
use crate::model::{BeamModel, ModelOptions, Orientation, Rig};

/// The modes measured at one free length.
#[derive(Clone, Debug, Serialize)]
pub struct LengthModes {
    /// Free length L (m).
    pub length_m: f64,
    /// Distance of the sensor (a lumped mass) from the tip (m).
    pub sensor_from_tip_m: f64,
    /// Natural frequencies (Hz) of modes 1, 2, … and their 1-σ (Hz).
    pub freq_hz: Vec<(f64, f64)>,
    /// Where they came from.
    pub source: String,
}

/// A candidate explanation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LengthEffect {
    /// Uniform clamped–free beam, one stiffness scale.
    None,
    /// Rotational spring at the clamp.
    RootCompliance,
    /// Lumped (sensor) mass at its position near the tip.
    TipMass,
    /// Gravity axial load, beam hanging below the clamp.
    GravityHanging,
    /// Gravity axial load, beam standing above the clamp.
    GravityUpright,
    /// Root compliance and sensor mass together.
    RootComplianceAndTipMass,
}

impl LengthEffect {
    /// The catalogue effects this hypothesis contains (none for the nominal beam).
    pub fn effects(&self) -> &'static [Effect] {
        match self {
            LengthEffect::None => &[],
            LengthEffect::RootCompliance => &[Effect::RootCompliance],
            LengthEffect::TipMass => &[Effect::TipMass],
            LengthEffect::GravityHanging | LengthEffect::GravityUpright => {
                &[Effect::GravityAxialLoad]
            }
            LengthEffect::RootComplianceAndTipMass => &[Effect::RootCompliance, Effect::TipMass],
        }
    }

    /// The JSON/CLI id: the catalogue ids joined by `+` (`gravity_axial_load` for both
    /// orientations), `none` for the nominal beam.
    pub fn id(&self) -> String {
        if self.effects().is_empty() {
            return "none".to_string();
        }
        let ids: Vec<&str> = self.effects().iter().map(|e| e.id()).collect();
        ids.join("+")
    }

    /// Every candidate, nominal first.
    pub fn all() -> [LengthEffect; 6] {
        [
            LengthEffect::None,
            LengthEffect::RootCompliance,
            LengthEffect::TipMass,
            LengthEffect::GravityHanging,
            LengthEffect::GravityUpright,
            LengthEffect::RootComplianceAndTipMass,
        ]
    }
}

/// Options of [`diagnose_lengths`].
#[derive(Clone, Debug)]
pub struct LengthOptions {
    /// Modes per length used (1 or 2 or more, as measured).
    pub n_modes: usize,
    /// Relative uncertainty floor added in quadrature to each frequency's own σ (model
    /// error: the section is not exactly uniform, the sensor position is approximate).
    pub floor_rel: f64,
    /// Galerkin basis functions (6: f2 converged to ≈ 1e-5).
    pub n_basis: usize,
}

impl Default for LengthOptions {
    fn default() -> Self {
        LengthOptions {
            n_modes: 2,
            floor_rel: 1e-3,
            n_basis: 6,
        }
    }
}

/// One hypothesis fitted.
#[derive(Clone, Debug, Serialize)]
pub struct LengthFit {
    /// The hypothesis.
    pub effect: LengthEffect,
    /// Stiffness scale (multiplies the rig's E) fitted on all lengths.
    pub stiffness_scale: f64,
    /// Physical parameters fitted on all lengths, with unit in the name, and 1-σ.
    pub parameters: Vec<(String, f64, f64)>,
    /// Σ r² on all lengths (r = relative error / σ_rel).
    pub chi2: f64,
    /// BIC on all lengths: χ² + p ln N.
    pub bic: f64,
    /// Relative errors (%) of every length and mode, fitted on all lengths.
    pub errors_pct: Vec<Vec<f64>>,
    /// Leave-one-length-out: relative errors (%) of each length predicted from the others.
    pub heldout_errors_pct: Vec<Vec<f64>>,
    /// RMS of `heldout_errors_pct` (%).
    pub heldout_rms_pct: f64,
    /// χ² of the held-out errors (each over its relative 1-σ).
    pub heldout_chi2: f64,
    /// Why it was not named (empty for the selected one and for the nominal model).
    pub verdict: String,
}

/// Result of [`diagnose_lengths`].
#[derive(Clone, Debug, Serialize)]
pub struct LengthDiagnosis {
    /// The measurements.
    pub lengths: Vec<LengthModes>,
    /// Words: where the nominal model fails.
    pub location: Vec<String>,
    /// Every hypothesis, nominal first.
    pub fits: Vec<LengthFit>,
    /// The named effect (`None` if nothing earned its parameters).
    pub selected: LengthEffect,
}

/// The rig's beam clamped at free length `length_m`: the section must be uniform (the series
/// clamps the same bar at different points).
pub fn rig_at_length(rig: &Rig, length_m: f64) -> Result<Rig> {
    let beam = rig.beam.as_ref().context("the rig has no [beam] section")?;
    let prof = rig.profile()?;
    let (a0, a1) = (prof.area(0.0), prof.area(beam.length_m));
    let (i0, i1) = (prof.inertia(0.0), prof.inertia(beam.length_m));
    if (a1 / a0 - 1.0).abs() > 0.01 || (i1 / i0 - 1.0).abs() > 0.01 {
        bail!("a length series needs a uniform beam; the rig's section changes from root to tip");
    }
    if !(length_m > 0.0) {
        bail!("free length must be > 0 m (got {length_m})");
    }
    let mut r = rig.clone();
    let b = r.beam.as_mut().expect("checked");
    b.length_m = length_m;
    b.stations.clear();
    b.profile = vec![
        crate::model::rig::ProfilePoint {
            x_m: 0.0,
            area_m2: a0,
            inertia_m4: i0,
        },
        crate::model::rig::ProfilePoint {
            x_m: length_m,
            area_m2: a0,
            inertia_m4: i0,
        },
    ];
    Ok(r)
}

/// Natural frequencies (Hz) of the clamped-base modes of `rig` with `opts`, ascending.
pub fn clamped_freqs_hz(rig: &Rig, opts: &ModelOptions) -> Result<Vec<f64>> {
    let w = BeamModel::new(rig, opts)?.clamped_modes()?.omega_rad_s;
    Ok(w.iter().map(|w| w / (2.0 * std::f64::consts::PI)).collect())
}

/// EI (N·m²) and ρA (kg/m) of the rig's (uniform) beam.
fn section(rig: &Rig) -> Result<(f64, f64)> {
    let beam = rig.beam.as_ref().context("the rig has no [beam] section")?;
    let prof = rig.profile()?;
    Ok((
        beam.youngs_modulus_pa * prof.inertia(0.0),
        beam.density_kg_m3 * prof.area(0.0),
    ))
}

struct Series<'a> {
    rigs: Vec<Rig>,
    data: &'a [LengthModes],
    opts: &'a LengthOptions,
    effect: LengthEffect,
    ei: f64,
}

impl Series<'_> {
    fn gravity(&self) -> bool {
        matches!(
            self.effect,
            LengthEffect::GravityHanging | LengthEffect::GravityUpright
        )
    }

    /// Model frequencies (Hz) of length `i`. Parameters `x`: for gravity, [ln s]; otherwise
    /// the extras [ln κ (κ = k_θ / EI, 1/m)] and/or [ln m (kg)] at stiffness scale `scale`.
    fn freqs_at(&self, x: &DVector<f64>, i: usize, scale: f64) -> Option<Vec<f64>> {
        let d = &self.data[i];
        let mut o = ModelOptions {
            n_modes: self.opts.n_basis,
            stiffness_scale: scale,
            ..Default::default()
        };
        let mut k = 0;
        if matches!(
            self.effect,
            LengthEffect::RootCompliance | LengthEffect::RootComplianceAndTipMass
        ) {
            o.root_stiffness_nm_per_rad = Some(x[k].exp() * self.ei * scale);
            k += 1;
        }
        if matches!(
            self.effect,
            LengthEffect::TipMass | LengthEffect::RootComplianceAndTipMass
        ) {
            o.point_mass = Some(((d.length_m - d.sensor_from_tip_m).max(0.0), x[k].exp()));
        }
        if self.gravity() {
            o.stiffness_scale = x[0].exp();
            o.axial_load = Some(if self.effect == LengthEffect::GravityHanging {
                Orientation::Hanging
            } else {
                Orientation::Upright
            });
        }
        clamped_freqs_hz(&self.rigs[i], &o).ok()
    }

    /// The stiffness scale s and the model frequencies of `which`. Without gravity every
    /// stiffness (EI, and the spring as κ·EI) scales with s, so f = √s · g and s is the
    /// weighted least-squares solution in log-frequency (eliminated, variable projection).
    fn solve(&self, x: &DVector<f64>, which: &[usize]) -> Option<(f64, Vec<Vec<f64>>)> {
        if self.gravity() {
            let f = which
                .iter()
                .map(|&i| self.freqs_at(x, i, 1.0))
                .collect::<Option<Vec<_>>>()?;
            return Some((x[0].exp(), f));
        }
        let g = which
            .iter()
            .map(|&i| self.freqs_at(x, i, 1.0))
            .collect::<Option<Vec<_>>>()?;
        let (mut num, mut den) = (0.0, 0.0);
        for (gi, &i) in g.iter().zip(which) {
            for (j, &(fm, sd)) in self.data[i]
                .freq_hz
                .iter()
                .take(self.opts.n_modes)
                .enumerate()
            {
                let w = 1.0 / (sd / fm).hypot(self.opts.floor_rel).powi(2);
                num += w * (fm.ln() - gi.get(j)?.ln());
                den += w;
            }
        }
        let scale = (2.0 * num / den).exp();
        let f = g
            .iter()
            .map(|v| v.iter().map(|x| x * scale.sqrt()).collect())
            .collect();
        Some((scale, f))
    }

    fn residuals_for(&self, x: &DVector<f64>, which: &[usize]) -> Option<DVector<f64>> {
        let (_, f) = self.solve(x, which)?;
        let mut r = Vec::new();
        for (fi, &i) in f.iter().zip(which) {
            for (j, &(fm, sd)) in self.data[i]
                .freq_hz
                .iter()
                .take(self.opts.n_modes)
                .enumerate()
            {
                let s = (sd / fm).hypot(self.opts.floor_rel);
                r.push((fi.get(j)? / fm - 1.0) / s);
            }
        }
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    /// Relative errors (%) of length `i` with the parameters fitted on `which`.
    fn errors_pct(&self, x: &DVector<f64>, which: &[usize], i: usize) -> Vec<f64> {
        let n = self.opts.n_modes;
        let Some((scale, _)) = self.solve(x, which) else {
            return vec![f64::NAN; n];
        };
        let f = if self.gravity() {
            self.freqs_at(x, i, 1.0)
        } else {
            self.freqs_at(x, i, 1.0)
                .map(|g| g.iter().map(|v| v * scale.sqrt()).collect())
        };
        match f {
            Some(f) => self.data[i]
                .freq_hz
                .iter()
                .take(n)
                .zip(&f)
                .map(|(m, p)| 100.0 * (p / m.0 - 1.0))
                .collect(),
            None => vec![f64::NAN; n],
        }
    }
}

/// Fits the series' effect on the lengths `which` from several starts; returns (x, χ²,
/// Jacobian of the projected residuals).
fn fit(s: &Series, which: &[usize]) -> Option<(DVector<f64>, f64, DMatrix<f64>)> {
    let l = s.data[which[0]].length_m;
    let rho_a = section(&s.rigs[which[0]]).map(|v| v.1).ok()?;
    // κ = k_θ/EI ~ {5, 100} / L; mass ~ {2 %, 20 %} of the beam.
    let k_starts = [(5.0 / l).ln(), (100.0 / l).ln()];
    let m_starts = [(rho_a * l * 0.02).ln(), (rho_a * l * 0.2).ln()];
    let starts: Vec<Vec<f64>> = match s.effect {
        LengthEffect::None => vec![vec![]],
        LengthEffect::RootCompliance => k_starts.iter().map(|&k| vec![k]).collect(),
        LengthEffect::TipMass => m_starts.iter().map(|&m| vec![m]).collect(),
        LengthEffect::RootComplianceAndTipMass => k_starts
            .iter()
            .flat_map(|&k| m_starts.iter().map(move |&m| vec![k, m]))
            .collect(),
        LengthEffect::GravityHanging | LengthEffect::GravityUpright => {
            // Start from the nominal scale.
            let nominal = Series {
                rigs: s.rigs.clone(),
                data: s.data,
                opts: s.opts,
                effect: LengthEffect::None,
                ei: s.ei,
            };
            let (scale, _) = nominal.solve(&DVector::zeros(0), which)?;
            vec![vec![scale.ln()]]
        }
    };
    let mut best: Option<(DVector<f64>, f64, DMatrix<f64>)> = None;
    for st in starts {
        let x0 = DVector::from_vec(st);
        let (x, r, j) = if x0.is_empty() {
            let r = s.residuals_for(&x0, which)?;
            let n = r.len();
            (x0, r, DMatrix::zeros(n, 0))
        } else {
            let f = |x: &DVector<f64>| s.residuals_for(x, which);
            let opts = LmOptions {
                difference: Difference::Central,
                ..LmOptions::new(vec![1e-5; x0.len()])
            };
            let out = lm::minimize(&f, x0, &opts);
            let Some(r) = f(&out.x) else {
                continue;
            };
            let Some(j) = lm::fd_jacobian(&f, &out.x, &r, &opts) else {
                continue;
            };
            (out.x, r, j)
        };
        let chi2 = r.norm_squared();
        if best.as_ref().map_or(true, |b| chi2 < b.1) {
            best = Some((x, chi2, j));
        }
    }
    best
}

/// Refuses fewer than 3 lengths, a length without `n_modes` modes, a sensor off the beam.
fn check_series(data: &[LengthModes], opts: &LengthOptions) -> Result<()> {
    if data.len() < 3 {
        bail!(
            "a length series needs at least 3 lengths (got {}): one to hold out, two to fit",
            data.len()
        );
    }
    for d in data {
        if d.freq_hz.len() < opts.n_modes {
            bail!(
                "{} (L = {} m): {} mode(s) identified, {} needed",
                d.source,
                d.length_m,
                d.freq_hz.len(),
                opts.n_modes
            );
        }
        if !(d.sensor_from_tip_m >= 0.0 && d.sensor_from_tip_m < d.length_m) {
            bail!(
                "{}: sensor {} m from the tip is not on a {} m beam",
                d.source,
                d.sensor_from_tip_m,
                d.length_m
            );
        }
    }
    Ok(())
}

/// Held-out relative errors (%) of every length h fitted on the others; for the nominal model
/// also every length's errors under each leave-one-out fit (`loo`, (h, i, mode)).
fn leave_one_out(s: &Series, all: &[usize], n_modes: usize) -> (Vec<Vec<f64>>, Vec<Vec<Vec<f64>>>) {
    let mut heldout = Vec::new();
    let mut loo = Vec::new();
    for h in 0..all.len() {
        let rest: Vec<usize> = all.iter().copied().filter(|&i| i != h).collect();
        let xh = fit(s, &rest).map(|v| v.0);
        let errs = |i: usize| match &xh {
            Some(xh) => s.errors_pct(xh, &rest, i),
            None => vec![f64::NAN; n_modes],
        };
        heldout.push(errs(h));
        if s.effect == LengthEffect::None {
            loo.push(all.iter().map(|&i| errs(i)).collect());
        }
    }
    (heldout, loo)
}

/// The reported parameters of `effect` at `x` (σ from the covariance `cov`), with the
/// stiffness scale `scale`.
fn length_parameters(
    s: &Series,
    x: &DVector<f64>,
    cov: &Option<DMatrix<f64>>,
    scale: f64,
    rho_a: f64,
) -> Vec<(String, f64, f64)> {
    let (effect, ei, data) = (s.effect, s.ei, s.data);
    let sd = |k: usize| cov.as_ref().map_or(f64::NAN, |c| c[(k, k)].max(0.0).sqrt());
    let mut parameters = Vec::new();
    let mut k = 0;
    let l_mid = data.iter().map(|d| d.length_m).sum::<f64>() / data.len() as f64;
    if matches!(
        effect,
        LengthEffect::RootCompliance | LengthEffect::RootComplianceAndTipMass
    ) {
        let kappa = x[k].exp();
        let kt = kappa * ei * scale;
        parameters.push(("root_stiffness_nm_per_rad".into(), kt, kt * sd(k)));
        parameters.push((
            "root_stiffness_times_l_over_ei".into(),
            kappa * l_mid,
            kappa * l_mid * sd(k),
        ));
        k += 1;
    }
    if matches!(
        effect,
        LengthEffect::TipMass | LengthEffect::RootComplianceAndTipMass
    ) {
        let m = x[k].exp();
        parameters.push(("tip_mass_kg".into(), m, m * sd(k)));
        let dimless = m / (rho_a * l_mid);
        parameters.push(("tip_mass_over_beam_mass".into(), dimless, dimless * sd(k)));
    }
    if s.gravity() {
        parameters.push((
            if effect == LengthEffect::GravityHanging {
                "orientation=hanging"
            } else {
                "orientation=upright"
            }
            .into(),
            f64::NAN,
            f64::NAN,
        ));
    }
    parameters
}

/// Fits `s.effect` on every length and held out; `None` when it cannot be fitted.
fn fit_effect(
    s: &Series,
    opts: &LengthOptions,
    rho_a: f64,
    loo_errors: &mut Vec<Vec<Vec<f64>>>,
) -> Option<LengthFit> {
    let data = s.data;
    let all: Vec<usize> = (0..data.len()).collect();
    let n_obs = (data.len() * opts.n_modes) as f64;
    let (x, chi2, j) = fit(s, &all)?;
    let errors_pct: Vec<Vec<f64>> = all.iter().map(|&i| s.errors_pct(&x, &all, i)).collect();
    let (heldout, loo) = leave_one_out(s, &all, opts.n_modes);
    if s.effect == LengthEffect::None {
        *loo_errors = loo;
    }
    let heldout_chi2: f64 = heldout
        .iter()
        .zip(data)
        .flat_map(|(e, d)| {
            e.iter()
                .zip(&d.freq_hz)
                .map(|(e, &(fm, sd))| (e / 100.0 / (sd / fm).hypot(opts.floor_rel)).powi(2))
        })
        .sum();
    let flat: Vec<f64> = heldout.iter().flatten().copied().collect();
    let heldout_rms_pct = (flat.iter().map(|v| v * v).sum::<f64>() / flat.len() as f64).sqrt();
    // Parameters: the extras plus the stiffness scale (eliminated or fitted).
    let p = (x.len() + usize::from(!s.gravity())) as f64;
    let dof = (n_obs - p).max(1.0);
    let cov = (j.transpose() * &j)
        .try_inverse()
        .map(|c| c * (chi2 / dof).max(1.0));
    let scale = s.solve(&x, &all).map_or(f64::NAN, |v| v.0);
    Some(LengthFit {
        effect: s.effect,
        stiffness_scale: scale,
        parameters: length_parameters(s, &x, &cov, scale, rho_a),
        chi2,
        bic: chi2 + p * n_obs.ln(),
        errors_pct,
        heldout_errors_pct: heldout,
        heldout_rms_pct,
        heldout_chi2,
        verdict: String::new(),
    })
}

/// Applies the shared guard to every effect against the nominal fit (`fits[0]`); which qualify.
fn qualify(
    fits: &mut [LengthFit],
    data: &[LengthModes],
    loo_errors: &[Vec<Vec<f64>>],
) -> Vec<bool> {
    let nominal = fits[0].clone();
    let mut qualifies = vec![false; fits.len()];
    for (q, f) in qualifies.iter_mut().zip(fits.iter_mut()).skip(1) {
        let weakest_z = f
            .parameters
            .iter()
            .filter(|p| p.1.is_finite())
            .map(|p| p.1 / p.2)
            .fold(f64::INFINITY, f64::min);
        let k = f.parameters.iter().filter(|p| p.1.is_finite()).count() / 2;
        let allowance = generic_heldout_reduction(data, loo_errors, k);
        let why = guard(&Evidence {
            delta_bic: f.bic - nominal.bic,
            delta_val: f.heldout_chi2 - nominal.heldout_chi2,
            reduction: 1.0 - f.heldout_rms_pct / nominal.heldout_rms_pct,
            allowance,
            structured: None,
            significance: weakest_z,
            structure_explained: None,
            implausible: vec![],
        });
        *q = why.is_empty();
        f.verdict = why.join("; ");
    }
    qualifies
}

/// The qualifying effect with the lowest held-out error, the pair only if it beats a
/// qualifying single effect by more than 20 % (parsimony); verdicts in words.
fn select_length_effect(fits: &mut [LengthFit], qualifies: &[bool]) -> LengthEffect {
    let best = (1..fits.len())
        .filter(|&i| qualifies[i])
        .min_by(|&a, &b| fits[a].heldout_rms_pct.total_cmp(&fits[b].heldout_rms_pct));
    let Some(mut i) = best else {
        return LengthEffect::None;
    };
    if fits[i].effect == LengthEffect::RootComplianceAndTipMass {
        if let Some(j) = (1..fits.len())
            .filter(|&j| {
                qualifies[j]
                    && matches!(
                        fits[j].effect,
                        LengthEffect::RootCompliance | LengthEffect::TipMass
                    )
            })
            .min_by(|&a, &b| fits[a].heldout_rms_pct.total_cmp(&fits[b].heldout_rms_pct))
        {
            if fits[j].heldout_rms_pct <= 1.25 * fits[i].heldout_rms_pct {
                fits[i].verdict = format!(
                    "qualifies, but its held-out error {:.3} % is not 20 % below the single effect's {:.3} % (parsimony)",
                    fits[i].heldout_rms_pct, fits[j].heldout_rms_pct
                );
                i = j;
            }
        }
    }
    let best_rms = fits[i].heldout_rms_pct;
    for (k, f) in fits.iter_mut().enumerate().skip(1) {
        if k == i {
            f.verdict.clear();
        } else if qualifies[k] && f.verdict.is_empty() {
            f.verdict = format!(
                "qualifies, but held-out error {:.3} % is above the selected one's {best_rms:.3} %",
                f.heldout_rms_pct
            );
        }
    }
    fits[i].effect
}

/// Runs the length-series diagnosis (module docs) on `data` (≥ 3 lengths) with the rig's
/// (uniform) section and material.
///
/// Errors: fewer than 3 lengths, a length without `n_modes` modes, a non-uniform rig, the
/// nominal model failing to fit.
pub fn diagnose_lengths(
    rig: &Rig,
    data: &[LengthModes],
    opts: &LengthOptions,
) -> Result<LengthDiagnosis> {
    check_series(data, opts)?;
    let rigs = data
        .iter()
        .map(|d| rig_at_length(rig, d.length_m))
        .collect::<Result<Vec<_>>>()?;
    let (ei, rho_a) = section(rig)?;
    let mut fits = Vec::new();
    // nominal model fitted without length h: relative errors (%) of every length (h, i, mode)
    let mut loo_errors: Vec<Vec<Vec<f64>>> = Vec::new();
    for effect in LengthEffect::all() {
        let s = Series {
            rigs: rigs.clone(),
            data,
            opts,
            effect,
            ei,
        };
        match fit_effect(&s, opts, rho_a, &mut loo_errors) {
            Some(f) => fits.push(f),
            None if effect == LengthEffect::None => {
                bail!("the nominal uniform-beam model could not be fitted")
            }
            None => {}
        }
    }
    // Selection: the guard of the module docs, then the lowest held-out error, then parsimony.
    let qualifies = qualify(&mut fits, data, &loo_errors);
    let selected = select_length_effect(&mut fits, &qualifies);
    Ok(LengthDiagnosis {
        lengths: data.to_vec(),
        location: locate(data, &fits[0], opts.n_modes),
        fits,
        selected,
    })
}

/// The model-form allowance of a length series ([`super::selection::guard`]): the held-out rms error
/// reduction a physics-free correction with `k` coefficients earns. Its dictionary is, per
/// mode, a constant and a trend in ln(L/L̄) of the relative frequency error; for every held-out
/// length h the coefficients are least squares on the nominal model's errors at the other
/// lengths (that model itself fitted without h) and the correction is applied to h. The best
/// k-subset is kept (`loo[h][i][mode]`, %; 0 for k = 0).
fn generic_heldout_reduction(data: &[LengthModes], loo: &[Vec<Vec<f64>>], k: usize) -> f64 {
    let n_modes = loo.first().and_then(|v| v.first()).map_or(0, |v| v.len());
    let m = 2 * n_modes;
    if k == 0 || m == 0 || k > m {
        return 0.0;
    }
    let l_mid = (data.iter().map(|d| d.length_m.ln()).sum::<f64>() / data.len() as f64).exp();
    let phi = |i: usize, mode: usize, col: usize| -> f64 {
        match (col / 2 == mode, col % 2) {
            (false, _) => 0.0,
            (true, 0) => 1.0,
            (true, _) => (data[i].length_m / l_mid).ln(),
        }
    };
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let before: Vec<f64> = (0..loo.len()).flat_map(|h| loo[h][h].clone()).collect();
    let mut best = 0.0f64;
    for mask in 0u32..(1 << m) {
        if mask.count_ones() as usize != k {
            continue;
        }
        let cols: Vec<usize> = (0..m).filter(|c| mask & (1 << c) != 0).collect();
        let mut after = Vec::new();
        for h in 0..loo.len() {
            let rows: Vec<(usize, usize)> = (0..data.len())
                .filter(|&i| i != h)
                .flat_map(|i| (0..n_modes).map(move |md| (i, md)))
                .collect();
            let a = DMatrix::from_fn(rows.len(), k, |r, c| phi(rows[r].0, rows[r].1, cols[c]));
            let y = DVector::from_fn(rows.len(), |r, _| loo[h][rows[r].0][rows[r].1]);
            let Ok(coef) = a.clone().svd(true, true).solve(&y, 1e-12) else {
                after.clear();
                break;
            };
            for md in 0..n_modes {
                let pred: f64 = (0..k).map(|c| coef[c] * phi(h, md, cols[c])).sum();
                after.push(loo[h][h][md] - pred);
            }
        }
        if after.len() == before.len() && after.iter().all(|v| v.is_finite()) {
            best = best.max(1.0 - rms(&after) / rms(&before));
        }
    }
    best
}

/// Uniform clamped–free beam: f2/f1 = (β2L/β1L)².
pub const UNIFORM_F2_OVER_F1: f64 = 6.266_931_4;

fn locate(data: &[LengthModes], nominal: &LengthFit, n_modes: usize) -> Vec<String> {
    let mut w = Vec::new();
    let fl2: Vec<f64> = data
        .iter()
        .map(|d| d.freq_hz[0].0 * d.length_m * d.length_m)
        .collect();
    let (lo, hi) = (
        fl2.iter().cloned().fold(f64::INFINITY, f64::min),
        fl2.iter().cloned().fold(0.0, f64::max),
    );
    w.push(format!(
        "f1·L² = {} Hz·m² at L = {} m: a uniform beam keeps it constant; it varies by {:.2} % ({}).",
        fl2.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", "),
        data.iter().map(|d| format!("{:.3}", d.length_m)).collect::<Vec<_>>().join(", "),
        100.0 * (hi / lo - 1.0),
        {
            let (a, b) = (fl2[0], fl2[fl2.len() - 1]);
            let (la, lb) = (data[0].length_m, data[data.len() - 1].length_m);
            if (b - a) * (lb - la) > 0.0 {
                "rising with length: the short beams are relatively softer or heavier at the tip, or a hanging beam's tension grows with L³"
            } else {
                "falling with length: an upright beam's compression grows with L³"
            }
        }
    ));
    if n_modes >= 2 {
        let ratios: Vec<f64> = data
            .iter()
            .map(|d| d.freq_hz[1].0 / d.freq_hz[0].0)
            .collect();
        w.push(format!(
            "f2/f1 = {} against {:.3} for a uniform clamped–free beam ({:+.1} % on average): a single stiffness scale cannot change a frequency ratio.",
            ratios.iter().map(|v| format!("{v:.3}")).collect::<Vec<_>>().join(", "),
            UNIFORM_F2_OVER_F1,
            100.0 * (ratios.iter().sum::<f64>() / ratios.len() as f64 / UNIFORM_F2_OVER_F1 - 1.0)
        ));
    }
    for (d, e) in data.iter().zip(&nominal.errors_pct) {
        w.push(format!(
            "L = {:.3} m: nominal model (scale {:.4} fitted on all lengths) errs {} %.",
            d.length_m,
            nominal.stiffness_scale,
            e.iter()
                .enumerate()
                .map(|(i, v)| format!("f{} {v:+.2}", i + 1))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    w
}

/// The JSON of the diagnosis, in the `diagnose` schema: `effect`, `parameters`
/// (name_with_unit → value), `uncertainty`, `validation {nrmse_before, nrmse_after}` (here
/// the held-out RMS relative frequency error, as a fraction), `candidates [{effect, score}]`
/// (score = held-out error reduction against the nominal model, fraction), plus the series.
pub fn to_json(d: &LengthDiagnosis) -> serde_json::Value {
    let nominal = &d.fits[0];
    let sel = d
        .fits
        .iter()
        .find(|f| f.effect == d.selected)
        .unwrap_or(nominal);
    let params: serde_json::Map<String, serde_json::Value> = sel
        .parameters
        .iter()
        .map(|p| match p.0.split_once('=') {
            Some((k, v)) => (k.to_string(), serde_json::json!(v)),
            None => (p.0.clone(), serde_json::json!(p.1)),
        })
        .collect();
    let unc: serde_json::Map<String, serde_json::Value> = sel
        .parameters
        .iter()
        .filter(|p| p.2.is_finite())
        .map(|p| (p.0.clone(), serde_json::json!(p.2)))
        .collect();
    serde_json::json!({
        "effect": d.selected.id(),
        "parameters": params,
        "uncertainty": unc,
        "validation": {
            "nrmse_before": nominal.heldout_rms_pct / 100.0,
            "nrmse_after": sel.heldout_rms_pct / 100.0,
            "channel": "natural frequencies, each length held out",
        },
        "candidates": d.fits.iter().skip(1).map(|f| serde_json::json!({
            "effect": f.effect.id(),
            "orientation": match f.effect { LengthEffect::GravityHanging => Some("hanging"), LengthEffect::GravityUpright => Some("upright"), _ => None },
            "score": 1.0 - f.heldout_rms_pct / nominal.heldout_rms_pct,
            "bic": f.bic,
            "verdict": f.verdict,
        })).collect::<Vec<_>>(),
        "location": d.location,
        "fits": d.fits,
        "lengths": d.lengths,
    })
}

/// The diagnosis in words: location, the named effect with parameters, the runner-ups.
pub fn words(d: &LengthDiagnosis) -> String {
    let mut s = String::new();
    s.push_str("Where the uniform-beam model fails:\n");
    for l in &d.location {
        s.push_str(&format!("  - {l}\n"));
    }
    s.push_str(&hypotheses_table(&d.fits));
    s.push_str(&named_words(d));
    s.push_str("Runner-ups:\n");
    for f in d.fits.iter().skip(1).filter(|f| f.effect != d.selected) {
        s.push_str(&format!(
            "  {:<26} {}\n",
            format!("{:?}", f.effect),
            f.verdict
        ));
    }
    s
}

/// One row per hypothesis: stiffness scale, χ², BIC, held-out RMS and parameters ± 1 σ.
fn hypotheses_table(fits: &[LengthFit]) -> String {
    let mut s = String::from(
        "\nHypotheses (fitted on all lengths; held-out = each length predicted from the others):\n",
    );
    s.push_str(&format!(
        "  {:<26} {:>8} {:>9} {:>9} {:>14}  parameters\n",
        "effect", "scale", "chi2", "BIC", "held-out RMS %"
    ));
    for f in fits {
        let params: Vec<String> = f
            .parameters
            .iter()
            .map(|p| {
                if p.1.is_finite() {
                    format!("{} = {:.4e} ± {:.1e}", p.0, p.1, p.2)
                } else {
                    p.0.clone()
                }
            })
            .collect();
        let name = match f.effect {
            LengthEffect::GravityHanging => format!("{} (hang)", Effect::GravityAxialLoad),
            LengthEffect::GravityUpright => format!("{} (up)", Effect::GravityAxialLoad),
            e => e.id(),
        };
        s.push_str(&format!(
            "  {:<26} {:>8.4} {:>9.1} {:>9.1} {:>14.3}  {}\n",
            name,
            f.stiffness_scale,
            f.chi2,
            f.bic,
            f.heldout_rms_pct,
            params.join(", ")
        ));
    }
    s
}

/// The named effect with its held-out frequency error against the nominal model, per length.
fn named_words(d: &LengthDiagnosis) -> String {
    let nominal = &d.fits[0];
    let Some(f) = d
        .fits
        .iter()
        .find(|f| f.effect == d.selected && d.selected != LengthEffect::None)
    else {
        return "\nNamed: none — no hypothesis earned its parameters.\n".to_string();
    };
    let mut s = format!(
        "\nNamed: {} — held-out frequency error {:.3} % → {:.3} % ({:.0} % lower).\n",
        f.effect.id(),
        nominal.heldout_rms_pct,
        f.heldout_rms_pct,
        100.0 * (1.0 - f.heldout_rms_pct / nominal.heldout_rms_pct)
    );
    let pct = |e: &Vec<f64>| {
        e.iter()
            .map(|v| format!("{v:+.2} %"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    for (l, (e0, e1)) in d
        .lengths
        .iter()
        .zip(nominal.heldout_errors_pct.iter().zip(&f.heldout_errors_pct))
    {
        s.push_str(&format!(
            "  L = {:.3} m held out: {} → {}\n",
            l.length_m,
            pct(e0),
            pct(e1)
        ));
    }
    s
}

#[cfg(test)]
mod tests;
