//! `ringdown-coverage`: the coverage of the pooled ring-down path's ±2σ on synthetic
//! closed-loop recordings ([`crate::ident::ringdown_sim`]).

use crate::ident::ringdown_sim::{
    ringdown_coverage, CoverageSpec, LinkDesign, RingdownCoverage, SigmaCoverage,
};
use crate::ident::ringdowns::RingdownOptions;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

/// `ringdown-coverage` arguments.
#[derive(Args, Debug)]
pub struct RingdownCoverageArgs {
    /// Number of synthetic recordings.
    #[arg(long, default_value_t = 100)]
    pub runs: usize,
    /// Seed of the first recording (the others follow).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Keep the design fixed (truth 1.75 Hz / 0.03, --kp/--kd, ±0.05 rad, 5 s period); only the
    /// quantisation grids' offsets are drawn. Default: truth, gains, amplitude, period and
    /// steps drawn per run.
    #[arg(long)]
    pub fixed: bool,
    /// Hub rest positions at the middle of an encoder step (the reference on the encoder's grid).
    #[arg(long)]
    pub rest_mid_step: bool,
    /// Hub PD gains (with --fixed).
    #[arg(long, default_value_t = 1.0)]
    pub kp: f64,
    /// See --kp.
    #[arg(long, default_value_t = 0.03)]
    pub kd: f64,
    /// Hub encoder step (mrad; 0: not quantised).
    #[arg(long, default_value_t = 1.0)]
    pub hub_step_mrad: f64,
    /// Tip deflection step (mm; 0: not quantised).
    #[arg(long, default_value_t = 1.0)]
    pub tip_step_mm: f64,
    /// Sample rate of the recordings (Hz).
    #[arg(long, default_value_t = 1000.0)]
    pub rate_hz: f64,
    /// Samples per period after decimation (20 in `identify`; large: no decimation).
    #[arg(long, default_value_t = 20.0)]
    pub samples_per_period: f64,
    /// Bootstrap replicas per recording (0: jackknife only).
    #[arg(long, default_value_t = crate::ident::ringdown_sigma::BOOTSTRAP_REPLICAS)]
    pub replicas: usize,
    /// Print every run.
    #[arg(long)]
    pub per_run: bool,
    /// Write one recording (the first seed's design) as a CSV `time_s,base_pos_m,tip_pos_m`
    /// here, and stop.
    #[arg(long)]
    pub write_csv: Option<PathBuf>,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `beamtool ringdown-coverage`: simulate, identify by pooled ring-downs, count ±2σ coverage.
pub fn ringdown_coverage_cmd(a: RingdownCoverageArgs) -> Result<()> {
    if a.runs == 0 || !(a.hub_step_mrad >= 0.0 && a.tip_step_mm >= 0.0 && a.rate_hz > 0.0) {
        bail!("--runs ≥ 1, steps ≥ 0 and --rate-hz > 0 please");
    }
    let spec = CoverageSpec {
        base: LinkDesign {
            kp: a.kp,
            kd: a.kd,
            hub_step_rad: 1e-3 * a.hub_step_mrad,
            tip_step_m: 1e-3 * a.tip_step_mm,
            rate_hz: a.rate_hz,
            ..Default::default()
        },
        vary: !a.fixed,
        rest_mid_step: a.rest_mid_step,
        opts: RingdownOptions {
            samples_per_period: a.samples_per_period,
            bootstrap_replicas: a.replicas,
            ..Default::default()
        },
    };
    if let Some(p) = &a.write_csv {
        return write_synthetic(&spec, a.seed, p);
    }
    let c = ringdown_coverage(&spec, a.runs, a.seed, &mut |k, n| {
        if k % 20 == 0 || k == n {
            eprintln!("  .. {k}/{n} runs");
        }
    });
    print_coverage(&c, a.fixed, a.per_run);
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&c)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}

/// Writes the design of run `seed` of `spec` as a recording CSV to `p`.
fn write_synthetic(spec: &CoverageSpec, seed: u64, p: &std::path::Path) -> Result<()> {
    let d = crate::ident::ringdown_sim::draw_design(spec, seed);
    let (b, y) = crate::ident::ringdown_sim::simulate_link(&d);
    let mut rec = crate::recording::Recording::with_uniform_time(b.len(), d.rate_hz);
    rec.tip_pos_m = Some(b.iter().zip(&y).map(|(b, y)| b + y).collect());
    rec.base_pos_m = Some(b);
    rec.write_csv(p)?;
    println!(
        "synthetic closed-loop recording (seed {}, arm {} Hz, ζ {}, Kp {}, Kd {}) -> {}",
        seed,
        d.freq_hz,
        d.zeta,
        d.kp,
        d.kd,
        p.display()
    );
    Ok(())
}

/// The coverage table of [`ringdown_coverage_cmd`] (every run too with `per_run`).
fn print_coverage(c: &RingdownCoverage, fixed: bool, per_run: bool) {
    if per_run {
        println!("  seed  f_true  f_est  σf(rep) σf(jack) σf(boot) biasf | ζ_true ζ_est σζ(rep) σζ(jack) σζ(boot) biasζ");
        for p in &c.per_run {
            println!(
                "  {:>4} {:.4} {:.5} {:.1e} {:.1e} {:.1e} {:+.1e} | {:.4} {:.5} {:.1e} {:.1e} {:.1e} {:+.1e}",
                p.seed, p.truth.0, p.estimate.0, p.sigma.0, p.jackknife.0, p.boot_sd.0, p.boot_bias.0,
                p.truth.1, p.estimate.1, p.sigma.1, p.jackknife.1, p.boot_sd.1, p.boot_bias.1
            );
        }
    }
    let n = c.per_run.len();
    println!(
        "pooled ring-down coverage: {} runs ({}), {} failed; mean error f {:+.2e} Hz, ζ {:+.2e}; rms error f {:.2e} Hz, ζ {:.2e}",
        c.runs,
        if fixed { "fixed design" } else { "drawn designs" },
        c.failed,
        c.mean_error.0,
        c.mean_error.1,
        c.rms_error.0,
        c.rms_error.1
    );
    println!(
        "  {:<34} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9}",
        "sigma", "f cover", "ζ cover", "f rms z", "ζ rms z", "f mean z", "ζ mean z"
    );
    let row = |name: &str, s: &SigmaCoverage| {
        let pct = |k: usize| 100.0 * k as f64 / n.max(1) as f64;
        println!(
            "  {:<34} {:>7.1}% {:>7.1}% {:>9.2} {:>9.2} {:>9.2} {:>9.2}",
            name,
            pct(s.covered.0),
            pct(s.covered.1),
            s.rms_z.0,
            s.rms_z.1,
            s.mean_z.0,
            s.mean_z.1
        );
    };
    row("reported (max of jackknife, boot)", &c.reported);
    row("jackknife over segments alone", &c.jackknife);
    row("bias-corrected, bootstrap sd", &c.corrected);
}
