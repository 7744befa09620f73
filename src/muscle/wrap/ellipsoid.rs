//! Ellipsoid wrapping, as OpenSim's `WrapEllipsoid::wrapLine` defines it.

use std::f64::consts::PI;

use super::closest::{
    Ellipsoid, auto_plane, closest, unit_to_closest_with_jacobian,
    unit_to_closest_with_jacobian_rate,
};
use super::elliptic::ellipse_arc_length;
use super::fan_sum;
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
/// A run's interpolatory sum of one degree is accepted when the sum of half that degree
/// (from every second node) differs from it by at most this per sample in the unit
/// vectors, and by at most [`FAN_JACOBIAN_TOLERANCE`] of the Jacobians' size: the coarser
/// sum is then that close, and the accepted one far closer still (on the HumanML3D clip's
/// ~1,200 fan sums, within 1e-11 of the sample-by-sample sum, relative).
const FAN_SUM_TOLERANCE: f64 = 1e-7;
/// See [`FAN_SUM_TOLERANCE`]; relative to Σ_k |W_k| ‖∂u/∂x(node k)‖.
const FAN_JACOBIAN_TOLERANCE: f64 = 1e-6;
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
/// true), so without a fan c1 is only mirrored: reproduced. (4) The fan's 298 unit vectors
/// are summed, where the chord allows, from 17 or 33 of them by polynomial interpolation
/// along each side of the medial plane (within ~1e-11 of the plain sum, relative; checked
/// per run, and summed sample by sample where the check fails).
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
///
/// The samples are summed by interpolation where that reproduces their sum to ~1e-11
/// relative ([`fan_by_interpolation`]), otherwise one by one.
fn fan_direction<T: Real>(e: &Ellipsoid, x1: &V3<T>, chord: &V3<T>) -> V3<T> {
    // Second order: the rates of the two Jacobian sums along δ (each sample's Jacobian
    // differentiated along its own rate Ẋ1 + f·ċhord, on `D1`).
    let rates = if T::SECOND {
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
    let fan = FanLine {
        e,
        x1: x1.val(),
        chord: chord.val(),
        x1_rate: rates.0,
        chord_rate: rates.1,
    };
    let (sums, special) = match fan_by_interpolation::<T>(&fan) {
        Some(sums) => (sums, V3::<T>::zero()),
        None => fan_by_samples(&fan, x1, chord),
    };
    let FanSums {
        sum,
        jac_x1,
        jac_chord,
        jac_x1_rate,
        jac_chord_rate,
    } = sums;
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

/// The fan's chord, in the ellipsoid's frame, with its rates for the second order.
struct FanLine<'a> {
    e: &'a Ellipsoid,
    x1: Vec3,
    chord: Vec3,
    x1_rate: Vec3,
    chord_rate: Vec3,
}

/// Weighted sums of the fan's unit vectors and of their Jacobians with respect to X1 and
/// the chord vector (∂x/∂X1 = I, ∂x/∂chord = f·I), with the Jacobians' rates on the second
/// order.
#[derive(Default)]
struct FanSums {
    sum: Vec3,
    jac_x1: Mat3,
    jac_chord: Mat3,
    jac_x1_rate: Mat3,
    jac_chord_rate: Mat3,
}

/// One fan sample: (u, root, ∂u/∂x, rate of ∂u/∂x).
type FanSample = (Vec3, f64, Mat3, Mat3);

impl FanLine<'_> {
    /// dt/df of the closest-point root t along the chord at fraction f, by the implicit
    /// function theorem on G(t; x) = Σ a_j² x_j² q_j² − 1, q_j = 1/(a_j² + t):
    /// dt/df = −(∂G/∂x · chord)/G′(t), ∂G/∂x_j = 2 a_j² x_j q_j², G′ = −2 Σ a_j² x_j² q_j³.
    fn root_slope(&self, f: f64, t: f64) -> f64 {
        let x = self.x1 + self.chord * f;
        let (mut dg_df, mut dg_dt) = (0.0, 0.0);
        for j in 0..3 {
            let q = 1.0 / (self.e.a2[j] + t);
            let term = self.e.a2[j] * x[j] * q * q;
            dg_df += 2.0 * term * self.chord[j];
            dg_dt -= 2.0 * term * x[j] * q;
        }
        if dg_dt != 0.0 && dg_dt.is_finite() {
            -dg_df / dg_dt
        } else {
            0.0
        }
    }

    /// The sample at chord fraction f (None on a coordinate plane, where OpenSim reduces
    /// the closest-point problem to the section), its root started from `guess`.
    fn sample<T: Real>(&self, f: f64, guess: Option<f64>) -> Option<FanSample> {
        let x = self.x1 + self.chord * f;
        if T::SECOND {
            let xdot = self.x1_rate + self.chord_rate * f;
            unit_to_closest_with_jacobian_rate(self.e, &x, &xdot, guess)
        } else {
            unit_to_closest_with_jacobian(self.e, &x, guess)
                .map(|(u, t, j)| (u, t, j, Mat3::zeros()))
        }
    }
}

impl FanSums {
    fn merge(&mut self, other: &FanSums) {
        self.sum += other.sum;
        self.jac_x1 += other.jac_x1;
        self.jac_chord += other.jac_chord;
        self.jac_x1_rate += other.jac_x1_rate;
        self.jac_chord_rate += other.jac_chord_rate;
    }

    /// Adds `weight` times the sample at chord fraction f.
    fn add<T: Real>(&mut self, weight: f64, f: f64, sample: &FanSample) {
        let (u, _, du_dx, du_dx_rate) = sample;
        self.sum += u * weight;
        if T::HAS_GRAD {
            self.jac_x1 += du_dx * weight;
            self.jac_chord += du_dx * (weight * f);
        }
        if T::SECOND {
            self.jac_x1_rate += du_dx_rate * weight;
            self.jac_chord_rate += du_dx_rate * (weight * f);
        }
    }
}

/// The roots of the last five consecutive fan samples, for the next one's warm start: their
/// extrapolation by the quartic through them (the root is smooth along the chord away from
/// the medial plane, where it is only a guess anyway). Newton's method then mostly stops
/// after its first step, where it took two from a quadratic extrapolation: compute_paths of
/// the default model 13 % faster.
#[derive(Default)]
struct SampleRoots([Option<f64>; 5]);

impl SampleRoots {
    fn guess(&self) -> Option<f64> {
        match self.0 {
            [Some(a), Some(b), Some(c), Some(d), Some(g)] => {
                Some(5.0 * a - 10.0 * b + 10.0 * c - 5.0 * d + g)
            }
            [Some(a), Some(b), Some(c), Some(d), None] => Some(4.0 * a - 6.0 * b + 4.0 * c - d),
            [Some(a), Some(b), Some(c), None, _] => Some(3.0 * a - 3.0 * b + c),
            [Some(a), Some(b), None, _, _] => Some(2.0 * a - b),
            [a, _, _, _, _] => a,
        }
    }

    fn push(&mut self, t: f64) {
        let r = &mut self.0;
        *r = [Some(t), r[0], r[1], r[2], r[3]];
    }
}

/// The fan summed sample by sample: the sums and the unit vectors of the samples that lie
/// on a coordinate plane (summed on `T`, by OpenSim's section reduction).
fn fan_by_samples<T: Real>(fan: &FanLine, x1: &V3<T>, chord: &V3<T>) -> (FanSums, V3<T>) {
    let mut sums = FanSums::default();
    let mut special = V3::<T>::zero();
    let mut roots = SampleRoots::default();
    for i in 1..NUM_FAN_SAMPLES - 1 {
        let f = i as f64 / NUM_FAN_SAMPLES as f64;
        if let Some(sample) = fan.sample::<T>(f, roots.guess()) {
            roots.push(sample.1);
            sums.add::<T>(1.0, f, &sample);
        } else {
            // A sample on a coordinate plane: OpenSim's section reduction, on `T`.
            let xt = *x1 + chord.scale_f(f);
            let v = closest(fan.e, &xt, None, None).0 - xt;
            let len = safe_norm(&v);
            if len.val() > 0.0 {
                special = special + v.scale(T::cst(1.0) / len);
            }
        }
    }
    (sums, special)
}

/// The fan's sums by interpolation: the chord's samples split into the run before and the
/// run after its crossing of the plane of the smallest radius (the medial plane, where the
/// closest point may jump from one side to the other), each run summed by [`fan_run`].
/// None, for the caller to sum every sample, when a sample lies on a coordinate plane or
/// when the chord's samples change side more than once (round-off at a grazing crossing).
fn fan_by_interpolation<T: Real>(fan: &FanLine) -> Option<FanSums> {
    let e = fan.e;
    let m = (0..3).min_by(|&i, &j| e.a2[i].total_cmp(&e.a2[j]))?;
    let last = NUM_FAN_SAMPLES - 2;
    let n = NUM_FAN_SAMPLES as f64;
    let x_at = |i: usize| fan.x1 + fan.chord * (i as f64 / n);
    // Samples on a coordinate plane (|x_j| ≤ the round-off OpenSim reduces at) can only lie
    // around the chord's crossing of that plane: those nearby are checked as computed.
    for j in 0..3 {
        let c = fan.chord[j];
        let (from, to) = if c == 0.0 {
            if fan.x1[j].abs() <= e.zero_tol {
                return None;
            }
            continue;
        } else {
            let centre = -fan.x1[j] / c * n;
            let width = e.zero_tol / c.abs() * n;
            (centre - width - 1.0, centre + width + 1.0)
        };
        if !(to >= 1.0 && from <= last as f64) {
            continue;
        }
        let (from, to) = (
            from.max(1.0).ceil() as usize,
            to.min(last as f64).floor() as usize,
        );
        if to >= from + 8 {
            return None;
        }
        if (from..=to).any(|i| auto_plane(e, &x_at(i)).is_some()) {
            return None;
        }
    }
    // The side of the medial plane changes once, after the crossing at f* = −X1_m/chord_m;
    // the samples around it are checked as computed (round-off flips none farther away).
    let side = |i: usize| x_at(i)[m] > 0.0;
    let c = fan.chord[m];
    let crossing = if c == 0.0 {
        f64::INFINITY
    } else {
        -fan.x1[m] / c * n
    };
    let split = if crossing >= 1.0 && crossing < last as f64 {
        let first = crossing.floor() as usize + 1;
        let before = side(1);
        let around = first.saturating_sub(3).max(1)..=(first + 2).min(last);
        if around.clone().any(|i| side(i) != ((i < first) == before)) {
            return None;
        }
        Some(first)
    } else {
        None
    };
    let mut sums = FanSums::default();
    match split {
        Some(i) => {
            fan_run::<T>(fan, 1, i - 1, &mut sums)?;
            fan_run::<T>(fan, i, last, &mut sums)?;
        }
        None => fan_run::<T>(fan, 1, last, &mut sums)?,
    }
    Some(sums)
}

/// Adds the samples lo..=hi (a run on one side of the medial plane) to `sums`: runs shorter
/// than [`fan_sum::MIN_RUN`] sample by sample, longer ones from their Chebyshev–Lobatto
/// interpolant (see `fan_sum`). The sum of degree K/2 is accepted when it agrees with that
/// of degree K/4 (every second node) to [`FAN_SUM_TOLERANCE`] per sample in the unit
/// vectors and to [`FAN_JACOBIAN_TOLERANCE`] in the Jacobians (the finer sum is then far
/// closer still); otherwise, for runs of at least [`fan_sum::MIN_RUN_FINE`], the nodes
/// between are added and the sum of degree K is accepted by the same test against K/2, and
/// if that fails too the run is halved and each half summed the same way (the unit vector
/// is not smooth enough along the whole run, e.g. near the medial plane's rim, where the
/// closest point turns fast); shorter runs are then summed sample by sample. None when a
/// node lies on a coordinate plane.
fn fan_run<T: Real>(fan: &FanLine, lo: usize, hi: usize, sums: &mut FanSums) -> Option<()> {
    let count = hi + 1 - lo;
    let one_by_one = |sums: &mut FanSums| {
        let mut roots = SampleRoots::default();
        for i in lo..=hi {
            let f = i as f64 / NUM_FAN_SAMPLES as f64;
            let sample = fan.sample::<T>(f, roots.guess())?;
            roots.push(sample.1);
            sums.add::<T>(1.0, f, &sample);
        }
        Some(())
    };
    if count < fan_sum::MIN_RUN {
        return one_by_one(sums);
    }
    let weights = fan_sum::sum_weights(count);
    let half = (count - 1) as f64 / 2.0;
    let fraction = |k: usize| {
        (lo as f64 + (1.0 + fan_sum::node(k, fan_sum::DEGREE)) * half) / NUM_FAN_SAMPLES as f64
    };
    // node k of degree K: (f, sample, root slope dt/df)
    let mut nodes: [Option<(f64, FanSample, f64)>; fan_sum::NODES] = [None; fan_sum::NODES];
    // The nodes of K/2 in order, each root started from the quadratic through the last
    // node's root, its slope along the chord and the slope's change since the node before.
    let mut curvature = 0.0;
    for k in (0..fan_sum::NODES).step_by(2) {
        let f = fraction(k);
        let guess = k
            .checked_sub(2)
            .and_then(|p| nodes[p])
            .map(|(f0, s0, slope)| {
                let df = f - f0;
                s0.1 + df * (slope + 0.5 * curvature * df)
            });
        let sample = fan.sample::<T>(f, guess)?;
        let slope = fan.root_slope(f, sample.1);
        if let Some((f0, _, slope0)) = k.checked_sub(2).and_then(|p| nodes[p]) {
            curvature = (slope - slope0) / (f - f0);
        }
        nodes[k] = Some((f, sample, slope));
    }
    let at = |nodes: &[Option<(f64, FanSample, f64)>], k: usize| nodes[k].map(|n| (n.0, n.1));
    let level = |nodes: &[Option<(f64, FanSample, f64)>], step: usize, w: &[f64]| {
        let mut run = FanSums::default();
        for (i, &wk) in w.iter().enumerate() {
            if let Some((f, sample)) = at(nodes, i * step) {
                run.add::<T>(wk, f, &sample);
            }
        }
        run
    };
    let jac_size = |nodes: &[Option<(f64, FanSample, f64)>], step: usize, w: &[f64]| {
        w.iter()
            .enumerate()
            .filter_map(|(i, &wk)| at(nodes, i * step).map(|(_, s)| wk.abs() * s.2.norm()))
            .sum::<f64>()
    };
    let agree = |finer: &FanSums, coarser: &FanSums, size: f64| {
        (finer.sum - coarser.sum).norm() <= FAN_SUM_TOLERANCE * count as f64
            && (!T::HAS_GRAD
                || (finer.jac_x1 - coarser.jac_x1).norm() <= FAN_JACOBIAN_TOLERANCE * size)
    };
    let middle = level(&nodes, 2, &weights.middle);
    let coarse = level(&nodes, 4, &weights.coarse);
    if agree(&middle, &coarse, jac_size(&nodes, 2, &weights.middle)) {
        sums.merge(&middle);
        return Some(());
    }
    if count < fan_sum::MIN_RUN_FINE {
        return one_by_one(sums);
    }
    // The nodes between, each root from the cubic Hermite interpolant of its neighbours.
    for k in (1..fan_sum::NODES).step_by(2) {
        let f = fraction(k);
        let (Some((f0, s0, d0)), Some((f1, s1, d1))) = (nodes[k - 1], nodes[k + 1]) else {
            return None;
        };
        let h = f1 - f0;
        let x = (f - f0) / h;
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * x) * (1.0 - x) * (1.0 - x),
            x * (1.0 - x) * (1.0 - x),
            x * x * (3.0 - 2.0 * x),
            x * x * (x - 1.0),
        );
        let guess = h00 * s0.1 + h10 * h * d0 + h01 * s1.1 + h11 * h * d1;
        let sample = fan.sample::<T>(f, Some(guess))?;
        nodes[k] = Some((f, sample, 0.0));
    }
    let fine = level(&nodes, 1, &weights.fine);
    if agree(&fine, &middle, jac_size(&nodes, 1, &weights.fine)) {
        sums.merge(&fine);
        return Some(());
    }
    let mid = lo + count / 2;
    fan_run::<T>(fan, lo, mid - 1, sums)?;
    fan_run::<T>(fan, mid, hi, sums)
}

#[cfg(test)]
mod fan_sum_tests {
    use super::super::tests::Rng;
    use super::*;

    /// A chord between two random surface points: (X1, X2 − X1).
    fn random_fan(rng: &mut Rng, radii: [f64; 3]) -> (Vec3, Vec3) {
        let r = Vec3::from(radii);
        let x1 = rng.unit().component_mul(&r);
        let x2 = rng.unit().component_mul(&r);
        (x1, x2 - x1)
    }

    /// The interpolatory sums against the sum of every sample (OpenSim's definition; its
    /// values and Jacobians are checked against references in the wrap tests), on first and
    /// second order, over chords of three ellipsoids (one nearly a spheroid, b = c to 1
    /// ulp, as in the default model), most of them crossing the medial plane.
    #[test]
    fn fan_sums_by_interpolation_agree_with_every_sample() {
        let mut rng = Rng::new(31);
        let (mut interpolated, mut crossing, mut total) = (0, 0, 0);
        let (mut worst_value, mut worst_jacobian, mut worst_rate) = (0.0f64, 0.0f64, 0.0f64);
        for radii in [
            [0.05, 0.03, 0.04],
            [0.12, 0.07, 0.06],
            [
                0.022670952105551753,
                0.01813676168462492,
                0.018136761684624917,
            ],
        ] {
            let e = Ellipsoid::new(radii);
            let m = (0..3).min_by(|&i, &j| e.a2[i].total_cmp(&e.a2[j])).unwrap();
            for case in 0..150 {
                let (x1, chord) = random_fan(&mut rng, radii);
                total += 1;
                if x1[m].signum() != (x1 + chord)[m].signum() {
                    crossing += 1;
                }
                let (x1d, chordd) = seed(&x1, &chord);
                let fan = FanLine {
                    e: &e,
                    x1,
                    chord,
                    x1_rate: Vec3::zeros(),
                    chord_rate: Vec3::zeros(),
                };
                let Some(a) = fan_by_interpolation::<D6>(&fan) else {
                    continue;
                };
                interpolated += 1;
                let (b, special) = fan_by_samples::<D6>(&fan, &x1d, &chordd);
                assert_eq!(special.val(), Vec3::zeros());
                let count = (NUM_FAN_SAMPLES - 2) as f64;
                worst_value = worst_value.max((a.sum - b.sum).norm() / count);
                for (ja, jb) in [(a.jac_x1, b.jac_x1), (a.jac_chord, b.jac_chord)] {
                    worst_jacobian = worst_jacobian.max((ja - jb).norm() / jb.norm());
                }
                if case % 10 == 0 {
                    // second order: the Jacobians' rates along a direction
                    let dir = [0.3, -0.2, 0.5, 0.1, 0.4, -0.6];
                    let fan = FanLine {
                        x1_rate: Vec3::new(dir[0], dir[1], dir[2]),
                        chord_rate: Vec3::new(dir[3], dir[4], dir[5]),
                        ..fan
                    };
                    let (x1s, chords) = seed2(&x1, &chord, &dir);
                    let a = fan_by_interpolation::<D6<D1>>(&fan).expect("as on first order");
                    let (b, _) = fan_by_samples::<D6<D1>>(&fan, &x1s, &chords);
                    for (ra, rb) in [
                        (a.jac_x1_rate, b.jac_x1_rate),
                        (a.jac_chord_rate, b.jac_chord_rate),
                    ] {
                        worst_rate = worst_rate.max((ra - rb).norm() / rb.norm());
                    }
                }
            }
        }
        assert!(
            interpolated >= total * 9 / 10 && crossing >= total / 3,
            "{interpolated} of {total} chords summed by interpolation, {crossing} crossing"
        );
        // measured: 9.4e-12, 5.2e-10 and 8.7e-9
        assert!(
            worst_value <= 5e-11,
            "unit vectors: {worst_value:e} per sample"
        );
        assert!(
            worst_jacobian <= 5e-9,
            "Jacobians: {worst_jacobian:e} relative"
        );
        assert!(
            worst_rate <= 1e-7,
            "Jacobian rates: {worst_rate:e} relative"
        );
    }
}
