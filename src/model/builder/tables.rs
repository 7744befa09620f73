//! The default model's parameter tables (`data/model/*.csv`): one record type per file, read
//! with the column names as headers. Every record carries the publication of its figures in
//! `source`; the reader refuses a row without one.

use crate::error::TableError;
use serde::Deserialize;
use std::path::Path;

/// The reference subject the tables describe (`reference_subject.csv`: quantity,value,source).
#[derive(Clone, Debug, Deserialize)]
pub struct SubjectRow {
    pub quantity: String,
    pub value: f64,
    pub source: String,
}

/// One segment of a published segment-parameter table (`segments.csv`), in percent of body
/// mass and of the segment length between its two landmarks.
#[derive(Clone, Debug, Deserialize)]
pub struct SegmentRow {
    pub segment: String,
    pub mass_percent: f64,
    /// Centre of mass from the proximal landmark, % of the segment length.
    pub com_percent: f64,
    /// Radii of gyration about the sagittal (antero-posterior), transverse (medio-lateral) and
    /// longitudinal axes, % of the segment length.
    pub r_sagittal_percent: f64,
    pub r_transverse_percent: f64,
    pub r_longitudinal_percent: f64,
    pub source: String,
}

/// A model body made of a share of one published segment (`bodies.csv`); a body may have
/// several rows (e.g. the torso: upper trunk and head). The landmarks are in the body frame
/// of the source model, in metres, before scaling to the reference height.
#[derive(Clone, Debug, Deserialize)]
pub struct BodyRow {
    pub body: String,
    pub segment: String,
    pub share: f64,
    pub proximal_x: f64,
    pub proximal_y: f64,
    pub proximal_z: f64,
    pub distal_x: f64,
    pub distal_y: f64,
    pub distal_z: f64,
    /// The part of the segment, as fractions of its length from the proximal landmark, that
    /// this body takes (0 and 1 for a whole segment; `share` is then the mass fraction).
    pub slice_start: f64,
    pub slice_end: f64,
    /// Standing height of the source model's geometry (the landmarks scale by H / this).
    pub source_height: f64,
    pub source: String,
}

/// A joint (`joints.csv`): parent and child frames (location and xyz body-fixed orientation
/// of the joint frame in each body), in the source model's geometry.
#[derive(Clone, Debug, Deserialize)]
pub struct JointRow {
    pub joint: String,
    /// `custom` (its axes in coordinates.csv) or `weld`.
    pub kind: String,
    pub parent: String,
    pub child: String,
    pub parent_x: f64,
    pub parent_y: f64,
    pub parent_z: f64,
    pub parent_rx: f64,
    pub parent_ry: f64,
    pub parent_rz: f64,
    pub child_x: f64,
    pub child_y: f64,
    pub child_z: f64,
    pub child_rx: f64,
    pub child_ry: f64,
    pub child_rz: f64,
    pub source_height: f64,
    pub source: String,
}

/// One transform axis of a custom joint (`coordinates.csv`). `coordinate` empty: the axis
/// is fixed (constant 0). `function`: `identity`, `linear:K` (the axis moves K × the
/// coordinate) or `spline:NAME` (joint_splines.csv; a translation's values scale with the
/// geometry).
#[derive(Clone, Debug, Deserialize)]
pub struct AxisRow {
    pub joint: String,
    /// rotation1..3, translation1..3.
    pub slot: String,
    pub coordinate: String,
    pub axis_x: f64,
    pub axis_y: f64,
    pub axis_z: f64,
    pub function: String,
    /// Coordinate properties (on the row that introduces the coordinate; radians or metres).
    pub default_value: Option<f64>,
    pub range_min: Option<f64>,
    pub range_max: Option<f64>,
    pub locked: Option<bool>,
    pub source: String,
}

/// A knot of a joint spline (`joint_splines.csv`).
#[derive(Clone, Debug, Deserialize)]
pub struct SplineKnotRow {
    pub spline: String,
    pub x: f64,
    pub y: f64,
    pub source: String,
}

/// A coordinate coupled to another (`couplers.csv`): dependent = ratio × independent.
#[derive(Clone, Debug, Deserialize)]
pub struct CouplerRow {
    pub name: String,
    pub dependent: String,
    pub independent: String,
    pub ratio: f64,
    pub source: String,
}

/// A coordinate coupled to several others through a multivariate polynomial
/// (`polynomial_couplers.csv`): dependent = p(independent…), OpenSim's
/// `MultivariatePolynomialFunction` with its coefficients in OpenSim's term order. The
/// dependent coordinate belongs to the joint whose axes it drives (`shoulder_rhythm.csv`);
/// its range is given here.
#[derive(Clone, Debug, Deserialize)]
pub struct PolynomialCouplerRow {
    pub name: String,
    pub dependent: String,
    /// The independent coordinates, separated by spaces.
    pub independent: String,
    pub order: u32,
    /// Coefficients separated by spaces.
    pub coefficients: String,
    pub range_min: f64,
    pub range_max: f64,
    pub source: String,
}

/// A knot of a joint's rhythm translation (`shoulder_rhythm.csv`): the displacement along the
/// parent frame's `axis` (x, y or z) of the joint centre, a spline of `coordinate`.
#[derive(Clone, Debug, Deserialize)]
pub struct RhythmKnotRow {
    pub joint: String,
    pub axis: String,
    pub function: String,
    pub coordinate: String,
    pub knot: f64,
    pub value: f64,
    pub source: String,
}

/// A knot of a rhythm-driven path point (`shoulder_rhythm_points.csv`): the location along
/// `axis` of point `index` of `muscle` in `body`'s frame, a spline of `coordinate`; the point
/// becomes a moving point.
#[derive(Clone, Debug, Deserialize)]
pub struct RhythmPointKnotRow {
    pub muscle: String,
    pub index: u32,
    pub body: String,
    pub axis: String,
    pub function: String,
    pub coordinate: String,
    pub knot: f64,
    pub value: f64,
    pub source: String,
}

/// A marker (`markers.csv`), in the body frame of the source geometry.
#[derive(Clone, Debug, Deserialize)]
pub struct MarkerRow {
    pub marker: String,
    pub body: String,
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub source_height: f64,
    pub source: String,
}

/// A ground-contact sphere (`contacts.csv`).
#[derive(Clone, Debug, Deserialize)]
pub struct ContactRow {
    pub contact: String,
    pub body: String,
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub radius: f64,
    pub source_height: f64,
    pub source: String,
}

/// A musculotendon unit (`muscles.csv`), Thelen 2003 parameters; lengths in the source
/// geometry (they scale with it).
#[derive(Clone, Debug, Deserialize)]
pub struct MuscleRow {
    pub name: String,
    pub group: String,
    pub side: String,
    pub max_isometric_force: f64,
    pub optimal_fiber_length: f64,
    pub tendon_slack_length: f64,
    pub pennation_angle: f64,
    pub max_contraction_velocity: f64,
    pub source: String,
}

/// A path point (`path_points.csv`), in order of `index` per muscle: `fixed`, `conditional`
/// (active while `coordinate` is in [range_min, range_max]) or `moving` (its location in
/// moving_point_functions.csv).
#[derive(Clone, Debug, Deserialize)]
pub struct PathPointRow {
    pub muscle: String,
    pub index: u32,
    #[serde(rename = "type")]
    pub kind: String,
    pub body: String,
    pub x: Option<f64>,
    pub y: Option<f64>,
    pub z: Option<f64>,
    pub coordinate: String,
    pub range_min: Option<f64>,
    pub range_max: Option<f64>,
    pub source: String,
}

/// A knot of a moving path point's coordinate function (`moving_point_functions.csv`; the
/// source is the muscle's).
#[derive(Clone, Debug, Deserialize)]
pub struct MovingKnotRow {
    pub muscle: String,
    pub index: u32,
    pub axis: String,
    pub function: String,
    pub coordinate: String,
    pub knot: f64,
    pub value: f64,
}

/// A wrap surface (`wrap_objects.csv`): cylinder (radius, length), sphere (radius), ellipsoid
/// (dim_x..z), torus (radius = inner, dim_x = outer radius).
#[derive(Clone, Debug, Deserialize)]
pub struct WrapObjectRow {
    pub name: String,
    pub body: String,
    #[serde(rename = "type")]
    pub kind: String,
    pub rot_x: f64,
    pub rot_y: f64,
    pub rot_z: f64,
    pub tx: f64,
    pub ty: f64,
    pub tz: f64,
    pub radius: Option<f64>,
    pub length: Option<f64>,
    pub dim_x: Option<f64>,
    pub dim_y: Option<f64>,
    pub dim_z: Option<f64>,
    pub quadrant: String,
    pub source: String,
}

/// A muscle's use of a wrap surface (`muscle_wraps.csv`; the source is the muscle's).
#[derive(Clone, Debug, Deserialize)]
pub struct MuscleWrapRow {
    pub muscle: String,
    pub order: u32,
    pub wrap_object: String,
    pub method: String,
    pub range_start: i64,
    pub range_end: i64,
}

/// Every table of the default model.
#[derive(Clone, Debug)]
pub struct ModelTables {
    pub subject: Vec<SubjectRow>,
    pub segments: Vec<SegmentRow>,
    pub bodies: Vec<BodyRow>,
    pub joints: Vec<JointRow>,
    pub axes: Vec<AxisRow>,
    pub splines: Vec<SplineKnotRow>,
    pub couplers: Vec<CouplerRow>,
    pub polynomial_couplers: Vec<PolynomialCouplerRow>,
    pub rhythm: Vec<RhythmKnotRow>,
    pub rhythm_points: Vec<RhythmPointKnotRow>,
    pub markers: Vec<MarkerRow>,
    pub contacts: Vec<ContactRow>,
    pub muscles: Vec<MuscleRow>,
    pub path_points: Vec<PathPointRow>,
    pub moving_knots: Vec<MovingKnotRow>,
    pub wrap_objects: Vec<WrapObjectRow>,
    pub muscle_wraps: Vec<MuscleWrapRow>,
}

/// Rows that carry a `source`.
trait Sourced {
    fn source(&self) -> &str;
}

macro_rules! sourced {
    ($($t:ty),*) => {$(impl Sourced for $t { fn source(&self) -> &str { &self.source } })*};
}
sourced!(
    SubjectRow,
    SegmentRow,
    BodyRow,
    JointRow,
    AxisRow,
    SplineKnotRow,
    CouplerRow,
    PolynomialCouplerRow,
    RhythmKnotRow,
    RhythmPointKnotRow,
    MarkerRow,
    ContactRow,
    MuscleRow,
    PathPointRow,
    WrapObjectRow
);

// Rows whose figures are those of the muscle they belong to.
macro_rules! inherited {
    ($($t:ty),*) => {$(impl Sourced for $t { fn source(&self) -> &str { "inherited from the muscle" } })*};
}
inherited!(MovingKnotRow, MuscleWrapRow);

/// The rows of several files with the same columns, one after the other.
fn read_all<T: for<'de> Deserialize<'de> + Sourced>(
    dir: &Path,
    files: &[&str],
) -> Result<Vec<T>, TableError> {
    let mut rows = Vec::new();
    for file in files {
        rows.extend(read(dir, file)?);
    }
    Ok(rows)
}

fn read<T: for<'de> Deserialize<'de> + Sourced>(
    dir: &Path,
    file: &str,
) -> Result<Vec<T>, TableError> {
    let path = dir.join(file);
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(&path)
        .map_err(|e| TableError::Io {
            path: path.clone(),
            message: e.to_string(),
        })?;
    let mut rows = Vec::new();
    for (i, record) in reader.deserialize::<T>().enumerate() {
        let row = i + 2;
        let record = record.map_err(|e| TableError::Row {
            path: path.clone(),
            row,
            message: e.to_string(),
        })?;
        if record.source().trim().is_empty() {
            return Err(TableError::Row {
                path: path.clone(),
                row,
                message: "the `source` column is empty; every figure needs its publication".into(),
            });
        }
        rows.push(record);
    }
    Ok(rows)
}

impl ModelTables {
    /// Reads every table from `dir` (normally `data/model`).
    pub fn read(dir: &Path) -> Result<Self, TableError> {
        Ok(ModelTables {
            subject: read(dir, "reference_subject.csv")?,
            segments: read(dir, "segments.csv")?,
            bodies: read(dir, "bodies.csv")?,
            joints: read(dir, "joints.csv")?,
            axes: read(dir, "coordinates.csv")?,
            splines: read(dir, "joint_splines.csv")?,
            couplers: read(dir, "couplers.csv")?,
            polynomial_couplers: read(dir, "polynomial_couplers.csv")?,
            rhythm: read(dir, "shoulder_rhythm.csv")?,
            rhythm_points: read(dir, "shoulder_rhythm_points.csv")?,
            markers: read(dir, "markers.csv")?,
            contacts: read(dir, "contacts.csv")?,
            muscles: read_all(dir, &["muscles.csv", "lumbar_muscles.csv"])?,
            path_points: read_all(dir, &["path_points.csv", "lumbar_path_points.csv"])?,
            moving_knots: read(dir, "moving_point_functions.csv")?,
            wrap_objects: read_all(dir, &["wrap_objects.csv", "lumbar_wrap_objects.csv"])?,
            muscle_wraps: read_all(dir, &["muscle_wraps.csv", "lumbar_muscle_wraps.csv"])?,
        })
    }
}
