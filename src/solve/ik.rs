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
//!   J_i = ∂p_i/∂q (analytic: `dynamics::point_jacobian`, reduced coordinates),
//!   H = Σ_i w_i J_iᵀ J_i + Σ_c w_c e_c e_cᵀ + s I,   g = Σ_i w_i J_iᵀ r_i + Σ_c w_c (q_c − q̂_c) e_c + s (q − q_prev),
//!   free set F = { j : not (q_j = lo_j and g_j > 0) and not (q_j = hi_j and g_j < 0) },
//!   (H_FF + μ diag H_FF) δ_F = −g_F,   q ← clamp(q + δ),
//!
//! accepting a step when f decreases (μ scaled by Nielsen's max(1/3, 1 − (2ρ − 1)³), ρ the
//! ratio of the actual to the predicted decrease) and rejecting it otherwise (μ × 4). A frame
//! ends when an accepted step moves no coordinate by more than the tolerance, when f falls
//! by less than [`RELATIVE_DECREASE`] of itself, or when the projected gradient vanishes.
//! The damping μ carries over from frame to frame. Each frame starts from the previous
//! frames' solutions extrapolated at constant velocity (the first from `initial_q` or the
//! model's default pose), so frames within a clip are sequential; clips run in parallel
//! ([`solve_motions`]) and the result does not depend on the thread count.
//!
//! After the first frame no allocation happens: `IkWorkspace` holds every buffer.

use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::model::{CoordinateRole, Model};
use crate::motion::Motion;
use crate::solve::qp::linalg::dot;
use crate::spatial::Vec3;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// A frame ends when an accepted step lowers f by less than this fraction of f. Gauss–Newton
/// converges linearly on real (non-zero-residual) data; at this threshold no single
/// coordinate moved by ±10⁻⁴ lowers f by more than ~10⁻⁸ of itself (tests/ik_datasets.rs
/// probes every frame), while 10⁻⁷ leaves up to 4·10⁻⁵ in poorly determined directions.
pub const RELATIVE_DECREASE: f64 = 1e-8;

/// A model marker that follows a target column of the motion.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerTask {
    /// Index in `Model::markers`.
    pub marker: usize,
    /// Column of the target motion.
    pub target: usize,
    pub weight: f64,
}

/// An independent coordinate held near a value (OpenSim's IKCoordinateTask).
#[derive(Clone, Debug, PartialEq)]
pub struct CoordinateTask {
    /// Index in q.
    pub q: usize,
    pub weight: f64,
    /// The value per frame, or one value for every frame.
    pub value: Vec<f64>,
}

/// What the solver fits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IkTasks {
    pub markers: Vec<MarkerTask>,
    pub coordinates: Vec<CoordinateTask>,
}

/// Which coordinate ranges bound the solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bounds {
    /// Every independent coordinate stays within its range.
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
    /// The first frame's starting point (default: the model's default coordinates).
    pub initial_q: Option<Vec<f64>>,
    /// Divide the marker weights by their sum over the markers present in each frame, as
    /// OpenSim's IK does (its marker goal is a weighted mean, its coordinate goals are not;
    /// the two choices have different minimisers when coordinate tasks exist). Default
    /// false.
    pub normalize_marker_weights: bool,
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            bounds: Bounds::Range,
            smoothness: 0.0,
            max_iterations: 100,
            tolerance: 1e-6,
            initial_q: None,
            normalize_marker_weights: false,
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
        if self.max_iterations == 0 {
            return Err(Error::invalid("max_iterations", "must be at least 1"));
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
    /// Per frame: root mean square of the present markers' errors (m).
    pub rmse: Vec<f64>,
    /// Per frame: the largest marker error (m).
    pub max_error: Vec<f64>,
    /// Per frame: the indices in q of the coordinates that ended at a bound.
    pub at_limit: Vec<Vec<usize>>,
    /// Per frame: iterations used.
    pub iterations: Vec<u32>,
    /// Per frame: evaluations of f (one per trial step, accepted or not, plus the start).
    pub evaluations: Vec<u32>,
}

impl IkSolution {
    pub fn n_frames(&self) -> usize {
        self.time.len()
    }

    /// The coordinates of frame `f`.
    pub fn frame(&self, f: usize) -> &[f64] {
        &self.q[f * self.nq..(f + 1) * self.nq]
    }

    /// The frames at which at least one coordinate ended at a bound.
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
            Bounds::Range => true,
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
    jac: DMatrix<f64>,
    hessian: DMatrix<f64>,
    chol: Vec<f64>,
    inv_diag: Vec<f64>,
    packed: Vec<f64>,
    gradient: DVector<f64>,
    step: DVector<f64>,
    q: Vec<f64>,
    q_trial: Vec<f64>,
    q_prev: Vec<f64>,
    q_prev2: Vec<f64>,
    free: Vec<bool>,
    cols: Vec<usize>,
    jcols: Vec<[f64; 3]>,
    /// Marquardt's damping, carried from frame to frame.
    mu: f64,
    /// Evaluations of f in the current frame.
    evaluations: u32,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl IkWorkspace {
    pub fn new(model: &Model, bounds: Bounds) -> IkWorkspace {
        let n = model.nq();
        let (lo, hi) = coordinate_bounds(model, bounds);
        IkWorkspace {
            data: Data::new(model),
            jac: DMatrix::zeros(3, n),
            hessian: DMatrix::zeros(n, n),
            chol: vec![0.0; n * n],
            inv_diag: vec![0.0; n],
            packed: vec![0.0; n],
            gradient: DVector::zeros(n),
            step: DVector::zeros(n),
            q: vec![0.0; n],
            q_trial: vec![0.0; n],
            q_prev: vec![0.0; n],
            q_prev2: vec![0.0; n],
            free: vec![true; n],
            cols: Vec::with_capacity(n),
            jcols: Vec::with_capacity(n),
            mu: 1e-3,
            evaluations: 0,
            lo,
            hi,
        }
    }
}

/// One frame's inputs.
struct Frame<'a> {
    targets: &'a [Vec3],
    index: usize,
    smoothness: f64,
    /// Factor on every marker weight this frame (1, or 1/Σ w of the markers present).
    marker_scale: f64,
}

/// f(q) for one frame; leaves forward kinematics at q in `data`.
fn objective(
    model: &Model,
    data: &mut Data,
    tasks: &IkTasks,
    frame: &Frame,
    q: &[f64],
    q_prev: &[f64],
) -> crate::Result<f64> {
    dynamics::forward_kinematics(model, data, q)?;
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

/// H and g (of f/2) at the q whose forward kinematics `ws.data` holds.
fn normal_equations(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
) -> crate::Result<()> {
    let n = model.nq();
    ws.hessian.fill(0.0);
    ws.gradient.fill(0.0);
    for t in &tasks.markers {
        let x = frame.targets[t.target];
        if x.x.is_nan() || t.weight == 0.0 {
            continue;
        }
        let m = &model.markers[t.marker];
        dynamics::point_jacobian(model, &ws.data, m.body, &m.location_in_body, &mut ws.jac)?;
        let r = ws.data.point_position(m.body, &m.location_in_body) - x;
        let w = frame.marker_scale * t.weight;
        // The columns this marker moves with (those of the joints between it and ground),
        // gathered with their Jacobian columns.
        let jac = ws.jac.as_slice(); // column-major 3 × n
        ws.cols.clear();
        ws.jcols.clear();
        for a in 0..n {
            let c = [jac[3 * a], jac[3 * a + 1], jac[3 * a + 2]];
            if c != [0.0; 3] {
                ws.cols.push(a);
                ws.jcols.push(c);
            }
        }
        // H += w Jᵀ J (upper triangle),  g += w Jᵀ r
        let h = ws.hessian.as_mut_slice();
        for (i, (&a, ja)) in ws.cols.iter().zip(&ws.jcols).enumerate() {
            ws.gradient[a] += w * (ja[0] * r.x + ja[1] * r.y + ja[2] * r.z);
            let wa = [w * ja[0], w * ja[1], w * ja[2]];
            for (&b, jb) in ws.cols[i..].iter().zip(&ws.jcols[i..]) {
                h[a + b * n] += wa[0] * jb[0] + wa[1] * jb[1] + wa[2] * jb[2];
            }
        }
    }
    for t in &tasks.coordinates {
        let v = t.value[if t.value.len() == 1 { 0 } else { frame.index }];
        ws.hessian[(t.q, t.q)] += t.weight;
        ws.gradient[t.q] += t.weight * (ws.q[t.q] - v);
    }
    if frame.smoothness > 0.0 {
        for j in 0..n {
            ws.hessian[(j, j)] += frame.smoothness;
            ws.gradient[j] += frame.smoothness * (ws.q[j] - ws.q_prev[j]);
        }
    }
    for a in 0..n {
        for b in 0..a {
            ws.hessian[(a, b)] = ws.hessian[(b, a)];
        }
    }
    Ok(())
}

/// Solves (H_FF + μ D_FF + ε I) δ_F = −g_F by Cholesky (L Lᵀ) on the free
/// coordinates packed together (`chol`, m × m row-major), δ = 0 off the free set; false when
/// the damped matrix is not positive definite.
fn damped_step(ws: &mut IkWorkspace, mu: f64) -> bool {
    let n = ws.gradient.len();
    ws.cols.clear();
    ws.cols.extend((0..n).filter(|&j| ws.free[j]));
    let m = ws.cols.len();
    let h = ws.hessian.as_slice(); // column-major n × n, symmetric
    // Marquardt's scaling D = diag H, floored at 10⁻² of its largest entry so that poorly
    // determined coordinates (a forearm's roll seen by one joint centre) cannot take long
    // steps that the next iterations must walk back.
    let floor = 1e-2 * (0..n).map(|j| h[j + j * n]).fold(0.0f64, f64::max);
    let l = &mut ws.chol[..m * m];
    // L_ik = (A_ik − Σ_{p<k} L_ip L_kp) / L_kk,  L_ii = √(A_ii − Σ_{p<i} L_ip²)
    // (row-major L; the reciprocals 1/L_kk kept in `inv_diag` to avoid divisions)
    let inv = &mut ws.inv_diag[..m];
    for i in 0..m {
        let gi = ws.cols[i];
        let (done, row) = l.split_at_mut(i * m);
        let row = &mut row[..m];
        for k in 0..=i {
            let gk = ws.cols[k];
            let a = h[gi + gk * n];
            let lk: &[f64] = if k == i {
                &row[..k]
            } else {
                &done[k * m..k * m + k]
            };
            let dot = dot(&row[..k], lk);
            if k == i {
                let s = a + mu * a.max(floor) + 1e-12 * (1.0 + a) - dot;
                if !(s > 0.0 && s.is_finite()) {
                    return false;
                }
                row[i] = s.sqrt();
                inv[i] = 1.0 / row[i];
            } else {
                row[k] = (a - dot) * inv[k];
            }
        }
    }
    // L y = −g,  Lᵀ δ = y (y and δ packed in `packed`)
    let y = &mut ws.packed[..m];
    for i in 0..m {
        let d = dot(&l[i * m..i * m + i], &y[..i]);
        y[i] = (-ws.gradient[ws.cols[i]] - d) * inv[i];
    }
    for i in (0..m).rev() {
        let mut s = y[i];
        for p in i + 1..m {
            s -= l[p * m + i] * y[p];
        }
        y[i] = s * inv[i];
    }
    ws.step.fill(0.0);
    for (i, &g) in ws.cols.iter().enumerate() {
        ws.step[g] = y[i];
    }
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
) -> crate::Result<(f64, u32)> {
    let mut f = objective(model, &mut ws.data, tasks, frame, &ws.q, &ws.q_prev)?;
    ws.evaluations += 1;
    let mut mu = ws.mu;
    let mut iterations = 0u32;
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
                // −2 (gᵀδ + ½ δᵀHδ)  (g and H are those of f/2)
                let h = ws.hessian.as_slice();
                let mut quadratic = 0.0;
                let mut linear = 0.0;
                for b in 0..n {
                    let db = ws.step[b];
                    if db == 0.0 {
                        continue;
                    }
                    linear += ws.gradient[b] * db;
                    let column = &h[b * n..(b + 1) * n];
                    let hd = dot(column, ws.step.as_slice());
                    quadratic += db * hd;
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
                    if largest <= tolerance || decrease <= RELATIVE_DECREASE * f {
                        return Ok((f, iterations));
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
    // Leave forward kinematics at the solution.
    dynamics::forward_kinematics(model, &mut ws.data, &ws.q)?;
    Ok((f, iterations))
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
    solve(model, targets, tasks, settings, None, progress)
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
    solve(model, targets, tasks, settings, Some(starts), progress)
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
    let n = model.nq();
    let mut ws = IkWorkspace::new(model, settings.bounds);
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
    ws.q_prev.copy_from_slice(&ws.q);
    ws.q_prev2.copy_from_slice(&ws.q);
    let frames = targets.n_frames();
    let nm = tasks.markers.len();
    let mut out = IkSolution {
        nq: n,
        time: targets.time.clone(),
        q: Vec::with_capacity(frames * n),
        objective: Vec::with_capacity(frames),
        marker_error: Vec::with_capacity(frames * nm),
        rmse: Vec::with_capacity(frames),
        max_error: Vec::with_capacity(frames),
        at_limit: Vec::with_capacity(frames),
        iterations: Vec::with_capacity(frames),
        evaluations: Vec::with_capacity(frames),
    };
    for f in 0..frames {
        // Start from the previous solution moved on at its last velocity (constant-velocity
        // prediction, q̂ = q_{f−1} + (t_f − t_{f−1})/(t_{f−1} − t_{f−2}) · (q_{f−1} − q_{f−2})),
        // kept within bounds: at 20 fps a walking pelvis moves 7 cm a frame. A frame with no
        // target at all keeps the previous pose.
        let has_data = tasks
            .markers
            .iter()
            .any(|t| t.weight > 0.0 && !targets.frame(f)[t.target].x.is_nan())
            || tasks.coordinates.iter().any(|t| t.weight > 0.0);
        if let Some(starts) = starts {
            for j in 0..n {
                ws.q[j] = starts.frame(f)[j].clamp(ws.lo[j], ws.hi[j]);
            }
        } else if f >= 2 && has_data {
            let ratio = (targets.time[f] - targets.time[f - 1])
                / (targets.time[f - 1] - targets.time[f - 2]);
            for j in 0..n {
                ws.q[j] = (ws.q_prev[j] + ratio * (ws.q_prev[j] - ws.q_prev2[j]))
                    .clamp(ws.lo[j], ws.hi[j]);
            }
        }
        let frame_targets = targets.frame(f);
        let present_weight: f64 = tasks
            .markers
            .iter()
            .filter(|t| !frame_targets[t.target].x.is_nan())
            .map(|t| t.weight)
            .sum();
        let frame = Frame {
            targets: frame_targets,
            index: f,
            // The first frame has no predecessor to stay close to.
            smoothness: if f == 0 { 0.0 } else { settings.smoothness },
            marker_scale: if settings.normalize_marker_weights && present_weight > 0.0 {
                1.0 / present_weight
            } else {
                1.0
            },
        };
        let max_iterations = if f == 0 {
            settings.max_iterations * 10
        } else {
            settings.max_iterations
        };
        ws.evaluations = 0;
        let (value, iterations) = solve_frame(
            model,
            &mut ws,
            tasks,
            &frame,
            max_iterations,
            settings.tolerance,
        )?;
        out.evaluations.push(ws.evaluations);
        out.q.extend_from_slice(&ws.q);
        out.objective.push(value);
        out.iterations.push(iterations);
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
            (0..n)
                .filter(|&j| ws.q[j] <= ws.lo[j] || ws.q[j] >= ws.hi[j])
                .collect(),
        );
        std::mem::swap(&mut ws.q_prev, &mut ws.q_prev2);
        ws.q_prev.copy_from_slice(&ws.q);
        progress(f + 1);
    }
    Ok(out)
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
