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

mod clip;
mod plot;

pub use clip::clip_page;
pub use plot::{PALETTE, Series, WIDTH, heat_map, histogram, line_chart, line_chart_over};

use crate::augment::output::ClipRecord;
use crate::evaluate::{ClipFile, ClipMetrics, SetOptions, SetReport, model_of};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

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
