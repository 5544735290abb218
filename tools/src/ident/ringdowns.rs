//! Pooled ring-downs of a step-excited recording (closed loop or open loop): a base that
//! steps between levels (a square-wave reference under feedback, moves with rests) and a
//! tip that rings after each step. The structure's mode, not the loop's poles.
//!
//! Model (the base-excited beam of paper §2, first mode, tip deflection y, base position b):
//! ÿ + 2ζω ẏ + ω² y = −Γ b̈. The measured base is the input, so the feedback loop that moves
//! it does not enter: what is fitted is the transfer from the base to the tip, whose pole is
//! the structure's mode (under a stiff loop the tip rings near it, under a soft one at the
//! coupled frequency; either way the base's measured motion carries the difference).
//! With ψ = y + b the model is ψ̈ + 2ζωψ̇ + ω²ψ = 2ζωḃ + ω²b, simulated without differentiating
//! the (quantised) base by the state z = (ψ, ψ̇ − 2ζωb), ż = A z + B b, A = [[0, 1], [−ω²,
//! −2ζω]], B = (2ζω, ω² − 4ζ²ω²), discretised with the base linear between samples (first-order hold).
//!
//! Steps:
//! 1. **Steps**: crossings of the base's mid-level with hysteresis (a Schmitt trigger at 25 %
//!    and 75 % of its range); the recording is cut at each step's onset (the last sample
//!    before the crossing that is within 5 % of the range of the previous level) into segments.
//! 2. Base and tip decimated to ≥ 20 samples per period of the dominant tip frequency.
//! 3. **Joint fit** (variable projection, Golub & Pereyra 1973): for given (ω, ζ), the tip
//!    deflection of every segment is c₁ z₁ + c₂ b (shared: the forced response) + a
//!    per-segment free decay e^{−ζωt}(p cos ω_d t + q sin ω_d t) + offset, solved by linear
//!    least squares; (f, ζ) minimise the residual (Levenberg–Marquardt on the projected
//!    residual). Quantisation of the sensors (steps q: variance q²/12) is white noise here.
//! 4. **1-σ**: jackknife over segments (leave one segment out, refit): a segment's errors are
//!    correlated (model error, quantisation staircases), segments are nearly independent.

use super::ModeEstimate;
use crate::numeric::lm::{minimize, LmOptions};
use crate::recording::{decimate_fir, fmt_sig};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use std::f64::consts::PI;
use std::ops::Range;

/// Schmitt-trigger levels of a step (fractions of the base's range): a step crosses from
/// below 25 % to above 75 % (or back), so noise and a loop's overshoot are not steps.
pub const STEP_LOW: f64 = 0.25;
/// Upper level of a step, see [`STEP_LOW`].
pub const STEP_HIGH: f64 = 0.75;

/// Fewest steps for the pooled fit (and for a jackknife over segments).
pub const MIN_STEPS: usize = 4;

/// Most of the record a step-excited base spends in transit: between 25 % and 75 % of the
/// range of its 10th..90th percentiles for at most 20 % of the time (a sine spends 33 % there,
/// a sweep likewise; steps only their rise times, whatever the loop's overshoot and ring).
pub const TRANSIT_FRACTION: f64 = 0.2;

/// Step onsets of base `b`: sample indices where the base leaves its level toward a crossing
/// of the Schmitt trigger (module doc, step 1).
pub fn step_onsets(b: &[f64]) -> Vec<usize> {
    let (lo, hi) = b
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let r = hi - lo;
    if !(r > 0.0) {
        return vec![];
    }
    let (l1, l2) = (lo + STEP_LOW * r, lo + STEP_HIGH * r);
    let mut state: Option<bool> = None; // Some(true): high
    let mut out = Vec::new();
    for (k, &v) in b.iter().enumerate() {
        let now = if v > l2 {
            Some(true)
        } else if v < l1 {
            Some(false)
        } else {
            None
        };
        if let (Some(s), Some(n)) = (state, now) {
            if s != n {
                // walk back to where the base left its previous level (within 5 % of range)
                let level = if s { hi } else { lo };
                let mut j = k;
                while j > 0 && (b[j] - level).abs() > 0.05 * r {
                    j -= 1;
                }
                out.push(j);
            }
        }
        if now.is_some() {
            state = now;
        }
    }
    out
}

/// `Some(reason)` when base `b` is step-excited: ≥ [`MIN_STEPS`] steps and in transit between
/// its levels for ≤ [`TRANSIT_FRACTION`] of the samples.
pub fn step_excited(b: &[f64]) -> Option<String> {
    let steps = step_onsets(b);
    let mut sorted = b.to_vec();
    sorted.sort_by(f64::total_cmp);
    let (lo, hi) = (sorted[b.len() / 10], sorted[b.len() * 9 / 10]);
    let r = hi - lo;
    let transit = b
        .iter()
        .filter(|v| **v > lo + 0.25 * r && **v < lo + 0.75 * r)
        .count() as f64
        / b.len().max(1) as f64;
    (steps.len() >= MIN_STEPS && transit <= TRANSIT_FRACTION).then(|| {
        format!(
            "the base steps between levels ({} steps, {} % of the time in transit)",
            steps.len(),
            fmt_sig(100.0 * transit, 3)
        )
    })
}

/// Result of [`identify_ringdowns`].
#[derive(Clone, Debug)]
pub struct RingdownResult {
    /// The mode (f Hz, ζ, 1-σ from the jackknife over segments).
    pub mode: ModeEstimate,
    /// Segments pooled.
    pub segments: usize,
    /// Sample rate after decimation (Hz).
    pub sample_rate_hz: f64,
    /// Fraction of the tip deflection's variance (about each segment's mean) the model explains.
    pub r2: f64,
}

/// The forced response z₁ of the model to base `b` (sample interval `dt`), zero initial state.
fn forced(b: &[f64], dt: f64, w: f64, z: f64) -> Vec<f64> {
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * z * w]);
    let bb = DMatrix::from_column_slice(2, 1, &[2.0 * z * w, w * w - 4.0 * z * z * w * w]);
    // First-order hold (the base linear between samples, ramp-invariant):
    // exp([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]) gives Φ, Γ₁ (value) and Γ₂ (ramp).
    let mut m = DMatrix::<f64>::zeros(4, 4);
    m.view_mut((0, 0), (2, 2)).copy_from(&(a * dt));
    m.view_mut((0, 2), (2, 1)).copy_from(&(bb * dt));
    m[(2, 3)] = 1.0;
    let e = m.exp();
    let (p00, p01, p10, p11) = (e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]);
    let (g0, g1, h0, h1) = (e[(0, 2)], e[(1, 2)], e[(0, 3)], e[(1, 3)]);
    let (mut x0, mut x1) = (b[0], 0.0); // start at rest at the first base position
    (0..b.len())
        .map(|k| {
            let y = x0;
            let u = b[k];
            let du = b.get(k + 1).map_or(0.0, |v| v - u);
            let n0 = p00 * x0 + p01 * x1 + g0 * u + h0 * du;
            let n1 = p10 * x0 + p11 * x1 + g1 * u + h1 * du;
            x0 = n0;
            x1 = n1;
            y
        })
        .collect()
}

/// Projected residual of the joint fit at (f, ζ) over the segments `segs` of (b, y).
fn projected(
    b: &[f64],
    y: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f: f64,
    z: f64,
) -> Option<(DVector<f64>, f64)> {
    if !(f > 0.0 && z > 0.0 && z < 0.9) {
        return None;
    }
    let w = 2.0 * PI * f;
    let wd = w * (1.0 - z * z).sqrt();
    let zf = forced(b, dt, w, z);
    let m: usize = segs.iter().map(|s| s.len()).sum();
    let p = 2 + 3 * segs.len();
    let mut phi = DMatrix::<f64>::zeros(m, p);
    let mut rhs = DVector::<f64>::zeros(m);
    let mut row = 0;
    for (si, s) in segs.iter().enumerate() {
        for k in s.clone() {
            let t = (k - s.start) as f64 * dt;
            let e = (-z * w * t).exp();
            phi[(row, 0)] = zf[k];
            phi[(row, 1)] = b[k];
            phi[(row, 2 + 3 * si)] = e * (wd * t).cos();
            phi[(row, 3 + 3 * si)] = e * (wd * t).sin();
            phi[(row, 4 + 3 * si)] = 1.0;
            rhs[row] = y[k];
            row += 1;
        }
    }
    // column scaling for conditioning
    let scale: Vec<f64> = (0..p).map(|c| phi.column(c).norm().max(1e-300)).collect();
    for c in 0..p {
        phi.column_mut(c).scale_mut(1.0 / scale[c]);
    }
    let svd = phi.clone().svd(true, true);
    let coef = svd.solve(&rhs, 1e-12).ok()?;
    let r = &rhs - &phi * coef;
    let ss = r.norm_squared();
    Some((r, ss))
}

/// LM fit of (f, ζ) over `segs` from (f0, ζ0): (f, ζ, residual sum of squares).
fn fit(
    b: &[f64],
    y: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f0: f64,
    z0: f64,
) -> Option<(f64, f64, f64)> {
    let m: usize = segs.iter().map(|s| s.len()).sum();
    // parameters: ln f, ln ζ
    let res = |x: &DVector<f64>| {
        projected(b, y, segs, dt, x[0].exp(), x[1].exp())
            .map(|r| r.0)
            .or_else(|| Some(DVector::from_element(m, 1e10)))
    };
    let mut o = LmOptions::new(vec![1e-5, 1e-4]);
    o.max_evaluations = 400;
    let fitr = minimize(&res, DVector::from_vec(vec![f0.ln(), z0.ln()]), &o);
    let (f, z) = (fitr.x[0].exp(), fitr.x[1].exp());
    let ss = projected(b, y, segs, dt, f, z)?.1;
    Some((f, z, ss))
}

/// Identifies the structure's first mode from a step-excited recording: base `b` and tip
/// deflection `y` (m, same length), uniform at `rate_hz`, band `f_min..f_max` Hz, damping
/// below `zeta_max` (module doc).
///
/// Errors: fewer than [`MIN_STEPS`] steps, no tip resonance in the band, a fit that does
/// not converge to a plausible mode.
pub fn identify_ringdowns(
    b: &[f64],
    y: &[f64],
    rate_hz: f64,
    f_min: f64,
    f_max: f64,
    zeta_max: f64,
) -> Result<RingdownResult> {
    if b.len() != y.len() || b.len() < 64 {
        bail!(
            "base and tip must have the same length ≥ 64 (got {} and {})",
            b.len(),
            y.len()
        );
    }
    let onsets = step_onsets(b);
    if onsets.len() < MIN_STEPS {
        bail!(
            "{} base steps; the pooled ring-down fit needs {MIN_STEPS}",
            onsets.len()
        );
    }
    // dominant tip frequency (ring) in the band
    let (fr, mag) = super::spectrum::amplitude_spectrum(y, rate_hz);
    let f_peak = super::spectrum::peaks(&fr, &mag, f_min, f_max.min(0.45 * rate_hz))
        .first()
        .map(|p| p.0)
        .ok_or_else(|| {
            anyhow::anyhow!("no spectral peak of the tip deflection between {f_min} and {f_max} Hz")
        })?;
    let q = ((rate_hz / (20.0 * f_peak)).floor() as usize).max(1);
    let (bd, yd) = (decimate_fir(b, q), decimate_fir(y, q));
    let rate = rate_hz / q as f64;
    let dt = 1.0 / rate;
    let mut cuts: Vec<usize> = onsets.iter().map(|k| k / q).collect();
    cuts.push(bd.len());
    let segs: Vec<Range<usize>> = cuts
        .windows(2)
        .map(|w| w[0]..w[1])
        .filter(|r| r.len() >= 8)
        .collect();
    // coarse search over f (0.5–2 × the ring) and ζ, then LM
    let best = coarse_start(&bd, &yd, &segs, dt, f_peak, (f_min, f_max));
    let (f, z, ss) = fit(&bd, &yd, &segs, dt, best.1, best.2)
        .ok_or_else(|| anyhow::anyhow!("the pooled ring-down fit failed"))?;
    if !(f >= f_min && f <= f_max && z > 1e-4 && z < zeta_max) {
        bail!(
            "the pooled ring-down fit gave an implausible mode ({} Hz, ζ {})",
            fmt_sig(f, 4),
            fmt_sig(z, 3)
        );
    }
    let n = segs.len();
    let (freq_hz_std, zeta_std) = jackknife_sigma(&bd, &yd, &segs, dt, f, z);
    let tot: f64 = segs
        .iter()
        .map(|s| {
            let m = yd[s.clone()].iter().sum::<f64>() / s.len() as f64;
            yd[s.clone()].iter().map(|v| (v - m).powi(2)).sum::<f64>()
        })
        .sum();
    Ok(RingdownResult {
        mode: ModeEstimate {
            freq_hz: f,
            zeta: z,
            freq_hz_std,
            zeta_std,
            method: format!("pooled ring-downs ({n} segments, base as input; jackknife σ)"),
        },
        segments: n,
        sample_rate_hz: rate,
        r2: 1.0 - ss / tot.max(1e-300),
    })
}

/// The coarse start of the pooled fit: the (residual, f, ζ) of the grid over f in
/// 0.5–2 × `f_peak` (41 log steps, inside `band`) and ζ in {0.005 … 0.1} that leaves the
/// least residual.
fn coarse_start(
    bd: &[f64],
    yd: &[f64],
    segs: &[Range<usize>],
    dt: f64,
    f_peak: f64,
    band: (f64, f64),
) -> (f64, f64, f64) {
    let (f_min, f_max) = band;
    let mut best = (f64::INFINITY, f_peak, 0.02);
    for i in 0..41 {
        let f = f_peak * 2f64.powf(-1.0 + i as f64 / 20.0);
        if f < f_min || f > f_max {
            continue;
        }
        for z in [0.005, 0.01, 0.02, 0.05, 0.1] {
            if let Some((_, ss)) = projected(bd, yd, segs, dt, f, z) {
                if ss < best.0 {
                    best = (ss, f, z);
                }
            }
        }
    }
    best
}

/// The jackknife σ of (f, ζ) over the segments (each left out once, refitted from (f, ζ)).
fn jackknife_sigma(
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
        if let Some((fj, zj, _)) = fit(bd, yd, &sub, dt, f, z) {
            jf.push(fj);
            jz.push(zj);
        }
    }
    let jack = |v: &[f64]| {
        let k = v.len() as f64;
        let m = v.iter().sum::<f64>() / k;
        ((k - 1.0) / k * v.iter().map(|x| (x - m).powi(2)).sum::<f64>()).sqrt()
    };
    (jack(&jf), jack(&jz))
}
