//! Reading: the header dialects, the label row and the data rows, with the checks of the
//! module documentation.

use std::collections::HashMap;
use std::path::Path;

use super::{
    Dialect, HeaderLine, REPEAT_TOLERANCE, ReadOptions, RepeatedTime, Table, TableLines,
    classify_header_line, looks_like_data_row,
};
use crate::io::FileWarning;
use crate::{Error, Result};

fn line_u32(index: usize) -> u32 {
    u32::try_from(index + 1).unwrap_or(u32::MAX)
}

fn content_error(source: &str, line: u32, element: String, message: String) -> Error {
    Error::Model {
        file: source.to_string(),
        line,
        element,
        message,
    }
}

/// A count declared in the header, with the line that declared it.
struct Declared {
    key: String,
    value: usize,
    line: u32,
}

impl Table {
    /// Reads a `.sto` or `.mot` file.
    pub fn read(path: &Path) -> Result<Table> {
        Table::read_with(path, &ReadOptions::default())
    }

    /// Reads a `.sto` or `.mot` file with options.
    pub fn read_with(path: &Path, options: &ReadOptions) -> Result<Table> {
        let text = crate::text::read_text(path)?;
        Table::parse_with(&text, &path.display().to_string(), options)
    }

    /// Parses the text of a storage file; `source` names it in error messages.
    pub fn parse(text: &str, source: &str) -> Result<Table> {
        Table::parse_with(text, source, &ReadOptions::default())
    }

    /// Parses the text of a storage file with options.
    pub fn parse_with(text: &str, source: &str, options: &ReadOptions) -> Result<Table> {
        let mut lines = text.lines().enumerate();
        let mut table = Table {
            name: String::new(),
            dialect: Dialect::Unversioned,
            in_degrees: None,
            metadata: Vec::new(),
            description: Vec::new(),
            labels: Vec::new(),
            time: Vec::new(),
            values: Vec::new(),
            dropped_repeated_rows: Vec::new(),
            warnings: Vec::new(),
            lines: None,
        };
        let header = read_header(&mut lines, &mut table, source)?;
        let label_line = read_labels(&mut lines, &mut table, source, &header)?;
        let mut row_lines = read_rows(lines, &mut table, source)?;
        if table.time.is_empty() {
            return Err(content_error(
                source,
                label_line,
                "table".into(),
                "no data rows after the column labels".into(),
            ));
        }
        let rows_in_file = table.time.len();
        drop_repeated_times(&mut table, &row_lines, source, options)?;
        let dropped: std::collections::HashSet<u32> =
            table.dropped_repeated_rows.iter().copied().collect();
        row_lines.retain(|l| !dropped.contains(l));
        table.lines = Some(TableLines {
            labels: label_line,
            rows: row_lines,
        });
        if let Some(d) = &header.declared_rows
            && d.value != rows_in_file
        {
            table.warnings.push(FileWarning {
                file: source.to_string(),
                line: d.line,
                element: format!("header \"{}\"", d.key),
                message: format!(
                    "declares {} rows, but the file holds {rows_in_file}: all {rows_in_file} \
                     are read",
                    d.value
                ),
            });
        }
        Ok(table)
    }
}

/// The lines of a file with their 0-based indices.
type NumberedLines<'t> = std::iter::Enumerate<std::str::Lines<'t>>;

fn header_error(source: &str, line: u32, key: &str, message: String) -> Error {
    content_error(source, line, format!("header \"{key}\""), message)
}

/// What the header lines have said so far beyond the table's own fields.
#[derive(Default)]
struct Header {
    /// The `endheader` line (0 until it is read).
    end_line: u32,
    has_version: bool,
    has_opensim_version: bool,
    declared_rows: Option<Declared>,
    declared_columns: Option<Declared>,
}

/// The header, up to `endheader`, into `table` (name, description, metadata, `inDegrees`,
/// dialect), with its structural keys checked; returns what the later stages need.
fn read_header(lines: &mut NumberedLines, table: &mut Table, source: &str) -> Result<Header> {
    let mut header = Header::default();
    let mut end_line = None;
    let mut first = true;
    let mut last_line = 0;
    // A header line that looks like the column labels, for the missing-`endheader` error.
    let mut labels_like_line = None;
    for (index, raw) in lines.by_ref() {
        let line = line_u32(index);
        last_line = line;
        let class = classify_header_line(raw, first);
        if class != HeaderLine::Blank {
            first = false;
        }
        match class {
            HeaderLine::Blank => {}
            HeaderLine::End => {
                end_line = Some(line);
                break;
            }
            HeaderLine::Name(text) | HeaderLine::Description(text) if looks_like_data_row(text) => {
                return Err(content_error(
                    source,
                    line,
                    "header".into(),
                    match labels_like_line {
                        Some(l) => format!(
                            "a row of numbers before the `endheader` line (line {l} looks \
                             like the column labels; the header must end with `endheader` \
                             before them)"
                        ),
                        None => "a row of numbers before the `endheader` line".into(),
                    },
                ));
            }
            HeaderLine::Name(name) => table.name = name.to_string(),
            HeaderLine::Description(text) => {
                if labels_like_line.is_none() && text.split_whitespace().next() == Some("time") {
                    labels_like_line = Some(line);
                }
                table.description.push(text.to_string())
            }
            HeaderLine::KeyValue(key, value) => {
                header_key_value(table, &mut header, source, line, key, value)?
            }
        }
    }
    let Some(end_line) = end_line else {
        return Err(content_error(
            source,
            last_line.max(1),
            "header".into(),
            match (last_line, labels_like_line) {
                (0, _) => "the file is empty".into(),
                (_, Some(l)) => format!(
                    "no `endheader` line (line {l} looks like the column labels; the \
                     header must end with `endheader` before them)"
                ),
                _ => "no `endheader` line".into(),
            },
        ));
    };
    header.end_line = end_line;
    table.dialect = match (header.has_opensim_version, header.has_version) {
        (true, _) => Dialect::OpenSim4,
        (false, true) => Dialect::Version1,
        (false, false) => Dialect::Unversioned,
    };
    Ok(header)
}

/// One `key=value` header line: the structural keys checked (`version`, `DataType`, `range`,
/// `inDegrees`, the row and column counts, which must agree when declared twice), the others
/// kept as metadata.
fn header_key_value(
    table: &mut Table,
    header: &mut Header,
    source: &str,
    line: u32,
    key: &str,
    value: &str,
) -> Result<()> {
    match key {
        "name" => table.name = value.to_string(),
        "version" => {
            value.parse::<i64>().map_err(|_| {
                header_error(source, line, key, format!("`{value}` is not an integer"))
            })?;
            header.has_version = true;
        }
        "OpenSimVersion" => header.has_opensim_version = true,
        "DataType" if value != "double" => {
            return Err(header_error(
                source,
                line,
                key,
                format!("only DataType=double is supported, not `{value}`"),
            ));
        }
        "DataType" => {}
        "range" => {
            let numbers: Vec<Option<f64>> = value
                .split_whitespace()
                .map(|v| v.parse::<f64>().ok().filter(|x| x.is_finite()))
                .collect();
            if numbers.len() != 2 || numbers.contains(&None) {
                return Err(header_error(
                    source,
                    line,
                    key,
                    format!("expected two numbers (first and last time), found `{value}`"),
                ));
            }
        }
        "inDegrees" => {
            table.in_degrees = match value.to_ascii_lowercase().as_str() {
                "yes" | "y" => Some(true),
                "no" | "n" => Some(false),
                _ => {
                    return Err(header_error(
                        source,
                        line,
                        key,
                        format!("expected `yes` or `no`, found `{value}`"),
                    ));
                }
            }
        }
        "nRows" | "nr" | "datarows" | "nColumns" | "nc" | "datacolumns" => {
            let count: usize = value.parse().map_err(|_| {
                header_error(source, line, key, format!("`{value}` is not a count"))
            })?;
            let slot = if matches!(key, "nRows" | "nr" | "datarows") {
                &mut header.declared_rows
            } else {
                &mut header.declared_columns
            };
            if let Some(previous) = slot
                && previous.value != count
            {
                return Err(header_error(
                    source,
                    line,
                    key,
                    format!(
                        "declares {count}, but `{}` on line {} declares {}",
                        previous.key, previous.line, previous.value
                    ),
                ));
            }
            *slot = Some(Declared {
                key: key.to_string(),
                value: count,
                line,
            });
        }
        "endheader" => {
            return Err(header_error(
                source,
                line,
                key,
                "`endheader` with a value: the header's end is ambiguous".into(),
            ));
        }
        _ => table.metadata.push((key.to_string(), value.to_string())),
    }
    Ok(())
}

/// The column labels (the first non-blank line after `endheader`): `time` first, unique,
/// as many as a declared column count; into `table.labels` (after `time`). Returns their line.
fn read_labels(
    lines: &mut NumberedLines,
    table: &mut Table,
    source: &str,
    header: &Header,
) -> Result<u32> {
    let Some((label_index, label_row)) = lines.by_ref().find(|(_, l)| !l.trim().is_empty()) else {
        return Err(content_error(
            source,
            header.end_line,
            "table".into(),
            "no column labels after `endheader`".into(),
        ));
    };
    let label_line = line_u32(label_index);
    let mut labels: Vec<&str> = if label_row.contains('\t') {
        label_row
            .split('\t')
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect()
    } else {
        label_row.split_whitespace().collect()
    };
    if labels[0] != "time" {
        return Err(content_error(
            source,
            label_line,
            format!("column \"{}\"", labels[0]),
            "the first column must be `time`".into(),
        ));
    }
    labels.remove(0);
    let mut seen: HashMap<&str, usize> = HashMap::with_capacity(labels.len() + 1);
    seen.insert("time", 0);
    for (c, &label) in labels.iter().enumerate() {
        if let Some(previous) = seen.insert(label, c + 1) {
            return Err(content_error(
                source,
                label_line,
                format!("column \"{label}\""),
                format!(
                    "duplicate column label (columns {} and {}, time being column 1)",
                    previous + 1,
                    c + 2
                ),
            ));
        }
    }
    if let Some(d) = &header.declared_columns
        && d.value != labels.len() + 1
    {
        return Err(header_error(
            source,
            d.line,
            &d.key,
            format!(
                "declares {} columns, but the label row (line {label_line}) has {} \
                 (time included)",
                d.value,
                labels.len() + 1
            ),
        ));
    }
    table.labels = labels.into_iter().map(String::from).collect();
    Ok(label_line)
}

/// Every data row (blank lines skipped) into `table.time` and `table.values`: finite
/// numbers, time and one per label. Returns the file line of each row; repeated times are
/// judged later, against the median step of them all.
fn read_rows(lines: NumberedLines, table: &mut Table, source: &str) -> Result<Vec<u32>> {
    let width = table.labels.len();
    let labels = &table.labels;
    let column_name = |c: usize| -> String {
        match c {
            0 => "column \"time\"".to_string(),
            c if c <= width => format!("column \"{}\"", labels[c - 1]),
            c => format!("column {} (beyond the last label)", c + 1),
        }
    };
    let mut row_lines: Vec<u32> = Vec::new();
    for (index, raw) in lines {
        let raw = raw.trim();
        if raw.is_empty() {
            continue;
        }
        let line = line_u32(index);
        let mut count = 0;
        for (c, token) in raw.split_whitespace().enumerate() {
            count += 1;
            if c > width {
                continue;
            }
            let value = token
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    content_error(
                        source,
                        line,
                        column_name(c),
                        format!("`{token}` is not a finite number"),
                    )
                })?;
            if c == 0 {
                table.time.push(value);
            } else {
                table.values.push(value);
            }
        }
        if count != width + 1 {
            let c = count.min(width + 1);
            return Err(content_error(
                source,
                line,
                column_name(c),
                format!(
                    "the row has {count} values, expected {} (time and {width} labels)",
                    width + 1
                ),
            ));
        }
        row_lines.push(line);
    }
    Ok(row_lines)
}

/// Leaves out the rows whose time repeats the previous kept row's within
/// [`REPEAT_TOLERANCE`] × the median positive step (module documentation), recording their
/// lines and a warning for each; a time earlier than that is an error. `lines` holds the file
/// line of every row.
fn drop_repeated_times(
    table: &mut Table,
    lines: &[u32],
    source: &str,
    options: &ReadOptions,
) -> Result<()> {
    let mut steps: Vec<f64> = table
        .time
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 0.0)
        .collect();
    let tolerance = if steps.is_empty() {
        0.0
    } else {
        let mid = steps.len() / 2;
        let (_, median, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
        REPEAT_TOLERANCE * *median
    };
    let width = table.labels.len();
    let n = table.time.len();
    // Compacts rows in place: `kept` rows are final, row `r` is the one being judged.
    let mut kept = 1;
    let mut kept_line = lines[0];
    for r in 1..n {
        let (t_prev, t) = (table.time[kept - 1], table.time[r]);
        let line = lines[r];
        if t < t_prev - tolerance {
            return Err(content_error(
                source,
                line,
                "column \"time\"".into(),
                format!(
                    "time {t} is earlier than the time {t_prev} on line {kept_line}; time \
                     must increase"
                ),
            ));
        }
        if t <= t_prev + tolerance {
            let within = if t == t_prev {
                String::new()
            } else {
                format!(" (within {:.1e} s)", (t - t_prev).abs())
            };
            let dropped = match options.repeated_time {
                RepeatedTime::Error => {
                    return Err(content_error(
                        source,
                        line,
                        "column \"time\"".into(),
                        format!(
                            "time {t} repeats the time {t_prev} on line {kept_line}{within}; \
                             time must increase strictly"
                        ),
                    ));
                }
                RepeatedTime::KeepFirst => line,
                RepeatedTime::KeepLast => {
                    // The later row replaces the kept one.
                    table.time[kept - 1] = t;
                    table
                        .values
                        .copy_within(r * width..(r + 1) * width, (kept - 1) * width);
                    std::mem::replace(&mut kept_line, line)
                }
            };
            table.dropped_repeated_rows.push(dropped);
            let message = if dropped == line {
                format!("time {t} repeats the time on line {kept_line}{within}: row left out")
            } else {
                format!(
                    "time {t_prev} is repeated on line {line}{within}: row left out (the \
                     later one is kept)"
                )
            };
            table.warnings.push(FileWarning {
                file: source.to_string(),
                line: dropped,
                element: "column \"time\"".into(),
                message,
            });
            continue;
        }
        if kept != r {
            table.time[kept] = t;
            table
                .values
                .copy_within(r * width..(r + 1) * width, kept * width);
        }
        kept += 1;
        kept_line = line;
    }
    table.time.truncate(kept);
    table.values.truncate(kept * width);
    Ok(())
}
