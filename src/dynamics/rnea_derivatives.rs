//! Partial derivatives of inverse dynamics in full coordinates, ∂τ/∂θ and ∂τ/∂θ̇ (∂τ/∂θ̈ is
//! the mass matrix, [`super::crba_full`]), by differentiating the recursive Newton–Euler
//! passes in ground axes, one coordinate direction at a time (the world-frame recursions of
//! Carpentier & Mansard 2018, "Analytical derivatives of rigid body dynamics algorithms",
//! RSS, written as tangent passes).
//!
//! Every spatial quantity is taken in ground axes about the point O of the current state. A
//! change ε of θ_j moves everything beyond coordinate j by the screw ε s_j: a motion vector m
//! attached there changes by s_j ×ₘ m, a spatial inertia by δI v = s_j ×* (I v) − I (s_j ×ₘ v);
//! nothing else moves (ground, gravity, the axes up to and including s_j). With
//!
//! ```text
//! v_b = v_λ + Σ_d s_d θ̇_d                        (d over the joint's coordinates)
//! a_b = a_λ + Σ_d (s_d θ̈_d + v_d ×ₘ s_d θ̇_d)     (v_d: the velocity after coordinate d)
//! f_b = I_b a_b + v_b ×* I_b v_b,   F_b = f_b + Σ_children F_c,   τ_d = s_dᵀ F_body(d)
//! ```
//!
//! the tangent of each line, for the direction θ_j (δs_d = s_j ×ₘ s_d beyond j, else 0):
//!
//! ```text
//! δv_b = δv_λ + Σ_d δs_d θ̇_d
//! δa_b = δa_λ + Σ_d (δs_d θ̈_d + (δv_d ×ₘ s_d + v_d ×ₘ δs_d) θ̇_d)
//! δf_b = δI_b a_b + I_b δa_b + δv_b ×* I_b v_b + v_b ×* (δI_b v_b + I_b δv_b)
//! δF_b = δf_b + Σ_children δF_c,   δτ_d = δs_dᵀ F_d + s_dᵀ δF_d
//! ```
//!
//! and for the direction θ̇_j the same with δs = 0, δI = 0 and δθ̇_d = [d = j], i.e.
//! δv_d = s_j beyond j and δa_b gains v_j ×ₘ s_j. The tangents vanish outside the subtree
//! that θ_j moves, and the joints above it see only the subtree's total δF, so each direction
//! is one pass over that subtree plus the path to ground: O(n·depth) for both Jacobians,
//! allocation-free after [`RneaDerivatives::new`].
//!
//! In the independent coordinates q (θ = φ(q), θ̇ = Φq̇, θ̈ = Φq̈ + Φ̇q̇, τ = Φᵀ τ_full) the
//! chain rule gives, with D_θ, D_θ̇ the full-coordinate Jacobians above and M_full = ∂τ_full/∂θ̈:
//!
//! ```text
//! ∂τ/∂q  = Σ_d τ_full,d ∂²θ_d/∂q∂q + Φᵀ (D_θ Φ + D_θ̇ ∂θ̇/∂q + M_full ∂θ̈/∂q)
//! ∂τ/∂q̇ = Φᵀ (D_θ̇ Φ + M_full ∂(Φ̇q̇)/∂q̇)
//! ∂τ/∂q̈ = Φᵀ M_full Φ = M
//! ```
//!
//! where ∂θ̇/∂q, ∂θ̈/∂q (third derivatives of the coupling and axis functions included) and
//! ∂²θ/∂q∂q come from one tangent pass per coordinate through the reduction graph.

use super::Data;
use super::reduction::{ReductionTangents, evaluate_position, evaluate_velocity};
use crate::model::Model;
use crate::spatial::{Force, Motion, SpatialInertia};
use nalgebra::DMatrix;

/// The outputs and workspace of [`rnea_derivatives`] and [`rnea_derivatives_full`] for one
/// model.
#[derive(Clone, Debug)]
pub struct RneaDerivatives {
    /// ∂τ/∂q, ∂τ/∂q̇ and ∂τ/∂q̈ = M (n × n, independent coordinates) from [`rnea_derivatives`].
    pub dtau_dq: DMatrix<f64>,
    pub dtau_dqd: DMatrix<f64>,
    pub dtau_dqdd: DMatrix<f64>,
    /// ∂τ_full/∂θ (n_full × n_full).
    pub dtau_dtheta: DMatrix<f64>,
    /// ∂τ_full/∂θ̇ (n_full × n_full).
    pub dtau_dtheta_dot: DMatrix<f64>,
    moves: MovedBy,
    /// Each body's own force f_b and the velocity after each coordinate, v_d.
    own_force: Vec<Force>,
    dof_vel: Vec<Motion>,
    // tangents of one direction
    d_vel: Vec<Motion>,
    d_acc: Vec<Motion>,
    d_force: Vec<Force>,
    d_axis: Vec<Motion>,
    // reduction to q
    tangents: ReductionTangents,
    /// n_full × n scratch for the chain rule.
    chain: DMatrix<f64>,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    theta_ddot: Vec<f64>,
}

/// Which bodies and which axes a change of each full coordinate θ_j moves.
#[derive(Clone, Debug)]
pub(crate) struct MovedBy {
    n_bodies: usize,
    n_full: usize,
    /// [j * n_bodies + b]: body b moves with θ_j (b is the child of j's joint or below it).
    body: Vec<bool>,
    /// [j * n_full + d]: axis s_d moves with θ_j (d comes after j in j's joint, or belongs to
    /// a joint whose parent body moves with θ_j).
    dof: Vec<bool>,
    /// The joints whose child body moves with θ_j (j's own first), in tree order:
    /// `subtree[subtree_start[j]..subtree_start[j + 1]]`.
    subtree_start: Vec<usize>,
    subtree: Vec<usize>,
    /// The full coordinates of the joints above j's (their bodies are ancestors of j's body).
    above_start: Vec<usize>,
    above: Vec<usize>,
}

impl MovedBy {
    pub fn new(model: &Model) -> MovedBy {
        let (nf, nb) = (model.dofs.len(), model.bodies.len());
        let mut body = vec![false; nf * nb];
        let mut dof = vec![false; nf * nf];
        // Joints are in topological order: a body moves with θ_j when it is j's body or its
        // joint's parent body moves with θ_j.
        for (j, dj) in model.dofs.iter().enumerate() {
            let row = &mut body[j * nb..(j + 1) * nb];
            row[dj.body] = true;
            for joint in &model.joints {
                if row[joint.parent_body] {
                    row[joint.child_body] = true;
                }
            }
            for (d, dd) in model.dofs.iter().enumerate() {
                let joint = &model.joints[dd.joint];
                dof[j * nf + d] = (dd.joint == dj.joint && d > j) || row[joint.parent_body];
            }
        }
        let (mut subtree_start, mut subtree) = (vec![0], Vec::new());
        let (mut above_start, mut above) = (vec![0], Vec::new());
        for (j, dj) in model.dofs.iter().enumerate() {
            let moved = &body[j * nb..(j + 1) * nb];
            subtree.extend((0..model.joints.len()).filter(|&i| moved[model.joints[i].child_body]));
            subtree_start.push(subtree.len());
            // walk from j's joint's parent body to ground
            let mut b = model.joints[dj.joint].parent_body;
            let mut chain = Vec::new();
            while b != 0 {
                let i = model
                    .joints
                    .iter()
                    .position(|jt| jt.child_body == b)
                    .expect("every moving body has a joint");
                chain.extend(model.joints[i].dof_range.clone());
                b = model.joints[i].parent_body;
            }
            above.extend(chain);
            above_start.push(above.len());
        }
        MovedBy {
            n_bodies: nb,
            n_full: nf,
            body,
            dof,
            subtree_start,
            subtree,
            above_start,
            above,
        }
    }

    /// The joints θ_j moves the child of (j's own first), in tree order.
    pub fn subtree_joints(&self, j: usize) -> &[usize] {
        &self.subtree[self.subtree_start[j]..self.subtree_start[j + 1]]
    }

    /// The full coordinates of the joints between ground and j's joint.
    pub fn dofs_above(&self, j: usize) -> &[usize] {
        &self.above[self.above_start[j]..self.above_start[j + 1]]
    }

    /// Per body: moves with θ_j.
    pub fn bodies(&self, j: usize) -> &[bool] {
        &self.body[j * self.n_bodies..(j + 1) * self.n_bodies]
    }

    /// Per full coordinate: its axis moves with θ_j.
    pub fn dofs(&self, j: usize) -> &[bool] {
        &self.dof[j * self.n_full..(j + 1) * self.n_full]
    }
}

impl RneaDerivatives {
    /// Allocates the outputs and workspace for `model`.
    pub fn new(model: &Model) -> RneaDerivatives {
        let (nf, nb) = (model.dofs.len(), model.bodies.len());
        let n = model.nq();
        RneaDerivatives {
            dtau_dq: DMatrix::zeros(n, n),
            dtau_dqd: DMatrix::zeros(n, n),
            dtau_dqdd: DMatrix::zeros(n, n),
            tangents: ReductionTangents::new(model),
            chain: DMatrix::zeros(nf, n),
            theta: vec![0.0; nf],
            theta_dot: vec![0.0; nf],
            theta_ddot: vec![0.0; nf],
            dtau_dtheta: DMatrix::zeros(nf, nf),
            dtau_dtheta_dot: DMatrix::zeros(nf, nf),
            moves: MovedBy::new(model),
            own_force: vec![Force::ZERO; nb],
            dof_vel: vec![Motion::ZERO; nf],
            d_vel: vec![Motion::ZERO; nb],
            d_acc: vec![Motion::ZERO; nb],
            d_force: vec![Force::ZERO; nb],
            d_axis: vec![Motion::ZERO; nf],
        }
    }

    fn fits(&self, model: &Model) -> crate::Result<()> {
        let (nf, nb) = (model.dofs.len(), model.bodies.len());
        if self.dtau_dtheta.shape() != (nf, nf)
            || self.own_force.len() != nb
            || self.dtau_dq.nrows() != model.nq()
        {
            return Err(crate::error::Error::invalid(
                "derivatives",
                "RneaDerivatives was built for another model",
            ));
        }
        Ok(())
    }
}

/// ∂τ/∂q, ∂τ/∂q̇ and ∂τ/∂q̈ of [`super::rnea`] at (q, q̇, q̈) in the independent
/// coordinates, into `out.dtau_dq`, `out.dtau_dqd`, `out.dtau_dqdd` (the full-coordinate
/// Jacobians are left in `out` too); `data` is left as `rnea` leaves it, τ in `data.tau()`.
pub fn rnea_derivatives(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    out: &mut RneaDerivatives,
) -> crate::Result<()> {
    out.fits(model)?;
    data.fits(model)?;
    super::check_len("q", q, model.nq())?;
    super::check_len("qd", qd, model.nq())?;
    super::check_len("qdd", qdd, model.nq())?;
    evaluate_position(model, data, q);
    evaluate_velocity(model, data, qd);
    out.tangents.compute(model, data, qdd);
    let nc = model.reduction.n_coordinates;
    out.theta.copy_from_slice(&data.node_value[nc..]);
    out.theta_dot.copy_from_slice(&data.node_vel[nc..]);
    for (d, a) in out.theta_ddot.iter_mut().enumerate() {
        *a = data.node_acc_bias[nc + d];
        for (j, qj) in qdd.iter().enumerate() {
            *a += out.tangents.phi[(d, j)] * qj;
        }
    }
    let (theta, theta_dot, theta_ddot) = (
        std::mem::take(&mut out.theta),
        std::mem::take(&mut out.theta_dot),
        std::mem::take(&mut out.theta_ddot),
    );
    let full = rnea_derivatives_full(model, data, &theta, &theta_dot, &theta_ddot, out);
    (out.theta, out.theta_dot, out.theta_ddot) = (theta, theta_dot, theta_ddot);
    full?;
    super::crba_full(model, data)?;
    let RneaDerivatives {
        dtau_dq,
        dtau_dqd,
        dtau_dqdd,
        dtau_dtheta,
        dtau_dtheta_dot,
        tangents: t,
        chain,
        ..
    } = out;
    let m_full = &data.mass_matrix_full;
    // Φ and the tangents are sparse (column k is non-zero only on the full coordinates that
    // depend on q_k), so the products below run over those entries only.
    // ∂τ/∂q = Σ_d τ_full,d ∂²θ_d/∂q∂q + Φᵀ (D_θ Φ + D_θ̇ ∂θ̇/∂q + M_full ∂θ̈/∂q)
    sparse_chain(
        t,
        &[
            (dtau_dtheta, &t.phi),
            (dtau_dtheta_dot, &t.theta_dot_q),
            (m_full, &t.theta_ddot_q),
        ],
        chain,
    );
    dtau_dq.fill(0.0);
    t.add_weighted_hessian(model, &data.tau_full, dtau_dq);
    add_phi_transpose_times(t, chain, dtau_dq);
    // ∂τ/∂q̇ = Φᵀ (D_θ̇ Φ + M_full ∂(Φ̇q̇)/∂q̇)
    sparse_chain(
        t,
        &[(dtau_dtheta_dot, &t.phi), (m_full, &t.theta_ddot_qd)],
        chain,
    );
    dtau_dqd.fill(0.0);
    add_phi_transpose_times(t, chain, dtau_dqd);
    // ∂τ/∂q̈ = Φᵀ M_full Φ
    sparse_chain(t, &[(m_full, &t.phi)], chain);
    dtau_dqdd.fill(0.0);
    add_phi_transpose_times(t, chain, dtau_dqdd);
    super::rnea(model, data, q, qd, qdd)?;
    Ok(())
}

/// chain = Σ_pairs A B for n_full × n_full matrices A and n_full × n matrices B whose column k
/// is non-zero only on `t.full_of(k)`.
fn sparse_chain(
    t: &ReductionTangents,
    pairs: &[(&DMatrix<f64>, &DMatrix<f64>)],
    chain: &mut DMatrix<f64>,
) {
    for k in 0..chain.ncols() {
        let mut col = chain.column_mut(k);
        col.fill(0.0);
        for &d in t.full_of(k) {
            for (a, b) in pairs {
                let w = b[(d, k)];
                if w != 0.0 {
                    col.axpy(w, &a.column(d), 1.0);
                }
            }
        }
    }
}

/// out += Φᵀ chain (Φ's column j non-zero only on `t.full_of(j)`).
fn add_phi_transpose_times(t: &ReductionTangents, chain: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    for j in 0..out.nrows() {
        for &d in t.full_of(j) {
            let w = t.phi[(d, j)];
            for k in 0..out.ncols() {
                out[(j, k)] += w * chain[(d, k)];
            }
        }
    }
}

/// ∂τ_full/∂θ and ∂τ_full/∂θ̇ of [`super::rnea_full`] at (θ, θ̇, θ̈), gravity included, into
/// `out`; `data` is left as `rnea_full` leaves it.
pub fn rnea_derivatives_full(
    model: &Model,
    data: &mut Data,
    theta: &[f64],
    theta_dot: &[f64],
    theta_ddot: &[f64],
    out: &mut RneaDerivatives,
) -> crate::Result<()> {
    out.fits(model)?;
    super::rnea_full(model, data, theta, theta_dot, theta_ddot)?;
    let (nf, nb) = (model.dofs.len(), model.bodies.len());
    let Data {
        dof_motion: s,
        body_vel: v,
        body_acc: a,
        body_inertia: inertia,
        body_force: total,
        ..
    } = data;
    // The velocity after each coordinate and each body's own force f_b.
    for joint in &model.joints {
        let mut vd = v[joint.parent_body];
        for d in joint.dof_range.clone() {
            vd.add_scaled(&s[d], theta_dot[d]);
            out.dof_vel[d] = vd;
        }
    }
    out.own_force[0] = Force::ZERO;
    for b in 1..nb {
        let iv = inertia[b].mul_motion(&v[b]);
        out.own_force[b] = inertia[b].mul_motion(&a[b]).add(&v[b].cross_force(&iv));
    }
    let RneaDerivatives {
        dtau_dtheta,
        dtau_dtheta_dot,
        moves,
        dof_vel,
        d_vel,
        d_acc,
        d_force,
        d_axis,
        ..
    } = out;
    // Each direction moves only the subtree of its joint: the tangents are zero elsewhere,
    // and the bodies above see the subtree's δF unchanged. O(subtree + depth) per direction.
    dtau_dtheta.fill(0.0);
    dtau_dtheta_dot.fill(0.0);
    for j in 0..nf {
        let sj = s[j];
        let (body_moves, dof_moves) = (moves.bodies(j), moves.dofs(j));
        let joints = moves.subtree_joints(j);
        let own = &model.joints[model.dofs[j].joint];
        let top = own.child_body;

        // --- direction θ_j ---
        for &i in joints {
            for d in model.joints[i].dof_range.clone() {
                d_axis[d] = if dof_moves[d] {
                    sj.cross_motion(&s[d])
                } else {
                    Motion::ZERO
                };
            }
        }
        d_vel[own.parent_body] = Motion::ZERO;
        d_acc[own.parent_body] = Motion::ZERO;
        for &i in joints {
            let joint = &model.joints[i];
            let mut dv = d_vel[joint.parent_body];
            let mut da = d_acc[joint.parent_body];
            for d in joint.dof_range.clone() {
                dv.add_scaled(&d_axis[d], theta_dot[d]);
                // δ(v_d ×ₘ s_d) = δv_d ×ₘ s_d + v_d ×ₘ δs_d
                let dvs = dv
                    .cross_motion(&s[d])
                    .add(&dof_vel[d].cross_motion(&d_axis[d]));
                da.add_scaled(&d_axis[d], theta_ddot[d]);
                da.add_scaled(&dvs, theta_dot[d]);
            }
            d_vel[joint.child_body] = dv;
            d_acc[joint.child_body] = da;
        }
        body_force_tangents(
            model,
            joints,
            inertia,
            v,
            a,
            d_vel,
            d_acc,
            Some((&sj, body_moves)),
            d_force,
        );
        for &i in joints {
            for d in model.joints[i].dof_range.clone() {
                let b = model.dofs[d].body;
                dtau_dtheta[(d, j)] = d_axis[d].dot(&total[b]) + s[d].dot(&d_force[b]);
            }
        }
        for &d in moves.dofs_above(j) {
            dtau_dtheta[(d, j)] = s[d].dot(&d_force[top]);
        }

        // --- direction θ̇_j ---
        for &i in joints {
            let joint = &model.joints[i];
            let mut dv = d_vel[joint.parent_body];
            let mut da = d_acc[joint.parent_body];
            for d in joint.dof_range.clone() {
                if d == j {
                    dv = dv.add(&sj);
                    // ∂/∂θ̇_j of v_j ×ₘ s_j θ̇_j: v_j ×ₘ s_j (plus s_j ×ₘ s_j θ̇_j = 0)
                    da = da.add(&dof_vel[d].cross_motion(&s[d]));
                }
                da.add_scaled(&dv.cross_motion(&s[d]), theta_dot[d]);
            }
            d_vel[joint.child_body] = dv;
            d_acc[joint.child_body] = da;
        }
        body_force_tangents(model, joints, inertia, v, a, d_vel, d_acc, None, d_force);
        for &i in joints {
            for d in model.joints[i].dof_range.clone() {
                dtau_dtheta_dot[(d, j)] = s[d].dot(&d_force[model.dofs[d].body]);
            }
        }
        for &d in moves.dofs_above(j) {
            dtau_dtheta_dot[(d, j)] = s[d].dot(&d_force[top]);
        }
    }
    Ok(())
}

/// δF_b of the bodies of `joints` (a subtree, in tree order) from δv, δa, and for a position
/// direction the screw s_j with the bodies it moves (their inertias turn with it):
/// δf_b = δI_b a_b + I_b δa_b + δv_b ×* I_b v_b + v_b ×* (δI_b v_b + I_b δv_b), accumulated from
/// the leaves to the subtree's root body (the first joint's child).
#[allow(clippy::too_many_arguments)]
fn body_force_tangents(
    model: &Model,
    joints: &[usize],
    inertia: &[SpatialInertia],
    v: &[Motion],
    a: &[Motion],
    d_vel: &[Motion],
    d_acc: &[Motion],
    screw: Option<(&Motion, &[bool])>,
    d_force: &mut [Force],
) {
    for &jt in joints {
        let b = model.joints[jt].child_body;
        let i = &inertia[b];
        let iv = i.mul_motion(&v[b]);
        let mut f = i
            .mul_motion(&d_acc[b])
            .add(&d_vel[b].cross_force(&iv))
            .add(&v[b].cross_force(&i.mul_motion(&d_vel[b])));
        if let Some((sj, moves)) = screw {
            if moves[b] {
                // δI x = s_j ×* (I x) − I (s_j ×ₘ x)
                let d_i = |x: &Motion| {
                    let ix = i.mul_motion(x);
                    let turned = i.mul_motion(&sj.cross_motion(x));
                    let g = sj.cross_force(&ix);
                    Force {
                        ang: g.ang - turned.ang,
                        lin: g.lin - turned.lin,
                    }
                };
                f = f.add(&d_i(&a[b])).add(&v[b].cross_force(&d_i(&v[b])));
            }
        }
        d_force[b] = f;
    }
    for &jt in joints.iter().skip(1).rev() {
        let joint = &model.joints[jt];
        let f = d_force[joint.child_body];
        d_force[joint.parent_body].add_assign(&f);
    }
}
