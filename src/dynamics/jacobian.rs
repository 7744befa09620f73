//! Point, body and contact Jacobians and their J̇q̇ products.
//!
//! Column j of a Jacobian sums the reduced motion subspace columns S̃_c = Σ_d Φ_dj s_d of q_j
//! on the path from ground to the body (J = J_full Φ).
//! J̇q̇ is the acceleration the body or point has when q̈ = 0 and gravity is off.

use super::forward_kinematics::propagate_accelerations;
use super::{Data, Stage, point_acceleration_from};
use crate::model::Model;
use crate::model::reduction::NONE;
use crate::spatial::{Motion, Vec3};
use nalgebra::DMatrix;

fn check_body(model: &Model, body: usize) -> crate::Result<()> {
    if body >= model.bodies.len() {
        return Err(crate::Error::invalid(
            "body",
            format!("index {body} out of range ({} bodies)", model.bodies.len()),
        ));
    }
    Ok(())
}

fn check_shape(out: &DMatrix<f64>, rows: usize, n: usize) -> crate::Result<()> {
    if out.shape() != (rows, n) {
        return Err(crate::Error::invalid(
            "out",
            format!("must be {rows} × {n}, is {:?}", out.shape()),
        ));
    }
    Ok(())
}

/// Adds `f(S̃_c)` into rows `row0..` of column q_c of `out`, for every reduced column c on
/// the path from ground to `body`.
fn accumulate<const R: usize>(
    model: &Model,
    data: &Data,
    body: usize,
    out: &mut DMatrix<f64>,
    row0: usize,
    f: impl Fn(&Motion) -> [f64; R],
) {
    let cols = &model.reduction.columns;
    let mut c = cols.body_last[body];
    while c != NONE {
        let col = f(&data.col_motion[c]);
        let j = cols.q[c];
        for (i, v) in col.iter().enumerate() {
            out[(row0 + i, j)] += v;
        }
        c = cols.parent[c];
    }
}

fn require_reduced(model: &Model, data: &Data, algorithm: &'static str) -> crate::Result<()> {
    data.require(model, Stage::Position, algorithm)?;
    if data.node_grad.first().is_some_and(|g| g.is_nan()) {
        return Err(crate::Error::StageNotComputed {
            algorithm,
            needs: "forward_kinematics (not forward_kinematics_full)",
        });
    }
    Ok(())
}

/// J (3 × n) of a point fixed in `body` (`point` in body coordinates): ṗ = J q̇.
pub fn point_jacobian(
    model: &Model,
    data: &Data,
    body: usize,
    point: &Vec3,
    out: &mut DMatrix<f64>,
) -> crate::Result<()> {
    require_reduced(model, data, "point_jacobian")?;
    check_body(model, body)?;
    check_shape(out, 3, model.nq())?;
    out.as_mut_slice().fill(0.0);
    let off = data.point_position(body, point) - data.reference_point;
    accumulate(model, data, body, out, 0, |s| {
        let v = s.linear_at(&off);
        [v.x, v.y, v.z]
    });
    Ok(())
}

/// The full-coordinate body Jacobian J_full (6 × n_full; rows as in [`body_jacobian`]):
/// column d is the motion subspace s_d, taken at the body origin, of every full coordinate
/// on the path from ground to the body. Valid after any forward kinematics, including
/// [`super::forward_kinematics_full`].
pub fn body_jacobian_full(
    model: &Model,
    data: &Data,
    body: usize,
    out: &mut DMatrix<f64>,
) -> crate::Result<()> {
    data.require(model, Stage::Position, "body_jacobian_full")?;
    check_body(model, body)?;
    check_shape(out, 6, model.n_full())?;
    out.as_mut_slice().fill(0.0);
    let off = data.body_pos[body] - data.reference_point;
    let mut b = body;
    let mut last = None;
    while let Some(j) = model.bodies[b].joint {
        let r = &model.joints[j].dof_range;
        if !r.is_empty() {
            last = Some(r.end - 1);
            break;
        }
        b = model.joints[j].parent_body;
    }
    while let Some(d) = last {
        let s = &data.dof_motion[d];
        let v = s.linear_at(&off);
        for i in 0..3 {
            out[(i, d)] = s.ang[i];
            out[(3 + i, d)] = v[i];
        }
        last = model.dofs[d].parent_dof;
    }
    Ok(())
}

/// J (6 × n) of a body: rows 0–2 map q̇ to its angular velocity, rows 3–5 to the velocity
/// of its origin, both in ground axes.
pub fn body_jacobian(
    model: &Model,
    data: &Data,
    body: usize,
    out: &mut DMatrix<f64>,
) -> crate::Result<()> {
    require_reduced(model, data, "body_jacobian")?;
    check_body(model, body)?;
    check_shape(out, 6, model.nq())?;
    out.as_mut_slice().fill(0.0);
    let off = data.body_pos[body] - data.reference_point;
    accumulate(model, data, body, out, 0, |s| {
        let v = s.linear_at(&off);
        [s.ang.x, s.ang.y, s.ang.z, v.x, v.y, v.z]
    });
    Ok(())
}

/// The contact Jacobian J_c (3k × n) of k body-fixed points: rows 3i..3i+3 map q̇ to the
/// velocity of point i in ground.
pub fn contact_jacobian(
    model: &Model,
    data: &Data,
    points: &[(usize, Vec3)],
    out: &mut DMatrix<f64>,
) -> crate::Result<()> {
    require_reduced(model, data, "contact_jacobian")?;
    check_shape(out, 3 * points.len(), model.nq())?;
    out.as_mut_slice().fill(0.0);
    for (i, (body, p)) in points.iter().enumerate() {
        check_body(model, *body)?;
        let off = data.point_position(*body, p) - data.reference_point;
        accumulate(model, data, *body, out, 3 * i, |s| {
            let v = s.linear_at(&off);
            [v.x, v.y, v.z]
        });
    }
    Ok(())
}

/// Spatial accelerations with q̈ = 0 and no gravity (needs the velocity stage).
fn ensure_bias_accelerations(
    model: &Model,
    data: &mut Data,
    algorithm: &'static str,
) -> crate::Result<()> {
    data.require(model, Stage::Velocity, algorithm)?;
    if !data.body_acc_bias_valid {
        let nc = model.reduction.n_coordinates;
        let Data {
            dof_motion,
            body_vel,
            node_vel,
            node_acc_bias,
            body_acc_bias,
            ..
        } = data;
        // θ̈ = Φ̇q̇ when q̈ = 0
        propagate_accelerations(
            model,
            dof_motion,
            body_vel,
            &node_vel[nc..],
            &node_acc_bias[nc..],
            Motion::ZERO,
            body_acc_bias,
        );
        data.body_acc_bias_valid = true;
    }
    Ok(())
}

/// J̇q̇ of a body-fixed point: its acceleration when q̈ = 0 (velocity stage).
pub fn point_jacobian_dot_qd(
    model: &Model,
    data: &mut Data,
    body: usize,
    point: &Vec3,
) -> crate::Result<Vec3> {
    check_body(model, body)?;
    ensure_bias_accelerations(model, data, "point_jacobian_dot_qd")?;
    let off = data.point_position(body, point) - data.reference_point;
    Ok(point_acceleration_from(&data.body_vel[body], &data.body_acc_bias[body], off).1)
}

/// J̇q̇ of a body: (angular acceleration, acceleration of the origin) when q̈ = 0.
pub fn body_jacobian_dot_qd(
    model: &Model,
    data: &mut Data,
    body: usize,
) -> crate::Result<(Vec3, Vec3)> {
    check_body(model, body)?;
    ensure_bias_accelerations(model, data, "body_jacobian_dot_qd")?;
    let off = data.body_pos[body] - data.reference_point;
    Ok(point_acceleration_from(
        &data.body_vel[body],
        &data.body_acc_bias[body],
        off,
    ))
}

/// J̇_c q̇ (3k) of k body-fixed points.
pub fn contact_jacobian_dot_qd(
    model: &Model,
    data: &mut Data,
    points: &[(usize, Vec3)],
    out: &mut [f64],
) -> crate::Result<()> {
    if out.len() != 3 * points.len() {
        return Err(crate::Error::invalid(
            "out",
            format!("needs length {}, has {}", 3 * points.len(), out.len()),
        ));
    }
    for (i, (body, p)) in points.iter().enumerate() {
        let a = point_jacobian_dot_qd(model, data, *body, p)?;
        out[3 * i..3 * i + 3].copy_from_slice(a.as_slice());
    }
    Ok(())
}
