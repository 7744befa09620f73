//! Mutation test of every file reader: 10,000 deterministically mutated copies of small
//! valid inputs per reader (see `mutation/mutate.rs` for the mutations, `mutation/seeds.rs`
//! for the inputs). For each copy the reader must
//!
//! * return `Ok` or `Err`, never panic (each read runs under `catch_unwind`; an abort or a
//!   stack overflow ends the test process, which fails the test);
//! * hold at most [`memory_bound`] bytes at once while reading (a counting global
//!   allocator; a request above 1 GiB is also reported on stderr with the case before it is
//!   attempted, since an impossible one aborts);
//! * on `Err`, name the file it was given and a place in it: a 1-based line (XML, storage,
//!   TRC, setups, models), or for binary and whole-file problems a named place (`header`,
//!   `frame 3`, `parameter POINT:RATE`, `array shape`).
//!
//! Failures are listed with the reader, the seed, the case number and the mutations, which
//! reproduce the case (the generator is seeded per reader).

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
#[path = "mutation/mutate.rs"]
mod mutate;
#[path = "mutation/seeds.rs"]
mod seeds;

use musculo::io::external_loads::ExternalLoads;
use musculo::io::ik_setup::IkSetup;
use musculo::io::scale_setup::{ScaleSetup, parse_marker_set};
use musculo::io::{Table, setup, trc::Trc};
use musculo::model::ForceSetFiles;
use musculo::motion::c3d::C3d;
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{bvh, humanml3d, kit, npy};
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::{Error, Model};
use mutate::{Rng, Targets, mutate};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::Instant;

/// Mutated inputs per reader.
const CASES: usize = 10_000;

/// The most bytes a reader may hold at once for an input of `len` bytes: far above what
/// any of them needs for these small inputs, far below what a size field taken on trust
/// (a row count of 10⁹, a time span of 1e308 s) makes it ask for.
fn memory_bound(len: usize) -> usize {
    (32 << 20) + 64 * len
}

/// Reports above this size on stderr before the request is made.
const REPORT_ABOVE: usize = 1 << 30;

/// A reader under test: its seeds (file name, bytes) and how to read one input.
struct Reader<'a> {
    name: &'static str,
    /// The `cargo fuzz` target of `fuzz/` that reads the same way.
    fuzz_target: &'static str,
    /// Other files read with each input, which an error may name instead (an ExternalLoads
    /// .xml and its data file).
    also_reads: &'static [&'static str],
    xml: bool,
    seeds: Vec<(String, Vec<u8>)>,
    /// Reads the bytes as the file named by the second argument.
    read: &'a dyn Fn(&[u8], &str) -> Result<(), Error>,
}

fn text(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(bytes)
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "<non-string panic payload>".to_string()
    }
}

/// The number after each `key` in `s` (`line 12` → 12).
fn numbers_after(s: &str, key: &str) -> Vec<u64> {
    s.match_indices(key)
        .filter_map(|(i, m)| {
            let rest = &s[i + m.len()..];
            let end = rest
                .find(|c: char| !c.is_ascii_digit())
                .unwrap_or(rest.len());
            rest[..end].parse().ok()
        })
        .collect()
}

/// Why `e` (from reading the file named `source`, with the files `also_reads`) is not
/// located, or `Ok`.
fn check_located(e: &Error, source: &str, also_reads: &[&str]) -> Result<(), String> {
    let message = e.to_string();
    let file_ok = |file: &str| {
        if file == source || also_reads.contains(&file) {
            Ok(())
        } else {
            Err(format!("names file {file:?}, not {source:?}"))
        }
    };
    match e {
        Error::Xml { file, line, .. } | Error::Model { file, line, .. } => {
            file_ok(file)?;
            if *line == 0 {
                return Err("line 0 (lines count from 1)".into());
            }
        }
        Error::Table { table, line, .. } => {
            file_ok(table)?;
            if *line == 0 {
                return Err("line 0 (lines count from 1)".into());
            }
        }
        Error::Motion { file, location, .. } => {
            file_ok(file)?;
            if location.trim().is_empty() {
                return Err("an empty location".into());
            }
        }
        _ => return Err("an error kind that names no file and place".into()),
    }
    if numbers_after(&message, "line ").contains(&0) {
        return Err("names line 0 (lines count from 1)".into());
    }
    Ok(())
}

/// With `MUSCULO_FUZZ_SEEDS=<dir>`, writes `seeds` as `<dir>/<target>/<name>`: the
/// starting corpus of the `cargo fuzz` targets (see docs/src/validation/tests.md, "Fuzzing").
fn write_fuzz_seeds(target: &str, seeds: &[(String, Vec<u8>)]) {
    let Some(dir) = std::env::var_os("MUSCULO_FUZZ_SEEDS") else {
        return;
    };
    let dir = Path::new(&dir).join(target);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, bytes) in seeds {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

/// Tries `CASES` mutations of the reader's seeds; panics with the list of failures.
fn run(reader: Reader, seed: u64) {
    let started = Instant::now();
    if reader.fuzz_target != "external_loads" {
        write_fuzz_seeds(reader.fuzz_target, &reader.seeds);
    }
    for (name, bytes) in &reader.seeds {
        if let Err(e) = (reader.read)(bytes, name) {
            panic!(
                "{}: the seed {name} must read without error: {e}",
                reader.name
            );
        }
    }
    let targets: Vec<Targets> = reader
        .seeds
        .iter()
        .map(|(_, b)| Targets::new(b, reader.xml))
        .collect();
    let mut rng = Rng(seed);
    let (mut ok, mut refused) = (0usize, 0usize);
    let mut failures: Vec<String> = Vec::new();
    let mut worst_peak = 0usize;
    for case in 0..CASES {
        let s = case % reader.seeds.len();
        let (name, bytes) = &reader.seeds[s];
        let (what, mutated) = mutate(bytes, &targets[s], &mut rng);
        let label = format!("{} case {case} of seed {name}: {what}", reader.name);
        counting_alloc::report_requests_above(REPORT_ABOVE, &label);
        let (peak, result) = counting_alloc::peak_bytes_during(|| {
            catch_unwind(AssertUnwindSafe(|| (reader.read)(&mutated, name)))
        });
        counting_alloc::report_requests_above(usize::MAX, "");
        worst_peak = worst_peak.max(peak);
        match result {
            Err(p) => failures.push(format!("{label}: PANIC {}", panic_message(&*p))),
            Ok(Ok(())) => ok += 1,
            Ok(Err(e)) => {
                refused += 1;
                if let Err(why) = check_located(&e, name, reader.also_reads) {
                    failures.push(format!("{label}: UNLOCATED ({why}): {e}"));
                }
            }
        }
        let bound = memory_bound(mutated.len());
        if peak > bound {
            failures.push(format!(
                "{label}: MEMORY {peak} bytes held at once for a {}-byte input (bound {bound})",
                mutated.len()
            ));
        }
    }
    println!(
        "{}: {CASES} mutated inputs from {} seeds: {ok} read, {refused} refused with a located \
         error, {} failures; peak {:.1} MiB; {:.1} s",
        reader.name,
        reader.seeds.len(),
        failures.len(),
        worst_peak as f64 / (1 << 20) as f64,
        started.elapsed().as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{}: {} of {CASES} mutated inputs failed:\n{}",
        reader.name,
        failures.len(),
        failures
            .iter()
            .take(25)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

fn seeds_of(list: Vec<(&str, String)>) -> Vec<(String, Vec<u8>)> {
    list.into_iter()
        .map(|(n, t)| (n.to_string(), t.into_bytes()))
        .collect()
}

#[test]
fn model_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| Model::from_osim_str(&text(b), name).map(drop);
    run(
        Reader {
            name: "model (.osim)",
            fuzz_target: "osim",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![
                ("demo.osim", seeds::DEMO_OSIM.to_string()),
                ("small.osim", seeds::small_osim()),
            ]),
            read: &read,
        },
        0x05EE_D001,
    );
}

/// The model reader and `export-mjcf` together: a mutated model the reader accepts exports
/// to MJCF with finite numbers only (one validation for every command: before, a coupler
/// scale of 1e308, a range of ±1e308 or knots a subnormal distance apart were read, and the
/// export panicked or wrote NaN). A non-finite number written is reported as a failure.
#[test]
fn model_reader_and_mjcf_export_survive_mutations() {
    let read = |b: &[u8], name: &str| {
        let model = Model::from_osim_str(&text(b), name)?;
        let export = musculo::mjcf::to_mjcf(&model);
        let bad = export.xml.split(['"', ' ']).find(|w| {
            let w = w.trim_start_matches('-').to_ascii_lowercase();
            w == "nan" || w == "inf" || w == "infinity"
        });
        assert!(
            bad.is_none(),
            "an accepted model exported to MJCF with a non-finite number ({bad:?})"
        );
        Ok(())
    };
    run(
        Reader {
            name: "model (.osim) then export-mjcf",
            fuzz_target: "osim",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![
                ("demo.osim", seeds::DEMO_OSIM.to_string()),
                ("small.osim", seeds::small_osim()),
            ]),
            read: &read,
        },
        0x05EE_D00E,
    );
}

#[test]
fn force_set_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| {
        let sets = ForceSetFiles {
            files: vec![(text(b).into_owned(), name.to_string())],
            replace: false,
        };
        Model::from_osim_str_with_force_sets(
            seeds::DEMO_OSIM,
            "demo.osim",
            &Default::default(),
            &sets,
        )
        .map(drop)
    };
    run(
        Reader {
            name: "force set (.xml)",
            fuzz_target: "force_set",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![("reserves.xml", seeds::force_set())]),
            read: &read,
        },
        0x05EE_D002,
    );
}

#[test]
fn storage_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| Table::parse(&text(b), name).map(drop);
    run(
        Reader {
            name: "motion (.mot/.sto)",
            fuzz_target: "storage",
            also_reads: &[],
            xml: false,
            seeds: seeds_of(seeds::storage_files()),
            read: &read,
        },
        0x05EE_D003,
    );
}

/// Reads an ExternalLoads .xml and its data file, then resolves both against the demo model,
/// as `id --external-loads` does.
fn read_external_loads(model: &Model, xml: &str, data: &str) -> Result<(), Error> {
    let loads = ExternalLoads::parse(xml, "grf.xml")?;
    let table = Table::parse(data, "grf.mot")?;
    ExternalLoadSet::new(model, &loads, &table, "grf.mot").map(drop)
}

#[test]
fn external_loads_reader_survives_mutations() {
    // The .xml is mutated; its data file stays valid.
    let model = Model::demo();
    let (xml, data) = (seeds::external_loads_xml(), seeds::grf_mot());
    // The fuzz target reads the .xml, a NUL byte, then the data file.
    write_fuzz_seeds(
        "external_loads",
        &[("grf.xml".into(), format!("{xml}\0{data}").into_bytes())],
    );
    let read = |b: &[u8], _: &str| read_external_loads(&model, &text(b), &data);
    run(
        Reader {
            name: "external loads (.xml)",
            fuzz_target: "external_loads",
            also_reads: &["grf.mot"],
            xml: true,
            seeds: seeds_of(vec![("grf.xml", xml.clone())]),
            read: &read,
        },
        0x05EE_D004,
    );
}

#[test]
fn external_loads_data_reader_survives_mutations() {
    // The data file is mutated; the .xml stays valid.
    let model = Model::demo();
    let (xml, data) = (seeds::external_loads_xml(), seeds::grf_mot());
    let read = |b: &[u8], _: &str| read_external_loads(&model, &xml, &text(b));
    run(
        Reader {
            name: "external loads data (.mot)",
            fuzz_target: "external_loads",
            also_reads: &["grf.xml"],
            xml: false,
            seeds: seeds_of(vec![("grf.mot", data)]),
            read: &read,
        },
        0x05EE_D005,
    );
}

#[test]
fn tool_setup_readers_survive_mutations() {
    let read = |b: &[u8], name: &str| setup::parse(&text(b), Path::new(name)).map(drop);
    run(
        Reader {
            name: "ID and SO setups (.xml)",
            fuzz_target: "tool_setup",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(seeds::tool_setups()),
            read: &read,
        },
        0x05EE_D006,
    );
}

#[test]
fn ik_setup_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| IkSetup::parse(&text(b), Path::new(name)).map(drop);
    run(
        Reader {
            name: "IK setup (.xml)",
            fuzz_target: "ik_setup",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![("ik_setup.xml", seeds::ik_setup())]),
            read: &read,
        },
        0x05EE_D007,
    );
}

#[test]
fn scale_setup_and_marker_set_readers_survive_mutations() {
    let read = |b: &[u8], name: &str| ScaleSetup::parse(&text(b), Path::new(name)).map(drop);
    run(
        Reader {
            name: "Scale setup (.xml)",
            fuzz_target: "scale_setup",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![("scale_setup.xml", seeds::scale_setup())]),
            read: &read,
        },
        0x05EE_D008,
    );
    let read = |b: &[u8], name: &str| parse_marker_set(&text(b), Path::new(name)).map(drop);
    run(
        Reader {
            name: "marker set (.xml)",
            fuzz_target: "marker_set",
            also_reads: &[],
            xml: true,
            seeds: seeds_of(vec![("markers.xml", seeds::marker_set())]),
            read: &read,
        },
        0x05EE_D009,
    );
}

#[test]
fn trc_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| {
        let t = Trc::parse(&text(b), name)?;
        musculo::motion::Motion::from_trc(&t, name).map(drop)
    };
    run(
        Reader {
            name: "markers (.trc)",
            fuzz_target: "trc",
            also_reads: &[],
            xml: false,
            seeds: seeds_of(vec![("walk.trc", seeds::trc())]),
            read: &read,
        },
        0x05EE_D00A,
    );
}

#[test]
fn bvh_reader_survives_mutations() {
    let read =
        |b: &[u8], name: &str| bvh::parse(&text(b), name, &bvh::BvhOptions::default()).map(drop);
    run(
        Reader {
            name: "BVH",
            fuzz_target: "bvh",
            also_reads: &[],
            xml: false,
            seeds: seeds_of(vec![("walk.bvh", seeds::bvh())]),
            read: &read,
        },
        0x05EE_D00B,
    );
}

#[test]
fn npy_clip_readers_survive_mutations() {
    // The .npy reader, then HumanML3D's or KIT-ML's reading of the array.
    let read = |b: &[u8], name: &str| {
        let a = npy::parse_array_as_f64(b, name)?;
        if name.contains("kit") {
            kit::from_array(a.view(), name, &kit::Options::default()).map(drop)
        } else {
            humanml3d::from_array(a.view(), name, &humanml3d::Options::default()).map(drop)
        }
    };
    run(
        Reader {
            name: "HumanML3D/KIT-ML (.npy)",
            fuzz_target: "npy_clip",
            also_reads: &[],
            xml: false,
            seeds: seeds::joint_clips()
                .into_iter()
                .map(|(n, b)| (n.to_string(), b))
                .collect(),
            read: &read,
        },
        0x05EE_D00C,
    );
}

#[test]
fn c3d_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| C3d::parse(b, name).map(drop);
    run(
        Reader {
            name: "C3D",
            fuzz_target: "c3d",
            also_reads: &[],
            xml: false,
            seeds: vec![
                ("trial.c3d".to_string(), seeds::c3d(4)),
                ("one_frame.c3d".to_string(), seeds::c3d(1)),
            ],
            read: &read,
        },
        0x05EE_D00D,
    );
}

#[test]
fn skeleton_map_reader_survives_mutations() {
    let read = |b: &[u8], name: &str| SkeletonMap::parse(&text(b), name).map(drop);
    let seeds = ["cmu_bvh", "humanml3d", "c3d_lower_body"]
        .iter()
        .map(|n| {
            let path = format!("{}/data/skeletons/{n}.json", env!("CARGO_MANIFEST_DIR"));
            let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
            (format!("{n}.json"), bytes)
        })
        .collect();
    run(
        Reader {
            name: "skeleton map (.json)",
            fuzz_target: "skeleton_map",
            also_reads: &[],
            xml: false,
            seeds,
            read: &read,
        },
        0x05EE_D00E,
    );
}

#[test]
fn the_memory_bound_is_measured() {
    // The check above is only as good as the allocator's accounting: a reader that holds
    // 64 MiB must be seen holding at least that.
    let (peak, v) = counting_alloc::peak_bytes_during(|| vec![1u8; 64 << 20]);
    assert!(peak >= 64 << 20 && peak > memory_bound(1000), "{peak}");
    drop(v);
    let (peak, ()) = counting_alloc::peak_bytes_during(|| ());
    assert_eq!(peak, 0);
}

/// Regression (found by this test): a NumFrames of 2³¹ made the .trc reader ask for 154 GB
/// up front and abort; now it is an error naming the header line, read in little memory.
#[test]
fn a_huge_trc_frame_count_is_an_error_not_an_allocation() {
    let text = seeds::trc().replace("100\t100\t10\t3", "100\t100\t2147483648\t3");
    let (peak, r) = counting_alloc::peak_bytes_during(|| Trc::parse(&text, "walk.trc"));
    let e = r.expect_err("10 rows are not 2147483648").to_string();
    assert!(
        e.starts_with("walk.trc:") && e.contains("2147483648"),
        "{e}"
    );
    assert!(peak < 1 << 20, "{peak} bytes for a 1 kB file");
}

/// Regression (found by this test): a skeleton map's semantic errors said line 0; they name
/// the line of the target's "marker" key or the segment's "name" key.
#[test]
fn skeleton_map_errors_name_the_line_of_the_entry() {
    let map = r#"{
 "skeleton": "test",
 "axes": ["x", "y", "z"],
 "targets": [
  {"source": ["a"], "marker": "A", "weight": 1},
  {"source": ["b"],
   "marker": "B", "weight": -2}
 ],
 "segments": [
  {"name": "s", "bodies": ["pelvis"], "pairs": [["A", "C"]]}
 ]
}"#;
    let e = SkeletonMap::parse(map, "m.json").unwrap_err().to_string();
    assert!(e.starts_with("m.json:7:") && e.contains("weight -2"), "{e}");
    let e = SkeletonMap::parse(&map.replace("-2", "2"), "m.json")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("m.json:10:") && e.contains("`C`"), "{e}");
    let e = SkeletonMap::parse(&map.replace("\"z\"]", "\"w\"]"), "m.json")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("m.json:3:") && e.contains("axes[2]"), "{e}");
    // a landmark that is not placed would never be used as one
    let e = SkeletonMap::parse(
        &map.replace("-2", "2")
            .replace("\"weight\": 1}", "\"weight\": 1, \"landmark\": true}"),
        "m.json",
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("m.json:5:") && e.contains("landmark"), "{e}");
}
