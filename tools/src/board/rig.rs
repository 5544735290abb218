//! A virtual rig that measures: the beam of a rig file ([`crate::model`]) clamped on a
//! servo-driven carriage that follows the board's step output, and a tip sensor that records
//! what it sees, so that the host's checks work on measurements, not on the identified modes.
//!
//! Per board tick (period `dt`):
//! - **carriage**: the drive follows the emitted step position `r` (setpoint rounded down to
//!   whole steps, as [`beamshaper::output::StepOutput`] emits it) as a second-order servo
//!   `ẍ + 2ζ_s ω_s ẋ + ω_s² x = ω_s² r` (default 25 Hz, ζ_s = 0.8), exact zero-order-hold
//!   discretisation;
//! - **beam**: clamped-base modes of the rig's Galerkin model, `η̈ + 2ζω η̇ + ω² η = −Γ ÿ`,
//!   driven by the carriage's velocity change each tick, stepped by the model's simulator
//!   ([`crate::model::sim::BaseMotionSim::step`]), tip = x + Σ φ_r(l) η_r;
//! - **sensors**: an encoder on the carriage (quantised to `encoder_m`) and a camera on the
//!   tip at `sample_rate_hz` with a `latency_s` delay and Gaussian noise `noise_m`.
//!
//! The sensor writes a recording CSV (`time_s` = board time, `base_cmd_m` = shaped setpoint,
//! `base_pos_m` = encoder, `tip_pos_m` = camera), one flushed line per frame, so another
//! process can read it while the board runs ([`read_sensor_log`]).

use crate::model::sim::{mode_zoh, BaseMotionSim, BaseMotionState};
use crate::model::{BeamModel, ModelOptions, Rig};
use crate::recording::Recording;
use nalgebra::{Matrix2, Vector2};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why the virtual rig cannot be built, write its log, or its log cannot be read.
#[derive(Debug, Error)]
pub enum RigError {
    /// Sensor or servo parameters out of range (the message says which).
    #[error("{0}")]
    Sensors(String),
    /// The rig's beam model is unusable.
    #[error(transparent)]
    Model(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// A file operation on the sensor log failed.
    #[error("cannot {what} the sensor log {}", path.display())]
    File {
        /// `create`, `write`, `read`.
        what: &'static str,
        /// The log.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A complete line of the log is not 4 numbers.
    #[error("{} line {line}: `{text}` is not 4 numbers", path.display())]
    Line {
        /// The log.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
        /// Its text.
        text: String,
    },
}

/// Sensor and servo parameters of the virtual rig.
#[derive(Clone, Debug, PartialEq)]
pub struct RigSensors {
    /// Camera frame rate (Hz); default the rig file's `[sensors] sample_rate_hz`.
    pub sample_rate_hz: f64,
    /// Camera latency (s).
    pub latency_s: f64,
    /// Camera noise, 1 σ (m).
    pub noise_m: f64,
    /// Encoder resolution (m).
    pub encoder_m: f64,
    /// Servo bandwidth (Hz) and damping ratio.
    pub servo_hz: f64,
    /// Servo damping ratio.
    pub servo_zeta: f64,
    /// Noise seed.
    pub seed: u64,
}

impl RigSensors {
    /// A Keyence-like camera (the paper's §5.1): 20 ms latency, 20 µm noise, 1 µm encoder,
    /// 25 Hz servo; frame rate from the rig file (100 Hz if absent).
    pub fn camera(rig: &Rig) -> Self {
        RigSensors {
            sample_rate_hz: rig.sensors.as_ref().map_or(100.0, |s| s.sample_rate_hz),
            latency_s: 0.02,
            noise_m: 20e-6,
            encoder_m: 1e-6,
            servo_hz: 25.0,
            servo_zeta: 0.8,
            seed: 11,
        }
    }
}

/// The simulated beam, carriage and sensors, advanced one board tick at a time.
pub struct VirtualRig {
    dt: f64,
    servo_phi: Matrix2<f64>,
    servo_gamma: Vector2<f64>,
    servo_w2: f64,
    carriage: Vector2<f64>,
    beam: BaseMotionSim,
    beam_state: BaseMotionState,
    frame_every: u64,
    latency: VecDeque<f64>,
    latency_ticks: usize,
    noise: Normal<f64>,
    rng: rand::rngs::StdRng,
    sensors: RigSensors,
    ticks: u64,
    out: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
    /// The rig and the model options in force (rebuilt by a drift).
    rig: Rig,
    opts: ModelOptions,
    /// Tip accelerometer, if attached ([`VirtualRig::attach_accel`]).
    accel: Option<super::accel::AccelSim>,
    /// Drifts not yet applied, by time.
    drifts: Vec<super::accel::Drift>,
}

impl VirtualRig {
    /// Builds the rig of `rig` for a board ticking at `tick_hz`, writing the sensor log to
    /// `log`. Errors: no beam, unusable model, sensor rate not a divisor-friendly fraction of
    /// the tick rate (must be ≤ tick rate), unwritable log.
    pub fn new(rig: &Rig, sensors: RigSensors, tick_hz: f64, log: &Path) -> Result<Self, RigError> {
        check_sensors(&sensors, tick_hz)?;
        let s = &sensors;
        let model_err = |e: anyhow::Error| RigError::Model(e.into());
        let model = BeamModel::new(rig, &ModelOptions::default()).map_err(model_err)?;
        let dt = 1.0 / tick_hz;
        let beam = BaseMotionSim::new(&model, dt).map_err(model_err)?;
        let ws = 2.0 * std::f64::consts::PI * s.servo_hz;
        let (servo_phi, servo_gamma) = mode_zoh(ws, s.servo_zeta, dt);
        let file_err = |what| {
            move |source| RigError::File {
                what,
                path: log.to_path_buf(),
                source,
            }
        };
        let file = std::fs::File::create(log).map_err(file_err("create"))?;
        let mut out = std::io::BufWriter::new(file);
        writeln!(out, "time_s,base_cmd_m,base_pos_m,tip_pos_m")
            .and_then(|_| out.flush())
            .map_err(file_err("write"))?;
        let latency_ticks = (s.latency_s * tick_hz).round() as usize;
        Ok(VirtualRig {
            dt,
            servo_phi,
            servo_gamma,
            servo_w2: ws * ws,
            carriage: Vector2::zeros(),
            beam_state: beam.rest(),
            beam,
            frame_every: (tick_hz / s.sample_rate_hz).round().max(1.0) as u64,
            latency: VecDeque::from(vec![0.0; latency_ticks + 1]),
            latency_ticks,
            noise: Normal::new(0.0, s.noise_m.max(1e-30))
                .map_err(|e| RigError::Sensors(format!("camera noise: {e}")))?,
            rng: rand::rngs::StdRng::seed_from_u64(s.seed),
            sensors,
            ticks: 0,
            out,
            path: log.to_path_buf(),
            rig: rig.clone(),
            opts: ModelOptions::default(),
            accel: None,
            drifts: Vec::new(),
        })
    }

    /// Attaches a tip accelerometer: from now on each tick adds its samples
    /// ([`VirtualRig::take_accel`]).
    pub fn attach_accel(&mut self, accel: super::accel::AccelSim) {
        self.accel = Some(accel);
    }

    /// The accelerometer's configuration, if one is attached.
    pub fn accel_config(&self) -> Option<beamshaper::sensor::AccelConfig> {
        self.accel.as_ref().map(|a| a.config())
    }

    /// The accelerometer's events since the last call.
    pub fn take_accel(&mut self) -> Vec<beamshaper::sensor::SensorEvent> {
        self.accel.as_mut().map_or_else(Vec::new, |a| a.take())
    }

    /// Schedules changes of the rig at board times (`vboard --drift`).
    pub fn schedule_drifts(&mut self, drifts: &[super::accel::Drift]) {
        self.drifts.extend_from_slice(drifts);
        self.drifts.sort_by(|a, b| b.at_s.total_cmp(&a.at_s));
    }

    /// The model options in force (tip mass, stiffness scale).
    pub fn model_options(&self) -> &ModelOptions {
        &self.opts
    }

    /// Applies the drifts that are due at board time `t_s`: rebuilds the beam, keeping the
    /// modal coordinates.
    fn apply_drifts(&mut self, t_s: f64) -> Result<(), RigError> {
        use super::accel::DriftChange;
        let mut changed = false;
        while self.drifts.last().is_some_and(|d| d.at_s <= t_s) {
            let Some(d) = self.drifts.pop() else { break };
            match d.change {
                DriftChange::TipMassKg(m) => self.opts.tip_mass_kg = m,
                DriftChange::StiffnessScale(s) => self.opts.stiffness_scale = s,
            }
            changed = true;
        }
        if !changed {
            return Ok(());
        }
        let model_err = |e: anyhow::Error| RigError::Model(e.into());
        let model = BeamModel::new(&self.rig, &self.opts).map_err(model_err)?;
        let beam = BaseMotionSim::new(&model, self.dt).map_err(model_err)?;
        let mut state = beam.rest();
        state.copy_from(&self.beam_state);
        self.beam = beam;
        self.beam_state = state;
        Ok(())
    }

    /// The sensor log's path.
    pub fn log_path(&self) -> &Path {
        &self.path
    }

    /// Advances one tick with the board's shaped setpoint (m) and its emitted step position (m).
    pub fn tick(&mut self, setpoint_m: f64, step_pos_m: f64) -> Result<(), RigError> {
        let v_before = self.carriage[1];
        self.carriage =
            self.servo_phi * self.carriage + self.servo_gamma * (self.servo_w2 * step_pos_m);
        self.beam
            .step(&mut self.beam_state, self.carriage[1] - v_before);
        let tip = self.beam.tip_m(&self.beam_state, self.carriage[0]);
        if let Some(a) = self.accel.as_mut() {
            a.tick(tip);
        }
        if !self.drifts.is_empty() {
            self.apply_drifts((self.ticks + 1) as f64 * self.dt)?;
        }
        self.latency.push_back(tip);
        while self.latency.len() > self.latency_ticks + 1 {
            self.latency.pop_front();
        }
        self.ticks += 1;
        if self.ticks % self.frame_every == 0 {
            let seen =
                self.latency.front().copied().unwrap_or(tip) + self.noise.sample(&mut self.rng);
            let q = self.sensors.encoder_m;
            let enc = (self.carriage[0] / q).round() * q;
            let t = self.ticks as f64 * self.dt;
            writeln!(self.out, "{t:.6},{setpoint_m:.9},{enc:.9},{seen:.9}")
                .and_then(|_| self.out.flush())
                .map_err(|source| RigError::File {
                    what: "write",
                    path: self.path.clone(),
                    source,
                })?;
        }
        Ok(())
    }
}

/// Refuses a sensor rate above the tick rate (or ≤ 0) and negative latency, noise, encoder
/// resolution or servo bandwidth.
fn check_sensors(s: &RigSensors, tick_hz: f64) -> Result<(), RigError> {
    if !(s.sample_rate_hz > 0.0 && s.sample_rate_hz <= tick_hz) {
        return Err(RigError::Sensors(format!(
            "sensor rate {} Hz must be > 0 and at most the board's tick rate {tick_hz} Hz",
            s.sample_rate_hz
        )));
    }
    if !(s.latency_s >= 0.0 && s.noise_m >= 0.0 && s.encoder_m > 0.0 && s.servo_hz > 0.0) {
        return Err(RigError::Sensors(
            "sensor latency, noise, encoder resolution and servo bandwidth must be positive".into(),
        ));
    }
    Ok(())
}

/// Reads the sensor log written so far (complete lines only) between board times
/// `from_s` and `to_s`. Errors: unreadable file, a complete line that does not parse.
pub fn read_sensor_log(path: &Path, from_s: f64, to_s: f64) -> Result<Recording, RigError> {
    let text = std::fs::read_to_string(path).map_err(|source| RigError::File {
        what: "read",
        path: path.to_path_buf(),
        source,
    })?;
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut rec = Recording {
        base_cmd_m: Some(Vec::new()),
        base_pos_m: Some(Vec::new()),
        tip_pos_m: Some(Vec::new()),
        ..Default::default()
    };
    for (i, line) in complete.lines().enumerate().skip(1) {
        let v: Vec<f64> = line
            .split(',')
            .map(|c| c.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 4)
            .ok_or_else(|| RigError::Line {
                path: path.to_path_buf(),
                line: i + 1,
                text: line.to_string(),
            })?;
        if v[0] < from_s || v[0] > to_s {
            continue;
        }
        rec.time_s.push(v[0]);
        for (ch, x) in [&mut rec.base_cmd_m, &mut rec.base_pos_m, &mut rec.tip_pos_m]
            .into_iter()
            .zip(&v[1..])
        {
            ch.as_mut().expect("allocated").push(*x);
        }
    }
    Ok(rec)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rig steps its beam with the model's simulator: stepping the velocity changes of a
    /// base trajectory one sample at a time gives the batch run's tip deflection (one sample
    /// later: `run` reports each sample before its kick).
    #[test]
    fn stepping_the_beam_matches_the_batch_simulator() {
        let rig = Rig::from_toml_str(crate::tune::DEFAULT_RIG_TOML).unwrap();
        let model = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
        let dt = 1e-3;
        let sim = BaseMotionSim::new(&model, dt).unwrap();
        let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, 1.0 / dt, 3.0).unwrap();
        let (w, _) = sim.run(&y);
        let mut state = sim.rest();
        let v = |k: usize| match k {
            0 => 0.0,
            k if k < y.len() => (y[k] - y[k - 1]) / dt,
            _ => 0.0,
        };
        let peak = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(peak > 1e-3, "the move must excite the beam ({peak} m)");
        for k in 0..y.len() - 1 {
            sim.step(&mut state, v(k + 1) - v(k));
            let stepped = sim.tip_m(&state, 0.0);
            assert!(
                (stepped - w[k + 1]).abs() <= 1e-12 * peak,
                "sample {k}: {stepped} vs {}",
                w[k + 1]
            );
        }
    }

    #[test]
    fn sensor_parameters_out_of_range_are_refused() {
        let rig = Rig::from_toml_str(crate::tune::DEFAULT_RIG_TOML).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("rig-test.csv");
        let mut s = RigSensors::camera(&rig);
        s.sample_rate_hz = 2000.0;
        let e = VirtualRig::new(&rig, s, 1000.0, &log).err().unwrap();
        assert!(
            e.to_string().contains("at most the board's tick rate"),
            "{e}"
        );
        let mut s = RigSensors::camera(&rig);
        s.servo_hz = 0.0;
        assert!(matches!(
            VirtualRig::new(&rig, s, 1000.0, &log),
            Err(RigError::Sensors(_))
        ));
    }
}
