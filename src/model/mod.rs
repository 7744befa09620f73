//! The immutable `Model`: everything read from a model file, arranged for the dynamics
//! algorithms (bodies and joints in topological order, flat id-indexed arrays).
//!
//! Three levels of coordinates exist, from the outside in:
//! - **independent coordinates** `q` (length `nq()`): the model's degrees of freedom — every
//!   OpenSim `Coordinate` that is neither locked nor the dependent coordinate of a
//!   `CoordinateCouplerConstraint`. All dynamics quantities (M, bias, τ, Jacobians) are in q.
//! - **coordinates**: every OpenSim `Coordinate`, in file order (joint by joint). Locked ones
//!   are held at their default value; dependent ones are `scale · f(independent …)`.
//! - **full coordinates** `θ = q_full` (length `n_full()`): one per movable transform axis
//!   (a hinge or a slide), as MuJoCo would see the expanded tree. Each is a function of
//!   coordinates: for a CustomJoint the TransformAxis function, for the other joint types
//!   the coordinate itself. θ = φ(q), Φ = ∂φ/∂q.

pub mod builder;
mod frames;
pub mod function;
mod knots;
pub mod natural_spline;
mod osim;
pub(crate) mod reduction;
pub mod reserves;

pub use frames::resolve_path;
pub use function::{Arity, Function};
pub(crate) use osim::FunctionReader;
pub use osim::{ForceSetFiles, LoadOptions};
pub use reduction::Reduction;

use crate::spatial::{Mat3, Transform, Vec3};
use std::path::Path;

/// A rigid body. Index 0 of `Model::bodies` is ground.
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    pub mass: f64,
    /// Centre of mass in the body frame.
    pub com_in_body: Vec3,
    /// Inertia about the centre of mass, in body axes (symmetric).
    pub inertia_about_com: Mat3,
    /// The joint that moves this body (None for ground).
    pub joint: Option<usize>,
    /// The parent body (None for ground).
    pub parent: Option<usize>,
    /// Line of the body's element in the model file (0 for built-in bodies).
    pub line: u32,
}

/// The OpenSim joint types musculo reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    Custom,
    Pin,
    Slider,
    Weld,
    Universal,
    Ball,
    Gimbal,
    Free,
    Planar,
}

impl JointKind {
    pub fn name(&self) -> &'static str {
        match self {
            JointKind::Custom => "CustomJoint",
            JointKind::Pin => "PinJoint",
            JointKind::Slider => "SliderJoint",
            JointKind::Weld => "WeldJoint",
            JointKind::Universal => "UniversalJoint",
            JointKind::Ball => "BallJoint",
            JointKind::Gimbal => "GimbalJoint",
            JointKind::Free => "FreeJoint",
            JointKind::Planar => "PlanarJoint",
        }
    }
}

/// One step of a joint's transform from its parent frame F to its child frame M.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointStep {
    /// A fixed transform (e.g. a TransformAxis driven by a Constant function).
    Fixed(Transform),
    /// A movable axis: the full coordinate (dof) with this index.
    Dof(usize),
}

/// A joint connecting `parent_body` to `child_body`:
/// X_G,child = X_G,parent · parent_offset · X_FM(θ) · child_offset⁻¹.
#[derive(Clone, Debug)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    pub parent_body: usize,
    pub child_body: usize,
    /// Pose of the joint's parent frame F in the parent body.
    pub parent_offset: Transform,
    /// Pose of the joint's child frame M in the child body.
    pub child_offset: Transform,
    /// `child_offset⁻¹`, precomputed.
    pub child_offset_inv: Transform,
    /// The joint's coordinates (indices into `Model::coordinates`).
    pub coordinates: Vec<usize>,
    /// The transform F → M, applied in order: translations along F's axes, then body-fixed
    /// rotations (OpenSim's convention for every joint type).
    pub steps: Vec<JointStep>,
    /// Range of this joint's full coordinates (dofs) in `Model::dofs`.
    pub dof_range: std::ops::Range<usize>,
    pub line: u32,
}

/// Hinge (rotation about an axis) or slide (translation along an axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DofKind {
    Hinge,
    Slide,
}

/// A full coordinate: one movable transform axis of a joint.
#[derive(Clone, Debug)]
pub struct Dof {
    /// `joint/axis`, e.g. `knee_r/translation1`.
    pub name: String,
    pub joint: usize,
    pub kind: DofKind,
    /// Unit axis in the frame that precedes this step in the joint's chain (F for slides;
    /// for hinges the frame after the previous rotations, i.e. body-fixed).
    pub axis: Vec3,
    /// θ = function(coordinates\[args\]).
    pub function: Function,
    /// Arguments of `function` (indices into `Model::coordinates`).
    pub args: Vec<usize>,
    /// The preceding dof in the kinematic tree (None if only ground precedes it).
    pub parent_dof: Option<usize>,
    /// The body this dof moves (its joint's child body).
    pub body: usize,
}

impl Dof {
    /// For an axis along ±x, ±y or ±z: its index (0, 1, 2) and sign. Rotations and
    /// translations about such axes need no general Rodrigues formula.
    #[inline]
    pub fn elementary_axis(&self) -> Option<(usize, f64)> {
        let a = &self.axis;
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            if a[i] == 0.0 && a[j] == 0.0 && a[k].abs() == 1.0 {
                return Some((k, a[k]));
            }
        }
        None
    }
}

/// What an OpenSim coordinate is to the reduced model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoordinateRole {
    /// The j-th independent coordinate q_j.
    Independent(usize),
    /// Locked: held at its default value.
    Locked,
    /// The dependent coordinate of the coupler constraint with this index.
    Dependent(usize),
}

/// OpenSim's coordinate motion type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionType {
    Rotational,
    Translational,
    Coupled,
}

/// An OpenSim Coordinate.
#[derive(Clone, Debug)]
pub struct Coordinate {
    pub name: String,
    pub joint: usize,
    pub motion_type: MotionType,
    pub default_value: f64,
    pub default_speed: f64,
    pub range: [f64; 2],
    pub clamped: bool,
    pub locked: bool,
    pub prescribed: bool,
    pub role: CoordinateRole,
    pub line: u32,
}

/// OpenSim CoordinateCouplerConstraint: coordinates\[dependent\] =
/// scale · function(coordinates\[independents\]).
#[derive(Clone, Debug)]
pub struct CouplerConstraint {
    pub name: String,
    pub dependent: usize,
    pub independents: Vec<usize>,
    pub function: Function,
    pub scale: f64,
    pub line: u32,
}

/// A marker fixed in a body.
#[derive(Clone, Debug)]
pub struct Marker {
    pub name: String,
    pub body: usize,
    pub location_in_body: Vec3,
    pub fixed: bool,
}

/// Contact geometry shapes.
#[derive(Clone, Debug, PartialEq)]
pub enum ContactShape {
    Sphere {
        radius: f64,
    },
    /// The half-space x < 0 of its frame (OpenSim's convention: the outward normal is the
    /// frame's −x... see `ContactHalfSpace`); the plane passes through the frame origin.
    HalfSpace,
}

/// OpenSim ContactSphere / ContactHalfSpace, fixed in a body.
#[derive(Clone, Debug)]
pub struct ContactGeometry {
    pub name: String,
    pub body: usize,
    /// Pose of the geometry frame in the body.
    pub pose_in_body: Transform,
    pub shape: ContactShape,
}

/// A path point of a muscle or other path actuator.
#[derive(Clone, Debug)]
pub struct PathPoint {
    pub name: String,
    pub body: usize,
    /// Pose of the point's parent frame in `body` (identity when attached to the body).
    pub frame_in_body: Transform,
    /// Location in that frame (for a moving point: its value at the default pose).
    pub location: Vec3,
    pub kind: PathPointKind,
    pub line: u32,
}

#[derive(Clone, Debug)]
pub enum PathPointKind {
    Fixed,
    /// Active only while `coordinate` lies in `range`.
    Conditional {
        coordinate: usize,
        range: [f64; 2],
    },
    /// Each component of the location is a function of one coordinate.
    Moving {
        x: (Function, usize),
        y: (Function, usize),
        z: (Function, usize),
    },
}

/// A wrap-object reference of a geometry path.
#[derive(Clone, Debug)]
pub struct PathWrap {
    pub wrap_object: usize,
    pub method: String,
    /// Path-point range (1-based, OpenSim's), `[-1, -1]` meaning the whole path.
    pub range: [i32; 2],
}

/// A muscle's or path actuator's geometry path.
#[derive(Clone, Debug, Default)]
pub struct GeometryPath {
    pub points: Vec<PathPoint>,
    pub wraps: Vec<PathWrap>,
}

/// Wrap surfaces.
#[derive(Clone, Debug, PartialEq)]
pub enum WrapShape {
    Sphere {
        radius: f64,
    },
    Cylinder {
        radius: f64,
        length: f64,
    },
    Ellipsoid {
        dimensions: Vec3,
    },
    Torus {
        inner_radius: f64,
        outer_radius: f64,
    },
}

/// A wrap object fixed in a body.
#[derive(Clone, Debug)]
pub struct WrapObject {
    pub name: String,
    pub body: usize,
    pub pose_in_body: Transform,
    pub shape: WrapShape,
    pub quadrant: String,
    pub active: bool,
    pub line: u32,
}

/// An element kept verbatim from the file (tag, name attribute, text, children), so that
/// nothing the next stages need is lost.
#[derive(Clone, Debug, Default)]
pub struct RawElement {
    pub tag: String,
    pub name: Option<String>,
    pub text: String,
    pub line: u32,
    pub children: Vec<RawElement>,
}

impl RawElement {
    /// The first child with this tag.
    pub fn child(&self, tag: &str) -> Option<&RawElement> {
        self.children.iter().find(|c| c.tag == tag)
    }

    /// A child's text parsed as one number.
    pub fn number(&self, tag: &str) -> Option<f64> {
        self.child(tag).and_then(|c| c.text.trim().parse().ok())
    }
}

/// A force element of the ForceSet (muscles, actuators, springs...). Its physics is not part
/// of the rigid-body dynamics; the raw element is kept for the muscle and actuator stages.
#[derive(Clone, Debug)]
pub struct ForceElement {
    pub name: String,
    /// OpenSim class name, e.g. `Thelen2003Muscle`.
    pub kind: String,
    /// Geometry path, for muscles and path actuators; shared between copies of a model
    /// (`Arc::make_mut` edits a copy's own).
    pub path: Option<std::sync::Arc<GeometryPath>>,
    /// `<appliesForce>` (OpenSim 4; `false` disables the element).
    pub applies_force: bool,
    /// For OpenSim's scalar actuators (muscles included): control bounds, optimal force and
    /// where the force acts.
    pub actuator: Option<ScalarActuator>,
    /// The element as read; shared between copies of a model, as `path` is (a clip's model
    /// is a copy of the scaled one).
    pub raw: std::sync::Arc<RawElement>,
    pub line: u32,
    /// The file the element was read from (the model's, or the force-set file that added
    /// it), for messages; empty for elements built in code.
    pub file: String,
}

/// A scalar actuator: one control x produces the force (or torque) x · `optimal_force`,
/// x ∈ [`min_control`, `max_control`] (OpenSim's ScalarActuator; for muscles x is the
/// activation and the force comes from the muscle model).
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarActuator {
    pub min_control: f64,
    pub max_control: f64,
    pub optimal_force: f64,
    pub kind: ActuatorKind,
}

/// Where a scalar actuator's force acts, resolved to the model's bodies and coordinates.
#[derive(Clone, Debug, PartialEq)]
pub enum ActuatorKind {
    /// A muscle: tension along its geometry path.
    Muscle,
    /// A PathActuator: tension x · F_opt along its geometry path.
    Path,
    /// A CoordinateActuator: generalized force on the coordinate (`Model::coordinates`
    /// index).
    Coordinate { coordinate: usize },
    /// A PointActuator: force along the unit `direction` (in ground if `force_is_global`,
    /// else in the body) at `point` (in ground if `point_is_global`, else in the body).
    Point {
        body: usize,
        point: Vec3,
        point_is_global: bool,
        direction: Vec3,
        force_is_global: bool,
    },
    /// A TorqueActuator: torque about the unit `axis` (in ground if `torque_is_global`, else
    /// in body A) on `body_a`, and its opposite on `body_b`.
    Torque {
        body_a: usize,
        body_b: usize,
        axis: Vec3,
        torque_is_global: bool,
    },
}

impl ForceElement {
    /// True for OpenSim muscle classes.
    pub fn is_muscle(&self) -> bool {
        self.kind.ends_with("Muscle")
    }

    /// The file to name in a message about this element: the one it was read from, or the
    /// model's (`model_source`) for an element built in code.
    pub fn file_or<'a>(&'a self, model_source: &'a str) -> &'a str {
        if self.file.is_empty() {
            model_source
        } else {
            &self.file
        }
    }
}

/// Something in the model file that musculo read but does not use, treats in a documented
/// simplified way, or accepts although it is not physical. Never silent: `musculo inspect`
/// lists them all, and every command that loads a model prints the
/// [`WarningKind::NonphysicalInertia`] ones.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    pub line: u32,
    pub element: String,
    pub message: String,
    pub kind: WarningKind,
}

/// What a model [`Warning`] is about.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WarningKind {
    /// An element read but not used, or used in a documented simplified way.
    #[default]
    NotUsed,
    /// A body whose principal moments of inertia violate the triangle inequality, accepted
    /// because [`LoadOptions::strict`] is off (as OpenSim's release builds accept it).
    NonphysicalInertia,
}

/// The immutable model. Build it with [`Model::from_osim_file`] or [`Model::from_osim_str`].
#[derive(Clone, Debug)]
pub struct Model {
    pub name: String,
    /// Where the model was read from (a path, or a label such as `<demo>`).
    pub source: String,
    /// Gravity in ground (m/s²).
    pub gravity: Vec3,
    /// Bodies; `bodies[0]` is ground; a body's parent always precedes it.
    pub bodies: Vec<Body>,
    /// Joints in topological order (a joint's parent body is moved by an earlier joint).
    pub joints: Vec<Joint>,
    pub coordinates: Vec<Coordinate>,
    /// Full coordinates (movable transform axes), in tree order.
    pub dofs: Vec<Dof>,
    pub couplers: Vec<CouplerConstraint>,
    pub markers: Vec<Marker>,
    pub contact_geometry: Vec<ContactGeometry>,
    pub forces: Vec<ForceElement>,
    pub wrap_objects: Vec<WrapObject>,
    /// Elements read but not used, with the reason.
    pub warnings: Vec<Warning>,
    /// Number of display-only elements (meshes, appearance, frame geometry) skipped.
    pub visual_elements_skipped: usize,
    /// Independent coordinates and the evaluation plan for θ = φ(q).
    pub reduction: Reduction,
}

impl Model {
    /// Reads an OpenSim 4.x `.osim` file.
    pub fn from_osim_file(path: impl AsRef<Path>) -> crate::Result<Model> {
        Self::from_osim_file_with(path, &LoadOptions::default())
    }

    /// Reads an OpenSim 4.x `.osim` file with options.
    pub fn from_osim_file_with(
        path: impl AsRef<Path>,
        options: &LoadOptions,
    ) -> crate::Result<Model> {
        let path = path.as_ref();
        let text = crate::text::read_text(path)?;
        osim::parse(&text, &path.display().to_string(), options)
    }

    /// Reads an `.osim` file and adds the forces of OpenSim force-set files (reserve and
    /// residual actuators, typically), as the `<force_set_files>` of a tool's setup do. With
    /// `replace`, the model's own forces are dropped first (`<replace_force_set>`).
    pub fn from_osim_file_with_force_sets(
        path: impl AsRef<Path>,
        options: &LoadOptions,
        force_set_files: &[impl AsRef<Path>],
        replace: bool,
    ) -> crate::Result<Model> {
        let read = crate::text::read_text;
        let path = path.as_ref();
        let text = read(path)?;
        let mut sets = ForceSetFiles {
            files: Vec::new(),
            replace,
        };
        for f in force_set_files {
            let f = f.as_ref();
            sets.files.push((read(f)?, f.display().to_string()));
        }
        osim::parse_with_force_sets(&text, &path.display().to_string(), options, &sets)
    }

    /// Parses OpenSim 4.x XML together with force-set files given as text (see
    /// [`Model::from_osim_file_with_force_sets`]).
    pub fn from_osim_str_with_force_sets(
        xml: &str,
        source: &str,
        options: &LoadOptions,
        force_sets: &ForceSetFiles,
    ) -> crate::Result<Model> {
        osim::parse_with_force_sets(xml, source, options, force_sets)
    }

    /// Parses OpenSim 4.x XML; `source` names it in error messages.
    pub fn from_osim_str(xml: &str, source: &str) -> crate::Result<Model> {
        osim::parse(xml, source, &LoadOptions::default())
    }

    /// Parses OpenSim 4.x XML with options.
    pub fn from_osim_str_with(
        xml: &str,
        source: &str,
        options: &LoadOptions,
    ) -> crate::Result<Model> {
        osim::parse(xml, source, options)
    }

    /// The small built-in demonstration model (`models/demo.osim`).
    pub fn demo() -> Model {
        osim::parse(crate::DEMO_MODEL_OSIM, "<demo>", &LoadOptions::default())
            .expect("the built-in demo model is valid")
    }

    /// The default full-body model (`models/musculo_fullbody.osim`, embedded in the library).
    pub fn default_fullbody() -> Model {
        osim::parse(
            crate::DEFAULT_MODEL_OSIM,
            "<default model: models/musculo_fullbody.osim>",
            &LoadOptions::default(),
        )
        .expect("the built-in default model is valid")
    }

    /// Number of independent coordinates n.
    pub fn nq(&self) -> usize {
        self.reduction.independent.len()
    }

    /// Number of full coordinates (movable transform axes).
    pub fn n_full(&self) -> usize {
        self.dofs.len()
    }

    pub fn total_mass(&self) -> f64 {
        self.bodies.iter().map(|b| b.mass).sum()
    }

    /// Why the model has no weight m |g| > 0 (zero gravity, or no mass), or None. The
    /// results that are per body weight (the verdicts of `augment`, the metrics of
    /// `evaluate`) are NaN for such a model.
    pub fn weightless(&self) -> Option<String> {
        let mass = self.total_mass();
        let gravity = self.gravity.norm();
        (!(mass * gravity > 0.0 && (mass * gravity).is_finite())).then(|| {
            format!(
                "the model \"{}\" has no weight (mass {mass} kg, gravity {gravity})",
                self.name
            )
        })
    }

    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.name == name)
    }

    pub fn coordinate_index(&self, name: &str) -> Option<usize> {
        self.coordinates.iter().position(|c| c.name == name)
    }

    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Index in q of the named coordinate, if it is independent.
    pub fn q_index(&self, coordinate: &str) -> Option<usize> {
        match self.coordinates[self.coordinate_index(coordinate)?].role {
            CoordinateRole::Independent(j) => Some(j),
            _ => None,
        }
    }

    /// Names of the independent coordinates, in q order.
    pub fn q_names(&self) -> Vec<&str> {
        self.reduction
            .independent
            .iter()
            .map(|&c| self.coordinates[c].name.as_str())
            .collect()
    }

    /// The default independent coordinates (each coordinate's `default_value`).
    pub fn default_q(&self) -> Vec<f64> {
        self.reduction
            .independent
            .iter()
            .map(|&c| self.coordinates[c].default_value)
            .collect()
    }

    /// Number of muscles in the force set.
    pub fn muscle_count(&self) -> usize {
        self.forces.iter().filter(|f| f.is_muscle()).count()
    }
}
