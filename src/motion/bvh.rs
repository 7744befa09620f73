//! Biovision Hierarchy (BVH) motion files: any skeleton, any channel layout, and the
//! joint-centre positions of every frame by forward kinematics.
//!
//! A BVH file is a `HIERARCHY` of joints — `ROOT name { OFFSET x y z  CHANNELS n c₁ … cₙ
//! JOINT … { … }  End Site { OFFSET x y z } }` — followed by `MOTION`, `Frames: N`,
//! `Frame Time: Δt` and N lines of channel values in hierarchy order (degrees for rotations,
//! file units for positions).
//!
//! Each joint's transform relative to its parent is its OFFSET followed by its channels
//! applied in the order they are listed (as the BVH definition, CMU's and most readers —
//! e.g. bvh11 and fairmotion — do):
//!
//! ```text
//! T_j = Trans(offset_j) · C₁ · C₂ · … · Cₙ,   C = Rot_axis(value·π/180) or Trans(axis·value)
//! T_world,j = T_world,parent(j) · T_j,          joint centre = origin of T_world,j
//! ```
//!
//! so `Zrotation Xrotation Yrotation` means R = R_z · R_x · R_y (intrinsic rotations in
//! channel order), and a position channel listed after rotations moves along the rotated
//! axes. Position channels add to the OFFSET; [`PositionChannels::ReplaceOffset`] is for
//! exporters that write the offset itself into every joint's position channels.
//! End sites (`End Site`) are positioned the same way with no channels, and named
//! `<parent>_end` (`<parent>_end2`, … if a joint has several).
//!
//! Units. BVH does not state its length unit: [`BvhOptions::unit`] does (default
//! centimetres, the unit of most BVH exports — Mixamo, MotionBuilder, LAFAN1). The CMU
//! database's BVH conversions keep the CMU skeletons' unit of 1/0.45 inch = 0.056444 m
//! (`LengthUnit::Custom(0.056444)`). The implied body height — the largest distance between
//! two joints or end sites in the rest pose (head to toe or fingertip to fingertip, ≈
//! stature) — must be a person's in the chosen unit ([`super::check_plausible_height`]), so a file read in the
//! wrong unit is refused with the unit that would fit.
//!
//! Errors name the file and the 1-based line for syntax errors, and the frame (and line) for
//! a wrong number of values or a non-finite one (or one beyond ±[`MAX_CHANNEL_VALUE`]).

use super::{LengthUnit, Motion, PLAUSIBLE_HEIGHT_M, check_plausible_height};
use crate::error::Error;
use crate::spatial::Vec3;
use nalgebra::Matrix3;
use std::path::Path;

/// The largest magnitude of a channel value (degrees, or file units for positions).
pub const MAX_CHANNEL_VALUE: f64 = 1e6;

/// One channel of a joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    Xposition,
    Yposition,
    Zposition,
    Xrotation,
    Yrotation,
    Zrotation,
}

impl Channel {
    /// Parses a channel name (`Xposition` … `Zrotation`, any letter case).
    pub fn parse(text: &str) -> Option<Channel> {
        Some(match text.to_ascii_lowercase().as_str() {
            "xposition" => Channel::Xposition,
            "yposition" => Channel::Yposition,
            "zposition" => Channel::Zposition,
            "xrotation" => Channel::Xrotation,
            "yrotation" => Channel::Yrotation,
            "zrotation" => Channel::Zrotation,
            _ => return None,
        })
    }

    /// The axis (0 = x, 1 = y, 2 = z).
    pub fn axis(self) -> usize {
        match self {
            Channel::Xposition | Channel::Xrotation => 0,
            Channel::Yposition | Channel::Yrotation => 1,
            Channel::Zposition | Channel::Zrotation => 2,
        }
    }

    pub fn is_rotation(self) -> bool {
        matches!(
            self,
            Channel::Xrotation | Channel::Yrotation | Channel::Zrotation
        )
    }
}

/// A joint or end site of the hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    pub name: String,
    /// Index of the parent in [`Bvh::joints`] (always smaller than this joint's); `None` for
    /// a root.
    pub parent: Option<usize>,
    /// OFFSET from the parent, in file units.
    pub offset: Vec3,
    /// Channels in file order (none for an end site).
    pub channels: Vec<Channel>,
    /// Column of the first channel in a frame's values.
    pub first_channel: usize,
    /// True for an `End Site`.
    pub end_site: bool,
    /// Line (1-based) where it is declared.
    pub line: usize,
}

/// A parsed BVH file, values as in the file (degrees, file units).
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    pub source: String,
    /// Joints and end sites in file order; parents precede children.
    pub joints: Vec<Joint>,
    /// `Frame Time` (s).
    pub frame_time: f64,
    /// Channels per frame.
    pub n_channels: usize,
    /// Frame-major channel values, `n_frames × n_channels`.
    pub values: Vec<f64>,
}

/// How position channels combine with a joint's OFFSET.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PositionChannels {
    /// Translation = OFFSET + channels (the BVH definition; bvh11, fairmotion).
    #[default]
    AddToOffset,
    /// Translation = channels alone, for joints that have position channels (exporters that
    /// write the offset into every joint's channels).
    ReplaceOffset,
}

/// How a BVH file becomes a [`Motion`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhOptions {
    /// The file's length unit (default centimetres; CMU conversions: `Custom(0.056444)`).
    pub unit: LengthUnit,
    /// Include end sites as targets (`<parent>_end`).
    pub end_sites: bool,
    pub position_channels: PositionChannels,
}

impl Default for BvhOptions {
    fn default() -> BvhOptions {
        BvhOptions {
            unit: LengthUnit::Centimetres,
            end_sites: false,
            position_channels: PositionChannels::AddToOffset,
        }
    }
}

/// The CMU skeletons' length unit, 1/0.45 inch (m).
pub const CMU_UNIT_M: f64 = 0.056444;

struct Token<'a> {
    text: &'a str,
    line: usize,
}

struct Parser<'a> {
    source: &'a str,
    tokens: Vec<Token<'a>>,
    at: usize,
    /// Line of the last token, for "unexpected end" messages.
    last_line: usize,
}

impl<'a> Parser<'a> {
    fn error(&self, line: usize, message: impl Into<String>) -> Error {
        Error::Motion {
            file: self.source.to_string(),
            location: format!("line {line}"),
            message: message.into(),
        }
    }

    fn next(&mut self, what: &str) -> crate::Result<&'a str> {
        match self.tokens.get(self.at) {
            Some(t) => {
                self.at += 1;
                Ok(t.text)
            }
            None => Err(self.error(
                self.last_line,
                format!("the hierarchy ends where {what} is expected (truncated file?)"),
            )),
        }
    }

    fn line(&self) -> usize {
        self.tokens
            .get(self.at.saturating_sub(1))
            .map_or(self.last_line, |t| t.line)
    }

    fn expect(&mut self, keyword: &str) -> crate::Result<()> {
        let t = self.next(&format!("'{keyword}'"))?;
        if t.eq_ignore_ascii_case(keyword) {
            Ok(())
        } else {
            Err(self.error(self.line(), format!("expected '{keyword}', found '{t}'")))
        }
    }

    fn number(&mut self, what: &str) -> crate::Result<f64> {
        let t = self.next(what)?;
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.error(self.line(), format!("{what}: '{t}' is not a finite number"))),
        }
    }

    fn offset(&mut self) -> crate::Result<Vec3> {
        self.expect("OFFSET")?;
        Ok(Vec3::new(
            self.number("OFFSET x")?,
            self.number("OFFSET y")?,
            self.number("OFFSET z")?,
        ))
    }

    /// The joint name: the rest of the keyword's line, up to a `{`.
    fn name(&mut self, keyword_line: usize) -> crate::Result<String> {
        let start = self.at;
        while self
            .tokens
            .get(self.at)
            .is_some_and(|t| t.line == keyword_line && t.text != "{")
        {
            self.at += 1;
        }
        let name = self.tokens[start..self.at]
            .iter()
            .map(|t| t.text)
            .collect::<Vec<_>>()
            .join(" ");
        if name.is_empty() {
            return Err(self.error(keyword_line, "joint without a name"));
        }
        Ok(name)
    }
}

fn is(token: &str, keyword: &str) -> bool {
    token.eq_ignore_ascii_case(keyword)
}

impl Bvh {
    /// Reads and parses a BVH file.
    pub fn read(path: &Path) -> crate::Result<Bvh> {
        let source = path.display().to_string();
        let text = crate::text::read_text(path)?;
        Bvh::parse(&text, &source)
    }

    /// Parses BVH text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> crate::Result<Bvh> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
        // The hierarchy's tokens, up to the MOTION line.
        let mut tokens = Vec::new();
        let mut motion_line = None;
        let mut last_line = 1;
        for (n, line) in lines.by_ref() {
            last_line = n;
            let mut words = line.split_ascii_whitespace().peekable();
            if words.peek().is_some_and(|w| is(w, "MOTION")) {
                motion_line = Some(n);
                break;
            }
            tokens.extend(words.map(|text| Token { text, line: n }));
        }
        let mut p = Parser {
            source,
            tokens,
            at: 0,
            last_line,
        };
        let joints = parse_hierarchy(&mut p)?;
        let Some(motion_line) = motion_line else {
            return Err(p.error(last_line, "no MOTION section (truncated file?)"));
        };
        let n_channels = joints.iter().map(|j| j.channels.len()).sum::<usize>();

        // "Frames: N" and "Frame Time: dt".
        let mut header = lines.by_ref().filter(|(_, l)| !l.trim().is_empty());
        let (n, line) = header
            .next()
            .ok_or_else(|| p.error(motion_line, "MOTION without 'Frames:' (truncated file?)"))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        let n_frames = match words.as_slice() {
            [k, v] if is(k, "Frames:") => v.parse::<usize>().ok(),
            _ => None,
        }
        .ok_or_else(|| {
            p.error(
                n,
                format!("expected 'Frames: <count>', found '{}'", line.trim()),
            )
        })?;
        let (n, line) = header
            .next()
            .ok_or_else(|| p.error(n, "'Frames:' without 'Frame Time:' (truncated file?)"))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        let frame_time = match words.as_slice() {
            [k1, k2, v] if is(k1, "Frame") && is(k2, "Time:") => v.parse::<f64>().ok(),
            _ => None,
        }
        .filter(|dt| *dt > 0.0 && dt.is_finite())
        .ok_or_else(|| {
            p.error(
                n,
                format!(
                    "expected 'Frame Time: <positive seconds>', found '{}'",
                    line.trim()
                ),
            )
        })?;
        if n_frames == 0 {
            return Err(p.error(n, "the file has no frames (Frames: 0)"));
        }

        // Frame values: one line per frame; never reserve more than the text can hold.
        // (each value takes at least two bytes, "0 ")
        let mut values =
            Vec::with_capacity(n_frames.saturating_mul(n_channels).min(text.len() / 2 + 1));
        let mut frame = 0;
        let mut last = n;
        for (n, line) in header {
            last = n;
            if frame == n_frames {
                return Err(p.error(
                    n,
                    format!("more frame lines than the {n_frames} that 'Frames:' declares"),
                ));
            }
            let start = values.len();
            for word in line.split_ascii_whitespace() {
                let column = values.len() - start;
                // within ±10⁶ (degrees, or file units): an angle of 10³⁰⁰° turned each
                // frame to a pseudo-random pose that IK then fitted
                match word.parse::<f64>() {
                    Ok(v) if v.abs() <= MAX_CHANNEL_VALUE => values.push(v),
                    _ => {
                        return Err(Error::Motion {
                            file: source.to_string(),
                            location: format!("frame {frame} (line {n})"),
                            message: format!(
                                "value {} ({}) '{word}' is not a finite number within \
                                 ±{MAX_CHANNEL_VALUE:e}",
                                column + 1,
                                channel_name(&joints, column)
                            ),
                        });
                    }
                }
            }
            let count = values.len() - start;
            if count != n_channels {
                return Err(Error::Motion {
                    file: source.to_string(),
                    location: format!("frame {frame} (line {n})"),
                    message: format!(
                        "{count} values where the hierarchy has {n_channels} channels"
                    ),
                });
            }
            frame += 1;
        }
        if frame < n_frames {
            return Err(p.error(
                last,
                format!(
                    "the file ends after {frame} of the {n_frames} frames declared (truncated?)"
                ),
            ));
        }
        Ok(Bvh {
            source: source.to_string(),
            joints,
            frame_time,
            n_channels,
            values,
        })
    }

    pub fn n_frames(&self) -> usize {
        self.values.len().checked_div(self.n_channels).unwrap_or(0)
    }

    /// Frames per second, 1/`Frame Time` — rounded to the nearest integer when within 10⁻⁴
    /// of it, since files write the frame time rounded (0.0083333 s for 120 Hz).
    pub fn rate_hz(&self) -> f64 {
        let rate = 1.0 / self.frame_time;
        if (rate - rate.round()).abs() <= 1e-4 * rate {
            rate.round()
        } else {
            rate
        }
    }

    /// A frame's channel values.
    pub fn frame(&self, f: usize) -> &[f64] {
        &self.values[f * self.n_channels..(f + 1) * self.n_channels]
    }

    /// Positions of every joint and end site in the rest pose (all channels zero; file
    /// units): the OFFSETs accumulated from the root.
    pub fn rest_pose(&self) -> Vec<Vec3> {
        let mut out: Vec<Vec3> = Vec::with_capacity(self.joints.len());
        for j in &self.joints {
            let base = j
                .parent
                .and_then(|p| out.get(p).copied())
                .unwrap_or_else(Vec3::zeros);
            out.push(base + j.offset);
        }
        out
    }

    /// The rest pose's largest distance between two joints or end sites (file units): head
    /// to toe or fingertip to fingertip, ≈ stature.
    pub fn implied_height(&self) -> f64 {
        super::humanml3d::frame_span(&self.rest_pose())
    }

    /// Forward kinematics of frame `f`: the position of every joint and end site (in
    /// [`Bvh::joints`] order) in file units times `scale` (metres per file unit).
    /// `out` and `rotations` (scratch: each joint's orientation) have `joints.len()` entries.
    pub fn forward_kinematics(
        &self,
        f: usize,
        scale: f64,
        position_channels: PositionChannels,
        rotations: &mut [Matrix3<f64>],
        out: &mut [Vec3],
    ) -> crate::Result<()> {
        let n = self.joints.len();
        if out.len() != n || rotations.len() != n {
            return Err(Error::invalid(
                "out",
                format!(
                    "{} positions and {} rotations for {n} joints",
                    out.len(),
                    rotations.len()
                ),
            ));
        }
        if f >= self.n_frames() {
            return Err(Error::invalid(
                "f",
                format!("frame {f} of {}", self.n_frames()),
            ));
        }
        let values = self.frame(f);
        for (j, joint) in self.joints.iter().enumerate() {
            // T_j = Trans(offset) · C₁ · … · Cₙ, accumulated as (R, p).
            let has_position = joint.channels.iter().any(|c| !c.is_rotation());
            let mut p = match position_channels {
                PositionChannels::ReplaceOffset if has_position => Vec3::zeros(),
                _ => joint.offset * scale,
            };
            let mut r = Matrix3::identity();
            for (k, &c) in joint.channels.iter().enumerate() {
                let v = values[joint.first_channel + k];
                if c.is_rotation() {
                    r *= axis_rotation(c.axis(), v.to_radians());
                } else {
                    // p += R · (e_axis · v)
                    p += r.column(c.axis()) * (v * scale);
                }
            }
            match joint.parent {
                Some(parent) => {
                    out[j] = out[parent] + rotations[parent] * p;
                    rotations[j] = rotations[parent] * r;
                }
                None => {
                    out[j] = p;
                    rotations[j] = r;
                }
            }
        }
        Ok(())
    }

    /// Joint-centre positions of every frame (metres), checked for a plausible body height
    /// in `options.unit`.
    pub fn to_motion(&self, options: &BvhOptions) -> crate::Result<Motion> {
        let scale = options.unit.metres();
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(Error::invalid(
                "unit",
                format!("{scale} m per unit must be positive"),
            ));
        }
        let height = self.implied_height() * scale;
        check_plausible_height(&self.source, height, options.unit)
            .map_err(|e| cmu_hint(e, height / scale))?;
        let keep: Vec<usize> = (0..self.joints.len())
            .filter(|&j| options.end_sites || !self.joints[j].end_site)
            .collect();
        let n_frames = self.n_frames();
        let mut positions = Vec::with_capacity(n_frames * keep.len());
        let mut rotations = vec![Matrix3::identity(); self.joints.len()];
        let mut frame = vec![Vec3::zeros(); self.joints.len()];
        for f in 0..n_frames {
            self.forward_kinematics(
                f,
                scale,
                options.position_channels,
                &mut rotations,
                &mut frame,
            )?;
            positions.extend(keep.iter().map(|&j| frame[j]));
        }
        let names = keep.iter().map(|&j| self.joints[j].name.clone()).collect();
        Motion::uniform(self.source.clone(), names, self.rate_hz(), positions)
    }
}

/// Adds the CMU unit to a wrong-unit error when it would make the skeleton a person's.
fn cmu_hint(e: Error, raw_height: f64) -> Error {
    let [lo, hi] = PLAUSIBLE_HEIGHT_M;
    let cmu = raw_height * CMU_UNIT_M;
    match e {
        Error::Motion {
            file,
            location,
            message,
        } if (lo..=hi).contains(&cmu) => Error::Motion {
            file,
            location,
            message: format!(
                "{message} (CMU BVH conversions use 1/0.45 inch = {CMU_UNIT_M} m per unit, \
                 which makes it {cmu:.2} m)"
            ),
        },
        e => e,
    }
}

/// Rot_axis(angle): x = 0, y = 1, z = 2, right-handed.
fn axis_rotation(axis: usize, angle: f64) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    match axis {
        0 => Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        1 => Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        _ => Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
    }
}

/// `joint "Hips" Xrotation` for a frame column, for messages.
fn channel_name(joints: &[Joint], column: usize) -> String {
    joints
        .iter()
        .find(|j| (j.first_channel..j.first_channel + j.channels.len()).contains(&column))
        .map(|j| {
            format!(
                "joint \"{}\" {:?}",
                j.name,
                j.channels[column - j.first_channel]
            )
        })
        .unwrap_or_else(|| "beyond the hierarchy's channels".into())
}

fn parse_hierarchy(p: &mut Parser) -> crate::Result<Vec<Joint>> {
    let first = p.next("'HIERARCHY'")?;
    if !is(first, "HIERARCHY") {
        return Err(p.error(p.line(), format!("expected 'HIERARCHY', found '{first}'")));
    }
    let mut joints: Vec<Joint> = Vec::new();
    // Every name given so far: a name is checked against it in constant time, so a
    // hierarchy of n joints is read in O(n), however deep or wide.
    let mut names: std::collections::HashSet<String> = std::collections::HashSet::new();
    // Open joints (indices into `joints`), innermost last.
    let mut open: Vec<usize> = Vec::new();
    let mut n_channels = 0usize;
    while p.at < p.tokens.len() {
        let line = p.tokens[p.at].line;
        let t = p.next("a keyword")?;
        if is(t, "ROOT") || is(t, "JOINT") {
            let root = is(t, "ROOT");
            if root != open.is_empty() {
                return Err(p.error(
                    line,
                    if root {
                        "ROOT inside a joint"
                    } else {
                        "JOINT outside a ROOT"
                    },
                ));
            }
            check_hierarchy_size(p, line, joints.len(), open.len())?;
            let name = p.name(line)?;
            if !names.insert(name.clone()) {
                return Err(p.error(line, format!("duplicate joint name \"{name}\"")));
            }
            p.expect("{")?;
            let offset = p.offset()?;
            let mut channels = Vec::new();
            if p.tokens.get(p.at).is_some_and(|t| is(t.text, "CHANNELS")) {
                p.at += 1;
                let count = p.next("the channel count")?;
                let count: usize = count.parse().map_err(|_| {
                    p.error(
                        p.line(),
                        format!("channel count '{count}' is not a whole number"),
                    )
                })?;
                for _ in 0..count {
                    let c = p.next("a channel name")?;
                    channels.push(Channel::parse(c).ok_or_else(|| {
                        p.error(
                            p.line(),
                            format!("unknown channel '{c}' (Xposition … Zrotation expected)"),
                        )
                    })?);
                }
            }
            joints.push(Joint {
                name,
                parent: open.last().copied(),
                offset,
                first_channel: n_channels,
                end_site: false,
                line,
                channels,
            });
            n_channels += joints[joints.len() - 1].channels.len();
            open.push(joints.len() - 1);
        } else if is(t, "End") {
            p.expect("Site")?;
            let Some(&parent) = open.last() else {
                return Err(p.error(line, "End Site outside a joint"));
            };
            p.expect("{")?;
            let offset = p.offset()?;
            p.expect("}")?;
            // an end site closes at once: it counts as a joint, not as a level
            check_hierarchy_size(p, line, joints.len(), 0)?;
            let base = format!("{}_end", joints[parent].name);
            let mut name = base.clone();
            let mut k = 2;
            while !names.insert(name.clone()) {
                name = format!("{base}{k}");
                k += 1;
            }
            joints.push(Joint {
                name,
                parent: Some(parent),
                offset,
                channels: Vec::new(),
                first_channel: n_channels,
                end_site: true,
                line,
            });
        } else if t == "}" {
            if open.pop().is_none() {
                return Err(p.error(line, "'}' without an open joint"));
            }
        } else {
            return Err(p.error(
                line,
                format!("unexpected '{t}' (ROOT, JOINT, End Site, '}}' or MOTION expected)"),
            ));
        }
    }
    if let Some(&j) = open.last() {
        return Err(p.error(
            p.last_line,
            format!(
                "joint \"{}\" (line {}) is not closed before MOTION",
                joints[j].name, joints[j].line
            ),
        ));
    }
    if joints.is_empty() {
        return Err(p.error(p.last_line, "the hierarchy has no joints"));
    }
    Ok(joints)
}

/// Refuses one more joint (or end site) at nesting depth `depth` beyond
/// [`crate::limits::MAX_BVH_JOINTS`] or [`crate::limits::MAX_BVH_DEPTH`].
fn check_hierarchy_size(p: &Parser, line: usize, joints: usize, depth: usize) -> crate::Result<()> {
    use crate::limits::{MAX_BVH_DEPTH, MAX_BVH_JOINTS};
    let over = if joints >= MAX_BVH_JOINTS {
        format!(
            "the hierarchy has more than {MAX_BVH_JOINTS} joints and end sites \
             (musculo::limits::MAX_BVH_JOINTS)"
        )
    } else if depth >= MAX_BVH_DEPTH {
        format!(
            "the hierarchy nests deeper than {MAX_BVH_DEPTH} joints \
             (musculo::limits::MAX_BVH_DEPTH)"
        )
    } else {
        return Ok(());
    };
    Err(crate::limits::exceeded(
        p.source,
        &format!("line {line}"),
        over,
    ))
}

/// Reads a BVH file's joint-centre positions.
pub fn read(path: &Path, options: &BvhOptions) -> crate::Result<Motion> {
    Bvh::read(path)?.to_motion(options)
}

/// Parses BVH text (`source` names it in errors) into joint-centre positions.
pub fn parse(text: &str, source: &str, options: &BvhOptions) -> crate::Result<Motion> {
    Bvh::parse(text, source)?.to_motion(options)
}
