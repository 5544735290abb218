//! `diagnose`, `diagnose-proof` and `diagnose-lengths` subcommands: arguments, files, progress
//! and printing around the library in [`crate::diagnose`].

use crate::diagnose::fit::{residuals, CHANNEL_NAMES};
use crate::diagnose::model::Prepared;
use crate::diagnose::report::{to_json, words};
use crate::diagnose::{diagnose as run_diagnosis, Diagnosis};
use crate::ident::spectrum::amplitude_spectrum;
use crate::model::Rig;
use crate::plot::{lines, Series};
use crate::progress::Progress;
use crate::recording::ReadOptions;
use crate::truth::EFFECTS;
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use std::path::{Path, PathBuf};

/// The recordings of one diagnosis and how they are read (`diagnose`, `diagnose-bootstrap`).
#[derive(Args, Debug)]
pub struct Recordings {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// Fit recording(s) (CSV), repeatable.
    #[arg(long = "fit", required = true)]
    pub fit: Vec<PathBuf>,
    /// Validation recording (CSV), never fitted.
    #[arg(long)]
    pub validate: PathBuf,
    /// How every recording is read (`--columns`: the same mapping for the fit and the
    /// validation files).
    #[command(flatten)]
    pub read: super::read::ReadArgs,
}

/// `diagnose` arguments.
#[derive(Args, Debug)]
pub struct DiagnoseArgs {
    /// The recordings.
    #[command(flatten)]
    pub inputs: Recordings,
    /// Write the JSON result here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write report.md, diagnosis.json, SVG plots and validation_predictions.csv (the validation
    /// recording, the nominal and the final model's predictions) into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

fn bar(len: u64) -> ProgressBar {
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b
}

/// Shows library progress: a bar on a terminal, one line per stage (and note) on stderr
/// otherwise (logs, CI, pipes); nothing when not `show`n.
pub struct StageProgress {
    bar: ProgressBar,
    lines: bool,
    show: bool,
    t0: std::time::Instant,
    stage: String,
}

impl StageProgress {
    /// A sink that shows (or, when `!show`, hides) progress.
    pub fn new(show: bool) -> Self {
        use std::io::IsTerminal;
        let lines = show && !std::io::stderr().is_terminal();
        let bar = bar(1);
        if !show || lines {
            bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        StageProgress {
            bar,
            lines,
            show,
            t0: std::time::Instant::now(),
            stage: String::new(),
        }
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Progress for StageProgress {
    fn stage(&mut self, name: &str) {
        self.stage = name.to_string();
        self.bar.set_message(name.to_string());
    }

    fn advance(&mut self, done: u64, total: u64) {
        self.bar.set_length(total);
        self.bar.set_position(done);
        if self.lines {
            eprintln!(
                "[{:>6.1} s] {done}/{total} {}",
                self.t0.elapsed().as_secs_f64(),
                self.stage
            );
        }
    }

    fn note(&mut self, text: &str) {
        if self.show {
            self.bar
                .suspend(|| eprintln!("[{:>6.0} s] {text}", self.t0.elapsed().as_secs_f64()));
        }
    }
}

/// Reads and prepares one recording of `rig` with the reading options `opts`
/// ([`crate::diagnose::load`]), printing its notes.
pub fn load(path: &Path, rig: &Rig, opts: &ReadOptions) -> Result<Prepared> {
    let loaded = crate::diagnose::load::load_with(path, rig, opts)?;
    super::print_notes(path, &loaded.notes);
    Ok(loaded.prepared)
}

/// Runs a diagnosis on files read with `opts`, with progress shown when `show`.
pub fn diagnose_files(
    rig: &Path,
    fit: &[PathBuf],
    validate: &Path,
    opts: &ReadOptions,
    show: bool,
) -> Result<Diagnosis> {
    let rig = Rig::from_toml_file(rig)?;
    let fit: Vec<Prepared> = fit
        .iter()
        .map(|p| load(p, &rig, opts))
        .collect::<Result<_>>()?;
    let val = load(validate, &rig, opts)?;
    let mut progress = StageProgress::new(show);
    let d = run_diagnosis(&rig, &fit, &val, &mut progress)?;
    progress.finish();
    Ok(d)
}

/// Writes `report.md`, `diagnosis.json`, the SVG plots and `validation_predictions.csv` (the
/// validation recording beside the calibrated nominal model's and the final model's predictions,
/// [`write_predictions`]) into `dir`.
pub fn write_report(d: &Diagnosis, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(
        dir.join("report.md"),
        format!("# Diagnosis\n\n```\n{}```\n", words(d)),
    )?;
    std::fs::write(
        dir.join("diagnosis.json"),
        serde_json::to_string_pretty(&to_json(d))?,
    )?;
    let v = &d.validate;
    let r0 = residuals(v, &d.val_pred_nominal);
    let r1 = residuals(v, &d.final_val_pred);
    for c in 0..3 {
        let meas = match c {
            0 => &v.base_m,
            1 => &v.tip_m,
            _ => &v.force_n,
        };
        if let (Some(meas), Some(r0), Some(r1)) = (meas, &r0[c], &r1[c]) {
            channel_plots(d, dir, c, meas, r0, r1)?;
        }
    }
    write_predictions(d, &dir.join("validation_predictions.csv"))
}

/// Writes the validation recording and both models' predictions of it as CSV: `time_s`, then
/// per recorded channel (`base_pos_m`, `tip_pos_m`, `force_n`; SI units) the recording, the
/// calibrated nominal model's prediction (`…_nominal`) and the final model's (`…_augmented`),
/// one row per sample. The residuals the diagnosis reads are recording − prediction, except on
/// samples held at a sensor's rail or without a reading, which it leaves out.
pub fn write_predictions(d: &Diagnosis, path: &Path) -> Result<()> {
    let v = &d.validate;
    let p0 = &d.val_pred_nominal;
    let p1 = &d.final_val_pred;
    let columns: Vec<(&str, &Vec<f64>, &Vec<f64>, &Vec<f64>)> = [
        (&v.base_m, &p0.base_m, &p1.base_m),
        (&v.tip_m, &p0.tip_m, &p1.tip_m),
        (&v.force_n, &p0.force_n, &p1.force_n),
    ]
    .into_iter()
    .zip(CHANNEL_NAMES)
    .filter_map(|((m, a, b), name)| Some((name, m.as_ref()?, a.as_ref()?, b.as_ref()?)))
    .collect();
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("cannot write {}", path.display()))?;
    let mut header = vec!["time_s".to_string()];
    for (name, ..) in &columns {
        header.extend([
            name.to_string(),
            format!("{name}_nominal"),
            format!("{name}_augmented"),
        ]);
    }
    w.write_record(&header)?;
    for (k, t) in v.time_s.iter().enumerate() {
        let mut row = vec![t.to_string()];
        for (_, m, a, b) in &columns {
            for s in [m, a, b] {
                row.push(s.get(k).map_or(String::new(), |x| x.to_string()));
            }
        }
        w.write_record(&row)?;
    }
    w.flush()?;
    Ok(())
}

/// Recording vs nominal vs augmented, residuals before/after and their spectra of channel `c`.
fn channel_plots(
    d: &Diagnosis,
    dir: &Path,
    c: usize,
    meas: &[f64],
    r0: &[f64],
    r1: &[f64],
) -> Result<()> {
    let t = &d.validate.time_s;
    let nominal: Vec<f64> = meas.iter().zip(r0).map(|(m, r)| m - r).collect();
    let augmented: Vec<f64> = meas.iter().zip(r1).map(|(m, r)| m - r).collect();
    let name = CHANNEL_NAMES[c];
    lines(
        &dir.join(format!("{name}_recording.svg")),
        &format!(
            "validation {name}: recording, nominal, augmented ({})",
            d.effect
        ),
        "time (s)",
        name,
        &[
            Series {
                label: "recording".into(),
                x: t,
                y: meas,
            },
            Series {
                label: "nominal (calibrated)".into(),
                x: t,
                y: &nominal,
            },
            Series {
                label: format!("augmented ({})", d.effect),
                x: t,
                y: &augmented,
            },
        ],
        false,
    )?;
    lines(
        &dir.join(format!("{name}_residual.svg")),
        &format!("validation {name} residual before/after"),
        "time (s)",
        name,
        &[
            Series {
                label: "nominal".into(),
                x: t,
                y: r0,
            },
            Series {
                label: format!("augmented ({})", d.effect),
                x: t,
                y: r1,
            },
        ],
        false,
    )?;
    spectrum_plot(d, dir, name, r0, r1)
}

/// The spectra of the validation residual before and after, with the model's modes.
fn spectrum_plot(d: &Diagnosis, dir: &Path, name: &str, r0: &[f64], r1: &[f64]) -> Result<()> {
    let (f, m0) = amplitude_spectrum(r0, 1.0 / d.validate.dt);
    let (_, m1) = amplitude_spectrum(r1, 1.0 / d.validate.dt);
    lines(
        &dir.join(format!("{name}_residual_spectrum.svg")),
        &format!(
            "validation {name} residual spectrum (model modes {:?} Hz)",
            d.location
                .model_freqs_hz
                .iter()
                .map(|f| (f * 100.0).round() / 100.0)
                .collect::<Vec<_>>()
        ),
        "frequency (Hz)",
        "amplitude",
        &[
            Series {
                label: "nominal".into(),
                x: &f,
                y: &m0,
            },
            Series {
                label: format!("augmented ({})", d.effect),
                x: &f,
                y: &m1,
            },
        ],
        true,
    )
}

/// Runs `diagnose`.
pub fn diagnose(a: DiagnoseArgs) -> Result<()> {
    let t0 = std::time::Instant::now();
    let i = &a.inputs;
    let d = diagnose_files(&i.rig, &i.fit, &i.validate, &i.read.options(), true)?;
    if std::env::var_os("DIAG_SELECT").is_some() {
        for line in &d.trace {
            eprintln!("{line}");
        }
    }
    print!("{}", words(&d));
    println!(
        "({} model evaluations, {:.1} s)",
        d.evaluations,
        t0.elapsed().as_secs_f64()
    );
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&to_json(&d))?)
            .with_context(|| format!("cannot write {}", j.display()))?;
    }
    if let Some(r) = &a.report {
        write_report(&d, r)?;
        println!("report in {}", r.display());
    }
    Ok(())
}

/// `diagnose-proof` arguments.
#[derive(Args, Debug)]
pub struct ProofArgs {
    /// Concealed cases per single catalogue effect.
    #[arg(long, default_value_t = 2)]
    pub cases: usize,
    /// Pairs of simultaneous effects (comma-separated `a+b`; default: seven pairs, see
    /// `diagnose::proof::DEFAULT_PAIRS`; `--pairs ''` for none).
    #[arg(long)]
    pub pairs: Option<String>,
    /// Cases per pair.
    #[arg(long, default_value_t = 1)]
    pub pair_cases: usize,
    /// Physics outside the catalogue (comma-separated: crack, loose_sensor_mount, sensor_drift;
    /// default: all; `--unmodelled ''` for none).
    #[arg(long)]
    pub unmodelled: Option<String>,
    /// Cases per out-of-catalogue kind.
    #[arg(long, default_value_t = 2)]
    pub unmodelled_cases: usize,
    /// Null cases (no effect; about a quarter are carriage-only rigs, drawn from the seed).
    #[arg(long, default_value_t = 16)]
    pub nulls: usize,
    /// First seed.
    #[arg(long, default_value_t = 1000)]
    pub seed: u64,
    /// Duration of each recording (s); shortened at high rates to `--max-samples`.
    #[arg(long, default_value_t = 40.0)]
    pub duration_s: f64,
    /// Most samples per recording.
    #[arg(long, default_value_t = 10_000)]
    pub max_samples: usize,
    /// Every case at 100 Hz with channels as drawn (no cycled rates, missing channels, noise).
    #[arg(long)]
    pub no_vary: bool,
    /// Only cases with these row labels (comma-separated: effect ids, `a+b` pairs, out-of-catalogue
    /// kinds, `none` for the nulls).
    #[arg(long)]
    pub only: Option<String>,
    /// Score these `proof.json` files together (repeatable; e.g. two seed sets) instead of
    /// running cases: the confusion table and summary of all their rows.
    #[arg(long)]
    pub rescore: Vec<PathBuf>,
    /// Output directory (cases, per-case reports, proof.json, summary.json, proof.md).
    #[arg(long, default_value = "diagnose-proof")]
    pub out: PathBuf,
}

fn list(s: &Option<String>, default: &[&str]) -> Vec<String> {
    match s {
        Some(s) => s
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect(),
        None => default.iter().map(|s| s.to_string()).collect(),
    }
}

/// Runs `diagnose-proof`.
pub fn proof(a: ProofArgs) -> Result<()> {
    use crate::diagnose::proof::{
        plan, proof_table, run_plan, score, sorted_label, PlanOptions, DEFAULT_PAIRS,
    };
    use crate::truth::unmodelled::Unmodelled;
    if !a.rescore.is_empty() {
        let rows = crate::diagnose::proof::read_rows(&a.rescore)?;
        print!(
            "{}{}",
            crate::diagnose::proof::confusion(&rows),
            crate::diagnose::proof::summary_text(&score(&rows))
        );
        return Ok(());
    }
    let unmodelled = list(&a.unmodelled, &Unmodelled::ALL.map(|u| u.id()))
        .iter()
        .map(|s| Unmodelled::parse(s))
        .collect::<Result<Vec<_>>>()?;
    let mut specs = plan(&PlanOptions {
        singles: list(&None, &EFFECTS),
        cases: a.cases,
        pairs: list(&a.pairs, &DEFAULT_PAIRS),
        pair_cases: a.pair_cases,
        unmodelled,
        unmodelled_cases: a.unmodelled_cases,
        nulls: a.nulls,
        seed: a.seed,
        duration_s: a.duration_s,
        max_samples: a.max_samples,
        vary: !a.no_vary,
    });
    if let Some(o) = &a.only {
        let keep = list(&Some(o.clone()), &[]);
        specs.retain(|c| {
            keep.iter()
                .any(|k| *k == c.label || sorted_label(k) == c.label)
        });
    }
    if specs.is_empty() {
        anyhow::bail!("no cases to run (check --only)");
    }
    eprintln!("diagnose-proof: {} cases", specs.len());
    let mut progress = StageProgress::new(true);
    let out = a.out.clone();
    let rows = run_plan(&specs, &mut progress, &mut |spec, _, o| {
        if let Some(o) = o {
            let dir = out.join(format!("{}-{}", spec.label, spec.seed));
            o.case.write(&dir)?;
            write_report(&o.diagnosis, &dir.join("report"))?;
        }
        Ok(())
    })?;
    progress.finish();
    let table = proof_table(&rows);
    print!("{table}");
    std::fs::create_dir_all(&a.out)?;
    std::fs::write(a.out.join("proof.md"), format!("```\n{table}```\n"))?;
    std::fs::write(
        a.out.join("proof.json"),
        serde_json::to_string_pretty(&json!(rows))?,
    )?;
    std::fs::write(
        a.out.join("summary.json"),
        serde_json::to_string_pretty(&json!({"cases": specs, "summary": score(&rows)}))?,
    )?;
    Ok(())
}

/// `diagnose-lengths` arguments.
#[derive(Args, Debug)]
pub struct LengthsArgs {
    /// Rig file (TOML) with the beam's (uniform) section and material; its length is ignored.
    #[arg(long)]
    pub rig: PathBuf,
    /// A free decay at one free length: `L_m=path.npy` or `L_m=path.npy@sensor_from_tip_m`
    /// (.npy [time_s; signal] or recording CSV); repeat for each length (at least 3).
    #[arg(long = "decay", required = true)]
    pub decay: Vec<String>,
    /// Default distance of the sensor (a lumped mass) from the tip (m).
    #[arg(long, default_value_t = 0.06)]
    pub sensor_from_tip_m: f64,
    /// Modes per length (1 or 2).
    #[arg(long, default_value_t = 2)]
    pub modes: usize,
    /// Write the JSON result here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Parses `L_m=path[@sensor_m]`.
/// Shortest plausible beam length of `diagnose-lengths` (m).
pub const MIN_LENGTH_M: f64 = 0.02;
/// Longest plausible beam length of `diagnose-lengths` (m).
pub const MAX_LENGTH_M: f64 = 5.0;

fn parse_decay(s: &str, default_sensor: f64) -> Result<(f64, PathBuf, f64)> {
    let (l, rest) = s
        .split_once('=')
        .with_context(|| format!("--decay `{s}`: expected `L_m=path[@sensor_from_tip_m]`"))?;
    let l: f64 = l
        .trim()
        .parse()
        .with_context(|| format!("--decay `{s}`: `{l}` is not a length in metres"))?;
    // a lab cantilever is centimetres to a few metres long; 40 for 0.40 m is a unit slip
    if !(l >= MIN_LENGTH_M && l <= MAX_LENGTH_M) {
        anyhow::bail!(
            "--decay `{s}`: length {l} m is not plausible for a cantilever ({MIN_LENGTH_M}–{MAX_LENGTH_M} m); lengths are in metres{}",
            if l > MAX_LENGTH_M && l / 100.0 <= MAX_LENGTH_M {
                format!(" (did you mean {} m?)", l / 100.0)
            } else {
                String::new()
            }
        );
    }
    let (path, sensor) = match rest.rsplit_once('@') {
        Some((p, m)) => (
            p,
            m.trim().parse::<f64>().with_context(|| {
                format!("--decay `{s}`: `{m}` is not a sensor distance in metres")
            })?,
        ),
        None => (rest, default_sensor),
    };
    Ok((l, PathBuf::from(path), sensor))
}

/// The modes of one free decay for the length series: mode 1 and, when asked, the mode nearest
/// to 6.27 f1 (within ±25 %; the uniform-beam ratio).
pub fn length_modes(
    l: f64,
    path: &Path,
    sensor: f64,
    n_modes: usize,
) -> Result<crate::diagnose::lengths::LengthModes> {
    let (t, x, what) = crate::ident::identify::free_decay_of(path)?;
    let r = crate::ident::freedecay::identify_free_decay(
        &t,
        &x,
        &crate::ident::freedecay::FreeDecayOptions {
            f_min_hz: 0.2,
            f_max_hz: 0.45 * 1.0 / ((t[t.len() - 1] - t[0]) / (t.len() - 1) as f64),
            ..Default::default()
        },
    )
    .with_context(|| format!("identifying {}", path.display()))?;
    let f1 = r.mode.freq_hz;
    let mut freq_hz = vec![(f1, r.mode.freq_hz_std)];
    if n_modes >= 2 {
        let m2 = r
            .modes
            .iter()
            .filter(|m| (m.freq_hz / (crate::diagnose::lengths::UNIFORM_F2_OVER_F1 * f1) - 1.0).abs() < 0.25)
            .min_by(|a, b| {
                (a.freq_hz / f1 - crate::diagnose::lengths::UNIFORM_F2_OVER_F1)
                    .abs()
                    .total_cmp(&(b.freq_hz / f1 - crate::diagnose::lengths::UNIFORM_F2_OVER_F1).abs())
            })
            .with_context(|| {
                format!(
                    "{}: no second bending mode within ±25 % of 6.27 × f1 = {:.2} Hz (modes found: {:?} Hz)",
                    path.display(),
                    crate::diagnose::lengths::UNIFORM_F2_OVER_F1 * f1,
                    r.modes.iter().map(|m| (m.freq_hz * 100.0).round() / 100.0).collect::<Vec<_>>()
                )
            })?;
        freq_hz.push((m2.freq_hz, m2.freq_hz_std));
    }
    Ok(crate::diagnose::lengths::LengthModes {
        length_m: l,
        sensor_from_tip_m: sensor,
        freq_hz,
        source: what,
    })
}

/// Runs `diagnose-lengths`.
pub fn diagnose_lengths(a: LengthsArgs) -> Result<()> {
    let t0 = std::time::Instant::now();
    let rig = Rig::from_toml_file(&a.rig)?;
    let mut data = Vec::new();
    let mut seen: Vec<(f64, PathBuf, Vec<u8>)> = Vec::new();
    for s in &a.decay {
        let (l, p, sensor) = parse_decay(s, a.sensor_from_tip_m)?;
        // distinct recordings at distinct lengths: the same file (or identical content) for two
        // lengths carries no length information
        let bytes = std::fs::read(&p).with_context(|| format!("cannot read {}", p.display()))?;
        for (l0, p0, b0) in &seen {
            if *b0 == bytes {
                anyhow::bail!(
                    "--decay: {} (L = {l} m) and {} (L = {l0} m) are the same recording; every length needs its own decay",
                    p.display(),
                    p0.display()
                );
            }
            if (l0 - l).abs() < 1e-9 {
                anyhow::bail!("--decay: length {l} m is given twice");
            }
        }
        seen.push((l, p.clone(), bytes));
        let m = length_modes(l, &p, sensor, a.modes)?;
        println!(
            "L = {:.3} m: {}  ({})",
            l,
            m.freq_hz
                .iter()
                .enumerate()
                .map(|(i, (f, sd))| format!("f{} = {f:.4} ± {sd:.4} Hz", i + 1))
                .collect::<Vec<_>>()
                .join(", "),
            m.source
        );
        data.push(m);
    }
    data.sort_by(|x, y| x.length_m.total_cmp(&y.length_m));
    let pb = bar(1);
    pb.set_message("fitting hypotheses (leave-one-length-out)");
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    let d = crate::diagnose::lengths::diagnose_lengths(
        &rig,
        &data,
        &crate::diagnose::lengths::LengthOptions {
            n_modes: a.modes,
            ..Default::default()
        },
    )?;
    pb.finish_and_clear();
    print!("\n{}", crate::diagnose::lengths::words(&d));
    println!("({:.1} s)", t0.elapsed().as_secs_f64());
    if let Some(j) = &a.json {
        std::fs::write(
            j,
            serde_json::to_string_pretty(&crate::diagnose::lengths::to_json(&d))?,
        )
        .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}
