//! Sphere and cylinder: shortest-path references, tangency, OpenSim's wrap conditions and
//! quadrant rules, continuity at first contact.

use std::f64::consts::{PI, TAU};

use super::super::*;
use super::{Rng, golden_min, perpendicular, scan_min};
use crate::spatial::Vec3;

/// Shortest path P → S in the plane (normal n) around the circle (centre c, radius rho),
/// over both sides; the straight segment if it misses the circle.
fn circle_wrap(c: Vec3, rho: f64, n: Vec3, p: &Vec3, s: &Vec3) -> f64 {
    let (a, b) = (p - c, s - c);
    let (da, db) = (a.norm(), b.norm());
    let ex = a / da;
    let ey = n.cross(&ex);
    let delta = b.dot(&ey).atan2(b.dot(&ex)).abs();
    let beta = (rho / da).acos() + (rho / db).acos();
    if delta <= beta {
        return (p - s).norm();
    }
    let arc = (delta - beta).min(TAU - delta - beta);
    (da * da - rho * rho).sqrt() + (db * db - rho * rho).sqrt() + rho * arc
}

/// Brute force for the sphere: the best, over all planes through the line PS, of the
/// shortest planar path around that plane's section circle.
fn sphere_reference(r: f64, p: &Vec3, s: &Vec3) -> f64 {
    let u = (s - p).normalize();
    let e1 = perpendicular(&u);
    let e2 = u.cross(&e1);
    let planar = |psi: f64| {
        let n = e1 * psi.cos() + e2 * psi.sin();
        let off = n.dot(p);
        let rho2 = r * r - off * off;
        if rho2 <= 0.0 {
            return (p - s).norm();
        }
        circle_wrap(n * off, rho2.sqrt(), n, p, s)
    };
    scan_min(planar, 0.0, PI, 720).1
}

/// Brute force for the cylinder: contact points at the projected tangent angles for the
/// given direction about the axis, their heights found by minimising the path length
/// (straight – helix – straight) numerically.
fn cylinder_reference(r: f64, p: &Vec3, s: &Vec3, sense: f64) -> f64 {
    let (d1, d2) = (p.xy().norm(), s.xy().norm());
    let (phi1, phi2) = (p.y.atan2(p.x), s.y.atan2(s.x));
    let (b1, b2) = ((r / d1).acos(), (r / d2).acos());
    let (a1, a2) = (phi1 + sense * b1, phi2 - sense * b2);
    let theta = (sense * (a2 - a1)).rem_euclid(TAU);
    let t1 = Vec3::new(r * a1.cos(), r * a1.sin(), 0.0);
    let t2 = Vec3::new(r * a2.cos(), r * a2.sin(), 0.0);
    let len = |z1: f64, z2: f64| {
        (p - t1 - Vec3::z() * z1).norm()
            + ((r * theta).powi(2) + (z2 - z1).powi(2)).sqrt()
            + (s - t2 - Vec3::z() * z2).norm()
    };
    let (lo, hi) = (p.z.min(s.z) - 1.0, p.z.max(s.z) + 1.0);
    let inner = |z1: f64| golden_min(|z2| len(z1, z2), lo, hi, 120).1;
    golden_min(inner, lo, hi, 120).1
}

/// A random segment crossing the sphere (`around_axis == false`) or, in projection along z,
/// the cylinder of radius r, with both ends outside.
fn crossing_segment(rng: &mut Rng, r: f64, around_axis: bool) -> (Vec3, Vec3) {
    loop {
        let (u, off) = if around_axis {
            let a = rng.range(0.0, TAU);
            let u = Vec3::new(a.cos(), a.sin(), rng.range(-1.5, 1.5)).normalize();
            let w = Vec3::new(-a.sin(), a.cos(), 0.0);
            (
                u,
                w * rng.range(-0.95, 0.95) * r + Vec3::z() * rng.range(-2.0, 2.0) * r,
            )
        } else {
            let u = rng.unit();
            let w = perpendicular(&u);
            let tilt = rng.range(0.0, TAU);
            let w = w * tilt.cos() + u.cross(&w) * tilt.sin();
            (u, w * rng.range(0.0, 0.95) * r)
        };
        let p = off - u * rng.range(1.2, 4.0) * r;
        let s = off + u * rng.range(1.2, 4.0) * r;
        let outside = |x: &Vec3| {
            if around_axis {
                x.xy().norm() > 1.02 * r
            } else {
                x.norm() > 1.02 * r
            }
        };
        if outside(&p) && outside(&s) {
            return (p, s);
        }
    }
}

#[test]
fn sphere_length_equals_brute_force_minimum_over_wrap_planes() {
    let r = 0.04;
    let mut rng = Rng::new(1);
    for _ in 0..40 {
        let (p, s) = crossing_segment(&mut rng, r, false);
        let w = wrap_sphere(r, Quadrant::All, &p, &s)
            .wrapped()
            .expect("crossing segment wraps");
        let reference = sphere_reference(r, &p, &s);
        assert!(
            (w.length - reference).abs() < 1e-10,
            "{} vs brute force {reference}",
            w.length
        );
        assert!(w.length >= (p - s).norm());
    }
}

#[test]
fn cylinder_length_equals_brute_force_helix_minimum() {
    let r = 0.03;
    let mut rng = Rng::new(2);
    for _ in 0..40 {
        let (p, s) = crossing_segment(&mut rng, r, true);
        let w = wrap_cylinder(r, 10.0, Quadrant::All, &p, &s)
            .wrapped()
            .expect("crossing segment wraps");
        let reference = cylinder_reference(r, &p, &s, 1.0).min(cylinder_reference(r, &p, &s, -1.0));
        assert!(
            (w.length - reference).abs() < 1e-9,
            "{} vs brute force {reference}",
            w.length
        );
    }
}

fn check_tangency(name: &str, w: &Wrapped, p: &Vec3, s: &Vec3, normal: impl Fn(&Vec3) -> Vec3) {
    for (q, t) in [(p, w.t1), (s, w.t2)] {
        let d = q - t;
        if d.norm() > 1e-9 {
            let c = d.normalize().dot(&normal(&t));
            assert!(c.abs() < 1e-12, "{name}: not tangent, cos = {c}");
        }
    }
    let parts = (p - w.t1).norm() + w.surface_length + (w.t2 - s).norm();
    assert!(
        (parts - w.length).abs() < 1e-14,
        "{name}: length is not the sum of its parts"
    );
    assert!(
        w.length >= (p - s).norm() - 1e-15,
        "{name}: shorter than the straight line"
    );
    assert!(w.surface_length >= 0.0);
}

#[test]
fn sphere_and_cylinder_wraps_are_tangent_on_the_surface_and_not_shorter_than_straight() {
    let r = 0.05;
    let mut rng = Rng::new(3);
    let quadrants = [
        Quadrant::All,
        Quadrant::Positive(0),
        Quadrant::Negative(1),
        Quadrant::Positive(2),
    ];
    let mut count = [0; 2];
    for i in 0..400 {
        let q = quadrants[i % 4];
        let p = rng.unit() * rng.range(1.05, 4.0) * r;
        let s = rng.unit() * rng.range(1.05, 4.0) * r;
        if let Some(w) = wrap_sphere(r, q, &p, &s).wrapped() {
            count[0] += 1;
            check_tangency("sphere", &w, &p, &s, |t| t.normalize());
            assert!((w.t1.norm() - r).abs() < 1e-15 && (w.t2.norm() - r).abs() < 1e-15);
            // Envelope theorem: the gradient is the unit vector from the contact point.
            assert!((w.dlength_dp - (p - w.t1).normalize()).norm() < 1e-12);
            assert!((w.dlength_ds - (s - w.t2).normalize()).norm() < 1e-12);
        }
        if let Some(w) = wrap_cylinder(r, 1.0, q, &p, &s).wrapped() {
            count[1] += 1;
            check_tangency("cylinder", &w, &p, &s, |t| {
                Vec3::new(t.x, t.y, 0.0).normalize()
            });
            assert!((w.t1.xy().norm() - r).abs() < 1e-15 && (w.t2.xy().norm() - r).abs() < 1e-15);
            assert!((w.dlength_dp - (p - w.t1).normalize()).norm() < 1e-12);
            assert!((w.dlength_ds - (s - w.t2).normalize()).norm() < 1e-12);
            // The helix makes P–T1–T2–S straight when unrolled: equal slopes.
            let slope = |a: &Vec3, b: &Vec3| (b.z - a.z) / (b - a).xy().norm();
            let helix_slope =
                (w.t2.z - w.t1.z) / (w.surface_length.powi(2) - (w.t2.z - w.t1.z).powi(2)).sqrt();
            if (p - w.t1).xy().norm() > 1e-6 && w.surface_length > 1e-6 {
                assert!(
                    (slope(&p, &w.t1) - helix_slope).abs() < 1e-9,
                    "{} vs {helix_slope}",
                    slope(&p, &w.t1)
                );
            }
        }
    }
    assert!(count[0] > 40 && count[1] > 40, "too few wraps: {count:?}");
}

#[test]
fn no_wrap_when_the_segment_misses_stops_short_or_starts_inside() {
    let r = 0.05;
    let misses = (Vec3::new(-0.2, 0.06, 0.0), Vec3::new(0.2, 0.055, 0.01));
    let short = (Vec3::new(-0.2, 0.0, 0.0), Vec3::new(-0.08, 0.01, 0.0));
    let inside = (Vec3::new(-0.2, 0.0, 0.0), Vec3::new(0.03, 0.01, 0.0));
    for (p, s) in [misses, short, inside] {
        for q in [Quadrant::All, Quadrant::Positive(1), Quadrant::Negative(1)] {
            assert!(
                wrap_sphere(r, q, &p, &s).wrapped().is_none(),
                "sphere {p:?} {s:?} {q:?}"
            );
        }
        assert!(
            wrap_cylinder(r, 1.0, Quadrant::All, &p, &s)
                .wrapped()
                .is_none(),
            "cylinder {p:?} {s:?}"
        );
    }
    // The same segments but crossing: wrap.
    let crossing = (Vec3::new(-0.2, 0.02, 0.0), Vec3::new(0.2, 0.025, 0.01));
    assert!(
        wrap_sphere(r, Quadrant::All, &crossing.0, &crossing.1)
            .wrapped()
            .is_some()
    );
    assert!(
        wrap_cylinder(r, 1.0, Quadrant::All, &crossing.0, &crossing.1)
            .wrapped()
            .is_some()
    );
}

#[test]
fn sphere_quadrant_chooses_the_side_of_the_wrap() {
    let r = 0.03;
    // The line passes on the +y side of the centre, both points at y > 0.
    let p = Vec3::new(-0.1, 0.01, 0.002);
    let s = Vec3::new(0.09, 0.012, -0.003);
    let all = wrap_sphere(r, Quadrant::All, &p, &s).wrapped().unwrap();
    let plus_y = wrap_sphere(r, Quadrant::Positive(1), &p, &s)
        .wrapped()
        .unwrap();
    let minus_y = wrap_sphere(r, Quadrant::Negative(1), &p, &s)
        .wrapped()
        .unwrap();
    // Both points active for +y: the shortest (near) wrap, over +y; OpenSim flags it
    // mandatory only because a quadrant is set.
    assert_eq!(
        Wrapped {
            mandatory: false,
            ..plus_y
        },
        all
    );
    assert!(plus_y.mandatory && !all.mandatory && !minus_y.mandatory);
    assert!(all.arc.point(0.5).y > 0.0);
    // -y: around the other side, over -y, longer, still tangent.
    assert!(
        minus_y.arc.point(0.5).y < -0.9 * r,
        "{:?}",
        minus_y.arc.point(0.5)
    );
    assert!(minus_y.length > all.length);
    check_tangency("far side", &minus_y, &p, &s, |t| t.normalize());
    // The far path has the geometric (positive) arc: 2π − Δ − β1 − β2.
    let delta = p.angle(&s);
    let beta = (r / p.norm()).acos() + (r / s.norm()).acos();
    assert!((minus_y.surface_length - r * (TAU - delta - beta)).abs() < 1e-14);
}

#[test]
fn cylinder_quadrant_forces_prevents_and_redirects_wraps() {
    let r = 1.0;
    let plus_y = Quadrant::Positive(1);
    let minus_y = Quadrant::Negative(1);
    // Line misses (closest approach 1.08 at y < 0); P inactive, S active for +y: forced wrap
    // round the active side, the long way relative to the line.
    let (p, s) = (Vec3::new(-3.0, -3.0, 0.0), Vec3::new(3.0, 0.5, 0.2));
    assert!(
        wrap_cylinder(r, 10.0, Quadrant::All, &p, &s)
            .wrapped()
            .is_none()
    );
    let forced = wrap_cylinder(r, 10.0, plus_y, &p, &s)
        .wrapped()
        .expect("forced wrap");
    assert!(forced.t1.y > 0.0 && forced.t2.y > 0.0 && forced.arc.point(0.5).y > 0.9);
    assert!((forced.length - cylinder_reference(r, &p, &s, -1.0)).abs() < 1e-9);
    // For -y the line's closest point is on the active side: no wrap.
    assert!(wrap_cylinder(r, 10.0, minus_y, &p, &s).wrapped().is_none());
    // Both points inactive: always wraps, round the active side, even when crossing on the
    // inactive side.
    let (p2, s2) = (Vec3::new(-3.0, -0.5, 0.0), Vec3::new(3.0, -0.5, 0.1));
    let near = wrap_cylinder(r, 10.0, Quadrant::All, &p2, &s2)
        .wrapped()
        .unwrap();
    assert!(near.arc.point(0.5).y < 0.0);
    let redirected = wrap_cylinder(r, 10.0, plus_y, &p2, &s2).wrapped().unwrap();
    assert!(redirected.arc.point(0.5).y > 0.9 && redirected.length > near.length);
    assert!((redirected.length - cylinder_reference(r, &p2, &s2, -1.0)).abs() < 1e-9);
    // Both points active and crossing: the ordinary wrap.
    assert_eq!(
        wrap_cylinder(r, 10.0, minus_y, &p2, &s2).wrapped().unwrap(),
        near
    );
    // Both inactive and missing: still forced round the active side (over half a turn).
    let (p3, s3) = (Vec3::new(-3.0, -2.0, 0.0), Vec3::new(3.0, -2.0, 0.0));
    let around = wrap_cylinder(r, 10.0, plus_y, &p3, &s3).wrapped().unwrap();
    assert!(around.arc.point(0.5).y > 0.9);
    assert!((around.length - cylinder_reference(r, &p3, &s3, -1.0)).abs() < 1e-9);
    // Both active and missing: no wrap.
    assert!(
        wrap_cylinder(r, 10.0, minus_y, &p3, &s3)
            .wrapped()
            .is_none()
    );
}

#[test]
fn cylinder_does_not_wrap_beyond_its_ends() {
    let r = 0.02;
    let len = 0.1;
    let at = |z1: f64, z2: f64| (Vec3::new(-0.1, 0.005, z1), Vec3::new(0.1, 0.008, z2));
    let (p, s) = at(0.04, 0.045);
    assert!(
        wrap_cylinder(r, len, Quadrant::All, &p, &s)
            .wrapped()
            .is_some()
    );
    let (p, s) = at(0.06, 0.07);
    assert!(
        wrap_cylinder(r, len, Quadrant::All, &p, &s)
            .wrapped()
            .is_none()
    );
    let (p, s) = at(-0.06, -0.07);
    assert!(
        wrap_cylinder(r, len, Quadrant::All, &p, &s)
            .wrapped()
            .is_none()
    );
    // Sloped: one contact point within the ends is enough.
    let (p, s) = (Vec3::new(-0.025, 0.005, 0.0), Vec3::new(0.1, 0.008, 0.3));
    let w = wrap_cylinder(r, len, Quadrant::All, &p, &s)
        .wrapped()
        .unwrap();
    assert!(w.t1.z.abs() <= 0.05 && w.t2.z.abs() > 0.05);
}

/// Length and gradient of the path, wrapped or straight.
fn effective(w: Option<Wrapped>, p: &Vec3, s: &Vec3) -> (f64, Vec3, Vec3) {
    match w {
        Some(w) => (w.length, w.dlength_dp, w.dlength_ds),
        None => {
            let u = (p - s).normalize();
            ((p - s).norm(), u, -u)
        }
    }
}

#[test]
fn length_and_gradient_are_continuous_as_the_line_first_touches() {
    let r = 0.05;
    let n = 4000;
    let step = 0.02 / n as f64;
    type WrapFn = fn(&Vec3, &Vec3) -> Option<Wrapped>;
    let surfaces: [(&str, WrapFn); 2] = [
        ("sphere", |p, s| {
            wrap_sphere(0.05, Quadrant::All, p, s).wrapped()
        }),
        ("cylinder", |p, s| {
            wrap_cylinder(0.05, 1.0, Quadrant::All, p, s).wrapped()
        }),
    ];
    for (name, wrap) in surfaces {
        let mut prev: Option<(f64, Vec3, Vec3, bool)> = None;
        let (mut transitions, mut max_dl, mut max_dg) = (0, 0.0f64, 0.0f64);
        for i in 0..=n {
            let y = 0.06 - step * i as f64;
            let p = Vec3::new(-0.2, y + 0.01, 0.03);
            let s = Vec3::new(0.2, y - 0.005, -0.02);
            let w = wrap(&p, &s);
            let wrapped = w.is_some();
            let (l, gp, gs) = effective(w, &p, &s);
            if let Some((l0, gp0, gs0, w0)) = prev {
                transitions += (w0 != wrapped) as usize;
                max_dl = max_dl.max((l - l0).abs());
                max_dg = max_dg.max((gp - gp0).norm() + (gs - gs0).norm());
            }
            prev = Some((l, gp, gs, wrapped));
        }
        assert_eq!(transitions, 1, "{name}");
        // |dL/dy| ≤ 2; the gradient is Hölder-½ at first contact (θ ~ √depth).
        assert!(max_dl <= 2.0 * step, "{name}: length jumps by {max_dl}");
        assert!(
            max_dg <= 8.0 * (step / r).sqrt(),
            "{name}: gradient jumps by {max_dg}"
        );
    }
}
