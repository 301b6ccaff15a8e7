use crate::base::LegError;
use pma_model::error::within;
use serde::{Deserialize, Serialize};

/// One joint's impedance set point.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointImpedance {
    /// Stiffness about the reference (N m/rad), realised by co-contraction. Default: the
    /// middle of what the joint's pair reaches at rest ([`MusclePair::stiffness_range`]).
    #[serde(default)]
    pub stiffness_nm_per_rad: Option<f64>,
    /// Damping about the reference (N m s/rad): the muscles' own, plus a feedback on the
    /// velocity error for any more. Default 0 (the muscles' own only).
    #[serde(default)]
    pub damping_nm_s_per_rad: f64,
}

/// `[control.impedance]`: the set points of impedance mode.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ImpedanceSettings {
    /// The hip's set point.
    #[serde(default)]
    pub hip: JointImpedance,
    /// The knee's set point.
    #[serde(default)]
    pub knee: JointImpedance,
    /// Time constant of the filter on the encoder's differentiated angle (s).
    #[serde(default = "default_velocity_filter")]
    pub velocity_filter_s: f64,
    /// On a treadmill, add the body weight a stance leg carries (the belt's share, passed
    /// from the trailing to the leading leg over double support) to the torque the pairs
    /// hold ([`StanceLoad`]). Default on: without it the stance knees buckle under the
    /// weight the support leaves them.
    #[serde(default = "stance_load_on")]
    pub stance_load: bool,
    /// An assist-as-needed feedforward learned stride by stride ([`StrideLearning`]).
    /// Absent: none (the law as before).
    #[serde(default)]
    pub learning: Option<LearningSettings>,
    /// Admittance mode: time constant of the filter on the cuff torque the patient adds
    /// (s; [`crate::admittance`]).
    #[serde(default = "default_cuff_filter")]
    pub cuff_filter_s: f64,
    /// Share of the adults' walking moments (Fukuchi et al. 2018 at the reference's speed,
    /// scaled as `own_torque = "walking"` scales them) the plan leaves to the patient:
    /// impedance and admittance modes take it off the torque they hold, at the reference's
    /// phase ([`ExpectedMoments`]). Default 0: the device plans the whole stance and
    /// swing, a passive patient's; 1: it expects a patient who walks as adults do, and
    /// yields to what they do beyond it or lack. Needs a `[treadmill]` and the adult gait.
    #[serde(default)]
    pub patient_moment_share: f64,
    /// The share per leg on a two-leg trainer, `[right, left]`, instead of
    /// `patient_moment_share`: less left to a patient's weak side (as
    /// `patient.active.strength_by_leg` makes one).
    #[serde(deserialize_with = "pma_model::error::exact::option", default)]
    pub patient_moment_share_by_leg: Option<[f64; 2]>,
    /// Gain (1/s) of the trainer's gait clock on the legs' measured lead over the
    /// reference ([`crate::phase_sync`]): the reference's timing follows a patient who
    /// walks on their own. Default 0: the reference keeps its own clock.
    #[serde(default)]
    pub phase_sync_per_s: f64,
    /// Integral gain (1/s²) of the gait clock's loop: with it the clock takes the whole of
    /// a patient's steady cadence difference, not only the part a stiff spring lets the
    /// legs show ([`crate::phase_sync`]). Default 0; below `phase_sync_per_s` over the
    /// stride period (the loop's stability bound).
    #[serde(default)]
    pub phase_sync_integral_per_s2: f64,
}

/// `[control.impedance.learning]`: the torque each joint's pair adds at each phase of the
/// stride, learned from the error there in the strides before, with a forgetting factor
/// (Emken, Benitez and Reinkensmeyer 2007, JNER 4:8: `F(i+1) = f F(i) + g e(i)` per phase;
/// the forgetting lets the assistance fade where the error is small).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LearningSettings {
    /// `g` over the joint's stiffness: the share of last stride's spring torque `K e` at a
    /// phase added to that phase's feedforward (per stride). On a spring alone the error
    /// then falls to `(1 - f) / (1 - f + gain)` of what it was without learning.
    pub gain: f64,
    /// `f`, the share of the learned torque kept from one stride to the next.
    pub forgetting: f64,
}

/// Phase bins of a learned feedforward over one stride: 50, about 35 ms each at the adult
/// reference's 1.75 s stride, averaging the error over tens of periods (the filter that
/// keeps learning on the stride's shape, not on the valves' ripple).
pub const LEARNING_BINS: usize = 50;

fn stance_load_on() -> bool {
    true
}

impl Default for JointImpedance {
    fn default() -> Self {
        Self {
            stiffness_nm_per_rad: None,
            damping_nm_s_per_rad: 0.0,
        }
    }
}

fn default_velocity_filter() -> f64 {
    0.005
}

fn default_cuff_filter() -> f64 {
    0.01
}

impl Default for ImpedanceSettings {
    fn default() -> Self {
        Self {
            hip: JointImpedance::default(),
            knee: JointImpedance::default(),
            velocity_filter_s: default_velocity_filter(),
            stance_load: true,
            learning: None,
            cuff_filter_s: default_cuff_filter(),
            patient_moment_share: 0.0,
            patient_moment_share_by_leg: None,
            phase_sync_per_s: 0.0,
            phase_sync_integral_per_s2: 0.0,
        }
    }
}

/// Checks a stiffness set point given on a command line: finite, above 0 and at most
/// [`STIFFNESS_MAX_NM_PER_RAD`].
pub fn stiffness_in_range(k: f64) -> bool {
    k.is_finite() && k > 0.0 && k <= STIFFNESS_MAX_NM_PER_RAD
}

/// Highest stiffness a set point may name (N m/rad): ten times what LOPES II renders at
/// most (1500 N m/rad), beyond any gait trainer's; what a pair reaches is checked against
/// its muscles when the leg is built.
pub const STIFFNESS_MAX_NM_PER_RAD: f64 = 15_000.0;

impl ImpedanceSettings {
    /// The share of the adults' walking moments left to leg `leg`'s patient.
    pub fn patient_moment_share(&self, leg: usize) -> f64 {
        self.patient_moment_share_by_leg
            .map_or(self.patient_moment_share, |by_leg| by_leg[leg.min(1)])
    }

    /// The set point of joint `joint` (0 hip, 1 knee).
    pub fn joint(&self, joint: usize) -> JointImpedance {
        if joint == 0 {
            self.hip
        } else {
            self.knee
        }
    }

    /// Checks every field's range (the muscles' reach is checked by [`MusclePair`]).
    pub fn validate(&self) -> Result<(), LegError> {
        for (name, j) in [("hip", self.hip), ("knee", self.knee)] {
            if let Some(k) = j.stiffness_nm_per_rad {
                within(
                    format!("control.impedance.{name}.stiffness_nm_per_rad"),
                    k,
                    f64::MIN_POSITIVE,
                    STIFFNESS_MAX_NM_PER_RAD,
                    "must be > 0 and at most 15000 N m/rad (ten times LOPES II's 1500)",
                )?;
            }
            within(
                format!("control.impedance.{name}.damping_nm_s_per_rad"),
                j.damping_nm_s_per_rad,
                0.0,
                1000.0,
                "must be 0 to 1000 N m s/rad",
            )?;
        }
        within(
            "control.impedance.velocity_filter_s",
            self.velocity_filter_s,
            0.0,
            0.1,
            "must be 0 to 0.1 s",
        )?;
        within(
            "control.impedance.cuff_filter_s",
            self.cuff_filter_s,
            0.0,
            0.5,
            "must be 0 to 0.5 s",
        )?;
        within(
            "control.impedance.patient_moment_share",
            self.patient_moment_share,
            0.0,
            1.0,
            "must be 0 to 1 (the share of the adults' walking moments left to the patient)",
        )?;
        for (leg, side) in ["right", "left"].iter().enumerate() {
            if let Some(by_leg) = self.patient_moment_share_by_leg {
                within(
                    format!("control.impedance.patient_moment_share_by_leg[{leg}] ({side})"),
                    by_leg[leg],
                    0.0,
                    1.0,
                    "must be 0 to 1 (the share of the adults' walking moments left to the patient)",
                )?;
            }
        }
        if let Some(l) = self.learning {
            within(
                "control.impedance.learning.forgetting",
                l.forgetting,
                0.0,
                1.0,
                "must be 0 to 1 (the share of the learned torque kept per stride)",
            )?;
            // On a spring the learned torque follows F(i+1) = (f - gain) F(i) + ...: it
            // converges for |f - gain| < 1.
            within(
                "control.impedance.learning.gain",
                l.gain,
                0.0,
                1.0 + l.forgetting - 1e-9,
                "must be >= 0 and below 1 + forgetting (beyond it the learning diverges)",
            )?;
        }
        Ok(())
    }
}

/// A feedforward torque per joint over the phases of the stride, learned from the error
/// at each phase stride by stride ([`LearningSettings`]). Fixed-size: it allocates nothing.
#[derive(Debug, Clone)]
pub struct StrideLearning {
    settings: LearningSettings,
    /// Learned torque per joint and bin (N m).
    learned_nm: [[f64; LEARNING_BINS]; 2],
    /// The error summed over the current visit of a bin, and its periods.
    error_sum_rad: [f64; 2],
    periods: u32,
    /// The bin being visited.
    bin: Option<usize>,
}

impl StrideLearning {
    /// Nothing learned yet.
    pub fn new(settings: LearningSettings) -> Self {
        Self {
            settings,
            learned_nm: [[0.0; LEARNING_BINS]; 2],
            error_sum_rad: [0.0; 2],
            periods: 0,
            bin: None,
        }
    }

    /// The learned torque per joint (N m) at `phase` (0-1), linear between the bins'
    /// centres, after taking in the error `error_rad` (reference minus measured) of joints
    /// of stiffness `stiffness_nm_per_rad`. A bin is updated when the phase leaves it,
    /// from the mean error over that visit.
    pub fn update(
        &mut self,
        phase: f64,
        error_rad: [f64; 2],
        stiffness_nm_per_rad: [f64; 2],
    ) -> [f64; 2] {
        let x = phase.rem_euclid(1.0) * LEARNING_BINS as f64;
        let bin = (x as usize).min(LEARNING_BINS - 1);
        if let Some(left) = self.bin.filter(|&b| b != bin) {
            self.close(left, stiffness_nm_per_rad);
        }
        self.bin = Some(bin);
        for (sum, e) in self.error_sum_rad.iter_mut().zip(error_rad) {
            *sum += e;
        }
        self.periods += 1;
        self.at(x)
    }

    /// Stops taking in errors (a held pose, a standing start): the visit in progress is
    /// dropped, what was learned stays.
    pub fn pause(&mut self) {
        self.bin = None;
        self.error_sum_rad = [0.0; 2];
        self.periods = 0;
    }

    /// The learned torque (N m) at `x` bins into the stride.
    pub fn at(&self, x: f64) -> [f64; 2] {
        let s = x - 0.5;
        let k = s.floor();
        let w = s - k;
        let below = (k as i64).rem_euclid(LEARNING_BINS as i64) as usize;
        let above = (below + 1) % LEARNING_BINS;
        [0, 1].map(|j| (1.0 - w) * self.learned_nm[j][below] + w * self.learned_nm[j][above])
    }

    fn close(&mut self, bin: usize, stiffness_nm_per_rad: [f64; 2]) {
        if self.periods > 0 {
            let LearningSettings { gain, forgetting } = self.settings;
            let n = f64::from(self.periods);
            for ((learned, sum), k) in self
                .learned_nm
                .iter_mut()
                .zip(self.error_sum_rad)
                .zip(stiffness_nm_per_rad)
            {
                learned[bin] = forgetting * learned[bin] + gain * k * (sum / n);
            }
        }
        self.error_sum_rad = [0.0; 2];
        self.periods = 0;
    }
}
