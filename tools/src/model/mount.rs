//! The resonance of a mount that carries the beam, as the rig shows it.
//!
//! A mount mass m_m sits on a spring k between the carriage and the beam root, and carries the
//! beam (mass m_b, clamped-base modes of angular frequency ω_r and participation
//! Γ_r = ∫ ρA φ_r dx for mass-normalised shapes φ_r). With the carriage held, the coordinates
//! q = [y_r, η_1 … η_n] (root displacement, modal coordinates) obey
//!
//! ```text
//! [ m_m + m_b  Γᵀ ] q̈  +  [ k  0      ] q = 0
//! [ Γ          I  ]       [ 0  diag ω_r² ]
//! ```
//!
//! (the kinetic energy of the beam on a moving root, paper eq. 12 with the base as a
//! coordinate). Its mode with the largest share of its strain energy in the mount spring is the
//! mount's resonance: the frequency a measurement of the rig finds (a peak of the
//! command → tip response). It is not √(k/(m_m + m_b)), the beam taken as rigid: above its
//! own first modes the beam's apparent mass m_b + Σ Γ_r² ω²/(ω_r² − ω²) is much smaller, so the
//! resonance sits well above that (17–19 % on the independent set's two mounts, near 1.4 and
//! 9 Hz beam modes and a 15 Hz mount).

use nalgebra::{DMatrix, SymmetricEigen};

/// The mount's resonance (Hz) of the coupled mount + beam with the carriage held (module docs):
/// spring `stiffness_n_per_m` (N/m), mount mass `mount_mass_kg` (kg), beam (and tip) mass
/// `beam_mass_kg` (kg), clamped-base modes `omega_rad_s` (rad/s) with participations
/// `participation` (kg^½), one per mode. `None` when the masses or the stiffness are not
/// positive, the lists differ in length, or the mass matrix is not positive definite
/// (Σ Γ_r² ≥ m_m + m_b).
pub fn coupled_resonance_hz(
    stiffness_n_per_m: f64,
    mount_mass_kg: f64,
    beam_mass_kg: f64,
    participation: &[f64],
    omega_rad_s: &[f64],
) -> Option<f64> {
    if !(stiffness_n_per_m > 0.0 && mount_mass_kg > 0.0 && beam_mass_kg >= 0.0)
        || participation.len() != omega_rad_s.len()
    {
        return None;
    }
    let n = omega_rad_s.len() + 1;
    let mut m = DMatrix::<f64>::identity(n, n);
    let mut k = DMatrix::<f64>::zeros(n, n);
    m[(0, 0)] = mount_mass_kg + beam_mass_kg;
    k[(0, 0)] = stiffness_n_per_m;
    for (r, (&g, &w)) in participation.iter().zip(omega_rad_s).enumerate() {
        m[(0, r + 1)] = g;
        m[(r + 1, 0)] = g;
        k[(r + 1, r + 1)] = w * w;
    }
    // K v = λ M v with M = L Lᵀ: the symmetric A = L⁻¹ K L⁻ᵀ, v = L⁻ᵀ u
    let l = m.cholesky()?.l();
    let l_inv = l.clone().try_inverse()?;
    let a = &l_inv * &k * l_inv.transpose();
    let eig = SymmetricEigen::new((&a + a.transpose()) * 0.5);
    let v = l_inv.transpose() * &eig.eigenvectors;
    let (mut best, mut share) = (None, -1.0);
    for j in 0..n {
        let col = v.column(j);
        let strain = (col.transpose() * &k * col)[(0, 0)];
        let s = stiffness_n_per_m * col[0] * col[0] / strain.max(1e-300);
        if s > share && eig.eigenvalues[j] > 0.0 {
            share = s;
            best = Some(eig.eigenvalues[j].sqrt() / (2.0 * std::f64::consts::PI));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn without_beam_modes_the_mount_is_a_mass_on_a_spring() {
        // no modes: the beam is a rigid mass on the mount
        let (k, m_m, m_b) = (4000.0, 0.4, 0.2);
        let f = coupled_resonance_hz(k, m_m, m_b, &[], &[]).unwrap();
        assert!(
            (f - (k / (m_m + m_b)).sqrt() / (2.0 * PI)).abs() < 1e-9,
            "{f}"
        );
    }

    #[test]
    fn beam_modes_below_the_mount_lighten_it() {
        // a uniform cantilever's effective masses (61 %, 19 %, 6.5 %, 3.3 % of m_b) with modes
        // at 1.41, 8.80, 24.6, 48.3 Hz under a 0.405 kg mount whose rigid-beam frequency is
        // 12.38 Hz (independent case06's fit): the mount resonates at about 14.9 Hz (its key:
        // 14.88 Hz), between √(k/(m_m + m_b)) and √(k/m_m)
        let m_b = 0.2274;
        let m_m = 0.405;
        let frac = [0.613, 0.188, 0.065, 0.033];
        let f_r = [1.41, 8.80, 24.6, 48.3];
        let g: Vec<f64> = frac.iter().map(|e: &f64| (e * m_b).sqrt()).collect();
        let w: Vec<f64> = f_r.iter().map(|f| 2.0 * PI * f).collect();
        let k = (2.0 * PI * 12.375f64).powi(2) * (m_m + m_b);
        let f = coupled_resonance_hz(k, m_m, m_b, &g, &w).unwrap();
        assert!((f - 14.88).abs() < 0.3, "{f}");
        assert!(f < (k / m_m).sqrt() / (2.0 * PI));
        // a mount far below the beam's modes sees the whole beam
        let k_soft = (2.0 * PI * 0.2f64).powi(2) * (m_m + m_b);
        let f_soft = coupled_resonance_hz(k_soft, m_m, m_b, &g, &w).unwrap();
        assert!((f_soft - 0.2).abs() < 0.01, "{f_soft}");
    }

    #[test]
    fn impossible_inputs_give_none() {
        assert!(coupled_resonance_hz(0.0, 0.4, 0.2, &[], &[]).is_none());
        assert!(coupled_resonance_hz(100.0, 0.0, 0.2, &[], &[]).is_none());
        assert!(coupled_resonance_hz(100.0, 0.4, 0.2, &[0.1], &[]).is_none());
        // Σ Γ² beyond the total mass: no positive-definite mass matrix
        assert!(coupled_resonance_hz(100.0, 0.1, 0.1, &[1.0], &[10.0]).is_none());
    }
}
