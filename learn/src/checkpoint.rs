//! A trained autoencoder on disk: one folder with
//!
//! - `autoencoder.bpk`: the weights (burn's burnpack record, `Module::save_file`);
//! - `autoencoder.json`: the sizes, the feature layout, the standardization, the training
//!   settings and the musculo model's hash, everything needed to rebuild and use it;
//! - `loss.csv`: the loss curve, one row per step, and `loss.html`, its plot (a page of musculo's
//!   report: log₁₀ of each loss over the steps).
//!
//! A snapshot of a run in progress adds what continuing it needs ([`save_state`]):
//!
//! - `resume-<step>.bpk` and `optimizer-<step>.bpk`: the network and Adam's moments after that
//!   many steps;
//! - `resume.json`: the step, the window generator's state, the log so far and what the run
//!   was (sizes, settings, standardization, model hash), written last: a snapshot counts once
//!   this file names it, and the previous step's files are removed after.
//!
//! A diffusion checkpoint's snapshot holds the same under the names `denoiser-resume-<step>.bpk`,
//! `denoiser-optimizer-<step>.bpk` and `denoiser-resume.json` ([`save_denoiser_state`]).
//!
//! Each file is written to a temporary name and renamed, so an interrupted save leaves the
//! previous checkpoint whole.

use crate::autoencoder::{Autoencoder, AutoencoderConfig};
use crate::data::{FeatureLayout, LearnError, Normalizer, Result};
use crate::train::{StepLog, TrainConfig, TrainState, Trained};
use burn::config::Config;
use burn::module::Module;
use burn::optim::{AdamConfig, ModuleOptimizer};
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

/// `resume.json`: where a run stood at its latest snapshot, and what the run was.
#[derive(serde::Serialize, serde::Deserialize)]
struct ResumeDescription {
    format: String,
    autoencoder: serde_json::Value,
    train: TrainConfig,
    normalizer: Normalizer,
    model_hash: String,
    step: usize,
    rng: u64,
    log: Vec<StepLog>,
}

const RESUME_FORMAT: &str = "musculo-learn autoencoder run 1";

/// What a run is: its sizes, settings, standardization (the data) and model.
pub struct RunIdentity<'a> {
    pub config: &'a AutoencoderConfig,
    pub train: &'a TrainConfig,
    pub normalizer: &'a Normalizer,
    pub model_hash: &'a str,
}

/// Writes a snapshot of a run at `step` into `dir`: `{prefix}resume-{step}.bpk` (the network),
/// `{prefix}optimizer-{step}.bpk` (Adam's state), then `{prefix}resume.json` (`description`, the
/// commit point), and removes the network and optimizer files of other steps.
fn write_snapshot<M: Module>(
    dir: &Path,
    prefix: &str,
    step: usize,
    net: &M,
    optimizer: &ModuleOptimizer,
    description: &impl serde::Serialize,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| file_error(dir, e))?;
    let keep = [
        format!("{prefix}resume-{step}.bpk"),
        format!("{prefix}optimizer-{step}.bpk"),
    ];
    write_weights(net, dir, &keep[0])?;
    let moments = dir.join(&keep[1]);
    let partial = dir.join(format!(".{}.partial", keep[1]));
    optimizer
        .save(&partial)
        .map_err(|e| file_error(&moments, e))?;
    std::fs::rename(&partial, &moments).map_err(|e| file_error(&moments, e))?;
    let json = serde_json::to_string(description).map_err(|e| file_error(dir, e))?;
    write_atomic(&dir.join(format!("{prefix}resume.json")), json.as_bytes())?;
    // the snapshot is committed: the files of other steps are stale
    let stale = [format!("{prefix}resume-"), format!("{prefix}optimizer-")];
    let entries = std::fs::read_dir(dir).map_err(|e| file_error(dir, e))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let snapshot_file =
            stale.iter().any(|s| name.starts_with(s.as_str())) && name.ends_with(".bpk");
        if snapshot_file && !keep.contains(&name) {
            std::fs::remove_file(entry.path()).map_err(|e| file_error(&entry.path(), e))?;
        }
    }
    Ok(())
}

/// The network (made by `init`, then read) and Adam's state of the snapshot at `step` in `dir`
/// (see [`write_snapshot`]).
fn read_snapshot<M: Module>(
    dir: &Path,
    prefix: &str,
    step: usize,
    init: impl FnOnce() -> M,
) -> Result<(M, ModuleOptimizer)> {
    let weights = dir.join(format!("{prefix}resume-{step}.bpk"));
    let net = {
        // an initialization draws from the device's generator: not while a seeded one runs
        let _held = crate::INITIALIZATION.lock();
        init()
    }
    .try_load_file(&weights)
    .map_err(|e| file_error(&weights, e))?;
    let moments = dir.join(format!("{prefix}optimizer-{step}.bpk"));
    let optimizer = AdamConfig::new()
        .init()
        .load(&moments)
        .map_err(|e| file_error(&moments, e))?;
    Ok((net, optimizer))
}

/// A snapshot's description at `path` is this run's (`differs`: what is not) and whole (one log
/// entry per step).
fn check_snapshot(path: &Path, differs: Option<&str>, step: usize, logged: usize) -> Result<()> {
    if let Some(what) = differs {
        return Err(file_error(
            path,
            format!(
                "a snapshot of another run: {what} differ; continue it with the same \
                 arguments, or write to another folder"
            ),
        ));
    }
    if logged != step {
        return Err(file_error(
            path,
            format!("step {step} with {logged} log entries"),
        ));
    }
    Ok(())
}

/// Writes the state of run `run` into `dir` (module docs: `resume-<step>.bpk`,
/// `optimizer-<step>.bpk`, then `resume.json`), and removes the files of earlier snapshots.
pub fn save_state(state: &TrainState, run: &RunIdentity, dir: &Path) -> Result<()> {
    let description = ResumeDescription {
        format: RESUME_FORMAT.into(),
        autoencoder: serde_json::from_str(&run.config.to_string())
            .map_err(|e| file_error(dir, e))?,
        train: run.train.clone(),
        normalizer: run.normalizer.clone(),
        model_hash: run.model_hash.to_string(),
        step: state.step,
        rng: state.rng,
        log: state.log.clone(),
    };
    write_snapshot(
        dir,
        "",
        state.step,
        &state.net,
        &state.optimizer,
        &description,
    )
}

/// The state saved in `dir` by run `run`, on `device` (an autodiff device); `None` when `dir`
/// holds no snapshot; an error, naming what differs, when the snapshot is of another run
/// (other sizes, settings, data or model).
pub fn load_state(dir: &Path, run: &RunIdentity, device: &Device) -> Result<Option<TrainState>> {
    let path = dir.join("resume.json");
    if !path.is_file() {
        return Ok(None);
    }
    let d: ResumeDescription =
        read_description(&path, RESUME_FORMAT, |d: &ResumeDescription| &d.format)?;
    let config: serde_json::Value =
        serde_json::from_str(&run.config.to_string()).map_err(|e| file_error(&path, e))?;
    let differs = if d.autoencoder != config {
        Some("the autoencoder's sizes")
    } else if serde_json::to_value(&d.train).ok() != serde_json::to_value(run.train).ok() {
        Some("the training settings")
    } else if d.normalizer != *run.normalizer {
        Some("the data (their standardization)")
    } else if d.model_hash != run.model_hash {
        Some("the model")
    } else {
        None
    };
    check_snapshot(&path, differs, d.step, d.log.len())?;
    let (net, optimizer) = read_snapshot(dir, "", d.step, || run.config.init(device))?;
    Ok(Some(TrainState {
        net,
        optimizer,
        rng: d.rng,
        step: d.step,
        log: d.log,
    }))
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

/// `denoiser-resume.json`: where a denoiser's run stood at its latest snapshot, and what the
/// run was.
#[derive(serde::Serialize, serde::Deserialize)]
struct DenoiserResumeDescription {
    format: String,
    denoiser: serde_json::Value,
    train: crate::diffusion::DiffusionTrainConfig,
    autoencoder: PathBuf,
    text: TextKind,
    /// FNV-1a of the caption vectors' bits, clip by clip.
    texts_hash: String,
    /// The training data's standardization (their fingerprint).
    data: Normalizer,
    step: usize,
    rng: u64,
    log: Vec<(usize, f64, f64)>,
}

const DENOISER_RESUME_FORMAT: &str = "musculo-learn diffusion run 1";

/// What a denoiser's run is: sizes, settings, the autoencoder it encodes with, its captions and
/// data.
pub struct DenoiserRunIdentity<'a> {
    pub config: &'a crate::diffusion::DenoiserConfig,
    pub train: &'a crate::diffusion::DiffusionTrainConfig,
    /// The autoencoder's checkpoint folder.
    pub autoencoder: &'a Path,
    pub text: &'a TextKind,
    /// The caption vectors, one per clip.
    pub texts: &'a [Vec<f32>],
    /// The standardization of the training data ([`Normalizer::of`] the set).
    pub data: &'a Normalizer,
}

impl DenoiserRunIdentity<'_> {
    fn texts_hash(&self) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for v in self.texts.iter().flatten() {
            for b in v.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        format!("{h:016x}")
    }
}

/// Writes the state of a denoiser's run into `dir`: `denoiser-resume-<step>.bpk`,
/// `denoiser-optimizer-<step>.bpk`, then `denoiser-resume.json` (as [`save_state`]).
pub fn save_denoiser_state(
    state: &crate::diffusion::DenoiserState,
    run: &DenoiserRunIdentity,
    dir: &Path,
) -> Result<()> {
    let autoencoder =
        std::fs::canonicalize(run.autoencoder).map_err(|e| file_error(run.autoencoder, e))?;
    let description = DenoiserResumeDescription {
        format: DENOISER_RESUME_FORMAT.into(),
        denoiser: serde_json::from_str(&run.config.to_string()).map_err(|e| file_error(dir, e))?,
        train: run.train.clone(),
        autoencoder,
        text: run.text.clone(),
        texts_hash: run.texts_hash(),
        data: run.data.clone(),
        step: state.step,
        rng: state.rng,
        log: state.log.clone(),
    };
    write_snapshot(
        dir,
        "denoiser-",
        state.step,
        &state.net,
        &state.optimizer,
        &description,
    )
}

/// The state saved in `dir` by the denoiser's run `run`, on `device` (an autodiff device);
/// `None` without a snapshot; an error naming what differs for a snapshot of another run.
pub fn load_denoiser_state(
    dir: &Path,
    run: &DenoiserRunIdentity,
    device: &Device,
) -> Result<Option<crate::diffusion::DenoiserState>> {
    let path = dir.join("denoiser-resume.json");
    if !path.is_file() {
        return Ok(None);
    }
    let d: DenoiserResumeDescription = read_description(
        &path,
        DENOISER_RESUME_FORMAT,
        |d: &DenoiserResumeDescription| &d.format,
    )?;
    let config: serde_json::Value =
        serde_json::from_str(&run.config.to_string()).map_err(|e| file_error(&path, e))?;
    let autoencoder = std::fs::canonicalize(run.autoencoder).ok();
    let differs = if d.denoiser != config {
        Some("the denoiser's sizes")
    } else if serde_json::to_value(&d.train).ok() != serde_json::to_value(run.train).ok() {
        Some("the training settings")
    } else if autoencoder.as_deref() != Some(d.autoencoder.as_path()) {
        Some("the autoencoder folders")
    } else if d.text != *run.text || d.texts_hash != run.texts_hash() {
        Some("the captions")
    } else if d.data != *run.data {
        Some("the data (their standardization)")
    } else {
        None
    };
    check_snapshot(&path, differs, d.step, d.log.len())?;
    let (net, optimizer) = read_snapshot(dir, "denoiser-", d.step, || run.config.init(device))?;
    Ok(Some(crate::diffusion::DenoiserState {
        net,
        optimizer,
        rng: d.rng,
        step: d.step,
        log: d.log,
    }))
}
