/// Standard gravity (m/s^2), the same as the muscle bench's.
pub(crate) const G: f64 = pma_model::GRAVITY_M_S2;

/// Link inertia data read from the URDF (for the controllers' nominal models).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertia {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Distance of the centre of mass below the proximal joint (m).
    pub com_below_joint_m: f64,
    /// Inertia about the centre of mass around the flexion axis (kg m^2).
    pub inertia_kg_m2: f64,
}

/// Geometry the nominal models and the hand checks need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegInertia {
    /// Thigh.
    pub thigh: LinkInertia,
    /// Shank (with foot).
    pub shank: LinkInertia,
    /// Hip-to-knee distance (m).
    pub thigh_length_m: f64,
    /// Backward pitch of the fixed pelvis (rad, about the hip's flexion axis): 0 standing,
    /// pi/2 for a thigh lying horizontal at zero hip flexion (the seated pendulum test).
    pub pelvis_pitch_rad: f64,
}

/// Mass of the exoskeleton's thigh frame (kg): the URDFs' stated design, an aluminium bar
/// (`models/exo_leg.urdf`, `models/exo_trainer.urdf`).
pub const FRAME_THIGH_KG: f64 = 2.0;

/// Mass of its shank frame (kg).
pub const FRAME_SHANK_KG: f64 = 1.5;

/// Where each frame's centre of mass sits below its joint (m): the middle of a 0.40 m bar.
pub const FRAME_COM_M: f64 = 0.20;

impl LinkInertia {
    /// A uniform bar of `mass_kg` whose middle is `FRAME_COM_M` below its joint.
    fn frame_bar(mass_kg: f64) -> Self {
        let length = 2.0 * FRAME_COM_M;
        Self {
            mass_kg,
            com_below_joint_m: FRAME_COM_M,
            inertia_kg_m2: mass_kg * length * length / 12.0,
        }
    }

    /// This link without `part` (both about the same joint): the rest's mass, centre and
    /// inertia about its own centre (parallel axes).
    fn without(&self, part: &LinkInertia) -> Self {
        let mass_kg = self.mass_kg - part.mass_kg;
        let com = (self.mass_kg * self.com_below_joint_m - part.mass_kg * part.com_below_joint_m)
            / mass_kg;
        let about_joint =
            |l: &LinkInertia| l.inertia_kg_m2 + l.mass_kg * l.com_below_joint_m.powi(2);
        Self {
            mass_kg,
            com_below_joint_m: com,
            inertia_kg_m2: about_joint(self) - about_joint(part) - mass_kg * com * com,
        }
    }
}

impl LegInertia {
    /// The exoskeleton's own frames on this leg's geometry (the URDFs' stated design).
    pub fn frames(&self) -> Self {
        Self {
            thigh: LinkInertia::frame_bar(FRAME_THIGH_KG),
            shank: LinkInertia::frame_bar(FRAME_SHANK_KG),
            ..*self
        }
    }

    /// The patient's limb alone: this leg without the exoskeleton's frames.
    pub fn limb(&self) -> Self {
        let frames = self.frames();
        Self {
            thigh: self.thigh.without(&frames.thigh),
            shank: self.shank.without(&frames.shank),
            ..*self
        }
    }

    /// Inertia about the knee of the shank (kg m^2).
    pub fn knee_inertia(&self) -> f64 {
        let s = &self.shank;
        s.inertia_kg_m2 + s.mass_kg * s.com_below_joint_m.powi(2)
    }

    /// Inertia about the hip of the straight leg (kg m^2).
    pub fn hip_inertia(&self) -> f64 {
        let (t, s) = (&self.thigh, &self.shank);
        t.inertia_kg_m2
            + t.mass_kg * t.com_below_joint_m.powi(2)
            + s.inertia_kg_m2
            + s.mass_kg * (self.thigh_length_m + s.com_below_joint_m).powi(2)
    }

    /// Kinetic plus gravitational potential energy (J) of thigh and shank at flexion
    /// angles `q` (rad) and rates `qd` (rad/s), potential measured from the hip height.
    pub fn energy(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        let (t, s, l) = (&self.thigh, &self.shank, self.thigh_length_m);
        let (h, k, hd, kd) = (q[0] + self.pelvis_pitch_rad, q[1], qd[0], qd[1]);
        let (phi, phid) = (h - k, hd - kd);
        let thigh_ke = 0.5 * (t.inertia_kg_m2 + t.mass_kg * t.com_below_joint_m.powi(2)) * hd * hd;
        let vx = l * h.cos() * hd + s.com_below_joint_m * phi.cos() * phid;
        let vz = l * h.sin() * hd + s.com_below_joint_m * phi.sin() * phid;
        let shank_ke = 0.5 * s.mass_kg * (vx * vx + vz * vz) + 0.5 * s.inertia_kg_m2 * phid * phid;
        let pe = -G
            * (t.mass_kg * t.com_below_joint_m * h.cos()
                + s.mass_kg * (l * h.cos() + s.com_below_joint_m * phi.cos()));
        thigh_ke + shank_ke + pe
    }

    /// Gravity torques (N m, flexion positive) at hip and knee flexion `(h, k)` (rad).
    pub fn gravity_torques(&self, h: f64, k: f64) -> [f64; 2] {
        let (t, s) = (&self.thigh, &self.shank);
        let h = h + self.pelvis_pitch_rad;
        let shank_angle = h - k;
        let hip = -G
            * (t.mass_kg * t.com_below_joint_m * h.sin()
                + s.mass_kg
                    * (self.thigh_length_m * h.sin() + s.com_below_joint_m * shank_angle.sin()));
        let knee = G * s.mass_kg * s.com_below_joint_m * shank_angle.sin();
        [hip, knee]
    }

    /// The joint-space mass matrix `M(q)` (kg m^2, `[row][column]`, hip then knee) at angles
    /// `q` (rad): [`LegInertia::inverse_dynamics`]'s torques for each unit acceleration,
    /// at rest, less its torques at rest (gravity).
    pub fn mass_matrix(&self, q: [f64; 2]) -> [[f64; 2]; 2] {
        let still = self.inverse_dynamics(q, [0.0; 2], [0.0; 2]);
        let column = |j: usize| {
            let mut unit = [0.0; 2];
            unit[j] = 1.0;
            let t = self.inverse_dynamics(q, [0.0; 2], unit);
            [t[0] - still[0], t[1] - still[1]]
        };
        let (c0, c1) = (column(0), column(1));
        [[c0[0], c1[0]], [c0[1], c1[1]]]
    }

    /// Joint torques (N m, flexion positive) that move the rigid leg with accelerations
    /// `qdd` (rad/s^2) at angles `q` (rad) and rates `qd` (rad/s): `M(q) qdd + C(q, qd) qd`
    /// minus gravity, the two-link pendulum's Lagrange equations. In absolute link angles
    /// (thigh `a = h + pitch`, shank `b = a - k`) the mass matrix is `[[A, B cos k], [B cos
    /// k, D]]` with `A = I_t + m_t c_t^2 + m_s l^2`, `B = m_s l c_s`, `D = I_s + m_s c_s^2`;
    /// the joint torques are `tau_hip = Q_a + Q_b` and `tau_knee = -Q_b` (virtual work).
    pub fn inverse_dynamics(&self, q: [f64; 2], qd: [f64; 2], qdd: [f64; 2]) -> [f64; 2] {
        let (t, s, l) = (&self.thigh, &self.shank, self.thigh_length_m);
        let a_coef = t.inertia_kg_m2 + t.mass_kg * t.com_below_joint_m.powi(2) + s.mass_kg * l * l;
        let b_coef = s.mass_kg * l * s.com_below_joint_m;
        let d_coef = self.knee_inertia();
        let k = q[1];
        let (ad, bd) = (qd[0], qd[0] - qd[1]);
        let (add, bdd) = (qdd[0], qdd[0] - qdd[1]);
        let (c, sn) = (k.cos(), k.sin());
        let gravity = self.gravity_torques(q[0], q[1]);
        let q_a = a_coef * add + b_coef * c * bdd + b_coef * sn * bd * bd;
        let q_b = b_coef * c * add + d_coef * bdd - b_coef * sn * ad * ad;
        [q_a + q_b - gravity[0], -q_b - gravity[1]]
    }

    /// Joint accelerations (rad/s^2) of the rigid leg under joint torques `tau` (N m) at
    /// angles `q` (rad) and rates `qd` (rad/s): [`LegInertia::inverse_dynamics`] inverted,
    /// `M(q)^-1 (tau - C(q, qd) qd + gravity)`. `None` where the mass matrix is singular
    /// (a leg without mass).
    pub fn forward_dynamics(&self, q: [f64; 2], qd: [f64; 2], tau: [f64; 2]) -> Option<[f64; 2]> {
        let m = self.mass_matrix(q);
        let bias = self.inverse_dynamics(q, qd, [0.0; 2]);
        crate::base::solve_2x2(m, [tau[0] - bias[0], tau[1] - bias[1]])
    }

    /// The rigid leg's angles and rates after `secs` from `(q, qd)`, joint torques
    /// `torque(q, qd)`, by the classical fourth-order Runge-Kutta method in f64 at step `h_s`:
    /// the reference rapier's step is measured against (its error at 1 us is under 1e-12
    /// rad here). No joint limits: keep the motion inside them. `None` where the mass matrix
    /// turns singular.
    pub fn rk4_motion(
        &self,
        (q, qd): ([f64; 2], [f64; 2]),
        secs: f64,
        h_s: f64,
        torque: impl Fn([f64; 2], [f64; 2]) -> [f64; 2],
    ) -> Option<([f64; 2], [f64; 2])> {
        let f = |q: [f64; 2], v: [f64; 2]| self.forward_dynamics(q, v, torque(q, v));
        let add = |x: [f64; 2], y: [f64; 2], s: f64| [x[0] + s * y[0], x[1] + s * y[1]];
        let (mut q, mut v) = (q, qd);
        let steps = (secs / h_s).round() as usize;
        for _ in 0..steps {
            let (k1q, k1v) = (v, f(q, v)?);
            let k2q = add(v, k1v, h_s / 2.0);
            let k2v = f(add(q, k1q, h_s / 2.0), k2q)?;
            let k3q = add(v, k2v, h_s / 2.0);
            let k3v = f(add(q, k2q, h_s / 2.0), k3q)?;
            let k4q = add(v, k3v, h_s);
            let k4v = f(add(q, k3q, h_s), k4q)?;
            for i in 0..2 {
                q[i] += h_s / 6.0 * (k1q[i] + 2.0 * k2q[i] + 2.0 * k3q[i] + k4q[i]);
                v[i] += h_s / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
            }
        }
        Some((q, v))
    }
}

/// Two bodies' masses, centres and inertias about the flexion axis as one (parallel
/// axes): the shank and a foot at its neutral angle, for the nominal models.
pub(crate) fn combined(parts: [(f64, [f64; 2], f64); 2]) -> (f64, [f64; 2], f64) {
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    let com: [f64; 2] =
        std::array::from_fn(|k| parts.iter().map(|p| p.0 * p.1[k]).sum::<f64>() / mass);
    let inertia = parts
        .iter()
        .map(|(m, c, i)| i + m * ((c[0] - com[0]).powi(2) + (c[1] - com[1]).powi(2)))
        .sum();
    (mass, com, inertia)
}
