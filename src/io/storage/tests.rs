// Numbers are written as they appear in the files, digits beyond f64 precision included.
#![allow(clippy::excessive_precision)]

use super::*;
use std::path::{Path, PathBuf};

/// A reference file, or `None` (after saying so) when the reference data is absent and not
/// required.
fn reference(rel: &str) -> Option<PathBuf> {
    let p = crate::reference::file(&format!("opensim-models/{rel}"));
    if p.is_none() {
        assert!(
            !crate::reference::required(),
            "reference file {rel} not found"
        );
        println!("skipped: reference data not found ({rel})");
    }
    p
}

fn read(rel: &str) -> Option<Table> {
    let p = reference(rel)?;
    Some(Table::read(&p).unwrap_or_else(|e| panic!("{e}")))
}

fn value(t: &Table, row: usize, label: &str) -> f64 {
    t.value(row, t.column_index(label).unwrap()).unwrap()
}

/// The fields of a content error, for assertions.
fn model_error(text: &str) -> (u32, String, String) {
    match Table::parse(text, "inline.sto") {
        Err(Error::Model {
            file,
            line,
            element,
            message,
        }) => {
            assert_eq!(file, "inline.sto");
            (line, element, message)
        }
        other => panic!("expected a content error, got {other:?}"),
    }
}

const HEADER: &str = "test\nversion=1\ninDegrees=no\nendheader\n";

// ---------------------------------------------------------------------------------------
// Header dialects, on the reference files.

#[test]
fn version1_header_reads_arm26_cmc_controls() {
    let Some(t) = read(
        "Tutorials/Computed_Muscle_Control/OutputReference/ComputedMuscleControl/Results/arm26_controls.sto",
    ) else {
        return;
    };
    assert_eq!(t.dialect, Dialect::Version1);
    assert_eq!(t.name, "controls");
    assert_eq!(t.in_degrees, Some(false));
    assert_eq!(t.n_rows(), 441);
    assert_eq!(t.labels.len(), 8);
    assert_eq!(t.labels[0], "TRIlong");
    assert_eq!(t.labels[7], "r_elbow_flex_reserve");
    assert_eq!(t.time[0], 0.03);
    assert_eq!(t.time[1], 0.03013083);
    assert_eq!(*t.time.last().unwrap(), 0.99);
    assert_eq!(value(&t, 0, "TRIlat"), 0.03750043);
    assert_eq!(value(&t, 1, "BIClong"), 0.06145857);
    assert_eq!(value(&t, 0, "r_elbow_flex_reserve"), -0.0053878);
    assert!(t.metadata.is_empty() && t.description.is_empty());
}

#[test]
fn version1_header_with_description_reads_gait2392_ik_motion() {
    let Some(t) = read("Pipelines/Gait2392_Simbody/subject01_walk1_ik.mot") else {
        return;
    };
    assert_eq!(t.dialect, Dialect::Version1);
    assert_eq!(t.name, "Coordinates");
    assert_eq!(t.in_degrees, Some(true));
    assert_eq!((t.n_rows(), t.n_columns()), (211, 23));
    assert_eq!(
        t.description,
        [
            "Units are S.I. units (second, meters, Newtons, ...)",
            "Angles are in degrees."
        ]
    );
    assert_eq!(t.time[0], 0.5);
    assert_eq!(t.time[1], 0.51666667);
    assert_eq!(value(&t, 0, "pelvis_tilt"), 4.76281529);
    assert_eq!(value(&t, 0, "knee_angle_r"), -19.85408256);
    assert_eq!(value(&t, 1, "pelvis_ty"), 1.02967655);
}

#[test]
fn version1_header_reads_gait2392_inverse_dynamics_output() {
    let Some(t) = read(
        "Pipelines/Gait2392_Simbody/OutputReference/ResultsInverseDynamics/InverseDynamicsOutput.sto",
    ) else {
        return;
    };
    assert_eq!(t.name, "Inverse Dynamics");
    assert_eq!(t.in_degrees, Some(false));
    assert_eq!((t.n_rows(), t.n_columns()), (73, 23));
    assert_eq!(t.time[0], 0.39999934);
    assert_eq!(value(&t, 0, "pelvis_tilt_moment"), 19.87038755);
    assert_eq!(value(&t, 1, "pelvis_tx_force"), -74.84225493);
    assert_eq!(value(&t, 0, "hip_flexion_r_moment"), 35.67454489);
}

#[test]
fn header_lines_with_trailing_tabs_read_gait2392_grf() {
    // Every header line of this file ends in a run of tabs.
    let Some(t) = read("Pipelines/Gait2392_Simbody/subject01_walk1_grf.mot") else {
        return;
    };
    assert_eq!(t.name, "subject01_walk1_grf.mot");
    assert_eq!(t.in_degrees, Some(true));
    assert_eq!((t.n_rows(), t.n_columns()), (1501, 18));
    assert_eq!(t.labels[6], "1_ground_force_vx");
    assert_eq!(t.time[1], 0.0017);
    assert_eq!(value(&t, 0, "ground_force_vx"), 101.5119767);
    assert_eq!(value(&t, 0, "ground_force_vy"), 745.4661142);
    assert_eq!(value(&t, 1, "ground_force_vz"), -46.86966548);
}

#[test]
fn simm_header_reads_joint_reaction_grf_motion() {
    let Some(t) = read("Tutorials/Estimating_Joint_Reaction_Loads/subject01_walk1_grf.mot") else {
        return;
    };
    assert_eq!(t.dialect, Dialect::Unversioned);
    assert_eq!(t.name, "subject01_walk1_grf.mot");
    assert_eq!(t.in_degrees, None);
    assert!(
        t.metadata.is_empty(),
        "range is structural: {:?}",
        t.metadata
    );
    // Labels are tab-separated and padded with spaces.
    assert_eq!((t.n_rows(), t.n_columns()), (9009, 18));
    assert_eq!(t.labels[0], "right_foot_force_vx");
    assert_eq!(value(&t, 0, "right_foot_force_vy"), 745.46611415);
    assert_eq!(value(&t, 1, "right_foot_force_vx"), 103.20438764);
    assert_eq!(*t.time.last().unwrap(), 15.0133);
}

#[test]
fn mixed_version_and_simm_header_reads_gait2392_cmc_kinematics() {
    // `nRows=` / `nColumns=` lines, then a SIMM block (`name`, `datacolumns`, `datarows`,
    // `otherdata`, `range`), no `version`.
    let Some(t) = read(
        "Pipelines/Gait2392_Simbody/OutputReference/ResultsCMC/subject01_walk1_Kinematics_q.mot",
    ) else {
        return;
    };
    assert_eq!(t.dialect, Dialect::Unversioned);
    assert_eq!(t.name, "Coordinates");
    assert_eq!(t.metadata, [("otherdata".to_string(), "1".to_string())]);
    assert_eq!(t.description, ["# SIMM Motion File Header:"]);
    assert_eq!((t.n_rows(), t.n_columns()), (1460, 23));
    assert_eq!(t.time[0], 0.53000000000000003);
    assert_eq!(value(&t, 0, "pelvis_tx"), 0.58746650759975538);
}

#[test]
fn version1_header_reads_static_optimization_forces() {
    let Some(t) = read(
        "Tutorials/Estimating_Joint_Reaction_Loads/OutputReference/ResultsStaticOptimization/subject01_StaticOptimization_force.sto",
    ) else {
        return;
    };
    assert_eq!(t.name, "ModelForces");
    assert_eq!((t.n_rows(), t.n_columns()), (151, 116));
    assert_eq!(t.labels[0], "glut_med1_r");
    assert_eq!(t.labels[115], "calcn_l_left_foot_Tz");
    assert_eq!(t.time[0], 0.5);
    assert_eq!(value(&t, 0, "glut_med1_r"), 28.30825025437631481395);
    assert_eq!(value(&t, 0, "glut_med2_r"), 64.36576095687034637649);
    assert_eq!(*t.time.last().unwrap(), 1.99900000000000011013);
}

#[test]
fn state_labels_use_opensim3_dot_names_in_arm26_states() {
    let Some(t) = read(
        "Tutorials/Computed_Muscle_Control/OutputReference/ComputedMuscleControl/Results/arm26_states.sto",
    ) else {
        return;
    };
    assert_eq!(t.name, "arm26_states");
    assert_eq!(t.n_columns(), 16);
    assert_eq!(value(&t, 0, "TRIlat.activation"), 0.04225167);
    assert_eq!(value(&t, 1, "BIClong.activation"), 0.02044965);
    assert_eq!(value(&t, 0, "BRA.fiber_length"), 0.09327521);
}

#[test]
fn repeated_rows_in_gait2392_rra_states_are_dropped_with_a_warning_or_an_error_on_request() {
    let rel =
        "Pipelines/Gait2392_Simbody/OutputReference/ResultsRRA/subject01_walk1_RRA_states.sto";
    let Some(p) = reference(rel) else {
        return;
    };
    let strict = ReadOptions {
        repeated_time: RepeatedTime::Error,
    };
    match Table::read_with(&p, &strict) {
        Err(Error::Model {
            line,
            element,
            message,
            ..
        }) => {
            assert_eq!((line, element.as_str()), (3023, "column \"time\""));
            assert!(
                message.contains("line 3022") && !message.contains("row"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    let t = Table::read(&p).unwrap();
    assert_eq!(t.n_rows(), 3015);
    assert_eq!(t.dropped_repeated_rows, [3023]);
    assert_eq!(t.warnings.len(), 1, "{:?}", t.warnings);
    assert_eq!(t.warnings[0].line, 3023);
    let options = ReadOptions {
        repeated_time: RepeatedTime::KeepLast,
    };
    let t = Table::read_with(&p, &options).unwrap();
    assert_eq!(t.n_rows(), 3015);
    assert_eq!(t.dropped_repeated_rows, [3022]);
    assert_eq!(*t.time.last().unwrap(), 1.999);
}

#[test]
fn duplicate_labels_in_gait2392_reference_ik_are_an_error() {
    let Some(p) = reference("Pipelines/Gait2392_Simbody/OutputReference/subject01_walk1_ik.mot")
    else {
        return;
    };
    match Table::read(&p) {
        Err(Error::Model { line, element, .. }) => {
            assert_eq!((line, element.as_str()), (12, "column \"ground_force_vx\""))
        }
        other => panic!("{other:?}"),
    }
}

/// Every `.sto` / `.mot` in the reference data reads (repeated rows allowed), except the
/// one with duplicate labels, and survives a write/read round trip unchanged.
#[test]
fn every_reference_storage_file_reads_and_round_trips() {
    let Some(root) = reference("") else {
        return;
    };
    let mut stack = vec![root];
    let mut files = 0;
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            if !p.extension().is_some_and(|x| x == "sto" || x == "mot") {
                continue;
            }
            files += 1;
            let options = ReadOptions {
                repeated_time: RepeatedTime::KeepLast,
            };
            let t = match Table::read_with(&p, &options) {
                Ok(t) => t,
                Err(e) if e.to_string().contains("duplicate column label") => continue,
                Err(e) => panic!("{e}"),
            };
            let back = Table::parse(&t.to_file_string().unwrap(), "round trip").unwrap();
            assert_eq!(back.dialect, Dialect::OpenSim4);
            assert_eq!(
                (&back.name, back.in_degrees, &back.labels),
                (&t.name, t.in_degrees, &t.labels),
                "{}",
                p.display()
            );
            assert_eq!(
                (&back.metadata, &back.description),
                (&t.metadata, &t.description)
            );
            assert!(
                back.time == t.time && back.values == t.values,
                "{}",
                p.display()
            );
        }
    }
    assert!(files >= 100, "found only {files} storage files");
}

// ---------------------------------------------------------------------------------------
// OpenSim 4 dialect and other layouts (inline).

#[test]
fn opensim4_header_is_read() {
    // As STOFileAdapter writes it: name, sorted metadata, DataType, version=3, OpenSimVersion;
    // labels may contain spaces because columns are tab-separated.
    let text = "Moco solution\ninDegrees=no\nnum_controls=1\nDataType=double\nversion=3\n\
                OpenSimVersion=4.5-2024-01-10-abc\nendheader\n\
                time\t/forceset/soleus_r/activation\tsome label\n\
                0\t0.1\t-2.5e-3\n0.01\t0.2\t1E2\n";
    let t = Table::parse(text, "moco.sto").unwrap();
    assert_eq!(t.dialect, Dialect::OpenSim4);
    assert_eq!(t.name, "Moco solution");
    assert_eq!(t.in_degrees, Some(false));
    assert_eq!(t.metadata, [("num_controls".into(), "1".into())]);
    assert_eq!(t.labels, ["/forceset/soleus_r/activation", "some label"]);
    assert_eq!(t.time, [0.0, 0.01]);
    assert_eq!(t.values, [0.1, -2.5e-3, 0.2, 100.0]);
    assert_eq!(t.column("some label").unwrap(), [-2.5e-3, 100.0]);
}

#[test]
fn opensim4_header_without_name_line_is_read() {
    let text = "inDegrees=yes\r\nDataType=double\r\nversion=1\r\nOpenSimVersion=4.1\r\n\
                endheader\r\ntime q\r\n0.0 1\r\n";
    let t = Table::parse(text, "crlf.sto").unwrap();
    assert_eq!((t.name.as_str(), t.in_degrees), ("", Some(true)));
    assert_eq!((t.labels.len(), t.values.as_slice()), (1, &[1.0][..]));
}

#[test]
fn table_with_time_column_only_is_read() {
    let t = Table::parse(&format!("{HEADER}time\n0\n0.5\n"), "t").unwrap();
    assert_eq!((t.n_rows(), t.n_columns()), (2, 0));
}

// ---------------------------------------------------------------------------------------
// Bad input: each names the file, the line of the row and the column.

#[test]
fn non_numeric_value_is_an_error_naming_column_and_row() {
    let (line, element, message) =
        model_error(&format!("{HEADER}time\ta\tb\n0\t1\t2\n0.1\t3\tx4\n"));
    assert_eq!((line, element.as_str()), (7, "column \"b\""));
    assert!(
        message.contains("`x4`") && !message.contains("row 1"),
        "{message}"
    );
}

#[test]
fn nan_and_infinite_values_are_errors() {
    for bad in ["NaN", "nan", "inf", "-infinity", "1e999"] {
        let (line, element, _) = model_error(&format!("{HEADER}time a\n0 1\n0.1 {bad}\n"));
        assert_eq!((line, element.as_str()), (7, "column \"a\""), "{bad}");
    }
    let (_, element, _) = model_error(&format!("{HEADER}time a\nnan 1\n"));
    assert_eq!(element, "column \"time\"");
}

#[test]
fn row_with_too_few_values_names_the_first_missing_column() {
    let (line, element, message) = model_error(&format!("{HEADER}time a b c\n0 1 2 3\n1 4\n"));
    assert_eq!((line, element.as_str()), (7, "column \"b\""));
    assert!(
        message.contains("has 2 values, expected 4") && !message.contains("row 1"),
        "{message}"
    );
}

#[test]
fn row_with_too_many_values_names_the_surplus_column() {
    let (line, element, _) = model_error(&format!("{HEADER}time a\n0 1 2\n"));
    assert_eq!(
        (line, element.as_str()),
        (6, "column 3 (beyond the last label)")
    );
}

#[test]
fn decreasing_time_is_an_error() {
    let (line, element, message) = model_error(&format!("{HEADER}time a\n0 1\n0.2 1\n0.1 1\n"));
    assert_eq!((line, element.as_str()), (8, "column \"time\""));
    assert!(
        message.contains("line 7") && message.contains("earlier") && !message.contains("row"),
        "{message}"
    );
}

#[test]
fn repeated_time_is_dropped_by_default_kept_last_or_an_error_on_request() {
    let text = format!("{HEADER}time a\n0 1\n0.1 2\n0.1 3\n0.2 4\n");
    let strict = ReadOptions {
        repeated_time: RepeatedTime::Error,
    };
    let e = Table::parse_with(&text, "t", &strict).unwrap_err();
    let Error::Model {
        line,
        element,
        message,
        ..
    } = e
    else {
        panic!("{e:?}")
    };
    assert_eq!((line, element.as_str()), (8, "column \"time\""));
    assert!(message.contains("repeats"), "{message}");
    let t = Table::parse(&text, "t").unwrap();
    assert_eq!(
        (t.values.as_slice(), t.dropped_repeated_rows.as_slice()),
        (&[1.0, 2.0, 4.0][..], &[8][..])
    );
    let w = t.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>();
    assert_eq!(
        w,
        ["t:8: column \"time\": time 0.1 repeats the time on line 7: row left out"]
    );
    let last = ReadOptions {
        repeated_time: RepeatedTime::KeepLast,
    };
    let t = Table::parse_with(&text, "t", &last).unwrap();
    assert_eq!(
        (t.values.as_slice(), t.dropped_repeated_rows.as_slice()),
        (&[1.0, 3.0, 4.0][..], &[7][..])
    );
    assert_eq!(t.time, [0.0, 0.1, 0.2]);
    assert_eq!(t.warnings[0].line, 7);
}

#[test]
fn a_near_repeated_time_is_dropped_like_an_exact_repeat() {
    // The last row repeats 2.0 s plus 6.6e-14 s: the same sample written twice.
    let text = format!("{HEADER}time a\n1.98 1\n1.99 2\n2 3\n2.000000000000066 3.5\n");
    let t = Table::parse(&text, "walk.mot").unwrap();
    assert_eq!(t.time, [1.98, 1.99, 2.0]);
    assert_eq!(t.values, [1.0, 2.0, 3.0]);
    assert_eq!(t.dropped_repeated_rows, [9]);
    let w = t.warnings[0].to_string();
    assert!(
        w.starts_with(
            "walk.mot:9: column \"time\": time 2.000000000000066 repeats the time on \
                       line 8 (within 6.6e-14 s)"
        ),
        "{w}"
    );
    // A near-repeat slightly earlier is a repeat too, not a decreasing time.
    let text = format!("{HEADER}time a\n1.98 1\n1.99 2\n2 3\n1.999999999999934 3.5\n");
    let t = Table::parse(&text, "walk.mot").unwrap();
    assert_eq!((t.n_rows(), t.warnings.len()), (3, 1));
    // A step of a thousandth of the sampling interval is a sample, not a repeat.
    let text = format!("{HEADER}time a\n1.98 1\n1.99 2\n2 3\n2.00001 3.5\n");
    let t = Table::parse(&text, "walk.mot").unwrap();
    assert_eq!((t.n_rows(), t.warnings.len()), (4, 0));
    // Beyond the tolerance, an earlier time is an error.
    let text = format!("{HEADER}time a\n1.98 1\n1.99 2\n2 3\n1.99999 3.5\n");
    let (line, _, message) = model_error(&text);
    assert_eq!(line, 9);
    assert!(message.contains("earlier"), "{message}");
}

#[test]
fn missing_time_column_is_an_error() {
    let (line, element, message) = model_error(&format!("{HEADER}t a\n0 1\n"));
    assert_eq!((line, element.as_str()), (5, "column \"t\""));
    assert!(message.contains("`time`"));
}

#[test]
fn duplicate_labels_are_an_error() {
    let (line, element, message) = model_error(&format!("{HEADER}time a b a\n0 1 2 3\n"));
    assert_eq!((line, element.as_str()), (5, "column \"a\""));
    assert!(message.contains("columns 2 and 4"), "{message}");
    let (_, element, _) = model_error(&format!("{HEADER}time a time\n0 1 2\n"));
    assert_eq!(element, "column \"time\"");
}

#[test]
fn table_without_rows_is_an_error() {
    let (line, element, _) = model_error(&format!("{HEADER}time a\n\n"));
    assert_eq!((line, element.as_str()), (5, "table"));
    let (line, element, _) = model_error(HEADER);
    assert_eq!((line, element.as_str()), (4, "table"));
}

#[test]
fn empty_file_and_missing_endheader_are_errors() {
    let (line, element, message) = model_error("");
    assert_eq!((line, element.as_str()), (1, "header"));
    assert!(message.contains("empty"));
    let (line, _, message) = model_error("name\nversion=1\ntime a\n0 1\n");
    assert_eq!(line, 4);
    assert!(
        message.contains("line 3 looks like the column labels"),
        "{message}"
    );
}

#[test]
fn a_declared_row_count_that_disagrees_is_a_warning_and_a_column_count_an_error() {
    let text = "x\nversion=1\nnRows=3\nnColumns=2\nendheader\ntime a\n0 1\n1 2\n";
    let t = Table::parse(text, "few.mot").unwrap();
    assert_eq!(t.time, [0.0, 1.0]);
    let w: Vec<String> = t.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(
        w,
        ["few.mot:3: header \"nRows\": declares 3 rows, but the file holds 2: all 2 are read"]
    );
    // SIMM's `datarows`, declaring fewer rows than there are.
    let text = "name x\ndatacolumns 2\ndatarows 1\nrange 0 2\nendheader\ntime a\n0 1\n1 2\n2 3\n";
    let t = Table::parse(text, "simm.mot").unwrap();
    assert_eq!(t.n_rows(), 3);
    assert!(
        t.warnings[0]
            .to_string()
            .starts_with("simm.mot:3: header \"datarows\": declares 1 rows, but the file holds 3"),
        "{:?}",
        t.warnings
    );
    let (line, element, _) =
        model_error("x\nversion=1\nnRows=1\nnColumns=3\nendheader\ntime a\n0 1\n");
    assert_eq!((line, element.as_str()), (4, "header \"nColumns\""));
    let (line, element, _) =
        model_error("name x\ndatacolumns 2\ndatarows 1\nnRows=2\nendheader\ntime a\n0 1\n");
    assert_eq!((line, element.as_str()), (4, "header \"nRows\""));
}

#[test]
fn bad_header_values_are_errors() {
    let (line, element, _) = model_error("x\ninDegrees=maybe\nendheader\ntime a\n0 1\n");
    assert_eq!((line, element.as_str()), (2, "header \"inDegrees\""));
    let (_, element, message) = model_error("x\nDataType=Vec3\nendheader\ntime a\n0 1,2,3\n");
    assert_eq!(element, "header \"DataType\"");
    assert!(message.contains("Vec3"));
    let (_, element, _) = model_error("x\nversion=one\nendheader\ntime a\n0 1\n");
    assert_eq!(element, "header \"version\"");
    let (line, element, _) = model_error("range of motion\nendheader\ntime a\n0 1\n");
    assert_eq!((line, element.as_str()), (1, "header \"range\""));
}

#[test]
fn read_of_missing_file_is_an_io_error_with_the_path() {
    let p = Path::new("/nonexistent/dir/file.sto");
    match Table::read(p) {
        Err(Error::Io { path, .. }) => assert_eq!(path, p),
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// Writing.

/// A file name in the system's temporary directory, unique to this test process.
fn temp_path(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("musculo-storage-{}-{name}", std::process::id()))
}

fn awkward_table() -> Table {
    let values = vec![
        0.1,
        1.0 / 3.0,
        -2.5e-7,
        1e-300,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        -0.0,
        123456789.123456789,
        6.02214076e23,
        -1.0,
        0.0,
    ];
    let mut t = Table::new(
        "awkward",
        vec!["a".into(), "b".into(), "/forceset/m/activation".into()],
        vec![0.0, 1.0 / 3.0, 0.7, 1e6],
        values,
    )
    .unwrap();
    t.in_degrees = Some(true);
    t.metadata = vec![
        ("DataRate".into(), "100".into()),
        ("units".into(), "m".into()),
    ];
    t.description = vec!["Units are S.I. units (second, meters, Newtons, ...)".into()];
    t
}

#[test]
fn write_then_read_gives_identical_values() {
    let t = awkward_table();
    let path = temp_path("round_trip.sto");
    t.write(&path).unwrap();
    let mut back = Table::read(&path).unwrap();
    // The rows' lines: the label row follows the header, one row per line after it.
    let lines = back
        .lines
        .take()
        .expect("a table read from a file knows its lines");
    let first = lines.labels + 1;
    assert_eq!(
        lines.rows,
        (first..first + t.n_rows() as u32).collect::<Vec<_>>()
    );
    assert_eq!(back, t);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back.values), bits(&t.values));
    assert_eq!(bits(&back.time), bits(&t.time));
    // No temporary file is left beside it.
    let file_name = path.file_name().unwrap().to_string_lossy().into_owned();
    let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(&file_name))
        .collect();
    assert_eq!(names, [file_name]);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn written_header_is_what_opensim_readers_expect() {
    let text = awkward_table().to_file_string().unwrap();
    let header: Vec<&str> = text.lines().take(12).collect();
    assert_eq!(
        header,
        [
            "awkward",
            "version=1",
            "nRows=4",
            "nColumns=4",
            "inDegrees=yes",
            "Units are S.I. units (second, meters, Newtons, ...)",
            "DataRate=100",
            "units=m",
            "DataType=double",
            "OpenSimVersion=4.5",
            "endheader",
            "time\ta\tb\t/forceset/m/activation",
        ]
    );
    assert_eq!(
        text.lines().nth(12).unwrap(),
        "0\t0.1\t0.3333333333333333\t-2.5e-7"
    );
}

#[test]
fn write_overwrites_an_existing_file_whole() {
    let path = temp_path("overwrite.mot");
    awkward_table().write(&path).unwrap();
    let small = Table::new("small", vec!["q".into()], vec![0.0], vec![1.5]).unwrap();
    small.write(&path).unwrap();
    let mut back = Table::read(&path).unwrap();
    back.lines = None;
    assert_eq!(back, small);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn write_refuses_invalid_tables_and_reports_io_errors_with_the_path() {
    let mut t = awkward_table();
    t.values[4] = f64::NAN;
    let path = temp_path("never_written.sto");
    assert!(matches!(t.write(&path), Err(Error::InvalidArgument { .. })));
    assert!(!path.exists());

    for labels in [
        vec!["a\tb".to_string()],
        vec![" a".to_string()],
        vec!["time".into()],
        vec![String::new()],
    ] {
        assert!(Table::new("x", labels, vec![0.0], vec![1.0]).is_err());
    }
    assert!(Table::new("x", vec!["a".into(), "a".into()], vec![0.0], vec![1.0, 2.0]).is_err());
    assert!(Table::new("x", vec!["a".into()], vec![0.0, 0.0], vec![1.0, 2.0]).is_err());
    assert!(Table::new("x", vec!["a".into()], vec![], vec![]).is_err());
    assert!(Table::new("x", vec!["a".into()], vec![0.0], vec![1.0, 2.0]).is_err());
    for name in ["nRows 3", "a=b", "12.5 3", "two\nlines", " padded"] {
        assert!(
            Table::new(name, vec![], vec![0.0], vec![]).is_err(),
            "{name:?}"
        );
    }
    let mut t = awkward_table();
    t.metadata.push(("nRows".into(), "1".into()));
    assert!(t.validate().is_err());
    let mut t = awkward_table();
    t.description.push("version 2".into());
    assert!(t.validate().is_err());

    let bad = Path::new("/nonexistent/dir/out.sto");
    match awkward_table().write(bad) {
        Err(Error::Output { path, .. }) => assert_eq!(path, bad),
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// Access and interpolation.

#[test]
fn interpolate_is_linear_between_rows_and_clamped_at_the_ends() {
    let t = Table::parse(&format!("{HEADER}time a b\n0 0 10\n1 2 10\n3 -2 20\n"), "t").unwrap();
    let a = t.column_index("a").unwrap();
    let b = t.column_index("b").unwrap();
    assert_eq!(t.interpolate(a, 0.5).unwrap(), 1.0);
    assert_eq!(t.interpolate(a, 1.0).unwrap(), 2.0);
    assert_eq!(t.interpolate(a, 2.0).unwrap(), 0.0);
    assert_eq!(t.interpolate(b, 2.5).unwrap(), 17.5);
    assert_eq!(t.interpolate(a, -1.0).unwrap(), 0.0);
    assert_eq!(t.interpolate(a, 7.0).unwrap(), -2.0);
    assert!(t.interpolate(2, 0.5).is_err());
    assert!(t.interpolate(a, f64::NAN).is_err());
    assert_eq!(t.column("b").unwrap(), [10.0, 10.0, 20.0]);
    assert_eq!(t.column("c"), None);
    assert_eq!(t.row(2).unwrap(), [-2.0, 20.0]);
    assert_eq!(t.row(3), None);
    assert_eq!(t.value(0, 2), None);
}

#[test]
fn parse_never_panics_on_mutated_input() {
    // Deterministic mutations (xorshift) of a small valid file: every outcome must be a
    // content error or a table that validates and survives a write/read round trip; never a
    // panic.
    let base = "arm\nversion=1\nnRows=3\nnColumns=3\ninDegrees=no\nendheader\n\
                time\ta\tb\n0\t1\t2\n0.5\t3e-2\t-4\n1\t5\t6\n";
    let pieces = [
        "",
        "\t",
        " ",
        "\n",
        "=",
        "endheader",
        "time",
        "nan",
        "1e400",
        "-",
        "0.5",
        "x",
    ];
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    for _ in 0..20_000 {
        let mut text = base.to_string();
        for _ in 0..1 + next(3) {
            let at = next(text.len() + 1);
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            let cut = (at + next(4)).min(text.len());
            let cut = (cut..=text.len())
                .find(|&i| text.is_char_boundary(i))
                .unwrap();
            text.replace_range(at..cut, pieces[next(pieces.len())]);
        }
        match Table::parse(&text, "fuzz") {
            Ok(t) => {
                let written = t.to_file_string().unwrap_or_else(|e| {
                    panic!("read a table that does not validate ({e}) from {text:?}")
                });
                let mut back = Table::parse(&written, "again").unwrap();
                back.dialect = t.dialect;
                back.dropped_repeated_rows
                    .clone_from(&t.dropped_repeated_rows);
                back.warnings.clone_from(&t.warnings);
                back.lines.clone_from(&t.lines);
                assert_eq!(back, t, "round trip of {text:?}");
            }
            Err(Error::Model { .. }) => {}
            Err(e) => panic!("unexpected error kind {e:?} for {text:?}"),
        }
    }
}
