//! `musculo model build`: the default full-body model from its parameter tables.

use musculo::model::builder::{ModelTables, build_osim};
use std::path::PathBuf;

#[derive(clap::Subcommand)]
pub enum Command {
    /// Build the model file from the CSV tables (every figure with its source).
    Build(BuildArgs),
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
    }
}
