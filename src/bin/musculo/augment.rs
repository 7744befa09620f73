//! `musculo augment`: a motion dataset in, per-clip tensors of joint torques, contact forces
//! and muscle activations out (see `musculo::augment`); and `musculo merge`, which puts the
//! shards of a run together.

use crate::tool::{invalid, model_text, read_options, skeleton_map};
use indicatif::{ProgressBar, ProgressStyle};
use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::output::{self, VerdictSummary};
use musculo::augment::perturb::PerturbationRanges;
use musculo::augment::runner::{self, ClipInput, RunOptions};
use musculo::augment::verdict::Verdict;
use musculo::augment::{demo, describe};
use musculo::motion::Format;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Motion files or folders (searched recursively for .npy, .bvh, .c3d, .trc); the output
    /// tree mirrors each folder's tree.
    #[arg(long, num_args = 1.., required_unless_present = "demo")]
    input: Vec<PathBuf>,
    /// Run the three sample clips built into musculo (march in place, squat, reach) on the
    /// default model.
    #[arg(long, conflicts_with = "input")]
    demo: bool,
    /// Input format (default: from each file's extension and array shape).
    #[arg(long, value_parser = Format::parse)]
    format: Option<Format>,
    /// Skeleton map (built-in name or .json file; default: the format's built-in map).
    #[arg(long)]
    map: Option<String>,
    /// Length unit of the inputs (m, cm, mm, in or metres per unit).
    #[arg(long)]
    length_unit: Option<String>,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Model (.osim); default: the built-in full-body model.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Variants per clip: 1 = the clips as recorded; each further variant perturbs body
    /// height and mass, adds a carried load and warps time (seeded).
    #[arg(long, default_value_t = 1, value_parser = variants)]
    variants: usize,
    /// Seed of the perturbations.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = crate::tool::jobs)]
    jobs: Option<usize>,
    /// Run shard K of N (0 ≤ K < N), e.g. `--shard $SLURM_ARRAY_TASK_ID/8`; finish with
    /// `musculo merge OUT`.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Skip clips already finished in OUT (after an interruption).
    #[arg(long)]
    resume: bool,
    /// Low-pass cutoff (Hz) of the coordinates before differentiation; 0 = none.
    #[arg(long, default_value_t = 6.0)]
    lowpass: f64,
    /// Do not scale the model to each clip's bone lengths.
    #[arg(long)]
    no_scale: bool,
    /// Multiply every muscle's maximum isometric force by K (as OpenSim users strengthen a
    /// model for tasks beyond walking); recorded in the manifest. Default 1: the model as given.
    #[arg(
        long,
        value_name = "K",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    muscle_strength: f64,
    /// The clips were recorded on a treadmill: contact speeds are taken relative to the belt,
    /// at SPEED (m/s, its direction from the stance feet) or at the speed estimated per clip.
    /// Default: detected per clip from the stance feet (a treadmill when they move together at
    /// 0.2 m/s or more); the manifest records what each clip got.
    #[arg(long, value_name = "SPEED", num_args = 0..=1, conflicts_with = "overground")]
    treadmill: Option<Option<f64>>,
    /// The clips were recorded on a floor at rest (no treadmill detection).
    #[arg(long)]
    overground: bool,
    /// Keep a held pose at a clip's start or end that the motion jumps from or to (a
    /// calibration T-pose). By default such frames are left out with a warning naming them.
    #[arg(long)]
    keep_calibration_frames: bool,
    #[command(flatten)]
    strict: crate::warnings::Strict,
    /// Measured ground reactions for a single trial (an OpenSim ExternalLoads .xml and its
    /// data file), used instead of the estimate from kinematics.
    #[arg(long)]
    external_loads: Option<PathBuf>,
    /// Use each C3D input's force plates as measured ground reactions (each plate applied to
    /// the calcaneus nearest its centre of pressure).
    #[arg(long, conflicts_with = "external_loads")]
    force_plates: bool,
    /// Also write OpenSim files per clip: `<clip>_ik.mot`, `_tau.sto`, `_activation.sto`,
    /// `_grf.mot` and the scaled model `<clip>.osim`, so a clip opens in OpenSim's GUI.
    #[arg(long)]
    opensim_files: bool,
    /// At the end, evaluate the output (as `musculo evaluate` does) and write the dataset
    /// page OUT/report/index.html. Implies --opensim-files, so that each clip is judged on
    /// its own scaled model. A shard writes no page: `musculo merge --report` does, once
    /// every shard has finished.
    #[arg(long)]
    report: bool,
    /// Exit non-zero also when a clip's verdict is this or worse: `failed` (a clip judged
    /// failed), `suspect` (suspect or failed). Without it the exit status says whether every
    /// clip could be computed.
    #[arg(long, value_enum, value_name = "VERDICT")]
    fail_on: Option<FailOn>,
}

/// `--fail-on`: the verdict from which the exit status is non-zero.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum FailOn {
    Failed,
    Suspect,
}

impl FailOn {
    fn verdict(self) -> Verdict {
        match self {
            FailOn::Failed => Verdict::Failed,
            FailOn::Suspect => Verdict::Suspect,
        }
    }
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The output folder the shards wrote into.
    out: PathBuf,
    /// Then evaluate the merged output and write the dataset page OUT/report/index.html (as
    /// `augment --report` does for an unsharded run).
    #[arg(long)]
    report: bool,
    /// Threads of the evaluation (default: all cores).
    #[arg(long, value_parser = crate::tool::jobs)]
    jobs: Option<usize>,
    /// Exit non-zero also when a clip's verdict is this or worse (as `augment --fail-on`).
    #[arg(long, value_enum, value_name = "VERDICT")]
    fail_on: Option<FailOn>,
}

/// One line on a HumanML3D / KIT-ML root: which motion folder, captions, splits.
fn print_dataset(d: &musculo::augment::dataset::DatasetRoot) {
    let description = d.describe();
    let mut parts = vec![format!("clips from {}/", description.motions)];
    if let Some(other) = &description.left_out {
        parts.push(format!("{other}/ left out (the same motions)"));
    }
    parts.push(match &description.texts {
        Some(_) => "captions from texts/ copied beside the outputs".to_string(),
        None => "no texts/".to_string(),
    });
    if !description.splits.is_empty() {
        let splits: Vec<&str> = description.splits.iter().map(|(n, _)| n.as_str()).collect();
        parts.push(format!("splits {} in the records", splits.join("/")));
    }
    eprintln!(
        "{}: a HumanML3D / KIT-ML root: {}",
        description.root,
        parts.join("; ")
    );
}

fn parse_shard(text: &str) -> Result<(usize, usize), musculo::Error> {
    let bad = || {
        invalid(
            "--shard",
            format!("`{text}`: expected K/N with 0 ≤ K < N, e.g. 3/8"),
        )
    };
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

/// `--variants`: a count from 1 to [`runner::MAX_VARIANTS`].
fn variants(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=runner::MAX_VARIANTS).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{text}`: give a whole number from 1 to {}",
            runner::MAX_VARIANTS
        )),
    }
}

pub fn run(args: &Args) -> Result<bool, musculo::Error> {
    check_factors(args)?;
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    let (xml, source) = model_text(args.model.as_deref())?;
    let options = chain_options(args)?;
    // Read once here for `--strict` and the model's warnings; the chain reads the same text.
    args.strict.load_str(&xml, &source)?;
    let chain = Chain::new(xml, source, options)?;
    let layout = describe(&chain)?;
    let (clips, datasets): (Vec<ClipInput>, _) = if args.demo {
        (demo::inputs(&chain.model)?, Vec::new())
    } else {
        runner::list_dataset(&args.input, args.format)?
    };
    for d in &datasets {
        print_dataset(d);
    }
    let run_options = run_options(args, shard, datasets)?;
    let (report, seconds, pool) = run_with_progress(args, &chain, &layout, &clips, &run_options)?;
    let failed = report.records.iter().filter(|r| r.reason.is_some()).count();
    print_run_summary(args, &report, seconds);
    print_worst_clips(args, &report);
    let mut verdicts = VerdictSummary::default();
    for r in &report.records {
        let v = output::clip_verdict(r.status, r.reason.as_deref(), r.quality.as_ref());
        verdicts.add(&r.clip, v.as_ref());
    }
    print_verdicts(&verdicts, &args.out);
    match shard {
        Some((k, n)) => eprintln!(
            "shard {k}/{n} done; when every shard has finished: musculo merge {}{}",
            if args.report { "--report " } else { "" },
            args.out.display()
        ),
        None => eprintln!("wrote {}", args.out.join("manifest.json").display()),
    }
    if args.report && shard.is_none() && report.records.len() > failed {
        let page = crate::report::dataset_report(&args.out, &args.out.join("report"), &pool)?;
        eprintln!("wrote {}", page.display());
    }
    Ok(failed == 0 && !fails_on(&verdicts, args.fail_on))
}

/// `--lowpass` (≥ 0) and `--muscle-strength` (within the scaling's limits) checked.
fn check_factors(args: &Args) -> Result<(), musculo::Error> {
    if !(args.lowpass >= 0.0 && args.lowpass.is_finite()) {
        return Err(invalid(
            "--lowpass",
            format!("{} must be ≥ 0 (0: no filter)", args.lowpass),
        ));
    }
    use musculo::solve::scale::strength::{MAX_STRENGTH_FACTOR, MIN_STRENGTH_FACTOR};
    if !(MIN_STRENGTH_FACTOR..=MAX_STRENGTH_FACTOR).contains(&args.muscle_strength) {
        return Err(invalid(
            "--muscle-strength",
            format!(
                "{} must be from {MIN_STRENGTH_FACTOR} to {MAX_STRENGTH_FACTOR}",
                args.muscle_strength
            ),
        ));
    }
    Ok(())
}

/// The chain's options from the command line (the floor: `--treadmill`, `--overground`).
fn chain_options(args: &Args) -> Result<ChainOptions, musculo::Error> {
    let mut options = ChainOptions {
        lowpass_hz: (args.lowpass > 0.0).then_some(args.lowpass),
        scale_to_clip: !args.no_scale,
        opensim_files: args.opensim_files || args.report,
        muscle_strength: args.muscle_strength,
        keep_calibration_frames: args.keep_calibration_frames,
        ..ChainOptions::default()
    };
    if let Some(speed) = args.treadmill {
        if let Some(v) = speed
            && !(v >= 0.0 && v.is_finite())
        {
            return Err(invalid(
                "--treadmill",
                format!("{v}: the belt speed must be a finite number of m/s, ≥ 0"),
            ));
        }
        options.contact.floor_motion = musculo::solve::contact::FloorMotion::Treadmill { speed };
    }
    if args.overground {
        options.contact.floor_velocity = Some(musculo::spatial::Vec3::zeros());
    }
    Ok(options)
}

/// The run's options from the command line: output, variants, shard, resume, skeleton map,
/// reading options, measured loads and the datasets found.
fn run_options(
    args: &Args,
    shard: Option<(usize, usize)>,
    datasets: Vec<musculo::augment::dataset::DatasetRoot>,
) -> Result<RunOptions, musculo::Error> {
    let map = match (&args.map, args.format) {
        (Some(m), Some(f)) => skeleton_map(Some(m), f)?,
        (Some(m), None) => skeleton_map(Some(m), Format::Trc)?,
        (None, _) => None,
    };
    let read = read_options(args.length_unit.as_deref())?;
    Ok(RunOptions {
        out: args.out.clone(),
        variants: args.variants,
        seed: args.seed,
        perturbation: PerturbationRanges::default(),
        shard,
        resume: args.resume,
        map,
        read,
        external_loads: args.external_loads.clone(),
        force_plates: args.force_plates,
        datasets,
    })
}

/// Runs the chain on the clips in a pool of `--jobs` threads behind a progress bar; returns
/// the run's report, its duration (s) and the pool (for the report pages).
fn run_with_progress(
    args: &Args,
    chain: &Chain,
    layout: &output::LayoutDescription,
    clips: &[ClipInput],
    run_options: &RunOptions,
) -> Result<(runner::RunReport, f64, rayon::ThreadPool), musculo::Error> {
    let mine = runner::shard_clips(clips, run_options.shard).len() * args.variants.max(1);
    let bar = ProgressBar::new(mine as u64).with_style(
        ProgressStyle::with_template("augment [{bar:30}] {pos}/{len} clips  {msg}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let progress = |p: runner::Progress| {
        let s = start.elapsed().as_secs_f64().max(1e-9);
        bar.set_position(p.done as u64);
        bar.set_message(format!(
            "{:.1} clips/s, {:.0} frames/s, {} failed",
            p.done as f64 / s,
            p.frames as f64 / s,
            p.failed
        ));
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .map_err(|e| invalid("--jobs", e.to_string()))?;
    let report = pool.install(|| runner::run(chain, layout, clips, run_options, &progress));
    bar.finish_and_clear();
    let report = report?;
    let seconds = start.elapsed().as_secs_f64();
    Ok((report, seconds, pool))
}

/// What the run did: partial files removed, the failed clips, the first warnings, and the
/// counts of clips and frames with the speed.
fn print_run_summary(args: &Args, report: &runner::RunReport, seconds: f64) {
    let failed: Vec<_> = report
        .records
        .iter()
        .filter(|r| r.reason.is_some())
        .collect();
    let frames = report.frames();
    if report.temporaries_removed > 0 {
        eprintln!(
            "removed {} partial file(s) left by an interrupted run",
            report.temporaries_removed
        );
    }
    print_failures(
        failed
            .iter()
            .map(|r| (r.clip.as_str(), r.input.as_str(), r.reason.as_deref())),
        &args.out,
        " (after `musculo merge` for a sharded run)",
    );
    // what the clips' chains accepted but reported, the first few in full (all of them are
    // in the manifest, with their clips)
    let warnings: Vec<&String> = report.records.iter().flat_map(|r| &r.warnings).collect();
    for w in warnings.iter().take(SHOWN) {
        eprintln!("warning: {w}");
    }
    if warnings.len() > SHOWN {
        eprintln!(
            "warning: … and {} more, each with its clip in {}",
            warnings.len() - SHOWN,
            args.out.join("manifest.json").display()
        );
    }
    let clips = report.records.len();
    eprintln!(
        "{} of {clips} clip(s) computed, {} failed ({} now, {} resumed); {frames} frames in \
         {seconds:.1} s ({:.0} frames/s); output in {}",
        clips - failed.len(),
        failed.len(),
        report.computed,
        report.resumed,
        frames as f64 / seconds.max(1e-9),
        args.out.display()
    );
}

/// The three clips with the largest residual force, with their quality figures, and how
/// many clips leave more than 5 % of the joint moments to the reserves.
fn print_worst_clips(args: &Args, report: &runner::RunReport) {
    let mut worst: Vec<_> = report
        .records
        .iter()
        .filter_map(|r| r.quality.as_ref().map(|q| (r.clip.as_str(), q)))
        .collect();
    worst.sort_by(|a, b| {
        b.1.residual_force_max_bw
            .total_cmp(&a.1.residual_force_max_bw)
    });
    for (clip, q) in worst.iter().take(3) {
        let muscles = if q.muscle_samples > 0 {
            format!(
                ", {} of {} muscle samples at full activation, {} of {} excitations clamped",
                q.muscle_samples_at_full_activation,
                q.muscle_samples,
                q.clamped_excitations,
                q.muscle_samples
            )
        } else {
            String::new()
        };
        eprintln!(
            "  {clip}: IK RMSE {:.1} mm (median; worst error {:.0} mm), residual force peak \
             {:.3} BW (RMS {:.3} BW), reserves {:.2} % of joint moments{muscles}",
            q.ik_rmse_median * 1e3,
            q.ik_error_max * 1e3,
            q.residual_force_max_bw,
            q.residual_force_rms_bw,
            100.0 * q.reserve_share,
        );
    }
    let over = worst.iter().filter(|(_, q)| q.reserve_share > 0.05).count();
    if over > 0 {
        eprintln!(
            "{over} of {} clip(s) leave more than 5 % of the joint moments to the reserves: the \
             motion asks more than the model's muscles give (the manifest names the \
             coordinates; --muscle-strength K multiplies every muscle's force, this run × {})",
            worst.len(),
            args.muscle_strength
        );
    }
}

/// Whether `--fail-on` makes the exit status non-zero: a clip at its verdict or worse.
fn fails_on(verdicts: &VerdictSummary, fail_on: Option<FailOn>) -> bool {
    fail_on.is_some_and(|level| verdicts.at_least(level.verdict()) > 0)
}

/// The verdict counts, of how many clips, and the first few suspect and failed clips with
/// the reason that decided each (all of them are in the manifest's summary).
fn print_verdicts(v: &VerdictSummary, out: &std::path::Path) {
    let unjudged = if v.unjudged > 0 {
        format!(", {} recorded without a verdict", v.unjudged)
    } else {
        String::new()
    };
    eprintln!(
        "verdicts of {} clip(s): {} ok, {} suspect, {} failed{unjudged}",
        v.clips, v.ok, v.suspect, v.failed
    );
    for (name, list) in [("failed", &v.failed_clips), ("suspect", &v.suspect_clips)] {
        for (clip, reason) in list.iter().take(SHOWN) {
            eprintln!("  {name}: {clip}: {reason}");
        }
        if list.len() > SHOWN {
            eprintln!(
                "  {name}: … and {} more, each with its reason in {}",
                list.len() - SHOWN,
                out.join("manifest.json").display()
            );
        }
    }
}

/// How many failed clips and warnings are printed in full (all are in the manifest).
const SHOWN: usize = 10;

/// The failed clips (clip, input, reason), the first few in full and a count of the rest,
/// whose reasons are in OUT's manifest (`where_note` follows its path).
fn print_failures<'a>(
    failed: impl Iterator<Item = (&'a str, &'a str, Option<&'a str>)>,
    out: &std::path::Path,
    where_note: &str,
) {
    let mut count = 0;
    for (clip, input, reason) in failed {
        if count < SHOWN {
            eprintln!("failed: {clip} ({input}): {}", reason.unwrap_or(""));
        }
        count += 1;
    }
    if count > SHOWN {
        eprintln!(
            "failed: … and {} more clip(s), each with its reason in {}{where_note}",
            count - SHOWN,
            out.join("manifest.json").display()
        );
    }
}

/// Merges the shards of `args.out`; Ok(false) when the merged manifest records failed clips
/// (as `augment` exits non-zero when a clip failed), after writing it and naming them.
pub fn merge(args: &MergeArgs) -> Result<bool, musculo::Error> {
    let manifest = runner::merge(&args.out)?;
    print_failures(
        (manifest.clips.iter())
            .filter(|c| c.reason.is_some())
            .map(|c| (c.clip.as_str(), c.input.as_str(), c.reason.as_deref())),
        &args.out,
        "",
    );
    eprintln!(
        "merged: {} of {} clip(s) computed, {} failed, {} frames; wrote {}",
        manifest.summary.clips_ok,
        manifest.summary.clips_ok + manifest.summary.clips_failed,
        manifest.summary.clips_failed,
        manifest.summary.frames,
        args.out.join("manifest.json").display()
    );
    print_verdicts(&manifest.summary.verdicts, &args.out);
    if args.report && manifest.summary.clips_ok > 0 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(args.jobs.unwrap_or(0))
            .build()
            .map_err(|e| invalid("--jobs", e.to_string()))?;
        let page = crate::report::dataset_report(&args.out, &args.out.join("report"), &pool)?;
        eprintln!("wrote {}", page.display());
    }
    Ok(manifest.summary.clips_failed == 0 && !fails_on(&manifest.summary.verdicts, args.fail_on))
}
