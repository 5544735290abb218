//! Least-squares complex-frequency-domain (LSCF) estimator, single input single output
//! (Guillaume, Verboven, Vanlanduit 1998; the `lscf` of sdypy-EMA).
//!
//! On the lines k of the band [f_lo, f_hi], with Ω_k = e^{iω_kΔt}, Δt = 1/(2 f_hi), the FRF is
//! modelled as a common-denominator rational function H ≈ B(Ω)/A(Ω) of order n. The linearised
//! error W_k (B(Ω_k) − H_k A(Ω_k)) is minimised in least squares: with X_k = W_k[Ω_k^j],
//! Y_k = −W_k H_k [Ω_k^j], R = Re XᴴX, S = Re XᴴY, T = Re YᴴY, the numerator is eliminated,
//! M = T − Sᵀ R⁻¹ S, and the denominator with a_n = 1 solves M[..n,..n] a = −M[..n, n].
//! The roots z_r of A are the discrete poles, s_r = ln(z_r)/Δt.

use super::poles::{physical_poles, poly_roots, Pole};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use realfft::num_complex::Complex64;

/// Poles of the order-`order` LSCF model of `h` at `freq_hz` (the lines to use), with
/// per-line weights `weight` (e.g. 1 or the coherence), keeping physical poles with
/// 0 < ζ < `zeta_max` inside [f_lo, f_hi] = the first and last line.
///
/// Errors: fewer lines than 2·order + 2, an ill-conditioned system.
pub fn lscf_poles(
    freq_hz: &[f64],
    h: &[Complex64],
    weight: &[f64],
    order: usize,
    zeta_max: f64,
) -> Result<Vec<Pole>> {
    lscf_poles_sk(freq_hz, h, weight, order, zeta_max, 0)
}

/// [`lscf_poles`] followed by `sk_iterations` Sanathanan–Koerner iterations: each re-solves
/// with the line weights divided by |A(Ω_k)| of the previous denominator, so the cost tends to
/// the output error |B/A − H|² and the damping bias that output noise gives the linearised
/// cost (H noise multiplied by A) goes away.
pub fn lscf_poles_sk(
    freq_hz: &[f64],
    h: &[Complex64],
    weight: &[f64],
    order: usize,
    zeta_max: f64,
    sk_iterations: usize,
) -> Result<Vec<Pole>> {
    let mut w = weight.to_vec();
    let mut res = lscf_once(freq_hz, h, &w, order, zeta_max)?;
    let dt = 1.0 / (2.0 * freq_hz[freq_hz.len() - 1]);
    for _ in 0..sk_iterations {
        let coef = &res.1;
        let mut nw = Vec::with_capacity(w.len());
        for (k, &f) in freq_hz.iter().enumerate() {
            let om = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f * dt).exp();
            let mut p = Complex64::new(1.0, 0.0);
            let mut a = Complex64::new(0.0, 0.0);
            for &c in coef {
                a += p * c;
                p *= om;
            }
            nw.push(weight[k] / a.norm().max(1e-300));
        }
        let m = nw.iter().cloned().fold(0.0, f64::max);
        if !(m > 0.0 && m.is_finite()) {
            break;
        }
        w = nw.iter().map(|v| v / m).collect();
        match lscf_once(freq_hz, h, &w, order, zeta_max) {
            Ok(r) => res = r,
            Err(_) => break,
        }
    }
    Ok(res.0)
}

fn lscf_once(
    freq_hz: &[f64],
    h: &[Complex64],
    weight: &[f64],
    order: usize,
    zeta_max: f64,
) -> Result<(Vec<Pole>, Vec<f64>)> {
    let nl = freq_hz.len();
    if nl < 2 * order + 2 || order == 0 {
        bail!(
            "LSCF order {order} needs at least {} frequency lines in the band (have {nl})",
            2 * order + 2
        );
    }
    let f_lo = freq_hz[0];
    let f_hi = freq_hz[nl - 1];
    let dt = 1.0 / (2.0 * f_hi);
    let n1 = order + 1;
    // R, S and T are Toeplitz: Re(conj(Ω^i) Ω^j) = cos((j − i)θ) and
    // Re(−conj(Ω^i) H Ω^j) = Re(−H Ω^(j−i)); their diagonals are sums over the lines of
    // one power Ω^d each, O(lines × order) instead of O(lines × order²).
    let mut rd = vec![0.0; n1];
    let mut td = vec![0.0; n1];
    let mut sp = vec![0.0; n1]; // j − i = d ≥ 0
    let mut sm = vec![0.0; n1]; // i − j = d ≥ 0
    for k in 0..nl {
        let w = weight[k];
        if !(w > 0.0) || !h[k].re.is_finite() || !h[k].im.is_finite() {
            continue;
        }
        let om = Complex64::new(0.0, 2.0 * std::f64::consts::PI * freq_hz[k] * dt).exp();
        let w2 = w * w;
        let hh = h[k];
        let h2 = hh.norm_sqr();
        let mut p = Complex64::new(1.0, 0.0);
        for d in 0..n1 {
            rd[d] += w2 * p.re;
            td[d] += w2 * h2 * p.re;
            sp[d] -= w2 * (hh * p).re;
            sm[d] -= w2 * (hh * p.conj()).re;
            p *= om;
        }
    }
    let r = DMatrix::<f64>::from_fn(n1, n1, |i, j| rd[i.abs_diff(j)]);
    let t = DMatrix::<f64>::from_fn(n1, n1, |i, j| td[i.abs_diff(j)]);
    let s = DMatrix::<f64>::from_fn(n1, n1, |i, j| if j >= i { sp[j - i] } else { sm[i - j] });
    let rinv_s = match r.clone().cholesky() {
        Some(c) => c.solve(&s),
        None => {
            r.clone()
                .pseudo_inverse(1e-12)
                .map_err(|e| anyhow::anyhow!("LSCF: {e}"))?
                * &s
        }
    };
    let m = &t - s.transpose() * rinv_s;
    let a = m.view((0, 0), (order, order)).into_owned();
    let rhs = -DVector::from_iterator(order, (0..order).map(|i| m[(i, order)]));
    let sol = match a.clone().lu().solve(&rhs) {
        Some(v) if v.iter().all(|x| x.is_finite()) => v,
        _ => a
            .svd(true, true)
            .solve(&rhs, 1e-14)
            .map_err(|e| anyhow::anyhow!("LSCF: singular system at order {order}: {e}"))?,
    };
    let mut coef: Vec<f64> = sol.iter().copied().collect();
    coef.push(1.0);
    let roots = poly_roots(&coef);
    Ok((physical_poles(&roots, dt, f_lo, f_hi, zeta_max), coef))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn modal_frf(f: &[f64], modes: &[(f64, f64, f64)]) -> Vec<Complex64> {
        f.iter()
            .map(|&fk| {
                let w = 2.0 * std::f64::consts::PI * fk;
                modes
                    .iter()
                    .map(|&(fr, z, a)| {
                        let wr = 2.0 * std::f64::consts::PI * fr;
                        Complex64::new(a, 0.0) / Complex64::new(wr * wr - w * w, 2.0 * z * wr * w)
                    })
                    .sum()
            })
            .collect()
    }

    #[test]
    fn recovers_two_modes_of_an_exact_frf() {
        let f: Vec<f64> = (0..800).map(|k| 0.3 + k as f64 * 0.01).collect();
        let h = modal_frf(&f, &[(1.105, 0.0074, 1.0), (6.92, 0.0074, -0.6)]);
        let p = lscf_poles(&f, &h, &vec![1.0; f.len()], 8, 0.2).unwrap();
        let m1 = p
            .iter()
            .find(|p| (p.freq_hz - 1.105).abs() < 0.01)
            .expect("mode 1");
        let m2 = p
            .iter()
            .find(|p| (p.freq_hz - 6.92).abs() < 0.05)
            .expect("mode 2");
        assert!(
            (m1.freq_hz / 1.105 - 1.0).abs() < 1e-4 && (m1.zeta / 0.0074 - 1.0).abs() < 0.01,
            "{m1:?}"
        );
        assert!(
            (m2.freq_hz / 6.92 - 1.0).abs() < 1e-4 && (m2.zeta / 0.0074 - 1.0).abs() < 0.01,
            "{m2:?}"
        );
    }

    #[test]
    fn too_few_lines_is_an_error() {
        let f = [1.0, 2.0, 3.0];
        let h = vec![Complex64::new(1.0, 0.0); 3];
        assert!(lscf_poles(&f, &h, &[1.0; 3], 4, 0.2).is_err());
    }
}
