//! Locating the public reference data (`../shared/reference`) that tests, benchmarks and
//! validation read in place. The directory comes from `MUSCULO_REFERENCE` or defaults to
//! `../shared/reference` beside this repository.

use std::path::PathBuf;

/// The reference data directory: `$MUSCULO_REFERENCE`, else `<repo>/../shared/reference`.
pub fn directory() -> PathBuf {
    match std::env::var_os("MUSCULO_REFERENCE") {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/reference"),
    }
}

/// True when `MUSCULO_REQUIRE_REFERENCE=1`: a missing reference file is then a failure
/// instead of a skip.
pub fn required() -> bool {
    std::env::var("MUSCULO_REQUIRE_REFERENCE")
        .is_ok_and(|v| v == "1" || v.eq_ignore_ascii_case("true"))
}

/// The path of a reference file (relative to the reference directory), if it exists.
pub fn file(relative: &str) -> Option<PathBuf> {
    let p = directory().join(relative);
    p.exists().then_some(p)
}
