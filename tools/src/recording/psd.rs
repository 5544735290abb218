//! Klipper's spectrum files: `resonances_*.csv` (written by `TEST_RESONANCES`) and
//! `calibration_data_*.csv` (written by `SHAPER_CALIBRATE` and `calibrate_shaper.py -c`).
//!
//! Format (Klipper v0.13.0, `shaper_calibrate.save_calibration_data`): optional `#` comment
//! lines, then the header `freq,psd_x,psd_y,psd_z,psd_xyz`, then one row per frequency bin:
//! frequency (Hz, `%.1f`) and the power spectral densities of the acceleration along X, Y, Z and
//! their sum (`%.3e`, (mm/s²)²/Hz). A calibration file appends one column per fitted shaper,
//! named `mzv(53.8)` (v0.13.0) or after a `shapers:` marker column (later versions), holding that
//! shaper's vibration-reduction ratio per bin.
//!
//! Klipper divides the PSDs by the frequency before it fits a shaper
//! ([`normalize_to_frequencies`]); a file with shaper columns was written after that step, a
//! file without them before it (the rule of `scripts/calibrate_shaper.py`). [`read_spectrum`]
//! returns the PSDs as written and says which; [`KlipperSpectrum::fitting_psd`] gives the
//! normalised sum Klipper fits on.
//!
//! Multi-accelerometer files (header `freq,<name>,<name>,…`) hold only per-dataset sums and are
//! refused with a message naming the header.

use anyhow::{bail, Context, Result};
use std::path::Path;

/// Klipper's `MIN_FREQ` (Hz): below 2 × this the PSD is attenuated as low-frequency noise by
/// [`normalize_to_frequencies`].
pub const KLIPPER_MIN_FREQ_HZ: f64 = 5.0;

/// The header every spectrum file starts with.
pub const SPECTRUM_HEADER: &str = "freq,psd_x,psd_y,psd_z,psd_xyz";

/// A spectrum read from a Klipper file.
#[derive(Clone, Debug, PartialEq)]
pub struct KlipperSpectrum {
    /// Frequency bins (Hz), strictly increasing.
    pub freq_hz: Vec<f64>,
    /// PSD along X, Y, Z and their sum ((mm/s²)²/Hz, or divided by frequency when
    /// `normalized`), one value per bin.
    pub psd_x: Vec<f64>,
    /// See [`KlipperSpectrum::psd_x`].
    pub psd_y: Vec<f64>,
    /// See [`KlipperSpectrum::psd_x`].
    pub psd_z: Vec<f64>,
    /// See [`KlipperSpectrum::psd_x`].
    pub psd_sum: Vec<f64>,
    /// The file holds shaper columns, so its PSDs were already divided by frequency.
    pub normalized: bool,
    /// The shaper columns' names as written (e.g. `mzv(53.8)`), empty for a resonances file.
    pub shaper_columns: Vec<String>,
}

impl KlipperSpectrum {
    /// The PSD Klipper fits a shaper on: the sum over the axes, divided by frequency
    /// ([`normalize_to_frequencies`]) unless the file was written after that step.
    pub fn fitting_psd(&self) -> Vec<f64> {
        self.per_axis_fitting(&self.psd_sum)
    }

    /// `psd` (one of the file's columns) on the scale Klipper fits on.
    pub fn per_axis_fitting(&self, psd: &[f64]) -> Vec<f64> {
        match self.normalized {
            true => psd.to_vec(),
            false => normalize_to_frequencies(&self.freq_hz, psd),
        }
    }
}

/// Klipper's `CalibrationData.normalize_to_frequencies` (v0.13.0), from its formula: every bin
/// divided by `f + 0.1` (Hz), and bins below `2·MIN_FREQ` = 10 Hz attenuated by
/// `exp(1 − (2·MIN_FREQ / (f + 0.1))²)` (low-frequency noise). Shapes: `psd.len() == freq_hz.len()`.
pub fn normalize_to_frequencies(freq_hz: &[f64], psd: &[f64]) -> Vec<f64> {
    let lim = 2.0 * KLIPPER_MIN_FREQ_HZ;
    freq_hz
        .iter()
        .zip(psd)
        .map(|(&f, &p)| {
            let v = p / (f + 0.1);
            match f < lim {
                true => v * (1.0 - (lim / (f + 0.1)).powi(2)).exp(),
                false => v,
            }
        })
        .collect()
}

/// The first non-comment line of the file at `path` starts with `freq,psd_x,…` (optionally
/// after a `#`): a Klipper spectrum. `false` when the file cannot be read.
pub fn is_spectrum_file(path: &Path) -> bool {
    use std::io::BufRead;
    let Ok(f) = std::fs::File::open(path) else {
        return false;
    };
    for line in std::io::BufReader::new(f).lines().take(50) {
        let Ok(line) = line else { return false };
        let t = line.trim_start_matches('\u{feff}').trim();
        if t.is_empty() {
            continue;
        }
        if header_text(t).is_some() {
            return true;
        }
        if !t.starts_with('#') {
            return false;
        }
    }
    false
}

/// The header without a leading `#`, when `line` is a spectrum header.
fn header_text(line: &str) -> Option<&str> {
    let h = line.strip_prefix('#').unwrap_or(line).trim();
    h.starts_with(SPECTRUM_HEADER).then_some(h)
}

/// Reads a Klipper spectrum file (see the module docs).
///
/// Errors (each names the file and, for a cell, its line and column): unreadable file; no
/// `freq,psd_x,psd_y,psd_z,psd_xyz` header (a multi-accelerometer header is named as such); a
/// row with fewer than 5 cells; a cell that is not a finite number; a negative PSD; frequencies
/// not strictly increasing; fewer than 3 rows.
pub fn read_spectrum(path: &Path) -> Result<KlipperSpectrum> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the spectrum file {}", path.display()))?;
    parse_spectrum(&text).with_context(|| format!("spectrum file {}", path.display()))
}

/// The first five cells of the row at 1-based `line_no`: frequency and four PSDs (finite,
/// PSDs non-negative). Errors name the line and the column.
fn parse_row(line_no: usize, line: &str, names: &[&str]) -> Result<[f64; 5]> {
    let cells: Vec<&str> = line.split(',').map(str::trim).collect();
    if cells.len() < 5 {
        bail!(
            "line {line_no}: {} cells, expected at least 5 ({SPECTRUM_HEADER})",
            cells.len()
        );
    }
    let mut v = [0.0; 5];
    for (c, (slot, cell)) in v.iter_mut().zip(&cells).enumerate() {
        *slot = cell
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .with_context(|| {
                format!(
                    "line {line_no}, column `{}`: `{cell}` is not a finite number",
                    names[c]
                )
            })?;
        if c > 0 && *slot < 0.0 {
            bail!(
                "line {line_no}, column `{}`: negative power spectral density {cell}",
                names[c]
            );
        }
    }
    Ok(v)
}

/// [`read_spectrum`] on the file's text.
pub fn parse_spectrum(text: &str) -> Result<KlipperSpectrum> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| {
        let t = l.trim_start_matches('\u{feff}').trim();
        !t.is_empty() && (!t.starts_with('#') || header_text(t).is_some())
    });
    let Some((_, first)) = lines.next() else {
        bail!("empty: no header `{SPECTRUM_HEADER}`");
    };
    let first = first.trim_start_matches('\u{feff}').trim();
    let Some(header) = header_text(first) else {
        if first.starts_with("freq,") {
            bail!("header `{first}` is a multi-accelerometer file (per-dataset sums, no per-axis PSD); give one accelerometer's file with header `{SPECTRUM_HEADER}`");
        }
        bail!("not a Klipper spectrum: the header is `{first}`, expected `{SPECTRUM_HEADER}` (resonances_*.csv or calibration_data_*.csv)");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let shaper_columns: Vec<String> = names[5..]
        .iter()
        .filter(|n| !n.is_empty() && **n != "shapers:")
        .map(|n| n.to_string())
        .collect();
    let mut s = KlipperSpectrum {
        freq_hz: vec![],
        psd_x: vec![],
        psd_y: vec![],
        psd_z: vec![],
        psd_sum: vec![],
        normalized: !shaper_columns.is_empty(),
        shaper_columns,
    };
    for (i, line) in lines {
        let v = parse_row(i + 1, line, &names)?;
        if let Some(&last) = s.freq_hz.last() {
            if v[0] <= last {
                bail!(
                    "line {}: frequency {} Hz does not increase (previous {last} Hz)",
                    i + 1,
                    v[0]
                );
            }
        }
        s.freq_hz.push(v[0]);
        s.psd_x.push(v[1]);
        s.psd_y.push(v[2]);
        s.psd_z.push(v[3]);
        s.psd_sum.push(v[4]);
    }
    if s.freq_hz.len() < 3 {
        bail!(
            "{} frequency rows, at least 3 are needed for a spectrum",
            s.freq_hz.len()
        );
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_both_kinds_and_normalizes_only_the_resonances_file() {
        let r = parse_spectrum(
            "freq,psd_x,psd_y,psd_z,psd_xyz\n0.0,1,2,3,6\n20.0,1,1,1,3\n40.0,2,0,0,2\n",
        )
        .unwrap();
        assert!(!r.normalized);
        let p = r.fitting_psd();
        assert!((p[1] - 3.0 / 20.1).abs() < 1e-12);
        // 0 Hz: 6/0.1 · exp(1 − (10/0.1)²) underflows to 0.
        assert_eq!(p[0], 0.0);
        let c = parse_spectrum("#comment\nfreq,psd_x,psd_y,psd_z,psd_xyz,shapers:,zv(50.0),mzv(40.0)\n1.0,1,2,3,6,,0.5,0.4\n2.0,1,1,1,3,,0.5,0.4\n3.0,1,1,1,3,,0.5,0.4\n").unwrap();
        assert!(c.normalized);
        assert_eq!(c.shaper_columns, vec!["zv(50.0)", "mzv(40.0)"]);
        assert_eq!(c.fitting_psd(), c.psd_sum);
    }

    #[test]
    fn refuses_bad_files_with_the_line_named() {
        let e = parse_spectrum("time,accel_x\n1,2\n").unwrap_err();
        assert!(e.to_string().contains("not a Klipper spectrum"), "{e}");
        let e = parse_spectrum("freq,a,b\n1,2,3\n").unwrap_err();
        assert!(e.to_string().contains("multi-accelerometer"), "{e}");
        let h = "freq,psd_x,psd_y,psd_z,psd_xyz\n";
        let e = parse_spectrum(&format!("{h}1,1,1,1,x\n")).unwrap_err();
        assert!(e.to_string().contains("line 2, column `psd_xyz`"), "{e}");
        let e = parse_spectrum(&format!("{h}1,1,1,1,1\n1,1,1,1,1\n2,1,1,1,1\n")).unwrap_err();
        assert!(e.to_string().contains("does not increase"), "{e}");
        let e = parse_spectrum(&format!("{h}1,1,-1,1,1\n")).unwrap_err();
        assert!(e.to_string().contains("negative"), "{e}");
        let e = parse_spectrum(&format!("{h}1,1,1,1,1\n")).unwrap_err();
        assert!(e.to_string().contains("at least 3"), "{e}");
    }
}
