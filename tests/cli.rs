//! The `musculo` command line: `inspect` on the built-in model, on a reference model, as JSON,
//! and its errors.

mod common;
use common::*;

#[test]
fn inspect_demo_prints_the_model_summary() {
    let (ok, out, _) = run_musculo(&["inspect", "--demo"]);
    assert!(ok);
    for line in [
        "bodies      5 (plus ground)",
        "coordinates 7 : 6 independent, 1 dependent (coupled), 0 locked",
        "muscles     1 (1 Thelen2003Muscle)",
        "total mass  22.8000 kg",
    ] {
        assert!(out.contains(line), "missing `{line}` in:\n{out}");
    }
    assert!(
        out.contains("patella_angle") && out.contains("= f(knee_angle) [patella_follows_knee]")
    );
}

#[test]
fn inspect_rajagopal_reports_couplers_locked_coordinates_and_muscles() {
    let Some(p) = reference_file("opensim-models/Models/Rajagopal/Rajagopal2016.osim") else {
        return;
    };
    let (ok, out, err) = run_musculo(&["inspect", p.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("coordinates 39 : 29 independent, 2 dependent (coupled), 8 locked"),
        "{out}"
    );
    assert!(
        out.contains("muscles     80 (80 Millard2012EquilibriumMuscle)"),
        "{out}"
    );
    assert!(out.contains("other forces 17 CoordinateActuator"), "{out}");
}

#[test]
fn inspect_json_is_machine_readable() {
    let Some(p) =
        reference_file("opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")
    else {
        return;
    };
    let (ok, out, _) = run_musculo(&["inspect", "--json", p.to_str().unwrap()]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert_eq!(v["n_independent_coordinates"], 23);
    assert_eq!(v["muscles"], 92);
    assert!((v["total_mass_kg"].as_f64().unwrap() - 75.1646).abs() < 1e-9);
    assert_eq!(v["bodies"].as_array().unwrap().len(), 12);
}

#[test]
fn inspect_lists_unsupported_elements_and_strict_refuses_bad_inertia() {
    let Some(p) = reference_file(
        "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads/subject01_simbody_adjusted_StaticOp.osim",
    ) else {
        return;
    };
    let (ok, _, err) = run_musculo(&["inspect", "--strict", p.to_str().unwrap()]);
    assert!(
        !ok && err.contains("toes_r")
            && err.contains("triangle inequality")
            && err.contains("`--strict`"),
        "{err}"
    );
    let (ok, out, _) = run_musculo(&["inspect", p.to_str().unwrap()]);
    assert!(
        ok && out.contains("NOT USED BY MUSCULO (2 warnings") && out.contains("toes_r"),
        "{out}"
    );
}

#[test]
fn inspect_reports_a_missing_file_and_a_bad_model_without_panicking() {
    let (ok, _, err) = run_musculo(&["inspect", "/no/such/model.osim"]);
    assert!(
        !ok && err.starts_with("error: /no/such/model.osim"),
        "{err}"
    );
    let dir = std::env::temp_dir().join(format!("musculo-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.osim");
    std::fs::write(
        &bad,
        include_str!("../models/demo.osim").replace("<mass>3.5</mass>", "<mass>-3.5</mass>"),
    )
    .unwrap();
    let (ok, _, err) = run_musculo(&["inspect", bad.to_str().unwrap()]);
    assert!(
        !ok && err.contains("Body \"shank\"") && err.contains("negative mass"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fresh directory under the system temp dir, removed when dropped.
struct TempDir(std::path::PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("musculo-cli-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn so_runs_opensims_setup_and_writes_activation_and_force_files() {
    let dir = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let (Some(setup), Some(model)) = (
        reference_file(&format!("{dir}/setup_static_optimization.xml")),
        reference_file(&format!("{dir}/subject01_simbody_adjusted_StaticOp.osim")),
    ) else {
        return;
    };
    let tmp = TempDir::new("so");
    let prefix = tmp.0.join("walk");
    let (ok, _, err) = run_musculo(&[
        "so",
        "--setup",
        setup.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
        "-o",
        prefix.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("151 frames") && err.contains("98 actuators (92 muscles)"),
        "{err}"
    );
    let act = musculo::io::Table::read(&tmp.0.join("walk_activation.sto")).unwrap();
    let force = musculo::io::Table::read(&tmp.0.join("walk_force.sto")).unwrap();
    assert_eq!((act.n_rows(), act.n_columns()), (151, 98));
    assert_eq!(act.labels[0], "glut_med1_r");
    assert_eq!(act.labels[97], "MZ");
    // Actuator forces, then the external loads as OpenSim records them.
    assert_eq!(force.n_columns(), 98 + 18);
    assert_eq!(force.labels[98], "calcn_r_right_foot_Fx");
    assert_eq!(force.labels[115], "calcn_l_left_foot_Tz");
}

#[test]
fn so_reports_infeasible_frames_and_goes_on() {
    // The demo leg with weak, bounded reserves: standing still needs more hip and knee moment
    // than they give, so every frame is infeasible; the run still writes its files.
    let tmp = TempDir::new("so-infeasible");
    let mut reserves = String::from(
        "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\"><ForceSet name=\"r\"><objects>\n",
    );
    for c in [
        "pelvis_tilt",
        "pelvis_tx",
        "pelvis_ty",
        "hip_flexion",
        "knee_angle",
        "ankle_angle",
    ] {
        let weak = if c.starts_with("pelvis") { 1000.0 } else { 0.1 };
        reserves += &format!(
            "<CoordinateActuator name=\"res_{c}\"><coordinate>{c}</coordinate><optimal_force>{weak}</optimal_force>\
             <min_control>-1</min_control><max_control>1</max_control></CoordinateActuator>\n"
        );
    }
    reserves += "</objects></ForceSet></OpenSimDocument>\n";
    let reserves_path = tmp.0.join("reserves.xml");
    std::fs::write(&reserves_path, reserves).unwrap();
    let model_path = tmp.0.join("demo.osim");
    std::fs::write(&model_path, musculo::DEMO_MODEL_OSIM).unwrap();
    let labels: Vec<String> = [
        "pelvis_tilt",
        "pelvis_tx",
        "pelvis_ty",
        "hip_flexion",
        "knee_angle",
        "ankle_angle",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let time: Vec<f64> = (0..11).map(|i| i as f64 * 0.01).collect();
    let values: Vec<f64> = time
        .iter()
        .flat_map(|_| [0.0, 0.0, 0.93, 40.0, -60.0, 10.0])
        .collect();
    let mut motion = musculo::io::Table::new("still", labels, time, values).unwrap();
    motion.in_degrees = Some(true);
    let motion_path = tmp.0.join("still.mot");
    motion.write(&motion_path).unwrap();
    let prefix = tmp.0.join("out");
    let (ok, _, err) = run_musculo(&[
        "so",
        "--model",
        model_path.to_str().unwrap(),
        "--coordinates",
        motion_path.to_str().unwrap(),
        "--actuators",
        reserves_path.to_str().unwrap(),
        "-o",
        prefix.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("s: infeasible") && err.contains("hip_flexion"),
        "{err}"
    );
    // Summarised: the count and the worst frame, not one line per frame.
    assert!(
        err.contains("11 of 11 frame(s) not solved exactly"),
        "{err}"
    );
    assert!(err.contains("worst at time"), "{err}");
    assert_eq!(
        err.lines().filter(|l| l.starts_with("warning:")).count(),
        2,
        "{err}"
    );
    assert!(tmp.0.join("out_activation.sto").exists());

    // An actuator file naming an unknown body: a clear error, no output.
    std::fs::write(
        &reserves_path,
        "<OpenSimDocument Version=\"40000\"><ForceSet name=\"r\"><objects>\
         <PointActuator name=\"p\"><body>tibia</body></PointActuator></objects></ForceSet></OpenSimDocument>",
    )
    .unwrap();
    let (ok, _, err) = run_musculo(&[
        "so",
        "--model",
        model_path.to_str().unwrap(),
        "--coordinates",
        motion_path.to_str().unwrap(),
        "--actuators",
        reserves_path.to_str().unwrap(),
        "-o",
        tmp.0.join("bad").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("reserves.xml:1") && err.contains("unknown body `tibia`"),
        "{err}"
    );
}

#[test]
fn id_runs_opensims_setup() {
    let Some(setup) = reference_file(
        "opensim-models/Pipelines/Gait10dof18musc/OutputReference/ID/walk_Setup_ID.xml",
    ) else {
        return;
    };
    let tmp = TempDir::new("id");
    let out = tmp.0.join("id.sto");
    let (ok, _, err) = run_musculo(&[
        "id",
        "--setup",
        setup.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let t = musculo::io::Table::read(&out).unwrap();
    assert_eq!(t.n_rows(), 151, "{err}");
    assert!(t.column_index("knee_angle_r_moment").is_some());
    assert!(t.column_index("pelvis_tx_force").is_some());
    // A missing model file is an error naming it.
    let (ok, _, err) = run_musculo(&[
        "id",
        "--setup",
        setup.to_str().unwrap(),
        "--model",
        "/nonexistent/model.osim",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("/nonexistent/model.osim"), "{err}");
}

#[test]
fn model_build_reproduces_the_default_model_and_scale_writes_a_subject() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = TempDir::new("model");
    let built = tmp.0.join("built.osim");
    let (ok, out, err) = run_musculo(&[
        "model",
        "build",
        "--data",
        root.join("data/model").to_str().unwrap(),
        "-o",
        built.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("324 muscles"), "{out}");
    let committed = std::fs::read(root.join("models/musculo_fullbody.osim")).unwrap();
    assert!(
        std::fs::read(&built).unwrap() == committed,
        "rebuilt model differs"
    );
    let small = tmp.0.join("small.osim");
    let (ok, out, err) = run_musculo(&[
        "model",
        "scale",
        built.to_str().unwrap(),
        "--mass",
        "60",
        "--height",
        "1.6",
        "-o",
        small.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("masses × 0.8000"), "{out}");
    let text = std::fs::read_to_string(&small).unwrap();
    assert!(text.contains("reference subject 60 kg, 1.6 m"));
    let model = musculo::Model::from_osim_str(&text, "small").unwrap();
    assert!((model.total_mass() - 60.0).abs() < 1e-9);
    // a model that does not state its height needs --model-height
    let (ok, _, err) = run_musculo(&[
        "model",
        "scale",
        root.join("models/demo.osim").to_str().unwrap(),
        "--mass",
        "60",
        "--height",
        "1.6",
        "-o",
        small.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("--model-height"), "{err}");
}

/// A model with nothing to move (no coordinate, or only locked ones) is refused by the
/// commands whose results are per coordinate, naming the file and why, and none of them
/// writes a file; before, `id`, `so` and `muscles` wrote tables of no column (the motion's
/// columns ignored) and `check` said "all checks passed". `inspect` still describes it.
#[test]
fn a_model_with_nothing_to_move_is_refused_by_the_per_coordinate_commands() {
    let d = TempDir::new("nothing-to-move");
    let empty = d.0.join("empty.osim");
    std::fs::write(
        &empty,
        r#"<OpenSimDocument Version="40000"><Model name="x"></Model></OpenSimDocument>"#,
    )
    .unwrap();
    let locked = d.0.join("locked.osim");
    std::fs::write(
        &locked,
        r#"<OpenSimDocument Version="40000"><Model name="y">
<BodySet><objects><Body name="a"><mass>1</mass><inertia>0.1 0.1 0.1 0 0 0</inertia></Body></objects></BodySet>
<JointSet><objects><PinJoint name="j"><socket_parent_frame>/ground</socket_parent_frame>
<socket_child_frame>/bodyset/a</socket_child_frame>
<coordinates><Coordinate name="q"><locked>true</locked></Coordinate></coordinates>
</PinJoint></objects></JointSet></Model></OpenSimDocument>"#,
    )
    .unwrap();
    let motion = d.0.join("walk.mot");
    std::fs::write(
        &motion,
        "walk\nversion=1\nnRows=3\nnColumns=2\ninDegrees=yes\nendheader\n\
         time\tknee_angle\n0\t10\n0.01\t11\n0.02\t12\n",
    )
    .unwrap();
    let trc = d.0.join("trial.trc");
    std::fs::write(
        &trc,
        "PathFileType\t4\t(X/Y/Z)\ttrial.trc\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t2\t1\tm\t100\t1\t2\n\
         Frame#\tTime\thip\t\t\n\
         \t\tX1\tY1\tZ1\n\n\
         1\t0\t0\t0.9\t0\n\
         2\t0.01\t0\t0.9\t0\n",
    )
    .unwrap();
    let out = d.0.join("out");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    for (model, why) in [
        (&empty, "(it has no coordinate)"),
        (&locked, "(its 1 coordinate(s) are all locked"),
    ] {
        let m = s(model);
        let commands: [Vec<String>; 5] = [
            vec!["check".into(), m.clone()],
            vec![
                "id".into(),
                "--model".into(),
                m.clone(),
                "--coordinates".into(),
                s(&motion),
                "-o".into(),
                s(&out.join("id.sto")),
            ],
            vec![
                "so".into(),
                "--model".into(),
                m.clone(),
                "--coordinates".into(),
                s(&motion),
                "-o".into(),
                s(&out.join("so.sto")),
            ],
            vec![
                "muscles".into(),
                m.clone(),
                "--coords".into(),
                s(&motion),
                "-o".into(),
                s(&out.join("m")),
            ],
            vec![
                "ik".into(),
                "--model".into(),
                m.clone(),
                "--input".into(),
                s(&trc),
                "-o".into(),
                s(&out.join("ik.mot")),
            ],
        ];
        for command in commands {
            let (ok, stdout, err) = run_musculo(&command);
            assert!(!ok, "{command:?} succeeded: {stdout}");
            assert!(
                err.contains(&m) && err.contains("has nothing to move") && err.contains(why),
                "{command:?}: {err}"
            );
            assert!(!out.exists(), "{command:?} wrote into {}", out.display());
        }
        let (ok, stdout, err) = run_musculo(&["inspect", m.as_str()]);
        assert!(ok && stdout.contains("COORDINATES"), "inspect: {err}");
    }
}

#[test]
fn help_texts_name_the_demo_clips_and_every_model_subcommand() {
    // the demo's clips, as `augment --demo` writes them (src/augment/demo.rs)
    let (ok, out, _) = run_musculo(&["augment", "--help"]);
    assert!(ok);
    assert!(out.contains("march in place, squat, reach"), "{out}");
    assert!(!out.contains("walk, squat"), "{out}");
    let (ok, out, _) = run_musculo(&["--help"]);
    assert!(ok);
    let model_line = out
        .lines()
        .find(|l| l.trim_start().starts_with("model "))
        .expect("a `model` line in --help");
    assert!(!model_line.contains("build it"), "{model_line}");
    let (ok, out, _) = run_musculo(&["model", "--help"]);
    assert!(ok);
    for sub in ["build", "scale", "reserves", "strengthen"] {
        assert!(
            out.lines().any(|l| l.trim_start().starts_with(sub)),
            "`model --help` lacks `{sub}`:\n{out}"
        );
        assert!(
            out.lines().next().unwrap_or("").contains(sub),
            "`model --help`'s first line does not name `{sub}`:\n{out}"
        );
    }
}

/// `musculo train-ae` (and the other learned-module commands) run `musculo-learn` beside the
/// program or on PATH; where neither has it, the command says how to build it and fails.
#[test]
fn learned_module_commands_say_how_to_build_the_module_when_it_is_missing() {
    let dir = common::ScratchDir::new("learn-missing");
    let program = dir.join(&format!("musculo{}", std::env::consts::EXE_SUFFIX));
    std::fs::copy(env!("CARGO_BIN_EXE_musculo"), &program).expect("copy musculo");
    let empty_path = dir.join("bin");
    std::fs::create_dir_all(&empty_path).expect("empty PATH folder");
    for command in ["train-ae", "reconstruct", "train-diffusion", "generate"] {
        let out = std::process::Command::new(&program)
            .args([command, "--data", "anywhere"])
            .env("PATH", &empty_path)
            .output()
            .expect("run the copied musculo");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success(),
            "{command} succeeded without the module"
        );
        assert!(
            err.contains("cargo build --release -p musculo-learn") && err.contains("musculo-learn"),
            "{command}: {err}"
        );
        assert!(!err.contains("panicked"), "{command}: {err}");
    }
}
