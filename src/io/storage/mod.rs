//! OpenSim storage files (`.sto`, `.mot`): a header, a row of column labels starting with
//! `time`, then one row of numbers per time sample.
//!
//! # Header dialects read
//!
//! Everything up to a line `endheader` is header. Three dialects occur in practice, and
//! mixtures of them (OpenSim 2–3 wrote version-1 lines followed by a SIMM block):
//!
//! * **version 1** (OpenSim's `Storage` class): a name line, `version=1`, `nRows=`,
//!   `nColumns=` (time included), `inDegrees=yes|no`, free description text;
//! * **OpenSim 4** (`TimeSeriesTable` / `STOFileAdapter`): optional name line, any
//!   `key=value` metadata, `DataType=double`, `version=` (1 to 3), `OpenSimVersion=4.x`;
//! * **SIMM motion** (old `.mot`): `name …`, `datacolumns N`, `datarows M`, `range a b`,
//!   `otherdata 1`, with no `version` line.
//!
//! The structural keys (`version`, `nRows`/`nr`/`datarows`, `nColumns`/`nc`/`datacolumns`,
//! `range`, `inDegrees`, `DataType`, `OpenSimVersion`, the name) are interpreted and checked.
//! A declared column count must match the label row (a mismatch is an error). A declared
//! row count that disagrees with the rows the file holds is a warning (OpenSim reads the
//! rows; so does this reader, and [`Table::warnings`] names the header line and both
//! counts). Other `key=value` lines are kept in [`Table::metadata`] and the remaining
//! free text in [`Table::description`], both in file order. Only `DataType=double` is
//! supported.
//!
//! Column labels are split on tabs when the label row contains one (a label may then contain
//! spaces, which OpenSim 4's reader allows), otherwise on whitespace; data rows are split on any whitespace. Blank
//! lines are skipped. OpenSim reads a SIMM-dialect `.mot` without `inDegrees` as degrees;
//! this reader reports what the file says, `in_degrees: None`, and leaves that choice to the
//! caller.
//!
//! # Errors
//!
//! Bad content is an [`Error::Model`] whose `file` is the `source` passed to
//! [`Table::parse`] (the path for [`Table::read`]) and whose `line` is the 1-based line of
//! the file where the problem is: for a data value, the line of its row. `element` names
//! the column — `column "knee_angle_r"`, `column "time"`, or `column 25 (beyond the last
//! label)` for a surplus value — or `header "nRows"` for a header line, or `table`. Rows
//! are named by their line only (never by a row index counted from 0 beside it), and
//! [`Table::lines`] keeps the line of the labels and of every row for the checks of later
//! stages. Values must be finite numbers, every row must have one value per
//! label, time must not decrease, labels must be unique and the table must have rows.
//!
//! # Repeated times
//!
//! OpenSim's CMC, RRA and forward tools sometimes record the state at one time twice, with
//! the time equal or differing in the last digits (a repeat 6.6e-14 s apart at the end of a
//! 100 Hz motion). Both are the same sample, and keeping both makes a spline through the
//! column ring over the last frames. A row whose time is within [`REPEAT_TOLERANCE`] × the
//! median sampling interval (the median of the positive steps between rows) of the
//! previous kept row's is a repeat: by default ([`RepeatedTime::KeepFirst`]) it is left
//! out, with a warning naming its line and time; [`ReadOptions::repeated_time`] can keep
//! the last of the repeats instead, or make them an error. A time earlier than the previous
//! row's by more than the tolerance is always an error.
//!
//! I/O failures are [`Error::Io`] with the path. Nothing is ever repaired silently: every
//! departure from the header or from strictly increasing time is in [`Table::warnings`].
//!
//! # Writing
//!
//! [`Table::write`] produces an OpenSim-4-style header that both of OpenSim's readers
//! accept: `version=1` with `nRows` and `nColumns` (required by the `Storage` class, which
//! the GUI uses to load motions, for version-1 files) plus `DataType=double` and
//! `OpenSimVersion` (what `STOFileAdapter` expects), tab-separated columns, and numbers in
//! the shortest form that reads back to the same `f64`. (A label containing a space is
//! written as it is; `STOFileAdapter` reads it, but `Storage` splits labels at spaces.) The
//! file is written beside its
//! destination under a temporary name and renamed into place, so an interrupted write leaves
//! the old file or none, never half a file.

use crate::io::FileWarning;
use crate::{Error, Result};

mod locate;
mod read;
#[cfg(test)]
mod tests;
mod write;

pub use locate::TableLocator;

/// The header dialect a table was read in (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialect {
    /// A `version=` line without `OpenSimVersion`: OpenSim's `Storage` format.
    Version1,
    /// `OpenSimVersion=` present: OpenSim 4's `STOFileAdapter` format. Also what
    /// [`Table::write`] produces, and the dialect of tables built with [`Table::new`].
    OpenSim4,
    /// No `version` line: SIMM-era motion files (`datacolumns`, `datarows`, `range`).
    Unversioned,
}

/// A time series read from or written to an OpenSim storage file.
///
/// Values are stored row-major: the value of column `c` (an index into `labels`) at row `r`
/// is `values[r * labels.len() + c]`. [`Table::new`] and [`Table::read`] guarantee the
/// invariants listed in the module documentation; [`Table::write`] checks them again, since
/// the fields are public.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The name line of the header (`Coordinates`, `arm26_states`, …); may be empty.
    pub name: String,
    pub dialect: Dialect,
    /// `inDegrees=yes|no` from the header, `None` when the file does not say.
    pub in_degrees: Option<bool>,
    /// Header `key=value` lines other than the structural keys, in file order.
    pub metadata: Vec<(String, String)>,
    /// Free-text header lines, in file order.
    pub description: Vec<String>,
    /// Column labels after `time`.
    pub labels: Vec<String>,
    /// Sample times (s), strictly increasing.
    pub time: Vec<f64>,
    /// Row-major values, `time.len() * labels.len()` of them.
    pub values: Vec<f64>,
    /// File lines of rows left out because their time repeated a neighbour's (module
    /// documentation, "Repeated times").
    pub dropped_repeated_rows: Vec<u32>,
    /// What the reader accepted but the caller should tell the user: a row count in the
    /// header that disagrees with the data, repeated times dropped. Empty for tables built
    /// in memory.
    pub warnings: Vec<FileWarning>,
    /// Where the labels and rows are in the file read; `None` for a table built in memory.
    pub lines: Option<TableLines>,
}

/// The 1-based file lines of a table read from a file, so that a problem found later (a
/// value the dynamics cannot use, a missing column) can name the line it comes from.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TableLines {
    /// The line of the column labels.
    pub labels: u32,
    /// The line of every row of [`Table::time`], in order (rows left out are not here).
    pub rows: Vec<u32>,
}

/// Two rows whose times differ by at most this fraction of the median sampling interval are
/// one sample recorded twice (module documentation, "Repeated times"). A millionth of a
/// step is far below any real sampling jitter and far above the rounding of printed times.
pub const REPEAT_TOLERANCE: f64 = 1e-6;

/// What to do with a row whose time repeats the previous row's (within
/// [`REPEAT_TOLERANCE`] of the sampling interval).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RepeatedTime {
    /// An error naming the row.
    Error,
    /// Keep the first of the rows with that time (the default); list the others' lines in
    /// [`Table::dropped_repeated_rows`], with a warning for each.
    #[default]
    KeepFirst,
    /// Keep the last of the rows with that time; list the others' lines in
    /// [`Table::dropped_repeated_rows`], with a warning for each.
    KeepLast,
}

/// Options for [`Table::parse_with`] / [`Table::read_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// What to do with a repeated time (module documentation, "Repeated times"): keep the
    /// first row by default.
    pub repeated_time: RepeatedTime,
}

/// Header keys this module interprets; they are not kept in `metadata`.
const STRUCTURAL_KEYS: [&str; 12] = [
    "name",
    "version",
    "nRows",
    "nr",
    "datarows",
    "nColumns",
    "nc",
    "datacolumns",
    "range",
    "inDegrees",
    "DataType",
    "OpenSimVersion",
];

/// SIMM header keys written as `key value` rather than `key=value`.
const SIMM_KEYS: [&str; 9] = [
    "name",
    "datacolumns",
    "datarows",
    "range",
    "otherdata",
    "units",
    "wrap",
    "enforce_loops",
    "enforce_constraints",
];

/// What `OpenSimVersion` the writer declares: the 4.x series whose readers it targets.
const WRITTEN_OPENSIM_VERSION: &str = "4.5";

/// How a header line is understood.
#[derive(Debug, PartialEq)]
enum HeaderLine<'a> {
    Blank,
    End,
    KeyValue(&'a str, &'a str),
    Name(&'a str),
    Description(&'a str),
}

/// Classifies one header line; `first` is true for the first non-blank line, which is the
/// table's name unless it is a key/value pair.
fn classify_header_line(line: &str, first: bool) -> HeaderLine<'_> {
    let line = line.trim();
    if line.is_empty() {
        return HeaderLine::Blank;
    }
    if line == "endheader" {
        return HeaderLine::End;
    }
    // `endheader` followed by more: OpenSim's readers disagree on where such a header ends;
    // classified as a key so that reading rejects it.
    if let Some(rest) = line.strip_prefix("endheader")
        && rest.starts_with([' ', '\t', '='])
    {
        return HeaderLine::KeyValue("endheader", rest.trim_start_matches([' ', '\t', '=']));
    }
    if let Some((key, value)) = line.split_once('=') {
        let key = key.trim();
        if !key.is_empty() && !key.contains(char::is_whitespace) {
            return HeaderLine::KeyValue(key, value.trim());
        }
    }
    // `key value`: SIMM's form, which OpenSim's `Storage` also accepts for its own keys.
    let (word, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
    if SIMM_KEYS.contains(&word) || STRUCTURAL_KEYS.contains(&word) {
        return HeaderLine::KeyValue(word, rest.trim());
    }
    if first {
        HeaderLine::Name(line)
    } else {
        HeaderLine::Description(line)
    }
}

/// True for a line made of digits, dots, minus signs and blanks that starts with a digit:
/// a row of numbers, which OpenSim's `STOFileAdapter` refuses in a header (it means a
/// missing `endheader`).
fn looks_like_data_row(text: &str) -> bool {
    text.starts_with(|c: char| c.is_ascii_digit())
        && text
            .chars()
            .all(|c| c.is_ascii_digit() || ".\t -".contains(c))
}

impl Table {
    /// A table built in memory. `values` is row-major (`time.len() * labels.len()`); the
    /// same checks as for a file apply, reported as [`Error::InvalidArgument`].
    pub fn new(
        name: impl Into<String>,
        labels: Vec<String>,
        time: Vec<f64>,
        values: Vec<f64>,
    ) -> Result<Table> {
        let table = Table {
            name: name.into(),
            dialect: Dialect::OpenSim4,
            in_degrees: None,
            metadata: Vec::new(),
            description: Vec::new(),
            labels,
            time,
            values,
            dropped_repeated_rows: Vec::new(),
            warnings: Vec::new(),
            lines: None,
        };
        table.validate()?;
        Ok(table)
    }

    /// The file line of the column labels, when the table was read from a file.
    pub fn label_line(&self) -> Option<u32> {
        self.lines.as_ref().map(|l| l.labels)
    }

    /// The file line of row `r`, when the table was read from a file.
    pub fn row_line(&self, r: usize) -> Option<u32> {
        self.lines.as_ref().and_then(|l| l.rows.get(r).copied())
    }

    /// Number of rows (time samples).
    pub fn n_rows(&self) -> usize {
        self.time.len()
    }

    /// Number of columns after `time`.
    pub fn n_columns(&self) -> usize {
        self.labels.len()
    }

    /// The values of row `row` (columns after time), if it exists.
    pub fn row(&self, row: usize) -> Option<&[f64]> {
        if row >= self.time.len() {
            return None;
        }
        let w = self.labels.len();
        self.values.get(row * w..(row + 1) * w)
    }

    /// The value at `row` of column `column` (an index into `labels`).
    pub fn value(&self, row: usize, column: usize) -> Option<f64> {
        self.row(row)?.get(column).copied()
    }

    /// The index (into `labels`) of the column with this label.
    pub fn column_index(&self, label: &str) -> Option<usize> {
        self.labels.iter().position(|l| l == label)
    }

    /// The values of the column with this label, one per row.
    pub fn column(&self, label: &str) -> Option<Vec<f64>> {
        self.column_at(self.column_index(label)?)
    }

    /// The values of column `column` (an index into `labels`), one per row.
    pub fn column_at(&self, column: usize) -> Option<Vec<f64>> {
        let w = self.labels.len();
        (column < w).then(|| {
            self.values
                .iter()
                .skip(column)
                .step_by(w)
                .copied()
                .collect()
        })
    }

    /// Column `column` at time `t`, linearly interpolated between the neighbouring rows and
    /// held constant beyond the first and last rows.
    pub fn interpolate(&self, column: usize, t: f64) -> Result<f64> {
        let w = self.labels.len();
        if column >= w {
            return Err(Error::invalid(
                "column",
                format!("index {column}, but the table has {w} columns after time"),
            ));
        }
        if !t.is_finite() {
            return Err(Error::invalid("t", format!("{t} is not finite")));
        }
        let n = self.time.len();
        if n == 0 || self.values.len() != n * w {
            return Err(Error::invalid(
                "table",
                "has no rows, or values do not match its rows and labels",
            ));
        }
        let at = |r: usize| self.values[r * w + column];
        // Index of the first row with time > t.
        let upper = self.time.partition_point(|&ti| ti <= t);
        Ok(if upper == 0 {
            at(0)
        } else if upper == n {
            at(n - 1)
        } else {
            let (t0, t1) = (self.time[upper - 1], self.time[upper]);
            let s = (t - t0) / (t1 - t0);
            // v(t) = v0 + s (v1 − v0), s = (t − t0)/(t1 − t0)
            at(upper - 1) + s * (at(upper) - at(upper - 1))
        })
    }
}
