//! `oma-coverage`: the coverage of the output-only path's ±2σ on synthetic recordings
//! ([`crate::ident::oma_sim`]).

use crate::ident::oma_sim::{output_only_coverage, SimDesign, SimMode};
use crate::ident::ssi::{t_coverage_2sigma, SsiOptions, N_BLOCKS};
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

/// `oma-coverage` arguments.
#[derive(Args, Debug)]
pub struct OmaCoverageArgs {
    /// Number of synthetic recordings.
    #[arg(long, default_value_t = 200)]
    pub runs: usize,
    /// Seed of the first recording (the others follow).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A mode `f_hz:zeta:rms` (repeatable); default 1.75:0.02:1 and 6.3:0.01:0.3.
    #[arg(long)]
    pub mode: Vec<String>,
    /// Sample rate (Hz).
    #[arg(long, default_value_t = 100.0)]
    pub rate_hz: f64,
    /// Duration of each recording (s).
    #[arg(long, default_value_t = 1000.0)]
    pub duration_s: f64,
    /// RMS of the white measurement noise (response units).
    #[arg(long, default_value_t = 0.1)]
    pub noise_rms: f64,
    /// Write one recording (the first seed) as a CSV `time_s,tip_pos_m` here, and stop.
    #[arg(long)]
    pub write_csv: Option<PathBuf>,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

fn parse_mode(s: &str) -> Result<SimMode> {
    let v: Vec<f64> = s
        .split(':')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--mode `{s}`: want f_hz:zeta:rms"))?;
    if v.len() != 3 || !(v[0] > 0.0 && v[1] > 0.0 && v[1] < 1.0 && v[2] > 0.0) {
        bail!("--mode `{s}`: want f_hz:zeta:rms with f > 0, 0 < zeta < 1, rms > 0");
    }
    Ok(SimMode {
        freq_hz: v[0],
        zeta: v[1],
        rms: v[2],
    })
}

/// `beamtool oma-coverage`: simulate, identify output-only, count ±2σ coverage.
pub fn oma_coverage(a: OmaCoverageArgs) -> Result<()> {
    let mut d = SimDesign {
        rate_hz: a.rate_hz,
        duration_s: a.duration_s,
        noise_rms: a.noise_rms,
        ..Default::default()
    };
    if !a.mode.is_empty() {
        d.modes = a
            .mode
            .iter()
            .map(|s| parse_mode(s))
            .collect::<Result<_>>()?;
    }
    if !(d.rate_hz > 0.0 && d.duration_s > 0.0 && d.noise_rms >= 0.0) {
        bail!("--rate-hz and --duration-s must be > 0, --noise-rms >= 0");
    }
    if let Some(p) = &a.write_csv {
        return write_synthetic(&d, a.seed, p);
    }
    if a.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let opts = SsiOptions::default();
    let c = output_only_coverage(&d, a.runs, a.seed, &opts, &mut |k, n| {
        if k % 20 == 0 || k == n {
            eprintln!("  .. {k}/{n} runs");
        }
    })?;
    print_coverage(&c, &d);
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&c)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}

/// Writes one synthetic output-only recording of design `d` (seed `seed`) to `p`.
fn write_synthetic(d: &SimDesign, seed: u64, p: &std::path::Path) -> Result<()> {
    let y = crate::ident::oma_sim::simulate_output_only(d, seed);
    let mut rec = crate::recording::Recording::with_uniform_time(y.len(), d.rate_hz);
    rec.tip_pos_m = Some(y);
    rec.write_csv(p)?;
    println!(
        "synthetic output-only recording (seed {seed}) -> {}",
        p.display()
    );
    Ok(())
}

/// The coverage table of [`oma_coverage`].
fn print_coverage(c: &crate::ident::oma_sim::Coverage, d: &SimDesign) {
    println!(
        "output-only SSI-cov coverage: {} runs ({} s at {} Hz, noise RMS {}), {} failed, {} with a spurious mode",
        c.runs, d.duration_s, d.rate_hz, d.noise_rms, c.failed, c.runs_with_spurious
    );
    println!(
        "  expected ±2σ coverage of a batch mean of {N_BLOCKS} blocks (Student t, {} dof): {:.1} %",
        N_BLOCKS - 1,
        100.0 * t_coverage_2sigma(N_BLOCKS - 1)
    );
    println!(
        "  {:>8} {:>7} {:>6} {:>10} {:>10} {:>9} {:>9} {:>9} {:>9}",
        "f (Hz)",
        "zeta",
        "found",
        "f cover",
        "zeta cover",
        "f mean z",
        "f rms z",
        "z mean z",
        "z rms z"
    );
    for m in &c.modes {
        let pct = |k: usize| 100.0 * k as f64 / m.found.max(1) as f64;
        println!(
            "  {:>8.3} {:>7.4} {:>6} {:>9.1}% {:>9.1}% {:>9.2} {:>9.2} {:>9.2} {:>9.2}",
            m.truth.freq_hz,
            m.truth.zeta,
            m.found,
            pct(m.freq_covered),
            pct(m.zeta_covered),
            m.freq_mean_z,
            m.freq_rms_z,
            m.zeta_mean_z,
            m.zeta_rms_z
        );
    }
}
