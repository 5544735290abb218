//! Poles: continuous-time s = −ζω_n ± iω_n√(1−ζ²) from discrete roots z = e^{sΔt}, and the
//! polynomial roots the estimators need (companion matrix eigenvalues, nalgebra).

use nalgebra::DMatrix;
use realfft::num_complex::Complex64;
use serde::Serialize;

/// One pole of a fitted model (upper half-plane member of a conjugate pair).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pole {
    /// Undamped natural frequency |s| / 2π (Hz).
    pub freq_hz: f64,
    /// Damping ratio −Re(s)/|s|.
    pub zeta: f64,
}

impl Pole {
    /// From a continuous-time pole s (rad/s).
    pub fn from_s(s: Complex64) -> Pole {
        let wn = s.norm();
        Pole {
            freq_hz: wn / (2.0 * std::f64::consts::PI),
            zeta: -s.re / wn,
        }
    }

    /// The pole with an extra decay rate `sigma` (1/s) removed (exponential window):
    /// s' = s + σ.
    pub fn remove_decay(&self, sigma: f64) -> Pole {
        if sigma == 0.0 {
            return *self;
        }
        let wn = 2.0 * std::f64::consts::PI * self.freq_hz;
        let s = Complex64::new(
            -self.zeta * wn + sigma,
            wn * (1.0 - self.zeta * self.zeta).max(0.0).sqrt(),
        );
        Pole::from_s(s)
    }
}

/// Roots of Σ_{j=0}^{n} c_j z^j (c_n ≠ 0) as companion-matrix eigenvalues.
pub fn poly_roots(c: &[f64]) -> Vec<Complex64> {
    let n = c.len().saturating_sub(1);
    if n == 0 || c[n] == 0.0 || !c.iter().all(|v| v.is_finite()) {
        return vec![];
    }
    let mut m = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        m[(0, j)] = -c[n - 1 - j] / c[n];
    }
    for i in 1..n {
        m[(i, i - 1)] = 1.0;
    }
    m.complex_eigenvalues()
        .iter()
        .map(|z| Complex64::new(z.re, z.im))
        .collect()
}

/// Physical poles of discrete roots z (z = e^{sΔt}): upper half-plane, inside the unit circle
/// (stable), 0 < ζ < `zeta_max`, f_lo ≤ f ≤ f_hi; sorted by frequency.
pub fn physical_poles(
    roots: &[Complex64],
    dt: f64,
    f_lo: f64,
    f_hi: f64,
    zeta_max: f64,
) -> Vec<Pole> {
    let mut p: Vec<Pole> = roots
        .iter()
        .filter(|z| z.im > 0.0 && z.norm() < 1.0 && z.norm() > 0.0)
        .map(|z| Pole::from_s(z.ln() / dt))
        .filter(|p| p.zeta > 0.0 && p.zeta < zeta_max && p.freq_hz >= f_lo && p.freq_hz <= f_hi)
        .collect();
    p.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_and_poles_round_trip() {
        // (z - a)(z - conj a) with a = e^{s dt}
        let dt = 0.01;
        let wn = 2.0 * std::f64::consts::PI * 3.0;
        let z = 0.02;
        let s = Complex64::new(-z * wn, wn * (1.0f64 - z * z).sqrt());
        let a = (s * dt).exp();
        let c = [a.norm_sqr(), -2.0 * a.re, 1.0];
        let r = poly_roots(&c);
        let p = physical_poles(&r, dt, 0.0, 100.0, 0.5);
        assert_eq!(p.len(), 1);
        assert!((p[0].freq_hz - 3.0).abs() < 1e-9 && (p[0].zeta - z).abs() < 1e-9);
        let q = Pole {
            freq_hz: 3.0,
            zeta: 0.05,
        }
        .remove_decay(0.1);
        assert!(q.zeta < 0.05 && (q.freq_hz - 3.0).abs() < 0.01);
    }
}
