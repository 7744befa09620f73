//! Vector–Jacobian products of inverse dynamics with external point forces, in O(n): for a
//! weight vector u, the gradients of uᵀτ with respect to q, q̇, q̈ and the forces λ, where
//! τ = M q̈ + C q̇ + G − J_cᵀ λ. This is what a loss Σ ‖r‖² needs (u = 2 W r), at the cost of
//! a few inverse-dynamics passes instead of the O(n²) Jacobians of [`super::rnea_derivatives`].
//!
//! Virtual work form. With V_b = Σ_{d on the path to b} u_d s_d (the velocity body b would have
//! with joint rates u), uᵀτ_full = Σ_b V_bᵀ f_b − Σ_i V_{b_i}ᵀ f^c_i: f_b = I_b a_b + v_b ×* I_b v_b
//! the body's own force, f^c_i = ((p_i − O) × λ_i, λ_i) the external force i. A change ε of θ_j
//! moves the subtree of j by the screw ε s_j. Everything attached to it turns with it
//! (δx = s_j ×ₘ x or s_j ×* x), and the power mᵀf of two attached vectors does not change;
//! what is not attached gives the terms below. For every body b beyond j:
//!
//! ```text
//! δv_b = s_j ×ₘ v_b − c_v,                        c_v = s_j ×ₘ v_j
//! δa_b = s_j ×ₘ a_b − c_a − c_v ×ₘ (v_b − v_j),    c_a = s_j ×ₘ a_j
//! δV_b = s_j ×ₘ (V_b − V_j)
//! ```
//!
//! (v_j, a_j, V_j: the values just after coordinate j, the part that does not move), and λ_i
//! keeps its direction while its point moves with its carrier. Collecting terms into sums over
//! the subtree of j's body (P = Σ I_b V_b, R = Σ (v_b ×* I_b V_b − V_b ×* I_b v_b −
//! I_b (v_b ×ₘ V_b)), F = Σ f_b, F^c = Σ f^c_i, K = Σ λ_i × (V_{b_i} at p_i) + g_i × (λ_i × ω^V_{b_i})
//! with g_i the point's ground offset from its carrier):
//!
//! ```text
//! ∂(uᵀτ)/∂θ_j = −(s_j ×ₘ V_j)ᵀ (F − F^c) − c_aᵀ P + (c_v ×ₘ v_j)ᵀ P − c_vᵀ R + s_j,angᵀ K
//! ∂(uᵀτ)/∂θ̇_j = s_jᵀ R + 2 (v_j ×ₘ s_j)ᵀ P
//! ∂(uᵀτ)/∂θ̈_j = s_jᵀ P                          (= (M_full u)_j)
//! ∂(uᵀτ)/∂λ_i = −(V_{b_i} at p_i)                (= −J_i u)
//! ```
//!
//! Each is one forward and one backward pass. In the independent coordinates (uᵀτ = (Φu)ᵀτ_full)
//! the chain rule through θ = φ(q) adds Σ_d τ_full,d ∂(Φ_d u)/∂q and the ∂θ̇/∂q, ∂θ̈/∂q terms of
//! the reduction (see [`super::rnea_derivatives`]).

use super::Data;
use super::reduction::{ReductionTangents, evaluate_position, evaluate_velocity};
use crate::model::Model;
use crate::spatial::{Force, Motion, Vec3};
use nalgebra::DVector;

/// External forces λ_i (ground axes, N) at points c_i + g_i: c_i fixed in a body (the carrier),
/// g_i fixed in ground (empty: none). A contact sphere is loaded at its lowest point: carrier
/// its centre, offset −ρ n.
#[derive(Clone, Copy, Debug, Default)]
pub struct PointForces<'a> {
    pub carriers: &'a [(usize, Vec3)],
    pub offsets_in_ground: &'a [Vec3],
    pub forces: &'a [Vec3],
}

impl PointForces<'_> {
    fn offset(&self, i: usize) -> Vec3 {
        self.offsets_in_ground
            .get(i)
            .copied()
            .unwrap_or_else(Vec3::zeros)
    }

    pub(crate) fn validate(&self, model: &Model) -> crate::Result<()> {
        let p = self.carriers.len();
        if self.forces.len() != p {
            return Err(crate::Error::invalid(
                "forces",
                format!("{} forces for {p} points", self.forces.len()),
            ));
        }
        if !(self.offsets_in_ground.is_empty() || self.offsets_in_ground.len() == p) {
            return Err(crate::Error::invalid(
                "offsets_in_ground",
                format!(
                    "{} offsets for {p} points (give one per point, or none)",
                    self.offsets_in_ground.len()
                ),
            ));
        }
        let nb = model.bodies.len();
        for (i, ((body, c), f)) in self.carriers.iter().zip(self.forces).enumerate() {
            if *body >= nb {
                return Err(crate::Error::invalid(
                    "points",
                    format!("point {i}: body index {body} out of range ({nb} bodies)"),
                ));
            }
            let g = self.offset(i);
            if !(c.iter().chain(f.iter()).chain(g.iter())).all(|v| v.is_finite()) {
                return Err(crate::Error::invalid(
                    "forces",
                    format!("point {i}: location, offset or force is not finite"),
                ));
            }
        }
        Ok(())
    }
}

/// The outputs and workspace of [`rnea_vjp`] and [`rnea_vjp_full`] for one model.
#[derive(Clone, Debug)]
pub struct RneaVjp {
    /// uᵀ∂τ/∂q, uᵀ∂τ/∂q̇, uᵀ∂τ/∂q̈ (= M u) in the independent coordinates (n).
    pub dq: DVector<f64>,
    pub dqd: DVector<f64>,
    pub dqdd: DVector<f64>,
    /// ∂(uᵀτ)/∂λ_i = −J_i u, one per point.
    pub dforces: Vec<Vec3>,
    /// The same in full coordinates (n_full), for u_full.
    pub dtheta: Vec<f64>,
    pub dtheta_dot: Vec<f64>,
    pub dtheta_ddot: Vec<f64>,
    /// τ = M q̈ + C q̇ + G − J_cᵀλ (n) and τ_full − Q_full (n_full) at the state of the last
    /// forward pass.
    pub tau: DVector<f64>,
    pub tau_full: Vec<f64>,
    /// τ_ID = M q̈ + C q̇ + G alone (n), from the last forward pass.
    pub tau_id: DVector<f64>,
    /// The external forces of the last forward pass: body, application point p − O, ground
    /// offset g, force λ.
    points: Vec<(usize, Vec3, Vec3, Vec3)>,
    /// Set by a forward pass: 1 in full coordinates, 2 in independent coordinates.
    prepared: u8,
    dof_vel: Vec<Motion>,
    dof_acc: Vec<Motion>,
    dof_virtual: Vec<Motion>,
    body_virtual: Vec<Motion>,
    sum_p: Vec<Force>,
    sum_r: Vec<Force>,
    sum_fc: Vec<Force>,
    sum_k: Vec<Vec3>,
    // reduction
    tangents: ReductionTangents,
    u_full: Vec<f64>,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    theta_ddot: Vec<f64>,
}

impl RneaVjp {
    /// Allocates the outputs and workspace for `model`.
    pub fn new(model: &Model) -> RneaVjp {
        let (n, nf, nb) = (model.nq(), model.n_full(), model.bodies.len());
        RneaVjp {
            dq: DVector::zeros(n),
            dqd: DVector::zeros(n),
            dqdd: DVector::zeros(n),
            dforces: Vec::new(),
            tau: DVector::zeros(n),
            tau_id: DVector::zeros(n),
            points: Vec::new(),
            prepared: 0,
            dtheta: vec![0.0; nf],
            dtheta_dot: vec![0.0; nf],
            dtheta_ddot: vec![0.0; nf],
            tau_full: vec![0.0; nf],
            dof_vel: vec![Motion::ZERO; nf],
            dof_acc: vec![Motion::ZERO; nf],
            dof_virtual: vec![Motion::ZERO; nf],
            body_virtual: vec![Motion::ZERO; nb],
            sum_p: vec![Force::ZERO; nb],
            sum_r: vec![Force::ZERO; nb],
            sum_fc: vec![Force::ZERO; nb],
            sum_k: vec![Vec3::zeros(); nb],
            tangents: ReductionTangents::new(model),
            u_full: vec![0.0; nf],
            theta: vec![0.0; nf],
            theta_dot: vec![0.0; nf],
            theta_ddot: vec![0.0; nf],
        }
    }

    fn fits(&self, model: &Model) -> crate::Result<()> {
        if self.dq.len() != model.nq()
            || self.dtheta.len() != model.n_full()
            || self.sum_p.len() != model.bodies.len()
        {
            return Err(crate::Error::invalid(
                "vjp",
                "RneaVjp was built for another model",
            ));
        }
        Ok(())
    }
}

/// Both passes at once: uᵀ∂τ/∂q, uᵀ∂τ/∂q̇, uᵀ∂τ/∂q̈ and ∂(uᵀτ)/∂λ of τ = M q̈ + C q̇ + G − J_cᵀλ
/// at (q, q̇, q̈) into `out` (see [`RneaVjp::forward`] and [`RneaVjp::backward`]).
#[allow(clippy::too_many_arguments)]
pub fn rnea_vjp(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    external: &PointForces,
    u: &[f64],
    out: &mut RneaVjp,
) -> crate::Result<()> {
    out.forward(model, data, q, qd, qdd, external)?;
    out.backward(model, data, u)
}

/// Both passes at once in full coordinates (see [`RneaVjp::forward_full`] and
/// [`RneaVjp::backward_full`]).
#[allow(clippy::too_many_arguments)]
pub fn rnea_vjp_full(
    model: &Model,
    data: &mut Data,
    theta: &[f64],
    theta_dot: &[f64],
    theta_ddot: &[f64],
    external: &PointForces,
    u_full: &[f64],
    out: &mut RneaVjp,
) -> crate::Result<()> {
    out.forward_full(model, data, theta, theta_dot, theta_ddot, external)?;
    out.backward_full(model, data, u_full)
}

impl RneaVjp {
    /// The forward pass at (q, q̇, q̈): τ = M q̈ + C q̇ + G − J_cᵀλ into `self.tau` (returned), and
    /// everything [`Self::backward`] needs. `data` must not be used by anything else until
    /// the backward pass.
    pub fn forward(
        &mut self,
        model: &Model,
        data: &mut Data,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        external: &PointForces,
    ) -> crate::Result<&DVector<f64>> {
        self.fits(model)?;
        data.fits(model)?;
        let n = model.nq();
        for (name, x) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            super::check_len(name, x, n)?;
        }
        evaluate_position(model, data, q);
        evaluate_velocity(model, data, qd);
        self.tangents.compute(model, data, qdd);
        let nc = model.reduction.n_coordinates;
        self.theta.copy_from_slice(&data.node_value[nc..]);
        self.theta_dot.copy_from_slice(&data.node_vel[nc..]);
        // θ̈ = Φq̈ + Φ̇q̇
        for d in 0..model.n_full() {
            let mut a = data.node_acc_bias[nc + d];
            for e in model.reduction.phi_row(d) {
                let j = model.reduction.dep_index[e];
                a += self.tangents.phi[(d, j)] * qdd[j];
            }
            self.theta_ddot[d] = a;
        }
        let (theta, theta_dot, theta_ddot) = (
            std::mem::take(&mut self.theta),
            std::mem::take(&mut self.theta_dot),
            std::mem::take(&mut self.theta_ddot),
        );
        let full = self.forward_full(model, data, &theta, &theta_dot, &theta_ddot, external);
        (self.theta, self.theta_dot, self.theta_ddot) = (theta, theta_dot, theta_ddot);
        full?;
        // τ = Φᵀ (τ_full − Q_full)
        self.tau.gemv_tr(
            1.0,
            &self.tangents.phi,
            &nalgebra::DVectorView::from_slice(&self.tau_full, model.n_full()),
            0.0,
        );
        self.tau_id.gemv_tr(
            1.0,
            &self.tangents.phi,
            &nalgebra::DVectorView::from_slice(&data.tau_full, model.n_full()),
            0.0,
        );
        self.prepared = 2;
        Ok(&self.tau)
    }

    /// The backward pass for weights u (n) after [`Self::forward`]: uᵀ∂τ/∂q, uᵀ∂τ/∂q̇,
    /// uᵀ∂τ/∂q̈ into `dq`, `dqd`, `dqdd` and −J_i u into `dforces`.
    pub fn backward(&mut self, model: &Model, data: &Data, u: &[f64]) -> crate::Result<()> {
        self.fits(model)?;
        if self.prepared != 2 {
            return Err(crate::Error::invalid(
                "vjp",
                "RneaVjp::backward needs RneaVjp::forward first",
            ));
        }
        let n = model.nq();
        super::check_len("u", u, n)?;
        // ũ = Φu
        let r = &model.reduction;
        let mut u_full = std::mem::take(&mut self.u_full);
        for (d, w) in u_full.iter_mut().enumerate() {
            *w = 0.0;
            for e in r.phi_row(d) {
                let j = r.dep_index[e];
                *w += self.tangents.phi[(d, j)] * u[j];
            }
        }
        self.prepared = 1;
        let full = self.backward_full(model, data, &u_full);
        self.u_full = u_full;
        self.prepared = 2;
        full?;
        // uᵀ∂τ/∂q_k = Σ_d (τ_full − Q_full)_d ∂(Φ_d u)/∂q_k + g_θᵀ Φ_k + g_θ̇ᵀ ∂θ̇/∂q_k
        //             + g_θ̈ᵀ ∂θ̈/∂q_k
        // uᵀ∂τ/∂q̇_k = g_θ̇ᵀ Φ_k + g_θ̈ᵀ ∂θ̈/∂q̇_k,   uᵀ∂τ/∂q̈_k = g_θ̈ᵀ Φ_k
        let t = &self.tangents;
        let ne = r.dep_index.len();
        for k in 0..n {
            let grad_k = &t.grad_q[k * ne..(k + 1) * ne];
            let (mut gq, mut gqd, mut gqdd) = (0.0, 0.0, 0.0);
            for &d in t.full_of(k) {
                let mut h = 0.0;
                for e in r.phi_row(d) {
                    h += grad_k[e] * u[r.dep_index[e]];
                }
                gq += self.tau_full[d] * h
                    + self.dtheta[d] * t.phi[(d, k)]
                    + self.dtheta_dot[d] * t.theta_dot_q[(d, k)]
                    + self.dtheta_ddot[d] * t.theta_ddot_q[(d, k)];
                gqd += self.dtheta_dot[d] * t.phi[(d, k)]
                    + self.dtheta_ddot[d] * t.theta_ddot_qd[(d, k)];
                gqdd += self.dtheta_ddot[d] * t.phi[(d, k)];
            }
            self.dq[k] = gq;
            self.dqd[k] = gqd;
            self.dqdd[k] = gqdd;
        }
        Ok(())
    }

    /// The forward pass in full coordinates: τ_full − Q_full into `self.tau_full`.
    pub fn forward_full(
        &mut self,
        model: &Model,
        data: &mut Data,
        theta: &[f64],
        theta_dot: &[f64],
        theta_ddot: &[f64],
        external: &PointForces,
    ) -> crate::Result<()> {
        self.fits(model)?;
        external.validate(model)?;
        super::rnea_full(model, data, theta, theta_dot, theta_ddot)?;
        let (s, v, a) = (&data.dof_motion, &data.body_vel, &data.body_acc);
        let o = data.reference_point;
        // the velocity and acceleration just after each coordinate
        for joint in &model.joints {
            let (mut vd, mut ad) = (v[joint.parent_body], a[joint.parent_body]);
            for d in joint.dof_range.clone() {
                vd.add_scaled(&s[d], theta_dot[d]);
                ad.add_scaled(&s[d], theta_ddot[d]);
                ad.add_scaled(&vd.cross_motion(&s[d]), theta_dot[d]);
                self.dof_vel[d] = vd;
                self.dof_acc[d] = ad;
            }
        }
        // external forces f^c_i = ((p_i − O) × λ_i, λ_i), summed over subtrees
        self.points.clear();
        self.sum_fc.fill(Force::ZERO);
        for (i, ((body, c), f)) in external.carriers.iter().zip(external.forces).enumerate() {
            let g = external.offset(i);
            let rp = data.body_rot[*body] * c + data.body_pos[*body] + g - o;
            self.points.push((*body, rp, g, *f));
            self.sum_fc[*body].add_assign(&Force {
                ang: rp.cross(f),
                lin: *f,
            });
        }
        accumulate(model, &mut self.sum_fc);
        for (d, dof) in model.dofs.iter().enumerate() {
            self.tau_full[d] = data.tau_full[d] - s[d].dot(&self.sum_fc[dof.body]);
        }
        self.prepared = 1;
        Ok(())
    }

    /// The backward pass in full coordinates for weights u_full after
    /// [`Self::forward_full`]: ∂(u_fullᵀτ_full)/∂θ, ∂θ̇, ∂θ̈ into `dtheta`, `dtheta_dot`,
    /// `dtheta_ddot` and −J_i u into `dforces`.
    pub fn backward_full(
        &mut self,
        model: &Model,
        data: &Data,
        u_full: &[f64],
    ) -> crate::Result<()> {
        self.fits(model)?;
        if self.prepared == 0 {
            return Err(crate::Error::invalid(
                "vjp",
                "RneaVjp::backward_full needs a forward pass first",
            ));
        }
        super::check_len("u_full", u_full, model.n_full())?;
        let (s, v, inertia, total) = (
            &data.dof_motion,
            &data.body_vel,
            &data.body_inertia,
            &data.body_force,
        );
        // virtual velocities V_b = Σ u_d s_d, and V just after each coordinate
        self.body_virtual[0] = Motion::ZERO;
        for joint in &model.joints {
            let mut w = self.body_virtual[joint.parent_body];
            for d in joint.dof_range.clone() {
                w.add_scaled(&s[d], u_full[d]);
                self.dof_virtual[d] = w;
            }
            self.body_virtual[joint.child_body] = w;
        }
        // P = I V and R = v ×* I V − V ×* I v − I (v ×ₘ V) per body
        self.sum_p[0] = Force::ZERO;
        self.sum_r[0] = Force::ZERO;
        for b in 1..model.bodies.len() {
            let (i, vb, wb) = (&inertia[b], &v[b], &self.body_virtual[b]);
            let p = i.mul_motion(wb);
            let q1 = vb.cross_force(&p);
            let q2 = wb.cross_force(&i.mul_motion(vb));
            let q3 = i.mul_motion(&vb.cross_motion(wb));
            self.sum_p[b] = p;
            self.sum_r[b] = Force {
                ang: q1.ang - q2.ang - q3.ang,
                lin: q1.lin - q2.lin - q3.lin,
            };
        }
        // K = Σ λ × (V at p) + g × (λ × ω^V), and ∂/∂λ_i = −(V at p_i)
        self.sum_k.fill(Vec3::zeros());
        self.dforces.clear();
        for &(body, rp, g, f) in &self.points {
            let wb = &self.body_virtual[body];
            let vel = wb.linear_at(&rp);
            self.sum_k[body] += f.cross(&vel) + g.cross(&f.cross(&wb.ang));
            self.dforces.push(-vel);
        }
        accumulate(model, &mut self.sum_p);
        accumulate(model, &mut self.sum_r);
        for joint in model.joints.iter().rev() {
            if joint.parent_body != 0 {
                let k = self.sum_k[joint.child_body];
                self.sum_k[joint.parent_body] += k;
            }
        }
        for (j, dof) in model.dofs.iter().enumerate() {
            let b = dof.body;
            let (sj, vj, aj) = (&s[j], &self.dof_vel[j], &self.dof_acc[j]);
            let (p, r, fc) = (&self.sum_p[b], &self.sum_r[b], &self.sum_fc[b]);
            let c_v = sj.cross_motion(vj);
            let c_a = sj.cross_motion(aj);
            let net = Force {
                ang: total[b].ang - fc.ang,
                lin: total[b].lin - fc.lin,
            };
            // −(s_j ×ₘ V_j)ᵀ(F − F^c) − c_aᵀP + (c_v ×ₘ v_j)ᵀP − c_vᵀR + s_j,angᵀK
            self.dtheta[j] = -sj.cross_motion(&self.dof_virtual[j]).dot(&net) - c_a.dot(p)
                + c_v.cross_motion(vj).dot(p)
                - c_v.dot(r)
                + sj.ang.dot(&self.sum_k[b]);
            // s_jᵀR + 2 (v_j ×ₘ s_j)ᵀP,   s_jᵀP
            self.dtheta_dot[j] = sj.dot(r) + 2.0 * vj.cross_motion(sj).dot(p);
            self.dtheta_ddot[j] = sj.dot(p);
        }
        Ok(())
    }
}

/// F_parent += F_child, from the leaves to the root.
fn accumulate(model: &Model, f: &mut [Force]) {
    for joint in model.joints.iter().rev() {
        if joint.parent_body != 0 {
            let c = f[joint.child_body];
            f[joint.parent_body].add_assign(&c);
        }
    }
}
