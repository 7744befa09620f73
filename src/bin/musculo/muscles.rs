//! `musculo muscles`: musculotendon lengths, moment arms and maximum isometric moments along
//! a motion, written as OpenSim-style .sto files (like OpenSim's MuscleAnalysis).

use indicatif::{ProgressBar, ProgressStyle};
use musculo::io::Table;
use musculo::io::output::{OutputSet, name_in_folder, with_suffix};
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
    /// PREFIX_MaxIsometricMoment_<coordinate>.sto, all or none (default: the motion file's
    /// path without its extension). A prefix ending in `/` is a folder, the files named after
    /// the motion file in it; missing folders are created.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    let model = args.strict.load_movable(&args.model)?;
    let set = MuscleSet::new(&model)?;
    let motion = Table::read(&args.coords)?;
    crate::warnings::print(&motion.warnings);
    let stem = crate::tool::stem(&args.coords);
    let prefix = match &args.output {
        Some(o) => name_in_folder(o, &stem),
        None => args.coords.with_file_name(&stem),
    };
    let mut outputs = OutputSet::new([args.model.as_path(), args.coords.as_path()]);
    outputs.check(&with_suffix(&prefix, "_Length.sto"))?;
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
        if let Some(k) = paths.length.iter().position(|l| !l.is_finite()) {
            // Name the coordinate largest in magnitude: the likeliest cause.
            let j = (0..n)
                .max_by(|&a, &b| q[a].abs().total_cmp(&q[b].abs()))
                .unwrap_or(0);
            return Err(motion.locator(&args.coords.display().to_string()).row(
                r,
                format!("column \"{}\"", model.q_names()[j]),
                format!(
                    "the length of muscle `{}` is {} with this row's coordinates (the \
                     largest, {}, is beyond what the muscle paths can compute)",
                    set.names().nth(k).unwrap_or("?"),
                    paths.length[k],
                    musculo::text::short_number(q[j])
                ),
            ));
        }
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

    let labels: Vec<String> = set.names().map(str::to_string).collect();
    let mut add = |suffix: &str, values: Vec<f64>, description: &str| {
        let mut table = Table::new(
            suffix.to_string(),
            labels.clone(),
            motion.time.clone(),
            values,
        )?;
        table.in_degrees = Some(false);
        table.description = vec![description.to_string()];
        let path = with_suffix(&prefix, &format!("_{suffix}.sto"));
        outputs.add(&path, table.to_file_string()?.as_bytes())
    };
    add(
        "Length",
        lengths,
        "Musculotendon length (m) of each muscle, computed by musculo.",
    )?;
    let names = model.q_names();
    for j in 0..n {
        if arms[j].iter().all(|&r| r.abs() < 1e-12) {
            continue; // no muscle crosses this coordinate
        }
        add(
            &format!("MomentArm_{}", names[j]),
            std::mem::take(&mut arms[j]),
            &format!(
                "Moment arm r = -dl/dq of each muscle about {} (m, or dimensionless for a translation).",
                names[j]
            ),
        )?;
        add(
            &format!("MaxIsometricMoment_{}", names[j]),
            std::mem::take(&mut moments[j]),
            &format!(
                "Moment about {} of each muscle at full activation, isometric (N m): r times the isometric tendon force.",
                names[j]
            ),
        )?;
    }
    let written = crate::tool::commit(outputs)?;
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
