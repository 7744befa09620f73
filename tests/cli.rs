//! The `musculo` command line: `inspect` on the built-in model, on a reference model, as JSON,
//! and its errors.

mod common;
use common::*;
use std::process::Command;

fn musculo(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args(args)
        .output()
        .expect("run musculo");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn inspect_demo_prints_the_model_summary() {
    let (ok, out, _) = musculo(&["inspect", "--demo"]);
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
    let (ok, out, err) = musculo(&["inspect", p.to_str().unwrap()]);
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
    let (ok, out, _) = musculo(&["inspect", "--json", p.to_str().unwrap()]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert_eq!(v["n_independent_coordinates"], 23);
    assert_eq!(v["muscles"], 92);
    assert!((v["total_mass_kg"].as_f64().unwrap() - 75.1646).abs() < 1e-9);
    assert_eq!(v["bodies"].as_array().unwrap().len(), 12);
}

#[test]
fn inspect_lists_unsupported_elements_and_needs_the_option_for_bad_inertia() {
    let Some(p) = reference_file(
        "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads/subject01_simbody_adjusted_StaticOp.osim",
    ) else {
        return;
    };
    let (ok, _, err) = musculo(&["inspect", p.to_str().unwrap()]);
    assert!(
        !ok && err.contains("toes_r") && err.contains("triangle inequality"),
        "{err}"
    );
    let (ok, out, _) = musculo(&[
        "inspect",
        "--allow-nonphysical-inertia",
        p.to_str().unwrap(),
    ]);
    assert!(
        ok && out.contains("NOT USED BY MUSCULO (2 warnings"),
        "{out}"
    );
}

#[test]
fn inspect_reports_a_missing_file_and_a_bad_model_without_panicking() {
    let (ok, _, err) = musculo(&["inspect", "/no/such/model.osim"]);
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
    let (ok, _, err) = musculo(&["inspect", bad.to_str().unwrap()]);
    assert!(
        !ok && err.contains("Body \"shank\"") && err.contains("negative mass"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
    let _ = std::fs::remove_dir_all(&dir);
}
