//! Calibration segments at a clip's ends (`motion::calibration`): CMU's T-pose frame is found
//! and left out, a held pose at either end at any frame rate is found, clips without one lose
//! no frame, and leaving the T-pose out removes the unexplained force it caused.

mod common;

use common::{reference_file, run_musculo};
use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::perturb::Variant;
use musculo::motion::calibration::{self, CalibrationCheck};
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, LengthUnit, Motion, ReadOptions};
use std::path::{Path, PathBuf};

const CMU: [&str; 3] = ["bvh/131_01.bvh", "bvh/131_03.bvh", "bvh/cmu_01_01.bvh"];

fn read(path: &Path, unit: Option<LengthUnit>) -> Motion {
    motion::read(path, None, &ReadOptions { length_unit: unit }).unwrap()
}

fn cmu(path: &Path) -> Motion {
    read(path, Some(LengthUnit::Custom(0.056444)))
}

/// The segments found, as (first frame, one past the last).
fn segments(check: &CalibrationCheck) -> Vec<(usize, usize)> {
    [&check.leading, &check.trailing]
        .into_iter()
        .flatten()
        .map(|s| (s.frames.start, s.frames.end))
        .collect()
}

/// The frames of a BVH file in the skeleton's rest pose — more than half of the joint
/// rotation channels (all but the root's six) exactly 0 — read from the file's text: CMU's
/// calibration T-pose is the rest pose the hierarchy's offsets describe.
fn rest_pose_frames(path: &Path) -> Vec<usize> {
    let text = std::fs::read_to_string(path).unwrap();
    let motion = text.split("Frame Time:").nth(1).unwrap();
    motion
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .filter(|(_, line)| {
            let values: Vec<f64> = line
                .split_whitespace()
                .skip(6)
                .map(|v| v.parse().unwrap())
                .collect();
            2 * values.iter().filter(|v| **v == 0.0).count() > values.len()
        })
        .map(|(f, _)| f)
        .collect()
}

#[test]
fn the_cmu_tpose_frames_and_only_those_are_found() {
    for rel in CMU {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let clip = cmu(&path);
        let check = calibration::detect(&clip);
        let expected: Vec<(usize, usize)> = match rest_pose_frames(&path)[..] {
            [] => vec![],
            [f] => vec![(f, f + 1)],
            ref many => panic!("{rel}: rest pose in frames {many:?}"),
        };
        println!("{rel}: rest-pose frames {expected:?}, found {check:?}");
        assert_eq!(segments(&check), expected, "{rel}");
    }
}

/// A clip made of `tpose` held for `lead` frames, the motion, and `tpose` held for `trail`
/// frames, at the motion's rate.
fn with_held_pose(
    motion: &Motion,
    tpose: &[musculo::spatial::Vec3],
    lead: usize,
    trail: usize,
) -> Motion {
    let mut positions = Vec::new();
    for _ in 0..lead {
        positions.extend_from_slice(tpose);
    }
    positions.extend_from_slice(&motion.positions);
    for _ in 0..trail {
        positions.extend_from_slice(tpose);
    }
    Motion::uniform("held", motion.names.clone(), motion.rate_hz, positions).unwrap()
}

#[test]
fn a_held_pose_at_either_end_is_found_at_mocap_and_humanml3d_rates() {
    let Some(path) = reference_file("bvh/cmu_01_01.bvh") else {
        return;
    };
    let clip = cmu(&path);
    let tpose = clip.frame(0).to_vec();
    let walk = clip
        .time_window(clip.time[1], clip.time[clip.n_frames() - 1])
        .unwrap();
    let frames = walk.n_frames();
    // half a second of T-pose before, a quarter after, at 120 fps
    let held = with_held_pose(&walk, &tpose, 60, 30);
    let check = calibration::detect(&held);
    assert_eq!(segments(&check), [(0, 60), (60 + frames, 90 + frames)]);
    assert_eq!(check.keep, 60..60 + frames);
    // the same clip at HumanML3D's 20 fps (every sixth frame): the jump is 6 frames' worth
    let mut slow = walk.clone();
    let keep: Vec<usize> = (0..frames).step_by(6).collect();
    slow.positions = keep.iter().flat_map(|&f| walk.frame(f).to_vec()).collect();
    let slow = Motion::uniform("slow", walk.names.clone(), 20.0, slow.positions).unwrap();
    let held = with_held_pose(&slow, &tpose, 1, 2);
    let check = calibration::detect(&held);
    assert_eq!(segments(&check), [(0, 1), (1 + keep.len(), 3 + keep.len())]);
    // without the held pose: nothing
    assert_eq!(calibration::detect(&walk).keep, 0..frames);
    assert_eq!(calibration::detect(&slow).keep, 0..keep.len());
}

/// The clips at hand that start and end in motion or in a continuous stand (HumanML3D, the
/// OpenSim TRC trials, the C3D walks, CMU 131_01/03): no frame is taken for calibration.
#[test]
fn clips_without_a_calibration_segment_lose_no_frame() {
    let files: [(&str, Option<LengthUnit>); 12] = [
        ("humanml3d/new_joints_012314.npy", None),
        ("humanml3d/new_joint_vecs_012314.npy", None),
        ("c3d/walking2.c3d", None),
        ("c3d/walking5.c3d", None),
        (
            "opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1.trc",
            None,
        ),
        (
            "opensim-models/Pipelines/Gait2392_Simbody/subject01_static.trc",
            None,
        ),
        (
            "opensim-models/Pipelines/Gait10dof18musc/ExperimentalData/subject01_walk.trc",
            None,
        ),
        (
            "opensim-models/Pipelines/Rajagopal/ExpData/motion_capture_run.trc",
            None,
        ),
        (
            "opensim-models/Pipelines/Rajagopal/ExpData/static_run.trc",
            None,
        ),
        (
            "opensim-models/Tutorials/Computed_Muscle_Control/InverseKinematics/arm26_elbow_flex.trc",
            None,
        ),
        (CMU[0], Some(LengthUnit::Custom(0.056444))),
        (CMU[1], Some(LengthUnit::Custom(0.056444))),
    ];
    for (rel, unit) in files {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let clip = read(&path, unit);
        let check = calibration::detect(&clip);
        assert_eq!(check.keep, 0..clip.n_frames(), "{rel}: {check:?}");
    }
    // and through `musculo augment`: the frames written are those kept with
    // --keep-calibration-frames, and no warning speaks of calibration
    let gait = "opensim-models/Pipelines/Gait2392_Simbody";
    let runs: [(&str, Vec<String>); 3] = [
        ("humanml3d/new_joints_012314.npy", vec![]),
        (
            "c3d/walking2.c3d",
            vec!["--map".into(), "c3d_lower_body".into()],
        ),
        (
            &format!("{gait}/subject01_walk1.trc"),
            vec![
                "--no-scale".into(),
                "--model".into(),
                reference_path(&format!("{gait}/OutputReference/subject01_simbody.osim")),
                "--external-loads".into(),
                reference_path(&format!("{gait}/subject01_walk1_grf.xml")),
            ],
        ),
    ];
    for (rel, extra) in runs {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let frames = |keep: bool| {
            let out = temp_dir(&format!("keep-{keep}"));
            let mut args: Vec<String> = vec![
                "augment".into(),
                "--input".into(),
                path.display().to_string(),
                "--out".into(),
                out.display().to_string(),
            ];
            args.extend(extra.iter().cloned());
            if keep {
                args.push("--keep-calibration-frames".into());
            }
            let (ok, _, stderr) = run_musculo(&args);
            assert!(ok, "{rel}: {stderr}");
            let clip = manifest_clip(&out);
            let _ = std::fs::remove_dir_all(&out);
            (
                clip["quality"]["frames"].as_u64().unwrap(),
                clip["warnings"].to_string(),
            )
        };
        let (kept, warnings) = frames(false);
        let (all, _) = frames(true);
        println!("{rel}: {kept} frames written, {all} with --keep-calibration-frames");
        assert_eq!(kept, all, "{rel}");
        assert!(!warnings.contains("calibration"), "{rel}: {warnings}");
    }
}

fn reference_path(rel: &str) -> String {
    musculo::reference::directory()
        .join(rel)
        .display()
        .to_string()
}

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("musculo-calibration-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn manifest_clip(out: &Path) -> serde_json::Value {
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    manifest["clips"][0].clone()
}

/// Largest unexplained force (× body weight; any one component, as the manifest's
/// `residual_force_max_bw`) over the frames of `residual` (T × 6, the pelvis rows: three
/// moments, then the three forces) with time in `[t0, t1]`.
fn residual_bw(out: &musculo::augment::chain::ClipOutput, t0: f64, t1: f64) -> f64 {
    let get = |name: &str| out.arrays.iter().find(|a| a.name == name).unwrap();
    let (residual, time) = (get("residual"), get("time"));
    let weight = out.quality.body_mass * 9.80665;
    time.values
        .iter()
        .enumerate()
        .filter(|(_, t)| (t0..=t1).contains(&(**t as f64)))
        .map(|(f, _)| {
            let r = &residual.values[f * 6 + 3..f * 6 + 6];
            r.iter().map(|v| (*v as f64).abs()).fold(0.0, f64::max) / weight
        })
        .fold(0.0, f64::max)
}

/// CMU cmu_01_01 starts with its T-pose frame: kept, the 38 m/s jump into the walk is an
/// unexplained force of several body weights over the first frames; left out (the default),
/// the warning names frame 0, the clip keeps its times (starting at 1/120 s), and the first
/// half second carries under 0.3 BW. Each figure is printed with the clip's peak.
#[test]
fn leaving_the_tpose_out_removes_its_unexplained_force() {
    let Some(path) = reference_file("bvh/cmu_01_01.bvh") else {
        return;
    };
    let clip = cmu(&path);
    let map = SkeletonMap::builtin(Format::Bvh.default_map().unwrap()).unwrap();
    let run = |keep: bool| {
        Chain::default_model(ChainOptions {
            keep_calibration_frames: keep,
            ..ChainOptions::default()
        })
        .unwrap()
        .run(&clip, Some(&map), &Variant::identity())
        .unwrap()
    };
    let (trimmed, kept) = (run(false), run(true));
    let start = |out| residual_bw(out, 0.0, 0.5);
    for (what, out) in [("trimmed", &trimmed), ("kept", &kept)] {
        println!(
            "cmu_01_01, T-pose {what}: {} frames, unexplained force ≤ {:.3} BW in the first \
             0.5 s, ≤ {:.3} BW over the clip, reserves {:.2} %",
            out.quality.frames,
            start(out),
            out.quality.residual_force_max_bw,
            100.0 * out.quality.reserve_share
        );
    }
    assert_eq!(trimmed.quality.frames, clip.n_frames() - 1);
    assert_eq!(kept.quality.frames, clip.n_frames());
    let time = &trimmed
        .arrays
        .iter()
        .find(|a| a.name == "time")
        .unwrap()
        .values;
    assert!((time[0] as f64 - 1.0 / 120.0).abs() < 1e-6, "{}", time[0]);
    let warning = trimmed
        .warnings
        .iter()
        .find(|w| w.contains("calibration"))
        .expect("a warning about the calibration frame");
    assert!(warning.contains("frame 0 (t = 0.000 s)"), "{warning}");
    assert!(!kept.warnings.iter().any(|w| w.contains("calibration")));
    assert!(start(&trimmed) <= 0.3, "{}", start(&trimmed));
    assert!(start(&kept) > 1.0, "{}", start(&kept));
}
