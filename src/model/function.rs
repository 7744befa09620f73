//! Scalar functions of coordinates, as OpenSim defines them: `Constant`, `LinearFunction`,
//! `PolynomialFunction`, `SimmSpline` (= `NaturalCubicSpline`, which OpenSim reads as a
//! `SimmSpline`), `PiecewiseLinearFunction`, `GCVSpline`, `MultiplierFunction` and
//! `MultivariatePolynomialFunction`.
//!
//! Every function returns its value and its first and second partial derivatives, which the
//! coordinate reduction needs for Φ and Φ̇q̇, and its third derivative along three directions
//! (for the derivatives of Φ̇q̇).

use super::natural_spline::NaturalSpline;

/// A function of zero or more coordinates.
#[derive(Clone, Debug, PartialEq)]
pub enum Function {
    /// f = value, for any number of arguments.
    Constant(f64),
    /// OpenSim `LinearFunction`: coefficients `[a_1, …, a_k, b]`, f(x) = Σ a_i x_i + b.
    Linear(Vec<f64>),
    /// OpenSim `PolynomialFunction`: coefficients from the highest power to the constant,
    /// f(x) = c_0 xⁿ + c_1 xⁿ⁻¹ + … + c_n.
    Polynomial(Vec<f64>),
    /// OpenSim `SimmSpline` / `NaturalCubicSpline`.
    SimmSpline(SimmSpline),
    /// OpenSim `PiecewiseLinearFunction`.
    PiecewiseLinear(PiecewiseLinear),
    /// OpenSim `GCVSpline` with `error_variance` = 0: the interpolating natural spline of
    /// degree 2·half_order − 1.
    GcvSpline(NaturalSpline),
    /// OpenSim `MultiplierFunction`: f = scale · g.
    Multiplier(Box<Function>, f64),
    /// OpenSim `MultivariatePolynomialFunction`: a polynomial of `dimension` arguments whose
    /// terms have total degree at most `order`.
    MultivariatePolynomial(MultivariatePolynomial),
}

/// How many arguments a function accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arity {
    Any,
    Exactly(usize),
}

impl Function {
    /// The number of arguments this function takes.
    pub fn arity(&self) -> Arity {
        match self {
            Function::Constant(_) => Arity::Any,
            Function::Linear(c) => Arity::Exactly(c.len().saturating_sub(1)),
            Function::Multiplier(f, _) => f.arity(),
            Function::MultivariatePolynomial(p) => Arity::Exactly(p.dimension()),
            _ => Arity::Exactly(1),
        }
    }

    /// The OpenSim element name of this function.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Function::Constant(_) => "Constant",
            Function::Linear(_) => "LinearFunction",
            Function::Polynomial(_) => "PolynomialFunction",
            Function::SimmSpline(_) => "SimmSpline",
            Function::PiecewiseLinear(_) => "PiecewiseLinearFunction",
            Function::GcvSpline(_) => "GCVSpline",
            Function::Multiplier(_, _) => "MultiplierFunction",
            Function::MultivariatePolynomial(_) => "MultivariatePolynomialFunction",
        }
    }

    /// True when the function is a constant whatever its arguments.
    pub fn is_constant(&self) -> bool {
        match self {
            Function::Constant(_) => true,
            Function::Multiplier(f, s) => *s == 0.0 || f.is_constant(),
            Function::MultivariatePolynomial(p) => p.is_constant(),
            _ => false,
        }
    }

    /// True when every third partial derivative is zero everywhere (a `Constant`, a
    /// `LinearFunction`, a `PiecewiseLinearFunction`, a multivariate polynomial of order ≤ 2,
    /// or a multiple of one), so that [`Function::third_directional`] can be skipped.
    pub fn third_order_vanishes(&self) -> bool {
        match self {
            Function::Constant(_) | Function::Linear(_) | Function::PiecewiseLinear(_) => true,
            Function::Polynomial(c) => c.len() <= 3,
            Function::Multiplier(f, s) => *s == 0.0 || f.third_order_vanishes(),
            Function::MultivariatePolynomial(p) => p.order() <= 2,
            Function::SimmSpline(_) | Function::GcvSpline(_) => false,
        }
    }

    /// Value, first and second derivative of a function of one argument. A `Constant`
    /// returns zero derivatives. For a `LinearFunction` of one argument the slope is used.
    #[inline]
    pub fn eval1(&self, x: f64) -> (f64, f64, f64) {
        match self {
            Function::Constant(v) => (*v, 0.0, 0.0),
            Function::Linear(c) => {
                if c.len() == 2 {
                    (c[0] * x + c[1], c[0], 0.0)
                } else {
                    (c.last().copied().unwrap_or(0.0), 0.0, 0.0)
                }
            }
            Function::Polynomial(c) => polynomial(c, x),
            Function::SimmSpline(s) => s.eval(x),
            Function::PiecewiseLinear(p) => p.eval(x),
            Function::GcvSpline(s) => s.eval(x),
            Function::Multiplier(f, s) => {
                let (v, d1, d2) = f.eval1(x);
                (s * v, s * d1, s * d2)
            }
            // a constant polynomial of any dimension is its constant term (as for a
            // LinearFunction of several arguments above, a fixed axis is evaluated at 0)
            Function::MultivariatePolynomial(p) if p.is_constant() => {
                (p.coefficients()[0], 0.0, 0.0)
            }
            Function::MultivariatePolynomial(p) => {
                let (mut d1, mut d2) = ([0.0], [0.0]);
                let v = p.eval(&[x], &mut d1, &mut d2);
                (v, d1[0], d2[0])
            }
        }
    }

    /// Third derivative of a function of one argument (what exact derivatives of Φ̇q̇ with
    /// respect to q need). A `Constant`, a `LinearFunction` and a `PiecewiseLinearFunction`
    /// give 0; the splines give the third derivative of the piece holding x (0 where they
    /// extrapolate linearly).
    pub fn third_derivative1(&self, x: f64) -> f64 {
        match self {
            Function::Constant(_) | Function::Linear(_) | Function::PiecewiseLinear(_) => 0.0,
            Function::Polynomial(c) => polynomial_third_derivative(c, x),
            Function::SimmSpline(s) => s.third_derivative(x),
            Function::GcvSpline(s) => s.derivative(x, 3),
            Function::Multiplier(f, s) => s * f.third_derivative1(x),
            Function::MultivariatePolynomial(p) => {
                p.third_directional(&[x], &[1.0], &[1.0], &[1.0])
            }
        }
    }

    /// D³f(x)[u, v, w] = Σ_abc ∂³f/∂x_a∂x_b∂x_c u_a v_b w_c, the third derivative of a
    /// function of `x.len()` arguments along three directions; f‴(x) u v w for one argument.
    /// The caller guarantees that `x` matches `arity()` and the directions have its length.
    pub fn third_directional(&self, x: &[f64], u: &[f64], v: &[f64], w: &[f64]) -> f64 {
        match (self, x.len()) {
            (Function::Constant(_) | Function::Linear(_), _) => 0.0,
            (Function::Multiplier(f, s), _) => s * f.third_directional(x, u, v, w),
            (Function::MultivariatePolynomial(p), _) => p.third_directional(x, u, v, w),
            (_, 1) => self.third_derivative1(x[0]) * u[0] * v[0] * w[0],
            // Unreachable for functions validated against their arity at model load.
            _ => f64::NAN,
        }
    }

    /// Value of a function of `x.len()` arguments, with its gradient written to `grad`
    /// (length k) and its Hessian to `hess` (k×k, row-major). The caller guarantees that `x`
    /// matches `arity()` and the slices have the right lengths.
    pub fn eval(&self, x: &[f64], grad: &mut [f64], hess: &mut [f64]) -> f64 {
        match (self, x.len()) {
            (Function::Constant(v), _) => {
                grad.fill(0.0);
                hess.fill(0.0);
                *v
            }
            (Function::Linear(c), k) if k + 1 == c.len() => {
                hess.fill(0.0);
                let mut v = c[k];
                for i in 0..k {
                    grad[i] = c[i];
                    v += c[i] * x[i];
                }
                v
            }
            (Function::Multiplier(f, s), _) => {
                let v = f.eval(x, grad, hess);
                grad.iter_mut().for_each(|g| *g *= s);
                hess.iter_mut().for_each(|h| *h *= s);
                s * v
            }
            (Function::MultivariatePolynomial(p), k) if k == p.dimension() => p.eval(x, grad, hess),
            (_, 1) => {
                let (v, d1, d2) = self.eval1(x[0]);
                grad[0] = d1;
                hess[0] = d2;
                v
            }
            _ => {
                // Unreachable for functions validated against their arity at model load.
                grad.fill(f64::NAN);
                hess.fill(f64::NAN);
                f64::NAN
            }
        }
    }
}

/// Horner evaluation of a polynomial (highest power first) and its two derivatives.
fn polynomial(c: &[f64], x: f64) -> (f64, f64, f64) {
    // p = Σ c_i x^(n-i); p' and p'' accumulated alongside (Horner's scheme for derivatives).
    let (mut p, mut d1, mut d2) = (0.0, 0.0, 0.0);
    for &ci in c {
        d2 = d2 * x + 2.0 * d1;
        d1 = d1 * x + p;
        p = p * x + ci;
    }
    (p, d1, d2)
}

/// Third derivative of a polynomial (highest power first): p‴ = Σ c_i m(m−1)(m−2) x^(m−3)
/// with m = n − i, by Horner's scheme on the differentiated coefficients.
fn polynomial_third_derivative(c: &[f64], x: f64) -> f64 {
    let n = c.len().saturating_sub(1);
    let mut d3 = 0.0;
    for (i, &ci) in c.iter().enumerate() {
        if n - i >= 3 {
            let m = (n - i) as f64;
            d3 = d3 * x + ci * m * (m - 1.0) * (m - 2.0);
        }
    }
    d3
}

pub use super::knots::MIN_KNOT_GAP_FRACTION;
use super::knots::check_xy;

/// Index k of the interval [x_k, x_{k+1}] holding t, for x[0] ≤ t ≤ x[n-1].
#[inline]
fn interval(x: &[f64], t: f64) -> usize {
    let n = x.len();
    // partition_point gives the first index with x > t.
    let k = x.partition_point(|&xi| xi <= t);
    k.saturating_sub(1).min(n - 2)
}

/// OpenSim's `SimmSpline`: the cubic spline of Forsythe, Malcolm & Moler (1977,
/// *Computer Methods for Mathematical Computations*, routine SPLINE). Its end conditions
/// match the third derivative at each end to that of the cubic through the four nearest
/// points (so it reproduces any cubic exactly); with three points the end third derivatives
/// are zero, and two points give a straight line. Outside [x_0, x_{n−1}] it extrapolates
/// linearly with the end slope, as OpenSim does.
#[derive(Clone, Debug, PartialEq)]
pub struct SimmSpline {
    x: Vec<f64>,
    y: Vec<f64>,
    // On [x_i, x_{i+1}]: s(t) = y_i + b_i dt + c_i dt² + d_i dt³, dt = t − x_i.
    b: Vec<f64>,
    c: Vec<f64>,
    d: Vec<f64>,
}

impl SimmSpline {
    pub fn new(x: Vec<f64>, y: Vec<f64>) -> Result<Self, String> {
        check_xy(&x, &y, 2)?;
        let n = x.len();
        let mut b = vec![0.0; n];
        let mut c = vec![0.0; n];
        let mut d = vec![0.0; n];
        if n == 2 {
            let slope = (y[1] - y[0]) / (x[1] - x[0]);
            b.fill(slope);
            return Ok(SimmSpline { x, y, b, c, d });
        }
        // Unknowns σ_i = s''(x_i)/6. Interior rows (h_i = x_{i+1} − x_i, δ_i the divided
        // difference (y_{i+1} − y_i)/h_i):
        //   h_{i−1} σ_{i−1} + 2 (h_{i−1} + h_i) σ_i + h_i σ_{i+1} = δ_i − δ_{i−1}.
        // End rows match the third derivative s''' = 6 (σ_1 − σ_0)/h_0 to that of the
        // interpolating cubic through the first four points (likewise at the end):
        //   −h_0 σ_0 + h_0 σ_1 = h_0² Δ³_0,   h_{n−2} σ_{n−2} − h_{n−2} σ_{n−1} = −h_{n−2}² Δ³_{n−4}
        // with Δ³ the third divided difference; zero right-hand sides when n = 3.
        let h: Vec<f64> = (0..n - 1).map(|i| x[i + 1] - x[i]).collect();
        let delta: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
        let mut diag = vec![0.0; n];
        let mut rhs = vec![0.0; n];
        diag[0] = -h[0];
        diag[n - 1] = -h[n - 2];
        for i in 1..n - 1 {
            diag[i] = 2.0 * (h[i - 1] + h[i]);
            rhs[i] = delta[i] - delta[i - 1];
        }
        if n > 3 {
            let dd2 = |i: usize| (delta[i + 1] - delta[i]) / (x[i + 2] - x[i]);
            let third_first = (dd2(1) - dd2(0)) / (x[3] - x[0]);
            let third_last = (dd2(n - 3) - dd2(n - 4)) / (x[n - 1] - x[n - 4]);
            rhs[0] = h[0] * h[0] * third_first;
            rhs[n - 1] = -h[n - 2] * h[n - 2] * third_last;
        }
        // Symmetric tridiagonal system with off-diagonal h_i: Gaussian elimination without
        // pivoting (the matrix is diagonally dominant in the interior), then back substitution.
        for i in 1..n {
            let t = h[i - 1] / diag[i - 1];
            diag[i] -= t * h[i - 1];
            rhs[i] -= t * rhs[i - 1];
        }
        let mut sigma = vec![0.0; n];
        sigma[n - 1] = rhs[n - 1] / diag[n - 1];
        for i in (0..n - 1).rev() {
            sigma[i] = (rhs[i] - h[i] * sigma[i + 1]) / diag[i];
        }
        // Polynomial coefficients on each interval from σ:
        //   b_i = δ_i − h_i (σ_{i+1} + 2σ_i),  c_i = 3σ_i,  d_i = (σ_{i+1} − σ_i)/h_i.
        for i in 0..n - 1 {
            b[i] = delta[i] - h[i] * (sigma[i + 1] + 2.0 * sigma[i]);
            c[i] = 3.0 * sigma[i];
            d[i] = (sigma[i + 1] - sigma[i]) / h[i];
        }
        // Slope at the last knot, used for extrapolation: s'(x_{n−1}) = δ_{n−2} + h_{n−2}(σ_{n−2} + 2σ_{n−1}).
        b[n - 1] = delta[n - 2] + h[n - 2] * (sigma[n - 2] + 2.0 * sigma[n - 1]);
        c[n - 1] = 3.0 * sigma[n - 1];
        d[n - 1] = d[n - 2];
        // knots a subnormal distance apart, or values huge for their spacing, overflow here
        for (name, v) in [("slope", &b), ("curvature", &c), ("third-order", &d)] {
            if let Some(i) = v.iter().position(|a| !a.is_finite()) {
                return Err(format!(
                    "the spline's {name} coefficient on [x[{i}], x[{}]] is {}: its values are \
                     too large for the spacing of its knots",
                    (i + 1).min(n - 1),
                    v[i]
                ));
            }
        }
        Ok(SimmSpline { x, y, b, c, d })
    }

    pub fn x(&self) -> &[f64] {
        &self.x
    }

    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Value, first and second derivative at t.
    #[inline]
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let n = self.x.len();
        if t < self.x[0] {
            return (self.y[0] + (t - self.x[0]) * self.b[0], self.b[0], 0.0);
        }
        if t > self.x[n - 1] {
            return (
                self.y[n - 1] + (t - self.x[n - 1]) * self.b[n - 1],
                self.b[n - 1],
                0.0,
            );
        }
        let k = interval(&self.x, t);
        let dt = t - self.x[k];
        let (b, c, d) = (self.b[k], self.c[k], self.d[k]);
        (
            self.y[k] + dt * (b + dt * (c + dt * d)),
            b + dt * (2.0 * c + 3.0 * dt * d),
            2.0 * c + 6.0 * dt * d,
        )
    }
}

impl SimmSpline {
    /// Third derivative at t: 6 d_k on the interval holding t, 0 where the spline
    /// extrapolates linearly.
    pub fn third_derivative(&self, t: f64) -> f64 {
        if t < self.x[0] || t > self.x[self.x.len() - 1] {
            return 0.0;
        }
        6.0 * self.d[interval(&self.x, t)]
    }
}

/// OpenSim's `PiecewiseLinearFunction`: linear interpolation between the points, linear
/// extrapolation with the first (last) segment's slope outside the range.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseLinear {
    x: Vec<f64>,
    y: Vec<f64>,
    slope: Vec<f64>,
}

impl PiecewiseLinear {
    pub fn new(x: Vec<f64>, y: Vec<f64>) -> Result<Self, String> {
        check_xy(&x, &y, 2)?;
        let slope = (0..x.len() - 1)
            .map(|i| (y[i + 1] - y[i]) / (x[i + 1] - x[i]))
            .collect();
        Ok(PiecewiseLinear { x, y, slope })
    }

    #[inline]
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let k = if t < self.x[0] {
            0
        } else if t > self.x[self.x.len() - 1] {
            self.slope.len() - 1
        } else {
            interval(&self.x, t)
        };
        (
            self.y[k] + (t - self.x[k]) * self.slope[k],
            self.slope[k],
            0.0,
        )
    }
}

/// Largest `dimension` of a [`MultivariatePolynomial`] musculo reads: a coordinate coupled to
/// more coordinates than this is no musculoskeletal model, and the limit keeps a typing error
/// in a file from allocating a huge exponent table.
pub const MAX_POLYNOMIAL_DIMENSION: usize = 32;

/// OpenSim's `MultivariatePolynomialFunction` of n = `dimension` arguments and total degree at
/// most `order`:
///
/// ```text
/// f(x) = Σ_t c_t Π_i x_i^(e_ti),   over every exponent vector e_t with Σ_i e_ti ≤ order,
/// ```
///
/// C(n + order, order) terms. The coefficients are in OpenSim's order: the exponent vectors
/// (e_0, …, e_{n−1}) ascending lexicographically, the last argument's exponent varying
/// fastest. For n = 2, order 2: 1, x₁, x₁², x₀, x₀x₁, x₀² (so c_1 multiplies the *last*
/// argument; the reverse of the univariate `PolynomialFunction`, which starts at the highest
/// power).
///
/// Derivatives are exact, term by term, with the falling powers
/// ∂ᵐ(xᵉ)/∂xᵐ = e (e − 1) … (e − m + 1) x^(e − m) (zero for m > e): a partial derivative of a
/// term by the multiset of arguments {a, b, …} is Π_i ∂^(m_i) x_i^(e_ti) with m_i how many
/// times i appears. (OpenSim 4.6 itself evaluates only first derivatives of this function.)
#[derive(Clone, Debug, PartialEq)]
pub struct MultivariatePolynomial {
    dimension: usize,
    order: usize,
    coefficients: Vec<f64>,
    /// e_ti at t · dimension + i, in the coefficients' order.
    exponents: Vec<u32>,
}

impl MultivariatePolynomial {
    /// Checks `dimension` (1 to [`MAX_POLYNOMIAL_DIMENSION`]), the number of coefficients
    /// (C(dimension + order, order)) and their finiteness.
    pub fn new(dimension: usize, order: usize, coefficients: Vec<f64>) -> Result<Self, String> {
        if dimension == 0 {
            return Err("<dimension> must be at least 1".into());
        }
        if dimension > MAX_POLYNOMIAL_DIMENSION {
            return Err(format!(
                "<dimension> {dimension} exceeds the {MAX_POLYNOMIAL_DIMENSION} arguments musculo reads"
            ));
        }
        let n = coefficients.len();
        // C(dimension + order, order) ≥ order + 1: an order ≥ n is too large, and is only
        // counted (in `order` steps) when small
        let count = if order < n.max(1000) {
            term_count(dimension, order)
        } else {
            None
        };
        match count {
            Some(t) if t == n => {}
            Some(t) => {
                return Err(format!(
                    "<coefficients> has {n} values; dimension {dimension} and order {order} \
                     need C({dimension} + {order}, {order}) = {t}"
                ));
            }
            None => {
                return Err(format!(
                    "<coefficients> has {n} values; dimension {dimension} and order {order} \
                     need C({dimension} + {order}, {order}), more than that"
                ));
            }
        }
        if let Some(i) = coefficients.iter().position(|c| !c.is_finite()) {
            return Err(format!(
                "<coefficients> value {i} (counting from 0) is {}",
                coefficients[i]
            ));
        }
        let exponents = exponent_table(dimension, order);
        debug_assert_eq!(exponents.len(), n * dimension);
        Ok(MultivariatePolynomial {
            dimension,
            order,
            coefficients,
            exponents,
        })
    }

    pub fn dimension(&self) -> usize {
        self.dimension
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// The coefficients, in OpenSim's order (see the type's description).
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// The exponents (e_t0, …, e_t,n−1) of term t.
    pub fn exponents(&self, t: usize) -> &[u32] {
        &self.exponents[t * self.dimension..(t + 1) * self.dimension]
    }

    /// True when every non-constant term has a zero coefficient.
    pub fn is_constant(&self) -> bool {
        self.coefficients[1..].iter().all(|&c| c == 0.0)
    }

    /// ∂^(m_0 + …) f / ∂x_0^(m_0) … of term t without its coefficient: Π_i ∂^(m_i) x_i^(e_ti),
    /// with `m(i)` the order in argument i; the powers x_i^k from `powers` (see [`Powers`]).
    #[inline]
    fn term_derivative(&self, t: usize, powers: &Powers, m: impl Fn(usize) -> u32) -> f64 {
        let mut p = 1.0;
        for (i, &e) in self.exponents(t).iter().enumerate() {
            let mi = m(i);
            if mi > e {
                return 0.0;
            }
            p *= falling_factor(e, mi) * powers.get(i, e - mi);
        }
        p
    }

    /// Value at x, gradient into `grad` (length n) and Hessian into `hess` (n×n, row-major):
    /// term by term, f = Σ_t c_t Π_i x_i^(e_ti), f_a = Σ_t c_t ∂_a(…), f_ab = Σ_t c_t ∂_ab(…).
    /// NaN everywhere when the lengths do not match the dimension.
    pub fn eval(&self, x: &[f64], grad: &mut [f64], hess: &mut [f64]) -> f64 {
        let n = self.dimension;
        if x.len() != n || grad.len() != n || hess.len() != n * n {
            grad.fill(f64::NAN);
            hess.fill(f64::NAN);
            return f64::NAN;
        }
        grad.fill(0.0);
        hess.fill(0.0);
        let powers = Powers::new(x, self.order);
        if n == 2 && powers.tabulated {
            return self.eval2(&powers, grad, hess);
        }
        let x = &powers;
        let mut v = 0.0;
        for (t, &c) in self.coefficients.iter().enumerate() {
            if c == 0.0 {
                continue;
            }
            v += c * self.term_derivative(t, x, |_| 0);
            for a in 0..n {
                if self.exponents(t)[a] == 0 {
                    continue;
                }
                grad[a] += c * self.term_derivative(t, x, |i| u32::from(i == a));
                for b in a..n {
                    let h =
                        c * self.term_derivative(t, x, |i| u32::from(i == a) + u32::from(i == b));
                    hess[a * n + b] += h;
                    if b != a {
                        hess[b * n + a] += h;
                    }
                }
            }
        }
        v
    }

    /// [`Self::eval`] for two arguments (x, y) from tabulated powers, term by term
    /// (c xⁱ yʲ):
    ///   f += c xⁱ yʲ,  f_x += c i xⁱ⁻¹ yʲ,  f_y += c j xⁱ yʲ⁻¹,
    ///   f_xx += c i(i−1) xⁱ⁻² yʲ,  f_xy += c i j xⁱ⁻¹ yʲ⁻¹,  f_yy += c j(j−1) xⁱ yʲ⁻².
    fn eval2(&self, powers: &Powers, grad: &mut [f64], hess: &mut [f64]) -> f64 {
        let (px, py) = (&powers.table[0], &powers.table[1]);
        let (mut v, mut gx, mut gy, mut hxx, mut hxy, mut hyy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (t, &c) in self.coefficients.iter().enumerate() {
            let e = &self.exponents[2 * t..2 * t + 2];
            let (i, j) = (e[0] as usize, e[1] as usize);
            let (fi, fj) = (e[0] as f64, e[1] as f64);
            let (xi, yj) = (px[i], py[j]);
            v += c * xi * yj;
            if i >= 1 {
                let xi1 = c * fi * px[i - 1];
                gx += xi1 * yj;
                if j >= 1 {
                    hxy += xi1 * fj * py[j - 1];
                }
                if i >= 2 {
                    hxx += c * fi * (fi - 1.0) * px[i - 2] * yj;
                }
            }
            if j >= 1 {
                gy += c * fj * xi * py[j - 1];
                if j >= 2 {
                    hyy += c * fj * (fj - 1.0) * xi * py[j - 2];
                }
            }
        }
        grad[0] = gx;
        grad[1] = gy;
        hess[0] = hxx;
        hess[1] = hxy;
        hess[2] = hxy;
        hess[3] = hyy;
        v
    }

    /// D³f(x)[u, v, w] = Σ_t c_t Σ_abc ∂_abc(Π_i x_i^(e_ti)) u_a v_b w_c; NaN when the lengths
    /// do not match the dimension.
    pub fn third_directional(&self, x: &[f64], u: &[f64], v: &[f64], w: &[f64]) -> f64 {
        let n = self.dimension;
        if [x.len(), u.len(), v.len(), w.len()] != [n; 4] {
            return f64::NAN;
        }
        if self.order < 3 {
            return 0.0;
        }
        let powers = Powers::new(x, self.order);
        let x = &powers;
        let mut d = 0.0;
        for (t, &c) in self.coefficients.iter().enumerate() {
            if c == 0.0 || self.exponents(t).iter().sum::<u32>() < 3 {
                continue;
            }
            for a in 0..n {
                for b in 0..n {
                    for k in 0..n {
                        let weight = u[a] * v[b] * w[k];
                        if weight == 0.0 {
                            continue;
                        }
                        let m =
                            |i: usize| u32::from(i == a) + u32::from(i == b) + u32::from(i == k);
                        d += c * weight * self.term_derivative(t, x, m);
                    }
                }
            }
        }
        d
    }
}

/// e (e − 1) … (e − m + 1), the factor of ∂ᵐ(xᵉ)/∂xᵐ = e (e − 1) … (e − m + 1) x^(e − m), for
/// m ≤ e.
#[inline]
fn falling_factor(e: u32, m: u32) -> f64 {
    let mut k = 1.0;
    for j in 0..m {
        k *= f64::from(e - j);
    }
    k
}

/// The powers x_i^k, k = 0…order, of every argument, computed once per evaluation by repeated
/// multiplication (x^k = x^(k−1) x) and kept on the stack for up to [`Powers::DIMENSIONS`]
/// arguments and order [`Powers::ORDER`]; beyond that each power is computed where it is used.
struct Powers<'a> {
    x: &'a [f64],
    table: [[f64; Powers::ORDER + 1]; Powers::DIMENSIONS],
    tabulated: bool,
}

impl<'a> Powers<'a> {
    const DIMENSIONS: usize = 3;
    const ORDER: usize = 24;

    fn new(x: &'a [f64], order: usize) -> Powers<'a> {
        let mut table = [[1.0; Powers::ORDER + 1]; Powers::DIMENSIONS];
        let tabulated = x.len() <= Powers::DIMENSIONS && order <= Powers::ORDER;
        if tabulated {
            for (row, &xi) in table.iter_mut().zip(x) {
                for k in 1..=order {
                    row[k] = row[k - 1] * xi;
                }
            }
        }
        Powers {
            x,
            table,
            tabulated,
        }
    }

    /// x_i^k (k ≤ the polynomial's order).
    #[inline]
    fn get(&self, i: usize, k: u32) -> f64 {
        if self.tabulated {
            self.table[i][k as usize]
        } else {
            self.x[i].powi(k as i32)
        }
    }
}

/// C(dimension + order, order), the number of terms, computed as the running product
/// C(n + j, j) = C(n + j − 1, j − 1) (n + j) / j; None when it overflows.
fn term_count(dimension: usize, order: usize) -> Option<usize> {
    let mut c: usize = 1;
    for j in 1..=order {
        // C(n + j − 1, j − 1) (n + j) is divisible by j
        c = c.checked_mul(dimension.checked_add(j)?)? / j;
    }
    Some(c)
}

/// The exponent vectors of every term in OpenSim's order: (e_0, …, e_{n−1}) ascending
/// lexicographically with Σ e_i ≤ order (the last exponent varies fastest), flattened. The
/// successor of e increases the last e_i for which e_0 + … + e_i < order and zeroes those
/// after it; there is none after (order, 0, …, 0).
fn exponent_table(dimension: usize, order: usize) -> Vec<u32> {
    // order < the number of terms, itself a length in memory
    let order = u32::try_from(order).unwrap_or(u32::MAX);
    let mut table = Vec::new();
    let mut e = vec![0u32; dimension];
    loop {
        table.extend_from_slice(&e);
        let mut prefix: u32 = e.iter().sum();
        let mut next = None;
        for i in (0..dimension).rev() {
            // prefix = e_0 + … + e_i here
            if prefix < order {
                next = Some(i);
                break;
            }
            prefix -= e[i];
        }
        let Some(i) = next else {
            return table;
        };
        e[i] += 1;
        e[i + 1..].fill(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic(t: f64) -> (f64, f64, f64) {
        (
            0.5 - 1.2 * t + 0.7 * t * t - 0.3 * t * t * t,
            -1.2 + 1.4 * t - 0.9 * t * t,
            1.4 - 1.8 * t,
        )
    }

    #[test]
    fn simm_spline_reproduces_any_cubic_exactly() {
        // FMM end conditions match the third derivative of the cubic through the end points,
        // so sampled cubic data is reproduced exactly inside the range.
        let x = vec![-2.0, -1.3, -0.2, 0.1, 0.9, 1.7, 2.5];
        let y: Vec<f64> = x.iter().map(|&t| cubic(t).0).collect();
        let s = SimmSpline::new(x, y).unwrap();
        for i in 0..=100 {
            let t = -2.0 + 4.5 * i as f64 / 100.0;
            let (v, d1, d2) = s.eval(t);
            let (ev, ed1, ed2) = cubic(t);
            assert!((v - ev).abs() < 1e-12, "value at {t}");
            assert!((d1 - ed1).abs() < 1e-11, "slope at {t}");
            assert!((d2 - ed2).abs() < 1e-10, "curvature at {t}");
        }
    }

    #[test]
    fn simm_spline_extrapolates_linearly_with_end_slopes() {
        let x = vec![0.0, 1.0, 2.5, 3.0, 4.0];
        let y: Vec<f64> = x.iter().map(|&t| cubic(t).0).collect();
        let s = SimmSpline::new(x, y).unwrap();
        let (y0, b0, _) = s.eval(0.0);
        let (v, d1, d2) = s.eval(-0.5);
        assert!((v - (y0 - 0.5 * b0)).abs() < 1e-14 && d1 == b0 && d2 == 0.0);
        let (yn, bn, _) = s.eval(4.0);
        assert!((yn - cubic(4.0).0).abs() < 1e-12 && (bn - cubic(4.0).1).abs() < 1e-10);
        let (v, _, _) = s.eval(5.0);
        assert!((v - (yn + bn)).abs() < 1e-12);
    }

    #[test]
    fn simm_spline_with_three_points_has_zero_end_third_derivative_conditions() {
        // n = 3: s'''(x_0) from the first interval equals s''' on the second interval
        // (σ_1 − σ_0 = 0 and σ_2 − σ_1 = 0 ⇒ a single parabola through the three points).
        let x = vec![0.0, 1.0, 3.0];
        let p = |t: f64| 1.0 + 2.0 * t - 0.5 * t * t;
        let s = SimmSpline::new(x.clone(), x.iter().map(|&t| p(t)).collect()).unwrap();
        for t in [0.2, 0.9, 1.7, 2.9] {
            assert!((s.eval(t).0 - p(t)).abs() < 1e-13);
        }
    }

    #[test]
    #[allow(clippy::approx_constant)] // knots of gait2392's knee spline, as written in the file
    fn simm_spline_derivatives_match_finite_differences() {
        let x = vec![
            -2.0944, -1.22173, -0.523599, -0.349066, -0.174533, 0.159149, 2.0944,
        ];
        let y = vec![
            -0.4226, -0.4082, -0.399, -0.3976, -0.3966, -0.395264, -0.396,
        ];
        let s = SimmSpline::new(x, y).unwrap();
        let h = 1e-6;
        for i in 0..50 {
            let t = -2.0 + 4.0 * i as f64 / 49.0 + 1e-3;
            let (_, d1, d2) = s.eval(t);
            let fd1 = (s.eval(t + h).0 - s.eval(t - h).0) / (2.0 * h);
            let fd2 = (s.eval(t + h).1 - s.eval(t - h).1) / (2.0 * h);
            assert!((d1 - fd1).abs() < 1e-7, "{t}: {d1} vs {fd1}");
            assert!((d2 - fd2).abs() < 1e-6, "{t}: {d2} vs {fd2}");
        }
    }

    #[test]
    fn spline_interpolates_knots_and_is_c2() {
        let x = vec![0.0, 0.3, 0.5, 1.1, 1.4, 2.0];
        let y = vec![0.0, 0.2, -0.1, 0.5, 0.4, 1.0];
        let s = SimmSpline::new(x.clone(), y.clone()).unwrap();
        for i in 0..x.len() {
            assert!((s.eval(x[i]).0 - y[i]).abs() < 1e-14);
        }
        for &k in &x[1..x.len() - 1] {
            let l = s.eval(k - 1e-9);
            let r = s.eval(k + 1e-9);
            assert!((l.1 - r.1).abs() < 1e-7 && (l.2 - r.2).abs() < 1e-6);
        }
    }

    #[test]
    fn third_derivatives_match_differences_of_second_derivatives() {
        let h = 1e-6;
        let spline_x: Vec<f64> = (0..7).map(|i| -1.0 + 0.37 * i as f64).collect();
        let spline_y: Vec<f64> = spline_x.iter().map(|x| (2.0 * x).sin() + 0.3 * x).collect();
        let functions = [
            Function::Polynomial(vec![0.4, -1.1, 0.3, 2.0, -0.7]),
            Function::SimmSpline(SimmSpline::new(spline_x.clone(), spline_y.clone()).unwrap()),
            Function::GcvSpline(
                NaturalSpline::interpolating(3, spline_x.clone(), spline_y.clone()).unwrap(),
            ),
            Function::Multiplier(
                Box::new(Function::Polynomial(vec![1.0, 0.0, 0.0, 0.0])),
                2.5,
            ),
            Function::Linear(vec![0.8, 0.1]),
        ];
        for f in &functions {
            // points inside intervals (not at knots), and outside the spline range
            for x in [-1.3, -0.81, -0.2, 0.45, 1.02, 1.6] {
                let fd = (f.eval1(x + h).2 - f.eval1(x - h).2) / (2.0 * h);
                let d3 = f.third_derivative1(x);
                assert!(
                    (d3 - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{} at {x}: {d3} vs {fd}",
                    f.kind_name()
                );
            }
        }
        // p‴ = 0.4·4·3·2 x − 1.1·3·2 at x = 0.5
        let p = Function::Polynomial(vec![0.4, -1.1, 0.3, 2.0, -0.7]);
        assert!((p.third_derivative1(0.5) - (9.6 * 0.5 - 6.6)).abs() < 1e-12);
    }

    #[test]
    fn polynomial_uses_highest_power_first() {
        let f = Function::Polynomial(vec![2.0, -3.0, 0.5, 4.0]); // 2x³ − 3x² + 0.5x + 4
        let (v, d1, d2) = f.eval1(1.5);
        assert!((v - (2.0 * 3.375 - 3.0 * 2.25 + 0.75 + 4.0)).abs() < 1e-14);
        assert!((d1 - (6.0 * 2.25 - 6.0 * 1.5 + 0.5)).abs() < 1e-14);
        assert!((d2 - (12.0 * 1.5 - 6.0)).abs() < 1e-14);
    }

    #[test]
    fn piecewise_linear_interpolates_and_extrapolates() {
        let f = PiecewiseLinear::new(vec![0.0, 1.0, 3.0], vec![1.0, 3.0, 2.0]).unwrap();
        assert_eq!(f.eval(0.5), (2.0, 2.0, 0.0));
        assert_eq!(f.eval(2.0), (2.5, -0.5, 0.0));
        assert_eq!(f.eval(-1.0), (-1.0, 2.0, 0.0));
        assert_eq!(f.eval(5.0), (1.0, -0.5, 0.0));
    }

    #[test]
    fn multiplier_and_linear_of_several_arguments() {
        let f = Function::Multiplier(Box::new(Function::Linear(vec![2.0, -1.0, 0.5])), 3.0);
        assert_eq!(f.arity(), Arity::Exactly(2));
        let mut g = [0.0; 2];
        let mut h = [1.0; 4];
        let v = f.eval(&[1.0, 4.0], &mut g, &mut h);
        assert_eq!(v, 3.0 * (2.0 - 4.0 + 0.5));
        assert_eq!(g, [6.0, -3.0]);
        assert_eq!(h, [0.0; 4]);
    }

    /// A small deterministic generator of numbers in [−1, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    fn random_polynomial(rng: &mut Lcg, dimension: usize, order: usize) -> MultivariatePolynomial {
        let n = term_count(dimension, order).unwrap();
        MultivariatePolynomial::new(dimension, order, (0..n).map(|_| rng.next()).collect()).unwrap()
    }

    #[test]
    fn multivariate_polynomial_terms_are_in_opensims_order() {
        // OpenSim 4.6's own table for three arguments (X, Y, Z) and order 3, checked with
        // its Python API (a unit coefficient at index t evaluated at (2, 3, 5) gives
        // 2^a 3^b 5^c): ascending lexicographic exponents, Z's varying fastest.
        let expected: [[u32; 3]; 20] = [
            [0, 0, 0],
            [0, 0, 1],
            [0, 0, 2],
            [0, 0, 3],
            [0, 1, 0],
            [0, 1, 1],
            [0, 1, 2],
            [0, 2, 0],
            [0, 2, 1],
            [0, 3, 0],
            [1, 0, 0],
            [1, 0, 1],
            [1, 0, 2],
            [1, 1, 0],
            [1, 1, 1],
            [1, 2, 0],
            [2, 0, 0],
            [2, 0, 1],
            [2, 1, 0],
            [3, 0, 0],
        ];
        for (t, e) in expected.iter().enumerate() {
            let mut c = vec![0.0; 20];
            c[t] = 1.0;
            let p = MultivariatePolynomial::new(3, 3, c).unwrap();
            assert_eq!(p.exponents(t), e);
            let (mut g, mut h) = ([0.0; 3], [0.0; 9]);
            let v = p.eval(&[2.0, 3.0, 5.0], &mut g, &mut h);
            let monomial = 2f64.powi(e[0] as i32) * 3f64.powi(e[1] as i32) * 5f64.powi(e[2] as i32);
            assert_eq!(v, monomial, "term {t}");
        }
        // the number of terms is C(n + order, order)
        for (n, order, count) in [
            (1, 0, 1),
            (1, 4, 5),
            (2, 2, 6),
            (2, 4, 15),
            (3, 4, 35),
            (6, 3, 84),
        ] {
            assert_eq!(exponent_table(n, order).len(), count * n);
            assert_eq!(term_count(n, order), Some(count));
        }
    }

    #[test]
    fn multivariate_polynomial_matches_hand_computed_derivatives() {
        // dimension 2, order 3, terms 1, y, y², y³, x, xy, xy², x², x²y, x³:
        // f = 1.5 + 2y − xy + 0.5x²y
        let mut c = vec![0.0; 10];
        c[0] = 1.5;
        c[1] = 2.0;
        c[5] = -1.0;
        c[8] = 0.5;
        let f = Function::MultivariatePolynomial(MultivariatePolynomial::new(2, 3, c).unwrap());
        assert_eq!(f.arity(), Arity::Exactly(2));
        let (x, y) = (0.7, -1.3);
        let (mut g, mut h) = ([0.0; 2], [0.0; 4]);
        let v = f.eval(&[x, y], &mut g, &mut h);
        assert!((v - (1.5 + 2.0 * y - x * y + 0.5 * x * x * y)).abs() < 1e-15);
        // f_x = −y + xy, f_y = 2 − x + 0.5x², f_xx = y, f_xy = −1 + x, f_yy = 0
        assert!((g[0] - (-y + x * y)).abs() < 1e-15);
        assert!((g[1] - (2.0 - x + 0.5 * x * x)).abs() < 1e-15);
        assert!((h[0] - y).abs() < 1e-15 && h[3] == 0.0);
        assert!((h[1] - (-1.0 + x)).abs() < 1e-15 && h[1] == h[2]);
        // the only non-zero third derivative is f_xxy = 1: D³f[u, v, w] = u₀v₀w₁ + u₀v₁w₀ + u₁v₀w₀
        let (u, vv, w) = ([0.3, -0.8], [1.1, 0.4], [-0.6, 0.9]);
        let d3 = f.third_directional(&[x, y], &u, &vv, &w);
        let expected = u[0] * vv[0] * w[1] + u[0] * vv[1] * w[0] + u[1] * vv[0] * w[0];
        assert!((d3 - expected).abs() < 1e-15);
        assert!(!f.third_order_vanishes() && !f.is_constant());
    }

    #[test]
    fn multivariate_polynomial_derivatives_match_finite_differences() {
        let mut rng = Lcg(7);
        let h = 1e-6;
        for (n, order) in [(1, 4), (2, 1), (2, 3), (2, 4), (3, 2), (3, 4)] {
            let p = random_polynomial(&mut rng, n, order);
            let f = Function::Multiplier(Box::new(Function::MultivariatePolynomial(p)), 1.7);
            for _ in 0..5 {
                let x: Vec<f64> = (0..n).map(|_| 1.5 * rng.next()).collect();
                let (mut g, mut hs) = (vec![0.0; n], vec![0.0; n * n]);
                f.eval(&x, &mut g, &mut hs);
                let [u, v, w]: [Vec<f64>; 3] =
                    std::array::from_fn(|_| (0..n).map(|_| rng.next()).collect());
                let d3 = f.third_directional(&x, &u, &v, &w);
                for a in 0..n {
                    let (mut xp, mut xm) = (x.clone(), x.clone());
                    xp[a] += h;
                    xm[a] -= h;
                    let (mut gp, mut gm) = (vec![0.0; n], vec![0.0; n]);
                    let (mut hp, mut hm) = (vec![0.0; n * n], vec![0.0; n * n]);
                    let fd =
                        (f.eval(&xp, &mut gp, &mut hp) - f.eval(&xm, &mut gm, &mut hm)) / (2.0 * h);
                    assert!((g[a] - fd).abs() < 1e-8, "n {n} order {order}: f_{a}");
                    for b in 0..n {
                        let fd = (gp[b] - gm[b]) / (2.0 * h);
                        assert!((hs[a * n + b] - fd).abs() < 1e-7, "f_{a}{b}");
                    }
                }
                // D³f[u, v, w] = d/ds (Σ_ab f_ab(x + s w) u_a v_b) at s = 0
                let bilinear = |s: f64| {
                    let xs: Vec<f64> = x.iter().zip(&w).map(|(xi, wi)| xi + s * wi).collect();
                    let (mut g, mut hs) = (vec![0.0; n], vec![0.0; n * n]);
                    f.eval(&xs, &mut g, &mut hs);
                    (0..n * n)
                        .map(|ab| hs[ab] * u[ab / n] * v[ab % n])
                        .sum::<f64>()
                };
                let fd = (bilinear(h) - bilinear(-h)) / (2.0 * h);
                assert!((d3 - fd).abs() < 1e-6, "n {n} order {order}: {d3} vs {fd}");
                if n == 1 {
                    let (v1, d1, d2) = f.eval1(x[0]);
                    let (mut g1, mut h1) = ([0.0], [0.0]);
                    assert_eq!(v1, f.eval(&x, &mut g1, &mut h1));
                    assert_eq!((d1, d2), (g1[0], h1[0]));
                    let t = f.third_derivative1(x[0]);
                    assert!((t * u[0] * v[0] * w[0] - d3).abs() < 1e-12);
                }
            }
            assert_eq!(f.third_order_vanishes(), order <= 2);
        }
    }

    #[test]
    fn bad_multivariate_polynomials_are_rejected() {
        let err = |n, order, c: Vec<f64>| MultivariatePolynomial::new(n, order, c).unwrap_err();
        assert!(err(2, 2, vec![1.0; 5]).contains("C(2 + 2, 2) = 6"));
        assert!(err(2, 2, vec![1.0; 7]).contains("has 7 values"));
        assert!(err(0, 0, vec![1.0]).contains("at least 1"));
        assert!(err(33, 0, vec![1.0]).contains("exceeds"));
        assert!(err(2, 1, vec![1.0, f64::NAN, 0.0]).contains("value 1"));
        // an absurd order is refused without counting its terms
        assert!(err(3, usize::MAX, vec![1.0; 4]).contains("more than that"));
        assert!(err(1, 4, vec![1.0; 4]).contains("C(1 + 4, 4) = 5"));
        assert!(err(usize::MAX, 1, vec![1.0; 4]).contains("exceeds"));
        // lengths that do not match give NaN, never a panic
        let p = MultivariatePolynomial::new(2, 1, vec![1.0, 2.0, 3.0]).unwrap();
        let (mut g, mut h) = ([0.0; 1], [0.0; 1]);
        assert!(p.eval(&[1.0], &mut g, &mut h).is_nan());
        assert!(Function::MultivariatePolynomial(p).eval1(0.5).0.is_nan());
        // a constant of several arguments is its constant term, whatever the arguments
        let p = MultivariatePolynomial::new(2, 2, vec![0.25, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
        assert!(p.is_constant());
        assert_eq!(
            Function::MultivariatePolynomial(p).eval1(0.0),
            (0.25, 0.0, 0.0)
        );
    }

    #[test]
    fn bad_spline_input_is_rejected() {
        assert!(SimmSpline::new(vec![0.0, 1.0], vec![0.0]).is_err());
        assert!(SimmSpline::new(vec![0.0], vec![0.0]).is_err());
        assert!(SimmSpline::new(vec![0.0, 0.0, 1.0], vec![0.0, 1.0, 2.0]).is_err());
        assert!(SimmSpline::new(vec![0.0, f64::NAN], vec![0.0, 1.0]).is_err());
        assert!(PiecewiseLinear::new(vec![1.0, 0.0], vec![0.0, 1.0]).is_err());
    }
}
