//! # musculo
//!
//! Musculoskeletal dynamics for motion datasets: reads OpenSim 4.x models, reduces them to
//! their independent coordinates, and computes forward kinematics, the mass matrix, inverse
//! dynamics, bias forces, Jacobians, centre of mass and momentum — fast and exactly.
//!
//! ```
//! use musculo::{Model, Data, dynamics};
//! let model = Model::demo();
//! let mut data = Data::new(&model);
//! let q = model.default_q();
//! let m = dynamics::crba(&model, &mut data, &q).unwrap();
//! assert_eq!(m.nrows(), model.nq());
//! ```
//!
//! The library never prints; the `musculo` binary is a thin command-line layer on top.

pub mod augment;
pub mod check;
pub mod dynamics;
pub mod error;
pub mod evaluate;
pub mod io;
pub mod limits;
pub(crate) mod linalg;
pub mod loss;
pub mod mjcf;
pub mod model;
pub mod motion;
#[cfg(feature = "mujoco")]
pub mod mujoco;
pub mod muscle;
pub mod random;
pub mod reference;
pub mod report;
pub mod solve;
pub mod spatial;
pub mod text;
pub(crate) mod xml;

pub use dynamics::Data;
pub use error::{Error, Result};
pub use model::Model;

/// The default full-body model, `models/musculo_fullbody.osim` (21 segments, 29 degrees of
/// freedom, 324 muscles; built from `data/model` by `musculo model build`).
pub const DEFAULT_MODEL_OSIM: &str = include_str!("../models/musculo_fullbody.osim");

/// The built-in demonstration model, `models/demo.osim`.
pub const DEMO_MODEL_OSIM: &str = include_str!("../models/demo.osim");
