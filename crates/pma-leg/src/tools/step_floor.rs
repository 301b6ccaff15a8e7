//! rapier's leg against its exact motion as the physics step shrinks: where its error halves
//! with the step, to 512 substeps in the fork's f64 (in f32 round-off stopped it at about 32:
//! docs/convergence.md "rapier's floor").
use crate::base::{invalid, LegError, PerLeg};
use crate::body::{Exoskeleton, JointSettings, EMBEDDED_URDF};

/// The pose constant joint torques hold (hip, knee flexion, rad): inside every joint limit.
const HOLD_RAD: [f64; 2] = [0.5, 0.8];
/// Where the leg is released, at rest (rad).
const START_RAD: [f64; 2] = [0.7, 1.0];
/// The control period the substeps divide (s), the leg's.
const PERIOD_S: f64 = 1e-3;
/// The reference's Runge-Kutta step (s): 2 us lands within 1e-13 rad of it over 2 s.
const REFERENCE_STEP_S: f64 = 1e-6;
/// The substeps docs/convergence.md's table runs: from one step a period to past the floor.
pub const STEP_FLOOR_SUBSTEPS: [u32; 10] = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512];

/// One physics step's error against the exact motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepError {
    /// Physics substeps of the 1 ms period.
    pub substeps: u32,
    /// rapier's final angles less the exact ones (rad, hip then knee).
    pub error_rad: [f64; 2],
    /// rapier's final energy less the exact one (J).
    pub energy_error_j: f64,
}

impl StepError {
    /// The row docs/convergence.md prints.
    pub fn markdown_row(&self) -> String {
        format!(
            "| {} | {:.2} | {:+.2e} | {:+.2e} | {:+.2e} |",
            self.substeps,
            PERIOD_S / f64::from(self.substeps) * 1e6,
            self.error_rad[0],
            self.error_rad[1],
            self.energy_error_j
        )
    }
}

/// The in-air leg (`exo_leg.urdf`, no muscles) released 0.2 rad from a pose constant torques
/// hold, with joint damping `damping_nm_s_per_rad`, for `secs`; at each of `substeps` its
/// final angles and energy against the same two-link pendulum's Lagrange equations
/// ([`crate::body::LegInertia`], the URDF's inertias) by fourth-order Runge-Kutta in f64 at
/// 1 us.
pub fn step_floor(
    secs: f64,
    damping_nm_s_per_rad: f64,
    substeps: &[u32],
) -> Result<Vec<StepError>, LegError> {
    if !(secs > 0.0 && secs <= 60.0) {
        return Err(invalid("seconds", secs, "a swing of (0, 60] s"));
    }
    if !(0.0..=100.0).contains(&damping_nm_s_per_rad) {
        return Err(invalid(
            "damping_nm_s_per_rad",
            damping_nm_s_per_rad,
            "0 to 100 N m s/rad",
        ));
    }
    if let Some(&n) = substeps.iter().find(|&&n| n == 0) {
        return Err(invalid("physics_substeps", f64::from(n), "at least 1"));
    }
    let body = *leg(damping_nm_s_per_rad, 1)?.inertia();
    let g = body.gravity_torques(HOLD_RAD[0], HOLD_RAD[1]);
    let tau = [-g[0], -g[1]];
    let d = damping_nm_s_per_rad;
    let (q, qd) = body
        .rk4_motion((START_RAD, [0.0; 2]), secs, REFERENCE_STEP_S, |_, v| {
            [tau[0] - d * v[0], tau[1] - d * v[1]]
        })
        .ok_or_else(|| LegError::Parse {
            file: "step_floor".into(),
            message: "the leg's mass matrix is singular".into(),
        })?;
    let exact_energy = body.energy(q, qd);
    substeps
        .iter()
        .map(|&n| {
            let (rq, rqd) = swing(d, n, secs, tau)?;
            Ok(StepError {
                substeps: n,
                error_rad: [rq[0] - q[0], rq[1] - q[1]],
                energy_error_j: body.energy(rq, rqd) - exact_energy,
            })
        })
        .collect()
}

fn leg(damping: f64, substeps: u32) -> Result<Exoskeleton, LegError> {
    let j = JointSettings {
        damping_nm_s_per_rad: damping,
        friction_nm: 0.0,
    };
    Exoskeleton::from_urdf_str(EMBEDDED_URDF, "exo_leg.urdf", [j, j], PERIOD_S, substeps)
}

/// rapier's swing at `substeps`: its final angles and rates.
fn swing(
    damping: f64,
    substeps: u32,
    secs: f64,
    tau: [f64; 2],
) -> Result<([f64; 2], [f64; 2]), LegError> {
    let mut l = leg(damping, substeps)?;
    l.set_state(0, START_RAD, [0.0; 2]);
    for _ in 0..(secs / PERIOD_S).round() as usize {
        l.step(|_, _| PerLeg::one(tau));
    }
    Ok((l.angles(0), l.velocities(0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 50: rapier's leg converges at first order (semi-implicit Euler) to the two-link
    /// pendulum's Lagrange equations as the physics step shrinks, from 1 to 8 substeps of a 1
    /// ms period; finer than 16-32 substeps its single precision is the floor (`cargo run
    /// --release --example step_floor`, docs/convergence.md "rapier's floor").
    #[test]
    fn rapier_leg_converges_at_first_order_to_the_lagrange_equations() {
        let rows = step_floor(1.0, 0.5, &[1, 2, 4, 8]).unwrap();
        let errors: Vec<f64> = rows
            .iter()
            .map(|r| r.error_rad[0].hypot(r.error_rad[1]))
            .collect();
        // After 1 s the leg is where the equations put it within 0.03 deg at one 1 ms step.
        assert!(errors[0] < 5e-4, "{errors:?}");
        for pair in errors.windows(2) {
            let order = pair[0] / pair[1];
            assert!((1.8..=2.2).contains(&order), "halving the step: {errors:?}");
        }
    }
}
