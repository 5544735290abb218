//! `bench-sim`: 60 s of a 6-mode model at 1 kHz, our exact modal simulator against
//! `scipy.signal.lsim` on the same state-space model and input (`tools/benches/lsim_peer.py`,
//! needs `pip install scipy`), in the same run.

use super::sim::{mode_zoh, BaseMotionSim};
use super::{trapezoid_reference, BeamModel, ModelOptions, Rig};
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

/// `bench-sim` arguments.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Rig file (TOML).
    #[arg(long, default_value = "../rigs/paper.toml")]
    pub rig: PathBuf,
    /// The scipy peer script.
    #[arg(long, default_value = "benches/lsim_peer.py")]
    pub peer: PathBuf,
}

/// `beamtool bench-sim`.
pub fn bench_sim(a: BenchArgs) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    let model = BeamModel::new(
        &rig,
        &ModelOptions {
            n_modes: 6,
            ..Default::default()
        },
    )?;
    let dt = 1e-3;
    // 60 s of back-and-forth 50 mm moves.
    let (mv, _) = trapezoid_reference(0.0, 0.05, 0.2, 2.0, 1000.0, 2.65)?;
    let mut y: Vec<f64> = Vec::new();
    while y.len() < 60_000 {
        let back = (y.len() / mv.len()) % 2 == 1;
        y.extend(mv.iter().map(|v| if back { 0.05 - v } else { *v }));
    }
    y.truncate(60_000);
    let mut runs = Vec::new();
    let mut w = Vec::new();
    for _ in 0..5 {
        let t0 = Instant::now();
        let sim = BaseMotionSim::new(&model, dt)?;
        w = sim.run(&y).0;
        runs.push(t0.elapsed().as_secs_f64());
    }
    runs.sort_by(|x, z| x.total_cmp(z));
    let ours = runs[2];
    // The same model as continuous state space driven by the base acceleration (the velocity
    // kick of sample k, dv_k/dt, held for one step: what lsim with interp=False (ZOH) does).
    let sim = BaseMotionSim::new(&model, dt)?;
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
    let _ = mode_zoh;
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
    let json = serde_json::json!({"A": am, "B": bm, "C": cm, "D": [[0.0]], "dt": dt, "u": u});
    let path = std::env::temp_dir().join(format!("beamshaper-lsim-{}.json", std::process::id()));
    std::fs::write(&path, json.to_string())?;
    let out = std::process::Command::new("python3")
        .arg(&a.peer)
        .arg(&path)
        .output()
        .with_context(|| format!("cannot run python3 {}", a.peer.display()))?;
    if !out.status.success() {
        bail!(
            "scipy peer failed (pip install scipy numpy?): {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let peer: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let t_peer = peer["median_s"].as_f64().context("peer: no median_s")?;
    let yp: Vec<f64> = peer["y"]
        .as_array()
        .context("peer: no y")?
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    let peak = w.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let diff = w
        .iter()
        .zip(&yp)
        .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
    println!("60 s of a 6-mode model at 1 kHz (60000 samples), median of 5 runs:");
    println!(
        "  beamtool exact modal simulation (incl. eigen-analysis and discretisation): {:.3} ms",
        ours * 1e3
    );
    println!(
        "  scipy.signal.lsim on the same 12-state model and input:                 {:.3} ms",
        t_peer * 1e3
    );
    println!("  ratio scipy / beamtool = {:.1}x; largest tip difference {:.2e} m ({:.2e} of the peak {:.3e} m)", t_peer / ours, diff, diff / peak, peak);
    let _ = std::fs::remove_file(&path);
    Ok(())
}
