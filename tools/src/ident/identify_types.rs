//! The types of [`super::identify()`] — the path asked for and taken, its options, its
//! stages, and its result — and the Rayleigh coefficients of a result (eq. 22): shared by
//! `identify.rs` and `identify_paths.rs` (split out so that neither imports the other's
//! types in a circle).

use super::freedecay::{FreeDecayOptions, FreeDecayResult};
use super::frf::Frf;
use super::pipeline::{IdentOptions, IdentResult};
use super::ModeEstimate;
use crate::recording::fmt_sig;
use anyhow::{bail, Result};
use serde::Serialize;
use std::fmt;

/// Which path to take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum PathChoice {
    /// Decide from the recording ([`choose_path`]).
    Auto,
    /// FRF of the input/output recording and the FRF estimators.
    Frf,
    /// Free decay of the tip (after the base's last move, if it moves).
    Decay,
    /// Output-only (SSI-cov) identification of the tip response ([`super::ssi`]).
    OutputOnly,
    /// Peaks of Klipper's PSD of a raw accelerometer file ([`super::klipper_raw`]).
    Spectrum,
}

impl PathChoice {
    /// `auto`, `frf`, `decay`, `output-only`, `spectrum`.
    pub fn from_name(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(PathChoice::Auto),
            "frf" | "sweep" => Ok(PathChoice::Frf),
            "decay" | "free-decay" | "ringdown" | "ring-down" => Ok(PathChoice::Decay),
            "output-only" | "oma" | "ssi" => Ok(PathChoice::OutputOnly),
            "spectrum" | "psd" => Ok(PathChoice::Spectrum),
            _ => {
                bail!("unknown identification path `{s}` (auto, frf, decay, output-only, spectrum)")
            }
        }
    }
}

/// The path taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum IdentPath {
    /// The whole (clean) recording is a free decay of the tip.
    FreeDecay,
    /// Free decay of the tip deflection after the base's last move.
    RingDown,
    /// FRF of the input/output recording.
    Frf,
    /// Peaks of a magnitude spectrum (LabVIEW `.lvm` of an impact test, [`super::magspec`]).
    Spectrum,
    /// Output-only: SSI-cov of a stationary response with no usable input ([`super::ssi`]).
    OutputOnly,
    /// Pooled ring-downs after the base's steps, base as input ([`super::ringdowns`]).
    RingDowns,
    /// Peaks of Klipper's PSD of a raw accelerometer file of a resonance test
    /// ([`super::klipper_raw`]).
    KlipperPsd,
}

impl fmt::Display for IdentPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            IdentPath::FreeDecay => "free decay",
            IdentPath::RingDown => "ring-down after the last move",
            IdentPath::Frf => "FRF (input/output)",
            IdentPath::Spectrum => "magnitude spectrum",
            IdentPath::OutputOnly => "output-only (SSI-cov)",
            IdentPath::RingDowns => "pooled ring-downs after steps",
            IdentPath::KlipperPsd => "Klipper PSD peaks (spectrum path)",
        })
    }
}

/// Options of [`identify`].
#[derive(Clone, Debug)]
pub struct IdentifyOptions {
    /// Path (default: auto).
    pub path: PathChoice,
    /// FRF path options (estimators, channels, Welch, band, orders).
    pub frf: IdentOptions,
    /// Free-decay path options (band).
    pub decay: FreeDecayOptions,
    /// Longest FRF segment (samples): a longer one is Welch-averaged in Hamming segments of
    /// this length (bounded memory); the segment itself follows resolution ([`super::longrec`]).
    pub max_segment: usize,
    /// How the recording file is read by [`identify_file`] (`--columns`, `--axis`).
    pub read: crate::recording::ReadOptions,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            path: PathChoice::Auto,
            frf: IdentOptions::default(),
            decay: FreeDecayOptions::default(),
            max_segment: 1 << 19,
            read: Default::default(),
        }
    }
}

/// A stage of [`identify`], for progress reports.
#[derive(Clone, Debug, PartialEq)]
pub enum Stage {
    /// Reading the file (rows so far).
    Reading(usize),
    /// Checking the time base for gaps.
    Gaps,
    /// Classifying the excitation.
    Excitation,
    /// Estimating on the chosen path (with the number of samples).
    Estimating(IdentPath, usize),
    /// Screening the modes.
    Screening,
    /// Maximum-likelihood refinement of this many modes.
    Refining(usize),
    /// Anti-aliased decimation by this factor ([`decimation_factor`]).
    Decimating(usize),
    /// Welch FRF with segments of this many samples.
    Welch(usize),
    /// The FRF estimators on this many lines in the band.
    Estimators(usize),
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stage::Reading(n) => write!(f, "reading: {n} rows"),
            Stage::Gaps => write!(f, "checking the time base for gaps"),
            Stage::Excitation => write!(f, "classifying the excitation"),
            Stage::Estimating(p, n) => write!(f, "estimating modes: {p}, {n} samples"),
            Stage::Screening => write!(f, "screening the modes"),
            Stage::Refining(n) => write!(f, "maximum-likelihood refinement of {n} mode(s)"),
            Stage::Decimating(q) => write!(f, "decimating by {q} (anti-aliased FIR)"),
            Stage::Welch(n) => write!(f, "FRF: Welch segments of {n} samples"),
            Stage::Estimators(n) => write!(f, "FRF estimators on {n} lines"),
        }
    }
}

/// A mode an estimator proposed that is not in the table, and why.
#[derive(Clone, Debug, Serialize)]
pub struct RejectedMode {
    /// The estimate.
    pub mode: ModeEstimate,
    /// Why it is not a physical mode.
    pub reason: String,
}

/// The base's motion ([`base_motion`]).
#[derive(Clone, Debug, Serialize)]
pub struct BaseMotion {
    /// Noise of the still base (m, 1.4826 × MAD of the last 10 % of the recording).
    pub noise_m: f64,
    /// Still band half-width (m): 6 × noise (at least 10⁻⁷ of the range).
    pub still_band_m: f64,
    /// Range of the base position (m).
    pub range_m: f64,
    /// First sample from which the base stays within the still band of its final position.
    pub still_from: usize,
    /// Direction reversals beyond the still band (or 0.5 % of the range) before `still_from`.
    pub reversals: usize,
    /// True when the base's final 10 % is itself still (its noise < 5 % of the range), or the
    /// base never moves beyond 20 × its noise (range against the larger of the tail's noise
    /// and the sample-to-sample noise, 1.4826 × MAD of second differences / √6).
    pub ends_still: bool,
    /// When the base's excitation of the tip's dominant mode ([`super::quiet`]) lets the
    /// ring-down start before the base settles within its still band: that start (then
    /// `still_from`), the excitation bound and the amplitudes it was judged against.
    pub quiet: Option<super::quiet::QuietStart>,
}

/// The result of [`identify`].
#[derive(Clone, Debug, Serialize)]
pub struct Identification {
    /// Physical modes, ascending in frequency, with 1-σ.
    pub modes: Vec<ModeEstimate>,
    /// The path taken.
    pub path: IdentPath,
    /// Why this path, and what it used (segment, channels, method).
    pub reason: String,
    /// Rayleigh α1 (1/s), α2 (s) from the first two modes (eq. 22).
    pub rayleigh: Option<(f64, f64)>,
    /// Estimates not in the table, with the reason.
    pub rejected: Vec<RejectedMode>,
    /// Warnings (gaps, jitter, resolution, refinement, …).
    pub warnings: Vec<String>,
    /// Time span used (s).
    pub span_s: (f64, f64),
    /// Sample rate (Hz) of the span used.
    pub sample_rate_hz: f64,
    /// The base's motion, when the recording has a base channel.
    pub base: Option<BaseMotion>,
    /// FRF path: the estimators' full result.
    #[serde(skip)]
    pub frf_result: Option<(IdentResult, Frf)>,
    /// Free-decay paths: the analysis.
    #[serde(skip)]
    pub decay_result: Option<FreeDecayResult>,
}

/// Rayleigh α1, α2 (eq. 22) of the first two modes; a negative coefficient is reported as a
/// warning (the damping of these two modes is not of Rayleigh form).
pub(crate) fn rayleigh(modes: &[ModeEstimate], warnings: &mut Vec<String>) -> Option<(f64, f64)> {
    if modes.len() < 2 {
        return None;
    }
    let w = |m: &ModeEstimate| 2.0 * std::f64::consts::PI * m.freq_hz;
    let (a1, a2) = crate::model::galerkin::rayleigh_coefficients(
        w(&modes[0]),
        modes[0].zeta,
        w(&modes[1]),
        modes[1].zeta,
    );
    if a1 < 0.0 || a2 < 0.0 {
        warnings.push(format!(
            "Rayleigh coefficients α1 = {} 1/s, α2 = {} s: one is negative, so the damping of modes 1 and 2 is not of Rayleigh form (eq. 22)",
            fmt_sig(a1, 4),
            fmt_sig(a2, 4)
        ));
    }
    Some((a1, a2))
}
