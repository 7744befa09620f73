//! Sphere wrapping, as OpenSim's `WrapSphere::wrapLine` defines it.

use std::f64::consts::PI;

use nalgebra::Matrix3x6;

use super::real::{D1, D6, Real, V3, join, seed2};
use super::{Quadrant, SurfaceArc, WrapOutcome, WrapSecondOrder, Wrapped, all_finite, dsign};
use crate::spatial::{Mat3, Vec3};

/// Wraps the segment P → S over a sphere of radius `radius` centred at the origin.
///
/// Definition followed (OpenSim `WrapSphere`):
/// - `InsideRadius` if P or S is strictly inside the sphere; `NoWrap` if the segment does not
///   cross it: both roots λ of |S + λ(P − S)|² = R² must lie in (0, 1). This holds whatever
///   the quadrant: a quadrant only chooses the side of the sphere the path goes around.
/// - `mandatory` (OpenSim's `mandatoryWrap`) only with a quadrant and P or S on its active
///   side; an unconstrained sphere wrap is a plain `wrapped` in OpenSim.
/// - The path lies in the plane through P, S and the centre. With P at angle 0 and S at
///   angle Δ ∈ (0, π] in that plane, the tangent points from a point at distance d are at
///   ±β, β = acos(R/d) from its direction, and the tangent length is h = √(d² − R²).
///   *Near* wrap (the side the segment passes, the shortest path): T1 at β1, T2 at Δ − β2,
///   arc θ = Δ − β1 − β2. *Far* wrap (around the other side): T1 at −β1, T2 at Δ + β2,
///   θ = 2π − Δ − β1 − β2. length = h1 + R·θ + h2.
/// - Quadrant `(axis, sign)`: if both P and S are on the active side, the near wrap. Otherwise
///   OpenSim takes the far pair unless the sum of its tangent directions (T1 − P) + (T2 − S)
///   points away from the active side (negative component along `sign·e_axis`), in which
///   case the near pair.
///
/// Deliberate deviations: (1) for a far-side wrap longer than half a turn OpenSim stores a
/// *negative* surface length (`angle = −(2π − angle)`), which shortens the muscle; the
/// geometric, positive arc length is returned here. (2) When P, S and the centre are
/// collinear (OpenSim: within 1e-5 rad) OpenSim reuses the previous frame's tangent points;
/// this function is stateless and picks the plane containing the line and the quadrant axis
/// (or, unconstrained, the coordinate axis least aligned with the line). Every plane gives
/// the same length there, so only the tangent points and the one-sided gradient depend on
/// that choice.
///
/// Gradients: both wraps are stationary paths (taut strings), so by the envelope theorem
/// ∂length/∂P is the unit vector from T1 to P, written as (h1/d1)·P̂ ∓ (R/d1)·ê so that it
/// stays finite when P lies on the sphere (likewise S). The contact points' Jacobians
/// `dt1`, `dt2` are the exact derivatives, in closed form, of T1 = (R/d1)(R·P̂ + σh1·ê1),
/// T2 = (R/d2)(R·Ŝ − σh2·(n × Ŝ)) (σ = +1 near, −1 far), n the plane normal; the side is a
/// discrete choice.
///
/// Degenerate input: zero, negative or non-finite radius, non-finite points, or P = S give
/// `NoWrap`.
pub fn wrap_sphere(radius: f64, quadrant: Quadrant, p: &Vec3, s: &Vec3) -> WrapOutcome {
    if !(radius > 0.0 && radius.is_finite() && quadrant.is_valid() && all_finite(p, s)) {
        return WrapOutcome::NoWrap;
    }
    if p.norm() < radius || s.norm() < radius {
        return WrapOutcome::InsideRadius;
    }
    wrap_outside(radius, quadrant, p, s).map_or(WrapOutcome::NoWrap, WrapOutcome::Wrapped)
}

fn wrap_outside(r: f64, quadrant: Quadrant, p: &Vec3, s: &Vec3) -> Option<Wrapped> {
    let (d1, d2) = (p.norm(), s.norm());

    // Segment S + λ(P − S) against |x|² = R²: both crossings strictly inside the segment.
    let ps = p - s;
    let a = ps.norm_squared();
    let b = 2.0 * s.dot(&ps);
    let c = s.norm_squared() - r * r;
    let disc = b * b - 4.0 * a * c;
    if !(a > 0.0) || disc < 0.0 {
        return None;
    }
    let l_hi = (-b + disc.sqrt()) / (2.0 * a);
    let l_lo = (-b - disc.sqrt()) / (2.0 * a);
    if !(0.0 < l_lo && l_lo <= l_hi && l_hi < 1.0) {
        return None;
    }

    // In-plane frame: ex along P, ey towards S's side, n the plane normal.
    let ex = p / d1;
    let (n, plane) = wrap_plane_normal(p, s, ps, quadrant);
    let ey = n.cross(&ex);
    let delta = s.dot(&ey).max(0.0).atan2(s.dot(&ex));
    let (h1, h2) = (
        (d1 * d1 - r * r).max(0.0).sqrt(),
        (d2 * d2 - r * r).max(0.0).sqrt(),
    );
    let (beta1, beta2) = (h1.atan2(r), h2.atan2(r));
    let on_circle = |angle: f64| (ex * angle.cos() + ey * angle.sin()) * r;

    let near = (beta1, delta - beta2, (delta - beta1 - beta2).max(0.0), 1.0);
    let far = (
        -beta1,
        delta + beta2,
        (2.0 * PI - delta - beta1 - beta2).max(0.0),
        -1.0,
    );
    let mut mandatory = false;
    let (a1, a2, theta, sense) = match quadrant.constraint() {
        None => near,
        Some((axis, sign)) => {
            let (p_active, s_active) = (dsign(p[axis]) == sign, dsign(s[axis]) == sign);
            mandatory = p_active || s_active;
            if p_active && s_active {
                near
            } else {
                let pull = (on_circle(far.0) - p) + (on_circle(far.1) - s);
                if pull[axis] * sign < 0.0 { near } else { far }
            }
        }
    };
    let (t1, t2) = (on_circle(a1), on_circle(a2));

    let surface_length = r * theta;
    let length = h1 + surface_length + h2;
    // ê: in-plane unit perpendicular to the point's direction, towards increasing angle.
    let dlength_dp = ex * (h1 / d1) - ey * (sense * r / d1);
    let s_hat = s / d2;
    let dlength_ds = s_hat * (h2 / d2) + n.cross(&s_hat) * (sense * r / d2);
    if !(length.is_finite()
        && dlength_dp
            .iter()
            .chain(dlength_ds.iter())
            .all(|g| g.is_finite()))
    {
        return None; // overflow with extreme coordinates
    }
    let (dt1, dt2) = contact_jacobians(r, p, s, &n, plane, sense, h1, h2);

    Some(Wrapped {
        t1,
        t2,
        surface_length,
        length,
        dlength_dp,
        dlength_ds,
        dt1,
        dt2,
        mandatory,
        arc: SurfaceArc {
            center: Vec3::zeros(),
            w1: t1,
            w2: n.cross(&t1) * sense,
            w3: Vec3::zeros(),
            span: theta,
        },
    })
}

/// [`super::WrapSurface::second_order`] for the sphere, given its wrap `w`: the closed forms
/// of the gradient, g_P = (h1/d1)·P̂ − σ(R/d1)·(n × P̂), g_S = (h2/d2)·Ŝ + σ(R/d2)·(n × Ŝ),
/// and of the contact points (see `contact_jacobians`), on `D6<D1>`, with the plane normal
/// built as `wrap_plane_normal` built it and σ read from the wrap's arc.
pub(super) fn second_order(
    r: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
    w: &Wrapped,
    dir: &[f64; 6],
) -> Option<WrapSecondOrder> {
    let (n_val, plane) = wrap_plane_normal(p, s, p - s, quadrant);
    let sense = if w.arc.w2.dot(&n_val.cross(&w.t1)) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    let (pd, sd) = seed2(p, s, dir);
    type T = D6<D1>;
    let m: V3<T> = match plane {
        Plane::Cross => pd.cross(&sd),
        Plane::Line(axis) => (pd - sd).cross(&V3::cst(&Vec3::ith(axis, 1.0))),
        Plane::Fixed => V3::cst(&Vec3::z()),
    };
    let n = m.scale(T::cst(1.0) / m.norm());
    let (d1, d2) = (pd.norm(), sd.norm());
    let (h1, h2) = ((d1 * d1 - r * r).sqrt(), (d2 * d2 - r * r).sqrt());
    let (p_hat, s_hat) = (pd.scale(T::cst(1.0) / d1), sd.scale(T::cst(1.0) / d2));
    let g_p = p_hat.scale(h1 / d1) - n.cross(&p_hat).scale(T::cst(sense * r) / d1);
    let g_s = s_hat.scale(h2 / d2) + n.cross(&s_hat).scale(T::cst(sense * r) / d2);
    let t1 = pd.scale(T::cst(r * r) / (d1 * d1)) + n.cross(&pd).scale(h1 * (sense * r) / (d1 * d1));
    let t2 = sd.scale(T::cst(r * r) / (d2 * d2)) - n.cross(&sd).scale(h2 * (sense * r) / (d2 * d2));
    let g = [g_p.x, g_p.y, g_p.z, g_s.x, g_s.y, g_s.z];
    Some(WrapSecondOrder {
        hessian_dir: std::array::from_fn(|k| g[k].v.d),
        dt1_dir: nalgebra::Matrix3x6::from_fn(|i, k| t1.at(i).g[k].d),
        dt2_dir: nalgebra::Matrix3x6::from_fn(|i, k| t2.at(i).g[k].d),
    })
}

/// Which construction `wrap_plane_normal` used: P × S, or (collinear) the line direction
/// crossed with a coordinate axis.
#[derive(Clone, Copy)]
enum Plane {
    Cross,
    Line(usize),
    Fixed,
}

/// Unit normal of the plane through P, S and the centre, oriented so that S lies at a
/// positive angle from P about it; a deterministic choice when the three are collinear.
fn wrap_plane_normal(p: &Vec3, s: &Vec3, ps: Vec3, quadrant: Quadrant) -> (Vec3, Plane) {
    let n = p.cross(s);
    let nn = n.norm();
    if nn > 1e-12 * p.norm() * s.norm() {
        return (n / nn, Plane::Cross);
    }
    let u = ps / ps.norm();
    let least_aligned = (0..3)
        .min_by(|&i, &j| u[i].abs().total_cmp(&u[j].abs()))
        .unwrap_or(0);
    let preferred = quadrant
        .constraint()
        .map_or(least_aligned, |(axis, _)| axis);
    for axis in [preferred, least_aligned] {
        let m = u.cross(&Vec3::ith(axis, 1.0));
        let mn = m.norm();
        if mn > 1e-6 {
            return (m / mn, Plane::Line(axis));
        }
    }
    // Unreachable for a unit u (its least-aligned axis is at least 54.7° away).
    (Vec3::z(), Plane::Fixed)
}

/// ∂T1/∂(P, S) and ∂T2/∂(P, S) of the closed forms T1 = α·P + β·(n × P),
/// T2 = γ·S − δ·(n × S), with α = R²/d1², β = σR·h1/d1², γ = R²/d2², δ = σR·h2/d2²
/// (σ = `sense`: +1 near wrap, −1 far) and the plane normal n = m/|m| as
/// `wrap_plane_normal` built it: m = P × S, or (P − S) × e_axis.
#[allow(clippy::too_many_arguments)]
fn contact_jacobians(
    r: f64,
    p: &Vec3,
    s: &Vec3,
    n: &Vec3,
    plane: Plane,
    sense: f64,
    h1: f64,
    h2: f64,
) -> (Matrix3x6<f64>, Matrix3x6<f64>) {
    // n = m/|m| with dm = −[c_p]× dP + [c_s]× dS (m = P × S: c_p = S, c_s = P;
    // m = (P − S) × e: c_p = c_s = e), so dn = μ(I − n nᵀ)(∓[c]×) with μ = 1/|m|, and
    // [X]×(I − n nᵀ)[c]× = c Xᵀ − (X·c) I − (X × n)(n × c)ᵀ: no matrix products.
    let (mu, c_p, c_s) = match plane {
        Plane::Cross => (1.0 / p.cross(s).norm(), *s, *p),
        Plane::Line(axis) => {
            let e = Vec3::ith(axis, 1.0);
            (1.0 / (p - s).cross(&e).norm(), e, e)
        }
        Plane::Fixed => (0.0, Vec3::zeros(), Vec3::zeros()),
    };
    // [X]× ∂n/∂P and [X]× ∂n/∂S.
    let x_dn = |x: &Vec3| {
        let term = |c: &Vec3| {
            c * x.transpose()
                - Mat3::from_diagonal_element(x.dot(c))
                - x.cross(n) * n.cross(c).transpose()
        };
        (term(&c_p) * (-mu), term(&c_s) * mu)
    };
    let nx = n.cross_matrix();
    let (d1sq, d2sq) = (p.norm_squared(), s.norm_squared());
    let r2 = r * r;

    // T1: ∇α = −2α·P/d1², ∇β = σR(2R² − d1²)/(h1·d1⁴)·P, d(n × P) = [n]× dP − [P]× dn.
    let (alpha, beta) = (r2 / d1sq, sense * r * h1 / d1sq);
    let grad_alpha = p * (-2.0 * alpha / d1sq);
    let grad_beta = p * (sense * r * (2.0 * r2 - d1sq) / (h1 * d1sq * d1sq));
    let w = n.cross(p);
    let (p_dn_dp, p_dn_ds) = x_dn(p);
    let dt1_dp = p * grad_alpha.transpose()
        + Mat3::from_diagonal_element(alpha)
        + w * grad_beta.transpose()
        + (nx - p_dn_dp) * beta;
    let dt1_ds = p_dn_ds * (-beta);

    // T2, likewise with −δ.
    let (gamma, delta) = (r2 / d2sq, sense * r * h2 / d2sq);
    let grad_gamma = s * (-2.0 * gamma / d2sq);
    let grad_delta = s * (sense * r * (2.0 * r2 - d2sq) / (h2 * d2sq * d2sq));
    let v = n.cross(s);
    let (s_dn_dp, s_dn_ds) = x_dn(s);
    let dt2_ds = s * grad_gamma.transpose() + Mat3::from_diagonal_element(gamma)
        - v * grad_delta.transpose()
        - (nx - s_dn_ds) * delta;
    let dt2_dp = s_dn_dp * delta;

    (join(&dt1_dp, &dt1_ds), join(&dt2_dp, &dt2_ds))
}
