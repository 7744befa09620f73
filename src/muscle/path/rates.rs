//! Rates of the moment arms along a motion: ṙ_k = d/dt r_k(q) at velocity q̇, exactly, for
//! any path (wraps of every shape, interacting wraps, moving and conditional points).
//! Because r_k = −∇ℓ_k, ṙ_k = −∇²ℓ_k q̇: the Hessian of the path length times q̇, which is
//! what the q-gradient of a loss on R(q)·F needs: ∂(uᵀR(q)f)/∂q = Σ_k f_k ṙ_k(q, q̇ = u).
//!
//! With D_k = ∂x_k/∂q (3 × n) the total derivative of node k and, for every engaged wrap,
//! A, B its neighbours, W its body, J_W(x) the Jacobian of W's point at x, g_A, g_B the
//! gradients of its length L(A, B) (wrap frame fixed) and G_TA = ∂T/∂A, G_TB = ∂T/∂B of its
//! tangent points T (all in ground axes), the path's gradient is (as in [`super::chain`])
//!
//! ```text
//! ∇ℓ = Σ_wraps [g_Aᵀ(D_A − J_W(A)) + g_Bᵀ(D_B − J_W(B))]
//!    + Σ_{point–point segments} ûᵀ(D_b − D_a) − Σ_{wrap–wrap segments} ûᵀ(D_b − D_a),
//! D_T = J_W(T) + G_TA (D_A − J_W(A)) + G_TB (D_B − J_W(B)),
//! D_p = J_b(p) + R_b F (∂p/∂c) ∂c/∂q          (a moving point; fixed points: J_b(p)),
//! ```
//!
//! and every factor is differentiated along q̇ (ẋ_k = D_k q̇):
//!
//! ```text
//! d/dt J_b(x)   = JacobianTimeVariation::point_jacobian_rate(b, x, ẋ)   (x may slide on b)
//! ġ_A           = ω_W × g_A + R_W (H δ)_A,     δ = (R_Wᵀ(ẋ_A − J_W(A) q̇), R_Wᵀ(ẋ_B − J_W(B) q̇))
//! Ġ_TA          = [ω_W]× G_TA − G_TA [ω_W]× + R_W (d/dt ∂T/∂A)_local R_Wᵀ
//! u̇             = (I − ûûᵀ)(ẋ_b − ẋ_a)/|x_b − x_a|
//! d/dt (R_b F e_i f′(c) ∂c/∂q) = ω_b × (R_b F e_i) f′ ∂c/∂q + R_b F e_i (f″ ċ ∂c/∂q + f′ (∂c/∂q)˙)
//! ```
//!
//! where H δ and the rates of ∂T/∂(A, B) come from [`crate::muscle::wrap::WrapSurface::second_order`].
//! The tangent points' D and Ḋ are iterated to their fixed point, as the path itself is.

use super::chain::{body_point_derivative, segment_sign};
use super::wrapping::{WrapCache, surface_of, wrap_frame};
use super::{Node, NodeKind, PathGeometry, PathSet, PointKind, active_points, apply_wrap_objects};
use crate::dynamics::{Data, JacobianTimeVariation, Stage};
use crate::error::Error;
use crate::model::Model;
use crate::spatial::{Mat3, Vec3};
use nalgebra::Matrix3x6;

/// Iterations of the tangent points' fixed points.
const MAX_ITERATIONS: usize = 200;

/// An engaged wrap at the final path: its first tangent node, the gradients and tangent
/// Jacobians at its final neighbours (ground axes) and their rates.
#[derive(Clone, Copy, Debug)]
struct Engaged {
    node: usize,
    /// The wrap's index in the path, its frame's rotation, the neighbours in its frame and
    /// the wrap there.
    wrap: usize,
    rot: Mat3,
    local: [Vec3; 2],
    wrapped: crate::muscle::wrap::Wrapped,
    grad: [Vec3; 2],
    grad_rate: [Vec3; 2],
    /// ∂T1/∂A, ∂T1/∂B, ∂T2/∂A, ∂T2/∂B.
    jac: [Mat3; 4],
    jac_rate: [Mat3; 4],
}

/// Workspace of [`MomentArmRates::compute`] for one model and path set.
#[derive(Clone, Debug)]
pub struct MomentArmRates {
    jtv: JacobianTimeVariation,
    nodes: Vec<Node>,
    engaged: Vec<Engaged>,
    /// Per node, n columns each: D, Ḋ, J_body(x) and its rate; per first tangent node k,
    /// J_W at its neighbours and their rates.
    d: Vec<Vec3>,
    d_rate: Vec<Vec3>,
    fixed: Vec<Vec3>,
    fixed_rate: Vec<Vec3>,
    wa: Vec<Vec3>,
    wb: Vec<Vec3>,
    wa_rate: Vec<Vec3>,
    wb_rate: Vec<Vec3>,
    xdot: Vec<Vec3>,
    /// ṙ of the current path (n).
    rate: Vec<f64>,
}

impl MomentArmRates {
    /// Allocates the workspace for `model` and `set`.
    pub fn new(model: &Model, set: &PathSet) -> MomentArmRates {
        let (m, n) = (set.max_nodes.max(2), model.nq());
        MomentArmRates {
            jtv: JacobianTimeVariation::new(model),
            nodes: Vec::with_capacity(m),
            engaged: Vec::with_capacity(m / 2 + 1),
            d: vec![Vec3::zeros(); m * n],
            d_rate: vec![Vec3::zeros(); m * n],
            fixed: vec![Vec3::zeros(); m * n],
            fixed_rate: vec![Vec3::zeros(); m * n],
            wa: vec![Vec3::zeros(); m * n],
            wb: vec![Vec3::zeros(); m * n],
            wa_rate: vec![Vec3::zeros(); m * n],
            wb_rate: vec![Vec3::zeros(); m * n],
            xdot: vec![Vec3::zeros(); m],
            rate: vec![0.0; n],
        }
    }

    /// Σ_k f_k ṙ_k into `out` (n), with f = `weights` (one per path of `set`; paths with
    /// f_k = 0 are skipped), at the state (q, q̇) of `data` (velocity stage at least).
    /// Allocates nothing.
    pub fn compute(
        &mut self,
        model: &Model,
        data: &Data,
        set: &PathSet,
        weights: &[f64],
        out: &mut [f64],
    ) -> crate::Result<()> {
        data.require(model, Stage::Velocity, "MomentArmRates::compute")?;
        let n = model.nq();
        if weights.len() != set.len() {
            return Err(Error::invalid(
                "weights",
                format!("{} weights for {} paths", weights.len(), set.len()),
            ));
        }
        if out.len() != n || self.rate.len() != n {
            return Err(Error::invalid(
                "out",
                format!(
                    "needs {n} values, has {} (or workspace of another model)",
                    out.len()
                ),
            ));
        }
        self.jtv.compute(model, data)?;
        out.fill(0.0);
        for (k, &f) in weights.iter().enumerate() {
            if f == 0.0 {
                continue;
            }
            self.path(model, data, set, k)?;
            for (o, r) in out.iter_mut().zip(&self.rate) {
                *o += f * r;
            }
        }
        Ok(())
    }

    /// ṙ of path `k` into `self.rate`.
    ///
    /// Steps (module documentation): the path's nodes; first order (D of every node, the
    /// engaged wraps, D of the tangent points at their fixed point, ẋ); second order (the
    /// wraps' rates, Ḋ of the path points, Ḋ of the tangent points); ṙ = −d/dt ∇ℓ.
    fn path(&mut self, model: &Model, data: &Data, set: &PathSet, k: usize) -> crate::Result<()> {
        let n = model.nq();
        let path = &set.paths[k];
        active_points(model, data, path, &mut self.nodes);
        if !path.wraps.is_empty() {
            apply_wrap_objects(model, data, path, &mut self.nodes, &mut WrapCache::new());
        }
        let qd: Vec3Speeds = Vec3Speeds { data, model };

        // ---- first order ----
        self.point_derivatives(model, data, path);
        self.engage_wraps(model, data, path)?;
        self.tangent_derivatives(n);
        for i in 0..self.nodes.len() {
            self.xdot[i] = qd.apply(&self.d[col(i, n)]);
        }

        // ---- second order ----
        self.wrap_rates(model, data, path, &qd)?;
        self.point_derivative_rates(model, data, path)?;
        self.tangent_derivative_rates(n);

        // ---- ṙ = −d/dt ∇ℓ ----
        self.length_gradient_rate(n);
        Ok(())
    }

    /// First order at every node: J_body(x) into `fixed`, D = J_body(x) (+ the moving
    /// point's R_b F e_i f′(c) ∂c/∂q) into `d`, and J_W at the neighbours of every first
    /// tangent node into `wa`, `wb`.
    #[inline]
    fn point_derivatives(&mut self, model: &Model, data: &Data, path: &PathGeometry) {
        let n = model.nq();
        let c = data.coordinate_values(model);
        let nodes = &self.nodes;
        for (i, node) in nodes.iter().enumerate() {
            body_point_derivative(
                model,
                data,
                node.body,
                &node.ground,
                &mut self.fixed[col(i, n)],
            );
            self.d[col(i, n)].copy_from_slice(&self.fixed[col(i, n)]);
            if let NodeKind::Point(pi) = node.kind
                && let PointKind::Moving { frame, axes } = &path.points[pi].kind
            {
                let rot = data.body_pose(node.body).0 * frame.rot;
                for (a, (func, ci)) in axes.iter().enumerate() {
                    let [lo, hi] = model.coordinates[*ci].range;
                    if c[*ci] < lo || c[*ci] > hi {
                        continue; // clamped: the location does not move
                    }
                    let dir = rot.column(a) * func.eval1(c[*ci]).1;
                    for (j, dcdq) in data.coordinate_gradient(model, *ci) {
                        self.d[i * n + j] += dir * dcdq;
                    }
                }
            }
            if let NodeKind::Tangent(_, false) = node.kind {
                body_point_derivative(
                    model,
                    data,
                    node.body,
                    &nodes[i - 1].ground,
                    &mut self.wa[col(i, n)],
                );
                body_point_derivative(
                    model,
                    data,
                    node.body,
                    &nodes[i + 2].ground,
                    &mut self.wb[col(i, n)],
                );
            }
        }
    }

    /// Each engaged wrap between its final neighbours (wrap frame): its length gradients and
    /// tangent Jacobians in ground axes, into `engaged`.
    #[inline]
    fn engage_wraps(
        &mut self,
        model: &Model,
        data: &Data,
        path: &PathGeometry,
    ) -> crate::Result<()> {
        let nodes = &self.nodes;
        self.engaged.clear();
        for i in 0..nodes.len() {
            if let NodeKind::Tangent(w, false) = nodes[i].kind {
                let def = &path.wraps[w];
                let (rot, origin) = wrap_frame(model, data, def);
                let ya = rot.transpose() * (nodes[i - 1].ground - origin);
                let yb = rot.transpose() * (nodes[i + 2].ground - origin);
                let Some(wrapped) = surface_of(model, def)
                    .wrap(def.quadrant, &ya, &yb)
                    .wrapped()
                else {
                    return Err(not_rewrapped(model, path, w));
                };
                // G = R_W G_local R_Wᵀ
                let ground = |m: &Matrix3x6<f64>, c: usize| {
                    rot * m.fixed_columns::<3>(c).into_owned() * rot.transpose()
                };
                self.engaged.push(Engaged {
                    node: i,
                    wrap: w,
                    rot,
                    local: [ya, yb],
                    wrapped,
                    grad: [rot * wrapped.dlength_dp, rot * wrapped.dlength_ds],
                    grad_rate: [Vec3::zeros(); 2],
                    jac: [
                        ground(&wrapped.dt1, 0),
                        ground(&wrapped.dt1, 3),
                        ground(&wrapped.dt2, 0),
                        ground(&wrapped.dt2, 3),
                    ],
                    jac_rate: [Mat3::zeros(); 4],
                });
            }
        }
        Ok(())
    }

    /// D of the tangent points at their fixed point:
    /// D_T = J_W(T) + G_TA (D_A − J_W(A)) + G_TB (D_B − J_W(B)).
    #[inline]
    fn tangent_derivatives(&mut self, n: usize) {
        let (fixed, wa, wb) = (&self.fixed, &self.wa, &self.wb);
        iterate_tangents(n, &self.engaged, &mut self.d, |e, t, j, d| {
            let (a, b, k) = (e.node - 1, e.node + 2, e.node);
            let (ja, jb) = if t == k {
                (e.jac[0], e.jac[1])
            } else {
                (e.jac[2], e.jac[3])
            };
            fixed[t * n + j]
                + ja * (d[a * n + j] - wa[k * n + j])
                + jb * (d[b * n + j] - wb[k * n + j])
        });
    }

    /// Each engaged wrap's ġ_A, ġ_B = ω_W × g + R_W (H δ) and
    /// Ġ_T = [ω_W]× G_T − G_T [ω_W]× + R_W (d/dt ∂T)_local R_Wᵀ.
    #[inline]
    fn wrap_rates(
        &mut self,
        model: &Model,
        data: &Data,
        path: &PathGeometry,
        qd: &Vec3Speeds,
    ) -> crate::Result<()> {
        let n = model.nq();
        let nodes = &self.nodes;
        for e in self.engaged.iter_mut() {
            let (i, w, rot) = (e.node, e.wrap, e.rot);
            let def = &path.wraps[w];
            let omega = data.body_velocity(nodes[i].body).0;
            let (a, b) = (i - 1, i + 2);
            let va = qd.apply(&self.wa[col(i, n)]);
            let vb = qd.apply(&self.wb[col(i, n)]);
            // δ = (R_Wᵀ(ẋ_A − J_W(A) q̇), R_Wᵀ(ẋ_B − J_W(B) q̇))
            let da = rot.transpose() * (self.xdot[a] - va);
            let db = rot.transpose() * (self.xdot[b] - vb);
            let dir = [da.x, da.y, da.z, db.x, db.y, db.z];
            let [ya, yb] = e.local;
            let so = surface_of(model, def)
                .second_order_of(def.quadrant, &ya, &yb, &e.wrapped, &dir)
                .ok_or_else(|| not_rewrapped(model, path, w))?;
            let h = &so.hessian_dir;
            e.grad_rate = [
                omega.cross(&e.grad[0]) + rot * Vec3::new(h[0], h[1], h[2]),
                omega.cross(&e.grad[1]) + rot * Vec3::new(h[3], h[4], h[5]),
            ];
            let om = omega.cross_matrix();
            let local = [
                so.dt1_dir.fixed_columns::<3>(0).into_owned(),
                so.dt1_dir.fixed_columns::<3>(3).into_owned(),
                so.dt2_dir.fixed_columns::<3>(0).into_owned(),
                so.dt2_dir.fixed_columns::<3>(3).into_owned(),
            ];
            for (r, (g, l)) in e.jac_rate.iter_mut().zip(e.jac.iter().zip(local)) {
                *r = om * g - g * om + rot * l * rot.transpose();
            }
        }
        Ok(())
    }

    /// Rates of the body Jacobians at every node (the node moving with ẋ) into `fixed_rate`
    /// and of J_W at the wrap neighbours into `wa_rate`, `wb_rate`; Ḋ of the path points
    /// into `d_rate`.
    #[inline]
    fn point_derivative_rates(
        &mut self,
        model: &Model,
        data: &Data,
        path: &PathGeometry,
    ) -> crate::Result<()> {
        let n = model.nq();
        let nodes = &self.nodes;
        for (i, node) in nodes.iter().enumerate() {
            self.jtv.point_jacobian_rate(
                model,
                data,
                node.body,
                &node.ground,
                &self.xdot[i],
                &mut self.fixed_rate[col(i, n)],
            )?;
            self.d_rate[col(i, n)].copy_from_slice(&self.fixed_rate[col(i, n)]);
            if let NodeKind::Point(pi) = node.kind
                && let PointKind::Moving { frame, axes } = &path.points[pi].kind
            {
                let rot = data.body_pose(node.body).0 * frame.rot;
                let moving = MovingPointRate {
                    rot,
                    omega: data.body_velocity(node.body).0,
                    axes,
                };
                moving.add_rate(model, data, &self.jtv, &mut self.d_rate[col(i, n)]);
            }
            if let NodeKind::Tangent(_, false) = node.kind {
                self.jtv.point_jacobian_rate(
                    model,
                    data,
                    node.body,
                    &nodes[i - 1].ground,
                    &self.xdot[i - 1],
                    &mut self.wa_rate[col(i, n)],
                )?;
                self.jtv.point_jacobian_rate(
                    model,
                    data,
                    node.body,
                    &nodes[i + 2].ground,
                    &self.xdot[i + 2],
                    &mut self.wb_rate[col(i, n)],
                )?;
            }
        }
        Ok(())
    }

    /// Ḋ of the tangent points at their fixed point: Ḋ_T = J̇_W(T) + Ġ_TA (D_A − J_W(A)) +
    /// G_TA (Ḋ_A − J̇_W(A)) + Ġ_TB (D_B − J_W(B)) + G_TB (Ḋ_B − J̇_W(B)).
    #[inline]
    fn tangent_derivative_rates(&mut self, n: usize) {
        let (d, wa, wb, wa_rate, wb_rate, fixed_rate) = (
            &self.d,
            &self.wa,
            &self.wb,
            &self.wa_rate,
            &self.wb_rate,
            &self.fixed_rate,
        );
        iterate_tangents(n, &self.engaged, &mut self.d_rate, |e, t, j, dr| {
            let (a, b, k) = (e.node - 1, e.node + 2, e.node);
            let s = if t == k { 0 } else { 2 };
            let (ja, jb, ja_r, jb_r) = (e.jac[s], e.jac[s + 1], e.jac_rate[s], e.jac_rate[s + 1]);
            let rel_a = d[a * n + j] - wa[k * n + j];
            let rel_b = d[b * n + j] - wb[k * n + j];
            let rel_a_rate = dr[a * n + j] - wa_rate[k * n + j];
            let rel_b_rate = dr[b * n + j] - wb_rate[k * n + j];
            fixed_rate[t * n + j] + ja_r * rel_a + ja * rel_a_rate + jb_r * rel_b + jb * rel_b_rate
        });
    }

    /// ṙ = −d/dt ∇ℓ into `rate`: the wraps' terms
    /// −[ġ_Aᵀ(D_A − J_W(A)) + g_Aᵀ(Ḋ_A − J̇_W(A)) + (same for B)], then per straight segment
    /// −sign·[u̇ᵀ(D_b − D_a) + ûᵀ(Ḋ_b − Ḋ_a)] with u̇ = (I − ûûᵀ)(ẋ_b − ẋ_a)/|x_b − x_a|.
    #[inline]
    fn length_gradient_rate(&mut self, n: usize) {
        let nodes = &self.nodes;
        let m = nodes.len();
        let rate = &mut self.rate;
        rate.fill(0.0);
        for e in &self.engaged {
            let (a, b, k) = (e.node - 1, e.node + 2, e.node);
            for j in 0..n {
                let rel_a = self.d[a * n + j] - self.wa[k * n + j];
                let rel_b = self.d[b * n + j] - self.wb[k * n + j];
                let rel_a_rate = self.d_rate[a * n + j] - self.wa_rate[k * n + j];
                let rel_b_rate = self.d_rate[b * n + j] - self.wb_rate[k * n + j];
                rate[j] -= e.grad_rate[0].dot(&rel_a)
                    + e.grad[0].dot(&rel_a_rate)
                    + e.grad_rate[1].dot(&rel_b)
                    + e.grad[1].dot(&rel_b_rate);
            }
        }
        for i in 0..m.saturating_sub(1) {
            let Some(sign) = segment_sign(nodes[i].kind, nodes[i + 1].kind) else {
                continue;
            };
            let v = nodes[i + 1].ground - nodes[i].ground;
            let len = v.norm();
            if len == 0.0 {
                continue;
            }
            let u = v / len;
            let vrel = self.xdot[i + 1] - self.xdot[i];
            let u_rate = (vrel - u * u.dot(&vrel)) / len;
            for j in 0..n {
                let rel = self.d[(i + 1) * n + j] - self.d[i * n + j];
                let rel_rate = self.d_rate[(i + 1) * n + j] - self.d_rate[i * n + j];
                rate[j] -= sign * (u_rate.dot(&rel) + u.dot(&rel_rate));
            }
        }
    }
}

/// The n columns of node i in the node-major 3 × n blocks.
#[inline]
fn col(i: usize, n: usize) -> std::ops::Range<usize> {
    i * n..(i + 1) * n
}

/// A moving path point's frame in ground (R_b F), its body's angular velocity and its
/// location functions.
struct MovingPointRate<'a> {
    rot: Mat3,
    omega: Vec3,
    axes: &'a [(crate::model::Function, usize)],
}

impl MovingPointRate<'_> {
    /// Adds to the point's Ḋ columns d/dt (R_b F e_i f′(c) ∂c/∂q) =
    /// ω_b × (R_b F e_i) f′ ∂c/∂q + R_b F e_i (f″ ċ ∂c/∂q + f′ (∂c/∂q)˙), for each axis whose
    /// coordinate is within its range (clamped locations do not move).
    #[inline]
    fn add_rate(
        &self,
        model: &Model,
        data: &Data,
        jtv: &JacobianTimeVariation,
        d_rate: &mut [Vec3],
    ) {
        let c = data.coordinate_values(model);
        for (a, (func, ci)) in self.axes.iter().enumerate() {
            let [lo, hi] = model.coordinates[*ci].range;
            if c[*ci] < lo || c[*ci] > hi {
                continue;
            }
            let (_, f1, f2) = func.eval1(c[*ci]);
            let axis = self.rot.column(a).into_owned();
            let cdot: f64 = data
                .coordinate_gradient(model, *ci)
                .map(|(j, g)| g * data.independent_speed(model, j))
                .sum();
            let dir_rate = self.omega.cross(&axis) * f1 + axis * (f2 * cdot);
            for ((j, g), (_, g_rate)) in data
                .coordinate_gradient(model, *ci)
                .zip(jtv.coordinate_gradient_rate(model, data, *ci))
            {
                d_rate[j] += dir_rate * g + axis * (f1 * g_rate);
            }
        }
    }
}

/// q̇ applied to a 3 × n block of columns: Σ_j col_j q̇_j.
struct Vec3Speeds<'a> {
    data: &'a Data,
    model: &'a Model,
}

impl Vec3Speeds<'_> {
    fn apply(&self, cols: &[Vec3]) -> Vec3 {
        cols.iter().enumerate().fold(Vec3::zeros(), |s, (j, c)| {
            s + c * self.data.independent_speed(self.model, j)
        })
    }
}

/// Iterates `value(wrap, tangent node, column, current)` over the tangent nodes of every
/// engaged wrap until no entry of `x` changes by more than 1e-15 of its largest entry (the
/// tangent points of neighbouring wraps depend on each other; one pass when they do not).
fn iterate_tangents(
    n: usize,
    engaged: &[Engaged],
    x: &mut [Vec3],
    value: impl Fn(&Engaged, usize, usize, &[Vec3]) -> Vec3,
) {
    let scale = x.iter().fold(1.0f64, |s, v| s.max(v.amax()));
    for _ in 0..MAX_ITERATIONS {
        let mut change = 0.0f64;
        for e in engaged {
            for t in [e.node, e.node + 1] {
                for j in 0..n {
                    let new = value(e, t, j, x);
                    change = change.max((new - x[t * n + j]).amax());
                    x[t * n + j] = new;
                }
            }
        }
        if change <= 1e-15 * scale {
            break;
        }
    }
}

fn not_rewrapped(model: &Model, path: &super::PathGeometry, w: usize) -> Error {
    Error::invalid(
        "state",
        format!(
            "path {}: wrap object {} does not wrap again between its final neighbours \
             (a degenerate configuration at the edge of the wrap); its moment-arm rates are \
             not defined here",
            path.name, model.wrap_objects[path.wraps[w].object].name
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, forward_kinematics_velocity};
    use crate::muscle::path::{PathData, compute_paths, current_path};
    use crate::random::SplitMix64;

    /// Moment arms of every path at q (n × paths, column-major).
    fn arms(model: &Model, set: &PathSet, q: &[f64]) -> Vec<f64> {
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, q).unwrap();
        let mut out = PathData::new(model, set);
        compute_paths(model, &data, set, &mut out).unwrap();
        out.moment_arms.as_slice().to_vec()
    }

    /// ṙ_k of every path equals the central difference (r_k(q + h q̇) − r_k(q − h q̇))/2h at
    /// random states of the default model, gait2392 and Rajagopal2016 — wrapped paths of every
    /// shape, interacting wraps and moving points included. Paths whose moment arms are not
    /// smooth over the stencil (a wrap engaging, a conditional point switching: the steps h
    /// and 2h then disagree) are skipped and counted.
    #[test]
    fn moment_arm_rates_match_central_differences_of_the_moment_arms() {
        let h = 1e-5;
        for (name, model) in crate::reference::test_models() {
            let set = PathSet::new(&model).unwrap();
            let n = model.nq();
            let mut rng = SplitMix64(7);
            let mut rates = MomentArmRates::new(&model, &set);
            let (mut checked, mut skipped, mut several_wraps, mut wrapped) = (0, 0, 0, 0);
            let mut worst = 0.0f64;
            for _ in 0..20 {
                let q = crate::reference::random_q(&model, &mut rng, 0.05);
                let qd: Vec<f64> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let step =
                    |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * b).collect() };
                let (p1, m1, p2, m2) = (
                    arms(&model, &set, &step(h)),
                    arms(&model, &set, &step(-h)),
                    arms(&model, &set, &step(2.0 * h)),
                    arms(&model, &set, &step(-2.0 * h)),
                );
                let mut data = Data::new(&model);
                forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
                let mut weights = vec![0.0; set.len()];
                let mut out = vec![0.0; n];
                for k in 0..set.len() {
                    let cols = k * n..(k + 1) * n;
                    let fd: Vec<f64> = cols.clone().map(|i| (p1[i] - m1[i]) / (2.0 * h)).collect();
                    let fd2: Vec<f64> = cols.clone().map(|i| (p2[i] - m2[i]) / (4.0 * h)).collect();
                    let scale = fd.iter().fold(1e-3f64, |s, v| s.max(v.abs()));
                    let jump = fd
                        .iter()
                        .zip(&fd2)
                        .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
                    if jump > 1e-5 * scale {
                        skipped += 1;
                        continue;
                    }
                    weights.fill(0.0);
                    weights[k] = 1.0;
                    rates
                        .compute(&model, &data, &set, &weights, &mut out)
                        .unwrap_or_else(|e| panic!("{name} {}: {e}", set.paths[k].name));
                    // Richardson extrapolation of the two steps: O(h⁴)
                    let err = out
                        .iter()
                        .zip(fd.iter().zip(&fd2))
                        .fold(0.0f64, |s, (a, (b, c))| {
                            s.max((a - (4.0 * b - c) / 3.0).abs())
                        });
                    worst = worst.max(err / scale);
                    assert!(
                        err <= 1e-6 * scale,
                        "{name} {}: ṙ {:?}\n central differences {:?}",
                        set.paths[k].name,
                        out,
                        fd
                    );
                    checked += 1;
                    let tangents = current_path(&model, &data, &set, k)
                        .unwrap()
                        .iter()
                        .filter(|(p, _)| {
                            matches!(
                                p,
                                crate::muscle::path::PathPoint::Tangent { second: false, .. }
                            )
                        })
                        .count();
                    wrapped += usize::from(tangents >= 1);
                    several_wraps += usize::from(tangents >= 2);
                }
            }
            eprintln!(
                "{name}: {checked} path states checked ({wrapped} wrapped, {several_wraps} with \
                 several wraps engaged), {skipped} not smooth over the stencil; worst error \
                 {worst:.1e} of the rate's scale"
            );
            assert!(
                skipped * 20 <= checked,
                "{name}: {skipped} skipped of {checked}"
            );
            if !model.wrap_objects.is_empty() {
                assert!(wrapped > 0, "{name}: no wrapped path was checked");
            }
        }
    }
}
