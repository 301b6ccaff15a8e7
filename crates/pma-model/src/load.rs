use crate::error::{non_negative, positive, within, Invalid};

/// Heaviest load accepted (kg): a DMSP-40 pulls at most 6 kN (Festo Info 501), about 600 kg.
pub const MAX_LOAD_KG: f64 = 600.0;
const LOAD_RANGE: &str = "must be 0 to 600 kg (a DMSP-40 lifts at most about 600 kg)";

/// Standard gravity (m/s^2).
pub const GRAVITY_M_S2: f64 = 9.81;

/// A mass added to the load at a given time (the paper's Fig. 8 load steps).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct LoadStep {
    /// When the mass is added (s).
    pub time_s: f64,
    /// Added mass (kg).
    pub extra_mass_kg: f64,
}

/// The mass hanging on the muscle, possibly stepping up during a run.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct LoadProfile {
    /// Mass at the start (kg).
    pub mass_kg: f64,
    /// Optional single step (the paper's experiments use one).
    #[cfg_attr(feature = "serde", serde(default))]
    pub step: Option<LoadStep>,
}

impl LoadProfile {
    /// A constant load.
    pub fn constant(mass_kg: f64) -> Self {
        Self {
            mass_kg,
            step: None,
        }
    }

    /// The same load with `extra_mass_kg` added at `time_s`.
    pub fn with_step(self, time_s: f64, extra_mass_kg: f64) -> Self {
        Self {
            step: Some(LoadStep {
                time_s,
                extra_mass_kg,
            }),
            ..self
        }
    }

    /// Mass (kg) at time `t_s`.
    pub fn mass_at(&self, t_s: f64) -> f64 {
        match self.step {
            Some(s) if t_s >= s.time_s => self.mass_kg + s.extra_mass_kg,
            _ => self.mass_kg,
        }
    }

    /// Checks for a positive mass and a non-negative, finite step.
    pub fn validate(&self) -> Result<(), Invalid> {
        positive("mass_kg", self.mass_kg)?;
        within("mass_kg", self.mass_kg, 0.0, MAX_LOAD_KG, LOAD_RANGE)?;
        if let Some(s) = self.step {
            non_negative("step.time_s", s.time_s)?;
            non_negative("step.extra_mass_kg", s.extra_mass_kg)?;
            within(
                "step.extra_mass_kg",
                s.extra_mass_kg,
                0.0,
                MAX_LOAD_KG,
                LOAD_RANGE,
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_adds_mass_from_its_time_on() {
        let l = LoadProfile::constant(2.0).with_step(10.0, 2.5);
        assert_eq!(l.mass_at(9.999), 2.0);
        assert_eq!(l.mass_at(10.0), 4.5);
        assert!(l.validate().is_ok());
        assert!(LoadProfile::constant(-1.0).validate().is_err());
    }
}
