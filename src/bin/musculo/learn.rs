//! `musculo train-ae`, `reconstruct`, `train-diffusion` and `generate`: the learned module lives in the workspace
//! member `learn/` (burn, kept out of the default build), whose program `musculo-learn` these
//! subcommands run with the same arguments. It is looked for beside this program, then on PATH.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// The arguments passed on unchanged.
#[derive(clap::Args)]
#[command(disable_help_flag = true)]
pub struct Args {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    args: Vec<OsString>,
}

/// Runs `musculo-learn SUBCOMMAND ARGS…` and returns its exit status.
pub fn run(subcommand: &str, args: &Args) -> ExitCode {
    let name = format!("musculo-learn{}", std::env::consts::EXE_SUFFIX);
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(|d| d.join(&name)))
        .filter(|p| p.is_file());
    let program = beside.unwrap_or_else(|| PathBuf::from(&name));
    match Command::new(&program)
        .arg(subcommand)
        .args(&args.args)
        .status()
    {
        Ok(status) if status.success() => ExitCode::SUCCESS,
        Ok(status) => ExitCode::from(status.code().unwrap_or(1).clamp(1, 255) as u8),
        Err(e) => {
            eprintln!(
                "error: cannot run {} ({e}); build the learned module first: \
                 cargo build --release -p musculo-learn",
                program.display()
            );
            ExitCode::FAILURE
        }
    }
}
