//! A rig run end to end: configure, supervise, log, run the loop on a dedicated (real-time
//! when permitted) thread, and report; venting on every exit path.
use crate::backend::{Pacing, RigBackend};
use crate::config::{ClockMode, Driver, RigConfig};
use crate::daq::{Daq, DaqError, OutputHandle};
use crate::error::RigError;
use crate::log::{LogSpec, LogSummary, RigLog};
use crate::replay::{
    format_line, CONFIG_BEGIN, CONFIG_END, EXCITATION_BEGIN, EXCITATION_END, GAINS_BEGIN,
    GAINS_END, REFERENCE_START,
};
use crate::timing::{enter_realtime, RealtimeStatus, TimingSummary};
use crate::virtual_daq::{Injection, VirtualDaq};
use pma_control::supervisor::{
    Alarm, Fault, Supervised, VentAction, WatchdogClock, WatchdogFactory,
};
use pma_control::{ControllerConfig, ExcitationSpec, MuscleStep, MuscleTask, Tracking};
use pma_loop::{End, LoopSettings, Recorder};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

/// The supervised rig, as recorders see it.
pub type Rig = Supervised<RigBackend>;

/// What a run may override in its configuration.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Duration (s) instead of the configuration's.
    pub duration_s: Option<f64>,
    /// Controller and gains instead of the configuration's.
    pub controller: Option<ControllerConfig>,
    /// Faults for the virtual rig.
    pub injections: Vec<Injection>,
    /// The virtual rig's clock instead of the configuration's.
    pub clock: Option<ClockMode>,
    /// Log path instead of the configuration's.
    pub log_path: Option<PathBuf>,
    /// Ask for `SCHED_FIFO` (or not) instead of the configuration's `realtime.fifo`.
    pub fifo: Option<bool>,
    /// Excite the muscle open loop (`rig excite`) instead of running the controller.
    pub excitation: Option<ExcitationSpec>,
    /// One line saying what ran (the program, the command line, the inputs), written into
    /// the log's header after its format line.
    pub provenance: Option<String>,
}

/// A run's outcome.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RigReport {
    /// Configuration name.
    pub config: String,
    /// `virtual` or `comedi`.
    pub driver: String,
    /// The device.
    pub device: String,
    /// `lockstep` or `realtime`.
    pub clock: String,
    /// Controller.
    pub controller: String,
    /// Whether every period ran.
    pub completed: bool,
    /// The fault that stopped the run (`interrupted` for SIGINT/SIGTERM), if any.
    pub fault: Option<String>,
    /// The fault's message.
    pub fault_detail: Option<String>,
    /// Whether the valve was vented at the end.
    pub vented: bool,
    /// Whether the watchdog vented on its own.
    pub watchdog_vented: bool,
    /// Control periods run.
    pub periods: u64,
    /// Deadlines missed (skipped).
    pub overruns: u64,
    /// Wake-up latency (us), median; null in lockstep.
    pub jitter_p50_us: f64,
    /// 99th percentile (us).
    pub jitter_p99_us: f64,
    /// Maximum (us).
    pub jitter_max_us: f64,
    /// The loop's own work per period (us), median.
    pub compute_p50_us: f64,
    /// 99th percentile (us).
    pub compute_p99_us: f64,
    /// Maximum (us).
    pub compute_max_us: f64,
    /// Whether the loop ran under `SCHED_FIFO`.
    pub realtime: bool,
    /// What real-time set-up was refused.
    pub realtime_warnings: Vec<String>,
    /// MAE on the measured position (m).
    pub mae_m: f64,
    /// IAE (mean |e|) on the measured position (m).
    pub iae_m: f64,
    /// RTE (%).
    pub rte_percent: f64,
    /// Command variation (bar/s).
    pub command_variation_bar_per_s: f64,
    /// The log.
    pub log: String,
    /// Rows in the log.
    pub log_rows: u64,
    /// Records lost (the writer fell behind).
    pub log_dropped: u64,
    /// Why the log is incomplete, if it is.
    pub log_error: Option<String>,
}

impl RigReport {
    /// Process exit status: 0 completed, 130 interrupted, 3 any fault.
    pub fn exit_code(&self) -> i32 {
        match self.fault.as_deref() {
            None => 0,
            Some("interrupted") => 130,
            Some(_) => 3,
        }
    }
}

/// Vents registered outputs from the panic hook, before unwinding starts.
type VentRegistry = Mutex<Vec<(u64, Box<dyn OutputHandle>, f64)>>;

fn vent_registry() -> &'static VentRegistry {
    static REGISTRY: OnceLock<VentRegistry> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if let Some(reg) = REGISTRY.get() {
                if let Ok(list) = reg.try_lock() {
                    for (_, handle, volts) in list.iter() {
                        let _ = handle.write(*volts);
                    }
                }
            }
            previous(info);
        }));
        Mutex::new(Vec::new())
    })
}

/// Keeps a valve registered with the panic hook while alive.
struct PanicVent(u64);

impl PanicVent {
    fn register(handle: Box<dyn OutputHandle>, vent_v: f64) -> Self {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let id = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if let Ok(mut list) = vent_registry().lock() {
            list.push((id, handle, vent_v));
        }
        Self(id)
    }
}

impl Drop for PanicVent {
    fn drop(&mut self) {
        if let Ok(mut list) = vent_registry().lock() {
            list.retain(|(id, _, _)| *id != self.0);
        }
    }
}

/// Opens the configured board: the virtual rig, or a Comedi device.
pub fn open_daq(config: &RigConfig, injections: &[Injection]) -> Result<Box<dyn Daq>, RigError> {
    match config.device.driver {
        Driver::Virtual => Ok(Box::new(VirtualDaq::new(config, injections)?)),
        Driver::Comedi => {
            if !injections.is_empty() {
                return Err(RigError::Field {
                    field: "--inject",
                    message: "faults can only be injected into the virtual rig".into(),
                });
            }
            let path = &config.device.path;
            crate::comedi::open_comedi(path).map_err(|e| match e {
                // Name the device even when the driver is not built in.
                DaqError::Unsupported(message) => RigError::Daq(DaqError::Open {
                    device: path.clone(),
                    message,
                }),
                e => RigError::Daq(e),
            })
        }
    }
}

fn pacing_of(
    config: &RigConfig,
    daq: &dyn Daq,
    lockstep: Option<crate::virtual_daq::LockstepClock>,
) -> Pacing {
    let _ = daq;
    match lockstep {
        Some(clock) if config.device.driver == Driver::Virtual => Pacing::Lockstep(clock),
        _ => Pacing::Realtime(Duration::from_secs_f64(config.period_s)),
    }
}

/// Configures the rig without activating it (`rig check`): the board checked, the vent
/// value written, the sensor read.
pub fn check(config: &RigConfig) -> Result<RigBackend, RigError> {
    let mut cfg = config.clone();
    if let Some(v) = cfg.virtual_rig.as_mut() {
        v.clock = ClockMode::Lockstep;
    }
    let daq = VirtualOrBoard::open(&cfg, &[])?;
    let pacing = pacing_of(&cfg, daq.daq.as_ref(), daq.lockstep);
    RigBackend::configure(&cfg, daq.daq, pacing)
}

struct VirtualOrBoard {
    daq: Box<dyn Daq>,
    lockstep: Option<crate::virtual_daq::LockstepClock>,
}

impl VirtualOrBoard {
    fn open(config: &RigConfig, injections: &[Injection]) -> Result<Self, RigError> {
        if config.device.driver == Driver::Virtual {
            let v = VirtualDaq::new(config, injections)?;
            let lockstep = v.lockstep_clock();
            Ok(Self {
                daq: Box::new(v),
                lockstep,
            })
        } else {
            Ok(Self {
                daq: open_daq(config, injections)?,
                lockstep: None,
            })
        }
    }
}

/// The log header: version, the configuration with the gains and where the reference
/// starts, for replay.
fn header(
    config: &RigConfig,
    gains: &ControllerConfig,
    options: &RunOptions,
    reference_start_m: f64,
) -> Result<String, RigError> {
    let excitation = options.excitation.as_ref();
    let mut cfg = config.clone();
    cfg.control.gains = None;
    cfg.control.controller = gains.kind().as_str().to_owned();
    let toml = toml::to_string(&cfg).map_err(|e| RigError::Field {
        field: "config",
        message: format!("cannot serialise the configuration for the log: {e}"),
    })?;
    let excitation = match excitation {
        Some(e) => {
            let text = toml::to_string(e).map_err(|e| RigError::Field {
                field: "excitation",
                message: format!("cannot serialise the excitation for the log: {e}"),
            })?;
            format!("{EXCITATION_BEGIN}\n{text}{EXCITATION_END}\n")
        }
        None => String::new(),
    };
    // One line, whatever the command line held (the header is one `#` comment per line).
    let provenance = match &options.provenance {
        Some(line) => format!("{}\n", line.replace(['\n', '\r'], " ")),
        None => String::new(),
    };
    Ok(format!(
        "{}\n{provenance}{CONFIG_BEGIN}\n{toml}{CONFIG_END}\n{GAINS_BEGIN}\n{}{GAINS_END}\n{excitation}{REFERENCE_START}{reference_start_m:?}",
        format_line(),
        gains.to_toml_string()
    ))
}

/// The configuration of a run: the file's, with the run's overrides, validated.
fn configured(config: &RigConfig, options: &RunOptions) -> Result<RigConfig, RigError> {
    let mut cfg = config.clone();
    if let Some(d) = options.duration_s {
        cfg.duration_s = d;
    }
    if let Some(p) = &options.log_path {
        cfg.log_path = p.clone();
    }
    if let (Some(clock), Some(v)) = (options.clock, cfg.virtual_rig.as_mut()) {
        v.clock = clock;
    }
    if let Some(fifo) = options.fifo {
        cfg.realtime.fifo = fifo;
    }
    cfg.validate()?;
    check_injections(
        &options.injections,
        cfg.duration_s,
        cfg.signals.pressure.is_some(),
    )?;
    Ok(cfg)
}

/// The rig configured and everything that guards it, before the valve goes live.
struct Armed {
    rig: Rig,
    reference: pma_control::SmoothStart,
    header: String,
    alarm: Arc<Alarm>,
    vent_v: f64,
    realtime_pacing: bool,
    clock: &'static str,
    device: String,
    _panic_vent: PanicVent,
}

/// Opens and configures the board (the vent value written, the sensor read), registers
/// the valve with the panic hook and puts the supervisor, its watchdog and the log's
/// alarm around the backend.
fn arm(cfg: &RigConfig, gains: &ControllerConfig, options: &RunOptions) -> Result<Armed, RigError> {
    let injections = &options.injections;
    let board = VirtualOrBoard::open(cfg, injections)?;
    let clock = if board.lockstep.is_some() {
        "lockstep"
    } else {
        "realtime"
    };
    let watchdog_clock = watchdog_clock(board.lockstep.clone());
    let pacing = pacing_of(cfg, board.daq.as_ref(), board.lockstep);
    let realtime_pacing = matches!(pacing, Pacing::Realtime(_));
    let backend = RigBackend::configure(cfg, board.daq, pacing)?;
    let device = backend.device().to_owned();
    let start_m = backend.configure_reading_m();
    let vent_v = backend.vent_v();
    let header = header(cfg, gains, options, start_m)?;
    let panic_vent = PanicVent::register(backend.valve_handle()?, vent_v);
    let watchdog_handle = backend.valve_handle()?;
    let factory: WatchdogFactory = Box::new(move || {
        let vent: VentAction = Box::new(move || watchdog_handle.write(vent_v).is_ok());
        Some(vent)
    });
    let alarm = Alarm::new();
    let rig = Supervised::new(backend, cfg.supervisor_limits(), Some(factory))
        .with_watchdog_clock(watchdog_clock)
        .with_alarm(Arc::clone(&alarm));
    Ok(Armed {
        rig,
        reference: cfg.reference(start_m),
        header,
        alarm,
        vent_v,
        realtime_pacing,
        clock,
        device,
        _panic_vent: panic_vent,
    })
}

/// The clock the watchdog measures silence on: a lockstep rig's simulated periods (a
/// loaded machine slows the loop and its plant alike: nothing stalls in simulated time
/// but a simulated hang), the wall clock for everything that follows wall time.
fn watchdog_clock(lockstep: Option<crate::virtual_daq::LockstepClock>) -> WatchdogClock {
    match lockstep {
        Some(clock) => WatchdogClock::Simulated(Arc::new(move || clock.elapsed())),
        None => WatchdogClock::Wall,
    }
}

/// How the loop thread ended.
struct Finished {
    end: Ended,
    /// The run's covered time when the loop returned (`None`: it panicked).
    ran_s: Option<f64>,
    rt: RealtimeStatus,
    log: LogSummary,
}

/// The loop's thread: real-time set-up, the log, the loop itself with a panic caught.
fn loop_thread<R>(
    armed: &mut Armed,
    cfg: &RigConfig,
    task: &mut MuscleTask<'_>,
    recorders: &mut (Tracking<Rig>, R),
    settings: &LoopSettings,
) -> Result<Finished, RigError>
where
    R: Recorder<Rig, MuscleStep>,
{
    // Real-time set-up first, so that the log's header says what was obtained; the log is
    // still opened before anything goes live.
    let rt = if armed.realtime_pacing {
        enter_realtime(cfg.realtime.fifo, cfg.realtime.priority)
    } else {
        no_rt()
    };
    let header = format!(
        "{}\n{}",
        armed.header,
        realtime_line(&rt, armed.realtime_pacing)
    );
    let mut log = RigLog::create(
        &crate::log::expand_time(&cfg.log_path),
        LogSpec {
            header: &header,
            reference: Box::new(armed.reference),
            vent_valve_v: armed.vent_v,
            wait_when_full: !armed.realtime_pacing,
            alarm: Arc::clone(&armed.alarm),
        },
    )?;
    let (tracking, recorder) = recorders;
    let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| {
        pma_loop::run(
            &mut armed.rig,
            task,
            &mut (&mut *tracking, &mut log, &mut *recorder),
            settings,
        )
    }));
    let (end, ran_s) = match outcome {
        Ok(o) => {
            let o = o?;
            (Ended::Loop(o.end), Some(o.ran_s))
        }
        Err(_) => {
            // The panic hook vented already, and the loop's guard through the backend;
            // close the log with the fault.
            log.vent_row(Some("controller-panic"));
            (Ended::Panic, None)
        }
    };
    Ok(Finished {
        end,
        ran_s,
        rt,
        log: log.finish(),
    })
}

/// Runs `body` on its own thread (the loop's, made real-time when permitted).
fn on_loop_thread<T: Send>(
    body: impl FnOnce() -> Result<T, RigError> + Send,
) -> Result<T, RigError> {
    std::thread::scope(|s| {
        let worker = std::thread::Builder::new()
            .name("pma-rig-loop".into())
            .spawn_scoped(s, body);
        match worker {
            Ok(h) => h.join().unwrap_or_else(|_| {
                Err(RigError::Io {
                    path: "pma-rig-loop thread".into(),
                    message: "the loop thread panicked outside the loop".into(),
                })
            }),
            Err(e) => Err(RigError::Io {
                path: "pma-rig-loop thread".into(),
                message: format!("cannot start the loop thread: {e}"),
            }),
        }
    })
}

/// Runs the rig of `config` (gain files relative to `config_dir`), `recorder` observing
/// every period (Rerun, say). `stop` ends the run early (SIGINT, SIGTERM). The valve is
/// vented on every exit path: the end of the run, a fault, `stop`, a panic.
pub fn run<R>(
    config: &RigConfig,
    config_dir: &Path,
    options: &RunOptions,
    stop: &AtomicBool,
    recorder: R,
) -> Result<RigReport, RigError>
where
    R: Recorder<Rig, MuscleStep> + Send,
{
    let cfg = configured(config, options)?;
    let gains = match options.controller {
        Some(c) => c,
        None => cfg
            .control
            .controller_config(cfg.control_kind()?, config_dir)?,
    };
    let settings = LoopSettings::new(cfg.duration_s)?.with_stop_flag(stop);
    settings.periods(cfg.period_s)?;
    let controller = cfg.controller_for(&gains, options.excitation.as_ref())?;
    let controller_name = controller.name().to_owned();
    let mut armed = arm(&cfg, &gains, options)?;
    let reference = armed.reference;
    let mut task = MuscleTask::new(controller, &reference);
    // A rig knows nothing but its reading.
    let mut recorders = (
        Tracking::<Rig>::new(|reading, _| reading.position_m),
        recorder,
    );
    let finished =
        on_loop_thread(|| loop_thread(&mut armed, &cfg, &mut task, &mut recorders, &settings))?;
    Ok(report(
        &cfg,
        &armed,
        controller_name,
        &recorders.0,
        finished,
    ))
}

/// The report of a finished run.
fn report(
    cfg: &RigConfig,
    armed: &Armed,
    controller: String,
    tracking: &Tracking<Rig>,
    finished: Finished,
) -> RigReport {
    let Finished {
        end,
        ran_s,
        rt,
        log,
    } = finished;
    let rig = &armed.rig;
    let timing = rig.inner().timing();
    let periods = tracking.summary(1.0, None).stats.samples as u64;
    let summary = tracking.summary(ran_s.unwrap_or(periods as f64 * cfg.period_s), None);
    let (mut fault, mut detail) = end.fault();
    if let (None, Some(e)) = (&fault, &log.error) {
        // The run completed but its log did not: not a success.
        fault = Some("log-error".into());
        detail = Some(format!("the log cannot be written ({e})"));
    }
    RigReport {
        config: cfg.name.clone(),
        driver: match cfg.device.driver {
            Driver::Virtual => "virtual".into(),
            Driver::Comedi => "comedi".into(),
        },
        device: armed.device.clone(),
        clock: armed.clock.into(),
        controller,
        completed: matches!(end, Ended::Loop(End::Completed)) && log.error.is_none(),
        fault,
        fault_detail: detail,
        vented: rig.inner().vented() || rig.watchdog_vented(),
        watchdog_vented: rig.watchdog_vented(),
        periods,
        overruns: timing.map_or(0, |t| t.overruns),
        jitter_p50_us: timing.map_or(f64::NAN, |t| t.jitter_p50_us),
        jitter_p99_us: timing.map_or(f64::NAN, |t| t.jitter_p99_us),
        jitter_max_us: timing.map_or(f64::NAN, |t| t.jitter_max_us),
        compute_p50_us: timing.map_or(f64::NAN, |t| t.compute_p50_us),
        compute_p99_us: timing.map_or(f64::NAN, |t| t.compute_p99_us),
        compute_max_us: timing.map_or(f64::NAN, |t: TimingSummary| t.compute_max_us),
        realtime: rt.is_realtime(),
        realtime_warnings: rt.warnings,
        mae_m: summary.stats.mae_m,
        iae_m: summary.stats.iae_m,
        rte_percent: summary.stats.rte_percent,
        command_variation_bar_per_s: summary.command_variation_pa_per_s / 1e5,
        log: log.path.display().to_string(),
        log_rows: log.rows,
        log_dropped: log.dropped,
        log_error: log.error,
    }
}

/// Every injected fault must fall inside the run (after the activation at 0 s, before the
/// end): one that cannot fire would make a test of a fault path pass without the fault.
fn check_injections(
    injections: &[Injection],
    duration_s: f64,
    pressure_channel: bool,
) -> Result<(), RigError> {
    for i in injections {
        if i.fault == crate::InjectedFault::PressureHigh && !pressure_channel {
            return Err(RigError::Field {
                field: "--inject",
                message: format!(
                    "pressure-high@{} cannot fire: the rig has no pressure channel ([signals] pressure)",
                    i.at_s
                ),
            });
        }
        if !(i.at_s > 0.0 && i.at_s < duration_s) {
            return Err(RigError::Field {
                field: "--inject",
                message: format!(
                    "{}@{} cannot fire: the run lasts {duration_s} s and an injection must come after the activation (0 s) and before the end",
                    i.fault.name(),
                    i.at_s
                ),
            });
        }
    }
    Ok(())
}

/// The log header's line on the real-time set-up.
fn realtime_line(rt: &RealtimeStatus, realtime_pacing: bool) -> String {
    if !realtime_pacing {
        return "timing: lockstep (no wall clock)".into();
    }
    let mut line = format!(
        "timing: absolute deadlines; SCHED_FIFO {}; mlockall {}; timer slack 1 ns {}",
        rt.fifo_priority
            .map_or("no".to_owned(), |p| format!("yes (priority {p})")),
        if rt.memory_locked { "yes" } else { "no" },
        if rt.timer_slack_1ns { "yes" } else { "no" },
    );
    for w in &rt.warnings {
        line.push_str("; warning: ");
        line.push_str(w);
    }
    line
}

fn no_rt() -> RealtimeStatus {
    RealtimeStatus {
        fifo_priority: None,
        memory_locked: false,
        timer_slack_1ns: false,
        warnings: Vec::new(),
    }
}

enum Ended {
    Loop(End<Fault<crate::daq::DaqError>>),
    Panic,
}

impl Ended {
    fn fault(&self) -> (Option<String>, Option<String>) {
        match self {
            Ended::Loop(End::Completed) => (None, None),
            Ended::Loop(End::Stopped) => (
                Some("interrupted".into()),
                Some("stopped by a signal (SIGINT or SIGTERM)".into()),
            ),
            Ended::Loop(End::Fault { error, period, .. }) => (
                Some(error.name().into()),
                Some(format!("period {period}: {error}")),
            ),
            Ended::Panic => (
                Some("controller-panic".into()),
                Some("the control loop panicked (see the message above)".into()),
            ),
        }
    }
}
