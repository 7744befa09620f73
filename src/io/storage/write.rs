//! Writing: the checks a table must pass to be written and read back unchanged, the
//! OpenSim-4-style text, and the atomic write.

use std::collections::HashMap;
use std::path::Path;

use super::{
    HeaderLine, STRUCTURAL_KEYS, Table, WRITTEN_OPENSIM_VERSION, classify_header_line,
    looks_like_data_row,
};
use crate::{Error, Result};

impl Table {
    /// Checks the invariants of the module documentation and that the header fields can be
    /// written and read back unchanged; errors are [`Error::InvalidArgument`] naming `table`.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| Err(Error::invalid("table", message));
        if self.time.is_empty() {
            return bad("has no rows".into());
        }
        let w = self.labels.len();
        if self.values.len() != self.time.len() * w {
            return bad(format!(
                "has {} values, but {} rows × {w} labels need {}",
                self.values.len(),
                self.time.len(),
                self.time.len() * w
            ));
        }
        let mut seen: HashMap<&str, usize> = HashMap::with_capacity(w);
        for (c, label) in self.labels.iter().enumerate() {
            // Interior spaces survive tab-separated columns; tabs, line breaks and
            // surrounding blanks do not.
            if label.is_empty()
                || label.trim() != label
                || label.contains(['\t', '\n', '\r'])
                || label == "time"
            {
                return bad(format!(
                    "column {c} label `{label}` must be non-empty, without tabs, line breaks \
                     or surrounding blanks, and not `time`"
                ));
            }
            if let Some(previous) = seen.insert(label, c) {
                return bad(format!(
                    "column \"{label}\": duplicate label (columns {previous} and {c})"
                ));
            }
        }
        for (r, &t) in self.time.iter().enumerate() {
            if !t.is_finite() {
                return bad(format!(
                    "column \"time\": the time after {} is {t}, not a finite number",
                    r.checked_sub(1)
                        .map_or("the start".to_string(), |p| format!("{} s", self.time[p]))
                ));
            }
            if r > 0 && t <= self.time[r - 1] {
                return bad(format!(
                    "column \"time\": time {t} does not exceed the previous {}",
                    self.time[r - 1]
                ));
            }
        }
        if let Some(i) = self.values.iter().position(|v| !v.is_finite()) {
            return bad(format!(
                "column \"{}\" at time {} s: {} is not finite",
                self.labels[i % w],
                self.time[i / w],
                self.values[i]
            ));
        }
        if !self.name.is_empty()
            && (!is_safe_header_text(&self.name)
                || classify_header_line(&self.name, true) != HeaderLine::Name(&self.name))
        {
            return bad(format!(
                "name `{}` would not read back as a name line (one line, no `=`, no \
                 surrounding whitespace, not a header keyword)",
                self.name
            ));
        }
        for (key, value) in &self.metadata {
            let line = format!("{key}={value}");
            if STRUCTURAL_KEYS.contains(&key.as_str())
                || key == "endheader"
                || line.contains(['\n', '\r'])
                || classify_header_line(&line, false) != HeaderLine::KeyValue(key, value)
            {
                return bad(format!(
                    "metadata `{key}={value}` would not read back unchanged (the key must be \
                     non-empty, without whitespace or `=`, and not one the writer sets; the \
                     value one line without surrounding whitespace)"
                ));
            }
        }
        for text in &self.description {
            if !is_safe_header_text(text)
                || classify_header_line(text, false) != HeaderLine::Description(text)
            {
                return bad(format!(
                    "description line `{text}` would not read back as description text"
                ));
            }
        }
        Ok(())
    }

    /// The file text [`Table::write`] writes (see the module documentation).
    pub fn to_file_string(&self) -> Result<String> {
        self.validate()?;
        use std::fmt::Write as _;
        let mut s = String::with_capacity(32 * (self.labels.len() + 1) * (self.time.len() + 2));
        // `write!` into a String cannot fail.
        if !self.name.is_empty() {
            let _ = writeln!(s, "{}", self.name);
        }
        let _ = writeln!(s, "version=1");
        let _ = writeln!(s, "nRows={}", self.time.len());
        let _ = writeln!(s, "nColumns={}", self.labels.len() + 1);
        if let Some(deg) = self.in_degrees {
            let _ = writeln!(s, "inDegrees={}", if deg { "yes" } else { "no" });
        }
        for text in &self.description {
            let _ = writeln!(s, "{text}");
        }
        for (key, value) in &self.metadata {
            let _ = writeln!(s, "{key}={value}");
        }
        let _ = writeln!(s, "DataType=double");
        let _ = writeln!(s, "OpenSimVersion={WRITTEN_OPENSIM_VERSION}");
        let _ = writeln!(s, "endheader");
        s.push_str("time");
        for label in &self.labels {
            s.push('\t');
            s.push_str(label);
        }
        s.push('\n');
        for (r, &t) in self.time.iter().enumerate() {
            push_number(&mut s, t);
            for &v in self.row(r).unwrap_or(&[]) {
                s.push('\t');
                push_number(&mut s, v);
            }
            s.push('\n');
        }
        Ok(s)
    }

    /// Writes the table (see the module documentation) atomically: to a temporary file beside
    /// `path`, then renamed onto it ([`crate::io::output::write_file_atomic`]).
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::output::write_file_atomic(path, self.to_file_string()?.as_bytes())
    }
}

/// True when a free-text header line (name or description) is one line that no reader takes
/// for anything else: not a row of numbers, and not starting with the word `endheader`
/// (OpenSim's `Storage` ends the header at the first word before a space, tab or `=`).
/// Keywords are excluded separately, by classifying the line as the reader does.
fn is_safe_header_text(text: &str) -> bool {
    let first_word = text.split([' ', '\t', '=']).next().unwrap_or("");
    !text.contains(['\n', '\r']) && !looks_like_data_row(text) && first_word != "endheader"
}

/// Appends `x` in the shortest form that parses back to the same `f64`: positional notation
/// for moderate magnitudes, scientific notation (`1.5e-7`) otherwise, both of which C++
/// streams read.
fn push_number(s: &mut String, x: f64) {
    use std::fmt::Write as _;
    let magnitude = x.abs();
    let _ = if x == 0.0 || (1e-5..1e16).contains(&magnitude) {
        write!(s, "{x}")
    } else {
        write!(s, "{x:e}")
    };
}
