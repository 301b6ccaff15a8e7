use crate::SimError;
use pma_control::{NominalModel, NominalSpec};
use pma_model::{LoadProfile, MuscleParams, MuscleScale, SensorParams, ValveParams};
use serde::{Deserialize, Serialize};

/// Names of the embedded plant presets (`crates/pma-bench/models/plants/<name>.toml`).
pub const PRESET_NAMES: [&str; 4] = ["ideal", "mismatch", "realistic", "realistic_known_lag"];

const PRESETS: [(&str, &str); 4] = [
    ("ideal", include_str!("../models/plants/ideal.toml")),
    ("mismatch", include_str!("../models/plants/mismatch.toml")),
    ("realistic", include_str!("../models/plants/realistic.toml")),
    (
        "realistic_known_lag",
        include_str!("../models/plants/realistic_known_lag.toml"),
    ),
];

fn default_substeps() -> u32 {
    4
}

fn default_exact_step() -> bool {
    true
}

/// A single-muscle plant: true muscle, load, valve, sensor, and the nominal model the
/// controllers get. Loaded from TOML (`crates/pma-bench/models/plants/*.toml`).
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
    /// A period in which the pressure is held (an instantaneous valve, nothing else acting
    /// on the load) is one exact step instead of the substeps: the substeps' limit, and a
    /// quarter faster. On by default: the substeps damped the chattering baselines, whose
    /// figures had no converged value at them (`docs/convergence.md`); `false` gives the
    /// substeps everywhere (for a fit that needs one integrator throughout).
    #[serde(default = "default_exact_step")]
    pub exact_held_pressure_step: bool,
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
        self.nominal
            .validate()
            .map_err(|e| e.within_section("nominal"))?;
        pma_model::error::check(
            (1..=1000).contains(&self.substeps_per_period),
            "substeps_per_period",
            f64::from(self.substeps_per_period),
            "must be 1 to 1000",
        )?;
        Ok(())
    }

    /// The true muscle.
    pub fn true_muscle(&self) -> MuscleParams {
        self.muscle.apply(MuscleParams::TABLE_I)
    }

    /// The controllers' model.
    pub fn nominal_model(&self) -> NominalModel {
        self.nominal.model()
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
        let text =
            include_str!("../models/plants/ideal.toml").replace("[load]", "[load]\nmas_kg = 1");
        let e = PlantConfig::from_toml_str(&text, "x.toml").unwrap_err();
        assert!(
            e.to_string().contains("mas_kg") && e.to_string().contains("x.toml"),
            "{e}"
        );
        let text = include_str!("../models/plants/ideal.toml")
            .replace("mass_kg = 2.0\n\n[valve]", "mass_kg = -2.0\n\n[valve]");
        let e = PlantConfig::from_toml_str(&text, "x.toml").unwrap_err();
        assert!(e.to_string().contains("mass_kg"), "{e}");
    }
}
