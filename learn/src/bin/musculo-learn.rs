//! `musculo-learn`: the learned module's command-line tool (also reached as `musculo train-ae`
//! and `musculo reconstruct`, which run this program when it is installed beside `musculo`).

use burn::tensor::Device;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use musculo::model::Model;
use musculo_learn::autoencoder::AutoencoderConfig;
use musculo_learn::checkpoint;
use musculo_learn::data::{ClipSet, LearnError};
use musculo_learn::physics::PhysicsWeights;
use musculo_learn::train::{self, TrainConfig};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "musculo-learn",
    version,
    about = "musculo's learned module: a physics-aware motion autoencoder on musculo's tensors"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train the autoencoder on tensor files of `musculo augment` (reconstruction +
    /// Euler–Lagrange and muscle losses); writes a checkpoint folder with the loss curve.
    TrainAe(TrainArgs),
    /// Run a checkpoint over tensor files and report what the reconstruction kept: joint
    /// position error and the Euler–Lagrange residual of the decoded frames (JSON).
    Reconstruct(ReconstructArgs),
}

#[derive(clap::Args)]
struct TrainArgs {
    /// Tensor files or folders of `musculo augment` output.
    #[arg(long, num_args = 1.., required = true)]
    data: Vec<PathBuf>,
    /// The checkpoint folder to write.
    #[arg(long)]
    out: PathBuf,
    /// The .osim model the data were augmented with (default: the built-in full-body model).
    #[arg(long)]
    model: Option<PathBuf>,
    #[arg(long, default_value_t = 2000)]
    steps: usize,
    #[arg(long, default_value_t = 8)]
    batch: usize,
    /// Frames per training window (a multiple of --downsample).
    #[arg(long, default_value_t = 64)]
    window: usize,
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// w_E, the Euler–Lagrange term (0: off).
    #[arg(long, default_value_t = 1.0)]
    euler_weight: f64,
    /// w_M, the muscle term (0: off; ~1.5 ms per evaluated frame on the default model).
    #[arg(long, default_value_t = 0.0)]
    muscle_weight: f64,
    /// The muscle term is evaluated on every k-th frame.
    #[arg(long, default_value_t = 4)]
    muscle_stride: usize,
    /// w_a, the activation-bound penalty.
    #[arg(long, default_value_t = 1.0)]
    bound_weight: f64,
    #[arg(long, default_value_t = 128)]
    d_model: usize,
    #[arg(long, default_value_t = 2)]
    layers: usize,
    #[arg(long, default_value_t = 32)]
    latent: usize,
    #[arg(long, default_value_t = 4)]
    downsample: usize,
}

#[derive(clap::Args)]
struct ReconstructArgs {
    /// The checkpoint folder of `train-ae`.
    #[arg(long)]
    checkpoint: PathBuf,
    /// Tensor files or folders.
    #[arg(long, num_args = 1.., required = true)]
    data: Vec<PathBuf>,
    /// The .osim model (default: the built-in full-body model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Frames per window (default: the training window).
    #[arg(long)]
    window: Option<usize>,
    /// Write the figures here as JSON (default: print them).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::TrainAe(args) => train_ae(args),
        Command::Reconstruct(args) => reconstruct(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn load_model(path: Option<&Path>) -> Result<(Model, String), LearnError> {
    let xml = match path {
        Some(p) => std::fs::read_to_string(p).map_err(|e| LearnError::File {
            path: p.to_path_buf(),
            message: e.to_string(),
        })?,
        None => musculo::DEFAULT_MODEL_OSIM.to_string(),
    };
    let source = path.map_or("<default model>".to_string(), |p| p.display().to_string());
    let model = Model::from_osim_str(&xml, &source)?;
    Ok((model, musculo::augment::output::fnv1a_hex(&xml)))
}

fn train_ae(args: TrainArgs) -> Result<(), LearnError> {
    let (model, hash) = load_model(args.model.as_deref())?;
    let set = ClipSet::read(&args.data, &model)?;
    let config = AutoencoderConfig::new(set.layout.width())
        .with_d_model(args.d_model)
        .with_layers(args.layers)
        .with_latent(args.latent)
        .with_downsample(args.downsample);
    let train = TrainConfig {
        steps: args.steps,
        batch: args.batch,
        window: args.window,
        learning_rate: args.lr,
        seed: args.seed,
        physics: PhysicsWeights {
            euler: args.euler_weight,
            muscle: args.muscle_weight,
            muscle_stride: args.muscle_stride,
        },
        bound_weight: args.bound_weight,
    };
    eprintln!(
        "training on {} clips ({} frames, {} features per frame)",
        set.clips.len(),
        set.frames(),
        set.layout.width()
    );
    let bar = ProgressBar::new(train.steps as u64).with_style(
        ProgressStyle::with_template("train-ae [{bar:30}] {pos}/{len} steps  {msg}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let device = Device::flex().autodiff();
    let trained = train::train_autoencoder(&set, &model, &config, &train, &device, &mut |s| {
        bar.set_position(s.step as u64 + 1);
        bar.set_message(format!(
            "loss {:.4} (recon {:.4}, EL {:.4})",
            s.total, s.reconstruction, s.euler
        ));
    })?;
    bar.finish_and_clear();
    checkpoint::save(&trained, &train, &hash, &args.out)?;
    eprintln!(
        "{} parameters, {} steps in {:.1} s; wrote {}",
        train::parameters(&trained.model),
        train.steps,
        trained.log.last().map_or(0.0, |s| s.seconds),
        args.out.display()
    );
    Ok(())
}

fn reconstruct(args: ReconstructArgs) -> Result<(), LearnError> {
    let (model, hash) = load_model(args.model.as_deref())?;
    let device = Device::flex();
    let loaded = checkpoint::load(&args.checkpoint, &device)?;
    if loaded.model_hash != hash {
        eprintln!(
            "warning: the checkpoint was trained on model {}, this is {hash}",
            loaded.model_hash
        );
    }
    let set = ClipSet::read(&args.data, &model)?;
    let window = args.window.unwrap_or(loaded.train.window);
    let recon = train::reconstruct(&loaded.trained, &set, window, &device)?;
    let quality = train::quality(&set, &recon, &model)?;
    let json = serde_json::to_string_pretty(&quality)
        .map_err(|e| LearnError::invalid("json", e.to_string()))?;
    match &args.out {
        Some(path) => musculo::motion::npy::write_file_atomic(path, json.as_bytes())?,
        None => println!("{json}"),
    }
    Ok(())
}
