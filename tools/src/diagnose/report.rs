//! Report of a diagnosis: the JSON of the issue and plain words (the SVG plots and files are
//! drawn by `crate::cli::diagnose`).

use super::fit::CHANNEL_NAMES;
use super::{CandidateOutcome, Diagnosis};
use crate::effect::Effect;
use serde_json::{json, Map, Value};

/// One reported parameter: JSON name with unit, value, 1-σ (NaN: not identified) and its
/// effective degrees of freedom ([`super::honesty::effective_dof`]; infinite when none were
/// measured).
#[derive(Clone, Debug)]
pub struct Reported {
    /// JSON name with unit.
    pub name: String,
    /// Value (physical units).
    pub value: f64,
    /// 1-σ (physical units).
    pub std: f64,
    /// Effective degrees of freedom of `std`.
    pub dof: f64,
}

impl Reported {
    fn new(name: &str, value: f64, std: f64, dof: f64) -> Reported {
        Reported {
            name: name.to_string(),
            value,
            std,
            dof,
        }
    }

    /// Half-width of the 95 % interval, t₀.₉₇₅(ν) σ ([`super::honesty::coverage_factor_95`]).
    pub fn u95(&self) -> f64 {
        super::honesty::coverage_factor_95(self.dof) * self.std
    }
}

/// Parameters of the effect `id` whose values sit at `off..off + len` of a fit, with the
/// degrees of freedom `dof` of that fit's parameters (empty: none measured); cogging
/// sine/cosine become amplitude and pitch (the fewer degrees of freedom of the two), gravity
/// its orientation (from `words`).
pub fn parameters_at(
    id: Effect,
    words: &str,
    fit: &super::fit::FitResult,
    (off, len): (usize, usize),
    dof: &[f64],
) -> (Vec<Reported>, Option<String>) {
    let mut out = Vec::new();
    let names = &fit.names[off..off + len];
    let vals = &fit.values[off..off + len];
    let std = &fit.std[off..off + len];
    let nu = |i: usize| dof.get(off + i).copied().unwrap_or(f64::INFINITY);
    if id == Effect::CoggingRipple {
        let (a, b) = (vals[0], vals[1]);
        let amp = a.hypot(b);
        let s = ((a * std[0]).powi(2) + (b * std[1]).powi(2)).sqrt() / amp.max(1e-300);
        out.push(Reported::new(
            "cogging_amplitude_n",
            amp,
            s,
            nu(0).min(nu(1)),
        ));
        out.push(Reported::new("cogging_pitch_m", vals[2], std[2], nu(2)));
    } else if id == Effect::CubicStiffness {
        // the recordings determine c₃; k₃ = c₃ k_r⁴ inherits k_r, which the stiffness scale
        // largely absorbs (a long flat valley where the linearised σ means nothing): k₃ is
        // reported with its uncertainty null ("not identified"); see docs/diagnose.md
        let (kr, c3) = (vals[0], vals[1]);
        out.push(Reported::new(
            "cubic_root_stiffness_nm_per_rad3",
            c3 * kr.powi(4),
            f64::NAN,
            f64::INFINITY,
        ));
        out.push(Reported::new(names[1], c3, std[1], nu(1)));
        out.push(Reported::new(names[0], kr, std[0], nu(0)));
    } else if id == Effect::SensorGain {
        out.push(Reported::new("sensor_gain", 1.0 + vals[0], std[0], nu(0)));
    } else {
        for i in 0..names.len() {
            let v = if matches!(
                names[i],
                "tip_mass_kg"
                    | "drag_coefficient_kg_per_m2"
                    | "tip_drag_coefficient_kg_per_m"
                    | "backlash_m"
            ) {
                vals[i].abs()
            } else {
                vals[i]
            };
            out.push(Reported::new(names[i], v, std[i], nu(i)));
        }
    }
    let orientation = if id == Effect::GravityAxialLoad {
        Some(if words.contains("hangs") {
            "hanging".to_string()
        } else {
            "upright".to_string()
        })
    } else {
        None
    };
    (out, orientation)
}

/// Effect parameters of a candidate outcome (its own fit).
pub fn effect_parameters(o: &CandidateOutcome) -> (Vec<Reported>, Option<String>) {
    let len = o.fit.values.len() - o.param_offset;
    parameters_at(o.id, &o.words, &o.fit, (o.param_offset, len), &[])
}

/// Every selected effect with its parameters from the final joint fit:
/// (id, words, parameters, orientation, outcome when it was added).
pub fn final_effects(
    d: &Diagnosis,
) -> Vec<(Effect, Vec<Reported>, Option<String>, &CandidateOutcome)> {
    let mut off = d.calibration.names.len();
    let mut out = Vec::new();
    for (c, o) in d.final_set.iter().zip(&d.effects) {
        let len = c.params.len();
        let (mut p, or) = parameters_at(
            c.id,
            c.words,
            &d.final_fit,
            (off, len),
            &d.honesty.degrees_of_freedom,
        );
        off += len;
        if let (Effect::MountResonance, Some((f, s))) = (c.id, d.mount_resonance) {
            as_the_rig_shows(&mut p, f, s);
        }
        out.push((c.id, p, or, o));
    }
    out
}

/// A coupled mount's parameters `p` with `mount_frequency_hz` the resonance as the rig shows
/// it (`f` ± `s` Hz, [`Diagnosis::mount_resonance`], with the degrees of freedom of the fitted
/// frequency it follows from); the fit's own frequency, the beam taken as a rigid mass on the
/// mount, follows as `mount_rigid_beam_frequency_hz`.
fn as_the_rig_shows(p: &mut Vec<Reported>, f: f64, s: f64) {
    if let Some(i) = p.iter().position(|r| r.name == "mount_frequency_hz") {
        let rigid = p[i].clone();
        p[i] = Reported::new("mount_frequency_hz", f, s, rigid.dof);
        p.push(Reported {
            name: "mount_rigid_beam_frequency_hz".to_string(),
            ..rigid
        });
    }
}

/// Following error of the fitted servo loop on the validation recording: (rms, peak) of
/// command − predicted base (m).
fn following_error(d: &Diagnosis) -> Option<(f64, f64)> {
    let b = d.final_val_pred.base_m.as_ref()?;
    let e: Vec<f64> = d.validate.cmd_m.iter().zip(b).map(|(c, y)| c - y).collect();
    let rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    Some((rms, e.iter().fold(0.0f64, |a, x| a.max(x.abs()))))
}

/// The primary channel and its validation NRMSE before/after.
pub fn validation_summary(d: &Diagnosis) -> (usize, f64, f64) {
    match d.effects.first() {
        Some(o) => (
            o.best_channel,
            d.val_nrmse_nominal[o.best_channel],
            d.final_val_nrmse[o.best_channel],
        ),
        None => {
            let c = [1, 2, 0]
                .into_iter()
                .find(|&c| d.val_nrmse_nominal[c].is_finite())
                .unwrap_or(0);
            (c, d.val_nrmse_nominal[c], d.val_nrmse_nominal[c])
        }
    }
}

/// One selected effect in the JSON: (object, parameters, uncertainties).
fn effect_json(
    d: &Diagnosis,
    id: Effect,
    p: &[Reported],
    orient: &Option<String>,
    o: &CandidateOutcome,
) -> (Value, Map<String, Value>, Map<String, Value>) {
    let finite_or_null = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    let (mut pm, mut um) = (Map::new(), Map::new());
    let (mut nu, mut u95) = (Map::new(), Map::new());
    for r in p {
        pm.insert(r.name.clone(), json!(r.value));
        um.insert(r.name.clone(), finite_or_null(r.std));
        nu.insert(r.name.clone(), finite_or_null(r.dof));
        u95.insert(r.name.clone(), finite_or_null(r.u95()));
    }
    if let Some(o) = orient {
        pm.insert("orientation".into(), json!(o));
    }
    if id == Effect::ServoLag {
        if let Some((rms, peak)) = following_error(d) {
            pm.insert("servo_following_error_rms_m".into(), json!(rms));
            pm.insert("servo_following_error_peak_m".into(), json!(peak));
        }
    }
    let c = o.best_channel;
    let e = json!({
        "effect": id, "words": o.words, "parameters": pm, "uncertainty": um,
        "degrees_of_freedom": nu, "expanded_uncertainty_95": u95,
        "validation": {"channel": CHANNEL_NAMES[c], "nrmse_before": o.nrmse_before[c],
            "nrmse_after": o.val_nrmse[c], "reduction": o.reduction, "model_form_allowance": o.allowance,
            "delta_neg2loglik": o.delta_val},
        "delta_bic": o.delta_bic,
        "indistinguishable_from": o.look_alike.as_ref().filter(|l| l.indistinguishable).map(|l| l.effect),
        "look_alike": o.look_alike.as_ref().map(|l| l.words.clone()),
    });
    (e, pm, um)
}

/// The first round's candidates in the JSON.
fn candidates_json(d: &Diagnosis) -> Vec<Value> {
    d.candidates
        .iter()
        .map(|o| {
            let (p, orient) = effect_parameters(o);
            let mut pm = Map::new();
            for r in p {
                pm.insert(r.name, json!(r.value));
            }
            if let Some(o) = orient {
                pm.insert("orientation".into(), json!(o));
            }
            json!({
                "effect": o.id, "score": -o.delta_val, "delta_bic": o.delta_bic,
                "validation_delta_neg2loglik": o.delta_val, "validation_nrmse_reduction": o.reduction, "model_form_allowance": o.allowance,
                "channel": CHANNEL_NAMES[o.best_channel], "ljung_box_before_after": [o.whiteness.0, o.whiteness.1],
                "significance_sigma": if o.significance.is_finite() { json!(o.significance) } else { Value::Null },
                "predictive_z": o.predictive.map(|t| t.z), "p_value": o.predictive.map(|t| t.p_value),
                "passed": o.passed, "reason": o.reason, "parameters": pm,
            })
        })
        .collect()
}

/// Validation NRMSE per recorded channel before (calibrated nominal) and after (final model).
fn per_channel_json(d: &Diagnosis) -> Map<String, Value> {
    let mut per = Map::new();
    for k in 0..3 {
        if d.val_nrmse_nominal[k].is_finite() {
            per.insert(
                CHANNEL_NAMES[k].into(),
                json!({"nrmse_before": d.val_nrmse_nominal[k], "nrmse_after": d.final_val_nrmse[k]}),
            );
        }
    }
    per
}

/// The calibration refitted jointly with the named effects (the final model's first
/// parameters), with its 1-σ (long-run, the recordings' disagreement, discretisation, the
/// base-motion assumption): what the rig is once the named physics is in the model. The
/// `calibration` entry is that of the nominal model, which may have absorbed the effects.
/// Each identified parameter also carries its effective degrees of freedom (`null`: infinite)
/// and the half-width of its 95 % interval, t₀.₉₇₅(ν) σ, as the effects' parameters do.
/// A parameter that either the nominal or the final fit does not identify
/// ([`super::effects::calibration_unidentified`]) has `null` values, `identified: false` and
/// the reason (the final fit's first): e.g. a damping ratio the joint fit drove out of the
/// range the model applies.
fn final_calibration_json(d: &Diagnosis) -> Map<String, Value> {
    let finite_or_null = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    let mut out = Map::new();
    for (i, name) in d.calibration.names.iter().enumerate() {
        let entry = match final_calibration_entry(d, i) {
            Ok((v, s)) => {
                let dof = d.honesty.degrees_of_freedom.get(i).copied();
                let r = Reported::new(name, v, s, dof.unwrap_or(f64::INFINITY));
                let mut e = json!({"value": v, "std": s, "identified": true,
                       "degrees_of_freedom": finite_or_null(r.dof),
                       "expanded_uncertainty_95": finite_or_null(r.u95())});
                if let (Some(a), true) =
                    (d.final_applied_stiffness_scale, *name == "stiffness_scale")
                {
                    e["applied_to_ei"] = json!(a);
                }
                e
            }
            Err(reason) => json!({"value": Value::Null, "std": Value::Null, "identified": false,
                        "reason": reason,
                        "degrees_of_freedom": Value::Null, "expanded_uncertainty_95": Value::Null}),
        };
        out.insert((*name).into(), entry);
    }
    out
}

/// Value and 1 σ of calibration parameter `i` (nominal order) in the final model, or why it is
/// not identified there.
fn final_calibration_entry(d: &Diagnosis, i: usize) -> Result<(f64, f64), String> {
    match (
        final_calibration_at(d, i),
        final_calibration_unidentified(d, i),
    ) {
        (Some(vs), None) => Ok(vs),
        (_, reason) => Err(reason.unwrap_or_else(|| "not in the final model".into())),
    }
}

/// Value and 1 σ of calibration parameter `i` (nominal order) in the final fit, looked up by
/// name.
fn final_calibration_at(d: &Diagnosis, i: usize) -> Option<(f64, f64)> {
    let name = d.calibration.names.get(i)?;
    let k = d.final_fit.names.iter().position(|n| n == name)?;
    Some((*d.final_fit.values.get(k)?, *d.final_fit.std.get(k)?))
}

/// Why calibration parameter `i` is not identified in the final model: the final fit's
/// reason; the nominal fit's only when the final fit has no value for it. A damping ratio the
/// nominal model drove out of range beside a mode at the wrong frequency (a tip mass held-out
/// 572010: ζ2 1.2 nominal) is identified once the named effects put the mode in place (ζ2
/// 0.0085 final), and is reported so.
fn final_calibration_unidentified(d: &Diagnosis, i: usize) -> Option<String> {
    let reason = |v: &[Option<String>]| v.get(i).cloned().flatten();
    if final_calibration_at(d, i).is_some() {
        return reason(&d.final_calibration_unidentified);
    }
    reason(&d.calibration_unidentified).map(|r| format!("in the nominal calibration: {r}"))
}

/// The JSON report (`effect`, `parameters`, `validation`, `candidates` as the issue specifies,
/// plus `effects`, `unexplained`, uncertainties, calibration, location and the honesty
/// measurements).
pub fn to_json(d: &Diagnosis) -> Value {
    let mut params = Map::new();
    let mut unc = Map::new();
    let mut effects = Vec::new();
    for (i, (id, p, orient, o)) in final_effects(d).iter().enumerate() {
        let (e, pm, um) = effect_json(d, *id, p, orient, o);
        if i == 0 {
            (params, unc) = (pm, um);
        }
        effects.push(e);
    }
    let (c, before, after) = validation_summary(d);
    let mut cal = Map::new();
    for i in 0..d.calibration.names.len() {
        let entry = match d.calibration_unidentified.get(i).cloned().flatten() {
            Some(reason) => {
                json!({"value": Value::Null, "std": Value::Null, "identified": false, "reason": reason})
            }
            None => {
                json!({"value": d.calibration.values[i], "std": d.calibration.std[i], "identified": true})
            }
        };
        cal.insert(d.calibration.names[i].into(), entry);
    }
    json!({
        "effect": d.effect,
        "words": d.effects.first().map(|o| o.words.clone()).unwrap_or_else(|| "no candidate earns its parameters".into()),
        "effects": effects,
        "unexplained": d.unexplained.as_ref().map(|u| serde_json::to_value(u).unwrap_or(Value::Null)),
        "assumptions": d.assumptions,
        "honesty": serde_json::to_value(&d.honesty).unwrap_or(Value::Null),
        "selection_rounds": d.rounds,
        "parameters": params,
        "uncertainty": unc,
        "validation": {"nrmse_before": before, "nrmse_after": after, "channel": CHANNEL_NAMES[c], "per_channel": per_channel_json(d)},
        "candidates": candidates_json(d),
        "calibration": cal,
        "final_calibration": final_calibration_json(d),
        "location": serde_json::to_value(&d.location).unwrap_or(Value::Null),
        "model_evaluations": d.evaluations,
        "model_evaluations_simulated": d.evaluations_simulated,
        "model": {
            "band_edge_hz": d.band_edge_hz,
            "working_rate_hz": d.working_rate.rate_hz,
            "content_edge_hz": d.working_rate.content_edge_hz,
            "decimation": d.working_rate.recordings.iter().map(|(name, r, q)| json!({"recording": name, "rate_hz": r, "factor": q})).collect::<Vec<_>>(),
            "basis_functions": d.basis.as_ref().map(|b| b.n_basis),
            "in_band_modes_hz": d.basis.as_ref().map(|b| b.freqs_hz.clone()),
            "convergence_rel": d.basis.as_ref().map(|b| b.convergence_rel),
            "drive_reading": {
                "chosen": d.drive_reading.chosen,
                "fit_bic": d.drive_reading.fit_bic,
                "compared": d.drive_reading.compared.iter().map(|(r, b)| json!({"reading": r, "fit_bic": b})).collect::<Vec<_>>(),
            },
        },
    })
}

/// The calibration, where the residual lies, the model modes and the assumptions, in words.
fn calibration_words(d: &Diagnosis) -> String {
    let mut s = String::new();
    s += "Calibration of the nominal model (fit recordings):\n";
    for i in 0..d.calibration.names.len() {
        s += &match d.calibration_unidentified.get(i).cloned().flatten() {
            Some(reason) => format!("  {} = not identified ({reason})\n", d.calibration.names[i]),
            None => format!(
                "  {} = {:.5} ± {:.2e}\n",
                d.calibration.names[i], d.calibration.values[i], d.calibration.std[i]
            ),
        };
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
    for a in &d.assumptions {
        s += &format!("ASSUMPTION: {a}\n");
    }
    s
}

/// Every selected effect with its parameters and validation gain, in words.
fn effects_words(d: &Diagnosis) -> String {
    let mut s = String::new();
    let (c, before, _) = validation_summary(d);
    let fe = final_effects(d);
    if fe.is_empty() {
        s += &format!(
            "\nDIAGNOSIS: none — no candidate earns its parameters (validation NRMSE {} {:.4})\n",
            CHANNEL_NAMES[c], before
        );
    }
    for (k, (id, p, orient, o)) in fe.iter().enumerate() {
        s += &format!("\nDIAGNOSIS {}: {} — {}\n", k + 1, id, o.words);
        if let Some(or) = orient {
            s += &format!("  orientation = {or}\n");
        }
        for r in p {
            if !r.std.is_finite() {
                s += &format!(
                    "  {} = {:.5e} ({})\n",
                    r.name,
                    r.value,
                    undefined_std(d, *id, r)
                );
                continue;
            }
            s += &format!("  {} = {:.5e} ± {:.2e}", r.name, r.value, r.std);
            if super::honesty::dof_is_finite(r.dof) {
                s += &format!(
                    " (95 % interval ± {:.2e}: {:.1} degrees of freedom, the fit recordings disagree beyond noise)",
                    r.u95(),
                    r.dof
                );
            }
            s += "\n";
        }
        if *id == Effect::ServoLag {
            if let Some((rms, peak)) = following_error(d) {
                s += &format!(
                    "  following error on validation: rms {rms:.3e} m, peak {peak:.3e} m\n"
                );
            }
        }
        let c = o.best_channel;
        s += &format!(
            "  shows in {}: validation NRMSE {:.4} → {:.4} ({:.1} % lower than the model before it); ΔBIC {:+.1}; validation Δ(−2lnL) {:+.1}; Ljung–Box {:.0} → {:.0}\n",
            CHANNEL_NAMES[c],
            o.nrmse_before[c],
            o.val_nrmse[c],
            100.0 * o.reduction,
            o.delta_bic,
            o.delta_val,
            o.whiteness.0,
            o.whiteness.1
        );
        if let Some(l) = &o.look_alike {
            s += &format!("  {}\n", l.words);
        }
    }
    if !fe.is_empty() {
        s += &final_calibration_words(d);
    }
    s
}

/// Why effect parameter `r` of `id` has no 1 σ, in words.
fn undefined_std(d: &Diagnosis, id: Effect, r: &Reported) -> &'static str {
    let eid = id.to_string();
    if d.honesty
        .beyond_band
        .iter()
        .any(|(e, p, _)| *e == eid && *p == r.name)
    {
        "beyond the recordings' band: a lower bound, 1 σ undefined (the loop's resonance lies outside what was recorded)"
    } else if d
        .honesty
        .at_bound
        .iter()
        .any(|(e, p)| *e == eid && *p == r.name)
    {
        "at the end of its search range, 1 σ undefined: the recordings ask for no more of it"
    } else {
        "1 σ undefined: the recordings do not determine it"
    }
}

/// The calibration refitted with the named effects, in words (see [`final_calibration_json`]).
fn final_calibration_words(d: &Diagnosis) -> String {
    let mut s = String::from("Calibration refitted with the named effects:\n");
    for (i, name) in d.calibration.names.iter().enumerate() {
        s += &match final_calibration_entry(d, i) {
            Ok((v, sd)) => match d.final_applied_stiffness_scale {
                Some(a) if *name == "stiffness_scale" => format!(
                    "  {name} = {v:.5} ± {sd:.2e} (the plain beam's; applied to EI beside the named structural effects, which keep f1: {a:.5})\n"
                ),
                _ => format!("  {name} = {v:.5} ± {sd:.2e}\n"),
            },
            Err(reason) => format!("  {name} = not identified ({reason})\n"),
        };
    }
    s
}

/// What stays unexplained, in words.
fn unexplained_words(d: &Diagnosis) -> String {
    match &d.unexplained {
        Some(u) => format!(
            "\nUNEXPLAINED: {} keeps a structured residual {:.1}× its noise (rms {:.1}× the noise, NRMSE {:.4}, Ljung–Box {:.0}, mean offset {:.3e}) in {:.2}–{:.2} Hz{}; windows {:?}; correlation with commanded velocity {:+.2}, acceleration {:+.2}{}\n",
            u.channel,
            u.structured_over_noise,
            u.residual_over_noise,
            u.nrmse,
            u.ljung_box_q,
            u.offset,
            u.band_hz[0],
            u.band_hz[1],
            u.nearest_model_mode_hz
                .map(|f| format!(" (nearest model mode {f:.2} Hz)"))
                .unwrap_or_default(),
            u.windows,
            u.correlation_velocity,
            u.correlation_acceleration,
            u.closest_catalogue_effect
                .as_ref()
                .map(|c| format!("\n  closest catalogue effect, not named: {c}"))
                .unwrap_or_default()
        ),
        None => "\nNothing structured above noise is left on the validation recording.\n".into(),
    }
}

/// Plain-words report.
pub fn words(d: &Diagnosis) -> String {
    let mut s = calibration_words(d);
    s += &effects_words(d);
    s += &unexplained_words(d);
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
