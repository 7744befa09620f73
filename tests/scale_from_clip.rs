//! Scaling the default model to a clip's bone lengths (`musculo ik --scale auto`,
//! `musculo scale --from-clip`): the factors are the clip's median bone lengths over the
//! model's, recomputed here by hand from the joint array, and the written model file gives
//! the same IK as the in-memory one.

mod common;

use common::{ScratchDir, musculo_cli, reference_file};
use musculo::Model;
use musculo::dynamics::{self, Data};
use musculo::io::Table;
use musculo::motion::{self, ReadOptions, skeleton::SkeletonMap};
use musculo::solve::scale_from_clip::scale_to_clip;

const CLIP: &str = "humanml3d/new_joints_012314.npy";

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[test]
fn segment_factors_are_median_bone_lengths_over_the_model_s() {
    let Some(path) = reference_file(CLIP) else {
        return;
    };
    let clip = motion::read(&path, None, &ReadOptions::default()).unwrap();
    let model = Model::default_fullbody();
    let map = SkeletonMap::builtin("humanml3d").unwrap();
    let scaling =
        scale_to_clip(musculo::DEFAULT_MODEL_OSIM, "default", &model, &map, &clip).unwrap();
    let mut data = Data::new(&model);
    dynamics::forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
    let marker = |name: &str| {
        let m = model.markers.iter().find(|m| m.name == name).unwrap();
        data.point_position(m.body, &m.location_in_body)
    };
    // Right thigh: SMPL right_hip (2) – right_knee (5); left forearm: left_elbow (18) –
    // left_wrist (20); joint indices of the HumanML3D array.
    for (segment, a, b, ia, ib) in [
        ("right thigh", "right_hip", "right_knee", 2, 5),
        ("left forearm", "left_elbow", "left_wrist", 18, 20),
    ] {
        let lengths: Vec<f64> = (0..clip.n_frames())
            .map(|f| (clip.frame(f)[ia] - clip.frame(f)[ib]).norm())
            .collect();
        let expected = median(lengths) / (marker(a) - marker(b)).norm();
        let got = scaling
            .factors
            .iter()
            .find(|(n, _)| n == segment)
            .unwrap()
            .1;
        println!("{segment}: factor {got:.6} (by hand {expected:.6})");
        assert!(
            (got - expected).abs() < 1e-12,
            "{segment}: {got} vs {expected}"
        );
    }
    // The scaled femur's length (hip centre to knee centre in the default pose) is the clip's.
    let scaled = &scaling.model;
    let mut d2 = Data::new(scaled);
    dynamics::forward_kinematics(scaled, &mut d2, &scaled.default_q()).unwrap();
    let at = |name: &str| {
        let m = scaled.markers.iter().find(|m| m.name == name).unwrap();
        d2.point_position(m.body, &m.location_in_body)
    };
    let clip_thigh = median(
        (0..clip.n_frames())
            .map(|f| (clip.frame(f)[2] - clip.frame(f)[5]).norm())
            .collect(),
    );
    let model_thigh = (at("right_hip") - at("right_knee")).norm();
    println!("right thigh: clip {clip_thigh:.5} m, scaled model {model_thigh:.5} m");
    assert!((model_thigh - clip_thigh).abs() < 2e-3 * clip_thigh);
    // Masses are kept.
    assert!((scaled.total_mass() - model.total_mass()).abs() < 1e-9);
}

#[test]
fn scale_from_clip_writes_the_model_that_ik_scale_auto_uses() {
    let Some(path) = reference_file(CLIP) else {
        return;
    };
    let dir = ScratchDir::new("scale-from-clip");
    let osim = dir.join("subject.osim");
    let (ok, _, err) = musculo_cli("scale --from-clip {} -o {}", &[&path, &osim]);
    assert!(ok, "{err}");
    let (a, b) = (dir.join("auto.mot"), dir.join("file.mot"));
    let (ok, _, err) = musculo_cli("ik --input {} --scale auto -o {}", &[&path, &a]);
    assert!(ok, "{err}");
    let (ok, _, err) = musculo_cli("ik --model {} --input {} -o {}", &[&osim, &path, &b]);
    assert!(ok, "{err}");
    let (ta, tb) = (Table::read(&a).unwrap(), Table::read(&b).unwrap());
    assert_eq!(ta.labels, tb.labels);
    let worst = ta
        .values
        .iter()
        .zip(&tb.values)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    println!("ik --scale auto vs ik --model <scale --from-clip>: max difference {worst:.2e}");
    // The file holds the numbers in shortest round-trip form: the same model.
    assert!(worst < 1e-6, "{worst}");
}

/// The augmentation chain's scaling (`scale_to_clip_shared`): factors rounded to the grid,
/// and a clip whose rounded factors an earlier clip had takes that clip's scaled model —
/// with exactly the result it gets from an empty cache. The two forms of HumanML3D 012314
/// (joints, and joints recovered from the 263 features) stand for two clips of one skeleton:
/// HumanML3D retargets every clip onto one, so their factors differ by float32 rounding only.
#[test]
fn clips_of_one_skeleton_share_a_scaled_model_and_get_what_they_would_alone() {
    use musculo::solve::scale_from_clip::{SHARED_FACTOR_GRID, ScaledModels, scale_to_clip_shared};
    let (Some(joints), Some(vecs)) = (
        reference_file(CLIP),
        reference_file("humanml3d/new_joint_vecs_012314.npy"),
    ) else {
        return;
    };
    let read = |p| motion::read(p, None, &ReadOptions::default()).unwrap();
    let (joints, vecs) = (read(&joints), read(&vecs));
    let model = Model::default_fullbody();
    let map = SkeletonMap::builtin("humanml3d").unwrap();
    let xml = musculo::DEFAULT_MODEL_OSIM;
    let scale = |clip: &motion::Motion, shared: &ScaledModels| {
        scale_to_clip_shared(xml, "default", &model, &map, clip, shared).unwrap()
    };
    let shared = ScaledModels::new();
    let first = scale(&joints, &shared);
    let second = scale(&vecs, &shared);
    assert_eq!(
        shared.len(),
        1,
        "the two forms should share one scaled model"
    );
    let alone = scale(&vecs, &ScaledModels::new());
    assert_eq!(second.xml().unwrap(), alone.xml().unwrap());
    assert_eq!(second.factors, alone.factors);
    assert_eq!(first.factors, second.factors);
    // the rounded factors: on the grid, within half a step of the unrounded ones
    let exact = scale_to_clip(xml, "default", &model, &map, &joints).unwrap();
    for ((name, rounded), (_, s)) in first.factors.iter().zip(&exact.factors) {
        let steps = rounded / SHARED_FACTOR_GRID;
        assert!((steps - steps.round()).abs() < 1e-6, "{name}: {rounded}");
        assert!(
            (rounded - s).abs() <= 0.5 * SHARED_FACTOR_GRID + 1e-12,
            "{name}: {rounded} vs {s}"
        );
    }
    // another skeleton (the clip 3 % and 6 % larger) is another entry; the oldest goes
    // once CAPACITY are held
    let mut grown = joints.clone();
    for k in 1..=ScaledModels::CAPACITY {
        grown.positions = joints
            .positions
            .iter()
            .map(|p| p * (1.0 + 0.03 * k as f64))
            .collect();
        let s = scale(&grown, &shared);
        assert!((s.factors[0].1 / first.factors[0].1 - (1.0 + 0.03 * k as f64)).abs() < 2e-4);
        assert_eq!(shared.len(), (k + 1).min(ScaledModels::CAPACITY));
    }
}

/// A skeleton map's `scale` multiplies positions after the reader checked the body's height
/// in its own unit: a scale that leaves no person is refused where it acts — `"scale": 100`
/// on HumanML3D's metres (a 150 m body, fitted with 50 m of error under exit status 0) when
/// the map is applied, `1e300` when the segments are measured (it reached the XML scaling
/// and was blamed on the model's inertias).
#[test]
fn a_map_scale_that_leaves_no_person_is_refused() {
    let Some(path) = reference_file(CLIP) else {
        return;
    };
    let clip = motion::read(&path, None, &ReadOptions::default()).unwrap();
    let model = Model::default_fullbody();
    let mut map = SkeletonMap::builtin("humanml3d").unwrap();
    assert!(map.apply(&model, &clip).is_ok());
    map.scale = 100.0;
    let e = map.apply(&model, &clip).unwrap_err().to_string();
    assert!(
        e.contains("scale 100") && e.contains("not a person's"),
        "{e}"
    );
    map.scale = 1e300;
    let e = musculo::solve::scale_from_clip::segment_factors(&model, &map, &clip)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("outside 0.01 to 100") && e.contains("segment"),
        "{e}"
    );
    // a scale that keeps a person is accepted (centimetres read as metres, undone)
    let cm: Vec<_> = clip.positions.iter().map(|p| p * 100.0).collect();
    let clip_cm = motion::Motion {
        positions: cm,
        ..clip.clone()
    };
    map.scale = 0.01;
    assert!(map.apply(&model, &clip_cm).is_ok());
}
