//! Report pages a person can read: one self-contained HTML file per clip (inline SVG plots,
//! no script, no external resource) and a dataset page with the distributions of the
//! plausibility metrics ([`crate::evaluate`]) and the worst clips linked.
//!
//! A clip page shows, from the clip's tensor file: joint angles, joint torques, the ground
//! reaction forces and centres of pressure (with a reference clip's — measured loads — dashed
//! beside them), the contact timeline of the contact spheres, a muscle-activation heat map
//! (muscles grouped by the joint each moves most at the default pose, frames in time), the
//! share of the joint moments the reserves carry over time, the IK error per marker over time
//! (the tensor file's `ik_marker_error`, named by the clip's augmentation record) and the IK
//! figures of that record when there is one.
//! Every plot is an `<svg>` inside `<figure class="plot" data-plot="…">`.

mod plot;

pub use plot::{PALETTE, Series, WIDTH, heat_map, histogram, line_chart, line_chart_over};

use crate::augment::output::ClipRecord;
use crate::dynamics::{self, Data};
use crate::evaluate::{ClipFile, ClipMetrics, SetOptions, SetReport, model_of};
use crate::loss::tensor_file::TensorFrames;
use crate::model::{Model, MotionType};
use crate::motion::npy::read_npz_as_f64;
use crate::muscle::MuscleSet;
use crate::muscle::path::{PathData, compute_paths};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Most lines in one chart (the largest by range or peak).
const MOST_LINES: usize = 8;
/// Most columns of a heat map (frames are averaged into bins beyond it).
const MOST_COLUMNS: usize = 300;

/// The plots of a page written here: (id, `<svg>…</svg>`) of each
/// `<figure class="plot" data-plot="id">`, in page order.
pub fn figures(html: &str) -> Vec<(String, String)> {
    const MARK: &str = "<figure class=\"plot\" data-plot=\"";
    let mut out = Vec::new();
    let mut rest = html;
    while let Some(i) = rest.find(MARK) {
        rest = &rest[i + MARK.len()..];
        let Some(id_end) = rest.find('"') else { break };
        let id = rest[..id_end].to_string();
        let (Some(start), Some(end)) = (rest.find("<svg"), rest.find("</svg>")) else {
            break;
        };
        if end < start {
            break;
        }
        out.push((id, rest[start..end + 6].to_string()));
        rest = &rest[end + 6..];
    }
    out
}

/// The pixel size (width, height) an `<svg width=… height=…>` declares.
pub fn svg_size(svg: &str) -> Option<(u32, u32)> {
    let attr = |name: &str| -> Option<u32> {
        let i = svg.find(&format!("{name}=\""))? + name.len() + 2;
        svg[i..i + svg[i..].find('"')?].parse().ok()
    };
    Some((attr("width")?, attr("height")?))
}

/// `text` with `&`, `<`, `>` and `"` escaped for HTML.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

const STYLE: &str = "body{font-family:sans-serif;margin:24px;max-width:940px;color:#222}\
table{border-collapse:collapse;margin:8px 0 16px}td,th{border:1px solid #ccc;padding:3px 8px;\
text-align:right;font-size:13px}th{background:#f4f4f4}td:first-child,th:first-child{text-align:left}\
figure{margin:12px 0}figcaption{font-size:12px;color:#555}.pair figure{display:inline-block;\
margin:4px}";

fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\
         <style>{STYLE}</style></head><body>\n{body}</body></html>\n",
        escape(title)
    )
}

fn figure(out: &mut String, id: &str, svg: &str, caption: &str) {
    let _ = writeln!(
        out,
        "<figure class=\"plot\" data-plot=\"{id}\">{svg}<figcaption>{}</figcaption></figure>",
        escape(caption)
    );
}

/// A training run's loss curves as a page: `csv` is a loss log with a header whose first column
/// is the step and whose other columns are losses (as `musculo-learn` writes `loss.csv`; a column
/// named `seconds` is left out). One chart of log₁₀ of every loss column over the steps, columns
/// that are zero throughout omitted. Errors name `source` and the line of a malformed row.
pub fn training_page(title: &str, source: &str, csv: &str) -> crate::Result<String> {
    let bad = |line: usize, m: String| {
        crate::Error::invalid("loss log", format!("{source}: line {line}: {m}"))
    };
    let mut lines = csv.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| bad(1, "empty".into()))?
        .split(',')
        .collect();
    if header.len() < 2 {
        return Err(bad(1, "expected step and at least one loss column".into()));
    }
    let mut steps = Vec::new();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); header.len() - 1];
    for (k, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let values: Vec<f64> = line
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| bad(k + 2, e.to_string()))?;
        if values.len() != header.len() {
            return Err(bad(
                k + 2,
                format!("{} values, the header has {}", values.len(), header.len()),
            ));
        }
        steps.push(values[0]);
        for (c, v) in values[1..].iter().enumerate() {
            columns[c].push(*v);
        }
    }
    let series: Vec<Series> = header[1..]
        .iter()
        .zip(&columns)
        .filter(|(name, values)| **name != "seconds" && values.iter().any(|v| *v != 0.0))
        .enumerate()
        .map(|(i, (name, values))| Series {
            name: name.to_string(),
            values: values
                .iter()
                .map(|v| if *v > 0.0 { v.log10() } else { f64::NAN })
                .collect(),
            dashed: false,
            color: i,
        })
        .collect();
    let svg = line_chart_over("loss", "step", "log₁₀ loss", &steps, &series, 360)?;
    let mut body = format!("<h1>{}</h1>\n", escape(title));
    figure(
        &mut body,
        "loss",
        &svg,
        &format!("{} steps from {source}", steps.len()),
    );
    Ok(page(title, &body))
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
    // the file read once: its frames, and the arrays only the plots need
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
    let names = model.q_names();
    let set = crate::augment::chain::contact_set(model)?;
    let joints: Vec<usize> = (0..n).filter(|j| !set.floating_base.contains(j)).collect();
    let mut body = format!(
        "<h1>{}</h1>\n<p>model “{}”, file {}</p>\n",
        escape(name),
        escape(&model.name),
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
    // joint angles: the rotational joint coordinates with the largest range of motion
    let rotational: Vec<usize> = joints
        .iter()
        .copied()
        .filter(|&j| {
            model.coordinates[model.reduction.independent[j]].motion_type == MotionType::Rotational
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
        .map(|&j| (j, spread(&column(&frames.q, n, j))))
        .collect();
    let series: Vec<Series> = largest(&scores, MOST_LINES)
        .into_iter()
        .enumerate()
        .map(|(i, j)| Series {
            name: names[j].to_string(),
            values: column(&frames.q, n, j)
                .iter()
                .map(|v| v.to_degrees())
                .collect(),
            dashed: false,
            color: i,
        })
        .collect();
    let svg = line_chart("Joint angles", "angle (°)", &time, &series, 300)?;
    figure(
        &mut body,
        "joint_angles",
        &svg,
        "The joint coordinates with the largest range of motion.",
    );
    // joint torques, the reference's dashed
    let scores: Vec<(usize, f64)> = joints
        .iter()
        .map(|&j| {
            (
                j,
                column(&frames.tau, n, j)
                    .iter()
                    .fold(0.0, |m: f64, v| m.max(v.abs())),
            )
        })
        .collect();
    let mut series = Vec::new();
    for (i, j) in largest(&scores, MOST_LINES).into_iter().enumerate() {
        series.push(Series {
            name: names[j].to_string(),
            values: column(&frames.tau, n, j),
            dashed: false,
            color: i,
        });
        if let Some(r) = &reference {
            series.push(Series {
                name: format!("{} (reference)", names[j]),
                values: column(&r.tau, n, j),
                dashed: true,
                color: i,
            });
        }
    }
    let svg = line_chart(
        "Joint torques",
        "moment (N·m) / force (N)",
        &time,
        &series,
        300,
    )?;
    figure(
        &mut body,
        "joint_torques",
        &svg,
        "Net generalized forces of the joint coordinates with the largest peaks; a reference clip's dashed.",
    );
    // ground reactions and centres of pressure per contact group
    let groups = set.groups();
    let g = groups.len();
    let cop = extra_array(&arrays, "cop");
    if frames.groups == g && !frames.grf.is_empty() {
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
            if let Some(r) = reference
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
        let svg = line_chart("Ground reaction forces", "force (N)", &time, &series, 300)?;
        figure(
            &mut body,
            "ground_reaction",
            &svg,
            "Vertical ground reaction force per contact group (estimate, or the measured loads); a reference clip's dashed.",
        );
        if let Some((shape, values)) = &cop
            && shape.len() == 3
            && shape[1] == g
        {
            let series: Vec<Series> = groups
                .iter()
                .enumerate()
                .map(|(k, group)| Series {
                    name: format!("{group} x"),
                    values: (0..t_count)
                        .map(|f| {
                            if frames.grf[3 * (f * g + k) + 1]
                                > crate::augment::chain::PLATE_THRESHOLD
                            {
                                values[3 * (f * g + k)]
                            } else {
                                f64::NAN
                            }
                        })
                        .collect(),
                    dashed: false,
                    color: k,
                })
                .collect();
            let svg = line_chart("Centre of pressure", "x (m)", &time, &series, 260)?;
            figure(
                &mut body,
                "centre_of_pressure",
                &svg,
                "Forward (x) position of each group's centre of pressure while it carries more than 20 N.",
            );
        }
    }
    // contact timeline
    if let Some((shape, state)) = extra_array(&arrays, "contact_state")
        && shape.len() == 2
        && shape[1] == set.points.len()
    {
        let p = shape[1];
        let (cols, binned) = bin_columns(&state, t_count, p);
        let labels: Vec<(usize, String)> = set
            .points
            .iter()
            .enumerate()
            .map(|(i, c)| (i, c.name.clone()))
            .collect();
        let svg = heat_map(
            "Contact timeline",
            span,
            &binned,
            p,
            cols,
            1.0,
            &labels,
            60 + 16 * p as u32,
        )?;
        figure(
            &mut body,
            "contact_timeline",
            &svg,
            "Contact factor of each contact sphere over time (dark: in contact).",
        );
    }
    // activations grouped by region, and the reserves' share over time
    let muscles = MuscleSet::new(model)?;
    let m = muscles.muscles.len();
    if m > 0 && frames.muscle_act.len() == t_count * m {
        let mut data = Data::new(model);
        let mut paths = PathData::new(model, &muscles.paths);
        dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
        compute_paths(model, &data, &muscles.paths, &mut paths)?;
        // region: the coordinate each muscle moves most at the default pose, sides merged
        let region_of = |k: usize| -> (usize, String) {
            let j = (0..n)
                .max_by(|a, b| {
                    paths.moment_arms[(*a, k)]
                        .abs()
                        .total_cmp(&paths.moment_arms[(*b, k)].abs())
                })
                .unwrap_or(0);
            let name = names[j]
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
        let mut rows = vec![0.0; m * t_count];
        let mut labels: Vec<(usize, String)> = Vec::new();
        for (row, (region, _, k)) in order.iter().enumerate() {
            if labels.last().is_none_or(|(_, r)| r != region) {
                labels.push((row, region.clone()));
            }
            for f in 0..t_count {
                rows[row * t_count + f] = frames.muscle_act[f * m + k];
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
            span,
            &binned,
            m,
            cols,
            1.0,
            &labels,
            520,
        )?;
        figure(
            &mut body,
            "activations",
            &svg,
            "Activation of every muscle (rows, grouped by the joint each moves most) over time (dark: 1).",
        );
        if frames.muscle_force.len() == t_count * m {
            let mut share = Vec::with_capacity(t_count);
            for f in 0..t_count {
                dynamics::forward_kinematics(model, &mut data, &frames.q[f * n..(f + 1) * n])?;
                compute_paths(model, &data, &muscles.paths, &mut paths)?;
                let (mut reserve, mut total) = (0.0, 0.0);
                for &j in &joints {
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
                &time,
                &series,
                240,
            )?;
            figure(
                &mut body,
                "reserve_share",
                &svg,
                "Σ|τ − R F| / Σ|τ| over the joint coordinates, per frame: what no muscle carried.",
            );
        }
    }
    // IK error per marker: the markers with the largest median error
    if let Some((shape, error)) = extra_array(&arrays, "ik_marker_error")
        && shape.len() == 2
        && shape[0] == t_count
        && shape[1] > 0
    {
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
            let svg = line_chart("IK error per marker", "error (mm)", &time, &series, 240)?;
            figure(
                &mut body,
                "ik_marker_error",
                &svg,
                "‖model marker − target‖ of inverse kinematics for the markers (or joint \
                 centres) with the largest median error; gaps where the input had no target.",
            );
        }
    }
    Ok(page(name, &body))
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

/// The dataset page of `report`: the set summary, the distribution of each metric over the
/// clips, the failures, and the worst clips — linked to `<clip>.html` where `linked` says
/// there is one.
pub fn dataset_page(
    title: &str,
    report: &SetReport,
    linked: &dyn Fn(&str) -> bool,
) -> crate::Result<String> {
    let columns = report.summary.columns();
    let mut body = format!("<h1>{}</h1>\n<table><tr>", escape(title));
    for (name, _) in &columns {
        let _ = write!(body, "<th>{name}</th>");
    }
    body.push_str("</tr><tr>");
    for (_, value) in &columns {
        let _ = write!(body, "<td>{}</td>", escape(value));
    }
    body.push_str("</tr></table>\n");
    let clips = &report.clips;
    let metric = |f: &dyn Fn(&ClipMetrics) -> Option<f64>| -> Vec<f64> {
        clips.iter().filter_map(f).collect()
    };
    let plots: [(&str, &str, Vec<f64>); 6] = [
        ("skate", "Skate (ratio)", metric(&|c| Some(c.skate))),
        ("float", "Float (mm)", metric(&|c| Some(1e3 * c.float))),
        (
            "penetrate",
            "Penetrate (mm)",
            metric(&|c| Some(1e3 * c.penetrate)),
        ),
        (
            "joint_actuation",
            "Joint actuation (N·m/kg)",
            metric(&|c| c.joint_actuation()),
        ),
        (
            "muscle_limit",
            "Muscle limit",
            metric(&|c| c.muscle_limit()),
        ),
        (
            "el_residual",
            "EL residual (log10)",
            metric(&|c| c.el_residual.map(|r| r.max(1e-16).log10())),
        ),
    ];
    body.push_str("<div class=\"pair\">\n");
    for (id, label, values) in plots {
        if values.is_empty() {
            continue;
        }
        let svg = histogram(label, label, &values, 20)?;
        figure(
            &mut body,
            id,
            &svg,
            &format!("{label} over {} clips", values.len()),
        );
    }
    body.push_str("</div>\n");
    let link = |name: &str| {
        if linked(name) {
            format!("<a href=\"{}.html\">{}</a>", escape(name), escape(name))
        } else {
            escape(name)
        }
    };
    for (heading, key) in [
        (
            "Most skating",
            &(|c: &ClipMetrics| Some(c.skate)) as &dyn Fn(&ClipMetrics) -> Option<f64>,
        ),
        ("Largest Euler–Lagrange residual", &|c: &ClipMetrics| {
            c.el_residual
        }),
        ("Largest joint actuation", &|c: &ClipMetrics| {
            c.joint_actuation()
        }),
        ("Largest muscle limit", &|c: &ClipMetrics| c.muscle_limit()),
    ] {
        let mut worst: Vec<(&str, f64)> = clips
            .iter()
            .filter_map(|c| key(c).map(|v| (c.clip.as_str(), v)))
            .collect();
        worst.sort_by(|a, b| b.1.total_cmp(&a.1));
        if worst.is_empty() {
            continue;
        }
        let _ = write!(
            body,
            "<h2>{heading}</h2><table><tr><th>clip</th><th>value</th></tr>"
        );
        for (name, v) in worst.iter().take(10) {
            let _ = write!(body, "<tr><td>{}</td><td>{v:.3e}</td></tr>", link(name));
        }
        body.push_str("</table>\n");
    }
    if !report.failed.is_empty() {
        body.push_str("<h2>Failed</h2><table><tr><th>clip</th><th>reason</th></tr>");
        for (clip, reason) in &report.failed {
            let _ = write!(
                body,
                "<tr><td>{}</td><td style=\"text-align:left\">{}</td></tr>",
                escape(clip),
                escape(reason)
            );
        }
        body.push_str("</table>\n");
    }
    Ok(page(title, &body))
}

/// The augmentation record of `clip` when its folder holds one (`.musculo/records/`).
fn record_of(clip: &ClipFile) -> Option<ClipRecord> {
    let path = clip.path.to_string_lossy();
    let root = path.strip_suffix(&format!("{}.npz", clip.name))?;
    let root = if root.is_empty() {
        Path::new(".")
    } else {
        Path::new(root)
    };
    crate::augment::output::read_record(root, &clip.name)
        .ok()
        .flatten()
}

/// Writes the report of an evaluated set into `out`: `index.html` (the dataset page of
/// `report`, titled `title`) and, with `pages`, `<clip>.html` for every evaluated tensor
/// file of `clips` (a motion file's figures are on the dataset page only) (in parallel, `progress(done, total)` after each). Each file is written whole or
/// not at all; returns the files written.
pub fn write_report(
    title: &str,
    clips: &[ClipFile],
    report: &SetReport,
    options: &SetOptions,
    out: &Path,
    pages: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> crate::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    if pages {
        let bodies = crate::augment::identity::Bodies::new(options.model.as_deref())?;
        let done = AtomicUsize::new(0);
        let evaluated: Vec<(&ClipFile, &ClipMetrics)> = report
            .clips
            .iter()
            .filter_map(|m| {
                clips
                    .iter()
                    .find(|c| c.name == m.clip && c.format.is_none())
                    .map(|c| (c, m))
            })
            .collect();
        let files: Vec<crate::Result<PathBuf>> = evaluated
            .par_iter()
            .map(|(clip, metrics)| {
                let model = model_of(clip, &bodies)?.model;
                let reference = options
                    .reference
                    .as_ref()
                    .map(|d| d.join(format!("{}.npz", clip.name)));
                let html = clip_page(
                    &model,
                    &clip.name,
                    &clip.path,
                    reference.as_deref(),
                    Some(metrics),
                    record_of(clip).as_ref(),
                )?;
                let path = out.join(format!("{}.html", clip.name));
                if let Some(parent) = path.parent() {
                    std::fs::create_dir_all(parent).map_err(|source| crate::Error::Io {
                        path: parent.to_path_buf(),
                        source,
                    })?;
                }
                crate::motion::npy::write_file_atomic(&path, html.as_bytes())?;
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, evaluated.len());
                Ok(path)
            })
            .collect();
        for f in files {
            written.push(f?);
        }
    }
    std::fs::create_dir_all(out).map_err(|source| crate::Error::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let index = out.join("index.html");
    let paged = |name: &str| pages && clips.iter().any(|c| c.name == name && c.format.is_none());
    crate::motion::npy::write_file_atomic(&index, dataset_page(title, report, &paged)?.as_bytes())?;
    written.push(index);
    Ok(written)
}
