//! Camera glitches on the tip channel: isolated samples far off their neighbours.
//!
//! A camera that loses its marker for a frame (a reflection, another bright blob, a dropped
//! line) writes a tip position millimetres off for one to three samples and then tracks again.
//! The beam cannot move so: its tip is band-limited by its modes. Left in, a handful of such
//! samples carry more squared residual than the whole rest of a recording and a diagnosis names
//! whatever absorbs a broadband residual best (independent cases with ten 5–30 mm glitches per
//! recording: a null, a friction and a latency case each gained a 4th-order servo loop;
//! docs/diagnose.md "Session 48").
//!
//! A run of 1 to [`MAX_GLITCH_RUN`] samples is a glitch when
//! 1. every sample of it is more than [`GLITCH_SCALES`] local scales off the cubic
//!    least-squares fit through the four samples before and the four after it. The local scale
//!    is the median, over ±[`LOCAL_HALF_WIDTH`] samples, of every sample's distance from the
//!    cubic through its own eight neighbours, floored by the recording's median non-zero
//!    distance (a quantised, resting tip has most at 0). A cubic follows a large slow swing to
//!    its fourth derivative (a median of the neighbours misses its crest by its curvature,
//!    millimetres on a 2 Hz, 40 mm swing at 100 Hz); a beam mode even at 0.45 × the sample rate
//!    rings at every sample alike and raises the local scale with it; Gaussian noise passes 25
//!    scales never. A mode struck by a stop rings for a few samples only, and at 100 Hz a 20 Hz
//!    transient leaves the cubic by 12–16 local scales (independent case14): 25 leaves it alone,
//!    and a camera glitch is millimetres against a scale of tens of micrometres;
//! 2. that cubic fits the eight samples either side to within [`CLEAN_STENCIL_SCALES`] local
//!    scales and a quarter of the run's largest distance: no glitch among them (a clean sample
//!    beside a glitch is judged on a fit pulled by it, and would otherwise be taken for one),
//!    and no step (a camera re-zeroed mid-recording, left to the diagnosis).
//!
//! Runs are tried shortest first at every sample; two glitches closer than four samples spoil
//! each other's fits and are left alone.
//!
//! Glitches are replaced by the degree-5 local interpolation of the other samples
//! ([`super::regular::lagrange_at`]) with a note naming how many, the largest distance and the
//! first times. When more than [`MAX_GLITCH_FRACTION`] of the samples qualify, the channel is
//! not a clean signal with glitches, and it is left as recorded with a note.

use super::{fmt_sig, Recording};
use crate::numeric::stats::median;
use nalgebra::{DMatrix, DVector};

/// How many local scales a sample must be off the median of its neighbours to be a glitch.
pub const GLITCH_SCALES: f64 = 25.0;
/// Half-width (samples) of the window of the local scale.
pub const LOCAL_HALF_WIDTH: usize = 50;
/// The longest run of consecutive glitch samples.
pub const MAX_GLITCH_RUN: usize = 3;
/// The largest share of a channel's samples that are replaced.
pub const MAX_GLITCH_FRACTION: f64 = 0.05;

/// Samples each side of a run through which its cubic is fitted.
const NEIGHBOURS: usize = 4;

/// How many local scales the cubic's rms residual on the samples either side of a run may
/// reach: more, and a glitch sits among them or the tip steps there.
const CLEAN_STENCIL_SCALES: f64 = 2.0;

/// `rec` with the glitches of `tip_pos_m` replaced (module header), with a note; unchanged
/// without a tip channel or a glitch.
pub fn mend_tip_glitches(mut rec: Recording) -> Recording {
    let Some(tip) = rec.tip_pos_m.as_ref() else {
        return rec;
    };
    let found = glitches(tip);
    if found.is_empty() {
        return rec;
    }
    let n = tip.len();
    let count: usize = found.iter().map(|g| g.len).sum();
    let largest = found.iter().map(|g| g.distance).fold(0.0, f64::max);
    if count as f64 > MAX_GLITCH_FRACTION * n as f64 {
        rec.notes.push(format!(
            "tip_pos_m: {count} samples lie far off their neighbours (up to {} m), more than {:.0} % of the recording: left as recorded",
            fmt_sig(largest, 3),
            100.0 * MAX_GLITCH_FRACTION
        ));
        return rec;
    }
    let mut bad = vec![false; n];
    for g in &found {
        bad[g.start..g.start + g.len]
            .iter_mut()
            .for_each(|b| *b = true);
    }
    let (u, x): (Vec<f64>, Vec<f64>) = (0..n)
        .filter(|&k| !bad[k])
        .map(|k| (k as f64, tip[k]))
        .unzip();
    let at: Vec<usize> = (0..n).filter(|&k| bad[k]).collect();
    let filled = super::regular::lagrange_at(&u, &x, at.iter().map(|&k| k as f64));
    let times: Vec<String> = found
        .iter()
        .take(3)
        .map(|g| format!("{} s", fmt_sig(rec.time_s[g.start], 4)))
        .collect();
    let tip = rec.tip_pos_m.as_mut().expect("checked above");
    for (&k, v) in at.iter().zip(filled) {
        tip[k] = v;
    }
    rec.notes.push(format!(
        "tip_pos_m: {count} samples in {} glitches (a camera losing its marker: up to {} m off their neighbours, first at {}{}) replaced by interpolation",
        found.len(),
        fmt_sig(largest, 3),
        times.join(", "),
        if found.len() > 3 { ", …" } else { "" }
    ));
    rec
}

/// One run of glitch samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Glitch {
    /// First sample.
    pub start: usize,
    /// Samples in the run (1..=[`MAX_GLITCH_RUN`]).
    pub len: usize,
    /// Largest distance from the neighbours' median in the run (channel units).
    pub distance: f64,
}

/// The glitches of `x` (module header), in order.
pub fn glitches(x: &[f64]) -> Vec<Glitch> {
    let n = x.len();
    if n < 2 * LOCAL_HALF_WIDTH || x.iter().any(|v| !v.is_finite()) {
        return Vec::new();
    }
    // the scale: each sample against the cubic through its neighbours (a gap of one)
    let one = GapFit::new(1);
    let d: Vec<f64> = (0..n)
        .map(|k| one.at(x, k).map_or(0.0, |(dev, _)| dev[0]))
        .collect();
    let nonzero: Vec<f64> = d.iter().map(|v| v.abs()).filter(|v| *v > 0.0).collect();
    if nonzero.is_empty() {
        return Vec::new();
    }
    let floor = median(&nonzero);
    let scale: Vec<f64> = (0..n)
        .map(|k| {
            let (lo, hi) = (
                k.saturating_sub(LOCAL_HALF_WIDTH),
                (k + LOCAL_HALF_WIDTH + 1).min(n),
            );
            let w: Vec<f64> = d[lo..hi].iter().map(|v| v.abs()).collect();
            median(&w).max(floor)
        })
        .collect();
    // every run of 1..=MAX_GLITCH_RUN samples whose every sample is far off the cubic through
    // the samples either side, which that cubic fits (no glitch among them, no step)
    let fits: Vec<GapFit> = (1..=MAX_GLITCH_RUN).map(GapFit::new).collect();
    let mut out: Vec<Glitch> = Vec::new();
    let mut k = 0;
    while k < n {
        let found = fits.iter().find_map(|f| {
            let (dev, rms) = f.at(x, k)?;
            let s = scale[k];
            let far = dev.iter().all(|v| v.abs() > GLITCH_SCALES * s);
            let distance = dev.iter().map(|v| v.abs()).fold(0.0, f64::max);
            (far && rms < CLEAN_STENCIL_SCALES * s && rms < 0.25 * distance).then_some(Glitch {
                start: k,
                len: f.len,
                distance,
            })
        });
        match found {
            Some(g) => {
                k += g.len;
                out.push(g);
            }
            None => k += 1,
        }
    }
    out
}

/// The cubic least-squares fit through the [`NEIGHBOURS`] samples before and after a run of
/// `len` samples, as fixed weights (the stencil's geometry is the same at every run).
struct GapFit {
    len: usize,
    /// Stencil offsets from the run's first sample.
    offsets: Vec<i64>,
    /// Pseudo-inverse of the stencil's cubic design matrix (4 × stencil).
    pinv: DMatrix<f64>,
}

impl GapFit {
    fn new(len: usize) -> GapFit {
        let h = NEIGHBOURS as i64;
        let offsets: Vec<i64> = (-h..0).chain(len as i64..len as i64 + h).collect();
        let a = DMatrix::from_fn(offsets.len(), 4, |i, p| (offsets[i] as f64).powi(p as i32));
        let pinv = a
            .pseudo_inverse(1e-12)
            .expect("a cubic through eight distinct points");
        GapFit { len, offsets, pinv }
    }

    /// For the run of `len` samples from `s` of `x`: each sample's distance from the cubic
    /// through the stencil, and the cubic's rms residual on the stencil; `None` where the
    /// stencil leaves the recording.
    fn at(&self, x: &[f64], s: usize) -> Option<(Vec<f64>, f64)> {
        let first = s as i64 + self.offsets[0];
        let last = s as i64 + self.offsets[self.offsets.len() - 1];
        if first < 0 || last >= x.len() as i64 {
            return None;
        }
        let y = DVector::from_iterator(
            self.offsets.len(),
            self.offsets.iter().map(|o| x[(s as i64 + o) as usize]),
        );
        let c = &self.pinv * &y;
        let cubic = |u: f64| c[0] + u * (c[1] + u * (c[2] + u * c[3]));
        let ss: f64 = self
            .offsets
            .iter()
            .zip(y.iter())
            .map(|(o, v)| (v - cubic(*o as f64)).powi(2))
            .sum();
        let dev = (0..self.len).map(|i| x[s + i] - cubic(i as f64)).collect();
        Some((dev, (ss / self.offsets.len() as f64).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// A tip recording at `rate` Hz: modes at 1.2 Hz and 0.42 × the rate ringing down over a
    /// move, camera noise 30 µm, quantised to `quantum` m (0: none).
    fn tip(rate: f64, n: usize, quantum: f64, seed: u64) -> Vec<f64> {
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 3e-5).unwrap();
        (0..n)
            .map(|k| {
                let t = k as f64 / rate;
                let move_m = 0.2 * (t / 5.0).min(1.0);
                let ring = 0.01 * (-0.1 * t).exp() * (2.0 * std::f64::consts::PI * 1.2 * t).sin()
                    + 0.002
                        * (-0.3 * t).exp()
                        * (2.0 * std::f64::consts::PI * 0.42 * rate * t).sin();
                let v = move_m + ring + noise.sample(&mut rng);
                if quantum > 0.0 {
                    (v / quantum).round() * quantum
                } else {
                    v
                }
            })
            .collect()
    }

    #[test]
    fn a_clean_tip_has_no_glitch_at_any_rate_or_quantum() {
        for (rate, quantum, seed) in [(50.0, 0.0, 1), (100.0, 1e-4, 2), (1000.0, 1e-5, 3)] {
            let x = tip(rate, 3000, quantum, seed);
            assert!(glitches(&x).is_empty(), "{rate} Hz, quantum {quantum}");
        }
    }

    #[test]
    fn isolated_glitches_are_found_and_replaced_near_the_truth() {
        let clean = tip(100.0, 3000, 0.0, 4);
        let mut x = clean.clone();
        let mut rng = StdRng::seed_from_u64(9);
        let mut at = Vec::new();
        // from 6 s on, where the 0.42 × rate mode has rung down to 0.3 mm (12 mm among a
        // 1 mm ring at 0.42 × the rate is within 12 local scales, and is rightly left)
        for j in 0..8 {
            let k = 600 + 300 * j;
            let len = 1 + j % 3;
            for i in 0..len {
                x[k + i] += if j % 2 == 0 { 0.012 } else { -0.02 } + rng.gen_range(-1e-3..1e-3);
            }
            at.push((k, len));
        }
        let found: Vec<(usize, usize)> = glitches(&x).iter().map(|g| (g.start, g.len)).collect();
        assert_eq!(found, at);
        let rec = Recording {
            tip_pos_m: Some(x),
            ..Recording::with_uniform_time(3000, 100.0)
        };
        let mended = mend_tip_glitches(rec);
        assert!(mended.notes[0].contains("8 glitches"), "{:?}", mended.notes);
        let worst = mended
            .tip_pos_m
            .unwrap()
            .iter()
            .zip(&clean)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // the 0.42 × rate mode is filled across three samples only roughly; far below 12 mm
        assert!(worst < 2e-3, "worst {worst}");
    }

    #[test]
    fn a_step_or_a_long_excursion_is_not_a_glitch() {
        let mut x = tip(100.0, 3000, 0.0, 5);
        // a camera re-zeroed: every sample from 1500 on 5 mm off
        x[1500..].iter_mut().for_each(|v| *v += 0.005);
        // a marker lost for 6 samples
        x[800..806].iter_mut().for_each(|v| *v += 0.02);
        assert!(glitches(&x).is_empty(), "{:?}", glitches(&x));
    }

    #[test]
    fn a_channel_full_of_outliers_is_left_as_recorded() {
        let mut x = tip(100.0, 3000, 0.0, 6);
        // a two-sample glitch every 22 samples: 9 % of the samples, yet four clean samples
        // either side of each
        for k in (100..2900).step_by(22) {
            x[k] += 0.01;
            x[k + 1] += 0.01;
        }
        let rec = Recording {
            tip_pos_m: Some(x.clone()),
            ..Recording::with_uniform_time(3000, 100.0)
        };
        let out = mend_tip_glitches(rec);
        assert_eq!(out.tip_pos_m.unwrap(), x);
        assert!(out.notes[0].contains("left as recorded"), "{:?}", out.notes);
    }
}
