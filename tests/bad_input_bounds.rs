//! Bad input that used to kill the process or run without bound: a time column that asks
//! the low-pass filter's resampling for unbounded memory, XML entities that expand to
//! gigabytes, and counts or cutoffs from the command line with no limit. Each is now a
//! located error, returned quickly and with bounded memory. Every input is generated here.

mod common;
#[path = "common/counting_alloc.rs"]
mod counting_alloc;

use common::{ScratchDir, musculo_cli};
use counting_alloc::peak_bytes_during;
use musculo::io::Table;
use musculo::io::external_loads::ExternalLoads;
use musculo::model::{ForceSetFiles, LoadOptions};
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use musculo::{Error, Model};
use std::time::{Duration, Instant};

const DEMO: &str = include_str!("../models/demo.osim");

/// A `.mot` of the demo model's coordinates at `times`, all at rest. Its label row is line 7
/// and row k is line 8 + k.
fn motion(times: &[&str]) -> String {
    let mut s = format!(
        "Coordinates\nversion=1\nnRows={}\nnColumns=7\ninDegrees=no\nendheader\n\
         time\tpelvis_tilt\tpelvis_tx\tpelvis_ty\thip_flexion\tknee_angle\tankle_angle\n",
        times.len()
    );
    for t in times {
        s.push_str(&format!("{t}\t0\t0\t0.93\t0\t0\t0\n"));
    }
    s
}

/// Runs inverse dynamics on the demo model with a 6 Hz cutoff, returning the result and the
/// most bytes held at once.
fn filtered_id(text: &str) -> (usize, musculo::Result<Table>) {
    let model = Model::demo();
    let table = Table::parse(text, "m.mot").unwrap();
    let options = InverseDynamicsOptions {
        lowpass_hz: Some(6.0),
        ..InverseDynamicsOptions::default()
    };
    peak_bytes_during(|| {
        inverse_dynamics(&model, &table, "m.mot", None, &options, &mut |_, _| {}).map(|o| o.table)
    })
}

#[test]
fn a_last_time_of_1e308_with_a_lowpass_is_a_located_error_not_an_abort() {
    // Padding reflects 1e308 to infinity: the resampling once looped without end,
    // allocating until the process aborted.
    let (peak, result) = filtered_id(&motion(&["0", "0.01", "0.02", "0.03", "1e308"]));
    match result {
        Err(Error::Model {
            file,
            line,
            element,
            message,
        }) => {
            assert_eq!(
                (file.as_str(), line, element.as_str()),
                ("m.mot", 7, "column \"time\"")
            );
            assert!(
                message.contains("1e308") && message.contains("pad"),
                "{message}"
            );
        }
        other => panic!("expected a located error, got {other:?}"),
    }
    assert!(peak < 1 << 20, "{peak} bytes for a 5-row motion");
}

#[test]
fn huge_but_finite_time_spans_resample_within_a_bounded_number_of_rows() {
    // 1e300 pads to a finite 2e300; the resampling grid is bounded (OpenSim's 100,000 rows),
    // and whatever follows fails or succeeds without an allocation beyond that.
    for last in ["1e300", "1e200", "3e9"] {
        let (peak, result) = filtered_id(&motion(&["0", "0.01", "0.02", "0.03", last]));
        assert!(
            peak < 200 << 20,
            "{last}: {peak} bytes held resampling a 5-row motion"
        );
        if let Err(e) = result {
            let text = e.to_string();
            assert!(text.starts_with("m.mot:"), "{last}: {text}");
            assert!(!text.starts_with("m.mot:0:"), "{last}: {text}");
        }
    }
}

#[test]
fn the_cli_reports_the_1e308_motion_and_exits_cleanly() {
    let d = ScratchDir::new("bounds-id-1e308");
    let mot = d.join("m.mot");
    std::fs::write(&mot, motion(&["0", "0.01", "0.02", "0.03", "1e308"])).unwrap();
    let model = d.join("demo.osim");
    std::fs::write(&model, DEMO).unwrap();
    let out = d.join("out.sto");
    let (ok, _, stderr) = musculo_cli(
        "id --model {} --coordinates {} --lowpass 6 -o {}",
        &[&model, &mot, &out],
    );
    assert!(!ok);
    assert!(
        stderr.contains("m.mot:7: column \"time\"") && stderr.contains("1e308"),
        "{stderr}"
    );
    assert!(!stderr.contains("memory allocation"), "{stderr}");
    assert!(!out.exists());
}

#[test]
fn lowpass_cutoffs_that_cannot_filter_are_refused_by_the_cli() {
    let d = ScratchDir::new("bounds-lowpass");
    let mot = d.join("m.mot");
    std::fs::write(&mot, motion(&["0", "0.01", "0.02", "0.03", "0.04"])).unwrap();
    let model = d.join("demo.osim");
    std::fs::write(&model, DEMO).unwrap();
    let out = d.join("out.sto");
    for bad in ["NaN", "inf", "-inf", "0", "six"] {
        for command in ["id", "so"] {
            let pattern =
                format!("{command} --model {{}} --coordinates {{}} --lowpass={bad} -o {{}}");
            let (ok, _, stderr) = musculo_cli(&pattern, &[&model, &mot, &out]);
            assert!(!ok, "{command} --lowpass={bad} was accepted");
            assert!(
                stderr.contains("--lowpass") && stderr.contains(bad),
                "{command} --lowpass={bad}: {stderr}"
            );
        }
    }
    // Above 0.4 of the sampling rate (100 Hz here) the filter rings at the ends: refused,
    // naming the highest usable cutoff (OpenSim lowers 50 Hz and more to 0.49 of the rate).
    // `so` prepares its coordinates by the same function (and needs actuators on this model).
    for (cutoff, accepted) in [("1000", false), ("41", false), ("40", true)] {
        let pattern = format!("id --model {{}} --coordinates {{}} --lowpass {cutoff} -o {{}}");
        let (ok, _, stderr) = musculo_cli(&pattern, &[&model, &mot, &out]);
        if accepted {
            assert!(ok, "id --lowpass {cutoff}: {stderr}");
        } else {
            assert!(!ok, "id --lowpass {cutoff} was accepted");
            assert!(
                stderr.contains(&format!(
                    "the low-pass cutoff {cutoff} Hz is above 0.4 of the sampling rate (100 Hz)"
                )) && stderr.contains("at most 40 Hz"),
                "id --lowpass {cutoff}: {stderr}"
            );
        }
    }
    // A negative cutoff still means no filtering, as in OpenSim's setups.
    let (ok, _, stderr) = musculo_cli(
        "id --model {} --coordinates {} --lowpass=-1 -o {}",
        &[&model, &mot, &out],
    );
    assert!(ok, "{stderr}");
}

#[test]
fn thread_and_pose_counts_are_bounded() {
    // 100,000 threads ran for minutes before the system refused one; ten million random
    // poses would take most of a day.
    for command in [
        "evaluate --input x --out y.json",
        "report x --out y",
        "merge x --report",
    ] {
        for jobs in ["100000", "0"] {
            let (ok, _, stderr) = musculo_cli(&format!("{command} --jobs {jobs}"), &[]);
            assert!(!ok, "{command} --jobs {jobs} was accepted");
            assert!(
                stderr.contains("--jobs") && stderr.contains("from 1 to 1024"),
                "{command} --jobs {jobs}: {stderr}"
            );
        }
    }
    let (ok, _, stderr) = musculo_cli("check --demo --random-poses 100000000", &[]);
    assert!(!ok);
    assert!(
        stderr.contains("--random-poses") && stderr.contains("from 0 to 1000000"),
        "{stderr}"
    );
    let options = musculo::check::CheckOptions {
        random_poses: musculo::check::MAX_RANDOM_POSES + 1,
        ..Default::default()
    };
    let e = musculo::check::run(&Model::demo(), &options).unwrap_err();
    assert!(e.to_string().contains("random_poses"), "{e}");
}

/// The floor and contact options of `evaluate` and `report` are physical quantities with a
/// range: a floor within ±1 km, a floor velocity within ±100 m/s per axis, a contact height in
/// (0, 1] m. Before, a velocity of 1e300 printed a skate speed of `inf`, a floor of −1e300 a
/// 300-digit Float and a contact height of 1e300 passed; the library's validation agrees.
#[test]
fn evaluate_floor_and_contact_options_are_bounded() {
    for command in ["evaluate --input x --out y.json", "report x --out y"] {
        for (flag, value, said) in [
            ("--floor", "-1e300", "within ±1000"),
            ("--floor", "1001", "within ±1000"),
            ("--floor", "NaN", "within ±1000"),
            ("--floor-velocity", "1e300,0,0", "each within ±100"),
            ("--floor-velocity", "0,0,-101", "each within ±100"),
            ("--floor-velocity", "inf,0,0", "each within ±100"),
        ] {
            let (ok, _, stderr) = musculo_cli(&format!("{command} {flag}={value}"), &[]);
            assert!(!ok, "{command} {flag}={value} was accepted");
            assert!(
                stderr.contains(flag) && stderr.contains(value) && stderr.contains(said),
                "{command} {flag}={value}: {stderr}"
            );
        }
    }
    for value in ["1e300", "1.5", "0", "-0.02", "NaN"] {
        let command = format!("evaluate --input x --out y.json --contact-height={value}");
        let (ok, _, stderr) = musculo_cli(&command, &[]);
        assert!(!ok, "{command} was accepted");
        assert!(
            stderr.contains("--contact-height") && stderr.contains("in (0, 1]"),
            "{command}: {stderr}"
        );
    }
    use musculo::evaluate::EvaluateOptions;
    use musculo::spatial::Vec3;
    let base = EvaluateOptions::default();
    let bad = [
        EvaluateOptions {
            floor_height: Some(-1e300),
            ..base.clone()
        },
        EvaluateOptions {
            floor_velocity: Some(Vec3::new(1e300, 0.0, 0.0)),
            ..base.clone()
        },
        EvaluateOptions {
            contact_height: 1e300,
            ..base.clone()
        },
    ];
    for (o, name) in bad
        .iter()
        .zip(["floor_height", "floor_velocity", "contact_height"])
    {
        let e = o.validate().unwrap_err().to_string();
        assert!(e.contains(name) && e.contains("1e300"), "{e}");
    }
    let edge = EvaluateOptions {
        floor_height: Some(-1000.0),
        floor_velocity: Some(Vec3::new(100.0, 0.0, -100.0)),
        contact_height: 1.0,
        ..base
    };
    edge.validate().unwrap();
}

#[test]
fn check_grid_points_are_bounded() {
    let (ok, _, stderr) = musculo_cli("check --demo --grid-points 100000000000", &[]);
    assert!(!ok);
    assert!(
        stderr.contains("--grid-points") && stderr.contains("10000"),
        "{stderr}"
    );
    let (ok, _, stderr) = musculo_cli("check --demo --grid-points 1", &[]);
    assert!(!ok && stderr.contains("--grid-points"), "{stderr}");
    // The library refuses the same, and a grid step that would need as many points.
    let options = musculo::check::CheckOptions {
        grid_points: musculo::check::MAX_GRID_POINTS + 1,
        ..Default::default()
    };
    let e = musculo::check::run(&Model::demo(), &options).unwrap_err();
    assert!(e.to_string().contains("grid_points"), "{e}");
    let options = musculo::check::CheckOptions {
        max_grid_step: 1e-9,
        ..Default::default()
    };
    let e = musculo::check::run(&Model::demo(), &options).unwrap_err();
    assert!(e.to_string().contains("max_grid_step"), "{e}");
}

/// A document type declaration with one entity of `size` bytes, and `uses` references to it:
/// expanded, size × uses bytes.
fn entity_bomb(root: &str, size: usize, uses: usize) -> (String, String) {
    let doctype = format!(
        "<!DOCTYPE {root} [\n  <!ENTITY big \"{}\">\n]>\n",
        "x".repeat(size)
    );
    (doctype, "&big;".repeat(uses))
}

/// Asserts `result` is an XML error at line 3 (the `<!ENTITY` line) of `file`, and that the
/// refusal took little time and memory.
#[track_caller]
fn assert_entity_refused<T: std::fmt::Debug>(
    file: &str,
    run: impl FnOnce() -> musculo::Result<T>,
    text_len: usize,
) {
    let start = Instant::now();
    let (peak, result) = peak_bytes_during(run);
    let elapsed = start.elapsed();
    match result {
        Err(Error::Xml {
            file: f,
            line,
            column,
            message,
        }) => {
            assert_eq!((f.as_str(), line, column), (file, 3, 3), "{message}");
            assert!(message.contains("<!ENTITY big"), "{message}");
            // The entity's megabyte of text is not echoed back.
            assert!(message.len() < 400, "{} bytes", message.len());
        }
        other => panic!("{file}: expected an XML error, got {other:?}"),
    }
    assert!(
        peak < 4 * text_len + (1 << 20),
        "{file}: {peak} bytes held for a {text_len}-byte file"
    );
    assert!(elapsed < Duration::from_secs(2), "{file}: {elapsed:?}");
}

/// The demo model behind `doctype`, with `credits` added to its `<Model>`.
fn with_doctype(doctype: &str, credits: &str) -> String {
    let root = DEMO.find("<OpenSimDocument").unwrap();
    format!("<?xml version=\"1.0\"?>\n{doctype}{}", &DEMO[root..]).replacen(
        "</Model>",
        &format!("<credits>{credits}</credits></Model>"),
        1,
    )
}

#[test]
fn a_model_with_an_expanding_entity_is_refused_quickly_and_without_big_memory() {
    // 1 MB × 10,000 references: 10 GB if expanded.
    let (doctype, uses) = entity_bomb("OpenSimDocument", 1 << 20, 10_000);
    let xml = with_doctype(&doctype, &uses);
    assert_entity_refused(
        "bomb.osim",
        || Model::from_osim_str(&xml, "bomb.osim"),
        xml.len(),
    );
}

#[test]
fn force_set_external_loads_and_setup_files_refuse_entities_the_same_way() {
    let (doctype, uses) = entity_bomb("OpenSimDocument", 1 << 20, 10_000);
    let force_set = format!(
        "<?xml version=\"1.0\"?>\n{doctype}<OpenSimDocument Version=\"40000\"><ForceSet \
         name=\"reserves\"><objects><CoordinateActuator name=\"r\"><coordinate>knee_angle\
         </coordinate><optimal_force>{uses}</optimal_force></CoordinateActuator></objects>\
         </ForceSet></OpenSimDocument>\n"
    );
    let sets = ForceSetFiles {
        files: vec![(force_set.clone(), "reserves.xml".into())],
        replace: false,
    };
    assert_entity_refused(
        "reserves.xml",
        || Model::from_osim_str_with_force_sets(DEMO, "demo.osim", &LoadOptions::default(), &sets),
        force_set.len(),
    );
    let loads = format!(
        "<?xml version=\"1.0\"?>\n{doctype}<OpenSimDocument Version=\"40000\"><ExternalLoads \
         name=\"grf\"><objects><ExternalForce name=\"{uses}\"/></objects></ExternalLoads>\
         </OpenSimDocument>\n"
    );
    assert_entity_refused(
        "grf.xml",
        || ExternalLoads::parse(&loads, "grf.xml"),
        loads.len(),
    );
    let setup = format!(
        "<?xml version=\"1.0\"?>\n{doctype}<OpenSimDocument Version=\"40000\">\
         <InverseDynamicsTool name=\"id\"><model_file>{uses}</model_file>\
         </InverseDynamicsTool></OpenSimDocument>\n"
    );
    assert_entity_refused(
        "setup.xml",
        || musculo::io::setup::parse(&setup, std::path::Path::new("setup.xml")),
        setup.len(),
    );
}

#[test]
fn a_model_with_an_entity_bomb_is_refused_by_every_command_that_reads_models() {
    let d = ScratchDir::new("bounds-entity-cli");
    let (doctype, uses) = entity_bomb("OpenSimDocument", 1 << 20, 4_000);
    let xml = with_doctype(&doctype, &uses);
    let model = d.join("bomb.osim");
    std::fs::write(&model, &xml).unwrap();
    let out = d.join("out.xml");
    for pattern in [
        "inspect {}",
        "export-mjcf {} -o {}",
        "model scale {} --mass 70 --height 1.8 --model-height 1.7 -o {}",
        "check {}",
    ] {
        let paths: Vec<&std::path::Path> = if pattern.matches("{}").count() == 2 {
            vec![&model, &out]
        } else {
            vec![&model]
        };
        let start = Instant::now();
        let (ok, _, stderr) = musculo_cli(pattern, &paths);
        assert!(!ok, "{pattern}");
        assert!(
            stderr.contains("bomb.osim:3:3") && stderr.contains("<!ENTITY big"),
            "{pattern}: {stderr}"
        );
        assert!(start.elapsed() < Duration::from_secs(10), "{pattern}");
        assert!(!out.exists(), "{pattern}");
    }
}

#[test]
fn augment_counts_from_the_command_line_are_bounded() {
    let d = ScratchDir::new("bounds-augment-counts");
    let out = d.join("out");
    for (flag, value) in [
        ("--variants", "100000000000"),
        ("--variants", "0"),
        ("--jobs", "100000000000"),
        ("--jobs", "0"),
    ] {
        let (ok, _, stderr) = musculo_cli(
            &format!("augment --demo {flag} {value} --out {{}}"),
            &[&out],
        );
        assert!(!ok, "{flag} {value} was accepted");
        assert!(stderr.contains(flag) && stderr.contains(value), "{stderr}");
        assert!(!out.exists(), "{flag} {value} started a run");
    }
}

#[test]
fn a_megabyte_long_bad_value_is_not_echoed_whole() {
    // A number followed by a megabyte of letters: the error names file, line and column, and
    // the command prints it cut in the middle, not the whole token.
    let dir = ScratchDir::new("bounds-long-token");
    let model = dir.join("demo.osim");
    std::fs::write(&model, DEMO).unwrap();
    let mot = dir.join("long.mot");
    let token = format!("99999{}", "x".repeat(1_000_000));
    std::fs::write(
        &mot,
        format!(
            "long\nversion=1\nnRows=2\nnColumns=2\nendheader\ntime\tknee_angle\n0\t{token}\n0.01\t1\n"
        ),
    )
    .unwrap();
    let out = dir.join("tau.sto");
    let (ok, _, stderr) = musculo_cli(
        "id --model {} --coordinates {} -o {}",
        &[&model, &mot, &out],
    );
    assert!(!ok);
    assert!(
        stderr.contains("long.mot:7: column \"knee_angle\""),
        "{stderr}"
    );
    assert!(stderr.contains("bytes left out"), "{stderr}");
    assert!(stderr.len() < 2000, "{} bytes on stderr", stderr.len());
}

/// Inputs of `augment` and `ik` that a sweep found accepted or misreported, each refused with
/// its reason: a length unit of 10³⁰⁰ m (the body's size overflowed and read as 0 m), a
/// skeleton whose joints all lie on one point (blamed on the length unit), `--out` naming an
/// existing file ("File exists"), force plates beside an ExternalLoads file (the plates were
/// ignored), and a model without contact spheres (the message named a library function).
#[test]
fn augment_inputs_are_refused_with_their_reason() {
    let dir = ScratchDir::new("augment-inputs");
    let zeros = dir.join("zeros.npy");
    let array = ndarray::ArrayD::<f32>::zeros(ndarray::IxDyn(&[10, 22, 3]));
    musculo::motion::npy::write_npy(&zeros, array.view()).unwrap();
    let out = dir.join("out");
    let (ok, _, stderr) = musculo_cli("ik --input {} --length-unit 1e300 -o {}", &[&zeros, &out]);
    assert!(!ok && stderr.contains("from 1e-6 to 1e3"), "{stderr}");
    let (ok, _, stderr) = musculo_cli("ik --input {} -o {}", &[&zeros, &out]);
    assert!(
        !ok && stderr.contains("every joint lies on the same point"),
        "{stderr}"
    );
    let (ok, _, stderr) = musculo_cli("augment --input {} --out {}", &[&zeros, &zeros]);
    assert!(
        !ok && stderr.contains("is a file, not a folder"),
        "{stderr}"
    );
    let (ok, _, stderr) = musculo_cli(
        "augment --input {} --force-plates --external-loads {} --out {}",
        &[&zeros, &zeros, &out],
    );
    assert!(!ok && stderr.contains("cannot be used with"), "{stderr}");
    let Some(arm) = common::reference_file("opensim-models/Models/Arm26/arm26.osim") else {
        return;
    };
    let (ok, _, stderr) = musculo_cli("augment --demo --model {} --out {}", &[&arm, &out]);
    assert!(
        !ok && stderr.contains("has no ContactSphere for the ground contacts")
            && !stderr.contains("from_points"),
        "{stderr}"
    );
}

#[test]
fn a_cutoff_below_one_cycle_over_the_recording_is_refused_naming_the_lowest() {
    // Before: `--lowpass 0.01` was accepted and the filter's start-up transient, far longer
    // than the recording, ran the angles away (3,100 rad; the clip called "ok"). One second
    // of rows: the lowest cutoff is one cycle over it, 1 Hz.
    let times: Vec<String> = (0..=100).map(|k| format!("{}", k as f64 * 0.01)).collect();
    let times: Vec<&str> = times.iter().map(String::as_str).collect();
    let model = Model::demo();
    let table = Table::parse(&motion(&times), "m.mot").unwrap();
    let id = |hz: f64| {
        let options = InverseDynamicsOptions {
            lowpass_hz: Some(hz),
            ..InverseDynamicsOptions::default()
        };
        inverse_dynamics(&model, &table, "m.mot", None, &options, &mut |_, _| {})
    };
    match id(0.01) {
        Err(Error::Model {
            file,
            line,
            element,
            message,
        }) => {
            assert_eq!(
                (file.as_str(), line, element.as_str()),
                ("m.mot", 7, "column \"time\"")
            );
            assert!(
                message.contains("0.01 Hz is below 1 cycle") && message.contains("at least 1 Hz"),
                "{message}"
            );
        }
        Err(other) => panic!("expected a located error, got {other}"),
        Ok(_) => panic!("a 0.01 Hz cutoff on one second of rows was accepted"),
    }
    assert!(id(1.0).is_ok());
}

#[test]
fn a_trc_whose_units_header_contradicts_its_markers_spread_is_refused() {
    // Before: millimetre data under `Units m` were fitted with 966 m marker errors under
    // exit 0. The spread is judged against a body's size; the data are not rescaled.
    let trc = |units: &str, scale: f64| {
        let mut s = format!(
            "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
             DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
             100\t100\t3\t3\t{units}\t100\t1\t3\n\
             Frame#\tTime\tHEAD\t\t\tLHIP\t\t\tRTOE\t\t\n\
             \t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\n\n"
        );
        for f in 0..3 {
            let x = 0.01 * f as f64;
            let p = |v: f64| format!("{}", v * scale);
            s.push_str(&format!(
                "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\n",
                f + 1,
                f as f64 * 0.01,
                p(x),
                p(1.7),
                p(0.0),
                p(x),
                p(0.9),
                p(0.1),
                p(x + 0.2),
                p(0.02),
                p(0.1)
            ));
        }
        s
    };
    let read = |text: &str| {
        let t = musculo::io::trc::Trc::parse(text, "t.trc").unwrap();
        musculo::motion::Motion::from_trc(&t, "t.trc")
    };
    // a person 1.7 m tall, in metres and in millimetres
    assert!(read(&trc("m", 1.0)).is_ok());
    assert!(read(&trc("mm", 1000.0)).is_ok());
    match read(&trc("m", 1000.0)) {
        Err(Error::Motion {
            file,
            location,
            message,
        }) => {
            assert_eq!(
                (file.as_str(), location.as_str()),
                ("t.trc", "header \"Units\"")
            );
            assert!(
                message.contains("Units `m`")
                    && message.contains("the markers span 1694.")
                    && message.contains("in mm it would be 1.69 m"),
                "{message}"
            );
        }
        other => panic!("expected a located error, got {other:?}"),
    }
}
