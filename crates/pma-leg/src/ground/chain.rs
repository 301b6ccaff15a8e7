use crate::ground::FootSphere;

/// Step of the joint angles of [`SagittalChain`]'s Jacobians (rad).
const JACOBIAN_STEP_RAD: f64 = 1e-6;

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

/// The `(sin, cos)` of a pose's ankle, knee and hip angles on a [`SagittalChain`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainRotations([(f64, f64); 3]);

impl SagittalChain {
    /// Centre of sphere `i` in the pelvis frame (m, `[x, z]`) at hip and knee flexion and
    /// ankle dorsiflexion `q` (rad).
    pub fn sphere_centre(&self, i: usize, q: [f64; 3]) -> [f64; 2] {
        self.sphere_centre_at(i, &self.rotations(q))
    }

    /// [`Self::sphere_centre`] with the chain's [`Self::rotations`] at `q` given: every
    /// sphere of a pose shares them (the virtual other leg's at every substep, issue 50).
    pub fn sphere_centre_at(&self, i: usize, rotations: &ChainRotations) -> [f64; 2] {
        let c = self.spheres[i].center_m;
        self.in_pelvis_at([c[0], c[2]], rotations)
    }

    /// The `(sin, cos)` of the ankle's, the knee's and the hip's angles at `q`.
    pub fn rotations(&self, q: [f64; 3]) -> ChainRotations {
        let angle = |j: usize| self.pitch_rad[j] + self.flexion_sign[j] * q[j];
        ChainRotations([angle(2).sin_cos(), angle(1).sin_cos(), angle(0).sin_cos()])
    }

    /// A point of the foot `[x, z]` (foot frame) in the pelvis frame at `q`.
    fn in_pelvis(&self, p: [f64; 2], q: [f64; 3]) -> [f64; 2] {
        self.in_pelvis_at(p, &self.rotations(q))
    }

    fn in_pelvis_at(&self, p: [f64; 2], rotations: &ChainRotations) -> [f64; 2] {
        // A rotation about -Y by `a` takes (x, z) to (x cos a - z sin a, x sin a + z cos a).
        let rot = |p: [f64; 2], (s, c): (f64, f64)| [p[0] * c - p[1] * s, p[0] * s + p[1] * c];
        let add = |a: [f64; 2], b: [f64; 2]| [a[0] + b[0], a[1] + b[1]];
        let [ankle, knee, hip] = rotations.0;
        let in_shank = add(self.origins_m[2], rot(p, ankle));
        let in_thigh = add(self.origins_m[1], rot(in_shank, knee));
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
