//! Block 3 of the chain, between the drive and the beam root: backlash, a dead band of total
//! width b between the carriage and the beam root, as the play (backlash) operator
//! `y_r[k] = clamp(y_r[k−1], y[k] − b/2, y[k] + b/2)` ([`play`]; `backlash`): the root stays where
//! it was left until the drive takes it up from the other side (a root held by friction inside
//! the gap, driven through a rigid contact); mount: the beam root is a mount mass on a
//! spring–damper from the carriage, loaded by the beam (coupled to its modes, [`coupled_mount`];
//! `mount_resonance` with `mount_mass_kg`), or a massless filter of the root motion (a mount the
//! beam does not load). [`root_motion`] composes them.

use super::beam::{beam_cache, root_transition, BeamCache};
use super::discrete::{advance, second_order};
use super::params::Params;
use crate::model::Rig;

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

/// What [`coupled_mount`] returns, per sample: the root position (m), the tip deflection
/// Σ tip_j η_j (m) and the force the carriage's mount spring and damper pass to the mount mass
/// and the beam (N, the mean over the interval centred on the sample), all from the exact
/// state.
pub(crate) struct MountResponse {
    pub(crate) root: Vec<f64>,
    pub(crate) tip_w: Vec<f64>,
    pub(crate) force: Vec<f64>,
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
pub(crate) fn coupled_mount(
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

/// Beam-root position: the drive through the play (`backlash`) and the mount (coupled to the
/// beam of `c` when it has a mass and there is a beam, else a filter the beam does not load);
/// with the coupled mount also the tip deflection and force of its exact state
/// ([`coupled_mount`]).
pub(crate) fn root_motion(
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
