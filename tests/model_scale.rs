//! `solve::scale::scale_uniform` against what uniform scaling must do to a model: total mass and segment
//! masses × k, mass centres × s, inertias × k s², gravity torques on rotational coordinates
//! × k s (forces on translational ones × k), musculotendon lengths × s, and each muscle's
//! optimal fiber and tendon slack lengths in the same ratio to its length as before.

mod common;

use common::reference_file;
use musculo::model::{LoadOptions, Model, MotionType};
use musculo::muscle::path::{PathData, PathSet, compute_paths};
use musculo::solve::scale::{ScaleFactors, scale_uniform};
use musculo::{Data, dynamics};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

fn lengths(model: &Model) -> Vec<(String, f64)> {
    let set = PathSet::new(model).unwrap();
    let mut data = Data::new(model);
    dynamics::forward_kinematics(model, &mut data, &model.default_q()).unwrap();
    let mut paths = PathData::new(model, &set);
    compute_paths(model, &data, &set, &mut paths).unwrap();
    set.paths
        .iter()
        .map(|p| p.name.clone())
        .zip(paths.length.iter().copied())
        .collect()
}

fn muscle_parameter(model: &Model, name: &str, tag: &str) -> f64 {
    let f = model.forces.iter().find(|f| f.name == name).unwrap();
    let child = f.raw.children.iter().find(|c| c.tag == tag);
    let child = child.unwrap_or_else(|| panic!("{name}: no {tag}"));
    child.text.trim().parse().unwrap()
}

fn check_scaling(xml: &str, source: &str, options: &LoadOptions, s: f64, k: f64) {
    let model = Model::from_osim_str_with(xml, source, options).unwrap();
    let factors = ScaleFactors { length: s, mass: k };
    let scaled_xml = scale_uniform(xml, source, &model, factors).unwrap();
    let scaled = Model::from_osim_str_with(&scaled_xml, source, options).unwrap();
    assert!(close(scaled.total_mass(), k * model.total_mass(), 1e-12));
    for (a, b) in model.bodies.iter().zip(&scaled.bodies) {
        assert!(close(b.mass, k * a.mass, 1e-12), "{} mass", a.name);
        for i in 0..3 {
            assert!(
                close(b.com_in_body[i], s * a.com_in_body[i], 1e-12),
                "{} com",
                a.name
            );
            for j in 0..3 {
                let (x, y) = (
                    b.inertia_about_com[(i, j)],
                    k * s * s * a.inertia_about_com[(i, j)],
                );
                assert!(close(x, y, 1e-12), "{} inertia", a.name);
            }
        }
    }
    // gravity at a few poses: rotational × k s, translational × k
    let mut rng = common::Rng::new(5);
    for _ in 0..5 {
        let q = common::random_q(&model, &mut rng);
        let mut q_scaled = q.clone();
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            if model.coordinates[c].motion_type == MotionType::Translational {
                q_scaled[j] *= s;
            }
        }
        let (mut d, mut ds) = (Data::new(&model), Data::new(&scaled));
        let g = dynamics::gravity(&model, &mut d, &q).unwrap().clone();
        let gs = dynamics::gravity(&scaled, &mut ds, &q_scaled)
            .unwrap()
            .clone();
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            let f = match model.coordinates[c].motion_type {
                MotionType::Translational => k,
                _ => k * s,
            };
            assert!(
                (gs[j] - f * g[j]).abs() <= 1e-9 * (1.0 + g[j].abs() * f),
                "{source}: G[{}] {} vs {}",
                model.coordinates[c].name,
                gs[j],
                f * g[j]
            );
        }
    }
    // musculotendon lengths × s; fiber and tendon in the same ratio to them
    for ((name, l0), (_, l1)) in lengths(&model).into_iter().zip(lengths(&scaled)) {
        assert!(close(l1, s * l0, 1e-9), "{name}: length {l1} vs {}", s * l0);
        for tag in ["optimal_fiber_length", "tendon_slack_length"] {
            let (a, b) = (
                muscle_parameter(&model, &name, tag),
                muscle_parameter(&scaled, &name, tag),
            );
            assert!(
                close(b / l1, a / l0, 1e-9),
                "{name}: {tag} ratio {} vs {}",
                b / l1,
                a / l0
            );
        }
    }
}

#[test]
fn scaling_the_default_model_scales_mass_inertia_gravity_and_muscles_consistently() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/musculo_fullbody.osim");
    let xml = std::fs::read_to_string(path).unwrap();
    check_scaling(
        &xml,
        "musculo_fullbody",
        &LoadOptions::default(),
        1.6 / 1.75,
        60.0 / 75.0,
    );
    check_scaling(
        &xml,
        "musculo_fullbody",
        &LoadOptions::default(),
        1.95 / 1.75,
        95.0 / 75.0,
    );
}

#[test]
fn scaling_gait2392_and_arm26_scales_consistently() {
    for relative in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Arm26/arm26.osim",
    ] {
        let Some(path) = reference_file(relative) else {
            return;
        };
        let xml = std::fs::read_to_string(&path).unwrap();
        check_scaling(&xml, relative, &LoadOptions::default(), 0.9, 1.1);
    }
}

#[test]
fn bad_factors_are_errors() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/demo.osim");
    let xml = std::fs::read_to_string(path).unwrap();
    let model = Model::from_osim_str(&xml, "demo").unwrap();
    for (s, k) in [(0.0, 1.0), (1.0, -2.0), (f64::NAN, 1.0)] {
        let f = ScaleFactors { length: s, mass: k };
        assert!(scale_uniform(&xml, "demo", &model, f).is_err());
    }
    assert!(ScaleFactors::for_subject(&model, 1.75, 0.0, 1.7).is_err());
    // a subject 10³⁰⁰ times heavier (a model `augment` then overflowed float32 on), 10⁶ m
    // tall, or of 10⁻³⁰⁰ kg: factors outside [0.01, 100] are no subject's
    let m = model.total_mass();
    for (model_height, mass, height, argument) in [
        (1.75, 1e300, 1.7, "mass"),
        (1.75, 1e-300, 1.7, "mass"),
        (1.75, 101.0 * m, 1.7, "mass"),
        (1.75, m, 1e6, "height"),
        (1.75, m, 0.0174, "height"),
        (1e300, m, 1.7, "height"),
    ] {
        let e = ScaleFactors::for_subject(&model, model_height, mass, height).unwrap_err();
        assert!(
            matches!(&e, musculo::Error::InvalidArgument { argument: a, message }
                if *a == argument && message.contains("outside 0.01 to 100")),
            "{e}"
        );
    }
    let f = ScaleFactors::for_subject(&model, 1.75, 99.0 * m, 1.75 * 0.011).unwrap();
    assert!((f.mass - 99.0).abs() < 1e-9 && (f.length - 0.011).abs() < 1e-12);
}
