//! The page of one clip: a header, then one section per figure (joint angles, joint torques,
//! ground reactions and centres of pressure, contact timeline, muscle activations and the
//! reserves' share, IK error per marker), each written by its own stage.

use super::{Series, escape, figure, heat_map, line_chart, page};
use crate::augment::output::ClipRecord;
use crate::dynamics::{self, Data};
use crate::evaluate::ClipMetrics;
use crate::loss::tensor_file::TensorFrames;
use crate::model::{Model, MotionType};
use crate::motion::npy::read_npz_as_f64;
use crate::muscle::MuscleSet;
use crate::muscle::path::{PathData, compute_paths};
use crate::solve::contact::ContactSet;
use std::fmt::Write as _;
use std::path::Path;

/// Most lines in one chart (the largest by range or peak).
const MOST_LINES: usize = 8;
/// Most columns of a heat map (frames are averaged into bins beyond it).
const MOST_COLUMNS: usize = 300;

/// The HTML page of the clip `name` in the tensor file `path` (read for `model`), with a
/// `reference` clip's file, the clip's `metrics` and its augmentation `record` when given.
pub fn clip_page(
    model: &Model,
    name: &str,
    path: &Path,
    reference: Option<&Path>,
    metrics: Option<&ClipMetrics>,
    record: Option<&ClipRecord>,
) -> crate::Result<String> {
    let clip = Clip::read(model, path, reference)?;
    let mut body = header(&clip, name, path, metrics, record);
    clip.joint_angles(&mut body)?;
    clip.joint_torques(&mut body)?;
    clip.ground_reactions(&mut body)?;
    clip.contact_timeline(&mut body)?;
    clip.activations_and_reserves(&mut body)?;
    clip.ik_marker_error(&mut body, record)?;
    Ok(page(name, &body))
}

/// What the page's sections read: the clip's file (its frames and the arrays only the plots
/// need), a reference clip's frames, the time axis and the model's contact set.
struct Clip<'a> {
    model: &'a Model,
    arrays: Vec<(String, ndarray::ArrayD<f64>)>,
    frames: TensorFrames,
    reference: Option<TensorFrames>,
    /// Frames T (≥ 2).
    t_count: usize,
    /// The frames' times (s), or their indices when the file has none.
    time: Vec<f64>,
    /// (first, last) of `time`.
    span: (f64, f64),
    /// Independent coordinates n and their names.
    n: usize,
    names: Vec<&'a str>,
    set: ContactSet,
    /// The independent coordinates outside the floating base.
    joints: Vec<usize>,
}

impl<'a> Clip<'a> {
    /// Reads the file once, and a reference clip's when given; refuses fewer than 2 frames.
    fn read(model: &'a Model, path: &Path, reference: Option<&Path>) -> crate::Result<Self> {
        let arrays = read_npz_as_f64(path)?;
        let frames = TensorFrames::from_arrays(&arrays, model, &path.display().to_string())?;
        let reference = match reference {
            Some(p) => Some(TensorFrames::read(p, model)?),
            None => None,
        };
        let t_count = frames.frames;
        if t_count < 2 {
            return Err(crate::Error::invalid(
                "clip",
                format!("{}: {t_count} frame(s); a page needs ≥ 2", path.display()),
            ));
        }
        let time: Vec<f64> = if frames.time.len() == t_count {
            frames.time.clone()
        } else {
            (0..t_count).map(|f| f as f64).collect()
        };
        let span = (time[0], time[t_count - 1]);
        let n = model.nq();
        let set = crate::augment::chain::contact_set(model)?;
        let joints: Vec<usize> = (0..n).filter(|j| !set.floating_base.contains(j)).collect();
        Ok(Clip {
            model,
            arrays,
            frames,
            reference,
            t_count,
            time,
            span,
            n,
            names: model.q_names(),
            set,
            joints,
        })
    }

    /// Joint angles: the rotational joint coordinates with the largest range of motion.
    fn joint_angles(&self, body: &mut String) -> crate::Result<()> {
        let (model, n) = (self.model, self.n);
        let rotational: Vec<usize> = self
            .joints
            .iter()
            .copied()
            .filter(|&j| {
                model.coordinates[model.reduction.independent[j]].motion_type
                    == MotionType::Rotational
            })
            .collect();
        let spread = |v: &[f64]| {
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            hi - lo
        };
        let scores: Vec<(usize, f64)> = rotational
            .iter()
            .map(|&j| (j, spread(&column(&self.frames.q, n, j))))
            .collect();
        let series: Vec<Series> = largest(&scores, MOST_LINES)
            .into_iter()
            .enumerate()
            .map(|(i, j)| Series {
                name: self.names[j].to_string(),
                values: column(&self.frames.q, n, j)
                    .iter()
                    .map(|v| v.to_degrees())
                    .collect(),
                dashed: false,
                color: i,
            })
            .collect();
        let svg = line_chart("Joint angles", "angle (°)", &self.time, &series, 300)?;
        figure(
            body,
            "joint_angles",
            &svg,
            "The joint coordinates with the largest range of motion.",
        );
        Ok(())
    }

    /// Joint torques: the joint coordinates with the largest peaks, the reference's dashed.
    fn joint_torques(&self, body: &mut String) -> crate::Result<()> {
        let n = self.n;
        let scores: Vec<(usize, f64)> = self
            .joints
            .iter()
            .map(|&j| {
                (
                    j,
                    column(&self.frames.tau, n, j)
                        .iter()
                        .fold(0.0, |m: f64, v| m.max(v.abs())),
                )
            })
            .collect();
        let mut series = Vec::new();
        for (i, j) in largest(&scores, MOST_LINES).into_iter().enumerate() {
            series.push(Series {
                name: self.names[j].to_string(),
                values: column(&self.frames.tau, n, j),
                dashed: false,
                color: i,
            });
            if let Some(r) = &self.reference {
                series.push(Series {
                    name: format!("{} (reference)", self.names[j]),
                    values: column(&r.tau, n, j),
                    dashed: true,
                    color: i,
                });
            }
        }
        let svg = line_chart(
            "Joint torques",
            "moment (N·m) / force (N)",
            &self.time,
            &series,
            300,
        )?;
        figure(
            body,
            "joint_torques",
            &svg,
            "Net generalized forces of the joint coordinates with the largest peaks; a reference clip's dashed.",
        );
        Ok(())
    }

    /// Vertical ground reaction per contact group (the reference's dashed), then the centres
    /// of pressure when the file has them; nothing when the file has no forces for the groups.
    fn ground_reactions(&self, body: &mut String) -> crate::Result<()> {
        let (frames, t_count) = (&self.frames, self.t_count);
        let groups = self.set.groups();
        let g = groups.len();
        let cop = extra_array(&self.arrays, "cop");
        if frames.groups != g || frames.grf.is_empty() {
            return Ok(());
        }
        let up = |grf: &[f64], k: usize, axis: usize| -> Vec<f64> {
            (0..t_count).map(|f| grf[3 * (f * g + k) + axis]).collect()
        };
        let mut series = Vec::new();
        for (k, group) in groups.iter().enumerate() {
            series.push(Series {
                name: format!("{group} vertical"),
                values: up(&frames.grf, k, 1),
                dashed: false,
                color: k,
            });
            if let Some(r) = self
                .reference
                .as_ref()
                .filter(|r| r.groups == g && !r.grf.is_empty())
            {
                series.push(Series {
                    name: format!("{group} vertical (reference)"),
                    values: up(&r.grf, k, 1),
                    dashed: true,
                    color: k,
                });
            }
        }
        let svg = line_chart(
            "Ground reaction forces",
            "force (N)",
            &self.time,
            &series,
            300,
        )?;
        figure(
            body,
            "ground_reaction",
            &svg,
            "Vertical ground reaction force per contact group (estimate, or the measured loads); a reference clip's dashed.",
        );
        if let Some((shape, values)) = &cop
            && shape.len() == 3
            && shape[1] == g
        {
            self.centres_of_pressure(body, groups, values)?;
        }
        Ok(())
    }

    /// Forward (x) position of each group's centre of pressure (`cop`, T × G × 3) while the
    /// group carries more than the plate threshold.
    fn centres_of_pressure(
        &self,
        body: &mut String,
        groups: &[String],
        cop: &[f64],
    ) -> crate::Result<()> {
        let (frames, g) = (&self.frames, groups.len());
        let series: Vec<Series> = groups
            .iter()
            .enumerate()
            .map(|(k, group)| Series {
                name: format!("{group} x"),
                values: (0..self.t_count)
                    .map(|f| {
                        if frames.grf[3 * (f * g + k) + 1] > crate::augment::chain::PLATE_THRESHOLD
                        {
                            cop[3 * (f * g + k)]
                        } else {
                            f64::NAN
                        }
                    })
                    .collect(),
                dashed: false,
                color: k,
            })
            .collect();
        let svg = line_chart("Centre of pressure", "x (m)", &self.time, &series, 260)?;
        figure(
            body,
            "centre_of_pressure",
            &svg,
            "Forward (x) position of each group's centre of pressure while it carries more than 20 N.",
        );
        Ok(())
    }

    /// The contact factor of each contact sphere over time, when the file has them.
    fn contact_timeline(&self, body: &mut String) -> crate::Result<()> {
        let Some((shape, state)) = extra_array(&self.arrays, "contact_state") else {
            return Ok(());
        };
        if !(shape.len() == 2 && shape[1] == self.set.points.len()) {
            return Ok(());
        }
        let p = shape[1];
        let (cols, binned) = bin_columns(&state, self.t_count, p);
        let labels: Vec<(usize, String)> = self
            .set
            .points
            .iter()
            .enumerate()
            .map(|(i, c)| (i, c.name.clone()))
            .collect();
        let svg = heat_map(
            "Contact timeline",
            self.span,
            &binned,
            p,
            cols,
            1.0,
            &labels,
            60 + 16 * p as u32,
        )?;
        figure(
            body,
            "contact_timeline",
            &svg,
            "Contact factor of each contact sphere over time (dark: in contact).",
        );
        Ok(())
    }

    /// The activations as a heat map, muscles grouped by region, and the reserves' share
    /// over time when the file has muscle forces; nothing without activations.
    fn activations_and_reserves(&self, body: &mut String) -> crate::Result<()> {
        let model = self.model;
        let muscles = MuscleSet::new(model)?;
        let m = muscles.muscles.len();
        if !(m > 0 && self.frames.muscle_act.len() == self.t_count * m) {
            return Ok(());
        }
        let mut data = Data::new(model);
        let mut paths = PathData::new(model, &muscles.paths);
        dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
        compute_paths(model, &data, &muscles.paths, &mut paths)?;
        let (order, labels) = self.muscles_by_region(&paths, m);
        self.activations(body, &order, &labels)?;
        if self.frames.muscle_force.len() == self.t_count * m {
            self.reserve_share(body, &muscles, &mut data, &mut paths)?;
        }
        Ok(())
    }

    /// The muscles in heat-map row order: by region (the coordinate each moves most at the
    /// default pose, whose moment arms `paths` holds, sides merged), regions in the order of
    /// their first coordinate; with the first row of each region and its name.
    fn muscles_by_region(
        &self,
        paths: &PathData,
        m: usize,
    ) -> (Vec<(String, usize, usize)>, Vec<(usize, String)>) {
        let region_of = |k: usize| -> (usize, String) {
            let j = (0..self.n)
                .max_by(|a, b| {
                    paths.moment_arms[(*a, k)]
                        .abs()
                        .total_cmp(&paths.moment_arms[(*b, k)].abs())
                })
                .unwrap_or(0);
            let name = self.names[j]
                .trim_end_matches("_r")
                .trim_end_matches("_l")
                .to_string();
            (j, name)
        };
        let mut order: Vec<(String, usize, usize)> = (0..m)
            .map(|k| {
                let (j, name) = region_of(k);
                (name, j, k)
            })
            .collect();
        let first: std::collections::HashMap<String, usize> =
            order
                .iter()
                .fold(Default::default(), |mut h, (name, j, _)| {
                    let e = h.entry(name.clone()).or_insert(*j);
                    *e = (*e).min(*j);
                    h
                });
        order.sort_by(|a, b| {
            first[&a.0]
                .cmp(&first[&b.0])
                .then(a.0.cmp(&b.0))
                .then(a.2.cmp(&b.2))
        });
        let mut labels: Vec<(usize, String)> = Vec::new();
        for (row, (region, _, _)) in order.iter().enumerate() {
            if labels.last().is_none_or(|(_, r)| r != region) {
                labels.push((row, region.clone()));
            }
        }
        (order, labels)
    }

    /// The activation of every muscle (rows in `order`, `labels` at the regions' first rows)
    /// over time.
    fn activations(
        &self,
        body: &mut String,
        order: &[(String, usize, usize)],
        labels: &[(usize, String)],
    ) -> crate::Result<()> {
        let (t_count, m) = (self.t_count, order.len());
        let mut rows = vec![0.0; m * t_count];
        for (row, (_, _, k)) in order.iter().enumerate() {
            for f in 0..t_count {
                rows[row * t_count + f] = self.frames.muscle_act[f * m + k];
            }
        }
        // row-major rows × frames → binned columns
        let mut transposed = vec![0.0; t_count * m];
        for r in 0..m {
            for f in 0..t_count {
                transposed[f * m + r] = rows[r * t_count + f];
            }
        }
        let (cols, binned) = bin_columns(&transposed, t_count, m);
        let svg = heat_map(
            "Muscle activations",
            self.span,
            &binned,
            m,
            cols,
            1.0,
            labels,
            520,
        )?;
        figure(
            body,
            "activations",
            &svg,
            "Activation of every muscle (rows, grouped by the joint each moves most) over time (dark: 1).",
        );
        Ok(())
    }

    /// Per frame, Σ|τ − R F| / Σ|τ| over the joint coordinates: what no muscle carried.
    fn reserve_share(
        &self,
        body: &mut String,
        muscles: &MuscleSet,
        data: &mut Data,
        paths: &mut PathData,
    ) -> crate::Result<()> {
        let (model, frames, n) = (self.model, &self.frames, self.n);
        let m = muscles.muscles.len();
        let mut share = Vec::with_capacity(self.t_count);
        for f in 0..self.t_count {
            dynamics::forward_kinematics(model, data, &frames.q[f * n..(f + 1) * n])?;
            compute_paths(model, data, &muscles.paths, paths)?;
            let (mut reserve, mut total) = (0.0, 0.0);
            for &j in &self.joints {
                let carried: f64 = (0..m)
                    .map(|k| paths.moment_arms[(j, k)] * frames.muscle_force[f * m + k])
                    .sum();
                let tau = frames.tau[f * n + j];
                reserve += (tau - carried).abs();
                total += tau.abs();
            }
            share.push(if total > 0.0 {
                100.0 * reserve / total
            } else {
                0.0
            });
        }
        let series = [Series {
            name: "reserves".into(),
            values: share,
            dashed: false,
            color: 3,
        }];
        let svg = line_chart(
            "Reserve share",
            "share of |joint moments| (%)",
            &self.time,
            &series,
            240,
        )?;
        figure(
            body,
            "reserve_share",
            &svg,
            "Σ|τ − R F| / Σ|τ| over the joint coordinates, per frame: what no muscle carried.",
        );
        Ok(())
    }

    /// IK error per marker: the markers with the largest median error, named by the
    /// augmentation `record` when it names as many.
    fn ik_marker_error(&self, body: &mut String, record: Option<&ClipRecord>) -> crate::Result<()> {
        let Some((shape, error)) = extra_array(&self.arrays, "ik_marker_error") else {
            return Ok(());
        };
        if !(shape.len() == 2 && shape[0] == self.t_count && shape[1] > 0) {
            return Ok(());
        }
        let k = shape[1];
        let labels: Vec<String> = match record.and_then(|r| r.quality.as_ref()) {
            Some(q) if q.ik_markers.len() == k => q.ik_markers.clone(),
            _ => (0..k).map(|i| format!("marker {i}")).collect(),
        };
        let median = |v: &[f64]| {
            let mut f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
            f.sort_by(f64::total_cmp);
            f.get(f.len() / 2).copied().unwrap_or(0.0)
        };
        let scores: Vec<(usize, f64)> =
            (0..k).map(|i| (i, median(&column(&error, k, i)))).collect();
        let series: Vec<Series> = largest(&scores, MOST_LINES)
            .into_iter()
            .enumerate()
            .map(|(c, i)| Series {
                name: labels[i].clone(),
                values: column(&error, k, i).iter().map(|e| 1e3 * e).collect(),
                dashed: false,
                color: c,
            })
            .collect();
        if !series.is_empty() {
            let svg = line_chart(
                "IK error per marker",
                "error (mm)",
                &self.time,
                &series,
                240,
            )?;
            figure(
                body,
                "ik_marker_error",
                &svg,
                "‖model marker − target‖ of inverse kinematics for the markers (or joint \
                 centres) with the largest median error; gaps where the input had no target.",
            );
        }
        Ok(())
    }
}

/// The page's title line, model and file, the metrics table and the IK summary of the
/// augmentation record.
fn header(
    clip: &Clip,
    name: &str,
    path: &Path,
    metrics: Option<&ClipMetrics>,
    record: Option<&ClipRecord>,
) -> String {
    let mut body = format!(
        "<h1>{}</h1>\n<p>model “{}”, file {}</p>\n",
        escape(name),
        escape(&clip.model.name),
        escape(&path.display().to_string())
    );
    if let Some(m) = metrics {
        body.push_str(&metrics_table(m));
    }
    if let Some(r) = record.and_then(|r| r.quality.as_ref()) {
        let _ = writeln!(
            body,
            "<p>Inverse kinematics (augmentation record): median frame RMSE {:.1} mm, largest \
             marker error {:.1} mm, {} frame(s) at a coordinate bound; reserves carry {:.2} % \
             of the joint moments.</p>",
            1e3 * r.ik_rmse_median,
            1e3 * r.ik_error_max,
            r.ik_frames_at_bound,
            100.0 * r.reserve_share
        );
    }
    body
}

/// The `k` indices of `scores` with the largest values (ties by index), in index order.
fn largest(scores: &[(usize, f64)], k: usize) -> Vec<usize> {
    let mut s: Vec<(usize, f64)> = scores.iter().copied().filter(|(_, v)| *v > 0.0).collect();
    s.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut keep: Vec<usize> = s.into_iter().take(k).map(|(i, _)| i).collect();
    keep.sort_unstable();
    keep
}

/// Column `j` of a T × n row-major array.
fn column(a: &[f64], n: usize, j: usize) -> Vec<f64> {
    a.chunks(n).map(|r| r[j]).collect()
}

/// One optional array of `arrays` (shape, values).
fn extra_array(
    arrays: &[(String, ndarray::ArrayD<f64>)],
    name: &str,
) -> Option<(Vec<usize>, Vec<f64>)> {
    arrays
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, a)| (a.shape().to_vec(), a.iter().copied().collect()))
}

/// The metrics as a two-row table.
fn metrics_table(m: &ClipMetrics) -> String {
    let o = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or("–".to_string(), f);
    format!(
        "<table><tr><th>frames</th><th>Skate</th><th>skate speed</th><th>Float</th>\
         <th>Penetrate</th><th>Contact force</th><th>Joint actuation</th><th>Muscle limit</th>\
         <th>EL residual</th></tr><tr><td>{} at {:.1} Hz</td><td>{:.3}</td><td>{:.3} m/s</td>\
         <td>{:.1} mm</td><td>{:.1} mm</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr></table>\n",
        m.frames,
        m.rate_hz,
        m.skate,
        m.skate_speed,
        1e3 * m.float,
        1e3 * m.penetrate,
        o(m.contact_force_error, &|v| format!("{v:.3} BW")),
        o(m.joint_actuation(), &|v| format!("{v:.3} N·m/kg")),
        o(m.muscle_limit(), &|v| format!("{v:.3}")),
        o(m.el_residual, &|v| format!("{v:.1e}")),
    )
}

/// A T × rows array (frame-major) as rows × columns, the frames averaged into at most
/// [`MOST_COLUMNS`] bins.
fn bin_columns(values: &[f64], t_count: usize, rows: usize) -> (usize, Vec<f64>) {
    let cols = t_count.clamp(1, MOST_COLUMNS);
    let mut out = vec![0.0; rows * cols];
    let mut count = vec![0usize; cols];
    for f in 0..t_count {
        let c = f * cols / t_count.max(1);
        count[c] += 1;
        for r in 0..rows {
            out[r * cols + c] += values[f * rows + r];
        }
    }
    for r in 0..rows {
        for c in 0..cols {
            out[r * cols + c] /= count[c].max(1) as f64;
        }
    }
    (cols, out)
}
