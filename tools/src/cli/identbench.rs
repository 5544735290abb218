//! `beamtool identify FILE --bench`: wall time per stage of [`crate::ident::identify()`] (read,
//! checks, decimate, FRF, estimators, screening, refinement), the peak resident memory (VmHWM
//! of /proc/self/status), and the same work by a named peer on the same file in the same run:
//! scipy's `csd`/`welch` H1 and sdypy-EMA's LSCF (`bench/identify_peer.py`, run by the Python
//! given with `--peer-python`), with the decimation, segment, band and order beamtool chose.

use crate::ident::frf::Window;
use crate::ident::{IdentPath, Identification, Stage};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Stage events of one identification, timed.
pub struct StageClock {
    t0: Instant,
    events: Vec<(Instant, Stage)>,
}

impl StageClock {
    /// Starts the clock (before the file is read).
    pub fn start() -> Self {
        StageClock {
            t0: Instant::now(),
            events: vec![],
        }
    }

    /// Notes that `stage` begins now.
    pub fn mark(&mut self, stage: &Stage) {
        self.events.push((Instant::now(), stage.clone()));
    }

    /// The decimation factor reported (1 without decimation).
    pub fn decimation(&self) -> usize {
        self.events
            .iter()
            .find_map(|(_, s)| match s {
                Stage::Decimating(q) => Some(*q),
                _ => None,
            })
            .unwrap_or(1)
    }

    /// Seconds per stage group, in the order first met, until `end`: the time before the first
    /// stage after reading is the read.
    pub fn seconds(&self, end: Instant) -> Vec<(&'static str, f64)> {
        let mut out: Vec<(&'static str, f64)> = vec![];
        let mut add = |name: &'static str, s: f64| match out.iter_mut().find(|(n, _)| *n == name) {
            Some(e) => e.1 += s,
            None => out.push((name, s)),
        };
        let mut from = self.t0;
        let mut group = "read";
        for (t, s) in &self.events {
            add(group, (*t - from).as_secs_f64());
            from = *t;
            group = match s {
                Stage::Reading(_) => "read",
                Stage::Gaps | Stage::Excitation => "checks (gaps, base motion, path)",
                Stage::Decimating(_) => "decimate (anti-aliased FIR)",
                Stage::Estimating(IdentPath::Frf, _) | Stage::Welch(_) => {
                    "FRF (Welch; base from command or tracking filter)"
                }
                Stage::Estimating(..) => "free-decay estimators",
                Stage::Estimators(_) => "estimators (LSCF/LSCE, stabilisation)",
                Stage::Screening => "screening",
                Stage::Refining(_) => "refinement (maximum likelihood)",
            };
        }
        add(group, (end - from).as_secs_f64());
        out
    }
}

/// Peak resident set size (MB) of this process: VmHWM of /proc/self/status (Linux).
pub fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The peer's script: `script` if given, else `bench/identify_peer.py` of the checkout the
/// binary sits in, or of the working directory or one of its parents.
fn peer_script(script: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = script {
        if !p.exists() {
            bail!("--peer-script {}: no such file", p.display());
        }
        return Ok(p.to_path_buf());
    }
    let rel = Path::new("bench/identify_peer.py");
    let exe = std::env::current_exe().ok();
    let cwd = std::env::current_dir().ok();
    exe.iter()
        .chain(cwd.iter())
        .flat_map(|d| d.ancestors().map(|a| a.join(rel)))
        .find(|p| p.exists())
        .context("bench/identify_peer.py not found beside the binary or above the working directory; give --peer-script")
}

/// Runs the peer on `file` with the decimation `q`, segment, band, order and modes of `id`;
/// returns its JSON and its wall time (s, process start to end).
fn run_peer(
    python: &Path,
    script: &Path,
    file: &Path,
    id: &Identification,
    q: usize,
    window: Window,
    max_order: usize,
) -> Result<(serde_json::Value, f64)> {
    let (r, frf) = id
        .frf_result
        .as_ref()
        .context("the peer does the FRF path's work; this recording took the free-decay path")?;
    let whole = frf.n_averages == 1;
    let win = match (whole, window) {
        (false, _) | (true, Window::Hamming) => "hamming",
        (true, Window::Hann) => "hann",
        _ => "boxcar",
    };
    let near: Vec<String> = id.modes.iter().map(|m| format!("{}", m.freq_hz)).collect();
    let t = Instant::now();
    let out = std::process::Command::new(python)
        .arg(script)
        .arg(file)
        .args(["--q", &q.to_string()])
        .args([
            "--nperseg",
            &if whole { 0 } else { frf.nperseg }.to_string(),
        ])
        .args(["--window", win])
        .args(["--band", &format!("{},{}", r.band_hz.0, r.band_hz.1)])
        .args(["--order", &max_order.to_string()])
        .args(["--near", &near.join(",")])
        .output()
        .with_context(|| format!("cannot run {}", python.display()))?;
    let wall = t.elapsed().as_secs_f64();
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        bail!(
            "{} {} failed: {}",
            python.display(),
            script.display(),
            err.lines().last().unwrap_or("no message")
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().last().unwrap_or("");
    let v =
        serde_json::from_str(line).with_context(|| format!("peer output is not JSON: {line}"))?;
    Ok((v, wall))
}

/// What `--bench` needs besides the identification.
pub struct BenchArgs<'a> {
    /// The recording.
    pub file: &'a Path,
    /// Python with numpy, scipy and sdypy-EMA (`None`: the peer is not run).
    pub python: Option<&'a Path>,
    /// The peer's script (`None`: found beside the binary).
    pub script: Option<&'a Path>,
    /// The FRF window asked for (the peer's window for a one-segment FRF).
    pub window: Window,
    /// Highest model order.
    pub max_order: usize,
}

/// Prints the stage table, the peak RSS, and the peer's run with the ratio.
pub fn print_bench(a: &BenchArgs, id: &Identification, clock: &StageClock, end: Instant) {
    let secs = clock.seconds(end);
    let total: f64 = secs.iter().map(|(_, s)| s).sum();
    let rss = peak_rss_mb();
    println!("bench: beamtool identify {}", a.file.display());
    for (name, s) in &secs {
        println!("  {name:<52} {s:>8.3} s");
    }
    let rss_text = rss.map_or("peak RSS n/a (no /proc/self/status)".into(), |m| {
        format!("peak RSS {m:.0} MB (VmHWM)")
    });
    println!("  {:<52} {total:>8.3} s, {rss_text}", "total");
    let Some(python) = a.python else {
        println!(
            "peer: not run (give --peer-python PATH, a Python with numpy, scipy and sdypy-EMA)"
        );
        return;
    };
    let q = clock.decimation();
    let run = peer_script(a.script)
        .and_then(|s| run_peer(python, &s, a.file, id, q, a.window, a.max_order));
    let (v, wall) = match run {
        Ok(x) => x,
        Err(e) => {
            println!("peer: not run ({e:#})");
            return;
        }
    };
    let num = |p: &str| v.pointer(p).and_then(|x| x.as_f64()).unwrap_or(f64::NAN);
    let ver = |k: &str| v["versions"][k].as_str().unwrap_or("?").to_string();
    println!(
        "peer: scipy {} csd/welch H1 + sdypy-EMA {} LSCF (numpy {}), decimation {q}, segment, band and order as beamtool's:",
        ver("scipy"),
        ver("sdypy-EMA"),
        ver("numpy")
    );
    let stages = ["import", "read", "decimate", "frf", "lscf"];
    let parts: Vec<String> = stages
        .iter()
        .map(|s| format!("{s} {:.3}", num(&format!("/stages_s/{s}"))))
        .collect();
    let work = num("/total_s") - num("/stages_s/import");
    println!(
        "  {} s; process {wall:.3} s, work without interpreter start and imports {work:.3} s; peak RSS {:.0} MB",
        parts.join(", "),
        num("/peak_rss_mb")
    );
    let modes: Vec<String> = v["modes"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|m| match (m[0].as_f64(), m[1].as_f64()) {
                    (Some(f), Some(z)) if f > 0.0 => format!("{f:.4} Hz zeta {z:.5}"),
                    _ => "no stable pole".into(),
                })
                .collect()
        })
        .unwrap_or_default();
    let ours: Vec<String> = id
        .modes
        .iter()
        .map(|m| format!("{:.4} Hz zeta {:.5}", m.freq_hz, m.zeta))
        .collect();
    println!(
        "  modes near beamtool's ({}): {}",
        ours.join("; "),
        modes.join("; ")
    );
    println!(
        "  ratio peer/beamtool: {:.2} (process) , {:.2} (work only); peak RSS {:.2}",
        wall / total,
        work / total,
        num("/peak_rss_mb") / rss.unwrap_or(f64::NAN)
    );
}
