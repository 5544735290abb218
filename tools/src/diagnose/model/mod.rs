//! The augmented model the diagnosis fits: the nominal Galerkin model (`crate::model`, paper §2)
//! with every candidate extension switchable, predicting the recorded channels of one recording.
//! One file per block of the signal chain (each block off unless its parameters are set):
//! 1. [`servo`]: the base follows its command through a finite-bandwidth position loop of order
//!    1–4 ([`ServoLaw`]), coupled to the beam's reaction and loaded by the carriage forces;
//!    predicted `base_pos_m`;
//! 2. [`predict`]: the beam is driven by the *measured* base position when recorded (so
//!    carriage effects do not leak into the tip channel), else by the predicted one;
//! 3. [`mount`]: backlash (the play operator) and a mount between the carriage and the beam root;
//! 4. [`beam`] (clamped-base modes of [`crate::model::BeamModel`] with tip mass, root spring,
//!    gravity axial load and the calibration scale) and [`beam_response`] (the modes driven by
//!    the root, quadratic drag, a cubic clamp, the motor force of eq. 5);
//! 5. [`carriage`]: Coulomb and viscous friction and cogging on the carriage
//!    ([`CarriageLoad`]), in the force channel and inside the loop;
//! 6. [`sensor`]: the tip sensor's latency, scale and mount resonance.
//!
//! [`params`] holds every parameter of every block ([`Params`]); [`prepared`] one recording
//! prepared for simulation ([`Prepared`]); [`predict`] composes the blocks ([`predict()`]);
//! [`discrete`] the exact discretisation the blocks share.

pub mod beam;
pub mod beam_response;
pub mod carriage;
pub mod discrete;
pub mod mount;
pub mod params;
pub mod predict;
pub mod prepared;
pub mod sensor;
pub mod servo;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_blocks;

pub use beam::*;
pub use beam_response::*;
pub use carriage::*;
pub use discrete::*;
pub use mount::*;
pub use params::*;
pub use predict::*;
pub use prepared::*;
pub use sensor::*;
pub use servo::*;
