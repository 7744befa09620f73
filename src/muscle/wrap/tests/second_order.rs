//! The second-order rates (`WrapSurface::second_order`) against central differences of the
//! exact first derivatives (`dlength_dp`, `dlength_ds`, `dt1`, `dt2`) along the direction.

use super::super::*;
use super::Rng;
use crate::spatial::Vec3;

/// The first derivatives at P + εδP, S + εδS as one vector: ∂L (6), dt1 (18), dt2 (18).
fn first(
    surface: &WrapSurface,
    q: Quadrant,
    p: &Vec3,
    s: &Vec3,
    dir: &[f64; 6],
    eps: f64,
) -> Option<Vec<f64>> {
    let dp = Vec3::new(dir[0], dir[1], dir[2]) * eps;
    let ds = Vec3::new(dir[3], dir[4], dir[5]) * eps;
    let w = surface.wrap(q, &(p + dp), &(s + ds)).wrapped()?;
    let mut v: Vec<f64> = w
        .dlength_dp
        .iter()
        .chain(w.dlength_ds.iter())
        .copied()
        .collect();
    v.extend(w.dt1.iter());
    v.extend(w.dt2.iter());
    Some(v)
}

/// Random wrapped configurations of `surface`; for each whose first derivatives are smooth
/// over the stencil, the rates must equal the Richardson-extrapolated central difference.
fn check(name: &str, surface: WrapSurface, q: Quadrant, half: f64, seed: u64, want: usize) {
    let mut rng = Rng::new(seed);
    let (mut checked, mut skipped, mut tries) = (0, 0, 0);
    let h = 2e-6;
    while checked < want && tries < 200 * want {
        tries += 1;
        let rnd = |rng: &mut Rng| {
            Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * half
        };
        let (p, s) = (rnd(&mut rng), rnd(&mut rng));
        let dir: [f64; 6] = std::array::from_fn(|_| rng.range(-1.0, 1.0));
        if surface.wrap(q, &p, &s).wrapped().is_none() {
            continue;
        }
        let Some(so) = surface.second_order(q, &p, &s, &dir) else {
            skipped += 1;
            continue;
        };
        let f = |e: f64| first(&surface, q, &p, &s, &dir, e);
        let (Some(a1), Some(b1), Some(a2), Some(b2)) = (f(h), f(-h), f(2.0 * h), f(-2.0 * h))
        else {
            skipped += 1;
            continue;
        };
        let fd: Vec<f64> = (0..a1.len()).map(|i| (a1[i] - b1[i]) / (2.0 * h)).collect();
        let fd2: Vec<f64> = (0..a1.len()).map(|i| (a2[i] - b2[i]) / (4.0 * h)).collect();
        let scale = fd.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let jump = fd
            .iter()
            .zip(&fd2)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        if jump > 1e-3 * scale {
            skipped += 1; // a kink or jump inside the stencil
            continue;
        }
        checked += 1;
        let mut ours: Vec<f64> = so.hessian_dir.to_vec();
        ours.extend(so.dt1_dir.iter());
        ours.extend(so.dt2_dir.iter());
        for i in 0..ours.len() {
            let rich = (4.0 * fd[i] - fd2[i]) / 3.0;
            let err = (ours[i] - rich).abs();
            assert!(
                err <= 1e-6 * scale,
                "{name}: entry {i} of the rates is {} where central differences give {rich} \
                 (scale {scale}) at P = {p:?}, S = {s:?}, δ = {dir:?}",
                ours[i]
            );
        }
    }
    assert_eq!(
        checked, want,
        "{name}: only {checked} smooth wraps in {tries} tries"
    );
    assert!(
        skipped * 10 <= checked,
        "{name}: {skipped} skipped of {checked}"
    );
}

const QUADRANTS: [Quadrant; 3] = [Quadrant::All, Quadrant::Positive(0), Quadrant::Negative(2)];

#[test]
fn sphere_and_cylinder_second_order_rates_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        check(
            "sphere",
            WrapSurface::Sphere { radius: 0.05 },
            q,
            0.2,
            300 + i as u64,
            40,
        );
        let cyl = WrapSurface::Cylinder {
            radius: 0.05,
            length: 0.3,
        };
        check("cylinder", cyl, q, 0.2, 310 + i as u64, 40);
    }
}

#[test]
fn ellipsoid_second_order_rates_match_central_differences_for_every_method() {
    let radii = Vec3::new(0.06, 0.025, 0.04);
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        for (j, method) in [
            EllipsoidMethod::Hybrid,
            EllipsoidMethod::Midpoint,
            EllipsoidMethod::Axial,
        ]
        .into_iter()
        .enumerate()
        {
            let e = WrapSurface::Ellipsoid { radii, method };
            check(
                &format!("ellipsoid {method:?} {q:?}"),
                e,
                q,
                0.2,
                320 + (3 * i + j) as u64,
                15,
            );
        }
    }
}

#[test]
fn torus_second_order_rates_match_central_differences() {
    for (i, q) in QUADRANTS.into_iter().enumerate() {
        let t = WrapSurface::Torus {
            inner_radius: 0.02,
            outer_radius: 0.06,
        };
        check(&format!("torus {q:?}"), t, q, 0.1, 340 + i as u64, 40);
    }
}
