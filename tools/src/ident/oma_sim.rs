//! Synthetic output-only recordings with known modes, and the coverage of the output-only
//! path's ±2σ intervals over many of them (the proof that [`super::ssi`]'s uncertainty is
//! honest; `beamtool oma-coverage`).
//!
//! Each mode is a continuous single-degree-of-freedom oscillator q̈ + 2ζω q̇ + ω² q = w(t)
//! driven by its own continuous white noise w, sampled exactly: x_{k+1} = Φ x_k + v_k with
//! Φ = e^{AΔt} and v_k ~ N(0, Q), Q = ∫₀^Δt e^{Aτ} B Bᵀ e^{Aᵀτ} dτ by Van Loan's method
//! (C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE Trans.
//! Autom. Control 23 (1978) 395–404). The response is the sum of the modal displacements
//! (each scaled to its stated RMS) plus white Gaussian measurement noise, so the true poles
//! are exactly s = −ζω ± iω√(1−ζ²).

use super::ssi::{identify_output_only, SsiOptions};
use anyhow::Result;
use nalgebra::{DMatrix, Matrix2};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

/// One simulated mode.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SimMode {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// RMS of its displacement in the response (response units).
    pub rms: f64,
}

/// A synthetic output-only recording's design.
#[derive(Clone, Debug, Serialize)]
pub struct SimDesign {
    /// The modes.
    pub modes: Vec<SimMode>,
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// RMS of the white measurement noise (response units).
    pub noise_rms: f64,
}

impl Default for SimDesign {
    /// Two modes (1.75 Hz, ζ 0.02, RMS 1; 6.3 Hz, ζ 0.01, RMS 0.3), 100 Hz, 1 000 s,
    /// measurement noise RMS 0.1.
    fn default() -> Self {
        SimDesign {
            modes: vec![
                SimMode {
                    freq_hz: 1.75,
                    zeta: 0.02,
                    rms: 1.0,
                },
                SimMode {
                    freq_hz: 6.3,
                    zeta: 0.01,
                    rms: 0.3,
                },
            ],
            rate_hz: 100.0,
            duration_s: 1000.0,
            noise_rms: 0.1,
        }
    }
}

/// (Φ, chol(Q)) of one mode at step `dt` (module doc).
fn discrete_mode(freq_hz: f64, zeta: f64, dt: f64) -> (Matrix2<f64>, Matrix2<f64>) {
    let w = 2.0 * std::f64::consts::PI * freq_hz;
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * zeta * w]);
    let bbt = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, 0.0, 1.0]);
    let mut m = DMatrix::<f64>::zeros(4, 4);
    m.view_mut((0, 0), (2, 2)).copy_from(&(-&a * dt));
    m.view_mut((0, 2), (2, 2)).copy_from(&(&bbt * dt));
    m.view_mut((2, 2), (2, 2)).copy_from(&(a.transpose() * dt));
    let e = m.exp();
    let phi_t = e.view((2, 2), (2, 2)).into_owned();
    let phi = phi_t.transpose();
    let q = &phi * e.view((0, 2), (2, 2)).into_owned();
    let q = 0.5 * (&q + q.transpose());
    let l = nalgebra::Cholesky::new(q.clone())
        .map(|c| c.l())
        .unwrap_or_else(|| DMatrix::from_diagonal(&q.diagonal().map(|v| v.max(0.0).sqrt())));
    (
        Matrix2::from_iterator(phi.iter().copied()),
        Matrix2::from_iterator(l.iter().copied()),
    )
}

/// A synthetic output-only response of `d` (module doc), reproducible from `seed`.
pub fn simulate_output_only(d: &SimDesign, seed: u64) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let n = (d.duration_s * d.rate_hz).round() as usize;
    let dt = 1.0 / d.rate_hz;
    let mut y = vec![0.0; n];
    for m in &d.modes {
        let (phi, l) = discrete_mode(m.freq_hz, m.zeta, dt);
        // Start in the stationary distribution: run 10 time constants first.
        let burn =
            ((10.0 / (m.zeta * 2.0 * std::f64::consts::PI * m.freq_hz)) * d.rate_hz) as usize;
        let mut x = nalgebra::Vector2::zeros();
        let mut q = Vec::with_capacity(n);
        for k in 0..burn + n {
            let v = nalgebra::Vector2::new(
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
            );
            x = phi * x + l * v;
            if k >= burn {
                q.push(x[0]);
            }
        }
        let rms = (q.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        for (yk, qk) in y.iter_mut().zip(&q) {
            *yk += m.rms * qk / rms;
        }
    }
    for yk in y.iter_mut() {
        let e: f64 = StandardNormal.sample(&mut rng);
        *yk += d.noise_rms * e;
    }
    y
}

/// Coverage of one mode over the runs.
#[derive(Clone, Debug, Serialize)]
pub struct ModeCoverage {
    /// The true mode.
    pub truth: SimMode,
    /// Runs in which the mode was identified (within 10 % in frequency).
    pub found: usize,
    /// Runs whose f ± 2σ covers the true frequency.
    pub freq_covered: usize,
    /// Runs whose ζ ± 2σ covers the true damping ratio.
    pub zeta_covered: usize,
    /// Mean of (f̂ − f) / σ_f over the found runs.
    pub freq_mean_z: f64,
    /// Mean of (ζ̂ − ζ) / σ_ζ over the found runs.
    pub zeta_mean_z: f64,
    /// RMS of (f̂ − f) / σ_f (1 for an honest σ).
    pub freq_rms_z: f64,
    /// RMS of (ζ̂ − ζ) / σ_ζ.
    pub zeta_rms_z: f64,
}

/// The coverage of `runs` synthetic recordings of `d` (seeds `seed`, `seed` + 1, …).
#[derive(Clone, Debug, Serialize)]
pub struct Coverage {
    /// Runs made.
    pub runs: usize,
    /// Runs where identification failed (error).
    pub failed: usize,
    /// Runs that reported a mode matching no true mode (within 10 %).
    pub runs_with_spurious: usize,
    /// Per true mode.
    pub modes: Vec<ModeCoverage>,
}

/// Simulates `runs` recordings of `d` and identifies each with [`identify_output_only`]:
/// how often ±2σ covers the true frequency and damping ratio of each mode. `progress` is
/// called after each run with (runs done, runs).
pub fn output_only_coverage(
    d: &SimDesign,
    runs: usize,
    seed: u64,
    opts: &SsiOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Coverage> {
    let mut per: Vec<(usize, usize, usize, Vec<f64>, Vec<f64>)> =
        d.modes.iter().map(|_| (0, 0, 0, vec![], vec![])).collect();
    let (mut failed, mut spurious) = (0, 0);
    for r in 0..runs {
        let y = simulate_output_only(d, seed + r as u64);
        match identify_output_only(&y, d.rate_hz, opts) {
            Err(_) => failed += 1,
            Ok(res) => {
                if res.modes.iter().any(|m| {
                    d.modes
                        .iter()
                        .all(|t| (m.freq_hz / t.freq_hz - 1.0).abs() >= 0.1)
                }) {
                    spurious += 1;
                }
                for (t, acc) in d.modes.iter().zip(per.iter_mut()) {
                    let Some(m) = res
                        .modes
                        .iter()
                        .filter(|m| (m.freq_hz / t.freq_hz - 1.0).abs() < 0.1)
                        .min_by(|a, b| {
                            (a.freq_hz - t.freq_hz)
                                .abs()
                                .total_cmp(&(b.freq_hz - t.freq_hz).abs())
                        })
                    else {
                        continue;
                    };
                    let zf = (m.freq_hz - t.freq_hz) / m.freq_hz_std;
                    let zz = (m.zeta - t.zeta) / m.zeta_std;
                    acc.0 += 1;
                    acc.1 += usize::from(zf.abs() <= 2.0);
                    acc.2 += usize::from(zz.abs() <= 2.0);
                    acc.3.push(zf);
                    acc.4.push(zz);
                }
            }
        }
        progress(r + 1, runs);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    Ok(Coverage {
        runs,
        failed,
        runs_with_spurious: spurious,
        modes: d
            .modes
            .iter()
            .zip(per)
            .map(|(t, (found, fc, zc, zf, zz))| ModeCoverage {
                truth: *t,
                found,
                freq_covered: fc,
                zeta_covered: zc,
                freq_mean_z: mean(&zf),
                zeta_mean_z: mean(&zz),
                freq_rms_z: rms(&zf),
                zeta_rms_z: rms(&zz),
            })
            .collect(),
    })
}
