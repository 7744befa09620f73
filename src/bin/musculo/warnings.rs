//! What every command does with what the library's readers accepted but reported: print it on
//! stderr, one line per warning, and past a few, one line counting the rest; warnings about
//! many frames summarised (the count, the worst frame in full, the first few times). Also the
//! `--strict` flag shared by every command that loads a model, and the refusal of a model with
//! nothing to move by the commands whose results are per coordinate.

use musculo::Model;
use musculo::model::{LoadOptions, WarningKind};
use std::fmt::Display;
use std::path::Path;

/// Warnings printed from one list before the rest are only counted (and frame times listed
/// by a frame summary).
const SHOWN: usize = 5;

/// `--strict`, flattened into the arguments of every command that loads a model.
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct Strict {
    /// Refuse a model whose bodies' principal moments of inertia violate the triangle
    /// inequality. Without it such a body is read with a warning naming it, as OpenSim's
    /// release builds read it.
    #[arg(long)]
    pub strict: bool,
}

impl Strict {
    pub fn load_options(self) -> LoadOptions {
        LoadOptions {
            strict: self.strict,
        }
    }

    /// Reads a model file, printing its nonphysical-inertia warnings.
    pub fn load(self, path: &Path) -> Result<Model, musculo::Error> {
        let model = Model::from_osim_file_with(path, &self.load_options())?;
        print_model(&model);
        Ok(model)
    }

    /// Reads model text (named `source` in messages), printing its nonphysical-inertia
    /// warnings.
    pub fn load_str(self, xml: &str, source: &str) -> Result<Model, musculo::Error> {
        let model = Model::from_osim_str_with(xml, source, &self.load_options())?;
        print_model(&model);
        Ok(model)
    }

    /// [`load`](Self::load) for a command whose results are per coordinate (`id`, `so`,
    /// `muscles`, `ik`, `check`): a model with nothing to move is refused
    /// ([`require_movable`]).
    pub fn load_movable(self, path: &Path) -> Result<Model, musculo::Error> {
        let model = self.load(path)?;
        require_movable(&model)?;
        Ok(model)
    }

    /// [`load_str`](Self::load_str) with [`require_movable`].
    pub fn load_str_movable(self, xml: &str, source: &str) -> Result<Model, musculo::Error> {
        let model = self.load_str(xml, source)?;
        require_movable(&model)?;
        Ok(model)
    }
}

/// Refuses a model without an independent coordinate for the commands whose results are per
/// coordinate: with none they would write tables of no column (and ignore every column of
/// the motion) and report success, or pass every check vacuously. `inspect` and
/// `export-mjcf` still read such a model: describing it is meaningful.
pub fn require_movable(model: &Model) -> Result<(), musculo::Error> {
    if model.nq() > 0 {
        return Ok(());
    }
    let why = if model.coordinates.is_empty() {
        "it has no coordinate".to_string()
    } else {
        format!(
            "its {} coordinate(s) are all locked or coupled to others",
            model.coordinates.len()
        )
    };
    Err(musculo::Error::InvalidArgument {
        argument: "model",
        message: format!(
            "{}: the model \"{}\" has nothing to move ({why}): there is no coordinate to \
             compute results for (`musculo inspect` lists what the model holds)",
            model.source, model.name
        ),
    })
}

/// Longest message printed whole (bytes); a longer one is cut in the middle.
const LONGEST: usize = 1000;

/// `text`, or, when it is longer than [`LONGEST`] (a message quoting a megabyte-long token
/// of a broken file), its start and end around a note of how much was left out.
pub fn shorten(text: &str) -> std::borrow::Cow<'_, str> {
    if text.len() <= LONGEST {
        return text.into();
    }
    let head = text.floor_char_boundary(LONGEST * 3 / 5);
    let tail = text.ceil_char_boundary(text.len() - LONGEST / 5);
    format!(
        "{} … [{} bytes left out] … {}",
        &text[..head],
        tail - head,
        &text[tail..]
    )
    .into()
}

/// Prints `warnings`, one line each; past [`SHOWN`], the count of the others.
pub fn print<W: Display>(warnings: &[W]) {
    for w in warnings.iter().take(SHOWN) {
        eprintln!("warning: {}", shorten(&w.to_string()));
    }
    if warnings.len() > SHOWN {
        eprintln!(
            "warning: … and {} more like these ({} in all)",
            warnings.len() - SHOWN,
            warnings.len()
        );
    }
}

/// Prints the warnings about a model that change what it computes: bodies whose inertia no
/// rigid body can have. (`musculo inspect` lists every warning.)
pub fn print_model(model: &Model) {
    let lines: Vec<String> = model
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::NonphysicalInertia)
        .map(|w| format!("{}:{}: {}: {}", model.source, w.line, w.element, w.message))
        .collect();
    print(&lines);
}

/// One frame's warning: its time, a size to rank it by, and the full text.
pub struct FrameWarning {
    pub time: f64,
    pub size: f64,
    pub text: String,
}

/// The lines to print for `warnings` about `what` (e.g. "frame(s) not solved exactly") out
/// of `total` frames: all of them when there are at most two, else the count, the worst in
/// full and the first few times.
pub fn frame_warnings(what: &str, total: usize, warnings: &[FrameWarning]) -> Vec<String> {
    if warnings.len() <= 2 {
        return warnings
            .iter()
            .map(|w| format!("time {:.6} s: {}", w.time, w.text))
            .collect();
    }
    let worst = warnings
        .iter()
        .min_by(|a, b| b.size.total_cmp(&a.size)) // the first of the largest
        .expect("at least three warnings");
    let first: Vec<String> = (warnings.iter().take(SHOWN))
        .map(|w| format!("{:.6}", w.time))
        .collect();
    let more = if warnings.len() > SHOWN { ", …" } else { "" };
    vec![
        format!(
            "{} of {total} {what}, at times {} s{more} (from {:.6} to {:.6} s)",
            warnings.len(),
            first.join(", "),
            warnings[0].time,
            warnings[warnings.len() - 1].time
        ),
        format!("worst at time {:.6} s: {}", worst.time, worst.text),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_message_is_cut_in_the_middle_and_says_how_much() {
        assert_eq!(shorten("short"), "short");
        let long = format!("f.mot:7: `{}` is not a number", "é".repeat(500_000));
        let cut = shorten(&long);
        assert!(cut.len() < LONGEST + 100, "{}", cut.len());
        assert!(cut.starts_with("f.mot:7: `é") && cut.ends_with("é` is not a number"));
        let (head, rest) = cut.split_once(" … [").unwrap();
        let (note, tail) = rest.split_once("] … ").unwrap();
        let left_out: usize = note
            .strip_suffix(" bytes left out")
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(head.len() + left_out + tail.len(), long.len());
    }

    fn w(time: f64, size: f64) -> FrameWarning {
        FrameWarning {
            time,
            size,
            text: format!("off by {size}"),
        }
    }

    #[test]
    fn two_warnings_are_printed_whole() {
        let lines = frame_warnings("frames bad", 10, &[w(0.1, 1.0), w(0.2, 2.0)]);
        assert_eq!(
            lines,
            ["time 0.100000 s: off by 1", "time 0.200000 s: off by 2"]
        );
    }

    #[test]
    fn many_warnings_give_count_worst_and_first_times() {
        let many: Vec<FrameWarning> = (0..200)
            .map(|k| w(k as f64 * 0.01, (k % 37) as f64))
            .collect();
        let lines = frame_warnings("frames bad", 211, &many);
        assert_eq!(lines.len(), 2);
        assert!(
            lines[0].starts_with("200 of 211 frames bad, at times 0.000000, 0.010000, 0.020000, 0.030000, 0.040000 s, …"),
            "{}",
            lines[0]
        );
        assert!(
            lines[0].ends_with("(from 0.000000 to 1.990000 s)"),
            "{}",
            lines[0]
        );
        // the first frame of size 36 is k = 36
        assert_eq!(lines[1], "worst at time 0.360000 s: off by 36");
    }
}
