//! Spectrum files (Klipper's `resonances_*.csv`, `calibration_data_*.csv`): `tune FILE` on one
//! ([`tune_spectrum`]: design, side-by-side table, plot, `tune.json`, board) and
//! `beamtool klipper-compare FILES…` (one row per file, the not-worse / better fractions of
//! issue 70's goal).

use super::tune::TuneArgs;
use crate::plot::{lines_marked_svg, Marks, Series};
use crate::recording::psd::KlipperSpectrum;
use crate::shaping::klipper::{
    worst_response, FitSpectrum, Recommendation, SHAPER_VIBRATION_REDUCTION,
};
use crate::shaping::spectrum::{
    metrics, verdict, Comparison, Metrics, Objective, VIBRATION_MARGIN,
};
use crate::tune::spectrum::{design_file, tune_spectrum as job, SpectrumView};
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// Fraction of files on which ours must be "not worse" (issue 70).
pub const GOAL_NOT_WORSE: f64 = 0.9;
/// Fraction of files on which ours must be "better" (issue 70).
pub const GOAL_BETTER: f64 = 0.5;

/// `klipper-compare` arguments.
#[derive(Args, Debug, Clone)]
pub struct KlipperCompareArgs {
    /// Klipper spectrum files (`resonances_*.csv`, `calibration_data_*.csv`) or raw
    /// accelerometer files (`raw_data_*.csv`: their PSD computed as Klipper does).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Also print Klipper's own console lines for each file ("Fitted shaper …",
    /// "Recommended shaper is …"), as `calibrate_shaper.py` prints them.
    #[arg(long)]
    pub verbose: bool,
    /// What our design minimises within the "not worse" box: `least-smoothing` (issue 70's
    /// rule) or `klipper-score` (Klipper's own trade of vibrations against smoothing).
    #[arg(long, value_enum, default_value_t = ObjectiveArg::LeastSmoothing)]
    pub objective: ObjectiveArg,
    /// Remaining vibrations (percentage points) our design may leave above Klipper's
    /// recommendation (issue 70's "not worse" margin is 1; 0 = never more than Klipper's).
    #[arg(long, default_value_t = 100.0 * VIBRATION_MARGIN, value_parser = super::finite_f64)]
    pub vibration_margin_pct: f64,
}

/// See [`Objective`].
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectiveArg {
    /// [`Objective::LeastSmoothing`].
    LeastSmoothing,
    /// [`Objective::KlipperScore`].
    KlipperScore,
}

/// Klipper's console lines for a recommendation (the format of `calibrate_shaper.py`).
pub fn klipper_console(r: &Recommendation) -> Vec<String> {
    let mut out = vec![];
    for f in &r.fitted {
        out.push(format!(
            "Fitted shaper '{}' frequency = {:.1} Hz (vibrations = {:.1}%, smoothing ~= {:.3})",
            f.kind.name(),
            f.freq_hz,
            f.vibrations * 100.0,
            f.smoothing_mm
        ));
        out.push(format!(
            "To avoid too much smoothing with '{}', suggested max_accel <= {:.0} mm/sec^2",
            f.kind.name(),
            (f.max_accel_mm_s2 / 100.0).round() * 100.0
        ));
    }
    out.push(format!(
        "Recommended shaper is {} @ {:.1} Hz",
        r.best.kind.name(),
        r.best.freq_hz
    ));
    out
}

/// The side-by-side table: ours and Klipper's recommendation with Klipper's metrics.
pub fn comparison_table(fit: &FitSpectrum, c: &Comparison) -> String {
    let k = metrics(&c.klipper.best.shaper, fit);
    let row = |who: &str, name: &str, m: &Metrics| {
        format!(
            "  {who:<8} {name:<44} {:>6.2} % {:>9.4} mm {:>9.0}\n",
            100.0 * m.vibrations,
            m.smoothing_mm,
            m.max_accel_mm_s2
        )
    };
    let (nw, better) = verdict(&c.ours.metrics, &k);
    let kname = format!(
        "{} @ {:.1} Hz",
        c.klipper.best.kind.name(),
        c.klipper.best.freq_hz
    );
    let mut s = format!(
        "  {:<8} {:<44} {:>8} {:>12} {:>9}\n",
        "", "shaper (frequencies)", "vibr.", "smoothing", "max accel"
    );
    s += &row("Klipper", &kname, &k);
    s += &row("ours", &c.ours.name, &c.ours.metrics);
    s += &format!(
        "  (Klipper's metrics: vibrations over zeta 0.075/0.1/0.15 on the PSD summed over the axes; smoothing at 5000 mm/s², scv 5 mm/s; max accel for 0.12 mm smoothing, mm/s²)\n  ours vs Klipper: {}{}",
        if nw { "not worse" } else { "WORSE" },
        if better { ", better" } else { "" }
    );
    s
}

/// `spectrum.svg`: the measured PSD per axis and summed (Klipper's fitting scale), the sum left
/// by our shaper and by Klipper's (worst over the test damping ratios), and Klipper's threshold.
pub fn spectrum_plot(
    path: &Path,
    s: &KlipperSpectrum,
    fit: &FitSpectrum,
    c: &Comparison,
) -> Result<()> {
    let keep = s
        .freq_hz
        .iter()
        .filter(|&&f| f <= crate::shaping::klipper::MAX_FREQ_HZ)
        .count();
    let f = &s.freq_hz[..keep];
    let axis = |p: &[f64]| s.per_axis_fitting(p)[..keep].to_vec();
    let (px, py, pz) = (axis(&s.psd_x), axis(&s.psd_y), axis(&s.psd_z));
    let after = |sh| -> Vec<f64> {
        worst_response(sh, f)
            .iter()
            .zip(&fit.psd)
            .map(|(v, p)| v * p)
            .collect()
    };
    let (ours, klipper) = (after(&c.ours.shaper), after(&c.klipper.best.shaper));
    let max = fit.psd.iter().cloned().fold(0.0, f64::max);
    let series = [
        Series {
            label: "X+Y+Z (measured)".into(),
            x: f,
            y: &fit.psd,
        },
        Series {
            label: "X".into(),
            x: f,
            y: &px,
        },
        Series {
            label: "Y".into(),
            x: f,
            y: &py,
        },
        Series {
            label: "Z".into(),
            x: f,
            y: &pz,
        },
        Series {
            label: format!("X+Y+Z after ours: {}", c.ours.name),
            x: f,
            y: &ours,
        },
        Series {
            label: format!(
                "X+Y+Z after Klipper's: {} @ {:.1} Hz",
                c.klipper.best.kind.name(),
                c.klipper.best.freq_hz
            ),
            x: f,
            y: &klipper,
        },
    ];
    let marks = Marks {
        hlines: vec![(
            max / SHAPER_VIBRATION_REDUCTION,
            "Klipper's vibration threshold (max / 20)".into(),
        )],
        shaded_x: vec![],
        y_range: None,
    };
    let svg = lines_marked_svg(
        "measured PSD and what the shapers leave (worst over zeta 0.075/0.1/0.15)",
        "frequency (Hz)",
        "PSD / frequency (Klipper's fitting scale)",
        &series,
        false,
        &marks,
    )
    .with_context(|| format!("drawing {}", path.display()))?;
    std::fs::write(path, svg).with_context(|| format!("cannot write {}", path.display()))
}

/// `tune.json` for a spectrum.
fn write_report(
    path: &Path,
    input: &Path,
    fit: &FitSpectrum,
    c: &Comparison,
    board: Option<(&str, bool)>,
) -> Result<()> {
    let k = metrics(&c.klipper.best.shaper, fit);
    let (nw, better) = verdict(&c.ours.metrics, &k);
    let imps: Vec<_> = c
        .ours
        .shaper
        .impulses()
        .iter()
        .map(|i| serde_json::json!({"amplitude": i.amplitude, "time_s": i.time_s}))
        .collect();
    let m = |m: &Metrics| serde_json::json!({"vibrations_pct": 100.0 * m.vibrations, "smoothing_mm": m.smoothing_mm, "max_accel_mm_s2": m.max_accel_mm_s2});
    let j = serde_json::json!({
        "input": input.display().to_string(),
        "method": "design from a measured spectrum, scored by Klipper v0.13.0's metrics (docs/klipper.md)",
        "peaks_hz": c.peaks_hz,
        "ours": {"shaper": c.ours.name, "modes": c.ours.modes, "impulses": imps, "duration_s": c.ours.shaper.duration_s(), "metrics": m(&c.ours.metrics)},
        "klipper": {"shaper": c.klipper.best.kind.name(), "freq_hz": c.klipper.best.freq_hz, "metrics": m(&k),
            "fitted": c.klipper.fitted.iter().map(|f| serde_json::json!({"shaper": f.kind.name(), "freq_hz": f.freq_hz, "vibrations_pct": 100.0 * f.vibrations, "smoothing_mm": f.smoothing_mm, "max_accel_mm_s2": f.max_accel_mm_s2})).collect::<Vec<_>>()},
        "not_worse": nw,
        "better": better,
        "passed": board.is_some(),
        "verified": board.map(|_| "predicted only"),
        "board": board.map(|(port, saved)| serde_json::json!({"port": port, "programmed_and_read_back": true, "saved": saved, "checked_by": "remaining vibrations on the measured spectrum within Klipper's recommendation's; no motion measured"})),
        "units": {"vibrations_pct": "% (Klipper's remaining vibrations)", "smoothing_mm": "mm at 5000 mm/s², scv 5 mm/s", "max_accel_mm_s2": "mm/s² for 0.12 mm smoothing", "freq_hz": "Hz", "time_s": "s"},
    });
    std::fs::write(path, serde_json::to_string_pretty(&j)?)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Prints the design and writes the plot before the board is touched.
struct Printer<'a> {
    a: &'a TuneArgs,
}

impl SpectrumView for Printer<'_> {
    fn designed(
        &mut self,
        s: &KlipperSpectrum,
        fit: &FitSpectrum,
        c: &Comparison,
    ) -> Result<(), crate::tune::Foreign> {
        show_design(self.a, s, fit, c).map_err(Into::into)
    }
}

fn show_design(a: &TuneArgs, s: &KlipperSpectrum, fit: &FitSpectrum, c: &Comparison) -> Result<()> {
    let input = a.recording.clone().unwrap_or_default();
    let raw = crate::recording::rawpsd::is_raw_file(&input);
    let kind = match (raw, s.normalized) {
        (true, _) => "raw accelerometer file, PSD divided by frequency as Klipper does",
        (false, true) => "calibration_data file, PSD already divided by frequency",
        (false, false) => "resonances file, PSD divided by frequency as Klipper does",
    };
    println!(
        "spectrum {}: {} bins {:.1}-{:.1} Hz, Klipper {kind}; peaks {:?} Hz",
        input.display(),
        s.freq_hz.len(),
        s.freq_hz[0],
        s.freq_hz[s.freq_hz.len() - 1],
        c.peaks_hz
            .iter()
            .map(|f| (f * 10.0).round() / 10.0)
            .collect::<Vec<_>>()
    );
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    if raw {
        let psd = a.out.join("psd.csv");
        std::fs::write(&psd, crate::recording::rawpsd::format_spectrum_csv(s, &[]))
            .with_context(|| format!("cannot write {}", psd.display()))?;
        println!(
            "  {}; written in Klipper's resonances format -> {}",
            crate::recording::rawpsd::spectrum_note(s),
            psd.display()
        );
    }
    println!("Klipper's own calibration (v0.13.0 method):");
    for l in klipper_console(&c.klipper) {
        println!("  {l}");
    }
    println!("design (least smoothing within Klipper's recommendation's remaining vibrations):");
    println!("{}", comparison_table(fit, c));
    spectrum_plot(&a.out.join("spectrum.svg"), s, fit, c)?;
    write_report(&a.out.join("tune.json"), &input, fit, c, None)?;
    println!("plot {}", a.out.join("spectrum.svg").display());
    Ok(())
}

/// `tune FILE` on a spectrum: design, table, plot, `tune.json`, then program, read back and
/// save on the board (`--port`, or the virtual board).
pub fn tune_spectrum(a: &TuneArgs) -> Result<()> {
    let mut view = Printer { a };
    let r = job(&a.options(), &mut view)?;
    let input = a.recording.clone().unwrap_or_default();
    let report = a.out.join("tune.json");
    if !r.saved {
        write_report(&report, &input, &r.fit, &r.comparison, None)?;
        bail!(
            "nothing can measure a shaper designed from a spectrum (it holds no time signal): the board was not touched and nothing was saved (see {}); --accept-predicted programs and saves it, and the board's `status` then says verified=predicted-only",
            report.display()
        );
    }
    println!(
        "programmed {} and read the table back: {} impulses identical; saved as verified=predicted-only (checked on the measured spectrum only: no motion was measured)",
        r.port, r.programmed_impulses
    );
    write_report(
        &report,
        &input,
        &r.fit,
        &r.comparison,
        Some((&r.port, r.saved)),
    )?;
    println!("report {}", report.display());
    Ok(())
}

/// One file's row: ours vs Klipper's and the verdict.
pub struct Row {
    /// Klipper's recommendation's metrics.
    pub klipper: Metrics,
    /// Ours.
    pub ours: Metrics,
    /// Not worse / better.
    pub verdict: (bool, bool),
}

/// `beamtool klipper-compare`: one row per file, then the fractions and the goal's verdict.
/// Errors: a file that cannot be read (after every other row), or the goal not met.
pub fn klipper_compare(a: KlipperCompareArgs) -> Result<()> {
    println!(
        "{:<44} | {:<18} {:>6} {:>7} {:>6} | {:<40} {:>6} {:>7} {:>6} | verdict",
        "file", "Klipper", "vibr%", "smooth", "accel", "ours", "vibr%", "smooth", "accel"
    );
    let objective = match a.objective {
        ObjectiveArg::LeastSmoothing => Objective::LeastSmoothing,
        ObjectiveArg::KlipperScore => Objective::KlipperScore,
    };
    if !(0.0..=100.0).contains(&a.vibration_margin_pct) {
        bail!(
            "--vibration-margin-pct must be between 0 and 100 (got {})",
            a.vibration_margin_pct
        );
    }
    let margin = a.vibration_margin_pct / 100.0;
    let (mut rows, mut failed) = (vec![], vec![]);
    for f in &a.files {
        match design_file(f, objective, margin) {
            Ok((_, fit, c)) => rows.push(print_row(f, &fit, &c, a.verbose)),
            Err(e) => {
                println!("{:<44} | error: {e:#}", short(f));
                failed.push(f.display().to_string());
            }
        }
    }
    if rows.is_empty() {
        bail!("no spectrum file could be read ({} failed)", failed.len());
    }
    let met = print_summary(&rows);
    if !failed.is_empty() {
        bail!(
            "{} file(s) could not be read: {}",
            failed.len(),
            failed.join(", ")
        );
    }
    if !met {
        bail!("issue 70's goal is not met on these files");
    }
    Ok(())
}

/// Prints one file's row (and Klipper's console lines when `verbose`); returns it.
fn print_row(f: &Path, fit: &FitSpectrum, c: &Comparison, verbose: bool) -> Row {
    let k = metrics(&c.klipper.best.shaper, fit);
    let v = verdict(&c.ours.metrics, &k);
    println!(
        "{:<44} | {:<18} {:>6.2} {:>7.4} {:>6.0} | {:<40} {:>6.2} {:>7.4} {:>6.0} | {}",
        short(f),
        format!(
            "{} {:.1}",
            c.klipper.best.kind.name(),
            c.klipper.best.freq_hz
        ),
        100.0 * k.vibrations,
        k.smoothing_mm,
        k.max_accel_mm_s2,
        c.ours.name,
        100.0 * c.ours.metrics.vibrations,
        c.ours.metrics.smoothing_mm,
        c.ours.metrics.max_accel_mm_s2,
        match v {
            (true, true) => "better",
            (true, false) => "not worse",
            _ => "WORSE",
        }
    );
    if verbose {
        for l in klipper_console(&c.klipper) {
            println!("    {l}");
        }
    }
    Row {
        klipper: k,
        ours: c.ours.metrics,
        verdict: v,
    }
}

/// Prints the fractions, how "better" was reached, and the means; returns whether issue 70's
/// goal is met.
fn print_summary(rows: &[Row]) -> bool {
    let n = rows.len();
    let count = |p: &dyn Fn(&Row) -> bool| rows.iter().filter(|r| p(r)).count();
    let nw = count(&|r| r.verdict.0);
    let b = count(&|r| r.verdict.1);
    let b_vib = count(&|r| r.verdict.1 && r.ours.vibrations <= r.klipper.vibrations - 0.01);
    let b_smooth = count(&|r| r.verdict.1 && r.ours.smoothing_mm <= 0.95 * r.klipper.smoothing_mm);
    let more_vib = count(&|r| r.ours.vibrations > r.klipper.vibrations + 1e-4);
    let mean = |g: &dyn Fn(&Row) -> f64| rows.iter().map(g).sum::<f64>() / n as f64;
    let pct = |k: usize| 100.0 * k as f64 / n as f64;
    println!(
        "{n} files: not worse {nw}/{n} ({:.0} %, goal >= {:.0} %), better {b}/{n} ({:.0} %, goal >= {:.0} %)",
        pct(nw),
        100.0 * GOAL_NOT_WORSE,
        pct(b),
        100.0 * GOAL_BETTER,
    );
    println!(
        "  better by >= 1 point fewer vibrations: {b_vib}; by >= 5 % less smoothing: {b_smooth}; ours leaves more vibrations than Klipper's on {more_vib}/{n}"
    );
    println!(
        "  mean smoothing ours/Klipper {:.3}; mean vibrations ours {:.2} % vs Klipper {:.2} %; mean max accel ours/Klipper {:.3}",
        mean(&|r| r.ours.smoothing_mm / r.klipper.smoothing_mm),
        mean(&|r| 100.0 * r.ours.vibrations),
        mean(&|r| 100.0 * r.klipper.vibrations),
        mean(&|r| r.ours.max_accel_mm_s2 / r.klipper.max_accel_mm_s2),
    );
    (nw as f64) >= GOAL_NOT_WORSE * n as f64 && (b as f64) >= GOAL_BETTER * n as f64
}

fn short(p: &Path) -> String {
    let s = p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    match s.chars().count() > 44 {
        true => s.chars().skip(s.chars().count() - 44).collect(),
        false => s,
    }
}

/// `beamtool tune`: a Klipper spectrum file (`resonances_*.csv`, `calibration_data_*.csv`) or a
/// Klipper raw accelerometer file (its PSD as Klipper computes it) goes to the spectrum design
/// ([`tune_spectrum`]); anything else to [`super::tune::tune`]. (Here,
/// not in `cli/tune.rs`, so that the two modules do not import each other.)
pub fn run_tune(a: TuneArgs) -> Result<()> {
    match a.recording.as_deref() {
        Some(p)
            if crate::recording::psd::is_spectrum_file(p)
                || crate::recording::rawpsd::is_raw_file(p) =>
        {
            tune_spectrum(&a)
        }
        _ => super::tune::tune(a).map(|_| ()),
    }
}
