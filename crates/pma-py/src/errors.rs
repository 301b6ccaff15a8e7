//! Rust errors as Python exceptions, with the CLI's one-line messages.
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::{PyErr, PyResult};

create_exception!(
    pma_exo,
    PmaError,
    PyValueError,
    "An error of pma-exo: a bad argument, file or value, or a run that failed; its message is the CLI's one line."
);
create_exception!(
    pma_exo,
    SupervisorError,
    PmaError,
    "The supervisor stopped a run (a reading outside its window, a NaN reading): the muscles are vented."
);

/// A `PmaError` carrying the CLI's line (`pma_exo::error_line`).
pub fn to_py(e: anyhow::Error) -> PyErr {
    PmaError::new_err(pma_exo::error_line(&e))
}

/// A `PmaError` from any Rust error.
pub fn py_err<E: Into<anyhow::Error>>(e: E) -> PyErr {
    to_py(e.into())
}

/// A supervisor's fault, latched until a reset: every later call raises it again.
#[derive(Default)]
pub struct Latch(Option<String>);

impl Latch {
    /// `Ok` unless latched; else the fault, naming `what` was stopped.
    pub fn check(&self, what: &str) -> PyResult<()> {
        match &self.0 {
            Some(f) => Err(SupervisorError::new_err(format!(
                "the supervisor stopped the {what} ({f}): call reset() to start again"
            ))),
            None => Ok(()),
        }
    }

    /// Latches `message` and returns it as the exception to raise now.
    pub fn set(&mut self, message: String) -> PyErr {
        self.0 = Some(message.clone());
        SupervisorError::new_err(message)
    }

    /// Clears the fault (a reset).
    pub fn clear(&mut self) {
        self.0 = None;
    }
}

/// A leg run's error: `SupervisorError` when the supervisor stopped it, else `PmaError`;
/// the CLI's line either way.
pub fn leg_err(e: pma_leg::LegError) -> PyErr {
    match e {
        pma_leg::LegError::Supervisor(message) => SupervisorError::new_err(message),
        other => py_err(other),
    }
}
