//! `musculo ik`: inverse kinematics — a motion file (markers or joint centres) in, the
//! model's coordinates out (OpenSim `.mot`), with the per-frame and per-marker errors beside
//! it. Either an OpenSim InverseKinematicsTool setup (`--setup`), or a motion dataset file
//! mapped onto a model's markers by a skeleton map.

use crate::tool::{FrameProgress, invalid, missing, model_text, read_options, skeleton_map};
use musculo::io::Table;
use musculo::io::ik_setup::IkSetup;
use musculo::io::output::{OutputSet, name_in_folder};
use musculo::model::Model;
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, Motion, ReadOptions};
use musculo::solve::ik::robust as ik_robust;
use musculo::solve::ik::{self, Bounds, IkSettings, IkSolution, IkTasks};
use musculo::solve::{ik_tool, scale_from_clip};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// An OpenSim InverseKinematicsTool setup file (model, marker file, tasks and weights,
    /// time range, output); flags override it.
    #[arg(long)]
    setup: Option<PathBuf>,
    /// Model (.osim). Default: the setup's model_file, else the built-in default full-body
    /// model.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Motion file(s): markers (.trc, .c3d) or joint centres (HumanML3D / KIT .npy, .bvh).
    /// Several files are solved in parallel, one output each.
    #[arg(long, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Input format: humanml3d, kit, bvh, c3d or trc. Default: from the file (extension,
    /// and the array shape for .npy).
    #[arg(long, value_parser = Format::parse)]
    format: Option<Format>,
    /// Skeleton map: a built-in name (humanml3d, kit, cmu_bvh, c3d_lower_body) or a JSON file. Default:
    /// the format's built-in map; markers (.trc, .c3d) are matched to the model's markers
    /// by name.
    #[arg(long)]
    map: Option<String>,
    /// `auto`: first scale the model's segments to the clip's bone lengths (median over the
    /// frames) so that the skeleton fits without systematic error.
    #[arg(long, value_name = "auto")]
    scale: Option<String>,
    /// Length unit of BVH and KIT files: m, cm, mm, in, or metres per unit (default: the
    /// reader's; an implausible body height is refused).
    #[arg(long)]
    length_unit: Option<String>,
    /// Temporal smoothness weight s of s‖q − q_prev‖² (default 0).
    #[arg(long, default_value_t = 0.0)]
    smoothness: f64,
    /// A frame ends when a step lowers the objective by less than this fraction of it
    /// (default 1e-8). 1e-6 is about a quarter faster on joint-centre data; what it leaves
    /// unsettled is mostly poorly determined coordinates (a forearm's roll).
    #[arg(long, default_value_t = ik::RELATIVE_DECREASE)]
    relative_decrease: f64,
    /// Bound every coordinate by its range (`range`, default for datasets; the floating
    /// base's position in the room excepted), only clamped coordinates (`clamped`, OpenSim's
    /// rule and the default with --setup), or none.
    #[arg(long, value_parser = ["range", "clamped", "none"])]
    bounds: Option<String>,
    /// Keep every marker's weight 1 even where a marker disagrees with the others over the
    /// clip. Without it (and without --setup), such a marker (a wrong label, a swap, a marker
    /// displaced on the skin) is down-weighted and named in a warning; with --setup the
    /// setup's weights are used as given, always.
    #[arg(long)]
    no_robust: bool,
    /// Time range START END (s). Default: the setup's time_range, else the whole motion.
    #[arg(
        long,
        num_args = 2,
        value_names = ["START", "END"],
        allow_negative_numbers = true,
        value_parser = crate::tool::time_s
    )]
    time_range: Option<Vec<f64>>,
    /// Output .mot file; with several inputs, or ending in `/`, a folder receiving
    /// <input stem>.mot each (with --setup: the setup's output file name). Written with the
    /// marker-error tables beside it, all or none; missing folders are created. Default: the
    /// setup's output_motion_file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

fn parse_bounds(text: Option<&str>, default: Bounds) -> Bounds {
    match text {
        Some("range") => Bounds::Range,
        Some("clamped") => Bounds::Clamped,
        Some("none") => Bounds::None,
        _ => default,
    }
}

/// `out.mot` → `out_ik_marker_errors.sto` (and `…_by_marker.sto`).
fn beside(output: &Path, suffix: &str) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    output.with_file_name(format!("{stem}{suffix}"))
}

/// Adds the motion and its two marker-error tables (`out.mot`, `out_ik_marker_errors.sto`,
/// `out_ik_marker_errors_by_marker.sto`) to `outputs`.
fn add_outputs(
    outputs: &mut OutputSet,
    model: &Model,
    solution: &IkSolution,
    tasks: &IkTasks,
    output: &Path,
) -> Result<(), musculo::Error> {
    let tables = [
        (
            output.to_path_buf(),
            ik_tool::coordinates_table(model, solution)?,
        ),
        (
            beside(output, "_ik_marker_errors.sto"),
            ik_tool::marker_errors_table(solution, tasks)?,
        ),
        (
            beside(output, "_ik_marker_errors_by_marker.sto"),
            ik_tool::marker_errors_by_marker(model, solution, tasks)?,
        ),
    ];
    for (path, table) in tables {
        outputs.add(&path, table.to_file_string()?.as_bytes())?;
    }
    Ok(())
}

/// Prints the fit's figures; `input` names the motion file in the warnings.
fn summarize(
    model: &Model,
    solution: &IkSolution,
    tasks: &IkTasks,
    input: &Path,
    output: &Path,
    seconds: f64,
) {
    for w in ik_robust::warnings(model, tasks, solution, &input.display().to_string()) {
        eprintln!("warning: {w}");
    }
    let frames = solution.n_frames();
    let mut rmse: Vec<f64> = solution
        .rmse
        .iter()
        .copied()
        .filter(|v| !v.is_nan())
        .collect();
    rmse.sort_by(f64::total_cmp);
    let median = rmse.get(rmse.len() / 2).copied().unwrap_or(f64::NAN);
    let worst = solution
        .max_error
        .iter()
        .copied()
        .filter(|v| !v.is_nan())
        .fold(0.0f64, f64::max);
    eprintln!(
        "wrote {}: {frames} frames × {} coordinates; marker RMSE median {:.2} mm, worst marker \
         error {:.2} mm; {:.0} frames/s",
        output.display(),
        model.coordinates.len(),
        median * 1e3,
        worst * 1e3,
        frames as f64 / seconds.max(1e-9)
    );
    if !solution.first_frame_starts.is_empty() {
        eprintln!(
            "first frame from {} starts: {}",
            solution.first_frame_starts.len(),
            musculo::solve::ik::describe_starts(&solution.first_frame_starts)
        );
    }
    let at_limit = solution.frames_at_limit();
    if at_limit > 0 {
        let names = model.q_names();
        let mut count = vec![0usize; model.nq()];
        for l in &solution.at_limit {
            for &j in l {
                count[j] += 1;
            }
        }
        let list: Vec<String> = count
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(j, c)| format!("{} ({c})", names[j]))
            .collect();
        eprintln!(
            "{at_limit} frame(s) with a coordinate at a bound: {}",
            list.join(", ")
        );
    }
    let missing = ik_tool::missing_marker_frames(solution, tasks);
    let gaps: Vec<String> = tasks
        .markers
        .iter()
        .zip(&missing)
        .filter(|(_, m)| **m > 0)
        .map(|(t, m)| format!("{} ({m})", model.markers[t.marker].name))
        .collect();
    if !gaps.is_empty() {
        eprintln!(
            "markers missing in some frames (left out there): {}",
            gaps.join(", ")
        );
    }
}

fn run_setup(args: &Args, setup_path: &Path) -> Result<(), musculo::Error> {
    let setup = IkSetup::read(setup_path)?;
    for w in &setup.warnings {
        eprintln!("warning: {w}");
    }
    let model_path = args
        .model
        .clone()
        .or_else(|| setup.model_file.clone())
        .ok_or_else(|| missing("--model", "model file"))?;
    let marker_path = args
        .input
        .first()
        .cloned()
        .or_else(|| setup.marker_file.clone())
        .ok_or_else(|| missing("--input", "marker file"))?;
    let output = match &args.output {
        Some(o) => {
            let name = setup
                .output_path()
                .and_then(|p| Some(p.file_name()?.to_owned()));
            let default = format!("{}_ik.mot", crate::tool::stem(&marker_path));
            name_in_folder(
                o,
                &name.map_or(default, |n| n.to_string_lossy().into_owned()),
            )
        }
        None => setup
            .output_path()
            .ok_or_else(|| missing("--output", "output file"))?,
    };
    let inputs = [model_path.as_path(), marker_path.as_path(), setup_path]
        .into_iter()
        .chain(setup.coordinate_file.as_deref());
    let mut outputs = OutputSet::new(inputs);
    outputs.check(&output)?;
    let model = args.strict.load_movable(&model_path)?;
    let (markers, read_warnings) =
        motion::read_with_warnings(&marker_path, args.format, &ReadOptions::default())?;
    crate::warnings::print(&read_warnings);
    let range = match &args.time_range {
        Some(r) => Some([r[0], r[1]]),
        None => setup.time_range,
    };
    let markers = ik_tool::select_frames(&markers, range)?;
    let coordinates = setup
        .coordinate_file
        .as_deref()
        .map(Table::read)
        .transpose()?;
    if let Some(c) = &coordinates {
        crate::warnings::print(&c.warnings);
    }
    let (tasks, warnings) =
        ik_tool::tasks_from_setup(&model, &setup, &markers, coordinates.as_ref())?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let settings = IkSettings {
        bounds: parse_bounds(args.bounds.as_deref(), Bounds::Clamped),
        smoothness: args.smoothness,
        relative_decrease: args.relative_decrease,
        normalize_marker_weights: true,
        // OpenSim's problem: the setup's weights as given, whatever the residuals
        robust: None,
        ..IkSettings::default()
    };
    let progress = FrameProgress::new("inverse kinematics");
    let frames = markers.n_frames();
    let start = Instant::now();
    let solution = ik::solve_motion(&model, &markers, &tasks, &settings, &|k| {
        progress.update(k, frames)
    });
    progress.finish();
    let solution = solution?;
    let seconds = start.elapsed().as_secs_f64();
    add_outputs(&mut outputs, &model, &solution, &tasks, &output)?;
    crate::tool::commit(outputs)?;
    summarize(&model, &solution, &tasks, &marker_path, &output, seconds);
    Ok(())
}

/// One clip's targets in the model frame and its tasks (markers by name when no map).
fn targets_and_tasks(
    model: &Model,
    motion: &Motion,
    map: Option<&SkeletonMap>,
) -> Result<(Motion, IkTasks), musculo::Error> {
    match map {
        Some(map) => map.apply(model, motion),
        None => {
            let tasks = ik::tasks_by_name(model, motion);
            if tasks.markers.is_empty() {
                return Err(invalid(
                    "--map",
                    format!(
                        "no marker of {} has a model marker of the same name; give a skeleton \
                         map",
                        motion.source
                    ),
                ));
            }
            Ok((motion.clone(), tasks))
        }
    }
}

fn run_dataset(args: &Args) -> Result<(), musculo::Error> {
    if args.input.is_empty() {
        return Err(missing("--input", "motion file"));
    }
    let output = args
        .output
        .clone()
        .ok_or_else(|| missing("--output", "output file"))?;
    let inputs = args.input.iter().chain(&args.model).map(PathBuf::as_path);
    let mut outputs = OutputSet::new(inputs);
    let (base_xml, base_source) = model_text(args.model.as_deref())?;
    let base_model = args.strict.load_str_movable(&base_xml, &base_source)?;
    let options = read_options(args.length_unit.as_deref())?;
    let auto_scale = match args.scale.as_deref() {
        None => false,
        Some("auto") => true,
        Some(other) => {
            return Err(invalid(
                "--scale",
                format!("`{other}`: the only value is `auto`"),
            ));
        }
    };
    let several = args.input.len() > 1;
    if several {
        let mut stems: Vec<_> = args.input.iter().map(|p| p.file_stem()).collect();
        stems.sort();
        if let Some(w) = stems.windows(2).find(|w| w[0] == w[1]) {
            return Err(invalid(
                "--input",
                format!(
                    "two inputs are named {}: their outputs would overwrite each other in {}",
                    w[0].unwrap_or_default().to_string_lossy(),
                    output.display()
                ),
            ));
        }
    }
    let mut jobs = Vec::new();
    for path in &args.input {
        let format = match args.format {
            Some(f) => f,
            None => Format::detect(path)?,
        };
        let (mut clip, read_warnings) = motion::read_with_warnings(path, Some(format), &options)?;
        crate::warnings::print(&read_warnings);
        if let Some(r) = &args.time_range {
            clip = clip.time_window(r[0], r[1])?;
        }
        let map = skeleton_map(args.map.as_deref(), format)?;
        let model = if auto_scale {
            let map = map
                .as_ref()
                .ok_or_else(|| invalid("--scale", "auto scaling needs a skeleton map"))?;
            let scaling =
                scale_from_clip::scale_to_clip(&base_xml, &base_source, &base_model, map, &clip)?;
            eprintln!(
                "{}: segments scaled to the clip's bone lengths: {}; {} marker(s) placed",
                path.display(),
                scaling.summary(),
                scaling.placed.len()
            );
            scaling.model
        } else {
            base_model.clone()
        };
        let (targets, tasks) = targets_and_tasks(&model, &clip, map.as_ref())?;
        let name = format!("{}.mot", crate::tool::stem(path));
        let out = if several {
            output.join(name)
        } else {
            name_in_folder(&output, &name)
        };
        outputs.check(&out)?;
        jobs.push((path.clone(), model, targets, tasks, out));
    }
    let settings = IkSettings {
        bounds: parse_bounds(args.bounds.as_deref(), Bounds::Range),
        smoothness: args.smoothness,
        relative_decrease: args.relative_decrease,
        robust: (!args.no_robust).then(ik_robust::RobustMarkers::default),
        ..IkSettings::default()
    };
    let total: usize = jobs.iter().map(|j| j.2.n_frames()).sum();
    let progress = FrameProgress::new("inverse kinematics");
    let done = std::sync::atomic::AtomicUsize::new(0);
    let start = Instant::now();
    use rayon::prelude::*;
    let results: Vec<_> = jobs
        .par_iter()
        .map(|(_, model, targets, tasks, _)| {
            let reported = std::cell::Cell::new(0usize);
            let t0 = Instant::now();
            let r = ik::solve_motion(model, targets, tasks, &settings, &|k| {
                let new = k - reported.replace(k);
                let all = done.fetch_add(new, std::sync::atomic::Ordering::Relaxed) + new;
                progress.update(all, total);
            });
            (r, t0.elapsed().as_secs_f64())
        })
        .collect();
    progress.finish();
    let _ = start;
    let mut failed = 0;
    let mut solved = Vec::new();
    for ((path, model, _, tasks, out), (result, seconds)) in jobs.iter().zip(results) {
        match result {
            Ok(solution) => {
                add_outputs(&mut outputs, model, &solution, tasks, out)?;
                solved.push((path, model, solution, tasks, out, seconds));
            }
            Err(e) => {
                let message = format!("{}: {e}", path.display());
                eprintln!("error: {}", crate::warnings::shorten(&message));
                failed += 1;
            }
        }
    }
    // The solved clips' files, all together (a failed clip writes none).
    crate::tool::commit(outputs)?;
    for (path, model, solution, tasks, out, seconds) in &solved {
        summarize(model, solution, tasks, path, out, *seconds);
    }
    if failed > 0 {
        return Err(invalid(
            "--input",
            format!("{failed} of {} clip(s) failed", jobs.len()),
        ));
    }
    Ok(())
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    match &args.setup {
        Some(setup) => run_setup(args, setup),
        None => run_dataset(args),
    }
}
