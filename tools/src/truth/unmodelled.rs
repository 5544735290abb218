//! Physics outside the diagnosis catalogue, for the widened proof (issue 10): the diagnosis has
//! no candidate for any of these, so the right answer is an `unexplained` residual (located),
//! never a catalogue name. Off by default (`TruthOptions::unmodelled = None`).
//!
//! - [`Unmodelled::Crack`]: a local bending-stiffness loss in one FE element between 0.35 and
//!   0.6 of the length (a fatigue crack or a notch; the cracked-element model of Dimarogonas,
//!   *Eng. Fract. Mech.* 55 (1996), reduced to a uniform EI loss over one element). The loss is
//!   drawn so that f1 drops by 3–8 %; a stiffness recalibration absorbs f1, the mode-shape and
//!   frequency-ratio change is what stays.
//! - [`Unmodelled::LooseSensorMount`]: the tip sensor (a camera target or accelerometer) sits on a
//!   compliant mount, a base-excited single-DOF oscillator between the beam tip x and the reported
//!   position s: `s̈ = ω_s²(x − s) + 2ζ_sω_s(ẋ − ṡ)`, i.e. `S/X = (2ζ_sω_s p + ω_s²)/(p² +
//!   2ζ_sω_s p + ω_s²)`, with f_s = 2.5–4.5 f1 (≤ 0.35 × the sample rate, ≥ 15 % from f2) and
//!   ζ_s = 0.02–0.06. The sensor mass is negligible (no reaction on the beam).
//! - [`Unmodelled::SensorDrift`]: a slow thermal drift of the tip sensor's zero, different in
//!   every recording: `d(t) = a (t/T − ½) + b sin(2πt/P + φ)`, |a| = 4–10 and b = 3–6 × the
//!   tip-sensor error σ (noise and quantisation), P = 15–40 s.
//!
//! The parameters are drawn from their own random stream (derived from the seed), so switching
//! one on leaves every other draw of a case unchanged.

use super::fe::{FeBeam, FeModes};
use super::plant::Sensors;
use anyhow::{bail, Result};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde_json::Value;

/// A kind of physics outside the catalogue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Unmodelled {
    /// Local bending-stiffness loss mid-span.
    Crack,
    /// Tip sensor on a compliant mount (a resonance between tip and sensor).
    LooseSensorMount,
    /// Slow thermal drift of the tip sensor's zero.
    SensorDrift,
}

impl Unmodelled {
    /// Every kind.
    pub const ALL: [Unmodelled; 3] = [
        Unmodelled::Crack,
        Unmodelled::LooseSensorMount,
        Unmodelled::SensorDrift,
    ];

    /// The id (`crack`, `loose_sensor_mount`, `sensor_drift`).
    pub fn id(self) -> &'static str {
        match self {
            Unmodelled::Crack => "crack",
            Unmodelled::LooseSensorMount => "loose_sensor_mount",
            Unmodelled::SensorDrift => "sensor_drift",
        }
    }

    /// Parses an id. Errors: an unknown id.
    pub fn parse(s: &str) -> Result<Unmodelled> {
        match Unmodelled::ALL.iter().find(|u| u.id() == s.trim()) {
            Some(u) => Ok(*u),
            None => bail!(
                "unknown unmodelled physics `{s}` (one of {})",
                Unmodelled::ALL.map(|u| u.id()).join(", ")
            ),
        }
    }
}

/// The drawn parameters of one unmodelled physics (or none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drawn {
    /// Nothing outside the catalogue.
    Off,
    /// EI of FE element `element` multiplied by `1 − stiffness_loss`.
    Crack {
        /// Element index (0 = at the root).
        element: usize,
        /// Centre of the cracked element (m from the root).
        position_m: f64,
        /// Fractional EI loss of that element.
        stiffness_loss: f64,
        /// Resulting relative drop of f1.
        f1_drop: f64,
    },
    /// Sensor on a compliant mount.
    LooseSensorMount {
        /// Mount natural frequency (Hz).
        freq_hz: f64,
        /// Mount damping ratio.
        zeta: f64,
    },
    /// Thermal zero drift.
    SensorDrift {
        /// Ramp over the recording (m, end minus start).
        ramp_m: f64,
        /// Sinusoidal wander amplitude (m).
        amplitude_m: f64,
        /// Wander period (s).
        period_s: f64,
        /// Seed of the per-recording signs and phases.
        seed: u64,
    },
}

/// Every sensor noise σ multiplied by `scale` (quanta unchanged).
pub fn scale_noise(s: Sensors, scale: f64) -> Sensors {
    Sensors {
        tip_noise_m: s.tip_noise_m * scale,
        encoder_noise_m: s.encoder_noise_m * scale,
        force_noise_n: s.force_noise_n * scale,
        ..s
    }
}

fn f_hz(m: &FeModes, r: usize) -> f64 {
    m.omega_rad_s[r] / (2.0 * std::f64::consts::PI)
}

/// Modes of `beam` with EI of element `e` multiplied by `1 − loss` (the cracked-element model;
/// the lowest `n_keep`). Errors: as [`FeBeam::modes_of`].
pub fn cracked_modes(beam: &FeBeam, e: usize, loss: f64, n_keep: usize) -> Result<FeModes> {
    let (m, mut k, r) = beam.assemble()?;
    let h = beam.length_m / beam.elements as f64;
    let ei = beam.youngs_modulus_pa * beam.section((e as f64 + 0.5) * h).1;
    let ke = [
        [12.0, 6.0 * h, -12.0, 6.0 * h],
        [6.0 * h, 4.0 * h * h, -6.0 * h, 2.0 * h * h],
        [-12.0, -6.0 * h, 12.0, -6.0 * h],
        [6.0 * h, 2.0 * h * h, -6.0 * h, 4.0 * h * h],
    ];
    // full DOF d (w0 θ0 w1 θ1 …) → reduced index: w0 is clamped, θ0 free only with a root spring
    let off = usize::from(beam.root_stiffness_nm_per_rad.is_some());
    let map = |d: usize| -> Option<usize> {
        match d {
            0 => None,
            1 => (off == 1).then_some(0),
            _ => Some(d - 2 + off),
        }
    };
    for p in 0..4 {
        for q in 0..4 {
            if let (Some(i), Some(j)) = (map(2 * e + p), map(2 * e + q)) {
                k[(i, j)] -= loss * ei / (h * h * h) * ke[p][q];
            }
        }
    }
    beam.modes_of(&m, &k, &r, n_keep)
}

fn draw_crack(rng: &mut StdRng, beam: &FeBeam) -> Result<Drawn> {
    let ne = beam.elements;
    let e = ((rng.gen_range(0.35..0.6) * ne as f64) as usize).min(ne - 1);
    let f0 = f_hz(&beam.modes(1)?, 0);
    let target = rng.gen_range(0.06..0.15);
    let drop =
        |loss: f64| -> Result<f64> { Ok(1.0 - f_hz(&cracked_modes(beam, e, loss, 1)?, 0) / f0) };
    let (mut lo, mut hi) = (0.0, 0.97);
    if drop(hi)? > target {
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if drop(mid)? < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
    }
    let loss = hi;
    Ok(Drawn::Crack {
        element: e,
        position_m: (e as f64 + 0.5) * beam.length_m / ne as f64,
        stiffness_loss: loss,
        f1_drop: drop(loss)?,
    })
}

fn draw_mount(rng: &mut StdRng, beam: &FeBeam, rate_hz: f64) -> Result<Drawn> {
    let m = beam.modes(2)?;
    let (f1, f2) = (f_hz(&m, 0), f_hz(&m, 1));
    let mut fs = (rng.gen_range(2.5..4.5) * f1).min(0.35 * rate_hz);
    if (fs / f2 - 1.0).abs() < 0.15 {
        fs = if fs < f2 { 0.85 * f2 } else { 1.15 * f2 };
    }
    Ok(Drawn::LooseSensorMount {
        freq_hz: fs.min(0.35 * rate_hz),
        zeta: rng.gen_range(0.02..0.06),
    })
}

/// Draws the parameters of `kind` for a case with `seed`, the final (effect-modified) `beam`,
/// the output rate and the tip sensor (noise σ, quantum). Errors: FE failures.
pub fn draw(
    kind: Option<Unmodelled>,
    seed: u64,
    beam: &FeBeam,
    rate_hz: f64,
    tip: (f64, f64),
) -> Result<Drawn> {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x0BAD_5EED_u64.wrapping_mul(31));
    // the sensor's error σ: noise and uniform quantisation together
    let err = (tip.0 * tip.0 + tip.1 * tip.1 / 12.0).sqrt();
    Ok(match kind {
        None => Drawn::Off,
        Some(Unmodelled::Crack) => draw_crack(&mut rng, beam)?,
        Some(Unmodelled::LooseSensorMount) => draw_mount(&mut rng, beam, rate_hz)?,
        Some(Unmodelled::SensorDrift) => Drawn::SensorDrift {
            ramp_m: rng.gen_range(4.0..10.0) * err,
            amplitude_m: rng.gen_range(3.0..6.0) * err,
            period_s: rng.gen_range(15.0..40.0),
            seed: rng.gen(),
        },
    })
}

impl Drawn {
    /// The beam's lowest `n_keep` modes, with the crack when there is one.
    pub fn modes(&self, beam: &FeBeam, n_keep: usize) -> Result<FeModes> {
        match *self {
            Drawn::Crack {
                element,
                stiffness_loss,
                ..
            } => cracked_modes(beam, element, stiffness_loss, n_keep),
            _ => beam.modes(n_keep),
        }
    }

    /// The position the tip sensor sees, per fine step `dt`, for the true tip `tip_m`; `None`
    /// when the sensor sees the tip itself.
    pub fn sensed_tip(&self, tip_m: &[f64], dt: f64) -> Option<Vec<f64>> {
        let Drawn::LooseSensorMount { freq_hz, zeta } = *self else {
            return None;
        };
        Some(loose_mount(tip_m, dt, freq_hz, zeta))
    }

    /// Zero drift (m) of recording `rec` (0-based) at time `t_s` of a recording `duration_s`
    /// long; 0 without a drift.
    pub fn drift_m(&self, rec: usize, t_s: f64, duration_s: f64) -> f64 {
        let Drawn::SensorDrift {
            ramp_m,
            amplitude_m,
            period_s,
            seed,
        } = *self
        else {
            return 0.0;
        };
        let mut r = StdRng::seed_from_u64(seed.wrapping_add(rec as u64 * 7_919));
        let sign = if r.gen_bool(0.5) { 1.0 } else { -1.0 };
        let phase = r.gen_range(0.0..2.0 * std::f64::consts::PI);
        sign * ramp_m * (t_s / duration_s.max(1e-9) - 0.5)
            + amplitude_m * (2.0 * std::f64::consts::PI * t_s / period_s + phase).sin()
    }

    /// Truth entries (names, values) for `truth.json`.
    pub fn truth(&self) -> Vec<(String, Value)> {
        let v = |n: &str, x: f64| (n.to_string(), Value::from(x));
        match *self {
            Drawn::Off => vec![],
            Drawn::Crack {
                position_m,
                stiffness_loss,
                f1_drop,
                ..
            } => vec![
                ("unmodelled".into(), "crack".into()),
                v("crack_position_m", position_m),
                v("crack_stiffness_loss", stiffness_loss),
                v("crack_f1_drop", f1_drop),
            ],
            Drawn::LooseSensorMount { freq_hz, zeta } => vec![
                ("unmodelled".into(), "loose_sensor_mount".into()),
                v("sensor_mount_frequency_hz", freq_hz),
                v("sensor_mount_damping_ratio", zeta),
            ],
            Drawn::SensorDrift {
                ramp_m,
                amplitude_m,
                period_s,
                ..
            } => vec![
                ("unmodelled".into(), "sensor_drift".into()),
                v("drift_ramp_m", ramp_m),
                v("drift_amplitude_m", amplitude_m),
                v("drift_period_s", period_s),
            ],
        }
    }
}

/// Base-excited oscillator `S/X = (2ζω p + ω²)/(p² + 2ζω p + ω²)` on a uniformly sampled input,
/// controllable canonical form (q̇1 = q2, q̇2 = −ω²q1 − 2ζωq2 + x, s = ω²q1 + 2ζωq2), RK4 with
/// the input linear between samples, started at rest at the first input value.
fn loose_mount(x: &[f64], dt: f64, freq_hz: f64, zeta: f64) -> Vec<f64> {
    let w = 2.0 * std::f64::consts::PI * freq_hz;
    let (w2, c) = (w * w, 2.0 * zeta * w);
    let f = |q: [f64; 2], u: f64| [q[1], -w2 * q[0] - c * q[1] + u];
    let mut q = [x.first().copied().unwrap_or(0.0) / w2, 0.0];
    let mut out = Vec::with_capacity(x.len());
    for k in 0..x.len() {
        out.push(w2 * q[0] + c * q[1]);
        let (u0, u1) = (x[k], x[(k + 1).min(x.len() - 1)]);
        let um = 0.5 * (u0 + u1);
        let k1 = f(q, u0);
        let k2 = f([q[0] + 0.5 * dt * k1[0], q[1] + 0.5 * dt * k1[1]], um);
        let k3 = f([q[0] + 0.5 * dt * k2[0], q[1] + 0.5 * dt * k2[1]], um);
        let k4 = f([q[0] + dt * k3[0], q[1] + dt * k3[1]], u1);
        for i in 0..2 {
            q[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::{generate, TruthOptions};

    fn strip() -> FeBeam {
        FeBeam {
            length_m: 0.8,
            density_kg_m3: 7900.0,
            youngs_modulus_pa: 2.0e11,
            width_m: (0.02, 0.02),
            thickness_m: (0.0015, 0.0015),
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            gravity_sign: 0.0,
            elements: 24,
        }
    }

    #[test]
    fn off_by_default_and_off_changes_nothing() {
        assert_eq!(TruthOptions::default().unmodelled, None);
        let b = strip();
        let d = draw(None, 3, &b, 100.0, (1e-4, 1e-5)).unwrap();
        assert_eq!(d, Drawn::Off);
        assert_eq!(
            d.modes(&b, 3).unwrap().omega_rad_s,
            b.modes(3).unwrap().omega_rad_s
        );
        assert!(d.sensed_tip(&[1.0, 2.0], 1e-3).is_none());
        assert_eq!(d.drift_m(0, 3.0, 10.0), 0.0);
        assert!(d.truth().is_empty());
        let c = generate(
            "none",
            4,
            &TruthOptions {
                duration_s: 8.0,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(!c.truth.contains_key("unmodelled"));
    }

    #[test]
    fn crack_lowers_f1_and_changes_the_frequency_ratio() {
        let b = strip();
        let nominal = b.modes(3).unwrap();
        // zero loss is the uncracked beam
        let same = cracked_modes(&b, 12, 0.0, 3).unwrap();
        assert!((same.omega_rad_s[1] / nominal.omega_rad_s[1] - 1.0).abs() < 1e-12);
        let d = draw(Some(Unmodelled::Crack), 7, &b, 100.0, (1e-4, 1e-5)).unwrap();
        let Drawn::Crack {
            f1_drop,
            position_m,
            ..
        } = d
        else {
            panic!("{d:?}")
        };
        assert!((0.06..0.15).contains(&f1_drop), "{f1_drop}");
        assert!((0.3..0.65).contains(&(position_m / b.length_m)));
        let m = d.modes(&b, 3).unwrap();
        let drop = 1.0 - m.omega_rad_s[0] / nominal.omega_rad_s[0];
        assert!((drop - f1_drop).abs() < 1e-9);
        // not a uniform stiffness scale: f2/f1 moves by more than 1 %
        let r = |m: &FeModes| m.omega_rad_s[1] / m.omega_rad_s[0];
        assert!(
            (r(&m) / r(&nominal) - 1.0).abs() > 0.01,
            "{} {}",
            r(&m),
            r(&nominal)
        );
        // also with a root spring (θ0 a DOF): still a stiffness loss
        let bs = FeBeam {
            root_stiffness_nm_per_rad: Some(50.0),
            ..strip()
        };
        let ms = cracked_modes(&bs, 12, 0.5, 1).unwrap();
        assert!(ms.omega_rad_s[0] < bs.modes(1).unwrap().omega_rad_s[0]);
    }

    #[test]
    fn loose_mount_follows_its_transfer_function() {
        let (fs, zeta, dt) = (12.0, 0.03, 1.0 / 4000.0);
        // a constant passes unchanged
        let c = loose_mount(&vec![0.3; 4000], dt, fs, zeta);
        assert!(c.iter().all(|v| (v - 0.3).abs() < 1e-12));
        // a sinusoid at f = fs/3 in steady state: |H| = √((1 + (2ζr)²)/((1 − r²)² + (2ζr)²))
        let f = fs / 3.0;
        let n = 80_000;
        let x: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * f * k as f64 * dt).sin())
            .collect();
        let y = loose_mount(&x, dt, fs, zeta);
        let peak = y[n / 2..].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let r = f / fs;
        let h = ((1.0 + (2.0 * zeta * r).powi(2))
            / ((1.0 - r * r).powi(2) + (2.0 * zeta * r).powi(2)))
        .sqrt();
        assert!((peak / h - 1.0).abs() < 2e-3, "{peak} vs {h}");
        // drawn: between 2.5 f1 and 0.35 × the rate, away from f2
        let b = strip();
        let m = b.modes(2).unwrap();
        let (f1, f2) = (f_hz(&m, 0), f_hz(&m, 1));
        let Drawn::LooseSensorMount { freq_hz, .. } = draw(
            Some(Unmodelled::LooseSensorMount),
            2,
            &b,
            100.0,
            (1e-4, 1e-5),
        )
        .unwrap() else {
            panic!()
        };
        assert!(freq_hz <= 35.0 + 1e-9 && freq_hz >= (2.5 * f1).min(0.85 * f2) - 1e-9);
        assert!((freq_hz / f2 - 1.0).abs() >= 0.15 - 1e-9);
    }

    #[test]
    fn unmodelled_physics_changes_only_the_tip_sensor_or_the_beam() {
        let base = TruthOptions {
            duration_s: 10.0,
            base_pos: Some(true),
            ..Default::default()
        };
        let plain = generate("none", 21, &base).unwrap();
        let tip = |c: &crate::truth::TruthCase| c.validate.tip_pos_m.clone().unwrap();
        let rms = |a: &[f64], b: &[f64]| {
            (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
        };
        for u in Unmodelled::ALL {
            let c = generate(
                "none",
                21,
                &TruthOptions {
                    unmodelled: Some(u),
                    ..base
                },
            )
            .unwrap();
            assert_eq!(c.truth["unmodelled"], u.id());
            let noise = c.truth["tip_noise_m"].as_f64().unwrap();
            let d = rms(&tip(&c), &tip(&plain));
            assert!(d > noise, "{}: tip changes by {d} vs noise {noise}", u.id());
            let base_same = c.validate.base_pos_m == plain.validate.base_pos_m;
            // sensor-side physics leaves the carriage alone; a crack changes the beam's reaction
            assert_eq!(base_same, u != Unmodelled::Crack, "{}", u.id());
        }
        // the drift differs between recordings and is bounded by ramp/2 + amplitude
        let d = draw(
            Some(Unmodelled::SensorDrift),
            5,
            &strip(),
            100.0,
            (1e-4, 0.0),
        )
        .unwrap();
        let Drawn::SensorDrift {
            ramp_m,
            amplitude_m,
            ..
        } = d
        else {
            panic!()
        };
        let a: Vec<f64> = (0..400)
            .map(|k| d.drift_m(0, k as f64 * 0.1, 40.0))
            .collect();
        let b: Vec<f64> = (0..400)
            .map(|k| d.drift_m(1, k as f64 * 0.1, 40.0))
            .collect();
        assert!(a
            .iter()
            .all(|v| v.abs() <= 0.5 * ramp_m + amplitude_m + 1e-15));
        assert!(rms(&a, &b) > 1e-5);
    }

    #[test]
    fn noise_scale_multiplies_every_noise_sigma() {
        let s = Sensors {
            tip_noise_m: 1e-4,
            tip_quantum_m: 1e-5,
            tip_delay_s: 0.0,
            tip_gain: 1.0,
            encoder_noise_m: 1e-6,
            encoder_quantum_m: 1e-6,
            force_noise_n: 0.1,
            force_quantum_n: 0.01,
        };
        let t = scale_noise(s, 3.0);
        assert!((t.tip_noise_m - 3e-4).abs() < 1e-18 && (t.force_noise_n - 0.3).abs() < 1e-15);
        assert!((t.encoder_noise_m - 3e-6).abs() < 1e-18 && t.tip_quantum_m == 1e-5);
    }
}
