//! Muscles: geometry paths (points, wrapping, lengths, moment arms), Hill-type force models
//! and activation dynamics.

pub mod activation;
pub mod hill;
pub mod path;
mod set;
pub mod wrap;

pub use set::{MuscleData, MuscleSet, TendonMode, compute_muscles};
