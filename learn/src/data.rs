//! Training data: the tensor files of `musculo augment`, read into per-frame feature vectors.
//!
//! Each frame of a clip becomes one vector y_t of D values, the modalities of METHOD.md §1 in
//! the form the physics losses take them (SI units, ground frame):
//!
//! ```text
//! y_t = [ p_t (J×3, m) | q_t | q̇_t | q̈_t | τ_t (n each) | λ_t (P×3, N) | a_t (m) ]
//! ```
//!
//! - p: `joint_pos`, the joint centres — what a person looks at, and what the reconstruction
//!   error is measured on;
//! - q, q̇, q̈, τ: `q`, `qd`, `qdd`, `tau`, the model's n independent coordinates (radians and
//!   metres), their rates and the generalized forces (N·m or N);
//! - λ: `contact_point_force`, the ground force at each of the model's P contact spheres, each
//!   acting at the sphere's lowest point (the contact points of [`musculo::loss::EulerLagrange`]);
//! - a: `muscle_act`, the m muscle activations.
//!
//! The coordinate blocks stand in for the per-joint rotations of METHOD.md §1 because the
//! losses are exact in them: r = M q̈ + C q̇ + G − τ − J_cᵀλ needs q, q̇, q̈, τ and λ as they are,
//! and going back from per-joint rotations to q is a fit. A decoded y_t is therefore a motion the
//! physics can judge directly (`musculo loss`, `musculo evaluate`).
//!
//! The network sees standardized features, (y − μ)/σ per feature with the set's mean and
//! standard deviation ([`Normalizer`]); a feature that barely varies (a locked coordinate, a
//! contact sphere that never touches) gets the floor σ = max(σ, 1 % of its block's mean σ) so
//! that it is neither amplified nor divided by zero.

use musculo::augment::identity::{BaseModel, Bodies, ModelIdentity};
use musculo::augment::perturb::Variant;
use musculo::loss::tensor_file::TensorFrames;
use musculo::model::Model;
use musculo::motion::npy::read_npz_as_f64;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where each modality sits in a frame's feature vector.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FeatureLayout {
    /// J, the joints of `joint_pos`.
    pub joints: usize,
    /// n, the model's independent coordinates.
    pub coordinates: usize,
    /// P, the contact points of λ.
    pub contacts: usize,
    /// m, the muscles of a.
    pub muscles: usize,
}

impl FeatureLayout {
    /// D, the width of a frame's vector.
    pub fn width(&self) -> usize {
        3 * self.joints + 4 * self.coordinates + 3 * self.contacts + self.muscles
    }

    /// The blocks in order, each with its name and range.
    pub fn blocks(&self) -> [(&'static str, Range<usize>); 7] {
        let (j, n, p, m) = (
            3 * self.joints,
            self.coordinates,
            3 * self.contacts,
            self.muscles,
        );
        let mut start = 0;
        let mut next = |len: usize| {
            let r = start..start + len;
            start += len;
            r
        };
        [
            ("joint_pos", next(j)),
            ("q", next(n)),
            ("qd", next(n)),
            ("qdd", next(n)),
            ("tau", next(n)),
            ("contact_point_force", next(p)),
            ("muscle_act", next(m)),
        ]
    }

    /// The range of block `name` (one of [`Self::blocks`]'s names).
    pub fn block(&self, name: &str) -> Range<usize> {
        self.blocks()
            .into_iter()
            .find(|(k, _)| *k == name)
            .map(|(_, r)| r)
            .unwrap_or(0..0)
    }
}

/// One clip: T frames × D features, SI units.
#[derive(Clone, Debug)]
pub struct Clip {
    pub name: String,
    pub frames: usize,
    /// T × D, row-major.
    pub y: Vec<f32>,
    /// The clip's body, an index into [`ClipSet::bodies`] (0: the model the set was read for):
    /// the model rebuilt from the file's model identity (scaled to the clip's bones, a
    /// variant's mass and load), on which the physics terms judge the clip. None for a file
    /// without an identity that a manifest lists as a variant with a changed body: it cannot
    /// be rebuilt, so the clip is reconstructed but left out of the physics terms.
    pub body: Option<usize>,
    /// The clip's caption ([`crate::text::caption`]).
    pub caption: String,
}

/// One distinct body of a training set.
#[derive(Clone, Debug)]
pub struct SetBody {
    /// What tells bodies apart ([`musculo::augment::identity::ClipBody::key`]; "model" for the
    /// model the set was read for).
    pub key: String,
    pub model: Arc<Model>,
}

/// The clips of a training set, one layout for all.
#[derive(Clone, Debug)]
pub struct ClipSet {
    pub layout: FeatureLayout,
    pub clips: Vec<Clip>,
    /// The distinct bodies of the clips ([`Clip::body`]); the first is the model the set was
    /// read for.
    pub bodies: Vec<SetBody>,
    /// The frame rate shared by every clip (Hz).
    pub rate_hz: f64,
}

pub use crate::error::{LearnError, Result};

impl ClipSet {
    /// Reads the tensor files `inputs` (files, or folders searched recursively for `.npz`
    /// files other than `stats.npz`) for `model`, each clip on its own body: the model rebuilt
    /// from the file's model identity ([`musculo::augment::identity`]: scaled to the clip's
    /// bones, a variant's mass and load; `model` itself when the identity is its unchanged
    /// body), found as `musculo evaluate` finds it ([`Bodies::of_tensor_file`], here without
    /// `--model`). A file without an identity is taken on `model`, unless the `manifest.json`
    /// of `musculo augment` in its folder lists it as a variant with a changed body.
    pub fn read(inputs: &[PathBuf], model: &Model) -> Result<ClipSet> {
        Self::read_for(inputs, model, None)
    }

    /// [`ClipSet::read`], with `model_hash` (the FNV-1a hash of the model file's text,
    /// [`musculo::augment::output::fnv1a_hex`]) checked against each file's model identity: a
    /// clip of another base model is refused, naming both.
    pub fn read_for(
        inputs: &[PathBuf],
        model: &Model,
        model_hash: Option<&str>,
    ) -> Result<ClipSet> {
        Self::read_with(inputs, model, model_hash, &Bodies::new(None)?)
    }

    /// [`ClipSet::read_for`], the clips' bodies found by `bodies` (give it the `--model` file,
    /// [`Bodies::new`], so that a body is rebuilt from that file's text).
    pub fn read_with(
        inputs: &[PathBuf],
        model: &Model,
        model_hash: Option<&str>,
        bodies: &Bodies,
    ) -> Result<ClipSet> {
        let mut files = Vec::new();
        let mut variants = Vec::new();
        for input in inputs {
            if input.is_dir() {
                collect_npz(input, &mut files)?;
                variants.extend(changed_bodies(input)?);
            } else if input.is_file() {
                files.push(input.clone());
            } else {
                return Err(LearnError::File {
                    path: input.clone(),
                    message: "no such file or folder".into(),
                });
            }
        }
        files.sort();
        if files.is_empty() {
            return Err(LearnError::invalid(
                "training data",
                format!("no tensor files (.npz) in {}", show_paths(inputs)),
            ));
        }
        let mut set: Option<ClipSet> = None;
        let mut found = vec![SetBody {
            key: "model".to_string(),
            model: Arc::new(model.clone()),
        }];
        for file in &files {
            let name = file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let (clip, layout, rate) = read_clip(file, &name, model)?;
            let body = match musculo::augment::identity::read_identity(file)? {
                None => (!variants.iter().any(|v| v == &name)).then_some(0),
                Some(id) if own_body(file, &id, model, model_hash)? => Some(0),
                Some(_) => {
                    let body = bodies.of_tensor_file(file)?;
                    let at = found.iter().position(|b| b.key == body.key);
                    Some(at.unwrap_or_else(|| {
                        found.push(SetBody {
                            key: body.key,
                            model: body.model,
                        });
                        found.len() - 1
                    }))
                }
            };
            let clip = Clip {
                body,
                caption: crate::text::caption(&name, file, inputs)?,
                ..clip
            };
            match &mut set {
                None => {
                    set = Some(ClipSet {
                        layout,
                        clips: vec![clip],
                        bodies: Vec::new(),
                        rate_hz: rate,
                    })
                }
                Some(s) => {
                    if s.layout != layout {
                        return Err(LearnError::File {
                            path: file.clone(),
                            message: format!(
                                "layout {layout:?} differs from the first file's {:?}",
                                s.layout
                            ),
                        });
                    }
                    if (s.rate_hz - rate).abs() > 1e-6 * rate {
                        return Err(LearnError::File {
                            path: file.clone(),
                            message: format!(
                                "{rate} frames/s, the first file has {} (resample the set to one rate)",
                                s.rate_hz
                            ),
                        });
                    }
                    s.clips.push(clip);
                }
            }
        }
        let mut set = set.ok_or_else(|| LearnError::invalid("training data", "no clips"))?;
        set.bodies = found;
        Ok(set)
    }

    /// The models of [`Self::bodies`], in order (for [`crate::physics::Physics::with_bodies`]).
    pub fn body_models(&self) -> Vec<Arc<Model>> {
        self.bodies.iter().map(|b| Arc::clone(&b.model)).collect()
    }

    /// Every frame of every clip.
    pub fn frames(&self) -> usize {
        self.clips.iter().map(|c| c.frames).sum()
    }
}

/// One tensor file as a clip.
fn read_clip(path: &Path, name: &str, model: &Model) -> Result<(Clip, FeatureLayout, f64)> {
    let arrays = read_npz_as_f64(path)?;
    let source = path.display().to_string();
    let frames = TensorFrames::from_arrays(&arrays, model, &source)?;
    let file_error = |message: String| LearnError::File {
        path: path.to_path_buf(),
        message,
    };
    if frames.layout_error.is_some() {
        return Err(file_error(
            "holds only the per-joint layout (no q, qd, qdd, tau): train on files of `musculo augment`".into(),
        ));
    }
    if frames.muscles == 0 {
        return Err(file_error("has no `muscle_act`".into()));
    }
    if !frames.external.is_empty() && frames.external.iter().any(|v| *v != 0.0) {
        return Err(file_error(
            "carries measured external loads (`external`), which the feature vector has no place for".into(),
        ));
    }
    let joint_pos = arrays
        .iter()
        .find(|(k, _)| k == "joint_pos")
        .map(|(_, a)| a)
        .ok_or_else(|| file_error("has no array `joint_pos`".into()))?;
    let t = frames.frames;
    if joint_pos.ndim() != 3 || joint_pos.shape()[0] != t || joint_pos.shape()[2] != 3 {
        return Err(file_error(format!(
            "`joint_pos` has shape {:?}, expected ({t}, J, 3)",
            joint_pos.shape()
        )));
    }
    let layout = FeatureLayout {
        joints: joint_pos.shape()[1],
        coordinates: model.nq(),
        contacts: frames.contacts,
        muscles: frames.muscles,
    };
    let rate = frames.rate_hz()?;
    let d = layout.width();
    let (n, p, m) = (layout.coordinates, 3 * layout.contacts, layout.muscles);
    let pos: Vec<f64> = joint_pos.iter().copied().collect();
    let mut y = Vec::with_capacity(t * d);
    for f in 0..t {
        let j = 3 * layout.joints;
        y.extend(pos[f * j..(f + 1) * j].iter().map(|v| *v as f32));
        for block in [&frames.q, &frames.qd, &frames.qdd, &frames.tau] {
            y.extend(block[f * n..(f + 1) * n].iter().map(|v| *v as f32));
        }
        if p > 0 {
            y.extend(frames.lambda[f * p..(f + 1) * p].iter().map(|v| *v as f32));
        }
        y.extend(
            frames.muscle_act[f * m..(f + 1) * m]
                .iter()
                .map(|v| *v as f32),
        );
    }
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(file_error(format!(
            "frame {}: feature {} is not finite",
            i / d,
            i % d
        )));
    }
    let clip = Clip {
        name: name.to_string(),
        frames: t,
        y,
        body: Some(0),
        caption: String::new(),
    };
    Ok((clip, layout, rate))
}

/// Whether the body `id` (the model identity of the tensor file `path`) is `model` itself: its
/// own `<clip>.osim`, or its base model unscaled, without a variant's mass or load and at
/// muscle strength 1. With `model_hash`, a file whose base model (or own `.osim`) has another
/// hash is an error naming both.
fn own_body(
    path: &Path,
    id: &ModelIdentity,
    model: &Model,
    model_hash: Option<&str>,
) -> Result<bool> {
    if let Some(hash) = model_hash {
        if id.osim_hash.as_deref() == Some(hash) {
            return Ok(true);
        }
        if id.base.file_hash != hash {
            return Err(LearnError::File {
                path: path.to_path_buf(),
                message: format!(
                    "belongs to model {}, not to --model \"{}\" (hash {hash})",
                    id.describe(),
                    model.name
                ),
            });
        }
    }
    Ok(id.scale.is_none()
        && id.mass_scale == 1.0
        && id.load_kg == 0.0
        && id.base.muscle_strength == 1.0)
}

fn collect_npz(dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| LearnError::File {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    for entry in entries {
        let path = entry
            .map_err(|e| LearnError::File {
                path: dir.to_path_buf(),
                message: e.to_string(),
            })?
            .path();
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let hidden = name.as_deref().is_some_and(|n| n.starts_with('.'));
        if hidden {
            continue;
        }
        if path.is_dir() {
            collect_npz(&path, files)?;
        } else if path.extension().is_some_and(|e| e == "npz")
            && name.as_deref() != Some("stats.npz")
        {
            files.push(path);
        }
    }
    Ok(())
}

/// The clip names of `dir/manifest.json` whose variant changed the body (height, mass or a
/// carried load); none without a manifest.
fn changed_bodies(dir: &Path) -> Result<Vec<String>> {
    let path = dir.join("manifest.json");
    let Ok(text) = std::fs::read_to_string(&path) else {
        return Ok(Vec::new());
    };
    let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| LearnError::File {
        path: path.clone(),
        message: e.to_string(),
    })?;
    let mut out = Vec::new();
    for clip in json["clips"].as_array().into_iter().flatten() {
        let v = &clip["variant"];
        let number = |k: &str, neutral: f64| v[k].as_f64().unwrap_or(neutral);
        let changed = (number("height_scale", 1.0) - 1.0).abs() > 1e-12
            || (number("mass_scale", 1.0) - 1.0).abs() > 1e-12
            || number("load_kg", 0.0) != 0.0;
        if let (true, Some(name)) = (changed, clip["clip"].as_str()) {
            out.push(name.rsplit('/').next().unwrap_or(name).to_string());
        }
    }
    Ok(out)
}

fn show_paths(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Augments the demo clips of `musculo augment --demo` (default model, default chain) into
/// folder `out`: a small training set on any machine (3 clips, 330 frames at 30 Hz).
pub fn augment_demo(out: &Path) -> Result<()> {
    use musculo::augment::chain::{Chain, ChainOptions};
    use musculo::augment::runner::{self, RunOptions};
    use musculo::augment::{demo, describe};
    let chain = Chain::default_model(ChainOptions::default())?;
    let layout = describe(&chain)?;
    let clips = demo::inputs(&chain.model)?;
    runner::run(&chain, &layout, &clips, &RunOptions::new(out), &|_| {})?;
    Ok(())
}

/// Per-feature standardization: z = (y − μ)/σ.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Normalizer {
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
}

impl Normalizer {
    /// μ and σ of every feature over all frames of `set`, σ floored per block (module docs).
    pub fn of(set: &ClipSet) -> Normalizer {
        let d = set.layout.width();
        let count = set.frames().max(1) as f64;
        let mut sum = vec![0.0f64; d];
        let mut sq = vec![0.0f64; d];
        for clip in &set.clips {
            for row in clip.y.chunks(d) {
                for i in 0..d {
                    let v = row[i] as f64;
                    sum[i] += v;
                    sq[i] += v * v;
                }
            }
        }
        let mean: Vec<f64> = sum.iter().map(|s| s / count).collect();
        let mut std: Vec<f64> = (0..d)
            .map(|i| (sq[i] / count - mean[i] * mean[i]).max(0.0).sqrt())
            .collect();
        for (_, range) in set.layout.blocks() {
            if range.is_empty() {
                continue;
            }
            let typical = std[range.clone()].iter().sum::<f64>() / range.len() as f64;
            let floor = (0.01 * typical).max(1e-6);
            for s in &mut std[range] {
                *s = s.max(floor);
            }
        }
        Normalizer {
            mean: mean.iter().map(|v| *v as f32).collect(),
            std: std.iter().map(|v| *v as f32).collect(),
        }
    }

    /// Standardizes rows of D values in place.
    pub fn normalize(&self, y: &mut [f32]) {
        let d = self.mean.len();
        for row in y.chunks_mut(d) {
            for i in 0..d {
                row[i] = (row[i] - self.mean[i]) / self.std[i];
            }
        }
    }

    /// Undoes [`Self::normalize`] in place.
    pub fn denormalize(&self, z: &mut [f32]) {
        let d = self.mean.len();
        for row in z.chunks_mut(d) {
            for i in 0..d {
                row[i] = row[i] * self.std[i] + self.mean[i];
            }
        }
    }
}

/// The identity of a motion generated on the model whose file text is `xml` (named `source`;
/// the built-in model when `xml` is its text): that model unscaled, at full muscle strength,
/// with no variant — what `musculo augment --no-scale` records for a clip on it.
pub fn generated_identity(model: &Model, xml: &str, source: &str) -> ModelIdentity {
    let base = BaseModel::new(&model.name, source, xml, 1.0, xml);
    ModelIdentity::new(&base, None, &Variant::identity())
}

/// Writes frames `y` (T × D, SI units, at `rate_hz`) as a tensor file in musculo's format, so
/// that `musculo loss`, `evaluate` and `report` read it: `joint_pos` (T × J × 3), `q`, `qd`,
/// `qdd`, `tau` (T × n), `contact_point_force` (T × P × 3), `muscle_act` (T × m) and `time`
/// (T, s), float32, with `identity` (the body the frames belong to, see
/// [`generated_identity`]) as the text member `model_identity`, as augment writes it.
pub fn write_tensor_file(
    path: &Path,
    layout: &FeatureLayout,
    y: &[f32],
    rate_hz: f64,
    identity: &ModelIdentity,
) -> Result<()> {
    use ndarray::{ArrayD, IxDyn};
    let d = layout.width();
    if y.is_empty() || !y.len().is_multiple_of(d) || rate_hz.is_nan() || rate_hz <= 0.0 {
        return Err(LearnError::invalid(
            "tensor file",
            format!(
                "{} values are not whole frames of {d}, or rate {rate_hz} Hz",
                y.len()
            ),
        ));
    }
    let t = y.len() / d;
    let block = |name: &str, shape: Vec<usize>| -> Result<ArrayD<f32>> {
        let r = layout.block(name);
        let values: Vec<f32> = (0..t)
            .flat_map(|f| y[f * d + r.start..f * d + r.end].iter().copied())
            .collect();
        ArrayD::from_shape_vec(IxDyn(&shape), values)
            .map_err(|e| LearnError::invalid("tensor file", e.to_string()))
    };
    let n = layout.coordinates;
    let arrays = [
        ("joint_pos", block("joint_pos", vec![t, layout.joints, 3])?),
        ("q", block("q", vec![t, n])?),
        ("qd", block("qd", vec![t, n])?),
        ("qdd", block("qdd", vec![t, n])?),
        ("tau", block("tau", vec![t, n])?),
        (
            "contact_point_force",
            block("contact_point_force", vec![t, layout.contacts, 3])?,
        ),
        ("muscle_act", block("muscle_act", vec![t, layout.muscles])?),
        (
            "time",
            ArrayD::from_shape_vec(
                IxDyn(&[t]),
                (0..t).map(|f| (f as f64 / rate_hz) as f32).collect(),
            )
            .map_err(|e| LearnError::invalid("tensor file", e.to_string()))?,
        ),
    ];
    let views: Vec<(&str, ndarray::ArrayViewD<'_, f32>)> =
        arrays.iter().map(|(k, a)| (*k, a.view())).collect();
    let json = identity.to_json();
    let texts = [(musculo::augment::identity::MEMBER, json.as_str())];
    musculo::motion::npy::write_npz_with_texts(path, &views, &texts, false)?;
    Ok(())
}
