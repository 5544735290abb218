//! Peak picking with half-power (−3 dB) damping (Ewins, *Modal Testing*, §4.3).
//!
//! Natural frequency: a local maximum of |H| refined by a parabola through the three bins
//! around it. Damping: the frequencies f_a < f_n < f_b where |H| = |H(f_n)|/√2 (linear
//! interpolation between lines), ζ = (f_b − f_a)/(2 f_n). Needs a frequency step well below
//! the half-power bandwidth 2ζf_n (warned otherwise) and well separated modes.

use super::poles::Pole;
use realfft::num_complex::Complex64;

/// A picked peak.
#[derive(Clone, Debug, PartialEq)]
pub struct Peak {
    /// Frequency and half-power damping.
    pub pole: Pole,
    /// |H| at the peak.
    pub magnitude: f64,
    /// Lines inside the half-power band (resolution check).
    pub lines_in_band: usize,
}

/// The `max_peaks` strongest local maxima of |h| in the band [f_lo, f_hi] whose half-power
/// points lie inside the record; sorted by frequency. Peaks weaker than `min_rel` × the
/// strongest are ignored.
pub fn pick_peaks(
    freq_hz: &[f64],
    h: &[Complex64],
    f_lo: f64,
    f_hi: f64,
    max_peaks: usize,
    min_rel: f64,
) -> Vec<Peak> {
    let mag: Vec<f64> = h
        .iter()
        .map(|c| {
            if c.re.is_finite() && c.im.is_finite() {
                c.norm()
            } else {
                0.0
            }
        })
        .collect();
    let n = mag.len();
    let mut cand: Vec<usize> = (1..n.saturating_sub(1))
        .filter(|&k| {
            freq_hz[k] >= f_lo && freq_hz[k] <= f_hi && mag[k] > mag[k - 1] && mag[k] >= mag[k + 1]
        })
        .collect();
    cand.sort_by(|&a, &b| mag[b].total_cmp(&mag[a]));
    let strongest = cand.first().map_or(0.0, |&k| mag[k]);
    let df = if n > 1 { freq_hz[1] - freq_hz[0] } else { 1.0 };
    let mut out: Vec<Peak> = Vec::new();
    for &k in &cand {
        if out.len() >= max_peaks || mag[k] < min_rel * strongest {
            break;
        }
        let half = mag[k] / std::f64::consts::SQRT_2;
        // Walk out to the half-power crossings; a higher point on the way means another peak dominates.
        let mut a = k;
        while a > 0 && mag[a] > half {
            a -= 1;
            if mag[a] > mag[k] {
                break;
            }
        }
        let mut b = k;
        while b + 1 < n && mag[b] > half {
            b += 1;
            if mag[b] > mag[k] {
                break;
            }
        }
        if mag[a] > half || mag[b] > half || mag[a] > mag[k] || mag[b] > mag[k] {
            continue;
        }
        let fa = freq_hz[a] + (half - mag[a]) / (mag[a + 1] - mag[a]) * df;
        let fb = freq_hz[b - 1] + (mag[b - 1] - half) / (mag[b - 1] - mag[b]) * df;
        let (l, c, r) = (mag[k - 1], mag[k], mag[k + 1]);
        let d = l - 2.0 * c + r;
        let off = if d != 0.0 {
            (0.5 * (l - r) / d).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        let fnat = freq_hz[k] + off * df;
        // Close peaks: keep the stronger (already in `out`).
        if out
            .iter()
            .any(|p| (p.pole.freq_hz - fnat).abs() < 2.0 * (fb - fa))
        {
            continue;
        }
        out.push(Peak {
            pole: Pole {
                freq_hz: fnat,
                zeta: (fb - fa) / (2.0 * fnat),
            },
            magnitude: c + 0.0 * off,
            lines_in_band: b - a - 1,
        });
    }
    out.sort_by(|a, b| a.pole.freq_hz.total_cmp(&b.pole.freq_hz));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_power_of_a_fine_sdof_frf() {
        let (fr, z) = (2.0, 0.02);
        let f: Vec<f64> = (0..4000).map(|k| k as f64 * 0.001).collect();
        let h: Vec<Complex64> = f
            .iter()
            .map(|&fk| {
                let (w, wr) = (
                    2.0 * std::f64::consts::PI * fk,
                    2.0 * std::f64::consts::PI * fr,
                );
                Complex64::new(1.0, 0.0) / Complex64::new(wr * wr - w * w, 2.0 * z * wr * w)
            })
            .collect();
        let p = pick_peaks(&f, &h, 0.5, 3.5, 3, 0.05);
        assert_eq!(p.len(), 1);
        assert!((p[0].pole.freq_hz / 2.0 - 1.0).abs() < 1e-3, "{:?}", p[0]);
        assert!((p[0].pole.zeta / z - 1.0).abs() < 0.02, "{:?}", p[0]);
        assert!(p[0].lines_in_band > 50);
    }
}
