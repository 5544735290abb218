//! Least-squares complex exponential (LSCE) method (paper §3.1, §5.2; Brown et al. 1979).
//!
//! 1. Impulse response h(t) = IFFT of the FRF, band-limited to [f_lo, f_hi] with raised-cosine
//!    edges inside the band (outside the excited band the FRF estimate is noise). The edges spread the
//!    response by about 1/(edge width), so the fit starts after `skip_s`.
//! 2. The IRF is decimated to a rate of ≈ 5 f_hi (keeps the band, conditions the problem).
//! 3. Prony / linear prediction: h[k+p] + a₁h[k+p−1] + … + a_p h[k] = 0 for all k, in least
//!    squares (SVD), p = 2 × the number of modes; the roots z_r of z^p + a₁z^{p−1} + … + a_p are
//!    e^{s_rΔt}.

use super::frf::Frf;
use super::poles::{physical_poles, poly_roots, Pole};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;

/// A band-limited impulse response, decimated.
#[derive(Clone, Debug)]
pub struct ImpulseResponse {
    /// Samples h[k] at t = k·dt_s (from 0).
    pub h: Vec<f64>,
    /// Sample interval (s).
    pub dt_s: f64,
}

/// Impulse response of `frf.h1` band-limited to [f_lo, f_hi] (raised-cosine edges of width
/// `edge_hz` inside the band), decimated to ≈ 5 f_hi.
///
/// Errors: a band beyond Nyquist or empty.
pub fn impulse_response(frf: &Frf, f_lo: f64, f_hi: f64, edge_hz: f64) -> Result<ImpulseResponse> {
    let nyq = 0.5 * frf.sample_rate_hz;
    if !(f_hi <= nyq && f_lo < f_hi && f_lo >= 0.0) {
        bail!("LSCE band {f_lo}..{f_hi} Hz must lie within 0..Nyquist {nyq} Hz");
    }
    let nf = frf.freq_hz.len();
    let nfft = 2 * (nf - 1);
    let mut spec: Vec<Complex64> = (0..nf)
        .map(|k| {
            let f = frf.freq_hz[k];
            let g = if f < f_lo || f > f_hi {
                0.0
            } else if f < f_lo + edge_hz {
                0.5 - 0.5 * (std::f64::consts::PI * (f - f_lo) / edge_hz).cos()
            } else if f > f_hi - edge_hz {
                0.5 + 0.5 * (std::f64::consts::PI * (f - f_hi + edge_hz) / edge_hz).cos()
            } else {
                1.0
            };
            let v = frf.h1[k];
            if g > 0.0 && v.re.is_finite() && v.im.is_finite() {
                v * g
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    spec[0].im = 0.0;
    spec[nf - 1].im = 0.0;
    let mut planner = RealFftPlanner::<f64>::new();
    let inv = planner.plan_fft_inverse(nfft);
    let mut out = inv.make_output_vec();
    inv.process(&mut spec, &mut out)
        .map_err(|e| anyhow::anyhow!("IFFT: {e}"))?;
    let fs = frf.sample_rate_hz;
    let stride = ((fs / (5.0 * f_hi)).floor() as usize).max(1);
    let h: Vec<f64> = out
        .iter()
        .step_by(stride)
        .map(|v| v * fs / nfft as f64)
        .collect();
    Ok(ImpulseResponse {
        h,
        dt_s: stride as f64 / fs,
    })
}

/// LSCE poles of model order `n_poles` (= 2 × modes) from the impulse response samples between
/// `skip_s` and `skip_s + len_s`, physical poles in [f_lo, f_hi] with ζ < `zeta_max`,
/// corrected for the window decay `sigma_w` (1/s).
///
/// Errors: too few samples for the order, a singular system.
pub fn lsce_poles(
    irf: &ImpulseResponse,
    n_poles: usize,
    skip_s: f64,
    len_s: f64,
    f_lo: f64,
    f_hi: f64,
    zeta_max: f64,
    sigma_w: f64,
) -> Result<Vec<Pole>> {
    let p = n_poles.max(2);
    let k0 = (skip_s / irf.dt_s).round() as usize;
    let k1 = (((skip_s + len_s) / irf.dt_s).round() as usize).min(irf.h.len() / 2);
    if k1 <= k0 + 3 * p {
        bail!(
            "LSCE order {p} needs more than {} impulse-response samples after {skip_s} s (have {})",
            3 * p,
            k1.saturating_sub(k0)
        );
    }
    let h = &irf.h[k0..k1];
    let rows = h.len() - p;
    let mut a = DMatrix::<f64>::zeros(rows, p);
    let mut b = DVector::<f64>::zeros(rows);
    for i in 0..rows {
        for j in 0..p {
            // column j multiplies h[i + p − 1 − j] (coefficient a_{j+1})
            a[(i, j)] = h[i + p - 1 - j];
        }
        b[i] = -h[i + p];
    }
    let svd = a.svd(true, true);
    let coef = svd
        .solve(&b, 1e-12)
        .map_err(|e| anyhow::anyhow!("LSCE: {e}"))?;
    // z^p + a1 z^{p-1} + ... + ap  → ascending coefficients [ap, ..., a1, 1]
    let mut c: Vec<f64> = coef.iter().rev().copied().collect();
    c.push(1.0);
    let roots = poly_roots(&c);
    Ok(physical_poles(&roots, irf.dt_s, 0.0, f64::INFINITY, 1.0)
        .into_iter()
        .map(|p| p.remove_decay(sigma_w))
        .filter(|p| p.zeta > 0.0 && p.zeta < zeta_max && p.freq_hz >= f_lo && p.freq_hz <= f_hi)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prony_recovers_two_damped_modes() {
        let dt = 0.04;
        let h: Vec<f64> = (0..1500)
            .map(|k| {
                let t = k as f64 * dt;
                let m = |f: f64, z: f64, a: f64| {
                    let w = 2.0 * std::f64::consts::PI * f;
                    a * (-z * w * t).exp() * (w * (1.0 - z * z).sqrt() * t + 0.3).sin()
                };
                m(1.105, 0.0074, 1.0) + m(6.92, 0.0074, 0.3)
            })
            .collect();
        let irf = ImpulseResponse { h, dt_s: dt };
        let p = lsce_poles(&irf, 4, 0.0, 30.0, 0.1, 10.0, 0.2, 0.0).unwrap();
        assert_eq!(p.len(), 2, "{p:?}");
        assert!(
            (p[0].freq_hz / 1.105 - 1.0).abs() < 1e-6 && (p[0].zeta / 0.0074 - 1.0).abs() < 1e-4
        );
        assert!(
            (p[1].freq_hz / 6.92 - 1.0).abs() < 1e-6 && (p[1].zeta / 0.0074 - 1.0).abs() < 1e-4
        );
    }
}
