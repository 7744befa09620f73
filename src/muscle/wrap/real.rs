//! Scalars for the wrap algorithms: plain `f64`, and a forward-mode dual number `D6` that
//! carries the derivative with respect to the six inputs (P, S). Running an algorithm on `D6`
//! gives the exact derivative of what the algorithm computes; iterative solvers run on `f64`
//! and are lifted to `D6` by the implicit-function theorem (one Newton step taken in dual
//! arithmetic from the converged root: for `F(x*, θ) = 0`, `x = x* − F(x*, θ)/F_x` has value
//! `x*` and derivative `−F_θ/F_x`, exactly the implicit derivative).

use std::ops::{Add, Div, Mul, Neg, Sub};

use nalgebra::Matrix3x6;

use crate::spatial::{Mat3, Vec3};

/// The arithmetic the wrap algorithms need, implemented by `f64`, `D6` and `D6<D1>`.
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
    /// Whether it also carries second derivatives (`D6<D1>`): implicit lifts then take a
    /// second Newton step, and shortcuts that accumulate first derivatives in `f64` are off.
    const SECOND: bool;
    fn cst(v: f64) -> Self;
    fn val(self) -> f64;
    fn sqrt(self) -> Self;
    /// atan2(self, x); at (0, 0) the derivative is taken as zero.
    fn atan2(self, x: Self) -> Self;
    fn abs(self) -> Self;
    /// A quantity y = f(x_1, …, x_k) evaluated in `f64` from its value, its gradient and
    /// its Hessian in the arguments: `terms` = (∂f/∂x_a, x_a), `hess` the k × k matrix
    /// ∂²f/∂x_a∂x_b row-major. The chain rule to second order:
    ///   dy = Σ_a f_a dx_a,   d²y = Σ_a f_a d²x_a + Σ_ab f_ab dx_a dx_b.
    /// First-order scalars ignore `hess`; an empty `hess` is only allowed for them.
    fn chain(value: f64, terms: &[(f64, Self)], hess: &[f64]) -> Self;
    /// As [`Real::chain`], with the rates ḟ_a of the coefficients along δ given directly
    /// (`coef_rates`, one per term; ignored by first-order scalars).
    fn chain_rates(value: f64, terms: &[(f64, Self)], coef_rates: &[f64]) -> Self;
    /// The value's rate along δ (0 for first-order scalars).
    fn value_rate(self) -> f64;
}

impl Real for f64 {
    const HAS_GRAD: bool = false;
    const SECOND: bool = false;
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
    fn chain(value: f64, _terms: &[(f64, Self)], _hess: &[f64]) -> Self {
        value
    }
    #[inline]
    fn chain_rates(value: f64, _terms: &[(f64, Self)], _coef_rates: &[f64]) -> Self {
        value
    }
    #[inline]
    fn value_rate(self) -> f64 {
        0.0
    }
}

/// What a [`D6`] carries in each slot: `f64` (values and first derivatives) or [`D1`]
/// (each of those together with its rate along one direction, hence second derivatives).
pub(crate) trait Base:
    Copy
    + std::fmt::Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Mul<f64, Output = Self>
{
    /// Whether this is a second-order slot.
    const SECOND: bool;
    fn cst(v: f64) -> Self;
    fn val(self) -> f64;
    fn sqrt(self) -> Self;
    fn atan2(self, x: Self) -> Self;
    fn plus(self, c: f64) -> Self;
    /// The rate along the [`D1`] direction (0 for `f64`).
    fn rate(self) -> f64;
    /// A slot with this value and rate (`f64` drops the rate).
    fn from_value_rate(v: f64, d: f64) -> Self;
}

impl Base for f64 {
    const SECOND: bool = false;
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
    fn plus(self, c: f64) -> Self {
        self + c
    }
    #[inline]
    fn rate(self) -> f64 {
        0.0
    }
    #[inline]
    fn from_value_rate(v: f64, _d: f64) -> Self {
        v
    }
}

/// A value with its rate along one direction δ: v + ε d.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct D1 {
    pub v: f64,
    pub d: f64,
}

impl D1 {
    #[inline]
    pub fn new(v: f64, d: f64) -> Self {
        D1 { v, d }
    }
}

impl Add for D1 {
    type Output = D1;
    #[inline]
    fn add(self, o: D1) -> D1 {
        D1::new(self.v + o.v, self.d + o.d)
    }
}
impl Sub for D1 {
    type Output = D1;
    #[inline]
    fn sub(self, o: D1) -> D1 {
        D1::new(self.v - o.v, self.d - o.d)
    }
}
impl Mul for D1 {
    type Output = D1;
    #[inline]
    fn mul(self, o: D1) -> D1 {
        D1::new(self.v * o.v, self.d * o.v + self.v * o.d)
    }
}
impl Div for D1 {
    type Output = D1;
    #[inline]
    fn div(self, o: D1) -> D1 {
        let q = self.v / o.v;
        D1::new(q, (self.d - q * o.d) / o.v)
    }
}
impl Neg for D1 {
    type Output = D1;
    #[inline]
    fn neg(self) -> D1 {
        D1::new(-self.v, -self.d)
    }
}
impl Mul<f64> for D1 {
    type Output = D1;
    #[inline]
    fn mul(self, o: f64) -> D1 {
        D1::new(self.v * o, self.d * o)
    }
}

impl Base for D1 {
    const SECOND: bool = true;
    #[inline]
    fn cst(v: f64) -> Self {
        D1::new(v, 0.0)
    }
    #[inline]
    fn val(self) -> f64 {
        self.v
    }
    #[inline]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        D1::new(r, 0.5 * self.d / r)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        let r2 = self.v * self.v + x.v * x.v;
        let v = self.v.atan2(x.v);
        if r2 == 0.0 {
            return D1::new(v, 0.0);
        }
        D1::new(v, (x.v * self.d - self.v * x.d) / r2)
    }
    #[inline]
    fn plus(self, c: f64) -> Self {
        D1::new(self.v + c, self.d)
    }
    #[inline]
    fn rate(self) -> f64 {
        self.d
    }
    #[inline]
    fn from_value_rate(v: f64, d: f64) -> Self {
        D1::new(v, d)
    }
}

/// Dual number with six tangent directions: ∂/∂P (0..3) and ∂/∂S (3..6). With `S = D1`
/// every slot also carries its rate along a direction δ of (P, S): the value's rate is the
/// directional derivative and each gradient entry's rate a row of the Hessian times δ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct D6<S = f64> {
    pub v: S,
    pub g: [S; 6],
}

impl D6<f64> {
    /// The `k`-th input variable (value `v`, unit derivative in direction `k`).
    pub fn var(v: f64, k: usize) -> Self {
        let mut g = [0.0; 6];
        g[k] = 1.0;
        D6 { v, g }
    }
}

impl D6<D1> {
    /// The `k`-th input variable with value `v` moving at rate `d` along δ.
    pub fn var2(v: f64, d: f64, k: usize) -> Self {
        let mut g = [D1::cst(0.0); 6];
        g[k] = D1::cst(1.0);
        D6 {
            v: D1::new(v, d),
            g,
        }
    }
}

impl<S: Base> D6<S> {
    #[inline]
    fn map(self, v: S, d: S) -> Self {
        let mut g = self.g;
        for gi in &mut g {
            *gi = *gi * d;
        }
        D6 { v, g }
    }
}

impl<S: Base> Add for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn add(self, o: D6<S>) -> D6<S> {
        let mut g = self.g;
        for (gi, oi) in g.iter_mut().zip(o.g) {
            *gi = *gi + oi;
        }
        D6 { v: self.v + o.v, g }
    }
}
impl<S: Base> Sub for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn sub(self, o: D6<S>) -> D6<S> {
        let mut g = self.g;
        for (gi, oi) in g.iter_mut().zip(o.g) {
            *gi = *gi - oi;
        }
        D6 { v: self.v - o.v, g }
    }
}
impl<S: Base> Mul for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn mul(self, o: D6<S>) -> D6<S> {
        let mut g = self.g;
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = self.g[k] * o.v + self.v * o.g[k];
        }
        D6 { v: self.v * o.v, g }
    }
}
impl<S: Base> Div for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn div(self, o: D6<S>) -> D6<S> {
        let q = self.v / o.v;
        let inv = S::cst(1.0) / o.v;
        let mut g = self.g;
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = (self.g[k] - q * o.g[k]) * inv;
        }
        D6 { v: q, g }
    }
}
impl<S: Base> Neg for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn neg(self) -> D6<S> {
        self.map(-self.v, S::cst(-1.0))
    }
}
impl<S: Base> Add<f64> for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn add(self, o: f64) -> D6<S> {
        D6 {
            v: self.v.plus(o),
            g: self.g,
        }
    }
}
impl<S: Base> Sub<f64> for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn sub(self, o: f64) -> D6<S> {
        D6 {
            v: self.v.plus(-o),
            g: self.g,
        }
    }
}
impl<S: Base> Mul<f64> for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn mul(self, o: f64) -> D6<S> {
        let mut g = self.g;
        for gi in &mut g {
            *gi = *gi * o;
        }
        D6 { v: self.v * o, g }
    }
}
impl<S: Base> Div<f64> for D6<S> {
    type Output = D6<S>;
    #[inline]
    fn div(self, o: f64) -> D6<S> {
        let inv = 1.0 / o;
        let mut g = self.g;
        for gi in &mut g {
            *gi = *gi * inv;
        }
        D6 {
            v: self.v / S::cst(o),
            g,
        }
    }
}

impl<S: Base> Real for D6<S> {
    const HAS_GRAD: bool = true;
    const SECOND: bool = S::SECOND;
    #[inline]
    fn cst(v: f64) -> Self {
        D6 {
            v: S::cst(v),
            g: [S::cst(0.0); 6],
        }
    }
    #[inline]
    fn val(self) -> f64 {
        self.v.val()
    }
    #[inline]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        self.map(r, S::cst(0.5) / r)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        let r2 = self.v * self.v + x.v * x.v;
        let v = self.v.atan2(x.v);
        if r2.val() == 0.0 {
            return D6 {
                v,
                g: [S::cst(0.0); 6],
            };
        }
        // d atan2(y, x) = (x dy − y dx) / (x² + y²)
        let mut g = self.g;
        for (k, gk) in g.iter_mut().enumerate() {
            *gk = (x.v * self.g[k] - self.v * x.g[k]) / r2;
        }
        D6 { v, g }
    }
    #[inline]
    fn abs(self) -> Self {
        if self.v.val() < 0.0 { -self } else { self }
    }
    #[inline]
    fn chain(value: f64, terms: &[(f64, Self)], hess: &[f64]) -> Self {
        // ḟ_a = Σ_b f_ab ẋ_b
        debug_assert!(terms.len() <= 6);
        debug_assert!(!S::SECOND || hess.len() == terms.len() * terms.len());
        let n = terms.len();
        let mut rates = [0.0; 6];
        if S::SECOND {
            for (a, r) in rates.iter_mut().enumerate().take(n) {
                *r = (0..n).map(|b| hess[a * n + b] * terms[b].1.v.rate()).sum();
            }
        }
        Self::chain_rates(value, terms, &rates[..n.min(6)])
    }
    #[inline]
    fn chain_rates(value: f64, terms: &[(f64, Self)], coef_rates: &[f64]) -> Self {
        // Slot k: Σ_a f_a ∂_k x_a, whose rate is Σ_a (f_a (∂_k x_a)˙ + ḟ_a ∂_k x_a); the
        // value's rate is Σ_a f_a ẋ_a.
        let mut g = [S::cst(0.0); 6];
        let mut rate = 0.0;
        for (a, (c, t)) in terms.iter().enumerate() {
            rate += c * t.v.rate();
            let dc = if S::SECOND { coef_rates[a] } else { 0.0 };
            for (gk, tk) in g.iter_mut().zip(t.g) {
                *gk = *gk + tk * *c + S::from_value_rate(0.0, dc * tk.val());
            }
        }
        D6 {
            v: S::from_value_rate(value, rate),
            g,
        }
    }
    #[inline]
    fn value_rate(self) -> f64 {
        self.v.rate()
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

/// P and S as second-order dual vectors: unit tangents in the six slots, each input moving
/// at its rate `dir[k]` along δ.
pub(crate) fn seed2(p: &Vec3, s: &Vec3, dir: &[f64; 6]) -> (V3<D6<D1>>, V3<D6<D1>>) {
    let v = |x: f64, k: usize| D6::var2(x, dir[k], k);
    (
        V3::new(v(p.x, 0), v(p.y, 1), v(p.z, 2)),
        V3::new(v(s.x, 3), v(s.y, 4), v(s.z, 5)),
    )
}

/// The second-order rates of a wrap from its length and contact points on `D6<D1>`.
pub(crate) fn second_order_of(
    length: &D6<D1>,
    t1: &V3<D6<D1>>,
    t2: &V3<D6<D1>>,
) -> super::WrapSecondOrder {
    super::WrapSecondOrder {
        hessian_dir: std::array::from_fn(|k| length.g[k].d),
        dt1_dir: Matrix3x6::from_fn(|i, k| t1.at(i).g[k].d),
        dt2_dir: Matrix3x6::from_fn(|i, k| t2.at(i).g[k].d),
    }
}
