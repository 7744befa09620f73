//! Markers, contact geometry, wrap objects and the force set (muscles with their geometry
//! paths, actuators, other forces), kept for the later stages.

use super::functions::{function_child, parse_function};
use super::xml::{Ctx, XNode, child, elements, set_members};
use crate::error::Error;
use crate::model::frames::{FrameRegistry, resolve_path};
use crate::model::{
    ActuatorKind, Arity, ContactGeometry, ContactShape, ForceElement, Function, GeometryPath,
    Marker, Model, PathPoint, PathPointKind, PathWrap, ScalarActuator, WrapObject, WrapShape,
};
use crate::spatial::{Transform, Vec3};

/// Muscle classes whose physics musculo implements (or will, in its muscle stage).
pub const SUPPORTED_MUSCLES: &[&str] = &[
    "Thelen2003Muscle",
    "Millard2012EquilibriumMuscle",
    "DeGrooteFregly2016Muscle",
];

/// Actuators used as they are by the optimisation stages.
pub const ACTUATORS: &[&str] = &[
    "CoordinateActuator",
    "PointActuator",
    "TorqueActuator",
    "PathActuator",
];

/// Resolves a socket path naming a coordinate (e.g. `/jointset/knee_r/knee_angle_r` or a bare
/// name) to its index.
fn coordinate_from_socket(
    ctx: &Ctx,
    node: XNode,
    model: &Model,
    tag: &str,
) -> Result<usize, Error> {
    let path = ctx
        .text(node, tag)
        .filter(|s| !s.is_empty())
        .ok_or_else(|| ctx.err(node, format!("missing <{tag}>")))?;
    let name = path.rsplit('/').next().unwrap_or(path);
    let idx = model
        .coordinate_index(name)
        .ok_or_else(|| ctx.err(node, format!("<{tag}>: unknown coordinate `{path}`")))?;
    // When the path names the joint too, it must be the coordinate's joint.
    let segs: Vec<&str> = path.split('/').filter(|s| !s.is_empty()).collect();
    if segs.len() >= 3 && segs[segs.len() - 3] == "jointset" {
        let joint = segs[segs.len() - 2];
        if model.joints[model.coordinates[idx].joint].name != joint {
            return Err(ctx.err(
                node,
                format!("<{tag}>: coordinate `{name}` does not belong to joint `{joint}`"),
            ));
        }
    }
    Ok(idx)
}

fn frame_socket(
    ctx: &Ctx,
    node: XNode,
    frames: &mut FrameRegistry,
    owner: &str,
    tag: &str,
) -> Result<(usize, Transform), Error> {
    let socket = ctx
        .text(node, tag)
        .filter(|s| !s.is_empty())
        .ok_or_else(|| ctx.err(node, format!("missing <{tag}>")))?;
    frames
        .resolve(owner, socket)
        .map_err(|e| ctx.err(node, format!("<{tag}>: {e}")))
}

pub(super) fn read_marker(
    ctx: &mut Ctx,
    m: XNode,
    frames: &mut FrameRegistry,
) -> Result<Marker, Error> {
    let name = ctx.name(m)?;
    let owner = format!("/markerset/{name}");
    let (body, x) = frame_socket(ctx, m, frames, &owner, "socket_parent_frame")?;
    let location = ctx.vec3_or(m, "location", Vec3::zeros())?;
    for c in elements(m) {
        match c.tag_name().name() {
            "socket_parent_frame" | "location" | "fixed" => {}
            _ => ctx.unknown(c),
        }
    }
    Ok(Marker {
        name,
        body,
        location_in_body: x.apply_point(&location),
        fixed: ctx.bool_or(m, "fixed", false)?,
    })
}

pub(super) fn read_contact_geometry(
    ctx: &mut Ctx,
    g: XNode,
    frames: &mut FrameRegistry,
) -> Result<Option<ContactGeometry>, Error> {
    let tag = g.tag_name().name();
    let shape = match tag {
        "ContactSphere" => {
            let radius = ctx.req_f64(g, "radius")?;
            if radius <= 0.0 {
                return Err(ctx.err(g, format!("radius {radius} must be positive")));
            }
            ContactShape::Sphere { radius }
        }
        "ContactHalfSpace" => ContactShape::HalfSpace,
        _ => {
            ctx.warn(
                g,
                format!("contact geometry `{tag}` is not supported; ignored"),
            );
            return Ok(None);
        }
    };
    let name = ctx.name(g)?;
    let owner = format!("/contactgeometryset/{name}");
    let (body, x) = frame_socket(ctx, g, frames, &owner, "socket_frame")?;
    let location = ctx.vec3_or(g, "location", Vec3::zeros())?;
    let orientation = ctx.vec3_or(g, "orientation", Vec3::zeros())?;
    for c in elements(g) {
        match c.tag_name().name() {
            "socket_frame" | "location" | "orientation" | "radius" => {}
            _ => ctx.unknown(c),
        }
    }
    Ok(Some(ContactGeometry {
        name,
        body,
        pose_in_body: x.compose(&Transform::from_translation_xyz_body(location, orientation)),
        shape,
    }))
}

/// The largest radius or length of a wrap object (m): the bound of a joint's motion
/// ([`super::kinematic_range::MAX_AXIS_VALUE`]).
const MAX_WRAP_SIZE: f64 = super::kinematic_range::MAX_AXIS_VALUE;

pub(super) fn read_wrap_object(
    ctx: &mut Ctx,
    w: XNode,
    body: usize,
) -> Result<Option<WrapObject>, Error> {
    let tag = w.tag_name().name();
    let positive = |ctx: &Ctx, tag: &str| -> Result<f64, Error> {
        let v = ctx.req_f64(w, tag)?;
        if v <= 0.0 {
            return Err(ctx.err(w, format!("<{tag}> must be positive, found {v}")));
        }
        // as a joint's motion (kinematic_range): beyond, no body's wrap surface, and the
        // MJCF export's sites at twice the radius overflowed
        if v > MAX_WRAP_SIZE {
            return Err(ctx.err(
                w,
                format!("<{tag}> {v:e} m is beyond {MAX_WRAP_SIZE:e} m, which no body reaches"),
            ));
        }
        Ok(v)
    };
    let shape = match tag {
        "WrapSphere" => WrapShape::Sphere {
            radius: positive(ctx, "radius")?,
        },
        "WrapCylinder" => WrapShape::Cylinder {
            radius: positive(ctx, "radius")?,
            length: ctx.f64_or(w, "length", 1.0)?,
        },
        "WrapEllipsoid" => {
            let d = ctx.vec3_or(w, "dimensions", Vec3::zeros())?;
            if child(w, "dimensions").is_none()
                || d.iter().any(|&v| !(v > 0.0 && v <= MAX_WRAP_SIZE))
            {
                return Err(ctx.err(
                    w,
                    format!(
                        "<dimensions> must hold three positive radii up to {MAX_WRAP_SIZE:e} m"
                    ),
                ));
            }
            WrapShape::Ellipsoid { dimensions: d }
        }
        "WrapTorus" => WrapShape::Torus {
            inner_radius: positive(ctx, "inner_radius")?,
            outer_radius: positive(ctx, "outer_radius")?,
        },
        _ => {
            ctx.warn(
                w,
                format!(
                    "wrap object type `{tag}` is not supported; paths that use it are reported"
                ),
            );
            return Ok(None);
        }
    };
    for c in elements(w) {
        match c.tag_name().name() {
            "active" | "xyz_body_rotation" | "translation" | "quadrant" | "radius" | "length"
            | "dimensions" | "inner_radius" | "outer_radius" | "display_preference" | "color" => {}
            _ => ctx.unknown(c),
        }
    }
    Ok(Some(WrapObject {
        name: ctx.name(w)?,
        body,
        pose_in_body: Transform::from_translation_xyz_body(
            ctx.vec3_or(w, "translation", Vec3::zeros())?,
            ctx.vec3_or(w, "xyz_body_rotation", Vec3::zeros())?,
        ),
        shape,
        quadrant: ctx.text(w, "quadrant").unwrap_or("all").to_string(),
        active: ctx.bool_or(w, "active", true)?,
        line: ctx.line(w),
    }))
}

pub(super) fn read_force(
    ctx: &mut Ctx,
    f: XNode,
    frames: &mut FrameRegistry,
    model: &Model,
) -> Result<ForceElement, Error> {
    let name = ctx.name(f)?;
    let kind = f.tag_name().name().to_string();
    let path = match child(f, "GeometryPath") {
        Some(gp) => Some(read_geometry_path(
            ctx,
            gp,
            frames,
            model,
            &format!("/forceset/{name}"),
        )?),
        None => None,
    };
    let is_muscle = kind.ends_with("Muscle") || kind.contains("Muscle_");
    if is_muscle {
        check_muscle_numbers(ctx, f)?;
        for (tag, min_exclusive) in [
            ("optimal_fiber_length", true),
            ("max_isometric_force", false),
            ("tendon_slack_length", false),
            ("max_contraction_velocity", true),
        ] {
            if child(f, tag).is_some() {
                let v = ctx.req_f64(f, tag)?;
                if (min_exclusive && v <= 0.0) || v < 0.0 {
                    let need = if min_exclusive {
                        "positive"
                    } else {
                        "non-negative"
                    };
                    return Err(ctx.err(f, format!("<{tag}> must be {need}, found {v}")));
                }
            }
        }
        if !SUPPORTED_MUSCLES.contains(&kind.as_str()) {
            ctx.warn(
                f,
                format!(
                    "muscle model `{kind}` is not one musculo implements ({}); its path is kept",
                    SUPPORTED_MUSCLES.join(", ")
                ),
            );
        }
        if path.is_none() {
            return Err(ctx.err(f, "muscle without a <GeometryPath>"));
        }
    } else if !ACTUATORS.contains(&kind.as_str()) {
        ctx.warn(
            f,
            format!("force element `{kind}` is kept but not applied by musculo's dynamics"),
        );
    }
    let applies_force = ctx.bool_or(f, "appliesForce", true)?;
    let actuator = read_scalar_actuator(ctx, f, &kind, is_muscle, model)?;
    Ok(ForceElement {
        name,
        kind,
        path: path.map(std::sync::Arc::new),
        applies_force,
        actuator,
        raw: std::sync::Arc::new(ctx.raw(f)),
        line: ctx.line(f),
        file: ctx.file.to_string(),
    })
}

/// The range of a muscle property every muscle class shares, in radians or seconds:
/// (tag, lowest, highest, whether the highest is excluded).
const MUSCLE_RANGES: &[(&str, f64, f64, bool)] = &[
    (
        "pennation_angle_at_optimal",
        0.0,
        std::f64::consts::FRAC_PI_2,
        true,
    ),
    (
        "maximum_pennation_angle",
        0.0,
        std::f64::consts::FRAC_PI_2,
        false,
    ),
    (
        "activation_time_constant",
        f64::MIN_POSITIVE,
        f64::INFINITY,
        true,
    ),
    (
        "deactivation_time_constant",
        f64::MIN_POSITIVE,
        f64::INFINITY,
        true,
    ),
    ("default_activation", 0.0, 1.0, false),
    ("minimum_activation", 0.0, 1.0, false),
];

/// Refuses, at the element that holds it, a number a muscle's force model cannot use: any
/// numeric property of the muscle or of its curve objects that is NaN or infinite (its
/// geometry path is read and checked on its own; control bounds may be infinite), and the
/// shared properties of [`MUSCLE_RANGES`] outside their range. OpenSim reads `NaN` and
/// `Inf` as numbers, so without this check a model with a NaN pennation angle would be
/// inspected, exported and scaled as if nothing were wrong.
fn check_muscle_numbers(ctx: &Ctx, f: XNode) -> Result<(), Error> {
    let mut stack: Vec<XNode> = elements(f).collect();
    while let Some(c) = stack.pop() {
        let tag = c.tag_name().name();
        if matches!(tag, "GeometryPath" | "min_control" | "max_control") {
            continue;
        }
        if elements(c).next().is_some() {
            stack.extend(elements(c));
            continue;
        }
        let text = c.text().unwrap_or("").trim();
        let values: Vec<f64> = text
            .split_whitespace()
            .map_while(|t| t.parse::<f64>().ok())
            .collect();
        if values.is_empty() || values.len() != text.split_whitespace().count() {
            continue; // not numeric (a name, a boolean, a socket path)
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(ctx.err(c, format!("<{tag}> `{text}` is not a finite number")));
        }
        if c.parent_element() != Some(f) {
            continue;
        }
        if let Some(&(_, lo, hi, open)) = MUSCLE_RANGES.iter().find(|r| r.0 == tag) {
            let v = values[0];
            if values.len() != 1 || v < lo || v > hi || (open && v == hi) {
                let range = match (lo == f64::MIN_POSITIVE, hi.is_finite(), open) {
                    (true, false, _) => "positive".to_string(),
                    (_, _, true) => format!("in [{lo}, {hi})"),
                    _ => format!("in [{lo}, {hi}]"),
                };
                return Err(ctx.err(c, format!("<{tag}> must be {range}, found `{text}`")));
            }
        }
    }
    Ok(())
}

/// A control bound: a number, `Inf`/`-Inf` allowed.
fn control_bound(ctx: &Ctx, node: XNode, tag: &str, default: f64) -> Result<f64, Error> {
    match child(node, tag) {
        None => Ok(default),
        Some(c) => {
            let t = c.text().unwrap_or("").trim();
            let v: f64 = t
                .parse()
                .map_err(|_| ctx.err(c, format!("<{tag}>: `{t}` is not a number")))?;
            if v.is_nan() {
                return Err(ctx.err(c, format!("<{tag}> is NaN")));
            }
            Ok(v)
        }
    }
}

/// A body named by an actuator property: a body name or a path whose last part is one.
fn actuator_body(ctx: &Ctx, node: XNode, tag: &str, model: &Model) -> Result<Option<usize>, Error> {
    let Some(text) = ctx.text(node, tag).filter(|t| !t.is_empty()) else {
        return Ok(None);
    };
    let name = text.rsplit('/').next().unwrap_or(text);
    model
        .body_index(name)
        .map(Some)
        .ok_or_else(|| ctx.err(node, format!("<{tag}>: unknown body `{text}`")))
}

fn unit(ctx: &Ctx, node: XNode, tag: &str, v: Vec3) -> Result<Vec3, Error> {
    let n = v.norm();
    if !(n > 0.0) {
        return Err(ctx.err(node, format!("<{tag}> must be a non-zero vector")));
    }
    Ok(v / n)
}

/// The control bounds, optimal force and point of action of OpenSim's scalar actuators.
/// Control defaults are OpenSim's: muscles [0, 1], except Thelen 2003 and Millard 2012 whose
/// minimum is their default minimum activation 0.01; other actuators unbounded.
fn read_scalar_actuator(
    ctx: &Ctx,
    f: XNode,
    kind: &str,
    is_muscle: bool,
    model: &Model,
) -> Result<Option<ScalarActuator>, Error> {
    let (min_default, max_default) = match kind {
        _ if !is_muscle => (f64::NEG_INFINITY, f64::INFINITY),
        "Thelen2003Muscle" | "Millard2012EquilibriumMuscle" => (0.01, 1.0),
        _ => (0.0, 1.0),
    };
    let actuator_kind = if is_muscle {
        ActuatorKind::Muscle
    } else {
        match kind {
            "PathActuator" => ActuatorKind::Path,
            "CoordinateActuator" => ActuatorKind::Coordinate {
                coordinate: coordinate_from_socket(ctx, f, model, "coordinate")?,
            },
            "PointActuator" => {
                let body = actuator_body(ctx, f, "body", model)?
                    .ok_or_else(|| ctx.err(f, "missing <body>"))?;
                ActuatorKind::Point {
                    body,
                    point: ctx.vec3_or(f, "point", Vec3::zeros())?,
                    point_is_global: ctx.bool_or(f, "point_is_global", false)?,
                    direction: unit(
                        ctx,
                        f,
                        "direction",
                        ctx.vec3_or(f, "direction", Vec3::new(1.0, 0.0, 0.0))?,
                    )?,
                    force_is_global: ctx.bool_or(f, "force_is_global", false)?,
                }
            }
            "TorqueActuator" => {
                let body_a = actuator_body(ctx, f, "bodyA", model)?
                    .ok_or_else(|| ctx.err(f, "missing <bodyA>"))?;
                ActuatorKind::Torque {
                    body_a,
                    body_b: actuator_body(ctx, f, "bodyB", model)?.unwrap_or(0),
                    axis: unit(
                        ctx,
                        f,
                        "axis",
                        ctx.vec3_or(f, "axis", Vec3::new(0.0, 0.0, 1.0))?,
                    )?,
                    torque_is_global: ctx.bool_or(f, "torque_is_global", true)?,
                }
            }
            _ => return Ok(None),
        }
    };
    let min_control = control_bound(ctx, f, "min_control", min_default)?;
    let max_control = control_bound(ctx, f, "max_control", max_default)?;
    if min_control > max_control {
        return Err(ctx.err(
            f,
            format!("<min_control> {min_control} is greater than <max_control> {max_control}"),
        ));
    }
    let optimal_force = ctx.f64_or(f, "optimal_force", 1.0)?;
    if !is_muscle && !(optimal_force > 0.0) {
        return Err(ctx.err(
            f,
            format!("<optimal_force> must be positive, found {optimal_force}"),
        ));
    }
    Ok(Some(ScalarActuator {
        min_control,
        max_control,
        optimal_force,
        kind: actuator_kind,
    }))
}

fn read_geometry_path(
    ctx: &mut Ctx,
    gp: XNode,
    frames: &mut FrameRegistry,
    model: &Model,
    owner: &str,
) -> Result<GeometryPath, Error> {
    let gp_owner = resolve_path(owner, gp.attribute("name").unwrap_or("geometrypath"));
    let mut path = GeometryPath::default();
    for c in elements(gp) {
        match c.tag_name().name() {
            "PathPointSet" => {
                for p in set_members(c) {
                    path.points
                        .push(read_path_point(ctx, p, frames, model, &gp_owner)?);
                }
            }
            "PathWrapSet" => {
                for w in set_members(c) {
                    path.wraps.push(read_path_wrap(ctx, w, model)?);
                }
            }
            "default_color" => {}
            _ => ctx.unknown(c),
        }
    }
    if path.points.len() < 2 {
        return Err(ctx.err(
            gp,
            format!(
                "a path needs at least 2 points, found {}",
                path.points.len()
            ),
        ));
    }
    Ok(path)
}

fn read_path_point(
    ctx: &mut Ctx,
    p: XNode,
    frames: &mut FrameRegistry,
    model: &Model,
    owner: &str,
) -> Result<PathPoint, Error> {
    let tag = p.tag_name().name();
    let name = ctx.name(p)?;
    let point_owner = resolve_path(owner, &name);
    let (body, frame_in_body) = frame_socket(ctx, p, frames, &point_owner, "socket_parent_frame")?;
    let mut location = ctx.vec3_or(p, "location", Vec3::zeros())?;
    let kind = match tag {
        "PathPoint" => PathPointKind::Fixed,
        "ConditionalPathPoint" => {
            let coordinate = coordinate_from_socket(ctx, p, model, "socket_coordinate")?;
            let r = ctx
                .vec_opt(p, "range")?
                .ok_or_else(|| ctx.err(p, "missing <range>"))?;
            if r.len() != 2 || r[0] > r[1] {
                return Err(ctx.err(p, "<range> must be two numbers, minimum first"));
            }
            PathPointKind::Conditional {
                coordinate,
                range: [r[0], r[1]],
            }
        }
        "MovingPathPoint" => {
            let comp = |axis: &str| -> Result<(Function, usize), Error> {
                let holder = child(p, &format!("{axis}_location"))
                    .ok_or_else(|| ctx.err(p, format!("missing <{axis}_location>")))?;
                let fnode = function_child(holder)
                    .ok_or_else(|| ctx.err(holder, "holds no function element"))?;
                let f = parse_function(ctx, fnode)?;
                if !matches!(f.arity(), Arity::Any | Arity::Exactly(1)) {
                    return Err(ctx.err(
                        fnode,
                        "a moving point's location must be a function of one coordinate",
                    ));
                }
                let c =
                    coordinate_from_socket(ctx, p, model, &format!("socket_{axis}_coordinate"))?;
                Ok((f, c))
            };
            let (x, y, z) = (comp("x")?, comp("y")?, comp("z")?);
            // Location at the model's default coordinate values.
            let at = |(f, c): &(Function, usize)| f.eval1(model.coordinates[*c].default_value).0;
            location = Vec3::new(at(&x), at(&y), at(&z));
            PathPointKind::Moving { x, y, z }
        }
        _ => return Err(ctx.err(p, format!("unsupported path point type `{tag}`"))),
    };
    for c in elements(p) {
        match c.tag_name().name() {
            "socket_parent_frame"
            | "location"
            | "socket_coordinate"
            | "range"
            | "x_location"
            | "y_location"
            | "z_location"
            | "socket_x_coordinate"
            | "socket_y_coordinate"
            | "socket_z_coordinate" => {}
            _ => ctx.unknown(c),
        }
    }
    Ok(PathPoint {
        name,
        body,
        frame_in_body,
        location,
        kind,
        line: ctx.line(p),
    })
}

fn read_path_wrap(ctx: &mut Ctx, w: XNode, model: &Model) -> Result<PathWrap, Error> {
    if w.tag_name().name() != "PathWrap" {
        return Err(ctx.err(
            w,
            format!("unsupported path wrap type `{}`", w.tag_name().name()),
        ));
    }
    let obj = ctx.req_text(w, "wrap_object")?;
    let hits: Vec<usize> = (0..model.wrap_objects.len())
        .filter(|&i| model.wrap_objects[i].name == obj)
        .collect();
    let wrap_object = match hits.as_slice() {
        [i] => *i,
        [] => {
            return Err(ctx.err(w, format!(
                "unknown wrap object `{obj}` (or one of a type musculo does not support: see the warnings)"
            )));
        }
        _ => {
            return Err(ctx.err(
                w,
                format!("wrap object name `{obj}` is used by several bodies"),
            ));
        }
    };
    let range = match ctx.vec_opt(w, "range")? {
        None => [-1, -1],
        Some(r) if r.len() == 2 && r.iter().all(|v| v.fract() == 0.0) => [r[0] as i32, r[1] as i32],
        Some(_) => return Err(ctx.err(w, "<range> must be two integers")),
    };
    Ok(PathWrap {
        wrap_object,
        method: ctx.text(w, "method").unwrap_or("hybrid").to_string(),
        range,
    })
}
