//! Generalized gravity forces from the centre-of-mass Jacobian:
//!   G(q) = ∂V/∂q = −(Σ_b m_b ∂c_b/∂q)ᵀ g = −m_total J_comᵀ g,
//! an algorithm independent of inverse dynamics (G must equal τ(q, 0, 0)).

use super::crba::composite_inertias;
use super::forward_kinematics::poses;
use super::reduction::evaluate_position;
use super::{Data, Stage, check_len};
use crate::model::Model;
use nalgebra::DVector;

/// The gravity term G(q) of M q̈ + C q̇ + G = τ (the generalized force gravity exerts is −G).
pub fn gravity<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> crate::Result<&'d DVector<f64>> {
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    data.stage = Stage::Position;
    composite_inertias(model, data);
    let r = &model.reduction;
    let Data { composite, dof_motion, gravity, node_grad, .. } = data;
    gravity.fill(0.0);
    for (d, dof) in model.dofs.iter().enumerate() {
        // Σ_{b ⊂ subtree(d)} m_b ∂c_b/∂θ_d = m_sub s_lin + s_ang × h_sub  (h about O)
        let sub = &composite[dof.body];
        let s = &dof_motion[d];
        let dmc = s.lin * sub.mass + s.ang.cross(&sub.h);
        let g_full = -model.gravity.dot(&dmc);
        for e in r.phi_row(d) {
            gravity[r.dep_index[e]] += node_grad[e] * g_full;
        }
    }
    Ok(&data.gravity)
}
