//! Cost of identification: `identify` on a 20 s excitation of the `realistic` plant
//! (steps then a chirp, as `rig excite` drives it), from the log to the intervals, with
//! the position alone and with the valve's pressure channel. A 60 s log costs about three
//! times as much (docs/commissioning.md).
use criterion::{criterion_group, criterion_main, Criterion};
use pma_bench::{MuscleBench, PlantConfig};
use pma_control::ExcitationSpec;
use pma_studies::identify::{identify, IdLog};
use std::hint::black_box;

fn realistic_log(seconds: f64) -> IdLog {
    let plant = PlantConfig::preset("realistic").expect("preset");
    let spec = ExcitationSpec::steps_and_chirp(seconds, 0.5e5, 3.0e5, 1e8);
    let mut bench = MuscleBench::vented(&plant).expect("bench");
    let start_m = bench.measure().position_m;
    let n = (seconds * 1e3) as usize;
    let command_pa: Vec<f64> = (0..n).map(|k| spec.schedule_pa(k as f64 * 1e-3)).collect();
    let (position_m, pressure_pa) = command_pa
        .iter()
        .map(|&c| {
            bench.apply(c, 1e-3);
            (bench.measure().position_m, bench.pressure())
        })
        .unzip();
    IdLog {
        source: format!("a simulated {seconds} s excitation"),
        period_s: 1e-3,
        command_pa,
        position_m,
        start_m,
        pressure_max_pa: 6e5,
        pressure_pa: Some(pressure_pa),
        weighed_kg: Some(2.5),
        added_mass_kg: 0.0,
    }
}

fn identify_20s(c: &mut Criterion) {
    let with_pressure = realistic_log(20.0);
    let position_only = IdLog {
        pressure_pa: None,
        ..with_pressure.clone()
    };
    let mut group = c.benchmark_group("identify");
    group.sample_size(10);
    group.bench_function("realistic_20s_log", |b| {
        b.iter(|| black_box(identify(black_box(&position_only), 2.5, 1)).expect("identified"))
    });
    group.bench_function("realistic_20s_log_pressure_channel", |b| {
        b.iter(|| black_box(identify(black_box(&with_pressure), 2.5, 1)).expect("identified"))
    });
    group.finish();
}

criterion_group!(benches, identify_20s);
criterion_main!(benches);
