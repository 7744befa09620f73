//! `musculo evaluate`: physical-plausibility metrics of a set of tensor files (augmented
//! clips or generated motions), per clip and for the set, as JSON or CSV.

use crate::tool::invalid;
use indicatif::{ProgressBar, ProgressStyle};
use musculo::evaluate::{EvaluateOptions, SetOptions, collect, evaluate_set};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Tensor files (.npz in musculo's format: q, qd, qdd, tau, time and, where present,
    /// contact_point_force, muscle_act, muscle_force; or only the per-joint layout), motion
    /// files (HumanML3D/KIT .npy, .bvh, .c3d, .trc) or folders of them (searched recursively;
    /// an augmentation's output folder works as it is).
    #[arg(long, required = true, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Where to write the metrics: FILE.json (every clip, the failures and the set summary)
    /// or FILE.csv (a row per clip and a `(set)` row).
    #[arg(long, value_name = "FILE.json|FILE.csv")]
    out: PathBuf,
    /// OpenSim 4.x model of every clip (default: `<clip>.osim` beside the clip when there is
    /// one, else the built-in default model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Folder of reference clips of the same names (e.g. the augmented real data a generated
    /// set imitates, or clips with measured loads): adds the contact-force and joint-actuation
    /// errors.
    #[arg(long, value_name = "DIR")]
    reference: Option<PathBuf>,
    /// Folder of control files `<clip>.npz` (`joint_pos` T × J × 3 targets for the model's
    /// joint centres, `mask` T × J): adds the trajectory metrics.
    #[arg(long, value_name = "DIR")]
    control: Option<PathBuf>,
    /// Floor height (m, along +y), or `clip`: each clip's own ground level (the 5th
    /// percentile of its lowest contact heights while it needs support), for data whose floor
    /// is not at 0.
    #[arg(long, default_value = "0", allow_hyphen_values = true)]
    floor: String,
    /// A foot's contact sphere within this height of the clip's ground level can be in
    /// contact, for skating (m).
    #[arg(long, default_value_t = 0.02)]
    contact_height: f64,
    /// Joint capacities from the muscle paths at every frame's pose (exact; adds the reserve
    /// share of augmented clips) instead of the model's joint strength curves: a muscle-path
    /// evaluation per frame, several times slower.
    #[arg(long)]
    muscles_per_frame: bool,
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

pub fn run(args: &Args) -> Result<bool, musculo::Error> {
    let csv = match args.out.extension().and_then(|e| e.to_str()) {
        Some("json") => false,
        Some("csv") => true,
        _ => {
            return Err(invalid(
                "--out",
                format!("{}: name a .json or .csv file", args.out.display()),
            ));
        }
    };
    let floor = match args.floor.as_str() {
        "clip" => None,
        text => Some(text.parse::<f64>().map_err(|_| {
            invalid(
                "--floor",
                format!("{text}: give a height in metres or `clip`"),
            )
        })?),
    };
    let clips = collect(&args.input, args.format)?;
    let options = SetOptions {
        model: args.model.clone(),
        reference: args.reference.clone(),
        control: args.control.clone(),
        read: crate::tool::read_options(args.length_unit.as_deref())?,
        map: match &args.map {
            // the format only matters without a map
            Some(m) => crate::tool::skeleton_map(Some(m), musculo::motion::Format::Trc)?,
            None => None,
        },
        metrics: EvaluateOptions {
            floor_height: floor,
            contact_height: args.contact_height,
            muscles_per_frame: args.muscles_per_frame,
            ..EvaluateOptions::default()
        },
    };
    let bar = ProgressBar::new(clips.len() as u64).with_style(
        ProgressStyle::with_template("evaluate [{bar:30}] {pos}/{len} clips  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .map_err(|e| invalid("--jobs", e.to_string()))?;
    let report =
        pool.install(|| evaluate_set(&clips, &options, &|done, _| bar.set_position(done as u64)));
    bar.finish_and_clear();
    let report = report?;
    let bytes = if csv {
        report.to_csv()
    } else {
        serde_json::to_string_pretty(&report).map_err(|e| invalid("--out", e.to_string()))?
    };
    let inputs: Vec<&std::path::Path> = clips.iter().map(|c| c.path.as_path()).collect();
    crate::tool::write_output(&args.out, bytes.as_bytes(), &inputs)?;
    let line: Vec<String> = report
        .summary
        .columns()
        .iter()
        .map(|(name, value)| format!("{name} {value}"))
        .collect();
    println!("{}", line.join(", "));
    for (clip, reason) in &report.failed {
        eprintln!("failed: {clip}: {reason}");
    }
    println!("metrics written to {}", args.out.display());
    Ok(report.failed.is_empty())
}
