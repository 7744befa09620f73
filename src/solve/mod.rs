//! Solvers that turn recorded motion into the quantities of the equations of motion:
//! kinematics preparation (filtering, differentiation).
//! External loads over time ([`external_loads`]) and OpenSim's Inverse Dynamics tool
//! ([`inverse_dynamics`]).

pub mod contact;
pub mod external_loads;
pub mod filter;
pub mod ik;
pub mod ik_tool;
pub mod inverse_dynamics;
pub mod kinematics;
pub mod ltl;
pub mod orientation_filter;
pub mod qp;
pub mod scale;
pub mod scale_from_clip;
pub mod static_optimization;

/// The former path of [`ik::robust`].
pub use ik::robust as ik_robust;
