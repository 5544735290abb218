//! Shaper design from a measured spectrum (Klipper's `resonances_*.csv` /
//! `calibration_data_*.csv`, or any PSD), scored by Klipper's own metrics
//! ([`super::klipper`]) so that the comparison with Klipper's recommendation is fair.
//!
//! Specification. Over the PSD Klipper fits on (sum over the axes, normalised by frequency):
//! 1. Klipper's recommendation `K` ([`super::klipper::recommend`]) bounds the design: ours
//!    may leave at most [`VIBRATION_MARGIN`] (1 point) more remaining vibrations than `K`
//!    and no more smoothing — issue 70's "not worse" box, tightened to no extra smoothing.
//! 2. Candidates are the core's positive shaper designs ([`beamshaper::shaper::design`]):
//!    ZV, MZV, ZVD, ZVDD, EI / 2-hump EI / 3-hump EI at tolerances [`EI_TOLERANCES`], each at
//!    design damping ratios [`DESIGN_ZETAS`], at frequencies from 150 Hz down to 21 Hz
//!    (Klipper's range) in [`FREQ_STEP_HZ`] steps; and, when the spectrum has two distinct
//!    peaks ([`two_peaks`]), the convolution of two short designs (ZV, MZV, ZVD at ζ = 0.1),
//!    one per peak, on a grid of ±[`PEAK_SEARCH_FRACTION`] around each peak (paper §4:
//!    multi-mode shapers by convolution). Klipper's recommended shaper itself is a candidate.
//! 3. Within the box, the design is the candidate that minimises the [`Objective`]:
//!    - [`Objective::LeastSmoothing`] (default; issue 70's rule "keeps the remaining
//!      vibrations low with the least smoothing"): the least smoothing;
//!    - [`Objective::KlipperScore`]: the lowest Klipper score `smoothing · (R^1.5 + 0.2 R +
//!      0.01)` — Klipper's own trade of remaining vibrations R against smoothing, applied over
//!      the wider design space.
//!
//!    Smoothing rises monotonically as the frequency falls for a fixed design (impulse times
//!    scale as 1/f), and the score is at least `0.01 · smoothing`, so each family is scanned
//!    from 150 Hz down only while its smoothing (or `0.01 · smoothing`) can still win.
//!
//! Negative-impulse designs (UM-ZV) are left out: Klipper's smoothing is defined for
//! positive impulse trains, and a negative impulse triples the peak velocity of a shaped
//! move.

use super::klipper::{
    self, max_accel_mm_s2, remaining_vibrations, smoothing_mm, FitSpectrum, Recommendation,
    SHAPER_VIBRATION_REDUCTION, SMOOTHING_ACCEL_MM_S2, SQUARE_CORNER_VELOCITY_MM_S,
};
use beamshaper::config::ModeSetting;
use beamshaper::shaper::{design, Shaper, ShaperKind};

/// Design damping ratios tried: undamped, half, Klipper's, and its highest test value.
pub const DESIGN_ZETAS: [f64; 4] = [0.0, 0.05, 0.1, 0.15];
/// EI vibration tolerances tried: Klipper's 1/20, and the 2 % and 10 % levels of the
/// literature's EI tables (Singhose et al. 1994, 1997).
pub const EI_TOLERANCES: [f64; 3] = [0.02, 0.05, 0.1];
/// Remaining vibrations (fraction) ours may leave above Klipper's recommendation: issue 70's
/// "not worse" margin of 1 point, below the resolution Klipper's users act on (it prints
/// whole recommendations from vibrations differing by less).
pub const VIBRATION_MARGIN: f64 = 0.01;
/// The lowest Klipper score (`smoothing · (R^1.5 + 0.2R + 0.01)`) is at least this times the
/// smoothing (R = 0): the bound that stops a family's scan.
const SCORE_FLOOR: f64 = 0.01;
/// Frequency step of our scan (Hz): half Klipper's 0.2 Hz.
pub const FREQ_STEP_HZ: f64 = 0.1;
/// Lowest shaper frequency tried (Hz): Klipper's lowest `min_freq` (zv).
pub const MIN_SHAPER_FREQ_HZ: f64 = 21.0;
/// Two peaks are distinct modes when the PSD between them falls below this fraction of the
/// smaller peak (the half-power criterion that bounds a resonance's bandwidth).
pub const PEAK_DIP_FRACTION: f64 = 0.5;
/// Half-width of the frequency window searched around each peak for a two-mode design
/// (fraction of the peak frequency).
pub const PEAK_SEARCH_FRACTION: f64 = 0.3;
/// Frequency step (Hz) of the two-mode grid.
pub const PEAK_STEP_HZ: f64 = 0.5;

/// Klipper's metrics of one shaper on one spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Remaining vibrations (fraction).
    pub vibrations: f64,
    /// Smoothing at 5 000 mm/s², scv 5 mm/s (mm).
    pub smoothing_mm: f64,
    /// Max acceleration for 0.12 mm smoothing (mm/s²).
    pub max_accel_mm_s2: f64,
}

/// Klipper's metrics of `s` on `spec`.
pub fn metrics(s: &Shaper, spec: &FitSpectrum) -> Metrics {
    Metrics {
        vibrations: remaining_vibrations(s, spec),
        smoothing_mm: smoothing_mm(s, SMOOTHING_ACCEL_MM_S2, SQUARE_CORNER_VELOCITY_MM_S),
        max_accel_mm_s2: max_accel_mm_s2(s, SQUARE_CORNER_VELOCITY_MM_S),
    }
}

/// A design for a spectrum.
#[derive(Clone, Debug)]
pub struct SpectrumDesign {
    /// Description, e.g. `EI(v 0.10, zeta 0.05) 62.3 Hz` or `ZV 40.0 Hz * MZV 71.5 Hz`.
    pub name: String,
    /// The mode settings that program it on the board (one per convolved factor).
    pub modes: Vec<ModeSetting>,
    /// The shaper.
    pub shaper: Shaper,
    /// Its metrics.
    pub metrics: Metrics,
}

/// Ours and Klipper's on one spectrum.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// Klipper's recommendation and fits.
    pub klipper: Recommendation,
    /// Our design.
    pub ours: SpectrumDesign,
    /// The spectrum's distinct peaks (Hz; one or two) used for the two-mode search.
    pub peaks_hz: Vec<f64>,
}

/// Ours is "not worse" than Klipper's: vibrations ≤ its + 1 point and smoothing ≤ 1.02 × its
/// (issue 70's criterion); "better": not worse and 1 point fewer vibrations or 5 % less
/// smoothing.
pub fn verdict(ours: &Metrics, klipper: &Metrics) -> (bool, bool) {
    let not_worse = ours.vibrations <= klipper.vibrations + 0.01
        && ours.smoothing_mm <= 1.02 * klipper.smoothing_mm;
    let better = not_worse
        && (ours.vibrations <= klipper.vibrations - 0.01
            || ours.smoothing_mm <= 0.95 * klipper.smoothing_mm);
    (not_worse, better)
}

fn kind_label(k: ShaperKind) -> String {
    match k.v_tol() {
        Some(v) => format!("{}(v {v:.2})", k.name().to_uppercase()),
        None => k.name().to_uppercase(),
    }
}

/// The single-mode families: (kind, design ζ).
fn families() -> Vec<(ShaperKind, f64)> {
    let mut kinds = vec![
        ShaperKind::Zv,
        ShaperKind::Mzv,
        ShaperKind::Zvd,
        ShaperKind::Zvdd,
    ];
    for v_tol in EI_TOLERANCES {
        kinds.extend([
            ShaperKind::Ei { v_tol },
            ShaperKind::Ei2Hump { v_tol },
            ShaperKind::Ei3Hump { v_tol },
        ]);
    }
    let mut out = vec![];
    for k in kinds {
        for z in DESIGN_ZETAS {
            out.push((k, z));
        }
    }
    out
}

/// The distinct peaks of the fitting PSD (Hz), largest first, at most two: local maxima above
/// Klipper's threshold (max / 20) such that the PSD between two kept peaks falls below
/// [`PEAK_DIP_FRACTION`] of the smaller one. Only peaks within Klipper's shaper range count.
pub fn two_peaks(spec: &FitSpectrum) -> Vec<f64> {
    let p = &spec.psd;
    let max = p.iter().cloned().fold(0.0, f64::max);
    let th = max / SHAPER_VIBRATION_REDUCTION;
    let cand: Vec<usize> = (1..p.len().saturating_sub(1))
        .filter(|&i| p[i] > th && p[i] >= p[i - 1] && p[i] > p[i + 1])
        .filter(|&i| {
            (MIN_SHAPER_FREQ_HZ * (1.0 - PEAK_SEARCH_FRACTION)..=klipper::MAX_SHAPER_FREQ_HZ)
                .contains(&spec.freq_hz[i])
        })
        .collect();
    let kept = crate::numeric::peaks::distinct_peaks(p, cand, PEAK_DIP_FRACTION, 2);
    kept.iter().map(|&i| spec.freq_hz[i]).collect()
}

/// The vibrations R at which `R^1.5 + 0.2R + 0.01 = g` (bisection; the left side increases
/// with R); 0 for `g ≤ 0.01`.
fn score_inverse(g: f64) -> f64 {
    let h = |r: f64| r.powf(1.5) + 0.2 * r + SCORE_FLOOR;
    if g <= SCORE_FLOOR {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, 1.0f64);
    while h(hi) < g {
        hi *= 2.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        match h(mid) < g {
            true => lo = mid,
            false => hi = mid,
        }
    }
    hi
}

/// What the design minimises within the box (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Objective {
    /// The least smoothing (issue 70's rule).
    #[default]
    LeastSmoothing,
    /// Klipper's score (its own trade between vibrations and smoothing).
    KlipperScore,
}

/// Tracks the best candidate within the box (module docs).
struct Best {
    objective: Objective,
    max_vibrations: f64,
    max_smoothing_mm: f64,
    /// The best value of the objective so far.
    value: f64,
    best: SpectrumDesign,
}

/// What [`Best::offer`] did with a candidate.
#[derive(PartialEq)]
enum Offer {
    /// Its smoothing is out of the box or cannot beat the best score (nor can a lower
    /// frequency of its family).
    Stop,
    /// Scored and not kept.
    Scored,
    /// The new best.
    Kept,
}

impl Best {
    /// Scores `s` unless its smoothing already rules it out; keeps it if in the box with a
    /// lower score than the best so far.
    fn offer(
        &mut self,
        spec: &FitSpectrum,
        name: impl FnOnce() -> String,
        modes: Vec<ModeSetting>,
        s: Shaper,
    ) -> Offer {
        let sm = smoothing_mm(&s, SMOOTHING_ACCEL_MM_S2, SQUARE_CORNER_VELOCITY_MM_S);
        // The largest vibrations that could still win at this smoothing.
        let limit = match self.objective {
            Objective::LeastSmoothing if sm >= self.value => return Offer::Stop,
            Objective::LeastSmoothing => self.max_vibrations,
            Objective::KlipperScore
                if sm > self.max_smoothing_mm || SCORE_FLOOR * sm >= self.value =>
            {
                return Offer::Stop
            }
            Objective::KlipperScore => self.max_vibrations.min(score_inverse(self.value / sm)),
        };
        let Some(v) = klipper::remaining_vibrations_within(&s, spec, limit) else {
            return Offer::Scored;
        };
        let value = match self.objective {
            Objective::LeastSmoothing => sm,
            Objective::KlipperScore => klipper::score(sm, v),
        };
        if v > self.max_vibrations || value >= self.value {
            return Offer::Scored;
        }
        let m = Metrics {
            vibrations: v,
            smoothing_mm: sm,
            max_accel_mm_s2: max_accel_mm_s2(&s, SQUARE_CORNER_VELOCITY_MM_S),
        };
        self.value = value;
        self.best = SpectrumDesign {
            name: name(),
            modes,
            shaper: s,
            metrics: m,
        };
        Offer::Kept
    }
}

/// Our design and Klipper's recommendation on `spec` (module docs), with the box's vibration
/// margin `vibration_margin` (fraction; [`VIBRATION_MARGIN`] by default, 0 = no more
/// vibrations than Klipper's). Errors: none; when nothing in the box does better on
/// `objective`, Klipper's recommendation is the design.
pub fn design_for_spectrum(
    spec: &FitSpectrum,
    objective: Objective,
    vibration_margin: f64,
) -> Comparison {
    let klipper = klipper::recommend(spec);
    let k = &klipper.best;
    let start = SpectrumDesign {
        name: format!("{} {:.1} Hz (Klipper's)", k.kind.name(), k.freq_hz),
        modes: vec![ModeSetting {
            kind: k.kind.core_kind(),
            freq_hz: k.freq_hz,
            zeta: klipper::DEFAULT_DAMPING_RATIO,
        }],
        shaper: k.shaper.clone(),
        metrics: metrics(&k.shaper, spec),
    };
    let mut best = Best {
        objective,
        max_vibrations: start.metrics.vibrations + vibration_margin,
        max_smoothing_mm: start.metrics.smoothing_mm,
        value: match objective {
            Objective::LeastSmoothing => start.metrics.smoothing_mm,
            Objective::KlipperScore => {
                klipper::score(start.metrics.smoothing_mm, start.metrics.vibrations)
            }
        },
        best: start,
    };
    let n = ((klipper::MAX_SHAPER_FREQ_HZ - MIN_SHAPER_FREQ_HZ) / FREQ_STEP_HZ).round() as usize;
    for (kind, zeta) in families() {
        for i in 0..=n {
            let f = klipper::MAX_SHAPER_FREQ_HZ - i as f64 * FREQ_STEP_HZ;
            let Ok(s) = design(kind, f, zeta) else { break };
            let modes = vec![ModeSetting {
                kind,
                freq_hz: f,
                zeta,
            }];
            let name = || format!("{} zeta {zeta:.2} {f:.1} Hz", kind_label(kind));
            if best.offer(spec, name, modes, s) == Offer::Stop {
                break;
            }
        }
    }
    let peaks_hz = two_peaks(spec);
    if peaks_hz.len() == 2 {
        two_mode(spec, &peaks_hz, &mut best);
    }
    Comparison {
        ours: best.best,
        klipper,
        peaks_hz,
    }
}

/// The two-mode convolutions around the two peaks (module docs).
fn two_mode(spec: &FitSpectrum, peaks_hz: &[f64], best: &mut Best) {
    let kinds = [ShaperKind::Zv, ShaperKind::Mzv, ShaperKind::Zvd];
    let zeta = klipper::DEFAULT_DAMPING_RATIO;
    let grid = |p: f64| -> Vec<f64> {
        let n = (2.0 * PEAK_SEARCH_FRACTION * p / PEAK_STEP_HZ).floor() as usize;
        (0..=n)
            .map(|i| p * (1.0 + PEAK_SEARCH_FRACTION) - i as f64 * PEAK_STEP_HZ)
            .filter(|&f| f >= MIN_SHAPER_FREQ_HZ * (1.0 - PEAK_SEARCH_FRACTION))
            .collect()
    };
    let (g1, g2) = (grid(peaks_hz[0]), grid(peaks_hz[1]));
    for k1 in kinds {
        for k2 in kinds {
            for &f1 in &g1 {
                let Ok(s1) = design(k1, f1, zeta) else {
                    continue;
                };
                for &f2 in &g2 {
                    let Ok(s2) = design(k2, f2, zeta) else {
                        continue;
                    };
                    let Ok(s) = s1.convolve(&s2) else { continue };
                    let modes = vec![
                        ModeSetting {
                            kind: k1,
                            freq_hz: f1,
                            zeta,
                        },
                        ModeSetting {
                            kind: k2,
                            freq_hz: f2,
                            zeta,
                        },
                    ];
                    let name = || {
                        format!(
                            "{} {f1:.1} Hz * {} {f2:.1} Hz",
                            kind_label(k1),
                            kind_label(k2)
                        )
                    };
                    if best.offer(spec, name, modes, s) == Offer::Stop {
                        break; // lower f2 only adds smoothing at this f1
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(peaks: &[(f64, f64)]) -> FitSpectrum {
        let freq_hz: Vec<f64> = (0..400).map(|i| 5.0 + 0.5 * i as f64).collect();
        let psd = freq_hz
            .iter()
            .map(|&f| {
                peaks
                    .iter()
                    .map(|&(fp, a)| a / (1.0 + ((f - fp) / (0.05 * fp)).powi(2)))
                    .sum::<f64>()
            })
            .collect();
        FitSpectrum { freq_hz, psd }
    }

    #[test]
    fn ours_is_in_the_box_and_scores_no_worse_than_klipper() {
        let s = spec(&[(48.0, 1.0)]);
        for o in [Objective::LeastSmoothing, Objective::KlipperScore] {
            let c = design_for_spectrum(&s, o, VIBRATION_MARGIN);
            let k = metrics(&c.klipper.best.shaper, &s);
            assert!(c.ours.metrics.vibrations <= k.vibrations + VIBRATION_MARGIN);
            assert!(c.ours.metrics.smoothing_mm <= k.smoothing_mm);
            let ks = klipper::score(k.smoothing_mm, k.vibrations);
            let os = klipper::score(c.ours.metrics.smoothing_mm, c.ours.metrics.vibrations);
            if o == Objective::KlipperScore {
                assert!(os <= ks);
            }
            assert_eq!(c.peaks_hz.len(), 1);
        }
    }

    #[test]
    fn two_separated_peaks_are_found_and_one_broad_peak_is_one() {
        assert_eq!(two_peaks(&spec(&[(40.0, 1.0), (80.0, 0.6)])).len(), 2);
        assert_eq!(two_peaks(&spec(&[(40.0, 1.0), (41.0, 0.6)])).len(), 1);
    }
}
