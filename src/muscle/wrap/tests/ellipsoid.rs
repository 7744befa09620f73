//! Ellipsoid: agreement with the sphere, tangency, each method's wrap plane against an
//! independent construction of its c1, quadrants, and evidence that it is not a shortest
//! path.

use std::f64::consts::TAU;

use super::super::closest::Ellipsoid;
use super::super::ellipsoid::planar_wrap;
use super::super::real::V3;
use super::super::*;
use super::{Rng, perpendicular, scan_min};
use crate::spatial::Vec3;

const METHODS: [EllipsoidMethod; 3] = [
    EllipsoidMethod::Hybrid,
    EllipsoidMethod::Midpoint,
    EllipsoidMethod::Axial,
];

/// A segment crossing the ellipsoid: one crossing the unit sphere, scaled by the radii.
fn crossing_segment(rng: &mut Rng, radii: &Vec3) -> (Vec3, Vec3) {
    loop {
        let u = rng.unit();
        let w = perpendicular(&u);
        let tilt = rng.range(0.0, TAU);
        let w = w * tilt.cos() + u.cross(&w) * tilt.sin();
        let off = w * rng.range(0.0, 0.95);
        let p = (off - u * rng.range(1.2, 4.0)).component_mul(radii);
        let s = (off + u * rng.range(1.2, 4.0)).component_mul(radii);
        if p.normalize().dot(&s.normalize()) < 0.99 {
            return (p, s);
        }
    }
}

fn level(radii: &Vec3, x: &Vec3) -> f64 {
    x.component_div(radii).norm_squared() - 1.0
}

/// Reference closest point on the ellipsoid (or ellipse: radii of length 2) by bisection on
/// the largest root t of Σ (a_j x_j / (a_j² + t))² = 1.
fn closest_ref(radii: &[f64], x: &[f64]) -> Vec<f64> {
    let a2: Vec<f64> = radii.iter().map(|a| a * a).collect();
    let f = |t: f64| {
        a2.iter()
            .zip(x)
            .map(|(a2, x)| a2 * x * x / ((a2 + t) * (a2 + t)))
            .sum::<f64>()
    };
    let mut lo = -a2.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut hi = 1.0;
    while f(hi) > 1.0 {
        hi *= 2.0;
    }
    for _ in 0..400 {
        let mid = 0.5 * (lo + hi);
        if mid == lo || mid == hi {
            break;
        }
        if f(mid) > 1.0 { lo = mid } else { hi = mid }
    }
    let t = 0.5 * (lo + hi);
    a2.iter().zip(x).map(|(a2, x)| a2 * x / (a2 + t)).collect()
}

fn closest3(radii: &Vec3, x: &Vec3) -> Vec3 {
    let c = closest_ref(radii.as_slice(), x.as_slice());
    Vec3::new(c[0], c[1], c[2])
}

/// Chord crossings X1 (near P) and X2 (near S).
fn chord(radii: &Vec3, p: &Vec3, s: &Vec3) -> (Vec3, Vec3) {
    let d = (p - s).component_div(radii);
    let q = s.component_div(radii);
    let (a, b, c) = (d.norm_squared(), 2.0 * d.dot(&q), q.norm_squared() - 1.0);
    let root = (b * b - 4.0 * a * c).sqrt();
    let (l1, l2) = ((-b + root) / (2.0 * a), (-b - root) / (2.0 * a));
    (s + (p - s) * l1, s + (p - s) * l2)
}

/// The axial (Frans) c1: the chord point on the plane of the chord's most aligned axis, and
/// its closest point on that section. Returns (c1, chord fraction, alignment).
fn frans_c1(radii: &Vec3, p: &Vec3, s: &Vec3) -> (Vec3, f64, f64) {
    let (x1, x2) = chord(radii, p, s);
    let u = (p - s).normalize().abs();
    let k = u.imax();
    let t = -x1[k] / (x2 - x1)[k];
    let sv = x1 + (x2 - x1) * t;
    let (j, l) = ((k + 1) % 3, (k + 2) % 3);
    let c = closest_ref(&[radii[j], radii[l]], &[sv[j], sv[l]]);
    let mut c1 = Vec3::zeros();
    c1[j] = c[0];
    c1[l] = c[1];
    (c1, t, u[k])
}

/// The fan c1 (OpenSim's 298 samples), with the reference closest point.
fn fan_c1(radii: &Vec3, p: &Vec3, s: &Vec3) -> Vec3 {
    let (x1, x2) = chord(radii, p, s);
    let mut sum = Vec3::zeros();
    for i in 1..299 {
        let x = x1 + (x2 - x1) * (i as f64 / 300.0);
        sum += (closest3(radii, &x) - x).normalize();
    }
    let mid = (x1 + x2) * 0.5;
    closest3(radii, &(mid + sum.normalize() * radii.sum() / 3.0))
}

/// Distance of c from the plane through P, S and T1, relative to the configuration's size.
fn off_plane(w: &Wrapped, p: &Vec3, s: &Vec3, c: &Vec3) -> f64 {
    let n = (s - p).cross(&(w.t1 - p)).normalize();
    n.dot(&(c - p)).abs() / (s - p).norm()
}

#[test]
fn ellipsoid_with_equal_radii_reproduces_the_sphere() {
    let r = 0.04;
    let radii = Vec3::new(r, r, r);
    let mut rng = Rng::new(21);
    for _ in 0..60 {
        let (p, s) = crossing_segment(&mut rng, &radii);
        let sphere = wrap_sphere(r, Quadrant::All, &p, &s).wrapped().unwrap();
        for m in METHODS {
            let w = wrap_ellipsoid(&radii, Quadrant::All, m, &p, &s)
                .wrapped()
                .unwrap_or_else(|| panic!("{m:?} wraps"));
            assert!(
                (w.length - sphere.length).abs() < 1e-13,
                "{m:?}: {} vs {}",
                w.length,
                sphere.length
            );
            assert!(
                (w.t1 - sphere.t1).norm() < 1e-10 && (w.t2 - sphere.t2).norm() < 1e-10,
                "{m:?}"
            );
            assert!(
                (w.dlength_dp - sphere.dlength_dp).norm() < 1e-8,
                "{m:?}: {} vs {}",
                w.dlength_dp,
                sphere.dlength_dp
            );
            assert!((w.dlength_ds - sphere.dlength_ds).norm() < 1e-8, "{m:?}");
        }
    }
}

#[test]
fn ellipsoid_wraps_are_tangent_coplanar_on_the_surface_and_not_shorter_than_straight() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    let mut rng = Rng::new(22);
    let quadrants = [
        Quadrant::All,
        Quadrant::Positive(0),
        Quadrant::Negative(1),
        Quadrant::Positive(2),
    ];
    let mut count = 0;
    for i in 0..300 {
        let (p, s) = crossing_segment(&mut rng, &radii);
        let m = METHODS[i % 3];
        let q = quadrants[(i / 3) % 4];
        let Some(w) = wrap_ellipsoid(&radii, q, m, &p, &s).wrapped() else {
            panic!("{m:?} {q:?} must wrap a crossing segment")
        };
        count += 1;
        for (x, t) in [(p, w.t1), (s, w.t2)] {
            assert!(level(&radii, &t).abs() < 1e-12, "contact off the surface");
            let normal = t.component_div(&radii).component_div(&radii).normalize();
            assert!(
                (x - t).normalize().dot(&normal).abs() < 1e-10,
                "not tangent"
            );
        }
        let n = (s - p).cross(&(w.t1 - p)).normalize();
        assert!(
            n.dot(&(w.t2 - p)).abs() < 1e-12,
            "T2 off the plane of P, S, T1"
        );
        assert!(
            n.dot(&(w.arc.point(0.37) - p)).abs() < 1e-12,
            "arc off the plane"
        );
        assert!(
            level(&radii, &w.arc.point(0.37)).abs() < 1e-12,
            "arc off the surface"
        );
        // Unconstrained, the arc leaves T1 along T1 − P and arrives at T2 along S − T2. (With a
        // quadrant OpenSim's own construction can kink: its tangent solve may land on the
        // far side of the line PS for one end only.)
        let eps = 1e-6;
        if q == Quadrant::All {
            assert!(
                (w.arc.point(eps) - w.t1).dot(&(w.t1 - p)) > 0.0,
                "{m:?}: arc doubles back at T1"
            );
            assert!(
                (s - w.t2).dot(&(w.t2 - w.arc.point(1.0 - eps))) > 0.0,
                "{m:?}: arc doubles back at T2"
            );
        }
        let parts = (p - w.t1).norm() + w.surface_length + (w.t2 - s).norm();
        assert!((parts - w.length).abs() < 1e-14);
        assert!(w.length >= (p - s).norm());
    }
    assert_eq!(count, 300);
}

#[test]
fn ellipsoid_arc_length_matches_a_refined_polyline_of_the_section() {
    let radii = Vec3::new(0.08, 0.015, 0.04);
    let mut rng = Rng::new(23);
    for i in 0..30 {
        let (p, s) = crossing_segment(&mut rng, &radii);
        let w = wrap_ellipsoid(
            &radii,
            [Quadrant::All, Quadrant::Negative(0)][i % 2],
            METHODS[i % 3],
            &p,
            &s,
        )
        .wrapped()
        .unwrap();
        let polyline = |n: usize| {
            (0..n)
                .map(|k| {
                    (w.arc.point((k + 1) as f64 / n as f64) - w.arc.point(k as f64 / n as f64))
                        .norm()
                })
                .sum::<f64>()
        };
        // Richardson extrapolation of the O(h²) polyline error.
        let (a, b) = (polyline(4000), polyline(8000));
        let reference = b + (b - a) / 3.0;
        assert!(
            (w.surface_length - reference).abs() < 1e-12 * reference.max(1e-3),
            "{} vs {reference}",
            w.surface_length
        );
    }
}

#[test]
fn each_method_puts_the_wrap_plane_through_its_own_c1() {
    let radii = Vec3::new(0.05, 0.03, 0.04);
    let mut rng = Rng::new(24);
    let (mut fan_only, mut frans_only) = (0, 0);
    for _ in 0..60 {
        let (p, s) = crossing_segment(&mut rng, &radii);
        let (x1, x2) = chord(&radii, &p, &s);
        // Midpoint: the closest surface point to the chord midpoint.
        let w = wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Midpoint, &p, &s)
            .wrapped()
            .unwrap();
        let c_mid = closest3(&radii, &((x1 + x2) * 0.5));
        assert!(off_plane(&w, &p, &s, &c_mid) < 1e-11, "midpoint plane");
        // Axial: Frans' point (used when inside the chord).
        let (c_frans, t, mu) = frans_c1(&radii, &p, &s);
        let axial = wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Axial, &p, &s)
            .wrapped()
            .unwrap();
        if t > 0.0 && t < 1.0 {
            assert!(off_plane(&axial, &p, &s, &c_frans) < 1e-11, "axial plane");
        }
        // Hybrid: Frans alone when well aligned away from the chord ends, the fan alone when
        // poorly aligned.
        let hybrid = wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Hybrid, &p, &s)
            .wrapped()
            .unwrap();
        if mu >= 0.9 && (0.3..=0.7).contains(&t) {
            frans_only += 1;
            assert_eq!(hybrid, axial);
        } else if mu < 0.7073 {
            fan_only += 1;
            assert!(
                off_plane(&hybrid, &p, &s, &fan_c1(&radii, &p, &s)) < 1e-11,
                "fan plane"
            );
        }
    }
    assert!(
        fan_only >= 10 && frans_only >= 3,
        "cases: fan {fan_only}, Frans {frans_only}"
    );
}

#[test]
fn ellipsoid_quadrant_moves_the_wrap_to_the_active_side() {
    let radii = Vec3::new(0.05, 0.03, 0.04);
    // The chord passes below the centre (y < 0): the free wrap goes over −y.
    let p = Vec3::new(-0.12, -0.012, 0.01);
    let s = Vec3::new(0.11, -0.008, -0.012);
    for m in METHODS {
        let free = wrap_ellipsoid(&radii, Quadrant::All, m, &p, &s)
            .wrapped()
            .unwrap();
        assert!(free.arc.point(0.5).y < 0.0, "{m:?}");
        assert_eq!(
            wrap_ellipsoid(&radii, Quadrant::Negative(1), m, &p, &s)
                .wrapped()
                .unwrap(),
            free,
            "{m:?}"
        );
        let up = wrap_ellipsoid(&radii, Quadrant::Positive(1), m, &p, &s)
            .wrapped()
            .unwrap();
        assert!(
            up.arc.point(0.5).y > 0.0 && up.t1.y > 0.0 && up.t2.y > 0.0,
            "{m:?}: {up:?}"
        );
        assert!(up.length > free.length, "{m:?}");
    }
}

#[test]
fn ellipsoid_does_not_wrap_misses_short_segments_inside_points_or_same_directions() {
    let radii = Vec3::new(0.05, 0.03, 0.04);
    let cases = [
        (Vec3::new(-0.2, 0.035, 0.0), Vec3::new(0.2, 0.032, 0.0)), // misses
        (Vec3::new(-0.2, 0.0, 0.0), Vec3::new(-0.06, 0.001, 0.0)), // stops short
        (Vec3::new(-0.2, 0.0, 0.0), Vec3::new(0.04, 0.001, 0.0)),  // ends inside
        (Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.2, 0.0005, 0.0)),   // same direction
    ];
    for (p, s) in cases {
        for m in METHODS {
            for q in [Quadrant::All, Quadrant::Negative(1)] {
                assert!(
                    wrap_ellipsoid(&radii, q, m, &p, &s).wrapped().is_none(),
                    "{p:?} {s:?} {m:?} {q:?}"
                );
            }
        }
    }
}

#[test]
fn ellipsoid_wrap_is_not_a_shortest_path() {
    // The best plane through P and S gives a shorter planar path than OpenSim's, and the
    // true geodesic is shorter still; for a sphere the two coincide.
    let cases = [
        (Vec3::new(0.06, 0.02, 0.035), 1e-6),
        (Vec3::new(0.04, 0.04, 0.04), -1.0),
    ];
    for (radii, margin) in cases {
        let e = Ellipsoid::new([radii.x, radii.y, radii.z]);
        let p = Vec3::new(-0.11, 0.015, 0.06);
        let s = Vec3::new(0.09, -0.01, -0.05);
        let opensim = wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Hybrid, &p, &s)
            .wrapped()
            .unwrap();
        let mid = (p + s) * 0.5;
        let u = (s - p).normalize();
        let (e1, e2) = (perpendicular(&u), u.cross(&perpendicular(&u)));
        let planar = |psi: f64| {
            let c1 = mid + (e1 * psi.cos() + e2 * psi.sin()) * 0.01;
            planar_wrap::<f64>(
                &e,
                &V3::cst(&p),
                &V3::cst(&s),
                &V3::cst(&c1),
                (c1, c1),
                false,
            )
            .map_or(f64::INFINITY, |w| w.length)
        };
        let (_, best) = scan_min(planar, 0.0, TAU, 720);
        assert!(
            best <= opensim.length + 1e-13,
            "the best plane is never worse"
        );
        if margin > 0.0 {
            assert!(
                opensim.length - best > margin * opensim.length,
                "{} vs best plane {best}",
                opensim.length
            );
        } else {
            assert!(
                (opensim.length - best).abs() < 1e-12,
                "sphere: {} vs {best}",
                opensim.length
            );
        }
    }
}
