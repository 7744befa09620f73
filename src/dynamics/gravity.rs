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
pub fn gravity<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &[f64],
) -> crate::Result<&'d DVector<f64>> {
    data.fits(model)?;
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    data.stage = Stage::Position;
    composite_inertias(model, data);
    let cols = &model.reduction.columns;
    let Data {
        composite,
        col_motion,
        gravity,
        ..
    } = data;
    gravity.as_mut_slice().fill(0.0);
    for c in 0..cols.len() {
        // Σ_{b ⊂ subtree} m_b ∂c_b/∂q_j = m_sub S̃_lin + S̃_ang × h_sub  (h about O)
        let sub = &composite[cols.body[c]];
        let s = &col_motion[c];
        gravity[cols.q[c]] -= model.gravity.dot(&(s.lin * sub.mass + s.ang.cross(&sub.h)));
    }
    Ok(&data.gravity)
}
