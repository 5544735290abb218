//! Tests of the selection's rounds, evidence measures, placement and plausibility rules.

use super::guard::*;
use crate::diagnose::effects::{Candidate, Transform};
use crate::diagnose::fit::FitResult;
use crate::diagnose::model::Prediction;
use crate::diagnose::CandidateOutcome;
use crate::effect::Effect;
use crate::numeric::arx;

use super::allowance::*;
use super::backward_step::*;
use super::compliance::*;
use super::evidence::*;
use super::placement::*;
use super::plausibility::*;
use super::rounds::*;
use crate::diagnose::effects::servo_candidate;
use nalgebra::DVector;

#[test]
fn the_along_beam_ladder_is_anchored_inside_the_root_springs_scan() {
    // a 0.5 m beam with EI/L = 2 N·m/rad: the root spring's scan spans k 2 … 2000 N·m/rad
    let hints = crate::diagnose::fit::tests::hints();
    let root = crate::diagnose::effects::structural_candidates(&hints)
        .into_iter()
        .find(|c| c.id == Effect::RootCompliance)
        .unwrap();
    let along = crate::diagnose::effects::along_beam_of(&root, 0.5).unwrap();
    let set = [&along];
    // a root spring the recordings identify anchors the ladder itself
    assert_eq!(root_spring_anchor(&set, 50f64.ln()), 50f64.ln());
    // a rigid one (k L/EI 10⁵, what a crack away from the root leaves it at) anchors it in
    // the middle of the scan, √(2 · 2000) ≈ 63 N·m/rad; so does one softer than the beam
    let middle = (2.0f64 * 2000.0).sqrt().ln();
    assert!((root_spring_anchor(&set, 2e5f64.ln()) - middle).abs() < 1e-12);
    assert!((root_spring_anchor(&set, 0.1f64.ln()) - middle).abs() < 1e-12);
}

#[test]
fn a_newcomer_is_refitted_from_the_better_optimum_of_what_was_chosen_with_its_own_values() {
    let joint = nalgebra::DVector::from_vec(vec![0.7, 0.01, 0.065, 0.0028, 1.6, -6.4]);
    let better = nalgebra::DVector::from_vec(vec![0.69, 0.009, 0.008, 0.0098]);
    let x = continued_start(&joint, &better);
    assert_eq!(x.as_slice(), [0.69, 0.009, 0.008, 0.0098, 1.6, -6.4]);
}

/// A following error that is a lag of the command (a position loop, y = r − τ ṙ) is the
/// loop's physics: the base yardstick of a model without a loop (predicted base = command)
/// earns nothing on it at any size, the whole dictionary (a model with a loop) all of it.
#[test]
fn a_lag_of_the_command_is_no_allowance_for_a_model_without_a_loop() {
    let sig = |f: f64, k: usize| (2.0 * std::f64::consts::PI * f * k as f64 / 500.0).sin();
    let cmd = |phase: usize| -> Vec<f64> {
        (0..4000)
            .map(|k| sig(0.8, k + phase) + 0.3 * sig(3.1, k + phase))
            .collect()
    };
    let normal = |u: &[f64], without: &[(usize, usize)]| {
        let phi = arx::dictionary(&[u, u], without);
        let lag: Vec<f64> = std::iter::once(0.0)
            .chain(u.windows(2).map(|w| -0.004 * 500.0 * (w[1] - w[0])))
            .collect();
        let mut ne = arx::Normal::new(phi.len());
        ne.add(&lag, &phi);
        ne
    };
    let (u_fit, u_val) = (cmd(0), cmd(777));
    for (has_loop, earns) in [(false, false), (true, true)] {
        let without = base_without(has_loop);
        assert_eq!(
            arx::dictionary(&[&u_fit, &u_fit], without).len(),
            generic_column_count(0, has_loop)
        );
        let (f, v) = (normal(&u_fit, without), normal(&u_val, without));
        for k in 1..=6 {
            let g = arx::best_correction_of_size(&f, &v, k).map_or(0.0, |g| g.val_reduction());
            assert_eq!(g > 0.9, earns, "loop {has_loop}, k {k}: {g}");
            assert!(earns || g < 0.05, "loop {has_loop}, k {k}: {g}");
        }
    }
}

#[test]
fn a_force_ripple_is_judged_outside_the_drives_bursts_at_acceleration_steps() {
    // force residual: a 0.05 N ripple (what the effect explains) over 0.02 N of noise,
    // and at eight acceleration steps a ±1.5 N loop transient of a few samples (what
    // nothing explains); the effect leaves noise and bursts
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let n = 10_000;
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let white: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
    let burst = |k: usize| -> f64 {
        // a ringing transient, 1.5 N decaying by −0.8 per sample
        let j = k % 1250;
        if (100..112).contains(&j) {
            1.5 * (-0.8f64).powi((j - 100) as i32)
        } else {
            0.0
        }
    };
    let after: Vec<f64> = (0..n).map(|k| white[k] + burst(k)).collect();
    let before: Vec<f64> = (0..n)
        .map(|k| after[k] + 0.05 * (k as f64 * 0.07).sin())
        .collect();
    let flagged = burst_samples(&before, &after).expect("bursts");
    assert!(flagged.iter().filter(|b| **b).count() <= 8 * 16);
    assert!((0..n)
        .filter(|k| burst(*k).abs() >= 0.4)
        .all(|k| flagged[k]));
    // on another channel the bursts stay in: the ripple is a sliver of the autocovariance;
    // in its own band it is all of the structure
    let ((p_before, p_after), whole) = structure_evidence(Some(&before), Some(&after), 1, &[]);
    assert!(p_after > 0.5 * p_before);
    assert!(whole.unwrap() < MIN_STRUCTURE_EXPLAINED, "{whole:?}");
    // the bursts are no response to the motion that drives the ripple
    let motion: Vec<f64> = (0..n).map(|k| (k as f64 * 0.07).cos()).collect();
    let (_, own_band) = structure_evidence(Some(&before), Some(&after), 1, &[&motion]);
    assert!(own_band.unwrap() > 0.9, "{own_band:?}");
    // on the force channel the ripple is what is left once the bursts are out
    let quiet = structure_explained(Some(&before), Some(&after), 2).unwrap();
    assert!(quiet > 0.9, "{quiet}");
    let ((q_before, q_after), share) = structure_evidence(Some(&before), Some(&after), 2, &[]);
    assert_eq!(share, Some(quiet));
    assert!(q_after < 0.1 * q_before);
    // a white force residual has no bursts to take out
    assert!(burst_samples(&white, &white).is_none());
    // a force the effect explains while a short move runs (friction: 0.3 N over 6 % of
    // the samples) stands out of the resting residual like a burst, but the effect brings
    // it back to the background: its own signal, judged with every sample
    let moving = |k: usize| (k % 1250) >= 500 && (k % 1250) < 575;
    let friction: Vec<f64> = (0..n)
        .map(|k| white[k] + if moving(k) { 0.3 } else { 0.0 })
        .collect();
    assert!(outliers(&friction).unwrap().iter().filter(|o| **o).count() > 400);
    assert!(burst_samples(&friction, &white).is_none());
    let share = structure_explained(Some(&friction), Some(&white), 2).unwrap();
    assert!(share > 0.9, "{share}");
}

#[test]
fn an_effect_is_judged_on_the_structure_in_its_own_band_unless_the_rest_is_driven() {
    // a real axis's force residual: friction's sign(v) square wave at 0.5 Hz beside the
    // position loop hunting at 48 Hz (100 Hz samples), white noise under both
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::PI;
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.2).unwrap();
    let n = 3000;
    let white: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
    // the hunting wanders in phase (a limit cycle, not locked to the motion)
    let mut phase = 0.0;
    let hunt: Vec<f64> = (0..n)
        .map(|_| {
            phase += 2.0 * PI * 0.48 + 0.3 * noise.sample(&mut rng);
            1.5 * f64::sin(phase)
        })
        .collect();
    let square = |k: usize| if (k / 100) % 2 == 0 { 1.0 } else { -1.0 };
    let command: Vec<f64> = (0..n).map(|k| (PI * k as f64 / 100.0).sin()).collect();
    let before: Vec<f64> = (0..n).map(|k| white[k] + hunt[k] + square(k)).collect();
    let after: Vec<f64> = (0..n).map(|k| white[k] + hunt[k]).collect();
    let judge = |b: &[f64], a: &[f64], inputs: &[&[f64]]| {
        structure_evidence(Some(b), Some(a), 1, inputs).1.unwrap()
    };
    // over the whole band the square wave is a third of the structure: a sliver
    assert!(judge(&before, &after, &[]) < MIN_STRUCTURE_EXPLAINED);
    // in its own band it is all of it, and the hunting is no response to the command
    let share = judge(&before, &after, &[&command]);
    assert!(share > 0.95, "{share}");
    // an effect that removes a fifth of the structure in its own band still fails
    let partial: Vec<f64> = (0..n)
        .map(|k| white[k] + hunt[k] + 0.9 * square(k))
        .collect();
    let share = judge(&before, &partial, &[&command]);
    assert!(share < MIN_STRUCTURE_EXPLAINED, "{share}");
    // a 4.2 Hz ring the same command drives (a loose tip sensor's resonance the effect
    // does not model) is the rest of one driven signature: the whole band decides
    let ring: Vec<f64> = (0..n)
        .map(|k| {
            let t = (k % 100) as f64 / 100.0;
            square(k) * 4.0 * (-1.5 * t).exp() * (2.0 * PI * 4.2 * t).sin()
        })
        .collect();
    let driven_before: Vec<f64> = (0..n).map(|k| white[k] + ring[k] + square(k)).collect();
    let driven_after: Vec<f64> = (0..n).map(|k| white[k] + ring[k]).collect();
    let square_cmd: Vec<f64> = (0..n).map(square).collect();
    let share = judge(&driven_before, &driven_after, &[&command, &square_cmd]);
    let whole = judge(&driven_before, &driven_after, &[]);
    assert_eq!(share, whole);
    assert!(share < MIN_STRUCTURE_EXPLAINED, "{share}");
    // judged against an input the ring does not answer to, it would have passed
    let unrelated: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
    let share = judge(&driven_before, &driven_after, &[&unrelated]);
    assert!(share > MIN_STRUCTURE_EXPLAINED && share > whole, "{share}");
}

#[test]
fn a_mounts_resonance_is_a_second_peak_only_outside_its_half_width_and_inside_the_band() {
    // pairs seed 18, case10 (100 Hz): 17.22 Hz at ζ 0.069 beside the 19.02 Hz mode, placed
    // to ± 0.04 Hz (an illustrative σ of the recordings)
    let modes = [1.25, 7.02, 19.02, 37.4];
    assert!(split_off_peak(17.22, 0.04, 0.069, 45.0, &modes));
    // 1.1 Hz from the mode is inside its half-power half-width (1.24 Hz): a calibration matter
    assert!(!split_off_peak(17.92, 0.04, 0.069, 45.0, &modes));
    // a crack at 50 Hz fitted as a mount at ζ 0.19: 26.3 Hz lies beyond the band edge
    assert!(!split_off_peak(26.3, 0.2, 0.19, 22.5, &[3.40, 20.29]));
    // a resonance the recordings do not place (2 σ reaching the mode) is not a second peak
    assert!(!split_off_peak(17.22, 0.5, 0.069, 45.0, &modes));
}

#[test]
fn a_split_refit_earns_the_allowance_only_with_what_it_gains() {
    // a refit predicting the validation 2.3× worse re-tunes nothing a candidate could be
    // mistaken for: no allowance, however loosely the one recording holds the parameters
    assert_eq!(split_gain(2.3), 0.0);
    assert_eq!(split_gain(1e6), 0.0);
    // one that predicts it 10 % better earns exactly that gain
    assert!((split_gain(0.9) - 0.1).abs() < 1e-12);
    assert_eq!(split_gain(1.0), 0.0);
}

#[test]
fn a_play_smaller_than_one_count_of_the_drive_sensor_is_not_resolved() {
    // the catalogue's play has one parameter, backlash_m, on a log scale
    let mut c = servo_candidate(1, 100.0);
    c.id = Effect::Backlash;
    c.params.truncate(1);
    c.params[0].name = "backlash_m";
    let sub_count = fitted(&c, &[1.8e-7]);
    assert_eq!(implausible(&c, &sub_count, 0, (0.0, Some(1e-6))).len(), 1);
    // counts of 0.1 µm (a command written with seven decimals), or no counts at all
    assert!(implausible(&c, &sub_count, 0, (0.0, Some(1e-7))).is_empty());
    assert!(implausible(&c, &sub_count, 0, (0.0, None)).is_empty());
    let real = fitted(&c, &[5e-5]);
    assert!(implausible(&c, &real, 0, (0.0, Some(1e-6))).is_empty());
}

/// A fit of `cand` with effect values `values` (no calibration parameters).
fn fitted(cand: &Candidate, values: &[f64]) -> FitResult {
    FitResult {
        x: DVector::from_iterator(
            values.len(),
            cand.params.iter().zip(values).map(|(d, v)| d.repr(*v)),
        ),
        values: values.to_vec(),
        std: vec![0.01; values.len()],
        names: cand.params.iter().map(|d| d.name).collect(),
        cost: 0.0,
        evaluations: 0,
        trace: vec![],
    }
}

/// A `servo_lag` outcome for tests (reduction 0.5 on `tip_pos_m`).
pub(crate) fn outcome(delta_bic: f64, passed: bool, reason: &str) -> CandidateOutcome {
    let c = servo_candidate(1, 100.0);
    CandidateOutcome {
        id: c.id,
        cand_index: 0,
        param_offset: 0,
        nrmse_before: [f64::NAN; 3],
        words: String::new(),
        fit: fitted(&c, &[5.0, 0.9]),
        k: 2,
        delta_bic,
        delta_val: delta_bic,
        val_nrmse: [f64::NAN; 3],
        best_channel: 1,
        reduction: 0.5,
        allowance: 0.1,
        whiteness: (100.0, 10.0),
        significance: 10.0,
        predictive: None,
        passed,
        reason: reason.into(),
        val_pred: Prediction {
            base_m: None,
            tip_m: None,
            force_n: None,
        },
        unplaced: None,
        look_alike: None,
        partial: false,
        beside_mode: false,
    }
}

fn param(name: &'static str, zero_is_null: bool) -> crate::diagnose::effects::ParamDef {
    crate::diagnose::effects::ParamDef {
        name,
        transform: Transform::Linear,
        starts: vec![1.0],
        scale: 1.0,
        zero_is_null,
        scan: vec![],
    }
}

/// A final model's fit with these physical values and 1 σ (nothing else filled in).
fn fit(values: Vec<f64>, std: Vec<f64>) -> FitResult {
    FitResult {
        x: DVector::from_vec(values.clone()),
        names: vec![""; values.len()],
        values,
        std,
        cost: 0.0,
        evaluations: 0,
        trace: vec![],
    }
}

fn candidate(id: Effect, params: Vec<crate::diagnose::effects::ParamDef>) -> Candidate {
    Candidate {
        id,
        words: "",
        orientation: None,
        params,
    }
}

#[test]
fn an_effect_within_three_honest_sigma_of_no_effect_is_not_identified() {
    // independent case07 (a null, tip only) cut to its first 60 %: a root spring
    // 101 ± 449 N·m/rad beside the rig's loop; a rigid clamp (k → ∞) is 0.2 σ away
    let root = candidate(
        Effect::RootCompliance,
        vec![param("root_stiffness_nm_per_rad", false)],
    );
    let servo = servo_candidate(1, 100.0);
    let friction = candidate(
        Effect::BaseFriction,
        vec![param("friction_n", true), param("viscous_n_s_per_m", true)],
    );
    // one calibration parameter, then the loop (no null: not judged), the spring, friction
    let set = [&servo, &root, &friction];
    let f = fit(
        vec![1.0, 38.0, 0.99, 101.0, 0.5, 0.0],
        vec![1e-3, 1.1, 0.02, 449.0, 0.1, 1.0],
    );
    let alone = |f: &FitResult| NullEvidence {
        std: f.std.clone(),
        alternatives: vec![],
    };
    let (i, why) =
        unidentified_in_final(&set, &f, &alone(&f), 1).expect("the spring is not identified");
    assert_eq!(i, 1);
    assert!(
        why.contains("root_stiffness_nm_per_rad") && why.contains("0.2 σ"),
        "{why}"
    );
    // identified: 5 σ from a rigid clamp; friction's null is joint (not judged here)
    let g = fit(
        vec![1.0, 38.0, 0.99, 101.0, 0.15, 0.0],
        vec![1e-3, 1.1, 0.02, 20.0, 0.1, 1.0],
    );
    assert!(unidentified_in_final(&set, &g, &alone(&g), 1).is_none());
    // a tip mass within 2 σ of zero is, and so is one 2.5 σ from it (the selection's own
    // significance bound, 3 σ, judged with the honest σ); 3.2 σ is identified
    let tip = candidate(Effect::TipMass, vec![param("tip_mass_kg", true)]);
    for (mass, expected) in [(0.004, Some(1)), (0.0075, Some(1)), (0.0096, None)] {
        let h = fit(vec![1.0, 101.0, mass], vec![1e-3, 20.0, 0.003]);
        assert_eq!(
            unidentified_in_final(&[&root, &tip], &h, &alone(&h), 1).map(|(i, _)| i),
            expected,
            "tip mass {mass} ± 0.003 kg"
        );
    }
    // an undefined σ is not judged
    assert_eq!(
        sigmas_from_null(&root, &[101.0], &[101.0], &[f64::NAN], 0),
        None
    );
    assert_eq!(
        sigmas_from_null(&servo, &[38.0, 0.99], &[38.0, 0.99], &[1.0, 0.1], 0),
        None
    );
}

/// Whether an effect is there is asked at every model-form alternative's value too, with the
/// recordings' 1 σ: second simulator seed 6, case08 (a spring the other reading of the
/// drive makes stiffer but keeps).
#[test]
fn an_effect_is_judged_at_each_model_form_alternative_s_value() {
    let root = candidate(
        Effect::RootCompliance,
        vec![param("root_stiffness_nm_per_rad", false)],
    );
    let tip = candidate(Effect::TipMass, vec![param("tip_mass_kg", true)]);
    // case08's numbers:
    // a spring of 24.2 ± 2.81 N·m/rad (the recordings' 1 σ) that the other reading puts at
    // 57.5 is 3.6 σ from a rigid clamp there (in compliance); one that an alternative takes
    // to 200 is 1.0 σ
    let spring = |alt: f64| {
        let f = fit(vec![1.0, 24.2], vec![1e-3, 2.81]);
        let evidence = NullEvidence {
            std: f.std.clone(),
            alternatives: vec![vec![1.0, alt], vec![1.0, 24.0], vec![1.0]],
        };
        unidentified_in_final(&[&root], &f, &evidence, 1)
    };
    assert!(spring(57.5).is_none());
    let (_, why) = spring(200.0).expect("the other form takes the spring to a rigid clamp");
    assert!(why.contains("1.0 σ"), "{why}");
    // a tip mass 10 σ from zero that an alternative takes to 2 σ is not identified
    let h = fit(vec![1.0, 101.0, 0.03], vec![1e-3, 20.0, 0.003]);
    let evidence = NullEvidence {
        std: h.std.clone(),
        alternatives: vec![vec![1.0, 101.0, 0.006]],
    };
    assert_eq!(
        unidentified_in_final(&[&root, &tip], &h, &evidence, 1).map(|(i, _)| i),
        Some(1)
    );
}

/// A latency on the impossible side of zero is not identified, however many σ from it:
/// held-out 531000 (backlash, tip alone): −3.02 ± 0.88 ms beside a loop.
#[test]
fn a_negative_latency_in_the_final_model_is_not_identified() {
    let delay = candidate(Effect::SensorDelay, vec![param("sensor_delay_s", true)]);
    let tip = candidate(Effect::TipMass, vec![param("tip_mass_kg", true)]);
    let alone = |f: &FitResult| NullEvidence {
        std: f.std.clone(),
        alternatives: vec![],
    };
    let f = fit(vec![1.0, 0.03, -0.00302], vec![1e-3, 0.003, 0.00088]);
    let (i, why) = unidentified_in_final(&[&tip, &delay], &f, &alone(&f), 1)
        .expect("a negative latency is not identified");
    assert_eq!(i, 1);
    assert!(
        why.contains("sensor_delay_s") && why.contains("negative"),
        "{why}"
    );
    // the same size positive is identified
    let g = fit(vec![1.0, 0.03, 0.00302], vec![1e-3, 0.003, 0.00088]);
    assert!(unidentified_in_final(&[&tip, &delay], &g, &alone(&g), 1).is_none());
}

/// A mount is placed in the final model only when its frequency + 2 σ (reported: with the
/// model's stated accuracy) lies inside the band: own null 1085000 at 100 Hz (edge 45 Hz), a
/// mount at 40.1 ± 8.3 Hz, is not; v1 case06's 14.98 ± 0.03 Hz is; an undefined σ is not.
#[test]
fn a_final_mount_whose_interval_reaches_the_band_edge_is_not_placed() {
    let mount = candidate(
        Effect::MountResonance,
        vec![
            param("mount_frequency_hz", false),
            param("mount_damping_ratio", false),
        ],
    );
    let tip = candidate(Effect::TipMass, vec![param("tip_mass_kg", true)]);
    let at =
        |f_hz: f64, sd_hz: f64| fit(vec![1.0, 0.03, f_hz, 0.1], vec![1e-3, 0.003, sd_hz, 0.05]);
    let (i, why) = unplaced_in_final(&[&tip, &mount], &at(40.1, 8.3), 1, 45.0)
        .expect("the interval reaches beyond the band edge");
    assert_eq!(i, 1);
    assert!(why.contains("40.1 ± 8.3 Hz"), "{why}");
    assert!(unplaced_in_final(&[&tip, &mount], &at(14.98, 0.03), 1, 45.0).is_none());
    assert!(unplaced_in_final(&[&tip, &mount], &at(40.1, 2.0), 1, 45.0).is_none());
    assert!(unplaced_in_final(&[&tip, &mount], &at(40.1, f64::NAN), 1, 45.0).is_some());
    assert!(
        unplaced_in_final(&[&tip], &fit(vec![1.0, 0.03], vec![1e-3, 0.003]), 1, 45.0).is_none()
    );
}

#[test]
fn after_a_backward_check_failing_candidates_are_shown_against_the_new_reference() {
    // null 79015: a failing mount kept ΔBIC −17426 against the first reference while the
    // passing candidates were judged again; now every row is (and a failure stays one)
    let mut outs = vec![
        outcome(
            -17426.0,
            false,
            "removes only 10 % of the structured residual",
        ),
        outcome(-17000.0, true, "passes every guard"),
        outcome(-900.0, false, "validation Δ(−2lnL) -3 not < −10"),
    ];
    rejudge(&mut outs, |o| {
        // against the better reference: 17000 less, and a failure could seem a pass
        let dbic = o.delta_bic + 17000.0;
        Some(outcome(dbic, dbic < -10.0, "judged again"))
    });
    assert_eq!(outs[0].delta_bic, -426.0);
    assert!(!outs[0].passed);
    assert!(outs[0].reason.contains("removes only 10 %"));
    assert!(outs[0].reason.contains("before the backward check"));
    assert_eq!(outs[1].delta_bic, 0.0);
    assert!(!outs[1].passed);
    assert_eq!(outs[2].delta_bic, 16100.0);
    // one that cannot be simulated keeps its judgement, marked
    let mut kept = vec![outcome(-50.0, true, "passes every guard")];
    rejudge(&mut kept, |_| None);
    assert!(kept[0].passed && kept[0].delta_bic == -50.0);
    assert!(kept[0].reason.contains("not re-simulated"));
}

#[test]
fn a_candidate_with_likelihood_evidence_is_refitted_in_the_next_round() {
    // held-out pair 186050 (friction + mount): beside the friction's force residual the
    // mount removed 44 % of the structure and its mass stopped at a search limit; it earns
    // a refit on the augmented model, where it passed
    let beside = outcome(
        -473.8,
        false,
        "removes only 44 % of the structured residual",
    );
    assert!(showed_evidence(&beside));
    assert!(showed_evidence(&outcome(-50.0, true, "passes every guard")));
    // no likelihood evidence: not refitted once the budget is low
    assert!(!showed_evidence(&outcome(
        -5.0,
        false,
        "ΔBIC -5.0 not < −10"
    )));
    // within the allowance of the model so far: judged again against the augmented model
    let mut within_allowance = outcome(-473.8, false, "does not beat the allowance");
    within_allowance.allowance = 0.6;
    assert!(showed_evidence(&within_allowance));
    // likelihood evidence on the fit recordings alone: not refitted
    let mut fit_only = outcome(-473.8, false, "validation Δ(−2lnL) +8 not < −10");
    fit_only.delta_val = 8.0;
    assert!(!showed_evidence(&fit_only));
}

#[test]
fn an_effect_of_the_measurement_is_credited_only_on_its_sensor_channel() {
    // the joint refit with a tip-sensor latency moved force_n 10 % and tip_pos_m 1 %
    let (vrss, vrss0, vn) = ([1.0, 0.98, 0.81], [1.0, 1.0, 1.0], [100, 100, 100]);
    let (c, red) = credited_reduction(Effect::SensorDelay, &vrss, &vrss0, &vn);
    assert_eq!(c, 1);
    assert!((red - (1.0 - 0.98f64.sqrt())).abs() < 1e-12);
    assert_eq!(
        credited_reduction(Effect::SensorGain, &vrss, &vrss0, &vn).0,
        1
    );
    // an effect of the plant acts on every channel: the best one
    let (c, red) = credited_reduction(Effect::TipMass, &vrss, &vrss0, &vn);
    assert_eq!(c, 2);
    assert!((red - 0.1).abs() < 1e-12);
    // a sensor channel not recorded gives no credit at all
    let no_tip = [100, 0, 100];
    let (_, red) = credited_reduction(Effect::SensorDelay, &vrss, &vrss0, &no_tip);
    assert!(red == f64::NEG_INFINITY);
}

#[test]
fn a_loop_slower_than_the_recording_is_not_a_position_loop() {
    // order 1: bandwidth, velocity feed-forward; 30 s recordings resolve 1/30 Hz
    let c = servo_candidate(1, 100.0);
    let slow = fitted(&c, &[1e-6, 0.96]);
    assert_eq!(implausible(&c, &slow, 0, (1.0 / 30.0, None)).len(), 1);
    let real = fitted(&c, &[5.0, 0.96]);
    assert!(implausible(&c, &real, 0, (1.0 / 30.0, None)).is_empty());
}
