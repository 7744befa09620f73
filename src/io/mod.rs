//! Readers and writers of motion and result files.
//!
//! * [`storage`]: OpenSim `.sto` / `.mot` tables ([`Table`]).
//! * [`external_loads`]: OpenSim ExternalLoads `.xml` (forces applied to bodies from data columns).
//! * [`trc`]: marker trajectories (`.trc`), read and written.
//! * [`output`]: writing a command's output files whole or not at all.
//! * [`folder`]: the files below a folder of clips (links followed, loops refused).
//! * [`setup`]: OpenSim tool setup files (Inverse Dynamics, Analyze with Static Optimization).

pub mod external_loads;
pub mod folder;
pub mod ik_setup;
pub mod output;
pub mod scale_setup;
pub mod setup;
pub mod storage;
pub mod trc;

pub use storage::{Dialect, ReadOptions, RepeatedTime, Table, TableLines, TableLocator};

use std::path::{Path, PathBuf};

/// Something a reader accepted but the user should know about (a header count that
/// disagrees with the data, a repeated time dropped, a setting not applied). Readers return
/// these; they never print them.
#[derive(Clone, Debug, PartialEq)]
pub struct FileWarning {
    pub file: String,
    /// 1-based line of the file.
    pub line: u32,
    /// The element, column or header key, e.g. `header "nRows"`, `column "time"`,
    /// `AnalyzeTool "arm26" > <speeds_file>`.
    pub element: String,
    pub message: String,
}

impl std::fmt::Display for FileWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{}: {}: {}",
            self.file, self.line, self.element, self.message
        )
    }
}

/// A data-file path written in a setup or ExternalLoads file, resolved against the directory
/// `base` of that file, as OpenSim's tools resolve it. A path written on Windows
/// (`..\grf.mot`) names a file elsewhere: when the path as written does not exist and holds
/// a backslash, the backslashes are read as separators (a backslash is legal in a Unix file
/// name, so a file that exists as written wins). Every reader that takes a path from a
/// setup or ExternalLoads file goes through here.
pub fn resolve_data_path(base: &Path, written: &str) -> PathBuf {
    let written = written.trim();
    let as_written = base.join(written);
    if !written.contains('\\') || std::path::MAIN_SEPARATOR == '\\' || as_written.exists() {
        return as_written;
    }
    // An absolute Windows path (`C:\data\grf.mot`) keeps `C:` as a relative first
    // component: it cannot name a file here either way, and the error will show it.
    let parts = written.split(['\\', '/']).filter(|p| !p.is_empty());
    let mut resolved = if written.starts_with(['\\', '/']) {
        PathBuf::from("/")
    } else {
        base.to_path_buf()
    };
    resolved.extend(parts);
    resolved
}
