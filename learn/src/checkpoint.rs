//! A trained autoencoder on disk: one folder with
//!
//! - `autoencoder.bpk`: the weights (burn's burnpack record, `Module::save_file`);
//! - `autoencoder.json`: the sizes, the feature layout, the standardization, the training
//!   settings and the musculo model's hash, everything needed to rebuild and use it;
//! - `loss.csv`: the loss curve, one row per step.
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
    let weights = dir.join("autoencoder.bpk");
    let partial: PathBuf = dir.join(".autoencoder.bpk.partial");
    trained
        .model
        .clone()
        .save_file(&partial)
        .map_err(|e| file_error(&weights, e))?;
    std::fs::rename(&partial, &weights).map_err(|e| file_error(&weights, e))?;
    write_atomic(&dir.join("autoencoder.json"), json.as_bytes())?;
    let mut csv = String::from(StepLog::CSV_HEADER);
    csv.push('\n');
    for row in &trained.log {
        csv.push_str(&row.csv_row());
        csv.push('\n');
    }
    write_atomic(&dir.join("loss.csv"), csv.as_bytes())
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
    let text = std::fs::read_to_string(&path).map_err(|e| file_error(&path, e))?;
    let d: Description = serde_json::from_str(&text).map_err(|e| file_error(&path, e))?;
    if d.format != FORMAT {
        return Err(file_error(
            &path,
            format!("format {:?}, expected {FORMAT:?}", d.format),
        ));
    }
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
