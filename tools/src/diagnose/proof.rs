//! `diagnose-proof`: the diagnosis on concealed cases of the project's own truth generator
//! (`crate::truth`), widened for issue 10, and its scoring.
//!
//! Cases ([`plan`]): every catalogue effect alone, pairs of simultaneous effects, physics outside
//! the catalogue ([`crate::truth::unmodelled`]) and nulls. Each case runs under one of a fixed
//! cycle of recording conditions ([`EFFECT_CONDITIONS`], [`NULL_CONDITIONS`]): sample rate
//! 50–1000 Hz, `base_pos_m` or `force_n` missing, sensor noise ×0.3–3; geometry (length, taper,
//! thickness, material), damping and move profiles are drawn from the seed by the generator.
//!
//! Scoring ([`score`]), the convention of the independent scorer
//! (`../shared/tools/score_discrepancy.py`): every generated rig has a finite servo loop, so a
//! named `servo_lag` never counts against a case whose hidden set lacks it. A single or a null is
//! right when the named set equals the hidden set (and a gravity case's orientation is right);
//! pairs are scored by recall (hidden effects named / hidden) and precision (named effects that
//! are hidden / named), summed over the pair cases; a null with any name or with an
//! `unexplained` report is a false alarm (the second independent set's rule,
//! `../shared/data/independent-v2/score.py`); an
//! out-of-catalogue case is right when no catalogue effect is named and the residual is reported
//! `unexplained`. Coverage: for every parameter of a correctly named effect that the generator
//! knows the truth of, whether |estimate − truth| ≤ 2σ; the robust z scale
//! median(|z|)/0.6745 says how much larger the observed scatter is than the reported σ (1 when σ
//! is honest and errors are Gaussian).

use super::model::Prepared;
use super::report::{to_json, validation_summary};
use super::{diagnose as run_diagnosis, fit::CHANNEL_NAMES, Diagnosis};
use crate::model::Rig;
use crate::progress::{Progress, Silent};
use crate::truth::unmodelled::Unmodelled;
use crate::truth::{generate, TruthCase, TruthOptions, EFFECTS};
use anyhow::Result;
use serde::{Deserialize, Deserializer, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// What a case tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Group {
    /// One catalogue effect.
    Single,
    /// Two (or more) simultaneous catalogue effects.
    Pair,
    /// Physics outside the catalogue.
    Unmodelled,
    /// No effect.
    Null,
}

/// Recording conditions of a case.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Conditions {
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// `base_pos_m` forced present/absent (`None`: drawn from the seed).
    pub base_pos: Option<bool>,
    /// `force_n` forced present/absent (`None`: drawn from the seed).
    pub force: Option<bool>,
    /// Sensor-noise multiplier.
    pub noise_scale: f64,
}

const fn cond(rate_hz: f64, base_pos: Option<bool>, force: Option<bool>, noise: f64) -> Conditions {
    Conditions {
        rate_hz,
        base_pos,
        force,
        noise_scale: noise,
    }
}

/// Conditions cycled over effect cases (singles, pairs, out-of-catalogue).
pub const EFFECT_CONDITIONS: [Conditions; 7] = [
    cond(100.0, None, None, 1.0),
    cond(50.0, None, None, 1.0),
    cond(250.0, None, Some(false), 1.0),
    cond(100.0, Some(false), None, 1.0),
    cond(500.0, None, None, 0.5),
    cond(1000.0, None, None, 1.0),
    cond(100.0, None, None, 2.0),
];

/// Conditions cycled over null cases.
pub const NULL_CONDITIONS: [Conditions; 8] = [
    cond(100.0, None, None, 1.0),
    cond(50.0, None, None, 1.0),
    cond(250.0, Some(false), None, 1.0),
    cond(1000.0, None, None, 1.0),
    cond(100.0, Some(false), Some(false), 1.0),
    cond(100.0, None, None, 3.0),
    cond(500.0, None, Some(false), 0.3),
    cond(200.0, Some(true), Some(true), 1.0),
];

/// Pairs run by default.
pub const DEFAULT_PAIRS: [&str; 7] = [
    "base_friction+servo_lag",
    "sensor_delay+tip_mass",
    "base_friction+tip_mass",
    "root_compliance+sensor_gain",
    "cogging_ripple+quadratic_damping",
    "mount_resonance+base_friction",
    "backlash+tip_mass",
];

/// One planned case.
#[derive(Clone, Debug, Serialize)]
pub struct CaseSpec {
    /// Row label: the hidden effect ids joined by `+` (sorted), an out-of-catalogue kind, or
    /// `none`.
    pub label: String,
    /// Hidden catalogue effects as handed to the generator (`none` when there are none).
    pub effect: String,
    /// Physics outside the catalogue.
    pub unmodelled: Option<Unmodelled>,
    /// Group.
    pub group: Group,
    /// Seed.
    pub seed: u64,
    /// Recording duration (s).
    pub duration_s: f64,
    /// Recording conditions.
    pub conditions: Conditions,
}

impl CaseSpec {
    /// The conditions in words (`250 Hz, 40 s, no force_n, noise ×2`).
    pub fn conditions_words(&self) -> String {
        let c = &self.conditions;
        let mut s = format!("{:.0} Hz, {:.0} s", c.rate_hz, self.duration_s);
        for (v, n) in [(c.base_pos, "base_pos_m"), (c.force, "force_n")] {
            match v {
                Some(false) => s += &format!(", no {n}"),
                Some(true) => s += &format!(", with {n}"),
                None => {}
            }
        }
        if c.noise_scale != 1.0 {
            s += &format!(", noise ×{}", c.noise_scale);
        }
        s
    }
}

/// What to plan.
#[derive(Clone, Debug)]
pub struct PlanOptions {
    /// Single effects (ids).
    pub singles: Vec<String>,
    /// Cases per single effect.
    pub cases: usize,
    /// Pairs (`a+b`).
    pub pairs: Vec<String>,
    /// Cases per pair.
    pub pair_cases: usize,
    /// Out-of-catalogue kinds.
    pub unmodelled: Vec<Unmodelled>,
    /// Cases per out-of-catalogue kind.
    pub unmodelled_cases: usize,
    /// Null cases.
    pub nulls: usize,
    /// First seed.
    pub seed: u64,
    /// Duration of each recording (s), shortened at high rates to `max_samples`.
    pub duration_s: f64,
    /// Most samples per recording (the rate × duration bound).
    pub max_samples: usize,
    /// Cycle the recording conditions (else every case at 100 Hz, channels drawn, noise ×1).
    pub vary: bool,
}

/// True when a hidden effect shows in `force_n` only (friction, cogging): that channel is then
/// never dropped.
fn needs_force(effect: &str) -> bool {
    crate::truth::parse_effects(effect).is_ok_and(|v| {
        v.iter()
            .any(|e| e.shows_in() == [crate::effect::Channel::Force])
    })
}

/// `a+b` with the ids sorted (the row label of a pair).
pub fn sorted_label(effect: &str) -> String {
    let mut v: Vec<&str> = effect.split('+').map(str::trim).collect();
    v.sort_unstable();
    v.join("+")
}

/// The case list: singles (seed + 100 i + k), pairs (seed + 2000 + 10 i + k), out-of-catalogue
/// (seed + 3000 + 10 i + k), nulls (seed + 5000 + k), conditions cycled per group.
pub fn plan(o: &PlanOptions) -> Vec<CaseSpec> {
    let mut out = Vec::new();
    let mut push = |effect: &str, um: Option<Unmodelled>, group, seed: u64, c: Conditions| {
        let mut c = if o.vary { c } else { EFFECT_CONDITIONS[0] };
        // friction and cogging act on the force channel only; it is never dropped for them
        if needs_force(effect) && c.force == Some(false) {
            c.force = Some(true);
        }
        let duration_s = o.duration_s.min(o.max_samples as f64 / c.rate_hz);
        out.push(CaseSpec {
            label: um.map_or_else(|| sorted_label(effect), |u| u.id().to_string()),
            effect: effect.to_string(),
            unmodelled: um,
            group,
            seed,
            duration_s,
            conditions: c,
        });
    };
    let ec = &EFFECT_CONDITIONS;
    for (i, e) in o.singles.iter().enumerate() {
        for k in 0..o.cases {
            let s = o.seed + 100 * i as u64 + k as u64;
            push(e, None, Group::Single, s, ec[(i + k) % ec.len()]);
        }
    }
    for (i, p) in o.pairs.iter().enumerate() {
        for k in 0..o.pair_cases {
            let s = o.seed + 2000 + 10 * i as u64 + k as u64;
            push(p, None, Group::Pair, s, ec[(i + 3 * k) % ec.len()]);
        }
    }
    for (i, u) in o.unmodelled.iter().enumerate() {
        for k in 0..o.unmodelled_cases {
            let s = o.seed + 3000 + 10 * i as u64 + k as u64;
            push(
                "none",
                Some(*u),
                Group::Unmodelled,
                s,
                ec[(2 * i + k) % ec.len()],
            );
        }
    }
    for k in 0..o.nulls {
        let s = o.seed + 5000 + k as u64;
        push(
            "none",
            None,
            Group::Null,
            s,
            NULL_CONDITIONS[k % NULL_CONDITIONS.len()],
        );
    }
    out
}

/// One parameter estimate against its truth.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Estimate {
    /// Parameter name (JSON name of the diagnosis).
    pub kind: String,
    /// True value.
    pub truth: f64,
    /// Estimate.
    pub value: f64,
    /// Reported 1 σ (`None`: not identified / not reported).
    pub sigma: Option<f64>,
    /// Reported half-width of the 95 % interval, ± t₀.₉₇₅(ν) σ (`None`: not reported).
    #[serde(default)]
    pub u95: Option<f64>,
}

/// One proof row (the elements of `proof.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ProofRow {
    /// Row label (hidden effects, out-of-catalogue kind, or `none`).
    pub truth: String,
    /// Group.
    pub group: Group,
    /// Seed.
    pub seed: u64,
    /// Recording conditions in words.
    pub conditions: String,
    /// Channels the generator recorded.
    pub channels: Vec<String>,
    /// Named effects (sorted, `+`-joined; `servo_lag` dropped unless hidden), or `none`.
    pub named: String,
    /// Every effect the diagnosis named, in selection order.
    pub named_raw: Vec<String>,
    /// The unexplained residual's channel and band, when reported.
    pub unexplained: Option<String>,
    /// Right by the rules of the module header.
    pub correct: bool,
    /// First parameter with a truth: name, true, fitted, relative error (correct effects only).
    pub parameter: Option<(String, f64, f64, f64)>,
    /// Estimates of every parameter with a truth, of correctly named effects.
    pub estimates: Vec<Estimate>,
    /// Orientation correct (gravity cases).
    pub orientation_ok: Option<bool>,
    /// Validation NRMSE before/after, channel.
    #[serde(deserialize_with = "nrmse_or_nan")]
    pub nrmse: (f64, f64, String),
    /// Seconds (generation + diagnosis).
    pub seconds: f64,
    /// The diagnosis ended in an error or a panic (the case counts as wrong, never as a named
    /// effect).
    pub error: Option<String>,
}

impl ProofRow {
    /// Hidden catalogue effects (empty for nulls and out-of-catalogue cases).
    pub fn hidden(&self) -> Vec<&str> {
        match self.group {
            Group::Null | Group::Unmodelled => vec![],
            _ => self.truth.split('+').collect(),
        }
    }

    /// Named catalogue effects under the scorer's convention (empty for `none`).
    pub fn named_set(&self) -> Vec<&str> {
        if self.named == "none" || self.error.is_some() {
            vec![]
        } else {
            self.named.split('+').collect()
        }
    }
}

/// JSON writes a NaN NRMSE (a failed case) as `null`; read it back as NaN.
fn nrmse_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<(f64, f64, String), D::Error> {
    let (a, b, c) = <(Option<f64>, Option<f64>, String)>::deserialize(d)?;
    Ok((a.unwrap_or(f64::NAN), b.unwrap_or(f64::NAN), c))
}

/// Reads the rows of `proof.json` files (several seed sets scored together).
///
/// Errors: a file that cannot be read or is not a `proof.json`.
pub fn read_rows(paths: &[std::path::PathBuf]) -> Result<Vec<ProofRow>> {
    let mut rows = Vec::new();
    for p in paths {
        let text = std::fs::read_to_string(p)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", p.display()))?;
        let r: Vec<ProofRow> = serde_json::from_str(&text).map_err(|e| {
            anyhow::anyhow!("{} is not a diagnose-proof proof.json: {e}", p.display())
        })?;
        rows.extend(r);
    }
    Ok(rows)
}

/// Named effects of a diagnosis JSON (`effects[].effect`), without `none`/`unexplained`.
fn json_effects(j: &Value) -> Vec<(String, Value)> {
    j["effects"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|e| Some((e["effect"].as_str()?.to_string(), e.clone())))
                .filter(|(n, _)| !matches!(n.as_str(), "none" | "unexplained" | "unknown"))
                .collect()
        })
        .unwrap_or_default()
}

/// The named set under the servo convention: sorted, deduplicated, `servo_lag` dropped unless
/// hidden; `none` when empty.
pub fn conventional_names(named: &[String], hidden: &[&str]) -> String {
    let mut v: Vec<&str> = named.iter().map(String::as_str).collect();
    if !hidden.contains(&"servo_lag") {
        v.retain(|n| *n != "servo_lag");
    }
    v.sort_unstable();
    v.dedup();
    if v.is_empty() {
        "none".into()
    } else {
        v.join("+")
    }
}

/// Parameters of the correctly named effects in `j` that `truth` knows, plus the calibrated
/// carriage-mass correction of the final model (`final_calibration`, else the nominal
/// `calibration`) against the truth (when the diagnosis gives it a σ).
fn estimates(
    j: &Value,
    hidden: &[&str],
    truth: &BTreeMap<String, Value>,
    rig_mass_kg: f64,
) -> Vec<Estimate> {
    let mut out = Vec::new();
    for (name, e) in json_effects(j) {
        if !hidden.contains(&name.as_str()) {
            continue;
        }
        if let Some(p) = e["parameters"].as_object() {
            for (k, v) in p {
                if let (Some(t), Some(x)) = (truth.get(k).and_then(Value::as_f64), v.as_f64()) {
                    out.push(Estimate {
                        kind: k.clone(),
                        truth: t,
                        value: x,
                        sigma: e["uncertainty"][k].as_f64(),
                        u95: e["expanded_uncertainty_95"][k].as_f64(),
                    });
                }
            }
        }
    }
    // the calibration of the final model (refitted with the named effects), when reported
    let cal = match &j["final_calibration"]["base_mass_delta_kg"] {
        c if c["value"].is_f64() => c,
        _ => &j["calibration"]["base_mass_delta_kg"],
    };
    if let (Some(x), Some(s), Some(m)) = (
        cal["value"].as_f64(),
        cal["std"].as_f64(),
        truth.get("true_carriage_mass_kg").and_then(Value::as_f64),
    ) {
        out.push(Estimate {
            kind: "base_mass_delta_kg (calibration)".into(),
            truth: m - rig_mass_kg,
            value: x,
            sigma: s.is_finite().then_some(s),
            // the final calibration's 95 % interval (its degrees of freedom); ±1.96σ else
            u95: cal["expanded_uncertainty_95"]
                .as_f64()
                .or_else(|| s.is_finite().then_some(1.96 * s)),
        });
    }
    out
}

/// A case as generated and diagnosed, for the caller to keep (write the recordings and the
/// report) before it is dropped.
pub struct CaseOutput {
    /// The generated case (rig, recordings, truth).
    pub case: TruthCase,
    /// Its diagnosis.
    pub diagnosis: Diagnosis,
}

/// Generates the case of `spec` (rig, prepared fit and validation recordings).
fn generate_case(spec: &CaseSpec) -> Result<(TruthCase, Rig, Vec<Prepared>, Prepared)> {
    let opts = TruthOptions {
        duration_s: spec.duration_s,
        rate_hz: spec.conditions.rate_hz,
        unmodelled: spec.unmodelled,
        base_pos: spec.conditions.base_pos,
        force: spec.conditions.force,
        noise_scale: spec.conditions.noise_scale,
        ..Default::default()
    };
    let case = generate(&spec.effect, spec.seed, &opts)?;
    let rig = Rig::from_toml_str(&case.rig_toml)?;
    let fit: Vec<Prepared> = case
        .fit
        .iter()
        .enumerate()
        .map(|(i, r)| Prepared::new(&format!("fit{}", i + 1), r))
        .collect::<Result<_>>()?;
    let val = Prepared::new("validate", &case.validate)?;
    Ok((case, rig, fit, val))
}

/// The located unexplained residual of a diagnosis JSON in words (`channel f0–f1 Hz`).
fn unexplained_words(j: &Value) -> Option<String> {
    j["unexplained"]["channel"].as_str().map(|ch| {
        let b = &j["unexplained"]["band_hz"];
        format!(
            "{ch} {:.2}–{:.2} Hz",
            b[0].as_f64().unwrap_or(f64::NAN),
            b[1].as_f64().unwrap_or(f64::NAN)
        )
    })
}

/// Scores diagnosis `d` (JSON `j`) of `spec` against the generated `case`.
fn score_case(spec: &CaseSpec, case: &TruthCase, d: &Diagnosis, rig: &Rig) -> ProofRow {
    let j = to_json(d);
    let (c, before, after) = validation_summary(d);
    let named_raw: Vec<String> = json_effects(&j).into_iter().map(|(n, _)| n).collect();
    let group = spec.group;
    let hidden: Vec<&str> = match group {
        Group::Null | Group::Unmodelled => vec![],
        _ => spec.effect.split('+').collect(),
    };
    let named = conventional_names(&named_raw, &hidden);
    let orientation_ok = case.truth.get("orientation").map(|v| {
        json_effects(&j)
            .iter()
            .any(|(_, e)| e["parameters"]["orientation"].as_str() == v.as_str())
    });
    let unexplained = unexplained_words(&j);
    let correct = match group {
        Group::Unmodelled => named == "none" && unexplained.is_some(),
        Group::Null => named == "none" && unexplained.is_none(),
        _ => named == spec.label && orientation_ok.unwrap_or(true),
    };
    let mut est = estimates(&j, &hidden, &case.truth, rig.base.mass_kg);
    if !correct {
        // a calibration that absorbed a missed effect is not a calibration of the true rig
        est.retain(|e| !e.kind.contains("calibration"));
    }
    let parameter = est
        .iter()
        .find(|e| !e.kind.contains("calibration"))
        .map(|e| {
            let rel = (e.value - e.truth).abs() / e.truth.abs().max(1e-300);
            (e.kind.clone(), e.truth, e.value, rel)
        });
    let channels = case.truth["channels"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|c| Some(c.as_str()?.to_string()))
                .collect()
        })
        .unwrap_or_default();
    ProofRow {
        truth: spec.label.clone(),
        group,
        seed: spec.seed,
        conditions: spec.conditions_words(),
        channels,
        named,
        named_raw,
        unexplained,
        correct,
        parameter,
        estimates: est,
        orientation_ok,
        nrmse: (before, after, CHANNEL_NAMES[c].to_string()),
        seconds: 0.0,
        error: None,
    }
}

/// Generates, diagnoses and scores one case; returns the row and what was generated and
/// diagnosed.
pub fn run_case(spec: &CaseSpec) -> Result<(ProofRow, CaseOutput)> {
    let t0 = std::time::Instant::now();
    let (case, rig, fit, val) = generate_case(spec)?;
    let d = run_diagnosis(&rig, &fit, &val, &mut Silent)?;
    let mut row = score_case(spec, &case, &d, &rig);
    row.seconds = t0.elapsed().as_secs_f64();
    Ok((row, CaseOutput { case, diagnosis: d }))
}

/// The row of a case whose generation or diagnosis failed with `msg`.
fn failed_row(spec: &CaseSpec, msg: String, seconds: f64) -> ProofRow {
    ProofRow {
        truth: spec.label.clone(),
        group: spec.group,
        seed: spec.seed,
        conditions: spec.conditions_words(),
        channels: vec![],
        named: "error".into(),
        named_raw: vec![],
        unexplained: None,
        correct: false,
        parameter: None,
        estimates: vec![],
        orientation_ok: None,
        nrmse: (f64::NAN, f64::NAN, String::new()),
        seconds,
        error: Some(msg),
    }
}

/// [`run_case`], with an error or a panic of the diagnosis turned into a failed row.
fn run_case_guarded(spec: &CaseSpec) -> (ProofRow, Option<CaseOutput>) {
    let t0 = std::time::Instant::now();
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run_case(spec))) {
        Ok(Ok((r, o))) => (r, Some(o)),
        Ok(Err(e)) => (
            failed_row(spec, format!("error: {e:#}"), t0.elapsed().as_secs_f64()),
            None,
        ),
        Err(p) => {
            let m = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            (
                failed_row(spec, format!("panic: {m}"), t0.elapsed().as_secs_f64()),
                None,
            )
        }
    }
}

/// One line per case: `i/n label seed (conditions): named … ok|WRONG (s)`, plus the error.
pub fn case_line(i: usize, n: usize, r: &ProofRow) -> String {
    let mut s = format!(
        "{}/{} {} seed {} ({}): named {}{} {} ({:.1} s)",
        i + 1,
        n,
        r.truth,
        r.seed,
        r.conditions,
        r.named,
        r.unexplained
            .as_ref()
            .map_or(String::new(), |u| format!(", unexplained {u}")),
        if r.correct { "ok" } else { "WRONG" },
        r.seconds
    );
    if let Some(e) = &r.error {
        s += &format!("\n    {e}");
    }
    s
}

/// Runs every case in order (no parallelism: the machine is shared). Each case is a stage of
/// `progress` and its result line ([`case_line`]) a note; `keep` receives each case's row and,
/// unless it failed, what was generated and diagnosed.
pub fn run_plan(
    cases: &[CaseSpec],
    progress: &mut dyn Progress,
    keep: &mut dyn FnMut(&CaseSpec, &ProofRow, Option<CaseOutput>) -> Result<()>,
) -> Result<Vec<ProofRow>> {
    let mut rows = Vec::with_capacity(cases.len());
    for (i, c) in cases.iter().enumerate() {
        progress.stage(&format!("{} seed {}", c.label, c.seed));
        progress.advance(i as u64, cases.len() as u64);
        let (r, o) = run_case_guarded(c);
        progress.note(&case_line(i, cases.len(), &r));
        keep(c, &r, o)?;
        rows.push(r);
    }
    Ok(rows)
}

/// The classic proof (singles and nulls at 100 Hz, channels drawn): `cases` per effect, `nulls`
/// nulls, from `seed0`. Kept for the integration test and the earlier numbers in docs.
pub fn run_proof(
    effects: &[&str],
    cases: usize,
    nulls: usize,
    seed0: u64,
    duration_s: f64,
    progress: &mut dyn Progress,
) -> Result<Vec<ProofRow>> {
    let specs = plan(&PlanOptions {
        singles: effects.iter().map(|s| s.to_string()).collect(),
        cases,
        pairs: vec![],
        pair_cases: 0,
        unmodelled: vec![],
        unmodelled_cases: 0,
        nulls,
        seed: seed0,
        duration_s,
        max_samples: usize::MAX,
        vary: false,
    });
    run_plan(&specs, progress, &mut |_, _, _| Ok(()))
}

/// Coverage of ±2σ for one parameter kind.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Coverage {
    /// Estimates with a finite σ.
    pub n: usize,
    /// Of those, |estimate − truth| ≤ 2σ.
    pub within_2sigma: usize,
    /// Estimates without a σ (not identified).
    pub no_sigma: usize,
    /// median(|z|)/0.6745, z = (estimate − truth)/σ: the observed scatter over the reported σ.
    pub z_scale: f64,
    /// Estimates with a finite 95 % half-width U (± t₀.₉₇₅(ν) σ).
    pub n_u95: usize,
    /// Of those, |estimate − truth| ≤ U.
    pub within_u95: usize,
}

impl Coverage {
    /// The covered fraction (NaN when n = 0).
    pub fn fraction(&self) -> f64 {
        self.within_2sigma as f64 / self.n as f64
    }
}

/// Coverage of `est`.
pub fn coverage<'a>(est: impl IntoIterator<Item = &'a Estimate>) -> Coverage {
    let mut c = Coverage::default();
    let mut z = Vec::new();
    for e in est {
        match e.sigma {
            Some(s) if s.is_finite() && s > 0.0 => {
                let zi = ((e.value - e.truth) / s).abs();
                c.n += 1;
                c.within_2sigma += usize::from(zi <= 2.0);
                z.push(zi);
                if let Some(u) = e.u95.filter(|u| u.is_finite()) {
                    c.n_u95 += 1;
                    c.within_u95 += usize::from((e.value - e.truth).abs() <= u);
                }
            }
            _ => c.no_sigma += 1,
        }
    }
    z.sort_by(|a, b| a.total_cmp(b));
    c.z_scale = if z.is_empty() {
        f64::NAN
    } else {
        let m = z.len() / 2;
        let med = if z.len() % 2 == 1 {
            z[m]
        } else {
            0.5 * (z[m - 1] + z[m])
        };
        med / 0.6745
    };
    c
}

/// The proof's score.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    /// Cases.
    pub cases: usize,
    /// Cases whose diagnosis ended in an error or a panic (counted wrong).
    pub errors: Vec<String>,
    /// Singles right / total.
    pub singles: (usize, usize),
    /// Pair cases with exactly the hidden set named / total.
    pub pairs_exact: (usize, usize),
    /// Over pair cases: hidden effects named (true positives).
    pub pairs_tp: usize,
    /// Hidden effects not named.
    pub pairs_fn: usize,
    /// Named effects not hidden.
    pub pairs_fp: usize,
    /// tp / (tp + fn).
    pub pairs_recall: f64,
    /// tp / (tp + fp).
    pub pairs_precision: f64,
    /// Nulls with any name or an `unexplained` report / nulls.
    pub null_false_alarms: (usize, usize),
    /// Nulls reported `unexplained` (no name) / nulls.
    pub null_unexplained: (usize, usize),
    /// Out-of-catalogue cases answered `unexplained` without a catalogue name / total.
    pub unmodelled_unexplained: (usize, usize),
    /// Out-of-catalogue cases located on the tip channel (every kind here acts on the tip).
    pub unmodelled_tip_channel: usize,
    /// Coverage per parameter kind.
    pub coverage: BTreeMap<String, Coverage>,
    /// Coverage over every effect parameter (calibration excluded).
    pub coverage_effects: Coverage,
    /// Correctly named effect cases with at least one parameter estimate.
    pub coverage_cases: usize,
}

fn frac(n: usize, d: usize) -> f64 {
    n as f64 / d as f64
}

/// Scores `rows` by the rules of the module header.
pub fn score(rows: &[ProofRow]) -> Summary {
    let mut s = Summary {
        cases: rows.len(),
        ..Default::default()
    };
    for r in rows {
        if let Some(e) = &r.error {
            s.errors.push(format!("{} seed {}: {e}", r.truth, r.seed));
        }
        let hidden = r.hidden();
        let named = r.named_set();
        match r.group {
            Group::Single => {
                s.singles.1 += 1;
                s.singles.0 += usize::from(r.correct);
            }
            Group::Pair => {
                s.pairs_exact.1 += 1;
                s.pairs_exact.0 += usize::from(r.correct);
                let tp = hidden.iter().filter(|h| named.contains(h)).count();
                s.pairs_tp += tp;
                s.pairs_fn += hidden.len() - tp;
                s.pairs_fp += named.iter().filter(|n| !hidden.contains(n)).count();
            }
            Group::Null => {
                s.null_false_alarms.1 += 1;
                s.null_false_alarms.0 += usize::from(!named.is_empty() || r.unexplained.is_some());
                s.null_unexplained.1 += 1;
                s.null_unexplained.0 += usize::from(named.is_empty() && r.unexplained.is_some());
            }
            Group::Unmodelled => {
                s.unmodelled_unexplained.1 += 1;
                s.unmodelled_unexplained.0 += usize::from(r.correct);
                s.unmodelled_tip_channel += usize::from(
                    r.unexplained
                        .as_ref()
                        .is_some_and(|u| u.starts_with("tip_pos_m")),
                );
            }
        }
    }
    s.pairs_recall = frac(s.pairs_tp, s.pairs_tp + s.pairs_fn);
    s.pairs_precision = frac(s.pairs_tp, s.pairs_tp + s.pairs_fp);
    let all: Vec<&Estimate> = rows.iter().flat_map(|r| &r.estimates).collect();
    let mut kinds: Vec<&str> = all.iter().map(|e| e.kind.as_str()).collect();
    kinds.sort_unstable();
    kinds.dedup();
    for k in kinds {
        s.coverage.insert(
            k.to_string(),
            coverage(all.iter().copied().filter(|e| e.kind == k)),
        );
    }
    s.coverage_effects = coverage(
        all.iter()
            .copied()
            .filter(|e| !e.kind.contains("calibration")),
    );
    s.coverage_cases = rows
        .iter()
        .filter(|r| r.estimates.iter().any(|e| !e.kind.contains("calibration")))
        .count();
    s
}

fn pct(n: usize, d: usize) -> String {
    if d == 0 {
        "–".into()
    } else {
        format!("{n}/{d} = {:.0} %", 100.0 * frac(n, d))
    }
}

/// The per-case table, the confusion table (rows: hidden, columns: named; a pair case counts in
/// each column it names) and the summary, as printed by `diagnose-proof`.
pub fn proof_table(rows: &[ProofRow]) -> String {
    let mut s = format!(
        "{:<34} {:>6} {:<36} {:<40} {:>4} {:>28} {:>7} {:>6}\n",
        "hidden", "seed", "conditions", "named", "ok", "parameter (true → fitted)", "red %", "s"
    );
    for r in rows {
        let p = r.parameter.as_ref().map_or_else(
            || match (r.orientation_ok, &r.unexplained) {
                (Some(o), _) => format!("orientation {}", if o { "ok" } else { "WRONG" }),
                (None, Some(u)) => format!("unexpl. {u}"),
                _ => "-".into(),
            },
            |(n, t, f, e)| format!("{n} {t:.3e}→{f:.3e} ({:.0}%)", 100.0 * e),
        );
        s += &format!(
            "{:<34} {:>6} {:<36} {:<40} {:>4} {:>28} {:>7.1} {:>6.1}\n",
            r.truth,
            r.seed,
            r.conditions,
            r.named,
            if r.correct { "yes" } else { "NO" },
            p,
            100.0 * (1.0 - r.nrmse.1 / r.nrmse.0),
            r.seconds
        );
    }
    s += &confusion(rows);
    s += &summary_text(&score(rows));
    s
}

/// The confusion table: rows = hidden (in order of appearance), columns = catalogue effects,
/// `none` (nothing named) and `unexpl.` (an unexplained residual reported).
pub fn confusion(rows: &[ProofRow]) -> String {
    let mut labels: Vec<&str> = Vec::new();
    for r in rows {
        if !labels.contains(&r.truth.as_str()) {
            labels.push(&r.truth);
        }
    }
    let mut cols: Vec<&str> = EFFECTS.to_vec();
    for r in rows {
        for n in r.named_set() {
            if !cols.contains(&n) {
                cols.push(n);
            }
        }
    }
    let mut s = String::from(
        "\nconfusion (rows: hidden; columns: named, servo_lag counted only where hidden; `none`: nothing named; `unexpl.`: unexplained residual reported)\n",
    );
    for (j, c) in cols.iter().enumerate() {
        s += &format!("  {j:>2} = {c}\n");
    }
    s += &format!("{:<34}{:>4}", "", "n");
    for j in 0..cols.len() {
        s += &format!("{j:>4}");
    }
    s += "  none unexpl.\n";
    for l in labels {
        let rs: Vec<&ProofRow> = rows.iter().filter(|r| r.truth == l).collect();
        s += &format!("{l:<34}{:>4}", rs.len());
        let cell = |k: usize| {
            if k == 0 {
                ".".to_string()
            } else {
                k.to_string()
            }
        };
        for c in &cols {
            s += &format!(
                "{:>4}",
                cell(rs.iter().filter(|r| r.named_set().contains(c)).count())
            );
        }
        let none = rs.iter().filter(|r| r.named == "none").count();
        let un = rs.iter().filter(|r| r.unexplained.is_some()).count();
        s += &format!("{:>6}{:>8}\n", cell(none), cell(un));
    }
    s
}

/// The summary in words.
pub fn summary_text(m: &Summary) -> String {
    let mut s = format!(
        "\nsingles right {} (target ≥ 90 %)\npairs: exactly right {}; recall {}/{} = {:.2} (target ≥ 0.75), precision {}/{} = {:.2} (target ≥ 0.9)\n",
        pct(m.singles.0, m.singles.1),
        pct(m.pairs_exact.0, m.pairs_exact.1),
        m.pairs_tp,
        m.pairs_tp + m.pairs_fn,
        m.pairs_recall,
        m.pairs_tp,
        m.pairs_tp + m.pairs_fp,
        m.pairs_precision,
    );
    s += &format!(
        "nulls: false alarms (a name or `unexplained`) {}/{} (target 0); unexplained reported on {}\nout of catalogue answered `unexplained` {} (target ≥ 75 %), located on tip_pos_m {}\n",
        m.null_false_alarms.0,
        m.null_false_alarms.1,
        pct(m.null_unexplained.0, m.null_unexplained.1),
        pct(m.unmodelled_unexplained.0, m.unmodelled_unexplained.1),
        m.unmodelled_tip_channel
    );
    s += &format!(
        "coverage of ±2σ over {} correctly named effect cases (≈ 95 % if σ is honest; z scale = median|z|/0.6745, 1 if honest), and of the reported 95 % interval ± t₀.₉₇₅(ν) σ:\n",
        m.coverage_cases
    );
    let line = |k: &str, c: &Coverage| {
        format!(
            "  {k:<36} {:>3}/{:<3} = {:>5.1} %  z scale {:>7.2}  (no σ: {})  95 % interval {:>3}/{:<3}\n",
            c.within_2sigma,
            c.n,
            100.0 * c.fraction(),
            c.z_scale,
            c.no_sigma,
            c.within_u95,
            c.n_u95
        )
    };
    for (k, c) in &m.coverage {
        s += &line(k, c);
    }
    s += &line("all effect parameters", &m.coverage_effects);
    if !m.errors.is_empty() {
        s += &format!("errors (counted wrong) {}:\n", m.errors.len());
        for e in &m.errors {
            s += &format!("  {e}\n");
        }
    }
    s
}

#[cfg(test)]
mod tests;
