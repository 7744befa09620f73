//! The dual Newton solver against Clarabel (independent interior-point reference), the KKT
//! conditions, warm starts, infeasibility and bad input.

mod reference;

use super::*;
use nalgebra::DMatrix;
use reference::{
    Case, Rng, clarabel_least_residual, clarabel_power, clarabel_quadratic, random_case,
};

/// A solve's result, copied out of the workspace.
#[derive(Clone, Debug)]
struct Outcome {
    status: QpStatus,
    x: Vec<f64>,
    residual: Vec<f64>,
    residual_tolerance: f64,
    multipliers: Vec<f64>,
    objective: f64,
    iterations: usize,
}

fn run(workspace: &mut QpWorkspace, case: &Case, settings: &QpSettings) -> Outcome {
    let s = workspace
        .solve(&case.problem(), settings)
        .expect("valid problem");
    Outcome {
        status: s.status,
        x: s.x.to_vec(),
        residual: s.residual.to_vec(),
        residual_tolerance: s.residual_tolerance,
        multipliers: s.multipliers.to_vec(),
        objective: s.objective,
        iterations: s.iterations,
    }
}

fn cold(case: &Case, settings: &QpSettings) -> Outcome {
    run(&mut QpWorkspace::new(case.n(), case.m()), case, settings)
}

fn with_exponent(p: f64) -> QpSettings {
    QpSettings {
        exponent: p,
        ..QpSettings::default()
    }
}

/// (n, m, reserves, cases): OpenSim-like sizes — gait2392 (23 coordinates, 92 muscles) and a
/// full-body model (29 coordinates, 324 muscles) — and small and large ones.
const SIZES: [(usize, usize, usize, usize); 5] = [
    (3, 6, 1, 40),
    (10, 40, 3, 20),
    (23, 92, 6, 12),
    (29, 324, 6, 6),
    (40, 400, 8, 3),
];

/// x agrees to `tol` of each coordinate's box size, the objective to `objective_tol`.
fn assert_same_optimum(
    case: &Case,
    ours: &Outcome,
    x_ref: &[f64],
    f_ref: f64,
    tol: f64,
    objective_tol: f64,
    what: &str,
) {
    for i in 0..case.m() {
        let err = (ours.x[i] - x_ref[i]).abs() / case.box_size(i, x_ref[i]);
        assert!(
            err <= tol,
            "{what}: x[{i}] = {} vs reference {} (error {err:.2e} of the box)",
            ours.x[i],
            x_ref[i]
        );
    }
    let err = (ours.objective - f_ref).abs() / f_ref.abs().max(1e-300);
    assert!(
        err <= objective_tol,
        "{what}: objective {} vs reference {f_ref} (relative error {err:.2e})",
        ours.objective
    );
}

/// A cold solve of a feasible `case` with `settings` (p = 2): Solved, and the optimum Clarabel
/// finds (x to 1e-6 of each box, the objective to 1e-8). Returns our outcome.
fn solved_like_clarabel(case: &Case, settings: &QpSettings, what: &str) -> Outcome {
    let ours = cold(case, settings);
    assert_eq!(ours.status, QpStatus::Solved, "{what}: {ours:?}");
    let reference = clarabel_quadratic(case, &case.b);
    assert!(
        reference.solved(),
        "{what}: Clarabel {:?}",
        reference.status
    );
    assert_same_optimum(
        case,
        &ours,
        &reference.x,
        reference.objective,
        1e-6,
        1e-8,
        what,
    );
    ours
}

#[test]
fn matches_clarabel_on_random_feasible_problems() {
    let mut rng = Rng(1);
    let settings = QpSettings::default();
    for (n, m, reserves, count) in SIZES {
        for k in 0..count {
            let case = random_case(&mut rng, n, m, reserves);
            solved_like_clarabel(&case, &settings, &format!("n = {n}, m = {m}, case {k}"));
        }
    }
}

#[test]
fn matches_clarabel_power_cone_for_exponents_other_than_two() {
    let mut rng = Rng(2);
    for p in [1.5, 3.0] {
        let settings = with_exponent(p);
        for (n, m, reserves, count) in [(3, 6, 1, 10), (10, 40, 3, 6), (23, 92, 6, 3)] {
            for k in 0..count {
                let case = random_case(&mut rng, n, m, reserves);
                let ours = cold(&case, &settings);
                let reference = clarabel_power(&case, &case.b, p);
                let what = format!("p = {p}, n = {n}, m = {m}, case {k}");
                assert_eq!(ours.status, QpStatus::Solved, "{what}");
                assert!(
                    reference.solved(),
                    "{what}: Clarabel {:?}",
                    reference.status
                );
                // Clarabel's power-cone x is accurate to about √(gap tolerance) ≈ 3e-6 (the
                // objective is flat at the optimum; on the worst case here ours has both the
                // lower objective and a residual 1e4 times smaller), so x is compared at 1e-5
                // and the KKT conditions of ours are checked tightly.
                assert_kkt(&case, &ours, p, &what);
                assert_same_optimum(
                    &case,
                    &ours,
                    &reference.x,
                    reference.objective,
                    1e-5,
                    1e-8,
                    &what,
                );
            }
        }
    }
}

/// Makes `case` infeasible by asking a row k that no reserve actuator acts on for `factor`
/// times the most its muscles can give, plus `extra`; None when no row has a positive
/// capacity (every muscle on it pulls the other way).
fn make_infeasible(case: &mut Case, rng: &mut Rng, factor: f64, extra: f64) -> Option<usize> {
    let rows: Vec<(usize, f64)> = (case.reserves..case.n())
        .filter_map(|k| case.row_capacity(k).map(|cap| (k, cap)))
        .filter(|(_, cap)| *cap > 0.0)
        .collect();
    if rows.is_empty() {
        return None;
    }
    let (k, cap) = rows[rng.below(rows.len())];
    case.b[k] = factor * cap + extra;
    Some(k)
}

#[test]
fn infeasible_problems_match_clarabel_verdict_and_least_residual() {
    let mut rng = Rng(3);
    let settings = QpSettings::default();
    for (n, m, reserves, count) in SIZES {
        for k in 0..count.div_ceil(2) {
            // far outside A·box, then just outside (by 1e-4 of the row's capacity)
            let (factor, label) = if k % 2 == 0 {
                (1.5, "far")
            } else {
                (1.0001, "barely")
            };
            let case = loop {
                let mut case = random_case(&mut rng, n, m, reserves);
                if make_infeasible(&mut case, &mut rng, factor, 0.0).is_some() {
                    break case;
                }
            };
            let what = format!("n = {n}, m = {m}, {label} infeasible case {k}");
            let ours = cold(&case, &settings);
            assert_eq!(ours.status, QpStatus::Infeasible, "{what}: {ours:?}");
            let reference = clarabel_quadratic(&case, &case.b);
            assert!(
                reference.infeasible(),
                "{what}: Clarabel {:?}",
                reference.status
            );

            // The residual is the least achievable over the box (r* is unique).
            let (status, r_ref) = clarabel_least_residual(&case);
            assert!(
                matches!(status, clarabel::solver::SolverStatus::Solved),
                "{what}"
            );
            let b_max = case.b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            for (r, rr) in ours.residual.iter().zip(&r_ref) {
                assert!(
                    (r - rr).abs() <= 1e-7 * b_max,
                    "{what}: residual {r} vs {rr}"
                );
            }
            let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!(norm(&ours.residual) <= norm(&r_ref) * (1.0 + 1e-9) + 1e-9 * b_max);
            for i in 0..m {
                assert!(case.lower[i] <= ours.x[i] && ours.x[i] <= case.upper[i]);
            }

            // Among the x with that residual, ours has the least objective: Clarabel on the
            // right-hand side A x we reached (on the boundary of A·box) agrees.
            let mut reached = case.clone();
            reached.set_b_from(&ours.x);
            let tie = clarabel_quadratic(&reached, &reached.b);
            assert!(tie.solved(), "{what}: Clarabel on A x: {:?}", tie.status);
            assert_same_optimum(&case, &ours, &tie.x, tie.objective, 1e-5, 1e-7, &what);
        }
    }
}

#[test]
fn infeasible_solution_is_least_residual_then_least_objective() {
    // x₀ + x₁ = 10 is out of reach for x₀, x₁ ∈ [0, 1]; x₀ + x₂ + x₃ = 3 is reachable;
    // the least residual pins x₀ = x₁ = 1, then min x₂² + 4x₃² s.t. x₂ + x₃ = 2 gives
    // x₂ = 1.6, x₃ = 0.4. A third row no column acts on keeps its b as residual.
    let a = DMatrix::from_row_slice(
        3,
        4,
        &[1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    );
    let case = Case {
        a,
        b: vec![10.0, 3.0, -0.5],
        weights: vec![1.0, 1.0, 1.0, 4.0],
        lower: vec![0.0, 0.0, 0.0, 0.0],
        upper: vec![1.0, 1.0, 5.0, 5.0],
        reserves: 0,
        x_true: vec![0.0; 4],
    };
    let ours = cold(&case, &QpSettings::default());
    assert_eq!(ours.status, QpStatus::Infeasible);
    for (x, e) in ours.x.iter().zip([1.0, 1.0, 1.6, 0.4]) {
        assert!((x - e).abs() < 1e-7, "{:?}", ours.x);
    }
    for (r, e) in ours.residual.iter().zip([-8.0, 0.0, 0.5]) {
        assert!((r - e).abs() < 1e-7, "{:?}", ours.residual);
    }
    assert!(ours.residual[1].abs() <= ours.residual_tolerance);
}

#[test]
fn barely_feasible_problems_are_solved_like_clarabel() {
    let mut rng = Rng(4);
    let settings = QpSettings::default();
    for (n, m, reserves, count) in SIZES {
        for k in 0..count.div_ceil(2) {
            let mut case = random_case(&mut rng, n, m, reserves);
            let row = case.reserves + rng.below(n - reserves);
            let vertex = case.vertex_maximising_row(row);
            // on the boundary of A·box, then 1e-6 of the way inside
            let inside = if k % 2 == 0 { 0.0 } else { 1e-6 };
            let x: Vec<f64> = (vertex.iter().zip(&case.x_true))
                .map(|(v, t)| (1.0 - inside) * v + inside * t)
                .collect();
            case.set_b_from(&x);
            let what = format!("n = {n}, m = {m}, boundary case {k} ({inside} inside)");
            solved_like_clarabel(&case, &settings, &what);
        }
    }
}

/// The contact QP's shape: bounded columns that cannot balance b alone, and one slack per
/// row (unbounded, weight 1e4; the contact QP's 1e8 defeats Clarabel) that takes the rest.
/// The slacks span ℝⁿ, so μ stays below 10⁻¹² of their curvature; with μ_max the slack
/// directions (curvature 1/(2·1e4)) crept towards the optimum by a small fraction per proximal
/// step and the first case already ran into the iteration limit.
#[test]
fn heavily_weighted_slacks_converge_like_clarabel() {
    let mut rng = Rng(7);
    let settings = QpSettings::default();
    for (n, m, _, count) in SIZES {
        for k in 0..count.div_ceil(2) {
            let mut case = random_case(&mut rng, n, m, 0);
            // b well outside A·box: the slacks carry a part of every row
            let reach: Vec<f64> = (0..n)
                .map(|r| (0..m).map(|i| case.a[(r, i)].abs()).sum::<f64>())
                .collect();
            let b: Vec<f64> = reach.iter().map(|v| 1.5 * v + 10.0).collect();
            let mut a = DMatrix::zeros(n, m + n);
            a.columns_mut(0, m).copy_from(&case.a);
            for r in 0..n {
                a[(r, m + r)] = 1.0;
                case.weights.push(1e4);
                case.lower.push(f64::NEG_INFINITY);
                case.upper.push(f64::INFINITY);
                case.x_true.push(0.0);
            }
            case.a = a;
            case.b = b;
            let what = format!("n = {n}, m = {m} + {n} slacks, case {k}");
            let ours = solved_like_clarabel(&case, &settings, &what);
            assert!(
                ours.iterations <= 40,
                "{what}: {} iterations",
                ours.iterations
            );
        }
    }
}

/// Stationarity with multipliers recomputed here: ∂f/∂xᵢ − aᵢᵀλ is 0 inside the box, ≥ 0 at
/// the lower bound and ≤ 0 at the upper bound; A x = b within the reported tolerance.
fn assert_kkt(case: &Case, ours: &Outcome, p: f64, what: &str) {
    let lambda = nalgebra::DVector::from_column_slice(&ours.multipliers);
    let s = case.a.transpose() * &lambda;
    for i in 0..case.m() {
        let (x, l, u, w) = (ours.x[i], case.lower[i], case.upper[i], case.weights[i]);
        assert!(l <= x && x <= u, "{what}: x[{i}] = {x} outside [{l}, {u}]");
        let grad = p * w * x.abs().powf(p - 1.0) * x.signum();
        let reduced = grad - s[i];
        let tol = 1e-9 * (grad.abs() + s[i].abs() + 1e-9);
        if x > l && x < u {
            assert!(
                reduced.abs() <= tol,
                "{what}: x[{i}] free, ∂f − aᵀλ = {reduced}"
            );
        } else if x == l && l < u {
            assert!(
                reduced >= -tol,
                "{what}: x[{i}] at lower bound, ∂f − aᵀλ = {reduced}"
            );
        } else if x == u && l < u {
            assert!(
                reduced <= tol,
                "{what}: x[{i}] at upper bound, ∂f − aᵀλ = {reduced}"
            );
        }
    }
    let ax = &case.a * nalgebra::DVector::from_column_slice(&ours.x);
    for k in 0..case.n() {
        let r = ax[k] - case.b[k];
        assert!(
            (r - ours.residual[k]).abs()
                <= 1e-12 * (1.0 + case.b[k].abs()) + 1e-9 * ours.residual_tolerance.max(1e-300)
        );
        assert!(
            r.abs() <= 1.01 * ours.residual_tolerance,
            "{what}: row {k} residual {r}"
        );
    }
}

#[test]
fn kkt_conditions_hold_at_returned_solution() {
    let mut rng = Rng(5);
    for p in [2.0, 1.5, 3.0] {
        for (n, m, reserves, _) in SIZES {
            let case = random_case(&mut rng, n, m, reserves);
            let ours = cold(&case, &with_exponent(p));
            let what = format!("p = {p}, n = {n}, m = {m}");
            assert_eq!(ours.status, QpStatus::Solved, "{what}");
            assert_kkt(&case, &ours, p, &what);
        }
    }
}

/// Frames of a slowly varying problem: A and b drift as moment arms and joint moments do
/// between 100 Hz samples.
fn trajectory(rng: &mut Rng, n: usize, m: usize, reserves: usize, frames: usize) -> Vec<Case> {
    let base = random_case(rng, n, m, reserves);
    let drift_a = DMatrix::from_fn(n, m, |k, i| {
        if base.a[(k, i)] != 0.0 && i >= reserves {
            rng.range(-0.05, 0.05)
        } else {
            0.0
        }
    });
    let phase: Vec<f64> = (0..m)
        .map(|_| rng.range(0.0, std::f64::consts::TAU))
        .collect();
    (0..frames)
        .map(|f| {
            let t = f as f64 * 0.01;
            let mut case = base.clone();
            let wave = (2.0 * std::f64::consts::PI * t).sin();
            case.a += &drift_a
                .map(|v| v * wave)
                .component_mul(&base.a.map(f64::abs));
            let x: Vec<f64> = (0..m)
                .map(|i| {
                    let v =
                        base.x_true[i] + 0.05 * (2.0 * std::f64::consts::PI * t + phase[i]).sin();
                    v.clamp(case.lower[i], case.upper[i])
                })
                .collect();
            case.set_b_from(&x);
            case
        })
        .collect()
}

#[test]
fn warm_start_takes_fewer_iterations_than_cold_start() {
    let mut rng = Rng(6);
    for p in [2.0, 3.0] {
        for (n, m, reserves) in [(23, 92, 6), (29, 324, 6)] {
            let frames = trajectory(&mut rng, n, m, reserves, 50);
            let settings = with_exponent(p);
            let mut warm = QpWorkspace::new(n, m);
            let (mut cold_iterations, mut warm_iterations) = (0, 0);
            for case in &frames {
                let c = cold(case, &settings);
                let w = run(&mut warm, case, &settings);
                assert_eq!(c.status, QpStatus::Solved);
                assert_eq!(w.status, QpStatus::Solved);
                for i in 0..m {
                    assert!((c.x[i] - w.x[i]).abs() <= 1e-7 * case.box_size(i, c.x[i]));
                }
                cold_iterations += c.iterations;
                warm_iterations += w.iterations;
            }
            assert!(
                (warm_iterations as f64) < 0.8 * cold_iterations as f64,
                "p = {p}, m = {m}: warm {warm_iterations} vs cold {cold_iterations} iterations"
            );
        }
    }
}

#[test]
fn an_infeasible_frame_does_not_spoil_the_next_warm_start() {
    let mut rng = Rng(7);
    let frames = trajectory(&mut rng, 23, 92, 6, 5);
    let mut bad = frames[2].clone();
    make_infeasible(&mut bad, &mut rng, 2.0, 0.0).expect("a row with positive capacity");
    let mut ws = QpWorkspace::new(23, 92);
    let settings = QpSettings::default();
    assert_eq!(run(&mut ws, &frames[1], &settings).status, QpStatus::Solved);
    assert_eq!(run(&mut ws, &bad, &settings).status, QpStatus::Infeasible);
    let after = run(&mut ws, &frames[3], &settings);
    let fresh = cold(&frames[3], &settings);
    assert_eq!(after.status, QpStatus::Solved);
    assert_eq!(
        after.iterations, fresh.iterations,
        "the next frame starts cold"
    );
}

/// The problem the bad-input tests spoil one entry of (4 equations, 8 unknowns), and a
/// workspace for it.
fn bad_input_case() -> (Case, QpWorkspace) {
    let mut rng = Rng(8);
    (random_case(&mut rng, 4, 8, 1), QpWorkspace::new(4, 8))
}

/// The error of solving `c`, if any.
fn solve_error(ws: &mut QpWorkspace, c: &Case, s: &QpSettings) -> Option<QpError> {
    ws.solve(&c.problem(), s).err()
}

#[test]
fn non_finite_entries_of_a_and_b_are_named() {
    let (case, mut ws) = bad_input_case();
    let settings = QpSettings::default();
    let mut c = case.clone();
    c.a[(2, 5)] = f64::NAN;
    assert!(matches!(
        solve_error(&mut ws, &c, &settings),
        Some(QpError::NonFiniteMatrix {
            row: 2,
            column: 5,
            ..
        })
    ));
    c = case.clone();
    c.a[(0, 3)] = f64::INFINITY;
    assert!(matches!(
        solve_error(&mut ws, &c, &settings),
        Some(QpError::NonFiniteMatrix {
            row: 0,
            column: 3,
            ..
        })
    ));
    c = case.clone();
    c.b[1] = f64::NEG_INFINITY;
    assert!(matches!(
        solve_error(&mut ws, &c, &settings),
        Some(QpError::NonFinite {
            argument: "b",
            index: 1,
            ..
        })
    ));
}

#[test]
fn invalid_weights_and_bounds_are_named_by_index() {
    let (case, mut ws) = bad_input_case();
    let settings = QpSettings::default();
    for w in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let mut c = case.clone();
        c.weights[4] = w;
        assert!(matches!(
            solve_error(&mut ws, &c, &settings),
            Some(QpError::InvalidWeight { index: 4, .. })
        ));
    }
    for (l, u) in [
        (1.0, 0.0),
        (f64::NAN, 1.0),
        (0.0, f64::NAN),
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    ] {
        let mut c = case.clone();
        (c.lower[6], c.upper[6]) = (l, u);
        assert!(
            matches!(
                solve_error(&mut ws, &c, &settings),
                Some(QpError::InvalidBounds { index: 6, .. })
            ),
            "[{l}, {u}]"
        );
    }
    // The messages name the argument.
    let message = QpError::InvalidWeight {
        index: 4,
        value: 0.0,
    }
    .to_string();
    assert!(message.contains("weights[4]"), "{message}");
}

#[test]
fn wrong_sizes_are_named_by_argument() {
    let (case, mut ws) = bad_input_case();
    let settings = QpSettings::default();
    let mut c = case.clone();
    c.b.push(0.0);
    assert!(matches!(
        solve_error(&mut ws, &c, &settings),
        Some(QpError::WrongSize {
            argument: "b",
            expected: 4,
            actual: 5
        })
    ));
    c = case.clone();
    c.upper.pop();
    assert!(matches!(
        solve_error(&mut ws, &c, &settings),
        Some(QpError::WrongSize {
            argument: "upper",
            ..
        })
    ));
    assert!(matches!(
        solve_error(&mut QpWorkspace::new(5, 8), &case, &settings),
        Some(QpError::WrongSize {
            argument: "a (rows)",
            ..
        })
    ));
    assert!(matches!(
        solve_error(&mut QpWorkspace::new(4, 9), &case, &settings),
        Some(QpError::WrongSize {
            argument: "a (columns)",
            ..
        })
    ));
}

#[test]
fn invalid_settings_are_named_by_field() {
    let (case, mut ws) = bad_input_case();
    let settings = QpSettings::default();
    let bad_settings = [
        (
            "exponent",
            QpSettings {
                exponent: 1.0,
                ..settings.clone()
            },
        ),
        (
            "exponent",
            QpSettings {
                exponent: 0.5,
                ..settings.clone()
            },
        ),
        (
            "exponent",
            QpSettings {
                exponent: f64::NAN,
                ..settings.clone()
            },
        ),
        (
            "tolerance",
            QpSettings {
                tolerance: 0.0,
                ..settings.clone()
            },
        ),
        (
            "infeasibility_tolerance",
            QpSettings {
                infeasibility_tolerance: 1.0,
                ..settings.clone()
            },
        ),
        (
            "regularization_max",
            QpSettings {
                regularization_max: 0.0,
                ..settings.clone()
            },
        ),
        (
            "regularization_min",
            QpSettings {
                regularization_min: 1e-3,
                ..settings.clone()
            },
        ),
    ];
    for (name, s) in bad_settings {
        assert!(
            matches!(s.validate(), Err(QpError::InvalidSetting { field, .. }) if field == name),
            "{name}"
        );
        assert!(
            matches!(solve_error(&mut ws, &case, &s), Some(QpError::InvalidSetting { field, .. }) if field == name)
        );
    }
    assert!(QpSettings::default().validate().is_ok());
}

#[test]
fn degenerate_problems_do_not_panic() {
    let settings = QpSettings::default();
    let solve = |case: &Case| cold(case, &settings);
    let empty = |n: usize, m: usize, b: Vec<f64>| Case {
        a: DMatrix::zeros(n, m),
        b,
        weights: vec![1.0; m],
        lower: vec![-1.0; m],
        upper: vec![2.0; m],
        reserves: 0,
        x_true: vec![0.0; m],
    };
    // No equations: x minimises f over the box alone.
    let c = Case {
        lower: vec![0.5, -1.0, -3.0],
        upper: vec![1.0, 1.0, -2.0],
        ..empty(0, 3, vec![])
    };
    let o = solve(&c);
    assert_eq!(o.status, QpStatus::Solved);
    assert_eq!(o.x, vec![0.5, 0.0, -2.0]);
    // No unknowns: solved only if b = 0.
    assert_eq!(solve(&empty(2, 0, vec![0.0, 0.0])).status, QpStatus::Solved);
    let o = solve(&empty(2, 0, vec![1.0, 0.0]));
    assert_eq!(o.status, QpStatus::Infeasible);
    assert_eq!(o.residual, vec![-1.0, 0.0]);
    // A = 0 with b ≠ 0, and fixed coordinates.
    assert_eq!(
        solve(&empty(2, 3, vec![0.0, 3.0])).status,
        QpStatus::Infeasible
    );
    let mut c = empty(1, 2, vec![2.0]);
    c.a[(0, 0)] = 1.0;
    c.a[(0, 1)] = 1.0;
    (c.lower[0], c.upper[0]) = (0.5, 0.5);
    let o = solve(&c);
    assert_eq!(o.status, QpStatus::Solved);
    assert!(
        (o.x[0] - 0.5).abs() < 1e-15 && (o.x[1] - 1.5).abs() < 1e-9,
        "{:?}",
        o.x
    );
    // Huge but finite entries: a status, not a panic.
    let mut c = empty(2, 2, vec![1e300, 0.0]);
    c.a[(0, 0)] = 1e300;
    c.a[(1, 1)] = 1e-300;
    let _ = solve(&c);
}
