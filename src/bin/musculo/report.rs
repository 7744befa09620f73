//! `musculo report`: HTML pages of tensor files — one per clip with its plots, and a dataset
//! page with the distributions of the plausibility metrics and the worst clips linked.

use crate::tool::{FrameProgress, invalid};
use musculo::evaluate::{EvaluateOptions, SetOptions, collect, evaluate_set};
use std::path::{Path, PathBuf};

/// The arguments `evaluate` and `report` share: which model, reference and floor, and how
/// motion files are read.
#[derive(clap::Args)]
pub struct SetArgs {
    /// OpenSim 4.x model of every clip (default: `<clip>.osim` beside the clip when there is
    /// one, else the built-in default model).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Folder of reference clips of the same names (e.g. the augmented real data a generated
    /// set imitates, or clips with measured loads): adds the contact-force and joint-actuation
    /// errors, and draws its torques and forces dashed in the report.
    #[arg(long, value_name = "DIR")]
    pub reference: Option<PathBuf>,
    /// Floor height (m, along +y), or `clip`: each clip's own ground level (the 5th
    /// percentile of its lowest contact heights while it needs support), for data whose floor
    /// is not at 0.
    #[arg(long, default_value = "0", allow_hyphen_values = true)]
    pub floor: String,
    /// Format of motion files among the inputs (default: from each file's extension and
    /// array shape); they go through IK, inverse dynamics and contacts first (no muscles).
    #[arg(long, value_parser = musculo::motion::Format::parse)]
    pub format: Option<musculo::motion::Format>,
    /// Length unit of motion files (m, cm, mm, in or metres per unit).
    #[arg(long)]
    pub length_unit: Option<String>,
    /// Skeleton map of motion files (built-in name or .json file; default: each format's
    /// built-in map).
    #[arg(long)]
    pub map: Option<String>,
    /// Threads (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
}

impl SetArgs {
    /// The clips of `input` and the set's options (metrics at their defaults but the floor).
    pub fn clips_and_options(
        &self,
        input: &[PathBuf],
    ) -> Result<(Vec<musculo::evaluate::ClipFile>, SetOptions), musculo::Error> {
        let floor = match self.floor.as_str() {
            "clip" => None,
            text => Some(text.parse::<f64>().map_err(|_| {
                invalid(
                    "--floor",
                    format!("{text}: give a height in metres or `clip`"),
                )
            })?),
        };
        let options = SetOptions {
            model: self.model.clone(),
            reference: self.reference.clone(),
            control: None,
            read: crate::tool::read_options(self.length_unit.as_deref())?,
            map: match &self.map {
                // the format only matters without a map
                Some(m) => crate::tool::skeleton_map(Some(m), musculo::motion::Format::Trc)?,
                None => None,
            },
            metrics: EvaluateOptions {
                floor_height: floor,
                ..EvaluateOptions::default()
            },
        };
        Ok((collect(input, self.format)?, options))
    }

    /// The thread pool of `--jobs`.
    pub fn pool(&self) -> Result<rayon::ThreadPool, musculo::Error> {
        rayon::ThreadPoolBuilder::new()
            .num_threads(self.jobs.unwrap_or(0))
            .build()
            .map_err(|e| invalid("--jobs", e.to_string()))
    }
}

#[derive(clap::Args)]
pub struct Args {
    /// Tensor files (.npz) or motion files, or folders of them, e.g. an augmentation's output
    /// folder.
    #[arg(required = true, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Folder to write `index.html` (the dataset page) and `<clip>.html` into.
    #[arg(long)]
    out: PathBuf,
    /// Only the dataset page (no page per clip).
    #[arg(long)]
    no_clip_pages: bool,
    #[command(flatten)]
    set: SetArgs,
}

pub fn run(args: &Args) -> Result<bool, musculo::Error> {
    let (clips, options) = args.set.clips_and_options(&args.input)?;
    let pool = args.set.pool()?;
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
