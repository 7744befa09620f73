//! `musculo id`: OpenSim's Inverse Dynamics tool — generalized forces from a motion and
//! its external loads, written as an OpenSim .sto file.

use crate::tool::{FrameProgress, missing, read_coordinates};
use musculo::io::output::{OutputSet, name_in_folder};
use musculo::io::setup::InverseDynamicsSetup;
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::{InverseDynamicsOptions, inverse_dynamics};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim). Default: the setup's model_file.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Coordinates over time (.mot or .sto, e.g. an IK result). Default: the setup's
    /// coordinates_file.
    #[arg(long)]
    coordinates: Option<PathBuf>,
    /// ExternalLoads file (.xml) naming the forces and their data file. Default: the setup's
    /// external_loads_file (none if neither).
    #[arg(long)]
    external_loads: Option<PathBuf>,
    /// An OpenSim InverseDynamicsTool setup file; its settings apply unless a flag overrides
    /// them (paths in it are relative to its directory).
    #[arg(long)]
    setup: Option<PathBuf>,
    /// Low-pass cutoff (Hz) for the coordinates; a negative value means no filtering.
    /// Default: the setup's lowpass_cutoff_frequency_for_coordinates, else no filtering.
    #[arg(long, allow_negative_numbers = true, value_name = "HZ", value_parser = crate::tool::lowpass_hz)]
    lowpass: Option<f64>,
    /// Time range START END (s). Default: the setup's time_range, else the whole motion.
    #[arg(
        long,
        num_args = 2,
        value_names = ["START", "END"],
        allow_negative_numbers = true,
        value_parser = crate::tool::time_s
    )]
    time_range: Option<Vec<f64>>,
    /// Output .sto file; a path ending in `/` is a folder (the setup's output_gen_force_file,
    /// else inverse_dynamics.sto, in it). It may not be an input. Default: the setup's
    /// results_directory/output_gen_force_file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    strict: crate::warnings::Strict,
    /// Hold the model's coordinates that the coordinates file has no column for at their
    /// default values (to apply another model's motion by coordinate name) instead of
    /// stopping with an error.
    #[arg(long)]
    missing_coordinates_at_default: bool,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    let setup = args
        .setup
        .as_deref()
        .map(InverseDynamicsSetup::read)
        .transpose()?;
    if let Some(s) = &setup {
        for w in &s.warnings {
            eprintln!("warning: {w}");
        }
    }
    let model_path = args
        .model
        .clone()
        .or_else(|| setup.as_ref()?.model_file.clone())
        .ok_or_else(|| missing("--model", "model file"))?;
    let coordinates_path = args
        .coordinates
        .clone()
        .or_else(|| setup.as_ref()?.coordinates_file.clone())
        .ok_or_else(|| missing("--coordinates", "coordinates file"))?;
    let loads_path = args
        .external_loads
        .clone()
        .or_else(|| setup.as_ref()?.external_loads_file.clone());
    let output = match (&args.output, setup.as_ref()) {
        (Some(o), s) => {
            let name = s.and_then(|s| s.output_gen_force_file.clone());
            name_in_folder(o, name.as_deref().unwrap_or("inverse_dynamics.sto"))
        }
        (None, s) => s
            .and_then(InverseDynamicsSetup::output_path)
            .ok_or_else(|| missing("--output", "output file"))?,
    };
    let mut options = setup
        .as_ref()
        .map(InverseDynamicsOptions::from_setup)
        .unwrap_or_default();
    if let Some(hz) = args.lowpass {
        options.lowpass_hz = (hz > 0.0).then_some(hz);
    }
    if let Some(r) = &args.time_range {
        options.time_range = Some([r[0], r[1]]);
    }

    let model = args.strict.load_movable(&model_path)?;
    let coordinates = read_coordinates(
        &model,
        &coordinates_path,
        args.missing_coordinates_at_default,
    )?;
    let loads = loads_path
        .as_deref()
        .map(|p| ExternalLoadSet::read(&model, p))
        .transpose()?;
    if let Some(l) = &loads {
        crate::warnings::print(&l.warnings);
    }
    let data_path = loads.as_ref().map(|l| PathBuf::from(&l.data_source));
    let inputs = [
        Some(&model_path),
        Some(&coordinates_path),
        loads_path.as_ref(),
        data_path.as_ref(),
        args.setup.as_ref(),
    ];
    let mut outputs = OutputSet::new(inputs.into_iter().flatten().map(PathBuf::as_path));
    outputs.check(&output)?;

    let progress = FrameProgress::new("inverse dynamics");
    let result = inverse_dynamics(
        &model,
        &coordinates,
        &coordinates_path.display().to_string(),
        loads.as_ref(),
        &options,
        &mut |done, total| progress.update(done, total),
    );
    progress.finish();
    let out = result?;
    for w in &out.warnings {
        eprintln!("warning: {w}");
    }
    outputs.add(&output, out.table.to_file_string()?.as_bytes())?;
    crate::tool::commit(outputs)?;
    let t = &out.table;
    eprintln!(
        "wrote {}: {} rows ({:.6} – {:.6} s) × {} generalized forces{}{}",
        output.display(),
        t.n_rows(),
        t.time[0],
        t.time[t.n_rows() - 1],
        t.n_columns(),
        match options.lowpass_hz {
            Some(hz) => format!(", coordinates low-pass filtered at {hz} Hz"),
            None => String::new(),
        },
        match &loads {
            Some(l) => format!(", {} external force(s)", l.forces.len()),
            None => String::new(),
        }
    );
    Ok(())
}
