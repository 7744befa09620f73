//! `musculo report`: HTML pages of tensor files — one per clip with its plots, and a dataset
//! page with the distributions of the plausibility metrics and the worst clips linked.

use crate::tool::{FrameProgress, invalid};
use musculo::evaluate::{
    EvaluateOptions, MAX_FLOOR_HEIGHT, MAX_FLOOR_SPEED, SetOptions, collect, evaluate_set,
};
use std::path::{Path, PathBuf};

/// The arguments `evaluate` and `report` share: which model, reference and floor, and how
/// motion files are read.
#[derive(clap::Args)]
pub struct SetArgs {
    /// OpenSim 4.x model. Tensor files: by default each clip's own body, from the model
    /// identity augment records in it (its base model rebuilt with the clip's scaling and
    /// variant, or <clip>.osim beside it); a model given here must be a clip's base model or
    /// its own <clip>.osim, else the clip is refused. Files without an identity: this model,
    /// else <clip>.osim beside the clip, else the built-in model, with a warning. Motion files
    /// are fitted on this model (default: the built-in model).
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
    /// Floor velocity X,Y,Z (m/s, ground frame; the belt of a treadmill walk), or `clip`: each
    /// clip's own (per axis, the median horizontal velocity of its feet in contact). Skating is
    /// measured relative to it; motion files' contacts are estimated on it too.
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub floor_velocity: String,
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
    /// Threads, 1 to 1024 (default: all cores).
    #[arg(long, value_parser = crate::tool::jobs)]
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
            text => Some(
                text.parse::<f64>()
                    .ok()
                    .filter(|h| h.abs() <= MAX_FLOOR_HEIGHT)
                    .ok_or_else(|| {
                        invalid(
                            "--floor",
                            format!(
                                "{text}: give a height in metres within ±{MAX_FLOOR_HEIGHT} \
                                 (no capture volume spans a kilometre) or `clip`"
                            ),
                        )
                    })?,
            ),
        };
        let floor_velocity = match self.floor_velocity.as_str() {
            "clip" => None,
            text => {
                let v: Vec<f64> = text
                    .split(',')
                    .map(|c| c.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .ok()
                    .filter(|v: &Vec<f64>| {
                        v.len() == 3 && v.iter().all(|x| x.abs() <= MAX_FLOOR_SPEED)
                    })
                    .ok_or_else(|| {
                        invalid(
                            "--floor-velocity",
                            format!(
                                "{text}: give X,Y,Z in m/s, each within ±{MAX_FLOOR_SPEED} (ten \
                                 times the fastest treadmill belt), or `clip`"
                            ),
                        )
                    })?;
                Some(musculo::spatial::Vec3::new(v[0], v[1], v[2]))
            }
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
                floor_velocity,
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
    /// Also write every figure as PNG beside its page (`<page>.<figure>.png`), rendered by
    /// headless Chromium (`--chromium`, else MUSCULO_CHROMIUM, else `chromium` on the PATH).
    #[arg(long)]
    png: bool,
    /// The Chromium executable for --png.
    #[arg(long, requires = "png")]
    chromium: Option<PathBuf>,
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
    let mut pngs = 0;
    if args.png {
        let browser = chromium(args.chromium.as_deref())?;
        let bar = FrameProgress::new("png");
        for (i, page) in written.iter().enumerate() {
            pngs += write_pngs(&browser, page)?;
            bar.update(i + 1, written.len());
        }
        bar.finish();
    }
    let warnings: Vec<String> = (report.clips.iter())
        .flat_map(|c| c.warnings.iter().map(move |w| format!("{}: {w}", c.clip)))
        .collect();
    crate::warnings::print(&warnings);
    for (clip, reason) in &report.failed {
        eprintln!("failed: {clip}: {reason}");
    }
    if args.png {
        println!("{pngs} figure(s) written as PNG beside their pages");
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

/// The Chromium executable: `given`, else MUSCULO_CHROMIUM, else `chromium` or
/// `chromium-browser` on the PATH.
fn chromium(given: Option<&Path>) -> Result<PathBuf, musculo::Error> {
    if let Some(p) = given {
        return Ok(p.to_path_buf());
    }
    if let Some(p) = std::env::var_os("MUSCULO_CHROMIUM") {
        return Ok(PathBuf::from(p));
    }
    std::env::var_os("PATH")
        .and_then(|path| {
            std::env::split_paths(&path)
                .flat_map(|d| [d.join("chromium"), d.join("chromium-browser")])
                .find(|p| p.is_file())
        })
        .ok_or_else(|| {
            invalid(
                "--png",
                "needs headless Chromium (Debian: apt install chromium); name it with \
                 --chromium or MUSCULO_CHROMIUM",
            )
        })
}

/// Renders every figure of the HTML page `page` to `<page without .html>.<figure>.png`
/// beside it; returns how many.
fn write_pngs(browser: &Path, page: &Path) -> Result<usize, musculo::Error> {
    let io = |path: &Path, source| musculo::Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let html = std::fs::read_to_string(page).map_err(|e| io(page, e))?;
    let scratch = std::env::temp_dir().join(format!("musculo-png-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).map_err(|e| io(&scratch, e))?;
    let stem = page.with_extension("");
    let mut count = 0;
    for (id, svg) in musculo::report::figures(&html) {
        let (w, h) = musculo::report::svg_size(&svg).ok_or_else(|| {
            invalid(
                "--png",
                format!("{}: figure {id} has no size", page.display()),
            )
        })?;
        let one = scratch.join(format!("{id}.html"));
        let text = format!("<!DOCTYPE html><html><body style=\"margin:0\">{svg}</body></html>");
        std::fs::write(&one, text).map_err(|e| io(&one, e))?;
        let target = PathBuf::from(format!("{}.{id}.png", stem.display()));
        // drawn under a hidden name beside the target, then renamed: whole or not at all
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let partial = target.with_file_name(format!(".{name}.tmp-{}.png", std::process::id()));
        let absolute = std::path::absolute(&partial).map_err(|e| io(&partial, e))?;
        let _ = std::fs::remove_file(&absolute);
        let out = std::process::Command::new(browser)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
            ])
            .arg(format!("--window-size={w},{h}"))
            .arg(format!("--screenshot={}", absolute.display()))
            .arg(format!("file://{}", one.display()))
            .output()
            .map_err(|e| io(browser, e))?;
        if !absolute.is_file() {
            return Err(invalid(
                "--png",
                format!(
                    "{} drew no {}: {}",
                    browser.display(),
                    target.display(),
                    String::from_utf8_lossy(&out.stderr)
                        .lines()
                        .last()
                        .unwrap_or("")
                ),
            ));
        }
        std::fs::rename(&absolute, &target).map_err(|e| io(&target, e))?;
        count += 1;
    }
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(count)
}
