//! Generalized forces of external wrenches (ground-reaction forces, actuators).

use super::{Data, Stage};
use crate::model::Model;
use crate::model::reduction::NONE;
use crate::spatial::{Force, Vec3};

/// Adds to `out` the generalized force Q = Jᵀ w of a force `force` applied at the point
/// `point_in_ground` of `body` together with a couple `torque` (ground axes): the spatial
/// force about O, (torque + (p − O) × force, force), projected on the reduced motion columns
/// from the body to ground. It enters the equations of motion as M q̈ + bias = τ + Q.
pub fn add_body_wrench(
    model: &Model,
    data: &Data,
    body: usize,
    point_in_ground: &Vec3,
    force: &Vec3,
    torque: &Vec3,
    out: &mut [f64],
) -> crate::Result<()> {
    data.require(model, Stage::Position, "add_body_wrench")?;
    if body >= model.bodies.len() {
        return Err(crate::Error::invalid(
            "body",
            format!("index {body} out of range"),
        ));
    }
    if out.len() != model.nq() {
        return Err(crate::Error::invalid(
            "out",
            format!("expected length {}, got {}", model.nq(), out.len()),
        ));
    }
    let w = Force {
        ang: torque + (point_in_ground - data.reference_point).cross(force),
        lin: *force,
    };
    let cols = &model.reduction.columns;
    let mut c = cols.body_last[body];
    while c != NONE {
        out[cols.q[c]] += data.column_motion(c).dot(&w);
        c = cols.parent[c];
    }
    Ok(())
}
