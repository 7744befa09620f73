//! Scale factors from a setup's `ModelScaler`: marker-pair measurements on a static trial
//! and manual factors, combined in the setup's `scaling_order` (OpenSim's ModelScaler).
//!
//! A measurement's factor is the mean over its marker pairs of
//!
//!   d_exp / d_model,  d_exp = mean over the window's frames of ‖p₁(t) − p₂(t)‖,
//!
//! d_model the distance between the two model markers with the *unscaled* model at its
//! default pose (coordinates at their default values). The window is OpenSim's
//! `MarkerData::findFrameRange`: from the last frame at or before the range's start (the
//! first frame if none) to the first frame at or after its end (the last frame if none) —
//! so the default range −1 −1 is the first frame alone. The factor goes to the listed axes
//! of each listed body. Manual factors replace all three factors of their body. The steps
//! run in `scaling_order`; a later step overrides an earlier one; bodies that no step
//! touches keep factor 1.
//!
//! Differences from OpenSim, all making a silent failure an error or a kept frame:
//! OpenSim averages a pair's distance over every frame of the window and gives up the
//! whole measurement (with a log line) when a marker is missing in one of them; musculo
//! averages over the frames where both markers are present and fails only when there is
//! none. A marker missing from the model or the trial, a zero model distance, a manual
//! scale for an unknown body, or a measurement none of whose bodies exist are errors naming
//! the setup file and line (OpenSim skips them); a single unknown body of a measurement is a
//! warning (OpenSim ignores it silently; the Gait2392 setup lists `patella_r`, which that
//! model does not have).

use super::{MAX_SCALE_FACTOR, MIN_SCALE_FACTOR, ScaleSet};
use crate::io::scale_setup::{Measurement, ModelScaler, ScalingStep};
use crate::io::setup::SetupWarning;
use crate::io::trc::Trc;
use crate::model::Model;
use crate::motion::Motion;
use crate::spatial::Vec3;
use crate::text::short_number;
use std::path::Path;

/// One marker pair of a measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct PairDistance {
    pub markers: [String; 2],
    /// At the unscaled model's default pose (m).
    pub model: f64,
    /// Mean over the frames used (m).
    pub experimental: f64,
    /// Frames in which both markers are present / frames in the window.
    pub frames_used: usize,
    pub frames_in_window: usize,
}

/// A measurement's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredFactor {
    pub name: String,
    /// Mean over the pairs of experimental / model distance.
    pub factor: f64,
    pub pairs: Vec<PairDistance>,
}

/// OpenSim's `MarkerData::findFrameRange`: the first and last frame (inclusive) averaged
/// for the time range `[start, end]`.
pub fn frame_range(time: &[f64], start: f64, end: f64) -> (usize, usize) {
    let n = time.len();
    let first = (0..n).rev().find(|&i| time[i] <= start).unwrap_or(0);
    let last = (first..n)
        .find(|&i| time[i] >= end)
        .unwrap_or(n.saturating_sub(1));
    (first, last)
}

/// The model's marker positions in ground at its default pose.
pub fn default_pose_markers(model: &Model) -> crate::Result<Vec<Vec3>> {
    let mut data = crate::Data::new(model);
    crate::dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
    let mut out = vec![Vec3::zeros(); model.markers.len()];
    data.marker_positions(model, &mut out)?;
    Ok(out)
}

/// Measures one measurement on the trial; None (with a warning) when it has no pairs.
pub fn measure(
    model: &Model,
    markers_at_default: &[Vec3],
    trial: &Motion,
    time_range: [f64; 2],
    m: &Measurement,
) -> crate::Result<Option<MeasuredFactor>> {
    if m.pairs.is_empty() {
        return Ok(None);
    }
    let (first, last) = frame_range(&trial.time, time_range[0], time_range[1]);
    let mut pairs = Vec::with_capacity(m.pairs.len());
    let mut sum = 0.0;
    for pair in &m.pairs {
        let mut model_idx = [0; 2];
        let mut trial_idx = [0; 2];
        for k in 0..2 {
            let name = &pair.markers[k];
            model_idx[k] =
                (model.markers.iter().position(|mk| &mk.name == name)).ok_or_else(|| {
                    pair.place.error(format!(
                        "marker \"{name}\" is not in the model (nor in the marker set file)"
                    ))
                })?;
            trial_idx[k] = trial.index(name).ok_or_else(|| {
                pair.place
                    .error(format!("marker \"{name}\" is not in {}", trial.source))
            })?;
        }
        let d_model = (markers_at_default[model_idx[0]] - markers_at_default[model_idx[1]]).norm();
        if d_model.is_nan() || d_model <= 0.0 {
            return Err(pair.place.error(format!(
                "markers \"{}\" and \"{}\" coincide on the model (distance {d_model} m): \
                 no scale factor can be measured",
                pair.markers[0], pair.markers[1]
            )));
        }
        // d_exp = mean over frames with both markers of ‖p₁ − p₂‖
        let (mut total, mut used) = (0.0, 0);
        for f in first..=last {
            let frame = trial.frame(f);
            let d = (frame[trial_idx[0]] - frame[trial_idx[1]]).norm();
            if d.is_finite() {
                total += d;
                used += 1;
            }
        }
        if used == 0 {
            return Err(pair.place.error(format!(
                "markers \"{}\" and \"{}\" are never both present in frames {}–{} \
                 (t = {}–{} s) of {}",
                pair.markers[0],
                pair.markers[1],
                first,
                last,
                trial.time[first],
                trial.time[last],
                trial.source
            )));
        }
        let d_exp = total / used as f64;
        sum += d_exp / d_model;
        pairs.push(PairDistance {
            markers: pair.markers.clone(),
            model: d_model,
            experimental: d_exp,
            frames_used: used,
            frames_in_window: last - first + 1,
        });
    }
    Ok(Some(MeasuredFactor {
        name: m.name.clone(),
        factor: sum / m.pairs.len() as f64,
        pairs,
    }))
}

/// The factors a `ModelScaler` computes: every body starts at 1, then the steps of
/// `scaling_order` in turn. `trial` is the static trial (its `marker_file`), needed when
/// a measurement is applied. Returns the factors, each applied measurement's outcome, and
/// warnings.
pub fn scale_set(
    model: &Model,
    scaler: &ModelScaler,
    trial: Option<&Motion>,
) -> crate::Result<(ScaleSet, Vec<MeasuredFactor>, Vec<SetupWarning>)> {
    let mut set = ScaleSet::identity(model);
    let mut measured: Vec<MeasuredFactor> = Vec::new();
    let mut warnings = Vec::new();
    for step in &scaler.scaling_order {
        match step {
            ScalingStep::Measurements => {
                let applied: Vec<&Measurement> =
                    scaler.measurements.iter().filter(|m| m.apply).collect();
                if applied.is_empty() {
                    continue;
                }
                let Some(trial) = trial else {
                    return Err(scaler
                        .place
                        .error("measurements are used but no marker_file is set"));
                };
                let at_default = default_pose_markers(model)?;
                for m in applied {
                    let Some(result) = measure(model, &at_default, trial, scaler.time_range, m)?
                    else {
                        warnings.push(m.place.warning("no marker pairs: measurement not used"));
                        continue;
                    };
                    let mut known = 0;
                    for b in &m.bodies {
                        if model.body_index(&b.body).is_none() {
                            warnings.push(b.place.warning(format!(
                                "no body \"{}\" in the model: not scaled by this measurement",
                                b.body
                            )));
                            continue;
                        }
                        known += 1;
                        let mut f = set.get(&b.body).unwrap_or(Vec3::new(1.0, 1.0, 1.0));
                        for k in 0..3 {
                            if b.axes[k] {
                                f[k] = result.factor;
                            }
                        }
                        set.set(&b.body, f);
                    }
                    if known == 0 {
                        return Err(m.place.error(format!(
                            "measurement \"{}\" scales no body of the model",
                            m.name
                        )));
                    }
                    measured.push(result);
                }
            }
            ScalingStep::ManualScale => {
                for s in scaler.manual.iter().filter(|s| s.apply) {
                    if model.body_index(&s.body).is_none() {
                        return Err(s
                            .place
                            .error(format!("no body \"{}\" in the model", s.body)));
                    }
                    if !s
                        .factors
                        .iter()
                        .all(|f| super::scale_factor_is_plausible(*f))
                    {
                        return Err(s.place.error(format!(
                            "factors ({}, {}, {}) must lie in [{MIN_SCALE_FACTOR}, \
                             {MAX_SCALE_FACTOR}]: a factor beyond them is a typing or unit error",
                            short_number(s.factors.x),
                            short_number(s.factors.y),
                            short_number(s.factors.z)
                        )));
                    }
                    set.set(&s.body, s.factors);
                }
            }
        }
    }
    Ok((set, measured, warnings))
}

/// Reads a `.trc` static trial as a [`Motion`] (metres), with the reader's warnings (frames
/// repeating a time, left out).
pub fn read_trial(path: &Path) -> crate::Result<(Motion, Vec<SetupWarning>)> {
    let trc = Trc::read(path)?;
    let motion = Motion::from_trc(&trc, &path.display().to_string())?;
    Ok((motion, trc.warnings))
}
