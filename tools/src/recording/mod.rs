//! The recording format shared by every tool of the project.
//!
//! CSV: a header row, comma-separated (`;` with decimal commas, or tabs, are read too, with a
//! note), uniform sampling. Columns:
//! - `time_s` (required): time in seconds of each sample, strictly increasing, uniform step
//!   (dropped frames, duplicated rows and jittering stamps are mended by [`regular`]);
//! - `base_cmd_m`: commanded base position (m);
//! - `base_pos_m`: measured base position (m);
//! - `tip_pos_m`: absolute tip position along the base axis, lab frame (m);
//! - `force_n`: motor force (N).
//!
//! Columns other than `time_s` are optional; unknown columns are ignored with a note. Positions
//! in millimetres or micrometres (`tip_pos_mm`, `base_cmd_um`, …) and times in `time_ms` or
//! `time_us` are converted to SI with a note. A blank
//! or `nan` cell of a channel is a missing value ([`regular`] fills short runs of them).
//! Also reads NumPy `.npy` arrays of shape (2, N) = [time; signal] (the format of the real
//! data in `shared/data/real/`) via [`Recording::read_npy`], without assuming uniform time.

pub mod glitch;
pub mod multirate;
pub mod orient;
pub mod psd;
pub mod regular;
pub mod zero;

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
        self.validate_gapped()?;
        let dt = self.sample_interval_s();
        for (k, w) in self.time_s.windows(2).enumerate() {
            let d = w[1] - w[0];
            if (d - dt).abs() > UNIFORM_TOLERANCE * dt {
                bail!(
                    "time_s is not uniformly sampled: step {} s at data row {} vs median {} s \
                     (a gap or jitter; `identify` splits a recording at its gaps)",
                    fmt_sig(d, 4),
                    k + 2,
                    fmt_sig(dt, 4)
                );
            }
        }
        Ok(())
    }

    /// [`Recording::validate`] without the uniform-step check: a recording with logging gaps
    /// or jitter (strictly increasing, finite time; finite channels of the same length).
    pub fn validate_gapped(&self) -> Result<()> {
        let n = self.time_s.len();
        if n < 2 {
            bail!("recording has {n} samples; at least 2 are needed");
        }
        if let Some(k) = self.time_s.iter().position(|t| !t.is_finite()) {
            bail!("time_s is not finite (NaN or inf) at data row {}", k + 1);
        }
        if let Some(k) = self.time_s.windows(2).position(|w| w[1] <= w[0]) {
            bail!(
                "time_s is not strictly increasing at data row {} ({} -> {})",
                k + 2,
                self.time_s[k],
                self.time_s[k + 1]
            );
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

    /// Reads a recording CSV onto a uniform, complete time base: duplicated rows, dropped
    /// frames, blank or `nan` cells and jittering time stamps are mended as
    /// [`regular::regularise`] says, with a note each; the result passes
    /// [`Recording::validate`].
    ///
    /// Errors: unreadable file, no time column, a cell that is not a number (row and
    /// column named), a ragged row, and what [`regular::regularise`] refuses (time going
    /// backwards, a long gap, a varying sample rate), each with the file's name.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Self> {
        Self::read_csv_leaving_gaps(path, &[]).map(|(rec, _)| rec)
    }

    /// [`Recording::read_csv`], except that the channels named in `gappy` may lose their
    /// reading for longer than [`regular::MAX_FILL_RUN`] samples (a camera that lost its
    /// marker): those runs are bridged and returned ([`regular::regularise_leaving_gaps`]),
    /// for a comparison to leave out.
    ///
    /// Errors: as [`Recording::read_csv`], except the long gap in a channel of `gappy`.
    pub fn read_csv_leaving_gaps(
        path: impl AsRef<Path>,
        gappy: &[&str],
    ) -> Result<(Self, regular::Gaps)> {
        let path = path.as_ref();
        let rec = Self::read_csv_cells(path, &mut |_| {})?;
        if let Some(k) = rec.time_s.iter().position(|t| !t.is_finite()) {
            bail!(
                "{}: time_s is not finite at data row {}",
                path.display(),
                k + 1
            );
        }
        regular::regularise_leaving_gaps(rec, gappy)
            .with_context(|| format!("{}: invalid recording", path.display()))
    }

    /// Reads a recording CSV row by row (memory: the columns only, 8 bytes per value) and
    /// checks it with [`Recording::validate_gapped`]: logging gaps and jitter are allowed
    /// (see [`split_at_gaps`]). The time column is `time_s` (seconds) or `time_ms`
    /// (milliseconds, converted with a note). `progress(rows)` is called every 2²⁰ rows.
    ///
    /// Errors: unreadable file, no time column (a `time`/`t` column is refused with the
    /// hint to name its unit), a cell that is not a number, NaN/inf, non-increasing time.
    pub fn read_csv_gapped(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        let rec = Self::read_csv_cells(path, progress)?;
        rec.validate_gapped()
            .with_context(|| format!("{}: invalid recording", path.display()))?;
        Ok(rec)
    }

    /// [`Recording::read_csv_gapped`], except that a file with blank or `nan` cells is first
    /// [regularised](regular::regularise) (short runs filled, with notes); where that is refused
    /// (a long logging gap, which `identify` splits at), the gapped reading's error stands.
    fn read_csv_any(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        let rec = Self::read_csv_cells(path, progress)?;
        let blanks = CHANNELS
            .iter()
            .filter_map(|n| rec.channel(n))
            .any(|c| c.iter().any(|v| v.is_nan()));
        if blanks && rec.time_s.iter().all(|t| t.is_finite()) {
            if let Ok(r) = regular::regularise(rec.clone()) {
                return Ok(r);
            }
        }
        rec.validate_gapped()
            .with_context(|| format!("{}: invalid recording", path.display()))?;
        Ok(rec)
    }

    /// The cells of a recording CSV as numbers, unchecked: a blank or `nan` cell of a
    /// channel is NaN (a missing value).
    fn read_csv_cells(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        let delimiter = sniff_delimiter(path)?;
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .delimiter(delimiter)
            .from_path(path)
            .with_context(|| format!("cannot open recording {}", path.display()))?;
        let headers = rdr
            .headers()
            .with_context(|| format!("{}: no header row", path.display()))?
            .clone();
        let names: Vec<&str> = headers.iter().collect();
        let (time_col, time_scale) =
            time_column(&names).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        let mut rec = Recording::default();
        rec.notes.extend(delimiter_note(delimiter));
        if time_scale != 1.0 {
            let h = names[time_col];
            rec.notes.push(format!(
                "time column `{h}` converted to seconds (×{time_scale:e})"
            ));
        }
        let cols = channel_columns(&names, time_col, &mut rec)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
        let mut slots: Vec<Vec<f64>> = vec![Vec::new(); cols.len()];
        let mut record = csv::ByteRecord::new();
        let mut row = 0usize;
        loop {
            let more = rdr.read_byte_record(&mut record).map_err(|e| {
                anyhow!(
                    "{}: data row {}: {}",
                    path.display(),
                    row + 1,
                    csv_error(&e)
                )
            })?;
            if !more {
                break;
            }
            row += 1;
            let cell = |i: usize, name: &str| -> Result<f64> {
                let b = record.get(i).ok_or_else(|| {
                    anyhow!("{}: data row {row}: missing column {name}", path.display())
                })?;
                let s = std::str::from_utf8(b).unwrap_or("?");
                if s.is_empty() && i != time_col {
                    return Ok(f64::NAN);
                }
                parse_number(s, delimiter).map_err(|_| {
                    anyhow!(
                        "{}: data row {row}, column {name}: `{s}` is not a number",
                        path.display()
                    )
                })
            };
            rec.time_s
                .push(cell(time_col, names[time_col])? * time_scale);
            for (slot, &(i, name, scale)) in slots.iter_mut().zip(&cols) {
                slot.push(cell(i, name)? * scale);
            }
            if row % (1 << 20) == 0 {
                progress(row);
            }
        }
        for (slot, &(_, name, _)) in slots.into_iter().zip(&cols) {
            *rec.channel_slot(name).expect("known channel") = Some(slot);
        }
        Ok(rec)
    }

    /// Reads any recording by its extension: `.npy` ([`Recording::read_npy`], the signal
    /// row as `tip_pos_m` in the unit it was recorded in, with a note) or CSV (any other
    /// extension, [`Recording::read_csv_gapped`]). Gaps and jitter are kept (see
    /// [`split_at_gaps`]); a time base in milliseconds is refused with that hint when
    /// nothing could be identified below its Nyquist frequency (see [`check_time_unit`]).
    /// LabVIEW `.lvm` files are spectra here: read them with `ident::magspec::read_lvm`. A CSV
    /// with blank or `nan` cells is read through [`regular::regularise`] where it allows.
    pub fn read_any(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let rec = if ext == "npy" {
            let (t, x) = Self::read_npy(path)?;
            Recording {
                time_s: t,
                tip_pos_m: Some(x),
                notes: vec![
                    "`.npy` [time; signal]: the signal row stands for the tip (unit as recorded)"
                        .into(),
                ],
                ..Default::default()
            }
        } else if ext == "lvm" {
            bail!(
                "{}: a LabVIEW `.lvm` file is read as a magnitude spectrum by `identify`, not as a time recording",
                path.display()
            );
        } else {
            Self::read_csv_any(path, progress)?
        };
        check_time_unit(&rec).map_err(|e| anyhow!("{}: {e}", path.display()))?;
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

    /// Reads a NumPy `.npy` array of shape (2, N) or (N, 2) (float64, float32 or integer):
    /// row 0 time (s), row 1 a signal.
    /// Returns `(time_s, signal)` as stored: the time base is **not** assumed uniform
    /// (the real accelerometer recordings have logging gaps); see [`resample_uniform`].
    ///
    /// Errors: not a numeric array, wrong shape, NaN, non-increasing time.
    pub fn read_npy(path: impl AsRef<Path>) -> Result<(Vec<f64>, Vec<f64>)> {
        let path = path.as_ref();
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let npy = npyz::NpyFile::new(&bytes[..])
            .with_context(|| format!("{}: not a .npy file", path.display()))?;
        let shape = npy.shape().to_vec();
        let fortran = npy.order() == npyz::Order::Fortran;
        let data = npy_values(&bytes)
            .ok_or_else(|| anyhow!("{}: expected a float or integer array (float64, float32, int8..int64, uint8..uint64)", path.display()))?;
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
                "{}: expected shape (2, N) [time; signal], got ({})",
                path.display(),
                s.iter()
                    .map(|d| d.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
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

/// The values of a `.npy` file as f64, whatever its numeric dtype (`None` if not numeric).
fn npy_values(bytes: &[u8]) -> Option<Vec<f64>> {
    fn conv<T: npyz::Deserialize + Into<f64>>(bytes: &[u8]) -> Option<Vec<f64>> {
        let v = npyz::NpyFile::new(bytes).ok()?.into_vec::<T>().ok()?;
        Some(v.into_iter().map(Into::into).collect())
    }
    fn conv64<T: npyz::Deserialize + Copy>(bytes: &[u8], f: fn(T) -> f64) -> Option<Vec<f64>> {
        let v = npyz::NpyFile::new(bytes).ok()?.into_vec::<T>().ok()?;
        Some(v.into_iter().map(f).collect())
    }
    conv::<f64>(bytes)
        .or_else(|| conv::<f32>(bytes))
        .or_else(|| conv64::<i64>(bytes, |v| v as f64))
        .or_else(|| conv::<i32>(bytes))
        .or_else(|| conv::<i16>(bytes))
        .or_else(|| conv::<i8>(bytes))
        .or_else(|| conv64::<u64>(bytes, |v| v as f64))
        .or_else(|| conv::<u32>(bytes))
        .or_else(|| conv::<u16>(bytes))
        .or_else(|| conv::<u8>(bytes))
}

/// The time column of a CSV header and its scale to seconds: `time_s` (1), `time_ms` (10⁻³)
/// or `time_us` (10⁻⁶). A column named `time` or `t` without a unit is refused with the hint.
fn time_column(names: &[&str]) -> Result<(usize, f64)> {
    if let Some(i) = names.iter().position(|h| *h == "time_s") {
        return Ok((i, 1.0));
    }
    if let Some(i) = names.iter().position(|h| *h == "time_ms") {
        return Ok((i, 1e-3));
    }
    if let Some(i) = names.iter().position(|h| *h == "time_us") {
        return Ok((i, 1e-6));
    }
    if names
        .iter()
        .any(|h| matches!(h.to_ascii_lowercase().as_str(), "time" | "t" | "timestamp"))
    {
        bail!(
            "the time column has no unit: name it `time_s` (seconds) or `time_ms` (milliseconds)"
        );
    }
    bail!("no `time_s` column (header: {})", names.join(", "))
}

/// The channel columns of a CSV header (index, channel, scale to SI, see [`channel_column`]),
/// with an empty slot in `rec` for each and a note for every converted or ignored column.
/// Errors: two columns holding one channel.
fn channel_columns(
    names: &[&str],
    time_col: usize,
    rec: &mut Recording,
) -> Result<Vec<(usize, &'static str, f64)>> {
    let mut cols: Vec<(usize, &'static str, f64)> = Vec::new();
    for (i, h) in names.iter().enumerate() {
        if i == time_col {
            continue;
        }
        if let Some((name, scale)) = channel_column(h) {
            if cols.iter().any(|c| c.1 == name) {
                bail!("two columns hold `{name}` (`{h}` and another)");
            }
            if scale != 1.0 {
                rec.notes
                    .push(format!("column `{h}` converted to `{name}` (×{scale:e})"));
            }
            cols.push((i, name, scale));
            *rec.channel_slot(name).expect("known channel") = Some(Vec::new());
        } else {
            rec.notes.push(format!("ignored column `{h}`"));
        }
    }
    Ok(cols)
}

/// The channel a CSV column holds and its scale to SI: a channel's own name (1), or a position
/// channel in millimetres or micrometres (`tip_pos_mm`, `base_cmd_um`: 10⁻³, 10⁻⁶).
fn channel_column(header: &str) -> Option<(&'static str, f64)> {
    CHANNELS.iter().find_map(|&c| {
        if header == c {
            return Some((c, 1.0));
        }
        let stem = c.strip_suffix("_m")?;
        match header.strip_prefix(stem)? {
            "_mm" => Some((c, 1e-3)),
            "_um" => Some((c, 1e-6)),
            _ => None,
        }
    })
}

/// The note on a column separator other than the comma.
fn delimiter_note(delimiter: u8) -> Option<String> {
    match delimiter {
        b';' => Some("columns separated by `;` (decimal commas read as points)".into()),
        b'\t' => Some("columns separated by tabs".into()),
        _ => None,
    }
}

/// A cell as a number; with `;` as the separator, a decimal comma reads as a point.
fn parse_number(cell: &str, delimiter: u8) -> std::result::Result<f64, std::num::ParseFloatError> {
    if delimiter == b';' && cell.contains(',') {
        cell.replacen(',', ".", 1).parse()
    } else {
        cell.parse()
    }
}

/// The column separator of a recording CSV, read from its header (the first line that is not
/// a `#` comment): a comma where it has one, else `;` (spreadsheets set to a decimal comma
/// write that), else a tab, else a comma (a one-column file).
fn sniff_delimiter(path: &Path) -> Result<u8> {
    use std::io::BufRead;
    let file = std::fs::File::open(path)
        .with_context(|| format!("cannot open recording {}", path.display()))?;
    for line in std::io::BufReader::new(file).split(b'\n') {
        let line = line.with_context(|| format!("cannot read recording {}", path.display()))?;
        let line = line.trim_ascii();
        if line.is_empty() || line.starts_with(b"#") {
            continue;
        }
        return Ok([b',', b';', b'\t']
            .into_iter()
            .find(|d| line.contains(d))
            .unwrap_or(b','));
    }
    Ok(b',')
}

/// A csv error without Rust debug text.
fn csv_error(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => {
            format!("{len} fields where the header has {expected_len}")
        }
        csv::ErrorKind::Io(e) => e.to_string(),
        csv::ErrorKind::Utf8 { .. } => "not valid UTF-8 text".into(),
        _ => e.to_string(),
    }
}

/// Lowest frequency (Hz) the identification looks at; a recording whose Nyquist frequency
/// lies below it has nothing to identify.
pub const F_MIN_HZ: f64 = 0.2;

/// Refuses a time base that cannot be seconds: a median step so long that the Nyquist
/// frequency falls below [`F_MIN_HZ`] (a time column in milliseconds read as seconds; a
/// 100 Hz recording in ms has a "0.1 Hz" sample rate), with the hint to convert it.
pub fn check_time_unit(rec: &Recording) -> Result<()> {
    if rec.time_s.len() < 2 {
        return Ok(());
    }
    let rate = rec.sample_rate_hz();
    if 0.5 * rate < F_MIN_HZ {
        bail!(
            "the time steps are {} s (sample rate {} Hz, Nyquist below {F_MIN_HZ} Hz): is the time in milliseconds? \
             Name the CSV column `time_ms`, or divide the time by 1000",
            fmt_sig(1.0 / rate, 4),
            fmt_sig(rate, 3)
        );
    }
    Ok(())
}

/// `v` with `digits` significant digits, without exponent noise for ordinary magnitudes
/// (`45.00000000000096` → `45.00`).
pub fn fmt_sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-4..=7).contains(&mag) {
        return format!("{:.*e}", digits.saturating_sub(1), v);
    }
    let decimals = (digits as i32 - 1 - mag).max(0) as usize;
    format!("{v:.decimals$}")
}

/// A logging gap: `time_s[index] - time_s[index - 1]` is `length_s`, far longer than the
/// median step.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Gap {
    /// Index of the first sample after the gap.
    pub index: usize,
    /// Time of the last sample before the gap (s).
    pub start_s: f64,
    /// Length of the time step over the gap (s).
    pub length_s: f64,
}

/// The gaps of a time base: steps longer than `max_step_s`.
pub fn find_gaps(time_s: &[f64], max_step_s: f64) -> Vec<Gap> {
    time_s
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] - w[0] > max_step_s)
        .map(|(k, w)| Gap {
            index: k + 1,
            start_s: w[0],
            length_s: w[1] - w[0],
        })
        .collect()
}

/// Splits `rec` at `gaps` into the clean segments between them (every channel cut alike).
pub fn split_at_gaps(rec: &Recording, gaps: &[Gap]) -> Vec<Recording> {
    let mut bounds = vec![0];
    bounds.extend(gaps.iter().map(|g| g.index));
    bounds.push(rec.len());
    bounds
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| rec.slice(w[0]..w[1]))
        .collect()
}

impl Recording {
    /// The samples in `r`, every channel alike (notes kept).
    pub fn slice(&self, r: std::ops::Range<usize>) -> Recording {
        let cut = |c: &Option<Vec<f64>>| c.as_ref().map(|v| v[r.clone()].to_vec());
        Recording {
            time_s: self.time_s[r.clone()].to_vec(),
            base_cmd_m: cut(&self.base_cmd_m),
            base_pos_m: cut(&self.base_pos_m),
            tip_pos_m: cut(&self.tip_pos_m),
            force_n: cut(&self.force_n),
            notes: self.notes.clone(),
        }
    }

    /// The recording on a uniform grid at its median sample rate (linear interpolation of
    /// every channel; use on a gap-free segment whose steps only jitter).
    pub fn resampled_uniform(&self) -> Recording {
        let rate = self.sample_rate_hz();
        let re = |c: &Option<Vec<f64>>| {
            c.as_ref()
                .map(|v| resample_uniform(&self.time_s, v, rate).1)
        };
        let (t, _, _) = resample_uniform(&self.time_s, &self.time_s, rate);
        Recording {
            time_s: t,
            base_cmd_m: re(&self.base_cmd_m),
            base_pos_m: re(&self.base_pos_m),
            tip_pos_m: re(&self.tip_pos_m),
            force_n: re(&self.force_n),
            notes: self.notes.clone(),
        }
    }

    /// True when every step is within [`UNIFORM_TOLERANCE`] of the median.
    pub fn is_uniform(&self) -> bool {
        let dt = self.sample_interval_s();
        self.time_s
            .windows(2)
            .all(|w| ((w[1] - w[0]) - dt).abs() <= UNIFORM_TOLERANCE * dt)
    }
}

/// A linear-phase low-pass FIR: `2 half + 1` taps of the ideal low-pass with cut-off `fc_cycles`
/// (cycles per sample, < 0.5) times `window(i)` (i = 0..=2 half), scaled to unit DC gain.
pub fn windowed_sinc(half: usize, fc_cycles: f64, window: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut h: Vec<f64> = (0..=2 * half)
        .map(|i| {
            let k = i as f64 - half as f64;
            let sinc = if k == 0.0 {
                2.0 * fc_cycles
            } else {
                (2.0 * std::f64::consts::PI * fc_cycles * k).sin() / (std::f64::consts::PI * k)
            };
            sinc * window(i)
        })
        .collect();
    let s: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= s);
    h
}

/// Anti-aliased decimation by `q`: a Hamming-windowed sinc low-pass (cut-off 0.4 × the new
/// sample rate, 16 q + 1 taps, unit DC gain, zero phase) evaluated only at the kept samples,
/// so the work is N × 16 and the memory the output. `q` ≤ 1 returns a copy.
pub fn decimate_fir(x: &[f64], q: usize) -> Vec<f64> {
    if q <= 1 {
        return x.to_vec();
    }
    let half = 8 * q;
    let fc = 0.4 / q as f64; // cycles per input sample
    let h = windowed_sinc(half, fc, |i| {
        0.54 - 0.46 * (2.0 * std::f64::consts::PI * i as f64 / (2 * half) as f64).cos()
    });
    let n = x.len();
    (0..n)
        .step_by(q)
        .map(|c| {
            // Edges: the signal is held at its end values.
            h.iter()
                .enumerate()
                .map(|(i, hv)| {
                    let k = (c + i).saturating_sub(half).min(n - 1);
                    hv * x[k]
                })
                .sum()
        })
        .collect()
}

impl Recording {
    /// Every channel [decimated](decimate_fir) by `q` (uniform recordings), time base kept.
    pub fn decimated(&self, q: usize) -> Recording {
        let d = |c: &Option<Vec<f64>>| c.as_ref().map(|v| decimate_fir(v, q));
        Recording {
            time_s: self.time_s.iter().step_by(q.max(1)).copied().collect(),
            base_cmd_m: d(&self.base_cmd_m),
            base_pos_m: d(&self.base_pos_m),
            tip_pos_m: d(&self.tip_pos_m),
            force_n: d(&self.force_n),
            notes: self.notes.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_the_band_and_removes_aliases() {
        let rate = 1000.0;
        let tone = |f: f64| -> Vec<f64> {
            (0..20000)
                .map(|k| (2.0 * std::f64::consts::PI * f * k as f64 / rate).sin())
                .collect()
        };
        let rms = |v: &[f64]| {
            (v[200..v.len() - 200].iter().map(|x| x * x).sum::<f64>() / (v.len() - 400) as f64)
                .sqrt()
        };
        // q = 10: new rate 100 Hz, pass band to 40 Hz; 5 Hz kept, 170 Hz (would alias to 30 Hz) removed.
        let kept = decimate_fir(&tone(5.0), 10);
        assert_eq!(kept.len(), 2000);
        assert!(
            (rms(&kept) / std::f64::consts::FRAC_1_SQRT_2 - 1.0).abs() < 0.01,
            "{}",
            rms(&kept)
        );
        assert!(rms(&decimate_fir(&tone(170.0), 10)) < 0.01);
    }

    #[test]
    fn semicolons_with_decimal_commas_and_tabs_read_as_commas_do() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let comma = "# logger v2; 100 Hz\ntime_s,base_cmd_m,tip_pos_m\n0,0,0.001\n0.01,0.5,-0.25\n";
        let files = [
            ("comma.csv", comma.to_string()),
            (
                "semicolon.csv",
                "time_s;base_cmd_m;tip_pos_m\n0;0;0,001\n0,01;0,5;-0,25\n".into(),
            ),
            ("tab.csv", comma.replace(',', "\t")),
        ];
        let mut read = Vec::new();
        for (name, text) in files {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            read.push(Recording::read_csv(&p).unwrap());
        }
        assert!(read[0].notes.is_empty(), "{:?}", read[0].notes);
        for r in &read[1..] {
            assert_eq!(r.time_s, read[0].time_s);
            assert_eq!(r.base_cmd_m, read[0].base_cmd_m);
            assert_eq!(r.tip_pos_m, read[0].tip_pos_m);
            assert!(
                r.notes[0].starts_with("columns separated by"),
                "{:?}",
                r.notes
            );
        }
    }

    #[test]
    fn positions_in_millimetres_and_times_in_milliseconds_are_read_in_si_units() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let si = dir.join("si.csv");
        std::fs::write(
            &si,
            "time_s,base_cmd_m,tip_pos_m\n0,0,0.001\n0.01,0.5,-0.25\n",
        )
        .unwrap();
        let mm = dir.join("mm.csv");
        std::fs::write(
            &mm,
            "time_ms,base_cmd_mm,tip_pos_um\n0,0,1000\n10,500,-250000\n",
        )
        .unwrap();
        let (a, b) = (
            Recording::read_csv(&si).unwrap(),
            Recording::read_csv(&mm).unwrap(),
        );
        for (x, y) in [(&a.time_s, &b.time_s)]
            .into_iter()
            .chain([(
                a.base_cmd_m.as_ref().unwrap(),
                b.base_cmd_m.as_ref().unwrap(),
            )])
            .chain([(a.tip_pos_m.as_ref().unwrap(), b.tip_pos_m.as_ref().unwrap())])
        {
            for (u, v) in x.iter().zip(y) {
                assert!((u - v).abs() < 1e-12, "{u} vs {v}");
            }
        }
        assert_eq!(b.notes.len(), 3, "{:?}", b.notes);
        assert!(
            b.notes[2].contains("`tip_pos_um` converted to `tip_pos_m`"),
            "{:?}",
            b.notes
        );
        let twice = dir.join("twice.csv");
        std::fs::write(&twice, "time_s,tip_pos_m,tip_pos_mm\n0,0,0\n0.01,0.001,1\n").unwrap();
        let err = Recording::read_csv(&twice).unwrap_err().to_string();
        assert!(err.contains("two columns hold `tip_pos_m`"), "{err}");
    }

    #[test]
    fn gaps_split_and_numbers_print_plainly() {
        let t = vec![0.0, 0.01, 0.02, 0.6, 0.61, 0.62, 0.63];
        let g = find_gaps(&t, 0.05);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].index, 3);
        let rec = Recording {
            time_s: t.clone(),
            tip_pos_m: Some(t.clone()),
            ..Default::default()
        };
        let s = split_at_gaps(&rec, &g);
        assert_eq!((s[0].len(), s[1].len()), (3, 4));
        assert_eq!(fmt_sig(45.00000000000096, 4), "45.00");
        assert_eq!(fmt_sig(0.0074, 2), "0.0074");
    }
}

/// `rec` at `rate_hz` by keeping every `round(rate / rate_hz)`-th sample of every channel
/// (no anti-alias filter: for simulator output that is already band-limited, e.g. the 1 kHz
/// simulation of a rig sampled at 100 Hz). A factor below 1 keeps every sample; notes are
/// dropped.
pub fn decimate(rec: &Recording, rate_hz: f64) -> Recording {
    let f = ((rec.sample_rate_hz() / rate_hz).round() as usize).max(1);
    let pick = |v: &Option<Vec<f64>>| v.as_ref().map(|v| v.iter().step_by(f).copied().collect());
    Recording {
        time_s: rec.time_s.iter().step_by(f).copied().collect(),
        base_cmd_m: pick(&rec.base_cmd_m),
        base_pos_m: pick(&rec.base_pos_m),
        tip_pos_m: pick(&rec.tip_pos_m),
        force_n: pick(&rec.force_n),
        notes: vec![],
    }
}
