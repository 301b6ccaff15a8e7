//! The rig: one supervised period of the lockstep virtual rig (DAQ in volts and counts,
//! supervisor, APRC-NDO, charge pump), timed over runs of 1000 periods (criterion's figure
//! divided by 1000 is the cost of one period); and how long a fault takes to vent, from
//! the board's read of the faulty value to the board's write of the vent value
//! (`docs/safety.md`).
use criterion::{criterion_group, criterion_main, Criterion};
use pma_control::ControllerKind;
use pma_control::MuscleTask;
use pma_loop::LoopSettings;
use pma_rig::config::EMBEDDED_VIRTUAL;
use pma_rig::supervisor::{VentAction, WatchdogFactory};
use pma_rig::{
    AnalogChannel, Daq, DaqError, DigitalLine, InjectedFault, Injection, OutputHandle, Pacing,
    RigBackend, RigConfig, Supervised, VirtualDaq,
};
use std::hint::black_box;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn rig(c: &mut Criterion) {
    let cfg = RigConfig::from_toml_str(EMBEDDED_VIRTUAL, "virtual.toml").expect("config");
    let daq = VirtualDaq::new(&cfg, &[]).expect("virtual rig");
    let clock = daq.lockstep_clock().expect("lockstep");
    let backend =
        RigBackend::configure(&cfg, Box::new(daq), Pacing::Lockstep(clock)).expect("configure");
    let reference = cfg.reference(backend.configure_reading_m());
    let mut rig = Supervised::new(backend, cfg.supervisor_limits(), None);
    let controller = cfg
        .build_controller(&ControllerKind::AprcNdo.default_config())
        .expect("controller");
    let mut task = MuscleTask::new(controller, &reference);
    let settings = LoopSettings::new(1.0).expect("settings");
    c.bench_function("rig_lockstep_supervised_x1000", |b| {
        b.iter(|| {
            let outcome =
                pma_loop::run(&mut rig, &mut task, &mut (), &settings).expect("a sound duration");
            black_box(outcome.periods)
        })
    });
}

/// The virtual board, timestamping the first NaN it reads and the first vent after it.
struct Stopwatch {
    inner: VirtualDaq,
    vent_v: f64,
    fault_at: Arc<Mutex<Option<Instant>>>,
    vent_at: Arc<Mutex<Option<Instant>>>,
}

impl Daq for Stopwatch {
    fn device(&self) -> &str {
        self.inner.device()
    }
    fn check(
        &mut self,
        i: &[AnalogChannel],
        o: &[AnalogChannel],
        l: &[DigitalLine],
    ) -> Result<(), DaqError> {
        self.inner.check(i, o, l)
    }
    fn range_v(&mut self, c: &AnalogChannel, output: bool) -> Result<(f64, f64), DaqError> {
        self.inner.range_v(c, output)
    }
    fn read_analog(&mut self, c: &AnalogChannel) -> Result<f64, DaqError> {
        let v = self.inner.read_analog(c)?;
        if v.is_nan() {
            if let Ok(mut t) = self.fault_at.lock() {
                t.get_or_insert_with(Instant::now);
            }
        }
        Ok(v)
    }
    fn write_analog(&mut self, c: &AnalogChannel, volts: f64) -> Result<(), DaqError> {
        self.inner.write_analog(c, volts)?;
        let faulted = self.fault_at.lock().map(|t| t.is_some()).unwrap_or(false);
        if faulted && volts == self.vent_v {
            if let Ok(mut t) = self.vent_at.lock() {
                t.get_or_insert_with(Instant::now);
            }
        }
        Ok(())
    }
    fn write_digital(&mut self, l: &DigitalLine, high: bool) -> Result<(), DaqError> {
        self.inner.write_digital(l, high)
    }
    fn output_handle(&self, c: &AnalogChannel) -> Result<Box<dyn OutputHandle>, DaqError> {
        self.inner.output_handle(c)
    }
}

/// One supervised run of the lockstep virtual rig whose sensor reads NaN from the 10th
/// period on, with the watchdog of `rig run` running: how long from the board's NaN to
/// the board's vent.
fn fault_to_vent(cfg: &RigConfig) -> Duration {
    let injection = Injection {
        fault: InjectedFault::SensorNan,
        at_s: 0.0095,
    };
    let daq = VirtualDaq::new(cfg, &[injection]).expect("virtual rig");
    let clock = daq.lockstep_clock().expect("lockstep");
    let watchdog_handle = daq.output_handle(&cfg.signals.valve).expect("handle");
    let vent_v = cfg.calibration.valve_v(0.0);
    let (fault_at, vent_at) = (Arc::new(Mutex::new(None)), Arc::new(Mutex::new(None)));
    let board = Stopwatch {
        inner: daq,
        vent_v,
        fault_at: Arc::clone(&fault_at),
        vent_at: Arc::clone(&vent_at),
    };
    let backend =
        RigBackend::configure(cfg, Box::new(board), Pacing::Lockstep(clock)).expect("configure");
    let reference = cfg.reference(backend.configure_reading_m());
    let factory: WatchdogFactory = Box::new(move || {
        let vent: VentAction = Box::new(move || watchdog_handle.write(vent_v).is_ok());
        Some(vent)
    });
    let mut rig = Supervised::new(backend, cfg.supervisor_limits(), Some(factory));
    let controller = cfg
        .build_controller(&ControllerKind::AprcNdo.default_config())
        .expect("controller");
    let mut task = MuscleTask::new(controller, &reference);
    let settings = LoopSettings::new(1.0).expect("settings");
    let outcome = pma_loop::run(&mut rig, &mut task, &mut (), &settings).expect("a sound duration");
    assert!(matches!(outcome.end, pma_loop::End::Fault { .. }));
    let fault = fault_at.lock().expect("lock").expect("a NaN was read");
    let vent = vent_at.lock().expect("lock").expect("vented");
    vent.duration_since(fault)
}

fn vent(c: &mut Criterion) {
    let cfg = RigConfig::from_toml_str(EMBEDDED_VIRTUAL, "virtual.toml").expect("config");
    c.bench_function("rig_sensor_nan_to_vent", |b| {
        b.iter_custom(|iters| (0..iters).map(|_| fault_to_vent(&cfg)).sum())
    });
}

criterion_group!(benches, rig, vent);
criterion_main!(benches);
