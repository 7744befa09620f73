//! The LTL factorization of a symmetric positive-definite matrix with branch-induced
//! sparsity (Featherstone, *Rigid Body Dynamics Algorithms*, 2008, §6.5).
//!
//! A matrix whose rows and columns are indexed by a kinematic tree's coordinates — the mass
//! matrix, or the normal matrix Σ wᵢ Jᵢᵀ Jᵢ of point targets — has A_ij ≠ 0 only where one of
//! i, j lies on the other's path to the root. Factored from the leaves towards the root as
//! A = Lᵀ L (L lower triangular), such a matrix fills in nothing: row k of L has entries only
//! at k and at k's ancestors λ(k), λ(λ(k)), …, and the factorization costs Σ_k d_k²/2
//! multiply–adds (d_k the depth of k) instead of n³/6.
//!
//! For any other pattern the same code applies with λ the *elimination tree* of the pattern
//! under this order (Liu 1990): eliminating k (from n − 1 down to 0) joins every pair of its
//! remaining neighbours, and λ(k) is its largest remaining neighbour. The rows of L then lie
//! within the ancestor chains, and a dense pattern degrades gracefully to a chain
//! (λ(k) = k − 1), i.e. a dense Cholesky factorization.
//!
//!   for k = n−1 … 0:   L_kk = √A_kk,   L_ki = A_ki / L_kk  (i ∈ anc(k)),
//!                      A_ij −= L_ki L_kj  (i ∈ anc(k), j ∈ anc(i) ∪ {i});
//!   Lᵀ y = b:  for k = n−1 … 0:  y_k /= L_kk,  y_i −= L_ki y_k  (i ∈ anc(k));
//!   L x = y:   for k = 0 … n−1:  x_k = (y_k − Σ_{i ∈ anc(k)} L_ki x_i) / L_kk.
//!
//! Storage is by rows, each packed: row k holds (A_kk, A_k,a₀, A_k,a₁, …) for its ancestors
//! a₀ = λ(k), a₁ = λ(a₀), … at `row_start(k)`. Since anc(i) for i = a_p is the tail a_{p+1}, …
//! of the same list, row i's packed entries {i} ∪ anc(i) line up with row k's entries from
//! a_p on, and the update of row i is one contiguous axpy:
//!
//!   row_i[0 .. d−p] −= L_k,a_p · row_k[1+p .. 1+d]   (d = |anc(k)|).

/// Marks the root's absent parent.
pub const NONE: usize = usize::MAX;

/// The elimination tree λ of a symmetric pattern (`parent[k] < k`, or [`NONE`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EliminationTree {
    parent: Vec<usize>,
    /// anc(k) = λ(k), λ(λ(k)), … flattened: `ancestors[start[k]..start[k + 1]]` (so that the
    /// loops read indices instead of chasing parents; anc(i) is the tail of anc(k) after i).
    ancestors: Vec<usize>,
    start: Vec<usize>,
    /// Packed row k at `row[k]..row[k + 1]`: its diagonal, then its ancestors' entries.
    row: Vec<usize>,
}

impl EliminationTree {
    /// The tree of an n × n pattern given as its off-diagonal non-zero pairs (i, j), in any
    /// order and either orientation; indices must be below n. O(n³) in the worst case, once.
    pub fn from_pattern(n: usize, pairs: impl IntoIterator<Item = (usize, usize)>) -> Self {
        let mut nz = vec![false; n * n];
        for (i, j) in pairs {
            assert!(i < n && j < n, "pattern index out of range");
            if i != j {
                nz[i * n + j] = true;
                nz[j * n + i] = true;
            }
        }
        let mut parent = vec![NONE; n];
        let mut neighbours = Vec::with_capacity(n);
        for k in (0..n).rev() {
            neighbours.clear();
            neighbours.extend((0..k).filter(|&i| nz[k * n + i]));
            parent[k] = neighbours.last().copied().unwrap_or(NONE);
            // eliminating k connects its remaining neighbours pairwise (fill)
            for (a, &i) in neighbours.iter().enumerate() {
                for &j in &neighbours[..a] {
                    nz[i * n + j] = true;
                    nz[j * n + i] = true;
                }
            }
        }
        EliminationTree::with_parents(parent)
    }

    fn with_parents(parent: Vec<usize>) -> Self {
        let (mut ancestors, mut start) = (Vec::new(), vec![0]);
        for k in 0..parent.len() {
            let mut i = parent[k];
            while i != NONE {
                ancestors.push(i);
                i = parent[i];
            }
            start.push(ancestors.len());
        }
        let row = start.iter().enumerate().map(|(k, &s)| s + k).collect();
        EliminationTree {
            parent,
            ancestors,
            start,
            row,
        }
    }

    /// The tree of a dense pattern: the chain λ(k) = k − 1.
    pub fn dense(n: usize) -> Self {
        EliminationTree::with_parents((0..n).map(|k| k.checked_sub(1).unwrap_or(NONE)).collect())
    }

    pub fn len(&self) -> usize {
        self.parent.len()
    }

    pub fn is_empty(&self) -> bool {
        self.parent.is_empty()
    }

    /// λ(k), or [`NONE`] at a root.
    pub fn parent(&self, k: usize) -> usize {
        self.parent[k]
    }

    /// Multiply–adds of one factorization (Σ over k of the ancestor pairs of k).
    pub fn factor_cost(&self) -> usize {
        (0..self.len())
            .map(|k| {
                let d = self.ancestors(k).len();
                d * (d + 1) / 2 + d
            })
            .sum()
    }

    /// anc(k), nearest first.
    pub fn ancestors(&self, k: usize) -> &[usize] {
        &self.ancestors[self.start[k]..self.start[k + 1]]
    }

    /// Length of the packed storage: n diagonal entries plus every (k, ancestor) pair.
    pub fn storage_len(&self) -> usize {
        self.row[self.len()]
    }

    /// Where packed row k begins: A_kk there, then A_k,i for i ∈ anc(k) in the order of
    /// [`EliminationTree::ancestors`].
    pub fn row_start(&self, k: usize) -> usize {
        self.row[k]
    }

    /// Factors A = Lᵀ L in place: `a` holds A in packed rows (see
    /// [`EliminationTree::row_start`]), and on return L in the same places, with
    /// `inv_diag` the reciprocals 1/L_kk. False when a pivot is not positive and finite (A
    /// not positive definite).
    pub fn factor(&self, a: &mut [f64], inv_diag: &mut [f64]) -> bool {
        let n = self.len();
        assert!(a.len() >= self.storage_len() && inv_diag.len() >= n);
        for k in (0..n).rev() {
            let (head, tail) = a.split_at_mut(self.row[k]);
            let row_k = &mut tail[..self.row[k + 1] - self.row[k]];
            let d = row_k[0];
            if !(d > 0.0 && d.is_finite()) {
                return false;
            }
            let lkk = d.sqrt();
            row_k[0] = lkk;
            let inv = 1.0 / lkk;
            inv_diag[k] = inv;
            for v in &mut row_k[1..] {
                *v *= inv;
            }
            // A_ij −= L_ki L_kj for i = a_p ∈ anc(k), j ∈ {i} ∪ anc(i) = a_p, a_{p+1}, …;
            // ancestors have smaller indices, so their rows lie in `head`.
            for (p, &i) in self.ancestors(k).iter().enumerate() {
                let lki = row_k[1 + p];
                let src = &row_k[1 + p..];
                let dst = &mut head[self.row[i]..self.row[i] + src.len()];
                for (x, &l) in dst.iter_mut().zip(src) {
                    *x -= lki * l;
                }
            }
        }
        true
    }

    /// Solves Lᵀ L x = b in place (`x` holds b on entry), with L (packed rows) and
    /// `inv_diag` from [`EliminationTree::factor`].
    pub fn solve(&self, l: &[f64], inv_diag: &[f64], x: &mut [f64]) {
        let n = self.len();
        for k in (0..n).rev() {
            let yk = x[k] * inv_diag[k];
            x[k] = yk;
            let row = &l[self.row[k] + 1..self.row[k + 1]];
            for (&i, &lki) in self.ancestors(k).iter().zip(row) {
                x[i] -= lki * yk;
            }
        }
        for k in 0..n {
            let row = &l[self.row[k] + 1..self.row[k + 1]];
            let mut s = x[k];
            for (&i, &lki) in self.ancestors(k).iter().zip(row) {
                s -= lki * x[i];
            }
            x[k] = s * inv_diag[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;
    use nalgebra::{DMatrix, DVector};

    /// A random SPD matrix with the pattern of a tree given by parents (A = Σ over random
    /// "bodies" k of v vᵀ with v supported on k's path to the root, plus a diagonal).
    fn tree_matrix(parents: &[usize], rng: &mut SplitMix64) -> DMatrix<f64> {
        let n = parents.len();
        let mut a = DMatrix::<f64>::identity(n, n) * 0.1;
        for _ in 0..3 {
            for k in 0..n {
                let mut v = DVector::<f64>::zeros(n);
                let mut i = k;
                while i != NONE {
                    v[i] = rng.uniform(-1.0, 1.0);
                    i = parents[i];
                }
                a += &v * v.transpose();
            }
        }
        a
    }

    fn pairs_of(a: &DMatrix<f64>) -> Vec<(usize, usize)> {
        let n = a.nrows();
        (0..n)
            .flat_map(|i| (0..i).map(move |j| (i, j)))
            .filter(|&(i, j)| a[(i, j)] != 0.0)
            .collect()
    }

    /// A's entries in the tree's packed rows.
    fn packed(tree: &EliminationTree, a: &DMatrix<f64>) -> Vec<f64> {
        let mut l = vec![0.0; tree.storage_len()];
        for k in 0..tree.len() {
            let r = tree.row_start(k);
            l[r] = a[(k, k)];
            for (p, &i) in tree.ancestors(k).iter().enumerate() {
                l[r + 1 + p] = a[(k, i)];
            }
        }
        l
    }

    fn solve_with(tree: &EliminationTree, a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
        let n = a.nrows();
        let mut l = packed(tree, a);
        let mut inv = vec![0.0; n];
        assert!(tree.factor(&mut l, &mut inv));
        let mut x = b.as_slice().to_vec();
        tree.solve(&l, &inv, &mut x);
        DVector::from_vec(x)
    }

    #[test]
    fn a_tree_pattern_is_its_own_elimination_tree_and_solves_as_nalgebra_cholesky() {
        // a floating base (0–5 chained), two legs and a trunk with two arms
        let mut parents = vec![NONE, 0, 1, 2, 3, 4];
        parents.extend([5, 6, 7, 8, 9]); // leg 6–10
        parents.extend([5, 11, 12, 13, 14]); // leg 11–15
        parents.extend([5, 16, 17]); // trunk 16–18
        parents.extend([18, 19, 20, 21, 22]); // arm 19–23
        parents.extend([18, 24, 25, 26, 27]); // arm 24–28
        let mut rng = SplitMix64(7);
        let a = tree_matrix(&parents, &mut rng);
        let tree = EliminationTree::from_pattern(a.nrows(), pairs_of(&a));
        for (k, &p) in parents.iter().enumerate() {
            assert_eq!(tree.parent(k), p, "node {k}");
        }
        let dense = 29 * 29 * 29 / 6;
        assert!(
            tree.factor_cost() * 2 < dense,
            "{} vs {dense}",
            tree.factor_cost()
        );
        let b = DVector::from_fn(29, |i, _| rng.uniform(-1.0, 1.0) + i as f64 * 0.01);
        let x = solve_with(&tree, &a, &b);
        let reference = a.clone().cholesky().expect("SPD").solve(&b);
        let err = (&x - &reference).amax() / reference.amax();
        assert!(err < 1e-12, "{err}");
        assert!((&a * &x - &b).amax() < 1e-10);
    }

    #[test]
    fn arbitrary_patterns_fill_in_along_the_elimination_tree() {
        let mut rng = SplitMix64(11);
        for trial in 0..50 {
            let n = 1 + trial % 12;
            // random sparse symmetric pattern, SPD by diagonal dominance
            let mut a = DMatrix::<f64>::zeros(n, n);
            for i in 0..n {
                for j in 0..i {
                    if rng.uniform(0.0, 1.0) < 0.25 {
                        let v = rng.uniform(-1.0, 1.0);
                        a[(i, j)] = v;
                        a[(j, i)] = v;
                    }
                }
            }
            for i in 0..n {
                a[(i, i)] = 1.0 + (0..n).map(|j| a[(i, j)].abs()).sum::<f64>();
            }
            let tree = EliminationTree::from_pattern(n, pairs_of(&a));
            let b = DVector::from_fn(n, |_, _| rng.uniform(-1.0, 1.0));
            let x = solve_with(&tree, &a, &b);
            let reference = a.clone().cholesky().expect("SPD").solve(&b);
            assert!(
                (&x - &reference).amax() < 1e-12 * (1.0 + reference.amax()),
                "trial {trial}"
            );
            // the dense chain gives the same solution
            let y = solve_with(&EliminationTree::dense(n), &a, &b);
            assert!((&y - &reference).amax() < 1e-12 * (1.0 + reference.amax()));
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        let tree = EliminationTree::dense(2);
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]); // eigenvalues 3, −1
        let mut inv = [0.0; 2];
        assert!(!tree.factor(&mut packed(&tree, &a), &mut inv));
        let nan = DMatrix::from_row_slice(2, 2, &[f64::NAN, 0.0, 0.0, 1.0]);
        assert!(!tree.factor(&mut packed(&tree, &nan), &mut inv));
    }
}
