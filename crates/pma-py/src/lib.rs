//! `pma_exo`, the Python module of pma-exo: the CLI's runs (`single`, `simulate`,
//! `pendulum`) returning numpy arrays and the CLI's figures, and a muscle bench a Python
//! controller steps period by period (`Bench`) behind the rig's supervisor.
//!
//! Every run is assembled by `pma_exo::setup` (the CLI's library), so a run from Python
//! checks the same arguments, loads the same files and gives the same figures as the
//! CLI; every error is a `pma_exo.PmaError` with the CLI's one-line message.
use pyo3::prelude::*;

mod bench;
mod convert;
mod errors;
mod leg;
mod runs;

pub use errors::{PmaError, SupervisorError};

/// pma-exo: pneumatic-muscle control (APRC-NDO, Cao et al. 2020) from Python.
#[pymodule]
fn pma_exo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // NumPy's C API is looked up now, at import: looked up at a run's end, a pending
    // Ctrl-C would interrupt its import.
    numpy::PyArray1::<f64>::zeros(py, [0], false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("PmaError", py.get_type::<PmaError>())?;
    m.add("SupervisorError", py.get_type::<SupervisorError>())?;
    m.add_function(wrap_pyfunction!(runs::single, m)?)?;
    m.add_function(wrap_pyfunction!(runs::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(runs::pendulum, m)?)?;
    m.add_function(wrap_pyfunction!(runs::size, m)?)?;
    m.add_function(wrap_pyfunction!(runs::identify, m)?)?;
    m.add_function(wrap_pyfunction!(runs::fit_gait, m)?)?;
    m.add_function(wrap_pyfunction!(runs::sweep, m)?)?;
    m.add_class::<bench::Bench>()?;
    m.add_class::<leg::Leg>()?;
    m.add(
        "CONTROLLERS",
        pma_control::ControllerKind::ALL
            .iter()
            .map(|k| k.as_str())
            .collect::<Vec<_>>(),
    )?;
    m.add("PLANTS", pma_bench::PRESET_NAMES.to_vec())?;
    Ok(())
}
