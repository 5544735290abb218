//! The backward step inside a round ([`backward_check`]): after a candidate is added, every effect
//! chosen before it must still earn its place beside it; the candidates are judged again against
//! the better reference that leaves ([`rejudge`]).

use super::budget::Budget;
use super::context::Ctx;
use super::state::{set_of, Reference};
use crate::diagnose::effects::Candidate;
use crate::diagnose::fit::FitResult;
use crate::diagnose::CandidateOutcome;

/// Backward check: the effects already chosen (in the first round: the calibration alone),
/// refitted from the joint optimum without the newcomer. If they alone do better there than the
/// reference, part of the newcomer's gain was only a better optimum of what was already chosen:
/// every passing candidate is judged again against that better reference. Returns the index of
/// the pick in `outs`.
pub(crate) fn backward_check(
    ctx: &Ctx,
    cands: &[Candidate],
    chosen: &[usize],
    outs: &mut [CandidateOutcome],
    reference: &mut Reference,
    budget: &mut Budget,
    pool_len: usize,
) -> Option<usize> {
    let mut pick = outs.iter().position(|o| o.passed);
    let mut checked: Vec<usize> = Vec::new();
    while checked.len() < 3 {
        let Some(s) = pick else { break };
        if checked.contains(&outs[s].cand_index) {
            break;
        }
        checked.push(outs[s].cand_index);
        let prev = set_of(cands, chosen);
        let warm = outs[s].fit.x.rows(0, reference.fit.x.len()).into_owned();
        let f = ctx.fit(&prev, Some(&warm), budget.share(pool_len + 1));
        budget.spend(f.evaluations);
        ctx.trace(format!(
            "backward check of {}: chosen effects alone from the joint optimum cost {:.6e} (reference {:.6e}, with it {:.6e})\n  reference {:?}\n  joint     {:?}\n  refit     {:?}",
            outs[s].id, f.cost, reference.fit.cost, outs[s].fit.cost,
            reference.fit.values, outs[s].fit.values, f.values
        ));
        if !(f.cost < reference.fit.cost) {
            break;
        }
        let Some(mut better) = ctx.reference(&prev, f) else {
            break;
        };
        better.split = reference.split;
        *reference = better;
        let passing = outs.iter().filter(|o| o.passed).count();
        rejudge(outs, |o| {
            let set: Vec<&Candidate> = prev
                .iter()
                .copied()
                .chain(std::iter::once(&cands[o.cand_index]))
                .collect();
            let f = if o.passed {
                let f = on_better_reference(ctx, &set, o, reference, budget.share(passing));
                budget.spend(f.evaluations);
                f
            } else {
                o.fit.clone()
            };
            let r = ctx.reference(&set, f)?;
            Some(ctx.assess(&set, o.cand_index, r, reference))
        });
        outs.sort_by(|a, b| a.delta_val.total_cmp(&b.delta_val));
        crate::diagnose::keep_lowest_bic_form(outs);
        pick = outs.iter().position(|o| o.passed);
    }
    pick
}

/// The joint fit of a passing candidate `o` (model `set`) continued from the better reference's
/// optimum with `o`'s own parameters, at most `max_evaluations` evaluations; `o`'s fit if that
/// is no better. The joint fit had spent its share before the reference's refit found the
/// better optimum of what was already chosen, so judged as it was it would be charged with the
/// difference (second simulator seed 4, case00: friction after a tip mass, its force residual
/// down 3× and still ΔBIC +2500, because the tip mass's refit alone had reached half the tip
/// residual the joint fit had).
fn on_better_reference(
    ctx: &Ctx,
    set: &[&Candidate],
    o: &CandidateOutcome,
    reference: &Reference,
    max_evaluations: usize,
) -> FitResult {
    let x = continued_start(&o.fit.x, &reference.fit.x);
    let f = ctx.fit(set, Some(&x), max_evaluations);
    if f.cost < o.fit.cost {
        f
    } else {
        o.fit.clone()
    }
}

/// The start of [`on_better_reference`]: the joint optimum `joint` (representation: the
/// calibration and the chosen effects, then the newcomer's parameters) with the leading
/// parameters replaced by the better reference's optimum `reference`.
pub(crate) fn continued_start(
    joint: &nalgebra::DVector<f64>,
    reference: &nalgebra::DVector<f64>,
) -> nalgebra::DVector<f64> {
    let mut x = joint.clone();
    let n0 = reference.len().min(x.len());
    x.rows_mut(0, n0).copy_from(&reference.rows(0, n0));
    x
}

/// Judges every outcome of `outs` again (`judge`: its own fit against the new, better
/// reference; `None` when it cannot be simulated), so that every number of the round's table
/// is relative to the reference it is judged against (one that cannot be simulated keeps its
/// first judgement, marked). A placement found before is kept. A
/// candidate that failed keeps failing, with its first reason marked as such: every guard is
/// harder against a better reference, and a candidate is named only after the full test
/// (placement included) of the passing ones.
pub(crate) fn rejudge(
    outs: &mut [CandidateOutcome],
    mut judge: impl FnMut(&CandidateOutcome) -> Option<CandidateOutcome>,
) {
    for o in outs.iter_mut() {
        let Some(mut n) = judge(o) else {
            o.reason = format!(
                "{} (judged against the reference before the backward check: not re-simulated)",
                o.reason
            );
            continue;
        };
        n.unplaced = o.unplaced.take();
        n.look_alike = o.look_alike.take();
        n.apply_placement();
        if !o.passed && n.passed {
            n.passed = false;
            n.reason = format!(
                "{} (judged against the reference before the backward check)",
                o.reason
            );
        }
        *o = n;
    }
}
