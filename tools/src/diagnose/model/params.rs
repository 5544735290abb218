//! The parameters of the augmented model ([`Params`]): every physical parameter of every block
//! of the signal chain, and how the model reads a drive between its samples ([`DriveReading`]).

use crate::model::Orientation;

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
    /// Velocity over which the Coulomb term is smoothed (m/s; [`super::FRICTION_SMOOTHING_M_S`]).
    pub friction_smoothing_m_s: f64,
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
    /// (a decimated one is always emphasised, [`crate::diagnose::rate`]); chosen by the recordings
    /// (`crate::diagnose::diagnose`).
    pub drive_reading: DriveReading,
}

/// How the model reads a drive sampled at the recording's own rate between its samples: the
/// samples say nothing of the motion between them, and two simulators of the same rig can
/// differ there (a drive that moves linearly between setpoint updates, a position loop far
/// faster than the recording), so the recordings choose ([`crate::diagnose::diagnose`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveReading {
    /// The piecewise-linear path through the samples: the beam is forced by the second
    /// difference of the drive, sinc²(f/r) of a smooth motion's content (12 % low at 0.2 ×
    /// the rate).
    #[default]
    PiecewiseLinear,
    /// A smooth motion: the model's input is `x_k − δ²x_k / 12`
    /// ([`crate::diagnose::rate::emphasise_of`] with half-length 1), so its second difference is the
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
pub(crate) const FOURTH_ORDER_HALF: usize = 1;

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
            friction_smoothing_m_s: super::FRICTION_SMOOTHING_M_S,
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
