//! A study's files: errors that name them (the files themselves are written by the caller).
use crate::StudyError;
use std::path::Path;

/// A sweep's file that cannot be read.
pub(crate) fn read_error(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Io {
        operation: "read",
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// A sweep's file or directory that cannot be written.
pub(crate) fn write_error(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Io {
        operation: "write",
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// An output directory that does not hold what it should.
pub(crate) fn dir_error(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Output {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
