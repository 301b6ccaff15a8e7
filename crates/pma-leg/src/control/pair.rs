use crate::base::LegError;
use crate::control::JointImpedance;
use crate::plant::{MuscleActuator, Side};
use pma_model::{DampingMode, MuscleModel};

/// One muscle of a pair as the law models it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PairMuscle {
    /// Signed moment arm (m): contraction per radian of flexion.
    pub(crate) arm_m: f64,
    pub(crate) contraction_at_zero_m: f64,
    pub(crate) model: MuscleModel,
}

/// Step of the numerical slope of a Festo map (m): a tenth of a millimetre.
const DX_M: f64 = 1e-4;

impl PairMuscle {
    fn contraction(&self, q_rad: f64) -> f64 {
        self.contraction_at_zero_m + self.arm_m * q_rad
    }

    /// Static force (N) at pressure `p` and joint angle `q`, unclamped.
    pub(crate) fn force(&self, p: f64, q_rad: f64) -> f64 {
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
    pub(crate) joint: usize,
    /// Flexor, extensor.
    pub(crate) muscles: [PairMuscle; 2],
    /// Their places among the leg's four muscles.
    pub(crate) indices: [usize; 2],
    pub(crate) pressure_max_pa: f64,
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
            let step = crate::base::solve_2x2([[c0[0], c1[0]], [c0[1], c1[1]]], r)?;
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
        let name = crate::base::JOINT_NAMES[self.joint];
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
                    "the {name}'s muscles reach {:.1} to {:.1} N m/rad at rest by co-contraction (`pma-exo impedance SCENARIO` shows the ranges)",
                    range.min_nm_per_rad, range.max_nm_per_rad
                ),
            });
        }
        Ok(k)
    }
}
