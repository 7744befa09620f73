//! A trained autoencoder on disk: one folder with
//!
//! - `autoencoder.bpk`: the weights (burn's burnpack record, `Module::save_file`);
//! - `autoencoder.json`: the sizes, the feature layout, the standardization, the training
//!   settings and the musculo model's hash, everything needed to rebuild and use it;
//! - `loss.csv`: the loss curve, one row per step, and `loss.html`, its plot (a page of musculo's
//!   report: log₁₀ of each loss over the steps).
//!
//! Each file is written to a temporary name and renamed, so an interrupted save leaves the
//! previous checkpoint whole.

use crate::autoencoder::{Autoencoder, AutoencoderConfig};
use crate::data::{FeatureLayout, LearnError, Normalizer, Result};
use crate::train::{StepLog, TrainConfig, Trained};
use burn::config::Config;
use burn::module::Module;
use burn::tensor::Device;
use std::path::{Path, PathBuf};

/// The JSON part of a checkpoint.
#[derive(serde::Serialize, serde::Deserialize)]
struct Description {
    format: String,
    autoencoder: serde_json::Value,
    layout: [usize; 4],
    normalizer: Normalizer,
    train: TrainConfig,
    model_hash: String,
}

const FORMAT: &str = "musculo-learn autoencoder 1";

fn file_error(path: &Path, e: impl std::fmt::Display) -> LearnError {
    LearnError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    musculo::motion::npy::write_file_atomic(path, bytes).map_err(LearnError::from)
}

/// `module`'s weights as `dir/name` (burnpack), through a temporary file and a rename.
fn write_weights<M: Module>(module: &M, dir: &Path, name: &str) -> Result<()> {
    let weights = dir.join(name);
    let partial = dir.join(format!(".{name}.partial"));
    module
        .clone()
        .save_file(&partial)
        .map_err(|e| file_error(&weights, e))?;
    std::fs::rename(&partial, &weights).map_err(|e| file_error(&weights, e))
}

/// The JSON description at `path`, checked to be of `format` (read from its `format` field).
fn read_description<T: serde::de::DeserializeOwned>(
    path: &Path,
    format: &str,
    found: impl Fn(&T) -> &str,
) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| file_error(path, e))?;
    let d: T = serde_json::from_str(&text).map_err(|e| file_error(path, e))?;
    if found(&d) != format {
        return Err(file_error(
            path,
            format!("format {:?}, expected {format:?}", found(&d)),
        ));
    }
    Ok(d)
}

/// Writes `trained` (trained with `train` on model `model_hash`) into folder `dir`.
pub fn save(trained: &Trained, train: &TrainConfig, model_hash: &str, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| file_error(dir, e))?;
    let l = &trained.layout;
    let description = Description {
        format: FORMAT.into(),
        autoencoder: serde_json::from_str(&trained.config.to_string())
            .map_err(|e| file_error(dir, e))?,
        layout: [l.joints, l.coordinates, l.contacts, l.muscles],
        normalizer: trained.normalizer.clone(),
        train: train.clone(),
        model_hash: model_hash.to_string(),
    };
    let json = serde_json::to_string_pretty(&description).map_err(|e| file_error(dir, e))?;
    write_weights(&trained.model, dir, "autoencoder.bpk")?;
    write_atomic(&dir.join("autoencoder.json"), json.as_bytes())?;
    let mut csv = String::from(StepLog::CSV_HEADER);
    csv.push('\n');
    for row in &trained.log {
        csv.push_str(&row.csv_row());
        csv.push('\n');
    }
    write_loss(dir, "autoencoder training", &csv)
}

/// `loss.csv` and its plot `loss.html` (musculo's report page of a loss log) in `dir`.
fn write_loss(dir: &Path, title: &str, csv: &str) -> Result<()> {
    write_atomic(&dir.join("loss.csv"), csv.as_bytes())?;
    let html = musculo::report::training_page(title, "loss.csv", csv)?;
    write_atomic(&dir.join("loss.html"), html.as_bytes())
}

/// A checkpoint read back: the autoencoder on `device` and what it was trained with.
pub struct Loaded {
    pub trained: Trained,
    pub train: TrainConfig,
    pub model_hash: String,
}

/// Reads the checkpoint in `dir` onto `device`.
pub fn load(dir: &Path, device: &Device) -> Result<Loaded> {
    let path = dir.join("autoencoder.json");
    let d: Description = read_description(&path, FORMAT, |d: &Description| &d.format)?;
    let config = AutoencoderConfig::load_binary(d.autoencoder.to_string().as_bytes())
        .map_err(|e| file_error(&path, e))?;
    let layout = FeatureLayout {
        joints: d.layout[0],
        coordinates: d.layout[1],
        contacts: d.layout[2],
        muscles: d.layout[3],
    };
    if layout.width() != config.features || d.normalizer.mean.len() != config.features {
        return Err(file_error(
            &path,
            "the layout, the standardization and the autoencoder's width disagree",
        ));
    }
    let weights = dir.join("autoencoder.bpk");
    if !weights.is_file() {
        return Err(file_error(&weights, "missing"));
    }
    let model: Autoencoder = config
        .init(device)
        .try_load_file(&weights)
        .map_err(|e| file_error(&weights, e))?;
    Ok(Loaded {
        trained: Trained {
            model,
            config,
            normalizer: d.normalizer,
            layout,
            log: Vec::new(),
        },
        train: d.train,
        model_hash: d.model_hash,
    })
}

/// How a diffusion model's captions become vectors.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum TextKind {
    /// The built-in bag of words ([`crate::text::bag_of_words`]).
    BuiltIn,
    /// Precomputed embeddings of this many values.
    Precomputed(usize),
}

/// The JSON part of a diffusion checkpoint.
#[derive(serde::Serialize, serde::Deserialize)]
struct DiffusionDescription {
    format: String,
    denoiser: serde_json::Value,
    latent_scale: f32,
    autoencoder: PathBuf,
    text: TextKind,
    rate_hz: f64,
    train: crate::diffusion::DiffusionTrainConfig,
}

const DIFFUSION_FORMAT: &str = "musculo-learn diffusion 1";

/// A diffusion checkpoint read back.
pub struct LoadedDenoiser {
    pub denoiser: crate::diffusion::TrainedDenoiser,
    /// The autoencoder checkpoint it was trained on.
    pub autoencoder: PathBuf,
    pub text: TextKind,
    /// The frame rate of its training data (Hz).
    pub rate_hz: f64,
}

/// Writes a trained denoiser into `dir`: `denoiser.bpk`, `denoiser.json` (sizes, latent scale,
/// the autoencoder's folder as an absolute path, the caption kind, the frame rate) and
/// `loss.csv`.
pub fn save_denoiser(
    trained: &crate::diffusion::TrainedDenoiser,
    train: &crate::diffusion::DiffusionTrainConfig,
    autoencoder: &Path,
    text: TextKind,
    rate_hz: f64,
    dir: &Path,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| file_error(dir, e))?;
    let autoencoder = std::fs::canonicalize(autoencoder).map_err(|e| file_error(autoencoder, e))?;
    let description = DiffusionDescription {
        format: DIFFUSION_FORMAT.into(),
        denoiser: serde_json::from_str(&trained.config.to_string())
            .map_err(|e| file_error(dir, e))?,
        latent_scale: trained.latent_scale,
        autoencoder,
        text,
        rate_hz,
        train: train.clone(),
    };
    let json = serde_json::to_string_pretty(&description).map_err(|e| file_error(dir, e))?;
    write_weights(&trained.model, dir, "denoiser.bpk")?;
    write_atomic(&dir.join("denoiser.json"), json.as_bytes())?;
    let mut csv = String::from("step,loss,seconds\n");
    for (step, loss, seconds) in &trained.log {
        csv.push_str(&format!("{step},{loss:e},{seconds:.3}\n"));
    }
    write_loss(dir, "latent diffusion training", &csv)
}

/// Reads the diffusion checkpoint in `dir` onto `device`.
pub fn load_denoiser(dir: &Path, device: &Device) -> Result<LoadedDenoiser> {
    use crate::diffusion::{DenoiserConfig, TrainedDenoiser};
    let path = dir.join("denoiser.json");
    let d: DiffusionDescription =
        read_description(&path, DIFFUSION_FORMAT, |d: &DiffusionDescription| {
            &d.format
        })?;
    let config = DenoiserConfig::load_binary(d.denoiser.to_string().as_bytes())
        .map_err(|e| file_error(&path, e))?;
    let weights = dir.join("denoiser.bpk");
    let model = config
        .init(device)
        .try_load_file(&weights)
        .map_err(|e| file_error(&weights, e))?;
    Ok(LoadedDenoiser {
        denoiser: TrainedDenoiser {
            model,
            config,
            latent_scale: d.latent_scale,
            log: Vec::new(),
        },
        autoencoder: d.autoencoder,
        text: d.text,
        rate_hz: d.rate_hz,
    })
}
