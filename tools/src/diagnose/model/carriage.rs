//! Block 5 of the chain, the carriage load: `+ F_c sign(ẏ) + c_v ẏ` (`base_friction`, smoothed
//! over 1 mm/s) and `+ a sin(2πy/p) + b cos(2πy/p)` (`cogging_ripple`) on the carriage
//! ([`CarriageLoad`]), in the force channel and inside the position loop alike, and the force
//! channel's latency ([`carriage_forces`]).

use super::params::Params;
use super::sensor::delayed;

/// Velocity over which the model smooths Coulomb friction (m/s): `F_c tanh(v / v_s)`, in the
/// force channel and inside the position loop alike. The recordings rarely resolve the
/// transition through zero velocity; the model-form alternative that fits it
/// ([`crate::diagnose::honesty::add_friction_law_std`]) carries that choice into the 1-σ.
pub const FRICTION_SMOOTHING_M_S: f64 = 1e-3;

/// Forces on the carriage besides the drive's and the beam's, which the motor supplies and a
/// position loop must overcome (`base_friction`, `cogging_ripple`): Coulomb friction
/// `F_c tanh(v / 1 mm/s)`, viscous `c_v v`, cogging `a sin(2πy/p) + b cos(2πy/p)` (N; y in m,
/// v in m/s). Inside a loop of finite stiffness they leave a following error: a Coulomb force
/// over K_p = M ω_n² is a step of F_c / K_p at every reversal, which the integral action then
/// removes (Ellis, *Control System Design Guide*, 4th ed., ch. 17, disturbance response).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarriageLoad {
    /// Coulomb friction (N).
    pub friction_n: f64,
    /// Viscous friction (N·s/m).
    pub viscous_n_s_per_m: f64,
    /// Cogging: sine and cosine amplitudes (N) and pitch (m).
    pub cogging: Option<(f64, f64, f64)>,
    /// Velocity over which the Coulomb term is smoothed (m/s; [`FRICTION_SMOOTHING_M_S`] in
    /// the model, fitted by the friction law's model-form alternative).
    pub smoothing_m_s: f64,
}

impl Default for CarriageLoad {
    fn default() -> Self {
        CarriageLoad {
            friction_n: 0.0,
            viscous_n_s_per_m: 0.0,
            cogging: None,
            smoothing_m_s: FRICTION_SMOOTHING_M_S,
        }
    }
}

impl CarriageLoad {
    /// The load of `p`; `None` when it has neither friction nor cogging.
    pub fn of(p: &Params) -> Option<CarriageLoad> {
        let load = CarriageLoad {
            friction_n: p.friction_n,
            viscous_n_s_per_m: p.viscous_n_s_per_m,
            cogging: p.cogging,
            smoothing_m_s: p.friction_smoothing_m_s,
        };
        let none =
            load.friction_n == 0.0 && load.viscous_n_s_per_m == 0.0 && load.cogging.is_none();
        (!none).then_some(load)
    }

    /// The load divided by the moving mass `mass_kg`: its force per unit mass (N/kg), what a
    /// loop simulated per unit mass (a rig without a beam) carries.
    pub fn per_unit_mass(&self, mass_kg: f64) -> CarriageLoad {
        let m = mass_kg.max(1e-9);
        CarriageLoad {
            friction_n: self.friction_n / m,
            viscous_n_s_per_m: self.viscous_n_s_per_m / m,
            cogging: self.cogging.map(|(a, b, pitch)| (a / m, b / m, pitch)),
            smoothing_m_s: self.smoothing_m_s,
        }
    }

    /// The force the motor spends on the load (N) at carriage position `y_m` and velocity
    /// `v_m_s`.
    pub fn force_n(&self, y_m: f64, v_m_s: f64) -> f64 {
        let mut f =
            self.friction_n * (v_m_s / self.smoothing_m_s).tanh() + self.viscous_n_s_per_m * v_m_s;
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
    pub(crate) fn substeps(&self, m_eff_kg: f64, dt: f64) -> usize {
        let rate = (self.friction_n.abs() / self.smoothing_m_s + self.viscous_n_s_per_m.abs())
            / m_eff_kg.max(1e-9);
        ((rate * dt).ceil() as usize).clamp(1, 32)
    }
}

/// Adds friction and cogging on the carriage (moving with `drive`) to the motor force and
/// applies the force channel's latency.
pub(crate) fn carriage_forces(p: &Params, drive: &[f64], mut force: Vec<f64>, dt: f64) -> Vec<f64> {
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
