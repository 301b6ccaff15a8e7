use crate::SimError;
use pma_control::NominalModel;
use pma_model::{LoadProfile, MuscleParams, SensorParams, ValveParams};
use serde::{Deserialize, Serialize};

/// Names of the embedded plant presets (`models/plants/<name>.toml`).
pub const PRESET_NAMES: [&str; 4] = ["ideal", "mismatch", "realistic", "realistic_known_lag"];

const PRESETS: [(&str, &str); 4] = [
    ("ideal", include_str!("../../../models/plants/ideal.toml")),
    (
        "mismatch",
        include_str!("../../../models/plants/mismatch.toml"),
    ),
    (
        "realistic",
        include_str!("../../../models/plants/realistic.toml"),
    ),
    (
        "realistic_known_lag",
        include_str!("../../../models/plants/realistic_known_lag.toml"),
    ),
];

/// Factors applied to Table I to obtain the *true* muscle (1.0 = nominal).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MuscleScale {
    /// Factor on `f0`.
    pub f0_scale: f64,
    /// Factor on `f1`.
    pub f1_scale: f64,
    /// Factor on `k0`.
    pub k0_scale: f64,
    /// Factor on `k1`.
    pub k1_scale: f64,
    /// Factor on `b0i`.
    pub b0_inflation_scale: f64,
    /// Factor on `b1i`.
    pub b1_inflation_scale: f64,
    /// Factor on `b0d`.
    pub b0_deflation_scale: f64,
    /// Factor on `b1d`.
    pub b1_deflation_scale: f64,
}

impl Default for MuscleScale {
    fn default() -> Self {
        Self {
            f0_scale: 1.0,
            f1_scale: 1.0,
            k0_scale: 1.0,
            k1_scale: 1.0,
            b0_inflation_scale: 1.0,
            b1_inflation_scale: 1.0,
            b0_deflation_scale: 1.0,
            b1_deflation_scale: 1.0,
        }
    }
}

impl MuscleScale {
    /// Table I with these factors applied.
    pub fn apply(&self, p: MuscleParams) -> MuscleParams {
        MuscleParams {
            f0_n: p.f0_n * self.f0_scale,
            f1_n_per_pa: p.f1_n_per_pa * self.f1_scale,
            k0_n_per_m: p.k0_n_per_m * self.k0_scale,
            k1_n_per_m_pa: p.k1_n_per_m_pa * self.k1_scale,
            b0_inflation_ns_per_m: p.b0_inflation_ns_per_m * self.b0_inflation_scale,
            b1_inflation_ns_per_m_pa: p.b1_inflation_ns_per_m_pa * self.b1_inflation_scale,
            b0_deflation_ns_per_m: p.b0_deflation_ns_per_m * self.b0_deflation_scale,
            b1_deflation_ns_per_m_pa: p.b1_deflation_ns_per_m_pa * self.b1_deflation_scale,
        }
    }
}

/// What the controllers believe: Table I and this load mass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NominalSpec {
    /// Assumed load mass (kg).
    pub mass_kg: f64,
    /// See [`NominalModel::mode_switch_deadband_pa`].
    #[serde(default = "default_deadband")]
    pub mode_switch_deadband_pa: f64,
    /// See [`NominalModel::mode_switch_fraction`].
    #[serde(default = "default_fraction")]
    pub mode_switch_fraction: f64,
    /// Valve lag the controllers compensate (s), [`NominalModel::valve_time_constant_s`];
    /// 0 (the default, the paper) takes the pressure to equal the command.
    #[serde(default)]
    pub valve_time_constant_s: f64,
}

fn default_deadband() -> f64 {
    pma_control::DEFAULT_MODE_SWITCH_DEADBAND_PA
}

fn default_fraction() -> f64 {
    pma_control::DEFAULT_MODE_SWITCH_FRACTION
}

fn default_substeps() -> u32 {
    4
}

/// A single-muscle plant: true muscle, load, valve, sensor, and the nominal model the
/// controllers get. Loaded from TOML (`models/plants/*.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantConfig {
    /// Short name.
    pub name: String,
    /// One-line description.
    #[serde(default)]
    pub description: String,
    /// Controllers' model.
    pub nominal: NominalSpec,
    /// True muscle relative to Table I.
    #[serde(default)]
    pub muscle: MuscleScale,
    /// True load.
    pub load: LoadProfile,
    /// Valve.
    pub valve: ValveParams,
    /// Position sensor.
    pub sensor: SensorParams,
    /// Integration substeps per control period (the muscle is stiff: see `MuscleBench`).
    #[serde(default = "default_substeps")]
    pub substeps_per_period: u32,
}

impl PlantConfig {
    /// One of [`PRESET_NAMES`].
    pub fn preset(name: &str) -> Result<Self, SimError> {
        let (_, text) = PRESETS
            .iter()
            .find(|(n, _)| *n == name)
            .ok_or_else(|| SimError::UnknownPlant(name.to_owned()))?;
        Self::from_toml_str(text, name)
    }

    /// A preset name, or a path ending in `.toml`.
    pub fn load(name_or_path: &str) -> Result<Self, SimError> {
        if !name_or_path.ends_with(".toml") {
            return Self::preset(name_or_path);
        }
        let text = std::fs::read_to_string(name_or_path).map_err(|e| SimError::Io {
            operation: "read",
            path: name_or_path.to_owned(),
            message: e.to_string(),
        })?;
        Self::from_toml_str(&text, name_or_path)
    }

    /// Parses and validates a plant file; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, SimError> {
        let cfg: PlantConfig = toml::from_str(text).map_err(|e| SimError::Parse {
            what: "plant file",
            file: file.to_owned(),
            message: pma_control::text::toml_error(text, &e),
        })?;
        cfg.validate().map_err(|e| SimError::Parse {
            what: "plant file",
            file: file.to_owned(),
            message: e.to_string(),
        })?;
        Ok(cfg)
    }

    /// Checks every physical parameter.
    pub fn validate(&self) -> Result<(), SimError> {
        let wrap = |source| SimError::Model {
            plant: self.name.clone(),
            source,
        };
        self.true_muscle().validate().map_err(wrap)?;
        self.load.validate().map_err(wrap)?;
        self.valve.validate().map_err(wrap)?;
        self.sensor.validate().map_err(wrap)?;
        LoadProfile::constant(self.nominal.mass_kg)
            .validate()
            .map_err(wrap)?;
        let tau = self.nominal.valve_time_constant_s;
        if !(tau.is_finite() && tau >= 0.0) {
            return Err(SimError::InvalidRun {
                name: "nominal.valve_time_constant_s",
                value: tau,
                expected: "must be a finite number of seconds >= 0",
            });
        }
        if self.substeps_per_period == 0 {
            return Err(SimError::InvalidRun {
                name: "substeps_per_period",
                value: 0.0,
                expected: "must be >= 1",
            });
        }
        Ok(())
    }

    /// The true muscle.
    pub fn true_muscle(&self) -> MuscleParams {
        self.muscle.apply(MuscleParams::TABLE_I)
    }

    /// The controllers' model.
    pub fn nominal_model(&self) -> NominalModel {
        NominalModel {
            muscle: MuscleParams::TABLE_I,
            mass_kg: self.nominal.mass_kg,
            load_force_n: self.nominal.mass_kg * pma_model::GRAVITY_M_S2,
            mode_switch_deadband_pa: self.nominal.mode_switch_deadband_pa,
            mode_switch_fraction: self.nominal.mode_switch_fraction,
            valve_time_constant_s: self.nominal.valve_time_constant_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_load_and_encode_the_issue_definitions() {
        let ideal = PlantConfig::preset("ideal").unwrap();
        assert_eq!(ideal.true_muscle(), MuscleParams::TABLE_I);
        assert!(ideal.valve.is_instantaneous());
        let m = PlantConfig::preset("mismatch").unwrap();
        let t = m.true_muscle();
        assert!((t.k0_n_per_m / 18063.0 - 1.2).abs() < 1e-12);
        assert!((t.b0_inflation_ns_per_m / 6435.31 - 1.2).abs() < 1e-12);
        assert!((t.b0_deflation_ns_per_m / 2522.01 - 1.2).abs() < 1e-12);
        assert!((t.f0_n / -202.32 - 0.9).abs() < 1e-12);
        assert_eq!(m.load.mass_kg, 2.5);
        assert_eq!(m.nominal.mass_kg, 2.0);
        let r = PlantConfig::preset("realistic").unwrap();
        assert_eq!(r.valve.time_constant_s, 0.020);
        assert_eq!(r.sensor.resolution_bits, 16);
        assert_eq!(r.sensor.noise_rms_m, 20e-6);
        assert_eq!(r.true_muscle(), t);
    }

    #[test]
    fn bad_plant_files_name_the_problem() {
        let e = PlantConfig::preset("vacuum").unwrap_err();
        assert!(e.to_string().contains("vacuum"));
        let text = include_str!("../../../models/plants/ideal.toml")
            .replace("[load]", "[load]\nmas_kg = 1");
        let e = PlantConfig::from_toml_str(&text, "x.toml").unwrap_err();
        assert!(
            e.to_string().contains("mas_kg") && e.to_string().contains("x.toml"),
            "{e}"
        );
        let text = include_str!("../../../models/plants/ideal.toml")
            .replace("mass_kg = 2.0\n\n[valve]", "mass_kg = -2.0\n\n[valve]");
        let e = PlantConfig::from_toml_str(&text, "x.toml").unwrap_err();
        assert!(e.to_string().contains("mass_kg"), "{e}");
    }
}
