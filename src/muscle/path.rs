//! Geometry paths: musculotendon length ℓ(q), lengthening speed ℓ̇ and moment arms
//! r_jk = −∂ℓ_k/∂q_j for every path of a model, as OpenSim's GeometryPath defines them.
//!
//! A path is its active points in order — fixed points, conditional points whose coordinate
//! lies in their range (±1e-5, OpenSim's tolerance), moving points whose location is a
//! function of a coordinate (clamped to the coordinate's range, as OpenSim does) — with the
//! tangent points of its wrap objects inserted by OpenSim's algorithm (see
//! [`apply_wrap_objects`]). Its length is the sum of the straight segments plus the surface
//! lengths between each wrap object's two tangent points.
//!
//! Moment arms come from the tension the path transmits, not from finite differences:
//!   ℓ̇ = Σ_segments û_k·(v_{k+1} − v_k) = Σ_nodes v_k·(û_{k−1} − û_k),
//! so ∂ℓ/∂q = Σ_nodes J_kᵀ (û_{k−1} − û_k) with J_k the Jacobian of node k (a tangent point
//! moves with its wrap object's body; a moving point adds R (∂p/∂c) ∂c/∂q). Each node's
//! force is applied to its body as a spatial force about O, summed per body, and projected
//! on the reduced motion columns of the body's ancestors, as in the backward pass of RNEA.
//! Surface arcs contribute nothing: the wrapped path is a shortest path over the surface
//! between its end points, so sliding a tangent point along the surface leaves ℓ stationary
//! (where a wrap algorithm is not exactly a shortest path, its own exact gradients are used;
//! see [`super::wrap`]).

use crate::dynamics::{Data, Stage};
use crate::error::Error;
use crate::model::reduction::NONE;
use crate::model::{Function, Model, PathPointKind, WrapShape};
use crate::spatial::{Force, Vec3};
use nalgebra::DMatrix;

/// One point of a path definition.
#[derive(Clone, Debug)]
struct PointDef {
    body: usize,
    /// Fixed location in the body (fixed and conditional points).
    location: Vec3,
    kind: PointKind,
}

#[derive(Clone, Debug)]
enum PointKind {
    Fixed,
    Conditional {
        coordinate: usize,
        range: [f64; 2],
    },
    /// Location in the body = frame · (f_x(c_x), f_y(c_y), f_z(c_z)).
    Moving {
        frame: crate::spatial::Transform,
        axes: [(Function, usize); 3],
    },
}

/// A wrap object used by a path, with the range of path points it applies to.
#[derive(Clone, Debug)]
struct WrapDef {
    object: usize,
    /// 0-based first and last path point (inclusive) it may wrap between.
    start: usize,
    end: usize,
    quadrant: super::wrap::Quadrant,
    method: super::wrap::EllipsoidMethod,
}

/// The immutable description of one path.
#[derive(Clone, Debug)]
pub struct PathGeometry {
    /// Index of the force element in `Model::forces`.
    pub force: usize,
    pub name: String,
    points: Vec<PointDef>,
    wraps: Vec<WrapDef>,
}

/// Every geometry path of a model (muscles and path actuators), in `Model::forces` order.
#[derive(Clone, Debug)]
pub struct PathSet {
    pub paths: Vec<PathGeometry>,
    max_nodes: usize,
}

impl PathSet {
    /// Builds the path definitions of every force element that has a geometry path.
    pub fn new(model: &Model) -> crate::Result<PathSet> {
        Self::with_filter(model, |_| true)
    }

    /// The paths of the muscles only, in `Model::forces` order.
    pub fn muscles(model: &Model) -> crate::Result<PathSet> {
        Self::with_filter(model, |f| f.is_muscle())
    }

    fn with_filter(
        model: &Model,
        keep: impl Fn(&crate::model::ForceElement) -> bool,
    ) -> crate::Result<PathSet> {
        let mut paths = Vec::new();
        let mut max_nodes = 0;
        for (fi, f) in model.forces.iter().enumerate() {
            let Some(gp) = &f.path else { continue };
            if !keep(f) {
                continue;
            }
            let mut points = Vec::with_capacity(gp.points.len());
            for p in &gp.points {
                let kind = match &p.kind {
                    PathPointKind::Fixed => PointKind::Fixed,
                    PathPointKind::Conditional { coordinate, range } => PointKind::Conditional {
                        coordinate: *coordinate,
                        range: *range,
                    },
                    PathPointKind::Moving { x, y, z } => PointKind::Moving {
                        frame: p.frame_in_body,
                        axes: [x.clone(), y.clone(), z.clone()],
                    },
                };
                points.push(PointDef {
                    body: p.body,
                    location: p.frame_in_body.apply_point(&p.location),
                    kind,
                });
            }
            let mut wraps = Vec::with_capacity(gp.wraps.len());
            for w in &gp.wraps {
                let obj = &model.wrap_objects[w.wrap_object];
                let bad = |m: String| Error::Model {
                    file: model.source.clone(),
                    line: f.line,
                    element: format!("{} \"{}\" > PathWrap \"{}\"", f.kind, f.name, obj.name),
                    message: m,
                };
                let n = points.len();
                let start = if w.range[0] < 1 {
                    0
                } else {
                    (w.range[0] as usize - 1).min(n - 1)
                };
                let end = if w.range[1] < 1 {
                    n - 1
                } else {
                    (w.range[1] as usize - 1).min(n - 1)
                };
                wraps.push(WrapDef {
                    object: w.wrap_object,
                    start,
                    end,
                    quadrant: super::wrap::Quadrant::parse(&obj.quadrant).map_err(bad)?,
                    method: super::wrap::EllipsoidMethod::parse(&w.method).map_err(bad)?,
                });
            }
            max_nodes = max_nodes.max(points.len() + 2 * wraps.len());
            paths.push(PathGeometry {
                force: fi,
                name: f.name.clone(),
                points,
                wraps,
            });
        }
        Ok(PathSet { paths, max_nodes })
    }

    pub fn len(&self) -> usize {
        self.paths.len()
    }

    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }

    /// Index of the path of the named force element.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.paths.iter().position(|p| p.name == name)
    }
}

/// What a node of the current path is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum NodeKind {
    /// Path point with this index in the definition.
    Point(usize),
    /// First (false) or second (true) tangent point of the path's wrap with this index.
    Tangent(usize, bool),
}

/// A point of the current (wrapped) path.
#[derive(Clone, Copy, Debug)]
struct Node {
    kind: NodeKind,
    body: usize,
    /// Location in ground.
    ground: Vec3,
    /// For a tangent-point pair (on the second point): the surface length from the first.
    surface: f64,
}

/// Per-worker scratch: the nodes of the current path and the forces it puts on bodies.
#[derive(Clone, Debug)]
struct Scratch {
    nodes: Vec<Node>,
    body_force: Vec<Force>,
    touched: Vec<usize>,
}

impl Scratch {
    fn new(model: &Model, set: &PathSet) -> Scratch {
        Scratch {
            nodes: Vec::with_capacity(set.max_nodes.max(2)),
            body_force: vec![Force::ZERO; model.bodies.len()],
            touched: Vec::with_capacity(model.bodies.len()),
        }
    }
}

/// Workspace for computing the paths of one model; one per thread.
#[derive(Clone, Debug)]
pub struct PathData {
    /// ℓ of each path (m).
    pub length: Vec<f64>,
    /// ℓ̇ of each path (m/s), when velocities were given.
    pub speed: Vec<f64>,
    /// Moment arms r (n × paths): r[(j, k)] = −∂ℓ_k/∂q_j, so a tension F_k ≥ 0 produces the
    /// generalized force r_jk F_k.
    pub moment_arms: DMatrix<f64>,
    /// One scratch per rayon worker for [`compute_paths_parallel`]; the first serves
    /// [`compute_paths`].
    scratch: Vec<Scratch>,
}

impl PathData {
    pub fn new(model: &Model, set: &PathSet) -> PathData {
        PathData {
            length: vec![0.0; set.len()],
            speed: vec![0.0; set.len()],
            moment_arms: DMatrix::zeros(model.nq(), set.len()),
            scratch: (0..rayon::current_num_threads().max(1))
                .map(|_| Scratch::new(model, set))
                .collect(),
        }
    }
}

/// Lengths and moment arms of every path at the state of `data` (position stage at least);
/// with the velocity stage also the lengthening speeds ℓ̇ = −rᵀq̇. Allocates nothing.
pub fn compute_paths(
    model: &Model,
    data: &Data,
    set: &PathSet,
    out: &mut PathData,
) -> crate::Result<()> {
    check(model, data, set, out)?;
    let n = model.nq().max(1);
    let PathData {
        length,
        speed,
        moment_arms,
        scratch,
    } = out;
    let columns = moment_arms.as_mut_slice().chunks_mut(n);
    for (k, ((r, l), v)) in columns
        .zip(length.iter_mut())
        .zip(speed.iter_mut())
        .enumerate()
    {
        (*l, *v) = compute_path(model, data, &set.paths[k], &mut scratch[0], r);
    }
    Ok(())
}

/// [`compute_paths`] with the paths split over rayon's worker threads (each path is
/// independent of the others).
pub fn compute_paths_parallel(
    model: &Model,
    data: &Data,
    set: &PathSet,
    out: &mut PathData,
) -> crate::Result<()> {
    use rayon::prelude::*;
    check(model, data, set, out)?;
    if set.is_empty() {
        return Ok(());
    }
    let n = model.nq().max(1);
    let per = set.len().div_ceil(out.scratch.len()).max(1);
    let PathData {
        length,
        speed,
        moment_arms,
        scratch,
    } = out;
    moment_arms
        .as_mut_slice()
        .par_chunks_mut(n * per)
        .zip(length.par_chunks_mut(per))
        .zip(speed.par_chunks_mut(per))
        .zip(scratch.par_iter_mut())
        .enumerate()
        .for_each(|(w, (((r, l), v), sc))| {
            for (i, ((ri, li), vi)) in r
                .chunks_mut(n)
                .zip(l.iter_mut())
                .zip(v.iter_mut())
                .enumerate()
            {
                (*li, *vi) = compute_path(model, data, &set.paths[w * per + i], sc, ri);
            }
        });
    Ok(())
}

fn check(model: &Model, data: &Data, set: &PathSet, out: &PathData) -> crate::Result<()> {
    data.require(model, Stage::Position, "compute_paths")?;
    if out.moment_arms.shape() != (model.nq(), set.len()) {
        return Err(Error::invalid(
            "out",
            "PathData was built for another model or path set",
        ));
    }
    Ok(())
}

/// Location of point `p` in its body at the current coordinates, and whether it is active.
fn point_location(model: &Model, data: &Data, p: &PointDef) -> (Vec3, bool) {
    let c = data.coordinate_values(model);
    match &p.kind {
        PointKind::Fixed => (p.location, true),
        PointKind::Conditional { coordinate, range } => {
            let v = c[*coordinate];
            (p.location, v >= range[0] - 1e-5 && v <= range[1] + 1e-5)
        }
        PointKind::Moving { frame, axes } => {
            let mut local = Vec3::zeros();
            for (i, (f, ci)) in axes.iter().enumerate() {
                let [lo, hi] = model.coordinates[*ci].range;
                local[i] = f.eval1(c[*ci].clamp(lo, hi)).0;
            }
            (frame.apply_point(&local), true)
        }
    }
}

/// ℓ and ℓ̇ of one path, and its moment arms into `r` (length n).
fn compute_path(
    model: &Model,
    data: &Data,
    path: &PathGeometry,
    scratch: &mut Scratch,
    r: &mut [f64],
) -> (f64, f64) {
    let nodes = &mut scratch.nodes;
    nodes.clear();
    for (i, p) in path.points.iter().enumerate() {
        let (local, active) = point_location(model, data, p);
        if active {
            nodes.push(Node {
                kind: NodeKind::Point(i),
                body: p.body,
                ground: data.point_position(p.body, &local),
                surface: 0.0,
            });
        }
    }
    if !path.wraps.is_empty() {
        apply_wrap_objects(model, data, path, nodes);
    }
    let length = path_length(nodes);
    moment_arms(
        model,
        data,
        path,
        nodes,
        &mut scratch.body_force,
        &mut scratch.touched,
        r,
    );
    let speed = if data.stage() >= Stage::Velocity {
        -(0..model.nq())
            .map(|j| r[j] * data.independent_speed(model, j))
            .sum::<f64>()
    } else {
        0.0
    };
    (length, speed)
}

/// ℓ = Σ straight segments + the surface length between the two tangent points of a wrap.
fn path_length(nodes: &[Node]) -> f64 {
    let mut l = 0.0;
    for w in nodes.windows(2) {
        l += match (w[0].kind, w[1].kind) {
            (NodeKind::Tangent(a, false), NodeKind::Tangent(b, true)) if a == b => w[1].surface,
            _ => (w[1].ground - w[0].ground).norm(),
        };
    }
    l
}

/// r = −∂ℓ/∂q = Σ_nodes J_kᵀ (û_k − û_{k−1}), with û_k the unit vector of the straight
/// segment leaving node k (zero across a surface arc).
fn moment_arms(
    model: &Model,
    data: &Data,
    path: &PathGeometry,
    nodes: &[Node],
    body_force: &mut [Force],
    touched: &mut Vec<usize>,
    r: &mut [f64],
) {
    r.fill(0.0);
    let o = data.reference_point();
    let unit = |a: &Node, b: &Node| -> Vec3 {
        if let (NodeKind::Tangent(x, false), NodeKind::Tangent(y, true)) = (a.kind, b.kind) {
            if x == y {
                return Vec3::zeros();
            }
        }
        let d = b.ground - a.ground;
        let n = d.norm();
        if n > 0.0 { d / n } else { Vec3::zeros() }
    };
    let cols = &model.reduction.columns;
    for (i, node) in nodes.iter().enumerate() {
        let before = if i > 0 {
            unit(&nodes[i - 1], node)
        } else {
            Vec3::zeros()
        };
        let after = if i + 1 < nodes.len() {
            unit(node, &nodes[i + 1])
        } else {
            Vec3::zeros()
        };
        // The path tension pulls node k along û_k and back along û_{k−1}.
        let f = after - before;
        if f == Vec3::zeros() {
            continue;
        }
        if node.body != 0 {
            if body_force[node.body] == Force::ZERO {
                touched.push(node.body);
            }
            body_force[node.body].add_assign(&Force {
                ang: (node.ground - o).cross(&f),
                lin: f,
            });
        }
        // A moving point's own motion in its body: v += R (∂p/∂c) ċ.
        if let NodeKind::Point(pi) = node.kind {
            if let PointKind::Moving { frame, axes } = &path.points[pi].kind {
                let rot = data.body_pose(node.body).0 * frame.rot;
                let c = data.coordinate_values(model);
                for (a, (func, ci)) in axes.iter().enumerate() {
                    let [lo, hi] = model.coordinates[*ci].range;
                    if c[*ci] < lo || c[*ci] > hi {
                        continue; // clamped: the location does not move
                    }
                    let slope = func.eval1(c[*ci]).1;
                    let dir = rot.column(a) * slope;
                    let g = f.dot(&dir);
                    for (j, dcdq) in data.coordinate_gradient(model, *ci) {
                        r[j] += g * dcdq;
                    }
                }
            }
        }
    }
    // Project each body's force on the reduced columns from the body to ground.
    for &b in touched.iter() {
        let f = body_force[b];
        let mut c = cols.body_last[b];
        while c != NONE {
            r[cols.q[c]] += data.column_motion(c).dot(&f);
            c = cols.parent[c];
        }
        body_force[b] = Force::ZERO;
    }
    touched.clear();
}

/// The outcome of wrapping one segment over one wrap object.
enum SegmentWrap {
    /// The segment stays straight.
    None,
    /// A path point lies inside the object (OpenSim's insideRadius).
    Inside,
    /// Wrapped: tangent points in the wrap body's frame and in ground, surface length, and
    /// whether the straight segment intersected the object (a mandatory wrap).
    Wrapped {
        t1: Vec3,
        t2: Vec3,
        surface: f64,
        mandatory: bool,
    },
}

/// Wraps the segment a → b over the path's wrap `w`, in the wrap object's frame.
fn wrap_segment(model: &Model, data: &Data, w: &WrapDef, a: &Vec3, b: &Vec3) -> SegmentWrap {
    use super::wrap::{self, WrapOutcome};
    let obj = &model.wrap_objects[w.object];
    let (rot, pos) = data.body_pose(obj.body);
    // X_GW = X_GB · X_BW
    let x_bw = &obj.pose_in_body;
    let r_gw = rot * x_bw.rot;
    let p_gw = rot * x_bw.pos + pos;
    let to_wrap = |x: &Vec3| r_gw.transpose() * (x - p_gw);
    let (p, s) = (to_wrap(a), to_wrap(b));
    let outcome = match obj.shape {
        WrapShape::Sphere { radius } => wrap::wrap_sphere(radius, w.quadrant, &p, &s),
        WrapShape::Cylinder { radius, length } => {
            wrap::wrap_cylinder(radius, length, w.quadrant, &p, &s)
        }
        WrapShape::Ellipsoid { dimensions } => {
            wrap::wrap_ellipsoid(&dimensions, w.quadrant, w.method, &p, &s)
        }
        WrapShape::Torus {
            inner_radius,
            outer_radius,
        } => wrap::wrap_torus(inner_radius, outer_radius, w.quadrant, &p, &s),
    };
    match outcome {
        WrapOutcome::NoWrap => SegmentWrap::None,
        WrapOutcome::InsideRadius => SegmentWrap::Inside,
        WrapOutcome::Wrapped(wr) => SegmentWrap::Wrapped {
            t1: r_gw * wr.t1 + p_gw,
            t2: r_gw * wr.t2 + p_gw,
            surface: wr.surface_length,
            mandatory: wr.mandatory,
        },
    }
}

/// OpenSim's wrapping of a path (GeometryPath::applyWrapObjects): for each wrap object in
/// order, remove its previous tangent points, then try every segment of the current path
/// between the first and last active points of its range (except a segment joining two
/// tangent points of the same object): the first segment whose straight line intersects the
/// object must wrap; otherwise the wrap that lengthens its segment least is taken. With two or
/// more wrap objects the sweep repeats (at most 8 times) until the length changes by less
/// than 0.5 mm; after the first sweep, if the first object did not wrap and the second found
/// a point inside itself, the two are swapped.
fn apply_wrap_objects(model: &Model, data: &Data, path: &PathGeometry, nodes: &mut Vec<Node>) {
    let nw = path.wraps.len();
    let iterations = if nw < 2 { 1 } else { 8 };
    let mut order = [0usize; 2];
    order[0] = 0;
    order[1] = 1.min(nw - 1);
    let mut last_length = f64::INFINITY;
    let mut first_results = [0u8; 2]; // 0 no wrap, 1 inside, 2 wrapped
    for iteration in 0..iterations {
        for oi in 0..nw {
            let wi = if oi < 2 { order[oi] } else { oi };
            let w = &path.wraps[wi];
            // Remove this object's tangent points.
            if let Some(pos) = nodes
                .iter()
                .position(|n| n.kind == NodeKind::Tangent(wi, false))
            {
                nodes.remove(pos);
                nodes.remove(pos);
            }
            let mut result = 0u8;
            if model.wrap_objects[w.object].active {
                // First and last active points of the range, found in the current path.
                let active = |i: usize| nodes.iter().position(|n| n.kind == NodeKind::Point(i));
                let Some(start) = (w.start..=w.end).find_map(active) else {
                    continue;
                };
                let Some(end) = (w.start..=w.end).rev().find_map(active) else {
                    continue;
                };
                let mut best: Option<(usize, SegmentWrap)> = None;
                let mut min_change = f64::INFINITY;
                for a in start..end {
                    let (na, nb) = (nodes[a], nodes[a + 1]);
                    if let (NodeKind::Tangent(x, _), NodeKind::Tangent(y, _)) = (na.kind, nb.kind) {
                        if x == y {
                            continue;
                        }
                    }
                    match wrap_segment(model, data, w, &na.ground, &nb.ground) {
                        SegmentWrap::None => {}
                        SegmentWrap::Inside => result = result.max(1),
                        wrapped @ SegmentWrap::Wrapped {
                            mandatory: true, ..
                        } => {
                            result = 2;
                            best = Some((a, wrapped));
                            break;
                        }
                        SegmentWrap::Wrapped {
                            t1,
                            t2,
                            surface,
                            mandatory,
                        } => {
                            result = 2;
                            let change =
                                (t1 - na.ground).norm() + surface + (nb.ground - t2).norm()
                                    - (nb.ground - na.ground).norm();
                            if change < min_change {
                                min_change = change;
                                best = Some((
                                    a,
                                    SegmentWrap::Wrapped {
                                        t1,
                                        t2,
                                        surface,
                                        mandatory,
                                    },
                                ));
                            }
                        }
                    }
                }
                if let Some((
                    a,
                    SegmentWrap::Wrapped {
                        t1, t2, surface, ..
                    },
                )) = best
                {
                    let body = model.wrap_objects[w.object].body;
                    nodes.insert(
                        a + 1,
                        Node {
                            kind: NodeKind::Tangent(wi, false),
                            body,
                            ground: t1,
                            surface: 0.0,
                        },
                    );
                    nodes.insert(
                        a + 2,
                        Node {
                            kind: NodeKind::Tangent(wi, true),
                            body,
                            ground: t2,
                            surface,
                        },
                    );
                }
            }
            if iteration == 0 && oi < 2 {
                first_results[oi] = result;
            }
        }
        if nw < 2 {
            break;
        }
        let length = path_length(nodes);
        if (length - last_length).abs() < 0.0005 {
            break;
        }
        last_length = length;
        if iteration == 0 && first_results[0] == 0 && first_results[1] == 1 {
            order = [1, 0];
            if let Some(pos) = nodes
                .iter()
                .position(|n| n.kind == NodeKind::Tangent(0, false))
            {
                nodes.remove(pos);
                nodes.remove(pos);
            }
        }
    }
}
