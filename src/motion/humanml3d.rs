//! HumanML3D motions (Guo et al. 2022, github.com/EricGuo5513/HumanML3D), in either of the
//! two forms the dataset ships:
//!
//! - `new_joints/<id>.npy`: `float32` T×22×3 joint centres in metres, y up, 20 fps, in the
//!   SMPL joint order of [`JOINT_NAMES`] (kinematic chains [`KINEMATIC_CHAINS`], from the
//!   project's `paramUtil.py`, `t2m_kinematic_chain`);
//! - `new_joint_vecs/<id>.npy`: `float32` T×263 features (`motion_representation.ipynb`,
//!   `process_file`), per frame t:
//!
//! | columns | meaning |
//! |---|---|
//! | 0 | root yaw velocity ω_t: the **half**-angle increment of the heading about +y (rad/frame) |
//! | 1–2 | root planar velocity (x, z) in the heading frame |
//! | 3 | root (pelvis) height y |
//! | 4–66 | the 21 other joints relative to the root in x and z, absolute in y, in the heading frame ("ric") |
//! | 67–192 | 21 joint rotations, continuous 6-D |
//! | 193–258 | 22 joint velocities |
//! | 259–262 | 4 foot-contact flags |
//!
//! Joint positions are recovered from the features as the project's `recover_from_ric` does
//! (and as its `new_joints` files were made — they *are* this recovery of the features):
//!
//! ```text
//! a_0 = 0,  a_t = Σ_{k<t} ω_k                      heading quaternion q_t = (cos a_t, 0, sin a_t, 0),
//!                                                  i.e. a rotation by θ_t = 2 a_t about +y
//! R_y(−θ)(x, y, z) = (x cos θ − z sin θ, y, x sin θ + z cos θ)          (rotation by q_t⁻¹)
//! r_0 = 0,  r_t = r_{t−1} + R_y(−θ_t) (v_{t−1,x}, 0, v_{t−1,z})        root x, z
//! root_t = (r_t,x , h_t , r_t,z)
//! joint_j,t = R_y(−θ_t) ric_j,t + (r_t,x , 0 , r_t,z)                   j = 1 … 21
//! ```
//!
//! Model outputs are usually normalised features; [`Normalization`] (the dataset's
//! `Mean.npy`/`Std.npy`) turns them back into features first: `x = x̂ · Std + Mean`.
//!
//! The same layout with 21 joints (T×251) is KIT-ML's ([`super::kit`]); the functions here
//! that take a joint set are shared with that reader. Every value must be finite; the implied
//! body size ([`implied_height`]) must be a person's height in the chosen unit
//! ([`super::check_plausible_height`]): a clip saved in centimetres is refused with the unit
//! that would fit.

use super::npy::{self, shape_text};
use super::{LengthUnit, Motion, check_plausible_height};
use crate::error::Error;
use crate::spatial::Vec3;
use ndarray::{ArrayView2, ArrayView3, ArrayViewD, Ix2, Ix3};
use std::path::Path;

/// HumanML3D's frame rate (Hz).
pub const RATE_HZ: f64 = 20.0;

/// The 22 SMPL body joints in HumanML3D's order.
pub const JOINT_NAMES: [&str; 22] = [
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
];

/// Kinematic chains (joint indices), `t2m_kinematic_chain` of HumanML3D's `paramUtil.py`:
/// right leg, left leg, spine to head, right arm, left arm.
pub const KINEMATIC_CHAINS: [&[usize]; 5] = [
    &[0, 2, 5, 8, 11],
    &[0, 1, 4, 7, 10],
    &[0, 3, 6, 9, 12, 15],
    &[9, 14, 17, 19, 21],
    &[9, 13, 16, 18, 20],
];

/// Parent of each joint, from [`KINEMATIC_CHAINS`] (the pelvis has none).
pub const PARENTS: [Option<usize>; 22] = [
    None,
    Some(0),
    Some(0),
    Some(0),
    Some(1),
    Some(2),
    Some(3),
    Some(4),
    Some(5),
    Some(6),
    Some(7),
    Some(8),
    Some(9),
    Some(9),
    Some(9),
    Some(12),
    Some(13),
    Some(14),
    Some(16),
    Some(17),
    Some(18),
    Some(19),
];

/// Number of features per frame for `n_joints` joints: 4 root values, (J−1)·3 positions,
/// (J−1)·6 rotations, J·3 velocities, 4 contacts = 12 J − 1 (263 for 22 joints, 251 for 21).
pub const fn n_features(n_joints: usize) -> usize {
    12 * n_joints - 1
}

/// HumanML3D's feature count (263).
pub const N_FEATURES: usize = n_features(22);

/// Dataset feature statistics: normalised features x̂ become features `x̂ · std + mean`.
#[derive(Clone, Debug, PartialEq)]
pub struct Normalization {
    pub mean: Vec<f64>,
    pub std: Vec<f64>,
}

impl Normalization {
    /// From the two vectors (same length, finite).
    pub fn new(mean: Vec<f64>, std: Vec<f64>) -> crate::Result<Normalization> {
        if mean.len() != std.len() {
            return Err(Error::invalid(
                "std",
                format!("{} values for {} means", std.len(), mean.len()),
            ));
        }
        if let Some(k) = mean.iter().chain(&std).position(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "mean/std",
                format!("value {} is not finite", k % mean.len().max(1)),
            ));
        }
        Ok(Normalization { mean, std })
    }

    /// Reads `Mean.npy` and `Std.npy` (1-D, `float32` or `float64`).
    pub fn read(mean: &Path, std: &Path) -> crate::Result<Normalization> {
        let load = |path: &Path| -> crate::Result<Vec<f64>> {
            let source = path.display().to_string();
            let a = npy::read_array_as_f64(path)?;
            let v = npy::expect_rank::<f64, ndarray::Ix1>(a.view(), &source)?.to_vec();
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                return Err(motion_error(
                    &source,
                    format!("feature {k}"),
                    "value is not finite",
                ));
            }
            Ok(v)
        };
        let (m, s) = (load(mean)?, load(std)?);
        if m.len() != s.len() {
            return Err(motion_error(
                &std.display().to_string(),
                "array shape".into(),
                format!("{} values where the mean has {}", s.len(), m.len()),
            ));
        }
        Ok(Normalization { mean: m, std: s })
    }
}

/// How a HumanML3D (or KIT-ML) clip is read.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Frame rate (Hz); HumanML3D's is 20.
    pub rate_hz: f64,
    /// Length unit of the file's values (HumanML3D's are metres).
    pub unit: LengthUnit,
    /// De-normalisation of the features (the feature form only; an error for joints).
    pub normalization: Option<Normalization>,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            rate_hz: RATE_HZ,
            unit: LengthUnit::Metres,
            normalization: None,
        }
    }
}

fn motion_error(source: &str, location: String, message: impl Into<String>) -> Error {
    Error::Motion {
        file: source.to_string(),
        location,
        message: message.into(),
    }
}

/// What feature column `k` of a `12 J − 1` vector holds, for messages.
pub(crate) fn feature_meaning(k: usize, names: &[&str]) -> String {
    let j = names.len();
    let (pos, rot, vel) = (4 + 3 * (j - 1), 4 + 9 * (j - 1), 4 + 9 * (j - 1) + 3 * j);
    let axis = ["x", "y", "z"];
    match k {
        0 => "feature 0 (root yaw velocity)".into(),
        1 | 2 => format!("feature {k} (root {} velocity)", ["x", "z"][k - 1]),
        3 => "feature 3 (root height)".into(),
        _ if k < pos => format!(
            "feature {k} (joint \"{}\" position {})",
            names[1 + (k - 4) / 3],
            axis[(k - 4) % 3]
        ),
        _ if k < rot => format!(
            "feature {k} (joint \"{}\" rotation)",
            names[1 + (k - pos) / 6]
        ),
        _ if k < vel => format!(
            "feature {k} (joint \"{}\" velocity {})",
            names[(k - rot) / 3],
            axis[(k - rot) % 3]
        ),
        _ => format!("feature {k} (foot contact)"),
    }
}

/// Joint positions (file units, frame-major) from a T×J×3 array; every value finite.
pub(crate) fn joints_from_array_raw(
    array: ArrayViewD<'_, f64>,
    source: &str,
    names: &[&str],
) -> crate::Result<Vec<Vec3>> {
    let shape_error = |shape: &[usize]| {
        motion_error(
            source,
            "array shape".into(),
            format!(
                "shape {} is not T×{}×3 joint positions (frames × joints × xyz)",
                shape_text(shape),
                names.len()
            ),
        )
    };
    let shape = array.shape().to_vec();
    let a: ArrayView3<f64> = array
        .into_dimensionality::<Ix3>()
        .map_err(|_| shape_error(&shape))?;
    let (frames, joints, three) = a.dim();
    if joints != names.len() || three != 3 {
        return Err(shape_error(&shape));
    }
    if frames == 0 {
        return Err(motion_error(
            source,
            "frames".into(),
            "the array has no frames",
        ));
    }
    let mut out = Vec::with_capacity(frames * joints);
    for f in 0..frames {
        for (j, name) in names.iter().enumerate() {
            let p = Vec3::new(a[[f, j, 0]], a[[f, j, 1]], a[[f, j, 2]]);
            if !p.iter().all(|v| v.is_finite()) {
                return Err(motion_error(
                    source,
                    format!("frame {f}, joint \"{name}\""),
                    format!("position ({}, {}, {}) is not finite", p.x, p.y, p.z),
                ));
            }
            out.push(p);
        }
    }
    Ok(out)
}

/// HumanML3D's `recover_from_ric` (see the module documentation): joint positions, frame-major
/// T×J, from T×(12 J − 1) features. No checks of shape or values: [`from_features`] does
/// them.
pub fn recover_from_ric(features: ArrayView2<'_, f64>, n_joints: usize) -> Vec<Vec3> {
    let frames = features.nrows();
    let mut out = Vec::with_capacity(frames * n_joints);
    let (mut half_angle, mut root_x, mut root_z) = (0.0_f64, 0.0_f64, 0.0_f64);
    for t in 0..frames {
        if t > 0 {
            // a_t = a_{t−1} + ω_{t−1};  r_t = r_{t−1} + R_y(−θ_t) v_{t−1}
            half_angle += features[[t - 1, 0]];
        }
        let (s, c) = (2.0 * half_angle).sin_cos();
        if t > 0 {
            let (vx, vz) = (features[[t - 1, 1]], features[[t - 1, 2]]);
            root_x += vx * c - vz * s;
            root_z += vx * s + vz * c;
        }
        out.push(Vec3::new(root_x, features[[t, 3]], root_z));
        for j in 1..n_joints {
            let k = 4 + 3 * (j - 1);
            let (x, y, z) = (features[[t, k]], features[[t, k + 1]], features[[t, k + 2]]);
            out.push(Vec3::new(x * c - z * s + root_x, y, x * s + z * c + root_z));
        }
    }
    out
}

/// Joint positions (file units, frame-major) from a T×(12 J − 1) feature array, after
/// de-normalisation if given; every feature must be finite.
pub(crate) fn features_from_array_raw(
    array: ArrayViewD<'_, f64>,
    source: &str,
    names: &[&str],
    normalization: Option<&Normalization>,
) -> crate::Result<Vec<Vec3>> {
    let width = n_features(names.len());
    let shape = array.shape().to_vec();
    let shape_error = || {
        motion_error(
            source,
            "array shape".into(),
            format!(
                "shape {} is not T×{width} features ({} joints)",
                shape_text(&shape),
                names.len()
            ),
        )
    };
    let a: ArrayView2<f64> = array
        .into_dimensionality::<Ix2>()
        .map_err(|_| shape_error())?;
    if a.ncols() != width {
        return Err(shape_error());
    }
    if a.nrows() == 0 {
        return Err(motion_error(
            source,
            "frames".into(),
            "the array has no frames",
        ));
    }
    let denormalized;
    let a = a.view();
    let features: ArrayView2<f64> = match normalization {
        Some(n) => {
            if n.mean.len() != width {
                return Err(Error::invalid(
                    "normalization",
                    format!("{} mean/std values for {width} features", n.mean.len()),
                ));
            }
            let mut d = a.to_owned();
            for mut row in d.rows_mut() {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = *v * n.std[k] + n.mean[k];
                }
            }
            denormalized = d;
            denormalized.view()
        }
        None => a,
    };
    for (t, row) in features.rows().into_iter().enumerate() {
        if let Some(k) = row.iter().position(|v| !v.is_finite()) {
            return Err(motion_error(
                source,
                format!("frame {t}, {}", feature_meaning(k, names)),
                format!("value {} is not finite", row[k]),
            ));
        }
    }
    Ok(recover_from_ric(features, names.len()))
}

/// A body-size measure to tell length units apart: per frame, the largest distance between
/// two targets (head to toe when standing, hand to foot when reaching; ≈ 0.85–1.2 × stature),
/// and its median over the frames (at most 512 frames, evenly spaced, are used). Targets with
/// non-finite coordinates are skipped; 0 if nothing is left.
pub fn implied_height(n_targets: usize, positions: &[Vec3]) -> f64 {
    let frames = positions.len().checked_div(n_targets).unwrap_or(0);
    let step = frames.div_ceil(512).max(1);
    let mut spans: Vec<f64> = (0..frames)
        .step_by(step)
        .map(|f| frame_span(&positions[f * n_targets..(f + 1) * n_targets]))
        .collect();
    spans.sort_by(f64::total_cmp);
    spans.get(spans.len() / 2).copied().unwrap_or(0.0)
}

/// The largest distance between two finite points.
pub(crate) fn frame_span(points: &[Vec3]) -> f64 {
    let mut best = 0.0_f64;
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            let d = (a - b).norm_squared();
            if d.is_finite() {
                best = best.max(d);
            }
        }
    }
    best.sqrt()
}

/// Scales file-unit positions to metres, checks the implied height, and builds the motion.
pub(crate) fn finish_motion(
    source: &str,
    names: &[&str],
    rate_hz: f64,
    unit: LengthUnit,
    mut positions: Vec<Vec3>,
) -> crate::Result<Motion> {
    let scale = unit.metres();
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(Error::invalid(
            "unit",
            format!("{scale} m per unit must be positive"),
        ));
    }
    if !(rate_hz > 0.0 && rate_hz.is_finite()) {
        return Err(motion_error(
            source,
            "frame rate".into(),
            format!("{rate_hz} Hz must be positive and finite"),
        ));
    }
    for p in &mut positions {
        *p *= scale;
    }
    check_plausible_height(source, implied_height(names.len(), &positions), unit)?;
    Motion::uniform(
        source,
        names.iter().map(|s| s.to_string()).collect(),
        rate_hz,
        positions,
    )
}

/// A `new_joints` clip (T×22×3) from an array; `source` names it in errors.
pub fn from_joints(
    array: ArrayViewD<'_, f64>,
    source: &str,
    options: &Options,
) -> crate::Result<Motion> {
    if options.normalization.is_some() {
        return Err(Error::invalid(
            "normalization",
            "applies to the feature form (new_joint_vecs), not to joint positions",
        ));
    }
    let positions = joints_from_array_raw(array, source, &JOINT_NAMES)?;
    finish_motion(
        source,
        &JOINT_NAMES,
        options.rate_hz,
        options.unit,
        positions,
    )
}

/// A `new_joint_vecs` clip (T×263) from an array, joints recovered from the features.
pub fn from_features(
    array: ArrayViewD<'_, f64>,
    source: &str,
    options: &Options,
) -> crate::Result<Motion> {
    let positions =
        features_from_array_raw(array, source, &JOINT_NAMES, options.normalization.as_ref())?;
    finish_motion(
        source,
        &JOINT_NAMES,
        options.rate_hz,
        options.unit,
        positions,
    )
}

/// Either form, told apart by the array's shape (T×22×3 joints or T×263 features).
pub fn from_array(
    array: ArrayViewD<'_, f64>,
    source: &str,
    options: &Options,
) -> crate::Result<Motion> {
    if array.ndim() == 2 {
        from_features(array, source, options)
    } else {
        from_joints(array, source, options)
    }
}

/// Reads a `new_joints` `.npy` file (T×22×3, `float32` or `float64`).
pub fn read_joints(path: &Path, options: &Options) -> crate::Result<Motion> {
    let array = npy::read_array_as_f64(path)?;
    from_joints(array.view(), &path.display().to_string(), options)
}

/// Reads a `new_joint_vecs` `.npy` file (T×263) and recovers the joints.
pub fn read_features(path: &Path, options: &Options) -> crate::Result<Motion> {
    let array = npy::read_array_as_f64(path)?;
    from_features(array.view(), &path.display().to_string(), options)
}

/// Reads either form of HumanML3D `.npy` file, told apart by its shape.
pub fn read(path: &Path, options: &Options) -> crate::Result<Motion> {
    let array = npy::read_array_as_f64(path)?;
    from_array(array.view(), &path.display().to_string(), options)
}
