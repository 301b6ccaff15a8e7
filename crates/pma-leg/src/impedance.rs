//! Impedance by co-contraction: each joint's stiffness set through its muscle pair's
//! pressure sum and its torque through their difference (Tondu and Lopez 2000; Verrelst
//! et al. 2005), the valves' own pressure loops as the inner loops.
//!
//! A muscle at constant pressure `P` is a spring in its contraction `x`: `dF/dx = -k(P)`
//! for eq. (1), the map's slope for a Festo size. On a pulley of signed arm `m` its
//! contraction is `x0 + m q`, so the pair's joint stiffness at constant pressures is
//! `K = m_f^2 k_f(P_f) + m_e^2 k_e(P_e)`, which grows with both pressures, while the torque
//! `m_f F_f + m_e F_e` grows with their difference. Each period the law solves the two
//! equations "stiffness = set point, torque at the reference pose = what the reference
//! needs" for the two pressures; the muscles then are a spring of the set stiffness about
//! the reference, by their own physics, with no position feedback: a push on the leg
//! deflects it by `torque / K` whatever the controller does within the valve's lag.
//!
//! What the torque at the reference pose holds: the rigid leg's inverse dynamics along the
//! reference, with gravity at the *measured* pose (the device's weight compensated where it
//! is, so that gravity adds no stiffness of its own), the muscles' own damping along the
//! reference's velocity (so that the damping acts about the reference), and a damping
//! feedback on the velocity error for whatever the set point asks beyond the muscles' own.
use crate::config::Side;
use crate::error::LegError;
use crate::exoskeleton::LegInertia;
use crate::gait::GaitSample;
use crate::plant::MuscleActuator;
use pma_model::error::within;
use pma_model::{DampingMode, MuscleModel};
use serde::{Deserialize, Serialize};

/// How a leg's joints are controlled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlMode {
    /// Robot in charge: each muscle's controller tracks its length along the reference.
    #[default]
    Position,
    /// Each joint a spring and damper about the reference, its stiffness set by the pair's
    /// co-contraction ([`ImpedanceSettings`]).
    Impedance,
    /// Path control (Duschau-Wicke et al. 2010): free inside a tunnel around the
    /// reference's path in joint space, whatever the timing; a wall outside; a supportive
    /// torque along the path ([`PathSettings`]). The pairs at their softest.
    Path,
    /// Patient in charge: no torque on the limb but what compensates the device (its
    /// weight, the muscles' own damping); the pairs at their softest.
    Transparent,
    /// Impedance through the muscles' own controllers (admittance control): each joint's
    /// reference displaced by the cuff torque the patient adds over the set stiffness
    /// (`[control.impedance]`), tracked by the muscle controllers as in position mode
    /// ([`crate::admittance`]).
    Admittance,
}

impl ControlMode {
    /// Whether the muscles' own controllers run (position mode) or the pairs are set by
    /// pressure (every other mode).
    pub fn runs_muscle_controllers(self) -> bool {
        matches!(self, Self::Position | Self::Admittance)
    }

    /// Whether the pairs' pressures are set by [`ImpedanceLaw`] (impedance, path and
    /// transparent modes), no muscle controller running.
    pub fn sets_pressures(self) -> bool {
        !self.runs_muscle_controllers()
    }
}

/// Whose weight and inertia the pressure-set modes carry besides their own law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Compensation {
    /// The whole leg, limb and frames: a passive patient is carried (default).
    #[default]
    Leg,
    /// The exoskeleton's own frames only: an active patient carries their own limb.
    Device,
}

/// `[control.path]`: path control's tunnel and support.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PathSettings {
    /// Half-width of the tunnel around the path in the hip-knee plane (deg).
    #[serde(default = "default_width")]
    pub width_deg: f64,
    /// Stiffness of the wall beyond it (N m/rad).
    #[serde(default = "default_wall")]
    pub wall_nm_per_rad: f64,
    /// Supportive torque along the path (N m, as a vector in the hip-knee plane).
    #[serde(default)]
    pub support_nm: f64,
}

fn default_width() -> f64 {
    5.0
}
fn default_wall() -> f64 {
    100.0
}

impl Default for PathSettings {
    fn default() -> Self {
        Self {
            width_deg: default_width(),
            wall_nm_per_rad: default_wall(),
            support_nm: 0.0,
        }
    }
}

impl PathSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LegError> {
        within(
            "control.path.width_deg",
            self.width_deg,
            0.0,
            30.0,
            "must be 0..=30 deg (a tunnel half-width in the hip-knee plane)",
        )?;
        within(
            "control.path.wall_nm_per_rad",
            self.wall_nm_per_rad,
            0.0,
            STIFFNESS_MAX_NM_PER_RAD,
            "must be 0..=15000 N m/rad",
        )?;
        within(
            "control.path.support_nm",
            self.support_nm,
            0.0,
            100.0,
            "must be 0..=100 N m",
        )?;
        Ok(())
    }
}

/// Points of the reference's path over a stride.
const PATH_POINTS: usize = 200;
/// Segments scanned each way from the last nearest one (a stride's 200 segments pass in
/// 1-2 s, a few per 1 ms period).
const LOCAL_SEGMENTS: usize = 12;

/// The reference's path over one stride in the hip-knee plane (rad), closed.
#[derive(Debug, Clone)]
pub struct Tunnel {
    points: Vec<[f64; 2]>,
    width_rad: f64,
}

/// Where a pose is against the tunnel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// From the nearest point of the path to the pose (rad).
    pub offset_rad: [f64; 2],
    /// Distance to the path (rad).
    pub distance_rad: f64,
    /// Unit tangent of the path there, in the gait's direction.
    pub tangent: [f64; 2],
}

impl Tunnel {
    /// The path of `gait` over its stride after the start-up, of half-width `width_deg`.
    pub fn new(gait: &crate::gait::GaitReference, width_deg: f64) -> Self {
        let t0 = gait.ramp_s() + gait.stride_period_s();
        let points = (0..PATH_POINTS)
            .map(|i| {
                let g = gait.sample(t0 + gait.stride_period_s() * i as f64 / PATH_POINTS as f64);
                [g.hip.angle_rad, g.knee.angle_rad]
            })
            .collect();
        Self {
            points,
            width_rad: width_deg.to_radians(),
        }
    }

    /// Half-width (rad).
    pub fn width_rad(&self) -> f64 {
        self.width_rad
    }

    /// The nearest point of the path to `q` (a scan of all its segments).
    pub fn locate(&self, q: [f64; 2]) -> PathPoint {
        self.nearest(q, 0..self.points.len()).0
    }

    /// As [`Tunnel::locate`], scanning first only the segments within `LOCAL_SEGMENTS` of
    /// `*hint` (the last one found, updated): a leg moves a few segments per period. A
    /// distance within the tunnel found so is within it for the full scan too (the full
    /// scan can only find a nearer point); beyond it, all segments are scanned, so that
    /// whether the leg is inside, and the wall's push, are exactly the full scan's.
    pub fn locate_near(&self, q: [f64; 2], hint: &mut usize) -> PathPoint {
        let n = self.points.len();
        let start = *hint + n - LOCAL_SEGMENTS;
        let (mut at, mut index) =
            self.nearest(q, (start..start + 2 * LOCAL_SEGMENTS + 1).map(|i| i % n));
        if at.distance_rad > self.width_rad {
            (at, index) = self.nearest(q, 0..n);
        }
        *hint = index;
        at
    }

    /// The nearest point over segments `range` and its segment's index.
    fn nearest(&self, q: [f64; 2], range: impl Iterator<Item = usize>) -> (PathPoint, usize) {
        let n = self.points.len();
        let mut best = PathPoint {
            offset_rad: [f64::INFINITY; 2],
            distance_rad: f64::INFINITY,
            tangent: [1.0, 0.0],
        };
        let mut index = 0;
        // Compared squared: `hypot`, once per segment, was 5 % of a two-leg period.
        let mut best_d2 = f64::INFINITY;
        for i in range {
            let a = self.points[i];
            let b = self.points[(i + 1) % n];
            let ab = [b[0] - a[0], b[1] - a[1]];
            let len2 = ab[0] * ab[0] + ab[1] * ab[1];
            if len2 <= 0.0 {
                continue;
            }
            let s = (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0);
            let offset = [q[0] - a[0] - s * ab[0], q[1] - a[1] - s * ab[1]];
            let d2 = offset[0] * offset[0] + offset[1] * offset[1];
            if d2 < best_d2 {
                best_d2 = d2;
                let len = len2.sqrt();
                best.offset_rad = offset;
                best.tangent = [ab[0] / len, ab[1] / len];
                index = i;
            }
        }
        if best_d2.is_finite() {
            best.distance_rad = best.offset_rad[0].hypot(best.offset_rad[1]);
        }
        (best, index)
    }
}

impl std::fmt::Display for ControlMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Position => "position",
            Self::Impedance => "impedance",
            Self::Path => "path",
            Self::Transparent => "transparent",
            Self::Admittance => "admittance",
        })
    }
}

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
                "must be 0..=1000 N m s/rad",
            )?;
        }
        within(
            "control.impedance.velocity_filter_s",
            self.velocity_filter_s,
            0.0,
            0.1,
            "must be 0..=0.1 s",
        )?;
        within(
            "control.impedance.cuff_filter_s",
            self.cuff_filter_s,
            0.0,
            0.5,
            "must be 0..=0.5 s",
        )?;
        within(
            "control.impedance.patient_moment_share",
            self.patient_moment_share,
            0.0,
            1.0,
            "must be 0..=1 (the share of the adults' walking moments left to the patient)",
        )?;
        for (leg, side) in ["right", "left"].iter().enumerate() {
            if let Some(by_leg) = self.patient_moment_share_by_leg {
                within(
                    format!("control.impedance.patient_moment_share_by_leg[{leg}] ({side})"),
                    by_leg[leg],
                    0.0,
                    1.0,
                    "must be 0..=1 (the share of the adults' walking moments left to the patient)",
                )?;
            }
        }
        if let Some(l) = self.learning {
            within(
                "control.impedance.learning.forgetting",
                l.forgetting,
                0.0,
                1.0,
                "must be 0..=1 (the share of the learned torque kept per stride)",
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

/// One muscle of a pair as the law models it.
#[derive(Debug, Clone, Copy)]
struct PairMuscle {
    /// Signed moment arm (m): contraction per radian of flexion.
    arm_m: f64,
    contraction_at_zero_m: f64,
    model: MuscleModel,
}

/// Step of the numerical slope of a Festo map (m): a tenth of a millimetre.
const DX_M: f64 = 1e-4;

impl PairMuscle {
    fn contraction(&self, q_rad: f64) -> f64 {
        self.contraction_at_zero_m + self.arm_m * q_rad
    }

    /// Static force (N) at pressure `p` and joint angle `q`, unclamped.
    fn force(&self, p: f64, q_rad: f64) -> f64 {
        self.model
            .force_unclamped(p, self.contraction(q_rad), 0.0, DampingMode::Inflation)
    }

    /// This muscle's share of the joint stiffness (N m/rad) at pressure `p`.
    fn stiffness(&self, p: f64, q_rad: f64) -> f64 {
        let x = self.contraction(q_rad);
        let at = |x: f64| {
            self.model
                .force_unclamped(p, x, 0.0, DampingMode::Inflation)
        };
        -self.arm_m * self.arm_m * (at(x + DX_M) - at(x - DX_M)) / (2.0 * DX_M)
    }

    /// Its share of the joint damping (N m s/rad) at pressure `p`: the mean of the
    /// inflating and deflating coefficients (which one acts depends on the valve's
    /// direction, unknown ahead).
    fn damping(&self, p: f64) -> f64 {
        let b = |mode| match self.model {
            MuscleModel::ThreeElement(m) => m.damping(p, mode),
            MuscleModel::Festo(f) => f.damping(p, mode),
        };
        self.arm_m * self.arm_m * 0.5 * (b(DampingMode::Inflation) + b(DampingMode::Deflation))
    }
}

/// A joint's flexor and extensor as the impedance law models them (their assumed
/// models: Table I for an eq. (1) muscle, the map for a Festo size).
#[derive(Debug, Clone, Copy)]
pub struct MusclePair {
    joint: usize,
    /// Flexor, extensor.
    muscles: [PairMuscle; 2],
    /// Their places among the leg's four muscles.
    indices: [usize; 2],
    pressure_max_pa: f64,
}

/// What a pair reaches at one pose and torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StiffnessRange {
    /// Lowest stiffness (N m/rad) with both muscles pulling within the valve's range.
    pub min_nm_per_rad: f64,
    /// Highest.
    pub max_nm_per_rad: f64,
}

/// Points of the pressure-sum scan of [`MusclePair::stiffness_range`].
const RANGE_POINTS: usize = 400;

impl MusclePair {
    /// A leg's two pairs, hip then knee, from its four muscles.
    pub fn of_leg(muscles: &[MuscleActuator], pressure_max_pa: f64) -> Result<[Self; 2], LegError> {
        Ok([
            Self::new(muscles, 0, pressure_max_pa)?,
            Self::new(muscles, 1, pressure_max_pa)?,
        ])
    }

    /// The pair on joint `joint` of a leg's four muscles.
    pub fn new(
        muscles: &[MuscleActuator],
        joint: usize,
        pressure_max_pa: f64,
    ) -> Result<Self, LegError> {
        let find = |side: Side| {
            muscles
                .iter()
                .position(|m| m.joint == joint && m.geometry.side == side)
                .ok_or_else(|| LegError::Muscle {
                    muscle: format!("joint {joint}"),
                    message: format!("has no {side:?} (impedance needs a pair on each joint)")
                        .to_lowercase(),
                })
        };
        let indices = [find(Side::Flexor)?, find(Side::Extensor)?];
        let muscles = indices.map(|i| {
            let m = &muscles[i];
            PairMuscle {
                arm_m: m.geometry.moment_arm_m(),
                contraction_at_zero_m: m.geometry.contraction_at_zero_m,
                model: m.assumed_model(),
            }
        });
        Ok(Self {
            joint,
            muscles,
            indices,
            pressure_max_pa,
        })
    }

    /// Joint stiffness (N m/rad) at pressures `[flexor, extensor]` and angle `q`.
    pub fn stiffness(&self, p: [f64; 2], q_rad: f64) -> f64 {
        self.muscles[0].stiffness(p[0], q_rad) + self.muscles[1].stiffness(p[1], q_rad)
    }

    /// Static joint torque (N m, flexion positive) at pressures `p` and angle `q`.
    pub fn torque(&self, p: [f64; 2], q_rad: f64) -> f64 {
        self.muscles[0].arm_m * self.muscles[0].force(p[0], q_rad)
            + self.muscles[1].arm_m * self.muscles[1].force(p[1], q_rad)
    }

    /// The muscles' own joint damping (N m s/rad) at pressures `p`.
    pub fn damping(&self, p: [f64; 2]) -> f64 {
        self.muscles[0].damping(p[0]) + self.muscles[1].damping(p[1])
    }

    /// Pressures `[flexor, extensor]` (Pa, not clamped) at which the pair has stiffness
    /// `stiffness` and holds `torque` at angle `q`: Newton's method on the two equations
    /// (exact in one step for eq. (1) muscles, whose stiffness and torque are affine in the
    /// pressures). `None` if the equations are singular there.
    pub fn pressures_for(&self, stiffness: f64, torque: f64, q_rad: f64) -> Option<[f64; 2]> {
        const DP: f64 = 1e3;
        let mut p = [0.5 * self.pressure_max_pa; 2];
        for _ in 0..6 {
            let r = [
                self.stiffness(p, q_rad) - stiffness,
                self.torque(p, q_rad) - torque,
            ];
            let d = |i: usize| {
                let mut q = p;
                q[i] += DP;
                [
                    (self.stiffness(q, q_rad) - stiffness - r[0]) / DP,
                    (self.torque(q, q_rad) - torque - r[1]) / DP,
                ]
            };
            let (c0, c1) = (d(0), d(1));
            let det = c0[0] * c1[1] - c1[0] * c0[1];
            if !det.is_finite() || det.abs() < 1e-30 {
                return None;
            }
            let step = [
                (r[0] * c1[1] - c1[0] * r[1]) / det,
                (c0[0] * r[1] - r[0] * c0[1]) / det,
            ];
            p = [p[0] - step[0], p[1] - step[1]];
            if step[0].abs() + step[1].abs() < 1e-3 {
                break;
            }
        }
        p.iter().all(|v| v.is_finite()).then_some(p)
    }

    /// Whether pressures `p` are within the valve's range with both muscles pulling at `q`.
    fn feasible(&self, p: [f64; 2], q_rad: f64) -> bool {
        p.iter().all(|&v| (0.0..=self.pressure_max_pa).contains(&v))
            && self.muscles[0].force(p[0], q_rad) > 0.0
            && self.muscles[1].force(p[1], q_rad) > 0.0
    }

    /// The stiffness the pair reaches while holding `torque` at angle `q`: a scan of the
    /// pressure sum, each point's difference solved for the torque. `None` if no pressures
    /// within the valve's range hold that torque with both muscles pulling.
    pub fn stiffness_range(&self, torque: f64, q_rad: f64) -> Option<StiffnessRange> {
        let mut range: Option<StiffnessRange> = None;
        for i in 0..=RANGE_POINTS {
            let mean = self.pressure_max_pa * i as f64 / RANGE_POINTS as f64;
            let Some(p) = self.pressures_for_mean(mean, torque, q_rad) else {
                continue;
            };
            if !self.feasible(p, q_rad) {
                continue;
            }
            let k = self.stiffness(p, q_rad);
            range = Some(match range {
                None => StiffnessRange {
                    min_nm_per_rad: k,
                    max_nm_per_rad: k,
                },
                Some(r) => StiffnessRange {
                    min_nm_per_rad: r.min_nm_per_rad.min(k),
                    max_nm_per_rad: r.max_nm_per_rad.max(k),
                },
            });
        }
        range
    }

    /// Pressures of mean `mean` holding `torque` at `q` (bisection on the difference, the
    /// torque rising with it).
    fn pressures_for_mean(&self, mean: f64, torque: f64, q_rad: f64) -> Option<[f64; 2]> {
        let at = |d: f64| [mean + 0.5 * d, mean - 0.5 * d];
        let (mut lo, mut hi) = (-2.0 * self.pressure_max_pa, 2.0 * self.pressure_max_pa);
        if (self.torque(at(lo), q_rad) - torque) * (self.torque(at(hi), q_rad) - torque) > 0.0 {
            return None;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.torque(at(mid), q_rad) < torque {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(at(0.5 * (lo + hi)))
    }

    /// The stiffness `set` asks of this pair (its default: the middle of the range at
    /// rest), checked against what the pair reaches standing (the rest pose, no torque);
    /// out of reach is an error naming the field.
    pub fn resolve(&self, set: JointImpedance) -> Result<f64, LegError> {
        let name = crate::exoskeleton::JOINT_NAMES[self.joint];
        let field = format!("control.impedance.{name}.stiffness_nm_per_rad");
        let Some(range) = self.stiffness_range(0.0, 0.0) else {
            return Err(LegError::Unreachable {
                name: field,
                value: set.stiffness_nm_per_rad.unwrap_or(f64::NAN),
                message: format!(
                    "the {name}'s muscles cannot hold the rest pose within the valve's range"
                ),
            });
        };
        let k = set
            .stiffness_nm_per_rad
            .unwrap_or(0.5 * (range.min_nm_per_rad + range.max_nm_per_rad));
        if !(range.min_nm_per_rad..=range.max_nm_per_rad).contains(&k) {
            return Err(LegError::Unreachable {
                name: field,
                value: k,
                message: format!(
                    "the {name}'s muscles reach {:.1}..={:.1} N m/rad at rest by co-contraction (`pma-exo impedance SCENARIO` shows the ranges)",
                    range.min_nm_per_rad, range.max_nm_per_rad
                ),
            });
        }
        Ok(k)
    }
}

/// Where in its range a pressure-set mode without a stiffness set point holds each pair:
/// near its softest at rest, with room for the torques.
const SOFT_SHARE: f64 = 0.15;

/// The weight a stance leg carries on a treadmill, as the joint torques that hold it: the
/// belt's share of the system's weight, `(1 - bws) m g`, pushing up at the ankle, all of it
/// on a leg in single support and passed linearly from the trailing to the leading leg over
/// double support (the two legs' shares always sum to one; while the start-up stands, half
/// each). A feedforward from the reference's timing: the trainer measures no ground
/// reaction.
#[derive(Debug, Clone)]
pub struct StanceLoad {
    chain: crate::ground::SagittalChain,
    mass_kg: f64,
    support: crate::ground::TreadmillSettings,
    toe_off: f64,
}

impl StanceLoad {
    /// The share of `mass_kg`'s weight that `support`'s harness leaves to the legs (at
    /// each instant: a start's support lowered over a window is followed), carried by legs
    /// of `chain`'s geometry whose stance ends at `toe_off` (phase, 0.5-1).
    pub fn new(
        chain: crate::ground::SagittalChain,
        mass_kg: f64,
        support: crate::ground::TreadmillSettings,
        toe_off: f64,
    ) -> Self {
        Self {
            chain,
            mass_kg,
            support,
            toe_off,
        }
    }

    /// The weight the legs carry together `t_s` after the start (N).
    pub fn load_n(&self, t_s: f64) -> f64 {
        (1.0 - self.support.support_fraction_at(t_s)) * self.mass_kg * pma_model::GRAVITY_M_S2
    }

    /// The share of the load on a leg at `phase` of its cycle (0-1).
    pub fn share(&self, phase: f64) -> f64 {
        let double = (self.toe_off - 0.5).max(1e-9);
        match phase {
            p if p < double => p / double,
            p if p < 0.5 => 1.0,
            p if p < self.toe_off => 1.0 - (p - 0.5) / double,
            _ => 0.0,
        }
    }

    /// Hip and knee torques (N m, flexion positive) that hold `share` of the load at
    /// `t_s` up at the ankle at hip and knee angles `q` (rad): `-J^T F` with `J` the
    /// ankle's height per joint angle.
    pub fn torques_nm(&self, q: [f64; 2], share: f64, t_s: f64) -> [f64; 2] {
        let f = share * self.load_n(t_s);
        if f == 0.0 {
            return [0.0; 2];
        }
        let [d_hip, d_knee] = self.chain.ankle_jacobian([q[0], q[1], 0.0]);
        [-d_hip[1] * f, -d_knee[1] * f]
    }
}

/// The joint moments the plan leaves to a walking patient: the adults' mean moments at
/// the leg's reference phase, times the share of them expected
/// ([`ImpedanceSettings::patient_moment_share`]), the walking start's ramp and, while the
/// harness lowers a start's support, the share of the weight the legs carry: the torque
/// an active patient of `own_torque = "walking"` produces on the reference's clock.
#[derive(Debug, Clone)]
pub struct ExpectedMoments {
    /// Hip and knee moments (N m, flexion positive) at 0, 1, ..., 100 % of the cycle,
    /// the share already applied.
    moments_nm: [Vec<f64>; 2],
    support: crate::ground::TreadmillSettings,
}

impl ExpectedMoments {
    /// `share` of walking's moments `moments_nm` (N m at 0, 1, ..., 100 % of the cycle,
    /// for the legs' share of the weight under `support`'s constant support).
    pub fn new(
        moments_nm: [Vec<f64>; 2],
        share: f64,
        support: crate::ground::TreadmillSettings,
    ) -> Self {
        Self {
            moments_nm: moments_nm.map(|c| c.into_iter().map(|m| share * m).collect()),
            support,
        }
    }

    /// Hip and knee moments (N m) expected of the patient at `t_s`, with `gait` at its
    /// time `clock_s` (the harness's support follows `t_s`).
    pub fn torques_nm(
        &self,
        gait: &crate::gait::GaitReference,
        clock_s: f64,
        t_s: f64,
    ) -> [f64; 2] {
        let scale = gait.ramp_share(clock_s) * self.support.legs_share_at(t_s);
        let phase = gait.phase(clock_s);
        self.moments_nm
            .each_ref()
            .map(|c| scale * crate::gait::sample_cycle(c, phase))
    }
}

/// One leg's law in every mode that sets the pairs' pressures (impedance, path,
/// transparent): two pairs, their set points and the leg's rigid model.
#[derive(Debug, Clone)]
pub struct ImpedanceLaw {
    mode: ControlMode,
    pairs: [MusclePair; 2],
    settings: ImpedanceSettings,
    path: PathSettings,
    tunnel: Option<Tunnel>,
    /// The tunnel's last nearest segment.
    tunnel_hint: usize,
    /// The model whose dynamics the law carries (the leg's or the frames').
    carried: LegInertia,
    /// Each pair's stiffness in path and transparent modes (N m/rad).
    soft_nm_per_rad: [f64; 2],
    /// Each joint's stiffness (N m/rad), defaults resolved.
    stiffness_nm_per_rad: [f64; 2],
    velocity_rad_s: [f64; 2],
    last_rad: Option<[f64; 2]>,
    commands_pa: [f64; 4],
    /// The learned feedforward (impedance mode with `[control.impedance.learning]`).
    learning: Option<StrideLearning>,
}

impl ImpedanceLaw {
    /// The law of `sc`'s mode for a leg of four muscles on `gait`, each set point checked
    /// against its pair's reach.
    pub fn new(
        sc: &crate::Scenario,
        muscles: &[MuscleActuator],
        inertia: &LegInertia,
        gait: &crate::gait::GaitReference,
    ) -> Result<Self, LegError> {
        let settings = sc.control.impedance;
        let pressure_max_pa = sc.plant.valve.pressure_max_pa;
        settings.validate()?;
        sc.control.path.validate()?;
        let pairs = MusclePair::of_leg(muscles, pressure_max_pa)?;
        let stiffness_nm_per_rad = [
            pairs[0].resolve(settings.hip)?,
            pairs[1].resolve(settings.knee)?,
        ];
        let soft = |p: &MusclePair| {
            p.stiffness_range(0.0, 0.0).map_or(f64::NAN, |r| {
                r.min_nm_per_rad + SOFT_SHARE * (r.max_nm_per_rad - r.min_nm_per_rad)
            })
        };
        let carried = match sc.control.compensation {
            Compensation::Leg => *inertia,
            Compensation::Device => inertia.frames(),
        };
        Ok(Self {
            mode: sc.control.mode,
            pairs,
            settings,
            path: sc.control.path,
            tunnel: (sc.control.mode == ControlMode::Path)
                .then(|| Tunnel::new(gait, sc.control.path.width_deg)),
            tunnel_hint: 0,
            carried,
            soft_nm_per_rad: [soft(&pairs[0]), soft(&pairs[1])],
            stiffness_nm_per_rad,
            velocity_rad_s: [0.0; 2],
            last_rad: None,
            commands_pa: [0.0; 4],
            learning: settings
                .learning
                .filter(|_| sc.control.mode == ControlMode::Impedance)
                .map(StrideLearning::new),
        })
    }

    /// The mode the law runs.
    pub fn mode(&self) -> ControlMode {
        self.mode
    }

    /// The joints' pairs (hip, knee).
    pub fn pairs(&self) -> &[MusclePair; 2] {
        &self.pairs
    }

    /// Each joint's stiffness set point (N m/rad), defaults resolved.
    pub fn stiffness_nm_per_rad(&self) -> [f64; 2] {
        self.stiffness_nm_per_rad
    }

    /// Restarts the velocity estimate at rest, from the valves' present commands.
    pub fn reset(&mut self, commands_pa: [f64; 4]) {
        self.velocity_rad_s = [0.0; 2];
        self.last_rad = None;
        self.commands_pa = commands_pa;
    }

    /// The last commands the valves took (the damping estimate's pressures).
    pub fn applied(&mut self, commands_pa: [f64; 4]) {
        self.commands_pa = commands_pa;
    }

    fn estimate_velocity(&mut self, q: [f64; 2], dt_s: f64) {
        if let Some(last) = self.last_rad {
            let a = dt_s / (self.settings.velocity_filter_s + dt_s);
            for j in 0..2 {
                let raw = (q[j] - last[j]) / dt_s;
                self.velocity_rad_s[j] += a * (raw - self.velocity_rad_s[j]);
            }
        }
        self.last_rad = Some(q);
    }

    /// The four pressure commands (Pa, within the valve's range) for reference `g` at
    /// measured angles `q` (rad).
    /// `load_nm` is what the leg carries besides its own dynamics (a stance leg's share of
    /// the weight, [`StanceLoad`]; impedance mode only).
    /// `phase` is the leg's phase in its stride (0-1), `None` while it stands or holds a
    /// pose: the learned feedforward ([`StrideLearning`]) learns only while it walks.
    pub fn update(
        &mut self,
        g: &GaitSample,
        q: [f64; 2],
        load_nm: [f64; 2],
        phase: Option<f64>,
        dt_s: f64,
    ) -> [f64; 4] {
        self.estimate_velocity(q, dt_s);
        if self.mode != ControlMode::Impedance {
            return self.update_soft(q);
        }
        let q_ref = [g.hip.angle_rad, g.knee.angle_rad];
        let qd_ref = [g.hip.velocity_rad_s, g.knee.velocity_rad_s];
        let qdd_ref = [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2];
        let dynamics = self.carried.inverse_dynamics(q, qd_ref, qdd_ref);
        let learned = self.learned_nm(phase, [q_ref[0] - q[0], q_ref[1] - q[1]]);
        let feedforward = [0, 1].map(|j| dynamics[j] + load_nm[j] + learned[j]);
        let mut out = self.commands_pa;
        for pair in &self.pairs {
            let j = pair.joint;
            let set = self.settings.joint(j);
            let held = [
                self.commands_pa[pair.indices[0]],
                self.commands_pa[pair.indices[1]],
            ];
            let own = pair.damping(held);
            let extra = (set.damping_nm_s_per_rad - own).max(0.0);
            let torque =
                feedforward[j] + own * qd_ref[j] + extra * (qd_ref[j] - self.velocity_rad_s[j]);
            let p = pair
                .pressures_for(self.stiffness_nm_per_rad[j], torque, q_ref[j])
                .unwrap_or(held);
            for (k, &i) in pair.indices.iter().enumerate() {
                out[i] = p[k].clamp(0.0, pair.pressure_max_pa);
            }
        }
        out
    }

    /// The learned feedforward at `phase` after taking in `error_rad` (zero without
    /// learning; held, not updated, while the leg does not walk).
    fn learned_nm(&mut self, phase: Option<f64>, error_rad: [f64; 2]) -> [f64; 2] {
        let Some(l) = &mut self.learning else {
            return [0.0; 2];
        };
        match phase {
            Some(phase) => l.update(phase, error_rad, self.stiffness_nm_per_rad),
            None => {
                l.pause();
                [0.0; 2]
            }
        }
    }

    /// Path and transparent modes: the pairs at their soft stiffness, holding at the
    /// measured pose the carried model's weight, the muscles' own damping cancelled, and
    /// in path mode the tunnel's wall and the support along the path.
    fn update_soft(&mut self, q: [f64; 2]) -> [f64; 4] {
        let mut torque = self.carried.inverse_dynamics(q, [0.0; 2], [0.0; 2]);
        if let Some(t) = &self.tunnel {
            let at = t.locate_near(q, &mut self.tunnel_hint);
            let beyond = at.distance_rad - t.width_rad();
            if beyond > 0.0 && at.distance_rad > 0.0 {
                for (j, tau) in torque.iter_mut().enumerate() {
                    *tau -= self.path.wall_nm_per_rad * beyond * at.offset_rad[j] / at.distance_rad;
                }
            }
            for (j, tau) in torque.iter_mut().enumerate() {
                *tau += self.path.support_nm * at.tangent[j];
            }
        }
        let mut out = self.commands_pa;
        for pair in &self.pairs {
            let j = pair.joint;
            let held = [
                self.commands_pa[pair.indices[0]],
                self.commands_pa[pair.indices[1]],
            ];
            let tau = torque[j] + pair.damping(held) * self.velocity_rad_s[j];
            let p = pair
                .pressures_for(self.soft_nm_per_rad[j], tau, q[j])
                .unwrap_or(held);
            for (k, &i) in pair.indices.iter().enumerate() {
                out[i] = p[k].clamp(0.0, pair.pressure_max_pa);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pma_model::MuscleParams;

    /// The trainer's stance load: 500 N on legs whose stance ends at 0.675.
    fn stance_load() -> StanceLoad {
        let loaded = crate::Scenario::load("gait_treadmill").expect("embedded");
        let exo =
            crate::sim::build_exo(&loaded, crate::exoskeleton::Mount::default()).expect("trainer");
        let ground = exo.ground().expect("a treadmill");
        let mut support = *ground.settings();
        support.bws_fraction = 0.0;
        StanceLoad::new(
            ground.chain().clone(),
            500.0 / pma_model::GRAVITY_M_S2,
            support,
            0.675,
        )
    }

    #[test]
    fn learning_on_a_spring_converges_to_the_error_its_forgetting_leaves() {
        // A spring of stiffness K under a disturbance d(phase): e = (d - F) / K. Per phase,
        // F(i+1) = f F(i) + gain K e(i) = (f - gain) F(i) + gain d, which settles at
        // F = gain d / (1 - f + gain): the error falls to (1 - f) / (1 - f + gain) of d / K.
        let (gain, forgetting) = (0.5, 0.9);
        let k = [100.0, 20.0];
        let d = |phase: f64| {
            let w = std::f64::consts::TAU * phase;
            [10.0 * w.sin(), 5.0 * w.cos()]
        };
        let mut l = StrideLearning::new(LearningSettings { gain, forgetting });
        let periods = 1000;
        let mut sq = [[0.0; 2]; 2];
        for stride in 0..60 {
            for n in 0..periods {
                let phase = n as f64 / periods as f64;
                let x = phase * LEARNING_BINS as f64;
                let f = l.at(x);
                let e = [0, 1].map(|j| (d(phase)[j] - f[j]) / k[j]);
                l.update(phase, e, k);
                if stride == 59 {
                    for j in 0..2 {
                        sq[j][0] += e[j] * e[j];
                        sq[j][1] += (d(phase)[j] / k[j]).powi(2);
                    }
                }
            }
        }
        let expected = (1.0 - forgetting) / (1.0 - forgetting + gain);
        for (j, [e, unlearned]) in sq.iter().enumerate() {
            let ratio = (e / unlearned).sqrt();
            assert!(
                (ratio / expected - 1.0).abs() < 0.05,
                "joint {j}: error {ratio:.4} of the unlearned, expected {expected:.4}"
            );
        }
    }

    #[test]
    fn a_moment_share_out_of_range_is_refused_naming_the_leg_and_a_leg_takes_its_own() {
        let mut s = ImpedanceSettings {
            patient_moment_share: 1.5,
            ..ImpedanceSettings::default()
        };
        let e = s.validate().expect_err("refused").to_string();
        assert!(e.contains("control.impedance.patient_moment_share"), "{e}");
        s.patient_moment_share = 1.0;
        s.patient_moment_share_by_leg = Some([1.0, -0.2]);
        let e = s.validate().expect_err("refused").to_string();
        assert!(
            e.contains("patient_moment_share_by_leg[1] (left)") && !e.contains('\n'),
            "{e}"
        );
        s.patient_moment_share_by_leg = Some([1.0, 0.4]);
        assert!(s.validate().is_ok());
        assert_eq!(
            [s.patient_moment_share(0), s.patient_moment_share(1)],
            [1.0, 0.4]
        );
    }

    #[test]
    fn learning_that_would_diverge_is_refused_naming_the_field() {
        let mut s = ImpedanceSettings::default();
        for (gain, forgetting, field) in [
            (1.95, 0.9, "control.impedance.learning.gain"),
            (-0.1, 0.9, "control.impedance.learning.gain"),
            (0.5, 1.2, "control.impedance.learning.forgetting"),
        ] {
            s.learning = Some(LearningSettings { gain, forgetting });
            let e = s.validate().expect_err("refused").to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
        s.learning = Some(LearningSettings {
            gain: 1.0,
            forgetting: 0.95,
        });
        assert!(s.validate().is_ok());
    }

    #[test]
    fn the_stance_load_follows_a_start_support_as_the_harness_lowers_it() {
        // 80 % carried until 1 s, lowered to 30 % by 2 s: the legs carry 20 % of the
        // weight, then 70 %, and the harness's quintic in between.
        let mut s = stance_load();
        s.support.bws_fraction = 0.3;
        s.support.bws_start_fraction = Some(0.8);
        s.support.bws_release_s = [1.0, 2.0];
        let weight = 500.0;
        for (t_s, legs) in [(0.0, 0.2), (1.0, 0.2), (1.5, 0.45), (2.0, 0.7), (9.0, 0.7)] {
            let load = s.load_n(t_s);
            assert!((load - legs * weight).abs() < 1e-9, "{t_s} s: {load} N");
        }
    }

    #[test]
    fn the_two_legs_carry_the_whole_load_between_them_at_every_phase() {
        let s = stance_load();
        for k in 0..1000 {
            let phase = k as f64 / 1000.0;
            let (a, b) = (s.share(phase), s.share((phase + 0.5) % 1.0));
            assert!((0.0..=1.0).contains(&a), "{phase}: {a}");
            assert!((a + b - 1.0).abs() < 1e-12, "{phase}: {a} + {b}");
        }
        assert_eq!(s.share(0.3), 1.0);
        assert_eq!(s.share(0.8), 0.0);
    }

    #[test]
    fn a_stance_load_is_the_vertical_force_times_its_horizontal_lever() {
        // Each joint turns the chain below it about its centre: the vertical force's moment
        // about a joint is the force times the ankle's fore-aft distance from it.
        let s = stance_load();
        let c = &s.chain;
        let f = 0.8 * 500.0;
        for q in [[0.1, 0.1], [0.4, 0.2], [-0.05, 0.6]] {
            let tau = s.torques_nm(q, 0.8, 0.0);
            let ankle = c.ankle_centre([q[0], q[1], 0.0]);
            let hip = c.origins_m[0];
            let (sin, cos) = (c.pitch_rad[0] + c.flexion_sign[0] * q[0]).sin_cos();
            let o = c.origins_m[1];
            let knee_x = hip[0] + o[0] * cos - o[1] * sin;
            let expected = [
                -c.flexion_sign[0] * (ankle[0] - hip[0]) * f,
                -c.flexion_sign[1] * (ankle[0] - knee_x) * f,
            ];
            for j in 0..2 {
                assert!(
                    (tau[j] - expected[j]).abs() < 1e-5,
                    "{q:?}: {tau:?} vs {expected:?}"
                );
            }
        }
        assert_eq!(s.torques_nm([0.3, 0.3], 0.0, 0.0), [0.0; 2]);
    }

    /// A pair of Table I muscles on pulleys of 15 mm, 30 mm contracted at zero angle.
    fn table_i_pair() -> MusclePair {
        let muscle = |arm_m: f64| PairMuscle {
            arm_m,
            contraction_at_zero_m: 0.03,
            model: MuscleModel::ThreeElement(MuscleParams::TABLE_I),
        };
        MusclePair {
            joint: 0,
            muscles: [muscle(0.015), muscle(-0.015)],
            indices: [0, 1],
            pressure_max_pa: 6e5,
        }
    }

    #[test]
    fn an_eq1_pairs_stiffness_is_r_squared_times_the_sum_of_its_springs() {
        let pair = table_i_pair();
        let t = MuscleParams::TABLE_I;
        for (pf, pe, q) in [(1e5, 4e5, 0.0), (3e5, 3e5, 0.3), (5.5e5, 0.5e5, -0.2)] {
            let analytic = 0.015f64.powi(2) * (t.stiffness(pf) + t.stiffness(pe));
            let k = pair.stiffness([pf, pe], q);
            assert!((k / analytic - 1.0).abs() < 1e-9, "{k} against {analytic}");
        }
    }

    #[test]
    fn the_pressures_solved_give_the_stiffness_and_torque_asked() {
        let pair = table_i_pair();
        for (k, tau, q) in [(9.0, 0.0, 0.0), (10.0, 5.0, 0.2), (8.8, -4.0, -0.3)] {
            let p = pair.pressures_for(k, tau, q).expect("a solution");
            assert!((pair.stiffness(p, q) - k).abs() < 1e-6, "{p:?}");
            assert!((pair.torque(p, q) - tau).abs() < 1e-6, "{p:?}");
        }
    }

    #[test]
    fn the_stiffness_range_grows_with_the_pressure_sum_and_ends_at_the_valves_limit() {
        let pair = table_i_pair();
        let r = pair.stiffness_range(0.0, 0.0).expect("a range");
        let t = MuscleParams::TABLE_I;
        // Both at 6 bar is the stiffest; the softest has both muscles just pulling.
        let top = 2.0 * 0.015f64.powi(2) * t.stiffness(6e5);
        assert!(
            (r.max_nm_per_rad / top - 1.0).abs() < 0.01,
            "{r:?} against {top}"
        );
        assert!(r.min_nm_per_rad < r.max_nm_per_rad);
        assert!(r.min_nm_per_rad >= 2.0 * 0.015f64.powi(2) * t.k0_n_per_m);
        // A torque narrows it: one muscle has to pull harder than the other.
        let loaded = pair.stiffness_range(20.0, 0.0).expect("a range");
        assert!(loaded.max_nm_per_rad < r.max_nm_per_rad);
    }

    #[test]
    fn the_tunnel_locates_a_pose_on_and_off_the_path() {
        let gait = crate::gait::GaitReference::adult(0.5, 1.6, 1.6).unwrap();
        let tunnel = Tunnel::new(&gait, 5.0);
        let g = gait.sample(1.6 + 1.6 + 0.4);
        let on = [g.hip.angle_rad, g.knee.angle_rad];
        let at = tunnel.locate(on);
        assert!(at.distance_rad < 1e-3, "{at:?}");
        let t = at.tangent;
        assert!((t[0].hypot(t[1]) - 1.0).abs() < 1e-9);
        // Moved off along the normal by 0.05 rad: that far from the path (the path
        // bends, so no nearer than that and not much farther).
        let off = [on[0] - 0.05 * t[1], on[1] + 0.05 * t[0]];
        let d = tunnel.locate(off).distance_rad;
        assert!(d <= 0.05 + 1e-9 && d > 0.03, "{d}");
    }

    #[test]
    fn the_local_search_finds_what_the_full_scan_finds_along_a_gait() {
        let gait = crate::gait::GaitReference::adult(0.5, 1.6, 1.6).unwrap();
        let tunnel = Tunnel::new(&gait, 5.0);
        let mut hint = 0;
        for k in 0..4000 {
            // A leg a little off the path, a millisecond per step, over two strides, now
            // inside the 5-degree tunnel (0.087 rad), now beyond it.
            let g = gait.sample(3.2 + k as f64 * 1e-3);
            let off = if (k / 500) % 2 == 0 { 0.02 } else { 0.3 };
            let q = [g.hip.angle_rad + off, g.knee.angle_rad - 0.01];
            let near = tunnel.locate_near(q, &mut hint);
            let full = tunnel.locate(q);
            // Inside the tunnel, what matters is that it is inside; beyond it, the push.
            let width = tunnel.width_rad();
            assert_eq!(
                near.distance_rad <= width,
                full.distance_rad <= width,
                "step {k}"
            );
            if full.distance_rad > width {
                assert_eq!(near.offset_rad, full.offset_rad, "step {k}");
            }
        }
    }

    #[test]
    fn bad_path_settings_name_their_field() {
        for (s, field) in [
            (
                PathSettings {
                    width_deg: -1.0,
                    ..PathSettings::default()
                },
                "control.path.width_deg",
            ),
            (
                PathSettings {
                    width_deg: 45.0,
                    ..PathSettings::default()
                },
                "control.path.width_deg",
            ),
            (
                PathSettings {
                    wall_nm_per_rad: -3.0,
                    ..PathSettings::default()
                },
                "control.path.wall_nm_per_rad",
            ),
            (
                PathSettings {
                    support_nm: f64::NAN,
                    ..PathSettings::default()
                },
                "control.path.support_nm",
            ),
        ] {
            let e = s.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }

    #[test]
    fn bad_set_points_name_their_field() {
        let mut s = ImpedanceSettings::default();
        s.knee.stiffness_nm_per_rad = Some(-5.0);
        let e = s.validate().unwrap_err().to_string();
        assert!(
            e.contains("control.impedance.knee.stiffness_nm_per_rad"),
            "{e}"
        );
        let mut s = ImpedanceSettings::default();
        s.hip.damping_nm_s_per_rad = f64::NAN;
        let e = s.validate().unwrap_err().to_string();
        assert!(
            e.contains("control.impedance.hip.damping_nm_s_per_rad"),
            "{e}"
        );
        let pair = table_i_pair();
        let e = pair
            .resolve(JointImpedance {
                stiffness_nm_per_rad: Some(200.0),
                damping_nm_s_per_rad: 0.0,
            })
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control.impedance.hip.stiffness_nm_per_rad = 200 is out of reach"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}
