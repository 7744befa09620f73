//! `musculo muscles`: musculotendon lengths, moment arms and maximum isometric moments along
//! a motion, written as OpenSim-style .sto files (like OpenSim's MuscleAnalysis).

use indicatif::{ProgressBar, ProgressStyle};
use musculo::io::Table;
use musculo::muscle::MuscleSet;
use musculo::muscle::path::{PathData, compute_paths};
use musculo::solve::kinematics::independent_columns;
use musculo::{Data, dynamics};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim).
    model: PathBuf,
    /// Coordinates over time (.mot or .sto; degrees are converted when the file says
    /// inDegrees=yes).
    #[arg(long)]
    coords: PathBuf,
    /// Output prefix: writes PREFIX_Length.sto, PREFIX_MomentArm_<coordinate>.sto and
    /// PREFIX_MaxIsometricMoment_<coordinate>.sto (default: the motion file's stem).
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    let model = args.strict.load(&args.model)?;
    let set = MuscleSet::new(&model)?;
    let motion = Table::read(&args.coords)?;
    crate::warnings::print(&motion.warnings);
    let q_columns = independent_columns(&model, &motion, &args.coords.display().to_string())?;
    let (n, m, rows) = (model.nq(), set.len(), motion.n_rows());
    let mut data = Data::new(&model);
    let mut paths = PathData::new(&model, &set.paths);
    let mut q = vec![0.0; n];
    let mut lengths = Vec::with_capacity(rows * m);
    // [coordinate][row * m + muscle]
    let mut arms = vec![Vec::with_capacity(rows * m); n];
    let mut moments = vec![Vec::with_capacity(rows * m); n];
    let bar = ProgressBar::new(rows as u64).with_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} frames")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message("muscles");
    for r in 0..rows {
        for j in 0..n {
            q[j] = q_columns[j][r];
        }
        dynamics::forward_kinematics(&model, &mut data, &q)?;
        compute_paths(&model, &data, &set.paths, &mut paths)?;
        lengths.extend_from_slice(&paths.length);
        for k in 0..m {
            let f_iso = set.muscles[k].isometric_force(paths.length[k]);
            for j in 0..n {
                let rjk = paths.moment_arms[(j, k)];
                arms[j].push(rjk);
                moments[j].push(rjk * f_iso);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();

    let prefix = args
        .output
        .clone()
        .unwrap_or_else(|| args.coords.with_extension(""));
    let labels: Vec<String> = set.names().map(str::to_string).collect();
    let write =
        |suffix: &str, values: Vec<f64>, description: &str| -> Result<PathBuf, musculo::Error> {
            let path = PathBuf::from(format!("{}_{suffix}.sto", prefix.display()));
            let mut table = Table::new(
                suffix.to_string(),
                labels.clone(),
                motion.time.clone(),
                values,
            )?;
            table.in_degrees = Some(false);
            table.description = vec![description.to_string()];
            table.write(&path)?;
            Ok(path)
        };
    let mut written = vec![write(
        "Length",
        lengths,
        "Musculotendon length (m) of each muscle, computed by musculo.",
    )?];
    let names = model.q_names();
    for j in 0..n {
        if arms[j].iter().all(|&r| r.abs() < 1e-12) {
            continue; // no muscle crosses this coordinate
        }
        written.push(write(
            &format!("MomentArm_{}", names[j]),
            std::mem::take(&mut arms[j]),
            &format!("Moment arm r = -dl/dq of each muscle about {} (m, or dimensionless for a translation).", names[j]),
        )?);
        written.push(write(
            &format!("MaxIsometricMoment_{}", names[j]),
            std::mem::take(&mut moments[j]),
            &format!("Moment about {} of each muscle at full activation, isometric (N m): r times the isometric tendon force.", names[j]),
        )?);
    }
    eprintln!(
        "{} muscles, {rows} frames: wrote {} files",
        m,
        written.len()
    );
    for p in &written {
        eprintln!("  {}", p.display());
    }
    Ok(())
}
