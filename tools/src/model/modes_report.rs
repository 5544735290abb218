//! The model's modes as a JSON report: what `beamtool modes --json` prints and what the Python
//! package's `Rig.modes` returns, written once.

use super::BeamModel;
use anyhow::Result;
use serde_json::{json, Value};

/// `{beam_mass_kg, rayleigh_alpha1_per_s, rayleigh_alpha2_s, modes: [{mode, freq_hz_clamped_base,
/// freq_hz_free_base, damping_ratio, participation_kg_sqrt, tip_per_modal_coordinate}]}`: the
/// clamped-base modes of `m` (paper eqs. 13–22) beside its free-base natural frequencies.
///
/// Errors: the model's eigenproblem fails ([`BeamModel::clamped_modes`],
/// [`BeamModel::free_base_freqs_hz`]).
pub fn modes_report(m: &BeamModel) -> Result<Value> {
    let cm = m.clamped_modes()?;
    let free = m.free_base_freqs_hz()?;
    let two_pi = 2.0 * std::f64::consts::PI;
    let modes: Vec<Value> = (0..cm.omega_rad_s.len())
        .map(|r| {
            json!({
                "mode": r + 1,
                "freq_hz_clamped_base": cm.omega_rad_s[r] / two_pi,
                "freq_hz_free_base": free.get(r),
                "damping_ratio": cm.zeta[r],
                "participation_kg_sqrt": cm.participation[r],
                "tip_per_modal_coordinate": cm.tip[r],
            })
        })
        .collect();
    Ok(json!({
        "beam_mass_kg": m.beam_mass_kg, "rayleigh_alpha1_per_s": m.rayleigh.0,
        "rayleigh_alpha2_s": m.rayleigh.1, "modes": modes }))
}
