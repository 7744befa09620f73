//! Kinematics preparation: independent coordinates q(t) from a motion table (.mot/.sto),
//! and their smooth derivatives q̇(t), q̈(t), as OpenSim's tools compute them.
//!
//! Columns are matched to coordinates by name (`knee_angle_r`, or an OpenSim 4 state path
//! such as `/jointset/knee_r/knee_angle_r/value`); with `inDegrees=yes`, rotational
//! coordinates are converted to radians (OpenSim converts only coordinates whose motion type
//! is rotational). Dependent and locked coordinates are not read: the reduction computes them.
//!
//! Differentiation uses the interpolating natural quintic spline through each column
//! (OpenSim's `GCVSplineSet(5, …)` with zero error variance), which is smooth (C⁴) and exact
//! for polynomials of degree ≤ 2 outside the data; two variants match OpenSim's tools:
//! - [`Differentiation::SecondDerivative`] (Inverse Dynamics tool): q̇ = S'(t), q̈ = S''(t);
//! - [`Differentiation::SplineOfSpeeds`] (Analyze tool, Static Optimization): q̇ = S'(t), and
//!   q̈ is the derivative of a second quintic spline through the speeds S'(t_i) sampled at
//!   the data times.

use super::filter::{cutoff_problem, lowpass_padded};
use crate::error::Error;
use crate::io::{Table, TableLocator};
use crate::model::natural_spline::NaturalSpline;
use crate::model::{Model, MotionType};
use crate::text::short_number;

/// How q̈ is obtained from the spline of q.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Differentiation {
    #[default]
    SecondDerivative,
    SplineOfSpeeds,
}

/// How coordinates are prepared.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KinematicsOptions {
    /// Low-pass cutoff (Hz); None: no filtering (OpenSim's −1).
    pub lowpass_hz: Option<f64>,
    pub differentiation: Differentiation,
}

/// q(t), q̇(t), q̈(t) for every independent coordinate.
#[derive(Clone, Debug)]
pub struct CoordinateTrajectory {
    /// The data times.
    pub time: Vec<f64>,
    q: Vec<NaturalSpline>,
    /// Splines of the speeds, for `SplineOfSpeeds`.
    qd: Option<Vec<NaturalSpline>>,
    /// Where the coordinates came from, for [`Self::eval_finite`]'s errors.
    locator: TableLocator,
    /// The column of each independent coordinate, in q order.
    names: Vec<String>,
}

impl CoordinateTrajectory {
    /// Fits the trajectory of every independent coordinate of `model` in `table` (read from
    /// `source`, named in errors), low-pass filtered first when `options.lowpass_hz` is set
    /// (OpenSim's padding by half the record at each end and zero-lag third-order
    /// Butterworth; the splines then span the padded record, as in OpenSim).
    pub fn from_table(
        model: &Model,
        table: &Table,
        source: &str,
        options: &KinematicsOptions,
    ) -> crate::Result<CoordinateTrajectory> {
        let locator = table.locator(source);
        let err = |element: String, message: String| locator.labels(element, message);
        let mut columns = independent_columns(model, table, source)?;
        let mut time = table.time.clone();
        if let Some(fc) = options.lowpass_hz {
            let n = time.len();
            if n < 4 {
                return Err(err(
                    "table".into(),
                    format!("{n} rows are too few to filter (4 or more needed)"),
                ));
            }
            let dt = (time[n - 1] - time[0]) / (n - 1) as f64;
            let uniform = time
                .windows(2)
                .all(|w| ((w[1] - w[0]) - dt).abs() <= 1e-6 * dt);
            if !uniform {
                return Err(err(
                    "column \"time\"".into(),
                    "filtering needs uniformly sampled rows; resample the motion first".into(),
                ));
            }
            if let Some(problem) = cutoff_problem(fc, dt, time[n - 1] - time[0]) {
                return Err(err("column \"time\"".into(), problem));
            }
            time = lowpass_padded(&time, &mut columns, dt, fc).map_err(|(k, m)| {
                let c = model.reduction.independent[k];
                err(format!("column \"{}\"", model.coordinates[c].name), m)
            })?;
        }
        // One quintic spline per coordinate, all on the same knots (built together).
        let q = NaturalSpline::interpolating_many(3, time.clone(), columns).map_err(|(k, m)| {
            let c = model.reduction.independent[k];
            err(format!("column \"{}\"", model.coordinates[c].name), m)
        })?;
        let qd = match options.differentiation {
            Differentiation::SecondDerivative => None,
            Differentiation::SplineOfSpeeds => Some(
                NaturalSpline::interpolating_many(
                    3,
                    time.clone(),
                    q.iter()
                        .map(|s| time.iter().map(|&t| s.eval(t).1).collect())
                        .collect(),
                )
                .map_err(|(_, m)| err("table".into(), m))?,
            ),
        };
        Ok(CoordinateTrajectory {
            time: table.time.clone(),
            q,
            qd,
            names: model.q_names().iter().map(|s| s.to_string()).collect(),
            locator,
        })
    }

    /// Makes errors name the rows and lines of `table` (read from `source`): for a
    /// trajectory fitted to a table prepared from it (filtered, resampled).
    pub fn locate_in(&mut self, table: &Table, source: &str) {
        self.locator = table.locator(source);
    }

    /// The error for a value the trajectory or a stage after it cannot use at time `t`,
    /// about coordinate `j` (in q order): at the file line of the row at (or nearest) `t`
    /// and the coordinate's column.
    pub fn error_at(&self, t: f64, j: usize, message: impl Into<String>) -> Error {
        let name = self.names.get(j).map_or("?", String::as_str);
        self.locator
            .at_time(t, format!("column \"{name}\""), message)
    }

    /// [`Self::eval`], with an error at the row and column when q, q̇ or q̈ is not finite
    /// (values so large or rows so close that the spline overflows).
    pub fn eval_finite(
        &self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
        qdd: &mut [f64],
    ) -> crate::Result<()> {
        self.eval(t, q, qd, qdd);
        for (what, values) in [("value", &*q), ("speed", &*qd), ("acceleration", &*qdd)] {
            if let Some(j) = values.iter().position(|v| !v.is_finite()) {
                return Err(self.error_at(
                    t,
                    j,
                    format!(
                        "the coordinate's {what} from the spline through the column is {} \
                         (values too large or times too close to differentiate)",
                        values[j]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The coordinate (q order) whose value, speed or acceleration is largest in magnitude: the one to name when a result computed
    /// from all of them overflows.
    pub fn largest(q: &[f64], qd: &[f64], qdd: &[f64]) -> usize {
        let size = |j: usize| q[j].abs().max(qd[j].abs()).max(qdd[j].abs());
        (0..q.len())
            .max_by(|&a, &b| size(a).total_cmp(&size(b)))
            .unwrap_or(0)
    }

    /// q, q̇, q̈ at time t (outside the data the splines extrapolate as OpenSim's do).
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for (j, s) in self.q.iter().enumerate() {
            let (v, d1, d2) = s.eval(t);
            q[j] = v;
            qd[j] = d1;
            qdd[j] = match &self.qd {
                Some(u) => u[j].eval(t).1,
                None => d2,
            };
        }
    }
}

/// The largest magnitude of a coordinate value read from a motion, in radians or metres.
/// Beyond it a value is a typing or unit error, not a pose: near 10¹⁵ adjacent doubles are
/// 0.125 apart, so an angle no longer resolves 7°, and no body travels 10¹⁵ m. Such a value
/// makes inverse dynamics and static optimization fail on a NaN force at another row (the
/// spline through it overflows its derivatives at the neighbouring rows), and the muscle
/// paths compute finite nonsense from the sine of it; refused at its own row instead.
pub const MAX_COORDINATE_MAGNITUDE: f64 = 1e15;

/// The values of every independent coordinate of `model` in `table`, one column per
/// coordinate in q order, in radians (rotational coordinates are converted when the table
/// says `inDegrees=yes`). A missing column is an error naming it; a value beyond
/// ±[`MAX_COORDINATE_MAGNITUDE`] (or not finite) is an error at its row's line and column.
pub fn independent_columns(
    model: &Model,
    table: &Table,
    source: &str,
) -> crate::Result<Vec<Vec<f64>>> {
    let degrees = table.in_degrees.unwrap_or(false);
    let mut columns = Vec::with_capacity(model.nq());
    for &c in &model.reduction.independent {
        let coord = &model.coordinates[c];
        let col = table
            .labels
            .iter()
            .position(|l| column_names_coordinate(l, &coord.name))
            .ok_or_else(|| {
                table.locator(source).labels(
                    format!("column \"{}\"", coord.name),
                    format!(
                        "no column for the model's independent coordinate `{}`",
                        coord.name
                    ),
                )
            })?;
        let scale = if degrees && coord.motion_type == MotionType::Rotational {
            std::f64::consts::PI / 180.0
        } else {
            1.0
        };
        let values: Vec<f64> = (0..table.n_rows())
            .map(|r| table.value(r, col).unwrap_or(f64::NAN) * scale)
            .collect();
        if let Some(r) = values
            .iter()
            .position(|v| !(v.abs() <= MAX_COORDINATE_MAGNITUDE))
        {
            let unit = match coord.motion_type {
                MotionType::Rotational => "rad",
                MotionType::Translational => "m",
                MotionType::Coupled => "rad or m",
            };
            let value = short_number(table.value(r, col).unwrap_or(f64::NAN));
            let value = if scale == 1.0 {
                format!("{value} {unit}")
            } else {
                format!("{value}° ({} rad)", short_number(values[r]))
            };
            return Err(table.locator(source).row(
                r,
                format!("column \"{}\"", coord.name),
                format!(
                    "the value {value} is beyond ±{MAX_COORDINATE_MAGNITUDE:e} {unit}, which no \
                     coordinate reaches: a typing or unit error"
                ),
            ));
        }
        columns.push(values);
    }
    Ok(columns)
}

/// True when a column label names the coordinate: its name, or a state path ending in
/// `/<name>/value`.
fn column_names_coordinate(label: &str, name: &str) -> bool {
    label == name
        || label
            .strip_suffix("/value")
            .is_some_and(|p| p.rsplit('/').next() == Some(name))
}

/// Adds, for every independent coordinate of `model` that `table` has no column for, a
/// constant column at the coordinate's default value (in degrees for a rotational coordinate
/// when the table is in degrees) — for applying another model's motion by coordinate name.
/// Returns the names of the coordinates added, in q order.
pub fn fill_missing_coordinates(model: &Model, table: &mut Table) -> Vec<String> {
    let degrees = table.in_degrees.unwrap_or(false);
    let missing: Vec<usize> = (model.reduction.independent.iter().copied())
        .filter(|&c| {
            let name = &model.coordinates[c].name;
            !table
                .labels
                .iter()
                .any(|l| column_names_coordinate(l, name))
        })
        .collect();
    if missing.is_empty() {
        return Vec::new();
    }
    let old = table.labels.len();
    let defaults: Vec<f64> = (missing.iter())
        .map(|&c| {
            let coord = &model.coordinates[c];
            if degrees && coord.motion_type == MotionType::Rotational {
                coord.default_value.to_degrees()
            } else {
                coord.default_value
            }
        })
        .collect();
    let mut values = Vec::with_capacity(table.time.len() * (old + missing.len()));
    for r in 0..table.time.len() {
        values.extend_from_slice(&table.values[r * old..(r + 1) * old]);
        values.extend_from_slice(&defaults);
    }
    table.values = values;
    let names: Vec<String> = missing
        .iter()
        .map(|&c| model.coordinates[c].name.clone())
        .collect();
    table.labels.extend(names.iter().cloned());
    names
}
