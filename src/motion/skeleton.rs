//! Skeleton maps: which model marker each joint (or marker) of an input skeleton stands for,
//! with what weight, and how the input's axes turn into the model's.
//!
//! A map is a declarative JSON table (the built-in ones live in `data/skeletons/`):
//!
//! ```json
//! {
//!   "skeleton": "HumanML3D (SMPL, 22 joints)",
//!   "description": "why each choice was made …",
//!   "axes": ["z", "y", "-x"],
//!   "targets": [
//!     { "source": ["pelvis"], "marker": "pelvis", "weight": 1.0 },
//!     { "source": ["LeftUpLeg", "LeftHip"], "marker": "LeftUpLeg", "weight": 1.0 }
//!   ]
//! }
//! ```
//!
//! - `axes[k]` is the input axis (`x`, `y`, `z`, optionally negated) that becomes model axis
//!   k: p_model = A p_input with A a signed permutation. A proper rotation keeps the motion
//!   as it is; a reflection (det A = −1, for left-handed input frames) is only accepted with
//!   `"mirror": true`, so that no motion is mirrored by accident.
//! - `scale` (optional, default 1): metres per input unit, for inputs whose reader cannot
//!   know the unit.
//! - `source` lists the accepted names of one input joint (the first one present is used),
//!   so one map serves the naming variants of a skeleton (CMU BVH conversions differ).
//! - `weight` ≥ 0: the IK weight of that target.
//! - `placed` (optional, default false): the input skeleton puts this joint by a convention
//!   of its own (SMPL's pelvis joint lies above the hip centres, its spine joints are not the
//!   model's vertebral joints), so fitting the model to a clip moves the model marker to the
//!   clip's average position on the marker's body, as OpenSim's marker placement does.
//! - `landmark` (optional, default false, with `placed`): the model marker sits at the
//!   anatomical landmark the input names (the default model's pelvis landmarks RASI, LASI,
//!   RPSI, LPSI), so the first placement round fits it at full weight: where only such
//!   markers fix a body's pose, that pose comes from the model's anatomy rather than from
//!   the first round's guess.
//! - `segments` (optional): `{ "name", "bodies": [model bodies], "pairs": [[a, b], …] }`,
//!   where a and b are target (model marker) names: scaling a model to a clip multiplies
//!   the bodies' dimensions by the median over frames of ‖x_a − x_b‖ divided by the same
//!   distance on the model (see `solve::scale_from_clip`); `"axes": ["z"]` limits the factor
//!   to some body axes (a later segment overrides an earlier one there).
//!
//! [`SkeletonMap::apply`] turns a [`Motion`] into targets in the model's frame, one column
//! per mapped target, with the IK marker tasks that pair them with the model's markers. A
//! motion that lacks a source joint, or a model that lacks a marker, is an error that lists
//! every name missing.

use super::Motion;
use super::tasks::{IkTasks, MarkerTask};
use crate::error::Error;
use crate::model::Model;
use crate::spatial::{Mat3, Vec3};
use serde::Deserialize;

/// One input joint → one model marker.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapTarget {
    /// Accepted names of the input joint, in order of preference.
    pub source: Vec<String>,
    /// The model marker it stands for.
    pub marker: String,
    /// IK weight (≥ 0).
    pub weight: f64,
    /// Why this pairing (free text, for people).
    #[serde(default)]
    pub note: String,
    /// The input skeleton places this joint by its own convention (SMPL's pelvis and spine
    /// joints, a BVH's neck): when a model is fitted to a clip, the marker is moved to where
    /// the clip puts it on its body (see `solve::scale_from_clip`).
    #[serde(default)]
    pub placed: bool,
    /// With `placed`: the model carries this marker at the anatomical landmark the input
    /// names (not a re-used joint-centre marker), so the first placement round weighs it
    /// fully and the pose it fixes (a pelvis' tilt about the hip axis) is the one the
    /// placement keeps.
    #[serde(default)]
    pub landmark: bool,
}

/// A group of model bodies scaled together from target distances (for scaling a model to a
/// clip, [`crate::solve::scale_from_clip`]).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSegment {
    /// For messages (`right thigh`).
    pub name: String,
    /// Model bodies scaled by the segment's factor on all three axes.
    pub bodies: Vec<String>,
    /// Pairs of map targets (model marker names) whose distance measures the segment.
    pub pairs: Vec<[String; 2]>,
    /// The body axes the factor applies to (`x`, `y`, `z`; default all three). A later
    /// segment overrides an earlier one on the axes it names.
    #[serde(default = "all_axes")]
    pub axes: Vec<String>,
}

fn all_axes() -> Vec<String> {
    vec!["x".into(), "y".into(), "z".into()]
}

/// A skeleton map (see the module documentation for the file format).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkeletonMap {
    /// What skeleton it reads.
    pub skeleton: String,
    #[serde(default)]
    pub description: String,
    /// Input axis per model axis.
    pub axes: [String; 3],
    /// Accept a reflection (det A = −1).
    #[serde(default)]
    pub mirror: bool,
    /// Metres per input unit.
    #[serde(default = "one")]
    pub scale: f64,
    pub targets: Vec<MapTarget>,
    /// Segments for scaling the model to a clip (optional).
    #[serde(default)]
    pub segments: Vec<MapSegment>,
    /// Where it was read from.
    #[serde(skip)]
    pub source: String,
}

fn one() -> f64 {
    1.0
}

/// The built-in maps: (name, file text).
const BUILTIN: [(&str, &str); 4] = [
    (
        "humanml3d",
        include_str!("../../data/skeletons/humanml3d.json"),
    ),
    ("kit", include_str!("../../data/skeletons/kit.json")),
    ("cmu_bvh", include_str!("../../data/skeletons/cmu_bvh.json")),
    (
        "c3d_lower_body",
        include_str!("../../data/skeletons/c3d_lower_body.json"),
    ),
];

impl SkeletonMap {
    /// Names of the built-in maps.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// A built-in map by name (`humanml3d`, `kit`, `cmu_bvh`).
    pub fn builtin(name: &str) -> crate::Result<SkeletonMap> {
        let (n, text) = BUILTIN.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            Error::invalid(
                "skeleton map",
                format!(
                    "no built-in map `{name}` (built in: {})",
                    Self::builtin_names().join(", ")
                ),
            )
        })?;
        Self::parse(text, &format!("data/skeletons/{n}.json"))
    }

    /// Reads a map file.
    pub fn read(path: &std::path::Path) -> crate::Result<SkeletonMap> {
        let text = crate::text::read_text(path)?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses map text; `source` names it in errors, with the line of the JSON key that
    /// holds the bad value (`"weight"` of the target, `"name"` of the segment, …).
    pub fn parse(text: &str, source: &str) -> crate::Result<SkeletonMap> {
        let table_error = |line: usize, message: String| Error::Table {
            table: source.to_string(),
            line,
            message,
        };
        let mut map: SkeletonMap =
            serde_json::from_str(text).map_err(|e| table_error(e.line().max(1), e.to_string()))?;
        map.source = source.to_string();
        // The n-th occurrence of a key, or the first line: a target is found by its
        // "marker" key and a segment by its "name" key, which only they have.
        let keys = KeyLines::new(text);
        let line = |key: &str, n: usize| keys.line(key, n);
        let det = map
            .axes_matrix()
            .map_err(|e| match e {
                Error::Table { table, message, .. } => Error::Table {
                    table,
                    line: line("axes", 0),
                    message,
                },
                other => other,
            })?
            .determinant();
        if det < 0.0 && !map.mirror {
            return Err(table_error(
                line("axes", 0),
                format!(
                    "axes {:?} mirror the motion (a left-handed input frame); say \"mirror\": \
                     true if that is meant",
                    map.axes
                ),
            ));
        }
        if !(map.scale > 0.0 && map.scale.is_finite()) {
            return Err(table_error(
                line("scale", 0),
                format!("scale {} must be positive", map.scale),
            ));
        }
        if map.targets.is_empty() {
            return Err(table_error(line("targets", 0), "no targets".into()));
        }
        for (i, t) in map.targets.iter().enumerate() {
            let at = line("marker", i);
            if t.source.is_empty() || t.source.iter().any(|s| s.trim().is_empty()) {
                return Err(table_error(at, format!("target {i}: empty source name")));
            }
            if !(t.weight >= 0.0 && t.weight.is_finite()) {
                return Err(table_error(
                    at,
                    format!(
                        "target {i} (`{}`): weight {} must be ≥ 0",
                        t.marker, t.weight
                    ),
                ));
            }
            if t.landmark && !t.placed {
                return Err(table_error(
                    at,
                    format!(
                        "target {i} (`{}`): \"landmark\" applies to placed targets only (add \
                         \"placed\": true, or leave the marker where the model has it)",
                        t.marker
                    ),
                ));
            }
            if let Some(j) = map.targets[..i].iter().position(|o| o.marker == t.marker) {
                return Err(table_error(
                    at,
                    format!("targets {j} and {i} both map onto marker `{}`", t.marker),
                ));
            }
        }
        for (k, seg) in map.segments.iter().enumerate() {
            let at = line("name", k);
            for name in seg.pairs.iter().flatten() {
                if !map.targets.iter().any(|t| &t.marker == name) {
                    return Err(table_error(
                        at,
                        format!(
                            "segment `{}`: `{name}` is not a target marker of the map",
                            seg.name
                        ),
                    ));
                }
            }
            if seg.axes.is_empty()
                || seg
                    .axes
                    .iter()
                    .any(|a| !["x", "y", "z"].contains(&a.as_str()))
            {
                return Err(table_error(
                    at,
                    format!(
                        "segment `{}`: axes {:?} must be among x, y, z",
                        seg.name, seg.axes
                    ),
                ));
            }
            if seg.bodies.is_empty() || seg.pairs.is_empty() {
                return Err(table_error(
                    at,
                    format!("segment `{}` needs bodies and pairs", seg.name),
                ));
            }
        }
        Ok(map)
    }

    /// A: p_model = A p_input (a signed permutation).
    pub fn axes_matrix(&self) -> crate::Result<Mat3> {
        let mut a = Mat3::zeros();
        let mut used = [false; 3];
        for (k, text) in self.axes.iter().enumerate() {
            let t = text.trim();
            let (sign, axis) = match t.strip_prefix('-') {
                Some(rest) => (-1.0, rest.trim()),
                None => (1.0, t.strip_prefix('+').unwrap_or(t).trim()),
            };
            let i = match axis {
                "x" | "X" => 0,
                "y" | "Y" => 1,
                "z" | "Z" => 2,
                _ => {
                    return Err(Error::Table {
                        table: self.source.clone(),
                        line: 0,
                        message: format!("axes[{k}] = `{text}`: expected x, y or z, optionally -"),
                    });
                }
            };
            if used[i] {
                return Err(Error::Table {
                    table: self.source.clone(),
                    line: 0,
                    message: format!("axes {:?} use input axis {axis} twice", self.axes),
                });
            }
            used[i] = true;
            a[(k, i)] = sign;
        }
        Ok(a)
    }

    /// For each target, the motion column of its source joint (None where absent).
    pub fn source_columns(&self, motion: &Motion) -> Vec<Option<usize>> {
        self.targets
            .iter()
            .map(|t| t.source.iter().find_map(|s| motion.index(s)))
            .collect()
    }

    /// Whether `motion` has every source joint of the map.
    pub fn matches(&self, motion: &Motion) -> bool {
        self.source_columns(motion).iter().all(Option::is_some)
    }

    /// The built-in map whose every source joint or marker `motion` has (the one with the
    /// most targets when several do), or None: how a marker file (C3D, TRC) that names no
    /// model marker finds its map without `--map`.
    pub fn builtin_matching(motion: &Motion) -> Option<SkeletonMap> {
        BUILTIN
            .iter()
            .filter_map(|(n, _)| Self::builtin(n).ok())
            .filter(|m| m.matches(motion))
            .max_by_key(|m| m.targets.len())
    }

    /// The targets in the model's frame and metres, one column per map target (named after
    /// its model marker), and the IK marker tasks pairing each with its model marker.
    pub fn apply(&self, model: &Model, motion: &Motion) -> crate::Result<(Motion, IkTasks)> {
        let columns = self.source_columns(motion);
        let missing: Vec<String> = self
            .targets
            .iter()
            .zip(&columns)
            .filter(|(_, c)| c.is_none())
            .map(|(t, _)| t.source.join(" or "))
            .collect();
        if !missing.is_empty() {
            return Err(Error::Motion {
                file: motion.source.clone(),
                location: "skeleton".into(),
                message: format!(
                    "does not match the skeleton map {} ({}): no joint {} (the motion has: {})",
                    self.source,
                    self.skeleton,
                    missing.join(", "),
                    motion.names.join(", ")
                ),
            });
        }
        let mut markers = Vec::with_capacity(self.targets.len());
        let mut absent = Vec::new();
        for t in &self.targets {
            match model.markers.iter().position(|m| m.name == t.marker) {
                Some(i) => markers.push(i),
                None => absent.push(t.marker.as_str()),
            }
        }
        if !absent.is_empty() {
            return Err(Error::invalid(
                "model",
                format!(
                    "model `{}` has no marker {} that the skeleton map {} needs",
                    model.name,
                    absent.join(", "),
                    self.source
                ),
            ));
        }
        let a = self.axes_matrix()? * self.scale;
        let n = self.targets.len();
        let mut positions = Vec::with_capacity(motion.n_frames() * n);
        for f in 0..motion.n_frames() {
            let frame = motion.frame(f);
            for c in &columns {
                let p: Vec3 = frame[c.expect("checked above")];
                positions.push(a * p);
            }
        }
        // The reader checked the body's height in its own unit; a map that scales again must
        // leave a person (`"scale": 100` on metres made a 170 m body, fitted with 50 m of
        // error under exit status 0).
        if self.scale != 1.0 {
            let height = super::humanml3d::implied_height(n, &positions);
            let [lo, hi] = super::PLAUSIBLE_HEIGHT_M;
            if !(lo..=hi).contains(&height) {
                return Err(Error::invalid(
                    "map",
                    format!(
                        "{}: the skeleton map {}'s scale {} (metres per input unit) makes the \
                         clip's body {} m tall, not a person's ({lo}–{hi} m)",
                        motion.source,
                        self.source,
                        crate::text::short_number(self.scale),
                        crate::text::short_number((height * 1e3).round() / 1e3)
                    ),
                ));
            }
        }
        let out = Motion {
            source: motion.source.clone(),
            names: self.targets.iter().map(|t| t.marker.clone()).collect(),
            rate_hz: motion.rate_hz,
            time: motion.time.clone(),
            positions,
        };
        let tasks = IkTasks {
            markers: self
                .targets
                .iter()
                .zip(markers)
                .enumerate()
                .map(|(k, (t, marker))| MarkerTask {
                    marker,
                    target: k,
                    weight: t.weight,
                })
                .collect(),
            coordinates: Vec::new(),
        };
        Ok((out, tasks))
    }
}

/// The 1-based lines of the object keys of a JSON text, in order (a string followed by `:`;
/// string contents, escapes included, are skipped, so a key quoted inside a description does
/// not count).
struct KeyLines<'t> {
    keys: Vec<(&'t str, usize)>,
}

impl<'t> KeyLines<'t> {
    fn new(text: &'t str) -> KeyLines<'t> {
        let bytes = text.as_bytes();
        let mut keys = Vec::new();
        let (mut i, mut line) = (0, 1);
        while i < bytes.len() {
            match bytes[i] {
                b'\n' => line += 1,
                b'"' => {
                    let start = i + 1;
                    i += 1;
                    while i < bytes.len() && bytes[i] != b'"' {
                        if bytes[i] == b'\\' {
                            i += 1;
                        } else if bytes[i] == b'\n' {
                            line += 1;
                        }
                        i += 1;
                    }
                    let end = i.min(bytes.len());
                    let next = bytes[end.saturating_add(1).min(bytes.len())..]
                        .iter()
                        .find(|b| !b.is_ascii_whitespace());
                    if next == Some(&b':') {
                        if let Some(key) = text.get(start..end) {
                            keys.push((key, line));
                        }
                    }
                }
                _ => {}
            }
            i += 1;
        }
        KeyLines { keys }
    }

    /// The line of the `n`-th (from 0) occurrence of `key`, or 1 when there are fewer.
    fn line(&self, key: &str, n: usize) -> usize {
        self.keys
            .iter()
            .filter(|(k, _)| *k == key)
            .nth(n)
            .map_or(1, |&(_, l)| l)
    }
}
