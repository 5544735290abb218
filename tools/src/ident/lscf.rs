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

/// The lines of one LSCF problem prepared once for every model order up to `max_order`: the
/// discrete frequencies Ω_k = e^{iω_kΔt} and the first pass's Toeplitz diagonals (module docs)
/// up to lag `max_order`. An order-n model uses their first n + 1 entries, so a stabilisation
/// diagram sums over the lines once instead of once per order; every order's answer is the one
/// a separate computation gives, bit for bit.
pub struct LscfLines<'a> {
    freq_hz: &'a [f64],
    h: &'a [Complex64],
    weight: &'a [f64],
    /// Ω_k = e^{iω_kΔt}, one per line.
    omega: Vec<Complex64>,
    /// The diagonals of the first pass (weights `weight`), lags 0..=max_order.
    first: Diagonals,
}

/// The Toeplitz diagonals of R, T and S (lags d ≥ 0; S's above and below its diagonal).
struct Diagonals {
    rd: Vec<f64>,
    td: Vec<f64>,
    sp: Vec<f64>,
    sm: Vec<f64>,
}

impl Diagonals {
    /// R, S and T are Toeplitz: Re(conj(Ω^i) Ω^j) = cos((j − i)θ) and
    /// Re(−conj(Ω^i) H Ω^j) = Re(−H Ω^(j−i)); their diagonals are sums over the lines of one
    /// power Ω^d each, O(lines × order) instead of O(lines × order²).
    fn sum(omega: &[Complex64], h: &[Complex64], weight: &[f64], n1: usize) -> Diagonals {
        let mut g = Diagonals {
            rd: vec![0.0; n1],
            td: vec![0.0; n1],
            sp: vec![0.0; n1], // j − i = d ≥ 0
            sm: vec![0.0; n1], // i − j = d ≥ 0
        };
        for k in 0..omega.len() {
            let w = weight[k];
            if !(w > 0.0) || !h[k].re.is_finite() || !h[k].im.is_finite() {
                continue;
            }
            let om = omega[k];
            let w2 = w * w;
            let hh = h[k];
            let h2 = hh.norm_sqr();
            let mut p = Complex64::new(1.0, 0.0);
            for d in 0..n1 {
                g.rd[d] += w2 * p.re;
                g.td[d] += w2 * h2 * p.re;
                g.sp[d] -= w2 * (hh * p).re;
                g.sm[d] -= w2 * (hh * p.conj()).re;
                p *= om;
            }
        }
        g
    }
}

impl<'a> LscfLines<'a> {
    /// Prepares `freq_hz` (ascending, the band's lines), `h` and `weight` (one per line) for
    /// orders up to `max_order`; Δt = 1/(2 f_hi) with f_hi the last line.
    pub fn new(
        freq_hz: &'a [f64],
        h: &'a [Complex64],
        weight: &'a [f64],
        max_order: usize,
    ) -> LscfLines<'a> {
        let dt = 1.0 / (2.0 * freq_hz.last().copied().unwrap_or(1.0));
        let omega: Vec<Complex64> = freq_hz
            .iter()
            .map(|&f| Complex64::new(0.0, 2.0 * std::f64::consts::PI * f * dt).exp())
            .collect();
        let first = Diagonals::sum(&omega, h, weight, max_order + 1);
        LscfLines {
            freq_hz,
            h,
            weight,
            omega,
            first,
        }
    }

    /// The order-`order` model's physical poles (0 < ζ < `zeta_max`, inside the band) after
    /// `sk_iterations` Sanathanan–Koerner iterations: each re-solves with the line weights
    /// divided by |A(Ω_k)| of the previous denominator, so the cost tends to the output error
    /// |B/A − H|² and the damping bias that output noise gives the linearised cost (H noise
    /// multiplied by A) goes away.
    ///
    /// Errors: fewer lines than 2·order + 2, order 0 or above the prepared maximum, an
    /// ill-conditioned system.
    pub fn poles(&self, order: usize, zeta_max: f64, sk_iterations: usize) -> Result<Vec<Pole>> {
        let nl = self.freq_hz.len();
        if nl < 2 * order + 2 || order == 0 {
            bail!(
                "LSCF order {order} needs at least {} frequency lines in the band (have {nl})",
                2 * order + 2
            );
        }
        if order + 1 > self.first.rd.len() {
            bail!(
                "LSCF order {order} above the prepared maximum {}",
                self.first.rd.len() - 1
            );
        }
        let mut res = self.solve(&self.first, order, zeta_max)?;
        for _ in 0..sk_iterations {
            let Some(w) = self.sk_weights(&res.1) else {
                break;
            };
            let g = Diagonals::sum(&self.omega, self.h, &w, order + 1);
            match self.solve(&g, order, zeta_max) {
                Ok(r) => res = r,
                Err(_) => break,
            }
        }
        Ok(res.0)
    }

    /// The weights of the next Sanathanan–Koerner pass: `weight` / |A(Ω_k)|, normalised to a
    /// maximum of 1; `None` when A vanishes everywhere or overflows.
    fn sk_weights(&self, coef: &[f64]) -> Option<Vec<f64>> {
        let mut nw = Vec::with_capacity(self.omega.len());
        for (k, &om) in self.omega.iter().enumerate() {
            let mut p = Complex64::new(1.0, 0.0);
            let mut a = Complex64::new(0.0, 0.0);
            for &c in coef {
                a += p * c;
                p *= om;
            }
            nw.push(self.weight[k] / a.norm().max(1e-300));
        }
        let m = nw.iter().cloned().fold(0.0, f64::max);
        (m > 0.0 && m.is_finite()).then(|| nw.iter().map(|v| v / m).collect())
    }

    /// Solves the reduced normal equations of order `order` from the diagonals `g` (module
    /// docs): the physical poles and the denominator's coefficients (a_n = 1 last).
    fn solve(&self, g: &Diagonals, order: usize, zeta_max: f64) -> Result<(Vec<Pole>, Vec<f64>)> {
        let nl = self.freq_hz.len();
        let (f_lo, f_hi) = (self.freq_hz[0], self.freq_hz[nl - 1]);
        let dt = 1.0 / (2.0 * f_hi);
        let n1 = order + 1;
        let r = DMatrix::<f64>::from_fn(n1, n1, |i, j| g.rd[i.abs_diff(j)]);
        let t = DMatrix::<f64>::from_fn(n1, n1, |i, j| g.td[i.abs_diff(j)]);
        let s = DMatrix::<f64>::from_fn(
            n1,
            n1,
            |i, j| {
                if j >= i {
                    g.sp[j - i]
                } else {
                    g.sm[i - j]
                }
            },
        );
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
        let w = vec![1.0; f.len()];
        let p = LscfLines::new(&f, &h, &w, 8).poles(8, 0.2, 0).unwrap();
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
        assert!(LscfLines::new(&f, &h, &[1.0; 3], 4)
            .poles(4, 0.2, 0)
            .is_err());
    }
}
