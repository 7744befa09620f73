//! Arc length of an ellipse through Carlson's symmetric elliptic integrals (Carlson 1995,
//! "Numerical computation of real or complex elliptic integrals"; DLMF §19.36), exact to
//! round-off for any eccentricity, with its derivatives in closed form.

use std::f64::consts::{FRAC_PI_2, PI};

use super::real::{Real, V3};

/// Duplication steps cap: each step shrinks the spread of the arguments fourfold, so the
/// stopping test (spread < 1e-3 relative, series error ~1e-18) is met in ≲ 20 steps for
/// arguments within 1e12 of each other.
const MAX_DUPLICATIONS: usize = 40;
const SERIES_TOL: f64 = 1e-3;

/// R_F(x, y, z) = ½ ∫₀^∞ dt / √((t+x)(t+y)(t+z)), x, y, z ≥ 0, at most one zero.
pub(crate) fn carlson_rf(mut x: f64, mut y: f64, mut z: f64) -> f64 {
    let mut a = (x + y + z) / 3.0;
    for _ in 0..MAX_DUPLICATIONS {
        if spread(a, [x, y, z]) < SERIES_TOL {
            break;
        }
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * sy + sx * sz + sy * sz;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
        a = 0.25 * (a + lambda);
    }
    // X + Y + Z = 0; E2 = XY − Z², E3 = XYZ.
    let (dx, dy) = (1.0 - x / a, 1.0 - y / a);
    let dz = -(dx + dy);
    let e2 = dx * dy - dz * dz;
    let e3 = dx * dy * dz;
    (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / a.sqrt()
}

/// R_D(x, y, z) = (3/2) ∫₀^∞ dt / ((t+z) √((t+x)(t+y)(t+z))), x, y ≥ 0 (not both 0), z > 0.
pub(crate) fn carlson_rd(mut x: f64, mut y: f64, mut z: f64) -> f64 {
    let mut a = (x + y + 3.0 * z) / 5.0;
    let mut sum = 0.0;
    let mut fac = 1.0;
    for _ in 0..MAX_DUPLICATIONS {
        if spread(a, [x, y, z]) < SERIES_TOL {
            break;
        }
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * sy + sx * sz + sy * sz;
        // R_D(x, y, z) = ¼ R_D(x', y', z') + 3 / (√z (z + λ)).
        sum += fac / (sz * (z + lambda));
        fac *= 0.25;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
        a = 0.25 * (a + lambda);
    }
    // X + Y + 3Z = 0.
    let (dx, dy) = (1.0 - x / a, 1.0 - y / a);
    let dz = -(dx + dy) / 3.0;
    let xy = dx * dy;
    let z2 = dz * dz;
    let e2 = xy - 6.0 * z2;
    let e3 = (3.0 * xy - 8.0 * z2) * dz;
    let e4 = 3.0 * (xy - z2) * z2;
    let e5 = xy * z2 * dz;
    let series = 1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0
        - 3.0 * e4 / 22.0
        - 9.0 * e2 * e3 / 52.0
        + 3.0 * e5 / 26.0;
    fac * series / (a * a.sqrt()) + 3.0 * sum
}

fn spread(a: f64, v: [f64; 3]) -> f64 {
    v.iter().map(|&t| (1.0 - t / a).abs()).fold(0.0, f64::max)
}

/// E(φ|m) = ∫₀^φ √(1 − m sin²θ) dθ and D(φ|m) = ∫₀^φ sin²θ / √(1 − m sin²θ) dθ, any real
/// φ, 0 ≤ m < 1. For |ψ| ≤ π/2 (s = sin ψ, c = cos ψ, Δ² = 1 − m s²):
/// F = s R_F(c², Δ², 1), D = s³ R_D(c², Δ², 1)/3, E = F − m D; beyond, E(ψ + jπ) = E(ψ) + 2j E(m)
/// with the complete integrals (c = 0, s = 1), likewise D.
pub(crate) fn elliptic_e_d(phi: f64, m: f64) -> (f64, f64) {
    let j = (phi / PI).round();
    let psi = phi - j * PI;
    let (s, c) = psi.sin_cos();
    let d2 = 1.0 - m * s * s;
    let rf = carlson_rf(c * c, d2, 1.0);
    let rd = carlson_rd(c * c, d2, 1.0);
    let mut dd = s * s * s * rd / 3.0;
    let mut e = s * rf - m * dd;
    if j != 0.0 {
        let dc = carlson_rd(0.0, 1.0 - m, 1.0) / 3.0;
        let ec = carlson_rf(0.0, 1.0 - m, 1.0) - m * dc;
        e += 2.0 * j * ec;
        dd += 2.0 * j * dc;
    }
    (e, dd)
}

/// E(φ|m) on `T`, with Δ = √(1 − m sin²φ), s = sin φ, c = cos φ:
///   ∂E/∂φ = Δ,   ∂E/∂m = −D/2,
///   ∂²E/∂φ² = −m s c/Δ,   ∂²E/∂φ∂m = −s²/(2Δ),   ∂²E/∂m² = −½ ∂D/∂m,
/// where, from ∂F/∂m = E/(2m(1 − m)) − F/(2m) − s c/(2(1 − m)Δ) (DLMF 19.4.2 with m = k²),
/// E_m = −D/2 and F = E + mD:
///   ∂D/∂m = (E − s c/Δ − 2(1 − m) D) / (2m(1 − m)).
/// That quotient cancels as m → 0; below m = 10⁻³ the series
/// ∂D/∂m = ½ Σ_k (2k+1)!!/(2^k k!) m^k I_{2k+4}(φ), I_j = ∫₀^φ sin^j θ dθ, is used instead.
fn elliptic_e<T: Real>(phi: T, m: T) -> T {
    let (pv, mv) = (phi.val(), m.val());
    let (e, d) = elliptic_e_d(pv, mv);
    let (sn, cs) = pv.sin_cos();
    let delta = (1.0 - mv * sn * sn).sqrt();
    let hess = if T::SECOND {
        let e_pp = -mv * sn * cs / delta;
        let e_pm = -sn * sn / (2.0 * delta);
        let e_mm = -0.5 * elliptic_d_dm(pv, mv, e, d, delta);
        [e_pp, e_pm, e_pm, e_mm]
    } else {
        [0.0; 4]
    };
    T::chain(e, &[(delta, phi), (-0.5 * d, m)], &hess)
}

/// ∂D(φ|m)/∂m (see `elliptic_e`), given E, D and Δ at (φ, m).
pub(crate) fn elliptic_d_dm(phi: f64, m: f64, e: f64, d: f64, delta: f64) -> f64 {
    let (s, c) = phi.sin_cos();
    if m >= 1e-3 {
        return (e - s * c / delta - 2.0 * (1.0 - m) * d) / (2.0 * m * (1.0 - m));
    }
    // I_j = −sin^{j−1}φ cos φ / j + (j − 1)/j · I_{j−2}, I_0 = φ; terms up to m⁵ (< 1e-15).
    let mut i_prev = phi; // I_0
    let mut sum = 0.0;
    let mut coef = 1.0; // (2k+1)!!/(2^k k!) for k = 0
    let mut mk = 1.0;
    let mut j = 2;
    let mut k = 0;
    while k <= 5 {
        let ij = -s.powi(j - 1) * c / j as f64 + (j - 1) as f64 / j as f64 * i_prev;
        i_prev = ij;
        if j >= 4 {
            sum += coef * mk * ij;
            k += 1;
            coef *= (2 * k + 1) as f64 / (2 * k) as f64;
            mk *= m;
        }
        j += 2;
    }
    0.5 * sum
}

/// √(a² + b²) with a zero derivative at the origin (where it has none).
fn hypot<T: Real>(a: T, b: T) -> T {
    if a.val() == 0.0 && b.val() == 0.0 {
        T::cst(0.0)
    } else {
        (a * a + b * b).sqrt()
    }
}

/// Arc length of x(t) = c + cos t·w1 + sin t·w2 over t ∈ [0, span] (w1, w2 conjugate
/// semi-diameters of an ellipse). The speed² is |w1|² sin²t − 2 w1·w2 sin t cos t + |w2|² cos²t
/// = p − R cos(2t − 2t0) with p = (|w1|² + |w2|²)/2, R cos 2t0 = (|w1|² − |w2|²)/2,
/// R sin 2t0 = w1·w2; writing it as α²(1 − m sin²u), α² = p + R, m = 2R/(p + R),
/// u = t − t0 + π/2, the length is α [E(span − t0 + π/2 | m) − E(π/2 − t0 | m)].
pub(crate) fn ellipse_arc_length<T: Real>(w1: &V3<T>, w2: &V3<T>, span: T) -> T {
    let (n1, n2) = (w1.norm2(), w2.norm2());
    let p = (n1 + n2) * 0.5;
    let mc = (n1 - n2) * 0.5;
    let ns = w1.dot(w2);
    let r = hypot(mc, ns);
    let t0 = ns.atan2(mc) * 0.5;
    let alpha2 = p + r;
    let m = r * 2.0 / alpha2;
    let u0 = -t0 + FRAC_PI_2;
    alpha2.sqrt() * (elliptic_e(u0 + span, m) - elliptic_e(u0, m))
}
