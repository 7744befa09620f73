//! Sums of a smooth function over equispaced samples, from its values at a few
//! Chebyshev–Lobatto points: the weights of the ellipsoid fan's interpolatory summation.
//!
//! OpenSim's fan (see `ellipsoid::fan_direction`) sums g(i/300) over hundreds of consecutive
//! samples i = m..=n. Along each stretch of the chord that stays on one side of the
//! ellipsoid's medial plane, g is smooth, so it is replaced there by its polynomial
//! interpolant p at the K + 1 Chebyshev–Lobatto points of [m, n] (mapped to s ∈ [−1, 1]):
//!
//!   p(s) = Σ_k ℓ_k(s) g(s_k),   s_k = sin(π (2k − K) / (2K)),   k = 0..=K,
//!
//! and the sum of the samples becomes
//!
//!   Σ_{r=0}^{N−1} g(s_r) ≈ Σ_{r=0}^{N−1} p(s_r) = Σ_k W_k g(s_k),
//!   W_k = Σ_{r=0}^{N−1} ℓ_k(s_r),   s_r = −1 + 2r/(N − 1),   N = n − m + 1,
//!
//! exactly (up to rounding) for every polynomial of degree ≤ K. The weights depend only on
//! N and K; ℓ_k comes from the barycentric formula of the second kind with the Lobatto
//! weights λ_k = (−1)^k (halved at both ends),
//!
//!   ℓ_k(s) = (λ_k / (s − s_k)) / Σ_j λ_j / (s − s_j),
//!
//! which is stable for every s (Berrut & Trefethen, SIAM Review 46, 2004). Every second
//! node of K is a node of K/2, and every fourth one of K/4, so the same evaluations give
//! the coarser sums too; the difference of two levels bounds the error of the coarser one,
//! and the caller accepts the finer sum only when that difference is negligible (otherwise
//! it goes one level finer, splits the run, or sums every sample). The weights for each N
//! are computed once per process, on first use (N·(K + K/2 + K/4 + 3) divisions).

use std::sync::OnceLock;

/// Interpolation degree of the finest sum (K); the coarser ones use K/2 and K/4.
pub(crate) const DEGREE: usize = 32;
/// Nodes of the finest sum.
pub(crate) const NODES: usize = DEGREE + 1;
/// The longest run of samples the tables serve (OpenSim's fan: 298).
pub(crate) const MAX_SAMPLES: usize = 298;
/// Runs shorter than this are summed sample by sample (the interpolation of degree K/2
/// would save little).
pub(crate) const MIN_RUN: usize = DEGREE + 2;
/// Runs shorter than this are not tried at degree K.
pub(crate) const MIN_RUN_FINE: usize = 2 * NODES;

/// The weights of one run length N at degrees K, K/2 and K/4 (the nodes of each coarser
/// level are every second node of the finer one).
pub(crate) struct SumWeights {
    pub fine: [f64; NODES],
    pub middle: [f64; DEGREE / 2 + 1],
    pub coarse: [f64; DEGREE / 4 + 1],
}

/// Chebyshev–Lobatto node k of degree `degree` on [−1, 1], ascending, in the symmetric
/// form sin(π (2k − K) / (2K)), so that the middle node is exactly 0 and s_{K−k} = −s_k.
pub(crate) fn node(k: usize, degree: usize) -> f64 {
    (std::f64::consts::PI * (2.0 * k as f64 - degree as f64) / (2.0 * degree as f64)).sin()
}

/// W_k = Σ_r ℓ_k(s_r) for the K + 1 Lobatto nodes of degree `degree` (≤ [`DEGREE`]) and
/// the N = `samples` equispaced points of [−1, 1], into `out` (K + 1 entries).
fn weights(degree: usize, samples: usize, out: &mut [f64]) {
    let mut nodes = [0.0; NODES];
    for (k, x) in nodes.iter_mut().enumerate().take(degree + 1) {
        *x = node(k, degree);
    }
    let nodes = &nodes[..=degree];
    let lambda = |k: usize| {
        let sign = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
        if k == 0 || k == degree {
            0.5 * sign
        } else {
            sign
        }
    };
    out.fill(0.0);
    let mut terms = [0.0; NODES];
    let terms = &mut terms[..=degree];
    for r in 0..samples {
        let s = -1.0 + 2.0 * r as f64 / (samples - 1) as f64;
        if let Some(k) = nodes.iter().position(|&x| x == s) {
            out[k] += 1.0;
            continue;
        }
        let mut total = 0.0;
        for (k, t) in terms.iter_mut().enumerate() {
            *t = lambda(k) / (s - nodes[k]);
            total += *t;
        }
        for (o, t) in out.iter_mut().zip(terms.iter()) {
            *o += t / total;
        }
    }
}

/// The weights for a run of `samples` (2 ≤ N ≤ [`MAX_SAMPLES`]) consecutive samples
/// (computed on first use, without allocating: per-frame code stays allocation-free).
pub(crate) fn sum_weights(samples: usize) -> &'static SumWeights {
    static TABLES: [OnceLock<SumWeights>; MAX_SAMPLES + 1] =
        [const { OnceLock::new() }; MAX_SAMPLES + 1];
    TABLES[samples].get_or_init(|| {
        let mut w = SumWeights {
            fine: [0.0; NODES],
            middle: [0.0; DEGREE / 2 + 1],
            coarse: [0.0; DEGREE / 4 + 1],
        };
        weights(DEGREE, samples, &mut w.fine);
        weights(DEGREE / 2, samples, &mut w.middle);
        weights(DEGREE / 4, samples, &mut w.coarse);
        w
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Σ_r g(s_r) by the weights against the plain sum, for polynomials (exact up to degree
    /// K, and K/2 for the coarse sum) and a smooth non-polynomial function.
    #[test]
    fn weights_sum_polynomials_exactly_and_smooth_functions_closely() {
        for samples in [MIN_RUN, MIN_RUN_FINE, 97, 150, MAX_SAMPLES] {
            let w = sum_weights(samples);
            let s_r = |r: usize| -1.0 + 2.0 * r as f64 / (samples - 1) as f64;
            for degree in [0usize, 1, 7, 16, 31, 32] {
                let g = |s: f64| s.powi(degree as i32) + 0.3 * s;
                let plain: f64 = (0..samples).map(|r| g(s_r(r))).sum();
                let fine: f64 = (0..NODES).map(|k| w.fine[k] * g(node(k, DEGREE))).sum();
                assert!(
                    (fine - plain).abs() <= 1e-11 * samples as f64,
                    "N {samples}, degree {degree}: {fine} vs {plain}"
                );
                let middle: f64 = (0..=DEGREE / 2)
                    .map(|k| w.middle[k] * g(node(k, DEGREE / 2)))
                    .sum();
                if degree <= DEGREE / 2 {
                    assert!((middle - plain).abs() <= 1e-11 * samples as f64);
                }
                let coarse: f64 = (0..=DEGREE / 4)
                    .map(|k| w.coarse[k] * g(node(k, DEGREE / 4)))
                    .sum();
                if degree <= DEGREE / 4 {
                    assert!((coarse - plain).abs() <= 1e-11 * samples as f64);
                }
            }
            // smooth but not polynomial: the fine sum within 1e-12 relative
            let g = |s: f64| (1.3 * s).exp() / (2.0 + s);
            let plain: f64 = (0..samples).map(|r| g(s_r(r))).sum();
            let fine: f64 = (0..NODES).map(|k| w.fine[k] * g(node(k, DEGREE))).sum();
            assert!(
                (fine - plain).abs() <= 1e-12 * plain.abs(),
                "{fine} vs {plain}"
            );
        }
    }

    /// Every second node of K is a node of K/2, and every fourth one of K/4 (the coarser
    /// sums reuse the evaluations).
    #[test]
    fn coarser_nodes_are_every_second_finer_node() {
        for k in 0..=DEGREE / 2 {
            assert_eq!(node(k, DEGREE / 2), node(2 * k, DEGREE));
        }
        for k in 0..=DEGREE / 4 {
            assert_eq!(node(k, DEGREE / 4), node(4 * k, DEGREE));
        }
    }
}
