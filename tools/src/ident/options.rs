//! What the FRF identification is asked ([`IdentOptions`]: estimators, channels, Welch, band,
//! orders, stabilisation) and what one estimator answers ([`MethodResult`]). Apart from
//! [`super::pipeline`], which runs the estimators, and [`super::estimator`], which defines
//! them, so that both read the same types and neither imports the other's.

use super::frf::{InputChannel, OutputChannel, WelchOptions, Window};
use super::stabilisation::{Diagram, StabCriteria};
use super::ModeEstimate;
use anyhow::{bail, Result};
use serde::Serialize;

/// An estimator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Method {
    /// Least-squares complex frequency domain, stabilised over orders (the default).
    Lscf,
    /// Least-squares complex exponential (the paper's), stabilised over orders.
    Lsce,
    /// Peak picking with half-power damping.
    Peak,
    /// Logarithmic decrement + damped-sinusoid fit on the free decays after each move.
    LogDec,
}

impl Method {
    /// `lscf`, `lsce`, `peak`, `logdec`; `all` = every method.
    pub fn parse_list(s: &str) -> Result<Vec<Method>> {
        let mut v = Vec::new();
        for w in s.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            match w.to_ascii_lowercase().as_str() {
                "lscf" | "plscf" => v.push(Method::Lscf),
                "lsce" => v.push(Method::Lsce),
                "peak" | "pp" | "half-power" => v.push(Method::Peak),
                "logdec" | "decay" | "free-decay" => v.push(Method::LogDec),
                "all" => v.extend([Method::Lscf, Method::Lsce, Method::Peak, Method::LogDec]),
                _ => bail!("unknown method `{w}` (lscf, lsce, peak, logdec, all)"),
            }
        }
        if v.is_empty() {
            bail!("no identification method given");
        }
        v.dedup();
        Ok(v)
    }

    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Lscf => "lscf",
            Method::Lsce => "lsce",
            Method::Peak => "peak",
            Method::LogDec => "logdec",
        }
    }
}

/// Options of [`identify_recording`].
#[derive(Clone, Debug, Serialize)]
pub struct IdentOptions {
    /// Estimators; the first is the primary one (its modes are the result).
    pub methods: Vec<Method>,
    /// FRF input.
    pub input: InputChannel,
    /// FRF output.
    pub output: OutputChannel,
    /// FRF estimation.
    pub welch: WelchOptions,
    /// Band (Hz); `None` = where the input auto-spectrum is within 30 dB of its maximum.
    pub band_hz: Option<(f64, f64)>,
    /// Highest LSCF order / LSCE number of poles.
    pub max_order: usize,
    /// Damping ratios above this are not physical modes here.
    pub zeta_max: f64,
    /// Keep only the this many best-supported modes (by stable poles).
    pub n_modes: Option<usize>,
    /// Stabilisation criteria.
    pub criteria: StabCriteria,
    /// Tracking-filter a swept kinematic input (base acceleration/position) before the FRF
    /// ([`super::denoise`]); skipped with a warning when the input is not a sweep, and never
    /// applied to the force (it also carries the beam's reaction at its resonances).
    pub track_input: bool,
    /// Sanathanan–Koerner iterations of LSCF ([`super::lscf::LscfLines::poles`]): reduce the
    /// damping bias of output noise; 1 by default (more iterations lost poles at low orders;
    /// docs/ident.md, "Numbers behind the design choices").
    pub sk_iterations: usize,
    /// Refine the primary FRF method's modes by the output-error (maximum-likelihood) fit of
    /// [`super::mlfit`]; its Gauss–Newton σ joins the uncertainty. On by default.
    pub ml_refine: bool,
}

impl Default for IdentOptions {
    /// LSCF on H1 of base acceleration → tip deflection, whole record as one segment with a
    /// rectangular window (a sweep recorded from rest to rest), orders up to 32.
    fn default() -> Self {
        IdentOptions {
            methods: vec![Method::Lscf],
            input: InputChannel::BaseAccel,
            output: OutputChannel::TipDeflection,
            welch: WelchOptions {
                nperseg: None,
                overlap: 0.5,
                window: Window::Rectangular,
                detrend: super::frf::Detrend::Mean,
                pad: 1,
            },
            band_hz: None,
            max_order: 32,
            zeta_max: 0.2,
            n_modes: None,
            criteria: StabCriteria::default(),
            track_input: true,
            sk_iterations: 1,
            ml_refine: true,
        }
    }
}

/// Result of one estimator.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// Estimator.
    pub method: Method,
    /// Modes, ascending in frequency; uncertainty = spread over model orders (LSCF, LSCE),
    /// over free-decay segments and sub-windows (logdec), 0 (peak picking: one estimate).
    pub modes: Vec<ModeEstimate>,
    /// The stabilisation diagram (LSCF, LSCE).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diagram: Option<Diagram>,
}
