//! A study's files: errors that name them, and results written in full or not at all.
use crate::StudyError;
use std::io::Write;
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

/// Writes `text` to `path` in full or not at all: a temporary file beside it, renamed.
pub(crate) fn write_atomically(path: &Path, text: &str) -> Result<(), StudyError> {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Err(dir_error(
            path,
            "is not a regular file: refusing to replace it",
        ));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut temp = tempfile::Builder::new()
        .prefix(".sweep.")
        .suffix(".part")
        .tempfile_in(dir)
        .map_err(|e| write_error(path, e))?;
    temp.write_all(text.as_bytes())
        .and_then(|()| temp.as_file().sync_all())
        .map_err(|e| write_error(path, e))?;
    temp.persist(path).map_err(|e| write_error(path, e.error))?;
    Ok(())
}
