/// Where in its range a pressure-set mode without a stiffness set point holds each pair:
/// near its softest at rest, with room for the torques.
pub(crate) const SOFT_SHARE: f64 = 0.15;

/// The weight a stance leg carries on a treadmill, as the joint torques that hold it: the
/// belt's share of the system's weight, `(1 - bws) m g`, pushing up at the ankle, all of it
/// on a leg in single support and passed linearly from the trailing to the leading leg over
/// double support (the two legs' shares always sum to one; while the start-up stands, half
/// each). A feedforward from the reference's timing: the trainer measures no ground
/// reaction.
#[derive(Debug, Clone)]
pub struct StanceLoad {
    pub(crate) chain: crate::ground::SagittalChain,
    mass_kg: f64,
    pub(crate) support: crate::ground::TreadmillSettings,
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
