//! The learned module's error type: every reader, trainer and the command line return it.

use std::path::PathBuf;

/// Errors of the learned module, each naming what it is about.
#[derive(Debug, thiserror::Error)]
pub enum LearnError {
    #[error(transparent)]
    Musculo(#[from] musculo::Error),
    #[error("{what}: {message}")]
    Invalid { what: String, message: String },
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
}

impl LearnError {
    pub fn invalid(what: impl Into<String>, message: impl Into<String>) -> LearnError {
        LearnError::Invalid {
            what: what.into(),
            message: message.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, LearnError>;
