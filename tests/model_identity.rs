//! Every augmented clip names the body it was computed on (`model_identity` in its `.npz`),
//! and `evaluate`, `loss` and `report` judge it on that body or refuse a model that is not it:
//! a trial augmented on its own model with `--no-scale`, HumanML3D clips scaled to their bones
//! with body-changing variants, and files written without an identity. The check that the
//! right body was used is the physics: the Euler–Lagrange residual of the tensors is zero
//! (float32 rounding) on the body they were computed on and large on another; and the body's
//! mass is the model file's (read here) times the variant's factor plus its load.

mod common;

use common::{musculo_cli, reference_file};
use musculo::Model;
use musculo::augment::identity::{Bodies, read_identity};
use musculo::augment::output::fnv1a_hex;
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-identity-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn metrics(json: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

fn total_mass(model: &Model) -> f64 {
    model.bodies.iter().map(|b| b.mass).sum()
}

#[test]
fn a_trial_augmented_without_scaling_is_judged_on_its_own_model() {
    let (Some(trc), Some(osim)) = (
        reference_file("opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1.trc"),
        reference_file(
            "opensim-models/Pipelines/Gait2392_Simbody/OutputReference/subject01_simbody.osim",
        ),
    ) else {
        return;
    };
    let dir = scratch("trial");
    // a copy of the trial's model (moved and edited below) and of the trial
    let (input, out, json) = (dir.join("in"), dir.join("out"), dir.join("m.json"));
    std::fs::create_dir_all(&input).unwrap();
    std::fs::copy(&trc, input.join("walk.trc")).unwrap();
    let model_file = dir.join("subject01.osim");
    std::fs::copy(&osim, &model_file).unwrap();
    let text = std::fs::read_to_string(&model_file).unwrap();
    let trial_mass = total_mass(&Model::from_osim_file(&model_file).unwrap());
    let (ok, _, err) = musculo_cli(
        "augment --input {} --model {} --no-scale --out {}",
        &[&input, &model_file, &out],
    );
    assert!(ok, "{err}");
    let npz = out.join("walk.npz");
    assert!(!out.join("walk.osim").exists());
    let id = read_identity(&npz).unwrap().unwrap();
    assert_eq!(id.base.file_hash, fnv1a_hex(&text));
    assert!(id.scale.is_none());

    // without --model: the trial's body (its mass, a zero residual), no warning
    let (ok, stdout, err) = musculo_cli("evaluate --input {} --out {}", &[&out, &json]);
    assert!(ok, "{err}");
    println!("{}", stdout.lines().next().unwrap_or(""));
    assert!(!err.contains("warning"), "{err}");
    let clip = &metrics(&json)["clips"][0];
    let mass = clip["body_mass"].as_f64().unwrap();
    assert!(
        (mass - trial_mass).abs() < 1e-9 * trial_mass,
        "{mass} vs {trial_mass} kg"
    );
    let residual = clip["el_residual"].as_f64().unwrap();
    assert!(residual < 1e-6, "{residual:e}");
    let (ok, stdout, err) = musculo_cli("loss {}", &[&npz]);
    assert!(ok, "{err}");
    assert!(stdout.contains("model \"subject01\""), "{stdout}");

    // another model is refused, naming both
    let builtin = dir.join("fullbody.osim");
    std::fs::write(&builtin, musculo::DEFAULT_MODEL_OSIM).unwrap();
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&out, &builtin, &json],
    );
    assert!(!ok);
    for named in [
        "musculo_fullbody",
        &fnv1a_hex(musculo::DEFAULT_MODEL_OSIM),
        "subject01",
        &fnv1a_hex(&text),
    ] {
        assert!(err.contains(named), "{named} not in: {err}");
    }
    let (ok, _, err) = musculo_cli("loss {} --model {}", &[&npz, &builtin]);
    assert!(!ok);
    assert!(
        err.contains("is not the model this clip belongs to"),
        "{err}"
    );

    // the model moved away: refused, naming it; given again (same text): used
    let moved = dir.join("moved.osim");
    std::fs::rename(&model_file, &moved).unwrap();
    let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[&out, &json]);
    assert!(!ok);
    assert!(
        err.contains("subject01") && err.contains("--model"),
        "{err}"
    );
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&out, &moved, &json],
    );
    assert!(ok, "{err}");
    assert!(metrics(&json)["clips"][0]["el_residual"].as_f64().unwrap() < 1e-6);
    // a file of that name with other text is not the model
    std::fs::write(
        &model_file,
        text.replace("</OpenSimDocument>", "<!-- -->\n</OpenSimDocument>"),
    )
    .unwrap();
    let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[&out, &json]);
    assert!(!ok);
    assert!(err.contains("has changed"), "{err}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn clips_scaled_to_their_bones_and_their_variants_are_rebuilt_from_the_base_model() {
    let Some(hml) = reference_file("humanml3d/new_joints_012314.npy") else {
        return;
    };
    let dir = scratch("scaled");
    let (input, plain, files, json) = (
        dir.join("in"),
        dir.join("plain"),
        dir.join("files"),
        dir.join("m.json"),
    );
    std::fs::create_dir_all(&input).unwrap();
    std::fs::copy(&hml, input.join("clip.npy")).unwrap();
    for (out, extra) in [(&plain, ""), (&files, " --opensim-files")] {
        let (ok, _, err) = musculo_cli(
            &format!("augment --input {{}} --variants 3 --out {{}}{extra}"),
            &[&input, out],
        );
        assert!(ok, "{err}");
    }
    let manifest = metrics(&plain.join("manifest.json"));
    let base_mass = total_mass(&Model::default_fullbody());
    let (ok, stdout, err) = musculo_cli("evaluate --input {} --out {}", &[&plain, &json]);
    assert!(ok, "{err}");
    println!("{}", stdout.lines().next().unwrap_or(""));
    assert!(!err.contains("warning"), "{err}");
    let report = metrics(&json);
    for (clip, record) in report["clips"]
        .as_array()
        .unwrap()
        .iter()
        .zip(manifest["clips"].as_array().unwrap())
    {
        let name = clip["clip"].as_str().unwrap();
        assert_eq!(name, record["clip"].as_str().unwrap());
        let v = &record["variant"];
        let expected =
            base_mass * v["mass_scale"].as_f64().unwrap() + v["load_kg"].as_f64().unwrap();
        let mass = clip["body_mass"].as_f64().unwrap();
        assert!(
            (mass - expected).abs() < 1e-9 * expected,
            "{name}: {mass} vs {expected} kg"
        );
        let residual = clip["el_residual"].as_f64().unwrap();
        assert!(residual < 1e-6, "{name}: {residual:e}");
        let id = read_identity(&plain.join(format!("{name}.npz")))
            .unwrap()
            .unwrap();
        assert!(id.scale.is_some(), "{name}");
        assert!(id.osim_hash.is_none());
    }

    // the body rebuilt from the identity is the <clip>.osim augment --opensim-files writes:
    // the same masses, centres of mass, inertias and joint frames
    let bodies = Bodies::new(None).unwrap();
    for name in ["clip", "clip_v1", "clip_v2"] {
        let rebuilt = bodies
            .of_tensor_file(&plain.join(format!("{name}.npz")))
            .unwrap();
        assert!(rebuilt.warning.is_none());
        let written = Model::from_osim_file(files.join(format!("{name}.osim"))).unwrap();
        let (a, b) = (&rebuilt.model, &written);
        assert_eq!(a.bodies.len(), b.bodies.len());
        for (x, y) in a.bodies.iter().zip(&b.bodies) {
            assert!(
                (x.mass - y.mass).abs() <= 1e-9 * (1.0 + y.mass),
                "{name} {}",
                x.name
            );
            assert!(
                (x.com_in_body - y.com_in_body).norm() < 1e-9,
                "{name} {}",
                x.name
            );
            assert!(
                (x.inertia_about_com - y.inertia_about_com).norm() < 1e-9,
                "{name} {}",
                x.name
            );
        }
        for (x, y) in a.joints.iter().zip(&b.joints) {
            for (p, q) in [
                (&x.parent_offset, &y.parent_offset),
                (&x.child_offset, &y.child_offset),
            ] {
                assert!((p.pos - q.pos).norm() < 1e-9, "{name} {}", x.name);
            }
        }
    }

    // the clip's own file is used beside it and accepted as --model; a sibling's is refused
    let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[&files, &json]);
    assert!(ok, "{err}");
    for clip in metrics(&json)["clips"].as_array().unwrap() {
        assert!(clip["el_residual"].as_f64().unwrap() < 1e-6, "{clip}");
    }
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&files.join("clip.npz"), &files.join("clip.osim"), &json],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&files.join("clip.npz"), &files.join("clip_v1.osim"), &json],
    );
    assert!(!ok);
    assert!(
        err.contains("is not the model this clip belongs to"),
        "{err}"
    );

    // the same tensors without their identity are read on the built-in (unscaled) model,
    // with a warning: their residual is the bones' scaling
    let bare = dir.join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    let arrays = musculo::motion::npy::read_npz_f32(&plain.join("clip.npz")).unwrap();
    let views: Vec<_> = arrays.iter().map(|(k, a)| (k.as_str(), a.view())).collect();
    musculo::motion::npy::write_npz(&bare.join("clip.npz"), &views, false).unwrap();
    let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[&bare, &json]);
    assert!(ok, "{err}");
    assert!(
        err.contains("does not say which model it belongs to"),
        "{err}"
    );
    let report = metrics(&json);
    let unscaled = report["clips"][0]["el_residual"].as_f64().unwrap();
    assert!(
        !report["clips"][0]["warnings"]
            .as_array()
            .unwrap()
            .is_empty()
    );
    println!("clip on its scaled body: residual < 1e-6; on the unscaled model {unscaled:.3}");
    assert!(unscaled > 1e-3, "{unscaled}");
    let _ = std::fs::remove_dir_all(dir);
}
