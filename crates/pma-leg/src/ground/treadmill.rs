use crate::base::{invalid, LegError};
use crate::ground::ContactParams;
use pma_model::error::within;
use serde::Deserialize;

/// How the harness holds the pelvis up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum BwsKind {
    /// A constant upward force (an actively controlled unloading system, as the Lokomat's
    /// Lokolift or a cable robot).
    #[default]
    ConstantForce,
    /// A spring (a counterweight-free harness), giving the support force at the standing
    /// pelvis height and `bws_spring_n_per_m` per metre of sinking.
    Spring,
}

/// What holds the pelvis up besides the harness while a one-leg trainer's leg swings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Contralateral {
    /// A virtual other leg: the reference half a stride later, rigid (its ankle at
    /// neutral), with this foot's spheres and contact, pushing the pelvis up wherever its
    /// foot reaches the belt. It stands in for the other leg where one leg is enough (a
    /// cheaper run, the one-leg rig's muscles); it is a vertical force only and lands
    /// hard (docs/treadmill.md).
    #[default]
    Reference,
    /// Nothing: the harness and the simulated feet alone (a two-leg trainer, or physics
    /// checks of one leg).
    None,
}

/// Fastest belt a scenario may ask for (m/s): gait trainers' belts run up to about 3.2
/// km/h (Lokomat), treadmills for gait research to a few metres per second.
pub const BELT_SPEED_MAX_M_S: f64 = 3.0;

/// The passive ankle: an ankle-foot orthosis (or a trainer's foot lifter) as a rotational
/// spring and damper about a rest angle, within its stops (the scenario's
/// `[treadmill.ankle]`; defaults and their sources: docs/treadmill.md).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AnkleSettings {
    /// Rotational stiffness about the rest angle (N m/rad).
    pub stiffness_nm_per_rad: f64,
    /// Rotational damping (N m s/rad).
    pub damping_nm_s_per_rad: f64,
    /// Rest angle (deg, dorsiflexion positive).
    pub rest_deg: f64,
    /// Stops `[plantarflexion, dorsiflexion]` (deg, dorsiflexion positive).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub range_deg: [f64; 2],
}

impl Default for AnkleSettings {
    fn default() -> Self {
        Self {
            stiffness_nm_per_rad: ANKLE_STIFFNESS_NM_PER_RAD,
            damping_nm_s_per_rad: ANKLE_DAMPING_NM_S_PER_RAD,
            rest_deg: ANKLE_REST_DEG,
            range_deg: ANKLE_RANGE_DEG,
        }
    }
}

/// Default orthosis stiffness (N m/rad): the middle of 13 commercial carbon-composite
/// ankle-foot orthoses, 0.58-3.66 N m/deg (33-210 N m/rad; Shuman & Russell Esposito 2021,
/// J Biomech Eng 144(1):011004, abstract).
pub const ANKLE_STIFFNESS_NM_PER_RAD: f64 = 100.0;

/// Default orthosis damping (N m s/rad): no measured value was found; 1.0 damps the
/// unloaded foot at about half of critical.
pub const ANKLE_DAMPING_NM_S_PER_RAD: f64 = 1.0;

/// Default rest angle (deg): 5 deg of dorsiflexion, the orthosis as a foot lifter. In
/// swing the adult reference's ankle is at +3..+7 deg (Fukuchi et al. 2018); at neutral
/// the toes of the compliant foot scuff the belt at 82-88 % of the cycle (docs/treadmill.md).
pub const ANKLE_REST_DEG: f64 = 5.0;

/// Default stops (deg): the adult reference's ankle spans -3..+14 deg at 0.5 m/s, children's
/// at slow speed -14..+14 (Schwartz et al. 2008).
pub const ANKLE_RANGE_DEG: [f64; 2] = [-15.0, 15.0];

impl AnkleSettings {
    pub(crate) fn validate(&self) -> Result<(), LegError> {
        within(
            "treadmill.ankle.stiffness_nm_per_rad",
            self.stiffness_nm_per_rad,
            0.0,
            2000.0,
            "must be 0 to 2000 N m/rad (a free hinge to a stiff orthosis)",
        )?;
        within(
            "treadmill.ankle.damping_nm_s_per_rad",
            self.damping_nm_s_per_rad,
            0.0,
            20.0,
            "must be 0 to 20 N m s/rad",
        )?;
        let [lo, hi] = self.range_deg;
        if !(lo.is_finite()
            && hi.is_finite()
            && (-45.0..0.0).contains(&lo)
            && hi > 0.0
            && hi <= 40.0)
        {
            return Err(LegError::Range {
                name: "treadmill.ankle.range_deg".into(),
                low: lo,
                high: hi,
                expected: "needs -45 <= plantarflexion < 0 < dorsiflexion <= 40 deg (the ankle's anatomical range)",
            });
        }
        if !(self.rest_deg >= lo && self.rest_deg <= hi) {
            return Err(invalid(
                "treadmill.ankle.rest_deg",
                self.rest_deg,
                "must lie within treadmill.ankle.range_deg",
            ));
        }
        Ok(())
    }

    /// The orthosis's torque (N m, dorsiflexion positive) at `angle_rad`, turning at
    /// `rate_rad_s`.
    pub fn torque_nm(&self, angle_rad: f64, rate_rad_s: f64) -> f64 {
        -self.stiffness_nm_per_rad * (angle_rad - self.rest_deg.to_radians())
            - self.damping_nm_s_per_rad * rate_rad_s
    }
}

/// The `[treadmill]` section of a scenario.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreadmillSettings {
    /// Legs on the belt: 1 (with a virtual other leg, or none) or 2 (a bilateral trainer,
    /// the second leg half a stride later). Default 1.
    #[serde(default = "one_leg")]
    pub legs: usize,
    /// Belt speed (m/s, the belt's surface moves backwards); absent: the reference's own,
    /// the mean backward speed of its foot's contact point over its stance (see
    /// [`reference_belt_speed`]).
    #[serde(default)]
    pub speed_m_per_s: Option<f64>,
    /// Fraction of the body weight (patient and exoskeleton) the harness carries, 0-1.
    pub bws_fraction: f64,
    /// The patient's body mass (kg): everything above the hips (and a missing leg) rides
    /// on the pelvis.
    pub body_mass_kg: f64,
    /// The patient's height (m; default the trainer URDF's patient, 1.75 m): the frame's
    /// thigh and shank, the patient's segments and the feet take their lengths from it
    /// (Winter's proportions), as a trainer's orthosis is adjusted to the patient.
    #[serde(default)]
    pub height_m: Option<f64>,
    /// The support at the start (0-1, at least `bws_fraction`; default: `bws_fraction`):
    /// the harness carries it until `bws_release_s[0]` and lowers it to `bws_fraction` by
    /// `bws_release_s[1]` (the gait's quintic), as a therapist lowers the unloading once
    /// the patient walks. The start-up drags the standing feet on the belt until the
    /// stance matches it (docs/treadmill.md), which unsupported legs may not survive.
    #[serde(default)]
    pub bws_start_fraction: Option<f64>,
    /// When the start's support is lowered, `[from, to]` (s from the start). Default [0, 0].
    #[serde(deserialize_with = "pma_model::error::exact::array", default)]
    pub bws_release_s: [f64; 2],
    /// Constant force (default) or spring.
    #[serde(default)]
    pub bws: BwsKind,
    /// Stiffness of a spring harness (N/m).
    #[serde(default)]
    pub bws_spring_n_per_m: f64,
    /// The feet's contact.
    #[serde(default)]
    pub contact: ContactParams,
    /// The passive ankles' orthosis.
    #[serde(default)]
    pub ankle: AnkleSettings,
    /// The other leg of a one-leg trainer (default: the virtual one; a two-leg trainer has
    /// its own and takes `none` or nothing).
    #[serde(default)]
    pub contralateral: Option<Contralateral>,
    /// Stiffness of the harness's hold on the pelvis fore-aft (N/m), if the URDF lets the
    /// pelvis slide fore-aft (`pelvis_x`). Default 200: the pelvis is nearly free fore-aft
    /// (as LOPES's in its zero-force mode), so the stance legs carry the body over the feet
    /// and the body's speed swings as it does in walking; the spring only keeps it from
    /// drifting. A stiff hold (the Lokomat holds the pelvis) keeps whatever offset the
    /// start leaves, held by the feet's static friction: docs/treadmill.md.
    #[serde(default = "default_fore_aft_stiffness")]
    pub pelvis_fore_aft_n_per_m: f64,
    /// Damping of that hold (N s/m). Default 200.
    #[serde(default = "default_fore_aft_damping")]
    pub pelvis_fore_aft_damping_n_s_per_m: f64,
    /// Until when (s from the start) the harness holds the pelvis firmly fore-aft at its
    /// start ([`START_HOLD_N_PER_M`]), so that the start-up, whose stance does not yet match
    /// the belt, does not throw it onto its stop. Default 0: no hold.
    #[serde(default)]
    pub pelvis_held_until_s: f64,
    /// A self-paced belt (1/s; default 0, a belt at constant speed): after the start-up
    /// the belt's speed changes by this gain times how far the pelvis's stride-mean
    /// position (low-passed over [`SELF_PACED_FILTER_S`]) lies ahead of its start, so that
    /// a pelvis free fore-aft stays over the belt without resting on a stop, as a
    /// self-paced treadmill keeps its walker in place (Sloot et al. 2014) and the Lokomat
    /// synchronises its belt to the orthosis.
    #[serde(default)]
    pub self_paced_gain_per_s: f64,
}

impl TreadmillSettings {
    /// The share of the body weight the harness carries `t_s` after the start:
    /// `bws_fraction`, or more while the start's support is lowered.
    pub fn support_fraction_at(&self, t_s: f64) -> f64 {
        let Some(start) = self.bws_start_fraction else {
            return self.bws_fraction;
        };
        let [from, to] = self.bws_release_s;
        let released = if t_s >= to {
            1.0
        } else if t_s <= from {
            0.0
        } else {
            pma_control::quintic_blend((t_s - from) / (to - from), to - from).0
        };
        start + (self.bws_fraction - start) * released
    }

    /// The share of the body weight the legs carry at `t_s` over the share they carry at
    /// the walking support `bws_fraction`: 1 (exactly) but while a start's support is
    /// lowered; 1 if they carry nothing then.
    pub fn legs_share_at(&self, t_s: f64) -> f64 {
        let walking = 1.0 - self.bws_fraction;
        if walking > 0.0 {
            (1.0 - self.support_fraction_at(t_s)) / walking
        } else {
            1.0
        }
    }

    /// A release window without a start's support, or a start's support without a
    /// window, would be ignored at run time: both are refused.
    fn validate_release_pairing(&self) -> Result<(), LegError> {
        let [_, to] = self.bws_release_s;
        let has_window = to > 0.0;
        match self.bws_start_fraction {
            None if has_window => Err(invalid(
                "treadmill.bws_release_s",
                to,
                "needs treadmill.bws_start_fraction (the support it lowers); without one, leave bws_release_s out",
            )),
            Some(start) if !has_window && start != self.bws_fraction => Err(invalid(
                "treadmill.bws_start_fraction",
                start,
                "needs treadmill.bws_release_s = [from, to] with to > 0 s (when the start's support is lowered)",
            )),
            _ => Ok(()),
        }
    }
}

/// Low-pass of the pelvis position a self-paced belt follows (s): a stride or so, so that
/// the belt does not follow the body's swing within a stride.
pub const SELF_PACED_FILTER_S: f64 = 1.0;

/// Stiffness of the start-up's fore-aft hold (N/m) and its damping (N s/m): a pelvis
/// held within millimetres against the start-up's hundreds of newtons.
pub const START_HOLD_N_PER_M: (f64, f64) = (2.0e4, 2.0e3);

fn one_leg() -> usize {
    1
}

fn default_fore_aft_stiffness() -> f64 {
    200.0
}

fn default_fore_aft_damping() -> f64 {
    200.0
}

/// The heights the trainer's frame adjusts to (m): those of the 42 adults whose walking is
/// the reference (Fukuchi et al. 2018's `WBDSinfo.xlsx`, 147.0 to 192.0 cm; a copy is
/// nikorose87/DJS-GA `Fukuchi/meta_info_Fukuchi.csv`). Its angles are theirs, and Winter's
/// segment proportions, which scale the legs, are adults'.
pub const PATIENT_HEIGHT_RANGE_M: (f64, f64) = (1.47, 1.92);

/// Plausible patients' masses (kg): a small child to a heavy adult (gait trainers are
/// rated up to 135-150 kg).
pub const BODY_MASS_RANGE_KG: (f64, f64) = (15.0, 200.0);

impl TreadmillSettings {
    /// A one-leg treadmill carrying `bws_fraction` of a patient of `body_mass_kg`, every
    /// other field at its default: the belt at the reference's speed, a constant-force
    /// harness, the other leg the reference's.
    pub fn new(bws_fraction: f64, body_mass_kg: f64) -> Self {
        Self {
            legs: 1,
            speed_m_per_s: None,
            bws_fraction,
            body_mass_kg,
            height_m: None,
            bws_start_fraction: None,
            bws_release_s: [0.0, 0.0],
            bws: BwsKind::default(),
            bws_spring_n_per_m: 0.0,
            contact: ContactParams::default(),
            ankle: AnkleSettings::default(),
            contralateral: None,
            pelvis_fore_aft_n_per_m: default_fore_aft_stiffness(),
            pelvis_fore_aft_damping_n_s_per_m: default_fore_aft_damping(),
            pelvis_held_until_s: 0.0,
            self_paced_gain_per_s: 0.0,
        }
    }

    /// The belt speed (m/s; 0 if not resolved yet).
    pub fn belt_speed_m_s(&self) -> f64 {
        self.speed_m_per_s.unwrap_or(0.0)
    }

    /// What stands in for the other leg: the virtual one (a one-leg trainer's default) or
    /// nothing.
    pub fn other_leg(&self) -> Contralateral {
        match (self.legs, self.contralateral) {
            (_, Some(c)) => c,
            (1, None) => Contralateral::Reference,
            (_, None) => Contralateral::None,
        }
    }

    /// Checks every field against a plausible range; the error names it.
    pub fn validate(&self) -> Result<(), LegError> {
        if !(1..=crate::base::MAX_LEGS).contains(&self.legs) {
            return Err(invalid(
                "treadmill.legs",
                self.legs as f64,
                "must be 1 (one leg, a virtual other) or 2 (both legs)",
            ));
        }
        if self.legs == 2 && self.contralateral == Some(Contralateral::Reference) {
            return Err(LegError::Unsupported {
                name: "treadmill.contralateral".into(),
                value: "\"reference\"".into(),
                message: "a two-leg trainer (treadmill.legs = 2) has its other leg: `reference` is for one leg (use `none` or leave it out)".into(),
            });
        }
        if let Some(v) = self.speed_m_per_s {
            within(
                "treadmill.speed_m_per_s",
                v,
                0.0,
                BELT_SPEED_MAX_M_S,
                "a gait trainer's belt, 0 to 3 m/s",
            )?;
        }
        within(
            "treadmill.bws_fraction",
            self.bws_fraction,
            0.0,
            1.0,
            "a fraction of the body weight, 0 to 1",
        )?;
        if let Some(start) = self.bws_start_fraction {
            within(
                "treadmill.bws_start_fraction",
                start,
                self.bws_fraction,
                1.0,
                "the start's support, from bws_fraction to 1",
            )?;
        }
        let [from, to] = self.bws_release_s;
        if !(from.is_finite() && to.is_finite() && 0.0 <= from && from <= to && to <= 60.0) {
            return Err(LegError::Unsupported {
                name: "treadmill.bws_release_s".into(),
                value: format!(
                    "[{}, {}]",
                    pma_model::error::number(from),
                    pma_model::error::number(to)
                ),
                message: "must be [from, to] with 0 <= from <= to <= 60 s".into(),
            });
        }
        self.validate_release_pairing()?;
        within(
            "treadmill.body_mass_kg",
            self.body_mass_kg,
            BODY_MASS_RANGE_KG.0,
            BODY_MASS_RANGE_KG.1,
            "a patient's mass, 15 to 200 kg",
        )?;
        if let Some(h) = self.height_m {
            within(
                "treadmill.height_m",
                h,
                PATIENT_HEIGHT_RANGE_M.0,
                PATIENT_HEIGHT_RANGE_M.1,
                "the adult reference's subjects' heights, 1.47 to 1.92 m (Fukuchi et al. 2018): the reference's angles are theirs",
            )?;
        }
        if self.bws == BwsKind::Spring {
            within(
                "treadmill.bws_spring_n_per_m",
                self.bws_spring_n_per_m,
                1.0,
                1e6,
                "a harness spring, 1 to 1e6 N/m (stiffer is a fixed pelvis)",
            )?;
        }
        within(
            "treadmill.pelvis_fore_aft_n_per_m",
            self.pelvis_fore_aft_n_per_m,
            0.0,
            1e6,
            "must be 0 to 1e6 N/m",
        )?;
        within(
            "treadmill.pelvis_fore_aft_damping_n_s_per_m",
            self.pelvis_fore_aft_damping_n_s_per_m,
            0.0,
            1e5,
            "must be 0 to 1e5 N s/m",
        )?;
        within(
            "treadmill.pelvis_held_until_s",
            self.pelvis_held_until_s,
            0.0,
            60.0,
            "must be 0 to 60 s",
        )?;
        within(
            "treadmill.self_paced_gain_per_s",
            self.self_paced_gain_per_s,
            0.0,
            5.0,
            "must be 0 to 5 per second (0: a belt at constant speed)",
        )?;
        self.contact.validate()?;
        self.ankle.validate()
    }
}
