//! The `.npy`/`.npz`, HumanML3D and KIT-ML readers: round trips through the files, the
//! HumanML3D reference clip in both of its forms (features recovered to the stored joints),
//! hand-computed feature recovery, synthetic KIT skeletons in millimetres and metres, and
//! every kind of bad input as an error naming the file and the frame/joint or shape.

mod common;

use common::reference_file;
use musculo::Error;
use musculo::motion::{LengthUnit, humanml3d, kit, npy};
use musculo::spatial::Vec3;
use ndarray::{Array, ArrayD, IxDyn};
use std::path::{Path, PathBuf};

/// A fresh directory for one test's files, removed at the end.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("musculo-motion-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }
    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    fn entries(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn motion_message(e: &Error) -> (String, String, String) {
    match e {
        Error::Motion {
            file,
            location,
            message,
        } => (file.clone(), location.clone(), message.clone()),
        other => panic!("expected Error::Motion, got {other:?}"),
    }
}

fn ramp(shape: &[usize]) -> ArrayD<f32> {
    let n: usize = shape.iter().product();
    Array::from_shape_vec(
        IxDyn(shape),
        (0..n).map(|i| i as f32 * 0.25 - 3.0).collect(),
    )
    .unwrap()
}

// ---------------------------------------------------------------------------------------
// .npy / .npz

#[test]
fn npy_round_trip_any_rank_f32_and_f64() {
    let dir = Scratch::new("npy-round-trip");
    for shape in [&[][..], &[5], &[4, 3], &[2, 3, 4], &[2, 1, 3, 2]] {
        let a = ramp(shape);
        let path = dir.join("a.npy");
        npy::write_npy(&path, a.view()).unwrap();
        assert_eq!(npy::read_array_f32(&path).unwrap(), a, "shape {shape:?}");
        // float32 widens exactly
        assert_eq!(npy::read_array_as_f64(&path).unwrap(), a.mapv(f64::from));
        let b = a.mapv(|v| f64::from(v) / 3.0);
        npy::write_npy(&path, b.view()).unwrap();
        assert_eq!(npy::read_array_f64(&path).unwrap(), b);
        assert_eq!(npy::read_array_as_f64(&path).unwrap(), b);
    }
    // The atomic writer leaves no temporary file behind.
    assert_eq!(dir.entries(), vec!["a.npy".to_string()]);
}

#[test]
fn npy_reads_fortran_order_and_misaligned_buffers() {
    use ndarray_npy::WriteNpyExt;
    let a = ramp(&[3, 4]);
    // A transposed view is Fortran-contiguous: the crate writes it with fortran_order True.
    let t = a.t();
    assert!(!t.is_standard_layout());
    let mut bytes = Vec::new();
    t.write_npy(&mut bytes).unwrap();
    assert!(String::from_utf8_lossy(&bytes[..128]).contains("'fortran_order': True"));
    let back = npy::parse_array::<f32>(&bytes, "t.npy").unwrap();
    assert_eq!(back, t.to_owned().into_dyn());
    assert!(back.is_standard_layout());
    // The same bytes one byte off alignment still parse (through the crate's reader).
    let mut shifted = vec![0u8];
    shifted.extend_from_slice(&bytes);
    assert_eq!(
        npy::parse_array::<f32>(&shifted[1..], "t.npy").unwrap(),
        back
    );
}

#[test]
fn npz_round_trip_stored_and_compressed() {
    let dir = Scratch::new("npz");
    let q = ramp(&[10, 29]);
    let pos = ramp(&[10, 22, 3]);
    let zeros = ArrayD::<f32>::zeros(IxDyn(&[2000]));
    let arrays = [
        ("q", q.view()),
        ("joint_pos", pos.view()),
        ("zeros", zeros.view()),
    ];
    let stored = dir.join("stored.npz");
    let packed = dir.join("packed.npz");
    npy::write_npz(&stored, &arrays, false).unwrap();
    npy::write_npz(&packed, &arrays, true).unwrap();
    for path in [&stored, &packed] {
        let back = npy::read_npz_f32(path).unwrap();
        let names: Vec<&str> = back.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["q", "joint_pos", "zeros"]);
        assert_eq!(back[0].1, q);
        assert_eq!(back[1].1, pos);
        assert_eq!(back[2].1, zeros);
        let wide = npy::read_npz_as_f64(path).unwrap();
        assert_eq!(wide[1].1, pos.mapv(f64::from));
    }
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(
        size(&packed) < size(&stored),
        "{} vs {}",
        size(&packed),
        size(&stored)
    );
    // Duplicate names are refused before anything is written.
    let dup = dir.join("dup.npz");
    let e = npy::write_npz(&dup, &[("a", q.view()), ("a", q.view())], false).unwrap_err();
    assert!(matches!(e, Error::InvalidArgument { .. }), "{e}");
    assert!(!dup.exists());
    assert_eq!(
        dir.entries(),
        vec!["packed.npz".to_string(), "stored.npz".to_string()]
    );
}

#[test]
fn npy_write_replaces_atomically_and_reports_unwritable_paths() {
    let dir = Scratch::new("atomic");
    let path = dir.join("out.npy");
    npy::write_npy(&path, ramp(&[3]).view()).unwrap();
    npy::write_npy(&path, ramp(&[7, 2]).view()).unwrap();
    assert_eq!(npy::read_array_f32(&path).unwrap().shape(), &[7, 2]);
    assert_eq!(dir.entries(), vec!["out.npy".to_string()]);
    let missing = dir.join("no/such/folder/out.npz");
    let e = npy::write_npz(&missing, &[("a", ramp(&[2]).view())], true).unwrap_err();
    assert!(matches!(e, Error::Output { .. }), "{e}");
    assert!(e.to_string().contains("no/such/folder"), "{e}");
}

#[test]
fn npy_errors_name_the_file_and_the_problem() {
    let dir = Scratch::new("npy-errors");
    // Missing file: an I/O error with the path.
    let e = npy::read_array_f32(&dir.join("absent.npy")).unwrap_err();
    assert!(
        matches!(e, Error::Io { .. }) && e.to_string().contains("absent.npy"),
        "{e}"
    );
    // Not an .npy at all.
    let text = dir.join("text.npy");
    std::fs::write(&text, "pelvis,left_hip\n1,2\n").unwrap();
    let (file, _, message) = motion_message(&npy::read_array_f32(&text).unwrap_err());
    assert!(
        file.ends_with("text.npy") && message.contains("not an .npy"),
        "{message}"
    );
    // Wrong dtype: float64 read as float32 names both.
    let f64_path = dir.join("f64.npy");
    npy::write_npy(&f64_path, ramp(&[4]).mapv(f64::from).view()).unwrap();
    let (_, _, message) = motion_message(&npy::read_array_f32(&f64_path).unwrap_err());
    assert!(
        message.contains("<f8") && message.contains("float32"),
        "{message}"
    );
    // Truncated data.
    let good = dir.join("good.npy");
    npy::write_npy(&good, ramp(&[100]).view()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let (_, _, message) = motion_message(
        &npy::parse_array::<f32>(&bytes[..bytes.len() - 10], "cut.npy").unwrap_err(),
    );
    assert!(
        message.contains("truncated") && message.contains("10 bytes"),
        "{message}"
    );
    // A header claiming an enormous shape: an error, not an allocation.
    let header_end = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
    let header = std::str::from_utf8(&bytes[10..header_end]).unwrap();
    let forged = header
        .replacen("(100,)", "(99999999999,)", 1)
        .replacen("        \n", "\n", 1);
    assert_eq!(forged.len(), header.len());
    let mut forged_bytes = bytes[..10].to_vec();
    forged_bytes.extend_from_slice(forged.as_bytes());
    forged_bytes.extend_from_slice(&bytes[header_end..]);
    let (_, _, message) =
        motion_message(&npy::parse_array::<f32>(&forged_bytes, "forged.npy").unwrap_err());
    assert!(message.contains("missing"), "{message}");
    // Wrong rank, with the actual shape.
    let a = npy::read_array_f32(&good).unwrap();
    let (_, location, message) =
        motion_message(&npy::expect_rank::<f32, ndarray::Ix3>(a.view(), "good.npy").unwrap_err());
    assert_eq!(location, "array shape");
    assert!(
        message.contains("(100,)") && message.contains("rank 3"),
        "{message}"
    );
    // An .npz that is not a zip archive.
    let (_, _, message) = motion_message(&npy::read_npz_f32(&good).unwrap_err());
    assert!(message.contains("not an .npz"), "{message}");
}

#[test]
fn npy_reads_the_reference_arrays() {
    let Some(path) = reference_file("humanml3d/new_joints_012314.npy") else {
        return;
    };
    let a = npy::read_array_f32(&path).unwrap();
    assert_eq!(a.shape(), &[170, 22, 3]);
    let e = npy::read_array_f64(&path).unwrap_err();
    assert!(
        e.to_string().contains("new_joints_012314.npy") && e.to_string().contains("<f4"),
        "{e}"
    );
    let Some(mean) = reference_file("humanml3d/Mean.npy") else {
        return;
    };
    assert_eq!(npy::read_array_f32(&mean).unwrap().shape(), &[263]);
}

// ---------------------------------------------------------------------------------------
// HumanML3D

fn max_difference(a: &[Vec3], b: &[Vec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).amax())
        .fold(0.0, f64::max)
}

#[test]
fn humanml3d_both_forms_of_the_reference_clip_give_the_same_joints() {
    let (Some(joints), Some(vecs)) = (
        reference_file("humanml3d/new_joints_012314.npy"),
        reference_file("humanml3d/new_joint_vecs_012314.npy"),
    ) else {
        return;
    };
    let options = humanml3d::Options::default();
    let start = std::time::Instant::now();
    let a = humanml3d::read_joints(&joints, &options).unwrap();
    let b = humanml3d::read_features(&vecs, &options).unwrap();
    eprintln!(
        "HumanML3D 012314: both forms read (170 frames each) in {:.2} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    assert_eq!((a.n_frames(), a.n_targets(), a.rate_hz), (170, 22, 20.0));
    assert_eq!(a.names, b.names);
    assert_eq!(a.names, humanml3d::JOINT_NAMES.map(String::from));
    assert!((a.time[1] - 0.05).abs() < 1e-15 && (a.duration() - 169.0 / 20.0).abs() < 1e-12);
    let d = max_difference(&a.positions, &b.positions);
    eprintln!("HumanML3D 012314: features → joints differ from new_joints by at most {d:.3e} m");
    assert!(d <= 1e-5, "{d}");
    // `read` tells the two forms apart by shape.
    assert_eq!(humanml3d::read(&vecs, &options).unwrap(), b);
    assert_eq!(humanml3d::read(&joints, &options).unwrap(), a);
    let height = humanml3d::implied_height(a.n_targets(), &a.positions);
    eprintln!("HumanML3D 012314: implied height (median largest joint distance) {height:.3} m");
    assert!((1.2..2.0).contains(&height), "{height}");
}

#[test]
fn humanml3d_normalized_features_are_denormalized_with_mean_and_std() {
    let (Some(vecs), Some(mean), Some(std)) = (
        reference_file("humanml3d/new_joint_vecs_012314.npy"),
        reference_file("humanml3d/Mean.npy"),
        reference_file("humanml3d/Std.npy"),
    ) else {
        return;
    };
    let stats = humanml3d::Normalization::read(&mean, &std).unwrap();
    assert_eq!(stats.mean.len(), humanml3d::N_FEATURES);
    let x = npy::read_array_as_f64(&vecs).unwrap();
    let mut normalized = x.clone();
    for mut row in normalized.rows_mut() {
        for (k, v) in row.iter_mut().enumerate() {
            *v = (*v - stats.mean[k]) / stats.std[k];
        }
    }
    let plain = humanml3d::from_features(x.view(), "x", &Default::default()).unwrap();
    let options = humanml3d::Options {
        normalization: Some(stats),
        ..Default::default()
    };
    let back = humanml3d::from_features(normalized.view(), "x̂", &options).unwrap();
    assert!(max_difference(&plain.positions, &back.positions) < 1e-9);
    // Normalising joint positions makes no sense: refused.
    let joints = Array::from_shape_vec(IxDyn(&[1, 22, 3]), vec![0.0; 66]).unwrap();
    let e = humanml3d::from_joints(joints.view(), "j", &options).unwrap_err();
    assert!(matches!(e, Error::InvalidArgument { .. }), "{e}");
}

/// Recovery checked against positions worked out by hand: the half-angle ω = π/4 per frame
/// turns the heading by θ = π/2 per frame.
#[test]
fn humanml3d_recover_from_ric_matches_hand_computed_positions() {
    use std::f64::consts::FRAC_PI_4;
    let j = 3;
    let width = humanml3d::n_features(j);
    assert_eq!(width, 35);
    let mut f = ndarray::Array2::<f64>::zeros((3, width));
    // Frame 0: ω = π/4, v = (1, 0), height 0.9, joint 1 at (0.2, 0.5, 0), joint 2 at (0, 1.0, 0.3).
    // Frame 1: ω = 0, v = (0, 2), height 0.8, same local joints. Frame 2: height 0.7.
    for t in 0..3 {
        f[[t, 3]] = 0.9 - 0.1 * t as f64;
        f[[t, 4]] = 0.2;
        f[[t, 5]] = 0.5;
        f[[t, 8]] = 1.0;
        f[[t, 9]] = 0.3;
    }
    f[[0, 0]] = FRAC_PI_4;
    f[[0, 1]] = 1.0;
    f[[1, 2]] = 2.0;
    let p = humanml3d::recover_from_ric(f.view(), j);
    // t = 0: no rotation, root at the origin.
    let expect = [
        [0.0, 0.9, 0.0],
        [0.2, 0.5, 0.0],
        [0.0, 1.0, 0.3],
        // t = 1: θ = π/2; R_y(−π/2) (x, y, z) = (−z, y, x); root += R_y(−π/2)(1, 0, 0) = (0, 0, 1).
        [0.0, 0.8, 1.0],
        [0.0, 0.5, 1.2],
        [-0.3, 1.0, 1.0],
        // t = 2: θ = π/2 still; root += R_y(−π/2)(0, 0, 2) = (−2, 0, 0).
        [-2.0, 0.7, 1.0],
        [-2.0, 0.5, 1.2],
        [-2.3, 1.0, 1.0],
    ];
    for (k, (got, want)) in p.iter().zip(expect).enumerate() {
        assert!(
            (got - Vec3::from(want)).amax() < 1e-12,
            "target {k}: {got:?} vs {want:?}"
        );
    }
}

#[test]
fn humanml3d_bad_input_is_an_error_naming_file_frame_and_joint() {
    let Some(path) = reference_file("humanml3d/new_joints_012314.npy") else {
        return;
    };
    let good = npy::read_array_as_f64(&path).unwrap();
    let options = humanml3d::Options::default();
    // Wrong shape, named.
    let wrong = good.slice(ndarray::s![.., .., 0..2]).to_owned().into_dyn();
    let (file, location, message) =
        motion_message(&humanml3d::from_joints(wrong.view(), "clip.npy", &options).unwrap_err());
    assert_eq!(
        (file.as_str(), location.as_str()),
        ("clip.npy", "array shape")
    );
    assert!(
        message.contains("(170, 22, 2)") && message.contains("T×22×3"),
        "{message}"
    );
    let flat = Array::from_shape_vec(IxDyn(&[170, 66]), good.iter().copied().collect()).unwrap();
    let (_, _, message) =
        motion_message(&humanml3d::from_features(flat.view(), "f", &options).unwrap_err());
    assert!(
        message.contains("(170, 66)") && message.contains("T×263"),
        "{message}"
    );
    // A NaN frame names the frame and the joint.
    let mut nan = good.clone();
    nan[[57, 4, 1]] = f64::NAN;
    let (_, location, _) =
        motion_message(&humanml3d::from_joints(nan.view(), "c", &options).unwrap_err());
    assert_eq!(location, "frame 57, joint \"left_knee\"");
    // A finite value no capture volume holds (it passed the implied height, a median over
    // frames, and reached IK as a target) names the frame and the joint.
    let mut far = good.clone();
    far[[5, 4, 1]] = 1e30;
    let (_, location, message) =
        motion_message(&humanml3d::from_joints(far.view(), "c", &options).unwrap_err());
    assert_eq!(location, "frame 5, target \"left_knee\"");
    assert!(message.contains("beyond ±1e6 m"), "{message}");
    // A clip in centimetres read as metres is refused, saying which unit fits.
    let cm = good.mapv(|v| v * 100.0);
    let (_, _, message) =
        motion_message(&humanml3d::from_joints(cm.view(), "cm.npy", &options).unwrap_err());
    assert!(
        message.contains("implied body height") && message.contains("read in centimetres (cm)"),
        "{message}"
    );
    // ... and read with the unit it has, it is the same clip.
    let as_cm = humanml3d::Options {
        unit: LengthUnit::Centimetres,
        ..Default::default()
    };
    let m = humanml3d::from_joints(cm.view(), "cm.npy", &as_cm).unwrap();
    let reference = humanml3d::from_joints(good.view(), "m.npy", &options).unwrap();
    assert!(max_difference(&m.positions, &reference.positions) < 1e-12);
    // Frame rate must be positive.
    let zero = humanml3d::Options {
        rate_hz: 0.0,
        ..Default::default()
    };
    let (_, location, _) =
        motion_message(&humanml3d::from_joints(good.view(), "c", &zero).unwrap_err());
    assert_eq!(location, "frame rate");
    // No frames.
    let empty = ArrayD::<f64>::zeros(IxDyn(&[0, 22, 3]));
    assert!(humanml3d::from_joints(empty.view(), "e", &options).is_err());
    // A non-finite feature names the frame and what the feature is.
    let Some(vecs) = reference_file("humanml3d/new_joint_vecs_012314.npy") else {
        return;
    };
    let mut x = npy::read_array_as_f64(&vecs).unwrap();
    x[[12, 4 + 3 * 3 + 1]] = f64::INFINITY;
    let (_, location, _) =
        motion_message(&humanml3d::from_features(x.view(), "v", &options).unwrap_err());
    assert_eq!(
        location,
        "frame 12, feature 14 (joint \"left_knee\" position y)"
    );
    x[[12, 14]] = 0.0;
    x[[3, 260]] = f64::NAN;
    let (_, location, _) =
        motion_message(&humanml3d::from_features(x.view(), "v", &options).unwrap_err());
    assert_eq!(location, "frame 3, feature 260 (foot contact)");
}

#[test]
fn humanml3d_parents_follow_the_kinematic_chains() {
    let mut parents = [None; 22];
    for chain in humanml3d::KINEMATIC_CHAINS {
        for w in chain.windows(2) {
            parents[w[1]] = Some(w[0]);
        }
    }
    assert_eq!(parents, humanml3d::PARENTS);
    let mut parents = [None; 21];
    for chain in kit::KINEMATIC_CHAINS {
        for w in chain.windows(2) {
            parents[w[1]] = Some(w[0]);
        }
    }
    assert_eq!(parents, kit::PARENTS);
}

// ---------------------------------------------------------------------------------------
// KIT-ML (synthetic: there is no KIT file in the reference data)

/// A standing KIT/MMM skeleton (m, y up, facing +z, left at +x) — 1.78 m along its longest
/// bone path — walking along +z at 1 m/s with a small sway, at 12.5 fps.
fn kit_clip(frames: usize) -> Vec<[f64; 3]> {
    let rest: [[f64; 3]; 21] = [
        [0.0, 1.00, 0.0],    // root
        [0.0, 1.10, 0.0],    // BP
        [0.0, 1.30, 0.0],    // BT
        [0.0, 1.50, 0.0],    // BLN
        [0.0, 1.62, 0.0],    // BUN
        [0.18, 1.45, 0.0],   // LS
        [0.18, 1.15, 0.0],   // LE
        [0.18, 0.88, 0.0],   // LW
        [-0.18, 1.45, 0.0],  // RS
        [-0.18, 1.15, 0.0],  // RE
        [-0.18, 0.88, 0.0],  // RW
        [0.09, 0.95, 0.0],   // LH
        [0.09, 0.52, 0.0],   // LK
        [0.09, 0.09, 0.0],   // LA
        [0.09, 0.03, 0.12],  // LMrot
        [0.09, 0.02, 0.20],  // LF
        [-0.09, 0.95, 0.0],  // RH
        [-0.09, 0.52, 0.0],  // RK
        [-0.09, 0.09, 0.0],  // RA
        [-0.09, 0.03, 0.12], // RMrot
        [-0.09, 0.02, 0.20], // RF
    ];
    let mut out = Vec::new();
    for f in 0..frames {
        let t = f as f64 / 12.5;
        for p in rest {
            out.push([p[0] + 0.02 * (3.0 * t).sin(), p[1], p[2] + t]);
        }
    }
    out
}

fn kit_array(clip: &[[f64; 3]], scale: f64) -> ArrayD<f64> {
    let frames = clip.len() / 21;
    let v = clip.iter().flat_map(|p| p.map(|c| c * scale)).collect();
    Array::from_shape_vec(IxDyn(&[frames, 21, 3]), v).unwrap()
}

#[test]
fn kit_millimetres_are_detected_and_converted() {
    let clip = kit_clip(25);
    let mm = kit_array(&clip, 1000.0);
    let m = kit::from_joints(mm.view(), "kit_mm.npy", &kit::Options::default()).unwrap();
    assert_eq!((m.n_frames(), m.n_targets(), m.rate_hz), (25, 21, 12.5));
    assert_eq!(m.names, kit::JOINT_NAMES.map(String::from));
    assert!((m.time[1] - 0.08).abs() < 1e-15);
    for (got, want) in m.positions.iter().zip(&clip) {
        assert!((got - Vec3::from(*want)).amax() < 1e-12);
    }
    // Named positions land where they were put: the left toe of frame 10.
    let lf = m.index("LF").unwrap();
    assert!((m.frame(10)[lf] - Vec3::from(clip[10 * 21 + 15])).amax() < 1e-12);
    assert_eq!(kit::detect_unit(1780.0), Some(LengthUnit::Millimetres));
    assert_eq!(kit::detect_unit(1.78), Some(LengthUnit::Metres));
    assert_eq!(kit::detect_unit(178.0), None);
}

#[test]
fn kit_metres_are_detected_and_an_explicit_unit_overrides() {
    let clip = kit_clip(10);
    let m_array = kit_array(&clip, 1.0);
    let m = kit::from_joints(m_array.view(), "kit_m.npy", &kit::Options::default()).unwrap();
    assert!((m.positions[0] - Vec3::from(clip[0])).amax() < 1e-15);
    // Metres declared as millimetres: a 1.8 mm person is refused.
    let wrong = kit::Options {
        unit: Some(LengthUnit::Millimetres),
        ..Default::default()
    };
    let (_, location, message) =
        motion_message(&kit::from_joints(m_array.view(), "kit_m.npy", &wrong).unwrap_err());
    assert_eq!(location, "skeleton");
    assert!(message.contains("implied body height"), "{message}");
    // Centimetres: neither metres nor millimetres fit, so detection refuses, and the explicit
    // unit reads it.
    let cm = kit_array(&clip, 100.0);
    let (_, _, message) = motion_message(
        &kit::from_joints(cm.view(), "kit_cm.npy", &kit::Options::default()).unwrap_err(),
    );
    assert!(
        message.contains("neither metres nor millimetres"),
        "{message}"
    );
    let as_cm = kit::Options {
        unit: Some(LengthUnit::Centimetres),
        ..Default::default()
    };
    let back = kit::from_joints(cm.view(), "kit_cm.npy", &as_cm).unwrap();
    assert!(
        back.positions
            .iter()
            .zip(&m.positions)
            .all(|(a, b)| (a - b).amax() < 1e-12)
    );
}

#[test]
fn kit_shape_and_value_errors() {
    let options = kit::Options::default();
    let smpl = ArrayD::<f64>::zeros(IxDyn(&[5, 22, 3]));
    let (_, location, message) =
        motion_message(&kit::from_joints(smpl.view(), "k", &options).unwrap_err());
    assert_eq!(location, "array shape");
    assert!(
        message.contains("(5, 22, 3)") && message.contains("T×21×3"),
        "{message}"
    );
    let hml = ArrayD::<f64>::zeros(IxDyn(&[5, 263]));
    let (_, _, message) = motion_message(&kit::from_array(hml.view(), "k", &options).unwrap_err());
    assert!(
        message.contains("(5, 263)") && message.contains("T×251"),
        "{message}"
    );
    let mut a = kit_array(&kit_clip(6), 1000.0);
    a[[4, 13, 2]] = f64::NAN;
    let (_, location, _) = motion_message(&kit::from_joints(a.view(), "k", &options).unwrap_err());
    assert_eq!(location, "frame 4, joint \"LA\"");
}

/// KIT features (T×251) built from the synthetic clip by the definition (heading fixed,
/// root velocities, root-relative positions) recover the clip.
#[test]
fn kit_features_recover_the_joints() {
    let clip = kit_clip(8);
    let frames = 8;
    let mut x = ndarray::Array2::<f64>::zeros((frames, kit::N_FEATURES));
    for t in 0..frames {
        let root = clip[t * 21];
        let next = clip[(t + 1).min(frames - 1) * 21];
        x[[t, 1]] = (next[0] - root[0]) * 1000.0;
        x[[t, 2]] = (next[2] - root[2]) * 1000.0;
        x[[t, 3]] = root[1] * 1000.0;
        for j in 1..21 {
            let p = clip[t * 21 + j];
            x[[t, 4 + 3 * (j - 1)]] = (p[0] - root[0]) * 1000.0;
            x[[t, 5 + 3 * (j - 1)]] = p[1] * 1000.0;
            x[[t, 6 + 3 * (j - 1)]] = (p[2] - root[2]) * 1000.0;
        }
    }
    let m = kit::from_features(
        x.into_dyn().view(),
        "kit_vecs.npy",
        &kit::Options::default(),
    )
    .unwrap();
    // The features integrate the root from x = z = 0: compare relative to frame 0's root.
    let origin = Vec3::new(clip[0][0], 0.0, clip[0][2]);
    for (got, want) in m.positions.iter().zip(&clip) {
        assert!(
            (got + origin - Vec3::from(*want)).amax() < 1e-9,
            "{got:?} vs {want:?}"
        );
    }
}
