use thiserror::Error;

/// Errors of the bench: bad plant files and parameters, never a panic.
#[derive(Debug, Error)]
pub enum SimError {
    /// A model parameter is invalid.
    #[error("plant `{plant}`: {source}")]
    Model {
        /// Plant name.
        plant: String,
        /// Cause.
        #[source]
        source: pma_model::Invalid,
    },
    /// A controller gain set is invalid.
    #[error(transparent)]
    Controller(#[from] pma_control::ConfigError),
    /// No preset of that name.
    #[error("unknown plant `{0}` (expected one of: ideal, mismatch, realistic, realistic_known_lag, or a .toml file)")]
    UnknownPlant(String),
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
    /// A file could not be parsed.
    #[error("{what} `{file}`: {message}")]
    Parse {
        /// What the file is (`plant file`, `sweep file`, `gait file`).
        what: &'static str,
        /// File name.
        file: String,
        /// Parser message.
        message: String,
    },
    /// The run's duration or period is invalid.
    #[error(transparent)]
    Settings(#[from] pma_loop::SettingsError),
    /// A value is invalid.
    #[error(transparent)]
    Invalid(#[from] pma_model::Invalid),
}
