//! The main job end to end: recording → modes → shaper → board → verified move.
//!
//! 1. **Recording**: a recording CSV or `.npy` free decay; with none, one is generated from
//!    the reference rig (an unshaped 0 → 50 mm move and its ring-down, 100 Hz camera-like
//!    sampling with 20 µm Gaussian noise).
//! 2. **Identify** the modes ([`crate::ident::freedecay`]) with their 1-σ uncertainty.
//! 3. **Design**: every shaper kind of the core, for mode 1 alone and for modes 1 + 2
//!    (convolution), is checked over the uncertainty band (f ± 2σ_f, ζ ± 2σ_ζ, at least
//!    ±`min_band_pct`) of **every** identified mode; the shortest one whose worst-case
//!    percentage vibration stays under the tolerance wins.
//! 4. **Program** the board over its serial console (a real port, or the virtual board on a
//!    PTY through the same `serialport` code), read the table back and compare it.
//! 5. **Verify**: a 0 → 50 mm move on the board, its setpoints captured and read back, fed
//!    to the simulator (the rig model, or a modal model of the identified modes), measured
//!    against the unshaped move; then `save`. Any failure before `save` leaves the board's
//!    saved configuration as it was.

use crate::board::client::BoardClient;
use crate::ident::ModeEstimate;
use crate::measures::{measure, percentage_vibration};
use crate::model::cli::{decimate, SIM_RATE_HZ};
use crate::model::sim::BaseMotionSim;
use crate::model::{trapezoid_reference, BeamModel, ModelOptions, Rig};
use crate::plot::{lines, Series};
use anyhow::{anyhow, bail, Context, Result};
use beamshaper::shaper::{design, residual_vibration, Shaper, ShaperKind};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// `tune` arguments.
#[derive(Args, Debug)]
pub struct TuneArgs {
    /// Recording (CSV or .npy free decay). Without it one is generated from --rig.
    pub recording: Option<PathBuf>,
    /// Rig file for generation and verification (default: the shipped reference rig).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Percentage-vibration tolerance (%), over the whole uncertainty band.
    #[arg(long, default_value_t = 2.0)]
    pub tolerance_pct: f64,
    /// Minimum half-width of the frequency band checked (% of each frequency).
    #[arg(long, default_value_t = 2.0)]
    pub min_band_pct: f64,
    /// Serial port of a real board (e.g. /dev/ttyACM0); default: a virtual board on a PTY.
    #[arg(long)]
    pub port: Option<String>,
    /// Verification move target (mm), from the current position 0.
    #[arg(long, default_value_t = 50.0)]
    pub move_mm: f64,
    /// Verification move speed (mm/s).
    #[arg(long, default_value_t = 200.0)]
    pub speed_mm_s: f64,
    /// Verification move acceleration (mm/s²).
    #[arg(long, default_value_t = 2000.0)]
    pub accel_mm_s2: f64,
    /// Output directory (generated recording, plots, report JSON).
    #[arg(long, default_value = "tune-out")]
    pub out: PathBuf,
}

/// A candidate shaper: one kind per shaped mode.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// Description, e.g. `ZVD(1.100 Hz) * EI(6.900 Hz)`.
    pub name: String,
    /// Console lines that program it.
    pub console: Vec<String>,
    /// The shaper.
    pub shaper: Shaper,
    /// Worst-case percentage vibration over the bands of all modes (%).
    pub worst_pct: f64,
}

/// Worst V (%) of `s` over f ∈ [f(1−b), f(1+b)], ζ ∈ [ζ−2σ, ζ+2σ] of every mode.
pub fn worst_case_pct(s: &Shaper, modes: &[ModeEstimate], min_band: f64) -> f64 {
    let mut worst = 0.0f64;
    for m in modes {
        let half = (2.0 * m.freq_hz_std / m.freq_hz).max(min_band);
        let (z0, z1) = (
            (m.zeta - 2.0 * m.zeta_std).max(0.0),
            (m.zeta + 2.0 * m.zeta_std).min(0.99),
        );
        for i in 0..=60 {
            let f = m.freq_hz * (1.0 - half + 2.0 * half * i as f64 / 60.0);
            for z in [z0, m.zeta, z1] {
                worst = worst.max(100.0 * residual_vibration(s, f, z));
            }
        }
    }
    worst
}

/// All candidates (mode 1 alone; modes 1 and 2), sorted by duration; feasibility not filtered.
pub fn candidates(modes: &[ModeEstimate], v_tol: f64, min_band: f64) -> Vec<Candidate> {
    let mut out = Vec::new();
    let kinds = ShaperKind::all(v_tol.clamp(0.01, 0.2));
    let line = |slot: usize, k: ShaperKind, m: &ModeEstimate| {
        let mut l = format!("mode {slot} {} {} {}", k.name(), m.freq_hz, m.zeta);
        if let Some(v) = k.v_tol() {
            l.push_str(&format!(" {v}"));
        }
        l
    };
    for &k1 in &kinds {
        let Ok(s1) = design(k1, modes[0].freq_hz, modes[0].zeta) else {
            continue;
        };
        let name1 = format!("{}({:.3} Hz)", k1.name().to_uppercase(), modes[0].freq_hz);
        out.push(Candidate {
            name: name1.clone(),
            console: vec![line(1, k1, &modes[0])],
            worst_pct: worst_case_pct(&s1, modes, min_band),
            shaper: s1.clone(),
        });
        if let Some(m2) = modes.get(1) {
            for &k2 in &kinds {
                let Ok(s2) = design(k2, m2.freq_hz, m2.zeta) else {
                    continue;
                };
                let Ok(s) = s1.convolve(&s2) else { continue };
                out.push(Candidate {
                    name: format!(
                        "{name1} * {}({:.3} Hz)",
                        k2.name().to_uppercase(),
                        m2.freq_hz
                    ),
                    console: vec![line(1, k1, &modes[0]), line(2, k2, m2)],
                    worst_pct: worst_case_pct(&s, modes, min_band),
                    shaper: s,
                });
            }
        }
    }
    out.sort_by(|a, b| {
        a.shaper
            .duration_s()
            .total_cmp(&b.shaper.duration_s())
            .then(a.worst_pct.total_cmp(&b.worst_pct))
    });
    out
}

/// Generates the reference-rig recording: unshaped move and ring-down, 100 Hz, 20 µm noise.
pub fn generate_recording(rig: &Rig, path: &Path) -> Result<()> {
    let model = BeamModel::new(rig, &ModelOptions::default())?;
    let sim = BaseMotionSim::new(&model, 1.0 / SIM_RATE_HZ)?;
    let (y, _) = trapezoid_reference(0.0, 0.05, 0.2, 2.0, SIM_RATE_HZ, 30.0)?;
    let mut rec = decimate(&sim.recording(&y, 0.0), rig.sample_rate_hz());
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let noise = Normal::new(0.0, 20e-6).map_err(|e| anyhow!("{e}"))?;
    for v in rec.tip_pos_m.as_mut().into_iter().flatten() {
        *v += noise.sample(&mut rng);
    }
    rec.force_n = None;
    rec.write_csv(path)
}

fn bar(len: u64, msg: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>28} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_message(msg.to_string());
    pb
}

/// Programs `c` on the board and checks the read-back table. Does not save.
pub fn program(board: &mut BoardClient, c: &Candidate) -> Result<()> {
    board
        .command("clear all")
        .context("programming the board")?;
    board
        .command("custom clear")
        .context("programming the board")?;
    for l in &c.console {
        board
            .command(l)
            .with_context(|| format!("programming the board (`{l}`)"))?;
    }
    let reply = board.command("shaper").context("reading the table back")?;
    let imps = reply
        .field("impulses")
        .ok_or_else(|| anyhow!("malformed `shaper` reply (no impulses=): {}", reply.ok))?;
    let mut back = Vec::new();
    for p in imps.split(',') {
        let (a, t) = p
            .split_once('@')
            .ok_or_else(|| anyhow!("malformed impulse `{p}` in the read-back table"))?;
        let a: f64 = a
            .parse()
            .map_err(|_| anyhow!("malformed amplitude `{a}` in the read-back table"))?;
        let t: f64 = t
            .parse()
            .map_err(|_| anyhow!("malformed time `{t}` in the read-back table"))?;
        back.push((a, t));
    }
    if back.len() != c.shaper.len() {
        bail!(
            "read-back table has {} impulses, designed {}",
            back.len(),
            c.shaper.len()
        );
    }
    for ((a, t), i) in back.iter().zip(c.shaper.impulses()) {
        if (a - i.amplitude).abs() > 1e-12 || (t - i.time_s).abs() > 1e-12 {
            bail!(
                "read-back impulse {a}@{t} differs from the designed {}@{}",
                i.amplitude,
                i.time_s
            );
        }
    }
    Ok(())
}

/// Runs the move on the board and reads back the setpoints (m) captured every tick.
pub fn verification_move(
    board: &mut BoardClient,
    target_mm: f64,
    speed: f64,
    accel: f64,
    duration_s: f64,
) -> Result<(Vec<f64>, f64)> {
    let st = board.command("status")?;
    let tick_hz = st.number("tick_hz")?;
    let start_mm = st.number("setpoint_mm")?;
    if start_mm.abs() > 1e-6 {
        board
            .command("move 0")
            .context("returning to 0 before the verification move")?;
        wait_still(board, duration_s + 2.0, None)?;
        board.command("zero")?;
    }
    let cap = board.command("capture 1")?;
    let capacity = cap.number("capacity")? as usize;
    board.command(&format!("move {target_mm} {speed} {accel}"))?;
    let needed = ((target_mm.abs() / speed + speed / accel + duration_s) * tick_hz) as usize + 10;
    if needed > capacity {
        bail!("the move and shaper need {needed} ticks of capture, the board holds {capacity}");
    }
    wait_still(board, needed as f64 / tick_hz + 5.0, Some(capacity))?;
    let pb = bar(capacity as u64, "reading setpoints back");
    let mut sp = Vec::with_capacity(capacity);
    while sp.len() < capacity {
        let r = board.command(&format!("dump {} 32", sp.len()))?;
        let n = r.number("n")? as usize;
        if n == 0 {
            break;
        }
        let vals = r
            .field("values")
            .ok_or_else(|| anyhow!("malformed `dump` reply: {}", r.ok))?;
        for v in vals.split(',') {
            sp.push(
                v.parse::<i64>()
                    .map_err(|_| anyhow!("malformed setpoint `{v}` in `dump` reply"))?
                    as f64
                    * 1e-9,
            );
        }
        pb.set_position(sp.len() as u64);
    }
    pb.finish_and_clear();
    Ok((sp, tick_hz))
}

fn wait_still(board: &mut BoardClient, timeout_s: f64, capture_full: Option<usize>) -> Result<()> {
    let end = std::time::Instant::now() + Duration::from_secs_f64(timeout_s);
    loop {
        let s = board.command("status")?;
        let still = s.number("moving")? == 0.0
            && s.number("still_ticks")? > s.number("duration_ticks")? + 5.0;
        let full = match capture_full {
            Some(c) => board.command("dump 0 0")?.number("total")? as usize >= c,
            None => true,
        };
        if still && full {
            return Ok(());
        }
        if std::time::Instant::now() > end {
            bail!("board did not finish the move within {timeout_s:.0} s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The identified modes and how they were found.
pub struct IdentifiedModes {
    /// Physical modes, ascending in frequency, with 1-σ.
    pub modes: Vec<ModeEstimate>,
    /// The path taken and why, the mode table, rejected estimates and warnings (text).
    pub description: String,
}

/// The identification step: the recording at `path` (CSV, `.npy`, `.lvm` spectrum; a sweep,
/// a free decay or moves + ring-down, with gaps) → its physical modes
/// ([`crate::ident::identify::identify_file`] with default options).
pub fn identify_step(path: &Path) -> Result<IdentifiedModes> {
    let id = crate::ident::identify::identify_file(
        path,
        &crate::ident::IdentifyOptions::default(),
        &mut |_| {},
    )?;
    Ok(IdentifiedModes {
        description: crate::ident::report::identification_table(&id),
        modes: id.modes,
    })
}

/// `beamtool tune`.
pub fn tune(a: TuneArgs) -> Result<()> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let rig_path = a.rig.clone().unwrap_or_else(|| {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../rigs/paper.toml"))
    });
    // 1. Recording.
    let rec_path = match &a.recording {
        Some(p) => p.clone(),
        None => {
            let rig = Rig::from_toml_file(&rig_path)?;
            let p = a.out.join("generated-recording.csv");
            generate_recording(&rig, &p)?;
            println!("1. no recording given: generated {} from {} (unshaped 0 -> 50 mm move, 30 s ring-down, 100 Hz, 20 um noise)", p.display(), rig_path.display());
            p
        }
    };
    // 2. Identify.
    let id = identify_step(&rec_path)?;
    println!("2. identified from {}:", rec_path.display());
    for line in id.description.lines() {
        println!("   {line}");
    }
    let modes: Vec<ModeEstimate> = id.modes.iter().take(2).cloned().collect();
    // The board: its step resolution and maximum step rate bound the shaped speed.
    let port = match &a.port {
        Some(p) => p.clone(),
        None => {
            let flash = a.out.join("vboard-flash.bin");
            let p = crate::board::spawn_on_pty(Some(flash), 10.0)?;
            println!(
                "   no --port: virtual board on {p} (flash {}, 10x real time)",
                a.out.join("vboard-flash.bin").display()
            );
            p
        }
    };
    let mut board = BoardClient::open(&port)?;
    let cfg = board
        .command("config")
        .context("reading the board's configuration")?;
    let step_nm = cfg.number("step_nm")?;
    let max_rate = cfg.number("maxrate")?;
    let max_abs_sum = max_rate * step_nm * 1e-6 / a.speed_mm_s;
    // 3. Design.
    let tol = a.tolerance_pct;
    let all = candidates(&modes, tol / 100.0, a.min_band_pct / 100.0);
    let feasible: Vec<&Candidate> = all
        .iter()
        .filter(|c| {
            c.worst_pct <= tol
                && c.shaper.duration_s() * 1000.0 < 16_000.0
                && c.shaper.abs_amplitude_sum() <= max_abs_sum
        })
        .collect();
    let Some(best) = feasible.first().copied() else {
        bail!("no shaper keeps the percentage vibration under {tol} % over the band within the board's step rate ({max_rate} steps/s of {step_nm} nm at {} mm/s); loosen --tolerance-pct", a.speed_mm_s);
    };
    println!("3. shaper: {} — {} impulses, duration {:.4} s, worst-case V {:.2} % (tolerance {tol} % over f +-max(2 sd, {} %), zeta +-2 sd of {} mode(s))",
        best.name, best.shaper.len(), best.shaper.duration_s(), best.worst_pct, a.min_band_pct, modes.len());
    println!("   runner-ups (feasible, by duration):");
    for c in feasible.iter().skip(1).take(5) {
        println!(
            "     {:<40} duration {:.4} s, worst V {:.2} %",
            c.name,
            c.shaper.duration_s(),
            c.worst_pct
        );
    }
    let plot_f: Vec<f64> = (0..400)
        .map(|i| {
            0.02 + i as f64 * 0.005 * modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max) * 1.5
                / 2.0
        })
        .collect();
    let v_best: Vec<f64> = plot_f
        .iter()
        .map(|&f| 100.0 * residual_vibration(&best.shaper, f, modes[0].zeta))
        .collect();
    let mut curves = vec![Series {
        label: best.name.clone(),
        x: &plot_f,
        y: &v_best,
    }];
    let v_runner: Vec<f64>;
    if let Some(r) = feasible.get(1) {
        v_runner = plot_f
            .iter()
            .map(|&f| 100.0 * residual_vibration(&r.shaper, f, modes[0].zeta))
            .collect();
        curves.push(Series {
            label: r.name.clone(),
            x: &plot_f,
            y: &v_runner,
        });
    }
    lines(
        &a.out.join("sensitivity.svg"),
        "percentage vibration vs frequency",
        "frequency (Hz)",
        "V (%)",
        &curves,
        false,
    )?;
    println!("4. programming the board on {port}");
    program(&mut board, best).context("programming the board")?;
    println!(
        "   programmed {} and read the table back: {} impulses identical to the design",
        port,
        best.shaper.len()
    );
    // 5. Verify.
    let (sp, tick_hz) = verification_move(
        &mut board,
        a.move_mm,
        a.speed_mm_s,
        a.accel_mm_s2,
        best.shaper.duration_s(),
    )?;
    let target = a.move_mm * 1e-3;
    let (reference, ref_end) = trapezoid_reference(
        0.0,
        target,
        a.speed_mm_s * 1e-3,
        a.accel_mm_s2 * 1e-3,
        tick_hz,
        12.0,
    )?;
    let mut shaped = sp.clone();
    shaped.resize(reference.len(), target);
    let (tip_u, tip_s, sim_what) = simulate_pair(
        &rig_path,
        a.rig.is_some() || a.recording.is_none(),
        &modes,
        &reference,
        &shaped,
        tick_hz,
    )?;
    let tt: Vec<f64> = (0..reference.len()).map(|k| k as f64 / tick_hz).collect();
    let cmd_end = |y: &[f64]| {
        y.iter()
            .rposition(|v| (v - target).abs() > 1e-9)
            .map_or(0.0, |k| (k + 1) as f64 / tick_hz)
    };
    let band = 0.02 * target.abs();
    let mu = measure(
        &tt,
        &tip_u,
        0.0,
        target,
        cmd_end(&reference),
        ref_end as f64 / tick_hz,
        band,
    );
    let ms = measure(
        &tt,
        &tip_s,
        0.0,
        target,
        cmd_end(&shaped),
        ref_end as f64 / tick_hz,
        band,
    );
    let pv = percentage_vibration(&ms, &mu);
    let fmt_settle = |s: Option<f64>| s.map_or("> 12 s".to_string(), |v| format!("{v:.2} s"));
    println!("5. verification move 0 -> {} mm on the board ({} setpoints read back), simulated with {sim_what}:", a.move_mm, sp.len());
    println!(
        "   {:<10} {:>14} {:>14} {:>24}",
        "", "settling", "overshoot", "percentage vibration"
    );
    println!(
        "   {:<10} {:>14} {:>13.2}% {:>23.2}%",
        "unshaped",
        fmt_settle(mu.settling_s),
        mu.overshoot_pct,
        100.0
    );
    println!(
        "   {:<10} {:>14} {:>13.2}% {:>23.2}%",
        "shaped",
        fmt_settle(ms.settling_s),
        ms.overshoot_pct,
        pv
    );
    let mm = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
    let (a1, a2, a3) = (mm(&tip_u), mm(&tip_s), mm(&shaped));
    let n = tt.len().min((8.0 * tick_hz) as usize);
    lines(
        &a.out.join("verification.svg"),
        "verification move: tip position",
        "time (s)",
        "position (mm)",
        &[
            Series {
                label: "tip, unshaped".into(),
                x: &tt[..n],
                y: &a1[..n],
            },
            Series {
                label: "tip, shaped (board setpoints)".into(),
                x: &tt[..n],
                y: &a2[..n],
            },
            Series {
                label: "board setpoint".into(),
                x: &tt[..n],
                y: &a3[..n],
            },
        ],
        false,
    )?;
    let saved = board
        .command("save")
        .context("saving the configuration on the board")?;
    println!(
        "   saved on the board ({}); plots {}/sensitivity.svg, {}/verification.svg",
        saved.ok,
        a.out.display(),
        a.out.display()
    );
    let report = serde_json::json!({
        "modes": modes, "shaper": best.name, "console": best.console, "duration_s": best.shaper.duration_s(),
        "worst_case_vibration_pct": best.worst_pct, "tolerance_pct": tol,
        "verification": {"percentage_vibration_pct": pv, "overshoot_pct_shaped": ms.overshoot_pct, "overshoot_pct_unshaped": mu.overshoot_pct,
            "settling_s_shaped": ms.settling_s, "settling_s_unshaped": mu.settling_s},
    });
    std::fs::write(
        a.out.join("tune.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    println!(
        "done in {:.1} s; report {}",
        t0.elapsed().as_secs_f64(),
        a.out.join("tune.json").display()
    );
    if pv > tol * 1.5 {
        println!("WARNING: simulated percentage vibration {pv:.2} % exceeds the tolerance: the model and the identified modes disagree");
    }
    Ok(())
}

/// Tip responses (m) of the unshaped reference and the shaped setpoints: with the rig model,
/// or (`use_rig == false`) a modal model of the identified modes with the participation of a
/// uniform cantilever's modes (only the ratio shaped/unshaped is reported, so the absolute
/// scale does not matter).
fn simulate_pair(
    rig_path: &Path,
    use_rig: bool,
    modes: &[ModeEstimate],
    reference: &[f64],
    shaped: &[f64],
    tick_hz: f64,
) -> Result<(Vec<f64>, Vec<f64>, String)> {
    let dt = 1.0 / tick_hz;
    let tip = |y: &[f64], w: Vec<f64>| y.iter().zip(w).map(|(y, w)| y + w).collect::<Vec<f64>>();
    if use_rig {
        let rig = Rig::from_toml_file(rig_path)?;
        let model = BeamModel::new(&rig, &ModelOptions::default())?;
        let sim = BaseMotionSim::new(&model, dt)?;
        return Ok((
            tip(reference, sim.run(reference).0),
            tip(shaped, sim.run(shaped).0),
            format!("the rig model {}", rig_path.display()),
        ));
    }
    // Uniform cantilever: Γ_r·φ_r(l) per unit beam mass = 1.566, −0.867, 0.509 (effective tip participation).
    let weights = [1.566, -0.867, 0.509];
    let run = |y: &[f64]| -> Vec<f64> {
        let mut out = vec![0.0; y.len()];
        for (r, m) in modes.iter().enumerate().take(3) {
            let w = 2.0 * std::f64::consts::PI * m.freq_hz;
            let (phi, _) = crate::model::sim::mode_zoh(w, m.zeta, dt);
            let mut x = nalgebra::Vector2::zeros();
            for k in 0..y.len() {
                let vb = if k == 0 { 0.0 } else { (y[k] - y[k - 1]) / dt };
                let va = if k + 1 < y.len() {
                    (y[k + 1] - y[k]) / dt
                } else {
                    0.0
                };
                out[k] += x[0];
                x[1] -= weights[r] * (va - vb);
                x = phi * x;
            }
        }
        out
    };
    Ok((
        tip(reference, run(reference)),
        tip(shaped, run(shaped)),
        "a modal model of the identified modes".into(),
    ))
}
