//! Kinetic and potential energy, and momentum.

use super::{Data, Stage};
use crate::model::Model;
use crate::spatial::{Force, Vec3};

/// T = ½ Σ_b v_bᵀ I_b v_b (velocity stage).
pub fn kinetic_energy(model: &Model, data: &Data) -> crate::Result<f64> {
    data.require(model, Stage::Velocity, "kinetic_energy")?;
    Ok((1..model.bodies.len())
        .map(|b| 0.5 * data.body_vel[b].dot(&data.body_inertia[b].mul_motion(&data.body_vel[b])))
        .sum())
}

/// V = −Σ_b m_b g · c_b, zero with every centre of mass at the ground origin (position stage).
pub fn potential_energy(model: &Model, data: &Data) -> crate::Result<f64> {
    data.require(model, Stage::Position, "potential_energy")?;
    let o = data.reference_point;
    Ok((1..model.bodies.len())
        .map(|b| {
            let i = &data.body_inertia[b];
            -model.gravity.dot(&(i.h + o * i.mass))
        })
        .sum())
}

/// Total momentum of the model, in ground axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Momentum {
    /// Linear momentum Σ m v_c (kg·m/s).
    pub linear: Vec3,
    /// Angular momentum about the whole-body centre of mass (kg·m²/s).
    pub angular_about_com: Vec3,
    /// Angular momentum about the ground origin.
    pub angular_about_origin: Vec3,
}

/// h = Σ_b I_b v_b (velocity stage).
pub fn momentum(model: &Model, data: &Data) -> crate::Result<Momentum> {
    data.require(model, Stage::Velocity, "momentum")?;
    let mut h = Force::ZERO;
    let mut m = 0.0;
    let mut mc = Vec3::zeros();
    for b in 1..model.bodies.len() {
        let i = &data.body_inertia[b];
        h.add_assign(&i.mul_motion(&data.body_vel[b]));
        m += i.mass;
        mc += i.h;
    }
    let o = data.reference_point;
    // L_A = L_O + (O − A) × p
    let com = if m > 0.0 { mc / m } else { Vec3::zeros() }; // relative to O
    Ok(Momentum {
        linear: h.lin,
        angular_about_com: h.ang - com.cross(&h.lin),
        angular_about_origin: h.ang + o.cross(&h.lin),
    })
}
