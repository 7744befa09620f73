//! The `musculo` command-line tool: a thin layer over the library.

mod augment;
mod check;
mod evaluate;
mod export_mjcf;
mod id;
mod ik;
mod inspect;
mod learn;
mod loss;
mod model;
mod muscles;
mod report;
mod scale;
mod so;
mod tool;
mod warnings;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// `musculo --version`: the version and the file formats (with their versions) it reads and
/// writes.
const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    "\n",
    "reads:\n",
    "  models       OpenSim 4.x .osim (OpenSimDocument Version >= 40000; OpenSim 3 models are \
     refused: save them in OpenSim 4 first)\n",
    "  OpenSim xml  force-set, ExternalLoads, marker-set and tool setup files (IK, ID, Analyze/SO, \
     Scale) of OpenSim 2.3 to 4.x\n",
    "  tables       .sto/.mot (version=1 and OpenSim 4 headers, SIMM .mot), .trc markers\n",
    "  motion       C3D (force platforms of types 1-4), BVH, HumanML3D and KIT-ML .npy, .npy/.npz\n",
    "writes:\n",
    "  .osim (Version 40000), .sto/.mot (OpenSim 4 headers), MuJoCo MJCF (MuJoCo 3.x), .npz\n",
    "changes: CHANGELOG.md in musculo's source, beside README.md; the manual: docs/ (an mdBook)",
);

#[derive(Parser)]
#[command(
    name = "musculo",
    version = VERSION,
    about = "Musculoskeletal dynamics for motion datasets"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Read a model and print its bodies, joints, coordinates, muscles, total mass and
    /// anything musculo does not use.
    Inspect(inspect::Args),
    /// Write the model as MuJoCo MJCF: one hinge or slide per movable transform axis, so
    /// MuJoCo's coordinates are musculo's full coordinates.
    ExportMjcf(export_mjcf::Args),
    /// Musculotendon lengths, moment arms and maximum isometric moments along a motion, as
    /// OpenSim-style .sto files.
    Muscles(muscles::Args),
    /// Inverse dynamics as OpenSim's tool computes it: generalized forces from coordinates
    /// (filtered and splined like OpenSim) and external loads, written as a .sto file.
    Id(id::Args),
    /// Inverse kinematics: the model's coordinates that best fit a motion's markers or joint
    /// centres (OpenSim IK setups; HumanML3D, KIT-ML, BVH, C3D and TRC files), written as a
    /// .mot with the marker errors beside it.
    Ik(ik::Args),
    /// Static optimization as OpenSim's tool computes it: per frame, the muscle activations
    /// and reserve/residual actuator controls of least Σ xᵖ that produce the inverse-dynamics
    /// generalized forces; writes PREFIX_activation.sto and PREFIX_force.sto.
    So(so::Args),
    /// OpenSim's Scale tool from a setup file: scale factors from marker-pair measurements
    /// and manual factors, mass scaling, marker placement on a static trial.
    Scale(scale::Args),
    /// Model files: build the default full-body model from its tables (data/model), scale or
    /// strengthen a model, write its reserves (residual and reserve actuators).
    #[command(subcommand)]
    Model(model::Command),
    /// Biomechanics unit checks: connectivity, masses and inertias, coordinate ranges,
    /// muscle parameters, paths over the range of motion, agonist moment-arm signs and
    /// maximum isometric joint moments against published ranges. Exits non-zero when a
    /// check fails.
    Check(check::Args),
    /// Augment a motion dataset: per clip, joint torques, ground contact forces and muscle
    /// activations of the model (IK, inverse dynamics, contacts, static optimization), as
    /// float32 .npz tensors with a manifest and statistics. Resumable and shardable.
    Augment(augment::Args),
    /// Combine the shards of an `augment --shard K/N` run into one manifest and statistics;
    /// like `augment`, exits non-zero (naming them) when clips failed.
    Merge(augment::MergeArgs),
    /// The Euler–Lagrange residual M q̈ + C q̇ + G − τ − J_cᵀλ of a tensor file (an augmented
    /// clip or a generated motion): L_euler, per-frame and per-coordinate figures.
    Loss(loss::Args),
    /// Physical-plausibility metrics of tensor files (augmented clips or generated motions):
    /// foot skating, floating, penetration, contact-force and joint-actuation errors, muscle
    /// limits, Euler–Lagrange residual and control error, per clip and for the set in the
    /// columns of FlexMotion's tables.
    Evaluate(evaluate::Args),
    /// HTML pages of tensor files: per clip its joint angles, torques, ground reactions,
    /// contacts, muscle activations and reserves; a dataset page with the metrics'
    /// distributions and the worst clips.
    Report(report::Args),
    /// Train the physics-aware motion autoencoder on tensor files (runs `musculo-learn
    /// train-ae`, the learned module: `cargo build --release -p musculo-learn`).
    TrainAe(learn::Args),
    /// Reconstruct tensor files with a trained autoencoder and report the joint-position error
    /// and the Euler–Lagrange residual (runs `musculo-learn reconstruct`).
    Reconstruct(learn::Args),
    /// Train the latent diffusion model (captions and spatial controls) on a trained
    /// autoencoder's latents (runs `musculo-learn train-diffusion`).
    TrainDiffusion(learn::Args),
    /// Generate motions from captions (--and, --not) and spatial controls as tensor files
    /// (runs `musculo-learn generate`).
    Generate(learn::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::ExportMjcf(args) => export_mjcf::run(&args),
        Command::Muscles(args) => muscles::run(&args),
        Command::Id(args) => id::run(&args),
        Command::Ik(args) => ik::run(&args),
        Command::So(args) => so::run(&args),
        Command::Scale(args) => scale::run(&args),
        Command::Model(command) => model::run(&command),
        Command::Augment(args) => match augment::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
        Command::Merge(args) => match augment::merge(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
        Command::Loss(args) => loss::run(&args),
        Command::TrainAe(args) => return learn::run("train-ae", &args),
        Command::Reconstruct(args) => return learn::run("reconstruct", &args),
        Command::TrainDiffusion(args) => return learn::run("train-diffusion", &args),
        Command::Generate(args) => return learn::run("generate", &args),
        Command::Report(args) => match report::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
        Command::Evaluate(args) => match evaluate::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
        Command::Check(args) => match check::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", warnings::shorten(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}
