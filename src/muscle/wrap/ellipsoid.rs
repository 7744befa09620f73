//! Ellipsoid wrapping, as OpenSim's `WrapEllipsoid::wrapLine` defines it.

use std::f64::consts::PI;

use super::closest::{
    Ellipsoid, closest, unit_to_closest_with_jacobian, unit_to_closest_with_jacobian_rate,
};
use super::elliptic::ellipse_arc_length;
use super::real::{D1, D6, Real, V3, gradients, jacobian, second_order_of, seed, seed2};
use super::{
    EllipsoidMethod, Quadrant, SurfaceArc, WrapOutcome, WrapSecondOrder, Wrapped, all_finite, dsign,
};
use crate::spatial::{Mat3, Vec3};

/// OpenSim's `MU_BLEND_MIN`: below this axis alignment, c1 comes from the fan alone (it
/// must exceed cos 45°, so that the most-aligned axis never switches while Frans' c1 is in
/// use).
const MU_BLEND_MIN: f64 = 0.7073;
/// OpenSim's `MU_BLEND_MAX`: above this, c1 comes from Frans' technique alone.
const MU_BLEND_MAX: f64 = 0.9;
/// OpenSim's `SV_BOUNDARY_BLEND`: Frans' point fades out within this fraction of the chord
/// ends.
const SV_BOUNDARY_BLEND: f64 = 0.3;
/// OpenSim's `NUM_FAN_SAMPLES`: the fan sums samples i/300, i = 1..=298.
const NUM_FAN_SAMPLES: usize = 300;
/// OpenSim's thresholds on Σ x²/a² − 1 (inside) and on P̂·Ŝ − 1 (same direction).
const INSIDE_LEVEL: f64 = -1e-4;
const SAME_DIRECTION: f64 = 1e-4;
/// OpenSim takes a path point within this of the surface (in Σ x²/a² − 1) as its own
/// tangent point.
const ON_SURFACE_LEVEL: f64 = 1e-4;
/// OpenSim's polyline step along the arc (it assumes metres): below one step it takes the
/// chord as the arc, and it checks the arc's direction only from two steps on.
const OPENSIM_SEGMENT: f64 = 0.001;
/// OpenSim's `calcTangentPoint` limits: outer iterations and the residual it accepts.
const LM_MAX_ITER: usize = 50;
const LM_TOLERANCE: f64 = 1e-8;
/// OpenSim allows 1000 inner damping/extension passes; beyond ~60 the damping (×4 each) or
/// the extension (×2 each) has left double precision, so the result is the same.
const LM_MAX_INNER: usize = 64;

/// Wraps the segment P → S over the ellipsoid x²/a² + y²/b² + z²/c² = 1, `radii` = (a, b, c).
///
/// Definition followed (OpenSim `WrapEllipsoid`):
/// - `InsideRadius` if P or S is inside (Σ x²/a² < 1 − 1e-4); `NoWrap` if P and S lie in
///   nearly the same direction from the centre (P̂·Ŝ > 1 − 1e-4), or if the segment does not
///   cross the ellipsoid (both crossings strictly between P and S); quadrants never force a
///   wrap. A wrap is always `mandatory` (OpenSim returns `mandatoryWrap`).
/// - The path lies in the plane through P, S and a surface point c1, and follows that plane
///   section: P → T1 (tangent from P within the plane) → section arc → T2 → S. It is *not* a
///   shortest path: a plane section is generally not a geodesic, and c1 is a heuristic (the
///   best plane through P and S already gives a shorter path).
/// - c1 (with X1, X2 the chord's crossings, the chord's most-aligned axis k with alignment
///   μ = |(P − S)_k|/|P − S|):
///   - *Frans*: the chord point with x_k = 0 (at fraction t of X1→X2), and its closest point
///     on the section x_k = 0;
///   - *fan*: the chord midpoint plus (a + b + c)/3 times the unit mean of the unit vectors
///     from the chord points X1 + (i/300)(X2 − X1), i = 1..298, to their closest surface
///     points, projected onto the surface;
///   - `Hybrid`: Frans above μ = 0.9, the fan below 0.7073, in between the projection of
///     their blend with weight (μ − 0.7073)/(0.9 − 0.7073) on Frans; μ is first faded
///     towards 0.7073 when t lies within 0.3 of the chord's ends (to 0.7073 outside it);
///   - `Axial`: Frans; `Midpoint`: the closest surface point to the chord midpoint.
/// - Quadrant `(axis, sign)`: if c1 is not on the active side it is mirrored across the
///   plane; when the fan took part (weight w = 1 − blend weight), its coordinate is then
///   scaled by 1 − w and c1 projected back onto the surface.
/// - T1 and T2 are tangent points within the plane (two from each end). OpenSim finds them
///   with an iterative solve started at c1 (at the mirrored c1 after a quadrant flip; at X1
///   and X2 for `Axial` when Frans' point lies outside the chord), and lands in regular
///   cases on c1's side of the line PS, but not always: with a quadrant it can land on the
///   other side for one end or both, giving a kinked path or no effective restriction.
///   Here each tangent point is computed exactly (the intersection of the wrap plane, the
///   point's polar plane x·diag(1/a²)·P = 1 and the ellipsoid) and the one OpenSim's solver
///   lands on is taken: the solver is run as OpenSim runs it (same damping, scaling and
///   stopping rule) only to make that choice. A path point within 1e-4 of the surface (in
///   Σ x²/a² − 1) is its own contact point in OpenSim: here the exact tangent point towards
///   the other end.
/// - The arc runs from T1 to T2 along the section, the short way round as seen from a0, the
///   plane's point on the coordinate axis most aligned with the plane normal; with a
///   quadrant, the long way if that arc leaves T1 towards P or reaches T2 from S's side
///   (checked, as in OpenSim, only for contact points at least 2 mm apart). Below 1 mm
///   apart, the short arc (OpenSim uses the chord).
///
/// Deliberate deviations: (1) OpenSim measures the arc as a polyline of ~1 mm steps on rays
/// from a0 (the chord below 1 mm), slightly shorter than the curve, with small jumps as the
/// step count changes; here the exact arc length of the section ellipse (elliptic
/// integral). When a0 falls outside the section, OpenSim's rays miss the arc (a wrong
/// length, or NaN); the exact arc in the same direction is returned. (2) Contact points
/// exact instead of OpenSim's 1e-4 residual. Against OpenSim 4.6 itself, lengths agree to
/// ~2e-5 m over the random cases of `tests/opensim_reference.txt`. (3) OpenSim's
/// `fanWeight` default for the quadrant pull is dead code (its comparison with −∞ is never
/// true), so without a fan c1 is only mirrored: reproduced.
///
/// With equal radii every method yields the sphere's unconstrained result (c1 is then a
/// radial projection, so the plane contains the centre).
///
/// Gradients: exact derivatives of this construction, by dual numbers through every step
/// (root-finding lifted by the implicit-function theorem, elliptic integrals with their
/// closed-form partials); the contact points' Jacobians `dt1`, `dt2` come from the same
/// pass. The length is piecewise smooth: it jumps where a discrete choice
/// changes (method regime, quadrant flip, the contact point OpenSim's solver lands on, the
/// arc's direction), and, for the fan, where one of its 298 samples crosses the
/// ellipsoid's medial plane and its closest point jumps (OpenSim's "jitter").
///
/// Degenerate input: non-positive or non-finite radii, non-finite points, P = S, or c1 on
/// the line PS (no plane) give `NoWrap`.
pub fn wrap_ellipsoid(
    radii: &Vec3,
    quadrant: Quadrant,
    method: EllipsoidMethod,
    p: &Vec3,
    s: &Vec3,
) -> WrapOutcome {
    if !(radii.iter().all(|&a| a > 0.0 && a.is_finite()) && quadrant.is_valid() && all_finite(p, s))
    {
        return WrapOutcome::NoWrap;
    }
    let e = Ellipsoid::new([radii.x, radii.y, radii.z]);
    if e.level(p) < INSIDE_LEVEL || e.level(s) < INSIDE_LEVEL {
        return WrapOutcome::InsideRadius;
    }
    let (pd, sd) = seed(p, s);
    let Some(w) = ellipsoid_core::<D6>(&e, quadrant, method, &pd, &sd) else {
        return WrapOutcome::NoWrap;
    };
    let (dlength_dp, dlength_ds) = gradients(&w.length);
    if !dlength_dp
        .iter()
        .chain(dlength_ds.iter())
        .all(|g| g.is_finite())
    {
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
        mandatory: true,
        arc: w.arc,
    })
}

/// [`super::WrapSurface::second_order`] for the ellipsoid (the caller checked that it wraps).
pub(super) fn second_order(
    radii: &Vec3,
    quadrant: Quadrant,
    method: EllipsoidMethod,
    p: &Vec3,
    s: &Vec3,
    dir: &[f64; 6],
) -> Option<WrapSecondOrder> {
    let e = Ellipsoid::new([radii.x, radii.y, radii.z]);
    let (pd, sd) = seed2(p, s, dir);
    let w = ellipsoid_core::<D6<D1>>(&e, quadrant, method, &pd, &sd)?;
    Some(second_order_of(&w.length, &w.t1_t, &w.t2_t))
}

pub(crate) struct EllipsoidWrap<T> {
    pub t1: Vec3,
    pub t2: Vec3,
    /// t1 and t2 on `T`.
    pub t1_t: V3<T>,
    pub t2_t: V3<T>,
    pub length: T,
    pub surface_length: f64,
    pub arc: SurfaceArc,
}

/// The ellipsoid wrap on any scalar (decisions on values, geometry in `T`).
pub(crate) fn ellipsoid_core<T: Real>(
    e: &Ellipsoid,
    quadrant: Quadrant,
    method: EllipsoidMethod,
    p: &V3<T>,
    s: &V3<T>,
) -> Option<EllipsoidWrap<T>> {
    let (pv, sv) = (p.val(), s.val());
    if e.level(&pv) < INSIDE_LEVEL || e.level(&sv) < INSIDE_LEVEL {
        return None;
    }
    let (np, ns) = (pv.norm(), sv.norm());
    if (pv.dot(&sv) / (np * ns) - 1.0).abs() < SAME_DIRECTION {
        return None;
    }

    // Chord: S + λ(P − S) on the surface, in the metric A = diag(1/a²); X1 near P, X2 near S.
    let d = *p - *s;
    let ad = d.mul_diag(&e.inv_a2);
    let qa = ad.dot(&d);
    let qb = ad.dot(s) * 2.0;
    let qc = s.mul_diag(&e.inv_a2).dot(s) - 1.0;
    let disc = qb * qb - qa * qc * 4.0;
    if !(qa.val() > 0.0) || !(disc.val() > 0.0) {
        return None;
    }
    let root = disc.sqrt();
    let l1 = (-qb + root) / (qa * 2.0);
    let l2 = (-qb - root) / (qa * 2.0);
    if !(0.0 < l1.val() && l1.val() < 1.0 && 0.0 < l2.val() && l2.val() < 1.0) {
        return None;
    }
    let x1 = *s + d.scale(l1);
    let x2 = *s + d.scale(l2);
    let chord = x2 - x1;

    // ==== c1, the point that fixes the wrap plane ====
    let dn = d.norm();
    let mu = [d.x.abs() / dn, d.y.abs() / dn, d.z.abs() / dn];
    let mut best = 0;
    for k in 1..3 {
        if mu[k].val() > mu[best].val() {
            best = k;
        }
    }
    // Frans: the chord point on the plane x_best = 0 and its closest point on that section.
    let t_frans = -x1.at(best) / chord.at(best);
    let mut sv_frans = x1 + chord.scale(t_frans);
    sv_frans.set(best, T::cst(0.0));
    let c1_frans = closest(e, &sv_frans, Some(best), None).0;
    let tf = t_frans.val();

    let mut mu_b = mu[best];
    let mut fan_weight: Option<T> = None;
    let mut c1;
    match method {
        EllipsoidMethod::Hybrid => {
            if mu_b.val() > MU_BLEND_MIN {
                let fade = if !(0.0..=1.0).contains(&tf) {
                    Some(T::cst(0.0))
                } else if tf < SV_BOUNDARY_BLEND {
                    Some(t_frans / SV_BOUNDARY_BLEND)
                } else if tf > 1.0 - SV_BOUNDARY_BLEND {
                    Some((-t_frans + 1.0) / SV_BOUNDARY_BLEND)
                } else {
                    None
                };
                if let Some(f) = fade {
                    mu_b = (mu_b - MU_BLEND_MIN) * f + MU_BLEND_MIN;
                }
            }
            c1 = c1_frans;
            if mu_b.val() < MU_BLEND_MAX {
                let mid = x1 + chord.scale_f(0.5);
                let scale = (e.radii[0] + e.radii[1] + e.radii[2]) / 3.0;
                let fan_tip = mid + fan_direction(e, &x1, &chord).scale_f(scale);
                let fan_c1 = closest(e, &fan_tip, None, None).0;
                if mu_b.val() <= MU_BLEND_MIN {
                    c1 = fan_c1;
                    fan_weight = Some(T::cst(1.0));
                } else {
                    let tt = (mu_b - MU_BLEND_MIN) / (MU_BLEND_MAX - MU_BLEND_MIN);
                    let blend = c1_frans.scale(tt) + fan_c1.scale(-tt + 1.0);
                    c1 = closest(e, &blend, None, None).0;
                    fan_weight = Some(-tt + 1.0);
                }
            }
        }
        EllipsoidMethod::Axial => {
            c1 = c1_frans;
        }
        EllipsoidMethod::Midpoint => {
            let mid = x1 + chord.scale_f(0.5);
            c1 = closest(e, &mid, None, None).0;
        }
    }

    // OpenSim starts its tangent-point solves at c1, except for `Axial` with Frans' point
    // outside the chord, where it starts them at the chord's crossings X1 and X2.
    let axial_outside = method == EllipsoidMethod::Axial && !(tf > 0.0 && tf < 1.0);
    let mut guesses = if axial_outside {
        (x1.val(), x2.val())
    } else {
        (c1.val(), c1.val())
    };

    if let Some((axis, sign)) = quadrant.constraint()
        && dsign(c1.at(axis).val()) != sign
    {
        c1.set(axis, -c1.at(axis));
        // The solves start at the mirrored c1, before the pull below.
        guesses = (c1.val(), c1.val());
        if let Some(w) = fan_weight
            && w.val() > 0.0
        {
            let w = if w.val() > 1.0 { T::cst(1.0) } else { w };
            c1.set(axis, c1.at(axis) * (-w + 1.0));
            c1 = closest(e, &c1, None, None).0;
        }
    }

    planar_wrap(e, p, s, &c1, guesses, quadrant.constraint().is_some())
}

/// The wrap in the plane through P, S and c1, as OpenSim builds it: each tangent point is
/// the exact one (of the two from that end) on which OpenSim's own solver, started at the
/// guess, lands; the arc runs from T1 to T2 the short way round as seen from OpenSim's axis
/// point a0, or (constrained, when that arc leaves T1 or reaches T2 against the straight
/// parts) the long way.
pub(crate) fn planar_wrap<T: Real>(
    e: &Ellipsoid,
    p: &V3<T>,
    s: &V3<T>,
    c1: &V3<T>,
    guesses: (Vec3, Vec3),
    constrained: bool,
) -> Option<EllipsoidWrap<T>> {
    let (pv, sv) = (p.val(), s.val());
    let d = *p - *s;
    let dn = d.norm();
    // ==== the wrap plane n·x = h through P, S and c1 ====
    let n_raw = d.cross(&(*p - *c1));
    let n_len = n_raw.norm();
    if !(n_len.val() > 1e-12 * dn.val() * (pv - c1.val()).norm()) {
        return None;
    }
    let n = n_raw.scale(T::cst(1.0) / n_len);
    let h = n.dot(c1);
    let nv = n.val();

    let cand1 = tangent_candidates(e, &n, h, p)?;
    let cand2 = tangent_candidates(e, &n, h, s)?;
    let landing1 = opensim_tangent_landing(e, &nv, h.val(), &pv, &guesses.0);
    let landing2 = opensim_tangent_landing(e, &nv, h.val(), &sv, &guesses.1);
    let nearest = |c: &[V3<T>; 2], x: &Vec3| {
        if (c[0].val() - x).norm() <= (c[1].val() - x).norm() {
            c[0]
        } else {
            c[1]
        }
    };
    // On the surface (within OpenSim's band) OpenSim starts the arc at the point itself: the
    // exact tangent point towards the other end.
    let t2 = match landing2 {
        Some(x) => nearest(&cand2, &x),
        None => nearest(&cand2, &landing1.unwrap_or(pv)),
    };
    let t1 = match landing1 {
        Some(x) => nearest(&cand1, &x),
        None => nearest(&cand1, &t2.val()),
    };

    // ==== the section ellipse: centre xc, conjugate semi-diameters w1 (to T1) and w2 ====
    // xc = h·A⁻¹n / (nᵀA⁻¹n) (where A·x ∥ n); k = 1 − xcᵀA xc; x = xc + cos t·w1 + sin t·w2.
    let a_inv_n = n.mul_diag(&e.a2);
    let xc = a_inv_n.scale(h / a_inv_n.dot(&n));
    let k = -xc.mul_diag(&e.inv_a2).dot(&xc) + 1.0;
    if !(k.val() > 0.0) {
        return None;
    }
    let w1 = t1 - xc;
    let w2_dir = n.cross(&w1.mul_diag(&e.inv_a2));
    let mut w2 = w2_dir.scale((k / w2_dir.mul_diag(&e.inv_a2).dot(&w2_dir)).sqrt());
    // (w1 × w2)·n > 0 now: increasing t turns counter-clockwise about n.

    // OpenSim's direction: from a0 (the plane's point on the coordinate axis most aligned
    // with n) the short way from T1 to T2.
    let (t1v, t2v) = (t1.val(), t2.val());
    let imax = (0..3).fold(0, |b, i| if nv[i].abs() > nv[b].abs() { i } else { b });
    let a0 = Vec3::ith(imax, h.val() / nv[imax]);
    let mut ccw = (t1v - a0).cross(&(t2v - a0)).dot(&nv) >= 0.0;
    let (x0, w1v, w2v) = (xc.val(), w1.val(), w2.val());
    // Direction of travel at parameter t when the arc turns counter-clockwise (or not).
    let tangent_at = |ccw: bool, t: f64| {
        let w2s = if ccw { w2v } else { -w2v };
        w2s * t.cos() - w1v * t.sin()
    };
    let span_of = |ccw: bool| {
        let r = (t2v - x0).component_mul(&Vec3::from(e.inv_a2));
        let (c, s) = (r.dot(&w1v), r.dot(&w2v));
        let a = if ccw { s.atan2(c) } else { (-s).atan2(c) };
        if a < -1e-6 { a + 2.0 * PI } else { a }
    };
    let chord = (t1v - t2v).norm();
    if chord < OPENSIM_SEGMENT {
        // OpenSim takes the chord itself: the short arc.
        ccw = span_of(true) <= span_of(false);
    } else if constrained && chord >= 2.0 * OPENSIM_SEGMENT {
        // The arc doubles back if it leaves T1 towards P or arrives at T2 from S's side.
        let span = span_of(ccw);
        let tau1 = tangent_at(ccw, 0.0);
        let tau2 = tangent_at(ccw, span);
        if (pv - t1v).dot(&tau1) > 0.0 || (sv - t2v).dot(&tau2) < 0.0 {
            ccw = !ccw;
        }
    }
    if !ccw {
        w2 = -w2;
    }
    let r2 = (t2 - xc).mul_diag(&e.inv_a2);
    let mut span = r2.dot(&w2).atan2(r2.dot(&w1));
    if span.val() < -1e-6 {
        span = span + 2.0 * PI;
    }
    let arc = ellipse_arc_length(&w1, &w2, span);
    let length = safe_norm(&(*p - t1)) + arc + safe_norm(&(t2 - *s));
    if !length.val().is_finite() {
        return None;
    }
    Some(EllipsoidWrap {
        t1: t1v,
        t2: t2v,
        t1_t: t1,
        t2_t: t2,
        length,
        surface_length: arc.val(),
        arc: SurfaceArc {
            center: xc.val(),
            w1: w1.val(),
            w2: w2.val(),
            w3: Vec3::zeros(),
            span: span.val(),
        },
    })
}

/// Where OpenSim's tangent solver (`WrapEllipsoid::calcTangentPoint`) lands, started at
/// `guess`: damped Gauss–Newton on the residuals (plane n·x − h, surface Σx²/a² − 1, and
/// the tangency pair ∇·x + d, ∇·q + d with ∇ = 2x/a²), in OpenSim's coordinates scaled by
/// 3/(a + b + c), with its damping, step scaling (1/16, and 1 − cos¹⁰⁰ near q's direction)
/// and line extension. Only used to pick which exact tangent point OpenSim converges to;
/// `None` when q is within OpenSim's band of the surface (it then uses q itself).
fn opensim_tangent_landing(
    e: &Ellipsoid,
    n: &Vec3,
    h: f64,
    q: &Vec3,
    guess: &Vec3,
) -> Option<Vec3> {
    let inv_a2 = Vec3::from(e.inv_a2);
    if (q.component_mul(q).dot(&inv_a2) - 1.0).abs() < ON_SURFACE_LEVEL {
        return None;
    }
    let f = 3.0 / (e.radii[0] + e.radii[1] + e.radii[2]);
    let (q, a2inv) = (q * f, inv_a2 / (f * f));
    let vs4 = -h * f;
    let mut r = guess * f;
    let grad = |r: &Vec3| r.component_mul(&a2inv) * 2.0;
    let mut d1 = -grad(&r).dot(&r);
    let residuals = |r: &Vec3, d1: f64| {
        let g = grad(r);
        nalgebra::Vector4::new(
            n.dot(r) + vs4,
            r.component_mul(r).dot(&a2inv) - 1.0,
            g.dot(r) + d1,
            g.dot(&q) + d1,
        )
    };
    let mut ee = residuals(&r, d1);
    let mut ssq = ee.norm_squared();
    let mut ssqo = ssq;
    let mut alpha = 0.01;
    for _ in 0..LM_MAX_ITER {
        if ssq <= LM_TOLERANCE {
            break;
        }
        // J[i][j] = ∂ee_j/∂θ_i, θ = (x, y, z, d).
        let mut jac = nalgebra::Matrix4::<f64>::zeros();
        for i in 0..3 {
            jac[(i, 0)] = n[i];
            jac[(i, 1)] = 2.0 * r[i] * a2inv[i];
            jac[(i, 2)] = 4.0 * r[i] * a2inv[i];
            jac[(i, 3)] = 2.0 * q[i] * a2inv[i];
        }
        jac[(3, 2)] = 1.0;
        jac[(3, 3)] = 1.0;
        let towards = (q - r).try_normalize(0.0).unwrap_or_else(Vec3::zeros);
        let pcos = towards.dot(&q.try_normalize(0.0).unwrap_or_else(Vec3::zeros));
        let dd = if pcos > 0.1 {
            1.0 - pcos.powi(100)
        } else {
            1.0
        };
        let v = -(jac * ee);
        let mut jj = jac * jac.transpose();
        let diag = jj.diagonal();
        let mut step = nalgebra::Vector4::zeros();
        for _ in 0..LM_MAX_INNER {
            if ssq < ssqo {
                break;
            }
            for i in 0..4 {
                jj[(i, i)] = diag[i] * (1.0 + alpha);
            }
            step = jj
                .try_inverse()
                .map_or(nalgebra::Vector4::zeros(), |inv| inv * v * (dd / 16.0));
            r += step.xyz();
            d1 += step[3];
            ee = residuals(&r, d1);
            ssqo = ssq;
            ssq = ee.norm_squared();
            alpha *= 4.0;
        }
        alpha /= 8.0;
        let mut fakt = 0.5;
        for _ in 0..LM_MAX_INNER {
            if !(ssq <= ssqo) {
                break;
            }
            fakt *= 2.0;
            r += step.xyz() * fakt;
            d1 += step[3] * fakt;
            ee = residuals(&r, d1);
            ssqo = ssq;
            ssq = ee.norm_squared();
        }
        r -= step.xyz() * fakt;
        d1 -= step[3] * fakt;
        ee = residuals(&r, d1);
        ssq = ee.norm_squared();
        ssqo = ssq;
    }
    Some(r / f)
}

/// The two tangent points from `q` (outside, in the plane n·x = h) to the section: the
/// intersection of that plane, q's polar plane (A q)·x = 1 and the ellipsoid. The line
/// x0 + λ·(n × Aq) with x0 = α n + β Aq on both planes, then xᵀAx = 1 in λ.
fn tangent_candidates<T: Real>(e: &Ellipsoid, n: &V3<T>, h: T, q: &V3<T>) -> Option<[V3<T>; 2]> {
    let m = q.mul_diag(&e.inv_a2);
    let dir = n.cross(&m);
    let (nm, mm) = (n.dot(&m), m.dot(&m));
    let det = mm - nm * nm;
    if !(det.val() > 1e-24 * mm.val()) {
        return None;
    }
    let beta = (-(h * nm) + 1.0) / det;
    let alpha = h - beta * nm;
    let x0 = n.scale(alpha) + m.scale(beta);
    let adir = dir.mul_diag(&e.inv_a2);
    let qa = adir.dot(&dir);
    let qb = adir.dot(&x0) * 2.0;
    let qc = x0.mul_diag(&e.inv_a2).dot(&x0) - 1.0;
    let disc = qb * qb - qa * qc * 4.0;
    if disc.val() <= 0.0 {
        // q on the surface (double root): both candidates are q's foot on the section.
        let lam = -qb / (qa * 2.0);
        let t = x0 + dir.scale(lam);
        return Some([t, t]);
    }
    let root = disc.sqrt();
    let la = (-qb + root) / (qa * 2.0);
    let lb = (-qb - root) / (qa * 2.0);
    Some([x0 + dir.scale(la), x0 + dir.scale(lb)])
}

/// |v| with a zero derivative at v = 0.
fn safe_norm<T: Real>(v: &V3<T>) -> T {
    if v.val() == Vec3::zeros() {
        T::cst(0.0)
    } else {
        v.norm()
    }
}

/// OpenSim's fan: the normalised sum of the unit vectors from the chord points
/// X1 + (i/300)·(X2 − X1), i = 1..298, to their closest surface points. On dual numbers the
/// derivative is accumulated as Jacobians with respect to X1 and the chord vector.
fn fan_direction<T: Real>(e: &Ellipsoid, x1: &V3<T>, chord: &V3<T>) -> V3<T> {
    let (x1v, cv) = (x1.val(), chord.val());
    let mut sum = Vec3::zeros();
    let mut jac_x1 = Mat3::zeros();
    let mut jac_chord = Mat3::zeros();
    // Second order: the rates of the two Jacobian sums along δ (each sample's Jacobian
    // differentiated along its own rate Ẋ1 + f·ċhord, on `D1`).
    let (x1_rate, chord_rate) = if T::SECOND {
        (
            Vec3::new(x1.x.value_rate(), x1.y.value_rate(), x1.z.value_rate()),
            Vec3::new(
                chord.x.value_rate(),
                chord.y.value_rate(),
                chord.z.value_rate(),
            ),
        )
    } else {
        (Vec3::zeros(), Vec3::zeros())
    };
    let mut jac_x1_rate = Mat3::zeros();
    let mut jac_chord_rate = Mat3::zeros();
    let mut special = V3::<T>::zero();
    // Warm start: the roots of the previous samples, extrapolated by the quartic through the
    // last five (the root is smooth along the chord away from the medial plane, where it is
    // only a guess anyway). Newton's method then mostly stops after its first step, where it
    // took two from a quadratic extrapolation: compute_paths of the default model 13 % faster.
    let mut roots: [Option<f64>; 5] = [None; 5];
    for i in 1..NUM_FAN_SAMPLES - 1 {
        let f = i as f64 / NUM_FAN_SAMPLES as f64;
        let x = x1v + cv * f;
        let guess = match roots {
            [Some(a), Some(b), Some(c), Some(d), Some(g)] => {
                Some(5.0 * a - 10.0 * b + 10.0 * c - 5.0 * d + g)
            }
            [Some(a), Some(b), Some(c), Some(d), None] => Some(4.0 * a - 6.0 * b + 4.0 * c - d),
            [Some(a), Some(b), Some(c), None, _] => Some(3.0 * a - 3.0 * b + c),
            [Some(a), Some(b), None, _, _] => Some(2.0 * a - b),
            [a, _, _, _, _] => a,
        };
        let sample = if T::SECOND {
            let xdot = x1_rate + chord_rate * f;
            unit_to_closest_with_jacobian_rate(e, &x, &xdot, guess)
        } else {
            unit_to_closest_with_jacobian(e, &x, guess).map(|(u, t, j)| (u, t, j, Mat3::zeros()))
        };
        if let Some((u, t, du_dx, du_dx_rate)) = sample {
            roots = [Some(t), roots[0], roots[1], roots[2], roots[3]];
            sum += u;
            if T::HAS_GRAD {
                // ∂x/∂X1 = I, ∂x/∂chord = f·I.
                jac_x1 += du_dx;
                jac_chord += du_dx * f;
            }
            if T::SECOND {
                jac_x1_rate += du_dx_rate;
                jac_chord_rate += du_dx_rate * f;
            }
        } else {
            // A sample on a coordinate plane: OpenSim's section reduction, on `T`.
            let xt = *x1 + chord.scale_f(f);
            let v = closest(e, &xt, None, None).0 - xt;
            let len = safe_norm(&v);
            if len.val() > 0.0 {
                special = special + v.scale(T::cst(1.0) / len);
            }
        }
    }
    let comp = |j: usize| {
        let mut terms = [(0.0, T::cst(0.0)); 6];
        let mut rates = [0.0; 6];
        for k in 0..3 {
            terms[k] = (jac_x1[(j, k)], x1.at(k));
            terms[3 + k] = (jac_chord[(j, k)], chord.at(k));
            rates[k] = jac_x1_rate[(j, k)];
            rates[3 + k] = jac_chord_rate[(j, k)];
        }
        T::chain_rates(sum[j], &terms, &rates)
    };
    let total = V3::new(comp(0), comp(1), comp(2)) + special;
    let len = safe_norm(&total);
    if len.val() > 0.0 {
        total.scale(T::cst(1.0) / len)
    } else {
        total
    }
}
