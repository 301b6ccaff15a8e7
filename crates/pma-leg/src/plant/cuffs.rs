use crate::plant::CuffSettings;

/// The thigh and shank cuff forces (N, perpendicular to their segments, forward positive)
/// that put the joint torques `interaction_nm` (hip, knee; flexion positive) into the limb
/// at knee flexion `knee_rad`, the thigh `thigh_length_m` long and the cuffs where `cuffs`
/// says. A cuff force is a generalized force through its point's Jacobian: with the thigh
/// at absolute angle `a` and the shank at `b = a - k`, the thigh cuff at `d` below the hip
/// gives `Q_a = F_t d`, the shank cuff at `c` below the knee `Q_a = F_s l cos k` and `Q_b =
/// F_s c`; the joint torques are `tau_hip = Q_a + Q_b` and `tau_knee = -Q_b` (as in
/// [`crate::body::LegInertia::inverse_dynamics`]). Two cuffs, two torques: one solution.
pub fn cuff_forces_n(
    interaction_nm: [f64; 2],
    knee_rad: f64,
    thigh_length_m: f64,
    cuffs: &CuffSettings,
) -> [f64; 2] {
    let (d, c) = (cuffs.thigh_below_hip_m, cuffs.shank_below_knee_m);
    let shank = -interaction_nm[1] / c;
    let thigh = (interaction_nm[0] - shank * (thigh_length_m * knee_rad.cos() + c)) / d;
    [thigh, shank]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2-D cross product `r x f` (positive: turning towards flexion).
    fn cross(r: [f64; 2], f: [f64; 2]) -> f64 {
        r[0] * f[1] - r[1] * f[0]
    }

    /// Forces at the cuffs of a sagittal leg drawn point by point (x forward, z up, the
    /// thigh hanging at angle `a` from the vertical, the shank at `a - k`) give joint
    /// torques as moments about hip and knee; `cuff_forces_n` gives the forces back.
    #[test]
    fn the_cuff_forces_give_back_the_joint_torques_as_moments_of_the_drawn_leg() {
        let cuffs = CuffSettings {
            thigh_below_hip_m: 0.17,
            shank_below_knee_m: 0.23,
        };
        let l = 0.42;
        for (a, k, f_t, f_s) in [
            (0.3, 0.1, 40.0, -25.0),
            (-0.2, 1.1, -60.0, 15.0),
            (0.6, 0.0, 5.0, 80.0),
            (0.0, 1.4, 0.0, -33.0),
        ] {
            let b: f64 = a - k;
            let along = |angle: f64| [angle.sin(), -angle.cos()];
            let forward = |angle: f64| [angle.cos(), angle.sin()];
            let (d, c) = (cuffs.thigh_below_hip_m, cuffs.shank_below_knee_m);
            let thigh_cuff = along(a).map(|x| d * x);
            let knee = along(a).map(|x| l * x);
            let to_shank_cuff = along(b).map(|x| c * x);
            let shank_cuff = [knee[0] + to_shank_cuff[0], knee[1] + to_shank_cuff[1]];
            let (ft, fs) = (forward(a).map(|x| f_t * x), forward(b).map(|x| f_s * x));
            let hip = cross(thigh_cuff, ft) + cross(shank_cuff, fs);
            // Knee flexion turns the shank backwards: its torque is minus the moment.
            let knee_torque = -cross(to_shank_cuff, fs);
            let got = cuff_forces_n([hip, knee_torque], k, l, &cuffs);
            assert!(
                (got[0] - f_t).abs() < 1e-9 && (got[1] - f_s).abs() < 1e-9,
                "{got:?}"
            );
        }
    }
}
