//! Recursive Newton–Euler inverse dynamics (Featherstone 2008, §5.3), in ground axes.

use super::forward_kinematics::{poses, propagate_accelerations};
use super::reduction::{evaluate_position, evaluate_velocity, theta_acceleration};
use super::{Data, Stage, check_len};
use crate::model::Model;
use crate::spatial::{Force, Motion};
use nalgebra::DVector;

/// Which reduced vector an RNEA pass writes.
#[derive(Clone, Copy)]
enum Target {
    Tau,
    Bias,
    Coriolis,
}

/// Inverse dynamics τ = M(q) q̈ + C(q, q̇) q̇ + G(q): the generalized forces that produce q̈.
pub fn rnea<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> crate::Result<&'d DVector<f64>> {
    check_len("qdd", qdd, model.nq())?;
    reduced_pass(model, data, q, qd, Some(qdd), true, Target::Tau)?;
    Ok(&data.tau)
}

/// The bias forces C(q, q̇) q̇ + G(q) = τ(q, q̇, 0).
pub fn nonlinear_effects<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &[f64],
    qd: &[f64],
) -> crate::Result<&'d DVector<f64>> {
    reduced_pass(model, data, q, qd, None, true, Target::Bias)?;
    Ok(&data.bias)
}

/// Coriolis and centrifugal forces C(q, q̇) q̇ (with the Φ̇q̇ terms of coupled coordinates).
pub fn coriolis<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &[f64],
    qd: &[f64],
) -> crate::Result<&'d DVector<f64>> {
    reduced_pass(model, data, q, qd, None, false, Target::Coriolis)?;
    Ok(&data.coriolis)
}

/// Inverse dynamics in full coordinates: τ_full = M_full θ̈ + bias_full(θ, θ̇), one value
/// per movable axis (MuJoCo's qfrc_inverse of the expanded tree).
pub fn rnea_full<'d>(
    model: &Model,
    data: &'d mut Data,
    theta: &[f64],
    theta_dot: &[f64],
    theta_ddot: &[f64],
) -> crate::Result<&'d [f64]> {
    check_len("theta_ddot", theta_ddot, model.n_full())?;
    super::forward_kinematics_full(model, data, theta, theta_dot)?;
    data.theta_acc.copy_from_slice(theta_ddot);
    body_forces(model, data, true);
    // τ_full,d = s_dᵀ f_body(d)
    let Data {
        tau_full,
        dof_motion,
        body_force,
        ..
    } = data;
    for (d, dof) in model.dofs.iter().enumerate() {
        tau_full[d] = dof_motion[d].dot(&body_force[dof.body]);
    }
    data.stage = Stage::Velocity;
    Ok(&data.tau_full)
}

fn reduced_pass(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: Option<&[f64]>,
    with_gravity: bool,
    target: Target,
) -> crate::Result<()> {
    data.fits(model)?;
    check_len("q", q, model.nq())?;
    check_len("qd", qd, model.nq())?;
    evaluate_position(model, data, q);
    poses(model, data);
    evaluate_velocity(model, data, qd);
    theta_acceleration(model, data, qdd);
    body_forces(model, data, with_gravity);
    // τ = Φᵀ τ_full = Σ_c S̃_cᵀ f_body(c), accumulated over the reduced columns.
    let Data {
        tau,
        bias,
        coriolis,
        col_motion,
        body_force,
        ..
    } = data;
    let out = match target {
        Target::Tau => tau,
        Target::Bias => bias,
        Target::Coriolis => coriolis,
    };
    out.as_mut_slice().fill(0.0);
    let cols = &model.reduction.columns;
    for c in 0..cols.len() {
        out[cols.q[c]] += col_motion[c].dot(&body_force[cols.body[c]]);
    }
    // The pass leaves valid velocities; its accelerations include gravity.
    data.stage = Stage::Velocity;
    Ok(())
}

/// The forward and backward passes of RNEA over the full coordinates, with θ, θ̇ in the
/// nodes and θ̈ in `theta_acc`: leaves in `body_force[b]` the total force transmitted to body
/// b's subtree through its joint.
fn body_forces(model: &Model, data: &mut Data, with_gravity: bool) {
    let nc = model.reduction.n_coordinates;
    let Data {
        dof_motion,
        body_vel,
        body_acc,
        body_inertia,
        body_force,
        node_vel,
        theta_acc,
        ..
    } = data;
    let theta_dot = &node_vel[nc..];
    // Forward pass: v_i = v_λ + Σ s θ̇, a_i = a_λ + Σ (s θ̈ + v × s θ̇), with a_0 = −g so that
    // gravity enters as a fictitious upward acceleration of ground.
    super::forward_kinematics::velocities_into(model, dof_motion, theta_dot, body_vel);
    let a0 = if with_gravity {
        Motion::new(Default::default(), -model.gravity)
    } else {
        Motion::ZERO
    };
    propagate_accelerations(
        model, dof_motion, body_vel, theta_dot, theta_acc, a0, body_acc,
    );
    // f_i = I_i a_i + v_i ×* I_i v_i
    body_force[0] = Force::ZERO;
    for b in 1..model.bodies.len() {
        let i = &body_inertia[b];
        let v = &body_vel[b];
        body_force[b] = i
            .mul_motion(&body_acc[b])
            .add(&v.cross_force(&i.mul_motion(v)));
    }
    // Backward pass: f_parent += f_child.
    for joint in model.joints.iter().rev() {
        if joint.parent_body != 0 {
            let f = body_force[joint.child_body];
            body_force[joint.parent_body].add_assign(&f);
        }
    }
}
