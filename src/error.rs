//! The crate's error type. Every error carries the context a user needs to find the
//! problem: the file, the element and its line for model XML; the argument name for
//! bad inputs to an algorithm.

use std::path::PathBuf;

/// Result alias used throughout musculo.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in musculo. Bad input is always an `Err`, never a panic.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// The file is not well-formed XML.
    #[error("{file}:{line}:{column}: malformed XML: {message}")]
    Xml {
        file: String,
        line: u32,
        column: u32,
        message: String,
    },

    /// An output file could not be written, or may not be: it would overwrite one of the
    /// command's inputs, it is a folder, or its name leaves its results folder.
    #[error("cannot write output {}: {message}", path.display())]
    Output { path: PathBuf, message: String },

    /// The XML is well-formed but describes an invalid or unsupported model.
    /// `element` names the element (e.g. `CustomJoint "knee_r" > TransformAxis "translation1"`).
    #[error("{file}:{line}: {element}: {message}")]
    Model {
        file: String,
        line: u32,
        element: String,
        message: String,
    },

    /// An argument passed to a library function has the wrong size or an invalid value.
    #[error("invalid argument `{argument}`: {message}")]
    InvalidArgument {
        argument: &'static str,
        message: String,
    },

    /// A reference table (e.g. `data/check/*.csv`) is malformed.
    #[error("{table}:{line}: {message}")]
    Table {
        table: String,
        line: usize,
        message: String,
    },

    /// A motion file (`.npy`, `.bvh`, `.c3d`, …) holds data musculo cannot use. `location`
    /// says where: `line 40`, `frame 12, joint "left_knee"`, `header`, `array shape`.
    #[error("{file}: {location}: {message}")]
    Motion {
        file: String,
        location: String,
        message: String,
    },

    /// A text file (model, motion, setup, …) is not UTF-8. `line` and `column` (1-based,
    /// column in characters) and `offset` (bytes from the start of the file) locate the
    /// first byte that is not.
    #[error("{file}:{line}:{column}: byte offset {offset}: {message}")]
    Encoding {
        file: String,
        line: u32,
        column: u32,
        offset: usize,
        message: String,
    },

    /// A file is over one of the limits of [`crate::limits`] (size, archive members, inflated
    /// bytes, XML attributes or depth, bodies, BVH joints or depth), or is not a regular
    /// file; refused before the work it would have cost.
    #[error("{file}: {location}: {message}")]
    Limit {
        file: String,
        location: String,
        message: String,
    },

    /// MuJoCo (feature `mujoco`) refused the model or is the wrong version.
    #[error("MuJoCo: {message}")]
    Mujoco { message: String },

    /// An algorithm was called before the stage it depends on was computed for this Data
    /// (e.g. a Jacobian before forward kinematics).
    #[error("{algorithm} needs {needs} to be computed first for this Data")]
    StageNotComputed {
        algorithm: &'static str,
        needs: &'static str,
    },

    /// The default model's parameter tables are unreadable or inconsistent.
    #[error(transparent)]
    ModelBuild(#[from] BuildError),
}

impl Error {
    pub(crate) fn invalid(argument: &'static str, message: impl Into<String>) -> Self {
        Error::InvalidArgument {
            argument,
            message: message.into(),
        }
    }
}

/// A table of the default model (`model::builder`) could not be read: the file, and the row
/// (1-based, header = row 1) when known.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{path}, row {row}: {message}")]
    Row {
        path: PathBuf,
        row: usize,
        message: String,
    },
}

/// The default model's tables (`model::builder`) are inconsistent (each message names the
/// table and the row's key).
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error(transparent)]
    Table(#[from] TableError),
    #[error("{table}: {message}")]
    Inconsistent {
        table: &'static str,
        message: String,
    },
}
