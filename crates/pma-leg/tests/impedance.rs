//! Impedance by co-contraction on the leg in the air (issue 28): the stiffness a
//! small-perturbation test measures against the set point, at three set points per joint;
//! a spasm against position control.
use pma_leg::impedance::{probe_stiffness, ControlMode};
use pma_leg::{LegSim, MusclePair, Scenario};

/// Seconds each load is held: six time constants of the hip's pair (its own damping over
/// its stiffness, about 1.6 s).
const SETTLE_S: f64 = 10.0;

#[test]
fn realised_stiffness_is_within_ten_percent_of_three_set_points_per_joint() {
    let loaded = Scenario::load("gait_training").unwrap();
    let sim = LegSim::new(&loaded).unwrap();
    let pose = [20f64.to_radians(), 30f64.to_radians()];
    let inertia = *sim.exo().inertia();
    for joint in 0..2 {
        let pair = MusclePair::new(sim.plant().leg_muscles(0), joint, 6e5).unwrap();
        let gravity = inertia.inverse_dynamics(pose, [0.0; 2], [0.0; 2])[joint];
        let r = pair.stiffness_range(gravity, pose[joint]).unwrap();
        for share in [0.2, 0.5, 0.8] {
            let k = r.min_nm_per_rad + share * (r.max_nm_per_rad - r.min_nm_per_rad);
            let p = probe_stiffness(&loaded, joint, k, pose, SETTLE_S).unwrap();
            assert!(!p.held_by_friction, "{p:?}");
            assert!(p.error.abs() < 0.10, "{p:?}");
        }
    }
}

#[test]
fn the_perturbation_test_refuses_a_treadmill_scenario() {
    let loaded = Scenario::load("gait_treadmill").unwrap();
    let e = probe_stiffness(&loaded, 0, 100.0, [0.0; 2], 1.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("in the air"), "{e}");
}

/// A knee spasm under impedance mode against position control: the leg yields (a larger
/// deviation) and the valves barely move (a far lower pressure rate), as a compliant joint
/// should; position control holds the knee by racing its valves.
#[test]
fn a_spasm_deflects_an_impedance_joint_more_with_slower_valves_than_position_control() {
    let run = |mode: ControlMode| {
        let mut loaded = Scenario::load("gait_spasms").unwrap();
        loaded.scenario.control.mode = mode;
        let mut sim = LegSim::new(&loaded).unwrap();
        let report = sim.run(8.0, &mut ()).unwrap();
        let spasm = &report.spasms[0];
        (spasm.peak_deviation_deg, spasm.peak_pressure_rate_bar_s)
    };
    let (position_dev, position_rate) = run(ControlMode::Position);
    let (impedance_dev, impedance_rate) = run(ControlMode::Impedance);
    assert!(
        impedance_dev > 3.0 * position_dev,
        "{impedance_dev} against {position_dev}"
    );
    assert!(
        impedance_rate < 0.1 * position_rate,
        "{impedance_rate} against {position_rate}"
    );
}
