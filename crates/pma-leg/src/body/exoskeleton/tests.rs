//! Tests of `exoskeleton.rs`.
use super::*;
use crate::body::EMBEDDED_URDF;

fn leg(damping: f64, substeps: u32) -> Exoskeleton {
    let j = JointSettings {
        damping_nm_s_per_rad: damping,
        friction_nm: 0.0,
    };
    Exoskeleton::from_urdf_str(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, substeps).unwrap()
}

#[test]
fn flexion_is_positive_and_gravity_pulls_the_leg_back() {
    let mut l = leg(0.0, 1);
    l.set_state(0, [0.3, 0.4], [0.0, 0.0]);
    let a = l.angles(0);
    assert!(
        (a[0] - 0.3).abs() < 1e-5 && (a[1] - 0.4).abs() < 1e-5,
        "{a:?}"
    );
    // Flexed hip: the knee is in front of the hip (+X).
    let knee_x = l.link_poses().iter().find(|p| p.0 == "shank").unwrap().1[0];
    assert!(knee_x > 0.1, "knee at x = {knee_x}");
    l.step(|_, _| PerLeg::one([0.0, 0.0]));
    let v = l.velocities(0);
    assert!(v[0] < 0.0, "hip falls back: {v:?}");
}

#[test]
fn joint_torque_accelerates_in_its_sign() {
    let mut l = leg(0.0, 1);
    l.step(|_, _| PerLeg::one([50.0, -20.0]));
    let v = l.velocities(0);
    assert!(v[0] > 0.0 && v[1] < 0.0, "{v:?}");
}

#[test]
fn the_mass_matrix_is_symmetric_and_gives_the_kinetic_energy() {
    let body = *leg(0.0, 2).inertia();
    for (q, qd) in [
        ([0.3, 0.8], [1.2, -2.0]),
        ([-0.1, 0.0], [0.5, 0.7]),
        ([0.9, 1.3], [-1.5, 3.0]),
    ] {
        let m = body.mass_matrix(q);
        let kinetic = 0.5
            * (qd[0] * (m[0][0] * qd[0] + m[0][1] * qd[1])
                + qd[1] * (m[1][0] * qd[0] + m[1][1] * qd[1]));
        let from_energy = body.energy(q, qd) - body.energy(q, [0.0; 2]);
        assert!((m[0][1] - m[1][0]).abs() < 1e-12, "{m:?}");
        assert!(
            (kinetic - from_energy).abs() < 1e-12 * from_energy,
            "{q:?} {qd:?}: 1/2 qd' M qd = {kinetic} J, energy's {from_energy} J"
        );
    }
}

#[test]
fn inverse_dynamics_torques_give_rapier_the_asked_accelerations() {
    // Forward dynamics (rapier) of the inverse dynamics (Lagrange, by hand): at states
    // with large Coriolis and coupling terms, one step under tau = ID(q, qd, qdd)
    // changes the velocities by qdd * h.
    let h = 1e-3;
    for (q, qd, qdd) in [
        ([0.3, 0.9], [2.0, -3.0], [5.0, -8.0]),
        ([-0.2, 0.2], [-1.5, 4.0], [-3.0, 10.0]),
        ([0.6, 1.2], [0.0, 0.0], [0.0, 0.0]),
    ] {
        let mut l = leg(0.0, 1);
        l.set_state(0, q, qd);
        let tau = l.inertia().inverse_dynamics(q, qd, qdd);
        l.step(|_, _| PerLeg::one(tau));
        let v = l.velocities(0);
        for j in 0..2 {
            let a = (v[j] - qd[j]) / h;
            assert!(
                (a - qdd[j]).abs() < 0.02 * qdd[j].abs().max(5.0),
                "joint {j} at q {q:?}, qd {qd:?}: asked {} rad/s^2, got {a} (tau {tau:?})",
                qdd[j]
            );
        }
    }
}

#[test]
fn a_pitched_pelvis_turns_gravity_about_the_hip() {
    // Pitched by 90 deg, the straight leg lies horizontal: the full static moment at the
    // hip, and the torques the formula gives hold it.
    let j = JointSettings {
        damping_nm_s_per_rad: 0.0,
        friction_nm: 0.0,
    };
    let mount = Mount {
        pelvis_pitch_rad: std::f64::consts::FRAC_PI_2,
        knee_limits_rad: None,
    };
    let mut l =
        Exoskeleton::mounted(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, 2, mount).unwrap();
    let i = *l.inertia();
    let g = i.gravity_torques(0.0, 0.0);
    let static_moment = G
        * (i.thigh.mass_kg * i.thigh.com_below_joint_m
            + i.shank.mass_kg * (i.thigh_length_m + i.shank.com_below_joint_m));
    assert!(
        (g[0] + static_moment).abs() < 1e-9,
        "{g:?} vs {static_moment}"
    );
    l.set_state(0, [0.1, 0.3], [0.0, 0.0]);
    let g = i.gravity_torques(0.1, 0.3);
    for _ in 0..300 {
        l.step(|_, _| PerLeg::one([-g[0], -g[1]]));
    }
    let a = l.angles(0);
    assert!(
        (a[0] - 0.1).abs() < 1e-3 && (a[1] - 0.3).abs() < 1e-3,
        "{a:?}"
    );
}

#[test]
fn gravity_torques_match_the_hand_formula() {
    // Holding torques equal to minus gravity keep the leg still.
    let mut l = leg(0.0, 2);
    let q = [0.35, 0.5];
    l.set_state(0, q, [0.0, 0.0]);
    let g = l.inertia().gravity_torques(q[0], q[1]);
    for _ in 0..500 {
        l.step(|_, _| PerLeg::one([-g[0], -g[1]]));
    }
    let a = l.angles(0);
    assert!(
        (a[0] - q[0]).abs() < 1e-3 && (a[1] - q[1]).abs() < 1e-3,
        "{a:?}"
    );
}

/// The rapier fork (vendor/rapier3d/PATCHES.md) computes the multibody's body
/// Jacobians and mass matrix on each link's branch (its own and its ancestors' DOFs)
/// only. On the two-leg trainer, moving, they must be what the full products give: each
/// link's Jacobian times the generalized velocity is the link's velocity (rapier's own,
/// propagated link to link), and the mass matrix is the sum over links of Jᵀ M J, the
/// legs' cross terms zero.
#[test]
fn rapier_fork_branch_dynamics_equal_the_full_products_on_two_legs() {
    let t = TreadmillSettings {
        legs: 2,
        speed_m_per_s: Some(0.5),
        contralateral: Some(crate::ground::Contralateral::None),
        ..TreadmillSettings::new(0.3, 75.0)
    };
    let j = JointSettings {
        damping_nm_s_per_rad: 0.5,
        friction_nm: 0.0,
    };
    let mut e = Exoskeleton::on_treadmill(
        crate::body::EMBEDDED_TRAINER_URDF,
        "exo_trainer.urdf",
        [j, j],
        1e-3,
        1,
        &t,
    )
    .unwrap();
    e.set_state(0, [0.4, 0.7], [1.5, -2.0]);
    e.set_state(1, [-0.1, 0.2], [-0.7, 3.0]);
    for _ in 0..5 {
        e.step(|_, _| PerLeg::from_fn(2, |leg| [10.0 * leg as f64, -5.0]));
    }
    let handle = e.legs[0].joints[0].handle;
    // Each link's Jacobian at this pose against its centre of mass's finite difference
    // over the next period (semi-implicit Euler moves the pose with the new velocity).
    let coms = |e: &Exoskeleton| -> Vec<[f64; 3]> {
        let (mb, _) = e.world.multibody_joints.get(handle).unwrap();
        mb.links()
            .map(|l| {
                let c = e.world.bodies[l.rigid_body_handle()]
                    .mass_properties()
                    .world_com;
                [c.x, c.y, c.z].map(f64::from)
            })
            .collect()
    };
    let before = coms(&e);
    let jacobians: Vec<_> = {
        let (mb, _) = e.world.multibody_joints.get(handle).unwrap();
        (0..mb.num_links())
            .map(|i| mb.body_jacobian(i).clone())
            .collect()
    };
    e.step(|_, _| PerLeg::from_fn(2, |leg| [10.0 * leg as f64, -5.0]));
    let after = coms(&e);
    let bodies = &e.world.bodies;
    let (mb, _) = e.world.multibody_joints.get_mut(handle).unwrap();
    let n = mb.ndofs();
    assert_eq!(n, 8, "pelvis x and z, two hips, knees and ankles");
    let qd: Vec<f64> = mb.generalized_velocity().iter().copied().collect();
    let (mut worst_velocity, mut fastest) = (0.0f64, 0.0f64);
    for (i, jac) in jacobians.iter().enumerate() {
        for r in 0..3 {
            let jv: f64 = (0..n).map(|c| jac[(r, c)] * qd[c]).sum();
            let moved = (after[i][r] - before[i][r]) / 1e-3;
            worst_velocity = worst_velocity.max((jv - moved).abs());
            fastest = fastest.max(moved.abs());
        }
    }
    // The mass matrix at the present pose: rapier reassembles it (dt = 0: no damping).
    mb.dof_inverse_inertia(bodies);
    let mut full = vec![vec![0.0f64; n]; n];
    for (i, link) in mb.links().enumerate() {
        let jac = mb.body_jacobian(i);
        let props = bodies[link.rigid_body_handle()].mass_properties();
        let m = props.effective_mass();
        let inertia = props.effective_angular_inertia();
        // The link's spatial inertia at its centre of mass: mass, then the world inertia.
        let i3 = [
            [inertia.m11, inertia.m12, inertia.m13],
            [inertia.m12, inertia.m22, inertia.m23],
            [inertia.m13, inertia.m23, inertia.m33],
        ];
        let mut spatial = [[0.0f64; 6]; 6];
        for (k, mass) in [m.x, m.y, m.z].into_iter().enumerate() {
            spatial[k][k] = mass;
            for l in 0..3 {
                spatial[3 + k][3 + l] = i3[k][l];
            }
        }
        for (r, row) in full.iter_mut().enumerate() {
            for (c, entry) in row.iter_mut().enumerate() {
                for a in 0..6 {
                    for b in 0..6 {
                        *entry += jac[(a, r)] * spatial[a][b] * jac[(b, c)];
                    }
                }
            }
        }
    }
    let fork = mb.inv_augmented_mass().reconstruct();
    let scale = full.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
    let mut worst_mass = 0.0f64;
    for r in 0..n {
        for c in 0..n {
            worst_mass = worst_mass.max((fork[(r, c)] - full[r][c]).abs() / scale);
        }
    }
    // The hips' cross term: no link moves with both legs.
    let hips = e.legs.iter().map(|l| l.joints[0].dof).collect::<Vec<_>>();
    let cross = fork[(hips[0], hips[1])].abs() / scale;
    println!(
        "J qdot vs the links' finite-difference velocity: {worst_velocity:.2e} m/s (fastest {fastest:.2} m/s); mass matrix vs full sum: {worst_mass:.2e} of its largest entry ({scale:.1} kg); hips' cross term {cross:.1e}"
    );
    assert!(
        worst_velocity < 0.02 * fastest,
        "J qdot is {worst_velocity} m/s off a link's velocity"
    );
    assert!(
        worst_mass < 1e-5,
        "mass matrix {worst_mass} off the full sum"
    );
    assert!(cross < 1e-6, "the hips' cross term is {cross}");
}
