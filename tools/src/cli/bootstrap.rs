//! `diagnose-bootstrap`: the decision rule checked on null replicates of the user's own
//! recordings ([`crate::diagnose::bootstrap`]): how many name an effect or report `unexplained`,
//! and whether the candidates' p-values are uniform.

use crate::diagnose::bootstrap::{null_model, NoiseFrom};
use crate::diagnose::report::to_json;
use crate::diagnose::{diagnose as run_diagnosis, model::Prepared};
use crate::model::Rig;
use crate::numeric::stats::ks_uniform;
use anyhow::{bail, Context, Result};
use clap::Args;
use rand::SeedableRng;
use serde_json::json;
use std::path::PathBuf;

/// `diagnose-bootstrap` arguments.
#[derive(Args, Debug)]
pub struct BootstrapArgs {
    /// The recordings, as `diagnose` reads them.
    #[command(flatten)]
    pub inputs: super::diagnose::Recordings,
    /// Null replicates to diagnose (each a whole diagnosis: about as long as one `diagnose`).
    #[arg(long, default_value_t = 10)]
    pub replicates: usize,
    /// Seed of the noise draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where each channel's noise model is read: `final` (the residual of the diagnosis' final
    /// model of these recordings) or `calibrated` (the calibrated nominal model's: every effect
    /// of the rig counted as noise).
    #[arg(long, default_value = "final", value_parser = ["final", "calibrated"])]
    pub noise_from: String,
    /// Output directory: bootstrap.json (the noise models, every replicate's outcome, the
    /// p-values' Kolmogorov–Smirnov statistic) and replicate-NN.json (each diagnosis).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the bootstrap: calibrates the no-effect model, diagnoses `replicates` draws of it, and
/// prints how many alarmed and the KS statistic of every candidate's p-value against the uniform.
pub fn bootstrap(a: BootstrapArgs) -> Result<()> {
    if a.replicates == 0 {
        bail!("--replicates must be at least 1");
    }
    let i = &a.inputs;
    let rig = Rig::from_toml_file(&i.rig)?;
    let opts = i.read.options();
    let fit: Vec<Prepared> = i
        .fit
        .iter()
        .map(|p| super::diagnose::load(p, &rig, &opts))
        .collect::<Result<_>>()?;
    let val = super::diagnose::load(&i.validate, &rig, &opts)?;
    let from = match a.noise_from.as_str() {
        "calibrated" => NoiseFrom::Calibrated,
        _ => NoiseFrom::Final,
    };
    println!(
        "calibrating the no-effect model{} …",
        if from == NoiseFrom::Final {
            " and diagnosing the recordings (the noise is what the final model leaves)"
        } else {
            ""
        }
    );
    let null = null_model(&rig, &fit, &val, from)?;
    if let Some(named) = &null.named {
        println!(
            "the recordings' own diagnosis named [{}]: left out of every replicate; the noise is what its final model leaves",
            named.join(", ")
        );
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(a.seed);
    let (mut rows, mut p_values) = (Vec::new(), Vec::new());
    for i in 0..a.replicates {
        let t0 = std::time::Instant::now();
        let (rf, rv) = null.replicate(&mut rng);
        let d = run_diagnosis(&rig, &rf, &rv, &mut crate::progress::Silent)?;
        let j = to_json(&d);
        let file = a.out.join(format!("replicate-{i:02}.json"));
        std::fs::write(&file, serde_json::to_string_pretty(&j)?)
            .with_context(|| format!("cannot write {}", file.display()))?;
        let named: Vec<String> = d.effects.iter().map(|e| e.id.to_string()).collect();
        let ps: Vec<f64> = j["candidates"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|c| c["p_value"].as_f64())
            .collect();
        println!(
            "replicate {i:2}: named [{}]{} ({} candidate p-values, smallest {:.1e}; {:.1} s)",
            named.join(", "),
            if d.unexplained.is_some() {
                ", unexplained"
            } else {
                ""
            },
            ps.len(),
            ps.iter().copied().fold(1.0, f64::min),
            t0.elapsed().as_secs_f64()
        );
        rows.push(json!({
            "file": file.file_name().and_then(|f| f.to_str()),
            "effects": named,
            "unexplained": d.unexplained.is_some(),
        }));
        p_values.extend(ps);
    }
    summarise(&a, &null, &rows, &p_values)
}

/// Prints and writes bootstrap.json: the noise models, the replicates' outcomes, the p-values'
/// histogram and KS statistic.
fn summarise(
    a: &BootstrapArgs,
    null: &crate::diagnose::bootstrap::NullModel,
    rows: &[serde_json::Value],
    p_values: &[f64],
) -> Result<()> {
    let named = rows.iter().filter(|r| r["effects"] != json!([])).count();
    let unexplained = rows
        .iter()
        .filter(|r| r["unexplained"] == json!(true))
        .count();
    let alarms = rows
        .iter()
        .filter(|r| r["effects"] != json!([]) || r["unexplained"] == json!(true))
        .count();
    let mut bins = [0usize; 10];
    for p in p_values {
        bins[((p * 10.0) as usize).min(9)] += 1;
    }
    let ks = ks_uniform(p_values);
    println!(
        "{} null replicates: {alarms} false alarms ({named} naming a catalogue effect, {unexplained} `unexplained`)",
        rows.len()
    );
    if let Some((d, crit)) = ks {
        println!(
            "{} candidate p-values: Kolmogorov–Smirnov D = {d:.3} against the uniform (5 % critical value {crit:.3}); histogram 0–0.1 … 0.9–1: {bins:?}; below 0.001: {}",
            p_values.len(),
            p_values.iter().filter(|&&p| p < 1e-3).count()
        );
    }
    let noise: Vec<_> = null
        .names
        .iter()
        .zip(&null.noise)
        .map(|(name, ch)| {
            let each: Vec<_> = ch
                .iter()
                .map(|m| {
                    m.as_ref().map(|m| {
                        json!({"ar_order": m.coefficients.len(), "innovation_std": m.innovation_variance.sqrt()})
                    })
                })
                .collect();
            json!({"recording": name, "base_pos_m": each[0], "tip_pos_m": each[1], "force_n": each[2]})
        })
        .collect();
    let named_first = &null.named;
    let summary = json!({
        "rig": a.inputs.rig, "fit": a.inputs.fit, "validate": a.inputs.validate, "seed": a.seed,
        "noise_from": a.noise_from, "named_on_the_recordings": named_first,
        "noise_models": noise,
        "replicates": rows,
        "false_alarms": alarms,
        "p_values": {"n": p_values.len(), "ks_d": ks.map(|k| k.0), "ks_critical_5pct": ks.map(|k| k.1), "histogram": bins},
    });
    let file = a.out.join("bootstrap.json");
    std::fs::write(&file, serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("cannot write {}", file.display()))?;
    println!("written: {}", file.display());
    Ok(())
}
