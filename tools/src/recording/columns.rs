//! How a file's columns become the project's channels: the user's `--columns` map and the
//! reading options.
//!
//! `--columns` is a comma-separated list of `channel=file_column[:scale]`, e.g.
//! `time_s=t:0.001,base_pos_m=theta:0.45,tip_pos_m=defl:0.001`: each of the project's channels
//! (`time_s` and [`super::CHANNELS`]) is read from the named column of the file, its value
//! multiplied by `scale` (default 1) to give SI units (s, m, N, m/s²). Columns the map does not
//! name are ignored (with a note). Without a `time_s` entry the file's own time column is used
//! (`time_s`, `time_ms`, `time_us`).
//!
//! Errors name the problem: an unknown channel (the valid names listed), a channel given twice,
//! a scale that is not a finite non-zero number, an entry without `=`, and (when the file is
//! read, [`ColumnMap::resolve`]) a column the file does not have (the file's columns listed).

use super::CHANNELS;
use anyhow::{bail, Result};

/// One entry of `--columns`: the project's channel, the file's column and the scale to SI.
#[derive(Clone, Debug, PartialEq)]
pub struct ColumnEntry {
    /// `time_s`, one of [`CHANNELS`], or [`TIP_DEFLECTION`].
    pub channel: &'static str,
    /// The file's column name (header field), as written.
    pub column: String,
    /// Multiplies the file's value to give the channel in SI units.
    pub scale: f64,
}

/// The user's column map (`--columns`), parsed ([`ColumnMap::parse`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColumnMap {
    /// The entries in the order given.
    pub entries: Vec<ColumnEntry>,
}

/// Which axis of a three-axis accelerometer file to read (`--axis`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// `accel_x`.
    X,
    /// `accel_y`.
    Y,
    /// `accel_z`.
    Z,
}

impl Axis {
    /// `x`, `y` or `z` (either case). Errors: anything else.
    pub fn from_name(s: &str) -> Result<Axis> {
        match s.trim().to_ascii_lowercase().as_str() {
            "x" => Ok(Axis::X),
            "y" => Ok(Axis::Y),
            "z" => Ok(Axis::Z),
            _ => bail!("--axis `{s}`: want x, y or z"),
        }
    }

    /// 0, 1, 2 for x, y, z.
    pub fn index(self) -> usize {
        self as usize
    }

    /// `x`, `y`, `z`.
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }
}

/// How a recording file is read: the column map and the accelerometer axis, both optional
/// (the defaults read the project's own column names, and a Klipper raw accelerometer file's
/// axis with the most energy).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// `--columns`: the file's columns for the project's channels.
    pub columns: Option<ColumnMap>,
    /// `--axis`: the axis of a Klipper raw accelerometer file.
    pub axis: Option<Axis>,
}

/// The `--columns` name of a tip position measured *from the base* (m): a crane's sway angle
/// times its rope length, a flexible link's tip deflection in the hub's frame. It is read as
/// `tip_pos_m` = base + this (the base channel, `base_pos_m` or else `base_cmd_m`, is needed).
pub const TIP_DEFLECTION: &str = "tip_defl_m";

/// Every channel name `--columns` accepts.
pub fn channel_names() -> Vec<&'static str> {
    let mut v = vec!["time_s"];
    v.extend(CHANNELS);
    v.push(TIP_DEFLECTION);
    v
}

impl ColumnMap {
    /// Parses `channel=file_column[:scale],…` (see the module header). The scale is the text
    /// after the last `:`; a column name holding `:` cannot be given a scale.
    ///
    /// Errors: an empty list or entry, an entry without `=`, an unknown channel, a channel
    /// given twice, an empty column name, a scale that is not a finite non-zero number.
    pub fn parse(spec: &str) -> Result<ColumnMap> {
        let mut entries: Vec<ColumnEntry> = Vec::new();
        if spec.trim().is_empty() {
            bail!("--columns is empty: want `channel=file_column[:scale],…`");
        }
        for item in spec.split(',') {
            let item = item.trim();
            let Some((ch, rest)) = item.split_once('=') else {
                bail!("--columns entry `{item}`: want `channel=file_column[:scale]`");
            };
            let ch = ch.trim();
            let Some(channel) = channel_names().into_iter().find(|c| *c == ch) else {
                bail!(
                    "--columns entry `{item}`: unknown channel `{ch}` (channels: {})",
                    channel_names().join(", ")
                );
            };
            let (column, scale) = match rest.rsplit_once(':') {
                Some((col, s)) => {
                    let scale: f64 = s.trim().parse().map_err(|_| {
                        anyhow::anyhow!(
                            "--columns entry `{item}`: bad scale `{s}` (want a number, e.g. `{col}:0.001`)"
                        )
                    })?;
                    if !scale.is_finite() || scale == 0.0 {
                        bail!("--columns entry `{item}`: bad scale `{s}` (want a finite non-zero number)");
                    }
                    (col.trim(), scale)
                }
                None => (rest.trim(), 1.0),
            };
            if column.is_empty() {
                bail!("--columns entry `{item}`: no file column after `=`");
            }
            if entries.iter().any(|e| e.channel == channel) {
                bail!("--columns: channel `{channel}` given twice");
            }
            let tips = ["tip_pos_m", TIP_DEFLECTION];
            if tips.contains(&channel) && entries.iter().any(|e| tips.contains(&e.channel)) {
                bail!("--columns: give the tip as tip_pos_m (lab frame) or tip_defl_m (from the base), not both");
            }
            entries.push(ColumnEntry {
                channel,
                column: column.to_string(),
                scale,
            });
        }
        Ok(ColumnMap { entries })
    }

    /// True when the tip is given from the base ([`TIP_DEFLECTION`]).
    pub fn tip_from_base(&self) -> bool {
        self.entries.iter().any(|e| e.channel == TIP_DEFLECTION)
    }

    /// The entry for `time_s`, if any.
    pub fn time(&self) -> Option<&ColumnEntry> {
        self.entries.iter().find(|e| e.channel == "time_s")
    }

    /// The header index of every entry (in the map's order), for a file whose header is
    /// `names`.
    ///
    /// Errors: a column the file does not have (the file's columns listed).
    pub fn resolve(&self, names: &[&str]) -> Result<Vec<usize>> {
        self.entries
            .iter()
            .map(|e| {
                names.iter().position(|n| *n == e.column).ok_or_else(|| {
                    anyhow::anyhow!(
                        "--columns: the file has no column `{}` (for {}); its columns: {}",
                        e.column,
                        e.channel,
                        names.join(", ")
                    )
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_column_map_parses_and_names_what_is_wrong() {
        let m = ColumnMap::parse("time_s=t:0.001, base_pos_m=theta:0.45,tip_pos_m=defl").unwrap();
        assert_eq!(m.entries.len(), 3);
        assert_eq!(m.entries[0].scale, 0.001);
        assert_eq!(m.entries[1].column, "theta");
        assert_eq!(m.entries[2].scale, 1.0);
        assert_eq!(m.resolve(&["defl", "t", "theta"]).unwrap(), vec![1, 2, 0]);
        let e = m.resolve(&["t", "angle"]).unwrap_err().to_string();
        assert!(
            e.contains("no column `theta`") && e.contains("t, angle"),
            "{e}"
        );
        for (spec, want) in [
            ("tip=x", "unknown channel `tip`"),
            ("tip_pos_m=x:mm", "bad scale `mm`"),
            ("tip_pos_m=x:0", "bad scale `0`"),
            ("tip_pos_m=x,tip_pos_m=y", "given twice"),
            ("tip_pos_m", "want `channel=file_column[:scale]`"),
            ("tip_pos_m=:2", "no file column"),
            ("tip_pos_m=a,tip_defl_m=b", "not both"),
        ] {
            let e = ColumnMap::parse(spec).unwrap_err().to_string();
            assert!(e.contains(want), "{spec}: {e}");
        }
    }
}
