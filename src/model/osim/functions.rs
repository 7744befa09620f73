//! Reading OpenSim function elements.

use super::xml::{Ctx, XNode, child, elements};
use crate::error::Error;
use crate::model::function::{Function, MultivariatePolynomial, PiecewiseLinear, SimmSpline};
use crate::model::knots::{check_knot_spacing, check_xy};
use crate::model::natural_spline::NaturalSpline;

/// Tags of the function elements musculo reads.
pub const FUNCTION_TAGS: &[&str] = &[
    "Constant",
    "LinearFunction",
    "PolynomialFunction",
    "SimmSpline",
    "NaturalCubicSpline",
    "natCubicSpline",
    "PiecewiseLinearFunction",
    "GCVSpline",
    "MultiplierFunction",
    "MultivariatePolynomialFunction",
];

/// OpenSim function classes musculo does not read (named in the error).
const UNSUPPORTED_FUNCTION_TAGS: &[&str] = &[
    "Sine",
    "StepFunction",
    "PiecewiseConstantFunction",
    "FunctionAdapter",
    "ExpressionBasedFunction",
    "SmoothSegmentedFunction",
];

pub fn is_function_tag(tag: &str) -> bool {
    FUNCTION_TAGS.contains(&tag) || UNSUPPORTED_FUNCTION_TAGS.contains(&tag)
}

/// The function element among `parent`'s children, if any.
pub fn function_child<'a, 'i>(parent: XNode<'a, 'i>) -> Option<XNode<'a, 'i>> {
    elements(parent).find(|c| is_function_tag(c.tag_name().name()))
}

/// Reads one function element.
pub fn parse_function(ctx: &Ctx, node: XNode) -> Result<Function, Error> {
    let tag = node.tag_name().name();
    let xy = |ctx: &Ctx| -> Result<(Vec<f64>, Vec<f64>), Error> {
        let x = ctx
            .vec_opt(node, "x")?
            .ok_or_else(|| ctx.err(node, "missing <x>"))?;
        let y = ctx
            .vec_opt(node, "y")?
            .ok_or_else(|| ctx.err(node, "missing <y>"))?;
        // the constructors check lengths, finiteness and order first (their messages)
        check_xy(&x, &y, 1).map_err(|m| ctx.err(node, m))?;
        check_knot_spacing(&x).map_err(|m| ctx.err(node, m))?;
        Ok((x, y))
    };
    match tag {
        "Constant" => Ok(Function::Constant(ctx.f64_or(node, "value", 0.0)?)),
        "LinearFunction" => {
            let c = ctx
                .vec_opt(node, "coefficients")?
                .unwrap_or_else(|| vec![1.0, 0.0]);
            if c.len() < 2 {
                return Err(ctx.err(
                    node,
                    format!(
                        "<coefficients> needs at least 2 values (slopes then intercept), found {}",
                        c.len()
                    ),
                ));
            }
            Ok(Function::Linear(c))
        }
        "PolynomialFunction" => {
            let c = ctx
                .vec_opt(node, "coefficients")?
                .unwrap_or_else(|| vec![1.0]);
            if c.is_empty() {
                return Err(ctx.err(node, "<coefficients> is empty"));
            }
            Ok(Function::Polynomial(c))
        }
        "SimmSpline" | "NaturalCubicSpline" | "natCubicSpline" => {
            let (x, y) = xy(ctx)?;
            SimmSpline::new(x, y)
                .map(Function::SimmSpline)
                .map_err(|m| ctx.err(node, m))
        }
        "PiecewiseLinearFunction" => {
            let (x, y) = xy(ctx)?;
            PiecewiseLinear::new(x, y)
                .map(Function::PiecewiseLinear)
                .map_err(|m| ctx.err(node, m))
        }
        "GCVSpline" => {
            let variance = ctx.f64_or(node, "error_variance", 0.0)?;
            if variance != 0.0 {
                return Err(ctx.err(
                    node,
                    format!(
                        "smoothing GCVSpline (error_variance = {variance}) is not supported; \
                         only the interpolating form (error_variance 0, OpenSim's default) is"
                    ),
                ));
            }
            let m = ctx.f64_or(node, "half_order", 0.0)?;
            if m.fract() != 0.0 || m < 1.0 {
                return Err(ctx.err(
                    node,
                    format!("<half_order> must be a positive integer, found {m}"),
                ));
            }
            let (x, y) = xy(ctx)?;
            NaturalSpline::interpolating(m as usize, x, y)
                .map(Function::GcvSpline)
                .map_err(|msg| ctx.err(node, msg))
        }
        "MultiplierFunction" => {
            let scale = ctx.f64_or(node, "scale", 1.0)?;
            let holder =
                child(node, "function").ok_or_else(|| ctx.err(node, "missing <function>"))?;
            let inner = function_child(holder)
                .ok_or_else(|| ctx.err(holder, "<function> holds no function element"))?;
            Ok(Function::Multiplier(
                Box::new(parse_function(ctx, inner)?),
                scale,
            ))
        }
        "MultivariatePolynomialFunction" => {
            // OpenSim 4.6's properties are <dimension>, <order> and <coefficients> (defaults
            // 0, 0 and none); nothing else changes its value.
            let count = |tag: &str| -> Result<usize, Error> {
                let v = ctx.f64_or(node, tag, 0.0)?;
                if v.fract() != 0.0 || v < 0.0 {
                    return Err(ctx.err(
                        node,
                        format!("<{tag}> must be a non-negative integer, found {v}"),
                    ));
                }
                Ok(v as usize) // saturates; an absurd value fails the checks below
            };
            if child(node, "dimension").is_none() {
                return Err(ctx.err(
                    node,
                    "missing <dimension> (OpenSim's default, 0, is a function of no coordinate)",
                ));
            }
            let (dimension, order) = (count("dimension")?, count("order")?);
            let c = ctx.vec_opt(node, "coefficients")?.unwrap_or_default();
            MultivariatePolynomial::new(dimension, order, c)
                .map(Function::MultivariatePolynomial)
                .map_err(|m| ctx.err(node, m))
        }
        other => Err(ctx.err(
            node,
            format!(
                "unsupported function type `{other}` (musculo reads {})",
                FUNCTION_TAGS.join(", ")
            ),
        )),
    }
}
