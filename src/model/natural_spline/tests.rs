//! Tests of the interpolating natural spline against independent references.
use super::*;
use nalgebra::{DMatrix, DVector};

/// Irregular knots (ratios of neighbouring spacings up to ~13).
fn irregular_knots() -> Vec<f64> {
    vec![
        -1.0, -0.6, -0.55, 0.0, 0.7, 1.0, 1.04, 2.1, 2.5, 3.3, 3.35, 4.0,
    ]
}

fn data_fn(t: f64) -> f64 {
    (1.3 * t).sin() + 0.4 * (3.1 * t).cos() + 0.1 * t * t
}

fn sample(x: &[f64]) -> Vec<f64> {
    x.iter().map(|&t| data_fn(t)).collect()
}

/// Deterministic pseudo-random numbers in [0, 1) (xorshift), for larger tests.
fn rand_seq(n: usize, mut state: u64) -> Vec<f64> {
    (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// Test abscissae: inside every interval, at the knots and outside on both sides.
fn probe_points(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut ts = vec![
        x[0] - 1.5,
        x[0] - 0.3,
        x[0] - 1e-3,
        x[n - 1] + 1e-3,
        x[n - 1] + 0.4,
        x[n - 1] + 2.0,
    ];
    for w in x.windows(2) {
        for k in 0..=10 {
            ts.push(w[0] + (w[1] - w[0]) * k as f64 / 10.0);
        }
    }
    ts
}

fn close(a: f64, b: f64, tol: f64, scale: f64) -> bool {
    (a - b).abs() <= tol * scale.max(1.0)
}

// ---------- 1. m = 1: piecewise linear, constant extrapolation ----------

#[test]
fn m1_is_piecewise_linear_with_constant_extrapolation() {
    let x = irregular_knots();
    let y = sample(&x);
    let s = NaturalSpline::interpolating(1, x.clone(), y.clone()).unwrap();
    assert_eq!(s.half_order(), 1);
    let n = x.len();
    for &t in &probe_points(&x) {
        let (v, d1, d2) = s.eval(t);
        // Independent reference: linear interpolation; outside, degree m−1 = 0 ⇒ constant.
        let (rv, rd1) = if t < x[0] {
            (y[0], 0.0)
        } else if t > x[n - 1] {
            (y[n - 1], 0.0)
        } else {
            let i = (0..n - 1).find(|&i| t <= x[i + 1]).unwrap();
            let slope = (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
            (y[i] + slope * (t - x[i]), slope)
        };
        assert!(close(v, rv, 1e-13, 1.0), "t={t}: {v} vs {rv}");
        // At a knot the slope is one of the two one-sided slopes; avoid knots for d1.
        if !x.contains(&t) {
            assert!(close(d1, rd1, 1e-12, rd1.abs()), "t={t}: {d1} vs {rd1}");
        }
        assert_eq!(d2, 0.0);
    }
    assert_eq!(s.eval(-1e300), (y[0], 0.0, 0.0));
    assert_eq!(s.eval(f64::INFINITY), (y[n - 1], 0.0, 0.0));
}

// ---------- 2. m = 2 vs textbook natural cubic spline ----------

/// Textbook natural cubic spline: tridiagonal system for M_i = S''(x_i) with M_1 = M_n = 0,
/// solved by the Thomas algorithm. Returns (S, S', S'') at t, linear extrapolation outside.
fn textbook_cubic(x: &[f64], y: &[f64], t: f64) -> (f64, f64, f64) {
    let n = x.len();
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    // h_{i−1} M_{i−1} + 2(h_{i−1} + h_i) M_i + h_i M_{i+1}
    //   = 6[(y_{i+1} − y_i)/h_i − (y_i − y_{i−1})/h_{i−1}], i = 1..n−2.
    let mut mm = vec![0.0; n];
    if n > 2 {
        let k = n - 2;
        let mut diag = vec![0.0; k];
        let mut sup = vec![0.0; k];
        let mut rhs = vec![0.0; k];
        for r in 0..k {
            let i = r + 1;
            diag[r] = 2.0 * (h[i - 1] + h[i]);
            sup[r] = h[i];
            rhs[r] = 6.0 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
        }
        // Thomas: sub-diagonal entry in row r is h[r] (= h_{i−1}).
        for r in 1..k {
            let w = h[r] / diag[r - 1];
            diag[r] -= w * sup[r - 1];
            rhs[r] -= w * rhs[r - 1];
        }
        let mut sol = vec![0.0; k];
        sol[k - 1] = rhs[k - 1] / diag[k - 1];
        for r in (0..k - 1).rev() {
            sol[r] = (rhs[r] - sup[r] * sol[r + 1]) / diag[r];
        }
        mm[1..n - 1].copy_from_slice(&sol);
    }
    let piece = |i: usize, t: f64| {
        let (a, b) = (x[i + 1] - t, t - x[i]);
        let hi = h[i];
        let v = mm[i] * a.powi(3) / (6.0 * hi)
            + mm[i + 1] * b.powi(3) / (6.0 * hi)
            + (y[i] / hi - mm[i] * hi / 6.0) * a
            + (y[i + 1] / hi - mm[i + 1] * hi / 6.0) * b;
        let d1 = -mm[i] * a * a / (2.0 * hi) + mm[i + 1] * b * b / (2.0 * hi)
            - (y[i] / hi - mm[i] * hi / 6.0)
            + (y[i + 1] / hi - mm[i + 1] * hi / 6.0);
        let d2 = mm[i] * a / hi + mm[i + 1] * b / hi;
        (v, d1, d2)
    };
    if t < x[0] {
        let (v, d1, _) = piece(0, x[0]);
        (v + d1 * (t - x[0]), d1, 0.0)
    } else if t > x[n - 1] {
        let (v, d1, _) = piece(n - 2, x[n - 1]);
        (v + d1 * (t - x[n - 1]), d1, 0.0)
    } else {
        let i = (0..n - 1).find(|&i| t <= x[i + 1]).unwrap();
        piece(i, t)
    }
}

#[test]
fn m2_matches_textbook_natural_cubic_spline() {
    let x = irregular_knots();
    let y = sample(&x);
    let s = NaturalSpline::interpolating(2, x.clone(), y.clone()).unwrap();
    for &t in &probe_points(&x) {
        let (v, d1, d2) = s.eval(t);
        let (rv, rd1, rd2) = textbook_cubic(&x, &y, t);
        assert!(close(v, rv, 1e-12, 1.0), "t={t}: value {v} vs {rv}");
        assert!(close(d1, rd1, 1e-12, 1.0), "t={t}: d1 {d1} vs {rd1}");
        assert!(close(d2, rd2, 1e-12, 1.0), "t={t}: d2 {d2} vs {rd2}");
    }
    // Linear extrapolation: second derivative exactly zero, slope constant.
    let n = x.len();
    let (_, slope_l, _) = s.eval(x[0]);
    let (_, slope_r, _) = s.eval(x[n - 1]);
    for dt in [0.1, 1.0, 10.0] {
        let (vl, d1l, d2l) = s.eval(x[0] - dt);
        assert!(close(vl, y[0] - slope_l * dt, 1e-12, 1.0 + dt));
        assert!(close(d1l, slope_l, 1e-13, 1.0));
        assert_eq!(d2l, 0.0);
        let (vr, d1r, d2r) = s.eval(x[n - 1] + dt);
        assert!(close(vr, y[n - 1] + slope_r * dt, 1e-12, 1.0 + dt));
        assert!(close(d1r, slope_r, 1e-13, 1.0));
        assert_eq!(d2r, 0.0);
    }
}

#[test]
fn m2_matches_textbook_on_300_random_knots() {
    let r = rand_seq(600, 0x9E3779B97F4A7C15);
    let mut x = Vec::new();
    let mut acc = 0.0;
    for i in 0..300 {
        acc += 0.01 + r[i]; // spacings in [0.01, 1.01)
        x.push(acc);
    }
    let y: Vec<f64> = (0..300).map(|i| 10.0 * (r[300 + i] - 0.5)).collect();
    let s = NaturalSpline::interpolating(2, x.clone(), y.clone()).unwrap();
    for &t in &probe_points(&x) {
        let (v, d1, d2) = s.eval(t);
        let (rv, rd1, rd2) = textbook_cubic(&x, &y, t);
        assert!(close(v, rv, 1e-11, 10.0), "t={t}: value {v} vs {rv}");
        assert!(close(d1, rd1, 1e-11, 1000.0), "t={t}: d1 {d1} vs {rd1}");
        assert!(close(d2, rd2, 1e-11, 1e5), "t={t}: d2 {d2} vs {rd2}");
    }
}

// ---------- 3. Reproduction of polynomials of degree ≤ m − 1 ----------

#[test]
fn reproduces_polynomials_of_degree_below_m() {
    let x = irregular_knots();
    // m = 2: linear; m = 3: quadratic; m = 4: cubic. (p, p', p'') closures.
    let cases: [(usize, fn(f64) -> (f64, f64, f64)); 3] = [
        (2, |t| (0.7 - 1.9 * t, -1.9, 0.0)),
        (3, |t| (0.3 + 0.5 * t - 1.2 * t * t, 0.5 - 2.4 * t, -2.4)),
        (4, |t| {
            (
                1.0 - t + 0.25 * t * t + 0.6 * t.powi(3),
                -1.0 + 0.5 * t + 1.8 * t * t,
                0.5 + 3.6 * t,
            )
        }),
    ];
    for (m, p) in cases {
        let y: Vec<f64> = x.iter().map(|&t| p(t).0).collect();
        let s = NaturalSpline::interpolating(m, x.clone(), y).unwrap();
        let mut ts = probe_points(&x);
        ts.extend([-20.0, 25.0]);
        for t in ts {
            let (v, d1, d2) = s.eval(t);
            let (rv, rd1, rd2) = p(t);
            let sc = 1.0 + t.abs().powi(m as i32);
            assert!(close(v, rv, 1e-12, sc), "m={m} t={t}: {v} vs {rv}");
            assert!(close(d1, rd1, 1e-11, sc), "m={m} t={t}: {d1} vs {rd1}");
            assert!(close(d2, rd2, 1e-10, sc), "m={m} t={t}: {d2} vs {rd2}");
        }
    }
}

#[test]
fn n_equal_m_gives_interpolating_polynomial() {
    // m = 3, three points: the quadratic through them.
    let x = vec![-0.5, 0.2, 1.7];
    let y = vec![1.0, -2.0, 0.5];
    let s = NaturalSpline::interpolating(3, x.clone(), y.clone()).unwrap();
    // Lagrange form as independent reference.
    let lag = |t: f64| -> f64 {
        (0..3)
            .map(|i| {
                let mut l = y[i];
                for j in 0..3 {
                    if j != i {
                        l *= (t - x[j]) / (x[i] - x[j]);
                    }
                }
                l
            })
            .sum()
    };
    for t in [-3.0, -0.5, 0.0, 0.2, 1.0, 1.7, 4.0] {
        assert!(close(s.eval(t).0, lag(t), 1e-12, 1.0 + t * t), "t={t}");
        assert!(s.derivative(t, 3).abs() < 1e-10, "t={t}");
    }
    // m = 4, four points: the cubic through them (here t³ − 2t).
    let x4 = vec![-1.0, 0.5, 0.7, 2.0];
    let y4: Vec<f64> = x4.iter().map(|t| t * t * t - 2.0 * t).collect();
    let s4 = NaturalSpline::interpolating(4, x4, y4).unwrap();
    for t in [-2.0, -1.0, 0.0, 0.6, 1.5, 2.0, 3.0] {
        let (v, d1, d2) = s4.eval(t);
        let sc = 1.0 + t.abs().powi(3);
        assert!(close(v, t * t * t - 2.0 * t, 1e-12, sc), "t={t}");
        assert!(close(d1, 3.0 * t * t - 2.0, 1e-11, sc), "t={t}");
        assert!(close(d2, 6.0 * t, 1e-10, sc), "t={t}");
    }
    // m = 1, a single point: a constant.
    let c = NaturalSpline::interpolating(1, vec![2.0], vec![-4.5]).unwrap();
    for t in [-1.0, 2.0, 7.0] {
        assert_eq!(c.eval(t), (-4.5, 0.0, 0.0));
    }
    // m = 2, two points: the line.
    let l = NaturalSpline::interpolating(2, vec![1.0, 3.0], vec![2.0, 6.0]).unwrap();
    for t in [-1.0, 1.0, 2.5, 3.0, 9.0] {
        let (v, d1, d2) = l.eval(t);
        assert!(
            close(v, 2.0 * t, 1e-13, t.abs()) && close(d1, 2.0, 1e-13, 1.0) && d2.abs() < 1e-12
        );
    }
}

// ---------- 4. Interpolation, continuity, natural end conditions ----------

fn check_defining_conditions(s: &NaturalSpline, x: &[f64], y: &[f64], tol: f64) {
    let m = s.half_order();
    let n = x.len();
    let ymax = y.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    for i in 0..n {
        let (v, _, _) = s.eval(x[i]);
        assert!(
            close(v, y[i], 1e-12, ymax),
            "m={m}: f(x[{i}]) = {v} vs {}",
            y[i]
        );
    }
    // Scale of each derivative order (for relative tolerances).
    let pieces: Vec<Piece> = std::iter::once(Piece::Left)
        .chain((0..n - 1).map(Piece::Interval))
        .chain(std::iter::once(Piece::Right))
        .collect();
    let order_scale: Vec<f64> = (0..2 * m)
        .map(|r| {
            (0..n - 1)
                .flat_map(|i| {
                    [
                        s.piece_derivative(Piece::Interval(i), x[i], r),
                        s.piece_derivative(Piece::Interval(i), x[i + 1], r),
                    ]
                })
                .fold(1e-300_f64, |a, v| a.max(v.abs()))
        })
        .collect();
    // C^(2m−2) at every knot, including across the end knots into the extrapolation.
    for i in 0..n {
        let (lp, rp) = (pieces[i], pieces[i + 1]);
        for r in 0..=2 * m - 2 {
            let a = s.piece_derivative(lp, x[i], r);
            let b = s.piece_derivative(rp, x[i], r);
            assert!(
                (a - b).abs() <= tol * order_scale[r],
                "m={m}: derivative {r} jumps at x[{i}]: {a} vs {b} (scale {})",
                order_scale[r]
            );
        }
    }
    // Natural end conditions: f^(j)(x_1) = f^(j)(x_n) = 0, j = m..2m−2, from the interval side.
    for r in m..=2 * m - 2 {
        let a = s.piece_derivative(Piece::Interval(0), x[0], r);
        let b = s.piece_derivative(Piece::Interval(n - 2), x[n - 1], r);
        assert!(a.abs() <= tol * order_scale[r], "m={m}: f^({r})(x_1) = {a}");
        assert!(b.abs() <= tol * order_scale[r], "m={m}: f^({r})(x_n) = {b}");
    }
    // Same continuity seen through eval (value, d1, d2) at x_i ± tiny.
    for i in 1..n - 1 {
        let eps = 1e-9 * (x[i + 1] - x[i - 1]);
        let (a0, a1, a2) = s.eval(x[i] - eps);
        let (b0, b1, b2) = s.eval(x[i] + eps);
        if m >= 2 {
            assert!(
                (a1 - b1).abs() <= 1e-6 * order_scale[1],
                "m={m} d1 at x[{i}]"
            );
        }
        if m >= 3 {
            assert!(
                (a2 - b2).abs() <= 1e-6 * order_scale[2],
                "m={m} d2 at x[{i}]"
            );
        }
        assert!((a0 - b0).abs() <= 1e-6 * order_scale[0].max(order_scale[1]));
    }
}

#[test]
fn interpolation_continuity_and_end_conditions_m1_to_m4() {
    let x = irregular_knots();
    let y = sample(&x);
    for m in 1..=4 {
        let s = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        check_defining_conditions(&s, &x, &y, 1e-11);
        // Degree 2m−1 is really used: the top derivative jumps at some interior knot.
        if m >= 2 {
            let top = 2 * m - 1;
            let jump = (1..x.len() - 1)
                .map(|i| {
                    (s.piece_derivative(Piece::Interval(i - 1), x[i], top)
                        - s.piece_derivative(Piece::Interval(i), x[i], top))
                    .abs()
                })
                .fold(0.0, f64::max);
            assert!(jump > 1e-3, "m={m}: no jump in derivative {top}");
        }
    }
}

#[test]
fn large_irregular_problem_m1_to_m4() {
    let n = 400;
    let r = rand_seq(2 * n, 12345);
    let mut x = Vec::with_capacity(n);
    let mut acc = 3.0;
    for i in 0..n {
        // Spacings spanning two orders of magnitude.
        acc += 0.01 * 10f64.powf(2.0 * r[i]);
        x.push(acc);
    }
    let y: Vec<f64> = (0..n)
        .map(|i| (x[i] * 2.0).sin() + 0.3 * (r[n + i] - 0.5))
        .collect();
    for m in 1..=4 {
        let s = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        check_defining_conditions(&s, &x, &y, 1e-10);
    }
}

#[test]
fn very_short_end_and_interior_intervals_stay_accurate() {
    // A short first/last interval makes B-spline rows for f^(r)(x_1) = 0 nearly dependent;
    // the Taylor/blossom treatment of the ends must keep full accuracy. Spacing ratio 1e4.
    let d = 1e-4;
    let layouts = [
        vec![0.0, d, 1.0, 1.7, 2.0, 3.0],
        vec![0.0, 1.0, 1.7, 2.0, 3.0 - d, 3.0],
        vec![0.0, 1.0, 1.0 + d, 1.7, 2.0, 3.0],
        vec![0.0, d, 1.0, 1.0 + d, 2.0, 3.0 - d, 3.0],
    ];
    for x in &layouts {
        for m in 2..=4 {
            // Polynomial of degree m − 1: reproduced everywhere.
            let p = |t: f64| -> f64 {
                let mut v = 1.0 - 0.5 * t;
                if m >= 3 {
                    v += 0.3 * t * t;
                }
                if m >= 4 {
                    v -= 0.2 * t * t * t;
                }
                v
            };
            let y: Vec<f64> = x.iter().map(|&t| p(t)).collect();
            let s = NaturalSpline::interpolating(m, x.clone(), y).unwrap();
            for i in 0..=600 {
                let t = -1.0 + 5.0 * i as f64 / 600.0;
                let err = (s.eval(t).0 - p(t)).abs();
                assert!(err < 1e-9, "m={m} x={x:?} t={t}: error {err:e}");
            }
            // Non-polynomial data: defining conditions.
            let y = sample(x);
            let s = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
            for (i, (&xi, &yi)) in x.iter().zip(&y).enumerate() {
                assert!((s.eval(xi).0 - yi).abs() < 1e-12, "m={m} x={x:?} knot {i}");
            }
            check_defining_conditions(&s, x, &y, 1e-9);
        }
        // m = 2 against the textbook natural cubic spline.
        let y = sample(x);
        let s = NaturalSpline::interpolating(2, x.clone(), y.clone()).unwrap();
        for t in probe_points(x) {
            let (v, d1, d2) = s.eval(t);
            let (rv, rd1, rd2) = textbook_cubic(x, &y, t);
            assert!(close(v, rv, 1e-10, 1.0), "x={x:?} t={t}: {v} vs {rv}");
            assert!(
                close(d1, rd1, 1e-10, rd1.abs()),
                "x={x:?} t={t}: {d1} vs {rd1}"
            );
            assert!(
                close(d2, rd2, 1e-9, rd2.abs()),
                "x={x:?} t={t}: {d2} vs {rd2}"
            );
        }
    }
}

#[test]
fn invariant_under_affine_change_of_abscissa_and_scaling_of_data() {
    let x = irregular_knots();
    let y = sample(&x);
    let (a, b, c) = (1e3, -7.0, 1e-4); // x' = a x + b, y' = c y
    let x2: Vec<f64> = x.iter().map(|v| a * v + b).collect();
    let y2: Vec<f64> = y.iter().map(|v| c * v).collect();
    for m in 1..=4 {
        let s1 = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        let s2 = NaturalSpline::interpolating(m, x2.clone(), y2.clone()).unwrap();
        for t in probe_points(&x) {
            let (v1, d11, d21) = s1.eval(t);
            let (v2, d12, d22) = s2.eval(a * t + b);
            assert!(close(v2 / c, v1, 1e-10, 1.0 + t * t), "m={m} t={t}");
            assert!(close(d12 * a / c, d11, 1e-9, 1.0 + t.abs()), "m={m} t={t}");
            assert!(close(d22 * a * a / c, d21, 1e-8, 1.0), "m={m} t={t}");
        }
    }
}

/// Independent reference for m = 3, 4: assemble the full square system of interpolation,
/// C^(2m−2) continuity and natural end conditions for per-interval monomials in local
/// s ∈ [0, 1], solve with dense LU.
fn collocation_reference(m: usize, x: &[f64], y: &[f64]) -> Vec<Vec<f64>> {
    let n = x.len();
    let p = 2 * m;
    let size = (n - 1) * p;
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let mut a = DMatrix::<f64>::zeros(size, size);
    let mut b = DVector::<f64>::zeros(size);
    let mut row = 0;
    // r-th t-derivative of s^k at s: k!/(k−r)! s^{k−r} / h^r.
    let basis = |k: usize, r: usize, s: f64, hi: f64| -> f64 {
        if k < r {
            0.0
        } else {
            falling_factorial(k, r) * s.powi((k - r) as i32) / hi.powi(r as i32)
        }
    };
    for i in 0..n - 1 {
        for k in 0..p {
            a[(row, i * p + k)] = basis(k, 0, 0.0, h[i]);
            a[(row + 1, i * p + k)] = basis(k, 0, 1.0, h[i]);
        }
        b[row] = y[i];
        b[row + 1] = y[i + 1];
        row += 2;
    }
    for i in 1..n - 1 {
        for r in 1..=2 * m - 2 {
            for k in 0..p {
                a[(row, (i - 1) * p + k)] = basis(k, r, 1.0, h[i - 1]);
                a[(row, i * p + k)] = -basis(k, r, 0.0, h[i]);
            }
            row += 1;
        }
    }
    for r in m..=2 * m - 2 {
        for k in 0..p {
            a[(row, k)] = basis(k, r, 0.0, h[0]);
            a[(row + 1, (n - 2) * p + k)] = basis(k, r, 1.0, h[n - 2]);
        }
        row += 2;
    }
    assert_eq!(row, size);
    let sol = a.lu().solve(&b).expect("reference system singular");
    (0..n - 1)
        .map(|i| sol.rows(i * p, p).iter().copied().collect())
        .collect()
}

#[test]
fn m3_m4_match_direct_collocation_system() {
    let x = irregular_knots();
    let y = sample(&x);
    for m in 3..=4 {
        let s = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        let reference = collocation_reference(m, &x, &y);
        for (i, c) in reference.iter().enumerate() {
            for k in 0..=10 {
                let sl = k as f64 / 10.0;
                let t = x[i] + sl * (x[i + 1] - x[i]);
                let h = x[i + 1] - x[i];
                let mut rv = [0.0; 3];
                for (j, &cj) in c.iter().enumerate() {
                    rv[0] += cj * sl.powi(j as i32);
                    if j >= 1 {
                        rv[1] += cj * j as f64 * sl.powi(j as i32 - 1) / h;
                    }
                    if j >= 2 {
                        rv[2] += cj * (j * (j - 1)) as f64 * sl.powi(j as i32 - 2) / (h * h);
                    }
                }
                let (v, d1, d2) = s.piece_eval(Piece::Interval(i), t);
                assert!(close(v, rv[0], 1e-12, 1.0), "m={m} t={t}: {v} vs {}", rv[0]);
                assert!(
                    close(d1, rv[1], 1e-11, 1.0),
                    "m={m} t={t}: {d1} vs {}",
                    rv[1]
                );
                assert!(
                    close(d2, rv[2], 1e-10, 10.0),
                    "m={m} t={t}: {d2} vs {}",
                    rv[2]
                );
            }
        }
    }
}

// ---------- 5. Minimum-norm property and derivative consistency ----------

/// ∫_{x_1}^{x_n} g² dx, by 6-point Gauss–Legendre on every knot interval (exact for
/// piecewise-polynomial g of degree ≤ 5); g is a derivative f^(r) of the function under test.
fn seminorm(x: &[f64], g: &dyn Fn(f64) -> f64) -> f64 {
    const NODES: [f64; 6] = [
        -0.932_469_514_203_152_0,
        -0.661_209_386_466_264_5,
        -0.238_619_186_083_196_9,
        0.238_619_186_083_196_9,
        0.661_209_386_466_264_5,
        0.932_469_514_203_152_0,
    ];
    const WEIGHTS: [f64; 6] = [
        0.171_324_492_379_170_3,
        0.360_761_573_048_138_6,
        0.467_913_934_572_691_0,
        0.467_913_934_572_691_0,
        0.360_761_573_048_138_6,
        0.171_324_492_379_170_3,
    ];
    x.windows(2)
        .map(|w| {
            let (mid, half) = ((w[0] + w[1]) / 2.0, (w[1] - w[0]) / 2.0);
            NODES
                .iter()
                .zip(WEIGHTS)
                .map(|(&z, wt)| wt * half * g(mid + half * z).powi(2))
                .sum::<f64>()
        })
        .sum()
}

#[test]
fn m3_minimises_integral_of_squared_third_derivative() {
    let x = vec![0.0, 0.4, 0.5, 1.1, 1.5, 2.3, 2.6];
    let y = sample(&x);
    let s3 = NaturalSpline::interpolating(3, x.clone(), y.clone()).unwrap();
    let j3 = seminorm(&x, &|t| s3.derivative(t, 3));
    assert!(j3 > 0.0);
    // Perturbation vanishing at all knots: ω(x) = Π (x − x_i), degree 7, ω''' degree 4.
    let omega3 = |t: f64| -> f64 {
        // Expand Π(t − x_i) into monomial coefficients, then differentiate exactly.
        let mut c = vec![1.0];
        for &xi in &x {
            let mut nc = vec![0.0; c.len() + 1];
            for (k, &ck) in c.iter().enumerate() {
                nc[k + 1] += ck;
                nc[k] -= xi * ck;
            }
            c = nc;
        }
        c.iter()
            .enumerate()
            .skip(3)
            .map(|(k, &ck)| ck * falling_factorial(k, 3) * t.powi(k as i32 - 3))
            .sum()
    };
    let j_omega = seminorm(&x, &omega3);
    for eps in [1e-3, -0.05, 0.5, 3.0] {
        let j = seminorm(&x, &|t| s3.derivative(t, 3) + eps * omega3(t));
        assert!(j > j3, "eps={eps}: {j} <= {j3}");
        // Orthogonality: J(f + εω) = J(f) + ε² J(ω) exactly.
        let pred = j3 + eps * eps * j_omega;
        assert!((j - pred).abs() <= 1e-8 * pred, "eps={eps}: {j} vs {pred}");
    }
    // Other interpolants in H³: the natural cubic (m = 2) and septic (m = 4) splines.
    for m in [2, 4] {
        let other = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        let j = seminorm(&x, &|t| other.derivative(t, 3));
        assert!(j > j3 * (1.0 + 1e-6), "m={m}: {j} vs {j3}");
    }
    // And the same for m = 2: the cubic spline minimises ∫(f'')² against the quintic.
    let s2 = NaturalSpline::interpolating(2, x.clone(), y.clone()).unwrap();
    let j2 = seminorm(&x, &|t| s2.derivative(t, 2));
    let j2_of_s3 = seminorm(&x, &|t| s3.derivative(t, 2));
    assert!(j2_of_s3 > j2 * (1.0 + 1e-6));
}

#[test]
fn eval_derivatives_match_finite_differences() {
    let x = irregular_knots();
    let y = sample(&x);
    for m in 1..=4 {
        let s = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
        let hfd = 1e-6;
        for t in probe_points(&x) {
            // Stay away from knots for m = 1 (kinks) and for the second derivative of m = 2.
            if x.iter().any(|&k| (t - k).abs() < 10.0 * hfd) {
                continue;
            }
            let (_, d1, d2) = s.eval(t);
            let fd1 = (s.eval(t + hfd).0 - s.eval(t - hfd).0) / (2.0 * hfd);
            let fd2 = (s.eval(t + hfd).1 - s.eval(t - hfd).1) / (2.0 * hfd);
            assert!(close(d1, fd1, 1e-7, d1.abs()), "m={m} t={t}: {d1} vs {fd1}");
            assert!(close(d2, fd2, 1e-7, d2.abs()), "m={m} t={t}: {d2} vs {fd2}");
            // `derivative` agrees with `eval`.
            assert!(close(s.derivative(t, 1), d1, 1e-13, d1.abs()));
            assert!(close(s.derivative(t, 2), d2, 1e-13, d2.abs()));
            assert!(close(s.derivative(t, 0), s.eval(t).0, 1e-14, 1.0));
        }
    }
}

// ---------- 6. Bad input ----------

#[test]
fn rejects_bad_input_without_panicking() {
    let ok_x = vec![0.0, 1.0, 2.0, 3.0, 4.0];
    let ok_y = vec![1.0, 2.0, 0.0, 1.0, 3.0];
    let cases: Vec<(usize, Vec<f64>, Vec<f64>, &str)> = vec![
        (
            3,
            vec![0.0, 2.0, 1.0, 3.0, 4.0],
            ok_y.clone(),
            "strictly increasing",
        ),
        (
            3,
            vec![0.0, 1.0, 1.0, 3.0, 4.0],
            ok_y.clone(),
            "strictly increasing (x[2] = 1 after x[1] = 1)",
        ),
        (
            3,
            vec![0.0, 1.0, f64::NAN, 3.0, 4.0],
            ok_y.clone(),
            "x values must be finite (x[2] = NaN)",
        ),
        (
            3,
            ok_x.clone(),
            vec![1.0, f64::NAN, 0.0, 1.0, 3.0],
            "y values must be finite (y[1] = NaN)",
        ),
        (
            3,
            vec![0.0, 1.0, 2.0, 3.0, f64::INFINITY],
            ok_y.clone(),
            "finite",
        ),
        (3, ok_x.clone(), vec![1.0, 2.0, 3.0], "same length"),
        (0, ok_x.clone(), ok_y.clone(), "half order"),
        (5, ok_x.clone(), ok_y.clone(), "half order"),
        (
            4,
            vec![0.0, 1.0, 2.0],
            vec![1.0, 2.0, 3.0],
            "at least 4 data points",
        ),
        (1, vec![], vec![], "at least one data point"),
        (2, vec![-1e308, 1e308], vec![0.0, 1.0], "too large"),
    ];
    for (m, x, y, msg) in cases {
        let err = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap_err();
        assert!(
            err.contains(msg),
            "m={m} x={x:?}: got {err:?}, expected to contain {msg:?}"
        );
    }
    // Extreme but valid inputs either succeed with finite results or give an Err.
    let extreme = [
        (4, vec![0.0, 1e-200, 1.0, 2.0, 3.0], ok_y.clone()),
        (4, ok_x.clone(), vec![1e300, -1e300, 1e300, -1e300, 1e300]),
        (2, vec![1e15, 1e15 + 0.25, 1e15 + 0.5], vec![0.0, 1.0, 0.0]),
    ];
    for (m, x, y) in extreme {
        if let Ok(s) = NaturalSpline::interpolating(m, x.clone(), y) {
            for &t in &x {
                let (v, _, _) = s.eval(t);
                assert!(v.is_finite());
            }
        }
    }
    // NaN abscissa in eval gives NaN, no panic.
    let s = NaturalSpline::interpolating(3, ok_x, ok_y).unwrap();
    assert!(s.eval(f64::NAN).0.is_nan());
}

/// Several columns built together equal each column built alone, bit for bit; a bad column is
/// named by its index.
#[test]
fn columns_built_together_equal_columns_built_alone() {
    let x: Vec<f64> = (0..40)
        .map(|i| 0.05 * i as f64 + 0.001 * (i as f64).sin())
        .collect();
    let ys: Vec<Vec<f64>> = (0..5)
        .map(|c| {
            x.iter()
                .map(|&t| (c as f64 * 1.3 * t).cos() * (c + 1) as f64)
                .collect()
        })
        .collect();
    for m in 1..=4 {
        let together = NaturalSpline::interpolating_many(m, x.clone(), ys.clone()).unwrap();
        for (y, s) in ys.iter().zip(&together) {
            let alone = NaturalSpline::interpolating(m, x.clone(), y.clone()).unwrap();
            assert_eq!(&alone, s);
        }
    }
    let mut bad = ys.clone();
    bad[3][7] = f64::NAN;
    let (column, message) = NaturalSpline::interpolating_many(3, x, bad).unwrap_err();
    assert_eq!(column, 3);
    assert!(message.contains("y[7]"), "{message}");
}
