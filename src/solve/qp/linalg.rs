//! The sparse kernel of the dual Newton method: A by its nonzero entries ([`SparseColumns`]).
//! The dense kernels it shares with other solvers are in [`crate::linalg`].

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{cholesky_in_place, cholesky_solve_in_place};

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
}
