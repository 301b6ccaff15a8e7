//! The treadmill: a compliant foot on a moving belt and the pelvis on body-weight support.
//!
//! rapier's contacts are rigid and inelastic (a heel strike is a one-step impulse, and
//! contact softness is global), so the foot's contacts are computed here instead, as
//! Hunt-Crossley spheres against the belt plane, the normal force of OpenSim's
//! `SmoothSphereHalfSpaceForce` (Serrancoli, Falisse et al. 2019, IEEE TNSRE 27(1); used by
//! Falisse et al. 2019, J R Soc Interface 16:20190402, for predictive gait):
//! `F_n = K d^{3/2} (1 + 3/2 c d')` with `K = (4/3) k^{3/2} sqrt(r)`, `k = E^{2/3} / 2`.
//!
//! Friction is elasto-plastic: while a sphere sticks, the belt shears it like a spring of
//! Mindlin's tangential stiffness of a Hertzian contact, `k_t = 2 (1 - nu) / (2 - nu) dF_n/dd`
//! (Mindlin 1949, J Appl Mech 16:259; Johnson 1985, Contact Mechanics, Sec. 7.2; `nu = 0.5`
//! for a rubber sole gives `k_t = K sqrt(d)`), damped as the normal direction is; once that
//! force would exceed `(mu + mu_v |v|) F_n` the sphere slides at that force against the slip
//! `v`. OpenSim's smooth Coulomb law `mu F_n min(v/v_t, 1)` was tried first: at the leg's
//! 0.5 ms substeps its slope `mu F_n / v_t` chattered on a loaded heel (the friction
//! alternating between about +800 and -800 N from one substep to the next, the slip at
//! 0.15 m/s where the foot was not moving), and a wider `v_t` lets a stance foot creep.
//! A belt moving backwards at `speed` is the plane's velocity in the slip: no moving body
//! is needed. The forces go on the foot at the contact points, so the loading rate at heel
//! strike comes from the model, not from the solver's regularisation.
use crate::error::{invalid, LegError};
use crate::legs::PerLeg;
use pma_model::error::within;
use rapier3d::prelude::{Real, RigidBodyHandle, RigidBodySet, Vector};
use serde::Deserialize;

/// The compliant contact of one foot sphere with the belt.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Hertz stiffness `E` of OpenSim's smooth sphere model (N/m^2). Default 2.0e6: SCONE's
    /// two-sphere H0918 foot (opensim-org/SCONE, `scenarios/Examples/data/H0918.hfd`,
    /// stiffness 5975.21 in Hyfydy's units) converted to OpenSim's (Hyfydy user manual).
    pub stiffness_n_per_m2: f64,
    /// Hunt-Crossley dissipation `c` (s/m). Default 1.0 (H0918's damping).
    pub dissipation_s_per_m: f64,
    /// Coulomb friction coefficient of shoe on belt. Default 0.8: no measured value was
    /// found; gait models use 0.7-0.9 (Falisse et al. 2019: 0.8), and level walking needs
    /// only about 0.2 (Redfern et al. 2001, Ergonomics 44:1138).
    pub friction: f64,
    /// Viscous friction `mu_v` (s/m) while sliding. Default 0.5 (Falisse et al. 2019).
    pub viscous_friction_s_per_m: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m2: 2.0e6,
            dissipation_s_per_m: 1.0,
            friction: 0.8,
            viscous_friction_s_per_m: 0.5,
        }
    }
}

impl ContactParams {
    fn validate(&self) -> Result<(), LegError> {
        within(
            "treadmill.contact.stiffness_n_per_m2",
            self.stiffness_n_per_m2,
            1e4,
            1e9,
            "must be 1e4..=1e9 N/m^2 (from a soft pad to a hard sole; gait models use 1e6-2e6)",
        )?;
        within(
            "treadmill.contact.dissipation_s_per_m",
            self.dissipation_s_per_m,
            0.0,
            10.0,
            "must be 0..=10 s/m (Hunt-Crossley; gait models use 1-2)",
        )?;
        within(
            "treadmill.contact.friction",
            self.friction,
            0.0,
            2.0,
            "must be 0..=2 (shoe on belt: models use 0.7-0.9)",
        )?;
        within(
            "treadmill.contact.viscous_friction_s_per_m",
            self.viscous_friction_s_per_m,
            0.0,
            10.0,
            "must be 0..=10 s/m (gait models use 0.5)",
        )?;
        Ok(())
    }

    /// `K` of `F_n = K d^{3/2}` for a sphere of `radius_m` (N/m^{3/2}).
    pub fn hertz_coefficient(&self, radius_m: f64) -> f64 {
        let k = 0.5 * self.stiffness_n_per_m2.powf(2.0 / 3.0);
        4.0 / 3.0 * k * (radius_m * k).sqrt()
    }

    /// Normal force (N, pushing the foot up) at penetration `depth_m` growing at
    /// `depth_rate_m_s`: zero out of contact, never pulling.
    pub fn normal_force(&self, radius_m: f64, depth_m: f64, depth_rate_m_s: f64) -> f64 {
        if depth_m <= 0.0 {
            return 0.0;
        }
        let hertz = self.hertz_coefficient(radius_m) * depth_m.powf(1.5);
        (hertz * (1.0 + 1.5 * self.dissipation_s_per_m * depth_rate_m_s)).max(0.0)
    }

    /// Largest friction (N) under `normal_n` at a slip of `slip_m_s`: a sliding sphere's.
    pub fn friction_limit(&self, normal_n: f64, slip_m_s: f64) -> f64 {
        normal_n * (self.friction + self.viscous_friction_s_per_m * slip_m_s.abs())
    }

    /// Tangential stiffness (N/m) of a sphere of `radius_m` at penetration `depth_m`:
    /// Mindlin's `2 (1 - nu) / (2 - nu)` of the normal stiffness `3/2 K d^{1/2}`, `nu = 0.5`.
    pub fn tangential_stiffness(&self, radius_m: f64, depth_m: f64) -> f64 {
        self.hertz_coefficient(radius_m) * depth_m.max(0.0).sqrt()
    }
}

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
    fn validate(&self) -> Result<(), LegError> {
        within(
            "treadmill.ankle.stiffness_nm_per_rad",
            self.stiffness_nm_per_rad,
            0.0,
            2000.0,
            "must be 0..=2000 N m/rad (a free hinge to a stiff orthosis)",
        )?;
        within(
            "treadmill.ankle.damping_nm_s_per_rad",
            self.damping_nm_s_per_rad,
            0.0,
            20.0,
            "must be 0..=20 N m s/rad",
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
        if !(1..=crate::legs::MAX_LEGS).contains(&self.legs) {
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
                "a gait trainer's belt, 0..=3 m/s",
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
            "a patient's mass, 15..=200 kg",
        )?;
        if self.bws == BwsKind::Spring {
            within(
                "treadmill.bws_spring_n_per_m",
                self.bws_spring_n_per_m,
                1.0,
                1e6,
                "a harness spring, 1..=1e6 N/m (stiffer is a fixed pelvis)",
            )?;
        }
        within(
            "treadmill.pelvis_fore_aft_n_per_m",
            self.pelvis_fore_aft_n_per_m,
            0.0,
            1e6,
            "must be 0..=1e6 N/m",
        )?;
        within(
            "treadmill.pelvis_fore_aft_damping_n_s_per_m",
            self.pelvis_fore_aft_damping_n_s_per_m,
            0.0,
            1e5,
            "must be 0..=1e5 N s/m",
        )?;
        within(
            "treadmill.pelvis_held_until_s",
            self.pelvis_held_until_s,
            0.0,
            60.0,
            "must be 0..=60 s",
        )?;
        within(
            "treadmill.self_paced_gain_per_s",
            self.self_paced_gain_per_s,
            0.0,
            5.0,
            "must be 0..=5 per second (0: a belt at constant speed)",
        )?;
        self.contact.validate()?;
        self.ankle.validate()
    }
}

/// Step of the joint angles of [`SagittalChain`]'s Jacobians (rad).
const JACOBIAN_STEP_RAD: f64 = 1e-6;

/// One contact sphere on a foot, in the foot's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootSphere {
    /// Centre in the foot link's frame (m).
    pub center_m: [f64; 3],
    /// Radius (m).
    pub radius_m: f64,
}

/// What the belt did to one foot during one period (averaged over its substeps).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FootReaction {
    /// Vertical ground reaction force (N).
    pub vertical_n: f64,
    /// Horizontal (fore-aft) ground reaction force (N, forward positive).
    pub fore_aft_n: f64,
    /// Deepest penetration of a sphere into the belt (m; 0 out of contact).
    pub penetration_m: f64,
    /// Largest slip speed of a loaded sphere against the belt (m/s).
    pub slip_m_s: f64,
    /// The foot's fore-aft speed against the belt where it touches (m/s, forward
    /// positive): its loaded spheres' material contact points, weighted by their normal
    /// forces over the period; 0 out of contact.
    pub fore_aft_slip_m_s: f64,
    /// Spheres in contact at the end of the period.
    pub contacts: usize,
}

/// What the belt, the harness and a virtual other leg did during one period (averaged
/// over its substeps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundReaction {
    /// Each simulated foot's.
    pub feet: PerLeg<FootReaction>,
    /// Vertical force of the virtual other leg on the pelvis (N; 0 without one).
    pub contralateral_n: f64,
    /// The harness's upward force on the pelvis (N).
    pub support_n: f64,
    /// The harness's fore-aft force on the pelvis (N, forward positive).
    pub harness_fore_aft_n: f64,
    /// The belt's speed (m/s): a self-paced belt's changes.
    pub belt_speed_m_s: f64,
}

impl Default for GroundReaction {
    fn default() -> Self {
        Self {
            feet: PerLeg::one(FootReaction::default()),
            contralateral_n: 0.0,
            support_n: 0.0,
            harness_fore_aft_n: 0.0,
            belt_speed_m_s: 0.0,
        }
    }
}

impl GroundReaction {
    /// Vertical force the belt carries: every foot's and the virtual other leg's (N).
    pub fn belt_load_n(&self) -> f64 {
        self.feet.iter().map(|f| f.vertical_n).sum::<f64>() + self.contralateral_n
    }
}

/// One sphere's contact with the belt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereContact {
    /// Force on the foot (N, world frame).
    pub force_n: [f64; 3],
    /// Where it acts: the sphere's lowest point (m).
    pub point_m: [f64; 3],
    /// Penetration into the belt (m).
    pub depth_m: f64,
    /// Slip speed against the belt (m/s).
    pub slip_m_s: f64,
}

/// One sphere's contact over a substep of `h_s`, from the sphere centre `c` (m) and the
/// velocity `v` (m/s) of the foot's material point at the contact: the belt is the plane
/// `z = 0` moving at `-belt_speed_m_s` along X. `stick_m` is how far the belt has sheared
/// the sphere while it sticks (m, X and Y; updated, zero out of contact). `None` out of
/// contact.
pub fn sphere_contact(
    params: &ContactParams,
    radius_m: f64,
    c: [f64; 3],
    v: [f64; 3],
    belt_speed_m_s: f64,
    (stick_m, h_s): (&mut [f64; 2], f64),
) -> Option<SphereContact> {
    let depth = radius_m - c[2];
    if depth <= 0.0 {
        *stick_m = [0.0; 2];
        return None;
    }
    let point = [c[0], c[1], c[2] - radius_m];
    let normal = params.normal_force(radius_m, depth, -v[2]);
    let slip = [v[0] + belt_speed_m_s, v[1]];
    let speed = slip[0].hypot(slip[1]);
    // Sticking: a spring sheared by the slip, damped as Hunt-Crossley damps the normal
    // direction (3/2 c times the elastic force per unit of rate).
    let k_t = params.tangential_stiffness(radius_m, depth);
    let c_t =
        1.5 * params.dissipation_s_per_m * params.hertz_coefficient(radius_m) * depth.powf(1.5);
    let sheared = [stick_m[0] + slip[0] * h_s, stick_m[1] + slip[1] * h_s];
    let mut f = [
        -k_t * sheared[0] - c_t * slip[0],
        -k_t * sheared[1] - c_t * slip[1],
    ];
    let limit = params.friction_limit(normal, speed);
    let magnitude = f[0].hypot(f[1]);
    if magnitude > limit {
        // Sliding: the limit against the shear, and the spring no further than it holds.
        f = [f[0] * limit / magnitude, f[1] * limit / magnitude];
        *stick_m = if k_t > 0.0 {
            [-f[0] / k_t, -f[1] / k_t]
        } else {
            [0.0; 2]
        };
    } else {
        *stick_m = sheared;
    }
    Some(SphereContact {
        force_n: [f[0], f[1], normal],
        point_m: point,
        depth_m: depth,
        slip_m_s: speed,
    })
}

/// The leg's sagittal geometry as the URDF gives it, for the virtual other leg and the
/// belt's speed: joint origins `[x, z]` (m) and pitch (rad, about -Y) of hip (in the pelvis
/// frame), knee (thigh) and ankle (shank), each joint's flexion (the ankle's dorsiflexion)
/// as a rotation about -Y (`+1`) or +Y (`-1`), 0 for a fixed ankle, and the foot's spheres.
#[derive(Debug, Clone, PartialEq)]
pub struct SagittalChain {
    /// Hip, knee and ankle origins in their parents' frames (m), `[x, z]`.
    pub origins_m: [[f64; 2]; 3],
    /// Hip, knee and ankle origins' rotations about -Y (rad): an anteriorly tilted pelvis
    /// turns the thigh back by its tilt.
    pub pitch_rad: [f64; 3],
    /// Sign of each joint's flexion as a rotation about -Y (hip, knee, ankle).
    pub flexion_sign: [f64; 3],
    /// The foot's contact spheres (foot frame).
    pub spheres: Vec<FootSphere>,
}

impl SagittalChain {
    /// Centre of sphere `i` in the pelvis frame (m, `[x, z]`) at hip and knee flexion and
    /// ankle dorsiflexion `q` (rad).
    pub fn sphere_centre(&self, i: usize, q: [f64; 3]) -> [f64; 2] {
        let c = self.spheres[i].center_m;
        self.in_pelvis([c[0], c[2]], q)
    }

    /// A point of the foot `[x, z]` (foot frame) in the pelvis frame at `q`.
    fn in_pelvis(&self, p: [f64; 2], q: [f64; 3]) -> [f64; 2] {
        // A rotation about -Y by `a` takes (x, z) to (x cos a - z sin a, x sin a + z cos a).
        let rot = |p: [f64; 2], a: f64| {
            let (s, c) = a.sin_cos();
            [p[0] * c - p[1] * s, p[0] * s + p[1] * c]
        };
        let add = |a: [f64; 2], b: [f64; 2]| [a[0] + b[0], a[1] + b[1]];
        let ankle = self.pitch_rad[2] + self.flexion_sign[2] * q[2];
        let in_shank = add(self.origins_m[2], rot(p, ankle));
        let knee = self.pitch_rad[1] + self.flexion_sign[1] * q[1];
        let in_thigh = add(self.origins_m[1], rot(in_shank, knee));
        let hip = self.pitch_rad[0] + self.flexion_sign[0] * q[0];
        add(self.origins_m[0], rot(in_thigh, hip))
    }

    /// The ankle's centre in the pelvis frame (m, `[x, z]`) at `q`.
    pub fn ankle_centre(&self, q: [f64; 3]) -> [f64; 2] {
        self.in_pelvis([0.0, 0.0], q)
    }

    /// How sphere `i`'s centre moves in the pelvis frame per radian of hip and of knee
    /// flexion at `q` (m/rad): `[d/d(hip), d/d(knee)]`, each `[x, z]`.
    pub fn sphere_jacobian(&self, i: usize, q: [f64; 3]) -> [[f64; 2]; 2] {
        let c = self.spheres[i].center_m;
        self.jacobian([c[0], c[2]], q)
    }

    /// As [`Self::sphere_jacobian`] for the ankle's centre.
    pub fn ankle_jacobian(&self, q: [f64; 3]) -> [[f64; 2]; 2] {
        self.jacobian([0.0, 0.0], q)
    }

    /// Central differences of a foot point `p`'s position over hip and knee flexion.
    fn jacobian(&self, p: [f64; 2], q: [f64; 3]) -> [[f64; 2]; 2] {
        let h = JACOBIAN_STEP_RAD;
        let at = |dh: f64, dk: f64| self.in_pelvis(p, [q[0] + dh, q[1] + dk, q[2]]);
        let slope =
            |a: [f64; 2], b: [f64; 2]| [(a[0] - b[0]) / (2.0 * h), (a[1] - b[1]) / (2.0 * h)];
        [
            slope(at(h, 0.0), at(-h, 0.0)),
            slope(at(0.0, h), at(0.0, -h)),
        ]
    }

    /// The foot's rotation about -Y relative to the pelvis at `q` (rad).
    pub fn foot_angle_rad(&self, q: [f64; 3]) -> f64 {
        self.pitch_rad.iter().sum::<f64>()
            + self.flexion_sign[0] * q[0]
            + self.flexion_sign[1] * q[1]
            + self.flexion_sign[2] * q[2]
    }
}

/// The belt speed at which `gait`'s foot does not slip: the mean backward speed, over the
/// reference's stance (initial contact to toe-off), of the material point of the foot at
/// its lowest sphere's lowest point, the leg at the reference's angles (its ankle's, if
/// the reference has one; by central differences, 400 samples of one stride after the
/// start-up ramp).
pub fn reference_belt_speed(gait: &crate::gait::GaitReference, chain: &SagittalChain) -> f64 {
    let period = gait.stride_period_s();
    let start = (gait.ramp_s() / period).ceil() * period;
    let n = 400;
    let h = 1e-5 * period;
    let pose = |t: f64| gait.sample(t).angles_rad();
    let mut sum = 0.0;
    for k in 0..n {
        let t = start + (k as f64 + 0.5) / n as f64 * gait.toe_off_phase() * period;
        let (q, q0, q1) = (pose(t), pose(t - h), pose(t + h));
        let lowest = (0..chain.spheres.len())
            .min_by(|&a, &b| {
                let z = |i: usize| chain.sphere_centre(i, q)[1] - chain.spheres[i].radius_m;
                z(a).total_cmp(&z(b))
            })
            .unwrap_or(0);
        let vx =
            (chain.sphere_centre(lowest, q1)[0] - chain.sphere_centre(lowest, q0)[0]) / (2.0 * h);
        // The lowest point of the sphere turns with the foot: it moves forward at r times
        // the foot's rate of rotation about -Y relative to the centre.
        let spin = (chain.foot_angle_rad(q1) - chain.foot_angle_rad(q0)) / (2.0 * h);
        sum += vx + chain.spheres[lowest].radius_m * spin;
    }
    -sum / n as f64
}

/// The virtual other leg: the reference half a stride later, rigid, its ankle at neutral,
/// on the belt.
#[derive(Debug, Clone)]
pub(crate) struct OtherLeg {
    pub gait: crate::gait::GaitReference,
    /// A pose held instead of the gait (rad), when this leg holds one too.
    pub hold: Option<[f64; 2]>,
    pub chain: SagittalChain,
    /// Each sphere's height in the pelvis frame at the last substep (m), for its rate.
    previous_z: Vec<f64>,
}

impl OtherLeg {
    pub(crate) fn new(gait: crate::gait::GaitReference, chain: SagittalChain) -> Self {
        let n = chain.spheres.len();
        Self {
            gait,
            hold: None,
            chain,
            previous_z: vec![f64::NAN; n],
        }
    }

    /// Its joint angles at `t_s` (rad).
    fn pose(&self, t_s: f64) -> [f64; 2] {
        self.hold.unwrap_or_else(|| {
            let g = self.gait.sample_half_stride_later(t_s);
            [g.hip.angle_rad, g.knee.angle_rad]
        })
    }

    /// Upward force (N) on a pelvis whose frame is at height `z_m` above the belt, rising at
    /// `vz_m_s`, at time `t_s` after a substep of `h_s`.
    fn force(&mut self, params: &ContactParams, t_s: f64, h_s: f64, z_m: f64, vz_m_s: f64) -> f64 {
        let q = self.pose(t_s);
        let mut total = 0.0;
        for (i, s) in self.chain.spheres.iter().enumerate() {
            let cz = self.chain.sphere_centre(i, [q[0], q[1], 0.0])[1];
            let rate = if self.previous_z[i].is_finite() {
                (cz - self.previous_z[i]) / h_s
            } else {
                0.0
            };
            self.previous_z[i] = cz;
            let depth = s.radius_m - (z_m + cz);
            total += params.normal_force(s.radius_m, depth, -(vz_m_s + rate));
        }
        total
    }
}

/// One foot as the treadmill sees it: its rigid body, its link and its spheres.
#[derive(Debug, Clone)]
pub struct FootSetup {
    /// The foot's body.
    pub(crate) body: RigidBodyHandle,
    /// The foot's link (`foot`, `right_foot`, ...).
    pub link: String,
    /// Its contact spheres, in the link's frame.
    pub spheres: Vec<FootSphere>,
}

/// What a treadmill is made of, fixed when the exoskeleton is built.
#[derive(Debug, Clone)]
pub(crate) struct GroundSetup {
    pub settings: TreadmillSettings,
    /// The simulated feet, leg by leg.
    pub feet: Vec<FootSetup>,
    /// The first leg's sagittal geometry (the virtual other leg is its copy).
    pub chain: SagittalChain,
    pub pelvis: RigidBodyHandle,
    /// Everything the belt and harness carry (kg).
    pub total_mass_kg: f64,
    /// The patient's mass on the pelvis (kg).
    pub carried_kg: f64,
    /// The pelvis's height standing (m): a spring harness's rest.
    pub standing_z_m: f64,
    /// Whether the pelvis slides fore-aft (`pelvis_x`), held by the harness's spring at
    /// its place when built (m, world X).
    pub fore_aft_at_m: Option<f64>,
    /// Where the pelvis frame is when its fore-aft slide is at its lower and upper limit
    /// (m, world X; `None` without a slide).
    pub fore_aft_stops_m: Option<[f64; 2]>,
}

/// One foot's contacts, summed over a period's substeps.
#[derive(Debug, Clone)]
struct FootState {
    /// Vertical and fore-aft force on the foot (N), summed over the period's substeps.
    sum: [f64; 2],
    deepest_m: f64,
    fastest_slip_m_s: f64,
    /// Sum of fore-aft slip times normal force, and of the normal forces, over the period.
    weighted_slip: [f64; 2],
    contacts: usize,
    /// This substep's contacts, sphere by sphere (sized once).
    current: Vec<Option<SphereContact>>,
    /// How far the belt has sheared each sphere while it sticks (m, X and Y).
    stick_m: Vec<[f64; 2]>,
    last: FootReaction,
}

impl FootState {
    fn new(spheres: usize) -> Self {
        Self {
            sum: [0.0; 2],
            deepest_m: 0.0,
            fastest_slip_m_s: 0.0,
            weighted_slip: [0.0; 2],
            contacts: 0,
            current: vec![None; spheres],
            stick_m: vec![[0.0; 2]; spheres],
            last: FootReaction::default(),
        }
    }

    /// The belt's contacts on `foot`'s spheres over a substep of `h_s`, the belt moving
    /// backwards at `belt_m_s`.
    fn apply(
        &mut self,
        foot: &FootSetup,
        params: &ContactParams,
        belt_m_s: f64,
        bodies: &mut RigidBodySet,
        h_s: f64,
    ) {
        let Some(rb) = bodies.get_mut(foot.body) else {
            return;
        };
        let pose = *rb.position();
        self.contacts = 0;
        for (k, s) in foot.spheres.iter().enumerate() {
            self.current[k] = None;
            let c = pose.transform_point(vector(s.center_m));
            let contact_point = c - Vector::new(0.0, 0.0, s.radius_m as Real);
            let v = rb.velocity_at_point(contact_point);
            let Some(contact) = sphere_contact(
                params,
                s.radius_m,
                [c.x, c.y, c.z].map(f64::from),
                [v.x, v.y, v.z].map(f64::from),
                belt_m_s,
                (&mut self.stick_m[k], h_s),
            ) else {
                continue;
            };
            self.current[k] = Some(contact);
            let f = contact.force_n;
            rb.add_force_at_point(vector(f), vector(contact.point_m), true);
            self.sum[0] += f[2];
            self.sum[1] += f[0];
            self.deepest_m = self.deepest_m.max(contact.depth_m);
            if f[2] > 0.0 {
                self.fastest_slip_m_s = self.fastest_slip_m_s.max(contact.slip_m_s);
                self.weighted_slip[0] += (f64::from(v.x) + belt_m_s) * f[2];
                self.weighted_slip[1] += f[2];
            }
            self.contacts += 1;
        }
    }

    /// Closes a period of `n` substeps.
    fn end_period(&mut self, n: f64) {
        self.last = FootReaction {
            vertical_n: self.sum[0] / n,
            fore_aft_n: self.sum[1] / n,
            penetration_m: self.deepest_m,
            slip_m_s: self.fastest_slip_m_s,
            fore_aft_slip_m_s: if self.weighted_slip[1] > 0.0 {
                self.weighted_slip[0] / self.weighted_slip[1]
            } else {
                0.0
            },
            contacts: self.contacts,
        };
        self.sum = [0.0; 2];
        self.deepest_m = 0.0;
        self.fastest_slip_m_s = 0.0;
        self.weighted_slip = [0.0; 2];
    }

    /// Fore-aft centre of pressure of the last substep's contacts (m, world X; NaN
    /// without one).
    fn centre_of_pressure_x_m(&self) -> f64 {
        let (moment, force) = self.current.iter().flatten().fold((0.0, 0.0), |(m, f), c| {
            (m + c.point_m[0] * c.force_n[2], f + c.force_n[2])
        });
        if force > 0.0 {
            moment / force
        } else {
            f64::NAN
        }
    }
}

/// The treadmill acting on the exoskeleton: the belt's contacts on every foot, the
/// harness and a virtual other leg on the pelvis, applied every physics substep.
#[derive(Debug, Clone)]
pub struct Ground {
    setup: GroundSetup,
    other: Option<OtherLeg>,
    /// Time since the exoskeleton was built (s), advanced every substep.
    clock_s: f64,
    /// The belt comes up to speed over this long from the start (s), with the gait.
    belt_ramp_s: f64,
    feet: Vec<FootState>,
    /// This period's sums over substeps: the other leg's and the harness's vertical
    /// forces, the harness's fore-aft force (N), the belt's speed (m/s).
    sum: [f64; 4],
    substeps: u32,
    last: GroundReaction,
    /// The pelvis's low-passed fore-aft offset from its start a self-paced belt follows
    /// (m).
    pelvis_offset_m: f64,
    /// How far the belt's surface has moved backwards since the start (m).
    belt_travel_m: f64,
}

impl Ground {
    pub(crate) fn new(setup: GroundSetup) -> Self {
        let feet = setup
            .feet
            .iter()
            .map(|f| FootState::new(f.spheres.len()))
            .collect();
        Self {
            setup,
            other: None,
            clock_s: 0.0,
            belt_ramp_s: 0.0,
            feet,
            sum: [0.0; 4],
            substeps: 0,
            last: GroundReaction::default(),
            pelvis_offset_m: 0.0,
            belt_travel_m: 0.0,
        }
    }

    /// Sets the belt's speed (m/s).
    pub(crate) fn set_belt_speed(&mut self, v_m_s: f64) {
        self.setup.settings.speed_m_per_s = Some(v_m_s);
    }

    /// Brings the belt up to speed over `ramp_s` from the start, with the gait's own
    /// start-up (the same quintic): a belt at full speed under a standing leg would drag
    /// its foot away.
    pub(crate) fn set_belt_ramp(&mut self, ramp_s: f64) {
        self.belt_ramp_s = ramp_s;
    }

    /// The belt's speed at the exoskeleton's clock (m/s).
    pub fn belt_speed_now_m_s(&self) -> f64 {
        let v = self.setup.settings.belt_speed_m_s();
        if self.belt_ramp_s <= 0.0 || self.clock_s >= self.belt_ramp_s {
            return v + self.self_paced_trim_m_s();
        }
        let s = (self.clock_s / self.belt_ramp_s).max(0.0);
        v * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
    }

    /// How far the belt's surface has moved backwards since the start (m).
    pub fn belt_travel_m(&self) -> f64 {
        self.belt_travel_m
    }

    /// A self-paced belt's change of speed (m/s; 0 for a belt at constant speed): the
    /// pelvis ahead of its start speeds the belt up.
    fn self_paced_trim_m_s(&self) -> f64 {
        self.setup.settings.self_paced_gain_per_s * self.pelvis_offset_m
    }

    /// Whether a self-paced belt follows the pelvis now: after the belt's start-up and the
    /// harness's start-up hold.
    fn self_paced_now(&self) -> bool {
        let s = &self.setup.settings;
        s.self_paced_gain_per_s > 0.0
            && self.clock_s >= self.belt_ramp_s
            && self.clock_s >= s.pelvis_held_until_s
    }

    /// Puts the virtual other leg under the pelvis.
    pub(crate) fn set_other_leg(&mut self, other: OtherLeg) {
        self.other = Some(other);
    }

    /// Whether a virtual other leg shares the load.
    pub fn has_other_leg(&self) -> bool {
        self.other.is_some()
    }

    /// The simulated feet, leg by leg.
    pub fn feet(&self) -> &[FootSetup] {
        &self.setup.feet
    }

    /// Foot `leg`'s contacts at the last substep, sphere by sphere (`None` out of contact).
    pub fn sphere_contacts(&self, leg: usize) -> &[Option<SphereContact>] {
        self.feet.get(leg).map_or(&[], |f| f.current.as_slice())
    }

    /// Fore-aft centre of pressure of foot `leg`'s last substep's contacts (m, world X;
    /// NaN without one).
    pub fn centre_of_pressure_x_m(&self, leg: usize) -> f64 {
        self.feet
            .get(leg)
            .map_or(f64::NAN, FootState::centre_of_pressure_x_m)
    }

    /// The settings.
    pub fn settings(&self) -> &TreadmillSettings {
        &self.setup.settings
    }

    /// Mass of everything the belt and harness carry: exoskeleton, legs and the patient's
    /// mass on the pelvis (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.setup.total_mass_kg
    }

    /// Where the pelvis frame is at its fore-aft slide's limits (m, world X; `None`
    /// without a slide).
    pub fn fore_aft_stops_m(&self) -> Option<[f64; 2]> {
        self.setup.fore_aft_stops_m
    }

    /// The patient's mass put on the pelvis (kg).
    pub fn carried_kg(&self) -> f64 {
        self.setup.carried_kg
    }

    /// The weight the belt carries at rest: `(1 - bws_fraction) m g` (N).
    pub fn unsupported_weight_n(&self) -> f64 {
        (1.0 - self.setup.settings.bws_fraction)
            * self.setup.total_mass_kg
            * pma_model::GRAVITY_M_S2
    }

    pub(crate) fn pelvis(&self) -> RigidBodyHandle {
        self.setup.pelvis
    }

    /// The first leg's sagittal geometry.
    pub fn chain(&self) -> &SagittalChain {
        &self.setup.chain
    }

    /// The other leg's joint angles (rad) now, if there is one.
    pub fn other_leg_pose(&self) -> Option<[f64; 2]> {
        Some(self.other.as_ref()?.pose(self.clock_s))
    }

    /// Makes the other leg hold `pose` (rad) instead of walking (`None`: walk again).
    pub(crate) fn hold_other_leg(&mut self, pose: Option<[f64; 2]>) {
        if let Some(o) = &mut self.other {
            o.hold = pose;
        }
    }

    /// The share of the body weight the harness carries now: `bws_fraction`, or more
    /// while the start's support is lowered.
    pub fn support_fraction_now(&self) -> f64 {
        self.setup.settings.support_fraction_at(self.clock_s)
    }

    /// The harness's upward force (N) with the pelvis at height `z_m`.
    pub fn support_force_n(&self, z_m: f64) -> f64 {
        let weight =
            self.support_fraction_now() * self.setup.total_mass_kg * pma_model::GRAVITY_M_S2;
        match self.setup.settings.bws {
            BwsKind::ConstantForce => weight,
            BwsKind::Spring => (weight
                + self.setup.settings.bws_spring_n_per_m * (self.setup.standing_z_m - z_m))
                .max(0.0),
        }
    }

    /// Adds this substep's contact forces to every foot, and the harness's and the other
    /// leg's to the pelvis (their user forces reset by the exoskeleton at the substep's
    /// start); `h_s` is the substep's length.
    pub(crate) fn apply(&mut self, bodies: &mut RigidBodySet, h_s: f64) {
        self.substeps += 1;
        if let Some(rb) = bodies.get_mut(self.setup.pelvis) {
            let z = f64::from(rb.translation().z);
            let up = self.support_force_n(z);
            let other = match &mut self.other {
                Some(o) => o.force(
                    &self.setup.settings.contact,
                    self.clock_s,
                    h_s,
                    z,
                    f64::from(rb.linvel().z),
                ),
                None => 0.0,
            };
            let held = match self.setup.fore_aft_at_m {
                Some(x0) => {
                    let t = &self.setup.settings;
                    let (k, c) = if self.clock_s < t.pelvis_held_until_s {
                        START_HOLD_N_PER_M
                    } else {
                        (
                            t.pelvis_fore_aft_n_per_m,
                            t.pelvis_fore_aft_damping_n_s_per_m,
                        )
                    };
                    -k * (f64::from(rb.translation().x) - x0) - c * f64::from(rb.linvel().x)
                }
                None => 0.0,
            };
            if let (true, Some(x0)) = (self.self_paced_now(), self.setup.fore_aft_at_m) {
                let offset = f64::from(rb.translation().x) - x0;
                self.pelvis_offset_m += (offset - self.pelvis_offset_m) * h_s / SELF_PACED_FILTER_S;
            }
            self.sum[0] += other;
            self.sum[1] += up;
            self.sum[2] += held;
            rb.add_force(Vector::new(held as Real, 0.0, (up + other) as Real), true);
        }
        let belt = self.belt_speed_now_m_s();
        self.sum[3] += belt;
        self.belt_travel_m += belt * h_s;
        let params = self.setup.settings.contact;
        for (state, foot) in self.feet.iter_mut().zip(&self.setup.feet) {
            state.apply(foot, &params, belt, bodies, h_s);
        }
        self.clock_s += h_s;
    }

    /// Closes a period: its averages become [`Self::reaction`].
    pub(crate) fn end_period(&mut self) {
        let n = f64::from(self.substeps.max(1));
        for f in &mut self.feet {
            f.end_period(n);
        }
        let feet = &self.feet;
        self.last = GroundReaction {
            feet: PerLeg::from_fn(feet.len(), |i| feet[i].last),
            contralateral_n: self.sum[0] / n,
            support_n: self.sum[1] / n,
            harness_fore_aft_n: self.sum[2] / n,
            belt_speed_m_s: self.sum[3] / n,
        };
        self.sum = [0.0; 4];
        self.substeps = 0;
    }

    /// The last period's ground reaction.
    pub fn reaction(&self) -> GroundReaction {
        self.last
    }

    /// Time since the exoskeleton was built, as the other leg's reference sees it (s).
    pub fn clock_s(&self) -> f64 {
        self.clock_s
    }
}

fn vector(v: [f64; 3]) -> Vector {
    Vector::new(v[0] as Real, v[1] as Real, v[2] as Real)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hertz_law_matches_opensims_smooth_sphere_constants() {
        // E = 1e6 N/m^2, r = 0.032 m (Falisse et al. 2019): k = 5000, K = 4/3 k sqrt(r k).
        let p = ContactParams {
            stiffness_n_per_m2: 1e6,
            ..ContactParams::default()
        };
        let k = p.hertz_coefficient(0.032);
        assert!((k - 4.0 / 3.0 * 5000.0 * (0.032f64 * 5000.0).sqrt()).abs() < 1e-6);
        assert_eq!(p.normal_force(0.032, -1e-3, 0.0), 0.0);
        let f = p.normal_force(0.032, 0.01, 0.0);
        assert!((f - k * 1e-3).abs() < 1e-9, "{f}");
        // Separating fast, the damping term never makes the contact pull.
        assert_eq!(p.normal_force(0.032, 0.01, -10.0), 0.0);
    }

    #[test]
    fn friction_opposes_slip_against_the_moving_belt() {
        let p = ContactParams::default();
        let h = 5e-4;
        // A foot at rest on a belt moving backwards slips forwards relative to it: the belt
        // drags it backwards, at the sliding limit.
        let mut stick = [0.0; 2];
        let c = sphere_contact(&p, 0.03, [0.0, 0.0, 0.02], [0.0; 3], 1.0, (&mut stick, h)).unwrap();
        let f = c.force_n;
        assert!(f[0] < 0.0 && (c.slip_m_s - 1.0).abs() < 1e-12, "{c:?}");
        assert!((-f[0] - f[2] * (0.8 + 0.5)).abs() < 1e-9, "{c:?}");
        // Sliding leaves the spring at what it holds.
        let k_t = p.tangential_stiffness(0.03, 0.01);
        assert!((stick[0] * k_t + f[0]).abs() < 1e-9, "{stick:?}");
        // Moving with the belt and unsheared: no friction.
        let mut stick = [0.0; 2];
        let c = sphere_contact(
            &p,
            0.03,
            [0.0, 0.0, 0.02],
            [-1.0, 0.0, 0.0],
            1.0,
            (&mut stick, h),
        )
        .unwrap();
        assert_eq!(c.force_n[0], 0.0);
        let mut stick = [0.001, 0.0];
        assert!(
            sphere_contact(&p, 0.03, [0.0, 0.0, 0.031], [0.0; 3], 1.0, (&mut stick, h)).is_none()
        );
        assert_eq!(stick, [0.0; 2], "lifting off releases the shear");
    }

    #[test]
    fn a_sticking_sphere_is_a_spring_of_mindlins_stiffness() {
        // Sheared by 1 mm at rest, below the sliding limit: the force is k_t x 1 mm, and
        // k_t is 2/3 of the normal stiffness (nu = 0.5).
        let p = ContactParams::default();
        let (r, d): (f64, f64) = (0.03, 0.01);
        let k_n = 1.5 * p.hertz_coefficient(r) * d.sqrt();
        assert!((p.tangential_stiffness(r, d) - 2.0 / 3.0 * k_n).abs() < 1e-9);
        let mut stick = [1e-3, 0.0];
        let c = sphere_contact(
            &p,
            r,
            [0.0, 0.0, r - d],
            [-0.5, 0.0, 0.0],
            0.5,
            (&mut stick, 5e-4),
        )
        .unwrap();
        assert!(
            (c.force_n[0] + p.tangential_stiffness(r, d) * 1e-3).abs() < 1e-9,
            "{c:?}"
        );
        assert!(c.force_n[0].abs() < 0.8 * c.force_n[2]);
        assert_eq!(stick, [1e-3, 0.0]);
    }

    #[test]
    fn bad_treadmill_input_names_the_field() {
        let ok = TreadmillSettings {
            speed_m_per_s: Some(0.6),
            ..TreadmillSettings::new(0.3, 75.0)
        };
        ok.validate().unwrap();
        for (bad, field) in [
            (
                TreadmillSettings {
                    speed_m_per_s: Some(-0.5),
                    ..ok
                },
                "speed_m_per_s",
            ),
            (
                TreadmillSettings {
                    bws_fraction: 1.2,
                    ..ok
                },
                "bws_fraction",
            ),
            (
                TreadmillSettings {
                    body_mass_kg: f64::NAN,
                    ..ok
                },
                "body_mass_kg",
            ),
            (
                TreadmillSettings {
                    bws: BwsKind::Spring,
                    ..ok
                },
                "bws_spring_n_per_m",
            ),
            (
                TreadmillSettings {
                    self_paced_gain_per_s: -0.3,
                    ..ok
                },
                "self_paced_gain_per_s",
            ),
            (
                TreadmillSettings {
                    bws_start_fraction: Some(0.2),
                    ..ok
                },
                "bws_start_fraction",
            ),
            (
                TreadmillSettings {
                    bws_release_s: [3.0, 1.0],
                    ..ok
                },
                "bws_release_s",
            ),
            (
                TreadmillSettings {
                    bws_release_s: [-1.0, 1.0],
                    ..ok
                },
                "bws_release_s",
            ),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn the_legs_share_follows_the_support_the_harness_lowers() {
        // Walking at 30 %: while the harness carries 80 % the legs carry 0.2 / 0.7 of what
        // they carry at 30 %, after the window all of it.
        let mut s = TreadmillSettings::new(0.3, 75.0);
        s.bws_start_fraction = Some(0.8);
        s.bws_release_s = [1.0, 2.0];
        for (t_s, share) in [(0.5, 0.2 / 0.7), (1.5, 0.45 / 0.7), (3.0, 1.0)] {
            assert!((s.legs_share_at(t_s) - share).abs() < 1e-12, "{t_s} s");
        }
        s.bws_fraction = 1.0;
        assert_eq!(s.legs_share_at(0.5), 1.0);
    }

    #[test]
    fn regression_a_release_window_without_a_start_support_was_ignored() {
        let base = TreadmillSettings::new(0.0, 75.0);
        let window_alone = TreadmillSettings {
            bws_release_s: [1.0, 2.0],
            ..base
        };
        let e = window_alone.validate().unwrap_err().to_string();
        assert!(
            e.contains("treadmill.bws_release_s") && e.contains("bws_start_fraction"),
            "{e}"
        );
        let start_alone = TreadmillSettings {
            bws_start_fraction: Some(0.3),
            ..base
        };
        let e = start_alone.validate().unwrap_err().to_string();
        assert!(e.contains("treadmill.bws_start_fraction"), "{e}");
        // A start equal to the walking support changes nothing and needs no window.
        TreadmillSettings {
            bws_start_fraction: Some(0.0),
            ..base
        }
        .validate()
        .unwrap();
        TreadmillSettings {
            bws_start_fraction: Some(0.3),
            bws_release_s: [1.0, 2.0],
            ..base
        }
        .validate()
        .unwrap();
    }
}
