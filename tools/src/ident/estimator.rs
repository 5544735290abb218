//! The FRF estimators behind one trait, so that [`super::pipeline::identify_frf`] is a loop.
//!
//! An [`FrfEstimator`] takes an FRF and the band to work in and returns its modes (a
//! [`MethodResult`]): [`Lscf`] and [`Lsce`] stabilised over model orders
//! ([`super::stabilisation`]), [`PeakPicking`] with half-power damping, and [`MlRefined`], any of
//! them followed by the maximum-likelihood (output-error) refinement of [`super::mlfit`].
//! [`frf_estimators`] builds the list an [`IdentOptions`] asks for: its FRF methods in order,
//! the first one refined when `ml_refine` is set and it is LSCF or LSCE. The log decrement works
//! on the recording's free decays, not on the FRF (`super::pipeline::identify_segments`).

use super::frf::Frf;
use super::lsce::{impulse_response, lsce_poles};
use super::lscf::LscfLines;
use super::mlfit::refine_estimates;
use super::options::{IdentOptions, Method, MethodResult};
use super::peak::pick_peaks;
use super::stabilisation::{diagram, Diagram, StableMode};
use super::ModeEstimate;
use crate::progress::Progress;
use anyhow::Result;

/// What an estimator works on: the FRF, the band (Hz) and the options.
pub struct FrfContext<'a> {
    /// The FRF (H1 is used).
    pub frf: &'a Frf,
    /// Band (Hz), validated: 0 ≤ lo < hi ≤ Nyquist, at least 16 lines.
    pub band_hz: (f64, f64),
    /// Orders, damping limit, stabilisation criteria, modes kept.
    pub opts: &'a IdentOptions,
}

/// An estimator of modes from an FRF.
pub trait FrfEstimator {
    /// Which method this is.
    fn method(&self) -> Method;
    /// The modes in `cx.band_hz`, ascending in frequency. `warnings` collects what the user
    /// should know (resolution limits, a skipped refinement); `progress` is told the orders.
    fn estimate(
        &self,
        cx: &FrfContext,
        warnings: &mut Vec<String>,
        progress: &mut dyn Progress,
    ) -> Result<MethodResult>;
}

/// The estimators `opts.methods` asks for (log decrement excluded), in order; the first is
/// wrapped in [`MlRefined`] when `opts.ml_refine` is set and it is LSCF or LSCE.
pub fn frf_estimators(opts: &IdentOptions) -> Vec<Box<dyn FrfEstimator>> {
    let mut out: Vec<Box<dyn FrfEstimator>> = Vec::new();
    for &m in &opts.methods {
        let e: Box<dyn FrfEstimator> = match m {
            Method::Lscf => Box::new(Lscf),
            Method::Lsce => Box::new(Lsce),
            Method::Peak => Box::new(PeakPicking),
            Method::LogDec => continue,
        };
        let refine = out.is_empty() && opts.ml_refine && matches!(m, Method::Lscf | Method::Lsce);
        out.push(if refine { Box::new(MlRefined(e)) } else { e });
    }
    out
}

fn to_estimates(modes: &[StableMode], method: &str) -> Vec<ModeEstimate> {
    modes
        .iter()
        .map(|m| ModeEstimate {
            freq_hz: m.freq_hz,
            zeta: m.zeta,
            freq_hz_std: m.freq_hz_std,
            zeta_std: m.zeta_std,
            method: method.to_string(),
        })
        .collect()
}

/// The stable modes inside the band, the `n` best supported (by stable poles) when given.
fn keep_best(modes: Vec<StableMode>, n: Option<usize>, band: (f64, f64)) -> Vec<StableMode> {
    // Poles at an edge model the truncation, not the beam: within 10 % of the lower edge's
    // frequency (a fraction of the band width would drop a 1.1 Hz mode from a 0.1-40 Hz
    // band) or 5 % of the band width below the upper edge.
    let e = 0.05 * (band.1 - band.0);
    let mut modes: Vec<StableMode> = modes
        .into_iter()
        .filter(|m| m.freq_hz > 1.1 * band.0 && m.freq_hz < band.1 - e)
        .collect();
    if let Some(n) = n {
        modes.sort_by(|a, b| b.count.cmp(&a.count));
        modes.truncate(n);
        modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    }
    modes
}

/// A stabilisation-diagram method's result: the diagram's best stable modes in the band.
fn from_diagram(method: Method, name: &str, d: Diagram, cx: &FrfContext) -> MethodResult {
    let modes = keep_best(d.modes.clone(), cx.opts.n_modes, cx.band_hz);
    MethodResult {
        method,
        modes: to_estimates(&modes, name),
        diagram: Some(d),
    }
}

/// Least-squares complex frequency domain ([`super::lscf`]), Sanathanan–Koerner iterated,
/// orders 2..=max(max_order, 4), the window's decay removed from every pole.
pub struct Lscf;

impl FrfEstimator for Lscf {
    fn method(&self) -> Method {
        Method::Lscf
    }
    fn estimate(
        &self,
        cx: &FrfContext,
        _warnings: &mut Vec<String>,
        progress: &mut dyn Progress,
    ) -> Result<MethodResult> {
        let (frf, o) = (cx.frf, cx.opts);
        let band = frf.band(cx.band_hz.0, cx.band_hz.1);
        let (fq, h) = (&frf.freq_hz[band.clone()], &frf.h1[band]);
        let w = vec![1.0; fq.len()];
        let orders: Vec<usize> = (2..=o.max_order.max(4)).collect();
        let lines = LscfLines::new(fq, h, &w, o.max_order.max(4));
        let poles = |n| {
            Ok(lines
                .poles(n, 1.0, o.sk_iterations)?
                .into_iter()
                .map(|p| p.remove_decay(frf.window_decay_s))
                .filter(|p| p.zeta > 0.0 && p.zeta < o.zeta_max)
                .collect())
        };
        let d = diagram("LSCF", orders, &o.criteria, poles, progress)?;
        Ok(from_diagram(Method::Lscf, "lscf", d, cx))
    }
}

/// Least-squares complex exponential ([`super::lsce`], the paper's) on the impulse response of
/// the band, even pole counts 2..=max(max_order, 4).
pub struct Lsce;

impl FrfEstimator for Lsce {
    fn method(&self) -> Method {
        Method::Lsce
    }
    fn estimate(
        &self,
        cx: &FrfContext,
        _warnings: &mut Vec<String>,
        progress: &mut dyn Progress,
    ) -> Result<MethodResult> {
        let (frf, o) = (cx.frf, cx.opts);
        let (f_lo, f_hi) = cx.band_hz;
        let edge = (0.5 * f_lo).min(0.1 * (f_hi - f_lo)).max(2.0 * frf.df_hz());
        let irf = impulse_response(frf, f_lo, f_hi, edge)?;
        let len_s = (irf.h.len() as f64 * irf.dt_s * 0.5).min(60.0);
        let skip_s = 2.0 * irf.dt_s;
        let orders: Vec<usize> = (1..=o.max_order.max(4) / 2).map(|k| 2 * k).collect();
        let sigma_w = frf.window_decay_s;
        let poles = |n| lsce_poles(&irf, n, skip_s, len_s, f_lo, f_hi, o.zeta_max, sigma_w);
        let d = diagram("LSCE", orders, &o.criteria, poles, progress)?;
        Ok(from_diagram(Method::Lsce, "lsce", d, cx))
    }
}

/// Peak picking ([`super::peak`]) with half-power damping, at most `n_modes` (default 4)
/// peaks; a warning for each peak whose half-power band spans fewer than 3 lines.
pub struct PeakPicking;

impl FrfEstimator for PeakPicking {
    fn method(&self) -> Method {
        Method::Peak
    }
    fn estimate(
        &self,
        cx: &FrfContext,
        warnings: &mut Vec<String>,
        _progress: &mut dyn Progress,
    ) -> Result<MethodResult> {
        let frf = cx.frf;
        let (f_lo, f_hi) = cx.band_hz;
        let n = cx.opts.n_modes.unwrap_or(4);
        let pk = pick_peaks(&frf.freq_hz, &frf.h1, f_lo, f_hi, n, 0.01);
        for p in pk.iter().filter(|p| p.lines_in_band < 3) {
            warnings.push(format!("peak picking at {:.3} Hz: only {} lines inside the half-power band; damping is resolution-limited (record longer)", p.pole.freq_hz, p.lines_in_band));
        }
        let modes = pk
            .iter()
            .map(|p| {
                let q = p.pole.remove_decay(frf.window_decay_s);
                ModeEstimate {
                    freq_hz: q.freq_hz,
                    zeta: q.zeta,
                    freq_hz_std: 0.0,
                    zeta_std: 0.0,
                    method: "peak".into(),
                }
            })
            .collect();
        Ok(MethodResult {
            method: Method::Peak,
            modes,
            diagram: None,
        })
    }
}

/// An estimator followed by the maximum-likelihood refinement of its modes
/// ([`refine_estimates`]): each σ becomes the estimator's and the fit's in quadrature; when the
/// fit fails the estimator's modes stay and a warning says why.
pub struct MlRefined(pub Box<dyn FrfEstimator>);

impl FrfEstimator for MlRefined {
    fn method(&self) -> Method {
        self.0.method()
    }
    fn estimate(
        &self,
        cx: &FrfContext,
        warnings: &mut Vec<String>,
        progress: &mut dyn Progress,
    ) -> Result<MethodResult> {
        let mut r = self.0.estimate(cx, warnings, progress)?;
        let name = r.method.name();
        refine_estimates(cx.frf, cx.band_hz, &mut r.modes, name, warnings);
        Ok(r)
    }
}
