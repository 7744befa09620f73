//! Interpolating natural splines of odd degree 2m−1 (half order m), the function behind
//! OpenSim's `GCVSpline` when its `error_variance` is 0 (OpenSim's default).
//!
//! # Definition
//!
//! Given knots x_1 < … < x_n, data y_i and a half order m ≥ 1, the interpolating natural
//! spline of order 2m is the unique function f that
//!
//! * interpolates: f(x_i) = y_i;
//! * is a polynomial of degree ≤ 2m−1 on every interval [x_i, x_{i+1}];
//! * is C^(2m−2) at the interior knots;
//! * satisfies the natural end conditions f^(j)(x_1) = f^(j)(x_n) = 0, j = m, …, 2m−2;
//! * outside [x_1, x_n] is the polynomial of degree ≤ m−1 obtained by truncating the Taylor
//!   expansion of f at the nearest end knot (which, because of the end conditions, keeps f
//!   C^(2m−2) across x_1 and x_n).
//!
//! m = 1 gives piecewise-linear interpolation with constant extrapolation, m = 2 the natural
//! cubic spline with linear extrapolation, m = 3 the natural quintic spline, and so on.
//!
//! # Method
//!
//! f is also the unique minimiser of ∫_{x_1}^{x_n} (f^(m))² dx among all interpolants in the
//! Sobolev space H^m (Schoenberg; Lyche, Schumaker & Sepehrnoori 1983; Woltring 1986); the
//! tests check that property, but the construction imposes the defining conditions directly.
//!
//! Abscissae are mapped to u = (x − x_1)/(x_n − x_1) ∈ [0, 1] and ordinates divided by
//! max |y_i|. Splines of degree 2m−1 that are C^(2m−2) at the interior knots are written in the
//! B-spline basis of order 2m on the knot sequence with x_1 and x_n repeated 2m times
//! (n + 2m − 2 functions), which keeps the interpolation equations well conditioned on
//! irregular knots. The natural end conditions are not imposed as rows f^(r)(x_1) = 0 in that
//! basis — those rows are badly conditioned when an end interval is much shorter than its
//! neighbours — but by writing the end polynomial in Taylor form with the vanishing terms left
//! out and tying it to the B-spline coefficients through the blossoming (Marsden) identity,
//! whose weights all lie in [−1, 1]. The resulting square system (4m + n unknowns: B-spline
//! coefficients plus m + 1 Taylor coefficients per end) is banded; it is row-equilibrated and
//! solved by banded Gaussian elimination with partial pivoting.
//!
//! Every interval polynomial is then stored as monomial coefficients in the local variable
//! s = (t − x_i)/(x_{i+1} − x_i) ∈ [0, 1], so evaluation is a binary search plus Horner's rule,
//! without allocation.

/// Largest supported half order (OpenSim's `GCVSpline` accepts degrees 1, 3, 5, 7).
const MAX_HALF_ORDER: usize = 4;

/// An interpolating natural spline of half order `m` (degree 2m − 1).
///
/// See the module documentation for the defining conditions.
#[derive(Clone, Debug, PartialEq)]
pub struct NaturalSpline {
    half_order: usize,
    x: Vec<f64>,
    /// For interval i (between `x[i]` and `x[i+1]`), entries `2m·i .. 2m·(i+1)` are the
    /// coefficients c_{i,k} of p_i(s) = Σ_{k=0}^{2m−1} c_{i,k} s^k, s = (t − x_i)/(x_{i+1} − x_i).
    coef: Vec<f64>,
    /// Taylor coefficients f^(j)(x_1)/j!, j = 0, …, m−1, used for t < x_1.
    left: Vec<f64>,
    /// Taylor coefficients f^(j)(x_n)/j!, j = 0, …, m−1, used for t > x_n.
    right: Vec<f64>,
}

/// Which polynomial piece of the spline applies at some abscissa.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Piece {
    /// t < x_1: Taylor polynomial of degree m−1 at x_1.
    Left,
    /// x_i ≤ t ≤ x_{i+1}.
    Interval(usize),
    /// t > x_n: Taylor polynomial of degree m−1 at x_n.
    Right,
}

impl NaturalSpline {
    /// Builds the natural spline of half order `half_order` (m, 1 ≤ m ≤ 4, i.e. degree 1, 3, 5
    /// or 7) interpolating the points (x_i, y_i).
    ///
    /// Requirements (otherwise a human-readable `Err` is returned; this never panics):
    /// * 1 ≤ m ≤ 4;
    /// * `x.len() == y.len()` and at least m points (and at least one);
    /// * all values finite, `x` strictly increasing.
    ///
    /// With exactly n = m points the natural spline is the interpolating polynomial of degree
    /// m − 1 (the only interpolant with ∫(f^(m))² = 0); this case is accepted and produces that
    /// polynomial everywhere. In particular a single point with m = 1 gives a constant.
    ///
    /// An `Err` is also returned in the pathological cases where two knots coincide once the
    /// knot range is mapped to [0, 1] (a spacing below about 1e-16 of the range) or the
    /// computation overflows.
    /// Accuracy is relative to the size of the spline itself; like the interpolation problem,
    /// it degrades as neighbouring spacings become very unequal (roughly ε·ρ to ε·ρ² for a
    /// spacing ratio ρ, ε = 2.2e-16).
    pub fn interpolating(half_order: usize, x: Vec<f64>, y: Vec<f64>) -> Result<Self, String> {
        let mut splines =
            Self::interpolating_many(half_order, x, vec![y]).map_err(|(_, message)| message)?;
        Ok(splines.remove(0))
    }

    /// [`NaturalSpline::interpolating`] of several data columns on the same knots: the
    /// interpolation matrix, its factorization and the B-spline values at the knots depend on
    /// the knots only, so they are computed once (each spline is exactly the one
    /// `interpolating` builds for its column). An `Err` names the first failing column.
    ///
    /// Steps (module documentation, Method): check the data; normalise the knots to
    /// u ∈ [0, 1]; build the B-spline basis of order 2m; assemble the banded system of blossom
    /// and interpolation rows; solve it for every column; convert each solution to the
    /// monomial coefficients of every interval and the Taylor coefficients of the ends.
    pub fn interpolating_many(
        half_order: usize,
        x: Vec<f64>,
        ys: Vec<Vec<f64>>,
    ) -> Result<Vec<Self>, (usize, String)> {
        let m = half_order;
        check_half_order_and_data(m, &x, &ys)?;
        let n = x.len();
        if n == 1 {
            // Only possible for m = 1: the "interpolating polynomial of degree 0".
            return Ok(ys
                .iter()
                .map(|y| Self {
                    half_order: m,
                    coef: Vec::new(),
                    left: vec![y[0]],
                    right: vec![y[0]],
                    x: x.clone(),
                })
                .collect());
        }

        // Normalisation: u = (x − x_1)/L with L = x_n − x_1, and ỹ = y / Y with Y = max |y_i|.
        let (span, u) = normalised_knots(&x)?;
        let basis = EndBlossomBasis::new(m, &u);
        let sys = basis.interpolation_system(&u);
        let y_scales: Vec<f64> = ys
            .iter()
            .map(|y| {
                let y_max = y.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
                if y_max > 0.0 { y_max } else { 1.0 }
            })
            .collect();
        let rhs = basis.right_hand_sides(&ys, &y_scales);
        let solutions = sys.solve_many(rhs)?;

        let knot_ders = basis.interior_knot_derivatives(&u);
        let mut splines = Vec::with_capacity(ys.len());
        for (column, (z, &y_scale)) in solutions.iter().zip(&y_scales).enumerate() {
            let coef = basis.interval_coefficients(&u, &knot_ders, z, y_scale);
            // Extrapolation: f^(r)(x_end)/r! = Y c_r / L^r.
            let taylor = |c: &[f64]| -> Vec<f64> {
                c.iter()
                    .enumerate()
                    .map(|(r, v)| v * y_scale / span.powi(r as i32))
                    .collect()
            };
            let left = taylor(&z[0..m]);
            let right = taylor(&z[basis.col_r..basis.col_r + m]);

            if !coef
                .iter()
                .chain(&left)
                .chain(&right)
                .all(|v| v.is_finite())
            {
                return Err((
                    column,
                    "natural spline computation overflowed: knot spacing or data magnitude too extreme"
                        .to_string(),
                ));
            }

            splines.push(Self {
                half_order: m,
                x: x.clone(),
                coef,
                left,
                right,
            });
        }
        Ok(splines)
    }

    /// The half order m (the spline has degree 2m − 1).
    pub fn half_order(&self) -> usize {
        self.half_order
    }

    /// The knots x_1 < … < x_n.
    pub fn knots(&self) -> &[f64] {
        &self.x
    }

    /// Value, first and second derivative at `t`.
    ///
    /// Outside [x_1, x_n] this is the degree-(m−1) Taylor polynomial at the nearest end knot.
    /// A NaN `t` gives NaNs; an infinite `t` gives non-finite results unless m = 1.
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        self.piece_eval(self.locate(t), t)
    }

    /// Derivative of order `order` (0 = value) at `t`. Orders ≥ 2m are identically 0 (≥ m
    /// outside the knot range). At an interior knot the piece to its right is used, at x_n the
    /// last interval; this only matters for order 2m − 1, the only discontinuous derivative
    /// (for m = 1 that is the slope, which `eval` reports the same way).
    pub fn derivative(&self, t: f64, order: usize) -> f64 {
        self.piece_derivative(self.locate(t), t, order)
    }

    /// Piece containing `t` (intervals are closed; a NaN `t` maps to the first interval).
    fn locate(&self, t: f64) -> Piece {
        let n = self.x.len();
        if t < self.x[0] {
            Piece::Left
        } else if t > self.x[n - 1] || n == 1 {
            Piece::Right
        } else {
            // Number of knots ≤ t, minus one, clamped so that t = x_n falls in the last interval.
            let k = self.x.partition_point(|&xi| xi <= t);
            Piece::Interval(k.saturating_sub(1).min(n - 2))
        }
    }

    /// Coefficients of a piece, its origin and the length that scales its variable.
    fn piece_poly(&self, piece: Piece) -> (&[f64], f64, f64) {
        let m = self.half_order;
        match piece {
            Piece::Left => (&self.left, self.x[0], 1.0),
            Piece::Right => (&self.right, self.x[self.x.len() - 1], 1.0),
            Piece::Interval(i) => (
                &self.coef[2 * m * i..2 * m * (i + 1)],
                self.x[i],
                self.x[i + 1] - self.x[i],
            ),
        }
    }

    /// Value and first two derivatives of one piece's polynomial at `t` (any `t`).
    fn piece_eval(&self, piece: Piece, t: f64) -> (f64, f64, f64) {
        let (c, origin, len) = self.piece_poly(piece);
        let s = (t - origin) / len;
        // Horner with two derivative accumulators: after the loop p = P(s), dp = P'(s),
        // ddp = P''(s)/2.
        let (p, dp, ddp) = match c.split_last() {
            None => (0.0, 0.0, 0.0),
            Some((&top, rest)) => {
                let (mut p, mut dp, mut ddp) = (top, 0.0, 0.0);
                for &ck in rest.iter().rev() {
                    ddp = ddp * s + dp;
                    dp = dp * s + p;
                    p = p * s + ck;
                }
                (p, dp, ddp)
            }
        };
        // d/dt = (1/len) d/ds.
        (p, dp / len, 2.0 * ddp / (len * len))
    }

    /// Derivative of order `order` of one piece's polynomial at `t` (any `t`).
    fn piece_derivative(&self, piece: Piece, t: f64, order: usize) -> f64 {
        let (c, origin, len) = self.piece_poly(piece);
        if order >= c.len() {
            return 0.0;
        }
        let s = (t - origin) / len;
        // P^(r)(s) = Σ_{l≥r} c_l · l!/(l−r)! · s^{l−r}, by Horner.
        let last = c.len() - 1;
        let mut acc = c[last] * falling_factorial(last, order);
        for l in (order..last).rev() {
            acc = acc * s + c[l] * falling_factorial(l, order);
        }
        acc / len.powi(order as i32)
    }
}

/// l!/(l−r)! = l (l−1) ⋯ (l−r+1) (1 for r = 0), for r ≤ l.
fn falling_factorial(l: usize, r: usize) -> f64 {
    (l + 1 - r..=l).map(|v| v as f64).product()
}

/// 1 ≤ m ≤ MAX_HALF_ORDER, and every column is valid data on the knots (`check_xy`).
fn check_half_order_and_data(m: usize, x: &[f64], ys: &[Vec<f64>]) -> Result<(), (usize, String)> {
    if m == 0 || m > MAX_HALF_ORDER {
        return Err((
            0,
            format!(
                "half order must be between 1 and {MAX_HALF_ORDER} (spline degree 1, 3, 5 or 7), got {m}"
            ),
        ));
    }
    for (c, y) in ys.iter().enumerate() {
        super::knots::check_xy(x, y, m.max(1)).map_err(|e| (c, e))?;
    }
    Ok(())
}

/// (L, u): the knot range L = x_n − x_1 and the knots u_i = (x_i − x_1)/L, which must stay
/// strictly increasing (n ≥ 2).
fn normalised_knots(x: &[f64]) -> Result<(f64, Vec<f64>), (usize, String)> {
    let n = x.len();
    let span = x[n - 1] - x[0];
    if !span.is_finite() {
        return Err((
            0,
            format!(
                "the knot range x[{}] - x[0] = {} - {} is too large to represent",
                n - 1,
                x[n - 1],
                x[0]
            ),
        ));
    }
    let u: Vec<f64> = x.iter().map(|v| (v - x[0]) / span).collect();
    if let Some(i) = (1..n).find(|&i| u[i] <= u[i - 1]) {
        return Err((
            0,
            format!(
                "knot spacing x[{i}] - x[{}] = {} is too small relative to the knot range {span}",
                i - 1,
                x[i] - x[i - 1]
            ),
        ));
    }
    Ok((span, u))
}

/// The B-spline basis of order k = 2m on the normalised knots, with the layout of the
/// unknowns of the interpolation system.
///
/// Basis: the knot sequence `t` has u_1 and u_n of multiplicity k and simple interior knots:
/// nb = n + 2m − 2 functions B_0 … B_{nb−1}; every spline of degree 2m−1 that is C^(2m−2) at
/// the interior knots is f = Σ_j a_j B_j.
///
/// Natural end conditions. Writing them as rows f^(r)(x_1) = Σ_j a_j B_j^(r)(x_1) = 0 is
/// numerically poor when the first interval is much shorter than the next ones (the
/// restrictions of B_0 … B_{2m−1} to that interval are then nearly dependent, and the
/// rows for r = m … 2m−2 agree in their leading digits). Instead, the polynomial on the
/// first interval is written in Taylor form at x_1 with the natural conditions built in,
///   p_0(u) = Σ_{r<m} c_r (u − u_1)^r + c_{2m−1} (u − u_1)^{2m−1},
/// and tied to the B-spline coefficients of the functions that are non-zero there by the
/// blossoming (Marsden) identity: for j = 0 … 2m−1,
///   a_j = Σ_r c_r σ_r(δ_{j,1}, …, δ_{j,2m−1}) / C(2m−1, r),   δ_{j,l} = t_{j+l} − u_1,
/// σ_r the elementary symmetric function. Since 0 ≤ δ ≤ 1 these weights lie in [0, 1].
/// Only j = 2m−1 involves c_{2m−1}, whose unknown is scaled as e = c_{2m−1} Π_l δ_{2m−1,l}.
/// The same at x_n with Taylor coefficients c'_r at u_n (there −1 ≤ δ ≤ 0).
///
/// Unknowns: [c_0 … c_{m−1}, e | a_0 … a_{nb−1} | c'_0 … c'_{m−1}, e'].
/// Equations, in this order (banded with half-bandwidth max(2m − 1, m + 1)):
///   2m blossom rows at x_1; f(x_i) = ỹ_i for i = 1 … n; 2m blossom rows at x_n.
/// Count: 4m + n = nb + 2(m + 1) unknowns.
struct EndBlossomBasis {
    m: usize,
    /// k = 2m, the B-spline order.
    k: usize,
    /// Number of knots.
    n: usize,
    /// Number of B-splines, n + 2m − 2.
    nb: usize,
    /// The knot sequence.
    t: Vec<f64>,
    /// First column of the a_j.
    col_a: usize,
    /// First column of the c'_r.
    col_r: usize,
    /// Number of unknowns.
    size: usize,
}

impl EndBlossomBasis {
    fn new(m: usize, u: &[f64]) -> Self {
        let n = u.len();
        let k = 2 * m;
        let nb = n + k - 2;
        let mut t = Vec::with_capacity(nb + k);
        t.extend(std::iter::repeat_n(u[0], k - 1));
        t.extend_from_slice(u);
        t.extend(std::iter::repeat_n(u[n - 1], k - 1));
        let col_a = m + 1;
        let col_r = col_a + nb;
        let size = col_r + m + 1;
        EndBlossomBasis {
            m,
            k,
            n,
            nb,
            t,
            col_a,
            col_r,
            size,
        }
    }

    /// Span of interval i (u_i ≤ u ≤ u_{i+1}) in `t`: t[k−1+i] = u_i; the k B-splines that are
    /// non-zero there are B_i … B_{i+k−1}.
    fn span_of(&self, i: usize) -> usize {
        self.k - 1 + i
    }

    /// σ_r(δ_{j,1..k−1}) / C(k−1, r), r < m, δ_{j,l} = t_{j+l} − origin, by the recurrence
    /// σ_r ← σ_r + δ σ_{r−1}.
    fn blossom_weights(&self, j: usize, origin: f64) -> [f64; MAX_HALF_ORDER] {
        let (m, k) = (self.m, self.k);
        let mut sigma = [0.0; MAX_HALF_ORDER];
        sigma[0] = 1.0;
        for l in 1..k {
            let delta = self.t[j + l] - origin;
            for r in (1..m).rev() {
                sigma[r] += delta * sigma[r - 1];
            }
        }
        for (r, v) in sigma.iter_mut().enumerate().take(m) {
            *v /= binomial(k - 1, r);
        }
        sigma
    }

    /// The banded matrix: 2m blossom rows at x_1, n interpolation rows, 2m blossom rows at x_n.
    #[allow(clippy::needless_range_loop)] // index arithmetic mirrors the equations
    fn interpolation_system(&self, u: &[f64]) -> BandLu {
        let (m, k, n, nb) = (self.m, self.k, self.n, self.nb);
        let (col_a, col_r) = (self.col_a, self.col_r);
        let mut sys = BandLu::new(self.size, (2 * m - 1).max(m + 1));
        // a_j − Σ_r w_{j,r} c_r = 0 (and − e for j = 2m−1)
        for j in 0..k {
            let w = self.blossom_weights(j, u[0]);
            sys.set(j, col_a + j, 1.0);
            for r in 0..m {
                sys.set(j, r, -w[r]);
            }
        }
        sys.set(k - 1, m, -1.0);
        // f(u_1) = a_0
        sys.set(k, col_a, 1.0);
        let mut ders = [[0.0; 2 * MAX_HALF_ORDER]; 2 * MAX_HALF_ORDER];
        for i in 1..n - 1 {
            basis_derivatives(&self.t, k, self.span_of(i), u[i], 0, &mut ders);
            // B_{i+k−1} starts at x_i and vanishes there.
            for q in 0..k - 1 {
                sys.set(k + i, col_a + i + q, ders[0][q]);
            }
        }
        // f(u_n) = a_{nb−1}
        sys.set(k + n - 1, col_a + nb - 1, 1.0);
        for jj in 0..k {
            let (row, j) = (k + n + jj, nb - k + jj);
            let w = self.blossom_weights(j, u[n - 1]);
            sys.set(row, col_a + j, 1.0);
            for r in 0..m {
                sys.set(row, col_r + r, -w[r]);
            }
        }
        sys.set(k + n, col_r + m, -1.0);
        sys
    }

    /// Per column, the right-hand side: ỹ_i = y_i / Y in the interpolation rows, 0 elsewhere.
    fn right_hand_sides(&self, ys: &[Vec<f64>], y_scales: &[f64]) -> Vec<Vec<f64>> {
        let mut rhs: Vec<Vec<f64>> = vec![vec![0.0; self.size]; ys.len()];
        for ((b, y), scale) in rhs.iter_mut().zip(ys).zip(y_scales) {
            for i in 0..self.n {
                b[self.k + i] = y[i] / scale;
            }
        }
        rhs
    }

    /// The B-spline derivatives at each interior knot, shared by the columns.
    fn interior_knot_derivatives(&self, u: &[f64]) -> Vec<KnotDerivatives> {
        let n = self.n;
        let mut knot_ders = vec![[[0.0; 2 * MAX_HALF_ORDER]; 2 * MAX_HALF_ORDER]; n];
        for i in 1..n.saturating_sub(2) {
            basis_derivatives(
                &self.t,
                self.k,
                self.span_of(i),
                u[i],
                self.k - 1,
                &mut knot_ders[i],
            );
        }
        knot_ders
    }

    /// Local polynomials p_i(s) = Σ_r coef_{i,r} s^r, s = (u − u_i)/h_i ∈ [0, 1], in data
    /// units, from one solution `z` with data scale Y = `y_scale`.
    fn interval_coefficients(
        &self,
        u: &[f64],
        knot_ders: &[KnotDerivatives],
        z: &[f64],
        y_scale: f64,
    ) -> Vec<f64> {
        let (k, n) = (self.k, self.n);
        let a = &z[self.col_a..self.col_r];
        let mut coef = vec![0.0; (n - 1) * k];
        // Interior intervals: coef_{i,r} = Y f̃^(r)(u_i⁺) h_i^r / r!, with
        // f̃^(r)(u_i⁺) = Σ_q a_{i+q} B_{i+q}^(r)(u_i).
        for i in 1..n.saturating_sub(2) {
            let hi = u[i + 1] - u[i];
            let ders = &knot_ders[i];
            let mut factor = y_scale; // Y h^r / r!
            for r in 0..k {
                let fr: f64 = (0..k).map(|q| a[i + q] * ders[r][q]).sum();
                coef[i * k + r] = fr * factor;
                factor *= hi / (r + 1) as f64;
            }
        }
        // The last interval is done before the first, which wins when n = 2.
        self.last_interval_coefficients(u, z, y_scale, &mut coef[(n - 2) * k..(n - 1) * k]);
        self.first_interval_coefficients(u, z, y_scale, &mut coef[..k]);
        coef
    }

    /// Last interval, from the Taylor form at u_n: p(u) = Σ_q d_q σ^q with σ = (u − u_n)/h =
    /// s − 1 and d_q = c'_q h^q, so coef_r = Σ_{q≥r} d_q C(q, r) (−1)^(q−r).
    /// d_{2m−1} = e' h^{2m−1}/Π_l δ'_l with δ'_{2m−1} = −h, i.e. −e' Π_{l<2m−1} (h/δ'_l).
    #[allow(clippy::needless_range_loop)] // index arithmetic mirrors the equations
    fn last_interval_coefficients(&self, u: &[f64], z: &[f64], y_scale: f64, coef: &mut [f64]) {
        let (m, k, n, col_r) = (self.m, self.k, self.n, self.col_r);
        let h = u[n - 1] - u[n - 2];
        let mut d = [0.0; 2 * MAX_HALF_ORDER];
        let mut hp = 1.0;
        for q in 0..m {
            d[q] = z[col_r + q] * hp;
            hp *= h;
        }
        let j = self.nb - k;
        d[k - 1] = -z[col_r + m]
            * (1..k - 1)
                .map(|l| h / (self.t[j + l] - u[n - 1]))
                .product::<f64>();
        for r in 0..k {
            let cr: f64 = (r..k)
                .map(|q| d[q] * binomial(q, r) * if (q - r) % 2 == 0 { 1.0 } else { -1.0 })
                .sum();
            coef[r] = cr * y_scale;
        }
    }

    /// First interval: coef_r = c_r h^r (r < m), 0 for m ≤ r ≤ 2m−2 (natural conditions,
    /// exactly), and c_{2m−1} h^{2m−1} = e Π_{l≥2} (h/δ_l) since δ_1 = h.
    fn first_interval_coefficients(&self, u: &[f64], z: &[f64], y_scale: f64, coef: &mut [f64]) {
        let (m, k) = (self.m, self.k);
        let h = u[1] - u[0];
        let mut hp = 1.0;
        coef.fill(0.0);
        for r in 0..m {
            coef[r] = z[r] * hp * y_scale;
            hp *= h;
        }
        coef[k - 1] = z[m]
            * (2..k)
                .map(|l| h / (self.t[k - 1 + l] - u[0]))
                .product::<f64>()
            * y_scale;
    }
}

/// B_j^(r) at one knot: [r][q] for the k B-splines non-zero on the interval it starts.
type KnotDerivatives = [[f64; 2 * MAX_HALF_ORDER]; 2 * MAX_HALF_ORDER];

/// Binomial coefficient C(n, r) as a float, r ≤ n.
fn binomial(n: usize, r: usize) -> f64 {
    falling_factorial(n, r) / falling_factorial(r, r)
}

/// Values and derivatives of the B-splines of order `k` (degree k − 1) on knots `t` that are
/// non-zero on the span t[mu] ≤ u ≤ t[mu+1] (t[mu] < t[mu+1], k − 1 ≤ mu, mu + k ≤ t.len()):
/// `out[r][q]` = B_{mu−k+1+q}^(r)(u) for r = 0..=nd (nd < k), q = 0..k−1. The polynomial pieces
/// of that span are used, so u may be either end of the span.
#[allow(clippy::needless_range_loop)]
fn basis_derivatives(
    t: &[f64],
    k: usize,
    mu: usize,
    u: f64,
    nd: usize,
    out: &mut [[f64; 2 * MAX_HALF_ORDER]; 2 * MAX_HALF_ORDER],
) {
    // vals[o−1][p] = B_{mu−o+1+p, o}(u), the order-o B-splines non-zero on the span, by the
    // Cox–de Boor recurrence
    //   B_{j,o+1}(u) = (u − t_j)/(t_{j+o} − t_j) B_{j,o}(u) + (t_{j+o+1} − u)/(t_{j+o+1} − t_{j+1}) B_{j+1,o}(u).
    let mut vals = [[0.0; 2 * MAX_HALF_ORDER]; 2 * MAX_HALF_ORDER];
    vals[0][0] = 1.0;
    for o in 1..k {
        let mut saved = 0.0;
        for p in 0..o {
            let right = t[mu + 1 + p] - u;
            let left = u - t[mu + 1 + p - o];
            let term = vals[o - 1][p] / (right + left);
            vals[o][p] = saved + right * term;
            saved = left * term;
        }
        vals[o][o] = saved;
    }
    // r-th derivative of B_{j,k}: write it as Σ_i α_i B_{i,k−r} by applying r times the rule
    //   d/du Σ_i α_i B_{i,o} = Σ_i (o − 1)(α_i − α_{i−1})/(t_{i+o−1} − t_i) B_{i,o−1},
    // starting from the unit vector α = e_j.
    for r in 0..=nd.min(k - 1) {
        let base = k - r;
        for q in 0..k {
            let mut alpha = [0.0; 2 * MAX_HALF_ORDER];
            alpha[q] = 1.0;
            for o in (base + 1..=k).rev() {
                // Local index p' (order o − 1) ↔ i = mu − o + 2 + p'.
                for p in 0..o - 1 {
                    alpha[p] = (o - 1) as f64 * (alpha[p + 1] - alpha[p])
                        / (t[mu + 1 + p] - t[mu + 2 + p - o]);
                }
            }
            out[r][q] = (0..base).map(|p| alpha[p] * vals[base - 1][p]).sum();
        }
    }
}

/// Square banded matrix with equal lower and upper half-bandwidth, solved by Gaussian
/// elimination with partial pivoting (rows equilibrated first).
struct BandLu {
    n: usize,
    /// Half-bandwidth b of the original matrix; row r is stored over columns
    /// r − b ..= r + 2b (room for the fill-in caused by row interchanges).
    band: usize,
    width: usize,
    data: Vec<f64>,
}

impl BandLu {
    fn new(n: usize, band: usize) -> Self {
        let width = 3 * band + 1;
        Self {
            n,
            band,
            width,
            data: vec![0.0; n * width],
        }
    }

    /// Storage index of (r, c); requires r − band ≤ c ≤ r + 2·band.
    fn idx(&self, r: usize, c: usize) -> usize {
        debug_assert!(c + self.band >= r && c <= r + 2 * self.band);
        r * self.width + (c + self.band - r)
    }

    fn get(&self, r: usize, c: usize) -> f64 {
        self.data[self.idx(r, c)]
    }

    fn set(&mut self, r: usize, c: usize, v: f64) {
        let i = self.idx(r, c);
        self.data[i] = v;
    }

    /// Solves A x = b for every b of `bs` (the same operations on each as [`BandLu::solve`]);
    /// an `Err` names the first b whose solution overflowed.
    #[allow(clippy::needless_range_loop)]
    fn solve_many(mut self, mut bs: Vec<Vec<f64>>) -> Result<Vec<Vec<f64>>, (usize, String)> {
        let (n, bw) = (self.n, self.band);
        // Row equilibration: divide each row (and b) by its largest magnitude.
        for r in 0..n {
            let lo = r.saturating_sub(bw);
            let hi = (r + bw).min(n - 1);
            let scale = (lo..=hi).fold(0.0_f64, |acc, c| acc.max(self.get(r, c).abs()));
            if !(scale > 0.0 && scale.is_finite()) {
                return Err((
                    0,
                    "natural spline system is singular or overflowed (knot spacing too extreme)"
                        .to_string(),
                ));
            }
            for c in lo..=hi {
                let v = self.get(r, c) / scale;
                self.set(r, c, v);
            }
            for b in bs.iter_mut() {
                b[r] /= scale;
            }
        }
        // Elimination. Invariant: before step c, rows ≥ c have no entries left of column c, and
        // row r ≥ c has entries only up to column r + 2·bw.
        for c in 0..n {
            let last_row = (c + bw).min(n - 1);
            let last_col = (c + 2 * bw).min(n - 1);
            let mut p = c;
            for r in c + 1..=last_row {
                if self.get(r, c).abs() > self.get(p, c).abs() {
                    p = r;
                }
            }
            let pivot = self.get(p, c);
            if !(pivot != 0.0 && pivot.is_finite()) {
                return Err((
                    0,
                    "natural spline system is numerically singular (knot spacing too extreme)"
                        .to_string(),
                ));
            }
            if p != c {
                for col in c..=last_col {
                    let (ip, ic) = (self.idx(p, col), self.idx(c, col));
                    self.data.swap(ip, ic);
                }
                for b in bs.iter_mut() {
                    b.swap(p, c);
                }
            }
            for r in c + 1..=last_row {
                let l = self.get(r, c) / pivot;
                if l != 0.0 {
                    for col in c..=last_col {
                        let v = self.get(r, col) - l * self.get(c, col);
                        self.set(r, col, v);
                    }
                    for b in bs.iter_mut() {
                        b[r] -= l * b[c];
                    }
                }
            }
        }
        // Back substitution with the upper triangle (bandwidth 2·bw).
        for (i, b) in bs.iter_mut().enumerate() {
            for r in (0..n).rev() {
                let mut sum = b[r];
                for col in r + 1..=(r + 2 * bw).min(n - 1) {
                    sum -= self.get(r, col) * b[col];
                }
                b[r] = sum / self.get(r, r);
            }
            if !b.iter().all(|v| v.is_finite()) {
                return Err((
                    i,
                    "natural spline computation overflowed (knot spacing too extreme)".to_string(),
                ));
            }
        }
        Ok(bs)
    }
}

#[cfg(test)]
mod tests;
