//! Modal identification (paper §3, §5.2): natural frequencies and damping ratios with their
//! uncertainty, from free decays or from input/output recordings.
//!
//! - [`spectrum`]: Hamming-windowed amplitude spectra and peak picking with parabolic refinement.
//! - [`freedecay`]: automatic free-decay segment, logarithmic decrement (eqs. 28–29) and a
//!   least-squares damped-sinusoid fit (Levenberg–Marquardt).
//! - [`sweep`]: linear/exponential sine sweeps (eqs. 33–34) with stroke, acceleration and
//!   tip-deflection limits, as command CSV.
//! - [`frf`]: Welch H1/H2/coherence (Hamming window by default, overlap, detrending).
//! - [`lscf`], [`lsce`], [`peak`]: the estimators; [`poles`] their common pole algebra;
//!   [`estimator`]: the one trait they (and the maximum-likelihood refinement) sit behind.
//! - [`magspec`]: modes of a magnitude-only spectrum (LabVIEW `.lvm` of an impact test).
//! - [`mlfit`]: maximum-likelihood (output-error) refinement of the modes on the FRF.
//! - [`stabilisation`]: diagrams over model orders and automatic mode selection.
//! - [`identify`]: **the entry point** [`identify()`]: any recording (sweep, free decay, moves +
//!   ring-down, with gaps), the path taken and why, only physical modes.
//! - [`pipeline`]: [`identify_recording`] (the FRF path) and [`identify_decay`].
//! - [`report`]: tables (text) and plots (SVG).
//!
//! # Public API
//! ```ignore
//! let (res, frf) = beamtools::ident::identify_recording(&rec, &IdentOptions::default())?;
//! let first: Option<(f64, f64)> = res.modes.first().map(|m| (m.freq_hz, m.zeta)); // Hz, ζ; σ in *_std
//! let res = beamtools::ident::identify_decay(&t, &x, &FreeDecayOptions::default())?;
//! ```
//! Uncertainties are 1-σ: for LSCF/LSCE the spread (1.4826 × MAD) of the stable poles across
//! model orders, for log decrement the spread across free-decay segments and sub-windows;
//! [`IdentResult::modes`] widens the primary method's σ by the standard deviation of every
//! method's estimate of the same mode (within 3 % in frequency).

pub mod denoise;
pub mod estimator;
pub mod freedecay;
pub mod frf;
pub mod identify;
pub mod identify_paths;
pub mod identify_types;
pub mod klipper_raw;
pub mod longrec;
pub mod lsce;
pub mod lscf;
pub mod magspec;
pub mod mlfit;
pub mod oma_sim;
pub mod options;
pub mod peak;
pub mod pipeline;
pub mod poles;
pub mod protocol;
pub mod quiet;
pub mod report;
pub(crate) mod ringdown_fit;
pub mod ringdown_sigma;
pub mod ringdown_sim;
pub mod ringdowns;
pub mod spectrum;
pub mod ssi;
pub mod stabilisation;
pub mod sweep;

pub use identify::{identify, IdentPath, Identification, IdentifyOptions, PathChoice, Stage};
pub use pipeline::{identify_decay, identify_recording, IdentOptions, IdentResult, Method};

use serde::Serialize;

/// One identified mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModeEstimate {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// 1-σ uncertainty of the natural frequency (Hz): spread across methods and sub-windows.
    pub freq_hz_std: f64,
    /// 1-σ uncertainty of the damping ratio.
    pub zeta_std: f64,
    /// How it was obtained.
    pub method: String,
}

/// Sample standard deviation (0 for fewer than 2 values).
pub fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}
