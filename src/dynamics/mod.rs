//! Rigid-body dynamics over `(&Model, &mut Data)`.
//!
//! Stages, in the order they build on each other:
//! 1. [`forward_kinematics`] (position) → [`forward_kinematics_velocity`] →
//!    [`forward_kinematics_acceleration`];
//! 2. [`crba`] (mass matrix M), [`rnea`] (inverse dynamics τ), [`nonlinear_effects`]
//!    (bias = C q̇ + G), [`coriolis`] (C q̇), [`gravity`] (G);
//! 3. Jacobians, centre of mass, momentum and energy, from the state left in `Data` by
//!    forward kinematics; [`JacobianTimeVariation`] (d/dt of the motion subspace and J̇) from
//!    the velocity stage.
//!
//! Equations of motion in the independent coordinates q:
//!   M(q) q̈ + C(q, q̇) q̇ + G(q) = τ + J_c(q)ᵀ λ.
//! Internally every algorithm runs on the expanded tree of full coordinates θ = φ(q) (one
//! hinge or slide per movable axis), where joint motion subspaces are constant in their
//! local frames, and is reduced with Φ = ∂φ/∂q:
//!   M = Φᵀ M_full Φ,   bias = Φᵀ (bias_full + M_full Φ̇ q̇),   τ = Φᵀ τ_full(θ, θ̇, Φq̈ + Φ̇q̇).
//! This treats q-dependent joint axes (spline-driven knee translations and rotations)
//! exactly, including their Ṡq̇ terms, which appear as Φ̇q̇.
//!
//! Spatial quantities are expressed in ground axes about a reference point O
//! (`Data::reference_point`, the origin of the first moving body), see [`crate::spatial`].

mod center_of_mass;
mod contact_force_derivatives;
mod crba;
mod energy;
mod external_forces;
pub(crate) mod forward_kinematics;
mod gravity;
mod jacobian;
mod jacobian_time_variation;
mod reduction;
mod rnea;
mod rnea_derivatives;
mod rnea_vjp;

pub use center_of_mass::{center_of_mass, center_of_mass_jacobian};
pub use contact_force_derivatives::{ContactForceDerivatives, contact_force_derivatives};
pub use crba::{crba, crba_full};
pub use energy::{Momentum, kinetic_energy, momentum, potential_energy};
pub use external_forces::add_body_wrench;
pub use forward_kinematics::{
    forward_kinematics, forward_kinematics_acceleration, forward_kinematics_full,
    forward_kinematics_velocity,
};
pub use gravity::gravity;
pub use jacobian::{
    body_jacobian, body_jacobian_dot_qd, body_jacobian_full, contact_jacobian,
    contact_jacobian_dot_qd, point_jacobian, point_jacobian_dot_qd,
};
pub use jacobian_time_variation::JacobianTimeVariation;
pub use rnea::{coriolis, nonlinear_effects, rnea, rnea_full};
pub use rnea_derivatives::{RneaDerivatives, rnea_derivatives, rnea_derivatives_full};
pub use rnea_vjp::{PointForces, RneaVjp, rnea_vjp, rnea_vjp_full};

use crate::model::Model;
use crate::spatial::{Force, Mat3, Motion, SpatialInertia, Vec3};
use nalgebra::{DMatrix, DVector};

/// How far the kinematics in a `Data` have been computed for the current state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    None,
    Position,
    Velocity,
    Acceleration,
}

/// The workspace of one model: every array an algorithm writes, allocated once. One `Data`
/// per thread; no algorithm allocates after it is built.
#[derive(Clone, Debug)]
pub struct Data {
    /// (coordinates, full coordinates, bodies, independent coordinates) of the model this
    /// workspace was built for.
    shape: (usize, usize, usize, usize),
    pub(crate) stage: Stage,
    // --- coordinate reduction (nodes: coordinates, then full coordinates) ---
    pub(crate) node_value: Vec<f64>,
    pub(crate) node_vel: Vec<f64>,
    /// The q̈-independent part of each node's acceleration: (Φ̇q̇) for full coordinates.
    pub(crate) node_acc_bias: Vec<f64>,
    /// ∂node/∂q entries, laid out as `Reduction::dep_index`.
    pub(crate) node_grad: Vec<f64>,
    pub(crate) node_g1: Vec<f64>,
    pub(crate) node_g2: Vec<f64>,
    pub(crate) arg_scratch: Vec<f64>,
    /// θ̈ of the current acceleration-level computation.
    pub(crate) theta_acc: Vec<f64>,
    // --- kinematics ---
    /// O: the point about which spatial quantities are taken (ground coordinates).
    pub(crate) reference_point: Vec3,
    pub(crate) body_rot: Vec<Mat3>,
    pub(crate) body_pos: Vec<Vec3>,
    /// Axis of each full coordinate in ground, and a point on it.
    pub(crate) dof_axis: Vec<Vec3>,
    pub(crate) dof_point: Vec<Vec3>,
    /// Motion subspace s_d of each full coordinate (ground axes, about O).
    pub(crate) dof_motion: Vec<Motion>,
    /// Reduced motion subspace columns S̃_c = Σ Φ_dj s_d (see `Reduction::columns`).
    pub(crate) col_motion: Vec<Motion>,
    /// Spatial inertia of each body (ground axes, about O).
    pub(crate) body_inertia: Vec<SpatialInertia>,
    pub(crate) body_vel: Vec<Motion>,
    pub(crate) body_acc: Vec<Motion>,
    /// Body accelerations with q̈ = 0 and no gravity: the J̇q̇ terms.
    pub(crate) body_acc_bias: Vec<Motion>,
    pub(crate) body_acc_bias_valid: bool,
    // --- dynamics ---
    pub(crate) body_force: Vec<Force>,
    pub(crate) composite: Vec<SpatialInertia>,
    pub(crate) tau_full: Vec<f64>,
    pub(crate) mass_matrix_full: DMatrix<f64>,
    pub(crate) mass_matrix: DMatrix<f64>,
    pub(crate) tau: DVector<f64>,
    pub(crate) bias: DVector<f64>,
    pub(crate) coriolis: DVector<f64>,
    pub(crate) gravity: DVector<f64>,
    pub(crate) jac_scratch: Vec<Motion>,
}

impl Data {
    /// Allocates the workspace for `model`.
    pub fn new(model: &Model) -> Data {
        let r = &model.reduction;
        let n_nodes = r.nodes.len();
        let nb = model.bodies.len();
        let nf = model.dofs.len();
        let n = model.nq();
        Data {
            shape: Self::shape_of(model),
            stage: Stage::None,
            node_value: vec![0.0; n_nodes],
            node_vel: vec![0.0; n_nodes],
            node_acc_bias: vec![0.0; n_nodes],
            node_grad: vec![0.0; r.dep_index.len()],
            node_g1: vec![0.0; *r.arg_start.last().unwrap_or(&0)],
            node_g2: vec![0.0; *r.hess_start.last().unwrap_or(&0)],
            arg_scratch: vec![0.0; r.max_args.max(1)],
            theta_acc: vec![0.0; nf],
            reference_point: Vec3::zeros(),
            body_rot: vec![Mat3::identity(); nb],
            body_pos: vec![Vec3::zeros(); nb],
            dof_axis: vec![Vec3::zeros(); nf],
            dof_point: vec![Vec3::zeros(); nf],
            dof_motion: vec![Motion::ZERO; nf],
            col_motion: vec![Motion::ZERO; r.columns.len()],
            body_inertia: vec![SpatialInertia::ZERO; nb],
            body_vel: vec![Motion::ZERO; nb],
            body_acc: vec![Motion::ZERO; nb],
            body_acc_bias: vec![Motion::ZERO; nb],
            body_acc_bias_valid: false,
            body_force: vec![Force::ZERO; nb],
            composite: vec![SpatialInertia::ZERO; nb],
            tau_full: vec![0.0; nf],
            // n × n: allocated by the first crba / crba_full, so that the algorithms that
            // never need them (inverse dynamics, kinematics) stay linear in the bodies
            mass_matrix_full: DMatrix::zeros(0, 0),
            mass_matrix: DMatrix::zeros(0, 0),
            tau: DVector::zeros(n),
            bias: DVector::zeros(n),
            coriolis: DVector::zeros(n),
            gravity: DVector::zeros(n),
            jac_scratch: vec![Motion::ZERO; nf],
        }
    }

    /// Bytes of heap memory this workspace holds.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let f = size_of::<f64>();
        let v = |n: usize, s: usize| n * s;
        v(
            self.node_value.capacity() + self.node_vel.capacity() + self.node_acc_bias.capacity(),
            f,
        ) + v(
            self.node_grad.capacity() + self.node_g1.capacity() + self.node_g2.capacity(),
            f,
        ) + v(
            self.arg_scratch.capacity() + self.theta_acc.capacity() + self.tau_full.capacity(),
            f,
        ) + v(self.body_rot.capacity(), size_of::<Mat3>())
            + v(
                self.body_pos.capacity() + self.dof_axis.capacity() + self.dof_point.capacity(),
                size_of::<Vec3>(),
            )
            + v(
                self.dof_motion.capacity()
                    + self.col_motion.capacity()
                    + self.body_vel.capacity()
                    + self.body_acc.capacity()
                    + self.body_acc_bias.capacity()
                    + self.jac_scratch.capacity(),
                size_of::<Motion>(),
            )
            + v(
                self.body_inertia.capacity() + self.composite.capacity(),
                size_of::<SpatialInertia>(),
            )
            + v(self.body_force.capacity(), size_of::<Force>())
            + v(self.mass_matrix_full.len() + self.mass_matrix.len(), f)
            + v(
                self.tau.len() + self.bias.len() + self.coriolis.len() + self.gravity.len(),
                f,
            )
    }

    /// The stage the kinematics have been computed to.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The reference point O of the spatial quantities, in ground.
    pub fn reference_point(&self) -> Vec3 {
        self.reference_point
    }

    /// Values of all coordinates (`Model::coordinates` order) at the current state.
    pub fn coordinate_values<'a>(&'a self, model: &Model) -> &'a [f64] {
        &self.node_value[..model.reduction.n_coordinates]
    }

    /// Rates of all coordinates at the current state (velocity stage).
    pub fn coordinate_speeds<'a>(&'a self, model: &Model) -> &'a [f64] {
        &self.node_vel[..model.reduction.n_coordinates]
    }

    /// q̇_j of the last velocity-stage computation.
    pub fn independent_speed(&self, model: &Model, j: usize) -> f64 {
        self.node_vel[model.reduction.independent[j]]
    }

    /// The non-zero entries (j, ∂c/∂q_j) of coordinate `c`'s gradient.
    pub fn coordinate_gradient<'a>(
        &'a self,
        model: &'a Model,
        c: usize,
    ) -> impl Iterator<Item = (usize, f64)> + 'a {
        let r = &model.reduction;
        (r.dep_start[c]..r.dep_start[c + 1]).map(move |e| (r.dep_index[e], self.node_grad[e]))
    }

    /// Reduced motion column S̃_c (see `Reduction::columns`).
    pub(crate) fn column_motion(&self, c: usize) -> &Motion {
        &self.col_motion[c]
    }

    /// Full coordinates θ.
    pub fn theta<'a>(&'a self, model: &Model) -> &'a [f64] {
        &self.node_value[model.reduction.n_coordinates..]
    }

    /// Full-coordinate rates θ̇ (velocity stage).
    pub fn theta_dot<'a>(&'a self, model: &Model) -> &'a [f64] {
        &self.node_vel[model.reduction.n_coordinates..]
    }

    /// Φ̇q̇ for the full coordinates (velocity stage).
    pub fn phi_dot_qd<'a>(&'a self, model: &Model) -> &'a [f64] {
        &self.node_acc_bias[model.reduction.n_coordinates..]
    }

    /// Φ = ∂θ/∂q as a dense n_full × n matrix (allocates; for tests and export).
    pub fn phi_matrix(&self, model: &Model) -> DMatrix<f64> {
        let r = &model.reduction;
        let mut phi = DMatrix::zeros(model.n_full(), model.nq());
        for d in 0..model.n_full() {
            for e in r.phi_row(d) {
                phi[(d, r.dep_index[e])] = self.node_grad[e];
            }
        }
        phi
    }

    /// Pose of a body in ground: (rotation, origin).
    pub fn body_pose(&self, body: usize) -> (Mat3, Vec3) {
        (self.body_rot[body], self.body_pos[body])
    }

    /// Position in ground of a point fixed in `body` (`point` in body coordinates).
    pub fn point_position(&self, body: usize, point: &Vec3) -> Vec3 {
        self.body_rot[body] * point + self.body_pos[body]
    }

    /// Angular velocity and velocity of the body origin, in ground (velocity stage).
    pub fn body_velocity(&self, body: usize) -> (Vec3, Vec3) {
        let v = &self.body_vel[body];
        (
            v.ang,
            v.linear_at(&(self.body_pos[body] - self.reference_point)),
        )
    }

    /// Velocity in ground of a point fixed in `body` (velocity stage).
    pub fn point_velocity(&self, body: usize, point: &Vec3) -> Vec3 {
        let p = self.point_position(body, point);
        self.body_vel[body].linear_at(&(p - self.reference_point))
    }

    /// Angular acceleration and acceleration of a body-fixed point, in ground (acceleration
    /// stage). The classical acceleration of point p from the spatial acceleration â:
    /// a_p = â_lin + α × (p − O) + ω × v_p.
    pub fn point_acceleration(&self, body: usize, point: &Vec3) -> (Vec3, Vec3) {
        point_acceleration_from(
            &self.body_vel[body],
            &self.body_acc[body],
            self.point_position(body, point) - self.reference_point,
        )
    }

    /// Marker positions in ground, in `Model::markers` order.
    pub fn marker_positions(&self, model: &Model, out: &mut [Vec3]) -> crate::Result<()> {
        self.require(model, Stage::Position, "marker_positions")?;
        if out.len() != model.markers.len() {
            return Err(crate::Error::invalid(
                "out",
                format!("needs {} entries, has {}", model.markers.len(), out.len()),
            ));
        }
        for (o, m) in out.iter_mut().zip(&model.markers) {
            *o = self.point_position(m.body, &m.location_in_body);
        }
        Ok(())
    }

    /// The joint-space inertia matrix from the last [`crba`] call (0 × 0 before the first).
    pub fn mass_matrix(&self) -> &DMatrix<f64> {
        &self.mass_matrix
    }

    /// The full-coordinate inertia matrix from the last [`crba_full`] call (0 × 0 before the
    /// first).
    pub fn mass_matrix_full(&self) -> &DMatrix<f64> {
        &self.mass_matrix_full
    }

    /// Generalized forces from the last [`rnea`] call.
    pub fn tau(&self) -> &DVector<f64> {
        &self.tau
    }

    /// Full-coordinate generalized forces from the last [`rnea`] / [`rnea_full`] call.
    pub fn tau_full(&self) -> &[f64] {
        &self.tau_full
    }

    fn shape_of(model: &Model) -> (usize, usize, usize, usize) {
        (
            model.coordinates.len(),
            model.n_full(),
            model.bodies.len(),
            model.nq(),
        )
    }

    /// Errors unless this workspace was built for a model of `model`'s shape.
    pub(crate) fn fits(&self, model: &Model) -> crate::Result<()> {
        if self.shape != Self::shape_of(model) {
            return Err(crate::Error::invalid(
                "data",
                format!(
                    "this Data was built for another model (Data::new({}) is needed)",
                    model.name
                ),
            ));
        }
        Ok(())
    }

    pub(crate) fn require(
        &self,
        model: &Model,
        stage: Stage,
        algorithm: &'static str,
    ) -> crate::Result<()> {
        self.fits(model)?;
        if self.stage < stage {
            return Err(crate::Error::StageNotComputed {
                algorithm,
                needs: match stage {
                    Stage::Position | Stage::None => "forward_kinematics",
                    Stage::Velocity => "forward_kinematics_velocity",
                    Stage::Acceleration => "forward_kinematics_acceleration",
                },
            });
        }
        Ok(())
    }
}

/// Classical acceleration of a point at `offset` = p − O of a body moving with spatial
/// velocity `v` and spatial acceleration `a`: (α, â_lin + α × offset + ω × v_p).
#[inline]
pub(crate) fn point_acceleration_from(v: &Motion, a: &Motion, offset: Vec3) -> (Vec3, Vec3) {
    let vp = v.linear_at(&offset);
    (a.ang, a.lin + a.ang.cross(&offset) + v.ang.cross(&vp))
}

/// Checks a slice argument's length.
pub(crate) fn check_len(argument: &'static str, x: &[f64], n: usize) -> crate::Result<()> {
    if x.len() != n {
        return Err(crate::Error::invalid(
            argument,
            format!("expected length {n}, got {}", x.len()),
        ));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(crate::Error::invalid(
            argument,
            format!("element {i} is not finite ({})", x[i]),
        ));
    }
    Ok(())
}
