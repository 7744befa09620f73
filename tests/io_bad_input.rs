//! Bad input to the motion, external-load, marker and setup readers and to inverse dynamics:
//! each is an error naming the file, the column (or element) and the row (or line) — or, for
//! the one suspicion that cannot be decided from the file, a documented warning.
//!
//! Degrees vs radians: a file's `inDegrees` header is honoured (a SIMM `.mot` without one
//! counts as degrees, as OpenSim reads it). When a file read as radians holds a rotational
//! coordinate beyond 2π although the model limits it to ±2π, inverse dynamics still honours
//! the header but returns a warning naming the file, the column, the row and the value.

use musculo::Model;
use musculo::io::Table;
use musculo::io::setup::InverseDynamicsSetup;
use musculo::io::trc::Trc;
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use std::path::PathBuf;

/// A fresh directory for this test's files, removed when the test ends.
struct Scratch(PathBuf);

impl Scratch {
    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn scratch(test: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!(
        "musculo-io-bad-input-{}-{test}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// A motion of the demo model (every independent coordinate), degrees for rotations.
fn demo_motion(
    labels: &[&str],
    rows: usize,
    in_degrees: &str,
    row: impl Fn(usize) -> Vec<String>,
) -> String {
    let mut s = format!(
        "demo motion\nversion=1\nnRows={rows}\nnColumns={}\ninDegrees={in_degrees}\nendheader\ntime\t{}\n",
        labels.len() + 1,
        labels.join("\t")
    );
    for r in 0..rows {
        s += &format!("{}\t{}\n", r as f64 * 0.01, row(r).join("\t"));
    }
    s
}

const DEMO_COORDS: [&str; 6] = [
    "pelvis_tilt",
    "pelvis_tx",
    "pelvis_ty",
    "hip_flexion",
    "knee_angle",
    "ankle_angle",
];

fn walkish(r: usize, degrees: bool) -> Vec<String> {
    let t = r as f64 * 0.01;
    let k = if degrees {
        180.0 / std::f64::consts::PI
    } else {
        1.0
    };
    [
        0.1 * (3.0 * t).sin() * k,
        1.2 * t,
        0.93 + 0.02 * (6.0 * t).cos(),
        0.4 * (6.0 * t).sin() * k,
        -0.6 * (1.0 - (6.0 * t).cos()) * k,
        0.2 * (6.0 * t).sin() * k,
    ]
    .iter()
    .map(|v| v.to_string())
    .collect()
}

fn run_id(
    path: &std::path::Path,
) -> musculo::Result<musculo::solve::inverse_dynamics::InverseDynamicsOutput> {
    let model = Model::demo();
    let table = Table::read(path)?;
    inverse_dynamics(
        &model,
        &table,
        &path.display().to_string(),
        None,
        &InverseDynamicsOptions {
            lowpass_hz: Some(6.0),
            ..Default::default()
        },
        &mut |_, _| {},
    )
}

#[test]
fn a_motion_without_a_coordinate_column_is_an_error_naming_file_and_column() {
    let d = scratch("missing-column");
    let path = d.join("no_knee.mot");
    let labels: Vec<&str> = DEMO_COORDS
        .iter()
        .copied()
        .filter(|c| *c != "knee_angle")
        .collect();
    std::fs::write(
        &path,
        demo_motion(&labels, 20, "yes", |r| {
            let mut v = walkish(r, true);
            v.remove(4);
            v
        }),
    )
    .unwrap();
    let e = run_id(&path).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(
        e.contains("no_knee.mot") && e.contains("column \"knee_angle\"") && e.contains("no column"),
        "{e}"
    );
}

#[test]
fn degrees_under_in_degrees_no_are_honoured_with_a_warning_naming_column_and_row() {
    let d = scratch("degrees");
    let path = d.join("says_radians.mot");
    std::fs::write(
        &path,
        demo_motion(&DEMO_COORDS, 60, "no", |r| walkish(r, true)),
    )
    .unwrap();
    let out = run_id(&path).unwrap();
    for w in &out.warnings {
        eprintln!("warning: {w}");
    }
    let w: Vec<&String> = out
        .warnings
        .iter()
        .filter(|w| w.contains("look like degrees"))
        .collect();
    // Hip, knee and ankle exceed 2π as radians (their peaks, in degrees: 22.9, −68.7, 11.5);
    // the pelvis tilt (≤ 5.7°) does not.
    assert_eq!(w.len(), 3, "{:?}", out.warnings);
    assert!(
        // Row 52 (time 0.52) is on line 60: 6 header lines, the labels, rows from line 8.
        w[1].contains("says_radians.mot:60: column \"knee_angle\" (time 0.52): -68.74")
            && w[1].contains("inDegrees=no"),
        "{}",
        w[1]
    );
    // The same values in radians: no such warning.
    let path = d.join("radians.mot");
    std::fs::write(
        &path,
        demo_motion(&DEMO_COORDS, 60, "no", |r| walkish(r, false)),
    )
    .unwrap();
    let out = run_id(&path).unwrap();
    assert!(
        !out.warnings.iter().any(|w| w.contains("degrees")),
        "{:?}",
        out.warnings
    );
}

#[test]
fn a_simm_mot_without_in_degrees_is_read_in_degrees_as_opensim_does() {
    let d = scratch("simm");
    let rows = 40;
    let body = |deg: bool| -> String {
        (0..rows)
            .map(|r| format!("{}\t{}\n", r as f64 * 0.01, walkish(r, deg).join("\t")))
            .collect()
    };
    let simm = d.join("simm.mot");
    std::fs::write(
        &simm,
        format!(
            "name simm\ndatacolumns 7\ndatarows {rows}\nrange 0 0.39\nendheader\ntime\t{}\n{}",
            DEMO_COORDS.join("\t"),
            body(true)
        ),
    )
    .unwrap();
    let radians = d.join("radians.mot");
    std::fs::write(
        &radians,
        demo_motion(&DEMO_COORDS, rows, "no", |r| walkish(r, false)),
    )
    .unwrap();
    let (a, b) = (
        run_id(&simm).unwrap().table,
        run_id(&radians).unwrap().table,
    );
    assert_eq!(a.n_rows(), b.n_rows());
    for (x, y) in a.values.iter().zip(&b.values) {
        assert!((x - y).abs() <= 1e-6 * (1.0 + y.abs()), "{x} vs {y}");
    }
}

#[test]
fn time_that_goes_back_is_an_error_naming_file_column_and_row() {
    let d = scratch("time");
    let path = d.join("back.mot");
    let mut text = demo_motion(&DEMO_COORDS, 10, "yes", |r| walkish(r, true));
    text = text.replace("\n0.05\t", "\n0.03\t");
    std::fs::write(&path, text).unwrap();
    let e = Table::read(&path).unwrap_err().to_string();
    eprintln!("{e}");
    // The sixth row is on line 13 (6 header lines, the labels, rows from line 8); the message
    // names the line of the row before it, never a row index counted from 0.
    assert!(
        e.contains("back.mot:13")
            && e.contains("column \"time\"")
            && e.contains("line 12")
            && !e.contains("row 5"),
        "{e}"
    );
}

#[test]
fn a_nan_row_is_an_error_naming_file_column_and_row() {
    let d = scratch("nan");
    let path = d.join("nan.mot");
    let text = demo_motion(&DEMO_COORDS, 10, "yes", |r| {
        let mut v = walkish(r, true);
        if r == 3 {
            v[3] = "NaN".into();
        }
        v
    });
    std::fs::write(&path, text).unwrap();
    let e = Table::read(&path).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(
        e.contains("nan.mot:11")
            && e.contains("column \"hip_flexion\"")
            && e.contains("`NaN`")
            && !e.contains("row 3"),
        "{e}"
    );
}

const GRF: &str = "grf\nversion=1\nnRows=4\nnColumns=10\ninDegrees=no\nendheader\n\
time\tf_vx\tf_vy\tf_vz\tf_px\tf_py\tf_pz\tt_x\tt_y\tt_z\n\
0\t0\t700\t0\t0.1\t0\t0\t0\t0\t0\n0.1\t0\t710\t0\t0.1\t0\t0\t0\t0\t0\n\
0.2\t0\t720\t0\t0.1\t0\t0\t0\t0\t0\n0.3\t0\t730\t0\t0.1\t0\t0\t0\t0\t0\n";

fn loads_xml(body: &str, torque: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<OpenSimDocument Version="40000">
  <ExternalLoads name="grf">
    <objects>
      <ExternalForce name="right">
        <applied_to_body>{body}</applied_to_body>
        <force_expressed_in_body>ground</force_expressed_in_body>
        <point_expressed_in_body>ground</point_expressed_in_body>
        <force_identifier>f_v</force_identifier>
        <point_identifier>f_p</point_identifier>
        <torque_identifier>{torque}</torque_identifier>
      </ExternalForce>
    </objects>
    <datafile>grf.mot</datafile>
  </ExternalLoads>
</OpenSimDocument>
"#
    )
}

#[test]
fn external_loads_naming_an_unknown_body_are_an_error_naming_file_element_and_line() {
    let d = scratch("loads-body");
    std::fs::write(d.join("grf.mot"), GRF).unwrap();
    let xml = d.join("loads.xml");
    std::fs::write(&xml, loads_xml("calcn_r", "t_")).unwrap();
    let e = ExternalLoadSet::read(&Model::demo(), &xml)
        .unwrap_err()
        .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("loads.xml:5")
            && e.contains("ExternalForce \"right\" > <applied_to_body>")
            && e.contains("calcn_r"),
        "{e}"
    );
    // The same file with the demo's foot works.
    std::fs::write(&xml, loads_xml("foot", "t_")).unwrap();
    let set = ExternalLoadSet::read(&Model::demo(), &xml).unwrap();
    assert_eq!(set.forces[0].columns.len(), 9);
}

#[test]
fn an_identifier_without_three_columns_is_an_error_naming_data_file_and_column() {
    let d = scratch("loads-columns");
    std::fs::write(d.join("grf.mot"), GRF).unwrap();
    let xml = d.join("loads.xml");
    std::fs::write(&xml, loads_xml("foot", "torque_")).unwrap();
    let e = ExternalLoadSet::read(&Model::demo(), &xml)
        .unwrap_err()
        .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("grf.mot") && e.contains("column \"torque_*\"") && e.contains("found 0"),
        "{e}"
    );
}

const TRC: &str = "PathFileType\t4\t(X/Y/Z)\tm.trc\n\
DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
60\t60\t3\t2\tmm\t60\t1\t3\n\
Frame#\tTime\tHEEL\t\t\tTOE\t\t\t\n\
\t\tX1\tY1\tZ1\tX2\tY2\tZ2\t\n\
\n\
1\t0\t10\t20\t30\t110\t20\t30\t\n\
2\t0.016667\t11\t21\t31\t\t\t\t\n\
3\t0.033333\t12\t22\t32\t112\t22\t32\t\n";

#[test]
fn trc_missing_markers_are_reported_not_errors() {
    let t = Trc::parse(TRC, "m.trc").unwrap();
    let missing = t.missing();
    assert_eq!(missing.len(), 1);
    assert_eq!(
        (
            missing[0].name.as_str(),
            missing[0].frames,
            missing[0].gaps.clone()
        ),
        ("TOE", 1, vec![[1, 1]])
    );
    assert!(t.position(1, 1).x.is_nan());
    assert_eq!(t.position(2, 1).x, 0.112);
    // Written and read back from disk, missing markers stay missing.
    let d = scratch("trc");
    let path = d.join("back.trc");
    t.write(&path).unwrap();
    let back = Trc::read(&path).unwrap();
    assert_eq!(back.missing(), missing);
    assert_eq!(back.markers, t.markers);
}

#[test]
fn trc_bad_rows_are_errors_naming_file_marker_and_row() {
    // Wrong number of values.
    let e = Trc::parse(
        &TRC.replace(
            "3\t0.033333\t12\t22\t32\t112\t22\t32\t",
            "3\t0.033333\t12\t22\t32\t112\t22",
        ),
        "m.trc",
    )
    .unwrap_err()
    .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("m.trc:9")
            && e.contains("marker \"TOE\" (column Z2)")
            && e.contains("the row has 7 values"),
        "{e}"
    );
    // Not a number.
    let e = Trc::parse(&TRC.replace("\t21\t", "\t2l\t"), "m.trc")
        .unwrap_err()
        .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("m.trc:8")
            && e.contains("marker \"HEEL\" (column Y1)")
            && e.contains("`2l` is not a number"),
        "{e}"
    );
    // Duplicate marker names.
    let e = Trc::parse(&TRC.replace("\tTOE\t", "\tHEEL\t"), "m.trc")
        .unwrap_err()
        .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("m.trc:4") && e.contains("marker \"HEEL\"") && e.contains("duplicate"),
        "{e}"
    );
    // Time going back.
    let e = Trc::parse(&TRC.replace("0.033333", "0.01"), "m.trc")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.trc:9") && e.contains("column \"Time\"") && e.contains("line 8"),
        "{e}"
    );
}

#[test]
fn malformed_setup_xml_is_an_xml_error_with_its_place() {
    let d = scratch("setup");
    let path = d.join("setup.xml");
    std::fs::write(
        &path,
        "<OpenSimDocument><InverseDynamicsTool name=\"x\">\n<model_file>m.osim</model_fil>\n</InverseDynamicsTool></OpenSimDocument>",
    )
    .unwrap();
    let e = InverseDynamicsSetup::read(&path).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, musculo::Error::Xml { line: 2, .. }), "{e:?}");
    assert!(e.to_string().contains("setup.xml:2"), "{e}");
}
