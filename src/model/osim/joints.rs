//! Joints and coordinates: reading every OpenSim 4 joint type, expanding each into its
//! sequence of fixed transforms and movable axes, and ordering the tree from ground.

use super::functions::{function_child, parse_function};
use super::read_offset_frame;
use super::xml::{Ctx, XNode, child, elements};
use crate::error::Error;
use crate::model::frames::FrameRegistry;
use crate::model::{
    Arity, Coordinate, CoordinateRole, Dof, DofKind, Function, Joint, JointKind, JointStep,
    MotionType,
};
use crate::spatial::{Transform, Vec3, rotation_about_axis};

/// A coordinate as read.
struct CoordDef<'a, 'i> {
    node: XNode<'a, 'i>,
    name: String,
    default_value: f64,
    default_speed: f64,
    range: [f64; 2],
    clamped: bool,
    locked: bool,
    prescribed: bool,
}

/// One TransformAxis of a CustomJoint.
struct AxisDef<'a, 'i> {
    node: XNode<'a, 'i>,
    rotation: bool,
    axis: Vec3,
    coords: Vec<String>,
    function: Function,
}

pub(super) struct JointDef<'a, 'i> {
    node: XNode<'a, 'i>,
    name: String,
    kind: JointKind,
    parent_socket: String,
    child_socket: String,
    coords: Vec<CoordDef<'a, 'i>>,
    axes: Vec<AxisDef<'a, 'i>>,
}

fn joint_kind(tag: &str) -> Option<JointKind> {
    Some(match tag {
        "CustomJoint" => JointKind::Custom,
        "PinJoint" => JointKind::Pin,
        "SliderJoint" => JointKind::Slider,
        "WeldJoint" => JointKind::Weld,
        "UniversalJoint" => JointKind::Universal,
        "BallJoint" => JointKind::Ball,
        "GimbalJoint" => JointKind::Gimbal,
        "FreeJoint" => JointKind::Free,
        "PlanarJoint" => JointKind::Planar,
        _ => return None,
    })
}

/// Reads every joint element and registers the offset frames it owns.
pub(super) fn read_joints<'a, 'i>(
    ctx: &mut Ctx<'a, 'i>,
    nodes: &[XNode<'a, 'i>],
    frames: &mut FrameRegistry,
) -> Result<Vec<JointDef<'a, 'i>>, Error> {
    let mut defs = Vec::new();
    let mut names = std::collections::HashSet::new();
    for &j in nodes {
        let tag = j.tag_name().name();
        let kind = joint_kind(tag).ok_or_else(|| {
            ctx.err(j, format!(
                "unsupported joint type `{tag}` (musculo reads CustomJoint, PinJoint, SliderJoint, WeldJoint, \
                 UniversalJoint, BallJoint, GimbalJoint, FreeJoint and PlanarJoint)"
            ))
        })?;
        let name = ctx.name(j)?;
        if !names.insert(name.clone()) {
            return Err(ctx.err(j, "two joints have this name"));
        }
        let owner = format!("/jointset/{name}");
        let mut coords = Vec::new();
        let mut axes = Vec::new();
        for c in elements(j) {
            match c.tag_name().name() {
                "socket_parent_frame" | "socket_child_frame" => {}
                "reverse" => {
                    if ctx.bool_or(j, "reverse", false)? {
                        return Err(ctx.err(c, "reversed joints are not supported"));
                    }
                }
                "frames" => {
                    for f in super::set_members(c) {
                        if f.tag_name().name() == "PhysicalOffsetFrame" {
                            let def = read_offset_frame(ctx, f, &owner)?;
                            if !frames.add_offset(def) {
                                return Err(ctx.err(f, "another frame has the same path"));
                            }
                        } else {
                            return Err(ctx.err(
                                f,
                                format!(
                                    "unsupported frame type `{}` in a joint",
                                    f.tag_name().name()
                                ),
                            ));
                        }
                    }
                }
                "coordinates" => {
                    for k in elements(c) {
                        if k.tag_name().name() != "Coordinate" {
                            ctx.unknown(k);
                            continue;
                        }
                        coords.push(read_coordinate(ctx, k)?);
                    }
                }
                "SpatialTransform" if kind == JointKind::Custom => {
                    axes = read_spatial_transform(ctx, c)?;
                }
                _ => ctx.unknown(c),
            }
        }
        let parent_socket = ctx
            .text(j, "socket_parent_frame")
            .filter(|s| !s.is_empty())
            .ok_or_else(|| ctx.err(j, "missing <socket_parent_frame>"))?
            .to_string();
        let child_socket = ctx
            .text(j, "socket_child_frame")
            .filter(|s| !s.is_empty())
            .ok_or_else(|| ctx.err(j, "missing <socket_child_frame>"))?
            .to_string();
        if kind == JointKind::Custom && axes.is_empty() {
            return Err(ctx.err(j, "CustomJoint without a <SpatialTransform>"));
        }
        defs.push(JointDef {
            node: j,
            name,
            kind,
            parent_socket,
            child_socket,
            coords,
            axes,
        });
    }
    Ok(defs)
}

fn read_coordinate<'a, 'i>(
    ctx: &mut Ctx<'a, 'i>,
    k: XNode<'a, 'i>,
) -> Result<CoordDef<'a, 'i>, Error> {
    let name = ctx.name(k)?;
    let range = match ctx.vec_opt(k, "range")? {
        None => [-10.0, 10.0], // OpenSim's default range
        Some(r) if r.len() == 2 => [r[0], r[1]],
        Some(r) => {
            return Err(ctx.err(k, format!("<range> must hold 2 numbers, found {}", r.len())));
        }
    };
    if range[0] > range[1] {
        return Err(ctx.err(
            k,
            format!("<range> minimum {} exceeds maximum {}", range[0], range[1]),
        ));
    }
    // The functions of the coordinate are checked, and MJCF fits made, over samples of the
    // range: a range whose width overflows (±1e308) has no samples.
    if !(range[1] - range[0]).is_finite() {
        return Err(ctx.err(
            k,
            format!(
                "<range> [{:e}, {:e}] is wider than the largest number (its width overflows): \
                 give the coordinate's real limits",
                range[0], range[1]
            ),
        ));
    }
    let prescribed = ctx.bool_or(k, "prescribed", false)?;
    for c in elements(k) {
        match c.tag_name().name() {
            "default_value"
            | "default_speed_value"
            | "range"
            | "clamped"
            | "locked"
            | "prescribed"
            | "prescribed_function"
            | "is_free_to_satisfy_constraints" => {}
            "motion_type" => {}
            _ => ctx.unknown(c),
        }
    }
    if prescribed {
        ctx.warn(k, "prescribed coordinate: treated as an ordinary degree of freedom (its values come from the motion)");
    }
    Ok(CoordDef {
        node: k,
        name,
        default_value: ctx.f64_or(k, "default_value", 0.0)?,
        default_speed: ctx.f64_or(k, "default_speed_value", 0.0)?,
        range,
        clamped: ctx.bool_or(k, "clamped", false)?,
        locked: ctx.bool_or(k, "locked", false)?,
        prescribed,
    })
}

const AXIS_NAMES: [&str; 6] = [
    "rotation1",
    "rotation2",
    "rotation3",
    "translation1",
    "translation2",
    "translation3",
];

fn read_spatial_transform<'a, 'i>(
    ctx: &mut Ctx<'a, 'i>,
    st: XNode<'a, 'i>,
) -> Result<Vec<AxisDef<'a, 'i>>, Error> {
    let mut found: [Option<XNode>; 6] = [None; 6];
    for a in elements(st) {
        if a.tag_name().name() != "TransformAxis" {
            ctx.unknown(a);
            continue;
        }
        let name = ctx.object_name(a)?;
        let i = AXIS_NAMES.iter().position(|n| *n == name).ok_or_else(|| {
            ctx.err(
                a,
                format!(
                    "TransformAxis name must be one of {}",
                    AXIS_NAMES.join(", ")
                ),
            )
        })?;
        if found[i].is_some() {
            return Err(ctx.err(a, "this TransformAxis appears twice"));
        }
        found[i] = Some(a);
    }
    let mut axes = Vec::with_capacity(6);
    for (i, a) in found.iter().enumerate() {
        let a =
            a.ok_or_else(|| ctx.err(st, format!("missing TransformAxis `{}`", AXIS_NAMES[i])))?;
        let coords: Vec<String> = ctx
            .text(a, "coordinates")
            .unwrap_or("")
            .split_whitespace()
            .map(str::to_string)
            .collect();
        let axis = ctx.vec3_or(a, "axis", Vec3::zeros())?;
        if child(a, "axis").is_none() {
            return Err(ctx.err(a, "missing <axis>"));
        }
        let norm = axis.norm();
        if norm < 1e-12 {
            return Err(ctx.err(a, "<axis> is the zero vector"));
        }
        // OpenSim's defaults: no function means f = q for one coordinate, 0 for none.
        let function = match function_child(a) {
            Some(f) => parse_function(ctx, f)?,
            None => match coords.len() {
                0 => Function::Constant(0.0),
                1 => Function::Linear(vec![1.0, 0.0]),
                _ => return Err(ctx.err(a, "several coordinates but no function")),
            },
        };
        if let Arity::Exactly(k) = function.arity()
            && k != coords.len()
        {
            return Err(ctx.err(
                a,
                format!(
                    "{} of {k} argument(s) driven by {} coordinate(s)",
                    function.kind_name(),
                    coords.len()
                ),
            ));
        }
        for c in elements(a) {
            let t = c.tag_name().name();
            if !matches!(t, "coordinates" | "axis") && !super::functions::is_function_tag(t) {
                ctx.unknown(c);
            }
        }
        axes.push(AxisDef {
            node: a,
            rotation: i < 3,
            axis: axis / norm,
            coords,
            function,
        });
    }
    // OpenSim refuses collinear axes within the rotations or within the translations.
    for start in [0, 3] {
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if axes[start + p].axis.cross(&axes[start + q].axis).norm() < 1e-5 {
                return Err(ctx.err(
                    st,
                    format!(
                        "axes of {} and {} are collinear",
                        AXIS_NAMES[start + p],
                        AXIS_NAMES[start + q]
                    ),
                ));
            }
        }
    }
    Ok(axes)
}

/// The kinematic tree in topological order.
pub(super) struct Tree {
    pub joints: Vec<Joint>,
    pub coordinates: Vec<Coordinate>,
    pub dofs: Vec<Dof>,
    /// new body index → file-order index (ground first).
    pub body_order: Vec<usize>,
    /// file-order index → new index.
    pub body_new_index: Vec<usize>,
    pub body_joint: Vec<Option<usize>>,
    pub body_parent: Vec<Option<usize>>,
}

/// A joint's frames resolved to bodies: X_PF on the parent, X_BM on the child.
struct Resolved {
    parent: usize,
    x_parent: Transform,
    child: usize,
    x_child: Transform,
}

/// Orders the joints from ground (file order among those ready), numbers the bodies in that
/// order and expands each joint into its coordinates, full coordinates and steps.
pub(super) fn build_tree(
    ctx: &mut Ctx,
    defs: Vec<JointDef>,
    frames: &mut FrameRegistry,
    body_lines: &[u32],
) -> Result<Tree, Error> {
    let n_bodies = body_lines.len();
    let (resolved, child_of) = resolve_joint_frames(ctx, &defs, frames, n_bodies)?;
    let order = topological_order(&resolved, n_bodies)
        .map_err(|k| unplaced_joint_error(ctx, &defs, &resolved, &child_of, frames, k))?;
    if let Some(b) = (1..n_bodies).find(|&b| child_of[b].is_none()) {
        let path = body_name_hint(frames, b);
        return Err(Error::Model {
            file: ctx.file.to_string(),
            line: body_lines[b],
            element: format!("Body \"{}\"", path.rsplit('/').next().unwrap_or(&path)),
            message: "no joint connects this body to the tree".into(),
        });
    }

    // New body numbering: ground, then children in joint order.
    let mut body_order = vec![0usize];
    body_order.extend(order.iter().map(|&k| resolved[k].child));
    let mut body_new_index = vec![0usize; n_bodies];
    for (new, &old) in body_order.iter().enumerate() {
        body_new_index[old] = new;
    }

    let mut builder = TreeBuilder::new(n_bodies, order.len());
    for &k in &order {
        builder.add_joint(ctx, &defs[k], &resolved[k], &body_new_index)?;
    }
    // body_joint / body_parent were filled at new indices.
    Ok(Tree {
        joints: builder.joints,
        coordinates: builder.coordinates,
        dofs: builder.dofs,
        body_order,
        body_new_index,
        body_joint: builder.body_joint,
        body_parent: builder.body_parent,
    })
}

/// Resolves each joint's parent and child frames to bodies; a reversed joint (ground as the
/// child), a joint within one body or a body with two parent joints is an error. Returns the
/// resolved frames and, per file-order body, the joint whose child it is.
fn resolve_joint_frames(
    ctx: &Ctx,
    defs: &[JointDef],
    frames: &mut FrameRegistry,
    n_bodies: usize,
) -> Result<(Vec<Resolved>, Vec<Option<usize>>), Error> {
    let mut resolved = Vec::with_capacity(defs.len());
    let mut child_of: Vec<Option<usize>> = vec![None; n_bodies];
    for (k, d) in defs.iter().enumerate() {
        let owner = format!("/jointset/{}", d.name);
        let (parent, x_parent) = frames
            .resolve(&owner, &d.parent_socket)
            .map_err(|e| ctx.err(d.node, format!("parent frame: {e}")))?;
        let (child, x_child) = frames
            .resolve(&owner, &d.child_socket)
            .map_err(|e| ctx.err(d.node, format!("child frame: {e}")))?;
        if child == 0 {
            return Err(ctx.err(
                d.node,
                "ground is the joint's child: reversed joints are not supported",
            ));
        }
        if child == parent {
            return Err(ctx.err(d.node, "parent and child frames are on the same body"));
        }
        if let Some(other) = child_of[child] {
            return Err(ctx.err(
                d.node,
                format!(
                    "body is already the child of joint `{}` (closed loops are not supported)",
                    defs[other].name
                ),
            ));
        }
        child_of[child] = Some(k);
        resolved.push(Resolved {
            parent,
            x_parent,
            child,
            x_child,
        });
    }
    Ok((resolved, child_of))
}

/// Stable topological order: repeatedly take, in file order, the joints whose parent body
/// is already placed. Err(the first joint never reached), from a cycle or a missing
/// connection.
fn topological_order(resolved: &[Resolved], n_bodies: usize) -> Result<Vec<usize>, usize> {
    let mut placed = vec![false; n_bodies];
    placed[0] = true;
    let mut order = Vec::with_capacity(resolved.len());
    let mut done = vec![false; resolved.len()];
    loop {
        let mut progress = false;
        for k in 0..resolved.len() {
            if !done[k] && placed[resolved[k].parent] {
                done[k] = true;
                placed[resolved[k].child] = true;
                order.push(k);
                progress = true;
            }
        }
        if !progress {
            break;
        }
    }
    match (0..resolved.len()).find(|&k| !done[k]) {
        Some(k) => Err(k),
        None => Ok(order),
    }
}

/// The error for joint `k`, which the topological order never reached: walking up its
/// parents tells a cycle from a missing connection to ground.
fn unplaced_joint_error(
    ctx: &Ctx,
    defs: &[JointDef],
    resolved: &[Resolved],
    child_of: &[Option<usize>],
    frames: &FrameRegistry,
    k: usize,
) -> Error {
    let mut chain = vec![k];
    let mut body = resolved[k].parent;
    loop {
        match child_of[body] {
            None => {
                return ctx.err(
                    defs[k].node,
                    format!(
                        "not connected to ground: body `{}` has no joint to a parent",
                        body_name_hint(frames, body)
                    ),
                );
            }
            Some(j) if chain.contains(&j) => {
                let names: Vec<&str> = chain.iter().map(|&j| defs[j].name.as_str()).collect();
                return ctx.err(
                    defs[k].node,
                    format!(
                        "joints form a cycle ({}), so no body in it is connected to ground",
                        names.join(" → ")
                    ),
                );
            }
            Some(j) => {
                chain.push(j);
                body = resolved[j].parent;
            }
        }
    }
}

/// The tree as it is assembled, joint by joint in topological order (bodies at new indices).
struct TreeBuilder {
    joints: Vec<Joint>,
    coordinates: Vec<Coordinate>,
    dofs: Vec<Dof>,
    body_joint: Vec<Option<usize>>,
    body_parent: Vec<Option<usize>>,
    /// The last full coordinate on each body's chain from ground (its dofs' `parent_dof`).
    last_dof_of_body: Vec<Option<usize>>,
    coord_names: std::collections::HashMap<String, usize>,
}

impl TreeBuilder {
    fn new(n_bodies: usize, n_joints: usize) -> Self {
        TreeBuilder {
            joints: Vec::with_capacity(n_joints),
            coordinates: Vec::new(),
            dofs: Vec::new(),
            body_joint: vec![None; n_bodies],
            body_parent: vec![None; n_bodies],
            last_dof_of_body: vec![None; n_bodies],
            coord_names: std::collections::HashMap::new(),
        }
    }

    /// Appends joint `d` (resolved as `r`): its coordinates, then its steps (fixed transforms
    /// and full coordinates) from the joint type's recipe.
    fn add_joint(
        &mut self,
        ctx: &Ctx,
        d: &JointDef,
        r: &Resolved,
        body_new_index: &[usize],
    ) -> Result<(), Error> {
        let ji = self.joints.len();
        let parent = body_new_index[r.parent];
        let child = body_new_index[r.child];
        self.body_joint[child] = Some(ji);
        self.body_parent[child] = Some(parent);

        let (coord_defs, motion_types, recipe) = joint_recipe(ctx, d)?;
        let first_coord = self.coordinates.len();
        for (cd, mt) in coord_defs.iter().zip(motion_types) {
            self.add_coordinate(ctx, cd, mt, ji)?;
        }

        let mut steps = Vec::new();
        let dof_start = self.dofs.len();
        let mut prev = self.last_dof_of_body[parent];
        for item in recipe {
            match item {
                RecipeItem::Fixed(x) => steps.push(JointStep::Fixed(x)),
                RecipeItem::Axis {
                    name,
                    kind,
                    axis,
                    function,
                    args,
                } => {
                    let di = self.dofs.len();
                    self.dofs.push(Dof {
                        name: format!("{}/{}", d.name, name),
                        joint: ji,
                        kind,
                        axis,
                        function,
                        args: args.into_iter().map(|a| first_coord + a).collect(),
                        parent_dof: prev,
                        body: child,
                    });
                    prev = Some(di);
                    steps.push(JointStep::Dof(di));
                }
            }
        }
        self.last_dof_of_body[child] = prev;
        self.joints.push(Joint {
            name: d.name.clone(),
            kind: d.kind,
            parent_body: parent,
            child_body: child,
            parent_offset: r.x_parent,
            child_offset: r.x_child,
            child_offset_inv: r.x_child.inverse(),
            coordinates: (first_coord..self.coordinates.len()).collect(),
            steps,
            dof_range: dof_start..self.dofs.len(),
            line: ctx.line(d.node),
        });
        Ok(())
    }

    /// Appends coordinate `cd` of joint `ji`; two coordinates with one name are an error.
    fn add_coordinate(
        &mut self,
        ctx: &Ctx,
        cd: &CoordDef,
        motion_type: MotionType,
        ji: usize,
    ) -> Result<(), Error> {
        if self
            .coord_names
            .insert(cd.name.clone(), self.coordinates.len())
            .is_some()
        {
            return Err(ctx.err(cd.node, "two coordinates have this name"));
        }
        self.coordinates.push(Coordinate {
            name: cd.name.clone(),
            joint: ji,
            motion_type,
            default_value: cd.default_value,
            default_speed: cd.default_speed,
            range: cd.range,
            clamped: cd.clamped,
            locked: cd.locked,
            prescribed: cd.prescribed,
            role: CoordinateRole::Locked, // set by the reduction
            line: ctx.line(cd.node),
        });
        Ok(())
    }
}

fn body_name_hint(frames: &FrameRegistry, body: usize) -> String {
    frames.body_path(body).unwrap_or_else(|| format!("#{body}"))
}

enum RecipeItem {
    Fixed(Transform),
    Axis {
        name: String,
        kind: DofKind,
        axis: Vec3,
        function: Function,
        /// Argument indices into the joint's own coordinate list.
        args: Vec<usize>,
    },
}

type Recipe<'d, 'a, 'i> = (Vec<&'d CoordDef<'a, 'i>>, Vec<MotionType>, Vec<RecipeItem>);

/// The joint's coordinates (in mobility order), their motion types, and the transform
/// F → M as a sequence of fixed steps and movable axes: translations along F's axes first,
/// then the rotations in body-fixed order — X_FM = [R₁(θ₁) R₂(θ₂) R₃(θ₃), Σ tᵢ aᵢ].
fn joint_recipe<'d, 'a, 'i>(
    ctx: &Ctx,
    d: &'d JointDef<'a, 'i>,
) -> Result<Recipe<'d, 'a, 'i>, Error> {
    use DofKind::{Hinge, Slide};
    let identity = Function::Linear(vec![1.0, 0.0]);
    let ex = Vec3::x();
    let ey = Vec3::y();
    let ez = Vec3::z();
    // (name, kind, axis, coordinate index) for the fixed-structure joints.
    let layout: Vec<(&str, DofKind, Vec3, usize)> = match d.kind {
        JointKind::Custom => return custom_recipe(ctx, d),
        JointKind::Weld => vec![],
        JointKind::Pin => vec![("rz", Hinge, ez, 0)],
        JointKind::Slider => vec![("tx", Slide, ex, 0)],
        JointKind::Universal => vec![("rx", Hinge, ex, 0), ("ry", Hinge, ey, 1)],
        JointKind::Ball | JointKind::Gimbal => {
            vec![
                ("rx", Hinge, ex, 0),
                ("ry", Hinge, ey, 1),
                ("rz", Hinge, ez, 2),
            ]
        }
        JointKind::Free => vec![
            ("tx", Slide, ex, 3),
            ("ty", Slide, ey, 4),
            ("tz", Slide, ez, 5),
            ("rx", Hinge, ex, 0),
            ("ry", Hinge, ey, 1),
            ("rz", Hinge, ez, 2),
        ],
        JointKind::Planar => vec![
            ("tx", Slide, ex, 1),
            ("ty", Slide, ey, 2),
            ("rz", Hinge, ez, 0),
        ],
    };
    if d.coords.len() != layout.len() {
        return Err(ctx.err(
            d.node,
            format!(
                "{} needs {} coordinate(s), found {}",
                d.kind.name(),
                layout.len(),
                d.coords.len()
            ),
        ));
    }
    let mut types = vec![MotionType::Rotational; d.coords.len()];
    let mut recipe = Vec::new();
    for (name, kind, axis, c) in layout {
        if kind == Slide {
            types[c] = MotionType::Translational;
        }
        recipe.push(RecipeItem::Axis {
            name: name.to_string(),
            kind,
            axis,
            function: identity.clone(),
            args: vec![c],
        });
    }
    Ok((d.coords.iter().collect(), types, recipe))
}

fn custom_recipe<'d, 'a, 'i>(
    ctx: &Ctx,
    d: &'d JointDef<'a, 'i>,
) -> Result<Recipe<'d, 'a, 'i>, Error> {
    // Coordinates in order of first appearance in the SpatialTransform (OpenSim's mobility
    // order), each of which must be declared in the joint's <coordinates>.
    let mut order: Vec<usize> = Vec::new();
    for a in &d.axes {
        for n in &a.coords {
            let i = d.coords.iter().position(|c| &c.name == n).ok_or_else(|| {
                ctx.err(
                    a.node,
                    format!("unknown coordinate `{n}`: it is not one of this joint's coordinates"),
                )
            })?;
            if !order.contains(&i) {
                order.push(i);
            }
        }
    }
    if let Some(unused) = d
        .coords
        .iter()
        .enumerate()
        .find(|(i, _)| !order.contains(i))
    {
        return Err(ctx.err(
            unused.1.node,
            "coordinate drives no TransformAxis of its CustomJoint",
        ));
    }
    let slot = |n: &String| {
        order
            .iter()
            .position(|&i| &d.coords[i].name == n)
            .unwrap_or(0)
    };

    // OpenSim's motion type rule: an axis with a LinearFunction of slope ±1 makes the
    // coordinate Rotational or Translational; any other function makes it Coupled unless it
    // is already pure on another axis.
    let mut types: Vec<Option<MotionType>> = vec![None; order.len()];
    for (ai, a) in d.axes.iter().enumerate() {
        for n in &a.coords {
            let s = slot(n);
            let pure =
                matches!(&a.function, Function::Linear(c) if c.len() == 2 && c[0].abs() == 1.0);
            if pure {
                types[s] = Some(if ai < 3 {
                    MotionType::Rotational
                } else {
                    MotionType::Translational
                });
            } else if types[s].is_none() {
                types[s] = Some(MotionType::Coupled);
            }
        }
    }
    // musculo's one departure: a coordinate that drives only rotation axes, each through a
    // LinearFunction, is an angle whatever the slopes (e.g. lumbar extension shared over five
    // vertebral joints); OpenSim would call it Coupled and leave it unconverted from degrees.
    for (s, t) in types.iter_mut().enumerate() {
        if *t != Some(MotionType::Coupled) {
            continue;
        }
        let name = &d.coords[order[s]].name;
        let users: Vec<(usize, &_)> = (d.axes.iter().enumerate())
            .filter(|(_, a)| a.coords.contains(name))
            .collect();
        if !users.is_empty()
            && users.iter().all(|(ai, a)| {
                *ai < 3 && matches!(&a.function, Function::Linear(c) if c.len() == 2 && c[0] != 0.0)
            })
        {
            *t = Some(MotionType::Rotational);
        }
    }
    let types = types
        .into_iter()
        .map(|t| t.unwrap_or(MotionType::Coupled))
        .collect();

    let mut recipe = Vec::new();
    for ai in [3, 4, 5, 0, 1, 2] {
        let a = &d.axes[ai];
        let name = AXIS_NAMES[ai].to_string();
        let kind = if a.rotation {
            DofKind::Hinge
        } else {
            DofKind::Slide
        };
        if a.function.is_constant() {
            let v = a.function.eval1(0.0).0;
            if v != 0.0 {
                let x = match kind {
                    DofKind::Slide => Transform::new(crate::spatial::Mat3::identity(), a.axis * v),
                    DofKind::Hinge => {
                        Transform::new(rotation_about_axis(&a.axis, v), Vec3::zeros())
                    }
                };
                recipe.push(RecipeItem::Fixed(x));
            }
        } else {
            recipe.push(RecipeItem::Axis {
                name,
                kind,
                axis: a.axis,
                function: a.function.clone(),
                args: a.coords.iter().map(&slot).collect(),
            });
        }
    }
    Ok((order.iter().map(|&i| &d.coords[i]).collect(), types, recipe))
}
