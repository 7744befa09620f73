//! Readers and writers of motion and result files.
//!
//! * [`storage`]: OpenSim `.sto` / `.mot` tables ([`Table`]).
//! * [`external_loads`]: OpenSim ExternalLoads `.xml` (forces applied to bodies from data columns).

pub mod external_loads;
pub mod storage;

pub use storage::{Dialect, ReadOptions, RepeatedTime, Table};
