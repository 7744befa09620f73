//! Export to MuJoCo's MJCF, as the *expanded* tree: one MuJoCo hinge or slide joint per
//! movable transform axis, in the order OpenSim applies them, so that MuJoCo's qpos are
//! musculo's full coordinates θ (joint names are the full coordinates' names,
//! `joint/axis`).
//!
//! Each MuJoCo body frame is the OpenSim body frame. With the joint's fixed steps and the
//! full coordinates at zero, the body sits at X_PB(0) = X_PF · X_FM(0) · X_MB; a joint's axis
//! and anchor are those of its transform axis expressed in the body frame at θ = 0. MuJoCo
//! composes a body's joints by right-multiplying body-fixed motions, which reproduces
//! X_FM(θ) = Π (fixed step)·(axis motion) exactly, fixed rotations between axes included.
//!
//! What MJCF cannot express is approximated where possible and always listed in
//! [`MjcfExport::notes`]: couplings between full coordinates become joint equality
//! constraints with quartic polynomials (splines are fitted), except that an axis depending on
//! several independent coordinates (through a coupler or a `MultivariatePolynomialFunction`
//! of several coordinates) is left free, as an equality couples two joints only; conditional
//! and moving path
//! points become fixed sites, ellipsoid and torus wrap objects are left out, and MuJoCo's
//! muscle curves replace the Hill-type ones (optimal fibre and tendon slack lengths and the
//! maximum force and velocity are kept).

use crate::dynamics::{self, Data};
use crate::model::{
    ContactShape, DofKind, ForceElement, GeometryPath, JointStep, Model, PathPointKind, WrapObject,
    WrapShape,
};
use crate::spatial::{Mat3, Transform, Vec3};
use nalgebra::{DMatrix, DVector, UnitQuaternion};
use std::collections::HashMap;
use std::fmt::Write;

/// The MJCF text and the list of everything it could not express exactly.
#[derive(Clone, Debug)]
pub struct MjcfExport {
    pub xml: String,
    pub notes: Vec<String>,
}

/// Default range of normalised fibre length of MuJoCo's muscle (its `range` attribute).
const MUSCLE_RANGE: [f64; 2] = [0.75, 1.05];

fn v3(v: &Vec3) -> String {
    format!("{} {} {}", v.x, v.y, v.z)
}

fn quat(r: &Mat3) -> String {
    let q = UnitQuaternion::from_matrix(r);
    format!("{} {} {} {}", q.w, q.i, q.j, q.k)
}

/// XML-escapes a name for an attribute value.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Pose, in the body frame at θ = 0, of the frame that precedes each step of a joint; and
/// X_PB(0).
fn joint_frames_at_zero(model: &Model, j: usize) -> (Transform, HashMap<usize, Transform>) {
    let joint = &model.joints[j];
    let mut c = Transform::identity(); // X_F,current
    let mut before = Vec::new();
    for step in &joint.steps {
        match step {
            JointStep::Fixed(x) => c = c.compose(x),
            JointStep::Dof(d) => before.push((*d, c)),
        }
    }
    // X_B,F = (X_FM(0) X_MB)⁻¹
    let x_fb = c.compose(&joint.child_offset_inv);
    let x_bf = x_fb.inverse();
    let frames = before
        .into_iter()
        .map(|(d, x)| (d, x_bf.compose(&x)))
        .collect();
    (joint.parent_offset.compose(&x_fb), frames)
}

/// Least-squares quartic y ≈ Σ a_k x^k on samples; returns (coefficients, max |error|), or
/// None when fewer than five finite samples (or a non-finite fit) leave nothing to fit:
/// the model reader refuses functions that overflow over their ranges, so this is a guard.
fn fit_quartic(x: &[f64], y: &[f64]) -> Option<([f64; 5], f64)> {
    if x.len() < 5 || x.iter().chain(y).any(|v| !v.is_finite()) {
        return None;
    }
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    let a = DMatrix::from_fn(x.len(), 5, |i, k| (x[i] / scale).powi(k as i32));
    let b = DVector::from_column_slice(y);
    let sol = a.clone().svd(true, true).solve(&b, 1e-14).ok()?;
    let err = (&a * &sol - &b).amax();
    let mut c = [0.0; 5];
    for k in 0..5 {
        c[k] = sol[k] / scale.powi(k as i32);
    }
    (c.iter().all(|v| v.is_finite()) && err.is_finite()).then_some((c, err))
}

/// Exports `model` to MJCF.
///
/// The stages, in the order their notes are listed: per-body sites and geoms (markers,
/// contact geometry, wrap objects), tendons and muscles, couplings, then the document:
/// header, body tree, equalities, keyframe, tendons and actuators.
pub fn to_mjcf(model: &Model) -> MjcfExport {
    let mut notes = Vec::new();
    let children = joints_by_parent_body(model);
    let pose = DefaultPose::new(model);

    let mut body_extra: Vec<String> = vec![String::new(); model.bodies.len()];
    write_markers(model, &mut body_extra);
    write_contact_geoms(model, &mut body_extra);
    let wrap_ok = write_wrap_geoms(model, &mut body_extra, &mut notes);
    let paths = PathExport {
        model,
        pose: &pose,
        wrap_ok: &wrap_ok,
    };
    let (tendons, actuators) = write_tendons_and_muscles(&paths, &mut body_extra, &mut notes);

    // Couplings: every full coordinate that is a function of an independent coordinate other
    // than the reference axis of that coordinate becomes a joint equality constraint.
    let (equalities, limits) = couplings(model, &mut notes);

    let mut out = String::new();
    write_header(model, &mut out, &mut notes);
    let tree = BodyTree {
        model,
        children: &children,
        body_extra: &body_extra,
        limits: &limits,
    };
    write_worldbody(&tree, &mut out, &mut notes);
    if !equalities.is_empty() {
        let _ = writeln!(out, "<equality>\n{equalities}</equality>");
    }
    write_default_keyframe(model, &pose, &children, &mut out);
    if !tendons.is_empty() {
        let _ = writeln!(out, "<tendon>\n{tendons}</tendon>");
    }
    if !actuators.is_empty() {
        let _ = writeln!(out, "<actuator>\n{actuators}</actuator>");
    }
    out += "</mujoco>\n";
    for w in &model.warnings {
        if w.message.contains("NOT enforced") {
            notes.push(format!("{}: {}", w.element, w.message));
        }
    }
    MjcfExport { xml: out, notes }
}

/// The joints whose parent is each body, in model order.
fn joints_by_parent_body(model: &Model) -> Vec<Vec<usize>> {
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); model.bodies.len()];
    for (j, joint) in model.joints.iter().enumerate() {
        children[joint.parent_body].push(j);
    }
    children
}

/// Kinematics at the model's default pose; `fk_ok` is false when they could not be computed.
struct DefaultPose {
    data: Data,
    fk_ok: bool,
}

impl DefaultPose {
    fn new(model: &Model) -> Self {
        let mut data = Data::new(model);
        let q0 = model.default_q();
        let fk_ok = dynamics::forward_kinematics(model, &mut data, &q0).is_ok();
        Self { data, fk_ok }
    }
}

/// A `<site>` per marker, in its body.
fn write_markers(model: &Model, body_extra: &mut [String]) {
    for m in &model.markers {
        let _ = writeln!(
            body_extra[m.body],
            "<site name=\"marker:{}\" pos=\"{}\" size=\"0.008\" rgba=\"0.2 0.4 1 1\"/>",
            esc(&m.name),
            v3(&m.location_in_body)
        );
    }
}

/// A `<geom>` per contact sphere or half-space, in its body.
fn write_contact_geoms(model: &Model, body_extra: &mut [String]) {
    for g in &model.contact_geometry {
        match g.shape {
            ContactShape::Sphere { radius } => {
                let _ = writeln!(
                    body_extra[g.body],
                    "<geom name=\"contact:{}\" type=\"sphere\" size=\"{radius}\" pos=\"{}\" rgba=\"0.9 0.5 0.2 1\"/>",
                    esc(&g.name),
                    v3(&g.pose_in_body.pos)
                );
            }
            ContactShape::HalfSpace => {
                // OpenSim's half-space fills x > 0 of its frame (outward normal −x); a MuJoCo
                // plane's normal is its frame's +z: rotate so that z_plane = −x_halfspace.
                let r =
                    g.pose_in_body.rot * Mat3::new(0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
                let _ = writeln!(
                    body_extra[g.body],
                    "<geom name=\"contact:{}\" type=\"plane\" size=\"0 0 1\" pos=\"{}\" quat=\"{}\" rgba=\"0.8 0.8 0.8 1\"/>",
                    esc(&g.name),
                    v3(&g.pose_in_body.pos),
                    quat(&r)
                );
            }
        }
    }
}

/// A `<geom>` (and a side site) per sphere or cylinder wrap object, in its body; ellipsoids
/// and tori are noted and left out. Returns, per wrap object, whether it was written.
fn write_wrap_geoms(
    model: &Model,
    body_extra: &mut [String],
    notes: &mut Vec<String>,
) -> Vec<bool> {
    let mut wrap_ok = vec![false; model.wrap_objects.len()];
    for (w, obj) in model.wrap_objects.iter().enumerate() {
        let p = &obj.pose_in_body;
        let (shape, size) = match obj.shape {
            WrapShape::Sphere { radius } => ("sphere", format!("{radius}")),
            WrapShape::Cylinder { radius, length } => {
                ("cylinder", format!("{radius} {}", 0.5 * length))
            }
            _ => {
                notes.push(format!(
                    "wrap object `{}` ({}) cannot be represented in MJCF: left out, paths that use it run straight",
                    obj.name,
                    if matches!(obj.shape, WrapShape::Ellipsoid { .. }) { "WrapEllipsoid" } else { "WrapTorus" }
                ));
                continue;
            }
        };
        wrap_ok[w] = true;
        // MuJoCo's cylinder axis is its frame's z, like OpenSim's WrapCylinder.
        let _ = writeln!(
            body_extra[obj.body],
            "<geom name=\"wrap:{}\" type=\"{shape}\" size=\"{size}\" pos=\"{}\" quat=\"{}\" contype=\"0\" conaffinity=\"0\" group=\"3\" rgba=\"0.5 0.9 0.9 0.4\"/>",
            esc(&obj.name),
            v3(&p.pos),
            quat(&p.rot)
        );
        // A side site on the quadrant's side selects which side the tendon wraps around.
        if let Some(dir) = quadrant_direction(&obj.quadrant) {
            let r = match obj.shape {
                WrapShape::Sphere { radius } | WrapShape::Cylinder { radius, .. } => radius,
                _ => 0.0,
            };
            // side site at centre + R·(2r·dir)
            let _ = writeln!(
                body_extra[obj.body],
                "<site name=\"side:{}\" pos=\"{}\" size=\"0.002\" group=\"3\"/>",
                esc(&obj.name),
                v3(&(p.pos + p.rot * dir * (2.0 * r)))
            );
        }
    }
    wrap_ok
}

/// The unit axis a wrap quadrant (`+x`, `-y`, …) names, or None (`all`, or unknown).
fn quadrant_direction(quadrant: &str) -> Option<Vec3> {
    let q = quadrant.trim().to_ascii_lowercase();
    match q.as_str() {
        "+x" | "x" => Some(Vec3::x()),
        "-x" => Some(-Vec3::x()),
        "+y" | "y" => Some(Vec3::y()),
        "-y" => Some(-Vec3::y()),
        "+z" | "z" => Some(Vec3::z()),
        "-z" => Some(-Vec3::z()),
        _ => None,
    }
}

/// What the tendon stage reads: the model, its default pose and which wraps were written.
struct PathExport<'a> {
    model: &'a Model,
    pose: &'a DefaultPose,
    wrap_ok: &'a [bool],
}

/// A `<spatial>` tendon per force with a path (its sites go into `body_extra`) and a
/// `<muscle>` actuator per muscle with its parameters. Returns (tendons, actuators).
fn write_tendons_and_muscles(
    px: &PathExport,
    body_extra: &mut [String],
    notes: &mut Vec<String>,
) -> (String, String) {
    let model = px.model;
    let mut tendons = String::new();
    let mut actuators = String::new();
    let mut pennated = 0;
    for f in &model.forces {
        let Some(path) = &f.path else { continue };
        let site_names = write_path_sites(f, path, body_extra, notes);
        let wrap_after = assign_wraps_to_segments(px, f, path, notes);
        let _ = writeln!(
            tendons,
            "<spatial name=\"{}\" width=\"0.003\">\n  {}\n</spatial>",
            esc(&f.name),
            tendon_entries(model, &site_names, &wrap_after).join("\n  ")
        );
        if f.is_muscle() {
            match write_muscle_actuator(f, &mut actuators) {
                Some(is_pennated) => pennated += usize::from(is_pennated),
                None => notes.push(format!(
                    "muscle `{}` lacks force or length parameters: no actuator",
                    f.name
                )),
            }
        }
    }
    if pennated > 0 {
        notes.push(format!(
            "{pennated} muscles have a pennation angle, which MuJoCo's muscle does not model"
        ));
    }
    if model.muscle_count() > 0 {
        notes.push(format!(
            "{} muscles use MuJoCo's muscle curves (force-length, force-velocity, passive) instead of their OpenSim curves",
            model.muscle_count()
        ));
    }
    (tendons, actuators)
}

/// A site per path point (`path:<force>:<i>`) in its body, noting conditional and moving
/// points; returns the site names in path order.
fn write_path_sites(
    f: &ForceElement,
    path: &GeometryPath,
    body_extra: &mut [String],
    notes: &mut Vec<String>,
) -> Vec<String> {
    let mut site_names = Vec::new();
    for (i, p) in path.points.iter().enumerate() {
        let name = format!("path:{}:{i}", f.name);
        let loc = p.frame_in_body.apply_point(&p.location);
        let _ = writeln!(
            body_extra[p.body],
            "<site name=\"{}\" pos=\"{}\" size=\"0.004\"/>",
            esc(&name),
            v3(&loc)
        );
        match p.kind {
            PathPointKind::Fixed => {}
            PathPointKind::Conditional { .. } => notes.push(format!(
                "`{}`: conditional path point `{}` exported as a fixed site (MJCF has no conditional points)",
                f.name, p.name
            )),
            PathPointKind::Moving { .. } => notes.push(format!(
                "`{}`: moving path point `{}` exported as a fixed site at its default-pose location",
                f.name, p.name
            )),
        }
        site_names.push(name);
    }
    site_names
}

/// Per path point, the wrap object (if any) that follows it: each representable wrap goes
/// between the two sites of the segment (within its range) closest to the wrap centre at
/// the default pose; a segment takes one wrap, the others are noted and left out.
fn assign_wraps_to_segments(
    px: &PathExport,
    f: &ForceElement,
    path: &GeometryPath,
    notes: &mut Vec<String>,
) -> Vec<Option<usize>> {
    let model = px.model;
    let mut wrap_after: Vec<Option<usize>> = vec![None; path.points.len()];
    for pw in &path.wraps {
        if !px.wrap_ok[pw.wrap_object] {
            continue;
        }
        let n = path.points.len();
        let (lo, hi) = if pw.range[0] < 1 || pw.range[1] < 1 {
            (0, n - 1)
        } else {
            (
                (pw.range[0] as usize - 1).min(n - 1),
                (pw.range[1] as usize - 1).min(n - 1),
            )
        };
        let obj = &model.wrap_objects[pw.wrap_object];
        let best = (lo..hi.max(lo + 1).min(n - 1)).min_by(|&a, &b| {
            let d = |i: usize| segment_distance_to_wrap(px.pose, path, i, obj);
            d(a).total_cmp(&d(b))
        });
        match best {
            Some(i) if wrap_after[i].is_none() => wrap_after[i] = Some(pw.wrap_object),
            _ => notes.push(format!(
                "`{}`: wrap object `{}` shares a path segment with another wrap; left out (MJCF allows one per segment)",
                f.name, obj.name
            )),
        }
    }
    if path.wraps.len() > 1 {
        notes.push(format!(
            "`{}`: {} wrap objects are each fixed to one path segment; OpenSim chooses the wrapping segment as the path moves",
            f.name,
            path.wraps.len()
        ));
    }
    wrap_after
}

/// Distance, at the default pose, from the wrap object's centre to the segment between path
/// points i and i + 1 (0 when the default pose could not be computed).
fn segment_distance_to_wrap(
    pose: &DefaultPose,
    path: &GeometryPath,
    i: usize,
    obj: &WrapObject,
) -> f64 {
    if !pose.fk_ok {
        return 0.0;
    }
    let data = &pose.data;
    let point = |k: usize| {
        let p = &path.points[k];
        data.point_position(p.body, &p.frame_in_body.apply_point(&p.location))
    };
    let pa = point(i);
    let pb = point(i + 1);
    let c = data.point_position(obj.body, &obj.pose_in_body.pos);
    // t* = clamp((c − a)·(b − a) / |b − a|², 0, 1); distance |a + t*(b − a) − c|
    let ab = pb - pa;
    let t = ((c - pa).dot(&ab) / ab.norm_squared().max(1e-300)).clamp(0.0, 1.0);
    (pa + ab * t - c).norm()
}

/// The tendon's `<site>` and `<geom>` entries in path order.
fn tendon_entries(
    model: &Model,
    site_names: &[String],
    wrap_after: &[Option<usize>],
) -> Vec<String> {
    let mut entries: Vec<String> = Vec::new();
    for (i, s) in site_names.iter().enumerate() {
        entries.push(format!("<site site=\"{}\"/>", esc(s)));
        if let Some(w) = wrap_after[i] {
            let obj = &model.wrap_objects[w];
            let side = if obj.quadrant.trim().eq_ignore_ascii_case("all")
                || obj.quadrant.trim().is_empty()
            {
                String::new()
            } else {
                format!(" sidesite=\"side:{}\"", esc(&obj.name))
            };
            entries.push(format!("<geom geom=\"wrap:{}\"{side}/>", esc(&obj.name)));
        }
    }
    entries
}

/// Writes the muscle's `<muscle>` actuator; returns whether it is pennated, or None (nothing
/// written) when it lacks force or length parameters.
fn write_muscle_actuator(f: &ForceElement, actuators: &mut String) -> Option<bool> {
    let num = |tag: &str| f.raw.number(tag);
    let (Some(fmax), Some(l0), Some(lt)) = (
        num("max_isometric_force"),
        num("optimal_fiber_length"),
        num("tendon_slack_length"),
    ) else {
        return None;
    };
    // MuJoCo's muscle: L0 = (lr₁ − lr₀)/(r₁ − r₀), tendon length lr₀ − r₀ L0; choose
    // the length range that gives OpenSim's optimal fibre and tendon slack lengths.
    let lr = [lt + MUSCLE_RANGE[0] * l0, lt + MUSCLE_RANGE[1] * l0];
    let vmax = num("max_contraction_velocity").unwrap_or(10.0);
    let tact = num("activation_time_constant").unwrap_or(0.01);
    let tdeact = num("deactivation_time_constant").unwrap_or(0.04);
    let _ = writeln!(
        actuators,
        "<muscle name=\"{}\" tendon=\"{}\" force=\"{fmax}\" lengthrange=\"{} {}\" range=\"{} {}\" vmax=\"{vmax}\" timeconst=\"{tact} {tdeact}\"/>",
        esc(&f.name),
        esc(&f.name),
        lr[0],
        lr[1],
        MUSCLE_RANGE[0],
        MUSCLE_RANGE[1]
    );
    Some(num("pennation_angle_at_optimal").is_some_and(|a| a != 0.0))
}

/// `<mujoco>`, `<compiler>`, `<option>` and `<default>`; notes MuJoCo's balanceinertia when
/// some inertia violates the triangle inequality.
fn write_header(model: &Model, out: &mut String, notes: &mut Vec<String>) {
    let _ = writeln!(out, "<mujoco model=\"{}\">", esc(&model.name));
    let balance = model
        .warnings
        .iter()
        .any(|w| w.message.contains("triangle inequality"));
    if balance {
        notes.push(
            "some inertias violate the triangle inequality: exported with MuJoCo's balanceinertia"
                .into(),
        );
    }
    let _ = writeln!(
        out,
        "<compiler angle=\"radian\" inertiafromgeom=\"false\" autolimits=\"true\" balanceinertia=\"{balance}\">\n  <lengthrange mode=\"none\"/>\n</compiler>"
    );
    let _ = writeln!(out, "<option gravity=\"{}\"/>", v3(&model.gravity));
    let _ = writeln!(
        out,
        "<default><joint armature=\"0\" damping=\"0\"/><geom contype=\"1\" conaffinity=\"1\"/></default>"
    );
}

/// What the body-tree stage reads.
struct BodyTree<'a> {
    model: &'a Model,
    children: &'a [Vec<usize>],
    body_extra: &'a [String],
    limits: &'a [Option<[f64; 2]>],
}

/// `<worldbody>`: the bodies depth-first from ground, each with its inertial, its joints and
/// its sites and geoms.
fn write_worldbody(tree: &BodyTree, out: &mut String, notes: &mut Vec<String>) {
    let model = tree.model;
    let _ = writeln!(out, "<worldbody>\n<light pos=\"0 0 4\" dir=\"0 0 -1\"/>");
    *out += &tree.body_extra[0];
    let mut stack: Vec<(usize, bool)> =
        tree.children[0].iter().rev().map(|&j| (j, false)).collect();
    while let Some((j, closing)) = stack.pop() {
        if closing {
            *out += "</body>\n";
            continue;
        }
        let joint = &model.joints[j];
        let b = joint.child_body;
        let body = &model.bodies[b];
        let (x_pb, frames) = joint_frames_at_zero(model, j);
        let _ = writeln!(
            out,
            "<body name=\"{}\" pos=\"{}\" quat=\"{}\">",
            esc(&body.name),
            v3(&x_pb.pos),
            quat(&x_pb.rot)
        );
        write_inertial(model, j, out, notes);
        write_joints(tree, j, &frames, out);
        *out += &tree.body_extra[b];
        stack.push((j, true));
        for &c in tree.children[b].iter().rev() {
            stack.push((c, false));
        }
    }
    *out += "</worldbody>\n";
}

/// Whether the joint's child body moves: the joint or one of its ancestors has a full
/// coordinate.
fn body_moves(model: &Model, j: usize) -> bool {
    let joint = &model.joints[j];
    if !joint.dof_range.is_empty() {
        return true;
    }
    let mut p = joint.parent_body;
    while let Some(pj) = model.bodies[p].joint {
        if !model.joints[pj].dof_range.is_empty() {
            return true;
        }
        p = model.joints[pj].parent_body;
    }
    false
}

/// The child body's `<inertial>`; a moving body without mass or inertia gets tiny ones (noted),
/// since MuJoCo needs both on moving bodies.
fn write_inertial(model: &Model, j: usize, out: &mut String, notes: &mut Vec<String>) {
    let body = &model.bodies[model.joints[j].child_body];
    let mut mass = body.mass;
    let mut i = body.inertia_about_com;
    if body_moves(model, j) && (mass <= 0.0 || i.trace() <= 0.0) {
        notes.push(format!(
            "body `{}` has no mass or inertia; MuJoCo needs both on moving bodies: exported with 1e-9 kg and 1e-12 kg·m²",
            body.name
        ));
        mass = mass.max(1e-9);
        if i.trace() <= 0.0 {
            i = Mat3::identity() * 1e-12;
        }
    }
    if mass > 0.0 {
        let _ = writeln!(
            out,
            "<inertial pos=\"{}\" mass=\"{mass}\" fullinertia=\"{}\"/>",
            v3(&body.com_in_body),
            crate::spatial::inertia_text(&i)
        );
    }
}

/// A hinge or slide `<joint>` per full coordinate of joint `j`, its axis and anchor in the
/// body frame at θ = 0 (`frames`), limited where the coupling stage found a range.
fn write_joints(tree: &BodyTree, j: usize, frames: &HashMap<usize, Transform>, out: &mut String) {
    let model = tree.model;
    for d in model.joints[j].dof_range.clone() {
        let dof = &model.dofs[d];
        let x = frames[&d];
        let (kind, axis) = match dof.kind {
            DofKind::Hinge => ("hinge", x.rot * dof.axis),
            DofKind::Slide => ("slide", x.rot * dof.axis),
        };
        let limit = match tree.limits[d] {
            Some([lo, hi]) => format!("limited=\"true\" range=\"{lo} {hi}\""),
            None => "limited=\"false\"".to_string(),
        };
        let _ = writeln!(
            out,
            "<joint name=\"{}\" type=\"{kind}\" pos=\"{}\" axis=\"{}\" {limit}/>",
            esc(&dof.name),
            v3(&x.pos),
            v3(&axis)
        );
    }
}

/// MuJoCo's qpos0 is θ = 0, where coupled axes (e.g. a knee's translations) violate their
/// equalities; the keyframe `default` is the model's default pose, which satisfies them.
fn write_default_keyframe(
    model: &Model,
    pose: &DefaultPose,
    children: &[Vec<usize>],
    out: &mut String,
) {
    if !pose.fk_ok {
        return;
    }
    let qpos: Vec<String> = qpos_order(model, children)
        .into_iter()
        .map(|d| pose.data.theta(model)[d].to_string())
        .collect();
    let _ = writeln!(
        out,
        "<keyframe>\n<key name=\"default\" qpos=\"{}\"/>\n</keyframe>",
        qpos.join(" ")
    );
}

/// The full coordinates in MuJoCo's qpos order: bodies depth-first as written, each body's
/// joints in order.
fn qpos_order(model: &Model, children: &[Vec<usize>]) -> Vec<usize> {
    let mut order = Vec::with_capacity(model.n_full());
    let mut stack: Vec<usize> = children[0].iter().rev().copied().collect();
    while let Some(j) = stack.pop() {
        order.extend(model.joints[j].dof_range.clone());
        stack.extend(children[model.joints[j].child_body].iter().rev());
    }
    order
}

/// Joint equality constraints for the full coordinates that depend on independent
/// coordinates: per independent coordinate, one reference axis (preferably θ = q itself);
/// every other axis of that coordinate follows it by a quartic fitted over the coordinate's
/// range. Axes of locked coordinates are held at their value. Also returns, per full
/// coordinate, the range of its coordinate when the axis value is the coordinate itself (the
/// joint limit a MuJoCo simulation should respect; the fits hold only within it).
fn couplings(model: &Model, notes: &mut Vec<String>) -> (String, Vec<Option<[f64; 2]>>) {
    let r = &model.reduction;
    let nc = r.n_coordinates;
    let mut data = Data::new(model);
    let q0 = model.default_q();
    let mut limits = vec![None; model.n_full()];
    if dynamics::forward_kinematics(model, &mut data, &q0).is_err() {
        return (String::new(), limits);
    }
    let theta0 = data.theta(model).to_vec();
    let mut out = String::new();
    let deps = |d: usize| &r.dep_index[r.dep_start[nc + d]..r.dep_start[nc + d + 1]];
    // Reference axis per independent coordinate: the first with Φ_dj = 1 at the default pose
    // and θ_d = q_j, else the first that depends on q_j alone.
    let mut reference: Vec<Option<usize>> = vec![None; model.nq()];
    for d in 0..model.n_full() {
        if let [j] = deps(d) {
            let c = r.independent[*j];
            let exact = (theta0[d] - q0[*j]).abs() < 1e-15
                && matches!(&model.dofs[d].function, crate::model::Function::Linear(k) if k.len() == 2 && k[0] == 1.0 && k[1] == 0.0)
                && model.dofs[d].args == [c];
            if (exact && reference[*j].is_none_or(|p| !matches!(&model.dofs[p].function, crate::model::Function::Linear(k) if k[0] == 1.0 && k[1] == 0.0)))
                || reference[*j].is_none()
            {
                reference[*j] = Some(d);
            }
        }
    }
    for d in 0..model.n_full() {
        let name = esc(&model.dofs[d].name);
        match deps(d) {
            [] => {
                let _ = writeln!(out, "<joint joint1=\"{name}\" polycoef=\"{} 0 0 0 0\"/>", theta0[d]);
            }
            [j] if reference[*j] == Some(d) => {
                if matches!(&model.dofs[d].function, crate::model::Function::Linear(k) if k.len() == 2 && k[0] == 1.0 && k[1] == 0.0)
                    && model.dofs[d].args == [r.independent[*j]]
                {
                    limits[d] = Some(model.coordinates[r.independent[*j]].range);
                }
            }
            [j] => {
                let rd = reference[*j].unwrap_or(d);
                let [lo, hi] = model.coordinates[r.independent[*j]].range;
                let (mut xs, mut ys) = (Vec::new(), Vec::new());
                let mut q = q0.clone();
                for k in 0..=40 {
                    let s = k as f64 / 40.0;
                    q[*j] = lo * (1.0 - s) + hi * s;
                    if dynamics::forward_kinematics(model, &mut data, &q).is_ok() {
                        xs.push(data.theta(model)[rd]);
                        ys.push(data.theta(model)[d]);
                    }
                }
                let Some((c, err)) = fit_quartic(&xs, &ys) else {
                    notes.push(format!(
                        "`{}` could not be fitted to `{}` over [{lo}, {hi}] (the model's pose \
                         there is not finite), so it is left free",
                        model.dofs[d].name, model.dofs[rd].name
                    ));
                    continue;
                };
                let scale = ys.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
                if err > 1e-9 * scale {
                    notes.push(format!(
                        "`{}` follows `{}` through a quartic fitted over [{lo}, {hi}] (max error {err:.2e})",
                        model.dofs[d].name, model.dofs[rd].name
                    ));
                }
                let _ = writeln!(
                    out,
                    "<joint joint1=\"{name}\" joint2=\"{}\" polycoef=\"{} {} {} {} {}\"/>",
                    esc(&model.dofs[rd].name),
                    c[0],
                    c[1],
                    c[2],
                    c[3],
                    c[4]
                );
            }
            several => notes.push(format!(
                "`{}` depends on {} independent coordinates; MJCF equalities couple two joints only, so it is left free",
                model.dofs[d].name,
                several.len()
            )),
        }
    }
    (out, limits)
}
