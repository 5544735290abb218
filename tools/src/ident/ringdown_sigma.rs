//! The 1-σ of [`super::ringdowns`]: a jackknife over segments and a parametric bootstrap of
//! the measurement (the fitted model re-measured through the recording's own quantisation,
//! decimated and refitted).
//!
//! Why both: the jackknife sees what differs between segments; the errors of a step-excited
//! recording are mostly shared by all segments (the same staircase of a quantised base and tip
//! after every step of a square wave), which only a model of the measurement can reproduce.
//! The bootstrap (Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 6 and 10:
//! parametric bootstrap, bootstrap estimate of bias) takes the fitted model driven by a smooth
//! base (the measured base low-passed at the fit's band) as the truth, measures it again with the recording's quantisation steps at a
//! random offset of the grid (base and tip), or, for a tip that is not quantised, adds the
//! residual resampled in moving blocks of one period of the mode (Künsch, Ann. Statist. 17
//! (1989) 1217–1241), and refits from the estimate. Its root mean square error about the
//! estimate (spread and bias together) is the bootstrap σ.

use super::ringdown_fit::{fit, model_tip, Linear};
use crate::recording::{decimate_fir, windowed_sinc};
use rand::{Rng, SeedableRng};
use std::ops::Range;

/// Replicas of the parametric bootstrap (the relative precision of its σ is about
/// 1/√(2·replicas), 7 % at 100).
pub const BOOTSTRAP_REPLICAS: usize = 100;

/// The jackknife σ of (f, ζ) over the segments `segs` of decimated (b, y) at interval `dt`
/// (each segment left out once, refitted from (f, ζ)); (0, 0) with fewer than 2 refits.
pub(crate) fn jackknife_sigma(
    bd: &[f64],
    yd: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f: f64,
    z: f64,
) -> (f64, f64) {
    let n = segs.len();
    let mut jf = Vec::with_capacity(n);
    let mut jz = Vec::with_capacity(n);
    for leave in 0..n {
        let sub: Vec<Range<usize>> = segs
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != leave)
            .map(|(_, s)| s.clone())
            .collect();
        if let Some((fj, zj, _, _)) = fit(bd, yd, &sub, dt, f, z) {
            jf.push(fj);
            jz.push(zj);
        }
    }
    if jf.len() < 2 {
        return (0.0, 0.0);
    }
    let jack = |v: &[f64]| {
        let k = v.len() as f64;
        let m = v.iter().sum::<f64>() / k;
        ((k - 1.0) / k * v.iter().map(|x| (x - m).powi(2)).sum::<f64>()).sqrt()
    };
    (jack(&jf), jack(&jz))
}

/// What the parametric bootstrap gave.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct BootstrapSigma {
    /// Replicas refitted.
    pub replicas: usize,
    /// Standard deviation of the replicas' f (Hz) and ζ.
    pub sd: (f64, f64),
    /// Mean of the replicas minus the estimate (Hz, ζ): the bootstrap estimate of bias.
    pub bias: (f64, f64),
    /// Quantisation steps found in the base and the tip deflection (m; 0: not quantised).
    pub steps_m: (f64, f64),
}

impl BootstrapSigma {
    /// Root mean square error about the estimate: √(sd² + bias²), (Hz, ζ).
    pub fn rmse(&self) -> (f64, f64) {
        (self.sd.0.hypot(self.bias.0), self.sd.1.hypot(self.bias.1))
    }
}

/// The data of one pooled fit, as the bootstrap needs it.
pub(crate) struct FitData<'a> {
    /// Base and tip deflection at the full rate (m).
    pub b: &'a [f64],
    /// See `b`.
    pub y: &'a [f64],
    /// Full sample rate (Hz) and the decimation factor.
    pub rate_hz: f64,
    /// See `rate_hz`.
    pub q: usize,
    /// Segments (decimated rows).
    pub segs: &'a [Range<usize>],
    /// Residual of the fit over the segments' rows (decimated, in order).
    pub resid: &'a [f64],
}

/// Quantises `x` to step `q` on a grid offset by `o` (m); `x` itself for q = 0.
fn requantise(x: &[f64], q: f64, o: f64) -> Vec<f64> {
    if q > 0.0 {
        x.iter().map(|v| ((v + o) / q).round() * q - o).collect()
    } else {
        x.to_vec()
    }
}

/// A smooth stand-in for the true base behind the quantised base `b` (full rate): the
/// zero-phase low-pass of [`decimate_fir`] for factor `qs` (cut-off 0.4 × rate/`qs`, 16 `qs` + 1
/// taps, edges held) evaluated at every sample. Requantising `b` itself would only shift it by
/// a constant (it is already on the grid).
fn smooth(b: &[f64], qs: usize) -> Vec<f64> {
    if qs <= 1 {
        return b.to_vec();
    }
    let half = 8 * qs;
    let h = windowed_sinc(half, 0.4 / qs as f64, |i| {
        0.54 - 0.46 * (2.0 * std::f64::consts::PI * i as f64 / (2 * half) as f64).cos()
    });
    let n = b.len();
    (0..n)
        .map(|c| {
            h.iter()
                .enumerate()
                .map(|(i, hv)| hv * b[(c + i).saturating_sub(half).min(n - 1)])
                .sum()
        })
        .collect()
}

/// Parametric bootstrap of the pooled fit `d` at (f, ζ) with linear parameters `lin`
/// (module doc): `replicas` re-measurements, reproducible from `seed`.
pub(crate) fn bootstrap_sigma(
    d: &FitData,
    f: f64,
    z: f64,
    lin: &Linear,
    replicas: usize,
    seed: u64,
) -> BootstrapSigma {
    // the quantisation steps as the reader finds them (0: not quantised)
    let step = |x: &[f64]| crate::recording::hold::quantum(x).unwrap_or(0.0);
    let (qb, qy) = (step(d.b), step(d.y));
    let dt = 1.0 / d.rate_hz;
    let n = d.b.len();
    let segs_full: Vec<Range<usize>> = d
        .segs
        .iter()
        .map(|s| (s.start * d.q).min(n)..(s.end * d.q).min(n))
        .collect();
    // the replicas' true base: smooth at the band of 20 samples per period of the mode
    let btrue = if qb > 0.0 {
        smooth(d.b, ((d.rate_hz / (20.0 * f)).floor() as usize).max(1))
    } else {
        d.b.to_vec()
    };
    let yhat = model_tip(&btrue, dt, &segs_full, f, z, lin);
    let dtd = dt * d.q as f64;
    // moving blocks of one period of the mode (at least 8 rows) for an unquantised tip
    let block = ((1.0 / (f * dtd)).round() as usize)
        .max(8)
        .min(d.resid.len().max(1));
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (mut fs, mut zs) = (Vec::with_capacity(replicas), Vec::with_capacity(replicas));
    for _ in 0..replicas {
        let bs = requantise(&btrue, qb, rng.gen::<f64>() * qb);
        let ys = requantise(&yhat, qy, rng.gen::<f64>() * qy);
        let (bd, mut yd) = (decimate_fir(&bs, d.q), decimate_fir(&ys, d.q));
        if qy == 0.0 && !d.resid.is_empty() {
            let rows = d.segs.iter().flat_map(|s| s.clone());
            let mut k = block; // position inside the current block
            let mut start = 0;
            for row in rows {
                if k == block {
                    start = rng.gen_range(0..=d.resid.len() - block);
                    k = 0;
                }
                yd[row] += d.resid[start + k];
                k += 1;
            }
        }
        if let Some((fr, zr, _, _)) = fit(&bd, &yd, d.segs, dtd, f, z) {
            fs.push(fr);
            zs.push(zr);
        }
    }
    let k = fs.len().max(1) as f64;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / k;
    let (mf, mz) = (mean(&fs), mean(&zs));
    BootstrapSigma {
        replicas: fs.len(),
        sd: (super::std_dev(&fs), super::std_dev(&zs)),
        bias: (mf - f, mz - z),
        steps_m: (qb, qy),
    }
}
