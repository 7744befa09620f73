//! `musculo evaluate`: physical-plausibility metrics of a set of tensor files (augmented
//! clips or generated motions), per clip and for the set, as JSON or CSV.

use crate::tool::invalid;
use indicatif::{ProgressBar, ProgressStyle};
use musculo::evaluate::{MAX_CONTACT_HEIGHT, evaluate_set};
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
    /// Folder of control files `<clip>.npz` (`joint_pos` T × J × 3 targets for the model's
    /// joint centres, `mask` T × J): adds the trajectory metrics.
    #[arg(long, value_name = "DIR")]
    control: Option<PathBuf>,
    /// A foot's contact sphere within this height of the clip's ground level can be in
    /// contact, for skating (m).
    #[arg(long, default_value_t = 0.02)]
    contact_height: f64,
    /// Joint capacities from the muscle paths at every frame's pose (exact; adds the reserve
    /// share of augmented clips) instead of the model's joint strength curves: a muscle-path
    /// evaluation per frame, several times slower.
    #[arg(long)]
    muscles_per_frame: bool,
    #[command(flatten)]
    set: crate::report::SetArgs,
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
    if !(args.contact_height > 0.0 && args.contact_height <= MAX_CONTACT_HEIGHT) {
        return Err(invalid(
            "--contact-height",
            format!(
                "{}: give a height in metres in (0, {MAX_CONTACT_HEIGHT}] (a foot a metre above \
                 the ground is at a hip's height, never in contact)",
                musculo::text::short_number(args.contact_height)
            ),
        ));
    }
    let (clips, mut options) = args.set.clips_and_options(&args.input)?;
    options.control = args.control.clone();
    options.metrics.contact_height = args.contact_height;
    options.metrics.muscles_per_frame = args.muscles_per_frame;
    let bar = ProgressBar::new(clips.len() as u64).with_style(
        ProgressStyle::with_template("evaluate [{bar:30}] {pos}/{len} clips  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let pool = args.set.pool()?;
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
    let warnings: Vec<String> = (report.clips.iter())
        .flat_map(|c| c.warnings.iter().map(move |w| format!("{}: {w}", c.clip)))
        .collect();
    crate::warnings::print(&warnings);
    for (clip, reason) in &report.failed {
        eprintln!("failed: {clip}: {reason}");
    }
    println!("metrics written to {}", args.out.display());
    Ok(report.failed.is_empty())
}
