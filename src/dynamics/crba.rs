//! Composite rigid body algorithm for the joint-space inertia matrix (Featherstone 2008,
//! §6.2), in ground axes, followed by the reduction M = Φᵀ M_full Φ.

use super::forward_kinematics::poses;
use super::reduction::evaluate_position;
use super::{Data, Stage, check_len};
use crate::model::Model;
use nalgebra::DMatrix;

/// The joint-space inertia matrix M(q) (symmetric positive definite), n × n. The
/// full-coordinate matrix M_full is left in `Data::mass_matrix_full`.
pub fn crba<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> crate::Result<&'d DMatrix<f64>> {
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    data.stage = Stage::Position;
    composite_inertias(model, data);
    let r = &model.reduction;
    let Data { composite, dof_motion, mass_matrix_full, mass_matrix, node_grad, .. } = data;
    mass_matrix.fill(0.0);
    for (d, dof) in model.dofs.iter().enumerate() {
        // F = I^c_body(d) s_d ;  M_de = s_eᵀ F for e = d and every ancestor e of d.
        let f = composite[dof.body].mul_motion(&dof_motion[d]);
        let mut e = Some(d);
        while let Some(ei) = e {
            let m = dof_motion[ei].dot(&f);
            mass_matrix_full[(d, ei)] = m;
            mass_matrix_full[(ei, d)] = m;
            // M += Φ_dᵀ m Φ_e (+ the transposed term for d ≠ e)
            for pd in r.phi_row(d) {
                let (j, a) = (r.dep_index[pd], node_grad[pd] * m);
                for pe in r.phi_row(ei) {
                    let (k, ab) = (r.dep_index[pe], a * node_grad[pe]);
                    mass_matrix[(j, k)] += ab;
                    if ei != d {
                        mass_matrix[(k, j)] += ab;
                    }
                }
            }
            e = model.dofs[ei].parent_dof;
        }
    }
    Ok(&data.mass_matrix)
}

/// M_full(θ) at the full coordinates of the last forward kinematics (position stage or
/// [`super::forward_kinematics_full`]).
pub fn crba_full<'d>(model: &Model, data: &'d mut Data) -> crate::Result<&'d DMatrix<f64>> {
    data.require(Stage::Position, "crba_full")?;
    composite_inertias(model, data);
    let Data { composite, dof_motion, mass_matrix_full, .. } = data;
    mass_matrix_full.fill(0.0);
    for (d, dof) in model.dofs.iter().enumerate() {
        let f = composite[dof.body].mul_motion(&dof_motion[d]);
        let mut e = Some(d);
        while let Some(ei) = e {
            let m = dof_motion[ei].dot(&f);
            mass_matrix_full[(d, ei)] = m;
            mass_matrix_full[(ei, d)] = m;
            e = model.dofs[ei].parent_dof;
        }
    }
    Ok(&data.mass_matrix_full)
}

/// I^c_i = I_i + Σ_children I^c_child (ground axes: a plain sum).
pub(crate) fn composite_inertias(model: &Model, data: &mut Data) {
    data.composite.copy_from_slice(&data.body_inertia);
    for joint in model.joints.iter().rev() {
        if joint.parent_body != 0 {
            let c = data.composite[joint.child_body];
            data.composite[joint.parent_body].add_assign(&c);
        }
    }
}
