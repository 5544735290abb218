//! `simulate` and `modes`: arguments, printing and files of the model commands over
//! [`crate::model`].

use crate::diagnose::model::spline_accel;
use crate::measures::measure;
use crate::model::sim::{BaseMotionSim, ForceSim};
use crate::model::SIM_RATE_HZ;
use crate::model::{shape_with_engine, trapezoid_reference, BeamModel, ModelOptions, Rig};
use crate::plot::{lines_svg, Series};
use crate::recording::{decimate, Recording};
use anyhow::{bail, Context, Result};
use beamshaper::engine::NumericPath;
use beamshaper::shaper::{design, Shaper, ShaperKind};
use clap::Args;
use std::path::{Path, PathBuf};

/// `simulate` arguments.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Rig file (TOML).
    #[arg(long, default_value = "../rigs/paper.toml")]
    pub rig: PathBuf,
    /// Move target (mm), from 0.
    #[arg(long, default_value_t = 50.0)]
    pub to_mm: f64,
    /// Move speed (mm/s).
    #[arg(long, default_value_t = 200.0)]
    pub speed_mm_s: f64,
    /// Move acceleration (mm/s²).
    #[arg(long, default_value_t = 2000.0)]
    pub accel_mm_s2: f64,
    /// Instead of a move: a CSV with `time_s,base_cmd_m` (uniform), played as the base position.
    #[arg(long)]
    pub command: Option<PathBuf>,
    /// Instead of a position command: a CSV with `time_s,force_n` (uniform), applied as the
    /// motor force to the FREE carriage (paper eqs. 12/23, zero-order hold).
    #[arg(long, conflicts_with_all = ["command", "shaper"])]
    pub force: Option<PathBuf>,
    /// Shaper kind for the move (zv, zvd, zvdd, …); none = unshaped.
    #[arg(long)]
    pub shaper: Option<String>,
    /// Natural frequency of mode 1 for the shaper (Hz).
    #[arg(long, default_value_t = 1.1)]
    pub freq_hz: f64,
    /// Natural frequency of mode 2 (Hz): two-mode shaper by convolution.
    #[arg(long)]
    pub freq2_hz: Option<f64>,
    /// Damping ratio for the shaper design.
    #[arg(long, default_value_t = 0.0074)]
    pub zeta: f64,
    /// Seconds to record after the move.
    #[arg(long, default_value_t = 8.0)]
    pub hold_s: f64,
    /// Basis functions of the Galerkin model.
    #[arg(long, default_value_t = 4)]
    pub modes: usize,
    /// Output recording CSV (sampled at the rig's sensor rate).
    #[arg(long, default_value = "sim.csv")]
    pub out: PathBuf,
    /// Plot (SVG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// `modes` arguments.
#[derive(Args, Debug)]
pub struct ModesArgs {
    /// Rig file (TOML).
    #[arg(long, default_value = "../rigs/paper.toml")]
    pub rig: PathBuf,
    /// Basis functions of the Galerkin model.
    #[arg(long, default_value_t = 6)]
    pub modes: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn shaper_for(kind: &str, f1: f64, f2: Option<f64>, zeta: f64) -> Result<Shaper> {
    let k = ShaperKind::from_name(kind, 0.05)
        .with_context(|| format!("unknown shaper kind `{kind}`"))?;
    let mut s = design(k, f1, zeta).map_err(|e| anyhow::anyhow!("{}", e.message()))?;
    if let Some(f2) = f2 {
        s = s
            .convolve(&design(k, f2, zeta).map_err(|e| anyhow::anyhow!("{}", e.message()))?)
            .map_err(|e| anyhow::anyhow!("{}", e.message()))?;
    }
    Ok(s)
}

/// `channel` of the uniform recording `rec` at [`SIM_RATE_HZ`]: `hold` = zero-order hold (a
/// force a drive applies until its next update), else the cubic spline through the samples
/// ([`spline_at`]).
fn at_sim_rate(rec: &Recording, channel: &[f64], hold: bool) -> Vec<f64> {
    let rate = rec.sample_rate_hz();
    let last = channel.len() - 1;
    let n = ((rec.len() - 1) as f64 * SIM_RATE_HZ / rate).round() as usize + 1;
    if !hold {
        return spline_at(channel, rate, n);
    }
    (0..n)
        .map(|k| {
            let pos = k as f64 * rate / SIM_RATE_HZ;
            channel[((pos + 1e-9).floor() as usize).min(last)]
        })
        .collect()
}

/// A position sampled at `rate` Hz (`y`, m) at the first `n` ticks of [`SIM_RATE_HZ`]: the
/// cubic spline through the samples, its knot accelerations [`spline_accel`] (de Boor, *A
/// Practical Guide to Splines*, ch. IV, the interpolant's standard form
/// `S = A y_i + B y_{i+1} + ((A³ − A) M_i + (B³ − B) M_{i+1}) h² / 6`, B the fraction of the
/// interval, A = 1 − B). The samples say nothing of the motion between them; the piecewise-linear
/// path (before December 2026) moves at constant velocity between them, so its whole velocity
/// change falls on the one fine tick at each sample — the carriage force at the samples, which
/// the output keeps, was then rate/[`SIM_RATE_HZ`]'s inverse × the acceleration (5 × for a
/// 200 Hz command: 79 N where the drive pushed 20 N). The spline's acceleration is continuous
/// and exact for a constant acceleration; a path at the internal rate is passed through as is.
fn spline_at(y: &[f64], rate: f64, n: usize) -> Vec<f64> {
    let h = 1.0 / rate;
    let m = spline_accel(y, h);
    let last = y.len() - 1;
    (0..n)
        .map(|k| {
            let pos = k as f64 * rate / SIM_RATE_HZ;
            let i = (pos.floor() as usize).min(last);
            if i == last {
                return y[last];
            }
            let b = pos - i as f64;
            let a = 1.0 - b;
            a * y[i]
                + b * y[i + 1]
                + ((a * a * a - a) * m[i] + (b * b * b - b) * m[i + 1]) * h * h / 6.0
        })
        .collect()
}

/// The base command at [`SIM_RATE_HZ`] (`--command` or the move) and its description.
fn command_of(a: &SimulateArgs) -> Result<(Vec<f64>, String)> {
    if let Some(p) = &a.command {
        let rec = super::read_recording(p)?;
        let cmd = rec
            .base_cmd_m
            .clone()
            .with_context(|| format!("{}: no base_cmd_m column", p.display()))?;
        return Ok((
            at_sim_rate(&rec, &cmd, false),
            format!("command {}", p.display()),
        ));
    }
    let (r, _) = trapezoid_reference(
        0.0,
        a.to_mm * 1e-3,
        a.speed_mm_s * 1e-3,
        a.accel_mm_s2 * 1e-3,
        SIM_RATE_HZ,
        a.hold_s,
    )?;
    let what = format!(
        "move 0 -> {} mm at {} mm/s, {} mm/s^2",
        a.to_mm, a.speed_mm_s, a.accel_mm_s2
    );
    Ok((r, what))
}

/// `y` shaped by `--shaper` (held at its end for the shaper's duration) and the description.
fn shaped(a: &SimulateArgs, y: Vec<f64>) -> Result<(Vec<f64>, String)> {
    let Some(kind) = &a.shaper else {
        return Ok((y, String::from(", unshaped")));
    };
    let s = shaper_for(kind, a.freq_hz, a.freq2_hz, a.zeta)?;
    let mut y = y;
    let hold = (s.duration_s() * SIM_RATE_HZ) as usize + 1;
    y.extend(std::iter::repeat(*y.last().unwrap_or(&0.0)).take(hold));
    let what = format!(
        ", shaped by {} ({} impulses, {:.3} s)",
        kind.to_uppercase(),
        s.len(),
        s.duration_s()
    );
    Ok((
        shape_with_engine(&s, SIM_RATE_HZ, &y, NumericPath::Fixed)?,
        what,
    ))
}

/// `beamtool simulate`.
pub fn simulate(a: SimulateArgs) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    let opts = ModelOptions {
        n_modes: a.modes,
        ..Default::default()
    };
    let model = BeamModel::new(&rig, &opts)?;
    if let Some(p) = &a.force {
        return simulate_force(&a, &rig, &model, p);
    }
    let (y, what) = command_of(&a)?;
    let (y, shaped) = shaped(&a, y)?;
    let sim = BaseMotionSim::new(&model, 1.0 / SIM_RATE_HZ)?;
    let rec = decimate(&sim.recording(&y, 0.0), rig.sample_rate_hz());
    rec.write_csv(&a.out)?;
    println!(
        "simulated {what}{shaped}: {} samples at {} Hz -> {}",
        rec.len(),
        rig.sample_rate_hz(),
        a.out.display()
    );
    let tip = rec.tip_pos_m.as_ref().context("internal: no tip channel")?;
    print_tip_measures(&rec.time_s, tip, &y);
    if let Some(p) = &a.plot {
        let base = rec
            .base_pos_m
            .as_ref()
            .context("internal: no base channel")?;
        plot_positions(p, &format!("{what}{shaped}"), &rec.time_s, base, tip)?;
    }
    Ok(())
}

/// Overshoot, residual and settling of the tip for the command `y` (at [`SIM_RATE_HZ`]), or
/// the largest excursion when the command returns to its start.
fn print_tip_measures(time_s: &[f64], tip: &[f64], y: &[f64]) {
    let (start, target) = (
        y.first().copied().unwrap_or(0.0),
        y.last().copied().unwrap_or(0.0),
    );
    if (target - start).abs() <= 1e-9 {
        let peak = tip.iter().map(|p| (p - target).abs()).fold(0.0, f64::max);
        println!(
            "largest tip excursion from the final base position {:.3} mm",
            peak * 1e3
        );
        return;
    }
    // The command's last change (the shaped command's end).
    let end_s = y
        .iter()
        .rposition(|v| (v - target).abs() > 1e-12)
        .map_or(0.0, |k| (k + 1) as f64 / SIM_RATE_HZ);
    let band = 0.02 * (target - start).abs();
    let m = measure(time_s, tip, start, target, end_s, end_s, band);
    println!(
        "tip: overshoot {:.2} % of the {:.1} mm move, residual vibration after the command ends {:.3} mm, \
         settling to +-{:.2} mm (2 %) {} after the command ends at {end_s:.3} s",
        m.overshoot_pct,
        (target - start).abs() * 1e3,
        m.residual_m * 1e3,
        band * 1e3,
        m.settling_s.map_or("not within the record".into(), |s| format!("{s:.2} s"))
    );
}

/// Plot of the base and the absolute tip (mm) against time.
fn plot_positions(path: &Path, title: &str, t: &[f64], base: &[f64], tip: &[f64]) -> Result<()> {
    let mm = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
    let (b, tp) = (mm(base), mm(tip));
    let series = [
        Series {
            label: "base".into(),
            x: t,
            y: &b,
        },
        Series {
            label: "tip (absolute)".into(),
            x: t,
            y: &tp,
        },
    ];
    let svg = lines_svg(title, "time (s)", "position (mm)", &series, false)?;
    std::fs::write(path, svg).with_context(|| format!("cannot write {}", path.display()))?;
    println!("plot -> {}", path.display());
    Ok(())
}

/// `simulate --force`: the force-driven free carriage.
fn simulate_force(a: &SimulateArgs, rig: &Rig, model: &BeamModel, p: &Path) -> Result<()> {
    let rec = super::read_recording(p)?;
    let u = rec
        .force_n
        .clone()
        .with_context(|| format!("{}: no force_n column", p.display()))?;
    if u.len() < 2 {
        bail!("{}: needs at least 2 samples of force_n", p.display());
    }
    // Zero-order hold of the recorded force at the internal rate.
    let u_fine = at_sim_rate(&rec, &u, true);
    let sim = ForceSim::new(model, 1.0 / SIM_RATE_HZ, false)?;
    let out = decimate(
        &sim.recording(&u_fine, 1.0 / SIM_RATE_HZ),
        rig.sample_rate_hz(),
    );
    out.write_csv(&a.out)?;
    let base = out
        .base_pos_m
        .as_ref()
        .context("internal: no base channel")?;
    let tip = out.tip_pos_m.as_ref().context("internal: no tip channel")?;
    let defl = tip
        .iter()
        .zip(base)
        .map(|(t, b)| (t - b).abs())
        .fold(0.0, f64::max);
    println!(
        "simulated the free carriage under the motor force of {} ({} samples at {:.1} Hz, zero-order hold): \
         {} samples at {} Hz -> {}",
        p.display(),
        u.len(),
        rec.sample_rate_hz(),
        out.len(),
        rig.sample_rate_hz(),
        a.out.display()
    );
    println!(
        "final carriage position {:.3} mm, largest tip deflection relative to the carriage {:.3} mm",
        base.last().copied().unwrap_or(0.0) * 1e3,
        defl * 1e3
    );
    if let Some(plot) = &a.plot {
        let title = format!("free carriage driven by {}", p.display());
        plot_positions(plot, &title, &out.time_s, base, tip)?;
    }
    Ok(())
}

/// `beamtool modes`.
pub fn modes(a: ModesArgs) -> Result<()> {
    let rig = Rig::from_toml_file(&a.rig)?;
    let model = BeamModel::new(
        &rig,
        &ModelOptions {
            n_modes: a.modes,
            ..Default::default()
        },
    )?;
    let cm = model.clamped_modes()?;
    let free = model.free_base_freqs_hz()?;
    let two_pi = 2.0 * std::f64::consts::PI;
    if a.json {
        let report = crate::model::modes_report::modes_report(&model)?;
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("beam mass {:.4} kg, carriage {:.3} kg, {} basis functions; Rayleigh alpha1 = {:.4e} 1/s, alpha2 = {:.4e} s",
        model.beam_mass_kg, model.base_mass_kg, a.modes, model.rayleigh.0, model.rayleigh.1);
    println!(
        "{:>4} {:>16} {:>16} {:>10} {:>14} {:>14}",
        "mode", "f clamped (Hz)", "f free base (Hz)", "zeta", "participation", "eff. mass (%)"
    );
    for r in 0..cm.omega_rad_s.len() {
        println!(
            "{:>4} {:>16.5} {:>16.5} {:>10.5} {:>14.5} {:>14.2}",
            r + 1,
            cm.omega_rad_s[r] / two_pi,
            free.get(r).copied().unwrap_or(f64::NAN),
            cm.zeta[r],
            cm.participation[r],
            100.0 * cm.participation[r].powi(2) / model.beam_mass_kg
        );
    }
    println!("mode shapes w(x)/w(l) at x/l = 0, 0.25, 0.5, 0.75, 1:");
    let l = model.length_m;
    for r in 0..cm.omega_rad_s.len().min(4) {
        let w = |x: f64| -> f64 {
            let c = model.coordinate_deflections(x);
            c.iter()
                .enumerate()
                .map(|(i, v)| cm.shapes[(i, r)] * v)
                .sum()
        };
        let tip = w(l);
        let pts: Vec<String> = [0.0, 0.25, 0.5, 0.75, 1.0]
            .iter()
            .map(|f| format!("{:+.4}", w(f * l) / tip))
            .collect();
        println!("  mode {}: {}", r + 1, pts.join("  "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trapezoid's constant acceleration read from its 200 Hz samples at the internal rate:
    /// the spline recovers it at every tick inside the phase, the piecewise-linear path put the
    /// whole velocity change of an interval on one tick.
    #[test]
    fn a_command_sampled_slower_than_the_simulation_keeps_its_acceleration() {
        let (rate, accel) = (200.0, 4.0);
        // 0.1 s at 4 m/s² from rest, then 0.1 s at constant speed
        let pos = |t: f64| {
            if t < 0.1 {
                0.5 * accel * t * t
            } else {
                0.02 + 0.4 * (t - 0.1)
            }
        };
        let y: Vec<f64> = (0..60).map(|k| pos(k as f64 / rate)).collect();
        let n = ((y.len() - 1) as f64 * SIM_RATE_HZ / rate) as usize + 1;
        let fine = spline_at(&y, rate, n);
        let h = 1.0 / SIM_RATE_HZ;
        let acc = |k: usize| (fine[k + 1] - 2.0 * fine[k] + fine[k - 1]) / (h * h);
        for k in 20..80 {
            assert!(
                (acc(k) - accel).abs() < 0.02 * accel,
                "tick {k}: {}",
                acc(k)
            );
        }
        for k in 150..250 {
            assert!(acc(k).abs() < 0.02 * accel, "tick {k}: {}", acc(k));
        }
        // through every sample
        for (i, v) in y.iter().enumerate() {
            assert!((fine[5 * i] - v).abs() < 1e-12);
        }
    }
}
