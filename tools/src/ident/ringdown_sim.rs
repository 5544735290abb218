//! Synthetic closed-loop, step-excited recordings with a known arm mode, and the coverage of
//! the pooled ring-down path's ±2σ over many of them (`beamtool ringdown-coverage`; the
//! closed-loop counterpart of [`super::oma_sim`]).
//!
//! The plant is the rotary flexible link of `tools/tests/ident_closed_loop.rs`: a hub θ
//! (inertia J_h) driven by a PD loop u = Kp(θ_ref − θ) − Kd θ̇ with a square-wave reference,
//! and an arm ψ (inertia J_a) on a torsion spring k and damper c to the hub, so that with the
//! hub held the arm's mode is f, ζ (k = J_a ω², c = 2ζ√(k J_a)); integrated by RK4 at four
//! steps per sample. The recording is the base L·θ (θ quantised to the hub encoder's step) and
//! the tip deflection L·(ψ − θ) quantised to the tip sensor's step, each grid at its own offset
//! (where the encoder's zero falls). The arm's transfer from the base is exactly the model of
//! [`super::ringdowns`], so the errors are the measurement's (quantisation, decimation,
//! sampling), not model error.

use super::ringdowns::{identify_ringdowns_with, RingdownOptions};
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::f64::consts::PI;

/// One simulated closed-loop recording's design.
#[derive(Clone, Debug, Serialize)]
pub struct LinkDesign {
    /// The arm's natural frequency with the hub held (Hz) and its damping ratio: the truth.
    pub freq_hz: f64,
    /// See `freq_hz`.
    pub zeta: f64,
    /// Hub and arm inertias (kg m²).
    pub j_hub: f64,
    /// See `j_hub`.
    pub j_arm: f64,
    /// PD gains of the hub loop (N m/rad, N m s/rad).
    pub kp: f64,
    /// See `kp`.
    pub kd: f64,
    /// Square-wave reference: amplitude (rad) and period (s), starting high.
    pub amp_rad: f64,
    /// See `amp_rad`.
    pub period_s: f64,
    /// Duration (s) and sample rate (Hz).
    pub duration_s: f64,
    /// See `duration_s`.
    pub rate_hz: f64,
    /// Arm length L (m): base = L θ, tip deflection = L (ψ − θ).
    pub arm_len_m: f64,
    /// Hub encoder step (rad; 0: not quantised) and tip deflection step (m; 0: not quantised).
    pub hub_step_rad: f64,
    /// See `hub_step_rad`.
    pub tip_step_m: f64,
    /// Offsets of the two quantisation grids (fractions of a step, 0..1).
    pub grid_offsets: (f64, f64),
}

impl Default for LinkDesign {
    /// The design of `tools/tests/ident_closed_loop.rs` at Kp 1, Kd 0.03: 1.75 Hz, ζ 0.03,
    /// J_h 0.002, J_a 0.004 kg m², ±0.05 rad square wave of period 5 s, 40 s at 1 kHz,
    /// L 0.45 m, 1 mrad hub and 1 mm tip steps, grids at zero offset.
    fn default() -> Self {
        LinkDesign {
            freq_hz: 1.75,
            zeta: 0.03,
            j_hub: 0.002,
            j_arm: 0.004,
            kp: 1.0,
            kd: 0.03,
            amp_rad: 0.05,
            period_s: 5.0,
            duration_s: 40.0,
            rate_hz: 1000.0,
            arm_len_m: 0.45,
            hub_step_rad: 1e-3,
            tip_step_m: 1e-3,
            grid_offsets: (0.0, 0.0),
        }
    }
}

/// Quantises `x` to step `q` on a grid offset by `o` steps; `x` for q = 0.
fn quantise(x: f64, q: f64, o: f64) -> f64 {
    if q > 0.0 {
        ((x / q + o).round() - o) * q
    } else {
        x
    }
}

/// Simulates the design `d` (module doc): (base m, tip deflection m), one sample per 1/rate.
pub fn simulate_link(d: &LinkDesign) -> (Vec<f64>, Vec<f64>) {
    let w = 2.0 * PI * d.freq_hz;
    let k = d.j_arm * w * w;
    let c = 2.0 * d.zeta * (k * d.j_arm).sqrt();
    let n = (d.duration_s * d.rate_hz).round() as usize;
    let deriv = |x: [f64; 4], r: f64| {
        let (th, thd, ps, psd) = (x[0], x[1], x[2], x[3]);
        let spring = k * (ps - th) + c * (psd - thd);
        let u = d.kp * (r - th) - d.kd * thd;
        [thd, (u + spring) / d.j_hub, psd, -spring / d.j_arm]
    };
    let mut x = [0.0f64; 4];
    let sub = 4;
    let h = 1.0 / d.rate_hz / sub as f64;
    let (mut base, mut defl) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let add = |x: [f64; 4], s: f64, kk: [f64; 4]| std::array::from_fn(|j| x[j] + s * kk[j]);
    for i in 0..n {
        let t = i as f64 / d.rate_hz;
        let high = ((t / (0.5 * d.period_s)) as usize) % 2 == 0;
        let r = if high { d.amp_rad } else { -d.amp_rad };
        let th = quantise(x[0], d.hub_step_rad, d.grid_offsets.0);
        base.push(d.arm_len_m * th);
        defl.push(quantise(
            d.arm_len_m * (x[2] - x[0]),
            d.tip_step_m,
            d.grid_offsets.1,
        ));
        for _ in 0..sub {
            let k1 = deriv(x, r);
            let k2 = deriv(add(x, h / 2.0, k1), r);
            let k3 = deriv(add(x, h / 2.0, k2), r);
            let k4 = deriv(add(x, h, k3), r);
            for j in 0..4 {
                x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
    }
    (base, defl)
}

/// What varies between the runs of [`ringdown_coverage`].
#[derive(Clone, Debug, Serialize)]
pub struct CoverageSpec {
    /// The design every run starts from.
    pub base: LinkDesign,
    /// Draw per run: truth f ∈ U[1.5, 2] Hz and ζ log-uniform in [0.015, 0.05]; Kp
    /// log-uniform in [0.5, 4] with Kd = 0.03·Kp^0.7 (the four gain sets of the test lie on
    /// it); amplitude U[0.03, 0.08] rad; period U[4, 6] s; both quantisation steps × 2^U[−1, 1].
    /// Off: only the grid offsets are drawn.
    pub vary: bool,
    /// Put the hub's rest positions (± the amplitude) at the middle of an encoder step: the
    /// amplitude rounded to a whole number of steps, the hub grid at zero offset (a reference on
    /// the encoder's grid, as in `tools/tests/ident_closed_loop.rs`); the hub's motion below half
    /// a step about its rest is then never seen.
    pub rest_mid_step: bool,
    /// Options of the identification.
    pub opts: RingdownOptions,
}

/// The design of run `seed` of `spec` (grid offsets always drawn, the rest when `vary`).
pub fn draw_design(spec: &CoverageSpec, seed: u64) -> LinkDesign {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut d = spec.base.clone();
    d.grid_offsets = (rng.gen(), rng.gen());
    if spec.vary {
        d.freq_hz = rng.gen_range(1.5..2.0);
        d.zeta = 0.015 * (0.05f64 / 0.015).powf(rng.gen::<f64>());
        d.kp = 0.5 * 8f64.powf(rng.gen::<f64>());
        d.kd = 0.03 * d.kp.powf(0.7);
        d.amp_rad = rng.gen_range(0.03..0.08);
        d.period_s = rng.gen_range(4.0..6.0);
        d.hub_step_rad *= 2f64.powf(rng.gen_range(-1.0..1.0));
        d.tip_step_m *= 2f64.powf(rng.gen_range(-1.0..1.0));
    }
    if spec.rest_mid_step && d.hub_step_rad > 0.0 {
        d.amp_rad = (d.amp_rad / d.hub_step_rad).round().max(1.0) * d.hub_step_rad;
        d.grid_offsets.0 = 0.0;
    }
    d
}

/// One run of [`ringdown_coverage`].
#[derive(Clone, Debug, Serialize)]
pub struct CoverageRun {
    /// Seed of the run.
    pub seed: u64,
    /// Its design.
    pub design: LinkDesign,
    /// Truth (Hz, ζ).
    pub truth: (f64, f64),
    /// Estimate (Hz, ζ).
    pub estimate: (f64, f64),
    /// Reported 1-σ (Hz, ζ).
    pub sigma: (f64, f64),
    /// Jackknife σ (Hz, ζ).
    pub jackknife: (f64, f64),
    /// Bootstrap standard deviation and bias (Hz, ζ).
    pub boot_sd: (f64, f64),
    /// See `boot_sd`.
    pub boot_bias: (f64, f64),
}

/// Coverage summary of one σ over the runs (f, ζ).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SigmaCoverage {
    /// Runs whose |estimate − truth| ≤ 2σ (f, ζ).
    pub covered: (usize, usize),
    /// RMS of (estimate − truth)/σ (f, ζ): 1 for an honest σ.
    pub rms_z: (f64, f64),
    /// Mean of (estimate − truth)/σ (f, ζ).
    pub mean_z: (f64, f64),
}

/// [`ringdown_coverage`]'s result.
#[derive(Clone, Debug, Serialize)]
pub struct RingdownCoverage {
    /// Runs made, and runs where identification failed.
    pub runs: usize,
    /// See `runs`.
    pub failed: usize,
    /// The reported σ.
    pub reported: SigmaCoverage,
    /// The jackknife σ alone (the σ before the bootstrap).
    pub jackknife: SigmaCoverage,
    /// The bias-corrected estimate (estimate − bootstrap bias) against the bootstrap sd.
    pub corrected: SigmaCoverage,
    /// Mean and RMS of the error (f Hz, ζ).
    pub mean_error: (f64, f64),
    /// See `mean_error`.
    pub rms_error: (f64, f64),
    /// Every run.
    pub per_run: Vec<CoverageRun>,
}

/// Coverage of errors `e` (f, ζ) against σ `s` (pairs per run).
fn summarise(e: &[(f64, f64)], s: &[(f64, f64)]) -> SigmaCoverage {
    let z: Vec<(f64, f64)> = e
        .iter()
        .zip(s)
        .map(|(e, s)| (e.0 / s.0, e.1 / s.1))
        .collect();
    let k = z.len().max(1) as f64;
    let rms = |g: fn(&(f64, f64)) -> f64| (z.iter().map(|v| g(v).powi(2)).sum::<f64>() / k).sqrt();
    let mean = |g: fn(&(f64, f64)) -> f64| z.iter().map(g).sum::<f64>() / k;
    SigmaCoverage {
        covered: (
            z.iter().filter(|v| v.0.abs() <= 2.0).count(),
            z.iter().filter(|v| v.1.abs() <= 2.0).count(),
        ),
        rms_z: (rms(|v| v.0), rms(|v| v.1)),
        mean_z: (mean(|v| v.0), mean(|v| v.1)),
    }
}

/// Simulates `runs` recordings of `spec` (seeds `seed`, `seed` + 1, …) and identifies each
/// with [`identify_ringdowns_with`] (band 0.2–20 Hz, ζ < 0.5): how often ±2σ covers the true
/// f and ζ, for the reported σ, the jackknife alone and the bias-corrected bootstrap.
/// `progress` is called after each run with (runs done, runs).
pub fn ringdown_coverage(
    spec: &CoverageSpec,
    runs: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize, usize),
) -> RingdownCoverage {
    let mut per_run = Vec::with_capacity(runs);
    let mut failed = 0;
    for r in 0..runs {
        let s = seed + r as u64;
        let d = draw_design(spec, s);
        let (b, y) = simulate_link(&d);
        match identify_ringdowns_with(&b, &y, d.rate_hz, (0.2, 20.0), 0.5, &spec.opts) {
            Err(_) => failed += 1,
            Ok(res) => per_run.push(CoverageRun {
                seed: s,
                design: d.clone(),
                truth: (d.freq_hz, d.zeta),
                estimate: (res.mode.freq_hz, res.mode.zeta),
                sigma: (res.mode.freq_hz_std, res.mode.zeta_std),
                jackknife: res.jackknife,
                boot_sd: res.bootstrap.sd,
                boot_bias: res.bootstrap.bias,
            }),
        }
        progress(r + 1, runs);
    }
    let err: Vec<(f64, f64)> = per_run
        .iter()
        .map(|p| (p.estimate.0 - p.truth.0, p.estimate.1 - p.truth.1))
        .collect();
    let corr: Vec<(f64, f64)> = per_run
        .iter()
        .zip(&err)
        .map(|(p, e)| (e.0 - p.boot_bias.0, e.1 - p.boot_bias.1))
        .collect();
    let pick = |g: fn(&CoverageRun) -> (f64, f64)| per_run.iter().map(g).collect::<Vec<_>>();
    let k = err.len().max(1) as f64;
    let mean_error = (
        err.iter().map(|e| e.0).sum::<f64>() / k,
        err.iter().map(|e| e.1).sum::<f64>() / k,
    );
    let rms_error = (
        (err.iter().map(|e| e.0 * e.0).sum::<f64>() / k).sqrt(),
        (err.iter().map(|e| e.1 * e.1).sum::<f64>() / k).sqrt(),
    );
    RingdownCoverage {
        runs,
        failed,
        reported: summarise(&err, &pick(|p| p.sigma)),
        jackknife: summarise(&err, &pick(|p| p.jackknife)),
        corrected: summarise(&corr, &pick(|p| p.boot_sd)),
        mean_error,
        rms_error,
        per_run,
    }
}
