//! `beamtool tune`: the arguments of the main job, and what it shows — one line (or table) per
//! step as the job reports it ([`crate::tune::TuneView`]), the sensitivity and verification
//! plots, and the report `tune.json` in the output directory.

use super::finite_f64;
use crate::board::steps::BoardState;
use crate::ident::ModeEstimate;
use crate::measures::MeasuredMove;
use crate::plot::{lines_marked_svg, Marks, Series};
use crate::shaping::{band, sensitivity, Candidate};
use crate::tune::{
    Design, Excitation, Foreign, IdentifiedModes, Outcome, Signal, TuneError, TuneOptions,
    TuneReport, TuneView,
};
use anyhow::{bail, Context, Result};
use beamshaper::config::Verified;
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a recording's vibration signal measures (see [`Signal`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SignalArg {
    /// `.npy` → acceleration, CSV → position.
    Auto,
    /// Tip position or deflection.
    Position,
    /// Tip acceleration (integrated twice for the model-free check).
    Acceleration,
}

/// `tune` arguments.
#[derive(Args, Debug, Clone)]
pub struct TuneArgs {
    /// Recording (CSV, .npy free decay), or a Klipper spectrum (`resonances_*.csv`,
    /// `calibration_data_*.csv`: designed from the PSD beside Klipper's own calibration, see
    /// docs/klipper.md). Without it, the virtual rig's camera records an excitation run on
    /// the board.
    pub recording: Option<PathBuf>,
    /// Rig file: the virtual rig's beam (without --port) and the model prediction (default:
    /// the embedded reference rig rigs/paper.toml).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Percentage-vibration tolerance (%), over the whole uncertainty band and measured.
    #[arg(long, default_value_t = 2.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub tolerance_pct: f64,
    /// Minimum half-width of the frequency band checked (% of each frequency).
    #[arg(long, default_value_t = 2.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub min_band_pct: f64,
    /// Serial port of a real board (e.g. /dev/ttyACM0); default: a virtual board on a PTY.
    #[arg(long)]
    pub port: Option<String>,
    /// Verification move distance (mm) from the current position (negative = backwards).
    #[arg(long, default_value_t = 50.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub move_mm: f64,
    /// Verification move peak speed (mm/s).
    #[arg(long, default_value_t = 150.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub speed_mm_s: f64,
    /// Verification move acceleration (mm/s²).
    #[arg(long, default_value_t = 2000.0, value_parser = finite_f64, allow_negative_numbers = true)]
    pub accel_mm_s2: f64,
    /// Output directory (recordings, plots, report JSON, virtual flash).
    #[arg(long, default_value = "tune-out")]
    pub out: PathBuf,
    /// Camera log of a board with a rig attached (`beamtool vboard --rig … --sensor-out FILE`):
    /// the verification moves are then measured on it.
    #[arg(long)]
    pub camera_log: Option<PathBuf>,
    /// What the recording's vibration signal is, for the model-free check: `auto` = an
    /// acceleration in a `.npy` (the accelerometer decays of shared/data/real), a position in
    /// a recording CSV (`tip_pos_m`).
    #[arg(long, value_enum, default_value_t = SignalArg::Auto)]
    pub signal: SignalArg,
    /// Virtual board speed-up over real time.
    #[arg(long, default_value_t = 200.0, value_parser = finite_f64)]
    pub time_scale: f64,
    /// When nothing can measure the shaper (no camera log, no rig camera, no recorded free
    /// vibration that resolves the tolerance), save it on the identified modes' prediction
    /// alone; `tune.json` says `"verified": "predicted only"` and the board's `status`
    /// `verified=predicted-only`.
    #[arg(long)]
    pub accept_predicted: bool,
    /// Also store the tuned frequencies as entry N (0-7) of the board's payload schedule
    /// (`payload N` on the console selects it later).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..8))]
    pub payload: Option<u8>,
    /// How the recording is read (`--columns`, `--axis`).
    #[command(flatten)]
    pub read: super::read::ReadArgs,
}

impl TuneArgs {
    /// The defaults of `beamtool tune` with `recording` and output directory `out`.
    pub fn new(recording: Option<PathBuf>, out: &Path) -> Self {
        TuneArgs::from_options(TuneOptions::new(recording, out))
    }

    fn from_options(o: TuneOptions) -> Self {
        TuneArgs {
            recording: o.recording,
            rig: o.rig,
            tolerance_pct: o.tolerance_pct,
            min_band_pct: o.min_band_pct,
            port: o.port,
            move_mm: o.move_mm,
            speed_mm_s: o.speed_mm_s,
            accel_mm_s2: o.accel_mm_s2,
            out: o.work_dir,
            camera_log: o.camera_log,
            signal: SignalArg::Auto,
            time_scale: o.time_scale,
            accept_predicted: o.accept_predicted,
            payload: o.payload,
            read: super::read::ReadArgs {
                columns: o.read.columns,
                axis: o.read.axis,
            },
        }
    }

    /// The library's options (the output directory is the work directory).
    pub fn options(&self) -> TuneOptions {
        TuneOptions {
            recording: self.recording.clone(),
            rig: self.rig.clone(),
            tolerance_pct: self.tolerance_pct,
            min_band_pct: self.min_band_pct,
            port: self.port.clone(),
            move_mm: self.move_mm,
            speed_mm_s: self.speed_mm_s,
            accel_mm_s2: self.accel_mm_s2,
            work_dir: self.out.clone(),
            camera_log: self.camera_log.clone(),
            signal: match self.signal {
                SignalArg::Auto => Signal::Auto,
                SignalArg::Position => Signal::Position,
                SignalArg::Acceleration => Signal::Acceleration,
            },
            time_scale: self.time_scale,
            accept_predicted: self.accept_predicted,
            payload: self.payload,
            read: self.read.options(),
        }
    }
}

/// `beamtool tune`: runs the job, printing each step, writing the plots and `tune.json`.
/// A failed verification prints what was done with the board and is an error.
pub fn tune(a: TuneArgs) -> Result<TuneReport> {
    let t0 = Instant::now();
    let mut view = Printer { a: &a };
    match crate::tune::tune(&a.options(), &mut view) {
        Ok(r) => {
            println!("done in {:.1} s", t0.elapsed().as_secs_f64());
            Ok(r)
        }
        Err(TuneError::VerificationFailed {
            restored, report, ..
        }) => {
            println!("{restored}");
            let why = crate::tune::why_failed(&report, a.tolerance_pct);
            bail!(
                "verification failed: {why} (see {}); {restored}",
                a.out.join("tune.json").display()
            )
        }
        Err(e) => Err(e.into()),
    }
}

/// Prints each step of the job and writes its files.
struct Printer<'a> {
    a: &'a TuneArgs,
}

impl TuneView for Printer<'_> {
    fn board(&mut self, port: &str, before: &BoardState) {
        let c = &before.config;
        println!(
            "board {port}: tick {} Hz, step {} nm, max {} steps/s, at {:.3} mm, shaping {}",
            c.tick_hz,
            c.step_nm,
            c.max_step_rate_hz,
            before.position_mm,
            if c.shaping { "on" } else { "off" }
        );
    }

    fn excited(&mut self, e: &Excitation) {
        let p = &e.plan;
        println!(
            "excitation: exponential sweep {}-{} Hz, {:.3} mm, {} s on the board (eq. 34, its own reference generator; {:.0} steps/s peak), {:.0} s recorded by the virtual rig's camera -> {}",
            p.f0_hz, p.f1_hz, p.amplitude_mm, p.duration_s, p.peak_step_rate_hz, e.recorded_s, e.recording.display()
        );
    }

    fn identified(&mut self, input: &Path, id: &IdentifiedModes) {
        println!("identified from {}:", input.display());
        for line in id.description.lines() {
            println!("  {line}");
        }
    }

    fn designed(&mut self, modes: &[ModeEstimate], d: &Design) -> Result<(), Foreign> {
        print_design(self.a, d);
        sensitivity_plot(self.a, modes, d).map_err(Into::into)
    }

    fn programmed(&mut self, port: &str, c: &Candidate) {
        println!(
            "programmed {port} and read the table back: {} impulses identical",
            c.shaper.len()
        );
    }

    fn verified(&mut self, r: &TuneReport) -> Result<(), Foreign> {
        print_verification(self.a, r);
        if let Some((mu, ms)) = &r.verification.moves {
            verification_plot(self.a, mu, ms)?;
        }
        write_report(self.a, r).map_err(Into::into)
    }

    fn saved(&mut self) {
        println!(
            "saved on the board; report {}",
            self.a.out.join("tune.json").display()
        );
    }
}

/// The chosen shaper, its verification move, the runners-up and the refused shorter ones.
fn print_design(a: &TuneArgs, d: &Design) {
    let (b, m) = (&d.best, &d.shaped);
    println!(
        "shaper: {} — {} impulses, {:.4} s, worst-case V {:.2} % (tolerance {} % over f ± max(2σ, {} %), ζ ± 2σ); verification move {:.1} -> {:.1} mm at {} mm/s, {:.0} steps/s of {}",
        b.name, b.shaper.len(), b.shaper.duration_s(), b.worst_pct, a.tolerance_pct, a.min_band_pct,
        m.start_mm, m.target_mm, m.speed_mm_s, m.peak_step_rate_hz, d.max_step_rate_hz
    );
    for c in &d.runners_up {
        println!(
            "  runner-up {:<40} {:.4} s, worst V {:.2} %",
            c.name,
            c.shaper.duration_s(),
            c.worst_pct
        );
    }
    for r in &d.refused_on_recording {
        println!("  refused (shorter) {r}");
    }
}

/// The checks, each a percentage vibration, and the verdict.
fn print_verification(a: &TuneArgs, r: &TuneReport) {
    let v = &r.verification;
    let fmt = |p: Option<f64>| p.map_or("-".to_string(), |p| format!("{p:.2} %"));
    println!(
        "verification (percentage vibration, tolerance {} %):",
        a.tolerance_pct
    );
    println!("  measured by the camera          {}", fmt(v.measured_pct));
    println!(
        "  shaper on the recorded vibration {} (model-free superposition{}; - = no free vibration that resolves {} %)",
        fmt(v.superposed_pct),
        if r.acceleration { ", acceleration integrated twice" } else { "" },
        a.tolerance_pct / 2.0
    );
    if let Some(n) = &v.recorded_note {
        println!("    ({n})");
    }
    println!("  rig model ({})  {}", r.rig_label, fmt(v.rig_model_pct));
    println!(
        "  predicted at the identified modes {:.2} %",
        v.predicted_pct
    );
    for why in &v.unmeasured_because {
        println!("  nothing measured: {why}");
    }
    println!(
        "  -> {}",
        match (r.verified, v.outcome(a.tolerance_pct)) {
            (Verified::Measured, _) => "PASS".to_string(),
            (Verified::PredictedOnly, _) => format!(
                "ACCEPTED ON THE PREDICTION ONLY (--accept-predicted): nothing measured the shaper; predicted {:.2} %",
                v.predicted_pct
            ),
            (_, Outcome::Unmeasured) => format!(
                "FAIL: nothing could measure the shaper{}",
                if a.accept_predicted {
                    " and the prediction exceeds the tolerance"
                } else {
                    " (--accept-predicted saves on the prediction alone)"
                }
            ),
            _ => "FAIL: exceeds the tolerance".to_string(),
        }
    );
    if let Some((mu, ms)) = &v.moves {
        println!(
            "  residual after the command: unshaped {:.3} mm, shaped {:.3} mm",
            mu.residual_m * 1e3,
            ms.residual_m * 1e3
        );
    }
}

/// `sensitivity.svg`: V(f) of the chosen shaper and the first runner-up, the checked bands
/// and the tolerance.
fn sensitivity_plot(a: &TuneArgs, modes: &[ModeEstimate], d: &Design) -> Result<()> {
    let fmax = modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max) * 1.3;
    let f: Vec<f64> = (1..=800).map(|i| fmax * i as f64 / 800.0).collect();
    let z = modes[0].zeta;
    let marks = sensitivity_marks(a, modes);
    let top = marks.y_range.map_or(100.0, |r| r.1);
    let clip = |v: Vec<f64>| v.into_iter().map(|x| x.min(top)).collect::<Vec<_>>();
    let v_best = clip(sensitivity(&d.best.shaper, &f, z));
    let v_r = d
        .runners_up
        .first()
        .map(|r| (r.name.clone(), clip(sensitivity(&r.shaper, &f, z))));
    let mut series = vec![Series {
        label: format!("{} (chosen)", d.best.name),
        x: &f,
        y: &v_best,
    }];
    if let Some((n, v)) = &v_r {
        series.push(Series {
            label: n.clone(),
            x: &f,
            y: v,
        });
    }
    let svg = lines_marked_svg(
        &format!("percentage vibration V(f) at zeta {z:.4}"),
        "frequency (Hz)",
        "percentage vibration V (%)",
        &series,
        false,
        &marks,
    );
    write_svg(&a.out.join("sensitivity.svg"), svg)
}

/// Writes an SVG document drawn by [`crate::plot`].
fn write_svg(path: &Path, svg: Result<String>) -> Result<()> {
    let svg = svg.with_context(|| format!("drawing {}", path.display()))?;
    std::fs::write(path, svg).with_context(|| format!("cannot write {}", path.display()))
}

/// The tolerance line, the checked band of each mode, the y range of the sensitivity plot.
fn sensitivity_marks(a: &TuneArgs, modes: &[ModeEstimate]) -> Marks {
    Marks {
        hlines: vec![(a.tolerance_pct, format!("tolerance {} %", a.tolerance_pct))],
        shaded_x: modes
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let b = band(m, a.min_band_pct / 100.0);
                let label = format!("checked band, mode {}", i + 1);
                (b.freq_hz.0, b.freq_hz.1, label)
            })
            .collect(),
        y_range: Some((
            0.0,
            100.0f64
                .min(8.0 * a.tolerance_pct)
                .max(2.0 * a.tolerance_pct),
        )),
    }
}

/// `verification.svg`: tip − target of the unshaped and the shaped measured moves.
fn verification_plot(a: &TuneArgs, mu: &MeasuredMove, ms: &MeasuredMove) -> Result<()> {
    let target_u = *mu.command_m.last().unwrap_or(&0.0);
    let target_s = *ms.command_m.last().unwrap_or(&0.0);
    let band_mm = 0.02 * a.move_mm.abs();
    let tol_mm = a.tolerance_pct / 100.0 * mu.residual_m * 1e3;
    let lim = (3.0 * band_mm)
        .max(3.0 * tol_mm)
        .max(1.3 * ms.residual_m * 1e3);
    // Both residuals with the sign of the shaped move, clipped to the visible range.
    let sgn = a.move_mm.signum();
    let res = |m: &MeasuredMove, tgt: f64, s: f64| -> Vec<f64> {
        m.tip_m
            .iter()
            .map(|p| ((p - tgt) * s * 1e3).clamp(-lim, lim))
            .collect()
    };
    let (ru, rs) = (res(mu, target_u, sgn), res(ms, target_s, -sgn));
    let svg = lines_marked_svg(
        "verification moves measured by the camera: tip − target (clipped)",
        "time since the command started (s)",
        "tip − target (mm)",
        &[
            Series {
                label: format!("unshaped (residual {:.2} mm)", mu.residual_m * 1e3),
                x: &mu.time_s,
                y: &ru,
            },
            Series {
                label: format!("shaped (residual {:.3} mm)", ms.residual_m * 1e3),
                x: &ms.time_s,
                y: &rs,
            },
        ],
        false,
        &verification_marks(a, band_mm, tol_mm, lim),
    );
    write_svg(&a.out.join("verification.svg"), svg)
}

/// The settling band and the tolerance lines (both signs) of the verification plot.
fn verification_marks(a: &TuneArgs, band_mm: f64, tol_mm: f64, lim: f64) -> Marks {
    let band = format!("±{band_mm:.2} mm settling band (2 % of the move)");
    let tol = format!("±tolerance: {} % of the unshaped residual", a.tolerance_pct);
    Marks {
        hlines: vec![
            (band_mm, band.clone()),
            (-band_mm, band),
            (tol_mm, tol.clone()),
            (-tol_mm, tol),
        ],
        shaded_x: vec![],
        y_range: Some((-lim, lim)),
    }
}

/// `tune.json`: the verdict, the identification, the shaper, every check, units.
fn write_report(a: &TuneArgs, r: &TuneReport) -> Result<()> {
    let (d, v) = (&r.design, &r.verification);
    let imps: Vec<_> = d
        .best
        .shaper
        .impulses()
        .iter()
        .map(|i| serde_json::json!({"amplitude": i.amplitude, "time_s": i.time_s}))
        .collect();
    let j = serde_json::json!({
        "passed": r.passed,
        "verified": match r.verified {
            Verified::Measured => Some("measured"),
            Verified::PredictedOnly => Some("predicted only"),
            Verified::Unknown => None,
        },
        "certified_bands_hz": r.passed.then(|| crate::tune::certificate(&a.options(), r).band_hz.iter().flatten().map(|(lo, hi)| [*lo as f64, *hi as f64]).collect::<Vec<_>>()),
        "input": r.input.display().to_string(),
        "port": r.port,
        "identification": r.id.description,
        "modes": r.id.modes,
        "shaper": d.best.name,
        "impulses": imps,
        "duration_s": d.best.shaper.duration_s(),
        "worst_case_vibration_pct": d.best.worst_pct,
        "tolerance_pct": a.tolerance_pct,
        "verification": {
            "measured_vibration_pct": v.measured_pct,
            "superposed_vibration_pct": v.superposed_pct,
            "predicted_vibration_pct": v.predicted_pct,
            "rig_model_vibration_pct": v.rig_model_pct,
            "residual_unshaped_m": v.moves.as_ref().map(|m| m.0.residual_m),
            "residual_shaped_m": v.moves.as_ref().map(|m| m.1.residual_m),
            "move": {"start_mm": d.shaped.start_mm, "target_mm": d.shaped.target_mm, "speed_mm_s": d.shaped.speed_mm_s, "accel_mm_s2": d.shaped.accel_mm_s2, "peak_step_rate_hz": d.shaped.peak_step_rate_hz},
        },
        "units": {"freq_hz": "Hz", "zeta": "1", "amplitude": "1", "time_s": "s", "vibration_pct": "% of the unshaped residual", "residual_m": "m", "mm": "mm"},
    });
    let path = a.out.join("tune.json");
    std::fs::write(&path, serde_json::to_string_pretty(&j)?)
        .with_context(|| format!("cannot write {}", path.display()))
}
