//! beamshaper core: `no_std`, no heap, no embassy.
//!
//! The same code runs in the firmware's timer interrupt (Cortex-M4F), in the host tests,
//! in the host tools and in the Cortex-M4 QEMU golden-vector image.
//!
//! - [`shaper`]: input-shaper design (paper §4, eqs. 30–32, and the wider literature),
//!   multi-mode convolution and the percentage residual vibration.
#![no_std]
#![deny(unsafe_code)]

pub mod config;
pub mod console;
pub mod engine;
pub mod golden;
pub mod output;
pub mod protocol;
pub mod reference;
pub mod runtime;
pub mod sensor;
pub mod shaper;
pub mod storage;
pub mod watch;
