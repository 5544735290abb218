//! The simulator benchmark: 60 s of a 6-mode model at 1 kHz, our exact modal simulator against
//! `scipy.signal.lsim` on the same state-space model and input (`tools/benches/lsim_peer.py`,
//! needs `pip install scipy`), in the same run. A benchmark, not a test: times depend on the
//! machine.

use crate::model::sim::BaseMotionSim;
use crate::model::{trapezoid_reference, BeamModel, ModelOptions, Rig};
use anyhow::{bail, Context, Result};
use std::path::Path;
use std::time::Instant;

/// Samples of the benchmark input (60 s at 1 kHz).
pub const N_SAMPLES: usize = 60_000;
/// Step (s).
pub const DT_S: f64 = 1e-3;
/// Runs of each side; the median is reported.
pub const RUNS: usize = 5;

/// Result of [`bench_sim`].
#[derive(Clone, Debug)]
pub struct BenchResult {
    /// Median wall time of ours, eigen-analysis and discretisation included (s).
    pub ours_s: f64,
    /// Median wall time of `scipy.signal.lsim` (s).
    pub scipy_s: f64,
    /// States of the continuous model given to scipy.
    pub n_states: usize,
    /// Largest |tip difference| between the two (m).
    pub max_diff_m: f64,
    /// Largest |tip deflection| of ours (m).
    pub peak_m: f64,
}

/// 60 s of back-and-forth 50 mm moves (200 mm/s, 2 m/s², 2.65 s hold) at 1 kHz (m).
pub fn back_and_forth() -> Result<Vec<f64>> {
    let (mv, _) = trapezoid_reference(0.0, 0.05, 0.2, 2.0, 1000.0, 2.65)?;
    let mut y: Vec<f64> = Vec::new();
    while y.len() < N_SAMPLES {
        let back = (y.len() / mv.len()) % 2 == 1;
        y.extend(mv.iter().map(|v| if back { 0.05 - v } else { *v }));
    }
    y.truncate(N_SAMPLES);
    Ok(y)
}

/// Median time of [`RUNS`] simulations of `y` (model set-up included) and the last output.
fn time_ours(model: &BeamModel, y: &[f64]) -> Result<(f64, Vec<f64>)> {
    let mut runs = Vec::new();
    let mut w = Vec::new();
    for _ in 0..RUNS {
        let t0 = Instant::now();
        let sim = BaseMotionSim::new(model, DT_S)?;
        w = sim.run(y).0;
        runs.push(t0.elapsed().as_secs_f64());
    }
    runs.sort_by(|x, z| x.total_cmp(z));
    Ok((runs[RUNS / 2], w))
}

/// The same model as continuous state space driven by the base acceleration (the velocity
/// kick of sample k, dv_k/dt, held for one step: what lsim with interp=False (ZOH) does), as
/// the peer's JSON (A, B, C, D, dt, u).
fn lsim_problem(model: &BeamModel, y: &[f64]) -> Result<serde_json::Value> {
    let sim = BaseMotionSim::new(model, DT_S)?;
    let m = sim.modes();
    let n = m.omega_rad_s.len();
    let mut am = vec![vec![0.0; 2 * n]; 2 * n];
    let mut bm = vec![vec![0.0]; 2 * n];
    let mut cm = vec![vec![0.0; 2 * n]];
    for r in 0..n {
        am[2 * r][2 * r + 1] = 1.0;
        am[2 * r + 1][2 * r] = -m.omega_rad_s[r].powi(2);
        am[2 * r + 1][2 * r + 1] = -2.0 * m.zeta[r] * m.omega_rad_s[r];
        bm[2 * r + 1][0] = -m.participation[r];
        cm[0][2 * r] = m.tip[r];
    }
    let dt = DT_S;
    let u: Vec<f64> = (0..y.len())
        .map(|k| {
            let vb = if k == 0 { 0.0 } else { (y[k] - y[k - 1]) / dt };
            let va = if k + 1 < y.len() {
                (y[k + 1] - y[k]) / dt
            } else {
                0.0
            };
            (va - vb) / dt
        })
        .collect();
    Ok(serde_json::json!({"A": am, "B": bm, "C": cm, "D": [[0.0]], "dt": dt, "u": u}))
}

/// Runs `python3 peer problem.json` (a temporary file) and returns its median time (s) and
/// output.
fn run_peer(peer: &Path, problem: &serde_json::Value) -> Result<(f64, Vec<f64>)> {
    let path = std::env::temp_dir().join(format!("beamshaper-lsim-{}.json", std::process::id()));
    std::fs::write(&path, problem.to_string())?;
    let out = std::process::Command::new("python3")
        .arg(peer)
        .arg(&path)
        .output();
    let _ = std::fs::remove_file(&path);
    let out = out.with_context(|| format!("cannot run python3 {}", peer.display()))?;
    if !out.status.success() {
        bail!(
            "scipy peer failed (pip install scipy numpy?): {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let t = v["median_s"].as_f64().context("peer: no median_s")?;
    let y: Vec<f64> = v["y"]
        .as_array()
        .context("peer: no y")?
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    Ok((t, y))
}

/// The benchmark of the module docs on `rig` (6 basis functions), against the scipy script
/// `peer`.
///
/// Errors: the model cannot be built, python3 or scipy is missing, the peer's output is bad.
pub fn bench_sim(rig: &Rig, peer: &Path) -> Result<BenchResult> {
    let opts = ModelOptions {
        n_modes: 6,
        ..Default::default()
    };
    let model = BeamModel::new(rig, &opts)?;
    let y = back_and_forth()?;
    let (ours_s, w) = time_ours(&model, &y)?;
    let problem = lsim_problem(&model, &y)?;
    let (scipy_s, yp) = run_peer(peer, &problem)?;
    let peak_m = w.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let max_diff_m = w
        .iter()
        .zip(&yp)
        .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
    Ok(BenchResult {
        ours_s,
        scipy_s,
        n_states: problem["A"].as_array().map_or(0, |a| a.len()),
        max_diff_m,
        peak_m,
    })
}
