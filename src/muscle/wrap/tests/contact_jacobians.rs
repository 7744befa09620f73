//! The contact points' Jacobians `dt1`, `dt2` against central differences of `t1`, `t2`, for
//! every surface, method and quadrant; and their consistency with the surface.

use nalgebra::Matrix3x6;

use super::super::*;
use super::Rng;
use crate::spatial::Vec3;

type WrapFn = Box<dyn Fn(&Vec3, &Vec3) -> Option<Wrapped>>;
type Jac = Matrix3x6<f64>;

/// Central differences of t1 and t2 with respect to (P, S); `None` if the segment does not
/// wrap somewhere on the stencil.
fn central_jacobians(wrap: &WrapFn, p: &Vec3, s: &Vec3, h: f64) -> Option<(Jac, Jac)> {
    let mut j1 = Jac::zeros();
    let mut j2 = Jac::zeros();
    for k in 0..6 {
        let e = Vec3::ith(k % 3, h);
        let (plus, minus) = if k < 3 {
            (wrap(&(p + e), s)?, wrap(&(p - e), s)?)
        } else {
            (wrap(p, &(s + e))?, wrap(p, &(s - e))?)
        };
        j1.set_column(k, &((plus.t1 - minus.t1) / (2.0 * h)));
        j2.set_column(k, &((plus.t2 - minus.t2) / (2.0 * h)));
    }
    Some((j1, j2))
}

/// Random configurations around an object of size ~`scale`; checks every wrapped one whose
/// contact points are smooth over the difference stencil (the length-gradient tests' rule:
/// central differences with steps h and 2h agree to O(h²)).
fn check(name: &str, wrap: &WrapFn, scale: f64, box_half: Vec3, seed: u64, want: usize) {
    let mut rng = Rng::new(seed);
    let (mut checked, mut skipped, mut tries) = (0, 0, 0);
    let mut worst: f64 = 0.0;
    let h = 1e-6 * scale / 0.05;
    while checked < want && tries < 100 * want {
        tries += 1;
        let rnd = |rng: &mut Rng| {
            Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .component_mul(&box_half)
        };
        let (p, s) = (rnd(&mut rng), rnd(&mut rng));
        let Some(w) = wrap(&p, &s) else { continue };
        let (Some(fd), Some(fd2)) = (
            central_jacobians(wrap, &p, &s, h),
            central_jacobians(wrap, &p, &s, 2.0 * h),
        ) else {
            skipped += 1;
            continue;
        };
        // A jump or kink inside the stencil breaks the O(h²) agreement of the two steps.
        let smooth = (fd.0 - fd2.0).norm() + (fd.1 - fd2.1).norm() < 1e-4;
        if !smooth {
            skipped += 1;
            continue;
        }
        checked += 1;
        // Richardson extrapolation: O(h⁴).
        let rich = ((fd.0 * 4.0 - fd2.0) / 3.0, (fd.1 * 4.0 - fd2.1) / 3.0);
        let size = 1.0 + w.dt1.norm().max(w.dt2.norm());
        let err = (w.dt1 - rich.0).norm().max((w.dt2 - rich.1).norm()) / size;
        worst = worst.max(err);
        assert!(
            err < 1e-8,
            "{name}: contact Jacobian off by {err} (relative) at P = {p:?}, S = {s:?}\n\
             dt1 {}\nvs {}\ndt2 {}\nvs {}",
            w.dt1,
            rich.0,
            w.dt2,
            rich.1
        );
    }
    println!("{name}: {checked} checked, {skipped} skipped, worst relative error {worst:.1e}");
    assert_eq!(
        checked, want,
        "{name}: only {checked} wrapped configurations in {tries} tries"
    );
    assert!(
        skipped * 20 <= checked,
        "{name}: {skipped} non-smooth of {checked}"
    );
}

const QUADRANTS: [Quadrant; 4] = [
    Quadrant::All,
    Quadrant::Positive(0),
    Quadrant::Negative(1),
    Quadrant::Positive(2),
];

const METHODS: [EllipsoidMethod; 3] = [
    EllipsoidMethod::Hybrid,
    EllipsoidMethod::Midpoint,
    EllipsoidMethod::Axial,
];

#[test]
fn sphere_and_cylinder_contact_jacobians_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        let sphere: WrapFn = Box::new(move |p, s| wrap_sphere(0.05, q, p, s).wrapped());
        check(
            &format!("sphere {q:?}"),
            &sphere,
            0.05,
            Vec3::new(0.2, 0.2, 0.2),
            140 + i as u64,
            100,
        );
        let cylinder: WrapFn = Box::new(move |p, s| wrap_cylinder(0.05, 0.3, q, p, s).wrapped());
        check(
            &format!("cylinder {q:?}"),
            &cylinder,
            0.05,
            Vec3::new(0.2, 0.2, 0.2),
            150 + i as u64,
            100,
        );
    }
}

#[test]
fn ellipsoid_contact_jacobians_match_central_differences_for_every_method() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        for (j, m) in METHODS.into_iter().enumerate() {
            let f: WrapFn = Box::new(move |p, s| wrap_ellipsoid(&radii, q, m, p, s).wrapped());
            check(
                &format!("ellipsoid {m:?} {q:?}"),
                &f,
                0.04,
                Vec3::new(0.2, 0.2, 0.2),
                160 + (3 * i + j) as u64,
                60,
            );
        }
    }
}

#[test]
fn torus_contact_jacobians_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        let f: WrapFn = Box::new(move |p, s| wrap_torus(0.02, 0.06, q, p, s).wrapped());
        check(
            &format!("torus {q:?}"),
            &f,
            0.04,
            Vec3::new(0.08, 0.08, 0.12),
            180 + i as u64,
            100,
        );
    }
}

/// The contact points stay on the surface: ∇φ(T)ᵀ·∂T = 0 for the surface's level function
/// φ, to round-off, at every wrapped configuration (including non-smooth ones).
#[test]
fn contact_jacobians_keep_the_contact_points_on_the_surface() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    let inv_a2 = radii.map(|a| 1.0 / (a * a));
    type Normal = fn(&Vec3, &Vec3) -> Vec3;
    let mut cases: Vec<(String, WrapFn, Normal)> = Vec::new();
    for q in QUADRANTS {
        cases.push((
            format!("sphere {q:?}"),
            Box::new(move |p, s| wrap_sphere(0.05, q, p, s).wrapped()),
            |t, _| *t,
        ));
        cases.push((
            format!("cylinder {q:?}"),
            Box::new(move |p, s| wrap_cylinder(0.05, 0.3, q, p, s).wrapped()),
            |t, _| Vec3::new(t.x, t.y, 0.0),
        ));
        for m in METHODS {
            cases.push((
                format!("ellipsoid {m:?} {q:?}"),
                Box::new(move |p, s| wrap_ellipsoid(&radii, q, m, p, s).wrapped()),
                |t, inv_a2| t.component_mul(inv_a2),
            ));
        }
    }
    // P, S and the centre collinear: the sphere's fallback plane (through the line and an
    // axis), whose Jacobian no difference can check (any offset leaves that branch).
    for q in QUADRANTS {
        let (p, s) = (Vec3::new(0.03, 0.1, 0.07), Vec3::new(-0.06, -0.2, -0.14));
        let w = wrap_sphere(0.05, q, &p, &s).wrapped().unwrap();
        for (t, dt) in [(w.t1, w.dt1), (w.t2, w.dt2)] {
            assert!(dt.iter().all(|v| v.is_finite()), "collinear {q:?}: {dt}");
            let off = (t.normalize().transpose() * dt).norm();
            assert!(
                off < 1e-12 * (1.0 + dt.norm()),
                "collinear {q:?}: rate {off}"
            );
        }
    }
    for (i, (name, wrap, normal)) in cases.iter().enumerate() {
        let mut rng = Rng::new(300 + i as u64);
        let mut checked = 0;
        while checked < 200 {
            let p = Vec3::new(
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
            );
            let s = Vec3::new(
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
            );
            let Some(w) = wrap(&p, &s) else { continue };
            checked += 1;
            for (t, dt) in [(w.t1, w.dt1), (w.t2, w.dt2)] {
                let n = normal(&t, &inv_a2).normalize();
                let off = (n.transpose() * dt).norm();
                assert!(
                    off < 1e-12 * (1.0 + dt.norm()),
                    "{name}: contact point leaves the surface at rate {off} \
                     (P = {p:?}, S = {s:?})"
                );
            }
        }
    }
}
