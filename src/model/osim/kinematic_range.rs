//! The kinematic functions of a model checked over their coordinates' ranges, once, when the
//! model is read: every command (`inspect`, `export-mjcf`, `id`, `evaluate`, `augment`, …)
//! then refuses the same models, at the element that is wrong.
//!
//! A transform axis θ = f(q) and a coupler q_dep = s · f(q_ind) must give, everywhere in the
//! declared ranges of their arguments, a finite value, slope and curvature, and a value no
//! joint can exceed ([`MAX_AXIS_VALUE`]). Without this check a coupler scale of 10³⁰⁸, a
//! polynomial with coefficients of 10²⁰⁰ or a spline value of 10³⁰⁰ were read, and each
//! command failed its own way: `id` with a NaN torque named at a pelvis column,
//! `export-mjcf` writing NaN coefficients, `evaluate` printing NaN metrics under exit 0.

use super::xml::Ctx;
use crate::error::Error;
use crate::model::{Arity, Function, Model};
use crate::text::short_number;

/// The largest |θ| a transform axis or coupler may reach over its coordinates' ranges (m for
/// a translation, rad for a rotation). No body of a musculoskeletal model moves a kilometre
/// from its parent, nor turns a thousand times; 10⁶ leaves room for loose ranges (OpenSim's
/// pelvis translations are often ±50 or ±99999 m) while values squared in the dynamics
/// (inertias m r², centripetal ω² r) stay far from overflow.
pub const MAX_AXIS_VALUE: f64 = 1e6;

/// Uniform samples of a one-argument function over its coordinate's range (plus its knots).
const SAMPLES: usize = 64;

/// Checks every transform axis and coupler of `model` (see the module's description).
pub(super) fn check_kinematic_functions(ctx: &Ctx, model: &Model) -> Result<(), Error> {
    for dof in &model.dofs {
        let joint = &model.joints[dof.joint];
        let axis = dof.name.rsplit('/').next().unwrap_or(&dof.name);
        if let Some(problem) = problem_over_ranges(model, &dof.function, 1.0, &dof.args) {
            return Err(Error::Model {
                file: ctx.file.to_string(),
                line: joint.line,
                element: format!(
                    "{} \"{}\" > TransformAxis \"{axis}\" > {}",
                    joint.kind.name(),
                    joint.name,
                    dof.function.kind_name()
                ),
                message: problem,
            });
        }
    }
    for c in &model.couplers {
        if let Some(problem) = problem_over_ranges(model, &c.function, c.scale, &c.independents) {
            return Err(Error::Model {
                file: ctx.file.to_string(),
                line: c.line,
                element: format!("CoordinateCouplerConstraint \"{}\"", c.name),
                message: format!(
                    "scale_factor {} × its {}: {problem}",
                    short_number(c.scale),
                    c.function.kind_name()
                ),
            });
        }
    }
    Ok(())
}

/// The first problem of s · f over the box of its arguments' ranges, or None.
fn problem_over_ranges(model: &Model, f: &Function, scale: f64, args: &[usize]) -> Option<String> {
    let ranges: Vec<[f64; 2]> = args.iter().map(|&c| model.coordinates[c].range).collect();
    let at = |x: &[f64]| -> String {
        let parts: Vec<String> = args
            .iter()
            .zip(x)
            .zip(&ranges)
            .map(|((&c, v), r)| {
                format!(
                    "{} = {} (range [{}, {}])",
                    model.coordinates[c].name,
                    short_number(*v),
                    short_number(r[0]),
                    short_number(r[1])
                )
            })
            .collect();
        if parts.is_empty() {
            String::new()
        } else {
            format!(" at {}", parts.join(", "))
        }
    };
    let judge = |x: &[f64], v: f64, d1: f64, d2: f64| -> Option<String> {
        for (what, a) in [("value", v), ("slope", d1), ("curvature", d2)] {
            if !a.is_finite() {
                return Some(format!(
                    "its {what} is {a}{}: the function overflows within its coordinates' ranges",
                    at(x)
                ));
            }
        }
        (v.abs() > MAX_AXIS_VALUE).then(|| {
            format!(
                "its value is {}{}, beyond ±{MAX_AXIS_VALUE:e} (m or rad), which no joint \
                 reaches: a typing error in the function or the coordinate's <range>",
                short_number(v),
                at(x)
            )
        })
    };
    if let ([r], Arity::Exactly(1)) = (ranges.as_slice(), f.arity()) {
        let [lo, hi] = *r;
        let knots = knots(f).iter().copied().filter(|k| (lo..=hi).contains(k));
        // lo (1 − s) + hi s stays finite for any finite ends
        let uniform = (0..=SAMPLES).map(|k| {
            let s = k as f64 / SAMPLES as f64;
            lo * (1.0 - s) + hi * s
        });
        for x in uniform.chain(knots) {
            let (v, d1, d2) = f.eval1(x);
            if let Some(p) = judge(&[x], scale * v, scale * d1, scale * d2) {
                return Some(p);
            }
        }
        return None;
    }
    // Several arguments (or none). A polynomial of several arguments is sampled on a grid
    // over the box of their ranges.
    if curved(f) {
        let mut grad = vec![0.0; ranges.len()];
        let mut hess = vec![0.0; ranges.len() * ranges.len()];
        for x in box_grid(&ranges) {
            let v = f.eval(&x, &mut grad, &mut hess);
            let slope = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
            let curvature = hess.iter().fold(0.0f64, |m, h| m.max(h.abs()));
            if let Some(p) = judge(&x, scale * v, scale * slope, scale * curvature) {
                return Some(p);
            }
        }
    }
    // A constant or an affine function has its extremes over the box at the corners its
    // gradient points to (for a curved one these corners are sampled too).
    let k = ranges.len();
    let (mut grad, mut hess) = (vec![0.0; k], vec![0.0; k * k]);
    let mid: Vec<f64> = ranges.iter().map(|r| 0.5 * r[0] + 0.5 * r[1]).collect();
    f.eval(&mid, &mut grad, &mut hess);
    for toward_max in [true, false] {
        let corner: Vec<f64> = (ranges.iter().zip(&grad))
            .map(|(r, g)| {
                if (*g >= 0.0) == toward_max {
                    r[1]
                } else {
                    r[0]
                }
            })
            .collect();
        let v = f.eval(&corner, &mut grad, &mut hess);
        let slope = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        if let Some(p) = judge(&corner, scale * v, scale * slope, 0.0) {
            return Some(p);
        }
    }
    None
}

/// True for a function of several arguments that is not affine (a multivariate polynomial
/// of order ≥ 2, or a multiple of one).
fn curved(f: &Function) -> bool {
    match f {
        Function::MultivariatePolynomial(p) => p.order() >= 2,
        Function::Multiplier(g, _) => curved(g),
        _ => false,
    }
}

/// Points of a grid over the box `ranges`: n points per argument, ends included, with
/// n = ⌊GRID_POINTS^(1/k)⌋ (at least 2, at most SAMPLES + 1) for k arguments; beyond 12
/// arguments (2¹² points) only the corners of the first 12, the others at their midpoints.
fn box_grid(ranges: &[[f64; 2]]) -> Vec<Vec<f64>> {
    const GRID_POINTS: f64 = 4096.0;
    let k = ranges.len();
    let gridded = k.min(12);
    let n = (GRID_POINTS.powf(1.0 / gridded.max(1) as f64).floor() as usize).clamp(2, SAMPLES + 1);
    let total = n.pow(gridded as u32);
    (0..total)
        .map(|mut index| {
            ranges
                .iter()
                .enumerate()
                .map(|(i, &[lo, hi])| {
                    let s = if i < gridded {
                        let s = (index % n) as f64 / (n - 1) as f64;
                        index /= n;
                        s
                    } else {
                        0.5
                    };
                    lo * (1.0 - s) + hi * s
                })
                .collect()
        })
        .collect()
}

/// The knots of a spline or piecewise-linear function (where its extremes may lie).
fn knots(f: &Function) -> &[f64] {
    match f {
        Function::SimmSpline(s) => s.x(),
        Function::PiecewiseLinear(p) => p.x(),
        Function::GcvSpline(s) => s.knots(),
        Function::Multiplier(g, _) => knots(g),
        _ => &[],
    }
}
