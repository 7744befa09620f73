//! The sample clips of `musculo augment --demo`: motions of the default model made here, so
//! that the main command runs on a fresh machine with nothing downloaded. Each clip is the
//! trajectory of the default model's 22 SMPL-named joint markers (`pelvis`, `left_hip`, …, the
//! targets HumanML3D clips are fitted to) under a coordinate motion written as a few
//! harmonics, at 30 frames per second:
//! - `march`: 4 s of marching in place, a step per second (each leg lifted in turn to 55° of
//!   hip and 70° of knee flexion, arms swinging ±20° in counter-phase);
//! - `squat`: 4 s, two squats to 90° of knee flexion with the feet flat, trunk leaning
//!   forward, arms raised forward to balance;
//! - `reach`: 3 s standing, the right arm raised forward and lowered while the trunk bends.
//!
//! The pelvis is then put on the ground: each frame its height is set so that the lowest
//! contact sphere touches the floor (y = 0). They are kinematic sketches, not recordings: no
//! balance is enforced (while one foot is lifted the centre of mass need not lie over the
//! other), which the chain's residual figures show.

use crate::dynamics::{self, Data};
use crate::model::{ContactShape, Model};
use crate::motion::Motion;
use crate::motion::humanml3d::JOINT_NAMES;
use crate::spatial::Vec3;
use std::f64::consts::PI;

/// Frames per second of the demo clips.
pub const RATE_HZ: f64 = 30.0;

/// (name, motion) of every demo clip, on `model` (the default model).
pub fn clips(model: &Model) -> crate::Result<Vec<(String, Motion)>> {
    let mut out = Vec::new();
    for (name, seconds) in [("march", 4.0), ("squat", 4.0), ("reach", 3.0)] {
        let frames = (seconds * RATE_HZ) as usize;
        let motion = from_pose(model, name, frames, |t, set| pose(name, t, set))?;
        out.push((name.to_string(), motion));
    }
    Ok(out)
}

/// The demo clips as inputs of [`super::runner::run`] (named `demo:<clip>`), on `model` (the
/// default model).
pub fn inputs(model: &Model) -> crate::Result<Vec<super::runner::ClipInput>> {
    Ok(clips(model)?
        .into_iter()
        .map(|(name, motion)| super::runner::ClipInput {
            input: format!("demo:{name}"),
            name,
            source: super::runner::ClipSource::Motion(Box::new(motion)),
        })
        .collect())
}

/// The coordinates of clip `name` at time t (s), through `set(coordinate, value)`.
fn pose(name: &str, t: f64, set: &mut dyn FnMut(&str, f64)) {
    let deg = PI / 180.0;
    match name {
        "march" => {
            // marching in place: each leg lifted in turn, one step per second
            let w = PI * t; // a leg's lift lasts half of its 2 s cycle
            set("lumbar_extension", -3.0 * deg);
            for (side, phase) in [("r", 0.0), ("l", PI)] {
                let lift = (w + phase).sin().max(0.0).powi(2);
                set(&format!("hip_flexion_{side}"), 55.0 * deg * lift);
                set(&format!("knee_angle_{side}"), -70.0 * deg * lift);
                set(&format!("ankle_angle_{side}"), 10.0 * deg * lift);
                set(&format!("arm_flex_{side}"), -20.0 * deg * (w + phase).sin());
                set(&format!("elbow_flex_{side}"), 60.0 * deg);
                set(&format!("arm_add_{side}"), -10.0 * deg);
            }
        }
        "squat" => {
            // depth d(t) ∈ [0, 1]: two squats in 4 s
            let d = 0.5 - 0.5 * (2.0 * PI * 0.5 * t).cos();
            set("pelvis_tilt", -25.0 * deg * d);
            set("lumbar_extension", -15.0 * deg * d);
            for side in ["r", "l"] {
                set(&format!("hip_flexion_{side}"), 95.0 * deg * d);
                set(&format!("knee_angle_{side}"), -90.0 * deg * d);
                set(&format!("ankle_angle_{side}"), 20.0 * deg * d);
                set(&format!("arm_flex_{side}"), 60.0 * deg * d);
                set(&format!("arm_add_{side}"), -10.0 * deg);
            }
        }
        _ => {
            // reach: up and down once in 3 s
            let d = 0.5 - 0.5 * (2.0 * PI * t / 3.0).cos();
            set("lumbar_extension", -20.0 * deg * d);
            set("lumbar_bending", 5.0 * deg * d);
            set("arm_flex_r", 65.0 * deg * d);
            set("elbow_flex_r", 30.0 * deg * (1.0 - d));
            for side in ["r", "l"] {
                set(&format!("arm_add_{side}"), -10.0 * deg);
                set(&format!("knee_angle_{side}"), -5.0 * deg);
            }
        }
    }
}

/// Sets the pelvis height so that the lowest contact sphere touches y = 0; leaves `data` at
/// the final pose.
fn ground(
    model: &Model,
    data: &mut Data,
    q: &mut [f64],
    names: &[&str],
    spheres: &[(usize, Vec3, f64)],
) -> crate::Result<()> {
    let Some(ty) = names.iter().position(|n| *n == "pelvis_ty") else {
        return Err(crate::Error::invalid(
            "model",
            format!("the demo needs pelvis_ty; model {} lacks it", model.name),
        ));
    };
    q[ty] = 0.0;
    dynamics::forward_kinematics(model, data, q)?;
    let lowest = spheres
        .iter()
        .map(|(b, p, r)| data.point_position(*b, p).y - r)
        .fold(f64::INFINITY, f64::min);
    q[ty] = -lowest;
    dynamics::forward_kinematics(model, data, q)
}

/// The 22 SMPL-named joint-marker trajectories (a [`Motion`] named `demo:<name>`, 30 frames per
/// second, `frames` frames) of the coordinate motion `pose` on `model` — `pose(t, set)` calls
/// `set(coordinate, value)` for the coordinates it moves at time t (s); the others keep their
/// defaults — with the pelvis put on the ground each frame as for the demo clips. Errors name a
/// coordinate or marker the model lacks.
pub fn from_pose(
    model: &Model,
    name: &str,
    frames: usize,
    pose: impl Fn(f64, &mut dyn FnMut(&str, f64)),
) -> crate::Result<Motion> {
    let names = model.q_names();
    let default: Vec<f64> = model
        .reduction
        .independent
        .iter()
        .map(|&c| model.coordinates[c].default_value)
        .collect();
    let markers: Vec<usize> = JOINT_NAMES
        .iter()
        .map(|n| {
            model
                .markers
                .iter()
                .position(|m| m.name == *n)
                .ok_or_else(|| {
                    crate::Error::invalid(
                        "model",
                        format!(
                            "the demo needs marker `{n}`, which model {} lacks",
                            model.name
                        ),
                    )
                })
        })
        .collect::<crate::Result<_>>()?;
    let spheres: Vec<(usize, Vec3, f64)> = model
        .contact_geometry
        .iter()
        .filter_map(|g| match g.shape {
            ContactShape::Sphere { radius } => Some((g.body, g.pose_in_body.pos, radius)),
            ContactShape::HalfSpace => None,
        })
        .collect();
    if spheres.is_empty() {
        return Err(crate::Error::invalid(
            "model",
            format!(
                "the demo needs contact spheres on the feet; model {} has none",
                model.name
            ),
        ));
    }
    let mut data = Data::new(model);
    let mut all = vec![Vec3::zeros(); model.markers.len()];
    let mut positions = Vec::with_capacity(frames * markers.len());
    let mut q = default.clone();
    for f in 0..frames {
        let t = f as f64 / RATE_HZ;
        q.copy_from_slice(&default);
        let mut unknown = None;
        pose(
            t,
            &mut |c: &str, v: f64| match names.iter().position(|n| *n == c) {
                Some(j) => q[j] = v,
                None => unknown = Some(c.to_string()),
            },
        );
        if let Some(c) = unknown {
            return Err(crate::Error::invalid(
                "model",
                format!(
                    "the demo moves coordinate `{c}`, which model {} lacks",
                    model.name
                ),
            ));
        }
        ground(model, &mut data, &mut q, &names, &spheres)?;
        data.marker_positions(model, &mut all)?;
        positions.extend(markers.iter().map(|&m| all[m]));
    }
    Motion::uniform(
        format!("demo:{name}"),
        JOINT_NAMES.iter().map(|s| s.to_string()).collect(),
        RATE_HZ,
        positions,
    )
}
