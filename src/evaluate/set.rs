//! A set of tensor files evaluated clip by clip (in parallel), with their references and
//! controls found by clip name, and the set summary.

use super::{
    Capacity, CapacityCurves, ClipMetrics, Control, EvaluateOptions, SetSummary, evaluate_clip,
    summarize,
};
use crate::augment::chain::{Chain, ChainOptions};
use crate::augment::identity::{Bodies, ClipBody};
use crate::augment::perturb::Variant;
use crate::error::Error;
use crate::loss::tensor_file::TensorFrames;
use crate::model::Model;
use crate::motion::skeleton::SkeletonMap;
use crate::motion::{Format, ReadOptions};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// One clip of the set: its name (the path below the folder given, without its extension;
/// the file stem for a file given directly), its file, and for a motion file (not a tensor
/// file) its format.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipFile {
    pub name: String,
    pub path: PathBuf,
    /// None for a tensor file (`.npz`); the motion format of any other file.
    pub format: Option<Format>,
}

/// The motion extensions a folder is searched for besides `.npz`.
const MOTION_EXTENSIONS: [&str; 4] = ["npy", "bvh", "c3d", "trc"];

/// The clip of file `path` named `name`: a tensor file for `.npz`, else a motion file of
/// `format` (or the format its extension and contents say).
fn clip_of(name: String, path: PathBuf, format: Option<Format>) -> crate::Result<ClipFile> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let format = if ext == "npz" {
        None
    } else {
        Some(match format {
            Some(f) => f,
            None => Format::detect(&path)?,
        })
    };
    Ok(ClipFile { name, path, format })
}

/// The clips of `inputs`: files as given, and below a folder every tensor file (`.npz`) and
/// motion file (`.npy`, `.bvh`, `.c3d`, `.trc`; hidden entries such as an augmentation's
/// `.musculo/` and the folder's own `stats.npz` left out), sorted by name. Motion files are
/// read as `format`, or as their extension and contents say. An input that does not exist or
/// a set without clips is an error; so are two clips of one name.
pub fn collect(inputs: &[PathBuf], format: Option<Format>) -> crate::Result<Vec<ClipFile>> {
    let mut clips = Vec::new();
    for input in inputs {
        if input.is_dir() {
            for path in crate::io::folder::files_below(input, true)? {
                let Some(file_name) = path.file_name().map(|n| n.to_string_lossy().into_owned())
                else {
                    continue;
                };
                if let Some((stem, ext)) = file_name.rsplit_once('.') {
                    let ext = ext.to_ascii_lowercase();
                    if ext != "npz" && !MOTION_EXTENSIONS.contains(&ext.as_str()) {
                        continue;
                    }
                    if path.parent() == Some(input.as_path()) && stem == "stats" && ext == "npz" {
                        continue;
                    }
                    let relative = path.strip_prefix(input).unwrap_or(&path);
                    let name = relative
                        .with_extension("")
                        .to_string_lossy()
                        .replace('\\', "/");
                    clips.push(clip_of(name, path, format)?);
                }
            }
        } else if input.is_file() {
            let name = input
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            clips.push(clip_of(name, input.clone(), format)?);
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
        return Err(Error::invalid(
            "--input",
            "no tensor (.npz) or motion file (.npy, .bvh, .c3d, .trc) found",
        ));
    }
    Ok(clips)
}

/// Settings of [`evaluate_set`].
#[derive(Clone, Debug, Default)]
pub struct SetOptions {
    /// `--model`: for a tensor file, its base model or its own `<clip>.osim` (any other model
    /// is refused, naming both); None: the body its model identity names
    /// ([`crate::augment::identity`]). For motion files, the model they are fitted on (None:
    /// the built-in default model).
    pub model: Option<PathBuf>,
    /// A folder holding `<clip>.npz` references (the same names).
    pub reference: Option<PathBuf>,
    /// A folder holding `<clip>.npz` control files.
    pub control: Option<PathBuf>,
    pub metrics: EvaluateOptions,
    /// How motion files are read (length unit).
    pub read: ReadOptions,
    /// The skeleton map of motion files; None: each format's built-in map (names matched
    /// for marker files).
    pub map: Option<SkeletonMap>,
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
///
/// A motion file goes through the augmentation chain without its muscles (scaling to the
/// clip's bones, IK, filtering, inverse dynamics, contacts; the format's built-in skeleton
/// map) on `options.model` or the default model, and is evaluated on the clip's scaled model
/// with capacities at every frame's pose.
pub fn evaluate_set(
    clips: &[ClipFile],
    options: &SetOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> crate::Result<SetReport> {
    options.metrics.validate()?;
    let shared = Shared {
        options,
        bodies: Bodies::new(options.model.as_deref())?,
        curves: Mutex::new(VecDeque::new()),
        chain: std::sync::OnceLock::new(),
    };
    let done = AtomicUsize::new(0);
    let results: Vec<Result<ClipMetrics, (String, String)>> = clips
        .par_iter()
        .map(|clip| {
            let result = shared
                .evaluate(clip)
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

/// The body of the tensor file `clip` ([`Bodies::of_tensor_file`]: the one its model identity
/// names, `--model` checked against it).
pub fn model_of(clip: &ClipFile, bodies: &Bodies) -> crate::Result<ClipBody> {
    bodies.of_tensor_file(&clip.path)
}

/// Joint strength curves kept per body.
const CURVES_HELD: usize = 8;

/// The joint strength curves of `model` (skipping its floating base).
fn curves_of(model: &Model) -> crate::Result<CapacityCurves> {
    let set = crate::augment::chain::contact_set(model)?;
    CapacityCurves::new(model, &set.floating_base)
}

/// What the clips of one set share: the settings, the models and curves built once, and the
/// chain for motion files.
struct Shared<'a> {
    options: &'a SetOptions,
    /// The tensor files' bodies (`--model` read once).
    bodies: Bodies,
    /// The curves of the last bodies, by body key (errors as text: they are shared).
    curves: Mutex<VecDeque<(String, Arc<Result<CapacityCurves, String>>)>>,
    chain: std::sync::OnceLock<Result<Chain, String>>,
}

impl Shared<'_> {
    fn evaluate(&self, clip: &ClipFile) -> crate::Result<ClipMetrics> {
        let shared_error = |e: &String| Error::invalid("model", e.clone());
        // the frames, the model they belong to, and how capacities are found
        let own_model;
        let body;
        let curves;
        let mut warnings = Vec::new();
        let (frames, model, capacity) = match clip.format {
            Some(format) => {
                let chain = self
                    .chain
                    .get_or_init(|| self.motion_chain().map_err(|e| e.to_string()))
                    .as_ref()
                    .map_err(shared_error)?;
                let (motion, _) = crate::motion::read_with_warnings(
                    &clip.path,
                    Some(format),
                    &self.options.read,
                )?;
                let builtin = match &self.options.map {
                    Some(_) => None,
                    None => format.default_map().map(SkeletonMap::builtin).transpose()?,
                };
                let map = self.options.map.as_ref().or(builtin.as_ref());
                let v = Variant::identity();
                own_model = chain.clip_model(&motion, map, &v)?;
                let out = chain.run(&motion, map, &v)?;
                let arrays: Vec<(String, ndarray::ArrayD<f64>)> = out
                    .arrays
                    .iter()
                    .map(|a| {
                        let values = a.values.iter().map(|&v| v as f64).collect();
                        ndarray::ArrayD::from_shape_vec(ndarray::IxDyn(&a.shape), values)
                            .map(|x| (a.name.to_string(), x))
                            .map_err(|e| Error::invalid("arrays", format!("{}: {e}", a.name)))
                    })
                    .collect::<crate::Result<_>>()?;
                let frames = TensorFrames::from_arrays(&arrays, &own_model, &clip.name)?;
                (frames, &own_model, Capacity::PerFrame)
            }
            None => {
                body = self.bodies.of_tensor_file(&clip.path)?;
                warnings.extend(body.warning.clone());
                let model: &Model = &body.model;
                // one set of curves per body (clips of one skeleton and variant share it)
                let capacity = if self.options.metrics.muscles_per_frame {
                    Capacity::PerFrame
                } else {
                    curves = self.curves_of(&body);
                    Capacity::Curves(curves.as_ref().as_ref().map_err(shared_error)?)
                };
                (TensorFrames::read(&clip.path, model)?, model, capacity)
            }
        };
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
        let reference = match &self.options.reference {
            Some(dir) => Some(TensorFrames::read(&find(dir, "reference")?, model)?),
            None => None,
        };
        let control = match &self.options.control {
            Some(dir) => Some(Control::read(&find(dir, "control")?, model)?),
            None => None,
        };
        let mut metrics = evaluate_clip(
            model,
            &clip.name,
            &frames,
            reference.as_ref(),
            control.as_ref(),
            capacity,
            &self.options.metrics,
        )?;
        metrics.warnings.extend(warnings);
        Ok(metrics)
    }

    /// The joint strength curves of `body`: held, or computed and kept.
    fn curves_of(&self, body: &ClipBody) -> Arc<Result<CapacityCurves, String>> {
        let lock = || self.curves.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, c)) = lock().iter().find(|(k, _)| k == &body.key) {
            return Arc::clone(c);
        }
        let made = Arc::new(curves_of(&body.model).map_err(|e| e.to_string()));
        let mut held = lock();
        if held.len() == CURVES_HELD {
            held.pop_front();
        }
        held.push_back((body.key.clone(), Arc::clone(&made)));
        made
    }

    /// The augmentation chain without muscles, on `--model` or the default model.
    fn motion_chain(&self) -> crate::Result<Chain> {
        let (xml, source) = match &self.options.model {
            Some(p) => (crate::text::read_text(p)?, p.display().to_string()),
            None => (
                crate::DEFAULT_MODEL_OSIM.to_string(),
                "models/musculo_fullbody.osim".to_string(),
            ),
        };
        let mut options = ChainOptions {
            muscles: false,
            ..ChainOptions::default()
        };
        // the contact estimate on the same floor the metrics take (a treadmill's belt)
        options.contact.floor_velocity = self.options.metrics.floor_velocity;
        Chain::new(xml, source, options)
    }
}

/// The CSV columns of [`SetReport::to_csv`].
const CSV_COLUMNS: &str = "clip,frames,rate_hz,body_mass,support_fraction,skate,skate_speed,\
float,float_max,penetrate,penetrate_max,contact_force,joint_actuation,muscle_limit,el_residual,\
trajectory,location_failure,trajectory_error,actuation_excess,actuation_over,actuation_peak,\
actuation_error,activation_excess,reserve_share,layout_fit_error,el_residual_from_q,range_share,\
range_worst,range_excess";

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
                o(c.el_residual_from_q),
                format!("{:e}", c.range_share),
                c.range_worst
                    .as_ref()
                    .map_or(String::new(), |w| csv_name(&w.describe())),
                o(c.range_worst.as_ref().map(|w| w.excess)),
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
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            o(m.el_residual_from_q),
            format!("{:e}", m.range_share),
            m.range_worst.as_ref().map_or(String::new(), |(clip, w)| {
                csv_name(&format!("{clip}: {}", w.describe()))
            }),
            o(m.range_worst.as_ref().map(|(_, w)| w.excess)),
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
