//! Files OpenSim accepts that musculo used to refuse (issue 12, group 1), each rebuilt here
//! from generated text: a row count in the header that disagrees with the rows, an
//! `<ActuatorSet>` force-set file, Windows separators in data-file paths, repeated and
//! near-repeated times, bodies whose inertia violates the triangle inequality, and
//! `PrescribedForce` in an ExternalLoads file.

mod common;
use common::{ScratchDir, run_musculo};

use musculo::io::external_loads::ExternalLoads;
use musculo::io::setup::InverseDynamicsSetup;
use musculo::io::{ReadOptions, RepeatedTime, Table};
use musculo::model::{ForceSetFiles, LoadOptions, Model, WarningKind};
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use musculo::spatial::Vec3;
use musculo::{Data, dynamics};
use std::path::PathBuf;

/// The demo model's independent coordinates in a smooth motion: `rows` samples at 100 Hz,
/// as a storage file's text (radians), with `extra` appended after the last row.
fn demo_motion(rows: usize, n_rows_declared: usize, extra: &str) -> String {
    let model = Model::demo();
    let names: Vec<&str> = model
        .reduction
        .independent
        .iter()
        .map(|&c| model.coordinates[c].name.as_str())
        .collect();
    let mut text = format!(
        "demo motion\nversion=1\nnRows={n_rows_declared}\nnColumns={}\ninDegrees=no\n\
         endheader\ntime\t{}\n",
        names.len() + 1,
        names.join("\t")
    );
    for r in 0..rows {
        let t = r as f64 * 0.01;
        text.push_str(&row(t, names.len()));
    }
    text.push_str(extra);
    text
}

/// One row of [`demo_motion`] at time `t` (written as `t` prints).
fn row(t: f64, n: usize) -> String {
    let mut line = format!("{t}");
    for j in 0..n {
        let phase = j as f64;
        // Small smooth angles and translations.
        let v = 0.2 * (2.0 * t + phase).sin() + 0.05 * (5.0 * t + 0.3 * phase).cos();
        line.push_str(&format!("\t{v}"));
    }
    line.push('\n');
    line
}

fn demo_osim(dir: &ScratchDir, name: &str, xml: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, xml).unwrap();
    p
}

// ---------------------------------------------------------------------------------------
// 1. A header row count that disagrees with the rows.

#[test]
fn a_datarows_count_that_disagrees_is_read_with_a_warning_printed_by_the_cli() {
    let dir = ScratchDir::new("accepts-nrows");
    let model = demo_osim(&dir, "demo.osim", musculo::DEMO_MODEL_OSIM);
    let coords = dir.join("walk.mot");
    std::fs::write(&coords, demo_motion(40, 45, "")).unwrap();
    let t = Table::read(&coords).unwrap();
    assert_eq!(t.n_rows(), 40);
    let w = t.warnings[0].to_string();
    assert!(
        w.contains("walk.mot:3:") && w.contains("declares 45 rows, but the file holds 40"),
        "{w}"
    );
    let out = dir.join("tau.sto");
    let (ok, _, err) = run_musculo(&[
        "id",
        "--model",
        model.to_str().unwrap(),
        "--coordinates",
        coords.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let warning = err
        .lines()
        .find(|l| l.contains("declares 45 rows"))
        .unwrap_or_else(|| panic!("no warning on stderr:\n{err}"));
    assert!(
        warning.starts_with("warning: ") && warning.contains("walk.mot:3: header \"nRows\""),
        "{warning}"
    );
    assert_eq!(Table::read(&out).unwrap().n_rows(), 40);
}

// ---------------------------------------------------------------------------------------
// 2. OpenSim 2–3 force-set files: <ActuatorSet>.

#[test]
fn an_actuator_set_file_adds_its_actuators_like_a_force_set() {
    let set = |tag: &str| {
        format!(
            r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenSimDocument Version="20302">
  <{tag} name="reserves">
    <objects>
      <CoordinateActuator name="knee_reserve">
        <coordinate> knee_angle </coordinate>
        <optimal_force> 25 </optimal_force>
      </CoordinateActuator>
    </objects>
    <groups />
  </{tag}>
</OpenSimDocument>"#
        )
    };
    let read = |text: String| {
        Model::from_osim_str_with_force_sets(
            musculo::DEMO_MODEL_OSIM,
            "demo.osim",
            &LoadOptions::default(),
            &ForceSetFiles {
                files: vec![(text, "reserves.xml".into())],
                replace: false,
            },
        )
    };
    let old = read(set("ActuatorSet")).unwrap();
    let new = read(set("ForceSet")).unwrap();
    let reserve = |m: &Model| {
        m.forces
            .iter()
            .find(|f| f.name == "knee_reserve")
            .cloned()
            .expect("the reserve is added")
    };
    assert_eq!(
        format!("{:?}", reserve(&old)),
        format!("{:?}", reserve(&new))
    );
    assert!(reserve(&old).actuator.is_some(), "read as an actuator");
    assert_eq!(old.forces.len(), Model::demo().forces.len() + 1);
    // Anything else is still refused, naming both set tags.
    let e = read(set("ControllerSet")).unwrap_err().to_string();
    assert!(
        e.contains("reserves.xml:2") && e.contains("<ActuatorSet>"),
        "{e}"
    );
}

/// OpenSim removes whitespace from component names in documents older than Version 30500
/// (with a warning) and refuses it in newer ones; a force-set file is read the same way.
#[test]
fn whitespace_in_a_name_is_removed_in_an_old_force_set_file_and_refused_in_a_new_one() {
    let set = |version: u32| {
        format!(
            r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenSimDocument Version="{version}">
  <ActuatorSet name="reserves">
    <objects>
      <CoordinateActuator name="knee reserve">
        <coordinate>knee_angle</coordinate>
      </CoordinateActuator>
    </objects>
  </ActuatorSet>
</OpenSimDocument>"#
        )
    };
    let read = |text: String| {
        Model::from_osim_str_with_force_sets(
            musculo::DEMO_MODEL_OSIM,
            "demo.osim",
            &LoadOptions::default(),
            &ForceSetFiles {
                files: vec![(text, "reserves.xml".into())],
                replace: false,
            },
        )
    };
    let old = read(set(20302)).expect("an OpenSim 2 file's name loses its space");
    assert!(old.forces.iter().any(|f| f.name == "kneereserve"));
    let warning = old
        .warnings
        .iter()
        .find(|w| w.message.contains("\"knee reserve\""))
        .unwrap_or_else(|| panic!("no warning names the renamed force: {:?}", old.warnings));
    assert!(
        warning.message.contains("\"kneereserve\""),
        "{}",
        warning.message
    );
    let e = read(set(40000)).unwrap_err().to_string();
    assert!(
        e.contains("reserves.xml:5") && e.contains("\"knee reserve\" contains a space"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// 3. Windows separators in paths from setup and ExternalLoads files.

#[test]
fn windows_backslashes_in_data_paths_resolve_in_external_loads_and_setups() {
    let dir = ScratchDir::new("accepts-backslash");
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::create_dir_all(dir.join("ID")).unwrap();
    let grf = dir.join("data").join("grf.mot");
    std::fs::write(
        &grf,
        "grf\nversion=1\nnRows=2\nnColumns=4\ninDegrees=no\nendheader\n\
         time\tf_vx\tf_vy\tf_vz\n0\t0\t1\t0\n1\t0\t2\t0\n",
    )
    .unwrap();
    let loads = dir.join("ID").join("loads.xml");
    std::fs::write(
        &loads,
        r#"<OpenSimDocument Version="40000"><ExternalLoads name="x"><objects>
        <ExternalForce name="f"><applied_to_body>shank</applied_to_body>
        <force_identifier>f_v</force_identifier></ExternalForce></objects>
        <datafile>..\data\grf.mot</datafile></ExternalLoads></OpenSimDocument>"#,
    )
    .unwrap();
    let l = ExternalLoads::read(&loads).unwrap();
    let resolved = l.datafile.clone().unwrap();
    assert_eq!(
        resolved.canonicalize().unwrap(),
        grf.canonicalize().unwrap()
    );
    let set = ExternalLoadSet::read(&Model::demo(), &loads).unwrap();
    assert_eq!(set.forces.len(), 1);

    let setup = dir.join("ID").join("setup.xml");
    let text = r#"<OpenSimDocument Version="40000"><InverseDynamicsTool name="w">
        <model_file>..\demo.osim</model_file>
        <coordinates_file>..\data\grf.mot</coordinates_file>
        <external_loads_file>loads.xml</external_loads_file>
        </InverseDynamicsTool></OpenSimDocument>"#;
    std::fs::write(&setup, text).unwrap();
    let s = InverseDynamicsSetup::read(&setup).unwrap();
    let coords = s.coordinates_file.unwrap();
    assert_eq!(coords.canonicalize().unwrap(), grf.canonicalize().unwrap());
    // A file that does not exist either way keeps the separators read as such, for the
    // error to show where it was looked for.
    let model = s.model_file.unwrap();
    assert_eq!(model, dir.join("ID").join("..").join("demo.osim"));
}

// ---------------------------------------------------------------------------------------
// 4. Repeated times.

#[test]
fn exact_and_near_repeated_times_are_dropped_alike_with_a_warning() {
    let last = row(0.39, 6);
    let near = last.replacen("0.39", "0.39000000000006604", 1);
    for (what, extra) in [("exact", last.clone()), ("near", near)] {
        let text = demo_motion(40, 41, &extra);
        let t = Table::parse(&text, "walk.mot").unwrap();
        assert_eq!(t.n_rows(), 40, "{what}");
        assert_eq!(t.dropped_repeated_rows, [48], "{what}");
        let w = t.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>();
        assert_eq!(w.len(), 1, "{what}: {w:?}");
        assert!(
            w[0].starts_with("walk.mot:48: column \"time\": time 0.39")
                && w[0].contains("repeats the time on line 47"),
            "{what}: {w:?}"
        );
        // The strict option refuses both.
        let strict = ReadOptions {
            repeated_time: RepeatedTime::Error,
        };
        assert!(
            Table::parse_with(&text, "walk.mot", &strict).is_err(),
            "{what}"
        );
    }
}

#[test]
fn a_near_repeated_last_row_no_longer_makes_inverse_dynamics_ring() {
    let model = Model::demo();
    let clean = Table::parse(&demo_motion(40, 40, ""), "clean.mot").unwrap();
    // The last sample written again 6.6e-14 s later (as OpenSim's tools sometimes do).
    let repeated_text = demo_motion(
        40,
        41,
        &row(0.39, 6).replacen("0.39", "0.39000000000006604", 1),
    );
    let repeated = Table::parse(&repeated_text, "repeated.mot").unwrap();
    let options = InverseDynamicsOptions::default();
    let tau = |t: &Table| {
        inverse_dynamics(&model, t, "m", None, &options, &mut |_, _| {})
            .unwrap()
            .table
    };
    let (a, b) = (tau(&clean), tau(&repeated));
    assert_eq!(a.time, b.time);
    let worst = a
        .values
        .iter()
        .zip(&b.values)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "inverse dynamics differs by {worst}");

    // What the reader protects against: the same rows kept, 6.6e-14 s apart, make the
    // spline's second derivative — and the generalized forces — ring near the end.
    let mut kept = clean.clone();
    kept.time.push(0.39 + 6.6e-14);
    let last_row = clean.row(clean.n_rows() - 1).unwrap().to_vec();
    kept.values.extend(last_row);
    let c = tau(&kept);
    let ringing = a
        .values
        .iter()
        .zip(&c.values)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    println!("kept near-repeat changes a generalized force by up to {ringing:.3e}");
    assert!(
        ringing > 1.0,
        "keeping the near-repeat should change the result visibly ({ringing})"
    );
}

#[test]
fn a_repeated_trc_frame_is_dropped_with_a_warning_exact_or_near() {
    let trc = |last_time: &str| {
        format!(
            "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
             DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t\
             OrigDataStartFrame\tOrigNumFrames\n\
             100\t100\t4\t1\tmm\t100\t1\t4\n\
             Frame#\tTime\tA\t\t\n\
             \t\tX1\tY1\tZ1\n\
             \n\
             1\t0\t1\t2\t3\n\
             2\t0.01\t4\t5\t6\n\
             3\t0.02\t7\t8\t9\n\
             4\t{last_time}\t7\t8\t9.5\n"
        )
    };
    for last in ["0.02", "0.020000000000000066", "0.019999999999999934"] {
        let t = musculo::io::trc::Trc::parse(&trc(last), "walk.trc").unwrap();
        assert_eq!(t.time, [0.0, 0.01, 0.02], "{last}");
        assert_eq!(t.positions.len(), 3, "{last}");
        let w = t.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>();
        assert_eq!(w.len(), 1, "{last}: {w:?}");
        assert!(
            w[0].starts_with("walk.trc:10: column \"Time\": time ")
                && w[0].contains("repeats the time on line 9"),
            "{w:?}"
        );
    }
    // A real step, and a time that goes back, are what they were.
    let t = musculo::io::trc::Trc::parse(&trc("0.03"), "walk.trc").unwrap();
    assert!(t.warnings.is_empty() && t.time.len() == 4);
    let e = musculo::io::trc::Trc::parse(&trc("0.015"), "walk.trc")
        .unwrap_err()
        .to_string();
    assert!(e.contains("walk.trc:10"), "{e}");
}

#[test]
fn a_repeated_trc_frame_reaches_the_caller_of_motion_read_and_the_ik_command() {
    // The demo model's four markers, the last frame repeating the third's time.
    let dir = ScratchDir::new("accepts-trc-cli");
    let model = demo_osim(&dir, "demo.osim", musculo::DEMO_MODEL_OSIM);
    let mut text = String::from(
        "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t\
         OrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t4\t4\tm\t100\t1\t4\n\
         Frame#\tTime\thip\t\t\tknee\t\t\tankle\t\t\ttoe\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\tX4\tY4\tZ4\n\
         \n",
    );
    for (frame, time) in ["0", "0.01", "0.02", "0.020000000000000066"]
        .iter()
        .enumerate()
    {
        text += &format!(
            "{}\t{time}\t0\t0.93\t0\t0.02\t0.5\t0\t0.0\t0.08\t0\t0.15\t0.02\t0\n",
            frame + 1
        );
    }
    let trc = dir.join("walk.trc");
    std::fs::write(&trc, text).unwrap();
    let (motion, warnings) =
        musculo::motion::read_with_warnings(&trc, None, &musculo::motion::ReadOptions::default())
            .unwrap();
    assert_eq!(motion.n_frames(), 3);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].to_string().contains("walk.trc:10:"),
        "{warnings:?}"
    );
    let out = dir.join("walk_ik.mot");
    let (ok, _, err) = run_musculo(&[
        "ik",
        "--model",
        model.to_str().unwrap(),
        "--input",
        trc.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.lines()
            .any(|l| l.starts_with("warning: ") && l.contains("walk.trc:10:")),
        "no warning on stderr:\n{err}"
    );
    assert_eq!(Table::read(&out).unwrap().n_rows(), 3);
}

// ---------------------------------------------------------------------------------------
// 5. Inertia violating the triangle inequality.

fn nonphysical_demo() -> String {
    let xml = musculo::DEMO_MODEL_OSIM.replace(
        "<inertia>0.11 0.03 0.12 0.002 0 0</inertia>",
        "<inertia>0.01 0.05 0.01 0 0 0</inertia>",
    );
    assert_ne!(
        xml,
        musculo::DEMO_MODEL_OSIM,
        "the thigh's inertia is in the demo"
    );
    xml
}

#[test]
fn a_triangle_inequality_violation_is_a_named_warning_and_strict_refuses() {
    let xml = nonphysical_demo();
    let model = Model::from_osim_str(&xml, "bad.osim").unwrap();
    let w: Vec<_> = model
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::NonphysicalInertia)
        .collect();
    assert_eq!(w.len(), 1, "{:?}", model.warnings);
    assert!(w[0].element.contains("Body \"thigh\""), "{:?}", w[0]);
    assert!(
        w[0].message
            .contains("1.000000e-2 + 1.000000e-2 < 5.000000e-2"),
        "{}",
        w[0].message
    );
    let e = Model::from_osim_str_with(&xml, "bad.osim", &LoadOptions { strict: true })
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.osim:") && e.contains("thigh") && e.contains("`--strict`"),
        "{e}"
    );
    assert!(!e.contains("allow_nonphysical"), "{e}");
}

#[test]
fn the_cli_warns_about_nonphysical_inertia_and_strict_refuses_on_every_model_command() {
    let dir = ScratchDir::new("accepts-strict");
    let model = demo_osim(&dir, "bad.osim", &nonphysical_demo());
    let coords = dir.join("walk.mot");
    std::fs::write(&coords, demo_motion(20, 20, "")).unwrap();
    let out = dir.join("tau.sto");
    let args = |strict: bool| {
        let mut a = vec![
            "id".to_string(),
            "--model".into(),
            model.display().to_string(),
            "--coordinates".into(),
            coords.display().to_string(),
            "-o".into(),
            out.display().to_string(),
        ];
        if strict {
            a.push("--strict".into());
        }
        a
    };
    let (ok, _, err) = run_musculo(&args(false));
    assert!(ok, "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("triangle inequality"))
        .unwrap_or_else(|| panic!("no warning:\n{err}"));
    assert!(
        line.starts_with("warning: ") && line.contains("bad.osim:") && line.contains("thigh"),
        "{line}"
    );
    let (ok, _, err) = run_musculo(&args(true));
    assert!(
        !ok && err.contains("`--strict`") && !err.contains("allow_nonphysical"),
        "{err}"
    );
    // Every command that loads a model takes --strict.
    for command in [
        &["inspect"][..],
        &["export-mjcf"],
        &["muscles"],
        &["id"],
        &["ik"],
        &["so"],
        &["scale"],
        &["check"],
        &["augment"],
        &["model", "scale"],
        &["model", "reserves"],
    ] {
        let mut a: Vec<&str> = command.to_vec();
        a.push("--help");
        let (ok, help, err) = run_musculo(&a);
        assert!(ok && help.contains("--strict"), "{command:?}: {help}{err}");
    }
}

// ---------------------------------------------------------------------------------------
// 6. PrescribedForce in an ExternalLoads file.

/// Samples of a linear function of time `a + b t` at 0, 0.1, …, 1 s, as `<x>` and `<y>`.
fn spline(tag: &str, a: f64, b: f64) -> String {
    let x: Vec<String> = (0..=10).map(|i| format!("{}", i as f64 * 0.1)).collect();
    let y: Vec<String> = (0..=10)
        .map(|i| format!("{}", a + b * i as f64 * 0.1))
        .collect();
    format!(
        "<{tag} name=\"s\"><x>{}</x><y>{}</y></{tag}>",
        x.join(" "),
        y.join(" ")
    )
}

fn function_set(name: &str, lines: [(f64, f64); 3]) -> String {
    format!(
        "<FunctionSet name=\"{name}\"><objects>{}{}{}</objects><groups /></FunctionSet>",
        spline("NaturalCubicSpline", lines[0].0, lines[0].1),
        spline("NaturalCubicSpline", lines[1].0, lines[1].1),
        spline("NaturalCubicSpline", lines[2].0, lines[2].1),
    )
}

const FORCE: [(f64, f64); 3] = [(10.0, 5.0), (700.0, -30.0), (-4.0, 2.0)];
const POINT: [(f64, f64); 3] = [(0.05, 0.1), (-0.3, 0.0), (0.02, -0.01)];
const TORQUE: [(f64, f64); 3] = [(0.0, 1.0), (2.0, 0.0), (-1.0, 0.5)];

fn prescribed_loads(force_global: bool, point_global: bool, sets: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="20302">
  <ExternalLoads name="">
    <objects>
      <PrescribedForce name="ExternalForce_1">
        <isDisabled>false</isDisabled>
        <body>shank</body>
        <pointIsGlobal>{point_global}</pointIsGlobal>
        <forceIsGlobal>{force_global}</forceIsGlobal>
        {sets}
      </PrescribedForce>
    </objects>
    <groups />
  </ExternalLoads>
</OpenSimDocument>"#
    )
}

/// The same loads as an ExternalForce with its columns in a data table.
fn data_loads(model: &Model, force_in: &str, point_in: &str) -> ExternalLoadSet {
    let xml = format!(
        r#"<OpenSimDocument Version="40000"><ExternalLoads name="x"><objects>
        <ExternalForce name="f"><applied_to_body>shank</applied_to_body>
        <force_expressed_in_body>{force_in}</force_expressed_in_body>
        <point_expressed_in_body>{point_in}</point_expressed_in_body>
        <force_identifier>f_v</force_identifier><point_identifier>f_p</point_identifier>
        <torque_identifier>t_</torque_identifier></ExternalForce>
        </objects><datafile>grf.mot</datafile></ExternalLoads></OpenSimDocument>"#
    );
    let loads = ExternalLoads::parse(&xml, "loads.xml").unwrap();
    let labels = [
        "f_vx", "f_vy", "f_vz", "f_px", "f_py", "f_pz", "t_x", "t_y", "t_z",
    ]
    .map(String::from)
    .to_vec();
    let time: Vec<f64> = (0..=10).map(|i| i as f64 * 0.1).collect();
    let mut values = Vec::new();
    for &t in &time {
        for (a, b) in FORCE.iter().chain(&POINT).chain(&TORQUE) {
            values.push(a + b * t);
        }
    }
    let table = Table::new("grf", labels, time, values).unwrap();
    ExternalLoadSet::new(model, &loads, &table, "grf.mot").unwrap()
}

#[test]
fn a_prescribed_force_applies_the_wrench_of_the_equivalent_external_force() {
    let dir = ScratchDir::new("accepts-prescribed");
    let model = Model::demo();
    let mut data = Data::new(&model);
    let mut q = model.default_q();
    for (i, v) in q.iter_mut().enumerate() {
        *v += 0.1 * (i as f64 + 1.0);
    }
    dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
    let sets = format!(
        "{}{}{}",
        function_set("forceFunctions", FORCE),
        function_set("pointFunctions", POINT),
        function_set("torqueFunctions", TORQUE)
    );
    for (force_global, point_global) in [(true, true), (true, false), (false, false)] {
        let path = dir.join("foot_floor_loads.xml");
        std::fs::write(&path, prescribed_loads(force_global, point_global, &sets)).unwrap();
        let prescribed = ExternalLoadSet::read(&model, &path).unwrap();
        assert_eq!(prescribed.forces.len(), 1);
        assert_eq!(prescribed.time_span, [0.0, 1.0]);
        let frame = |global: bool| if global { "ground" } else { "shank" };
        let reference = data_loads(&model, frame(force_global), frame(point_global));
        for t in [0.0, 0.25, 0.5, 0.93] {
            let (a, b) = (
                prescribed.wrench(&data, 0, t),
                reference.wrench(&data, 0, t),
            );
            let close = |x: Vec3, y: Vec3| (x - y).norm() <= 1e-9 * (1.0 + y.norm());
            assert!(
                a.body == b.body
                    && close(a.force_in_ground, b.force_in_ground)
                    && close(a.point_in_ground, b.point_in_ground)
                    && close(a.torque_in_ground, b.torque_in_ground),
                "{force_global} {point_global} at {t}: {a:?} vs {b:?}"
            );
            let mut qa = vec![0.0; model.nq()];
            let mut qb = vec![0.0; model.nq()];
            prescribed
                .add_generalized_forces(&model, &data, t, &mut qa)
                .unwrap();
            reference
                .add_generalized_forces(&model, &data, t, &mut qb)
                .unwrap();
            for (x, y) in qa.iter().zip(&qb) {
                assert!((x - y).abs() <= 1e-9 * (1.0 + y.abs()), "{qa:?} vs {qb:?}");
            }
        }
    }
}

#[test]
fn a_malformed_prescribed_force_is_a_located_error() {
    let dir = ScratchDir::new("accepts-prescribed-bad");
    let model = Model::demo();
    let path = dir.join("loads.xml");
    // Two functions where three are needed.
    let two = function_set("forceFunctions", FORCE).replacen(
        &spline("NaturalCubicSpline", FORCE[2].0, FORCE[2].1),
        "",
        1,
    );
    std::fs::write(&path, prescribed_loads(true, true, &two)).unwrap();
    let e = ExternalLoadSet::read(&model, &path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("loads.xml:10")
            && e.contains("FunctionSet \"forceFunctions\"")
            && e.contains("3 functions"),
        "{e}"
    );
    // An unknown body names the force and its line.
    let good = function_set("forceFunctions", FORCE);
    std::fs::write(
        &path,
        prescribed_loads(true, true, &good).replace("<body>shank</body>", "<body>tail</body>"),
    )
    .unwrap();
    let e = ExternalLoadSet::read(&model, &path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("loads.xml:5")
            && e.contains("PrescribedForce \"ExternalForce_1\"")
            && e.contains("tail"),
        "{e}"
    );
}
