//! Rust values to Python ones: a run's series to numpy arrays, its report to dicts.
use numpy::PyArray1;
use pma_loop::{Period, Recorder, Signals};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// Rows reserved before a run: 100 s of the bench or the leg at 1 kHz.
const RESERVED_ROWS_MAX: u64 = 100_000;

/// A run's channels, column by column: `t_s`, then a sample schema's columns (the CLI's
/// CSV columns, in its order).
pub struct Columns<F> {
    names: Vec<String>,
    columns: Vec<Vec<f64>>,
    row: Vec<f64>,
    sample: F,
}

impl<F> Columns<F> {
    /// Columns named by `schema`, `sample` making each period's sample; room for
    /// `periods` rows (at most [`RESERVED_ROWS_MAX`] reserved ahead: a run that is
    /// interrupted early does not hold the memory of the whole run).
    pub fn new(schema: &pma_loop::Schema, sample: F, periods: u64) -> Self {
        let mut names = vec!["t_s".to_owned()];
        names.extend(schema.columns());
        let n = usize::try_from(periods.min(RESERVED_ROWS_MAX)).unwrap_or(0);
        Self {
            columns: names.iter().map(|_| Vec::with_capacity(n)).collect(),
            row: vec![0.0; names.len()],
            names,
            sample,
        }
    }

    /// Every column as a 1-D float64 array under its name, into `dict`.
    pub fn into_dict(self, dict: &Bound<'_, PyDict>) -> PyResult<()> {
        let py = dict.py();
        for (name, column) in self.names.into_iter().zip(self.columns) {
            dict.set_item(name, PyArray1::from_vec(py, column))?;
        }
        Ok(())
    }
}

impl<B, O, S, F> Recorder<B, O> for Columns<F>
where
    B: pma_loop::Backend,
    S: Signals,
    F: FnMut(&Period<'_, B, O>) -> S,
{
    fn record(&mut self, p: &Period<'_, B, O>) {
        let sample = (self.sample)(p);
        self.row[0] = p.t_s;
        sample.values(&mut self.row[1..]);
        for (column, v) in self.columns.iter_mut().zip(&self.row) {
            column.push(*v);
        }
    }
}

/// A JSON value (a report as the CLI's `--json` prints it) as Python's `dict`, `list`,
/// `float`, `int`, `str`, `bool` or `None`.
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_u64(), n.as_i64(), n.as_f64()) {
            (Some(u), _, _) => u.into_pyobject(py)?.into_any(),
            (None, Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, None, Some(f)) => f.into_pyobject(py)?.into_any(),
            (None, None, None) => py.None().into_bound(py),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}
