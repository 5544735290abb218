//! The diagnosis report (`beamtool diagnose --report DIR`): beside the words, the JSON and the
//! plots, the validation recording and both models' predictions as CSV, so a user can read the
//! residuals the diagnosis judged.

mod common;

use beamtools::cli::diagnose::write_report;
use beamtools::diagnose::diagnose;
use beamtools::diagnose::fit::residuals;

#[test]
fn the_report_holds_the_validation_recording_and_both_predictions() {
    let (rig, fit, val, _) = common::short_tip_mass_case();
    let d = diagnose(&rig, &fit, &val, &mut beamtools::progress::Silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_report(&d, dir.path()).unwrap();
    for f in ["report.md", "diagnosis.json", "tip_pos_m_residual.svg"] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let mut r = csv::Reader::from_path(dir.path().join("validation_predictions.csv")).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let rows: Vec<Vec<f64>> = r
        .records()
        .map(|rec| rec.unwrap().iter().map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), val.time_s.len());
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let recorded = ["base_pos_m", "tip_pos_m", "force_n"]
        .iter()
        .zip([&val.base_m, &val.tip_m, &val.force_n])
        .filter(|(_, m)| m.is_some())
        .count();
    assert_eq!(header.len(), 1 + 3 * recorded, "{header:?}");
    // recording − augmented prediction is the final residual the diagnosis judged
    let r1 = residuals(&val, &d.final_val_pred);
    let (tip, aug) = (col("tip_pos_m"), col("tip_pos_m_augmented"));
    let final_tip = r1[1].as_ref().unwrap();
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row[tip], val.tip_m.as_ref().unwrap()[k]);
        assert!((row[tip] - row[aug] - final_tip[k]).abs() <= 1e-12 * row[tip].abs().max(1e-9));
    }
    // the named tip mass changes the prediction
    let nominal = col("tip_pos_m_nominal");
    assert!(rows.iter().any(|row| row[nominal] != row[aug]));
}
