//! Segmented quintic Bézier curves: the `SmoothSegmentedFunction` of Millard et al. (2013),
//! "Flexing computational muscle: modeling and simulation of musculotendon dynamics",
//! J. Biomech. Eng. 135(2), as OpenSim builds them (`SegmentedQuinticBezierToolkit`,
//! `SmoothSegmentedFunction`).
//!
//! A curve is a chain of "corner" sections. Each section is a pair of quintic Bézier
//! polynomials x(u), y(u), u ∈ [0, 1], whose control points are placed on the two tangent
//! lines of the corner, so that value and slope match at every joint (C1; the second
//! derivative is continuous too wherever both neighbouring sections have zero curvature at
//! the joint, which is the case at line-tangent ends). Outside [x0, x1] the curve continues
//! as the straight lines y0 + dydx0·(x − x0) and y1 + dydx1·(x − x1).
//!
//! Evaluating y(x) needs u(x): x(u) is monotone on each section, and u is found by a
//! bracketed Newton iteration started from a tabulated guess (OpenSim starts from a spline
//! fit of u(x) and iterates to |x(u) − x| ≤ 100·ε; the root is the same).

/// Value, slope and curvature of a normalised curve at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    pub value: f64,
    /// dy/dx.
    pub slope: f64,
    /// d²y/dx².
    pub curvature: f64,
}

impl CurvePoint {
    pub const fn new(value: f64, slope: f64, curvature: f64) -> Self {
        CurvePoint {
            value,
            slope,
            curvature,
        }
    }
}

/// OpenSim's mapping of a user "curviness" in [0, 1] to the control-point fraction
/// c = 0.1 + 0.8·curviness (`SmoothSegmentedFunctionFactory::scaleCurviness`).
pub fn scale_curviness(curviness: f64) -> f64 {
    0.1 + 0.8 * curviness
}

/// Control points (x and y, 6 each) of the quintic Bézier corner from (x0, y0) with slope
/// dydx0 to (x1, y1) with slope dydx1, with control-point fraction `c` (already scaled).
///
/// The two tangent lines meet at the corner point P_C. The inner control points sit at the
/// fraction c along each end point's segment towards P_C, doubled:
/// P = [P0, P0 + c(P_C − P0), same, P1 + c(P_C − P1), same, P1].
/// When the two slopes are equal (within √ε) P_C is taken halfway in x. The three points
/// must form a "C" (the chord P0P1 longer than either side to P_C), otherwise the corner
/// would be S-shaped and is rejected, as OpenSim does.
pub fn corner_control_points(
    x0: f64,
    y0: f64,
    dydx0: f64,
    x1: f64,
    y1: f64,
    dydx1: f64,
    c: f64,
) -> Result<([f64; 6], [f64; 6]), String> {
    if !(0.0..=1.0).contains(&c) {
        return Err(format!("corner curviness fraction {c} is outside [0, 1]"));
    }
    // Intersection of y = y0 + dydx0 (x − x0) and y = y1 + dydx1 (x − x1).
    let xc = if (dydx0 - dydx1).abs() > f64::EPSILON.sqrt() {
        (y1 - y0 - x1 * dydx1 + x0 * dydx0) / (dydx0 - dydx1)
    } else {
        0.5 * (x0 + x1)
    };
    let yc = (xc - x1) * dydx1 + y1;
    let side0 = (xc - x0).powi(2) + (yc - y0).powi(2);
    let side1 = (xc - x1).powi(2) + (yc - y1).powi(2);
    let chord = (x1 - x0).powi(2) + (y1 - y0).powi(2);
    if !(chord > side0 && chord > side1) {
        return Err(format!(
            "the tangent lines at ({x0}, {y0}) slope {dydx0} and ({x1}, {y1}) slope {dydx1} \
             do not form a C-shaped corner"
        ));
    }
    let x0m = x0 + c * (xc - x0);
    let y0m = y0 + c * (yc - y0);
    let x1m = x1 + c * (xc - x1);
    let y1m = y1 + c * (yc - y1);
    Ok(([x0, x0m, x0m, x1m, x1m, x1], [y0, y0m, y0m, y1m, y1m, y1]))
}

/// Number of intervals of the tabulated x(u) used for the starting guess of u(x).
const GUESS_INTERVALS: usize = 16;

/// One quintic Bézier section, stored in power basis for evaluation.
#[derive(Clone, Debug)]
struct Section {
    /// x(u) = Σ xc[k] u^k.
    xc: [f64; 6],
    /// y(u) = Σ yc[k] u^k.
    yc: [f64; 6],
    /// x at u = i / GUESS_INTERVALS.
    x_table: [f64; GUESS_INTERVALS + 1],
    /// dx/du at the same points.
    dx_table: [f64; GUESS_INTERVALS + 1],
    x_start: f64,
    x_end: f64,
}

/// Bernstein (Bézier) to power basis: a_k = C(5,k) Σ_{i≤k} (−1)^{k−i} C(k,i) p_i.
fn power_basis(p: &[f64; 6]) -> [f64; 6] {
    const BINOM: [[f64; 6]; 6] = [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 2.0, 1.0, 0.0, 0.0, 0.0],
        [1.0, 3.0, 3.0, 1.0, 0.0, 0.0],
        [1.0, 4.0, 6.0, 4.0, 1.0, 0.0],
        [1.0, 5.0, 10.0, 10.0, 5.0, 1.0],
    ];
    let mut a = [0.0; 6];
    for (k, ak) in a.iter_mut().enumerate() {
        let mut s = 0.0;
        for (i, pi) in p.iter().enumerate().take(k + 1) {
            let sign = if (k - i) % 2 == 0 { 1.0 } else { -1.0 };
            s += sign * BINOM[k][i] * pi;
        }
        *ak = BINOM[5][k] * s;
    }
    a
}

/// (p(u), p'(u), p''(u)) of a quintic in power basis, by Horner's rule.
#[inline]
fn poly3(a: &[f64; 6], u: f64) -> (f64, f64, f64) {
    let p = ((((a[5] * u + a[4]) * u + a[3]) * u + a[2]) * u + a[1]) * u + a[0];
    let dp = (((5.0 * a[5] * u + 4.0 * a[4]) * u + 3.0 * a[3]) * u + 2.0 * a[2]) * u + a[1];
    let ddp = ((20.0 * a[5] * u + 12.0 * a[4]) * u + 6.0 * a[3]) * u + 2.0 * a[2];
    (p, dp, ddp)
}

/// (p(u), p'(u)).
#[inline]
fn poly2(a: &[f64; 6], u: f64) -> (f64, f64) {
    let p = ((((a[5] * u + a[4]) * u + a[3]) * u + a[2]) * u + a[1]) * u + a[0];
    let dp = (((5.0 * a[5] * u + 4.0 * a[4]) * u + 3.0 * a[3]) * u + 2.0 * a[2]) * u + a[1];
    (p, dp)
}

impl Section {
    fn new(px: &[f64; 6], py: &[f64; 6]) -> Self {
        let xc = power_basis(px);
        let yc = power_basis(py);
        let mut x_table = [0.0; GUESS_INTERVALS + 1];
        let mut dx_table = [0.0; GUESS_INTERVALS + 1];
        for i in 0..=GUESS_INTERVALS {
            let (x, dx) = poly2(&xc, i as f64 / GUESS_INTERVALS as f64);
            x_table[i] = x;
            dx_table[i] = dx;
        }
        // The end points are the control points exactly.
        x_table[0] = px[0];
        x_table[GUESS_INTERVALS] = px[5];
        Section {
            xc,
            yc,
            x_table,
            dx_table,
            x_start: px[0],
            x_end: px[5],
        }
    }

    /// The u ∈ [0, 1] with x(u) = x, for x in [x_start, x_end].
    fn solve_u(&self, x: f64) -> f64 {
        let t = &self.x_table;
        // Interval of the table that holds x (x(u) is non-decreasing).
        let mut lo = 0usize;
        let mut hi = GUESS_INTERVALS;
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if t[mid] <= x {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let h = 1.0 / GUESS_INTERVALS as f64;
        let mut u_lo = lo as f64 * h;
        let mut u_hi = hi as f64 * h;
        let dx = t[hi] - t[lo];
        let (d_lo, d_hi) = (self.dx_table[lo], self.dx_table[hi]);
        // Starting guess: the cubic Hermite interpolant of the inverse u(x) on the interval,
        // from the end values and slopes du/dx = 1/x'(u).
        let mut u = if dx > 0.0 && d_lo > 0.0 && d_hi > 0.0 {
            let s = ((x - t[lo]) / dx).clamp(0.0, 1.0);
            let (s2, s3) = (s * s, s * s * s);
            let guess = (2.0 * s3 - 3.0 * s2 + 1.0) * u_lo
                + (s3 - 2.0 * s2 + s) * dx / d_lo
                + (3.0 * s2 - 2.0 * s3) * u_hi
                + (s3 - s2) * dx / d_hi;
            guess.clamp(u_lo, u_hi)
        } else if dx > 0.0 {
            u_lo + h * ((x - t[lo]) / dx).clamp(0.0, 1.0)
        } else {
            0.5 * (u_lo + u_hi)
        };
        let tol = 4.0 * f64::EPSILON * (self.x_start.abs().max(self.x_end.abs())).max(1.0);
        for _ in 0..40 {
            let (xu, dxu) = poly2(&self.xc, u);
            let f = xu - x;
            if f.abs() <= tol {
                break;
            }
            if f > 0.0 {
                u_hi = u;
            } else {
                u_lo = u;
            }
            let newton = if dxu > 0.0 { u - f / dxu } else { f64::NAN };
            u = if newton > u_lo && newton < u_hi {
                newton
            } else {
                0.5 * (u_lo + u_hi)
            };
            if u_hi - u_lo <= f64::EPSILON {
                break;
            }
        }
        u
    }

    /// (y, dy/dx, d²y/dx²) at u.
    #[inline]
    fn at(&self, u: f64) -> CurvePoint {
        let (_, dx, ddx) = poly3(&self.xc, u);
        let (y, dy, ddy) = poly3(&self.yc, u);
        // dy/dx = y'/x';  d²y/dx² = (y'' x' − y' x'') / x'³.
        let slope = dy / dx;
        let curvature = (ddy * dx - dy * ddx) / (dx * dx * dx);
        CurvePoint::new(y, slope, curvature)
    }
}

/// A C1 curve made of quintic Bézier corner sections, continued linearly outside its domain
/// (OpenSim's `SmoothSegmentedFunction`).
#[derive(Clone, Debug)]
pub struct SmoothSegmentedFunction {
    sections: Vec<Section>,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    dydx0: f64,
    dydx1: f64,
}

impl SmoothSegmentedFunction {
    /// A curve from its sections' control points, with the linear extrapolation
    /// y0 + dydx0 (x − x0) left of x0 and y1 + dydx1 (x − x1) right of x1.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ctrl_x: &[[f64; 6]],
        ctrl_y: &[[f64; 6]],
        x0: f64,
        x1: f64,
        y0: f64,
        y1: f64,
        dydx0: f64,
        dydx1: f64,
    ) -> Self {
        assert_eq!(ctrl_x.len(), ctrl_y.len());
        let sections = ctrl_x
            .iter()
            .zip(ctrl_y)
            .map(|(px, py)| Section::new(px, py))
            .collect();
        SmoothSegmentedFunction {
            sections,
            x0,
            x1,
            y0,
            y1,
            dydx0,
            dydx1,
        }
    }

    /// The domain [x0, x1] on which the curve is Bézier (linear outside).
    pub fn domain(&self) -> (f64, f64) {
        (self.x0, self.x1)
    }

    /// Value, slope and curvature at x.
    pub fn eval(&self, x: f64) -> CurvePoint {
        if x < self.x0 {
            return CurvePoint::new(self.y0 + self.dydx0 * (x - self.x0), self.dydx0, 0.0);
        }
        if x > self.x1 {
            return CurvePoint::new(self.y1 + self.dydx1 * (x - self.x1), self.dydx1, 0.0);
        }
        if x.is_nan() {
            return CurvePoint::new(f64::NAN, f64::NAN, f64::NAN);
        }
        // The section with x_start ≤ x < x_end (the last one also owns its end point).
        let last = self.sections.len() - 1;
        let idx = self
            .sections
            .iter()
            .position(|s| x >= s.x_start && x < s.x_end)
            .unwrap_or(last);
        let s = &self.sections[idx];
        s.at(s.solve_u(x))
    }

    /// Value at x.
    #[inline]
    pub fn value(&self, x: f64) -> f64 {
        self.eval(x).value
    }
}
