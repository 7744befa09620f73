//! `musculo export-mjcf`: write a model as MuJoCo MJCF (the expanded tree, one joint per
//! movable transform axis), listing what MJCF cannot express.

use musculo::io::output::name_in_folder;
use musculo::mjcf;
use musculo::model::Model;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim).
    #[arg(required_unless_present = "demo", conflicts_with = "demo")]
    model: Option<PathBuf>,
    /// Export the built-in demonstration model instead of a file.
    #[arg(long)]
    demo: bool,
    /// Output MJCF file; a path ending in `/` is a folder (<model name>.xml in it).
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
    let default_name = match &args.model {
        Some(p) => format!("{}.xml", crate::tool::stem(p)),
        None => "demo.xml".to_string(),
    };
    let output = name_in_folder(&args.output, &default_name);
    let inputs: Vec<&Path> = args.model.iter().map(PathBuf::as_path).collect();
    crate::tool::write_output(&output, export.xml.as_bytes(), &inputs)?;
    eprintln!(
        "wrote {} ({} bodies, {} joints = full coordinates)",
        output.display(),
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
