//! Reading and preparing one recording for the diagnosis: the step every front end (the CLI,
//! the proof harness, the Python package) shares, so each exercises the same preparation.
//!
//! A recording is read leaving gaps in the tip camera and the force channel (a camera may lose
//! its target for a while: those samples are left out of the fit, not refused), camera glitches
//! on the tip are mended ([`crate::recording::glitch`]), sensor directions are brought to the
//! format's ([`crate::recording::orient`], low-pass corners at ¼ and 10 × the rig's first
//! clamped natural frequency), then sensor zeros are taken from the rest
//! ([`crate::recording::zero`]).

use crate::diagnose::model::Prepared;
use crate::model::Rig;
use crate::recording::ReadOptions;
use anyhow::Result;
use std::path::Path;

/// One prepared recording and the notes its reading and preparation left (format guesses,
/// mended glitches, flipped sensor directions, zeros), in the order they were made.
pub struct Loaded {
    /// The recording as the diagnosis fits it.
    pub prepared: Prepared,
    /// Human-readable notes, one sentence each.
    pub notes: Vec<String>,
}

/// Reads and prepares the recording at `path` for `rig`, its columns named as the project
/// names them (`time_s`, `base_pos_m`, …).
///
/// Errors: the file cannot be read or parsed (the recording reader's messages), or the
/// recording is too short, still or inconsistent for the diagnosis ([`Prepared::new`]).
pub fn load(path: &Path, rig: &Rig) -> Result<Loaded> {
    load_with(path, rig, &ReadOptions::default())
}

/// [`load`] with the reading options `opts`: `opts.columns` maps the project's channels to
/// the file's columns, each with its scale to SI (`beamtool diagnose --columns`, the mapping
/// `identify` and `tune` take).
///
/// Errors: as [`load`], and a mapped column the file does not have.
pub fn load_with(path: &Path, rig: &Rig, opts: &ReadOptions) -> Result<Loaded> {
    let (rec, gaps) = crate::recording::Recording::read_csv_leaving_gaps_with(
        path,
        &["tip_pos_m", "force_n"],
        opts,
    )?;
    let rec = crate::recording::glitch::mend_tip_glitches(rec);
    let rec = match first_natural_freq_hz(rig) {
        Some(f1) => crate::recording::orient::orient(rec, f1 / 4.0, 10.0 * f1),
        None => rec,
    };
    let rec = crate::recording::zero::zero_at_rest(rec);
    let mut prepared = Prepared::new(&path.display().to_string(), &rec)?.with_gaps(&gaps)?;
    prepared.free_start = !crate::recording::zero::starts_at_rest(&rec);
    Ok(Loaded {
        prepared,
        notes: rec.notes,
    })
}

/// The rig file's first clamped natural frequency (Hz); `None` for a carriage-only rig or a
/// beam the model refuses (the diagnosis then reports why).
fn first_natural_freq_hz(rig: &Rig) -> Option<f64> {
    use crate::model::{BeamModel, ModelOptions};
    let modes = BeamModel::new(rig, &ModelOptions::default())
        .ok()?
        .clamped_modes()
        .ok()?;
    modes
        .omega_rad_s
        .first()
        .map(|w| w / (2.0 * std::f64::consts::PI))
}
