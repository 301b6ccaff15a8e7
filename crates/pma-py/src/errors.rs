//! Rust errors as Python exceptions, with the CLI's one-line messages.
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

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

/// The error as the CLI prints it: its causes joined on one line, a cause left out when
/// the message before it already says it (as `error_line` in `src/main.rs`).
pub fn error_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain().map(|c| c.to_string()) {
        if line.contains(&cause) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&cause);
    }
    pma_control::text::one_line(&line)
}

/// A `PmaError` carrying the CLI's line.
pub fn to_py(e: anyhow::Error) -> PyErr {
    PmaError::new_err(error_line(&e))
}

/// A `PmaError` from any Rust error.
pub fn py_err<E: Into<anyhow::Error>>(e: E) -> PyErr {
    to_py(e.into())
}

/// A leg run's error: `SupervisorError` when the supervisor stopped it, else `PmaError`;
/// the CLI's line either way.
pub fn leg_err(e: pma_leg::LegError) -> PyErr {
    match e {
        pma_leg::LegError::Supervisor(message) => SupervisorError::new_err(message),
        other => py_err(other),
    }
}
