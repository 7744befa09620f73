//! Interpolating natural splines of odd degree 2m−1 (half order m), the function behind
//! OpenSim's `GCVSpline` when its `error_variance` is 0 (OpenSim's default).
//!
//! TODO(helper): implementation in progress.

/// An interpolating natural spline of half order `m` (degree 2m − 1).
#[derive(Clone, Debug, PartialEq)]
pub struct NaturalSpline {
    half_order: usize,
    x: Vec<f64>,
}

impl NaturalSpline {
    /// Builds the natural spline of half order `half_order` (m ≥ 1) interpolating the points
    /// (x_i, y_i). Errors (as a message) on mismatched lengths, fewer than `m` points... 
    pub fn interpolating(half_order: usize, x: Vec<f64>, y: Vec<f64>) -> Result<Self, String> {
        let _ = y;
        Err(format!("not yet implemented (half_order {half_order}, {} points)", x.len()))
    }

    pub fn half_order(&self) -> usize {
        self.half_order
    }

    /// Value, first and second derivative at `t`.
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let _ = t;
        (f64::NAN, f64::NAN, f64::NAN)
    }
}
