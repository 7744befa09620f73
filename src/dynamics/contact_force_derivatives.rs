//! The generalized forces of point forces, Q(q) = J_c(q)ᵀ λ, and their derivative ∂Q/∂q with
//! the forces λ held fixed in ground (what the q-gradient of a residual M q̈ + C q̇ + G − τ −
//! J_cᵀ λ needs).
//!
//! Force i acts at p_i = c_i + g_i: c_i a point fixed in body b_i (the carrier) and g_i an
//! offset fixed in ground. With g_i = 0 it is a force on a body-fixed point; with c_i a contact
//! sphere's centre and g_i = −r n its lowest point (a sphere rolling on the floor n·x = h is
//! loaded there whatever its orientation). In full coordinates, with every spatial quantity in
//! ground axes about the fixed point O, force i is the spatial force
//! f_i = ((p_i − O) × λ_i, λ_i), and Q_full,d = s_dᵀ F_d with F_d the sum of the f_i on the
//! subtree moved by axis d. A change ε of θ_j moves the axes and carriers beyond j by the
//! screw ε s_j (see [`super::rnea_derivatives`]):
//!
//! ```text
//! δs_d = s_j ×ₘ s_d,   δp_i = δc_i = s_j,lin + s_j,ang × (c_i − O),   δf_i = (δp_i × λ_i, 0)
//! ∂Q_full,d/∂θ_j = δs_dᵀ F_d + s_dᵀ δF_d
//! ```
//!
//! and in the independent coordinates (Q = Φᵀ Q_full):
//! ∂Q/∂q = Σ_d Q_full,d ∂²θ_d/∂q∂q + Φᵀ (∂Q_full/∂θ) Φ.

use super::Data;
use super::reduction::{ReductionTangents, evaluate_velocity};
use super::rnea_derivatives::MovedBy;
use crate::model::Model;
use crate::spatial::{Force, Motion, Vec3};
use nalgebra::{DMatrix, DVector, DVectorView};

/// The outputs and workspace of [`contact_force_derivatives`] for one model.
#[derive(Clone, Debug)]
pub struct ContactForceDerivatives {
    /// Q = J_cᵀ λ (n).
    pub generalized_force: DVector<f64>,
    /// ∂Q/∂q (n × n).
    pub dq: DMatrix<f64>,
    /// ∂Q_full/∂θ (n_full × n_full).
    pub dtheta: DMatrix<f64>,
    moves: MovedBy,
    tangents: ReductionTangents,
    chain: DMatrix<f64>,
    q_full: Vec<f64>,
    zeros: Vec<f64>,
    /// Per body: the sum of its own point forces, then of its subtree's.
    body_force: Vec<Force>,
    d_force: Vec<Force>,
}

impl ContactForceDerivatives {
    /// Allocates the outputs and workspace for `model`.
    pub fn new(model: &Model) -> ContactForceDerivatives {
        let (n, nf, nb) = (model.nq(), model.n_full(), model.bodies.len());
        ContactForceDerivatives {
            generalized_force: DVector::zeros(n),
            dq: DMatrix::zeros(n, n),
            dtheta: DMatrix::zeros(nf, nf),
            moves: MovedBy::new(model),
            tangents: ReductionTangents::new(model),
            chain: DMatrix::zeros(nf, n),
            q_full: vec![0.0; nf],
            zeros: vec![0.0; n],
            body_force: vec![Force::ZERO; nb],
            d_force: vec![Force::ZERO; nb],
        }
    }
}

/// Q = J_c(q)ᵀ λ and ∂Q/∂q for forces `forces[i]` (ground axes, N) applied at c_i + g_i, with
/// the carriers `points[i]` = (body, location in body) and the ground offsets
/// `offsets_in_ground[i]` (m; an empty slice means none), into `out`; `data` is left at the
/// position stage of q.
pub fn contact_force_derivatives(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    points: &[(usize, Vec3)],
    offsets_in_ground: &[Vec3],
    forces: &[Vec3],
    out: &mut ContactForceDerivatives,
) -> crate::Result<()> {
    let (n, nf, nb) = (model.nq(), model.n_full(), model.bodies.len());
    if out.dq.nrows() != n || out.dtheta.nrows() != nf || out.body_force.len() != nb {
        return Err(crate::Error::invalid(
            "derivatives",
            "ContactForceDerivatives was built for another model",
        ));
    }
    if points.len() != forces.len() {
        return Err(crate::Error::invalid(
            "forces",
            format!("{} forces for {} points", forces.len(), points.len()),
        ));
    }
    if !(offsets_in_ground.is_empty() || offsets_in_ground.len() == points.len()) {
        return Err(crate::Error::invalid(
            "offsets_in_ground",
            format!(
                "{} offsets for {} points (give one per point, or none)",
                offsets_in_ground.len(),
                points.len()
            ),
        ));
    }
    let offset = |i: usize| {
        offsets_in_ground
            .get(i)
            .copied()
            .unwrap_or_else(Vec3::zeros)
    };
    for (i, ((body, p), f)) in points.iter().zip(forces).enumerate() {
        if *body >= nb {
            return Err(crate::Error::invalid(
                "points",
                format!("point {i}: body index {body} out of range ({nb} bodies)"),
            ));
        }
        let g = offset(i);
        if !(p.iter().chain(f.iter()).chain(g.iter())).all(|v| v.is_finite()) {
            return Err(crate::Error::invalid(
                "forces",
                format!("point {i}: location, offset or force is not finite"),
            ));
        }
    }
    super::forward_kinematics(model, data, q)?;
    evaluate_velocity(model, data, &out.zeros);
    out.tangents.compute(model, data, &out.zeros);
    let ContactForceDerivatives {
        generalized_force,
        dq,
        dtheta,
        moves,
        tangents,
        chain,
        q_full,
        body_force,
        d_force,
        ..
    } = out;
    let o = data.reference_point;
    let s = &data.dof_motion;
    // f_i = ((p_i − O) × λ_i, λ_i), summed per body and then over subtrees
    body_force.fill(Force::ZERO);
    for (i, ((body, p), f)) in points.iter().zip(forces).enumerate() {
        let r = data.point_position(*body, p) + offset(i) - o;
        body_force[*body].add_assign(&Force {
            ang: r.cross(f),
            lin: *f,
        });
    }
    accumulate_subtrees(model, body_force);
    // Q_full,d = s_dᵀ F_d
    for (d, dof) in model.dofs.iter().enumerate() {
        q_full[d] = s[d].dot(&body_force[dof.body]);
    }
    for j in 0..nf {
        let sj = s[j];
        let (body_moves, dof_moves) = (moves.bodies(j), moves.dofs(j));
        // δf_i = (δp_i × λ_i, 0) for points on bodies that move with θ_j
        d_force.fill(Force::ZERO);
        for ((body, p), f) in points.iter().zip(forces) {
            if body_moves[*body] {
                let dp = sj.linear_at(&(data.point_position(*body, p) - o));
                d_force[*body].add_assign(&Force {
                    ang: dp.cross(f),
                    lin: Vec3::zeros(),
                });
            }
        }
        accumulate_subtrees(model, d_force);
        // ∂Q_full,d/∂θ_j = δs_dᵀ F_d + s_dᵀ δF_d
        for (d, dof) in model.dofs.iter().enumerate() {
            let mut v = s[d].dot(&d_force[dof.body]);
            if dof_moves[d] {
                let ds: Motion = sj.cross_motion(&s[d]);
                v += ds.dot(&body_force[dof.body]);
            }
            dtheta[(d, j)] = v;
        }
    }
    // Q = Φᵀ Q_full;  ∂Q/∂q = Σ_d Q_full,d ∂²θ_d/∂q∂q + Φᵀ (∂Q_full/∂θ) Φ
    generalized_force.gemv_tr(
        1.0,
        &tangents.phi,
        &DVectorView::from_slice(q_full, nf),
        0.0,
    );
    dq.fill(0.0);
    tangents.add_weighted_hessian(model, q_full, dq);
    chain.gemm(1.0, dtheta, &tangents.phi, 0.0);
    dq.gemm_tr(1.0, &tangents.phi, chain, 1.0);
    Ok(())
}

/// F_parent += F_child, from the leaves to the root.
fn accumulate_subtrees(model: &Model, force: &mut [Force]) {
    for joint in model.joints.iter().rev() {
        if joint.parent_body != 0 {
            let f = force[joint.child_body];
            force[joint.parent_body].add_assign(&f);
        }
    }
}
