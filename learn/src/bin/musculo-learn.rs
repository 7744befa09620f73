//! `musculo-learn`: the learned module's command-line tool (also reached as `musculo train-ae`
//! and `musculo reconstruct`, which run this program when it is installed beside `musculo`).

use burn::module::Module;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use musculo::augment::identity::ModelIdentity;
use musculo::model::Model;
use musculo_learn::autoencoder::AutoencoderConfig;
use musculo_learn::checkpoint;
use musculo_learn::data::{ClipSet, LearnError, write_tensor_file};
use musculo_learn::diffusion::{self, Concept, Control, DenoiserConfig, DiffusionTrainConfig};
use musculo_learn::physics::PhysicsWeights;
use musculo_learn::text::bag_of_words;
use musculo_learn::train::{self, TrainConfig};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "musculo-learn",
    // run as `musculo train-ae …` (src/bin/musculo/learn.rs): usage lines name that command
    bin_name = "musculo",
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
    /// Train the latent diffusion model on the latents of a trained autoencoder, conditioned on
    /// captions (texts.json, HumanML3D texts/, or precomputed embeddings) and random spatial
    /// controls.
    TrainDiffusion(TrainDiffusionArgs),
    /// Generate motions from captions (with conjunction --and and negation --not) and spatial
    /// controls; writes tensor files that `musculo loss`, `evaluate` and `report` read.
    Generate(GenerateArgs),
}

#[derive(clap::Args)]
struct TrainDiffusionArgs {
    /// Where the networks run: cpu, or wgpu, cuda, cuda:N in a build with that feature
    /// (`--features wgpu` / `cuda`).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// The autoencoder checkpoint folder of `train-ae`.
    #[arg(long)]
    autoencoder: PathBuf,
    /// Tensor files or folders of `musculo augment` output (captions beside them).
    #[arg(long, num_args = 1.., required = true)]
    data: Vec<PathBuf>,
    /// The checkpoint folder to write.
    #[arg(long)]
    out: PathBuf,
    /// The .osim model of the data (default: the built-in full-body model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Precomputed caption embeddings: an .npz with one 1-D array per clip name (instead of the
    /// built-in bag of words).
    #[arg(long)]
    text_embeddings: Option<PathBuf>,
    #[arg(long, default_value_t = 3000)]
    steps: usize,
    #[arg(long, default_value_t = 16)]
    batch: usize,
    /// Frames per window (a multiple of the autoencoder's k).
    #[arg(long, default_value_t = 64)]
    window: usize,
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Write the checkpoint every N steps too (0: only at the end), with what continuing the
    /// run needs (network, Adam's state, generator, log).
    #[arg(long, default_value_t = 500)]
    save_every: usize,
    /// Continue the run from the latest snapshot in --out (same inputs and arguments): the
    /// result is the uninterrupted run's. Without a snapshot there the run starts from the
    /// beginning.
    #[arg(long)]
    resume: bool,
}

#[derive(clap::Args)]
struct GenerateArgs {
    /// Where the networks run: cpu, or wgpu, cuda, cuda:N in a build with that feature
    /// (`--features wgpu` / `cuda`).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// The diffusion checkpoint folder of `train-diffusion`.
    #[arg(long)]
    diffusion: PathBuf,
    /// The caption (built-in text encoder).
    #[arg(long)]
    text: Option<String>,
    /// A precomputed caption embedding (.npy, 1-D), for models trained with --text-embeddings.
    #[arg(long)]
    text_embedding: Option<PathBuf>,
    /// Concepts that must also be present (conjunction).
    #[arg(long = "and")]
    and: Vec<String>,
    /// Concepts that must be absent (negation).
    #[arg(long = "not")]
    not: Vec<String>,
    /// Guidance weight of each present concept.
    #[arg(long, default_value_t = 2.5)]
    weight: f32,
    /// Weight of each negated concept (subtracted).
    #[arg(long, default_value_t = 1.0)]
    not_weight: f32,
    /// Frames per motion (a multiple of k).
    #[arg(long, default_value_t = 64)]
    frames: usize,
    /// Motions to generate.
    #[arg(long, default_value_t = 1)]
    count: usize,
    /// DDIM steps.
    #[arg(long, default_value_t = 30)]
    sampling_steps: usize,
    /// Spatial-guidance gradient steps per DDIM step (with --control).
    #[arg(long, default_value_t = 5)]
    guidance: usize,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Spatial control: a tensor file whose frames give the targets.
    #[arg(long)]
    control: Option<PathBuf>,
    /// The controlled modalities (joint_pos, q, qd, qdd, tau, contact_point_force, muscle_act).
    #[arg(long, value_delimiter = ',', default_value = "joint_pos")]
    control_blocks: Vec<String>,
    /// The controlled frames, FIRST:END (end exclusive; default: all).
    #[arg(long)]
    control_frames: Option<String>,
    /// The .osim model the autoencoder was trained on (default: the built-in full-body model):
    /// the body the motions are generated on (recorded in each file) and the control file's.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Output folder: NAME_000.npz, NAME_001.npz, …
    #[arg(long)]
    out: PathBuf,
    /// The files' name stem.
    #[arg(long, default_value = "sample")]
    name: String,
}

#[derive(clap::Args)]
struct TrainArgs {
    /// Where the networks run: cpu, or wgpu, cuda, cuda:N in a build with that feature
    /// (`--features wgpu` / `cuda`).
    #[arg(long, default_value = "cpu")]
    device: String,
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
    /// Write the checkpoint every N steps too (0: only at the end), with what continuing the
    /// run needs (network, Adam's state, window generator, log).
    #[arg(long, default_value_t = 500)]
    save_every: usize,
    /// Continue the run from the latest snapshot in --out (same data and arguments): the result
    /// is the uninterrupted run's. Without a snapshot there the run starts from the beginning.
    #[arg(long)]
    resume: bool,
}

#[derive(clap::Args)]
struct ReconstructArgs {
    /// Where the networks run: cpu, or wgpu, cuda, cuda:N in a build with that feature
    /// (`--features wgpu` / `cuda`).
    #[arg(long, default_value = "cpu")]
    device: String,
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
        Command::TrainDiffusion(args) => train_diffusion(args),
        Command::Generate(args) => generate(args),
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
    let (model, hash, _) = load_model_with_identity(path)?;
    Ok((model, hash))
}

/// The model at `path` (the built-in model without it), its file hash, and the identity of a
/// motion generated on it ([`musculo_learn::data::generated_identity`]).
fn load_model_with_identity(
    path: Option<&Path>,
) -> Result<(Model, String, ModelIdentity), LearnError> {
    let (xml, source) = match path {
        Some(p) => (
            std::fs::read_to_string(p).map_err(|e| LearnError::File {
                path: p.to_path_buf(),
                message: e.to_string(),
            })?,
            p.display().to_string(),
        ),
        // named as `musculo augment` names it, so the identities agree
        None => (
            musculo::DEFAULT_MODEL_OSIM.to_string(),
            "models/musculo_fullbody.osim".to_string(),
        ),
    };
    let model = Model::from_osim_str(&xml, &source)?;
    let identity = musculo_learn::data::generated_identity(&model, &xml, &source);
    Ok((model, musculo::augment::output::fnv1a_hex(&xml), identity))
}

/// The clips of `data` for `model` (read from `path`, the built-in model without it; file
/// hash `hash`: a clip of another model is refused), each on its own body rebuilt from that
/// file; says on stderr how many clips could not be given a body (no model identity, and a
/// manifest listing them as variants with a changed body) and are left out of the physics terms.
fn read_set(
    data: &[PathBuf],
    model: &Model,
    hash: &str,
    path: Option<&Path>,
) -> Result<ClipSet, LearnError> {
    let bodies = musculo::augment::identity::Bodies::new(path)?;
    let set = ClipSet::read_with(data, model, Some(hash), &bodies)?;
    let other = set.clips.iter().filter(|c| c.body.is_none()).count();
    if other > 0 {
        eprintln!(
            "warning: {other} of {} clip(s) record no model identity and are variants with a \
             changed body (manifest.json): they are reconstructed but left out of the physics \
             terms and their figures (augment them again to record their body)",
            set.clips.len()
        );
    }
    Ok(set)
}

/// The progress bar of training `name`, at the step where the run starts; says on stderr where
/// a `--resume` run starts: at the snapshot's step, or from the beginning.
fn start_bar(
    name: &str,
    resume: bool,
    out: &Path,
    snapshot_step: Option<usize>,
    steps: usize,
) -> ProgressBar {
    match snapshot_step {
        Some(step) => eprintln!(
            "continuing the run in {} from step {step} of {steps}",
            out.display()
        ),
        None if resume => eprintln!("no snapshot in {}: starting the run", out.display()),
        None => {}
    }
    let bar = ProgressBar::new(steps as u64).with_style(
        ProgressStyle::with_template(&format!(
            "{name} [{{bar:30}}] {{pos}}/{{len}} steps  {{msg}}  ETA {{eta}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_position(snapshot_step.unwrap_or(0) as u64);
    bar.reset_eta();
    bar
}

fn train_ae(args: TrainArgs) -> Result<(), LearnError> {
    let (model, hash) = load_model(args.model.as_deref())?;
    let set = read_set(&args.data, &model, &hash, args.model.as_deref())?;
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
    let device = musculo_learn::device::parse(&args.device)?.autodiff();
    let normalizer = musculo_learn::data::Normalizer::of(&set);
    let run = checkpoint::RunIdentity {
        config: &config,
        train: &train,
        normalizer: &normalizer,
        model_hash: &hash,
    };
    let saved = match args.resume {
        true => checkpoint::load_state(&args.out, &run, &device)?,
        false => None,
    };
    let bar = start_bar(
        "train-ae",
        args.resume,
        &args.out,
        saved.as_ref().map(|s| s.step),
        train.steps,
    );
    let state = saved.unwrap_or_else(|| train::TrainState::new(&config, &train, &device));
    let mut saved: Result<(), LearnError> = Ok(());
    let trained = train::continue_training(
        &set,
        &model,
        &config,
        &train,
        &device,
        state,
        &mut |state| {
            let Some(s) = state.log.last() else { return };
            bar.set_position(state.step as u64);
            bar.set_message(format!(
                "loss {:.4} (recon {:.4}, EL {:.4})",
                s.total, s.reconstruction, s.euler
            ));
            if args.save_every > 0
                && state.step % args.save_every == 0
                && state.step < train.steps
                && saved.is_ok()
            {
                let snapshot = train::Trained {
                    model: state.net.valid(),
                    config: config.clone(),
                    normalizer: normalizer.clone(),
                    layout: set.layout.clone(),
                    log: state.log.clone(),
                };
                saved = checkpoint::save(&snapshot, &train, &hash, &args.out)
                    .and_then(|()| checkpoint::save_state(state, &run, &args.out));
            } else if state.step == train.steps && saved.is_ok() {
                // the finished run's state: `--resume` then has nothing left to do
                saved = checkpoint::save_state(state, &run, &args.out);
            }
        },
    )?;
    saved?;
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
    let device = musculo_learn::device::parse(&args.device)?;
    let loaded = checkpoint::load(&args.checkpoint, &device)?;
    if loaded.model_hash != hash {
        eprintln!(
            "warning: the checkpoint was trained on model {}, this is {hash}",
            loaded.model_hash
        );
    }
    let set = read_set(&args.data, &model, &hash, args.model.as_deref())?;
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

fn train_diffusion(args: TrainDiffusionArgs) -> Result<(), LearnError> {
    let (model, hash) = load_model(args.model.as_deref())?;
    let device = musculo_learn::device::parse(&args.device)?;
    let loaded = checkpoint::load(&args.autoencoder, &device)?;
    let set = read_set(&args.data, &model, &hash, args.model.as_deref())?;
    let (texts, kind) = match &args.text_embeddings {
        Some(path) => {
            let arrays = musculo::motion::npy::read_npz_f32(path)?;
            let mut texts = Vec::new();
            for clip in &set.clips {
                let (_, a) = arrays
                    .iter()
                    .find(|(k, _)| k == &clip.name)
                    .ok_or_else(|| LearnError::File {
                        path: path.clone(),
                        message: format!("has no embedding for clip {}", clip.name),
                    })?;
                texts.push(a.iter().copied().collect::<Vec<f32>>());
            }
            let width = texts[0].len();
            (texts, checkpoint::TextKind::Precomputed(width))
        }
        None => {
            let mut texts = Vec::new();
            for clip in &set.clips {
                texts.push(bag_of_words(&clip.caption));
            }
            (texts, checkpoint::TextKind::BuiltIn)
        }
    };
    let ae = &loaded.trained;
    let config = DenoiserConfig::new(
        ae.config.latent,
        ae.config.features,
        ae.config.downsample,
        texts[0].len(),
    );
    let train = DiffusionTrainConfig {
        steps: args.steps,
        batch: args.batch,
        window: args.window,
        learning_rate: args.lr,
        seed: args.seed,
    };
    let data = musculo_learn::data::Normalizer::of(&set);
    let run = checkpoint::DenoiserRunIdentity {
        config: &config,
        train: &train,
        autoencoder: &args.autoencoder,
        text: &kind,
        texts: &texts,
        data: &data,
    };
    let training = device.clone().autodiff();
    let saved = match args.resume {
        true => checkpoint::load_denoiser_state(&args.out, &run, &training)?,
        false => None,
    };
    let bar = start_bar(
        "train-diffusion",
        args.resume,
        &args.out,
        saved.as_ref().map(|s| s.step),
        train.steps,
    );
    let state = saved.unwrap_or_else(|| diffusion::DenoiserState::new(&config, &train, &training));
    let mut saved: Result<(), LearnError> = Ok(());
    let trained = diffusion::continue_denoiser(
        &set,
        &ae.model,
        &ae.normalizer,
        &texts,
        &config,
        &train,
        &training,
        state,
        &mut |s| {
            bar.set_position(s.step as u64 + 1);
            bar.set_message(format!("loss {:.4}", s.loss));
            let done = s.step + 1;
            if args.save_every > 0
                && done % args.save_every == 0
                && done < train.steps
                && saved.is_ok()
            {
                let snapshot = diffusion::TrainedDenoiser {
                    model: s.state.net.valid(),
                    config: config.clone(),
                    latent_scale: s.latent_scale,
                    log: s.state.log.clone(),
                };
                saved = checkpoint::save_denoiser(
                    &snapshot,
                    &train,
                    &args.autoencoder,
                    kind.clone(),
                    set.rate_hz,
                    &args.out,
                )
                .and_then(|()| checkpoint::save_denoiser_state(s.state, &run, &args.out));
            } else if done == train.steps && saved.is_ok() {
                // the finished run's state: `--resume` then has nothing left to do
                saved = checkpoint::save_denoiser_state(s.state, &run, &args.out);
            }
        },
    )?;
    saved?;
    bar.finish_and_clear();
    checkpoint::save_denoiser(
        &trained,
        &train,
        &args.autoencoder,
        kind,
        set.rate_hz,
        &args.out,
    )?;
    eprintln!(
        "{} parameters, {} steps in {:.1} s; wrote {}",
        trained.model.num_params(),
        train.steps,
        trained.log.last().map_or(0.0, |s| s.2),
        args.out.display()
    );
    Ok(())
}

fn generate(args: GenerateArgs) -> Result<(), LearnError> {
    let device = musculo_learn::device::parse(&args.device)?;
    let loaded = checkpoint::load_denoiser(&args.diffusion, &device)?;
    let ae = checkpoint::load(&loaded.autoencoder, &device)?;
    let layout = &ae.trained.layout;
    let d = layout.width();
    let vector = |text: &str| -> Result<Vec<f32>, LearnError> {
        match loaded.text {
            checkpoint::TextKind::BuiltIn => Ok(bag_of_words(text)),
            checkpoint::TextKind::Precomputed(_) => Err(LearnError::invalid(
                "--text",
                "this model was trained on precomputed embeddings: give --text-embedding FILE.npy (--and/--not need the built-in text encoder)",
            )),
        }
    };
    let mut concepts = Vec::new();
    match (&args.text, &args.text_embedding) {
        (Some(t), None) => concepts.push(Concept {
            text: vector(t)?,
            weight: args.weight,
        }),
        (None, Some(path)) => {
            let a = musculo::motion::npy::read_array_f32(path)?;
            concepts.push(Concept {
                text: a.iter().copied().collect(),
                weight: args.weight,
            });
        }
        (None, None) => {}
        (Some(_), Some(_)) => {
            return Err(LearnError::invalid(
                "--text",
                "give --text or --text-embedding, not both",
            ));
        }
    }
    for t in &args.and {
        concepts.push(Concept {
            text: vector(t)?,
            weight: args.weight,
        });
    }
    for t in &args.not {
        concepts.push(Concept {
            text: vector(t)?,
            weight: -args.not_weight,
        });
    }
    // the body the motions are generated on: the model the autoencoder was trained on
    let (model, hash, identity) = load_model_with_identity(args.model.as_deref())?;
    if ae.model_hash != hash {
        return Err(LearnError::invalid(
            "--model",
            format!(
                "the autoencoder was trained on model {}, this is {hash}: pass the model it was \
                 trained on with --model",
                ae.model_hash
            ),
        ));
    }
    let mut control = Control::none(args.frames, d);
    if let Some(path) = &args.control {
        let source = ClipSet::read(std::slice::from_ref(path), &model)?;
        let clip = &source.clips[0];
        if source.layout != *layout {
            return Err(LearnError::File {
                path: path.clone(),
                message: "its layout differs from the model's".into(),
            });
        }
        let range = match &args.control_frames {
            None => 0..args.frames,
            Some(spec) => {
                let (a, b) = spec.split_once(':').ok_or_else(|| {
                    LearnError::invalid("--control-frames", format!("{spec}: expected FIRST:END"))
                })?;
                let parse = |v: &str| {
                    v.trim().parse::<usize>().map_err(|e| {
                        LearnError::invalid("--control-frames", format!("{spec}: {e}"))
                    })
                };
                parse(a)?..parse(b)?
            }
        };
        if range.start >= range.end || range.end > args.frames.min(clip.frames) {
            return Err(LearnError::invalid(
                "--control-frames",
                format!(
                    "{range:?} is not within the {} generated frames and the control's {}",
                    args.frames, clip.frames
                ),
            ));
        }
        for block in &args.control_blocks {
            if layout.block(block).is_empty() {
                return Err(LearnError::invalid(
                    "--control-blocks",
                    format!("unknown block {block}"),
                ));
            }
            control.set_block(layout, block, range.clone(), &clip.y);
        }
    }
    let y = diffusion::sample(
        &loaded.denoiser,
        &ae.trained.model,
        &ae.trained.normalizer,
        &concepts,
        &control,
        args.frames,
        args.count,
        args.sampling_steps,
        args.guidance,
        args.seed,
        &device,
    )?;
    std::fs::create_dir_all(&args.out).map_err(|e| LearnError::File {
        path: args.out.clone(),
        message: e.to_string(),
    })?;
    for k in 0..args.count {
        let path = args.out.join(format!("{}_{k:03}.npz", args.name));
        write_tensor_file(
            &path,
            layout,
            &y[k * args.frames * d..(k + 1) * args.frames * d],
            loaded.rate_hz,
            &identity,
        )?;
    }
    eprintln!(
        "wrote {} motions of {} frames to {}",
        args.count,
        args.frames,
        args.out.display()
    );
    Ok(())
}
