//! Inverse kinematics: per frame, the independent coordinates q that best place the model's
//! markers on measured targets (OpenSim's Inverse Kinematics tool, and joint-centre targets
//! from motion datasets).
//!
//! Per frame t the solver minimises, with coordinate bounds lo ≤ q ≤ hi,
//!
//!   f(q) = Σ_i w_i ‖p_i(q) − x_i(t)‖²  +  Σ_c w_c (q_c − q̂_c(t))²  +  s ‖q − q(t−1)‖²
//!
//! (marker tasks, coordinate tasks, and an optional temporal-smoothness weight s). Markers
//! missing in a frame (NaN targets) drop out of that frame's sum. The method is a
//! bound-constrained Levenberg–Marquardt (Gauss–Newton with Marquardt's diagonal damping,
//! Moré 1978) with the projected-Newton active set of Bertsekas (1982):
//!
//!   J_i = ∂p_i/∂q (analytic, reduced coordinates),
//!   H = Σ_i w_i J_iᵀ J_i + Σ_c w_c e_c e_cᵀ + s I,   g = Σ_i w_i J_iᵀ r_i + Σ_c w_c (q_c − q̂_c) e_c + s (q − q_prev),
//!   free set F = { j : not (q_j = lo_j and g_j > 0) and not (q_j = hi_j and g_j < 0) },
//!   (H_FF + μ diag H_FF) δ_F = −g_F,   q ← clamp(q + δ),
//!
//! accepting a step when f decreases (μ scaled by Nielsen's max(1/3, 1 − (2ρ − 1)³), ρ the
//! ratio of the actual to the predicted decrease) and rejecting it otherwise (μ × 4). A frame
//! ends when an accepted step moves no coordinate by more than the tolerance, when f falls
//! by less than `relative_decrease` ([`RELATIVE_DECREASE`] by default) of itself, or when the
//! projected gradient vanishes.
//! The damping μ carries over from frame to frame. Each frame starts from the previous
//! frames' solutions extrapolated at constant velocity (the first from `initial_q` or the
//! model's default pose), then the clip is swept backwards, each frame solved again from the
//! frame after it and the better fit kept (module `backward`), so frames within a clip are
//! sequential; clips run in parallel
//! ([`solve_motions`]) and the result does not depend on the thread count.
//!
//! The marker term's H and g are never formed from Jacobians: Σ w_i J_iᵀ J_i is the inertia
//! matrix of point masses w_i at the markers, built by one composite-rigid-body pass
//! (`normal_equations`); it has the kinematic tree's branch-induced sparsity, which the
//! damped step keeps and factors by [`super::ltl`] (Lᵀ L from the leaves, no fill). Trial
//! points need body poses only.
//!
//! After the first frame no allocation happens: `IkWorkspace` holds every buffer.
//!
//! With [`IkSettings::robust`], a marker that disagrees with the others over the whole clip
//! (mislabelled, swapped, displaced) is down-weighted and the clip solved again
//! ([`robust`]); [`IkSolution::disagreeing`] names it.

use crate::dynamics::Data;
use crate::dynamics::forward_kinematics::{body_poses_only, motion_subspaces};
use crate::error::Error;
use crate::linalg::dot;
use crate::model::reduction::NONE;
use crate::model::{CoordinateRole, Model};
use crate::motion::Motion;
use crate::solve::ltl::EliminationTree;
use crate::spatial::{Force, Mat3, SpatialInertia, Vec3};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use robust::{DisagreeingMarker, RobustMarkers};

mod backward;
pub mod robust;
mod start;
pub use start::{StartOutcome, describe as describe_starts};

// The task types are the motion readers' too (a skeleton map produces them): they live in
// `motion`, below both.
pub use crate::motion::tasks::{CoordinateTask, IkTasks, MarkerTask};

/// A frame ends when an accepted step lowers f by less than this fraction of f. Gauss–Newton
/// converges linearly on real (non-zero-residual) data; at this threshold no single
/// coordinate moved by ±10⁻⁴ lowers f by more than ~10⁻⁸ of itself (tests/ik_datasets.rs
/// probes every frame), while 10⁻⁷ leaves up to 4·10⁻⁵ in poorly determined directions.
pub const RELATIVE_DECREASE: f64 = 1e-8;

/// Which coordinate ranges bound the solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bounds {
    /// Every independent coordinate stays within its range, except the translations of a
    /// joint to ground (see [`floating_base_translation`]).
    Range,
    /// Only coordinates marked `clamped` (OpenSim's IK: the assembler restricts clamped
    /// coordinates to their ranges).
    Clamped,
    /// No bounds.
    None,
}

/// Solver settings; [`IkSettings::default`] documents the defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct IkSettings {
    /// Default [`Bounds::Range`].
    pub bounds: Bounds,
    /// Temporal-smoothness weight s (m² per rad², as the marker terms); default 0.
    pub smoothness: f64,
    /// Iterations per frame (first frame: ten times as many); default 100.
    pub max_iterations: usize,
    /// The largest coordinate step (rad or m) that ends a frame; default 1e-6 (6e-5 degree).
    pub tolerance: f64,
    /// A frame also ends when an accepted step lowers f by less than this fraction of f;
    /// default [`RELATIVE_DECREASE`]. A larger value stops earlier in Gauss–Newton's linear
    /// tail on real data, whose last steps mostly move poorly determined coordinates (a
    /// forearm's roll seen by joint centres only): faster, and those coordinates less settled.
    pub relative_decrease: f64,
    /// The first frame's starting point (default: the model's default coordinates).
    pub initial_q: Option<Vec<f64>>,
    /// Divide the marker weights by their sum over the markers present in each frame, as
    /// OpenSim's IK does (its marker goal is a weighted mean, its coordinate goals are not;
    /// the two choices have different minimisers when coordinate tasks exist). Default
    /// false.
    pub normalize_marker_weights: bool,
    /// Down-weight the markers that disagree with the others over the clip
    /// ([`robust`]). Default None: every task keeps its weight, as an OpenSim setup's
    /// weights must. The augmentation chain and `musculo ik` without a setup (markers matched
    /// by name with weight 1, or a skeleton map's joint centres) turn it on.
    pub robust: Option<RobustMarkers>,
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            bounds: Bounds::Range,
            smoothness: 0.0,
            max_iterations: 100,
            tolerance: 1e-6,
            relative_decrease: RELATIVE_DECREASE,
            initial_q: None,
            normalize_marker_weights: false,
            robust: None,
        }
    }
}

impl IkSettings {
    /// Checks the settings' values.
    pub fn validate(&self) -> crate::Result<()> {
        if !(self.smoothness >= 0.0 && self.smoothness.is_finite()) {
            return Err(Error::invalid(
                "smoothness",
                format!("{} must be ≥ 0 and finite", self.smoothness),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(Error::invalid(
                "tolerance",
                format!("{} must lie in (0, 1)", self.tolerance),
            ));
        }
        if !(self.relative_decrease > 0.0 && self.relative_decrease < 1.0) {
            return Err(Error::invalid(
                "relative_decrease",
                format!("{} must lie in (0, 1)", self.relative_decrease),
            ));
        }
        if self.max_iterations == 0 {
            return Err(Error::invalid("max_iterations", "must be at least 1"));
        }
        if let Some(robust) = &self.robust {
            robust.validate()?;
        }
        Ok(())
    }
}

/// The solution of a clip.
#[derive(Clone, Debug, PartialEq)]
pub struct IkSolution {
    /// Number of independent coordinates.
    pub nq: usize,
    /// Time of each frame (s).
    pub time: Vec<f64>,
    /// Frame-major coordinates: `q[f * nq + j]`.
    pub q: Vec<f64>,
    /// f(q) per frame.
    pub objective: Vec<f64>,
    /// Frame-major marker errors ‖p_i − x_i‖ (m), one per marker task; NaN where missing.
    pub marker_error: Vec<f64>,
    /// Per frame: root mean square of the present markers' errors (m), the markers in
    /// [`IkSolution::disagreeing`] left out (their errors are in `marker_error`).
    pub rmse: Vec<f64>,
    /// Per frame: the largest marker error (m), the markers in `disagreeing` left out.
    pub max_error: Vec<f64>,
    /// Per frame: the indices in q of the coordinates that ended at a bound, among those
    /// that some task moves (a marker task of positive weight on a body the coordinate
    /// moves, or a coordinate task): a coordinate that no task determines — an arm's
    /// elbow when only the legs have markers — rests where it starts, at a bound or not,
    /// and is not listed.
    pub at_limit: Vec<Vec<usize>>,
    /// Per frame: iterations used.
    pub iterations: Vec<u32>,
    /// Per frame: evaluations of f (one per trial step, accepted or not, plus the start).
    pub evaluations: Vec<u32>,
    /// Per marker task: the weight of the final fit (the task's, or lower where
    /// [`IkSettings::robust`] down-weighted it).
    pub marker_weight: Vec<f64>,
    /// The marker tasks that disagreed with the others and were down-weighted (empty without
    /// [`IkSettings::robust`]); [`robust::warnings`] words them.
    pub disagreeing: Vec<DisagreeingMarker>,
    /// The starts the first frame was solved from and the objective each reached (see
    /// [`describe_starts`]); empty when the first frame started from a given pose (`initial_q`, or
    /// [`solve_motion_from`]'s starts).
    pub first_frame_starts: Vec<StartOutcome>,
}

impl IkSolution {
    pub fn n_frames(&self) -> usize {
        self.time.len()
    }

    /// The coordinates of frame `f`.
    pub fn frame(&self, f: usize) -> &[f64] {
        &self.q[f * self.nq..(f + 1) * self.nq]
    }

    /// The frames at which at least one coordinate that a task moves ended at a bound.
    pub fn frames_at_limit(&self) -> usize {
        self.at_limit.iter().filter(|l| !l.is_empty()).count()
    }
}

/// Every independent coordinate's bounds under `bounds` (±∞ where unbounded).
pub fn coordinate_bounds(model: &Model, bounds: Bounds) -> (Vec<f64>, Vec<f64>) {
    let n = model.nq();
    let (mut lo, mut hi) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
    for (j, &c) in model.reduction.independent.iter().enumerate() {
        let coord = &model.coordinates[c];
        let bounded = match bounds {
            Bounds::Range => !floating_base_translation(model, c),
            Bounds::Clamped => coord.clamped,
            Bounds::None => false,
        };
        if bounded && coord.range[0] <= coord.range[1] {
            lo[j] = coord.range[0];
            hi[j] = coord.range[1];
        }
    }
    (lo, hi)
}

/// A translation of a joint to ground (the floating base's position in the room): its range
/// is a slider's (gait2392's ±5 m, ±3 m), not a limit of the body, and bounding it would stop
/// a clip that walks further from the origin than that.
pub fn floating_base_translation(model: &Model, c: usize) -> bool {
    let coordinate = &model.coordinates[c];
    coordinate.motion_type == crate::model::MotionType::Translational
        && model.joints[coordinate.joint].parent_body == 0
}

/// Moves the start pose by the floating base's translations so that the weighted centroid of
/// the model markers falls on that of the first frame's targets (least squares over the
/// translation coordinates, within their bounds), so that IK does not depend on where in the
/// room a clip was recorded: from the model's default pose at the origin, a clip 10 m away
/// ended its first frame in another local minimum (the upper arms' roll 150° apart), and every
/// later frame followed from there. Nothing moves without such coordinates or targets.
fn move_start_to_targets(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &[Vec3],
) -> crate::Result<()> {
    let translations: Vec<usize> = (model.reduction.independent.iter().enumerate())
        .filter(|&(_, &c)| floating_base_translation(model, c))
        .map(|(j, _)| j)
        .collect();
    if translations.is_empty() {
        return Ok(());
    }
    // the weighted centroid of the markers whose targets are present, at q
    let centroid = |data: &mut Data, q: &[f64]| -> crate::Result<Option<Vec3>> {
        body_poses_only(model, data, q)?;
        let (mut sum, mut weight) = (Vec3::zeros(), 0.0);
        for t in tasks.markers.iter().filter(|t| t.weight > 0.0) {
            if !frame[t.target].x.is_nan() {
                let m = &model.markers[t.marker];
                sum += data.point_position(m.body, &m.location_in_body) * t.weight;
                weight += t.weight;
            }
        }
        Ok((weight > 0.0).then(|| sum / weight))
    };
    let (mut sum, mut weight) = (Vec3::zeros(), 0.0);
    for t in tasks.markers.iter().filter(|t| t.weight > 0.0) {
        if !frame[t.target].x.is_nan() {
            sum += frame[t.target] * t.weight;
            weight += t.weight;
        }
    }
    let Some(at_start) = centroid(&mut ws.data, &ws.q)? else {
        return Ok(());
    };
    let target = sum / weight;
    // a translation moves every point alike: column k of T is the centroid's motion per
    // unit of translation coordinate k (exact for any step; 1 m taken)
    let mut t = DMatrix::zeros(3, translations.len());
    let mut q = ws.q.clone();
    for (k, &j) in translations.iter().enumerate() {
        q[j] += 1.0;
        if let Some(moved) = centroid(&mut ws.data, &q)? {
            t.column_mut(k).copy_from(&(moved - at_start));
        }
        q[j] -= 1.0;
    }
    let gap = DVector::from_column_slice((target - at_start).as_slice());
    if let Ok(step) = t.svd(true, true).solve(&gap, 1e-9) {
        for (k, &j) in translations.iter().enumerate() {
            if step[k].is_finite() {
                ws.q[j] = (ws.q[j] + step[k]).clamp(ws.lo[j], ws.hi[j]);
            }
        }
    }
    Ok(())
}

/// Checks tasks against the model and the targets.
fn check_tasks(model: &Model, targets: &Motion, tasks: &IkTasks) -> crate::Result<()> {
    let frames = targets.n_frames();
    if tasks.markers.is_empty() && tasks.coordinates.is_empty() {
        return Err(Error::invalid("tasks", "no marker or coordinate task"));
    }
    for t in &tasks.markers {
        if t.marker >= model.markers.len() || t.target >= targets.n_targets() {
            return Err(Error::invalid(
                "tasks",
                format!(
                    "marker task ({}, target {}) out of range ({} markers, {} targets)",
                    t.marker,
                    t.target,
                    model.markers.len(),
                    targets.n_targets()
                ),
            ));
        }
        if !(t.weight >= 0.0 && t.weight.is_finite()) {
            return Err(Error::invalid(
                "tasks",
                format!(
                    "marker \"{}\": weight {} must be ≥ 0 and finite",
                    model.markers[t.marker].name, t.weight
                ),
            ));
        }
    }
    for t in &tasks.coordinates {
        if t.q >= model.nq() {
            return Err(Error::invalid(
                "tasks",
                format!(
                    "coordinate task q[{}] out of range (nq = {})",
                    t.q,
                    model.nq()
                ),
            ));
        }
        if !(t.weight >= 0.0 && t.weight.is_finite()) {
            return Err(Error::invalid(
                "tasks",
                format!(
                    "coordinate task q[{}]: weight {} must be ≥ 0",
                    t.q, t.weight
                ),
            ));
        }
        if t.value.len() != 1 && t.value.len() != frames {
            return Err(Error::invalid(
                "tasks",
                format!(
                    "coordinate task q[{}]: {} values for {frames} frames",
                    t.q,
                    t.value.len()
                ),
            ));
        }
        if t.value.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "tasks",
                format!("coordinate task q[{}]: a value is not finite", t.q),
            ));
        }
    }
    Ok(())
}

/// The buffers of one solve, reused frame after frame.
pub struct IkWorkspace {
    data: Data,
    hessian: DMatrix<f64>,
    chol: Vec<f64>,
    inv_diag: Vec<f64>,
    /// The elimination tree of H's pattern (the tasks' kinematic tree).
    tree: EliminationTree,
    gradient: DVector<f64>,
    step: DVector<f64>,
    q: Vec<f64>,
    q_trial: Vec<f64>,
    q_prev: Vec<f64>,
    q_prev2: Vec<f64>,
    free: Vec<bool>,
    /// Per reduced column c: (column e, its coordinate) for every column e towards ground,
    /// flattened (`column_path[column_path_start[c]..column_path_start[c + 1]]`).
    column_path: Vec<(usize, usize)>,
    column_path_start: Vec<usize>,
    /// The coordinate pairs j < k that H couples (a column and one towards ground, distinct
    /// coordinates), each once: H is zero elsewhere off the diagonal, so only these and the
    /// diagonal are cleared and read.
    pattern: Vec<(usize, usize)>,
    /// Per body: the markers' point masses and forces, then their composites.
    inertia: Vec<SpatialInertia>,
    force: Vec<Force>,
    /// Marquardt's damping, carried from frame to frame.
    mu: f64,
    /// The largest diagonal entry of H without the coordinate tasks' weights (see
    /// [`damped_step`]).
    diagonal_scale: f64,
    /// Evaluations of f in the current frame.
    evaluations: u32,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl IkWorkspace {
    pub fn new(model: &Model, bounds: Bounds) -> IkWorkspace {
        let n = model.nq();
        let (lo, hi) = coordinate_bounds(model, bounds);
        let cols = &model.reduction.columns;
        let (mut column_path, mut column_path_start) = (Vec::new(), vec![0]);
        for c in 0..cols.len() {
            let mut e = cols.parent[c];
            while e != NONE {
                column_path.push((e, cols.q[e]));
                e = cols.parent[e];
            }
            column_path_start.push(column_path.len());
        }
        let mut pattern: Vec<(usize, usize)> = column_path_start
            .windows(2)
            .enumerate()
            .flat_map(|(c, w)| column_path[w[0]..w[1]].iter().map(move |&(_, k)| (c, k)))
            .map(|(c, k)| (cols.q[c].min(k), cols.q[c].max(k)))
            .filter(|(j, k)| j != k)
            .collect();
        pattern.sort_unstable();
        pattern.dedup();
        IkWorkspace {
            column_path,
            column_path_start,
            pattern,
            data: Data::new(model),
            hessian: DMatrix::zeros(n, n),
            chol: vec![0.0; n * n],
            inv_diag: vec![0.0; n],
            tree: EliminationTree::dense(n),
            gradient: DVector::zeros(n),
            step: DVector::zeros(n),
            q: vec![0.0; n],
            q_trial: vec![0.0; n],
            q_prev: vec![0.0; n],
            q_prev2: vec![0.0; n],
            free: vec![true; n],
            inertia: vec![SpatialInertia::ZERO; model.bodies.len()],
            force: vec![Force::ZERO; model.bodies.len()],
            mu: 1e-3,
            diagonal_scale: 0.0,
            evaluations: 0,
            lo,
            hi,
        }
    }
}

/// The elimination tree of H = Σ w J_iᵀ J_i + diagonal terms: marker i's Jacobian has
/// non-zero columns only for the coordinates on its body's path to ground.
fn task_tree(model: &Model, tasks: &IkTasks) -> EliminationTree {
    let mut pairs = Vec::new();
    let mut deps = Vec::new();
    for t in &tasks.markers {
        path_coordinates(model, model.markers[t.marker].body, &mut deps);
        for (a, &i) in deps.iter().enumerate() {
            pairs.extend(deps[..a].iter().map(|&j| (i, j)));
        }
    }
    EliminationTree::from_pattern(model.nq(), pairs)
}

/// The coordinates of the reduced columns on `body`'s path to ground (a point on the body
/// moves with these), into `out`.
fn path_coordinates(model: &Model, body: usize, out: &mut Vec<usize>) {
    let cols = &model.reduction.columns;
    out.clear();
    let mut c = cols.body_last[body];
    while c != NONE {
        out.push(cols.q[c]);
        c = cols.parent[c];
    }
}

/// Per coordinate: whether a task moves it (a marker task of positive weight on a body on
/// whose path to ground the coordinate acts, or a coordinate task of positive weight).
fn moved_by_tasks(model: &Model, tasks: &IkTasks) -> Vec<bool> {
    let mut moved = vec![false; model.nq()];
    let mut deps = Vec::new();
    for t in tasks.markers.iter().filter(|t| t.weight > 0.0) {
        path_coordinates(model, model.markers[t.marker].body, &mut deps);
        for &j in &deps {
            moved[j] = true;
        }
    }
    for t in tasks.coordinates.iter().filter(|t| t.weight > 0.0) {
        moved[t.q] = true;
    }
    moved
}

/// One frame's inputs.
struct Frame<'a> {
    targets: &'a [Vec3],
    index: usize,
    smoothness: f64,
    /// Factor on every marker weight this frame (1, or 1/Σ w of the markers present).
    marker_scale: f64,
}

/// f(q) for one frame; leaves the body poses at q in `data`.
fn objective(
    model: &Model,
    data: &mut Data,
    tasks: &IkTasks,
    frame: &Frame,
    q: &[f64],
    q_prev: &[f64],
) -> crate::Result<f64> {
    body_poses_only(model, data, q)?;
    let mut f = 0.0;
    for t in &tasks.markers {
        let x = frame.targets[t.target];
        if x.x.is_nan() {
            continue;
        }
        let m = &model.markers[t.marker];
        f += frame.marker_scale
            * t.weight
            * (data.point_position(m.body, &m.location_in_body) - x).norm_squared();
    }
    for t in &tasks.coordinates {
        let v = t.value[if t.value.len() == 1 { 0 } else { frame.index }];
        f += t.weight * (q[t.q] - v).powi(2);
    }
    if frame.smoothness > 0.0 {
        f += frame.smoothness
            * q.iter()
                .zip(q_prev)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>();
    }
    Ok(f)
}

/// H and g (of f/2) at the q whose body poses `ws.data` holds.
///
/// The marker term's normal matrix is the joint-space inertia matrix of point masses wᵢ at
/// the markers: column a of marker i's Jacobian is v_a + ω_a × pᵢ for the motion subspace
/// s_a = (ω_a, v_a) of every column on its body's path to ground, so
/// Σ wᵢ J_iaᵀ J_ib = s_aᵀ I s_b with I = Σ wᵢ (point mass at pᵢ), and likewise
/// Σ wᵢ J_iaᵀ rᵢ = s_aᵀ F with the spatial force F = Σ (pᵢ × wᵢrᵢ, wᵢrᵢ). Both are summed per
/// body, composed from the leaves to the root, and projected as the composite-rigid-body
/// algorithm does (`dynamics::crba`):
///
///   I^c_b = I_b + Σ_children I^c,   F^c_b = F_b + Σ_children F^c,
///   H[q_c][q_e] += s_eᵀ I^c_{body(c)} s_c  (e = c and every column e towards ground),
///   g[q_c] += s_cᵀ F^c_{body(c)},
///
/// O(columns × depth) six-vector products instead of one 3 × n Jacobian per marker.
fn normal_equations(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
) -> crate::Result<()> {
    let n = model.nq();
    motion_subspaces(model, &mut ws.data);
    // Only H's pattern is ever written (the rest stays zero from `IkWorkspace::new`).
    let h = ws.hessian.as_mut_slice();
    for j in 0..n {
        h[j + j * n] = 0.0;
    }
    for &(j, k) in &ws.pattern {
        h[j + k * n] = 0.0;
        h[k + j * n] = 0.0;
    }
    ws.gradient.fill(0.0);
    ws.inertia.fill(SpatialInertia::ZERO);
    ws.force.fill(Force::ZERO);
    for t in &tasks.markers {
        let x = frame.targets[t.target];
        if x.x.is_nan() || t.weight == 0.0 {
            continue;
        }
        let m = &model.markers[t.marker];
        let p = ws.data.point_position(m.body, &m.location_in_body);
        let off = p - ws.data.reference_point;
        let w = frame.marker_scale * t.weight;
        let wr = (p - x) * w;
        ws.inertia[m.body].add_assign(&SpatialInertia::from_mass_com_inertia(
            w,
            &off,
            &Mat3::zeros(),
        ));
        ws.force[m.body].add_assign(&Force {
            ang: off.cross(&wr),
            lin: wr,
        });
    }
    for joint in model.joints.iter().rev() {
        if joint.parent_body != 0 {
            let (i, f) = (ws.inertia[joint.child_body], ws.force[joint.child_body]);
            ws.inertia[joint.parent_body].add_assign(&i);
            ws.force[joint.parent_body].add_assign(&f);
        }
    }
    let cols = &model.reduction.columns;
    let motion = &ws.data.col_motion;
    let h = ws.hessian.as_mut_slice(); // column-major: (i, j) at i + j n
    for c in 0..cols.len() {
        let body = cols.body[c];
        let j = cols.q[c];
        ws.gradient[j] += motion[c].dot(&ws.force[body]);
        let f = ws.inertia[body].mul_motion(&motion[c]);
        h[j + j * n] += motion[c].dot(&f);
        for &(e, k) in &ws.column_path[ws.column_path_start[c]..ws.column_path_start[c + 1]] {
            let v = motion[e].dot(&f);
            h[j + k * n] += v;
            h[k + j * n] += v;
        }
    }
    if frame.smoothness > 0.0 {
        for j in 0..n {
            ws.hessian[(j, j)] += frame.smoothness;
            ws.gradient[j] += frame.smoothness * (ws.q[j] - ws.q_prev[j]);
        }
    }
    ws.diagonal_scale = (0..n).map(|j| ws.hessian[(j, j)]).fold(0.0f64, f64::max);
    for t in &tasks.coordinates {
        let v = t.value[if t.value.len() == 1 { 0 } else { frame.index }];
        ws.hessian[(t.q, t.q)] += t.weight;
        ws.gradient[t.q] += t.weight * (ws.q[t.q] - v);
    }
    Ok(())
}

/// Solves (H_FF + μ D_FF + ε I) δ_F = −g_F, δ = 0 off the free set: the held coordinates'
/// rows and columns are replaced by the identity's (right-hand side 0), so that the matrix
/// keeps the tasks' tree pattern and is factored as Lᵀ L by [`ltl`] (branch-induced sparsity:
/// each limb's coordinates couple only with their own chain). False when the damped matrix
/// is not positive definite.
fn damped_step(ws: &mut IkWorkspace, mu: f64) -> bool {
    let n = ws.gradient.len();
    let h = ws.hessian.as_slice(); // column-major n × n, symmetric
    // Marquardt's scaling D = diag H, floored at 10⁻² of its largest entry so that poorly
    // determined coordinates (a forearm's roll seen by one joint centre) cannot take long
    // steps that the next iterations must walk back. The largest entry is taken without
    // the coordinate tasks' weights: a task that pins a coordinate (OpenSim's setups weight
    // them 1000 against markers whose weights sum to 1) would otherwise damp every other
    // coordinate by its weight, and from ~10¹⁴ on, the steps fell below the tolerance at
    // once and IK returned the starting pose as its solution.
    let largest = if ws.diagonal_scale > 0.0 {
        ws.diagonal_scale
    } else {
        (0..n).map(|j| h[j + j * n]).fold(0.0f64, f64::max)
    };
    let floor = 1e-2 * largest;
    // packed rows (`ltl`): row k holds k and its ancestors (n² ≥ any tree's storage)
    let l = &mut ws.chol[..ws.tree.storage_len()];
    for k in 0..n {
        let a = h[k + k * n];
        let r = ws.tree.row_start(k);
        if ws.free[k] {
            l[r] = a + mu * a.max(floor) + 1e-12 * (1.0 + a);
            for (v, &i) in l[r + 1..].iter_mut().zip(ws.tree.ancestors(k)) {
                *v = if ws.free[i] { h[i + k * n] } else { 0.0 };
            }
        } else {
            l[r] = 1.0;
            let d = ws.tree.ancestors(k).len();
            l[r + 1..r + 1 + d].fill(0.0);
        }
    }
    if !ws.tree.factor(l, &mut ws.inv_diag) {
        return false;
    }
    for k in 0..n {
        ws.step[k] = if ws.free[k] { -ws.gradient[k] } else { 0.0 };
    }
    ws.tree.solve(l, &ws.inv_diag, ws.step.as_mut_slice());
    true
}

/// [`damped_step`], holding also every coordinate at a bound whose step would leave the
/// box (the step is then re-solved without it), so that the projected step is the
/// minimiser of the damped model on the face of the box it moves in.
fn damped_step_at_bounds(ws: &mut IkWorkspace, mu: f64) -> bool {
    for _ in 0..ws.q.len() {
        if !damped_step(ws, mu) {
            return false;
        }
        let mut changed = false;
        for j in 0..ws.q.len() {
            let out = (ws.q[j] <= ws.lo[j] && ws.step[j] < 0.0)
                || (ws.q[j] >= ws.hi[j] && ws.step[j] > 0.0);
            if ws.free[j] && out {
                ws.free[j] = false;
                changed = true;
            }
        }
        if !changed {
            return true;
        }
    }
    true
}

/// The free set of the projected-Newton method: a coordinate at a bound whose gradient
/// pushes it further out is held; returns the projected gradient's largest component.
fn update_free_set(ws: &mut IkWorkspace) -> f64 {
    let mut pg = 0.0f64;
    for j in 0..ws.q.len() {
        let g = ws.gradient[j];
        let at_lo = ws.q[j] <= ws.lo[j] && g > 0.0;
        let at_hi = ws.q[j] >= ws.hi[j] && g < 0.0;
        ws.free[j] = !(at_lo || at_hi);
        if ws.free[j] {
            pg = pg.max(g.abs());
        }
    }
    pg
}

/// Solves one frame from `ws.q` (already within bounds); returns (f, iterations).
fn solve_frame(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
    max_iterations: usize,
    tolerance: f64,
    relative_decrease: f64,
) -> crate::Result<(f64, u32)> {
    let (f, iterations, _) = solve_frame_joining(
        model,
        ws,
        tasks,
        frame,
        max_iterations,
        tolerance,
        relative_decrease,
        None,
    )?;
    Ok((f, iterations))
}

/// How close (rad, or m for a translation; every coordinate) an iterate of
/// [`solve_frame_joining`] must come to the known solution to be taken as converging to it.
/// A thousandth of a radian is far inside any basin of f (the minima a limb can fall into
/// lie tens of degrees apart), and a step of the damped Gauss–Newton iteration that started
/// there would not leave it.
const JOIN_RADIUS: f64 = 1e-3;

/// [`solve_frame`], stopping early once every coordinate of an iterate (the start included)
/// lies within [`JOIN_RADIUS`] of `join`, a minimum of the same frame's f found before: the
/// solve would converge to it. Returns (f, iterations, joined); when joined, f is that of the
/// last iterate, not the minimum's, and the body poses are not updated.
#[allow(clippy::too_many_arguments)]
fn solve_frame_joining(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
    max_iterations: usize,
    tolerance: f64,
    relative_decrease: f64,
    join: Option<&[f64]>,
) -> crate::Result<(f64, u32, bool)> {
    let joined = |q: &[f64]| {
        join.is_some_and(|r| q.iter().zip(r).all(|(a, b)| (a - b).abs() <= JOIN_RADIUS))
    };
    let mut f = objective(model, &mut ws.data, tasks, frame, &ws.q, &ws.q_prev)?;
    ws.evaluations += 1;
    let mut mu = ws.mu;
    let mut iterations = 0u32;
    if joined(&ws.q) {
        return Ok((f, iterations, true));
    }
    normal_equations(model, ws, tasks, frame)?;
    while (iterations as usize) < max_iterations {
        iterations += 1;
        let pg = update_free_set(ws);
        if pg <= 1e-15 {
            break;
        }
        let mut accepted = false;
        while mu < 1e12 {
            if damped_step_at_bounds(ws, mu) {
                let n = ws.q.len();
                let mut largest = 0.0f64;
                for j in 0..n {
                    ws.q_trial[j] = (ws.q[j] + ws.step[j]).clamp(ws.lo[j], ws.hi[j]);
                    ws.step[j] = ws.q_trial[j] - ws.q[j];
                    largest = largest.max(ws.step[j].abs());
                }
                // Decrease of f the Gauss–Newton model predicts for the (projected) step:
                // −2 (gᵀδ + ½ δᵀHδ)  (g and H are those of f/2), δᵀHδ over H's pattern
                let h = ws.hessian.as_slice();
                let d = ws.step.as_slice();
                let linear = dot(ws.gradient.as_slice(), d);
                let mut quadratic = 0.0;
                for b in 0..n {
                    quadratic += h[b + b * n] * d[b] * d[b];
                }
                for &(j, k) in &ws.pattern {
                    quadratic += 2.0 * h[j + k * n] * d[j] * d[k];
                }
                let predicted = -2.0 * (linear + 0.5 * quadratic);
                let f_trial =
                    objective(model, &mut ws.data, tasks, frame, &ws.q_trial, &ws.q_prev)?;
                ws.evaluations += 1;
                if f_trial < f {
                    std::mem::swap(&mut ws.q, &mut ws.q_trial);
                    let decrease = f - f_trial;
                    f = f_trial;
                    // Nielsen's update from the gain ratio ρ = actual / predicted decrease.
                    let rho = if predicted > 0.0 {
                        decrease / predicted
                    } else {
                        1.0
                    };
                    mu = (mu * (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3))).max(1e-10);
                    ws.mu = mu;
                    accepted = true;
                    if largest <= tolerance || decrease <= relative_decrease * f {
                        return Ok((f, iterations, false));
                    }
                    if joined(&ws.q) {
                        return Ok((f, iterations, true));
                    }
                    break;
                }
            }
            mu *= 4.0;
        }
        if !accepted {
            break;
        }
        normal_equations(model, ws, tasks, frame)?;
    }
    // Leave the body poses at the solution.
    body_poses_only(model, &mut ws.data, &ws.q)?;
    Ok((f, iterations, false))
}

/// Inverse kinematics of one clip. `targets` must be in the model's frame and metres (see
/// `motion::skeleton`); `progress` is called with the number of frames done.
pub fn solve_motion(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    settings: &IkSettings,
    progress: &dyn Fn(usize),
) -> crate::Result<IkSolution> {
    let solution = solve(model, targets, tasks, settings, None, progress)?;
    reweighted(model, targets, tasks, settings, solution)
}

/// [`solve_motion`] with every frame started from its own guess: frame f from
/// `starts.frame(f)` (kept within bounds) instead of the previous frames' extrapolation — for
/// solving the same frames again after a small change of the model or the targets, as
/// marker placement does between its rounds. `starts` must have the frames of `targets`.
pub fn solve_motion_from(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    settings: &IkSettings,
    starts: &IkSolution,
    progress: &dyn Fn(usize),
) -> crate::Result<IkSolution> {
    if starts.nq != model.nq() || starts.n_frames() != targets.n_frames() {
        return Err(Error::invalid(
            "starts",
            format!(
                "has {} frames of {} coordinates; the targets have {} frames, the model {} \
                 coordinates",
                starts.n_frames(),
                starts.nq,
                targets.n_frames(),
                model.nq()
            ),
        ));
    }
    if !starts.q.iter().all(|v| v.is_finite()) {
        return Err(Error::invalid("starts", "holds a non-finite coordinate"));
    }
    let solution = solve(model, targets, tasks, settings, Some(starts), progress)?;
    reweighted(model, targets, tasks, settings, solution)
}

/// With [`IkSettings::robust`]: the clip solved again with the markers that disagree with the
/// others down-weighted ([`robust`]), the first frame from its previous solution and each
/// later one from the new solutions of the frames before it (as the first pass), until the
/// set of such markers stops changing (at most `max_passes` times); the fit figures then leave
/// them out. Without a disagreeing marker, `solution` as it is.
fn reweighted(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    settings: &IkSettings,
    mut solution: IkSolution,
) -> crate::Result<IkSolution> {
    let Some(robust) = &settings.robust else {
        return Ok(solution);
    };
    let nm = tasks.markers.len();
    // the later passes start from the first pass's first frame: its starts stand
    let first_frame_starts = solution.first_frame_starts.clone();
    let counted: Vec<bool> = tasks.markers.iter().map(|t| t.weight > 0.0).collect();
    // the weight factors of the last solve (all 1 for the first)
    let mut factors: Vec<Option<f64>> = vec![None; nm];
    for pass in 0..=robust.max_passes {
        let errors = robust::clip_errors(&solution, nm);
        let mut verdict = robust::disagreement(&errors, &counted, robust);
        robust::outvoted_only(model, targets, tasks, &solution, &mut verdict)?;
        let same_set = (verdict.iter().zip(&factors)).all(|(a, b)| a.is_some() == b.is_some());
        if same_set || pass == robust.max_passes {
            break;
        }
        factors = verdict;
        let mut weighted = tasks.clone();
        for (t, factor) in weighted.markers.iter_mut().zip(&factors) {
            t.weight *= factor.unwrap_or(1.0);
        }
        // Frame by frame from the new solutions (constant-velocity prediction), not from each
        // frame's previous solution: the segment a bad marker turned must turn back in every
        // frame, while the new solution of the frame before is already there.
        let again = IkSettings {
            initial_q: Some(solution.frame(0).to_vec()),
            ..settings.clone()
        };
        solution = solve(model, targets, &weighted, &again, None, &|_| {})?;
        solution.first_frame_starts.clone_from(&first_frame_starts);
    }
    if factors.iter().all(Option::is_none) {
        return Ok(solution);
    }
    let errors = robust::clip_errors(&solution, nm);
    let mut others: Vec<f64> = (0..nm)
        .filter(|&i| counted[i] && factors[i].is_none() && errors[i].1 > 0)
        .map(|i| errors[i].0)
        .collect();
    let others_median = robust::median(&mut others);
    solution.marker_weight = (tasks.markers.iter().zip(&factors))
        .map(|(t, f)| t.weight * f.unwrap_or(1.0))
        .collect();
    solution.disagreeing = (0..nm)
        .filter(|&i| factors[i].is_some())
        .map(|i| DisagreeingMarker {
            task: i,
            median_error: errors[i].0,
            frames_present: errors[i].1,
            others_median_error: others_median,
            weight: solution.marker_weight[i],
        })
        .collect();
    // the fit figures of the markers kept
    for f in 0..solution.n_frames() {
        let (mut sum, mut count, mut worst) = (0.0, 0usize, 0.0f64);
        for (i, &e) in solution.marker_error[f * nm..(f + 1) * nm]
            .iter()
            .enumerate()
        {
            if factors[i].is_none() && e.is_finite() {
                sum += e * e;
                count += 1;
                worst = worst.max(e);
            }
        }
        solution.rmse[f] = if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            f64::NAN
        };
        solution.max_error[f] = if count > 0 { worst } else { f64::NAN };
    }
    Ok(solution)
}

fn solve(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    settings: &IkSettings,
    starts: Option<&IkSolution>,
    progress: &dyn Fn(usize),
) -> crate::Result<IkSolution> {
    settings.validate()?;
    targets.validate()?;
    check_tasks(model, targets, tasks)?;
    check_something_to_fit(model, targets, tasks)?;
    let observed = Observed { targets, tasks };
    let n = model.nq();
    let mut ws = IkWorkspace::new(model, settings.bounds);
    ws.tree = task_tree(model, tasks);
    let moved = moved_by_tasks(model, tasks);
    set_start_pose(model, &mut ws, settings)?;
    // Without a given start, the first frame with a target is solved from several
    // (`start`); the frames before it (none seen) keep the start pose.
    let mut several_starts = starts.is_none() && settings.initial_q.is_none();
    let global_frame = if several_starts {
        several_starts_frame(&observed)
    } else {
        0
    };
    if several_starts {
        let first = (0..targets.n_frames())
            .find(|&f| observed.has_data(f))
            .unwrap_or(0);
        move_start_to_targets(model, &mut ws, tasks, targets.frame(first))?;
    }
    ws.q_prev.copy_from_slice(&ws.q);
    ws.q_prev2.copy_from_slice(&ws.q);
    let mut out = IkSolution::empty(n, targets, tasks);
    for f in 0..targets.n_frames() {
        predict_frame_start(&mut ws, targets, starts, f, observed.has_data(f));
        let frame = observed.frame(f, settings);
        let from_several = several_starts && f == global_frame;
        let max_iterations = if f == 0 || from_several {
            settings.max_iterations * 10
        } else {
            settings.max_iterations
        };
        ws.evaluations = 0;
        let (value, iterations) = if from_several {
            several_starts = false;
            let (value, iterations, outcomes) = start::best_of_starts(
                model,
                &mut ws,
                if (0..f).any(|g| observed.has_data(g)) {
                    "previous frames"
                } else {
                    "default pose"
                },
                tasks,
                &frame,
                max_iterations,
                settings.tolerance,
                settings.relative_decrease,
            )?;
            out.first_frame_starts = outcomes;
            (value, iterations)
        } else {
            solve_frame(
                model,
                &mut ws,
                tasks,
                &frame,
                max_iterations,
                settings.tolerance,
                settings.relative_decrease,
            )?
        };
        out.evaluations.push(ws.evaluations);
        out.q.extend_from_slice(&ws.q);
        out.objective.push(value);
        out.iterations.push(iterations);
        std::mem::swap(&mut ws.q_prev, &mut ws.q_prev2);
        ws.q_prev.copy_from_slice(&ws.q);
        progress(f + 1);
    }
    // Frames given their own starts are not tracked from their neighbours: no sweep.
    if starts.is_none() {
        backward::sweep(model, &mut ws, tasks, &observed, settings, &mut out)?;
    }
    for f in 0..targets.n_frames() {
        ws.q.copy_from_slice(out.frame(f));
        body_poses_only(model, &mut ws.data, &ws.q)?;
        record_fit(
            &mut out,
            model,
            &ws,
            tasks,
            &observed.frame(f, settings),
            &moved,
        );
    }
    Ok(out)
}

/// Refuses a clip with nothing to fit: a frame with no target keeps the previous pose, so a
/// clip in which no frame has one would be the start pose throughout, reported as solved.
fn check_something_to_fit(model: &Model, targets: &Motion, tasks: &IkTasks) -> crate::Result<()> {
    let weighted: Vec<&MarkerTask> = tasks.markers.iter().filter(|t| t.weight > 0.0).collect();
    let no_data = !tasks.coordinates.iter().any(|t| t.weight > 0.0)
        && (0..targets.n_frames()).all(|f| {
            let frame = targets.frame(f);
            weighted.iter().all(|t| frame[t.target].x.is_nan())
        });
    if no_data && weighted.is_empty() {
        return Err(Error::invalid(
            "tasks",
            "every marker and coordinate task has weight 0: nothing to fit",
        ));
    }
    if no_data {
        return Err(Error::invalid(
            "targets",
            format!(
                "no frame of {} has any of the model's {} IK marker(s) ({}{}): every one is \
                 missing in every frame, so there is nothing to fit",
                targets.source,
                weighted.len(),
                weighted
                    .iter()
                    .take(5)
                    .map(|t| model.markers[t.marker].name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                if weighted.len() > 5 { ", …" } else { "" }
            ),
        ));
    }
    Ok(())
}

/// The clip's targets as the tasks see them, frame by frame.
struct Observed<'a> {
    targets: &'a Motion,
    tasks: &'a IkTasks,
}

impl<'a> Observed<'a> {
    /// Whether frame `f` has a target to fit (a weighted marker present, or a weighted
    /// coordinate task).
    fn has_data(&self, f: usize) -> bool {
        (self.tasks.markers.iter())
            .any(|t| t.weight > 0.0 && !self.targets.frame(f)[t.target].x.is_nan())
            || self.tasks.coordinates.iter().any(|t| t.weight > 0.0)
    }

    /// Σ w of the marker tasks whose targets are present in frame `f`.
    fn present_weight(&self, f: usize) -> f64 {
        let frame = self.targets.frame(f);
        (self.tasks.markers.iter())
            .filter(|t| !frame[t.target].x.is_nan())
            .map(|t| t.weight)
            .sum()
    }

    /// Frame `f`'s targets and weights.
    fn frame(&self, f: usize, settings: &IkSettings) -> Frame<'a> {
        let present_weight = self.present_weight(f);
        Frame {
            targets: self.targets.frame(f),
            index: f,
            // The first frame has no predecessor to stay close to.
            smoothness: if f == 0 { 0.0 } else { settings.smoothness },
            marker_scale: if settings.normalize_marker_weights && present_weight > 0.0 {
                1.0 / present_weight
            } else {
                1.0
            },
        }
    }
}

/// The start pose in `ws.q`: `initial_q` or the model's default coordinates, within bounds.
fn set_start_pose(model: &Model, ws: &mut IkWorkspace, settings: &IkSettings) -> crate::Result<()> {
    let n = model.nq();
    let start = match &settings.initial_q {
        Some(q) if q.len() == n && q.iter().all(|v| v.is_finite()) => q.clone(),
        Some(q) => {
            return Err(Error::invalid(
                "initial_q",
                format!("needs {n} finite values, has {}", q.len()),
            ));
        }
        None => model.default_q(),
    };
    for j in 0..n {
        ws.q[j] = start[j].clamp(ws.lo[j], ws.hi[j]);
    }
    Ok(())
}

/// The frame solved from several starts: the first observed at least as well as the clip's
/// median frame (weight of the markers present). A clip whose first frames see one or two
/// markers (a C3D trial's subject walking into the volume) leaves the pose undetermined there.
fn several_starts_frame(observed: &Observed) -> usize {
    let frames = observed.targets.n_frames();
    let mut seen: Vec<f64> = (0..frames).map(|f| observed.present_weight(f)).collect();
    seen.sort_by(f64::total_cmp);
    let typical = seen[seen.len() / 2];
    (0..frames)
        .find(|&f| observed.has_data(f) && observed.present_weight(f) >= typical)
        .unwrap_or(0)
}

/// Frame `f`'s starting point in `ws.q`: the given start, or the previous solution moved on
/// at its last velocity (constant-velocity prediction,
/// q̂ = q_{f−1} + (t_f − t_{f−1})/(t_{f−1} − t_{f−2}) · (q_{f−1} − q_{f−2})), kept within
/// bounds: at 20 fps a walking pelvis moves 7 cm a frame. A frame with no target at all keeps
/// the previous pose.
fn predict_frame_start(
    ws: &mut IkWorkspace,
    targets: &Motion,
    starts: Option<&IkSolution>,
    f: usize,
    observed: bool,
) {
    let n = ws.q.len();
    if let Some(starts) = starts {
        for j in 0..n {
            ws.q[j] = starts.frame(f)[j].clamp(ws.lo[j], ws.hi[j]);
        }
    } else if f >= 2 && observed {
        let ratio =
            (targets.time[f] - targets.time[f - 1]) / (targets.time[f - 1] - targets.time[f - 2]);
        for j in 0..n {
            ws.q[j] =
                (ws.q_prev[j] + ratio * (ws.q_prev[j] - ws.q_prev2[j])).clamp(ws.lo[j], ws.hi[j]);
        }
    }
}

/// Appends the solved frame's fit figures to `out`: each marker's error ‖p_i − x_i‖ (NaN where
/// missing), their root mean square and maximum, and the moved coordinates at a bound.
fn record_fit(
    out: &mut IkSolution,
    model: &Model,
    ws: &IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
    moved: &[bool],
) {
    let (mut sum, mut count, mut worst) = (0.0, 0usize, 0.0f64);
    for t in &tasks.markers {
        let x = frame.targets[t.target];
        if x.x.is_nan() {
            out.marker_error.push(f64::NAN);
            continue;
        }
        let m = &model.markers[t.marker];
        let e = (ws.data.point_position(m.body, &m.location_in_body) - x).norm();
        out.marker_error.push(e);
        sum += e * e;
        count += 1;
        worst = worst.max(e);
    }
    out.rmse.push(if count > 0 {
        (sum / count as f64).sqrt()
    } else {
        f64::NAN
    });
    out.max_error.push(if count > 0 { worst } else { f64::NAN });
    out.at_limit.push(
        (0..ws.q.len())
            .filter(|&j| moved[j] && (ws.q[j] <= ws.lo[j] || ws.q[j] >= ws.hi[j]))
            .collect(),
    );
}

impl IkSolution {
    /// A solution with no frame yet, sized for `targets`.
    fn empty(nq: usize, targets: &Motion, tasks: &IkTasks) -> IkSolution {
        let frames = targets.n_frames();
        let nm = tasks.markers.len();
        IkSolution {
            nq,
            time: targets.time.clone(),
            q: Vec::with_capacity(frames * nq),
            objective: Vec::with_capacity(frames),
            marker_error: Vec::with_capacity(frames * nm),
            rmse: Vec::with_capacity(frames),
            max_error: Vec::with_capacity(frames),
            at_limit: Vec::with_capacity(frames),
            iterations: Vec::with_capacity(frames),
            evaluations: Vec::with_capacity(frames),
            marker_weight: tasks.markers.iter().map(|t| t.weight).collect(),
            disagreeing: Vec::new(),
            first_frame_starts: Vec::new(),
        }
    }
}

/// Inverse kinematics of several clips in parallel (one clip per task, frames within a clip
/// sequential): the same result whatever the thread count. `progress` receives the total
/// number of frames done across clips.
pub fn solve_motions(
    model: &Model,
    clips: &[(Motion, IkTasks)],
    settings: &IkSettings,
    progress: &(dyn Fn(usize) + Sync),
) -> Vec<crate::Result<IkSolution>> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let done = AtomicUsize::new(0);
    clips
        .par_iter()
        .map(|(motion, tasks)| {
            let reported = std::cell::Cell::new(0usize);
            solve_motion(model, motion, tasks, settings, &|k| {
                let new = k - reported.replace(k);
                progress(done.fetch_add(new, Ordering::Relaxed) + new);
            })
        })
        .collect()
}

/// The marker tasks that pair each model marker with the motion target of the same name,
/// all with weight 1 (OpenSim marker sets used as they are). Targets without a model marker
/// are left out.
pub fn tasks_by_name(model: &Model, targets: &Motion) -> IkTasks {
    let markers = model
        .markers
        .iter()
        .enumerate()
        .filter_map(|(i, m)| {
            targets.index(&m.name).map(|t| MarkerTask {
                marker: i,
                target: t,
                weight: 1.0,
            })
        })
        .collect();
    IkTasks {
        markers,
        coordinates: Vec::new(),
    }
}

/// Whether a model coordinate (by name) is independent, and its index in q.
pub fn independent_index(model: &Model, name: &str) -> Option<usize> {
    let c = model.coordinate_index(name)?;
    match model.coordinates[c].role {
        CoordinateRole::Independent(j) => Some(j),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, point_jacobian};
    use crate::random::SplitMix64;
    use crate::reference::{random_q, test_models};

    /// Tasks on every model marker (random weights), random targets, and a workspace with H
    /// and g assembled at random coordinates (the task tree set, as `solve` sets it).
    fn assembled(model: &Model, rng: &mut SplitMix64) -> (IkTasks, Vec<Vec3>, IkWorkspace) {
        let markers = (0..model.markers.len())
            .map(|i| MarkerTask {
                marker: i,
                target: i,
                weight: rng.uniform(0.5, 2.0),
            })
            .collect();
        let targets: Vec<Vec3> = (0..model.markers.len())
            .map(|_| {
                Vec3::new(
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(0.0, 1.5),
                    rng.uniform(-1.0, 1.0),
                )
            })
            .collect();
        let tasks = IkTasks {
            markers,
            coordinates: Vec::new(),
        };
        let frame = Frame {
            targets: &targets,
            index: 0,
            smoothness: 0.0,
            marker_scale: 1.0,
        };
        let mut ws = IkWorkspace::new(model, Bounds::None);
        ws.tree = task_tree(model, &tasks);
        // assembled twice: the second must clear every entry the first wrote
        ws.q = random_q(model, rng, 0.1);
        objective(model, &mut ws.data, &tasks, &frame, &ws.q, &ws.q_prev).unwrap();
        normal_equations(model, &mut ws, &tasks, &frame).unwrap();
        ws.q = random_q(model, rng, 0.1);
        objective(model, &mut ws.data, &tasks, &frame, &ws.q, &ws.q_prev).unwrap();
        normal_equations(model, &mut ws, &tasks, &frame).unwrap();
        (tasks, targets, ws)
    }

    #[test]
    fn normal_equations_equal_the_sum_over_marker_jacobians() {
        let mut rng = SplitMix64(5);
        for (name, model) in test_models() {
            if model.markers.is_empty() {
                continue;
            }
            let n = model.nq();
            let (tasks, targets, ws) = assembled(&model, &mut rng);
            // reference: H = Σ w JᵀJ and g = Σ w Jᵀr from `point_jacobian`
            let mut data = Data::new(&model);
            forward_kinematics(&model, &mut data, &ws.q).unwrap();
            let (mut h, mut g) = (DMatrix::<f64>::zeros(n, n), DVector::<f64>::zeros(n));
            let mut jac = DMatrix::zeros(3, n);
            for t in &tasks.markers {
                let m = &model.markers[t.marker];
                point_jacobian(&model, &data, m.body, &m.location_in_body, &mut jac).unwrap();
                let r = data.point_position(m.body, &m.location_in_body) - targets[t.target];
                let r = DVector::from_column_slice(r.as_slice());
                h += jac.transpose() * &jac * t.weight;
                g += jac.transpose() * r * t.weight;
            }
            let scale = h.amax();
            let dh = (&ws.hessian - &h).amax() / scale;
            let dg = (&ws.gradient - &g).amax() / g.amax();
            assert!(dh < 1e-13 && dg < 1e-13, "{name}: H {dh:e}, g {dg:e}");
            // every structural non-zero lies on the task tree's ancestor chains
            let tree = &ws.tree;
            for i in 0..n {
                for j in 0..i {
                    let mut a = tree.parent(i);
                    while a != NONE && a != j {
                        a = tree.parent(a);
                    }
                    assert!(
                        a == j || h[(i, j)].abs() <= 1e-14 * scale,
                        "{name}: H[{i}][{j}] = {} off the tree",
                        h[(i, j)]
                    );
                }
            }
            let dense = n * n * n / 6;
            eprintln!(
                "{name}: LᵀL factorization {} multiply–adds, dense Cholesky ~{dense}",
                tree.factor_cost()
            );
        }
    }

    #[test]
    fn the_damped_step_solves_the_damped_system_with_bounds_held() {
        let mut rng = SplitMix64(9);
        for (name, model) in test_models() {
            if model.markers.is_empty() {
                continue;
            }
            let n = model.nq();
            let (_, _, mut ws) = assembled(&model, &mut rng);
            for j in 0..n {
                ws.free[j] = j % 4 != 1;
            }
            let mu = 1e-2;
            assert!(damped_step(&mut ws, mu), "{name}");
            // reference: the free block solved densely by nalgebra
            let free: Vec<usize> = (0..n).filter(|&j| ws.free[j]).collect();
            let h = &ws.hessian;
            let floor = 1e-2 * (0..n).map(|j| h[(j, j)]).fold(0.0f64, f64::max);
            let a = DMatrix::from_fn(free.len(), free.len(), |r, c| {
                let (i, j) = (free[r], free[c]);
                let mut v = h[(i, j)];
                if i == j {
                    v += mu * v.max(floor) + 1e-12 * (1.0 + v);
                }
                v
            });
            let b = DVector::from_fn(free.len(), |r, _| -ws.gradient[free[r]]);
            let x = a.cholesky().expect("SPD").solve(&b);
            for (r, &j) in free.iter().enumerate() {
                assert!(
                    (ws.step[j] - x[r]).abs() <= 1e-9 * (1.0 + x.amax()),
                    "{name}: step[{j}] {} vs {}",
                    ws.step[j],
                    x[r]
                );
            }
            assert!((0..n).filter(|&j| !ws.free[j]).all(|j| ws.step[j] == 0.0));
        }
    }
}
