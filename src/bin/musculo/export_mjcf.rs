//! `musculo export-mjcf`: write a model as MuJoCo MJCF (the expanded tree, one joint per
//! movable transform axis), listing what MJCF cannot express.

use musculo::model::{Model, mjcf};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim).
    #[arg(required_unless_present = "demo", conflicts_with = "demo")]
    model: Option<PathBuf>,
    /// Export the built-in demonstration model instead of a file.
    #[arg(long)]
    demo: bool,
    /// Output MJCF file.
    #[arg(short, long)]
    output: PathBuf,
    // A body whose inertia violates the triangle inequality is exported with MuJoCo's
    // balanceinertia.
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    let model = match &args.model {
        Some(p) => args.strict.load(p)?,
        None => Model::demo(),
    };
    let export = mjcf::to_mjcf(&model);
    // Write next to the target and rename, so an interrupted run never leaves half a file.
    let tmp = args.output.with_extension("xml.partial");
    let io = |source| musculo::Error::Io {
        path: args.output.clone(),
        source,
    };
    std::fs::write(&tmp, &export.xml).map_err(io)?;
    std::fs::rename(&tmp, &args.output).map_err(io)?;
    eprintln!(
        "wrote {} ({} bodies, {} joints = full coordinates)",
        args.output.display(),
        model.bodies.len() - 1,
        model.n_full()
    );
    if export.notes.is_empty() {
        eprintln!("everything in the model is represented exactly");
    } else {
        eprintln!(
            "{} item(s) MJCF cannot express exactly:",
            export.notes.len()
        );
        for n in &export.notes {
            eprintln!("  note: {n}");
        }
    }
    Ok(())
}
