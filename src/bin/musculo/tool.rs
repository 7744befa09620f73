//! Pieces shared by the commands that run OpenSim-style tools (`id`, `so`): the error for a
//! missing input, the frame progress bar, and writing the outputs.

use indicatif::{ProgressBar, ProgressStyle};
use musculo::io::output::OutputSet;
use std::path::{Path, PathBuf};

/// The error for an input given neither as a flag nor by the setup file.
pub fn missing(argument: &'static str, what: &str) -> musculo::Error {
    musculo::Error::InvalidArgument {
        argument,
        message: format!("no {what}: give {argument} or a --setup file that names one"),
    }
}

/// A progress bar over frames, and the `progress(done, total)` callback the library's
/// whole-motion functions take.
pub struct FrameProgress {
    bar: ProgressBar,
}

impl FrameProgress {
    pub fn new(message: &'static str) -> FrameProgress {
        let bar = ProgressBar::new(0).with_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} frames")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message(message);
        FrameProgress { bar }
    }

    pub fn update(&self, done: usize, total: usize) {
        if done == 1 {
            self.bar.set_length(total as u64);
        }
        // Redrawing every frame would cost more than the frame.
        if done.is_multiple_of(64) || done == total {
            self.bar.set_position(done as u64);
        }
    }

    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// Names the outputs together (see `musculo::io::output`) and says on stderr what was tidied
/// from interrupted runs; returns the files written.
pub fn commit(outputs: OutputSet) -> Result<Vec<PathBuf>, musculo::Error> {
    let done = outputs.commit()?;
    for note in &done.notes {
        eprintln!("note: {note}");
    }
    Ok(done.files)
}

/// Writes one output file whole or not at all, refusing to overwrite any of `inputs`.
pub fn write_output(path: &Path, bytes: &[u8], inputs: &[&Path]) -> Result<(), musculo::Error> {
    let mut outputs = OutputSet::new(inputs.iter().copied());
    outputs.add(path, bytes)?;
    commit(outputs).map(|_| ())
}

/// The last component of `path` without its extension (`walk` for `data/walk.mot`).
pub fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The coordinates file, with the model's coordinates it lacks held at their defaults when
/// asked (saying which on stderr).
pub fn read_coordinates(
    model: &musculo::Model,
    path: &Path,
    missing_at_default: bool,
) -> Result<musculo::io::Table, musculo::Error> {
    let mut table = musculo::io::Table::read(path)?;
    crate::warnings::print(&table.warnings);
    if missing_at_default {
        let added = musculo::solve::kinematics::fill_missing_coordinates(model, &mut table);
        if !added.is_empty() {
            eprintln!(
                "{} coordinate(s) not in {} held at their defaults: {}",
                added.len(),
                path.display(),
                added.join(" ")
            );
        }
    }
    Ok(table)
}

/// The text of `--model FILE` and its name for messages, or the built-in default model's.
pub fn model_text(model: Option<&Path>) -> Result<(String, String), musculo::Error> {
    match model {
        Some(p) => Ok((musculo::text::read_text(p)?, p.display().to_string())),
        None => Ok((
            musculo::DEFAULT_MODEL_OSIM.to_string(),
            "models/musculo_fullbody.osim".to_string(),
        )),
    }
}

/// `--map`: a JSON file, else a built-in map's name; without it, the format's built-in map
/// (None for marker formats, matched by name).
pub fn skeleton_map(
    map: Option<&str>,
    format: musculo::motion::Format,
) -> Result<Option<musculo::motion::skeleton::SkeletonMap>, musculo::Error> {
    use musculo::motion::skeleton::SkeletonMap;
    match map {
        Some(name) if name.ends_with(".json") || Path::new(name).exists() => {
            Ok(Some(SkeletonMap::read(Path::new(name))?))
        }
        Some(name) => Ok(Some(SkeletonMap::builtin(name)?)),
        None => format.default_map().map(SkeletonMap::builtin).transpose(),
    }
}

/// An invalid command-line argument.
pub fn invalid(argument: &'static str, message: impl Into<String>) -> musculo::Error {
    musculo::Error::InvalidArgument {
        argument,
        message: message.into(),
    }
}

/// The motion readers' options from `--length-unit` (m, cm, mm, in or metres per unit).
pub fn read_options(
    length_unit: Option<&str>,
) -> Result<musculo::motion::ReadOptions, musculo::Error> {
    Ok(musculo::motion::ReadOptions {
        length_unit: length_unit
            .map(|u| {
                musculo::motion::LengthUnit::parse(u).ok_or_else(|| {
                    invalid(
                        "--length-unit",
                        format!("`{u}`: use m, cm, mm, in or a number of metres per unit from 1e-6 to 1e3"),
                    )
                })
            })
            .transpose()?,
    })
}

/// `--lowpass HZ` of `id` and `so`: a positive cutoff, or a negative number for no filtering
/// (OpenSim's −1). 0, NaN and infinities are refused when the arguments are parsed.
pub fn lowpass_hz(text: &str) -> Result<f64, String> {
    let hz: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of Hz"))?;
    if !hz.is_finite() || hz == 0.0 {
        return Err(format!(
            "{hz} Hz: give a positive finite cutoff, or a negative number for no filtering"
        ));
    }
    Ok(hz)
}

/// A time of `--time-range START END` (s): a finite number, refused when the arguments are
/// parsed (NaN selected no frame and was reported as an empty range; give the motion's last
/// time, or leave the flag out, for the whole motion).
pub fn time_s(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(t) if t.is_finite() => Ok(t),
        _ => Err(format!("`{text}`: give a finite time in seconds")),
    }
}

/// `--jobs`: 1 to 1024 worker threads (a larger count would start thousands of threads
/// before the system refused one).
pub fn jobs(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=1024).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{text}`: give a whole number of threads from 1 to 1024"
        )),
    }
}
