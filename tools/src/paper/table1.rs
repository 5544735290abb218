//! Table 1 of the paper (§5.2) in simulation: the four sweeps of [`protocol::paper_cases`]
//! played on the rig model, sampled at 100 Hz with noise on every channel, identified in the
//! 0.3–8 Hz band with two modes kept; compared with the model's own modes.

use crate::ident::frf::InputChannel;
use crate::ident::protocol::{self, Row};
use crate::ident::sweep::{SweepKind, SweepSpec};
use crate::ident::{IdentOptions, Method};
use crate::model::BeamModel;
use crate::progress::Progress;
use anyhow::Result;
use serde::Serialize;

/// Options of [`reproduce_table1`].
#[derive(Clone, Debug)]
pub struct Table1Options {
    /// Noise: fraction of each measured channel's RMS.
    pub noise_frac: f64,
    /// FRF input (the paper's: force).
    pub input: InputChannel,
    /// Estimators, the first primary (the paper's: LSCE).
    pub methods: Vec<Method>,
    /// Ring-down recorded after each sweep (s).
    pub tail_s: f64,
    /// Noise seed of the first sweep (the i-th uses `seed + i`).
    pub seed: u64,
}

impl Default for Table1Options {
    /// The paper's: force input, LSCE, 5 % noise, 20 s ring-down, seed 1.
    fn default() -> Self {
        Table1Options {
            noise_frac: 0.05,
            input: InputChannel::Force,
            methods: vec![Method::Lsce],
            tail_s: 20.0,
            seed: 1,
        }
    }
}

/// The reproduced table.
#[derive(Clone, Debug, Serialize)]
pub struct Table1 {
    /// One row per sweep.
    pub rows: Vec<Row>,
    /// The model's (f_hz, ζ) of the first modes for the input used.
    pub truth: Vec<(f64, f64)>,
}

impl Table1 {
    /// The table as text ([`protocol::table`]).
    pub fn text(&self) -> String {
        protocol::table(&self.rows, &self.truth)
    }
}

/// Runs the Table 1 protocol (module docs) on `model`; `progress` advances once per sweep.
///
/// Errors: an invalid option, a sweep the model cannot simulate, an identification failure.
pub fn reproduce_table1(
    model: &BeamModel,
    opts: &Table1Options,
    progress: &mut dyn Progress,
) -> Result<Table1> {
    let truth = protocol::truth(model)?.for_input(opts.input).to_vec();
    let ident = IdentOptions {
        methods: opts.methods.clone(),
        input: opts.input,
        band_hz: Some((0.3, 8.0)),
        n_modes: Some(2),
        ..Default::default()
    };
    let base = SweepSpec {
        tail_s: opts.tail_s,
        ..SweepSpec::paper(SweepKind::Exponential, 3.0)
    };
    let cases = protocol::paper_cases();
    progress.stage("table 1 sweeps");
    let mut rows = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        let seed = opts.seed + i as u64;
        let case = std::slice::from_ref(c);
        rows.extend(protocol::run(
            model,
            case,
            &base,
            opts.noise_frac,
            &ident,
            seed,
        )?);
        progress.advance(i as u64 + 1, cases.len() as u64);
    }
    Ok(Table1 { rows, truth })
}
