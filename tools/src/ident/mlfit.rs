//! Maximum-likelihood refinement of modal parameters on the FRF (output-error fit).
//!
//! LSCF linearises the fit: it minimises |A(ω) H(ω) − B(ω)|², which weights every line by the
//! denominator's magnitude and biases damping upward when the output is noisy (measured in
//! docs/ident.md, "Numbers behind the design choices"). The refinement minimises the *output
//! error* instead, the maximum-likelihood cost for white output noise (Pintelon & Schoukens,
//! *System Identification: a Frequency Domain Approach*, 2nd ed., §9; the MLMM step of
//! commercial PolyMAX):
//!
//! ```text
//! V(θ) = Σ_k S_xx(ω_k) · |H1(ω_k) − Ĥ(jω_k; θ)|²,      Ĥ(s) = Σ_r (a_r + b_r s) / (s² + 2ζ_r ω_r s + ω_r²) + c_0 + c_2 / s²
//! ```
//!
//! (weighting by S_xx turns the FRF error into the output error |Y − Ĥ X|²; `c_0` is the upper
//! residual of the modes above the band, `c_2 / s²` the lower residual, e.g. the rigid-body
//! motion of a force-driven carriage). The residues a_r, b_r, c_0, c_2 enter linearly and are
//! eliminated (variable projection, Golub & Pereyra 1973); Levenberg–Marquardt iterates on
//! θ = (ln ω_r, ln ζ_r) only. The 1-σ uncertainty of each f_r and ζ_r is the Gauss–Newton
//! covariance s² (JᵀJ)⁻¹ of the projected problem, s² = V / (N − p).

use crate::numeric::cores;
use crate::numeric::lm::{fd_jacobian_batched, minimize_batched, Difference, LmOptions};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use realfft::num_complex::Complex64;
use std::f64::consts::PI;

use super::frf::Frf;
use super::ModeEstimate;

/// A refined mode: natural frequency (Hz), damping ratio and their 1-σ from the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct RefinedMode {
    /// Natural frequency f_r = ω_r / 2π (Hz).
    pub freq_hz: f64,
    /// Damping ratio ζ_r.
    pub zeta: f64,
    /// 1-σ of `freq_hz` (Hz), from the fit's covariance.
    pub freq_hz_std: f64,
    /// 1-σ of `zeta`.
    pub zeta_std: f64,
}

/// Result of [`refine_modes`].
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Modes, in the order of the starting values.
    pub modes: Vec<RefinedMode>,
    /// Weighted cost before and after (same units: S_xx · |H|²).
    pub cost_start: f64,
    /// Cost after.
    pub cost_end: f64,
}

struct Problem<'a> {
    s: Vec<Complex64>,
    h: &'a [Complex64],
    sqrt_w: Vec<f64>,
}

impl Problem<'_> {
    /// Basis columns (complex) for poles `theta`: per mode 1/D, s/D; then 1 and 1/s².
    fn basis(&self, theta: &DVector<f64>) -> Vec<Vec<Complex64>> {
        let n_modes = theta.len() / 2;
        let mut cols = Vec::with_capacity(2 * n_modes + 2);
        for r in 0..n_modes {
            let w = theta[2 * r].exp();
            let z = theta[2 * r + 1].exp();
            let inv: Vec<Complex64> = self
                .s
                .iter()
                .map(|&s| 1.0 / (s * s + 2.0 * z * w * s + w * w))
                .collect();
            cols.push(self.s.iter().zip(&inv).map(|(s, d)| s * d).collect());
            cols.push(inv);
        }
        cols.push(vec![Complex64::new(1.0, 0.0); self.s.len()]);
        cols.push(self.s.iter().map(|&s| 1.0 / (s * s)).collect());
        cols
    }

    /// Weighted residual (real parts, then imaginary parts) after the linear LS for the
    /// residues; `None` if that LS is singular.
    fn projected(&self, theta: &DVector<f64>) -> Option<DVector<f64>> {
        let cols = self.basis(theta);
        let n = self.s.len();
        let p = cols.len();
        let mut a = DMatrix::<f64>::zeros(2 * n, p);
        let mut y = DVector::<f64>::zeros(2 * n);
        for k in 0..n {
            let w = self.sqrt_w[k];
            y[k] = w * self.h[k].re;
            y[n + k] = w * self.h[k].im;
            for (j, c) in cols.iter().enumerate() {
                a[(k, j)] = w * c[k].re;
                a[(n + k, j)] = w * c[k].im;
            }
        }
        // Column scaling keeps the LS well conditioned (the columns differ by ω⁴).
        let scale: Vec<f64> = (0..p).map(|j| a.column(j).norm().max(1e-300)).collect();
        for (j, sc) in scale.iter().enumerate() {
            a.column_mut(j).scale_mut(1.0 / sc);
        }
        let c = solve_scaled(&a, &y)?;
        let r = &a * c - y;
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    /// [`Self::projected`] at several points, the second half on a spare core when one is free
    /// ([`crate::numeric::cores`]); the results are those of one call per point, in order.
    fn projected_batch(&self, thetas: &[DVector<f64>]) -> Vec<Option<DVector<f64>>> {
        let core = if thetas.len() >= 2 {
            cores::take()
        } else {
            None
        };
        let Some(_core) = core else {
            return thetas.iter().map(|t| self.projected(t)).collect();
        };
        let (first, second) = thetas.split_at(thetas.len().div_ceil(2));
        std::thread::scope(|scope| {
            let theirs =
                scope.spawn(|| second.iter().map(|t| self.projected(t)).collect::<Vec<_>>());
            let mut mine: Vec<_> = first.iter().map(|t| self.projected(t)).collect();
            match theirs.join() {
                Ok(v) => mine.extend(v),
                Err(_) => mine.extend(second.iter().map(|t| self.projected(t))),
            }
            mine
        })
    }
}

/// The least-squares coefficients of `a c ≈ y` for `a` with unit-norm columns: Householder QR
/// (backward stable, the residual is accurate to rounding, which the finite-difference Jacobian
/// needs), or the SVD with singular values below 1e-12 dropped when R has a diagonal below
/// 1e-12 (a rank-deficient basis, e.g. two poles on top of each other). `None` when neither
/// gives finite values.
fn solve_scaled(a: &DMatrix<f64>, y: &DVector<f64>) -> Option<DVector<f64>> {
    let p = a.ncols();
    let qr = a.clone().qr();
    let r = qr.r();
    if (0..p).all(|i| r[(i, i)].abs() > 1e-12) {
        let mut qty = y.clone();
        qr.q_tr_mul(&mut qty);
        let mut c = qty.rows(0, p).into_owned();
        if r.solve_upper_triangular_mut(&mut c) && c.iter().all(|v| v.is_finite()) {
            return Some(c);
        }
    }
    a.clone().svd(true, true).solve(y, 1e-12).ok()
}

/// The adapter's options of the fit: central differences of step 1e-6 in (ln ω, ln ζ),
/// patience 200, the crate's default tolerances.
fn lm_options(n_theta: usize) -> LmOptions {
    LmOptions {
        difference: Difference::Central,
        patience: 200,
        ..LmOptions::new(vec![1e-6; n_theta])
    }
}

/// The lines `band` of `frf` as s = jω and the square roots of their weights S_xx / max S_xx,
/// and that maximum. Errors: fewer than 4 lines per parameter, no input power.
fn weighted_lines(
    frf: &Frf,
    band: std::ops::Range<usize>,
    band_hz: (f64, f64),
    n_par: usize,
) -> Result<(Vec<Complex64>, Vec<f64>, f64)> {
    if band.len() < 4 * n_par {
        bail!(
            "{} lines in {:.3}..{:.3} Hz for {} parameters",
            band.len(),
            band_hz.0,
            band_hz.1,
            n_par
        );
    }
    let s: Vec<Complex64> = frf.freq_hz[band.clone()]
        .iter()
        .map(|f| Complex64::new(0.0, 2.0 * PI * f))
        .collect();
    let sxx = &frf.sxx[band.clone()];
    let w_max = sxx.iter().fold(0.0f64, |a, &b| a.max(b));
    if !(w_max > 0.0) {
        bail!(
            "the input has no power in {:.3}..{:.3} Hz",
            band_hz.0,
            band_hz.1
        );
    }
    let sqrt_w: Vec<f64> = sxx.iter().map(|v| (v / w_max).max(0.0).sqrt()).collect();
    Ok((s, sqrt_w, w_max))
}

/// Refines `start` (natural frequencies in Hz, damping ratios) on the lines of `frf` with
/// `band_hz.0 ≤ f ≤ band_hz.1`, by the output-error (maximum-likelihood) fit of the module
/// docs. Weights: the input auto-spectrum S_xx of each line (white output noise).
///
/// Errors: no start mode, fewer than 4 lines per parameter in the band, a fit that does not
/// converge to finite values or moves a frequency out of the band.
pub fn refine_modes(frf: &Frf, band_hz: (f64, f64), start: &[ModeEstimate]) -> Result<Refinement> {
    if start.is_empty() {
        bail!("no mode to refine");
    }
    let band = frf.band(band_hz.0.max(frf.df_hz()), band_hz.1);
    let n_par = 2 * start.len() + (2 * start.len() + 2);
    let (s, sqrt_w, w_max) = weighted_lines(frf, band.clone(), band_hz, n_par)?;
    let theta0 = DVector::from_iterator(
        2 * start.len(),
        start
            .iter()
            .flat_map(|m| [(2.0 * PI * m.freq_hz).ln(), m.zeta.max(1e-5).ln()]),
    );
    let problem = Problem {
        s,
        h: &frf.h1[band.clone()],
        sqrt_w,
    };
    let Some(r0) = problem.projected(&theta0) else {
        bail!("singular least-squares problem at the starting poles");
    };
    let cost_start = r0.norm_squared() * w_max;
    let f = |theta: &DVector<f64>| problem.projected(theta);
    let batch = |thetas: &[DVector<f64>]| problem.projected_batch(thetas);
    let opts = lm_options(theta0.len());
    let out = minimize_batched(&f, &batch, theta0, &opts);
    if !out.cost.is_finite() {
        bail!("the fit did not converge ({})", out.termination);
    }
    let theta = out.x;
    let Some(r) = problem.projected(&theta) else {
        bail!("the fit diverged");
    };
    let Ok(j) = fd_jacobian_batched(&batch, &theta, &r, &opts) else {
        bail!("the fit diverged");
    };
    let n_obs = r.len() as f64;
    let dof = (n_obs - n_par as f64).max(1.0);
    let s2 = r.norm_squared() / dof;
    let cov = (j.transpose() * &j).try_inverse().map(|c| c * s2);
    Ok(Refinement {
        modes: refined_modes(&theta, cov.as_ref(), start, band_hz)?,
        cost_start,
        cost_end: r.norm_squared() * w_max,
    })
}

/// The modes of θ = (ln ω_r, ln ζ_r) with their 1-σ from `cov` (NaN without); errors when a
/// mode left the band or moved more than 5 % from its start.
fn refined_modes(
    theta: &DVector<f64>,
    cov: Option<&DMatrix<f64>>,
    start: &[ModeEstimate],
    band_hz: (f64, f64),
) -> Result<Vec<RefinedMode>> {
    let mut modes = Vec::with_capacity(start.len());
    for (i, m0) in start.iter().enumerate() {
        let freq_hz = theta[2 * i].exp() / (2.0 * PI);
        let zeta = theta[2 * i + 1].exp();
        if !(freq_hz.is_finite() && zeta.is_finite())
            || freq_hz < band_hz.0
            || freq_hz > band_hz.1
            || (freq_hz / m0.freq_hz - 1.0).abs() > 0.05
        {
            bail!(
                "the fit moved the mode at {:.4} Hz to {:.4} Hz (ζ {:.4})",
                m0.freq_hz,
                freq_hz,
                zeta
            );
        }
        let (sf, sz) = match cov {
            Some(c) => (
                freq_hz * c[(2 * i, 2 * i)].max(0.0).sqrt(),
                zeta * c[(2 * i + 1, 2 * i + 1)].max(0.0).sqrt(),
            ),
            None => (f64::NAN, f64::NAN),
        };
        modes.push(RefinedMode {
            freq_hz,
            zeta,
            freq_hz_std: sf,
            zeta_std: sz,
        });
    }
    Ok(modes)
}

/// Replaces `modes` by their maximum-likelihood refinement ([`super::mlfit`]); the σ of each is
/// the fit's Gauss–Newton σ and the method's own spread in quadrature. On failure the modes
/// stay and a warning says why (`method` names them in it).
pub fn refine_estimates(
    frf: &Frf,
    band: (f64, f64),
    modes: &mut [ModeEstimate],
    method: &str,
    warnings: &mut Vec<String>,
) {
    if modes.is_empty() {
        return;
    }
    match super::mlfit::refine_modes(frf, band, modes) {
        Ok(r) => {
            for (e, q) in modes.iter_mut().zip(&r.modes) {
                e.freq_hz_std = e.freq_hz_std.hypot(q.freq_hz_std);
                e.zeta_std = e.zeta_std.hypot(q.zeta_std);
                e.freq_hz = q.freq_hz;
                e.zeta = q.zeta;
                e.method = format!("{}+ml", e.method);
            }
        }
        Err(e) => warnings.push(format!(
            "maximum-likelihood refinement skipped ({e:#}); {method} estimates kept"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// A two-mode FRF with complex output noise: the refinement recovers f and ζ from poor
    /// starting values, and the truth lies within 4 σ of the estimate.
    #[test]
    fn recovers_two_modes_from_noisy_frf() {
        let df = 0.005;
        let n = 2000;
        let truth = [(1.1, 0.0074, -0.9), (6.9, 0.0074, 0.3)];
        let mut rng = StdRng::seed_from_u64(3);
        let nrm = Normal::new(0.0, 1.0).unwrap();
        let freq_hz: Vec<f64> = (0..n).map(|k| k as f64 * df).collect();
        let h1: Vec<Complex64> = freq_hz
            .iter()
            .map(|&f| {
                let s = Complex64::new(0.0, 2.0 * PI * f);
                let clean: Complex64 = truth
                    .iter()
                    .map(|&(fr, z, g)| {
                        let w = 2.0 * PI * fr;
                        g / (s * s + 2.0 * z * w * s + w * w)
                    })
                    .sum::<Complex64>()
                    + 0.001;
                clean + 2e-3 * Complex64::new(nrm.sample(&mut rng), nrm.sample(&mut rng))
            })
            .collect();
        let frf = Frf {
            freq_hz,
            h1: h1.clone(),
            h2: h1,
            coherence: vec![1.0; n],
            sxx: vec![1.0; n],
            syy: vec![1.0; n],
            n_averages: 1,
            sample_rate_hz: 2.0 * n as f64 * df,
            nperseg: 2 * n,
            window_decay_s: 0.0,
            input: String::new(),
            output: String::new(),
        };
        let start: Vec<ModeEstimate> = [(1.12, 0.01), (6.85, 0.012)]
            .iter()
            .map(|&(f, z)| ModeEstimate {
                freq_hz: f,
                zeta: z,
                freq_hz_std: 0.0,
                zeta_std: 0.0,
                method: "start".into(),
            })
            .collect();
        let r = refine_modes(&frf, (0.3, 9.0), &start).unwrap();
        assert!(r.cost_end < r.cost_start);
        for (m, t) in r.modes.iter().zip(&truth) {
            assert!(
                (m.freq_hz - t.0).abs() < 4.0 * m.freq_hz_std,
                "{m:?} vs {t:?}"
            );
            assert!((m.zeta - t.1).abs() < 4.0 * m.zeta_std, "{m:?} vs {t:?}");
            assert!((m.zeta / t.1 - 1.0).abs() < 0.1, "{m:?} vs {t:?}");
            assert!(m.zeta_std > 0.0 && m.freq_hz_std > 0.0);
        }
    }

    #[test]
    fn refuses_a_band_without_lines() {
        let frf = Frf {
            freq_hz: vec![0.0, 1.0, 2.0],
            h1: vec![Complex64::new(1.0, 0.0); 3],
            h2: vec![Complex64::new(1.0, 0.0); 3],
            coherence: vec![1.0; 3],
            sxx: vec![1.0; 3],
            syy: vec![1.0; 3],
            n_averages: 1,
            sample_rate_hz: 4.0,
            nperseg: 4,
            window_decay_s: 0.0,
            input: String::new(),
            output: String::new(),
        };
        let m = ModeEstimate {
            freq_hz: 1.0,
            zeta: 0.01,
            freq_hz_std: 0.0,
            zeta_std: 0.0,
            method: String::new(),
        };
        assert!(refine_modes(&frf, (0.5, 1.5), &[m]).is_err());
    }
}
