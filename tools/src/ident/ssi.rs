//! Output-only modal identification: covariance-driven stochastic subspace identification
//! (SSI-cov; Peeters & De Roeck, "Reference-based stochastic subspace identification for
//! output-only modal analysis", Mech. Syst. Signal Process. 13 (1999) 855–878), with the 1-σ
//! of every mode from the spread of independent block estimates ("batch means": Reynders,
//! Pintelon & De Roeck, "Uncertainty bounds on modal parameters obtained from stochastic
//! subspace identification", MSSP 22 (2008) 948–969, §1 and §5).
//!
//! Specification, for one response channel y (any unit: displacement, acceleration) sampled at
//! `rate_hz`, driven by unmeasured broadband (white-ish, stationary) forces:
//! 1. **Band**: the top of the band is the highest frequency where the Welch PSD of y is within
//!    30 dB of its maximum (capped at `f_max_hz`); y is decimated (anti-aliased FIR,
//!    [`crate::recording::decimate_fir`]) so that its Nyquist frequency is ≥ 2.5 × that top.
//! 2. **Correlations** R_k = 1/(N−k) Σ y_{t+k} y_t, k = 0..2i−1 (mean removed).
//! 3. **Block Toeplitz** T[r][c] = R_{i+r−c} (i × i, lags 1..2i−1: R_0 carries the
//!    measurement noise and is left out), SVD T = U S Vᵀ (nalgebra, singular values
//!    descending).
//! 4. For each model order n (2, 4, …, `max_order`): observability O = U_n S_n^{1/2},
//!    A = O↑⁺ O↓ (O without its last / first row), poles z = eig(A), s = ln z / Δt
//!    ([`super::poles::physical_poles`]: stable, upper half-plane, 0 < ζ < `zeta_max`, band).
//! 5. **Stabilisation** ([`super::stabilisation`]) over the orders: a mode is a cluster of
//!    frequency-stable poles at ≥ 30 % of the orders; ζ ≥ 10⁻⁴; of two modes within 5 % the
//!    one stable at fewer orders is a split peak.
//! 6. **Uncertainty by blocks**: the record is cut into n_b consecutive blocks (at most
//!    [`N_BLOCKS`], each ≥ [`MIN_BLOCK_CYCLES`] periods of the lowest mode); each block is
//!    identified alone (steps 2–5, same i and orders); a mode's block estimate is the block's
//!    stable cluster nearest to it (within [`BLOCK_MATCH_REL`] in frequency, and nearer to
//!    it than to any other mode). The mode's (f, ζ) is the whole record's estimate (the
//!    median of its stable poles) and the 1-σ the sample standard deviation of its block
//!    estimates / √(blocks found): the variance of an estimate from n_b times the data is
//!    1/n_b of a block's (Reynders et al. 2008, §1). The mean of the block estimates is not
//!    used as the estimate: a block's damping carries a short-record bias (+8 % at ζ = 0.02,
//!    measured, docs/ident.md). A mode found in fewer than half of the blocks is rejected (not
//!    a stationary mode of the response).

use super::poles::{physical_poles, Pole};
use super::stabilisation::{label, select, OrderPoles, StabCriteria, Stability, StableMode};
use super::{std_dev, ModeEstimate};
use crate::recording::{decimate_fir, fmt_sig};
use anyhow::{bail, Result};
use nalgebra::DMatrix;
use realfft::num_complex::Complex64;
use serde::Serialize;

/// Most blocks of the uncertainty: with 16 blocks the batch mean's t-statistic has 15 degrees
/// of freedom, so ±2σ covers 93.6 % of a normal block estimate's distribution (95 % needs
/// ±2.13σ); more blocks shorten each block (and its estimate's bias grows).
pub const N_BLOCKS: usize = 16;

/// Shortest block (periods of the lowest mode): a block must span many correlation times of
/// the response (1/(2πζf) s, i.e. 1/(2πζ) periods: 16 periods at ζ = 0.01) so that block
/// estimates are nearly independent and nearly normal.
pub const MIN_BLOCK_CYCLES: f64 = 100.0;

/// Fewest blocks for a block standard deviation (below this, no uncertainty is claimed and
/// the identification fails with a message asking for a longer record).
pub const MIN_BLOCKS: usize = 4;

/// A block's cluster is the same mode when its frequency is within this fraction of the
/// whole record's (a block's frequency scatter at ≥ 100 cycles and ζ ≤ 0.2 is a few per cent;
/// the beam's modes are ≥ 2.8 × apart).
pub const BLOCK_MATCH_REL: f64 = 0.1;

/// Most block rows (the Toeplitz SVD is i × i).
pub const MAX_BLOCK_ROWS: usize = 400;

/// Options of [`identify_output_only`].
#[derive(Clone, Debug, Serialize)]
pub struct SsiOptions {
    /// Lowest frequency considered (Hz).
    pub f_min_hz: f64,
    /// Highest frequency considered (Hz; also caps the band's top).
    pub f_max_hz: f64,
    /// Highest model order (even; 2 poles per mode).
    pub max_order: usize,
    /// Damping ratios at or above this are not physical modes.
    pub zeta_max: f64,
    /// Stabilisation criteria.
    pub criteria: StabCriteria,
}

impl Default for SsiOptions {
    /// 0.2–500 Hz, orders 2..40, ζ < 0.2, the default stabilisation criteria.
    fn default() -> Self {
        SsiOptions {
            f_min_hz: 0.2,
            f_max_hz: 500.0,
            max_order: 40,
            zeta_max: 0.2,
            criteria: StabCriteria::default(),
        }
    }
}

/// A mode the whole-record diagram proposed that is not kept, and why.
#[derive(Clone, Debug, Serialize)]
pub struct SsiRejected {
    /// Frequency (Hz) and damping ratio of the whole-record cluster.
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Why it is not kept.
    pub reason: String,
}

/// Result of [`identify_output_only`].
#[derive(Clone, Debug, Serialize)]
pub struct SsiResult {
    /// Modes (ascending): (f, ζ) of the whole record, 1-σ from the spread of the blocks'.
    pub modes: Vec<ModeEstimate>,
    /// Whole-record clusters not kept.
    pub rejected: Vec<SsiRejected>,
    /// The whole record's stable clusters (frequency, ζ, count).
    pub record_modes: Vec<StableMode>,
    /// Sample rate after decimation (Hz) and the decimation factor.
    pub sample_rate_hz: f64,
    /// Decimation factor applied to the input.
    pub decimation: usize,
    /// Top of the band (Hz) used for the decimation.
    pub band_top_hz: f64,
    /// Block rows i of the Toeplitz matrix.
    pub block_rows: usize,
    /// Number of blocks of the uncertainty.
    pub n_blocks: usize,
    /// Warnings.
    pub warnings: Vec<String>,
}

/// Output correlations R_k = 1/(N−k) Σ_t y_{t+k} y_t for k = 0..n_lags (y as given: remove
/// its mean first). Errors: fewer than 2 n_lags samples.
pub fn output_correlations(y: &[f64], n_lags: usize) -> Result<Vec<f64>> {
    let n = y.len();
    if n < 2 * n_lags {
        bail!("{n} samples are too few for {n_lags} correlation lags");
    }
    Ok((0..n_lags)
        .map(|k| {
            let s: f64 = y[k..].iter().zip(y).map(|(a, b)| a * b).sum();
            s / (n - k) as f64
        })
        .collect())
}

/// SSI-cov poles of one channel for every order in `orders` (ascending, even), from its
/// correlations `r` (length ≥ 2 `block_rows`) at sample interval `dt` (s): module doc steps
/// 3–4. Each order's poles are the physical ones in `f_lo..f_hi` Hz with 0 < ζ < `zeta_max`.
/// Orders above `block_rows − 1` are skipped.
pub fn ssi_cov_poles(
    r: &[f64],
    dt: f64,
    block_rows: usize,
    orders: &[usize],
    band_hz: (f64, f64),
    zeta_max: f64,
) -> Vec<(usize, Vec<Pole>)> {
    let i = block_rows;
    if r.len() < 2 * i {
        return vec![];
    }
    let t = DMatrix::from_fn(i, i, |row, col| r[i + row - col]);
    let svd = t.svd(true, false);
    let (Some(u), s) = (svd.u, svd.singular_values) else {
        return vec![];
    };
    // nalgebra's svd() returns the singular values in descending order.
    let mut out = Vec::new();
    for &n in orders {
        if n == 0 || n + 1 >= i {
            continue;
        }
        let mut o = u.columns(0, n).into_owned();
        for c in 0..n {
            let w = s[c].max(0.0).sqrt();
            o.column_mut(c).scale_mut(w);
        }
        let up = o.rows(0, i - 1).into_owned();
        let down = o.rows(1, i - 1).into_owned();
        let Ok(pinv) = up.pseudo_inverse(1e-12 * s[0].max(1e-300)) else {
            continue;
        };
        let a = pinv * down;
        let roots: Vec<Complex64> = a
            .complex_eigenvalues()
            .iter()
            .map(|z| Complex64::new(z.re, z.im))
            .collect();
        out.push((
            n,
            physical_poles(&roots, dt, band_hz.0, band_hz.1, zeta_max),
        ));
    }
    out
}

/// The stable clusters of one stretch `y` (mean removed here): correlations, poles over
/// `orders`, stabilisation, ζ ≥ 10⁻⁴.
fn stretch_modes(
    y: &[f64],
    dt: f64,
    block_rows: usize,
    orders: &[usize],
    band_hz: (f64, f64),
    opts: &SsiOptions,
) -> Result<Vec<StableMode>> {
    let m = y.iter().sum::<f64>() / y.len() as f64;
    let yc: Vec<f64> = y.iter().map(|v| v - m).collect();
    let r = output_correlations(&yc, 2 * block_rows)?;
    let raw = ssi_cov_poles(&r, dt, block_rows, orders, band_hz, opts.zeta_max);
    if raw.is_empty() {
        bail!("no model order could be estimated");
    }
    // Only poles stable in frequency *and* damping count: a single channel's extra poles
    // (noise modelled near a strong peak at high orders) wander in damping.
    let labelled: Vec<OrderPoles> = label(raw, &opts.criteria)
        .into_iter()
        .map(|mut o| {
            for p in o.poles.iter_mut() {
                if p.1 != Stability::Stable {
                    p.1 = Stability::New;
                }
            }
            o
        })
        .collect();
    Ok(select(&labelled, &opts.criteria)
        .into_iter()
        .filter(|c| c.zeta >= 1e-4)
        .collect())
}

/// (Top of the response's band, its dominant frequency) (Hz): the highest frequency in
/// `f_min..f_max` where its Welch PSD (Hann segments of 2¹² samples or the record, 50 %
/// overlap) is within 30 dB of its maximum, and where that maximum is.
fn band_top_hz(y: &[f64], rate_hz: f64, f_min: f64, f_max: f64) -> Result<(f64, f64)> {
    let wo = super::frf::WelchOptions {
        nperseg: Some(y.len().min(1 << 12)),
        overlap: 0.5,
        window: super::frf::Window::Hann,
        detrend: super::frf::Detrend::Mean,
        pad: 1,
    };
    let f = super::frf::welch(y, y, rate_hz, &wo)?;
    let inband: Vec<usize> = (0..f.freq_hz.len())
        .filter(|&k| f.freq_hz[k] >= f_min && f.freq_hz[k] <= f_max)
        .collect();
    let kmax = inband
        .iter()
        .copied()
        .max_by(|&a, &b| f.sxx[a].total_cmp(&f.sxx[b]))
        .unwrap_or(0);
    let top = f.sxx[kmax];
    if !(top > 0.0) {
        bail!("the response has no energy between {f_min} and {f_max} Hz");
    }
    let k = inband
        .iter()
        .rev()
        .find(|&&k| f.sxx[k] >= 1e-3 * top)
        .copied()
        .unwrap_or(inband[0]);
    Ok((f.freq_hz[k].max(f.df_hz()), f.freq_hz[kmax].max(f.df_hz())))
}

/// Identifies the modes of an output-only response `y` (one channel, any unit) sampled
/// uniformly at `rate_hz` Hz: SSI-cov with block uncertainty (module doc). Frequencies in Hz,
/// damping ratios, both with 1-σ.
///
/// Errors: non-finite samples, fewer than 64 samples, no energy in the band, no stable mode,
/// a record too short for [`MIN_BLOCKS`] blocks of [`MIN_BLOCK_CYCLES`] periods.
pub fn identify_output_only(y: &[f64], rate_hz: f64, opts: &SsiOptions) -> Result<SsiResult> {
    check_response(y, rate_hz)?;
    let mut warnings = Vec::new();
    let f_max = opts.f_max_hz.min(0.45 * rate_hz);
    let (top, f_peak) = band_top_hz(y, rate_hz, opts.f_min_hz, f_max)?;
    // Nyquist ≥ 2.5 × top: the decimating FIR is flat to ~0.3 of the new rate.
    let q = ((rate_hz / (5.0 * top)).floor() as usize).max(1);
    let yd = decimate_fir(y, q);
    let rate = rate_hz / q as f64;
    let dt = 1.0 / rate;
    let band = (opts.f_min_hz, f_max.min(0.45 * rate));
    let orders: Vec<usize> = (1..=opts.max_order / 2).map(|k| 2 * k).collect();
    // Block rows: above the highest order, and spanning one period of the dominant mode
    // (Peeters & De Roeck 1999; longer lags add the correlation estimate's noise: measured
    // in docs/ident.md, "Output-only identification").
    let i = ((rate / f_peak).ceil() as usize)
        .clamp(opts.max_order + 2, MAX_BLOCK_ROWS.max(opts.max_order + 2));
    if yd.len() < 8 * i {
        bail!(
            "{} samples at {} Hz are too few for output-only identification ({} block rows need ≥ {})",
            yd.len(),
            fmt_sig(rate, 4),
            i,
            8 * i
        );
    }
    let record = stretch_modes(&yd, dt, i, &orders, band, opts)?;
    if record.is_empty() {
        bail!(
            "no mode is stable over the model orders 2..{} between {} and {} Hz",
            opts.max_order,
            fmt_sig(band.0, 3),
            fmt_sig(band.1, 3)
        );
    }
    let (candidates, mut rejected) = split_peaks(&record);
    // Blocks are sized on the best-supported mode (a weak spurious cluster at a low
    // frequency must not shorten the record's blocks; it is screened by the blocks).
    let f_low = candidates
        .iter()
        .max_by_key(|c| c.count)
        .map_or(f64::NAN, |c| c.freq_hz);
    let span_cycles = yd.len() as f64 * dt * f_low;
    let n_blocks = N_BLOCKS.min((span_cycles / MIN_BLOCK_CYCLES).floor() as usize);
    if n_blocks < MIN_BLOCKS {
        bail!(
            "the record spans {} periods of its lowest mode ({} Hz); the block uncertainty needs {} blocks of {} periods ({} s)",
            fmt_sig(span_cycles, 3),
            fmt_sig(f_low, 4),
            MIN_BLOCKS,
            MIN_BLOCK_CYCLES,
            fmt_sig(MIN_BLOCKS as f64 * MIN_BLOCK_CYCLES / f_low, 3)
        );
    }
    let len = yd.len() / n_blocks;
    let blocks: Vec<Vec<StableMode>> = (0..n_blocks)
        .map(|b| {
            stretch_modes(&yd[b * len..(b + 1) * len], dt, i, &orders, band, opts)
                .unwrap_or_default()
        })
        .collect();
    let modes = modes_from_blocks(&candidates, &blocks, n_blocks, &mut rejected);
    warnings.extend(few_blocks_warning(n_blocks, len as f64 * dt));
    Ok(SsiResult {
        modes,
        rejected,
        record_modes: record,
        sample_rate_hz: rate,
        decimation: q,
        band_top_hz: top,
        block_rows: i,
        n_blocks,
        warnings,
    })
}

/// The warning when the record gives fewer than [`N_BLOCKS`] blocks (of `block_s` seconds):
/// the ±2σ coverage that Student's t gives with that many degrees of freedom.
fn few_blocks_warning(n_blocks: usize, block_s: f64) -> Option<String> {
    (n_blocks < N_BLOCKS).then(|| {
        format!(
            "{n_blocks} blocks of {} s for the uncertainty (a longer record gives {N_BLOCKS}); ±2σ covers ~{}% with {} degrees of freedom",
            fmt_sig(block_s, 3),
            fmt_sig(100.0 * t_coverage_2sigma(n_blocks - 1), 2),
            n_blocks - 1
        )
    })
}

/// Refuses a response shorter than 64 samples, with a non-finite sample, or a non-positive
/// or non-finite sample rate (the message names which).
fn check_response(y: &[f64], rate_hz: f64) -> Result<()> {
    if y.len() < 64 {
        bail!(
            "output-only identification needs at least 64 samples (got {})",
            y.len()
        );
    }
    if let Some(k) = y.iter().position(|v| !v.is_finite()) {
        bail!("the response is not finite at sample {k}");
    }
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        bail!("sample rate {rate_hz} Hz: want a finite positive rate");
    }
    Ok(())
}

/// Each candidate of the whole record with the spread of its block estimates: its 1 σ is
/// the standard deviation of the k block estimates / √k (batch means); a candidate found in
/// fewer than half the `n_blocks` blocks (or fewer than 2) goes to `rejected`.
fn modes_from_blocks(
    candidates: &[StableMode],
    blocks: &[Vec<StableMode>],
    n_blocks: usize,
    rejected: &mut Vec<SsiRejected>,
) -> Vec<ModeEstimate> {
    let mut modes = Vec::new();
    // Each block cluster belongs to its nearest candidate (relative frequency).
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let nearest = |f: f64| {
        (0..candidates.len()).min_by(|&a, &b| {
            rel(f, candidates[a].freq_hz).total_cmp(&rel(f, candidates[b].freq_hz))
        })
    };
    for (ci, c) in candidates.iter().enumerate() {
        let est: Vec<(f64, f64)> = blocks
            .iter()
            .filter_map(|bm| {
                bm.iter()
                    .filter(|m| {
                        rel(m.freq_hz, c.freq_hz) < BLOCK_MATCH_REL
                            && nearest(m.freq_hz) == Some(ci)
                    })
                    .min_by(|a, b| rel(a.freq_hz, c.freq_hz).total_cmp(&rel(b.freq_hz, c.freq_hz)))
                    .map(|m| (m.freq_hz, m.zeta))
            })
            .collect();
        if 2 * est.len() < n_blocks || est.len() < 2 {
            rejected.push(SsiRejected {
                freq_hz: c.freq_hz,
                zeta: c.zeta,
                reason: format!(
                    "found in only {} of {n_blocks} blocks: not a stationary mode of the response",
                    est.len()
                ),
            });
            continue;
        }
        let f: Vec<f64> = est.iter().map(|e| e.0).collect();
        let z: Vec<f64> = est.iter().map(|e| e.1).collect();
        let k = est.len() as f64;
        modes.push(ModeEstimate {
            freq_hz: c.freq_hz,
            zeta: c.zeta,
            freq_hz_std: std_dev(&f) / k.sqrt(),
            zeta_std: std_dev(&z) / k.sqrt(),
            method: format!("output-only SSI-cov ({} of {n_blocks} blocks)", est.len()),
        });
    }
    modes
}

/// Shortest output-only record (periods of its dominant frequency): [`MIN_BLOCKS`] blocks of
/// [`MIN_BLOCK_CYCLES`] periods.
pub const MIN_RECORD_CYCLES: f64 = MIN_BLOCKS as f64 * MIN_BLOCK_CYCLES;

/// A free decay loses more than half its amplitude over the record; an output-only response
/// does not (a free decay spanning [`MIN_RECORD_CYCLES`] periods that keeps half its amplitude
/// has ζ < ln 2 / (2π × 300) ≈ 4 × 10⁻⁴, below any beam or link measured here).
pub const DECAY_AMPLITUDE_RATIO: f64 = 0.5;

/// Whether `y` (uniform at `rate_hz`) is a stationary response for the output-only path and
/// not a free decay: it spans ≥ [`MIN_RECORD_CYCLES`] periods of its dominant frequency (in
/// `f_min..f_max` Hz) and the RMS of its last quarter is within a factor
/// [`DECAY_AMPLITUDE_RATIO`] of its first quarter's (both ways). Returns the reason either way
/// (`Ok(reason)`: stationary; `Err(reason)`: not).
pub fn stationary_response(
    y: &[f64],
    rate_hz: f64,
    f_min: f64,
    f_max: f64,
) -> std::result::Result<String, String> {
    let n = y.len();
    if n < 64 {
        return Err(format!("{n} samples"));
    }
    let (_, f_peak) =
        band_top_hz(y, rate_hz, f_min, f_max.min(0.45 * rate_hz)).map_err(|e| e.to_string())?;
    let cycles = n as f64 / rate_hz * f_peak;
    let m = y.iter().sum::<f64>() / n as f64;
    let rms =
        |s: &[f64]| (s.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / s.len() as f64).sqrt();
    let (first, last) = (rms(&y[..n / 4]), rms(&y[n - n / 4..]));
    let ratio = last / first.max(1e-300);
    let what = format!(
        "{} periods of its dominant {} Hz, RMS of the last quarter {} × the first's",
        fmt_sig(cycles, 3),
        fmt_sig(f_peak, 4),
        fmt_sig(ratio, 3)
    );
    if cycles >= MIN_RECORD_CYCLES
        && ratio >= DECAY_AMPLITUDE_RATIO
        && ratio <= 1.0 / DECAY_AMPLITUDE_RATIO
    {
        Ok(format!("a stationary response ({what})"))
    } else {
        Err(format!(
            "not a long stationary response ({what}; output-only needs ≥ {MIN_RECORD_CYCLES} periods and a ratio within ×{DECAY_AMPLITUDE_RATIO}..×{})",
            1.0 / DECAY_AMPLITUDE_RATIO
        ))
    }
}

/// Of two clusters within 5 % (a planar beam's modes are ≥ 2.8 × apart) the one stable at
/// fewer orders is a split peak: (kept, rejected).
fn split_peaks(record: &[StableMode]) -> (Vec<StableMode>, Vec<SsiRejected>) {
    let mut kept = Vec::new();
    let mut rejected = Vec::new();
    for (i, m) in record.iter().enumerate() {
        let better = record.iter().enumerate().find(|(j, o)| {
            *j != i
                && (o.freq_hz / m.freq_hz - 1.0).abs() < 0.05
                && (o.count > m.count || (o.count == m.count && *j < i))
        });
        match better {
            Some((_, o)) => rejected.push(SsiRejected {
                freq_hz: m.freq_hz,
                zeta: m.zeta,
                reason: format!(
                    "within 5 % of the better-supported {} Hz cluster ({} stable poles against {}): a split peak",
                    fmt_sig(o.freq_hz, 5),
                    o.count,
                    m.count
                ),
            }),
            None => kept.push(m.clone()),
        }
    }
    (kept, rejected)
}

/// P(|T| ≤ 2) for Student's t with `dof` degrees of freedom (the coverage of ±2σ of a batch
/// mean of dof + 1 blocks).
pub fn t_coverage_2sigma(dof: usize) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    match StudentsT::new(0.0, 1.0, dof.max(1) as f64) {
        Ok(t) => 2.0 * t.cdf(2.0) - 1.0,
        Err(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_noise_free_mode_gives_its_pole() {
        // AR(2) with poles at exp(s dt): the correlation is a damped cosine with the same pole.
        let (f, z, rate) = (2.0, 0.03, 50.0);
        let dt = 1.0 / rate;
        let wn = 2.0 * std::f64::consts::PI * f;
        let s = Complex64::new(-z * wn, wn * (1.0 - z * z).sqrt());
        let p = (s * dt).exp();
        let r: Vec<f64> = (0..200).map(|k| (p.powi(k)).re).collect();
        let poles = ssi_cov_poles(&r, dt, 60, &[2], (0.1, 20.0), 0.2);
        assert_eq!(poles.len(), 1);
        let q = poles[0].1[0];
        assert!(
            (q.freq_hz - f).abs() < 1e-6 && (q.zeta - z).abs() < 1e-6,
            "{q:?}"
        );
    }
}
