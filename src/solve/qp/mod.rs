//! Static optimization's per-frame problem (OpenSim's `StaticOptimization` analysis), solved
//! by a semismooth Newton method on its dual:
//!
//!   minimise  f(x) = Σᵢ wᵢ |xᵢ|ᵖ   subject to   A x = b,   l ≤ x ≤ u,
//!
//! with A n × m (column i: the generalized forces per unit xᵢ), weights wᵢ > 0, an exponent
//! p > 1 (OpenSim's `activation_exponent`, 2 by default) and bounds that may be infinite.
//!
//! # The dual
//! The objective is separable and strictly convex, so for multipliers λ ∈ ℝⁿ the Lagrangian
//! L(x, λ) = f(x) − λᵀ(A x − b) has, coordinate by coordinate, the box minimiser
//!
//!   xᵢ(λ) = clamp(ξᵢ(sᵢ), lᵢ, uᵢ),   s = Aᵀλ,   ξᵢ(s) = sgn(s) (|s| / (p wᵢ))^{1/(p−1)}
//!
//! (ξ solves p wᵢ |ξ|^{p−1} sgn ξ = s). The dual function g(λ) = min_{l≤x≤u} L(x, λ) is
//! concave and piecewise smooth, with ∇g = b − A x(λ) and generalized Hessian −A D Aᵀ,
//! Dᵢ = dxᵢ/dsᵢ = ξᵢ / ((p − 1) sᵢ) on free coordinates (1/(2wᵢ) for p = 2) and 0 on clamped
//! ones. Every x(λ) lies in the box and satisfies stationarity and complementarity exactly, so
//! the only KKT condition left is the primal residual r = A x(λ) − b: the iteration stops when
//! ‖r‖∞ ≤ ε · max(‖b‖∞, maxᵣ Σᵢ |A_ri xᵢ|).
//!
//! # The iteration (an inexact proximal point method with semismooth Newton inner steps)
//!   (A D Aᵀ + μ I) Δ = ∇ψ = −r − μ(λ − c),   λ ← λ + t Δ,
//! on ψ(λ) = g(λ) − (μ/2)‖λ − c‖², the dual regularised by a proximal term centred at c. ψ is
//! strongly concave, so its Newton steps are well defined even when the free columns do not
//! span ℝⁿ. Once ψ is maximised well enough (‖∇ψ‖ ≤ 0.1‖r‖, or at once when no step is found)
//! the centre moves to λ: one step of the proximal point method on the dual, i.e. of the method
//! of multipliers (augmented Lagrangian) on the primal with penalty 1/μ (Rockafellar 1976).
//! μ = h · clamp(θ‖r‖∞/scale, μ_min, μ_max), h the largest diagonal entry of A D_ref Aᵀ, so μ
//! vanishes as the residual does and the local convergence is that of Newton's method (finite
//! for p = 2 once the active set is found). For p = 2, when the columns with both bounds
//! infinite (reserves, residual slacks) span ℝⁿ on their own, A D Aᵀ ⪰ U = Σ_unbounded Dᵢaᵢaᵢᵀ
//! is positive definite for every λ and the problem feasible for every b: μ is then kept
//! below 10⁻¹² of U's smallest Cholesky pivot (and μ_min, μ_max lowered to it where they are
//! above), since a larger μ only slows the directions whose curvature is a heavily weighted
//! slack.
//!
//! The step length t comes from a line search on φ(t) = ψ(λ + tΔ), whose derivative
//! φ′(t) = ∇ψ(λ + tΔ)ᵀΔ is non-increasing (ψ is concave) and, for p = 2, piecewise linear
//! with breakpoints where a coordinate reaches a bound: t = 1 when φ′(1) ≥ −η φ′(0), otherwise
//! the root of φ′, found by one sweep over the sorted breakpoints (for p ≠ 2, a binary search
//! over them and regula falsi on the last smooth piece find t with |φ′(t)| ≤ η φ′(0)),
//! η = 0.1. A backtracking (Armijo) search was tried first: on infeasible problems its steps
//! shrank to nothing as columns went in and out of the free set, while the near-exact search
//! keeps the steps the geometry allows.
//!
//! For p = 2, D is constant on free coordinates and A D Aᵀ is updated by rank-1 terms of the
//! columns that entered or left the free set. A is kept by its nonzero entries (a muscle's
//! column has a row for each coordinate it spans, ≈ 3 of 29 on the default model), so the
//! products Aᵀλ, AΔ, A x and the rank-1 terms cost nnz(A) (or Σ nnz(aᵢ)²) rather than n·m; the
//! rest of an iteration is an n × n Cholesky factorisation, the sort of the breakpoints and
//! O(m) work for the line search. λ is kept in the workspace and warm-starts the next solve after a `Solved` one.
//!
//! # Infeasibility
//! When no x in the box satisfies A x = b, the dual is unbounded and λ diverges, but the
//! method of multipliers still converges in x: to the least-constraint-violation solution — the
//! x of least f among the minimisers of ‖A x − b‖₂ over the box (Dai & Zhang 2023). The residual
//! then stalls at r* ≠ 0 while x becomes a stationary point of ½‖A x − b‖² over the box, which
//! is checked directly with the projected gradient gᵢ = aᵢᵀr (kept only where it points into
//! the box): the problem is declared `Infeasible` when the residual stalls (‖rₖ₊₁‖ > 0.9‖rₖ‖),
//! is above tolerance, and |gᵢ| ≤ ε_inf ‖aᵢ‖ ‖r‖ for every i. A stationary point of that convex
//! least-squares problem is a global minimiser, so the verdict rests on a certificate rather
//! than on an iteration count; the returned x is in the box, its residual is the least
//! achievable (to ε_inf) and `residual` tells per equation what could not be balanced.
//!
//! References: R. T. Rockafellar, "Augmented Lagrangians and applications of the proximal point
//! algorithm in convex programming", Math. Oper. Res. 1 (1976); L. Qi & J. Sun, "A nonsmooth
//! version of Newton's method", Math. Program. 58 (1993); Y.-H. Dai & L. Zhang, "The augmented
//! Lagrangian method can approximately solve convex optimization with least constraint
//! violation", Math. Program. 200 (2023); F. C. Anderson & M. G. Pandy, "Static and dynamic
//! optimization solutions for gait are practically equivalent", J. Biomech. 34 (2001).

pub(crate) mod linalg;
#[cfg(test)]
mod tests;

use crate::linalg::{cholesky_in_place, cholesky_solve_in_place, dot};
pub use linalg::SparseColumns;
use nalgebra::DMatrixView;

/// The line search accepts t when |φ′(t)| ≤ η φ′(0) (or t = 1 when φ′(1) ≥ −η φ′(0)).
const LINE_SEARCH_ETA: f64 = 0.1;
/// Regula falsi steps of one line search, after the binary search over breakpoints.
const LINE_SEARCH_TRIALS: usize = 40;
/// ψ counts as maximised (and the proximal centre moves to λ) when ‖∇ψ‖₂ ≤ this × ‖r‖₂.
const INNER_TOLERANCE: f64 = 0.1;
/// The residual has stalled when ‖rₖ₊₁‖₂ exceeds this fraction of ‖rₖ‖₂.
const STALL_RATIO: f64 = 0.9;
/// μ/h = θ ‖r‖∞ / scale before clamping to [μ_min, μ_max] (see [`QpSettings`]).
const REGULARIZATION_GAIN: f64 = 1e-2;
/// Where the unbounded columns span ℝⁿ with curvature κ (see
/// [`QpWorkspace::unbounded_curvature`]), μ ≤ this × κ: each proximal step then shrinks the
/// slowest direction's distance to the optimum by this factor at least. 10⁻¹², below the
/// default tolerance, so that the Newton step that finds the active set already meets it: at
/// 10⁻⁶ that step left μ(λ − c) ≈ 10⁻⁶ of the residual it removed, and another step followed
/// (static optimization on the HumanML3D sample: 1,514 → 1,346 iterations over 170 frames,
/// 10⁻¹⁴ no fewer). U's pivots bound A D Aᵀ + μI's away from zero whatever μ is.
const UNBOUNDED_CONTRACTION: f64 = 1e-12;
/// For p ≠ 2 the slope dx/ds of a free coordinate is kept within these multiples of its
/// reference slope: it is 0 (p < 2) or ∞ (p > 2) at s = 0.
const SLOPE_FLOOR: f64 = 1e-6;
const SLOPE_CAP: f64 = 1e6;

/// Settings of [`QpWorkspace::solve`]; the defaults are those of [`QpSettings::default`].
#[derive(Clone, Debug, PartialEq)]
pub struct QpSettings {
    /// Exponent p > 1 of the objective Σᵢ wᵢ|xᵢ|ᵖ (OpenSim's `activation_exponent`).
    /// Default 2.
    pub exponent: f64,
    /// Converged when ‖A x − b‖∞ ≤ tolerance · max(‖b‖∞, maxᵣ Σᵢ |A_ri xᵢ|) (a residual
    /// relative to the size of the terms that balance). Default 1e-10.
    pub tolerance: f64,
    /// Infeasible when the residual has stalled above tolerance and the projected gradient
    /// of ½‖A x − b‖² satisfies |aᵢᵀr| ≤ infeasibility_tolerance · ‖aᵢ‖ ‖r‖ for every
    /// coordinate (the cosine between every feasible move and the residual). Default 1e-7.
    pub infeasibility_tolerance: f64,
    /// Newton iterations before giving up with [`QpStatus::MaxIterations`]. Default 100.
    pub max_iterations: usize,
    /// Start from the multipliers of the last `Solved` call of the workspace. Default true.
    pub warm_start: bool,
    /// Bounds of the proximal weight μ relative to the largest diagonal entry of A D Aᵀ
    /// (see the module documentation): μ_min keeps the Newton matrix numerically positive
    /// definite, μ_max sets the pace of the method of multipliers on infeasible problems
    /// (for p = 2 both are lowered, where needed, below 10⁻¹² of the curvature the unbounded
    /// columns give when they span ℝⁿ: such a problem is never infeasible). Defaults 1e-12
    /// and 1e-6.
    pub regularization_min: f64,
    pub regularization_max: f64,
}

impl Default for QpSettings {
    fn default() -> Self {
        QpSettings {
            exponent: 2.0,
            tolerance: 1e-10,
            infeasibility_tolerance: 1e-7,
            max_iterations: 100,
            warm_start: true,
            regularization_min: 1e-12,
            regularization_max: 1e-6,
        }
    }
}

impl QpSettings {
    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), QpError> {
        let bad = |field, value, requirement| {
            Err(QpError::InvalidSetting {
                field,
                value,
                requirement,
            })
        };
        if !(self.exponent > 1.0 && self.exponent.is_finite()) {
            return bad("exponent", self.exponent, "finite and greater than 1");
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad("tolerance", self.tolerance, "in (0, 1)");
        }
        if !(self.infeasibility_tolerance > 0.0 && self.infeasibility_tolerance < 1.0) {
            return bad(
                "infeasibility_tolerance",
                self.infeasibility_tolerance,
                "in (0, 1)",
            );
        }
        if !(self.regularization_max > 0.0 && self.regularization_max < 1.0) {
            return bad("regularization_max", self.regularization_max, "in (0, 1)");
        }
        if !(self.regularization_min > 0.0 && self.regularization_min <= self.regularization_max) {
            return bad(
                "regularization_min",
                self.regularization_min,
                "positive and at most regularization_max",
            );
        }
        Ok(())
    }
}

/// Bad input to the solver. Each variant names the argument or setting at fault.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QpError {
    /// An argument's size does not match the workspace (n equations, m unknowns).
    #[error("`{argument}` has size {actual}, expected {expected}")]
    WrongSize {
        argument: &'static str,
        expected: usize,
        actual: usize,
    },
    /// An entry of A is NaN or infinite.
    #[error("`a[({row}, {column})]` is {value}; every entry of A must be finite")]
    NonFiniteMatrix {
        row: usize,
        column: usize,
        value: f64,
    },
    /// An entry of a vector argument is NaN or infinite.
    #[error("`{argument}[{index}]` is {value}; it must be finite")]
    NonFinite {
        argument: &'static str,
        index: usize,
        value: f64,
    },
    /// A weight is not positive and finite.
    #[error("`weights[{index}]` is {value}; weights must be positive and finite")]
    InvalidWeight { index: usize, value: f64 },
    /// lower > upper, a NaN bound, or a bound infinite on the wrong side (lower = +∞ or
    /// upper = −∞).
    #[error(
        "bounds of x[{index}] are [{lower}, {upper}]; need lower ≤ upper, lower < +∞, upper > −∞"
    )]
    InvalidBounds {
        index: usize,
        lower: f64,
        upper: f64,
    },
    /// A field of [`QpSettings`] is out of range.
    #[error("setting `{field}` is {value}; it must be {requirement}")]
    InvalidSetting {
        field: &'static str,
        value: f64,
        requirement: &'static str,
    },
}

/// The constraint matrix A (n × m) of a [`QpProblem`]: dense, or by the nonzero entries of
/// its columns (the solver keeps A that way in any case, so a caller that knows its columns'
/// nonzeros spares it the scan of the dense matrix).
#[derive(Clone, Copy, Debug)]
pub enum QpMatrix<'a> {
    Dense(DMatrixView<'a, f64>),
    Sparse(&'a SparseColumns),
}

impl QpMatrix<'_> {
    /// Rows n.
    pub fn nrows(&self) -> usize {
        match self {
            QpMatrix::Dense(a) => a.nrows(),
            QpMatrix::Sparse(a) => a.nrows(),
        }
    }

    /// Columns m.
    pub fn ncols(&self) -> usize {
        match self {
            QpMatrix::Dense(a) => a.ncols(),
            QpMatrix::Sparse(a) => a.ncols(),
        }
    }
}

/// One frame's problem: minimise Σᵢ wᵢ|xᵢ|ᵖ subject to A x = b, lower ≤ x ≤ upper. Bounds may
/// be −∞ (lower) and +∞ (upper); lower = upper fixes a coordinate.
#[derive(Clone, Copy, Debug)]
pub struct QpProblem<'a> {
    /// n × m; column i holds the generalized forces per unit xᵢ
    /// (`QpMatrix::Dense(matrix.as_view())`).
    pub a: QpMatrix<'a>,
    /// n right-hand sides (e.g. inverse-dynamics generalized forces minus passive ones).
    pub b: &'a [f64],
    /// m positive weights wᵢ.
    pub weights: &'a [f64],
    /// m lower bounds lᵢ (may be −∞).
    pub lower: &'a [f64],
    /// m upper bounds uᵢ (may be +∞).
    pub upper: &'a [f64],
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpStatus {
    /// The residual is within tolerance: x is optimal.
    Solved,
    /// No x in the box satisfies A x = b. x minimises ‖A x − b‖₂ over the box (f breaks the
    /// tie), and `residual` is what could not be balanced.
    Infeasible,
    /// The iteration limit was reached first; x is the last iterate (in the box, optimal for
    /// its own right-hand side A x).
    MaxIterations,
    /// The Newton matrix could not be factored or no ascent step was found even with heavy
    /// regularisation (inputs of extreme magnitude); x is the last iterate.
    NumericalError,
}

/// The result of [`QpWorkspace::solve`], borrowing the workspace.
#[derive(Clone, Copy, Debug)]
pub struct QpSolution<'w> {
    pub status: QpStatus,
    /// The m unknowns, always within their bounds.
    pub x: &'w [f64],
    /// A x − b, per equation.
    pub residual: &'w [f64],
    /// The absolute residual tolerance of this solve, tolerance · max(‖b‖∞, maxᵣ Σᵢ|A_ri xᵢ|):
    /// equations with |residualᵣ| above it are the ones left unbalanced.
    pub residual_tolerance: f64,
    /// The multipliers λ of A x = b (∂f*/∂b). They diverge on infeasible problems.
    pub multipliers: &'w [f64],
    /// Σᵢ wᵢ|xᵢ|ᵖ.
    pub objective: f64,
    /// Newton iterations taken.
    pub iterations: usize,
}

/// The solver's memory for problems of n equations and m unknowns: every array the iteration
/// writes, allocated once, and the multipliers of the last solved problem for warm starts.
#[derive(Clone, Debug)]
pub struct QpWorkspace {
    n: usize,
    m: usize,
    /// λ (n) and whether it holds the solution of the last solve.
    multipliers: Vec<f64>,
    warm: bool,
    /// The current iterate per coordinate: s = Aᵀλ, x(s) and D = dx/ds (0 when clamped).
    s: Vec<f64>,
    x: Vec<f64>,
    slope: Vec<f64>,
    /// The same at a trial point of the line search (swapped in when it is accepted).
    s_trial: Vec<f64>,
    x_trial: Vec<f64>,
    slope_trial: Vec<f64>,
    /// The values of sᵢ at which ξᵢ(sᵢ) reaches lᵢ and uᵢ (±∞ for infinite bounds), and the
    /// step fractions in (0, 1) at which some coordinate changes state along Δ, each with the
    /// change it makes to the slope of φ′ (p = 2).
    s_at_lower: Vec<f64>,
    s_at_upper: Vec<f64>,
    breakpoints: Vec<(f64, f64)>,
    /// The coefficient each column currently has in `hessian`, and the slope used at a cold
    /// start (the secant from 0 to the box's size; 1/(2wᵢ) for p = 2).
    slope_in_hessian: Vec<f64>,
    slope_reference: Vec<f64>,
    /// ‖aᵢ‖₂ and AᵀΔ (m).
    column_norm: Vec<f64>,
    a_step: Vec<f64>,
    /// A D Aᵀ and its regularised Cholesky factor, n × n column-major (lower triangles).
    hessian: Vec<f64>,
    factor: Vec<f64>,
    /// r = A x − b, Σᵢ |A_ri xᵢ|, the proximal centre c, ∇ψ and the Newton step Δ (n).
    residual: Vec<f64>,
    magnitude: Vec<f64>,
    center: Vec<f64>,
    gradient: Vec<f64>,
    step: Vec<f64>,
    /// A of the current problem by its nonzero entries.
    columns: SparseColumns,
    /// Rank-1 terms applied to `hessian` since it was last formed from scratch.
    updates_since_rebuild: usize,
}

/// The terms of the line search along Δ: φ′(0) = ∇ψᵀΔ, ‖Δ‖² and μ.
struct Slope {
    psi: f64,
    step_norm2: f64,
    mu: f64,
}

/// The per-coordinate power law w|x|ᵖ and its conjugate map s ↦ ξ(s).
#[derive(Clone, Copy, Debug)]
struct PowerLaw {
    p: f64,
    quadratic: bool,
    /// 1/(p − 1).
    inverse_p_minus_1: f64,
}

impl PowerLaw {
    fn new(p: f64) -> Self {
        PowerLaw {
            p,
            quadratic: p == 2.0,
            inverse_p_minus_1: 1.0 / (p - 1.0),
        }
    }

    /// |x|ᵖ.
    #[inline]
    fn power(&self, x: f64) -> f64 {
        if self.quadratic {
            x * x
        } else {
            x.abs().powf(self.p)
        }
    }

    /// The reference slope Dᵢ: the secant of ξ from 0 to |x| = `size`, size^{2−p}/(p w)
    /// (exactly dξ/ds = 1/(2w) for p = 2).
    fn reference_slope(&self, size: f64, w: f64) -> f64 {
        if self.quadratic {
            0.5 / w
        } else {
            size.powf(2.0 - self.p) / (self.p * w)
        }
    }

    /// The value of s at which ξ(s) = x: p w |x|^{p−1} sgn x.
    fn s_at(&self, x: f64, w: f64) -> f64 {
        if x.is_infinite() {
            x
        } else if self.quadratic {
            2.0 * w * x
        } else {
            self.p * w * x.abs().powf(self.p - 1.0).copysign(x)
        }
    }

    /// The box minimiser of w|x|ᵖ − s x and its slope dx/ds: (clamp(ξ(s), l, u), D).
    /// D is dξ/ds = ξ/((p − 1) s) when ξ is within the bounds (boundary included) and 0 when
    /// clamped; for p ≠ 2 it is kept within [SLOPE_FLOOR, SLOPE_CAP] × `slope_reference`.
    /// `slope_reference` is [`PowerLaw::reference_slope`] of w: 1/(2w) for p = 2, where it
    /// is also the slope.
    #[inline]
    fn minimiser(&self, s: f64, w: f64, l: f64, u: f64, slope_reference: f64) -> (f64, f64) {
        // ξ: p w |ξ|^{p−1} sgn ξ = s (for p = 2, ξ = s/(2w) with the reference slope
        // D_ref = 1/(2w) computed once per solve)
        let xi = if self.quadratic {
            s * slope_reference
        } else {
            (s.abs() / (self.p * w))
                .powf(self.inverse_p_minus_1)
                .copysign(s)
        };
        if xi < l {
            (l, 0.0)
        } else if xi > u {
            (u, 0.0)
        } else if self.quadratic {
            (xi, slope_reference)
        } else {
            let d = if s == 0.0 {
                if self.p < 2.0 { 0.0 } else { f64::INFINITY }
            } else {
                xi * self.inverse_p_minus_1 / s
            };
            let d = d.clamp(SLOPE_FLOOR * slope_reference, SLOPE_CAP * slope_reference);
            (xi, d)
        }
    }
}

impl QpWorkspace {
    /// A workspace for problems with `n` equations and `m` unknowns.
    pub fn new(n: usize, m: usize) -> Self {
        QpWorkspace {
            n,
            m,
            multipliers: vec![0.0; n],
            warm: false,
            s: vec![0.0; m],
            x: vec![0.0; m],
            slope: vec![0.0; m],
            s_trial: vec![0.0; m],
            x_trial: vec![0.0; m],
            slope_trial: vec![0.0; m],
            s_at_lower: vec![0.0; m],
            s_at_upper: vec![0.0; m],
            breakpoints: Vec::with_capacity(2 * m),
            slope_in_hessian: vec![0.0; m],
            slope_reference: vec![0.0; m],
            column_norm: vec![0.0; m],
            a_step: vec![0.0; m],
            hessian: vec![0.0; n * n],
            factor: vec![0.0; n * n],
            residual: vec![0.0; n],
            magnitude: vec![0.0; n],
            center: vec![0.0; n],
            gradient: vec![0.0; n],
            step: vec![0.0; n],
            columns: SparseColumns::with_capacity(n, m),
            updates_since_rebuild: 0,
        }
    }

    /// Number of equations n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of unknowns m.
    pub fn m(&self) -> usize {
        self.m
    }

    /// Forgets the multipliers kept for warm starts: the next solve starts cold.
    pub fn clear_warm_start(&mut self) {
        self.warm = false;
    }

    /// Solves `problem` (see the module documentation). Bad input is an `Err`; whether the
    /// problem was solved, infeasible or not finished is the solution's `status`. Allocates
    /// nothing.
    pub fn solve(
        &mut self,
        problem: &QpProblem<'_>,
        settings: &QpSettings,
    ) -> Result<QpSolution<'_>, QpError> {
        settings.validate()?;
        self.check_arguments(problem)?;
        let law = PowerLaw::new(settings.exponent);
        let h_reference = self.prepare_columns(problem, &law)?;
        let (mu_min, mu_max) = self.regularization_bounds(problem, settings, &law, h_reference);
        let n = self.n;
        let cold = self.start(problem, settings, &law);
        let b_max = problem.b.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
        let (mut r_max, mut scale, mut r_norm) = self.update_residual(problem.b, b_max);
        let mut r_norm_previous = f64::INFINITY;
        let mut boost = 1.0;
        let mut iterations = 0;
        // μ = h clamp(θ‖r‖∞/scale, μ_min, μ_max) (× `boost` after failed line searches)
        let proximal_weight = |r_max: f64, scale: f64, boost: f64| {
            let relative = REGULARIZATION_GAIN * r_max / scale;
            h_reference * relative.clamp(mu_min, mu_max) * boost
        };
        // ψ(λ) = g(λ) − (μ/2)‖λ − c‖²: μ and the centre c stay fixed while ψ is maximised
        let mut mu = proximal_weight(r_max, scale, boost);
        self.center.copy_from_slice(&self.multipliers);

        let status = loop {
            if r_max <= settings.tolerance * scale {
                break QpStatus::Solved;
            }
            if r_norm > STALL_RATIO * r_norm_previous
                && self.least_squares_stationary(problem, settings, r_norm)
            {
                break QpStatus::Infeasible;
            }
            if iterations >= settings.max_iterations {
                break QpStatus::MaxIterations;
            }

            let Some(slope) = self.newton_direction(iterations == 0, cold, &mut mu) else {
                break QpStatus::NumericalError;
            };
            let accepted = self.line_search(problem, &law, &slope);
            if let Some(t) = accepted {
                self.take_step(t);
            }
            iterations += 1;
            r_norm_previous = r_norm;
            (r_max, scale, r_norm) = self.update_residual(problem.b, b_max);

            if accepted.is_none() {
                boost *= 100.0;
                if boost > 1e12 {
                    break QpStatus::NumericalError;
                }
            }
            // Proximal (outer) step: once ψ is maximised well enough, or when no step was
            // found, re-centre ψ at λ and update μ.
            let inner_gradient2: f64 = (0..n)
                .map(|j| {
                    let gj = self.residual[j] + mu * (self.multipliers[j] - self.center[j]);
                    gj * gj
                })
                .sum();
            if accepted.is_none() || inner_gradient2 <= (INNER_TOLERANCE * r_norm).powi(2) {
                self.center.copy_from_slice(&self.multipliers);
                mu = proximal_weight(r_max, scale, boost);
            }
        };

        self.warm = status == QpStatus::Solved;
        Ok(QpSolution {
            status,
            x: &self.x,
            residual: &self.residual,
            residual_tolerance: settings.tolerance * scale,
            multipliers: &self.multipliers,
            objective: (self.x.iter().zip(problem.weights))
                .map(|(&x, &w)| w * law.power(x))
                .sum(),
            iterations,
        })
    }

    /// μ's bounds relative to h: (μ_min, μ_max) of the settings, or lower where the unbounded
    /// columns alone make the dual strongly concave (see [`Self::unbounded_curvature`]).
    fn regularization_bounds(
        &mut self,
        problem: &QpProblem<'_>,
        settings: &QpSettings,
        law: &PowerLaw,
        h_reference: f64,
    ) -> (f64, f64) {
        match law
            .quadratic
            .then(|| self.unbounded_curvature(problem, h_reference))
            .flatten()
        {
            Some(kappa) => {
                let high = settings
                    .regularization_max
                    .min(UNBOUNDED_CONTRACTION * kappa / h_reference);
                (settings.regularization_min.min(high), high)
            }
            None => (settings.regularization_min, settings.regularization_max),
        }
    }

    /// The starting iterate: λ kept from the last solve (a warm start) or 0, s = Aᵀλ and
    /// x = x(s). Returns whether the start is cold.
    fn start(&mut self, problem: &QpProblem<'_>, settings: &QpSettings, law: &PowerLaw) -> bool {
        let cold = !(settings.warm_start && self.warm);
        if cold {
            self.multipliers.fill(0.0);
        }
        self.warm = false;
        // s = Aᵀλ, x = x(s)
        for i in 0..self.m {
            self.s[i] = self.columns.dot(i, &self.multipliers);
            (self.x[i], self.slope[i]) = law.minimiser(
                self.s[i],
                problem.weights[i],
                problem.lower[i],
                problem.upper[i],
                self.slope_reference[i],
            );
        }
        cold
    }

    /// The Newton direction of ψ: Δ = (A D Aᵀ + μI)⁻¹ ∇ψ with ∇ψ = −r − μ(λ − c), and AᵀΔ.
    /// `first`: the first iteration of this solve (A D Aᵀ formed from scratch, from the
    /// reference slopes when `cold`). Should rounding make the matrix indefinite, μ is raised
    /// (a new ψ, centred at λ). None when no ascent direction could be formed.
    fn newton_direction(&mut self, first: bool, cold: bool, mu: &mut f64) -> Option<Slope> {
        let n = self.n;
        // Newton matrix A D Aᵀ: at a cold start the reference slopes of every column
        // (at λ = 0 the exact slope is 0 or ∞ for p ≠ 2, and muscles sit on a bound).
        let use_reference = cold && first;
        self.update_hessian(first, use_reference);
        // A D Aᵀ + μI = L Lᵀ; should rounding make it indefinite, μ is raised (a new ψ)
        let mut attempts = 0;
        while !self.factor_newton_matrix(*mu) {
            attempts += 1;
            if attempts == 8 {
                break;
            }
            *mu = (100.0 * *mu).max(f64::MIN_POSITIVE);
            self.center.copy_from_slice(&self.multipliers);
        }
        if attempts == 8 {
            return None;
        }
        let mu = *mu;
        // ∇ψ = −r − μ(λ − c),  Δ = (A D Aᵀ + μI)⁻¹ ∇ψ
        for j in 0..n {
            self.gradient[j] = -self.residual[j] - mu * (self.multipliers[j] - self.center[j]);
        }
        self.step.copy_from_slice(&self.gradient);
        cholesky_solve_in_place(&self.factor, n, &mut self.step);
        let slope = Slope {
            psi: dot(&self.gradient, &self.step),
            step_norm2: dot(&self.step, &self.step),
            mu,
        };
        if !(slope.psi > 0.0 && slope.psi.is_finite()) {
            return None;
        }
        for i in 0..self.m {
            self.a_step[i] = self.columns.dot(i, &self.step);
        }
        Some(slope)
    }

    /// λ ← λ + tΔ, with s, x and D of the line search's trial point swapped in.
    fn take_step(&mut self, t: f64) {
        for (l, d) in self.multipliers.iter_mut().zip(&self.step) {
            *l += t * d;
        }
        std::mem::swap(&mut self.s, &mut self.s_trial);
        std::mem::swap(&mut self.x, &mut self.x_trial);
        std::mem::swap(&mut self.slope, &mut self.slope_trial);
    }

    /// Sizes against the workspace, and every vector entry (A is checked in
    /// [`Self::prepare_columns`], on the pass it makes anyway).
    fn check_arguments(&self, problem: &QpProblem<'_>) -> Result<(), QpError> {
        let size = |argument, expected, actual| {
            if expected == actual {
                Ok(())
            } else {
                Err(QpError::WrongSize {
                    argument,
                    expected,
                    actual,
                })
            }
        };
        size("a (rows)", self.n, problem.a.nrows())?;
        size("a (columns)", self.m, problem.a.ncols())?;
        size("b", self.n, problem.b.len())?;
        size("weights", self.m, problem.weights.len())?;
        size("lower", self.m, problem.lower.len())?;
        size("upper", self.m, problem.upper.len())?;
        if let Some((index, &value)) = problem.b.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(QpError::NonFinite {
                argument: "b",
                index,
                value,
            });
        }
        if let Some((index, &value)) =
            (problem.weights.iter().enumerate()).find(|(_, w)| !(**w > 0.0 && w.is_finite()))
        {
            return Err(QpError::InvalidWeight { index, value });
        }
        for (index, (&lower, &upper)) in problem.lower.iter().zip(problem.upper).enumerate() {
            if !(lower <= upper && lower < f64::INFINITY && upper > f64::NEG_INFINITY) {
                return Err(QpError::InvalidBounds {
                    index,
                    lower,
                    upper,
                });
            }
        }
        Ok(())
    }

    /// One pass over A: the column norms ‖aᵢ‖, the reference slopes D_ref,i, and
    /// h = maxᵣ Σᵢ A_ri² D_ref,i, the largest diagonal entry of A D_ref Aᵀ (the scale of μ).
    /// A non-finite entry is an error naming it.
    fn prepare_columns(&mut self, problem: &QpProblem<'_>, law: &PowerLaw) -> Result<f64, QpError> {
        match problem.a {
            QpMatrix::Dense(a) => {
                self.columns.clear();
                for i in 0..self.m {
                    self.columns.push(a.column(i).data.into_slice())?;
                }
            }
            QpMatrix::Sparse(a) => self.columns.assign(a),
        }
        // Σᵢ A_ri² D_ref,i accumulates in `magnitude` (overwritten by the first residual).
        self.magnitude.fill(0.0);
        for i in 0..self.m {
            let (l, u) = (problem.lower[i], problem.upper[i]);
            let size = [l, u]
                .iter()
                .filter(|v| v.is_finite())
                .fold(0.0_f64, |acc, v| acc.max(v.abs()));
            let size = if size > 0.0 { size } else { 1.0 };
            let d_ref = law.reference_slope(size, problem.weights[i]);
            self.slope_reference[i] = d_ref;
            self.s_at_lower[i] = law.s_at(l, problem.weights[i]);
            self.s_at_upper[i] = law.s_at(u, problem.weights[i]);
            let (rows, values) = self.columns.column(i);
            let mut sum = 0.0;
            for (&row, &v) in rows.iter().zip(values) {
                let v2 = v * v;
                sum += v2;
                self.magnitude[row] += v2 * d_ref;
            }
            if !sum.is_finite() {
                if let Some((&row, &value)) = rows.iter().zip(values).find(|(_, v)| !v.is_finite())
                {
                    return Err(QpError::NonFiniteMatrix {
                        row,
                        column: i,
                        value,
                    });
                }
            }
            self.column_norm[i] = sum.sqrt();
        }
        let h = self.magnitude.iter().fold(0.0_f64, |acc, v| acc.max(*v));
        Ok(if h > 0.0 { h } else { 1.0 })
    }

    /// When the columns with both bounds infinite span ℝⁿ: the smallest pivot κ of the
    /// Cholesky factorisation of U = Σ_{unbounded i} D_ref,i aᵢaᵢᵀ (λ_min(U) ≤ κ), provided it
    /// stands well above the rounding of A D Aᵀ (κ ≥ 1e4 ε h); else None. Those columns are
    /// free for every λ, so A D Aᵀ ⪰ U: the dual is strongly concave, the problem feasible
    /// for every b, and the Newton matrix definite without the proximal term. μ is then kept
    /// below [`UNBOUNDED_CONTRACTION`] κ: a larger μ slows the directions whose curvature is
    /// a heavily weighted unbounded column (a residual slack of weight w, curvature 1/(2w))
    /// to the factor μ/(μ + 1/(2w)) per proximal step — with μ_max the contact QP's force
    /// slacks (w = 1e8) crept by ≈ 0.9995 per step and ran into the iteration limit, and
    /// static optimization with reserves kept the proximal displacement μ(λ − c) in its
    /// residual for 2–3 iterations after finding the active set. Uses `factor` as scratch
    /// (it is refactored before use).
    fn unbounded_curvature(&mut self, problem: &QpProblem<'_>, h: f64) -> Option<f64> {
        let n = self.n;
        let unbounded =
            |i: usize| problem.lower[i] == f64::NEG_INFINITY && problem.upper[i] == f64::INFINITY;
        if (0..self.m).filter(|&i| unbounded(i)).count() < n {
            return None;
        }
        self.factor.fill(0.0);
        for i in (0..self.m).filter(|&i| unbounded(i)) {
            self.columns
                .rank_update(&mut self.factor, n, i, self.slope_reference[i]);
        }
        if !cholesky_in_place(&mut self.factor, n) {
            return None;
        }
        let kappa = (0..n)
            .map(|j| self.factor[j * n + j].powi(2))
            .fold(f64::INFINITY, f64::min);
        (kappa >= 100.0 * f64::EPSILON * h).then_some(kappa)
    }

    /// r = A x − b and Σᵢ |A_ri xᵢ|; returns (‖r‖∞, max(‖b‖∞, maxᵣ Σᵢ|A_ri xᵢ|), ‖r‖₂).
    fn update_residual(&mut self, b: &[f64], b_max: f64) -> (f64, f64, f64) {
        for ((r, mag), &br) in self.residual.iter_mut().zip(&mut self.magnitude).zip(b) {
            *r = -br;
            *mag = 0.0;
        }
        for (i, &xi) in self.x.iter().enumerate() {
            if xi == 0.0 {
                continue;
            }
            let (rows, values) = self.columns.column(i);
            for (&row, &a) in rows.iter().zip(values) {
                let t = a * xi;
                self.residual[row] += t;
                self.magnitude[row] += t.abs();
            }
        }
        let r_max = self
            .residual
            .iter()
            .fold(0.0_f64, |acc, v| acc.max(v.abs()));
        let scale = self.magnitude.iter().fold(b_max, |acc, v| acc.max(*v));
        (r_max, scale, dot(&self.residual, &self.residual).sqrt())
    }

    /// `factor` ← L with L Lᵀ = A D Aᵀ + μI; false if it is not numerically positive definite.
    fn factor_newton_matrix(&mut self, mu: f64) -> bool {
        let n = self.n;
        self.factor.copy_from_slice(&self.hessian);
        for j in 0..n {
            self.factor[j * n + j] += mu;
        }
        cholesky_in_place(&mut self.factor, n)
    }

    /// Brings `hessian` to A D Aᵀ for the current slopes (or the reference slopes): from
    /// scratch when asked, when more columns changed than are free, or after many updates;
    /// otherwise by rank-1 terms (D_new − D_old) aᵢaᵢᵀ for the columns whose slope changed.
    fn update_hessian(&mut self, rebuild: bool, use_reference: bool) {
        let n = self.n;
        let target = if use_reference {
            &self.slope_reference
        } else {
            &self.slope
        };
        let (mut changed, mut free) = (0, 0);
        for (d, h) in target.iter().zip(&self.slope_in_hessian) {
            changed += usize::from(d != h);
            free += usize::from(*d != 0.0);
        }
        let rebuild =
            rebuild || changed > free || self.updates_since_rebuild + changed > 2 * self.m;
        if rebuild {
            self.hessian.fill(0.0);
            for (i, &d) in target.iter().enumerate() {
                if d != 0.0 {
                    self.columns.rank_update(&mut self.hessian, n, i, d);
                }
            }
            self.updates_since_rebuild = 0;
        } else if changed > 0 {
            for (i, (&d, &d_in)) in target.iter().zip(&self.slope_in_hessian).enumerate() {
                if d != d_in {
                    self.columns.rank_update(&mut self.hessian, n, i, d - d_in);
                }
            }
            self.updates_since_rebuild += changed;
        }
        self.slope_in_hessian.copy_from_slice(target);
    }

    /// Exact line search: the maximiser over t ∈ (0, 1] of the concave φ(t) = ψ(λ + tΔ),
    /// found on its derivative
    ///   φ′(t) = φ′(0) − Σᵢ δᵢ (xᵢ(sᵢ + tδᵢ) − xᵢ(sᵢ)) − μ t ‖Δ‖²,   δ = AᵀΔ,
    /// which is decreasing (each term of the sum is ≥ 0) and free of the large cancelling
    /// terms of φ itself. t = 1 when φ′(1) ≥ −η φ′(0) (one evaluation); otherwise the t where
    /// φ′ changes sign. For p = 2, φ′ is piecewise linear with slope −Σ_free δᵢ² Dᵢ − μ‖Δ‖²,
    /// changing by ∓δᵢ² Dᵢ at each breakpoint (the t at which a coordinate enters or leaves
    /// its box), so one sweep over the sorted breakpoints finds the root and a second
    /// evaluation confirms it. Otherwise (p ≠ 2, or rounding in the sweep) a binary search over the
    /// breakpoints finds the segment where φ′ changes sign, on which φ′ is smooth and regula
    /// falsi (Illinois) finds |φ′(t)| ≤ η φ′(0). A full step can overshoot by orders of
    /// magnitude where many coordinates are clamped (the Newton matrix is then only μ in
    /// some directions), which backtracking would take many steps to undo.
    /// Leaves x(λ + tΔ) in the `_trial` arrays; None if no ascent step exists numerically.
    fn line_search(
        &mut self,
        problem: &QpProblem<'_>,
        law: &PowerLaw,
        slope: &Slope,
    ) -> Option<f64> {
        let d0 = slope.psi;
        let accept = LINE_SEARCH_ETA * d0;
        let (d1, rate) = self.full_step_and_breakpoints(problem, law, slope);
        if d1 >= -accept {
            return Some(1.0);
        }
        self.breakpoints
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        if law.quadratic {
            let t = self.sweep(d0, rate);
            let d = self.derivative_at(t, problem, law, slope);
            if d.abs() <= accept {
                return Some(t);
            }
        }
        // φ′(lo) > 0 ≥ φ′(hi), and no breakpoint strictly between them
        let (mut lo, mut d_lo, mut hi, mut d_hi) = (0.0, d0, 1.0, d1);
        let (mut first, mut last) = (0, self.breakpoints.len());
        while first < last {
            let mid = (first + last) / 2;
            let t = self.breakpoints[mid].0;
            let d = self.derivative_at(t, problem, law, slope);
            if d.abs() <= accept {
                return Some(t);
            }
            if d > 0.0 {
                (lo, d_lo, first) = (t, d, mid + 1);
            } else {
                (hi, d_hi, last) = (t, d, mid);
            }
        }
        // regula falsi on the smooth segment, halving the kept end's value (Illinois)
        let mut kept = 0;
        for _ in 0..LINE_SEARCH_TRIALS {
            let t = lo + (hi - lo) * (d_lo / (d_lo - d_hi));
            if !(t > lo && t < hi) {
                break;
            }
            let d = self.derivative_at(t, problem, law, slope);
            if d.abs() <= accept {
                return Some(t);
            }
            if d > 0.0 {
                (lo, d_lo) = (t, d);
                if kept == 1 {
                    d_hi *= 0.5;
                }
                kept = 1;
            } else {
                (hi, d_hi) = (t, d);
                if kept == -1 {
                    d_lo *= 0.5;
                }
                kept = -1;
            }
        }
        if lo > 0.0 {
            self.derivative_at(lo, problem, law, slope);
            Some(lo)
        } else {
            None
        }
    }

    /// For p = 2, with φ′(1) < 0: the root of the piecewise-linear φ′, swept over the sorted
    /// breakpoints from φ′(0) = `d0` and its slope `rate` after 0.
    fn sweep(&self, d0: f64, rate: f64) -> f64 {
        let (mut t, mut d, mut rate) = (0.0, d0, rate);
        for &(next, change) in &self.breakpoints {
            let d_next = d + rate * (next - t);
            if d_next <= 0.0 {
                // d > 0 ≥ d_next, so rate < 0
                return (t + d / -rate).clamp(t, next);
            }
            (t, d, rate) = (next, d_next, rate + change);
        }
        (t + d / -rate).clamp(t, 1.0)
    }

    /// φ′(1) as [`Self::derivative_at`] computes it (x(s + δ) left in the `_trial` arrays),
    /// and on the same pass the breakpoints in (0, 1), sᵢ + tδᵢ = sᵢ(lᵢ) or sᵢ(uᵢ), each with
    /// the change it makes to the slope of φ′ for p = 2 (−δᵢ²Dᵢ entering the box, +δᵢ²Dᵢ
    /// leaving it), unsorted in `breakpoints`; returns (φ′(1), the slope of φ′ just after
    /// t = 0). A full step that is accepted leaves the breakpoints unused; the pass saved
    /// when it is not is the larger share.
    fn full_step_and_breakpoints(
        &mut self,
        problem: &QpProblem<'_>,
        law: &PowerLaw,
        slope: &Slope,
    ) -> (f64, f64) {
        let mut moved = 0.0;
        let mut rate = -slope.mu * slope.step_norm2;
        self.breakpoints.clear();
        for i in 0..self.m {
            let (s, delta) = (self.s[i], self.a_step[i]);
            let (x, d) = law.minimiser(
                s + delta,
                problem.weights[i],
                problem.lower[i],
                problem.upper[i],
                self.slope_reference[i],
            );
            moved += delta * (x - self.x[i]);
            self.s_trial[i] = s + delta;
            self.x_trial[i] = x;
            self.slope_trial[i] = d;
            if delta == 0.0 {
                continue;
            }
            let (lower, upper) = (self.s_at_lower[i], self.s_at_upper[i]);
            let curvature = delta * delta * self.slope_reference[i];
            let free = (s > lower || (s == lower && delta > 0.0))
                && (s < upper || (s == upper && delta < 0.0));
            if free {
                rate -= curvature;
            }
            for (threshold, entering) in [(lower, delta > 0.0), (upper, delta < 0.0)] {
                // t = gap/δ is in (0, 1) only if gap and δ share their sign and |gap| < |δ|:
                // most thresholds fail that test, and it spares their divisions
                let gap = threshold - s;
                if (gap > 0.0) != (delta > 0.0) || !(gap.abs() < delta.abs()) {
                    continue;
                }
                let t = gap / delta;
                if t > 0.0 && t < 1.0 {
                    let change = if entering { -curvature } else { curvature };
                    self.breakpoints.push((t, change));
                }
            }
        }
        (slope.psi - moved - slope.mu * slope.step_norm2, rate)
    }

    /// φ′(t) of [`Self::line_search`], leaving x(s + tδ) in the `_trial` arrays.
    fn derivative_at(
        &mut self,
        t: f64,
        problem: &QpProblem<'_>,
        law: &PowerLaw,
        slope: &Slope,
    ) -> f64 {
        let mut moved = 0.0;
        for i in 0..self.m {
            let s = self.s[i] + t * self.a_step[i];
            let (x, d) = law.minimiser(
                s,
                problem.weights[i],
                problem.lower[i],
                problem.upper[i],
                self.slope_reference[i],
            );
            moved += self.a_step[i] * (x - self.x[i]);
            self.s_trial[i] = s;
            self.x_trial[i] = x;
            self.slope_trial[i] = d;
        }
        slope.psi - moved - slope.mu * t * slope.step_norm2
    }

    /// Whether x is a stationary point of ½‖A x − b‖² over the box: for every coordinate
    /// not fixed, the gradient gᵢ = aᵢᵀr, kept where it allows descent (gᵢ < 0 at the lower
    /// bound, gᵢ > 0 at the upper bound, any sign inside), is at most
    /// ε_inf ‖aᵢ‖ ‖r‖ in magnitude.
    fn least_squares_stationary(
        &self,
        problem: &QpProblem<'_>,
        settings: &QpSettings,
        r_norm: f64,
    ) -> bool {
        let eps = settings.infeasibility_tolerance * r_norm;
        (0..self.m).all(|i| {
            let (l, u, x) = (problem.lower[i], problem.upper[i], self.x[i]);
            if l == u {
                return true;
            }
            let g = self.columns.dot(i, &self.residual);
            let projected = if x <= l {
                g.min(0.0)
            } else if x >= u {
                g.max(0.0)
            } else {
                g
            };
            projected.abs() <= eps * self.column_norm[i]
        })
    }
}
