//! A physics-free linear correction of a model residual: the yardstick of the diagnosis'
//! model-form allowance.
//!
//! Given signals s_1..s_m of the model (its prediction ŷ of one channel, the part of it that a
//! filter inside the model would change, the base motion u that drives it), the correction is
//! r̂ = Σ_{j∈S} c_j φ_j with the dictionary φ = (s_i, Ds_i, D²s_i), D the central difference:
//! to first order, any small linear filter on the model's input path, inside it or on its
//! output (gain, lag, lead, a slightly different low-pass) is a combination of these (a linear
//! model's response to D^j u is D^j of its response to u). A caller leaves out a column that
//! is not model-form freedom of what is modelled but a physical path of its own (for the
//! diagnosis' force channel the carriage velocity, i.e. viscous friction): a yardstick that
//! contains a candidate's physics cannot measure whether that physics is needed. For a
//! given number k of free coefficients and every subset S (|S| = k), the coefficients c are
//! those of least squares on the **fit** recordings' residual, and the subset that fits them
//! best is kept — chosen on the fit recordings, as a candidate's parameters are; the
//! correction is then applied, never refitted, to the **validation** recording's residual.
//! That gain is what k free parameters without any physics earn on validation: a catalogue
//! effect with k parameters that does not beat it has not shown that its physics, rather than
//! generic model-form freedom, is what the recordings need. (Choosing the subset on the
//! validation recording instead would make the yardstick the best of up to C(9, 4) = 126
//! corrections on the very data it is compared on, a maximum over subsets that no single
//! candidate gets.)
//!
//! Computation: Gram matrices of the (rms-normalised) dictionary on fit and validation data,
//! every subset of size k solved by Cholesky (at most C(9, 4) = 126 systems of size ≤ 4).

use nalgebra::{DMatrix, DVector};

/// Derivative orders of every signal in the dictionary (0, 1, 2).
pub const ORDERS: usize = 3;

/// Central difference (one-sided at the ends), per sample.
fn diff(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (v[b] - v[a]) / (b - a).max(1) as f64
        })
        .collect()
}

/// Dictionary columns (module docs) of one recording: every signal of `signals` (same length)
/// and its first and second central differences, signal after signal, except the
/// `(signal, order)` pairs listed in `without` (a column that is not model-form freedom; see
/// the diagnosis' use).
pub fn dictionary(signals: &[&[f64]], without: &[(usize, usize)]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(ORDERS * signals.len());
    for (i, s) in signals.iter().enumerate() {
        let d1 = diff(s);
        let d2 = diff(&d1);
        for (order, col) in [s.to_vec(), d1, d2].into_iter().enumerate() {
            if !without.contains(&(i, order)) {
                out.push(col);
            }
        }
    }
    out
}

/// Number of columns [`dictionary`] gives for `n_signals` signals without `n_without` of them.
pub fn dictionary_size(n_signals: usize, n_without: usize) -> usize {
    ORDERS * n_signals - n_without
}

/// Accumulated normal equations of one data set: G = ΦᵀΦ, b = Φᵀr, rr = rᵀr.
#[derive(Clone, Debug)]
pub struct Normal {
    g: DMatrix<f64>,
    b: DVector<f64>,
    rr: f64,
}

impl Normal {
    /// Empty normal equations for a dictionary of `m` columns ([`dictionary_size`]).
    pub fn new(m: usize) -> Self {
        Normal {
            g: DMatrix::zeros(m, m),
            b: DVector::zeros(m),
            rr: 0.0,
        }
    }

    /// Adds one recording: residual `r` and the dictionary's columns ([`dictionary`]; each as
    /// long as `r`, as many as given to [`Normal::new`]). Recordings shorter than 3 samples are
    /// skipped.
    pub fn add(&mut self, r: &[f64], phi: &[Vec<f64>]) {
        if r.len() < 3 || phi.iter().any(|s| s.len() != r.len()) {
            return;
        }
        assert_eq!(phi.len(), self.b.len(), "dictionary size");
        for i in 0..phi.len() {
            self.b[i] += phi[i].iter().zip(r).map(|(a, b)| a * b).sum::<f64>();
            for j in 0..=i {
                let v: f64 = phi[i].iter().zip(&phi[j]).map(|(a, b)| a * b).sum();
                self.g[(i, j)] += v;
                self.g[(j, i)] = self.g[(i, j)];
            }
        }
        self.rr += r.iter().map(|x| x * x).sum::<f64>();
    }

    /// Residual sum of squares before any correction.
    pub fn rss(&self) -> f64 {
        self.rr
    }
}

/// The best generic correction with `k` coefficients.
#[derive(Clone, Debug)]
pub struct Correction {
    /// Dictionary columns used.
    pub columns: Vec<usize>,
    /// Their coefficients.
    pub coef: Vec<f64>,
    /// Fit-data RSS before and after.
    pub fit_rss: (f64, f64),
    /// Validation RSS before and after (the correction fitted on the fit data only).
    pub val_rss: (f64, f64),
}

impl Correction {
    /// Relative rms reduction of the validation residual, 1 − sqrt(after/before) (may be < 0).
    pub fn val_reduction(&self) -> f64 {
        1.0 - (self.val_rss.1 / self.val_rss.0.max(1e-300)).sqrt()
    }
}

/// The `k`-column correction (module docs) that fits `fit` best, with its gain on `val`;
/// `None` for k = 0 or when no subset can be solved.
pub fn best_correction(fit: &Normal, val: &Normal, k: usize) -> Option<Correction> {
    let m = fit.b.len();
    let k = k.min(m);
    if k == 0 || m > 16 {
        return None;
    }
    // normalise columns for conditioning
    let scale: Vec<f64> = (0..m).map(|i| fit.g[(i, i)].sqrt().max(1e-300)).collect();
    let mut best: Option<Correction> = None;
    for mask in 0u32..(1 << m) {
        if mask.count_ones() as usize != k {
            continue;
        }
        let cols: Vec<usize> = (0..m).filter(|i| mask & (1 << i) != 0).collect();
        if cols.iter().any(|&i| fit.g[(i, i)] <= 0.0) {
            continue;
        }
        let gs = DMatrix::from_fn(k, k, |a, b| {
            fit.g[(cols[a], cols[b])] / (scale[cols[a]] * scale[cols[b]])
        });
        let bs = DVector::from_fn(k, |a, _| fit.b[cols[a]] / scale[cols[a]]);
        let Some(ch) = gs.clone().cholesky() else {
            continue;
        };
        let cn = ch.solve(&bs);
        let fit_after = (fit.rr - bs.dot(&cn)).max(0.0);
        let c: Vec<f64> = (0..k).map(|a| cn[a] / scale[cols[a]]).collect();
        let mut val_after = val.rr;
        for a in 0..k {
            val_after -= 2.0 * c[a] * val.b[cols[a]];
            for b in 0..k {
                val_after += c[a] * c[b] * val.g[(cols[a], cols[b])];
            }
        }
        let val_after = val_after.max(0.0);
        if best.as_ref().map_or(true, |b| fit_after < b.fit_rss.1) {
            best = Some(Correction {
                columns: cols,
                coef: c,
                fit_rss: (fit.rr, fit_after),
                val_rss: (val.rr, val_after),
            });
        }
    }
    best
}

/// The correction of `k` parameters: [`best_correction`] with `k` columns, or, where no `k`
/// columns can be solved (the dictionary's rank is below k: two of its signals the same), the
/// best of the largest size that can, since a correction of k parameters with dependent columns
/// is one of fewer. `None` for k = 0 or when no column can be solved.
pub fn best_correction_of_size(fit: &Normal, val: &Normal, k: usize) -> Option<Correction> {
    (1..=k).rev().find_map(|j| best_correction(fit, val, j))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The columns are chosen on the fit recordings, as a candidate's parameters are: where the
    /// fit residual is one signal and the validation residual another, the correction of one
    /// column is the fit residual's and earns nothing on validation — the validation
    /// recording's own signal is not picked for it.
    #[test]
    fn the_columns_are_chosen_on_the_fit_recordings() {
        let n = 1500;
        let sig = |f: f64, k: usize| (2.0 * std::f64::consts::PI * f * k as f64 / 100.0).sin();
        let a: Vec<f64> = (0..n).map(|k| sig(0.37, k)).collect();
        let b: Vec<f64> = (0..n).map(|k| sig(1.9, k)).collect();
        let phi = dictionary(&[&a, &b], &[]);
        let (mut f, mut v) = (Normal::new(phi.len()), Normal::new(phi.len()));
        f.add(&a, &phi);
        v.add(&b, &phi);
        let c = best_correction(&f, &v, 1).unwrap();
        assert_eq!(c.columns, vec![0]);
        assert!(c.val_reduction() < 0.01, "{}", c.val_reduction());
    }

    /// A column left out of the dictionary is not available to the correction: a residual that
    /// is exactly the second signal's first difference is removed with it and not without it.
    #[test]
    fn a_column_left_out_is_not_used() {
        let n = 1500;
        let sig = |f: f64, k: usize| (2.0 * std::f64::consts::PI * f * k as f64 / 100.0).sin();
        let y: Vec<f64> = (0..n).map(|k| sig(1.1, k)).collect();
        let u: Vec<f64> = (0..n).map(|k| sig(0.37, k) + 0.2 * sig(2.9, k)).collect();
        let r = diff(&u);
        let reduction = |without: &[(usize, usize)]| {
            let phi = dictionary(&[&y, &u], without);
            assert_eq!(phi.len(), dictionary_size(2, without.len()));
            let (mut f, mut v) = (Normal::new(phi.len()), Normal::new(phi.len()));
            f.add(&r, &phi);
            v.add(&r, &phi);
            best_correction(&f, &v, 1).unwrap().val_reduction()
        };
        assert!(reduction(&[]) > 0.999);
        assert!(reduction(&[(1, 1)]) < 0.9, "{}", reduction(&[(1, 1)]));
    }

    /// Two signals of the dictionary the same (a prediction equal to the command): no five of
    /// its six columns can be solved, and a correction of five parameters is the best of three.
    #[test]
    fn a_correction_larger_than_the_dictionarys_rank_is_one_of_fewer() {
        let n = 1500;
        let sig = |f: f64, k: usize| (2.0 * std::f64::consts::PI * f * k as f64 / 100.0).sin();
        let u: Vec<f64> = (0..n).map(|k| sig(0.37, k) + 0.2 * sig(2.9, k)).collect();
        let r: Vec<f64> = diff(&u)
            .iter()
            .zip(&u)
            .map(|(d, x)| 0.3 * d - 0.1 * x)
            .collect();
        let phi = dictionary(&[&u, &u], &[]);
        let (mut f, mut v) = (Normal::new(phi.len()), Normal::new(phi.len()));
        f.add(&r, &phi);
        v.add(&r, &phi);
        assert!(best_correction(&f, &v, 5).is_none());
        let three = best_correction(&f, &v, 3).unwrap().val_reduction();
        let five = best_correction_of_size(&f, &v, 5).unwrap();
        assert_eq!(five.columns.len(), 3);
        assert!(
            three > 0.99 && five.val_reduction() == three,
            "{three} {five:?}"
        );
        assert!(best_correction_of_size(&f, &v, 0).is_none());
    }

    /// A residual that is a small lag of the prediction (r = −τ ẏ) is found on the fit data
    /// and removed on a different validation signal; a residual unrelated to the dictionary
    /// (a tone at another frequency) gains nothing on validation.
    #[test]
    fn finds_a_lag_and_not_an_unrelated_tone() {
        let n = 2000;
        let sig = |f: f64, k: usize| (2.0 * std::f64::consts::PI * f * k as f64 / 100.0).sin();
        let y_fit: Vec<f64> = (0..n).map(|k| sig(1.3, k) + 0.3 * sig(7.1, k)).collect();
        let y_val: Vec<f64> = (0..n).map(|k| sig(0.9, k) + 0.5 * sig(5.3, k)).collect();
        let u_fit: Vec<f64> = (0..n).map(|k| 0.1 * sig(0.2, k)).collect();
        let u_val: Vec<f64> = (0..n).map(|k| 0.1 * sig(0.3, k)).collect();
        let lag = |y: &[f64]| -> Vec<f64> { diff(y).iter().map(|v| -0.2 * v).collect() };
        let (mut f, mut v) = (Normal::new(6), Normal::new(6));
        f.add(&lag(&y_fit), &dictionary(&[&y_fit, &u_fit], &[]));
        v.add(&lag(&y_val), &dictionary(&[&y_val, &u_val], &[]));
        let c = best_correction(&f, &v, 1).unwrap();
        assert_eq!(c.columns, vec![1]);
        assert!(c.val_reduction() > 0.999, "{c:?}");
        let tone = |k0: usize| -> Vec<f64> { (0..n).map(|k| 0.01 * sig(17.0, k + k0)).collect() };
        let (mut f, mut v) = (Normal::new(6), Normal::new(6));
        f.add(&tone(0), &dictionary(&[&y_fit, &u_fit], &[]));
        v.add(&tone(3), &dictionary(&[&y_val, &u_val], &[]));
        let c = best_correction(&f, &v, 2).unwrap();
        assert!(c.val_reduction() < 0.05, "{c:?}");
    }
}
