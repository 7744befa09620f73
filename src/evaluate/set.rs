//! A set of tensor files evaluated clip by clip (in parallel), with their references and
//! controls found by clip name, and the set summary.

use super::{
    Capacity, CapacityCurves, ClipMetrics, Control, EvaluateOptions, SetSummary, evaluate_clip,
    summarize,
};
use crate::error::Error;
use crate::loss::tensor_file::TensorFrames;
use crate::model::Model;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// One clip of the set: its name (the path below the folder given, without `.npz`; the file
/// stem for a file given directly) and its file.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipFile {
    pub name: String,
    pub path: PathBuf,
}

/// The clips of `inputs`: `.npz` files as given, and every `.npz` below a folder (hidden
/// entries such as an augmentation's `.musculo/` and the folder's own `stats.npz` left out),
/// sorted by name. An input that does not exist, a file that is not `.npz` or a set without
/// clips is an error; so are two clips of one name.
pub fn collect(inputs: &[PathBuf]) -> crate::Result<Vec<ClipFile>> {
    let mut clips = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let mut stack = vec![input.clone()];
            while let Some(dir) = stack.pop() {
                let entries = std::fs::read_dir(&dir).map_err(|source| Error::Io {
                    path: dir.clone(),
                    source,
                })?;
                for entry in entries {
                    let entry = entry.map_err(|source| Error::Io {
                        path: dir.clone(),
                        source,
                    })?;
                    let path = entry.path();
                    let file_name = entry.file_name().to_string_lossy().into_owned();
                    if file_name.starts_with('.') {
                        continue;
                    }
                    if path.is_dir() {
                        stack.push(path);
                    } else if let Some(stem) = file_name.strip_suffix(".npz") {
                        if dir == *input && stem == "stats" {
                            continue;
                        }
                        let relative = path.strip_prefix(input).unwrap_or(&path);
                        let name = relative
                            .with_extension("")
                            .to_string_lossy()
                            .replace('\\', "/");
                        clips.push(ClipFile { name, path });
                    }
                }
            }
        } else if input.is_file() {
            if input.extension().is_none_or(|e| e != "npz") {
                return Err(Error::invalid(
                    "--input",
                    format!(
                        "{}: not a tensor file (.npz); evaluate reads musculo's tensor format",
                        input.display()
                    ),
                ));
            }
            let name = input
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            clips.push(ClipFile {
                name,
                path: input.clone(),
            });
        } else {
            return Err(Error::invalid(
                "--input",
                format!("{}: no such file or folder", input.display()),
            ));
        }
    }
    clips.sort_by(|a, b| a.name.cmp(&b.name));
    if let Some(w) = clips.windows(2).find(|w| w[0].name == w[1].name) {
        return Err(Error::invalid(
            "--input",
            format!(
                "two clips named \"{}\": {} and {}",
                w[0].name,
                w[0].path.display(),
                w[1].path.display()
            ),
        ));
    }
    if clips.is_empty() {
        return Err(Error::invalid("--input", "no .npz tensor files found"));
    }
    Ok(clips)
}

/// Settings of [`evaluate_set`].
#[derive(Clone, Debug, Default)]
pub struct SetOptions {
    /// The model of every clip; None: `<clip>.osim` beside the clip's file when there is one
    /// (what `augment --opensim-files` writes for a clip scaled to its bone lengths), else
    /// the built-in default model.
    pub model: Option<PathBuf>,
    /// A folder holding `<clip>.npz` references (the same names).
    pub reference: Option<PathBuf>,
    /// A folder holding `<clip>.npz` control files.
    pub control: Option<PathBuf>,
    pub metrics: EvaluateOptions,
}

/// The metrics of every clip that could be evaluated, the reasons of those that could not,
/// and the summary of the evaluated ones.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SetReport {
    pub clips: Vec<ClipMetrics>,
    /// (clip, reason) of each clip that failed.
    pub failed: Vec<(String, String)>,
    pub summary: SetSummary,
}

/// Evaluates `clips` in parallel on the current rayon pool, calling `progress(done, total)`
/// after each. A clip whose file, model, reference or control cannot be read or does not fit
/// is listed in [`SetReport::failed`] with the reason; the others are evaluated.
pub fn evaluate_set(
    clips: &[ClipFile],
    options: &SetOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> crate::Result<SetReport> {
    options.metrics.validate()?;
    let shared = match &options.model {
        Some(p) => Some(Model::from_osim_file(p)?),
        None => None,
    };
    let shared_curves = std::sync::OnceLock::new();
    let default = std::sync::OnceLock::new();
    let done = AtomicUsize::new(0);
    let results: Vec<Result<ClipMetrics, (String, String)>> = clips
        .par_iter()
        .map(|clip| {
            let result = evaluate_file(clip, options, shared.as_ref(), &default, &shared_curves)
                .map_err(|e| (clip.name.clone(), e.to_string()));
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, clips.len());
            result
        })
        .collect();
    let mut report = SetReport::default();
    for r in results {
        match r {
            Ok(m) => report.clips.push(m),
            Err(f) => report.failed.push(f),
        }
    }
    report.summary = summarize(&report.clips);
    Ok(report)
}

/// The model of `clip`: `model` when given, else `<clip>.osim` beside the clip's file when
/// there is one, else the built-in default model.
pub fn model_of(clip: &ClipFile, model: Option<&Path>) -> crate::Result<Model> {
    let beside = clip.path.with_extension("osim");
    match model {
        Some(p) => Model::from_osim_file(p),
        None if beside.is_file() => Model::from_osim_file(&beside),
        None => Ok(Model::default_fullbody()),
    }
}

/// The joint strength curves of `model` (skipping its floating base).
fn curves_of(model: &Model) -> crate::Result<CapacityCurves> {
    let set = crate::augment::chain::contact_set(model)?;
    CapacityCurves::new(model, &set.floating_base)
}

fn evaluate_file(
    clip: &ClipFile,
    options: &SetOptions,
    shared: Option<&Model>,
    default: &std::sync::OnceLock<Model>,
    shared_curves: &std::sync::OnceLock<Result<CapacityCurves, String>>,
) -> crate::Result<ClipMetrics> {
    let beside = clip.path.with_extension("osim");
    let own;
    let (model, model_is_shared) = match shared {
        Some(m) => (m, true),
        None if beside.is_file() => {
            own = Model::from_osim_file(&beside)?;
            (&own, false)
        }
        None => (default.get_or_init(Model::default_fullbody), true),
    };
    // one set of curves for the model every clip shares; a clip's own model gets its own
    let own_curves;
    let capacity = if options.metrics.muscles_per_frame {
        Capacity::PerFrame
    } else if model_is_shared {
        match shared_curves.get_or_init(|| curves_of(model).map_err(|e| e.to_string())) {
            Ok(c) => Capacity::Curves(c),
            Err(e) => return Err(Error::invalid("model", e.clone())),
        }
    } else {
        own_curves = curves_of(model)?;
        Capacity::Curves(&own_curves)
    };
    let frames = TensorFrames::read(&clip.path, model)?;
    let find = |dir: &Path, what: &'static str| -> crate::Result<PathBuf> {
        let p = dir.join(format!("{}.npz", clip.name));
        if p.is_file() {
            Ok(p)
        } else {
            Err(Error::invalid(
                what,
                format!("{}: no {what} for clip \"{}\"", p.display(), clip.name),
            ))
        }
    };
    let reference = match &options.reference {
        Some(dir) => Some(TensorFrames::read(&find(dir, "reference")?, model)?),
        None => None,
    };
    let control = match &options.control {
        Some(dir) => Some(Control::read(&find(dir, "control")?, model)?),
        None => None,
    };
    evaluate_clip(
        model,
        &clip.name,
        &frames,
        reference.as_ref(),
        control.as_ref(),
        capacity,
        &options.metrics,
    )
}

/// The CSV columns of [`SetReport::to_csv`].
const CSV_COLUMNS: &str = "clip,frames,rate_hz,body_mass,support_fraction,skate,skate_speed,\
float,float_max,penetrate,penetrate_max,contact_force,joint_actuation,muscle_limit,el_residual,\
trajectory,location_failure,trajectory_error,actuation_excess,actuation_over,actuation_peak,\
actuation_error,activation_excess,reserve_share,layout_fit_error";

impl SetReport {
    /// One row per evaluated clip, then a row `(set)` with the summary in FlexMotion's columns
    /// (`trajectory`: 1/0 per clip for a failed/followed control, the failed share for the
    /// set); empty cells where a metric was not computed.
    pub fn to_csv(&self) -> String {
        let o = |v: Option<f64>| v.map(|x| format!("{x:e}")).unwrap_or_default();
        let mut s = String::from(CSV_COLUMNS);
        s.push('\n');
        for c in &self.clips {
            let cells = [
                csv_name(&c.clip),
                c.frames.to_string(),
                format!("{}", c.rate_hz),
                format!("{}", c.body_mass),
                format!("{:e}", c.support_fraction),
                format!("{:e}", c.skate),
                format!("{:e}", c.skate_speed),
                format!("{:e}", c.float),
                format!("{:e}", c.float_max),
                format!("{:e}", c.penetrate),
                format!("{:e}", c.penetrate_max),
                o(c.contact_force_error),
                o(c.joint_actuation()),
                o(c.muscle_limit()),
                o(c.el_residual),
                o(c.trajectory_failed.map(|f| if f { 1.0 } else { 0.0 })),
                o(c.location_failure),
                o(c.trajectory_error),
                o(c.actuation_excess),
                o(c.actuation_over),
                o(c.actuation_peak),
                o(c.actuation_error),
                o(c.activation_excess),
                o(c.reserve_share),
                o(c.layout_fit_error),
            ];
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        let m = &self.summary;
        let cells = [
            "(set)".to_string(),
            m.frames.to_string(),
            String::new(),
            String::new(),
            String::new(),
            format!("{:e}", m.skate),
            format!("{:e}", m.skate_speed),
            format!("{:e}", m.float),
            String::new(),
            format!("{:e}", m.penetrate),
            String::new(),
            o(m.contact_force),
            o(m.joint_actuation),
            o(m.muscle_limit),
            o(m.el_residual),
            o(m.trajectory),
        ];
        s.push_str(&cells.join(","));
        s.push_str(&",".repeat(CSV_COLUMNS.split(',').count() - cells.len()));
        s.push('\n');
        s
    }
}

/// A clip name as one CSV cell (quoted when it holds a comma or a quote).
fn csv_name(name: &str) -> String {
    if name.contains([',', '"', '\n']) {
        format!("\"{}\"", name.replace('"', "\"\""))
    } else {
        name.to_string()
    }
}
