//! Modal identification (paper §3, §5.2): natural frequencies and damping ratios with their
//! uncertainty, from free decays or from input/output recordings.
//!
//! - [`spectrum`]: Hamming-windowed amplitude spectra and peak picking with parabolic refinement.
//! - [`freedecay`]: automatic free-decay segment, logarithmic decrement (eqs. 28–29) and a
//!   least-squares damped-sinusoid fit (Levenberg–Marquardt).

pub mod cli;
pub mod freedecay;
pub mod spectrum;

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
