//! Evidence measures of condition 6 of [`super::guard`]: the share of the structured residual a
//! model removes ([`structure_explained`]), taken also in the effect's own band
//! ([`EFFECT_BAND_POWER`]) when what it leaves outside is no response to the motion
//! ([`driven_share`], [`MAX_DRIVEN_SHARE`]), judged outside the residual's bursts
//! ([`burst_samples`]).

use super::guard::*;
use crate::diagnose::fit::FORCE_CHANNEL;
use crate::diagnose::rate::welch_power;
use crate::ident::frf::{welch, Frf, WelchOptions, Window};
use crate::numeric::stats::{innovation_variance, median};

/// The validation residuals `before` and `after` (one channel) as conditions 4 and 6 of
/// [`super::guard`] judge them. On `force_n` (`channel` [`FORCE_CHANNEL`]) the residual's
/// **bursts** ([`burst_samples`]: outliers of `before` that `after` leaves as outliers too) are
/// replaced by each residual's median: the force a drive reports around an acceleration step is
/// its loop's transient between samples, which the samples do not resolve and no catalogue
/// effect models; at ±1 N against a 0.05 N cogging ripple those few samples held most of the
/// force residual's variance and autocovariance, and every force effect "removed only" a third
/// of it (docs/diagnose.md, session 20). Samples the effect brings back to the background are its
/// own signal, not bursts: friction's force while a short move runs stood out of a mostly
/// resting residual like a burst, and taking it out left the effect "removing −189 %" of what
/// remained (docs/diagnose.md, session 23). Other channels, and a residual without bursts, are
/// returned as they are.
pub(crate) fn judged(
    before: Option<&[f64]>,
    after: Option<&[f64]>,
    channel: usize,
) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
    let burst = match (before, after, channel) {
        (Some(b), Some(a), FORCE_CHANNEL) => burst_samples(b, a),
        _ => None,
    };
    let quiet = |r: Option<&[f64]>| -> Option<Vec<f64>> {
        let r = r?;
        let Some(burst) = &burst else {
            return Some(r.to_vec());
        };
        let centre = median(r);
        Some(
            r.iter()
                .zip(burst)
                .map(|(x, out)| if *out { centre } else { *x })
                .collect(),
        )
    };
    (quiet(before), quiet(after))
}

/// Fraction of the structured validation residual (variance above the white-noise floor, the
/// smaller innovation variance of the two, [`innovation_variance`]) that `after` removes from
/// `before` ([`super::guard`] condition 6), both as [`judged`] on `channel`; `None` without
/// both.
pub(crate) fn structure_explained(
    before: Option<&[f64]>,
    after: Option<&[f64]>,
    channel: usize,
) -> Option<f64> {
    let (b, a) = judged(before, after, channel);
    share_removed(b.as_deref(), a.as_deref(), &[])
}

/// [`structure_explained`] of residuals already [`judged`]: the larger of the share over the
/// whole band and the share in the effect's own band ([`share_in_effect_band`]) when what the
/// effect leaves outside its band is not a response to `inputs` ([`driven_share`]); the whole
/// band alone without inputs.
fn share_removed(b: Option<&[f64]>, a: Option<&[f64]>, inputs: &[&[f64]]) -> Option<f64> {
    let (b, a) = (b?, a?);
    let var = |r: &[f64]| {
        let m = r.iter().sum::<f64>() / r.len().max(1) as f64;
        r.iter().map(|x| (x - m).powi(2)).sum::<f64>() / r.len().max(1) as f64
    };
    let noise = innovation_variance(b, LJUNG_BOX_LAGS).min(innovation_variance(a, LJUNG_BOX_LAGS));
    let (sb, sa) = ((var(b) - noise).max(0.0), (var(a) - noise).max(0.0));
    let whole = if sb > 0.0 { 1.0 - sa / sb } else { 0.0 };
    if inputs.is_empty() {
        return Some(whole);
    }
    Some(share_in_effect_band(b, a, noise, inputs).map_or(whole, |s| s.max(whole)))
}

/// Share of power the effect's band must hold of the change it makes (`before − after`).
pub const EFFECT_BAND_POWER: f64 = 0.9;

/// The share of the structured residual `after` removes from `before` **in the effect's own
/// band**: the fewest periodogram bins that hold [`EFFECT_BAND_POWER`] of the change the effect
/// makes (`before − after`), the white floor `noise` (variance) counted at its share of those
/// bins. Structure outside that band is another thing the effect does not claim to be — a
/// drive's position loop hunting near the Nyquist rate beside friction's sign(v) force on a
/// real axis — and is left for the unexplained report; in the band where it acts the effect
/// must still remove most of it, as condition 6 asks. Only structure that is *not a response
/// to the inputs* counts as another thing: when most of what is left outside the band is
/// coherent with the command or the model's prediction ([`driven_share`] over
/// [`MAX_DRIVEN_SHARE`]), it is the rest of the same driven signature — a loose tip sensor's
/// resonance seen at mode 1 as a latency and at mode 2 as nothing in the catalogue — and the
/// whole band decides. `None` then, when the structure in the band is not significant (below 3
/// standard errors of the noise's periodogram summed over the band) or the residuals are too
/// short.
fn share_in_effect_band(b: &[f64], a: &[f64], noise: f64, inputs: &[&[f64]]) -> Option<f64> {
    let n = b.len();
    if n != a.len() || n < 4 * LJUNG_BOX_LAGS {
        return None;
    }
    let d: Vec<f64> = b.iter().zip(a).map(|(x, y)| x - y).collect();
    // one Hann segment over the record, no padding (bin k at k/n cycles per sample): a
    // component's power stays in a few bins
    let (pb, pa, pd) = (welch_power(b, n), welch_power(a, n), welch_power(&d, n));
    let total: f64 = pd.iter().skip(1).sum();
    if !(total > 0.0) {
        return None;
    }
    let mut order: Vec<usize> = (1..pd.len()).collect();
    order.sort_by(|&i, &j| pd[j].total_cmp(&pd[i]));
    let (mut held, mut band) = (0.0, Vec::new());
    for k in order {
        if held >= EFFECT_BAND_POWER * total {
            break;
        }
        held += pd[k];
        band.push(k);
    }
    // white noise of variance σ² puts σ² Σw² = 3nσ²/8 in each bin of a Hann periodogram
    let floor = 0.375 * n as f64 * noise * band.len() as f64;
    let sum = |p: &[f64]| band.iter().map(|&k| p[k]).sum::<f64>();
    let (sb, sa) = (sum(&pb) - floor, (sum(&pa) - floor).max(0.0));
    if !(sb > 3.0 * floor / (band.len() as f64).sqrt()) {
        return None;
    }
    let band_hz: Vec<f64> = band.iter().map(|&k| k as f64 / n as f64).collect();
    if driven_share(a, noise, &band_hz, inputs) > MAX_DRIVEN_SHARE {
        return None;
    }
    Some(1.0 - sa / sb)
}

/// Largest share of the structure an effect leaves outside its own band that may be a
/// response to the inputs for the in-band judgement to apply ([`share_in_effect_band`]).
pub const MAX_DRIVEN_SHARE: f64 = 0.5;

/// The share of the structured power of `after` outside the effect's band (`band` frequencies
/// in cycles per sample) that is coherent with one of `inputs` (same length): Σ γ²(f) S(f) /
/// Σ S(f) over the Welch frequencies outside the band ([`crate::ident::frf::welch`]: Hann
/// segments of the largest power of two ≤ n/4, half overlapping), S the auto-spectrum above the
/// white floor `noise` (variance), γ² the largest ordinary coherence with an input (Bendat &
/// Piersol, *Random Data*, 4th ed., §9.2.3; with K segments an incoherent pair reads ≈ 1/K).
/// A response to the command — linear, or through the model's own prediction — is coherent; a
/// drive's loop hunting, a sensor's drift or mains pickup is not. 0 when nothing structured
/// is left outside the band or the residual is too short for four segments.
fn driven_share(after: &[f64], noise: f64, band: &[f64], inputs: &[&[f64]]) -> f64 {
    let quarter = after.len() / 4;
    if quarter < 32 {
        return 0.0;
    }
    // the largest power of two ≤ n/4
    let seg = 1usize << (usize::BITS - 1 - quarter.leading_zeros());
    let Some(own) = power_spectrum(after, after, Some(seg), Window::Hann) else {
        return 0.0;
    };
    let df = own.df_hz();
    let left: Vec<(usize, f64)> = (1..own.syy.len())
        .filter(|&j| !band.iter().any(|f| (f - own.freq_hz[j]).abs() <= 0.5 * df))
        .map(|j| (j, (own.syy[j] - 2.0 * noise) * df))
        .filter(|(_, s)| *s > 0.0)
        .collect();
    let total: f64 = left.iter().map(|(_, s)| s).sum();
    if !(total > 0.0) {
        return 0.0;
    }
    let coherence: Vec<Vec<f64>> = inputs
        .iter()
        .filter_map(|u| power_spectrum(u, after, Some(seg), Window::Hann))
        .map(|f| f.coherence)
        .collect();
    left.iter()
        .map(|&(j, s)| s * coherence.iter().map(|g| g[j]).fold(0.0, f64::max))
        .sum::<f64>()
        / total
}

/// Welch spectra of `y` over `x` (unit sample rate: frequencies in cycles per sample; mean
/// removed; half-overlapping segments of `segment` samples, the whole record for `None`),
/// `None` where the estimator refuses the pair (different lengths, too short, no energy).
fn power_spectrum(x: &[f64], y: &[f64], segment: Option<usize>, window: Window) -> Option<Frf> {
    let opts = WelchOptions {
        nperseg: segment,
        window,
        ..WelchOptions::default()
    };
    welch(x, y, 1.0, &opts).ok()
}

/// Conditions 4 and 6 from one [`judged`] pass: the correlated power (Σ of squared
/// autocovariances, [`structured_power`]; 0 for a missing channel) of `before` and `after`,
/// and the share of the structure `after` removes ([`structure_explained`]).
pub(crate) fn structure_evidence(
    before: Option<&[f64]>,
    after: Option<&[f64]>,
    channel: usize,
    inputs: &[&[f64]],
) -> ((f64, f64), Option<f64>) {
    let (b, a) = judged(before, after, channel);
    let sp = |v: Option<&[f64]>| v.map_or(0.0, |r| structured_power(r, LJUNG_BOX_LAGS));
    (
        (sp(b.as_deref()), sp(a.as_deref())),
        share_removed(b.as_deref(), a.as_deref(), inputs),
    )
}

/// Robust outlier threshold of a burst, in robust standard deviations (1.4826 × the median
/// absolute deviation) of the residual.
pub const BURST_ROBUST_SIGMAS: f64 = 6.0;

/// Largest share of the samples that may be bursts; beyond it the residual is not "a background
/// with bursts" and nothing is excluded.
pub const MAX_BURST_SHARE: f64 = 0.1;

/// The samples of `r` beyond [`BURST_ROBUST_SIGMAS`] robust σ of its median; `None` for a
/// residual too short to judge or without spread.
pub(crate) fn outliers(r: &[f64]) -> Option<Vec<bool>> {
    if r.len() < 4 * LJUNG_BOX_LAGS {
        return None;
    }
    let centre = median(r);
    let scale = 1.4826 * median(&r.iter().map(|x| (x - centre).abs()).collect::<Vec<f64>>());
    if !(scale > 0.0) {
        return None;
    }
    Some(
        r.iter()
            .map(|x| (x - centre).abs() > BURST_ROBUST_SIGMAS * scale)
            .collect(),
    )
}

/// The samples of the residuals `before` and `after` an effect (one channel, same length) in
/// **bursts**: outliers ([`outliers`], beyond [`BURST_ROBUST_SIGMAS`] robust σ of the median)
/// of `before` that stay outliers of `after` — what neither model explains —, widened by two
/// samples either side (the tail of a transient). `None` when there are none, or when more than
/// [`MAX_BURST_SHARE`] of the samples would be.
pub(crate) fn burst_samples(before: &[f64], after: &[f64]) -> Option<Vec<bool>> {
    let n = before.len();
    if after.len() != n {
        return None;
    }
    let (ob, oa) = (outliers(before)?, outliers(after)?);
    let mut burst = vec![false; n];
    for k in (0..n).filter(|&k| ob[k] && oa[k]) {
        burst[k.saturating_sub(2)..(k + 3).min(n)]
            .iter_mut()
            .for_each(|b| *b = true);
    }
    let count = burst.iter().filter(|b| **b).count();
    (count > 0 && (count as f64) <= MAX_BURST_SHARE * n as f64).then_some(burst)
}
