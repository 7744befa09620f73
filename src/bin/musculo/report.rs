//! `musculo report`: HTML pages of tensor files — one per clip with its plots, and a dataset
//! page with the distributions of the plausibility metrics and the worst clips linked.

use crate::tool::{FrameProgress, invalid};
use musculo::evaluate::{EvaluateOptions, SetOptions, collect, evaluate_set};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// Tensor files (.npz) or folders of them, e.g. an augmentation's output folder.
    #[arg(required = true, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Folder to write `index.html` (the dataset page) and `<clip>.html` into.
    #[arg(long)]
    out: PathBuf,
    /// OpenSim 4.x model of every clip (default: `<clip>.osim` beside the clip when there is
    /// one, else the built-in default model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Folder of reference clips of the same names (e.g. with measured loads): drawn dashed
    /// beside the clip's torques and ground reactions, and compared in the metrics.
    #[arg(long, value_name = "DIR")]
    reference: Option<PathBuf>,
    /// Floor height (m, along +y), or `clip` (see `musculo evaluate`).
    #[arg(long, default_value = "0", allow_hyphen_values = true)]
    floor: String,
    /// Only the dataset page (no page per clip).
    #[arg(long)]
    no_clip_pages: bool,
    /// Format of motion files among the inputs (default: from each file's extension and
    /// array shape); they go through IK, inverse dynamics and contacts first (no muscles).
    #[arg(long, value_parser = musculo::motion::Format::parse)]
    format: Option<musculo::motion::Format>,
    /// Length unit of motion files (m, cm, mm, in or metres per unit).
    #[arg(long)]
    length_unit: Option<String>,
    /// Skeleton map of motion files (built-in name or .json file; default: each format's
    /// built-in map).
    #[arg(long)]
    map: Option<String>,
    /// Threads (default: all cores).
    #[arg(long)]
    jobs: Option<usize>,
}

/// `--floor`: a height in metres or `clip`.
pub fn floor(text: &str) -> Result<Option<f64>, musculo::Error> {
    match text {
        "clip" => Ok(None),
        _ => text.parse::<f64>().map(Some).map_err(|_| {
            invalid(
                "--floor",
                format!("{text}: give a height in metres or `clip`"),
            )
        }),
    }
}

pub fn run(args: &Args) -> Result<bool, musculo::Error> {
    let clips = collect(&args.input, args.format)?;
    let options = SetOptions {
        model: args.model.clone(),
        reference: args.reference.clone(),
        control: None,
        read: crate::tool::read_options(args.length_unit.as_deref())?,
        map: match &args.map {
            // the format only matters without a map
            Some(m) => crate::tool::skeleton_map(Some(m), musculo::motion::Format::Trc)?,
            None => None,
        },
        metrics: EvaluateOptions {
            floor_height: floor(&args.floor)?,
            ..EvaluateOptions::default()
        },
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .map_err(|e| invalid("--jobs", e.to_string()))?;
    let bar = FrameProgress::new("evaluate");
    let report = pool.install(|| evaluate_set(&clips, &options, &|d, t| bar.update(d, t)))?;
    bar.finish();
    let bar = FrameProgress::new("pages");
    let title = match args.input.as_slice() {
        [one] => format!("musculo report: {}", one.display()),
        many => format!("musculo report: {} inputs", many.len()),
    };
    let written = pool.install(|| {
        musculo::report::write_report(
            &title,
            &clips,
            &report,
            &options,
            &args.out,
            !args.no_clip_pages,
            &|d, t| bar.update(d, t),
        )
    })?;
    bar.finish();
    for (clip, reason) in &report.failed {
        eprintln!("failed: {clip}: {reason}");
    }
    println!(
        "{} page(s) written; open {}",
        written.len(),
        args.out.join("index.html").display()
    );
    Ok(report.failed.is_empty())
}

/// The dataset page of an augmentation's output folder `out`, written to `dir/index.html`.
pub fn dataset_report(
    out: &Path,
    dir: &Path,
    pool: &rayon::ThreadPool,
) -> Result<PathBuf, musculo::Error> {
    let clips = collect(&[out.to_path_buf()], None)?;
    let options = SetOptions::default();
    let report = pool.install(|| evaluate_set(&clips, &options, &|_, _| {}))?;
    let title = format!("musculo augment: {}", out.display());
    musculo::report::write_report(&title, &clips, &report, &options, dir, false, &|_, _| {})?;
    Ok(dir.join("index.html"))
}
