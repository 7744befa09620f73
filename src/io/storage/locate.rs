//! Locating problems found after reading: a stage that works on a table's values (splines,
//! dynamics, muscle paths) reports a value it cannot use at the file, line and column it
//! came from, through a [`TableLocator`] taken from the table.

use super::{Table, TableLines};
use crate::Error;

/// The file a table was read from, with the times and lines of its rows: enough to name
/// the line of a row, of the row nearest a time, or of the labels, long after the values
/// themselves were filtered, splined or converted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TableLocator {
    /// The file (or, for a table built in memory, whatever names it).
    pub source: String,
    time: Vec<f64>,
    lines: Option<TableLines>,
}

impl Table {
    /// A [`TableLocator`] for this table, read from `source`.
    pub fn locator(&self, source: &str) -> TableLocator {
        TableLocator {
            source: source.to_string(),
            time: self.time.clone(),
            lines: self.lines.clone(),
        }
    }
}

impl TableLocator {
    /// An error about `element` (e.g. `column "knee_angle"`) as a whole: at the line of the
    /// column labels.
    pub fn labels(&self, element: impl Into<String>, message: impl Into<String>) -> Error {
        match &self.lines {
            Some(l) => Error::Model {
                file: self.source.clone(),
                line: l.labels,
                element: element.into(),
                message: message.into(),
            },
            None => Error::Motion {
                file: self.source.clone(),
                location: element.into(),
                message: message.into(),
            },
        }
    }

    /// An error about `element` in row `row` (an index of [`Table::time`]): at the row's line;
    /// for a table built in memory, naming the row's time.
    pub fn row(&self, row: usize, element: impl Into<String>, message: impl Into<String>) -> Error {
        let line = self.lines.as_ref().and_then(|l| l.rows.get(row).copied());
        match line {
            Some(line) => Error::Model {
                file: self.source.clone(),
                line,
                element: element.into(),
                message: message.into(),
            },
            None => Error::Motion {
                file: self.source.clone(),
                location: match self.time.get(row) {
                    Some(t) => format!("{}, time {t} s", element.into()),
                    None => element.into(),
                },
                message: message.into(),
            },
        }
    }

    /// An error about `element` at time `t`, which may lie between rows (filtered or
    /// resampled values) or beyond them (the filter's padding): at the line of the row
    /// nearest `t`, the message saying so when `t` is not that row's time.
    pub fn at_time(&self, t: f64, element: impl Into<String>, message: impl Into<String>) -> Error {
        let message = message.into();
        let Some(row) = self.nearest_row(t) else {
            return self.labels(element, format!("at time {t} s: {message}"));
        };
        let row_time = self.time[row];
        if t == row_time {
            return self.row(row, element, format!("at time {t} s: {message}"));
        }
        let (first, last) = (self.time[0], self.time[self.time.len() - 1]);
        let place = if t < first || t > last {
            format!(
                "at time {t} s, beyond the recorded {first} s to {last} s (the low-pass \
                 filter's padding; the nearest row is at {row_time} s)"
            )
        } else {
            format!("at time {t} s (between rows; the nearest row is at {row_time} s)")
        };
        self.row(row, element, format!("{place}: {message}"))
    }

    /// The row whose time is nearest `t`; None for an empty table or a NaN time.
    fn nearest_row(&self, t: f64) -> Option<usize> {
        if self.time.is_empty() || t.is_nan() {
            return None;
        }
        let after = self.time.partition_point(|&x| x < t);
        Some(match after {
            0 => 0,
            a if a == self.time.len() => a - 1,
            a if t - self.time[a - 1] <= self.time[a] - t => a - 1,
            a => a,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read() -> Table {
        Table::parse(
            "name\nversion=1\nendheader\ntime\tq\n0\t1\n\n0.1\t2\n0.2\t3\n",
            "m.sto",
        )
        .unwrap()
    }

    #[test]
    fn rows_labels_and_times_are_located_at_their_lines() {
        let t = read();
        assert_eq!(
            t.lines,
            Some(TableLines {
                labels: 4,
                rows: vec![5, 7, 8]
            })
        );
        let at = t.locator("m.sto");
        let e = at.row(1, "column \"q\"", "bad").to_string();
        assert_eq!(e, "m.sto:7: column \"q\": bad");
        assert_eq!(
            at.labels("column \"q\"", "missing").to_string(),
            "m.sto:4: column \"q\": missing"
        );
        let e = at.at_time(0.2, "column \"q\"", "inf").to_string();
        assert_eq!(e, "m.sto:8: column \"q\": at time 0.2 s: inf");
        let e = at.at_time(0.16, "column \"q\"", "inf").to_string();
        assert!(
            e.starts_with("m.sto:8: column \"q\": at time 0.16 s (between"),
            "{e}"
        );
        let e = at.at_time(-0.3, "column \"q\"", "inf").to_string();
        assert!(e.starts_with("m.sto:5:") && e.contains("padding"), "{e}");
    }

    #[test]
    fn a_table_built_in_memory_names_times() {
        let t = Table::new("x", vec!["q".into()], vec![0.0, 0.5], vec![1.0, 2.0]).unwrap();
        let e = t
            .locator("clip 3")
            .row(1, "column \"q\"", "bad")
            .to_string();
        assert_eq!(e, "clip 3: column \"q\", time 0.5 s: bad");
    }
}
