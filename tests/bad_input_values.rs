//! Bad values that used to be accepted silently, and messages that used to lack a location:
//! non-finite or out-of-range muscle parameters, repeated names, text that is not UTF-8,
//! coordinates the dynamics cannot use, and rows counted from 0 or lines reported as 0.
//! Every message is checked for the file, the 1-based line and the column or element.
//! Every input is generated here.

mod common;

use common::{ScratchDir, musculo_cli};
use musculo::io::Table;
use musculo::io::external_loads::ExternalLoads;
use musculo::io::trc::Trc;
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use musculo::{Error, Model};
use std::path::Path;

const DEMO: &str = include_str!("../models/demo.osim");

/// 1-based line of the only occurrence of `needle` in `text`.
#[track_caller]
fn line_of(text: &str, needle: &str) -> u32 {
    assert_eq!(
        text.matches(needle).count(),
        1,
        "`{needle}` must occur once"
    );
    text[..text.find(needle).unwrap()].matches('\n').count() as u32 + 1
}

/// The (file, line, element, message) of an `Error::Model`.
#[track_caller]
fn model_error<T: std::fmt::Debug>(r: musculo::Result<T>) -> (String, u32, String, String) {
    match r {
        Err(Error::Model {
            file,
            line,
            element,
            message,
        }) => (file, line, element, message),
        other => panic!("expected Error::Model, got {other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// Muscle parameters

#[test]
fn non_finite_muscle_parameters_are_errors_at_their_element() {
    for (tag, value) in [
        ("pennation_angle_at_optimal", "NaN"),
        ("pennation_angle_at_optimal", "inf"),
        ("activation_time_constant", "-Inf"),
        ("max_isometric_force", "nan"),
        ("optimal_fiber_length", "infinity"),
    ] {
        let from = DEMO[DEMO.find(&format!("<{tag}>")).unwrap()..]
            .split('\n')
            .next()
            .unwrap()
            .to_string();
        let xml = DEMO.replacen(&from, &format!("<{tag}>{value}</{tag}>"), 1);
        let (file, line, element, message) = model_error(Model::from_osim_str(&xml, "m.osim"));
        assert_eq!(file, "m.osim");
        assert_eq!(line, line_of(&xml, &format!("<{tag}>{value}")), "{tag}");
        assert!(
            element.contains("Thelen2003Muscle \"vasti\"") && element.contains(&format!("<{tag}>")),
            "{tag}: {element}"
        );
        assert!(
            message.contains(value) && message.contains("finite"),
            "{message}"
        );
    }
}

#[test]
fn a_non_finite_number_in_a_muscle_curve_object_is_an_error_too() {
    let xml = DEMO.replacen(
        "<max_contraction_velocity>",
        "<ActiveForceLengthCurve name=\"c\"><min_norm_active_fiber_length>NaN\
         </min_norm_active_fiber_length></ActiveForceLengthCurve><max_contraction_velocity>",
        1,
    );
    let (_, line, element, _) = model_error(Model::from_osim_str(&xml, "m.osim"));
    assert_eq!(line, line_of(&xml, "<min_norm_active_fiber_length>NaN"));
    assert!(
        element.contains("ActiveForceLengthCurve \"c\""),
        "{element}"
    );
}

#[test]
fn out_of_range_muscle_parameters_are_errors_at_their_element() {
    for (tag, value, range) in [
        ("pennation_angle_at_optimal", "1.6", "[0, 1.57"),
        ("pennation_angle_at_optimal", "-0.1", "[0, 1.57"),
        ("activation_time_constant", "0", "positive"),
        ("deactivation_time_constant", "-0.04", "positive"),
    ] {
        let from = DEMO[DEMO.find(&format!("<{tag}>")).unwrap()..]
            .split('\n')
            .next()
            .unwrap()
            .to_string();
        let xml = DEMO.replacen(&from, &format!("<{tag}>{value}</{tag}>"), 1);
        let (_, line, element, message) = model_error(Model::from_osim_str(&xml, "m.osim"));
        assert_eq!(line, line_of(&xml, &format!("<{tag}>{value}")), "{tag}");
        assert!(element.ends_with(&format!("<{tag}>")), "{element}");
        assert!(
            message.contains(range) && message.contains(value),
            "{message}"
        );
    }
    // Limits that are allowed: 0 pennation, a maximum pennation of exactly π/2.
    let xml = DEMO.replacen(
        "<pennation_angle_at_optimal>0.05<",
        "<maximum_pennation_angle>1.5707963267948966</maximum_pennation_angle>\
         <pennation_angle_at_optimal>0<",
        1,
    );
    Model::from_osim_str(&xml, "m.osim").unwrap();
}

#[test]
fn inspect_export_and_scale_refuse_a_nan_pennation_angle_and_write_nothing() {
    let d = ScratchDir::new("values-nan-pennation");
    let xml = DEMO.replacen(
        "<pennation_angle_at_optimal>0.05<",
        "<pennation_angle_at_optimal>NaN<",
        1,
    );
    let line = line_of(&xml, "<pennation_angle_at_optimal>NaN");
    let model = d.join("nan.osim");
    std::fs::write(&model, &xml).unwrap();
    let out = d.join("out.xml");
    for pattern in [
        "inspect {}",
        "export-mjcf {} -o {}",
        "model scale {} --mass 70 --height 1.8 --model-height 1.7 -o {}",
    ] {
        let paths: Vec<&Path> = if pattern.matches("{}").count() == 2 {
            vec![&model, &out]
        } else {
            vec![&model]
        };
        let (ok, _, stderr) = musculo_cli(pattern, &paths);
        assert!(!ok, "{pattern} accepted a NaN pennation angle");
        assert!(
            stderr.contains(&format!("nan.osim:{line}"))
                && stderr.contains("Thelen2003Muscle \"vasti\" > <pennation_angle_at_optimal>"),
            "{pattern}: {stderr}"
        );
        assert!(!out.exists(), "{pattern} wrote a file");
    }
}

// ---------------------------------------------------------------------------------------
// Repeated names

#[test]
fn two_muscles_with_one_name_are_an_error_naming_both_lines() {
    let start = DEMO.find("<Thelen2003Muscle name=\"vasti\">").unwrap();
    let end = DEMO.find("</Thelen2003Muscle>").unwrap() + "</Thelen2003Muscle>".len();
    let muscle = &DEMO[start..end];
    let xml = DEMO.replacen(muscle, &format!("{muscle}\n{muscle}"), 1);
    let first = line_of(DEMO, "<Thelen2003Muscle name=\"vasti\">");
    let second = first + muscle.matches('\n').count() as u32 + 1;
    let (file, line, element, message) = model_error(Model::from_osim_str(&xml, "m.osim"));
    assert_eq!((file.as_str(), line), ("m.osim", second));
    assert!(element.contains("Thelen2003Muscle \"vasti\""), "{element}");
    assert!(
        message.contains("two forces") && message.contains(&format!("line {first}")),
        "{message}"
    );
}

#[test]
fn an_actuator_named_like_a_muscle_and_two_markers_with_one_name_are_errors() {
    let actuator = "<CoordinateActuator name=\"vasti\"><coordinate>knee_angle</coordinate>\
                    <optimal_force>100</optimal_force></CoordinateActuator>";
    let xml = DEMO.replacen(
        "</Thelen2003Muscle>",
        &format!("</Thelen2003Muscle>\n{actuator}"),
        1,
    );
    let (_, line, element, message) = model_error(Model::from_osim_str(&xml, "m.osim"));
    assert_eq!(line, line_of(&xml, "<CoordinateActuator name=\"vasti\">"));
    assert!(
        element.contains("CoordinateActuator \"vasti\""),
        "{element}"
    );
    assert!(message.contains("Thelen2003Muscle"), "{message}");

    let xml = DEMO.replacen("<Marker name=\"knee\">", "<Marker name=\"hip\">", 1);
    let (_, line, element, message) = model_error(Model::from_osim_str(&xml, "m.osim"));
    let second = xml.match_indices("<Marker name=\"hip\">").nth(1).unwrap().0;
    assert_eq!(line, xml[..second].matches('\n').count() as u32 + 1);
    assert!(element.contains("Marker \"hip\"") && message.contains("two markers"));
}

#[test]
fn two_external_forces_with_one_name_are_an_error() {
    let force = |body: &str| {
        format!(
            "      <ExternalForce name=\"right\">\n        <applied_to_body>{body}</applied_to_body>\n\
             \x20       <force_identifier>f_v</force_identifier>\n      </ExternalForce>\n"
        )
    };
    let xml = format!(
        "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\">\n  <ExternalLoads \
         name=\"grf\">\n    <objects>\n{}{}    </objects>\n    <datafile>grf.mot</datafile>\n  \
         </ExternalLoads>\n</OpenSimDocument>\n",
        force("foot"),
        force("shank")
    );
    let (file, line, element, message) = model_error(ExternalLoads::parse(&xml, "grf.xml"));
    assert_eq!((file.as_str(), line), ("grf.xml", 9));
    assert_eq!(element, "ExternalForce \"right\"");
    assert!(message.contains("line 5"), "{message}");
}

/// A force, point or torque value of an external loads' data file beyond ±1e7 (N, m, N·m) is a
/// typing or unit error, refused at its own line and column (a force of 1e300 N gave moments
/// of 1e160 N·m where a NaN in the same cell was refused); 9.9e6 is still read.
#[test]
fn an_external_load_value_beyond_1e7_is_an_error_at_its_line_and_column() {
    use musculo::solve::external_loads::ExternalLoadSet;
    let dir = ScratchDir::new("external-load-magnitude");
    let xml = "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\">\n  <ExternalLoads \
               name=\"grf\">\n    <objects>\n      <ExternalForce name=\"right\">\n        \
               <applied_to_body>foot</applied_to_body>\n        \
               <force_identifier>f_v</force_identifier>\n        \
               <point_identifier>f_p</point_identifier>\n        \
               <torque_identifier>t_</torque_identifier>\n      </ExternalForce>\n    \
               </objects>\n    <datafile>grf.mot</datafile>\n  </ExternalLoads>\n\
               </OpenSimDocument>\n";
    std::fs::write(dir.join("grf.xml"), xml).unwrap();
    let labels = [
        "f_vx", "f_vy", "f_vz", "f_px", "f_py", "f_pz", "t_x", "t_y", "t_z",
    ];
    // `value` in column `col` at row 3 (line 11; the labels are on line 7)
    let data = |col: usize, value: &str| {
        let mut s = format!(
            "grf\nversion=1\nnRows=5\nnColumns=10\ninDegrees=no\nendheader\ntime\t{}\n",
            labels.join("\t")
        );
        for r in 0..5 {
            let row: Vec<&str> = (0..9)
                .map(|c| if r == 3 && c == col { value } else { "1" })
                .collect();
            s.push_str(&format!("{}\t{}\n", r as f64 * 0.01, row.join("\t")));
        }
        s
    };
    let model = Model::demo();
    for (col, value, unit) in [
        (1, "1e300", "N"),
        (1, "-2e7", "N"),
        (4, "1e300", "m"),
        (8, "1e10", "N·m"),
    ] {
        std::fs::write(dir.join("grf.mot"), data(col, value)).unwrap();
        let e = ExternalLoadSet::read(&model, &dir.join("grf.xml"))
            .expect_err(value)
            .to_string();
        assert!(
            e.contains("grf.mot:11")
                && e.contains(&format!("column \"{}\"", labels[col]))
                && e.contains(&format!("{value} is beyond ±1e7 {unit}"))
                && e.contains("ExternalForce \"right\""),
            "{e}"
        );
    }
    std::fs::write(dir.join("grf.mot"), data(1, "9.9e6")).unwrap();
    ExternalLoadSet::read(&model, &dir.join("grf.xml")).unwrap();
}

// ---------------------------------------------------------------------------------------
// Text that is not UTF-8

/// `text` with byte 0xE9 (é in Latin-1) written in place of the first `@`.
fn latin1(text: &str) -> Vec<u8> {
    let at = text.find('@').expect("an @ marks the bad byte");
    let mut bytes = text.as_bytes().to_vec();
    bytes[at] = 0xE9;
    bytes
}

#[track_caller]
fn assert_encoding_error<T: std::fmt::Debug>(
    r: musculo::Result<T>,
    path: &Path,
    at: (u32, u32, usize),
) {
    match r {
        Err(e @ Error::Encoding { .. }) => {
            let Error::Encoding {
                ref file,
                line,
                column,
                offset,
                ref message,
            } = e
            else {
                unreachable!()
            };
            assert_eq!(file, &path.display().to_string());
            assert_eq!((line, column, offset), at, "{e}");
            assert!(
                message.contains("0xE9") && message.contains("UTF-8"),
                "{message}"
            );
            let text = e.to_string();
            let expected = format!("{}:{}:{}: byte offset {}", file, at.0, at.1, at.2);
            assert!(text.starts_with(&expected), "{text}");
        }
        other => panic!(
            "{}: expected an encoding error, got {other:?}",
            path.display()
        ),
    }
}

/// (line, column, offset) of the `@` in `text`.
fn place(text: &str) -> (u32, u32, usize) {
    let at = text.find('@').unwrap();
    let line = text[..at].matches('\n').count() as u32 + 1;
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    (line, text[start..at].chars().count() as u32 + 1, at)
}

#[test]
fn every_text_reader_locates_a_byte_that_is_not_utf8() {
    let d = ScratchDir::new("values-utf8");
    let write = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, latin1(text)).unwrap();
        (p, place(text))
    };
    let model_text = DEMO.replacen(
        "<Body name=\"thigh\">",
        "<Body name=\"thigh\"><!-- f@mur -->",
        1,
    );
    let (p, at) = write("m.osim", &model_text);
    assert_encoding_error(Model::from_osim_file(&p), &p, at);

    let mot = "Coordinates\nversion=1\nendheader\ntime\tknée\n0\t1\n".replace('é', "@");
    let (p, at) = write("m.mot", &mot);
    assert_eq!(at, (4, 8, 39));
    assert_encoding_error(Table::read(&p), &p, at);

    let loads = "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\">\n<ExternalLoads \
                 name=\"gr@\"/></OpenSimDocument>\n";
    let (p, at) = write("grf.xml", loads);
    assert_encoding_error(ExternalLoads::read(&p), &p, at);

    let setup = "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\">\n\
                 <InverseDynamicsTool name=\"@\"/></OpenSimDocument>\n";
    let (p, at) = write("setup.xml", setup);
    assert_encoding_error(musculo::io::setup::read(&p), &p, at);

    let trc = "PathFileType\t4\t(X/Y/Z)\tm.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\t\
               Units\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n100\t100\t1\t1\tmm\t100\t1\t1\n\
               Frame#\tTime\tA@\n\t\tX1\tY1\tZ1\n\n1\t0\t1\t2\t3\n";
    let (p, at) = write("m.trc", trc);
    assert_encoding_error(Trc::read(&p), &p, at);

    let bvh = "HIERARCHY\nROOT hips@\n{\n}\n";
    let (p, at) = write("m.bvh", bvh);
    assert_encoding_error(musculo::motion::bvh::Bvh::read(&p), &p, at);

    // And the CLI says the same.
    let (p, at) = write("cli.osim", &model_text);
    let (ok, _, stderr) = musculo_cli("inspect {}", &[&p]);
    assert!(!ok);
    assert!(
        stderr.contains(&format!("cli.osim:{}:{}: byte offset {}", at.0, at.1, at.2)),
        "{stderr}"
    );
}

// ---------------------------------------------------------------------------------------
// Coordinates the dynamics cannot use, missing columns: file, line and column

/// A `.mot` of the demo's coordinates, knee_angle = `knee` at row 2 (line 10); label row at
/// line 7.
fn motion_with_knee(knee: &str) -> String {
    let mut s = "Coordinates\nversion=1\nnRows=5\nnColumns=7\ninDegrees=no\nendheader\n\
                 time\tpelvis_tilt\tpelvis_tx\tpelvis_ty\thip_flexion\tknee_angle\tankle_angle\n"
        .to_string();
    for (r, t) in ["0", "0.01", "0.02", "0.03", "0.04"].iter().enumerate() {
        let k = if r == 2 { knee } else { "0" };
        s.push_str(&format!("{t}\t0\t0\t0.93\t0\t{k}\t0\n"));
    }
    s
}

fn id(text: &str) -> musculo::Result<Table> {
    let table = Table::parse(text, "m.mot")?;
    inverse_dynamics(
        &Model::demo(),
        &table,
        "m.mot",
        None,
        &InverseDynamicsOptions::default(),
        &mut |_, _| {},
    )
    .map(|o| o.table)
}

/// A coordinate value beyond ±1e15 (radians or metres) is a typing or unit error: refused at
/// its own row's line and column. (Before, 1e250 made the spline's speeds square to infinity
/// and the error blamed the first row whose force was NaN, and 1e306 overflowed the spline,
/// blamed on the label line.)
#[test]
fn a_coordinate_value_beyond_1e15_is_an_error_at_its_own_row_and_column() {
    for knee in ["1e250", "1e306", "-1e16", "1.0000001e15"] {
        let (file, line, element, message) = model_error(id(&motion_with_knee(knee)));
        assert_eq!(
            (file.as_str(), line, element.as_str()),
            ("m.mot", 10, "column \"knee_angle\""),
            "knee {knee}: {message}"
        );
        assert!(
            message.contains("beyond ±1e15 rad") && message.contains(knee),
            "{message}"
        );
    }
    // In degrees, the message gives both the file's value and the radians.
    let text = motion_with_knee("1e300").replace("inDegrees=no", "inDegrees=yes");
    let (_, line, _, message) = model_error(id(&text));
    assert_eq!(line, 10);
    assert!(
        message.contains("1e300°") && message.contains("rad)"),
        "{message}"
    );
    // The bound itself is a (nonsensical but representable) pose: read, with the degrees
    // suspicion warning.
    id(&motion_with_knee("1e15")).expect("1e15 rad is read");
}

#[test]
fn a_missing_coordinate_column_is_reported_at_the_label_line_not_line_0() {
    let text = motion_with_knee("0").replace("\tankle_angle\n", "\tankle\n");
    let (file, line, element, message) = model_error(id(&text));
    assert_eq!(
        (file.as_str(), line, element.as_str()),
        ("m.mot", 7, "column \"ankle_angle\"")
    );
    assert!(message.contains("no column"), "{message}");
}

#[test]
fn the_cli_never_prints_line_0_or_an_element_index_for_bad_coordinates() {
    let d = ScratchDir::new("values-cli-coordinates");
    let model = d.join("demo.osim");
    std::fs::write(&model, DEMO).unwrap();
    let out = d.join("out.sto");
    // Static optimization needs an actuator per coordinate: reserves on every one.
    let reserves: String = [
        "pelvis_tilt",
        "pelvis_tx",
        "pelvis_ty",
        "hip_flexion",
        "knee_angle",
        "ankle_angle",
    ]
    .iter()
    .map(|c| {
        format!(
            "<CoordinateActuator name=\"reserve_{c}\"><coordinate>{c}</coordinate>\
                 <optimal_force>1000</optimal_force></CoordinateActuator>"
        )
    })
    .collect();
    let actuators = d.join("reserves.xml");
    std::fs::write(
        &actuators,
        format!(
            "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\"><ForceSet \
             name=\"reserves\"><objects>{reserves}</objects></ForceSet></OpenSimDocument>\n"
        ),
    )
    .unwrap();
    // Every value is refused at its row (line 10), in radians or in degrees, by `muscles`
    // as by `id` and `so` (it once read 1e300° without a word).
    for (knee, degrees) in [("1e250", false), ("1e306", false), ("1e300", true)] {
        let mot = d.join("m.mot");
        let mut text = motion_with_knee(knee);
        if degrees {
            text = text.replace("inDegrees=no", "inDegrees=yes");
        }
        std::fs::write(&mot, text).unwrap();
        for (pattern, paths) in [
            ("id --model {} --coordinates {} -o {}", [&model, &mot, &out]),
            (
                "so --model {} --coordinates {} --actuators {} -o {}",
                [&model, &mot, &actuators],
            ),
        ] {
            let mut paths: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
            if pattern.starts_with("so") {
                paths.push(&out);
            }
            let (ok, _, stderr) = musculo_cli(pattern, &paths);
            assert!(!ok, "{pattern} with knee {knee}");
            assert!(stderr.contains("m.mot:"), "{pattern}: {stderr}");
            assert!(!stderr.contains("m.mot:0:"), "{pattern}: {stderr}");
            assert!(!stderr.contains("element "), "{pattern}: {stderr}");
            assert!(
                stderr.contains("column \"knee_angle\""),
                "{pattern}: {stderr}"
            );
            assert!(stderr.contains("m.mot:10:"), "{pattern}: {stderr}");
        }
        let (ok, _, stderr) = musculo_cli("muscles {} --coords {} -o {}", &[&model, &mot, &out]);
        assert!(
            !ok && stderr.contains("m.mot:10:") && stderr.contains("beyond ±1e15 rad"),
            "{stderr}"
        );
        assert!(stderr.contains("column \"knee_angle\""), "{stderr}");
    }
}

#[test]
fn the_degrees_suspicion_warning_names_the_line_of_the_row() {
    let text = motion_with_knee("-68.7");
    let table = Table::parse(&text, "m.mot").unwrap();
    let out = inverse_dynamics(
        &Model::demo(),
        &table,
        "m.mot",
        None,
        &InverseDynamicsOptions::default(),
        &mut |_, _| {},
    )
    .unwrap();
    let w = out
        .warnings
        .iter()
        .find(|w| w.contains("exceeds 2π"))
        .expect("a degrees warning");
    assert!(
        w.starts_with("m.mot:10: column \"knee_angle\" (time 0.02)"),
        "{w}"
    );
}

// ---------------------------------------------------------------------------------------
// Rows are named by their line, never by an index counted from 0

#[test]
fn storage_and_trc_messages_name_lines_not_rows_counted_from_0() {
    let base = "x\nversion=1\nendheader\ntime\ta\n0\t1\n0.1\t2\n";
    for (text, line) in [
        (format!("{base}0.2\tx\n"), 7),
        (format!("{base}0.2\t1\t2\n"), 7),
        (format!("{base}0.05\t1\n"), 7),
    ] {
        let (file, l, _, message) = model_error(Table::parse(&text, "t.sto"));
        assert_eq!((file.as_str(), l), ("t.sto", line), "{message}");
        assert!(!has_row_index(&message), "{message}");
    }
    let trc = "PathFileType\t4\t(X/Y/Z)\tm.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\t\
               Units\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n100\t100\t2\t1\tmm\t100\t1\t2\n\
               Frame#\tTime\tA\n\t\tX1\tY1\tZ1\n\n1\t0\t1\t2\t3\n2\t0.01\t1\tq\t3\n";
    let e = Trc::parse(trc, "m.trc").unwrap_err().to_string();
    assert!(e.starts_with("m.trc:8: marker \"A\" (column Y1)"), "{e}");
    assert!(!has_row_index(&e), "{e}");
}

/// Whether `message` numbers a row (`row 3`): rows are named by their line.
fn has_row_index(message: &str) -> bool {
    message
        .split("row ")
        .skip(1)
        .any(|rest| rest.starts_with(|c: char| c.is_ascii_digit()))
}

#[test]
fn a_muscle_of_a_force_set_file_is_reported_in_that_file() {
    use musculo::model::{ForceSetFiles, LoadOptions};
    let start = DEMO.find("<Thelen2003Muscle name=\"vasti\">").unwrap();
    let end = DEMO.find("</Thelen2003Muscle>").unwrap() + "</Thelen2003Muscle>".len();
    let muscle = DEMO[start..end].replace("name=\"vasti\"", "name=\"vasti2\"");
    let set = |muscle: &str| {
        let text = format!(
            "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\">\n<ForceSet \
             name=\"extra\">\n<objects>\n{muscle}\n</objects>\n</ForceSet>\n</OpenSimDocument>\n"
        );
        (
            ForceSetFiles {
                files: vec![(text.clone(), "extra.xml".into())],
                replace: false,
            },
            text,
        )
    };
    let load = |sets: &ForceSetFiles| {
        Model::from_osim_str_with_force_sets(DEMO, "demo.osim", &LoadOptions::default(), sets)
    };
    // Caught when the file is read: the element in the force-set file.
    let (sets, text) = set(&muscle.replacen(
        "<pennation_angle_at_optimal>0.05<",
        "<pennation_angle_at_optimal>inf<",
        1,
    ));
    let (file, line, _, _) = model_error(load(&sets));
    assert_eq!(
        (file.as_str(), line),
        (
            "extra.xml",
            line_of(&text, "<pennation_angle_at_optimal>inf")
        )
    );
    // Caught by the muscle model (a curve parameter that must be positive): the muscle's
    // line in the force-set file, not the model file.
    let (sets, text) = set(&muscle.replacen(
        "<max_contraction_velocity>",
        "<FmaxTendonStrain>-0.04</FmaxTendonStrain><max_contraction_velocity>",
        1,
    ));
    let model = load(&sets).unwrap();
    let (file, line, element, message) =
        model_error(musculo::muscle::MuscleSet::new(&model).map(|_| ()));
    assert_eq!(
        (file.as_str(), line),
        (
            "extra.xml",
            line_of(&text, "<Thelen2003Muscle name=\"vasti2\">")
        )
    );
    assert!(
        element.contains("vasti2") && message.contains("FmaxTendonStrain"),
        "{message}"
    );
}
