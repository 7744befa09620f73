//! `musculo check`: the biomechanics unit checks on the demo model, arm26, gait2392 and
//! Rajagopal2016 (which checks those published models fail, and only those), and on
//! deliberately broken models, each of which must fail the right check.

mod common;
use common::*;
use musculo::Model;
use musculo::check::{self, CheckOptions, CheckReport, Family, Status, Tables};
use musculo::model::LoadOptions;
use std::collections::BTreeSet;
use std::process::Command;

fn run(model: &Model) -> CheckReport {
    check::run(model, &CheckOptions::default()).expect("valid options")
}

/// (family, check, subject) of every failed check.
fn failures(report: &CheckReport) -> BTreeSet<(Family, String, String)> {
    report
        .failures()
        .map(|c| (c.family, c.name.clone(), c.subject.clone()))
        .collect()
}

fn status(report: &CheckReport, family: Family, name: &str, subject: &str) -> Status {
    let found: Vec<_> = report
        .find(family, subject)
        .filter(|c| c.name == name)
        .collect();
    assert_eq!(
        found.len(),
        1,
        "{family:?} `{name}` on `{subject}`: {found:?}"
    );
    found[0].status
}

fn load(relative: &str) -> Option<Model> {
    let path = reference_file(relative)?;
    Some(
        Model::from_osim_file_with(path, &LoadOptions { strict: true })
            .expect("reference model reads"),
    )
}

const ARM26: &str = "opensim-models/Models/Arm26/arm26.osim";
const GAIT2392: &str = "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim";
const RAJAGOPAL: &str = "opensim-models/Models/Rajagopal/Rajagopal2016.osim";

#[test]
fn demo_model_passes_every_check() {
    let report = run(&Model::demo());
    assert!(report.passed(), "{:?}", failures(&report));
    // Every family but the table-driven ones (the demo's names are not in the tables) ran.
    for f in [
        Family::Connectivity,
        Family::MassInertia,
        Family::Coordinates,
        Family::MuscleParameters,
        Family::Paths,
    ] {
        assert!(report.summary(f).pass > 0, "{f:?}");
    }
}

#[test]
fn negative_mass_fails_the_mass_check_only() {
    // The reader refuses a negative mass in a file; a model built or changed in memory is
    // checked all the same.
    let mut model = Model::demo();
    let b = model.body_index("shank").unwrap();
    model.bodies[b].mass = -3.5;
    let report = run(&model);
    assert_eq!(
        failures(&report),
        BTreeSet::from([(Family::MassInertia, "mass > 0".into(), "shank".into())])
    );
}

#[test]
fn inertia_violating_the_triangle_inequality_fails_that_check() {
    let mut model = Model::demo();
    let b = model.body_index("thigh").unwrap();
    // Positive definite, but 0.01 + 0.01 < 0.05.
    model.bodies[b].inertia_about_com =
        musculo::spatial::Mat3::from_diagonal(&musculo::spatial::Vec3::new(0.01, 0.05, 0.01));
    let report = run(&model);
    assert_eq!(
        status(
            &report,
            Family::MassInertia,
            "inertia positive definite",
            "thigh"
        ),
        Status::Pass
    );
    assert_eq!(
        failures(&report),
        BTreeSet::from([(
            Family::MassInertia,
            "inertia triangle inequality".into(),
            "thigh".into()
        )])
    );
    // A non-positive-definite inertia fails the other check.
    model.bodies[b].inertia_about_com =
        musculo::spatial::Mat3::from_diagonal(&musculo::spatial::Vec3::new(0.01, -0.01, 0.01));
    let report = run(&model);
    assert_eq!(
        status(
            &report,
            Family::MassInertia,
            "inertia positive definite",
            "thigh"
        ),
        Status::Fail
    );
}

#[test]
fn triangle_inequality_is_reported_for_a_file_read_without_strict() {
    let xml = musculo::DEMO_MODEL_OSIM.replace(
        "<inertia>0.11 0.03 0.12 0.002 0 0</inertia>",
        "<inertia>0.01 0.05 0.01 0 0 0</inertia>",
    );
    assert!(
        Model::from_osim_str_with(&xml, "bad", &LoadOptions { strict: true }).is_err(),
        "the strict reader refuses it"
    );
    let model = Model::from_osim_str(&xml, "bad").unwrap();
    assert_eq!(
        failures(&run(&model)),
        BTreeSet::from([(
            Family::MassInertia,
            "inertia triangle inequality".into(),
            "thigh".into()
        )])
    );
}

#[test]
fn optimal_fiber_length_in_the_wrong_unit_fails_the_parameter_check() {
    let xml = musculo::DEMO_MODEL_OSIM.replace(
        "<optimal_fiber_length>0.087</optimal_fiber_length>",
        "<optimal_fiber_length>10</optimal_fiber_length>",
    );
    let model = Model::from_osim_str(&xml, "fiber-in-metres-x100").unwrap();
    let report = run(&model);
    let c = report
        .find(Family::MuscleParameters, "vasti")
        .find(|c| c.name == "optimal_fiber_length")
        .unwrap();
    assert_eq!((c.status, c.value), (Status::Fail, Some(10.0)));
    let failed = failures(&report);
    assert!(failed.contains(&(
        Family::MuscleParameters,
        "optimal_fiber_length".into(),
        "vasti".into()
    )));
    // The other parameters of the muscle still pass.
    for p in [
        "max_isometric_force",
        "tendon_slack_length",
        "pennation_angle_at_optimal",
    ] {
        assert_eq!(
            status(&report, Family::MuscleParameters, p, "vasti"),
            Status::Pass
        );
    }
}

#[test]
fn range_min_above_max_fails_the_range_check() {
    // The reader refuses it in a file; the check catches it in a model changed in memory.
    let xml =
        musculo::DEMO_MODEL_OSIM.replace("<range>-0.7 0.5</range>", "<range>0.5 -0.7</range>");
    assert!(Model::from_osim_str(&xml, "bad").is_err());
    let mut model = Model::demo();
    let c = model.coordinate_index("ankle_angle").unwrap();
    model.coordinates[c].range = [0.5, -0.7];
    let report = run(&model);
    let failed = failures(&report);
    assert!(failed.contains(&(
        Family::Coordinates,
        "range min < max".into(),
        "ankle_angle".into()
    )));
    // The default value 0 is outside [0.5, -0.7] as well.
    assert!(failed.contains(&(
        Family::Coordinates,
        "default value in range".into(),
        "ankle_angle".into()
    )));
    assert!(failed.iter().all(|(f, ..)| *f == Family::Coordinates));
}

#[test]
fn implausible_rotation_range_fails() {
    let mut model = Model::demo();
    let c = model.coordinate_index("hip_flexion").unwrap();
    model.coordinates[c].range = [-10.0, 10.0];
    let report = run(&model);
    assert_eq!(
        status(
            &report,
            Family::Coordinates,
            "range plausible",
            "hip_flexion"
        ),
        Status::Fail
    );
}

/// Tables naming the demo's knee: vasti extend it (knee_angle flexes negative, the wide side).
fn demo_tables() -> Tables {
    let mut t = Tables::builtin();
    t.coordinate_directions +=
        "knee_angle,extension,narrower,test\nknee_angle,flexion,wider,test\n";
    t.agonist_signs += "vasti,knee_angle,extension,test\n";
    t.max_isometric_moments += "knee_angle,extension,1,100000,test\n";
    // Without its wrap cylinder the vasti path cuts through the knee beyond 100° of flexion.
    t.range_of_motion += "knee_angle,flexion,90,test\n";
    t
}

#[test]
fn mirrored_muscle_path_fails_the_agonist_sign_check() {
    let options = CheckOptions {
        tables: demo_tables(),
        ..CheckOptions::default()
    };
    let mut model = Model::demo();
    let k = model.forces.iter().position(|f| f.name == "vasti").unwrap();
    // A plain point path (no wrapping), in front of the knee: an extensor up to 90° of flexion.
    std::sync::Arc::make_mut(model.forces[k].path.as_mut().unwrap())
        .wraps
        .clear();
    let report = check::run(&model, &options).unwrap();
    assert_eq!(
        status(
            &report,
            Family::AgonistSigns,
            "extension about knee_angle",
            "vasti"
        ),
        Status::Pass
    );
    assert_eq!(
        status(
            &report,
            Family::MaxIsometricMoments,
            "max isometric moment",
            "knee_angle extension"
        ),
        Status::Pass
    );
    // Mirror the thigh and shank points through the frontal plane of the knee (x → −x; the
    // knee centre lies on both bodies' y axes) and drop the patella point: the path passes
    // behind the knee.
    let patella = model.body_index("patella").unwrap();
    let path = std::sync::Arc::make_mut(model.forces[k].path.as_mut().unwrap());
    path.points.retain(|p| p.body != patella);
    for p in &mut path.points {
        p.location.x = -p.location.x;
    }
    let report = check::run(&model, &options).unwrap();
    let c = report
        .find(Family::AgonistSigns, "vasti")
        .find(|c| c.name == "extension about knee_angle")
        .unwrap();
    assert_eq!(c.status, Status::Fail, "{c:?}");
    assert!(c.message.contains("wrong sign"), "{c:?}");
    // It is now a flexor over most of the knee's range: the wrong sign at most poses.
    let wrong: usize = c.message["wrong sign at ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(wrong > 10, "{c:?}");
    assert!(
        c.value.unwrap() < 0.0,
        "a flexor at the default pose: {c:?}"
    );
}

#[test]
fn bad_options_and_tables_are_errors() {
    let model = Model::demo();
    let mut o = CheckOptions {
        grid_points: 1,
        ..CheckOptions::default()
    };
    assert!(check::run(&model, &o).is_err());
    o.grid_points = 9;
    o.tables.agonist_signs += "vasti,knee_angle,sideways,test\n";
    let e = check::run(&model, &o).unwrap_err().to_string();
    assert!(
        e.contains("agonist_signs.csv") && e.contains("sideways"),
        "{e}"
    );
    let mut o = CheckOptions::default();
    o.tables.parameter_ranges += "optimal_fiber_length,0.1,x,m,test\n";
    assert!(check::run(&model, &o).is_err());
    let mut o = CheckOptions::default();
    o.tables.max_isometric_moments += "knee_angle_{side},extension,100,200,\n";
    let e = check::run(&model, &o).unwrap_err().to_string();
    assert!(e.contains("empty source"), "{e}");
}

#[test]
fn arm26_fails_only_its_massless_base_and_two_shoulder_wrap_jumps() {
    let Some(model) = load(ARM26) else { return };
    let report = run(&model);
    assert_eq!(
        failures(&report)
            .into_iter()
            .map(|(f, n, s)| format!("{}/{n}/{s}", f.name()))
            .collect::<Vec<_>>(),
        [
            "mass-inertia/mass > 0/base",
            "mass-inertia/inertia positive definite/base",
            "paths/moment-arm continuity/TRIlong",
            "paths/moment-arm continuity/BIClong",
        ]
        .map(String::from)
        .into_iter()
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect::<Vec<_>>()
    );
    for m in ["BIClong", "BICshort", "BRA"] {
        assert_eq!(
            status(
                &report,
                Family::AgonistSigns,
                "flexion about r_elbow_flex",
                m
            ),
            Status::Pass
        );
    }
    for m in ["TRIlong", "TRIlat", "TRImed"] {
        assert_eq!(
            status(
                &report,
                Family::AgonistSigns,
                "extension about r_elbow_flex",
                m
            ),
            Status::Pass
        );
    }
    let s = report.summary(Family::MaxIsometricMoments);
    assert_eq!((s.pass, s.fail), (4, 0));
}

#[test]
fn gait2392_fails_only_explained_checks() {
    let Some(model) = load(GAIT2392) else { return };
    let report = run(&model);
    for f in [
        Family::Connectivity,
        Family::MassInertia,
        Family::Coordinates,
        Family::MuscleParameters,
        Family::MaxIsometricMoments,
    ] {
        assert_eq!(report.summary(f).fail, 0, "{f:?}: {:?}", failures(&report));
    }
    // Every direction of hip, knee, ankle and lumbar spine is compared (36 muscles' worth).
    assert_eq!(report.summary(Family::MaxIsometricMoments).pass, 20);
    // Agonist signs: only the hip flexors and gluteus maximus in deep hip flexion (> 100°),
    // the long head of biceps femoris at the end of knee flexion (−120°) and the straight
    // back muscles in deep lumbar flexion.
    let signs: BTreeSet<String> = failures(&report)
        .into_iter()
        .filter(|(f, ..)| *f == Family::AgonistSigns)
        .map(|(_, n, s)| format!("{n}/{s}"))
        .collect();
    let mut expected = BTreeSet::new();
    for side in ["r", "l"] {
        for m in ["iliacus", "psoas"] {
            expected.insert(format!("flexion about hip_flexion_{side}/{m}_{side}"));
        }
        for m in ["glut_max1", "glut_max2"] {
            expected.insert(format!("extension about hip_flexion_{side}/{m}_{side}"));
        }
        expected.insert(format!("flexion about knee_angle_{side}/bifemlh_{side}"));
        // Straight back muscles in deep lumbar flexion (75-80°).
        expected.insert(format!("extension about lumbar_extension/ercspn_{side}"));
        expected.insert(format!("flexion about lumbar_extension/intobl_{side}"));
    }
    assert_eq!(signs, expected);
    for side in ["r", "l"] {
        for (m, name) in [
            ("soleus", format!("plantarflexion about ankle_angle_{side}")),
            ("tib_ant", format!("dorsiflexion about ankle_angle_{side}")),
            ("rect_fem", format!("extension about knee_angle_{side}")),
            ("vas_lat", format!("extension about knee_angle_{side}")),
            ("extobl", "flexion about lumbar_extension".into()),
        ] {
            assert_eq!(
                status(&report, Family::AgonistSigns, &name, &format!("{m}_{side}")),
                Status::Pass,
                "{m}_{side}"
            );
        }
    }
    // Lengths are finite and positive everywhere on the grid.
    assert!(
        report
            .checks
            .iter()
            .filter(|c| c.name == "length finite > 0")
            .all(|c| c.status == Status::Pass)
    );
}

#[test]
fn rajagopal2016_fails_only_explained_checks() {
    let Some(model) = load(RAJAGOPAL) else { return };
    let report = run(&model);
    let failed = failures(&report);
    let coords: BTreeSet<_> = failed
        .iter()
        .filter(|(f, ..)| *f == Family::Coordinates)
        .map(|(_, n, s)| format!("{n}/{s}"))
        .collect();
    assert_eq!(
        coords,
        BTreeSet::from([
            "range plausible/knee_angle_l_beta".to_string(),
            "range plausible/knee_angle_r_beta".to_string()
        ])
    );
    for f in [
        Family::Connectivity,
        Family::MassInertia,
        Family::MuscleParameters,
        Family::Paths,
        Family::AgonistSigns,
    ] {
        assert_eq!(report.summary(f).fail, 0, "{f:?}: {failed:?}");
    }
    assert!(report.summary(Family::AgonistSigns).pass >= 50);
    // MRI volumes and a specific tension of 60 N/cm² (Rajagopal 2016): stronger than the
    // voluntary means of young men in the hip, knee and ankle, yet within the full-activation
    // envelope (1.5 × the voluntary ranges' upper ends) in every direction; never weaker
    // than the envelope's lower end.
    let moments: Vec<_> = report
        .checks
        .iter()
        .filter(|c| c.family == Family::MaxIsometricMoments && c.status != Status::Skip)
        .collect();
    assert!(moments.len() >= 16, "{}", moments.len());
    for c in &moments {
        assert_eq!(c.status, Status::Pass, "{c:?}");
    }
    let knee_extension = moments
        .iter()
        .find(|c| c.subject == "knee_angle_r extension")
        .and_then(|c| c.value)
        .unwrap();
    // above the old voluntary envelope's 400 N·m, below 1.5 × 400
    assert!(
        knee_extension > 400.0 && knee_extension < 600.0,
        "{knee_extension}"
    );
    assert_eq!(
        status(
            &report,
            Family::MaxIsometricMoments,
            "max isometric moment",
            "lumbar_extension extension"
        ),
        Status::Skip
    );
}

fn musculo(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args(args)
        .output()
        .expect("run musculo");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr),
    )
}

#[test]
fn cli_exits_zero_on_the_demo_and_non_zero_on_a_failing_model() {
    let (code, out) = musculo(&["check", "--demo"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("all checks passed"), "{out}");

    let dir = std::env::temp_dir().join(format!("musculo-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fiber10.osim");
    std::fs::write(
        &path,
        musculo::DEMO_MODEL_OSIM.replace(
            "<optimal_fiber_length>0.087</optimal_fiber_length>",
            "<optimal_fiber_length>10</optimal_fiber_length>",
        ),
    )
    .unwrap();
    let (code, out) = musculo(&["check", path.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{out}");
    assert!(
        out.lines().any(|l| l.starts_with("FAIL")
            && l.contains("optimal_fiber_length")
            && l.contains("vasti")),
        "{out}"
    );
    let (code, out) = musculo(&["check", "--json", path.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    let json: serde_json::Value = serde_json::from_str(&out).expect("JSON on stdout");
    assert_eq!(json["passed"], false);
    assert_eq!(json["summary"]["muscle-parameters"]["fail"], 1);
    assert!(
        json["checks"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["check"] == "optimal_fiber_length"
                && c["status"] == "fail"
                && c["value"] == 10.0)
    );
    std::fs::remove_dir_all(&dir).ok();

    let (code, out) = musculo(&["check", "no/such/model.osim"]);
    assert_eq!(code, Some(1));
    assert!(out.contains("no/such/model.osim"), "{out}");
}

#[test]
fn moment_arm_bound_holds_a_wrapped_muscle_to_its_pulley_radius() {
    let model = Model::from_osim_str(PULLEY_OSIM, "pulley.osim").unwrap();
    let header = "muscles,coordinates,max_m,source\n";
    let check_with = |bound: f64, random_poses: usize| {
        let mut options = CheckOptions {
            random_poses,
            ..CheckOptions::default()
        };
        options.tables.moment_arm_bounds = format!("{header}rope,theta,{bound},test\n");
        let report = check::run(&model, &options).unwrap();
        let found: Vec<_> = report
            .find(Family::MomentArmBounds, "rope")
            .cloned()
            .collect();
        assert_eq!(found.len(), 1, "{found:?}");
        (found[0].clone(), report)
    };
    for random_poses in [0, 50] {
        // A bound below the radius fails, with the radius as the measured value ...
        let (c, report) = check_with(0.9 * PULLEY_RADIUS, random_poses);
        assert_eq!(c.status, Status::Fail, "{c:?}");
        assert!((c.value.unwrap() - PULLEY_RADIUS).abs() < 1e-9, "{c:?}");
        assert!(c.limit.contains("about theta"), "{c:?}");
        if random_poses > 0 {
            assert_eq!(
                status(
                    &report,
                    Family::MomentArmBounds,
                    "random poses computable",
                    "pulley"
                ),
                Status::Pass
            );
        }
        // ... and one above it passes.
        let (c, _) = check_with(1.1 * PULLEY_RADIUS, random_poses);
        assert_eq!(c.status, Status::Pass, "{c:?}");
    }
    // Without a row for the coordinate the muscle crosses, the check is skipped, not passed.
    let mut options = CheckOptions::default();
    options.tables.moment_arm_bounds = format!("{header}rope,phi,0.1,test\n");
    let report = check::run(&model, &options).unwrap();
    assert_eq!(
        status(
            &report,
            Family::MomentArmBounds,
            "moment-arm magnitude",
            "rope"
        ),
        Status::Skip
    );
    // A bad bound is a table error naming the table and line.
    options.tables.moment_arm_bounds = format!("{header}rope,theta,-0.1,test\n");
    let e = check::run(&model, &options).unwrap_err().to_string();
    assert!(e.contains("moment_arm_bounds.csv:2"), "{e}");
}

#[test]
fn default_model_holds_every_moment_arm_within_its_bound() {
    let report = run(&Model::default_fullbody());
    let s = report.summary(Family::MomentArmBounds);
    assert_eq!(s.fail, 0, "{:?}", failures(&report));
    // every muscle but the two LTpT_T1 fascicles (across the welded T12/L1 joint only) is held
    // to a bound
    assert_eq!((s.pass, s.skip), (322, 2));
}
