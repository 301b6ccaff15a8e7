//! The rig's configuration file (`crates/pma-rig/models/*.toml`): device, signals, calibration,
//! limits, control, reference and, for the virtual rig, the simulated muscle.
use crate::daq::{AnalogChannel, DigitalLine};
use crate::error::RigError;
use pma_bench::PlantConfig;
use pma_control::supervisor::{ReadingWindow, SupervisorLimits};
use pma_control::{
    ChirpReference, ControllerConfig, ControllerKind, NominalModel, NominalSpec, SineReference,
    SmoothStart, Trajectory,
};
use pma_model::error::{check, finite, positive, within};
use pma_model::Invalid;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The embedded default configuration (`crates/pma-rig/models/virtual.toml`).
pub const EMBEDDED_VIRTUAL: &str = include_str!("../models/virtual.toml");
/// The seed rig's configuration (`crates/pma-rig/models/pci6052e.toml`).
pub const EMBEDDED_PCI6052E: &str = include_str!("../models/pci6052e.toml");

/// Which driver talks to the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Driver {
    /// The simulated rig (`pma-model` muscle behind a DAQ in volts and counts).
    Virtual,
    /// A Comedi board (feature `comedi`).
    Comedi,
}

/// The device.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceConfig {
    /// Driver.
    pub driver: Driver,
    /// Device path (Comedi: `/dev/comedi0`).
    #[serde(default)]
    pub path: String,
}

/// Where each signal is wired.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Signals {
    /// Displacement sensor (analog input).
    pub position: AnalogChannel,
    /// Proportional valve set point (analog output).
    pub valve: AnalogChannel,
    /// Charge-pump line toggled every period for the external dump-valve relay.
    #[serde(default)]
    pub charge_pump: Option<DigitalLine>,
    /// The valve's actual-pressure output (the VPPM's 0-10 V actual value), analog input:
    /// read and logged every period when present (identification fits the valve on it),
    /// and a reading above the pressure limit is a fault. Put it on a bipolar range: 0 bar
    /// is 0 V, the bottom of a unipolar range, where Comedi reports NaN.
    #[serde(default)]
    pub pressure: Option<AnalogChannel>,
}

impl Signals {
    /// Every signal on its own channel.
    fn validate(&self) -> Result<(), RigError> {
        let mut used: Vec<(&'static str, u32, u32)> = vec![
            (
                "signals.position",
                self.position.subdevice,
                self.position.channel,
            ),
            ("signals.valve", self.valve.subdevice, self.valve.channel),
        ];
        if let Some(p) = &self.charge_pump {
            used.push(("signals.charge_pump", p.subdevice, p.channel));
        }
        if let Some(p) = &self.pressure {
            used.push(("signals.pressure", p.subdevice, p.channel));
        }
        for (i, a) in used.iter().enumerate() {
            if let Some(b) = used[..i].iter().find(|b| (b.1, b.2) == (a.1, a.2)) {
                return Err(RigError::Field {
                    field: a.0,
                    message: format!(
                        "subdevice {} channel {} is already {}: every signal needs its own channel",
                        a.1, a.2, b.0
                    ),
                });
            }
        }
        Ok(())
    }
}

/// A linear transducer: `value = (volts - offset_v) * gain`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Sensor: contraction per volt (m/V).
    pub position_m_per_v: f64,
    /// Sensor: volts at zero contraction (V).
    pub position_offset_v: f64,
    /// Valve: pressure per volt (Pa/V).
    pub valve_pa_per_v: f64,
    /// Valve: volts at zero (gauge) pressure (V).
    pub valve_offset_v: f64,
    /// Pressure channel (`signals.pressure`): pressure per volt (Pa/V); default the valve's
    /// set-point scale (the VPPM's actual value uses the set point's scale).
    #[serde(default)]
    pub pressure_pa_per_v: Option<f64>,
    /// Pressure channel: volts at zero pressure (V); default the valve's.
    #[serde(default)]
    pub pressure_offset_v: Option<f64>,
}

impl Calibration {
    /// Contraction (m) of a sensor voltage.
    pub fn position_m(&self, volts: f64) -> f64 {
        (volts - self.position_offset_v) * self.position_m_per_v
    }
    /// Sensor voltage of a contraction.
    pub fn position_v(&self, position_m: f64) -> f64 {
        position_m / self.position_m_per_v + self.position_offset_v
    }
    /// Valve voltage of a pressure (Pa).
    pub fn valve_v(&self, pressure_pa: f64) -> f64 {
        pressure_pa / self.valve_pa_per_v + self.valve_offset_v
    }
    /// Pressure (Pa) of a valve voltage.
    pub fn valve_pa(&self, volts: f64) -> f64 {
        (volts - self.valve_offset_v) * self.valve_pa_per_v
    }
    /// Pressure (Pa) of the pressure channel's voltage.
    pub fn pressure_pa(&self, volts: f64) -> f64 {
        (volts - self.pressure_zero_v()) * self.pressure_scale_pa_per_v()
    }
    /// The pressure channel's voltage of a pressure (Pa).
    pub fn pressure_v(&self, pressure_pa: f64) -> f64 {
        pressure_pa / self.pressure_scale_pa_per_v() + self.pressure_zero_v()
    }
}

/// What the safety supervisor enforces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Highest pressure command (Pa); commands are clamped to `[0, max]`.
    pub pressure_max_pa: f64,
    /// Fastest command change (Pa/s); faster commands are rate-limited.
    pub pressure_rate_max_pa_per_s: f64,
    /// Lowest admissible contraction (m); below it the rig vents and stops.
    pub position_min_m: f64,
    /// Highest admissible contraction (m).
    pub position_max_m: f64,
    /// A reading identical for this many periods is a stuck sensor (0: not checked).
    pub sensor_stuck_periods: u32,
    /// The loop silent for this many periods trips the watchdog, which vents on its own
    /// (at most [`WATCHDOG_MAX_S`] of silence).
    pub watchdog_periods: u32,
    /// A wake-up that misses more than this many deadlines in a row is a timing fault.
    #[serde(default = "default_overrun_consecutive")]
    pub overrun_max_consecutive_periods: u32,
    /// A share of missed deadlines above this over a window of 1000 periods is a timing
    /// fault (0..=0.5).
    #[serde(default = "default_overrun_share")]
    pub overrun_max_share: f64,
}

fn default_overrun_consecutive() -> u32 {
    10
}

fn default_overrun_share() -> f64 {
    0.05
}

/// Longest watchdog timeout a configuration may ask for (s): a valve left at its last
/// command for longer than this is not supervised.
pub const WATCHDOG_MAX_S: f64 = 0.25;

/// Largest command step the rate limit may allow in one period, as a fraction of the
/// pressure limit: at most half the range, so that a full 0 -> max flip takes at least
/// two periods and the limit is never a field that says "on" while limiting nothing.
pub const RATE_STEP_MAX_FRACTION: f64 = 0.5;

/// Fewest periods of identical readings that count as a frozen sensor: one repeat is what a
/// quantised converter gives whenever the muscle moves less than a step in a period.
pub const SENSOR_STUCK_MIN_PERIODS: u32 = 2;

/// Longest a frozen reading may go undetected (s): the shipped 500 periods of 1 ms. Beyond
/// it the controller drives the muscle blind, its position window unchecked.
pub const SENSOR_STUCK_MAX_S: f64 = 0.5;

/// Longest run a rig configuration may ask for (s): a day. A longer one is a typo (a
/// `duration_s = 1e308` ran until killed, its log filling the disk).
pub const RIG_DURATION_MAX_S: f64 = 86_400.0;

/// Longest blend from rest into the reference (s).
pub const RAMP_MAX_S: f64 = 60.0;

/// Shortest and longest control period of a rig (s): the controllers are discretised for
/// periods of 0.1-10 ms (the paper ran at 1 ms).
pub const PERIOD_RANGE_S: (f64, f64) = (1e-4, 1e-2);

/// The muscle on the rig: what it tolerates, against which the limits are checked.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MuscleRating {
    /// Highest admissible pressure (Pa gauge): 6 bar for Festo's DMSP-20 and DMSP-40
    /// (Cao et al. 2020, Sec. IV-A; Festo Info 501).
    pub pressure_max_pa: f64,
    /// Nominal (rest) length (m).
    pub nominal_length_m: f64,
    /// Largest contraction as a fraction of the nominal length: 0.25 for the DMSP
    /// (Festo FluidSIM component library).
    #[serde(default = "default_contraction_max")]
    pub contraction_max_fraction: f64,
    /// Largest stretch below the rest length as a fraction of it. Festo allows a mounting
    /// pretension of 5 %; the default 10 % leaves room for a load hanging on the vented
    /// muscle. Readings beyond it mean a broken mount, not a muscle.
    #[serde(default = "default_stretch_max")]
    pub stretch_max_fraction: f64,
}

fn default_contraction_max() -> f64 {
    0.25
}

fn default_stretch_max() -> f64 {
    0.10
}

impl Default for MuscleRating {
    /// The seed rig's Festo DMSP-20-200: 0-6 bar, 200 mm.
    fn default() -> Self {
        Self {
            pressure_max_pa: 6.0e5,
            nominal_length_m: 0.2,
            contraction_max_fraction: default_contraction_max(),
            stretch_max_fraction: default_stretch_max(),
        }
    }
}

impl MuscleRating {
    /// Largest contraction the muscle can reach (m).
    pub fn contraction_max_m(&self) -> f64 {
        self.contraction_max_fraction * self.nominal_length_m
    }

    /// Largest stretch it can take (m, positive).
    pub fn stretch_max_m(&self) -> f64 {
        self.stretch_max_fraction * self.nominal_length_m
    }

    fn validate(&self) -> Result<(), RigError> {
        check(
            self.pressure_max_pa.is_finite()
                && self.pressure_max_pa > 0.0
                && self.pressure_max_pa <= 8.0e5,
            "muscle.pressure_max_pa",
            self.pressure_max_pa,
            "must be > 0 and at most 8 bar (the highest rating of a Festo DMSP)",
        )?;
        check(
            self.nominal_length_m.is_finite() && (0.03..=10.0).contains(&self.nominal_length_m),
            "muscle.nominal_length_m",
            self.nominal_length_m,
            "must be 0.03 to 10 m (Festo DMSP lengths are 40-9000 mm)",
        )?;
        check(
            self.contraction_max_fraction > 0.0 && self.contraction_max_fraction <= 0.3,
            "muscle.contraction_max_fraction",
            self.contraction_max_fraction,
            "must be > 0 and at most 0.3 (a DMSP contracts by at most 25 %)",
        )?;
        check(
            self.stretch_max_fraction > 0.0 && self.stretch_max_fraction <= 0.2,
            "muscle.stretch_max_fraction",
            self.stretch_max_fraction,
            "must be > 0 and at most 0.2",
        )?;
        Ok(())
    }
}

/// The controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlConfig {
    /// `aprc-ndo`, `aprc`, `psmc`, `ndo-smc`, `sta` or `pid`.
    pub controller: String,
    /// Gain file (relative to this file); absent: the controller's defaults.
    #[serde(default)]
    pub gains: Option<PathBuf>,
    /// What the controller believes of the muscle and load.
    pub nominal: NominalSpec,
}

/// The desired trajectory, entered smoothly from where the muscle rests at activation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum ReferenceConfig {
    /// `A sin(2 pi f t) + B`, eq. (50).
    Sine {
        /// `A` (m).
        amplitude_m: f64,
        /// `f` (Hz).
        frequency_hz: f64,
        /// `B` (m).
        offset_m: f64,
        /// Blend from the resting position into the sine (s).
        ramp_s: f64,
    },
    /// Linear chirp `f0 -> f1` over `sweep_s`.
    Chirp {
        /// Amplitude (m).
        amplitude_m: f64,
        /// Offset (m).
        offset_m: f64,
        /// Start frequency (Hz).
        f0_hz: f64,
        /// End frequency (Hz).
        f1_hz: f64,
        /// Sweep (s).
        sweep_s: f64,
        /// Blend from the resting position (s).
        ramp_s: f64,
    },
    /// Hold a contraction.
    Hold {
        /// Contraction (m).
        position_m: f64,
        /// Blend from the resting position (s).
        ramp_s: f64,
    },
}

/// How the virtual rig's time passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClockMode {
    /// The plant advances exactly one period per loop period, as fast as it can (tests).
    Lockstep,
    /// Wall-clock periods on absolute deadlines, the plant following wall time.
    Realtime,
}

/// The simulated rig behind the virtual DAQ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VirtualConfig {
    /// Plant preset or plant file (its muscle, load, valve and sensor noise; the sensor's
    /// range and resolution are the DAQ's).
    pub plant: String,
    /// Lockstep or real time.
    pub clock: ClockMode,
    /// Converter resolution (bits) of both analog channels; 0 for continuous values.
    pub converter_bits: u32,
    /// RMS noise the sensor adds (m); the plant file's sensor noise is not used.
    #[serde(default)]
    pub sensor_noise_rms_m: f64,
    /// Delay of the sensor reading (s).
    #[serde(default)]
    pub sensor_latency_s: f64,
    /// The analog input's range (V): optional, and if given it must be the range the
    /// simulated board (a PCI-6052E) has at `signals.position`'s range index.
    #[serde(deserialize_with = "pma_model::error::exact::option", default)]
    pub input_range_v: Option<[f64; 2]>,
    /// The analog output's range (V), likewise for `signals.valve`.
    #[serde(deserialize_with = "pma_model::error::exact::option", default)]
    pub output_range_v: Option<[f64; 2]>,
}

/// Real-time settings of the loop thread.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RealtimeConfig {
    /// Ask for `SCHED_FIFO` and `mlockall` (refusal is a warning).
    pub fifo: bool,
    /// `SCHED_FIFO` priority (1-99).
    pub priority: u8,
}

impl Default for RealtimeConfig {
    fn default() -> Self {
        Self {
            fifo: true,
            priority: 80,
        }
    }
}

/// What hangs on the muscle.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadConfig {
    /// The load, weighed (kg): identification takes its force scale from it.
    #[serde(default)]
    pub mass_kg: Option<f64>,
    /// A known mass added for this run (kg): the second run of the added-mass protocol,
    /// when the load is not weighed (`rig excite --added-mass-kg`). The virtual rig hangs it
    /// on its plant's load.
    #[serde(default)]
    pub added_mass_kg: f64,
}

/// A rig configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    /// Name.
    pub name: String,
    /// One line.
    #[serde(default)]
    pub description: String,
    /// Control period (s).
    pub period_s: f64,
    /// Run duration (s).
    pub duration_s: f64,
    /// CSV log (relative to the working directory).
    pub log_path: PathBuf,
    /// The board.
    pub device: DeviceConfig,
    /// Wiring.
    pub signals: Signals,
    /// Transducer scales.
    pub calibration: Calibration,
    /// The muscle's ratings (default: the DMSP-20-200 of the seed rig).
    #[serde(default)]
    pub muscle: MuscleRating,
    /// Safety limits.
    pub limits: Limits,
    /// The load (optional).
    #[serde(default)]
    pub load: LoadConfig,
    /// Controller.
    pub control: ControlConfig,
    /// Reference.
    pub reference: ReferenceConfig,
    /// Real-time settings.
    #[serde(default)]
    pub realtime: RealtimeConfig,
    /// The simulated rig (driver `virtual`).
    #[serde(default, rename = "virtual")]
    pub virtual_rig: Option<VirtualConfig>,
}

/// Highest reference frequency (Hz): a muscle under a load follows a few hertz at most
/// (Table I's corners are 0.06-1 Hz; the paper's chirp ends at 0.5 Hz).
pub const REFERENCE_FREQUENCY_MAX_HZ: f64 = 5.0;

fn frequency(field: &'static str, v: f64) -> Result<f64, Invalid> {
    within(
        field,
        v,
        0.0,
        REFERENCE_FREQUENCY_MAX_HZ,
        "must be 0 to 5 Hz (a loaded muscle follows a few hertz at most)",
    )
}

/// Largest magnitude of a calibration's volts (V): the widest ranges a DAQ board has are
/// +-10 V and 0..20 V (the PCI-6052E's).
pub const CALIBRATION_VOLTS_MAX: f64 = 20.0;
/// Plausible scales of a position sensor (m/V, magnitude): 10 um to 10 m over 10 V (a
/// DMSP's longest travel, 25 % of 9 m, is 2.25 m).
pub const POSITION_M_PER_V_RANGE: (f64, f64) = (1e-6, 1.0);
/// Plausible scales of a valve's set point or actual value (Pa/V): 0.1 to 100 bar over
/// 10 V (proportional pressure valves span 0-0.5 to 0-10 bar).
pub const PRESSURE_PA_PER_V_RANGE: (f64, f64) = (1e3, 1e6);

fn volts(field: &'static str, v: f64) -> Result<f64, Invalid> {
    within(
        field,
        v,
        -CALIBRATION_VOLTS_MAX,
        CALIBRATION_VOLTS_MAX,
        "must be -20 to 20 V (the widest ranges of a DAQ board are +-10 V and 0..20 V)",
    )
}

impl Calibration {
    /// Every scale and offset finite, of the right sign and plausible.
    fn validate(&self) -> Result<(), Invalid> {
        let (lo, hi) = POSITION_M_PER_V_RANGE;
        check(
            self.position_m_per_v.is_finite()
                && (lo..=hi).contains(&self.position_m_per_v.abs()),
            "calibration.position_m_per_v",
            self.position_m_per_v,
            "must be 1e-6 to 1 m/V in magnitude (10 um to 10 m over 10 V); negative if the sensor's voltage falls as the muscle contracts",
        )?;
        volts("calibration.position_offset_v", self.position_offset_v)?;
        pressure_scale(
            "calibration.valve_pa_per_v",
            self.valve_pa_per_v,
            "a higher set point must mean more pressure: a negative scale would turn every vent into full pressure",
        )?;
        volts("calibration.valve_offset_v", self.valve_offset_v)?;
        if let Some(v) = self.pressure_pa_per_v {
            pressure_scale(
                "calibration.pressure_pa_per_v",
                v,
                "a higher reading must mean more pressure: a negative scale would read an over-pressure as a vacuum and hide it",
            )?;
        }
        if let Some(v) = self.pressure_offset_v {
            volts("calibration.pressure_offset_v", v)?;
        }
        Ok(())
    }

    /// The pressure channel's scale (Pa/V): its own, or the valve's.
    pub fn pressure_scale_pa_per_v(&self) -> f64 {
        self.pressure_pa_per_v.unwrap_or(self.valve_pa_per_v)
    }

    /// The pressure channel's volts at 0 Pa: its own, or the valve's.
    pub fn pressure_zero_v(&self) -> f64 {
        self.pressure_offset_v.unwrap_or(self.valve_offset_v)
    }
}

fn pressure_scale(field: &'static str, v: f64, why: &str) -> Result<f64, Invalid> {
    let (lo, hi) = PRESSURE_PA_PER_V_RANGE;
    check(
        v.is_finite() && (lo..=hi).contains(&v),
        field,
        v,
        format!("must be 1e3 to 1e6 Pa/V (0.1 to 100 bar over 10 V); {why}"),
    )
}

impl RigConfig {
    /// Parses and validates a configuration; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, RigError> {
        let cfg: RigConfig = toml::from_str(text).map_err(|e| RigError::Parse {
            file: file.to_owned(),
            message: pma_control::text::toml_error(text, &e),
        })?;
        cfg.validate().map_err(|e| e.in_file(file))?;
        Ok(cfg)
    }

    /// Reads a configuration file, or `virtual` / `pci6052e` for the shipped ones.
    pub fn load(name_or_path: &str) -> Result<(Self, PathBuf), RigError> {
        match name_or_path {
            "virtual" => Ok((
                Self::from_toml_str(EMBEDDED_VIRTUAL, "crates/pma-rig/models/virtual.toml")?,
                PathBuf::from("crates/pma-rig/models"),
            )),
            "pci6052e" => Ok((
                Self::from_toml_str(EMBEDDED_PCI6052E, "crates/pma-rig/models/pci6052e.toml")?,
                PathBuf::from("crates/pma-rig/models"),
            )),
            path => {
                let text = std::fs::read_to_string(path).map_err(|e| RigError::Io {
                    path: path.to_owned(),
                    message: e.to_string(),
                })?;
                let dir = Path::new(path)
                    .parent()
                    .map(Path::to_path_buf)
                    .unwrap_or_default();
                Ok((Self::from_toml_str(&text, path)?, dir))
            }
        }
    }

    /// Every field in range, every limit consistent: checked before anything touches the
    /// board.
    pub fn validate(&self) -> Result<(), RigError> {
        check(
            self.period_s >= PERIOD_RANGE_S.0 && self.period_s <= PERIOD_RANGE_S.1,
            "period_s",
            self.period_s,
            "must be 0.0001 to 0.01 s (the controllers are discretised for 0.1-10 ms; the paper ran at 1 ms)",
        )?;
        within(
            "duration_s",
            self.duration_s,
            self.period_s,
            RIG_DURATION_MAX_S,
            "must be one period up to 86400 s (a day at the rig)",
        )?;
        if self.device.driver == Driver::Comedi && self.device.path.is_empty() {
            return Err(RigError::Missing {
                field: "device.path",
                why: "the comedi driver needs the device (e.g. /dev/comedi0)",
            });
        }
        self.signals.validate()?;
        self.calibration.validate()?;
        if let Some(m) = self.load.mass_kg {
            within(
                "load.mass_kg",
                m,
                0.05,
                pma_model::MAX_LOAD_KG,
                "must be 0.05 to 600 kg",
            )?;
        }
        within(
            "load.added_mass_kg",
            self.load.added_mass_kg,
            0.0,
            pma_model::MAX_LOAD_KG,
            "must be 0 to 600 kg",
        )?;
        self.muscle.validate()?;
        self.limits_check()?;
        self.control_kind()?;
        self.control.nominal_model_check()?;
        self.reference_check()?;
        check(
            (1..=99).contains(&self.realtime.priority),
            "realtime.priority",
            f64::from(self.realtime.priority),
            "must be 1 to 99",
        )?;
        match (&self.device.driver, &self.virtual_rig) {
            (Driver::Virtual, None) => {
                return Err(RigError::Missing {
                    field: "virtual",
                    why: "the virtual driver needs a [virtual] section",
                })
            }
            (Driver::Virtual, Some(v)) => v.validate()?,
            _ => {}
        }
        Ok(())
    }

    /// The limits against each other, the muscle's ratings and the period.
    fn limits_check(&self) -> Result<(), RigError> {
        let l = &self.limits;
        let m = &self.muscle;
        positive("limits.pressure_max_pa", l.pressure_max_pa)?;
        if l.pressure_max_pa > m.pressure_max_pa {
            return Err(RigError::Field {
                field: "limits.pressure_max_pa",
                message: format!(
                    "{} bar is above the muscle's rating, muscle.pressure_max_pa = {} bar",
                    l.pressure_max_pa / 1e5,
                    m.pressure_max_pa / 1e5
                ),
            });
        }
        self.rate_limit_check()?;
        finite("limits.position_min_m", l.position_min_m)?;
        finite("limits.position_max_m", l.position_max_m)?;
        check(
            l.position_max_m > l.position_min_m,
            "limits.position_max_m",
            l.position_max_m,
            "must exceed limits.position_min_m",
        )?;
        if l.position_max_m > m.contraction_max_m() {
            return Err(RigError::Field {
                field: "limits.position_max_m",
                message: format!(
                    "{} mm is beyond the muscle's largest contraction, {} mm ({} % of its {} mm): a window the muscle cannot reach protects nothing",
                    l.position_max_m * 1e3,
                    m.contraction_max_m() * 1e3,
                    m.contraction_max_fraction * 100.0,
                    m.nominal_length_m * 1e3
                ),
            });
        }
        if l.position_min_m < -m.stretch_max_m() {
            return Err(RigError::Field {
                field: "limits.position_min_m",
                message: format!(
                    "{} mm is a stretch beyond the muscle's {} mm ({} % of its {} mm)",
                    l.position_min_m * 1e3,
                    -m.stretch_max_m() * 1e3,
                    m.stretch_max_fraction * 100.0,
                    m.nominal_length_m * 1e3
                ),
            });
        }
        let timeout_s = f64::from(l.watchdog_periods) * self.period_s;
        if l.watchdog_periods < 2 || timeout_s > WATCHDOG_MAX_S {
            return Err(RigError::Field {
                field: "limits.watchdog_periods",
                message: format!(
                    "{} periods of {} s is a {timeout_s} s timeout: it must be at least 2 periods and at most {WATCHDOG_MAX_S} s",
                    l.watchdog_periods, self.period_s
                ),
            });
        }
        if l.overrun_max_consecutive_periods == 0
            || l.overrun_max_consecutive_periods >= l.watchdog_periods
        {
            return Err(RigError::Field {
                field: "limits.overrun_max_consecutive_periods",
                message: format!(
                    "{} must be at least 1 and below limits.watchdog_periods ({})",
                    l.overrun_max_consecutive_periods, l.watchdog_periods
                ),
            });
        }
        check(
            l.overrun_max_share > 0.0 && l.overrun_max_share <= 0.5,
            "limits.overrun_max_share",
            l.overrun_max_share,
            "must be > 0 and at most 0.5",
        )?;
        self.stuck_check()
    }

    /// The rate limit must bind: a command may cross at most half the pressure range in
    /// one period. Above that no step the valve range allows is ever limited, and the
    /// field would switch the limit off while saying it is on.
    fn rate_limit_check(&self) -> Result<(), RigError> {
        let l = &self.limits;
        let per_period_pa = l.pressure_rate_max_pa_per_s * self.period_s;
        if !(l.pressure_rate_max_pa_per_s.is_finite() && l.pressure_rate_max_pa_per_s > 0.0)
            || per_period_pa > RATE_STEP_MAX_FRACTION * l.pressure_max_pa
        {
            return Err(RigError::Field {
                field: "limits.pressure_rate_max_pa_per_s",
                message: format!(
                    "{} must be > 0 and at most {} (half of limits.pressure_max_pa, {} bar, per period of {} s): a faster limit never binds and leaves the valve unlimited",
                    pma_model::error::number(l.pressure_rate_max_pa_per_s),
                    pma_model::error::number(RATE_STEP_MAX_FRACTION * l.pressure_max_pa / self.period_s),
                    l.pressure_max_pa / 1e5,
                    self.period_s
                ),
            });
        }
        Ok(())
    }

    /// The frozen-sensor check cannot be switched off, nor set so long that the
    /// controller drives blind for longer than [`SENSOR_STUCK_MAX_S`].
    fn stuck_check(&self) -> Result<(), RigError> {
        let l = &self.limits;
        let blind_s = f64::from(l.sensor_stuck_periods) * self.period_s;
        if l.sensor_stuck_periods < SENSOR_STUCK_MIN_PERIODS || blind_s > SENSOR_STUCK_MAX_S {
            return Err(RigError::Field {
                field: "limits.sensor_stuck_periods",
                message: format!(
                    "{} periods of {} s must be at least {SENSOR_STUCK_MIN_PERIODS} periods and at most {SENSOR_STUCK_MAX_S} s: 0 would switch the frozen-sensor check off, and a longer one lets the controller drive blind",
                    l.sensor_stuck_periods, self.period_s
                ),
            });
        }
        Ok(())
    }

    /// What the supervisor enforces on this rig.
    pub fn supervisor_limits(&self) -> SupervisorLimits {
        let l = &self.limits;
        SupervisorLimits {
            pressure_max_pa: l.pressure_max_pa,
            pressure_rate_max_pa_per_s: l.pressure_rate_max_pa_per_s,
            windows: vec![ReadingWindow {
                name: "position",
                unit: "m",
                min: l.position_min_m,
                max: l.position_max_m,
            }],
            sensor_stuck_periods: l.sensor_stuck_periods,
            watchdog_periods: l.watchdog_periods,
            overrun_max_consecutive_periods: l.overrun_max_consecutive_periods,
            overrun_max_share: l.overrun_max_share,
        }
    }

    /// The controller kind.
    pub fn control_kind(&self) -> Result<ControllerKind, RigError> {
        self.control
            .controller
            .parse()
            .map_err(|e: pma_control::ConfigError| RigError::Field {
                field: "control.controller",
                message: e.to_string(),
            })
    }

    fn reference_check(&self) -> Result<(), RigError> {
        self.reference_shape_check()?;
        let (low, high) = self.reference_span_m();
        let l = &self.limits;
        if low < l.position_min_m || high > l.position_max_m {
            return Err(RigError::Field {
                field: "reference",
                message: format!(
                    "the reference spans {:.1}..{:.1} mm, outside the position window {:.1}..{:.1} mm: it would drive the muscle into a fault",
                    low * 1e3,
                    high * 1e3,
                    l.position_min_m * 1e3,
                    l.position_max_m * 1e3
                ),
            });
        }
        Ok(())
    }

    /// A ramp into the reference is a blend of seconds: one of [`RAMP_MAX_S`] or more never
    /// reaches, in any run worth making, the trajectory it was set up to track.
    fn ramp_check(&self, ramp_s: f64) -> Result<(), Invalid> {
        within(
            "reference.ramp_s",
            ramp_s,
            0.0,
            RAMP_MAX_S,
            "must be 0 to 60 s (a blend from rest into the reference; slower motion belongs in the reference itself)",
        )
        .map(|_| ())
    }

    /// The lowest and highest position of the reference's trajectory (m).
    pub fn reference_span_m(&self) -> (f64, f64) {
        match self.reference {
            ReferenceConfig::Sine {
                amplitude_m,
                offset_m,
                ..
            }
            | ReferenceConfig::Chirp {
                amplitude_m,
                offset_m,
                ..
            } => (offset_m - amplitude_m.abs(), offset_m + amplitude_m.abs()),
            ReferenceConfig::Hold { position_m, .. } => (position_m, position_m),
        }
    }

    fn reference_shape_check(&self) -> Result<(), RigError> {
        match self.reference {
            ReferenceConfig::Sine {
                amplitude_m,
                frequency_hz,
                offset_m,
                ramp_s,
            } => {
                finite("reference.amplitude_m", amplitude_m)?;
                frequency("reference.frequency_hz", frequency_hz)?;
                finite("reference.offset_m", offset_m)?;
                self.ramp_check(ramp_s)?;
            }
            ReferenceConfig::Chirp {
                amplitude_m,
                offset_m,
                f0_hz,
                f1_hz,
                sweep_s,
                ramp_s,
            } => {
                finite("reference.amplitude_m", amplitude_m)?;
                finite("reference.offset_m", offset_m)?;
                frequency("reference.f0_hz", f0_hz)?;
                frequency("reference.f1_hz", f1_hz)?;
                within(
                    "reference.sweep_s",
                    sweep_s,
                    f64::MIN_POSITIVE,
                    RIG_DURATION_MAX_S,
                    "must be > 0 and at most 86400 s",
                )?;
                self.ramp_check(ramp_s)?;
            }
            ReferenceConfig::Hold { position_m, ramp_s } => {
                finite("reference.position_m", position_m)?;
                self.ramp_check(ramp_s)?;
            }
        }
        Ok(())
    }

    /// The controller of `gains` with this rig's nominal model and pressure limit: the one
    /// the run, the replay and the benchmarks all build.
    pub fn build_controller(
        &self,
        gains: &ControllerConfig,
    ) -> Result<Box<dyn pma_control::Controller>, RigError> {
        let limits = pma_control::CommandLimits {
            min_pa: 0.0,
            max_pa: self.limits.pressure_max_pa,
        };
        Ok(pma_control::build_controller(
            gains,
            self.nominal_model(),
            limits,
        )?)
    }

    /// The controller of a run: the excitation if one is given, else `gains`' controller.
    pub fn controller_for(
        &self,
        gains: &ControllerConfig,
        excitation: Option<&pma_control::ExcitationSpec>,
    ) -> Result<Box<dyn pma_control::Controller>, RigError> {
        match excitation {
            Some(spec) => Ok(Box::new(pma_control::Excitation::new(*spec).map_err(
                |e| RigError::Field {
                    field: "excitation",
                    message: e.to_string(),
                },
            )?)),
            None => self.build_controller(gains),
        }
    }

    /// The default excitation of this rig for `duration_s`: steps and a 0.05-3 Hz chirp
    /// between 0.5 bar (at most a tenth of the limit) and half the pressure limit, at half
    /// the supervisor's rate limit, backing off 15 % of the position window inside it.
    pub fn default_excitation(&self, duration_s: f64) -> pma_control::ExcitationSpec {
        let l = &self.limits;
        let margin = 0.15 * (l.position_max_m - l.position_min_m);
        pma_control::ExcitationSpec {
            position_min_m: l.position_min_m + margin,
            position_max_m: l.position_max_m - margin,
            ..pma_control::ExcitationSpec::steps_and_chirp(
                duration_s,
                (0.5e5f64).min(0.1 * l.pressure_max_pa),
                0.5 * l.pressure_max_pa,
                0.5 * l.pressure_rate_max_pa_per_s,
            )
        }
    }

    /// The controller's model.
    pub fn nominal_model(&self) -> NominalModel {
        self.control.nominal.model()
    }

    /// The reference, entered from `start_m` over its ramp.
    pub fn reference(&self, start_m: f64) -> SmoothStart {
        let (trajectory, ramp_s): (Trajectory, f64) = match self.reference {
            ReferenceConfig::Sine {
                amplitude_m,
                frequency_hz,
                offset_m,
                ramp_s,
            } => (
                Trajectory::Sine(SineReference {
                    amplitude_m,
                    frequency_hz,
                    offset_m,
                }),
                ramp_s,
            ),
            ReferenceConfig::Chirp {
                amplitude_m,
                offset_m,
                f0_hz,
                f1_hz,
                sweep_s,
                ramp_s,
            } => (
                Trajectory::Chirp(ChirpReference {
                    amplitude_m,
                    offset_m,
                    f0_hz,
                    f1_hz,
                    sweep_s,
                }),
                ramp_s,
            ),
            ReferenceConfig::Hold { position_m, ramp_s } => (Trajectory::Hold(position_m), ramp_s),
        };
        SmoothStart {
            trajectory,
            start_m,
            ramp_s,
        }
    }
}

impl ControlConfig {
    fn nominal_model_check(&self) -> Result<(), RigError> {
        self.nominal
            .validate()
            .map_err(|e| e.within_section("control.nominal"))?;
        Ok(())
    }

    /// The controller configuration: the gain file (relative to `dir`) or the defaults.
    pub fn controller_config(
        &self,
        kind: ControllerKind,
        dir: &Path,
    ) -> Result<ControllerConfig, RigError> {
        let Some(rel) = &self.gains else {
            return Ok(kind.default_config());
        };
        let path = dir.join(rel);
        let text = std::fs::read_to_string(&path).map_err(|e| RigError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let cfg = ControllerConfig::from_toml_str(&text).map_err(|e| RigError::Field {
            field: "control.gains",
            message: format!("`{}`: {e}", path.display()),
        })?;
        Ok(cfg)
    }
}

impl VirtualConfig {
    fn validate(&self) -> Result<(), RigError> {
        PlantConfig::load(&self.plant).map_err(|e| RigError::Field {
            field: "virtual.plant",
            message: e.to_string(),
        })?;
        check(
            self.converter_bits <= 24,
            "virtual.converter_bits",
            f64::from(self.converter_bits),
            "must be 0 to 24",
        )?;
        check(
            self.sensor_latency_s.is_finite()
                && (0.0..=VIRTUAL_LATENCY_MAX_S).contains(&self.sensor_latency_s),
            "virtual.sensor_latency_s",
            self.sensor_latency_s,
            "must be 0 to 1 s",
        )?;
        check(
            self.sensor_noise_rms_m.is_finite()
                && (0.0..=VIRTUAL_NOISE_MAX_M).contains(&self.sensor_noise_rms_m),
            "virtual.sensor_noise_rms_m",
            self.sensor_noise_rms_m,
            "must be 0 to 0.001 m RMS",
        )?;
        Ok(())
    }
}

/// Longest sensor latency the virtual rig simulates (s).
pub const VIRTUAL_LATENCY_MAX_S: f64 = 1.0;
/// Largest sensor noise the virtual rig simulates (m RMS).
pub const VIRTUAL_NOISE_MAX_M: f64 = 1e-3;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_configurations_load() {
        let v = RigConfig::from_toml_str(EMBEDDED_VIRTUAL, "virtual.toml").unwrap();
        assert_eq!(v.device.driver, Driver::Virtual);
        let c = RigConfig::from_toml_str(EMBEDDED_PCI6052E, "pci6052e.toml").unwrap();
        assert_eq!(c.device.driver, Driver::Comedi);
        assert_eq!(c.device.path, "/dev/comedi0");
    }

    fn with_calibration(line: &str) -> String {
        let text = EMBEDDED_VIRTUAL.replace(
            "valve_offset_v = 0.0\n",
            &format!("valve_offset_v = 0.0\n{line}\n"),
        );
        assert_ne!(text, EMBEDDED_VIRTUAL);
        text
    }

    /// Regression: `pressure_pa_per_v = -1e5` was accepted while a negative
    /// `valve_pa_per_v` was refused; on a real board it reads an over-pressure as a vacuum,
    /// so the supervisor's pressure check never fires.
    #[test]
    fn a_negative_pressure_channel_scale_is_refused() {
        let e = RigConfig::from_toml_str(&with_calibration("pressure_pa_per_v = -1.0e5"), "n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("calibration.pressure_pa_per_v"), "{e}");
        assert!(e.contains("over-pressure"), "{e}");
    }

    /// Every calibration field has a plausible range, and a value outside it is one error
    /// naming the field.
    #[test]
    fn every_calibration_field_is_bounded_naming_the_field() {
        let cases = [
            (
                "position_m_per_v = 0.015\n",
                "position_m_per_v = 1.0e3\n",
                "calibration.position_m_per_v",
            ),
            (
                "position_m_per_v = 0.015\n",
                "position_m_per_v = 1.0e-9\n",
                "calibration.position_m_per_v",
            ),
            (
                "position_m_per_v = 0.015\n",
                "position_m_per_v = nan\n",
                "calibration.position_m_per_v",
            ),
            (
                "position_offset_v = 1.3333333333333333",
                "position_offset_v = 1.0e6",
                "calibration.position_offset_v",
            ),
            (
                "valve_pa_per_v = 1.0e5",
                "valve_pa_per_v = 1.0e12",
                "calibration.valve_pa_per_v",
            ),
            (
                "valve_pa_per_v = 1.0e5",
                "valve_pa_per_v = 1.0",
                "calibration.valve_pa_per_v",
            ),
            (
                "valve_offset_v = 0.0\n",
                "valve_offset_v = -1.0e6\n",
                "calibration.valve_offset_v",
            ),
            (
                "valve_offset_v = 0.0\n",
                "valve_offset_v = 0.0\npressure_pa_per_v = 1.0e9\n",
                "calibration.pressure_pa_per_v",
            ),
            (
                "valve_offset_v = 0.0\n",
                "valve_offset_v = 0.0\npressure_pa_per_v = 0.0\n",
                "calibration.pressure_pa_per_v",
            ),
            (
                "valve_offset_v = 0.0\n",
                "valve_offset_v = 0.0\npressure_offset_v = inf\n",
                "calibration.pressure_offset_v",
            ),
        ];
        for (from, to, field) in cases {
            let text = EMBEDDED_VIRTUAL.replace(from, to);
            assert_ne!(text, EMBEDDED_VIRTUAL, "{to}: the edit did not apply");
            let e = RigConfig::from_toml_str(&text, "cal.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(field) && e.lines().count() == 1, "{to}: {e}");
        }
        // The shipped scales, a sensor mounted the other way round and a 0-6 bar valve
        // on 0-10 V are plausible.
        for line in ["pressure_pa_per_v = 6.0e4", "pressure_offset_v = -0.5"] {
            RigConfig::from_toml_str(&with_calibration(line), "ok.toml").expect(line);
        }
        let reversed =
            EMBEDDED_VIRTUAL.replace("position_m_per_v = 0.015\n", "position_m_per_v = -0.015\n");
        RigConfig::from_toml_str(&reversed, "reversed.toml").expect("a reversed sensor");
    }
}
