//! Reproductions of the paper's results on the simulated rig, as data (printing, files and
//! plots are `cli::paper`'s).
//!
//! - [`table1`]: Table 1, sweep identification (§5.2) by the paper's protocol.
//! - [`table2`]: Table 2 and Figs. 6–9, shaped moves (§5.3).
//! - [`bench`]: the simulator against `scipy.signal.lsim` on the same model and input.

pub mod bench;
pub mod table1;
pub mod table2;
