//! The augmented simulator: the nominal Galerkin model (`crate::model`, paper §2) with every
//! candidate extension switchable, predicting the recorded channels of one recording.
//!
//! Chain (each block off unless its parameters are set):
//! 1. servo: the base follows its command through a finite-bandwidth position loop whose
//!    command → base transfer function has order 1–4 ([`ServoLaw`]): order 2 is
//!    `ÿ + 2ζ_sω_s ẏ + ω_s² y = k_a r̈ + 2ζ_sω_s k_v ṙ + ω_s² r`, i.e. the following error
//!    e = y − r obeys `ë + 2ζ_sω_s ė + ω_s² e = −(1 − k_a) r̈ − 2ζ_sω_s (1 − k_v) ṙ` (`servo_lag`;
//!    k_v = k_a = 0 is a plain 2nd-order lag, PID with velocity/acceleration feed-forward has
//!    fractions near 1); order 3 adds the integral action of a PID loop, order 4 a lag of the
//!    drive force, order 1 is a first-order lag; orders 2–4 are simulated with the beam's
//!    reaction on the carriage (eq. 5 in modal form, [`coupled_servo`]) and with the carriage
//!    forces of step 5, which the loop must overcome ([`CarriageLoad`]); predicted `base_pos_m`;
//! 2. the beam is driven by the *measured* base position when recorded (so carriage effects do
//!    not leak into the tip channel), else by the predicted one;
//! 3. backlash: a dead band of total width b between the carriage and the beam root, as the
//!    play (backlash) operator `y_r[k] = clamp(y_r[k−1], y[k] − b/2, y[k] + b/2)` ([`play`];
//!    `backlash`): the root stays where it was left until the drive takes it up from the other
//!    side (a root held by friction inside the gap, driven through a rigid contact);
//!    mount: the beam root is a mount mass on a spring–damper from the carriage, loaded by the
//!    beam (coupled to its modes, [`coupled_mount`]; `mount_resonance` with `mount_mass_kg`), or
//!    a massless filter of the root motion (a mount the beam does not load);
//! 4. beam: clamped-base modes of [`BeamModel`] (M, K of eqs. 13–20 with tip mass, root spring,
//!    gravity axial load and the calibration scale), `η̈_r + 2ζ_rω_r η̇_r + ω_r² η_r = −Γ_r ÿ_r + f_r`,
//!    integrated exactly between samples for a piecewise-linear base (as `model::sim`), with the
//!    quadratic drag applied as a per-sample impulse (`quadratic_damping`), distributed
//!    `f_r = −c_d ∫ φ_r |v| v dx` or on a body at the tip `f_r = −c_t φ_r(l) |v_l| v_l`; a cubic
//!    clamp moment `M₃ = k₃ θ³` on the root rotation
//!    θ = Σ s_r η_r − c M₃ of the compliant clamp (s_r the root rotation of mode r, c the
//!    residual flexibility of the modes not simulated, [`ResidualFlexibility`]) as a per-sample
//!    modal impulse `f_r = −s_r M₃` ([`cubic_moment`], bounded; `cubic_stiffness`, with the
//!    linear k_r in the modes), the tip moved by the same static correction; motor force from eq. (5), `u = J ÿ + hᵀ q̈ − ∫ drag`;
//! 5. carriage forces: `+ F_c sign(ẏ) + c_v ẏ` (`base_friction`, smoothed over 1 mm/s) and
//!    `+ a sin(2πy/p) + b cos(2πy/p)` (`cogging_ripple`);
//! 6. tip sensor latency τ: `tip(t − τ)` by a band-limited fractional delay ([`delayed`];
//!    `sensor_delay`); tip sensor scale g (camera calibration): `g · tip` (`sensor_gain`), or,
//!    for a sensor riding on the carriage, on the deflection only: `y + g · w`.

use crate::model::sim::{mode_ramp, mode_zoh};
use crate::model::{BeamModel, ModelOptions, Orientation, Rig};
use anyhow::{bail, Result};
use nalgebra::Vector2;

/// Every physical parameter of the augmented model. `Default` = the rig's nominal model.
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// Multiplies E (calibration).
    pub stiffness_scale: f64,
    /// Damping ratios of modes 1, 2 (Rayleigh, eq. 22); `None` = the rig's.
    pub zeta: Option<(f64, f64)>,
    /// Damping ratio of each clamped mode r (calibration, one per mode inside the recording's
    /// band); modes beyond the list keep the Rayleigh value of `zeta`.
    pub zeta_modes: Option<Vec<f64>>,
    /// Number of Galerkin basis functions (chosen so every mode below the band edge has
    /// converged; [`converged_basis`]).
    pub n_basis: usize,
    /// Number of lowest clamped modes simulated ([`BasisChoice::simulated_modes`], fixed for a
    /// diagnosis so that no parameter moves a mode across a truncation); `None` = the modes below
    /// each recording's band edge.
    pub simulated_modes: Option<usize>,
    /// Carriage-mass correction (kg, calibration).
    pub base_mass_delta_kg: f64,
    /// Coulomb friction (N).
    pub friction_n: f64,
    /// Viscous friction (N·s/m).
    pub viscous_n_s_per_m: f64,
    /// Servo loop natural frequency √(K_p/M)/2π (Hz; K_p the loop's proportional gain, M the
    /// carriage mass: [`ServoLaw::natural_frequency_rad_s`]) and damping ratio ζ.
    pub servo: Option<(f64, f64)>,
    /// Velocity and acceleration feed-forward fractions of the position loop (0 = plain lag).
    pub servo_ff: (f64, f64),
    /// Order of the position loop's command → base transfer function ([`ServoLaw`]): 1 a
    /// first-order lag, 2 a PD loop, 3 a PID loop, 4 a PID loop whose drive force lags.
    pub servo_order: usize,
    /// Integral action of a PID loop (order ≥ 3): its real closed-loop pole at α·ω_s.
    pub servo_integral_ratio: f64,
    /// Drive-force lag of an order-4 loop (current loop, digital delay): time constant β/ω_s.
    pub servo_force_lag_ratio: f64,
    /// Tip mass (kg).
    pub tip_mass_kg: f64,
    /// Root rotational stiffness (N·m/rad).
    pub root_stiffness_nm_per_rad: Option<f64>,
    /// Where that rotational spring sits (m from the clamp; 0 = the clamp,
    /// [`ModelOptions::spring_position_m`]): not a catalogue effect, the alternative placement a
    /// root spring is tested against (a local compliance along the beam: a crack).
    pub spring_position_m: f64,
    /// Distributed quadratic drag (kg/m²: force per unit length = c |v| v).
    pub drag_kg_per_m2: f64,
    /// Quadratic drag on a body at the tip (kg/m: force = c |v| v at the tip's absolute
    /// velocity), the other placement of `quadratic_damping`: a tip target, paddle or mass
    /// whose area dominates the beam's.
    pub tip_drag_kg_per_m: f64,
    /// Tip sensor latency (s).
    pub sensor_delay_s: f64,
    /// Tip sensor scale error g − 1: the sensor reports (1 + g) × the absolute tip position.
    pub sensor_gain_error: f64,
    /// The other placement of the tip sensor's scale error, g − 1 on the deflection from the
    /// carriage: a sensor riding on the carriage (a camera on the carriage, a strain gauge at
    /// the root) reports root + (1 + g) × deflection.
    pub sensor_deflection_gain_error: f64,
    /// Gravity axial load.
    pub orientation: Option<Orientation>,
    /// Mount resonance (Hz, damping ratio): k = (2π f)² (m_mount + m_beam), as loaded rigidly.
    pub mount: Option<(f64, f64)>,
    /// Mount (beam-side) mass (kg), part of the carriage mass; 0 = a massless filter.
    pub mount_mass_kg: f64,
    /// A resonance between the tip and its sensor (Hz, damping ratio): the reported position s
    /// follows the absolute tip x as `s̈ + 2ζω ṡ + ω² s = ω² x + 2ζω ẋ` (a loose sensor mount;
    /// not a catalogue effect: the alternative placement a mount resonance is tested against).
    pub tip_filter: Option<(f64, f64)>,
    /// Cogging: sine and cosine amplitudes (N) and pitch (m).
    pub cogging: Option<(f64, f64, f64)>,
    /// Latency of the force channel (s, calibration: drives that average or filter the
    /// current report it up to a sample late).
    pub force_delay_s: f64,
    /// Total play between the carriage and the beam root (m); 0 = none.
    pub backlash_m: f64,
    /// Cubic clamp stiffness k₃ (N·m/rad³) in `M = k_r θ + k₃ θ³`; needs
    /// `root_stiffness_nm_per_rad` (the root rotation is then a coordinate).
    pub cubic_root_stiffness_nm_per_rad3: f64,
    /// The drive's path between samples: `false` the piecewise-linear path through the
    /// samples (the model's), `true` a smooth one: the interpolating cubic spline's acceleration
    /// ([`spline_accel`]) for the carriage's force, the band-limited (emphasised) path for the
    /// beam (`drives`); the alternative the 1-σ are widened by
    /// (`honesty::add_drive_interpolation_std`).
    pub smooth_drive: bool,
    /// How the model reads a drive recorded at the recording's own rate between its samples
    /// (a decimated one is always emphasised, [`super::rate`]); chosen by the recordings
    /// (`super::diagnose`).
    pub drive_reading: DriveReading,
}

/// How the model reads a drive sampled at the recording's own rate between its samples: the
/// samples say nothing of the motion between them, and two simulators of the same rig can
/// differ there (a drive that moves linearly between setpoint updates, a position loop far
/// faster than the recording), so the recordings choose ([`super::diagnose`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveReading {
    /// The piecewise-linear path through the samples: the beam is forced by the second
    /// difference of the drive, sinc²(f/r) of a smooth motion's content (12 % low at 0.2 ×
    /// the rate).
    #[default]
    PiecewiseLinear,
    /// A smooth motion: the model's input is `x_k − δ²x_k / 12`
    /// ([`super::rate::emphasise_of`] with half-length 1), so its second difference is the
    /// fourth-order central difference of the acceleration, `(−x_{k−2} + 16 x_{k−1} − 30 x_k +
    /// 16 x_{k+1} − x_{k+2}) / 12` (Fornberg, Math. Comp. 51, 1988): sinc²(f/r)(1 +
    /// sin²(πf/r)/3) of the content (2.4 % low at 0.2 × the rate), a gain of at most 4/3 on
    /// noise at the Nyquist rate (the fully band-limited reading's 13 taps, 1.8 ×, let a play
    /// feed on an encoder's rounding, docs/diagnose.md, session 15).
    FourthOrder,
}

impl DriveReading {
    /// Both readings, the model's default first.
    pub const ALL: [DriveReading; 2] = [DriveReading::PiecewiseLinear, DriveReading::FourthOrder];

    /// Words for the report.
    pub fn words(self) -> &'static str {
        match self {
            DriveReading::PiecewiseLinear => "piecewise linear between samples",
            DriveReading::FourthOrder => "smooth between samples (fourth-order acceleration)",
        }
    }
}

/// Half-length of the emphasis of [`DriveReading::FourthOrder`] (3 taps).
const FOURTH_ORDER_HALF: usize = 1;

impl Params {
    /// Whether the beam model adds the tip-load shape to its basis
    /// ([`ModelOptions::tip_load_shape`]): with a tip mass, whose shear at the tip the
    /// clamped–free functions alone converge to only algebraically; without one they already
    /// meet the tip's natural conditions and the shape would only perturb a converged model.
    pub fn tip_load_shape(&self) -> bool {
        self.tip_mass_kg > 0.0
    }

    /// Whether any quadratic drag acts on the beam (distributed or on a tip body).
    pub fn has_drag(&self) -> bool {
        self.drag_kg_per_m2 > 0.0 || self.tip_drag_kg_per_m > 0.0
    }
}

impl Default for Params {
    fn default() -> Self {
        Params {
            stiffness_scale: 1.0,
            zeta: None,
            zeta_modes: None,
            n_basis: 4,
            simulated_modes: None,
            base_mass_delta_kg: 0.0,
            friction_n: 0.0,
            viscous_n_s_per_m: 0.0,
            servo: None,
            servo_ff: (0.0, 0.0),
            servo_order: 2,
            servo_integral_ratio: 0.0,
            servo_force_lag_ratio: 0.0,
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            spring_position_m: 0.0,
            drag_kg_per_m2: 0.0,
            tip_drag_kg_per_m: 0.0,
            sensor_delay_s: 0.0,
            sensor_gain_error: 0.0,
            sensor_deflection_gain_error: 0.0,
            orientation: None,
            mount: None,
            mount_mass_kg: 0.0,
            tip_filter: None,
            cogging: None,
            force_delay_s: 0.0,
            backlash_m: 0.0,
            cubic_root_stiffness_nm_per_rad3: 0.0,
            smooth_drive: false,
            drive_reading: DriveReading::PiecewiseLinear,
        }
    }
}

/// Half-length (samples) of the [`delayed`] interpolation kernel (2 × this many taps).
const DELAY_HALF: usize = 8;
/// Kaiser window shape β of the [`delayed`] kernel.
const DELAY_BETA: f64 = 5.0;

/// `x(t − τ)` between samples by a band-limited fractional delay (held at the ends): a
/// Kaiser-windowed sinc (β [`DELAY_BETA`], 2 × [`DELAY_HALF`] taps, weights scaled to unit DC
/// gain), flat within 0.3 % in amplitude up to 0.4 × the sample rate at every fraction.
/// Linear interpolation, used before, is a low-pass whose gain depends on the fraction
/// (half a sample: cos(πf/r), 0.51 at 0.33 r): at 50–100 Hz a latency of a few ms then also
/// removed 10–50 % of the beam's second mode from the prediction, so the tip latency of
/// `sensor_delay` lost to a position loop (exact between samples) and the force channel's
/// calibrated half-sample latency took its modes' content out of the model (Laakso et al.,
/// "Splitting the unit delay", IEEE Signal Processing Magazine 13(1), 1996).
pub fn delayed(x: &[f64], delay_s: f64, dt: f64) -> Vec<f64> {
    let n = x.len();
    let s = delay_s / dt;
    // x(k − s) = Σ_j w_j x[k + shift + j − h + 1]: the fraction, hence the weights, is the
    // same for every k
    let shift = (-s).floor();
    let a = -s - shift;
    let h = DELAY_HALF as i64;
    let w: Vec<f64> = if a < 1e-12 {
        vec![]
    } else {
        let i0b = super::rate::bessel_i0(DELAY_BETA);
        let raw: Vec<f64> = (0..2 * h)
            .map(|j| {
                let t = a - (j - h + 1) as f64;
                let r = t / h as f64;
                let pt = std::f64::consts::PI * t;
                pt.sin() / pt * super::rate::bessel_i0(DELAY_BETA * (1.0 - r * r).max(0.0).sqrt())
                    / i0b
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|v| v / sum).collect()
    };
    let shift = shift as i64;
    let at = |i: i64| x[i.clamp(0, n as i64 - 1) as usize];
    (0..n as i64)
        .map(|k| {
            let pos = k as f64 - s;
            if pos <= 0.0 {
                x[0]
            } else if pos >= (n - 1) as f64 {
                x[n - 1]
            } else if w.is_empty() {
                at(k + shift)
            } else {
                // the taps' first sample; inside the record, the same sum without the clamps
                let first = k + shift - h + 1;
                if first >= 0 && first + 2 * h <= n as i64 {
                    let taps = &x[first as usize..(first + 2 * h) as usize];
                    w.iter().zip(taps).map(|(wj, xj)| wj * xj).sum()
                } else {
                    let taps = (0..2 * h).map(|j| at(first + j));
                    w.iter().zip(taps).map(|(wj, xj)| wj * xj).sum()
                }
            }
        })
        .collect()
}

/// The play (backlash) operator of total width `width_m` (m): the output stays put while the
/// input moves inside the dead band and is dragged at ±width/2 behind it otherwise,
/// `y[k] = clamp(y[k−1], x[k] − w/2, x[k] + w/2)`, starting centred (`y[0] = x[0]`).
/// Rate-independent and 1-Lipschitz: |y − x| ≤ w/2 everywhere (Krasnosel'skii & Pokrovskii,
/// *Systems with Hysteresis*, 1989, §2.2).
pub fn play(x: &[f64], width_m: f64) -> Vec<f64> {
    let h = 0.5 * width_m.abs();
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&v| {
            // NaN in (an unstable servo prediction, a NaN width) gives NaN out, never a panic
            let (lo, hi) = (v - h, v + h);
            y = if lo <= hi {
                y.max(lo).min(hi)
            } else {
                f64::NAN
            };
            y
        })
        .collect()
}

/// Cubic part of a clamp moment, `k₃ θ · min(θ², θ_c²)` (N·m): exactly k₃θ³ up to the bound
/// θ_c and linear beyond it, so the model stays stable and its cost per sample fixed whatever
/// the fitted values. `theta_cap2` (rad²) comes from [`cubic_cap2`].
pub fn cubic_moment(k3: f64, theta: f64, theta_cap2: f64) -> f64 {
    k3 * theta * (theta * theta).min(theta_cap2)
}

/// The bound θ_c² of [`cubic_moment`] for linear clamp stiffness `k_r` (N·m/rad): softening
/// stops where the tangent stiffness k_r + 3k₃θ² would fall below k_r/10 (θ_c² = 0.3 k_r / |k₃|);
/// hardening where it would exceed 10 k_r (θ_c² = 3 k_r / k₃) or where the per-sample impulse
/// of the added stiffness would no longer be stable (3 k₃ θ² Σs_r² dt² ≤ 3, s_r the root
/// rotation of mode r per unit mass-normalised coordinate).
pub fn cubic_cap2(k3: f64, k_r: f64, sum_s2: f64, dt: f64) -> f64 {
    if k3 == 0.0 {
        return f64::INFINITY;
    }
    if k3 < 0.0 {
        0.3 * k_r / -k3
    } else {
        (3.0 * k_r / k3).min(3.0 / (3.0 * k3 * sum_s2.max(1e-300) * dt * dt))
    }
}

/// One recording prepared for simulation: uniform dt, the command (or the measured base when
/// no command was recorded) and the measured channels.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// Name (file).
    pub name: String,
    /// Sample interval (s).
    pub dt: f64,
    /// Time (s).
    pub time_s: Vec<f64>,
    /// Base command (m), as the model's input (at a working rate below the recording's,
    /// emphasised against its piecewise-linear interpolation, [`super::rate`]).
    pub cmd_m: Vec<f64>,
    /// The command as recorded (filtered, not emphasised) when `cmd_m` is emphasised: the
    /// predicted base of a model without a servo loop; `None` = `cmd_m`.
    pub cmd_identity_m: Option<Vec<f64>>,
    /// Measured base position (m), if recorded *and* a command exists.
    pub base_m: Option<Vec<f64>>,
    /// Measured base used to drive the beam (= `base_m`, or the base when it is the only one).
    pub drive_m: Option<Vec<f64>>,
    /// `drive_m` as sampled (not emphasised) when `drive_m` is emphasised; `None` = `drive_m`.
    pub drive_identity_m: Option<Vec<f64>>,
    /// Tip position (m).
    pub tip_m: Option<Vec<f64>>,
    /// Force (N).
    pub force_n: Option<Vec<f64>>,
    /// Samples held at a sensor's rail, per compared channel (base, tip, force): left out of
    /// every residual ([`super::saturation`]; the base, which also drives the model, has none).
    pub rails: [super::saturation::Rails; 3],
    /// Runs where a compared channel had no reading (base, tip, force; a sensor that lost its
    /// target for longer than the loader fills, bridged by a straight line): left out of every
    /// residual as the rails are ([`Prepared::with_gaps`]; the base, which drives the model,
    /// has none). The `values` of each are empty.
    pub gaps: [super::saturation::Rails; 3],
    /// The recording does not start at rest (a logger started mid-motion, or while the beam
    /// still rang: [`crate::recording::zero::starts_at_rest`]): the prediction adds the beam
    /// modes' free response from an unknown initial state ([`add_free_response`]).
    pub free_start: bool,
}

impl Prepared {
    /// Prepares a validated recording; finds the rails of its tip and force channels
    /// ([`super::saturation`]). Errors: no `base_cmd_m` and no `base_pos_m`, no channel to
    /// compare with, a channel more than [`super::saturation::MAX_RAIL_FRACTION`] at its rails.
    pub fn new(name: &str, rec: &crate::recording::Recording) -> Result<Prepared> {
        rec.validate()?;
        let (cmd, base, drive) = match (&rec.base_cmd_m, &rec.base_pos_m) {
            (Some(c), b) => (c.clone(), b.clone(), b.as_ref().map(|b| drive_of(c, b))),
            (None, Some(b)) => (b.clone(), None, Some(b.clone())),
            (None, None) => bail!("{name}: needs `base_cmd_m` or `base_pos_m` (the base motion that drives the model)"),
        };
        if base.is_none() && rec.tip_pos_m.is_none() && rec.force_n.is_none() {
            bail!("{name}: nothing to compare: record at least one of `base_pos_m` (with `base_cmd_m`), `tip_pos_m`, `force_n`");
        }
        let rails_of = |c: &Option<Vec<f64>>, channel: &str| -> Result<super::saturation::Rails> {
            let Some(y) = c else {
                return Ok(Default::default());
            };
            let r = super::saturation::rails(y);
            let share = r.samples() as f64 / y.len().max(1) as f64;
            if share > super::saturation::MAX_RAIL_FRACTION {
                bail!(
                    "{name}: {channel} sits at its sensor's rail ({}) on {:.0} % of the samples: too little of the motion was recorded; reduce the amplitude or widen the sensor's range",
                    r.values_words(),
                    100.0 * share
                );
            }
            Ok(r)
        };
        let rails = [
            Default::default(),
            rails_of(&rec.tip_pos_m, "tip_pos_m")?,
            rails_of(&rec.force_n, "force_n")?,
        ];
        Ok(Prepared {
            name: name.to_string(),
            dt: rec.sample_interval_s(),
            time_s: rec.time_s.clone(),
            cmd_m: cmd,
            cmd_identity_m: None,
            base_m: base,
            drive_m: drive,
            drive_identity_m: None,
            tip_m: rec.tip_pos_m.clone(),
            force_n: rec.force_n.clone(),
            rails,
            gaps: Default::default(),
            free_start: false,
        })
    }

    /// This recording with the runs `gaps` of its tip and force channels (as read by
    /// [`crate::recording::regular::regularise_leaving_gaps`]) left out of every residual.
    /// Errors: a gap in `base_pos_m` or `base_cmd_m` (they drive the model), or more than
    /// [`super::saturation::MAX_RAIL_FRACTION`] of a channel at its rails or in gaps.
    pub fn with_gaps(mut self, gaps: &crate::recording::regular::Gaps) -> Result<Prepared> {
        for (name, runs) in &gaps.runs {
            let c = match *name {
                "tip_pos_m" => 1,
                "force_n" => 2,
                _ => bail!("{}: {name} has no reading for a while: the base motion drives the model and cannot be left out; cut the recording there", self.name),
            };
            let len = self.cmd_m.len();
            let share = (self.rails[c].samples() + runs.iter().map(|(a, b)| b - a).sum::<usize>())
                as f64
                / len.max(1) as f64;
            if share > super::saturation::MAX_RAIL_FRACTION {
                bail!(
                    "{}: {name} has no usable reading (at a rail or missing) on {:.0} % of the samples: too little of the motion was recorded",
                    self.name,
                    100.0 * share
                );
            }
            self.gaps[c] = super::saturation::Rails {
                values: Vec::new(),
                runs: runs.clone(),
            };
        }
        Ok(self)
    }
}

impl Prepared {
    /// The command as recorded (at the working rate, not [emphasised](super::rate::emphasise)).
    pub fn cmd_as_sampled(&self) -> &[f64] {
        self.cmd_identity_m.as_deref().unwrap_or(&self.cmd_m)
    }

    /// The measured drive, else the command, as sampled (not emphasised): what a yardstick
    /// built from the recordings (the physics-free correction) may use. The emphasised inputs
    /// differ from these by ≈ (π²/3) dt² × their second derivative, a derivative of the motion
    /// that the model's own physics (a servo loop, an inertia) should have to earn.
    pub fn drive_as_sampled(&self) -> &[f64] {
        match &self.drive_m {
            Some(m) => self.drive_identity_m.as_deref().unwrap_or(m),
            None => self.cmd_as_sampled(),
        }
    }

    /// The largest tip deflection relative to the drive as sampled, max |tip − drive| (m);
    /// `None` without a tip channel.
    pub fn peak_deflection_m(&self) -> Option<f64> {
        let tip = self.tip_m.as_ref()?;
        Some(
            tip.iter()
                .zip(self.drive_as_sampled())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max),
        )
    }
}

/// The base motion that drives the model when `base_pos_m` (`base`) is recorded with its
/// command `cmd`: the command plus the measured following error (base − command) with its white
/// measurement noise removed ([`wiener_denoise`](crate::numeric::stats::wiener_denoise)). The
/// model differentiates its drive twice (the carriage's inertia on `force_n`, the beam root's
/// acceleration); a position sensor's noise σ becomes an acceleration noise of about
/// √6 σ / dt², which at high sample rates outweighs the motion's own acceleration — the force
/// calibration then fits a carriage without mass (errors in the input variable). The
/// following error's own content above the noise floor (the loop's lag and ripple) is kept.
pub fn drive_of(cmd: &[f64], base: &[f64]) -> Vec<f64> {
    let e: Vec<f64> = base.iter().zip(cmd).map(|(b, c)| b - c).collect();
    crate::numeric::stats::wiener_denoise(&e)
        .iter()
        .zip(cmd)
        .map(|(e, c)| c + e)
        .collect()
}

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

/// y = u + e with `ë + 2ζωė + ω²e = −g_a ü − g_v 2ζω u̇` for a piecewise-linear u: exact
/// (velocity kicks at the samples, constant forcing in between). `g_a = g_v = 1` is the plain
/// 2nd-order low-pass `ÿ + 2ζωẏ + ω²y = 2ζω… = ω² u`; a position loop with velocity and
/// acceleration feed-forward fractions k_v, k_a has `g_v = 1 − k_v`, `g_a = 1 − k_a`; a spring–
/// damper mount driven by its base has `g_a = 1, g_v = 0`.
fn second_order(u: &[f64], dt: f64, omega: f64, zeta: f64, g_v: f64, g_a: f64) -> Vec<f64> {
    let (phi, gam) = mode_zoh(omega, zeta, dt);
    let n = u.len();
    let mut x = Vector2::zeros();
    let mut y = Vec::with_capacity(n);
    for k in 0..n {
        let vb = if k == 0 { 0.0 } else { (u[k] - u[k - 1]) / dt };
        let va = if k + 1 < n {
            (u[k + 1] - u[k]) / dt
        } else {
            0.0
        };
        y.push(u[k] + x[0]);
        x[1] -= g_a * (va - vb);
        let f = -g_v * 2.0 * zeta * omega * va;
        x = (phi * x + gam * f).map(at_rest);
    }
    y
}

/// Velocity over which Coulomb friction is smoothed (m/s): `F_c tanh(v / v_s)`, in the force
/// channel and inside the position loop alike.
const FRICTION_SMOOTHING_M_S: f64 = 1e-3;

/// Forces on the carriage besides the drive's and the beam's, which the motor supplies and a
/// position loop must overcome (`base_friction`, `cogging_ripple`): Coulomb friction
/// `F_c tanh(v / 1 mm/s)`, viscous `c_v v`, cogging `a sin(2πy/p) + b cos(2πy/p)` (N; y in m,
/// v in m/s). Inside a loop of finite stiffness they leave a following error: a Coulomb force
/// over K_p = M ω_n² is a step of F_c / K_p at every reversal, which the integral action then
/// removes (Ellis, *Control System Design Guide*, 4th ed., ch. 17, disturbance response).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CarriageLoad {
    /// Coulomb friction (N).
    pub friction_n: f64,
    /// Viscous friction (N·s/m).
    pub viscous_n_s_per_m: f64,
    /// Cogging: sine and cosine amplitudes (N) and pitch (m).
    pub cogging: Option<(f64, f64, f64)>,
}

impl CarriageLoad {
    /// The load of `p`; `None` when it has neither friction nor cogging.
    pub fn of(p: &Params) -> Option<CarriageLoad> {
        let load = CarriageLoad {
            friction_n: p.friction_n,
            viscous_n_s_per_m: p.viscous_n_s_per_m,
            cogging: p.cogging,
        };
        (load != CarriageLoad::default()).then_some(load)
    }

    /// The load divided by the moving mass `mass_kg`: its force per unit mass (N/kg), what a
    /// loop simulated per unit mass (a rig without a beam) carries.
    pub fn per_unit_mass(&self, mass_kg: f64) -> CarriageLoad {
        let m = mass_kg.max(1e-9);
        CarriageLoad {
            friction_n: self.friction_n / m,
            viscous_n_s_per_m: self.viscous_n_s_per_m / m,
            cogging: self.cogging.map(|(a, b, pitch)| (a / m, b / m, pitch)),
        }
    }

    /// The force the motor spends on the load (N) at carriage position `y_m` and velocity
    /// `v_m_s`.
    pub fn force_n(&self, y_m: f64, v_m_s: f64) -> f64 {
        let mut f = self.friction_n * (v_m_s / FRICTION_SMOOTHING_M_S).tanh()
            + self.viscous_n_s_per_m * v_m_s;
        if let Some((a, b, pitch)) = self.cogging {
            let (s, co) = (2.0 * std::f64::consts::PI * y_m / pitch).sin_cos();
            f += a * s + b * co;
        }
        f
    }

    /// Steps per sample interval `dt` (1–32) over which the load, held constant in each, acts on
    /// a carriage of effective mass `m_eff_kg` without ringing: the smoothed friction is a
    /// damper of rate λ = (F_c / v_s + |c_v|) / m, and a held damper decays without overshoot
    /// for λh ≤ 1.
    fn substeps(&self, m_eff_kg: f64, dt: f64) -> usize {
        let rate = (self.friction_n.abs() / FRICTION_SMOOTHING_M_S + self.viscous_n_s_per_m.abs())
            / m_eff_kg.max(1e-9);
        ((rate * dt).ceil() as usize).clamp(1, 32)
    }
}

/// Carriage position under a position loop that carries the beam: the loop force
/// `F = M [k_a r̈ + 2ζω (k_v ṙ − ẏ) + ω² (r − y)]` (M the total moving mass the drive is tuned
/// for) acts on the carriage, which the beam modes push back (eq. 5 in modal form):
/// `(M − ΣΓ²) ÿ = F + Σ Γ_r (2ζ_rω_r η̇_r + ω_r² η_r)`, `η̈_r + 2ζ_rω_r η̇_r + ω_r² η_r = −Γ_r ÿ`.
/// For a rigid load this is the uncoupled loop of [`second_order`]. Exact for a piecewise-linear
/// command (r̈ as kicks at the samples): one matrix exponential per parameter set. A carriage
/// `load` (friction, cogging) acts on the carriage as `− F_load(y, ẏ)` ([`LoadedLoop`]).
fn coupled_servo(
    r: &[f64],
    dt: f64,
    omega: f64,
    zeta: f64,
    ff: (f64, f64),
    c: &BeamCache,
    load: Option<&CarriageLoad>,
) -> Vec<f64> {
    let n = r.len();
    let nm = c.omega.len();
    let m_tot = c.total_mass;
    let sum_g2: f64 = c.gamma.iter().map(|g| g * g).sum();
    let m_eff = (m_tot - sum_g2).max(1e-9 * m_tot);
    let (kv, ka) = ff;
    // z = [y, ẏ, (η_j, η̇_j)…, F_load?, r, ṙ]; within a sample interval r is linear (ṙ
    // constant), so the interval map is exactly exp(A dt)
    let dim = 4 + 2 * nm + usize::from(load.is_some());
    let (ri, vi) = (dim - 2, dim - 1);
    let li = load.map(|_| 2 + 2 * nm);
    let mut acc_row = vec![0.0; dim];
    acc_row[0] = -m_tot * omega * omega / m_eff;
    acc_row[1] = -m_tot * 2.0 * zeta * omega / m_eff;
    acc_row[ri] = m_tot * omega * omega / m_eff;
    acc_row[vi] = m_tot * 2.0 * zeta * omega * kv / m_eff;
    if let Some(li) = li {
        acc_row[li] = -1.0 / m_eff;
    }
    let generator = |damper: f64| {
        let mut row = acc_row.clone();
        row[1] -= damper / m_eff;
        root_generator(&mut row, m_eff, Some(c))
    };
    let Some(phi) = bounded_expm(generator(0.0), dt, 1e4) else {
        return vec![f64::NAN; n];
    };
    let loaded = match load.zip(li) {
        Some((l, li)) => match LoadedLoop::new(l, li, m_eff, dt, &generator, 1e4) {
            Some(ll) => Some(ll),
            None => return vec![f64::NAN; n],
        },
        None => None,
    };
    let mut saved = vec![0.0; dim];
    let (mut zv, mut tmp) = (vec![0.0; dim], vec![0.0; dim]);
    zv[0] = r[0];
    let mut y = Vec::with_capacity(n);
    let mut v_prev = 0.0;
    for k in 0..n {
        y.push(zv[0]);
        let v = if k + 1 < n {
            (r[k + 1] - r[k]) / dt
        } else {
            0.0
        };
        // acceleration feed-forward of the velocity step at this sample: an impulse
        let kick = ka * m_tot * (v - v_prev) / m_eff;
        zv[1] += kick;
        for j in 0..nm {
            zv[3 + 2 * j] -= c.gamma[j] * kick;
        }
        v_prev = v;
        zv[ri] = r[k];
        zv[vi] = v;
        match &loaded {
            Some(ll) => ll.advance(&phi, &mut zv, &mut tmp, &mut saved),
            None => advance(&phi, &mut zv, &mut tmp),
        }
        if !zv[0].is_finite() {
            y.extend(std::iter::repeat(f64::NAN).take(n - y.len()));
            break;
        }
    }
    y
}

/// A loop whose carriage carries a [`CarriageLoad`] (state index `li` holds the load's force,
/// constant over a step), stepped one sample interval at a time by a linearly implicit map
/// (a Rosenbrock step; Hairer & Wanner, *Solving ODEs II*, IV.7): the load is stiff only
/// inside the friction's smoothing band (|v| ≲ v_s), where the smoothed Coulomb force is a
/// damper of slope s(v) = F_c sech²(v/v_s) / v_s + c_v that a held force over a whole interval
/// would overshoot (s dt / m ≫ 1 at 100 Hz: a chatter of F_c dt / m).
/// - The interval map with a damper c_k in the generator — one of a ladder c_k = s(0) 2^−k,
///   k = 0…[`LADDER_RUNGS`] − 1, the rung nearest the slope at the interval's start — is exact
///   for the load linearised there, `F(v₀) + c_k (v − v₀)`: the remainder F(v₀) − c_k v₀ is held.
/// - Below the last rung (|v| ≳ 3 v_s: tanh saturated) the whole force is held.
/// - Either is taken only if the velocity ends the interval where that linearisation holds
///   (its slope within one rung, the same sign away from rest); otherwise the interval is
///   stepped again from its start in [`CarriageLoad::substeps`] held steps (λh ≤ 1).
struct LoadedLoop<'a> {
    load: &'a CarriageLoad,
    li: usize,
    steps: usize,
    /// s(0) = F_c / v_s + c_v (N·s/m): the friction's slope at rest.
    c_lin: f64,
    /// The damped interval maps of the ladder and the substep map; `None` when one held step
    /// per interval suffices (`steps` 1: cogging alone, or friction too weak to ring).
    maps: Option<(Vec<nalgebra::DMatrix<f64>>, nalgebra::DMatrix<f64>)>,
}

/// Rungs of the ladder of damped maps of [`LoadedLoop`] (slopes s(0) down to s(0) / 2⁷).
const LADDER_RUNGS: usize = 8;

impl<'a> LoadedLoop<'a> {
    /// From the loop's generator as a function of an extra carriage damper (N·s/m), with the
    /// element bound `limit` of [`bounded_expm`]; `None` when a map is out of bounds.
    fn new(
        load: &'a CarriageLoad,
        li: usize,
        m_eff: f64,
        dt: f64,
        generator: &dyn Fn(f64) -> nalgebra::DMatrix<f64>,
        limit: f64,
    ) -> Option<LoadedLoop<'a>> {
        let steps = load.substeps(m_eff, dt);
        let c_lin = load.friction_n / FRICTION_SMOOTHING_M_S + load.viscous_n_s_per_m;
        let maps = if steps == 1 || !(c_lin > 0.0) {
            None
        } else {
            let ladder = (0..LADDER_RUNGS)
                .map(|k| bounded_expm(generator(c_lin * 0.5f64.powi(k as i32)), dt, limit))
                .collect::<Option<Vec<_>>>()?;
            Some((
                ladder,
                bounded_expm(generator(0.0), dt / steps as f64, limit)?,
            ))
        };
        Some(LoadedLoop {
            load,
            li,
            steps: if maps.is_some() { steps } else { 1 },
            c_lin,
            maps,
        })
    }

    /// The slope of the load's force in the velocity (N·s/m) at `v_m_s`.
    fn slope(&self, v_m_s: f64) -> f64 {
        let u = (v_m_s / FRICTION_SMOOTHING_M_S).cosh();
        self.load.friction_n / (FRICTION_SMOOTHING_M_S * u * u) + self.load.viscous_n_s_per_m
    }

    /// The ladder's rung for velocity `v_m_s`: the nearest slope (log scale), or
    /// [`LADDER_RUNGS`] below the last.
    fn rung(&self, v_m_s: f64) -> usize {
        let k = (self.c_lin / self.slope(v_m_s)).log2().round();
        if k.is_finite() && k >= 0.0 {
            (k as usize).min(LADDER_RUNGS)
        } else {
            0
        }
    }

    /// One sample interval from `z` (`phi` the whole interval's map without a damper; `tmp`
    /// and `saved` scratch of the state's length).
    fn advance(
        &self,
        phi: &nalgebra::DMatrix<f64>,
        z: &mut [f64],
        tmp: &mut [f64],
        saved: &mut [f64],
    ) {
        let li = self.li;
        let v0 = z[1];
        let Some((ladder, sub)) = &self.maps else {
            z[li] = self.load.force_n(z[0], v0);
            advance(phi, z, tmp);
            return;
        };
        saved.copy_from_slice(z);
        let k = self.rung(v0);
        match ladder.get(k) {
            Some(map) => {
                let c_k = self.c_lin * 0.5f64.powi(k as i32);
                z[li] = self.load.force_n(z[0], v0) - c_k * v0;
                advance(map, z, tmp);
            }
            None => {
                z[li] = self.load.force_n(z[0], v0);
                advance(phi, z, tmp);
            }
        }
        // the linearisation held: the slope at the end within one rung, and no crossing of
        // the stiff band from one side to the other (at rest, k ≤ 1, the band is the map's)
        let k_end = self.rung(z[1]);
        if k_end.abs_diff(k) <= 1 && (k <= 1 || z[1] * v0 > 0.0) {
            return;
        }
        z.copy_from_slice(saved);
        for _ in 0..self.steps {
            z[li] = self.load.force_n(z[0], z[1]);
            advance(sub, z, tmp);
        }
    }
}

/// One sample interval's transition matrix exp(A·dt) of a beam root driven through a coupled
/// carriage: state z = [y_r, ẏ_r, (η_j, η̇_j)…, u, u̇] where `acc_row` gives ÿ_r as a linear
/// form of z (the caller sets the carriage terms; the beam's reaction
/// Σ Γ_j (ω_j² η_j + 2ζ_jω_j η̇_j) / m_eff is filled in here), each mode obeys η̈_j + 2ζ_jω_j η̇_j + ω_j² η_j = −Γ_j ÿ_r, and the drive u moves
/// at constant u̇ over the interval. `None` for a parameter set far outside the band (ω·dt ≫ 1)
/// or non-finite (the matrix exponential's scaling-and-squaring would not end on an infinite
/// norm).
fn root_transition(
    acc_row: &mut [f64],
    m_eff: f64,
    c: &BeamCache,
    dt: f64,
) -> Option<nalgebra::DMatrix<f64>> {
    bounded_expm(root_generator(acc_row, m_eff, Some(c)), dt, 1e4)
}

/// The generator A of [`root_transition`] (dimension `acc_row.len()`; rows of states other
/// than the root, the modes and the drive are left zero for the caller). Without a beam
/// (`c = None`) the root is a rigid mass: `acc_row` alone.
fn root_generator(
    acc_row: &mut [f64],
    m_eff: f64,
    c: Option<&BeamCache>,
) -> nalgebra::DMatrix<f64> {
    let dim = acc_row.len();
    let nm = c.map_or(0, |c| c.omega.len());
    if let Some(c) = c {
        for j in 0..nm {
            let (om, z) = (c.omega[j], c.zeta[j]);
            acc_row[2 + 2 * j] = c.gamma[j] * om * om / m_eff;
            acc_row[3 + 2 * j] = c.gamma[j] * 2.0 * z * om / m_eff;
        }
    }
    let mut a = nalgebra::DMatrix::<f64>::zeros(dim, dim);
    a[(0, 1)] = 1.0;
    for i in 0..dim {
        a[(1, i)] = acc_row[i];
    }
    if let Some(c) = c {
        for j in 0..nm {
            let (om, z) = (c.omega[j], c.zeta[j]);
            let (q, qd) = (2 + 2 * j, 3 + 2 * j);
            a[(q, qd)] = 1.0;
            for i in 0..dim {
                a[(qd, i)] = -c.gamma[j] * acc_row[i];
            }
            a[(qd, qd)] -= 2.0 * z * om;
            a[(qd, q)] -= om * om;
        }
    }
    a[(dim - 2, dim - 1)] = 1.0;
    a
}

/// A state or transition element below 1e-200 (SI units) is zero ([`at_rest`]): far below any
/// sensor, far above the subnormal range (below 2.2e-308), where one floating-point operation
/// costs about a hundred cycles. A mode that has rung down while the drive stands still (a
/// heavily damped high mode, a few seconds) would otherwise spend the rest of the recording
/// there: measured, half the run time of a 1000 Hz diagnosis (docs/diagnose.md, session 27).
const FLUSH_TO_ZERO: f64 = 1e-200;

/// `v`, or 0 when |v| < [`FLUSH_TO_ZERO`].
#[inline]
fn at_rest(v: f64) -> f64 {
    if v.abs() < FLUSH_TO_ZERO {
        0.0
    } else {
        v
    }
}

/// One interval of a sampled state-space model: `z ← Φ z` (Φ `dim × dim`, `z` and the scratch
/// `tmp` of length `dim`), without allocating. The sums run column by column as nalgebra's
/// matrix–vector product does, so the result is the same to the bit, but for components held
/// [`at_rest`]. Compiled for AVX as well and chosen at run time where the processor has it
/// (`multiversion`): the same arithmetic four lanes wide, so the same result.
#[multiversion::multiversion(targets("x86_64+avx"))]
fn advance(phi: &nalgebra::DMatrix<f64>, z: &mut [f64], tmp: &mut [f64]) {
    let dim = z.len();
    let a = phi.as_slice();
    tmp.iter_mut().for_each(|v| *v = 0.0);
    for (j, &zj) in z.iter().enumerate() {
        let col = &a[j * dim..(j + 1) * dim];
        for (t, c) in tmp.iter_mut().zip(col) {
            *t += c * zj;
        }
    }
    z.iter_mut()
        .zip(tmp.iter())
        .for_each(|(z, t)| *z = at_rest(*t));
}

/// exp(A·dt), or `None` for a generator far outside the band (largest element of A dt ≥
/// `limit`) or non-finite (the scaling-and-squaring would not end on an infinite norm).
fn bounded_expm(a: nalgebra::DMatrix<f64>, dt: f64, limit: f64) -> Option<nalgebra::DMatrix<f64>> {
    let ad = a * dt;
    let norm = ad.amax();
    if !(norm.is_finite() && norm < limit) {
        return None;
    }
    let phi = ad.exp().map(at_rest);
    phi.iter().all(|v| v.is_finite()).then_some(phi)
}

/// ω/ω_n of a PID loop (orders 3–4 of [`ServoLaw`]): its pole pair ω over its natural frequency
/// ω_n = √(K_p/M), 1/√(1 + 2ζα) for damping ratio ζ and integral ratio α (both taken ≥ 0);
/// 1 at α = 0, the PD loop.
pub fn pole_pair_ratio(zeta: f64, integral_ratio: f64) -> f64 {
    1.0 / (1.0 + 2.0 * zeta.max(0.0) * integral_ratio.max(0.0)).sqrt()
}

/// A position loop of selectable order (the `servo_lag` candidate), as the command → base
/// transfer function of a rigid carriage (and, coupled, with the beam pushing back):
/// - order 1: a first-order lag with velocity feed-forward, `ẏ = k_v ṙ + ω (r − y)`;
/// - order 2: PD with feed-forward, poles `s² + 2ζωs + ω²` ([`second_order`], [`coupled_servo`]);
/// - order 3: PID with feed-forward, `F/M = k_a r̈ + K_d (k_v ṙ − ẏ) + K_p (r − y) + K_i ∫(r − y)`
///   with the rigid closed-loop poles `(s² + 2ζωs + ω²)(s + αω)`: `K_d = (2ζ + α)ω`,
///   `K_p = (1 + 2ζα)ω²`, `K_i = αω³` (α → 0 is the PD loop); the fitted bandwidth is the
///   natural frequency ω_n = √K_p = ω√(1 + 2ζα) ([`ServoLaw::natural_frequency_rad_s`]), the
///   quantity a PID tuned for a bandwidth sets, so α and ζ shape the loop without moving it;
/// - order 4: the order-3 loop whose drive force follows its command through a first-order lag
///   of time constant β/ω (current loop, digital computation delay): `τ Ḟ = F_c − F`.
///
/// Source: Ellis, *Control System Design Guide* (4th ed., 2012), ch. 17 (position loops with
/// velocity/acceleration feed-forward); the order is chosen by the selection's information
/// criterion among the fitted forms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoLaw {
    /// Order 1–4.
    pub order: usize,
    /// ω (rad/s).
    pub omega: f64,
    /// ζ (orders ≥ 2).
    pub zeta: f64,
    /// Velocity and acceleration feed-forward fractions k_v, k_a.
    pub ff: (f64, f64),
    /// α (orders ≥ 3).
    pub integral_ratio: f64,
    /// β (order 4).
    pub force_lag_ratio: f64,
}

impl ServoLaw {
    /// The law of `p` (`None` without a servo). `p.servo.0` is the loop's natural frequency
    /// ω_n/2π = √(K_p/M)/2π (Hz, [`Params::servo`]); orders 3–4 place their poles at
    /// ω = ω_n/√(1 + 2ζα), since K_p = (1 + 2ζα)ω².
    pub fn of(p: &Params) -> Option<ServoLaw> {
        let (f, z) = p.servo?;
        let order = p.servo_order.clamp(1, 4);
        let integral_ratio = p.servo_integral_ratio.max(0.0);
        let to_pole = if order >= 3 {
            pole_pair_ratio(z, integral_ratio)
        } else {
            1.0
        };
        Some(ServoLaw {
            order,
            omega: 2.0 * std::f64::consts::PI * f * to_pole,
            zeta: z,
            ff: p.servo_ff,
            integral_ratio,
            force_lag_ratio: p.servo_force_lag_ratio.max(0.0),
        })
    }

    /// The loop's natural frequency ω_n = √(K_p/M) (rad/s): the proportional (stiffness) gain
    /// per unit carriage mass, the `servo_bandwidth_hz` the report gives (× 1/2π). It is ω for
    /// orders 1–2 and ω√(1 + 2ζα) for orders 3–4 (the struct's header). A parallel PID tuned
    /// as K_p = Mω_b² has it at its design bandwidth ω_b whatever its integral and derivative
    /// gains, which the pole pair ω alone does not (ω = ω_n/2.2 at α = 2.9, ζ 0.64).
    pub fn natural_frequency_rad_s(&self) -> f64 {
        if self.order >= 3 {
            self.omega / pole_pair_ratio(self.zeta, self.integral_ratio)
        } else {
            self.omega
        }
    }

    /// Largest gain |Y/R(jω)| of the command → base transfer function for a rigid load
    /// (the struct's header; order 1 `(k_v s + ω)/(s + ω)`, orders 2–4
    /// `(k_a s³ + K_d k_v s² + K_p s + K_i) / (τ s⁴ + s³ + K_d s² + K_p s + K_i)` with K_i = 0 and
    /// τ = 0 below order 3 and 4), over 0.01–100 × ω on a log grid of 801 points. A tuned loop
    /// peaks at 1–1.3; the plain second-order loop at ζ 0.3 at 1.75.
    pub fn peak_gain(&self) -> f64 {
        use nalgebra::Complex;
        let w = self.omega;
        let (z, al) = (
            self.zeta,
            if self.order >= 3 {
                self.integral_ratio
            } else {
                0.0
            },
        );
        let (kd, kp, ki) = (
            (2.0 * z + al) * w,
            (1.0 + 2.0 * z * al) * w * w,
            al * w * w * w,
        );
        let tau = if self.order >= 4 {
            self.force_lag_ratio / w
        } else {
            0.0
        };
        let (kv, ka) = self.ff;
        (0..=800)
            .map(|i| {
                let s = Complex::new(0.0, w * 10f64.powf(-2.0 + i as f64 / 200.0));
                let h = if self.order == 1 {
                    (s * kv + w) / (s + w)
                } else {
                    (s * s * s * ka + s * s * (kd * kv) + s * kp + ki)
                        / (s * s * s * s * tau + s * s * s + s * s * kd + s * kp + ki)
                };
                h.norm()
            })
            .fold(0.0, f64::max)
    }

    /// Base position for the command `r` sampled every `dt` s (piecewise linear between
    /// samples), coupled to the beam of `c` when given (the loop force then acts on the
    /// carriage, eq. 5 in modal form), else for a rigid load. Orders 2–4 carry the carriage
    /// `load` as well (friction and cogging the loop must overcome, [`CarriageLoad`]): in N
    /// with a beam, per unit moving mass (N/kg, [`CarriageLoad::per_unit_mass`]) without;
    /// order 1 has no mass to load.
    pub fn respond(
        &self,
        r: &[f64],
        dt: f64,
        c: Option<&BeamCache>,
        load: Option<&CarriageLoad>,
    ) -> Vec<f64> {
        match (self.order, c, load) {
            (1, _, _) => first_order(r, dt, self.omega, self.ff.0),
            (2, None, None) => second_order(
                r,
                dt,
                self.omega,
                self.zeta,
                1.0 - self.ff.0,
                1.0 - self.ff.1,
            ),
            (2, Some(c), _) => coupled_servo(r, dt, self.omega, self.zeta, self.ff, c, load),
            // a loaded rigid PD loop is the PID loop without integral action
            _ => self.pid(r, dt, c, load),
        }
    }

    /// Orders 3–4 (state space, exact per sample by one matrix exponential; a carriage `load`
    /// is stepped by [`LoadedLoop`]).
    fn pid(
        &self,
        r: &[f64],
        dt: f64,
        c: Option<&BeamCache>,
        load: Option<&CarriageLoad>,
    ) -> Vec<f64> {
        let n = r.len();
        let nm = c.map_or(0, |c| c.omega.len());
        let generator = |damper: f64| self.pid_generator(c, load.is_some(), damper);
        let (a, g, tau) = generator(0.0);
        // the drive-force row scales as ω³/β (m/s² per state unit): a larger element bound than
        // the root transition's, still finite
        let Some(phi) = bounded_expm(a, dt, 1e10) else {
            return vec![f64::NAN; n];
        };
        let lag = tau > 0.0;
        let dim = phi.nrows();
        let (fi, ri, vi) = (3 + 2 * nm, dim - 2, dim - 1);
        let m_eff = c.map_or(1.0, |c| c.total_mass) / g;
        let loaded = match load {
            Some(l) => match LoadedLoop::new(l, dim - 3, m_eff, dt, &|d| generator(d).0, 1e10) {
                Some(ll) => Some(ll),
                None => return vec![f64::NAN; n],
            },
            None => None,
        };
        let mut saved = vec![0.0; dim];
        let gamma: &[f64] = c.map_or(&[], |c| &c.gamma);
        let (mut zv, mut tmp) = (vec![0.0; dim], vec![0.0; dim]);
        zv[0] = r[0];
        let mut y = Vec::with_capacity(n);
        let mut v_prev = 0.0;
        for k in 0..n {
            y.push(zv[0]);
            let v = if k + 1 < n {
                (r[k + 1] - r[k]) / dt
            } else {
                0.0
            };
            // acceleration feed-forward of the velocity step at this sample: an impulse of
            // force (through the drive lag when there is one)
            let imp = self.ff.1 * (v - v_prev);
            if lag {
                zv[fi] += imp / tau;
            } else {
                zv[1] += g * imp;
                for j in 0..nm {
                    zv[3 + 2 * j] -= gamma[j] * g * imp;
                }
            }
            v_prev = v;
            zv[ri] = r[k];
            zv[vi] = v;
            match &loaded {
                Some(ll) => ll.advance(&phi, &mut zv, &mut tmp, &mut saved),
                None => advance(&phi, &mut zv, &mut tmp),
            }
            if !zv[0].is_finite() {
                y.extend(std::iter::repeat(f64::NAN).take(n - y.len()));
                break;
            }
        }
        y
    }

    /// The generator A of the order-3/4 loop (state `[y, ẏ, (η_j, η̇_j)…, ∫(r − y), F?,
    /// F_load?, r, ṙ]`, the load's force present with `loaded`) with an extra carriage damper
    /// (N·s/m), the ratio g = M / (M − ΣΓ²) of the force on the carriage to its acceleration
    /// per unit moving mass, and the drive lag τ (0 without).
    fn pid_generator(
        &self,
        c: Option<&BeamCache>,
        loaded: bool,
        damper: f64,
    ) -> (nalgebra::DMatrix<f64>, f64, f64) {
        let nm = c.map_or(0, |c| c.omega.len());
        let (m_tot, sum_g2) = c.map_or((1.0, 0.0), |c| {
            (c.total_mass, c.gamma.iter().map(|g| g * g).sum())
        });
        let m_eff = (m_tot - sum_g2).max(1e-9 * m_tot);
        let g = m_tot / m_eff;
        let (w, z, al) = (self.omega, self.zeta, self.integral_ratio);
        let (kd, kp, ki) = (
            (2.0 * z + al) * w,
            (1.0 + 2.0 * z * al) * w * w,
            al * w * w * w,
        );
        let lag = self.order >= 4 && self.force_lag_ratio > 0.0;
        let tau = if lag { self.force_lag_ratio / w } else { 0.0 };
        let ii = 2 + 2 * nm;
        let fi = ii + 1;
        let dim = ii + 1 + usize::from(lag) + usize::from(loaded) + 2;
        let (ri, vi) = (dim - 2, dim - 1);
        // the commanded force per unit moving mass (without the r̈ feed-forward impulses)
        let mut uc = vec![0.0; dim];
        uc[0] = -kp;
        uc[1] = -kd;
        uc[ii] = ki;
        uc[ri] = kp;
        uc[vi] = kd * self.ff.0;
        let mut acc_row = vec![0.0; dim];
        if lag {
            acc_row[fi] = g;
        } else {
            for i in 0..dim {
                acc_row[i] = g * uc[i];
            }
        }
        if loaded {
            acc_row[dim - 3] = -1.0 / m_eff;
        }
        acc_row[1] -= damper / m_eff;
        let mut a = root_generator(&mut acc_row, m_eff, c);
        a[(ii, 0)] = -1.0;
        a[(ii, ri)] = 1.0;
        if lag {
            for i in 0..dim {
                a[(fi, i)] = uc[i] / tau;
            }
            a[(fi, fi)] -= 1.0 / tau;
        }
        (a, g, tau)
    }
}

/// y = r + e with `ė + ωe = −(1 − k_v) ṙ` (a first-order lag with velocity feed-forward k_v),
/// exact for a piecewise-linear r.
fn first_order(r: &[f64], dt: f64, omega: f64, kv: f64) -> Vec<f64> {
    let a = (-omega * dt).exp();
    let b = if omega * dt > 1e-12 {
        (1.0 - a) / omega
    } else {
        dt
    };
    let n = r.len();
    let mut e = 0.0;
    let mut y = Vec::with_capacity(n);
    for k in 0..n {
        y.push(r[k] + e);
        let v = if k + 1 < n {
            (r[k + 1] - r[k]) / dt
        } else {
            0.0
        };
        e = at_rest(a * e - (1.0 - kv) * v * b);
    }
    y
}

/// What [`coupled_mount`] returns, per sample: the root position (m), the tip deflection
/// Σ tip_j η_j (m) and the force the carriage's mount spring and damper pass to the mount mass
/// and the beam (N, the mean over the interval centred on the sample), all from the exact
/// state.
struct MountResponse {
    root: Vec<f64>,
    tip_w: Vec<f64>,
    force: Vec<f64>,
}

/// Beam-root position behind a mount: a mass m_m on a spring–damper from the carriage y, loaded
/// by the beam (as the truth plant, `tools/src/truth/plant.rs`):
/// `(m_m + m_b − ΣΓ²) ÿ_r = k (y − y_r) + c (ẏ − ẏ_r) + Σ Γ_j (2ζ_jω_j η̇_j + ω_j² η_j)`,
/// `η̈_j + 2ζ_jω_j η̇_j + ω_j² η_j = −Γ_j ÿ_r`, k = ω_m² (m_m + m_b), c = 2ζ_m ω_m (m_m + m_b).
/// Exact for a piecewise-linear y (the matrix exponential over half a sample, squared for a whole
/// sample). The tip and the force come from the same exact state: the root rings at the mount
/// frequency, which a piecewise-linear resampling of it (the beam re-driven from the sampled
/// root) misrepresents when that frequency is a sizeable fraction of the sample rate. The
/// force is the momentum change of mount and beam over the interval centred on the sample,
/// `[(m_m + m_b) ẏ_r + Σ Γ_j η̇_j]` between the half-sample instants, over dt (the convention
/// of the rigid carriage's velocity kick in [`accel_at`]).
fn coupled_mount(
    y: &[f64],
    dt: f64,
    omega: f64,
    zeta: f64,
    m_m: f64,
    c: &BeamCache,
) -> MountResponse {
    let n = y.len();
    let nm = c.omega.len();
    let m_b = c.total_mass - c.base_mass;
    let sum_g2: f64 = c.gamma.iter().map(|g| g * g).sum();
    let m_eff = (m_m + m_b - sum_g2).max(1e-9);
    let k = omega * omega * (m_m + m_b);
    let cd = 2.0 * zeta * omega * (m_m + m_b);
    // z = [y_r, ẏ_r, (η_j, η̇_j)…, y, ẏ]
    let dim = 4 + 2 * nm;
    let (yi, vi) = (dim - 2, dim - 1);
    let mut acc_row = vec![0.0; dim];
    acc_row[0] = -k / m_eff;
    acc_row[1] = -cd / m_eff;
    acc_row[yi] = k / m_eff;
    acc_row[vi] = cd / m_eff;
    let nan = || MountResponse {
        root: vec![f64::NAN; n],
        tip_w: vec![f64::NAN; n],
        force: vec![f64::NAN; n],
    };
    let Some(phi_half) = root_transition(&mut acc_row, m_eff, c, 0.5 * dt) else {
        return nan();
    };
    // the momentum half a sample after a state z is mᵀ Φ_½ z = (Φ_½ᵀ m)ᵀ z: one product per
    // sample, the state itself advanced a whole sample at once
    let mut m = nalgebra::DVector::zeros(dim);
    m[1] = m_m + m_b;
    for j in 0..nm {
        m[3 + 2 * j] = c.gamma[j];
    }
    let momentum_half = phi_half.tr_mul(&m);
    let phi = &phi_half * &phi_half;
    let (mut zv, mut tmp) = (vec![0.0; dim], vec![0.0; dim]);
    zv[0] = y[0];
    let mut out = MountResponse {
        root: Vec::with_capacity(n),
        tip_w: Vec::with_capacity(n),
        force: Vec::with_capacity(n),
    };
    // momentum at the half-sample instant before the sample (at rest before the first)
    let mut p_before = 0.0;
    let mut v = 0.0;
    for kk in 0..n {
        out.root.push(zv[0]);
        out.tip_w
            .push((0..nm).map(|j| c.tip[j] * zv[2 + 2 * j]).sum::<f64>());
        // after the last sample the drive keeps its last velocity (as [`accel_at`])
        if kk + 1 < n {
            v = (y[kk + 1] - y[kk]) / dt;
        }
        zv[yi] = y[kk];
        zv[vi] = v;
        let p_after = momentum_half
            .iter()
            .zip(&zv)
            .map(|(a, b)| a * b)
            .sum::<f64>();
        out.force.push((p_after - p_before) / dt);
        p_before = p_after;
        advance(&phi, &mut zv, &mut tmp);
        if !zv[0].is_finite() {
            return nan();
        }
    }
    out
}

/// Cached structural model (rebuilt only when a structural parameter changes).
#[derive(Clone, Debug)]
pub struct BeamCache {
    key: Vec<f64>,
    omega: Vec<f64>,
    zeta: Vec<f64>,
    gamma: Vec<f64>,
    tip: Vec<f64>,
    /// root rotation per unit modal coordinate (0 without a compliant clamp)
    root_rot: Vec<f64>,
    /// the modes beyond `keep`, quasi-static: root rotation (rad) and tip deflection (m) per
    /// unit moment at the compliant clamp (N·m), [`ResidualFlexibility`]
    residual: ResidualFlexibility,
    /// mode shapes at the drag points: shape[r][j]
    shape: Vec<Vec<f64>>,
    weights: Vec<f64>,
    total_mass: f64,
    base_mass: f64,
    /// each mode's transition over half a sample interval (two make one)
    phi_half: Vec<nalgebra::Matrix2<f64>>,
    /// each mode's response to a linearly ramping force ([`mode_ramp`]); empty without a
    /// compliant clamp
    ramp: Vec<RampMaps>,
}

/// [`mode_ramp`] of one mode for a force ramping over a sample interval: at its end (`full`)
/// and at its middle (`half`); `quasi_static` for a mode of ω dt ≥ [`RAMP_LIMIT_RAD`], which
/// answers the clamp moment through [`ResidualFlexibility`] instead (its state takes none).
#[derive(Clone, Debug)]
struct RampMaps {
    full: (nalgebra::Matrix2<f64>, Vector2<f64>, Vector2<f64>),
    half: (nalgebra::Matrix2<f64>, Vector2<f64>, Vector2<f64>),
    quasi_static: bool,
}

/// ω dt (rad) from which a simulated mode answers a clamp moment quasi-statically: the ramp's
/// explicit part (the moment at the interval's start) feeds back through the clamp's tangent
/// stiffness, and with every simulated mode ramping (ω dt up to π) a hardening clamp at
/// 250 Hz diverged; with the limit at 2.6 or 2.0 it does not. At 1.0 a 100 Hz recording's
/// second mode (ω dt 1.22) lost its own amplitude-dependent frequency and the cubic fit moved
/// 2.3 % (docs/diagnose.md, session 52). The moment's content, a few times the lowest modes'
/// frequencies, lies well below a mode of ω dt ≥ 2.
const RAMP_LIMIT_RAD: f64 = 2.0;

impl RampMaps {
    /// The state at the end (`half` false) or middle of the interval from `x` (after the
    /// sample's impulses) with the modal force ramping from `f` to `f_next`.
    fn step(&self, half: bool, x: &Vector2<f64>, f: f64, f_next: f64) -> Vector2<f64> {
        let (phi, a, b) = if half { &self.half } else { &self.full };
        if self.quasi_static {
            phi * x
        } else {
            phi * x + (a - b) * f + b * f_next
        }
    }

    /// The displacement per unit force at the interval's end that [`RampMaps::step`] adds.
    fn next_gain(&self) -> f64 {
        if self.quasi_static {
            0.0
        } else {
            self.full.2[0]
        }
    }
}

/// The resonance (Hz) of a mount that carries the beam, as the rig shows it
/// ([`crate::model::mount::coupled_resonance_hz`]), for the model `p` with a coupled mount
/// (`p.mount` with `p.mount_mass_kg` > 0; its frequency is the rigid-beam one, k = (2π f)²
/// (m_m + m_b)) and the modes it simulates at sample interval `dt` (below the band edge).
/// `None` without a coupled mount or a beam.
pub fn mount_resonance_hz(rig: &Rig, p: &Params, dt: f64) -> Option<f64> {
    let (f, _) = p.mount?;
    if !(p.mount_mass_kg > 0.0) {
        return None;
    }
    let c = beam_cache(rig, p, dt).ok()?;
    let m_b = c.total_mass - c.base_mass;
    let k = (2.0 * std::f64::consts::PI * f).powi(2) * (p.mount_mass_kg + m_b);
    crate::model::mount::coupled_resonance_hz(k, p.mount_mass_kg, m_b, &c.gamma, &c.omega)
}

fn beam_cache(rig: &Rig, p: &Params, dt: f64) -> Result<BeamCache> {
    let opts = ModelOptions {
        n_modes: p.n_basis.clamp(1, 12),
        stiffness_scale: p.stiffness_scale,
        base_mass_delta_kg: p.base_mass_delta_kg,
        tip_mass_kg: p.tip_mass_kg,
        root_stiffness_nm_per_rad: p.root_stiffness_nm_per_rad,
        spring_position_m: p.spring_position_m,
        axial_load: p.orientation,
        point_mass: None,
        damping_ratios: p.zeta,
        tip_load_shape: p.tip_load_shape(),
    };
    let model = BeamModel::new(rig, &opts)?;
    let modes = model.clamped_modes()?;
    // the diagnosis's fixed mode count, else the modes below the band edge (0.45 × the sample
    // rate); the exact discretisation holds for any mode
    let edge = band_edge_hz(dt) * 2.0 * std::f64::consts::PI;
    let keep = p
        .simulated_modes
        .unwrap_or_else(|| modes.omega_rad_s.iter().take_while(|w| **w < edge).count())
        .clamp(1, modes.omega_rad_s.len());
    let l = model.length_m;
    let npts = 16;
    let off = usize::from(p.root_stiffness_nm_per_rad.is_some());
    let coords: Vec<Vec<f64>> = (0..npts)
        .map(|j| model.coordinate_deflections((j as f64 + 0.5) * l / npts as f64))
        .collect();
    let shape: Vec<Vec<f64>> = (0..keep)
        .map(|r| {
            coords
                .iter()
                .map(|c| {
                    c.iter()
                        .enumerate()
                        .map(|(i, v)| modes.shapes[(i, r)] * v)
                        .sum()
                })
                .collect()
        })
        .collect();
    let zeta: Vec<f64> = modes.zeta[..keep]
        .iter()
        .enumerate()
        .map(|(r, z)| {
            p.zeta_modes
                .as_ref()
                .and_then(|v| v.get(r).copied())
                .unwrap_or(*z)
                .clamp(0.0, 0.95)
        })
        .collect();
    let phi_half = (0..keep)
        .map(|r| mode_zoh(modes.omega_rad_s[r], zeta[r], 0.5 * dt).0)
        .collect();
    let (residual, ramp) = clamp_maps(&modes, &zeta, keep, dt, off == 1);
    Ok(BeamCache {
        key: structural_key(p, dt),
        omega: modes.omega_rad_s[..keep].to_vec(),
        zeta,
        gamma: modes.participation[..keep].to_vec(),
        tip: modes.tip[..keep].to_vec(),
        root_rot: (0..keep)
            .map(|r| if off == 1 { modes.shapes[(0, r)] } else { 0.0 })
            .collect(),
        residual,
        ramp,
        shape,
        weights: vec![l / npts as f64; npts],
        total_mass: model.mass[(0, 0)],
        base_mass: model.base_mass_kg,
        phi_half,
    })
}

/// The quasi-static response of the modes a simulation leaves out (residual flexibility, the
/// static correction of the mode-displacement method; Craig & Kurdila, *Fundamentals of
/// Structural Dynamics*, 2nd ed., §14.5) to a moment M at the compliant clamp: root rotation
/// `−root_rad_per_nm · M` and tip deflection `−tip_m_per_nm · M` beyond what the kept modes
/// carry.
///
/// Why: a root moment excites the clamp's own rotation, whose compliance lies mostly in modes
/// far above any sample rate (for a clamp 20 × stiffer than EI/l the first mode holds 17 % of
/// the static 1/k_r, the modes below 250 Hz 52 %, docs/diagnose.md session 52). A cubic clamp
/// moment applied to the kept modes only moves the root by a third to a half of what it does,
/// and the fitted k₃ grows to make up for it (2.6 % at 250 Hz, 4.9 % at 100 Hz on a noise-free
/// case).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ResidualFlexibility {
    /// Σ_{r ≥ keep} s_r² / ω_r² (rad / (N·m)).
    pub root_rad_per_nm: f64,
    /// Σ_{r ≥ keep} t_r s_r / ω_r² (m / (N·m)).
    pub tip_m_per_nm: f64,
}

impl ResidualFlexibility {
    /// From the mass-normalised modes of a complete (Galerkin or FE) eigen-solution: angular
    /// frequencies `omega_rad_s` (rad/s), tip deflection `tip` and root rotation `root_rot` per
    /// unit modal coordinate; `static_mode(r)` names the modes that answer quasi-statically
    /// (those not simulated, and those too fast for the sample interval). Over every mode the
    /// sums are the model's static compliance (K⁻¹), so the correction converges.
    pub fn of_modes(
        omega_rad_s: &[f64],
        tip: &[f64],
        root_rot: &[f64],
        static_mode: impl Fn(usize) -> bool,
    ) -> Self {
        let mut r = Self::default();
        for (i, ((w, t), s)) in omega_rad_s.iter().zip(tip).zip(root_rot).enumerate() {
            if static_mode(i) {
                r.root_rad_per_nm += s * s / (w * w);
                r.tip_m_per_nm += t * s / (w * w);
            }
        }
        r
    }
}

/// The compliant clamp's part of a [`BeamCache`] (`compliant`; defaults otherwise): the
/// quasi-static flexibility of the modes that do not simulate a clamp moment and the ramp
/// maps of the `keep` simulated ones with damping ratios `zeta`, at sample interval `dt`.
fn clamp_maps(
    modes: &crate::model::galerkin::ClampedModes,
    zeta: &[f64],
    keep: usize,
    dt: f64,
    compliant: bool,
) -> (ResidualFlexibility, Vec<RampMaps>) {
    if !compliant {
        return (ResidualFlexibility::default(), Vec::new());
    }
    let w = &modes.omega_rad_s;
    let residual = ResidualFlexibility::of_modes(
        w,
        &modes.tip,
        &modes.shapes.row(0).iter().copied().collect::<Vec<_>>(),
        |r| r >= keep || w[r] * dt >= RAMP_LIMIT_RAD,
    );
    let ramp = (0..keep)
        .map(|r| RampMaps {
            full: mode_ramp(w[r], zeta[r], dt, dt),
            half: mode_ramp(w[r], zeta[r], 0.5 * dt, dt),
            quasi_static: w[r] * dt >= RAMP_LIMIT_RAD,
        })
        .collect();
    (residual, ramp)
}

fn structural_key(p: &Params, dt: f64) -> Vec<f64> {
    let (z1, z2) = p.zeta.unwrap_or((-1.0, -1.0));
    let mut key = vec![
        p.stiffness_scale,
        z1,
        z2,
        p.base_mass_delta_kg,
        p.tip_mass_kg,
        p.root_stiffness_nm_per_rad.unwrap_or(-1.0),
        p.spring_position_m,
        match p.orientation {
            None => 0.0,
            Some(Orientation::Hanging) => 1.0,
            Some(Orientation::Upright) => -1.0,
        },
        dt,
        p.n_basis as f64,
        p.simulated_modes.map_or(-1.0, |n| n as f64),
    ];
    key.extend(p.zeta_modes.iter().flatten());
    key
}

/// The band edge (Hz) of a recording sampled every `dt` s: [`super::rate::PASS_EDGE`] (0.45) ×
/// the sample rate (90 % of Nyquist), the working band's pass edge. Modes below it are in the
/// model with their own damping ratio.
pub fn band_edge_hz(dt: f64) -> f64 {
    super::rate::PASS_EDGE / dt
}

/// The model's stated accuracy of its in-band natural frequencies (relative): [`converged_basis`]
/// adds basis functions until none of them moves by more than this when one more is added.
pub const BASIS_CONVERGENCE_REL: f64 = 1e-3;

/// How far the beam's structural parameters of `p` that `without` lacks (a tip mass, a root
/// spring) move the clamped natural frequencies below the band edge of sample interval `dt`:
/// the largest |f_r(p) / f_r(without) − 1| over the modes both have there (relative; the same
/// stiffness scale, so a shift common to every mode counts). `None` when either model is
/// refused or without a beam.
pub fn frequency_shift_rel(rig: &Rig, p: &Params, without: &Params, dt: f64) -> Option<f64> {
    frequency_ratios(rig, p, without, dt)?
        .iter()
        .map(|r| (r - 1.0).abs())
        .reduce(f64::max)
}

/// How far the cubic clamp of `p` (k₃, [`Params::cubic_root_stiffness_nm_per_rad3`], beside
/// its linear stiffness k_r) moves the clamped natural frequencies below the band edge of
/// sample interval `dt` between small motion and the recordings' peak: the shift
/// ([`frequency_shift_rel`]) from the linear clamp k_r to the describing-function stiffness
/// k_r + ¾ k₃ θ² of a root swinging with amplitude θ (Krylov–Bogoliubov first harmonic of
/// M = k_r θ + k₃ θ³). θ is read from `peak_deflection_m` (m, the largest tip deflection
/// relative to the carriage in the recordings) through the first mode's ratio of root
/// rotation to tip deflection. Relative; `None` without a beam, a compliant clamp or a
/// first mode with a tip deflection, or when a model is refused. A softening clamp that
/// loses its stiffness at the peak counts as an unbounded shift.
pub fn cubic_frequency_shift_rel(
    rig: &Rig,
    p: &Params,
    dt: f64,
    peak_deflection_m: f64,
) -> Option<f64> {
    let kr = p.root_stiffness_nm_per_rad?;
    let c = beam_cache(rig, p, dt).ok()?;
    let (s1, t1) = (*c.root_rot.first()?, *c.tip.first()?);
    if t1 == 0.0 || !(kr > 0.0) {
        return None;
    }
    let theta = peak_deflection_m * (s1 / t1).abs();
    let k_eq = kr + 0.75 * p.cubic_root_stiffness_nm_per_rad3 * theta * theta;
    if !(k_eq > 0.0) {
        return Some(f64::INFINITY);
    }
    let linear = Params {
        cubic_root_stiffness_nm_per_rad3: 0.0,
        ..p.clone()
    };
    let at_peak = Params {
        root_stiffness_nm_per_rad: Some(k_eq),
        ..linear.clone()
    };
    frequency_shift_rel(rig, &at_peak, &linear, dt)
}

/// f_r(p) / f_r(without) of the clamped modes both models keep below the band edge of `dt`;
/// `None` without a beam or when either model is refused.
fn frequency_ratios(rig: &Rig, p: &Params, without: &Params, dt: f64) -> Option<Vec<f64>> {
    rig.beam.as_ref()?;
    let (a, b) = (
        beam_cache(rig, p, dt).ok()?,
        beam_cache(rig, without, dt).ok()?,
    );
    Some(
        a.omega
            .iter()
            .zip(&b.omega)
            .map(|(wa, wb)| wa / wb)
            .collect(),
    )
}

/// The part of [`frequency_shift_rel`] that one stiffness scale cannot absorb: with d_r =
/// ln(f_r(p) / f_r(without)) over the modes below the band edge, the largest |d_r − c| for the
/// best common c, i.e. half the range of d_r (relative). Every natural frequency of a beam
/// without axial load scales with √(stiffness scale), so a shift common to every mode is a
/// recalibration, not evidence of the parameter. With a single in-band mode there is no ratio
/// to read: the plain shift of that mode. `None` as [`frequency_shift_rel`].
pub fn frequency_shift_beyond_scale_rel(
    rig: &Rig,
    p: &Params,
    without: &Params,
    dt: f64,
) -> Option<f64> {
    let d: Vec<f64> = frequency_ratios(rig, p, without, dt)?
        .iter()
        .map(|r| r.ln())
        .collect();
    let (lo, hi) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    match d.len() {
        0 => None,
        1 => Some(d[0].abs()),
        _ => Some(0.5 * (hi - lo)),
    }
}

/// Galerkin convergence of the modes below a band edge.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisChoice {
    /// Basis functions used.
    pub n_basis: usize,
    /// Clamped natural frequencies (Hz) of the modes below the band edge.
    pub freqs_hz: Vec<f64>,
    /// Largest relative change of those frequencies from `n_basis` to `n_basis + 1` functions.
    pub convergence_rel: f64,
    /// Lowest clamped modes simulated: every mode of the nominal model below the Nyquist
    /// frequency given (capped at the basis size), those between the band edge and Nyquist
    /// included (the sampled recordings show them). The count is fixed for a diagnosis, so no
    /// fitted parameter adds or removes a mode by moving it across a truncation (held-out
    /// 545001, a null at 50 Hz: its second mode at 22.51 Hz lay just above the 22.5 Hz band
    /// edge, and a hanging load, pulling it below, gained the mode and was named).
    pub simulated_modes: usize,
}

/// The smallest number of basis functions (4–11) for which every clamped mode below
/// `band_edge_hz` moves by less than [`BASIS_CONVERGENCE_REL`] when one more function is added,
/// and the modes to simulate for recordings whose highest Nyquist frequency is `nyquist_hz`.
///
/// Errors: the rig has no beam or the model refuses it.
pub fn converged_basis(
    rig: &Rig,
    stiffness_scale: f64,
    band_edge_hz: f64,
    nyquist_hz: f64,
) -> Result<BasisChoice> {
    let freqs = |n: usize| -> Result<Vec<f64>> {
        let m = BeamModel::new(
            rig,
            &ModelOptions {
                n_modes: n,
                stiffness_scale,
                ..Default::default()
            },
        )?;
        Ok(m.clamped_modes()?
            .omega_rad_s
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect())
    };
    let mut prev = freqs(4)?;
    let mut last = None;
    for n in 4..12 {
        let next = freqs(n + 1)?;
        let below = prev
            .iter()
            .take_while(|f| **f < band_edge_hz)
            .count()
            .max(1);
        let rel = (0..below.min(prev.len()))
            .map(|r| (prev[r] - next[r]).abs() / next[r])
            .fold(0.0, f64::max);
        let choice = BasisChoice {
            // one function more than the in-band modes so the last one is not the worst
            n_basis: n,
            freqs_hz: prev[..below.min(prev.len())].to_vec(),
            convergence_rel: rel,
            simulated_modes: prev
                .iter()
                .take_while(|f| **f < nyquist_hz)
                .count()
                .clamp(1, prev.len()),
        };
        if rel < BASIS_CONVERGENCE_REL && below < n {
            return Ok(choice);
        }
        last = Some(choice);
        prev = next;
    }
    Ok(last.expect("at least one basis size"))
}

thread_local! {
    /// Samples simulated by [`predict`] on this thread (every recording, every call).
    static SIMULATED_SAMPLES: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Samples [`predict`] has simulated on the calling thread so far: the work a diagnosis has
/// done, counted in the budget's unit (one diagnosis runs on one thread and counts what a
/// helper thread simulated for it, [`add_simulated_samples`]; [`super::forward::Budget`]).
pub fn simulated_samples() -> u64 {
    SIMULATED_SAMPLES.with(|c| c.get())
}

/// Counts `n` samples simulated for the calling thread by a helper thread
/// ([`super::fit::Problem::whitened_batch`]).
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
/// samples). When `d`'s inputs are [emphasised](super::rate::emphasise) against the model's
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
    use super::rate::{emphasise, emphasise_of};
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

/// Acceleration (m/s²) at sample k of a piecewise-linear path: the velocity step there / dt.
/// The path starts from rest and keeps its last velocity after the last sample (a recording
/// that ends mid-move says nothing of a stop; assuming one put a −v/dt spike of tens of N into
/// the last force sample, which the force calibration then bent its mass and latency to).
pub fn accel_at(y: &[f64], k: usize, dt: f64) -> f64 {
    velocity_step(y, k, dt) / dt
}

/// The velocity step (m/s) at sample k of the piecewise-linear path through `y` ([`accel_at`]
/// times dt): from rest before the first sample, none after the last.
fn velocity_step(y: &[f64], k: usize, dt: f64) -> f64 {
    let n = y.len();
    let vb = if k == 0 { 0.0 } else { (y[k] - y[k - 1]) / dt };
    let va = if k + 1 < n {
        (y[k + 1] - y[k]) / dt
    } else {
        vb
    };
    va - vb
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

/// Acceleration (m/s²) at every sample of the cubic spline through the samples `y` (spacing
/// `dt` s): its second derivatives M at the knots, `(M_{k−1} + 4 M_k + M_{k+1}) / 6 = a_k` with
/// a_k the piecewise-linear path's [`accel_at`] (the spline's continuity conditions; the rows of
/// the end samples keep only their inner neighbour). Both paths pass through every sample; the
/// linear one spreads a step of acceleration between two samples over three samples, the
/// spline recovers more of it (at Nyquist its gain is 3× the linear path's, exact
/// acceleration 2.47×), so the two bracket what the samples cannot say about the motion
/// between them (de Boor, *A Practical Guide to Splines*, ch. IV).
pub fn spline_accel(y: &[f64], dt: f64) -> Vec<f64> {
    let n = y.len();
    if n < 3 {
        return (0..n).map(|k| accel_at(y, k, dt)).collect();
    }
    // Thomas algorithm on the symmetric (1, 4, 1) / 6 system
    let mut c = vec![0.0; n];
    let mut m: Vec<f64> = (0..n).map(|k| accel_at(y, k, dt)).collect();
    let (off, diag) = (1.0 / 6.0, 4.0 / 6.0);
    c[0] = off / diag;
    m[0] /= diag;
    for k in 1..n {
        let den = diag - off * c[k - 1];
        c[k] = off / den;
        m[k] = (m[k] - off * m[k - 1]) / den;
    }
    for k in (0..n - 1).rev() {
        m[k] -= c[k] * m[k + 1];
    }
    m
}

/// Beam-root position: the drive through the play (`backlash`) and the mount (coupled to the
/// beam of `c` when it has a mass and there is a beam, else a filter the beam does not load);
/// with the coupled mount also the tip deflection and force of its exact state
/// ([`coupled_mount`]).
fn root_motion(
    p: &Params,
    drive: &[f64],
    dt: f64,
    c: Option<&BeamCache>,
) -> (Vec<f64>, Option<MountResponse>) {
    let played;
    let root_drive: &[f64] = if p.backlash_m != 0.0 {
        played = play(drive, p.backlash_m);
        &played
    } else {
        drive
    };
    match (p.mount, c) {
        (Some((f, z)), Some(c)) if p.mount_mass_kg > 0.0 => {
            let mut m = coupled_mount(
                root_drive,
                dt,
                2.0 * std::f64::consts::PI * f,
                z,
                p.mount_mass_kg,
                c,
            );
            (std::mem::take(&mut m.root), Some(m))
        }
        (Some((f, z)), _) => (
            second_order(root_drive, dt, 2.0 * std::f64::consts::PI * f, z, 0.0, 1.0),
            None,
        ),
        (None, _) => (root_drive.to_vec(), None),
    }
}

/// The beam's modes driven by the root motion (exact per sample for a piecewise-linear root,
/// with the drag and cubic-clamp impulses): the tip deflection (m) and the motor force (N) of
/// eq. (5), the carriage (less a mount mass) moving with `drive`.
///
/// The force is the drive's reading of it: its mean over the sample period, here the interval
/// centred on the sample (the force channel's calibrated latency places it). For the beam that
/// is its momentum change between the half-sample instants over dt, `[M ẏ_r + Σ Γ_r η̇_r]/dt`,
/// exact for the piecewise-linear root — the convention of the carriage's own second
/// difference ([`accel_at`]) and of the coupled mount ([`coupled_mount`]). The instantaneous
/// modal force at the sample would carry a mode at f at 1/sinc(f dt) of what the drive
/// reports: 8 % high for a 22 Hz mode at 100 Hz, 32 % for a 20 Hz mode at 50 Hz, where the
/// calibration can absorb neither (docs/diagnose.md, session 20).
fn beam_response(
    p: &Params,
    root: &[f64],
    drive: &[f64],
    dt: f64,
    c: &BeamCache,
) -> (Vec<f64>, Vec<f64>) {
    let n = root.len();
    let mount_mass = if p.mount.is_some() {
        p.mount_mass_kg
    } else {
        0.0
    };
    let dv: Vec<f64> = (0..n).map(|k| velocity_step(root, k, dt)).collect();
    let k3 = match p.root_stiffness_nm_per_rad {
        Some(_) => p.cubic_root_stiffness_nm_per_rad3,
        None => 0.0,
    };
    let (w, beam_force) = if p.has_drag() || k3 != 0.0 {
        nonlinear_modes(p, k3, root, &dv, dt, c)
    } else {
        let (w, momentum_step) = linear_modes(c, &dv);
        (w, momentum_step.iter().map(|m| m / dt).collect())
    };
    let force = (0..n)
        .map(|k| {
            let acc = dv[k] / dt;
            // the carriage itself moves with the drive, not with the mount
            c.total_mass * acc
                + beam_force[k]
                + (c.base_mass - mount_mass) * (accel_at(drive, k, dt) - acc)
        })
        .collect();
    (w, force)
}

/// Modes driven through at once in [`linear_modes`] (independent chains the processor overlaps).
const MODE_LANES: usize = 4;

/// The linear modes of [`beam_response`] (no drag, no cubic clamp) for the root's velocity
/// steps `dv` (m/s, one per sample): the tip deflection `w` (m) and the modes' momentum change
/// `Σ Γ_r (η̇_r(k+½) − η̇_r(k−½))` (kg m/s) per sample. Each mode is independent of the others,
/// so [`MODE_LANES`] of them run side by side through the samples with their states in
/// registers; the arithmetic per mode is that of [`nonlinear_modes`] without its impulses.
fn linear_modes(c: &BeamCache, dv: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = dv.len();
    let nm = c.omega.len();
    let mut w = vec![0.0; n];
    let mut momentum_step = vec![0.0; n];
    for first in (0..nm).step_by(MODE_LANES) {
        // padding lanes: identity transition, no participation, no tip deflection
        let mut a = [[1.0, 0.0, 0.0, 1.0]; MODE_LANES];
        let (mut g, mut t) = ([0.0; MODE_LANES], [0.0; MODE_LANES]);
        for (j, r) in (first..nm.min(first + MODE_LANES)).enumerate() {
            let m = &c.phi_half[r];
            a[j] = [m[(0, 0)], m[(1, 0)], m[(0, 1)], m[(1, 1)]];
            (g[j], t[j]) = (c.gamma[r], c.tip[r]);
        }
        let (mut x0, mut x1, mut rate_before) =
            ([0.0; MODE_LANES], [0.0; MODE_LANES], [0.0; MODE_LANES]);
        for k in 0..n {
            let (mut tip, mut step) = (0.0, 0.0);
            for j in 0..MODE_LANES {
                tip += t[j] * x0[j];
                x1[j] += -g[j] * dv[k];
                let h0 = a[j][0] * x0[j] + a[j][2] * x1[j];
                let h1 = a[j][1] * x0[j] + a[j][3] * x1[j];
                step += g[j] * (h1 - rate_before[j]);
                rate_before[j] = h1;
                x0[j] = a[j][0] * h0 + a[j][2] * h1;
                x1[j] = a[j][1] * h0 + a[j][3] * h1;
            }
            w[k] += tip;
            momentum_step[k] += step;
            // a mode rung down is held at rest before it reaches the subnormal range
            if k % 64 == 0 {
                x0.iter_mut()
                    .chain(x1.iter_mut())
                    .for_each(|v| *v = at_rest(*v));
            }
        }
    }
    (w, momentum_step)
}

/// The modes of [`beam_response`] with the distributed drag and the cubic clamp's moment
/// (`k3`, N m/rad³), which couple them at every sample, for the root positions `root` (m) and
/// their velocity steps `dv` (m/s): the tip deflection (m) and the modes' force
/// `Σ Γ_r Δη̇_r / dt − drag` (N) per sample.
///
/// The drag acts as a per-sample impulse. The clamp moment M₃ is smooth (the cube of the
/// rotation) and ramps linearly between its values at the samples ([`mode_ramp`], exact per
/// mode), the one at the end of the interval solved with the rotation it produces
/// ([`cubic_step`]); the modes left out answer it quasi-statically ([`ResidualFlexibility`]).
fn nonlinear_modes(
    p: &Params,
    k3: f64,
    root: &[f64],
    dv: &[f64],
    dt: f64,
    c: &BeamCache,
) -> (Vec<f64>, Vec<f64>) {
    let n = dv.len();
    let nm = c.omega.len();
    let mut x = vec![Vector2::<f64>::zeros(); nm];
    // modal velocities at the half-sample instant before the sample (at rest before the first)
    let mut rate_before = vec![0.0; nm];
    let mut w = Vec::with_capacity(n);
    let mut force = Vec::with_capacity(n);
    let mut modal_f = vec![0.0; nm];
    let cubic = (k3 != 0.0).then(|| CubicClamp {
        k3,
        // the explicit part's stability: the modes that ramp
        cap2: cubic_cap2(
            k3,
            p.root_stiffness_nm_per_rad.unwrap_or(0.0),
            (0..nm)
                .filter(|&r| !c.ramp[r].quasi_static)
                .map(|r| c.root_rot[r] * c.root_rot[r])
                .sum(),
            dt,
        ),
        // the response to the interval's end moment, and the modes left out
        flexibility: c.residual.root_rad_per_nm
            + (0..nm)
                .map(|r| c.root_rot[r] * c.root_rot[r] * c.ramp[r].next_gain())
                .sum::<f64>(),
    });
    // the clamp moment at the current sample (at rest: 0)
    let mut m3 = 0.0;
    for (k, &dv) in dv.iter().enumerate() {
        // the root's velocity over the interval before the sample
        let vb = if k == 0 {
            0.0
        } else {
            (root[k] - root[k - 1]) / dt
        };
        modal_f.iter_mut().for_each(|f| *f = 0.0);
        let drag_total = if p.has_drag() {
            drag_impulses(p, vb, &x, c, &mut modal_f)
        } else {
            0.0
        };
        let mut f = -drag_total;
        let mut tip = -c.residual.tip_m_per_nm * m3;
        for r in 0..nm {
            tip += c.tip[r] * x[r][0];
            x[r][1] += -c.gamma[r] * dv + modal_f[r] * dt;
        }
        let m3_next = match &cubic {
            Some(cl) => cubic_step(cl, &x, m3, c),
            None => 0.0,
        };
        for r in 0..nm {
            let (now, next) = (-c.root_rot[r] * m3, -c.root_rot[r] * m3_next);
            let half = if cubic.is_some() {
                c.ramp[r].step(true, &x[r], now, next)
            } else {
                c.phi_half[r] * x[r]
            };
            f += c.gamma[r] * (half[1] - rate_before[r]) / dt;
            rate_before[r] = half[1];
            x[r] = if cubic.is_some() {
                c.ramp[r].step(false, &x[r], now, next).map(at_rest)
            } else {
                (c.phi_half[r] * half).map(at_rest)
            };
        }
        m3 = m3_next;
        w.push(tip);
        force.push(f);
    }
    (w, force)
}

/// A cubic clamp in [`nonlinear_modes`]: k₃ (N·m/rad³), the bound θ_c² of [`cubic_moment`]
/// (rad²) and the root rotation per unit end-of-interval moment that the moment itself adds
/// (rad / N·m: the kept modes' ramp response plus the residual flexibility).
struct CubicClamp {
    k3: f64,
    cap2: f64,
    flexibility: f64,
}

impl CubicClamp {
    /// The cubic moment M₃ (N·m, [`cubic_moment`]) where the modes alone would turn the root
    /// by `theta_free` (rad): at the root of θ + c M₃(θ) = θ_free (c = `flexibility`), by Newton
    /// from θ_free. θ + c M₃(θ) rises monotonically (softening keeps the tangent stiffness
    /// above k_r/10 and c < 1/k_r), so a few steps converge.
    fn moment(&self, theta_free: f64) -> f64 {
        let (c, k3, cap2) = (self.flexibility, self.k3, self.cap2);
        let mut theta = theta_free;
        if c > 0.0 {
            for _ in 0..8 {
                let m = cubic_moment(k3, theta, cap2);
                // dM₃/dθ / k₃: 3θ² below the bound, θ_c² beyond it
                let d = if theta * theta < cap2 {
                    3.0 * theta * theta
                } else {
                    cap2
                };
                let slope = 1.0 + c * k3 * d;
                let step = (theta + c * m - theta_free) / slope.max(0.05);
                theta -= step;
                if step.abs() <= 1e-12 * theta.abs().max(1e-12) {
                    break;
                }
            }
        }
        cubic_moment(k3, theta, cap2)
    }
}

/// The clamp moment M₃ (N·m) at the end of the interval that starts in the modal state `x`
/// (after the sample's impulses) with moment `m3`: the root of θ + c M₃(θ) = θ_free, θ_free
/// the rotation the modes reach with the moment held at `m3` less its ramp part, c the
/// clamp's `flexibility` ([`CubicClamp::moment`]).
fn cubic_step(cl: &CubicClamp, x: &[Vector2<f64>], m3: f64, c: &BeamCache) -> f64 {
    let theta_free: f64 = (0..x.len())
        .map(|r| {
            let s = c.root_rot[r];
            s * c.ramp[r].step(false, &x[r], -s * m3, 0.0)[0]
        })
        .sum();
    cl.moment(theta_free)
}

/// The quadratic drag of `p` as modal impulses, added to the modal forces `modal_f`; returns
/// the total drag force (N). Absolute velocity v = root velocity `v_root` + the modes'
/// velocities `x[r][1]` at each point:
/// - distributed, `−c_d |v| v` per unit length at the drag points (`drag_kg_per_m2`);
/// - on a body at the tip, `−c_t |v| v` at the tip (`tip_drag_kg_per_m`).
fn drag_impulses(
    p: &Params,
    v_root: f64,
    x: &[Vector2<f64>],
    c: &BeamCache,
    modal_f: &mut [f64],
) -> f64 {
    let mut total = 0.0;
    if p.drag_kg_per_m2 > 0.0 {
        for j in 0..c.weights.len() {
            let coef = p.drag_kg_per_m2 * c.weights[j];
            total += drag_at(coef, v_root, x, |r| c.shape[r][j], modal_f);
        }
    }
    if p.tip_drag_kg_per_m > 0.0 {
        total += drag_at(p.tip_drag_kg_per_m, v_root, x, |r| c.tip[r], modal_f);
    }
    total
}

/// The drag `−coef |v| v` (N) at one point whose mode shapes are `shape(r)`, added to the
/// modal forces `modal_f` ([`drag_impulses`]).
fn drag_at(
    coef: f64,
    v_root: f64,
    x: &[Vector2<f64>],
    shape: impl Fn(usize) -> f64,
    modal_f: &mut [f64],
) -> f64 {
    let v = v_root + (0..x.len()).map(|r| shape(r) * x[r][1]).sum::<f64>();
    let f = -coef * v.abs() * v;
    for (r, m) in modal_f.iter_mut().enumerate().take(x.len()) {
        *m += shape(r) * f;
    }
    f
}

/// The tip sensor: absolute tip (root + deflection `w`, the deflection scaled by a sensor on
/// the carriage's gain), late by the sensor latency and scaled by its gain.
fn tip_sensor(p: &Params, root: &[f64], w: &[f64], dt: f64) -> Vec<f64> {
    let g_w = 1.0 + p.sensor_deflection_gain_error;
    let tip: Vec<f64> = root.iter().zip(w).map(|(y, w)| y + g_w * w).collect();
    let tip = match p.tip_filter {
        Some((f, z)) => second_order(&tip, dt, 2.0 * std::f64::consts::PI * f, z, 0.0, 1.0),
        None => tip,
    };
    let tip = if p.sensor_delay_s != 0.0 {
        delayed(&tip, p.sensor_delay_s, dt)
    } else {
        tip
    };
    if p.sensor_gain_error != 0.0 {
        tip.iter()
            .map(|v| (1.0 + p.sensor_gain_error) * v)
            .collect()
    } else {
        tip
    }
}

/// Adds friction and cogging on the carriage (moving with `drive`) to the motor force and
/// applies the force channel's latency.
fn carriage_forces(p: &Params, drive: &[f64], mut force: Vec<f64>, dt: f64) -> Vec<f64> {
    let n = drive.len();
    if let Some(load) = CarriageLoad::of(p) {
        for k in 0..n {
            let v = if k + 1 < n {
                (drive[k + 1] - drive[k.saturating_sub(1)])
                    / (dt * (k + 1 - k.saturating_sub(1)) as f64)
            } else {
                0.0
            };
            force[k] += load.force_n(drive[k], v);
        }
    }
    if p.force_delay_s != 0.0 {
        delayed(&force, p.force_delay_s, dt)
    } else {
        force
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Position (m) at time t (s) of a move with acceleration `a` over [t0, t0 + ta], coasting,
    /// then −a over [t1, t1 + ta] (steps of acceleration between samples), and its velocity.
    fn short_move(t: f64, a: f64, t0: f64, ta: f64, t1: f64) -> (f64, f64) {
        let v = a * ta;
        let (u, w) = ((t - t0).clamp(0.0, ta), (t - t1).clamp(0.0, ta));
        let pos = 0.5 * a * u * u + v * (t - t0 - ta).max(0.0)
            - 0.5 * a * w * w
            - v * (t - t1 - ta).max(0.0);
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

    fn rig() -> Rig {
        Rig::from_toml_str(
            "[beam]\nlength_m = 0.9\ndensity_kg_m3 = 8190.0\nyoungs_modulus_pa = 1.9e11\nstations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 }, { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]\n[base]\nmass_kg = 2.5\n",
        )
        .unwrap()
    }

    fn move_rec_at(rate: f64) -> crate::recording::Recording {
        let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, rate, 5.0).unwrap();
        let mut r = crate::recording::Recording::with_uniform_time(y.len(), rate);
        r.base_cmd_m = Some(y.clone());
        r.tip_pos_m = Some(y.clone());
        r.force_n = Some(vec![0.0; y.len()]);
        r
    }

    fn move_rec() -> crate::recording::Recording {
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
        let ratio = tip_amplitude(&rig, &smooth, &d, 10.0)
            / tip_amplitude(&rig, &Params::default(), &d, 10.0);
        let sinc = (0.1 * std::f64::consts::PI).sin() / (0.1 * std::f64::consts::PI);
        assert!((ratio * sinc * sinc - 1.0).abs() < 3e-3, "{ratio}");
        let decimated = super::super::rate::decimate_prepared(&d, 2);
        let same = tip_amplitude(&rig, &smooth, &decimated, 10.0)
            / tip_amplitude(&rig, &Params::default(), &decimated, 10.0);
        assert!((same - 1.0).abs() < 1e-12, "{same}");
    }

    #[test]
    fn the_fourth_order_reading_forces_the_beam_with_its_stencils_gain() {
        // a 20 Hz sine base at 100 Hz: the three-tap emphasis x − δ²x/12 raises the forcing
        // by 1 + sin²(0.2π)/3 = 1.115 over the piecewise-linear reading (sinc²(0.2) = 0.875
        // of the motion → 0.976); a decimated drive (already emphasised) is left alone
        let taps = super::super::rate::emphasis_taps_of(FOURTH_ORDER_HALF);
        for (t, want) in taps.iter().zip([-1.0 / 12.0, 7.0 / 6.0, -1.0 / 12.0]) {
            assert!((t - want).abs() < 1e-12, "{taps:?}");
        }
        let rig = rig();
        let d = sine_drive(100.0, 20.0);
        let fourth = Params {
            drive_reading: DriveReading::FourthOrder,
            ..Params::default()
        };
        let ratio = tip_amplitude(&rig, &fourth, &d, 20.0)
            / tip_amplitude(&rig, &Params::default(), &d, 20.0);
        let gain = 1.0 + (0.2 * std::f64::consts::PI).sin().powi(2) / 3.0;
        assert!((ratio / gain - 1.0).abs() < 3e-3, "{ratio} against {gain}");
        let decimated = super::super::rate::decimate_prepared(&d, 2);
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
    fn sine_drive(rate: f64, f_hz: f64) -> Prepared {
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
    fn tip_amplitude(rig: &Rig, p: &Params, d: &Prepared, f_hz: f64) -> f64 {
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
                (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64)
                    .sqrt()
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

    #[test]
    fn a_coupled_mount_at_a_third_of_the_sample_rate_is_exact_at_the_samples() {
        // 100 Hz samples, mount at 36 Hz: tip and root from the exact state equal those of the
        // same piecewise-linear drive integrated at 1 kHz; re-driving the beam from the sampled
        // root (the model before) is off by more than a tenth of what the mount changes
        let rig = rig();
        let rec = move_rec();
        let d = Prepared::new("t", &rec).unwrap();
        let c = beam_cache(&rig, &Params::default(), d.dt).unwrap();
        let fine: Vec<f64> = (0..(d.cmd_m.len() - 1) * 10 + 1)
            .map(|i| {
                let (k, r) = (i / 10, (i % 10) as f64 / 10.0);
                let next = d.cmd_m[(k + 1).min(d.cmd_m.len() - 1)];
                d.cmd_m[k] + r * (next - d.cmd_m[k])
            })
            .collect();
        let w = 2.0 * std::f64::consts::PI * 36.0;
        let coarse = coupled_mount(&d.cmd_m, d.dt, w, 0.08, 0.6, &c);
        let reference = coupled_mount(&fine, d.dt / 10.0, w, 0.08, 0.6, &c);
        let peak = reference.tip_w.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let p = Params {
            mount: Some((36.0, 0.08)),
            mount_mass_kg: 0.6,
            ..Params::default()
        };
        let (redriven, _) = beam_response(&p, &coarse.root, &d.cmd_m, d.dt, &c);
        let (rigid, _) = beam_response(&Params::default(), &d.cmd_m, &d.cmd_m, d.dt, &c);
        let (mut worst_redriven, mut mount_effect) = (0.0f64, 0.0f64);
        for k in 0..coarse.tip_w.len() - 1 {
            let exact = reference.tip_w[10 * k];
            assert!((coarse.tip_w[k] - exact).abs() < 1e-9 * peak);
            assert!((coarse.root[k] - reference.root[10 * k]).abs() < 1e-12);
            worst_redriven = worst_redriven.max((redriven[k] - exact).abs());
            mount_effect = mount_effect.max((rigid[k] - exact).abs());
        }
        assert!(
            worst_redriven > 0.1 * mount_effect,
            "{worst_redriven} {mount_effect}"
        );
    }

    #[test]
    fn a_stiff_coupled_mount_pushes_as_the_rigid_carriage() {
        // a 400 Hz mount under 20 Hz beam modes: the motor force of the exact mount state
        // (half-sample momentum changes) is the rigid carriage's, sample by sample
        let rig = rig();
        let rec = move_rec_at(1000.0);
        let d = Prepared::new("t", &rec).unwrap();
        let rigid = predict(&rig, &Params::default(), &d, &mut None).unwrap();
        let p = Params {
            mount: Some((400.0, 0.3)),
            mount_mass_kg: 0.5,
            ..Params::default()
        };
        let mounted = predict(&rig, &p, &d, &mut None).unwrap();
        let (a, b) = (rigid.force_n.unwrap(), mounted.force_n.unwrap());
        let peak = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.05 * peak, "{worst} of {peak}");
    }

    #[test]
    fn coupled_servo_follows_its_command_and_feels_the_beam() {
        // a stiff loop follows the command to well under its following-error bound, and the
        // beam's reaction moves the carriage (the coupled and uncoupled loops differ)
        let rig = rig();
        let rec = move_rec();
        let d = Prepared::new("t", &rec).unwrap();
        let p = Params::default();
        let c = beam_cache(&rig, &p, d.dt).unwrap();
        let w = 2.0 * std::f64::consts::PI * 40.0;
        let y = coupled_servo(&d.cmd_m, d.dt, w, 0.7, (1.0, 1.0), &c, None);
        let e = y
            .iter()
            .zip(&d.cmd_m)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(e < 1e-3, "{e}");
        let u = second_order(&d.cmd_m, d.dt, w, 0.7, 0.0, 0.0);
        let diff = y
            .iter()
            .zip(&u)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff > 1e-7 && diff < e.max(1e-6) * 10.0, "{diff} {e}");
    }

    /// A 10 Hz loop of `order` (2: PD, 3: PID with integral ratio 0.2), ζ 0.7, full
    /// feed-forward, and 2 N of Coulomb friction.
    fn loop_and_friction(order: usize) -> (ServoLaw, CarriageLoad) {
        let law = ServoLaw {
            order,
            omega: 2.0 * std::f64::consts::PI * 10.0,
            zeta: 0.7,
            ff: (1.0, 1.0),
            integral_ratio: if order == 3 { 0.2 } else { 0.0 },
            force_lag_ratio: 0.0,
        };
        let friction = CarriageLoad {
            friction_n: 2.0,
            ..CarriageLoad::default()
        };
        (law, friction)
    }

    /// The friction's lag of the loaded loop behind the free one on `d`, and the step F_c / K_p
    /// (K_p = M (1 + 2ζα) ω², [`ServoLaw`]).
    fn friction_lag(
        law: &ServoLaw,
        load: &CarriageLoad,
        d: &Prepared,
        c: &BeamCache,
    ) -> (Vec<f64>, f64) {
        let free = law.respond(&d.cmd_m, d.dt, Some(c), None);
        let held = law.respond(&d.cmd_m, d.dt, Some(c), Some(load));
        let lag = held.iter().zip(&free).map(|(a, b)| a - b).collect();
        let k_p = c.total_mass * (1.0 + 2.0 * law.zeta * law.integral_ratio) * law.omega.powi(2);
        (lag, load.friction_n / k_p)
    }

    #[test]
    fn friction_on_the_carriage_leaves_a_following_error_of_its_force_over_the_loop_stiffness() {
        // a PD or PID loop with full feed-forward holds the carriage against a Coulomb force F_c
        // with its proportional gain K_p: while the carriage moves the friction adds a lag of
        // F_c / K_p (second simulator pairs seed 11, case10: a 9.2 Hz loop beside 1.68 N of
        // friction left 54 × the noise in `base_pos_m`, correlated −0.61 with the sign of the
        // velocity, and the loop was not named); it neither rings at the samples nor outlasts
        // the move
        let rig = rig();
        let d = Prepared::new("t", &move_rec()).unwrap();
        let c = beam_cache(&rig, &Params::default(), d.dt).unwrap();
        for order in [2, 3] {
            let (law, friction) = loop_and_friction(order);
            let (lag, step) = friction_lag(&law, &friction, &d, &c);
            let most = lag.iter().cloned().fold(0.0, f64::min);
            assert!(
                (-most / step - 1.0).abs() < 0.2,
                "order {order}: {most} against {step}"
            );
            // after the move (over by 0.4 s; from 2.5 s), no sample-to-sample ringing above 1 % of
            // the step and nothing beyond the step
            let after = &lag[250..];
            assert!(
                after.iter().all(|e| e.abs() <= 1.01 * step),
                "order {order}"
            );
            let rough = after
                .windows(3)
                .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
                .fold(0.0, f64::max);
            assert!(rough < 0.01 * step, "order {order}: {rough} against {step}");
        }
        // without friction or cogging there is no load
        assert_eq!(CarriageLoad::of(&Params::default()), None);
    }

    #[test]
    fn the_loaded_loop_at_100_hz_lags_as_the_same_command_stepped_at_1000_hz() {
        // the interval maps (the ladder of linearly implicit maps, substeps where it fails)
        // against the same piecewise-linear command stepped at ten times the rate, where the maps
        // are closer still: the lags agree to 5 % of the step F_c / K_p
        let rig = rig();
        let d = Prepared::new("t", &move_rec()).unwrap();
        let c = beam_cache(&rig, &Params::default(), d.dt).unwrap();
        let n = 10 * (d.cmd_m.len() - 1) + 1;
        let cmd: Vec<f64> = (0..n)
            .map(|k| {
                let (i, f) = (k / 10, (k % 10) as f64 / 10.0);
                let next = d.cmd_m.get(i + 1).copied().unwrap_or(d.cmd_m[i]);
                d.cmd_m[i] * (1.0 - f) + next * f
            })
            .collect();
        let mut fine_rec = crate::recording::Recording::with_uniform_time(n, 1000.0);
        fine_rec.base_cmd_m = Some(cmd.clone());
        fine_rec.tip_pos_m = Some(cmd);
        let fd = Prepared::new("fine", &fine_rec).unwrap();
        let fc = beam_cache(&rig, &Params::default(), fd.dt).unwrap();
        let (law, friction) = loop_and_friction(3);
        let (coarse, step) = friction_lag(&law, &friction, &d, &c);
        let (fine, _) = friction_lag(&law, &friction, &fd, &fc);
        let worst = coarse
            .iter()
            .enumerate()
            .map(|(k, e)| (e - fine[10 * k]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.05 * step, "{worst} against {step}");
    }

    #[test]
    fn a_recorded_base_is_predicted_by_the_loop_the_beam_pushes_back() {
        // with `base_pos_m` recorded the beam is driven by it, and the loop's prediction of that
        // channel is the coupled one: its following error holds the beam's reaction at the modes
        // (a 13.5 Hz loop with feed-forward on the second simulator, bench/second_sim.py case14,
        // left 93 % of its base residual at f1 to a rigid-load loop)
        let rig = rig();
        let mut rec = move_rec();
        rec.base_pos_m = rec.base_cmd_m.clone();
        let d = Prepared::new("t", &rec).unwrap();
        let p = Params {
            servo: Some((8.0, 0.7)),
            servo_ff: (0.95, 0.95),
            servo_order: 3,
            servo_integral_ratio: 0.3,
            ..Params::default()
        };
        let mut cache = None;
        let out = predict(&rig, &p, &d, &mut cache).unwrap();
        let base = out.base_m.expect("a predicted base");
        let c = beam_cache(&rig, &p, d.dt).unwrap();
        let law = ServoLaw::of(&p).unwrap();
        let coupled = law.respond(&d.cmd_m, d.dt, Some(&c), None);
        let rigid = law.respond(&d.cmd_m, d.dt, None, None);
        let gap = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        assert!(gap(&base, &coupled) < 1e-15, "{}", gap(&base, &coupled));
        // the reaction is not a rounding matter: micrometres after a 50 mm move
        assert!(gap(&coupled, &rigid) > 1e-6, "{}", gap(&coupled, &rigid));
    }

    #[test]
    fn the_fitted_bandwidth_is_the_proportional_natural_frequency_of_a_pid_tuned_for_it() {
        // a parallel PID tuned for a 10 Hz bandwidth, per unit carriage mass (the independent
        // simulators' tuning): K_p = ω_b², K_d = 1.4 ω_b, K_i = ω_b³/8
        let wb = 2.0 * std::f64::consts::PI * 10.0;
        let (kd, kp, ki) = (1.4 * wb, wb * wb, wb.powi(3) / 8.0);
        // its rigid closed-loop poles (s² + 2ζωs + ω²)(s + p): p is the real root of
        // s³ + K_d s² + K_p s + K_i, found by bisection on −s
        let cubic = |p: f64| -p.powi(3) + kd * p * p - kp * p + ki;
        let (mut lo, mut hi) = (0.0, kd);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if cubic(lo).signum() == cubic(mid).signum() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let p_real = 0.5 * (lo + hi);
        let w = (ki / p_real).sqrt();
        let zeta = (kd - p_real) / (2.0 * w);
        let alpha = p_real / w;
        assert!(zeta > 0.0 && alpha > 0.0);
        for order in [3, 4] {
            let params = Params {
                servo: Some((10.0, zeta)),
                servo_order: order,
                servo_integral_ratio: alpha,
                ..Params::default()
            };
            let law = ServoLaw::of(&params).unwrap();
            // the law places its poles where the PID has them …
            assert!((law.omega - w).abs() < 1e-9 * w, "{} vs {w}", law.omega);
            // … and reports the bandwidth it was tuned for, not the pole pair
            assert!((law.natural_frequency_rad_s() - wb).abs() < 1e-9 * wb);
            assert!(
                (w - wb).abs() > 0.05 * wb,
                "the pole pair differs: {w} vs {wb}"
            );
        }
        // orders 1–2: the natural frequency is ω itself
        let two = Params {
            servo: Some((10.0, 0.7)),
            servo_order: 2,
            servo_integral_ratio: 2.0,
            ..Params::default()
        };
        let law = ServoLaw::of(&two).unwrap();
        assert_eq!(law.omega, law.natural_frequency_rad_s());
        assert!((law.omega - wb).abs() < 1e-9 * wb);
    }

    #[test]
    fn servo_orders_nest_and_stay_finite() {
        // order 3 with a vanishing integral is the PD loop of order 2, order 4 with a vanishing
        // drive lag is order 3, rigid and coupled alike; order 1 lags by (1 − k_v) v / ω
        let rig = rig();
        let rec = move_rec();
        let d = Prepared::new("t", &rec).unwrap();
        let c = beam_cache(&rig, &Params::default(), d.dt).unwrap();
        let w = 2.0 * std::f64::consts::PI * 8.0;
        let law = |order, al, be| ServoLaw {
            order,
            omega: w,
            zeta: 0.7,
            ff: (0.9, 0.5),
            integral_ratio: al,
            force_lag_ratio: be,
        };
        let maxdiff = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        for cc in [None, Some(&c)] {
            let y2 = law(2, 0.0, 0.0).respond(&d.cmd_m, d.dt, cc, None);
            let y3 = law(3, 1e-6, 0.0).respond(&d.cmd_m, d.dt, cc, None);
            assert!(maxdiff(&y2, &y3) < 1e-7, "{}", maxdiff(&y2, &y3));
            let y3 = law(3, 0.5, 0.0).respond(&d.cmd_m, d.dt, cc, None);
            let y4 = law(4, 0.5, 1e-4).respond(&d.cmd_m, d.dt, cc, None);
            let y4b = law(4, 0.5, 0.2).respond(&d.cmd_m, d.dt, cc, None);
            assert!(y4b.iter().all(|v| v.is_finite()));
            assert!(maxdiff(&y3, &y4) < 1e-5, "{}", maxdiff(&y3, &y4));
            assert!(maxdiff(&y3, &y4b) > 1e-6);
        }
        let y1 = law(1, 0.0, 0.0).respond(&d.cmd_m, d.dt, None, None);
        let lag = y1
            .iter()
            .zip(&d.cmd_m)
            .map(|(a, b)| b - a)
            .fold(0.0, f64::max);
        assert!((lag - 0.1 * 0.2 / w).abs() < 0.05 * 0.1 * 0.2 / w, "{lag}");
    }

    #[test]
    fn a_fractional_delay_keeps_the_amplitude_up_to_0_4_of_the_rate() {
        // a sinusoid at 0.33 × the sample rate (a beam's 2nd mode at 50 Hz sampling) delayed by
        // 0.5 and 0.2 samples equals the sinusoid sampled late; linear interpolation loses 49 %
        // and 27 % of it
        for (f_cyc, frac) in [
            (0.33, 0.5),
            (0.33, 0.2),
            (0.4, 0.5),
            (0.05, 0.7),
            (0.2, -1.3),
        ] {
            let dt = 0.02;
            let w = 2.0 * std::f64::consts::PI * f_cyc / dt;
            let x: Vec<f64> = (0..400).map(|k| (w * k as f64 * dt).sin()).collect();
            let y = delayed(&x, frac * dt, dt);
            let err = (50..350)
                .map(|k| (y[k] - (w * (k as f64 - frac) * dt).sin()).abs())
                .fold(0.0, f64::max);
            assert!(err < 5e-3, "f {f_cyc} × rate, {frac} samples: error {err}");
        }
        // whole samples are a plain shift; the ends are held
        let x: Vec<f64> = (0..20).map(|k| (k * k) as f64).collect();
        let y = delayed(&x, 3.0 * 0.01, 0.01);
        assert_eq!(&y[3..], &x[..17]);
        assert!(y[..3].iter().all(|v| *v == x[0]));
    }

    #[test]
    fn play_operator_keeps_within_half_the_gap_and_holds_inside_it() {
        let w = 2e-3;
        // up by 10 mm, back by 1.5 mm (inside the gap), back by 5 mm more
        let mut x: Vec<f64> = (0..=100).map(|k| 1e-4 * k as f64).collect();
        x.extend((1..=15).map(|k| 0.01 - 1e-4 * k as f64));
        x.extend((1..=50).map(|k| 0.0085 - 1e-4 * k as f64));
        let y = play(&x, w);
        assert!(y
            .iter()
            .zip(&x)
            .all(|(a, b)| (a - b).abs() <= 0.5 * w + 1e-15));
        // dragged behind by w/2 while moving up
        assert!((y[100] - (0.01 - 0.5 * w)).abs() < 1e-12);
        // reversing by less than the gap leaves the output where it was
        assert!(y[100..=115].iter().all(|v| (v - y[100]).abs() < 1e-12));
        // then it is taken up from the other side: x + w/2
        assert!((y[165] - (x[165] + 0.5 * w)).abs() < 1e-12);
        // rate independence: the same path sampled twice as coarsely ends in the same place
        let coarse: Vec<f64> = x.iter().step_by(5).copied().collect();
        let yc = play(&coarse, w);
        assert!((yc[yc.len() - 1] - y[y.len() - 1]).abs() < 1e-12);
        // no gap: the identity
        assert_eq!(play(&x, 0.0), x);
        // a non-finite input is passed on, not a panic, and the output recovers after it
        let y = play(&[0.0, f64::NAN, 1.0], w);
        assert!(y[1].is_nan() && (y[2] - (1.0 - 0.5 * w)).abs() < 1e-12);
        assert!(play(&[0.0, 1.0], f64::NAN).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn cubic_moment_is_odd_exact_below_its_bound_and_keeps_the_clamp_stiff() {
        let (kr, k3) = (20.0, 4e5);
        for k in [k3, -k3] {
            let cap = cubic_cap2(k, kr, 50.0, 0.01);
            for th in [1e-4, 3e-3, 1e-2, 0.1] {
                assert_eq!(cubic_moment(k, -th, cap), -cubic_moment(k, th, cap));
                if th * th <= cap {
                    assert!((cubic_moment(k, th, cap) - k * th.powi(3)).abs() < 1e-12 * k.abs());
                }
                // the tangent stiffness of the whole clamp stays within [k_r/10, 10 k_r]
                let h = 1e-7;
                let t =
                    kr + (cubic_moment(k, th + h, cap) - cubic_moment(k, th - h, cap)) / (2.0 * h);
                assert!(
                    t >= 0.1 * kr - 1e-6 && t <= 10.0 * kr + 1e-6,
                    "{k} {th} {t}"
                );
            }
        }
        assert_eq!(cubic_cap2(0.0, kr, 50.0, 0.01), f64::INFINITY);
        // the per-sample impulse bound: 3 k₃ θ_c² Σs² dt² ≤ 3
        let cap = cubic_cap2(1e9, kr, 50.0, 0.01);
        assert!(3.0 * 1e9 * cap * 50.0 * 1e-4 <= 3.0 + 1e-9);
    }

    /// Mean ringing frequency (Hz) of the tip deflection over the last `secs` s, from linearly
    /// interpolated zero crossings about its mean.
    fn ring_hz(rig: &Rig, p: &Params, rec: &crate::recording::Recording, secs: f64) -> f64 {
        let d = Prepared::new("t", rec).unwrap();
        let pred = predict(rig, p, &d, &mut None).unwrap();
        let tip = pred.tip_m.unwrap();
        let n0 = tip.len() - (secs / d.dt) as usize;
        let w: Vec<f64> = (n0..tip.len()).map(|k| tip[k] - d.cmd_m[k]).collect();
        let m = w.iter().sum::<f64>() / w.len() as f64;
        let t: Vec<f64> = w
            .windows(2)
            .enumerate()
            .filter(|(_, v)| (v[0] - m) * (v[1] - m) < 0.0)
            .map(|(k, v)| (k as f64 + (v[0] - m) / (v[0] - v[1])) * d.dt)
            .collect();
        (t.len() - 1) as f64 / (2.0 * (t[t.len() - 1] - t[0]))
    }

    #[test]
    fn a_hardening_clamp_rings_faster_and_a_softening_one_slower() {
        let rig = rig();
        let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, 200.0, 20.0).unwrap();
        let mut rec = crate::recording::Recording::with_uniform_time(y.len(), 200.0);
        rec.base_cmd_m = Some(y.clone());
        rec.tip_pos_m = Some(y);
        let kr = 5.0;
        let lin = Params {
            root_stiffness_nm_per_rad: Some(kr),
            zeta: Some((0.002, 0.002)),
            ..Params::default()
        };
        let f_lin = ring_hz(&rig, &lin, &rec, 15.0);
        // the root rotation after this move is of the order 1e-2 rad: k₃θ² ≈ ±0.1…0.5 k_r
        let f_hard = ring_hz(
            &rig,
            &Params {
                cubic_root_stiffness_nm_per_rad3: 2e4,
                ..lin.clone()
            },
            &rec,
            15.0,
        );
        let f_soft = ring_hz(
            &rig,
            &Params {
                cubic_root_stiffness_nm_per_rad3: -1e4,
                ..lin.clone()
            },
            &rec,
            15.0,
        );
        // measured: 0.847 < 0.890 < 0.983 Hz
        assert!(
            f_hard > 1.03 * f_lin && f_soft < 0.98 * f_lin,
            "{f_soft} {f_lin} {f_hard}"
        );
    }

    /// A cubic clamp's frequency shift (Hz) on the move of
    /// [`a_hardening_clamp_rings_faster_and_a_softening_one_slower`] sampled at `rate_hz`.
    fn cubic_shift_hz(rate_hz: f64, k3: f64) -> f64 {
        let rig = rig();
        let (y, _) = crate::model::trapezoid_reference(0.0, 0.05, 0.2, 2.0, rate_hz, 20.0).unwrap();
        let mut rec = crate::recording::Recording::with_uniform_time(y.len(), rate_hz);
        rec.base_cmd_m = Some(y.clone());
        rec.tip_pos_m = Some(y);
        let lin = Params {
            root_stiffness_nm_per_rad: Some(5.0),
            zeta: Some((0.002, 0.002)),
            ..Params::default()
        };
        let cubic = Params {
            cubic_root_stiffness_nm_per_rad3: k3,
            ..lin.clone()
        };
        ring_hz(&rig, &cubic, &rec, 15.0) - ring_hz(&rig, &lin, &rec, 15.0)
    }

    #[test]
    fn a_cubic_clamp_shifts_the_ring_alike_at_any_sample_rate() {
        // the clamp's compliance lies mostly in modes above any sample rate (module header,
        // ResidualFlexibility); a moment applied to the kept modes as per-sample impulses
        // shifted the ring by 8 % less at 50 Hz than at 1000 Hz
        for k3 in [2e4, -1e4] {
            let fine = cubic_shift_hz(1000.0, k3);
            for rate in [50.0, 100.0, 250.0] {
                let coarse = cubic_shift_hz(rate, k3);
                println!("k3 {k3} rate {rate}: {coarse} vs {fine}");
                assert!(
                    (coarse / fine - 1.0).abs() < 0.01,
                    "k3 {k3} at {rate} Hz: {coarse} vs {fine}"
                );
            }
        }
    }

    #[test]
    fn fast_filters_are_transparent_and_slow_ones_lag() {
        let rec = move_rec();
        let d = Prepared::new("t", &rec).unwrap();
        let y = second_order(
            &d.cmd_m,
            0.01,
            2.0 * std::f64::consts::PI * 1e4,
            0.7,
            1.0,
            1.0,
        );
        // following error 2ζv/ω = 4.5 µm at 10 kHz bandwidth
        assert!(y.iter().zip(&d.cmd_m).all(|(a, b)| (a - b).abs() < 5e-6));
        let y = second_order(
            &d.cmd_m,
            0.01,
            2.0 * std::f64::consts::PI * 5.0,
            0.7,
            1.0,
            1.0,
        );
        let lag = y
            .iter()
            .zip(&d.cmd_m)
            .map(|(a, b)| b - a)
            .fold(0.0, f64::max);
        // following error of a 2nd-order loop at 0.2 m/s: 2ζv/ω = 8.9 mm
        assert!(
            (lag - 2.0 * 0.7 * 0.2 / (2.0 * std::f64::consts::PI * 5.0)).abs() < 1e-3,
            "{lag}"
        );
    }
}
