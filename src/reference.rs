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

/// For unit tests: the embedded default model, then gait2392 and Rajagopal2016 where the
/// reference data has them ("skipped: reference data not found" for a missing one, a failure
/// under [`required`]).
#[cfg(test)]
pub(crate) fn test_models() -> Vec<(&'static str, crate::Model)> {
    let mut out = vec![("default", crate::Model::default_fullbody())];
    for (name, relative) in [
        (
            "gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        match file(relative) {
            Some(p) => out.push((
                name,
                crate::Model::from_osim_file(&p)
                    .unwrap_or_else(|e| panic!("{relative} does not load: {e}")),
            )),
            None if required() => {
                panic!("reference file {relative} not found and MUSCULO_REQUIRE_REFERENCE is set")
            }
            None => eprintln!("skipped: reference data not found ({relative})"),
        }
    }
    out
}

/// For unit tests: independent coordinates drawn uniformly inside their ranges, a fraction
/// `margin` of each range kept clear at both ends (so that small steps stay inside).
#[cfg(test)]
pub(crate) fn random_q(
    model: &crate::Model,
    rng: &mut crate::random::SplitMix64,
    margin: f64,
) -> Vec<f64> {
    model
        .reduction
        .independent
        .iter()
        .map(|&c| {
            let [lo, hi] = model.coordinates[c].range;
            let m = margin * (hi - lo);
            rng.uniform(lo + m, hi - m)
        })
        .collect()
}
