//! `tune` on a measured spectrum (Klipper's `resonances_*.csv` / `calibration_data_*.csv`, or
//! the PSD Klipper computes from a raw accelerometer file, [`crate::recording::rawpsd`]):
//! spectrum → design ([`crate::shaping::spectrum::design_for_spectrum`], scored by Klipper's
//! metrics beside Klipper's own recommendation) → board.
//!
//! Steps: every option is checked and the spectrum read before the board is touched
//! ([`super::inputs::check_inputs`]); the design is shown ([`SpectrumView::designed`]); the
//! board (`--port`, or the virtual board on a PTY) is read, the design programmed and its
//! impulse table read back identical ([`crate::board::steps::program`]), certified
//! `predicted-only` and saved — only with [`TuneOptions::accept_predicted`]: a spectrum holds
//! no time signal, so nothing can measure the shaper; the design rests on the remaining
//! vibrations on the measured spectrum (Klipper's estimate) being within the budget of
//! Klipper's own recommendation. Without it the board is not touched and the report says
//! why ([`SpectrumReport::saved`] false). Any board error restores the previous running
//! configuration.

use super::{check_inputs, connect, TuneError, TuneOptions};
use crate::board::steps::{program, read_board, restore, StepError};
use crate::recording::psd::{read_spectrum, KlipperSpectrum};
use crate::shaping::klipper::FitSpectrum;
use crate::shaping::spectrum::{design_for_spectrum, Comparison, Objective, VIBRATION_MARGIN};
use crate::shaping::Candidate;
use beamshaper::config::{Certificate, Verified, MAX_MODES};
use std::path::Path;

/// What the spectrum job found and did.
#[derive(Clone, Debug)]
pub struct SpectrumReport {
    /// The spectrum as read.
    pub spectrum: KlipperSpectrum,
    /// The bins scored (Klipper's fitting PSD).
    pub fit: FitSpectrum,
    /// Ours beside Klipper's.
    pub comparison: Comparison,
    /// The board's port.
    pub port: String,
    /// Impulses programmed and read back.
    pub programmed_impulses: usize,
    /// The board was programmed and saved (as `predicted-only`); false: not touched, as
    /// `--accept-predicted` was not given.
    pub saved: bool,
}

/// Told each step's value (the CLI prints, plots and writes files).
pub trait SpectrumView {
    /// The design was made, before the board is touched. An error stops the job.
    fn designed(
        &mut self,
        _s: &KlipperSpectrum,
        _fit: &FitSpectrum,
        _c: &Comparison,
    ) -> Result<(), super::Foreign> {
        Ok(())
    }
}

/// The shaper of a comparison as the board's candidate (its worst-case V is the remaining
/// vibrations on the measured spectrum, %).
pub fn candidate(c: &Comparison) -> Candidate {
    Candidate {
        name: c.ours.name.clone(),
        modes: c.ours.modes.clone(),
        shaper: c.ours.shaper.clone(),
        worst_pct: 100.0 * c.ours.metrics.vibrations,
    }
}

/// The spectrum at `path`: a Klipper spectrum file as written ([`read_spectrum`]), or the PSD
/// Klipper computes from a raw accelerometer file ([`crate::recording::rawpsd`]).
/// Errors: those of the file's reader.
pub fn load_spectrum(path: &Path) -> anyhow::Result<KlipperSpectrum> {
    match crate::recording::rawpsd::is_raw_file(path) {
        true => crate::recording::rawpsd::read_raw_spectrum(path),
        false => read_spectrum(path),
    }
}

/// Reads ([`load_spectrum`]: a spectrum or a raw accelerometer file) and designs for `objective` with the box's `vibration_margin` (fraction; see
/// [`design_for_spectrum`]) (no board): the spectrum at `path`, its fitting bins and
/// the comparison.
/// Errors: the file's (see [`load_spectrum`]).
pub fn design_file(
    path: &Path,
    objective: Objective,
    vibration_margin: f64,
) -> anyhow::Result<(KlipperSpectrum, FitSpectrum, Comparison)> {
    let s = load_spectrum(path)?;
    let fit = FitSpectrum::from_spectrum(&s);
    if fit.freq_hz.len() < 3 {
        anyhow::bail!(
            "spectrum file {}: fewer than 3 bins at or below {} Hz",
            path.display(),
            crate::shaping::klipper::MAX_FREQ_HZ
        );
    }
    let c = design_for_spectrum(&fit, objective, vibration_margin);
    Ok((s, fit, c))
}

/// The job (module docs) on the spectrum at `o.recording`.
pub fn tune_spectrum(
    o: &TuneOptions,
    view: &mut dyn SpectrumView,
) -> Result<SpectrumReport, TuneError> {
    let inputs = check_inputs(o)?;
    let path = o.recording.clone().unwrap_or_default();
    let (spectrum, fit, comparison) = design_file(&path, Objective::default(), VIBRATION_MARGIN)
        .map_err(|e| TuneError::Other(e.into()))?;
    view.designed(&spectrum, &fit, &comparison)
        .map_err(TuneError::View)?;
    if !o.accept_predicted {
        return Ok(SpectrumReport {
            spectrum,
            fit,
            comparison,
            port: String::new(),
            programmed_impulses: 0,
            saved: false,
        });
    }
    let mut bench = connect(o, &inputs)?;
    let before = read_board(&mut bench.session)?;
    let c = candidate(&comparison);
    let certificate = Certificate {
        verified: Verified::PredictedOnly,
        band_hz: [None; MAX_MODES],
    };
    let done = program(&mut bench.session, &c)
        .and_then(|()| bench.session.certify(&certificate).map_err(StepError::from))
        .and_then(|()| match o.payload {
            Some(n) => bench.session.payload_store(n).map_err(StepError::from),
            None => Ok(()),
        })
        .and_then(|()| bench.session.save().map_err(StepError::from));
    if let Err(e) = done {
        return Err(TuneError::Restored {
            restored: restore(&mut bench.session, &before),
            source: Box::new(e.into()),
        });
    }
    Ok(SpectrumReport {
        spectrum,
        fit,
        programmed_impulses: c.shaper.len(),
        comparison,
        port: bench.port,
        saved: true,
    })
}
