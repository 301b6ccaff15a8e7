use thiserror::Error;

/// Errors of the simulation layer: bad configuration, never a panic.
#[derive(Debug, Error)]
pub enum SimError {
    /// A model parameter is invalid.
    #[error("plant `{plant}`: {source}")]
    Model {
        /// Plant name.
        plant: String,
        /// Cause.
        #[source]
        source: pma_model::ModelError,
    },
    /// A controller gain set is invalid.
    #[error(transparent)]
    Controller(#[from] pma_control::ConfigError),
    /// No preset of that name.
    #[error("unknown plant `{0}` (expected one of: ideal, mismatch, realistic, realistic_known_lag, or a .toml file)")]
    UnknownPlant(String),
    /// A file could not be read.
    #[error("cannot read `{path}`: {message}")]
    Io {
        /// Path.
        path: String,
        /// OS message.
        message: String,
    },
    /// A plant file could not be parsed.
    #[error("plant file `{file}`: {message}")]
    Parse {
        /// File name.
        file: String,
        /// Parser message.
        message: String,
    },
    /// The run's duration or period is invalid.
    #[error(transparent)]
    Settings(#[from] pma_loop::SettingsError),
    /// A run parameter is invalid.
    #[error("{name} = {value} is invalid: {expected}")]
    InvalidRun {
        /// Parameter.
        name: &'static str,
        /// Value.
        value: f64,
        /// Requirement.
        expected: &'static str,
    },
}
