//! Scenario and muscle-geometry files (TOML, `deny_unknown_fields`, units in the names).
use crate::error::{invalid, LegError};
use crate::gait::{FourierSeries, GaitData, GaitReference, GaitSpeed, StartUp};
use crate::ground::TreadmillSettings;
use crate::patient::PatientSettings;
use pma_control::AprcGains;
use pma_model::error::{non_negative, positive, within};
use pma_model::festo::{DmspSize, FestoMuscle};
use pma_model::MuscleScale;
use pma_model::{SensorParams, ValveParams};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The embedded leg model (`crates/pma-leg/models/exo_leg.urdf`).
pub const EMBEDDED_URDF: &str = include_str!("../models/exo_leg.urdf");
/// The embedded trainer (`crates/pma-leg/models/exo_trainer.urdf`): the pelvis on fore-aft
/// and vertical slides, two legs with passive ankles and feet with contact spheres (a
/// one-leg treadmill keeps the right leg).
pub const EMBEDDED_TRAINER_URDF: &str = include_str!("../models/exo_trainer.urdf");
/// The embedded muscle geometry (`crates/pma-leg/models/muscles.toml`).
pub const EMBEDDED_MUSCLES: &str = include_str!("../models/muscles.toml");
/// The embedded treadmill muscles (`crates/pma-leg/models/muscles_treadmill.toml`): Festo
/// sizes and pulleys from `pma-exo size gait_treadmill_spastic`.
pub const EMBEDDED_TREADMILL_MUSCLES: &str = include_str!("../models/muscles_treadmill.toml");
/// The embedded default scenario (`crates/pma-leg/models/scenarios/gait_training.toml`).
pub const EMBEDDED_GAIT_TRAINING: &str = include_str!("../models/scenarios/gait_training.toml");
/// The embedded realistic scenario (`crates/pma-leg/models/scenarios/gait_realistic.toml`).
pub const EMBEDDED_GAIT_REALISTIC: &str = include_str!("../models/scenarios/gait_realistic.toml");

/// Every embedded scenario: name and text (`crates/pma-leg/models/scenarios/<name>.toml`).
pub const EMBEDDED_SCENARIOS: [(&str, &str); 10] = [
    ("gait_training", EMBEDDED_GAIT_TRAINING),
    ("gait_realistic", EMBEDDED_GAIT_REALISTIC),
    (
        "gait_spastic",
        include_str!("../models/scenarios/gait_spastic.toml"),
    ),
    (
        "gait_spasms",
        include_str!("../models/scenarios/gait_spasms.toml"),
    ),
    (
        "gait_resistive",
        include_str!("../models/scenarios/gait_resistive.toml"),
    ),
    (
        "gait_active",
        include_str!("../models/scenarios/gait_active.toml"),
    ),
    (
        "gait_treadmill",
        include_str!("../models/scenarios/gait_treadmill.toml"),
    ),
    (
        "gait_treadmill_spastic",
        include_str!("../models/scenarios/gait_treadmill_spastic.toml"),
    ),
    (
        "gait_treadmill_unsupported",
        include_str!("../models/scenarios/gait_treadmill_unsupported.toml"),
    ),
    (
        "gait_treadmill_one_leg",
        include_str!("../models/scenarios/gait_treadmill_one_leg.toml"),
    ),
];

/// The embedded scenarios' names, for help texts and messages.
pub const EMBEDDED_SCENARIO_NAMES: &str = "gait_training, gait_realistic, gait_spastic, gait_spasms, gait_resistive, gait_active, gait_treadmill, gait_treadmill_spastic, gait_treadmill_unsupported, gait_treadmill_one_leg";

fn embedded_text(name: &str) -> Option<&'static str> {
    EMBEDDED_SCENARIOS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
}

/// Which way a muscle pulls the joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Flexion contracts it.
    Flexor,
    /// Flexion stretches it.
    Extensor,
}

impl Side {
    /// `+1` for a flexor, `-1` for an extensor.
    pub fn sign(self) -> f64 {
        match self {
            Side::Flexor => 1.0,
            Side::Extensor => -1.0,
        }
    }
}

/// One muscle's geometry (see `crates/pma-leg/models/muscles.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MuscleGeometry {
    /// Unique name.
    pub name: String,
    /// URDF joint it acts on.
    pub joint: String,
    /// Flexor or extensor.
    pub side: Side,
    /// URDF link along which the muscle body lies (one of the joint's two links).
    pub body_link: String,
    /// Anchor of the muscle body in `body_link`'s frame (m).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub anchor_m: [f64; 3],
    /// Pulley radius at the joint (m): the moment arm.
    pub pulley_radius_m: f64,
    /// Contraction at zero joint angle (m).
    pub contraction_at_zero_m: f64,
    /// A Festo size (`dmsp-10`, `dmsp-20`, `dmsp-40`): the muscle's force is that size's
    /// measured map ([`pma_model::festo`]); absent: Table I (eq. 1).
    #[serde(default)]
    pub size: Option<DmspSize>,
    /// Nominal length of a Festo muscle (m), with `size`.
    #[serde(default)]
    pub rest_length_m: Option<f64>,
}

impl MuscleGeometry {
    /// The Festo muscle this geometry names, if it names one.
    pub fn festo(&self) -> Result<Option<FestoMuscle>, LegError> {
        let err = |message: &str| LegError::Muscle {
            muscle: self.name.clone(),
            message: message.into(),
        };
        match (self.size, self.rest_length_m) {
            (None, None) => Ok(None),
            (Some(size), Some(length)) => FestoMuscle::new(size, length)
                .map(Some)
                .map_err(|e| LegError::from(e.within_section(&self.name))),
            (Some(_), None) => Err(err("has a `size` but no `rest_length_m`")),
            (None, Some(_)) => Err(err(
                "has a `rest_length_m` but no `size` (dmsp-10, dmsp-20 or dmsp-40)",
            )),
        }
    }

    /// Contraction (m) at joint angle `theta_rad`.
    pub fn contraction(&self, theta_rad: f64) -> f64 {
        self.contraction_at_zero_m + self.moment_arm_m() * theta_rad
    }

    /// Signed moment arm (m): contraction per radian of flexion, `+r` for a flexor and
    /// `-r` for an extensor.
    pub fn moment_arm_m(&self) -> f64 {
        self.side.sign() * self.pulley_radius_m
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MuscleFile {
    muscles: Vec<MuscleGeometry>,
}

/// Plausible pulley radii (m): from a 5 mm cable drum to a 200 mm lever.
pub const PULLEY_RADIUS_RANGE_M: (f64, f64) = (0.005, 0.2);

/// Parses a muscle geometry file; `file` names it in errors.
pub fn parse_muscles(text: &str, file: &str) -> Result<Vec<MuscleGeometry>, LegError> {
    let f: MuscleFile = toml::from_str(text).map_err(|e| LegError::Parse {
        file: file.to_owned(),
        message: pma_control::text::toml_error(text, &e),
    })?;
    check_muscles(&f).map_err(|e| e.in_file(file))?;
    Ok(f.muscles)
}

fn check_muscles(f: &MuscleFile) -> Result<(), LegError> {
    for (i, m) in f.muscles.iter().enumerate() {
        if f.muscles[..i].iter().any(|o| o.name == m.name) {
            return Err(LegError::Muscle {
                muscle: m.name.clone(),
                message: "appears twice: muscle names must be unique".into(),
            });
        }
        within(
            format!("{}.pulley_radius_m", m.name),
            m.pulley_radius_m,
            PULLEY_RADIUS_RANGE_M.0,
            PULLEY_RADIUS_RANGE_M.1,
            "must be 0.005..=0.2 m (an exoskeleton's pulley or lever arm)",
        )?;
        if !m.contraction_at_zero_m.is_finite() || m.anchor_m.iter().any(|v| !v.is_finite()) {
            return Err(LegError::Muscle {
                muscle: m.name.clone(),
                message: "contraction_at_zero_m and anchor_m must be finite".into(),
            });
        }
        m.festo()?;
    }
    Ok(())
}

/// Viscous damping and Coulomb friction of a joint, set explicitly in rapier (which would
/// otherwise add its own default damping and ignores URDF `<dynamics>`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSettings {
    /// Viscous damping (N m s/rad).
    pub damping_nm_s_per_rad: f64,
    /// Coulomb friction (N m).
    #[serde(default)]
    pub friction_nm: f64,
}

/// Both joints.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joints {
    /// Hip.
    pub hip: JointSettings,
    /// Knee.
    pub knee: JointSettings,
}

/// Gait reference.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaitSettings {
    /// The normative data: `schwartz2008` (children, the default) or `fukuchi2018`
    /// (adults on a treadmill).
    #[serde(default)]
    pub data: GaitData,
    /// Speed class of the children's data whose curve shape is used (default `slow`).
    #[serde(default)]
    pub speed: Option<GaitSpeed>,
    /// Treadmill speed of the adults' data (m/s): one of its conditions.
    #[serde(default)]
    pub speed_m_per_s: Option<f64>,
    /// Stride period (s).
    pub stride_period_s: f64,
    /// Smooth start from standing (s).
    pub ramp_s: f64,
    /// How the legs leave standing over `ramp_s`: `standing` (default; straight legs, the
    /// motion grown) or `in_step` (the gait's posture, its cadence grown with the belt).
    #[serde(default)]
    pub start_up: StartUp,
    /// Added to the hip's curve (deg over the cycle, a Fourier series like the data's):
    /// the stance made consistent with a trainer's belt, as `pma-exo fit-gait` finds it
    /// for this scenario's legs, feet and belt (absent: the data's hip as measured).
    #[serde(default)]
    pub hip_correction: Option<FourierSeries>,
}

/// Largest coefficient of a hip correction (deg): a correction moves the stance by a few
/// degrees; anything larger is another gait, not the data's.
pub const HIP_CORRECTION_MAX_DEG: f64 = 10.0;

impl GaitSettings {
    /// The reference's name as outputs show it (`slow`, `adult 0.50 m/s`).
    pub fn speed_label(&self) -> String {
        match (self.data, self.speed_m_per_s) {
            (GaitData::Fukuchi2018, Some(v)) => format!("adult {v:.2} m/s"),
            _ => self.speed.unwrap_or_default().to_string(),
        }
    }

    /// The reference these settings describe (the first leg's; see
    /// [`GaitReference::for_leg`]).
    pub fn reference(&self) -> Result<GaitReference, LegError> {
        match (self.data, self.speed, self.speed_m_per_s) {
            (GaitData::Schwartz2008, _, Some(_)) => Err(invalid(
                "gait.speed_m_per_s",
                self.speed_m_per_s.unwrap_or(f64::NAN),
                "is for gait.data = \"fukuchi2018\" (adults); the children's data takes gait.speed (very-slow ... very-fast)",
            )),
            (GaitData::Schwartz2008, speed, None) => GaitReference::normative(
                speed.unwrap_or_default(),
                self.stride_period_s,
                self.ramp_s,
            ),
            (GaitData::Fukuchi2018, Some(s), _) => Err(LegError::Unsupported {
                name: "gait.speed".into(),
                value: format!("\"{s}\""),
                message: "is a speed class of the children's data: the adults' (gait.data = \"fukuchi2018\") take gait.speed_m_per_s".into(),
            }),
            (GaitData::Fukuchi2018, None, None) => Err(LegError::Missing {
                name: "gait.speed_m_per_s".into(),
                hint: "gait.data = \"fukuchi2018\" needs one of its treadmill speeds",
            }),
            (GaitData::Fukuchi2018, None, Some(v)) => {
                GaitReference::adult(v, self.stride_period_s, self.ramp_s)
            }
        }
        .and_then(|g| self.corrected(g))
        .and_then(|g| g.with_start_up(self.start_up))
    }

    /// `g` with the hip correction added, once it is checked.
    fn corrected(&self, g: GaitReference) -> Result<GaitReference, LegError> {
        let Some(c) = &self.hip_correction else {
            return Ok(g);
        };
        let largest = c.largest_coefficient_deg();
        let finite = c.cos_deg.iter().chain(&c.sin_deg).all(|v| v.is_finite());
        if !finite || largest > HIP_CORRECTION_MAX_DEG {
            return Err(invalid(
                "gait.hip_correction",
                if finite { largest } else { f64::NAN },
                "coefficients must be finite and at most 10 deg (a correction of the stance, as `pma-exo fit-gait` gives)",
            ));
        }
        if c.sin_deg[0] != 0.0 {
            return Err(invalid(
                "gait.hip_correction.sin_deg[0]",
                c.sin_deg[0],
                "must be 0 (the constant term is cos_deg[0])",
            ));
        }
        Ok(g.with_hip_correction(c))
    }
}

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
/// ([`crate::cooperative::cuff_forces_n`]). The default is this project's stated design:
/// each cuff at the middle of its 0.40 m frame bar
/// ([`crate::exoskeleton::FRAME_COM_M`]).
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
    crate::exoskeleton::FRAME_COM_M
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
                "must be 0.05..=0.6 m below the joint, along the segment",
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
            "must be 0..=100 N m (a tenth of the sensor's 1000 N m full scale)",
        )?;
        for (j, name) in ["hip", "knee"].iter().enumerate() {
            within(
                format!("plant.cuff_sensor.bias_nm[{j}] ({name})"),
                self.bias_nm[j],
                -CUFF_ERROR_MAX_NM,
                CUFF_ERROR_MAX_NM,
                "must be -100..=100 N m (a tenth of the sensor's 1000 N m full scale)",
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

/// Controllers: one APRC-NDO per muscle and the co-contraction regulator per joint.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlSettings {
    /// APRC-NDO gains of every muscle (fields left out keep the paper's values).
    #[serde(default)]
    pub gains: AprcGains,
    /// Fraction of the joint inertia reflected through the pulley (`I / r^2`) that each
    /// muscle's nominal model assumes as its mass. The control law turns every m/s^2 of
    /// acceleration error (observer lag, model error) into `m / f1` pascals: with the full
    /// reflected inertia (14 700 kg at the hip) 0.01 m/s^2 is 20 kPa and the valves end up
    /// switching between 0 and 6 bar. A fraction leaves the remaining inertia to the
    /// disturbance observer, the usual nominal-inertia trade-off of DOB control.
    pub nominal_inertia_fraction: f64,
    /// Target common-mode pressure `(p_flexor + p_extensor) / 2` of each joint (Pa).
    pub cocontraction_pa: f64,
    /// Co-contraction regulator: length-reference interference per pascal of common-mode
    /// error (m/Pa).
    pub cocontraction_gain_m_per_pa: f64,
    /// Largest interference (m).
    pub cocontraction_max_m: f64,
    /// Time constant of the common-mode pressure filter (s).
    pub cocontraction_filter_s: f64,
    /// Valve lag the controllers compensate (s), `NominalModel::valve_time_constant_s`;
    /// 0 (the default, the paper) takes each pressure to equal its command.
    #[serde(default)]
    pub nominal_valve_time_constant_s: f64,
    /// Each muscle's pressure sensor feeds its controller's disturbance observer
    /// (`Controller::pressure_sensed`) instead of the observer's own estimate of what the
    /// last command made of the pressure: behind a valve that lags, the lag is then not
    /// taken for a disturbance and compensated a second time. Default off (the paper's
    /// controllers see position only).
    #[serde(default)]
    pub pressure_feedback: bool,
    /// The supervisor's rate limit on every muscle's pressure command (Pa/s). The default,
    /// 6 bar per 1 ms period, binds on nothing the valve's range allows: the shipped
    /// scenarios' controllers step a knee muscle by up to 4.6 bar in one period (`docs/
    /// patient.md`), and the rig's 2 bar per period would change their figures. Set a
    /// lower one to see what a slower valve path does.
    #[serde(default = "default_rate_max")]
    pub pressure_rate_max_pa_per_s: f64,
    /// Which shipped gains the other controllers take (`--controller NAME` without
    /// `--gains`, `compare-leg`): `in-air` (default) or `treadmill`.
    #[serde(default)]
    pub gain_set: crate::gains::GainSet,
    /// How the joints are controlled: `position` (default, each muscle's controller
    /// tracking its length) or `impedance` (a spring and damper about the reference by
    /// co-contraction, `[control.impedance]`); `--mode` overrides it.
    #[serde(default)]
    pub mode: crate::impedance::ControlMode,
    /// Impedance mode's set points.
    #[serde(default)]
    pub impedance: crate::impedance::ImpedanceSettings,
    /// Path mode's tunnel and support.
    #[serde(default)]
    pub path: crate::impedance::PathSettings,
    /// What the pressure-set modes carry: `leg` (default, a passive patient) or `device`
    /// (the frames only; an active patient carries their limb).
    #[serde(default)]
    pub compensation: crate::impedance::Compensation,
}

fn default_rate_max() -> f64 {
    6.0e8
}

/// A gait-training scenario (`crates/pma-leg/models/scenarios/*.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// One line.
    #[serde(default)]
    pub description: String,
    /// URDF path relative to the scenario file; absent = the embedded `exo_leg.urdf`.
    #[serde(default)]
    pub urdf: Option<PathBuf>,
    /// Muscle geometry path relative to the scenario file; absent = the embedded one.
    #[serde(default)]
    pub muscle_geometry: Option<PathBuf>,
    /// Default duration (s).
    pub duration_s: f64,
    /// Control period (s).
    pub period_s: f64,
    /// Physics steps per control period.
    pub physics_substeps: u32,
    /// The muscles' damping evaluated at the joint rates the physics step ends on (linearly
    /// implicit), from the leg's own rigid-body model, except while a joint is at its limit:
    /// one step per period is then more accurate than one explicit step and about as
    /// accurate as two (`docs/benchmarks.md`). In the air only: on the treadmill the pelvis
    /// floats, which that model does not have.
    #[serde(default)]
    pub implicit_muscle_damping: bool,
    /// Gait reference.
    pub gait: GaitSettings,
    /// Joint damping and friction.
    pub joints: Joints,
    /// True plant.
    pub plant: PlantSettings,
    /// Controllers.
    pub control: ControlSettings,
    /// The patient in the exoskeleton (absent: the URDF's passive limb).
    #[serde(default)]
    pub patient: PatientSettings,
    /// The foot on a treadmill belt and the pelvis on body-weight support (absent: the leg
    /// swings in the air from a fixed pelvis). Its URDF needs a `foot` link and a
    /// `pelvis_z` slide; absent `urdf` and `muscle_geometry` are then the embedded
    /// `exo_trainer.urdf` and `muscles_treadmill.toml`.
    #[serde(default)]
    pub treadmill: Option<TreadmillSettings>,
}

/// Parses TOML text into `T`; an error names the line and the field's path
/// (`patient.knee.spasticity.preset`) on one line.
fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T, LegError> {
    let parse_error = |e: &toml::de::Error| LegError::Parse {
        file: file.to_owned(),
        message: pma_control::text::toml_error(text, e),
    };
    let de = toml::Deserializer::parse(text).map_err(|e| parse_error(&e))?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let message = pma_control::text::toml_error(text, e.inner());
        LegError::Parse {
            file: file.to_owned(),
            message: if path == "." || message.contains(&path) {
                message
            } else {
                format!("{path}: {message}")
            },
        }
    })
}

/// A scenario with its URDF and muscle geometry loaded.
#[derive(Debug, Clone)]
pub struct LoadedScenario {
    /// The scenario.
    pub scenario: Scenario,
    /// URDF text.
    pub urdf_text: String,
    /// Where the URDF came from (for messages).
    pub urdf_source: String,
    /// Muscles.
    pub muscles: Vec<MuscleGeometry>,
    /// Where the muscle geometry came from (for messages).
    pub muscles_source: String,
}

fn read(path: &Path) -> Result<String, LegError> {
    std::fs::read_to_string(path).map_err(|e| LegError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

impl Scenario {
    /// Parses and validates scenario text; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, LegError> {
        let s: Scenario = parse_toml(text, file)?;
        s.validate().map_err(|e| LegError::Parse {
            file: file.to_owned(),
            message: e.to_string(),
        })?;
        Ok(s)
    }

    /// Rejects a run of `duration_s` shorter than two strides: tracking figures and the
    /// tuner's objective start after the first one.
    pub fn check_run_duration(&self, duration_s: f64) -> Result<(), LegError> {
        let two_strides_s = 2.0 * self.gait.stride_period_s;
        if duration_s < two_strides_s {
            return Err(LegError::ShorterThanTwoStrides {
                scenario: self.name.clone(),
                duration_s,
                two_strides_s,
            });
        }
        if let Some(t) = &self.treadmill {
            let [_, until] = t.bws_release_s;
            if t.bws_start_fraction.is_some_and(|f| f != t.bws_fraction) && until > duration_s {
                return Err(LegError::Unsupported {
                    name: "treadmill.bws_release_s".into(),
                    value: format!("[{}, {until}]", t.bws_release_s[0]),
                    message: format!(
                        "the support is lowered until {until} s, after the run's {duration_s} s: it never reaches bws_fraction = {} within it (run longer, or release sooner)",
                        t.bws_fraction
                    ),
                });
            }
        }
        Ok(())
    }

    /// Range checks.
    pub fn validate(&self) -> Result<(), LegError> {
        positive("duration_s", self.duration_s)?;
        within(
            "period_s",
            self.period_s,
            1e-4,
            1e-2,
            "must be 0.0001..=0.01 s (the controllers are discretised for 0.1-10 ms)",
        )?;
        if !(1..=100).contains(&self.physics_substeps) {
            return Err(invalid(
                "physics_substeps",
                f64::from(self.physics_substeps),
                "must be 1..=100",
            ));
        }
        pma_model::error::check(
            !(self.implicit_muscle_damping && self.treadmill.is_some()),
            "implicit_muscle_damping",
            1.0,
            "is for a leg in the air: on the treadmill the pelvis floats, which the leg's rigid-body model it needs does not have",
        )?;
        within(
            "gait.stride_period_s",
            self.gait.stride_period_s,
            0.5,
            10.0,
            "must be 0.5..=10 s (normal strides last about 1 s, training strides 1.4-3 s)",
        )?;
        within(
            "gait.ramp_s",
            self.gait.ramp_s,
            0.0,
            10.0,
            "must be 0..=10 s (a start-up from standing over a few strides)",
        )?;
        self.gait.reference()?;
        for (n, j) in [("hip", self.joints.hip), ("knee", self.joints.knee)] {
            non_negative(
                format!("joints.{n}.damping_nm_s_per_rad"),
                j.damping_nm_s_per_rad,
            )?;
            non_negative(format!("joints.{n}.friction_nm"), j.friction_nm)?;
            within(
                format!("joints.{n}.damping_nm_s_per_rad"),
                j.damping_nm_s_per_rad,
                0.0,
                100.0,
                "must be 0..=100 N m s/rad",
            )?;
            within(
                format!("joints.{n}.friction_nm"),
                j.friction_nm,
                0.0,
                100.0,
                "must be 0..=100 N m",
            )?;
        }
        self.plant
            .valve
            .validate()
            .map_err(|e| e.within_section("plant.valve"))?;
        self.plant.flow_valve()?;
        self.control.impedance.validate()?;
        if let Some(f) = self.plant.muscle_rated_force_n {
            positive("plant.muscle_rated_force_n", f)?;
        }
        self.plant.encoder.sensor(0).validate()?;
        self.plant.cuff_sensor.validate()?;
        self.plant.cuffs.validate()?;
        positive("control.cocontraction_pa", self.control.cocontraction_pa)?;
        if self.control.cocontraction_pa > self.plant.valve.pressure_max_pa {
            return Err(invalid(
                "control.cocontraction_pa",
                self.control.cocontraction_pa,
                "must be at most the valve's plant.valve.pressure_max_pa",
            ));
        }
        positive(
            "control.nominal_inertia_fraction",
            self.control.nominal_inertia_fraction,
        )?;
        non_negative(
            "control.cocontraction_gain_m_per_pa",
            self.control.cocontraction_gain_m_per_pa,
        )?;
        non_negative(
            "control.cocontraction_max_m",
            self.control.cocontraction_max_m,
        )?;
        positive(
            "control.cocontraction_filter_s",
            self.control.cocontraction_filter_s,
        )?;
        non_negative(
            "control.nominal_valve_time_constant_s",
            self.control.nominal_valve_time_constant_s,
        )?;
        positive(
            "control.pressure_rate_max_pa_per_s",
            self.control.pressure_rate_max_pa_per_s,
        )?;
        pma_control::ControllerConfig::AprcNdo(self.control.gains).validate()?;
        self.patient.validate()?;
        if let Some(t) = &self.treadmill {
            t.validate()?;
        }
        Ok(())
    }

    /// The URDF and muscle geometry a scenario uses when it names none: the embedded
    /// in-air leg, or the treadmill's. Text and source of each.
    fn default_models(&self) -> [(&'static str, &'static str); 2] {
        if self.treadmill.is_some() {
            [
                (
                    EMBEDDED_TRAINER_URDF,
                    "crates/pma-leg/models/exo_trainer.urdf",
                ),
                (
                    EMBEDDED_TREADMILL_MUSCLES,
                    "crates/pma-leg/models/muscles_treadmill.toml",
                ),
            ]
        } else {
            [
                (EMBEDDED_URDF, "crates/pma-leg/models/exo_leg.urdf"),
                (EMBEDDED_MUSCLES, "crates/pma-leg/models/muscles.toml"),
            ]
        }
    }

    /// An embedded scenario by name (see [`EMBEDDED_SCENARIOS`]).
    pub fn embedded(name: &str) -> Option<LoadedScenario> {
        Self::load_embedded(embedded_text(name)?, name).ok()
    }

    fn load_embedded(text: &str, name: &str) -> Result<LoadedScenario, LegError> {
        let scenario = Scenario::from_toml_str(text, &format!("{name}.toml"))?;
        let [(urdf, urdf_source), (muscles, muscles_source)] = scenario.default_models();
        Ok(LoadedScenario {
            scenario,
            urdf_text: urdf.to_owned(),
            urdf_source: urdf_source.into(),
            muscles: parse_muscles(muscles, muscles_source)?,
            muscles_source: muscles_source.into(),
        })
    }

    /// Loads a scenario: an embedded name (see [`EMBEDDED_SCENARIOS`]) or a file, with
    /// the URDF and muscle geometry it refers to (relative to its directory).
    pub fn load(name_or_path: &str) -> Result<LoadedScenario, LegError> {
        if !name_or_path.ends_with(".toml") {
            return match embedded_text(name_or_path) {
                Some(text) => Self::load_embedded(text, name_or_path),
                None => Err(LegError::Parse {
                    file: name_or_path.to_owned(),
                    message: format!(
                        "unknown scenario (expected one of {EMBEDDED_SCENARIO_NAMES}, or a .toml file)"
                    ),
                }),
            };
        }
        let path = Path::new(name_or_path);
        let scenario = Scenario::from_toml_str(&read(path)?, name_or_path)?;
        let dir = path.parent().unwrap_or_else(|| Path::new("."));
        let [(urdf, urdf_default), (muscles, muscles_default)] = scenario.default_models();
        let (urdf_text, urdf_source) = match &scenario.urdf {
            Some(p) => {
                let full = dir.join(p);
                (read(&full)?, full.display().to_string())
            }
            None => (urdf.to_owned(), urdf_default.into()),
        };
        let (muscles, muscles_source) = match &scenario.muscle_geometry {
            Some(p) => {
                let full = dir.join(p).display().to_string();
                (parse_muscles(&read(Path::new(&full))?, &full)?, full)
            }
            None => (
                parse_muscles(muscles, muscles_default)?,
                muscles_default.into(),
            ),
        };
        Ok(LoadedScenario {
            scenario,
            urdf_text,
            urdf_source,
            muscles,
            muscles_source,
        })
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
        assert_eq!(ok.shank_below_knee_m, crate::exoskeleton::FRAME_COM_M);
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
