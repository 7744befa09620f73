//! Bad input to inverse kinematics, through the library and `musculo ik`: each case is a
//! clear error naming the file and the frame/joint (or a per-frame report), never a panic.
//!
//! - NaN frames in HumanML3D arrays; arrays of neither dataset's shape;
//! - missing markers (gaps) in a TRC file and in joint centres: left out of those frames'
//!   sums and reported;
//! - a skeleton that does not match the map;
//! - wrong length units (a clip in cm read as m, a CMU BVH read as metres);
//! - malformed skeleton maps, out-of-range IK settings and tasks;
//! - OpenSim IK setups naming markers the model lacks.

mod common;

use common::{
    ScratchDir, expect_invalid_argument, expect_motion_error, musculo_cli, reference_file,
};
use musculo::io::Table;
use musculo::io::ik_setup::IkSetup;
use musculo::io::trc::Trc;
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, LengthUnit, Motion, ReadOptions, npy};
use musculo::solve::ik::{self, Bounds, CoordinateTask, IkSettings, IkTasks, MarkerTask};
use musculo::solve::{ik_tool, scale_from_clip};
use musculo::spatial::Vec3;
use musculo::{DEFAULT_MODEL_OSIM, Error, Model};
use ndarray::{ArrayD, Axis, Slice};
use serde_json::json;
use std::path::{Path, PathBuf};

const HML_JOINTS: &str = "humanml3d/new_joints_012314.npy";
const BVH: &str = "bvh/131_01.bvh";
const GAIT: &str = "opensim-models/Pipelines/Gait2392_Simbody";
const NAN: Vec3 = Vec3::new(f64::NAN, f64::NAN, f64::NAN);

fn read(path: &Path) -> musculo::Result<Motion> {
    motion::read(path, None, &ReadOptions::default())
}

/// A reference `.npy` file as f32.
fn array(path: &Path) -> ArrayD<f32> {
    npy::read_array::<f32>(path).unwrap()
}

/// `array` written to `dir/name`.
fn write(dir: &ScratchDir, name: &str, array: ndarray::ArrayViewD<'_, f32>) -> PathBuf {
    let path = dir.join(name);
    npy::write_npy(&path, array).unwrap();
    path
}

fn path_text(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn a_nan_frame_in_a_humanml3d_clip_is_an_error_naming_the_frame_and_joint() {
    let Some(src) = reference_file(HML_JOINTS) else {
        return;
    };
    let dir = ScratchDir::new("ik-bad-nan");
    let mut a = array(&src);
    a[[37, 4, 1]] = f32::NAN; // frame 37, joint 4 = left_knee
    let one = write(&dir, "one_nan.npy", a.view());
    let (file, location, message) = expect_motion_error(read(&one).unwrap_err());
    assert_eq!(
        (file, location.as_str()),
        (path_text(&one), "frame 37, joint \"left_knee\"")
    );
    assert!(message.contains("not finite"), "{message}");

    // A whole frame of NaN: the first joint of that frame is named.
    let mut a = array(&src);
    a.index_axis_mut(Axis(0), 120).fill(f32::NAN);
    let (_, location, _) =
        expect_motion_error(read(&write(&dir, "frame.npy", a.view())).unwrap_err());
    assert_eq!(location, "frame 120, joint \"pelvis\"");

    // The feature form: the frame and the feature's meaning.
    if let Some(vecs) = reference_file("humanml3d/new_joint_vecs_012314.npy") {
        let mut v = array(&vecs);
        v[[50, 70]] = f32::NAN;
        let path = write(&dir, "vecs_nan.npy", v.view());
        let (file, location, _) = expect_motion_error(read(&path).unwrap_err());
        assert_eq!(file, path_text(&path));
        assert!(
            location.starts_with("frame 50, feature 70 (joint \""),
            "{location}"
        );
    }

    let out = dir.join("out.mot");
    let (ok, _, err) = musculo_cli("ik --input {} --scale auto -o {}", &[&one, &out]);
    assert!(!ok && !out.exists() && !err.contains("panicked"), "{err}");
    assert!(err.contains(&path_text(&one)), "{err}");
    assert!(err.contains("frame 37, joint \"left_knee\""), "{err}");
}

/// The Gait2392 walk's first 60 frames with `R.Shank.Front` blanked in frames 10–19 and
/// every marker blanked in frame 30, written as a TRC file and read back.
fn walk_with_gaps(dir: &ScratchDir) -> Option<(PathBuf, Motion)> {
    let trc = Trc::read(&reference_file(&format!("{GAIT}/subject01_walk1.trc"))?).unwrap();
    let nm = trc.n_markers();
    let blank = trc.marker_index("R.Shank.Front").unwrap();
    let mut positions = trc.positions[..60 * nm].to_vec();
    for f in 10..20 {
        positions[f * nm + blank] = NAN;
    }
    positions[30 * nm..31 * nm].fill(NAN);
    let time = trc.time[..60].to_vec();
    let gaps = Trc::new(trc.markers.clone(), time, positions, trc.data_rate).unwrap();
    let listed = gaps.missing();
    assert_eq!(listed.len(), nm, "every marker is missing in frame 30");
    assert_eq!(listed[blank].gaps, vec![[10, 19], [30, 30]]);
    let path = dir.join("walk_gaps.trc");
    gaps.write(&path).unwrap();
    let motion = read(&path).unwrap();
    Some((path, motion))
}

fn gait_model() -> Option<(PathBuf, Model)> {
    let p = reference_file(&format!("{GAIT}/OutputReference/subject01_simbody.osim"))?;
    let m = Model::from_osim_file(&p).unwrap();
    Some((p, m))
}

/// OpenSim's IK rules: only clamped coordinates bounded, marker weights normalised.
fn opensim_settings() -> IkSettings {
    IkSettings {
        bounds: Bounds::Clamped,
        normalize_marker_weights: true,
        ..IkSettings::default()
    }
}

#[test]
fn missing_markers_drop_out_of_their_frames_and_are_reported() {
    let dir = ScratchDir::new("ik-bad-gaps");
    let (Some((model_path, model)), Some((path, markers))) = (gait_model(), walk_with_gaps(&dir))
    else {
        return;
    };
    let blank = markers.index("R.Shank.Front").unwrap();
    for (i, m) in markers.missing_counts().iter().enumerate() {
        assert_eq!(*m, if i == blank { 11 } else { 1 }, "{}", markers.names[i]);
    }
    let tasks = ik::tasks_by_name(&model, &markers);
    let nm = tasks.markers.len();
    assert!(nm >= 30, "{nm} markers matched by name");
    let k_blank = tasks
        .markers
        .iter()
        .position(|t| t.target == blank)
        .unwrap();
    let sol = ik::solve_motion(&model, &markers, &tasks, &opensim_settings(), &|_| {}).unwrap();
    for f in 0..60 {
        for k in 0..nm {
            let gap = f == 30 || (k == k_blank && (10..20).contains(&f));
            let e = sol.marker_error[f * nm + k];
            assert_eq!(e.is_nan(), gap, "frame {f}, marker task {k}: error {e}");
        }
        let (rmse, max) = (sol.rmse[f], sol.max_error[f]);
        match f {
            30 => assert!(rmse.is_nan() && max.is_nan(), "no marker, no RMSE"),
            _ => assert!(rmse.is_finite() && rmse < 0.05, "frame {f}: {rmse}"),
        }
    }
    let counts = ik_tool::missing_marker_frames(&sol, &tasks);
    for (k, c) in counts.iter().enumerate() {
        assert_eq!(*c, if k == k_blank { 11 } else { 1 }, "marker task {k}");
    }
    // Frames 10–19 solved without R.Shank.Front stay close to the solve with it.
    let full = Trc::read(&reference_file(&format!("{GAIT}/subject01_walk1.trc")).unwrap());
    let full = Motion::from_trc(&full.unwrap(), "full").unwrap();
    let full = full.time_window(0.0, markers.time[59]).unwrap();
    let with = ik::solve_motion(&model, &full, &tasks, &opensim_settings(), &|_| {}).unwrap();
    let names = model.q_names();
    let mut worst = (0.0f64, "");
    for f in 10..20 {
        for (j, (a, b)) in sol.frame(f).iter().zip(with.frame(f)).enumerate() {
            if (a - b).abs() > worst.0 {
                worst = ((a - b).abs(), names[j]);
            }
        }
    }
    let (degrees, rmse31) = (worst.0.to_degrees(), sol.rmse[31] * 1e3);
    println!(
        "gaps: R.Shank.Front left out in frames 10–19 moves a coordinate by ≤ {degrees:.3}° \
         ({}); frame 31 (after the empty frame) RMSE {rmse31:.2} mm",
        worst.1
    );
    assert!(degrees < 2.0, "{worst:?}");
    // The per-marker table writes 0 where a marker is missing.
    let by_marker = ik_tool::marker_errors_by_marker(&model, &sol, &tasks).unwrap();
    assert_eq!(by_marker.value(15, k_blank), Some(0.0));

    // `musculo ik` on the file: solved, with the gaps reported per marker.
    let out = dir.join("gaps.mot");
    let (ok, _, err) = musculo_cli(
        "ik --model {} --input {} -o {}",
        &[&model_path, &path, &out],
    );
    assert!(ok, "{err}");
    assert!(err.contains("markers missing in some frames"), "{err}");
    assert!(err.contains("R.Shank.Front (11)"), "{err}");
    assert_eq!(Table::read(&out).unwrap().n_rows(), 60);
}

#[test]
fn a_frame_with_every_marker_missing_keeps_the_previous_pose() {
    let dir = ScratchDir::new("ik-bad-empty-frame");
    let (Some((_, model)), Some((_, markers))) = (gait_model(), walk_with_gaps(&dir)) else {
        return;
    };
    let tasks = ik::tasks_by_name(&model, &markers);
    let sol = ik::solve_motion(&model, &markers, &tasks, &opensim_settings(), &|_| {}).unwrap();
    assert_eq!(
        sol.frame(30),
        sol.frame(29),
        "frame 30 does not keep frame 29's pose"
    );
}

/// A frame without any marker keeps the previous pose, but a file in which no frame has any
/// of the model's markers has nothing to fit: `musculo ik` fails naming the file (rather
/// than writing the default pose with a marker RMSE of NaN), and so does the library.
#[test]
fn a_trc_file_with_every_marker_missing_in_every_frame_is_an_error_naming_it() {
    let dir = ScratchDir::new("ik-bad-all-blank");
    let tutorial = "opensim-models/Tutorials/Computed_Muscle_Control/InverseKinematics";
    let (Some(model_path), Some(trc_path)) = (
        reference_file(&format!("{tutorial}/arm26.osim")),
        reference_file(&format!("{tutorial}/arm26_elbow_flex.trc")),
    ) else {
        return;
    };
    let trc = Trc::read(&trc_path).unwrap();
    let blank = Trc::new(
        trc.markers.clone(),
        trc.time.clone(),
        vec![NAN; trc.positions.len()],
        trc.data_rate,
    )
    .unwrap();
    let path = dir.join("all_blank.trc");
    blank.write(&path).unwrap();
    let out = dir.join("all_blank.mot");
    let (ok, _, err) = musculo_cli(
        "ik --model {} --input {} -o {}",
        &[&model_path, &path, &out],
    );
    assert!(!ok, "musculo ik solved a file without markers: {err}");
    assert!(
        err.contains("no frame of") && err.contains("all_blank.trc") && err.contains("r_acromion"),
        "{err}"
    );
    assert!(!out.exists(), "wrote {}", out.display());
    let model = Model::from_osim_file(&model_path).unwrap();
    let markers = read(&path).unwrap();
    let tasks = ik::tasks_by_name(&model, &markers);
    let e = ik::solve_motion(&model, &markers, &tasks, &IkSettings::default(), &|_| {})
        .expect_err("solved a clip without markers")
        .to_string();
    assert!(e.contains("no frame of"), "{e}");
}

/// A TRC of arm26's three markers in mm, 3 frames (lines 6 to 8), with `value` for
/// r_acromion's X at the last frame.
fn arm_trc(value: &str) -> String {
    let mut s = "PathFileType\t4\t(X/Y/Z)\tarm.trc\n\
                 DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t\
                 OrigDataStartFrame\tOrigNumFrames\n120\t120\t3\t3\tmm\t120\t1\t3\n\
                 Frame#\tTime\tr_acromion\t\t\tr_humerus_epicondyle\t\t\tr_radius_styloid\n\
                 \t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\n"
        .to_string();
    for f in 0..3 {
        let x = if f == 2 { value } else { "-13.05" };
        s.push_str(&format!(
            "{}\t{}\t{x}\t839.5\t169.5\t-12.56\t502.59\t199.99\t-13.12\t266.43\t251.42\n",
            f + 1,
            f as f64 / 120.0
        ));
    }
    s
}

/// A marker coordinate beyond ±1e6 m (after the file's unit) is a typing or unit error,
/// refused at its line and column when the TRC is read; before, 1e300 reached IK and the
/// error named IK's output column `total_squared_error`. A NaN or infinite `--time-range`
/// is refused with the flag (NaN was reported as "no frame lies in [NaN, 1]").
#[test]
fn a_marker_beyond_1e6_m_and_a_non_finite_time_range_are_refused_where_they_are_given() {
    for value in ["1e300", "-2e9"] {
        let e = Trc::parse(&arm_trc(value), "arm.trc")
            .expect_err(value)
            .to_string();
        assert!(
            e.contains("arm.trc:8")
                && e.contains("r_acromion")
                && e.contains("X1")
                && e.contains(&format!("`{value}` mm"))
                && e.contains("beyond ±1e6 m"),
            "{e}"
        );
    }
    // 900 km in mm is still read
    Trc::parse(&arm_trc("9e8"), "arm.trc").unwrap();
    let dir = ScratchDir::new("ik-bad-huge-marker");
    let path = dir.join("arm.trc");
    std::fs::write(&path, arm_trc("1e300")).unwrap();
    let out = dir.join("arm.mot");
    if let Some(model) = reference_file("opensim-models/Models/Arm26/arm26.osim") {
        let (ok, _, err) = musculo_cli("ik --model {} --input {} -o {}", &[&model, &path, &out]);
        assert!(!ok, "musculo ik solved a marker at 1e300 mm");
        assert!(
            err.contains("arm.trc:8") && err.contains("beyond ±1e6 m"),
            "{err}"
        );
        assert!(!out.exists(), "wrote {}", out.display());
    }
    for range in ["NaN 1", "0 inf", "0 NaN"] {
        let command = format!("ik --model {{}} --input {{}} -o {{}} --time-range {range}");
        let (ok, _, err) = musculo_cli(&command, &[&path, &path, &out]);
        assert!(!ok, "{command} was accepted");
        assert!(
            err.contains("--time-range") && err.contains("give a finite time in seconds"),
            "{command}: {err}"
        );
    }
}

#[test]
fn gaps_in_joint_centres_are_left_out_and_a_joint_missing_everywhere_is_an_error() {
    let Some(hml) = reference_file(HML_JOINTS) else {
        return;
    };
    let model = Model::default_fullbody();
    let map = SkeletonMap::builtin("humanml3d").unwrap();
    let mut clip = read(&hml).unwrap();
    let knee = clip.index("left_knee").unwrap();
    for f in 60..70 {
        clip.positions[f * 22 + knee] = NAN;
    }
    let scale = |clip: &Motion| {
        scale_from_clip::scale_to_clip(DEFAULT_MODEL_OSIM, "default", &model, &map, clip)
    };
    let scaled = scale(&clip).unwrap().model;
    let (targets, tasks) = map.apply(&scaled, &clip).unwrap();
    let sol = ik::solve_motion(&scaled, &targets, &tasks, &IkSettings::default(), &|_| {});
    let sol = sol.unwrap();
    let k = tasks
        .markers
        .iter()
        .position(|t| targets.names[t.target] == "left_knee");
    let counts = ik_tool::missing_marker_frames(&sol, &tasks);
    assert_eq!((counts.iter().sum::<usize>(), counts[k.unwrap()]), (10, 10));
    assert!(sol.rmse.iter().all(|r| r.is_finite()));

    // The knee missing in every frame: scaling cannot measure the thigh.
    for f in 0..clip.n_frames() {
        clip.positions[f * 22 + knee] = NAN;
    }
    let (file, location, message) = expect_motion_error(scale(&clip).unwrap_err());
    assert_eq!(file, path_text(&hml));
    assert!(location.contains("thigh"), "{location}");
    assert!(message.contains("missing in every frame"), "{message}");
}

#[test]
fn a_skeleton_that_does_not_match_the_map_lists_the_missing_joints() {
    let (Some(hml), Some(bvh_path)) = (reference_file(HML_JOINTS), reference_file(BVH)) else {
        return;
    };
    let model = Model::default_fullbody();
    let map = SkeletonMap::builtin("humanml3d").unwrap();
    let cmu = ReadOptions {
        length_unit: Some(LengthUnit::Custom(0.056444)),
    };
    let bvh = motion::read(&bvh_path, Some(Format::Bvh), &cmu).unwrap();
    let (file, location, message) = expect_motion_error(map.apply(&model, &bvh).unwrap_err());
    assert_eq!(
        (file.as_str(), location.as_str()),
        (bvh.source.as_str(), "skeleton")
    );
    for joint in ["pelvis", "left_hip", "right_wrist", "head"] {
        assert!(message.contains(joint), "{message}");
    }
    // Scaling to that clip (`--scale auto`) fails before the map is applied, naming only the
    // first joint a segment needs (not the whole list).
    let e = scale_from_clip::scale_to_clip(DEFAULT_MODEL_OSIM, "default", &model, &map, &bvh);
    let (file, location, message) = expect_motion_error(e.unwrap_err());
    println!("--scale auto with the humanml3d map on a BVH: {file}: {location}: {message}");
    assert_eq!(
        (file.as_str(), location.as_str()),
        (bvh.source.as_str(), "skeleton")
    );
    assert!(
        message.contains("left_hip") && message.contains("humanml3d.json"),
        "{message}"
    );

    // One joint renamed: exactly that one is listed.
    let mut clip = read(&hml).unwrap();
    clip.names[4] = "knee_L".into();
    let (_, _, message) = expect_motion_error(map.apply(&model, &clip).unwrap_err());
    assert!(
        message.contains("no joint left_knee (the motion has:"),
        "{message}"
    );

    // A KIT-shaped array (T×21×3): refused as HumanML3D by its shape, and with the
    // HumanML3D map by the missing joints.
    let dir = ScratchDir::new("ik-bad-skeleton");
    let a = array(&hml);
    let kit = write(
        &dir,
        "kit_like.npy",
        a.slice_axis(Axis(1), Slice::from(0..21)),
    );
    let out = dir.join("out.mot");
    let (ok, _, err) = musculo_cli("ik --input {} --format humanml3d -o {}", &[&kit, &out]);
    assert!(
        !ok && err.contains(&path_text(&kit)) && err.contains("array shape"),
        "{err}"
    );
    assert!(
        err.contains("(170, 21, 3)") && err.contains("T×22×3"),
        "{err}"
    );
    let cli = "ik --input {} --format kit --map humanml3d -o {}";
    let (ok, _, err) = musculo_cli(cli, &[&kit, &out]);
    assert!(!ok && err.contains(&path_text(&kit)), "{err}");
    assert!(err.contains("does not match the skeleton map"), "{err}");
    assert!(
        err.contains("left_knee") && !err.contains("panicked") && !out.exists(),
        "{err}"
    );
}

/// A T×20×3 array (neither HumanML3D nor KIT-ML) read without a format: its message.
fn neither_shape(dir: &ScratchDir, hml: &Path) -> (PathBuf, String) {
    let a = array(hml);
    let path = write(dir, "twenty.npy", a.slice_axis(Axis(1), Slice::from(0..20)));
    let (file, location, message) = expect_motion_error(read(&path).unwrap_err());
    assert_eq!((file, location.as_str()), (path_text(&path), "array shape"));
    (path, message)
}

#[test]
fn an_npy_of_neither_dataset_shape_is_an_error_naming_its_shape() {
    let Some(hml) = reference_file(HML_JOINTS) else {
        return;
    };
    let dir = ScratchDir::new("ik-bad-shape");
    let (path, message) = neither_shape(&dir, &hml);
    assert!(
        message.contains("(170, 20, 3)") && message.contains("give --format"),
        "{message}"
    );
    let (ok, _, err) = musculo_cli("ik --input {} -o {}", &[&path, &dir.join("o.mot")]);
    assert!(!ok && err.contains("array shape"), "{err}");
}

/// A format the file's extension contradicts (`--format bvh` on an `.npy`) is refused by
/// name, before the reader meets the first bytes; an extension of no known format (a BVH
/// saved as `.txt`) is left to the reader, and a matching one reads.
#[test]
fn a_format_the_extension_contradicts_is_named() {
    let dir = ScratchDir::new("format-extension");
    let npy = dir.join("clip.npy");
    std::fs::write(&npy, b"\x93NUMPY whatever").unwrap();
    let e = motion::read(&npy, Some(Format::Bvh), &ReadOptions::default()).unwrap_err();
    let (file, location, message) = expect_motion_error(e);
    assert_eq!(
        (file.as_str(), location.as_str()),
        (npy.to_str().unwrap(), "file name")
    );
    assert!(
        message.contains("read as bvh (--format), but `.npy` names a NumPy array")
            && message.contains("leave --format out"),
        "{message}"
    );
    for format in [Format::C3d, Format::Trc] {
        let e = motion::read(&npy, Some(format), &ReadOptions::default()).unwrap_err();
        assert_eq!(expect_motion_error(e).1, "file name");
    }
    // `.txt`: the reader's own error (not a BVH), not the extension's
    let txt = dir.join("clip.txt");
    std::fs::write(&txt, "not a motion").unwrap();
    let e = motion::read(&txt, Some(Format::Bvh), &ReadOptions::default()).unwrap_err();
    assert_ne!(expect_motion_error(e).1, "file name");
    // `.npy` read as KIT-ML or HumanML3D passes the check (and fails on the content here)
    for format in [Format::HumanMl3d, Format::Kit] {
        let e = motion::read(&npy, Some(format), &ReadOptions::default()).unwrap_err();
        assert_ne!(expect_motion_error(e).1, "file name");
    }
}

#[test]
fn the_shape_message_has_no_run_of_spaces() {
    let Some(hml) = reference_file(HML_JOINTS) else {
        return;
    };
    let (_, message) = neither_shape(&ScratchDir::new("ik-bad-shape-spaces"), &hml);
    assert!(!message.contains("  "), "{message:?}");
}

#[test]
fn wrong_length_units_are_refused_with_the_implied_height() {
    let (Some(hml), Some(bvh)) = (reference_file(HML_JOINTS), reference_file(BVH)) else {
        return;
    };
    let dir = ScratchDir::new("ik-bad-units");
    let cm = write(&dir, "clip_in_cm.npy", (array(&hml) * 100.0).view());
    let (file, location, message) = expect_motion_error(read(&cm).unwrap_err());
    println!("HumanML3D ×100: {location}: {message}");
    assert_eq!((file, location.as_str()), (path_text(&cm), "skeleton"));
    assert!(
        message.contains("implied body height") && message.contains("centimetres (cm)"),
        "{message}"
    );
    let (ok, _, err) = musculo_cli("ik --input {} -o {}", &[&cm, &dir.join("o.mot")]);
    assert!(!ok && err.contains("implied body height"), "{err}");

    // CMU BVH (unit 1/0.45 inch) read as metres, and with the BVH default (cm).
    for unit in [LengthUnit::Metres, LengthUnit::Centimetres] {
        let options = ReadOptions {
            length_unit: Some(unit),
        };
        let e = motion::read(&bvh, Some(Format::Bvh), &options).unwrap_err();
        let (file, _, message) = expect_motion_error(e);
        println!("CMU BVH read in {unit:?}: {message}");
        assert_eq!(file, path_text(&bvh));
        assert!(message.contains("implied body height"), "{message}");
        assert!(message.contains("0.056444"), "{message}");
    }
    let cli = "ik --input {} --length-unit m -o {}";
    let (ok, _, err) = musculo_cli(cli, &[&bvh, &dir.join("o.mot")]);
    assert!(!ok && err.contains("implied body height"), "{err}");
}

#[test]
fn malformed_skeleton_maps_are_table_errors_naming_the_file() {
    let dir = ScratchDir::new("ik-bad-maps");
    let base: serde_json::Value =
        serde_json::from_str(include_str!("../data/skeletons/humanml3d.json")).unwrap();
    let cases = [
        ("axis_twice", "/axes", json!(["z", "y", "z"]), "twice"),
        ("reflection", "/axes", json!(["z", "y", "x"]), "mirror"),
        ("unknown_axis", "/axes/2", json!("-w"), "-w"),
        (
            "negative_weight",
            "/targets/3/weight",
            json!(-1.0),
            "weight -1",
        ),
        (
            "segment_marker",
            "/segments/0/pairs/0/1",
            json!("no_such"),
            "no_such",
        ),
    ];
    for (name, pointer, value, expected) in cases {
        let mut map = base.clone();
        *map.pointer_mut(pointer).unwrap() = value;
        let path = dir.join(&format!("{name}.json"));
        std::fs::write(&path, serde_json::to_string_pretty(&map).unwrap()).unwrap();
        match SkeletonMap::read(&path).unwrap_err() {
            Error::Table { table, message, .. } => {
                assert_eq!(table, path_text(&path), "{name}");
                assert!(message.contains(expected), "{name}: {message}");
            }
            other => panic!("{name}: expected Error::Table, got {other:?}"),
        }
    }
    // The same reflection is accepted when it says so, and mirrors the motion.
    let mut mirrored = base.clone();
    mirrored["axes"] = json!(["z", "y", "x"]);
    mirrored["mirror"] = true.into();
    let map = SkeletonMap::parse(&mirrored.to_string(), "mirrored.json").unwrap();
    assert!((map.axes_matrix().unwrap().determinant() + 1.0).abs() < 1e-15);
    // A map onto markers the model lacks: an error listing them.
    let mut other = base.clone();
    other["targets"][0]["marker"] = "no_such_marker".into();
    let map = SkeletonMap::parse(&other.to_string(), "other.json").unwrap();
    let names = motion::humanml3d::JOINT_NAMES.map(String::from).to_vec();
    let clip = Motion::uniform("one", names, 20.0, vec![Vec3::y(); 22]).unwrap();
    let e = map.apply(&Model::default_fullbody(), &clip).unwrap_err();
    let (argument, message) = expect_invalid_argument(e);
    assert_eq!(argument, "model");
    assert!(
        message.contains("no_such_marker") && message.contains("other.json"),
        "{message}"
    );
}

#[test]
fn a_map_edited_in_code_is_an_error_when_scaling_not_a_panic() {
    let Some(hml) = reference_file(HML_JOINTS) else {
        return;
    };
    let clip = read(&hml).unwrap();
    let model = Model::default_fullbody();
    let mut map = SkeletonMap::builtin("humanml3d").unwrap();
    map.segments[0].pairs[0][1] = "no_such_target".into();
    let e = scale_from_clip::scale_to_clip(DEFAULT_MODEL_OSIM, "default", &model, &map, &clip);
    assert!(e.is_err());
}

#[test]
fn ik_settings_and_tasks_out_of_range_are_invalid_arguments() {
    let model = Model::default_fullbody();
    let names = ["left_knee", "right_knee", "pelvis"]
        .map(String::from)
        .to_vec();
    let frame = [[0.1, 0.5, -0.1], [0.1, 0.5, 0.1], [0.0, 0.9, 0.0]].map(Vec3::from);
    let targets = Motion::uniform("three", names, 20.0, frame.repeat(4)).unwrap();
    let tasks = ik::tasks_by_name(&model, &targets);
    assert_eq!(tasks.markers.len(), 3);
    let solve = |tasks: &IkTasks, settings: &IkSettings| {
        let e = ik::solve_motion(&model, &targets, tasks, settings, &|_| {}).unwrap_err();
        expect_invalid_argument(e)
    };
    let with = |edit: &dyn Fn(&mut IkSettings)| {
        let mut s = IkSettings::default();
        edit(&mut s);
        s
    };
    let n = model.nq();
    let settings = [
        (with(&|s| s.smoothness = -1.0), "smoothness"),
        (with(&|s| s.smoothness = f64::NAN), "smoothness"),
        (with(&|s| s.max_iterations = 0), "max_iterations"),
        (with(&|s| s.tolerance = 0.0), "tolerance"),
        (with(&|s| s.relative_decrease = 0.0), "relative_decrease"),
        (with(&|s| s.relative_decrease = 1.0), "relative_decrease"),
        (
            with(&|s| s.relative_decrease = f64::NAN),
            "relative_decrease",
        ),
        (with(&|s| s.initial_q = Some(vec![0.0; n - 1])), "initial_q"),
        (
            with(&|s| s.initial_q = Some(vec![f64::NAN; n])),
            "initial_q",
        ),
    ];
    for (s, argument) in settings {
        assert_eq!(solve(&tasks, &s).0, argument, "{s:?}");
    }
    let m = |marker, target, weight| IkTasks {
        markers: vec![MarkerTask {
            marker,
            target,
            weight,
        }],
        coordinates: Vec::new(),
    };
    let c = |q, weight, value: Vec<f64>| IkTasks {
        markers: Vec::new(),
        coordinates: vec![CoordinateTask { q, weight, value }],
    };
    let bad = [
        (IkTasks::default(), "no marker or coordinate task"),
        (m(model.markers.len(), 0, 1.0), "out of range"),
        (m(0, 3, 1.0), "out of range"),
        (m(0, 0, -1.0), "weight -1"),
        (m(0, 0, f64::INFINITY), "weight inf"),
        (c(n, 1.0, vec![0.0]), "out of range"),
        (c(0, -2.0, vec![0.0]), "weight -2"),
        (c(0, 1.0, vec![0.0; 3]), "3 values for 4 frames"),
        (c(0, 1.0, vec![f64::NAN]), "not finite"),
    ];
    for (tasks, expected) in bad {
        let (argument, message) = solve(&tasks, &IkSettings::default());
        assert_eq!(argument, "tasks", "{message}");
        assert!(message.contains(expected), "{expected}: {message}");
    }
    // Targets that are infinite (not missing) are refused with the frame and target.
    let mut inf = targets.clone();
    inf.positions[2 * 3 + 1].y = f64::INFINITY;
    let e = ik::solve_motion(&model, &inf, &tasks, &IkSettings::default(), &|_| {});
    let (_, location, _) = expect_motion_error(e.unwrap_err());
    assert_eq!(location, "frame 2, target \"right_knee\"");
}

/// The Gait2392 IK setup with absolute paths and a short time range, `tasks` replacing its
/// IKTaskSet's objects (or added to them).
fn gait_setup(dir: &ScratchDir, name: &str, tasks: &str, replace: bool) -> Option<PathBuf> {
    let setup = reference_file(&format!("{GAIT}/subject01_Setup_IK.xml"))?;
    let (model, _) = gait_model()?;
    let trc = reference_file(&format!("{GAIT}/subject01_walk1.trc"))?;
    let mut text = std::fs::read_to_string(setup).unwrap();
    let mut tag = |t: &str, v: &str| {
        let (open, close) = (format!("<{t}>"), format!("</{t}>"));
        let a = text.find(&open).unwrap() + open.len();
        let b = text.find(&close).unwrap();
        text.replace_range(a..b, v);
    };
    tag("model_file", &path_text(&model));
    tag("marker_file", &path_text(&trc));
    tag("time_range", "0.5 0.6");
    tag("output_motion_file", &format!("{name}.mot"));
    if replace {
        tag("objects", tasks);
    } else {
        text = text.replacen("<objects>", &format!("<objects>{tasks}"), 1);
    }
    let path = dir.join(&format!("{name}.xml"));
    std::fs::write(&path, text).unwrap();
    Some(path)
}

const NO_SUCH: &str =
    "<IKMarkerTask name=\"NoSuchMarker\"><apply>true</apply><weight>1</weight></IKMarkerTask>";

#[test]
fn ik_setups_naming_markers_the_model_lacks_warn_or_fail() {
    let dir = ScratchDir::new("ik-bad-setup");
    let Some(path) = gait_setup(&dir, "extra", NO_SUCH, false) else {
        return;
    };
    let (_, model) = gait_model().unwrap();
    let setup = IkSetup::read(&path).unwrap();
    let markers = read(setup.marker_file.as_ref().unwrap()).unwrap();
    let markers = ik_tool::select_frames(&markers, setup.time_range).unwrap();
    let (tasks, warnings) = ik_tool::tasks_from_setup(&model, &setup, &markers, None).unwrap();
    let warning = warnings
        .iter()
        .find(|w| w.contains("NoSuchMarker"))
        .expect("a warning");
    assert!(
        warning.contains("the model has no such marker"),
        "{warning}"
    );
    assert!(warning.starts_with(&path_text(&path)), "{warning}");
    assert!(tasks.markers.len() >= 30);
    let sol = ik::solve_motion(&model, &markers, &tasks, &opensim_settings(), &|_| {}).unwrap();
    assert!(sol.rmse.iter().all(|r| r.is_finite() && *r < 0.05));

    let (ok, _, err) = musculo_cli("ik --setup {}", &[&path]);
    assert!(ok, "{err}");
    assert!(
        err.contains("warning:") && err.contains("NoSuchMarker"),
        "{err}"
    );
    let out = Table::read(&dir.join("extra.mot")).unwrap();
    assert_eq!(out.n_rows(), sol.n_frames());

    // Tasks that match no marker at all: an error naming the setup file.
    let path = gait_setup(&dir, "none", NO_SUCH, true).unwrap();
    let setup = IkSetup::read(&path).unwrap();
    let e = ik_tool::tasks_from_setup(&model, &setup, &markers, None).unwrap_err();
    let (argument, message) = expect_invalid_argument(e);
    assert_eq!(argument, "setup");
    assert!(message.contains(&path_text(&path)), "{message}");
    assert!(message.contains("no marker task"), "{message}");
    let (ok, _, err) = musculo_cli("ik --setup {}", &[&path]);
    assert!(!ok && err.contains("no marker task matches"), "{err}");
    assert!(!dir.join("none.mot").exists());
}

/// A coordinate task weighs against marker weights that OpenSim's IK normalizes to sum 1, so
/// its weight is only a pin's stiffness: the Gait2392 setup's pins (subtalar and mtp, 1000)
/// at 10¹⁵ or 10³⁰³ fit the markers as well (from 10¹⁴ on, the damping they set for every
/// coordinate stopped IK at its starting pose, 635 mm RMSE, without a word).
#[test]
fn stiff_coordinate_tasks_do_not_stall_the_fit() {
    let dir = ScratchDir::new("ik-stiff-pins");
    let Some(path) = gait_setup(&dir, "stiff", "", false) else {
        return;
    };
    let (_, model) = gait_model().unwrap();
    let setup = IkSetup::read(&path).unwrap();
    let markers = read(setup.marker_file.as_ref().unwrap()).unwrap();
    let markers = ik_tool::select_frames(&markers, setup.time_range).unwrap();
    let (tasks, _) = ik_tool::tasks_from_setup(&model, &setup, &markers, None).unwrap();
    assert!(tasks.coordinates.len() >= 4 && tasks.coordinates.iter().all(|t| t.weight == 1000.0));
    let fit = |factor: f64| {
        let mut t = tasks.clone();
        for c in &mut t.coordinates {
            c.weight *= factor;
        }
        ik::solve_motion(&model, &markers, &t, &opensim_settings(), &|_| {}).unwrap()
    };
    let base = fit(1.0);
    assert!(base.rmse.iter().all(|r| *r < 0.05), "{:?}", base.rmse);
    for factor in [1e12, 1e300] {
        let stiff = fit(factor);
        for (f, (a, b)) in base.rmse.iter().zip(&stiff.rmse).enumerate() {
            assert!(
                (a - b).abs() <= 1e-3 * a,
                "×{factor:e}, frame {f}: RMSE {b} vs {a}"
            );
        }
        let worst = base
            .q
            .iter()
            .zip(&stiff.q)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-3, "×{factor:e}: coordinates differ by {worst}");
    }
}

#[test]
fn inputs_with_the_same_stem_do_not_overwrite_each_other() {
    let Some(hml) = reference_file(HML_JOINTS) else {
        return;
    };
    let dir = ScratchDir::new("ik-bad-stems");
    for sub in ["a", "b"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let full = array(&hml);
    let a = write(&dir, "a/clip.npy", full.view());
    let b = write(
        &dir,
        "b/clip.npy",
        full.slice_axis(Axis(0), Slice::from(0..50)),
    );
    let out = dir.join("out");
    let (ok, _, err) = musculo_cli("ik --input {} {} -o {}", &[&a, &b, &out]);
    // Either a clear error, or one output per input.
    let mots = std::fs::read_dir(&out).map_or(0, |d| {
        let paths = d.map(|e| e.unwrap().path());
        paths
            .filter(|p| p.extension().is_some_and(|x| x == "mot"))
            .count()
    });
    assert!(
        if ok { mots == 2 } else { err.contains("clip") },
        "{mots} .mot files; {err}"
    );
}

/// `ik::solve_motion_from` starts every frame from a given solution: from the solution
/// itself it ends where it started, and starts that do not fit the clip (other frame count,
/// a non-finite value) are errors, not panics.
#[test]
fn per_frame_starts_are_checked_and_a_solution_is_its_own_fixed_point() {
    let model = Model::default_fullbody();
    let mut data = musculo::Data::new(&model);
    let n = model.nq();
    let names: Vec<String> = model.markers.iter().map(|m| m.name.clone()).collect();
    let mut positions = Vec::new();
    let mut q = model.default_q();
    for f in 0..6 {
        for (j, v) in q.iter_mut().enumerate() {
            *v = model.default_q()[j] + 0.02 * (f as f64) * ((j % 5) as f64 - 2.0) / 2.0;
        }
        musculo::dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        for m in &model.markers {
            positions.push(data.point_position(m.body, &m.location_in_body));
        }
    }
    let clip = Motion::uniform("synthetic", names, 20.0, positions).unwrap();
    let tasks = ik::tasks_by_name(&model, &clip);
    let settings = IkSettings::default();
    let first = ik::solve_motion(&model, &clip, &tasks, &settings, &|_| {}).unwrap();
    let again = ik::solve_motion_from(&model, &clip, &tasks, &settings, &first, &|_| {}).unwrap();
    let moved = first
        .q
        .iter()
        .zip(&again.q)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        moved < 1e-8,
        "restarting from the solution moved it by {moved}"
    );
    assert!(
        again.iterations.iter().all(|&i| i <= 2),
        "{:?}",
        again.iterations
    );
    // frame 3 started away from its solution takes more iterations there, and only there
    let mut off = first.clone();
    for v in &mut off.q[3 * n..4 * n] {
        *v += 0.05;
    }
    let moved_start =
        ik::solve_motion_from(&model, &clip, &tasks, &settings, &off, &|_| {}).unwrap();
    assert!(
        moved_start.iterations[3] > again.iterations[3],
        "{:?} vs {:?}",
        moved_start.iterations,
        again.iterations
    );
    assert_eq!(moved_start.iterations[4], again.iterations[4]);

    let short = ik::solve_motion(
        &model,
        &clip.time_window(0.0, 0.1).unwrap(),
        &tasks,
        &settings,
        &|_| {},
    )
    .unwrap();
    let e = ik::solve_motion_from(&model, &clip, &tasks, &settings, &short, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("3 frames"), "{e}");
    let mut bad = first.clone();
    bad.q[n + 2] = f64::NAN;
    let e = ik::solve_motion_from(&model, &clip, &tasks, &settings, &bad, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("non-finite"), "{e}");
}
