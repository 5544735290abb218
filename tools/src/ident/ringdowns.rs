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
//! −2ζω]], B = (2ζω, ω² − 4ζ²ω²), discretised with the base linear between samples (first-order hold) through samples
//! corrected by −Δ²b/12 (fourth-order accurate for a band-limited base, not second).
//!
//! Steps:
//! 1. **Steps**: crossings of the base's mid-level with hysteresis (a Schmitt trigger at 25 %
//!    and 75 % of its range); the recording is cut at each step's onset (the last sample
//!    before the crossing that is within 5 % of the range of the previous level) into segments.
//! 2. Base and tip decimated to ≥ 20 samples per period of the dominant tip frequency
//!    ([`RingdownOptions::samples_per_period`]).
//! 3. **Joint fit** (variable projection, Golub & Pereyra 1973): for given (ω, ζ), the tip
//!    deflection of every segment is c₁ z₁ + c₂ b (shared: the forced response) + a
//!    per-segment free decay e^{−ζωt}(p cos ω_d t + q sin ω_d t) + offset, solved by linear
//!    least squares; (f, ζ) minimise the residual (Levenberg–Marquardt on the projected
//!    residual). Quantisation of the sensors (steps q: variance q²/12) is white noise here.
//! 4. **1-σ** ([`super::ringdown_sigma`]): the larger of a jackknife over segments (leave one
//!    segment out, refit) and a parametric bootstrap of the measurement (the fitted model
//!    driven by the smoothed base, re-quantised at random grid offsets with the recording's
//!    own steps, decimated and refitted; its root mean square error about the estimate). The
//!    jackknife alone was far too small: quantisation errors are shared by every segment of a
//!    square wave (the same staircase after each step), so segment-to-segment scatter misses
//!    them (coverage measured by `beamtool ringdown-coverage`, [`super::ringdown_sim`]).

use super::ringdown_fit::{coarse_start, fit, project};
use super::ringdown_sigma::{bootstrap_sigma, jackknife_sigma, BootstrapSigma, FitData};
use super::ModeEstimate;
use crate::recording::{decimate_fir, fmt_sig};
use anyhow::{bail, Result};
use std::ops::Range;

/// Schmitt-trigger levels of a step (fractions of the base's range): a step crosses from
/// below 25 % to above 75 % (or back), so noise and a loop's overshoot are not steps.
pub const STEP_LOW: f64 = 0.25;
/// Upper level of a step, see [`STEP_LOW`].
pub const STEP_HIGH: f64 = 0.75;

/// Fewest steps for the pooled fit: a level change and its return, the least that tells a
/// base stepping between levels (a square-wave reference) from one move, which the ring-down
/// after the last move covers. The 1-σ does not rest on the number of segments: with two the
/// jackknife has two refits, and the bootstrap of the quantised measurement
/// ([`super::ringdown_sigma`]) does not depend on it (a real rotary flexible link logs two
/// steps in 10 s, docs/ident.md).
pub const MIN_STEPS: usize = 2;

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

/// Options of [`identify_ringdowns_with`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RingdownOptions {
    /// Samples per period of the tip's dominant frequency after decimation (at least; the
    /// factor is the largest integer that keeps it). Default 20: with the corrected hold of
    /// the base (`ringdown_fit::hold_input`) the unquantised link of
    /// `tools/tests/ident_closed_loop.rs` is then biased by ≤ 7·10⁻⁵ Hz and ≤ 1·10⁻⁵ in ζ.
    pub samples_per_period: f64,
    /// Replicas of the parametric bootstrap (0: none, jackknife σ only). Default
    /// [`super::ringdown_sigma::BOOTSTRAP_REPLICAS`].
    pub bootstrap_replicas: usize,
    /// Seed of the bootstrap's random grid offsets and blocks (the result is reproducible).
    pub seed: u64,
}

impl Default for RingdownOptions {
    fn default() -> Self {
        RingdownOptions {
            samples_per_period: 20.0,
            bootstrap_replicas: super::ringdown_sigma::BOOTSTRAP_REPLICAS,
            seed: 1,
        }
    }
}

/// Result of [`identify_ringdowns`].
#[derive(Clone, Debug)]
pub struct RingdownResult {
    /// The mode (f Hz, ζ; 1-σ the larger of the jackknife's and the bootstrap's, module doc).
    pub mode: ModeEstimate,
    /// Segments pooled.
    pub segments: usize,
    /// Sample rate after decimation (Hz).
    pub sample_rate_hz: f64,
    /// Fraction of the tip deflection's variance (about each segment's mean) the model explains.
    pub r2: f64,
    /// The jackknife σ over segments (Hz, ζ).
    pub jackknife: (f64, f64),
    /// The parametric bootstrap (all zero when not run).
    pub bootstrap: BootstrapSigma,
}

/// [`identify_ringdowns_with`] with the default [`RingdownOptions`].
pub fn identify_ringdowns(
    b: &[f64],
    y: &[f64],
    rate_hz: f64,
    f_min: f64,
    f_max: f64,
    zeta_max: f64,
) -> Result<RingdownResult> {
    identify_ringdowns_with(
        b,
        y,
        rate_hz,
        (f_min, f_max),
        zeta_max,
        &RingdownOptions::default(),
    )
}

/// The segments of decimated rows (decimation factor `q`, `n` decimated rows) between the
/// step onsets `onsets` (full-rate samples), each at least 8 rows.
fn segments(onsets: &[usize], q: usize, n: usize) -> Vec<Range<usize>> {
    let mut cuts: Vec<usize> = onsets.iter().map(|k| k / q).collect();
    cuts.push(n);
    cuts.windows(2)
        .map(|w| w[0]..w[1])
        .filter(|r| r.len() >= 8)
        .collect()
}

/// The dominant frequency (Hz) of the tip deflection `y` (rate `rate_hz`) inside `band`.
fn ring_peak(y: &[f64], rate_hz: f64, band: (f64, f64)) -> Result<f64> {
    let (f_min, f_max) = band;
    let (fr, mag) = super::spectrum::amplitude_spectrum(y, rate_hz);
    super::spectrum::peaks(&fr, &mag, f_min, f_max.min(0.45 * rate_hz))
        .first()
        .map(|p| p.0)
        .ok_or_else(|| {
            anyhow::anyhow!("no spectral peak of the tip deflection between {f_min} and {f_max} Hz")
        })
}

/// Fraction of the variance of `yd` about each segment's mean that a fit leaving the
/// residual sum of squares `ss` explains.
fn explained(yd: &[f64], segs: &[Range<usize>], ss: f64) -> f64 {
    let tot: f64 = segs
        .iter()
        .map(|s| {
            let m = yd[s.clone()].iter().sum::<f64>() / s.len() as f64;
            yd[s.clone()].iter().map(|v| (v - m).powi(2)).sum::<f64>()
        })
        .sum();
    1.0 - ss / tot.max(1e-300)
}

/// Identifies the structure's first mode from a step-excited recording: base `b` and tip
/// deflection `y` (m, same length), uniform at `rate_hz`, band `band` = (f_min, f_max) Hz,
/// damping below `zeta_max` (module doc).
///
/// Errors: fewer than [`MIN_STEPS`] steps, no tip resonance in the band, a fit that does
/// not converge to a plausible mode.
pub fn identify_ringdowns_with(
    b: &[f64],
    y: &[f64],
    rate_hz: f64,
    band: (f64, f64),
    zeta_max: f64,
    opts: &RingdownOptions,
) -> Result<RingdownResult> {
    let (f_min, f_max) = band;
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
    let f_peak = ring_peak(y, rate_hz, band)?;
    let q = ((rate_hz / (opts.samples_per_period * f_peak)).floor() as usize).max(1);
    let (bd, yd) = (decimate_fir(b, q), decimate_fir(y, q));
    let dt = q as f64 / rate_hz;
    let segs = segments(&onsets, q, bd.len());
    // coarse search over f (0.5–2 × the ring) and ζ, then LM
    let best = coarse_start(&bd, &yd, &segs, dt, f_peak, band);
    let (f, z, ss, lin) = fit(&bd, &yd, &segs, dt, best.1, best.2)
        .ok_or_else(|| anyhow::anyhow!("the pooled ring-down fit failed"))?;
    if !(f >= f_min && f <= f_max && z > 1e-4 && z < zeta_max) {
        bail!(
            "the pooled ring-down fit gave an implausible mode ({} Hz, ζ {})",
            fmt_sig(f, 4),
            fmt_sig(z, 3)
        );
    }
    let n = segs.len();
    let jackknife = jackknife_sigma(&bd, &yd, &segs, dt, f, z);
    let resid: Vec<f64> = project(&bd, &yd, &segs, dt, f, z)
        .map(|r| r.0.iter().copied().collect())
        .unwrap_or_default();
    let data = FitData {
        b,
        y,
        rate_hz,
        q,
        segs: &segs,
        resid: &resid,
    };
    let bootstrap = if opts.bootstrap_replicas > 0 {
        bootstrap_sigma(&data, f, z, &lin, opts.bootstrap_replicas, opts.seed)
    } else {
        BootstrapSigma::default()
    };
    let rmse = bootstrap.rmse();
    Ok(RingdownResult {
        mode: ModeEstimate {
            freq_hz: f,
            zeta: z,
            freq_hz_std: jackknife.0.max(rmse.0),
            zeta_std: jackknife.1.max(rmse.1),
            method: format!(
                "pooled ring-downs ({n} segments, base as input; σ: jackknife over segments, \
                 bootstrap of the quantised measurement)"
            ),
        },
        segments: n,
        sample_rate_hz: rate_hz / q as f64,
        r2: explained(&yd, &segs, ss),
        jackknife,
        bootstrap,
    })
}
