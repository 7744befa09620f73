//! Residual and reserve actuators (`musculo::model::reserves`, `musculo model reserves`,
//! `models/musculo_fullbody_reserves.xml`): the shipped file is generated from the shipped
//! model, every independent coordinate gets an actuator, and with them static optimization on
//! the default model solves every frame (where gait2392's force set leaves `pro_sup` without
//! one and no frame solves).

mod common;

use common::{body, coordinate, joint, osim, reference_file};
use musculo::io::Table;
use musculo::model::reserves::{
    ReserveActuator, ReserveOptions, reserve_actuators, reserve_force_set,
};
use musculo::model::{ActuatorKind, ForceSetFiles, LoadOptions};
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::kinematics::fill_missing_coordinates;
use musculo::solve::static_optimization::{
    SoRun, SoRunOptions, StaticOptimization, StaticOptimizationOptions, run_static_optimization,
};
use musculo::{Error, Model};
use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn with_force_set(model_xml: &str, force_set: &str) -> Model {
    let files = ForceSetFiles {
        files: vec![(force_set.to_string(), "reserves.xml".to_string())],
        replace: false,
    };
    Model::from_osim_str_with_force_sets(model_xml, "model", &LoadOptions::default(), &files)
        .expect("the generated force set loads with its model")
}

#[test]
fn shipped_reserves_file_is_generated_from_the_shipped_model() {
    let model_path = Path::new(ROOT).join("models/musculo_fullbody.osim");
    let model = Model::from_osim_file(&model_path).unwrap();
    let text =
        reserve_force_set(&model, "musculo_fullbody.osim", &ReserveOptions::default()).unwrap();
    let shipped =
        std::fs::read_to_string(Path::new(ROOT).join("models/musculo_fullbody_reserves.xml"))
            .expect("models/musculo_fullbody_reserves.xml is shipped");
    assert!(
        text == shipped,
        "models/musculo_fullbody_reserves.xml is stale: run `cargo run --release -- model reserves`"
    );
    // 6 pelvis residuals and a reserve on each of the 23 other independent coordinates
    let actuators = reserve_actuators(&model, &ReserveOptions::default()).unwrap();
    assert_eq!(actuators.len(), 6 + 23);
    let names: Vec<&str> = actuators.iter().map(|a| a.name()).collect();
    assert_eq!(&names[..6], ["FX", "FY", "FZ", "MX", "MY", "MZ"]);
    assert!(names.contains(&"pro_sup_r_reserve") && names.contains(&"lumbar_extension_reserve"));
}

/// A free-floating trunk with a thigh on a pin (and a locked pin below it); or the same on a
/// planar root.
fn small_model(root_kind: &str) -> String {
    let root_coords: Vec<String> = match root_kind {
        "FreeJoint" => ["rx", "ry", "rz", "tx", "ty", "tz"]
            .iter()
            .map(|n| coordinate(n, [-3.0, 3.0]))
            .collect(),
        _ => ["rz", "tx", "ty"]
            .iter()
            .map(|n| coordinate(n, [-3.0, 3.0]))
            .collect(),
    };
    let bodies = [
        body(
            "trunk",
            30.0,
            [0.0, 0.2, 0.0],
            [1.0, 0.5, 1.0, 0.0, 0.0, 0.0],
        ),
        body(
            "thigh",
            8.0,
            [0.0, -0.2, 0.0],
            [0.1, 0.02, 0.1, 0.0, 0.0, 0.0],
        ),
        body(
            "shank",
            3.0,
            [0.0, -0.2, 0.0],
            [0.05, 0.01, 0.05, 0.0, 0.0, 0.0],
        ),
    ]
    .join("\n");
    let locked = "<Coordinate name=\"ankle\"><default_value>0.1</default_value>\
                  <range>-1 1</range><locked>true</locked></Coordinate>"
        .to_string();
    let joints = [
        joint(
            root_kind,
            "root",
            "/ground",
            [0.0, 1.0, 0.0],
            "/bodyset/trunk",
            &root_coords,
            "",
        ),
        joint(
            "PinJoint",
            "hip",
            "/bodyset/trunk",
            [0.0, -0.1, 0.1],
            "/bodyset/thigh",
            &[coordinate("hip_flexion", [-1.0, 2.0])],
            "",
        ),
        joint(
            "PinJoint",
            "knee",
            "/bodyset/thigh",
            [0.0, -0.4, 0.0],
            "/bodyset/shank",
            &[locked],
            "",
        ),
    ]
    .join("\n");
    osim(&bodies, &joints, "", [0.0, -9.81, 0.0])
}

#[test]
fn a_free_root_gets_force_and_torque_residuals_and_each_joint_a_reserve() {
    let xml = small_model("FreeJoint");
    let model = Model::from_osim_str(&xml, "small").unwrap();
    let options = ReserveOptions {
        reserve_optimal_force: 2.0,
        residual_optimal_force: 5.0,
    };
    let actuators = reserve_actuators(&model, &options).unwrap();
    let trunk = model.body_index("trunk").unwrap();
    let hip = model.coordinate_index("hip_flexion").unwrap();
    let mut want = Vec::new();
    for (axis, l) in ["X", "Y", "Z"].into_iter().enumerate() {
        want.push(ReserveActuator::Force {
            name: format!("F{l}"),
            body: trunk,
            axis,
            optimal_force: 5.0,
        });
    }
    for (axis, l) in ["X", "Y", "Z"].into_iter().enumerate() {
        want.push(ReserveActuator::Torque {
            name: format!("M{l}"),
            body: trunk,
            axis,
            optimal_force: 5.0,
        });
    }
    // the locked ankle gets none
    want.push(ReserveActuator::Coordinate {
        name: "hip_flexion_reserve".into(),
        coordinate: hip,
        optimal_force: 2.0,
    });
    assert_eq!(actuators, want);

    // the file reads back as the same actuators: at the trunk's centre of mass, ground axes
    let text = reserve_force_set(&model, "small.osim", &options).unwrap();
    let loaded = with_force_set(&xml, &text);
    let read: Vec<_> = (loaded.forces.iter())
        .filter_map(|f| Some((f.name.as_str(), f.actuator.clone()?)))
        .collect();
    assert_eq!(read.len(), 7);
    for (name, a) in &read {
        assert_eq!(
            a.optimal_force,
            if *name == "hip_flexion_reserve" {
                2.0
            } else {
                5.0
            }
        );
        assert_eq!(
            (a.min_control, a.max_control),
            (f64::NEG_INFINITY, f64::INFINITY)
        );
    }
    match &read[1].1.kind {
        ActuatorKind::Point {
            body,
            point,
            point_is_global,
            direction,
            force_is_global,
        } => {
            assert_eq!(*body, trunk);
            assert_eq!(point.as_slice(), model.bodies[trunk].com_in_body.as_slice());
            assert!(!point_is_global && *force_is_global);
            assert_eq!(direction.as_slice(), [0.0, 1.0, 0.0]);
        }
        other => panic!("FY read as {other:?}"),
    }
    match &read[5].1.kind {
        ActuatorKind::Torque {
            body_a,
            body_b,
            axis,
            torque_is_global,
        } => {
            assert_eq!((*body_a, *body_b), (trunk, 0));
            assert!(*torque_is_global);
            assert_eq!(axis.as_slice(), [0.0, 0.0, 1.0]);
        }
        other => panic!("MZ read as {other:?}"),
    }
    assert_eq!(read[6].1.kind, ActuatorKind::Coordinate { coordinate: hip });
}

#[test]
fn a_planar_root_gets_coordinate_residuals() {
    let model = Model::from_osim_str(&small_model("PlanarJoint"), "small").unwrap();
    let names: Vec<String> = reserve_actuators(&model, &ReserveOptions::default())
        .unwrap()
        .iter()
        .map(|a| a.name().to_string())
        .collect();
    assert_eq!(
        names,
        [
            "rz_residual",
            "tx_residual",
            "ty_residual",
            "hip_flexion_reserve"
        ]
    );
}

#[test]
fn optimal_forces_must_be_finite_and_positive() {
    let model = Model::from_osim_str(&small_model("FreeJoint"), "small").unwrap();
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        for options in [
            ReserveOptions {
                reserve_optimal_force: bad,
                ..Default::default()
            },
            ReserveOptions {
                residual_optimal_force: bad,
                ..Default::default()
            },
        ] {
            let e = reserve_force_set(&model, "small.osim", &options).unwrap_err();
            assert!(
                matches!(e, Error::InvalidArgument { argument, .. } if argument.ends_with("optimal_force")),
                "{e}"
            );
        }
    }
}

fn so_run(model: &Model, coordinates: &Table, loads: Option<&ExternalLoadSet>) -> SoRun {
    let so = StaticOptimization::new(model, StaticOptimizationOptions::default()).unwrap();
    run_static_optimization(
        model,
        &so,
        coordinates,
        "motion",
        loads,
        &SoRunOptions {
            lowpass_hz: Some(6.0),
            time_range: None,
            step_interval: 1,
        },
        &mut |_, _| {},
    )
    .unwrap()
}

/// Largest |value| over the rows of the columns whose label ends with `suffix`, with the
/// label.
fn largest(table: &Table, suffix: &str) -> (f64, String) {
    let mut best = (0.0, String::new());
    for (j, label) in table.labels.iter().enumerate() {
        if label.ends_with(suffix) {
            for i in 0..table.n_rows() {
                let v = table.value(i, j).unwrap_or(0.0).abs();
                if v > best.0 {
                    best = (v, label.clone());
                }
            }
        }
    }
    best
}

#[test]
fn with_the_shipped_reserves_a_made_up_motion_without_loads_solves_every_frame() {
    // every coordinate swinging within its range, the body in the air: the pelvis residuals
    // carry its weight and whatever the motion asks of the floating base
    let text =
        std::fs::read_to_string(Path::new(ROOT).join("models/musculo_fullbody.osim")).unwrap();
    let reserves =
        std::fs::read_to_string(Path::new(ROOT).join("models/musculo_fullbody_reserves.xml"))
            .unwrap();
    let model = with_force_set(&text, &reserves);
    let n = model.nq();
    let names: Vec<String> = model.q_names().iter().map(|s| s.to_string()).collect();
    let frames = 40;
    let mut time = Vec::new();
    let mut values = Vec::new();
    for k in 0..frames {
        let t = k as f64 * 0.01;
        time.push(t);
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            let [lo, hi] = model.coordinates[c].range;
            let (mid, half) = (0.5 * (lo + hi), 0.25 * (hi - lo).min(1.0));
            values.push(mid + half * (2.0 * t + j as f64).sin());
        }
    }
    let mut table = Table::new("Coordinates", names, time, values).unwrap();
    table.in_degrees = Some(false);
    let run = so_run(&model, &table, None);
    assert!(run.problems.is_empty(), "{:?}", run.problems.first());
    assert_eq!(run.activation.n_rows(), frames);
    assert_eq!(run.activation.labels.len(), 324 + n);
    // the vertical residual carries about the body weight (75 kg) and more
    let (fy, _) = largest(&run.force, "FY");
    assert!(fy > 0.5 * 75.0 * 9.81, "FY at most {fy} N");
}

#[test]
fn the_default_model_walk_solves_every_frame_with_its_reserves_not_with_gait2392s() {
    let tutorial = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let (Some(kinematics), Some(grf), Some(gait2392_reserves)) = (
        reference_file(&format!("{tutorial}/subject01_walk1_Kinematics.sto")),
        reference_file("opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1_grf.xml"),
        reference_file(
            "opensim-models/Pipelines/Gait2392_Simbody/gait2392_SO_weak_Residual_Actuators.xml",
        ),
    ) else {
        return;
    };
    let text =
        std::fs::read_to_string(Path::new(ROOT).join("models/musculo_fullbody.osim")).unwrap();
    let ours =
        std::fs::read_to_string(Path::new(ROOT).join("models/musculo_fullbody_reserves.xml"))
            .unwrap();
    let theirs = std::fs::read_to_string(gait2392_reserves).unwrap();
    let walk = |force_set: &str| {
        let model = with_force_set(&text, force_set);
        let mut coordinates = Table::read(&kinematics).unwrap();
        fill_missing_coordinates(&model, &mut coordinates);
        let loads = ExternalLoadSet::read(&model, &grf).unwrap();
        so_run(&model, &coordinates, Some(&loads))
    };

    let run = walk(&ours);
    println!(
        "default model + models/musculo_fullbody_reserves.xml: {} frames, {} not solved",
        run.activation.n_rows(),
        run.problems.len()
    );
    assert_eq!(run.activation.n_rows(), 1500);
    assert!(run.problems.is_empty(), "{:?}", run.problems.first());
    let (reserve, which) = largest(&run.force, "_reserve");
    println!("largest reserve: {which} {reserve:.3} N·m");
    assert!(reserve < 1.0, "{which} carries {reserve} N·m");

    // gait2392's residuals alone leave the forearm roll (no muscle, no reserve) unbalanced
    let run = walk(&theirs);
    assert_eq!(run.problems.len(), run.activation.n_rows());
    assert!(
        (run.problems.iter()).all(|p| p.unbalanced.iter().any(|(c, _)| c.starts_with("pro_sup"))),
        "{:?}",
        run.problems.first()
    );
}

/// The command line: `model reserves` writes the force set beside the model; `so` without it
/// fails every frame of a floating model and says so in two summary lines, with it solves
/// every frame.
#[test]
fn cli_so_summarises_unsolved_frames_and_solves_them_with_model_reserves() {
    let bin = env!("CARGO_BIN_EXE_musculo");
    let dir = std::env::temp_dir().join(format!("musculo-reserves-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.osim"), small_model("FreeJoint")).unwrap();
    // weak bounded actuators: the floating base cannot carry the body's weight
    let mut weak =
        String::from("<OpenSimDocument Version=\"40000\"><ForceSet name=\"weak\"><objects>");
    for c in ["rx", "ry", "rz", "tx", "ty", "tz", "hip_flexion"] {
        weak += &format!(
            "<CoordinateActuator name=\"{c}_weak\"><coordinate>{c}</coordinate>\
             <min_control>-1</min_control><max_control>1</max_control>\
             <optimal_force>1</optimal_force></CoordinateActuator>"
        );
    }
    weak += "</objects></ForceSet></OpenSimDocument>";
    std::fs::write(dir.join("weak.xml"), weak).unwrap();
    let mut sto = String::from(
        "Coordinates\nversion=1\nnRows=50\nnColumns=8\ninDegrees=no\nendheader\n\
         time\trx\try\trz\ttx\tty\ttz\thip_flexion\n",
    );
    for k in 0..50 {
        let t = k as f64 * 0.02;
        sto += &format!(
            "{t}\t{}\t0\t0\t{}\t1\t0\t{}\n",
            0.1 * t.sin(),
            0.5 * t,
            0.3 * (3.0 * t).sin()
        );
    }
    std::fs::write(dir.join("walk.sto"), sto).unwrap();
    let run = |args: &[&str]| {
        let out = Command::new(bin)
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        (
            String::from_utf8(out.stdout).unwrap(),
            String::from_utf8(out.stderr).unwrap(),
        )
    };

    let (_, stderr) = run(&[
        "so",
        "--model",
        "m.osim",
        "--coordinates",
        "walk.sto",
        "--actuators",
        "weak.xml",
        "-o",
        "out/without",
    ]);
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning"))
        .collect();
    assert_eq!(warnings.len(), 2, "{stderr}");
    assert!(
        warnings[0].starts_with("warning: 50 of 50 frame(s) not solved exactly, at times 0.000000, 0.020000, 0.040000, 0.060000, 0.080000 s, … (from 0.000000 to 0.980000 s)"),
        "{stderr}"
    );
    assert!(
        warnings[1].starts_with("warning: worst at time "),
        "{stderr}"
    );
    assert!(warnings[1].contains("ty "), "{stderr}");

    let (stdout, _) = run(&["model", "reserves", "m.osim"]);
    assert!(
        stdout.starts_with("wrote m_reserves.xml: 7 actuators"),
        "{stdout}"
    );
    let (_, stderr) = run(&[
        "so",
        "--model",
        "m.osim",
        "--coordinates",
        "walk.sto",
        "--actuators",
        "m_reserves.xml",
        "-o",
        "out/with",
    ]);
    assert!(!stderr.contains("warning"), "{stderr}");
    assert!(
        stderr.contains("; 0 frame(s) not solved exactly"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
