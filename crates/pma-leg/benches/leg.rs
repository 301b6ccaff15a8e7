//! One closed-loop period of the default gait scenario (rapier + 4 muscles + 4 APRC-NDO
//! controllers + references) beside rapier's bare step of the same leg with the same
//! physics substeps, in one run (`cargo bench -p pma-leg --bench leg`). The same loop saving
//! a Rerun recording is the root package's `benches/leg_rerun.rs`.
use criterion::{criterion_group, criterion_main, Criterion};
use pma_leg::{Exoskeleton, LegSim, PerLeg, Scenario};
use std::hint::black_box;

fn leg(c: &mut Criterion) {
    let loaded = Scenario::load("gait_training").expect("embedded scenario");
    let sc = &loaded.scenario;
    let mut group = c.benchmark_group("leg_period_1ms");
    let mut bare = Exoskeleton::from_urdf_str(
        &loaded.urdf_text,
        &loaded.urdf_source,
        [sc.joints.hip, sc.joints.knee],
        sc.period_s,
        sc.physics_substeps,
    )
    .expect("leg");
    let mut k = 0u64;
    group.bench_function("rapier_bare", |b| {
        b.iter(|| {
            // A moving leg (a resting one would cost the same: sleeping is disabled).
            k += 1;
            let a = (k as f64 * 0.004).sin();
            bare.step(|_, _| PerLeg::one([20.0 * a, 5.0 * a]));
            black_box(bare.angles(0))
        })
    });
    // The trainer (pelvis on its slides, feet on a 0.6 m/s belt, 30 % BWS, passive
    // ankles) with one and two legs at the treadmill scenarios' physics substeps (those of
    // the closed loop below), the contacts computed every substep.
    let treadmill = Scenario::load("gait_treadmill").expect("gait_treadmill");
    for legs in [1, 2] {
        let settings = pma_leg::ground::TreadmillSettings {
            legs,
            speed_m_per_s: Some(0.6),
            contralateral: Some(pma_leg::ground::Contralateral::None),
            ..pma_leg::ground::TreadmillSettings::new(0.3, 75.0)
        };
        let mut on_belt = Exoskeleton::on_treadmill(
            pma_leg::body::EMBEDDED_TRAINER_URDF,
            "exo_trainer.urdf",
            [sc.joints.hip, sc.joints.knee],
            sc.period_s,
            treadmill.scenario.physics_substeps,
            &settings,
        )
        .expect("treadmill leg");
        for leg in 0..legs {
            on_belt.set_state(leg, [0.05, 0.10], [0.0, 0.0]);
        }
        on_belt.rest_on_belt();
        let name = format!("rapier_treadmill_bare_{legs}_leg");
        group.bench_function(name.as_str(), |b| {
            b.iter(|| {
                on_belt.step(|l, _| {
                    PerLeg::from_fn(legs, |leg| {
                        let (q, qd) = (l.angles(leg), l.velocities(leg));
                        [
                            -3000.0 * (q[0] - 0.05) - 60.0 * qd[0],
                            -3000.0 * (q[1] - 0.10) - 60.0 * qd[1],
                        ]
                    })
                });
                black_box(on_belt.ground_reaction())
            })
        });
    }
    // The closed loop is timed over runs of 100 periods (0.1 s) on one simulation that
    // keeps walking; criterion's figure divided by 100 is the cost of one period.
    let mut sim = LegSim::new(&loaded).expect("sim");
    group.bench_function("closed_loop_x100", |b| {
        b.iter(|| black_box(sim.run(0.1, &mut ()).expect("run")))
    });
    // The same leg in one physics step with the muscles' damping implicit.
    let mut implicit = loaded.clone();
    implicit.scenario.physics_substeps = 1;
    implicit.scenario.implicit_muscle_damping = true;
    let mut sim = LegSim::new(&implicit).expect("sim");
    group.bench_function("closed_loop_implicit_1_step_x100", |b| {
        b.iter(|| black_box(sim.run(0.1, &mut ()).expect("run")))
    });
    // The same on the treadmill (gait_treadmill: belt, harness, the other leg, the gait
    // phases' figures).
    let mut sim = LegSim::new(&treadmill).expect("sim");
    group.bench_function("closed_loop_treadmill_x100", |b| {
        b.iter(|| black_box(sim.run(0.1, &mut ()).expect("run")))
    });
    group.finish();
}

criterion_group!(benches, leg);
criterion_main!(benches);
