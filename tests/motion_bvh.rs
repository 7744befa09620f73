//! The BVH reader: forward kinematics against rotation matrices written out by hand (every
//! rotation order, channel counts other than 3 and 6, positions listed after rotations), the
//! three CMU reference files (bone lengths constant and equal to the OFFSETs, hand-derived
//! leg and arm positions, implied height in the CMU unit, read time of the 2,752-frame
//! file), and errors that name the file and the line or frame.

mod common;

use common::reference_file;
use musculo::Error;
use musculo::motion::LengthUnit;
use musculo::motion::bvh::{self, Bvh, BvhOptions, CMU_UNIT_M, PositionChannels};
use musculo::spatial::Vec3;
use nalgebra::Matrix3;

// Rotation matrices about x, y, z (right-handed, angle in degrees), written out.
fn rx(deg: f64) -> Matrix3<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn ry(deg: f64) -> Matrix3<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn rz(deg: f64) -> Matrix3<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}
fn rot(axis: char, deg: f64) -> Matrix3<f64> {
    match axis {
        'X' => rx(deg),
        'Y' => ry(deg),
        _ => rz(deg),
    }
}

fn metres() -> BvhOptions {
    BvhOptions {
        unit: LengthUnit::Metres,
        ..Default::default()
    }
}

fn close(a: Vec3, b: Vec3, tol: f64, what: &str) {
    assert!((a - b).amax() <= tol, "{what}: {a:?} vs {b:?}");
}

fn motion_error(e: &Error) -> (String, String) {
    match e {
        Error::Motion {
            location, message, ..
        } => (location.clone(), message.clone()),
        other => panic!("expected Error::Motion, got {other:?}"),
    }
}

/// Root A (3 rotation channels in `order`) → joint B at (0.3, 0.5, 0.4) with rotations
/// Y X Z → end site 0.5 along z.
fn chain(order: [char; 3], a: [f64; 3], b: [f64; 3]) -> String {
    let ch = |c: char| format!("{c}rotation");
    format!(
        "HIERARCHY\nROOT A\n{{\n  OFFSET 0 0 0\n  CHANNELS 3 {} {} {}\n  JOINT B\n  {{\n    \
         OFFSET 0.3 0.5 0.4\n    CHANNELS 3 Yrotation Xrotation Zrotation\n    End Site\n    {{\n      \
         OFFSET 0 0 0.5\n    }}\n  }}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n{} {} {} {} {} {}\n",
        ch(order[0]),
        ch(order[1]),
        ch(order[2]),
        a[0],
        a[1],
        a[2],
        b[0],
        b[1],
        b[2]
    )
}

#[test]
fn bvh_every_rotation_order_matches_hand_written_matrices() {
    let (a, b) = ([37.0, -52.0, 71.0], [-23.0, 14.0, 105.0]);
    for order in [
        ['X', 'Y', 'Z'],
        ['X', 'Z', 'Y'],
        ['Y', 'X', 'Z'],
        ['Y', 'Z', 'X'],
        ['Z', 'X', 'Y'],
        ['Z', 'Y', 'X'],
    ] {
        let options = BvhOptions {
            end_sites: true,
            ..metres()
        };
        let m = bvh::parse(&chain(order, a, b), "chain.bvh", &options).unwrap();
        assert_eq!(m.names, ["A", "B", "B_end"]);
        // Intrinsic rotations in channel order: R_A = R₁(a₁) R₂(a₂) R₃(a₃).
        let r_a = rot(order[0], a[0]) * rot(order[1], a[1]) * rot(order[2], a[2]);
        let r_b = ry(b[0]) * rx(b[1]) * rz(b[2]);
        let p_b = r_a * Vec3::new(0.3, 0.5, 0.4);
        let p_end = p_b + r_a * r_b * Vec3::new(0.0, 0.0, 0.5);
        let f = m.frame(0);
        close(f[0], Vec3::zeros(), 0.0, "A");
        close(f[1], p_b, 1e-15, &format!("B, order {order:?}"));
        close(f[2], p_end, 1e-15, &format!("B_end, order {order:?}"));
    }
}

/// Quarter turns whose results are exact: the order of the channels decides the answer.
#[test]
fn bvh_channel_order_decides_the_rotation() {
    let text = |channels: &str, values: &str| {
        format!(
            "HIERARCHY\nROOT R\n{{\nOFFSET 0 0 0\nCHANNELS {channels}\nJOINT C\n{{\nOFFSET 1 0 0\n\
             CHANNELS 1 Zrotation\nEnd Site\n{{\nOFFSET 0 0 0\n}}\n}}\n}}\nMOTION\nFrames: 2\n\
             Frame Time: 0.5\n{values} 0\n{values} 90\n"
        )
    };
    // Rx(90)·Ry(90)·(1,0,0) = Rx(90)·(0,0,−1) = (0,1,0); Ry(90)·Rx(90)·(1,0,0) = (0,0,−1).
    let xy = bvh::parse(&text("2 Xrotation Yrotation", "90 90"), "xy", &metres()).unwrap();
    let yx = bvh::parse(&text("2 Yrotation Xrotation", "90 90"), "yx", &metres()).unwrap();
    close(xy.frame(0)[1], Vec3::new(0.0, 1.0, 0.0), 1e-15, "XY");
    close(yx.frame(0)[1], Vec3::new(0.0, 0.0, -1.0), 1e-15, "YX");
    assert_eq!(xy.rate_hz, 2.0);
    assert_eq!(xy.time, [0.0, 0.5]);
    // A one-channel joint turning only itself does not move its own centre.
    close(xy.frame(1)[1], xy.frame(0)[1], 1e-15, "C's own rotation");
}

#[test]
fn bvh_position_channels_after_rotations_move_along_rotated_axes() {
    let text = |channels: &str| {
        format!(
            "HIERARCHY\nROOT R\n{{\nOFFSET 5 0 0\nCHANNELS {channels}\nJOINT C\n{{\nOFFSET 1 0 0\n\
             CHANNELS 0\n}}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n"
        )
    };
    // Zrotation 90 then Xposition 1: the translation is along the rotated x axis (= world y).
    let after = bvh::parse(
        &(text("4 Zrotation Xposition Yposition Zposition") + "90 1 0 0\n"),
        "a",
        &metres(),
    )
    .unwrap();
    close(
        after.frame(0)[0],
        Vec3::new(5.0, 1.0, 0.0),
        1e-15,
        "root, positions after",
    );
    close(
        after.frame(0)[1],
        Vec3::new(5.0, 2.0, 0.0),
        1e-15,
        "child, positions after",
    );
    // Positions first: along the parent's x.
    let before = bvh::parse(
        &(text("4 Xposition Yposition Zposition Zrotation") + "1 0 0 90\n"),
        "b",
        &metres(),
    )
    .unwrap();
    close(
        before.frame(0)[0],
        Vec3::new(6.0, 0.0, 0.0),
        1e-15,
        "root, positions before",
    );
    close(
        before.frame(0)[1],
        Vec3::new(6.0, 1.0, 0.0),
        1e-15,
        "child, positions before",
    );
    // Exporters that repeat the offset in the position channels: ReplaceOffset.
    let replace = BvhOptions {
        position_channels: PositionChannels::ReplaceOffset,
        ..metres()
    };
    let r = bvh::parse(
        &(text("4 Xposition Yposition Zposition Zrotation") + "1 0 0 90\n"),
        "r",
        &replace,
    )
    .unwrap();
    close(
        r.frame(0)[0],
        Vec3::new(1.0, 0.0, 0.0),
        1e-15,
        "root, offset replaced",
    );
    // Units scale offsets and position channels alike.
    let cm = BvhOptions {
        unit: LengthUnit::Centimetres,
        ..Default::default()
    };
    let text_cm = "HIERARCHY\nROOT R\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n\
                   JOINT C\n{\nOFFSET 0 170 0\nCHANNELS 0\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n10 0 -20\n";
    let m = bvh::parse(text_cm, "cm", &cm).unwrap();
    close(m.frame(0)[1], Vec3::new(0.1, 1.7, -0.2), 1e-15, "cm");
}

#[test]
fn bvh_end_sites_are_named_after_their_joint_and_optional() {
    let text = "HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n\
                End Site\n{\nOFFSET 0 1 0\n}\nEnd Site\n{\nOFFSET 0 -0.9 0\n}\n}\nMOTION\nFrames: 1\n\
                Frame Time: 0.0083333\n0 1 0\n";
    let all = bvh::parse(
        text,
        "e",
        &BvhOptions {
            end_sites: true,
            ..metres()
        },
    )
    .unwrap();
    assert_eq!(all.names, ["Hips", "Hips_end", "Hips_end2"]);
    close(all.frame(0)[1], Vec3::new(0.0, 2.0, 0.0), 0.0, "end site");
    assert_eq!(all.rate_hz, 120.0);
    let joints = bvh::parse(text, "e", &metres()).unwrap();
    assert_eq!(joints.names, ["Hips"]);
}

const CMU: [&str; 3] = ["bvh/131_01.bvh", "bvh/131_03.bvh", "bvh/cmu_01_01.bvh"];

fn cmu_options() -> BvhOptions {
    BvhOptions {
        unit: LengthUnit::Custom(CMU_UNIT_M),
        end_sites: true,
        ..Default::default()
    }
}

#[test]
fn bvh_cmu_bone_lengths_are_constant_and_equal_the_offsets() {
    for file in CMU {
        let Some(path) = reference_file(file) else {
            return;
        };
        let bvh = Bvh::read(&path).unwrap();
        let m = bvh.to_motion(&cmu_options()).unwrap();
        assert_eq!(
            bvh.joints.iter().filter(|j| !j.end_site).count(),
            31,
            "{file}"
        );
        assert_eq!(m.rate_hz, 120.0);
        let mut worst = 0.0_f64;
        for (j, joint) in bvh.joints.iter().enumerate() {
            let Some(parent) = joint.parent else { continue };
            let length = joint.offset.norm() * CMU_UNIT_M;
            for f in 0..m.n_frames() {
                let d = (m.frame(f)[j] - m.frame(f)[parent]).norm();
                let err = (d - length).abs() / length.max(1e-3);
                worst = worst.max(err);
                assert!(
                    err <= 1e-9,
                    "{file} frame {f} {}: {d} vs {length}",
                    joint.name
                );
            }
        }
        eprintln!(
            "{file}: {} frames, worst relative bone-length error {worst:.1e}",
            m.n_frames()
        );
    }
}

/// Frame `f`'s values read straight from the file text (line 188 + f), independently of the
/// reader.
fn frame_values(text: &str, f: usize) -> Vec<f64> {
    let line = text.lines().nth(187 + f).unwrap();
    line.split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

/// Left leg (Z Y X channels) and left arm (Z X Y) of 131_01.bvh by hand: offsets copied from
/// the file's hierarchy, world pose = product of the parents' transforms.
#[test]
fn bvh_cmu_positions_match_hand_derived_forward_kinematics() {
    let Some(path) = reference_file("bvh/131_01.bvh") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let m = bvh::read(&path, &cmu_options()).unwrap();
    let parsed = Bvh::read(&path).unwrap();
    let joint = |name: &str| {
        parsed
            .joints
            .iter()
            .find(|j| j.name == name)
            .unwrap()
            .clone()
    };
    let u = CMU_UNIT_M;
    for f in [0, 400, 993] {
        let v = frame_values(&text, f);
        assert_eq!(v.len(), 96);
        let zyx = |k: usize| rz(v[k]) * ry(v[k + 1]) * rx(v[k + 2]);
        let zxy = |k: usize| rz(v[k]) * rx(v[k + 1]) * ry(v[k + 2]);
        // Hips: position (0..3), rotation Z Y X (3..6).
        let hips = Vec3::new(v[0], v[1], v[2]) * u;
        let r_hips = zyx(3);
        // LHipJoint (6..9, offset 0) → LeftHip (9..12) → LeftKnee (12..15) → LeftAnkle.
        let r = r_hips * zyx(6);
        let hip = hips + r * Vec3::new(1.24777, -1.64261, 0.71711) * u;
        let r = r * zyx(9);
        let knee = hip + r * Vec3::new(2.49329, -6.85026, 0.0) * u;
        let r = r * zyx(12);
        let ankle = knee + r * Vec3::new(2.36770, -6.50520, 0.0) * u;
        for (name, p) in [("LeftHip", hip), ("LeftKnee", knee), ("LeftAnkle", ankle)] {
            close(
                m.frame(f)[m.index(name).unwrap()],
                p,
                1e-12,
                &format!("frame {f} {name}"),
            );
        }
        // Arm: lowerback → Chest → Chest2 → LeftCollar → LeftShoulder (Z X Y) → LeftElbow.
        let offset = |name: &str| joint(name).offset * u;
        let col = |name: &str| joint(name).first_channel;
        let mut r = r_hips;
        let mut p = hips;
        for name in ["lowerback", "Chest", "Chest2", "LeftCollar"] {
            p += r * offset(name);
            r *= zyx(col(name));
        }
        let shoulder = p + r * offset("LeftShoulder");
        let r = r * zxy(col("LeftShoulder"));
        let elbow = shoulder + r * offset("LeftElbow");
        close(
            m.frame(f)[m.index("LeftShoulder").unwrap()],
            shoulder,
            1e-12,
            "LeftShoulder",
        );
        close(
            m.frame(f)[m.index("LeftElbow").unwrap()],
            elbow,
            1e-12,
            "LeftElbow",
        );
    }
}

#[test]
fn bvh_cmu_implied_height_is_plausible_in_the_cmu_unit_only() {
    for file in CMU {
        let Some(path) = reference_file(file) else {
            return;
        };
        let bvh = Bvh::read(&path).unwrap();
        let raw = bvh.implied_height();
        eprintln!(
            "{file}: implied height {raw:.2} file units = {:.3} m in the CMU unit ({CMU_UNIT_M} m)",
            raw * CMU_UNIT_M
        );
        assert!((1.4..2.0).contains(&(raw * CMU_UNIT_M)));
        // In centimetres (the default) and in metres it is not a person: refused, with the
        // CMU unit suggested.
        for unit in [LengthUnit::Centimetres, LengthUnit::Metres] {
            let e = bvh
                .to_motion(&BvhOptions {
                    unit,
                    ..Default::default()
                })
                .unwrap_err();
            let (location, message) = motion_error(&e);
            assert_eq!(location, "skeleton");
            assert!(
                message.contains("implied body height") && message.contains("0.056444"),
                "{message}"
            );
            if file == CMU[0] && unit == LengthUnit::Centimetres {
                eprintln!("read in cm: {e}");
            }
        }
    }
}

#[test]
fn bvh_long_cmu_file_reads_fast() {
    let Some(path) = reference_file("bvh/cmu_01_01.bvh") else {
        return;
    };
    let start = std::time::Instant::now();
    let m = bvh::read(&path, &cmu_options()).unwrap();
    let elapsed = start.elapsed();
    assert_eq!(m.n_frames(), 2752);
    eprintln!(
        "cmu_01_01.bvh: {} frames × {} targets read and forward-kinematics'd in {:.1} ms",
        m.n_frames(),
        m.n_targets(),
        elapsed.as_secs_f64() * 1e3
    );
}

const SMALL: &str = "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n  JOINT Spine\n  {\n    OFFSET 0 1.2 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    {\n      OFFSET 0 0.5 0\n    }\n  }\n}\nMOTION\nFrames: 3\nFrame Time: 0.01\n0 1 0 0 0 0 0 0 0\n0 1 0 10 0 0 0 0 0\n0 1 0 20 0 0 0 0 0\n";

fn parse_error(text: &str) -> (String, String) {
    let e = Bvh::parse(text, "small.bvh").unwrap_err();
    assert!(e.to_string().starts_with("small.bvh: "), "{e}");
    motion_error(&e)
}

#[test]
fn bvh_errors_name_the_line_or_frame() {
    assert_eq!(
        bvh::parse(SMALL, "small.bvh", &metres())
            .unwrap()
            .n_frames(),
        3
    );
    // Truncated in the hierarchy, after MOTION, and in the frames.
    let (location, message) = parse_error(&SMALL[..SMALL.find("JOINT").unwrap() + 11]);
    assert_eq!(location, "line 6");
    assert!(message.contains("truncated"), "{message}");
    let (_, message) = parse_error(&SMALL[..SMALL.find("Frames").unwrap()]);
    assert!(message.contains("truncated"), "{message}");
    let cut = &SMALL[..SMALL.rfind("0 1 0 20").unwrap()];
    let (location, message) = parse_error(cut);
    assert_eq!(location, "line 20");
    assert!(message.contains("after 2 of the 3 frames"), "{message}");
    // A frame with the wrong number of values names the frame and its line.
    let (location, message) = parse_error(&SMALL.replace("0 1 0 10 0 0 0 0 0", "0 1 0 10 0 0 0 0"));
    assert_eq!(location, "frame 1 (line 20)");
    assert!(
        message.contains("8 values where the hierarchy has 9 channels"),
        "{message}"
    );
    // A NaN value, or one beyond ±1e6 (an angle of 1e300° made pseudo-random poses), names
    // the frame and the channel.
    for value in ["nan", "1e300", "-2e6"] {
        let (location, message) =
            parse_error(&SMALL.replace("0 1 0 20 0", &format!("0 1 0 {value} 0")));
        assert_eq!(location, "frame 2 (line 21)");
        assert!(message.contains("joint \"Hips\" Zrotation"), "{message}");
    }
    // Bad keyword, unknown channel, bad offset, unclosed joint, bad header lines.
    let (location, message) = parse_error(&SMALL.replace("JOINT Spine", "JIONT Spine"));
    assert_eq!(location, "line 6");
    assert!(message.contains("'JIONT'"), "{message}");
    let (location, message) = parse_error(&SMALL.replace(
        "Xrotation Yrotation\n  JOINT",
        "Xrotation Wrotation\n  JOINT",
    ));
    assert_eq!(location, "line 5");
    assert!(message.contains("'Wrotation'"), "{message}");
    let (location, _) = parse_error(&SMALL.replace("OFFSET 0 1.2 0", "OFFSET 0 x 0"));
    assert_eq!(location, "line 8");
    let (_, message) = parse_error(&SMALL.replacen("  }\n}\nMOTION", "  }\nMOTION", 1));
    assert!(message.contains("not closed"), "{message}");
    let (location, _) = parse_error(&SMALL.replace("Frames: 3", "Frames: three"));
    assert_eq!(location, "line 17");
    let (location, _) = parse_error(&SMALL.replace("Frame Time: 0.01", "Frame Time: 0"));
    assert_eq!(location, "line 18");
    // A rate no capture has (1 GHz gave accelerations of 10¹⁹ m/s²; a frame every 10⁹ s
    // failed in the low-pass filter) is refused when the motion is made.
    for time in ["1e-9", "1e9"] {
        let text = SMALL.replace("Frame Time: 0.01", &format!("Frame Time: {time}"));
        let e = bvh::parse(&text, "small.bvh", &metres()).unwrap_err();
        let (location, message) = motion_error(&e);
        assert_eq!(location, "frame rate");
        assert!(message.contains("is not a motion capture's"), "{message}");
    }
    let (location, message) = parse_error(&SMALL.replace("Frames: 3", "Frames: 2"));
    assert_eq!(location, "line 21");
    assert!(message.contains("more frame lines"), "{message}");
    let (location, _) = parse_error(&SMALL.replace("HIERARCHY", "HIERARCHIE"));
    assert_eq!(location, "line 1");
    // A missing file is an I/O error with its path.
    let e = Bvh::read(std::path::Path::new("no/such.bvh")).unwrap_err();
    assert!(
        matches!(e, Error::Io { .. }) && e.to_string().contains("no/such.bvh"),
        "{e}"
    );
}
