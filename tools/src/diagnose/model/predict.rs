//! The prediction of one recording ([`predict`]): composes the blocks of the chain (servo,
//! drive, backlash and mount, beam, tip sensor, carriage forces) into the predicted channels
//! ([`Prediction`]), and counts the samples simulated ([`simulated_samples`]). Step 2 of the
//! chain lives here: the beam is driven by the *measured* base position when recorded (so
//! carriage effects do not leak into the tip channel), else by the predicted one ([`drives`]).

use super::beam::{beam_cache, structural_key, BeamCache};
use super::beam_response::beam_response;
use super::carriage::{carriage_forces, CarriageLoad};
use super::discrete::{accel_at, spline_accel};
use super::mount::root_motion;
use super::params::{DriveReading, Params, FOURTH_ORDER_HALF};
use super::prepared::Prepared;
use super::sensor::tip_sensor;
use super::servo::ServoLaw;
use crate::model::Rig;
use anyhow::{bail, Result};

/// Predicted channels (present where the recording has them).
#[derive(Clone, Debug, Default)]
pub struct Prediction {
    /// Base position (m).
    pub base_m: Option<Vec<f64>>,
    /// Absolute tip position (m).
    pub tip_m: Option<Vec<f64>>,
    /// Motor force (N).
    pub force_n: Option<Vec<f64>>,
}

thread_local! {
    /// Samples simulated by [`predict`] on this thread (every recording, every call).
    static SIMULATED_SAMPLES: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Samples [`predict`] has simulated on the calling thread so far: the work a diagnosis has
/// done, counted in the budget's unit (one diagnosis runs on one thread and counts what a
/// helper thread simulated for it, [`add_simulated_samples`]; [`crate::diagnose::selection::Budget`]).
pub fn simulated_samples() -> u64 {
    SIMULATED_SAMPLES.with(|c| c.get())
}

/// Counts `n` samples simulated for the calling thread by a helper thread
/// ([`crate::diagnose::fit::Problem::whitened_batch`]).
pub fn add_simulated_samples(n: u64) {
    SIMULATED_SAMPLES.with(|c| c.set(c.get() + n));
}

/// Predicts the channels of `d` with parameters `p`. `cache` keeps the last structural model.
///
/// Errors: a structural parameter set the model refuses (e.g. buckling), a rig without a beam
/// when the recording has a tip channel.
pub fn predict(
    rig: &Rig,
    p: &Params,
    d: &Prepared,
    cache: &mut Option<BeamCache>,
) -> Result<Prediction> {
    let dt = d.dt;
    SIMULATED_SAMPLES.with(|n| n.set(n.get() + d.cmd_m.len() as u64));
    let mut out = Prediction::default();
    let c = match rig.beam {
        Some(_) => Some(fresh_cache(rig, p, dt, cache)?),
        None => None,
    };
    // 1. servo: the beam pushes the carriage back, so the loop is simulated coupled to its modes
    // whether or not the base is recorded (a measured one still drives the beam below; the
    // predicted `base_pos_m` then holds the beam's reaction in its following error), and so
    // do friction and cogging, which the loop must overcome
    let law = ServoLaw::of(p);
    let y_servo: std::borrow::Cow<[f64]> = match &law {
        Some(law) => std::borrow::Cow::Owned(loaded_servo(rig, p, d, c, law)),
        None => std::borrow::Cow::Borrowed(&d.cmd_m),
    };
    // 2. drive: the measured base when recorded; emphasised for the dynamics, as sampled for
    // positions
    let drives = drives(d, &law, &y_servo, p.smooth_drive, p.drive_reading);
    let (drive, drive_pos): (&[f64], &[f64]) = (&drives.0, &drives.1);
    // 3. backlash and mount between the drive and the beam root
    let (root, exact) = root_motion(p, drive, dt, c);
    // 4. beam, tip sensor and motor force (those of a coupled mount from its exact state
    // unless drag or a cubic clamp act on the modes)
    let force = match c {
        Some(c) => {
            let linear = !p.has_drag()
                && (p.root_stiffness_nm_per_rad.is_none()
                    || p.cubic_root_stiffness_nm_per_rad3 == 0.0);
            let (w, force) = match exact.filter(|_| linear) {
                Some(m) => {
                    let carriage = c.base_mass - p.mount_mass_kg;
                    let force = (0..drive.len())
                        .map(|k| carriage * accel_at(drive, k, dt) + m.force[k])
                        .collect();
                    (m.tip_w, force)
                }
                None => beam_response(p, &root, drive, dt, c),
            };
            if d.tip_m.is_some() {
                let root_pos: Vec<f64> = (0..root.len())
                    .map(|k| root[k] + drive_pos[k] - drive[k])
                    .collect();
                out.tip_m = Some(tip_sensor(p, &root_pos, &w, dt));
            }
            force
        }
        None => {
            if d.tip_m.is_some() {
                bail!(
                    "{}: the recording has `tip_pos_m` but the rig has no [beam]",
                    d.name
                );
            }
            let m = rig.base.mass_kg + p.base_mass_delta_kg;
            (0..drive.len())
                .map(|k| m * accel_at(drive, k, dt))
                .collect()
        }
    };
    // 5. carriage forces and the force channel's latency
    if d.force_n.is_some() {
        let force = smooth_drive_of(p, rig, c, force, (drive, drive_pos), dt);
        out.force_n = Some(carriage_forces(p, drive_pos, force, dt));
    }
    // 6. the predicted base, once the drives that may borrow the servo's output are done
    drop(drives);
    out.base_m = predicted_base(d, law.is_some(), y_servo);
    if let (true, Some(c)) = (d.free_start, c) {
        add_free_response(d, c, p.mount, &mut out);
    }
    Ok(out)
}

/// The base position of `d` under the position loop `law` of `p`, carrying the carriage load of
/// `p` ([`CarriageLoad`]: in N with the beam of `c`, per unit moving mass without one).
fn loaded_servo(
    rig: &Rig,
    p: &Params,
    d: &Prepared,
    c: Option<&BeamCache>,
    law: &ServoLaw,
) -> Vec<f64> {
    let load = CarriageLoad::of(p).map(|l| match c {
        Some(_) => l,
        None => l.per_unit_mass(rig.base.mass_kg + p.base_mass_delta_kg),
    });
    law.respond(&d.cmd_m, d.dt, c, load.as_ref())
}

/// The predicted `base_pos_m` of `d` (`None` when it is not recorded): the servo's output
/// `y_servo` (moved, not copied), or without a servo (`servo` false) the command as sampled.
fn predicted_base(d: &Prepared, servo: bool, y_servo: std::borrow::Cow<[f64]>) -> Option<Vec<f64>> {
    d.base_m.as_ref()?;
    Some(match (servo, &d.cmd_identity_m) {
        (false, Some(cmd)) => cmd.clone(),
        _ => y_servo.into_owned(),
    })
}

/// Adds to the predicted tip and force of a recording that does not start at rest the free
/// response of the beam's modes from the state it was in at the first sample, which nothing
/// recorded tells: each mode r rings from there as `e^{−ζ_r ω_r t} (a cos ω_dr t + b sin ω_dr t)`
/// (ω_dr = ω_r √(1 − ζ_r²)) in the tip and, as its modal acceleration, in the force (eq. 5's
/// `hᵀ q̈`: the same two functions); so does a mount's resonance (`mount`: Hz, damping ratio),
/// its frequency as the candidate states it. The 2 coefficients per mode below 0.8 × Nyquist are least
/// squares on the channel's residual, samples at a sensor's rail left out — the initial state
/// estimated as a nuisance, per recording and per channel, at every parameter set (variable
/// projection). The same mend as a fit of the initial conditions, without the 4R parameters
/// in the Levenberg–Marquardt problem.
fn add_free_response(d: &Prepared, c: &BeamCache, mount: Option<(f64, f64)>, out: &mut Prediction) {
    use nalgebra::{DMatrix, DVector};
    let nyquist = std::f64::consts::PI / d.dt;
    let mount = mount.map(|(f_hz, z)| (2.0 * std::f64::consts::PI * f_hz, z));
    let modes: Vec<(f64, f64)> = c
        .omega
        .iter()
        .copied()
        .zip(c.zeta.iter().copied())
        .chain(mount)
        .filter(|(w, z)| *w < 0.8 * nyquist && *z < 1.0)
        .collect();
    for (measured, predicted, rails, gaps) in [
        (&d.tip_m, &mut out.tip_m, &d.rails[1], &d.gaps[1]),
        (&d.force_n, &mut out.force_n, &d.rails[2], &d.gaps[2]),
    ] {
        let (Some(m), Some(p)) = (measured, predicted.as_mut()) else {
            continue;
        };
        let n = m.len().min(p.len());
        if modes.is_empty() || n < 4 * modes.len() {
            continue;
        }
        // e^{(−ζω + iω_d) k dt} by recurrence: one complex product per sample and mode
        let mut basis = DMatrix::zeros(n, 2 * modes.len());
        for (r, &(w, z)) in modes.iter().enumerate() {
            let step = nalgebra::Complex::from_polar(
                (-z * w * d.dt).exp(),
                w * (1.0 - z * z).sqrt() * d.dt,
            );
            let mut e = nalgebra::Complex::new(1.0, 0.0);
            for k in 0..n {
                basis[(k, 2 * r)] = e.re;
                basis[(k, 2 * r + 1)] = e.im;
                e *= step;
            }
        }
        let mut fitted = basis.clone();
        let mut r = DVector::from_fn(n, |k, _| m[k] - p[k]);
        for &(s, e) in rails.runs.iter().chain(&gaps.runs) {
            for k in s.min(n)..e.min(n) {
                r[k] = 0.0;
                fitted.row_mut(k).fill(0.0);
            }
        }
        let gram = fitted.tr_mul(&fitted);
        let ridge = 1e-12 * gram.trace().max(f64::MIN_POSITIVE);
        let size = gram.nrows();
        let gram = gram + DMatrix::identity(size, size) * ridge;
        let Some(ch) = gram.cholesky() else {
            continue;
        };
        let coef = ch.solve(&fitted.tr_mul(&r));
        let free = &basis * coef;
        if free.iter().all(|v| v.is_finite()) {
            p.iter_mut().zip(free.iter()).for_each(|(p, f)| *p += f);
        }
    }
}

/// The motor force `force` (N, one per sample) of the model's drive, or, when `p.smooth_drive`
/// asks for the drive-interpolation alternative, that of the cubic spline through the drive's
/// samples *as recorded* ([`smooth_drive_force`]) for the carriage's mass. `drives` is (the
/// model's input, the drive as sampled) of [`drives`]: the spline reads the samples, not the
/// emphasised input (which already undoes the linear path's sinc² loss up to 0.3 × the rate;
/// a spline through it would boost twice).
fn smooth_drive_of(
    p: &Params,
    rig: &Rig,
    c: Option<&BeamCache>,
    force: Vec<f64>,
    drives: (&[f64], &[f64]),
    dt: f64,
) -> Vec<f64> {
    if !p.smooth_drive {
        return force;
    }
    let carriage = match c {
        Some(c) if p.mount.is_some() => c.base_mass - p.mount_mass_kg,
        Some(c) => c.base_mass,
        None => rig.base.mass_kg + p.base_mass_delta_kg,
    };
    smooth_drive_force(force, carriage, drives, dt)
}

/// The drive of the beam root and carriage as (the model's input, the base position at the
/// samples). When `d`'s inputs are [emphasised](crate::diagnose::rate::emphasise) against the model's
/// piecewise-linear treatment of them (`cmd_identity_m` set), the input is the emphasised
/// signal — so the beam's forcing and the carriage's second difference carry the motion's
/// content at its true amplitude up to 0.3 × the rate instead of sinc²(f/r) of it — while the
/// absolute tip and the carriage's position-dependent forces take the base as sampled: the
/// emphasis changes sample values by (1/sinc² − 1) of the content (0.8 % at 0.05 × the rate,
/// millimetres of a 50 Hz move). A servo loop's output is the base at the samples (its
/// integration is exact for the emphasised command), emphasised in turn as a drive.
///
/// `bandlimited` (the smooth-drive alternative, [`Params::smooth_drive`]) emphasises a drive
/// taken at the recording's own rate as well: the band-limited path through the samples
/// instead of the piecewise-linear one. Only the 1-σ's model-form alternative uses it: as the
/// model's own reading it let backlash feed on the boosted encoder content of two independent
/// cases (docs/diagnose.md, session 15).
///
/// `reading` [`DriveReading::FourthOrder`] (and not `bandlimited`) emphasises a drive at the
/// recording's own rate by the three-tap filter of that reading; the positions stay as sampled.
fn drives<'a>(
    d: &'a Prepared,
    law: &Option<ServoLaw>,
    y_servo: &'a [f64],
    bandlimited: bool,
    reading: DriveReading,
) -> (std::borrow::Cow<'a, [f64]>, std::borrow::Cow<'a, [f64]>) {
    use crate::diagnose::rate::{emphasise, emphasise_of};
    use std::borrow::Cow;
    let emphasised = d.cmd_identity_m.is_some();
    if reading == DriveReading::FourthOrder && !emphasised && !bandlimited {
        let own: &[f64] = match &d.drive_m {
            Some(m) => m,
            None => y_servo,
        };
        return (
            Cow::Owned(emphasise_of(own, FOURTH_ORDER_HALF)),
            Cow::Borrowed(own),
        );
    }
    match (&d.drive_m, law) {
        (Some(m), _) => match &d.drive_identity_m {
            None if bandlimited => (Cow::Owned(emphasise(m)), Cow::Borrowed(m.as_slice())),
            sampled => (
                Cow::Borrowed(m.as_slice()),
                Cow::Borrowed(sampled.as_deref().unwrap_or(m)),
            ),
        },
        (None, None) if bandlimited && !emphasised => {
            (Cow::Owned(emphasise(y_servo)), Cow::Borrowed(y_servo))
        }
        (None, None) => (
            Cow::Borrowed(y_servo),
            Cow::Borrowed(d.cmd_identity_m.as_deref().unwrap_or(y_servo)),
        ),
        (None, Some(_)) if emphasised || bandlimited => {
            (Cow::Owned(emphasise(y_servo)), Cow::Borrowed(y_servo))
        }
        (None, Some(_)) => (Cow::Borrowed(y_servo), Cow::Borrowed(y_servo)),
    }
}

/// The structural model of `p`, rebuilt only when a structural parameter changed.
fn fresh_cache<'c>(
    rig: &Rig,
    p: &Params,
    dt: f64,
    cache: &'c mut Option<BeamCache>,
) -> Result<&'c BeamCache> {
    let stale = cache
        .as_ref()
        .map_or(true, |c| c.key != structural_key(p, dt));
    if stale {
        *cache = Some(beam_cache(rig, p, dt)?);
    }
    Ok(cache.as_ref().expect("cache just built"))
}

/// `force` (N) with the carriage's (`carriage_kg`) acceleration read from the cubic spline
/// through the drive's samples as recorded (`drives.1`) instead of the model's own, the
/// piecewise-linear path of its input `drives.0` ([`Params::smooth_drive`]):
/// `force + m (a_spline − a_model)` at every sample.
fn smooth_drive_force(
    mut force: Vec<f64>,
    carriage_kg: f64,
    drives: (&[f64], &[f64]),
    dt: f64,
) -> Vec<f64> {
    let (model, sampled) = drives;
    let smooth = spline_accel(sampled, dt);
    for (k, f) in force.iter_mut().enumerate() {
        *f += carriage_kg * (smooth[k] - accel_at(model, k, dt));
    }
    force
}
