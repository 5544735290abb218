//! The truth generator: an independent, higher-fidelity simulator that writes a rig TOML and
//! fit/validation recordings with one concealed effect switched on (or none).
//!
//! Independent of the nominal Galerkin model (`crate::model`): a 24-element Hermite FE beam
//! ([`fe`]) with its modes below 0.1 × the fine rate, a carriage with a digital cascaded servo,
//! Coulomb + viscous friction, cogging, a mount resonance, play in the drive (a stiff contact
//! with a gap and a guide friction on the beam side), a cubic clamp stiffness, distributed
//! quadratic air drag ([`plant`]), integrated by RK4 at 40 steps per output sample, and sensor models (tip camera
//! latency, noise and quantisation; encoder and force noise and quantisation).
//!
//! Concealment: the rig file handed to the diagnosis is *wrong* in the first-order way a user's
//! rig file is (Young's modulus ±6 %, carriage mass ±12 %, damping ratios ×0.6…1.7), and each
//! effect's strength is drawn relative to the noise of the channel it shows in (residual of the
//! order of 1–4 noise σ) or as a few-percent frequency change that a stiffness recalibration
//! largely absorbs. Geometry, material, damping, noise, channels and move profiles are drawn
//! widely at random from the seed.

pub mod fe;
pub mod plant;
pub mod profile;
pub mod unmodelled;

use crate::effect::Channel;
pub use crate::effect::Effect;
use crate::recording::Recording;
use anyhow::{bail, Context, Result};
use fe::FeBeam;
use plant::{Backlash, Friction, Mount, Plant, Sensors, Servo};
use profile::{random_profile, ProfileSpec};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The effect ids the `truth` and `diagnose-proof` commands accept (and `none`): the ids of
/// [`Effect::ALL`].
pub const EFFECTS: [&str; 12] = Effect::IDS;

/// Parses `none`, one effect id or several joined by `+` (e.g. `base_friction+servo_lag`).
///
/// Errors: an unknown id, `none` inside a combination, an effect given twice.
pub fn parse_effects(effect: &str) -> Result<Vec<Effect>> {
    if effect.trim() == "none" {
        return Ok(vec![]);
    }
    let mut out: Vec<Effect> = Vec::new();
    for part in effect.split('+').map(str::trim) {
        let e: Effect = part
            .parse()
            .map_err(|e| anyhow::anyhow!("{e}, or none; several joined by `+`"))?;
        if out.contains(&e) {
            bail!("effect `{e}` given twice in `{effect}`");
        }
        out.push(e);
    }
    Ok(out)
}

/// Fine integration steps per output sample.
pub const FINE_STEPS: usize = 40;

/// A generated case.
#[derive(Clone, Debug)]
pub struct TruthCase {
    /// Effect id or `none`.
    pub effect: String,
    /// Seed.
    pub seed: u64,
    /// The rig file as handed to the diagnosis (nominal, first-order wrong).
    pub rig_toml: String,
    /// True effect parameters (names as in the diagnosis JSON) and nominal truths.
    pub truth: BTreeMap<String, serde_json::Value>,
    /// Fit recordings.
    pub fit: Vec<Recording>,
    /// Validation recording.
    pub validate: Recording,
}

/// Options of the generator.
#[derive(Clone, Copy, Debug)]
pub struct TruthOptions {
    /// Duration of each recording (s).
    pub duration_s: f64,
    /// Number of fit recordings.
    pub n_fit: usize,
    /// Output sample rate (Hz).
    pub rate_hz: f64,
    /// Physics outside the diagnosis catalogue ([`unmodelled`]); `None` = off.
    pub unmodelled: Option<unmodelled::Unmodelled>,
    /// `base_pos_m` recorded (`Some`) or not; `None` = drawn from the seed.
    pub base_pos: Option<bool>,
    /// `force_n` recorded (`Some`) or not; `None` = drawn from the seed.
    pub force: Option<bool>,
    /// Multiplies every sensor-noise σ drawn from the seed (1 = as drawn).
    pub noise_scale: f64,
}

impl Default for TruthOptions {
    fn default() -> Self {
        TruthOptions {
            duration_s: 60.0,
            n_fit: 2,
            rate_hz: 100.0,
            unmodelled: None,
            base_pos: None,
            force: None,
            noise_scale: 1.0,
        }
    }
}

fn log_uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    (rng.gen_range(lo.ln()..hi.ln())).exp()
}

#[derive(Clone, Debug, Serialize)]
struct Geometry {
    length_m: f64,
    density: f64,
    youngs: f64,
    width: (f64, f64),
    thickness: f64,
}

fn fe_of(g: &Geometry) -> FeBeam {
    FeBeam {
        length_m: g.length_m,
        density_kg_m3: g.density,
        youngs_modulus_pa: g.youngs,
        width_m: g.width,
        thickness_m: (g.thickness, g.thickness),
        tip_mass_kg: 0.0,
        root_stiffness_nm_per_rad: None,
        gravity_sign: 0.0,
        elements: 24,
    }
}

fn f1_hz(b: &FeBeam) -> Result<f64> {
    Ok(b.modes(1)?.omega_rad_s[0] / (2.0 * std::f64::consts::PI))
}

/// Generates one case. `effect` is one of [`EFFECTS`] or `none`. A draw whose servo loop
/// goes unstable against the beam's modes (it happens with a fast velocity loop and a flexible
/// beam, as on a real rig) is redrawn from a derived seed, at most 8 times.
///
/// Errors: an unknown effect id; 8 unstable draws in a row.
pub fn generate(effect: &str, seed: u64, opts: &TruthOptions) -> Result<TruthCase> {
    let mut last = None;
    for attempt in 0..8u64 {
        match generate_once(effect, seed.wrapping_add(attempt * 1_000_003), opts) {
            Ok(mut c) => {
                c.seed = seed;
                return Ok(c);
            }
            Err(e) if e.to_string().contains("unstable") => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| anyhow::anyhow!("no stable draw")))
}

/// A case being drawn: everything the steps of [`generate_once`] share.
struct Draft {
    parts: Vec<Effect>,
    truth: BTreeMap<String, serde_json::Value>,
    geo: Geometry,
    beam: FeBeam,
    beam_mass: f64,
    carriage: f64,
    zeta: (f64, f64),
    sensors: Sensors,
    plant: Plant,
    spec: ProfileSpec,
    with_beam: bool,
    has_base: bool,
    has_force: bool,
    rate: f64,
    cubic_ratio: Option<f64>,
}

/// Steel or aluminium, length, width (optionally tapered) and thickness with f1 in 0.6–5 Hz.
fn draw_geometry(rng: &mut StdRng) -> Result<Geometry> {
    loop {
        let steel = rng.gen_bool(0.5);
        let (density, youngs) = if steel {
            (rng.gen_range(7800.0..8200.0), rng.gen_range(1.9e11..2.1e11))
        } else {
            (2700.0, rng.gen_range(6.8e10..7.2e10))
        };
        let w0 = rng.gen_range(0.012..0.04);
        let taper = if rng.gen_bool(0.5) {
            1.0
        } else {
            rng.gen_range(0.5..1.0)
        };
        let geo = Geometry {
            length_m: rng.gen_range(0.35..1.0),
            density,
            youngs,
            width: (w0, w0 * taper),
            thickness: rng.gen_range(0.0008..0.003),
        };
        let f1 = f1_hz(&fe_of(&geo))?;
        if (0.6..5.0).contains(&f1) {
            return Ok(geo);
        }
    }
}

/// Gravity: hanging or upright, thickness rescaled so the load shifts f1 by 4–12 %.
fn apply_gravity(
    rng: &mut StdRng,
    beam: &mut FeBeam,
    geo: &mut Geometry,
    truth: &mut BTreeMap<String, serde_json::Value>,
) -> Result<()> {
    let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
    let target = rng.gen_range(0.04..0.12);
    for _ in 0..30 {
        let f0 = f1_hz(beam)?;
        let fg = f1_hz(&FeBeam {
            gravity_sign: sign,
            ..beam.clone()
        })
        .unwrap_or(0.0);
        let shift = (fg / f0 - 1.0).abs();
        if (shift / target - 1.0).abs() < 0.05 {
            break;
        }
        let h = (beam.thickness_m.0 * (shift / target).powf(0.5)).clamp(2e-4, 5e-3);
        beam.thickness_m = (h, h);
    }
    geo.thickness = beam.thickness_m.0;
    beam.gravity_sign = sign;
    truth.insert(
        "orientation".into(),
        (if sign > 0.0 { "hanging" } else { "upright" }).into(),
    );
    Ok(())
}

/// Sensor noise and quantisation, scaled by `noise_scale`.
fn draw_sensors(rng: &mut StdRng, noise_scale: f64) -> Sensors {
    unmodelled::scale_noise(
        Sensors {
            tip_noise_m: log_uniform(rng, 2e-5, 3e-4),
            tip_quantum_m: if rng.gen_bool(0.5) { 1e-5 } else { 1e-4 },
            tip_delay_s: 0.0,
            tip_gain: 1.0,
            encoder_noise_m: log_uniform(rng, 2e-7, 2e-6),
            encoder_quantum_m: 1e-6,
            force_noise_n: log_uniform(rng, 0.01, 0.2),
            force_quantum_n: 0.01,
        },
        noise_scale,
    )
}

/// The plant without effects: a cascaded P/PI servo of 30–60 Hz with feed-forward.
fn nominal_plant(
    rng: &mut StdRng,
    carriage: f64,
    payload_kg: f64,
    zeta: (f64, f64),
    sensors: Sensors,
) -> Plant {
    let mut plant = Plant {
        beam: None,
        zeta,
        carriage_mass_kg: carriage,
        feedforward_mass_kg: carriage + payload_kg,
        servo: Servo {
            position_bandwidth_hz: rng.gen_range(30.0..60.0),
            velocity_bandwidth_hz: 0.0,
            feedforward: true,
        },
        friction: Friction::default(),
        cogging: None,
        mount: None,
        backlash: None,
        cubic_root_nm_per_rad3: 0.0,
        drag_kg_per_m2: 0.0,
        tip_drag_kg_per_m: 0.0,
        sensors,
    };
    plant.servo.velocity_bandwidth_hz = (4.0 * plant.servo.position_bandwidth_hz).min(150.0);
    plant
}

/// Move profile: span, speeds, accelerations, dwells.
fn draw_spec(rng: &mut StdRng, duration_s: f64) -> ProfileSpec {
    ProfileSpec {
        duration_s,
        span_m: rng.gen_range(0.06..0.3),
        speed_m_s: (0.05, rng.gen_range(0.1..0.4)),
        accel_m_s2: (0.5, rng.gen_range(1.0..5.0)),
        dwell_s: (rng.gen_range(1.0..2.0), rng.gen_range(2.5..6.0)),
    }
}

/// Which of `base_pos_m` and `force_n` are recorded: (has_base, has_force).
fn draw_channels(
    rng: &mut StdRng,
    parts: &[Effect],
    opts: &TruthOptions,
    with_beam: bool,
) -> (bool, bool) {
    let mut has_base = rng.gen_bool(0.6);
    let mut has_force = rng.gen_bool(0.6);
    for e in parts {
        if *e == Effect::ServoLag {
            has_base = rng.gen_bool(0.3);
        } else if e.shows_in() == [Channel::Force] {
            has_force = true;
        }
    }
    // the guide friction that makes a play a dead band would show in the force channel as
    // friction (true physics, but another effect): backlash cases record no force unless a
    // force-channel effect is hidden with it
    if parts.contains(&Effect::Backlash) && !parts.iter().any(|e| e.shows_in() == [Channel::Force])
    {
        has_force = false;
    }
    has_base = opts.base_pos.unwrap_or(has_base);
    has_force = opts.force.unwrap_or(has_force);
    if !with_beam {
        has_base = true;
    }
    (has_base, has_force)
}

impl Draft {
    /// Sets the strength of every hidden effect (in `parts` order).
    fn apply_effects(&mut self, rng: &mut StdRng) -> Result<()> {
        for effect in self.parts.clone() {
            match effect {
                Effect::BaseFriction | Effect::CoggingRipple | Effect::ServoLag => {
                    self.apply_carriage_effect(rng, effect)
                }
                Effect::TipMass | Effect::RootCompliance | Effect::CubicStiffness => {
                    self.apply_beam_effect(rng, effect)?
                }
                Effect::Backlash
                | Effect::SensorDelay
                | Effect::SensorGain
                | Effect::MountResonance => self.apply_drive_or_sensor_effect(rng, effect)?,
                Effect::QuadraticDamping | Effect::GravityAxialLoad => {}
            }
        }
        Ok(())
    }

    fn put(&mut self, name: &str, v: f64) {
        self.truth.insert(name.into(), v.into());
    }

    /// Friction, cogging, servo lag.
    fn apply_carriage_effect(&mut self, rng: &mut StdRng, effect: Effect) {
        let pi2 = 2.0 * std::f64::consts::PI;
        let sensors = self.sensors;
        match effect {
            Effect::BaseFriction => {
                // a few noise σ, and at least 3–8 % of the peak inertial force (below that the
                // 100 Hz discretisation of the motor force masks it; see docs/diagnose.md)
                let inertial = (self.carriage + self.beam_mass) * self.spec.accel_m_s2.1;
                let fc = (rng.gen_range(1.5..4.0) * sensors.force_noise_n)
                    .max(rng.gen_range(0.03..0.08) * inertial);
                let v_typ = 0.5 * (self.spec.speed_m_s.0 + self.spec.speed_m_s.1);
                let visc = rng.gen_range(0.0..1.0) * fc / v_typ;
                self.plant.friction = Friction {
                    coulomb_n: fc,
                    viscous_n_s_per_m: visc,
                    stribeck_m_s: 2e-3,
                };
                self.put("friction_n", fc);
                self.put("viscous_n_s_per_m", visc);
            }
            Effect::CoggingRipple => {
                let a = rng.gen_range(1.5..4.0) * sensors.force_noise_n * std::f64::consts::SQRT_2;
                let p = rng.gen_range(0.015..0.05);
                self.plant.cogging = Some((a, p, rng.gen_range(0.0..pi2)));
                self.put("cogging_amplitude_n", a);
                self.put("cogging_pitch_m", p);
            }
            _ => {
                let sigma = if self.has_base {
                    50.0 * sensors.encoder_noise_m
                } else {
                    sensors.tip_noise_m
                };
                let wp = self.spec.speed_m_s.1 / (rng.gen_range(2.0..6.0) * sigma);
                let f = (wp / pi2).clamp(3.0, 60.0);
                self.plant.servo = Servo {
                    position_bandwidth_hz: f,
                    velocity_bandwidth_hz: (4.0 * f).min(150.0),
                    feedforward: false,
                };
                self.put("servo_position_gain_hz", f);
                self.put(
                    "servo_bandwidth_hz",
                    self.plant.servo.natural_frequency_hz(),
                );
            }
        }
    }

    /// Tip mass, root compliance, cubic clamp.
    fn apply_beam_effect(&mut self, rng: &mut StdRng, effect: Effect) -> Result<()> {
        match effect {
            Effect::TipMass => {
                let m = rng.gen_range(0.05..0.2) * self.beam_mass;
                self.beam.tip_mass_kg = m;
                self.put("tip_mass_kg", m);
            }
            Effect::RootCompliance => {
                let kr = root_stiffness_for(&self.beam, 1.0 - rng.gen_range(0.06..0.15))?;
                self.beam.root_stiffness_nm_per_rad = Some(kr);
                self.put("root_stiffness_nm_per_rad", kr);
            }
            _ => {
                // a compliant clamp (f1 3–10 % low) whose stiffness changes by a fraction of
                // itself at the peak root rotation of the fit moves: +40…120 % (hardening) or
                // −5…−15 % (softening; tangent stiffness ≥ 55 % of k_r at the linear peak, which
                // a softening clamp exceeds)
                let kr = root_stiffness_for(&self.beam, 1.0 - rng.gen_range(0.03..0.10))?;
                self.beam.root_stiffness_nm_per_rad = Some(kr);
                self.put("root_stiffness_nm_per_rad", kr);
                self.cubic_ratio = Some(if rng.gen_bool(0.5) {
                    rng.gen_range(0.4..1.2)
                } else {
                    -rng.gen_range(0.05..0.15)
                });
            }
        }
        Ok(())
    }

    /// Backlash, sensor delay, sensor gain, mount resonance.
    fn apply_drive_or_sensor_effect(&mut self, rng: &mut StdRng, effect: Effect) -> Result<()> {
        let sensors = self.sensors;
        match effect {
            Effect::Backlash => {
                self.plant.backlash = Some(backlash_of(
                    rng,
                    &self.plant,
                    &sensors,
                    &self.spec,
                    self.beam_mass,
                    self.rate,
                ));
                if let Some(b) = self.plant.backlash {
                    self.put("backlash_m", b.lost_motion_m());
                    self.put("backlash_gap_m", b.gap_m);
                }
            }
            Effect::SensorDelay => {
                let tau = (rng.gen_range(2.0..6.0) * sensors.tip_noise_m / self.spec.speed_m_s.1)
                    .clamp(0.002, 0.03);
                self.plant.sensors.tip_delay_s = tau;
                self.put("sensor_delay_s", tau);
            }
            Effect::SensorGain => {
                // a camera calibration off by 2–8 % either way
                let g =
                    1.0 + rng.gen_range(0.02..0.08) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                self.plant.sensors.tip_gain = g;
                self.put("sensor_gain", g);
            }
            _ => {
                let pi2 = 2.0 * std::f64::consts::PI;
                let f2 = self.beam.modes(2)?.omega_rad_s[1] / pi2;
                let fm = (rng.gen_range(1.3..3.0) * f2).clamp(8.0, 0.4 * self.rate);
                let mount = Mount {
                    mass_kg: rng.gen_range(0.15..0.4) * self.carriage,
                    freq_hz: fm,
                    zeta: rng.gen_range(0.02..0.1),
                };
                self.plant.mount = Some(mount);
                self.put("mount_frequency_hz", fm);
                self.put("mount_damping_ratio", mount.zeta);
                self.put("mount_mass_kg", mount.mass_kg);
            }
        }
        Ok(())
    }

    /// The beam's modes below the fine integration's reach, with the out-of-catalogue physics.
    fn attach_modes(&mut self, extra: &unmodelled::Drawn, fine_dt: f64) -> Result<()> {
        if !self.with_beam {
            return Ok(());
        }
        let pi2 = 2.0 * std::f64::consts::PI;
        let mut modes = extra.modes(&self.beam, 8)?;
        let limit = pi2 * (0.1 / fine_dt).min(250.0);
        let keep = modes
            .omega_rad_s
            .iter()
            .take_while(|w| **w < limit)
            .count()
            .max(1);
        modes.omega_rad_s.truncate(keep);
        modes.participation.truncate(keep);
        modes.node_w.truncate(keep);
        let drawn = self.plant.mount;
        self.plant.beam = Some((modes, self.geo.length_m / self.beam.elements as f64));
        // a mount's resonance as the rig shows it (the closed loop, what the diagnosis
        // reports), besides the drawn rigid-beam frequency
        if let (Some(mt), Some(f)) = (drawn, self.plant.mount_resonance_hz()) {
            self.put("mount_frequency_hz", f);
            self.put("mount_rigid_beam_frequency_hz", mt.freq_hz);
        }
        Ok(())
    }

    /// The cubic clamp coefficient from the peak root rotation of the linear plant on `cmd`.
    fn set_cubic(&mut self, ratio: f64, cmd: &[(f64, f64, f64)], fine_dt: f64) -> Result<()> {
        let kr = self
            .beam
            .root_stiffness_nm_per_rad
            .context("cubic clamp without a compliant root")?;
        let run = self.plant.run(cmd, fine_dt);
        let peak = run
            .root_rot_rad
            .iter()
            .fold(0.0, |a: f64, t| a.max(t.abs()));
        let k3 = ratio * kr / peak.max(1e-9).powi(2);
        self.plant.cubic_root_nm_per_rad3 = k3;
        self.put("cubic_root_stiffness_nm_per_rad3", k3);
        self.put("cubic_root_compliance_rad_per_nm3", k3 / kr.powi(4));
        Ok(())
    }

    /// Drag giving an equivalent linear damping of 0.4–1.0 ζ1 at the peak tip deflection of
    /// `cmd`: distributed along the beam, or (one draw in two, from a stream of its own so every
    /// other draw of the seed stays what it was) on a body at the tip.
    fn set_drag(&mut self, rng: &mut StdRng, cmd: &[(f64, f64, f64)], fine_dt: f64) -> Result<()> {
        let (modes, h) = self.plant.beam.as_ref().context("beam")?;
        let run = self.plant.run(cmd, fine_dt);
        let peak = run
            .tip_m
            .iter()
            .zip(&run.y_motor_m)
            .map(|(t, y)| (t - y).abs())
            .fold(0.0, f64::max);
        let phi = &modes.node_w[0];
        let nn = phi.len();
        // the placement's own stream: the next draw, mixed with "tip_drag" in ASCII
        let on_tip =
            StdRng::seed_from_u64(rng.clone().gen::<u64>() ^ 0x7469_705f_6472_6167).gen_bool(0.5);
        // ∫|φ|³ along the beam, or |φ(l)|³ of the tip body
        let cube: f64 = if on_tip {
            phi[nn - 1].abs().powi(3)
        } else {
            (1..nn)
                .map(|j| if j + 1 == nn { 0.5 * h } else { *h } * phi[j].abs().powi(3))
                .sum()
        };
        let c = rng.gen_range(0.4..1.0) * self.zeta.0 * 3.0 * std::f64::consts::PI / 4.0
            * phi[nn - 1].abs()
            / (peak.max(1e-4) * cube);
        if on_tip {
            self.plant.tip_drag_kg_per_m = c;
            self.put("tip_drag_coefficient_kg_per_m", c);
        } else {
            self.plant.drag_kg_per_m2 = c;
            self.put("drag_coefficient_kg_per_m2", c);
        }
        Ok(())
    }

    /// Simulates `cmd` and samples it at the output rate with noise, quantisation, latency, gain
    /// and the out-of-catalogue sensor physics; refuses an unstable or rattling draw.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &self,
        cmd: &[(f64, f64, f64)],
        i_rec: usize,
        fine_dt: f64,
        extra: &unmodelled::Drawn,
        noise_rng: &mut StdRng,
        duration_s: f64,
    ) -> Result<Recording> {
        let plant = &self.plant;
        let sensors = self.sensors;
        let rate = self.rate;
        let mut run = plant.run(cmd, fine_dt);
        let bound = 10.0 * (self.spec.span_m + self.geo.length_m);
        if run
            .tip_m
            .iter()
            .chain(&run.y_motor_m)
            .any(|v| !v.is_finite() || v.abs() > bound)
        {
            bail!("the truth plant's servo loop is unstable for this draw");
        }
        if plant.backlash.is_some() && rattles(plant, cmd, fine_dt, &run, bound) {
            bail!(
                "the truth plant's servo loop is unstable for this draw (it rattles in the play)"
            );
        }
        if let Some(s) = extra.sensed_tip(&run.tip_m, fine_dt) {
            run.tip_m = s;
        }
        let n = cmd.len() / FINE_STEPS;
        let mut rec = Recording::with_uniform_time(n, rate);
        let q = |v: f64, qn: f64| if qn > 0.0 { (v / qn).round() * qn } else { v };
        let mut gauss = |s: f64| {
            Normal::new(0.0, s)
                .map(|d| d.sample(noise_rng))
                .unwrap_or(0.0)
        };
        rec.base_cmd_m = Some((0..n).map(|k| cmd[k * FINE_STEPS].0).collect());
        if self.has_base {
            rec.base_pos_m = Some(
                (0..n)
                    .map(|k| {
                        q(
                            run.y_motor_m[k * FINE_STEPS] + gauss(sensors.encoder_noise_m),
                            sensors.encoder_quantum_m,
                        )
                    })
                    .collect(),
            );
        }
        if self.with_beam {
            rec.tip_pos_m =
                Some(self.sample_tip(&run.tip_m, n, fine_dt, extra, i_rec, duration_s, &mut gauss));
        }
        if self.has_force {
            // the drive reports the mean force over each sample period
            rec.force_n = Some(
                (0..n)
                    .map(|k| {
                        let s = &run.force_n[k * FINE_STEPS..(k + 1) * FINE_STEPS];
                        q(
                            s.iter().sum::<f64>() / s.len() as f64 + gauss(sensors.force_noise_n),
                            sensors.force_quantum_n,
                        )
                    })
                    .collect(),
            );
        }
        Ok(rec)
    }

    /// The tip sensor's reading of the fine-step tip position `tip_m` at the output rate: latency
    /// (linear interpolation), gain, drift, noise and quantisation.
    #[allow(clippy::too_many_arguments)]
    fn sample_tip(
        &self,
        tip_m: &[f64],
        n: usize,
        fine_dt: f64,
        extra: &unmodelled::Drawn,
        i_rec: usize,
        duration_s: f64,
        gauss: &mut dyn FnMut(f64) -> f64,
    ) -> Vec<f64> {
        let sensors = self.sensors;
        let q = |v: f64, qn: f64| if qn > 0.0 { (v / qn).round() * qn } else { v };
        let d = self.plant.sensors.tip_delay_s / fine_dt;
        (0..n)
            .map(|k| {
                let pos = k as f64 * FINE_STEPS as f64 - d;
                let v = if pos <= 0.0 {
                    tip_m[0]
                } else {
                    let i = pos.floor() as usize;
                    let a = pos - i as f64;
                    tip_m[i] * (1.0 - a) + tip_m[(i + 1).min(tip_m.len() - 1)] * a
                };
                let drift = extra.drift_m(i_rec, k as f64 / self.rate, duration_s);
                q(
                    self.plant.sensors.tip_gain * v + drift + gauss(sensors.tip_noise_m),
                    sensors.tip_quantum_m,
                )
            })
            .collect()
    }

    /// The user's rig file, first-order wrong (E ±6 %, carriage ±12 %, ζ ×0.6–1.7), and the
    /// nominal truths.
    fn rig_file(&mut self, rng: &mut StdRng, seed: u64) -> String {
        let (geo, rate, zeta, carriage) = (&self.geo, self.rate, self.zeta, self.carriage);
        let e_rig = geo.youngs * (1.0 + rng.gen_range(-0.06..0.06));
        let m_rig = carriage * (1.0 + rng.gen_range(-0.12..0.12));
        let z_rig = (
            zeta.0 * rng.gen_range(0.6..1.7),
            zeta.1 * rng.gen_range(0.6..1.7),
        );
        let mut toml = format!("# truth case: effect hidden; seed {seed}\n");
        if self.with_beam {
            toml += &format!(
                "[beam]\nlength_m = {}\ndensity_kg_m3 = {}\nyoungs_modulus_pa = {}\nstations = [\n  {{ x_m = 0.0, width_m = {}, thickness_m = {} }},\n  {{ x_m = {}, width_m = {}, thickness_m = {} }},\n]\n",
                geo.length_m, geo.density, e_rig, geo.width.0, geo.thickness, geo.length_m, geo.width.1, geo.thickness
            );
        }
        toml += &format!("[base]\nmass_kg = {m_rig}\n[damping]\nratios = [{}, {}]\n[sensors]\nsample_rate_hz = {rate}\n", z_rig.0, z_rig.1);
        let youngs = geo.youngs;
        let geometry = serde_json::to_value(geo).unwrap_or_default();
        self.put("true_youngs_modulus_pa", youngs);
        self.put("true_carriage_mass_kg", carriage);
        self.truth
            .insert("true_damping_ratios".into(), vec![zeta.0, zeta.1].into());
        let (tn, fnn) = (self.sensors.tip_noise_m, self.sensors.force_noise_n);
        self.put("tip_noise_m", tn);
        self.put("force_noise_n", fnn);
        self.put("sample_rate_hz", rate);
        self.truth.insert("geometry".into(), geometry);
        let channels = [
            (self.has_base, "base_pos_m"),
            (self.with_beam, "tip_pos_m"),
            (self.has_force, "force_n"),
        ];
        self.truth.insert(
            "channels".into(),
            channels
                .iter()
                .filter(|c| c.0)
                .map(|c| c.1)
                .collect::<Vec<_>>()
                .into(),
        );
        toml
    }
}

/// Draws the plant, effects and recordings of one seed (see [`generate`]); the steps draw from
/// one random stream in a fixed order, so a seed always gives the same case.
fn generate_once(effect: &str, seed: u64, opts: &TruthOptions) -> Result<TruthCase> {
    let mut d = draft(effect, seed, opts)?;
    let mut rng = d.1;
    let fine_dt = 1.0 / (opts.rate_hz * FINE_STEPS as f64);
    let tip_sensor = (d.0.sensors.tip_noise_m, d.0.sensors.tip_quantum_m);
    let extra = unmodelled::draw(opts.unmodelled, seed, &d.0.beam, opts.rate_hz, tip_sensor)?;
    d.0.truth.extend(extra.truth());
    let mut d = d.0;
    d.attach_modes(&extra, fine_dt)?;
    let mut rng_profiles: Vec<StdRng> = (0..=opts.n_fit)
        .map(|i| StdRng::seed_from_u64(seed ^ (0xABCD + i as u64 * 7919)))
        .collect();
    let cmds: Vec<Vec<(f64, f64, f64)>> = rng_profiles
        .iter_mut()
        .map(|r| random_profile(&d.spec, fine_dt, r))
        .collect();
    if let Some(ratio) = d.cubic_ratio {
        d.set_cubic(ratio, &cmds[0], fine_dt)?;
    }
    if d.parts.contains(&Effect::QuadraticDamping) {
        d.set_drag(&mut rng, &cmds[0], fine_dt)?;
    }
    let mut noise_rng = StdRng::seed_from_u64(seed ^ 0x00C0_FFEE);
    let mut recs = Vec::new();
    for (i_rec, cmd) in cmds.iter().enumerate() {
        recs.push(d.record(cmd, i_rec, fine_dt, &extra, &mut noise_rng, opts.duration_s)?);
    }
    let toml = d.rig_file(&mut rng, seed);
    let validate = recs.pop().context("no recordings")?;
    Ok(TruthCase {
        effect: effect.to_string(),
        seed,
        rig_toml: toml,
        truth: d.truth,
        fit: recs,
        validate,
    })
}

/// The drawn plant and effect strengths of `effect` at `seed`, and the random stream to go on
/// with.
fn draft(effect: &str, seed: u64, opts: &TruthOptions) -> Result<(Draft, StdRng)> {
    let parts = parse_effects(effect)?;
    if parts.contains(&Effect::Backlash) && parts.contains(&Effect::MountResonance) {
        bail!("backlash and mount_resonance sit in the same place of the truth plant; hide one");
    }
    let mut rng = StdRng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5eed);
    let mut truth: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    // carriage-only for some base-side cases
    let base_side = parts.iter().all(|e| !e.needs_beam());
    let with_beam = !(base_side && rng.gen_bool(0.25)) || opts.unmodelled.is_some();
    let mut geo = draw_geometry(&mut rng)?;
    let mut beam = fe_of(&geo);
    if parts.contains(&Effect::GravityAxialLoad) {
        apply_gravity(&mut rng, &mut beam, &mut geo, &mut truth)?;
    }
    let beam_mass = geo.density * 0.5 * (geo.width.0 + geo.width.1) * geo.thickness * geo.length_m;
    let carriage = rng.gen_range(1.0..6.0);
    let zeta = (
        log_uniform(&mut rng, 0.003, 0.03),
        log_uniform(&mut rng, 0.003, 0.03),
    );
    let sensors = draw_sensors(&mut rng, opts.noise_scale);
    let payload = if with_beam { beam_mass } else { 0.0 };
    let plant = nominal_plant(&mut rng, carriage, payload, zeta, sensors);
    let spec = draw_spec(&mut rng, opts.duration_s);
    let (has_base, has_force) = draw_channels(&mut rng, &parts, opts, with_beam);
    let mut d = Draft {
        parts,
        truth,
        geo,
        beam,
        beam_mass,
        carriage,
        zeta,
        sensors,
        plant,
        spec,
        with_beam,
        has_base,
        has_force,
        rate: opts.rate_hz,
        cubic_ratio: None,
    };
    d.apply_effects(&mut rng)?;
    Ok((d, rng))
}

/// True when the play of `plant` hides an unstable servo or lets it fall into a self-excited
/// rattle: the same plant without play is unstable (peak deflection not below `bound_m`), or
/// the peak deflection of `run` exceeds twice that without play. Seen on seed 1000: the loop
/// without play diverges against the beam; with the play and the guide friction it settles
/// into a growing 70 mm beam oscillation late in a recording instead. Such a limit cycle is real
/// physics, but not the dead band this effect stands for; the draw is redone.
fn rattles(
    plant: &Plant,
    cmd: &[(f64, f64, f64)],
    fine_dt: f64,
    run: &plant::FineRun,
    bound_m: f64,
) -> bool {
    let tight = Plant {
        backlash: None,
        ..plant.clone()
    };
    let peak = |r: &plant::FineRun| {
        r.tip_m
            .iter()
            .zip(&r.y_motor_m)
            .fold(0.0, |a: f64, (t, y)| a.max((t - y).abs()))
    };
    let p_tight = peak(&tight.run(cmd, fine_dt));
    !(p_tight < bound_m) || peak(run) > 2.0 * p_tight
}

/// The root stiffness (N·m/rad) that puts the first natural frequency of `beam` at
/// `ratio` × its rigid-clamp value (bisection in ln k over 1e-3…1e6).
fn root_stiffness_for(beam: &FeBeam, ratio: f64) -> Result<f64> {
    let f0 = f1_hz(beam)?;
    let (mut lo, mut hi) = (1e-3f64.ln(), 1e6f64.ln());
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        let f = f1_hz(&FeBeam {
            root_stiffness_nm_per_rad: Some(mid.exp()),
            ..beam.clone()
        })?;
        if f / f0 < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok((0.5 * (lo + hi)).exp())
}

/// Play in the drive: a gap of 4–12 tip-noise σ (≥ 50 µm), the beam-root block 10–30 % of the
/// carriage, a guide friction 1.5–3 × the block's (+ beam's) peak inertial force (so the block
/// stays where it was left inside the gap instead of coasting across it), a contact at 1.5 × the
/// sample rate (above the band; resolved by the fine RK4 step) with damping ratio 0.3.
fn backlash_of(
    rng: &mut StdRng,
    plant: &Plant,
    sensors: &Sensors,
    spec: &ProfileSpec,
    beam_mass: f64,
    rate: f64,
) -> Backlash {
    let gap = (rng.gen_range(4.0..12.0) * sensors.tip_noise_m).max(5e-5);
    let block = rng.gen_range(0.1..0.3) * plant.carriage_mass_kg;
    let guide = rng.gen_range(1.5..3.0) * (block + beam_mass) * spec.accel_m_s2.1;
    let wc = 2.0 * std::f64::consts::PI * 1.5 * rate;
    let fine_dt = 1.0 / (rate * FINE_STEPS as f64);
    Backlash {
        gap_m: gap,
        block_mass_kg: block,
        contact_n_per_m: wc * wc * block,
        contact_damping_n_s_per_m: 2.0 * 0.3 * wc * block,
        guide_friction_n: guide,
        // the smoothed friction is a damper F_g / v_s: its time constant block·v_s/F_g is kept
        // at 3 fine steps or more so that RK4 resolves it
        guide_stribeck_m_s: (3.0 * fine_dt * guide / block).max(2e-3),
    }
}

impl TruthCase {
    /// Writes `rig.toml`, `fit1.csv` …, `validate.csv` and `truth.json` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        std::fs::write(dir.join("rig.toml"), &self.rig_toml)?;
        for (i, r) in self.fit.iter().enumerate() {
            r.write_csv(dir.join(format!("fit{}.csv", i + 1)))?;
        }
        self.validate.write_csv(dir.join("validate.csv"))?;
        let j = serde_json::json!({"effect": self.effect, "seed": self.seed, "truth": self.truth});
        std::fs::write(dir.join("truth.json"), serde_json::to_string_pretty(&j)?)?;
        Ok(())
    }
}
