//! Sine-sweep excitation for the rig (paper §5.2, eqs. 33–34), as a base-position command.
//!
//! The instantaneous frequency runs from f_a to f_b (or from f_b down to f_a when the rate β is
//! negative):
//! - **linear**: f(t) = f₀ + β t, β in Hz/s, duration T = |f_b − f_a| / |β| (eq. 33);
//! - **exponential**: f(t) = f₀ 2^{β t / 60}, β in octaves per minute, duration
//!   T = 60 log₂(f_b / f_a) / |β| (eq. 34).
//!
//! The command is y(t) = A(f(t)) g(t) sin φ(t), φ = 2π∫f dt, with a raised-cosine fade g at
//! both ends (so the base starts and ends at rest at 0) and an amplitude envelope A(f) that
//! keeps, in steady state,
//! - the base stroke |y| ≤ `stroke_max_m`,
//! - the base acceleration A (2πf)² ≤ `accel_max_m_s2`,
//! - the tip deflection |W/Y(f)| A ≤ `tip_max_m`, where W/Y is the base-position → tip-deflection
//!   transmissibility of the clamped-base modes (given as [`TipMode`]s: the rig model's
//!   Γ_r·tip_r, or 1.566 / −0.868 / 0.509 for a uniform cantilever's first three modes).
//!   This bounds the steady-state response only: a lightly damped mode keeps ringing after
//!   the sweep passes its resonance while the envelope grows again, so the transient peak can
//!   exceed it. `beamtool sweep --rig` therefore simulates the command and tightens the limit
//!   until the simulated peak tip deflection respects the user's limit.

use anyhow::{bail, Result};
use serde::Serialize;
use std::f64::consts::PI;

/// Sweep law.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum SweepKind {
    /// Linear in frequency, rate in Hz/s (eq. 33).
    Linear,
    /// Exponential (logarithmic) in frequency, rate in octaves per minute (eq. 34).
    Exponential,
}

impl SweepKind {
    /// `linear`/`lin` or `exponential`/`exp`/`log`.
    pub fn from_name(s: &str) -> Result<SweepKind> {
        match s.to_ascii_lowercase().as_str() {
            "linear" | "lin" => Ok(SweepKind::Linear),
            "exponential" | "exp" | "log" | "logarithmic" => Ok(SweepKind::Exponential),
            _ => bail!("unknown sweep kind `{s}` (linear or exponential)"),
        }
    }
}

/// A clamped-base mode's contribution to the base-position → tip-deflection transmissibility:
/// W/Y(ω) = Σ_r gain_r ω² / (ω_r² − ω² + 2iζ_r ω_r ω) (from η̈ + 2ζω_rη̇ + ω_r²η = −Γ_r ÿ,
/// w = Σ tip_r η_r, so gain_r = Γ_r tip_r; for a uniform cantilever 1.566, −0.868, 0.509).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TipMode {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Γ_r · tip_r (dimensionless).
    pub gain: f64,
}

/// Uniform-cantilever effective tip participation of the first three modes.
pub const UNIFORM_CANTILEVER_GAINS: [f64; 3] = [1.566, -0.868, 0.509];

/// |W/Y| at `freq_hz` (see [`TipMode`]).
pub fn tip_transmissibility(modes: &[TipMode], freq_hz: f64) -> f64 {
    let w = 2.0 * PI * freq_hz;
    let (mut re, mut im) = (0.0, 0.0);
    for m in modes {
        let wr = 2.0 * PI * m.freq_hz;
        let (a, b) = (wr * wr - w * w, 2.0 * m.zeta * wr * w);
        let d = a * a + b * b;
        re += m.gain * w * w * a / d;
        im -= m.gain * w * w * b / d;
    }
    re.hypot(im)
}

/// Sweep specification.
#[derive(Clone, Debug, Serialize)]
pub struct SweepSpec {
    /// Linear or exponential.
    pub kind: SweepKind,
    /// Lower frequency limit f_a (Hz).
    pub f_a_hz: f64,
    /// Upper frequency limit f_b (Hz).
    pub f_b_hz: f64,
    /// β: Hz/s (linear) or octaves/min (exponential); negative sweeps down from f_b.
    pub rate: f64,
    /// Command sample rate (Hz).
    pub sample_rate_hz: f64,
    /// Peak base stroke about the start position (m).
    pub stroke_max_m: f64,
    /// Peak base acceleration (m/s²).
    pub accel_max_m_s2: f64,
    /// Peak tip deflection (m); needs `tip_modes`.
    pub tip_max_m: Option<f64>,
    /// Modes for the tip-deflection limit.
    pub tip_modes: Vec<TipMode>,
    /// Raised-cosine fade-in and fade-out time (s).
    pub fade_s: f64,
    /// Rest before the sweep (s).
    pub lead_s: f64,
    /// Rest after the sweep, to record the ring-down (s).
    pub tail_s: f64,
}

impl SweepSpec {
    /// The paper's sweep: 0.1–8 Hz at rate β, 1 kHz, ±20 mm, 2 m/s², no tip limit, 2 s fades,
    /// 1 s lead, 20 s tail.
    pub fn paper(kind: SweepKind, rate: f64) -> SweepSpec {
        SweepSpec {
            kind,
            f_a_hz: 0.1,
            f_b_hz: 8.0,
            rate,
            sample_rate_hz: 1000.0,
            stroke_max_m: 0.02,
            accel_max_m_s2: 2.0,
            tip_max_m: None,
            tip_modes: vec![],
            fade_s: 2.0,
            lead_s: 1.0,
            tail_s: 20.0,
        }
    }

    /// Sweep duration T (s), eqs. (33)–(34) solved for T.
    pub fn duration_s(&self) -> f64 {
        match self.kind {
            SweepKind::Linear => (self.f_b_hz - self.f_a_hz).abs() / self.rate.abs(),
            SweepKind::Exponential => 60.0 * (self.f_b_hz / self.f_a_hz).log2() / self.rate.abs(),
        }
    }

    /// Checks the numbers. Errors name the offending field.
    pub fn validate(&self) -> Result<()> {
        let pos = |v: f64, name: &str| -> Result<()> {
            if !(v.is_finite() && v > 0.0) {
                bail!("sweep: {name} must be a positive number (got {v})");
            }
            Ok(())
        };
        pos(self.f_a_hz, "f_a_hz")?;
        pos(self.f_b_hz, "f_b_hz")?;
        pos(self.sample_rate_hz, "sample_rate_hz")?;
        pos(self.stroke_max_m, "stroke_max_m")?;
        pos(self.accel_max_m_s2, "accel_max_m_s2")?;
        if !(self.f_b_hz > self.f_a_hz) {
            bail!(
                "sweep: f_b ({}) must exceed f_a ({})",
                self.f_b_hz,
                self.f_a_hz
            );
        }
        if !(self.rate.is_finite() && self.rate != 0.0) {
            bail!("sweep: rate beta must be non-zero (got {})", self.rate);
        }
        if self.f_b_hz >= 0.5 * self.sample_rate_hz {
            bail!("sweep: f_b = {} Hz is at or beyond the Nyquist frequency {} Hz of the command rate", self.f_b_hz, 0.5 * self.sample_rate_hz);
        }
        if let Some(t) = self.tip_max_m {
            pos(t, "tip_max_m")?;
            if self.tip_modes.is_empty() {
                bail!(
                    "sweep: a tip-deflection limit needs the beam's modes (a rig file or --mode)"
                );
            }
        }
        if !(self.fade_s >= 0.0 && self.lead_s >= 0.0 && self.tail_s >= 0.0) {
            bail!("sweep: fade_s, lead_s and tail_s must be >= 0");
        }
        let t = self.duration_s();
        if t > 3600.0 {
            bail!("sweep: duration {t:.0} s is longer than an hour; raise |beta|");
        }
        if 2.0 * self.fade_s >= t {
            bail!(
                "sweep: the fades (2 x {} s) are longer than the sweep ({t:.2} s)",
                self.fade_s
            );
        }
        Ok(())
    }

    /// Instantaneous frequency (Hz) and phase (rad) at time `t` (s) from the sweep start.
    pub fn freq_phase(&self, t: f64) -> (f64, f64) {
        let f0 = if self.rate > 0.0 {
            self.f_a_hz
        } else {
            self.f_b_hz
        };
        match self.kind {
            SweepKind::Linear => (
                f0 + self.rate * t,
                2.0 * PI * (f0 * t + 0.5 * self.rate * t * t),
            ),
            SweepKind::Exponential => {
                let k = self.rate * std::f64::consts::LN_2 / 60.0;
                (f0 * (k * t).exp(), 2.0 * PI * f0 * (k * t).exp_m1() / k)
            }
        }
    }

    /// Envelope amplitude A(f) (m) under the three limits.
    pub fn amplitude_m(&self, freq_hz: f64) -> f64 {
        let w = 2.0 * PI * freq_hz;
        let mut a = self.stroke_max_m.min(self.accel_max_m_s2 / (w * w));
        if let Some(tip) = self.tip_max_m {
            let g = tip_transmissibility(&self.tip_modes, freq_hz);
            if g > 0.0 {
                a = a.min(tip / g);
            }
        }
        a
    }
}

/// Time scale of the envelope smoothing (s).
pub const ENVELOPE_SMOOTHING_S: f64 = 1.0;

/// Centred moving minimum over ±`h` samples (monotonic deque, O(n)).
fn moving_min(x: &[f64], h: usize) -> Vec<f64> {
    let n = x.len();
    let mut out = vec![0.0; n];
    let mut dq: std::collections::VecDeque<usize> = std::collections::VecDeque::new();
    let mut next = 0;
    for k in 0..n {
        while next < n && next <= k + h {
            while dq.back().is_some_and(|&j| x[j] >= x[next]) {
                dq.pop_back();
            }
            dq.push_back(next);
            next += 1;
        }
        while dq.front().is_some_and(|&j| j + h < k) {
            dq.pop_front();
        }
        out[k] = x[*dq.front().expect("window never empty")];
    }
    out
}

/// Centred moving mean over ±`h` samples (shrinking at the ends).
fn moving_mean(x: &[f64], h: usize) -> Vec<f64> {
    let n = x.len();
    let mut c = vec![0.0; n + 1];
    for k in 0..n {
        c[k + 1] = c[k] + x[k];
    }
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(h), (k + h + 1).min(n));
            (c[b] - c[a]) / (b - a) as f64
        })
        .collect()
}

/// A generated sweep.
#[derive(Clone, Debug, Serialize)]
pub struct Sweep {
    /// Sample times (s).
    pub time_s: Vec<f64>,
    /// Base-position command (m).
    pub base_cmd_m: Vec<f64>,
    /// Instantaneous frequency (Hz; 0 at rest).
    pub freq_hz: Vec<f64>,
    /// Sweep duration T (s), without lead and tail.
    pub duration_s: f64,
    /// Largest |command| (m).
    pub peak_stroke_m: f64,
    /// Largest |second difference / dt²| of the command (m/s²).
    pub peak_accel_m_s2: f64,
}

/// Generates the sweep of `spec` (validated first).
pub fn generate(spec: &SweepSpec) -> Result<Sweep> {
    spec.validate()?;
    let dt = 1.0 / spec.sample_rate_hz;
    let t_sweep = spec.duration_s();
    let n_lead = (spec.lead_s * spec.sample_rate_hz).round() as usize;
    let n_sweep = (t_sweep * spec.sample_rate_hz).round() as usize + 1;
    let n_tail = (spec.tail_s * spec.sample_rate_hz).round() as usize;
    let n = n_lead + n_sweep + n_tail;
    let mut y = vec![0.0; n];
    let mut fr = vec![0.0; n];
    let raw: Vec<f64> = (0..n_sweep)
        .map(|k| spec.amplitude_m(spec.freq_phase(k as f64 * dt).0))
        .collect();
    // The limits can switch abruptly (e.g. at an anti-resonance of the tip transmissibility);
    // a moving minimum over 2 w then a moving mean over w keeps the envelope below every
    // limit while bounding its rate of change (w = 1 s).
    let w = ((spec.sample_rate_hz * ENVELOPE_SMOOTHING_S) as usize).max(1);
    let env = moving_mean(&moving_min(&raw, w), w / 2);
    for k in 0..n_sweep {
        let t = k as f64 * dt;
        let (f, ph) = spec.freq_phase(t);
        let g = if spec.fade_s > 0.0 {
            let e = (t / spec.fade_s)
                .min((t_sweep - t) / spec.fade_s)
                .clamp(0.0, 1.0);
            0.5 - 0.5 * (PI * e).cos()
        } else {
            1.0
        };
        y[n_lead + k] = env[k] * g * ph.sin();
        fr[n_lead + k] = f;
    }
    let peak_stroke_m = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak_accel_m_s2 = y
        .windows(3)
        .map(|w| ((w[2] - 2.0 * w[1] + w[0]) / (dt * dt)).abs())
        .fold(0.0, f64::max);
    Ok(Sweep {
        time_s: (0..n).map(|k| k as f64 * dt).collect(),
        base_cmd_m: y,
        freq_hz: fr,
        duration_s: t_sweep,
        peak_stroke_m,
        peak_accel_m_s2,
    })
}

/// The clamped-base modes of `model` as [`TipMode`]s (gain Γ_r · tip_r).
///
/// Errors: the model's eigen-analysis fails.
pub fn tip_modes_of_model(model: &crate::model::BeamModel) -> Result<Vec<TipMode>> {
    let c = model.clamped_modes()?;
    Ok((0..c.omega_rad_s.len())
        .map(|i| TipMode {
            freq_hz: c.omega_rad_s[i] / (2.0 * PI),
            zeta: c.zeta[i],
            gain: c.participation[i] * c.tip[i],
        })
        .collect())
}

/// Modes given as (f_hz, ζ) with the uniform cantilever's gains
/// ([`UNIFORM_CANTILEVER_GAINS`], in order).
///
/// Errors: more modes than gains (3).
pub fn uniform_tip_modes(modes: &[(f64, f64)]) -> Result<Vec<TipMode>> {
    if modes.len() > UNIFORM_CANTILEVER_GAINS.len() {
        bail!(
            "at most {} uniform-cantilever modes",
            UNIFORM_CANTILEVER_GAINS.len()
        );
    }
    Ok(modes
        .iter()
        .zip(UNIFORM_CANTILEVER_GAINS)
        .map(|(&(freq_hz, zeta), gain)| TipMode {
            freq_hz,
            zeta,
            gain,
        })
        .collect())
}

/// A sweep designed against a rig model ([`design_sweep`]).
#[derive(Clone, Debug, Serialize)]
pub struct SweepDesign {
    /// The specification finally used (its `tip_max_m` possibly tightened).
    pub spec: SweepSpec,
    /// The generated sweep.
    pub sweep: Sweep,
    /// Peak |tip deflection| (m) of the sweep simulated on the model, when one was given.
    pub simulated_peak_tip_m: Option<f64>,
}

/// Peak |tip deflection| (m) of `cmd_m` played at `rate_hz` on `model` (exact simulation).
fn simulated_peak_tip_m(
    model: &crate::model::BeamModel,
    rate_hz: f64,
    cmd_m: &[f64],
) -> Result<f64> {
    let sim = crate::model::sim::BaseMotionSim::new(model, 1.0 / rate_hz)?;
    Ok(sim.run(cmd_m).0.iter().fold(0.0f64, |p, v| p.max(v.abs())))
}

/// Generates `spec` ([`generate`]); with a rig `model`, simulates it and, while the simulated
/// peak tip deflection exceeds `spec.tip_max_m` as given, tightens the envelope's tip limit by
/// the ratio (× 0.97) and regenerates, at most 8 times: the envelope bounds only the steady
/// state (module docs).
///
/// Errors: those of [`SweepSpec::validate`] and of the model's simulation.
pub fn design_sweep(
    spec: &SweepSpec,
    model: Option<&crate::model::BeamModel>,
) -> Result<SweepDesign> {
    let mut spec = spec.clone();
    let mut s = generate(&spec)?;
    let (Some(m), Some(limit)) = (model, spec.tip_max_m) else {
        let simulated_peak_tip_m = match model {
            Some(m) => Some(simulated_peak_tip_m(m, spec.sample_rate_hz, &s.base_cmd_m)?),
            None => None,
        };
        return Ok(SweepDesign {
            spec,
            sweep: s,
            simulated_peak_tip_m,
        });
    };
    for _ in 0..8 {
        let peak = simulated_peak_tip_m(m, spec.sample_rate_hz, &s.base_cmd_m)?;
        if peak <= limit {
            break;
        }
        spec.tip_max_m = spec.tip_max_m.map(|t| t * 0.97 * limit / peak);
        s = generate(&spec)?;
    }
    let peak = simulated_peak_tip_m(m, spec.sample_rate_hz, &s.base_cmd_m)?;
    Ok(SweepDesign {
        spec,
        sweep: s,
        simulated_peak_tip_m: Some(peak),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_follow_eqs_33_34() {
        let lin = SweepSpec::paper(SweepKind::Linear, 1.0);
        assert!((lin.duration_s() - 7.9).abs() < 1e-12);
        let exp = SweepSpec::paper(SweepKind::Exponential, 3.0);
        // eq. (34): beta = log2(fb/fa) 60 / T
        let t = exp.duration_s();
        assert!(((8.0f64 / 0.1).log2() * 60.0 / t - 3.0).abs() < 1e-12);
        let down = SweepSpec::paper(SweepKind::Exponential, -5.0);
        assert!((down.freq_phase(0.0).0 - 8.0).abs() < 1e-12);
        assert!((down.freq_phase(down.duration_s()).0 - 0.1).abs() < 1e-9);
    }

    #[test]
    fn instantaneous_frequency_is_the_phase_derivative() {
        for spec in [
            SweepSpec::paper(SweepKind::Linear, 1.0),
            SweepSpec::paper(SweepKind::Exponential, -5.0),
        ] {
            for &t in &[0.5, 3.0, 7.0] {
                let h = 1e-5;
                let d =
                    (spec.freq_phase(t + h).1 - spec.freq_phase(t - h).1) / (2.0 * h) / (2.0 * PI);
                assert!((d / spec.freq_phase(t).0 - 1.0).abs() < 1e-6, "{t}");
            }
        }
    }

    #[test]
    fn envelope_respects_stroke_acceleration_and_tip_limits() {
        let mut spec = SweepSpec::paper(SweepKind::Exponential, 7.0);
        spec.tip_max_m = Some(0.01);
        spec.tip_modes = vec![
            TipMode {
                freq_hz: 1.1,
                zeta: 0.0074,
                gain: 1.566,
            },
            TipMode {
                freq_hz: 6.9,
                zeta: 0.0074,
                gain: -0.868,
            },
        ];
        let s = generate(&spec).unwrap();
        assert!(s.peak_stroke_m <= spec.stroke_max_m + 1e-12);
        // Second differences of a sampled sine slightly under-read; the fade adds a little.
        assert!(
            s.peak_accel_m_s2 <= 1.1 * spec.accel_max_m_s2,
            "{}",
            s.peak_accel_m_s2
        );
        // Steady-state tip deflection bound at every instant.
        for (y, f) in s.base_cmd_m.iter().zip(&s.freq_hz) {
            if *f > 0.0 {
                assert!(y.abs() * tip_transmissibility(&spec.tip_modes, *f) <= 0.01 + 1e-12);
            }
        }
        // At resonance the tip limit is the active one: A = tip / (1.566 / (2 zeta)) roughly.
        assert!(spec.amplitude_m(1.1) < 1.2e-4);
        assert_eq!(s.base_cmd_m[0], 0.0);
        assert!(s.base_cmd_m.last().unwrap().abs() < 1e-15);
    }

    #[test]
    fn uniform_cantilever_transmissibility_tends_to_minus_one() {
        let m: Vec<TipMode> = [1.0, 6.27, 17.55]
            .iter()
            .zip(UNIFORM_CANTILEVER_GAINS)
            .map(|(&f, g)| TipMode {
                freq_hz: f,
                zeta: 0.01,
                gain: g,
            })
            .collect();
        assert!(tip_transmissibility(&m, 1e-3) < 1e-5);
        // Far above the modes W/Y -> -(sum of the gains); the infinite series sums to 1.
        let sum: f64 = UNIFORM_CANTILEVER_GAINS.iter().sum();
        assert!((tip_transmissibility(&m, 500.0) - sum).abs() < 0.01);
    }

    #[test]
    fn bad_specs_are_refused() {
        let mut s = SweepSpec::paper(SweepKind::Linear, 1.0);
        s.f_b_hz = 600.0;
        assert!(generate(&s).unwrap_err().to_string().contains("Nyquist"));
        let mut s = SweepSpec::paper(SweepKind::Linear, 0.0);
        s.rate = 0.0;
        assert!(generate(&s).is_err());
        let mut s = SweepSpec::paper(SweepKind::Linear, 1.0);
        s.tip_max_m = Some(0.01);
        assert!(generate(&s).unwrap_err().to_string().contains("modes"));
        let mut s = SweepSpec::paper(SweepKind::Linear, 1.0);
        s.f_a_hz = f64::NAN;
        assert!(generate(&s).is_err());
    }
}
