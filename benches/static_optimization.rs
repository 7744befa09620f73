//! Static optimization speed: the whole `musculo so` computation on OpenSim's Gait2392 walk
//! (92 muscles + 6 residual actuators, 23 coordinates, 1500 frames, one thread), its per-frame
//! stages, and the per-frame QP beside the peer a user would otherwise call in the same
//! process — Clarabel, an interior-point solver, on the identical problem (ratio musculo /
//! Clarabel, < 1: faster). A synthetic problem of the default full-body model's size (324
//! muscles + 29 reserves, 29 equations) is timed the same way.
//!
//! Run: `cargo bench --bench static_optimization` (needs ../shared/reference for the walk).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT,
    ZeroConeT,
};
use musculo::io::Table;
use musculo::io::setup::AnalyzeSetup;
use musculo::model::LoadOptions;
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::prepare_coordinates;
use musculo::solve::kinematics::Differentiation;
use musculo::solve::qp::{QpMatrix, QpProblem, QpSettings, QpWorkspace};
use musculo::solve::static_optimization::{
    SoFrame, SoRunOptions, SoWorkspace, StaticOptimization, StaticOptimizationOptions,
    run_static_optimization,
};
use musculo::{Data, Model, dynamics};
use nalgebra::DMatrix;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

const REPEATS: usize = 7;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Median over `REPEATS` of the mean µs per item of `f` over `items` items.
fn time_per_item(items: usize, mut f: impl FnMut()) -> f64 {
    median(
        (0..REPEATS)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e6 / items as f64
            })
            .collect(),
    )
}

fn reference_dir() -> PathBuf {
    std::env::var_os("MUSCULO_REFERENCE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference"))
        })
}

/// The SO problem of one frame.
struct Frame {
    a: DMatrix<f64>,
    b: Vec<f64>,
}

/// Clarabel on min Σ x² s.t. A x = b, l ≤ x ≤ u, with its default tolerances (as a user
/// would call it) or `tight` ones (1e-11, to check solutions); returns x and whether it
/// solved.
fn clarabel(
    a: &DMatrix<f64>,
    b: &[f64],
    lower: &[f64],
    upper: &[f64],
    tight: bool,
) -> (Vec<f64>, bool) {
    let (n, m) = a.shape();
    let (mut rows, mut cols, mut vals, mut rhs) = (vec![], vec![], vec![], b.to_vec());
    for i in 0..m {
        for k in 0..n {
            if a[(k, i)] != 0.0 {
                rows.push(k);
                cols.push(i);
                vals.push(a[(k, i)]);
            }
        }
    }
    let mut count = 0;
    for i in 0..m {
        for (bound, sign) in [(upper[i], 1.0), (lower[i], -1.0)] {
            if bound.is_finite() {
                rows.push(rhs.len());
                cols.push(i);
                vals.push(sign);
                rhs.push(sign * bound);
                count += 1;
            }
        }
    }
    let idx: Vec<usize> = (0..m).collect();
    let p = CscMatrix::new_from_triplets(m, m, idx.clone(), idx, vec![2.0; m]);
    let a = CscMatrix::new_from_triplets(rhs.len(), m, rows, cols, vals);
    let cones: Vec<SupportedConeT<f64>> = vec![ZeroConeT(n), NonnegativeConeT(count)];
    let settings = if tight {
        DefaultSettings {
            verbose: false,
            max_iter: 200,
            tol_gap_abs: 1e-11,
            tol_gap_rel: 1e-11,
            tol_feas: 1e-11,
            tol_ktratio: 1e-9,
            ..DefaultSettings::default()
        }
    } else {
        DefaultSettings {
            verbose: false,
            ..DefaultSettings::default()
        }
    };
    let mut solver =
        DefaultSolver::new(&p, &vec![0.0; m], &a, &rhs, &cones, settings).expect("valid problem");
    solver.solve();
    let ok = matches!(
        solver.solution.status,
        SolverStatus::Solved | SolverStatus::AlmostSolved
    );
    (solver.solution.x.clone(), ok)
}

/// Times musculo's QP (warm-started frame to frame, and cold) and Clarabel on `frames`; prints
/// a table row per case and the largest difference of the solutions.
fn qp_versus_clarabel(label: &str, frames: &[Frame], lower: &[f64], upper: &[f64]) {
    let (n, m) = frames[0].a.shape();
    let mut ws = QpWorkspace::new(n, m);
    let settings = QpSettings::default();
    let cold = QpSettings {
        warm_start: false,
        ..QpSettings::default()
    };
    let weights = vec![1.0; m];
    let solve = |f: &Frame, s: &QpSettings, ws: &mut QpWorkspace| -> (Vec<f64>, usize) {
        let p = QpProblem {
            a: QpMatrix::Dense(f.a.as_view()),
            b: &f.b,
            weights: &weights,
            lower,
            upper,
        };
        let sol = ws.solve(&p, s).expect("valid problem");
        (sol.x.to_vec(), sol.iterations)
    };
    let warm_us = time_per_item(frames.len(), || {
        for f in frames {
            black_box(solve(f, &settings, &mut ws));
        }
    });
    let cold_us = time_per_item(frames.len(), || {
        for f in frames {
            black_box(solve(f, &cold, &mut ws));
        }
    });
    let iterations: usize = frames.iter().map(|f| solve(f, &settings, &mut ws).1).sum();
    let clarabel_us = time_per_item(frames.len(), || {
        for f in frames {
            black_box(clarabel(&f.a, &f.b, lower, upper, false));
        }
    });
    let mut worst = 0.0f64;
    let mut unsolved = 0;
    for f in frames {
        let (x, _) = solve(f, &cold, &mut ws);
        let (y, ok) = clarabel(&f.a, &f.b, lower, upper, true);
        if !ok {
            unsolved += 1;
            continue;
        }
        for (a, b) in x.iter().zip(&y) {
            worst = worst.max((a - b).abs() / (1.0 + b.abs()));
        }
    }
    println!(
        "{label:<34} {n:>3}×{m:<4} {warm_us:>10.1} {cold_us:>10.1} {:>6.1} {clarabel_us:>11.1} {:>9.3} {:>9.3}   {worst:.1e}{}",
        iterations as f64 / frames.len() as f64,
        warm_us / clarabel_us,
        cold_us / clarabel_us,
        if unsolved > 0 {
            format!(" (Clarabel failed {unsolved})")
        } else {
            String::new()
        }
    );
}

fn gait2392() {
    let dir = reference_dir().join("opensim-models/Tutorials/Estimating_Joint_Reaction_Loads");
    let setup_path = dir.join("setup_static_optimization.xml");
    if !setup_path.exists() {
        println!("gait2392 walk: skipped (reference data not found)");
        return;
    }
    let setup = AnalyzeSetup::read(&setup_path).unwrap();
    let model = Model::from_osim_file_with_force_sets(
        dir.join("subject01_simbody_adjusted_StaticOp.osim"),
        &LoadOptions::default(),
        &setup.force_set_files,
        setup.replace_force_set,
    )
    .unwrap();
    let so = StaticOptimization::new(&model, StaticOptimizationOptions::default()).unwrap();
    let coordinates_path = setup.coordinates_file.clone().unwrap();
    let table = Table::read(&coordinates_path).unwrap();
    let source = coordinates_path.display().to_string();
    let loads =
        ExternalLoadSet::read(&model, setup.external_loads_file.as_deref().unwrap()).unwrap();
    let options = SoRunOptions::default();

    // Whole trial, as `musculo so` computes it (coordinate preparation included).
    let mut frames = 0;
    let whole = median(
        (0..REPEATS)
            .map(|_| {
                let t = Instant::now();
                let run = run_static_optimization(
                    &model,
                    &so,
                    &table,
                    &source,
                    Some(&loads),
                    &options,
                    &mut |_, _| {},
                )
                .unwrap();
                frames = run.activation.n_rows();
                black_box(&run);
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    println!(
        "gait2392 walk, whole trial: {frames} frames, {} actuators ({} muscles), {} coordinates, 1 thread",
        so.actuators.len(),
        so.muscles.len(),
        model.nq()
    );
    println!(
        "  {:.1} ms per trial = {:.1} µs per frame = {:.0} frames/s/core",
        whole * 1e3,
        whole * 1e6 / frames as f64,
        frames as f64 / whole
    );

    // Per-frame stages over the same frames.
    let mut warnings = vec![];
    let prepared = prepare_coordinates(
        &model,
        &table,
        &source,
        None,
        Differentiation::SplineOfSpeeds,
        &mut warnings,
    )
    .unwrap();
    let n = model.nq();
    let states: Vec<(f64, Vec<f64>, Vec<f64>, Vec<f64>)> = prepared
        .time
        .iter()
        .map(|&t| {
            let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            prepared.trajectory.eval(t, &mut q, &mut qd, &mut qdd);
            (t, q, qd, qdd)
        })
        .collect();
    let mut data = Data::new(&model);
    let mut ws = SoWorkspace::new(&model, &so);
    let mut out = SoFrame::new(&so, &model);
    let mut tau = vec![0.0; n];
    let mut ext = vec![0.0; n];
    let mut id = |data: &mut Data, s: &(f64, Vec<f64>, Vec<f64>, Vec<f64>), tau: &mut [f64]| {
        tau.copy_from_slice(
            dynamics::rnea(&model, data, &s.1, &s.2, &s.3)
                .unwrap()
                .as_slice(),
        );
        ext.fill(0.0);
        loads
            .add_generalized_forces(&model, data, s.0, &mut ext)
            .unwrap();
        for (t, e) in tau.iter_mut().zip(&ext) {
            *t -= e;
        }
    };
    let spline_us = time_per_item(states.len(), || {
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for s in &states {
            prepared.trajectory.eval(s.0, &mut q, &mut qd, &mut qdd);
            black_box(&qdd);
        }
    });
    let id_us = time_per_item(states.len(), || {
        for s in &states {
            id(&mut data, s, &mut tau);
            black_box(&tau);
        }
    });
    let assemble_us = time_per_item(states.len(), || {
        for s in &states {
            id(&mut data, s, &mut tau);
            so.assemble(&model, &data, &tau, &mut ws).unwrap();
            black_box(&ws.a);
        }
    }) - id_us;
    let solve_us = time_per_item(states.len(), || {
        for s in &states {
            id(&mut data, s, &mut tau);
            so.solve_frame(&model, &data, &tau, &mut ws, &mut out)
                .unwrap();
            black_box(&out.controls);
        }
    }) - id_us
        - assemble_us;
    println!(
        "  per frame: splines {spline_us:.2} µs, inverse dynamics + loads {id_us:.2} µs, \
         muscle paths + F_opt + A {assemble_us:.2} µs, QP {solve_us:.2} µs"
    );

    // The QP alone, beside Clarabel, on every 10th frame's problem.
    let mut problems = vec![];
    for s in states.iter().step_by(10) {
        id(&mut data, s, &mut tau);
        so.assemble(&model, &data, &tau, &mut ws).unwrap();
        problems.push(Frame {
            a: DMatrix::from_fn(ws.a.nrows(), ws.a.ncols(), |r, c| {
                ws.a.get(r, c).expect("entry")
            }),
            b: ws.b.clone(),
        });
    }
    let lower: Vec<f64> = so.actuators.iter().map(|a| a.min_control).collect();
    let upper: Vec<f64> = so.actuators.iter().map(|a| a.max_control).collect();
    println!();
    header();
    qp_versus_clarabel(
        "gait2392 walk frames (every 10th)",
        &problems,
        &lower,
        &upper,
    );
}

fn header() {
    println!(
        "{:<34} {:>8} {:>10} {:>10} {:>6} {:>11} {:>9} {:>9}   max |Δx|/(1+|x|) vs Clarabel at 1e-11",
        "QP per frame (µs)", "n×m", "warm", "cold", "iters", "Clarabel", "warm/Cl", "cold/Cl"
    );
}

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Frames of a problem the size of the default full-body model: 29 equations, a reserve per
/// equation (optimal force 1000 N·m... scaled like OpenSim's reserves) and 324 muscles each
/// crossing 1–3 consecutive coordinates, moment arm × F smoothly varying from frame to frame
/// as a motion would make them; b = A x for activations in [0, 0.6].
fn full_body_sized() {
    let (n, muscles, frames) = (29, 324, 100);
    let m = n + muscles;
    let mut rng = Rng(7);
    let mut base = DMatrix::zeros(n, m);
    let mut span = vec![];
    for j in 0..n {
        base[(j, j)] = 1.0;
    }
    for i in n..m {
        let len = 1 + (rng.unit() * 3.0) as usize;
        let start = (rng.unit() * (n - len + 1) as f64) as usize;
        for k in start..start + len {
            let sign = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
            base[(k, i)] = sign * (0.01 + 0.05 * rng.unit()) * (200.0 + 2800.0 * rng.unit());
        }
        span.push(rng.unit() * std::f64::consts::TAU);
    }
    let mut lower = vec![f64::NEG_INFINITY; n];
    let mut upper = vec![f64::INFINITY; n];
    lower.extend(std::iter::repeat_n(0.01, muscles));
    upper.extend(std::iter::repeat_n(1.0, muscles));
    let problems: Vec<Frame> = (0..frames)
        .map(|f| {
            let phase = f as f64 * 0.02;
            let mut a = base.clone();
            for i in n..m {
                let s = 1.0 + 0.2 * (phase + span[i - n]).sin();
                for k in 0..n {
                    a[(k, i)] *= s;
                }
            }
            let x: Vec<f64> = (0..m)
                .map(|i| {
                    if i < n {
                        0.0
                    } else {
                        0.01 + 0.3 * (1.0 + (2.0 * phase + i as f64).sin())
                    }
                })
                .collect();
            let b = (&a * nalgebra::DVector::from_vec(x)).as_slice().to_vec();
            Frame { a, b }
        })
        .collect();
    qp_versus_clarabel("full-body size (synthetic)", &problems, &lower, &upper);
}

fn main() {
    gait2392();
    full_body_sized();
}
