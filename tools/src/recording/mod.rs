//! The recording format shared by every tool of the project, and what loggers write.
//!
//! A [`Recording`] is a time base and optional channels, all one length, in SI units:
//! - `time_s` (required): time in seconds of each sample, strictly increasing (uniform after
//!   [`regular`]; the gapped readers keep logging gaps and jitter);
//! - `base_cmd_m`: commanded base position (m);
//! - `base_pos_m`: measured base position (m);
//! - `tip_pos_m`: absolute tip position along the base axis, lab frame (m);
//! - `force_n`: motor force (N);
//! - `tip_acc_m_s2`: tip acceleration along the base axis, lab frame (m/s²), e.g. one axis of
//!   a printer's accelerometer.
//!
//! Files read (docs/recording-formats.md has each with an example):
//! - the project's CSV: a header row with the channel names above, comma-separated (`;` with
//!   decimal commas, or tabs, are read too, with a note). Unknown columns are ignored with a
//!   note; positions in `_mm`/`_um`, `tip_acc_mm_s2` and times in `time_ms`/`time_us` are
//!   converted to SI with a note. A blank or `nan` cell is a missing value ([`regular`] fills
//!   short runs; [`multirate`] reads a channel logged on every k-th row at its own rate);
//! - any CSV whose columns `--columns` maps to the channels, each with its scale to SI
//!   ([`columns`]);
//! - Klipper's raw accelerometer CSV (`#time,accel_x,accel_y,accel_z`, mm/s²): one axis as
//!   `tip_acc_m_s2` ([`klipper`]);
//! - row-wise logs, whose rows update only some columns (a ROS bag exported row-wise): each
//!   channel forward-filled ([`rowwise`]);
//! - NumPy `.npy` arrays of shape (2, N) = [time; signal] (the real data in
//!   `shared/data/real/`) via [`Recording::read_npy`], without assuming uniform time.
//!
//! Reading is fast ([`csvread`]: `beamtool bench-read FILE`). What each channel's samples
//! really are is estimated from its values ([`hold`]): its quantisation step
//! ([`Recording::quantum`]) and, for a slow sensor held in a fast log (a sample-and-hold
//! staircase), its real update rate ([`Recording::update_rate_hz`]); both are noted on reading.

pub mod columns;
pub mod csvread;
pub mod glitch;
pub mod hold;
pub mod klipper;
pub mod multirate;
pub mod orient;
pub mod psd;
pub mod rawpsd;
mod read;
pub mod regular;
pub mod rowwise;
pub mod zero;

use anyhow::{anyhow, bail, Context, Result};
pub use columns::{Axis, ColumnMap, ReadOptions};
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
    /// Tip acceleration along the base axis, lab frame (m/s²): an accelerometer on the tip
    /// (Klipper's raw accelerometer CSV gives one axis of it, converted from mm/s²).
    pub tip_acc_m_s2: Option<Vec<f64>>,
    /// Notes made while reading (ignored columns, etc.), for the user.
    pub notes: Vec<String>,
}

/// The channel names in file order.
pub const CHANNELS: [&str; 5] = [
    "base_cmd_m",
    "base_pos_m",
    "tip_pos_m",
    "force_n",
    "tip_acc_m_s2",
];

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
            "tip_acc_m_s2" => self.tip_acc_m_s2.as_deref(),
            _ => None,
        }
    }

    /// A recording on the time base `time_s` whose every present channel is `f(channel)`
    /// (notes kept): slicing, resampling and decimation go through it, so that every channel
    /// of [`CHANNELS`] is treated alike.
    pub fn map_channels(&self, time_s: Vec<f64>, f: impl Fn(&[f64]) -> Vec<f64>) -> Recording {
        let mut out = Recording {
            time_s,
            notes: self.notes.clone(),
            ..Default::default()
        };
        for name in CHANNELS {
            if let Some(c) = self.channel(name) {
                *out.channel_slot(name).expect("known channel") = Some(f(c));
            }
        }
        out
    }

    pub(crate) fn channel_slot(&mut self, name: &str) -> Option<&mut Option<Vec<f64>>> {
        match name {
            "base_cmd_m" => Some(&mut self.base_cmd_m),
            "base_pos_m" => Some(&mut self.base_pos_m),
            "tip_pos_m" => Some(&mut self.tip_pos_m),
            "force_n" => Some(&mut self.force_n),
            "tip_acc_m_s2" => Some(&mut self.tip_acc_m_s2),
            _ => None,
        }
    }

    /// The quantisation step of channel `name` ([`hold::quantum`]): the step its values move
    /// in (an encoder's count, 1 mm, 0.001 rad), in the channel's unit; `None` when the channel
    /// is absent or its values are not on a grid.
    pub fn quantum(&self, name: &str) -> Option<f64> {
        hold::quantum(self.channel(name)?)
    }

    /// The staircase of channel `name` ([`hold::staircase`]), when it is a slow sensor's
    /// sample-and-hold in a faster log.
    pub fn staircase(&self, name: &str) -> Option<hold::Staircase> {
        let x = self.channel(name)?;
        hold::staircase(&self.time_s, x, hold::quantum(x))
    }

    /// The real update rate (Hz) of channel `name` when it is a sample-and-hold staircase (a
    /// 22 Hz sensor in a 100 Hz log: ~22), from the times its value changes
    /// ([`hold::staircase`]); `None` when the channel is absent or changes at the log's rate.
    pub fn update_rate_hz(&self, name: &str) -> Option<f64> {
        self.staircase(name).map(|s| s.update_rate_hz)
    }

    /// Sampling interval (s), the median of the time steps.
    pub fn sample_interval_s(&self) -> f64 {
        let mut d: Vec<f64> = self.time_s.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return f64::NAN;
        }
        // the middle element of the sorted steps, found without sorting them all
        let mid = d.len() / 2;
        *d.select_nth_unstable_by(mid, f64::total_cmp).1
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
        self.map_channels(self.time_s[r.clone()].to_vec(), |v| v[r.clone()].to_vec())
    }

    /// The recording on a uniform grid at its median sample rate (linear interpolation of
    /// every channel; use on a gap-free segment whose steps only jitter).
    pub fn resampled_uniform(&self) -> Recording {
        let rate = self.sample_rate_hz();
        let (t, _, _) = resample_uniform(&self.time_s, &self.time_s, rate);
        self.map_channels(t, |v| resample_uniform(&self.time_s, v, rate).1)
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
        let t = self.time_s.iter().step_by(q.max(1)).copied().collect();
        self.map_channels(t, |v| decimate_fir(v, q))
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
    let t = rec.time_s.iter().step_by(f).copied().collect();
    let mut out = rec.map_channels(t, |v| v.iter().step_by(f).copied().collect());
    out.notes.clear();
    out
}
