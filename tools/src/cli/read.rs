//! How the commands read a recording file (`--columns`, `--axis`, shared by `identify`, `tune`,
//! `frf` and `diagnose`), and `bench-read`: the reading's speed and memory on a file, beside a named peer
//! reading the same file in the same run.

use crate::recording::{Axis, ColumnMap, ReadOptions, Recording};
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

/// The reading options of a command that reads a recording.
#[derive(Args, Debug, Clone, Default, PartialEq)]
pub struct ReadArgs {
    /// Which column of the file holds which channel, with its scale to SI:
    /// `channel=file_column[:scale],…`, e.g.
    /// `time_s=t:0.001,base_pos_m=theta:0.45,tip_pos_m=defl:0.001`. Channels: time_s,
    /// base_cmd_m, base_pos_m, tip_pos_m, force_n, tip_acc_m_s2, and tip_defl_m (the tip
    /// measured from the base, read as tip_pos_m = base + it). Unmapped columns are ignored.
    #[arg(long, value_parser = parse_columns)]
    pub columns: Option<ColumnMap>,
    /// Axis of a Klipper raw accelerometer CSV (`#time,accel_x,accel_y,accel_z`) read as the
    /// tip acceleration: x, y or z (default: the axis with the most energy).
    #[arg(long, value_parser = parse_axis)]
    pub axis: Option<Axis>,
}

fn parse_columns(s: &str) -> std::result::Result<ColumnMap, String> {
    ColumnMap::parse(s).map_err(|e| e.to_string())
}

fn parse_axis(s: &str) -> std::result::Result<Axis, String> {
    Axis::from_name(s).map_err(|e| e.to_string())
}

impl ReadArgs {
    /// The library's reading options.
    pub fn options(&self) -> ReadOptions {
        ReadOptions {
            columns: self.columns.clone(),
            axis: self.axis,
        }
    }
}

/// `bench-read` arguments.
#[derive(Args, Debug)]
pub struct BenchReadArgs {
    /// Recording to read (CSV, Klipper raw CSV, `.npy`).
    pub file: PathBuf,
    /// How the file is read.
    #[command(flatten)]
    pub read: ReadArgs,
    /// Number of reads; the fastest is reported (the first warms the page cache).
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// The peer read in the same run: `python-csv` (python3's `csv` module into lists of
    /// floats), `pandas` (`pandas.read_csv`), `none`.
    #[arg(long, default_value = "python-csv")]
    pub peer: String,
    /// The Python interpreter of the peer (e.g. a venv's with pandas).
    #[arg(long, default_value = "python3")]
    pub python: String,
}

/// The peer's program: reads `sys.argv[1]` into columns of floats and prints
/// `seconds rows peak_rss_kib`.
fn peer_program(peer: &str) -> Result<&'static str> {
    Ok(match peer {
        "python-csv" => {
            r#"import csv,sys,time,resource
t=time.perf_counter()
cols=None
with open(sys.argv[1],newline='') as f:
    for row in csv.reader(f):
        if not row or row[0].startswith('#'):
            continue
        if cols is None:
            cols=[[] for _ in row]
            continue
        for c,v in zip(cols,row):
            c.append(float(v) if v else float('nan'))
print(time.perf_counter()-t, len(cols[0]), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"#
        }
        "pandas" => {
            r#"import sys,time,resource
import pandas
t=time.perf_counter()
d=pandas.read_csv(sys.argv[1],comment='#')
print(time.perf_counter()-t, len(d), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"#
        }
        _ => bail!("--peer `{peer}`: want python-csv, pandas or none"),
    })
}

/// The peak resident set size of this process (MiB), `VmHWM` of /proc/self/status.
pub fn peak_rss_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// The time (s) of parsing every column of the CSV at `path` alone (nothing mended or noted);
/// `None` when a column is not numeric.
fn cells_only_s(path: &std::path::Path) -> Option<f64> {
    use crate::recording::csvread::{layout, read_columns, Wanted};
    let l = layout(path).ok()?;
    let wanted: Vec<Wanted<'_>> = l
        .names
        .iter()
        .enumerate()
        .map(|(index, name)| Wanted {
            index,
            name,
            scale: 1.0,
            required: false,
        })
        .collect();
    let t0 = Instant::now();
    read_columns(path, &l, &wanted, &mut |_| {}).ok()?;
    Some(t0.elapsed().as_secs_f64())
}

/// `beamtool bench-read`: reads the file `--repeat` times ([`Recording::read_any_with`], the
/// whole reading: cells, row-wise fill, mending, notes), prints rows, MB, the fastest time,
/// rows/s, MB/s and the peak RSS, then the peer's time and peak RSS on the same file and the
/// ratio of the times.
pub fn bench_read(a: BenchReadArgs) -> Result<()> {
    let opts = a.read.options();
    let program = match a.peer.as_str() {
        "none" => None,
        p => Some(peer_program(p)?),
    };
    let bytes = std::fs::metadata(&a.file)
        .with_context(|| format!("cannot read {}", a.file.display()))?
        .len() as f64;
    let mut best = f64::INFINITY;
    let mut shape = (0usize, 0usize);
    let mut notes = Vec::new();
    for _ in 0..a.repeat.max(1) {
        let t0 = Instant::now();
        let rec = Recording::read_any_with(&a.file, &opts, &mut |_| {})?;
        best = best.min(t0.elapsed().as_secs_f64());
        shape = (
            rec.len(),
            crate::recording::CHANNELS
                .iter()
                .filter(|c| rec.channel(c).is_some())
                .count(),
        );
        notes = rec.notes;
    }
    super::print_notes(&a.file, &notes);
    let rss = peak_rss_mib().unwrap_or(f64::NAN);
    let cells_s = cells_only_s(&a.file);
    let data_mb = shape.0 as f64 * (shape.1 + 1) as f64 * 8.0 / 1e6;
    println!(
        "beamtool: {} rows x {} channels + time, {:.1} MB file: read in {:.3} s (best of {}), {:.2} M rows/s, {:.0} MB/s; peak RSS {:.0} MiB (the data: {:.1} MB)",
        shape.0,
        shape.1,
        bytes / 1e6,
        best,
        a.repeat.max(1),
        shape.0 as f64 / best / 1e6,
        bytes / 1e6 / best,
        rss,
        data_mb
    );
    if let Some(c) = cells_s {
        println!(
            "  of which parsing the cells: {c:.3} s ({:.0} MB/s); the rest is row-wise, staircase and quantum checks and mending",
            bytes / 1e6 / c
        );
    }
    match program {
        Some(p) => run_peer(&a, p, best),
        None => Ok(()),
    }
}

/// Runs the peer `program` on the file of `a` and prints its time, rows and peak RSS, and the
/// ratio of its time to beamtool's `best` (s).
fn run_peer(a: &BenchReadArgs, program: &str, best: f64) -> Result<()> {
    let out = std::process::Command::new(&a.python)
        .arg("-c")
        .arg(program)
        .arg(&a.file)
        .output()
        .with_context(|| format!("cannot run the peer `{}`", a.python))?;
    if !out.status.success() {
        bail!(
            "the peer ({} with {}) failed: {}",
            a.peer,
            a.python,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let v: Vec<f64> = text
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    if v.len() != 3 {
        bail!(
            "the peer printed `{}`, not `seconds rows peak_kib`",
            text.trim()
        );
    }
    println!(
        "peer {} ({}): {} rows read in {:.3} s, {:.2} M rows/s; peak RSS {:.0} MiB",
        a.peer,
        a.python,
        v[1],
        v[0],
        v[1] / v[0] / 1e6,
        v[2] / 1024.0
    );
    println!(
        "ratio: beamtool reads this file {:.1}x as fast as {} ({:.3} s vs {:.3} s)",
        v[0] / best,
        a.peer,
        best,
        v[0]
    );
    Ok(())
}
