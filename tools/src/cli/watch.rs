//! `beamtool watch --port P`: polls the board's drift watch (`watch`) and, after each move it
//! measured, prints the report, appends it to a CSV and redraws an SVG of f1 over the moves
//! against the band the watch compares it with.

use crate::board::client::BoardClient;
use anyhow::{Context, Result};
use beamshaper::protocol::WatchReply;
use clap::Args;
use std::io::Write;
use std::path::PathBuf;

/// `watch` arguments.
#[derive(Args)]
pub struct WatchArgs {
    /// Serial port of the board (e.g. /dev/ttyACM0, or the path `vboard` printed).
    #[arg(long)]
    port: String,
    /// CSV of the reports, one row per measured move.
    #[arg(long, default_value = "watch.csv")]
    csv: PathBuf,
    /// SVG plot of f1 over the moves against the band.
    #[arg(long, default_value = "watch.svg")]
    plot: PathBuf,
    /// Stop after this many measured moves (0 = until interrupted).
    #[arg(long, default_value_t = 0)]
    moves: u32,
    /// Polling interval (ms).
    #[arg(long, default_value_t = 200)]
    interval_ms: u64,
    /// Also drive the moves (a board without an upstream controller, e.g. the virtual
    /// board): after each measured move, `move` to this position (mm) and back to 0.
    #[arg(long)]
    move_mm: Option<f64>,
    /// Speed (mm/s) of those moves.
    #[arg(long, default_value_t = 150.0)]
    speed_mm_s: f64,
    /// Acceleration (mm/s²) of those moves.
    #[arg(long, default_value_t = 2000.0)]
    accel_mm_s2: f64,
}

const HEADER: &str = "move,state,f1_hz,zeta1,f2_hz,zeta2,band_lo_hz,band_hi_hz,residual_rms_m_s2,residual_ratio,auto,retunes,shaper_f1_hz";

fn cell(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| format!("{x}"))
}

/// One CSV row of a report.
pub fn csv_row(w: &WatchReply) -> String {
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        w.moves,
        w.state.name(),
        cell(w.f1_hz),
        cell(w.zeta1),
        cell(w.f2_hz),
        cell(w.zeta2),
        cell(w.band_lo_hz),
        cell(w.band_hi_hz),
        cell(w.residual_rms_m_s2),
        cell(w.residual_ratio),
        w.auto as u8,
        w.retunes,
        cell(w.shaper_f1_hz)
    )
}

/// The SVG of f1 (and the installed shaper's f1) over the moves, with the band's edges.
pub fn plot_svg(reports: &[WatchReply]) -> Result<String> {
    let col = |f: fn(&WatchReply) -> Option<f64>| -> Vec<f64> {
        reports.iter().map(|w| f(w).unwrap_or(f64::NAN)).collect()
    };
    let x: Vec<f64> = reports.iter().map(|w| w.moves as f64).collect();
    let (f1, lo, hi, sh) = (
        col(|w| w.f1_hz),
        col(|w| w.band_lo_hz),
        col(|w| w.band_hi_hz),
        col(|w| w.shaper_f1_hz),
    );
    let series = [
        crate::plot::Series {
            label: "measured f1 (Hz)".into(),
            x: &x,
            y: &f1,
        },
        crate::plot::Series {
            label: "band low (Hz)".into(),
            x: &x,
            y: &lo,
        },
        crate::plot::Series {
            label: "band high (Hz)".into(),
            x: &x,
            y: &hi,
        },
        crate::plot::Series {
            label: "shaper f1 (Hz)".into(),
            x: &x,
            y: &sh,
        },
    ];
    crate::plot::lines_svg("drift watch: f1 over moves", "move", "Hz", &series, false)
}

/// `beamtool watch`.
pub fn watch(a: WatchArgs) -> Result<()> {
    let mut c = BoardClient::open(&a.port)?;
    let mut csv = std::fs::File::create(&a.csv)
        .with_context(|| format!("cannot create {}", a.csv.display()))?;
    writeln!(csv, "{HEADER}")?;
    let mut reports: Vec<WatchReply> = Vec::new();
    let mut last_moves = None;
    println!(
        "watching {}; reports to {} and {}",
        a.port,
        a.csv.display(),
        a.plot.display()
    );
    let mut next_target = None;
    loop {
        if let Some(t) = next_target.take() {
            let r = c.command(&format!("move {t} {} {}", a.speed_mm_s, a.accel_mm_s2))?;
            println!("{}", r.ok);
        }
        let r = c.command("watch")?;
        for i in &r.info {
            println!("# {i}");
        }
        let w = WatchReply::parse(&r.ok).map_err(|e| anyhow::anyhow!("`{}`: {e}", r.ok))?;
        if last_moves != Some(w.moves) {
            if last_moves.is_some() || w.moves > 0 {
                println!("{}", r.ok);
                writeln!(csv, "{}", csv_row(&w))?;
                csv.flush()?;
                reports.push(w);
                if reports.iter().any(|w| w.f1_hz.is_some()) {
                    let svg = plot_svg(&reports)?;
                    std::fs::write(&a.plot, svg)
                        .with_context(|| format!("cannot write {}", a.plot.display()))?;
                }
            }
            if let Some(m) = a.move_mm {
                next_target = Some(if w.moves % 2 == 0 { m } else { 0.0 });
            }
            last_moves = Some(w.moves);
        }
        if a.moves > 0 && reports.len() as u32 >= a.moves {
            return Ok(());
        }
        std::thread::sleep(std::time::Duration::from_millis(a.interval_ms));
    }
}
