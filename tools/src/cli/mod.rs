//! The command-line layer: the ONLY place that parses arguments, prints, writes files or draws
//! progress (an `indicatif` bar on a terminal, one line per stage otherwise).
//!
//! One file per command group. Each maps its clap arguments to the library's typed options,
//! calls the library, and shows what came back. Nothing under `tools/src` outside this module and
//! `main.rs` imports it (checked by `tests/layout.rs`).

mod allocator;
pub mod board;
pub mod bootstrap;
pub mod diagnose;
pub mod ident;
mod identbench;
pub mod klipper;
pub mod model;
pub mod oma;
pub mod paper;
pub mod read;
pub mod ringdown;
pub mod truth;
pub mod tune;
pub mod watch;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// beamtool: model, identify, shape and verify a flexible beam on a linear-motor carriage.
#[derive(Parser)]
#[command(name = "beamtool", version, about)]
pub struct Cli {
    /// The command.
    #[command(subcommand)]
    pub command: Command,
}

/// Every command of `beamtool`.
#[derive(Subcommand)]
pub enum Command {
    /// The main job: recording -> modes -> shaper -> board -> verified move (generates a
    /// recording from the reference rig and uses a virtual board when given nothing).
    Tune(tune::TuneArgs),
    /// Run the virtual board (the firmware core on the host) on a pseudo-terminal.
    Vboard(board::VboardArgs),
    /// Send console commands to a board (real or virtual) and print the replies.
    Console(board::ConsoleArgs),
    /// Design a (multi-mode) input shaper and print its impulse table and sensitivity.
    Shaper(board::ShaperArgs),
    /// Simulate the beam on its moving base for a move or a command CSV (paper §2).
    Simulate(crate::cli::model::SimulateArgs),
    /// Natural frequencies, damping, participation and mode shapes of a rig.
    Modes(crate::cli::model::ModesArgs),
    /// Reproduce the paper's Table 2 and Figs. 6-9 in simulation.
    Table2(crate::cli::paper::Table2Args),
    /// Benchmark the simulator against scipy.signal.lsim (needs python3 with scipy).
    BenchSim(crate::cli::paper::BenchArgs),
    /// Identify natural frequencies and damping ratios from a free decay (.npy or CSV).
    Identify(crate::cli::ident::IdentifyArgs),
    /// Make a sine-sweep excitation (eqs. 33-34) as a command CSV, within stroke/accel/tip
    /// limits; with --port, run it on the board so a camera can record it.
    Sweep(board::SweepCmd),
    /// Welch H1/H2/coherence FRF of a recording (paper Step 2).
    Frf(crate::cli::ident::FrfArgs),
    /// Reproduce the paper's Table 1 (sweep identification) on the simulated rig.
    Table1(crate::cli::paper::Table1Args),
    /// Model-discrepancy diagnosis: locate the mismatch, name the missing physics, refit, validate.
    Diagnose(crate::cli::diagnose::DiagnoseArgs),
    /// Diagnosis across a length series of free decays (one beam clamped at several lengths).
    DiagnoseLengths(crate::cli::diagnose::LengthsArgs),
    /// Prove the diagnosis on concealed effects from the truth generator (confusion table).
    DiagnoseProof(crate::cli::diagnose::ProofArgs),
    /// Write one truth-generator case (rig + fit/validation recordings with a hidden effect).
    Truth(crate::cli::truth::TruthArgs),
    /// Benchmark reading a recording (rows/s, MB/s, peak RSS) beside a peer (python3's csv).
    BenchRead(crate::cli::read::BenchReadArgs),
    /// Score our spectrum designs against Klipper's own recommendation on Klipper spectrum
    /// files (resonances_*.csv, calibration_data_*.csv), by Klipper's metrics.
    KlipperCompare(crate::cli::klipper::KlipperCompareArgs),
    /// Coverage of the output-only (SSI-cov) ±2σ on synthetic recordings with known modes.
    OmaCoverage(crate::cli::oma::OmaCoverageArgs),
    /// Poll a board's drift watch after each move: print, write a CSV and an SVG of f1 over
    /// the moves against the band.
    Watch(crate::cli::watch::WatchArgs),
    /// Coverage of the pooled ring-down path's ±2σ on synthetic closed-loop recordings.
    RingdownCoverage(crate::cli::ringdown::RingdownCoverageArgs),
    /// The diagnosis' decision rule on null replicates of your recordings (parametric bootstrap
    /// of the calibrated no-effect model): false alarms and the p-values' uniformity.
    DiagnoseBootstrap(crate::cli::bootstrap::BootstrapArgs),
}

/// Runs one command: one arm per command (keep one line per arm where possible, append new
/// arms at the end, so that merges stay trivial).
pub fn run(command: Command) -> Result<()> {
    allocator::keep_freed_memory();
    match command {
        Command::Tune(a) => klipper::run_tune(a),
        Command::Vboard(a) => board::vboard(a),
        Command::Console(a) => board::console(a),
        Command::Shaper(a) => board::shaper(a),
        Command::Simulate(mut a) => {
            default_rig(&mut a.rig)?;
            crate::cli::model::simulate(a)
        }
        Command::Modes(mut a) => {
            default_rig(&mut a.rig)?;
            crate::cli::model::modes(a)
        }
        Command::Table2(mut a) => {
            default_rig(&mut a.rig)?;
            crate::cli::paper::table2(a)
        }
        Command::Identify(a) => crate::cli::ident::identify(a),
        Command::Sweep(a) => board::sweep(a),
        Command::Frf(a) => crate::cli::ident::frf(a),
        Command::Table1(mut a) => {
            default_rig(&mut a.rig)?;
            crate::cli::paper::table1(a)
        }
        Command::Diagnose(a) => crate::cli::diagnose::diagnose(a),
        Command::DiagnoseProof(a) => crate::cli::diagnose::proof(a),
        Command::DiagnoseLengths(a) => crate::cli::diagnose::diagnose_lengths(a),
        Command::Truth(a) => crate::cli::truth::truth(a),
        Command::BenchSim(mut a) => {
            default_rig(&mut a.rig)?;
            crate::cli::paper::bench_sim(a)
        }
        Command::BenchRead(a) => crate::cli::read::bench_read(a),
        Command::KlipperCompare(a) => crate::cli::klipper::klipper_compare(a),
        Command::OmaCoverage(a) => crate::cli::oma::oma_coverage(a),
        Command::Watch(a) => crate::cli::watch::watch(a),
        Command::RingdownCoverage(a) => crate::cli::ringdown::ringdown_coverage_cmd(a),
        Command::DiagnoseBootstrap(a) => crate::cli::bootstrap::bootstrap(a),
    }
}

/// A finite number (clap value parser): refuses NaN and ±inf with a clear message.
pub fn finite_f64(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("`{s}` is not a finite number")),
        Err(_) => Err(format!("`{s}` is not a number")),
    }
}

/// Reads a recording CSV onto a uniform time base ([`crate::recording::Recording::read_csv`]) and prints what
/// was mended on the way (`note: FILE: …` on stderr).
pub fn read_recording(path: &std::path::Path) -> Result<crate::recording::Recording> {
    read_recording_with(path, &Default::default())
}

/// [`read_recording`] with the reading options `opts` (`--columns`, `--axis`).
pub fn read_recording_with(
    path: &std::path::Path,
    opts: &crate::recording::ReadOptions,
) -> Result<crate::recording::Recording> {
    let rec = crate::recording::Recording::read_csv_with(path, opts)?;
    print_notes(path, &rec.notes);
    Ok(rec)
}

/// Prints notes on the recording at `path` (`note: FILE: …` on stderr).
pub fn print_notes(path: &std::path::Path, notes: &[String]) {
    for n in notes {
        eprintln!("note: {}: {n}", path.display());
    }
}

/// The commands' default `--rig ../rigs/paper.toml` is relative to `tools/`. From any other
/// directory: the `rigs/paper.toml` beside the binary (its checkout), else the built-in copy,
/// written once to one file in the temporary directory (replaced atomically when its content
/// differs, so concurrent runs never read a half-written file and runs leave no file each).
pub fn default_rig(rig: &mut PathBuf) -> Result<()> {
    if rig.as_path() != std::path::Path::new("../rigs/paper.toml") || rig.exists() {
        return Ok(());
    }
    let beside = std::env::current_exe().ok().and_then(|exe| {
        exe.ancestors()
            .map(|d| d.join("rigs/paper.toml"))
            .find(|p| p.exists())
    });
    *rig = match beside {
        Some(p) => p,
        None => {
            let p = std::env::temp_dir().join("beamtool-built-in-paper-rig.toml");
            let current = std::fs::read_to_string(&p).ok();
            if current.as_deref() != Some(crate::tune::DEFAULT_RIG_TOML) {
                let part = p.with_extension(format!("toml.{}", std::process::id()));
                std::fs::write(&part, crate::tune::DEFAULT_RIG_TOML)
                    .and_then(|()| std::fs::rename(&part, &p))
                    .with_context(|| format!("cannot write the built-in rig to {}", p.display()))?;
            }
            p
        }
    };
    Ok(())
}
