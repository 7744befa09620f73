//! `musculo check`: biomechanics unit checks of a model, as a table or JSON; the exit status
//! is non-zero when a check fails.

use musculo::check::{self, CheckOptions, CheckReport, Family, Status};
use musculo::model::Model;
use serde_json::json;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim).
    #[arg(required_unless_present = "demo", conflicts_with = "demo")]
    model: Option<PathBuf>,
    /// Check the small built-in demonstration model instead of a file.
    #[arg(long)]
    demo: bool,
    /// Print JSON (every check) instead of a table.
    #[arg(long)]
    json: bool,
    /// Print every check, not only the failures.
    #[arg(short, long)]
    verbose: bool,
    // Without --strict, a body whose inertia violates the triangle inequality is read, and
    // the mass-and-inertia check reports it.
    #[command(flatten)]
    strict: crate::warnings::Strict,
    /// Grid points over each coordinate's range for the path, sign and moment checks
    /// (2 to 10000).
    #[arg(long, default_value_t = CheckOptions::default().grid_points, value_parser = grid_points)]
    grid_points: usize,
    /// Also hold the moment arms to their bounds at this many random poses, every rotational
    /// coordinate drawn from its physiological range at once (seeded; 0: sweeps only; at
    /// most 1000000).
    #[arg(long, default_value_t = 0, value_parser = random_poses)]
    random_poses: usize,
    /// Also walk this many random straight lines through the physiological space (every
    /// rotational coordinate at once, steps of at most 0.5°; seeded) and fail a muscle whose
    /// length changes by more than 1 mm between neighbouring poses (0: none; at most 100000).
    #[arg(long, default_value_t = 0, value_parser = random_lines)]
    random_lines: usize,
}

/// `--random-poses`: a count from 0 to [`check::MAX_RANDOM_POSES`].
fn random_poses(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if n <= check::MAX_RANDOM_POSES => Ok(n),
        _ => Err(format!(
            "`{text}`: give a whole number of poses from 0 to {}",
            check::MAX_RANDOM_POSES
        )),
    }
}

/// `--random-lines`: a count from 0 to [`check::MAX_RANDOM_LINES`].
fn random_lines(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if n <= check::MAX_RANDOM_LINES => Ok(n),
        _ => Err(format!(
            "`{text}`: give a whole number of lines from 0 to {}",
            check::MAX_RANDOM_LINES
        )),
    }
}

/// `--grid-points`: a count from 2 to [`check::MAX_GRID_POINTS`].
fn grid_points(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (2..=check::MAX_GRID_POINTS).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{text}`: give a whole number from 2 to {}",
            check::MAX_GRID_POINTS
        )),
    }
}

/// Runs the checks; `Ok(false)` when some check failed.
pub fn run(args: &Args) -> Result<bool, musculo::Error> {
    let model = match &args.model {
        Some(p) => args.strict.load_movable(p)?,
        None => Model::demo(),
    };
    let options = CheckOptions {
        grid_points: args.grid_points,
        random_poses: args.random_poses,
        random_lines: args.random_lines,
        ..CheckOptions::default()
    };
    // a bar over the coordinates swept (drawn on a terminal only; hidden when piped)
    let bar = indicatif::ProgressBar::new(model.nq() as u64).with_style(
        indicatif::ProgressStyle::with_template("check [{bar:30}] {pos}/{len} coordinates swept")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = check::run_with_progress(&model, &options, &mut |done, _| {
        bar.set_position(done as u64)
    });
    bar.finish_and_clear();
    let report = report?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&to_json(&report)).unwrap_or_default()
        );
    } else {
        print!("{}", to_text(&report, args.verbose));
    }
    Ok(report.passed())
}

fn value_text(c: &check::Check) -> String {
    match c.value {
        Some(v) if v != 0.0 && (v.abs() < 1e-3 || v.abs() >= 1e5) => format!("{v:.3e} {}", c.unit),
        Some(v) => format!("{v:.4} {}", c.unit),
        None => "-".into(),
    }
}

fn to_text(report: &CheckReport, verbose: bool) -> String {
    let mut s = format!("checks of {}\n\n", report.model);
    let shown: Vec<_> = report
        .checks
        .iter()
        .filter(|c| verbose || c.status == Status::Fail)
        .collect();
    if !shown.is_empty() {
        s += &format!(
            "{:<4} {:<21} {:<30} {:<28} {:>16}  {:<28} {}\n",
            "", "family", "check", "subject", "value", "limit", "message"
        );
        for c in shown {
            s += &format!(
                "{:<4} {:<21} {:<30} {:<28} {:>16}  {:<28} {}\n",
                c.status.name(),
                c.family.name(),
                c.name,
                c.subject,
                value_text(c),
                c.limit,
                c.message
            );
        }
        s += "\n";
    }
    s += &format!(
        "{:<22} {:>5} {:>5} {:>5}\n",
        "family", "pass", "fail", "skip"
    );
    for f in Family::ALL {
        let n = report.summary(f);
        s += &format!(
            "{:<22} {:>5} {:>5} {:>5}\n",
            f.name(),
            n.pass,
            n.fail,
            n.skip
        );
    }
    let failed = report.failures().count();
    s += &if failed == 0 {
        "\nall checks passed\n".to_string()
    } else {
        format!("\n{failed} check(s) failed\n")
    };
    s
}

fn to_json(report: &CheckReport) -> serde_json::Value {
    json!({
        "model": report.model,
        "passed": report.passed(),
        "summary": Family::ALL.iter().map(|f| {
            let n = report.summary(*f);
            (f.name().to_string(), json!({"pass": n.pass, "fail": n.fail, "skip": n.skip}))
        }).collect::<serde_json::Map<_, _>>(),
        "checks": report.checks.iter().map(|c| json!({
            "family": c.family.name(),
            "check": c.name,
            "subject_kind": c.subject_kind.name(),
            "subject": c.subject,
            "status": match c.status { Status::Pass => "pass", Status::Fail => "fail", Status::Skip => "skip" },
            "value": c.value.filter(|v| v.is_finite()),
            "unit": c.unit,
            "limit": c.limit,
            "message": c.message,
        })).collect::<Vec<_>>(),
    })
}
