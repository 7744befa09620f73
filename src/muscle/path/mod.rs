//! Geometry paths: musculotendon length ℓ(q), lengthening speed ℓ̇ and moment arms
//! r_jk = −∂ℓ_k/∂q_j for every path of a model, as OpenSim's GeometryPath defines them.
//!
//! A path is its active points in order — fixed points, conditional points whose coordinate
//! lies in their range (±1e-5, OpenSim's tolerance), moving points whose location is a
//! function of a coordinate (clamped to the coordinate's range, as OpenSim does) — with the
//! tangent points of its wrap objects inserted by OpenSim's algorithm (see
//! `wrapping::apply_wrap_objects`). Its length is the sum of the straight segments plus the
//! surface lengths between each wrap object's two tangent points.
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
use crate::model::{Function, Model, PathPointKind};
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
    /// Some path has two or more wraps, one of them not a shortest path (ellipsoid, torus).
    needs_chain: bool,
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
                    file: f.file_or(&model.source).to_string(),
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
        let needs_chain = paths
            .iter()
            .any(|p| p.wraps.len() >= 2 && p.wraps.iter().any(|w| !geodesic(model, w)));
        Ok(PathSet {
            paths,
            max_nodes,
            needs_chain,
        })
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
    /// On a first tangent point: ∂L/∂P, on a second: ∂L/∂S, in ground axes, where
    /// L = |P − T1| + arc + |T2 − S| is the wrap's length between the path points P and S
    /// around it (the wrap frame held fixed).
    grad: Vec3,
    /// Net unit tension on the node (moment-arm computation).
    pull: Vec3,
}

/// Per-worker scratch: the nodes of the current path and the forces it puts on bodies.
#[derive(Clone, Debug)]
struct Scratch {
    nodes: Vec<Node>,
    body_force: Vec<Force>,
    touched: Vec<usize>,
    /// Node derivatives for paths with interacting wraps (see [`chain`]).
    chain: chain::ChainScratch,
    /// The wrap outcomes of the path being computed.
    wraps: WrapCache,
}

impl Scratch {
    fn new(model: &Model, set: &PathSet) -> Scratch {
        Scratch {
            nodes: Vec::with_capacity(set.max_nodes.max(2)),
            body_force: vec![Force::ZERO; model.bodies.len()],
            touched: Vec::with_capacity(model.bodies.len()),
            chain: chain::ChainScratch::new(
                if set.needs_chain { set.max_nodes } else { 0 },
                model.nq(),
            ),
            wraps: WrapCache::new(),
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

/// One point of a path as it is wrapped at the current state (OpenSim's `getCurrentPath`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathPoint {
    /// The path point with this 0-based index in the path's definition.
    Point(usize),
    /// The first (`second == false`) or second tangent point of the path's wrap with this
    /// 0-based index in its wrap set.
    Tangent { wrap: usize, second: bool },
}

/// The points of path `k` at the state of `data` (position stage at least), in order, with
/// their locations in ground; the tangent points of each engaged wrap follow OpenSim's
/// algorithm as in [`compute_paths`]. For inspection and plotting: it allocates.
pub fn current_path(
    model: &Model,
    data: &Data,
    set: &PathSet,
    k: usize,
) -> crate::Result<Vec<(PathPoint, Vec3)>> {
    data.require(model, Stage::Position, "current_path")?;
    let path = set
        .paths
        .get(k)
        .ok_or_else(|| Error::invalid("k", format!("no path {k} (the set has {})", set.len())))?;
    let mut nodes = Vec::with_capacity(set.max_nodes.max(2));
    active_points(model, data, path, &mut nodes);
    if !path.wraps.is_empty() {
        apply_wrap_objects(model, data, path, &mut nodes, &mut WrapCache::new());
    }
    Ok(nodes
        .iter()
        .map(|n| {
            let p = match n.kind {
                NodeKind::Point(i) => PathPoint::Point(i),
                NodeKind::Tangent(wrap, second) => PathPoint::Tangent { wrap, second },
            };
            (p, n.ground)
        })
        .collect())
}

/// The path's active points, in order, as nodes in ground.
fn active_points(model: &Model, data: &Data, path: &PathGeometry, nodes: &mut Vec<Node>) {
    nodes.clear();
    for (i, p) in path.points.iter().enumerate() {
        let (local, active) = point_location(model, data, p);
        if active {
            nodes.push(Node {
                kind: NodeKind::Point(i),
                body: p.body,
                ground: data.point_position(p.body, &local),
                surface: 0.0,
                grad: Vec3::zeros(),
                pull: Vec3::zeros(),
            });
        }
    }
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
    active_points(model, data, path, nodes);
    if !path.wraps.is_empty() {
        apply_wrap_objects(model, data, path, nodes, &mut scratch.wraps);
    }
    let length = path_length(nodes);
    if interacting_non_geodesic_wraps(model, path, nodes) {
        chain::moment_arms(
            model,
            data,
            path,
            nodes,
            &mut scratch.wraps,
            &mut scratch.chain,
            r,
        );
    } else {
        moment_arms(
            model,
            data,
            path,
            nodes,
            &mut scratch.body_force,
            &mut scratch.touched,
            r,
        );
    }
    let speed = if data.stage() >= Stage::Velocity {
        -(0..model.nq())
            .map(|j| r[j] * data.independent_speed(model, j))
            .sum::<f64>()
    } else {
        0.0
    };
    (length, speed)
}

/// True for wrap objects whose path is a shortest path over the surface (sphere, cylinder).
fn geodesic(model: &Model, w: &WrapDef) -> bool {
    matches!(
        model.wrap_objects[w.object].shape,
        crate::model::WrapShape::Sphere { .. } | crate::model::WrapShape::Cylinder { .. }
    )
}

/// Two or more wraps engaged on the current path, one of them not a shortest path: the
/// tangent points are then not stationary and [`chain`] differentiates the path exactly.
fn interacting_non_geodesic_wraps(model: &Model, path: &PathGeometry, nodes: &[Node]) -> bool {
    let mut engaged = 0;
    let mut non_geodesic = false;
    for n in nodes {
        if let NodeKind::Tangent(w, false) = n.kind {
            engaged += 1;
            non_geodesic |= !geodesic(model, &path.wraps[w]);
        }
    }
    engaged >= 2 && non_geodesic
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
    nodes: &mut [Node],
    body_force: &mut [Force],
    touched: &mut Vec<usize>,
    r: &mut [f64],
) {
    r.fill(0.0);
    let o = data.reference_point();
    // Whether ground takes some of the forces: then ground is the common ancestor.
    let mut grounded = false;
    let mut push = |body: usize, at: &Vec3, f: &Vec3| {
        if body == 0 {
            grounded |= *f != Vec3::zeros();
        } else {
            if body_force[body] == Force::ZERO {
                touched.push(body);
            }
            body_force[body].add_assign(&Force {
                ang: (at - o).cross(f),
                lin: *f,
            });
        }
    };
    // A wrap whose neighbours are both path points uses its exact gradients ∂L/∂P, ∂L/∂S;
    // a wrap next to another wrap's tangent point falls back to holding its tangent points
    // fixed on the wrap body (exact for shortest paths, OpenSim's own moment-arm rule).
    let exact = |i: usize, nodes: &[Node]| -> bool {
        // i: index of a first tangent point
        i >= 1
            && i + 2 < nodes.len()
            && matches!(nodes[i - 1].kind, NodeKind::Point(_))
            && matches!(nodes[i + 2].kind, NodeKind::Point(_))
    };
    for n in nodes.iter_mut() {
        n.pull = Vec3::zeros();
    }
    for i in 0..nodes.len().saturating_sub(1) {
        let (a, b) = (nodes[i], nodes[i + 1]);
        match (a.kind, b.kind) {
            (NodeKind::Tangent(x, false), NodeKind::Tangent(y, true)) if x == y => {} // surface arc
            (_, NodeKind::Tangent(_, false)) if exact(i + 1, nodes) => {
                // dL = g_Pᵀ (v_P − v_W(P)): −g_P pulls P; +g_P on the wrap body at P.
                nodes[i].pull -= b.grad;
                push(b.body, &a.ground, &b.grad);
            }
            (NodeKind::Tangent(_, true), _) if exact(i - 1, nodes) => {
                nodes[i + 1].pull -= a.grad;
                push(a.body, &b.ground, &a.grad);
            }
            _ => {
                // The tension pulls each end of a straight segment towards the other.
                let d = b.ground - a.ground;
                let len = d.norm();
                if len > 0.0 {
                    let u = d / len;
                    nodes[i].pull += u;
                    nodes[i + 1].pull -= u;
                }
            }
        }
    }
    for node in nodes.iter() {
        let f = node.pull;
        if f == Vec3::zeros() {
            continue;
        }
        push(node.body, &node.ground, &f);
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
    let cols = &model.reduction.columns;
    // Project each body's force on the reduced columns from the body towards ground. The
    // path's forces are pairs of equal and opposite forces on common lines, so their sum and
    // moment vanish: the columns of the lowest common ancestor of the bodies they act on
    // (ground among them, when a point or wrap surface sits on ground) and of its ancestors
    // receive nothing, and the walk stops there.
    let stop = if grounded {
        None
    } else {
        lowest_common_ancestor(model, touched)
    };
    for &b in touched.iter() {
        let f = body_force[b];
        let mut c = cols.body_last[b];
        while c != NONE && Some(cols.body[c]) != stop {
            r[cols.q[c]] += data.column_motion(c).dot(&f);
            c = cols.parent[c];
        }
        body_force[b] = Force::ZERO;
    }
    touched.clear();
}

/// The deepest body that is an ancestor of (or equal to) every body in `bodies`, or None
/// when only ground is (bodies in separate trees).
fn lowest_common_ancestor(model: &Model, bodies: &[usize]) -> Option<usize> {
    let depth = |mut b: usize| {
        let mut d = 0;
        while let Some(p) = model.bodies[b].parent {
            b = p;
            d += 1;
        }
        d
    };
    let mut iter = bodies.iter();
    let mut a = *iter.next()?;
    for &b0 in iter {
        let (mut x, mut y) = (a, b0);
        let (mut dx, mut dy) = (depth(x), depth(y));
        while dx > dy {
            x = model.bodies[x].parent.unwrap_or(0);
            dx -= 1;
        }
        while dy > dx {
            y = model.bodies[y].parent.unwrap_or(0);
            dy -= 1;
        }
        while x != y {
            x = model.bodies[x].parent.unwrap_or(0);
            y = model.bodies[y].parent.unwrap_or(0);
        }
        a = x;
    }
    (a != 0).then_some(a)
}

mod chain;
mod rates;
mod wrapping;
pub use rates::MomentArmRates;
use wrapping::{WrapCache, apply_wrap_objects};
