//! The patient's settings (the scenario's `[patient]`): presets, overrides, and their
//! validation, resolved into the parameters the model runs on.
use crate::base::{invalid, LegError};
use pma_model::error::{finite, non_negative, positive, within};
use serde::Deserialize;

/// Severity presets of the stretch reflex.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpasticityPreset {
    /// No reflex.
    None,
    /// Mild.
    Mild,
    /// Moderate.
    Moderate,
    /// Severe.
    Severe,
}

/// A stretch reflex: `tau = -K_ext max(0, w(t - d) - w_th) + K_flx max(0, -w(t - d) - w_th)`
/// with `w` the joint's flexion rate (flexion stretches the extensors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reflex {
    /// Gain of the extensors, stretched by flexion (N m s/rad).
    pub extensor_gain_nm_s_per_rad: f64,
    /// Gain of the flexors, stretched by extension (N m s/rad).
    pub flexor_gain_nm_s_per_rad: f64,
    /// Stretch speed above which the reflex acts (rad/s).
    pub threshold_rad_s: f64,
    /// Reflex delay, stretch to torque (s).
    pub delay_s: f64,
}

impl SpasticityPreset {
    /// The knee's reflex of this severity. Gains and thresholds are calibrated so that a
    /// Winter shank released from full extension (pendulum test, damping 0.5 N m s/rad)
    /// gives R2 = 1.41 (mild), 1.13 (moderate) and 1.05 (severe) against 1.66 without a
    /// reflex (healthy 1.678 +- 0.090, Kim et al. 1996); flexors at half the extensors'
    /// gain; a 60 ms delay (short-latency reflex plus electromechanical delay).
    pub fn knee(self) -> Reflex {
        let (k, th) = match self {
            SpasticityPreset::None => (0.0, f64::INFINITY),
            SpasticityPreset::Mild => (1.5, 2.6),
            SpasticityPreset::Moderate => (3.5, 1.2),
            SpasticityPreset::Severe => (7.0, 0.5),
        };
        Reflex {
            extensor_gain_nm_s_per_rad: k,
            flexor_gain_nm_s_per_rad: 0.5 * k,
            threshold_rad_s: th,
            delay_s: 0.06,
        }
    }

    /// The hip's reflex: the knee's, scaled by the ratio of healthy maximal voluntary
    /// torques (hip extensors ~ knee extensors, hip flexors ~ 1.3 x knee flexors); no
    /// published identification of the hip was found.
    pub fn hip(self) -> Reflex {
        let k = self.knee();
        Reflex {
            flexor_gain_nm_s_per_rad: 1.3 * k.flexor_gain_nm_s_per_rad,
            ..k
        }
    }
}

/// `[patient.<joint>.spasticity]`: a preset, any field of which may be overridden.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpasticitySettings {
    /// `none`, `mild`, `moderate` or `severe` (default `none`: every field must be given).
    pub preset: Option<SpasticityPreset>,
    /// Overrides the extensors' gain (N m s/rad).
    pub extensor_gain_nm_s_per_rad: Option<f64>,
    /// Overrides the flexors' gain (N m s/rad).
    pub flexor_gain_nm_s_per_rad: Option<f64>,
    /// Overrides the threshold (rad/s).
    pub threshold_rad_s: Option<f64>,
    /// Overrides the delay (s).
    pub delay_s: Option<f64>,
}

/// Which way a spasm pulls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SpasmDirection {
    /// Flexes the joint.
    Flexor,
    /// Extends it.
    Extensor,
    /// Either, with equal odds (random spasms only).
    Either,
}

impl std::fmt::Display for SpasmDirection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Flexor => "flexor",
            Self::Extensor => "extensor",
            Self::Either => "either",
        })
    }
}

/// One spasm at a given time.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpasmEventSettings {
    /// Onset (s).
    pub t_s: f64,
    /// Peak torque (N m, > 0).
    pub amplitude_nm: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// `flexor` or `extensor`.
    pub direction: SpasmDirection,
}

/// `[patient.<joint>.spasms]`: random events, given events, or both.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpasmSettings {
    /// Mean rate of random spasms (per minute); 0 for given events only.
    #[serde(default)]
    pub rate_per_min: f64,
    /// Range of their peak torque `[low, high]` (N m).
    #[serde(deserialize_with = "pma_model::error::exact::array", default)]
    pub amplitude_nm: [f64; 2],
    /// Range of their duration `[low, high]` (s).
    #[serde(
        deserialize_with = "pma_model::error::exact::array",
        default = "default_duration"
    )]
    pub duration_s: [f64; 2],
    /// Their direction (default `either`).
    #[serde(default = "default_direction")]
    pub direction: SpasmDirection,
    /// Fraction of a spasm spent rising (the rest falls).
    #[serde(default = "default_rise")]
    pub rise_fraction: f64,
    /// Seed of the random events.
    #[serde(default)]
    pub seed: u64,
    /// Spasms at given times.
    #[serde(default)]
    pub events: Vec<SpasmEventSettings>,
}

fn default_duration() -> [f64; 2] {
    [0.2, 0.8]
}
fn default_direction() -> SpasmDirection {
    SpasmDirection::Either
}
fn default_rise() -> f64 {
    0.3
}

/// `[patient.<joint>.effort]`: the patient's own push along the gait.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffortSettings {
    /// Fraction of the reference's inverse-dynamics torque: positive assists, negative
    /// resists (-0.3: resists at 30 %).
    pub fraction: f64,
    /// The patient lags the reference by this much (s).
    #[serde(default)]
    pub delay_s: f64,
}

/// Published passive-moment sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StiffnessPreset {
    /// Anderson (1999), the coefficients of Falisse et al. (2019).
    Anderson1999,
}

/// `tau = lower_nm exp(-lower_per_rad (q - lower_angle_rad)) - upper_nm exp(upper_per_rad
/// (q - upper_angle_rad))`: a flexing moment growing below the lower angle and an extending
/// one above the upper angle, about zero in between.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassiveMoment {
    /// Moment at the lower angle (N m).
    pub lower_nm: f64,
    /// Its exponential rate (1/rad).
    pub lower_per_rad: f64,
    /// Lower angle (rad).
    pub lower_angle_rad: f64,
    /// Moment at the upper angle (N m).
    pub upper_nm: f64,
    /// Its exponential rate (1/rad).
    pub upper_per_rad: f64,
    /// Upper angle (rad).
    pub upper_angle_rad: f64,
}

impl StiffnessPreset {
    /// Hip: `k = [-2.44, 5.05, 1.51, -21.88]`, `theta = [-0.6981, 1.81]` rad (flexion
    /// positive in both conventions).
    pub fn hip(self) -> PassiveMoment {
        PassiveMoment {
            lower_nm: 1.51,
            lower_per_rad: 21.88,
            lower_angle_rad: -0.6981,
            upper_nm: 2.44,
            upper_per_rad: 5.05,
            upper_angle_rad: 1.81,
        }
    }

    /// Knee: `k = [-6.09, 33.94, 11.03, -11.33]`, `theta = [-2.4, 0.13]` rad in OpenSim's
    /// convention (knee angle negative in flexion), turned to flexion positive.
    pub fn knee(self) -> PassiveMoment {
        PassiveMoment {
            lower_nm: 6.09,
            lower_per_rad: 33.94,
            lower_angle_rad: -0.13,
            upper_nm: 11.03,
            upper_per_rad: 11.33,
            upper_angle_rad: 2.4,
        }
    }
}

/// `[patient.<joint>.stiffness]`: a preset, any field of which may be overridden.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StiffnessSettings {
    /// `anderson1999` (default when absent: every field must be given).
    pub preset: Option<StiffnessPreset>,
    /// Overrides [`PassiveMoment::lower_nm`].
    pub lower_nm: Option<f64>,
    /// Overrides [`PassiveMoment::lower_per_rad`].
    pub lower_per_rad: Option<f64>,
    /// Overrides [`PassiveMoment::lower_angle_rad`].
    pub lower_angle_rad: Option<f64>,
    /// Overrides [`PassiveMoment::upper_nm`].
    pub upper_nm: Option<f64>,
    /// Overrides [`PassiveMoment::upper_per_rad`].
    pub upper_per_rad: Option<f64>,
    /// Overrides [`PassiveMoment::upper_angle_rad`].
    pub upper_angle_rad: Option<f64>,
}

/// One joint's patient (every part optional).
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointPatientSettings {
    /// Stretch reflex.
    pub spasticity: Option<SpasticitySettings>,
    /// Spasms.
    pub spasms: Option<SpasmSettings>,
    /// Voluntary effort.
    pub effort: Option<EffortSettings>,
    /// Passive stiffness near the range limits.
    pub stiffness: Option<StiffnessSettings>,
}

/// The scenario's `[patient]` section (absent: the passive limb of the URDF).
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatientSettings {
    /// Hip.
    #[serde(default)]
    pub hip: JointPatientSettings,
    /// Knee.
    #[serde(default)]
    pub knee: JointPatientSettings,
    /// A patient who walks: their own gait, tracked by their own muscles.
    #[serde(default)]
    pub active: Option<ActiveSettings>,
}

/// `[patient.active]`: a patient who produces their own joint torques to walk with their
/// own timing and amplitude. They aim at the reference's shape on their own clock, whose
/// stride period is drawn afresh every stride (seeded), scaled by `amplitude`, and track
/// it with their own joint impedance on top of their own torque ([`OwnTorque`]: their
/// limb's inverse dynamics, or walking's joint moments), all times `strength`. The torque
/// goes into the patient's effort (`effort_nm`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ActiveSettings {
    /// Their own mean stride period (s); default: the reference's.
    #[serde(default)]
    pub stride_period_s: Option<f64>,
    /// Stride-to-stride coefficient of variation of their stride period. Default 0.02:
    /// healthy adults' stride time varies by about 2 % (Hausdorff et al. 1996, J Appl
    /// Physiol 80(5)).
    #[serde(default = "default_stride_cv")]
    pub stride_cv: f64,
    /// Scale of their joint excursions against the reference's (default 1).
    #[serde(default = "one")]
    pub amplitude: f64,
    /// Their joint stiffness about their own aim (N m/rad), hip and knee. Default
    /// [60, 30]: an assumption (no measured hip or knee impedance during walking was
    /// found here), stiff enough to walk their own way against the device's frames.
    #[serde(
        deserialize_with = "pma_model::error::exact::array",
        default = "default_patient_stiffness"
    )]
    pub stiffness_nm_per_rad: [f64; 2],
    /// Their joint damping (N m s/rad), hip and knee. Default [3, 1.5].
    #[serde(
        deserialize_with = "pma_model::error::exact::array",
        default = "default_patient_damping"
    )]
    pub damping_nm_s_per_rad: [f64; 2],
    /// Share of a healthy limb's torque they produce (default 1; below 1 a weak limb);
    /// see [`ActiveSettings::strength`].
    #[serde(default)]
    pub strength: Option<f64>,
    /// The share per leg on a two-leg trainer, `[right, left]`, instead of `strength`: a
    /// patient weaker on one side (after a stroke, say).
    #[serde(deserialize_with = "pma_model::error::exact::option", default)]
    pub strength_by_leg: Option<[f64; 2]>,
    /// Seed of their stride-to-stride variation (both legs walk on the one clock it draws).
    #[serde(default)]
    pub seed: u64,
    /// What their own torque, under the impedance, is made of (default `limb`).
    #[serde(default)]
    pub own_torque: OwnTorque,
}

/// The torque an active patient produces along their aim, before their impedance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum OwnTorque {
    /// Their limb's inverse dynamics in the air along the aim: what swinging it takes,
    /// with nothing of a stance's load (the in-air leg's patient).
    #[default]
    Limb,
    /// The adults' mean joint moments in walking (Fukuchi et al. 2018, at the reference's
    /// speed) at their own phase, times their body mass and the share of their weight the
    /// legs carry (`1 - bws_fraction`, as `pma-exo size` scales the moments it compares
    /// with): a patient who carries their stance on a treadmill. Needs a `[treadmill]` and
    /// the adult gait (`gait.data = "fukuchi2018"`).
    Walking,
}

fn default_stride_cv() -> f64 {
    0.02
}
fn one() -> f64 {
    1.0
}
fn default_patient_stiffness() -> [f64; 2] {
    [60.0, 30.0]
}
fn default_patient_damping() -> [f64; 2] {
    [3.0, 1.5]
}

impl ActiveSettings {
    /// The share of a healthy limb's torque they produce: `strength`, or 1.
    pub fn strength(&self) -> f64 {
        self.strength.unwrap_or(1.0)
    }

    pub(crate) fn validate(&self) -> Result<(), LegError> {
        if let (Some(s), Some(_)) = (self.strength, self.strength_by_leg) {
            return Err(LegError::Unsupported {
                name: "patient.active.strength".into(),
                value: pma_model::error::number(s),
                message: "and patient.active.strength_by_leg are both given: strength_by_leg is instead of strength, give one".into(),
            });
        }
        if let Some(t) = self.stride_period_s {
            within(
                "patient.active.stride_period_s",
                t,
                0.5,
                10.0,
                "must be 0.5 to 10 s",
            )?;
        }
        within(
            "patient.active.stride_cv",
            self.stride_cv,
            0.0,
            0.2,
            "must be 0 to 0.2 (healthy adults about 0.02)",
        )?;
        within(
            "patient.active.amplitude",
            self.amplitude,
            0.0,
            1.5,
            "must be 0 to 1.5",
        )?;
        within(
            "patient.active.strength",
            self.strength(),
            0.0,
            2.0,
            "must be 0 to 2",
        )?;
        for (leg, side) in ["right", "left"].iter().enumerate() {
            if let Some(by_leg) = self.strength_by_leg {
                within(
                    format!("patient.active.strength_by_leg[{leg}] ({side})"),
                    by_leg[leg],
                    0.0,
                    2.0,
                    "must be 0 to 2",
                )?;
            }
        }
        for (j, name) in ["hip", "knee"].iter().enumerate() {
            within(
                format!("patient.active.stiffness_nm_per_rad[{j}] ({name})"),
                self.stiffness_nm_per_rad[j],
                0.0,
                2000.0,
                "must be 0 to 2000 N m/rad",
            )?;
            within(
                format!("patient.active.damping_nm_s_per_rad[{j}] ({name})"),
                self.damping_nm_s_per_rad[j],
                0.0,
                200.0,
                "must be 0 to 200 N m s/rad",
            )?;
        }
        Ok(())
    }
}

fn range(name: String, r: [f64; 2], positive_low: bool) -> Result<[f64; 2], LegError> {
    let low_ok = if positive_low {
        r[0] > 0.0
    } else {
        r[0] >= 0.0
    };
    if r.iter().all(|v| v.is_finite()) && low_ok && r[0] <= r[1] {
        Ok(r)
    } else {
        Err(LegError::Range {
            name,
            low: r[0],
            high: r[1],
            expected: if positive_low {
                "must be [low, high] with 0 < low <= high"
            } else {
                "must be [low, high] with 0 <= low <= high"
            },
        })
    }
}

impl SpasticitySettings {
    /// The reflex at `joint` (0 hip, 1 knee), validated; `at` names it in errors.
    pub fn resolve(&self, joint: usize, at: &str) -> Result<Reflex, LegError> {
        let preset = self.preset.unwrap_or(SpasticityPreset::None);
        let base = if joint == 0 {
            preset.hip()
        } else {
            preset.knee()
        };
        let r = Reflex {
            extensor_gain_nm_s_per_rad: self
                .extensor_gain_nm_s_per_rad
                .unwrap_or(base.extensor_gain_nm_s_per_rad),
            flexor_gain_nm_s_per_rad: self
                .flexor_gain_nm_s_per_rad
                .unwrap_or(base.flexor_gain_nm_s_per_rad),
            threshold_rad_s: self.threshold_rad_s.unwrap_or(base.threshold_rad_s),
            delay_s: self.delay_s.unwrap_or(base.delay_s),
        };
        non_negative(
            format!("{at}.extensor_gain_nm_s_per_rad"),
            r.extensor_gain_nm_s_per_rad,
        )?;
        non_negative(
            format!("{at}.flexor_gain_nm_s_per_rad"),
            r.flexor_gain_nm_s_per_rad,
        )?;
        for (field, gain) in [
            ("extensor_gain_nm_s_per_rad", r.extensor_gain_nm_s_per_rad),
            ("flexor_gain_nm_s_per_rad", r.flexor_gain_nm_s_per_rad),
        ] {
            at_most(
                format!("{at}.{field}"),
                gain,
                MAX_REFLEX_GAIN_NM_S_PER_RAD,
                "must be at most 50 N m s/rad (the `severe` preset's is 7)",
            )?;
        }
        // `none` has an infinite threshold: nothing to check unless a gain was given.
        let active = r.extensor_gain_nm_s_per_rad > 0.0 || r.flexor_gain_nm_s_per_rad > 0.0;
        if active {
            non_negative(format!("{at}.threshold_rad_s"), r.threshold_rad_s)?;
        }
        non_negative(format!("{at}.delay_s"), r.delay_s)?;
        if r.delay_s > MAX_DELAY_S {
            return Err(invalid(
                format!("{at}.delay_s"),
                r.delay_s,
                "must be at most 1 s",
            ));
        }
        Ok(r)
    }
}

/// Largest reflex gain accepted (N m s/rad): 7x the `severe` preset's.
pub const MAX_REFLEX_GAIN_NM_S_PER_RAD: f64 = 50.0;
/// Largest torque any part of the patient may produce (N m): above the strongest voluntary
/// hip extension of adults (about 200-300 N m); beyond it the leg is no longer a leg.
pub const MAX_PATIENT_TORQUE_NM: f64 = 300.0;
/// Longest spasm accepted (s).
pub const MAX_SPASM_DURATION_S: f64 = 10.0;

/// `value` no larger than `max`.
fn at_most(name: String, value: f64, max: f64, expected: &'static str) -> Result<(), LegError> {
    if value <= max {
        Ok(())
    } else {
        Err(invalid(name, value, expected))
    }
}

/// Longest reflex or effort delay accepted (s): the buffers are sized from it.
pub const MAX_DELAY_S: f64 = 1.0;
/// Largest exponential rate of a passive moment (1/rad); the stiffest published (knee,
/// 33.94 /rad) is a third of it.
pub const MAX_STIFFNESS_RATE_PER_RAD: f64 = 100.0;
/// Highest random spasm rate (per minute): one a second; every spasm of a run is drawn
/// before it.
pub const MAX_SPASM_RATE_PER_MIN: f64 = 60.0;

impl StiffnessSettings {
    /// The passive moment at `joint`, validated; `at` names it in errors.
    pub fn resolve(&self, joint: usize, at: &str) -> Result<PassiveMoment, LegError> {
        let base = self
            .preset
            .map(|p| if joint == 0 { p.hip() } else { p.knee() });
        let pick = |v: Option<f64>, b: Option<f64>, field: &str| -> Result<f64, LegError> {
            v.or(b).ok_or_else(|| LegError::Missing {
                name: format!("{at}.{field}"),
                hint: "give it or a `preset`",
            })
        };
        let m = PassiveMoment {
            lower_nm: pick(self.lower_nm, base.map(|b| b.lower_nm), "lower_nm")?,
            lower_per_rad: pick(
                self.lower_per_rad,
                base.map(|b| b.lower_per_rad),
                "lower_per_rad",
            )?,
            lower_angle_rad: pick(
                self.lower_angle_rad,
                base.map(|b| b.lower_angle_rad),
                "lower_angle_rad",
            )?,
            upper_nm: pick(self.upper_nm, base.map(|b| b.upper_nm), "upper_nm")?,
            upper_per_rad: pick(
                self.upper_per_rad,
                base.map(|b| b.upper_per_rad),
                "upper_per_rad",
            )?,
            upper_angle_rad: pick(
                self.upper_angle_rad,
                base.map(|b| b.upper_angle_rad),
                "upper_angle_rad",
            )?,
        };
        for (field, nm) in [("lower_nm", m.lower_nm), ("upper_nm", m.upper_nm)] {
            non_negative(format!("{at}.{field}"), nm)?;
            at_most(
                format!("{at}.{field}"),
                nm,
                MAX_PATIENT_TORQUE_NM,
                "must be at most 300 N m",
            )?;
        }
        for (field, rate) in [
            ("lower_per_rad", m.lower_per_rad),
            ("upper_per_rad", m.upper_per_rad),
        ] {
            non_negative(format!("{at}.{field}"), rate)?;
            if rate > MAX_STIFFNESS_RATE_PER_RAD {
                return Err(invalid(
                    format!("{at}.{field}"),
                    rate,
                    "must be at most 100 /rad (the moment would overflow within the joint's range)",
                ));
            }
        }
        finite(format!("{at}.lower_angle_rad"), m.lower_angle_rad)?;
        finite(format!("{at}.upper_angle_rad"), m.upper_angle_rad)?;
        if m.lower_angle_rad >= m.upper_angle_rad {
            return Err(LegError::Range {
                name: format!("{at}.lower_angle_rad, upper_angle_rad"),
                low: m.lower_angle_rad,
                high: m.upper_angle_rad,
                expected: "the lower angle must be below the upper one",
            });
        }
        Ok(m)
    }
}

impl PassiveMoment {
    /// Moment (N m, flexion positive) at `q` (rad).
    pub fn torque(&self, q: f64) -> f64 {
        self.lower_nm * (-self.lower_per_rad * (q - self.lower_angle_rad)).exp()
            - self.upper_nm * (self.upper_per_rad * (q - self.upper_angle_rad)).exp()
    }
}

impl SpasmSettings {
    pub(crate) fn validate(&self, at: &str) -> Result<(), LegError> {
        non_negative(format!("{at}.rate_per_min"), self.rate_per_min)?;
        if self.rate_per_min > MAX_SPASM_RATE_PER_MIN {
            return Err(invalid(
                format!("{at}.rate_per_min"),
                self.rate_per_min,
                "must be at most 60 (one spasm a second)",
            ));
        }
        // Checked even when no random spasm is drawn: a wrong range is a mistake either way.
        range(format!("{at}.amplitude_nm"), self.amplitude_nm, false)?;
        if self.rate_per_min > 0.0 && self.amplitude_nm[1] <= 0.0 {
            return Err(LegError::Missing {
                name: format!("{at}.amplitude_nm"),
                hint: "random spasms need their peak torque range [low, high] in N m",
            });
        }
        at_most(
            format!("{at}.amplitude_nm"),
            self.amplitude_nm[1],
            MAX_PATIENT_TORQUE_NM,
            "must be at most 300 N m (the strongest voluntary hip torque of adults)",
        )?;
        range(format!("{at}.duration_s"), self.duration_s, true)?;
        at_most(
            format!("{at}.duration_s"),
            self.duration_s[1],
            MAX_SPASM_DURATION_S,
            "must be at most 10 s",
        )?;
        if !(self.rise_fraction.is_finite() && self.rise_fraction > 0.0 && self.rise_fraction < 1.0)
        {
            return Err(invalid(
                format!("{at}.rise_fraction"),
                self.rise_fraction,
                "must be between 0 and 1 (exclusive)",
            ));
        }
        for (i, e) in self.events.iter().enumerate() {
            let at = format!("{at}.events[{i}]");
            non_negative(format!("{at}.t_s"), e.t_s)?;
            non_negative(format!("{at}.amplitude_nm"), e.amplitude_nm)?;
            at_most(
                format!("{at}.amplitude_nm"),
                e.amplitude_nm,
                MAX_PATIENT_TORQUE_NM,
                "must be at most 300 N m (the strongest voluntary hip torque of adults)",
            )?;
            positive(format!("{at}.duration_s"), e.duration_s)?;
            at_most(
                format!("{at}.duration_s"),
                e.duration_s,
                MAX_SPASM_DURATION_S,
                "must be at most 10 s",
            )?;
            if e.direction == SpasmDirection::Either {
                return Err(LegError::Missing {
                    name: format!("{at}.direction"),
                    hint: "a given spasm is `flexor` or `extensor`",
                });
            }
        }
        Ok(())
    }
}

impl EffortSettings {
    pub(crate) fn validate(&self, at: &str) -> Result<(), LegError> {
        finite(format!("{at}.fraction"), self.fraction)?;
        if self.fraction.abs() > 1.0 {
            return Err(invalid(
                format!("{at}.fraction"),
                self.fraction,
                "must be -1 to 1 (a patient resists or assists with at most the whole of the gait's own joint torque)",
            ));
        }
        non_negative(format!("{at}.delay_s"), self.delay_s)?;
        if self.delay_s > MAX_DELAY_S {
            return Err(invalid(
                format!("{at}.delay_s"),
                self.delay_s,
                "must be at most 1 s",
            ));
        }
        Ok(())
    }
}

impl PatientSettings {
    /// The settings of leg `leg` of a trainer: the same patient, its random spasms drawn
    /// from each seed plus `leg` (so that two legs do not jerk together), its walking on
    /// one clock (the same stride draws for both legs: a person's legs keep their half
    /// stride apart, where independent draws let them drift out of step).
    pub fn for_leg(&self, leg: usize) -> Self {
        let mut out = self.clone();
        for j in [&mut out.hip, &mut out.knee] {
            if let Some(s) = &mut j.spasms {
                s.seed = s.seed.wrapping_add(leg as u64);
            }
        }
        if let Some(a) = &mut out.active {
            if let Some(by_leg) = a.strength_by_leg.take() {
                a.strength = Some(by_leg[leg.min(1)]);
            }
        }
        out
    }

    /// Whether no part is set at either joint (the passive limb).
    pub fn is_passive(&self) -> bool {
        self.active.is_none()
            && self.joints().iter().all(|j| {
                j.spasticity.is_none()
                    && j.spasms.is_none()
                    && j.effort.is_none()
                    && j.stiffness.is_none()
            })
    }

    pub(super) fn joints(&self) -> [&JointPatientSettings; 2] {
        [&self.hip, &self.knee]
    }

    /// Range checks, each error naming its field (`patient.knee.spasms.rate_per_min`).
    pub fn validate(&self) -> Result<(), LegError> {
        if let Some(a) = &self.active {
            a.validate()?;
        }
        for (j, (name, s)) in ["hip", "knee"].iter().zip(self.joints()).enumerate() {
            let at = format!("patient.{name}");
            if let Some(sp) = &s.spasticity {
                sp.resolve(j, &format!("{at}.spasticity"))?;
            }
            if let Some(sp) = &s.spasms {
                sp.validate(&format!("{at}.spasms"))?;
            }
            if let Some(e) = &s.effort {
                e.validate(&format!("{at}.effort"))?;
            }
            if let Some(st) = &s.stiffness {
                st.resolve(j, &format!("{at}.stiffness"))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Random spasms at `rate_per_min`, 10-30 N m, 0.2-0.8 s, either direction.
    pub(in crate::patient) fn spasms(rate_per_min: f64, seed: u64) -> SpasmSettings {
        SpasmSettings {
            rate_per_min,
            amplitude_nm: [10.0, 30.0],
            duration_s: [0.2, 0.8],
            direction: SpasmDirection::Either,
            rise_fraction: 0.3,
            seed,
            events: Vec::new(),
        }
    }

    #[test]
    fn a_patient_weaker_on_one_side_gives_each_leg_its_strength() {
        let text = "[active]\nstrength_by_leg = [1.0, 0.4]\nseed = 3\n";
        let p: PatientSettings = toml::from_str(text).unwrap();
        p.validate().unwrap();
        let [right, left] = [0, 1].map(|leg| p.for_leg(leg).active.unwrap());
        assert_eq!((right.strength(), left.strength()), (1.0, 0.4));
        // Regression (issue 28): each leg drew its own strides (seed plus its index), so a
        // person's two legs drifted out of step; they share one clock.
        assert_eq!((right.seed, left.seed), (3, 3));
        let bad: PatientSettings =
            toml::from_str("[active]\nstrength_by_leg = [1.0, -0.5]\n").unwrap();
        let e = bad.validate().unwrap_err().to_string();
        assert!(
            e.contains("patient.active.strength_by_leg[1] (left)"),
            "{e}"
        );
    }

    #[test]
    fn regression_an_inverted_range_was_accepted_when_no_random_spasm_is_drawn() {
        // Only given events, rate 0: the ranges were not checked, so a typo passed silently.
        let mut s = spasms(0.0, 1);
        s.amplitude_nm = [30.0, 10.0];
        let e = s.validate("patient.knee.spasms").unwrap_err().to_string();
        assert!(e.contains("patient.knee.spasms.amplitude_nm"), "{e}");
        let mut s = spasms(0.0, 1);
        s.duration_s = [0.8, 0.2];
        let e = s.validate("patient.knee.spasms").unwrap_err().to_string();
        assert!(e.contains("patient.knee.spasms.duration_s"), "{e}");
        assert!(spasms(0.0, 1).validate("patient.knee.spasms").is_ok());
    }

    #[test]
    fn passive_moment_is_small_in_mid_range_and_pushes_back_beyond_the_ends() {
        let knee = StiffnessPreset::Anderson1999.knee();
        assert!(knee.torque(0.8).abs() < 0.01, "{}", knee.torque(0.8));
        assert!(
            knee.torque(-0.2) > 5.0,
            "hyperextended: {}",
            knee.torque(-0.2)
        );
        assert!(
            knee.torque(2.5) < -11.0,
            "deep flexion: {}",
            knee.torque(2.5)
        );
        let hip = StiffnessPreset::Anderson1999.hip();
        assert!((hip.torque(-0.6981) - 1.51).abs() < 0.01);
        assert!((hip.torque(1.81) + 2.44).abs() < 1e-6 + 1.51 * (-21.88f64 * 2.5081).exp());
    }

    #[test]
    fn presets_grow_in_gain_and_fall_in_threshold_with_severity() {
        let p = [
            SpasticityPreset::Mild,
            SpasticityPreset::Moderate,
            SpasticityPreset::Severe,
        ];
        for w in p.windows(2) {
            let (a, b) = (w[0].knee(), w[1].knee());
            assert!(b.extensor_gain_nm_s_per_rad > a.extensor_gain_nm_s_per_rad);
            assert!(b.threshold_rad_s < a.threshold_rad_s);
        }
        let r = SpasticityPreset::Moderate.hip();
        assert!(
            r.flexor_gain_nm_s_per_rad > SpasticityPreset::Moderate.knee().flexor_gain_nm_s_per_rad
        );
    }
}
