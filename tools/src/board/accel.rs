//! The virtual rig's tip accelerometer (`vboard --rig FILE --accel`) and its drift schedule
//! (`vboard --drift tip_mass_kg=X@T`, `--drift stiffness_scale=S@T`).
//!
//! **Accelerometer.** The tip's absolute acceleration is the second difference of the
//! simulated tip position at the tick rate (centred: it belongs to the previous tick), linearly
//! interpolated to the chip's sample instants (`rate_hz`, e.g. 3 200 Hz), plus a constant
//! offset (the chip's zero-g offset), plus Gaussian noise, then rounded to the chip's
//! resolution and clipped at its full scale (flagged saturated there), as the ADXL345 reads
//! in full-resolution mode (3.9 mg/LSB; noise about 1.1 LSB rms at 100 Hz, rising with the
//! output data rate: Analog Devices, ADXL345 data sheet Rev. G, Table 1 and Figure 17). The
//! watch sees the rig only through these samples.
//!
//! **Drift.** At board time T the beam model is rebuilt with the new tip mass or stiffness
//! scale; the modal coordinates carry over (mass-normalised shapes change little for a small
//! change; a drift is meant to happen between moves, when the beam is nearly at rest).

use beamshaper::sensor::{AccelConfig, AccelSample, SensorEvent};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Standard gravity (m/s²).
pub const G_M_S2: f64 = 9.80665;

/// The ADXL345 in full-resolution mode at ±16 g and 3 200 Hz: 3.9 mg/LSB.
pub fn adxl345() -> AccelConfig {
    AccelConfig {
        rate_hz: 3200.0,
        full_scale_m_s2: (16.0 * G_M_S2) as f32,
        lsb_m_s2: (0.0039 * G_M_S2) as f32,
    }
}

/// Noise of the simulated ADXL345 at 3 200 Hz, 1 σ (m/s²): about 3 LSB.
pub const ADXL345_NOISE_M_S2: f64 = 0.11;

/// A simulated accelerometer on the tip.
pub struct AccelSim {
    cfg: AccelConfig,
    noise: Normal<f64>,
    offset_m_s2: f64,
    rng: rand::rngs::StdRng,
    dt: f64,
    /// Tip positions of the last three ticks (m), newest first.
    tip: [f64; 3],
    /// Acceleration at the previous tick's instant (m/s²).
    acc_prev: f64,
    ticks: u64,
    /// Samples emitted so far.
    samples: u64,
    pending: Vec<SensorEvent>,
}

impl AccelSim {
    /// A chip `cfg` with noise `noise_m_s2` (1 σ) and zero-g offset `offset_m_s2`, on a board
    /// ticking every `dt` s.
    pub fn new(cfg: AccelConfig, noise_m_s2: f64, offset_m_s2: f64, dt: f64, seed: u64) -> Self {
        AccelSim {
            cfg,
            noise: Normal::new(0.0, noise_m_s2.max(1e-30)).expect("finite noise"),
            offset_m_s2,
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            dt,
            tip: [0.0; 3],
            acc_prev: 0.0,
            ticks: 0,
            samples: 0,
            pending: Vec::new(),
        }
    }

    /// The chip's configuration.
    pub fn config(&self) -> AccelConfig {
        self.cfg
    }

    /// One tick with the tip's position `tip_m` (m): emits the samples whose instants fall in
    /// the tick before the previous one's end (the centred difference's delay).
    pub fn tick(&mut self, tip_m: f64) {
        self.tip = [tip_m, self.tip[0], self.tip[1]];
        self.ticks += 1;
        if self.ticks < 3 {
            return;
        }
        let acc = (self.tip[0] - 2.0 * self.tip[1] + self.tip[2]) / (self.dt * self.dt);
        // `acc` belongs to t1 = (ticks − 1)·dt, `acc_prev` to t0 = t1 − dt.
        let t1 = (self.ticks - 1) as f64 * self.dt;
        let t0 = t1 - self.dt;
        let rate = self.cfg.rate_hz as f64;
        loop {
            let t = self.samples as f64 / rate;
            if t > t1 {
                break;
            }
            let w = ((t - t0) / self.dt).clamp(0.0, 1.0);
            let a = self.acc_prev + w * (acc - self.acc_prev);
            let ev = self.read(a);
            self.pending.push(ev);
            self.samples += 1;
        }
        self.acc_prev = acc;
    }

    /// What the chip reads for a true acceleration `a` (m/s²).
    fn read(&mut self, a: f64) -> SensorEvent {
        let lsb = self.cfg.lsb_m_s2 as f64;
        let fs = self.cfg.full_scale_m_s2 as f64;
        let v = a + self.offset_m_s2 + self.noise.sample(&mut self.rng);
        let q = (v / lsb).round() * lsb;
        SensorEvent::Sample(AccelSample {
            acc_m_s2: q.clamp(-fs, fs) as f32,
            saturated: q.abs() >= fs,
        })
    }

    /// The events emitted since the last call.
    pub fn take(&mut self) -> Vec<SensorEvent> {
        std::mem::take(&mut self.pending)
    }
}

/// One change of the virtual rig at a board time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drift {
    /// Board time (s).
    pub at_s: f64,
    /// What changes.
    pub change: DriftChange,
}

/// What a [`Drift`] changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriftChange {
    /// The lumped tip mass becomes this (kg).
    TipMassKg(f64),
    /// The beam's stiffness (Young's modulus) scale becomes this.
    StiffnessScale(f64),
}

impl std::str::FromStr for Drift {
    type Err = String;

    /// `tip_mass_kg=X@T` or `stiffness_scale=S@T` (T board seconds).
    fn from_str(s: &str) -> Result<Self, String> {
        let usage = || format!("`{s}`: expected tip_mass_kg=X@T or stiffness_scale=S@T");
        let (kv, at) = s.split_once('@').ok_or_else(usage)?;
        let (k, v) = kv.split_once('=').ok_or_else(usage)?;
        let num = |t: &str| t.trim().parse::<f64>().ok().filter(|x| x.is_finite());
        let (v, at_s) = (num(v).ok_or_else(usage)?, num(at).ok_or_else(usage)?);
        let change = match k.trim() {
            "tip_mass_kg" if v >= 0.0 => DriftChange::TipMassKg(v),
            "stiffness_scale" if v > 0.0 => DriftChange::StiffnessScale(v),
            _ => return Err(usage()),
        };
        if at_s < 0.0 {
            return Err(usage());
        }
        Ok(Drift { at_s, change })
    }
}
