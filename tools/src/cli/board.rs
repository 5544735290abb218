//! Board commands: `vboard` (the virtual board on a pseudo-terminal, optionally with a virtual
//! rig), `console` (send lines, print replies), `shaper` (design through the core and print
//! the table and its sensitivity) and `sweep --port` (run a sweep on a board).

use super::finite_f64;
use crate::board;
use crate::board::session::{Command, Session};
use crate::board::steps::{sweep_on_board, SweepRequest};
use anyhow::{Context, Result};
use beamshaper::reference::SweepKind;
use beamshaper::shaper::{design, insensitivity_band, residual_vibration, Shaper, ShaperKind};
use clap::Args;
use serialport::SerialPort;
use std::path::PathBuf;

/// `vboard` arguments.
#[derive(Args)]
pub struct VboardArgs {
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
    #[arg(long, default_value_t = 20.0, value_parser = finite_f64)]
    camera_noise_um: f64,
    /// Camera latency (ms).
    #[arg(long, default_value_t = 20.0, value_parser = finite_f64)]
    camera_latency_ms: f64,
    /// Put a simulated ADXL345 (3 200 Hz, ±16 g, 3.9 mg/LSB) on the rig's tip; the board's
    /// drift watch (`watch on`) reads it.
    #[arg(long)]
    accel: bool,
    /// The simulated accelerometer's noise, 1 sigma (m/s²).
    #[arg(long, default_value_t = board::accel::ADXL345_NOISE_M_S2, value_parser = finite_f64)]
    accel_noise_m_s2: f64,
    /// Change the rig at a board time: `tip_mass_kg=X@T` or `stiffness_scale=S@T` (T in board
    /// seconds; repeatable; works with --time-scale).
    #[arg(long)]
    drift: Vec<board::accel::Drift>,
}

/// `sweep` arguments: the sweep design, and a board to run it on.
#[derive(Args)]
pub struct SweepCmd {
    #[command(flatten)]
    design: crate::cli::ident::SweepArgs,
    /// Run the sweep on this board (its own reference generator) instead of writing a CSV.
    #[arg(long)]
    port: Option<String>,
}

/// `console` arguments.
#[derive(Args)]
pub struct ConsoleArgs {
    /// Serial port of the board (e.g. /dev/ttyACM0, or the path `vboard` printed).
    #[arg(long)]
    port: String,
    /// Console lines to send, in order (e.g. "mode 1 zvd 1.1 0.0074" status).
    lines: Vec<String>,
}

/// `shaper` arguments.
#[derive(Args)]
pub struct ShaperArgs {
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

fn parse_time_scale(s: &str) -> std::result::Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    board::check_time_scale(v)
}

/// `beamtool vboard`: serves the virtual board on a new pseudo-terminal until killed.
pub fn vboard(a: VboardArgs) -> Result<()> {
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
    let mut b = board::VirtualBoard::boot(Some(a.flash.clone()), &mut boot);
    if let Some(rig_path) = &a.rig {
        b.attach_rig(virtual_rig(
            &a,
            rig_path,
            b.runtime().tick_rate_hz() as f64,
        )?);
        println!(
            "virtual rig {} attached; its camera writes {}",
            rig_path.display(),
            a.sensor_out.display()
        );
    }
    print!("{boot}");
    Ok(b.serve(&mut master, a.time_scale)?)
}

/// The virtual rig of `rig_path` with the camera options of `a`.
fn virtual_rig(a: &VboardArgs, rig_path: &PathBuf, tick_hz: f64) -> Result<board::rig::VirtualRig> {
    let rig = crate::model::Rig::from_toml_file(rig_path)
        .with_context(|| format!("rig file {}", rig_path.display()))?;
    let mut sensors = board::rig::RigSensors::camera(&rig);
    sensors.noise_m = a.camera_noise_um * 1e-6;
    sensors.latency_s = a.camera_latency_ms * 1e-3;
    let mut vr = board::rig::VirtualRig::new(&rig, sensors, tick_hz, &a.sensor_out)?;
    if a.accel {
        vr.attach_accel(board::accel::AccelSim::new(
            board::accel::adxl345(),
            a.accel_noise_m_s2.max(0.0),
            0.3,
            1.0 / tick_hz,
            7,
        ));
        println!(
            "simulated ADXL345 on the tip (noise {} m/s^2)",
            a.accel_noise_m_s2
        );
    }
    for d in &a.drift {
        println!("drift at board time {} s: {:?}", d.at_s, d.change);
    }
    vr.schedule_drifts(&a.drift);
    Ok(vr)
}

/// `beamtool console`: sends each line, prints the info lines (`# …`) and the final line.
pub fn console(a: ConsoleArgs) -> Result<()> {
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

/// `beamtool sweep`: a command CSV, or with `--port` the sweep run on the board.
pub fn sweep(a: SweepCmd) -> Result<()> {
    let Some(p) = a.port else {
        return crate::cli::ident::sweep(a.design);
    };
    let spec = a.design.spec()?;
    let request = SweepRequest {
        kind: match spec.kind {
            crate::ident::sweep::SweepKind::Exponential => SweepKind::Exponential,
            crate::ident::sweep::SweepKind::Linear => SweepKind::Linear,
        },
        f_a_hz: spec.f_a_hz,
        f_b_hz: spec.f_b_hz,
        rate: spec.rate,
        stroke_mm: a.design.stroke_mm,
        accel_max_m_s2: spec.accel_max_m_s2,
    };
    println!("sweeping on {p}; record base and tip now (the sweep is sized and checked first)");
    let plan = sweep_on_board(&mut Session::open(&p)?, &request)?;
    println!(
        "done: {} sweep {}-{} Hz, amplitude {:.3} mm, {:.1} s ({:.0} steps/s peak); give the recording to `beamtool tune --port {p} RECORDING`",
        plan.kind.name(), plan.f0_hz, plan.f1_hz, plan.amplitude_mm, plan.duration_s, plan.peak_step_rate_hz
    );
    Ok(())
}

/// `beamtool shaper`: designs through the core (mode 1, and mode 2 convolved), prints the
/// impulse table, V at ±10 % and the insensitivity band per mode, and the `custom` line.
pub fn shaper(a: ShaperArgs) -> Result<()> {
    let kind = ShaperKind::from_name(&a.kind, a.v_tol)
        .with_context(|| format!("unknown shaper kind `{}`", a.kind))?;
    let (s, modes) = designed(&a, kind)?;
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
        print_mode_sensitivity(&s, i, f, z, a.v_tol);
    }
    // The console line that programs this table, written by the core's protocol type (when
    // the board's custom list can hold it).
    if let Ok(list) = heapless::Vec::from_slice(s.impulses()) {
        println!("console: {}", Command::Custom(list));
    }
    Ok(())
}

/// The core's design for mode 1, convolved with mode 2's when given; the modes (Hz, ζ).
fn designed(a: &ShaperArgs, kind: ShaperKind) -> Result<(Shaper, Vec<(f64, f64)>)> {
    let mut s =
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
    Ok((s, modes))
}

/// One line per mode: V at −10 %, 0, +10 % and the band where V ≤ `v_tol`.
fn print_mode_sensitivity(s: &Shaper, i: usize, f: f64, z: f64, v_tol: f64) {
    let v = |r: f64| 100.0 * residual_vibration(s, r * f, z);
    print!(
        "mode {}: f = {f} Hz, zeta = {z}: V(-10 %) = {:.3} %, V(0) = {:.3} %, V(+10 %) = {:.3} %",
        i + 1,
        v(0.9),
        v(1.0),
        v(1.1)
    );
    match insensitivity_band(s, f, z, v_tol) {
        Some((lo, hi)) => println!(
            ", V <= {} % on {lo:.4}..{hi:.4} Hz (width {:.1} %)",
            100.0 * v_tol,
            100.0 * (hi - lo) / f
        ),
        None => println!(", V > {} % at the design frequency", 100.0 * v_tol),
    }
}
