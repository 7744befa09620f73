//! Small dense linear algebra on flat slices, shared by the QP, the muscle wrapping solver and
//! the layout inverses: n × n matrices in column-major storage (entry (r, c) at `c * n + r`;
//! only the lower triangle r ≥ c of symmetric matrices is used), except the general solve
//! [`lu_solve_in_place`], which takes its matrix row-major. The kernels allocate nothing and
//! never panic on finite input; the loops run over contiguous slices so that they vectorise.

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

/// Solves A x = b in place for a general (unsymmetric) A: LU with partial pivoting, A
/// row-major n × n and overwritten, b becomes x; false when a pivot vanishes (below 1e-14 of
/// A's largest entry).
pub(crate) fn lu_solve_in_place(a: &mut [f64], n: usize, b: &mut [f64]) -> bool {
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for c in 0..n {
        // the row with the largest entry in column c, from c down
        let p = (c..n)
            .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
            .unwrap_or(c);
        if !(a[p * n + c].abs() > 1e-14 * scale) {
            return false;
        }
        if p != c {
            for k in 0..n {
                a.swap(c * n + k, p * n + k);
            }
            b.swap(c, p);
        }
        let pivot = a[c * n + c];
        for i in c + 1..n {
            let factor = a[i * n + c] / pivot;
            if factor == 0.0 {
                continue;
            }
            for k in c..n {
                a[i * n + k] -= factor * a[c * n + k];
            }
            b[i] -= factor * b[c];
        }
    }
    for c in (0..n).rev() {
        let s: f64 = (c + 1..n).map(|k| a[c * n + k] * b[k]).sum();
        b[c] = (b[c] - s) / a[c * n + c];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The in-place LU solve equals nalgebra's on a random matrix whose first pivot is 0.
    #[test]
    fn lu_solve_in_place_matches_nalgebra() {
        let n = 7;
        let mut rng = crate::random::SplitMix64(5);
        let mut a: Vec<f64> = (0..n * n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        a[0] = 0.0;
        let b: Vec<f64> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let m = nalgebra::DMatrix::from_row_slice(n, n, &a);
        let x = m
            .lu()
            .solve(&nalgebra::DVector::from_column_slice(&b))
            .unwrap();
        let mut ours = b.clone();
        assert!(lu_solve_in_place(&mut a, n, &mut ours));
        for (u, v) in ours.iter().zip(x.iter()) {
            assert!((u - v).abs() < 1e-12 * (1.0 + v.abs()), "{u} vs {v}");
        }
        let mut singular = vec![1.0; 4];
        assert!(!lu_solve_in_place(&mut singular, 2, &mut [1.0, 2.0]));
    }

    #[test]
    fn cholesky_reports_an_indefinite_matrix() {
        let mut m = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut m, 2));
    }
}
