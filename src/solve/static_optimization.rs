//! Static optimization, as OpenSim's StaticOptimization analysis defines it.
//!
//! Every scalar actuator k of the model (muscles, and CoordinateActuator, PointActuator and
//! TorqueActuator such as reserve and residual actuators) has one control x_k and produces
//! the force x_k F_k, where F_k is
//! - for a muscle with `use_muscle_physiology`: its rigid-tendon active force at full
//!   activation along the tendon, F_k = F_max f_L(ℓ̃) f_V(ṽ) cos α (OpenSim's
//!   `calcInextensibleTendonActiveFiberForce(s, 1)`; De Groote–Fregly: along the fiber, as
//!   OpenSim's);
//! - for a muscle without it: F_max;
//! - for other actuators: their optimal force.
//!
//! Per frame, with r_k the generalized force of actuator k per unit force (a muscle's moment
//! arms; a coordinate actuator's unit vector; Jᵀ d for a point actuator; J_ωᵀ a for a torque
//! actuator) and τ the generalized forces that inverse dynamics requires (M q̈ + C q̇ + G minus
//! the external loads), x solves
//!
//!   minimise Σ_k |x_k|^p   subject to   Σ_k r_k F_k x_k = τ,   x_min ≤ x ≤ x_max,
//!
//! p being OpenSim's `activation_exponent` (default 2). OpenSim states the equality on the
//! accelerations of the unconstrained coordinates, M⁻¹(Σ r F x − τ) = 0; M is invertible, so
//! the feasible set and the optimum are the same.
//!
//! Like OpenSim, the muscle force is x F_k alone: the passive fiber force is not applied
//! (OpenSim overrides each actuator's force with x F_k). [`StaticOptimizationOptions::passive_fiber_force`]
//! adds it, as a force that does not depend on x, for those who want it.

use crate::dynamics::{self, Data, Stage};
use crate::error::Error;
use crate::io::Table;
use crate::model::{ActuatorKind, Model};
use crate::muscle::MuscleSet;
use crate::muscle::hill::{HillMuscle, MuscleKind, MuscleState, MuscleStatus};
use crate::muscle::path::{PathData, compute_paths};
use crate::solve::external_loads::ExternalLoadSet;
use crate::solve::inverse_dynamics::{prepare_coordinates, rows_in_range};
use crate::solve::kinematics::{CoordinateTrajectory, Differentiation};
use crate::solve::qp::{QpMatrix, QpProblem, QpSettings, QpStatus, QpWorkspace, SparseColumns};
use crate::spatial::Vec3;
use crate::text::short_number;

/// Options of [`StaticOptimization`] (the StaticOptimization analysis' properties).
#[derive(Clone, Debug)]
pub struct StaticOptimizationOptions {
    /// p in Σ|x|^p (`activation_exponent`), > 1.
    pub activation_exponent: f64,
    /// Muscle force from the force–length–velocity relations (rigid tendon) rather than F_max
    /// (`use_muscle_physiology`).
    pub use_muscle_physiology: bool,
    /// Also apply each muscle's passive fiber force (rigid tendon, along the tendon) as a
    /// force independent of the controls. OpenSim does not; off by default.
    pub passive_fiber_force: bool,
    /// Settings of the QP solver (its `exponent` is replaced by `activation_exponent`).
    pub qp: QpSettings,
}

impl Default for StaticOptimizationOptions {
    fn default() -> Self {
        StaticOptimizationOptions {
            activation_exponent: 2.0,
            use_muscle_physiology: true,
            passive_fiber_force: false,
            qp: QpSettings::default(),
        }
    }
}

/// One scalar actuator of the problem.
#[derive(Clone, Debug)]
pub struct SoActuator {
    pub name: String,
    /// Index in `Model::forces`.
    pub force: usize,
    /// For muscles, the index in [`StaticOptimization::muscles`].
    pub muscle: Option<usize>,
    pub kind: ActuatorKind,
    pub min_control: f64,
    pub max_control: f64,
    /// Optimal force (actuators) or F_max (muscles).
    pub optimal_force: f64,
}

/// The static-optimization problem of a model: its actuators and options. Immutable; one
/// [`SoWorkspace`] per thread.
#[derive(Clone, Debug)]
pub struct StaticOptimization {
    pub actuators: Vec<SoActuator>,
    pub muscles: MuscleSet,
    pub options: StaticOptimizationOptions,
    lower: Vec<f64>,
    upper: Vec<f64>,
    weights: Vec<f64>,
}

/// How a frame was solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SoStatus {
    /// The equality holds (to the solver tolerance) within the bounds.
    Solved,
    /// No controls within the bounds produce τ: the controls returned come as close as the
    /// bounds allow (least squares), and [`SoFrame::residual`] says by how much each
    /// coordinate misses.
    Infeasible,
    /// The solver stopped at its iteration limit (or on a numerical failure); the controls
    /// are its last iterate.
    NotConverged,
}

/// The solution of one frame.
#[derive(Clone, Debug)]
pub struct SoFrame {
    pub status: SoStatus,
    /// x (activations for muscles), in [`StaticOptimization::actuators`] order.
    pub controls: Vec<f64>,
    /// x F: each actuator's force (N) or torque (N·m).
    pub forces: Vec<f64>,
    /// τ − Σ r F x per independent coordinate (N or N·m): zero when solved.
    pub residual: Vec<f64>,
    /// Residuals above this (N or N·m) count as unbalanced: the solver's tolerance relative
    /// to the size of the balanced terms.
    pub residual_tolerance: f64,
    /// Solver iterations.
    pub iterations: u32,
}

impl SoFrame {
    pub fn new(so: &StaticOptimization, model: &Model) -> SoFrame {
        SoFrame {
            status: SoStatus::Solved,
            controls: vec![0.0; so.actuators.len()],
            forces: vec![0.0; so.actuators.len()],
            residual: vec![0.0; model.nq()],
            residual_tolerance: 0.0,
            iterations: 0,
        }
    }
}

/// Per-thread workspace: muscle paths, the constraint matrix and the QP solver's state
/// (warm-started from the previous frame).
#[derive(Clone, Debug)]
pub struct SoWorkspace {
    pub paths: PathData,
    /// Generalized force per unit control of each actuator (n × actuators) by its nonzero
    /// entries: column k is r_k F_k (a muscle's has a row for each coordinate it spans).
    pub a: SparseColumns,
    /// Right-hand side τ − (passive muscle forces).
    pub b: Vec<f64>,
    /// F_k of each actuator at this frame.
    pub unit_force: Vec<f64>,
    /// Per muscle, fiber length and velocity (rigid tendon) from the evaluation that gave
    /// F_k (NaN until then, and when muscle physiology is off): see
    /// [`StaticOptimization::fiber_kinematics`].
    fiber: Vec<(f64, f64)>,
    column: Vec<f64>,
    qp: QpWorkspace,
}

impl SoWorkspace {
    pub fn new(model: &Model, so: &StaticOptimization) -> SoWorkspace {
        let (n, m) = (model.nq(), so.actuators.len());
        SoWorkspace {
            paths: PathData::new(model, &so.muscles.paths),
            a: SparseColumns::with_capacity(n, m),
            b: vec![0.0; n],
            unit_force: vec![0.0; m],
            fiber: vec![(f64::NAN, f64::NAN); so.muscles.muscles.len()],
            column: vec![0.0; n],
            qp: QpWorkspace::new(n, m),
        }
    }

    /// Forgets the previous solution (the next frame starts cold).
    pub fn reset(&mut self) {
        self.qp.clear_warm_start();
    }
}

impl StaticOptimization {
    /// The actuators of `model` that apply force (OpenSim drops disabled ones), in force-set
    /// order. A PathActuator, a muscle class musculo does not model, or fewer actuators than
    /// coordinates (OpenSim's "over-constrained system") is an error.
    pub fn new(model: &Model, options: StaticOptimizationOptions) -> crate::Result<Self> {
        if !(options.activation_exponent > 1.0 && options.activation_exponent.is_finite()) {
            return Err(Error::invalid(
                "activation_exponent",
                format!(
                    "must be a finite number greater than 1, got {}",
                    options.activation_exponent
                ),
            ));
        }
        let muscles = MuscleSet::new(model)?;
        let mut actuators = Vec::new();
        for (i, f) in model.forces.iter().enumerate() {
            let Some(act) = &f.actuator else { continue };
            if !f.applies_force {
                continue;
            }
            let model_err = |message: String| Error::Model {
                file: f.file_or(&model.source).to_string(),
                line: f.line,
                element: format!("{} \"{}\"", f.kind, f.name),
                message,
            };
            let (muscle, optimal_force) = match act.kind {
                ActuatorKind::Muscle => {
                    let k = muscles
                        .paths
                        .paths
                        .iter()
                        .position(|p| p.force == i)
                        .ok_or_else(|| model_err("muscle without a path".into()))?;
                    (Some(k), muscles.muscles[k].params().max_isometric_force)
                }
                ActuatorKind::Path => {
                    return Err(model_err(
                        "PathActuator is not supported by static optimization yet".into(),
                    ));
                }
                _ => (None, act.optimal_force),
            };
            actuators.push(SoActuator {
                name: f.name.clone(),
                force: i,
                muscle,
                kind: act.kind.clone(),
                min_control: act.min_control,
                max_control: act.max_control,
                optimal_force,
            });
        }
        if actuators.len() < model.nq() {
            return Err(Error::invalid(
                "model",
                format!(
                    "static optimization needs at least as many actuators as coordinates: {} \
                     actuators for {} coordinates (add reserve actuators, e.g. with --actuators)",
                    actuators.len(),
                    model.nq()
                ),
            ));
        }
        let mut settings = options.qp.clone();
        settings.exponent = options.activation_exponent;
        settings
            .validate()
            .map_err(|e| Error::invalid("options", e.to_string()))?;
        Ok(StaticOptimization {
            lower: actuators.iter().map(|a| a.min_control).collect(),
            upper: actuators.iter().map(|a| a.max_control).collect(),
            weights: vec![1.0; actuators.len()],
            actuators,
            muscles,
            options,
        })
    }

    /// Changes the control bounds of actuator `k` (e.g. [0, 1] for muscles whose model class
    /// defaults to a minimum of 0.01, to reproduce results of OpenSim versions before 4).
    pub fn set_control_bounds(&mut self, k: usize, min: f64, max: f64) -> crate::Result<()> {
        if k >= self.actuators.len() {
            return Err(Error::invalid(
                "k",
                format!("actuator {k} of {}", self.actuators.len()),
            ));
        }
        if min.is_nan()
            || max.is_nan()
            || min > max
            || min == f64::INFINITY
            || max == f64::NEG_INFINITY
        {
            return Err(Error::invalid(
                "bounds",
                format!("[{min}, {max}] is not an interval of controls"),
            ));
        }
        self.actuators[k].min_control = min;
        self.actuators[k].max_control = max;
        self.lower[k] = min;
        self.upper[k] = max;
        Ok(())
    }

    /// Actuator names, in order (the columns of the output files).
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.actuators.iter().map(|a| a.name.as_str())
    }

    /// Fills `ws.a`, `ws.b` and `ws.unit_force` for the state of `data` (velocity stage)
    /// and the required generalized forces `tau` (length `nq`).
    pub fn assemble(
        &self,
        model: &Model,
        data: &Data,
        tau: &[f64],
        ws: &mut SoWorkspace,
    ) -> crate::Result<()> {
        data.require(model, Stage::Velocity, "static optimization")?;
        let n = model.nq();
        if tau.len() != n {
            return Err(Error::invalid(
                "tau",
                format!("expected {n} values, got {}", tau.len()),
            ));
        }
        if ws.a.nrows() != n || ws.unit_force.len() != self.actuators.len() {
            return Err(Error::invalid(
                "workspace",
                "built for another model or problem",
            ));
        }
        if let Some(j) = tau.iter().position(|t| !t.is_finite()) {
            return Err(Error::invalid(
                "tau",
                format!("value for {} is not finite", model.q_names()[j]),
            ));
        }
        if !self.muscles.is_empty() {
            compute_paths(model, data, &self.muscles.paths, &mut ws.paths)?;
        }
        ws.b.copy_from_slice(tau);
        ws.a.clear();
        // r (n × paths, column-major): a muscle's column is its moment arms
        let arms = ws.paths.moment_arms.as_slice();
        for (k, act) in self.actuators.iter().enumerate() {
            let col = &mut ws.column;
            let (f, column): (f64, &[f64]) = match &act.kind {
                ActuatorKind::Muscle => {
                    let m = act.muscle.expect("muscle index");
                    let (f, fp) = self.muscle_forces(m, &ws.paths, &mut ws.fiber)?;
                    let arm = &arms[m * n..(m + 1) * n];
                    if let Some(fp) = fp {
                        for (b, r) in ws.b.iter_mut().zip(arm) {
                            *b -= r * fp;
                        }
                    }
                    (f, arm)
                }
                ActuatorKind::Coordinate { coordinate } => {
                    col.fill(0.0);
                    for (j, g) in data.coordinate_gradient(model, *coordinate) {
                        col[j] += g;
                    }
                    (act.optimal_force, col)
                }
                ActuatorKind::Point {
                    body,
                    point,
                    point_is_global,
                    direction,
                    force_is_global,
                } => {
                    col.fill(0.0);
                    let (rot, _) = data.body_pose(*body);
                    let p = if *point_is_global {
                        *point
                    } else {
                        data.point_position(*body, point)
                    };
                    let d = if *force_is_global {
                        *direction
                    } else {
                        rot * direction
                    };
                    dynamics::add_body_wrench(model, data, *body, &p, &d, &Vec3::zeros(), col)?;
                    (act.optimal_force, col)
                }
                ActuatorKind::Torque {
                    body_a,
                    body_b,
                    axis,
                    torque_is_global,
                } => {
                    col.fill(0.0);
                    let (rot, origin) = data.body_pose(*body_a);
                    let t = if *torque_is_global { *axis } else { rot * axis };
                    let zero = Vec3::zeros();
                    dynamics::add_body_wrench(model, data, *body_a, &origin, &zero, &t, col)?;
                    dynamics::add_body_wrench(model, data, *body_b, &origin, &zero, &-t, col)?;
                    (act.optimal_force, col)
                }
                ActuatorKind::Path => unreachable!("rejected by StaticOptimization::new"),
            };
            ws.unit_force[k] = f;
            ws.a.push_scaled(column, f)
                .map_err(|e| Error::invalid("static optimization", e.to_string()))?;
        }
        Ok(())
    }

    /// F_k of muscle `m` at the current lengths and speeds of `ws.paths`, and its passive
    /// fiber force along the tendon when the options subtract it; with muscle physiology, the
    /// state's fiber length and velocity go to `fiber[m]`. With a rigid tendon the passive
    /// force f_PE(l̃) F_max cos α depends on the fiber length only, so the unit-activation
    /// state that gives F_k holds it too.
    fn muscle_forces(
        &self,
        m: usize,
        paths: &PathData,
        fiber: &mut [(f64, f64)],
    ) -> crate::Result<(f64, Option<f64>)> {
        let muscle = &self.muscles.muscles[m];
        let passive = self.options.passive_fiber_force;
        if !self.options.use_muscle_physiology {
            let fp = passive.then(|| {
                let s = muscle.state_rigid_tendon(0.0, paths.length[m], paths.speed[m]);
                passive_along_tendon(muscle, &s)
            });
            return Ok((muscle.params().max_isometric_force, fp));
        }
        let s = muscle.state_rigid_tendon(1.0, paths.length[m], paths.speed[m]);
        fiber[m] = (s.fiber_length, s.fiber_velocity);
        let f = match s.status {
            MuscleStatus::FiberAtLowerBound => 0.0,
            _ if muscle.kind() == MuscleKind::DeGrooteFregly2016 => s.active_fiber_force,
            _ => s.active_fiber_force * s.cos_pennation_angle,
        };
        if !f.is_finite() {
            return Err(Error::invalid(
                "state",
                format!(
                    "muscle {}: active force is not finite at length {} m, speed {} m/s",
                    muscle.name(),
                    paths.length[m],
                    paths.speed[m]
                ),
            ));
        }
        Ok((f, passive.then(|| passive_along_tendon(muscle, &s))))
    }

    /// Fiber length and velocity of muscle `m` (rigid tendon) at the lengths and speeds of
    /// the last [`StaticOptimization::assemble`] on `ws`. With a rigid tendon neither depends
    /// on the activation (l = √(h² + (ℓ_MT − l_s)²), v = ℓ̇_MT cos α, and the clamp at the
    /// minimum length looks at l and v only), so the unit-activation state that gave F_k
    /// already holds them; without muscle physiology they are computed here.
    pub fn fiber_kinematics(&self, ws: &SoWorkspace, m: usize) -> (f64, f64) {
        if self.options.use_muscle_physiology {
            ws.fiber[m]
        } else {
            let s = self.muscles.muscles[m].state_rigid_tendon(
                0.0,
                ws.paths.length[m],
                ws.paths.speed[m],
            );
            (s.fiber_length, s.fiber_velocity)
        }
    }

    /// Solves one frame: `data` holds the state (velocity stage), `tau` the generalized
    /// forces inverse dynamics requires of the actuators (length `nq`).
    pub fn solve_frame(
        &self,
        model: &Model,
        data: &Data,
        tau: &[f64],
        ws: &mut SoWorkspace,
        out: &mut SoFrame,
    ) -> crate::Result<()> {
        self.assemble(model, data, tau, ws)?;
        self.solve_assembled(ws, out)
    }

    /// Solves the problem [`StaticOptimization::assemble`] left in `ws` (which the caller
    /// may have changed, e.g. another muscle force model: column k of `ws.a` is r_k F_k by
    /// its nonzero entries, `ws.unit_force[k]` is F_k).
    pub fn solve_assembled(&self, ws: &mut SoWorkspace, out: &mut SoFrame) -> crate::Result<()> {
        let mut settings = self.options.qp.clone();
        settings.exponent = self.options.activation_exponent;
        let problem = QpProblem {
            a: QpMatrix::Sparse(&ws.a),
            b: &ws.b,
            weights: &self.weights,
            lower: &self.lower,
            upper: &self.upper,
        };
        let solution = ws
            .qp
            .solve(&problem, &settings)
            .map_err(|e| Error::invalid("static optimization", e.to_string()))?;
        out.status = match solution.status {
            QpStatus::Solved => SoStatus::Solved,
            QpStatus::Infeasible => SoStatus::Infeasible,
            QpStatus::MaxIterations | QpStatus::NumericalError => SoStatus::NotConverged,
        };
        out.iterations = solution.iterations as u32;
        out.residual_tolerance = solution.residual_tolerance;
        out.controls.copy_from_slice(solution.x);
        for (r, s) in out.residual.iter_mut().zip(solution.residual) {
            *r = -s;
        }
        for k in 0..self.actuators.len() {
            out.forces[k] = out.controls[k] * ws.unit_force[k];
        }
        Ok(())
    }
}

/// The passive fiber force along the tendon in a rigid-tendon state (0 for a fiber held at
/// its minimum length).
fn passive_along_tendon(muscle: &HillMuscle, s: &MuscleState) -> f64 {
    match s.status {
        MuscleStatus::FiberAtLowerBound => 0.0,
        _ if muscle.kind() == MuscleKind::DeGrooteFregly2016 => s.passive_fiber_force,
        _ => s.passive_fiber_force * s.cos_pennation_angle,
    }
}

/// Settings of a whole-motion run ([`run_static_optimization`]): OpenSim's Analyze tool and
/// StaticOptimization analysis properties.
#[derive(Clone, Debug)]
pub struct SoRunOptions {
    /// Low-pass cutoff (Hz) for the coordinates (`lowpass_cutoff_frequency_for_coordinates`);
    /// None: no filtering.
    pub lowpass_hz: Option<f64>,
    /// [initial, final] time (s); None: the recorded span.
    pub time_range: Option<[f64; 2]>,
    /// Record the first and last rows and every row whose index in the prepared motion is a
    /// multiple of this (`step_interval`, ≥ 1).
    pub step_interval: usize,
}

impl Default for SoRunOptions {
    fn default() -> Self {
        SoRunOptions {
            lowpass_hz: None,
            time_range: None,
            step_interval: 1,
        }
    }
}

/// A frame the optimization could not solve exactly.
#[derive(Clone, Debug)]
pub struct FrameProblem {
    pub time: f64,
    pub status: SoStatus,
    /// The coordinates left unbalanced, with τ − Σ r F x (N or N·m), largest first: those
    /// above the solver's tolerance and above 10⁻³ of the largest.
    pub unbalanced: Vec<(String, f64)>,
}

/// The result of [`run_static_optimization`].
#[derive(Clone, Debug)]
pub struct SoRun {
    /// Controls (activations for muscles) per recorded row: OpenSim's `_activation.sto`.
    pub activation: Table,
    /// Actuator forces, then the external loads as OpenSim's force reporter records them:
    /// OpenSim's `_force.sto`.
    pub force: Table,
    /// Frames not solved exactly (infeasible or not converged); the run went on.
    pub problems: Vec<FrameProblem>,
    /// QP iterations over all frames.
    pub iterations: u64,
    /// Things the caller should know; the library never prints.
    pub warnings: Vec<String>,
}

/// OpenSim's Analyze tool with a StaticOptimization analysis: prepares the coordinates of
/// `coordinates` (read from `source`) as it does (optional padding and low-pass filtering,
/// quintic splines; q̈ from the spline of the speeds), then at each recorded row computes τ by
/// inverse dynamics with the external loads and solves [`StaticOptimization::solve_frame`],
/// warm-starting each frame from the previous one. `progress(done, total)` is called after
/// every frame.
pub fn run_static_optimization(
    model: &Model,
    so: &StaticOptimization,
    coordinates: &Table,
    source: &str,
    loads: Option<&ExternalLoadSet>,
    options: &SoRunOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> crate::Result<SoRun> {
    if options.step_interval == 0 {
        return Err(Error::invalid("step_interval", "must be at least 1"));
    }
    let mut warnings = Vec::new();
    let prepared = prepare_coordinates(
        model,
        coordinates,
        source,
        options.lowpass_hz,
        Differentiation::SplineOfSpeeds,
        &mut warnings,
    )?;
    let (i0, i1) = rows_in_range(&prepared, options.time_range, source, loads, &mut warnings)?;
    let rows: Vec<usize> = (i0..=i1)
        .filter(|&i| i == i0 || i == i1 || i % options.step_interval == 0)
        .collect();

    let n = model.nq();
    let m = so.actuators.len();
    let mut data = Data::new(model);
    let mut ws = SoWorkspace::new(model, so);
    let mut frame = SoFrame::new(so, model);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut tau = vec![0.0; n];
    let mut external = vec![0.0; n];
    let load_labels = loads.map(|l| l.record_labels(model)).unwrap_or_default();
    let mut activation = Vec::with_capacity(rows.len() * m);
    let mut force = Vec::with_capacity(rows.len() * (m + load_labels.len()));
    let mut problems = Vec::new();
    let mut iterations = 0u64;
    let names = model.q_names();
    for (k, &i) in rows.iter().enumerate() {
        let t = prepared.time[i];
        prepared
            .trajectory
            .eval_finite(t, &mut q, &mut qd, &mut qdd)?;
        // τ = M q̈ + C q̇ + G − Σ Jᵀ w_ext
        tau.copy_from_slice(dynamics::rnea(model, &mut data, &q, &qd, &qdd)?.as_slice());
        if let Some(l) = loads {
            external.fill(0.0);
            l.add_generalized_forces(model, &data, t, &mut external)?;
            for (v, e) in tau.iter_mut().zip(&external) {
                *v -= e;
            }
        }
        if let Some(j) = tau.iter().position(|v| !v.is_finite()) {
            let k = CoordinateTrajectory::largest(&q, &qd, &qdd);
            return Err(prepared.trajectory.error_at(
                t,
                k,
                format!(
                    "the generalized force on `{}` to balance is {}: this coordinate's value \
                     {}, speed {} and acceleration {} (the largest at this time) are beyond \
                     what the dynamics can compute",
                    names[j],
                    tau[j],
                    short_number(q[k]),
                    short_number(qd[k]),
                    short_number(qdd[k]),
                ),
            ));
        }
        so.solve_frame(model, &data, &tau, &mut ws, &mut frame)
            .map_err(|e| frame_error(&prepared.trajectory, &q, &qd, &qdd, t, e))?;
        iterations += frame.iterations as u64;
        if frame.status != SoStatus::Solved {
            // What misses: above the solver's tolerance and not negligible next to the
            // largest miss (the least-squares solution balances the rest only to ~1e-7 of it).
            let worst = frame.residual.iter().fold(0.0f64, |m, r| m.max(r.abs()));
            let threshold = frame.residual_tolerance.max(1e-3 * worst);
            let mut unbalanced: Vec<(String, f64)> = frame
                .residual
                .iter()
                .enumerate()
                .filter(|(_, r)| r.abs() > threshold)
                .map(|(j, &r)| (names[j].to_string(), r))
                .collect();
            unbalanced.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            problems.push(FrameProblem {
                time: t,
                status: frame.status,
                unbalanced,
            });
        }
        activation.extend_from_slice(&frame.controls);
        force.extend_from_slice(&frame.forces);
        if let Some(l) = loads {
            l.record(&data, t, &mut force);
        }
        progress(k + 1, rows.len());
    }
    let times: Vec<f64> = rows.iter().map(|&i| prepared.time[i]).collect();
    let actuator_names: Vec<String> = so.names().map(str::to_string).collect();
    let mut activation = Table::new(
        "Static Optimization",
        actuator_names.clone(),
        times.clone(),
        activation,
    )?;
    activation.in_degrees = Some(false);
    activation.description = vec!["This file contains static optimization results.".into()];
    let mut force_labels = actuator_names;
    force_labels.extend(load_labels);
    let mut force = Table::new("ModelForces", force_labels, times, force)?;
    force.in_degrees = Some(false);
    force.description = vec![
        "This file contains the forces exerted on a model during a simulation.".into(),
        "A force is a generalized force, meaning that it can be either a force (N) or a torque (Nm).".into(),
    ];
    Ok(SoRun {
        activation,
        force,
        problems,
        iterations,
        warnings,
    })
}

/// Names the frame in an error from one frame's solve.
fn frame_error(
    trajectory: &CoordinateTrajectory,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    t: f64,
    e: Error,
) -> Error {
    match e {
        // A value the frame's solve could not use: at the row of this time, in the column of
        // the coordinate that is largest then (the likeliest cause).
        Error::InvalidArgument { argument, message } => trajectory.error_at(
            t,
            CoordinateTrajectory::largest(q, qd, qdd),
            format!("static optimization (`{argument}`): {message}"),
        ),
        other => other,
    }
}
