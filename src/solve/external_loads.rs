//! External loads over time, applied as OpenSim's `ExternalForce` applies them: the generalized
//! forces Q = Σ Jᵀ w of every force of an ExternalLoads file at a state.
//!
//! What OpenSim does (ExternalForce.cpp, ExternalLoads.cpp, Storage.cpp), and this module
//! reproduces:
//! - the columns of an identifier are the data-file columns whose label *starts with* it
//!   (`ground_force_v` → `ground_force_vx`, `…vy`, `…vz`), taken in file order; there must be
//!   exactly three, otherwise the force is an error;
//! - every column becomes a function of time chosen by the number of rows n of the data file:
//!   a constant for n = 1, piecewise-linear interpolation (extrapolating with the end segments'
//!   slopes) for n = 2 or 3, and otherwise the interpolating natural cubic spline
//!   (`GCVSpline` of degree 3 with zero error variance, linear beyond the ends);
//! - the force and the torque are expressed in `force_expressed_in_body` and re-expressed in
//!   ground with that body's current orientation; the point is a station of
//!   `point_expressed_in_body` (current pose); without a point identifier the force acts at
//!   the origin of `applied_to_body`; the torque is a pure couple on `applied_to_body`;
//! - the identifiers are used as written: a file that names one foot's torque columns for the
//!   other foot (`torque_identifier left_foot_torque_` on the right foot in OpenSim's joint
//!   reaction tutorial) is applied that way, as OpenSim applies it.
//!
//! A `PrescribedForce` of the file is applied as OpenSim applies it: its functions of time,
//! force and torque in ground or in its body (`forceIsGlobal`), the point in ground or in its
//! body (`pointIsGlobal`), the body's origin without a point.
//!
//! Deliberate differences: an unknown `force_expressed_in_body` / `point_expressed_in_body` is
//! an error (OpenSim warns and uses ground), and so is an ExternalLoads file with
//! ExternalForces but without a `datafile`.

use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::io::Table;
use crate::io::external_loads::ExternalLoads;
use crate::model::Model;
use crate::model::function::{Function, PiecewiseLinear};
use crate::model::natural_spline::NaturalSpline;
use crate::spatial::Vec3;
use crate::text::short_number;
use std::path::Path;

/// The largest magnitude of a force (N), point (m) or torque (N·m) value in an external
/// loads' data file. Force plates are rated to some 10⁴ N, and the largest loads bodies
/// survive (impacts, a landing elephant) stay below 10⁵ N; a point 10⁷ m from the origin lies
/// outside the Earth (radius 6.4·10⁶ m), and 10⁷ N·m is 10⁷ N at a metre. A value beyond it is
/// a typing or unit error; read as a load it gives moments of 10¹⁶⁰ N·m for a force of 10³⁰⁰ N
/// where a NaN is refused.
pub const MAX_EXTERNAL_LOAD_MAGNITUDE: f64 = 1e7;

/// One external force, resolved against a model and a data file.
#[derive(Clone, Debug)]
pub struct AppliedExternalForce {
    pub name: String,
    /// Body indices into `Model::bodies`.
    pub applied_to_body: usize,
    pub force_expressed_in_body: usize,
    pub point_expressed_in_body: usize,
    /// x, y, z of the force (in `force_expressed_in_body`), if the force specifies one.
    force: Option<[Function; 3]>,
    /// x, y, z of the point (in `point_expressed_in_body`), if specified.
    point: Option<[Function; 3]>,
    /// x, y, z of the torque (in `force_expressed_in_body`), if specified.
    torque: Option<[Function; 3]>,
    /// The data-file columns used: force, point, torque (labels).
    pub columns: Vec<String>,
}

/// A wrench of one external force at one instant, in ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundWrench {
    /// The body the wrench acts on.
    pub body: usize,
    pub force_in_ground: Vec3,
    /// Where the force acts, in ground.
    pub point_in_ground: Vec3,
    pub torque_in_ground: Vec3,
}

/// The forces of an ExternalLoads file with their data, ready to be evaluated at any time.
#[derive(Clone, Debug)]
pub struct ExternalLoadSet {
    /// The ExternalLoads file (for messages).
    pub source: String,
    /// The data file (the ExternalLoads file when only PrescribedForces are in it).
    pub data_source: String,
    /// The forces in file order (ExternalForces and PrescribedForces).
    pub forces: Vec<AppliedExternalForce>,
    /// First and last time of the data file and of the PrescribedForces' samples
    /// (infinite when there are none: constant functions only).
    pub time_span: [f64; 2],
    /// What the data file's reader reported (a row count that disagrees, repeated times).
    pub warnings: Vec<crate::io::FileWarning>,
}

impl ExternalLoadSet {
    /// Reads an ExternalLoads `.xml` and its `datafile` (relative to the `.xml`), and resolves
    /// them against `model`.
    pub fn read(model: &Model, path: &Path) -> crate::Result<ExternalLoadSet> {
        let loads = ExternalLoads::read(path)?;
        // Body names first: an error in the .xml is reported before the data file is read.
        loads.bodies(model)?;
        loads.prescribed_bodies(model)?;
        let Some(datafile) = loads.datafile.clone() else {
            if let Some(first) = loads.forces.first() {
                return Err(Error::Model {
                    file: loads.source.clone(),
                    line: first.line,
                    element: format!("ExternalForce \"{}\"", first.name),
                    message: "the ExternalLoads file names no <datafile>: the force's columns \
                              cannot be found"
                        .into(),
                });
            }
            return Self::build(model, &loads, None);
        };
        let table = Table::read(&datafile)?;
        Self::new(model, &loads, &table, &datafile.display().to_string())
    }

    /// Resolves `loads` against `model` and the data `table` (read from `data_source`, named
    /// in errors): body names, the three columns of every identifier, and the functions of
    /// time OpenSim would build.
    pub fn new(
        model: &Model,
        loads: &ExternalLoads,
        table: &Table,
        data_source: &str,
    ) -> crate::Result<ExternalLoadSet> {
        Self::build(model, loads, Some((table, data_source)))
    }

    /// [`ExternalLoadSet::new`], with the data table optional (a file of PrescribedForces
    /// only needs none).
    fn build(
        model: &Model,
        loads: &ExternalLoads,
        data: Option<(&Table, &str)>,
    ) -> crate::Result<ExternalLoadSet> {
        let mut set = match data {
            Some((table, data_source)) => Self::from_data(model, loads, table, data_source)?,
            None => ExternalLoadSet {
                source: loads.source.clone(),
                data_source: loads.source.clone(),
                forces: Vec::new(),
                time_span: [f64::INFINITY, f64::NEG_INFINITY],
                warnings: Vec::new(),
            },
        };
        let mut lines: Vec<u32> = loads.forces.iter().map(|f| f.line).collect();
        for (p, body) in loads.prescribed.iter().zip(loads.prescribed_bodies(model)?) {
            let frame = |global: bool| if global { 0 } else { body };
            set.forces.push(AppliedExternalForce {
                name: p.name.clone(),
                applied_to_body: body,
                force_expressed_in_body: frame(p.force_is_global),
                point_expressed_in_body: frame(p.point_is_global),
                force: p.force.clone(),
                point: p.point.clone(),
                torque: p.torque.clone(),
                columns: Vec::new(),
            });
            lines.push(p.line);
            if let Some([t0, t1]) = p.time_span {
                set.time_span = [set.time_span[0].min(t0), set.time_span[1].max(t1)];
            }
        }
        if set.time_span[0] > set.time_span[1] {
            set.time_span = [f64::NEG_INFINITY, f64::INFINITY];
        }
        // File order: ExternalForces and PrescribedForces may be interleaved.
        let mut order: Vec<usize> = (0..set.forces.len()).collect();
        order.sort_by_key(|&i| lines[i]);
        let mut forces: Vec<Option<AppliedExternalForce>> = std::mem::take(&mut set.forces)
            .into_iter()
            .map(Some)
            .collect();
        set.forces = order.iter().filter_map(|&i| forces[i].take()).collect();
        Ok(set)
    }

    /// The ExternalForces of `loads`, resolved against the data `table`.
    fn from_data(
        model: &Model,
        loads: &ExternalLoads,
        table: &Table,
        data_source: &str,
    ) -> crate::Result<ExternalLoadSet> {
        let bodies = loads.bodies(model)?;
        let n = table.n_rows();
        let locator = table.locator(data_source);
        let err = |element: String, message: String| locator.labels(element, message);
        if n == 0 {
            return Err(err("table".into(), "no rows".into()));
        }
        let mut forces = Vec::with_capacity(loads.forces.len());
        for (f, b) in loads.forces.iter().zip(bodies) {
            let xml_err = |message: String| Error::Model {
                file: loads.source.clone(),
                line: f.line,
                element: format!("ExternalForce \"{}\"", f.name),
                message,
            };
            if f.force_identifier.is_none() && f.torque_identifier.is_none() {
                return Err(xml_err("no force or torque identified".into()));
            }
            if f.force_identifier.is_none() && f.point_identifier.is_some() {
                return Err(xml_err("a point is specified for no applied force".into()));
            }
            let mut columns = Vec::new();
            let mut functions =
                |identifier: &Option<String>, what: &str| -> crate::Result<Option<[Function; 3]>> {
                    let Some(id) = identifier else {
                        return Ok(None);
                    };
                    let found: Vec<usize> = (0..table.n_columns())
                        .filter(|&c| table.labels[c].starts_with(id.as_str()))
                        .collect();
                    if found.len() != 3 {
                        let listed = found
                            .iter()
                            .map(|&c| format!("`{}`", table.labels[c]))
                            .collect::<Vec<_>>()
                            .join(", ");
                        return Err(err(
                            format!("column \"{id}*\""),
                            format!(
                                "ExternalForce \"{}\" ({}, line {}): {what}_identifier `{id}` must \
                             match exactly 3 columns (labels starting with it), found {}{}",
                                f.name,
                                loads.source,
                                f.line,
                                found.len(),
                                if listed.is_empty() {
                                    String::new()
                                } else {
                                    format!(": {listed}")
                                }
                            ),
                        ));
                    }
                    let mut make = |c: usize| -> crate::Result<Function> {
                        columns.push(table.labels[c].clone());
                        let y = table.column_at(c).unwrap_or_default();
                        if let Some(r) = y
                            .iter()
                            .position(|v| !(v.abs() <= MAX_EXTERNAL_LOAD_MAGNITUDE))
                        {
                            let unit = match what {
                                "force" => "N",
                                "point" => "m",
                                _ => "N·m",
                            };
                            return Err(locator.row(
                            r,
                            format!("column \"{}\"", table.labels[c]),
                            format!(
                                "the {what} value {} is beyond ±{MAX_EXTERNAL_LOAD_MAGNITUDE:e} \
                                     {unit}, which no external load on a body reaches: a typing \
                                     or unit error (ExternalForce \"{}\" of {}{})",
                                short_number(y[r]),
                                f.name,
                                loads.source,
                                // (a force built from a C3D's plates has no line)
                                if f.line > 0 {
                                    format!(", line {}", f.line)
                                } else {
                                    String::new()
                                }
                            ),
                        ));
                        }
                        time_function(&table.time, y)
                            .map_err(|m| err(format!("column \"{}\"", table.labels[c]), m))
                    };
                    Ok(Some([make(found[0])?, make(found[1])?, make(found[2])?]))
                };
            let force = functions(&f.force_identifier, "force")?;
            let point = functions(&f.point_identifier, "point")?;
            let torque = functions(&f.torque_identifier, "torque")?;
            forces.push(AppliedExternalForce {
                name: f.name.clone(),
                applied_to_body: b[0],
                force_expressed_in_body: b[1],
                point_expressed_in_body: b[2],
                force,
                point,
                torque,
                columns,
            });
        }
        Ok(ExternalLoadSet {
            source: loads.source.clone(),
            data_source: data_source.to_string(),
            forces,
            time_span: [table.time[0], table.time[n - 1]],
            warnings: table.warnings.clone(),
        })
    }

    /// The wrench of force `i` at time `t`, in ground, with the model's pose in `data`
    /// (forward kinematics computed for the current q).
    pub fn wrench(&self, data: &Data, i: usize, t: f64) -> GroundWrench {
        let f = &self.forces[i];
        let eval =
            |fs: &[Function; 3]| Vec3::new(fs[0].eval1(t).0, fs[1].eval1(t).0, fs[2].eval1(t).0);
        let (rot_f, _) = data.body_pose(f.force_expressed_in_body);
        let force_in_ground = f
            .force
            .as_ref()
            .map_or(Vec3::zeros(), |fs| rot_f * eval(fs));
        let point_in_ground = match &f.point {
            Some(ps) => data.point_position(f.point_expressed_in_body, &eval(ps)),
            None => data.body_pose(f.applied_to_body).1,
        };
        let torque_in_ground = f
            .torque
            .as_ref()
            .map_or(Vec3::zeros(), |ts| rot_f * eval(ts));
        GroundWrench {
            body: f.applied_to_body,
            force_in_ground,
            point_in_ground,
            torque_in_ground,
        }
    }

    /// The labels OpenSim's force reporter gives the values of [`ExternalLoadSet::record`]:
    /// per force `<applied_to_body>_<name>_` followed by `Fx Fy Fz` (with a force), `px py pz`
    /// (with a point) and `Tx Ty Tz` (with a torque).
    pub fn record_labels(&self, model: &Model) -> Vec<String> {
        let mut labels = Vec::new();
        for f in &self.forces {
            let prefix = format!("{}_{}_", model.bodies[f.applied_to_body].name, f.name);
            let mut push = |present: bool, names: [&str; 3]| {
                if present {
                    labels.extend(names.iter().map(|n| format!("{prefix}{n}")));
                }
            };
            push(f.force.is_some(), ["Fx", "Fy", "Fz"]);
            push(f.force.is_some() && f.point.is_some(), ["px", "py", "pz"]);
            push(f.torque.is_some(), ["Tx", "Ty", "Tz"]);
        }
        labels
    }

    /// Appends to `out` the values OpenSim's force reporter records for every force at time
    /// `t` (labels from [`ExternalLoadSet::record_labels`]): the force and the torque in
    /// ground, the point in the frame of the body the force is applied to.
    pub fn record(&self, data: &Data, t: f64, out: &mut Vec<f64>) {
        for (i, f) in self.forces.iter().enumerate() {
            let w = self.wrench(data, i, t);
            if f.force.is_some() {
                out.extend(w.force_in_ground.iter());
                if f.point.is_some() {
                    let (rot, origin) = data.body_pose(f.applied_to_body);
                    out.extend((rot.transpose() * (w.point_in_ground - origin)).iter());
                }
            }
            if f.torque.is_some() {
                out.extend(w.torque_in_ground.iter());
            }
        }
    }

    /// Adds to `out` (length `model.nq()`) the generalized forces Q = Σ Jᵀ w of all forces at
    /// time `t`, for the pose in `data` (forward kinematics computed for the current q). They
    /// enter the equations of motion as M q̈ + bias = τ + Q. Allocates nothing.
    pub fn add_generalized_forces(
        &self,
        model: &Model,
        data: &Data,
        t: f64,
        out: &mut [f64],
    ) -> crate::Result<()> {
        for i in 0..self.forces.len() {
            let w = self.wrench(data, i, t);
            dynamics::add_body_wrench(
                model,
                data,
                w.body,
                &w.point_in_ground,
                &w.force_in_ground,
                &w.torque_in_ground,
                out,
            )?;
        }
        Ok(())
    }
}

/// OpenSim's choice of function through a data column (ExternalForce::extendConnectToModel):
/// constant for 1 sample, piecewise linear for 2–3, natural cubic spline otherwise.
fn time_function(time: &[f64], y: Vec<f64>) -> Result<Function, String> {
    Ok(match time.len() {
        0 => return Err("no rows".into()),
        1 => Function::Constant(y[0]),
        2 | 3 => Function::PiecewiseLinear(PiecewiseLinear::new(time.to_vec(), y)?),
        _ => Function::GcvSpline(NaturalSpline::interpolating(2, time.to_vec(), y)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(rows: usize) -> Table {
        let labels: Vec<String> = [
            "f_vx", "f_vy", "f_vz", "f_px", "f_py", "f_pz", "t_x", "t_y", "t_z",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let time: Vec<f64> = (0..rows).map(|i| i as f64 * 0.1).collect();
        let mut values = Vec::new();
        for (r, &t) in time.iter().enumerate() {
            let _ = r;
            values.extend_from_slice(&[1.0 + t, 2.0 * t * t, -3.0, 0.1, 0.0, 0.2 * t, 0.0, t, 0.5]);
        }
        Table::new("grf", labels, time, values).unwrap()
    }

    fn loads(body: &str, torque: &str) -> ExternalLoads {
        let xml = format!(
            r#"<OpenSimDocument Version="40000"><ExternalLoads name="x"><objects>
            <ExternalForce name="f"><applied_to_body>{body}</applied_to_body>
            <force_expressed_in_body>ground</force_expressed_in_body>
            <point_expressed_in_body>ground</point_expressed_in_body>
            <force_identifier>f_v</force_identifier><point_identifier>f_p</point_identifier>
            <torque_identifier>{torque}</torque_identifier></ExternalForce>
            </objects><datafile>grf.mot</datafile></ExternalLoads></OpenSimDocument>"#
        );
        ExternalLoads::parse(&xml, "loads.xml").unwrap()
    }

    #[test]
    fn interpolation_follows_opensim_by_sample_count() {
        let model = Model::demo();
        let body = model.bodies[1].name.clone();
        let mut data = Data::new(&model);
        dynamics::forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
        for (rows, kind) in [
            (1, "Constant"),
            (2, "PiecewiseLinearFunction"),
            (3, "PiecewiseLinearFunction"),
            (4, "GCVSpline"),
        ] {
            let set =
                ExternalLoadSet::new(&model, &loads(&body, "t_"), &table(rows), "grf.mot").unwrap();
            let f = &set.forces[0];
            assert_eq!(
                f.force.as_ref().unwrap()[0].kind_name(),
                kind,
                "{rows} rows"
            );
            assert_eq!(f.columns.len(), 9);
        }
        // With 2 rows: linear, extrapolated with the end slope (f_vx = 1 + t).
        let set = ExternalLoadSet::new(&model, &loads(&body, "t_"), &table(2), "grf.mot").unwrap();
        let w = set.wrench(&data, 0, 0.35);
        assert!((w.force_in_ground.x - 1.35).abs() < 1e-12);
        assert!((w.torque_in_ground - Vec3::new(0.0, 0.35, 0.5)).norm() < 1e-12);
    }

    #[test]
    fn identifiers_must_match_exactly_three_columns() {
        let model = Model::demo();
        let body = model.bodies[1].name.clone();
        let e = ExternalLoadSet::new(&model, &loads(&body, "t_q"), &table(5), "grf.mot")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("grf.mot") && e.contains("t_q") && e.contains("found 0"),
            "{e}"
        );
        // `f_` matches six columns.
        let e = ExternalLoadSet::new(&model, &loads(&body, "f_"), &table(5), "grf.mot")
            .unwrap_err()
            .to_string();
        assert!(e.contains("found 6") && e.contains("`f_vx`"), "{e}");
    }

    #[test]
    fn generalized_forces_equal_the_wrench_through_the_jacobian() {
        // A pure force at the body origin on the demo model must produce Jᵀ f.
        let model = Model::demo();
        let b = model.bodies.len() - 1;
        let body = model.bodies[b].name.clone();
        let mut data = Data::new(&model);
        let q = model.default_q();
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        let set = ExternalLoadSet::new(&model, &loads(&body, "t_"), &table(6), "grf.mot").unwrap();
        let mut out = vec![0.0; model.nq()];
        set.add_generalized_forces(&model, &data, 0.25, &mut out)
            .unwrap();
        let w = set.wrench(&data, 0, 0.25);
        let mut expect = vec![0.0; model.nq()];
        dynamics::add_body_wrench(
            &model,
            &data,
            b,
            &w.point_in_ground,
            &w.force_in_ground,
            &w.torque_in_ground,
            &mut expect,
        )
        .unwrap();
        assert_eq!(out, expect);
        // The spline interpolates the samples: f_vy = 2 t² at t = 0.3.
        let w3 = set.wrench(&data, 0, 0.3);
        assert!((w3.force_in_ground.y - 0.18).abs() < 1e-12);
    }
}
