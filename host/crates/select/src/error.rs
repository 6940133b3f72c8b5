//! What can go wrong in a selection: every variant that concerns a file names it, so the
//! command line can print one clear line.

use std::path::PathBuf;

use touchc_input::recording::RecordingError;

/// Errors of loading a data set, cross-validating, and saving or applying a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelectError {
    /// A recording could not be loaded.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A folder or manifest could not be read.
    #[error("{path}: cannot read")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A manifest line is not `path,label[,group]`.
    #[error("{path}: line {line}: {problem}")]
    Manifest {
        /// The manifest.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        problem: String,
    },
    /// The data set has fewer than two classes with recordings.
    #[error("{data}: {found} class(es) with recordings ({classes}); scoring needs at least two")]
    TooFewClasses {
        /// The data set (folder or manifest).
        data: PathBuf,
        /// Classes found.
        found: usize,
        /// Their names.
        classes: String,
    },
    /// A class has no recording.
    #[error("{data}: class {class:?} has no recording")]
    EmptyClass {
        /// The data set (folder or manifest).
        data: PathBuf,
        /// The class.
        class: String,
    },
    /// Two recordings of one data set have different sensor shapes.
    #[error("{second}: frames of {rows2} x {cols2} cells, but {first} has {rows1} x {cols1}: a data set shares one sensor")]
    MixedShapes {
        /// The first recording.
        first: String,
        /// Its rows.
        rows1: usize,
        /// Its columns.
        cols1: usize,
        /// The recording that differs.
        second: String,
        /// Its rows.
        rows2: usize,
        /// Its columns.
        cols2: usize,
    },
    /// The folds cannot be formed.
    #[error("{0}")]
    Folds(String),
    /// A setting is out of its range.
    #[error("{0}")]
    Setting(String),
    /// Training was stopped from outside (an interrupt).
    #[error("stopped before the end")]
    Cancelled,
    /// The network library failed.
    #[error("the network: {0}")]
    Network(String),
    /// A model file is not one this version wrote, or does not fit the recordings.
    #[error("{path}: {problem}")]
    ModelFile {
        /// The model file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}
