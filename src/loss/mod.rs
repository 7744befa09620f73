//! Physics losses for trainers of motion models, with their gradients (METHOD.md §2,
//! FlexMotion eqs. 6–7).
//!
//! - [`euler_lagrange`]: L_euler = Σ_t Σ_j w_j r_tj², r = M q̈ + C q̇ + G − τ − J_cᵀ λ, with
//!   ∂L/∂q, ∂L/∂q̇, ∂L/∂q̈, ∂L/∂τ and ∂L/∂λ from the exact derivatives of inverse dynamics
//!   ([`crate::dynamics::rnea_derivatives`]) and of the contact forces' generalized forces
//!   ([`crate::dynamics::contact_force_derivatives`]).
//!
//! - [`muscle`]: L_muscle = Σ_t Σ_j w_j (q̈ − M⁻¹ R F_max a)_tj² + β‖a‖² + a bound penalty, with
//!   ∂L/∂q (through M and through R: the exact moment-arm rates of
//!   [`crate::muscle::path::MomentArmRates`]), ∂L/∂q̈ and ∂L/∂a.
//!
//! - [`layout`]: L_euler of a motion in FlexMotion's per-joint layout, whose contact forces
//!   act at the joint centres with a free couple on each body that touches the ground (with
//!   [`crate::augment::layout_inverse_vjp`], gradients with respect to the layout itself).
//!
//! - [`tensor_file`]: the residual of an `.npz` tensor file (`musculo loss`).
//!
//! Batches are flat row-major arrays of frames (B × T frames, one row of n values per frame);
//! frames run in parallel (rayon) with one workspace per worker, and every per-frame value is
//! independent of the thread count (sums over frames are taken in frame order afterwards).

pub mod euler_lagrange;
pub mod layout;
pub mod muscle;
pub mod tensor_file;

pub use euler_lagrange::{EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact};
pub use layout::{LayoutEulerLagrange, LayoutEulerLagrangeBatch, LayoutEulerLagrangeOutput};
pub use muscle::{MuscleBatch, MuscleLoss, MuscleLossOutput};

/// Per-coordinate loss weights: none (all 1) or one finite w_j ≥ 0 per coordinate.
fn validate_weights(weights: &[f64], n: usize) -> crate::Result<()> {
    if !(weights.is_empty() || weights.len() == n) {
        return Err(crate::Error::invalid(
            "weights",
            format!("{} weights for {n} coordinates", weights.len()),
        ));
    }
    if let Some((j, w)) = weights
        .iter()
        .enumerate()
        .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
    {
        return Err(crate::Error::invalid(
            "weights",
            format!("weight {j} is {w} (must be finite and ≥ 0)"),
        ));
    }
    Ok(())
}
