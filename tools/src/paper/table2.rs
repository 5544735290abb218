//! Table 2 and Figs. 6–9 of the paper (§5.3) in simulation: a 50 mm move (trapezoidal
//! velocity 200 mm/s, 2000 mm/s², 0.35 s) of the rig model (4 basis functions), unshaped and
//! shaped by ZV, ZVD, ZVDD designed for f1 = 1.1 Hz (and convolved with the same kind at
//! f2 = 6.9 Hz for the two-mode rows), ζ = 0.0074, at 1 kHz by the firmware core's fixed-point
//! engine. Settling band ±2 % of the move, measured from the end of the unshaped move.

use crate::measures::{measure, percentage_vibration, MoveMeasures};
use crate::model::sim::BaseMotionSim;
use crate::model::SIM_RATE_HZ;
use crate::model::{shape_with_engine, trapezoid_reference, BeamModel, ModelOptions, Rig};
use anyhow::{anyhow, Context, Result};
use beamshaper::engine::NumericPath;
use beamshaper::shaper::{design, residual_vibration, Shaper, ShaperKind};

/// The paper's Table 2 (measured on the rig): shaper, two-mode, settling (s), overshoot (%),
/// percentage vibration (%).
pub const PAPER_TABLE2: [(&str, bool, f64, f64, f64); 6] = [
    ("ZV", false, 0.73, 22.04, 5.83),
    ("ZVD", false, 1.12, 14.96, 3.62),
    ("ZVDD", false, 1.57, 8.48, 2.84),
    ("ZV", true, 0.75, 13.18, 1.96),
    ("ZVD", true, 1.27, 6.86, 1.26),
    ("ZVDD", true, 1.75, 2.26, 0.36),
];

/// The design values of the paper's shapers: f1, f2 (Hz), ζ.
pub const DESIGN_F1_HZ: f64 = 1.1;
/// See [`DESIGN_F1_HZ`].
pub const DESIGN_F2_HZ: f64 = 6.9;
/// See [`DESIGN_F1_HZ`].
pub const DESIGN_ZETA: f64 = 0.0074;

/// Basis functions of the model.
pub const N_BASIS: usize = 4;

/// Figures 6–9: file name and the indices into [`Table2::responses`] they show.
pub const FIGURES: [(&str, &[usize]); 4] = [
    ("fig6_single_zv.svg", &[0, 1]),
    ("fig7_single_zvd_zvdd.svg", &[0, 2, 3]),
    ("fig8_two_mode_zv.svg", &[0, 4]),
    ("fig9_two_mode_zvd_zvdd.svg", &[0, 5, 6]),
];

/// One shaped row.
#[derive(Clone, Debug)]
pub struct Table2Row {
    /// `ZV`, `two-mode ZVD`, …
    pub label: String,
    /// Simulated settling, overshoot, residual.
    pub sim: MoveMeasures,
    /// Percentage vibration against the unshaped move (%).
    pub pv_pct: f64,
    /// The shaper's predicted residual vibration at the model's f1, ζ1 (%).
    pub predicted_v_pct: f64,
    /// The paper's settling (s), overshoot (%), percentage vibration (%).
    pub paper: (f64, f64, f64),
}

/// The reproduced table and the tip responses of the figures.
#[derive(Clone, Debug)]
pub struct Table2 {
    /// The unshaped move.
    pub unshaped: MoveMeasures,
    /// The shaped rows, in the paper's order.
    pub rows: Vec<Table2Row>,
    /// Time of the responses (s, 1 kHz).
    pub time_s: Vec<f64>,
    /// Label and absolute tip position (m): unshaped first, then one per row.
    pub responses: Vec<(String, Vec<f64>)>,
    /// The model's first two clamped-base natural frequencies (Hz).
    pub model_freq_hz: (f64, f64),
    /// The model's damping ratios.
    pub model_damping: (f64, f64),
}

fn shaper_for(kind: &str, two_mode: bool) -> Result<Shaper> {
    let k =
        ShaperKind::from_name(kind, 0.05).with_context(|| format!("unknown shaper `{kind}`"))?;
    let d = |f| design(k, f, DESIGN_ZETA).map_err(|e| anyhow!("{}", e.message()));
    let s = d(DESIGN_F1_HZ)?;
    if !two_mode {
        return Ok(s);
    }
    s.convolve(&d(DESIGN_F2_HZ)?)
        .map_err(|e| anyhow!("{}", e.message()))
}

/// The move of the module docs at 1 kHz: its samples and the end of the unshaped move (s).
fn reference_move() -> Result<(Vec<f64>, f64)> {
    let (target, speed, accel, hold) = (0.05, 0.2, 2.0, 10.0);
    let (reference, end) = trapezoid_reference(0.0, target, speed, accel, SIM_RATE_HZ, hold)?;
    Ok((reference, end as f64 / SIM_RATE_HZ))
}

/// Reproduces Table 2 on `rig` (module docs).
///
/// Errors: the model or a shaper cannot be built, the engine refuses a shaper.
pub fn reproduce_table2(rig: &Rig) -> Result<Table2> {
    let opts = ModelOptions {
        n_modes: N_BASIS,
        ..Default::default()
    };
    let model = BeamModel::new(rig, &opts)?;
    let sim = BaseMotionSim::new(&model, 1.0 / SIM_RATE_HZ)?;
    let (reference, ref_end_s) = reference_move()?;
    let target = *reference.last().context("empty move")?;
    let time_s: Vec<f64> = (0..reference.len())
        .map(|k| k as f64 / SIM_RATE_HZ)
        .collect();
    let band = 0.02 * target;
    let run = |y: &[f64]| -> Vec<f64> { sim.run(y).0.iter().zip(y).map(|(w, y)| w + y).collect() };
    let cmd_end = |y: &[f64]| -> f64 {
        y.iter()
            .rposition(|v| (v - target).abs() > 1e-9)
            .map_or(0.0, |k| (k + 1) as f64 / SIM_RATE_HZ)
    };
    let measure_of =
        |y: &[f64], tip: &[f64]| measure(&time_s, tip, 0.0, target, cmd_end(y), ref_end_s, band);
    let tip_u = run(&reference);
    let unshaped = measure_of(&reference, &tip_u);
    let cms = model.clamped_modes()?;
    let f1 = cms.omega_rad_s[0] / (2.0 * std::f64::consts::PI);
    let mut responses = vec![("unshaped".to_string(), tip_u)];
    let mut rows = Vec::new();
    for (name, two, p_settle, p_over, p_pv) in PAPER_TABLE2 {
        let s = shaper_for(name, two)?;
        let y = shape_with_engine(&s, SIM_RATE_HZ, &reference, NumericPath::Fixed)?;
        let tip = run(&y);
        let m = measure_of(&y, &tip);
        let label = format!("{}{}", if two { "two-mode " } else { "" }, name);
        rows.push(Table2Row {
            label: label.clone(),
            pv_pct: percentage_vibration(&m, &unshaped),
            sim: m,
            predicted_v_pct: 100.0 * residual_vibration(&s, f1, cms.zeta[0]),
            paper: (p_settle, p_over, p_pv),
        });
        responses.push((label, tip));
    }
    Ok(Table2 {
        unshaped,
        rows,
        time_s,
        responses,
        model_freq_hz: (f1, cms.omega_rad_s[1] / (2.0 * std::f64::consts::PI)),
        model_damping: model.damping_ratios,
    })
}

impl Table2 {
    /// The table as markdown, headed by a sentence naming `rig_label` and the set-up.
    pub fn markdown(&self, rig_label: &str) -> String {
        let settle = |m: &MoveMeasures| m.settling_s.map_or("> 10".into(), |s| format!("{s:.2}"));
        let mut md = format!(
            "Simulated §5.3 experiment: rig `{rig_label}`, {N_BASIS} basis functions (model f1 = {:.4} Hz, f2 = {:.4} Hz, zeta = {:?}); \
             base 0 -> 50 mm, trapezoidal velocity 200 mm/s, 2000 mm/s^2 (0.35 s), shaped at 1 kHz by the firmware core's \
             fixed-point engine; shapers designed from f1 = 1.1 Hz, f2 = 6.9 Hz, zeta = 0.0074; settling band +-1 mm (2 %) \
             measured from the end of the unshaped move.\n\n",
            self.model_freq_hz.0, self.model_freq_hz.1, self.model_damping);
        md.push_str("| shaper | settling (s) sim | paper | overshoot (%) sim | paper | percentage vibration (%) sim | paper | predicted V(f1) (%) |\n|---|---|---|---|---|---|---|---|\n");
        md.push_str(&format!(
            "| unshaped | {} | – | {:.2} | – | 100 | 100 | 100 |\n",
            settle(&self.unshaped),
            self.unshaped.overshoot_pct
        ));
        for r in &self.rows {
            let (p_settle, p_over, p_pv) = r.paper;
            md.push_str(&format!(
                "| {} | {} | {p_settle} | {:.2} | {p_over} | {:.2} | {p_pv} | {:.2} |\n",
                r.label,
                settle(&r.sim),
                r.sim.overshoot_pct,
                r.pv_pct,
                r.predicted_v_pct
            ));
        }
        md
    }
}
