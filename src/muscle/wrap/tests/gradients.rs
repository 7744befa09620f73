//! The gradients against central differences of the length, for every surface and method.

use super::super::*;
use super::{Rng, central_difference};
use crate::spatial::Vec3;

type WrapFn = Box<dyn Fn(&Vec3, &Vec3) -> Option<Wrapped>>;

/// Random configurations around an object of size ~`scale`; checks every wrapped one whose
/// length is smooth over the difference stencil. Returns (checked, skipped as non-smooth).
fn check(name: &str, wrap: &WrapFn, scale: f64, box_half: Vec3, seed: u64, want: usize) {
    let mut rng = Rng::new(seed);
    let length = |p: &Vec3, s: &Vec3| wrap(p, s).map(|w| w.length);
    let (mut checked, mut skipped, mut tries) = (0, 0, 0);
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
            central_difference(&length, &p, &s, h),
            central_difference(&length, &p, &s, 2.0 * h),
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
        // Richardson extrapolation: O(h⁴) (paths near the surface have large third
        // derivatives).
        let rich = ((fd.0 * 4.0 - fd2.0) / 3.0, (fd.1 * 4.0 - fd2.1) / 3.0);
        let err = (w.dlength_dp - rich.0)
            .norm()
            .max((w.dlength_ds - rich.1).norm());
        assert!(
            err < 1e-7,
            "{name}: gradient off by {err} at P = {p:?}, S = {s:?}\n{:?} vs {:?}\n{:?} vs {:?}",
            w.dlength_dp,
            rich.0,
            w.dlength_ds,
            rich.1
        );
    }
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

#[test]
fn sphere_and_cylinder_gradients_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        let sphere: WrapFn = Box::new(move |p, s| wrap_sphere(0.05, q, p, s).wrapped());
        check(
            &format!("sphere {q:?}"),
            &sphere,
            0.05,
            Vec3::new(0.2, 0.2, 0.2),
            40 + i as u64,
            100,
        );
        let cylinder: WrapFn = Box::new(move |p, s| wrap_cylinder(0.05, 0.3, q, p, s).wrapped());
        check(
            &format!("cylinder {q:?}"),
            &cylinder,
            0.05,
            Vec3::new(0.2, 0.2, 0.2),
            50 + i as u64,
            100,
        );
    }
}

#[test]
fn ellipsoid_gradients_match_central_differences_for_every_method() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        for (j, m) in [
            EllipsoidMethod::Hybrid,
            EllipsoidMethod::Midpoint,
            EllipsoidMethod::Axial,
        ]
        .into_iter()
        .enumerate()
        {
            let f: WrapFn = Box::new(move |p, s| wrap_ellipsoid(&radii, q, m, p, s).wrapped());
            check(
                &format!("ellipsoid {m:?} {q:?}"),
                &f,
                0.04,
                Vec3::new(0.2, 0.2, 0.2),
                60 + (3 * i + j) as u64,
                60,
            );
        }
    }
}

#[test]
fn torus_gradients_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        let f: WrapFn = Box::new(move |p, s| wrap_torus(0.02, 0.06, q, p, s).wrapped());
        check(
            &format!("torus {q:?}"),
            &f,
            0.04,
            Vec3::new(0.08, 0.08, 0.12),
            80 + i as u64,
            100,
        );
    }
}
