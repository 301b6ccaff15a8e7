//! The leg's closed-loop period with the patient model (spasticity, spasms, resistance,
//! passive joint moments) beside the same loop with the passive limb, in one run; and the
//! patient model's own cost per physics substep.
use criterion::{criterion_group, criterion_main, Criterion};
use pma_leg::{LegSim, Scenario};
use std::hint::black_box;

fn patient(c: &mut Criterion) {
    let mut group = c.benchmark_group("leg_patient_period_1ms");
    // The passive limb first and last: the spread of its two figures is this machine's
    // drift over the run, the yardstick for the patient's cost.
    for (label, name) in [
        ("gait_training", "gait_training"),
        ("gait_spastic", "gait_spastic"),
        ("gait_spasms", "gait_spasms"),
        ("gait_resistive", "gait_resistive"),
        ("gait_training_again", "gait_training"),
    ] {
        let loaded = Scenario::load(name).expect("embedded scenario");
        // Runs of 100 periods (0.1 s) on one simulation that keeps walking: criterion's
        // figure divided by 100 is the cost of one period, spasms included as they come.
        let mut sim = LegSim::new(&loaded).expect("sim");
        group.bench_function(format!("{label}_closed_loop_x100"), |b| {
            b.iter(|| black_box(sim.run(0.1, &mut ()).expect("run")))
        });
    }
    group.finish();
    // The patient model alone: one call per physics substep, the leg moving.
    let mut group = c.benchmark_group("patient_torques_per_substep");
    for name in ["gait_spastic", "gait_spasms", "gait_resistive"] {
        let loaded = Scenario::load(name).expect("embedded scenario");
        let sim = LegSim::new(&loaded).expect("sim");
        let mut patient = sim.plant().patient().expect("a patient").clone();
        let h = sim.exo().substep_s();
        patient.plan(1000.0);
        let mut k = 0u64;
        group.bench_function(name, |b| {
            b.iter(|| {
                k += 1;
                // Wraps within the planned spasms; the delay lines keep their length.
                let t = (k % 1_000_000) as f64 * h;
                let a = (t * 4.0).sin();
                black_box(patient.torques(t, [0.3 * a, 0.6 + 0.5 * a], [1.2 * a, 4.0 * a]))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, patient);
criterion_main!(benches);
