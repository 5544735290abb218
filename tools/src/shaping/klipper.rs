//! Klipper's input-shaper metrics and its recommendation, reimplemented from its published
//! method so that our designs can be scored the way Klipper's users read them.
//!
//! Followed: Klipper **v0.13.0** (tag commit `61c0c8d2ef40340781835dd53fb04cc7a454e37a`,
//! 2025-04-11), docs `Measuring_Resonances.md` and `Resonance_Compensation.md`, and the formulas
//! of `klippy/extras/shaper_calibrate.py` / `shaper_defs.py` of that tag, written anew from the
//! mathematics (Klipper is GPL-3; no code is copied). Specification:
//!
//! - **Shapers** ([`KlipperShaper`]): zv, mzv, zvd, ei, 2hump_ei, 3hump_ei designed at
//!   damping ratio ζ = 0.1 ([`DEFAULT_DAMPING_RATIO`]); the EI kinds at vibration tolerance
//!   1/20. In v0.13.0 these are exactly the closed forms of the core's
//!   [`beamshaper::shaper::design`] (K-weighted ZV/ZVD, MZV at 0, 3T_d/8, 3T_d/4, EI / 2-hump /
//!   3-hump EI of Singhose et al.), so they are designed through the core.
//! - **Response** of a shaper (A_i, t_i) at frequency f and damping ζ:
//!   `V(f, ζ) = |Σ A_i e^{−ζω(t_N − t_i)} e^{iω_d t_i}| / Σ A_i`
//!   ([`beamshaper::shaper::residual_vibration`]).
//! - **Remaining vibrations** on a PSD `P` (the sum over the axes, normalised by frequency):
//!   with the threshold `P_th = max P / 20` (a shaper reduces vibrations at most 20 times, so
//!   the part below is ignored), `R(ζ) = Σ max(V(f_k, ζ)·P_k − P_th, 0) / Σ max(P_k − P_th, 0)`
//!   over the bins f_k ≤ 200 Hz; the figure is the worst over the test damping ratios 0.075,
//!   0.1, 0.15 ([`remaining_vibrations`]); Klipper prints it as "vibrations = x %".
//! - **Smoothing** at acceleration a = 5 000 mm/s² and square-corner velocity v = 5 mm/s
//!   ([`smoothing_mm`]): with t̄ = Σ A_i t_i / Σ A_i,
//!   `s90 = √2 Σ_{t_i ≥ t̄} A_i (v + a/2 (t_i − t̄))(t_i − t̄) / Σ A_i`,
//!   `s180 = Σ A_i a/2 (t_i − t̄)² / Σ A_i`, smoothing = max(s90, s180) (mm).
//! - **Max acceleration** ([`max_accel_mm_s2`]): the largest a with smoothing(a) ≤ 0.12 mm
//!   (Klipper bisects; both s90 and s180 are affine in a, so it is solved exactly here).
//! - **Fit** of one shaper kind ([`fit_shaper`]): frequencies from the kind's minimum
//!   ([`KlipperShaper::min_freq_hz`]) to 150 Hz in 0.2 Hz steps; score
//!   `smoothing · (R^1.5 + 0.2 R + 0.01)`; the fit with the fewest vibrations (highest
//!   frequency on ties), then, scanning upwards in frequency, any fit with vibrations
//!   `< 1.1 ×` those and a lower score replaces the selection.
//! - **Recommendation** ([`recommend`]): kinds in the order zv, mzv, ei, 2hump_ei, 3hump_ei;
//!   a kind's fit replaces the best so far if its score is below `best / 1.2`, or below
//!   `best / 1.05` with smoothing below `best / 1.1`.

use crate::recording::psd::KlipperSpectrum;
use beamshaper::shaper::{design, residual_vibration, Shaper, ShaperKind};

/// Klipper's damping ratio of its shaper designs.
pub const DEFAULT_DAMPING_RATIO: f64 = 0.1;
/// Klipper's test damping ratios: the printer's damping is unknown, the worst is taken.
pub const TEST_DAMPING_RATIOS: [f64; 3] = [0.075, 0.1, 0.15];
/// Klipper's `SHAPER_VIBRATION_REDUCTION`: the EI tolerance is its inverse and the PSD below
/// `max / this` is ignored.
pub const SHAPER_VIBRATION_REDUCTION: f64 = 20.0;
/// Highest shaper frequency Klipper tries (Hz).
pub const MAX_SHAPER_FREQ_HZ: f64 = 150.0;
/// Highest PSD bin Klipper counts (Hz).
pub const MAX_FREQ_HZ: f64 = 200.0;
/// Klipper's frequency step of the fit (Hz).
pub const FREQ_STEP_HZ: f64 = 0.2;
/// Acceleration (mm/s²) of Klipper's printed smoothing.
pub const SMOOTHING_ACCEL_MM_S2: f64 = 5000.0;
/// Square-corner velocity (mm/s) of `calibrate_shaper.py`'s default.
pub const SQUARE_CORNER_VELOCITY_MM_S: f64 = 5.0;
/// Smoothing (mm) that defines Klipper's suggested max acceleration.
pub const TARGET_SMOOTHING_MM: f64 = 0.12;

/// Klipper's shaper kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KlipperShaper {
    /// zv.
    Zv,
    /// mzv.
    Mzv,
    /// zvd (not auto-tuned by Klipper).
    Zvd,
    /// ei.
    Ei,
    /// 2hump_ei.
    TwoHumpEi,
    /// 3hump_ei.
    ThreeHumpEi,
}

/// The kinds Klipper's recommendation tries, in its order (`AUTOTUNE_SHAPERS`).
pub const AUTOTUNE: [KlipperShaper; 5] = [
    KlipperShaper::Zv,
    KlipperShaper::Mzv,
    KlipperShaper::Ei,
    KlipperShaper::TwoHumpEi,
    KlipperShaper::ThreeHumpEi,
];

impl KlipperShaper {
    /// Klipper's name (`zv`, `mzv`, `zvd`, `ei`, `2hump_ei`, `3hump_ei`).
    pub fn name(self) -> &'static str {
        match self {
            KlipperShaper::Zv => "zv",
            KlipperShaper::Mzv => "mzv",
            KlipperShaper::Zvd => "zvd",
            KlipperShaper::Ei => "ei",
            KlipperShaper::TwoHumpEi => "2hump_ei",
            KlipperShaper::ThreeHumpEi => "3hump_ei",
        }
    }

    /// Lowest frequency Klipper fits this kind at (Hz; its `min_freq`, chosen so the projected
    /// max acceleration is about 1 500 mm/s²).
    pub fn min_freq_hz(self) -> f64 {
        match self {
            KlipperShaper::Zv => 21.0,
            KlipperShaper::Mzv => 23.0,
            KlipperShaper::Zvd | KlipperShaper::Ei => 29.0,
            KlipperShaper::TwoHumpEi => 39.0,
            KlipperShaper::ThreeHumpEi => 48.0,
        }
    }

    /// The core's kind with Klipper's tolerance 1/20 for the EI family.
    pub fn core_kind(self) -> ShaperKind {
        let v_tol = 1.0 / SHAPER_VIBRATION_REDUCTION;
        match self {
            KlipperShaper::Zv => ShaperKind::Zv,
            KlipperShaper::Mzv => ShaperKind::Mzv,
            KlipperShaper::Zvd => ShaperKind::Zvd,
            KlipperShaper::Ei => ShaperKind::Ei { v_tol },
            KlipperShaper::TwoHumpEi => ShaperKind::Ei2Hump { v_tol },
            KlipperShaper::ThreeHumpEi => ShaperKind::Ei3Hump { v_tol },
        }
    }

    /// Klipper's shaper of this kind at `freq_hz` (Hz, > 0) and ζ = 0.1.
    /// Panics only if `freq_hz` is not finite and positive (callers pass Klipper's grid).
    pub fn design(self, freq_hz: f64) -> Shaper {
        design(self.core_kind(), freq_hz, DEFAULT_DAMPING_RATIO)
            .expect("Klipper's kinds design at any positive frequency and zeta 0.1")
    }
}

/// The bins Klipper counts: frequencies ≤ [`MAX_FREQ_HZ`] with the fitting PSD.
#[derive(Clone, Debug, PartialEq)]
pub struct FitSpectrum {
    /// Frequency bins (Hz).
    pub freq_hz: Vec<f64>,
    /// Sum PSD over the axes, normalised by frequency.
    pub psd: Vec<f64>,
}

impl FitSpectrum {
    /// The bins of `s` Klipper counts (see [`KlipperSpectrum::fitting_psd`]).
    pub fn from_spectrum(s: &KlipperSpectrum) -> Self {
        let p = s.fitting_psd();
        let keep: Vec<usize> = (0..s.freq_hz.len())
            .filter(|&i| s.freq_hz[i] <= MAX_FREQ_HZ)
            .collect();
        FitSpectrum {
            freq_hz: keep.iter().map(|&i| s.freq_hz[i]).collect(),
            psd: keep.iter().map(|&i| p[i]).collect(),
        }
    }
}

/// Shaper response `V(f_k, ζ)` (fraction) at each bin of `freq_hz`.
/// A bin at 0 Hz has response 1 (no attenuation of a static offset).
pub fn response(s: &Shaper, freq_hz: &[f64], zeta: f64) -> Vec<f64> {
    freq_hz
        .iter()
        .map(|&f| match f > 0.0 {
            true => residual_vibration(s, f, zeta),
            false => 1.0,
        })
        .collect()
}

/// The worst response over [`TEST_DAMPING_RATIOS`] at each bin (what Klipper draws).
pub fn worst_response(s: &Shaper, freq_hz: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0f64; freq_hz.len()];
    for z in TEST_DAMPING_RATIOS {
        for (o, v) in out.iter_mut().zip(response(s, freq_hz, z)) {
            *o = o.max(v);
        }
    }
    out
}

/// Remaining vibrations (fraction, 0..1) of shaper `s` on `spec` (see the module docs): the
/// worst over [`TEST_DAMPING_RATIOS`]. A spectrum with no power above its threshold gives 0.
pub fn remaining_vibrations(s: &Shaper, spec: &FitSpectrum) -> f64 {
    remaining_vibrations_within(s, spec, f64::INFINITY).unwrap_or(f64::INFINITY)
}

/// [`remaining_vibrations`], or `None` as soon as it is known to exceed `limit` (fraction).
///
/// Exact shortcut: for a shaper with non-negative amplitudes `V ≤ 1`, so a bin whose PSD is at
/// or below the threshold adds nothing (`V·P − P_th ≤ 0`); only the bins above it are
/// evaluated, largest first, and the sum stops once it passes `limit`.
pub fn remaining_vibrations_within(s: &Shaper, spec: &FitSpectrum, limit: f64) -> Option<f64> {
    let threshold = spec.psd.iter().cloned().fold(0.0, f64::max) / SHAPER_VIBRATION_REDUCTION;
    let all: f64 = spec.psd.iter().map(|p| (p - threshold).max(0.0)).sum();
    if all <= 0.0 {
        return Some(0.0);
    }
    let positive = s.impulses().iter().all(|i| i.amplitude >= 0.0);
    let mut bins: Vec<usize> = (0..spec.psd.len())
        .filter(|&k| !positive || spec.psd[k] > threshold)
        .collect();
    bins.sort_by(|&a, &b| spec.psd[b].total_cmp(&spec.psd[a]));
    let stop = limit * all;
    let mut worst = 0.0f64;
    for z in TEST_DAMPING_RATIOS {
        let mut rem = 0.0;
        for &k in &bins {
            let f = spec.freq_hz[k];
            let v = match f > 0.0 {
                true => residual_vibration(s, f, z),
                false => 1.0,
            };
            rem += (v * spec.psd[k] - threshold).max(0.0);
            if rem > stop {
                return None;
            }
        }
        worst = worst.max(rem / all);
    }
    Some(worst)
}

/// The two sums smoothing is affine in: `s90(a) = √2(v·c90 + a/2·q90)`, `s180(a) = a/2·q180`.
fn smoothing_terms(s: &Shaper) -> (f64, f64, f64) {
    let imps = s.impulses();
    let d: f64 = imps.iter().map(|i| i.amplitude).sum();
    let ts = imps.iter().map(|i| i.amplitude * i.time_s).sum::<f64>() / d;
    let (mut c90, mut q90, mut q180) = (0.0, 0.0, 0.0);
    for i in imps {
        let dt = i.time_s - ts;
        if i.time_s >= ts {
            c90 += i.amplitude * dt;
            q90 += i.amplitude * dt * dt;
        }
        q180 += i.amplitude * dt * dt;
    }
    (c90 / d, q90 / d, q180 / d)
}

/// Klipper's smoothing (mm) of shaper `s` at acceleration `accel_mm_s2` and square-corner
/// velocity `scv_mm_s` (module docs; Klipper's `_get_shaper_smoothing`).
pub fn smoothing_mm(s: &Shaper, accel_mm_s2: f64, scv_mm_s: f64) -> f64 {
    let (c90, q90, q180) = smoothing_terms(s);
    let half = 0.5 * accel_mm_s2;
    let s90 = std::f64::consts::SQRT_2 * (scv_mm_s * c90 + half * q90);
    s90.max(half * q180)
}

/// The largest acceleration (mm/s²) at which the smoothing stays ≤ [`TARGET_SMOOTHING_MM`]
/// (Klipper's `find_shaper_max_accel`), exactly: the smaller of the two affine terms' roots.
/// 0 when even a vanishing acceleration smooths more (square-corner term alone too large).
pub fn max_accel_mm_s2(s: &Shaper, scv_mm_s: f64) -> f64 {
    let (c90, q90, q180) = smoothing_terms(s);
    let t = TARGET_SMOOTHING_MM;
    let a90 = match q90 > 0.0 {
        true => 2.0 * (t / std::f64::consts::SQRT_2 - scv_mm_s * c90) / q90,
        false => f64::INFINITY,
    };
    let a180 = match q180 > 0.0 {
        true => 2.0 * t / q180,
        false => f64::INFINITY,
    };
    a90.min(a180).max(0.0)
}

/// Klipper's score: `smoothing · (R^1.5 + 0.2 R + 0.01)` (lower is better).
pub fn score(smoothing_mm: f64, vibrations: f64) -> f64 {
    smoothing_mm * (vibrations.powf(1.5) + 0.2 * vibrations + 0.01)
}

/// One shaper scored by Klipper's metrics.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Kind.
    pub kind: KlipperShaper,
    /// Shaper frequency (Hz).
    pub freq_hz: f64,
    /// The shaper (ζ = 0.1).
    pub shaper: Shaper,
    /// Remaining vibrations (fraction).
    pub vibrations: f64,
    /// Smoothing at 5 000 mm/s² (mm).
    pub smoothing_mm: f64,
    /// Klipper's score.
    pub score: f64,
    /// Max acceleration for 0.12 mm smoothing (mm/s²).
    pub max_accel_mm_s2: f64,
}

/// Scores `kind` at `freq_hz` on `spec`.
pub fn evaluate(kind: KlipperShaper, freq_hz: f64, spec: &FitSpectrum) -> Fit {
    let shaper = kind.design(freq_hz);
    let vibrations = remaining_vibrations(&shaper, spec);
    let smoothing = smoothing_mm(&shaper, SMOOTHING_ACCEL_MM_S2, SQUARE_CORNER_VELOCITY_MM_S);
    Fit {
        kind,
        freq_hz,
        max_accel_mm_s2: max_accel_mm_s2(&shaper, SQUARE_CORNER_VELOCITY_MM_S),
        score: score(smoothing, vibrations),
        vibrations,
        smoothing_mm: smoothing,
        shaper,
    }
}

/// Klipper's frequency grid of `kind`: `min_freq + k·0.2` below 150 Hz (NumPy's `arange`:
/// `ceil((stop − start)/step)` points at `start + k·step`).
pub fn frequency_grid(kind: KlipperShaper) -> Vec<f64> {
    let start = kind.min_freq_hz();
    let n = ((MAX_SHAPER_FREQ_HZ - start) / FREQ_STEP_HZ).ceil() as usize;
    (0..n).map(|k| start + k as f64 * FREQ_STEP_HZ).collect()
}

/// Klipper's fit of one kind (module docs): the selected fit.
pub fn fit_shaper(kind: KlipperShaper, spec: &FitSpectrum) -> Fit {
    // Klipper scans from the top frequency down.
    let results: Vec<Fit> = frequency_grid(kind)
        .into_iter()
        .rev()
        .map(|f| evaluate(kind, f, spec))
        .collect();
    let mut best = 0;
    for (i, r) in results.iter().enumerate() {
        if r.vibrations < results[best].vibrations {
            best = i;
        }
    }
    let bound = results[best].vibrations * 1.1;
    let mut selected = best;
    for (i, r) in results.iter().enumerate().rev() {
        if r.vibrations < bound && r.score < results[selected].score {
            selected = i;
        }
    }
    results[selected].clone()
}

/// Klipper's recommendation and the fit of every auto-tuned kind (in [`AUTOTUNE`] order).
#[derive(Clone, Debug)]
pub struct Recommendation {
    /// The recommended shaper.
    pub best: Fit,
    /// The fitted shaper of each kind.
    pub fitted: Vec<Fit>,
}

/// Klipper's recommendation on `spec` (module docs).
pub fn recommend(spec: &FitSpectrum) -> Recommendation {
    let fitted: Vec<Fit> = AUTOTUNE.iter().map(|&k| fit_shaper(k, spec)).collect();
    let mut best = 0;
    for (i, f) in fitted.iter().enumerate().skip(1) {
        let b = &fitted[best];
        if f.score * 1.2 < b.score
            || (f.score * 1.05 < b.score && f.smoothing_mm * 1.1 < b.smoothing_mm)
        {
            best = i;
        }
    }
    Recommendation {
        best: fitted[best].clone(),
        fitted,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn klipper_designs_are_the_published_forms() {
        // zv at 50 Hz, zeta 0.1: A = [1, K]/(1+K), t = [0, 0.5/(f·√(1−ζ²))].
        let z: f64 = 0.1;
        let df = (1.0 - z * z).sqrt();
        let k = (-z * std::f64::consts::PI / df).exp();
        let s = KlipperShaper::Zv.design(50.0);
        let i = s.impulses();
        assert!((i[0].amplitude - 1.0 / (1.0 + k)).abs() < 1e-12);
        assert!((i[1].time_s - 0.5 / (50.0 * df)).abs() < 1e-12);
        let grid = frequency_grid(KlipperShaper::Mzv);
        assert_eq!(grid.len(), 635);
        assert!((grid.last().unwrap() - 149.8).abs() < 1e-9);
    }

    #[test]
    fn max_accel_gives_the_target_smoothing() {
        for k in AUTOTUNE {
            let s = k.design(45.0);
            let a = max_accel_mm_s2(&s, 5.0);
            let sm = smoothing_mm(&s, a, 5.0);
            assert!((sm - TARGET_SMOOTHING_MM).abs() < 1e-9, "{k:?} {a} {sm}");
        }
    }
}
