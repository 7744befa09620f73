//! Scalars for the wrap algorithms: plain `f64`, and a forward-mode dual number `D6` that
//! carries the derivative with respect to the six inputs (P, S). Running an algorithm on `D6`
//! gives the exact derivative of what the algorithm computes; iterative solvers run on `f64`
//! and are lifted to `D6` by the implicit-function theorem (one Newton step taken in dual
//! arithmetic from the converged root: for `F(x*, θ) = 0`, `x = x* − F(x*, θ)/F_x` has value
//! `x*` and derivative `−F_θ/F_x`, exactly the implicit derivative).

use std::ops::{Add, Div, Mul, Neg, Sub};

use nalgebra::Matrix3x6;

use crate::spatial::{Mat3, Vec3};

/// The arithmetic the wrap algorithms need, implemented by `f64` and `D6`.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// Whether this scalar carries derivatives (lets value-only callers skip Jacobians).
    const HAS_GRAD: bool;
    fn cst(v: f64) -> Self;
    fn val(self) -> f64;
    fn sqrt(self) -> Self;
    /// atan2(self, x); at (0, 0) the derivative is taken as zero.
    fn atan2(self, x: Self) -> Self;
    fn abs(self) -> Self;
    /// A quantity with value `value` whose derivative is `Σ coeff · d(arg)`: the chain rule
    /// for a function evaluated in `f64` whose partial derivatives are known.
    fn chain(value: f64, terms: &[(f64, Self)]) -> Self;
}

impl Real for f64 {
    const HAS_GRAD: bool = false;
    #[inline]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline]
    fn val(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn chain(value: f64, _terms: &[(f64, Self)]) -> Self {
        value
    }
}

/// Dual number with six tangent directions: ∂/∂P (0..3) and ∂/∂S (3..6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct D6 {
    pub v: f64,
    pub g: [f64; 6],
}

impl D6 {
    /// The `k`-th input variable (value `v`, unit derivative in direction `k`).
    pub fn var(v: f64, k: usize) -> Self {
        let mut g = [0.0; 6];
        g[k] = 1.0;
        D6 { v, g }
    }
    #[inline]
    fn map(self, v: f64, d: f64) -> Self {
        let mut g = self.g;
        for gi in &mut g {
            *gi *= d;
        }
        D6 { v, g }
    }
}

impl Add for D6 {
    type Output = D6;
    #[inline]
    fn add(self, o: D6) -> D6 {
        let mut g = self.g;
        for (gi, oi) in g.iter_mut().zip(o.g) {
            *gi += oi;
        }
        D6 { v: self.v + o.v, g }
    }
}
impl Sub for D6 {
    type Output = D6;
    #[inline]
    fn sub(self, o: D6) -> D6 {
        let mut g = self.g;
        for (gi, oi) in g.iter_mut().zip(o.g) {
            *gi -= oi;
        }
        D6 { v: self.v - o.v, g }
    }
}
impl Mul for D6 {
    type Output = D6;
    #[inline]
    fn mul(self, o: D6) -> D6 {
        let mut g = [0.0; 6];
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = self.g[k] * o.v + self.v * o.g[k];
        }
        D6 { v: self.v * o.v, g }
    }
}
impl Div for D6 {
    type Output = D6;
    #[inline]
    fn div(self, o: D6) -> D6 {
        let q = self.v / o.v;
        let inv = 1.0 / o.v;
        let mut g = [0.0; 6];
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = (self.g[k] - q * o.g[k]) * inv;
        }
        D6 { v: q, g }
    }
}
impl Neg for D6 {
    type Output = D6;
    #[inline]
    fn neg(self) -> D6 {
        self.map(-self.v, -1.0)
    }
}
impl Add<f64> for D6 {
    type Output = D6;
    #[inline]
    fn add(self, o: f64) -> D6 {
        D6 {
            v: self.v + o,
            g: self.g,
        }
    }
}
impl Sub<f64> for D6 {
    type Output = D6;
    #[inline]
    fn sub(self, o: f64) -> D6 {
        D6 {
            v: self.v - o,
            g: self.g,
        }
    }
}
impl Mul<f64> for D6 {
    type Output = D6;
    #[inline]
    fn mul(self, o: f64) -> D6 {
        self.map(self.v * o, o)
    }
}
impl Div<f64> for D6 {
    type Output = D6;
    #[inline]
    fn div(self, o: f64) -> D6 {
        self.map(self.v / o, 1.0 / o)
    }
}

impl Real for D6 {
    const HAS_GRAD: bool = true;
    #[inline]
    fn cst(v: f64) -> Self {
        D6 { v, g: [0.0; 6] }
    }
    #[inline]
    fn val(self) -> f64 {
        self.v
    }
    #[inline]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        self.map(r, 0.5 / r)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        let r2 = self.v * self.v + x.v * x.v;
        let v = self.v.atan2(x.v);
        if r2 == 0.0 {
            return D6::cst(v);
        }
        // d atan2(y, x) = (x dy − y dx) / (x² + y²)
        let mut g = [0.0; 6];
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = (x.v * self.g[k] - self.v * x.g[k]) / r2;
        }
        D6 { v, g }
    }
    #[inline]
    fn abs(self) -> Self {
        if self.v < 0.0 { -self } else { self }
    }
    #[inline]
    fn chain(value: f64, terms: &[(f64, Self)]) -> Self {
        let mut g = [0.0; 6];
        for (c, t) in terms {
            for (gk, tk) in g.iter_mut().zip(t.g) {
                *gk += c * tk;
            }
        }
        D6 { v: value, g }
    }
}

/// A 3-vector over any `Real` (nalgebra's vectors need traits a dual number does not have).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct V3<T> {
    pub x: T,
    pub y: T,
    pub z: T,
}

impl<T: Real> V3<T> {
    #[inline]
    pub fn new(x: T, y: T, z: T) -> Self {
        V3 { x, y, z }
    }
    #[inline]
    pub fn cst(v: &Vec3) -> Self {
        V3::new(T::cst(v.x), T::cst(v.y), T::cst(v.z))
    }
    #[inline]
    pub fn zero() -> Self {
        V3::new(T::cst(0.0), T::cst(0.0), T::cst(0.0))
    }
    #[inline]
    pub fn val(&self) -> Vec3 {
        Vec3::new(self.x.val(), self.y.val(), self.z.val())
    }
    #[inline]
    pub fn at(&self, i: usize) -> T {
        match i {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
    #[inline]
    pub fn set(&mut self, i: usize, v: T) {
        match i {
            0 => self.x = v,
            1 => self.y = v,
            _ => self.z = v,
        }
    }
    #[inline]
    pub fn dot(&self, o: &Self) -> T {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline]
    pub fn cross(&self, o: &Self) -> Self {
        V3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    #[inline]
    pub fn norm2(&self) -> T {
        self.dot(self)
    }
    #[inline]
    pub fn norm(&self) -> T {
        self.norm2().sqrt()
    }
    #[inline]
    pub fn scale(&self, s: T) -> Self {
        V3::new(self.x * s, self.y * s, self.z * s)
    }
    #[inline]
    pub fn scale_f(&self, s: f64) -> Self {
        V3::new(self.x * s, self.y * s, self.z * s)
    }
    /// Component-wise product with a constant vector (e.g. the ellipsoid metric diag(1/a²)).
    #[inline]
    pub fn mul_diag(&self, d: &[f64; 3]) -> Self {
        V3::new(self.x * d[0], self.y * d[1], self.z * d[2])
    }
}

impl<T: Real> Add for V3<T> {
    type Output = V3<T>;
    #[inline]
    fn add(self, o: V3<T>) -> V3<T> {
        V3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<T: Real> Sub for V3<T> {
    type Output = V3<T>;
    #[inline]
    fn sub(self, o: V3<T>) -> V3<T> {
        V3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<T: Real> Neg for V3<T> {
    type Output = V3<T>;
    #[inline]
    fn neg(self) -> V3<T> {
        V3::new(-self.x, -self.y, -self.z)
    }
}

/// P and S as dual vectors seeded with the six unit tangents.
pub(crate) fn seed(p: &Vec3, s: &Vec3) -> (V3<D6>, V3<D6>) {
    (
        V3::new(D6::var(p.x, 0), D6::var(p.y, 1), D6::var(p.z, 2)),
        V3::new(D6::var(s.x, 3), D6::var(s.y, 4), D6::var(s.z, 5)),
    )
}

/// The 3 × 6 Jacobian of a dual vector: rows x, y, z; columns ∂/∂P (0..3), ∂/∂S (3..6).
pub(crate) fn jacobian(v: &V3<D6>) -> Matrix3x6<f64> {
    Matrix3x6::from_fn(|i, k| v.at(i).g[k])
}

/// [∂/∂P | ∂/∂S] as one 3 × 6 matrix.
pub(crate) fn join(dp: &Mat3, ds: &Mat3) -> Matrix3x6<f64> {
    let mut j = Matrix3x6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(dp);
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(ds);
    j
}

/// Split a dual scalar's derivative into ∂/∂P and ∂/∂S.
pub(crate) fn gradients(l: &D6) -> (Vec3, Vec3) {
    (
        Vec3::new(l.g[0], l.g[1], l.g[2]),
        Vec3::new(l.g[3], l.g[4], l.g[5]),
    )
}
