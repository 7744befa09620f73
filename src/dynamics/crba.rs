//! Composite rigid body algorithm for the joint-space inertia matrix (Featherstone 2008,
//! §6.2), in ground axes, followed by the reduction M = Φᵀ M_full Φ.

use super::forward_kinematics::poses;
use super::reduction::evaluate_position;
use super::{Data, Stage, check_len};
use crate::model::Model;
use crate::model::reduction::NONE;
use nalgebra::DMatrix;

/// The joint-space inertia matrix M(q) (symmetric positive definite), n × n.
pub fn crba<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> crate::Result<&'d DMatrix<f64>> {
    data.fits(model)?;
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    data.stage = Stage::Position;
    composite_inertias(model, data);
    let cols = &model.reduction.columns;
    let n = model.nq();
    if data.mass_matrix.nrows() != n {
        data.mass_matrix = DMatrix::zeros(n, n); // the first call: allocated once
    }
    let Data {
        composite,
        col_motion,
        mass_matrix,
        ..
    } = data;
    let mm = mass_matrix.as_mut_slice(); // column-major: (i, j) at i + j n
    mm.fill(0.0);
    for c in 0..cols.len() {
        // F = I^c_body(c) S̃_c ;  M[q_c][q_e] += S̃_eᵀ F for e = c and every column e towards
        // ground (and the transposed entry for e ≠ c).
        let f = composite[cols.body[c]].mul_motion(&col_motion[c]);
        let j = cols.q[c];
        let v = col_motion[c].dot(&f);
        mm[j + j * n] += v;
        let mut e = cols.parent[c];
        while e != NONE {
            let k = cols.q[e];
            let v = col_motion[e].dot(&f);
            mm[j + k * n] += v;
            mm[k + j * n] += v;
            e = cols.parent[e];
        }
    }
    Ok(&data.mass_matrix)
}

/// M_full(θ), the inertia matrix of the full coordinates, at the state of the last forward
/// kinematics (position stage or
/// [`super::forward_kinematics_full`]).
pub fn crba_full<'d>(model: &Model, data: &'d mut Data) -> crate::Result<&'d DMatrix<f64>> {
    data.require(model, Stage::Position, "crba_full")?;
    composite_inertias(model, data);
    let nf = model.n_full();
    if data.mass_matrix_full.nrows() != nf {
        data.mass_matrix_full = DMatrix::zeros(nf, nf); // the first call: allocated once
    }
    let Data {
        composite,
        dof_motion,
        mass_matrix_full,
        ..
    } = data;
    mass_matrix_full.as_mut_slice().fill(0.0);
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
