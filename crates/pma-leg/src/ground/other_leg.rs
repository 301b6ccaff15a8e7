use crate::ground::{ContactParams, SagittalChain};

/// The virtual other leg: the reference half a stride later, rigid, its ankle at neutral,
/// on the belt.
#[derive(Debug, Clone)]
pub(crate) struct OtherLeg {
    /// The reference half a stride later, shifted once here rather than at every substep.
    later: crate::gait::GaitReference,
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
            later: gait.for_leg(1),
            hold: None,
            chain,
            previous_z: vec![f64::NAN; n],
        }
    }

    /// Its joint angles at `t_s` (rad).
    pub(crate) fn pose(&self, t_s: f64) -> [f64; 2] {
        self.hold.unwrap_or_else(|| self.later.angles_rad(t_s))
    }

    /// Upward force (N) on a pelvis whose frame is at height `z_m` above the belt, rising at
    /// `vz_m_s`, at time `t_s` after a substep of `h_s`.
    pub(crate) fn force(
        &mut self,
        params: &ContactParams,
        t_s: f64,
        h_s: f64,
        z_m: f64,
        vz_m_s: f64,
    ) -> f64 {
        let q = self.pose(t_s);
        let rotations = self.chain.rotations([q[0], q[1], 0.0]);
        let mut total = 0.0;
        for (i, s) in self.chain.spheres.iter().enumerate() {
            let cz = self.chain.sphere_centre_at(i, &rotations)[1];
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
