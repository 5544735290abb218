//! The recording format shared by every tool of the project.
//!
//! CSV: a header row, comma-separated, uniform sampling. Columns:
//! - `time_s` (required): time in seconds, strictly increasing, uniform step;
//! - `base_cmd_m`: commanded base position (m);
//! - `base_pos_m`: measured base position (m);
//! - `tip_pos_m`: absolute tip position along the base axis, lab frame (m);
//! - `force_n`: motor force (N).
//!
//! Columns other than `time_s` are optional; unknown columns are ignored with a note.
//! Also reads NumPy `.npy` arrays of shape (2, N) = [time; signal] (the format of the real
//! data in `shared/data/real/`) via [`Recording::read_npy`], without assuming uniform time.

use anyhow::{anyhow, bail, Context, Result};
use std::path::Path;

/// Relative tolerance on the sampling interval for a recording to count as uniform.
pub const UNIFORM_TOLERANCE: f64 = 1e-3;

/// A recording: time base and the optional channels, all the same length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// Sample times (s), strictly increasing.
    pub time_s: Vec<f64>,
    /// Commanded base position (m).
    pub base_cmd_m: Option<Vec<f64>>,
    /// Measured base position (m).
    pub base_pos_m: Option<Vec<f64>>,
    /// Absolute tip position, lab frame (m).
    pub tip_pos_m: Option<Vec<f64>>,
    /// Motor force (N).
    pub force_n: Option<Vec<f64>>,
    /// Notes made while reading (ignored columns, etc.), for the user.
    pub notes: Vec<String>,
}

/// The channel names in file order.
pub const CHANNELS: [&str; 4] = ["base_cmd_m", "base_pos_m", "tip_pos_m", "force_n"];

impl Recording {
    /// A recording with only a time base `t_k = k / sample_rate_hz`, k = 0..n.
    pub fn with_uniform_time(n: usize, sample_rate_hz: f64) -> Self {
        Recording {
            time_s: (0..n).map(|k| k as f64 / sample_rate_hz).collect(),
            ..Default::default()
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// True if there are no samples.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// The channel called `name` (one of [`CHANNELS`]).
    pub fn channel(&self, name: &str) -> Option<&[f64]> {
        match name {
            "base_cmd_m" => self.base_cmd_m.as_deref(),
            "base_pos_m" => self.base_pos_m.as_deref(),
            "tip_pos_m" => self.tip_pos_m.as_deref(),
            "force_n" => self.force_n.as_deref(),
            _ => None,
        }
    }

    fn channel_slot(&mut self, name: &str) -> Option<&mut Option<Vec<f64>>> {
        match name {
            "base_cmd_m" => Some(&mut self.base_cmd_m),
            "base_pos_m" => Some(&mut self.base_pos_m),
            "tip_pos_m" => Some(&mut self.tip_pos_m),
            "force_n" => Some(&mut self.force_n),
            _ => None,
        }
    }

    /// Sampling interval (s), the median of the time steps.
    pub fn sample_interval_s(&self) -> f64 {
        let mut d: Vec<f64> = self.time_s.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return f64::NAN;
        }
        d.sort_by(|a, b| a.total_cmp(b));
        d[d.len() / 2]
    }

    /// Sample rate (Hz) = 1 / [`Recording::sample_interval_s`].
    pub fn sample_rate_hz(&self) -> f64 {
        1.0 / self.sample_interval_s()
    }

    /// Checks the invariants every tool relies on: at least 2 samples, finite strictly
    /// increasing uniform time (within [`UNIFORM_TOLERANCE`]), every channel the same
    /// length as `time_s` and finite. Errors name the row (1-based data row) and column.
    pub fn validate(&self) -> Result<()> {
        let n = self.time_s.len();
        if n < 2 {
            bail!("recording has {n} samples; at least 2 are needed");
        }
        for (k, t) in self.time_s.iter().enumerate() {
            if !t.is_finite() {
                bail!("time_s is not finite at data row {}", k + 1);
            }
        }
        let dt = self.sample_interval_s();
        for (k, w) in self.time_s.windows(2).enumerate() {
            let d = w[1] - w[0];
            if d <= 0.0 {
                bail!(
                    "time_s is not strictly increasing at data row {} ({} -> {})",
                    k + 2,
                    w[0],
                    w[1]
                );
            }
            if (d - dt).abs() > UNIFORM_TOLERANCE * dt {
                bail!(
                    "time_s is not uniformly sampled: step {:.6} s at data row {} vs median {:.6} s \
                     (a gap or jitter; resample the recording first)",
                    d,
                    k + 2,
                    dt
                );
            }
        }
        for name in CHANNELS {
            if let Some(ch) = self.channel(name) {
                if ch.len() != n {
                    bail!("column {name} has {} samples, time_s has {n}", ch.len());
                }
                if let Some(k) = ch.iter().position(|v| !v.is_finite()) {
                    bail!(
                        "column {name} is not finite (NaN or inf) at data row {}",
                        k + 1
                    );
                }
            }
        }
        Ok(())
    }

    /// Reads a recording CSV and [validates](Recording::validate) it.
    ///
    /// Errors: unreadable file, no `time_s` column, a cell that is not a number (row and
    /// column named), a ragged row, non-uniform or non-increasing time, NaN/inf.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .from_path(path)
            .with_context(|| format!("cannot open recording {}", path.display()))?;
        let headers = rdr
            .headers()
            .with_context(|| format!("{}: no header row", path.display()))?
            .clone();
        let time_col = headers.iter().position(|h| h == "time_s").ok_or_else(|| {
            anyhow!(
                "{}: no `time_s` column (header: {:?})",
                path.display(),
                headers
            )
        })?;
        let mut rec = Recording::default();
        let mut cols: Vec<(usize, &'static str)> = Vec::new();
        for (i, h) in headers.iter().enumerate() {
            if i == time_col {
                continue;
            }
            if let Some(name) = CHANNELS.iter().find(|c| **c == h) {
                cols.push((i, name));
                *rec.channel_slot(name).expect("known channel") = Some(Vec::new());
            } else {
                rec.notes.push(format!("ignored column `{h}`"));
            }
        }
        for (row, result) in rdr.records().enumerate() {
            let record =
                result.with_context(|| format!("{}: data row {}", path.display(), row + 1))?;
            let cell = |i: usize, name: &str| -> Result<f64> {
                let s = record
                    .get(i)
                    .ok_or_else(|| anyhow!("data row {}: missing column {name}", row + 1))?;
                s.parse::<f64>().map_err(|_| {
                    anyhow!("data row {}, column {name}: `{s}` is not a number", row + 1)
                })
            };
            rec.time_s
                .push(cell(time_col, "time_s").with_context(|| path.display().to_string())?);
            for &(i, name) in &cols {
                let v = cell(i, name).with_context(|| path.display().to_string())?;
                rec.channel_slot(name)
                    .and_then(|c| c.as_mut())
                    .expect("allocated")
                    .push(v);
            }
        }
        rec.validate()
            .with_context(|| format!("{}: invalid recording", path.display()))?;
        Ok(rec)
    }

    /// Writes the recording as CSV (`time_s` then the present channels in [`CHANNELS`]
    /// order), full `f64` precision.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let mut w = csv::Writer::from_path(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let present: Vec<(&str, &[f64])> = CHANNELS
            .iter()
            .filter_map(|n| self.channel(n).map(|c| (*n, c)))
            .collect();
        let mut header = vec!["time_s"];
        header.extend(present.iter().map(|(n, _)| *n));
        w.write_record(&header)?;
        for k in 0..self.len() {
            let mut row = vec![format!("{}", self.time_s[k])];
            row.extend(present.iter().map(|(_, c)| format!("{}", c[k])));
            w.write_record(&row)?;
        }
        w.flush()?;
        Ok(())
    }

    /// Reads a NumPy `.npy` float64 array of shape (2, N): row 0 time (s), row 1 a signal.
    /// Returns `(time_s, signal)` as stored: the time base is **not** assumed uniform
    /// (the real accelerometer recordings have logging gaps); see [`resample_uniform`].
    ///
    /// Errors: not a float64 array, wrong shape, NaN, non-increasing time.
    pub fn read_npy(path: impl AsRef<Path>) -> Result<(Vec<f64>, Vec<f64>)> {
        let path = path.as_ref();
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let npy = npyz::NpyFile::new(&bytes[..])
            .with_context(|| format!("{}: not a .npy file", path.display()))?;
        let shape = npy.shape().to_vec();
        let fortran = npy.order() == npyz::Order::Fortran;
        let data: Vec<f64> = npy
            .into_vec::<f64>()
            .with_context(|| format!("{}: expected a float64 array", path.display()))?;
        let (t, x): (Vec<f64>, Vec<f64>) = match shape.as_slice() {
            [2, n] => {
                let n = *n as usize;
                if fortran {
                    (
                        data.iter().step_by(2).copied().collect(),
                        data.iter().skip(1).step_by(2).copied().collect(),
                    )
                } else {
                    (data[..n].to_vec(), data[n..].to_vec())
                }
            }
            [n, 2] => {
                let n = *n as usize;
                if fortran {
                    (data[..n].to_vec(), data[n..].to_vec())
                } else {
                    (
                        data.iter().step_by(2).copied().collect(),
                        data.iter().skip(1).step_by(2).copied().collect(),
                    )
                }
            }
            s => bail!(
                "{}: expected shape (2, N) [time; signal], got {:?}",
                path.display(),
                s
            ),
        };
        if t.len() < 2 {
            bail!("{}: fewer than 2 samples", path.display());
        }
        if let Some(k) = t
            .iter()
            .zip(&x)
            .position(|(a, b)| !a.is_finite() || !b.is_finite())
        {
            bail!("{}: NaN or inf at sample {k}", path.display());
        }
        if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
            bail!(
                "{}: time not strictly increasing at sample {}",
                path.display(),
                k + 1
            );
        }
        Ok((t, x))
    }
}

/// Resamples a non-uniformly sampled signal onto a uniform grid of `rate_hz` from `t[0]`
/// to `t[last]` by linear interpolation. Also returns the longest gap (s) in the input,
/// so that callers can warn when a gap is long against the signal's period.
pub fn resample_uniform(t: &[f64], x: &[f64], rate_hz: f64) -> (Vec<f64>, Vec<f64>, f64) {
    let max_gap = t.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let n = ((t[t.len() - 1] - t[0]) * rate_hz).floor() as usize + 1;
    let mut tu = Vec::with_capacity(n);
    let mut xu = Vec::with_capacity(n);
    let mut j = 0;
    for k in 0..n {
        let tk = t[0] + k as f64 / rate_hz;
        while j + 2 < t.len() && t[j + 1] < tk {
            j += 1;
        }
        let (t0, t1) = (t[j], t[j + 1]);
        let a = ((tk - t0) / (t1 - t0)).clamp(0.0, 1.0);
        tu.push(tk);
        xu.push(x[j] + a * (x[j + 1] - x[j]));
    }
    (tu, xu, max_gap)
}
