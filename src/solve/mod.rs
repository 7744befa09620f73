//! Solvers that turn recorded motion into the quantities of the equations of motion:
//! kinematics preparation (filtering, differentiation).

pub mod filter;
pub mod kinematics;
