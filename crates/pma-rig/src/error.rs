use crate::daq::DaqError;
use thiserror::Error;

/// Errors of the rig layer: configuration, board, log, replay. Faults of a running loop
/// are [`crate::Fault`]s.
#[derive(Debug, Error)]
pub enum RigError {
    /// A file could not be read or written.
    #[error("`{path}`: {message}")]
    Io {
        /// Path.
        path: String,
        /// OS message.
        message: String,
    },
    /// A configuration file could not be parsed (syntax, unknown field, wrong type).
    #[error("`{file}`: {message}")]
    Parse {
        /// File.
        file: String,
        /// Parser message, on one line.
        message: String,
    },
    /// A value is invalid (non-finite, out of its range or of its plausible range).
    #[error(transparent)]
    Invalid(#[from] pma_model::Invalid),
    /// A field is missing.
    #[error("{field} is missing: {why}")]
    Missing {
        /// Field.
        field: &'static str,
        /// Why it is needed.
        why: &'static str,
    },
    /// A field names something that does not exist or does not fit.
    #[error("{field}: {message}")]
    Field {
        /// Field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// An error in a named configuration file.
    #[error("`{file}`: {source}")]
    InFile {
        /// File.
        file: String,
        /// The error.
        #[source]
        source: Box<RigError>,
    },
    /// The board.
    #[error(transparent)]
    Daq(#[from] DaqError),
    /// The controller's gains.
    #[error(transparent)]
    Controller(#[from] pma_control::ConfigError),
    /// The simulated plant.
    #[error(transparent)]
    Bench(#[from] pma_bench::SimError),
    /// The loop settings.
    #[error(transparent)]
    Settings(#[from] pma_loop::SettingsError),
    /// A log file that replay cannot use.
    #[error("log `{path}`: {message}")]
    Log {
        /// Path.
        path: String,
        /// What is wrong.
        message: String,
    },
}

impl RigError {
    /// This error, naming the file it comes from.
    pub fn in_file(self, file: &str) -> Self {
        RigError::InFile {
            file: file.to_owned(),
            source: Box::new(self),
        }
    }
}
