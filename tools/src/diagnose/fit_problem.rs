//! The least-squares problem of a diagnosis fit ([`Problem`]): the per-channel residuals of every
//! fit recording ([`residuals`]), whitened by each channel's noise, the parameters of a point
//! (calibration + effects, [`params_of_values`]), evaluated in parallel batches for the
//! forward-difference Jacobian.

use super::effects::{apply_calibration, apply_effect, Calib, Candidate, ParamDef};
use super::model::{predict, BeamCache, Params, Prediction, Prepared};
use crate::model::Rig;
use crate::numeric::cores;
use crate::numeric::lm::{self, LmOptions};
use nalgebra::{DMatrix, DVector};
use std::cell::RefCell;

/// Channel order used everywhere in the diagnosis.
pub const CHANNEL_NAMES: [&str; 3] = ["base_pos_m", "tip_pos_m", "force_n"];

/// Index of `force_n` in [`CHANNEL_NAMES`].
pub const FORCE_CHANNEL: usize = 2;

/// Per-channel residuals (recording − prediction) of one recording; `None` where not recorded,
/// zero at the samples held at a sensor's rail ([`Prepared::rails`]).
pub fn residuals(d: &Prepared, pred: &Prediction) -> [Option<Vec<f64>>; 3] {
    let pairs = channel_pairs(d, pred);
    std::array::from_fn(|c| {
        let (Some(a), Some(b)) = pairs[c] else {
            return None;
        };
        let mut r = Vec::with_capacity(a.len().min(b.len()));
        push_channel(a, b, [&d.rails[c].runs, &d.gaps[c].runs], None, &mut r);
        Some(r)
    })
}

/// Appends [`residuals`] of `d` under `pred`, channel after channel, each divided by its noise
/// scale `sigma[c]`, to `out`: the same numbers as dividing the residuals, without the
/// intermediate vectors (a fit builds this vector at every evaluation).
pub fn extend_whitened(d: &Prepared, pred: &Prediction, sigma: [f64; 3], out: &mut Vec<f64>) {
    for (c, pair) in channel_pairs(d, pred).into_iter().enumerate() {
        if let (Some(a), Some(b)) = pair {
            push_channel(
                a,
                b,
                [&d.rails[c].runs, &d.gaps[c].runs],
                Some(sigma[c]),
                out,
            );
        }
    }
}

/// Recorded and predicted base, tip and force of one recording, in that order.
fn channel_pairs<'a>(
    d: &'a Prepared,
    pred: &'a Prediction,
) -> [(Option<&'a Vec<f64>>, Option<&'a Vec<f64>>); 3] {
    [
        (d.base_m.as_ref(), pred.base_m.as_ref()),
        (d.tip_m.as_ref(), pred.tip_m.as_ref()),
        (d.force_n.as_ref(), pred.force_n.as_ref()),
    ]
}

/// Appends recording − prediction of one channel (divided by `scale` when given) to `out`, 0
/// on the samples of the runs `left_out` (`[start, end)`: a sensor held at its rail, and one
/// that gave no reading).
fn push_channel(
    a: &[f64],
    b: &[f64],
    left_out: [&[(usize, usize)]; 2],
    scale: Option<f64>,
    out: &mut Vec<f64>,
) {
    let start = out.len();
    match scale {
        Some(s) => out.extend(a.iter().zip(b).map(|(x, y)| (x - y) / s)),
        None => out.extend(a.iter().zip(b).map(|(x, y)| x - y)),
    }
    let n = out.len() - start;
    for &(r0, r1) in left_out.into_iter().flatten() {
        out[start + r0.min(n)..start + r1.min(n)].fill(0.0);
    }
}

/// Sum of squares and count per channel over several recordings.
pub fn channel_rss(res: &[[Option<Vec<f64>>; 3]]) -> ([f64; 3], [usize; 3]) {
    let mut rss = [0.0; 3];
    let mut n = [0usize; 3];
    for r in res {
        for c in 0..3 {
            if let Some(v) = &r[c] {
                rss[c] += v.iter().map(|x| x * x).sum::<f64>();
                n[c] += v.len();
            }
        }
    }
    (rss, n)
}

/// The factor on the stiffness scale that keeps the first clamped natural frequency of the
/// structurally extended model (tip mass, root spring, axial load) equal to that of the plain
/// model: the structural candidates are fitted along the f1-preserving path, so that the first
/// mode's phase does not drift while their parameters move (a recalibration would absorb f1
/// anyway; what remains is their signature in frequency ratios and participation).
///
/// ω1² is close to linear in the scale g (ω1² ≈ a g − b: stiffness against an axial load, a
/// mass), so the root of ω1²(g) = ω1,plain² is found by the secant method from the
/// fixed-point step g = ω1,plain²/ω1²(1). The fixed-point iteration alone diverges once the
/// load takes more than half of the stiffness (b > a g/2; docs/diagnose.md, "Session 28").
/// A start at which the extended model buckles is doubled until it stands (at most 6 times),
/// a step onto one goes back halfway; after 12 steps the last one is returned. `None` when a model cannot be built.
pub fn f1_preserving_factor(rig: &Rig, p: &Params) -> Option<f64> {
    use crate::model::{BeamModel, ModelOptions};
    let omega1_sq = |opts: &ModelOptions| -> Option<f64> {
        let w = BeamModel::new(rig, opts)
            .ok()?
            .clamped_modes()
            .ok()?
            .omega_rad_s[0];
        (w.is_finite() && w > 0.0).then_some(w * w)
    };
    let target = omega1_sq(&ModelOptions {
        n_modes: p.n_basis.clamp(1, 12),
        stiffness_scale: p.stiffness_scale,
        ..Default::default()
    })?;
    let extended = |g: f64| {
        omega1_sq(&ModelOptions {
            n_modes: p.n_basis.clamp(1, 12),
            stiffness_scale: p.stiffness_scale * g,
            tip_mass_kg: p.tip_mass_kg,
            root_stiffness_nm_per_rad: p.root_stiffness_nm_per_rad,
            spring_position_m: p.spring_position_m,
            axial_load: p.orientation,
            tip_load_shape: p.tip_load_shape(),
            ..Default::default()
        })
        .map(|w2| w2 - target)
    };
    let mut g0 = 1.0;
    let mut e0 = extended(g0);
    for _ in 0..6 {
        if e0.is_some() {
            break;
        }
        g0 *= 2.0;
        e0 = extended(g0);
    }
    let mut e0 = e0?;
    let mut g1 = g0 * target / (e0 + target);
    for _ in 0..12 {
        // a step onto a scale where the loaded beam buckles goes back halfway to the last one
        let Some(e1) = extended(g1) else {
            g1 = 0.5 * (g0 + g1);
            continue;
        };
        if e1.abs() <= 1e-12 * target {
            return Some(g1);
        }
        let slope = (e1 - e0) / (g1 - g0);
        let next = if slope.is_finite() && slope > 0.0 {
            g1 - e1 / slope
        } else {
            g1 * target / (e1 + target)
        };
        (g0, e0, g1) = (g1, e1, next.max(0.5 * g1));
    }
    Some(g1)
}

/// The simulation parameters of `calib` + `cands` at physical `values` (calibration, then each
/// effect's, in definition order). With a structural effect (tip mass, root spring, axial
/// load) the stiffness scale applied to EI is the calibration's times the
/// [`f1_preserving_factor`]: the reported `stiffness_scale` is the plain model's.
pub fn params_of_values(rig: &Rig, calib: &Calib, cands: &[&Candidate], values: &[f64]) -> Params {
    let nc = calib.len();
    let mut p = Params::default();
    apply_calibration(calib, &values[..nc], &mut p);
    let mut off = nc;
    for c in cands {
        apply_effect(c, &values[off..off + c.params.len()], &mut p);
        off += c.params.len();
    }
    if !cands.is_empty()
        && (p.tip_mass_kg > 0.0 || p.root_stiffness_nm_per_rad.is_some() || p.orientation.is_some())
    {
        p.stiffness_scale *= f1_preserving_factor(rig, &p).unwrap_or(1.0);
    }
    p
}

/// A candidate bound to data: the least-squares problem.
pub struct Problem<'a> {
    rig: &'a Rig,
    data: &'a [Prepared],
    /// Channel noise scales σ (whitening).
    sigma: [f64; 3],
    calib: &'a Calib,
    cands: Vec<&'a Candidate>,
    x: DVector<f64>,
    caches: RefCell<Vec<Option<BeamCache>>>,
    /// Model evaluations so far.
    pub evaluations: RefCell<usize>,
    /// The first reasons the model refused a parameter set (for [`FitResult::trace`]).
    pub refusals: RefCell<Vec<String>>,
}

/// Refusals kept per problem.
const MAX_REFUSALS: usize = 5;

impl<'a> Problem<'a> {
    /// A problem over `calib` (+ the parameters of every effect in `cands`, in order) starting
    /// at representation `x0`.
    pub fn new(
        rig: &'a Rig,
        data: &'a [Prepared],
        sigma: [f64; 3],
        calib: &'a Calib,
        cands: &[&'a Candidate],
        x0: DVector<f64>,
    ) -> Self {
        Problem {
            rig,
            data,
            sigma,
            calib,
            cands: cands.to_vec(),
            x: x0,
            caches: RefCell::new(vec![None; data.len()]),
            evaluations: RefCell::new(0),
            refusals: RefCell::new(Vec::new()),
        }
    }

    /// Whitened cost Σ(r/σ)² at `x`.
    pub fn cost_at(&self, x: &DVector<f64>) -> f64 {
        self.whitened(x).norm_squared()
    }

    /// [`Problem::cost_at`] at every point of `xs`, in order ([`Problem::whitened_batch`]).
    pub fn costs_at(&self, xs: &[DVector<f64>]) -> Vec<f64> {
        self.whitened_batch(xs)
            .iter()
            .map(|r| r.norm_squared())
            .collect()
    }

    /// All parameter definitions in vector order.
    pub fn defs(&self) -> Vec<&ParamDef> {
        self.calib
            .defs
            .iter()
            .chain(self.cands.iter().flat_map(|c| c.params.iter()))
            .collect()
    }

    /// Physical parameters of representation `x`.
    pub fn params_of(&self, x: &DVector<f64>) -> Params {
        let vals: Vec<f64> = self
            .defs()
            .iter()
            .enumerate()
            .map(|(i, d)| d.value(x[i]))
            .collect();
        params_of_values(self.rig, self.calib, &self.cands, &vals)
    }

    /// Predictions for every recording at `x` (`None` if the model refuses the parameters).
    pub fn predictions(&self, x: &DVector<f64>) -> Option<Vec<Prediction>> {
        let p = self.params_of(x);
        *self.evaluations.borrow_mut() += 1;
        self.each_recording(&p, |_, pr| pr)
            .map_err(|why| self.refuse(why))
            .ok()
    }

    /// Residuals of every recorded channel divided by the channel's noise scale σ (recording
    /// after recording); a constant 1e3 where the model refuses the parameters.
    pub fn whitened(&self, x: &DVector<f64>) -> DVector<f64> {
        let total: usize = self.data.iter().map(len_of).sum();
        let p = self.params_of(x);
        *self.evaluations.borrow_mut() += 1;
        let sigma = self.sigma;
        // the first recording's vector has room for all, so only the later ones are copied
        let first = self.data.first();
        let parts = self.each_recording(&p, |d, pr| {
            let room = if first.is_some_and(|f| std::ptr::eq(f, d)) {
                total
            } else {
                len_of(d)
            };
            let mut v = Vec::with_capacity(room);
            extend_whitened(d, &pr, sigma, &mut v);
            v
        });
        let v = match parts {
            Ok(parts) => {
                let mut parts = parts.into_iter();
                let mut v = parts.next().unwrap_or_default();
                parts.for_each(|p| v.extend_from_slice(&p));
                v
            }
            Err(why) => {
                self.refuse(why);
                return DVector::from_element(total, 1e3);
            }
        };
        if v.iter().all(|e| e.is_finite()) {
            return DVector::from_vec(v);
        }
        self.refuse(format!(
            "non-finite residual: sigma {:?}, first at {:?} of {}",
            self.sigma,
            v.iter().position(|e| !e.is_finite()),
            v.len()
        ));
        DVector::from_element(total, 1e3)
    }

    /// `then` of every recording's prediction at `p`, in recording order, or why the model
    /// refused the first recording it refuses: what one after the other gives (no recording
    /// after a refused one is counted as simulated). With a spare core
    /// ([`crate::numeric::cores`]) the later half of the recordings is simulated beside, each
    /// with its own structural cache.
    fn each_recording<T: Send>(
        &self,
        p: &Params,
        then: impl Fn(&Prepared, Prediction) -> T + Sync,
    ) -> std::result::Result<Vec<T>, String> {
        let rig = self.rig;
        let run = |data: &[Prepared], caches: &mut [Option<BeamCache>]| {
            data.iter()
                .zip(caches.iter_mut())
                .map(|(d, c)| match predict(rig, p, d, c) {
                    Ok(pr) => Ok(then(d, pr)),
                    Err(e) => Err(format!("prediction failed: {e:#}")),
                })
                .collect::<std::result::Result<Vec<T>, String>>()
        };
        let mut caches = self.caches.borrow_mut();
        let core = if self.data.len() >= 2 {
            cores::take()
        } else {
            None
        };
        let Some(_core) = core else {
            return run(self.data, &mut caches);
        };
        let k = self.data.len().div_ceil(2);
        let (d1, d2) = self.data.split_at(k);
        let (c1, c2) = caches.split_at_mut(k);
        let (first, second, simulated) = beside(|| run(d1, c1), || run(d2, c2));
        let mut out = first?;
        crate::diagnose::model::add_simulated_samples(simulated);
        out.extend(second?);
        Ok(out)
    }

    /// Whitened residuals at every point of `xs`, in order: what [`Problem::whitened`] gives one
    /// after the other, to the bit. With a spare core ([`crate::numeric::cores`]) the second
    /// half runs beside on a copy of this problem (its own structural caches, which only save
    /// work), whose refusals and evaluations then join this one's after the first half's: the
    /// order one after the other gives them.
    pub fn whitened_batch(&self, xs: &[DVector<f64>]) -> Vec<DVector<f64>> {
        let core = if xs.len() >= 2 { cores::take() } else { None };
        let Some(_core) = core else {
            return xs.iter().map(|x| self.whitened(x)).collect();
        };
        let (first, second) = xs.split_at(xs.len().div_ceil(2));
        let fork = self.fork();
        let (mut mine, (theirs, fork), simulated) = beside(
            || first.iter().map(|x| self.whitened(x)).collect::<Vec<_>>(),
            move || {
                let v: Vec<DVector<f64>> = second.iter().map(|x| fork.whitened(x)).collect();
                (v, fork)
            },
        );
        crate::diagnose::model::add_simulated_samples(simulated);
        *self.evaluations.borrow_mut() += fork.evaluations.into_inner();
        for why in fork.refusals.into_inner() {
            self.refuse(why);
        }
        mine.extend(theirs);
        mine
    }

    /// A copy of this problem that shares its recordings and definitions, with the structural
    /// caches as they are now, no evaluations and no refusals.
    fn fork(&self) -> Problem<'a> {
        Problem {
            rig: self.rig,
            data: self.data,
            sigma: self.sigma,
            calib: self.calib,
            cands: self.cands.clone(),
            x: self.x.clone(),
            caches: RefCell::new(self.caches.borrow().clone()),
            evaluations: RefCell::new(0),
            refusals: RefCell::new(Vec::new()),
        }
    }

    /// Keeps the first [`MAX_REFUSALS`] reasons the model refused a parameter set.
    fn refuse(&self, why: String) {
        let mut r = self.refusals.borrow_mut();
        if r.len() < MAX_REFUSALS {
            r.push(why);
        }
    }

    /// Per parameter, whether it has no effect at and around `x`: a modal damping ratio beyond
    /// the range the model applies ([`crate::diagnose::effects::ZETA_APPLIED_RANGE`], clamped in
    /// [`crate::diagnose::effects::apply_calibration`]) by more than a finite-difference step, whose
    /// Jacobian column is therefore exactly zero (a mode the recordings carry nothing of, whose
    /// damping the calibration sent off the range). The minimiser skips evaluating those columns.
    pub(crate) fn inert_at(&self, x: &DVector<f64>) -> Vec<bool> {
        let (lo, hi) = crate::diagnose::effects::ZETA_APPLIED_RANGE;
        let margin = 1e-2;
        self.defs()
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let v = d.value(x[i]);
                d.name.starts_with("zeta_mode")
                    && (v > hi * (1.0 + margin) || v < lo * (1.0 - margin))
            })
            .collect()
    }

    /// Finite-difference steps (representation units) at the start point.
    pub(crate) fn steps(&self) -> Vec<f64> {
        self.defs()
            .iter()
            .enumerate()
            .map(|(i, d)| match d.transform {
                crate::diagnose::effects::Transform::Log => 1e-4,
                crate::diagnose::effects::Transform::Bounded(..) => 1e-3,
                crate::diagnose::effects::Transform::Linear => 1e-4 * d.scale.max(self.x[i].abs()),
            })
            .collect()
    }
}

impl Problem<'_> {
    /// Forward-difference Jacobian of the whitened residuals at `x`.
    pub fn jacobian_at(&self, x: &DVector<f64>) -> DMatrix<f64> {
        let r0 = self.whitened(x);
        let opts = LmOptions::new(self.steps());
        let batch = |xs: &[DVector<f64>]| self.whitened_batch(xs).into_iter().map(Some).collect();
        lm::fd_jacobian_batched(&batch, x, &r0, &opts)
            .expect("whitened residuals are always defined")
    }
}

/// `here()` on the calling thread and `there()` on a thread beside it, at once; also the
/// samples `there` simulated ([`crate::diagnose::model::simulated_samples`] counts per thread; the caller
/// decides what of it to count as its own). A panic beside is resumed here.
fn beside<A, B: Send>(here: impl FnOnce() -> A, there: impl FnOnce() -> B + Send) -> (A, B, u64) {
    let (a, b) = std::thread::scope(|s| {
        let other = s.spawn(|| {
            let start = crate::diagnose::model::simulated_samples();
            let b = there();
            (b, crate::diagnose::model::simulated_samples() - start)
        });
        (here(), other.join())
    });
    let (b, simulated) = b.unwrap_or_else(|e| std::panic::resume_unwind(e));
    (a, b, simulated)
}

/// Residuals of one recording: its samples × recorded channels.
fn len_of(d: &Prepared) -> usize {
    let n = d.cmd_m.len();
    n * (usize::from(d.base_m.is_some())
        + usize::from(d.tip_m.is_some())
        + usize::from(d.force_n.is_some()))
}
