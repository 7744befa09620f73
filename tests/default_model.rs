//! The default full-body model (`models/musculo_fullbody.osim`): rebuilt from its tables it is
//! byte-for-byte the committed file; its counts, mass and segment masses are the issue's and
//! de Leva's; every biomechanics check passes; static optimization balances a standing pose
//! and the gait2392 walk with its ground-reaction forces, reserves carrying < 5 % of the joint
//! moments.

mod common;

use common::reference_file;
use musculo::check::{CheckOptions, run as run_checks};
use musculo::io::Table;
use musculo::model::builder::{ModelTables, build_osim};
use musculo::model::{ForceSetFiles, LoadOptions, Model};
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use musculo::solve::kinematics::fill_missing_coordinates;
use musculo::solve::static_optimization::{
    SoRunOptions, StaticOptimization, StaticOptimizationOptions, run_static_optimization,
};
use std::path::{Path, PathBuf};

fn repo(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn default_model_text() -> String {
    std::fs::read_to_string(repo("models/musculo_fullbody.osim")).expect("committed model")
}

#[test]
fn rebuilding_from_the_tables_gives_the_committed_file_byte_for_byte() {
    let tables = ModelTables::read(&repo("data/model")).expect("tables");
    let built = build_osim(&tables).expect("builds");
    let committed = default_model_text();
    if built != committed {
        let line = (built.lines().zip(committed.lines()))
            .position(|(a, b)| a != b)
            .unwrap_or(built.lines().count().min(committed.lines().count()));
        panic!(
            "models/musculo_fullbody.osim differs from `musculo model build` at line {}: run it and commit",
            line + 1
        );
    }
}

#[test]
fn counts_mass_and_segment_masses_are_those_of_the_design() {
    let model = Model::from_osim_str(&default_model_text(), "musculo_fullbody").unwrap();
    assert_eq!(model.bodies.len() - 1, 21, "bodies besides ground");
    assert_eq!(model.nq(), 29, "independent coordinates");
    let muscles = (model.forces.iter())
        .filter(
            |f| matches!(&f.actuator, Some(a) if a.kind == musculo::model::ActuatorKind::Muscle),
        )
        .count();
    assert_eq!(muscles, 324);
    let mass = model.total_mass();
    assert!((mass - 75.0).abs() <= 0.005 * 75.0, "total mass {mass}");
    // de Leva (1996) Table 4, males: fractions of body mass
    let body = |n: &str| model.bodies.iter().find(|b| b.name == n).unwrap().mass;
    for (name, percent) in [
        ("pelvis", 11.17),
        ("femur_r", 14.16),
        ("tibia_l", 4.33),
        ("humerus_r", 2.71),
        ("torso", 15.96 + 6.94),
    ] {
        let expected = percent / 100.0 * 75.0;
        assert!(
            (body(name) - expected).abs() < 1e-9,
            "{name}: {} kg vs {expected}",
            body(name)
        );
    }
    let lumbar: f64 = (1..=5).map(|k| body(&format!("lumbar{k}"))).sum();
    assert!(
        (lumbar - 0.1633 * 75.0).abs() < 1e-9,
        "lumbar bodies {lumbar}"
    );
    // the coordinates gait2392 and Rajagopal2016 motions name
    for name in [
        "pelvis_tilt",
        "hip_flexion_r",
        "knee_angle_l",
        "ankle_angle_r",
        "lumbar_extension",
        "lumbar_bending",
        "lumbar_rotation",
        "arm_flex_r",
        "elbow_flex_l",
        "pro_sup_r",
    ] {
        assert!(model.coordinates.iter().any(|c| c.name == name), "{name}");
    }
    // SMPL (HumanML3D) and CMU joint markers, four contact spheres per foot
    for name in [
        "pelvis",
        "left_knee",
        "right_wrist",
        "head",
        "spine3",
        "LeftUpLeg",
        "RightHand",
        "Neck",
    ] {
        assert!(
            model.markers.iter().any(|m| m.name == name),
            "marker {name}"
        );
    }
    assert_eq!(model.contact_geometry.len(), 8);
}

#[test]
fn every_biomechanics_check_passes() {
    let model = Model::from_osim_str(&default_model_text(), "musculo_fullbody").unwrap();
    let report = run_checks(&model, &CheckOptions::default()).expect("checks run");
    let failed: Vec<String> = (report.checks.iter())
        .filter(|c| c.status == musculo::check::Status::Fail)
        .map(|c| format!("{} {} {}", c.family.name(), c.name, c.subject))
        .collect();
    assert!(failed.is_empty(), "{} failed: {failed:?}", failed.len());
}

/// CoordinateActuators on every independent coordinate: pelvis residuals and joint reserves,
/// optimal force 1 (OpenSim's weak-residual convention), unbounded controls.
fn with_reserves(model_text: &str) -> (Model, Vec<String>) {
    let plain = Model::from_osim_str(model_text, "musculo_fullbody").unwrap();
    let mut xml =
        String::from("<OpenSimDocument Version=\"40000\"><ForceSet name=\"reserves\"><objects>");
    let mut reserves = Vec::new();
    for &c in &plain.reduction.independent {
        let name = &plain.coordinates[c].name;
        xml += &format!(
            "<CoordinateActuator name=\"{name}_reserve\"><coordinate>{name}</coordinate><optimal_force>1</optimal_force><min_control>-Inf</min_control><max_control>Inf</max_control></CoordinateActuator>"
        );
        if !name.starts_with("pelvis_") {
            reserves.push(format!("{name}_reserve"));
        }
    }
    xml += "</objects></ForceSet></OpenSimDocument>";
    let files = ForceSetFiles {
        files: vec![(xml, "reserves.xml".to_string())],
        replace: false,
    };
    let model = Model::from_osim_str_with_force_sets(
        model_text,
        "musculo_fullbody",
        &LoadOptions::default(),
        &files,
    )
    .unwrap();
    (model, reserves)
}

/// Σ|reserve| / Σ|τ| over the joints (pelvis residuals excluded) and frames, and the worst
/// coordinate's share with its name.
fn reserve_share(
    model: &Model,
    reserves: &[String],
    force: &Table,
    tau: &Table,
) -> (f64, String, f64) {
    let (mut used, mut needed) = (0.0, 0.0);
    let mut worst = (String::new(), 0.0);
    for r in reserves {
        let coordinate = r.trim_end_matches("_reserve");
        let fc = force.labels.iter().position(|l| l == r).unwrap();
        let c = model
            .coordinates
            .iter()
            .position(|c| c.name == coordinate)
            .unwrap();
        let label = musculo::solve::inverse_dynamics::generalized_force_label(model, c);
        let tc = tau.labels.iter().position(|l| *l == label).unwrap();
        let (mut u, mut n) = (0.0, 0.0);
        for (row, t) in force.time.iter().enumerate() {
            let tr = tau.time.iter().position(|x| (x - t).abs() < 1e-9).unwrap();
            u += force.values[row * force.labels.len() + fc].abs();
            n += tau.values[tr * tau.labels.len() + tc].abs();
        }
        used += u;
        needed += n;
        // coordinates with little moment to carry are reported but not ranked
        if n > 1.0 * force.time.len() as f64 && u / n > worst.1 {
            worst = (coordinate.to_string(), u / n);
        }
    }
    (used / needed, worst.0, worst.1)
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

#[test]
fn static_optimization_balances_a_standing_pose_with_reserves_under_5_percent() {
    let text = default_model_text();
    let (model, reserves) = with_reserves(&text);
    let dir = std::env::temp_dir().join(format!("musculo-standing-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // the default pose held for one second
    let names: Vec<&str> = (model.reduction.independent.iter())
        .map(|&c| model.coordinates[c].name.as_str())
        .collect();
    let mut mot = format!(
        "standing\nversion=1\nnRows=11\nnColumns={}\ninDegrees=no\nendheader\ntime\t{}\n",
        names.len() + 1,
        names.join("\t")
    );
    for k in 0..=10 {
        let values: Vec<String> = (model.reduction.independent.iter())
            .map(|&c| model.coordinates[c].default_value.to_string())
            .collect();
        mot += &format!("{}\t{}\n", k as f64 * 0.1, values.join("\t"));
    }
    write(&dir.join("standing.mot"), &mot);
    // each foot carries half the weight, under the whole-body centre of mass in x
    let mut data = musculo::Data::new(&model);
    let q: Vec<f64> = (model.reduction.independent.iter())
        .map(|&c| model.coordinates[c].default_value)
        .collect();
    musculo::dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
    let com = musculo::dynamics::center_of_mass(&model, &data).unwrap();
    let weight = model.total_mass() * 9.80665;
    let foot_z = |body: &str| {
        let b = model.bodies.iter().position(|x| x.name == body).unwrap();
        data.body_pose(b).1.z
    };
    let (zr, zl) = (foot_z("calcn_r"), foot_z("calcn_l"));
    let mut grf = String::from(
        "grf\nversion=1\nnRows=11\nnColumns=13\ninDegrees=no\nendheader\ntime\tr_vx\tr_vy\tr_vz\tr_px\tr_py\tr_pz\tl_vx\tl_vy\tl_vz\tl_px\tl_py\tl_pz\n",
    );
    for k in 0..=10 {
        grf += &format!(
            "{}\t0\t{}\t0\t{}\t0\t{}\t0\t{}\t0\t{}\t0\t{}\n",
            k as f64 * 0.1,
            weight / 2.0,
            com.x,
            zr,
            weight / 2.0,
            com.x,
            zl
        );
    }
    write(&dir.join("grf.mot"), &grf);
    let force = |name: &str, body: &str, prefix: &str| {
        format!(
            "<ExternalForce name=\"{name}\"><applied_to_body>{body}</applied_to_body><force_expressed_in_body>ground</force_expressed_in_body><point_expressed_in_body>ground</point_expressed_in_body><force_identifier>{prefix}_v</force_identifier><point_identifier>{prefix}_p</point_identifier></ExternalForce>"
        )
    };
    write(
        &dir.join("grf.xml"),
        &format!(
            "<OpenSimDocument Version=\"40000\"><ExternalLoads name=\"standing\"><objects>{}{}</objects><datafile>grf.mot</datafile></ExternalLoads></OpenSimDocument>",
            force("right", "calcn_r", "r"),
            force("left", "calcn_l", "l")
        ),
    );
    let loads = ExternalLoadSet::read(&model, &dir.join("grf.xml")).unwrap();
    let coordinates = Table::read(&dir.join("standing.mot")).unwrap();
    let so = StaticOptimization::new(&model, StaticOptimizationOptions::default()).unwrap();
    let run = run_static_optimization(
        &model,
        &so,
        &coordinates,
        "standing.mot",
        Some(&loads),
        &SoRunOptions::default(),
        &mut |_, _| {},
    )
    .unwrap();
    assert!(run.problems.is_empty(), "{:?}", run.problems.first());
    let id = inverse_dynamics(
        &model,
        &coordinates,
        "standing.mot",
        Some(&loads),
        &InverseDynamicsOptions::default(),
        &mut |_, _| {},
    )
    .unwrap();
    let (share, worst, worst_share) = reserve_share(&model, &reserves, &run.force, &id.table);
    println!(
        "standing: {} frames, reserves carry {:.2} % of the joint moments (most: {worst} {:.1} %)",
        run.force.time.len(),
        100.0 * share,
        100.0 * worst_share
    );
    assert!(share < 0.05, "reserves carry {:.1} %", 100.0 * share);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn static_optimization_balances_the_gait2392_walk_with_reserves_under_5_percent() {
    let dir = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let (Some(kinematics), Some(grf)) = (
        reference_file(&format!("{dir}/subject01_walk1_Kinematics.sto")),
        reference_file("opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1_grf.xml"),
    ) else {
        return;
    };
    let (model, reserves) = with_reserves(&default_model_text());
    let mut coordinates = Table::read(&kinematics).unwrap();
    let added = fill_missing_coordinates(&model, &mut coordinates);
    println!("held at their defaults: {}", added.join(" "));
    let loads = ExternalLoadSet::read(&model, &grf).unwrap();
    let so = StaticOptimization::new(&model, StaticOptimizationOptions::default()).unwrap();
    let options = SoRunOptions {
        lowpass_hz: Some(6.0),
        time_range: Some([0.5, 2.0]),
        step_interval: 10,
    };
    let source = kinematics.display().to_string();
    let run = run_static_optimization(
        &model,
        &so,
        &coordinates,
        &source,
        Some(&loads),
        &options,
        &mut |_, _| {},
    )
    .unwrap();
    assert!(run.problems.is_empty(), "{:?}", run.problems.first());
    let id = inverse_dynamics(
        &model,
        &coordinates,
        &source,
        Some(&loads),
        &InverseDynamicsOptions {
            lowpass_hz: Some(6.0),
            time_range: Some([0.5, 2.0]),
            forces_to_exclude: None,
        },
        &mut |_, _| {},
    )
    .unwrap();
    let (share, worst, worst_share) = reserve_share(&model, &reserves, &run.force, &id.table);
    println!(
        "gait2392 walk: {} frames, reserves carry {:.2} % of the joint moments (most: {worst} {:.1} %)",
        run.force.time.len(),
        100.0 * share,
        100.0 * worst_share
    );
    assert!(share < 0.05, "reserves carry {:.1} %", 100.0 * share);
}
