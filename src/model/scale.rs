//! Uniform scaling of a model to a subject's mass and height (`musculo model scale`), for
//! per-subject perturbations. With s = H / H_model and k = M / M_model:
//!
//!   lengths × s (joint frames, body mass centres, path points and their spline functions,
//!   wrap surfaces, markers, contact geometry, translational coordinates and their splines),
//!   masses × k,   inertias × k s²,
//!   optimal fiber and tendon slack lengths × ℓ_new / ℓ_old, the ratio of each musculotendon
//!   length at the default pose after and before scaling (= s for a uniformly scaled path, but
//!   measured, so the ratio of fiber and tendon to musculotendon length is kept exactly).
//!
//! The text is rewritten in place: only the numbers change, every other byte of the file
//! (comments, element order, unknown elements) is kept.

use crate::error::Error;
use crate::model::{Model, MotionType};
use crate::muscle::path::{PathData, PathSet, compute_paths};

/// A scaling's two factors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleFactors {
    /// s: lengths.
    pub length: f64,
    /// k: masses.
    pub mass: f64,
}

impl ScaleFactors {
    /// The factors taking `model` (standing height `model_height`, m) to a subject of
    /// `mass` (kg) and `height` (m).
    pub fn for_subject(
        model: &Model,
        model_height: f64,
        mass: f64,
        height: f64,
    ) -> crate::Result<ScaleFactors> {
        for (argument, v) in [
            ("mass", mass),
            ("height", height),
            ("model_height", model_height),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(Error::invalid(
                    argument,
                    format!("{v} must be positive and finite"),
                ));
            }
        }
        Ok(ScaleFactors {
            length: height / model_height,
            mass: mass / model.total_mass(),
        })
    }
}

/// A number list to rewrite: the byte range of an element's text and the factor per value.
struct Edit {
    range: std::ops::Range<usize>,
    factor: f64,
}

const WRAP_OBJECTS: [&str; 4] = ["WrapCylinder", "WrapSphere", "WrapEllipsoid", "WrapTorus"];
const PATH_POINTS: [&str; 3] = ["PathPoint", "ConditionalPathPoint", "MovingPathPoint"];
const MUSCLE_LENGTHS: [&str; 2] = ["optimal_fiber_length", "tendon_slack_length"];

fn has_ancestor(node: roxmltree::Node, names: &[&str]) -> bool {
    node.ancestors()
        .skip(1)
        .any(|a| names.contains(&a.tag_name().name()))
}

fn parent_name<'a>(node: roxmltree::Node<'a, 'a>) -> &'a str {
    node.parent_element()
        .map(|p| p.tag_name().name())
        .unwrap_or("")
}

/// Whether a TransformAxis element moves along a translation.
fn translation_axis(axis: roxmltree::Node) -> bool {
    axis.attribute("name")
        .is_some_and(|n| n.starts_with("translation"))
}

/// Scales `xml` (read from `source`, named in errors) by `factors`; `model` is the same file
/// parsed (its coordinates' motion types and muscle paths are used).
pub fn scale_osim(
    xml: &str,
    source: &str,
    model: &Model,
    factors: ScaleFactors,
) -> crate::Result<String> {
    let (s, k) = (factors.length, factors.mass);
    if !(s > 0.0 && s.is_finite() && k > 0.0 && k.is_finite()) {
        return Err(Error::invalid(
            "factors",
            format!("length {s} and mass {k} must be positive"),
        ));
    }
    let doc = roxmltree::Document::parse(xml).map_err(|e| Error::Xml {
        file: source.to_string(),
        line: e.pos().row,
        column: e.pos().col,
        message: e.to_string(),
    })?;
    let translational: Vec<&str> = (model.coordinates.iter())
        .filter(|c| c.motion_type == MotionType::Translational)
        .map(|c| c.name.as_str())
        .collect();
    let mut edits: Vec<Edit> = Vec::new();
    let mut muscle_length_nodes: Vec<(String, std::ops::Range<usize>)> = Vec::new();
    for node in doc.descendants().filter(|n| n.is_element()) {
        let name = node.tag_name().name();
        let parent = parent_name(node);
        let factor = match name {
            "mass" if parent == "Body" => Some(k),
            "mass_center" if parent == "Body" => Some(s),
            "inertia" if parent == "Body" => Some(k * s * s),
            "translation" if parent == "PhysicalOffsetFrame" || WRAP_OBJECTS.contains(&parent) => {
                Some(s)
            }
            "radius" | "length" | "dimensions" | "inner_radius" | "outer_radius"
                if WRAP_OBJECTS.contains(&parent) =>
            {
                Some(s)
            }
            "location"
                if PATH_POINTS.contains(&parent)
                    || parent == "Marker"
                    || parent.starts_with("Contact") =>
            {
                Some(s)
            }
            "radius" if parent == "ContactSphere" => Some(s),
            // spline / constant / linear values of moving points and of translation axes
            "y" | "value" | "coefficients" => {
                let moving = has_ancestor(node, &["x_location", "y_location", "z_location"]);
                let translation = (node.ancestors())
                    .any(|a| a.tag_name().name() == "TransformAxis" && translation_axis(a));
                let identity = name == "coefficients" && is_identity_linear(node);
                (moving || (translation && !identity)).then_some(s)
            }
            "default_value" | "range" if parent == "Coordinate" => {
                let coordinate = node
                    .parent_element()
                    .and_then(|c| c.attribute("name"))
                    .unwrap_or("");
                translational.contains(&coordinate).then_some(s)
            }
            n if MUSCLE_LENGTHS.contains(&n) => {
                if let (Some(text), Some(owner)) = (node.first_child(), node.parent_element()) {
                    muscle_length_nodes.push((
                        owner.attribute("name").unwrap_or("").to_string(),
                        text.range(),
                    ));
                }
                None
            }
            _ => None,
        };
        if let (Some(factor), Some(text)) = (factor, node.first_child()) {
            if text.is_text() {
                edits.push(Edit {
                    range: text.range(),
                    factor,
                });
            }
        }
    }
    // Pass 1: geometry; pass 2: fiber and tendon lengths by the measured length ratio.
    let geometry = apply(xml, source, &edits)?;
    let scaled = Model::from_osim_str(&geometry, source)?;
    let ratios = length_ratios(model, &scaled)?;
    for (muscle, range) in muscle_length_nodes {
        let factor = *ratios.get(&muscle).unwrap_or(&s);
        edits.push(Edit { range, factor });
    }
    apply(xml, source, &edits)
}

/// A translation axis's identity LinearFunction (slope 1, intercept 0) maps the coordinate
/// itself, which is already scaled: left alone.
fn is_identity_linear(coefficients: roxmltree::Node) -> bool {
    let v: Vec<f64> = (coefficients.text().unwrap_or("").split_whitespace())
        .filter_map(|t| t.parse().ok())
        .collect();
    v.len() == 2 && v[0].abs() == 1.0 && v[1] == 0.0
}

/// ℓ_scaled / ℓ_original of every path at each model's default pose.
fn length_ratios(
    original: &Model,
    scaled: &Model,
) -> crate::Result<std::collections::HashMap<String, f64>> {
    let length = |model: &Model| -> crate::Result<Vec<(String, f64)>> {
        let set = PathSet::new(model)?;
        let mut data = crate::Data::new(model);
        crate::dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
        let mut paths = PathData::new(model, &set);
        compute_paths(model, &data, &set, &mut paths)?;
        Ok(set
            .paths
            .iter()
            .map(|p| p.name.clone())
            .zip(paths.length.iter().copied())
            .collect())
    };
    let before = length(original)?;
    let after = length(scaled)?;
    Ok(before
        .into_iter()
        .zip(after)
        .map(|((name, a), (_, b))| (name, b / a))
        .collect())
}

/// The text with every edited number list multiplied by its factor (written in Rust's
/// shortest round-trip form).
fn apply(xml: &str, source: &str, edits: &[Edit]) -> crate::Result<String> {
    let mut sorted: Vec<&Edit> = edits.iter().collect();
    sorted.sort_by_key(|e| e.range.start);
    let mut out = String::with_capacity(xml.len());
    let mut at = 0;
    for e in sorted {
        out.push_str(&xml[at..e.range.start]);
        let text = &xml[e.range.clone()];
        let mut values = Vec::new();
        for token in text.split_whitespace() {
            let v: f64 = token.parse().map_err(|_| Error::Model {
                file: source.to_string(),
                line: line_of(xml, e.range.start),
                element: String::new(),
                message: format!("`{token}` is not a number"),
            })?;
            values.push(format!("{}", v * e.factor));
        }
        out.push_str(&values.join(" "));
        at = e.range.end;
    }
    out.push_str(&xml[at..]);
    Ok(out)
}

fn line_of(xml: &str, byte: usize) -> u32 {
    xml[..byte].bytes().filter(|b| *b == b'\n').count() as u32 + 1
}
