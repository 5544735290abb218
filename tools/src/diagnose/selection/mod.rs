//! The selection: which candidate effects the recordings name, in one folder by job.
//!
//! - [`decision`]: the decision rule — one predictive test at a family-wise level, the
//!   model-form comparison and physical bounds (module docs: the specification);
//! - [`guard`]: the earlier conjunction of margins (kept for the ablation and for
//!   `diagnose-lengths`) and the evidence every candidate carries;
//! - `budget`: the work budget of one diagnosis, counted in model evaluations;
//! - `state`: a fitted model as the rounds compare with it ([`Reference`]) and the selection so
//!   far ([`Selection`]);
//! - `context`: the context of one selection ([`Ctx`]): fitting a set, evaluating a candidate;
//! - `assess`: the guard applied to one candidate, with the calibration-matter rules;
//! - `allowance`, `evidence`, `plausibility`: the measures the guard's conditions read (the
//!   model-form allowance; the structure explained, the effect's band, the driven share, the
//!   bursts; physical possibility and significance);
//! - `placement`, `compliance`: where a resonance and where a compliance sit (conditions 8, 9);
//! - `forward`: forward selection, round after round ([`select_forward`]); `rounds`: one round;
//!   `backward_step`: the backward check inside a round; `pairs`: effects named as a pair;
//! - [`lookalike`]: look-alikes settled on the final model; [`backward`]: backward elimination
//!   after forward selection.

mod allowance;
mod assess;
pub mod backward;
mod backward_step;
mod budget;
mod compliance;
mod context;
pub mod decision;
mod evidence;
mod forward;
pub mod guard;
pub mod lookalike;
mod pairs;
mod placement;
mod plausibility;
mod rounds;
mod state;
#[cfg(test)]
pub(crate) mod tests;

pub(crate) use budget::Budget;
pub use budget::{EVALUATION_BUDGET_RANGE, WORK_BUDGET_SAMPLE_EVALUATIONS};
pub(crate) use context::Ctx;
pub(crate) use forward::{resume_after_drop, select_forward};
pub use forward::{MAX_EFFECTS, MAX_RESUMPTIONS};
pub(crate) use pairs::structural_pair_as_crack;
pub(crate) use plausibility::{unidentified_in_final, unplaced_in_final, NullEvidence};
pub(crate) use state::{Reference, Selection};
