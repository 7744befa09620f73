//! Marker placement from a static trial (OpenSim's MarkerPlacer), on the scaled model:
//!
//! 1. The time range is clipped to the trial. The IK targets are the marker positions
//!    averaged over the frames with t₀ ≤ t ≤ t₁ (OpenSim's `averageRow`: a marker missing in
//!    one of those frames is missing from the average, so IK ignores it).
//! 2. Model markers absent from the trial are removed from the model.
//! 3. One frame of inverse kinematics ([`crate::solve::ik`]) from the default pose: the
//!    IKTaskSet's applied marker tasks with their weights (all trial markers with weight 1
//!    when it lists none), its coordinate tasks (target: the default value, the task's
//!    value, or the `coordinate_file` at t₀), clamped coordinates held in their ranges, and
//!    OpenSim's objective Σ_i (w_i / Σ w) ‖e_i‖² + Σ_c w_c (q_c − r_c)² (the marker goal a
//!    weighted mean over the markers present, the coordinate goals not).
//! 4. Each non-fixed model marker moves onto its experimental position averaged over
//!    OpenSim's frame window (`MarkerData::averageFrames`, which skips missing samples),
//!    expressed in the marker's own frame at the solved pose.
//!
//! With `max_marker_movement` ≥ 0, a marker whose coordinates vary over the window by more
//! than that is reported as a warning, as OpenSim logs it. Differences from OpenSim: its
//! IK is an assembly solver that reaches a local optimum; musculo's is Levenberg–Marquardt
//! from the same start (see `solve::ik`), so the pose — and the placed markers of the
//! segments the pose moves — may differ where the problem is poorly determined.

use super::markers::{keep_markers, marker_frames, set_marker_locations};
use super::measure::frame_range;
use super::measure::read_trial;
use crate::io::Table;
use crate::io::scale_setup::{CoordinateValue, IkTask, MarkerPlacer};
use crate::io::setup::SetupWarning;
use crate::model::{LoadOptions, Model, MotionType};
use crate::motion::Motion;
use crate::solve::ik::{self, Bounds, CoordinateTask, IkSettings, IkTasks, MarkerTask};
use crate::spatial::Vec3;

/// The outcome of marker placement.
#[derive(Clone, Debug)]
pub struct Placement {
    /// The model with its markers placed.
    pub xml: String,
    pub model: Model,
    /// Time of the static pose (t₀ of the clipped range).
    pub time: f64,
    /// The solved pose: every model coordinate's value (`Model::coordinates` order).
    pub coordinates: Vec<f64>,
    /// Marker errors of the IK before placement (m): per marker task (name, error).
    pub marker_errors: Vec<(String, f64)>,
    pub rmse: f64,
    pub max_error: f64,
    /// The starts the static pose was solved from and the objective each reached
    /// ([`ik::StartOutcome`]).
    pub starts: Vec<ik::StartOutcome>,
    /// Markers moved and how far (m, in the body).
    pub moved: Vec<(String, f64)>,
    /// Model markers removed because the trial lacks them.
    pub removed: Vec<String>,
    /// The static pose as an OpenSim `.mot` (degrees for rotations).
    pub static_pose: String,
    pub warnings: Vec<SetupWarning>,
}

/// Runs MarkerPlacer on `xml` (the scaled model, named `source` in messages).
pub fn place_markers(
    xml: &str,
    source: &str,
    placer: &MarkerPlacer,
    load: &LoadOptions,
) -> crate::Result<Placement> {
    let Some(file) = &placer.marker_file else {
        return Err(placer
            .place
            .error("no marker_file: the static trial is not named"));
    };
    let (trial, mut warnings) = read_trial(file)?;
    let (first_t, last_t) = (trial.time[0], trial.time[trial.n_frames() - 1]);
    let t0 = placer.time_range[0].max(first_t);
    let t1 = placer.time_range[1].min(last_t);
    if t1 <= t0 {
        return Err(placer.place.error(format!(
            "time range [{}, {}] clipped to the trial is [{t0}, {t1}]: nothing to average \
             (the trial covers [{first_t}, {last_t}] s)",
            placer.time_range[0], placer.time_range[1]
        )));
    }
    let n = trial.n_targets();
    // IK targets: mean over t0 ≤ t ≤ t1, NaN if a sample is missing (OpenSim's averageRow)
    let mut target = vec![Vec3::zeros(); n];
    let rows: Vec<usize> = (0..trial.n_frames())
        .filter(|&f| trial.time[f] >= t0 && trial.time[f] <= t1)
        .collect();
    for &f in &rows {
        for (t, p) in target.iter_mut().zip(trial.frame(f)) {
            *t += p;
        }
    }
    for t in &mut target {
        *t /= rows.len() as f64;
    }
    // Positions the markers move to: OpenSim's frame window, missing samples skipped
    let (a, b) = frame_range(&trial.time, t0, t1);
    let mut placed = vec![Vec3::repeat(f64::NAN); n];
    for (i, p) in placed.iter_mut().enumerate() {
        let present: Vec<Vec3> = (a..=b)
            .map(|f| trial.frame(f)[i])
            .filter(|v| v.x.is_finite())
            .collect();
        if !present.is_empty() {
            *p = present.iter().sum::<Vec3>() / present.len() as f64;
        }
        if let (Some(limit), false) = (placer.max_marker_movement, present.is_empty()) {
            let (mut lo, mut hi) = (present[0], present[0]);
            for v in &present {
                lo = lo.inf(v);
                hi = hi.sup(v);
            }
            let moved = (hi - lo).max();
            if limit > 0.0 && moved > limit {
                warnings.push(placer.place.warning(format!(
                    "marker {} moves {moved} m in {} (threshold {limit} m)",
                    trial.names[i], trial.source
                )));
            }
        }
    }
    let (xml, removed) = keep_markers(xml, source, |name| trial.index(name).is_some())?;
    let model = Model::from_osim_str_with(&xml, source, load)?;
    let tasks = tasks(&model, &trial, placer, t0, &mut warnings)?;
    let targets = Motion {
        source: trial.source.clone(),
        names: trial.names.clone(),
        rate_hz: trial.rate_hz,
        time: vec![t0],
        positions: target,
    };
    // OpenSim's objective: the marker goal a weighted mean, coordinate goals not
    let settings = IkSettings {
        bounds: Bounds::Clamped,
        normalize_marker_weights: true,
        ..IkSettings::default()
    };
    let solution = ik::solve_motion(&model, &targets, &tasks, &settings, &|_| {})?;
    let q = solution.frame(0).to_vec();
    let mut data = crate::Data::new(&model);
    crate::dynamics::forward_kinematics(&model, &mut data, &q)?;
    let coordinates = data.coordinate_values(&model).to_vec();
    let marker_errors: Vec<(String, f64)> = (tasks.markers.iter())
        .zip(&solution.marker_error)
        .map(|(t, e)| (model.markers[t.marker].name.clone(), *e))
        .collect();
    // Non-fixed markers onto the experimental positions, in their own frames
    let frames = marker_frames(&xml, source)?;
    let mut locations = Vec::new();
    let mut moved = Vec::new();
    for (m, (name, frame)) in model.markers.iter().zip(&frames) {
        debug_assert_eq!(&m.name, name);
        if m.fixed {
            continue;
        }
        let Some(i) = trial.index(&m.name) else {
            continue;
        };
        let x = placed[i];
        if !x.x.is_finite() {
            warnings.push(placer.place.warning(format!(
                "marker {} has no valid coordinates in {}: not moved",
                m.name, trial.source
            )));
            continue;
        }
        let (r, o) = data.body_pose(m.body);
        let in_body = r.transpose() * (x - o);
        moved.push((m.name.clone(), (in_body - m.location_in_body).norm()));
        locations.push((m.name.clone(), frame.inverse().apply_point(&in_body)));
    }
    let xml = set_marker_locations(&xml, source, &locations)?;
    let model = Model::from_osim_str_with(&xml, source, load)?;
    let static_pose = static_pose(&model, t0, &coordinates)?;
    Ok(Placement {
        xml,
        model,
        time: t0,
        coordinates,
        marker_errors,
        rmse: solution.rmse[0],
        max_error: solution.max_error[0],
        starts: solution.first_frame_starts.clone(),
        moved,
        removed,
        static_pose,
        warnings,
    })
}

/// The IK tasks of the IKTaskSet for `model` and the trial's columns.
fn tasks(
    model: &Model,
    trial: &Motion,
    placer: &MarkerPlacer,
    t0: f64,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<IkTasks> {
    let mut out = IkTasks::default();
    let mut coordinate_table: Option<Table> = None;
    for task in &placer.tasks {
        match task {
            IkTask::Marker {
                name,
                apply,
                weight,
                place,
            } => {
                if !apply {
                    continue;
                }
                let marker = model.markers.iter().position(|m| &m.name == name);
                let target = trial.index(name);
                match (marker, target) {
                    (Some(marker), Some(target)) => out.markers.push(MarkerTask {
                        marker,
                        target,
                        weight: *weight,
                    }),
                    (None, None) => {
                        return Err(place.error(format!(
                            "marker \"{name}\" is neither in the model nor in {}",
                            trial.source
                        )));
                    }
                    (Some(_), None) | (None, Some(_)) => warnings.push(place.warning(format!(
                        "marker \"{name}\" is not in {}: task not used",
                        if target.is_none() {
                            trial.source.as_str()
                        } else {
                            "the model"
                        }
                    ))),
                }
            }
            IkTask::Coordinate {
                name,
                apply,
                weight,
                value,
                place,
            } => {
                if !apply {
                    continue;
                }
                let Some(c) = model.coordinate_index(name) else {
                    return Err(place.error(format!("no coordinate \"{name}\" in the model")));
                };
                let Some(q) = ik::independent_index(model, name) else {
                    warnings.push(place.warning(format!(
                        "coordinate \"{name}\" is locked or coupled: the task has no effect"
                    )));
                    continue;
                };
                let v = match value {
                    CoordinateValue::Default => model.coordinates[c].default_value,
                    CoordinateValue::Manual(v) => *v,
                    CoordinateValue::FromFile => {
                        let Some(file) = &placer.coordinate_file else {
                            return Err(place.error(
                                "value_type from_file but the MarkerPlacer has no coordinate_file",
                            ));
                        };
                        if coordinate_table.is_none() {
                            let table = Table::read(file)?;
                            warnings.extend(table.warnings.iter().cloned());
                            coordinate_table = Some(table);
                        }
                        let table = coordinate_table.as_ref().expect("read above");
                        let col = table.column_index(name).ok_or_else(|| {
                            place.error(format!("no column \"{name}\" in {}", file.display()))
                        })?;
                        let v = table.interpolate(col, t0)?;
                        let rotational = model.coordinates[c].motion_type == MotionType::Rotational;
                        if table.in_degrees != Some(false) && rotational {
                            v.to_radians()
                        } else {
                            v
                        }
                    }
                };
                out.coordinates.push(CoordinateTask {
                    q,
                    weight: *weight,
                    value: vec![v],
                });
            }
        }
    }
    if placer
        .tasks
        .iter()
        .all(|t| !matches!(t, IkTask::Marker { apply: true, .. }))
    {
        out.markers = ik::tasks_by_name(model, trial).markers;
    }
    if out.markers.is_empty() {
        return Err(placer
            .place
            .error("no model marker has a counterpart in the static trial"));
    }
    // With every weight 0 the objective is 0 at any pose: the solver stops at the default
    // pose and the markers are moved onto the trial from there (by hundreds of millimetres).
    if out.markers.iter().all(|t| t.weight == 0.0)
        && out.coordinates.iter().all(|t| t.weight == 0.0)
    {
        return Err(placer.place.error(format!(
            "every applied task of the IKTaskSet ({} marker and {} coordinate task(s) used) has \
             weight 0: the static pose has nothing to fit; give the markers to fit a positive \
             weight",
            out.markers.len(),
            out.coordinates.len()
        )));
    }
    Ok(out)
}

/// The static pose as an OpenSim motion file: one row, every coordinate, rotational ones in
/// degrees (as OpenSim converts them).
fn static_pose(model: &Model, t: f64, coordinates: &[f64]) -> crate::Result<String> {
    let labels = model.coordinates.iter().map(|c| c.name.clone()).collect();
    let values = (model.coordinates.iter())
        .zip(coordinates)
        .map(|(c, v)| {
            if c.motion_type == MotionType::Rotational {
                v.to_degrees()
            } else {
                *v
            }
        })
        .collect();
    let mut table = Table::new("static pose", labels, vec![t], values)?;
    table.in_degrees = Some(true);
    table.to_file_string()
}
