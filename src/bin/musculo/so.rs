//! `musculo so`: OpenSim's static optimization (Analyze tool with a StaticOptimization
//! analysis) — muscle activations and actuator forces per frame, written as OpenSim's
//! `_activation.sto` and `_force.sto`.

use crate::tool::{FrameProgress, missing, read_coordinates};
use crate::warnings::{FrameWarning, frame_warnings};
use musculo::io::output::{OutputSet, name_in_folder, with_suffix};
use musculo::io::setup::{AnalyzeSetup, StaticOptimizationSetup};
use musculo::model::Model;
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::static_optimization::{
    SoRun, SoRunOptions, SoStatus, StaticOptimization, StaticOptimizationOptions,
    run_static_optimization,
};
use std::path::PathBuf;
use std::time::Instant;

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
    /// Force-set file(s) (.xml) with reserve and residual actuators, added to the model's
    /// forces. Default: the setup's force_set_files.
    #[arg(long, num_args = 1..)]
    actuators: Vec<PathBuf>,
    /// An OpenSim AnalyzeTool setup file with a StaticOptimization analysis; its settings
    /// apply unless a flag overrides them (paths in it are relative to its directory).
    #[arg(long)]
    setup: Option<PathBuf>,
    /// Low-pass cutoff (Hz) for the coordinates; a negative value means no filtering.
    /// Default: the setup's lowpass_cutoff_frequency_for_coordinates, else no filtering.
    #[arg(long, allow_negative_numbers = true, value_name = "HZ", value_parser = crate::tool::lowpass_hz)]
    lowpass: Option<f64>,
    /// Time range START END (s). Default: the setup's initial_time and final_time, else the
    /// whole motion.
    #[arg(
        long,
        num_args = 2,
        value_names = ["START", "END"],
        allow_negative_numbers = true,
        value_parser = crate::tool::time_s
    )]
    time_range: Option<Vec<f64>>,
    /// Solve every k-th frame (and the first and last). Default: the setup's step_interval,
    /// else 1.
    #[arg(long, value_name = "K")]
    step_interval: Option<usize>,
    /// Exponent p of the objective Σ|x|^p. Default: the setup's activation_exponent, else 2.
    #[arg(long, value_name = "P")]
    activation_exponent: Option<f64>,
    /// Muscle force = activation × F_max instead of the force–length–velocity relations
    /// (OpenSim's use_muscle_physiology = false).
    #[arg(long)]
    no_muscle_physiology: bool,
    /// Also apply each muscle's passive fiber force (OpenSim does not).
    #[arg(long)]
    passive_fiber_force: bool,
    /// Output prefix: writes PREFIX_activation.sto and PREFIX_force.sto, both or neither. A
    /// prefix ending in `/` is a folder (files named <name>_StaticOptimization_… with a setup,
    /// else after the coordinates file); missing folders are created. Default: the setup's
    /// results_directory/<name>_StaticOptimization.
    #[arg(short, long, value_name = "PREFIX")]
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
    let setup = args.setup.as_deref().map(AnalyzeSetup::read).transpose()?;
    if let Some(s) = &setup {
        for w in &s.warnings {
            eprintln!("warning: {w}");
        }
    }
    let so_setup = setup.as_ref().and_then(|s| s.static_optimization.clone());
    if let (Some(path), Some(s)) = (&args.setup, &setup)
        && s.static_optimization.is_none()
    {
        eprintln!(
            "warning: {}: no StaticOptimization analysis; using its defaults",
            path.display()
        );
    }
    let paths = SoPaths::resolve(args, setup.as_ref(), so_setup.as_ref())?;
    let (options, run_options) = so_options(args, setup.as_ref(), so_setup);
    let model = Model::from_osim_file_with_force_sets(
        &paths.model,
        &args.strict.load_options(),
        &paths.force_sets,
        paths.replace,
    )?;
    crate::warnings::print_model(&model);
    crate::warnings::require_movable(&model)?;
    let so = StaticOptimization::new(&model, options)?;
    let coordinates = read_coordinates(
        &model,
        &paths.coordinates,
        args.missing_coordinates_at_default,
    )?;
    let loads = (paths.loads.as_deref())
        .map(|p| ExternalLoadSet::read(&model, p))
        .transpose()?;
    if let Some(l) = &loads {
        crate::warnings::print(&l.warnings);
    }
    let (mut outputs, activation_path, force_path) = checked_outputs(args, &paths, loads.as_ref())?;
    let progress = FrameProgress::new("static optimization");
    let start = Instant::now();
    let result = run_static_optimization(
        &model,
        &so,
        &coordinates,
        &paths.coordinates.display().to_string(),
        loads.as_ref(),
        &run_options,
        &mut |done, total| progress.update(done, total),
    );
    progress.finish();
    let out = result?;
    let seconds = start.elapsed().as_secs_f64();
    for w in &out.warnings {
        eprintln!("warning: {w}");
    }
    let frames = out.activation.n_rows();
    for line in frame_warnings("frame(s) not solved exactly", frames, &frame_problems(&out)) {
        eprintln!("warning: {line}");
    }
    outputs.add(
        &activation_path,
        out.activation.to_file_string()?.as_bytes(),
    )?;
    outputs.add(&force_path, out.force.to_file_string()?.as_bytes())?;
    crate::tool::commit(outputs)?;
    let rows = out.activation.n_rows();
    eprintln!(
        "wrote {} and {}: {} frames ({:.6} – {:.6} s) × {} actuators ({} muscles); {} frame(s) \
         not solved exactly; {:.3} s ({:.0} frames/s)",
        activation_path.display(),
        force_path.display(),
        rows,
        out.activation.time[0],
        out.activation.time[rows - 1],
        so.actuators.len(),
        so.muscles.len(),
        out.problems.len(),
        seconds,
        rows as f64 / seconds
    );
    Ok(())
}

/// The files of a run, from the command line or else the setup: model, coordinates,
/// external loads, force sets (and whether they replace the model's) and output prefix.
struct SoPaths {
    model: PathBuf,
    coordinates: PathBuf,
    loads: Option<PathBuf>,
    force_sets: Vec<PathBuf>,
    replace: bool,
    prefix: PathBuf,
}

impl SoPaths {
    fn resolve(
        args: &Args,
        setup: Option<&AnalyzeSetup>,
        so_setup: Option<&StaticOptimizationSetup>,
    ) -> Result<SoPaths, musculo::Error> {
        let model = args
            .model
            .clone()
            .or_else(|| setup?.model_file.clone())
            .ok_or_else(|| missing("--model", "model file"))?;
        let coordinates = args
            .coordinates
            .clone()
            .or_else(|| setup?.coordinates_file.clone())
            .ok_or_else(|| missing("--coordinates", "coordinates file"))?;
        let loads = args
            .external_loads
            .clone()
            .or_else(|| setup?.external_loads_file.clone());
        let (force_sets, replace) = if args.actuators.is_empty() {
            setup
                .map(|s| (s.force_set_files.clone(), s.replace_force_set))
                .unwrap_or_default()
        } else {
            (args.actuators.clone(), false)
        };
        // OpenSim names the files <tool name>_<analysis name>_activation.sto.
        let setup_stem = setup.map(|s| {
            let analysis = so_setup.map_or("StaticOptimization", |a| &a.name);
            format!("{}_{analysis}", s.name)
        });
        let prefix = match (&args.output, setup) {
            (Some(o), _) => name_in_folder(
                o,
                &setup_stem
                    .clone()
                    .unwrap_or_else(|| crate::tool::stem(&coordinates)),
            ),
            (None, Some(s)) => s
                .results_directory
                .as_ref()
                .zip(setup_stem.as_ref())
                .map(|(dir, stem)| dir.join(stem))
                .ok_or_else(|| missing("--output", "output prefix"))?,
            (None, None) => return Err(missing("--output", "output prefix")),
        };
        Ok(SoPaths {
            model,
            coordinates,
            loads,
            force_sets,
            replace,
            prefix,
        })
    }
}

/// Static optimization's options and the run's (filter, time range, step), from the
/// command line over the setup over OpenSim's defaults.
fn so_options(
    args: &Args,
    setup: Option<&AnalyzeSetup>,
    so_setup: Option<StaticOptimizationSetup>,
) -> (StaticOptimizationOptions, SoRunOptions) {
    let defaults = so_setup.unwrap_or_default();
    let options = StaticOptimizationOptions {
        activation_exponent: args
            .activation_exponent
            .unwrap_or(defaults.activation_exponent),
        use_muscle_physiology: defaults.use_muscle_physiology && !args.no_muscle_physiology,
        passive_fiber_force: args.passive_fiber_force,
        ..Default::default()
    };
    let mut run_options = SoRunOptions {
        lowpass_hz: setup.and_then(|s| s.lowpass_cutoff_hz),
        time_range: setup.and_then(|s| match (s.initial_time, s.final_time) {
            (Some(a), Some(b)) => Some([a, b]),
            _ => None,
        }),
        step_interval: args.step_interval.unwrap_or(defaults.step_interval),
    };
    if let Some(hz) = args.lowpass {
        run_options.lowpass_hz = (hz > 0.0).then_some(hz);
    }
    if let Some(r) = &args.time_range {
        run_options.time_range = Some([r[0], r[1]]);
    }
    (options, run_options)
}

/// The output set (which refuses to overwrite an input) with the activation and force
/// files checked before the run.
fn checked_outputs(
    args: &Args,
    paths: &SoPaths,
    loads: Option<&ExternalLoadSet>,
) -> Result<(OutputSet, PathBuf, PathBuf), musculo::Error> {
    let data_path = loads.map(|l| PathBuf::from(&l.data_source));
    let inputs = [&paths.model, &paths.coordinates]
        .into_iter()
        .chain(&paths.loads)
        .chain(&data_path)
        .chain(&paths.force_sets)
        .chain(&args.setup);
    let outputs = OutputSet::new(inputs.map(PathBuf::as_path));
    let activation_path = with_suffix(&paths.prefix, "_activation.sto");
    let force_path = with_suffix(&paths.prefix, "_force.sto");
    outputs.check(&activation_path)?;
    outputs.check(&force_path)?;
    Ok((outputs, activation_path, force_path))
}

/// The frames static optimization did not solve exactly, as warnings: the status and the
/// coordinates left unbalanced (τ − Σ r F x) above tolerance.
fn frame_problems(out: &SoRun) -> Vec<FrameWarning> {
    (out.problems.iter())
        .map(|p| {
            let what = match p.status {
                SoStatus::Infeasible => "infeasible (the actuators cannot produce τ)",
                SoStatus::NotConverged => "not converged",
                SoStatus::Solved => "solved",
            };
            let list = (p.unbalanced.iter())
                .map(|(c, r)| format!("{c} {r:+.4}"))
                .collect::<Vec<_>>()
                .join(", ");
            FrameWarning {
                time: p.time,
                size: p
                    .unbalanced
                    .iter()
                    .map(|(_, r)| r.abs())
                    .fold(0.0, f64::max),
                text: format!(
                    "{what}; unbalanced τ − Σ r F x: {}",
                    if list.is_empty() {
                        "none above tolerance".into()
                    } else {
                        list
                    }
                ),
            }
        })
        .collect()
}
