//! Command profiles for the truth generator: a random sequence of trapezoidal-velocity
//! point-to-point moves (forward and back, varied distance, speed and acceleration) separated
//! by dwells in which the beam rings down freely.

use rand::Rng;

/// Profile ranges.
#[derive(Clone, Copy, Debug)]
pub struct ProfileSpec {
    /// Duration (s).
    pub duration_s: f64,
    /// Travel range: targets in [−span/2, span/2] (m).
    pub span_m: f64,
    /// Speed range (m/s).
    pub speed_m_s: (f64, f64),
    /// Acceleration range (m/s²).
    pub accel_m_s2: (f64, f64),
    /// Dwell range (s).
    pub dwell_s: (f64, f64),
}

/// Samples (position m, velocity m/s, acceleration m/s²) every `dt` for `spec.duration_s`.
pub fn random_profile(spec: &ProfileSpec, dt: f64, rng: &mut impl Rng) -> Vec<(f64, f64, f64)> {
    let n = (spec.duration_s / dt).round() as usize;
    let mut out = Vec::with_capacity(n);
    let mut pos = 0.0;
    let mut t_next = rng.gen_range(0.5..1.5);
    let mut k = 0usize;
    while k < n {
        let t = k as f64 * dt;
        if t < t_next {
            out.push((pos, 0.0, 0.0));
            k += 1;
            continue;
        }
        // new move
        let mut target = rng.gen_range(-0.5..0.5) * spec.span_m;
        if (target - pos).abs() < 0.1 * spec.span_m {
            target = -target.signum() * 0.3 * spec.span_m;
        }
        let vmax = rng.gen_range(spec.speed_m_s.0..=spec.speed_m_s.1);
        let amax = rng.gen_range(spec.accel_m_s2.0..=spec.accel_m_s2.1);
        let d = (target - pos).abs();
        let s = (target - pos).signum();
        let (ta, vpk) = if d < vmax * vmax / amax {
            ((d / amax).sqrt(), (d * amax).sqrt())
        } else {
            (vmax / amax, vmax)
        };
        let tc = (d - vpk * ta) / vpk;
        let total = 2.0 * ta + tc.max(0.0);
        let start = pos;
        let t0 = t;
        while k < n {
            let tau = k as f64 * dt - t0;
            if tau >= total {
                break;
            }
            let (p, v, a) = if tau < ta {
                (0.5 * amax * tau * tau, amax * tau, amax)
            } else if tau < ta + tc {
                (0.5 * amax * ta * ta + vpk * (tau - ta), vpk, 0.0)
            } else {
                let td = total - tau;
                (d - 0.5 * amax * td * td, amax * td, -amax)
            };
            out.push((start + s * p, s * v, s * a));
            k += 1;
        }
        pos = target;
        t_next = t0 + total + rng.gen_range(spec.dwell_s.0..=spec.dwell_s.1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn profile_is_consistent() {
        let spec = ProfileSpec {
            duration_s: 20.0,
            span_m: 0.2,
            speed_m_s: (0.1, 0.3),
            accel_m_s2: (1.0, 3.0),
            dwell_s: (1.0, 2.0),
        };
        let dt = 1e-3;
        let p = random_profile(&spec, dt, &mut rand::rngs::StdRng::seed_from_u64(3));
        assert_eq!(p.len(), 20000);
        let mut moves = 0;
        for w in p.windows(2) {
            // velocity is the derivative of position, acceleration bounded
            assert!(((w[1].0 - w[0].0) / dt - 0.5 * (w[0].1 + w[1].1)).abs() < 3.0 * dt + 1e-9);
            assert!(w[0].2.abs() <= 3.0 + 1e-12);
            if w[0].1 == 0.0 && w[1].1 != 0.0 {
                moves += 1;
            }
        }
        assert!(moves >= 3, "{moves} moves");
        assert!(p.iter().all(|x| x.0.abs() <= 0.1 + 1e-12));
    }
}
