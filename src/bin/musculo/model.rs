//! `musculo model build`: the default full-body model from its parameter tables;
//! `musculo model scale`: uniform scaling; `musculo model reserves`: the residual and reserve
//! actuators static optimization needs, as a force-set file.

use musculo::io::output::name_in_folder;
use musculo::model::builder::{ModelTables, build_osim};
use std::path::{Path, PathBuf};

/// The files of the parameter-table folder (which the built model may not overwrite).
fn table_files(folder: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(folder)
        .map(|entries| entries.flatten().map(|e| e.path()).collect())
        .unwrap_or_default()
}

#[derive(clap::Subcommand)]
pub enum Command {
    /// Build the model file from the CSV tables (every figure with its source).
    Build(BuildArgs),
    /// Scale a model uniformly to a subject's mass and height: lengths by H / H_model,
    /// masses by M / M_model, inertias by both, fiber and tendon slack lengths keeping their
    /// ratio to the musculotendon length at the default pose.
    Scale(ScaleArgs),
    /// Write the residual and reserve actuators for static optimization as an OpenSim
    /// force-set file: on the floating base three forces and three torques at its centre of
    /// mass (FX … MZ, as OpenSim's gait examples), one CoordinateActuator per other
    /// independent coordinate; controls unbounded, so every frame can be balanced.
    Reserves(ReservesArgs),
    /// Multiply every muscle's maximum isometric force by one factor (nothing else in the
    /// file changes), as OpenSim users strengthen a model for tasks beyond walking.
    Strengthen(StrengthenArgs),
}

#[derive(clap::Args)]
pub struct StrengthenArgs {
    /// OpenSim 4.x model file (.osim).
    model: PathBuf,
    /// The factor on every muscle's maximum isometric force.
    #[arg(long, value_name = "K", allow_negative_numbers = true)]
    factor: f64,
    /// Model file to write; a path ending in `/` is a folder (the input's file name in it).
    /// It may not be the input model.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

#[derive(clap::Args)]
pub struct ReservesArgs {
    /// OpenSim 4.x model file (.osim).
    #[arg(default_value = "models/musculo_fullbody.osim")]
    model: PathBuf,
    /// Optimal force of each joint reserve (N·m or N).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    reserve_optimal_force: f64,
    /// Optimal force of each floating-base residual (N or N·m).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    residual_optimal_force: f64,
    /// Force-set file to write (a path ending in `/` is a folder). Default: the model's path
    /// with `_reserves.xml` for `.osim`.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

#[derive(clap::Args)]
pub struct ScaleArgs {
    /// OpenSim 4.x model file (.osim).
    model: PathBuf,
    /// Subject mass (kg).
    #[arg(long)]
    mass: f64,
    /// Subject standing height (m).
    #[arg(long)]
    height: f64,
    /// The model's own standing height (m); read from a musculo-built model's credits
    /// ("reference subject … kg, … m") when not given.
    #[arg(long)]
    model_height: Option<f64>,
    /// Scaled model file to write; a path ending in `/` is a folder (the input's file name in
    /// it). It may not be the input model.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

/// The height in "reference subject 75 kg, 1.75 m)" of a musculo-built model's credits.
fn credited_height(xml: &str) -> Option<f64> {
    let start = xml.find("reference subject ")? + "reference subject ".len();
    let rest = &xml[start..];
    let comma = rest.find(", ")?;
    let after = &rest[comma + 2..];
    after.split(" m").next()?.trim().parse().ok()
}

#[derive(clap::Args)]
pub struct BuildArgs {
    /// Folder of the parameter tables.
    #[arg(long, default_value = "data/model")]
    data: PathBuf,
    /// Model file to write; a path ending in `/` is a folder (musculo_fullbody.osim in it).
    #[arg(short, long, default_value = "models/musculo_fullbody.osim")]
    output: PathBuf,
}

/// `models/x.osim` → `models/x_reserves.xml`.
fn reserves_path(model: &std::path::Path) -> PathBuf {
    let stem = model.file_stem().map(|s| s.to_string_lossy().into_owned());
    model.with_file_name(format!("{}_reserves.xml", stem.unwrap_or_default()))
}

fn reserves(args: &ReservesArgs) -> Result<(), musculo::Error> {
    use musculo::model::reserves::{ReserveOptions, reserve_actuators, reserve_force_set};
    let model = args.strict.load(&args.model)?;
    let options = ReserveOptions {
        reserve_optimal_force: args.reserve_optimal_force,
        residual_optimal_force: args.residual_optimal_force,
    };
    // the header names the model by its file name, so the text does not depend on the folder
    let label = args.model.file_name().map_or_else(
        || args.model.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let xml = reserve_force_set(&model, &label, &options)?;
    let count = reserve_actuators(&model, &options)?.len();
    let output = match &args.output {
        Some(o) => name_in_folder(o, &reserves_path(Path::new(&label)).to_string_lossy()),
        None => reserves_path(&args.model),
    };
    crate::tool::write_output(&output, xml.as_bytes(), &[&args.model])?;
    println!(
        "wrote {}: {count} actuators for the {} independent coordinates of {}",
        output.display(),
        model.nq(),
        args.model.display()
    );
    Ok(())
}

fn strengthen(args: &StrengthenArgs) -> Result<(), musculo::Error> {
    let xml = musculo::text::read_text(&args.model)?;
    let source = args.model.display().to_string();
    args.strict.load_str(&xml, &source)?;
    let (text, count) =
        musculo::solve::scale::strength::scale_muscle_strength(&xml, &source, args.factor)
            .map_err(|e| match e {
                musculo::Error::InvalidArgument { message, .. } => {
                    musculo::Error::InvalidArgument {
                        argument: "--factor",
                        message,
                    }
                }
                other => other,
            })?;
    let default_name = args.model.file_name().unwrap_or_default().to_string_lossy();
    let output = name_in_folder(&args.output, &default_name);
    crate::tool::write_output(&output, text.as_bytes(), &[&args.model])?;
    println!(
        "wrote {}: the maximum isometric force of {count} muscles × {}",
        output.display(),
        args.factor
    );
    Ok(())
}

pub fn run(command: &Command) -> Result<(), musculo::Error> {
    match command {
        Command::Reserves(args) => reserves(args),
        Command::Strengthen(args) => strengthen(args),
        Command::Build(args) => {
            let tables =
                ModelTables::read(&args.data).map_err(musculo::model::builder::BuildError::from)?;
            let xml = build_osim(&tables)?;
            let output = name_in_folder(&args.output, "musculo_fullbody.osim");
            let tables_read = table_files(&args.data);
            let inputs: Vec<&Path> = tables_read.iter().map(PathBuf::as_path).collect();
            crate::tool::write_output(&output, xml.as_bytes(), &inputs)?;
            println!(
                "wrote {} ({} bodies rows, {} joints, {} muscles)",
                output.display(),
                tables.bodies.len(),
                tables.joints.len(),
                tables.muscles.len()
            );
            Ok(())
        }
        Command::Scale(args) => {
            let xml = musculo::text::read_text(&args.model)?;
            let source = args.model.display().to_string();
            let model = args.strict.load_str(&xml, &source)?;
            let model_height = match args.model_height.or_else(|| credited_height(&xml)) {
                Some(h) => h,
                None => {
                    return Err(musculo::Error::InvalidArgument {
                        argument: "--model-height",
                        message: format!("{source} does not state its height; pass --model-height"),
                    });
                }
            };
            let factors = musculo::solve::scale::ScaleFactors::for_subject(
                &model,
                model_height,
                args.mass,
                args.height,
            )?;
            let mut scaled = musculo::solve::scale::scale_uniform(&xml, &source, &model, factors)?;
            // a musculo-built model states its subject: keep that true
            if let Some(at) = scaled.find("reference subject ") {
                if let Some(end) = scaled[at..].find(" m)").map(|e| at + e + 2) {
                    let stated = format!("reference subject {} kg, {} m", args.mass, args.height);
                    scaled.replace_range(at..end, &stated);
                }
            }
            let default_name = args.model.file_name().unwrap_or_default().to_string_lossy();
            let output = name_in_folder(&args.output, &default_name);
            crate::tool::write_output(&output, scaled.as_bytes(), &[&args.model])?;
            println!(
                "wrote {}: lengths × {:.4}, masses × {:.4} ({} kg, {} m from {:.2} kg, {} m)",
                output.display(),
                factors.length,
                factors.mass,
                args.mass,
                args.height,
                model.total_mass(),
                model_height
            );
            Ok(())
        }
    }
}
