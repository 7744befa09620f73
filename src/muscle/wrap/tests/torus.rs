//! Torus: OpenSim's local-cylinder construction checked where it has an independent answer
//! (meridian planes), its no-wrap and forced-wrap rules, and its contact geometry.

use std::f64::consts::TAU;

use super::super::*;
use super::Rng;
use crate::spatial::Vec3;

const TUBE: f64 = 0.02;
const RING: f64 = 0.06;

/// Shortest 2-D path from a to b around the circle (centre c, radius r), on the side the
/// segment passes (the segment crosses the circle).
fn circle_near_wrap(c: [f64; 2], r: f64, a: [f64; 2], b: [f64; 2]) -> f64 {
    let (ax, ay, bx, by) = (a[0] - c[0], a[1] - c[1], b[0] - c[0], b[1] - c[1]);
    let (da, db) = (ax.hypot(ay), bx.hypot(by));
    let delta = (ax * by - ay * bx).abs().atan2(ax * bx + ay * by);
    let theta = delta - (r / da).acos() - (r / db).acos();
    assert!(theta > 0.0, "test segment must cross the circle");
    (da * da - r * r).sqrt() + (db * db - r * r).sqrt() + r * theta
}

fn meridian_point(azimuth: f64, rho: f64, z: f64) -> Vec3 {
    Vec3::new(rho * azimuth.cos(), rho * azimuth.sin(), z)
}

#[test]
fn torus_meridian_wrap_equals_the_tube_cross_section_wrap() {
    let mut rng = Rng::new(31);
    for _ in 0..40 {
        let az = rng.range(0.0, TAU);
        // Through the hole side of the tube: ρ < R at both ends, crossing the tube circle.
        let (r1, z1) = (
            RING - rng.range(0.2, 0.9) * TUBE,
            rng.range(1.5, 4.0) * TUBE,
        );
        let (r2, z2) = (
            RING - rng.range(0.2, 0.9) * TUBE,
            -rng.range(1.5, 4.0) * TUBE,
        );
        let (p, s) = (meridian_point(az, r1, z1), meridian_point(az, r2, z2));
        let w = wrap_torus(TUBE, RING, Quadrant::All, &p, &s)
            .wrapped()
            .unwrap_or_else(|| panic!("crosses the tube {az} {r1} {z1} {r2} {z2}"));
        let reference = circle_near_wrap([RING, 0.0], TUBE, [r1, z1], [r2, z2]);
        assert!(
            (w.length - reference).abs() < 1e-14,
            "{} vs {reference}",
            w.length
        );
        for t in [w.t1, w.t2, w.arc.point(0.5)] {
            let on_torus = (t.xy().norm() - RING).powi(2) + t.z * t.z - TUBE * TUBE;
            assert!(
                on_torus.abs() < 1e-15,
                "meridian path leaves the torus: {on_torus}"
            );
            assert!(t.xy().norm() < RING, "wraps the inner side of the tube");
        }
    }
}

#[test]
fn torus_contacts_lie_on_the_local_cylinder_and_are_tangent() {
    let mut rng = Rng::new(32);
    let mut count = 0;
    for _ in 0..400 {
        let p = Vec3::new(
            rng.range(-0.05, 0.05),
            rng.range(-0.05, 0.05),
            rng.range(0.03, 0.1),
        );
        let s = Vec3::new(
            rng.range(-0.05, 0.05),
            rng.range(-0.05, 0.05),
            -rng.range(0.03, 0.1),
        );
        let Some(w) = wrap_torus(TUBE, RING, Quadrant::All, &p, &s).wrapped() else {
            continue;
        };
        count += 1;
        assert!(w.length >= (p - s).norm());
        if w.arc.w3.norm() < 1e-9 {
            continue;
        }
        // The helix axis: through arc.center along w3.
        let axis = w.arc.w3.normalize();
        let dist = |x: &Vec3| (x - w.arc.center - axis * axis.dot(&(x - w.arc.center))).norm();
        for (q, t) in [(p, w.t1), (s, w.t2)] {
            assert!(
                (dist(&t) - TUBE).abs() < 1e-14,
                "contact off the local cylinder"
            );
            let radial = t - w.arc.center - axis * axis.dot(&(t - w.arc.center));
            assert!(
                (q - t).normalize().dot(&radial.normalize()).abs() < 1e-10,
                "not tangent"
            );
        }
        // The local cylinder is tangent to the ring: its axis lies in z = 0 at distance R.
        assert!(w.arc.center.z.abs() < 1e-15 && axis.z.abs() < 1e-15);
        let foot = w.arc.center - axis * axis.dot(&w.arc.center);
        assert!(
            (foot.norm() - RING).abs() < 1e-14 && foot.z.abs() < 1e-15,
            "axis not tangent to the ring"
        );
    }
    assert!(count > 50, "{count} wraps");
}

#[test]
fn torus_wrap_conditions_follow_opensim() {
    // A line through the hole clear of the tube: both points active, no crossing, no wrap.
    let p = Vec3::new(0.01, 0.005, 0.1);
    let s = Vec3::new(0.012, -0.004, -0.1);
    assert!(
        wrap_torus(TUBE, RING, Quadrant::All, &p, &s)
            .wrapped()
            .is_none()
    );
    // Through the tube: wraps; a quadrant with the line's nearest point on the other side
    // prevents it.
    let p = Vec3::new(0.045, 0.002, 0.1);
    let s = Vec3::new(0.046, -0.003, -0.1);
    assert!(
        wrap_torus(TUBE, RING, Quadrant::All, &p, &s)
            .wrapped()
            .is_some()
    );
    assert!(
        wrap_torus(TUBE, RING, Quadrant::Positive(0), &p, &s)
            .wrapped()
            .is_some()
    );
    assert!(
        wrap_torus(TUBE, RING, Quadrant::Negative(0), &p, &s)
            .wrapped()
            .is_none()
    );
    // Both points beyond the ring (inactive for the local cylinder's "+x"): OpenSim forces
    // the wrap round the tube's inner side.
    let p = Vec3::new(0.1, 0.0, 0.05);
    let s = Vec3::new(0.1, 0.01, -0.05);
    let forced = wrap_torus(TUBE, RING, Quadrant::All, &p, &s)
        .wrapped()
        .expect("OpenSim's forced wrap");
    assert!(forced.arc.point(0.5).xy().norm() < RING - 0.9 * TUBE);
}
