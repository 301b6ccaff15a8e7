use thiserror::Error;

/// Errors of a study: its files, its runs and their parameters, never a panic.
#[derive(Debug, Error)]
pub enum StudyError {
    /// A run on the bench failed (its plant, its settings).
    #[error(transparent)]
    Bench(#[from] pma_bench::SimError),
    /// A run on the leg failed.
    #[error(transparent)]
    Leg(#[from] pma_leg::LegError),
    /// A gain set is invalid.
    #[error(transparent)]
    Controller(#[from] pma_control::ConfigError),
    /// The run's duration or period is invalid.
    #[error(transparent)]
    Settings(#[from] pma_loop::SettingsError),
    /// A value is invalid.
    #[error(transparent)]
    Invalid(#[from] pma_model::Invalid),
    /// A file could not be read or written.
    #[error("cannot {operation} `{path}`: {message}")]
    Io {
        /// `read` or `write`.
        operation: &'static str,
        /// Path.
        path: String,
        /// OS message.
        message: String,
    },
    /// An output file or directory holds something else than it should.
    #[error("`{path}`: {message}")]
    Output {
        /// Path.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// The operator stopped the work (SIGINT/SIGTERM) before it had a result.
    #[error("interrupted by the operator")]
    Interrupted,
    /// A study's file could not be parsed or holds something it cannot run.
    #[error("{what} `{file}`: {message}")]
    Parse {
        /// What the file is (`sweep file`).
        what: &'static str,
        /// File name.
        file: String,
        /// What is wrong.
        message: String,
    },
}
