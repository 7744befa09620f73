//! Cylinder wrapping, as OpenSim's `WrapCylinder::wrapLine` defines it; the core is generic
//! over the scalar so that the torus (a cylinder placed by a point-dependent frame) can run
//! it on dual numbers.

use std::f64::consts::PI;

use nalgebra::Matrix3x6;

use super::real::{D1, D6, Real, V3, join, second_order_of, seed2};
use super::{Quadrant, SurfaceArc, WrapOutcome, Wrapped, all_finite, dsign};
use crate::spatial::{Mat3, Vec3};

/// Wraps the segment P → S over a cylinder of radius `radius` whose axis is z, centred at the
/// origin, extending over z ∈ [−length/2, length/2].
///
/// Definition followed (OpenSim `WrapCylinder`); in the projection on the xy-plane a point at
/// distance d from the axis sees the circle under half-angle β = acos(R/d) at tangent length
/// h = √(d² − R²):
/// - `InsideRadius` if P or S is strictly inside the (infinite) cylinder: d < R.
/// - Unconstrained: wrap only if the projected segment crosses the circle (closest approach
///   of the line to the axis < R, reached strictly between P and S), and then `mandatory`.
///   The wrap goes around the side the segment passes: with Δ the angle between P and S
///   about the axis, the arc is θ = Δ − β1 − β2.
/// - Quadrant `(axis, sign)`: if P or S is on the active side, wrap if the segment crosses
///   (`mandatory`); otherwise wrap only if P and S are on opposite sides of the quadrant plane and the
///   point of the line closest to the cylinder axis is not on the active side; no wrap
///   otherwise. If neither P nor S is on the active side, always wrap. The direction around
///   the axis follows OpenSim's table on which of the four tangent candidates (at P's and
///   S's heights) lie on the active side; the arc is the angle from T1 to T2 in that
///   direction, in [0, 2π).
/// - Finite length: no wrap if both of OpenSim's trial contact heights lie beyond the
///   cylinder's ends (see `trial_heights`: the heights OpenSim tests, before it makes the
///   contacts tangent; deciding on the exact contact heights instead changed whether a path
///   wraps near the ends of short cylinders — by up to 5.6 mm in the default model's long
///   triceps over its small glenoid cylinder).
/// - The surface curve is the helix that, unrolled, makes P–T1–T2–S one straight line
///   (the geodesic): with H = h1 + R·θ + h2 and Δz = S.z − P.z,
///   length = √(H² + Δz²), T1.z = P.z + Δz·h1/H, T2.z = S.z − Δz·h2/H.
///
/// Deliberate deviations: (1) OpenSim approximates this helix iteratively (contact points
/// slid along the axis until tangent to within 0.1°, at most 100 passes), and not at all
/// when the path has a single wrap object and no visualiser: its preliminary contact
/// heights then make paths longer than the geodesic, by up to ~0.7 mm for R = 5 cm in
/// ordinary wraps and by millimetres to centimetres for long quadrant-forced wraps. This
/// returns the exact limit, which OpenSim 4.6 matches to ~1e-6 m when it iterates.
/// (2) The arc angle is the geometric angle in the chosen direction;
/// OpenSim's signed `atan2` plus "long wrap" test gives 2π + |θ| instead of 2π − |θ| for a
/// clockwise wrap longer than half a turn (OpenSim 4.6 returned 7.75 m where the path is
/// 0.32 m).
///
/// Gradients: the path is a geodesic, so ∂length/∂P is the unit vector from T1 to P (envelope
/// theorem), written as (H·∂H/∂P − Δz·ẑ)/length so that it stays finite on the surface.
/// The contact points' Jacobians `dt1`, `dt2` are the exact derivatives, in closed form, of
/// the tangent points in the projection and of the heights P.z + Δz·h1/H and
/// S.z − Δz·h2/H; the direction round the axis is a discrete choice.
///
/// Degenerate input: non-positive or non-finite radius or length, non-finite points, P = S,
/// or a segment parallel to the axis (unless a quadrant forces the wrap) give `NoWrap`.
pub fn wrap_cylinder(
    radius: f64,
    length: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
) -> WrapOutcome {
    let valid = radius > 0.0 && radius.is_finite() && length > 0.0 && !length.is_nan();
    if !(valid && quadrant.is_valid() && all_finite(p, s)) {
        return WrapOutcome::NoWrap;
    }
    if p.xy().norm() < radius || s.xy().norm() < radius {
        return WrapOutcome::InsideRadius;
    }
    wrap_outside(radius, length, quadrant, p, s).map_or(WrapOutcome::NoWrap, WrapOutcome::Wrapped)
}

fn wrap_outside(
    radius: f64,
    length: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
) -> Option<Wrapped> {
    let w = cylinder_core::<f64>(radius, 0.5 * length, quadrant, &V3::cst(p), &V3::cst(s))?;
    let g = &w.geo;
    // ∂H/∂P_xy = (h1/d1)·v̂1 − sense·(R/d1)·û1, ∂H/∂S_xy = (h2/d2)·v̂2 + sense·(R/d2)·û2.
    let (v1, v2) = (g.dir1, g.dir2);
    let (u1, u2) = (Vec3::new(-v1.y, v1.x, 0.0), Vec3::new(-v2.y, v2.x, 0.0));
    let dh_dp = v1 * (g.h1 / g.d1) - u1 * (g.sense * radius / g.d1);
    let dh_ds = v2 * (g.h2 / g.d2) + u2 * (g.sense * radius / g.d2);
    let dlength_dp = (dh_dp * g.h_total - Vec3::z() * g.dz) / w.length;
    let dlength_ds = (dh_ds * g.h_total + Vec3::z() * g.dz) / w.length;
    if !dlength_dp
        .iter()
        .chain(dlength_ds.iter())
        .all(|g| g.is_finite())
    {
        return None; // overflow with extreme coordinates
    }
    let (dt1, dt2) = contact_jacobians(radius, p, s, g, &dh_dp, &dh_ds);
    Some(Wrapped {
        t1: w.t1,
        t2: w.t2,
        surface_length: w.surface_length,
        length: w.length,
        dlength_dp,
        dlength_ds,
        dt1,
        dt2,
        mandatory: w.mandatory,
        arc: w.arc,
    })
}

/// [`super::WrapSurface::second_order`] for the cylinder (the caller checked that it wraps).
pub(super) fn second_order(
    radius: f64,
    length: f64,
    quadrant: Quadrant,
    p: &Vec3,
    s: &Vec3,
    dir: &[f64; 6],
) -> Option<super::WrapSecondOrder> {
    let (pd, sd) = seed2(p, s, dir);
    let w = cylinder_core::<D6<D1>>(radius, 0.5 * length, quadrant, &pd, &sd)?;
    Some(second_order_of(&w.length, &w.t1_t, &w.t2_t))
}

/// Values of the planar (projected) solution, for the closed-form gradient.
pub(crate) struct CylGeometry {
    /// +1: around the axis counter-clockwise (about +z) from T1 to T2; −1: clockwise.
    pub sense: f64,
    pub d1: f64,
    pub d2: f64,
    pub h1: f64,
    pub h2: f64,
    /// Unit xy-directions of P and S from the axis (z = 0).
    pub dir1: Vec3,
    pub dir2: Vec3,
    pub h_total: f64,
    pub dz: f64,
}

pub(crate) struct CylWrap<T> {
    pub t1: Vec3,
    pub t2: Vec3,
    /// t1 and t2 on `T` (their values as `t1`, `t2` only up to round-off; constants when `T`
    /// carries no derivatives).
    pub t1_t: V3<T>,
    pub t2_t: V3<T>,
    pub length: T,
    pub surface_length: f64,
    pub arc: SurfaceArc,
    pub geo: CylGeometry,
    /// OpenSim's `mandatoryWrap`: the segment crosses, with a point on the active side.
    pub mandatory: bool,
}

const CCW: f64 = 1.0;
const CW: f64 = -1.0;

/// The cylinder wrap on any scalar: decisions on values, the length in `T`.
///
/// Steps: the planar (projected) setup of P and S; the wrap direction from the quadrant
/// (or no wrap); the wrap angle; the unrolled length on `T`; OpenSim's finite-length test;
/// the tangent points and the surface arc.
pub(crate) fn cylinder_core<T: Real>(
    r: f64,
    half_length: f64,
    quadrant: Quadrant,
    p: &V3<T>,
    s: &V3<T>,
) -> Option<CylWrap<T>> {
    let (pv, sv) = (p.val(), s.val());
    let pl = Planar::new(r, &pv, &sv)?;
    let (sense, far, mandatory) = pl.choose_sense(quadrant, &pv, &sv)?;
    let (turns, theta) = pl.wrap_angle(sense, &pv, &sv);
    let (h_total_t, length) = pl.unrolled_length(p, s, sense, turns);

    let (h_total, dz, len) = (h_total_t.val(), (s.z - p.z).val(), length.val());
    if !(h_total > 0.0) || !len.is_finite() {
        return None;
    }
    let (h1, h2) = (pl.h1, pl.h2);
    let (c1, c2) = (pl.contact1(sense), pl.contact2(sense));
    // Heights of T1, T2: the path rises uniformly along the unrolled length.
    let t1 = Vec3::new(c1.x, c1.y, pv.z + dz * h1 / h_total);
    let t2 = Vec3::new(c2.x, c2.y, sv.z - dz * h2 / h_total);
    let outside = |z: f64| z < -half_length || z > half_length;
    let (z1, z2) = trial_heights(r, &pv, &sv, &c1, &c2, far);
    if outside(z1) && outside(z2) {
        return None;
    }
    let (t1_t, t2_t) = if T::HAS_GRAD {
        contact_points(r, p, s, sense, h_total_t)
    } else {
        (V3::cst(&t1), V3::cst(&t2))
    };
    let w1 = Vec3::new(t1.x, t1.y, 0.0);
    Some(CylWrap {
        t1,
        t2,
        t1_t,
        t2_t,
        length,
        surface_length: r * theta * len / h_total,
        arc: SurfaceArc {
            center: Vec3::new(0.0, 0.0, t1.z),
            w1,
            w2: Vec3::new(-w1.y, w1.x, 0.0) * sense,
            w3: Vec3::new(0.0, 0.0, t2.z - t1.z),
            span: theta,
        },
        geo: CylGeometry {
            sense,
            d1: pl.d1,
            d2: pl.d2,
            h1,
            h2,
            dir1: pl.dir1,
            dir2: pl.dir2,
            h_total,
            dz,
        },
        mandatory,
    })
}

/// P and S projected on the xy-plane (values only): their distances d from the axis, tangent
/// lengths h = √(d² − R²) and directions, and the projected line's closest approach to the
/// axis.
struct Planar {
    r: f64,
    d1: f64,
    d2: f64,
    h1: f64,
    h2: f64,
    dir1: Vec3,
    dir2: Vec3,
    /// The segment is (within OpenSim's tolerance) parallel to the axis.
    parallel: bool,
    /// Parameter of the closest approach on P + t (S − P) (NaN when parallel).
    t12: f64,
    /// The projected segment crosses the circle strictly between P and S.
    crosses: bool,
    /// (P × S)_z, and the sense (CCW, CW) the short way from P to S.
    cross: f64,
    near_sense: f64,
}

impl Planar {
    /// None when P or S is inside the cylinder or P = S.
    #[inline]
    fn new(r: f64, pv: &Vec3, sv: &Vec3) -> Option<Planar> {
        let (d1, d2) = (pv.xy().norm(), sv.xy().norm());
        if d1 < r || d2 < r || pv == sv {
            return None;
        }
        // Closest approach of the muscle line to the axis = of the projected line to the
        // origin. OpenSim treats a segment within ~5e-7 rad of the axis direction as parallel.
        let e = (sv - pv).xy();
        let parallel = e.norm_squared() <= 2e-13 * (sv - pv).norm_squared();
        let t12 = if parallel {
            f64::NAN
        } else {
            -pv.xy().dot(&e) / e.norm_squared()
        };
        let crosses =
            !parallel && (pv.xy() + e * t12).norm_squared() < r * r && t12 > 0.0 && t12 < 1.0;
        let cross = pv.x * sv.y - pv.y * sv.x;
        let near_sense = if cross > 0.0 { CCW } else { CW };
        Some(Planar {
            r,
            d1,
            d2,
            h1: (d1 * d1 - r * r).max(0.0).sqrt(),
            h2: (d2 * d2 - r * r).max(0.0).sqrt(),
            dir1: Vec3::new(pv.x / d1, pv.y / d1, 0.0),
            dir2: Vec3::new(sv.x / d2, sv.y / d2, 0.0),
            parallel,
            t12,
            crosses,
            cross,
            near_sense,
        })
    }

    /// Tangent point of P's line in the projection: sense = +1 puts T1 counter-clockwise of
    /// P's direction (OpenSim's r1a).
    #[inline]
    fn contact1(&self, sense: f64) -> Vec3 {
        let u = Vec3::new(-self.dir1.y, self.dir1.x, 0.0);
        (self.dir1 * self.r + u * (sense * self.h1)) * (self.r / self.d1)
    }

    /// Tangent point of S's line in the projection: sense = +1 puts T2 clockwise of S's
    /// direction (OpenSim's r2b).
    #[inline]
    fn contact2(&self, sense: f64) -> Vec3 {
        let u = Vec3::new(-self.dir2.y, self.dir2.x, 0.0);
        (self.dir2 * self.r - u * (sense * self.h2)) * (self.r / self.d2)
    }

    /// (sense, far, mandatory), or None (no wrap). `far`: OpenSim's far_side_wrap, which
    /// only picks the apex of its trial contact heights. Unconstrained: wrap the side the
    /// segment passes, only when it crosses (then mandatory).
    #[inline]
    fn choose_sense(&self, quadrant: Quadrant, pv: &Vec3, sv: &Vec3) -> Option<(f64, bool, bool)> {
        match quadrant.constraint() {
            None => {
                if !self.crosses {
                    return None;
                }
                Some((self.near_sense, false, true))
            }
            Some((axis, sign)) => self.quadrant_sense(axis, sign, pv, sv),
        }
    }

    /// Quadrant (axis, sign): with P or S on the active side, wrap when the segment crosses
    /// (mandatory) or is forced across the quadrant plane; then the direction from OpenSim's
    /// table of which tangent candidates (at P's and S's heights) lie on the active side.
    #[inline]
    fn quadrant_sense(
        &self,
        axis: usize,
        sign: f64,
        pv: &Vec3,
        sv: &Vec3,
    ) -> Option<(f64, bool, bool)> {
        let mut mandatory = false;
        let active = |v: f64| dsign(v) == sign;
        if active(pv[axis]) || active(sv[axis]) {
            mandatory = self.crosses;
            let near12 = pv + (sv - pv) * self.t12;
            let forced =
                !self.parallel && dsign(pv[axis]) != dsign(sv[axis]) && !active(near12[axis]);
            if !self.crosses && !forced {
                return None;
            }
        }
        // OpenSim's candidates carry the heights of P and S.
        let at = |xy: Vec3, z: f64| Vec3::new(xy.x, xy.y, z);
        let r1a = at(self.contact1(CCW), pv.z);
        let r1b = at(self.contact1(CW), pv.z);
        let r2a = at(self.contact2(CW), sv.z);
        let r2b = at(self.contact2(CCW), sv.z);
        let (a, b) = (active(r1a[axis]), active(r1b[axis]));
        let (c, d) = (active(r2a[axis]), active(r2b[axis]));
        // Planar angles of the counter-clockwise pair (r1a, r2b) and the clockwise pair
        // (r1b, r2a); NaN (degenerate) compares false, as in OpenSim.
        let angle =
            |u: Vec3, v: Vec3| (u.xy().dot(&v.xy()) / (u.xy().norm() * v.xy().norm())).acos();
        let ccw_wider = angle(r1a, r2b) > angle(r1b, r2a);
        let ccw = (CCW, ccw_wider);
        let cw = (CW, !ccw_wider);
        let (sense, far) = match (a, b) {
            (true, true) => {
                if c {
                    cw
                } else {
                    ccw
                }
            }
            (true, false) => ccw,
            (false, true) => cw,
            (false, false) => {
                if c {
                    cw
                } else if d {
                    ccw
                } else {
                    // Neither side active: the pair with the larger planar angle, taken
                    // as a far-side wrap.
                    (if ccw_wider { CCW } else { CW }, true)
                }
            }
        };
        Some((sense, far, mandatory))
    }

    /// (turns, θ): the wrap angle θ = Δ − β1 − β2 about the axis from T1 to T2 in direction
    /// `sense`, Δ the angle from P to S that way, β = atan(h/R); a forced wrap the short way
    /// round a line that misses takes a full turn less.
    #[inline]
    fn wrap_angle(&self, sense: f64, pv: &Vec3, sv: &Vec3) -> (f64, f64) {
        let r = self.r;
        let delta_near = self.cross.abs().atan2(pv.xy().dot(&sv.xy()));
        let beta = self.h1.atan2(r) + self.h2.atan2(r);
        if sense == self.near_sense {
            let th = delta_near - beta;
            if self.crosses || th >= 0.0 {
                (0.0, th.max(0.0))
            } else {
                (1.0, th + 2.0 * PI)
            }
        } else {
            (0.0, (2.0 * PI - delta_near - beta).max(0.0))
        }
    }

    /// (H, length) on `T`: the unrolled horizontal length H = (h1 − Rβ1) + (h2 − Rβ2) +
    /// R·(Δ_dir + 2π·turns) and length = √(H² + Δz²). The terms h − Rβ have derivative h/d
    /// with respect to d, finite on the surface.
    #[inline]
    fn unrolled_length<T: Real>(&self, p: &V3<T>, s: &V3<T>, sense: f64, turns: f64) -> (T, T) {
        let (r, d1, d2, h1, h2) = (self.r, self.d1, self.d2, self.h1, self.h2);
        let dd1 = (p.x * p.x + p.y * p.y).sqrt();
        let dd2 = (s.x * s.x + s.y * s.y).sqrt();
        // q(d) = h − R·atan(h/R): q' = h/d, q'' = R²/(h d²).
        let q1 = T::chain(
            h1 - r * h1.atan2(r),
            &[(h1 / d1, dd1)],
            &[r * r / (h1 * d1 * d1)],
        );
        let q2 = T::chain(
            h2 - r * h2.atan2(r),
            &[(h2 / d2, dd2)],
            &[r * r / (h2 * d2 * d2)],
        );
        let cross_t = p.x * s.y - p.y * s.x;
        let dot_t = p.x * s.x + p.y * s.y;
        // (+ 0.0 turns a −0 into +0, so that atan2 gives π, not −π, for opposite P and S.)
        let delta_near_t = (cross_t * self.near_sense + 0.0).atan2(dot_t);
        let delta_dir = if sense == self.near_sense {
            delta_near_t
        } else {
            -delta_near_t + 2.0 * PI
        };
        let h_total_t = q1 + q2 + (delta_dir + 2.0 * PI * turns) * r;
        let dz_t = s.z - p.z;
        (h_total_t, (h_total_t * h_total_t + dz_t * dz_t).sqrt())
    }
}

/// OpenSim's trial contact heights, on which its finite-length test decides (the wrap is
/// dropped when both lie beyond the cylinder's ends). The contact points start at the
/// heights of P and S (`c1`, `c2` in the projection) and are slid along the axis onto the
/// plane through P, S and an apex point A:
///   M = P + d1/(d1 + d2)·(S − P),  O = (0, 0, M.z),
///   n = unit((P − O)/|P − O| × (S − O)/|S − O|),  A = O ± R·unit(ẑ × n)
/// with the sign putting A nearer M, or farther for a far-side wrap; then
///   m = unit(unit(P − A) × unit(S − A)),  the plane m·X = m·P,
/// and the contact above r1 = (c1, P.z) moves to that plane's height when the line along the
/// axis through it meets the plane within ±10 m and the new height is nearer S.z than P.z is
/// (T2 likewise, nearer P.z than S.z is). OpenSim measures "nearer" on the line through
/// (0, 0, P.z) with direction (0, 0, S.z): when S.z = 0 that direction vanishes and every
/// point counts as at P.z (the first contact then never moves, the second always may).
/// A decision only: no derivatives.
fn trial_heights(r: f64, p: &Vec3, s: &Vec3, c1: &Vec3, c2: &Vec3, far: bool) -> (f64, f64) {
    let unit = |v: Vec3| {
        let n = v.norm();
        if n > 0.0 { v / n } else { v }
    };
    let (d1, d2) = (p.xy().norm(), s.xy().norm());
    let m = p + (s - p) * (d1 / (d1 + d2));
    let o = Vec3::new(0.0, 0.0, m.z);
    let n = unit(unit(p - o).cross(&unit(s - o)));
    let vert = unit(Vec3::z().cross(&n));
    let (apex1, apex2) = (o + vert * r, o - vert * r);
    let first_nearer = (m - apex1).norm_squared() < (m - apex2).norm_squared();
    let apex = if first_nearer != far { apex1 } else { apex2 };
    let plane = unit(unit(p - apex).cross(&unit(s - apex)));
    // Height where the axis-parallel segment from z0 − 10 to z0 + 10 at (x, y) meets the plane.
    let meet = |x: &Vec3| -> Option<f64> {
        let dot = 20.0 * plane.z;
        if !(dot.abs() >= 1e-5) {
            return None;
        }
        let start = Vec3::new(x.x, x.y, x.z - 10.0);
        let t = plane.dot(&(p - start)) / dot;
        (-1e-5..=1.0 + 1e-5)
            .contains(&t)
            .then(|| start.z + 20.0 * t)
    };
    // Closest point to height z on OpenSim's line through (0, 0, P.z) along (0, 0, S.z).
    let on_line = |z: f64| if s.z == 0.0 { p.z } else { z };
    let (mut z1, mut z2) = (p.z, s.z);
    if let Some(z) = meet(&Vec3::new(c1.x, c1.y, p.z)) {
        if (on_line(z) - s.z).powi(2) < (p.z - s.z).powi(2) {
            z1 = z;
        }
    }
    if let Some(z) = meet(&Vec3::new(c2.x, c2.y, s.z)) {
        if (on_line(z) - p.z).powi(2) < (s.z - p.z).powi(2) {
            z2 = z;
        }
    }
    (z1, z2)
}

/// ∂T1/∂(P, S) and ∂T2/∂(P, S) in closed form. In the projection T1 = α·P_xy + β·(ẑ × P_xy),
/// T2 = γ·S_xy − δ·(ẑ × S_xy), with α = R²/d1², β = σR·h1/d1², γ = R²/d2², δ = σR·h2/d2²
/// (σ = `sense`); heights T1.z = P.z + Δz·h1/H, T2.z = S.z − Δz·h2/H, with ∂H from
/// `dh_dp`, `dh_ds`.
fn contact_jacobians(
    r: f64,
    p: &Vec3,
    s: &Vec3,
    g: &CylGeometry,
    dh_dp: &Vec3,
    dh_ds: &Vec3,
) -> (Matrix3x6<f64>, Matrix3x6<f64>) {
    let (pxy, sxy) = (Vec3::new(p.x, p.y, 0.0), Vec3::new(s.x, s.y, 0.0));
    let (d1sq, d2sq) = (pxy.norm_squared(), sxy.norm_squared());
    let (r2, sense) = (r * r, g.sense);
    let flat = Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 0.0));
    let zx = Vec3::z().cross_matrix();
    let (hh, dz) = (g.h_total, g.dz);

    // T1: ∇α = −2α·P_xy/d1², ∇β = σR(2R² − d1²)/(h1·d1⁴)·P_xy.
    let (alpha, beta) = (r2 / d1sq, sense * r * g.h1 / d1sq);
    let grad_alpha = pxy * (-2.0 * alpha / d1sq);
    let grad_beta = pxy * (sense * r * (2.0 * r2 - d1sq) / (g.h1 * d1sq * d1sq));
    let mut dt1_dp = pxy * grad_alpha.transpose()
        + flat * alpha
        + Vec3::new(-p.y, p.x, 0.0) * grad_beta.transpose()
        + zx * beta;
    let mut dt1_ds = Mat3::zeros();
    // T1.z: ∂/∂P = ẑ(1 − h1/H) + Δz·P_xy/(H·h1) − Δz·h1·∂H/∂P/H²,
    //       ∂/∂S = ẑ·h1/H − Δz·h1·∂H/∂S/H².
    let k1 = dz * g.h1 / (hh * hh);
    let row1_p = Vec3::z() * (1.0 - g.h1 / hh) + pxy * (dz / (hh * g.h1)) - dh_dp * k1;
    let row1_s = Vec3::z() * (g.h1 / hh) - dh_ds * k1;
    dt1_dp.set_row(2, &row1_p.transpose());
    dt1_ds.set_row(2, &row1_s.transpose());

    // T2, likewise with −δ.
    let (gamma, delta) = (r2 / d2sq, sense * r * g.h2 / d2sq);
    let grad_gamma = sxy * (-2.0 * gamma / d2sq);
    let grad_delta = sxy * (sense * r * (2.0 * r2 - d2sq) / (g.h2 * d2sq * d2sq));
    let mut dt2_ds = sxy * grad_gamma.transpose() + flat * gamma
        - Vec3::new(-s.y, s.x, 0.0) * grad_delta.transpose()
        - zx * delta;
    let mut dt2_dp = Mat3::zeros();
    let k2 = dz * g.h2 / (hh * hh);
    let row2_s = Vec3::z() * (1.0 - g.h2 / hh) - sxy * (dz / (hh * g.h2)) + dh_ds * k2;
    let row2_p = Vec3::z() * (g.h2 / hh) + dh_dp * k2;
    dt2_ds.set_row(2, &row2_s.transpose());
    dt2_dp.set_row(2, &row2_p.transpose());

    (join(&dt1_dp, &dt1_ds), join(&dt2_dp, &dt2_ds))
}

/// The contact points on `T`, as `cylinder_core` places them: in the projection the tangent
/// points (R/d)(R·d̂ ± σh·û) (σ = `sense`, û = ẑ × d̂), at heights P.z + Δz·h1/H and
/// S.z − Δz·h2/H, with `h_total` = H on `T`.
fn contact_points<T: Real>(r: f64, p: &V3<T>, s: &V3<T>, sense: f64, h_total: T) -> (V3<T>, V3<T>) {
    let (dd1, dd2) = (p.x * p.x + p.y * p.y, s.x * s.x + s.y * s.y);
    let (h1, h2) = ((dd1 - r * r).sqrt(), (dd2 - r * r).sqrt());
    let (k1, k2) = (T::cst(r) / dd1, T::cst(r) / dd2);
    let (sh1, sh2) = (h1 * sense, h2 * sense);
    let dz = s.z - p.z;
    let t1 = V3::new(
        (p.x * r - p.y * sh1) * k1,
        (p.y * r + p.x * sh1) * k1,
        p.z + dz * h1 / h_total,
    );
    let t2 = V3::new(
        (s.x * r + s.y * sh2) * k2,
        (s.y * r - s.x * sh2) * k2,
        s.z - dz * h2 / h_total,
    );
    (t1, t2)
}
