//! Per-call cost, against a straight-line length measured in the same run
//! (`cargo test --release --lib muscle::wrap::tests::timing -- --ignored --nocapture`).

use std::hint::black_box;
use std::time::Instant;

use super::super::*;
use super::Rng;
use crate::spatial::Vec3;

fn per_call(f: &dyn Fn(&Vec3, &Vec3) -> f64, cases: &[(Vec3, Vec3)], reps: usize) -> f64 {
    let t = Instant::now();
    let mut acc = 0.0;
    for _ in 0..reps {
        for (p, s) in cases {
            acc += f(black_box(p), black_box(s));
        }
    }
    black_box(acc);
    t.elapsed().as_nanos() as f64 / (reps * cases.len()) as f64
}

#[test]
#[ignore]
fn timing_per_call() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    type F = Box<dyn Fn(&Vec3, &Vec3) -> Option<Wrapped>>;
    let surfaces: Vec<(&str, F, f64)> = vec![
        (
            "sphere",
            Box::new(|p, s| wrap_sphere(0.05, Quadrant::All, p, s).wrapped()),
            0.2,
        ),
        (
            "cylinder",
            Box::new(|p, s| wrap_cylinder(0.05, 0.3, Quadrant::All, p, s).wrapped()),
            0.2,
        ),
        (
            "cylinder +x",
            Box::new(|p, s| wrap_cylinder(0.05, 0.3, Quadrant::Positive(0), p, s).wrapped()),
            0.2,
        ),
        (
            "ellipsoid hybrid",
            Box::new(move |p, s| {
                wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Hybrid, p, s).wrapped()
            }),
            0.2,
        ),
        (
            "ellipsoid midpoint",
            Box::new(move |p, s| {
                wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Midpoint, p, s).wrapped()
            }),
            0.2,
        ),
        (
            "ellipsoid axial",
            Box::new(move |p, s| {
                wrap_ellipsoid(&radii, Quadrant::All, EllipsoidMethod::Axial, p, s).wrapped()
            }),
            0.2,
        ),
        (
            "ellipsoid hybrid -y",
            Box::new(move |p, s| {
                wrap_ellipsoid(&radii, Quadrant::Negative(1), EllipsoidMethod::Hybrid, p, s)
                    .wrapped()
            }),
            0.2,
        ),
        (
            "torus",
            Box::new(|p, s| wrap_torus(0.02, 0.06, Quadrant::All, p, s).wrapped()),
            0.1,
        ),
    ];
    let straight = |p: &Vec3, s: &Vec3| (p - s).norm();
    for (name, f, half) in &surfaces {
        let mut rng = Rng::new(99);
        let mut cases = Vec::new();
        while cases.len() < 200 {
            let p = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * *half;
            let s = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * *half;
            if f(&p, &s).is_some() {
                cases.push((p, s));
            }
        }
        let reps = 200;
        let base = per_call(&straight, &cases, reps * 10);
        let t = per_call(&|p, s| f(p, s).map_or(0.0, |w| w.length), &cases, reps);
        println!(
            "{name:22} {t:9.1} ns per wrapped call ({:.0}× a straight-line length)",
            t / base
        );
    }
}
