//! Torus wrapping, as OpenSim's `WrapTorus::wrapLine` defines it: a cylinder of the tube's
//! radius, tangent to the torus' centre circle at the point nearest the muscle line, wrapped
//! on its side facing the torus axis.

use super::cylinder::cylinder_core;
use super::real::{D1, D6, Real, V3, gradients, jacobian, second_order_of, seed, seed2};
use super::{Quadrant, SurfaceArc, WrapOutcome, Wrapped, all_finite, dsign};
use crate::spatial::Vec3;

/// OpenSim's `CYL_LENGTH`: the local cylinder is effectively infinite.
const CYLINDER_LENGTH: f64 = 10000.0;
/// OpenSim locates the line point by zeroing the residual
/// `2X·n − 2R·(2c4u + 2c3)/|X_xy|`, which is d/du (|X|² − 4R|X_xy|): the line's stationary
/// points with respect to a circle of radius 2R, not R. Reproduced, so that the cylinder
/// sits where OpenSim puts it.
const RING_FIT_FACTOR: f64 = 2.0;
/// Grid cells over the interval that holds every stationary point.
const GRID_CELLS: usize = 64;
const MAX_REFINE: usize = 100;

/// Wraps the segment P → S over a torus about the z axis: centre circle of radius
/// `outer_radius` in the plane z = 0, tube radius `inner_radius` (OpenSim's naming; OpenSim
/// requires 0 < inner < outer).
///
/// Definition followed (OpenSim `WrapTorus`):
/// - On the line X(u) = P + u(S − P), find the minima of g(u) = |X|² − 2κR|X_xy| (R =
///   `outer_radius`, κ = 2 as OpenSim's residual has it; see `RING_FIT_FACTOR`) reached from
///   P and from S; keep the one nearer the circle of radius R (unconstrained), or, with a
///   quadrant, the one on the active side (the nearer if both; no wrap if neither).
/// - The ring point C = R·X_xy/|X_xy| of that line point places a cylinder of radius
///   `inner_radius`, length 10000, axis tangent to the ring at C, its x axis towards the
///   torus axis (−Ĉ), y = −z: the tube's inner side, quadrant "+x". The segment is then
///   wrapped over that cylinder exactly as `wrap_cylinder` does, including its forced wraps:
///   when P and S both lie beyond the ring (inactive for "+x"), the path is forced round the
///   tube's inner side.
/// - The result is *not* a shortest path on the torus (it is a helix on the local cylinder,
///   which depends on P and S through C); it is a geodesic of the torus only in symmetric
///   cases such as a segment in a plane through the torus axis (a meridian arc).
///
/// Deliberate deviations: OpenSim runs a least-squares solve (MINPACK `lmdif`, tolerances
/// 1e-4) from each end; here the minimum reached by descent from each end, located on a
/// 64-cell grid over the interval that contains every stationary point and refined to
/// round-off (two minima within one cell may be missed). Where OpenSim's solves converge,
/// lengths agree with OpenSim 4.6 to ~1e-6 m; its solve can also stop short of any
/// stationary point (seen in 2 of 40 random "-x" cases, where it then placed the cylinder
/// elsewhere and did not wrap). The cylinder part has `wrap_cylinder`'s deviations (exact
/// helix).
///
/// Gradients and the contact points' Jacobians `dt1`, `dt2`: exact, by dual numbers through
/// the line-point root (implicit derivative), the cylinder placement and the cylinder wrap.
///
/// Outcome: OpenSim's torus reports a plain `wrapped` (never `mandatory`), and no wrap when
/// the local cylinder does not wrap or finds a point inside it (never `InsideRadius`).
///
/// Degenerate input: radii not satisfying 0 < inner < outer, non-finite values, P = S, or a
/// line along the torus axis give `NoWrap`.
pub fn wrap_torus(
    inner_radius: f64,
    outer_radius: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
) -> WrapOutcome {
    let radii_ok = inner_radius > 0.0 && outer_radius.is_finite() && inner_radius < outer_radius;
    if !(radii_ok && quadrant.is_valid() && all_finite(p, s)) {
        return WrapOutcome::NoWrap;
    }
    let (pd, sd) = seed(p, s);
    let Some(w) = torus_core::<D6>(inner_radius, outer_radius, quadrant, &pd, &sd) else {
        return WrapOutcome::NoWrap;
    };
    let (dlength_dp, dlength_ds) = gradients(&w.length);
    let finite = dlength_dp
        .iter()
        .chain(dlength_ds.iter())
        .all(|g| g.is_finite());
    if !(w.length.v.is_finite() && finite) {
        return WrapOutcome::NoWrap;
    }
    WrapOutcome::Wrapped(Wrapped {
        t1: w.t1,
        t2: w.t2,
        surface_length: w.surface_length,
        length: w.length.v,
        dlength_dp,
        dlength_ds,
        dt1: jacobian(&w.t1_t),
        dt2: jacobian(&w.t2_t),
        mandatory: false,
        arc: w.arc,
    })
}

/// [`super::WrapSurface::second_order`] for the torus (the caller checked that it wraps).
pub(super) fn second_order(
    inner_radius: f64,
    outer_radius: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
    dir: &[f64; 6],
) -> Option<super::WrapSecondOrder> {
    let (pd, sd) = seed2(p, s, dir);
    let w = torus_core::<D6<D1>>(inner_radius, outer_radius, quadrant, &pd, &sd)?;
    Some(second_order_of(&w.length, &w.t1_t, &w.t2_t))
}

pub(crate) struct TorusWrap<T> {
    pub t1: Vec3,
    pub t2: Vec3,
    /// t1 and t2 on `T` (constants when `T` carries no derivatives).
    pub t1_t: V3<T>,
    pub t2_t: V3<T>,
    pub length: T,
    pub surface_length: f64,
    pub arc: SurfaceArc,
}

fn torus_core<T: Real>(
    tube: f64,
    ring: f64,
    quadrant: Quadrant,
    p: &V3<T>,
    s: &V3<T>,
) -> Option<TorusWrap<T>> {
    let (pv, sv) = (p.val(), s.val());
    let line = Line {
        p: pv,
        e: sv - pv,
        k_r: RING_FIT_FACTOR * ring,
    };
    if line.e == Vec3::zeros() {
        return None;
    }
    // both descents walk the same grid: its values of g' are computed once each
    let mut grid = [f64::NAN; GRID_CELLS + 1];
    let u_from_p = line.descend(0.0, &mut grid)?;
    let u_from_s = line.descend(1.0, &mut grid)?;
    let (a1, a2) = (line.at(u_from_p), line.at(u_from_s));
    let ring_distance =
        |a: Vec3| (a.norm_squared() + ring * ring - 2.0 * ring * a.xy().norm()).max(0.0);
    let first_nearer = ring_distance(a1) < ring_distance(a2);
    let u = match quadrant.constraint() {
        None => {
            if first_nearer {
                u_from_p
            } else {
                u_from_s
            }
        }
        Some((axis, sign)) => match (dsign(a1[axis]) == sign, dsign(a2[axis]) == sign) {
            (true, true) => {
                if first_nearer {
                    u_from_p
                } else {
                    u_from_s
                }
            }
            (true, false) => u_from_p,
            (false, true) => u_from_s,
            (false, false) => return None,
        },
    };

    // The line point on `T`: one Newton step on g'(u; P, S) = 0 from the converged root.
    let g2 = line.g2(u);
    let e = *s - *p;
    let mut u_t = T::cst(u);
    if T::HAS_GRAD && g2 > 0.0 && g2.is_finite() {
        // g'(u) on `T`; a second step (same f64 slope g'') makes second derivatives exact.
        let g1 = |u: T| {
            let x = *p + e.scale(u);
            let (xy_dot, xy_len) = (x.x * e.x + x.y * e.y, (x.x * x.x + x.y * x.y).sqrt());
            x.dot(&e) * 2.0 - xy_dot * (2.0 * line.k_r) / xy_len
        };
        u_t = -(g1(T::cst(u)) / g2) + u;
        if T::SECOND {
            u_t = u_t - g1(u_t) / g2;
        }
    }
    let x = *p + e.scale(u_t);
    let rho = (x.x * x.x + x.y * x.y).sqrt();
    if !(rho.val() > 0.0) {
        return None;
    }
    // Cylinder frame at C = R·ĉ: x_c = −ĉ, y_c = −ẑ, z_c = x_c × y_c = (ĉ_y, −ĉ_x, 0).
    let (cx, cy) = (x.x / rho, x.y / rho);
    let to_cyl = |q: &V3<T>| {
        let (qx, qy) = (q.x - cx * ring, q.y - cy * ring);
        V3::new(-(cx * qx + cy * qy), -q.z, cy * qx - cx * qy)
    };
    let w = cylinder_core(
        tube,
        0.5 * CYLINDER_LENGTH,
        Quadrant::Positive(0),
        &to_cyl(p),
        &to_cyl(s),
    )?;

    let (c, k) = ((cx.val(), cy.val()), ring);
    let (xc, yc, zc) = (
        Vec3::new(-c.0, -c.1, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(c.1, -c.0, 0.0),
    );
    let vector = |v: Vec3| xc * v.x + yc * v.y + zc * v.z;
    let point = |v: Vec3| Vec3::new(c.0 * k, c.1 * k, 0.0) + vector(v);
    let (t1, t2) = (point(w.t1), point(w.t2));
    // The same map on `T`: C + x_c·v.x + y_c·v.y + z_c·v.z, C and the axes moving with ĉ.
    let point_t = |v: &V3<T>| {
        V3::new(
            cx * k - cx * v.x + cy * v.z,
            cy * k - cy * v.x - cx * v.z,
            -v.y,
        )
    };
    let (t1_t, t2_t) = if T::HAS_GRAD {
        (point_t(&w.t1_t), point_t(&w.t2_t))
    } else {
        (V3::cst(&t1), V3::cst(&t2))
    };
    Some(TorusWrap {
        t1,
        t2,
        t1_t,
        t2_t,
        length: w.length,
        surface_length: w.surface_length,
        arc: SurfaceArc {
            center: point(w.arc.center),
            w1: vector(w.arc.w1),
            w2: vector(w.arc.w2),
            w3: vector(w.arc.w3),
            span: w.arc.span,
        },
    })
}

/// The muscle line X(u) = p + u·e and g(u) = |X|² − 2·k_r·|X_xy| (k_r = κR).
struct Line {
    p: Vec3,
    e: Vec3,
    k_r: f64,
}

impl Line {
    fn at(&self, u: f64) -> Vec3 {
        self.p + self.e * u
    }

    /// g'(u) = 2 X·e − 2 k_r (X_xy·e_xy)/|X_xy| (the last term taken as 0 on the axis).
    fn g1(&self, u: f64) -> f64 {
        let x = self.at(u);
        let rho = x.xy().norm();
        let ring_term = if rho > 0.0 {
            x.xy().dot(&self.e.xy()) / rho
        } else {
            0.0
        };
        2.0 * x.dot(&self.e) - 2.0 * self.k_r * ring_term
    }

    /// g''(u) = 2|e|² − 2 k_r (|e_xy|²|X_xy|² − (X_xy·e_xy)²)/|X_xy|³.
    fn g2(&self, u: f64) -> f64 {
        self.g12(u).1
    }

    /// (g'(u), g''(u)), sharing X(u) and |X_xy| (each as [`Line::g1`] and [`Line::g2`]
    /// compute it).
    fn g12(&self, u: f64) -> (f64, f64) {
        let x = self.at(u);
        let (xy, exy) = (x.xy(), self.e.xy());
        let rho = xy.norm();
        let ring_term = if rho > 0.0 { xy.dot(&exy) / rho } else { 0.0 };
        let g1 = 2.0 * x.dot(&self.e) - 2.0 * self.k_r * ring_term;
        let curv = (exy.norm_squared() * rho * rho - xy.dot(&exy).powi(2)) / rho.powi(3);
        (g1, 2.0 * self.e.norm_squared() - 2.0 * self.k_r * curv)
    }

    /// The minimum of g reached by descent from u0. Every stationary point lies in
    /// u_c ± k_r|e_xy|/|e|² (u_c = −p·e/|e|²): outside it g' has the sign of u − u_c.
    /// `grid` holds g' at the grid points already evaluated (NaN where not yet).
    fn descend(&self, u0: f64, grid_values: &mut [f64; GRID_CELLS + 1]) -> Option<f64> {
        let e2 = self.e.norm_squared();
        let uc = -self.p.dot(&self.e) / e2;
        let half = self.k_r * self.e.xy().norm() / e2;
        // Widened a little: the bound is attained (a root at its end) for lines in a plane
        // through the torus axis.
        let (lo, hi) = (uc - 1.01 * half - 1e-12, uc + 1.01 * half + 1e-12);
        let g0 = self.g1(u0);
        if g0 == 0.0 {
            return Some(u0);
        }
        if half == 0.0 {
            // Line parallel to the torus axis: g is a parabola.
            return Some(uc);
        }
        let step = (hi - lo) / GRID_CELLS as f64;
        let grid = |i: usize| {
            if i == GRID_CELLS {
                hi
            } else {
                lo + step * i as f64
            }
        };
        // Walk grid points in the descent direction until g' changes sign.
        let (mut prev_u, mut prev_g) = (u0, g0);
        let downhill_right = g0 < 0.0;
        for k in 0..=GRID_CELLS {
            let i = if downhill_right { k } else { GRID_CELLS - k };
            let ui = grid(i);
            if (downhill_right && ui <= u0) || (!downhill_right && ui >= u0) {
                continue;
            }
            if grid_values[i].is_nan() {
                grid_values[i] = self.g1(ui);
            }
            let gi = grid_values[i];
            let flipped = if downhill_right { gi >= 0.0 } else { gi <= 0.0 };
            if flipped {
                return Some(if downhill_right {
                    self.refine(prev_u, prev_g, ui, gi)
                } else {
                    self.refine(ui, gi, prev_u, prev_g)
                });
            }
            (prev_u, prev_g) = (ui, gi);
        }
        None
    }

    /// Root of g' in [a, b] with g'(a) < 0 ≤ g'(b) (or ≤ 0 < at b from the left walk):
    /// Newton's method safeguarded by bisection, to round-off.
    fn refine(&self, mut a: f64, ga: f64, mut b: f64, gb: f64) -> f64 {
        if ga == 0.0 {
            return a;
        }
        if gb == 0.0 {
            return b;
        }
        let mut u = 0.5 * (a + b);
        for _ in 0..MAX_REFINE {
            let (g, d2) = self.g12(u);
            if g == 0.0 {
                return u;
            }
            if g < 0.0 {
                a = u;
            } else {
                b = u;
            }
            let mut next = u - g / d2;
            if !(d2 > 0.0 && next > a && next < b) {
                next = 0.5 * (a + b);
            }
            let tol = 4.0 * f64::EPSILON * (1.0 + u.abs());
            if (next - u).abs() <= tol || b - a <= tol {
                return next;
            }
            u = next;
        }
        u
    }
}
