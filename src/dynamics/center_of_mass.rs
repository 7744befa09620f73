//! Centre of mass of the whole model and its Jacobian.

use super::{Data, Stage};
use crate::model::Model;
use crate::spatial::Vec3;
use nalgebra::DMatrix;

/// Centre of mass in ground (position stage).
pub fn center_of_mass(model: &Model, data: &Data) -> crate::Result<Vec3> {
    data.require(model, Stage::Position, "center_of_mass")?;
    let mut m = 0.0;
    let mut h = Vec3::zeros();
    for b in 1..model.bodies.len() {
        m += data.body_inertia[b].mass;
        h += data.body_inertia[b].h;
    }
    if m <= 0.0 {
        return Err(crate::Error::invalid("model", "the model has no mass"));
    }
    Ok(h / m + data.reference_point)
}

/// J_com (3 × n), with ċ = J_com q̇ (position stage): column j sums, over the reduced
/// columns c of q_j, (m_sub S̃_lin + S̃_ang × h_sub) / m_total for the subtree c moves.
pub fn center_of_mass_jacobian(
    model: &Model,
    data: &mut Data,
    out: &mut DMatrix<f64>,
) -> crate::Result<()> {
    data.require(model, Stage::Position, "center_of_mass_jacobian")?;
    let n = model.nq();
    if out.shape() != (3, n) {
        return Err(crate::Error::invalid(
            "out",
            format!("must be 3 × {n}, is {:?}", out.shape()),
        ));
    }
    let total = model.total_mass();
    if total <= 0.0 {
        return Err(crate::Error::invalid("model", "the model has no mass"));
    }
    super::crba::composite_inertias(model, data);
    let cols = &model.reduction.columns;
    out.as_mut_slice().fill(0.0);
    for c in 0..cols.len() {
        let sub = &data.composite[cols.body[c]];
        let s = &data.col_motion[c];
        let col = (s.lin * sub.mass + s.ang.cross(&sub.h)) / total;
        for i in 0..3 {
            out[(i, cols.q[c])] += col[i];
        }
    }
    Ok(())
}
