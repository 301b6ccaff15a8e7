//! One error for a value that cannot be, and the checks that produce it: every crate of
//! the workspace validates its files, flags and parameters with these.
use std::borrow::Cow;
use thiserror::Error;

/// A value a file, a flag or a caller gave that cannot describe the thing it describes:
/// not finite, out of its range, or out of its plausible range. `name` is the field as
/// the user wrote it (`plant.valve.dead_time_s`, `patient.knee.spasms.amplitude_nm`).
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{name} = {} is invalid: {expected}", number(*.value))]
pub struct Invalid {
    /// The field.
    pub name: Cow<'static, str>,
    /// The value given.
    pub value: f64,
    /// What it must be, and why.
    pub expected: Cow<'static, str>,
}

impl Invalid {
    /// `name = value` is not `expected`.
    pub fn new(
        name: impl Into<Cow<'static, str>>,
        value: f64,
        expected: impl Into<Cow<'static, str>>,
    ) -> Self {
        Self {
            name: name.into(),
            value,
            expected: expected.into(),
        }
    }

    /// The same error with the field named from `prefix` (`valve` + `dead_time_s` gives
    /// `valve.dead_time_s`).
    pub fn within_section(self, prefix: &str) -> Self {
        Self {
            name: format!("{prefix}.{}", self.name).into(),
            ..self
        }
    }
}

/// A number as a person reads it: `{}` within 1e-6..1e15 in magnitude, exponent form
/// outside (`1e308`, not a 309-digit integer), `NaN`, `inf`.
pub fn number(value: f64) -> String {
    let a = value.abs();
    if value.is_finite() && a != 0.0 && !(1e-6..1e15).contains(&a) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// `value` if `ok`, otherwise `name = value` is not `expected`.
pub fn check(
    ok: bool,
    name: impl Into<Cow<'static, str>>,
    value: f64,
    expected: impl Into<Cow<'static, str>>,
) -> Result<f64, Invalid> {
    if ok {
        Ok(value)
    } else {
        Err(Invalid::new(name, value, expected))
    }
}

/// A finite value.
pub fn finite(name: impl Into<Cow<'static, str>>, value: f64) -> Result<f64, Invalid> {
    check(value.is_finite(), name, value, "must be a finite number")
}

/// A finite value `> 0`.
pub fn positive(name: impl Into<Cow<'static, str>>, value: f64) -> Result<f64, Invalid> {
    check(
        value.is_finite() && value > 0.0,
        name,
        value,
        "must be a finite number > 0",
    )
}

/// A finite value `>= 0`.
pub fn non_negative(name: impl Into<Cow<'static, str>>, value: f64) -> Result<f64, Invalid> {
    check(
        value.is_finite() && value >= 0.0,
        name,
        value,
        "must be a finite number >= 0",
    )
}

/// A finite value within `[low, high]`; `expected` states the range and why.
pub fn within(
    name: impl Into<Cow<'static, str>>,
    value: f64,
    low: f64,
    high: f64,
    expected: impl Into<Cow<'static, str>>,
) -> Result<f64, Invalid> {
    check(
        value.is_finite() && (low..=high).contains(&value),
        name,
        value,
        expected,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_name_the_field_and_the_requirement() {
        assert_eq!(positive("mass_kg", 2.0), Ok(2.0));
        let e = positive("mass_kg", -1.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "mass_kg = -1 is invalid: must be a finite number > 0"
        );
        let e = finite("x", f64::NAN).unwrap_err().within_section("load");
        assert_eq!(e.name, "load.x");
        assert!(within("t", 2.0, 0.0, 1.0, "must be 0 to 1 s").is_err());
        assert!(non_negative("t", 0.0).is_ok());
    }

    #[test]
    fn huge_values_print_in_exponent_form_not_as_309_digits() {
        assert_eq!(number(1e308), "1e308");
        assert_eq!(number(-2.5e20), "-2.5e20");
        assert_eq!(number(3e-9), "3e-9");
        assert_eq!(number(0.02), "0.02");
        assert_eq!(number(4294967295.0), "4294967295");
        let e = within("t", 1e308, 0.0, 1.0, "must be 0 to 1 s").unwrap_err();
        assert_eq!(e.to_string(), "t = 1e308 is invalid: must be 0 to 1 s");
    }
}

/// Serde helpers for fixed-length arrays in files: serde's own `[T; N]` reads the first
/// `N` entries of a longer list and drops the rest, so `range_deg = [-15, 15, 999]` was
/// accepted as `[-15, 15]`. These refuse a list of any other length, naming it.
#[cfg(feature = "serde")]
pub mod exact {
    use serde::de::{Deserialize, Deserializer, Error};

    /// `[T; N]` from a list of exactly `N` entries
    /// (`#[serde(deserialize_with = "pma_model::error::exact::array")]`).
    pub fn array<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        let v: Vec<T> = Vec::deserialize(d)?;
        let n = v.len();
        v.try_into().map_err(|_| {
            D::Error::invalid_length(n, &format!("a list of exactly {N} entries").as_str())
        })
    }

    /// `Option<[T; N]>`, the list when present of exactly `N` entries (with
    /// `#[serde(default, deserialize_with = "pma_model::error::exact::option")]`).
    pub fn option<'de, D, T, const N: usize>(d: D) -> Result<Option<[T; N]>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        array(d).map(Some)
    }
}
