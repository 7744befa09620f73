//! The MJCF export without MuJoCo: structure of the expanded tree, what it says it cannot
//! express, and the command line. (MuJoCo itself loads and checks it in
//! `tests/mujoco_crosscheck.rs` with the `mujoco` feature.)

mod common;
use common::*;
use musculo::Model;
use musculo::mjcf::to_mjcf;
use std::process::Command;

fn count(doc: &roxmltree::Document, tag: &str) -> usize {
    doc.descendants().filter(|n| n.has_tag_name(tag)).count()
}

#[test]
fn demo_exports_one_joint_per_full_coordinate_and_every_site() {
    let model = Model::demo();
    let export = to_mjcf(&model);
    let doc = roxmltree::Document::parse(&export.xml).expect("well-formed MJCF");
    assert_eq!(count(&doc, "body"), model.bodies.len() - 1);
    let joints: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("joint") && n.attribute("type").is_some())
        .map(|n| n.attribute("name").unwrap())
        .collect();
    let names: Vec<&str> = model.dofs.iter().map(|d| d.name.as_str()).collect();
    let mut sorted = joints.clone();
    sorted.sort();
    let mut expected = names.clone();
    expected.sort();
    assert_eq!(sorted, expected, "MuJoCo joints are the full coordinates");
    for m in &model.markers {
        assert!(
            export
                .xml
                .contains(&format!("site name=\"marker:{}\"", m.name))
        );
    }
    assert_eq!(count(&doc, "spatial"), 1);
    assert_eq!(count(&doc, "muscle"), 1);
    // The patella follows the knee, the knee translations follow its rotation: equalities.
    let eq: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("joint") && n.attribute("joint1").is_some())
        .collect();
    assert!(
        eq.iter()
            .any(|n| n.attribute("joint1") == Some("knee/translation1")
                && n.attribute("joint2") == Some("knee/rotation1"))
    );
    assert!(eq.iter().any(
        |n| n.attribute("joint1") == Some("patellofemoral/rotation1")
            && n.attribute("joint2") == Some("knee/rotation1")
    ));
    // The floor half-space becomes a plane whose normal (+z) is the half-space's −x: ground +y.
    let plane = doc
        .descendants()
        .find(|n| n.attribute("type") == Some("plane"))
        .unwrap();
    let q: Vec<f64> = plane
        .attribute("quat")
        .unwrap()
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        q[0], q[1], q[2], q[3],
    ));
    let normal = r * nalgebra::Vector3::z();
    assert!(
        (normal - nalgebra::Vector3::y()).norm() < 1e-12,
        "plane normal {normal:?}"
    );
    // Spline couplings are fitted, so the export says so.
    assert!(
        export.notes.iter().any(|n| n.contains("quartic")),
        "{:?}",
        export.notes
    );
}

#[test]
fn arm26_export_names_the_wrap_objects_mjcf_cannot_express() {
    let Some(p) = reference_file("opensim-models/Models/Arm26/arm26.osim") else {
        return;
    };
    let export = to_mjcf(&Model::from_osim_file(p).unwrap());
    for name in ["TRIlonghh", "BIClonghh"] {
        assert!(
            export
                .notes
                .iter()
                .any(|n| n.contains(name) && n.contains("WrapEllipsoid")),
            "{name} missing from {:?}",
            export.notes
        );
    }
    let doc = roxmltree::Document::parse(&export.xml).unwrap();
    // The wrap cylinders are there, with a side site for their quadrant.
    assert!(
        doc.descendants()
            .any(|n| n.attribute("type") == Some("cylinder")
                && n.attribute("name").is_some_and(|s| s.starts_with("wrap:")))
    );
    assert_eq!(count(&doc, "spatial"), 6);
}

#[test]
fn export_mjcf_command_writes_the_file_and_lists_notes() {
    let dir = std::env::temp_dir().join(format!("musculo-mjcf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("demo.xml");
    let o = Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args(["export-mjcf", "--demo", "-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("11 joints = full coordinates") && err.contains("note:"),
        "{err}"
    );
    let xml = std::fs::read_to_string(&out).unwrap();
    assert_eq!(xml, to_mjcf(&Model::demo()).xml);
    // nothing but the file: no temporary left beside it
    let entries: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(entries, ["demo.xml"]);
    let _ = std::fs::remove_dir_all(&dir);
}
