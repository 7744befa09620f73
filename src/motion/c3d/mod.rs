//! C3D motion-capture files: markers with gaps, analog channels, and force platforms of
//! types 1–4 turned into force, moment, centre of pressure and free moment.
//!
//! # The format
//!
//! A C3D file is a sequence of 512-byte blocks: a header block, a parameter section
//! (`GROUP:NAME` parameters such as `POINT:LABELS`, `ANALOG:SCALE`, `FORCE_PLATFORM:CORNERS`)
//! and a data section. Numbers are stored in the writing processor's format — Intel, DEC
//! (VAX floats) or MIPS (big-endian) — all three are read. Each 3-D frame holds, for every
//! point, X, Y, Z and a residual word (16-bit integers × `POINT:SCALE`, or 32-bit floats when
//! the scale is negative), followed by `ANALOG` samples: `n` subframes × the channels.
//!
//! * **Markers.** A point sample is missing when its residual word is negative (the sign bit
//!   of the fourth value, as ezc3d reads it); its coordinates are then NaN. Positions are
//!   converted from `POINT:UNITS` (mm, cm, m, in) to metres; one beyond ±1e6 m is an error
//!   naming frame and marker, as in `.trc` files. Points listed in `POINT:ANGLES`,
//!   `FORCES`, `MOMENTS`, `POWERS`, `SCALARS` or `REACTIONS` (model outputs that Vicon stores
//!   as points, in other units) are not markers and are left out, as OpenSim does.
//! * **Analog.** value = (raw − `OFFSET`) × `SCALE` × `GEN_SCALE` per channel, in the
//!   channel's `ANALOG:UNITS` (raw read as unsigned when `ANALOG:FORMAT` is `UNSIGNED`); the
//!   rate is the frame rate × samples per frame. (ezc3d subtracts |OFFSET|; the manual's signed
//!   offset is used here. Both files of the reference set have zero offsets.)
//! * **Force platforms.** From the channels listed in `FORCE_PLATFORM:CHANNEL`, per
//!   `FORCE_PLATFORM:TYPE`, in plate axes:
//!   - type 1: Fx, Fy, Fz, COPx, COPy (from the surface centre), Tz;
//!     M = r_cop × F + (0, 0, Tz);
//!   - type 2: Fx, Fy, Fz, Mx, My, Mz about the transducer origin;
//!   - type 3 (Kistler, 8 channels fx12, fx34, fy14, fy23, fz1…fz4, `ORIGIN` = a, b, az0):
//!     F = (fx12 + fx34, fy14 + fy23, Σfz); Mx = b(fz1 + fz2 − fz3 − fz4),
//!     My = a(−fz1 + fz2 + fz3 − fz4), Mz = b(fx34 − fx12) + a(fy14 − fy23); the COP
//!     correction `FPCOPPOLY` is applied when present;
//!   - type 4: (F, M) = `CAL_MATRIX` · channels (first index of `CAL_MATRIX` = row).
//!
//!   Force channels must be in N (or have no unit); moment channels in N·m, N·cm or N·mm,
//!   or without a unit, then taken as N × `POINT:UNITS` (ezc3d's assumption, also made for
//!   the outputs of a type-4 calibration matrix); type-1 COP channels in a length unit or
//!   `POINT:UNITS`. `CORNERS` and `ORIGIN` are in `POINT:UNITS`.
//!
//!   The moment is moved from the transducer origin to the centre of the working surface:
//!   M_c = M_o + F × r, with r = −`ORIGIN` when `ORIGIN`'s z is positive (the C3D
//!   convention: plate z points down, the origin lies below the surface) and `ORIGIN` as
//!   stored otherwise (ezc3d's rule); for type 3, r = (0, 0, −|az0|). Then
//!   COP = (−M_c,y / Fz, M_c,x / Fz, 0) and the free moment T = M_c + F × COP. Plate axes
//!   come from the corners c₁…c₄: x ∥ c₁ − c₂, z ∥ x × (c₁ − c₄), y = z × x; lab values are
//!   R · (plate value), plus the surface centre (mean of the corners) for the COP.
//!
//! These are ezc3d's definitions (`ezc3d::Modules::ForcePlatform`, read by OpenSim's
//! C3DFileAdapter), so [`ForcePlate`] values match `ezc3d.c3d(path,
//! extract_forceplat_data=True)`: the force channels rotated into the lab frame and not
//! negated (in the reference trials, and as OpenSim uses them, the ground reaction on the
//! subject: +z, about body weight, in stance), the moment about the surface centre (not the
//! transducer origin), at every analog sample, with no threshold on
//! Fz (the COP of an unloaded plate is meaningless and can be metres away; it is NaN only
//! where Fz is exactly 0). Two deliberate differences, for types the reference files do not
//! contain: the type-1 moment has the physical sign (ezc3d 1.5 writes −(r × F + Tz)), and for
//! type 3 the sensor offsets a, b are used as stored (ezc3d negates them too when az0 > 0).
//! `FORCE_PLATFORM:ZERO` (baseline samples) is not applied, as by ezc3d.
//!
//! # Frames
//!
//! Positions stay in the lab frame of the file. Gait labs, and the reference files, use a
//! z-up lab frame; OpenSim models are y-up. [`lab_to_opensim`] is the rotation OpenSim's own
//! C3D examples apply (−90° about x: x → x, y → −z, z → y); [`markers_to_opensim`] and
//! [`C3d::ground_reactions`] use it.
//!
//! # Errors
//!
//! Every problem is an [`Error::Motion`] naming the file and where: `header`,
//! `parameter section, byte N`, `parameter POINT:LABELS`, `force platform 2`, `frame 812`
//! (0-based, as in [`Motion`]). A truncated file is an error naming the first incomplete
//! frame, never a shorter motion; no input makes the reader panic, and what it allocates is
//! at most a fixed multiple (about 50) of the file's length.
//!
//! # Why not the `c3dio` crate
//!
//! c3dio 0.8.0 reads the markers of the reference files correctly (≤ 5e-7 mm, gaps at the
//! same samples as ezc3d), but (a) single-byte changes to the header or parameters make it
//! panic (slice indices out of range, e.g. a parameter-block number of 0) or abort the
//! process on a multi-gigabyte allocation (an analog-subframe count of 32776), which
//! `catch_unwind` cannot guard; (b) it reads a truncated file as a shorter one, without an
//! error; (c) its force-platform output is the raw force in plate axes and a 2-D COP at the
//! marker rate only, with no moment, no free moment and no lab-frame rotation, and its type-4
//! calibration matrices are never attached to their plates. Guarding (a) and (b) needs the
//! header and parameters parsed first, and (c) needs the force platforms computed here, so
//! this module reads the format itself.

mod binary;
mod plates;

pub use binary::Processor;
pub use plates::ForcePlate;

use super::Motion;
use crate::error::Error;
use crate::io::storage::Table;
use crate::io::trc::MAX_MARKER_COORDINATE;
use crate::spatial::Vec3;
use crate::text::short_number;
use binary::{Parameters, error};
use std::path::Path;

/// A C3D file read into SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct C3d {
    /// Where it was read from, for messages.
    pub source: String,
    /// The markers (m, lab frame of the file, NaN where missing), time 0 at the first frame;
    /// `None` when the file has no marker points.
    pub markers: Option<Motion>,
    /// `POINT:UNITS` as written in the file (`mm`), the unit the positions were converted
    /// from.
    pub marker_units: String,
    /// 3-D frame rate (Hz): `POINT:RATE`, equal to the header's.
    pub rate_hz: f64,
    /// Number of 3-D frames.
    pub n_frames: usize,
    /// The file's number of its first frame (header word 4, usually 1).
    pub first_frame: usize,
    /// The processor format the file was written in.
    pub processor: Processor,
    pub analog: Analog,
    /// The force platforms, in `FORCE_PLATFORM` order.
    pub plates: Vec<ForcePlate>,
}

/// The analog channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Analog {
    /// `ANALOG:LABELS`, trimmed.
    pub labels: Vec<String>,
    /// `ANALOG:UNITS` per channel (empty where the file has none).
    pub units: Vec<String>,
    /// Sampling rate (Hz): the frame rate × samples per frame.
    pub rate_hz: f64,
    /// Samples per channel in each 3-D frame.
    pub samples_per_frame: usize,
    /// Sample-major values in the channels' units: `values[s * labels.len() + c]`.
    pub values: Vec<f64>,
}

impl Analog {
    pub fn n_channels(&self) -> usize {
        self.labels.len()
    }

    pub fn n_samples(&self) -> usize {
        self.values
            .len()
            .checked_div(self.labels.len())
            .unwrap_or(0)
    }

    /// Index of the named channel.
    pub fn index(&self, label: &str) -> Option<usize> {
        self.labels.iter().position(|l| l == label)
    }

    /// The samples of channel `c`.
    pub fn channel(&self, c: usize) -> Vec<f64> {
        let n = self.labels.len();
        self.values
            .iter()
            .skip(c)
            .step_by(n.max(1))
            .copied()
            .collect()
    }
}

/// The rotation from a z-up lab frame to OpenSim's y-up frame, −90° about x:
/// (x, y, z) ↦ (x, z, −y).
pub fn lab_to_opensim(v: &Vec3) -> Vec3 {
    Vec3::new(v.x, v.z, -v.y)
}

/// The motion with every position rotated by [`lab_to_opensim`] (gaps stay NaN).
pub fn markers_to_opensim(motion: &Motion) -> Motion {
    let mut out = motion.clone();
    for p in &mut out.positions {
        *p = lab_to_opensim(p);
    }
    out
}

impl C3d {
    /// Reads a C3D file.
    pub fn read(path: &Path) -> crate::Result<C3d> {
        let bytes = crate::limits::read_binary_file_bytes(path)?;
        Self::parse(&bytes, &path.display().to_string())
    }

    /// Parses the bytes of a C3D file; `source` names it in errors.
    pub fn parse(bytes: &[u8], source: &str) -> crate::Result<C3d> {
        let (header, params) = binary::read_header_and_parameters(bytes, source)?;
        let layout = Layout::new(&header, &params)?;
        let data = &bytes[(header.data_start as usize - 1) * binary::BLOCK..];
        let frame_bytes = layout.frame_bytes();
        if frame_bytes == 0 {
            return Err(error(
                source,
                "header",
                "the file holds neither points nor analog channels",
            ));
        }
        let complete = data.len() / frame_bytes;
        if complete < layout.frames {
            return Err(error(
                source,
                format!("frame {complete}"),
                format!(
                    "the data section ends inside frame {complete} of {} ({} of {} bytes): truncated",
                    layout.frames,
                    data.len(),
                    layout.frames.saturating_mul(frame_bytes)
                ),
            ));
        }
        let markers = layout.markers(data, &params)?;
        let analog = layout.analog(data, &params)?;
        let view = plates::AnalogView {
            n_channels: analog.n_channels(),
            n_samples: analog.n_samples(),
            values: &analog.values,
            units: params
                .get("ANALOG", "UNITS")
                .map(|_| analog.units.as_slice()),
        };
        let plates = plates::force_plates(&params, &view, layout.point_unit)?;
        Ok(C3d {
            source: source.to_string(),
            markers,
            marker_units: layout.unit_text,
            rate_hz: layout.rate,
            n_frames: layout.frames,
            first_frame: header.first_frame as usize,
            processor: header.processor,
            analog,
            plates,
        })
    }

    /// The force platforms as an OpenSim ground-reaction table at the analog rate, in
    /// OpenSim's y-up axes ([`lab_to_opensim`]) and SI units: per plate `i` (from 1) the
    /// columns `plate{i}_force_vx/vy/vz` (the force), `plate{i}_force_px/py/pz` (the centre
    /// of pressure) and `plate{i}_torque_x/y/z` (the free moment), as OpenSim's
    /// C3DFileAdapter passes ezc3d's values on (no sign change: in the reference trials the
    /// force is the reaction on the subject, +y in stance). An ExternalForce reads them with
    /// `force_identifier` `plate{i}_force_v`, `point_identifier` `plate{i}_force_p` and
    /// `torque_identifier` `plate{i}_torque_`. Where the plate's normal load |F · n| is below
    /// `min_normal_force` (N, > 0) all nine values are 0, since the COP is then undefined.
    pub fn ground_reactions(&self, min_normal_force: f64) -> crate::Result<Table> {
        if !(min_normal_force > 0.0 && min_normal_force.is_finite()) {
            return Err(Error::invalid(
                "min_normal_force",
                format!("{min_normal_force} N must be positive and finite"),
            ));
        }
        if self.plates.is_empty() {
            return Err(error(
                &self.source,
                "FORCE_PLATFORM",
                "the file has no force platforms",
            ));
        }
        let mut labels = Vec::new();
        for i in 1..=self.plates.len() {
            for (what, axes) in [("force_v", "xyz"), ("force_p", "xyz"), ("torque_", "xyz")] {
                for a in axes.chars() {
                    labels.push(format!("plate{i}_{what}{a}"));
                }
            }
        }
        let n = self.analog.n_samples();
        let time = (0..n).map(|s| s as f64 / self.analog.rate_hz).collect();
        let mut values = Vec::with_capacity(n * labels.len());
        for s in 0..n {
            for plate in &self.plates {
                let load = plate.force[s].dot(&plate.surface_normal()).abs();
                if load < min_normal_force || !plate.cop[s].x.is_finite() {
                    values.extend([0.0; 9]);
                    continue;
                }
                let f = lab_to_opensim(&plate.force[s]);
                let p = lab_to_opensim(&plate.cop[s]);
                let t = lab_to_opensim(&plate.free_moment[s]);
                values.extend(f.iter().chain(p.iter()).chain(t.iter()));
            }
        }
        Table::new("ground_reactions", labels, time, values)
    }
}

/// Sizes and scales of the data section, checked against each other.
struct Layout {
    float: bool,
    processor: Processor,
    points: usize,
    channels: usize,
    subframes: usize,
    frames: usize,
    rate: f64,
    point_scale: f64,
    point_unit: Option<f64>,
    unit_text: String,
}

/// Parameters naming points that are model outputs, not markers.
const NON_MARKER_LISTS: [&str; 6] = [
    "ANGLES",
    "FORCES",
    "MOMENTS",
    "POWERS",
    "SCALARS",
    "REACTIONS",
];

impl Layout {
    fn new(header: &binary::Header, params: &Parameters) -> crate::Result<Layout> {
        let source = &params.source;
        let float = header.scale < 0.0;
        let points = header.points as usize;
        if let Some(used) = params.integer("POINT", "USED", true)?
            && used != points as i64
        {
            return Err(params.error(
                "POINT",
                "USED",
                format!("{used}, but the header says {points} points per frame"),
            ));
        }
        let point_scale = match params
            .numbers("POINT", "SCALE")?
            .and_then(|v| v.first().copied())
        {
            Some(s) if (s < 0.0) != float => {
                return Err(params.error(
                    "POINT",
                    "SCALE",
                    format!(
                        "{s} disagrees in sign (integer vs float storage) with the header's {}",
                        header.scale
                    ),
                ));
            }
            Some(s) => s.abs(),
            None => (header.scale as f64).abs(),
        };
        if !float && points > 0 && !(point_scale > 0.0 && point_scale.is_finite()) {
            return Err(params.error(
                "POINT",
                "SCALE",
                format!("{point_scale} must be positive for integer data"),
            ));
        }
        let rate = match params
            .numbers("POINT", "RATE")?
            .and_then(|v| v.first().copied())
        {
            Some(r) => {
                let h = header.rate as f64;
                if (r - h).abs() > 1e-4 * r.abs() {
                    return Err(params.error(
                        "POINT",
                        "RATE",
                        format!("{r} Hz, but the header says {h} Hz"),
                    ));
                }
                r
            }
            None => header.rate as f64,
        };
        if !(rate > 0.0 && rate.is_finite()) {
            return Err(error(
                source,
                "header",
                format!("frame rate {rate} Hz must be positive"),
            ));
        }
        let (first, last) = (header.first_frame as usize, header.last_frame as usize);
        let mut frames = match last.checked_sub(first) {
            Some(d) => d + 1,
            None => {
                return Err(error(
                    source,
                    "header",
                    format!("last frame {last} precedes first frame {first}"),
                ));
            }
        };
        if header.last_frame == u16::MAX {
            frames = long_frame_count(params)?.unwrap_or(frames);
        }
        let (analog_total, subframes) = (
            header.analog_per_frame as usize,
            header.analog_subframes as usize,
        );
        let channels = if analog_total == 0 {
            0
        } else if subframes == 0 || analog_total % subframes != 0 {
            return Err(error(
                source,
                "header",
                format!(
                    "{analog_total} analog values per frame is not a multiple of {subframes} samples per frame"
                ),
            ));
        } else {
            analog_total / subframes
        };
        if let Some(used) = params.integer("ANALOG", "USED", true)?
            && used != channels as i64
        {
            return Err(params.error(
                "ANALOG",
                "USED",
                format!("{used} channels, but the header's layout holds {channels}"),
            ));
        }
        let analog_rate = params
            .numbers("ANALOG", "RATE")?
            .and_then(|v| v.first().copied());
        if let Some(r) = analog_rate.filter(|_| channels > 0) {
            let expected = rate * subframes as f64;
            if (r - expected).abs() > 1e-4 * expected {
                return Err(params.error(
                    "ANALOG",
                    "RATE",
                    format!(
                        "{r} Hz, but {rate} Hz × {subframes} samples per frame is {expected} Hz"
                    ),
                ));
            }
        }
        let unit_text = params
            .strings("POINT", "UNITS")?
            .and_then(|v| v.into_iter().next())
            .unwrap_or_default();
        let point_unit = if unit_text.is_empty() {
            None
        } else {
            plates::length_unit(&unit_text)
        };
        if point_unit.is_none() && !unit_text.is_empty() {
            return Err(params.error(
                "POINT",
                "UNITS",
                format!("\"{unit_text}\" is not a length unit (mm, cm, m, in)"),
            ));
        }
        Ok(Layout {
            float,
            processor: header.processor,
            points,
            channels,
            subframes,
            frames,
            rate,
            point_scale,
            point_unit,
            unit_text,
        })
    }

    fn word(&self) -> usize {
        if self.float { 4 } else { 2 }
    }

    fn point_bytes(&self) -> usize {
        self.points * 4 * self.word()
    }

    fn frame_bytes(&self) -> usize {
        self.point_bytes() + self.channels * self.subframes * self.word()
    }

    /// The value of the `k`-th word at byte `at` (in bounds: the caller checked the length).
    fn value(&self, data: &[u8], at: usize) -> f64 {
        let p = self.processor;
        if self.float {
            p.f32([data[at], data[at + 1], data[at + 2], data[at + 3]]) as f64
        } else {
            p.i16([data[at], data[at + 1]]) as f64
        }
    }

    fn markers(&self, data: &[u8], params: &Parameters) -> crate::Result<Option<Motion>> {
        if self.points == 0 {
            return Ok(None);
        }
        let labels = params
            .continued("LABELS", |n| params.strings("POINT", n))?
            .ok_or_else(|| params.error("POINT", "LABELS", "missing"))?;
        if labels.len() < self.points {
            return Err(params.error(
                "POINT",
                "LABELS",
                format!("{} labels for {} points", labels.len(), self.points),
            ));
        }
        let mut excluded: Vec<String> = Vec::new();
        for list in NON_MARKER_LISTS {
            if let Some(v) = params.continued(list, |n| match params.get("POINT", n) {
                Some(p) if matches!(p.values, binary::Values::Char(_)) => {
                    params.strings("POINT", n)
                }
                _ => Ok(None),
            })? {
                excluded.extend(v.into_iter().filter(|s| !s.is_empty()));
            }
        }
        let kept: Vec<usize> = (0..self.points)
            .filter(|&i| !excluded.contains(&labels[i]))
            .collect();
        if kept.is_empty() {
            return Ok(None);
        }
        let metres = self.point_unit.ok_or_else(|| {
            params.error(
                "POINT",
                "UNITS",
                "missing: the marker positions need a length unit",
            )
        })?;
        let scale = if self.float {
            metres
        } else {
            metres * self.point_scale
        };
        let w = self.word();
        let mut positions = Vec::with_capacity(self.frames * kept.len());
        for f in 0..self.frames {
            let frame = f * self.frame_bytes();
            for &i in &kept {
                let at = frame + i * 4 * w;
                // Missing: a negative residual word (the sign bit of the fourth value).
                let missing = if self.float {
                    self.processor.f32_sign([
                        data[at + 12],
                        data[at + 13],
                        data[at + 14],
                        data[at + 15],
                    ])
                } else {
                    self.processor.i16([data[at + 6], data[at + 7]]) < 0
                };
                if missing {
                    positions.push(Vec3::repeat(f64::NAN));
                    continue;
                }
                let p = Vec3::new(
                    self.value(data, at),
                    self.value(data, at + w),
                    self.value(data, at + 2 * w),
                );
                if !p.iter().all(|x| x.is_finite()) {
                    return Err(error(
                        &params.source,
                        format!("frame {f}, marker \"{}\"", labels[i]),
                        format!(
                            "position ({}, {}, {}) is not finite but its residual says it is valid",
                            p.x, p.y, p.z
                        ),
                    ));
                }
                let p = p * scale;
                if !(p.amax() <= MAX_MARKER_COORDINATE) {
                    return Err(error(
                        &params.source,
                        format!("frame {f}, marker \"{}\"", labels[i]),
                        format!(
                            "position ({}, {}, {}) m is beyond ±{MAX_MARKER_COORDINATE:e} m, \
                             which no capture volume reaches: a corrupt value or a wrong \
                             POINT:SCALE or POINT:UNITS",
                            short_number(p.x),
                            short_number(p.y),
                            short_number(p.z)
                        ),
                    ));
                }
                positions.push(p);
            }
        }
        let names = kept.iter().map(|&i| labels[i].clone()).collect();
        Motion::uniform(params.source.clone(), names, self.rate, positions).map(Some)
    }

    fn analog(&self, data: &[u8], params: &Parameters) -> crate::Result<Analog> {
        let n = self.channels;
        let mut analog = Analog {
            labels: Vec::new(),
            units: Vec::new(),
            rate_hz: self.rate * self.subframes.max(1) as f64,
            samples_per_frame: self.subframes,
            values: Vec::new(),
        };
        if n == 0 {
            analog.samples_per_frame = 0;
            return Ok(analog);
        }
        let g = "ANALOG";
        let need = |name: &str, len: usize| {
            if len < n {
                Err(params.error(g, name, format!("{len} values for {n} channels")))
            } else {
                Ok(())
            }
        };
        let labels = params
            .continued("LABELS", |k| params.strings(g, k))?
            .ok_or_else(|| params.error(g, "LABELS", "missing"))?;
        need("LABELS", labels.len())?;
        let unsigned = params
            .strings(g, "FORMAT")?
            .and_then(|v| v.into_iter().next())
            .is_some_and(|f| f.eq_ignore_ascii_case("UNSIGNED"));
        let scale = params
            .continued("SCALE", |k| params.numbers(g, k))?
            .ok_or_else(|| params.error(g, "SCALE", "missing"))?;
        need("SCALE", scale.len())?;
        let offset = params
            .continued("OFFSET", |k| params.integers(g, k, unsigned))?
            .ok_or_else(|| params.error(g, "OFFSET", "missing"))?;
        need("OFFSET", offset.len())?;
        let gen_scale = params
            .numbers(g, "GEN_SCALE")?
            .and_then(|v| v.first().copied())
            .ok_or_else(|| params.error(g, "GEN_SCALE", "missing"))?;
        let mut units = params
            .continued("UNITS", |k| params.strings(g, k))?
            .unwrap_or_default();
        units.resize(n, String::new());
        units.truncate(n);
        let gain: Vec<f64> = scale[..n].iter().map(|s| s * gen_scale).collect();
        if let Some(c) = gain.iter().position(|g| !g.is_finite()) {
            return Err(params.error(
                g,
                "SCALE",
                format!("channel {} scale × GEN_SCALE is not finite", c + 1),
            ));
        }
        let w = self.word();
        analog.values.reserve(self.frames * self.subframes * n);
        for f in 0..self.frames {
            let start = f * self.frame_bytes() + self.point_bytes();
            for s in 0..self.subframes {
                for c in 0..n {
                    let at = start + (s * n + c) * w;
                    let raw = if !self.float && unsigned {
                        self.processor.u16([data[at], data[at + 1]]) as f64
                    } else {
                        self.value(data, at)
                    };
                    // value = (raw − offset) × SCALE × GEN_SCALE
                    let v = (raw - offset[c] as f64) * gain[c];
                    if !v.is_finite() {
                        return Err(error(
                            &params.source,
                            format!("frame {f}, analog channel \"{}\"", labels[c]),
                            format!("sample {} is not finite", f * self.subframes + s),
                        ));
                    }
                    analog.values.push(v);
                }
            }
        }
        analog.labels = labels[..n].to_vec();
        analog.units = units;
        Ok(analog)
    }
}

/// The frame count of a file with more than 65535 frames (header word 5 saturated):
/// `TRIAL:ACTUAL_END_FIELD − ACTUAL_START_FIELD + 1` (each two 16-bit words, low first), or
/// `POINT:FRAMES` (unsigned or float).
fn long_frame_count(params: &Parameters) -> crate::Result<Option<usize>> {
    let field = |name: &str| -> crate::Result<Option<i64>> {
        Ok(params
            .integers("TRIAL", name, true)?
            .filter(|v| v.len() >= 2)
            .map(|v| v[0] + 65536 * v[1]))
    };
    if let (Some(s), Some(e)) = (field("ACTUAL_START_FIELD")?, field("ACTUAL_END_FIELD")?) {
        if e >= s {
            return Ok(Some((e - s + 1) as usize));
        }
        return Err(params.error(
            "TRIAL",
            "ACTUAL_END_FIELD",
            format!("{e} precedes ACTUAL_START_FIELD {s}"),
        ));
    }
    Ok(params
        .integers("POINT", "FRAMES", true)?
        .and_then(|v| v.first().copied())
        .filter(|&n| n > 0)
        .map(|n| n as usize))
}
