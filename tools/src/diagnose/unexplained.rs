//! What the final model leaves unexplained on the never-fitted validation recording.
//!
//! A channel's validation residual r is *unexplained* when it is both
//! 1. **driven**: the residual is not independent of the commanded motion — the prewhitened
//!    residual–input cross-correlation test (Ljung 1999, §16.6;
//!    [`crate::numeric::independence`]) over [`LJUNG_BOX_LAGS`] lags of the commanded position,
//!    velocity and acceleration rejects independence at the level [`STRUCTURE_LEVEL`] (0.1 %:
//!    noise independent of the drive, however coloured, would be called driven once in a
//!    thousand recordings), the residual prewhitened by its own autoregression (least squares,
//!    order by AIC up to [`PREWHITENING_MAX_ORDER`]). Beside the lags, the final model's
//!    sensitivities to its own parameters on the channel (each prediction with one parameter
//!    moved by its 1 σ, less the prediction), constant and drifting linearly through the
//!    recording ([`crate::numeric::independence::residual_regressor_test`]): a discrepancy
//!    with a memory longer than the lags — a mode's frequency that is not the model's, or
//!    that drifts through the recording as a modulus does with temperature — is predictable
//!    from the residual's own past, and 20 lags of the prewhitened drive do not see it (own
//!    second simulator, seed 131, case18: a tip residual at the first mode 91 × its noise,
//!    p 0.79 on the lags alone). Physics the model lacks is driven by the motion; a
//!    sensor's coloured noise or a loop's stationary jitter is structured in time but is not,
//!    and the whiteness of the residual alone (Ljung–Box over 20 lags, reported as
//!    `ljung_box_q`, the earlier condition) calls both structure: on null replicates whose noise
//!    is the calibrated residual's own coloured spectrum it reported `unexplained` on 31 of 40
//!    (`beamtool diagnose-bootstrap --noise-from calibrated`, second set's nulls), and
//! 2. **well above the noise**: its structured rms √(rms² − σ̂²) is at least
//!    [`STRUCTURE_OVER_NOISE`] × the noise rms σ̂, σ̂² the smaller of the residual's one-step
//!    prediction-error variance from its own 20 previous samples
//!    ([`innovation_variance`](crate::numeric::stats::innovation_variance): what its past
//!    cannot predict) and its spectral floor
//!    ([`spectral_floor_variance`](crate::numeric::stats::spectral_floor_variance): the median
//!    periodogram ordinate / ln 2). A lightly damped mode ringing in the residual is not fully
//!    predictable from its own noisy past, so the first alone counts part of it as noise; the
//!    median of the spectrum does not see a structure confined to under half of the band. (The
//!    first-difference estimator σ̂² = mean((r_{k+1} − r_k)²)/2, von Neumann 1941,
//!    [`difference_noise`], counts structure near the Nyquist rate as noise.) σ̂² is at least
//!    the recorded channel's quantisation error variance q²/12 (its step q on the recording,
//!    [`crate::numeric::stats::quantum`]; Widrow & Kollár 2008, *Quantization Noise*, ch. 4):
//!    the counts' error is no physics, yet a deterministic function of the sensed position —
//!    driven by the motion, constant over each rest — which neither estimator above counts as
//!    noise where the sensor's own noise is below a step (own generator, null seed 1085006:
//!    a 1 µm encoder at a third of the usual noise, its base residual 0.17 µm rms, constant
//!    over each rest, called "driven" and "drifting").
//!
//! 3. **beyond the model's form**: its structured rms exceeds what the model-form alternatives
//!    of the final model change in their prediction of the same recording (each one's rms
//!    change, combined in quadrature as the reported 1 σ combines their parameter changes)
//!    ([`crate::diagnose::honesty::Alternative`]: one basis function more, the other standard
//!    reading of the drive between samples, a loop standing in for an unrecorded base; each
//!    refitted to the fit recordings). Those forms are equally standard readings of the same
//!    samples, so a structure no larger than their disagreement is what the recordings leave
//!    open about the model's form on this recording — its own null — not physics the catalogue
//!    lacks. (A 50 Hz camera: the carriage's motion between samples, which the samples do not
//!    hold, rings the second mode at 11.8 Hz; independent-v2 case32, a null.)
//! 4. **inside the working band**: the band holding its spectral peak (below) starts below
//!    the working band's pass edge ([`super::model::band_edge_hz`], 0.45 × the sample rate).
//!    Above it the response is decided by what the carriage did between samples, which the
//!    samples do not hold, and the model claims no accuracy there (a force residual at
//!    48.9 Hz of a 100 Hz recording, own generator, null seed 996000).
//!
//! 5. **beyond the final model's own uncertainty**: conditions 1–3 are read on the residual left
//!    after the final model's parameters move to the values, inside their joint region at the
//!    level [`UNCERTAINTY_REGION_P`], that predict the validation recording best
//!    ([`within_uncertainty`]). A residual that a plausible value of the calibration explains —
//!    a carriage mass the fit recordings left at ± 0.36 kg, 1.3 σ off on the validation move
//!    (own generator, null seed 996003: the force residual 0.92 correlated with the commanded
//!    acceleration) — is what the fit recordings did not pin down, not physics the model lacks.
//!
//! Its *structure* is either driven (the residual–input test above) or a **slow change of the
//! zero** the drive does not excite: a polynomial in time of one of the degrees
//! [`ZERO_DRIFT_DEGREES`] (offset, ramp and bow; a change through about one cycle within the
//! recording) significant at [`STRUCTURE_LEVEL`], family-wise over the degrees (Bonferroni),
//! against the residual's own stationary long-run variance, the test's scale corrected by
//! [`ZERO_DRIFT_REPLICATES`] bootstrap series of the residual's own noise model
//! ([`crate::numeric::independence::slow_trend_test`]: a bootstrap Bartlett correction, Rocke
//! 1989), and of an rms at least the noise rms — a tip sensor whose zero moved between
//! recordings or drifts during one (thermal drift), a force bias. The mean counts in its rms (the offset is part of
//! what the model leaves), never in its time structure.
//!
//! It is located, never named: the channel, the band holding half its spectral power around
//! the spectral peak, the 1 s windows where its rms is over twice the median window rms, the
//! NRMSE against the channel's signal, the nearest model mode and the correlation with the
//! commanded speed and acceleration.

use super::fit::CHANNEL_NAMES;
use super::model::{Prediction, Prepared};
use super::selection::decision::ablated;
use super::selection::guard::{ljung_box, LJUNG_BOX_LAGS};
use crate::ident::spectrum::amplitude_spectrum;
use crate::numeric::independence::{
    drifting, residual_input_test, residual_regressor_test, slow_trend_test, InputIndependence,
    SlowTrend,
};
use crate::numeric::stats::{noise_variance, quantum};
use serde::Serialize;

/// χ²(20) upper 0.1 % point (the Ljung–Box statistic's, reported beside the driven test).
pub const LJUNG_BOX_CRITICAL: f64 = 45.3;
/// Degrees of the slow change of a sensor's zero tested beside the drive (module docs): offset,
/// ramp and bow (2), and a change through about one cycle within the recording (4: a quartic
/// follows a sinusoid's full period over the span) — a drift over the recording, not structure
/// within it. Each is tested at [`STRUCTURE_LEVEL`] / 2 (Bonferroni over the family).
pub const ZERO_DRIFT_DEGREES: [usize; 2] = [2, 4];
/// Bootstrap series that correct the zero-drift test's scale (its Bartlett factor, the
/// replicates' mean statistic over its χ² mean): the factor's relative standard error is
/// √(2 / (d + 1)) / √200, 6 % at degree 2, for a χ² statistic; a computational cap. Drawn only
/// where the family's trend is at least the noise rms, which the flag needs anyway.
pub const ZERO_DRIFT_REPLICATES: usize = 200;
/// Level of the residual–input test (module docs, 1) and of the zero-drift test: 0.1 %.
pub const STRUCTURE_LEVEL: f64 = 0.001;
/// Highest order of the autoregression that prewhitens a residual before the residual–input
/// test, and of the noise model the parametric bootstrap draws
/// ([`super::bootstrap::MAX_NOISE_ORDER`]): 1 s of a 50 Hz recording, 40 ms at 1 kHz — longer
/// than the 20 lags the test reads. A computational cap; the order is chosen below it by AIC.
pub const PREWHITENING_MAX_ORDER: usize = 50;
/// Structured rms (above the noise floor) over the noise rms that counts as "well above noise":
/// the structure is at least as large as the noise (the residual rms ≥ √2 × the noise rms).
pub const STRUCTURE_OVER_NOISE: f64 = 1.0;

/// Level of the joint region of the final model's parameters in [`within_uncertainty`]: the
/// residual counts as explained by them when values inside the region whose chance is
/// 1 − 0.001 explain it (the 0.1 % of condition 1).
pub const UNCERTAINTY_REGION_P: f64 = 0.001;

/// The validation residuals `vres` (of the final model's prediction `pred`) less what the final
/// model's parameters explain inside their own uncertainty (module docs, 5). `moved[i]` is the
/// prediction with parameter i moved by its reported 1 σ, so a shift u_i = 1 is a 1-σ move;
/// the shift u minimising the residual, every channel together, each divided by its noise
/// rms `noise[c]`, subject to ‖u‖² ≤ χ²_k(1 − [`UNCERTAINTY_REGION_P`]) (k the parameters that
/// move the prediction; the 1 σ taken as independent, linear in u: a trust-region least squares,
/// Moré 1983, λ by bisection), is subtracted: r_c − Σ u_i (moved_i,c − pred_c). Channels or
/// moves whose lengths differ from the residual's are left out; without any move the residuals
/// are returned as they are.
pub fn within_uncertainty(
    vres: &[Option<Vec<f64>>; 3],
    pred: &Prediction,
    moved: &[Prediction],
    noise: [f64; 3],
) -> [Option<Vec<f64>>; 3] {
    use nalgebra::{DMatrix, DVector};
    let channels: Vec<usize> = (0..3)
        .filter(|&c| vres[c].is_some() && of(pred, c).is_some() && noise[c] > 0.0)
        .collect();
    // each move's change of the prediction, per channel (empty where it is not usable)
    let deltas: Vec<Vec<Vec<f64>>> = moved
        .iter()
        .map(|m| {
            channels
                .iter()
                .map(|&c| {
                    let (r, own) = (
                        vres[c].as_deref().unwrap_or(&[]),
                        of(pred, c).unwrap_or(&[]),
                    );
                    match of(m, c) {
                        Some(a) if a.len() == r.len() && own.len() == r.len() => {
                            a.iter().zip(own).map(|(x, y)| x - y).collect()
                        }
                        _ => vec![0.0; r.len()],
                    }
                })
                .collect()
        })
        .filter(|d: &Vec<Vec<f64>>| {
            d.iter().flatten().all(|v| v.is_finite()) && d.iter().flatten().any(|v| *v != 0.0)
        })
        .collect();
    let k = deltas.len();
    if k == 0 || channels.is_empty() {
        return vres.clone();
    }
    let n: usize = channels
        .iter()
        .map(|&c| vres[c].as_ref().map_or(0, Vec::len))
        .sum();
    let mut a = DMatrix::<f64>::zeros(n, k);
    let mut r = DVector::<f64>::zeros(n);
    let mut row = 0;
    for (j, &c) in channels.iter().enumerate() {
        let rc = vres[c].as_deref().unwrap_or(&[]);
        for (t, v) in rc.iter().enumerate() {
            r[row + t] = v / noise[c];
            for (i, d) in deltas.iter().enumerate() {
                a[(row + t, i)] = d[j][t] / noise[c];
            }
        }
        row += rc.len();
    }
    let Some(u) = trust_region_shift(&a, &r, chi2_upper(k, UNCERTAINTY_REGION_P)) else {
        return vres.clone();
    };
    let mut out = vres.clone();
    for (j, &c) in channels.iter().enumerate() {
        if let Some(rc) = out[c].as_mut() {
            for (t, v) in rc.iter_mut().enumerate() {
                *v -= (0..k).map(|i| u[i] * deltas[i][j][t]).sum::<f64>();
            }
        }
    }
    out
}

/// The u minimising ‖r − A u‖ subject to ‖u‖² ≤ `radius_sq`: the least-squares solution when
/// it lies inside, else (AᵀA + λI)⁻¹ Aᵀr with λ found by bisection so that it lies on the
/// boundary (‖u(λ)‖ falls with λ and is below ‖Aᵀr‖/λ). `None` when AᵀA cannot be factored.
fn trust_region_shift(
    a: &nalgebra::DMatrix<f64>,
    r: &nalgebra::DVector<f64>,
    radius_sq: f64,
) -> Option<nalgebra::DVector<f64>> {
    let k = a.ncols();
    let (g, b) = (a.tr_mul(a), a.tr_mul(r));
    let solve = |lambda: f64| {
        let ridge = lambda + 1e-12 * g.trace().max(f64::MIN_POSITIVE);
        (g.clone() + nalgebra::DMatrix::identity(k, k) * ridge)
            .cholesky()
            .map(|ch| ch.solve(&b))
    };
    let u = solve(0.0)?;
    if u.norm_squared() <= radius_sq {
        return Some(u);
    }
    let (mut lo, mut hi) = (0.0, b.norm() / radius_sq.sqrt());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        match solve(mid) {
            Some(v) if v.norm_squared() > radius_sq => lo = mid,
            _ => hi = mid,
        }
    }
    solve(hi)
}

/// The upper `p` point of χ² with `k` degrees of freedom.
fn chi2_upper(k: usize, p: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(k.max(1) as f64).map_or(f64::INFINITY, |d| d.inverse_cdf(1.0 - p))
}

/// A located residual the catalogue does not explain.
#[derive(Clone, Debug, Serialize)]
pub struct Unexplained {
    /// Channel (`tip_pos_m`, `force_n`, `base_pos_m`).
    pub channel: String,
    /// Band (Hz) holding the residual's spectral peak (half-power edges).
    pub band_hz: [f64; 2],
    /// Time windows (s) where the residual is strongest.
    pub windows: Vec<[f64; 2]>,
    /// rms(residual) / rms(signal − mean) on the validation recording.
    pub nrmse: f64,
    /// rms of the residual (its mean included) over the estimated noise rms.
    pub residual_over_noise: f64,
    /// Mean of the residual (the channel's unit): a zero offset the model does not have.
    pub offset: f64,
    /// Structured rms √(rms² − σ̂²) over the noise rms σ̂.
    pub structured_over_noise: f64,
    /// The model-form alternatives' rms change of the channel's prediction (combined in
    /// quadrature) over the noise rms σ̂ (module docs, 3; 0 without alternatives).
    pub model_form_over_noise: f64,
    /// Ljung–Box Q (20 lags) of the residual.
    pub ljung_box_q: f64,
    /// The residual–input test's n R² (module docs, 1; `None` where it could not be read).
    pub drive_correlation_chi2: Option<f64>,
    /// Its degrees of freedom (the rank of the commanded motion's lags and the final model's
    /// sensitivities, constant and drifting).
    pub drive_correlation_dof: Option<usize>,
    /// rms of the residual's slow zero change (the channel's unit): the most significant degree
    /// of [`ZERO_DRIFT_DEGREES`] (the family's degree whose trend clears the level, if any).
    pub zero_drift_rms: Option<f64>,
    /// Its Wald statistic against the residual's long-run variance over its bootstrap Bartlett
    /// factor (χ² with `zero_drift_dof` degrees of freedom).
    pub zero_drift_chi2: Option<f64>,
    /// Its degrees of freedom (the trend's degree + 1).
    pub zero_drift_dof: Option<usize>,
    /// Nearest model mode (Hz) to the band centre, if any model modes exist.
    pub nearest_model_mode_hz: Option<f64>,
    /// Correlation of the residual with the commanded speed |v|·sign(v) and acceleration.
    pub correlation_velocity: f64,
    /// Correlation with the commanded acceleration.
    pub correlation_acceleration: f64,
    /// The catalogue effect that came closest on the last selection round and why it was not
    /// named (`None` when no candidate was tried).
    pub closest_catalogue_effect: Option<String>,
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 3 {
        return 0.0;
    }
    let ma = a[..n].iter().sum::<f64>() / n as f64;
    let mb = b[..n].iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let (x, y) = (a[k] - ma, b[k] - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    let d = (saa * sbb).sqrt();
    if d > 0.0 {
        sab / d
    } else {
        0.0
    }
}

/// First-difference noise estimate σ̂ of `r`.
pub fn difference_noise(r: &[f64]) -> f64 {
    if r.len() < 2 {
        return 0.0;
    }
    let s: f64 = r.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
    (s / (2.0 * (r.len() - 1) as f64)).sqrt()
}

/// Band (Hz): the half-power edges around the residual's spectral peak above 0.05 Hz.
fn band_of(r: &[f64], rate: f64) -> [f64; 2] {
    let (f, a) = amplitude_spectrum(r, rate);
    let (mut ip, mut amax) = (0, 0.0);
    for (i, (&fi, &ai)) in f.iter().zip(&a).enumerate() {
        if fi > 0.05 && ai > amax {
            amax = ai;
            ip = i;
        }
    }
    let half = amax / std::f64::consts::SQRT_2;
    let mut lo = ip;
    while lo > 0 && a[lo - 1] >= half {
        lo -= 1;
    }
    let mut hi = ip;
    while hi + 1 < a.len() && a[hi + 1] >= half {
        hi += 1;
    }
    [f[lo], f[hi]]
}

/// The 1 s windows (s, merged when adjacent, at most 5) where the residual's rms is over twice
/// the median window rms.
fn windows_of(centred: &[f64], time_s: &[f64], rate: f64) -> Vec<[f64; 2]> {
    let w = (rate.round() as usize).max(1);
    let wr: Vec<f64> = centred.chunks(w).map(rms).collect();
    let mut sorted = wr.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let mut windows: Vec<[f64; 2]> = Vec::new();
    for (i, v) in wr.iter().enumerate() {
        if *v > 2.0 * median {
            let t0 = time_s[i * w];
            let t1 = time_s[((i + 1) * w).min(time_s.len()) - 1];
            match windows.last_mut() {
                Some(last) if (t0 - last[1]).abs() <= 1.5 / rate => last[1] = t1,
                _ => windows.push([t0, t1]),
            }
        }
    }
    windows.truncate(5);
    windows
}

/// Commanded velocity and acceleration (forward differences).
fn command_rates(cmd_m: &[f64], rate: f64) -> (Vec<f64>, Vec<f64>) {
    let diff = |v: &[f64]| -> Vec<f64> {
        (0..v.len())
            .map(|k| {
                let k1 = (k + 1).min(v.len() - 1);
                (v[k1] - v[k]) * rate
            })
            .collect()
    };
    let vel = diff(cmd_m);
    let acc = diff(&vel);
    (vel, acc)
}

/// The model-form alternatives' rms differences (channel `c`'s unit) between `pred` and each
/// alternative's prediction in `model_form`, combined in quadrature as the final model's 1 σ
/// combines their parameter changes ([`crate::diagnose::honesty`], GUM 5.1.2) (module docs,
/// 3); 0 without one on the channel.
fn model_form_rms(pred: &Prediction, model_form: &[Prediction], c: usize) -> f64 {
    let Some(own) = of(pred, c) else { return 0.0 };
    model_form
        .iter()
        .filter_map(|alt| of(alt, c))
        .filter(|a| a.len() == own.len() && !own.is_empty())
        .map(|a| {
            let ss: f64 = own.iter().zip(a).map(|(x, y)| (x - y) * (x - y)).sum();
            (ss / own.len() as f64).sqrt()
        })
        .filter(|m| m.is_finite())
        .fold(0.0, f64::hypot)
}

/// The residual `r` of channel `c` located, when it is structured, above the noise and beyond
/// the model's form (`form_rms`, [`model_form_rms`]; module docs); `None` otherwise.
fn locate_channel(
    d: &Prepared,
    c: usize,
    r: &[f64],
    form_rms: f64,
    model_freqs: &[f64],
    sensitivities: &[Vec<f64>],
) -> Option<Unexplained> {
    if r.len() < 4 * LJUNG_BOX_LAGS {
        return None;
    }
    let rate = 1.0 / d.dt;
    let step = recorded(d, c)
        .filter(|_| !ablated("quantisation_floor"))
        .and_then(quantum)
        .unwrap_or(0.0);
    let noise = noise_variance(r, LJUNG_BOX_LAGS)
        .max(step * step / 12.0)
        .sqrt();
    let m = r.iter().sum::<f64>() / r.len() as f64;
    let centred: Vec<f64> = r.iter().map(|x| x - m).collect();
    let e = rms(r);
    let structured = (e * e - noise * noise).max(0.0).sqrt();
    let ratio = if noise > 0.0 {
        structured / noise
    } else {
        f64::INFINITY
    };
    let q = ljung_box(r, LJUNG_BOX_LAGS);
    if !(ratio >= STRUCTURE_OVER_NOISE && structured > form_rms) {
        return None;
    }
    let band = band_of(r, rate);
    if band[0] >= super::model::band_edge_hz(d.dt) {
        return None;
    }
    let (vel, acc) = command_rates(&d.cmd_m, rate);
    let independence = drive_test(r, &[&d.cmd_m, &vel, &acc], sensitivities);
    let driven = independence
        .as_ref()
        .is_some_and(|t| t.p_value < STRUCTURE_LEVEL);
    let (offset_shows, drift) = zero_drift(r, noise, c);
    if !(driven || offset_shows) {
        return None;
    }
    let sig = super::channel_signal(d, c);
    let ms = sig.iter().sum::<f64>() / sig.len().max(1) as f64;
    let ss = rms(&sig.iter().map(|x| x - ms).collect::<Vec<_>>());
    let centre = 0.5 * (band[0] + band[1]);
    let nearest = model_freqs
        .iter()
        .copied()
        .min_by(|x, y| (x - centre).abs().total_cmp(&(y - centre).abs()));
    Some(Unexplained {
        channel: CHANNEL_NAMES[c].to_string(),
        band_hz: band,
        windows: windows_of(&centred, &d.time_s, rate),
        nrmse: e / ss.max(1e-300),
        residual_over_noise: e / noise.max(1e-300),
        offset: m,
        structured_over_noise: ratio,
        model_form_over_noise: form_rms / noise.max(1e-300),
        ljung_box_q: q,
        drive_correlation_chi2: independence.as_ref().map(|t| t.statistic),
        drive_correlation_dof: independence.as_ref().map(|t| t.degrees_of_freedom),
        zero_drift_rms: drift.as_ref().map(|t| t.trend_rms),
        zero_drift_chi2: drift.as_ref().map(|t| t.statistic / t.bartlett_factor),
        zero_drift_dof: drift.as_ref().map(|t| t.degrees_of_freedom),
        nearest_model_mode_hz: nearest,
        correlation_velocity: corr(&centred, &vel),
        correlation_acceleration: corr(&centred, &acc),
        closest_catalogue_effect: None,
    })
}

/// The residual–input test of module docs, 1 on the residual `r`: the commanded motion's lags
/// (`inputs`) and the final model's sensitivities to its own parameters on this channel
/// (`sensitivities`, each the prediction with one parameter moved by its 1 σ less the
/// prediction), constant and drifting linearly through the recording, the prewhitening fitted
/// by least squares ([`residual_regressor_test`]). With `DIAG_ABLATE=drive_sensitivities` the
/// lags alone, prewhitened by Yule–Walker (the test before December 2026).
fn drive_test(
    r: &[f64],
    inputs: &[&[f64]],
    sensitivities: &[Vec<f64>],
) -> Option<InputIndependence> {
    if ablated("drive_sensitivities") {
        return residual_input_test(r, inputs, LJUNG_BOX_LAGS, PREWHITENING_MAX_ORDER);
    }
    let own: Vec<&Vec<f64>> = sensitivities
        .iter()
        .filter(|s| s.len() == r.len())
        .collect();
    let drift: Vec<Vec<f64>> = own.iter().map(|s| drifting(s)).collect();
    let columns: Vec<&[f64]> = own
        .iter()
        .map(|s| s.as_slice())
        .chain(drift.iter().map(Vec::as_slice))
        .collect();
    residual_regressor_test(r, inputs, LJUNG_BOX_LAGS, &columns, PREWHITENING_MAX_ORDER)
}

/// Channel `c` of the prediction `p` (base position, tip position, force), if predicted.
fn of(p: &Prediction, c: usize) -> Option<&[f64]> {
    [&p.base_m, &p.tip_m, &p.force_n][c].as_deref()
}

/// Channel `c` of `d` as recorded (base position, tip position, force), if recorded.
fn recorded(d: &Prepared, c: usize) -> Option<&[f64]> {
    [&d.base_m, &d.tip_m, &d.force_n][c].as_deref()
}

/// Whether channel `c`'s residual `r` holds a slow change of its zero (module docs): a degree
/// of [`ZERO_DRIFT_DEGREES`] whose trend is significant at [`STRUCTURE_LEVEL`] over the family
/// (Bonferroni) and at least [`STRUCTURE_OVER_NOISE`] × the noise rms `noise`; with the trend to
/// report (that degree's, else the family's most significant).
fn zero_drift(r: &[f64], noise: f64, c: usize) -> (bool, Option<SlowTrend>) {
    let large = |t: &SlowTrend| t.trend_rms >= STRUCTURE_OVER_NOISE * noise && t.trend_rms > 0.0;
    let mut family = slow_trend_test(r, &ZERO_DRIFT_DEGREES, PREWHITENING_MAX_ORDER, 0, 0);
    if family.iter().any(large) {
        family = slow_trend_test(
            r,
            &ZERO_DRIFT_DEGREES,
            PREWHITENING_MAX_ORDER,
            if ablated("zero_drift_calibration") {
                0
            } else {
                ZERO_DRIFT_REPLICATES
            },
            c as u64,
        );
    }
    let level = STRUCTURE_LEVEL / ZERO_DRIFT_DEGREES.len() as f64;
    let by_p = |a: &&SlowTrend, b: &&SlowTrend| a.p_value.total_cmp(&b.p_value);
    let shown = family
        .iter()
        .filter(|t| t.p_value < level && large(t))
        .min_by(by_p);
    let offset_shows = shown.is_some();
    let drift = shown.or_else(|| family.iter().min_by(by_p)).cloned();
    (offset_shows, drift)
}

/// The final model's sensitivities on channel `c` (`n` samples): each moved prediction of
/// `moved` less `pred`, where both have the channel at that length and the move changes it.
fn sensitivities(pred: &Prediction, moved: &[Prediction], c: usize, n: usize) -> Vec<Vec<f64>> {
    let Some(own) = of(pred, c).filter(|o| o.len() == n) else {
        return Vec::new();
    };
    moved
        .iter()
        .filter_map(|m| of(m, c).filter(|a| a.len() == n))
        .map(|a| a.iter().zip(own).map(|(x, y)| x - y).collect::<Vec<f64>>())
        .filter(|d| d.iter().all(|v| v.is_finite()) && d.iter().any(|v| *v != 0.0))
        .collect()
}

/// The channel whose validation residual (`vres`, of the final model's prediction `pred` of
/// `d`) is most clearly structured, above noise and beyond the model's form (`model_form`: the
/// model-form alternatives' predictions of `d`), located; `None` when every channel's residual
/// is white, at the noise level or within the model's form.
pub fn assess(
    d: &Prepared,
    vres: &[Option<Vec<f64>>; 3],
    pred: &Prediction,
    model_form: &[Prediction],
    moved: &[Prediction],
    model_freqs: &[f64],
) -> Option<Unexplained> {
    let noise = std::array::from_fn(|c| {
        vres[c]
            .as_deref()
            .map_or(0.0, |r| noise_variance(r, LJUNG_BOX_LAGS).sqrt())
    });
    let vres = &within_uncertainty(vres, pred, moved, noise);
    let mut best: Option<Unexplained> = None;
    for c in 0..3 {
        let Some(r) = &vres[c] else { continue };
        let form_rms = model_form_rms(pred, model_form, c);
        let directions = sensitivities(pred, moved, c, r.len());
        let Some(u) = locate_channel(d, c, r, form_rms, model_freqs, &directions) else {
            continue;
        };
        if best
            .as_ref()
            .map_or(true, |b| u.structured_over_noise > b.structured_over_noise)
        {
            best = Some(u);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn a_zero_offset_well_above_the_noise_is_unexplained_and_white_noise_is_not() {
        // a tip sensor whose zero moved by 3 noise rms between recordings: white in time, yet
        // the model leaves it; a tenth of that is not "well above noise"
        let (n, rate) = (3000, 100.0);
        let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
        let cmd: Vec<f64> = (0..n).map(|k| 0.1 * (k as f64 / 500.0).sin()).collect();
        rec.base_cmd_m = Some(cmd.clone());
        rec.tip_pos_m = Some(cmd);
        let d = Prepared::new("t", &rec).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, 1e-4).unwrap();
        let white: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
        let with = |offset: f64| -> [Option<Vec<f64>>; 3] {
            [None, Some(white.iter().map(|v| v + offset).collect()), None]
        };
        let pred = Prediction::default();
        assert!(assess(&d, &with(0.0), &pred, &[], &[], &[]).is_none());
        assert!(assess(&d, &with(3e-5), &pred, &[], &[], &[]).is_none());
        let u = assess(&d, &with(3e-4), &pred, &[], &[], &[]).expect("an offset of 3 noise rms");
        assert_eq!(u.channel, "tip_pos_m");
        assert!((u.offset - 3e-4).abs() < 1e-5, "{}", u.offset);
        assert!(u.ljung_box_q < LJUNG_BOX_CRITICAL, "white in time");
        assert!((u.residual_over_noise - 10f64.sqrt()).abs() < 0.2);
        // a zero drifting by 6 noise rms over the recording (a ramp of rms √3): not driven by
        // the command, still left by the model
        let ramp: Vec<f64> = (0..n).map(|k| 6e-4 * (k as f64 / n as f64 - 0.5)).collect();
        let drifting = [
            None,
            Some(white.iter().zip(&ramp).map(|(a, b)| a + b).collect()),
            None,
        ];
        let u = assess(&d, &drifting, &pred, &[], &[], &[]).expect("a drift of the zero");
        assert!((u.zero_drift_rms.unwrap() / 1e-4 - 3f64.sqrt()).abs() < 0.1);
    }

    #[test]
    fn a_quantised_sensors_own_error_is_not_unexplained_and_a_drift_above_it_is() {
        // a 1 µm encoder under 0.03 µm noise follows the moves: its error (the counts' rounding)
        // is driven by the motion and constant over each rest, yet no physics (without the
        // quantisation floor it is called driven, 3 noise rms); a drift of 10 µm over the
        // recording is
        let (n, rate) = (10_000, 500.0);
        let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
        // rests off the grid, at two fractions of a count
        let truth: Vec<f64> = moves(n, rate)
            .iter()
            .map(|x| x * (1.0 + 2.3e-5) + 0.37e-6)
            .collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let noise = Normal::new(0.0, 3e-8).unwrap();
        let counts: Vec<f64> = truth
            .iter()
            .map(|x| ((x + noise.sample(&mut rng)) / 1e-6).round() * 1e-6)
            .collect();
        rec.base_cmd_m = Some(truth.clone());
        rec.base_pos_m = Some(counts.clone());
        let d = Prepared::new("t", &rec).unwrap();
        let error: Vec<f64> = counts.iter().zip(&truth).map(|(a, b)| a - b).collect();
        let pred = Prediction::default();
        let r = [Some(error.clone()), None, None];
        assert!(assess(&d, &r, &pred, &[], &[], &[]).is_none());
        let drifting: Vec<f64> = error
            .iter()
            .enumerate()
            .map(|(k, v)| v + 1e-5 * (k as f64 / n as f64 - 0.5))
            .collect();
        let u = assess(&d, &[Some(drifting), None, None], &pred, &[], &[], &[])
            .expect("a drift of ten counts");
        assert_eq!(u.channel, "base_pos_m");
    }

    /// Commanded positions (m) of 20 mm trapezoid moves back and forth, one every 3 s, each
    /// 0.6 s long with 0.15 s ramps of the speed, at `rate` Hz.
    fn moves(n: usize, rate: f64) -> Vec<f64> {
        let mut v = vec![0.0; n];
        for (k, x) in v.iter_mut().enumerate() {
            let t = k as f64 / rate;
            let sign = if (t / 3.0) as usize % 2 == 0 {
                1.0
            } else {
                -1.0
            };
            let tm = t % 3.0;
            *x = sign * (tm / 0.15).min(1.0).min(((0.6 - tm) / 0.15).max(0.0)) * 0.04;
        }
        let mut pos = vec![0.0; n];
        for k in 1..n {
            pos[k] = pos[k - 1] + v[k] / rate;
        }
        pos
    }

    /// A resonance at `f_hz` (ζ 0.02) driven by the second difference of `u` at `rate` Hz,
    /// scaled to unit rms: what a model-form error of a mode leaves after every move.
    fn resonance(u: &[f64], f_hz: f64, rate: f64) -> Vec<f64> {
        let wn = 2.0 * std::f64::consts::PI * f_hz / rate;
        let r = (-0.02 * wn).exp();
        let (a1, a2) = (2.0 * r * wn.cos(), -r * r);
        let mut y = vec![0.0; u.len()];
        for t in 2..u.len() {
            let acc = u[t] - 2.0 * u[t - 1] + u[t - 2];
            y[t] = a1 * y[t - 1] + a2 * y[t - 2] + acc;
        }
        let s = rms(&y);
        y.iter().map(|v| v / s).collect()
    }

    #[test]
    fn structure_within_the_model_forms_disagreement_is_not_unexplained() {
        // a ring at 11.8 Hz of 2 noise rms that every move leaves on the tip at 50 Hz:
        // unexplained when the model's forms agree to within a quarter of it, not when they
        // disagree by more than it, nor when it is there without the moves that drive it
        let (n, rate) = (3000, 50.0);
        let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
        let cmd = moves(n, rate);
        let shape = resonance(&cmd, 11.8, rate);
        rec.base_cmd_m = Some(cmd);
        rec.tip_pos_m = Some(vec![0.0; n]);
        let d = Prepared::new("t", &rec).unwrap();
        let mut still = rec.clone();
        still.base_cmd_m = Some(vec![0.0; n]);
        let still = Prepared::new("t", &still).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let noise = Normal::new(0.0, 1e-5).unwrap();
        let ring = |a: f64| -> Vec<f64> { shape.iter().map(|v| a * v).collect() };
        let r: Vec<f64> = ring(2e-5)
            .iter()
            .map(|v| v + noise.sample(&mut rng))
            .collect();
        let vres = [None, Some(r), None];
        let pred = Prediction {
            tip_m: Some(vec![0.0; n]),
            ..Prediction::default()
        };
        let alt = |rms: f64| Prediction {
            tip_m: Some(ring(rms)),
            ..Prediction::default()
        };
        let u = assess(&d, &vres, &pred, &[alt(0.5e-5)], &[], &[]).expect("beyond the forms");
        assert!(
            (u.structured_over_noise - 2.0).abs() < 0.3,
            "{}",
            u.structured_over_noise
        );
        assert!(
            (u.model_form_over_noise - 0.5).abs() < 0.1,
            "{}",
            u.model_form_over_noise
        );
        assert!(u.ljung_box_q > LJUNG_BOX_CRITICAL, "structured in time");
        assert!(assess(&d, &vres, &pred, &[alt(0.5e-5), alt(3e-5)], &[], &[]).is_none());
        // the same residual beside a carriage that stood still is noise, however coloured
        assert!(assess(&still, &vres, &pred, &[alt(0.5e-5)], &[], &[]).is_none());
        // a ring at 23.9 Hz that the moves drive, beyond the working band's pass edge (22.5 Hz
        // at 50 Hz)
        let high: Vec<f64> = resonance(rec.base_cmd_m.as_ref().unwrap(), 23.9, rate)
            .iter()
            .map(|v| 2e-5 * v + noise.sample(&mut rng))
            .collect();
        assert!(assess(&d, &[None, Some(high), None], &pred, &[], &[], &[]).is_none());
    }

    #[test]
    fn structure_a_plausible_value_of_a_parameter_explains_is_not_unexplained() {
        // a force residual proportional to the commanded acceleration, as a carriage mass off
        // by 1.3 of its reported 1 σ leaves it: removed inside the parameters' region; the same
        // shape 20 σ off is not (χ²₁ upper 0.1 %: at most 3.29 σ of it is taken away)
        let (n, rate) = (3000, 100.0);
        let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
        let cmd = moves(n, rate);
        let acc: Vec<f64> = (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                cmd[b] - 2.0 * cmd[k] + cmd[a]
            })
            .collect();
        let shape: Vec<f64> = acc.iter().map(|v| v / rms(&acc)).collect();
        rec.base_cmd_m = Some(cmd.clone());
        rec.force_n = Some(cmd);
        let d = Prepared::new("t", &rec).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let noise = Normal::new(0.0, 0.05).unwrap();
        let pred = Prediction {
            force_n: Some(vec![0.0; n]),
            ..Prediction::default()
        };
        let one_sigma = Prediction {
            force_n: Some(shape.iter().map(|v| 0.1 * v).collect()),
            ..Prediction::default()
        };
        let mut residual = |sigmas: f64| -> [Option<Vec<f64>>; 3] {
            let r = shape
                .iter()
                .map(|v| sigmas * 0.1 * v + noise.sample(&mut rng));
            [None, None, Some(r.collect())]
        };
        let plausible = residual(1.3);
        assert!(assess(&d, &plausible, &pred, &[], &[], &[]).is_some());
        assert!(assess(&d, &plausible, &pred, &[], &[one_sigma.clone()], &[]).is_none());
        let far = residual(20.0);
        let left = within_uncertainty(&far, &pred, &[one_sigma.clone()], [0.0, 0.0, 0.05]);
        let (before, after) = (
            rms(far[2].as_ref().unwrap()),
            rms(left[2].as_ref().unwrap()),
        );
        let removed = (before - after) / 0.1;
        assert!(
            (removed - chi2_upper(1, UNCERTAINTY_REGION_P).sqrt()).abs() < 0.05,
            "{removed}"
        );
        assert!(assess(&d, &far, &pred, &[], &[one_sigma], &[]).is_some());
    }

    #[test]
    fn difference_noise_recovers_white_noise_and_ignores_slow_structure() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let n = Normal::new(0.0, 0.5).unwrap();
        let white: Vec<f64> = (0..20000).map(|_| n.sample(&mut rng)).collect();
        assert!((difference_noise(&white) - 0.5).abs() < 0.02);
        let slow: Vec<f64> = white
            .iter()
            .enumerate()
            .map(|(k, x)| x + 5.0 * (k as f64 * 0.01).sin())
            .collect();
        assert!((difference_noise(&slow) - 0.5).abs() < 0.03);
    }
}
