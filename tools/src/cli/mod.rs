//! The command-line layer: the ONLY place that parses arguments, prints, writes files or draws
//! progress (an `indicatif` bar on a terminal, one line per stage otherwise).
//!
//! One file per command group. Each maps its clap arguments to the library's typed options,
//! calls the library, and shows what came back. Nothing under `tools/src` outside this module and
//! `main.rs` imports it (checked by `tests/layout.rs`).

pub mod diagnose;
pub mod truth;
