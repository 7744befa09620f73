//! Physical-plausibility metrics of a motion in musculo's tensor format (an augmented clip, or a
//! generated motion written in the same format): the columns of FlexMotion's tables
//! (`../shared/papers/flexmotion.txt` §4, A.3) computed from the physics, the same way for real
//! and generated data.
//!
//! Every metric is defined here once; units are SI. Per clip of T frames at rate f (Hz), with
//! the model's contact spheres p (centre c_p, radius r_p, floor normal n, floor height h₀):
//!
//! - **lowest point** of a sphere b_p = c_p − r_p n, its **height** h_p = n·b_p − h₀, and the
//!   body's lowest height h_min(t) = min_p h_p(t).
//! - **support**: frame t needs the ground when the external force the motion requires,
//!   F(t) = Σ_b m_b a_b − M g (Newton's law for the whole body: a_b the acceleration of body b's
//!   centre of mass, M the total mass), pushes up by more than `support_threshold` of body
//!   weight: n·F > s·M‖g‖ (default s = 0.2). Free flight and a falling body need no ground.
//! - **Float** (m): the mean over the support frames of max(0, h_min) — how far above the floor
//!   the body's lowest contact geometry is while it must stand on it (PhysDiff's "Float",
//!   Yuan et al. 2023, measured on the model's contact spheres instead of a mesh; support
//!   decided by the physics instead of a height threshold). `float_max`: its largest value.
//! - **Penetrate** (m): the mean over all frames of max(0, −h_min) — the depth of the deepest
//!   contact geometry below the floor (PhysDiff's "Penetrate" on the contact spheres, every
//!   body's: feet, hands, pelvis where the model has them). `penetrate_max`: its largest value.
//! - **Skate** (ratio): the foot-skating ratio of GMD/OmniControl (Karunratanakul et al. 2023;
//!   Xie et al. 2023), with their thresholds: a sphere of a foot group (`foot_r`, `foot_l`) is
//!   in contact over the frame pair (t, t+1) when both frames need support and at both its
//!   height is within `contact_height` (5 cm) of the body's lowest height h_min (not of the
//!   floor: a motion lifted off the floor floats, it does not stop its feet's contact — that is
//!   Float's job); its horizontal speed over the pair, relative to the floor, is
//!   v_p(t) = ‖f P(b_p(t+1) − b_p(t)) − P v_floor‖ (P removes the normal component; v_floor the
//!   floor's velocity: zero by default, a treadmill's belt velocity when given, or the clip's
//!   own — per axis the median of f P(b_p(t+1) − b_p(t)) over the pairs where the sphere is in
//!   the contact band at both frames), and its window speed v̄_p(t) the mean of v_p over the
//!   `skate_window` (5) pairs centred on t (pairs outside the clip count as 0, as
//!   `scipy.ndimage.uniform_filter1d(mode="constant")` does in their code). A pair skates when
//!   some in-contact sphere has v_p > `skate_speed` (0.5 m/s) and v̄_p > `skate_speed`;
//!   `skate` is the number of skating pairs over T − 1. `skate_speed`: the mean v_p over the
//!   in-contact (pair, sphere) samples (m/s), the continuous measure behind the ratio.
//! - **Contact Force** (× body weight): with a reference clip (same name, same frames: the
//!   measured loads or the estimate of a reference set), the mean over frames of
//!   Σ_g ‖F_g − F_g,ref‖ / (M‖g‖), F_g the total force of contact group g (the sum of its
//!   spheres' `contact_point_force`). Without a reference, or without contact forces in either
//!   file: not computed.
//! - **Joint Actuation**: against each joint's capacity, the maximum isometric moment of its
//!   muscles in the direction of the torque, C±_j(q) = Σ_k max(0, ±r_jk(q)) F_iso,k(ℓ_k(q))
//!   (r the moment arms, F_iso the tendon force at full activation and zero speed, as
//!   `musculo check` and `musculo muscles` compute it) — by default from the model's joint
//!   strength curves (C±_j as a function of q_j alone, every other coordinate at its default:
//!   [`CapacityCurves`], computed once per model), with [`Capacity::PerFrame`] at each frame's
//!   own pose — compared with τ_j over the
//!   joint coordinates (every independent coordinate but the floating base's, with muscles):
//!   `actuation_excess` the mean over frames and coordinates of max(0, |τ_j| − C^{sign τ_j}_j)
//!   per kg of body mass (N·m/kg; 0 when no torque exceeds what the muscles can give),
//!   `actuation_over` the share of those samples with |τ_j| > C_j, `actuation_peak` the largest
//!   |τ_j| / C_j where C_j > 0. Against a reference clip,
//!   `actuation_error` = the RMS of τ_j − τ_j,ref over frames and joint coordinates divided by
//!   body mass (N·m/kg); this is the "Joint Actuation" column when a reference is given, the
//!   excess otherwise.
//! - **Muscle Limit**: with `muscle_act`, `activation_excess` = the mean over frames and
//!   muscles of max(0, a − 1) + max(0, −a); with `muscle_force` (an augmented clip) and
//!   per-frame capacities, the `reserve_share` Σ|τ_j − Σ_k r_jk F_k| / Σ|τ_j| over frames and joint coordinates — the
//!   part of the joint torques no muscle could carry (activations that would have to exceed 1).
//!   The column is the reserve share when there are muscle forces, the activation excess
//!   otherwise.
//! - **Euler–Lagrange residual**: r = M q̈ + C q̇ + G − τ − J_cᵀλ of the motion as given
//!   ([`crate::loss::tensor_file`]); `el_residual` the median over frames of ‖r_t‖/‖τ_ID,t‖.
//!   A file holding only the per-joint layout has its coordinates fitted from the joint
//!   rotations (`layout_fit_error`: the largest rotation the fit leaves, rad — zero for a
//!   consistent layout, the inconsistency of a generated one otherwise); its residual is that
//!   of [`crate::loss::layout`] (the layout's contact forces at the joint centres with the best
//!   couple on each foot), None when the file has no `contact_force`.
//! - **Trajectory** (with a control): at the controlled samples (frame, joint) of a control
//!   file (`joint_pos` T × J × 3 targets, `mask` T × J, nonzero = controlled), the joint
//!   centres' errors e = ‖p_j(q_t) − target‖ (m): `trajectory_failed` when any e exceeds
//!   `control_threshold` (0.5 m, OmniControl's), `location_failure` the share of samples above
//!   it, `trajectory_error` the mean e. The set's column is the share of clips that failed
//!   (FlexMotion's "ratio of unsuccessful trajectories").
//!
//! - **Beyond range**: the share of (frame, joint coordinate) samples whose q lies outside its
//!   coordinate's range [min, max] in the model by more than `range_tolerance` (1 %) of the
//!   range's width (`range_share`), and the farthest one (`range_worst`: coordinate, frame,
//!   value, range). A generated motion with a knee at −480° is flagged here whatever its other
//!   figures; IK keeps an augmented clip within the ranges, and the tolerance leaves it the
//!   float32 rounding and the low-pass filter's small overshoot. The set counts the clips with
//!   any sample beyond (of all clips) and names the farthest.
//! - **Euler–Lagrange residual from q**: the residual above with q̇, q̈ differentiated from q
//!   at the file's times ([`differentiate`]: three-point differences) instead of the file's
//!   `qd`, `qdd` (`el_residual_from_q`). A motion whose decoded rates are consistent with
//!   its torques but not with its own trajectory has a small `el_residual` and a large one
//!   here; for an augmented clip the two differ by the differentiation's error.
//!
//! The set summary ([`summarize`]) weighs per-frame metrics by frames (a long clip counts by
//! its length), takes optional metrics over the clips that have them, and the trajectory
//! failure as the share of controlled clips that failed.

mod capacity;
mod clip;
mod set;

pub use capacity::{CapacityCurves, capacity_at, isometric_forces};
pub use clip::{Capacity, Control, differentiate, evaluate_clip};
pub use set::{ClipFile, SetOptions, SetReport, collect, evaluate_set, model_of};

use crate::text::short_number;
use serde::{Deserialize, Serialize};

/// The largest floor height from the data's origin (m): no capture volume spans a kilometre,
/// so a floor beyond it is a unit error (millimetres given as metres), and its heights would
/// print as figures of hundreds of digits.
pub const MAX_FLOOR_HEIGHT: f64 = 1e3;

/// The largest component of the floor's velocity (m/s): ten times the fastest treadmill belt
/// or sprint (about 10 m/s). Beyond it skating speeds are meaningless (10³⁰⁰ gave `inf`).
pub const MAX_FLOOR_SPEED: f64 = 100.0;

/// The largest contact height (m): a foot sphere a metre above the ground level is at a
/// person's hip, never in contact; a larger threshold calls every frame's feet in contact.
pub const MAX_CONTACT_HEIGHT: f64 = 1.0;

/// Thresholds of the metrics (see the module documentation); defaults in [`Default`].
#[derive(Clone, Debug, PartialEq)]
pub struct EvaluateOptions {
    /// Floor height along the normal (m); None: the clip's own ground level. Default
    /// Some(0): the frame the data is in.
    pub floor_height: Option<f64>,
    /// The floor's velocity (m/s, ground frame; its normal component is ignored): Some(0) by
    /// default; a treadmill's belt velocity; None: the clip's own (module documentation).
    pub floor_velocity: Option<crate::spatial::Vec3>,
    /// A foot sphere within this of the clip's ground level can be in contact (m).
    /// Default 0.02.
    pub contact_height: f64,
    /// Skating speed threshold (m/s). Default 0.5.
    pub skate_speed: f64,
    /// Pairs in the moving average of the skating speed (odd). Default 5.
    pub skate_window: usize,
    /// Support needs an upward force above this share of body weight. Default 0.2.
    pub support_threshold: f64,
    /// A controlled joint farther than this from its target fails the trajectory (m).
    /// Default 0.5.
    pub control_threshold: f64,
    /// Capacities from the muscle paths at every frame (and the reserve share of clips with
    /// muscle forces) instead of the joint strength curves: exact, but a muscle-path
    /// evaluation per frame. Default false.
    pub muscles_per_frame: bool,
    /// A joint coordinate counts as beyond its range when it passes an end by more than this
    /// share of the range's width. Default 0.01.
    pub range_tolerance: f64,
}

impl Default for EvaluateOptions {
    fn default() -> Self {
        EvaluateOptions {
            floor_height: Some(0.0),
            floor_velocity: Some(crate::spatial::Vec3::zeros()),
            contact_height: 0.02,
            skate_speed: 0.5,
            skate_window: 5,
            support_threshold: 0.2,
            control_threshold: 0.5,
            muscles_per_frame: false,
            range_tolerance: 0.01,
        }
    }
}

impl EvaluateOptions {
    /// Errors naming the first setting out of its domain.
    pub fn validate(&self) -> crate::Result<()> {
        let checks = [
            (
                "floor_height",
                self.floor_height.unwrap_or(0.0),
                self.floor_height
                    .is_none_or(|h| h.abs() <= MAX_FLOOR_HEIGHT),
                format!("|h| ≤ {MAX_FLOOR_HEIGHT} m"),
            ),
            (
                "contact_height",
                self.contact_height,
                self.contact_height > 0.0 && self.contact_height <= MAX_CONTACT_HEIGHT,
                format!("(0, {MAX_CONTACT_HEIGHT}] m"),
            ),
            (
                "skate_speed",
                self.skate_speed,
                self.skate_speed > 0.0,
                "> 0 m/s".into(),
            ),
            (
                "support_threshold",
                self.support_threshold,
                self.support_threshold >= 0.0,
                "≥ 0".into(),
            ),
            (
                "control_threshold",
                self.control_threshold,
                self.control_threshold > 0.0,
                "> 0 m".into(),
            ),
            (
                "range_tolerance",
                self.range_tolerance,
                self.range_tolerance >= 0.0,
                "≥ 0".into(),
            ),
        ];
        for (name, value, ok, range) in checks {
            if !(ok && value.is_finite()) {
                return Err(crate::Error::invalid(
                    name,
                    format!("{} is out of range (must be {range})", short_number(value)),
                ));
            }
        }
        if let Some(v) = self.floor_velocity
            && !v.iter().all(|x| x.abs() <= MAX_FLOOR_SPEED)
        {
            return Err(crate::Error::invalid(
                "floor_velocity",
                format!(
                    "({}, {}, {}) has a component beyond ±{MAX_FLOOR_SPEED} m/s (or not finite)",
                    short_number(v.x),
                    short_number(v.y),
                    short_number(v.z)
                ),
            ));
        }
        if self.skate_window == 0 || self.skate_window.is_multiple_of(2) {
            return Err(crate::Error::invalid(
                "skate_window",
                format!("{} (must be odd, ≥ 1)", self.skate_window),
            ));
        }
        Ok(())
    }
}

/// The metrics of one clip (see the module documentation for each).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ClipMetrics {
    pub clip: String,
    pub frames: usize,
    pub rate_hz: f64,
    /// Body mass of the model (kg).
    pub body_mass: f64,
    /// Share of frames that need the ground.
    pub support_fraction: f64,
    pub skate: f64,
    pub skate_speed: f64,
    pub float: f64,
    pub float_max: f64,
    pub penetrate: f64,
    pub penetrate_max: f64,
    pub contact_force_error: Option<f64>,
    pub actuation_excess: Option<f64>,
    pub actuation_over: Option<f64>,
    pub actuation_peak: Option<f64>,
    pub actuation_error: Option<f64>,
    pub activation_excess: Option<f64>,
    pub reserve_share: Option<f64>,
    pub el_residual: Option<f64>,
    /// The same residual with q̇ and q̈ differentiated from q ([`differentiate`]) instead of
    /// the file's: a generated motion whose q̇, q̈ disagree with its q shows here.
    #[serde(default)]
    pub el_residual_from_q: Option<f64>,
    /// Share of the (frame, joint coordinate) samples beyond their coordinate's range.
    #[serde(default)]
    pub range_share: f64,
    /// The sample farthest beyond its range.
    #[serde(default)]
    pub range_worst: Option<RangeExcess>,
    /// For a layout-only file: the largest joint-rotation error of the coordinate fit (rad).
    pub layout_fit_error: Option<f64>,
    pub trajectory_failed: Option<bool>,
    pub location_failure: Option<f64>,
    pub trajectory_error: Option<f64>,
    /// What makes the clip's figures less certain (e.g. a file that does not say which model
    /// it belongs to).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl ClipMetrics {
    /// FlexMotion's "Joint Actuation" column for this clip: the error against the reference
    /// when there is one, the capacity excess otherwise.
    pub fn joint_actuation(&self) -> Option<f64> {
        self.actuation_error.or(self.actuation_excess)
    }

    /// FlexMotion's "Muscle Limit" column: the reserve share with muscle forces, the
    /// activation excess otherwise.
    pub fn muscle_limit(&self) -> Option<f64> {
        self.reserve_share.or(self.activation_excess)
    }
}

/// A coordinate value beyond the model's range for it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RangeExcess {
    pub coordinate: String,
    pub frame: usize,
    /// The value (rad or m).
    pub value: f64,
    /// The coordinate's range [min, max] (rad or m).
    pub range: [f64; 2],
    /// How far beyond the range (rad or m).
    pub excess: f64,
    pub rotational: bool,
}

impl RangeExcess {
    /// `knee_angle_r −480.0° (range 0.0…120.0°, frame 12)`.
    pub fn describe(&self) -> String {
        let (k, unit) = if self.rotational {
            (180.0 / std::f64::consts::PI, "°")
        } else {
            (1.0, " m")
        };
        format!(
            "{} {:.1}{unit} (range {:.1}…{:.1}{unit}, frame {})",
            self.coordinate,
            k * self.value,
            k * self.range[0],
            k * self.range[1],
            self.frame
        )
    }
}

/// The set's figures in the columns of FlexMotion's tables (units of [`ClipMetrics`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetSummary {
    pub clips: usize,
    pub frames: usize,
    pub skate: f64,
    pub skate_speed: f64,
    pub float: f64,
    pub penetrate: f64,
    pub contact_force: Option<f64>,
    pub joint_actuation: Option<f64>,
    pub muscle_limit: Option<f64>,
    pub el_residual: Option<f64>,
    /// Share of the controlled clips whose trajectory failed.
    pub trajectory: Option<f64>,
    /// [`ClipMetrics::el_residual_from_q`] over the clips that have it (weighed by frames),
    /// and how many do.
    #[serde(default)]
    pub el_residual_from_q: Option<f64>,
    #[serde(default)]
    pub el_residual_clips: usize,
    /// Clips with a coordinate beyond its range, the share of all samples beyond, and the
    /// farthest sample (clip, excess).
    #[serde(default)]
    pub beyond_range_clips: usize,
    #[serde(default)]
    pub range_share: f64,
    #[serde(default)]
    pub range_worst: Option<(String, RangeExcess)>,
    /// Clips ordered by their Euler–Lagrange residual, worst first (at most 5).
    pub worst_residual: Vec<(String, f64)>,
}

impl SetSummary {
    /// The summary as (column, value with its unit) in FlexMotion's order, "–" where a
    /// metric was not computed: what the CLI prints and the dataset page shows.
    pub fn columns(&self) -> Vec<(&'static str, String)> {
        let o = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or("–".to_string(), f);
        vec![
            ("clips", self.clips.to_string()),
            ("frames", self.frames.to_string()),
            ("Skate", format!("{:.3}", self.skate)),
            ("skate speed", format!("{:.3} m/s", self.skate_speed)),
            ("Float", format!("{:.1} mm", 1e3 * self.float)),
            ("Penetrate", format!("{:.1} mm", 1e3 * self.penetrate)),
            (
                "Contact force",
                o(self.contact_force, &|v| format!("{v:.3} BW")),
            ),
            (
                "Joint actuation",
                o(self.joint_actuation, &|v| format!("{v:.3} N·m/kg")),
            ),
            ("Muscle limit", o(self.muscle_limit, &|v| format!("{v:.3}"))),
            ("EL residual", o(self.el_residual, &|v| format!("{v:.1e}"))),
            ("Trajectory", o(self.trajectory, &|v| format!("{v:.3}"))),
            (
                "EL residual from q",
                o(self.el_residual_from_q, &|v| {
                    format!("{v:.1e} (of {} clip(s))", self.el_residual_clips)
                }),
            ),
            (
                "beyond range",
                format!(
                    "{} of {} clips ({:.2} % of samples{})",
                    self.beyond_range_clips,
                    self.clips,
                    100.0 * self.range_share,
                    self.range_worst
                        .as_ref()
                        .map_or(String::new(), |(clip, w)| format!(
                            "; worst {} in {clip}",
                            w.describe()
                        ))
                ),
            ),
        ]
    }
}

/// The set summary of `clips` (see the module documentation).
pub fn summarize(clips: &[ClipMetrics]) -> SetSummary {
    let frames: usize = clips.iter().map(|c| c.frames).sum();
    let weighted = |f: &dyn Fn(&ClipMetrics) -> f64| {
        let w: f64 = clips.iter().map(|c| c.frames as f64).sum();
        if w == 0.0 {
            0.0
        } else {
            clips.iter().map(|c| f(c) * c.frames as f64).sum::<f64>() / w
        }
    };
    let mean_of = |f: &dyn Fn(&ClipMetrics) -> Option<f64>| {
        let (mut s, mut w) = (0.0, 0.0);
        for c in clips {
            if let Some(v) = f(c) {
                s += v * c.frames as f64;
                w += c.frames as f64;
            }
        }
        (w > 0.0).then(|| s / w)
    };
    let controlled: Vec<bool> = clips.iter().filter_map(|c| c.trajectory_failed).collect();
    let mut worst: Vec<(String, f64)> = clips
        .iter()
        .filter_map(|c| c.el_residual.map(|r| (c.clip.clone(), r)))
        .collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    worst.truncate(5);
    let range_worst = (clips.iter())
        .filter_map(|c| c.range_worst.as_ref().map(|w| (c.clip.clone(), w.clone())))
        .max_by(|a, b| a.1.excess.total_cmp(&b.1.excess));
    SetSummary {
        clips: clips.len(),
        frames,
        skate: weighted(&|c| c.skate),
        skate_speed: weighted(&|c| c.skate_speed),
        float: weighted(&|c| c.float),
        penetrate: weighted(&|c| c.penetrate),
        contact_force: mean_of(&|c| c.contact_force_error),
        joint_actuation: mean_of(&|c| c.joint_actuation()),
        muscle_limit: mean_of(&|c| c.muscle_limit()),
        el_residual: mean_of(&|c| c.el_residual),
        trajectory: (!controlled.is_empty())
            .then(|| controlled.iter().filter(|f| **f).count() as f64 / controlled.len() as f64),
        worst_residual: worst,
        el_residual_from_q: mean_of(&|c| c.el_residual_from_q),
        el_residual_clips: clips
            .iter()
            .filter(|c| c.el_residual_from_q.is_some())
            .count(),
        beyond_range_clips: clips.iter().filter(|c| c.range_worst.is_some()).count(),
        range_share: weighted(&|c| c.range_share),
        range_worst,
    }
}
