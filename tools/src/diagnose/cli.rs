//! `diagnose` and `diagnose-proof` subcommands.

use super::report::{to_json, validation_summary, words, write_report};
use super::sim::Prepared;
use super::{diagnose as run_diagnosis, Diagnosis};
use crate::model::Rig;
use crate::recording::Recording;
use crate::truth::{generate, TruthOptions, EFFECTS};
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use std::path::{Path, PathBuf};

/// `diagnose` arguments.
#[derive(Args, Debug)]
pub struct DiagnoseArgs {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// Fit recording(s) (CSV), repeatable.
    #[arg(long = "fit", required = true)]
    pub fit: Vec<PathBuf>,
    /// Validation recording (CSV), never fitted.
    #[arg(long)]
    pub validate: PathBuf,
    /// Write the JSON result here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write report.md, diagnosis.json and SVG plots into this directory.
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

/// Reads and prepares one recording.
pub fn load(path: &Path) -> Result<Prepared> {
    let rec = Recording::read_csv(path)?;
    Prepared::new(&path.display().to_string(), &rec)
}

/// Runs a diagnosis on files, with a progress bar.
pub fn diagnose_files(
    rig: &Path,
    fit: &[PathBuf],
    validate: &Path,
    show: bool,
) -> Result<Diagnosis> {
    let rig = Rig::from_toml_file(rig)?;
    let fit: Vec<Prepared> = fit.iter().map(|p| load(p)).collect::<Result<_>>()?;
    let val = load(validate)?;
    let pb = bar(1);
    // a bar on a terminal; one line per stage on stderr otherwise (logs, CI, pipes)
    use std::io::IsTerminal;
    let lines = show && !std::io::stderr().is_terminal();
    if !show || lines {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let t0 = std::time::Instant::now();
    let d = run_diagnosis(&rig, &fit, &val, &mut |i, n, m| {
        pb.set_length(n as u64);
        pb.set_position(i as u64);
        pb.set_message(m.to_string());
        if lines {
            eprintln!("[{:>5.1} s] {i}/{n} {m}", t0.elapsed().as_secs_f64());
        }
    })?;
    pb.finish_and_clear();
    Ok(d)
}

/// Runs `diagnose`.
pub fn diagnose(a: DiagnoseArgs) -> Result<()> {
    let t0 = std::time::Instant::now();
    let d = diagnose_files(&a.rig, &a.fit, &a.validate, true)?;
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
    /// Concealed cases per effect.
    #[arg(long, default_value_t = 2)]
    pub cases: usize,
    /// Null cases (no effect); at least 4.
    #[arg(long, default_value_t = 4)]
    pub nulls: usize,
    /// First seed.
    #[arg(long, default_value_t = 1000)]
    pub seed: u64,
    /// Duration of each recording (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration_s: f64,
    /// Only these effects (comma-separated ids).
    #[arg(long)]
    pub only: Option<String>,
    /// Output directory (cases, per-case reports, proof.json, proof.md).
    #[arg(long, default_value = "diagnose-proof")]
    pub out: PathBuf,
}

/// One proof row.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProofRow {
    /// Hidden effect.
    pub truth: String,
    /// Seed.
    pub seed: u64,
    /// Named effect.
    pub named: String,
    /// Correct.
    pub correct: bool,
    /// Main parameter: name, true, fitted, relative error.
    pub parameter: Option<(String, f64, f64, f64)>,
    /// Orientation correct (gravity cases).
    pub orientation_ok: Option<bool>,
    /// Validation NRMSE before/after, channel.
    pub nrmse: (f64, f64, String),
    /// Seconds.
    pub seconds: f64,
}

/// Runs the proof over generated cases; returns the rows.
pub fn run_proof(
    effects: &[&str],
    cases: usize,
    nulls: usize,
    seed0: u64,
    duration_s: f64,
    out: Option<&Path>,
    show: bool,
) -> Result<Vec<ProofRow>> {
    let mut jobs: Vec<(String, u64)> = Vec::new();
    for (i, e) in effects.iter().enumerate() {
        for k in 0..cases {
            jobs.push((e.to_string(), seed0 + 100 * i as u64 + k as u64));
        }
    }
    for k in 0..nulls {
        jobs.push(("none".into(), seed0 + 5000 + k as u64));
    }
    let pb = bar(jobs.len() as u64);
    if !show {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let opts = TruthOptions {
        duration_s,
        ..Default::default()
    };
    let mut rows = Vec::new();
    for (effect, seed) in jobs {
        pb.set_message(format!("{effect} seed {seed}"));
        let t0 = std::time::Instant::now();
        let case = generate(&effect, seed, &opts)?;
        let rig = Rig::from_toml_str(&case.rig_toml)?;
        let fit: Vec<Prepared> = case
            .fit
            .iter()
            .enumerate()
            .map(|(i, r)| Prepared::new(&format!("fit{}", i + 1), r))
            .collect::<Result<_>>()?;
        let val = Prepared::new("validate", &case.validate)?;
        let d = run_diagnosis(&rig, &fit, &val, &mut |_, _, _| {})?;
        let (c, before, after) = validation_summary(&d);
        let json = to_json(&d);
        let mut parameter = None;
        let mut orientation_ok = None;
        for (k, v) in &case.truth {
            if let (Some(tv), Some(fv)) = (v.as_f64(), json["parameters"][k].as_f64()) {
                if parameter.is_none() {
                    parameter = Some((k.clone(), tv, fv, (fv - tv).abs() / tv.abs().max(1e-300)));
                }
            }
            if k == "orientation" {
                orientation_ok = Some(json["parameters"]["orientation"].as_str() == v.as_str());
            }
        }
        // every generated rig has a finite servo loop: a named servo_lag is true physics and
        // never counts against a case whose hidden effect is another one (as the independent
        // scorer treats it); the named set must equal the hidden set otherwise
        let mut names: Vec<&str> = d.final_set.iter().map(|c| c.id.id()).collect();
        let mut hidden: Vec<&str> = effect.split('+').collect();
        if !hidden.contains(&"servo_lag") {
            names.retain(|n| *n != "servo_lag");
        }
        hidden.sort_unstable();
        let hidden = hidden.join("+");
        names.sort_unstable();
        names.dedup();
        let named = if names.is_empty() {
            "none".to_string()
        } else {
            names.join("+")
        };
        let correct = named == hidden && orientation_ok.unwrap_or(true);
        if let Some(o) = out {
            let dir = o.join(format!("{effect}-{seed}"));
            case.write(&dir)?;
            write_report(&d, &dir.join("report"))?;
        }
        rows.push(ProofRow {
            truth: effect,
            seed,
            named,
            correct,
            parameter,
            orientation_ok,
            nrmse: (before, after, super::fit::CHANNEL_NAMES[c].to_string()),
            seconds: t0.elapsed().as_secs_f64(),
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(rows)
}

/// The confusion table and summary of proof rows.
pub fn proof_table(rows: &[ProofRow]) -> String {
    let mut s = String::new();
    s += &format!(
        "{:<20} {:>6} {:<20} {:>4} {:>30} {:>10} {:>10} {:>7} {:>6}\n",
        "truth",
        "seed",
        "named",
        "ok",
        "parameter (true → fitted)",
        "NRMSE0",
        "NRMSE1",
        "red %",
        "s"
    );
    for r in rows {
        let p = r.parameter.as_ref().map_or_else(
            || {
                r.orientation_ok.map_or(String::from("-"), |o| {
                    format!("orientation {}", if o { "ok" } else { "WRONG" })
                })
            },
            |(n, t, f, e)| format!("{n} {t:.3e}→{f:.3e} ({:.0}%)", 100.0 * e),
        );
        s += &format!(
            "{:<20} {:>6} {:<20} {:>4} {:>30} {:>10.4} {:>10.4} {:>7.1} {:>6.1}\n",
            r.truth,
            r.seed,
            r.named,
            if r.correct { "yes" } else { "NO" },
            p,
            r.nrmse.0,
            r.nrmse.1,
            100.0 * (1.0 - r.nrmse.1 / r.nrmse.0),
            r.seconds
        );
    }
    // confusion matrix
    let mut labels: Vec<&str> = EFFECTS.to_vec();
    labels.push("none");
    labels.push("several");
    s += "\nconfusion (rows: hidden effect, columns: named; `several` = more than one effect named)\n";
    s += &format!("{:<20}", "");
    for (j, _) in labels.iter().enumerate() {
        s += &format!("{:>4}", j);
    }
    s += "\n";
    for (i, t) in labels.iter().enumerate() {
        if !rows.iter().any(|r| r.truth == *t) {
            continue;
        }
        s += &format!("{:<16}{:>4}", t, i);
        for n in &labels {
            let k = rows
                .iter()
                .filter(|r| {
                    r.truth == *t && (r.named == *n || (*n == "several" && r.named.contains('+')))
                })
                .count();
            s += &format!(
                "{:>4}",
                if k == 0 {
                    ".".to_string()
                } else {
                    k.to_string()
                }
            );
        }
        s += "\n";
    }
    let effect_rows: Vec<&ProofRow> = rows.iter().filter(|r| r.truth != "none").collect();
    let nulls: Vec<&ProofRow> = rows.iter().filter(|r| r.truth == "none").collect();
    let correct = rows.iter().filter(|r| r.correct).count();
    let false_disc = nulls.iter().filter(|r| r.named != "none").count();
    let mut red: Vec<f64> = effect_rows
        .iter()
        .map(|r| 1.0 - r.nrmse.1 / r.nrmse.0)
        .collect();
    red.sort_by(|a, b| a.total_cmp(b));
    let med = if red.is_empty() {
        f64::NAN
    } else {
        red[red.len() / 2]
    };
    let mut perr: Vec<f64> = effect_rows
        .iter()
        .filter(|r| r.correct)
        .filter_map(|r| r.parameter.as_ref().map(|p| p.3))
        .collect();
    perr.sort_by(|a, b| a.total_cmp(b));
    s += &format!(
        "\ncorrect {}/{} ({:.0} %); false discoveries on nulls {}/{}; median validation NRMSE reduction where an effect exists {:.1} %; median parameter error (correct cases) {:.0} %\n",
        correct,
        rows.len(),
        100.0 * correct as f64 / rows.len().max(1) as f64,
        false_disc,
        nulls.len(),
        100.0 * med,
        100.0 * perr.get(perr.len() / 2).copied().unwrap_or(f64::NAN)
    );
    s
}

/// Runs `diagnose-proof`.
pub fn proof(a: ProofArgs) -> Result<()> {
    let effects: Vec<&str> = match &a.only {
        Some(o) => o
            .split(',')
            .map(|s| s.trim())
            .filter(|s| !s.is_empty())
            .collect(),
        None => EFFECTS.to_vec(),
    };
    let rows = run_proof(
        &effects,
        a.cases,
        a.nulls.max(if a.only.is_some() { 0 } else { 4 }),
        a.seed,
        a.duration_s,
        Some(&a.out),
        true,
    )?;
    let table = proof_table(&rows);
    print!("{table}");
    std::fs::create_dir_all(&a.out)?;
    std::fs::write(a.out.join("proof.md"), format!("```\n{table}```\n"))?;
    std::fs::write(
        a.out.join("proof.json"),
        serde_json::to_string_pretty(&json!(rows))?,
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
) -> Result<super::lengths::LengthModes> {
    let (t, x, what) = crate::ident::cli::free_decay_of(path)?;
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
            .filter(|m| (m.freq_hz / (super::lengths::UNIFORM_F2_OVER_F1 * f1) - 1.0).abs() < 0.25)
            .min_by(|a, b| {
                (a.freq_hz / f1 - super::lengths::UNIFORM_F2_OVER_F1)
                    .abs()
                    .total_cmp(&(b.freq_hz / f1 - super::lengths::UNIFORM_F2_OVER_F1).abs())
            })
            .with_context(|| {
                format!(
                    "{}: no second bending mode within ±25 % of 6.27 × f1 = {:.2} Hz (modes found: {:?} Hz)",
                    path.display(),
                    super::lengths::UNIFORM_F2_OVER_F1 * f1,
                    r.modes.iter().map(|m| (m.freq_hz * 100.0).round() / 100.0).collect::<Vec<_>>()
                )
            })?;
        freq_hz.push((m2.freq_hz, m2.freq_hz_std));
    }
    Ok(super::lengths::LengthModes {
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
    let d = super::lengths::diagnose_lengths(
        &rig,
        &data,
        &super::lengths::LengthOptions {
            n_modes: a.modes,
            ..Default::default()
        },
    )?;
    pb.finish_and_clear();
    print!("\n{}", super::lengths::words(&d));
    println!("({:.1} s)", t0.elapsed().as_secs_f64());
    if let Some(j) = &a.json {
        std::fs::write(
            j,
            serde_json::to_string_pretty(&super::lengths::to_json(&d))?,
        )
        .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}
