//! Tests of the own-generator proof: the plan, the scoring and the tables.

use super::*;

fn row(truth: &str, group: Group, named: &str, unexplained: bool, correct: bool) -> ProofRow {
    ProofRow {
        truth: truth.into(),
        group,
        seed: 0,
        conditions: String::new(),
        channels: vec![],
        named: named.into(),
        named_raw: vec![],
        unexplained: unexplained.then(|| "tip_pos_m 1.00–2.00 Hz".to_string()),
        correct,
        parameter: None,
        estimates: vec![],
        orientation_ok: None,
        nrmse: (1.0, 0.5, "tip_pos_m".into()),
        seconds: 0.0,
        error: None,
    }
}

#[test]
fn the_carriage_mass_is_scored_on_the_final_calibration() {
    // the nominal calibration absorbed the effect (0.50 kg); the final model's is 0.11 kg
    let j = serde_json::json!({
        "effects": [{"effect": "tip_mass", "parameters": {"tip_mass_kg": 0.011},
                     "uncertainty": {"tip_mass_kg": 0.001}}],
        "calibration": {"base_mass_delta_kg": {"value": 0.5, "std": 0.01}},
        "final_calibration": {"base_mass_delta_kg": {"value": 0.11, "std": 0.02,
                               "degrees_of_freedom": 1.0, "expanded_uncertainty_95": 0.254}},
    });
    let truth: BTreeMap<String, Value> = [
        ("tip_mass_kg".to_string(), Value::from(0.01)),
        ("true_carriage_mass_kg".to_string(), Value::from(2.1)),
    ]
    .into_iter()
    .collect();
    let e = estimates(&j, &["tip_mass"], &truth, 2.0);
    let cal = e.iter().find(|e| e.kind.contains("calibration")).unwrap();
    assert_eq!((cal.value, cal.sigma), (0.11, Some(0.02)));
    assert!((cal.truth - 0.1).abs() < 1e-12);
    // its 95 % interval is the one its degrees of freedom give, not ±1.96σ
    assert_eq!(cal.u95, Some(0.254));
    let mut j = j;
    j["final_calibration"]["base_mass_delta_kg"]["expanded_uncertainty_95"] = Value::Null;
    let e = estimates(&j, &["tip_mass"], &truth, 2.0);
    let cal = e.iter().find(|e| e.kind.contains("calibration")).unwrap();
    assert!((cal.u95.unwrap() - 1.96 * 0.02).abs() < 1e-12);
}

fn est(kind: &str, truth: f64, value: f64, sigma: Option<f64>) -> Estimate {
    Estimate {
        kind: kind.into(),
        truth,
        value,
        sigma,
        u95: sigma.map(|s| 1.96 * s),
    }
}

#[test]
fn servo_lag_never_counts_unless_hidden() {
    let n = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(conventional_names(&n(&["servo_lag"]), &[]), "none");
    assert_eq!(
        conventional_names(&n(&["tip_mass", "servo_lag"]), &["tip_mass"]),
        "tip_mass"
    );
    assert_eq!(
        conventional_names(
            &n(&["servo_lag", "base_friction"]),
            &["base_friction", "servo_lag"]
        ),
        "base_friction+servo_lag"
    );
}

/// 13 hand-made rows: singles, pairs (exact, missing one, one extra), nulls and
/// out-of-catalogue cases, with estimates at z = 0.5, 1.5, 3 (tip mass) and 1, 4 (friction).
fn hand_made_rows() -> Vec<ProofRow> {
    let mut rows = vec![
        row("tip_mass", Group::Single, "tip_mass", false, true),
        row("sensor_delay", Group::Single, "servo_lag", false, false),
        row(
            "cogging_ripple",
            Group::Single,
            "cogging_ripple",
            false,
            true,
        ),
        row("cogging_ripple", Group::Single, "none", true, false),
        // pairs: 1 exact; one missing an effect; one with an extra effect
        row(
            "base_friction+servo_lag",
            Group::Pair,
            "base_friction+servo_lag",
            false,
            true,
        ),
        row(
            "sensor_delay+tip_mass",
            Group::Pair,
            "tip_mass",
            false,
            false,
        ),
        row(
            "base_friction+tip_mass",
            Group::Pair,
            "base_friction+root_compliance+tip_mass",
            false,
            false,
        ),
        row("none", Group::Null, "none", false, true),
        row("none", Group::Null, "none", true, false),
        row("none", Group::Null, "mount_resonance", false, false),
        row("crack", Group::Unmodelled, "none", true, true),
        row(
            "sensor_drift",
            Group::Unmodelled,
            "sensor_gain",
            true,
            false,
        ),
        row("sensor_drift", Group::Unmodelled, "none", false, false),
    ];
    // coverage: z = 0.5, 1.5, 3 (tip mass); z = 1, 4 (friction); one without σ
    rows[0].estimates = vec![
        est("tip_mass_kg", 1.0, 1.05, Some(0.1)),
        est("base_mass_delta_kg (calibration)", 0.0, 0.1, Some(0.1)),
    ];
    rows[4].estimates = vec![
        est("friction_n", 2.0, 2.1, Some(0.1)),
        // a σ resting on two recordings' disagreement (ν = 1): ± 12.7 σ covers z = 4
        Estimate {
            u95: Some(1.27),
            ..est("friction_n", 2.0, 2.4, Some(0.1))
        },
        est("servo_bandwidth_hz", 40.0, 30.0, None),
    ];
    rows[5].estimates = vec![
        est("tip_mass_kg", 1.0, 1.15, Some(0.1)),
        est("tip_mass_kg", 1.0, 0.7, Some(0.1)),
    ];
    rows
}

#[test]
fn scores_a_hand_made_table() {
    let rows = hand_made_rows();
    let s = score(&rows);
    assert_eq!(s.cases, 13);
    assert_eq!(s.singles, (2, 4));
    assert_eq!(s.pairs_exact, (1, 3));
    // hidden 6: named 5 of them (sensor_delay missed); named 6: one extra (root_compliance)
    assert_eq!((s.pairs_tp, s.pairs_fn, s.pairs_fp), (5, 1, 1));
    assert!((s.pairs_recall - 5.0 / 6.0).abs() < 1e-12);
    assert!((s.pairs_precision - 5.0 / 6.0).abs() < 1e-12);
    // a name (mount_resonance) and an `unexplained` report are both false alarms
    assert_eq!(s.null_false_alarms, (2, 3));
    assert_eq!(s.null_unexplained, (1, 3));
    assert_eq!(s.unmodelled_unexplained, (1, 3));
    assert_eq!(s.unmodelled_tip_channel, 2);
    let tm = &s.coverage["tip_mass_kg"];
    assert_eq!((tm.n, tm.within_2sigma, tm.no_sigma), (3, 2, 0));
    // median |z| of (0.5, 1.5, 3) = 1.5
    assert!((tm.z_scale - 1.5 / 0.6745).abs() < 1e-9);
    let fr = &s.coverage["friction_n"];
    assert_eq!((fr.n, fr.within_2sigma), (2, 1));
    assert_eq!((fr.n_u95, fr.within_u95), (2, 2));
    assert_eq!((tm.n_u95, tm.within_u95), (3, 2));
    assert!((fr.z_scale - 2.5 / 0.6745).abs() < 1e-9);
    assert_eq!(s.coverage["servo_bandwidth_hz"].no_sigma, 1);
    // all effect parameters: z = 0.5, 1.5, 3, 1, 4 → 3 of 5 within 2σ, median 1.5
    let all = &s.coverage_effects;
    assert_eq!((all.n, all.within_2sigma, all.no_sigma), (5, 3, 1));
    assert!((all.fraction() - 0.6).abs() < 1e-12);
    assert!((all.z_scale - 1.5 / 0.6745).abs() < 1e-9);
    assert_eq!(s.coverage_cases, 3);
    assert!(s.errors.is_empty());
}

#[test]
fn an_error_is_wrong_and_the_confusion_table_counts_pairs() {
    let rows = hand_made_rows();
    // an error is wrong, never a named effect (not a false alarm on a null)
    let mut e = row("none", Group::Null, "error", false, false);
    e.error = Some("panic: x".into());
    let se = score(&[e]);
    assert_eq!((se.null_false_alarms, se.errors.len()), ((0, 1), 1));
    // the confusion table counts a pair in each named column and reports unexplained
    let t = confusion(&rows);
    let line = t.lines().find(|l| l.starts_with("sensor_drift")).unwrap();
    // n = 2; one case named sensor_gain; none 1; unexplained 1
    let tok: Vec<&str> = line.split_whitespace().collect();
    let k = tok.len();
    assert_eq!((tok[1], tok[k - 2], tok[k - 1]), ("2", "1", "1"), "{line}");
    let sg = EFFECTS.iter().position(|e| *e == "sensor_gain").unwrap();
    assert_eq!(tok[2 + sg], "1", "{line}");
    assert_eq!(
        tok[2..k - 2].iter().filter(|t| **t != ".").count(),
        1,
        "{line}"
    );
}

#[test]
fn proof_json_reads_back_with_failed_rows() {
    let mut e = row("none", Group::Null, "error", false, false);
    e.error = Some("panic: x".into());
    e.nrmse = (f64::NAN, f64::NAN, String::new());
    let rows = vec![row("tip_mass", Group::Single, "tip_mass", false, true), e];
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("proof.json");
    std::fs::write(&p, serde_json::to_string(&rows).unwrap()).unwrap();
    let back = read_rows(&[p.clone(), p]).unwrap();
    assert_eq!(back.len(), 4);
    assert!(back[1].nrmse.0.is_nan() && back[1].error.is_some());
    let s = score(&back);
    assert_eq!((s.singles, s.errors.len()), ((2, 2), 2));
}

#[test]
fn plan_covers_every_group_and_keeps_force_for_friction() {
    let p = plan(&PlanOptions {
        singles: vec!["base_friction".into(), "tip_mass".into()],
        cases: 7,
        pairs: vec!["tip_mass+cogging_ripple".into()],
        pair_cases: 7,
        unmodelled: Unmodelled::ALL.to_vec(),
        unmodelled_cases: 2,
        nulls: 8,
        seed: 100,
        duration_s: 40.0,
        max_samples: 10_000,
        vary: true,
    });
    assert_eq!(p.len(), 14 + 7 + 6 + 8);
    let mut seeds: Vec<u64> = p.iter().map(|c| c.seed).collect();
    seeds.sort_unstable();
    seeds.dedup();
    assert_eq!(seeds.len(), p.len(), "seeds are distinct");
    for c in &p {
        if needs_force(&c.effect) {
            assert_ne!(c.conditions.force, Some(false), "{c:?}");
        }
        assert!(c.duration_s * c.conditions.rate_hz <= 10_000.0 + 1e-9);
    }
    assert!(p.iter().any(|c| c.label == "cogging_ripple+tip_mass"));
    let rates: Vec<f64> = p.iter().map(|c| c.conditions.rate_hz).collect();
    assert!(rates.contains(&50.0) && rates.contains(&1000.0));
    let nulls: Vec<&CaseSpec> = p.iter().filter(|c| c.group == Group::Null).collect();
    assert!(nulls.iter().any(|c| c.conditions.base_pos == Some(false)));
    assert!(nulls.iter().any(|c| c.conditions.force == Some(false)));
}
