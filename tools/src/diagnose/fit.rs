//! Nonlinear least squares of a candidate (calibration + effect parameters) on the fit
//! recordings: Levenberg–Marquardt ([`crate::numeric::lm`], MINPACK's algorithm) on the
//! noise-whitened residuals of every recorded channel, forward-difference Jacobian, and the
//! linearised covariance `s² (JᵀJ)⁻¹` for the parameter uncertainties.
//!
//! Every fit is bounded by a number of **model evaluations** (not by wall-clock time), so the
//! answer is the same on any machine; a generous wall-clock safety net ([`SAFETY_NET_S`]) only
//! ends a fit on a machine so overloaded that the run would otherwise never finish.
//!
//! The least-squares problem itself (residuals, whitening, [`Problem`]) is in
//! [`super::fit_problem`], the search for starting points in [`super::fit_starts`].

pub use super::fit_problem::{
    channel_rss, extend_whitened, f1_preserving_factor, params_of_values, residuals, Problem,
    CHANNEL_NAMES, FORCE_CHANNEL,
};
pub use super::fit_starts::SAFETY_NET_S;

use super::effects::{Calib, Candidate, ParamDef, Transform};
use super::fit_starts::{run_starts, scan_points, scan_starts, start_grid, stiffness_scan};
use super::model::Prepared;
use crate::model::Rig;
pub use crate::numeric::lm::covariance;
use crate::numeric::lm::{self};
use nalgebra::DVector;

/// Result of one fit.
#[derive(Clone, Debug)]
pub struct FitResult {
    /// Representation vector at the optimum.
    pub x: DVector<f64>,
    /// Physical values (definition order: calibration, then effect).
    pub values: Vec<f64>,
    /// 1-σ uncertainties (physical units).
    pub std: Vec<f64>,
    /// Parameter names.
    pub names: Vec<&'static str>,
    /// Whitened residual sum of squares.
    pub cost: f64,
    /// Model evaluations used.
    pub evaluations: usize,
    /// What happened, start by start (start and end point, cost, evaluations, termination)
    /// and the first model refusals: for a caller that shows diagnostics.
    pub trace: Vec<String>,
}

/// Parameters the model reads as their magnitude |x| ([`super::effects`]: a tip mass, air drag
/// along the beam or at its tip, backlash): the sign an optimum lands on says nothing, so a fit
/// reports the magnitude. The model is the same at x and −x, and the 1 σ too (the Jacobian's
/// column only changes sign). Only a linear representation has a sign (backlash is searched on
/// a log scale). Measured: second set, case00, the final model's drag came out
/// as −1.04e-3 kg/m² where the model held +1.04e-3.
pub const MAGNITUDES: [&str; 4] = [
    "tip_mass_kg",
    "drag_coefficient_kg_per_m2",
    "tip_drag_coefficient_kg_per_m",
    "backlash_m",
];

/// `x` (representation, in the order of `defs`) with every magnitude parameter ([`MAGNITUDES`])
/// of a linear representation at its magnitude.
pub(crate) fn as_magnitudes(defs: &[&ParamDef], mut x: DVector<f64>) -> DVector<f64> {
    for (i, d) in defs.iter().enumerate().take(x.len()) {
        if MAGNITUDES.contains(&d.name) && matches!(d.transform, Transform::Linear) {
            x[i] = x[i].abs();
        }
    }
    x
}

/// Fits `cand` (or the calibration alone) from every combination of starting values (at most
/// 6) plus `warm` (a previous calibration, representation), keeping the lowest cost. A start
/// from the rig's damping ratios at the best stiffness scale of a coarse scan (±65 % in E)
/// guards against the local minimum where a mismatched mode is damped out. Every start is
/// bounded by the Levenberg–Marquardt patience (30 × (parameters + 1) evaluations) and by an
/// equal share of what is left of `max_evaluations` model evaluations for all starts together
/// (the best point seen is kept), so the result does not depend on the machine. `seeds` are
/// whole starting points (representation, every parameter) put before the other starts after
/// the scans, e.g. a nested form's optimum ([`nested_seed`]), because a small budget does not
/// reach the last starts (successive halving); a seed of the wrong length is ignored.
#[allow(clippy::too_many_arguments)]
pub fn fit(
    rig: &Rig,
    data: &[Prepared],
    sigma: [f64; 3],
    calib: &Calib,
    cands: &[&Candidate],
    warm: Option<&DVector<f64>>,
    seeds: &[DVector<f64>],
    max_evaluations: usize,
    explore: bool,
) -> FitResult {
    let defs: Vec<&ParamDef> = calib
        .defs
        .iter()
        .chain(cands.iter().flat_map(|c| c.params.iter()))
        .collect();
    // a form without parameters (an orientation) has no scan at the rig's damping
    // ([`scan_starts`]): it takes the rig's damping as a start in every round
    let fresh_damping = cands.last().is_some_and(|c| explore || c.params.is_empty());
    let starts = start_grid(&defs, calib.len(), warm, fresh_damping);
    let (mut starts, grid_evaluations) = scan_starts(rig, data, sigma, calib, cands, &defs, starts);
    let scanned = if explore {
        stiffness_scan(rig, data, sigma, calib, cands, &defs, &starts[0])
    } else {
        None
    };
    let scan_evaluations = grid_evaluations
        + if scanned.is_some() {
            scan_points(cands)
        } else {
            0
        };
    if let Some(scanned) = scanned {
        if starts.iter().all(|s| (s - &scanned).norm() > 1e-6) {
            starts.push(scanned);
        }
    }
    // seeds first: the budget may not reach the last starts (successive halving)
    for seed in seeds.iter().rev() {
        if seed.len() == defs.len() && starts.iter().all(|s| (s - seed).norm() > 1e-6) {
            starts.insert(0, seed.clone());
        }
    }
    let problem = |x0: &DVector<f64>| Problem::new(rig, data, sigma, calib, cands, x0.clone());
    let run = run_starts(&problem, starts, max_evaluations, scan_evaluations);
    let (cost, x) = (run.cost, as_magnitudes(&defs, run.x));
    let final_problem = problem(&x);
    let j = final_problem.jacobian_at(&x);
    let std_repr = lm::std_errors(&j, cost);
    let values: Vec<f64> = defs
        .iter()
        .enumerate()
        .map(|(i, d)| d.value(x[i]))
        .collect();
    let std: Vec<f64> = defs
        .iter()
        .enumerate()
        .map(|(i, d)| std_repr[i] * d.dvalue(x[i]).abs())
        .collect();
    let evaluations = run.evaluations + *final_problem.evaluations.borrow();
    let mut trace = run.trace;
    trace.extend(final_problem.refusals.take());
    FitResult {
        x,
        values,
        std,
        names: defs.iter().map(|d| d.name).collect(),
        cost,
        evaluations,
        trace,
    }
}

/// The starting point a form `larger` of an effect takes from the optimum `smaller_x`
/// (representation: calibration, the effects chosen before, then `smaller`'s parameters) of a
/// form it nests: `smaller`'s parameters are the leading ones of `larger` (same names, same
/// order), and the extra ones start at their first listed value. A coupled mount (frequency,
/// damping ratio, mount mass) nests the massless one (a mount much heavier than the beam): the
/// massless form's resonance is where the coupled one's is, which its frequency scan, made at
/// one mass, can miss (second simulator seed 3, case17: a 0.36 kg mount at 12.6 Hz beside the
/// beam's 15.2 Hz second mode; scanned at 0.95 kg the coupled form ended at 25 Hz). `None` when
/// `larger` does not nest `smaller` or the lengths disagree.
pub fn nested_seed(
    smaller: &Candidate,
    smaller_x: &DVector<f64>,
    larger: &Candidate,
) -> Option<DVector<f64>> {
    let ns = smaller.params.len();
    if smaller.id != larger.id || !leads(smaller, larger) || smaller_x.len() < ns {
        return None;
    }
    let mut x: Vec<f64> = smaller_x.iter().copied().collect();
    x.extend(larger.params[ns..].iter().map(|d| d.repr(d.starts[0])));
    Some(DVector::from_vec(x))
}

/// The starting point a form `smaller` takes from the optimum `larger_x` (representation:
/// calibration, the effects chosen before, then `larger`'s parameters) of another candidate
/// whose leading parameters are `smaller`'s (same names, same order; any effect): `larger`'s
/// point with its extra parameters dropped. A cubic clamp holds a root spring, and its
/// two-parameter fit can reach the spring that the root spring's own search missed (second
/// simulator seed 8, case13: k_r 44.9 N·m/rad at 500 Hz; the clamp's fit ended at 44.0, the
/// spring's at 1.2·10⁷, a rigid clamp, after its scan had pointed to the stiff end). The point
/// is the smaller form's only if the extra parameters were at their null: the caller keeps it
/// when its cost is lower. `None` when the names do not lead or the lengths disagree.
pub fn reduced_seed(
    larger: &Candidate,
    larger_x: &DVector<f64>,
    smaller: &Candidate,
) -> Option<DVector<f64>> {
    let (ns, nl) = (smaller.params.len(), larger.params.len());
    if ns == 0 || !leads(smaller, larger) || larger_x.len() < nl {
        return None;
    }
    Some(larger_x.rows(0, larger_x.len() - (nl - ns)).into_owned())
}

/// The value (physical units) at which parameter `d` makes its effect vanish: 0 for one whose
/// null is zero (a log-represented one at 10⁻⁶ of its first start, the representation being
/// finite), a clamp 1000 × stiffer than its first start (k L/EI 10⁴) for a root stiffness.
/// `None` for a parameter without a null (a loop's bandwidth, a mount's frequency).
fn null_value(d: &ParamDef) -> Option<f64> {
    match (d.zero_is_null, d.transform) {
        (true, Transform::Log) => Some(1e-6 * d.starts[0]),
        (true, _) => Some(0.0),
        (false, _) if d.name == "root_stiffness_nm_per_rad" => Some(1e3 * d.starts[0]),
        (false, _) => None,
    }
}

/// The starting point of effect `newcomer` fitted on top of the effects chosen, the last of
/// which, `added`, came in after `newcomer`'s own fit of the round before: that fit's optimum
/// `previous` (representation: calibration and the `before_len` parameters of the effects
/// chosen before `added`, then `newcomer`'s) with `added`'s parameters inserted at `added`'s
/// absence — every parameter with a null ([`null_value`]) at it, the others (a ripple's pitch,
/// a spring's position) at `added_x`, its current values. The joint model nests that point, so
/// its optimum is never worse than `newcomer`'s fit without `added`; a start from the model
/// with `added` may lie in another basin (second simulator seed 10, case13: gravity fitted on
/// top of a cubic clamp from the clamp's optimum ended at twice the cost of the clamp alone,
/// above its own fit without the clamp). `None` when `added` has no parameter with a null (a
/// loop, a mount, an orientation) or the lengths disagree.
pub fn absent_seed(
    previous: &DVector<f64>,
    before_len: usize,
    added: &Candidate,
    added_x: &[f64],
    newcomer: &Candidate,
) -> Option<DVector<f64>> {
    let na = added.params.len();
    let nulls: Vec<Option<f64>> = added.params.iter().map(null_value).collect();
    if nulls.iter().all(Option::is_none)
        || added_x.len() != na
        || previous.len() != before_len + newcomer.params.len()
    {
        return None;
    }
    let absent = added
        .params
        .iter()
        .zip(&nulls)
        .zip(added_x)
        .map(|((d, n), x)| n.map_or(*x, |v| d.repr(v)));
    let x: Vec<f64> = previous
        .rows(0, before_len)
        .iter()
        .copied()
        .chain(absent)
        .chain(
            previous
                .rows(before_len, newcomer.params.len())
                .iter()
                .copied(),
        )
        .collect();
    Some(DVector::from_vec(x))
}

/// Whether `smaller`'s parameters are the leading ones of `larger`'s, which has more (same
/// names, same order): the nesting [`nested_seed`] and [`reduced_seed`] move between.
fn leads(smaller: &Candidate, larger: &Candidate) -> bool {
    smaller.params.len() < larger.params.len()
        && smaller
            .params
            .iter()
            .zip(&larger.params)
            .all(|(a, b)| a.name == b.name)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    use crate::diagnose::fit_starts::*;

    /// Start hints of a 0.5 m beam of 0.1 kg recorded at 500 Hz (the candidates' scales).
    pub(crate) fn hints() -> super::super::effects::StartHints {
        super::super::effects::StartHints {
            beam_mass_kg: 0.1,
            ei_over_l: 2.0,
            f2_hz: 15.0,
            rate_hz: 500.0,
            peak_deflection_m: 0.01,
            friction: (0.0, 0.0),
            cogging: (0.0, 0.0, 0.01),
            cogging_pitches_m: vec![],
            speed_m_s: 0.1,
            zeta1: 0.01,
            length_m: 0.5,
            carriage_mass_kg: 2.0,
            mode_freqs_hz: vec![2.7, 15.0, 41.0],
        }
    }

    #[test]
    fn a_magnitude_is_reported_as_one_and_a_log_scale_is_left_alone() {
        use super::super::effects::Transform;
        let def = |name, transform| ParamDef {
            name,
            transform,
            starts: vec![1.0],
            scale: 1.0,
            zero_is_null: true,
            scan: vec![],
        };
        let (tip, backlash, friction) = (
            def("tip_mass_kg", Transform::Linear),
            def("backlash_m", Transform::Log),
            def("friction_n", Transform::Linear),
        );
        let x = DVector::from_vec(vec![-0.012, -9.0, -0.2]);
        let y = as_magnitudes(&[&tip, &backlash, &friction], x);
        // the tip mass the model holds is |x|; a log scale's sign is its size; a friction's
        // sign is physics (judged, not hidden)
        assert_eq!(y.as_slice(), &[0.012, -9.0, -0.2]);
    }

    #[test]
    fn a_coupled_mount_starts_from_the_massless_mounts_optimum_and_a_servo_order_from_the_lower_one(
    ) {
        use super::super::effects::{mount_candidate, servo_candidate};
        let h = hints();
        let (massless, coupled) = (mount_candidate(&h, false), mount_candidate(&h, true));
        // calibration (2) then the massless mount at 13.3 Hz, ζ 0.02
        let x = DVector::from_vec(vec![
            0.01,
            -5.0,
            massless.params[0].repr(13.3),
            massless.params[1].repr(0.02),
        ]);
        let seed = nested_seed(&massless, &x, &coupled).expect("the coupled form nests it");
        assert_eq!(seed.len(), 5);
        assert_eq!(seed.rows(0, 4), x.rows(0, 4));
        let mass = &coupled.params[2];
        assert_eq!(mass.name, "mount_mass_kg");
        assert!((mass.value(seed[4]) - mass.starts[0]).abs() < 1e-9);
        // not the other way round, not across effects, not across forms that reorder
        assert!(nested_seed(&coupled, &seed, &massless).is_none());
        let (two, three) = (servo_candidate(2, 500.0), servo_candidate(3, 500.0));
        assert!(nested_seed(&massless, &x, &three).is_none());
        assert!(nested_seed(&servo_candidate(1, 500.0), &x, &two).is_none());
        let x2 = DVector::from_element(2 + two.params.len(), 0.3);
        let s3 = nested_seed(&two, &x2, &three).expect("order 3 adds the integral action");
        assert_eq!(s3.len(), 2 + three.params.len());
    }

    #[test]
    fn an_effect_refits_from_its_own_optimum_with_the_effect_added_since_at_its_absence() {
        use super::super::effects::{mount_candidate, servo_candidate};
        use crate::effect::Effect;
        let h = hints();
        let (tip, cubic) = (
            structural(Effect::TipMass),
            structural(Effect::CubicStiffness),
        );
        let (tip, cubic) = (&tip, &cubic);
        // the tip mass's own fit of the round before: calibration (3), then 12 g
        let previous = DVector::from_vec(vec![-0.1, -4.5, -3.8, 0.012]);
        // the cubic clamp, added since, at k_r 44 N·m/rad and c₃ 1e-5
        let added_x = [cubic.params[0].repr(44.0), cubic.params[1].repr(1e-5)];
        let seed = absent_seed(&previous, 3, cubic, &added_x, tip).expect("a clamp can be rigid");
        assert_eq!(seed.len(), 6);
        assert_eq!(seed.rows(0, 3), previous.rows(0, 3));
        assert_eq!(seed[5], 0.012);
        // rigid: 1000 × the first start (k L/EI 10⁴), and no cubic term
        let rigid = cubic.params[0].value(seed[3]);
        assert!(
            (rigid / cubic.params[0].starts[0] - 1e3).abs() < 1e-6,
            "{rigid}"
        );
        assert_eq!(cubic.params[1].value(seed[4]), 0.0);
        // a tip mass added since is absent at zero
        let seed = absent_seed(
            &previous.rows(0, 3).into_owned(),
            3,
            tip,
            &[0.02],
            &parameterless(),
        )
        .expect("a mass can be zero");
        assert_eq!(seed.as_slice(), &[-0.1, -4.5, -3.8, 0.0]);
        // a loop or a mount has no absence to start from; lengths that disagree give none
        let mount = mount_candidate(&h, false);
        assert!(absent_seed(&previous, 3, &mount, &[3.0, -4.0], tip).is_none());
        let loop2 = servo_candidate(2, 500.0);
        let lx = vec![0.0; loop2.params.len()];
        assert!(absent_seed(&previous, 3, &loop2, &lx, tip).is_none());
        assert!(absent_seed(&previous, 2, cubic, &added_x, tip).is_none());
        assert!(absent_seed(&previous, 3, cubic, &added_x[..1], tip).is_none());
    }

    /// The structural candidate `e` of [`hints`]' catalogue.
    fn structural(e: crate::effect::Effect) -> Candidate {
        super::super::effects::structural_candidates(&hints())
            .into_iter()
            .find(|c| c.id == e)
            .expect("in the catalogue")
    }

    /// A candidate without parameters (an orientation's form).
    fn parameterless() -> Candidate {
        Candidate {
            id: crate::effect::Effect::GravityAxialLoad,
            words: "no parameters",
            orientation: None,
            params: vec![],
        }
    }

    #[test]
    fn a_root_spring_restarts_from_the_cubic_clamps_optimum_without_its_cubic_term() {
        use super::super::effects::mount_candidate;
        use crate::effect::Effect;
        let h = hints();
        let (spring, cubic) = (
            structural(Effect::RootCompliance),
            structural(Effect::CubicStiffness),
        );
        let (spring, cubic) = (&spring, &cubic);
        // calibration (3), then the cubic clamp at k_r 44 N·m/rad, c₃ 1e-5
        let x = DVector::from_vec(vec![
            -0.1,
            -4.5,
            -3.8,
            cubic.params[0].repr(44.0),
            cubic.params[1].repr(1e-5),
        ]);
        let seed = reduced_seed(cubic, &x, spring).expect("the clamp's spring leads");
        assert_eq!(seed.len(), 4);
        assert_eq!(seed.rows(0, 4), x.rows(0, 4));
        assert!((spring.params[0].value(seed[3]) - 44.0).abs() < 1e-9);
        // not from the smaller to the larger, not between parameters of other names
        assert!(reduced_seed(spring, &seed, cubic).is_none());
        let (massless, coupled) = (mount_candidate(&h, false), mount_candidate(&h, true));
        assert!(reduced_seed(cubic, &x, &massless).is_none());
        let xm = DVector::from_element(3 + coupled.params.len(), 0.2);
        let sm = reduced_seed(&coupled, &xm, &massless).expect("the mass is the extra one");
        assert_eq!(sm.len(), 3 + massless.params.len());
    }

    #[test]
    fn the_f1_preserving_scale_holds_f1_for_an_upright_beam_near_half_its_buckling_load() {
        // a 0.82 m, 0.88 mm steel strip standing upright takes 40 % off f1² through its own
        // weight; calibrated without the load its scale fell to 0.59 (second simulator, seed 2,
        // case03). The plain fixed-point step g ← g ω1,plain²/ω1² oscillates there (3.3, 1.3,
        // 2.2, …); the factor found puts the loaded f1 back on the plain one
        use crate::model::{BeamModel, ModelOptions, Orientation, Rig};
        let rig = Rig::from_toml_str(
            r#"
[beam]
length_m = 0.823
density_kg_m3 = 7900.0
youngs_modulus_pa = 1.9e11
stations = [
  { x_m = 0.0, width_m = 0.0225, thickness_m = 0.00088 },
  { x_m = 0.823, width_m = 0.0198, thickness_m = 0.00088 },
]
[base]
mass_kg = 2.8
[damping]
ratios = [0.0074, 0.0074]
"#,
        )
        .unwrap();
        let f1 = |scale: f64, load: Option<Orientation>| {
            BeamModel::new(
                &rig,
                &ModelOptions {
                    n_modes: 6,
                    stiffness_scale: scale,
                    axial_load: load,
                    ..Default::default()
                },
            )
            .unwrap()
            .clamped_modes()
            .unwrap()
            .omega_rad_s[0]
        };
        let p = Params {
            n_basis: 6,
            stiffness_scale: 0.59,
            orientation: Some(Orientation::Upright),
            ..Params::default()
        };
        let g = f1_preserving_factor(&rig, &p).unwrap();
        let plain = f1(0.59, None);
        let loaded = f1(0.59 * g, Some(Orientation::Upright));
        assert!(
            (loaded / plain - 1.0).abs() < 1e-8,
            "f1 {loaded} against {plain}, g {g}"
        );
        assert!((1.5..1.9).contains(&g), "g {g}");
        // a tip mass (the path's other use) too
        let with_mass = Params {
            orientation: None,
            tip_mass_kg: 0.02,
            ..p.clone()
        };
        let gm = f1_preserving_factor(&rig, &with_mass).unwrap();
        let m = BeamModel::new(
            &rig,
            &ModelOptions {
                n_modes: 6,
                stiffness_scale: 0.59 * gm,
                tip_mass_kg: 0.02,
                tip_load_shape: with_mass.tip_load_shape(),
                ..Default::default()
            },
        )
        .unwrap()
        .clamped_modes()
        .unwrap()
        .omega_rad_s[0];
        assert!(
            (m / plain - 1.0).abs() < 1e-8,
            "f1 {m} against {plain}, g {gm}"
        );
    }

    /// A fake minimiser: from start `x0` (one coordinate: the distance to the optimum) it
    /// lowers the cost by one per 10 evaluations until the distance is covered.
    fn fake_run(
        calls: &mut Vec<(f64, usize)>,
    ) -> impl FnMut(&DVector<f64>, usize) -> StartOutcome + '_ {
        move |x0, share| {
            calls.push((x0[0], share));
            let steps = (x0[0] * 10.0).min(share as f64);
            let left = x0[0] - steps / 10.0;
            StartOutcome {
                cost: left,
                x: DVector::from_element(1, left),
                evaluations: steps as usize,
                unfinished: left > 0.0,
            }
        }
    }

    #[test]
    fn a_scan_read_at_two_dampings_starts_from_the_best_value_of_each() {
        // second simulator seed 4, case00 (friction + a tip mass of 11 % of the beam's): at the
        // calibrated damping, which had damped the misplaced f2 out, small masses score best;
        // at the rig's damping the true one (0.0088 kg) does, and only that start reaches it
        let costs = vec![
            (2.03e5, (0.0004, false)),
            (1.99e5, (0.0018, false)),
            (2.01e5, (0.0009, false)),
            (2.34e5, (0.0088, false)),
            (3.38e5, (0.0004, true)),
            (2.18e5, (0.0088, true)),
            (3.60e5, (0.0176, true)),
        ];
        assert_eq!(
            scan_picks(costs.clone(), true),
            [(0.0018, false), (0.0088, true)]
        );
        // one reading: the two best values more than 15 % apart
        let one: Vec<_> = costs.into_iter().filter(|c| !c.1 .1).collect();
        assert_eq!(scan_picks(one, false), [(0.0018, false), (0.0009, false)]);
        let close = vec![
            (1.0, (1.0, false)),
            (1.1, (1.1, false)),
            (1.2, (2.0, false)),
        ];
        assert_eq!(scan_picks(close, false), [(1.0, false), (2.0, false)]);
    }

    #[test]
    fn successive_halving_continues_the_best_start_to_convergence() {
        // four starts 50, 80, 60, 90 evaluation-tenths from the optimum, 1000 evaluations: an
        // equal split (250 each) would converge none of them; halving explores each with
        // 125 (the budget left divided among the starts left), then continues the best (50 → 37.5)
        let starts: Vec<DVector<f64>> = [50.0, 80.0, 60.0, 90.0]
            .iter()
            .map(|&d| DVector::from_element(1, d))
            .collect();
        let mut calls = Vec::new();
        let (best, evals) = {
            let mut run = fake_run(&mut calls);
            successive_halving(&starts, 1000, 0, &|| false, &mut run)
        };
        assert_eq!(best.cost, 0.0, "converged");
        assert!(!best.unfinished);
        assert!(evals <= 1000);
        assert_eq!(
            calls.len(),
            5,
            "four explorations and one continuation: {calls:?}"
        );
        assert!(
            calls[..4].iter().all(|&(_, share)| share == 125),
            "{calls:?}"
        );
        assert_eq!(
            calls[4].0, 37.5,
            "the best start continued from where it stopped"
        );
        // a single start gets the whole budget at once
        let mut calls = Vec::new();
        let one = [DVector::from_element(1, 50.0)];
        let (best, _) = {
            let mut run = fake_run(&mut calls);
            successive_halving(&one, 1000, 0, &|| false, &mut run)
        };
        assert_eq!(best.cost, 0.0);
        assert_eq!(calls, vec![(50.0, 1000)]);
    }
    use crate::diagnose::effects::{calibration_defs, Channels};
    use crate::diagnose::model::{predict, Params};

    /// A 0.9 m steel strip on a 2.5 kg carriage, and a 100 Hz recording of moves out to each of
    /// `strokes_m` and back (trapezoids of `speed` m/s, `accel` m/s², `dwell_s` at each end)
    /// whose tip channel is a placeholder (the command) for the test to fill.
    fn beam_and_moves(
        strokes_m: &[f64],
        speed: f64,
        accel: f64,
        dwell_s: f64,
    ) -> (Rig, crate::recording::Recording) {
        let rig = Rig::from_toml_str(
            "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\nstations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 }, { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]\n[base]\nmass_kg = 2.5\n",
        )
        .unwrap();
        let rate = 100.0;
        let mut y = vec![0.0; 50];
        for &x in strokes_m {
            for (a, b) in [(0.0, x), (x, 0.0)] {
                let (leg, _) =
                    crate::model::trapezoid_reference(a, b, speed, accel, rate, dwell_s).unwrap();
                y.extend(leg);
            }
        }
        let mut rec = crate::recording::Recording::with_uniform_time(y.len(), rate);
        rec.base_cmd_m = Some(y.clone());
        rec.tip_pos_m = Some(y);
        (rig, rec)
    }

    /// The calibration of a recording of the command and the tip alone (two damping ratios, six
    /// basis functions).
    fn tip_only_calibration(rig: &Rig) -> crate::diagnose::effects::Calib {
        let ch = Channels {
            base: false,
            tip: true,
            force: false,
            cmd_drives_beam: true,
        };
        calibration_defs(rig, &ch, 2, 6)
    }

    /// The one-pass whitened vector is the per-channel residuals divided by σ, bit for bit, with
    /// samples at a sensor's rail zero (a run past the end of a shorter prediction included),
    /// and those where the sensor gave no reading.
    #[test]
    fn whitened_residuals_in_one_pass_equal_the_divided_residuals() {
        let (rig, mut rec) = beam_and_moves(&[0.1, 0.06], 0.5, 3.0, 2.0);
        // a tip that rings (the command's flat dwells would read as a sensor's rails)
        let tip = rec.tip_pos_m.take().unwrap().into_iter().enumerate();
        rec.tip_pos_m = Some(
            tip.map(|(k, v)| v + 1e-3 * (0.37 * k as f64).sin())
                .collect(),
        );
        let mut d = Prepared::new("t", &rec).unwrap();
        let n = d.cmd_m.len();
        d.base_m = Some(d.cmd_m.iter().map(|v| 1.01 * v).collect());
        d.rails[1].runs = vec![(3, 40), (n - 5, n + 10)];
        // a camera without a reading on samples 60–74, as the loader returns it
        let gaps = crate::recording::regular::Gaps {
            runs: vec![("tip_pos_m", vec![(60, 75)])],
        };
        let d = d.with_gaps(&gaps).unwrap();
        let mut pred = predict(&rig, &Params::default(), &d, &mut None).unwrap();
        pred.tip_m.as_mut().unwrap().truncate(n - 2);
        let sigma = [3e-6, 7e-5, 0.3];
        let mut one_pass = Vec::new();
        extend_whitened(&d, &pred, sigma, &mut one_pass);
        let mut divided = Vec::new();
        for (c, r) in residuals(&d, &pred).iter().enumerate() {
            if let Some(r) = r {
                divided.extend(r.iter().map(|e| e / sigma[c]));
            }
        }
        assert!(d.tip_m.is_some() && d.base_m.is_some());
        assert_eq!(one_pass.len(), divided.len());
        assert!(one_pass
            .iter()
            .zip(&divided)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(
            one_pass[n + 3..n + 40]
                .iter()
                .filter(|v| **v == 0.0)
                .count(),
            37
        );
        assert!(one_pass[n + 60..n + 75].iter().all(|v| *v == 0.0));
        assert!(one_pass[n + 40..n + 60].iter().all(|v| *v != 0.0));
        // the base drives the model: a gap there is refused, as is a channel mostly unread
        let base_gap = crate::recording::regular::Gaps {
            runs: vec![("base_pos_m", vec![(60, 75)])],
        };
        let e = d.clone().with_gaps(&base_gap).unwrap_err().to_string();
        assert!(e.contains("base_pos_m has no reading for a while"), "{e}");
        let mostly = crate::recording::regular::Gaps {
            runs: vec![("tip_pos_m", vec![(100, 100 + n / 4)])],
        };
        assert!(d.with_gaps(&mostly).is_err());
    }

    #[test]
    fn residuals_side_by_side_are_those_one_after_the_other() {
        // three recordings (the later half simulated beside when a core is free) and a batch of
        // points (half of them evaluated beside): the same bits, evaluations and simulated
        // samples as one point and one recording after the other
        let data: Vec<Prepared> = [0.1, 0.06, 0.12]
            .iter()
            .map(|&s| {
                let (_, mut rec) = beam_and_moves(&[s, 0.6 * s], 0.5, 3.0, 1.0);
                // a tip that rings (flat dwells would read as a sensor's rails)
                let tip = rec.tip_pos_m.take().unwrap().into_iter().enumerate();
                rec.tip_pos_m = Some(tip.map(|(k, v)| v + s * (0.37 * k as f64).sin()).collect());
                Prepared::new("t", &rec).unwrap()
            })
            .collect();
        let (rig, _) = beam_and_moves(&[0.1], 0.5, 3.0, 1.0);
        let calib = tip_only_calibration(&rig);
        let x0 = DVector::from_iterator(
            calib.defs.len(),
            calib.defs.iter().map(|d| d.repr(d.starts[0])),
        );
        let xs: Vec<DVector<f64>> = (0..5)
            .map(|k| {
                let mut x = x0.clone();
                x[0] += 0.02 * k as f64;
                x
            })
            .collect();
        let sigma = [1e-6, 1e-4, 0.1];
        let one_by_one = Problem::new(&rig, &data, sigma, &calib, &[], x0.clone());
        let start = super::super::model::simulated_samples();
        let expected: Vec<DVector<f64>> = xs.iter().map(|x| one_by_one.whitened(x)).collect();
        let simulated = super::super::model::simulated_samples() - start;
        let batched = Problem::new(&rig, &data, sigma, &calib, &[], x0);
        let start = super::super::model::simulated_samples();
        let got = batched.whitened_batch(&xs);
        assert_eq!(super::super::model::simulated_samples() - start, simulated);
        assert_eq!(*batched.evaluations.borrow(), xs.len());
        let bits = |v: &[DVector<f64>]| {
            v.iter()
                .flat_map(|r| r.iter().map(|e| e.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&got), bits(&expected));
        assert_eq!(got.len(), 5);
        assert!(got[0].len() > 3 * 100 && got[0] != got[4]);
    }

    #[test]
    fn the_nominal_calibration_finds_a_stiffness_scale_far_from_the_rig_file() {
        // a beam 0.3 × as stiff as the rig file says (f1 45 % low: a heavy tip marker, a soft
        // clamp): outside a ±0.5 scan in ln E (which ends at 0.228 from its edge at 0.61), inside
        // the range the calibration accepts
        let (rig, rec) = beam_and_moves(&[0.1, 0.06], 0.3, 3.0, 3.0);
        let d = Prepared::new("t", &rec).unwrap();
        let truth = Params {
            stiffness_scale: 0.3,
            n_basis: 6,
            ..Default::default()
        };
        let mut d = d;
        d.tip_m = predict(&rig, &truth, &d, &mut None).unwrap().tip_m;
        let calib = tip_only_calibration(&rig);
        let data = [d];
        let f = fit(
            &rig,
            &data,
            [1e-6, 1e-4, 0.1],
            &calib,
            &[],
            None,
            &[],
            4000,
            true,
        );
        let scale = f.values[0];
        assert!((scale - 0.3).abs() < 0.01, "stiffness scale {scale}");
    }

    #[test]
    fn a_tip_clipped_at_its_sensors_rails_is_fitted_on_what_it_recorded() {
        // moves of 0.1 m on a beam 0.8 × as stiff as the rig file says, the tip camera clipped at
        // 70 % of the largest position: its flat tops cut every overshoot short, and fitted as
        // if they were the tip they read as a faster decay
        let (rig, mut rec) = beam_and_moves(&[0.1, 0.1], 0.5, 5.0, 2.0);
        let truth = Params {
            stiffness_scale: 0.8,
            n_basis: 6,
            ..Default::default()
        };
        let tip = predict(&rig, &truth, &Prepared::new("t", &rec).unwrap(), &mut None)
            .unwrap()
            .tip_m
            .unwrap();
        let (lo, hi) = tip
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let rail = 0.7 * hi;
        rec.tip_pos_m = Some(tip.iter().map(|v| v.clamp(lo, rail)).collect());
        let clipped = Prepared::new("t", &rec).unwrap();
        assert_eq!(
            clipped.rails[1].values,
            vec![rail],
            "the rail is found: {:?} of {lo} {hi}",
            clipped.rails[1]
        );
        let calib = tip_only_calibration(&rig);
        // (stiffness scale, damping ratio of mode 1) fitted
        let fitted = |d: Prepared| {
            let v = fit(
                &rig,
                &[d],
                [1e-6, 1e-4, 0.1],
                &calib,
                &[],
                None,
                &[],
                4000,
                true,
            )
            .values;
            (v[0], v[1])
        };
        let mut as_signal = clipped.clone();
        as_signal.rails = Default::default();
        let zeta = rig.damping_ratios().0;
        let (left_out, taken) = (fitted(clipped), fitted(as_signal));
        assert!(
            (left_out.0 - 0.8).abs() < 1e-3,
            "rail samples left out: {left_out:?}"
        );
        assert!(
            (left_out.1 / zeta - 1.0).abs() < 0.01,
            "rail samples left out: {left_out:?}"
        );
        // measured: ζ₁ 21 % high, the flat tops taken for a faster decay
        assert!(taken.1 / zeta - 1.0 > 0.1, "taken as the tip: {taken:?}");
    }
}
