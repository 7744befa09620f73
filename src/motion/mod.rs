//! Motion inputs: readers that turn a motion file into a [`Motion`] — named 3-D targets
//! (joint centres or markers) over time, in metres, in the axes of the file — and the
//! skeleton maps that say which model marker each target stands for.
//!
//! | format | module | what it holds |
//! |---|---|---|
//! | HumanML3D `new_joints` / `new_joint_vecs` `.npy` | [`humanml3d`] | 22 SMPL joint centres, y up, 20 fps |
//! | KIT-ML joints `.npy` | [`kit`] | 21 KIT joint centres, 12.5 fps |
//! | BVH | [`bvh`] | any hierarchy; joint centres by forward kinematics |
//! | C3D | [`c3d`] | markers with gaps, analog channels, force platforms |
//! | TRC | [`crate::io::trc`] | markers ([`Motion::from_trc`]) |
//!
//! A target missing in a frame (a marker gap) has NaN coordinates; everything else is finite.
//! Axes stay those of the file: [`skeleton::SkeletonMap`] converts them to the model's.

pub mod bvh;
pub mod c3d;
pub mod calibration;
pub mod humanml3d;
pub mod kit;
pub mod npy;
pub mod skeleton;
pub mod tasks;

use crate::error::Error;
use crate::io::trc::Trc;
use crate::spatial::Vec3;
use crate::text::short_number;
use std::path::Path;

/// The motion file formats [`read`] knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// HumanML3D `new_joints` (T×22×3) or `new_joint_vecs` (T×263) `.npy`, told apart by
    /// shape.
    HumanMl3d,
    /// KIT-ML joints (T×21×3) or features (T×251) `.npy`.
    Kit,
    Bvh,
    C3d,
    Trc,
}

impl Format {
    /// Parses `humanml3d`, `kit`, `bvh`, `c3d`, `trc`.
    pub fn parse(text: &str) -> crate::Result<Format> {
        Ok(match text.to_ascii_lowercase().as_str() {
            "humanml3d" => Format::HumanMl3d,
            "kit" | "kit-ml" | "kitml" => Format::Kit,
            "bvh" => Format::Bvh,
            "c3d" => Format::C3d,
            "trc" => Format::Trc,
            _ => {
                return Err(Error::invalid(
                    "format",
                    format!("`{text}`: expected humanml3d, kit, bvh, c3d or trc"),
                ));
            }
        })
    }

    /// The format of a file from its extension and, for `.npy`, its array shape (22 joints
    /// or 263 features: HumanML3D; 21 joints or 251 features: KIT-ML).
    pub fn detect(path: &Path) -> crate::Result<Format> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "bvh" => Ok(Format::Bvh),
            "c3d" => Ok(Format::C3d),
            "trc" => Ok(Format::Trc),
            "npy" => {
                let array = npy::read_array_as_f64(path)?;
                match array.shape() {
                    [_, 22, 3] | [_, humanml3d::N_FEATURES] => Ok(Format::HumanMl3d),
                    [_, 21, 3] | [_, kit::N_FEATURES] => Ok(Format::Kit),
                    shape => Err(Error::Motion {
                        file: path.display().to_string(),
                        location: "array shape".into(),
                        message: format!(
                            "{}: neither HumanML3D (T×22×3, T×{}) nor KIT-ML (T×21×3, T×{}); \
                             give --format",
                            npy::shape_text(shape),
                            humanml3d::N_FEATURES,
                            kit::N_FEATURES
                        ),
                    }),
                }
            }
            _ => Err(Error::Motion {
                file: path.display().to_string(),
                location: "file name".into(),
                message: "unknown motion file type (expected .npy, .bvh, .c3d or .trc)".into(),
            }),
        }
    }

    /// Refuses a format that another one's file extension contradicts (`--format bvh` on an
    /// `.npy` file), where reading would fail on the first bytes with a message about them;
    /// a file of another extension (a BVH saved as `.txt`) is left to the reader.
    pub fn check_extension(self, path: &Path) -> crate::Result<()> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let (formats, what): (&[Format], &str) = match ext.as_str() {
            "npy" => (
                &[Format::HumanMl3d, Format::Kit],
                "a NumPy array (HumanML3D or KIT-ML)",
            ),
            "bvh" => (&[Format::Bvh], "a BVH file"),
            "c3d" => (&[Format::C3d], "a C3D file"),
            "trc" => (&[Format::Trc], "a TRC file"),
            _ => return Ok(()),
        };
        if formats.contains(&self) {
            return Ok(());
        }
        Err(Error::Motion {
            file: path.display().to_string(),
            location: "file name".into(),
            message: format!(
                "read as {} (--format), but `.{ext}` names {what}; leave --format out to \
                 detect each file's format, or give the one this file has",
                self.name()
            ),
        })
    }

    /// The format's name as [`Format::parse`] takes it.
    pub fn name(self) -> &'static str {
        match self {
            Format::HumanMl3d => "humanml3d",
            Format::Kit => "kit",
            Format::Bvh => "bvh",
            Format::C3d => "c3d",
            Format::Trc => "trc",
        }
    }

    /// The built-in skeleton map of the format (None: markers matched by name).
    pub fn default_map(self) -> Option<&'static str> {
        match self {
            Format::HumanMl3d => Some("humanml3d"),
            Format::Kit => Some("kit"),
            Format::Bvh => Some("cmu_bvh"),
            Format::C3d | Format::Trc => None,
        }
    }
}

/// Options of [`read`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// The length unit of BVH and KIT files (default: each reader's; see [`bvh`], [`kit`]).
    pub length_unit: Option<LengthUnit>,
}

/// Reads any supported motion file as a [`Motion`] (format given or detected). C3D markers
/// come rotated from the z-up lab frame into OpenSim's y-up frame ([`c3d::lab_to_opensim`]),
/// as OpenSim users rotate them; TRC files are in their model's frame already.
///
/// What the reader accepted but reported (a `.trc` frame repeating a time, left out) is
/// dropped here; [`read_with_warnings`] returns it.
pub fn read(path: &Path, format: Option<Format>, options: &ReadOptions) -> crate::Result<Motion> {
    read_with_warnings(path, format, options).map(|(motion, _)| motion)
}

/// [`read`], with what the reader accepted but reported (today only `.trc` files report:
/// frames repeating the previous time, left out).
pub fn read_with_warnings(
    path: &Path,
    format: Option<Format>,
    options: &ReadOptions,
) -> crate::Result<(Motion, Vec<crate::io::FileWarning>)> {
    let format = match format {
        Some(f) => {
            f.check_extension(path)?;
            f
        }
        None => Format::detect(path)?,
    };
    let motion = match format {
        Format::HumanMl3d => {
            let mut o = humanml3d::Options::default();
            if let Some(u) = options.length_unit {
                o.unit = u;
            }
            humanml3d::read(path, &o)
        }
        Format::Kit => {
            let o = kit::Options {
                unit: options.length_unit,
                ..kit::Options::default()
            };
            kit::read(path, &o)
        }
        Format::Bvh => {
            let mut o = bvh::BvhOptions::default();
            if let Some(u) = options.length_unit {
                o.unit = u;
            }
            bvh::read(path, &o)
        }
        Format::C3d => {
            let file = c3d::C3d::read(path)?;
            let mut markers = file.markers.ok_or_else(|| Error::Motion {
                file: path.display().to_string(),
                location: "POINT".into(),
                message: "the file has no marker points".into(),
            })?;
            for p in &mut markers.positions {
                *p = c3d::lab_to_opensim(p);
            }
            // the reader converted POINT:UNITS to metres
            markers.check_marker_spread("the POINT:UNITS parameter", "POINT", 1.0)?;
            Ok(markers)
        }
        Format::Trc => {
            let trc = Trc::read(path)?;
            let motion = Motion::from_trc(&trc, &path.display().to_string())?;
            return Ok((motion, trc.warnings));
        }
    };
    Ok((motion?, Vec::new()))
}

/// Named 3-D targets over time.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Where it was read from (a path), for messages.
    pub source: String,
    /// Target names (joints or markers), unique.
    pub names: Vec<String>,
    /// Sampling rate (Hz).
    pub rate_hz: f64,
    /// Time of each frame (s), strictly increasing.
    pub time: Vec<f64>,
    /// Frame-major positions (m): `positions[f * names.len() + i]`; NaN where missing.
    pub positions: Vec<Vec3>,
}

/// The frame rates a motion may have. Capture systems record markers at up to a few kHz;
/// a BVH `Frame Time: 1e-9` (1 GHz) turned a squat's accelerations into 10¹⁹ m/s², and a
/// frame every 10⁹ s failed in the low-pass filter with a message about the cutoff.
pub const MIN_RATE_HZ: f64 = 0.01;
pub const MAX_RATE_HZ: f64 = 1e5;

impl Motion {
    /// A motion sampled at `rate_hz` from time 0, checked with [`Motion::validate`].
    pub fn uniform(
        source: impl Into<String>,
        names: Vec<String>,
        rate_hz: f64,
        positions: Vec<Vec3>,
    ) -> crate::Result<Motion> {
        let source = source.into();
        if !(rate_hz > 0.0 && rate_hz.is_finite()) {
            return Err(Error::Motion {
                file: source,
                location: "frame rate".into(),
                message: format!("{rate_hz} Hz must be positive and finite"),
            });
        }
        let frames = positions.len().checked_div(names.len()).unwrap_or(0);
        let time = (0..frames).map(|f| f as f64 / rate_hz).collect();
        let m = Motion {
            source,
            names,
            rate_hz,
            time,
            positions,
        };
        m.validate()?;
        Ok(m)
    }

    pub fn n_frames(&self) -> usize {
        self.time.len()
    }

    pub fn n_targets(&self) -> usize {
        self.names.len()
    }

    /// The targets of frame `f`.
    pub fn frame(&self, f: usize) -> &[Vec3] {
        let n = self.names.len();
        &self.positions[f * n..(f + 1) * n]
    }

    /// Index of the named target.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Duration from the first to the last frame (s).
    pub fn duration(&self) -> f64 {
        match (self.time.first(), self.time.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    fn error(&self, location: String, message: String) -> Error {
        Error::Motion {
            file: self.source.clone(),
            location,
            message,
        }
    }

    /// Checks sizes, unique non-empty names, a positive rate, finite strictly increasing
    /// times, and positions that are finite or NaN (missing) — never infinite, never beyond
    /// ±[`MAX_MARKER_COORDINATE`](crate::io::trc::MAX_MARKER_COORDINATE) m, and never
    /// partly missing (a target is missing in all three coordinates or in none).
    pub fn validate(&self) -> crate::Result<()> {
        let n = self.names.len();
        if n == 0 {
            return Err(self.error("targets".into(), "the motion has no targets".into()));
        }
        if self.time.is_empty() {
            return Err(self.error("frames".into(), "the motion has no frames".into()));
        }
        if self.positions.len() != self.time.len() * n {
            return Err(self.error(
                "array shape".into(),
                format!(
                    "{} positions for {} frames × {n} targets",
                    self.positions.len(),
                    self.time.len()
                ),
            ));
        }
        for (i, name) in self.names.iter().enumerate() {
            if name.trim().is_empty() {
                return Err(self.error(format!("target {i}"), "empty name".into()));
            }
            if let Some(j) = self.names[..i].iter().position(|o| o == name) {
                return Err(self.error(
                    format!("target \"{name}\""),
                    format!("duplicate name (targets {j} and {i})"),
                ));
            }
        }
        if !(MIN_RATE_HZ..=MAX_RATE_HZ).contains(&self.rate_hz) {
            return Err(self.error(
                "frame rate".into(),
                format!(
                    "{} Hz (a frame every {} s) is not a motion capture's: give a rate from \
                     {MIN_RATE_HZ} to {MAX_RATE_HZ:e} Hz",
                    short_number(self.rate_hz),
                    short_number(1.0 / self.rate_hz)
                ),
            ));
        }
        for (f, t) in self.time.iter().enumerate() {
            if !t.is_finite() || (f > 0 && *t <= self.time[f - 1]) {
                return Err(self.error(
                    format!("frame {f}"),
                    format!("time {t} is not finite or does not increase"),
                ));
            }
        }
        for (k, p) in self.positions.iter().enumerate() {
            let nan = p.iter().filter(|v| v.is_nan()).count();
            if p.iter().any(|v| v.is_infinite()) || (nan != 0 && nan != 3) {
                return Err(self.error(
                    format!("frame {}, target \"{}\"", k / n, self.names[k % n]),
                    format!(
                        "position ({}, {}, {}) is infinite or partly missing",
                        p.x, p.y, p.z
                    ),
                ));
            }
            // NaN (missing) passes: only a present coordinate is compared
            if p.amax() > crate::io::trc::MAX_MARKER_COORDINATE {
                return Err(self.error(
                    format!("frame {}, target \"{}\"", k / n, self.names[k % n]),
                    format!(
                        "position ({}, {}, {}) m is beyond ±{:e} m, which no capture volume \
                         reaches: a corrupt value or a wrong length unit",
                        short_number(p.x),
                        short_number(p.y),
                        short_number(p.z),
                        crate::io::trc::MAX_MARKER_COORDINATE
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Per target, the number of frames in which it is missing.
    pub fn missing_counts(&self) -> Vec<usize> {
        let n = self.names.len();
        let mut out = vec![0; n];
        for (k, p) in self.positions.iter().enumerate() {
            if p.x.is_nan() {
                out[k % n] += 1;
            }
        }
        out
    }

    /// The markers of a `.trc` file (already in metres).
    pub fn from_trc(trc: &Trc, source: &str) -> crate::Result<Motion> {
        let m = Motion {
            source: source.to_string(),
            names: trc.markers.clone(),
            rate_hz: trc.data_rate,
            time: trc.time.clone(),
            positions: trc.positions.clone(),
        };
        m.validate()?;
        m.check_marker_spread(
            &format!("the header's Units `{}`", trc.units.symbol()),
            "header \"Units\"",
            1.0 / trc.units.per_metre(),
        )?;
        Ok(m)
    }

    /// Per frame, the diagonal of the box holding its markers (m), for frames with at least
    /// two markers present; the median over frames (robust to a mislabelled marker).
    pub fn marker_spread(&self) -> Option<f64> {
        let mut diagonals: Vec<f64> = (0..self.n_frames())
            .filter_map(|f| {
                let present = self.frame(f).iter().filter(|p| !p[0].is_nan());
                let (mut lo, mut hi, mut count) =
                    (Vec3::repeat(f64::INFINITY), -Vec3::repeat(f64::INFINITY), 0);
                for p in present {
                    lo = lo.inf(p);
                    hi = hi.sup(p);
                    count += 1;
                }
                (count >= 2).then(|| (hi - lo).norm())
            })
            .collect();
        if diagonals.is_empty() {
            return None;
        }
        diagonals.sort_by(f64::total_cmp);
        Some(diagonals[diagonals.len() / 2])
    }

    /// Refuses markers whose spread ([`Motion::marker_spread`]) is not a body's
    /// ([`PLAUSIBLE_MARKER_SPREAD_M`]) in the unit the file states (`unit`, described as
    /// `stated`, `metres_per_unit` metres): the markers of millimetre data under a header of
    /// `m` were fitted 966 m away under exit 0, and markers all at the origin were fitted
    /// with 123 mm errors and called "ok". The data are not rescaled: the file is wrong.
    /// Files with fewer than two markers in every frame are not judged.
    pub fn check_marker_spread(
        &self,
        stated: &str,
        location: &str,
        metres_per_unit: f64,
    ) -> crate::Result<()> {
        let Some(spread) = self.marker_spread() else {
            return Ok(());
        };
        let [lo, hi] = PLAUSIBLE_MARKER_SPREAD_M;
        if (lo..=hi).contains(&spread) {
            return Ok(());
        }
        if spread == 0.0 {
            return Err(self.error(
                location.into(),
                "every marker lies on the same point in every frame (spread 0 m): there is \
                 no body to fit"
                    .into(),
            ));
        }
        let raw = spread / metres_per_unit;
        let suggestion = [("m", 1.0), ("cm", 0.01), ("mm", 0.001)]
            .iter()
            .find(|(_, m)| (lo..=hi).contains(&(raw * m)))
            .map(|(name, m)| format!("; in {name} it would be {:.2} m", raw * m))
            .unwrap_or_default();
        Err(self.error(
            location.into(),
            format!(
                "the markers span {} m in a frame (the median over frames, read in {stated}), \
                 not a body's {lo}–{hi} m: a wrong length unit?{suggestion}",
                if (1e-3..1e6).contains(&spread) {
                    format!("{spread:.3}")
                } else {
                    format!("{spread:.3e}")
                }
            ),
        ))
    }

    /// The frames whose time lies in `[start, end]` (inclusive, with a tolerance of a
    /// thousandth of a frame), as OpenSim's tools select a time range.
    pub fn time_window(&self, start: f64, end: f64) -> crate::Result<Motion> {
        let tol = 1e-3 / self.rate_hz;
        let frames: Vec<usize> = (0..self.n_frames())
            .filter(|&f| self.time[f] >= start - tol && self.time[f] <= end + tol)
            .collect();
        if frames.is_empty() {
            return Err(self.error(
                "time range".into(),
                format!(
                    "no frame lies in [{start}, {end}] (the motion covers [{}, {}])",
                    self.time[0],
                    self.time[self.n_frames() - 1]
                ),
            ));
        }
        let mut out = Motion {
            source: self.source.clone(),
            names: self.names.clone(),
            rate_hz: self.rate_hz,
            time: Vec::with_capacity(frames.len()),
            positions: Vec::with_capacity(frames.len() * self.n_targets()),
        };
        for f in frames {
            out.time.push(self.time[f]);
            out.positions.extend_from_slice(self.frame(f));
        }
        Ok(out)
    }
}

/// Length units of motion files that do not state theirs (BVH offsets, KIT joints).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LengthUnit {
    Metres,
    Centimetres,
    Millimetres,
    Inches,
    /// Any other unit, as metres per file unit (the CMU skeletons' unit is 1/0.45 inch =
    /// 0.056444 m, which many CMU BVH conversions keep).
    Custom(f64),
}

impl LengthUnit {
    /// Metres per file unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metres => 1.0,
            LengthUnit::Centimetres => 0.01,
            LengthUnit::Millimetres => 0.001,
            LengthUnit::Inches => 0.0254,
            LengthUnit::Custom(m) => m,
        }
    }

    /// Parses `m`, `cm`, `mm`, `in`, or a number of metres per unit from 10⁻⁶ (a micrometre)
    /// to 10³ (a kilometre): outside, no recording's unit (10³⁰⁰ overflowed the body's size,
    /// which then read as 0 m).
    pub fn parse(text: &str) -> Option<LengthUnit> {
        match text.trim().to_ascii_lowercase().as_str() {
            "m" | "metre" | "metres" | "meter" | "meters" => Some(LengthUnit::Metres),
            "cm" => Some(LengthUnit::Centimetres),
            "mm" => Some(LengthUnit::Millimetres),
            "in" | "inch" | "inches" => Some(LengthUnit::Inches),
            t => t
                .parse::<f64>()
                .ok()
                .filter(|v| (1e-6..=1e3).contains(v))
                .map(LengthUnit::Custom),
        }
    }
}

/// Standing-height bounds (m) a motion's implied body height must lie in: a clip whose
/// skeleton is 17 m or 17 mm tall was read in the wrong units.
pub const PLAUSIBLE_HEIGHT_M: [f64; 2] = [0.5, 2.6];

/// The markers' spread in a frame ([`Motion::marker_spread`], m) a recording of a person may
/// have: from a limb's few markers (0.2 m) to a tall adult's full set with raised arms.
pub const PLAUSIBLE_MARKER_SPREAD_M: [f64; 2] = [0.2, 2.5];

/// Checks that `height` (m, implied by the skeleton read in `unit`) is a human's; the error
/// names the unit that would make it one.
pub fn check_plausible_height(source: &str, height: f64, unit: LengthUnit) -> crate::Result<()> {
    let [lo, hi] = PLAUSIBLE_HEIGHT_M;
    if height >= lo && height <= hi {
        return Ok(());
    }
    if height == 0.0 {
        // no unit makes a body of this: the joints all lie on one point
        return Err(Error::Motion {
            file: source.to_string(),
            location: "skeleton".into(),
            message: "every joint lies on the same point in every frame (implied body height \
                      0 m): there is no skeleton to fit"
                .into(),
        });
    }
    let raw = height / unit.metres();
    // The unit that makes the skeleton closest to an adult's 1.7 m.
    let suggestion = [
        ("metres (m)", 1.0),
        ("centimetres (cm)", 0.01),
        ("millimetres (mm)", 0.001),
        ("inches (in)", 0.0254),
        ("the CMU unit, 1/0.45 inch (0.056444)", 0.056444),
    ]
    .iter()
    .filter(|(_, m)| (lo..=hi).contains(&(raw * m)))
    .min_by(|a, b| {
        ((raw * a.1) / 1.7)
            .ln()
            .abs()
            .total_cmp(&((raw * b.1) / 1.7).ln().abs())
    })
    .map(|(name, m)| format!("; read in {name} it would be {:.2} m", raw * m))
    .unwrap_or_default();
    Err(Error::Motion {
        file: source.to_string(),
        location: "skeleton".into(),
        message: format!(
            "implied body height {} m is not a person's ({lo}–{hi} m): wrong length unit \
             ({} m per file unit)?{suggestion}",
            if (1e-3..1e6).contains(&height) {
                format!("{height:.3}")
            } else {
                format!("{height:.3e}")
            },
            short_number(unit.metres())
        ),
    })
}
