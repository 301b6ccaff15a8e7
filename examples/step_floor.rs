//! How close rapier's leg comes to the exact motion as its physics step shrinks, and where
//! its single precision stops it (issue 50, docs/convergence.md "rapier's floor").
//!
//! The in-air leg (`exo_leg.urdf`, fixed pelvis) swings about a pose held by constant joint
//! torques (no joint limit reached), released 0.2 rad away with the joints' viscous damping,
//! for `SECONDS`; its final angles are compared with the same two-link pendulum's Lagrange
//! equations (`LegInertia`, the URDF's inertias) integrated by fourth-order Runge-Kutta in
//! f64 at 1 us.
//!
//!     cargo run --release --example step_floor [-- SECONDS [DAMPING_NM_S_PER_RAD]]
use pma_leg::body::{JointSettings, LegInertia, EMBEDDED_URDF};
use pma_leg::{Exoskeleton, PerLeg};

/// The pose the constant torques hold (hip, knee flexion, rad).
const HOLD_RAD: [f64; 2] = [0.5, 0.8];
/// Where the leg is released, at rest (rad).
const START_RAD: [f64; 2] = [0.7, 1.0];
const PERIOD_S: f64 = 1e-3;

fn leg(damping: f64, substeps: u32) -> Result<Exoskeleton, pma_leg::LegError> {
    let j = JointSettings {
        damping_nm_s_per_rad: damping,
        friction_nm: 0.0,
    };
    Exoskeleton::from_urdf_str(EMBEDDED_URDF, "exo_leg.urdf", [j, j], PERIOD_S, substeps)
}

/// The torques that hold `HOLD_RAD` against gravity.
fn hold(body: &LegInertia) -> [f64; 2] {
    let g = body.gravity_torques(HOLD_RAD[0], HOLD_RAD[1]);
    [-g[0], -g[1]]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let secs: f64 = args.next().map_or(Ok(2.0), |s| s.parse())?;
    let damping: f64 = args.next().map_or(Ok(0.5), |s| s.parse())?;
    if !(secs > 0.0 && secs <= 60.0 && (0.0..=100.0).contains(&damping)) {
        return Err("SECONDS in (0, 60], DAMPING_NM_S_PER_RAD in [0, 100]".into());
    }
    let body = *leg(damping, 1)?.inertia();
    let tau = hold(&body);
    let torque = |_: [f64; 2], qd: [f64; 2]| [tau[0] - damping * qd[0], tau[1] - damping * qd[1]];
    let exact = body
        .rk4_motion((START_RAD, [0.0; 2]), secs, 1e-6, torque)
        .ok_or("singular mass matrix")?;
    let half = body
        .rk4_motion((START_RAD, [0.0; 2]), secs, 2e-6, torque)
        .ok_or("singular mass matrix")?;
    let e_exact = body.energy(exact.0, exact.1);
    println!(
        "{secs} s, damping {damping} N m s/rad; RK4 (f64, 1 us) hip {:.9} knee {:.9} rad (2 us: {:.1e} rad away)",
        exact.0[0],
        exact.0[1],
        (half.0[0] - exact.0[0]).abs().max((half.0[1] - exact.0[1]).abs())
    );
    println!(
        "| physics substeps | step (us) | hip error (rad) | knee error (rad) | energy error (J) |"
    );
    println!("|---|---|---|---|---|");
    for substeps in [1u32, 2, 4, 8, 16, 32, 64, 128, 256, 512] {
        let mut l = leg(damping, substeps)?;
        l.set_state(0, START_RAD, [0.0; 2]);
        for _ in 0..(secs / PERIOD_S).round() as usize {
            l.step(|_, _| PerLeg::one(tau));
        }
        let (q, qd) = (l.angles(0), l.velocities(0));
        println!(
            "| {substeps} | {:.2} | {:+.2e} | {:+.2e} | {:+.2e} |",
            PERIOD_S / f64::from(substeps) * 1e6,
            q[0] - exact.0[0],
            q[1] - exact.0[1],
            body.energy(q, qd) - e_exact
        );
    }
    Ok(())
}
