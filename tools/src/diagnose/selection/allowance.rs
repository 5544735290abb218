//! The model-form allowance of condition 3 of [`super::guard`]: what a physics-free correction
//! with as many parameters earns on the validation residual ([`allowance`], with the
//! dictionary's columns [`generic_columns`] less the candidates' own physics, [`FORCE_WITHOUT`],
//! [`BASE_WITHOUT_LOOP`]), the split-refit gain's share, and the reduction credited to a
//! candidate per channel.

use super::guard::*;
use super::state::Reference;
use crate::diagnose::model::{Prediction, Prepared};
use crate::effect::Effect;
use crate::numeric::arx;

/// The channel whose validation rms residual `r` reduces most against `base`, and the relative
/// reduction.
pub(crate) fn best_reduction(r: &Reference, base: &Reference) -> (usize, f64) {
    best_of(&r.vrss, &base.vrss, &base.vn)
}

/// [`best_reduction`] on residual sums of squares `vrss` against `vrss0` (`vn` samples per
/// channel).
fn best_of(vrss: &[f64; 3], vrss0: &[f64; 3], vn: &[usize; 3]) -> (usize, f64) {
    let mut best = (0, f64::NEG_INFINITY);
    for c in 0..3 {
        let red = reduction_on(vrss, vrss0, vn, c);
        if red > best.1 {
            best = (c, red);
        }
    }
    best
}

/// The channel and validation reduction effect `id`, fitted as `r`, is credited with against
/// `base`: the channel it reduces most ([`best_reduction`]), except for an effect of the
/// measurement ([`Effect::measurement_channel`]), which is credited only on its sensor's
/// channel. A tip-sensor latency cannot change `force_n`; a gain there is the refit of the
/// parameters it was fitted with (a 60 Hz loop on 50 Hz data: a 4.4 ± 7.8 ms "latency" was
/// named beside the loop on a 9.5 % gain on `force_n`).
pub(crate) fn credited_reduction(
    id: Effect,
    vrss: &[f64; 3],
    vrss0: &[f64; 3],
    vn: &[usize; 3],
) -> (usize, f64) {
    match id.measurement_channel() {
        Some(ch) => (ch.index(), reduction_on(vrss, vrss0, vn, ch.index())),
        None => best_of(vrss, vrss0, vn),
    }
}

/// The relative reduction 1 − rms/rms₀ of the validation residual on channel `c` (residual
/// sums of squares `vrss` against `vrss0`, `vn` samples per channel); −∞ when `c` is not
/// recorded.
fn reduction_on(vrss: &[f64; 3], vrss0: &[f64; 3], vn: &[usize; 3], c: usize) -> f64 {
    if vn[c] > 0 {
        1.0 - (vrss[c] / vrss0[c].max(1e-300)).sqrt()
    } else {
        f64::NEG_INFINITY
    }
}

/// The gain a split refit reaches on the validation rms residual, ratio `rho` (refit /
/// reference), on the scale of a candidate's reduction: 1 − ρ for an improvement, 0 for a
/// worsening. The allowance is what re-tuning the parameters the model already has can earn
/// without new physics; a refit that predicts the validation worse earns nothing — it shows the
/// one recording leaves those parameters loosely held, which the full fit settles, not a gain a
/// candidate could be mistaken for. Counted as a change of either sign (|ln ρ|, until December
/// 2026), a model with an unrecorded base and a loop in it, both refits 25 % off the
/// validation, held a drag that gained 22 % with Δ(−2 ln L) −1 241 below that allowance
/// (independent-v2 case01); no null set moved (docs/diagnose.md, "Results").
pub(crate) fn split_gain(rho: f64) -> f64 {
    (1.0 - rho).max(0.0)
}

/// The model-form allowance of channel `c` for `k` parameters: what the physics-free correction
/// earns on `base`'s validation residual, or its split-refit gain if larger. Where no `k`
/// columns of the dictionary can be solved (its rank is below k: two of its signals the same),
/// a correction of k parameters is one of fewer, and the largest solvable size stands
/// ([`arx::best_correction_of_size`]). Until session 41 that counted 0, and a loop form of
/// five parameters escaped the allowance its four-parameter form was held to (real axis LinA:
/// order 3 passed at 43.5 % against 0.0 where order 2, the same fit, was held to 43.5 %;
/// docs/diagnose.md, "Session 38").
pub(crate) fn allowance(base: &Reference, c: usize, k: usize) -> f64 {
    base.generic[c]
        .as_ref()
        .and_then(|(fit_ne, val_ne)| arx::best_correction_of_size(fit_ne, val_ne, k))
        .map_or(0.0, |g| g.val_reduction())
        .max(base.split[c])
}

/// Ljung–Box Q of a residual (0 when absent).
pub(crate) fn q_of(v: &Option<Vec<f64>>) -> f64 {
    v.as_ref().map_or(0.0, |r| ljung_box(r, LJUNG_BOX_LAGS))
}

/// Columns of the physics-free correction of channel `c` ([`crate::numeric::arx`]): the
/// signals and their first two differences. Base — the predicted base and the command (for a
/// model without a loop, without their differences: [`BASE_WITHOUT_LOOP`]); tip —
/// the predicted tip, the predicted *deflection* (tip − drive, what a filter between the base
/// and the beam root changes) and the drive (measured base, else the command); force — the
/// predicted force and the drive, **without the drive's velocity** ([`FORCE_WITHOUT`]). The
/// command and drive as sampled, not as emphasised for the model: the emphasis adds a multiple
/// of their second difference, with which two columns gave the correction the command's
/// derivatives, a servo loop's physics (`base_friction+servo_lag` 87000: a 2-term correction
/// earned 99.3 % on `base_pos_m` against the loop's 99.1 %, and the loop went unnamed).
pub(crate) fn generic_columns(
    d: &Prepared,
    p: &Prediction,
    c: usize,
    has_loop: bool,
) -> Option<Vec<Vec<f64>>> {
    let drive = d.drive_as_sampled();
    Some(match c {
        0 => arx::dictionary(
            &[p.base_m.as_ref()?, d.cmd_as_sampled()],
            base_without(has_loop),
        ),
        1 => {
            let tip = p.tip_m.as_ref()?;
            let deflection: Vec<f64> = tip.iter().zip(drive).map(|(a, b)| a - b).collect();
            arx::dictionary(&[tip, &deflection, drive], &[])
        }
        _ => arx::dictionary(&[p.force_n.as_ref()?, drive], &FORCE_WITHOUT),
    })
}

/// The force channel's allowance leaves out the drive's first difference (signal 1, order 1):
/// a force on the carriage proportional to its velocity. By Newton the measured motor force is
/// the carriage's inertia plus the forces acting on it; a filter of the modelled force path
/// (force constant, latency, sensor bandwidth: the predicted force and its differences) or an
/// inertia error (the drive's second difference) is model-form error of what is modelled, but
/// a force ∝ carriage velocity is a force path of its own — viscous friction, the catalogue's
/// `base_friction` (and correlated with its Coulomb part, ∝ sign of the velocity). With it in
/// the dictionary the yardstick *is* the candidate's physics, and friction could never beat it.
pub const FORCE_WITHOUT: [(usize, usize); 1] = [(1, 1)];

/// The base channel's allowance of a model **without a position loop** leaves out the
/// differences of both its signals (the predicted base is then the command): a correction of
/// the following error by the command's velocity and acceleration is a lag of the command, a
/// position loop's own physics (a loop with velocity and acceleration feed-forward, PID or
/// cascade, follows a command as `y ≈ r − τ ṙ − …` below its bandwidth) — with it in the
/// dictionary the yardstick *is* the `servo_lag` candidate, as a force ∝ velocity is friction's
/// ([`FORCE_WITHOUT`]), and a loop could only pass through the rank gap
/// [`allowance`] closed (real axis LinA, docs/diagnose.md, "Session 38"). What stays is a gain
/// of the command, a scale error of the base sensor. With a loop in the model the dictionary is
/// whole: a correction by the command's derivatives is then the loop's *form* error.
pub const BASE_WITHOUT_LOOP: [(usize, usize); 4] = [(0, 1), (0, 2), (1, 1), (1, 2)];

/// The base dictionary's left-out columns ([`BASE_WITHOUT_LOOP`]).
pub(crate) fn base_without(has_loop: bool) -> &'static [(usize, usize)] {
    if has_loop {
        &[]
    } else {
        &BASE_WITHOUT_LOOP
    }
}

/// Number of columns [`generic_columns`] gives for channel `c`.
pub(crate) fn generic_column_count(c: usize, has_loop: bool) -> usize {
    match c {
        0 => arx::dictionary_size(2, base_without(has_loop).len()),
        1 => arx::dictionary_size(3, 0),
        _ => arx::dictionary_size(2, FORCE_WITHOUT.len()),
    }
}
