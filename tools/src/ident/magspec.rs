//! Modes from a measured *magnitude* spectrum (no phase, no time record): e.g. the LabVIEW
//! `.lvm` export of an impact-hammer test's acceleration spectrum.
//!
//! Each resonance is fitted, in dB, by the magnitude of one mode's accelerance plus a floor:
//!
//! ```text
//! |A(f)| = a · r² / √((1 − r²)² + (2ζr)²) + b,      r = f / f_n
//! ```
//!
//! (receptance of one mode times ω², paper eq. 25 for one term; `b` the neighbouring modes
//! and the noise floor), by Levenberg–Marquardt on the lines around the peak. Without phase
//! the damping comes from the peak's width only. When the measured −3 dB width spans fewer
//! than [`RESOLVED_LINES`] lines the peak is the analyser window's main lobe, not the mode:
//! then f_n is the Gaussian (log-parabolic) interpolation of the three top lines and ζ is
//! reported only as the upper bound w·Δf / (2 f_n) from the measured width w (half-power
//! bandwidth = 2ζf_n, paper eq. 27 with the half-power points).

use crate::numeric::lm::{fd_jacobian, minimize, Difference, LmOptions};
use anyhow::{bail, Context, Result};
use nalgebra::DVector;
use std::path::Path;

/// Half-power bands narrower than this many lines make ζ an upper bound.
pub const RESOLVED_LINES: f64 = 4.0;

/// A magnitude spectrum on a uniform grid.
#[derive(Clone, Debug)]
pub struct MagnitudeSpectrum {
    /// Frequencies (Hz), uniform.
    pub freq_hz: Vec<f64>,
    /// Magnitude (dB).
    pub mag_db: Vec<f64>,
    /// Unit of the magnitude (from the file header, e.g. `g`).
    pub unit: String,
}

/// Reads a LabVIEW measurement file (`.lvm`, text) holding a spectrum: the data after the last
/// `***End_of_Header***`, a `X_Value …` heading, then tab-separated frequency (Hz) and
/// magnitude (dB) rows.
///
/// Errors: no header end, fewer than 16 rows, a non-numeric or non-finite value (row named),
/// a non-uniform or non-increasing frequency grid, a `Delta_X` that disagrees with the rows.
pub fn read_lvm(path: &Path) -> Result<MagnitudeSpectrum> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let end = text.rfind("***End_of_Header***").with_context(|| {
        format!(
            "{}: no `***End_of_Header***` (not a LabVIEW .lvm file?)",
            path.display()
        )
    })?;
    let header = &text[..end];
    let field = |name: &str| {
        header
            .lines()
            .filter_map(|l| l.strip_prefix(name))
            .last()
            .map(|v| v.trim().to_string())
    };
    let unit = field("Y_Unit_Label").unwrap_or_default();
    let delta: Option<f64> =
        field("Delta_X").and_then(|v| v.split('\t').next()?.trim().parse().ok());
    let body = &text[end..];
    let (mut f, mut m) = (Vec::new(), Vec::new());
    for (i, line) in body.lines().enumerate().skip(1) {
        let line = line.trim();
        if line.is_empty() || line.starts_with("X_Value") {
            continue;
        }
        let mut it = line.split('\t');
        let parse = |s: Option<&str>, what: &str| -> Result<f64> {
            let s =
                s.with_context(|| format!("{}: data line {i}: missing {what}", path.display()))?;
            let v: f64 = s.trim().parse().with_context(|| {
                format!(
                    "{}: data line {i}: `{s}` is not a number ({what})",
                    path.display()
                )
            })?;
            if !v.is_finite() {
                bail!("{}: data line {i}: {what} is not finite", path.display());
            }
            Ok(v)
        };
        f.push(parse(it.next(), "frequency")?);
        m.push(parse(it.next(), "magnitude")?);
    }
    if f.len() < 16 {
        bail!(
            "{}: {} spectrum lines; need at least 16",
            path.display(),
            f.len()
        );
    }
    let df = f[1] - f[0];
    if !(df > 0.0) {
        bail!("{}: frequencies do not increase", path.display());
    }
    for k in 1..f.len() {
        if ((f[k] - f[k - 1]) / df - 1.0).abs() > 1e-3 {
            bail!(
                "{}: non-uniform frequency grid at line {k} ({} → {} Hz)",
                path.display(),
                f[k - 1],
                f[k]
            );
        }
    }
    if let Some(d) = delta {
        if (d / df - 1.0).abs() > 1e-3 {
            bail!(
                "{}: header Delta_X = {d} Hz but the rows step {df} Hz",
                path.display()
            );
        }
    }
    Ok(MagnitudeSpectrum {
        freq_hz: f,
        mag_db: m,
        unit,
    })
}

/// One mode fitted to a magnitude spectrum.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MagnitudeMode {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio; when `resolution_limited`, the upper bound w·Δf / (2 f_n).
    pub zeta: f64,
    /// 1-σ of `freq_hz` (Hz): the fit's covariance, or Δf/√12 when resolution-limited.
    pub freq_hz_std: f64,
    /// 1-σ of `zeta` from the fit's covariance (NaN when resolution-limited).
    pub zeta_std: f64,
    /// Topographic prominence of the peak (dB).
    pub prominence_db: f64,
    /// −3 dB width of the peak in spectral lines (measured if resolution-limited, else 2ζf_n/Δf).
    pub half_power_lines: f64,
    /// ζ cannot be resolved: half-power band < [`RESOLVED_LINES`] lines.
    pub resolution_limited: bool,
    /// RMS misfit of the fit (dB; NaN when resolution-limited: no fit).
    pub rms_misfit_db: f64,
}

/// |A(f)| of the module docs in dB, parameters p = (ln a, f_n, ln ζ, ln b).
fn model_db(p: &DVector<f64>, f: f64) -> f64 {
    let (a, fnat, z, b) = (p[0].exp(), p[1], p[2].exp(), p[3].exp());
    let r = f / fnat;
    let m = a * r * r / ((1.0 - r * r).powi(2) + (2.0 * z * r).powi(2)).sqrt() + b;
    20.0 * m.log10()
}

/// Residuals model − measured (dB) on the lines `f`, `db`; `None` if one is not finite.
fn peak_residuals(f: &[f64], db: &[f64], p: &DVector<f64>) -> Option<DVector<f64>> {
    let r = DVector::from_iterator(f.len(), f.iter().zip(db).map(|(&f, &d)| model_db(p, f) - d));
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// The adapter's options of a peak fit starting at `f_n0`: central differences, steps 1e-6 in
/// the logarithms and 1e-7 f_n0 in f_n, patience 300.
fn lm_options(f_n0: f64) -> LmOptions {
    LmOptions {
        difference: Difference::Central,
        patience: 300,
        ..LmOptions::new(vec![1e-6, 1e-7 * f_n0.abs().max(1e-3), 1e-6, 1e-6])
    }
}

/// Topographic prominence (dB) of the maximum at line `k`: its height above the higher of
/// the two lowest points between it and a higher line on each side (or the end of the
/// search, `reach` lines).
fn prominence(db: &[f64], k: usize, reach: usize) -> f64 {
    let side = |step: isize| {
        let mut lowest = db[k];
        let mut j = k as isize;
        for _ in 0..reach {
            j += step;
            if j < 0 || j as usize >= db.len() || db[j as usize] > db[k] {
                break;
            }
            lowest = lowest.min(db[j as usize]);
        }
        lowest
    };
    db[k] - side(-1).max(side(1))
}

/// Width (lines) of the peak at line `k` where it is 3 dB below its top, linearly
/// interpolated in dB on each side.
fn half_power_width_lines(db: &[f64], k: usize) -> f64 {
    let level = db[k] - 3.0;
    let side = |step: isize| {
        let mut j = k as isize;
        loop {
            let nx = j + step;
            if nx < 0 || nx as usize >= db.len() {
                return (j - k as isize).unsigned_abs() as f64;
            }
            let (a, b) = (db[j as usize], db[nx as usize]);
            if b <= level {
                return (j - k as isize).unsigned_abs() as f64 + (a - level) / (a - b);
            }
            j = nx;
        }
    };
    side(-1) + side(1)
}

/// Modes of a magnitude spectrum in `[f_min_hz, f_max_hz]`: local maxima with a topographic prominence of at
/// least `min_prominence_db` (searched over ±2000 lines), strongest first, at most
/// `max_modes` (a weaker maximum within 8 lines of a stronger one is dropped), each fitted as
/// in the module docs on ±max(8, 2w) lines; returned in ascending frequency.
///
/// Errors: an empty band, no peak.
pub fn identify_magnitude_spectrum(
    s: &MagnitudeSpectrum,
    f_min_hz: f64,
    f_max_hz: f64,
    min_prominence_db: f64,
    max_modes: usize,
) -> Result<Vec<MagnitudeMode>> {
    let (f, db) = (&s.freq_hz, &s.mag_db);
    let n = f.len();
    let lo = f.iter().position(|&x| x >= f_min_hz).unwrap_or(n).max(1);
    let hi = f
        .iter()
        .rposition(|&x| x <= f_max_hz)
        .unwrap_or(0)
        .min(n - 2);
    if lo > hi {
        bail!("no spectrum line in {f_min_hz}..{f_max_hz} Hz");
    }
    let kept = prominent_peaks(db, lo..=hi, min_prominence_db, max_modes);
    if kept.is_empty() {
        bail!(
            "no peak {min_prominence_db} dB above its neighbourhood in {f_min_hz}..{f_max_hz} Hz"
        );
    }
    let mut out: Vec<MagnitudeMode> = kept
        .into_iter()
        .filter_map(|(k, prom)| {
            let width = half_power_width_lines(db, k);
            if width < RESOLVED_LINES {
                Some(unresolved_mode(f, db, k, prom, width))
            } else {
                fit_peak(f, db, k, prom, width)
            }
        })
        .collect();
    if out.is_empty() {
        bail!("no peak could be fitted in {f_min_hz}..{f_max_hz} Hz");
    }
    out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok(out)
}

/// Half-width (lines) of a peak's fit window, and the distance within which a weaker maximum
/// is a stronger one's side lobe or noise.
const HALF_WINDOW: usize = 8;

/// Local maxima of `db` in `range` with a prominence ≥ `min_prominence_db` (over ±2000
/// lines), strongest first, none within [`HALF_WINDOW`] lines of a stronger one, at most
/// `max_modes`: (line, prominence dB).
fn prominent_peaks(
    db: &[f64],
    range: std::ops::RangeInclusive<usize>,
    min_prominence_db: f64,
    max_modes: usize,
) -> Vec<(usize, f64)> {
    let mut cands: Vec<(usize, f64)> = range
        .filter(|&k| db[k] > db[k - 1] && db[k] >= db[k + 1])
        .map(|k| (k, prominence(db, k, 2000)))
        .filter(|&(_, p)| p >= min_prominence_db)
        .collect();
    cands.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<(usize, f64)> = Vec::new();
    for c in cands {
        if kept.iter().all(|k| k.0.abs_diff(c.0) > HALF_WINDOW) {
            kept.push(c);
        }
    }
    kept.truncate(max_modes);
    kept
}

/// A peak narrower than [`RESOLVED_LINES`]: f_n by Gaussian (log-parabolic) interpolation of
/// the three top lines, ζ the upper bound w·Δf / (2 f_n).
fn unresolved_mode(f: &[f64], db: &[f64], k: usize, prom: f64, width: f64) -> MagnitudeMode {
    let df = f[1] - f[0];
    let (y0, y1, y2) = (db[k - 1], db[k], db[k + 1]);
    let d = y0 - 2.0 * y1 + y2;
    let shift = if d < 0.0 {
        (0.5 * (y0 - y2) / d).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let fnat = f[k] + shift * df;
    MagnitudeMode {
        freq_hz: fnat,
        zeta: width.max(1.0) * df / (2.0 * fnat),
        freq_hz_std: df / 12f64.sqrt(),
        zeta_std: f64::NAN,
        prominence_db: prom,
        half_power_lines: width,
        resolution_limited: true,
        rms_misfit_db: f64::NAN,
    }
}

/// The single-mode accelerance fit of the module docs on ±max(8, 2w) lines around line `k`,
/// started from the half-power width `width` and the median floor of ±60 lines; `None` when
/// the fit fails or leaves the window or 0 < ζ < 0.5.
fn fit_peak(f: &[f64], db: &[f64], k: usize, prom: f64, width: f64) -> Option<MagnitudeMode> {
    let (n, df) = (f.len(), f[1] - f[0]);
    let half = HALF_WINDOW.max(2 * width as usize);
    let (a, b) = (k.saturating_sub(half), (k + half + 1).min(n));
    let nb = 60;
    let mut v: Vec<f64> = db[k.saturating_sub(nb)..(k + nb + 1).min(n)].to_vec();
    v.sort_by(|x, y| x.total_cmp(y));
    let floor = v[v.len() / 2];
    let lin = |d: f64| 10f64.powf(d / 20.0);
    let z0 = (0.5 * width * df / f[k]).max(1e-5);
    let a0 = (lin(db[k]) - lin(floor)).max(1e-30) * 2.0 * z0;
    let p0 = DVector::from_vec(vec![a0.ln(), f[k], z0.ln(), lin(floor).ln()]);
    let res = |p: &DVector<f64>| peak_residuals(&f[a..b], &db[a..b], p);
    let opts = lm_options(f[k]);
    let p = minimize(&res, p0, &opts).x;
    let r = res(&p)?;
    let j = fd_jacobian(&res, &p, &r, &opts)?;
    let (fnat, zeta) = (p[1], p[2].exp());
    if !(fnat > f[a] && fnat < f[b - 1] && zeta > 0.0 && zeta < 0.5) {
        return None;
    }
    let dof = (r.len() as f64 - 4.0).max(1.0);
    let s2 = r.norm_squared() / dof;
    let cov = (j.transpose() * &j).try_inverse().map(|c| c * s2);
    let (sf, sz) = cov.map_or((f64::NAN, f64::NAN), |c| {
        (c[(1, 1)].max(0.0).sqrt(), zeta * c[(2, 2)].max(0.0).sqrt())
    });
    Some(MagnitudeMode {
        freq_hz: fnat,
        zeta,
        freq_hz_std: sf,
        zeta_std: sz,
        prominence_db: prom,
        half_power_lines: 2.0 * zeta * fnat / df,
        resolution_limited: false,
        rms_misfit_db: (r.norm_squared() / r.len() as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    fn synthetic(df: f64, modes: &[(f64, f64)], noise_db: f64) -> MagnitudeSpectrum {
        let mut rng = StdRng::seed_from_u64(2);
        let nrm = Normal::new(0.0, noise_db).unwrap();
        let freq_hz: Vec<f64> = (0..4000).map(|k| k as f64 * df).collect();
        let mag_db = freq_hz
            .iter()
            .map(|&f| {
                let m: f64 = modes
                    .iter()
                    .map(|&(fnat, z)| {
                        let r = f / fnat;
                        1e-3 * r * r / ((1.0 - r * r).powi(2) + (2.0 * z * r).powi(2)).sqrt()
                    })
                    .sum::<f64>()
                    + 1e-5;
                20.0 * m.log10() + nrm.sample(&mut rng)
            })
            .collect();
        MagnitudeSpectrum {
            freq_hz,
            mag_db,
            unit: "g".into(),
        }
    }

    /// Well-resolved peaks (half-power band ≥ 6 lines): f within 3 σ and a quarter line, ζ to
    /// 10 %.
    #[test]
    fn fits_resolved_modes() {
        let modes = [(6.6, 0.02), (41.4, 0.01)];
        let s = synthetic(0.02, &modes, 0.3);
        let r = identify_magnitude_spectrum(&s, 1.0, 70.0, 10.0, 2).unwrap();
        assert_eq!(r.len(), 2);
        for (m, t) in r.iter().zip(&modes) {
            assert!(
                (m.freq_hz - t.0).abs() < (3.0 * m.freq_hz_std).min(0.005),
                "{m:?}"
            );
            assert!((m.zeta / t.1 - 1.0).abs() < 0.1, "{m:?}");
            assert!(!m.resolution_limited);
        }
    }

    /// A peak one line wide is flagged resolution-limited.
    #[test]
    fn flags_unresolved_damping() {
        let s = synthetic(0.0853, &[(6.571, 0.003)], 0.3);
        let r = identify_magnitude_spectrum(&s, 1.0, 70.0, 10.0, 1).unwrap();
        assert!(r[0].resolution_limited, "{:?}", r[0]);
        assert!((r[0].freq_hz - 6.571).abs() < 0.0853);
    }
}
