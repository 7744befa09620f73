//! Readers and writers of motion and result files.
//!
//! * [`storage`]: OpenSim `.sto` / `.mot` tables ([`Table`]).
//! * [`external_loads`]: OpenSim ExternalLoads `.xml` (forces applied to bodies from data columns).
//! * [`trc`]: marker trajectories (`.trc`), read and written.
//! * [`setup`]: OpenSim tool setup files (Inverse Dynamics, Analyze with Static Optimization).

pub mod external_loads;
pub mod ik_setup;
pub mod scale_setup;
pub mod setup;
pub mod storage;
pub mod trc;

pub use storage::{Dialect, ReadOptions, RepeatedTime, Table};
