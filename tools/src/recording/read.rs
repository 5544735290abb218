//! Reading a recording file into a [`Recording`]: which columns hold which channel (the
//! project's names, `--columns`, Klipper's raw accelerometer header), the cells read fast
//! ([`super::csvread`]), a row-wise log forward-filled ([`super::rowwise`]), staircases and
//! quanta noted ([`super::hold`]), and the time base mended ([`super::regular`]) as each entry
//! point says.

use super::columns::ReadOptions;
use super::csvread::{self, delimiter_note, Layout, Wanted};
use super::{check_time_unit, hold, klipper, regular, rowwise, Recording, CHANNELS};
use anyhow::{anyhow, bail, Context, Result};
use std::path::Path;

/// What kind of file the cells came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    /// A recording CSV (the project's columns, or `--columns`).
    Plain,
    /// Klipper's raw accelerometer CSV.
    Klipper,
}

impl Recording {
    /// Reads a recording CSV onto a uniform, complete time base: duplicated rows, dropped
    /// frames, blank or `nan` cells and jittering time stamps are mended as
    /// [`regular::regularise`] says, with a note each; the result passes
    /// [`Recording::validate`]. A row-wise log is forward-filled first ([`rowwise`]).
    ///
    /// Errors: unreadable file, no time column, a cell that is not a number (row and
    /// column named), a ragged row, and what [`regular::regularise`] refuses (time going
    /// backwards, a long gap, a varying sample rate), each with the file's name.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Self> {
        Self::read_csv_with(path, &ReadOptions::default())
    }

    /// [`Recording::read_csv`] with the columns of `opts` (`--columns`, `--axis`).
    ///
    /// Errors: as [`Recording::read_csv`], and a `--columns` column the file does not have.
    pub fn read_csv_with(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Self> {
        Self::read_csv_leaving_gaps_with(path, &[], opts).map(|(rec, _)| rec)
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
        Self::read_csv_leaving_gaps_with(path, gappy, &ReadOptions::default())
    }

    /// [`Recording::read_csv_leaving_gaps`] with the columns of `opts`.
    pub fn read_csv_leaving_gaps_with(
        path: impl AsRef<Path>,
        gappy: &[&str],
        opts: &ReadOptions,
    ) -> Result<(Self, regular::Gaps)> {
        let path = path.as_ref();
        let (rec, _) = Self::read_csv_columns(path, opts, &mut |_| {})?;
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
    /// (see [`super::split_at_gaps`]). The time column is `time_s` (seconds), `time_ms` or
    /// `time_us` (converted with a note). `progress(rows)` is called every 2²⁰ rows.
    ///
    /// Errors: unreadable file, no time column (a `time`/`t` column is refused with the
    /// hint to name its unit), a cell that is not a number, NaN/inf, non-increasing time.
    pub fn read_csv_gapped(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        let (rec, _) = Self::read_csv_columns(path, &ReadOptions::default(), progress)?;
        rec.validate_gapped()
            .with_context(|| format!("{}: invalid recording", path.display()))?;
        Ok(rec)
    }

    /// Reads any recording by its extension ([`Recording::read_any_with`], default columns).
    pub fn read_any(path: &Path, progress: &mut dyn FnMut(usize)) -> Result<Self> {
        Self::read_any_with(path, &ReadOptions::default(), progress)
    }

    /// Reads any recording by its extension: `.npy` ([`Recording::read_npy`], the signal
    /// row as `tip_pos_m` in the unit it was recorded in, with a note) or CSV (any other
    /// extension: the project's columns, `opts.columns`, or Klipper's raw accelerometer CSV,
    /// row-wise logs forward-filled). Gaps and jitter are kept (see
    /// [`super::split_at_gaps`]), except that a CSV with blank or `nan` cells, and a Klipper
    /// file, are read through [`regular::regularise`] where it allows; a time base in
    /// milliseconds is refused with that hint when nothing could be identified below its
    /// Nyquist frequency (see [`check_time_unit`]). LabVIEW `.lvm` files are spectra here:
    /// read them with `ident::magspec::read_lvm`.
    ///
    /// Errors: as [`Recording::read_csv_gapped`]; `--columns`/`--axis` on a `.npy`.
    pub fn read_any_with(
        path: &Path,
        opts: &ReadOptions,
        progress: &mut dyn FnMut(usize),
    ) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let rec = if ext == "npy" {
            if opts != &ReadOptions::default() {
                bail!(
                    "{}: --columns and --axis apply to CSV files; a `.npy` holds [time; signal]",
                    path.display()
                );
            }
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
            Self::read_csv_any(path, opts, progress)?
        };
        check_time_unit(&rec).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        Ok(rec)
    }

    /// [`Recording::read_csv_gapped`] with `opts`, except that a file with blank or `nan`
    /// cells, or a Klipper file, is first [regularised](regular::regularise) (short runs
    /// filled, jitter mended, with notes); where that is refused (a long logging gap, which
    /// `identify` splits at), the gapped reading stands (its error, if it has one).
    fn read_csv_any(
        path: &Path,
        opts: &ReadOptions,
        progress: &mut dyn FnMut(usize),
    ) -> Result<Self> {
        let (mut rec, source) = Self::read_csv_columns(path, opts, progress)?;
        let blanks = CHANNELS
            .iter()
            .filter_map(|n| rec.channel(n))
            .any(|c| c.iter().any(|v| v.is_nan()));
        let finite_time = rec.time_s.iter().all(|t| t.is_finite());
        if (blanks || source == Source::Klipper) && finite_time {
            match regular::regularise(rec.clone()) {
                Ok(mut r) => {
                    if source == Source::Klipper {
                        r.notes.push(format!(
                            "the accelerometer's time base mended onto a uniform {} Hz grid",
                            super::fmt_sig(r.sample_rate_hz(), 5)
                        ));
                    }
                    return Ok(r);
                }
                Err(e) if source == Source::Klipper => rec.notes.push(format!(
                    "the accelerometer's time base kept as recorded ({} Hz median; not mended onto one grid: {e}); `identify` splits it at its gaps",
                    super::fmt_sig(rec.sample_rate_hz(), 5)
                )),
                Err(_) => {}
            }
        }
        rec.validate_gapped()
            .with_context(|| format!("{}: invalid recording", path.display()))?;
        Ok(rec)
    }

    /// The channels of a recording CSV as numbers (a blank or `nan` cell of a channel is NaN, a
    /// missing value), a row-wise log forward-filled, with notes on the columns read, the
    /// staircases and the coarse quanta; the time base unchecked.
    fn read_csv_columns(
        path: &Path,
        opts: &ReadOptions,
        progress: &mut dyn FnMut(usize),
    ) -> Result<(Self, Source)> {
        let at = |e: anyhow::Error| anyhow!("{}: {e}", path.display());
        let layout = csvread::layout(path)?;
        let names: Vec<&str> = layout.names.iter().map(String::as_str).collect();
        let is_klipper = opts.columns.is_none() && klipper::is_klipper_header(&names);
        if opts.axis.is_some() && !is_klipper {
            return Err(at(anyhow!(match opts.columns {
                Some(_) => "--axis picks the axis of a Klipper raw accelerometer file; with --columns, name the axis's column instead (e.g. `tip_acc_m_s2=accel_x:0.001`)".to_string(),
                None => format!("--axis applies to Klipper's raw accelerometer CSV (header `#time,accel_x,accel_y,accel_z`); this file's columns: {}", names.join(", ")),
            })));
        }
        let mut rec = Recording::default();
        rec.notes.extend(delimiter_note(layout.delimiter));
        let plan = plan(&layout, &names, opts, is_klipper, &mut rec.notes).map_err(at)?;
        let wanted: Vec<Wanted<'_>> = plan
            .iter()
            .enumerate()
            .map(|(k, &(index, _, scale))| Wanted {
                index,
                name: names[index],
                scale,
                required: k == 0,
            })
            .collect();
        let mut cols = csvread::read_columns(path, &layout, &wanted, progress)?.into_iter();
        rec.time_s = cols.next().expect("the time column");
        if is_klipper {
            let xyz: Vec<Vec<f64>> = cols.collect();
            let (axis, note) = klipper::choose_axis([&xyz[0], &xyz[1], &xyz[2]], opts.axis);
            rec.notes.push(note);
            rec.tip_acc_m_s2 = xyz.into_iter().nth(axis.index());
        } else {
            for (c, &(_, name, _)) in cols.zip(&plan[1..]) {
                *rec.channel_slot(name).expect("known channel") = Some(c);
            }
        }
        if rec.len() >= 2 && rowwise::is_rowwise(&rec) {
            rec = rowwise::forward_fill(rec).map_err(at)?;
        }
        for name in CHANNELS {
            if let Some(c) = rec.channel(name) {
                let notes = hold::notes(name, &rec.time_s, c);
                rec.notes.extend(notes);
            }
        }
        if opts.columns.as_ref().is_some_and(|m| m.tip_from_base()) {
            tip_from_base(&mut rec).map_err(at)?;
        }
        let source = if is_klipper {
            Source::Klipper
        } else {
            Source::Plain
        };
        Ok((rec, source))
    }
}

/// `tip_pos_m` read from a `tip_defl_m` column (the tip measured from the base) made the lab
/// frame's: the base (`base_pos_m`, else `base_cmd_m`) added sample by sample, with a note.
///
/// Errors: no base channel.
fn tip_from_base(rec: &mut Recording) -> Result<()> {
    let (name, base) = match (&rec.base_pos_m, &rec.base_cmd_m) {
        (Some(b), _) => ("base_pos_m", b.clone()),
        (None, Some(b)) => ("base_cmd_m", b.clone()),
        (None, None) => {
            bail!("--columns: tip_defl_m is the tip measured from the base; map base_pos_m or base_cmd_m too")
        }
    };
    if let Some(tip) = rec.tip_pos_m.as_mut() {
        tip.iter_mut().zip(&base).for_each(|(t, b)| *t += b);
    }
    rec.notes.push(format!(
        "--columns: tip_pos_m = {name} + tip_defl_m (the tip measured from the base, read in the lab frame)"
    ));
    Ok(())
}

/// The columns to read: the time column first, then each channel's (header index, channel,
/// scale to SI); for a Klipper file, time then `accel_x`, `accel_y`, `accel_z` (to m/s²),
/// channel names unused. Notes on conversions and ignored columns go to `notes`.
fn plan(
    layout: &Layout,
    names: &[&str],
    opts: &ReadOptions,
    is_klipper: bool,
    notes: &mut Vec<String>,
) -> Result<Vec<(usize, &'static str, f64)>> {
    if is_klipper {
        let s = klipper::MM_S2_TO_M_S2;
        return Ok(vec![
            (0, "time_s", 1.0),
            (1, "tip_acc_m_s2", s),
            (2, "tip_acc_m_s2", s),
            (3, "tip_acc_m_s2", s),
        ]);
    }
    if let Some(map) = &opts.columns {
        let idx = map.resolve(names)?;
        let mut out = Vec::new();
        match map.time() {
            Some(e) => {
                let i = idx[map
                    .entries
                    .iter()
                    .position(|x| x.channel == "time_s")
                    .unwrap()];
                out.push((i, "time_s", e.scale));
            }
            None => {
                let (i, s) = time_column(names)?;
                out.push((i, "time_s", s));
            }
        }
        for (e, &i) in map.entries.iter().zip(&idx) {
            if e.channel == super::columns::TIP_DEFLECTION {
                // read into tip_pos_m, the base added once the rows are filled
                out.push((i, "tip_pos_m", e.scale));
            } else if e.channel != "time_s" {
                out.push((i, e.channel, e.scale));
            }
        }
        let read: Vec<String> = map
            .entries
            .iter()
            .map(|e| {
                let scale = match e.scale.abs() {
                    s if (1e-3..1e4).contains(&s) => format!("{}", e.scale),
                    _ => format!("{:e}", e.scale),
                };
                format!("{} = `{}` × {scale}", e.channel, e.column)
            })
            .collect();
        notes.push(format!("--columns: {}", read.join(", ")));
        let unmapped: Vec<&str> = names
            .iter()
            .enumerate()
            .filter(|(i, _)| !out.iter().any(|o| o.0 == *i))
            .map(|(_, n)| *n)
            .collect();
        if !unmapped.is_empty() {
            notes.push(format!(
                "--columns: {} unmapped columns ignored ({})",
                unmapped.len(),
                unmapped.join(", ")
            ));
        }
        return Ok(out);
    }
    let _ = layout;
    let (time_col, time_scale) = time_column(names)?;
    if time_scale != 1.0 {
        notes.push(format!(
            "time column `{}` converted to seconds (×{time_scale:e})",
            names[time_col]
        ));
    }
    let mut out = vec![(time_col, "time_s", time_scale)];
    out.extend(channel_columns(names, time_col, notes)?);
    Ok(out)
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
    if let Some(h) = names
        .iter()
        .find(|h| matches!(h.to_ascii_lowercase().as_str(), "time" | "t" | "timestamp"))
    {
        bail!(
            "the time column `{h}` has no unit: name it `time_s` (seconds) or `time_ms` (milliseconds), or map it with --columns time_s={h}:SCALE (e.g. `:0.001` for ms)"
        );
    }
    bail!(
        "no `time_s` column (header: {}); map the file's columns with --columns, e.g. `--columns time_s=t:0.001,tip_pos_m=x`",
        names.join(", ")
    )
}

/// The channel columns of a CSV header (index, channel, scale to SI, see [`channel_column`]),
/// with a note for every converted or ignored column.
/// Errors: two columns holding one channel.
fn channel_columns(
    names: &[&str],
    time_col: usize,
    notes: &mut Vec<String>,
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
                notes.push(format!("column `{h}` converted to `{name}` (×{scale:e})"));
            }
            cols.push((i, name, scale));
        } else {
            notes.push(format!("ignored column `{h}`"));
        }
    }
    Ok(cols)
}

/// The channel a CSV column holds and its scale to SI: a channel's own name (1), or a position
/// channel in millimetres or micrometres (`tip_pos_mm`, `base_cmd_um`: 10⁻³, 10⁻⁶), or the
/// tip acceleration in mm/s² (`tip_acc_mm_s2`: 10⁻³).
fn channel_column(header: &str) -> Option<(&'static str, f64)> {
    CHANNELS.iter().find_map(|&c| {
        if header == c {
            return Some((c, 1.0));
        }
        if c == "tip_acc_m_s2" {
            return (header == "tip_acc_mm_s2").then_some((c, 1e-3));
        }
        let stem = c.strip_suffix("_m")?;
        match header.strip_prefix(stem)? {
            "_mm" => Some((c, 1e-3)),
            "_um" => Some((c, 1e-6)),
            _ => None,
        }
    })
}
