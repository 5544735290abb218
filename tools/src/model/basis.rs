//! The Galerkin basis: clamped–free Euler–Bernoulli beam functions (paper eqs. 9–11).
//!
//! φ_i(x) = cosh λx − cos λx − σ_i (sinh λx − sin λx), σ_i = (sinh λl − sin λl)/(cosh λl + cos λl),
//! with λ_i l the roots of 1 + cos λl cosh λl = 0 (1.87510, 4.69409, 7.85476, …).
//!
//! Deviation from the paper, on purpose: eq. (10) as printed mixes normalisations and eq. (11)
//! contains the base-to-beam mass ratio m_b/m, i.e. the roots of a pinned-mass (free-base)
//! problem. A Galerkin basis only has to be *admissible* (w(0) = w'(0) = 0); the coupling to the
//! moving base enters through the first row of M (h_i, eq. 18) whatever the basis. We use the
//! clamped–free functions, the m → ∞ limit of eq. (11), so that the same basis serves the clamped
//! and the free base and any A(x), I(x); the tests check the resulting frequencies against the
//! exact Euler–Bernoulli values, an independent finite-element model and eq. (11) itself.
//!
//! Numerics: for large λx the hyperbolic terms cancel catastrophically; we evaluate
//! `cosh s − σ sinh s = ½ e^{s}(1−σ) + ½ e^{−s}(1+σ)` with `e^{s}(1−σ)/2` rewritten as
//! `a·e^{s−L}`, `a = (e^{−L} + cos L + sin L)/(1 + e^{−2L} + 2 e^{−L} cos L)`, exact to rounding
//! for any mode number.

/// λ_i·l of the i-th clamped–free mode (i ≥ 1): root of 1 + cos x cosh x = 0 in ((i−1)π, iπ).
pub fn lambda_l(i: usize) -> f64 {
    let g = |x: f64| x.cos() + 1.0 / x.cosh();
    let (mut a, mut b) = (
        (i as f64 - 1.0) * std::f64::consts::PI + 0.01,
        i as f64 * std::f64::consts::PI,
    );
    let ga = g(a);
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if (g(m) > 0.0) == (ga > 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// One basis function, with λ (1/m) and the precomputed stable coefficients.
#[derive(Clone, Copy, Debug)]
pub struct BasisFn {
    /// λ_i (1/m).
    pub lambda: f64,
    l_lambda: f64,
    sigma: f64,
    a: f64,
}

impl BasisFn {
    /// The i-th function (i ≥ 1) for a beam of length `length_m`.
    pub fn new(i: usize, length_m: f64) -> Self {
        let big_l = lambda_l(i);
        let sigma = (big_l.sinh() - big_l.sin()) / (big_l.cosh() + big_l.cos());
        let e = (-big_l).exp();
        let a = (e + big_l.cos() + big_l.sin()) / (1.0 + e * e + 2.0 * e * big_l.cos());
        BasisFn {
            lambda: big_l / length_m,
            l_lambda: big_l,
            sigma,
            a,
        }
    }

    /// φ(x), φ'(x) (1/m), φ''(x) (1/m²).
    pub fn eval(&self, x: f64) -> (f64, f64, f64) {
        let s = self.lambda * x;
        let grow = self.a * (s - self.l_lambda).exp();
        let decay = 0.5 * (-s).exp() * (1.0 + self.sigma);
        let (sn, cs) = s.sin_cos();
        let lam = self.lambda;
        (
            grow + decay - cs + self.sigma * sn,
            lam * (grow - decay + sn + self.sigma * cs),
            lam * lam * (grow + decay + cs - self.sigma * sn),
        )
    }
}
