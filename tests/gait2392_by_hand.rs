//! Total mass and default-pose body positions of gait2392, against values worked out by hand
//! from `Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim`.
//!
//! Masses (kg, from the `<mass>` of each body): pelvis 11.777, femur 9.3014, tibia 3.7075,
//! talus 0.1, calcn 1.25, toes 0.2166 (each side), torso 34.2366:
//!   total = 11.777 + 2 (9.3014 + 3.7075 + 0.1 + 1.25 + 0.2166) + 34.2366 = 75.1646 kg.
//!
//! Default pose: every coordinate is 0 except pelvis_ty = 0.95, and every offset frame has
//! orientation 0 0 0, so all rotations are the identity and each body origin is its parent's
//! origin plus the joint's parent-frame translation plus the joint's translations:
//!   pelvis  = (0, 0.95, 0)
//!   femur_r = pelvis + (−0.0707, −0.0661, 0.0835)              (hip_r pelvis_offset)
//!   tibia_r = femur_r + (s_x(0), s_y(0), 0)                    (knee_r translation1/2 splines)
//!   talus_r = tibia_r + (0, −0.43, 0)                           (ankle_r tibia_r_offset)
//!   calcn_r = talus_r + (−0.04877, −0.04195, 0.00792)           (subtalar_r talus_r_offset)
//!   toes_r  = calcn_r + (0.1788, −0.002, 0.00108)               (mtp_r calcn_r_offset)
//!   torso   = pelvis + (−0.1007, 0.0815, 0)                     (back pelvis_offset)
//! and the left side mirrors z. The knee translations are the SimmSpline (Forsythe–Malcolm–
//! Moler) values at knee_angle = 0, which lies between the knots −0.174533 and 0.197344
//! (translation1) and −0.174533 and 0.159149 (translation2). They were computed outside
//! musculo by solving the spline's 12×12 and 7×7 systems densely with numpy (end rows
//! matching the third derivative of the cubic fitted through the four end points) and
//! evaluating the cubic on that interval:
//!   s_x(0) = −0.004499856517536013,  s_y(0) = −0.3958206964483503.

mod common;
use common::*;
use musculo::spatial::Vec3;
use musculo::{Data, Model, dynamics};

#[test]
fn gait2392_total_mass_and_default_pose_match_hand_computation() {
    let Some(path) =
        reference_file("opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")
    else {
        return;
    };
    let model = Model::from_osim_file(&path).unwrap();
    let total = 11.777 + 2.0 * (9.3014 + 3.7075 + 0.1 + 1.25 + 0.2166) + 34.2366;
    assert!(
        (model.total_mass() - total).abs() < 1e-12,
        "{} vs {total}",
        model.total_mass()
    );

    let mut data = Data::new(&model);
    dynamics::forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
    let (sx, sy) = (-0.004499856517536013, -0.3958206964483503);
    let pelvis = Vec3::new(0.0, 0.95, 0.0);
    let torso = pelvis + Vec3::new(-0.1007, 0.0815, 0.0);
    let mut expected = vec![("pelvis".to_string(), pelvis), ("torso".to_string(), torso)];
    for (side, z) in [("r", 1.0), ("l", -1.0)] {
        let femur = pelvis + Vec3::new(-0.0707, -0.0661, 0.0835 * z);
        let tibia = femur + Vec3::new(sx, sy, 0.0);
        let talus = tibia + Vec3::new(0.0, -0.43, 0.0);
        let calcn = talus + Vec3::new(-0.04877, -0.04195, 0.00792 * z);
        let toes = calcn + Vec3::new(0.1788, -0.002, 0.00108 * z);
        for (name, p) in [
            ("femur", femur),
            ("tibia", tibia),
            ("talus", talus),
            ("calcn", calcn),
            ("toes", toes),
        ] {
            expected.push((format!("{name}_{side}"), p));
        }
    }
    assert_eq!(expected.len(), model.bodies.len() - 1);
    for (name, p) in expected {
        let b = model
            .body_index(&name)
            .unwrap_or_else(|| panic!("no body {name}"));
        let (r, o) = data.body_pose(b);
        assert!((o - p).amax() < 1e-12, "{name}: {o:?} vs {p:?}");
        assert!(
            (r - nalgebra::Matrix3::identity()).amax() < 1e-15,
            "{name} rotation"
        );
    }
}
