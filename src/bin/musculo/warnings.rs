//! What every command does with what the library's readers accepted but reported: print it on
//! stderr, one line per warning, and past a few, one line counting the rest. Also the
//! `--strict` flag shared by every command that loads a model.

use musculo::Model;
use musculo::model::{LoadOptions, WarningKind};
use std::fmt::Display;
use std::path::Path;

/// Warnings printed from one list before the rest are only counted.
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
}

/// Prints `warnings`, one line each; past [`SHOWN`], the count of the others.
pub fn print<W: Display>(warnings: &[W]) {
    for w in warnings.iter().take(SHOWN) {
        eprintln!("warning: {w}");
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
