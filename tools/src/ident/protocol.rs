//! The paper's identification protocol (§5.2, Table 1) in simulation: sweep the reference rig
//! (linear β = 1 Hz/s, exponential β = 3, −5, 7 octaves/min over 0.1–8 Hz), record at 100 Hz
//! with camera-like noise, identify, and compare with the model's true modes.
//!
//! Truth: with base *acceleration* (or position) as the input, the FRF's poles are the
//! clamped-base modes of the beam; with the motor *force* as the input (the paper's choice)
//! they are the free-base modes of eq. (12) (the carriage moves with the beam), a little
//! higher. Both come from the rig's Galerkin model.

use super::frf::InputChannel;
use super::pipeline::{identify_recording, IdentOptions, IdentResult};
use super::sweep::{generate, SweepKind, SweepSpec};
use crate::model::sim::{BaseMotionSim, ForceSim};
use crate::model::BeamModel;
use crate::recording::Recording;
use anyhow::Result;
use rand::{rngs::StdRng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// The sweeps of Table 1: (label, kind, β).
pub fn paper_cases() -> Vec<(String, SweepKind, f64)> {
    vec![
        ("linear beta=1".into(), SweepKind::Linear, 1.0),
        ("exponential beta=3".into(), SweepKind::Exponential, 3.0),
        ("exponential beta=-5".into(), SweepKind::Exponential, -5.0),
        ("exponential beta=7".into(), SweepKind::Exponential, 7.0),
    ]
}

/// True modes of the model: (freq Hz, ζ) of the first two clamped-base and free-base modes.
#[derive(Clone, Debug, Serialize)]
pub struct Truth {
    /// Clamped-base modes (poles of base acceleration → tip deflection).
    pub clamped: Vec<(f64, f64)>,
    /// Free-base modes (poles of motor force → tip deflection).
    pub free_base: Vec<(f64, f64)>,
}

impl Truth {
    /// The truth for an FRF input.
    pub fn for_input(&self, input: InputChannel) -> &[(f64, f64)] {
        match input {
            InputChannel::Force => &self.free_base,
            _ => &self.clamped,
        }
    }
}

/// The model's true modes (dt only matters for the simulators' set-up).
pub fn truth(model: &BeamModel) -> Result<Truth> {
    let c = model.clamped_modes()?;
    let clamped = c
        .omega_rad_s
        .iter()
        .zip(&c.zeta)
        .map(|(w, z)| (w / (2.0 * std::f64::consts::PI), *z))
        .collect();
    let f = ForceSim::new(model, 1e-3, false)?;
    let free_base = f
        .omega_rad_s
        .iter()
        .zip(&f.zeta)
        .skip(1)
        .map(|(w, z)| (w / (2.0 * std::f64::consts::PI), *z))
        .collect();
    Ok(Truth { clamped, free_base })
}

/// Adds white Gaussian noise of `frac` × the RMS (about the mean) of each measured channel
/// (`base_pos_m`, `tip_pos_m`, `force_n`; the command stays clean), seeded.
pub fn add_noise(rec: &mut Recording, frac: f64, seed: u64) {
    let mut rng = StdRng::seed_from_u64(seed);
    for ch in [&mut rec.base_pos_m, &mut rec.tip_pos_m, &mut rec.force_n]
        .into_iter()
        .flatten()
    {
        let n = ch.len() as f64;
        let m = ch.iter().sum::<f64>() / n;
        let rms = (ch.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt();
        if let Ok(d) = Normal::new(0.0, frac * rms) {
            ch.iter_mut().for_each(|v| *v += d.sample(&mut rng));
        }
    }
}

/// Simulates `spec` (played at its own rate, the simulator's internal rate) on `model`,
/// decimates to `rate_out_hz` and adds `noise_frac` noise.
pub fn simulate_sweep(
    model: &BeamModel,
    spec: &SweepSpec,
    rate_out_hz: f64,
    noise_frac: f64,
    seed: u64,
) -> Result<Recording> {
    let s = generate(spec)?;
    let sim = BaseMotionSim::new(model, 1.0 / spec.sample_rate_hz)?;
    let mut rec = crate::recording::decimate(&sim.recording(&s.base_cmd_m, 0.0), rate_out_hz);
    if noise_frac > 0.0 {
        add_noise(&mut rec, noise_frac, seed);
    }
    Ok(rec)
}

/// One row of the table: identified modes vs truth.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Sweep label.
    pub sweep: String,
    /// Record length (s).
    pub record_s: f64,
    /// The identification.
    pub result: IdentResult,
}

/// Runs the protocol for `cases` and returns the rows.
pub fn run(
    model: &BeamModel,
    cases: &[(String, SweepKind, f64)],
    base: &SweepSpec,
    noise_frac: f64,
    opts: &IdentOptions,
    seed: u64,
) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for (i, (label, kind, rate)) in cases.iter().enumerate() {
        let spec = SweepSpec {
            kind: *kind,
            rate: *rate,
            ..base.clone()
        };
        let rec = simulate_sweep(model, &spec, 100.0, noise_frac, seed + i as u64)?;
        let (result, _) = identify_recording(&rec, opts)?;
        rows.push(Row {
            sweep: label.clone(),
            record_s: rec.time_s[rec.len() - 1],
            result,
        });
    }
    Ok(rows)
}

/// Table 1 layout: f1, f2, ζ1, ζ2 per sweep (mode i = the identified mode nearest to the true
/// mode i within 10 %), truth in the last row, errors in %.
pub fn table(rows: &[Row], truth: &[(f64, f64)]) -> String {
    let mut s = format!(
        "{:<22} {:>8} {:>16} {:>16} {:>16} {:>16}\n",
        "sweep", "record", "f1 (Hz)", "f2 (Hz)", "zeta1", "zeta2"
    );
    let pick = |r: &IdentResult, i: usize| {
        r.modes
            .iter()
            .filter(|m| (m.freq_hz / truth[i].0 - 1.0).abs() < 0.1)
            .min_by(|a, b| {
                (a.freq_hz - truth[i].0)
                    .abs()
                    .total_cmp(&(b.freq_hz - truth[i].0).abs())
            })
            .cloned()
    };
    for row in rows {
        let mut cells = Vec::new();
        for i in 0..2 {
            cells.push(match pick(&row.result, i) {
                Some(m) => format!(
                    "{:.4} ({:+.2}%)",
                    m.freq_hz,
                    100.0 * (m.freq_hz / truth[i].0 - 1.0)
                ),
                None => "-".into(),
            });
        }
        for i in 0..2 {
            cells.push(match pick(&row.result, i) {
                Some(m) => format!(
                    "{:.5} ({:+.0}%)",
                    m.zeta,
                    100.0 * (m.zeta / truth[i].1 - 1.0)
                ),
                None => "-".into(),
            });
        }
        s += &format!(
            "{:<22} {:>7.1}s {:>16} {:>16} {:>16} {:>16}\n",
            row.sweep, row.record_s, cells[0], cells[1], cells[2], cells[3]
        );
    }
    s += &format!(
        "{:<22} {:>8} {:>16.4} {:>16.4} {:>16.5} {:>16.5}\n",
        "truth (model)", "", truth[0].0, truth[1].0, truth[0].1, truth[1].1
    );
    s
}
