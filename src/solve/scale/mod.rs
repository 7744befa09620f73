//! Subject scaling as OpenSim 4.6's Scale tool does it (`musculo scale`): per-body scale
//! factors from marker-pair measurements and/or manual factors ([`measure`]), mass scaling,
//! the factors applied to the model file ([`scale_osim`]), the marker set of the setup
//! ([`markers`]), and the whole `ScaleTool` run from a setup file ([`tool`]).
//!
//! # Applying factors (`Model::scale`, component by component)
//!
//! A [`ScaleSet`] gives a body's factors f = (fx, fy, fz). Every component scales with the
//! factors of the body its frame is based on (an offset frame defers to its parent frame);
//! a component on a body with no entry is left alone:
//!
//! | component | law |
//! |---|---|
//! | body mass centre | c ∘ f |
//! | offset frame (joint frames, body sub-frames) | translation ∘ f of its *parent* frame's body |
//! | CustomJoint translation axes (not an identity `LinearFunction` [1, 0]) | function × Σ_i \|a_i\| f_i of the joint's parent body (a the axis; OpenSim's weighted sum) |
//! | path points (fixed, conditional) and markers | location ∘ f |
//! | moving path points | each location function with a coordinate × its axis's factor |
//! | wrap objects | translation ∘ f; with R the wrap frame's rotation and ‖R e_k ∘ f‖ its axis stretches: sphere radius × mean(f); cylinder radius × (ŝ_x + ŝ_y)/2, length × ŝ_z; ellipsoid dimension k × ŝ_k; torus radii × (ŝ_x + ŝ_y)/2 |
//! | attached display geometry | scale_factors ∘ f |
//! | translational coupler constraints | scale_factor × fx (uniform factors only) |
//! | masses | preserve_mass_distribution: unchanged, else m × \|fx fy fz\|; then, with a subject mass M, every mass × M / Σm |
//! | inertias | [`scale_inertia`] (uniform factors: × s², × \|s³\| when masses scale; otherwise OpenSim's cylinder rule); then × M / Σm with the masses |
//! | muscles (Thelen, Millard, DeGroote–Fregly…) | optimal fiber and tendon slack lengths × ℓ_after / ℓ_before, the musculotendon lengths at the default pose after and before scaling; ligaments and path springs: resting (slack) length likewise |
//!
//! OpenSim does not scale contact geometry or the values of translational coordinates; the
//! uniform subject scaling ([`scale_uniform`], `musculo model scale`) does, through
//! [`ScaleOptions::contact_geometry`] and [`ScaleOptions::translational_coordinates`].
//!
//! # Text, not a rebuilt model
//!
//! The file's text is rewritten in place: only the numbers of the scaled elements change
//! (written in the shortest form that reads back to the same `f64`), so comments, element
//! order and everything musculo does not model survive, and OpenSim loads the result. Where
//! OpenSim wraps a translation function in a `MultiplierFunction`, musculo multiplies the
//! function's values instead (the same function).

mod apply;
mod frames;
pub mod inertial;
pub mod markers;
pub mod measure;
pub mod place;
pub mod strength;
pub mod tool;

pub use apply::scale_inertia;

use crate::error::Error;
use crate::model::{LoadOptions, Model};
use crate::spatial::Vec3;

/// The range of a manual scale factor of a Scale setup. Bodies of people differ by a factor
/// of a few (a child and a tall adult); 100 turns a 1.8 m model into 180 m and 0.01 into
/// 1.8 cm, sizes of no musculoskeletal subject. A factor near 1000 or 0.001 is a millimetre
/// and metre mix-up, and 10³⁰⁰ overflowed the inertias to `inf` (blamed on the model file).
pub const MIN_SCALE_FACTOR: f64 = 0.01;
/// See [`MIN_SCALE_FACTOR`].
pub const MAX_SCALE_FACTOR: f64 = 100.0;

/// True for a factor in [[`MIN_SCALE_FACTOR`], [`MAX_SCALE_FACTOR`]] (NaN is not).
pub fn scale_factor_is_plausible(factor: f64) -> bool {
    (MIN_SCALE_FACTOR..=MAX_SCALE_FACTOR).contains(&factor)
}

/// Per-body scale factors (OpenSim's `ScaleSet`): body name → (fx, fy, fz).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ScaleSet {
    pub scales: Vec<BodyScale>,
}

/// One body's factors.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyScale {
    pub body: String,
    pub factors: Vec3,
}

impl ScaleSet {
    /// Factor 1 for every body of `model` (ground excluded), as OpenSim's ModelScaler starts.
    pub fn identity(model: &Model) -> ScaleSet {
        Self::uniform(model, 1.0)
    }

    /// The same factor `s` on every axis of every body (ground excluded).
    pub fn uniform(model: &Model, s: f64) -> ScaleSet {
        ScaleSet {
            scales: (model.bodies.iter().skip(1))
                .map(|b| BodyScale {
                    body: b.name.clone(),
                    factors: Vec3::new(s, s, s),
                })
                .collect(),
        }
    }

    /// The factors of a body, if it has an entry.
    pub fn get(&self, body: &str) -> Option<Vec3> {
        self.scales
            .iter()
            .find(|s| s.body == body)
            .map(|s| s.factors)
    }

    /// Sets (or adds) a body's factors.
    pub fn set(&mut self, body: &str, factors: Vec3) {
        match self.scales.iter_mut().find(|s| s.body == body) {
            Some(s) => s.factors = factors,
            None => self.scales.push(BodyScale {
                body: body.to_string(),
                factors,
            }),
        }
    }

    /// Every entry names a body of `model` once, with positive finite factors.
    pub fn validate(&self, model: &Model) -> crate::Result<()> {
        for (i, s) in self.scales.iter().enumerate() {
            if model.body_index(&s.body).is_none() {
                return Err(Error::invalid(
                    "scales",
                    format!("no body `{}` in model {}", s.body, model.name),
                ));
            }
            if self.scales[..i].iter().any(|o| o.body == s.body) {
                return Err(Error::invalid(
                    "scales",
                    format!("body `{}` has two entries", s.body),
                ));
            }
            if !s.factors.iter().all(|f| *f > 0.0 && f.is_finite()) {
                return Err(Error::invalid(
                    "scales",
                    format!(
                        "body `{}`: factors ({}, {}, {}) must be positive and finite",
                        s.body, s.factors.x, s.factors.y, s.factors.z
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// How masses change and what else scales.
#[derive(Clone, Debug, Default)]
pub struct ScaleOptions {
    /// Keep the bodies' relative masses (OpenSim's `preserve_mass_distribution`); otherwise
    /// each mass is first multiplied by |fx fy fz|.
    pub preserve_mass_distribution: bool,
    /// The total mass after scaling (kg): every mass and inertia × M / Σm at the end.
    pub subject_mass: Option<f64>,
    /// Also scale contact geometry (location ∘ f, sphere radius × mean f). OpenSim does not.
    pub contact_geometry: bool,
    /// Also multiply translational coordinates' default values and ranges by this factor
    /// (the uniform scaling's length factor). OpenSim does not.
    pub translational_coordinates: Option<f64>,
    /// Options for reading the scaled model back.
    pub load: LoadOptions,
}

/// A scaled model file.
#[derive(Clone, Debug)]
pub struct ScaledModel {
    /// The scaled `.osim` text.
    pub xml: String,
    /// The same, parsed.
    pub model: Model,
    /// ℓ_after / ℓ_before per force whose lengths were rescaled, in file order.
    pub length_ratios: Vec<(String, f64)>,
    /// Σ body masses after scaling (kg).
    pub total_mass: f64,
}

/// Scales a model file's text by per-body factors: `xml` (named `source` in messages) is
/// the file and `model` the same file parsed. The returned text differs from `xml` only in
/// the numbers listed in the [module documentation](self).
pub fn scale_osim(
    xml: &str,
    source: &str,
    model: &Model,
    scales: &ScaleSet,
    options: &ScaleOptions,
) -> crate::Result<ScaledModel> {
    apply::scale(xml, source, model, scales, options)
}

/// A uniform scaling's two factors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleFactors {
    /// s: lengths.
    pub length: f64,
    /// k: masses.
    pub mass: f64,
}

impl ScaleFactors {
    /// The factors taking `model` (standing height `model_height`, m) to a subject of
    /// `mass` (kg) and `height` (m); each must lie within [`MIN_SCALE_FACTOR`] and
    /// [`MAX_SCALE_FACTOR`].
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
        let factors = ScaleFactors {
            length: height / model_height,
            mass: mass / model.total_mass(),
        };
        // Factors outside [MIN_SCALE_FACTOR, MAX_SCALE_FACTOR] describe no subject (a mass of
        // 10³⁰⁰ kg was written, and every clip augmented on it overflowed float32).
        for (argument, factor, value, unit, of_model) in [
            ("height", factors.length, height, "m", model_height),
            ("mass", factors.mass, mass, "kg", model.total_mass()),
        ] {
            if !(MIN_SCALE_FACTOR..=MAX_SCALE_FACTOR).contains(&factor) {
                return Err(Error::invalid(
                    argument,
                    format!(
                        "{} {unit} against the model's {} {unit} is a factor of {}, outside \
                         {MIN_SCALE_FACTOR} to {MAX_SCALE_FACTOR}: no subject's",
                        crate::text::short_number(value),
                        crate::text::short_number(of_model),
                        crate::text::short_number(factor)
                    ),
                ));
            }
        }
        Ok(factors)
    }
}

/// Uniform scaling to a subject (`musculo model scale`): every body by s = `factors.length`
/// with masses × k = `factors.mass` (preserved distribution), so inertias × k s²; contact
/// geometry and translational coordinates scale by s too. The special case of
/// [`scale_osim`].
pub fn scale_uniform(
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
    let options = ScaleOptions {
        preserve_mass_distribution: true,
        subject_mass: Some(k * model.total_mass()).filter(|m| *m > 0.0),
        contact_geometry: true,
        translational_coordinates: Some(s),
        load: LoadOptions::default(),
    };
    Ok(scale_osim(xml, source, model, &ScaleSet::uniform(model, s), &options)?.xml)
}

/// Parses a model file's XML as the `.osim` reader does ([`crate::xml::parse`]).
pub(crate) fn parse_document<'i>(
    xml: &'i str,
    source: &str,
) -> crate::Result<roxmltree::Document<'i>> {
    crate::xml::parse(xml, source)
}
