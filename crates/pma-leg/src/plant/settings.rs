use crate::base::LegError;
use pma_model::error::within;
use pma_model::festo::FestoScale;
use pma_model::MuscleScale;
use pma_model::{SensorParams, ValveParams};
use serde::Deserialize;
use std::collections::BTreeMap;

/// Joint angle sensor (encoder) of each joint; both muscles of a joint read their
/// contraction from it, so their measured lengths are exactly complementary.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderSettings {
    /// Resolution over the encoder's full turn (bits); 0 for a continuous reading.
    #[serde(default)]
    pub resolution_bits: u32,
    /// RMS noise (rad).
    #[serde(default)]
    pub noise_rms_rad: f64,
    /// Seed (the knee uses `seed + 1`).
    #[serde(default)]
    pub seed: u64,
}

impl EncoderSettings {
    /// As sensor parameters over one turn.
    pub fn sensor(&self, joint_index: u64) -> SensorParams {
        SensorParams {
            range_min_m: -std::f64::consts::PI,
            range_max_m: std::f64::consts::PI,
            resolution_bits: self.resolution_bits,
            noise_rms_m: self.noise_rms_rad,
            seed: self.seed.wrapping_add(joint_index),
        }
    }
}

/// The true plant: valves, encoders, and each muscle's deviation from Table I.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSettings {
    /// Valve of every muscle.
    pub valve: ValveParams,
    /// Joint encoders.
    #[serde(default = "default_encoder")]
    pub encoder: EncoderSettings,
    /// Per-muscle factors on Table I (muscle name -> factors); absent = nominal.
    #[serde(default)]
    pub muscle_scale: BTreeMap<String, MuscleScale>,
    /// Per-muscle factors on a Festo muscle's force map, stiffness and damping (muscle
    /// name -> factors, each 0.5..=1.5); absent = as measured.
    #[serde(default)]
    pub festo_scale: BTreeMap<String, FestoScale>,
    /// Rated pulling force of every eq. (1) muscle (N), against which the run's peak force
    /// is reported. Default: what Table I's muscle itself pulls at the valve's limit and no
    /// contraction (4124 N at 6 bar), the rating of the muscle it models. (A Festo
    /// DMSP-20, 1500 N, is 2.8 times weaker than Table I's "similar PMA": a file of Festo
    /// muscles, `size`, is held against the Festo rating.)
    #[serde(default)]
    pub muscle_rated_force_n: Option<f64>,
    /// The cuff torque sensors' errors (default: ideal).
    #[serde(default)]
    pub cuff_sensor: CuffSensorSettings,
    /// Where the cuffs hold the limb (default: the middle of each frame bar).
    #[serde(default)]
    pub cuffs: CuffSettings,
    /// The pneumatics between each valve and its muscle (default: the `ideal` valve, the
    /// `[plant.valve]` model): a flow-limited valve, its supply and tube.
    #[serde(default)]
    pub pneumatics: pma_model::PneumaticsSettings,
}

/// `[plant.cuffs]`: where the thigh and shank cuffs hold the limb, on every leg. The
/// device's torque on the limb is reported as the two cuff forces that give it
/// ([`crate::plant::cuff_forces_n`]). The default is this project's stated design:
/// each cuff at the middle of its 0.40 m frame bar
/// ([`crate::body::FRAME_COM_M`]).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuffSettings {
    /// Distance of the thigh cuff below the hip, along the thigh (m); at most the thigh's
    /// length.
    #[serde(default = "default_cuff_below_joint")]
    pub thigh_below_hip_m: f64,
    /// Distance of the shank cuff below the knee, along the shank (m).
    #[serde(default = "default_cuff_below_joint")]
    pub shank_below_knee_m: f64,
}

fn default_cuff_below_joint() -> f64 {
    crate::body::FRAME_COM_M
}

impl Default for CuffSettings {
    fn default() -> Self {
        Self {
            thigh_below_hip_m: default_cuff_below_joint(),
            shank_below_knee_m: default_cuff_below_joint(),
        }
    }
}

/// Nearest a cuff may sit to its joint (m): closer, a joint torque needs a force beyond
/// any cuff's (10 N m at 5 cm is 200 N).
pub const CUFF_BELOW_JOINT_MIN_M: f64 = 0.05;

impl CuffSettings {
    /// Checks each field's range (the thigh cuff against the thigh's length where the leg
    /// is built); the error names it.
    pub fn validate(&self) -> Result<(), LegError> {
        for (name, v) in [
            ("plant.cuffs.thigh_below_hip_m", self.thigh_below_hip_m),
            ("plant.cuffs.shank_below_knee_m", self.shank_below_knee_m),
        ] {
            within(
                name,
                v,
                CUFF_BELOW_JOINT_MIN_M,
                0.6,
                "must be 0.05 to 0.6 m below the joint, along the segment",
            )?;
        }
        Ok(())
    }
}

/// `[plant.cuff_sensor]`: what separates the cuff torque sensors' readings (which
/// admittance mode acts on) from the torque the device puts into the limb, on every leg.
/// The true torque is what the outputs report as the interaction.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuffSensorSettings {
    /// RMS of white Gaussian noise on each reading (N m). Default 0.
    #[serde(default)]
    pub noise_rms_nm: f64,
    /// Constant offset of the hip's and the knee's readings (N m): a sensor not tared, or
    /// its drift. Default 0.
    #[serde(deserialize_with = "pma_model::error::exact::array", default)]
    pub bias_nm: [f64; 2],
    /// Seed of the noise (leg `l`'s joint `j` draws from `seed + 2 l + j`).
    #[serde(default)]
    pub seed: u64,
}

/// Largest noise or bias a cuff sensor may be given (N m): a tenth of its full scale
/// ([`crate::sim::CUFF_TORQUE_FULL_SCALE_NM`]).
pub const CUFF_ERROR_MAX_NM: f64 = 100.0;

impl CuffSensorSettings {
    /// Checks each field's range; the error names it.
    pub fn validate(&self) -> Result<(), LegError> {
        within(
            "plant.cuff_sensor.noise_rms_nm",
            self.noise_rms_nm,
            0.0,
            CUFF_ERROR_MAX_NM,
            "must be 0 to 100 N m (a tenth of the sensor's 1000 N m full scale)",
        )?;
        for (j, name) in ["hip", "knee"].iter().enumerate() {
            within(
                format!("plant.cuff_sensor.bias_nm[{j}] ({name})"),
                self.bias_nm[j],
                -CUFF_ERROR_MAX_NM,
                CUFF_ERROR_MAX_NM,
                "must be -100 to 100 N m (a tenth of the sensor's 1000 N m full scale)",
            )?;
        }
        Ok(())
    }
}

/// Festo DMSP-20's rated (maximum) force (N).
pub const DMSP20_RATED_FORCE_N: f64 = 1500.0;

impl PlantSettings {
    /// The flow-limited valve `[plant.pneumatics]` names, checked (`None`: the
    /// `[plant.valve]` model). The lag model's fields with a flow valve are refused: two
    /// valve models at once would run only one of them.
    pub fn flow_valve(&self) -> Result<Option<pma_model::ValveSpec>, LegError> {
        let p = &self.pneumatics;
        p.validate()
            .map_err(|e| LegError::from(e.within_section("plant.pneumatics")))?;
        if p.is_ideal() {
            return Ok(None);
        }
        let spec = pma_model::ValveSpec::load(&p.valve).map_err(|e| LegError::Parse {
            file: e.file,
            message: e.message,
        })?;
        let v = &self.valve;
        for (field, value, set) in [
            (
                "plant.valve.time_constant_s",
                v.time_constant_s,
                v.time_constant_s != 0.0,
            ),
            (
                "plant.valve.dead_time_s",
                v.dead_time_s,
                v.dead_time_s != 0.0,
            ),
            (
                "plant.valve.rate_limit_pa_per_s",
                v.rate_limit_pa_per_s.unwrap_or(f64::NAN),
                v.rate_limit_pa_per_s.is_some(),
            ),
        ] {
            if set {
                return Err(LegError::Unsupported {
                    name: field.into(),
                    value: pma_model::error::number(value),
                    message: format!(
                        "the lag model's fields do not apply to the flow-limited valve plant.pneumatics.valve = \"{}\" (its lag comes from its flow and tube); for the lag model set valve = \"ideal\"",
                        p.valve
                    ),
                });
            }
        }
        Ok(Some(spec))
    }

    /// The valve of a muscle of `model`: `[plant.valve]`, or the flow-limited valve into
    /// the muscle's own chamber, its tube's transport delay as the dead time.
    pub fn valve_of(
        &self,
        spec: Option<&pma_model::ValveSpec>,
        model: &pma_model::MuscleModel,
    ) -> ValveParams {
        match spec {
            None => self.valve,
            Some(spec) => ValveParams {
                dead_time_s: self.pneumatics.transport_delay_s(),
                flow: Some(self.pneumatics.flow(spec, model.chamber())),
                ..self.valve
            },
        }
    }

    /// The valve model that runs, as outputs name it.
    pub fn valve_label(&self) -> Result<String, LegError> {
        Ok(match self.flow_valve()? {
            None => format!("{} (plant.valve)", self.valve.describe()),
            Some(spec) => format!(
                "{} ({}): ISO 6358 C = {} l/(s bar), b = {}, supply {} bar, tube {} m x {} mm",
                spec.name,
                self.pneumatics.valve,
                spec.sonic_conductance_l_per_s_bar,
                spec.critical_pressure_ratio,
                self.pneumatics.supply_pressure_pa / 1e5,
                self.pneumatics.tube_length_m,
                self.pneumatics.tube_bore_m * 1e3
            ),
        })
    }

    /// An eq. (1) muscle's rating and where it comes from: the scenario's, or Table I's own
    /// pull at the valve's limit.
    pub fn three_element_rating(&self) -> (f64, String) {
        match self.muscle_rated_force_n {
            Some(f) => (f, "plant.muscle_rated_force_n".into()),
            None => {
                let p = self.valve.pressure_max_pa;
                let t = pma_model::MuscleParams::TABLE_I;
                (
                    t.f0_n + t.f1_n_per_pa * p,
                    format!("Table I's muscle at {:.1} bar, no contraction", p / 1e5),
                )
            }
        }
    }
}

fn default_encoder() -> EncoderSettings {
    EncoderSettings {
        resolution_bits: 0,
        noise_rms_rad: 0.0,
        seed: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cuff_sensor_error_beyond_a_tenth_of_full_scale_is_refused_naming_the_field() {
        let ok: CuffSensorSettings =
            toml::from_str("noise_rms_nm = 2.0\nbias_nm = [1.0, -1.0]\nseed = 4\n").unwrap();
        assert!(ok.validate().is_ok());
        for (text, field) in [
            ("noise_rms_nm = 150.0", "plant.cuff_sensor.noise_rms_nm"),
            ("noise_rms_nm = -1.0", "plant.cuff_sensor.noise_rms_nm"),
            (
                "bias_nm = [0.0, 101.0]",
                "plant.cuff_sensor.bias_nm[1] (knee)",
            ),
        ] {
            let s: CuffSensorSettings = toml::from_str(text).unwrap();
            let e = s.validate().expect_err(text).to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
        assert!(toml::from_str::<CuffSensorSettings>("drift = 1.0").is_err());
    }

    #[test]
    fn a_cuff_too_close_to_its_joint_or_too_far_is_refused_naming_the_field() {
        let ok: CuffSettings = toml::from_str("thigh_below_hip_m = 0.25").unwrap();
        assert!(ok.validate().is_ok());
        assert_eq!(ok.shank_below_knee_m, crate::body::FRAME_COM_M);
        for (text, field) in [
            ("thigh_below_hip_m = 0.01", "plant.cuffs.thigh_below_hip_m"),
            ("shank_below_knee_m = 0.7", "plant.cuffs.shank_below_knee_m"),
            ("shank_below_knee_m = nan", "plant.cuffs.shank_below_knee_m"),
        ] {
            let s: CuffSettings = toml::from_str(text).unwrap();
            let e = s.validate().expect_err(text).to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
        assert!(toml::from_str::<CuffSettings>("ankle_below_knee_m = 0.3").is_err());
    }
}
