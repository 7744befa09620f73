//! `musculo model build`: the default full-body model from its parameter tables.

use musculo::model::builder::{ModelTables, build_osim};
use std::path::PathBuf;

#[derive(clap::Subcommand)]
pub enum Command {
    /// Build the model file from the CSV tables (every figure with its source).
    Build(BuildArgs),
    /// Scale a model uniformly to a subject's mass and height: lengths by H / H_model,
    /// masses by M / M_model, inertias by both, fiber and tendon slack lengths keeping their
    /// ratio to the musculotendon length at the default pose.
    Scale(ScaleArgs),
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
    /// Scaled model file to write.
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
    /// Model file to write.
    #[arg(short, long, default_value = "models/musculo_fullbody.osim")]
    output: PathBuf,
}

pub fn run(command: &Command) -> Result<(), musculo::Error> {
    match command {
        Command::Build(args) => {
            let tables =
                ModelTables::read(&args.data).map_err(musculo::model::builder::BuildError::from)?;
            let xml = build_osim(&tables)?;
            crate::tool::create_parent_dir(&args.output)?;
            std::fs::write(&args.output, xml).map_err(|source| musculo::Error::Io {
                path: args.output.clone(),
                source,
            })?;
            println!(
                "wrote {} ({} bodies rows, {} joints, {} muscles)",
                args.output.display(),
                tables.bodies.len(),
                tables.joints.len(),
                tables.muscles.len()
            );
            Ok(())
        }
        Command::Scale(args) => {
            let xml =
                std::fs::read_to_string(&args.model).map_err(|source| musculo::Error::Io {
                    path: args.model.clone(),
                    source,
                })?;
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
            crate::tool::create_parent_dir(&args.output)?;
            std::fs::write(&args.output, scaled).map_err(|source| musculo::Error::Io {
                path: args.output.clone(),
                source,
            })?;
            println!(
                "wrote {}: lengths × {:.4}, masses × {:.4} ({} kg, {} m from {:.2} kg, {} m)",
                args.output.display(),
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
