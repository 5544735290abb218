//! The catalogue of model-discrepancy effects as one typed list, shared by the truth generator
//! (`crate::truth`, which hides them) and the diagnosis (`crate::diagnose`, which names them).
//! Data only: neither side's physics lives here.
//!
//! Spec:
//! - [`Effect`] is the closed set of effects; [`Effect::ALL`] lists them in a fixed order;
//! - [`Effect::id`] is the snake-case name used on the command line and in every JSON file
//!   (`effect`, `effects[].effect`); [`FromStr`] is its inverse (`none` is not an effect);
//! - [`Effect::parameters`] gives the reported parameter names (SI unit in the name) with their
//!   meaning; [`Effect::shows_in`] the recorded channels an effect is visible in (any of them);
//!   [`Effect::needs_beam`] whether it lives on the beam;
//! - [`Effect::conflicts_with`] says which two effects are alternative models of the same part
//!   (one model may contain at most one of them); [`Effect::look_alike`] which effect the
//!   recorded channels cannot tell a given one from.

use std::fmt;
use std::str::FromStr;

/// A recorded channel of a recording (the CSV column in brackets).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Measured carriage position (`base_pos_m`) against its command (`base_cmd_m`).
    BasePos,
    /// Absolute tip position (`tip_pos_m`).
    Tip,
    /// Drive force (`force_n`).
    Force,
}

impl Channel {
    /// Position in the recordings' channel order (`base_pos_m`, `tip_pos_m`, `force_n`; the
    /// order of `diagnose::fit::CHANNEL_NAMES`).
    pub fn index(self) -> usize {
        match self {
            Channel::BasePos => 0,
            Channel::Tip => 1,
            Channel::Force => 2,
        }
    }
}

/// A reported parameter: JSON name (SI unit in the name) and meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamSpec {
    /// Name in the JSON `parameters` object.
    pub name: &'static str,
    /// What it is.
    pub meaning: &'static str,
}

/// `ParamSpec` literal (a struct literal, so the tables below are promoted to statics).
macro_rules! p {
    ($name:expr, $meaning:expr $(,)?) => {
        ParamSpec {
            name: $name,
            meaning: $meaning,
        }
    };
}

/// An effect of the catalogue (issue 10; `none` is the absence of every effect).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Coulomb + viscous friction on the carriage.
    BaseFriction,
    /// Finite-bandwidth position loop (with or without feed-forward).
    ServoLag,
    /// Lumped mass at the tip.
    TipMass,
    /// Rotational spring at the clamp.
    RootCompliance,
    /// Distributed quadratic (aerodynamic) damping.
    QuadraticDamping,
    /// Latency of the tip sensor.
    SensorDelay,
    /// Gravity axial load (hanging or upright beam).
    GravityAxialLoad,
    /// Resonance between motor and beam root.
    MountResonance,
    /// Force ripple periodic in the carriage position.
    CoggingRipple,
    /// Scale error of the tip sensor.
    SensorGain,
    /// Dead band (play) between the drive and the beam root.
    Backlash,
    /// Amplitude-dependent (cubic) rotational stiffness of the clamp.
    CubicStiffness,
}

impl Effect {
    /// Every effect, in catalogue order.
    pub const ALL: [Effect; 12] = [
        Effect::BaseFriction,
        Effect::ServoLag,
        Effect::TipMass,
        Effect::RootCompliance,
        Effect::QuadraticDamping,
        Effect::SensorDelay,
        Effect::GravityAxialLoad,
        Effect::MountResonance,
        Effect::CoggingRipple,
        Effect::SensorGain,
        Effect::Backlash,
        Effect::CubicStiffness,
    ];

    /// The ids of [`Effect::ALL`], same order.
    pub const IDS: [&'static str; 12] = {
        let mut a = [""; 12];
        let mut i = 0;
        while i < 12 {
            a[i] = Effect::ALL[i].id();
            i += 1;
        }
        a
    };

    /// The id used on the command line and in JSON.
    pub const fn id(self) -> &'static str {
        match self {
            Effect::BaseFriction => "base_friction",
            Effect::ServoLag => "servo_lag",
            Effect::TipMass => "tip_mass",
            Effect::RootCompliance => "root_compliance",
            Effect::QuadraticDamping => "quadratic_damping",
            Effect::SensorDelay => "sensor_delay",
            Effect::GravityAxialLoad => "gravity_axial_load",
            Effect::MountResonance => "mount_resonance",
            Effect::CoggingRipple => "cogging_ripple",
            Effect::SensorGain => "sensor_gain",
            Effect::Backlash => "backlash",
            Effect::CubicStiffness => "cubic_stiffness",
        }
    }

    /// The parameters the diagnosis reports (and the truth generator records) for this effect.
    pub fn parameters(self) -> &'static [ParamSpec] {
        match self {
            Effect::BaseFriction => &[
                p!("friction_n", "Coulomb friction level (N)"),
                p!("viscous_n_s_per_m", "viscous friction coefficient (N·s/m)"),
            ],
            Effect::ServoLag => &[
                p!(
                    "servo_bandwidth_hz",
                    "position-loop natural frequency √(K_p/M) (Hz)"
                ),
                p!("servo_damping_ratio", "position-loop damping ratio (1)"),
                p!("servo_velocity_ff", "velocity feed-forward fraction (1)"),
                p!("servo_acceleration_ff", "acceleration feed-forward fraction (1)"),
                p!(
                    "servo_integral_ratio",
                    "PID loop (order 3–4): integral pole / pole-pair frequency ω (1)",
                ),
                p!(
                    "servo_force_lag_ratio",
                    "order-4 loop: drive-force lag time constant × pole-pair frequency ω (1)",
                ),
            ],
            Effect::TipMass => &[p!("tip_mass_kg", "lumped mass at the tip (kg)")],
            Effect::RootCompliance => &[p!(
                "root_stiffness_nm_per_rad",
                "rotational stiffness of the clamp (N·m/rad)",
            )],
            Effect::QuadraticDamping => &[
                p!(
                    "drag_coefficient_kg_per_m2",
                    "distributed drag: force per unit length = c |v| v (kg/m²)",
                ),
                p!(
                    "tip_drag_coefficient_kg_per_m",
                    "drag on a body at the tip: force = c |v| v at the tip (kg/m; the other placement)",
                ),
            ],
            Effect::SensorDelay => &[p!("sensor_delay_s", "latency of the tip sensor (s)")],
            Effect::GravityAxialLoad => &[],
            Effect::MountResonance => &[
                p!(
                    "mount_frequency_hz",
                    "mount resonance frequency as the rig shows it (Hz; for a mount carrying the beam, the coupled mount + beam with the carriage held; in the candidate table, the fit's rigid-beam frequency)",
                ),
                p!("mount_damping_ratio", "mount damping ratio (1)"),
                p!(
                    "mount_mass_kg",
                    "mount mass carrying the beam (kg; absent for a mount the beam does not load)",
                ),
            ],
            Effect::CoggingRipple => &[
                p!("cogging_amplitude_n", "ripple amplitude (N)"),
                p!("cogging_pitch_m", "ripple period in carriage position (m)"),
            ],
            Effect::SensorGain => &[p!("sensor_gain", "tip sensor scale: reported / true (1)")],
            Effect::Backlash => &[p!(
                "backlash_m",
                "total play between drive and beam root (m)",
            )],
            Effect::CubicStiffness => &[
                p!(
                    "cubic_root_stiffness_nm_per_rad3",
                    "cubic clamp stiffness k₃ in M = k_r θ + k₃ θ³ (N·m/rad³; > 0 hardening, < 0 softening)",
                ),
                p!(
                    "cubic_root_compliance_rad_per_nm3",
                    "c₃ = k₃ / k_r⁴: the clamp turns by θ ≈ M/k_r − c₃M³ under a root moment M (rad/(N·m)³); what the recordings determine",
                ),
                p!(
                    "root_stiffness_nm_per_rad",
                    "linear clamp stiffness k_r (N·m/rad)",
                ),
            ],
        }
    }

    /// The recorded channels this effect shows in (it is testable when any is recorded and,
    /// for [`Effect::needs_beam`], the rig has a beam).
    pub fn shows_in(self) -> &'static [Channel] {
        match self {
            Effect::BaseFriction | Effect::CoggingRipple => &[Channel::Force],
            Effect::ServoLag => &[Channel::BasePos, Channel::Tip, Channel::Force],
            _ => &[Channel::Tip],
        }
    }

    /// The one channel an effect of the measurement acts on: a latency or a scale error of the
    /// tip sensor changes what the sensor reports, never the motion, so with every other
    /// parameter held it leaves `base_pos_m` and `force_n` unchanged. `None` for effects of
    /// the plant, which act on every channel through the coupled motion.
    pub fn measurement_channel(self) -> Option<Channel> {
        match self {
            Effect::SensorDelay | Effect::SensorGain => Some(Channel::Tip),
            _ => None,
        }
    }

    /// True when the effect lives on the beam or its clamp (needs a rig with a beam).
    pub fn needs_beam(self) -> bool {
        !matches!(
            self,
            Effect::BaseFriction | Effect::CoggingRipple | Effect::ServoLag
        )
    }

    /// True when `self` and `other` model the same part and may not be in one model together
    /// (an effect conflicts with itself; a cubic clamp contains the linear compliant clamp).
    pub fn conflicts_with(self, other: Effect) -> bool {
        use Effect::*;
        self == other
            || matches!(
                (self, other),
                (RootCompliance, CubicStiffness) | (CubicStiffness, RootCompliance)
            )
    }

    /// The effect that, with the channels recorded, acts on them as the same filter to first
    /// order, so that the recordings cannot tell the two apart (`crate::diagnose::lookalike`):
    /// [`LOOK_ALIKES`]. `None`: no look-alike.
    pub fn look_alike(self, base_pos_recorded: bool) -> Option<Effect> {
        self.look_alike_why(base_pos_recorded).map(|(b, _)| b)
    }

    /// [`Self::look_alike`] with why the two act alike and what would tell them apart, in
    /// words ([`LOOK_ALIKES`]).
    pub fn look_alike_why(self, base_pos_recorded: bool) -> Option<(Effect, &'static str)> {
        LOOK_ALIKES.iter().find_map(|p| {
            if p.without_base_pos && base_pos_recorded {
                None
            } else if p.pair.0 == self {
                Some((p.pair.1, p.why))
            } else if p.pair.1 == self {
                Some((p.pair.0, p.why))
            } else {
                None
            }
        })
    }
}

/// Two effects that act on the recorded channels as the same filter to first order.
#[derive(Clone, Copy, Debug)]
pub struct LookAlikePair {
    /// The two effects (either way round).
    pub pair: (Effect, Effect),
    /// Alike only when `base_pos_m` is not recorded.
    pub without_base_pos: bool,
    /// Why they act alike, and what would tell them apart.
    pub why: &'static str,
}

/// Every look-alike pair. Without `base_pos_m` a position loop's lag (`servo_lag`) and a
/// tip-sensor latency (`sensor_delay`) are both a lag between the command and the tip. With any
/// channels, a compliant clamp (`root_compliance`) and the axial load of a standing or hanging
/// beam (`gravity_axial_load`) both change the beam's stiffness most near the root and so its
/// frequency ratios the same way to first order: where one ratio is in band (two modes) they
/// are one change.
pub const LOOK_ALIKES: [LookAlikePair; 2] = [
    LookAlikePair {
        pair: (Effect::ServoLag, Effect::SensorDelay),
        without_base_pos: true,
        why: "Without base_pos_m a position loop's lag and a tip-sensor latency are both filters between the command and the tip, and the calibrated force-channel latency absorbs the loop's lag on force_n. Record base_pos_m to tell them apart",
    },
    LookAlikePair {
        pair: (Effect::RootCompliance, Effect::GravityAxialLoad),
        without_base_pos: false,
        why: "A compliant clamp and the axial load of a standing or hanging beam both change the beam's stiffness most near its root, and so its frequency ratios alike: with few modes in band they are one change. Record at a rate that puts more modes in band, or with the beam turned, to tell them apart",
    },
];

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.id())
    }
}

/// An unknown effect id.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownEffect(pub String);

impl fmt::Display for UnknownEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown effect `{}` (one of {})",
            self.0,
            Effect::IDS.join(", ")
        )
    }
}

impl std::error::Error for UnknownEffect {}

impl FromStr for Effect {
    type Err = UnknownEffect;
    fn from_str(s: &str) -> Result<Effect, UnknownEffect> {
        Effect::ALL
            .iter()
            .copied()
            .find(|e| e.id() == s.trim())
            .ok_or_else(|| UnknownEffect(s.trim().to_string()))
    }
}

impl serde::Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_alikes_are_symmetric_and_a_loop_and_a_latency_only_without_base_pos() {
        for e in Effect::ALL {
            for base in [false, true] {
                if let Some((b, why)) = e.look_alike_why(base) {
                    assert_eq!(b.look_alike(base), Some(e), "{e} ↔ {b}");
                    assert!(!why.is_empty() && b != e);
                }
            }
        }
        assert_eq!(
            Effect::ServoLag.look_alike(false),
            Some(Effect::SensorDelay)
        );
        assert_eq!(Effect::ServoLag.look_alike(true), None);
        assert_eq!(
            Effect::GravityAxialLoad.look_alike(true),
            Some(Effect::RootCompliance)
        );
        assert_eq!(Effect::TipMass.look_alike(false), None);
    }

    #[test]
    fn ids_round_trip_and_are_unique() {
        for e in Effect::ALL {
            assert_eq!(e.id().parse::<Effect>().unwrap(), e);
            assert_eq!(e.to_string(), e.id());
        }
        let mut ids = Effect::IDS.to_vec();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), Effect::ALL.len());
        assert!("none".parse::<Effect>().is_err());
        assert!("backlash ".parse::<Effect>().is_ok());
    }

    #[test]
    fn parameter_names_carry_units() {
        // every reported parameter ends in an SI unit or is dimensionless by its name
        let units = [
            "_n",
            "_m",
            "_s",
            "_hz",
            "_kg",
            "_per_m",
            "_per_rad",
            "_per_rad3",
            "_kg_per_m2",
            "_ratio",
            "_ff",
            "_per_nm3",
            "sensor_gain",
        ];
        for e in Effect::ALL {
            for q in e.parameters() {
                assert!(
                    units.iter().any(|u| q.name.ends_with(u)),
                    "{}: {}",
                    e,
                    q.name
                );
            }
        }
    }

    #[test]
    fn conflicts_are_symmetric() {
        for a in Effect::ALL {
            assert!(a.conflicts_with(a));
            for b in Effect::ALL {
                assert_eq!(a.conflicts_with(b), b.conflicts_with(a));
            }
        }
        assert!(!Effect::Backlash.conflicts_with(Effect::MountResonance));
    }
}
