//! Closest point on an ellipsoid x²/a² + y²/b² + z²/c² = 1 (or on one of its coordinate-plane
//! sections) to a point, as OpenSim's `WrapEllipsoid::findClosestPoint` and
//! `closestPointToEllipse` define it (Eberly, Graphics Gems IV).
//!
//! For a point x whose coordinates are all non-zero, the closest point is
//! c_j = a_j² x_j / (a_j² + t), with t the largest root of G(t) = Σ_j (a_j x_j / (a_j² + t))² − 1
//! (t > −min a_j², where G decreases from +∞ to −1). Points with a coordinate within
//! OpenSim's round-off (2e-13 in its units, coordinates scaled by 3/(a + b + c)) of zero are
//! reduced, as OpenSim does, to the section in that coordinate plane (the coordinate is
//! kept), with its closed-form cases on the section's axes.
//!
//! The root is found on `f64` by Newton's method on K(t) = 1/√(G(t) + 1) − 1 (linear in t
//! for a sphere), safeguarded by bisection in a bracket, at most `MAX_ITER` steps; from a
//! close warm start, plain Newton on G. The result is lifted to a dual scalar by one Newton
//! step on `T`.

use super::real::{Base, D1};
use super::real::{Real, V3};
use crate::spatial::{Mat3, Vec3};

const MAX_ITER: usize = 64;
/// Newton steps tried from a warm start before falling back to the bracketed solve.
const WARM_ITER: usize = 3;
/// OpenSim's `ROUNDOFF_ERROR`, in its scaled units.
const ROUNDOFF: f64 = 2e-13;

/// An origin-centred, axis-aligned ellipsoid with its derived constants.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ellipsoid {
    pub radii: [f64; 3],
    pub a2: [f64; 3],
    /// The metric diag(1/a²): x is on the surface when Σ x_j² / a_j² = 1.
    pub inv_a2: [f64; 3],
    /// |x_j| at or below this counts as zero (OpenSim's round-off in its scaled units).
    pub zero_tol: f64,
}

impl Ellipsoid {
    pub fn new(radii: [f64; 3]) -> Self {
        let a2 = radii.map(|a| a * a);
        Ellipsoid {
            radii,
            a2,
            inv_a2: a2.map(|v| 1.0 / v),
            zero_tol: ROUNDOFF * (radii[0] + radii[1] + radii[2]) / 3.0,
        }
    }

    /// Σ x_j² / a_j² − 1: negative inside, zero on the surface.
    pub fn level(&self, x: &Vec3) -> f64 {
        (0..3).map(|j| x[j] * x[j] * self.inv_a2[j]).sum::<f64>() - 1.0
    }
}

/// The two in-plane axes of the section x_i = 0, in OpenSim's order (yz, zx, xy).
fn section_axes(i: usize) -> (usize, usize) {
    match i {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    }
}

/// OpenSim's choice when some coordinates are ~0: the section (among those planes) whose
/// two radii sum least.
pub(crate) fn auto_plane(e: &Ellipsoid, x: &Vec3) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for i in 0..3 {
        if x[i].abs() <= e.zero_tol {
            let (j, k) = section_axes(i);
            let sum = e.radii[j] + e.radii[k];
            if best.is_none_or(|(_, b)| sum < b) {
                best = Some((i, sum));
            }
        }
    }
    best.map(|(i, _)| i)
}

/// Closest point to `x` on the ellipsoid (`plane == None`, OpenSim's automatic reduction
/// applies) or on its section x_i = 0 with x_i kept (`plane == Some(i)`). `guess` is a
/// starting root for the general case (e.g. from a neighbouring point); the root is
/// returned when the general 3-D case was solved.
pub(crate) fn closest<T: Real>(
    e: &Ellipsoid,
    x: &V3<T>,
    plane: Option<usize>,
    guess: Option<f64>,
) -> (V3<T>, Option<f64>) {
    let xv = x.val();
    match plane.or_else(|| auto_plane(e, &xv)) {
        Some(i) => {
            let (j, k) = section_axes(i);
            let (cj, ck) = closest_on_ellipse(e, j, k, x.at(j), x.at(k));
            let mut c = *x;
            c.set(j, cj);
            c.set(k, ck);
            (c, None)
        }
        None => {
            let t = solve_root(&e.a2, &[xv.x, xv.y, xv.z], &[0, 1, 2], guess);
            let xs = [x.x, x.y, x.z];
            let tt = lift_root(&e.a2, &xs, &[0, 1, 2], t);
            let c = V3::new(
                x.x * e.a2[0] / (tt + e.a2[0]),
                x.y * e.a2[1] / (tt + e.a2[1]),
                x.z * e.a2[2] / (tt + e.a2[2]),
            );
            (c, Some(t))
        }
    }
}

/// The general 3-D case on `f64` with the Jacobian of the unit vector from x to its
/// closest point, or `None` when OpenSim's reduction to a section applies (then use
/// `closest`). Returns (u, root t, ∂u/∂x).
///
/// c_j = w_j x_j with w_j = a_j²/(a_j² + t); the implicit derivative of the root is
/// ∂t/∂x_k = −(∂G/∂x_k)/G'(t), so ∂c/∂x − I = diag(w − 1) + (∂c/∂t)(∂t/∂x)ᵀ; and for
/// u = (c − x)/|c − x|, ∂u/∂x = (I − u uᵀ)(∂c/∂x − I)/|c − x|.
pub(crate) fn unit_to_closest_with_jacobian(
    e: &Ellipsoid,
    x: &Vec3,
    guess: Option<f64>,
) -> Option<(Vec3, f64, Mat3)> {
    if auto_plane(e, x).is_some() {
        return None;
    }
    let t = solve_root(&e.a2, &[x.x, x.y, x.z], &[0, 1, 2], guess);
    let q = Vec3::new(
        1.0 / (e.a2[0] + t),
        1.0 / (e.a2[1] + t),
        1.0 / (e.a2[2] + t),
    );
    let w = Vec3::from(e.a2).component_mul(&q);
    let v = (w - Vec3::repeat(1.0)).component_mul(x);
    let len = v.norm();
    if len == 0.0 {
        return Some((Vec3::zeros(), t, Mat3::zeros()));
    }
    let u = v / len;
    // ∂c_j/∂t = −a_j² x_j q_j² and ∂G/∂x_k = 2 a_k² x_k q_k², G'(t) = −2 Σ a_j² x_j² q_j³.
    let dc_dt = -w.component_mul(x).component_mul(&q);
    let dg_dx = w.component_mul(x).component_mul(&q) * 2.0;
    let dg_dt = -2.0
        * w.component_mul(x)
            .component_mul(x)
            .component_mul(&q)
            .component_mul(&q)
            .sum();
    let dt_dx = if dg_dt != 0.0 && dg_dt.is_finite() {
        -dg_dx / dg_dt
    } else {
        Vec3::zeros()
    };
    // (I − u uᵀ)(D + a bᵀ) with D = diag(w − 1), a = ∂c/∂t, b = ∂t/∂x.
    let d = w - Vec3::repeat(1.0);
    let ua = u.dot(&dc_dt);
    let mut jac = Mat3::from_diagonal(&d) + dc_dt * dt_dx.transpose();
    jac -= u * (d.component_mul(&u) + dt_dx * ua).transpose();
    Some((u, t, jac / len))
}

/// [`unit_to_closest_with_jacobian`] with the rates of u and of ∂u/∂x as x moves with ẋ:
/// (u, root t, ∂u/∂x, d/dε ∂u/∂x (x + εẋ)), by the same closed forms on [`D1`] (the root's
/// rate ṫ = −(∂G/∂x·ẋ)/G′(t) from one Newton step on `D1`). For the second-order fan.
pub(crate) fn unit_to_closest_with_jacobian_rate(
    e: &Ellipsoid,
    x: &Vec3,
    xdot: &Vec3,
    guess: Option<f64>,
) -> Option<(Vec3, f64, Mat3, Mat3)> {
    if auto_plane(e, x).is_some() {
        return None;
    }
    let t = solve_root(&e.a2, &[x.x, x.y, x.z], &[0, 1, 2], guess);
    let xs: [D1; 3] = std::array::from_fn(|j| D1::new(x[j], xdot[j]));
    let one = D1::cst(1.0);
    // the root on D1: one Newton step on G(t; x) = Σ a_j² x_j² q_j² − 1 from the f64 root
    let mut g = D1::cst(-1.0);
    let mut gt = 0.0;
    for j in 0..3 {
        let q = 1.0 / (e.a2[j] + t);
        let ax = xs[j] * (e.a2[j].sqrt() * q);
        g = g + ax * ax;
        gt -= 2.0 * e.a2[j] * x[j] * x[j] * q * q * q;
    }
    let tt = if gt != 0.0 && gt.is_finite() {
        D1::new(t, -g.d / gt)
    } else {
        D1::cst(t)
    };
    let q: [D1; 3] = std::array::from_fn(|j| one / (tt.plus(e.a2[j])));
    let w: [D1; 3] = std::array::from_fn(|j| q[j] * e.a2[j]);
    let v: [D1; 3] = std::array::from_fn(|j| (w[j].plus(-1.0)) * xs[j]);
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len.v == 0.0 {
        return Some((Vec3::zeros(), t, Mat3::zeros(), Mat3::zeros()));
    }
    let u: [D1; 3] = std::array::from_fn(|j| v[j] / len);
    let dc_dt: [D1; 3] = std::array::from_fn(|j| -(w[j] * xs[j] * q[j]));
    let dg_dx: [D1; 3] = std::array::from_fn(|j| w[j] * xs[j] * q[j] * 2.0);
    let dg_dt = -((0..3).fold(D1::cst(0.0), |s, j| s + w[j] * xs[j] * xs[j] * q[j] * q[j]) * 2.0);
    let dt_dx: [D1; 3] = if dg_dt.v != 0.0 && dg_dt.v.is_finite() {
        std::array::from_fn(|j| -(dg_dx[j] / dg_dt))
    } else {
        [D1::cst(0.0); 3]
    };
    let d: [D1; 3] = std::array::from_fn(|j| w[j].plus(-1.0));
    let ua = (0..3).fold(D1::cst(0.0), |s, j| s + u[j] * dc_dt[j]);
    let mut jac = Mat3::zeros();
    let mut jac_rate = Mat3::zeros();
    for r in 0..3 {
        for c in 0..3 {
            let diag = if r == c { d[r] } else { D1::cst(0.0) };
            let entry = (diag + dc_dt[r] * dt_dx[c] - u[r] * (d[c] * u[c] + dt_dx[c] * ua)) / len;
            jac[(r, c)] = entry.v;
            jac_rate[(r, c)] = entry.d;
        }
    }
    Some((Vec3::new(u[0].v, u[1].v, u[2].v), t, jac, jac_rate))
}

/// Closest point on the ellipse u²/A² + v²/B² = 1 (A = radii[j], B = radii[k]) to (u, v),
/// with OpenSim's closed forms for points on the axes (the positive branch where there are
/// two closest points).
fn closest_on_ellipse<T: Real>(e: &Ellipsoid, j: usize, k: usize, u: T, v: T) -> (T, T) {
    let (a, b) = (e.radii[j], e.radii[k]);
    let (uv, vv) = (u.val(), v.val());
    let near_u = uv.abs() <= e.zero_tol;
    let near_v = vv.abs() <= e.zero_tol;
    let pm = |cond: bool, r: f64| T::cst(if cond { r } else { -r });
    if near_u && near_v {
        return if a < b {
            (pm(uv >= 0.0, a), v)
        } else {
            (u, pm(vv >= 0.0, b))
        };
    }
    if near_u {
        // On the B axis: the pole, or (inside the evolute) the off-axis foot.
        if a >= b || vv.abs() >= b - a * a / b {
            return (u, pm(vv >= 0.0, b));
        }
        let y = v * (b * b / (b * b - a * a));
        let q = y / b;
        return (((-(q * q)) + 1.0).abs().sqrt() * a, y);
    }
    if near_v {
        if b >= a || uv.abs() >= a - b * b / a {
            return (pm(uv >= 0.0, a), v);
        }
        let x = u * (a * a / (a * a - b * b));
        let q = x / a;
        return (x, ((-(q * q)) + 1.0).abs().sqrt() * b);
    }
    let a2 = [e.a2[j], e.a2[k], 0.0];
    let t = solve_root(&a2, &[uv, vv, 0.0], &[0, 1], None);
    let tt = lift_root(&a2, &[u, v, T::cst(0.0)], &[0, 1], t);
    (u * a2[0] / (tt + a2[0]), v * a2[1] / (tt + a2[1]))
}

/// Largest root of G(t) = Σ_{j∈axes} a_j² x_j² / (a_j² + t)² − 1 (all listed x_j ≠ 0).
fn solve_root(a2: &[f64; 3], x: &[f64; 3], axes: &[usize], guess: Option<f64>) -> f64 {
    let m = axes
        .iter()
        .copied()
        .min_by(|&i, &j| a2[i].total_cmp(&a2[j]))
        .unwrap_or(0);
    let f = |t: f64| -> (f64, f64) {
        // F = G + 1 and F'.
        let mut fv = 0.0;
        let mut fd = 0.0;
        for &j in axes {
            let q = 1.0 / (a2[j] + t);
            let term = a2[j] * x[j] * x[j] * q * q;
            fv += term;
            fd -= 2.0 * term * q;
        }
        (fv, fd)
    };
    // Warm start (neighbouring fan samples): plain Newton on G from a guess that is already
    // close, accepted once a step is tiny (quadratic convergence) with the iterate still
    // right of the pole at −a_min²; otherwise the bracketed solve below.
    if let Some(g) = guess {
        let mut t = g;
        for _ in 0..WARM_ITER {
            if !(a2[m] + t > 0.0) {
                break;
            }
            let (fv, fd) = f(t);
            let step = (fv - 1.0) / fd;
            t -= step;
            if step.abs() <= 1e-9 * (a2[m] + t).abs().min(t.abs() + a2[m]) {
                if a2[m] + t > 0.0 {
                    return t;
                }
                break;
            }
        }
    }
    let sum: f64 = axes.iter().map(|&j| a2[j] * x[j] * x[j]).sum();
    // F(lo) ≥ 1 (the smallest axis' term alone is 1), F(hi) ≤ 1.
    let mut lo = -a2[m] + (a2[m] * x[m] * x[m]).sqrt();
    let mut hi = -a2[m] + sum.sqrt();
    let mut t = guess.unwrap_or(0.0).max(lo).min(hi);
    let scale = a2[m];
    for _ in 0..MAX_ITER {
        let (fv, fd) = f(t);
        // K(t) = 1/√F − 1, increasing, K(root) = 0; K' = −F'/(2 F^{3/2}).
        let inv_sqrt = 1.0 / fv.sqrt();
        let k = inv_sqrt - 1.0;
        if k == 0.0 || !k.is_finite() {
            break;
        }
        if k < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let kd = -0.5 * fd * inv_sqrt / fv;
        let mut next = t - k / kd;
        let newton = next > lo && next < hi;
        if !newton {
            next = 0.5 * (lo + hi);
        }
        // Newton converges quadratically with |K''/K'| ≤ ~6/(a_min² + t): after a step Δ the
        // error is below 3Δ²/(a_min² + t), under 1e-16·(|t| + a_min²) for this Δ.
        let tol = 5e-9 * ((t.abs() + scale) * (a2[m] + t).max(0.0)).sqrt();
        let done = (newton && (next - t).abs() <= tol)
            || hi - lo <= 4.0 * f64::EPSILON * (t.abs() + scale);
        t = next;
        if done {
            break;
        }
    }
    t
}

/// The root t of G(t; x) = 0 as a function of x on `T`: one Newton step from the converged
/// `f64` root gives value t and derivative −G_x/G_t. For second derivatives a second step
/// is taken (with the same f64 slope G_t: the error after step k is O(|δx|^(k+1)), so two
/// steps make the second-order part exact).
fn lift_root<T: Real>(a2: &[f64; 3], x: &[T; 3], axes: &[usize], t: f64) -> T {
    if !T::HAS_GRAD {
        return T::cst(t);
    }
    let mut g = T::cst(-1.0);
    let mut gt = 0.0;
    for &j in axes {
        let q = 1.0 / (a2[j] + t);
        let ax = x[j] * (a2[j].sqrt() * q);
        g = g + ax * ax;
        let xv = x[j].val();
        gt -= 2.0 * a2[j] * xv * xv * q * q * q;
    }
    if gt == 0.0 || !gt.is_finite() {
        return T::cst(t);
    }
    let t1 = -(g / gt) + t;
    if !T::SECOND {
        return t1;
    }
    // G(t1; x) = Σ a_j² x_j² / (a_j² + t1)² − 1 on `T`.
    let mut g1 = T::cst(-1.0);
    for &j in axes {
        let ax = x[j] * a2[j].sqrt() / (t1 + a2[j]);
        g1 = g1 + ax * ax;
    }
    t1 - g1 / gt
}
