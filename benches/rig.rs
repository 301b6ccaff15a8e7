//! One supervised period of the lockstep virtual rig (DAQ in volts and counts, supervisor,
//! APRC-NDO, charge pump), timed over runs of 1000 periods: criterion's figure divided by
//! 1000 is the cost of one period.
use criterion::{criterion_group, criterion_main, Criterion};
use pma_control::ControllerKind;
use pma_loop::{LoopSettings, MuscleTask};
use pma_rig::config::EMBEDDED_VIRTUAL;
use pma_rig::{Pacing, RigBackend, RigConfig, Supervised, VirtualDaq};
use std::hint::black_box;

fn rig(c: &mut Criterion) {
    let cfg = RigConfig::from_toml_str(EMBEDDED_VIRTUAL, "virtual.toml").expect("config");
    let daq = VirtualDaq::new(&cfg, &[]).expect("virtual rig");
    let clock = daq.lockstep_clock().expect("lockstep");
    let backend =
        RigBackend::configure(&cfg, Box::new(daq), Pacing::Lockstep(clock)).expect("configure");
    let reference = cfg.reference(backend.configure_reading_m());
    let mut rig = Supervised::new(backend, cfg.limits, cfg.period_s, None);
    let controller = cfg
        .build_controller(&ControllerKind::AprcNdo.default_config())
        .expect("controller");
    let mut task = MuscleTask::new(controller, &reference);
    let settings = LoopSettings::new(cfg.period_s, 1.0).expect("settings");
    c.bench_function("rig_lockstep_supervised_x1000", |b| {
        b.iter(|| black_box(pma_loop::run(&mut rig, &mut task, &mut (), &settings).periods))
    });
}

criterion_group!(benches, rig);
criterion_main!(benches);
