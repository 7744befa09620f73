//! Force platforms (FORCE_PLATFORM group, types 1–4): force, moment, centre of pressure and
//! free moment in the lab frame at every analog sample, with ezc3d's conventions (the module
//! documentation of [`super`] states them).

use super::binary::Parameters;
use crate::error::Error;
use crate::motion::LengthUnit;
use crate::spatial::{Mat3, Vec3};
use nalgebra::{Matrix6, Vector6};

/// One force platform and its signals, in SI units and the lab frame of the file.
///
/// Every signal has one value per analog sample ([`super::Analog::rate_hz`]). The force is
/// the plate's force channels rotated into the lab frame, with the sign the file gives them
/// (as ezc3d and OpenSim report it; in the reference trials the ground reaction on the
/// subject, +z in stance). The moment is that force's moment about the centre of the
/// plate's working surface ([`ForcePlate::centre`]) when it acts at the centre of pressure,
/// plus the free moment. The centre of pressure lies on the surface plane; the
/// free moment is the moment about the centre of pressure (along the plate normal).
#[derive(Clone, Debug, PartialEq)]
pub struct ForcePlate {
    /// FORCE_PLATFORM:TYPE, 1 to 4.
    pub kind: u8,
    /// FORCE_PLATFORM:CORNERS (m, lab frame), in the file's order (plate quadrants 1–4).
    pub corners: [Vec3; 4],
    /// Centre of the working surface: the mean of the corners (m, lab frame).
    pub centre: Vec3,
    /// FORCE_PLATFORM:ORIGIN as stored (m, plate axes): for types 1, 2 and 4 the transducer
    /// origin relative to the surface centre; for type 3 the sensor offsets a, b and the
    /// height az0.
    pub origin: Vec3,
    /// Plate axes → lab axes: columns x = c₁ − c₂, y = (z × x), z = x × (c₁ − c₄), unit
    /// length (cₖ the corners).
    pub plate_to_lab: Mat3,
    /// The analog channels (0-based indices into [`super::Analog::labels`]) in
    /// FORCE_PLATFORM:CHANNEL order: 6 for types 1, 2, 4, 8 for type 3.
    pub channels: Vec<usize>,
    /// FORCE_PLATFORM:CAL_MATRIX of a type-4 plate (row = output, column = channel).
    pub calibration: Option<Matrix6<f64>>,
    /// Force (N), lab frame.
    pub force: Vec<Vec3>,
    /// Moment of that force about [`ForcePlate::centre`] (N·m).
    pub moment: Vec<Vec3>,
    /// Centre of pressure (m); NaN where the normal force is exactly zero.
    pub cop: Vec<Vec3>,
    /// Moment about the centre of pressure (N·m, along the plate normal); NaN where the
    /// centre of pressure is.
    pub free_moment: Vec<Vec3>,
}

impl ForcePlate {
    /// Number of samples.
    pub fn n_samples(&self) -> usize {
        self.force.len()
    }

    /// The plate's unit normal pointing up out of the working surface (lab frame): minus the
    /// plate z axis, which points down into the plate.
    pub fn surface_normal(&self) -> Vec3 {
        -self.plate_to_lab.column(2).into_owned()
    }
}

/// Metres per unit of a length unit written in the file (`mm`, `cm`, `m`, `in`).
pub(super) fn length_unit(text: &str) -> Option<f64> {
    LengthUnit::parse(text)
        .filter(|u| !matches!(u, LengthUnit::Custom(_)))
        .map(|u| u.metres())
}

fn squash(text: &str) -> String {
    text.chars()
        .filter(|c| !matches!(c, ' ' | '.' | '*' | '·' | '-' | '_'))
        .collect::<String>()
        .to_ascii_lowercase()
}

/// N·m per unit of a moment unit (`Nmm`, `N.mm`, `N·m`, `Ncm`…).
fn moment_unit(text: &str) -> Option<f64> {
    match squash(text).as_str() {
        "nm" => Some(1.0),
        "ncm" => Some(0.01),
        "nmm" => Some(0.001),
        _ => None,
    }
}

/// The analog data a plate is computed from.
pub(super) struct AnalogView<'a> {
    pub n_channels: usize,
    pub n_samples: usize,
    /// Sample-major values in the channels' units (after SCALE, OFFSET, GEN_SCALE).
    pub values: &'a [f64],
    /// ANALOG:UNITS per channel, when the file has them.
    pub units: Option<&'a [String]>,
}

/// All force platforms of the file (none when FORCE_PLATFORM:USED is absent or 0).
/// `point_unit` is metres per POINT:UNITS unit, needed for CORNERS and ORIGIN.
pub(super) fn force_plates(
    params: &Parameters,
    analog: &AnalogView,
    point_unit: Option<f64>,
) -> crate::Result<Vec<ForcePlate>> {
    let used = params.integer(G, "USED", true)?.unwrap_or(0) as usize;
    if used == 0 {
        return Ok(Vec::new());
    }
    // More plates than channels cannot be (each reads six or eight); the bound also keeps the
    // output (96 bytes per plate and sample) a fixed multiple of the file's length.
    if used > analog.n_channels {
        return Err(params.error(
            G,
            "USED",
            format!(
                "{used} platforms, but the file has {} analog channels",
                analog.n_channels
            ),
        ));
    }
    let table = PlatformTable::read(params, used, point_unit)?;
    let mut plates = Vec::with_capacity(used);
    for p in 0..used {
        let kind = table.kind(p)?;
        let channels = table.channels(p, kind, analog)?;
        let mut plate = table.geometry(p, kind, channels, analog.n_samples)?;
        let signals = table.conversion(p, &plate, analog)?;
        compute_signals(&mut plate, &signals, analog);
        plates.push(plate);
    }
    Ok(plates)
}

/// The parameter group of the force platforms.
const G: &str = "FORCE_PLATFORM";

/// The FORCE_PLATFORM parameters of `used` platforms, lengths in metres per POINT:UNITS unit.
struct PlatformTable<'a> {
    params: &'a Parameters,
    types: Vec<i64>,
    corners: Vec<f64>,
    origins: Vec<f64>,
    /// CHANNEL's dimensions, its rows (channels per platform) and values.
    channel_dims: Vec<usize>,
    channel_rows: usize,
    channel_values: Vec<i64>,
    cal: Option<Vec<f64>>,
    cop_poly: Option<Vec<f64>>,
    metres: f64,
}

impl<'a> PlatformTable<'a> {
    /// Reads the group, checking that TYPE, CORNERS, ORIGIN and CHANNEL are present and that
    /// TYPE, CORNERS and ORIGIN hold `used` platforms.
    fn read(
        params: &'a Parameters,
        used: usize,
        point_unit: Option<f64>,
    ) -> crate::Result<PlatformTable<'a>> {
        let missing = |name: &str| {
            params.error(
                G,
                name,
                format!("missing, but FORCE_PLATFORM:USED is {used}"),
            )
        };
        let need = |name: &str| -> crate::Result<Vec<f64>> {
            params.numbers(G, name)?.ok_or_else(|| missing(name))
        };
        let types = params
            .integers(G, "TYPE", false)?
            .ok_or_else(|| missing("TYPE"))?;
        let corners = need("CORNERS")?;
        let origins = need("ORIGIN")?;
        let channel_param = params.get(G, "CHANNEL").ok_or_else(|| missing("CHANNEL"))?;
        let channel_rows = channel_param.dims.first().copied().unwrap_or(1).max(1);
        let channel_values = params.integers(G, "CHANNEL", false)?.unwrap_or_default();
        let cal = params.numbers(G, "CAL_MATRIX")?;
        let cop_poly = params.numbers(G, "FPCOPPOLY")?;
        let metres = point_unit.ok_or_else(|| {
            params.error(
                "POINT",
                "UNITS",
                "missing: the force-platform CORNERS and ORIGIN need a length unit",
            )
        })?;
        if types.len() < used || corners.len() < 12 * used || origins.len() < 3 * used {
            return Err(params.error(
                G,
                if types.len() < used { "TYPE" } else if corners.len() < 12 * used { "CORNERS" } else { "ORIGIN" },
                format!(
                    "{used} platforms need {used} TYPE, {} CORNERS and {} ORIGIN values; the file has {}, {} and {}",
                    12 * used,
                    3 * used,
                    types.len(),
                    corners.len(),
                    origins.len()
                ),
            ));
        }
        Ok(PlatformTable {
            params,
            types,
            corners,
            origins,
            channel_dims: channel_param.dims.clone(),
            channel_rows,
            channel_values,
            cal,
            cop_poly,
            metres,
        })
    }

    /// An error about platform `p` (0-based).
    fn error(&self, p: usize, message: String) -> Error {
        Error::Motion {
            file: self.params.source.clone(),
            location: format!("force platform {}", p + 1),
            message,
        }
    }

    /// Platform `p`'s TYPE, 1 to 4.
    fn kind(&self, p: usize) -> crate::Result<u8> {
        match self.types[p] {
            k @ 1..=4 => Ok(k as u8),
            k => Err(self.error(
                p,
                format!("FORCE_PLATFORM:TYPE {k} is not supported (types 1 to 4 are)"),
            )),
        }
    }

    /// Platform `p`'s analog channels (0-based): 8 for type 3, else 6.
    fn channels(&self, p: usize, kind: u8, analog: &AnalogView) -> crate::Result<Vec<usize>> {
        let n_ch = if kind == 3 { 8 } else { 6 };
        let (rows, values) = (self.channel_rows, &self.channel_values);
        if rows < n_ch || values.len() < rows * (p + 1) {
            return Err(self.error(p, format!(
                "FORCE_PLATFORM:CHANNEL must list {n_ch} channels per platform (dimensions {:?}, {} values)",
                self.channel_dims,
                values.len()
            )));
        }
        let mut channels = Vec::with_capacity(n_ch);
        for j in 0..n_ch {
            let c = values[p * rows + j];
            if c < 1 || c as usize > analog.n_channels {
                return Err(self.error(
                    p,
                    format!(
                        "FORCE_PLATFORM:CHANNEL entry {} is {c}, outside the {} analog channels",
                        j + 1,
                        analog.n_channels
                    ),
                ));
            }
            channels.push(c as usize - 1);
        }
        Ok(channels)
    }

    /// Platform `p` without signals: its corners, centre, origin, axes and (type 4)
    /// calibration matrix.
    fn geometry(
        &self,
        p: usize,
        kind: u8,
        channels: Vec<usize>,
        n_samples: usize,
    ) -> crate::Result<ForcePlate> {
        let metres = self.metres;
        let corner = |k: usize| {
            let i = 12 * p + 3 * k;
            Vec3::new(self.corners[i], self.corners[i + 1], self.corners[i + 2]) * metres
        };
        let corners = [corner(0), corner(1), corner(2), corner(3)];
        let o = &self.origins;
        let origin = Vec3::new(o[3 * p], o[3 * p + 1], o[3 * p + 2]) * metres;
        if corners
            .iter()
            .chain([&origin])
            .any(|v| !v.iter().all(|x| x.is_finite()))
        {
            return Err(self.error(p, "CORNERS or ORIGIN is not finite".into()));
        }
        let centre = (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
        // x = c₁ − c₂, y' = c₁ − c₄, z = x × y', y = z × x (ezc3d's construction).
        let x = corners[0] - corners[1];
        let z = x.cross(&(corners[0] - corners[3]));
        let y = z.cross(&x);
        if !(x.norm() > 0.0 && z.norm() > 0.0) {
            return Err(self.error(
                p,
                "CORNERS do not span a plane (coincident or collinear corners)".into(),
            ));
        }
        let plate_to_lab = Mat3::from_columns(&[x.normalize(), y.normalize(), z.normalize()]);
        let calibration = if kind == 4 {
            // CAL_MATRIX [6, 6, n]: the first index (fastest) is the row.
            let c = self.cal.as_deref().unwrap_or(&[]);
            if c.len() < 36 * (p + 1) {
                return Err(self.error(p, format!(
                    "type 4 needs FORCE_PLATFORM:CAL_MATRIX with 36 values per platform; the file has {}",
                    c.len()
                )));
            }
            Some(Matrix6::from_fn(|i, j| c[36 * p + i + 6 * j]))
        } else {
            None
        };
        Ok(ForcePlate {
            kind,
            corners,
            centre,
            origin,
            plate_to_lab,
            channels,
            calibration,
            force: Vec::with_capacity(n_samples),
            moment: Vec::with_capacity(n_samples),
            cop: Vec::with_capacity(n_samples),
            free_moment: Vec::with_capacity(n_samples),
        })
    }

    /// How `plate` (platform `p`) turns its channels into a wrench, with the channels' units
    /// checked: force channels in N; moments in the channel's unit, or N × POINT:UNITS when
    /// it has none (ezc3d's assumption, also used for the outputs of a calibration matrix).
    fn conversion(
        &self,
        p: usize,
        plate: &ForcePlate,
        analog: &AnalogView,
    ) -> crate::Result<Conversion> {
        let (kind, channels, metres) = (plate.kind, &plate.channels, self.metres);
        let unit_of = |ch: usize| -> &str {
            analog
                .units
                .and_then(|u| u.get(channels[ch]))
                .map(String::as_str)
                .unwrap_or("")
        };
        let force_ok = |ch: usize| {
            matches!(
                squash(unit_of(ch)).as_str(),
                "" | "n" | "newton" | "newtons"
            )
        };
        let moment_scale = |ch: usize| -> crate::Result<f64> {
            match unit_of(ch) {
                u if u.trim().is_empty() || kind == 4 => Ok(metres),
                u => moment_unit(u).ok_or_else(|| {
                    self.error(
                        p,
                        format!(
                            "analog channel {} has unit \"{u}\", not a moment unit (N·m, N·mm)",
                            channels[ch] + 1
                        ),
                    )
                }),
            }
        };
        let force_channels = if kind == 3 { 0..8 } else { 0..3 };
        if let Some(ch) = force_channels.clone().find(|&c| kind != 4 && !force_ok(c)) {
            return Err(self.error(
                p,
                format!(
                    "analog channel {} has unit \"{}\", not N",
                    channels[ch] + 1,
                    unit_of(ch)
                ),
            ));
        }
        let poly: Option<[f64; 12]> = match (&self.cop_poly, kind) {
            (Some(v), 3) if v.len() >= 12 * (p + 1) => v[12 * p..12 * (p + 1)].try_into().ok(),
            _ => None,
        };
        let origin = plate.origin;
        Ok(match kind {
            1 => {
                let len_scale = match unit_of(3) {
                    u if u.trim().is_empty() => metres,
                    u => length_unit(u).ok_or_else(|| {
                        self.error(
                            p,
                            format!(
                                "analog channel {} has unit \"{u}\", not a length",
                                channels[3] + 1
                            ),
                        )
                    })?,
                };
                Conversion::Type1 {
                    length: len_scale,
                    moment: moment_scale(5)?,
                }
            }
            2 => Conversion::Type2 {
                moment: moment_scale(3)?,
                origin: ezc3d_origin(origin),
            },
            3 => Conversion::Type3 {
                a: origin.x,
                b: origin.y,
                height: -origin.z.abs(),
                poly,
                metres,
            },
            _ => Conversion::Type4 {
                cal: plate.calibration.unwrap_or_else(Matrix6::identity),
                moment: moment_scale(3)?,
                origin: ezc3d_origin(origin),
            },
        })
    }
}

/// The plate's force, moment, centre of pressure and free moment (lab frame) at every
/// analog sample.
fn compute_signals(plate: &mut ForcePlate, signals: &Conversion, analog: &AnalogView) {
    let mut ch = [0.0; 8];
    for s in 0..analog.n_samples {
        let row = &analog.values[s * analog.n_channels..(s + 1) * analog.n_channels];
        for (j, &c) in plate.channels.iter().enumerate() {
            ch[j] = row[c];
        }
        let w = signals.wrench(&ch);
        let (force, moment, cop, free) = lab_signals(&w, plate);
        plate.force.push(force);
        plate.moment.push(moment);
        plate.cop.push(cop);
        plate.free_moment.push(free);
    }
}

/// The vector from the transducer origin to the surface centre (plate axes): ezc3d negates
/// ORIGIN when its z is positive (the C3D convention: the origin lies below the surface and
/// the plate z axis points down) and uses it as stored otherwise.
fn ezc3d_origin(origin: Vec3) -> Vec3 {
    if origin.z > 0.0 { -origin } else { origin }
}

/// How a plate type turns its channels into a wrench in plate axes.
enum Conversion {
    /// Fx, Fy, Fz, COPx, COPy (from the surface centre), Tz.
    Type1 { length: f64, moment: f64 },
    /// Fx, Fy, Fz, Mx, My, Mz about the transducer origin.
    Type2 { moment: f64, origin: Vec3 },
    /// Kistler: fx12, fx34, fy14, fy23, fz1, fz2, fz3, fz4 with sensors at (±a, ±b).
    Type3 {
        a: f64,
        b: f64,
        height: f64,
        poly: Option<[f64; 12]>,
        metres: f64,
    },
    /// Six channels through the calibration matrix to Fx…Mz about the transducer origin.
    Type4 {
        cal: Matrix6<f64>,
        moment: f64,
        origin: Vec3,
    },
}

/// Force, moment about the surface centre, and centre of pressure (from the surface
/// centre, z = 0), all in plate axes and SI.
struct Wrench {
    force: Vec3,
    moment: Vec3,
    cop: Vec3,
}

impl Conversion {
    fn wrench(&self, ch: &[f64; 8]) -> Wrench {
        match *self {
            Conversion::Type1 { length, moment } => {
                let force = Vec3::new(ch[0], ch[1], ch[2]);
                let cop = Vec3::new(ch[3] * length, ch[4] * length, 0.0);
                // M_centre = r_cop × F + (0, 0, Tz)  (ezc3d writes the opposite sign).
                let moment = cop.cross(&force) + Vec3::new(0.0, 0.0, ch[5] * moment);
                Wrench { force, moment, cop }
            }
            Conversion::Type2 { moment, origin } => {
                let force = Vec3::new(ch[0], ch[1], ch[2]);
                let m_origin = Vec3::new(ch[3], ch[4], ch[5]) * moment;
                centred(force, m_origin, origin)
            }
            Conversion::Type4 {
                cal,
                moment,
                origin,
            } => {
                let out = cal * Vector6::new(ch[0], ch[1], ch[2], ch[3], ch[4], ch[5]);
                let force = Vec3::new(out[0], out[1], out[2]);
                let m_origin = Vec3::new(out[3], out[4], out[5]) * moment;
                centred(force, m_origin, origin)
            }
            Conversion::Type3 {
                a,
                b,
                height,
                poly,
                metres,
            } => {
                let [fx12, fx34, fy14, fy23, fz1, fz2, fz3, fz4] = *ch;
                let force = Vec3::new(fx12 + fx34, fy14 + fy23, fz1 + fz2 + fz3 + fz4);
                // Kistler: Mx = b (fz1 + fz2 − fz3 − fz4), My = a (−fz1 + fz2 + fz3 − fz4),
                // Mz = b (fx34 − fx12) + a (fy14 − fy23), about the sensor-plane centre.
                let m_origin = Vec3::new(
                    b * (fz1 + fz2 - fz3 - fz4),
                    a * (-fz1 + fz2 + fz3 - fz4),
                    b * (fx34 - fx12) + a * (fy14 - fy23),
                );
                let mut w = centred(force, m_origin, Vec3::new(0.0, 0.0, height));
                if let Some(c) = poly {
                    // Kistler's COP correction (FPCOPPOLY), in the file's length unit:
                    // Δx = (P₀y⁴ + P₁y² + P₂)x³ + (P₃y⁴ + P₄y² + P₅)x, Δy likewise with x↔y.
                    let (x, y) = (w.cop.x / metres, w.cop.y / metres);
                    let dx = (c[0] * y.powi(4) + c[1] * y * y + c[2]) * x.powi(3)
                        + (c[3] * y.powi(4) + c[4] * y * y + c[5]) * x;
                    let dy = (c[6] * x.powi(4) + c[7] * x * x + c[8]) * y.powi(3)
                        + (c[9] * x.powi(4) + c[10] * x * x + c[11]) * y;
                    w.cop.x -= dx * metres;
                    w.cop.y -= dy * metres;
                }
                w
            }
        }
    }
}

/// The wrench moved from the transducer origin to the surface centre, `r` the vector from
/// the former to the latter: M_c = M_o + F × r; COP = (−M_c,y / Fz, M_c,x / Fz, 0).
fn centred(force: Vec3, m_origin: Vec3, r: Vec3) -> Wrench {
    let moment = m_origin + force.cross(&r);
    let cop = if force.z == 0.0 {
        Vec3::repeat(f64::NAN)
    } else {
        Vec3::new(-moment.y / force.z, moment.x / force.z, 0.0)
    };
    Wrench { force, moment, cop }
}

/// Lab-frame force, moment about the centre, centre of pressure and free moment
/// T = M_c + F × r_cop (the moment about the centre of pressure).
fn lab_signals(w: &Wrench, plate: &ForcePlate) -> (Vec3, Vec3, Vec3, Vec3) {
    let r = &plate.plate_to_lab;
    let free = w.moment + w.force.cross(&w.cop);
    (
        r * w.force,
        r * w.moment,
        r * w.cop + plate.centre,
        r * free,
    )
}
