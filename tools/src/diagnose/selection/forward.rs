//! Forward selection ([`select_forward`]): each round fits every remaining candidate jointly
//! with the calibration and the effects already chosen, applies every guard
//! ([`super::guard::guard`] and the calibration-matter rules) against the current model, adds
//! the best that passes and stops when none does (at most [`MAX_EFFECTS`]). When none passes
//! but the best fails only for removing part of the structured residual, it is tried as the
//! first of a pair ([`pair_step`]). When the final model later drops an effect the recordings do
//! not identify, the rounds are played once more on what stays ([`resume_after_drop`]).
//!
//! Every fit draws on one [`Budget`] of model evaluations, never on the clock, so the same
//! recordings give the same answer on any machine.

use super::budget::Budget;
use super::context::Ctx;
use super::pairs::pair_step;
use super::rounds::{accept, play_round};
use super::state::{Reference, Selection};
use crate::diagnose::effects::Candidate;
use crate::progress::Progress;

/// Most effects forward selection adds.
pub const MAX_EFFECTS: usize = 4;

/// Forward selection from `nominal` (module docs). `step` is the first progress step.
pub(crate) fn select_forward(
    ctx: &Ctx,
    cands: &[Candidate],
    nominal: Reference,
    budget: &mut Budget,
    progress: &mut dyn Progress,
    step: usize,
) -> Selection {
    let mut sel = Selection {
        chosen: Vec::new(),
        outcomes: Vec::new(),
        reference: nominal,
        rounds: Vec::new(),
        step,
        dropped: Vec::new(),
    };
    play_rounds(ctx, cands, &mut sel, budget, progress, 0);
    sel
}

/// Most times forward selection is resumed after a drop ([`resume_after_drop`]), each with a
/// third more budget: once, so that a diagnosis does at most 4/3 of its budget's work and the
/// run time stays within its bound (the budget is sized for a minute on 2 cores).
pub const MAX_RESUMPTIONS: usize = 1;

/// Forward selection resumed on `sel` after the final model dropped an effect it does not
/// identify ([`Selection::dropped`]): every candidate not dropped is fitted again on top of
/// what stays, as in a round of its own, and rounds go on while one passes. A candidate fitted
/// on top of the dropped effect was judged against a model the recordings do not support: a
/// look-alike chosen first (a cubic clamp for an upright beam with a tip mass, second
/// simulator seed 10, case13) leaves the true partner failing beside it. The budget is
/// extended by a third first ([`Budget::extend_for_resumption`]); at most [`MAX_RESUMPTIONS`]
/// times. Returns whether an effect was added.
pub(crate) fn resume_after_drop(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut Selection,
    budget: &mut Budget,
    progress: &mut dyn Progress,
) -> bool {
    if sel.dropped.len() > MAX_RESUMPTIONS {
        return false;
    }
    let before = sel.chosen.len();
    budget.extend_for_resumption();
    play_rounds(ctx, cands, sel, budget, progress, sel.rounds.len());
    ctx.trace(format!(
        "selection resumed after a drop: {} effect(s) added",
        sel.chosen.len().saturating_sub(before)
    ));
    sel.chosen.len() > before
}

/// The rounds of forward selection from round `first` on `sel`, until none passes or
/// [`MAX_EFFECTS`] are chosen (counting those `sel` holds at the start).
fn play_rounds(
    ctx: &Ctx,
    cands: &[Candidate],
    sel: &mut Selection,
    budget: &mut Budget,
    progress: &mut dyn Progress,
    first: usize,
) {
    let (mut round, last) = (first, first + MAX_EFFECTS.saturating_sub(sel.chosen.len()));
    while round < last {
        let Some((mut outs, pick)) = play_round(ctx, cands, sel, budget, progress, round) else {
            break;
        };
        match pick {
            Some(s) => {
                if !accept(ctx, cands, sel, &mut outs, s) {
                    break;
                }
                sel.rounds.push(outs);
                round += 1;
            }
            None if round + 1 < last
                && pair_step(ctx, cands, sel, &mut outs, budget, progress, round) =>
            {
                round += 2;
            }
            None => {
                sel.rounds.push(outs);
                break;
            }
        }
    }
}
