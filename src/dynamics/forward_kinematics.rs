//! Forward kinematics: body poses, motion subspaces, spatial inertias, velocities and
//! accelerations, in ground axes about the reference point O.

use super::reduction::{evaluate_position, evaluate_velocity, theta_acceleration};
use super::{Data, Stage, check_len};
use crate::model::{DofKind, JointStep, Model};
use crate::spatial::{Mat3, Motion, SpatialInertia, Vec3, post_rotate};

/// Position stage at the independent coordinates `q`: coordinate values, θ, Φ, body poses,
/// motion subspaces and spatial inertias.
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) -> crate::Result<()> {
    data.fits(model)?;
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    data.stage = Stage::Position;
    Ok(())
}

/// Velocity stage: also θ̇, Φ̇q̇ and body spatial velocities.
pub fn forward_kinematics_velocity(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
) -> crate::Result<()> {
    check_len("qd", qd, model.nq())?;
    forward_kinematics(model, data, q)?;
    evaluate_velocity(model, data, qd);
    velocities(model, data);
    data.stage = Stage::Velocity;
    Ok(())
}

/// Acceleration stage: also θ̈ = Φq̈ + Φ̇q̇ and body spatial accelerations (without gravity).
pub fn forward_kinematics_acceleration(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> crate::Result<()> {
    check_len("qdd", qdd, model.nq())?;
    forward_kinematics_velocity(model, data, q, qd)?;
    theta_acceleration(model, data, Some(qdd));
    let Data {
        dof_motion,
        body_vel,
        node_vel,
        theta_acc,
        body_acc,
        ..
    } = data;
    let nc = model.reduction.n_coordinates;
    propagate_accelerations(
        model,
        dof_motion,
        body_vel,
        &node_vel[nc..],
        theta_acc,
        Motion::ZERO,
        body_acc,
    );
    data.stage = Stage::Acceleration;
    Ok(())
}

/// Position and velocity stages from the full coordinates θ and θ̇ directly (one value per
/// movable axis, the coordinates MuJoCo sees in the expanded tree). Coordinates, Φ and the
/// reduced algorithms are not available after this call; use [`super::crba_full`] and
/// [`super::rnea_full`].
pub fn forward_kinematics_full(
    model: &Model,
    data: &mut Data,
    theta: &[f64],
    theta_dot: &[f64],
) -> crate::Result<()> {
    data.fits(model)?;
    let nf = model.n_full();
    check_len("theta", theta, nf)?;
    check_len("theta_dot", theta_dot, nf)?;
    let nc = model.reduction.n_coordinates;
    data.node_value[..nc].fill(f64::NAN);
    data.node_value[nc..].copy_from_slice(theta);
    data.node_vel[nc..].copy_from_slice(theta_dot);
    data.node_acc_bias[nc..].fill(0.0);
    data.node_grad.fill(f64::NAN);
    poses(model, data);
    velocities(model, data);
    data.stage = Stage::Velocity;
    Ok(())
}

/// Body poses from θ; then O, the motion subspaces s_d and the spatial inertias.
pub(crate) fn poses(model: &Model, data: &mut Data) {
    body_poses(model, data);
    motion_subspaces(model, data);
    spatial_inertias(model, data);
}

/// Body poses only (no motion subspaces, no spatial inertias), for solvers that evaluate
/// many trial points ([`motion_subspaces`] completes a pose when needed); leaves `data` at
/// `Stage::None`, so that no algorithm takes it for a full position stage.
pub(crate) fn body_poses_only(model: &Model, data: &mut Data, q: &[f64]) -> crate::Result<()> {
    data.fits(model)?;
    check_len("q", q, model.nq())?;
    evaluate_position(model, data, q);
    data.stage = Stage::None;
    body_poses(model, data);
    Ok(())
}

/// X_GB of every body from θ (in the nodes), and the reference point O.
fn body_poses(model: &Model, data: &mut Data) {
    let nc = model.reduction.n_coordinates;
    data.body_acc_bias_valid = false;
    data.body_rot[0] = Mat3::identity();
    data.body_pos[0] = Vec3::zeros();
    for joint in &model.joints {
        let p = joint.parent_body;
        // X_GF = X_GP · X_PF
        let x = &joint.parent_offset;
        let mut rot = if x.rot == Mat3::identity() {
            data.body_rot[p]
        } else {
            data.body_rot[p] * x.rot
        };
        let mut pos = data.body_rot[p] * x.pos + data.body_pos[p];
        for step in &joint.steps {
            match step {
                JointStep::Fixed(x) => {
                    pos += rot * x.pos;
                    rot *= x.rot;
                }
                JointStep::Dof(d) => {
                    let dof = &model.dofs[*d];
                    let th = data.node_value[nc + d];
                    let elementary = dof.elementary_axis();
                    let axis_w = match elementary {
                        Some((k, sign)) => rot.column(k) * sign,
                        None => rot * dof.axis,
                    };
                    data.dof_axis[*d] = axis_w;
                    data.dof_point[*d] = pos;
                    match dof.kind {
                        // translation along the axis of the preceding frame
                        DofKind::Slide => pos += axis_w * th,
                        // body-fixed rotation: R ← R · R(axis, θ)
                        DofKind::Hinge => post_rotate(&mut rot, &dof.axis, elementary, th),
                    }
                }
            }
        }
        // X_GB = X_GM · X_MB
        let c = joint.child_body;
        let x = &joint.child_offset_inv;
        data.body_pos[c] = rot * x.pos + pos;
        data.body_rot[c] = if x.rot == Mat3::identity() {
            rot
        } else {
            rot * x.rot
        };
    }
    // O: the origin of the first moving body keeps spatial quantities well conditioned.
    let o = if model.bodies.len() > 1 {
        data.body_pos[1]
    } else {
        Vec3::zeros()
    };
    data.reference_point = o;
}

/// The motion subspaces s_d of the full coordinates and S̃_c of the reduced columns, in ground
/// axes about O, from the body poses.
pub(crate) fn motion_subspaces(model: &Model, data: &mut Data) {
    let o = data.reference_point;
    for (d, dof) in model.dofs.iter().enumerate() {
        let w = data.dof_axis[d];
        data.dof_motion[d] = match dof.kind {
            // a rotation about w through p moves the point at O with (p − O) × w
            DofKind::Hinge => Motion::new(w, (data.dof_point[d] - o).cross(&w)),
            DofKind::Slide => Motion::new(Vec3::zeros(), w),
        };
    }
    // S̃_c = Σ_d Φ_dj s_d
    let cols = &model.reduction.columns;
    for c in 0..cols.len() {
        let mut m = Motion::ZERO;
        for &(d, e) in &cols.terms[cols.start[c]..cols.start[c + 1]] {
            m.add_scaled(&data.dof_motion[d], data.node_grad[e]);
        }
        data.col_motion[c] = m;
    }
}

/// Every body's spatial inertia about O, from the body poses.
fn spatial_inertias(model: &Model, data: &mut Data) {
    let o = data.reference_point;
    for (b, body) in model.bodies.iter().enumerate().skip(1) {
        let r = &data.body_rot[b];
        let c = r * body.com_in_body + data.body_pos[b] - o;
        let i_com = r * body.inertia_about_com * r.transpose();
        data.body_inertia[b] = SpatialInertia::from_mass_com_inertia(body.mass, &c, &i_com);
    }
}

/// Body velocities from θ̇ in the nodes.
pub(crate) fn velocities(model: &Model, data: &mut Data) {
    let nc = model.reduction.n_coordinates;
    let Data {
        dof_motion,
        node_vel,
        body_vel,
        ..
    } = data;
    velocities_into(model, dof_motion, &node_vel[nc..], body_vel);
}

/// v_child = v_parent + Σ_{d ∈ joint} s_d θ̇_d.
pub(crate) fn velocities_into(
    model: &Model,
    dof_motion: &[Motion],
    theta_dot: &[f64],
    body_vel: &mut [Motion],
) {
    body_vel[0] = Motion::ZERO;
    for joint in &model.joints {
        let mut v = body_vel[joint.parent_body];
        for d in joint.dof_range.clone() {
            v.add_scaled(&dof_motion[d], theta_dot[d]);
        }
        body_vel[joint.child_body] = v;
    }
}

/// Spatial accelerations a_child = a_parent + Σ_d (s_d θ̈_d + v_d ×ₘ s_d θ̇_d), starting from
/// `a0` for ground (−g for inverse dynamics with gravity).
pub(crate) fn propagate_accelerations(
    model: &Model,
    dof_motion: &[Motion],
    body_vel: &[Motion],
    theta_dot: &[f64],
    theta_acc: &[f64],
    a0: Motion,
    out: &mut [Motion],
) {
    out[0] = a0;
    for joint in &model.joints {
        let mut v = body_vel[joint.parent_body];
        let mut a = out[joint.parent_body];
        for d in joint.dof_range.clone() {
            let sd = dof_motion[d].scale(theta_dot[d]);
            v = v.add(&sd);
            a = a
                .add(&dof_motion[d].scale(theta_acc[d]))
                .add(&v.cross_motion(&sd));
        }
        out[joint.child_body] = a;
    }
}
