//! The cells of a recording CSV as numbers, fast: the header found ([`layout`]), then the
//! columns wanted read row by row ([`read_columns`]).
//!
//! The header is the first line that is not a `#` comment, except when that line is already
//! data (its first cell is a number): then the last `#` line before it is the header when it
//! has as many fields as the data rows and none of them is a number. That is how Klipper's raw
//! accelerometer CSV writes it (`#time,accel_x,accel_y,accel_z`, after optional `##` status
//! lines); every other `#` line is a comment. The separator is read from the header: a comma
//! where it has one, else `;` (decimal commas then read as points), else a tab.
//!
//! Speed: the `csv` crate's [`csv::ByteRecord`] (one reused buffer, no per-row allocation),
//! each wanted cell trimmed and parsed from its bytes by `fast-float2` (Eisel–Lemire, exact
//! to the last bit like the standard library's parser), straight into one `Vec<f64>` per column
//! reserved from the file's size and its first rows' length: memory is the columns wanted,
//! 8 bytes a value, and nothing per row. `beamtool bench-read FILE` measures it.

use anyhow::{anyhow, bail, Context, Result};
use std::io::BufRead;
use std::path::Path;

/// Where a recording CSV's header is and how its cells are separated.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// The column separator (`,`, `;` or tab).
    pub delimiter: u8,
    /// The header's fields, trimmed (a commented header without its `#`).
    pub names: Vec<String>,
    /// The header was a `#` line (Klipper's raw accelerometer CSV).
    pub commented_header: bool,
    /// Mean length of the first data rows (bytes, with the line end); 0 when there are none.
    pub row_bytes: f64,
    /// File size (bytes).
    pub file_bytes: u64,
}

/// Data rows sampled for [`Layout::row_bytes`].
const ROWS_SAMPLED: usize = 1000;

/// The separator of one header line: a comma where it has one, else `;`, else a tab, else a
/// comma (a one-column file).
fn separator_of(line: &[u8]) -> u8 {
    [b',', b';', b'\t']
        .into_iter()
        .find(|d| line.contains(d))
        .unwrap_or(b',')
}

/// The fields of one line, trimmed.
fn fields(line: &[u8], delimiter: u8) -> Vec<String> {
    line.split(|b| *b == delimiter)
        .map(|f| String::from_utf8_lossy(f.trim_ascii()).into_owned())
        .collect()
}

/// True when `cell` reads as a number (with `;` as separator, a decimal comma too).
fn is_number(cell: &str, delimiter: u8) -> bool {
    parse_cell(cell.as_bytes(), delimiter == b';')
        .is_some_and(|v| !v.is_nan() || cell.eq_ignore_ascii_case("nan"))
}

/// Finds the header of the CSV at `path` (see the module header).
///
/// Errors: unreadable file, no line at all, data without any header line.
pub fn layout(path: &Path) -> Result<Layout> {
    let file = std::fs::File::open(path)
        .with_context(|| format!("cannot open recording {}", path.display()))?;
    let file_bytes = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut lines = std::io::BufReader::new(file).split(b'\n');
    let mut last_comment: Option<Vec<u8>> = None;
    let mut first: Option<Vec<u8>> = None;
    for line in lines.by_ref() {
        let line = line.with_context(|| format!("cannot read recording {}", path.display()))?;
        let t = line.trim_ascii();
        if t.is_empty() {
            continue;
        }
        if t.starts_with(b"#") {
            last_comment = Some(t.to_vec());
            continue;
        }
        first = Some(t.to_vec());
        break;
    }
    let Some(first) = first else {
        bail!("{}: no header row (the file has no data)", path.display());
    };
    let d_first = separator_of(&first);
    let first_fields = fields(&first, d_first);
    let first_is_data = is_number(&first_fields[0], d_first);
    let (delimiter, names, commented_header) = if !first_is_data {
        (d_first, first_fields, false)
    } else {
        let header = last_comment
            .as_deref()
            .map(|c| c.trim_ascii_start().trim_ascii_start_matches_hash())
            .filter(|h| !h.is_empty());
        let Some(h) = header else {
            bail!(
                "{}: no header row: the first line `{}` is data (write the column names on the first line, e.g. `time_s,tip_pos_m`)",
                path.display(),
                String::from_utf8_lossy(&first)
            );
        };
        let d = separator_of(h);
        let names = fields(h, d);
        let data_fields = fields(&first, d);
        if names.len() != data_fields.len() || names.iter().any(|n| is_number(n, d)) {
            bail!(
                "{}: no header row: the first line `{}` is data and the comment before it (`{}`) has not the names of its {} columns",
                path.display(),
                String::from_utf8_lossy(&first),
                String::from_utf8_lossy(h),
                data_fields.len()
            );
        }
        (d, names, true)
    };
    // the length of the first data rows, for reserving the columns
    let (mut bytes, mut rows) = (0usize, 0usize);
    if commented_header {
        bytes += first.len() + 1;
        rows += 1;
    }
    for line in lines.take(ROWS_SAMPLED) {
        let Ok(line) = line else { break };
        if line.first() != Some(&b'#') {
            bytes += line.len() + 1;
            rows += 1;
        }
    }
    Ok(Layout {
        delimiter,
        names,
        commented_header,
        row_bytes: if rows == 0 {
            0.0
        } else {
            bytes as f64 / rows as f64
        },
        file_bytes,
    })
}

/// `#`s stripped from the start of a comment line.
trait TrimHash {
    fn trim_ascii_start_matches_hash(&self) -> &[u8];
}

impl TrimHash for [u8] {
    fn trim_ascii_start_matches_hash(&self) -> &[u8] {
        let k = self.iter().position(|b| *b != b'#').unwrap_or(self.len());
        self[k..].trim_ascii()
    }
}

/// One cell's number: blank is NaN (a missing value, for the caller to refuse where it
/// must), `nan`/`inf` as written; `None` when it is not a number. With `decimal_comma`, one
/// `,` reads as a point.
#[inline]
pub fn parse_cell(cell: &[u8], decimal_comma: bool) -> Option<f64> {
    let c = cell.trim_ascii();
    if c.is_empty() {
        return Some(f64::NAN);
    }
    if decimal_comma && c.contains(&b',') {
        let s = String::from_utf8_lossy(c).replacen(',', ".", 1);
        return s.parse().ok();
    }
    match fast_float2::parse::<f64, _>(c) {
        Ok(v) => Some(v),
        // `+nan`, `infinity`, … : the standard library's reading of the rare words
        Err(_) => std::str::from_utf8(c).ok()?.parse().ok(),
    }
}

/// A column to read: its index in the header, its name (for errors) and the scale applied.
#[derive(Clone, Debug)]
pub struct Wanted<'a> {
    /// Index of the field in each row.
    pub index: usize,
    /// The header's name of the column.
    pub name: &'a str,
    /// Multiplies each value.
    pub scale: f64,
    /// A blank cell is an error (the time column), not a missing value.
    pub required: bool,
}

/// Reads the `wanted` columns of the CSV at `path` (laid out as `layout`), scaled, one
/// `Vec<f64>` each in the order of `wanted`; a blank cell is NaN unless the column is
/// `required`. `progress(rows)` is called every 2²⁰ rows.
///
/// Errors (file and data row named): a row without a column that is read (fields beyond the
/// header are ignored), a cell that is not a number, a blank required cell, text that is not
/// UTF-8.
pub fn read_columns(
    path: &Path,
    layout: &Layout,
    wanted: &[Wanted<'_>],
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<Vec<f64>>> {
    // rows may carry fields beyond the header (LabVIEW writes trailing columns it does not
    // name); a row without a column that is read is an error below
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .delimiter(layout.delimiter)
        .from_path(path)
        .with_context(|| format!("cannot open recording {}", path.display()))?;
    let estimate = if layout.row_bytes > 0.0 {
        (layout.file_bytes as f64 / layout.row_bytes * 1.02) as usize + 16
    } else {
        16
    };
    let mut cols: Vec<Vec<f64>> = wanted
        .iter()
        .map(|_| Vec::with_capacity(estimate))
        .collect();
    let mut record = csv::ByteRecord::new();
    let decimal_comma = layout.delimiter == b';';
    let mut row = 0usize;
    let mut skip_header = !layout.commented_header;
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
        if skip_header {
            skip_header = false;
            continue;
        }
        if record.len() == 1 && record[0].trim_ascii().is_empty() {
            continue; // a blank line
        }
        row += 1;
        for (col, w) in cols.iter_mut().zip(wanted) {
            let b = record.get(w.index).ok_or_else(|| {
                anyhow!(
                    "{}: data row {row}: missing column {}",
                    path.display(),
                    w.name
                )
            })?;
            match parse_cell(b, decimal_comma) {
                Some(v) if !(w.required && v.is_nan() && b.trim_ascii().is_empty()) => {
                    col.push(v * w.scale)
                }
                _ => bail!(
                    "{}: data row {row}, column {}: `{}` is not a number",
                    path.display(),
                    w.name,
                    String::from_utf8_lossy(b.trim_ascii())
                ),
            }
        }
        if row % (1 << 20) == 0 {
            progress(row);
        }
    }
    for c in &mut cols {
        c.shrink_to_fit();
    }
    Ok(cols)
}

/// A csv error without Rust debug text.
pub fn csv_error(e: &csv::Error) -> String {
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

/// The note on a column separator other than the comma.
pub fn delimiter_note(delimiter: u8) -> Option<String> {
    match delimiter {
        b';' => Some("columns separated by `;` (decimal commas read as points)".into()),
        b'\t' => Some("columns separated by tabs".into()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_parse_like_the_standard_library() {
        for s in [
            "0",
            "-1.5",
            "1e-3",
            " 2.25 ",
            "+3",
            "1.7976931348623157e308",
            "4.9e-324",
        ] {
            let want: f64 = s.trim().parse().unwrap();
            assert_eq!(parse_cell(s.as_bytes(), false), Some(want), "{s}");
        }
        assert!(parse_cell(b"", false).unwrap().is_nan());
        assert!(parse_cell(b"nan", false).unwrap().is_nan());
        assert_eq!(parse_cell(b"inf", false), Some(f64::INFINITY));
        assert_eq!(parse_cell(b"0,25", true), Some(0.25));
        assert_eq!(parse_cell(b"abc", false), None);
        assert_eq!(parse_cell(b"1.5x", false), None);
    }

    #[test]
    fn a_commented_header_before_data_is_the_header_and_other_comments_are_not() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("k.csv");
        std::fs::write(
            &p,
            "##rate=3200\n#time,accel_x,accel_y,accel_z\n1.0,2,3,4\n",
        )
        .unwrap();
        let l = layout(&p).unwrap();
        assert!(l.commented_header);
        assert_eq!(l.names, ["time", "accel_x", "accel_y", "accel_z"]);
        std::fs::write(&p, "# logger v2; 100 Hz\ntime_s,tip_pos_m\n0,1\n").unwrap();
        let l = layout(&p).unwrap();
        assert!(!l.commented_header);
        assert_eq!(l.names, ["time_s", "tip_pos_m"]);
        std::fs::write(&p, "# two, fields\n0,1,2\n").unwrap();
        let e = layout(&p).unwrap_err().to_string();
        assert!(e.contains("no header row"), "{e}");
    }
}
