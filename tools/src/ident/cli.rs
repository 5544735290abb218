//! `identify`: modes of a free decay in a NumPy `.npy` ([time; signal]) or a recording CSV.

use super::freedecay::{identify_free_decay, FreeDecayOptions, FreeDecayResult};
use crate::recording::Recording;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// `identify` arguments.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// Recording: `.npy` (2, N) [time_s; signal] or recording CSV (uses the tip deflection
    /// tip_pos_m − base_pos_m after the base last moved).
    pub recording: PathBuf,
    /// Lowest frequency considered (Hz).
    #[arg(long, default_value_t = 0.2)]
    pub f_min_hz: f64,
    /// Highest frequency considered (Hz).
    #[arg(long, default_value_t = 500.0)]
    pub f_max_hz: f64,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The free-decay part of a recording: the tip deflection (tip − base, or tip alone) from the
/// last sample at which the base moved. Returns (time, signal, description).
pub fn free_decay_of(path: &Path) -> Result<(Vec<f64>, Vec<f64>, String)> {
    if path.extension().is_some_and(|e| e == "npy") {
        let (t, x) = Recording::read_npy(path)?;
        return Ok((t, x, format!("{} (row 1 of the .npy)", path.display())));
    }
    let rec = Recording::read_csv(path)?;
    let tip = rec
        .tip_pos_m
        .as_ref()
        .with_context(|| format!("{}: no tip_pos_m column to identify from", path.display()))?;
    let base = rec.base_pos_m.as_ref().or(rec.base_cmd_m.as_ref());
    let (sig, start) = match base {
        Some(b) => {
            let moved = b
                .windows(2)
                .rposition(|w| (w[1] - w[0]).abs() > 1e-9)
                .map_or(0, |k| k + 1);
            (
                tip.iter().zip(b).map(|(t, b)| t - b).collect::<Vec<_>>(),
                moved,
            )
        }
        None => (tip.clone(), 0),
    };
    if rec.len() - start < 64 {
        bail!(
            "{}: only {} samples after the base stopped moving; a free decay needs more",
            path.display(),
            rec.len() - start
        );
    }
    Ok((
        rec.time_s[start..].to_vec(),
        sig[start..].to_vec(),
        format!(
            "{}: tip deflection from t = {:.3} s (base still)",
            path.display(),
            rec.time_s[start]
        ),
    ))
}

/// Prints a result as a table a controls engineer expects.
pub fn print_result(what: &str, r: &FreeDecayResult) {
    println!(
        "{what}: sample rate {:.1} Hz, decay segment {:.3}..{:.3} s",
        r.sample_rate_hz, r.segment_s.0, r.segment_s.1
    );
    for w in &r.warnings {
        println!("  warning: {w}");
    }
    println!(
        "  mode 1 log decrement (eqs. 28-29, {} peaks): f = {:.4} Hz, zeta = {:.5}",
        r.log_decrement.2, r.log_decrement.0, r.log_decrement.1
    );
    println!(
        "  mode 1 damped-sinusoid fit:                f = {:.4} Hz, zeta = {:.5}",
        r.sinusoid_fit.0, r.sinusoid_fit.1
    );
    println!(
        "  {:>4} {:>12} {:>10} {:>10} {:>10}",
        "mode", "f (Hz)", "+-1sd", "zeta", "+-1sd"
    );
    for (i, m) in r.modes.iter().enumerate() {
        println!(
            "  {:>4} {:>12.4} {:>10.4} {:>10.5} {:>10.5}",
            i + 1,
            m.freq_hz,
            m.freq_hz_std,
            m.zeta,
            m.zeta_std
        );
    }
}

/// `beamtool identify`.
pub fn identify(a: IdentifyArgs) -> Result<()> {
    let (t, x, what) = free_decay_of(&a.recording)?;
    let r = identify_free_decay(
        &t,
        &x,
        &FreeDecayOptions {
            f_min_hz: a.f_min_hz,
            f_max_hz: a.f_max_hz,
            ..Default::default()
        },
    )?;
    print_result(&what, &r);
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&r)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}
