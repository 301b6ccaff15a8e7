//! A muscle on a leg: its geometry, the true model that moves the plant, its valve and
//! what its controller assumes.
use crate::plant::{leg_label, MuscleGeometry};
use pma_model::{MuscleModel, Valve};

/// A muscle on a leg: geometry, the true three-element model and its valve.
#[derive(Debug, Clone)]
pub struct MuscleActuator {
    /// Geometry.
    pub geometry: MuscleGeometry,
    /// The leg it is on (0 right, 1 left).
    pub leg: usize,
    /// Its place among its leg's four muscles (the geometry file's order).
    pub index: usize,
    /// Joint index (0 hip, 1 knee).
    pub joint: usize,
    /// True muscle: eq. (1), or a Festo size as measured.
    pub model: MuscleModel,
    /// Rated pulling force (N): the Festo size's, or for an eq. (1) muscle Table I's own at
    /// the valve's limit (`plant.muscle_rated_force_n` overrides it).
    pub rated_force_n: f64,
    /// Where the rating comes from, as outputs say it.
    pub rating: String,
    pub(crate) valve: Valve,
}

impl MuscleActuator {
    /// The eq. (1) muscle its controller assumes: Table I for an eq. (1) muscle (its
    /// deviations from Table I are the plant's, unknown to the controller), the map's fit
    /// for a Festo muscle (its size is known; how far it is off its datasheet is not).
    pub fn assumed(&self) -> pma_model::MuscleParams {
        match self.model {
            MuscleModel::ThreeElement(_) => pma_model::MuscleParams::TABLE_I,
            MuscleModel::Festo(f) => f.nominal().three_element_fit(),
        }
    }

    /// The muscle its model-based laws assume, in its own form: Table I for an eq. (1)
    /// muscle, the measured map for a Festo size (impedance by co-contraction needs the
    /// map's slope, which the eq. (1) fit of [`MuscleActuator::assumed`] flattens).
    pub fn assumed_model(&self) -> MuscleModel {
        match self.model {
            MuscleModel::ThreeElement(_) => {
                MuscleModel::ThreeElement(pma_model::MuscleParams::TABLE_I)
            }
            MuscleModel::Festo(f) => MuscleModel::Festo(f.nominal()),
        }
    }

    /// Contraction (m) at its leg's joint angles `q`.
    pub fn contraction(&self, q: [f64; 2]) -> f64 {
        self.geometry.contraction(q[self.joint])
    }

    /// Contraction rate (m/s).
    pub fn contraction_rate(&self, qd: [f64; 2]) -> f64 {
        self.geometry.moment_arm_m() * qd[self.joint]
    }

    /// Eq. (1) force without the slack clamp (N): negative means slack.
    pub fn force_unclamped(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.model.force_unclamped(
            self.valve.pressure(),
            self.contraction(q),
            self.contraction_rate(qd),
            self.valve.mode(),
        )
    }

    /// Pulling force (N).
    pub fn force(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.force_unclamped(q, qd).max(0.0)
    }

    /// Joint torque (N m, flexion positive).
    pub fn torque(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.torque_of(self.force_unclamped(q, qd))
    }

    /// Joint torque (N m) of an unclamped force `force_unclamped_n` (N,
    /// [`MuscleActuator::force_unclamped`]'s): a slack muscle's is zero.
    pub fn torque_of(&self, force_unclamped_n: f64) -> f64 {
        self.geometry.moment_arm_m() * force_unclamped_n.max(0.0)
    }

    /// Muscle pressure (Pa).
    pub fn pressure(&self) -> f64 {
        self.valve.pressure()
    }

    /// The valve's last set point (Pa).
    pub fn set_point(&self) -> f64 {
        self.valve.set_point()
    }

    /// Its name as outputs show it: the geometry's, prefixed by the leg's side on a
    /// two-leg trainer (`left/hip_flexor`).
    pub fn label(&self, legs: usize) -> String {
        leg_label(legs, self.leg, &self.geometry.name)
    }
}

impl MuscleActuator {
    /// Its place among its leg's four muscles.
    pub fn index_in_leg(&self) -> usize {
        self.index
    }

    /// Its anchor in its body link's frame (m): the geometry's on the right leg, mirrored
    /// about the pelvis's sagittal plane (Y) on the left.
    pub fn anchor_m(&self) -> [f64; 3] {
        let [x, y, z] = self.geometry.anchor_m;
        if self.leg % 2 == 1 {
            [x, -y, z]
        } else {
            [x, y, z]
        }
    }
}
