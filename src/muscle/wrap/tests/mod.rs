//! Tests of the wrap geometry against independent references: brute-force minimisation for
//! the shortest paths, quadrature for the elliptic integrals, central differences for the
//! gradients, and OpenSim's rules on hand-built configurations.

use crate::spatial::Vec3;

mod api;
mod contact_jacobians;
mod ellipsoid;
mod gradients;
mod numerics;
mod second_order;
mod sphere_cylinder;
mod torus;

/// Deterministic generator (SplitMix64) for reproducible random configurations.
pub(super) struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
    pub fn unit(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
}

/// A unit vector perpendicular to `u`.
pub(super) fn perpendicular(u: &Vec3) -> Vec3 {
    let a = if u.x.abs() < 0.6 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    u.cross(&a).normalize()
}

/// Golden-section minimisation of a unimodal f on [a, b].
pub(super) fn golden_min(
    f: impl Fn(f64) -> f64,
    mut a: f64,
    mut b: f64,
    iters: usize,
) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let x = 0.5 * (a + b);
    (x, f(x))
}

/// Scan then golden-section refine: global minimum of f over [a, b] for a function with a
/// few local minima.
pub(super) fn scan_min(f: impl Fn(f64) -> f64, a: f64, b: f64, samples: usize) -> (f64, f64) {
    let h = (b - a) / samples as f64;
    let mut best = (a, f(a));
    for i in 1..=samples {
        let x = a + h * i as f64;
        let v = f(x);
        if v < best.1 {
            best = (x, v);
        }
    }
    let lo = (best.0 - h).max(a);
    let hi = (best.0 + h).min(b);
    let r = golden_min(&f, lo, hi, 80);
    if r.1 < best.1 { r } else { best }
}

/// Central differences of `f` with respect to P and S; `None` if f is undefined nearby.
pub(super) fn central_difference(
    f: &dyn Fn(&Vec3, &Vec3) -> Option<f64>,
    p: &Vec3,
    s: &Vec3,
    h: f64,
) -> Option<(Vec3, Vec3)> {
    let mut gp = Vec3::zeros();
    let mut gs = Vec3::zeros();
    for k in 0..3 {
        let e = Vec3::ith(k, h);
        gp[k] = (f(&(p + e), s)? - f(&(p - e), s)?) / (2.0 * h);
        gs[k] = (f(p, &(s + e))? - f(p, &(s - e))?) / (2.0 * h);
    }
    Some((gp, gs))
}
mod opensim;
mod timing;
