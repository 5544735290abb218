//! Report of a diagnosis: the JSON of the issue, plain words, and SVG plots.

use super::fit::{residuals, CHANNEL_NAMES};
use super::{CandidateOutcome, Diagnosis};
use crate::ident::spectrum::amplitude_spectrum;
use crate::plot::{lines, Series};
use anyhow::Result;
use serde_json::{json, Map, Value};
use std::path::Path;

/// Effect parameters of an outcome as (JSON name with unit, value, σ); cogging sine/cosine
/// become amplitude and pitch, gravity its orientation.
pub fn effect_parameters(
    o: &CandidateOutcome,
    n_calib: usize,
) -> (Vec<(String, f64, f64)>, Option<String>) {
    let mut out = Vec::new();
    let names = &o.fit.names[n_calib..];
    let vals = &o.fit.values[n_calib..];
    let std = &o.fit.std[n_calib..];
    if o.id == "cogging_ripple" {
        let (a, b) = (vals[0], vals[1]);
        let amp = a.hypot(b);
        let s = ((a * std[0]).powi(2) + (b * std[1]).powi(2)).sqrt() / amp.max(1e-300);
        out.push(("cogging_amplitude_n".to_string(), amp, s));
        out.push(("cogging_pitch_m".to_string(), vals[2], std[2]));
    } else {
        for i in 0..names.len() {
            let v = if matches!(names[i], "tip_mass_kg" | "drag_coefficient_kg_per_m2") {
                vals[i].abs()
            } else {
                vals[i]
            };
            out.push((names[i].to_string(), v, std[i]));
        }
    }
    let orientation = if o.id == "gravity_axial_load" {
        Some(if o.words.contains("hangs") {
            "hanging".to_string()
        } else {
            "upright".to_string()
        })
    } else {
        None
    };
    (out, orientation)
}

/// The primary channel and its validation NRMSE before/after.
pub fn validation_summary(d: &Diagnosis) -> (usize, f64, f64) {
    match d.selected {
        Some(s) => {
            let o = &d.candidates[s];
            (
                o.best_channel,
                d.val_nrmse_nominal[o.best_channel],
                o.val_nrmse[o.best_channel],
            )
        }
        None => {
            let c = [1, 2, 0]
                .into_iter()
                .find(|&c| d.val_nrmse_nominal[c].is_finite())
                .unwrap_or(0);
            (c, d.val_nrmse_nominal[c], d.val_nrmse_nominal[c])
        }
    }
}

/// The JSON report (`effect`, `parameters`, `validation`, `candidates` as the issue specifies,
/// plus uncertainties, calibration and location).
pub fn to_json(d: &Diagnosis) -> Value {
    let nc = d.calibration.names.len();
    let mut params = Map::new();
    let mut unc = Map::new();
    if let Some(s) = d.selected {
        let (p, orient) = effect_parameters(&d.candidates[s], nc);
        for (n, v, s) in p {
            params.insert(n.clone(), json!(v));
            unc.insert(n, json!(s));
        }
        if let Some(o) = orient {
            params.insert("orientation".into(), json!(o));
        }
    }
    let (c, before, after) = validation_summary(d);
    let mut per = Map::new();
    let after_all = d
        .selected
        .map(|s| d.candidates[s].val_nrmse)
        .unwrap_or(d.val_nrmse_nominal);
    for k in 0..3 {
        if d.val_nrmse_nominal[k].is_finite() {
            per.insert(
                CHANNEL_NAMES[k].into(),
                json!({"nrmse_before": d.val_nrmse_nominal[k], "nrmse_after": after_all[k]}),
            );
        }
    }
    let cands: Vec<Value> = d
        .candidates
        .iter()
        .map(|o| {
            let (p, orient) = effect_parameters(o, nc);
            let mut pm = Map::new();
            for (n, v, _) in p {
                pm.insert(n, json!(v));
            }
            if let Some(o) = orient {
                pm.insert("orientation".into(), json!(o));
            }
            json!({
                "effect": o.id, "score": -o.delta_val, "delta_bic": o.delta_bic,
                "validation_delta_neg2loglik": o.delta_val, "validation_nrmse_reduction": o.reduction,
                "channel": CHANNEL_NAMES[o.best_channel], "ljung_box_before_after": [o.whiteness.0, o.whiteness.1],
                "significance_sigma": if o.significance.is_finite() { json!(o.significance) } else { Value::Null },
                "passed": o.passed, "reason": o.reason, "parameters": pm,
            })
        })
        .collect();
    let mut cal = Map::new();
    for i in 0..nc {
        cal.insert(
            d.calibration.names[i].into(),
            json!({"value": d.calibration.values[i], "std": d.calibration.std[i]}),
        );
    }
    json!({
        "effect": d.effect,
        "words": d.selected.map(|s| d.candidates[s].words.clone()).unwrap_or_else(|| "no candidate earns its parameters".into()),
        "parameters": params,
        "uncertainty": unc,
        "validation": {"nrmse_before": before, "nrmse_after": after, "channel": CHANNEL_NAMES[c], "per_channel": per},
        "candidates": cands,
        "calibration": cal,
        "location": serde_json::to_value(&d.location).unwrap_or(Value::Null),
        "model_evaluations": d.evaluations,
        "model": {
            "band_edge_hz": d.band_edge_hz,
            "basis_functions": d.basis.as_ref().map(|b| b.n_basis),
            "in_band_modes_hz": d.basis.as_ref().map(|b| b.freqs_hz.clone()),
            "convergence_rel": d.basis.as_ref().map(|b| b.convergence_rel),
        },
    })
}

/// Plain-words report.
pub fn words(d: &Diagnosis) -> String {
    let nc = d.calibration.names.len();
    let mut s = String::new();
    s += "Calibration of the nominal model (fit recordings):\n";
    for i in 0..nc {
        s += &format!(
            "  {} = {:.5} ± {:.2e}\n",
            d.calibration.names[i], d.calibration.values[i], d.calibration.std[i]
        );
    }
    s += "Where the residual of the calibrated nominal model lies:\n";
    for w in &d.location.words {
        s += &format!("  {w}\n");
    }
    if !d.location.model_freqs_hz.is_empty() {
        let f: Vec<String> = d
            .location
            .model_freqs_hz
            .iter()
            .map(|f| format!("{f:.2}"))
            .collect();
        s += &format!("  model modes (Hz): {}\n", f.join(", "));
    }
    let (c, before, after) = validation_summary(d);
    match d.selected {
        Some(i) => {
            let o = &d.candidates[i];
            s += &format!("\nDIAGNOSIS: {} — {}\n", o.id, o.words);
            let (p, orient) = effect_parameters(o, nc);
            if let Some(or) = orient {
                s += &format!("  orientation = {or}\n");
            }
            for (n, v, sd) in p {
                s += &format!("  {n} = {v:.5e} ± {sd:.2e}\n");
            }
            s += &format!(
                "  shows in {}: validation NRMSE {:.4} → {:.4} ({:.1} % lower); ΔBIC {:+.1}; validation Δ(−2lnL) {:+.1}; Ljung–Box {:.0} → {:.0}\n",
                CHANNEL_NAMES[c],
                before,
                after,
                100.0 * (1.0 - after / before),
                o.delta_bic,
                o.delta_val,
                o.whiteness.0,
                o.whiteness.1
            );
        }
        None => {
            s += &format!(
            "\nDIAGNOSIS: none — no candidate earns its parameters (validation NRMSE {} {:.4})\n",
            CHANNEL_NAMES[c], before
        )
        }
    }
    s += "\nCandidates (best validation gain first):\n";
    for o in &d.candidates {
        s += &format!(
            "  {:<20} ΔBIC {:>+10.1}  val Δ(−2lnL) {:>+10.1}  {:>6.1} % on {:<10} {}: {}\n",
            o.id,
            o.delta_bic,
            o.delta_val,
            100.0 * o.reduction,
            CHANNEL_NAMES[o.best_channel],
            if o.passed { "PASS" } else { "fail" },
            o.reason
        );
    }
    s
}

/// Writes `report.md`, `diagnosis.json` and the SVG plots into `dir`.
pub fn write_report(d: &Diagnosis, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(
        dir.join("report.md"),
        format!("# Diagnosis\n\n```\n{}```\n", words(d)),
    )?;
    std::fs::write(
        dir.join("diagnosis.json"),
        serde_json::to_string_pretty(&to_json(d))?,
    )?;
    let v = &d.validate;
    let t = &v.time_s;
    let aug = d
        .selected
        .map(|s| &d.candidates[s].val_pred)
        .unwrap_or(&d.val_pred_nominal);
    let r0 = residuals(v, &d.val_pred_nominal);
    let r1 = residuals(v, aug);
    for c in 0..3 {
        let meas = match c {
            0 => &v.base_m,
            1 => &v.tip_m,
            _ => &v.force_n,
        };
        let (Some(meas), Some(r0), Some(r1)) = (meas, &r0[c], &r1[c]) else {
            continue;
        };
        let nominal: Vec<f64> = meas.iter().zip(r0).map(|(m, r)| m - r).collect();
        let augmented: Vec<f64> = meas.iter().zip(r1).map(|(m, r)| m - r).collect();
        let name = CHANNEL_NAMES[c];
        lines(
            &dir.join(format!("{name}_recording.svg")),
            &format!(
                "validation {name}: recording, nominal, augmented ({})",
                d.effect
            ),
            "time (s)",
            name,
            &[
                Series {
                    label: "recording".into(),
                    x: t,
                    y: meas,
                },
                Series {
                    label: "nominal (calibrated)".into(),
                    x: t,
                    y: &nominal,
                },
                Series {
                    label: format!("augmented ({})", d.effect),
                    x: t,
                    y: &augmented,
                },
            ],
            false,
        )?;
        lines(
            &dir.join(format!("{name}_residual.svg")),
            &format!("validation {name} residual before/after"),
            "time (s)",
            name,
            &[
                Series {
                    label: "nominal".into(),
                    x: t,
                    y: r0,
                },
                Series {
                    label: format!("augmented ({})", d.effect),
                    x: t,
                    y: r1,
                },
            ],
            false,
        )?;
        let (f, m0) = amplitude_spectrum(r0, 1.0 / v.dt);
        let (_, m1) = amplitude_spectrum(r1, 1.0 / v.dt);
        lines(
            &dir.join(format!("{name}_residual_spectrum.svg")),
            &format!(
                "validation {name} residual spectrum (model modes {:?} Hz)",
                d.location
                    .model_freqs_hz
                    .iter()
                    .map(|f| (f * 100.0).round() / 100.0)
                    .collect::<Vec<_>>()
            ),
            "frequency (Hz)",
            "amplitude",
            &[
                Series {
                    label: "nominal".into(),
                    x: &f,
                    y: &m0,
                },
                Series {
                    label: format!("augmented ({})", d.effect),
                    x: &f,
                    y: &m1,
                },
            ],
            true,
        )?;
    }
    Ok(())
}
