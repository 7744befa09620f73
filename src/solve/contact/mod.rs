//! Ground contact forces from kinematics alone (METHOD.md §4).
//!
//! Without force plates the floating-base rows of inverse dynamics say what the ground must
//! supply: with the model's root joint free (6 coordinates; 3 for a planar model), the
//! equations of motion M q̈ + C q̇ + G = τ + J_cᵀ λ have no actuator on the root's coordinates,
//! so on those rows (index set B)
//!
//!   τ_ID,B = (J_cᵀ λ)_B = Σ_p J_p,Bᵀ f_p,
//!
//! with τ_ID = M q̈ + C q̇ + G the generalized forces of inverse dynamics without contact and
//! f_p the force of the ground on contact point p. This module
//! 1. describes the contact points ([`ContactSet`]: the model's ContactSpheres, or points given
//!    by the caller or a JSON file, grouped per foot/hand), their floor (plane n·x = h) and the
//!    floating-base rows B;
//! 2. detects contact over a whole clip ([`detect`]): a Viterbi pass over the groups'
//!    contact states, from every point's height above its resting level and speed relative
//!    to the floor (a treadmill's belt detected from the stance feet), and from the normal
//!    support the whole-body motion needs (none in a running flight phase); a factor in
//!    [0, 1] per frame and point that rolls the load over a foot's points and passes it from
//!    foot to foot over double support;
//! 3. distributes the floating-base rows over the points in contact, frame by frame
//!    ([`ContactWorkspace::distribute`], allocation-free) with a small QP — minimum force plus a
//!    weighted unexplained residual, normal forces ≥ 0, friction pyramid (μ = 0.8 by default);
//! 4. sums each group's forces into what a force plate reports ([`ground_reaction`]): total
//!    force, centre of pressure on the floor and free moment.
//!
//! Typical use, per clip (q, q̇, q̈ frame-major, τ from [`crate::dynamics::rnea`]):
//! ```text
//! let set = ContactSet::from_model(&model)?;
//! let states = detect(&model, &set, &options, &q, &qd, &qdd, rate_hz)?;
//! let set = set.with_floor(states.floor);
//! for each frame t:  rnea(&model, &mut data, q_t, qd_t, qdd_t) → τ;
//!     workspace.distribute(&model, &data, &set, &options, states.frame(t), τ, &mut frame)?;
//!     ground_reaction(&set, &frame, &mut wrenches)?;   // per foot: force, COP, free moment
//!     joint torques: τ − frame.generalized; pelvis residual: frame.residual
//! ```
//!
//! Accuracy (tests/contact_grf.rs, subject01's treadmill walk of OpenSim's Gait2392 and
//! Gait10dof18musc pipelines, stored IK, 6 Hz): per-foot vertical RMSE 3.5 % and 4.0 % of body
//! weight against the force plates with the default options.
//!
//! Frames: everything is in ground; the floor normal is +y unless set (`ContactSet::floor_normal`).
//! Units: metres, seconds, newtons.

mod detect;
mod distribute;
mod low_bodies;
mod wrench;

pub use detect::{ContactStates, detect};
pub use distribute::{ContactFrame, ContactWorkspace};
pub use low_bodies::{LowBody, low_bodies};
pub use wrench::{GroupWrench, ground_reaction};

use crate::error::Error;
use crate::model::{ContactShape, CoordinateRole, DofKind, Model, MotionType};
use crate::spatial::Vec3;

/// Heel, first and fifth metatarsal heads and toe tip of both feet on gait2392's foot geometry
/// (`data/contacts/gait2392_feet.json`, read with [`points_from_json`]). The numbers are those
/// of the default model's table `data/model/contacts.csv` (spheres placed on gait2392's generic
/// foot, tangent to the floor at the default pose) before its height scaling.
pub const GAIT2392_FEET_JSON: &str = include_str!("../../../data/contacts/gait2392_feet.json");

/// A contact point: a sphere fixed in a body; it touches the floor at its lowest point, the
/// centre minus `radius` along the floor normal.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactPoint {
    pub name: String,
    /// Index into `Model::bodies` (not ground).
    pub body: usize,
    /// Sphere centre in the body frame (m).
    pub location_in_body: Vec3,
    /// Sphere radius (m, ≥ 0; 0 for a bare point).
    pub radius: f64,
    /// The group reported together by [`ground_reaction`]: "foot_r", "foot_l", "hand_r", …
    pub group: String,
}

/// The contact points of a model, their groups, the floor and the floating-base rows.
#[derive(Clone, Debug)]
pub struct ContactSet {
    pub points: Vec<ContactPoint>,
    /// Indices in q of the independent coordinates of the root joint (the joint between ground
    /// and the first body): the rows the contact forces must balance.
    pub floating_base: Vec<usize>,
    /// Whether each floating-base row is a rotation (its generalized force a moment, N·m).
    pub floating_base_rotational: Vec<bool>,
    /// Unit floor normal in ground, pointing up (default +y).
    pub floor_normal: Vec3,
    /// Height of the floor along the normal, n·x = h (default 0). [`detect`] may estimate it
    /// per clip; [`ground_reaction`] puts the centre of pressure on this plane.
    pub floor_height: f64,
    /// Group names in order of first appearance, and each point's group index.
    groups: Vec<String>,
    group_of: Vec<usize>,
}

/// The group of a body: `foot_r`/`foot_l` for calcn, toes and talus, `hand_r`/`hand_l` for hand,
/// radius and ulna bodies, otherwise the body's name.
pub fn group_for_body(body_name: &str) -> String {
    let lower = body_name.to_ascii_lowercase();
    let side = if lower.ends_with("_r") || lower.ends_with("_right") {
        Some("r")
    } else if lower.ends_with("_l") || lower.ends_with("_left") {
        Some("l")
    } else {
        None
    };
    let part = ["calcn", "toes", "talus", "foot"]
        .iter()
        .any(|p| lower.starts_with(p))
        .then_some("foot")
        .or_else(|| {
            ["hand", "radius", "ulna", "carp", "finger"]
                .iter()
                .any(|p| lower.starts_with(p))
                .then_some("hand")
        });
    match (part, side) {
        (Some(part), Some(side)) => format!("{part}_{side}"),
        _ => body_name.to_string(),
    }
}

/// An error about `element` of `model`: at its line of the model file when it has one (a
/// line of 0 marks built-in elements), else about the model as a whole.
fn model_error(model: &Model, line: u32, element: &str, message: String) -> Error {
    if line > 0 {
        Error::Model {
            file: model.source.clone(),
            line,
            element: element.to_string(),
            message,
        }
    } else {
        Error::invalid("model", format!("{}: {element}: {message}", model.source))
    }
}

/// The independent coordinates of the root joint, which must float: at least one translational
/// and one rotational coordinate (6 for a free joint, 3 for a planar one).
fn floating_base(model: &Model) -> crate::Result<(Vec<usize>, Vec<bool>)> {
    let roots: Vec<usize> = (0..model.joints.len())
        .filter(|&j| model.joints[j].parent_body == 0 && !model.joints[j].coordinates.is_empty())
        .collect();
    let [root] = roots[..] else {
        // Name the second root joint: with it the model has one too many.
        let (line, element) = match roots.get(1).map(|&j| &model.joints[j]) {
            Some(j) => (j.line, format!("{} \"{}\"", j.kind.name(), j.name)),
            None => (0, "root joint".to_string()),
        };
        return Err(model_error(
            model,
            line,
            &element,
            format!(
                "model \"{}\" has {} joints with coordinates attached to ground; contact \
                 estimation needs exactly one floating root joint",
                model.name,
                roots.len()
            ),
        ));
    };
    let joint = &model.joints[root];
    let mut rows = Vec::new();
    let mut rotational = Vec::new();
    let (mut translations, mut rotations) = (0, 0);
    for &c in &joint.coordinates {
        let coordinate = &model.coordinates[c];
        if let CoordinateRole::Independent(j) = coordinate.role {
            rows.push(j);
            // what the coordinate drives: a slide or a hinge of this joint
            let drives = |kind: DofKind| {
                model.dofs[joint.dof_range.clone()]
                    .iter()
                    .any(|d| d.kind == kind && d.args.contains(&c))
            };
            let (slide, hinge) = match coordinate.motion_type {
                MotionType::Translational => (true, false),
                MotionType::Rotational => (false, true),
                MotionType::Coupled => (drives(DofKind::Slide), drives(DofKind::Hinge)),
            };
            translations += usize::from(slide);
            rotations += usize::from(hinge);
            rotational.push(!slide);
        }
    }
    if translations == 0 || rotations == 0 {
        return Err(model_error(
            model,
            joint.line,
            &format!("{} \"{}\"", joint.kind.name(), joint.name),
            format!(
                "model \"{}\": the root joint has {translations} free translations and \
                 {rotations} free rotations; contact estimation needs a floating root \
                 (6 coordinates, or 3 for a planar model)",
                model.name
            ),
        ));
    }
    Ok((rows, rotational))
}

impl ContactSet {
    /// The model's ContactSpheres, grouped by body ([`group_for_body`]). Errors naming the
    /// model if it has no ContactSphere or no floating root joint.
    pub fn from_model(model: &Model) -> crate::Result<ContactSet> {
        let points: Vec<ContactPoint> = model
            .contact_geometry
            .iter()
            .filter_map(|g| match g.shape {
                ContactShape::Sphere { radius } => Some(ContactPoint {
                    name: g.name.clone(),
                    body: g.body,
                    location_in_body: g.pose_in_body.pos,
                    radius,
                    group: group_for_body(&model.bodies[g.body].name),
                }),
                ContactShape::HalfSpace => None,
            })
            .collect();
        if points.is_empty() {
            return Err(model_error(
                model,
                0,
                "ContactGeometrySet",
                format!(
                    "model \"{}\" has no ContactSphere; give the contact points with \
                     ContactSet::from_points",
                    model.name
                ),
            ));
        }
        Self::from_points(model, points)
    }

    /// A set from points given by the caller. Errors name the first bad point (unknown or
    /// ground body, non-finite location, negative radius, empty or repeated name).
    pub fn from_points(model: &Model, points: Vec<ContactPoint>) -> crate::Result<ContactSet> {
        if points.is_empty() {
            return Err(Error::invalid("points", "no contact points"));
        }
        for (i, p) in points.iter().enumerate() {
            let bad = |message: String| {
                Error::invalid("points", format!("point {i} (\"{}\"): {message}", p.name))
            };
            if p.name.is_empty() || points[..i].iter().any(|q| q.name == p.name) {
                return Err(bad("empty or repeated name".into()));
            }
            if p.body == 0 || p.body >= model.bodies.len() {
                return Err(bad(format!(
                    "body index {} is ground or out of range ({} bodies)",
                    p.body,
                    model.bodies.len()
                )));
            }
            if !p.location_in_body.iter().all(|v| v.is_finite()) {
                return Err(bad(format!(
                    "location {:?} is not finite",
                    p.location_in_body
                )));
            }
            if !(p.radius >= 0.0 && p.radius.is_finite()) {
                return Err(bad(format!("radius {} must be ≥ 0 and finite", p.radius)));
            }
            if p.group.is_empty() {
                return Err(bad("empty group".into()));
            }
        }
        let (floating_base, floating_base_rotational) = floating_base(model)?;
        let mut groups: Vec<String> = Vec::new();
        let mut group_of = Vec::with_capacity(points.len());
        for p in &points {
            let g = match groups.iter().position(|g| *g == p.group) {
                Some(g) => g,
                None => {
                    groups.push(p.group.clone());
                    groups.len() - 1
                }
            };
            group_of.push(g);
        }
        Ok(ContactSet {
            points,
            floating_base,
            floating_base_rotational,
            floor_normal: Vec3::y(),
            floor_height: 0.0,
            groups,
            group_of,
        })
    }

    /// The group names, in order of first appearance among the points.
    pub fn groups(&self) -> &[String] {
        &self.groups
    }

    /// The group index of point `p`.
    pub fn group_of(&self, p: usize) -> usize {
        self.group_of[p]
    }

    /// This set with the floor at height `h` (e.g. [`ContactStates::floor`]).
    pub fn with_floor(mut self, h: f64) -> ContactSet {
        self.floor_height = h;
        self
    }

    /// This set with another floor normal (normalised; must be finite and non-zero).
    pub fn with_floor_normal(mut self, normal: Vec3) -> crate::Result<ContactSet> {
        let norm = normal.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            return Err(Error::invalid(
                "normal",
                format!("{normal:?} must be finite and non-zero"),
            ));
        }
        self.floor_normal = normal / norm;
        Ok(self)
    }

    /// Two unit tangents (t₁, t₂) of the floor such that (t₁, n, t₂) is right-handed, as
    /// (x, y, z) are for n = +y: t₁ is ground x projected on the floor (z if n ∥ x).
    pub fn floor_tangents(&self) -> (Vec3, Vec3) {
        let n = self.floor_normal;
        let mut t1 = Vec3::x() - n * n.x;
        if t1.norm() < 1e-6 {
            t1 = Vec3::z() - n * n.z;
        }
        let t1 = t1.normalize();
        (t1, t1.cross(&n))
    }
}

/// Contact points from a JSON document (`source` names it in errors):
/// `{"points": [{"name": "heel_r", "body": "calcn_r", "location": [x, y, z], "radius": r,
/// "group": "foot_r"}, …], "scale_reference": {"joint": "mtp_r", "length": L}}`.
/// `group` is optional ([`group_for_body`] by default). Locations and radii are multiplied by
/// `scale`, or, when `scale` is None and the document has a `scale_reference`, by the length of
/// that joint's parent-frame offset in `model` divided by `length` (the foot scale factor of a
/// scaled model: the calcaneus-to-toes offset for `mtp_r`).
pub fn points_from_json(
    model: &Model,
    json: &str,
    source: &str,
    scale: Option<f64>,
) -> crate::Result<Vec<ContactPoint>> {
    // serde_json's values keep no positions: an element is named by its JSON path.
    let err = |element: String, message: String| Error::Motion {
        file: source.to_string(),
        location: element,
        message,
    };
    let doc: serde_json::Value = serde_json::from_str(json).map_err(|e| Error::Model {
        file: source.to_string(),
        line: u32::try_from(e.line()).unwrap_or(u32::MAX),
        element: format!("column {}", e.column()),
        message: format!("not a JSON document: {e}"),
    })?;
    let scale = match scale {
        Some(s) if s > 0.0 && s.is_finite() => s,
        Some(s) => return Err(Error::invalid("scale", format!("{s} must be positive"))),
        None => match doc.get("scale_reference") {
            None => 1.0,
            Some(r) => {
                let joint_name = r.get("joint").and_then(|v| v.as_str()).unwrap_or("");
                let length = r.get("length").and_then(|v| v.as_f64()).unwrap_or(f64::NAN);
                let Some(j) = model.joint_index(joint_name) else {
                    return Err(err(
                        "scale_reference.joint".into(),
                        format!("model \"{}\" has no joint \"{joint_name}\"", model.name),
                    ));
                };
                if !(length > 0.0 && length.is_finite()) {
                    return Err(err(
                        "scale_reference.length".into(),
                        "must be a positive number".into(),
                    ));
                }
                model.joints[j].parent_offset.pos.norm() / length
            }
        },
    };
    let Some(list) = doc.get("points").and_then(|v| v.as_array()) else {
        return Err(err("points".into(), "missing or not an array".into()));
    };
    let mut points = Vec::with_capacity(list.len());
    for (i, p) in list.iter().enumerate() {
        let field = |name: &str| p.get(name);
        let element = |name: &str| format!("points[{i}].{name}");
        let name = field("name")
            .and_then(|v| v.as_str())
            .ok_or_else(|| err(element("name"), "missing or not a string".into()))?;
        let body_name = field("body")
            .and_then(|v| v.as_str())
            .ok_or_else(|| err(element("body"), "missing or not a string".into()))?;
        let body = model.body_index(body_name).ok_or_else(|| {
            err(
                element("body"),
                format!("model \"{}\" has no body \"{body_name}\"", model.name),
            )
        })?;
        let location: Vec<f64> = field("location")
            .and_then(|v| v.as_array())
            .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
            .unwrap_or_default();
        if location.len() != 3 {
            return Err(err(element("location"), "needs 3 numbers".into()));
        }
        let radius = field("radius")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| err(element("radius"), "missing or not a number".into()))?;
        let group = match field("group") {
            None => group_for_body(body_name),
            Some(g) => g
                .as_str()
                .ok_or_else(|| err(element("group"), "not a string".into()))?
                .to_string(),
        };
        points.push(ContactPoint {
            name: name.to_string(),
            body,
            location_in_body: Vec3::new(location[0], location[1], location[2]) * scale,
            radius: radius * scale,
            group,
        });
    }
    Ok(points)
}

/// Settings of [`detect`] and [`ContactWorkspace::distribute`]; defaults in [`Default`].
#[derive(Clone, Debug, PartialEq)]
pub struct ContactOptions {
    /// Floor height along the normal (m). None: estimated per clip as the `floor_percentile`
    /// of the lowest points' heights over all frames and points (HumanML3D clips float or sink
    /// by a few cm). Default None.
    pub floor_height: Option<f64>,
    /// Percentile (0–100) used to estimate the floor. Default 5.
    pub floor_percentile: f64,
    /// Velocity of the floor in ground (m/s), e.g. a treadmill belt: speeds are measured
    /// relative to it. None: from the clip, as `floor_motion` says. Default None.
    pub floor_velocity: Option<Vec3>,
    /// Without a given `floor_velocity`: whether to detect a treadmill from the stance feet
    /// (the default) or take one as known (its speed given or estimated).
    pub floor_motion: FloorMotion,
    /// Scale of a point's height above its resting level in contact, σ_h (m): the
    /// kinematic likelihood of contact falls as exp(−½ (h/σ_h)²). Default 0.02 m, the
    /// accuracy of a fitted foot's height (skin and shoe-sole movement, marker placement).
    pub height_scale: f64,
    /// Scale of a point's speed relative to the floor in contact, σ_s (m/s), likewise.
    /// Default 0.5 m/s: a rolling foot's contact points move by a few tenths of a metre per
    /// second; a swinging foot moves at metres per second.
    pub speed_scale: f64,
    /// Scale of the normal support the motion needs and no contact gives (or the pull a
    /// contact would have to give), σ_d, in body weights. Default 0.1: the accuracy of a
    /// whole-body acceleration from low-pass filtered kinematics.
    pub demand_scale: f64,
    /// Scale of the ground moment the motion needs about the support of a contact state and
    /// that state's contacts cannot give, σ_b, in body weight × metres: with d the normal
    /// demand and e the distance (m) from the centre of pressure the motion needs to the
    /// hull of the state's points on the floor, the state costs ½(d e / σ_b)². Default 0.1:
    /// σ_d times a lever arm of a metre, the height of the centre of mass whose acceleration
    /// errors make it.
    pub balance_scale: f64,
    /// Time over which the dynamic evidence fades out towards the clip's first and last
    /// frames (s), whose accelerations rest on the low-pass filter's and the splines' end
    /// conditions. Default 0.05 s.
    pub end_time: f64,
    /// Expected contact changes per second and group (strikes and lifts), which sets the
    /// cost of a change between frames, ln(rate / this). Default 4 (a stride a second
    /// walking or running has two per foot; twice that for margin).
    pub transition_rate: f64,
    /// The highest a point's resting level may sit above the floor (m): a foot fitted with a
    /// few degrees of pitch rests with its heel or toe that high. Default 0.1 m.
    pub max_point_offset: f64,
    /// The slowest belt taken as a treadmill when detecting one (m/s): stance feet on a still
    /// floor move less than this. Default 0.2 m/s.
    pub belt_speed_min: f64,
    /// The longest time over which load passes from one group to another where their
    /// contacts overlap (s): the factor ramps over the overlap, at most this long.
    /// Default 0.2 s, about a walking double-support period.
    pub transition_time: f64,
    /// Friction coefficient μ: each force lies in the pyramid inscribed in the friction cone
    /// (edges n ± μ t₁, n ± μ t₂). None: normal ≥ 0, tangential force free — then the QP may
    /// balance pelvis moments with large opposing tangential forces between points.
    /// Default Some(0.8).
    pub friction: Option<f64>,
    /// Without friction: weight of the tangential force coordinates relative to the normal
    /// one (w_t in Σ_p (1/φ_p)(f_n² + w_t ‖f_t‖²)); a larger weight discourages opposing
    /// tangential forces between points. Default 1. (With a friction pyramid the edge
    /// coefficients all have weight 1/φ_p.)
    pub tangential_weight: f64,
    /// Weights of the unexplained residual relative to the force terms: the objective is
    /// Σ_p (1/factor_p) ‖x_p‖² + w_f ‖r_f‖² + w_m ‖r_m‖², x_p the point's force coordinates
    /// (N), r_f the floating-base translation rows left (N) and r_m the rotation rows left
    /// (N·m). Default 1e8 for forces: the force residual is used only where no contact force
    /// can balance the rows (the total vertical force is then m g + m a_y exactly). Default
    /// 100 for moments: a moment residual of 1 N·m costs as much as 10 N of force at full
    /// contact, so moments the contacts could only make with implausible forces (typically
    /// inconsistencies of the kinematics, of the order of OpenSim's pelvis residuals with
    /// measured plates, ~10–20 N·m RMS) are left as residual. Set it to 1e8 to reproduce the
    /// moment rows whenever the contacts can.
    pub residual_weight: f64,
    pub residual_moment_weight: f64,
    /// Settings of the QP solver (the exponent must stay 2).
    pub qp: crate::solve::qp::QpSettings,
}

impl Default for ContactOptions {
    fn default() -> Self {
        ContactOptions {
            floor_height: None,
            floor_percentile: 5.0,
            floor_velocity: None,
            floor_motion: FloorMotion::Detect,
            height_scale: 0.02,
            speed_scale: 0.5,
            demand_scale: 0.1,
            balance_scale: 0.2,
            end_time: 0.05,
            transition_rate: 4.0,
            max_point_offset: 0.1,
            belt_speed_min: 0.2,
            transition_time: 0.2,
            friction: Some(0.8),
            tangential_weight: 1.0,
            residual_weight: 1e8,
            residual_moment_weight: 100.0,
            qp: crate::solve::qp::QpSettings::default(),
        }
    }
}

impl ContactOptions {
    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |field: &'static str, value: f64, need: &str| {
            Err(Error::invalid(field, format!("{value}: must be {need}")))
        };
        if let Some(h) = self.floor_height
            && !h.is_finite()
        {
            return bad("floor_height", h, "finite");
        }
        if !(0.0..=100.0).contains(&self.floor_percentile) {
            return bad("floor_percentile", self.floor_percentile, "in [0, 100]");
        }
        if let Some(v) = self.floor_velocity
            && !v.iter().all(|x| x.is_finite())
        {
            return bad("floor_velocity", v.norm(), "finite");
        }
        if let FloorMotion::Treadmill { speed: Some(v) } = self.floor_motion
            && !(v >= 0.0 && v.is_finite())
        {
            return bad("floor_motion", v, "a finite speed ≥ 0");
        }
        for (field, value) in [
            ("height_scale", self.height_scale),
            ("speed_scale", self.speed_scale),
            ("demand_scale", self.demand_scale),
            ("balance_scale", self.balance_scale),
            ("transition_rate", self.transition_rate),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return bad(field, value, "positive");
            }
        }
        for (field, value) in [
            ("max_point_offset", self.max_point_offset),
            ("end_time", self.end_time),
            ("belt_speed_min", self.belt_speed_min),
        ] {
            if !(value >= 0.0 && value.is_finite()) {
                return bad(field, value, "≥ 0");
            }
        }
        if !(self.transition_time >= 0.0 && self.transition_time.is_finite()) {
            return bad("transition_time", self.transition_time, "≥ 0");
        }
        if let Some(mu) = self.friction
            && !(mu > 0.0 && mu.is_finite())
        {
            return bad("friction", mu, "positive");
        }
        if !(self.tangential_weight > 0.0 && self.tangential_weight.is_finite()) {
            return bad("tangential_weight", self.tangential_weight, "positive");
        }
        if !(self.residual_weight > 0.0 && self.residual_weight.is_finite()) {
            return bad("residual_weight", self.residual_weight, "positive");
        }
        if !(self.residual_moment_weight > 0.0 && self.residual_moment_weight.is_finite()) {
            return bad(
                "residual_moment_weight",
                self.residual_moment_weight,
                "positive",
            );
        }
        if self.qp.exponent != 2.0 {
            return bad("qp.exponent", self.qp.exponent, "2");
        }
        self.qp
            .validate()
            .map_err(|e| Error::invalid("qp", e.to_string()))
    }
}

/// How the floor moves when no velocity is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FloorMotion {
    /// A treadmill when the stance feet move together at `belt_speed_min` or more, else
    /// still.
    Detect,
    /// A treadmill: its speed given (m/s, direction from the stance feet) or estimated.
    Treadmill { speed: Option<f64> },
}

/// smoothstep: 0 for x ≤ 0, 1 for x ≥ 1, 3x² − 2x³ between.
pub(crate) fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}
