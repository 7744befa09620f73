//! The dense kernels of the dual Newton method, on flat column-major n × n storage (entry
//! (r, c) at `c * n + r`; only the lower triangle r ≥ c of symmetric matrices is used). They
//! allocate nothing and never panic on finite input; all loops run over contiguous column
//! slices so that they vectorise.

/// H += Σ_k c_k a_k a_kᵀ (lower triangle) for the columns `a_k = column(k)` and coefficients
/// `c_k` yielded by `terms` — the rank-k update that adds (c > 0) or removes (c < 0) columns of
/// the dual Hessian A D Aᵀ. Columns are taken four at a time so that each entry of H is loaded
/// and stored once per four rank-1 terms.
pub(crate) fn symmetric_rank_update<'a>(
    h: &mut [f64],
    n: usize,
    mut terms: impl Iterator<Item = (&'a [f64], f64)>,
) {
    loop {
        let Some((a0, c0)) = terms.next() else { return };
        let Some((a1, c1)) = terms.next() else {
            rank_update_1(h, n, a0, c0);
            return;
        };
        let Some((a2, c2)) = terms.next() else {
            rank_update_1(h, n, a0, c0);
            rank_update_1(h, n, a1, c1);
            return;
        };
        let Some((a3, c3)) = terms.next() else {
            rank_update_1(h, n, a0, c0);
            rank_update_1(h, n, a1, c1);
            rank_update_1(h, n, a2, c2);
            return;
        };
        for col in 0..n {
            // H[col.., col] += Σ_k (c_k a_k[col]) a_k[col..]
            let (t0, t1, t2, t3) = (c0 * a0[col], c1 * a1[col], c2 * a2[col], c3 * a3[col]);
            let h_col = &mut h[col * n + col..(col + 1) * n];
            let rows = h_col
                .iter_mut()
                .zip(&a0[col..n])
                .zip(&a1[col..n])
                .zip(&a2[col..n])
                .zip(&a3[col..n]);
            for ((((hr, &x0), &x1), &x2), &x3) in rows {
                *hr += t0 * x0 + t1 * x1 + t2 * x2 + t3 * x3;
            }
        }
    }
}

/// H += c a aᵀ (lower triangle).
fn rank_update_1(h: &mut [f64], n: usize, a: &[f64], c: f64) {
    for col in 0..n {
        let t = c * a[col];
        if t == 0.0 {
            continue;
        }
        let h_col = &mut h[col * n + col..(col + 1) * n];
        for (hr, &x) in h_col.iter_mut().zip(&a[col..n]) {
            *hr += t * x;
        }
    }
}

/// In-place Cholesky factorisation M = L Lᵀ of the lower triangle of `m` (right-looking, one
/// column at a time: L[j,j] = √M[j,j], L[j+1..,j] = M[j+1..,j] / L[j,j], then the trailing
/// M[c..,c] −= L[c,j] L[c..,j]). Returns false, leaving `m` partly overwritten, when a pivot
/// is not positive and finite (the matrix is not numerically positive definite).
pub(crate) fn cholesky_in_place(m: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let pivot = m[j * n + j];
        if !(pivot > 0.0 && pivot.is_finite()) {
            return false;
        }
        let l_jj = pivot.sqrt();
        m[j * n + j] = l_jj;
        let inv = 1.0 / l_jj;
        for v in &mut m[j * n + j + 1..(j + 1) * n] {
            *v *= inv;
        }
        let (done, trailing) = m.split_at_mut((j + 1) * n);
        let l_j = &done[j * n..(j + 1) * n];
        for c in j + 1..n {
            let t = l_j[c];
            if t == 0.0 {
                continue;
            }
            let col = &mut trailing[(c - j - 1) * n + c..(c - j) * n];
            for (v, &l) in col.iter_mut().zip(&l_j[c..n]) {
                *v -= t * l;
            }
        }
    }
    true
}

/// Solves L Lᵀ x = rhs in place for the factor of [`cholesky_in_place`]: forward
/// substitution L y = rhs by columns, then back substitution Lᵀ x = y by dot products with
/// the (contiguous) columns of L.
pub(crate) fn cholesky_solve_in_place(l: &[f64], n: usize, x: &mut [f64]) {
    for j in 0..n {
        let l_col = &l[j * n..(j + 1) * n];
        let xj = x[j] / l_col[j];
        x[j] = xj;
        for (xr, &lr) in x[j + 1..n].iter_mut().zip(&l_col[j + 1..n]) {
            *xr -= lr * xj;
        }
    }
    for j in (0..n).rev() {
        let l_col = &l[j * n..(j + 1) * n];
        let dot = dot(&l_col[j + 1..n], &x[j + 1..n]);
        x[j] = (x[j] - dot) / l_col[j];
    }
}

/// uᵀv with four independent accumulators (so that the sum vectorises).
pub(crate) fn dot(u: &[f64], v: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (u4, u_rest) = u.split_at(u.len() / 4 * 4);
    let (v4, v_rest) = v.split_at(u4.len());
    for (uc, vc) in u4.chunks_exact(4).zip(v4.chunks_exact(4)) {
        acc[0] += uc[0] * vc[0];
        acc[1] += uc[1] * vc[1];
        acc[2] += uc[2] * vc[2];
        acc[3] += uc[3] * vc[3];
    }
    let mut sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (a, b) in u_rest.iter().zip(v_rest) {
        sum += a * b;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_symmetric_positive_definite_system() {
        let n = 7;
        let cols: Vec<Vec<f64>> = (0..11)
            .map(|k| {
                (0..n)
                    .map(|r| ((r * 7 + k * 3) % 5) as f64 - 2.0 + 0.1 * k as f64)
                    .collect()
            })
            .collect();
        let mut h = vec![0.0; n * n];
        symmetric_rank_update(&mut h, n, cols.iter().map(|c| (c.as_slice(), 0.5)));
        for j in 0..n {
            h[j * n + j] += 1e-3;
        }
        let full = |r: usize, c: usize| if r >= c { h[c * n + r] } else { h[r * n + c] };
        let x_true: Vec<f64> = (0..n).map(|i| i as f64 - 3.0).collect();
        let mut rhs: Vec<f64> = (0..n)
            .map(|r| (0..n).map(|c| full(r, c) * x_true[c]).sum())
            .collect();
        let mut l = h.clone();
        assert!(cholesky_in_place(&mut l, n));
        cholesky_solve_in_place(&l, n, &mut rhs);
        for (x, t) in rhs.iter().zip(&x_true) {
            assert!((x - t).abs() < 1e-9, "{x} vs {t}");
        }
        // Removing the columns again leaves the diagonal shift only.
        symmetric_rank_update(&mut h, n, cols.iter().map(|c| (c.as_slice(), -0.5)));
        for c in 0..n {
            for r in c..n {
                let expect = if r == c { 1e-3 } else { 0.0 };
                assert!((h[c * n + r] - expect).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn cholesky_reports_an_indefinite_matrix() {
        let mut m = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut m, 2));
    }
}
