use anyhow::{Context, Result};
use beamshaper::shaper::{design, insensitivity_band, residual_vibration, Shaper, ShaperKind};
use beamtools::board;
use clap::{Args, Parser, Subcommand};
use serialport::SerialPort;
use std::path::PathBuf;

/// beamtool: model, identify, shape and verify a flexible beam on a linear-motor carriage.
#[derive(Parser)]
#[command(name = "beamtool", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job: recording -> modes -> shaper -> board -> verified move (generates a
    /// recording from the reference rig and uses a virtual board when given nothing).
    Tune(beamtools::tune::TuneArgs),
    /// Run the virtual board (the firmware core on the host) on a pseudo-terminal.
    Vboard(VboardArgs),
    /// Send console commands to a board (real or virtual) and print the replies.
    Console(ConsoleArgs),
    /// Design a (multi-mode) input shaper and print its impulse table and sensitivity.
    Shaper(ShaperArgs),
    /// Simulate the beam on its moving base for a move or a command CSV (paper §2).
    Simulate(beamtools::model::cli::SimulateArgs),
    /// Natural frequencies, damping, participation and mode shapes of a rig.
    Modes(beamtools::model::cli::ModesArgs),
    /// Reproduce the paper's Table 2 and Figs. 6-9 in simulation.
    Table2(beamtools::model::cli::Table2Args),
    /// Benchmark the simulator against scipy.signal.lsim (needs python3 with scipy).
    BenchSim(beamtools::model::bench::BenchArgs),
    /// Identify natural frequencies and damping ratios from a free decay (.npy or CSV).
    Identify(beamtools::ident::cli::IdentifyArgs),
    /// Make a sine-sweep excitation (eqs. 33-34) as a command CSV, within stroke/accel/tip
    /// limits; with --port, run it on the board so a camera can record it.
    Sweep(SweepCmd),
    /// Welch H1/H2/coherence FRF of a recording (paper Step 2).
    Frf(beamtools::ident::cli::FrfArgs),
    /// Reproduce the paper's Table 1 (sweep identification) on the simulated rig.
    Table1(beamtools::ident::cli::Table1Args),
    /// Model-discrepancy diagnosis: locate the mismatch, name the missing physics, refit, validate.
    Diagnose(beamtools::cli::diagnose::DiagnoseArgs),
    /// Diagnosis across a length series of free decays (one beam clamped at several lengths).
    DiagnoseLengths(beamtools::cli::diagnose::LengthsArgs),
    /// Prove the diagnosis on concealed effects from the truth generator (confusion table).
    DiagnoseProof(beamtools::cli::diagnose::ProofArgs),
    /// Write one truth-generator case (rig + fit/validation recordings with a hidden effect).
    Truth(beamtools::cli::truth::TruthArgs),
}

#[derive(Args)]
struct VboardArgs {
    /// File that emulates the board's settings flash.
    #[arg(long, default_value = "vboard-flash.bin")]
    flash: PathBuf,
    /// Also create this symlink to the pseudo-terminal (e.g. /tmp/ttyBEAM).
    #[arg(long)]
    link: Option<PathBuf>,
    /// Run the tick loop this many times faster than real time (0.001 to 1000).
    #[arg(long, default_value_t = 1.0, value_parser = parse_time_scale)]
    time_scale: f64,
    /// Attach a virtual rig (beam of this rig TOML on a servo carriage, camera on the tip)
    /// to the setpoint output; its camera writes --sensor-out.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Where the rig's camera writes what it saw (recording CSV, board time).
    #[arg(long, default_value = "vboard-camera.csv")]
    sensor_out: PathBuf,
    /// Camera noise, 1 sigma (micrometres).
    #[arg(long, default_value_t = 20.0, value_parser = beamtools::tune::finite_f64)]
    camera_noise_um: f64,
    /// Camera latency (ms).
    #[arg(long, default_value_t = 20.0, value_parser = beamtools::tune::finite_f64)]
    camera_latency_ms: f64,
}

#[derive(Args)]
struct SweepCmd {
    #[command(flatten)]
    design: beamtools::ident::cli::SweepArgs,
    /// Run the sweep on this board (its own reference generator) instead of writing a CSV.
    #[arg(long)]
    port: Option<String>,
}

#[derive(Args)]
struct ConsoleArgs {
    /// Serial port of the board (e.g. /dev/ttyACM0, or the path `vboard` printed).
    #[arg(long)]
    port: String,
    /// Console lines to send, in order (e.g. "mode 1 zvd 1.1 0.0074" status).
    lines: Vec<String>,
}

#[derive(Args)]
struct ShaperArgs {
    /// Shaper kind: zv, zvd, zvdd, zvddd, mzv, ei, 2hei, 3hei, umzv.
    #[arg(long, default_value = "zvd")]
    kind: String,
    /// Natural frequency of mode 1 (Hz).
    #[arg(long)]
    freq_hz: f64,
    /// Damping ratio of mode 1.
    #[arg(long, default_value_t = 0.0)]
    zeta: f64,
    /// Natural frequency of mode 2 (Hz): convolve a second shaper of the same kind.
    #[arg(long)]
    freq2_hz: Option<f64>,
    /// Damping ratio of mode 2 (default: same as mode 1).
    #[arg(long)]
    zeta2: Option<f64>,
    /// Vibration tolerance of the EI kinds and of the insensitivity band (fraction).
    #[arg(long, default_value_t = 0.05)]
    v_tol: f64,
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli.command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Tune(a) => beamtools::tune::tune(a).map(|_| ()),
        Command::Vboard(a) => vboard(a),
        Command::Console(a) => console(a),
        Command::Shaper(a) => shaper(a),
        Command::Simulate(mut a) => {
            default_rig(&mut a.rig)?;
            beamtools::model::cli::simulate(a)
        }
        Command::Modes(mut a) => {
            default_rig(&mut a.rig)?;
            beamtools::model::cli::modes(a)
        }
        Command::Table2(mut a) => {
            default_rig(&mut a.rig)?;
            beamtools::model::cli::table2(a)
        }
        Command::Identify(a) => beamtools::ident::cli::identify(a),
        Command::Sweep(SweepCmd { design, port: None }) => beamtools::ident::cli::sweep(design),
        Command::Sweep(SweepCmd {
            design,
            port: Some(p),
        }) => {
            println!(
                "sweeping on {p}; record base and tip now (the sweep is sized and checked first)"
            );
            let plan = beamtools::tune::board_sweep(&design, &p)?;
            println!(
                "done: {} sweep {}-{} Hz, amplitude {:.3} mm, {:.1} s ({:.0} steps/s peak); give the recording to `beamtool tune --port {p} RECORDING`",
                plan.kind.name(), plan.f0_hz, plan.f1_hz, plan.amplitude_mm, plan.duration_s, plan.peak_step_rate_hz
            );
            Ok(())
        }
        Command::Frf(a) => beamtools::ident::cli::frf(a),
        Command::Table1(mut a) => {
            default_rig(&mut a.rig)?;
            beamtools::ident::cli::table1(a)
        }
        Command::Diagnose(a) => beamtools::cli::diagnose::diagnose(a),
        Command::DiagnoseProof(a) => beamtools::cli::diagnose::proof(a),
        Command::DiagnoseLengths(a) => beamtools::cli::diagnose::diagnose_lengths(a),
        Command::Truth(a) => beamtools::cli::truth::truth(a),
        Command::BenchSim(mut a) => {
            default_rig(&mut a.rig)?;
            beamtools::model::bench::bench_sim(a)
        }
    }
}

fn parse_time_scale(s: &str) -> std::result::Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    board::check_time_scale(v)
}

/// The commands' default `--rig ../rigs/paper.toml` is relative to `tools/`. From any other
/// directory: the `rigs/paper.toml` beside the binary (its checkout), else the built-in copy.
fn default_rig(rig: &mut PathBuf) -> Result<()> {
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
            let p =
                std::env::temp_dir().join(format!("beamtool-paper-{}.toml", std::process::id()));
            std::fs::write(&p, beamtools::tune::DEFAULT_RIG_TOML)
                .with_context(|| format!("cannot write the built-in rig to {}", p.display()))?;
            p
        }
    };
    Ok(())
}

fn vboard(a: VboardArgs) -> Result<()> {
    let (mut master, slave) =
        serialport::TTYPort::pair().context("cannot create a pseudo-terminal")?;
    let path = slave.name().context("pseudo-terminal has no name")?;
    if let Some(link) = &a.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link)
            .with_context(|| format!("cannot create {}", link.display()))?;
    }
    println!(
        "virtual board console on {path} (115200 8N1); flash file {}; Ctrl-C to stop",
        a.flash.display()
    );
    let mut boot = String::new();
    let mut b = board::VirtualBoard::boot(Some(a.flash), &mut boot);
    if let Some(rig_path) = &a.rig {
        let rig = beamtools::model::Rig::from_toml_file(rig_path)
            .with_context(|| format!("rig file {}", rig_path.display()))?;
        let mut sensors = board::rig::RigSensors::camera(&rig);
        sensors.noise_m = a.camera_noise_um * 1e-6;
        sensors.latency_s = a.camera_latency_ms * 1e-3;
        let r = board::rig::VirtualRig::new(
            &rig,
            sensors,
            b.runtime().tick_rate_hz() as f64,
            &a.sensor_out,
        )?;
        b.attach_rig(r);
        println!(
            "virtual rig {} attached; its camera writes {}",
            rig_path.display(),
            a.sensor_out.display()
        );
    }
    print!("{boot}");
    b.serve(&mut master, a.time_scale)
}

fn console(a: ConsoleArgs) -> Result<()> {
    let mut c = board::client::BoardClient::open(&a.port)?;
    for line in &a.lines {
        let r = c.command(line)?;
        for i in &r.info {
            println!("# {i}");
        }
        println!("{}", r.ok);
    }
    Ok(())
}

fn shaper(a: ShaperArgs) -> Result<()> {
    let kind = ShaperKind::from_name(&a.kind, a.v_tol)
        .with_context(|| format!("unknown shaper kind `{}`", a.kind))?;
    let mut s: Shaper =
        design(kind, a.freq_hz, a.zeta).map_err(|e| anyhow::anyhow!("mode 1: {}", e.message()))?;
    let mut modes = vec![(a.freq_hz, a.zeta)];
    if let Some(f2) = a.freq2_hz {
        let z2 = a.zeta2.unwrap_or(a.zeta);
        let s2 = design(kind, f2, z2).map_err(|e| anyhow::anyhow!("mode 2: {}", e.message()))?;
        s = s
            .convolve(&s2)
            .map_err(|e| anyhow::anyhow!("{}", e.message()))?;
        modes.push((f2, z2));
    }
    println!(
        "{} shaper, {} impulses, duration {:.6} s",
        kind.name().to_uppercase(),
        s.len(),
        s.duration_s()
    );
    println!("{:>4} {:>22} {:>22}", "i", "amplitude", "time_s");
    for (i, imp) in s.impulses().iter().enumerate() {
        println!("{:>4} {:>22} {:>22}", i + 1, imp.amplitude, imp.time_s);
    }
    for (i, &(f, z)) in modes.iter().enumerate() {
        let v = |r: f64| 100.0 * residual_vibration(&s, r * f, z);
        print!(
            "mode {}: f = {f} Hz, zeta = {z}: V(-10 %) = {:.3} %, V(0) = {:.3} %, V(+10 %) = {:.3} %",
            i + 1,
            v(0.9),
            v(1.0),
            v(1.1)
        );
        match insensitivity_band(&s, f, z, a.v_tol) {
            Some((lo, hi)) => println!(
                ", V <= {} % on {lo:.4}..{hi:.4} Hz (width {:.1} %)",
                100.0 * a.v_tol,
                100.0 * (hi - lo) / f
            ),
            None => println!(", V > {} % at the design frequency", 100.0 * a.v_tol),
        }
    }
    let mut line = String::from("console: custom");
    for imp in s.impulses() {
        line.push_str(&format!(" {}@{}", imp.amplitude, imp.time_s));
    }
    if s.len() <= beamshaper::config::MAX_CUSTOM_IMPULSES {
        println!("{line}");
    }
    Ok(())
}
