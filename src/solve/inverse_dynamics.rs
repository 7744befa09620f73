//! OpenSim's Inverse Dynamics tool: the generalized forces τ that reproduce a recorded motion
//! under the recorded external loads,
//!
//!   τ = M(q) q̈ + C(q, q̇) q̇ + G(q) − Σ Jᵀ w_ext,
//!
//! at every row of the (prepared) motion within a time range, as a [`Table`] OpenSim's
//! `InverseDynamicsTool` would write.
//!
//! # What OpenSim does, reproduced here
//!
//! Preparation of the coordinates (InverseDynamicsTool::run, Storage::pad, Storage::lowpassIIR,
//! Storage::resample, GCVSplineSet):
//! 1. With a cutoff (OpenSim filters for any cutoff ≥ 0; musculo requires it to be positive)
//!    the motion is padded by ⌊n/2⌋ rows at each end by odd reflection,
//!    time included (t₋ᵢ = 2t₀ − tᵢ). If the padded times are not uniform to machine precision
//!    (mean step − smallest step > ε, which is the case for any file whose times were printed
//!    in decimal), every column is resampled at the smallest step with the interpolating
//!    natural quintic spline, at the times t₀, t₀ + h, t₀ + 2h, … accumulated by repeated
//!    addition while ≤ the last time (as OpenSim's loop does, so the output times carry the
//!    same drift, e.g. 0.39999934 for 0.4). Each column is then filtered by the zero-lag
//!    third-order Butterworth low-pass ([`super::filter::lowpass_butterworth3`]). A cutoff
//!    above 0.4 of the sampling rate is an error: OpenSim lowers one at or above half the
//!    rate to 0.49 of it, where the filter rings and the accelerations become noise
//!    ([`super::filter::HIGHEST_CUTOFF_FRACTION`]).
//! 2. Rotational coordinates are converted to radians when the file is in degrees. A file
//!    without `inDegrees` counts as degrees when it is an unversioned (SIMM) `.mot`, as
//!    OpenSim's `Storage` decides, and as radians otherwise.
//! 3. Every coordinate column gets the interpolating natural quintic spline S through the
//!    prepared rows (`GCVSplineSet(5, …)`); q = S(t), q̇ = S'(t), q̈ = S''(t).
//! 4. The rows computed are the prepared rows from the last one at or before
//!    max(first time, range start) to the last one at or before min(last time, range end)
//!    (`Storage::findIndex`). With filtering the first and last times are the padded ones, so
//!    a range starting before the recorded motion yields rows computed from the reflected
//!    padding, as in OpenSim (reported in [`InverseDynamicsOutput::warnings`]).
//! 5. External loads are applied as [`ExternalLoadSet`] describes (OpenSim's ExternalForce).
//! 6. Columns are named `<coordinate>_moment` for rotational coordinates and
//!    `<coordinate>_force` otherwise (translational and coupled: OpenSim tests
//!    `getMotionType() == Rotational`); the table is named
//!    `Inverse Dynamics Generalized Forces` with `inDegrees=no`.
//!
//! # Differences, by design
//!
//! - Without a time range the rows are those of the recorded span; OpenSim's default range
//!   (−∞, ∞) would include the padded rows when filtering.
//! - musculo's τ is in the model's independent coordinates: locked coordinates are held at
//!   their default value and dependent (coupled) coordinates follow their coupler, and their
//!   generalized forces are folded into the independent ones (τ = Φᵀ τ_full). OpenSim's tool
//!   ignores constraints and reports one mobility force per coordinate; for models with
//!   locked or coupled coordinates the columns therefore differ, and a warning says so.
//! - A coordinate missing from the motion is an error (OpenSim assumes its default value).
//! - No model force (muscle passive force, springs, limit forces) is applied: the result is
//!   OpenSim's with every force excluded. When the caller passes the setup's
//!   `forces_to_exclude`, forces OpenSim would have applied are listed as a warning.
//! - A rotational coordinate read as radians whose values exceed 2π while its model range
//!   lies within ±2π is reported as a warning (the file probably holds degrees but says
//!   `inDegrees=no`); the header is still honoured.

use super::external_loads::ExternalLoadSet;
use super::filter::{accumulated_grid, cutoff_problem, lowpass_butterworth3, pad_odd};
use super::kinematics::{
    CoordinateTrajectory, Differentiation, KinematicsOptions, independent_columns,
};
use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::io::{Dialect, Table};
use crate::model::natural_spline::NaturalSpline;
use crate::model::{Model, MotionType};
use crate::text::short_number;

/// OpenSim's `Storage::MAX_RESAMPLE_SIZE`: resampling never makes more rows than this.
const MAX_RESAMPLE_SIZE: f64 = 100_000.0;

/// Settings of the Inverse Dynamics tool.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InverseDynamicsOptions {
    /// Low-pass cutoff (Hz) for the coordinates; None: no filtering (OpenSim's −1). Must be
    /// positive when set.
    pub lowpass_hz: Option<f64>,
    /// [start, end] (s); None: the recorded rows, from the motion's first to its last time
    /// (OpenSim's default, (−∞, ∞), would also compute the rows of the filter's padding).
    pub time_range: Option<[f64; 2]>,
    /// The setup's `forces_to_exclude`, when the result is meant to match an OpenSim run:
    /// model forces it leaves in (which OpenSim would apply and musculo never does) are then
    /// reported as a warning. None: no such check.
    pub forces_to_exclude: Option<Vec<String>>,
}

impl InverseDynamicsOptions {
    /// The options an OpenSim `InverseDynamicsTool` setup file specifies (cutoff, time range,
    /// forces to exclude); its files are the caller's to read.
    pub fn from_setup(setup: &crate::io::setup::InverseDynamicsSetup) -> Self {
        InverseDynamicsOptions {
            lowpass_hz: setup.lowpass_cutoff_hz,
            time_range: setup.time_range,
            forces_to_exclude: Some(setup.forces_to_exclude.clone()),
        }
    }
}

/// The coordinates prepared as OpenSim's ID tool prepares them.
#[derive(Clone, Debug)]
pub struct PreparedCoordinates {
    /// q(t), q̇(t), q̈(t) (second derivative of the quintic spline).
    pub trajectory: CoordinateTrajectory,
    /// The prepared rows' times (padded and resampled when filtering).
    pub time: Vec<f64>,
    /// The first and last time of the motion as recorded.
    pub recorded_span: [f64; 2],
    /// The time step used for filtering (the smallest step of the padded rows), if filtered.
    pub filter_step: Option<f64>,
    /// Whether the rows were resampled before filtering.
    pub resampled: bool,
    /// Whether the file's rotational values were read as degrees.
    pub in_degrees: bool,
}

/// The result of [`inverse_dynamics`].
#[derive(Clone, Debug)]
pub struct InverseDynamicsOutput {
    /// τ per row: `time`, then `<coordinate>_moment` / `<coordinate>_force` in q order.
    pub table: Table,
    /// Things the caller should know (differences from what OpenSim would compute, suspect
    /// input); the library never prints them.
    pub warnings: Vec<String>,
}

/// Whether OpenSim reads the rotational values of `table` (from `source`) as degrees:
/// `inDegrees` when present, else degrees for an unversioned (SIMM) `.mot`, else radians.
pub fn opensim_in_degrees(table: &Table, source: &str) -> bool {
    match table.in_degrees {
        Some(d) => d,
        None => {
            table.dialect == Dialect::Unversioned && source.to_ascii_lowercase().ends_with(".mot")
        }
    }
}

/// The output column label OpenSim's ID tool gives coordinate `c` of `model`.
pub fn generalized_force_label(model: &Model, c: usize) -> String {
    let coord = &model.coordinates[c];
    match coord.motion_type {
        MotionType::Rotational => format!("{}_moment", coord.name),
        MotionType::Translational | MotionType::Coupled => format!("{}_force", coord.name),
    }
}

/// [`generalized_force_label`] of every independent coordinate, in q order.
pub fn generalized_force_labels(model: &Model) -> Vec<String> {
    model
        .reduction
        .independent
        .iter()
        .map(|&c| generalized_force_label(model, c))
        .collect()
}

/// Prepares the independent coordinates of `model` from `table` (read from `source`, named in
/// errors) as OpenSim's ID tool does (module documentation, steps 1–3), which is also how its
/// Analyze tool prepares them for static optimization. `differentiation` picks q̈: the ID
/// tool's S'' ([`Differentiation::SecondDerivative`]) or the Analyze tool's derivative of a
/// second spline through the speeds ([`Differentiation::SplineOfSpeeds`]). `warnings`
/// receives the degrees/radians suspicion.
pub fn prepare_coordinates(
    model: &Model,
    table: &Table,
    source: &str,
    lowpass_hz: Option<f64>,
    differentiation: Differentiation,
    warnings: &mut Vec<String>,
) -> crate::Result<PreparedCoordinates> {
    let locator = table.locator(source);
    let err = |element: String, message: String| locator.labels(element, message);
    let in_degrees = opensim_in_degrees(table, source);
    let mut columns = independent_columns(model, table, source)?;
    let names = model.q_names();
    if in_degrees && table.in_degrees.is_none() {
        // independent_columns reads a file without inDegrees as radians.
        for (col, &c) in columns.iter_mut().zip(&model.reduction.independent) {
            if model.coordinates[c].motion_type == MotionType::Rotational {
                col.iter_mut()
                    .for_each(|v| *v *= std::f64::consts::PI / 180.0);
            }
        }
    }
    if !in_degrees {
        degrees_suspicion(model, table, source, &columns, warnings);
    }
    let recorded_span = [table.time[0], table.time[table.n_rows() - 1]];
    let mut time = table.time.clone();
    let mut filter_step = None;
    let mut resampled = false;
    if let Some(fc) = lowpass_hz {
        if !(fc > 0.0 && fc.is_finite()) {
            return Err(Error::invalid(
                "lowpass_hz",
                format!("{fc} Hz: the cutoff must be a positive frequency"),
            ));
        }
        let n = time.len();
        if n < 4 {
            return Err(err(
                "table".into(),
                format!("{n} rows are too few to filter (4 or more needed)"),
            ));
        }
        // Storage::pad(n/2): odd reflection of every column, time included.
        let pad = n / 2;
        time = pad_odd(&time, pad);
        if let Some(t) = time.iter().find(|t| !t.is_finite()) {
            return Err(err(
                "column \"time\"".into(),
                format!(
                    "the times {} s to {} s are too large to pad for the low-pass filter \
                     (reflecting them gives {t})",
                    short_number(recorded_span[0]),
                    short_number(recorded_span[1])
                ),
            ));
        }
        for col in columns.iter_mut() {
            *col = pad_odd(col, pad);
        }
        // Storage::lowpassIIR: resample at the smallest step unless already uniform.
        let np = time.len();
        let mut dt = time
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let average = (time[np - 1] - time[0]) / (np - 1) as f64;
        if dt.is_nan() || dt <= f64::EPSILON {
            return Err(err(
                "column \"time\"".into(),
                format!("the smallest time step {dt} is too small to filter"),
            ));
        }
        if average - dt > f64::EPSILON {
            let (first, last) = (time[0], time[np - 1]);
            if (last - first) / dt > MAX_RESAMPLE_SIZE {
                dt = (last - first) / MAX_RESAMPLE_SIZE;
            }
            // GCVSplineSet::constructStorage: for (x = min; x <= max; x += dx), bounded.
            let new_time = accumulated_grid(first, last, dt).map_err(|m| {
                err(
                    "column \"time\"".into(),
                    format!(
                        "cannot resample the rows (recorded {} s to {} s) for the low-pass \
                         filter: {m}",
                        short_number(recorded_span[0]),
                        short_number(recorded_span[1])
                    ),
                )
            })?;
            for (col, name) in columns.iter_mut().zip(&names) {
                let spline = NaturalSpline::interpolating(3, time.clone(), std::mem::take(col))
                    .map_err(|m| err(format!("column \"{name}\""), m))?;
                *col = new_time.iter().map(|&t| spline.eval(t).0).collect();
            }
            time = new_time;
            resampled = true;
        }
        let duration = recorded_span[1] - recorded_span[0];
        if let Some(problem) = cutoff_problem(fc, dt, duration) {
            return Err(err("column \"time\"".into(), problem));
        }
        for (col, name) in columns.iter_mut().zip(&names) {
            *col = lowpass_butterworth3(col, dt, fc)
                .map_err(|m| err(format!("column \"{name}\""), m))?;
        }
        filter_step = Some(dt);
    }
    // Splines through the prepared rows, in radians.
    let nq = model.nq();
    let rows = time.len();
    let mut values = Vec::with_capacity(rows * nq);
    for r in 0..rows {
        values.extend(columns.iter().map(|c| c[r]));
    }
    let labels: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    let mut prepared = Table::new("prepared coordinates", labels, time.clone(), values)
        .map_err(|e| err("table".into(), format!("prepared coordinates: {e}")))?;
    prepared.in_degrees = Some(false);
    let mut trajectory = CoordinateTrajectory::from_table(
        model,
        &prepared,
        source,
        &KinematicsOptions {
            lowpass_hz: None,
            differentiation,
        },
    )
    .map_err(|e| match e {
        // A spline through a prepared column: name the column at the file's label line.
        Error::Motion {
            location, message, ..
        } => err(location, message),
        e => e,
    })?;
    trajectory.locate_in(table, source);
    Ok(PreparedCoordinates {
        trajectory,
        time,
        recorded_span,
        filter_step,
        resampled,
        in_degrees,
    })
}

/// A rotational coordinate read as radians that exceeds 2π although its model range lies
/// within ±2π: probably degrees under `inDegrees=no` (or no header).
fn degrees_suspicion(
    model: &Model,
    table: &Table,
    source: &str,
    columns: &[Vec<f64>],
    warnings: &mut Vec<String>,
) {
    let two_pi = 2.0 * std::f64::consts::PI;
    for (col, &c) in columns.iter().zip(&model.reduction.independent) {
        let coord = &model.coordinates[c];
        if coord.motion_type != MotionType::Rotational
            || coord.range[0] < -two_pi
            || coord.range[1] > two_pi
        {
            continue;
        }
        let (row, peak) = col.iter().enumerate().fold((0, 0.0f64), |(r, p), (i, v)| {
            if v.abs() > p { (i, v.abs()) } else { (r, p) }
        });
        if peak > two_pi {
            let at = table
                .row_line(row)
                .map_or(String::new(), |line| format!(":{line}"));
            warnings.push(format!(
                "{source}{at}: column \"{}\" (time {}): {} rad exceeds 2π while the \
                 model's range is [{}, {}] rad; the file reads as radians (inDegrees={}) but \
                 its values look like degrees",
                coord.name,
                table.time[row],
                col[row],
                coord.range[0],
                coord.range[1],
                match table.in_degrees {
                    Some(false) => "no",
                    _ => "absent",
                }
            ));
        }
    }
}

/// OpenSim's `Storage::findIndex`: the last row with time ≤ t (0 if none).
fn find_index(time: &[f64], t: f64) -> usize {
    time.partition_point(|&x| x <= t).saturating_sub(1)
}

/// The prepared rows OpenSim's tools compute for `time_range` (None: the recorded span):
/// from the last row at or before its start to the last row at or before its end
/// (`Storage::findIndex`), with warnings when rows come from the filter's padding or lie
/// beyond the external-load data.
pub fn rows_in_range(
    prepared: &PreparedCoordinates,
    time_range: Option<[f64; 2]>,
    source: &str,
    loads: Option<&ExternalLoadSet>,
    warnings: &mut Vec<String>,
) -> crate::Result<(usize, usize)> {
    let time = &prepared.time;
    let (first, last) = (time[0], time[time.len() - 1]);
    let [rec0, rec1] = prepared.recorded_span;
    let [start, end] = time_range.unwrap_or([rec0, rec1]);
    if start.is_nan() || end.is_nan() || start > end {
        return Err(Error::invalid(
            "time_range",
            format!("[{start}, {end}] is not a range"),
        ));
    }
    let start_time = first.max(start);
    let final_time = last.min(end);
    if start_time > final_time {
        return Err(Error::invalid(
            "time_range",
            format!("[{start}, {end}] s does not overlap the motion's rows, [{first}, {last}] s"),
        ));
    }
    let (i0, i1) = (find_index(time, start_time), find_index(time, final_time));
    // Resampled rows drift from the recorded times by a few ulps per step.
    let slack = 1e-3 * prepared.filter_step.unwrap_or(0.0);
    if time[i0] < rec0 - slack || time[i1] > rec1 + slack {
        warnings.push(format!(
            "{source}: rows from {:.8} s to {:.8} s are computed, but the motion was recorded from \
             {rec0} s to {rec1} s: rows outside come from the reflected padding of the \
             low-pass filter (as in OpenSim)",
            time[i0], time[i1]
        ));
    }
    if let Some(l) = loads {
        let [l0, l1] = l.time_span;
        let slack = 1e-6 * (l1 - l0);
        if time[i0] < l0 - slack || time[i1] > l1 + slack {
            warnings.push(format!(
                "{}: external load data span {l0} s to {l1} s, but rows from {:.8} s to {:.8} s are \
                 computed: beyond the data the forces are extrapolated (linearly, as OpenSim's \
                 splines do)",
                l.data_source, time[i0], time[i1]
            ));
        }
    }

    Ok((i0, i1))
}

/// Inverse dynamics of the motion in `coordinates` (read from `source`) with the external
/// loads `loads`, as OpenSim's Inverse Dynamics tool computes it (module documentation).
/// `progress(done, total)` is called after every row. One `Data` is used; nothing is
/// allocated per row beyond the output table.
pub fn inverse_dynamics(
    model: &Model,
    coordinates: &Table,
    source: &str,
    loads: Option<&ExternalLoadSet>,
    options: &InverseDynamicsOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> crate::Result<InverseDynamicsOutput> {
    let mut warnings = Vec::new();
    model_warnings(model, options, &mut warnings);
    let prepared = prepare_coordinates(
        model,
        coordinates,
        source,
        options.lowpass_hz,
        Differentiation::SecondDerivative,
        &mut warnings,
    )?;
    let (i0, i1) = rows_in_range(&prepared, options.time_range, source, loads, &mut warnings)?;
    let time = &prepared.time;
    let n = model.nq();
    let rows = i1 - i0 + 1;
    let mut data = Data::new(model);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut external = vec![0.0; n];
    let mut values = Vec::with_capacity(rows * n);
    for (k, &t) in time[i0..=i1].iter().enumerate() {
        prepared
            .trajectory
            .eval_finite(t, &mut q, &mut qd, &mut qdd)?;
        // τ = M q̈ + C q̇ + G (this also leaves the pose in `data` for the loads).
        let tau = dynamics::rnea(model, &mut data, &q, &qd, &qdd)?;
        if let Some(j) = tau.iter().position(|v| !v.is_finite()) {
            let k = CoordinateTrajectory::largest(&q, &qd, &qdd);
            return Err(prepared.trajectory.error_at(
                t,
                k,
                format!(
                    "the generalized force `{}` is {}: this coordinate's value {}, speed {} \
                     and acceleration {} (the largest at this time) are beyond what the \
                     dynamics can compute",
                    generalized_force_label(model, model.reduction.independent[j]),
                    tau[j],
                    short_number(q[k]),
                    short_number(qd[k]),
                    short_number(qdd[k]),
                ),
            ));
        }
        values.extend_from_slice(tau.as_slice());
        if let Some(l) = loads {
            external.fill(0.0);
            l.add_generalized_forces(model, &data, t, &mut external)?;
            // τ −= Σ Jᵀ w_ext
            let row = &mut values[k * n..(k + 1) * n];
            for (v, e) in row.iter_mut().zip(&external) {
                *v -= e;
            }
        }
        progress(k + 1, rows);
    }
    let labels = generalized_force_labels(model);
    let mut table = Table::new(
        "Inverse Dynamics Generalized Forces",
        labels,
        time[i0..=i1].to_vec(),
        values,
    )?;
    table.in_degrees = Some(false);
    Ok(InverseDynamicsOutput { table, warnings })
}

/// Warnings that depend on the model alone: coordinates OpenSim would report differently,
/// and model forces OpenSim would apply.
fn model_warnings(model: &Model, options: &InverseDynamicsOptions, warnings: &mut Vec<String>) {
    use crate::model::CoordinateRole;
    let constrained: Vec<&str> = model
        .coordinates
        .iter()
        .filter(|c| !matches!(c.role, CoordinateRole::Independent(_)))
        .map(|c| c.name.as_str())
        .collect();
    if !constrained.is_empty() {
        warnings.push(format!(
            "{}: locked or coupled coordinates ({}) have no column: musculo reports τ in the \
             independent coordinates (τ = Φᵀ τ_full), while OpenSim's tool ignores constraints \
             and reports a generalized force for every coordinate",
            model.source,
            constrained.join(", ")
        ));
    }
    let Some(exclude) = &options.forces_to_exclude else {
        return;
    };
    let has = |k: &str| exclude.iter().any(|e| e.eq_ignore_ascii_case(k));
    if has("all") {
        return;
    }
    let applied: Vec<&str> = model
        .forces
        .iter()
        .filter(|f| {
            let raw = |tag: &str| f.raw.child(tag).map(|c| c.text.trim().to_ascii_lowercase());
            let disabled = raw("appliesForce").as_deref() == Some("false")
                || raw("isDisabled").as_deref() == Some("true");
            if disabled || exclude.iter().any(|e| e == &f.name) {
                false
            } else if f.is_muscle() {
                !(has("muscles") || has("actuators"))
            } else {
                // Other actuators produce no force without controls (zero in OpenSim's ID).
                !f.kind.ends_with("Actuator")
            }
        })
        .map(|f| f.name.as_str())
        .collect();
    if !applied.is_empty() {
        let shown: Vec<&str> = applied.iter().take(8).copied().collect();
        warnings.push(format!(
            "forces_to_exclude leaves {} model force(s) in ({}{}), which OpenSim would apply; \
             musculo's inverse dynamics applies no model forces",
            applied.len(),
            shown.join(", "),
            if applied.len() > shown.len() {
                ", …"
            } else {
                ""
            }
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn find_index_is_the_last_row_at_or_before() {
        let t = [0.0, 0.1, 0.2, 0.3];
        assert_eq!(find_index(&t, -1.0), 0);
        assert_eq!(find_index(&t, 0.0), 0);
        assert_eq!(find_index(&t, 0.15), 1);
        assert_eq!(find_index(&t, 0.2), 2);
        assert_eq!(find_index(&t, 9.0), 3);
    }

    #[test]
    fn a_static_pose_needs_exactly_the_gravity_forces() {
        let model = Model::demo();
        let q = model.default_q();
        let names: Vec<String> = model.q_names().iter().map(|s| s.to_string()).collect();
        let time: Vec<f64> = (0..20).map(|i| i as f64 * 0.01).collect();
        let mut values = Vec::new();
        for _ in &time {
            values.extend_from_slice(&q);
        }
        let mut table = Table::new("static", names, time, values).unwrap();
        table.in_degrees = Some(false);
        let mut calls = 0;
        let out = inverse_dynamics(
            &model,
            &table,
            "static.sto",
            None,
            &InverseDynamicsOptions {
                lowpass_hz: Some(6.0),
                ..Default::default()
            },
            &mut |done, total| {
                calls += 1;
                assert!(done <= total);
            },
        )
        .unwrap();
        let mut data = Data::new(&model);
        let g = dynamics::gravity(&model, &mut data, &q).unwrap().clone();
        assert_eq!(out.table.n_rows(), 20);
        assert_eq!(calls, 20);
        for r in 0..out.table.n_rows() {
            for j in 0..model.nq() {
                let v = out.table.value(r, j).unwrap();
                assert!(
                    (v - g[j]).abs() < 1e-9 * (1.0 + g[j].abs()),
                    "row {r} coord {j}: {v} vs {}",
                    g[j]
                );
            }
        }
        assert_eq!(out.table.in_degrees, Some(false));
    }
}
