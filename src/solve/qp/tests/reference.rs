//! Test problems with the structure of static optimization, and the independent reference:
//! the same problems posed to Clarabel (an interior-point conic solver) as a QP (p = 2), a
//! power-cone program (p ≠ 2), or a least-squares QP (the least residual of an infeasible
//! problem).

use super::super::{QpMatrix, QpProblem};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, PowerConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};
use nalgebra::DMatrix;

/// SplitMix64: a small deterministic generator, so every run sees the same problems.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn chance(&mut self, p: f64) -> bool {
        self.range(0.0, 1.0) < p
    }
}

/// An owned problem: `reserves` unbounded coordinate actuators on the first coordinates
/// (columns 0..reserves), then muscles: each spans 1–4 consecutive coordinates with moment
/// arm × maximum force of either sign, activation in [0, 1] (some [0.02, 1]).
#[derive(Clone, Debug)]
pub struct Case {
    pub a: DMatrix<f64>,
    pub b: Vec<f64>,
    pub weights: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub reserves: usize,
    /// The x that generated b (in the box).
    pub x_true: Vec<f64>,
}

impl Case {
    pub fn problem(&self) -> QpProblem<'_> {
        QpProblem {
            a: QpMatrix::Dense(self.a.as_view()),
            b: &self.b,
            weights: &self.weights,
            lower: &self.lower,
            upper: &self.upper,
        }
    }

    pub fn n(&self) -> usize {
        self.a.nrows()
    }

    pub fn m(&self) -> usize {
        self.a.ncols()
    }

    /// Size of coordinate i's box (for comparing x): u − l, or 1 + |x| when unbounded.
    pub fn box_size(&self, i: usize, x: f64) -> f64 {
        let size = self.upper[i] - self.lower[i];
        if size.is_finite() {
            size.max(1e-12)
        } else {
            1.0 + x.abs()
        }
    }

    /// The largest value of row k of A x over the box, or None when an unbounded column
    /// enters row k.
    pub fn row_capacity(&self, k: usize) -> Option<f64> {
        let mut cap = 0.0;
        for i in 0..self.m() {
            let v = self.a[(k, i)];
            if v == 0.0 {
                continue;
            }
            let bound = if v > 0.0 {
                self.upper[i]
            } else {
                self.lower[i]
            };
            if !bound.is_finite() {
                return None;
            }
            cap += v * bound;
        }
        Some(cap)
    }

    /// The vertex of the box that maximises row k of A x (other coordinates keep x_true).
    pub fn vertex_maximising_row(&self, k: usize) -> Vec<f64> {
        (0..self.m())
            .map(|i| {
                let v = self.a[(k, i)];
                if v > 0.0 {
                    self.upper[i]
                } else if v < 0.0 {
                    self.lower[i]
                } else {
                    self.x_true[i]
                }
            })
            .collect()
    }

    pub fn set_b_from(&mut self, x: &[f64]) {
        let x = nalgebra::DVector::from_column_slice(x);
        self.b = (&self.a * x).as_slice().to_vec();
    }
}

/// A random feasible case with b = A x_true for x_true inside the box.
pub fn random_case(rng: &mut Rng, n: usize, m: usize, reserves: usize) -> Case {
    assert!(reserves <= n && reserves <= m);
    let mut a = DMatrix::zeros(n, m);
    let (mut weights, mut lower, mut upper, mut x_true) = (vec![], vec![], vec![], vec![]);
    for j in 0..reserves {
        a[(j, j)] = rng.range(5.0, 50.0);
        weights.push(1.0);
        lower.push(f64::NEG_INFINITY);
        upper.push(f64::INFINITY);
        x_true.push(rng.range(-2.0, 2.0));
    }
    for i in reserves..m {
        let span = (1 + rng.below(4)).min(n);
        let start = rng.below(n - span + 1);
        for k in start..start + span {
            let sign = if rng.chance(0.5) { 1.0 } else { -1.0 };
            a[(k, i)] = sign * rng.range(0.005, 0.06) * rng.range(300.0, 3000.0);
        }
        weights.push(if rng.chance(0.7) {
            1.0
        } else {
            rng.range(0.5, 2.0)
        });
        let l = if rng.chance(0.2) { 0.02 } else { 0.0 };
        lower.push(l);
        upper.push(1.0);
        x_true.push(if rng.chance(0.3) {
            l
        } else {
            rng.range(l, 0.5)
        });
    }
    let mut case = Case {
        a,
        b: vec![],
        weights,
        lower,
        upper,
        reserves,
        x_true: x_true.clone(),
    };
    case.set_b_from(&x_true);
    case
}

/// What Clarabel returned: its verdict and, when solved, x and the objective.
#[derive(Clone, Debug)]
pub struct Reference {
    pub status: SolverStatus,
    pub x: Vec<f64>,
    pub objective: f64,
}

impl Reference {
    pub fn solved(&self) -> bool {
        matches!(
            self.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        )
    }
    pub fn infeasible(&self) -> bool {
        matches!(
            self.status,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible
        )
    }
}

fn settings() -> DefaultSettings<f64> {
    DefaultSettings {
        verbose: false,
        max_iter: 200,
        tol_gap_abs: 1e-11,
        tol_gap_rel: 1e-11,
        tol_feas: 1e-11,
        tol_ktratio: 1e-9,
        ..DefaultSettings::default()
    }
}

/// Rows A x (+ extra columns) = b, then the finite bounds of the first m variables as
/// x ≤ u and −x ≤ −l, in Clarabel's form A x + s = b with s in the cones.
struct Constraints {
    rows: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    rhs: Vec<f64>,
    cones: Vec<SupportedConeT<f64>>,
}

impl Constraints {
    fn new(case: &Case, b: &[f64], residual_columns_from: Option<usize>) -> Self {
        let (n, m) = (case.n(), case.m());
        let mut c = Constraints {
            rows: vec![],
            cols: vec![],
            vals: vec![],
            rhs: b.to_vec(),
            cones: vec![ZeroConeT(n)],
        };
        for i in 0..m {
            for k in 0..n {
                let v = case.a[(k, i)];
                if v != 0.0 {
                    c.push(k, i, v);
                }
            }
        }
        if let Some(first) = residual_columns_from {
            // A x − r = b
            for k in 0..n {
                c.push(k, first + k, -1.0);
            }
        }
        let mut count = 0;
        for i in 0..m {
            if case.upper[i].is_finite() {
                let row = c.rhs.len();
                c.push(row, i, 1.0);
                c.rhs.push(case.upper[i]);
                count += 1;
            }
            if case.lower[i].is_finite() {
                let row = c.rhs.len();
                c.push(row, i, -1.0);
                c.rhs.push(-case.lower[i]);
                count += 1;
            }
        }
        c.cones.push(NonnegativeConeT(count));
        c
    }

    fn push(&mut self, row: usize, col: usize, val: f64) {
        self.rows.push(row);
        self.cols.push(col);
        self.vals.push(val);
    }

    fn solve(self, p: CscMatrix<f64>, q: Vec<f64>, nvars: usize) -> DefaultSolver<f64> {
        let a =
            CscMatrix::new_from_triplets(self.rhs.len(), nvars, self.rows, self.cols, self.vals);
        let mut solver = DefaultSolver::new(&p, &q, &a, &self.rhs, &self.cones, settings())
            .expect("valid Clarabel problem");
        solver.solve();
        solver
    }
}

fn diagonal(values: &[f64]) -> CscMatrix<f64> {
    let idx: Vec<usize> = (0..values.len()).collect();
    CscMatrix::new_from_triplets(
        values.len(),
        values.len(),
        idx.clone(),
        idx,
        values.to_vec(),
    )
}

/// min Σ wᵢxᵢ² s.t. A x = b, l ≤ x ≤ u, as the QP ½xᵀ(2W)x.
pub fn clarabel_quadratic(case: &Case, b: &[f64]) -> Reference {
    let m = case.m();
    let p = diagonal(&case.weights.iter().map(|w| 2.0 * w).collect::<Vec<_>>());
    let solver = Constraints::new(case, b, None).solve(p, vec![0.0; m], m);
    Reference {
        status: solver.solution.status,
        x: solver.solution.x.clone(),
        objective: solver.solution.obj_val,
    }
}

/// min Σ wᵢtᵢ s.t. (tᵢ, 1, xᵢ) in the power cone K(1/p) (tᵢ^{1/p} ≥ |xᵢ|), A x = b,
/// l ≤ x ≤ u; variables (x, t).
pub fn clarabel_power(case: &Case, b: &[f64], exponent: f64) -> Reference {
    let m = case.m();
    let mut c = Constraints::new(case, b, None);
    for i in 0..m {
        let row = c.rhs.len();
        c.push(row, m + i, -1.0); // s₁ = tᵢ
        c.push(row + 2, i, -1.0); // s₃ = xᵢ
        c.rhs.extend([0.0, 1.0, 0.0]); // s₂ = 1
        c.cones.push(PowerConeT(1.0 / exponent));
    }
    let mut q = vec![0.0; m];
    q.extend(&case.weights);
    let solver = c.solve(CscMatrix::zeros((2 * m, 2 * m)), q, 2 * m);
    Reference {
        status: solver.solution.status,
        x: solver.solution.x[..m].to_vec(),
        objective: solver.solution.obj_val,
    }
}

/// The least residual over the box: min ½‖r‖² s.t. A x − r = b, l ≤ x ≤ u; returns r
/// (unique, unlike x).
pub fn clarabel_least_residual(case: &Case) -> (SolverStatus, Vec<f64>) {
    let (n, m) = (case.n(), case.m());
    let p = {
        let idx: Vec<usize> = (m..m + n).collect();
        CscMatrix::new_from_triplets(m + n, m + n, idx.clone(), idx, vec![1.0; n])
    };
    let solver = Constraints::new(case, &case.b, Some(m)).solve(p, vec![0.0; m + n], m + n);
    (solver.solution.status, solver.solution.x[m..].to_vec())
}
