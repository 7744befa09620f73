//! The numerical building blocks: elliptic integrals and closest points.

use super::super::closest::{Ellipsoid, closest, unit_to_closest_with_jacobian};
use super::super::elliptic::{carlson_rd, carlson_rf, elliptic_d_dm, elliptic_e_d};
use super::super::real::V3;
use super::Rng;
use crate::spatial::Vec3;

/// Composite Gauss–Legendre (5 nodes) of f over [a, b] with n panels.
fn quad(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let x = [
        0.0,
        0.538_469_310_105_683_1,
        -0.538_469_310_105_683_1,
        0.906_179_845_938_664,
        -0.906_179_845_938_664,
    ];
    let w = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let h = (b - a) / n as f64;
    let mut sum = 0.0;
    for i in 0..n {
        let c = a + h * (i as f64 + 0.5);
        for k in 0..5 {
            sum += w[k] * f(c + 0.5 * h * x[k]);
        }
    }
    0.5 * h * sum
}

#[test]
fn carlson_integrals_match_their_defining_quadratures() {
    // Over t ∈ [0, ∞) via t = tan²θ: ∫₀^∞ g(t) dt = ∫₀^{π/2} g(tan²θ) 2 tanθ sec²θ dθ.
    let sub = |g: &dyn Fn(f64) -> f64| {
        quad(
            |th: f64| {
                let t = th.tan();
                g(t * t) * 2.0 * t / (th.cos() * th.cos())
            },
            0.0,
            std::f64::consts::FRAC_PI_2,
            4000,
        )
    };
    for (x, y, z) in [
        (1.0, 2.0, 3.0),
        (0.5, 1.0, 1.0),
        (0.0, 0.3, 1.0),
        (2.0, 0.01, 1.0),
        (1.0, 1.0, 1.0),
    ] {
        let rf = 0.5 * sub(&|t| 1.0 / ((t + x) * (t + y) * (t + z)).sqrt());
        let rd = 1.5 * sub(&|t| 1.0 / ((t + z) * ((t + x) * (t + y) * (t + z)).sqrt()));
        assert!(
            (carlson_rf(x, y, z) - rf).abs() < 1e-10 * rf,
            "R_F({x},{y},{z}) {} vs {rf}",
            carlson_rf(x, y, z)
        );
        assert!(
            (carlson_rd(x, y, z) - rd).abs() < 1e-10 * rd,
            "R_D({x},{y},{z}) {} vs {rd}",
            carlson_rd(x, y, z)
        );
    }
    assert!((carlson_rf(2.0, 2.0, 2.0) - 2f64.powf(-0.5)).abs() < 1e-15);
    assert!((carlson_rd(2.0, 2.0, 2.0) - 2f64.powf(-1.5)).abs() < 1e-15);
}

#[test]
fn incomplete_elliptic_integrals_match_quadrature_for_any_angle() {
    for m in [0.0, 1e-9, 0.3, 0.9, 0.999] {
        for phi in [0.0, 0.4, -1.2, 1.57, 1.58, 2.0, -3.5, 7.0, 12.9] {
            let e_ref = quad(|t: f64| (1.0 - m * t.sin().powi(2)).sqrt(), 0.0, phi, 2000);
            let d_ref = quad(
                |t: f64| t.sin().powi(2) / (1.0 - m * t.sin().powi(2)).sqrt(),
                0.0,
                phi,
                2000,
            );
            let (e, d) = elliptic_e_d(phi, m);
            assert!(
                (e - e_ref).abs() < 1e-12 * (1.0 + e_ref.abs()),
                "E({phi}|{m}) {e} vs {e_ref}"
            );
            assert!(
                (d - d_ref).abs() < 1e-11 * (1.0 + d_ref.abs()),
                "D({phi}|{m}) {d} vs {d_ref}"
            );
        }
    }
}

#[test]
fn closest_point_is_the_nearest_surface_point() {
    let e = Ellipsoid::new([0.05, 0.02, 0.035]);
    let mut rng = Rng::new(7);
    for _ in 0..200 {
        let x = Vec3::new(
            rng.range(-0.08, 0.08),
            rng.range(-0.05, 0.05),
            rng.range(-0.06, 0.06),
        );
        let (c, _) = closest::<f64>(&e, &V3::cst(&x), None, None);
        let c = c.val();
        assert!(e.level(&c).abs() < 1e-13, "on surface");
        let dist = (x - c).norm();
        // Brute force over a fine (θ, φ) grid refined locally.
        let surf = |th: f64, ph: f64| {
            Vec3::new(
                0.05 * th.sin() * ph.cos(),
                0.02 * th.sin() * ph.sin(),
                0.035 * th.cos(),
            )
        };
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for i in 0..=200 {
            for j in 0..400 {
                let (th, ph) = (
                    std::f64::consts::PI * i as f64 / 200.0,
                    std::f64::consts::TAU * j as f64 / 400.0,
                );
                let dd = (surf(th, ph) - x).norm();
                if dd < best.0 {
                    best = (dd, th, ph);
                }
            }
        }
        let mut h = 0.02;
        for _ in 0..60 {
            for (dt, dp) in [(h, 0.0), (-h, 0.0), (0.0, h), (0.0, -h)] {
                let dd = (surf(best.1 + dt, best.2 + dp) - x).norm();
                if dd < best.0 {
                    best = (dd, best.1 + dt, best.2 + dp);
                }
            }
            h *= 0.7;
        }
        assert!(
            dist <= best.0 + 1e-12,
            "closest {dist} but surface point at {}",
            best.0
        );
        assert!(
            dist >= best.0 - 1e-9,
            "brute force {} beats {dist}?",
            best.0
        );
    }
}

#[test]
fn unit_vector_to_closest_point_and_its_jacobian_match_central_differences() {
    let e = Ellipsoid::new([0.05, 0.02, 0.035]);
    let mut rng = Rng::new(11);
    for _ in 0..100 {
        let x = Vec3::new(
            rng.range(-0.04, 0.04),
            rng.range(-0.015, 0.015),
            rng.range(-0.03, 0.03),
        );
        let (u, _, jac) = unit_to_closest_with_jacobian(&e, &x, None).expect("general point");
        let c = closest::<f64>(&e, &V3::cst(&x), None, None).0.val();
        assert!((u - (c - x).normalize()).norm() < 1e-13);
        let h = 1e-7;
        for k in 0..3 {
            let d = Vec3::ith(k, h);
            let up = unit_to_closest_with_jacobian(&e, &(x + d), Some(0.0))
                .unwrap()
                .0;
            let um = unit_to_closest_with_jacobian(&e, &(x - d), None).unwrap().0;
            let fd = (up - um) / (2.0 * h);
            assert!(
                (fd - jac.column(k)).norm() < 1e-5 * (1.0 + fd.norm()),
                "column {k}: {fd} vs {}",
                jac.column(k)
            );
        }
    }
}

/// ∂D(φ|m)/∂m = ½ ∫₀^φ sin⁴θ (1 − m sin²θ)^(−3/2) dθ, on both sides of the switch from the
/// closed form to the series at m = 10⁻³.
#[test]
fn derivative_of_the_d_integral_in_m_matches_quadrature() {
    for m in [0.0, 1e-9, 1e-4, 9.99e-4, 1e-3, 0.01, 0.3, 0.9, 0.99] {
        for phi in [0.0, 0.4, -1.2, 1.57, 2.0, -3.5, 7.0] {
            let reference = quad(
                |t: f64| 0.5 * t.sin().powi(4) / (1.0 - m * t.sin().powi(2)).powf(1.5),
                0.0,
                phi,
                4000,
            );
            let (e, d) = elliptic_e_d(phi, m);
            let delta = (1.0 - m * phi.sin().powi(2)).sqrt();
            let got = elliptic_d_dm(phi, m, e, d, delta);
            assert!(
                (got - reference).abs() < 1e-10 * (1.0 + reference.abs()),
                "∂D/∂m({phi}|{m}) = {got}, quadrature {reference}"
            );
        }
    }
}
