use thiserror::Error;

/// A parameter set that cannot describe a physical device.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// A parameter is NaN or infinite.
    #[error("parameter `{name}` is not finite ({value})")]
    NotFinite {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// A parameter is outside its admissible range.
    #[error("parameter `{name}` = {value} is out of range: {expected}")]
    OutOfRange {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What the parameter must satisfy.
        expected: &'static str,
    },
}

/// Rejects NaN and infinities.
pub(crate) fn finite(name: &'static str, value: f64) -> Result<f64, ModelError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NotFinite { name, value })
    }
}

/// Requires a finite value `> 0`.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, ModelError> {
    finite(name, value)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(ModelError::OutOfRange {
            name,
            value,
            expected: "must be > 0",
        })
    }
}

/// Requires a finite value `>= 0`.
pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, ModelError> {
    finite(name, value)?;
    if value >= 0.0 {
        Ok(value)
    } else {
        Err(ModelError::OutOfRange {
            name,
            value,
            expected: "must be >= 0",
        })
    }
}

/// Requires a finite value within `[low, high]`; `expected` states the range and why.
pub(crate) fn within(
    name: &'static str,
    value: f64,
    low: f64,
    high: f64,
    expected: &'static str,
) -> Result<f64, ModelError> {
    finite(name, value)?;
    if (low..=high).contains(&value) {
        Ok(value)
    } else {
        Err(ModelError::OutOfRange {
            name,
            value,
            expected,
        })
    }
}
