//! KIT-ML motions (Plappert et al. 2016) as HumanML3D's release of them ships: `new_joints`
//! T×21×3 joint centres at 12.5 fps, y up, and `new_joint_vecs` T×251 features (the
//! HumanML3D feature layout for 21 joints, recovered as in [`super::humanml3d`]).
//!
//! Joint order and names. The order is the one of HumanML3D's `paramUtil.py`
//! (`kit_kinematic_chain` = `[0,11,12,13,14,15], [0,16,17,18,19,20], [0,1,2,3,4], [3,5,6,7],
//! [3,8,9,10]`); the names are the Master Motor Map (MMM) reference model's joint names that
//! KIT's data files use, in that order (as listed by the MDM and TEMOS projects, which read
//! the same files; the joint positions came from MMM forward kinematics in the
//! language2pose project):
//!
//! | # | name | joint | # | name | joint |
//! |---|---|---|---|---|---|
//! | 0 | `root` | pelvis (root segment) | 11 | `LH` | left hip |
//! | 1 | `BP` | lower spine (pelvis–abdomen) | 12 | `LK` | left knee |
//! | 2 | `BT` | upper spine (thorax) | 13 | `LA` | left ankle |
//! | 3 | `BLN` | lower neck | 14 | `LMrot` | left metatarsal (ball of the foot) |
//! | 4 | `BUN` | upper neck (head) | 15 | `LF` | left toe tip |
//! | 5 | `LS` | left shoulder | 16 | `RH` | right hip |
//! | 6 | `LE` | left elbow | 17 | `RK` | right knee |
//! | 7 | `LW` | left wrist | 18 | `RA` | right ankle |
//! | 8 | `RS` | right shoulder | 19 | `RMrot` | right metatarsal |
//! | 9 | `RE` | right elbow | 20 | `RF` | right toe tip |
//! | 10 | `RW` | right wrist | | | |
//!
//! (HumanML3D's processing code calls joints 11 and 5 the *right* hip and shoulder when it
//! computes the facing direction; the MMM names, which language2pose's own left/right tables
//! agree with, are kept here.)
//!
//! Units. KIT's raw MMM data are in millimetres, and HumanML3D's KIT-ML `new_joints` keep
//! that millimetre scale (they were computed from the raw millimetre root trajectory; the
//! projects that plot them scale KIT by 0.003 where they scale HumanML3D's metres by 1.3).
//! With [`Options::unit`] `None` the unit is detected from the implied body height
//! ([`super::humanml3d::implied_height`]): metres if that is a person's height in metres,
//! millimetres if it is one in millimetres, an error otherwise. An explicit unit is checked
//! the same way ([`super::check_plausible_height`]).

use super::humanml3d::{
    Normalization, features_from_array_raw, finish_motion, implied_height, joints_from_array_raw,
};
use super::{LengthUnit, Motion, PLAUSIBLE_HEIGHT_M};
use crate::error::Error;
use crate::spatial::Vec3;
use ndarray::ArrayViewD;
use std::path::Path;

/// KIT-ML's frame rate in HumanML3D's release (Hz).
pub const RATE_HZ: f64 = 12.5;

/// The 21 MMM joint names in KIT-ML's order (see the module documentation).
pub const JOINT_NAMES: [&str; 21] = [
    "root", "BP", "BT", "BLN", "BUN", "LS", "LE", "LW", "RS", "RE", "RW", "LH", "LK", "LA",
    "LMrot", "LF", "RH", "RK", "RA", "RMrot", "RF",
];

/// What each of [`JOINT_NAMES`] is.
pub const JOINT_DESCRIPTIONS: [&str; 21] = [
    "pelvis (root segment)",
    "lower spine (pelvis-abdomen)",
    "upper spine (thorax)",
    "lower neck",
    "upper neck (head)",
    "left shoulder",
    "left elbow",
    "left wrist",
    "right shoulder",
    "right elbow",
    "right wrist",
    "left hip",
    "left knee",
    "left ankle",
    "left metatarsal (ball of the foot)",
    "left toe tip",
    "right hip",
    "right knee",
    "right ankle",
    "right metatarsal (ball of the foot)",
    "right toe tip",
];

/// `kit_kinematic_chain` of HumanML3D's `paramUtil.py`: left leg, right leg, spine to head,
/// left arm, right arm.
pub const KINEMATIC_CHAINS: [&[usize]; 5] = [
    &[0, 11, 12, 13, 14, 15],
    &[0, 16, 17, 18, 19, 20],
    &[0, 1, 2, 3, 4],
    &[3, 5, 6, 7],
    &[3, 8, 9, 10],
];

/// Parent of each joint, from [`KINEMATIC_CHAINS`] (the root has none).
pub const PARENTS: [Option<usize>; 21] = [
    None,
    Some(0),
    Some(1),
    Some(2),
    Some(3),
    Some(3),
    Some(5),
    Some(6),
    Some(3),
    Some(8),
    Some(9),
    Some(0),
    Some(11),
    Some(12),
    Some(13),
    Some(14),
    Some(0),
    Some(16),
    Some(17),
    Some(18),
    Some(19),
];

/// Number of features per frame (251).
pub const N_FEATURES: usize = super::humanml3d::n_features(21);

/// How a KIT-ML clip is read.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Frame rate (Hz); KIT-ML's (HumanML3D release) is 12.5.
    pub rate_hz: f64,
    /// Length unit of the values; `None` detects metres or millimetres from the implied
    /// body height.
    pub unit: Option<LengthUnit>,
    /// De-normalisation of the features (the feature form only).
    pub normalization: Option<Normalization>,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            rate_hz: RATE_HZ,
            unit: None,
            normalization: None,
        }
    }
}

/// The unit that makes `height` (in file units) a person's height: metres or millimetres.
pub fn detect_unit(height: f64) -> Option<LengthUnit> {
    let [lo, hi] = PLAUSIBLE_HEIGHT_M;
    [LengthUnit::Metres, LengthUnit::Millimetres]
        .into_iter()
        .find(|u| (lo..=hi).contains(&(height * u.metres())))
}

fn resolve_unit(
    source: &str,
    positions: &[Vec3],
    unit: Option<LengthUnit>,
) -> crate::Result<LengthUnit> {
    if let Some(u) = unit {
        return Ok(u);
    }
    let height = implied_height(JOINT_NAMES.len(), positions);
    detect_unit(height).ok_or_else(|| Error::Motion {
        file: source.to_string(),
        location: "skeleton".into(),
        message: format!(
            "implied body height is {height:.4} file units: neither metres nor millimetres make \
             it a person's ({}–{} m); give the unit explicitly",
            PLAUSIBLE_HEIGHT_M[0], PLAUSIBLE_HEIGHT_M[1]
        ),
    })
}

/// A `new_joints` clip (T×21×3) from an array; `source` names it in errors.
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
    let unit = resolve_unit(source, &positions, options.unit)?;
    finish_motion(source, &JOINT_NAMES, options.rate_hz, unit, positions)
}

/// A `new_joint_vecs` clip (T×251) from an array, joints recovered from the features.
pub fn from_features(
    array: ArrayViewD<'_, f64>,
    source: &str,
    options: &Options,
) -> crate::Result<Motion> {
    let positions =
        features_from_array_raw(array, source, &JOINT_NAMES, options.normalization.as_ref())?;
    let unit = resolve_unit(source, &positions, options.unit)?;
    finish_motion(source, &JOINT_NAMES, options.rate_hz, unit, positions)
}

/// Either form, told apart by the array's rank (T×21×3 joints or T×251 features).
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

/// Reads a KIT-ML `.npy` file of either form (`float32` or `float64`).
pub fn read(path: &Path, options: &Options) -> crate::Result<Motion> {
    let array = super::npy::read_array_as_f64(path)?;
    from_array(array.view(), &path.display().to_string(), options)
}
