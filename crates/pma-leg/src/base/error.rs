use thiserror::Error;

/// Errors of the leg simulation: bad files and bad parameters, never a panic.
#[derive(Debug, Error)]
pub enum LegError {
    /// A file could not be read.
    #[error("cannot read `{path}`: {message}")]
    Io {
        /// Path.
        path: String,
        /// OS message.
        message: String,
    },
    /// A TOML file could not be parsed (syntax, unknown field, wrong type).
    #[error("`{file}`: {message}")]
    Parse {
        /// File.
        file: String,
        /// Parser message, on one line.
        message: String,
    },
    /// The URDF is malformed or lacks what the leg needs.
    #[error("URDF `{file}`: {message}")]
    Urdf {
        /// File.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// A muscle refers to something the URDF does not have, or is inconsistent.
    #[error("muscle `{muscle}`: {message}")]
    Muscle {
        /// Muscle name.
        muscle: String,
        /// What is wrong.
        message: String,
    },
    /// An error in a named file.
    #[error("`{file}`: {source}")]
    InFile {
        /// File.
        file: String,
        /// The error.
        source: Box<LegError>,
    },
    /// A `[low, high]` range is inverted or out of bounds.
    #[error("{name} = [{low}, {high}] is invalid: {expected}")]
    Range {
        /// Parameter.
        name: String,
        /// Low end.
        low: f64,
        /// High end.
        high: f64,
        /// Requirement.
        expected: &'static str,
    },
    /// A leg run too short for its figures, which start after the first stride.
    #[error("a run of {duration_s} s is shorter than two strides of {scenario} ({two_strides_s} s): its figures start after the first stride")]
    ShorterThanTwoStrides {
        /// Scenario name.
        scenario: String,
        /// The run's duration (s).
        duration_s: f64,
        /// Two stride periods (s).
        two_strides_s: f64,
    },
    /// A set point the hardware cannot reach (a stiffness beyond the muscles' range).
    #[error("{name} = {value} is out of reach: {message}")]
    Unreachable {
        /// The field.
        name: String,
        /// Its value.
        value: f64,
        /// What the hardware reaches.
        message: String,
    },
    /// A choice this computation cannot run.
    #[error("{name} = {value}: {message}")]
    Unsupported {
        /// Parameter.
        name: String,
        /// The choice.
        value: String,
        /// Why, and what it runs.
        message: String,
    },
    /// A parameter is needed and absent.
    #[error("{name} is missing: {hint}")]
    Missing {
        /// Parameter.
        name: String,
        /// What to give.
        hint: &'static str,
    },
    /// The simulation's state left physical bounds: the run failed.
    #[error("the simulation left physical bounds at {t_s:.3} s: {what}; the run failed (its figures would be meaningless)")]
    LeftPhysics {
        /// Time (s).
        t_s: f64,
        /// What.
        what: String,
    },
    /// The patient collapsed on the treadmill: the trainer's safety stopped the run (the
    /// belt stops, the harness takes the weight, every muscle vents; docs/safety.md).
    #[error("the patient collapsed at {t_s:.2} s: {what}; the trainer stopped the belt, the harness took the weight and the muscles vented")]
    Collapse {
        /// Time (s).
        t_s: f64,
        /// What gave way.
        what: String,
    },
    /// A controller gain set is invalid.
    #[error(transparent)]
    Controller(#[from] pma_control::ConfigError),
    /// The supervisor stopped the run (a NaN encoder, a joint out of its window).
    #[error("{0}")]
    Supervisor(String),
    /// A value is invalid (non-finite, out of its range or of its plausible range).
    #[error(transparent)]
    Invalid(#[from] pma_model::Invalid),
    /// The run's duration or period is invalid.
    #[error(transparent)]
    Settings(#[from] pma_loop::SettingsError),
}

pub(crate) use pma_control::text::one_line;

impl LegError {
    /// The error a supervised run ended with: the plant's own, or the supervisor's fault.
    pub fn from_fault(fault: pma_control::Fault<LegError>) -> Self {
        match fault {
            pma_control::Fault::Backend(e) => e,
            other => LegError::Supervisor(other.to_string()),
        }
    }

    /// This error, naming the file it comes from.
    pub fn in_file(self, file: &str) -> Self {
        LegError::InFile {
            file: file.to_owned(),
            source: Box::new(self),
        }
    }
}

/// A parameter's invalid value, with what it must be.
pub(crate) fn invalid(
    name: impl Into<std::borrow::Cow<'static, str>>,
    value: f64,
    expected: &'static str,
) -> LegError {
    pma_model::Invalid::new(name, value, expected).into()
}
