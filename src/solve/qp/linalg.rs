//! The kernels of the dual Newton method: A by its nonzero entries ([`SparseColumns`]), and
//! dense n × n matrices on flat column-major storage (entry (r, c) at `c * n + r`; only the
//! lower triangle r ≥ c of symmetric matrices is used; the general solve
//! [`lu_solve_in_place`] takes its matrix row-major). They allocate nothing and never panic
//! on finite input; the dense loops run over contiguous column slices so that they vectorise.

use super::QpError;

/// A matrix stored by columns with only its nonzero entries (compressed sparse columns).
/// Column i holds `rows[start[i]..start[i + 1]]` (ascending) and the values beside them.
///
/// Static optimization's A has a column per actuator and a row per coordinate; a muscle
/// spans a few coordinates, so its column has ≈ 3 nonzeros of 29 on the default model (1,130
/// of 10,237 entries per frame). Every product with A then costs its nonzeros, and a caller
/// that knows its columns can hand them over this way ([`super::QpMatrix::Sparse`]) without
/// ever forming the dense matrix.
#[derive(Clone, Debug)]
pub struct SparseColumns {
    n: usize,
    start: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
}

impl SparseColumns {
    /// An empty matrix of `n` rows, with room for `m` columns, so that
    /// [`SparseColumns::clear`] and the pushes of up to m columns never allocate.
    pub fn with_capacity(n: usize, m: usize) -> Self {
        let mut start = Vec::with_capacity(m + 1);
        start.push(0);
        SparseColumns {
            n,
            start,
            rows: Vec::with_capacity(n * m),
            values: Vec::with_capacity(n * m),
        }
    }

    /// Rows n.
    pub fn nrows(&self) -> usize {
        self.n
    }

    /// Columns pushed so far.
    pub fn ncols(&self) -> usize {
        self.start.len() - 1
    }

    /// Empties the matrix (keeping its storage and its number of rows).
    pub fn clear(&mut self) {
        self.start.truncate(1);
        self.rows.clear();
        self.values.clear();
    }

    /// Appends a column from its n dense entries, keeping those that are not zero (a NaN is
    /// kept). A column of another length is refused.
    pub fn push(&mut self, column: &[f64]) -> Result<(), QpError> {
        self.push_scaled(column, 1.0)
    }

    /// Appends `scale` times a column of n dense entries, keeping the products that are not
    /// zero (a NaN is kept). A column of another length is refused.
    pub fn push_scaled(&mut self, column: &[f64], scale: f64) -> Result<(), QpError> {
        if column.len() != self.n {
            return Err(QpError::WrongSize {
                argument: "column",
                expected: self.n,
                actual: column.len(),
            });
        }
        for (r, &v) in column.iter().enumerate() {
            let v = v * scale;
            if v != 0.0 {
                self.rows.push(r);
                self.values.push(v);
            }
        }
        self.start.push(self.rows.len());
        Ok(())
    }

    /// Row indices (ascending) and values of the nonzero entries of column i; None past the
    /// last column.
    pub fn entries(&self, i: usize) -> Option<(&[usize], &[f64])> {
        (i < self.ncols()).then(|| self.column(i))
    }

    /// Entry (row, column): 0 where the column has no entry for the row; None outside the
    /// matrix.
    pub fn get(&self, row: usize, column: usize) -> Option<f64> {
        let (rows, values) = self.entries(column)?;
        (row < self.n).then(|| match rows.binary_search(&row) {
            Ok(k) => values[k],
            Err(_) => 0.0,
        })
    }

    /// Becomes a copy of `other`, reusing this matrix's storage (no allocation when it has
    /// room).
    pub(crate) fn assign(&mut self, other: &SparseColumns) {
        self.n = other.n;
        self.start.clear();
        self.start.extend_from_slice(&other.start);
        self.rows.clear();
        self.rows.extend_from_slice(&other.rows);
        self.values.clear();
        self.values.extend_from_slice(&other.values);
    }

    /// Row indices and values of column i.
    #[inline]
    pub(crate) fn column(&self, i: usize) -> (&[usize], &[f64]) {
        let range = self.start[i]..self.start[i + 1];
        (&self.rows[range.clone()], &self.values[range])
    }

    /// aᵢᵀv.
    #[inline]
    pub(crate) fn dot(&self, i: usize, v: &[f64]) -> f64 {
        let (rows, values) = self.column(i);
        rows.iter().zip(values).map(|(&r, &a)| a * v[r]).sum()
    }

    /// H += c aᵢ aᵢᵀ on the lower triangle of the column-major n × n matrix `h` (entry (r, c)
    /// at `h[c * n + r]`, r ≥ c): nnz(aᵢ)(nnz(aᵢ) + 1)/2 products.
    #[inline]
    pub(crate) fn rank_update(&self, h: &mut [f64], n: usize, i: usize, c: f64) {
        let (rows, values) = self.column(i);
        for (k, (&col, &v)) in rows.iter().zip(values).enumerate() {
            let t = c * v;
            let h_col = &mut h[col * n..(col + 1) * n];
            for (&row, &w) in rows[k..].iter().zip(&values[k..]) {
                h_col[row] += t * w;
            }
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

    /// Columns with zeros in them (about a third of the entries), as A's columns have: dense,
    /// and as [`SparseColumns`].
    fn sparse_test_columns(n: usize) -> (Vec<Vec<f64>>, SparseColumns) {
        let cols: Vec<Vec<f64>> = (0..11)
            .map(|k| {
                (0..n)
                    .map(|r| {
                        if (r + 2 * k) % 3 == 0 {
                            0.0
                        } else {
                            ((r * 7 + k * 3) % 5) as f64 - 2.0 + 0.1 * k as f64
                        }
                    })
                    .collect()
            })
            .collect();
        let mut a = SparseColumns::with_capacity(n, cols.len());
        for c in &cols {
            a.push(c).expect("n entries");
        }
        (cols, a)
    }

    #[test]
    fn sparse_columns_keep_the_nonzeros_and_their_products_match_dense_ones() {
        let n = 7;
        let (cols, mut a) = sparse_test_columns(n);
        let v: Vec<f64> = (0..n).map(|r| 0.3 * r as f64 - 1.1).collect();
        let mut h = vec![0.0; n * n];
        for (i, c) in cols.iter().enumerate() {
            let (rows, values) = a.column(i);
            let dense_nonzeros: Vec<usize> = (0..n).filter(|&r| c[r] != 0.0).collect();
            assert_eq!(rows, dense_nonzeros.as_slice());
            assert!(values.iter().zip(rows).all(|(x, &r)| *x == c[r]));
            let dense_dot: f64 = c.iter().zip(&v).map(|(x, y)| x * y).sum();
            assert!((a.dot(i, &v) - dense_dot).abs() < 1e-12);
            a.rank_update(&mut h, n, i, 0.5 + 0.1 * i as f64);
        }
        // H = Σᵢ cᵢ aᵢ aᵢᵀ entry by entry
        for col in 0..n {
            for row in col..n {
                let expect: f64 = (cols.iter().enumerate())
                    .map(|(i, c)| (0.5 + 0.1 * i as f64) * c[row] * c[col])
                    .sum();
                assert!((h[col * n + row] - expect).abs() < 1e-12, "({row}, {col})");
            }
        }
        a.clear();
        let mut c = vec![0.0; n];
        (c[1], c[2]) = (f64::NAN, 2.0);
        a.push(&c).expect("n entries");
        assert_eq!(a.column(0).0, &[1, 2]);
        assert!(a.column(0).1[0].is_nan());
        // scaled: products that vanish are dropped; a column of another length is refused
        a.push_scaled(&c, 0.0).expect("n entries");
        assert_eq!(a.ncols(), 2);
        assert_eq!(a.entries(1).map(|e| e.0.len()), Some(1)); // NaN · 0 is NaN, kept
        assert!(a.entries(2).is_none());
        assert_eq!(
            (a.get(2, 0), a.get(0, 0), a.get(n, 0), a.get(0, 2)),
            (Some(2.0), Some(0.0), None, None)
        );
        assert!(matches!(
            a.push(&c[..n - 1]),
            Err(QpError::WrongSize {
                expected: 7,
                actual: 6,
                ..
            })
        ));
        assert_eq!(a.ncols(), 2);
        let mut b = SparseColumns::with_capacity(3, 1);
        b.assign(&a);
        assert_eq!((b.nrows(), b.ncols()), (n, 2));
        let (rows, values) = b.entries(0).expect("copied");
        assert_eq!(rows, &[1, 2]);
        assert!(values[0].is_nan() && values[1] == 2.0);
    }

    #[test]
    fn cholesky_solves_a_symmetric_positive_definite_system() {
        let n = 7;
        let (cols, a) = sparse_test_columns(n);
        let mut h = vec![0.0; n * n];
        for i in 0..cols.len() {
            a.rank_update(&mut h, n, i, 0.5);
        }
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
        for i in 0..cols.len() {
            a.rank_update(&mut h, n, i, -0.5);
        }
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
