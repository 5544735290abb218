//! Tests of the augmented model's blocks and of the prediction that composes them.

use crate::model::{BeamModel, ModelOptions, Rig};

use super::beam::*;
use super::discrete::*;
use super::params::*;
use super::predict::*;
use super::prepared::*;
use super::sensor::*;
use super::servo::*;

/// Position (m) at time t (s) of a move with acceleration `a` over [t0, t0 + ta], coasting,
/// then −a over [t1, t1 + ta] (steps of acceleration between samples), and its velocity.
pub(super) fn short_move(t: f64, a: f64, t0: f64, ta: f64, t1: f64) -> (f64, f64) {
    let v = a * ta;
    let (u, w) = ((t - t0).clamp(0.0, ta), (t - t1).clamp(0.0, ta));
    let pos =
        0.5 * a * u * u + v * (t - t0 - ta).max(0.0) - 0.5 * a * w * w - v * (t - t1 - ta).max(0.0);
    (pos, a * u - a * w)
}

#[test]
fn the_spline_reads_acceleration_steps_between_samples_closer_than_the_linear_path() {
    let (dt, n) = (0.02, 60);
    let mv = |t: f64| short_move(t, 2.5, 0.333, 0.047, 0.561);
    let y: Vec<f64> = (0..n).map(|k| mv(k as f64 * dt).0).collect();
    // what a drive that averages over the sample period reports: Δv / dt over [t_k, t_k+1]
    let truth: Vec<f64> = (0..n - 1)
        .map(|k| (mv((k + 1) as f64 * dt).1 - mv(k as f64 * dt).1) / dt)
        .collect();
    let lin: Vec<f64> = (0..n).map(|k| accel_at(&y, k, dt)).collect();
    let spl = spline_accel(&y, dt);
    // both read half a sample later (the force channel's latency calibration)
    let slope = |e: &[f64]| {
        let m: Vec<f64> = (0..n - 1).map(|k| 0.5 * (e[k] + e[k + 1])).collect();
        let sxy: f64 = m.iter().zip(&truth).map(|(a, b)| a * b).sum();
        let sxx: f64 = m.iter().map(|a| a * a).sum();
        sxy / sxx
    };
    let (sl, ss) = (slope(&lin), slope(&spl));
    // the mass fitted to the reported force is this slope × the true mass
    assert!(sl > 1.1, "linear path: slope {sl}");
    assert!(
        (ss - 1.0).abs() < 0.5 * (sl - 1.0),
        "spline {ss}, linear {sl}"
    );
    // a parabola through the samples is read exactly by both inside the record
    let p: Vec<f64> = (0..n)
        .map(|k| 0.5 * 3.0 * (k as f64 * dt).powi(2))
        .collect();
    let sp = spline_accel(&p, dt);
    assert!(
        sp[10..n - 10].iter().all(|x| (x - 3.0).abs() < 1e-4),
        "{sp:?}"
    );
}

#[test]
fn a_sensor_on_the_carriage_scales_the_deflection_and_a_fixed_one_the_whole_reading() {
    let dt = 0.01;
    let root: Vec<f64> = (0..200).map(|k| 0.3 * (k as f64 * dt).min(1.0)).collect();
    let w: Vec<f64> = (0..200)
        .map(|k| 0.004 * (9.0 * k as f64 * dt).sin())
        .collect();
    let p = Params::default();
    let plain = tip_sensor(&p, &root, &w, dt);
    let deflection = tip_sensor(
        &Params {
            sensor_deflection_gain_error: -0.03,
            ..p.clone()
        },
        &root,
        &w,
        dt,
    );
    let whole = tip_sensor(
        &Params {
            sensor_gain_error: -0.03,
            ..p.clone()
        },
        &root,
        &w,
        dt,
    );
    for k in 0..200 {
        assert!((deflection[k] - (root[k] + 0.97 * w[k])).abs() < 1e-15);
        assert!((whole[k] - 0.97 * plain[k]).abs() < 1e-15);
    }
    // at rest after the move the fixed sensor misreads the 0.3 m travel by 9 mm; the
    // carriage's sees it exactly
    assert!((whole[150] - root[150] - 0.97 * w[150]).abs() > 8e-3);
}

#[test]
fn a_first_order_loop_with_full_velocity_feed_forward_is_the_command() {
    // the identity start of the base-motion alternative (honesty::identity_servo)
    let dt = 0.01;
    let r: Vec<f64> = (0..500).map(|k| (k as f64 * dt).sin() * 0.1).collect();
    for omega in [1.0, 50.0, 400.0] {
        let y = first_order(&r, dt, omega, 1.0);
        assert!(y.iter().zip(&r).all(|(a, b)| (a - b).abs() < 1e-12));
    }
    let lag = first_order(&r, dt, 5.0, 0.0);
    assert!(lag.iter().zip(&r).any(|(a, b)| (a - b).abs() > 1e-3));
}
use crate::model::sim::BaseMotionSim;

pub(super) fn rig() -> Rig {
    Rig::from_toml_str(
        "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\nstations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 }, { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]\n[base]\nmass_kg = 2.5\n",
    )
    .unwrap()
}

pub(super) fn move_rec_at(rate: f64) -> crate::recording::Recording {
    let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, rate, 5.0).unwrap();
    let mut r = crate::recording::Recording::with_uniform_time(y.len(), rate);
    r.base_cmd_m = Some(y.clone());
    r.tip_pos_m = Some(y.clone());
    r.force_n = Some(vec![0.0; y.len()]);
    r
}

pub(super) fn move_rec() -> crate::recording::Recording {
    move_rec_at(100.0)
}

#[test]
fn a_mode_between_the_band_edge_and_nyquist_is_simulated_and_no_parameter_moves_it_out() {
    let rig = rig();
    let f = converged_basis(&rig, 1.0, 1e3, 1e3).unwrap().freqs_hz;
    // sampled so that mode 2 lies at 0.475 × the sample rate: above the band edge (0.45),
    // below Nyquist (0.5)
    let rate = f[1] / 0.475;
    let b = converged_basis(&rig, 1.0, band_edge_hz(1.0 / rate), 0.5 * rate).unwrap();
    assert_eq!(b.freqs_hz.len(), 1, "{b:?}");
    assert_eq!(b.simulated_modes, 2, "{b:?}");
    let dt = 1.0 / rate;
    let count = |scale: f64, fixed: Option<usize>| {
        let p = Params {
            stiffness_scale: scale,
            n_basis: b.n_basis,
            simulated_modes: fixed,
            ..Params::default()
        };
        beam_cache(&rig, &p, dt).unwrap().omega.len()
    };
    // by the band edge alone, a 20 % softer beam gains mode 2: a cliff a fitted parameter
    // can cross
    assert_eq!((count(1.0, None), count(0.8, None)), (1, 2));
    // the diagnosis's fixed count keeps it at every scale
    for scale in [0.8, 0.9, 1.0, 1.1, 1.2] {
        assert_eq!(count(scale, Some(b.simulated_modes)), 2, "scale {scale}");
    }
}

#[test]
fn a_tip_mass_moves_a_uniform_beams_frequencies_by_twice_its_mass_ratio() {
    // uniform cantilever: every mass-normalised mode has |φ_r(L)|² = 4/M, so to first order
    // a tip mass Δm lowers every f_r by 2 Δm/M (Rayleigh quotient)
    let rig = rig();
    let beam_mass_kg = 0.9 * 0.025 * 0.00115 * 8190.0;
    let dt = 0.002;
    let p0 = Params {
        n_basis: 8,
        ..Params::default()
    };
    for ratio in [1e-4, 1e-3, 0.01] {
        let p = Params {
            tip_mass_kg: ratio * beam_mass_kg,
            ..p0.clone()
        };
        let shift = frequency_shift_rel(&rig, &p, &p0, dt).unwrap();
        assert!(
            (shift / (2.0 * ratio) - 1.0).abs() < 0.1,
            "{ratio}: {shift}"
        );
    }
    let tiny = Params {
        tip_mass_kg: 1e-4 * beam_mass_kg,
        ..p0.clone()
    };
    assert!(frequency_shift_rel(&rig, &tiny, &p0, dt).unwrap() < BASIS_CONVERGENCE_REL);
    // a root spring lowering f1 by 5 %
    let spring = Params {
        root_stiffness_nm_per_rad: Some(6.0),
        ..p0.clone()
    };
    let s = frequency_shift_rel(&rig, &spring, &p0, dt).unwrap();
    assert!(s > 10.0 * BASIS_CONVERGENCE_REL, "{s}");
    // no beam: no frequencies
    let carriage = Rig::from_toml_str("[base]\nmass_kg = 2.5\n").unwrap();
    assert!(frequency_shift_rel(&carriage, &spring, &p0, dt).is_none());
}

#[test]
fn a_cubic_clamp_shifts_the_frequencies_with_amplitude_up_to_a_rigid_clamp() {
    let (rig, dt) = (rig(), 0.002);
    let p0 = Params {
        n_basis: 8,
        ..Params::default()
    };
    // a root spring lowering f1 by 5 %, hardening by k₃
    let clamp = |k3: f64| Params {
        root_stiffness_nm_per_rad: Some(6.0),
        cubic_root_stiffness_nm_per_rad3: k3,
        ..p0.clone()
    };
    // the rigid clamp's frequencies against the linear spring's
    let rigid_shift = frequency_shift_rel(&rig, &p0, &clamp(0.0), dt).unwrap();
    let shift = |k3: f64, peak_m: f64| cubic_frequency_shift_rel(&rig, &clamp(k3), dt, peak_m);
    // no cubic term: no amplitude dependence
    assert!(shift(0.0, 0.05).unwrap() < 1e-12);
    // hardening: grows with the amplitude, quadratically while small, and never beyond the
    // shift of the linear spring itself (a clamp that turns rigid)
    let k3 = 1e5;
    let (s1, s2, s_big) = (
        shift(k3, 1e-3).unwrap(),
        shift(k3, 2e-3).unwrap(),
        shift(k3, 1.0).unwrap(),
    );
    assert!(s1 > 0.0 && (s2 / s1 - 4.0).abs() < 0.2, "{s1} {s2}");
    assert!(
        s_big <= rigid_shift && s_big > 0.9 * rigid_shift,
        "{s_big} vs {rigid_shift}"
    );
    // a clamp that softens to nothing at the peak: unbounded
    assert_eq!(shift(-1e5, 1.0), Some(f64::INFINITY));
    // small motion of a weakly cubic clamp: within the model's accuracy
    assert!(shift(1.0, 0.01).unwrap() < BASIS_CONVERGENCE_REL);
    // a rigid clamp has no cubic term to judge
    assert!(cubic_frequency_shift_rel(&rig, &p0, dt, 0.05).is_none());
}

#[test]
fn the_smooth_alternative_reads_a_drive_at_its_own_rate_band_limited() {
    // a 10 Hz sine base at 100 Hz: the piecewise-linear path through its samples forces the
    // beam with sinc²(0.1) = 0.968 of it, the band-limited reading with all of it, so the
    // tip deflection's 10 Hz amplitude rises by 1/sinc²(0.1) = 1.033; a decimated drive
    // (already emphasised) is left alone
    let rig = rig();
    let d = sine_drive(100.0, 10.0);
    let smooth = Params {
        smooth_drive: true,
        ..Params::default()
    };
    let ratio =
        tip_amplitude(&rig, &smooth, &d, 10.0) / tip_amplitude(&rig, &Params::default(), &d, 10.0);
    let sinc = (0.1 * std::f64::consts::PI).sin() / (0.1 * std::f64::consts::PI);
    assert!((ratio * sinc * sinc - 1.0).abs() < 3e-3, "{ratio}");
    let decimated = crate::diagnose::rate::decimate_prepared(&d, 2);
    let same = tip_amplitude(&rig, &smooth, &decimated, 10.0)
        / tip_amplitude(&rig, &Params::default(), &decimated, 10.0);
    assert!((same - 1.0).abs() < 1e-12, "{same}");
}

#[test]
fn the_fourth_order_reading_forces_the_beam_with_its_stencils_gain() {
    // a 20 Hz sine base at 100 Hz: the three-tap emphasis x − δ²x/12 raises the forcing
    // by 1 + sin²(0.2π)/3 = 1.115 over the piecewise-linear reading (sinc²(0.2) = 0.875
    // of the motion → 0.976); a decimated drive (already emphasised) is left alone
    let taps = crate::diagnose::rate::emphasis_taps_of(FOURTH_ORDER_HALF);
    for (t, want) in taps.iter().zip([-1.0 / 12.0, 7.0 / 6.0, -1.0 / 12.0]) {
        assert!((t - want).abs() < 1e-12, "{taps:?}");
    }
    let rig = rig();
    let d = sine_drive(100.0, 20.0);
    let fourth = Params {
        drive_reading: DriveReading::FourthOrder,
        ..Params::default()
    };
    let ratio =
        tip_amplitude(&rig, &fourth, &d, 20.0) / tip_amplitude(&rig, &Params::default(), &d, 20.0);
    let gain = 1.0 + (0.2 * std::f64::consts::PI).sin().powi(2) / 3.0;
    assert!((ratio / gain - 1.0).abs() < 3e-3, "{ratio} against {gain}");
    let decimated = crate::diagnose::rate::decimate_prepared(&d, 2);
    let same = tip_amplitude(&rig, &fourth, &decimated, 20.0)
        / tip_amplitude(&rig, &Params::default(), &decimated, 20.0);
    assert!((same - 1.0).abs() < 1e-12, "{same}");
}

#[test]
fn a_loops_peak_gain_is_its_resonance() {
    let law = |order, zeta, ff, integral_ratio, force_lag_ratio| ServoLaw {
        order,
        omega: 2.0 * std::f64::consts::PI * 10.0,
        zeta,
        ff,
        integral_ratio,
        force_lag_ratio,
    };
    // the plain second-order loop: 1 / (2ζ√(1 − ζ²)) at ζ = 0.3
    let z = 0.3f64;
    let want = 1.0 / (2.0 * z * (1.0 - z * z).sqrt());
    assert!((law(2, z, (0.0, 0.0), 0.0, 0.0).peak_gain() / want - 1.0).abs() < 1e-3);
    // a first-order lag never exceeds 1; a tuned PID with full feed-forward stays near 1
    assert!(law(1, 0.7, (0.5, 0.0), 0.0, 0.0).peak_gain() <= 1.0 + 1e-12);
    assert!(law(4, 0.7, (1.0, 1.0), 0.3, 0.1).peak_gain() < 1.3);
    // session 18's fitted "loop" at a loose tip sensor (bandwidth 5.09 Hz): 18 ×
    let odd = ServoLaw {
        omega: 2.0 * std::f64::consts::PI * 5.0911,
        ..law(4, 0.6748, (0.8832, 0.0060), 0.2756, 0.9437)
    };
    assert!((odd.peak_gain() - 18.04).abs() < 0.1, "{}", odd.peak_gain());
}

/// A base commanded along a sine of `f_hz` (1 cm, raised-cosine onset over 2 s: no
/// start-up transient), 8 s at `rate` Hz, its tip recorded.
pub(super) fn sine_drive(rate: f64, f_hz: f64) -> Prepared {
    let n = (8.0 * rate) as usize;
    let mut rec = crate::recording::Recording::with_uniform_time(n, rate);
    let y: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 / rate;
            let onset = 0.5 - 0.5 * (std::f64::consts::PI * (t / 2.0).min(1.0)).cos();
            0.01 * onset * (2.0 * std::f64::consts::PI * f_hz * t).sin()
        })
        .collect();
    rec.base_cmd_m = Some(y.clone());
    rec.tip_pos_m = Some(y);
    Prepared::new("t", &rec).unwrap()
}

/// Amplitude (m) at `f_hz` of the predicted tip deflection after the first 3 s.
pub(super) fn tip_amplitude(rig: &Rig, p: &Params, d: &Prepared, f_hz: f64) -> f64 {
    let two_pi_f = 2.0 * std::f64::consts::PI * f_hz;
    let tip = predict(rig, p, d, &mut None).unwrap().tip_m.unwrap();
    let (mut c, mut s) = (0.0, 0.0);
    let from = (3.0 / d.dt) as usize;
    for k in from..tip.len() {
        let (w, t) = (tip[k] - d.cmd_as_sampled()[k], k as f64 * d.dt);
        c += w * (two_pi_f * t).cos();
        s += w * (two_pi_f * t).sin();
    }
    c.hypot(s)
}

#[test]
fn a_shift_common_to_every_mode_is_the_stiffness_scales() {
    let rig = rig();
    let dt = 0.01; // modes 1-3 of this beam below the 45 Hz band edge
    let p0 = Params {
        n_basis: 8,
        ..Params::default()
    };
    // a stiffer beam: every mode up by √1.1 − 1 = 4.9 %, nothing beyond the scale
    let stiffer = Params {
        stiffness_scale: 1.1,
        ..p0.clone()
    };
    assert!(frequency_shift_rel(&rig, &stiffer, &p0, dt).unwrap() > 0.04);
    assert!(frequency_shift_beyond_scale_rel(&rig, &stiffer, &p0, dt).unwrap() < 1e-9);
    // a root spring lowering f1 by ≈ 5 % changes the ratios by more than the model's accuracy
    let spring = Params {
        root_stiffness_nm_per_rad: Some(6.0),
        ..p0.clone()
    };
    let beyond = frequency_shift_beyond_scale_rel(&rig, &spring, &p0, dt).unwrap();
    assert!(beyond > BASIS_CONVERGENCE_REL, "{beyond}");
    assert!(beyond < frequency_shift_rel(&rig, &spring, &p0, dt).unwrap());
    // one mode in band: nothing to compare it with, the plain shift
    let one = 1.0 / 6.0;
    let single = frequency_shift_beyond_scale_rel(&rig, &stiffer, &p0, one).unwrap();
    assert!((single - 1.1f64.sqrt().ln()).abs() < 1e-9, "{single}");
}

#[test]
fn a_rung_down_model_rests_at_exact_zero_never_subnormal() {
    // heavily damped modes, a mount and a PID loop at 1 kHz: seconds after the move every
    // state has decayed by far more than 10^308; held at rest below 1e-200, the deflection
    // is exactly zero and no channel holds a subnormal number (each costs ~100 cycles)
    // a 0.3 m strip: mode 1 at 10 Hz, rung down by 10^-300 within 10 s at ζ 0.95
    let rig = Rig::from_toml_str(
        "[beam]\nlength_m = 0.3\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\nstations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 }, { x_m = 0.3, width_m = 0.025, thickness_m = 0.00115 } ]\n[base]\nmass_kg = 2.5\n",
    )
    .unwrap();
    let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, 1000.0, 14.0).unwrap();
    let mut rec = crate::recording::Recording::with_uniform_time(y.len(), 1000.0);
    rec.base_cmd_m = Some(y.clone());
    rec.tip_pos_m = Some(y.clone());
    rec.force_n = Some(vec![0.0; y.len()]);
    let d = Prepared::new("t", &rec).unwrap();
    let damped = Params {
        zeta_modes: Some(vec![0.9; 12]),
        ..Params::default()
    };
    let mounted = Params {
        mount: Some((40.0, 0.9)),
        mount_mass_kg: 0.2,
        servo: Some((20.0, 0.9)),
        servo_order: 3,
        servo_integral_ratio: 0.5,
        ..damped.clone()
    };
    let filtered = Params {
        mount: Some((40.0, 0.9)),
        servo: Some((20.0, 0.9)),
        servo_order: 1,
        ..damped.clone()
    };
    for p in [&damped, &mounted, &filtered] {
        let pred = predict(&rig, p, &d, &mut None).unwrap();
        let (tip, force) = (pred.tip_m.unwrap(), pred.force_n.unwrap());
        assert!(tip.iter().chain(&force).all(|v| !v.is_subnormal()), "{p:?}");
    }
    // the modes of the plain beam: exactly at rest, the tip exactly on the carriage
    let pred = predict(&rig, &damped, &d, &mut None).unwrap();
    let end = d.cmd_m.len() - 1;
    assert_eq!(pred.tip_m.unwrap()[end], d.cmd_m[end]);
    assert_eq!(pred.force_n.unwrap()[end], 0.0);
}

#[test]
fn nominal_matches_the_model_simulator() {
    // at 1 kHz every model mode is below Nyquist and kept: the tip identical to
    // `model::sim`; the force its instantaneous force averaged over the sample period
    // centred on the sample (the same piecewise-linear drive integrated 100 times finer)
    let rig = rig();
    let rec = move_rec_at(1000.0);
    let d = Prepared::new("t", &rec).unwrap();
    let p = Params::default();
    let pred = predict(&rig, &p, &d, &mut None).unwrap();
    let model = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
    let sim = BaseMotionSim::new(&model, 0.001).unwrap();
    let (w, u) = sim.run(&d.cmd_m);
    let sub = 100;
    let fine: Vec<f64> = (0..(d.cmd_m.len() - 1) * sub)
        .map(|i| {
            let (k, a) = (i / sub, (i % sub) as f64 / sub as f64);
            d.cmd_m[k] + a * (d.cmd_m[k + 1] - d.cmd_m[k])
        })
        .collect();
    let (_, u_fine) = BaseMotionSim::new(&model, 0.001 / sub as f64)
        .unwrap()
        .run(&fine);
    let force = pred.force_n.as_ref().unwrap();
    let peak = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut worst_mean, mut worst_instant) = (0.0f64, 0.0f64);
    for k in 0..w.len() {
        assert!((pred.tip_m.as_ref().unwrap()[k] - d.cmd_m[k] - w[k]).abs() < 1e-9);
        if k >= 1 && k + 2 < w.len() {
            let mean = (k * sub - sub / 2..k * sub + sub / 2)
                .map(|i| u_fine[i])
                .sum::<f64>()
                / sub as f64;
            worst_mean = worst_mean.max((force[k] - mean).abs());
            worst_instant = worst_instant.max((force[k] - u[k]).abs());
        }
    }
    assert!(worst_mean < 2e-3 * peak, "{worst_mean} of {peak}");
    // the instantaneous force differs by more (the beam's modes at 1 kHz)
    assert!(
        worst_instant > 3.0 * worst_mean,
        "{worst_instant} vs {worst_mean}"
    );
}

#[test]
fn a_recording_started_while_the_beam_rings_is_predicted_with_its_free_response() {
    // the move recorded from 0.2 s after its end: the beam rings, the carriage rests
    let rig = rig();
    let full = Prepared::new("t", &move_rec_at(100.0)).unwrap();
    let truth = predict(&rig, &Params::default(), &full, &mut None).unwrap();
    let end = full
        .cmd_m
        .iter()
        .rposition(|c| *c != full.cmd_m[full.cmd_m.len() - 1]);
    let k0 = end.unwrap() + 20;
    let mut late = crate::recording::Recording::with_uniform_time(full.cmd_m.len() - k0, 100.0);
    late.base_cmd_m = Some(full.cmd_m[k0..].to_vec());
    late.tip_pos_m = Some(truth.tip_m.as_ref().unwrap()[k0..].to_vec());
    late.force_n = Some(truth.force_n.as_ref().unwrap()[k0..].to_vec());
    let mut d = Prepared::new("late", &late).unwrap();
    let rms_of = |d: &Prepared| {
        let p = predict(&rig, &Params::default(), d, &mut None).unwrap();
        let rms = |a: &[f64], b: &[f64]| {
            (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt()
        };
        (
            rms(p.tip_m.as_ref().unwrap(), d.tip_m.as_ref().unwrap()),
            rms(p.force_n.as_ref().unwrap(), d.force_n.as_ref().unwrap()),
        )
    };
    let at_rest = rms_of(&d);
    d.free_start = true;
    let free = rms_of(&d);
    // from rest the model sees no ring at all; with the free response, all of it
    assert!(at_rest.0 > 1e-3 && at_rest.1 > 1e-2, "{at_rest:?}");
    // (measured 1.2e-13 m and 7e-13 N against 0.042 m and 0.18 N)
    assert!(
        free.0 < 1e-9 * at_rest.0 && free.1 < 1e-9 * at_rest.1,
        "{free:?} vs {at_rest:?}"
    );
}
