//! The metrics of one clip (definitions in the module documentation of [`super`]).

use super::capacity::{CapacityCurves, capacity_at, isometric_forces};
use super::{ClipMetrics, EvaluateOptions, RangeExcess};
use crate::dynamics::{self, Data};
use crate::loss::tensor_file::{TensorFrames, residual_of};
use crate::model::Model;
use crate::motion::npy::read_npz_as_f64;
use crate::muscle::MuscleSet;
use crate::muscle::path::{PathData, compute_paths};
use crate::solve::contact::ContactSet;
use crate::spatial::Vec3;
use std::path::Path;

/// A control signal: targets for the joint centres at some frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Control {
    pub frames: usize,
    /// T × J × 3 targets (m, ground), joints in `Model::joints` order.
    pub joint_pos: Vec<f64>,
    /// T × J, true where the target applies.
    pub mask: Vec<bool>,
}

impl Control {
    /// Reads a control file (`joint_pos` T × J × 3 and `mask` T × J, nonzero = controlled)
    /// for `model`.
    pub fn read(path: &Path, model: &Model) -> crate::Result<Control> {
        let source = path.display().to_string();
        let bad = |m: String| crate::Error::invalid("control file", format!("{source}: {m}"));
        let arrays = read_npz_as_f64(path)?;
        let find = |name: &str| {
            arrays
                .iter()
                .find(|(k, _)| k == name)
                .map(|(_, a)| a)
                .ok_or_else(|| bad(format!("has no array `{name}`")))
        };
        let (pos, mask) = (find("joint_pos")?, find("mask")?);
        let nj = model.joints.len();
        if pos.ndim() != 3 || pos.shape()[1] != nj || pos.shape()[2] != 3 {
            return Err(bad(format!(
                "`joint_pos` has shape {:?}; the model \"{}\" needs T × {nj} × 3",
                pos.shape(),
                model.name
            )));
        }
        let frames = pos.shape()[0];
        if mask.shape() != [frames, nj] {
            return Err(bad(format!(
                "`mask` has shape {:?}; expected {frames} × {nj}",
                mask.shape()
            )));
        }
        let joint_pos: Vec<f64> = pos.iter().copied().collect();
        let mask: Vec<bool> = mask.iter().map(|&m| m != 0.0).collect();
        if let Some(i) = (0..frames * nj)
            .find(|&i| mask[i] && !joint_pos[3 * i..3 * i + 3].iter().all(|v| v.is_finite()))
        {
            return Err(bad(format!(
                "frame {}, joint {}: a controlled target is not finite",
                i / nj,
                model.joints[i % nj].name
            )));
        }
        Ok(Control {
            frames,
            joint_pos,
            mask,
        })
    }
}

/// How the joint capacities are found.
#[derive(Clone, Copy, Debug)]
pub enum Capacity<'a> {
    /// From the muscle paths at every frame's pose (exact; also gives the reserve share of a
    /// clip with muscle forces). Costs a muscle-path evaluation per frame.
    PerFrame,
    /// From the model's joint strength curves (one lookup per coordinate and frame; no
    /// reserve share).
    Curves(&'a CapacityCurves),
}

/// The metrics of the clip `name` (its tensors `frames`, read for `model`), against a
/// `reference` clip and a `control` signal when given.
pub fn evaluate_clip(
    model: &Model,
    name: &str,
    frames: &TensorFrames,
    reference: Option<&TensorFrames>,
    control: Option<&Control>,
    capacity: Capacity,
    options: &EvaluateOptions,
) -> crate::Result<ClipMetrics> {
    options.validate()?;
    let rate = check_frames(name, frames, reference, control)?;
    let clip = ClipModel::new(model, name, frames)?;
    let sums = frame_pass(&clip, control, capacity, options)?;
    let contact = contact_metrics(&clip.set, &sums.lowest, &sums.support, rate, options);
    let (el_residual, el_residual_from_q) = residuals(model, frames)?;
    let (range_share, range_worst) = beyond_range(model, &frames.q, &clip.joints, options);
    let (t_count, mass) = (frames.frames, clip.mass);
    let mut metrics = ClipMetrics {
        clip: name.to_string(),
        frames: t_count,
        rate_hz: rate,
        body_mass: mass,
        support_fraction: contact.support_fraction,
        skate: contact.skate,
        skate_speed: contact.skate_speed,
        float: contact.float,
        float_max: contact.float_max,
        penetrate: contact.penetrate,
        penetrate_max: contact.penetrate_max,
        el_residual,
        el_residual_from_q,
        range_share,
        range_worst,
        layout_fit_error: frames.layout_error,
        ..ClipMetrics::default()
    };
    let a = &sums.actuation;
    if a.samples > 0 {
        metrics.actuation_excess = Some(a.excess / a.samples as f64 / mass);
        metrics.actuation_over = Some(a.over as f64 / a.samples as f64);
        metrics.actuation_peak = Some(a.peak);
    }
    if clip.with_forces && a.tau_abs > 0.0 {
        metrics.reserve_share = Some(a.reserve_abs / a.tau_abs);
    }
    if clip.with_act {
        let e: f64 = frames
            .muscle_act
            .iter()
            .map(|a| (a - 1.0).max(0.0) + (-a).max(0.0))
            .sum();
        metrics.activation_excess = Some(e / frames.muscle_act.len() as f64);
    }
    if let Some(reference) = reference {
        reference_errors(&clip, reference, &mut metrics);
    }
    if control.is_some() {
        let c = &sums.control;
        metrics.trajectory_failed = Some(c.failed > 0);
        if c.samples > 0 {
            metrics.location_failure = Some(c.failed as f64 / c.samples as f64);
            metrics.trajectory_error = Some(c.sum / c.samples as f64);
        }
    }
    Ok(metrics)
}

/// The frame rate of the clip, after checking it has ≥ 2 frames, as many as its reference
/// and its control signal.
fn check_frames(
    name: &str,
    frames: &TensorFrames,
    reference: Option<&TensorFrames>,
    control: Option<&Control>,
) -> crate::Result<f64> {
    let bad = |m: String| crate::Error::invalid("clip", format!("{name}: {m}"));
    let t_count = frames.frames;
    if t_count < 2 {
        return Err(bad(format!("{t_count} frame(s); the metrics need ≥ 2")));
    }
    let rate = frames.rate_hz().map_err(|e| bad(e.to_string()))?;
    if let Some(r) = reference
        && r.frames != t_count
    {
        return Err(bad(format!(
            "has {t_count} frames, its reference {}",
            r.frames
        )));
    }
    if let Some(c) = control
        && c.frames != t_count
    {
        return Err(bad(format!(
            "has {t_count} frames, its control {}",
            c.frames
        )));
    }
    Ok(rate)
}

/// The clip with what the metrics need of its model: the contact spheres, the muscles, the
/// joint coordinates, the body mass and weight.
struct ClipModel<'a> {
    model: &'a Model,
    frames: &'a TensorFrames,
    /// The model's contact spheres (gait2392-like feet without them get the standard points).
    set: ContactSet,
    muscles: MuscleSet,
    /// The independent coordinates outside the floating base.
    joints: Vec<usize>,
    /// Body mass (kg) and weight (N).
    mass: f64,
    weight: f64,
    /// The file has muscle forces / activations of every muscle.
    with_forces: bool,
    with_act: bool,
}

impl<'a> ClipModel<'a> {
    /// Refuses a weightless model.
    fn new(model: &'a Model, name: &str, frames: &'a TensorFrames) -> crate::Result<Self> {
        let n = model.nq();
        let set = crate::augment::chain::contact_set(model)?;
        let mass = model.total_mass();
        let weight = mass * model.gravity.norm();
        if let Some(why) = model.weightless() {
            return Err(crate::Error::invalid("clip", format!("{name}: {why}")));
        }
        let muscles = MuscleSet::new(model)?;
        let m = muscles.muscles.len();
        let joints: Vec<usize> = (0..n).filter(|j| !set.floating_base.contains(j)).collect();
        let t_count = frames.frames;
        Ok(ClipModel {
            model,
            frames,
            with_forces: m > 0 && frames.muscle_force.len() == t_count * m,
            with_act: m > 0 && frames.muscle_act.len() == t_count * m,
            set,
            muscles,
            joints,
            mass,
            weight,
        })
    }
}

/// The joint actuation beyond the muscles' capacity and the reserves, summed over the
/// frames and joint coordinates.
#[derive(Default)]
struct ActuationSums {
    /// Σ max(0, |τ_j| − C_j) over the samples with some capacity, their count, how many
    /// exceed it, and the largest |τ_j| / C_j.
    excess: f64,
    over: usize,
    peak: f64,
    samples: usize,
    /// Σ |τ_j − Σ_k r_jk F_k| and Σ |τ_j| (with muscle forces and per-frame capacity).
    reserve_abs: f64,
    tau_abs: f64,
}

/// The distances of the controlled joint centres from their targets.
#[derive(Default)]
struct ControlSums {
    samples: usize,
    /// Samples farther than the control threshold.
    failed: usize,
    /// Σ distance (m).
    sum: f64,
}

/// What one pass over the frames gathers.
struct FrameSums {
    /// [f * np + p]: the lowest point b_p of contact sphere p in frame f (ground).
    lowest: Vec<Vec3>,
    /// Per frame: the motion needs an external force above the support threshold.
    support: Vec<bool>,
    actuation: ActuationSums,
    control: ControlSums,
}

/// The muscles' state in the per-frame pass: path data and isometric forces.
struct MuscleScratch {
    paths: PathData,
    f_iso: Vec<f64>,
}

/// Every frame's kinematics (q, q̇, q̈), then its support, the spheres' lowest points, the
/// actuation against capacity and the control targets' errors.
fn frame_pass(
    clip: &ClipModel,
    control: Option<&Control>,
    capacity: Capacity,
    options: &EvaluateOptions,
) -> crate::Result<FrameSums> {
    let (model, frames, set) = (clip.model, clip.frames, &clip.set);
    let (t_count, n, np) = (frames.frames, model.nq(), set.points.len());
    let normal = set.floor_normal;
    let mut data = Data::new(model);
    let mut scratch = MuscleScratch {
        paths: PathData::new(model, &clip.muscles.paths),
        f_iso: vec![0.0; clip.muscles.muscles.len()],
    };
    let mut sums = FrameSums {
        lowest: vec![Vec3::zeros(); t_count * np],
        support: vec![false; t_count],
        actuation: ActuationSums::default(),
        control: ControlSums::default(),
    };
    for f in 0..t_count {
        let r = f * n..(f + 1) * n;
        dynamics::forward_kinematics_acceleration(
            model,
            &mut data,
            &frames.q[r.clone()],
            &frames.qd[r.clone()],
            &frames.qdd[r],
        )?;
        // F = Σ m_b a_b − M g, the external force the motion needs
        let mut force = -model.gravity * clip.mass;
        for (b, body) in model.bodies.iter().enumerate().skip(1) {
            if body.mass > 0.0 {
                force += data.point_acceleration(b, &body.com_in_body).1 * body.mass;
            }
        }
        sums.support[f] = normal.dot(&force) > options.support_threshold * clip.weight;
        // b_p = c_p − r_p n
        for (p, point) in set.points.iter().enumerate() {
            sums.lowest[f * np + p] =
                data.point_position(point.body, &point.location_in_body) - normal * point.radius;
        }
        if !clip.muscles.muscles.is_empty() && !clip.joints.is_empty() {
            actuation_at(clip, f, &data, &mut scratch, capacity, &mut sums.actuation)?;
        }
        if let Some(c) = control {
            control_at(model, &data, c, f, options, &mut sums.control);
        }
    }
    Ok(sums)
}

/// Frame `f` (its kinematics in `data`): per joint coordinate the capacity C±_j (from the
/// paths or the strength curves) and the torque beyond it, and with per-frame capacity and
/// muscle forces the reserve τ_j − Σ_k r_jk F_k.
fn actuation_at(
    clip: &ClipModel,
    f: usize,
    data: &Data,
    scratch: &mut MuscleScratch,
    capacity: Capacity,
    sums: &mut ActuationSums,
) -> crate::Result<()> {
    let (model, frames) = (clip.model, clip.frames);
    let (n, m) = (model.nq(), clip.muscles.muscles.len());
    let r = f * n..(f + 1) * n;
    let per_frame = matches!(capacity, Capacity::PerFrame);
    if per_frame {
        compute_paths(model, data, &clip.muscles.paths, &mut scratch.paths)?;
        isometric_forces(&clip.muscles, &scratch.paths, &mut scratch.f_iso);
    }
    let (q, tau) = (&frames.q[r.clone()], &frames.tau[r]);
    for &j in &clip.joints {
        // C±_j, and beyond it max(0, |τ_j| − C^{sign τ_j}_j)
        let (up, down) = match capacity {
            Capacity::PerFrame => capacity_at(&scratch.paths, &scratch.f_iso, j),
            Capacity::Curves(curves) => curves.at(j, q[j]).unwrap_or((0.0, 0.0)),
        };
        let capacity = if tau[j] >= 0.0 { up } else { down };
        if up + down > 0.0 {
            sums.samples += 1;
            let beyond = tau[j].abs() - capacity;
            if beyond > 0.0 {
                sums.over += 1;
                sums.excess += beyond;
            }
            if capacity > 0.0 {
                sums.peak = sums.peak.max(tau[j].abs() / capacity);
            }
        }
        if clip.with_forces && per_frame {
            // reserve_j = τ_j − Σ_k r_jk F_k
            let forces = &frames.muscle_force[f * m..(f + 1) * m];
            let carried: f64 = (0..m)
                .map(|k| scratch.paths.moment_arms[(j, k)] * forces[k])
                .sum();
            sums.reserve_abs += (tau[j] - carried).abs();
            sums.tau_abs += tau[j].abs();
        }
    }
    Ok(())
}

/// Frame `f` (its kinematics in `data`): the distance of each controlled joint centre from
/// its target.
fn control_at(
    model: &Model,
    data: &Data,
    c: &Control,
    f: usize,
    options: &EvaluateOptions,
    sums: &mut ControlSums,
) {
    for (j, joint) in model.joints.iter().enumerate() {
        let i = f * model.joints.len() + j;
        if !c.mask[i] {
            continue;
        }
        let p = data.point_position(joint.child_body, &joint.child_offset.pos);
        let target = Vec3::new(
            c.joint_pos[3 * i],
            c.joint_pos[3 * i + 1],
            c.joint_pos[3 * i + 2],
        );
        let e = (p - target).norm();
        sums.samples += 1;
        sums.sum += e;
        if e > options.control_threshold {
            sums.failed += 1;
        }
    }
}

/// The metrics of the contact spheres' heights and horizontal motion.
struct ContactMetrics {
    support_fraction: f64,
    skate: f64,
    skate_speed: f64,
    float: f64,
    float_max: f64,
    penetrate: f64,
    penetrate_max: f64,
}

/// Support, skating, floating and penetration from the spheres' `lowest` points and the
/// frames' `support`.
fn contact_metrics(
    set: &ContactSet,
    lowest: &[Vec3],
    support: &[bool],
    rate: f64,
    options: &EvaluateOptions,
) -> ContactMetrics {
    let (t_count, np, normal) = (support.len(), set.points.len(), set.floor_normal);
    // raw heights n·b_p, the lowest per frame, the clip's ground level g (the 5th percentile
    // of the lowest heights over the supported frames, all frames without support) and the
    // floor (given, or g)
    let raw_min: Vec<f64> = (0..t_count)
        .map(|f| {
            lowest[f * np..(f + 1) * np]
                .iter()
                .map(|b| normal.dot(b))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let mut levels: Vec<f64> = (0..t_count)
        .filter(|&f| support[f])
        .map(|f| raw_min[f])
        .collect();
    if levels.is_empty() {
        levels = raw_min.clone();
    }
    levels.sort_by(f64::total_cmp);
    let ground = levels[(0.05 * (levels.len() - 1) as f64).round() as usize];
    let floor = options.floor_height.unwrap_or(ground);
    // h_min(t) above the floor
    let h_min: Vec<f64> = raw_min.iter().map(|h| h - floor).collect();
    let supported = support.iter().filter(|s| **s).count();
    let (mut float_sum, mut float_max) = (0.0, 0.0f64);
    for f in (0..t_count).filter(|&f| support[f]) {
        let v = h_min[f].max(0.0);
        float_sum += v;
        float_max = float_max.max(v);
    }
    let depth: Vec<f64> = h_min.iter().map(|h| (-h).max(0.0)).collect();
    let (skate, skate_speed) = skating(set, lowest, ground, support, rate, options);
    ContactMetrics {
        support_fraction: supported as f64 / t_count as f64,
        skate,
        skate_speed,
        float: if supported > 0 {
            float_sum / supported as f64
        } else {
            0.0
        },
        float_max,
        penetrate: depth.iter().sum::<f64>() / t_count as f64,
        penetrate_max: depth.iter().fold(0.0, |a, b| a.max(*b)),
    }
}

/// The median relative Euler–Lagrange residual of the clip, and the same with q̇, q̈
/// differentiated from q alone; none for a layout-only file without contact forces (the
/// ground's forces missing).
fn residuals(model: &Model, frames: &TensorFrames) -> crate::Result<(Option<f64>, Option<f64>)> {
    if frames.layout_error.is_some() && frames.contact_force.is_empty() {
        return Ok((None, None));
    }
    let el_residual = median(&residual_of(model, frames)?.frame_relative);
    let (qd, qdd) = differentiate(&frames.q, &frames.time, model.nq());
    let from_q = TensorFrames {
        qd,
        qdd,
        ..frames.clone()
    };
    let from_q = median(&residual_of(model, &from_q)?.frame_relative);
    Ok((Some(el_residual), Some(from_q)))
}

/// The errors against a reference clip: joint actuation (RMS per kg) and contact force
/// (per body weight), into `metrics`.
fn reference_errors(clip: &ClipModel, reference: &TensorFrames, metrics: &mut ClipMetrics) {
    let (frames, set, joints) = (clip.frames, &clip.set, &clip.joints);
    let (t_count, n) = (frames.frames, clip.model.nq());
    // RMS of τ_j − τ_j,ref over frames and joint coordinates, per kg
    if !joints.is_empty() {
        let mut s = 0.0;
        for f in 0..t_count {
            for &j in joints {
                let d = frames.tau[f * n + j] - reference.tau[f * n + j];
                s += d * d;
            }
        }
        metrics.actuation_error = Some((s / (t_count * joints.len()) as f64).sqrt() / clip.mass);
    }
    let groups = set.groups().len();
    if let (Some(a), Some(b)) = (group_forces(frames, set), group_forces(reference, set)) {
        // mean over frames of Σ_g ‖F_g − F_g,ref‖ / body weight
        let total: f64 = (0..t_count)
            .map(|f| {
                (0..groups)
                    .map(|g| {
                        let i = 3 * (f * groups + g);
                        let d = |v: &[f64]| Vec3::new(v[i], v[i + 1], v[i + 2]);
                        (d(&a) - d(&b)).norm()
                    })
                    .sum::<f64>()
                    / clip.weight
            })
            .sum();
        metrics.contact_force_error = Some(total / t_count as f64);
    }
}

/// T × G × 3 ground force per contact group of `set`: the file's `grf` when it has one for
/// these groups (the estimate's sums or the measured loads), else the sums of its
/// `contact_point_force` over each group's spheres; None when it has neither.
fn group_forces(frames: &TensorFrames, set: &ContactSet) -> Option<Vec<f64>> {
    let groups = set.groups().len();
    if frames.groups == groups && !frames.grf.is_empty() {
        return Some(frames.grf.clone());
    }
    let np = set.points.len();
    if frames.contacts != np || frames.lambda.is_empty() {
        return None;
    }
    let mut out = vec![0.0; frames.frames * groups * 3];
    for f in 0..frames.frames {
        for p in 0..np {
            let g = set.group_of(p);
            for k in 0..3 {
                out[3 * (f * groups + g) + k] += frames.lambda[3 * (f * np + p) + k];
            }
        }
    }
    Some(out)
}

/// The skating ratio and the mean in-contact horizontal speed of the foot groups' spheres.
fn skating(
    set: &ContactSet,
    lowest: &[Vec3],
    ground: f64,
    support: &[bool],
    rate: f64,
    options: &EvaluateOptions,
) -> (f64, f64) {
    let np = set.points.len();
    let t_count = support.len();
    let pairs = t_count - 1;
    let normal = set.floor_normal;
    let feet: Vec<usize> = (0..np)
        .filter(|&p| set.points[p].group.starts_with("foot"))
        .collect();
    // contact per frame: within the band of a supported frame, and either in contact in the
    // frame before or arriving there slowly (a foot lands; one passing at speed swings by);
    // the first frame's spheres within the band are in contact whatever their speed
    let within = |f: usize, p: usize| {
        support[f] && normal.dot(&lowest[f * np + p]) - ground <= options.contact_height
    };
    // u_p(t) = f P(b_p(t+1) − b_p(t)), the horizontal velocity over a pair
    let horizontal = |t: usize, p: usize| {
        let d = lowest[(t + 1) * np + p] - lowest[t * np + p];
        (d - normal * normal.dot(&d)) * rate
    };
    // the floor's velocity: given, or the clip's own (per axis, the median of u_p over the
    // pairs with the sphere in the band at both frames: a treadmill's belt)
    let floor = match options.floor_velocity {
        Some(v) => v - normal * normal.dot(&v),
        None => {
            let low: Vec<Vec3> = (0..pairs)
                .flat_map(|t| feet.iter().map(move |&p| (t, p)))
                .filter(|&(t, p)| within(t, p) && within(t + 1, p))
                .map(|(t, p)| horizontal(t, p))
                .collect();
            let axis = |k: usize| median(&low.iter().map(|u| u[k]).collect::<Vec<f64>>());
            Vec3::new(axis(0), axis(1), axis(2))
        }
    };
    // v_p(t) = ‖u_p(t) − P v_floor‖
    let mut speed = vec![0.0; pairs * feet.len()];
    for t in 0..pairs {
        for (i, &p) in feet.iter().enumerate() {
            speed[t * feet.len() + i] = (horizontal(t, p) - floor).norm();
        }
    }
    let mut in_contact = vec![false; t_count * feet.len()];
    for (i, &p) in feet.iter().enumerate() {
        in_contact[i] = within(0, p);
        for f in 1..t_count {
            let before = in_contact[(f - 1) * feet.len() + i];
            in_contact[f * feet.len() + i] =
                within(f, p) && (before || speed[(f - 1) * feet.len() + i] <= options.skate_speed);
        }
    }
    let contact: Vec<bool> = (0..pairs * feet.len())
        .map(|k| in_contact[k] && in_contact[k + feet.len()])
        .collect();
    let half = options.skate_window / 2;
    let (mut skating_pairs, mut speed_sum, mut speed_samples) = (0usize, 0.0, 0usize);
    for t in 0..pairs {
        let mut skates = false;
        for i in 0..feet.len() {
            if !contact[t * feet.len() + i] {
                continue;
            }
            let v = speed[t * feet.len() + i];
            speed_sum += v;
            speed_samples += 1;
            // the window's mean, pairs outside the clip counting as 0
            let window: f64 = (t.saturating_sub(half)..=(t + half).min(pairs - 1))
                .map(|s| speed[s * feet.len() + i])
                .sum::<f64>()
                / options.skate_window as f64;
            if v > options.skate_speed && window > options.skate_speed {
                skates = true;
            }
        }
        if skates {
            skating_pairs += 1;
        }
    }
    let ratio = if pairs > 0 {
        skating_pairs as f64 / pairs as f64
    } else {
        0.0
    };
    let mean = if speed_samples > 0 {
        speed_sum / speed_samples as f64
    } else {
        0.0
    };
    (ratio, mean)
}

/// The median of `values` (0 for none).
/// q̇ and q̈ of the T × n coordinates `q` sampled at `time`, by finite differences: inside,
/// the three-point formulas for unequal steps h₋ = t_i − t_{i−1}, h₊ = t_{i+1} − t_i,
///
///   q̇_i = (h₋² q_{i+1} + (h₊² − h₋²) q_i − h₊² q_{i−1}) / (h₋ h₊ (h₋ + h₊)),
///   q̈_i = 2 (h₋ q_{i+1} − (h₋ + h₊) q_i + h₊ q_{i−1}) / (h₋ h₊ (h₋ + h₊))
///
/// (second-order accurate; the familiar central differences for equal steps); at the ends
/// q̇ from the one-sided difference and q̈ copied from the neighbour (q̈ = 0 for two frames).
pub fn differentiate(q: &[f64], time: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let t_count = time.len();
    let (mut qd, mut qdd) = (vec![0.0; t_count * n], vec![0.0; t_count * n]);
    if t_count < 2 {
        return (qd, qdd);
    }
    for i in 1..t_count - 1 {
        let (hm, hp) = (time[i] - time[i - 1], time[i + 1] - time[i]);
        let d = hm * hp * (hm + hp);
        for j in 0..n {
            let (a, b, c) = (q[(i - 1) * n + j], q[i * n + j], q[(i + 1) * n + j]);
            qd[i * n + j] = (hm * hm * c + (hp * hp - hm * hm) * b - hp * hp * a) / d;
            qdd[i * n + j] = 2.0 * (hm * c - (hm + hp) * b + hp * a) / d;
        }
    }
    let last = t_count - 1;
    for j in 0..n {
        qd[j] = (q[n + j] - q[j]) / (time[1] - time[0]);
        qd[last * n + j] =
            (q[last * n + j] - q[(last - 1) * n + j]) / (time[last] - time[last - 1]);
        if t_count > 2 {
            qdd[j] = qdd[n + j];
            qdd[last * n + j] = qdd[(last - 1) * n + j];
        }
    }
    (qd, qdd)
}

/// The share of (frame, joint coordinate) samples of `q` beyond their coordinate's range by
/// more than the tolerance (`range_tolerance` of the range's width), and the farthest one.
fn beyond_range(
    model: &Model,
    q: &[f64],
    joints: &[usize],
    options: &EvaluateOptions,
) -> (f64, Option<RangeExcess>) {
    let n = model.nq();
    let t_count = q.len() / n.max(1);
    let (mut beyond, mut samples) = (0usize, 0usize);
    let mut worst: Option<RangeExcess> = None;
    for &j in joints {
        let c = &model.coordinates[model.reduction.independent[j]];
        let [lo, hi] = c.range;
        if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
            continue;
        }
        let tolerance = options.range_tolerance * (hi - lo);
        for f in 0..t_count {
            let v = q[f * n + j];
            samples += 1;
            let excess = (lo - v).max(v - hi);
            if excess > tolerance {
                beyond += 1;
                if worst.as_ref().is_none_or(|w| excess > w.excess) {
                    worst = Some(RangeExcess {
                        coordinate: c.name.clone(),
                        frame: f,
                        value: v,
                        range: c.range,
                        excess,
                        rotational: c.motion_type == crate::model::MotionType::Rotational,
                    });
                }
            }
        }
    }
    (beyond as f64 / samples.max(1) as f64, worst)
}

fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let k = v.len() / 2;
    if v.len() % 2 == 1 {
        v[k]
    } else {
        0.5 * (v[k - 1] + v[k])
    }
}
