//! Marker trajectories in the `.trc` format (Motion Analysis / Vicon exports, OpenSim's
//! `TRCFileAdapter`).
//!
//! # Layout
//!
//! ```text
//! PathFileType  4  (X/Y/Z)  walk.trc
//! DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
//! 60.00     60.00       151        41          mm     60.00         1                   151
//! Frame#  Time  R.ASIS        L.ASIS        …
//!               X1  Y1  Z1    X2  Y2  Z2    …
//!
//! 1       0.000 617.2 1055.3 170.8  639.6 …
//! ```
//!
//! Fields are tab-separated (a line without tabs is split at whitespace). Blank label fields
//! are padding and are skipped, as OpenSim does. A marker whose three fields in a row are not
//! all present (empty fields, which Vicon and Motion Analysis write for occluded markers, or
//! `NaN`) is missing in that frame: its position is NaN and [`Trc::missing`] reports, per
//! marker, how many frames are missing and the gaps. Missing markers are data, not errors.
//! Trailing empty fields beyond the last marker are ignored.
//!
//! Positions are converted from the file's `Units` (`mm`, `cm` or `m`, any case) to metres.
//! The header keys are read by name; `DataRate`, `NumFrames`, `NumMarkers` and `Units` are
//! required, the others default as OpenSim's writer defaults them (rates to `DataRate`,
//! `OrigDataStartFrame` to 1, `OrigNumFrames` to the frame count).
//!
//! # Errors
//!
//! Bad content is an [`Error::Model`] naming the file, the 1-based line and the element —
//! `marker "R.ASIS" (column Y1)`, `column "Time"`, `column "Frame#"`, `header "NumMarkers"` —
//! with the row index (from 0) in the message: a value that is not a number, a row with too
//! few or too many values, time that does not increase, duplicate marker names, a label count
//! that contradicts `NumMarkers`, a frame count that contradicts `NumFrames`, unknown units.
//!
//! A frame whose time repeats the previous frame's — exactly, or within
//! [`REPEAT_TOLERANCE`](crate::io::storage::REPEAT_TOLERANCE) of the sampling interval
//! 1/`DataRate` — is the same sample written twice: it is left out, with a warning in
//! [`Trc::warnings`] naming its line and time (as `.mot`/`.sto` files are read). It still
//! counts as a row of the file for `NumFrames`.
//!
//! # Writing
//!
//! [`Trc::write`] produces the layout above exactly as OpenSim's `TRCFileAdapter` writes it
//! (so OpenSim's GUI and readers open it): the eight header keys in OpenSim's order, every
//! field followed by a tab, a blank line before the data, missing markers as empty fields,
//! numbers in the shortest form that reads back to the same value in the file's units,
//! through a temporary file renamed into place. (Reading divides by 1000 or 100 and writing
//! multiplies, so a round trip through millimetres may move a position's last bit; in metres
//! it is exact.)

use crate::error::Error;
use crate::spatial::Vec3;
use crate::text::short_number;
use std::path::Path;

/// The largest magnitude of a marker coordinate (m, after the file's unit). Capture volumes
/// span tens of metres, and a marker a thousand kilometres away is a typing or unit error.
/// Such a value reaches IK as a target: 1e300 m squares to an infinite marker error, and the
/// failure then names IK's output table instead of the file's cell.
pub const MAX_MARKER_COORDINATE: f64 = 1e6;

/// Length unit of a `.trc` file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LengthUnit {
    Millimetres,
    Centimetres,
    Metres,
}

impl LengthUnit {
    /// How many units make a metre.
    pub fn per_metre(self) -> f64 {
        match self {
            LengthUnit::Millimetres => 1000.0,
            LengthUnit::Centimetres => 100.0,
            LengthUnit::Metres => 1.0,
        }
    }

    /// The `Units` header value.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetres => "mm",
            LengthUnit::Centimetres => "cm",
            LengthUnit::Metres => "m",
        }
    }

    fn parse(text: &str) -> Option<LengthUnit> {
        match text.to_ascii_lowercase().as_str() {
            "mm" => Some(LengthUnit::Millimetres),
            "cm" => Some(LengthUnit::Centimetres),
            "m" => Some(LengthUnit::Metres),
            _ => None,
        }
    }
}

/// The frames in which one marker is missing.
#[derive(Clone, Debug, PartialEq)]
pub struct MissingMarker {
    /// Index into [`Trc::markers`].
    pub marker: usize,
    pub name: String,
    /// Number of frames missing.
    pub frames: usize,
    /// Runs of consecutive missing frames, as [first, last] frame indices (from 0).
    pub gaps: Vec<[usize; 2]>,
}

/// A marker trajectory file: frames × markers × 3, in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Trc {
    /// The file name in the first header line (may be empty).
    pub path_file_name: String,
    pub data_rate: f64,
    pub camera_rate: f64,
    /// The unit of the file (positions here are always in metres).
    pub units: LengthUnit,
    pub orig_data_rate: f64,
    pub orig_data_start_frame: i64,
    pub orig_num_frames: usize,
    pub markers: Vec<String>,
    /// The `Frame#` column.
    pub frame_numbers: Vec<i64>,
    /// The `Time` column (s), strictly increasing.
    pub time: Vec<f64>,
    /// Row-major positions in ground, metres: marker `m` of frame `f` is
    /// `positions[f * markers.len() + m]`; NaN where missing.
    pub positions: Vec<Vec3>,
    /// What the reader accepted but reports: frames left out because their time repeated
    /// the previous frame's. Empty for trajectories built in memory.
    pub warnings: Vec<crate::io::FileWarning>,
}

impl Trc {
    /// A trajectory built in memory: `positions` in metres, frames × markers, NaN where a
    /// marker is missing; frame numbers 1, 2, …; units millimetres.
    pub fn new(
        markers: Vec<String>,
        time: Vec<f64>,
        positions: Vec<Vec3>,
        data_rate: f64,
    ) -> crate::Result<Trc> {
        let n = time.len();
        let trc = Trc {
            path_file_name: String::new(),
            data_rate,
            camera_rate: data_rate,
            units: LengthUnit::Millimetres,
            orig_data_rate: data_rate,
            orig_data_start_frame: 1,
            orig_num_frames: n,
            markers,
            frame_numbers: (1..=n as i64).collect(),
            time,
            positions,
            warnings: Vec::new(),
        };
        trc.validate()?;
        Ok(trc)
    }

    pub fn n_frames(&self) -> usize {
        self.time.len()
    }

    pub fn n_markers(&self) -> usize {
        self.markers.len()
    }

    /// The markers of frame `f` (metres; NaN where missing).
    pub fn frame(&self, f: usize) -> &[Vec3] {
        let m = self.markers.len();
        &self.positions[f * m..(f + 1) * m]
    }

    /// Position of marker `m` in frame `f` (metres; NaN where missing).
    pub fn position(&self, f: usize, m: usize) -> Vec3 {
        self.positions[f * self.markers.len() + m]
    }

    pub fn marker_index(&self, name: &str) -> Option<usize> {
        self.markers.iter().position(|m| m == name)
    }

    /// Per marker with at least one missing frame: the count and the gaps, in marker order.
    pub fn missing(&self) -> Vec<MissingMarker> {
        let nm = self.markers.len();
        let mut out = Vec::new();
        for m in 0..nm {
            let mut gaps: Vec<[usize; 2]> = Vec::new();
            for f in 0..self.n_frames() {
                if self.positions[f * nm + m].iter().any(|v| v.is_nan()) {
                    match gaps.last_mut() {
                        Some(g) if g[1] + 1 == f => g[1] = f,
                        _ => gaps.push([f, f]),
                    }
                }
            }
            if !gaps.is_empty() {
                out.push(MissingMarker {
                    marker: m,
                    name: self.markers[m].clone(),
                    frames: gaps.iter().map(|g| g[1] - g[0] + 1).sum(),
                    gaps,
                });
            }
        }
        out
    }

    /// Checks what the writer needs: sizes, unique names without tabs, finite increasing
    /// times, positive rates, positions finite or NaN (missing).
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |m: String| Err(Error::invalid("trc", m));
        let (n, nm) = (self.time.len(), self.markers.len());
        if self.positions.len() != n * nm || self.frame_numbers.len() != n {
            return bad(format!(
                "{} positions and {} frame numbers for {n} frames × {nm} markers",
                self.positions.len(),
                self.frame_numbers.len()
            ));
        }
        for (i, name) in self.markers.iter().enumerate() {
            if name.is_empty() || name.trim() != name || name.contains(['\t', '\n', '\r']) {
                return bad(format!(
                    "marker {i} name `{name}` is empty or has tabs or surrounding blanks"
                ));
            }
            if let Some(j) = self.markers[..i].iter().position(|o| o == name) {
                return bad(format!(
                    "marker \"{name}\": duplicate name (markers {j} and {i})"
                ));
            }
        }
        for r in 0..n {
            if !self.time[r].is_finite() || (r > 0 && self.time[r] <= self.time[r - 1]) {
                return bad(format!(
                    "column \"Time\": time {} does not increase",
                    self.time[r]
                ));
            }
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| p.iter().any(|v| v.is_infinite()))
        {
            return bad(format!(
                "marker \"{}\" at time {} s: infinite position",
                self.markers[i % nm],
                self.time[i / nm]
            ));
        }
        if !(self.data_rate > 0.0 && self.camera_rate > 0.0 && self.orig_data_rate > 0.0) {
            return bad("rates must be positive".into());
        }
        if self.path_file_name.contains(['\n', '\r']) {
            return bad("the path file name must be one line".into());
        }
        Ok(())
    }

    /// Reads a `.trc` file.
    pub fn read(path: &Path) -> crate::Result<Trc> {
        let text = crate::text::read_text(path)?;
        Trc::parse(&text, &path.display().to_string())
    }

    /// Parses `.trc` text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> crate::Result<Trc> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let p = TrcParser { source };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
        let (l1, path_file_name) = p.path_file_type(&mut lines)?;
        let header = p.header(&mut lines, l1)?;
        let (ll, markers) = p.marker_names(&mut lines, &header)?;
        let xyz = p.coordinate_labels(&mut lines, ll, &markers)?;
        let columns = TrcColumns {
            markers: &markers,
            xyz: &xyz,
        };
        let rows = p.data_rows(lines, text.len(), &header, &columns)?;
        if rows.in_file != header.num_frames {
            return Err(p.err(
                header.line,
                "header \"NumFrames\"".into(),
                format!(
                    "NumFrames is {}, but the file has {} data rows",
                    header.num_frames, rows.in_file
                ),
            ));
        }
        Ok(Trc {
            path_file_name,
            data_rate: header.data_rate,
            camera_rate: header.camera_rate,
            units: header.units,
            orig_data_rate: header.orig_data_rate,
            orig_data_start_frame: header.orig_data_start_frame,
            orig_num_frames: header.orig_num_frames.unwrap_or(header.num_frames),
            markers,
            frame_numbers: rows.frame_numbers,
            time: rows.time,
            positions: rows.positions,
            warnings: rows.warnings,
        })
    }

    /// The file text [`Trc::write`] writes (module documentation), with `file_name` in the
    /// first line when `path_file_name` is empty.
    pub fn to_file_string(&self, file_name: &str) -> crate::Result<String> {
        use std::fmt::Write as _;
        self.validate()?;
        let nm = self.markers.len();
        let mut s = String::with_capacity(16 * (3 * nm + 2) * (self.n_frames() + 5));
        let name = if self.path_file_name.is_empty() {
            file_name
        } else {
            &self.path_file_name
        };
        let _ = writeln!(s, "PathFileType\t4\t(X/Y/Z)\t{name}");
        let _ = writeln!(
            s,
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t\
             OrigDataStartFrame\tOrigNumFrames"
        );
        let _ = writeln!(
            s,
            "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}",
            self.data_rate,
            self.camera_rate,
            self.n_frames(),
            nm,
            self.units.symbol(),
            self.orig_data_rate,
            self.orig_data_start_frame,
            self.orig_num_frames
        );
        s.push_str("Frame#\tTime\t");
        for m in &self.markers {
            let _ = write!(s, "{m}\t\t\t");
        }
        s.push_str("\n\t\t");
        for i in 1..=nm {
            let _ = write!(s, "X{i}\tY{i}\tZ{i}\t");
        }
        s.push_str("\n\n");
        let per_metre = self.units.per_metre();
        for f in 0..self.n_frames() {
            let _ = write!(s, "{}\t{}\t", self.frame_numbers[f], self.time[f]);
            for p in self.frame(f) {
                if p.iter().any(|v| v.is_nan()) {
                    s.push_str("\t\t\t");
                } else {
                    let _ = write!(
                        s,
                        "{}\t{}\t{}\t",
                        p.x * per_metre,
                        p.y * per_metre,
                        p.z * per_metre
                    );
                }
            }
            s.push('\n');
        }
        Ok(s)
    }

    /// Writes the file (module documentation) atomically, through a temporary file beside
    /// `path` ([`crate::io::output::write_file_atomic`]).
    pub fn write(&self, path: &Path) -> crate::Result<()> {
        let file_name = path
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let text = self.to_file_string(&file_name)?;
        crate::io::output::write_file_atomic(path, text.as_bytes())
    }
}

/// The reader of one `.trc` text: its stages in file order, and errors naming `source`.
struct TrcParser<'s> {
    source: &'s str,
}

/// The header keys and values (lines 2–3).
struct TrcHeader {
    /// The line of the header values.
    line: usize,
    data_rate: f64,
    camera_rate: f64,
    orig_data_rate: f64,
    num_frames: usize,
    num_markers: usize,
    units: LengthUnit,
    orig_data_start_frame: i64,
    orig_num_frames: Option<usize>,
}

/// The data columns' names: the markers (line 4) and their coordinate labels (line 5).
struct TrcColumns<'a> {
    markers: &'a [String],
    xyz: &'a [&'a str],
}

impl TrcColumns<'_> {
    /// Fields in a data row: Frame#, Time and 3 per marker.
    fn expected(&self) -> usize {
        2 + 3 * self.markers.len()
    }

    /// Column `c` of a data row, in words.
    fn name(&self, c: usize) -> String {
        match c {
            0 => "column \"Frame#\"".into(),
            1 => "column \"Time\"".into(),
            c if c < self.expected() => {
                format!(
                    "marker \"{}\" (column {})",
                    self.markers[(c - 2) / 3],
                    self.xyz[c - 2]
                )
            }
            c => format!("column {} (beyond the last marker)", c + 1),
        }
    }
}

/// The data rows kept, and how many the file has (repeated times included).
struct TrcRows {
    frame_numbers: Vec<i64>,
    time: Vec<f64>,
    positions: Vec<Vec3>,
    warnings: Vec<crate::io::FileWarning>,
    in_file: usize,
}

impl TrcParser<'_> {
    fn err(&self, line: usize, element: String, message: String) -> Error {
        Error::Model {
            file: self.source.to_string(),
            line: u32::try_from(line).unwrap_or(u32::MAX),
            element,
            message,
        }
    }

    /// Line 1: `PathFileType 4 (X/Y/Z) name`; returns its line and the name.
    fn path_file_type<'t>(
        &self,
        lines: &mut impl Iterator<Item = (usize, &'t str)>,
    ) -> crate::Result<(usize, String)> {
        let (l1, first) = lines
            .next()
            .ok_or_else(|| self.err(1, "header".into(), "the file is empty".into()))?;
        let mut words = first.split_whitespace();
        if words.next() != Some("PathFileType") {
            return Err(self.err(
                l1,
                "header".into(),
                "the first line must start with `PathFileType`".into(),
            ));
        }
        Ok((l1, words.skip(2).collect::<Vec<_>>().join(" ")))
    }

    /// Lines 2–3: the header keys and their values, read by name (`l1`: the first line's).
    fn header<'t>(
        &self,
        lines: &mut impl Iterator<Item = (usize, &'t str)>,
        l1: usize,
    ) -> crate::Result<TrcHeader> {
        let (lk, keys) = lines
            .next()
            .ok_or_else(|| self.err(l1, "header".into(), "no header keys line".into()))?;
        let (lv, vals) = lines
            .next()
            .ok_or_else(|| self.err(lk, "header".into(), "no header values line".into()))?;
        let keys: Vec<&str> = fields(keys).into_iter().filter(|k| !k.is_empty()).collect();
        let vals: Vec<&str> = fields(vals).into_iter().filter(|k| !k.is_empty()).collect();
        if keys.len() != vals.len() {
            return Err(self.err(
                lv,
                "header".into(),
                format!(
                    "{} header keys (line {lk}) but {} values",
                    keys.len(),
                    vals.len()
                ),
            ));
        }
        let value = |key: &str| keys.iter().position(|k| *k == key).map(|i| vals[i]);
        let header_err =
            |key: &str, message: String| self.err(lv, format!("header \"{key}\""), message);
        let number = |key: &str| -> crate::Result<Option<f64>> {
            value(key)
                .map(|v| {
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| header_err(key, format!("`{v}` is not a number")))
                })
                .transpose()
        };
        let count = |key: &str| -> crate::Result<Option<usize>> {
            value(key)
                .map(|v| {
                    v.parse::<usize>()
                        .map_err(|_| header_err(key, format!("`{v}` is not a count")))
                })
                .transpose()
        };
        let required = |key: &str| header_err(key, "missing from the header".into());
        let data_rate = number("DataRate")?.ok_or_else(|| required("DataRate"))?;
        if data_rate <= 0.0 {
            return Err(header_err(
                "DataRate",
                format!("{data_rate} is not a positive rate"),
            ));
        }
        let camera_rate = number("CameraRate")?.unwrap_or(data_rate);
        let orig_data_rate = number("OrigDataRate")?.unwrap_or(data_rate);
        let num_frames = count("NumFrames")?.ok_or_else(|| required("NumFrames"))?;
        let num_markers = count("NumMarkers")?.ok_or_else(|| required("NumMarkers"))?;
        let units_text = value("Units").ok_or_else(|| required("Units"))?;
        let units = LengthUnit::parse(units_text).ok_or_else(|| {
            header_err(
                "Units",
                format!("unknown unit `{units_text}` (mm, cm or m)"),
            )
        })?;
        let orig_data_start_frame = match value("OrigDataStartFrame") {
            Some(v) => v.parse::<i64>().map_err(|_| {
                header_err("OrigDataStartFrame", format!("`{v}` is not an integer"))
            })?,
            None => 1,
        };
        let orig_num_frames = count("OrigNumFrames")?;
        Ok(TrcHeader {
            line: lv,
            data_rate,
            camera_rate,
            orig_data_rate,
            num_frames,
            num_markers,
            units,
            orig_data_start_frame,
            orig_num_frames,
        })
    }

    /// Line 4: `Frame# Time` and the marker names, as many as NumMarkers, unique; returns
    /// its line and the names.
    fn marker_names<'t>(
        &self,
        lines: &mut impl Iterator<Item = (usize, &'t str)>,
        header: &TrcHeader,
    ) -> crate::Result<(usize, Vec<String>)> {
        let (lv, num_markers) = (header.line, header.num_markers);
        let (ll, label_line) = lines
            .next()
            .ok_or_else(|| self.err(lv, "header".into(), "no marker names line".into()))?;
        let labels: Vec<&str> = fields(label_line)
            .into_iter()
            .filter(|k| !k.is_empty())
            .collect();
        if labels.first() != Some(&"Frame#") || labels.get(1) != Some(&"Time") {
            return Err(self.err(
                ll,
                "header".into(),
                "the marker names line must start with `Frame#` and `Time`".into(),
            ));
        }
        let markers: Vec<String> = labels[2..].iter().map(|s| s.to_string()).collect();
        if markers.len() != num_markers {
            return Err(self.err(
                ll,
                "header \"NumMarkers\"".into(),
                format!(
                    "NumMarkers (line {lv}) is {num_markers}, but line {ll} names {} markers",
                    markers.len()
                ),
            ));
        }
        for (i, name) in markers.iter().enumerate() {
            if let Some(j) = markers[..i].iter().position(|o| o == name) {
                return Err(self.err(
                    ll,
                    format!("marker \"{name}\""),
                    format!(
                        "duplicate marker name (markers {} and {}, from 1)",
                        j + 1,
                        i + 1
                    ),
                ));
            }
        }
        Ok((ll, markers))
    }

    /// Line 5: `X1 Y1 Z1 …`, three labels per marker starting with X, Y and Z (`ll`: the
    /// marker names' line).
    fn coordinate_labels<'t>(
        &self,
        lines: &mut impl Iterator<Item = (usize, &'t str)>,
        ll: usize,
        markers: &[String],
    ) -> crate::Result<Vec<&'t str>> {
        let num_markers = markers.len();
        let (lx, xyz_line) = lines
            .next()
            .ok_or_else(|| self.err(ll, "header".into(), "no X1 Y1 Z1 line".into()))?;
        let xyz: Vec<&str> = fields(xyz_line)
            .into_iter()
            .filter(|k| !k.is_empty())
            .collect();
        if xyz.len() != 3 * num_markers {
            return Err(self.err(
                lx,
                "header".into(),
                format!(
                    "{} coordinate labels for {num_markers} markers (3 each)",
                    xyz.len()
                ),
            ));
        }
        for (k, label) in xyz.iter().enumerate() {
            let axis = ["X", "Y", "Z"][k % 3];
            if !label.starts_with(axis) {
                return Err(self.err(
                    lx,
                    format!("marker \"{}\" (column {label})", markers[k / 3]),
                    format!("expected a label starting with {axis}"),
                ));
            }
        }
        Ok(xyz)
    }

    /// The data rows (blank lines skipped): frame number, strictly increasing time (a time
    /// within the repeat tolerance of the previous one is left out with a warning) and the
    /// markers' positions in metres. `text_len` bounds the capacity reserved.
    fn data_rows<'t>(
        &self,
        lines: impl Iterator<Item = (usize, &'t str)>,
        text_len: usize,
        header: &TrcHeader,
        columns: &TrcColumns,
    ) -> crate::Result<TrcRows> {
        let nm = columns.markers.len();
        let expected = columns.expected();
        // NumFrames is not taken on trust for the capacity: a frame is at least a line of
        // two bytes, a marker in it at least three (three empty fields).
        let capacity = header.num_frames.min(text_len / 2 + 1);
        let mut rows = TrcRows {
            frame_numbers: Vec::with_capacity(capacity),
            time: Vec::with_capacity(capacity),
            positions: Vec::with_capacity(capacity.saturating_mul(nm).min(text_len / 3 + 1)),
            warnings: Vec::new(),
            in_file: 0,
        };
        let mut previous_line = 0;
        // Two frames closer than this are one sample (module documentation).
        let repeat_tolerance = crate::io::storage::REPEAT_TOLERANCE / header.data_rate;
        for (line, raw) in lines {
            if raw.trim().is_empty() {
                continue;
            }
            let mut f = fields(raw);
            while f.len() > expected && f.last().is_some_and(|s| s.is_empty()) {
                f.pop();
            }
            if f.len() != expected {
                let c = f.len().min(expected);
                return Err(self.err(
                    line,
                    columns.name(c),
                    format!(
                        "the row has {} values, expected {expected} (Frame#, Time and 3 for \
                         each of {nm} markers)",
                        f.len()
                    ),
                ));
            }
            let frame = f[0].parse::<i64>().map_err(|_| {
                self.err(
                    line,
                    columns.name(0),
                    format!("`{}` is not a frame number", f[0]),
                )
            })?;
            let t = f[1]
                .parse::<f64>()
                .ok()
                .filter(|t| t.is_finite())
                .ok_or_else(|| {
                    self.err(
                        line,
                        columns.name(1),
                        format!("`{}` is not a finite time", f[1]),
                    )
                })?;
            rows.in_file += 1;
            if let Some(&t_prev) = rows.time.last()
                && (t - t_prev).abs() <= repeat_tolerance
            {
                let within = if t == t_prev {
                    String::new()
                } else {
                    format!(" (within {:.1e} s)", (t - t_prev).abs())
                };
                rows.warnings.push(crate::io::FileWarning {
                    file: self.source.to_string(),
                    line: u32::try_from(line).unwrap_or(u32::MAX),
                    element: columns.name(1),
                    message: format!(
                        "time {t} repeats the time on line {previous_line}{within}: frame left out"
                    ),
                });
                continue;
            }
            if let Some(&t_prev) = rows.time.last()
                && t <= t_prev
            {
                return Err(self.err(
                    line,
                    columns.name(1),
                    format!(
                        "time {t} does not exceed the time {t_prev} on line {previous_line}; \
                         time must increase strictly"
                    ),
                ));
            }
            rows.frame_numbers.push(frame);
            rows.time.push(t);
            for m in 0..nm {
                let position = self.marker_position(&f, m, line, header.units, columns)?;
                rows.positions.push(position);
            }
            previous_line = line;
        }
        Ok(rows)
    }

    /// Marker `m`'s position (m) in the row `f` on `line`, in `units`: NaN when a field is
    /// empty or `NaN` (missing); an error when a field is not a number or beyond
    /// ±[`MAX_MARKER_COORDINATE`] m.
    fn marker_position(
        &self,
        f: &[&str],
        m: usize,
        line: usize,
        units: LengthUnit,
        columns: &TrcColumns,
    ) -> crate::Result<Vec3> {
        let c = 2 + 3 * m;
        let parts = [f[c], f[c + 1], f[c + 2]];
        let missing = parts
            .iter()
            .any(|s| s.is_empty() || s.eq_ignore_ascii_case("nan"));
        if missing {
            return Ok(Vec3::repeat(f64::NAN));
        }
        let per_metre = units.per_metre();
        let mut p = Vec3::zeros();
        for k in 0..3 {
            p[k] = parts[k]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    self.err(
                        line,
                        columns.name(c + k),
                        format!("`{}` is not a number", parts[k]),
                    )
                })?
                / per_metre;
            if !(p[k].abs() <= MAX_MARKER_COORDINATE) {
                return Err(self.err(
                    line,
                    columns.name(c + k),
                    format!(
                        "`{}` {} is {} m from the origin, beyond \
                         ±{MAX_MARKER_COORDINATE:e} m, which no capture volume reaches: \
                         a typing or unit error",
                        parts[k],
                        units.symbol(),
                        short_number(p[k])
                    ),
                ));
            }
        }
        Ok(p)
    }
}

/// The fields of a line: tab-separated when it has a tab, else whitespace-separated; each
/// trimmed.
fn fields(line: &str) -> Vec<&str> {
    if line.contains('\t') {
        line.split('\t').map(str::trim).collect()
    } else {
        line.split_whitespace().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRC: &str = "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
100\t100\t3\t2\tmm\t100\t1\t3\n\
Frame#\tTime\tA\t\t\tB\t\t\n\
\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\
\n\
1\t0\t1\t2\t3\t4\t5\t6\n\
2\t0.01\t\t\t\t40\t50\t60\n\
3\t0.02\t7\t8\t9\t\t\t\t\n";

    #[test]
    fn reads_values_in_metres_and_reports_missing_markers() {
        let t = Trc::parse(TRC, "t.trc").unwrap();
        assert_eq!(t.markers, vec!["A", "B"]);
        assert_eq!(t.time, vec![0.0, 0.01, 0.02]);
        assert_eq!(t.position(0, 1), Vec3::new(0.004, 0.005, 0.006));
        assert!(t.position(1, 0).x.is_nan());
        assert!(t.position(2, 1).z.is_nan());
        let missing = t.missing();
        assert_eq!(missing.len(), 2);
        assert_eq!((missing[0].name.as_str(), missing[0].frames), ("A", 1));
        assert_eq!(missing[0].gaps, vec![[1, 1]]);
        assert_eq!(missing[1].gaps, vec![[2, 2]]);
    }

    #[test]
    fn writes_what_it_reads() {
        let t = Trc::parse(TRC, "t.trc").unwrap();
        let text = t.to_file_string("t.trc").unwrap();
        let back = Trc::parse(&text, "back.trc").unwrap();
        assert_eq!(back.markers, t.markers);
        assert_eq!(back.time, t.time);
        for (a, b) in back.positions.iter().zip(&t.positions) {
            for k in 0..3 {
                // Unit conversion both ways may move the last bit.
                let same = (a[k] - b[k]).abs() <= 2.0 * f64::EPSILON * b[k].abs();
                assert!(same || (a[k].is_nan() && b[k].is_nan()), "{a} vs {b}");
            }
        }
        // OpenSim's layout: every field followed by a tab, a blank line before the data.
        assert!(
            text.contains("Frame#\tTime\tA\t\t\tB\t\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\t\n\n1\t0\t")
        );
    }

    #[test]
    fn bad_content_names_file_line_and_marker() {
        let e = Trc::parse(&TRC.replace("40\t50", "40\tx50"), "t.trc")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.trc:8") && e.contains("marker \"B\" (column Y2)") && !e.contains("row 1"),
            "{e}"
        );
        let e = Trc::parse(&TRC.replace("\tB\t", "\tA\t"), "t.trc")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.trc:4") && e.contains("duplicate"), "{e}");
        let e = Trc::parse(
            &TRC.replace("1\t0\t1\t2\t3\t4\t5\t6", "1\t0\t1\t2\t3\t4\t5"),
            "t.trc",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("t.trc:7") && e.contains("the row has 7 values, expected 8"),
            "{e}"
        );
        let e = Trc::parse(&TRC.replace("\tmm\t", "\tinch\t"), "t.trc")
            .unwrap_err()
            .to_string();
        assert!(e.contains("header \"Units\""), "{e}");
        let e = Trc::parse(&TRC.replace("\t3\t2\tmm", "\t4\t2\tmm"), "t.trc")
            .unwrap_err()
            .to_string();
        assert!(e.contains("NumFrames is 4"), "{e}");
    }

    /// The reference file, or None (skipped) unless reference data is required.
    fn reference(rel: &str) -> Option<std::path::PathBuf> {
        let p = crate::reference::file(rel);
        if p.is_none() {
            assert!(
                !crate::reference::required(),
                "reference data not found: {rel}"
            );
            eprintln!("skipped: reference data not found ({rel})");
        }
        p
    }

    #[test]
    fn reference_files_read_with_the_values_they_hold() {
        // (file, frames, markers, rate, [(row, marker, x y z in the file's mm)])
        type Spot = (usize, &'static str, [f64; 3]);
        let cases: [(&str, usize, usize, f64, [Spot; 2]); 3] = [
            (
                "opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1.trc",
                151,
                41,
                60.0,
                [
                    (0, "R.ASIS", [617.247620, 1055.275020, 170.781980]),
                    (150, "L.ASIS", [621.185490, 1036.777470, -89.615940]),
                ],
            ),
            (
                "opensim-models/Pipelines/Gait10dof18musc/ExperimentalData/subject01_walk.trc",
                151,
                41,
                60.0,
                [
                    (0, "V.Sacral", [430.869840, 1051.264650, 29.966750]),
                    (150, "R.ASIS", [597.613650, 1045.068850, 169.864320]),
                ],
            ),
            (
                "opensim-models/Tutorials/Computed_Muscle_Control/InverseKinematics/arm26_elbow_flex.trc",
                121,
                3,
                120.0,
                [
                    (0, "r_acromion", [-13.05452443, 839.50547557, 169.5054756]),
                    (
                        120,
                        "r_radius_styloid",
                        [231.0167559, 500.5158582, 230.9769121],
                    ),
                ],
            ),
        ];
        for (rel, frames, markers, rate, spots) in cases {
            let Some(path) = reference(rel) else { continue };
            let t = Trc::read(&path).unwrap();
            assert_eq!(
                (t.n_frames(), t.n_markers(), t.data_rate),
                (frames, markers, rate),
                "{rel}"
            );
            assert_eq!(t.units, LengthUnit::Millimetres);
            assert!(
                t.missing().is_empty(),
                "{rel}: no marker is missing in these files"
            );
            for (row, name, mm) in spots {
                let p = t.position(row, t.marker_index(name).unwrap());
                for k in 0..3 {
                    assert_eq!(p[k], mm[k] / 1000.0, "{rel} row {row} {name}");
                }
            }
            assert!(
                (t.time[frames - 1] - (frames - 1) as f64 / rate).abs() < 1e-6,
                "{rel}"
            );
            // Round trip through the writer, in the file's units and in metres.
            let back = Trc::parse(&t.to_file_string("x.trc").unwrap(), "x.trc").unwrap();
            assert_eq!(
                (back.markers.clone(), back.time.clone()),
                (t.markers.clone(), t.time.clone())
            );
            for (a, b) in back.positions.iter().zip(&t.positions) {
                assert!(
                    (a - b).amax() <= 2.0 * f64::EPSILON * b.amax(),
                    "{rel}: {a} vs {b}"
                );
            }
            let mut metres = t.clone();
            metres.units = LengthUnit::Metres;
            let back = Trc::parse(&metres.to_file_string("x.trc").unwrap(), "x.trc").unwrap();
            assert_eq!(back.positions, t.positions, "{rel}: exact in metres");
        }
    }
}
