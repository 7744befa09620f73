//! Inverse kinematics speed: frames per second on one core, default full-body model, the 22
//! HumanML3D joint-centre targets, each frame warm-started from the previous one.
//!
//! Beside musculo's solver (bound-constrained Levenberg–Marquardt, `solve::ik`) runs a peer
//! in the same process on the same frames, objective and analytic gradient: argmin's L-BFGS
//! (More–Thuente line search), the general-purpose optimiser of the Rust ecosystem. Both run
//! unbounded here so they solve the same problem; the table gives frames/s, the ratio, and
//! the median ratio of the objectives reached (argmin / musculo: ≥ 1 means musculo got as
//! low or lower). OpenSim 4.6's IK on the Gait2392 setup is timed by
//! `validation/opensim/run.sh` (ms per frame, same machine).
//!
//! A third line per case runs musculo as `musculo ik` does, every coordinate bounded by its
//! range (the unbounded figure is the one compared with the peer).
//!
//! Cases: the HumanML3D sample clip (real data: residuals of a cm; the model scaled to the
//! clip first) when the reference data is present, and a synthetic motion (targets made by
//! the model itself: zero residual).
//!
//! Run: `cargo bench --bench ik` (`IK_BENCH_NO_PEER=1` runs musculo alone, for profiling).

use argmin::core::{CostFunction, Executor, Gradient, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::LBFGS;
use musculo::dynamics::{self, Data};
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Motion};
use musculo::solve::ik::{self, Bounds, IkSettings, IkTasks};
use musculo::solve::scale_from_clip;
use musculo::spatial::Vec3;
use musculo::{Model, reference};
use nalgebra::DMatrix;
use std::cell::RefCell;
use std::time::Instant;

/// f(q) = Σ w ‖p(q) − x‖² and its gradient 2 Σ w Jᵀ (p − x), for argmin.
struct Frame<'a> {
    model: &'a Model,
    tasks: &'a IkTasks,
    targets: &'a [Vec3],
    data: RefCell<Data>,
    jac: RefCell<DMatrix<f64>>,
}

impl CostFunction for Frame<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, q: &Vec<f64>) -> Result<f64, argmin::core::Error> {
        let mut data = self.data.borrow_mut();
        dynamics::forward_kinematics(self.model, &mut data, q)?;
        let mut f = 0.0;
        for t in &self.tasks.markers {
            let m = &self.model.markers[t.marker];
            f += t.weight
                * (data.point_position(m.body, &m.location_in_body) - self.targets[t.target])
                    .norm_squared();
        }
        Ok(f)
    }
}

impl Gradient for Frame<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, q: &Vec<f64>) -> Result<Vec<f64>, argmin::core::Error> {
        let mut data = self.data.borrow_mut();
        let mut jac = self.jac.borrow_mut();
        dynamics::forward_kinematics(self.model, &mut data, q)?;
        let mut g = vec![0.0; q.len()];
        for t in &self.tasks.markers {
            let m = &self.model.markers[t.marker];
            dynamics::point_jacobian(self.model, &data, m.body, &m.location_in_body, &mut jac)?;
            let r = data.point_position(m.body, &m.location_in_body) - self.targets[t.target];
            for (j, gj) in g.iter_mut().enumerate() {
                *gj += 2.0 * t.weight * (jac[(0, j)] * r.x + jac[(1, j)] * r.y + jac[(2, j)] * r.z);
            }
        }
        Ok(g)
    }
}

/// argmin's L-BFGS over every frame, warm-started; returns (seconds, objective per frame).
fn argmin_lbfgs(model: &Model, targets: &Motion, tasks: &IkTasks, q0: &[f64]) -> (f64, Vec<f64>) {
    let mut q = q0.to_vec();
    let mut objective = Vec::with_capacity(targets.n_frames());
    let start = Instant::now();
    for f in 0..targets.n_frames() {
        let problem = Frame {
            model,
            tasks,
            targets: targets.frame(f),
            data: RefCell::new(Data::new(model)),
            jac: RefCell::new(DMatrix::zeros(3, model.nq())),
        };
        let solver = LBFGS::new(MoreThuenteLineSearch::new(), 10)
            .with_tolerance_cost(1e-14)
            .expect("valid tolerance")
            .with_tolerance_grad(1e-12)
            .expect("valid tolerance");
        let result = Executor::new(problem, solver)
            .configure(|s| s.param(q.clone()).max_iters(1000))
            .run()
            .expect("L-BFGS runs");
        q = result
            .state()
            .get_best_param()
            .expect("a best point")
            .clone();
        objective.push(result.state().get_best_cost());
    }
    (start.elapsed().as_secs_f64(), objective)
}

fn musculo_lm(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    q0: &[f64],
    relative_decrease: f64,
    bounds: Bounds,
) -> (f64, Vec<f64>) {
    let settings = IkSettings {
        bounds,
        initial_q: Some(q0.to_vec()),
        relative_decrease,
        ..IkSettings::default()
    };
    let start = Instant::now();
    let solution = ik::solve_motion(model, targets, tasks, &settings, &|_| {}).expect("IK runs");
    let seconds = start.elapsed().as_secs_f64();
    let per_frame = |v: &[u32]| v.iter().map(|&k| k as f64).sum::<f64>() / v.len() as f64;
    ITERATIONS.with(|i| {
        *i.borrow_mut() = (
            per_frame(&solution.iterations),
            per_frame(&solution.evaluations),
        )
    });
    (seconds, solution.objective)
}

thread_local! {
    /// Mean iterations and evaluations of f per frame of the last musculo run.
    static ITERATIONS: RefCell<(f64, f64)> = const { RefCell::new((0.0, 0.0)) };
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The best of `repeats` runs of `run` (seconds), and its objectives.
fn best_of(repeats: usize, run: impl Fn() -> (f64, Vec<f64>)) -> (f64, Vec<f64>) {
    let mut best = run();
    for _ in 1..repeats {
        let r = run();
        if r.0 < best.0 {
            best = r;
        }
    }
    best
}

fn report(name: &str, model: &Model, targets: &Motion, tasks: &IkTasks) {
    // Both start every run from the musculo solution of frame 0, so neither pays for the
    // first frame's long search from the default pose.
    let first = ik::solve_motion(
        model,
        &targets
            .time_window(targets.time[0], targets.time[0])
            .expect("frame 0"),
        tasks,
        &IkSettings {
            bounds: Bounds::None,
            ..IkSettings::default()
        },
        &|_| {},
    )
    .expect("IK runs");
    let q0 = first.frame(0).to_vec();
    let frames = targets.n_frames() as f64;
    let default = ik::RELATIVE_DECREASE;
    let (t_mus, f_mus) = best_of(20, || {
        musculo_lm(model, targets, tasks, &q0, default, Bounds::None)
    });
    let (it_mus, ev_mus) = ITERATIONS.with(|i| *i.borrow());
    // The same with the looser stopping rule `--relative-decrease 1e-6`: speed, and how far
    // above the default run's objective each frame ends.
    let loose = 1e-6;
    let (t_loose, f_loose) = best_of(20, || {
        musculo_lm(model, targets, tasks, &q0, loose, Bounds::None)
    });
    let (it_loose, _) = ITERATIONS.with(|i| *i.borrow());
    // As `musculo ik` runs it: every coordinate bounded by its range, default stopping rule.
    let (t_bounded, _) = best_of(20, || {
        musculo_lm(model, targets, tasks, &q0, default, Bounds::Range)
    });
    let (it_bounded, ev_bounded) = ITERATIONS.with(|i| *i.borrow());
    let bounded_line = format!(
        "{:<34} musculo {:>9.0} frames/s with the coordinate ranges as bounds, as `musculo ik` \
         runs ({it_bounded:.1} iterations and {ev_bounded:.1} evaluations of f per frame)",
        "",
        frames / t_bounded
    );
    let excess: Vec<f64> = f_loose
        .iter()
        .zip(&f_mus)
        .map(|(l, m)| (l - m) / (m + 1e-18))
        .collect();
    let loose_line = format!(
        "{:<34} musculo {:>9.0} frames/s with relative_decrease {loose:e} ({it_loose:.1} \
         iterations per frame; objective above the default run's by at most {:.1e} of it)",
        "",
        frames / t_loose,
        excess.iter().cloned().fold(0.0f64, f64::max)
    );
    if std::env::var_os("IK_BENCH_NO_PEER").is_some() {
        // For profiling musculo alone.
        println!(
            "{name:<34} musculo {:>9.0} frames/s, {it_mus:.1} iterations and {ev_mus:.1} \
             evaluations of f per frame",
            frames / t_mus
        );
        println!("{loose_line}");
        println!("{bounded_line}");
        return;
    }
    let (t_arg, f_arg) = best_of(2, || argmin_lbfgs(model, targets, tasks, &q0));
    let ratio: Vec<f64> = f_arg
        .iter()
        .zip(&f_mus)
        .map(|(a, m)| (a + 1e-18) / (m + 1e-18))
        .collect();
    println!(
        "{name:<34} {:>6} frames | musculo {:>9.0} frames/s | argmin L-BFGS {:>8.0} frames/s | \
         speed ratio {:>6.1}× | objective argmin/musculo: median {:.4}, min {:.4} | musculo \
         {:.1} iterations, {:.1} evaluations of f per frame",
        targets.n_frames(),
        frames / t_mus,
        frames / t_arg,
        t_arg / t_mus,
        median(ratio.clone()),
        ratio.iter().cloned().fold(f64::INFINITY, f64::min),
        it_mus,
        ev_mus
    );
    println!("{loose_line}");
    println!("{bounded_line}");
}

/// A smooth motion in the middle of every coordinate's range, and the 22 SMPL markers'
/// positions along it.
fn synthetic(model: &Model, frames: usize) -> (Motion, IkTasks) {
    let map = SkeletonMap::builtin("humanml3d").expect("built-in map");
    let names: Vec<String> = map.targets.iter().map(|t| t.marker.clone()).collect();
    let markers: Vec<usize> = names
        .iter()
        .map(|n| {
            model
                .markers
                .iter()
                .position(|m| &m.name == n)
                .expect("marker")
        })
        .collect();
    let mut data = Data::new(model);
    let mut positions = Vec::with_capacity(frames * names.len());
    for f in 0..frames {
        let t = f as f64 / 20.0;
        let q: Vec<f64> = model
            .reduction
            .independent
            .iter()
            .enumerate()
            .map(|(j, &c)| {
                let coord = &model.coordinates[c];
                let [lo, hi] = coord.range;
                let (lo, hi) = if coord.name.starts_with("pelvis_t") {
                    (-0.5, 0.5)
                } else if coord.name == "pelvis_rotation" {
                    (-1.0, 1.0)
                } else {
                    (lo, hi)
                };
                0.5 * (lo + hi) + 0.25 * (hi - lo) * (0.7 * t + j as f64).sin()
            })
            .collect();
        dynamics::forward_kinematics(model, &mut data, &q).expect("FK");
        for &i in &markers {
            let m = &model.markers[i];
            positions.push(data.point_position(m.body, &m.location_in_body));
        }
    }
    let motion = Motion::uniform("synthetic", names, 20.0, positions).expect("valid motion");
    let tasks = ik::tasks_by_name(model, &motion);
    (motion, tasks)
}

fn main() {
    let model = Model::default_fullbody();
    println!(
        "inverse kinematics, one core, default model ({} coordinates), 22 joint-centre targets",
        model.nq()
    );
    let path = reference::directory().join("humanml3d/new_joints_012314.npy");
    if path.exists() {
        let clip = motion::read(&path, None, &motion::ReadOptions::default()).expect("clip");
        let map = SkeletonMap::builtin("humanml3d").expect("built-in map");
        let fitted = scale_from_clip::scale_to_clip(
            musculo::DEFAULT_MODEL_OSIM,
            "default",
            &model,
            &map,
            &clip,
        )
        .expect("scaling")
        .model;
        let (targets, tasks) = map.apply(&fitted, &clip).expect("map");
        report("HumanML3D 012314 (scaled, real)", &fitted, &targets, &tasks);
    } else {
        println!(
            "(HumanML3D sample not found under {}: skipped)",
            path.display()
        );
    }
    let (targets, tasks) = synthetic(&model, 600);
    report("synthetic smooth motion (exact)", &model, &targets, &tasks);
}
