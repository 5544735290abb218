//! Host tools for the beamshaper project (std).
//!
//! One module per job; [`cli`] is the only module that parses arguments, prints, writes reports
//! or draws progress, and `main.rs` only calls it. See `docs/architecture.md`.
//! - [`recording`]: the recording CSV shared by every tool (and NumPy `.npy` import).
//! - [`model`]: the beam-on-moving-base model of the paper's §2 and its simulator.
//! - [`ident`]: modal identification (paper §3, §5.2).
//! - [`diagnose`]: model-discrepancy diagnosis.
//! - [`numeric`]: the Levenberg–Marquardt adapter and residual statistics.
//! - [`paper`]: the paper's Tables 1 and 2 and the simulator benchmark, reproduced as data.
//! - [`shaping`]: choosing the shortest robust shaper over the core's designs.
//! - [`board`]: the typed board session, the job's board steps, the virtual board and rig.
//! - [`tune`]: the main job end to end, as a pipeline of typed steps.

pub mod board;
pub mod cli;
pub mod diagnose;
pub mod effect;
pub mod ident;
pub mod measures;
pub mod model;
pub mod numeric;
pub mod paper;
pub mod plot;
pub mod progress;
pub mod recording;
pub mod shaping;
pub mod truth;
pub mod tune;
