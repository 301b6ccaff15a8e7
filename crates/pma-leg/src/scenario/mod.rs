//! Scenario and muscle-geometry files (TOML, `deny_unknown_fields`, units in the names).
use crate::body::{Joints, EMBEDDED_TRAINER_URDF, EMBEDDED_URDF};
use crate::control::ControlSettings;
use crate::gait::GaitSettings;
use crate::plant::{parse_muscles, MuscleGeometry, PlantSettings};
use crate::scenario::embedded_text;
mod embedded;
mod gains;

pub use embedded::*;
pub use gains::*;

use crate::base::{invalid, LegError};
use crate::ground::TreadmillSettings;
use crate::patient::PatientSettings;
use pma_model::error::{check, non_negative, positive, within};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// What a patient's height does to the belt the reference fits, for an error message.
fn height_note(height_m: Option<f64>, scaled_m_s: f64) -> String {
    match height_m {
        Some(h) if h != crate::body::URDF_PATIENT_HEIGHT_M => format!(
            ", {scaled_m_s:.3} m/s for a patient {h} m tall at the same cadence (the belt scales with the legs, height / {} m)",
            crate::body::URDF_PATIENT_HEIGHT_M
        ),
        _ => String::new(),
    }
}

/// Most physics steps a control period takes (`physics_substeps`): four times the in-air
/// scenarios' 64, so that their step can be checked at a quarter of itself (docs/convergence.md).
pub const PHYSICS_SUBSTEPS_MAX: u32 = 256;

/// Largest relative difference between a belt's speed and the speed its adult reference
/// was recorded at: 13 %, the spread of the subjects' own speeds in each condition
/// (standard deviation 0.064-0.162 m/s, 12.8-13.6 % of the mean from T01 to T05; Fukuchi et
/// al. 2018, `WBDSinfo.xlsx`). Beyond it few of the adults walked at that speed. Within it a
/// belt must still fit the stance the hip was fitted to: the servo-driven stride's demand
/// check refuses one that does not (0.52 m/s asks 16 times the adults' hip moment where the
/// shipped trainer's 0.4855 m/s asks 2.3 times; docs/treadmill.md). The shipped belts run
/// 2.7 % (0.4855 m/s) and 5.9 % (0.4697 m/s, unsupported) under T01's 0.499 m/s: the
/// model's legs are not the subjects'.
pub const BELT_SPEED_OFF_REFERENCE_MAX: f64 = 0.13;

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
            "must be 0.0001 to 0.01 s (the controllers are discretised for 0.1-10 ms)",
        )?;
        if !(1..=PHYSICS_SUBSTEPS_MAX).contains(&self.physics_substeps) {
            return Err(invalid(
                "physics_substeps",
                f64::from(self.physics_substeps),
                "must be 1 to 256 (PHYSICS_SUBSTEPS_MAX)",
            ));
        }
        check(
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
            "must be 0.5 to 10 s (normal strides last about 1 s, training strides 1.4-3 s)",
        )?;
        within(
            "gait.ramp_s",
            self.gait.ramp_s,
            0.0,
            10.0,
            "must be 0 to 10 s (a start-up from standing over a few strides)",
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
                "must be 0 to 100 N m s/rad",
            )?;
            within(
                format!("joints.{n}.friction_nm"),
                j.friction_nm,
                0.0,
                100.0,
                "must be 0 to 100 N m",
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
        if let Some(share) = self.control.force_max_of_rating {
            crate::control::check_share(share)?;
        }
        pma_control::ControllerConfig::AprcNdo(self.control.gains).validate()?;
        self.check_gains_below_support()?;
        self.patient.validate()?;
        if let Some(t) = &self.treadmill {
            t.validate()?;
            self.check_belt_on_reference(t)?;
        }
        Ok(())
    }

    /// `control.gains_below_support`: its support a share of the body weight on a treadmill
    /// (off one no harness carries anything to schedule by), its gains APRC-NDO's.
    fn check_gains_below_support(&self) -> Result<(), LegError> {
        let Some(s) = &self.control.gains_below_support else {
            return Ok(());
        };
        let name = "control.gains_below_support.support_fraction";
        within(
            name,
            s.support_fraction,
            0.0,
            1.0,
            "must be in [0, 1]: the share of the body weight below which its gains run (0: never)",
        )?;
        check(
            self.treadmill.is_some(),
            name,
            s.support_fraction,
            "needs a [treadmill]: the schedule is by the harness's treadmill.bws_fraction",
        )?;
        pma_control::ControllerConfig::AprcNdo(s.gains).validate()?;
        Ok(())
    }

    /// The walking support of the patient (the harness's share of their weight), `None`
    /// off a treadmill.
    pub fn support(&self) -> Option<f64> {
        self.treadmill.as_ref().map(|t| t.bws_fraction)
    }

    /// The APRC-NDO gains every muscle runs with on this scenario: `control.gains`, or
    /// `control.gains_below_support`'s where the patient's support is below its fraction.
    pub fn aprc_gains(&self) -> pma_control::AprcGains {
        self.control
            .scheduled_at(self.support())
            .map_or(self.control.gains, |s| s.gains)
    }

    /// A belt on the adults' data runs at a speed the data were recorded at: within
    /// [`BELT_SPEED_OFF_REFERENCE_MAX`] of the condition's mean speed. Off it, no recorded
    /// gait fits the belt (the stance foot would drag along it), and the run would follow a
    /// reference nobody walked at that speed (issue 47: at 0.7 m/s the patient collapsed,
    /// exit 0).
    fn check_belt_on_reference(&self, t: &TreadmillSettings) -> Result<(), LegError> {
        let (Some(belt), crate::gait::GaitData::Fukuchi2018, Some(speed)) =
            (t.speed_m_per_s, self.gait.data, self.gait.speed_m_per_s)
        else {
            return Ok(());
        };
        // A leg r times the URDF patient's walks the reference's angles at the same cadence
        // r times as fast: the belt is compared with the recorded speed so scaled.
        let r = t
            .height_m
            .map_or(1.0, |h| h / crate::body::URDF_PATIENT_HEIGHT_M);
        let recorded = crate::gait::AdultNorms::at(speed)?.speed_m_s * r;
        let off = (belt / recorded - 1.0).abs();
        check(
            off <= BELT_SPEED_OFF_REFERENCE_MAX,
            "treadmill.speed_m_per_s",
            belt,
            format!(
                "has no adult reference: the gait (gait.speed_m_per_s = {speed}) was recorded at {:.3} m/s (Fukuchi et al. 2018){}, a belt within {:.0} % of it is {:.3} to {:.3} m/s; the data's faster conditions (0.68-1.24 m/s) are not in this repository (docs/envelope.md)",
                recorded / r,
                height_note(t.height_m, recorded),
                100.0 * BELT_SPEED_OFF_REFERENCE_MAX,
                recorded * (1.0 - BELT_SPEED_OFF_REFERENCE_MAX),
                recorded * (1.0 + BELT_SPEED_OFF_REFERENCE_MAX),
            ),
        )?;
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
