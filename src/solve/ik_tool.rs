//! OpenSim's Inverse Kinematics tool on top of [`super::ik`]: the tasks, frames and
//! objective an `InverseKinematicsTool` setup asks for, and the files OpenSim writes.
//!
//! As OpenSim 4.6 does:
//! - marker tasks: the `IKMarkerTask`s with `apply` true whose marker is both in the model
//!   and in the marker file; when the task set lists no marker at all, every marker of the
//!   file that the model has, with weight 1;
//! - coordinate tasks (`apply` true) on independent coordinates, towards the default value,
//!   the manual value (in the coordinate's units), or the coordinate file's column
//!   (degrees converted for rotational coordinates; linearly interpolated at the frame
//!   times — OpenSim fits a quintic GCV spline; the two agree where the file's times are
//!   the frames', as in OpenSim's pipelines);
//! - the objective Σ_i (w_i / Σ_present w) ‖e_i‖² + Σ_c w_c (q_c − r_c)², i.e. twice
//!   OpenSim's assembler goal (its marker goal is a weighted mean over the markers present
//!   in the frame), with only `clamped` coordinates bounded;
//! - frames: the marker file's rows from the one nearest the start of `time_range` to the
//!   one nearest its end.
//!
//! Outputs: the coordinates as OpenSim's `.mot` (every coordinate, rotations in degrees), and
//! the marker errors as OpenSim's `_ik_marker_errors.sto` (`total_squared_error` = Σ‖e_i‖²
//! unweighted, `marker_error_RMS` = √(that / markers in use, missing ones included),
//! `marker_error_max`), plus musculo's per-marker errors table.

use super::ik::{CoordinateTask, IkSolution, IkTasks, MarkerTask};
use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::io::Table;
use crate::io::ik_setup::{CoordinateValue, IkSetup};
use crate::model::{CoordinateRole, Model, MotionType};
use crate::motion::Motion;

/// The row of `time` nearest to `t` (the earlier one on a tie).
fn nearest_row(time: &[f64], t: f64) -> usize {
    let upper = time.partition_point(|&ti| ti < t);
    if upper == 0 {
        0
    } else if upper == time.len() {
        time.len() - 1
    } else if (time[upper] - t) < (t - time[upper - 1]) {
        upper
    } else {
        upper - 1
    }
}

/// The frames OpenSim's IK tool solves: rows nearest the start and end of `range`.
pub fn select_frames(markers: &Motion, range: Option<[f64; 2]>) -> crate::Result<Motion> {
    let Some([start, end]) = range else {
        return Ok(markers.clone());
    };
    let first = nearest_row(&markers.time, start.max(markers.time[0]));
    let last = nearest_row(&markers.time, end.min(*markers.time.last().unwrap_or(&end)));
    if last < first {
        return Err(Error::Motion {
            file: markers.source.clone(),
            location: "time range".into(),
            message: format!("[{start}, {end}] selects no frame"),
        });
    }
    markers.time_window(markers.time[first], markers.time[last])
}

/// The tasks of an IK setup for `markers` (after [`select_frames`]); returns them with
/// warnings about tasks that name markers or coordinates the model or the file lacks.
pub fn tasks_from_setup(
    model: &Model,
    setup: &IkSetup,
    markers: &Motion,
    coordinate_file: Option<&Table>,
) -> crate::Result<(IkTasks, Vec<String>)> {
    let mut warnings = Vec::new();
    let mut tasks = IkTasks::default();
    let marker_index = |name: &str| model.markers.iter().position(|m| m.name == name);
    if setup.marker_tasks.is_empty() {
        for (target, name) in markers.names.iter().enumerate() {
            if let Some(marker) = marker_index(name) {
                tasks.markers.push(MarkerTask {
                    marker,
                    target,
                    weight: 1.0,
                });
            }
        }
    }
    let file = setup.source.display();
    for t in &setup.marker_tasks {
        if !t.apply {
            continue;
        }
        match (marker_index(&t.name), markers.index(&t.name)) {
            (Some(marker), Some(target)) => tasks.markers.push(MarkerTask {
                marker,
                target,
                weight: t.weight,
            }),
            (None, _) => warnings.push(format!(
                "{file}:{}: IKMarkerTask \"{}\": the model has no such marker; not used",
                t.line, t.name
            )),
            (_, None) => warnings.push(format!(
                "{file}:{}: IKMarkerTask \"{}\": {} has no such marker; not used",
                t.line, t.name, markers.source
            )),
        }
    }
    for t in &setup.coordinate_tasks {
        if !t.apply {
            continue;
        }
        let Some(c) = model.coordinate_index(&t.name) else {
            warnings.push(format!(
                "{file}:{}: IKCoordinateTask \"{}\": the model has no such coordinate; not used",
                t.line, t.name
            ));
            continue;
        };
        let coord = &model.coordinates[c];
        let CoordinateRole::Independent(q) = coord.role else {
            warnings.push(format!(
                "{file}:{}: IKCoordinateTask \"{}\": the coordinate is locked or coupled; not \
                 used (as OpenSim drops tasks on locked coordinates)",
                t.line, t.name
            ));
            continue;
        };
        let value = match t.value {
            CoordinateValue::Default => vec![coord.default_value],
            CoordinateValue::Manual(v) => vec![v],
            CoordinateValue::FromFile => {
                let table = coordinate_file.ok_or_else(|| {
                    Error::invalid(
                        "coordinate_file",
                        format!(
                            "{file}:{}: IKCoordinateTask \"{}\" takes its value from_file, but \
                             no coordinate_file is given",
                            t.line, t.name
                        ),
                    )
                })?;
                let column = table.column_index(&t.name).ok_or_else(|| {
                    Error::invalid(
                        "coordinate_file",
                        format!(
                            "no column \"{}\" for the IKCoordinateTask at {file}:{}",
                            t.name, t.line
                        ),
                    )
                })?;
                let to_si = if table.in_degrees != Some(false)
                    && coord.motion_type == MotionType::Rotational
                {
                    std::f64::consts::PI / 180.0
                } else {
                    1.0
                };
                markers
                    .time
                    .iter()
                    .map(|&time| Ok(table.interpolate(column, time)? * to_si))
                    .collect::<crate::Result<Vec<f64>>>()?
            }
        };
        tasks.coordinates.push(CoordinateTask {
            q,
            weight: t.weight,
            value,
        });
    }
    if tasks.markers.is_empty() {
        return Err(Error::invalid(
            "setup",
            format!(
                "{file}: no marker task matches both the model `{}` and {}",
                model.name, markers.source
            ),
        ));
    }
    Ok((tasks, warnings))
}

/// The solution as OpenSim's IK `.mot`: every model coordinate (locked and coupled ones
/// too), rotations in degrees.
pub fn coordinates_table(model: &Model, solution: &IkSolution) -> crate::Result<Table> {
    let mut data = Data::new(model);
    let labels: Vec<String> = model.coordinates.iter().map(|c| c.name.clone()).collect();
    let mut values = Vec::with_capacity(solution.n_frames() * labels.len());
    for f in 0..solution.n_frames() {
        dynamics::forward_kinematics(model, &mut data, solution.frame(f))?;
        for (c, v) in model.coordinates.iter().zip(data.coordinate_values(model)) {
            // OpenSim writes rotational coordinates in degrees, everything else as it is
            // (coupled coordinates too: gait2392's pelvis translations are `coupled`).
            values.push(if c.motion_type == MotionType::Rotational {
                v.to_degrees()
            } else {
                *v
            });
        }
    }
    let mut table = Table::new("Coordinates", labels, solution.time.clone(), values)?;
    table.in_degrees = Some(true);
    Ok(table)
}

/// OpenSim's `_ik_marker_errors.sto` columns.
pub fn marker_errors_table(solution: &IkSolution, tasks: &IkTasks) -> crate::Result<Table> {
    let nm = tasks.markers.len();
    let mut values = Vec::with_capacity(solution.n_frames() * 3);
    for f in 0..solution.n_frames() {
        let errors = &solution.marker_error[f * nm..(f + 1) * nm];
        let total: f64 = errors.iter().filter(|e| !e.is_nan()).map(|e| e * e).sum();
        let max = errors
            .iter()
            .filter(|e| !e.is_nan())
            .fold(0.0f64, |a, &e| a.max(e));
        values.extend([total, (total / nm.max(1) as f64).sqrt(), max]);
    }
    let mut table = Table::new(
        "Model Marker Errors from IK",
        vec![
            "total_squared_error".into(),
            "marker_error_RMS".into(),
            "marker_error_max".into(),
        ],
        solution.time.clone(),
        values,
    )?;
    table.in_degrees = Some(false);
    Ok(table)
}

/// Each marker's error per frame (m); a marker missing in a frame has error 0 there and is
/// listed by [`missing_marker_frames`].
pub fn marker_errors_by_marker(
    model: &Model,
    solution: &IkSolution,
    tasks: &IkTasks,
) -> crate::Result<Table> {
    let labels = tasks
        .markers
        .iter()
        .map(|t| model.markers[t.marker].name.clone())
        .collect();
    let values = solution
        .marker_error
        .iter()
        .map(|e| if e.is_nan() { 0.0 } else { *e })
        .collect();
    let mut table = Table::new(
        "Marker errors from IK, per marker (m)",
        labels,
        solution.time.clone(),
        values,
    )?;
    table.in_degrees = Some(false);
    Ok(table)
}

/// Per marker task, the number of frames in which its target was missing.
pub fn missing_marker_frames(solution: &IkSolution, tasks: &IkTasks) -> Vec<usize> {
    let nm = tasks.markers.len();
    let mut out = vec![0; nm];
    for (k, e) in solution.marker_error.iter().enumerate() {
        if e.is_nan() {
            out[k % nm] += 1;
        }
    }
    out
}
