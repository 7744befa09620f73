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
//! model's markers at its default pose q₀; every body of B is scaled by s on the segment's
//! axes (all three unless it names some; a later segment overrides an earlier one)
//! ([`super::scale::scale_osim`]: joint frames, mass centres, inertias, muscle paths and
//! lengths, markers). Masses are kept (the clip says nothing about them).
//!
//! Then the markers of the map's *placed* targets (joints the input skeleton puts by its
//! own convention: SMPL's pelvis joint above the hip centres, its spine joints) are moved
//! where the clip puts them, as OpenSim's marker placement moves markers onto a static
//! trial, by block-coordinate descent on the IK objective over (poses, placed markers):
//!
//!   1. IK over the clip with the placed targets at a tenth of their weight (landmark
//!      targets, whose model markers sit at the anatomical landmark, at their full weight);
//!   2. each placed marker ← the per-component median over frames of R_bᵀ (x(t) − o_b(t)),
//!      the target in its body's frame at the solved pose;
//!   3. IK with every weight, and step 2 again, [`PLACEMENT_ROUNDS`] times in all (each IK
//!      stopping early, [`PLACEMENT_ROUND_DECREASE`]).
//!
//! Placement looks at no more than [`PLACEMENT_FRAMES`] frames, evenly spread over the clip:
//! a median of that many samples moves by far less than the targets' own noise, and a long
//! clip (CMU's run to thousands of frames) then costs no more to place than a short one.
//!
//! The augmentation chain scales through [`scale_to_clip_shared`]: factors rounded to
//! [`SHARED_FACTOR_GRID`], and the scaled model (before placement) reused by the clips that
//! round to the same factors, as all clips of one skeleton do.

use super::ik::{self, IkSettings};
use super::scale::{ScaleOptions, ScaleSet, ScaledModel, scale_osim};
use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::model::Model;
use crate::motion::Motion;
use crate::motion::skeleton::SkeletonMap;
use crate::spatial::Vec3;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// Rounds of marker placement (IK, then placement).
pub const PLACEMENT_ROUNDS: usize = 3;

/// The relative-decrease stopping rule ([`IkSettings::relative_decrease`]) of the IK of
/// every placement round: those poses only feed the medians of step 2, which the last digits
/// of a converged pose do not move. Against the default rule in every round (median per-frame
/// IK RMSE after `--scale auto`): HumanML3D 012314 11.91 → 11.92 mm, BVH 131_01 8.31 → 8.29,
/// 131_03 8.07 → 8.06, cmu_01_01 5.43 → 5.37, C3D walking2 3.85 → 3.78, walking5 6.72 →
/// 5.18; placement on the HumanML3D clip 8.8 → 6.5 ms (all rounds but the last early). The
/// last round early too changed none of those figures at their printed precision
/// (`tests/ik_datasets.rs`), and the HumanML3D clip's model 8.0–8.1 → 7.1–7.3 ms.
pub const PLACEMENT_ROUND_DECREASE: f64 = 1e-4;

/// Most frames marker placement looks at (evenly spread over the clip). 50 fit as well as
/// 100 did (median IK RMSE after `--scale auto`, 100 → 50 frames: HumanML3D 012314 11.91 →
/// 11.93 mm, BVH 131_01 8.25 → 8.32 mm, cmu_01_01 5.38 → 5.45 mm, C3D walking2 4.03 → 2.03
/// mm) at two thirds of the scaling time.
pub const PLACEMENT_FRAMES: usize = 50;

/// At most `max` frames of `motion`, evenly spread and including the first and last.
fn spread_frames(motion: &Motion, max: usize) -> Motion {
    let t = motion.n_frames();
    if t <= max || max < 2 {
        return motion.clone();
    }
    let n = motion.names.len();
    let picked: Vec<usize> = (0..max)
        .map(|i| (i as f64 * (t - 1) as f64 / (max - 1) as f64).round() as usize)
        .collect();
    Motion {
        source: motion.source.clone(),
        names: motion.names.clone(),
        rate_hz: motion.rate_hz,
        time: picked.iter().map(|&f| motion.time[f]).collect(),
        positions: picked
            .iter()
            .flat_map(|&f| motion.positions[f * n..(f + 1) * n].iter().copied())
            .collect(),
    }
}

/// A model scaled to a clip.
#[derive(Clone, Debug)]
pub struct ClipScaling {
    /// The scaled model file's text, before marker placement (shared with the clips of the
    /// same scaled model).
    pub scaled_xml: Arc<str>,
    /// ℓ_after / ℓ_before per force whose lengths were rescaled (see [`ScaledModel`]).
    pub length_ratios: Vec<(String, f64)>,
    /// The scaled model with its placed markers moved: the model to run IK with.
    pub model: Model,
    /// Name of the model file in messages.
    pub source: String,
    /// Per map segment: its name and factor.
    pub factors: Vec<(String, f64)>,
    /// The per-body factors the model was scaled by: with the base model they rebuild its
    /// body ([`scale_by`]).
    pub scales: ScaleSet,
    /// Per placed marker: its name and its location in its body before and after placement.
    pub placed: Vec<(String, Vec3, Vec3)>,
}

impl ClipScaling {
    /// `model` as an OpenSim file: the scaled text with the placed markers' locations, each
    /// in its marker's own frame (made on request: the text edits cost a tenth of the
    /// scaling, and IK needs only `model`).
    pub fn xml(&self) -> crate::Result<String> {
        let frames = super::scale::markers::marker_frames(&self.scaled_xml, &self.source)?;
        let mut locations = Vec::with_capacity(self.placed.len());
        for (name, _, in_body) in &self.placed {
            let frame = frames.iter().find(|(n, _)| n == name).ok_or_else(|| {
                Error::invalid(
                    "model",
                    format!("marker `{name}` is not in the model file {}", self.source),
                )
            })?;
            locations.push((name.clone(), frame.1.inverse().apply_point(in_body)));
        }
        super::scale::markers::set_marker_locations(&self.scaled_xml, &self.source, &locations)
    }

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
            format!(
                "the skeleton map {} has no segments to scale by",
                map.source
            ),
        ));
    }
    let columns = map.source_columns(clip);
    let column_of = |marker: &str| -> crate::Result<usize> {
        let k = map
            .targets
            .iter()
            .position(|t| t.marker == marker)
            .ok_or_else(|| {
                Error::invalid(
                    "map",
                    format!(
                        "a segment of the skeleton map {} names `{marker}`, which is not one of \
                         its targets",
                        map.source
                    ),
                )
            })?;
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
        let m = model
            .markers
            .iter()
            .find(|m| m.name == name)
            .ok_or_else(|| {
                Error::invalid(
                    "model",
                    format!(
                        "model `{}` has no marker `{name}` that the map needs",
                        model.name
                    ),
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
            let model_distance =
                (data.point_position(ba, &pa) - data.point_position(bb, &pb)).norm();
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
        let factor = sum / seg.pairs.len() as f64;
        // as a Scale setup's manual factors: outside [0.01, 100] no subject's segment (a map
        // `"scale": 1e300` reached the XML scaling and was blamed on the model's inertias)
        use crate::solve::scale::{MAX_SCALE_FACTOR, MIN_SCALE_FACTOR};
        if !(MIN_SCALE_FACTOR..=MAX_SCALE_FACTOR).contains(&factor) {
            return Err(Error::Motion {
                file: clip.source.clone(),
                location: format!("segment \"{}\"", seg.name),
                message: format!(
                    "the clip's bones are {} times the model's (with the skeleton map {}'s \
                     scale {}), outside {MIN_SCALE_FACTOR} to {MAX_SCALE_FACTOR}: a wrong \
                     length unit or map scale",
                    crate::text::short_number(factor),
                    map.source,
                    crate::text::short_number(map.scale)
                ),
            });
        }
        out.push((seg.name.clone(), factor));
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
    let scales = clip_scale_set(model, map, &factors)?;
    let scaled = scale_osim(xml, source, model, &scales, &clip_scale_options())?;
    place_on_clip(Shared::from(scaled), source, map, clip, factors, scales)
}

/// `model` (whose file text is `xml`, named `source`) scaled by the per-body factors `scales`
/// as [`scale_to_clip`] scales it (masses kept), before its markers are placed on a clip:
/// the body of a clip scaled by augment, rebuilt from its [`ClipScaling::scales`].
pub fn scale_by(
    xml: &str,
    source: &str,
    model: &Model,
    scales: &ScaleSet,
) -> crate::Result<ScaledModel> {
    scale_osim(xml, source, model, scales, &clip_scale_options())
}

/// [`scale_to_clip`] with the segment factors rounded to [`SHARED_FACTOR_GRID`], and the
/// scaled model (before marker placement, which stays the clip's own) taken from `shared`
/// when a clip before this one had the same rounded factors. The result depends only on the
/// clip, never on what `shared` held: a run's output is the same whatever the order, thread
/// count or sharding of its clips. `shared` serves one base model (`xml`, `model`): its
/// entries are told apart by the per-body factors, `source` and the text's length only.
pub fn scale_to_clip_shared(
    xml: &str,
    source: &str,
    model: &Model,
    map: &SkeletonMap,
    clip: &Motion,
    shared: &ScaledModels,
) -> crate::Result<ClipScaling> {
    let mut factors = segment_factors(model, map, clip)?;
    for (_, s) in &mut factors {
        *s = (*s / SHARED_FACTOR_GRID).round() * SHARED_FACTOR_GRID;
    }
    let key = ScaleKey {
        source: source.to_string(),
        text_length: xml.len(),
        scales: clip_scale_set(model, map, &factors)?,
    };
    let scaled = shared.get_or_insert(&key, || {
        scale_osim(xml, source, model, &key.scales, &clip_scale_options()).map(Shared::from)
    })?;
    place_on_clip((*scaled).clone(), source, map, clip, factors, key.scales)
}

/// Grid of the segment factors in [`scale_to_clip_shared`]: 1e-4, a bone's length to within
/// 0.05 mm. Clips of one skeleton then share a scaled model: every HumanML3D clip does (its
/// processing retargets all motions onto the skeleton of its sample 000021, by its
/// `uniform_skeleton` step), and the factors of two
/// clips of a skeleton differ by the float32 rounding of their joint positions (the two forms
/// of HumanML3D 012314 by ≤ 6·10⁻⁸).
pub const SHARED_FACTOR_GRID: f64 = 1e-4;

/// Models scaled by [`scale_to_clip_shared`], by their per-body factors, for the clips that
/// follow (the last [`ScaledModels::CAPACITY`] distinct ones: a dataset holds a few skeletons
/// at most, HumanML3D one). Safe to share between threads.
#[derive(Debug, Default)]
pub struct ScaledModels {
    entries: Mutex<VecDeque<(ScaleKey, Arc<Shared>)>>,
}

/// A scaled model as clips take it: each copies the model (its markers are then placed on
/// the clip) and shares the text.
#[derive(Clone, Debug)]
struct Shared {
    xml: Arc<str>,
    model: Model,
    length_ratios: Vec<(String, f64)>,
}

impl From<ScaledModel> for Shared {
    fn from(scaled: ScaledModel) -> Shared {
        Shared {
            xml: scaled.xml.into(),
            model: scaled.model,
            length_ratios: scaled.length_ratios,
        }
    }
}

/// What a shared scaled model was made from, besides the base model's text.
#[derive(Clone, Debug, PartialEq)]
struct ScaleKey {
    source: String,
    text_length: usize,
    scales: ScaleSet,
}

impl Clone for ScaledModels {
    fn clone(&self) -> Self {
        ScaledModels {
            entries: Mutex::new(self.lock().clone()),
        }
    }
}

impl ScaledModels {
    /// Distinct factor sets kept.
    pub const CAPACITY: usize = 4;

    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Factor sets held now.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    // A poisoned lock still holds whole entries (nothing panics while it is held).
    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<(ScaleKey, Arc<Shared>)>> {
        self.entries.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The model scaled by `key`: held, or made by `make` (outside the lock, so other
    /// threads go on) and kept.
    fn get_or_insert(
        &self,
        key: &ScaleKey,
        make: impl FnOnce() -> crate::Result<Shared>,
    ) -> crate::Result<Arc<Shared>> {
        if let Some((_, m)) = self.lock().iter().find(|(k, _)| k == key) {
            return Ok(Arc::clone(m));
        }
        let made = Arc::new(make()?);
        let mut entries = self.lock();
        if let Some((_, m)) = entries.iter().find(|(k, _)| k == key) {
            return Ok(Arc::clone(m));
        }
        if entries.len() == Self::CAPACITY {
            entries.pop_front();
        }
        entries.push_back((key.clone(), Arc::clone(&made)));
        Ok(made)
    }
}

/// The per-body factors of one factor per segment of `map` (in the order of `map.segments`).
fn clip_scale_set(
    model: &Model,
    map: &SkeletonMap,
    factors: &[(String, f64)],
) -> crate::Result<ScaleSet> {
    let mut scales = ScaleSet::identity(model);
    for (seg, (_, s)) in map.segments.iter().zip(factors) {
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
            let mut f = scales.get(body).unwrap_or(Vec3::new(1.0, 1.0, 1.0));
            for axis in &seg.axes {
                match axis.as_str() {
                    "x" => f.x = *s,
                    "y" => f.y = *s,
                    "z" => f.z = *s,
                    other => {
                        return Err(Error::invalid(
                            "map",
                            format!("segment `{}`: axis `{other}` is not x, y or z", seg.name),
                        ));
                    }
                }
            }
            scales.set(body, f);
        }
    }
    Ok(scales)
}

/// Scaling a model to a clip keeps its masses (the clip says nothing about them).
fn clip_scale_options() -> ScaleOptions {
    ScaleOptions {
        preserve_mass_distribution: true,
        ..ScaleOptions::default()
    }
}

/// The scaled model with the map's placed markers moved onto `clip`.
fn place_on_clip(
    scaled: Shared,
    source: &str,
    map: &SkeletonMap,
    clip: &Motion,
    factors: Vec<(String, f64)>,
    scales: ScaleSet,
) -> crate::Result<ClipScaling> {
    let Shared {
        xml: scaled_xml,
        model: mut fitted,
        length_ratios,
    } = scaled;
    let placed = place_markers(&mut fitted, map, clip)?;
    Ok(ClipScaling {
        scaled_xml,
        length_ratios,
        model: fitted,
        source: source.to_string(),
        factors,
        scales,
        placed,
    })
}

/// Moves the markers of the map's placed targets onto the clip (see the module
/// documentation); returns (marker, location before, location after) for each.
pub fn place_markers(
    model: &mut Model,
    map: &SkeletonMap,
    clip: &Motion,
) -> crate::Result<Vec<(String, Vec3, Vec3)>> {
    let (targets, mut tasks) = map.apply(model, clip)?;
    let targets = spread_frames(&targets, PLACEMENT_FRAMES);
    let placed: Vec<usize> = (0..map.targets.len())
        .filter(|&k| map.targets[k].placed)
        .collect();
    if placed.is_empty() {
        return Ok(Vec::new());
    }
    let before: Vec<Vec3> = placed
        .iter()
        .map(|&k| model.markers[tasks.markers[k].marker].location_in_body)
        .collect();
    let full_weights: Vec<f64> = tasks.markers.iter().map(|t| t.weight).collect();
    let settings = IkSettings {
        relative_decrease: PLACEMENT_ROUND_DECREASE,
        ..IkSettings::default()
    };
    let mut data = Data::new(model);
    let frames = targets.n_frames();
    let mut samples: Vec<[Vec<f64>; 3]> = placed
        .iter()
        .map(|_| std::array::from_fn(|_| Vec::with_capacity(frames)))
        .collect();
    let mut previous: Option<ik::IkSolution> = None;
    for round in 0..PLACEMENT_ROUNDS {
        for (k, t) in tasks.markers.iter_mut().enumerate() {
            t.weight = if round == 0 && map.targets[k].placed && !map.targets[k].landmark {
                0.1 * full_weights[k]
            } else {
                full_weights[k]
            };
        }
        // Later rounds solve the same frames with markers that moved a little: each frame
        // starts from its own solution of the round before.
        let solution = match &previous {
            None => ik::solve_motion(model, &targets, &tasks, &settings, &|_| {})?,
            Some(before) => {
                ik::solve_motion_from(model, &targets, &tasks, &settings, before, &|_| {})?
            }
        };
        // Each placed target in its marker's body frame, R_bᵀ (x − o_b), per frame.
        for s in samples.iter_mut().flatten() {
            s.clear();
        }
        for f in 0..frames {
            dynamics::forward_kinematics(model, &mut data, solution.frame(f))?;
            for (&k, s) in placed.iter().zip(samples.iter_mut()) {
                let x = targets.frame(f)[k];
                if x.x.is_nan() {
                    continue;
                }
                let (rot, origin) = data.body_pose(model.markers[tasks.markers[k].marker].body);
                let local = rot.transpose() * (x - origin);
                for (s, v) in s.iter_mut().zip(local.iter()) {
                    s.push(*v);
                }
            }
        }
        for (&k, s) in placed.iter().zip(samples.iter_mut()) {
            if s[0].is_empty() {
                continue;
            }
            let location = Vec3::new(median(&mut s[0]), median(&mut s[1]), median(&mut s[2]));
            model.markers[tasks.markers[k].marker].location_in_body = location;
        }
        previous = Some(solution);
    }
    Ok(placed
        .iter()
        .zip(before)
        .map(|(&k, b)| {
            let m = &model.markers[tasks.markers[k].marker];
            (m.name.clone(), b, m.location_in_body)
        })
        .collect())
}
