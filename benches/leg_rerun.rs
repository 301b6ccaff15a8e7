//! The closed loop of pma-leg's `benches/leg.rs` saving a Rerun recording, at the full rate
//! and at 100 Hz (`cargo bench --bench leg_rerun`: the `rerun` feature; the leg's own bench
//! lives in pma-leg, which builds without it).
use criterion::{criterion_group, criterion_main, Criterion};
use pma_leg::{LegOutput, LegSim, PerLeg, Scenario, SupervisedLeg, TrainerSample};
use pma_loop::{FnRecorder, Period};
use std::hint::black_box;

fn leg_rerun(c: &mut Criterion) {
    let loaded = Scenario::load("gait_training").expect("embedded scenario");
    let sc = &loaded.scenario;
    // The group of pma-leg's bench: criterion keeps the figures where they were.
    let mut group = c.benchmark_group("leg_period_1ms");
    for (label, rate) in [
        ("closed_loop_x100_rerun_save_full_rate", None),
        ("closed_loop_x100_rerun_save_100hz", Some(100.0)),
    ] {
        let path = std::env::temp_dir().join(format!("pma-exo-bench-{label}.rrd"));
        let sink = pma_viz::Sink::Save(path.clone());
        let mut sim = LegSim::new(&loaded).expect("sim");
        let mut viz = pma_exo::viz::open(&sink, "bench", sc.period_s, rate)
            .expect("viz")
            .expect("on");
        let channels = pma_exo::viz::leg_layout(&mut viz, &sim, "bench").expect("layout");
        let (mut step, mut scalars) = (0i64, vec![0.0; channels]);
        let mut log = FnRecorder(|p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>| {
            step += 1;
            let s = TrainerSample::of(p);
            pma_exo::viz::push_leg(&mut viz, p.backend, &s, step, &mut scalars).expect("log");
        });
        group.bench_function(label, |b| {
            b.iter(|| black_box(sim.run(0.1, &mut log).expect("run")))
        });
        drop(viz);
        let _ = std::fs::remove_file(path);
    }
    group.finish();
}

criterion_group!(benches, leg_rerun);
criterion_main!(benches);
