//! Scaling a model to the skeleton of a motion clip (`musculo ik --scale auto`): joint-centre
//! data (HumanML3D, KIT-ML, BVH) carry a subject's bone lengths in every frame, so the model's
//! segments can be fitted to them before inverse kinematics, as OpenSim's Scale tool fits
//! them to marker-pair distances of a static trial.
//!
//! For each segment of the skeleton map (bodies B, target pairs P):
//!
//!   s = (1/|P|) Σ_{(a,b) ∈ P} median_t ‖x_a(t) − x_b(t)‖ / ‖p_a(q₀) − p_b(q₀)‖
//!
//! with x the clip's targets (in metres, frames where either is missing skipped) and p the
//! model's markers at its default pose q₀; every body of B is scaled by s on all three axes
//! ([`super::scale::scale_osim`]: joint frames, mass centres, inertias, muscle paths and
//! lengths, markers). Masses are kept (the clip says nothing about them).

use super::scale::{ScaleOptions, ScaleSet, ScaledModel, scale_osim};
use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::model::Model;
use crate::motion::Motion;
use crate::motion::skeleton::SkeletonMap;
use crate::spatial::Vec3;

/// A model scaled to a clip.
#[derive(Clone, Debug)]
pub struct ClipScaling {
    /// The scaled model (text and parsed).
    pub scaled: ScaledModel,
    /// Per map segment: its name and factor.
    pub factors: Vec<(String, f64)>,
}

impl ClipScaling {
    /// `right thigh ×1.02, …` for messages.
    pub fn summary(&self) -> String {
        self.factors
            .iter()
            .map(|(n, f)| format!("{n} ×{f:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// The factor of each segment of `map` for `clip` (in the input's axes and metres: the
/// distances do not depend on the axes).
pub fn segment_factors(
    model: &Model,
    map: &SkeletonMap,
    clip: &Motion,
) -> crate::Result<Vec<(String, f64)>> {
    if map.segments.is_empty() {
        return Err(Error::invalid(
            "map",
            format!("the skeleton map {} has no segments to scale by", map.source),
        ));
    }
    let columns = map.source_columns(clip);
    let column_of = |marker: &str| -> crate::Result<usize> {
        let k = map
            .targets
            .iter()
            .position(|t| t.marker == marker)
            .expect("segments name map targets (checked when the map was read)");
        columns[k].ok_or_else(|| Error::Motion {
            file: clip.source.clone(),
            location: "skeleton".into(),
            message: format!(
                "no joint {} for segment scaling with the map {}",
                map.targets[k].source.join(" or "),
                map.source
            ),
        })
    };
    let marker_point = |name: &str| -> crate::Result<(usize, Vec3)> {
        let m = model.markers.iter().find(|m| m.name == name).ok_or_else(|| {
            Error::invalid(
                "model",
                format!("model `{}` has no marker `{name}` that the map needs", model.name),
            )
        })?;
        Ok((m.body, m.location_in_body))
    };
    let mut data = Data::new(model);
    dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
    let mut out = Vec::with_capacity(map.segments.len());
    let mut distances = Vec::with_capacity(clip.n_frames());
    for seg in &map.segments {
        let mut sum = 0.0;
        for [a, b] in &seg.pairs {
            let (ca, cb) = (column_of(a)?, column_of(b)?);
            distances.clear();
            for f in 0..clip.n_frames() {
                let frame = clip.frame(f);
                let d = (frame[ca] - frame[cb]).norm() * map.scale;
                if d.is_finite() {
                    distances.push(d);
                }
            }
            if distances.is_empty() {
                return Err(Error::Motion {
                    file: clip.source.clone(),
                    location: format!("segment \"{}\"", seg.name),
                    message: format!("{a} or {b} is missing in every frame"),
                });
            }
            let (ba, pa) = marker_point(a)?;
            let (bb, pb) = marker_point(b)?;
            let model_distance = (data.point_position(ba, &pa) - data.point_position(bb, &pb)).norm();
            if !(model_distance > 1e-6) {
                return Err(Error::invalid(
                    "map",
                    format!(
                        "segment `{}`: markers {a} and {b} coincide on the model",
                        seg.name
                    ),
                ));
            }
            sum += median(&mut distances) / model_distance;
        }
        out.push((seg.name.clone(), sum / seg.pairs.len() as f64));
    }
    Ok(out)
}

/// `model` (whose file text is `xml`, named `source`) scaled to `clip`'s bone lengths.
pub fn scale_to_clip(
    xml: &str,
    source: &str,
    model: &Model,
    map: &SkeletonMap,
    clip: &Motion,
) -> crate::Result<ClipScaling> {
    let factors = segment_factors(model, map, clip)?;
    let mut scales = ScaleSet::identity(model);
    for (seg, (_, s)) in map.segments.iter().zip(&factors) {
        for body in &seg.bodies {
            if model.body_index(body).is_none() {
                return Err(Error::invalid(
                    "map",
                    format!(
                        "segment `{}` names body `{body}`, which model `{}` lacks",
                        seg.name, model.name
                    ),
                ));
            }
            scales.set(body, Vec3::new(*s, *s, *s));
        }
    }
    let options = ScaleOptions {
        preserve_mass_distribution: true,
        ..ScaleOptions::default()
    };
    let scaled = scale_osim(xml, source, model, &scales, &options)?;
    Ok(ClipScaling { scaled, factors })
}
