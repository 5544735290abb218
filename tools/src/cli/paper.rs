//! `table1`, `table2` and `bench-sim`: arguments, printing, files and plots of the paper's
//! reproductions ([`crate::paper`]).

use crate::ident::frf::InputChannel;
use crate::ident::Method;
use crate::model::{BeamModel, ModelOptions, Rig};
use crate::paper::bench::{bench_sim as run_bench, N_SAMPLES, RUNS};
use crate::paper::table1::{reproduce_table1, Table1Options};
use crate::paper::table2::{reproduce_table2, Table2, FIGURES};
use crate::plot::{lines, Series};
use crate::progress::Progress;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// A [`Progress`] drawn as an `indicatif` bar (hidden when stderr is not a terminal).
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    /// A bar with no length yet.
    pub fn new() -> Self {
        Bar(indicatif::ProgressBar::new(0))
    }
}

impl Default for Bar {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for Bar {
    fn stage(&mut self, name: &str) {
        self.0.set_message(name.to_string());
    }
    fn advance(&mut self, done: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }
    fn note(&mut self, text: &str) {
        self.0.suspend(|| eprintln!("  note: {text}"));
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// `table1` arguments.
#[derive(Args, Debug)]
pub struct Table1Args {
    /// Rig file (TOML).
    #[arg(long, default_value = "../rigs/paper.toml")]
    pub rig: PathBuf,
    /// Noise: fraction of each measured channel's RMS.
    #[arg(long, default_value_t = 0.05)]
    pub noise: f64,
    /// FRF input: force (the paper's) or accel.
    #[arg(long, default_value = "force")]
    pub input: String,
    /// Methods (first is primary): lsce (the paper's), lscf, peak.
    #[arg(long, default_value = "lsce")]
    pub method: String,
    /// Ring-down recorded after each sweep (s).
    #[arg(long, default_value_t = 20.0)]
    pub tail_s: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// JSON of all rows.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `beamtool table1`: [`reproduce_table1`], printed.
pub fn table1(a: Table1Args) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    let model = BeamModel::new(&rig, &ModelOptions::default())?;
    let opts = Table1Options {
        noise_frac: a.noise,
        input: InputChannel::from_name(&a.input)?,
        methods: Method::parse_list(&a.method)?,
        tail_s: a.tail_s,
        seed: a.seed,
    };
    let t = reproduce_table1(&model, &opts, &mut Bar::new())?;
    println!("Table 1 in simulation: {} rig, 100 Hz, {:.0} % noise, input {:?}, {} (band 0.3-8 Hz), {} s ring-down", a.rig.display(), a.noise * 100.0, opts.input, a.method, a.tail_s);
    print!("{}", t.text());
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&t.rows)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}

/// `table2` arguments.
#[derive(Args, Debug)]
pub struct Table2Args {
    /// Rig file (TOML).
    #[arg(long, default_value = "../rigs/paper.toml")]
    pub rig: PathBuf,
    /// Output directory for the table (markdown) and plots (SVG).
    #[arg(long, default_value = "table2")]
    pub out: PathBuf,
}

/// `beamtool table2`: [`reproduce_table2`], written as markdown and Figs. 6–9.
pub fn table2(a: Table2Args) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let t = reproduce_table2(&rig)?;
    if t.responses.len() != 7 {
        bail!("internal: expected 7 responses");
    }
    let md = t.markdown(&a.rig.display().to_string());
    let path = a.out.join("table2.md");
    std::fs::write(&path, &md)?;
    print!("{md}");
    plot_figures(&t, &a.out)?;
    println!(
        "table -> {}, plots -> {}/fig6..fig9*.svg",
        path.display(),
        a.out.display()
    );
    Ok(())
}

/// Figs. 6–9: the first 6 s of the tip responses (mm) of [`FIGURES`].
fn plot_figures(t: &Table2, dir: &Path) -> Result<()> {
    let mm: Vec<Vec<f64>> = t
        .responses
        .iter()
        .map(|(_, v)| v.iter().map(|x| x * 1e3).collect())
        .collect();
    let n = 6000.min(t.time_s.len());
    for (file, idx) in FIGURES {
        let series: Vec<Series> = idx
            .iter()
            .map(|&i| Series {
                label: t.responses[i].0.clone(),
                x: &t.time_s[..n],
                y: &mm[i][..n],
            })
            .collect();
        let title = format!("tip position, {}", file.trim_end_matches(".svg"));
        lines(
            &dir.join(file),
            &title,
            "time (s)",
            "tip position (mm)",
            &series,
            false,
        )?;
    }
    Ok(())
}

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

/// `beamtool bench-sim`: [`crate::paper::bench::bench_sim`], printed.
pub fn bench_sim(a: BenchArgs) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    let r = run_bench(&rig, &a.peer)?;
    println!("60 s of a 6-mode model at 1 kHz ({N_SAMPLES} samples), median of {RUNS} runs:");
    println!(
        "  beamtool exact modal simulation (incl. eigen-analysis and discretisation): {:.3} ms",
        r.ours_s * 1e3
    );
    println!(
        "  scipy.signal.lsim on the same {}-state model and input:                 {:.3} ms",
        r.n_states,
        r.scipy_s * 1e3
    );
    println!("  ratio scipy / beamtool = {:.1}x; largest tip difference {:.2e} m ({:.2e} of the peak {:.3e} m)", r.scipy_s / r.ours_s, r.max_diff_m, r.max_diff_m / r.peak_m, r.peak_m);
    Ok(())
}
