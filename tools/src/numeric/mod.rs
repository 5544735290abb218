//! Numerical building blocks shared by identification and diagnosis.
//!
//! - [`lm`]: the one Levenberg–Marquardt adapter (residual closure, bounds, finite-difference
//!   Jacobian, a deterministic evaluation budget, covariance at the optimum) over the
//!   `levenberg-marquardt` crate;
//! - [`cores`]: the machine's spare cores, lent to work that can run beside its thread;
//! - [`predictive`]: equal predictive accuracy of two models on never-fitted data
//!   (Diebold–Mariano with a HAC long-run variance), the diagnosis's decision statistic;
//! - [`stats`]: likelihood, information criterion and whiteness statistics;
//! - [`independence`]: is a residual independent of the drive (prewhitened residual–input
//!   cross-correlation, Ljung 1999 §16.6)?
//! - [`arx`]: a physics-free linear correction of a residual (least squares on lagged inputs),
//!   the yardstick of the diagnosis' model-form allowance.

pub mod arx;
pub mod cores;
pub mod independence;
pub mod lm;
pub mod peaks;
pub mod predictive;
pub mod stats;
