//! Which body a tensor file belongs to: the model identity `musculo augment` writes into every
//! clip's `.npz`, and how readers (`evaluate`, `loss`, `report`, the learned module) find that
//! body again or refuse a model that is not it.
//!
//! A clip's tensors (q, τ, λ, …) are only meaningful on the body they were computed on: the
//! run's model file, with the muscle strength of `--muscle-strength`, scaled to the clip's bone
//! lengths (unless `--no-scale`), and with a variant's mass scaling and carried load. The
//! identity records each step, so the body can be rebuilt from the base model alone:
//!
//! - `base`: the model file's name, source and absolute path (none for the built-in model),
//!   the FNV-1a hash of its text (`file_hash`), the muscle-strength factor and the hash of the
//!   text the chain used (`hash`, the manifest's `model_hash`);
//! - `scale`: for a clip scaled to its bones, the per-body factors (only those ≠ 1) and the
//!   hash of the scaled model's text ([`crate::solve::scale_from_clip::scale_by`] of the base
//!   text by those factors);
//! - `mass_scale`, `load_kg`, `load_site`: the variant's body ([`Variant::apply_to_model`]);
//! - `osim_hash`: the hash of `<clip>.osim` when augment wrote it beside the `.npz`
//!   (`--opensim-files`): that file is the whole body, markers placed on the clip included.
//!
//! It is stored as the text member `model_identity` of the `.npz` (UTF-8 JSON as a `uint8`
//! array, a few hundred bytes; `json.loads(bytes(np.load(f)["model_identity"]))` in Python).
//!
//! Resolution ([`Bodies::of_tensor_file`]): with `--model` the given file must be the clip's
//! base model (its text's hash is `file_hash`; the clip's body is rebuilt from it) or the
//! clip's own `<clip>.osim` (`osim_hash`); any other file is refused, naming both. Without it:
//! `<clip>.osim` beside the file when its hash matches, else the built-in model when the base
//! is the built-in one, else the base file at its recorded path when it is still there with
//! the same text; otherwise the clip is refused, naming the model to pass. A rebuilt body whose
//! text hash is not the recorded one (another musculo version scales differently) is refused
//! too. A file without an identity (written before it existed, or a generated motion) keeps
//! the earlier rule — `--model`, else `<clip>.osim` beside it, else the built-in model — with
//! a warning saying so.

use super::perturb::{LoadSite, Variant};
use crate::error::Error;
use crate::model::Model;
use crate::solve::scale::{BodyScale, ScaleSet};
use crate::spatial::Vec3;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The `.npz` member holding a clip's [`ModelIdentity`].
pub const MEMBER: &str = "model_identity";

/// The model file a run started from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BaseModel {
    /// The model's name (its `<Model name>`).
    pub name: String,
    /// The file as the run named it.
    pub source: String,
    /// The file's absolute path when it was read from one; None for the built-in model.
    pub path: Option<String>,
    /// FNV-1a 64-bit hash of the file's text.
    pub file_hash: String,
    /// The factor on every muscle's maximum isometric force (`--muscle-strength`).
    pub muscle_strength: f64,
    /// FNV-1a hash of the text the run used: the file's with that strength.
    pub hash: String,
}

impl BaseModel {
    /// The base of a run on the file text `file_text` (named `source`; a path when it is not
    /// the built-in model's text), used as `used_text` (after `muscle_strength`).
    pub fn new(
        name: &str,
        source: &str,
        file_text: &str,
        muscle_strength: f64,
        used_text: &str,
    ) -> BaseModel {
        let file_hash = fnv1a_hex(file_text);
        let builtin = file_hash == fnv1a_hex(crate::DEFAULT_MODEL_OSIM);
        let path = (!builtin)
            .then(|| std::fs::canonicalize(source).ok())
            .flatten()
            .map(|p| p.display().to_string());
        BaseModel {
            name: name.to_string(),
            source: source.to_string(),
            path,
            file_hash,
            muscle_strength,
            hash: fnv1a_hex(used_text),
        }
    }

    /// Whether the base is the built-in default model.
    pub fn is_builtin(&self) -> bool {
        self.file_hash == fnv1a_hex(crate::DEFAULT_MODEL_OSIM)
    }

    fn describe(&self) -> String {
        format!(
            "\"{}\" ({}, hash {})",
            self.name,
            if self.is_builtin() {
                "the built-in model".to_string()
            } else {
                self.path.clone().unwrap_or_else(|| self.source.clone())
            },
            self.file_hash
        )
    }
}

/// A clip scaled to its bone lengths: the factors of the bodies that changed, and the hash
/// of the scaled text.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClipScale {
    /// (body, [fx, fy, fz]) for every body with a factor ≠ 1.
    pub bodies: Vec<(String, [f64; 3])>,
    pub hash: String,
}

/// The body of one clip (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelIdentity {
    pub base: BaseModel,
    pub scale: Option<ClipScale>,
    pub mass_scale: f64,
    pub load_kg: f64,
    pub load_site: LoadSite,
    /// The hash of `<clip>.osim` when augment wrote it beside the clip.
    pub osim_hash: Option<String>,
}

impl ModelIdentity {
    /// The identity of a clip on `base`, scaled by `scales` (with the hash of the scaled
    /// text) when it was scaled, with `variant`'s body.
    pub fn new(base: &BaseModel, scale: Option<(&ScaleSet, String)>, variant: &Variant) -> Self {
        ModelIdentity {
            base: base.clone(),
            scale: scale.map(|(set, text)| ClipScale {
                bodies: (set.scales.iter())
                    .filter(|b| b.factors != Vec3::new(1.0, 1.0, 1.0))
                    .map(|b| (b.body.clone(), [b.factors.x, b.factors.y, b.factors.z]))
                    .collect(),
                hash: text,
            }),
            mass_scale: variant.mass_scale,
            load_kg: variant.load_kg,
            load_site: variant.load_site,
            osim_hash: None,
        }
    }

    /// The identity as the JSON text stored in the `.npz`.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("an identity serializes")
    }

    /// What tells two bodies apart (the identity without `osim_hash`).
    fn body_key(&self) -> String {
        ModelIdentity {
            osim_hash: None,
            ..self.clone()
        }
        .to_json()
    }

    /// `"gait2392" (/path/x.osim, hash …), scaled to the clip, mass ×1.05`, for messages.
    pub fn describe(&self) -> String {
        let mut s = self.base.describe();
        if self.base.muscle_strength != 1.0 {
            s += &format!(", muscle strength ×{}", self.base.muscle_strength);
        }
        if self.scale.is_some() {
            s += ", scaled to the clip's bones";
        }
        if self.mass_scale != 1.0 {
            s += &format!(", mass ×{}", self.mass_scale);
        }
        if self.load_kg != 0.0 {
            s += &format!(", carrying {} kg", self.load_kg);
        }
        s
    }

    /// The clip's body rebuilt from its base model's file text `text` (named `source`), whose
    /// hash must be `base.file_hash`.
    pub fn rebuild(&self, text: &str, source: &str) -> crate::Result<Model> {
        let stale = |what: &str, got: &str, want: &str| {
            Error::invalid(
                "model",
                format!(
                    "rebuilding the body of a clip on {source}: {what} has hash {got} where the \
                     clip records {want} (written by another musculo version?); pass the clip's \
                     own model with --model <clip>.osim (augment --opensim-files writes it)"
                ),
            )
        };
        let file_hash = fnv1a_hex(text);
        if file_hash != self.base.file_hash {
            return Err(stale("the model file", &file_hash, &self.base.file_hash));
        }
        let strengthened;
        let text = if self.base.muscle_strength == 1.0 {
            text
        } else {
            strengthened = crate::solve::scale::strength::scale_muscle_strength(
                text,
                source,
                self.base.muscle_strength,
            )?
            .0;
            &strengthened
        };
        let used = fnv1a_hex(text);
        if used != self.base.hash {
            return Err(stale(
                "the text with its muscle strength",
                &used,
                &self.base.hash,
            ));
        }
        let mut model = Model::from_osim_str(text, source)?;
        if let Some(scale) = &self.scale {
            let mut set = ScaleSet::identity(&model);
            for (body, [x, y, z]) in &scale.bodies {
                match set.scales.iter_mut().find(|b| &b.body == body) {
                    Some(b) => b.factors = Vec3::new(*x, *y, *z),
                    None => set.scales.push(BodyScale {
                        body: body.clone(),
                        factors: Vec3::new(*x, *y, *z),
                    }),
                }
            }
            let scaled = crate::solve::scale_from_clip::scale_by(text, source, &model, &set)?;
            let got = fnv1a_hex(&scaled.xml);
            if got != scale.hash {
                return Err(stale("the model scaled to the clip", &got, &scale.hash));
            }
            model = scaled.model;
        }
        let variant = Variant {
            mass_scale: self.mass_scale,
            load_kg: self.load_kg,
            load_site: self.load_site,
            ..Variant::identity()
        };
        variant.apply_to_model(&mut model)?;
        Ok(model)
    }
}

/// The identity stored in the tensor file `path`; None when it has none.
pub fn read_identity(path: &Path) -> crate::Result<Option<ModelIdentity>> {
    let Some(text) = crate::motion::npy::read_npz_text(path, MEMBER)? else {
        return Ok(None);
    };
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::Motion {
            file: path.display().to_string(),
            location: format!("archive member \"{MEMBER}\""),
            message: format!("not a model identity: {e}"),
        })
}

/// A model file given on the command line (`--model`), read once.
#[derive(Clone, Debug)]
pub struct GivenModel {
    pub path: PathBuf,
    pub text: String,
    pub hash: String,
    pub model: Arc<Model>,
}

impl GivenModel {
    pub fn read(path: &Path) -> crate::Result<GivenModel> {
        let text = crate::text::read_text(path)?;
        let model = Model::from_osim_str(&text, &path.display().to_string())?;
        Ok(GivenModel {
            path: path.to_path_buf(),
            hash: fnv1a_hex(&text),
            text,
            model: Arc::new(model),
        })
    }
}

/// The body of one tensor file: the model, a key telling bodies apart (clips of one key share
/// the model), and a warning when the file did not say which body it belongs to.
#[derive(Clone, Debug)]
pub struct ClipBody {
    pub model: Arc<Model>,
    pub key: String,
    pub warning: Option<String>,
}

/// Finds the bodies of tensor files (see the module documentation), keeping the last
/// [`Bodies::CAPACITY`] distinct ones for the clips that follow (a dataset scaled to one
/// skeleton has one body per variant). Safe to share between threads.
#[derive(Debug, Default)]
pub struct Bodies {
    given: Option<GivenModel>,
    held: Mutex<VecDeque<(String, Arc<Model>)>>,
    builtin: std::sync::OnceLock<Arc<Model>>,
}

impl Bodies {
    /// Distinct bodies kept.
    pub const CAPACITY: usize = 8;

    /// With `--model` read from `model` when given.
    pub fn new(model: Option<&Path>) -> crate::Result<Bodies> {
        Ok(Bodies {
            given: model.map(GivenModel::read).transpose()?,
            ..Bodies::default()
        })
    }

    /// The `--model` given, if any.
    pub fn given(&self) -> Option<&GivenModel> {
        self.given.as_ref()
    }

    fn builtin(&self) -> Arc<Model> {
        Arc::clone(
            self.builtin
                .get_or_init(|| Arc::new(Model::default_fullbody())),
        )
    }

    /// The body `key` held, or made by `make` and kept.
    fn held(
        &self,
        key: &str,
        make: impl FnOnce() -> crate::Result<Model>,
    ) -> crate::Result<Arc<Model>> {
        let lock = || self.held.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, m)) = lock().iter().find(|(k, _)| k == key) {
            return Ok(Arc::clone(m));
        }
        let made = Arc::new(make()?);
        let mut held = lock();
        if held.len() == Self::CAPACITY {
            held.pop_front();
        }
        held.push_back((key.to_string(), Arc::clone(&made)));
        Ok(made)
    }

    /// The body of the tensor file `path` (see the module documentation).
    pub fn of_tensor_file(&self, path: &Path) -> crate::Result<ClipBody> {
        let beside = path.with_extension("osim");
        let Some(id) = read_identity(path)? else {
            let (model, key, used) = match &self.given {
                Some(g) => (
                    Arc::clone(&g.model),
                    format!("given {}", g.hash),
                    format!("--model {}", g.path.display()),
                ),
                None if beside.is_file() => {
                    let text = crate::text::read_text(&beside)?;
                    let key = format!("file {}", fnv1a_hex(&text));
                    let source = beside.display().to_string();
                    let model = self.held(&key, || Model::from_osim_str(&text, &source))?;
                    (model, key, source)
                }
                None => (
                    self.builtin(),
                    "built-in".to_string(),
                    "the built-in model".to_string(),
                ),
            };
            return Ok(ClipBody {
                model,
                key,
                warning: Some(format!(
                    "{}: the file does not say which model it belongs to (no `{MEMBER}`: written \
                     before musculo recorded it, or not by augment); read on {used}",
                    path.display()
                )),
            });
        };
        let key = id.body_key();
        let found = |model| ClipBody {
            model,
            key: key.clone(),
            warning: None,
        };
        if let Some(g) = &self.given {
            if id.osim_hash.as_deref() == Some(g.hash.as_str()) {
                return Ok(found(Arc::clone(&g.model)));
            }
            if g.hash == id.base.file_hash {
                let source = g.path.display().to_string();
                return Ok(found(self.held(&key, || id.rebuild(&g.text, &source))?));
            }
            return Err(Error::invalid(
                "--model",
                format!(
                    "{}: --model {} (\"{}\", hash {}) is not the model this clip belongs to: {}",
                    path.display(),
                    g.path.display(),
                    g.model.name,
                    g.hash,
                    id.describe()
                ),
            ));
        }
        if let Some(want) = &id.osim_hash
            && beside.is_file()
        {
            let text = crate::text::read_text(&beside)?;
            if &fnv1a_hex(&text) == want {
                let source = beside.display().to_string();
                return Ok(found(
                    self.held(&key, || Model::from_osim_str(&text, &source))?,
                ));
            }
        }
        if id.base.is_builtin() {
            return Ok(found(self.held(&key, || {
                id.rebuild(crate::DEFAULT_MODEL_OSIM, "models/musculo_fullbody.osim")
            })?));
        }
        let why = match &id.base.path {
            Some(p) => match std::fs::read_to_string(p) {
                Ok(text) if fnv1a_hex(&text) == id.base.file_hash => {
                    return Ok(found(self.held(&key, || id.rebuild(&text, p))?));
                }
                Ok(text) => format!("the file at {p} has changed (hash {})", fnv1a_hex(&text)),
                Err(e) => format!("{p} cannot be read ({e})"),
            },
            None => format!("the run did not read it from a file ({})", id.base.source),
        };
        Err(Error::invalid(
            "model",
            format!(
                "{}: the clip belongs to model {}, and {why}: pass that model with --model",
                path.display(),
                id.describe()
            ),
        ))
    }
}

/// FNV-1a 64-bit hash of `text`, as 16 hex digits.
pub fn fnv1a_hex(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}
