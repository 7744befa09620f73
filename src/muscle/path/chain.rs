//! Exact moment arms of a path on which several wrap objects are engaged and one of them is
//! not a shortest path (OpenSim's ellipsoid and torus constructions).
//!
//! There the tangent points are not stationary points of ℓ, so holding them fixed on their
//! wrap bodies (the rule that is exact for spheres, cylinders, and any single wrap between
//! two path points) no longer gives ∂ℓ/∂q. Instead every node's total derivative
//! D_k = ∂x_k/∂q (3 × n) is computed: path points from their bodies' motion (and a moving
//! point's own), tangent points from the wrap that places them,
//!   T = T(A, B),  D_T = D_W(T) + (∂T/∂A)(D_A − D_W(A)) + (∂T/∂B)(D_B − D_W(B)),
//! where A, B are the wrap's neighbours and D_W(x) the motion of the wrap body's point at x.
//! Neighbouring wraps depend on each other, so these equations are iterated to their fixed
//! point (as the wrapped path itself is). Then, with L_w(A, B) each wrap's length between its
//! neighbours and the straight segment between two wraps counted in both,
//!   ∂ℓ/∂q = Σ_w [g_Aᵀ (D_A − D_W(A)) + g_Bᵀ (D_B − D_W(B))]
//!         + Σ_{point–point segments} ûᵀ (D_b − D_a) − Σ_{wrap–wrap segments} ûᵀ (D_b − D_a).

use super::wrapping::{SegmentWrap, WrapCache};
use super::{Node, NodeKind, PathGeometry, PointKind};
use crate::dynamics::Data;
use crate::model::Model;
use crate::model::reduction::NONE;
use crate::spatial::{Mat3, Vec3};

/// Iterations of the tangent-point sensitivities.
const MAX_ITERATIONS: usize = 200;
/// Wraps engaged at once on one path that this module differentiates (more would need a
/// path with more than 16 wrap objects in contact).
const MAX_WRAPS: usize = 16;

/// Fills `out` (n columns of 3) with the motion ∂x/∂q of the point of `body` at `x` (ground).
pub(super) fn body_point_derivative(
    model: &Model,
    data: &Data,
    body: usize,
    x: &Vec3,
    out: &mut [Vec3],
) {
    out.fill(Vec3::zeros());
    let cols = &model.reduction.columns;
    let off = x - data.reference_point();
    let mut c = cols.body_last[body];
    while c != NONE {
        out[cols.q[c]] += data.column_motion(c).linear_at(&off);
        c = cols.parent[c];
    }
}

/// The memory of [`moment_arms`]: the node derivatives (4 vectors per node and coordinate)
/// and the list of coordinates that move the path.
#[derive(Clone, Debug)]
pub(super) struct ChainScratch {
    deriv: Vec<Vec3>,
    active: Vec<usize>,
}

impl ChainScratch {
    /// For paths of up to `nodes` nodes on n coordinates; empty (`nodes` = 0) for a path set
    /// that never needs it.
    pub(super) fn new(nodes: usize, n: usize) -> ChainScratch {
        ChainScratch {
            deriv: vec![Vec3::zeros(); 4 * nodes * n],
            active: Vec::with_capacity(if nodes > 0 { n } else { 0 }),
        }
    }
}

/// r = −∂ℓ/∂q for a path with interacting wraps (`wraps`: the outcomes of its wrapping,
/// see [`WrapCache`]; `scratch` made for at least `nodes.len()` nodes).
pub(super) fn moment_arms(
    model: &Model,
    data: &Data,
    path: &PathGeometry,
    nodes: &[Node],
    wraps: &mut WrapCache,
    scratch: &mut ChainScratch,
    r: &mut [f64],
) {
    let ChainScratch { deriv, active } = scratch;
    let n = model.nq();
    let m = nodes.len();
    // d: D of every node; fixed: the node's motion fixed in its body (for a tangent point,
    // D_W(T)); wa, wb: for a wrap whose first tangent point is node k, D_W at its
    // neighbours A = k − 1 and B = k + 2 (slot k).
    let (d, rest) = deriv.split_at_mut(m * n);
    let (fixed, rest) = rest.split_at_mut(m * n);
    let (wa, rest) = rest.split_at_mut(m * n);
    let wb = &mut rest[..m * n];
    let col = |k: usize| k * n..(k + 1) * n;

    for (k, node) in nodes.iter().enumerate() {
        body_point_derivative(model, data, node.body, &node.ground, &mut fixed[col(k)]);
        d[col(k)].copy_from_slice(&fixed[col(k)]);
        // A moving point also moves in its body: R (∂p/∂c) ∂c/∂q.
        if let NodeKind::Point(pi) = node.kind {
            if let PointKind::Moving { frame, axes } = &path.points[pi].kind {
                let rot = data.body_pose(node.body).0 * frame.rot;
                let c = data.coordinate_values(model);
                for (a, (func, ci)) in axes.iter().enumerate() {
                    let [lo, hi] = model.coordinates[*ci].range;
                    if c[*ci] < lo || c[*ci] > hi {
                        continue; // clamped: the location does not move
                    }
                    let dir = rot.column(a) * func.eval1(c[*ci]).1;
                    for (j, dcdq) in data.coordinate_gradient(model, *ci) {
                        d[k * n + j] += dir * dcdq;
                    }
                }
            }
        }
        if let NodeKind::Tangent(_, false) = node.kind {
            body_point_derivative(
                model,
                data,
                node.body,
                &nodes[k - 1].ground,
                &mut wa[col(k)],
            );
            body_point_derivative(
                model,
                data,
                node.body,
                &nodes[k + 2].ground,
                &mut wb[col(k)],
            );
        }
    }
    // Each engaged wrap's contact-point sensitivities ∂T/∂A, ∂T/∂B at the final path (the
    // wrap evaluated once more between its final neighbours).
    let mut jacobians = [[Mat3::zeros(); 4]; MAX_WRAPS];
    let mut engaged = 0;
    for k in 0..m {
        if let NodeKind::Tangent(w, false) = nodes[k].kind {
            if engaged < MAX_WRAPS {
                if let SegmentWrap::Wrapped { jac, .. } = *wraps.wrap(
                    model,
                    data,
                    path,
                    w,
                    &nodes[k - 1].ground,
                    &nodes[k + 2].ground,
                ) {
                    jacobians[engaged] = jac;
                }
            }
            engaged += 1;
        }
    }
    // The coordinates that move some node or wrap body: in the others every D stays zero.
    active.clear();
    let moves = |v: &[Vec3], j: usize| (0..m).any(|k| v[k * n + j] != Vec3::zeros());
    active.extend((0..n).filter(|&j| moves(d, j) || moves(wa, j) || moves(wb, j)));
    // The tangent points' sensitivities, iterated to their fixed point.
    let scale = d.iter().fold(1.0f64, |s, v| s.max(v.amax()));
    for _ in 0..MAX_ITERATIONS {
        let mut change = 0.0f64;
        let mut wrap = 0;
        for k in 0..m {
            let NodeKind::Tangent(_, false) = nodes[k].kind else {
                continue;
            };
            let jac = jacobians[wrap.min(MAX_WRAPS - 1)];
            wrap += 1;
            let (a, b) = (k - 1, k + 2);
            for (t, jp, js) in [(k, jac[0], jac[1]), (k + 1, jac[2], jac[3])] {
                for &j in active.iter() {
                    let da = d[a * n + j] - wa[k * n + j];
                    let db = d[b * n + j] - wb[k * n + j];
                    let new = fixed[t * n + j] + jp * da + js * db;
                    let step = new - d[t * n + j];
                    // the largest |step| component (NaN ignored, as f64::max does)
                    for x in [step.x.abs(), step.y.abs(), step.z.abs()] {
                        if x > change {
                            change = x;
                        }
                    }
                    d[t * n + j] = new;
                }
            }
        }
        if change <= 1e-15 * scale {
            break;
        }
    }
    // r = −∂ℓ/∂q.
    r.fill(0.0);
    for k in 0..m {
        if let NodeKind::Tangent(_, false) = nodes[k].kind {
            let (a, b) = (k - 1, k + 2);
            let (ga, gb) = (nodes[k].grad, nodes[k + 1].grad);
            for &j in active.iter() {
                r[j] -= ga.dot(&(d[a * n + j] - wa[k * n + j]))
                    + gb.dot(&(d[b * n + j] - wb[k * n + j]));
            }
        }
    }
    for k in 0..m.saturating_sub(1) {
        let Some(sign) = segment_sign(nodes[k].kind, nodes[k + 1].kind) else {
            continue;
        };
        let u = nodes[k + 1].ground - nodes[k].ground;
        let len = u.norm();
        if len == 0.0 {
            continue;
        }
        let u = u / len;
        for &j in active.iter() {
            r[j] -= sign * u.dot(&(d[(k + 1) * n + j] - d[k * n + j]));
        }
    }
}

/// How a straight segment between two nodes counts in ∂ℓ/∂q when each wrap's length is taken
/// between its neighbours: +1 between two path points, −1 between two wraps (it is counted in
/// both wraps' lengths), none next to a wrap (part of that wrap's own length).
pub(super) fn segment_sign(a: NodeKind, b: NodeKind) -> Option<f64> {
    match (a, b) {
        (NodeKind::Point(_), NodeKind::Point(_)) => Some(1.0),
        (NodeKind::Tangent(x, true), NodeKind::Tangent(y, false)) if x != y => Some(-1.0),
        _ => None,
    }
}
