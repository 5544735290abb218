//! Sensor saturation: the samples a channel recorded at the end of its range.
//!
//! A sensor at its rail — a camera whose target leaves the field of view, an ADC at full
//! scale, a drive's force reading at its current limit — writes the same extreme value for as
//! long as the true signal lies beyond it. Such a sample says only "at least this far".
//! Compared with the model as if it were the signal, the flattened peaks pull every fit
//! towards smaller amplitudes: a stiffer, heavier or more damped beam than the rig's, which
//! the catalogue then names (independent case03 with its tip clipped at 80 % of its peak:
//! `tip_mass` instead of `root_compliance`, docs/diagnose.md, session 21).
//!
//! **Rule** (per output channel, `tip_pos_m` and `force_n`, of one recording as read): a rail
//! is the channel's largest (or smallest) value when
//! 1. it is held exactly — a rail is one number — on at least [`MIN_RAIL_SAMPLES`] samples, and
//! 2. on at least one run the signal was cut off in mid-swing: it steps into the run and out
//!    of it by s_in, s_out > [`MIN_STEP_NOISE`] × the channel's noise σ and two quanta of its
//!    grid ([`crate::numeric::stats::quantum`]), and a parabola leaving the run's ends with the
//!    smaller of those steps would have passed the rail by H = min(s_in, s_out)(L + 1)/4 over
//!    the run's L samples, more than [`MIN_HIDDEN_NOISE`] σ and four quanta. A beam that
//!    settles at its extreme position arrives in steps of a count or of the noise, a peak
//!    rounded within a count hides a few σ (held-out 332002: a 250 Hz tip on 0.1 mm counts
//!    held a peak for four samples, H = 4.1 σ, the most of any unclipped recording of held-out
//!    327000 and the independent set); a clipped swing hides 16–380 σ (docs/diagnose.md,
//!    session 21). A run at either end of the recording shows no cut-off.
//!
//! Every sample at a rail is left out of every residual ([`super::fit::residuals`] gives it
//! zero), so it constrains nothing; more than [`MAX_RAIL_FRACTION`] of a channel at its rails is
//! refused (the recording says too little). The noise σ is the robust spread of the second
//! difference, 1.4826 MAD(Δ²y)/√6 (white noise of σ has Δ² of variance 6σ²; a swing's own
//! curvature A ω² dt² inflates it, but a cut-off hides ≈ A ω dt L, larger by L/(ω dt)).

use crate::numeric::stats::{quantum, second_difference_noise};

/// Fewest samples at one rail for it to be one.
pub const MIN_RAIL_SAMPLES: usize = 3;
/// The steps into and out of a cut-off run, at least, in units of the noise σ.
pub const MIN_STEP_NOISE: f64 = 3.0;
/// The swing a flat run hides beyond its rail that shows a cut-off, in units of the noise σ.
pub const MIN_HIDDEN_NOISE: f64 = 10.0;
/// Largest share of a channel at its rails that still leaves a recording worth fitting.
pub const MAX_RAIL_FRACTION: f64 = 0.25;

/// The rails found on one channel and the runs of samples `[start, end)` held at them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rails {
    /// The lower and upper rail values (channel units), where found.
    pub values: Vec<f64>,
    /// Runs of samples at a rail, `[start, end)`, ascending.
    pub runs: Vec<(usize, usize)>,
}

impl Rails {
    /// Samples at a rail.
    pub fn samples(&self) -> usize {
        self.runs.iter().map(|(a, b)| b - a).sum()
    }

    /// The rail values in words, e.g. `-0.008000, 0.008000`.
    pub fn values_words(&self) -> String {
        let v: Vec<String> = self.values.iter().map(|v| format!("{v:.6}")).collect();
        v.join(", ")
    }

    /// The runs on a time base decimated by `q` (kept sample `k` = input sample `k q`), widened
    /// by `margin` kept samples on each side: a filtered sample near a clipped one carries it.
    pub fn decimated(&self, q: usize, margin: usize, len: usize) -> Rails {
        if q <= 1 {
            return self.clone();
        }
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for &(a, b) in &self.runs {
            let (s, e) = (
                (a / q).saturating_sub(margin),
                (b.div_ceil(q) + margin).min(len),
            );
            match runs.last_mut() {
                Some(last) if s <= last.1 => last.1 = last.1.max(e),
                _ => runs.push((s, e)),
            }
        }
        Rails {
            values: self.values.clone(),
            runs,
        }
    }
}

/// The rails of channel `y` (module rule); empty when it has none.
pub fn rails(y: &[f64]) -> Rails {
    let n = y.len();
    if n < 8 || y.iter().any(|v| !v.is_finite()) {
        return Rails::default();
    }
    let noise = second_difference_noise(y);
    let q = quantum(y).unwrap_or(0.0);
    let (step_min, hidden_min) = (
        (MIN_STEP_NOISE * noise).max(2.0 * q),
        (MIN_HIDDEN_NOISE * noise).max(4.0 * q),
    );
    let lo = y.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(hi > lo) {
        return Rails::default();
    }
    let mut out = Rails::default();
    for rail in [lo, hi] {
        let runs = runs_at(y, rail);
        let held: usize = runs.iter().map(|(a, b)| b - a).sum();
        let cut_off = runs
            .iter()
            .any(|&(a, b)| match (a.checked_sub(1), y.get(b)) {
                (Some(k), Some(v)) => {
                    let step = (y[k] - rail).abs().min((v - rail).abs());
                    step > step_min && step * (b - a + 1) as f64 / 4.0 > hidden_min
                }
                _ => false,
            });
        if held >= MIN_RAIL_SAMPLES && cut_off {
            out.values.push(rail);
            out.runs.extend(runs);
        }
    }
    out.runs.sort_unstable();
    out
}

/// Runs `[start, end)` of samples of `y` exactly equal to `v`.
fn runs_at(y: &[f64], v: f64) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (k, &x) in y.iter().enumerate() {
        match (x == v, start) {
            (true, None) => start = Some(k),
            (false, Some(s)) => {
                runs.push((s, k));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push((s, y.len()));
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A decaying swing of 10 mm at 1.5 Hz sampled at 100 Hz with 30 µm noise on 10 µm counts.
    fn swing(seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 30e-6).unwrap();
        (0..3000)
            .map(|k| {
                let t = k as f64 * 0.01;
                let x = 0.01 * (-0.05 * t).exp() * (2.0 * std::f64::consts::PI * 1.5 * t).sin()
                    + noise.sample(&mut rng);
                (x / 1e-5).round() * 1e-5
            })
            .collect()
    }

    #[test]
    fn a_swing_clipped_at_its_rails_is_found_and_an_unclipped_one_is_not() {
        let y = swing(1);
        assert_eq!(rails(&y), Rails::default(), "no rail on a free swing");
        let lim = 0.008;
        let clipped: Vec<f64> = y.iter().map(|v| v.clamp(-lim, lim)).collect();
        let r = rails(&clipped);
        assert_eq!(r.values, vec![-lim, lim]);
        let at = clipped.iter().filter(|v| v.abs() >= lim).count();
        assert_eq!(r.samples(), at);
        assert!(r
            .runs
            .iter()
            .all(|&(a, b)| clipped[a..b].iter().all(|v| v.abs() == lim)));
    }

    #[test]
    fn a_beam_at_rest_at_its_extreme_position_is_no_rail() {
        // a move to +20 mm that settles (the largest value is held at the end, in counts of
        // 0.5 mm, a coarse camera): arrived at in steps of the grid, not cut off
        let y: Vec<f64> = (0..2000)
            .map(|k| {
                let t = k as f64 * 0.01;
                let x = 0.02 * (1.0 - (-3.0 * t).exp() * (1.0 + 3.0 * t));
                (x / 5e-4).round() * 5e-4
            })
            .collect();
        assert!(y[1500..].iter().all(|v| *v == y[1999]), "held at the end");
        assert_eq!(rails(&y).values, Vec::<f64>::new());
    }

    #[test]
    fn a_recording_mostly_at_its_rails_is_refused_by_name() {
        let y = swing(2);
        let mut rec = crate::recording::Recording::with_uniform_time(y.len(), 100.0);
        rec.base_cmd_m = Some(vec![0.0; y.len()]);
        rec.tip_pos_m = Some(y.iter().map(|v| v.clamp(-0.002, 0.002)).collect());
        let e = super::super::model::Prepared::new("swing.csv", &rec).unwrap_err();
        let text = format!("{e:#}");
        assert!(
            text.contains("swing.csv") && text.contains("tip_pos_m") && text.contains("rail"),
            "{text}"
        );
        // clipped on a few swings only: prepared, those samples marked
        rec.tip_pos_m = Some(y.iter().map(|v| v.clamp(-0.009, 0.009)).collect());
        let d = super::super::model::Prepared::new("swing.csv", &rec).unwrap();
        assert!(d.rails[1].samples() > 0 && d.rails[2].runs.is_empty());
    }

    #[test]
    fn decimated_runs_cover_the_kept_samples_near_a_clip() {
        let r = Rails {
            values: vec![1.0],
            runs: vec![(10, 14), (17, 19), (100, 101)],
        };
        let d = r.decimated(4, 1, 30);
        // (10,14) → kept 2..4 widened to 1..5; (17,19) → 4..5 widened 3..6, merged
        assert_eq!(d.runs, vec![(1, 6), (24, 27)]);
        let at = |k: usize| d.runs.iter().any(|&(a, b)| a <= k && k < b);
        assert!(at(5) && !at(6));
    }
}
