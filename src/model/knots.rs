//! Checks of a function's knots (x, y data points), shared by the model's functions
//! ([`super::function`]) and the natural cubic spline they and the muscle curves build on
//! ([`super::natural_spline`]).

use crate::text::short_number;

/// Validates spline data: equal lengths, at least `min_points`, finite, x strictly increasing.
pub(crate) fn check_xy(x: &[f64], y: &[f64], min_points: usize) -> Result<(), String> {
    if x.len() != y.len() {
        return Err(format!(
            "x and y must have the same length (x has {} values but y has {})",
            x.len(),
            y.len()
        ));
    }
    if x.is_empty() {
        return Err("at least one data point is required, got none".to_string());
    }
    if x.len() < min_points {
        return Err(format!(
            "needs at least {min_points} data points, got {}",
            x.len()
        ));
    }
    for (name, v) in [("x", x), ("y", y)] {
        if let Some((i, a)) = v.iter().enumerate().find(|(_, a)| !a.is_finite()) {
            return Err(format!("{name} values must be finite ({name}[{i}] = {a})"));
        }
    }
    for i in 1..x.len() {
        if x[i] <= x[i - 1] {
            return Err(format!(
                "x values must be strictly increasing (x[{i}] = {} after x[{}] = {})",
                x[i],
                i - 1,
                x[i - 1]
            ));
        }
    }
    Ok(())
}

/// The smallest gap between consecutive knots of a model's function, as a fraction of the
/// knots' span (x_{n−1} − x_0).
///
/// Knots closer than this are a typing error, not a curve: a spline's slope over a gap h is
/// Δy/h and its second derivative Δy/h², so knots one floating-point step apart (h ≈ 10⁻¹⁶)
/// gave a knee torque of 10²⁶ N·m, and subnormal gaps overflow. A billionth of the span is
/// far below any digitised curve's spacing (OpenSim's splines have tens of knots).
pub const MIN_KNOT_GAP_FRACTION: f64 = 1e-9;

/// Checks that consecutive knots of a model's function are at least
/// [`MIN_KNOT_GAP_FRACTION`] of their span apart (after [`check_xy`]).
pub(crate) fn check_knot_spacing(x: &[f64]) -> Result<(), String> {
    let span = x[x.len() - 1] - x[0];
    for i in 1..x.len() {
        let gap = x[i] - x[i - 1];
        // the span itself may overflow (knots near ±f64::MAX): then no gap is small enough
        // to measure against it, and the span is refused
        if !span.is_finite() || !(gap >= MIN_KNOT_GAP_FRACTION * span) {
            return Err(format!(
                "x[{i}] = {} is only {} after x[{}] = {}: knots closer than \
                 {MIN_KNOT_GAP_FRACTION:e} of the knots' span ({}) make slopes and \
                 curvatures that are rounding noise",
                short_number(x[i]),
                short_number(gap),
                i - 1,
                short_number(x[i - 1]),
                short_number(span)
            ));
        }
    }
    Ok(())
}
