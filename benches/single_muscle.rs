//! Speed of the single-muscle core: one controller update, one plant period, and a whole
//! 20 s closed loop (its real-time factor is 20 s divided by the reported time).
use criterion::{criterion_group, criterion_main, Criterion};
use pma_bench::{run_single, MuscleBench, PlantConfig, RunSpec};
use pma_control::{
    build_controller, CommandLimits, ControllerKind, Measurement, Reference, SineReference,
};
use std::hint::black_box;

fn controller_update(c: &mut Criterion) {
    let r = SineReference::paper();
    let mut group = c.benchmark_group("controller_update");
    for kind in ControllerKind::ALL {
        let mut ctl = build_controller(
            &kind.default_config(),
            Default::default(),
            CommandLimits::default(),
        )
        .expect("default gains are valid");
        ctl.reset(Measurement { position_m: 0.015 }, r.sample(0.0));
        let mut k = 0u64;
        group.bench_function(kind.as_str(), |b| {
            b.iter(|| {
                k += 1;
                let t = (k % 20_000) as f64 * 1e-3;
                let s = r.sample(t);
                let m = Measurement {
                    position_m: s.position_m - 1e-4,
                };
                black_box(ctl.update(black_box(&s), black_box(&m), 1e-3))
            })
        });
    }
    group.finish();
}

fn plant_period(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant_period_1ms");
    for name in ["ideal", "realistic"] {
        let cfg = PlantConfig::preset(name).expect("preset");
        let mut bench = MuscleBench::at_rest(&cfg, 0.015).expect("bench");
        let mut k = 0u64;
        group.bench_function(name, |b| {
            b.iter(|| {
                k += 1;
                // Alternate the command so the damping mode and the valve both work.
                let p = if k.is_multiple_of(2) { 0.70e5 } else { 0.72e5 };
                bench.apply(black_box(p), 1e-3);
                black_box(bench.measure())
            })
        });
    }
    group.finish();
}

fn closed_loop(c: &mut Criterion) {
    let mut group = c.benchmark_group("closed_loop_20s");
    group.sample_size(20);
    for (kind, plant) in [
        (ControllerKind::AprcNdo, "ideal"),
        (ControllerKind::AprcNdo, "realistic"),
        (ControllerKind::Pid, "ideal"),
    ] {
        let cfg = PlantConfig::preset(plant).expect("preset");
        let ctl = kind.default_config();
        group.bench_function(format!("{}_{plant}", kind.as_str()), |b| {
            b.iter(|| {
                run_single(
                    &ctl,
                    &cfg,
                    &SineReference::paper(),
                    &RunSpec::default(),
                    &mut (),
                )
                .expect("run")
                .stats
            })
        });
    }
    group.finish();
}

/// One 1 ms period of a DMSP-20's pressure behind the MPYE-5-1/4 valve model (the two-leg
/// trainer runs eight a period): 20 internal steps of the flow and the spool.
fn flow_period(c: &mut Criterion) {
    use pma_model::pneumatics::FlowState;
    use pma_model::{Chamber, PneumaticsSettings, ValveSpec};
    let settings = PneumaticsSettings {
        valve: "mpye-5-1-4".into(),
        ..PneumaticsSettings::default()
    };
    let spec = ValveSpec::load("mpye-5-1-4").expect("shipped valve");
    let flow = settings.flow(&spec, Chamber::dmsp(0.02, 1.2));
    let mut state = FlowState {
        pressure_pa: 3e5,
        opening: 0.0,
    };
    let mut k = 0u64;
    c.bench_function("flow_period_1ms/mpye-5-1-4", |b| {
        b.iter(|| {
            k += 1;
            // Alternate the set point so the spool and the flow both work.
            let set = if k.is_multiple_of(2) { 3.0e5 } else { 3.2e5 };
            flow.advance(&mut state, black_box(set), 1e-3, 0.05, 0.01);
            black_box(state.pressure_pa)
        })
    });
}

criterion_group!(
    benches,
    controller_update,
    plant_period,
    flow_period,
    closed_loop
);
criterion_main!(benches);
