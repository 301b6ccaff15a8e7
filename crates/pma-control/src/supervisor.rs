//! The safety supervisor: a decorator around any backend, between the task and the
//! actuators (one muscle's valve on the rig, the leg's four). It clamps every command to
//! `[0, max]` and limits its rate; a NaN reading, a reading outside its window, a sensor
//! stuck for N periods, a backend error, a loop that misses its deadlines, a raised alarm
//! (the log) or a loop stall (seen by an independent watchdog thread, which vents on its
//! own) vents and stops with the fault named. A fault latches: the run is over.
use crate::Measurement;
use pma_loop::{Backend, Started};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why the supervisor stopped a run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Fault<E: std::error::Error + 'static> {
    /// A reading is NaN (a broken wire, a saturated converter).
    #[error("sensor-nan: the {channel} reading is NaN (no signal, or the converter saturated)")]
    SensorNan {
        /// Which reading.
        channel: &'static str,
    },
    /// A reading is outside its window.
    #[error(
        "position-out: the {channel} reads {value} {unit}, outside the window {min}..{max} {unit}"
    )]
    PositionOut {
        /// Which reading.
        channel: &'static str,
        /// Its value.
        value: f64,
        /// Window.
        min: f64,
        /// Window.
        max: f64,
        /// Unit.
        unit: &'static str,
    },
    /// A reading has not changed for too long.
    #[error("sensor-stuck: the {channel} reading has not changed for {periods} periods ({value})")]
    SensorStuck {
        /// Which reading.
        channel: &'static str,
        /// Periods.
        periods: u32,
        /// The frozen reading.
        value: f64,
    },
    /// The backend (board, plant) failed.
    #[error("{0}")]
    Backend(#[source] E),
    /// The loop went silent; the watchdog vented.
    #[error("stall: the control loop was silent for {silent_ms:.1} ms (watchdog {timeout_ms:.1} ms); the watchdog vented")]
    Stall {
        /// Silence (ms).
        silent_ms: f64,
        /// Timeout (ms).
        timeout_ms: f64,
    },
    /// The loop cannot keep its period: too many deadlines missed.
    #[error("timing: the loop cannot keep its period: {detail}")]
    Timing {
        /// What was missed.
        detail: String,
    },
    /// The log cannot be written: a run that is not recorded does not go on.
    #[error("log-error: the log cannot be written ({message})")]
    Log {
        /// Why.
        message: String,
    },
}

impl<E: std::error::Error + 'static> Fault<E> {
    /// Short name (the `--inject` names, `fault` in the JSON and the log).
    pub fn name(&self) -> &'static str {
        match self {
            Fault::SensorNan { .. } => "sensor-nan",
            Fault::PositionOut { .. } => "position-out",
            Fault::SensorStuck { .. } => "sensor-stuck",
            Fault::Backend(_) => "daq-error",
            Fault::Stall { .. } => "stall",
            Fault::Timing { .. } => "timing",
            Fault::Log { .. } => "log-error",
        }
    }
}

/// Something that drives the valve to its safe state from any thread; returns whether the
/// write succeeded.
pub type VentAction = Box<dyn Fn() -> bool + Send + 'static>;

/// The clock a watchdog measures the loop's silence on.
#[derive(Clone, Default)]
pub enum WatchdogClock {
    /// Wall time: a real board, or a virtual rig following wall time. Anything that holds
    /// the loop (a hung driver call, the scheduler, a loaded machine) is silence.
    #[default]
    Wall,
    /// Simulated time since the start, which only the loop advances (a lockstep virtual
    /// rig): a loaded machine slows the loop and its clock alike, so only silence in
    /// simulated time (a simulated hang) trips the watchdog.
    Simulated(Arc<dyn Fn() -> Duration + Send + Sync>),
}

impl WatchdogClock {
    /// Nanoseconds since `origin` (wall) or since the simulation started.
    fn now_ns(&self, origin: Instant) -> u64 {
        let elapsed = match self {
            WatchdogClock::Wall => origin.elapsed(),
            WatchdogClock::Simulated(now) => now(),
        };
        u64::try_from(elapsed.as_nanos()).unwrap_or(u64::MAX)
    }
}

/// An independent thread that vents on its own when the loop stops kicking it. Its sleep
/// between checks is interruptible: shutting it down never waits for a poll to end. The
/// loop checks it too ([`Watchdog::check`]) after every call that could hang, so a silence
/// is caught even when the thread has not been scheduled since.
pub struct Watchdog {
    shared: Arc<WatchdogShared>,
    thread: Option<std::thread::JoinHandle<()>>,
}

struct WatchdogShared {
    origin: Instant,
    clock: WatchdogClock,
    timeout_ns: u64,
    last_kick_ns: AtomicU64,
    tripped_silence_ns: AtomicU64,
    vented: AtomicBool,
    /// The vent runs once, from whichever side sees the silence first.
    vent: Mutex<Option<VentAction>>,
    stop: Mutex<bool>,
    wake: Condvar,
}

impl WatchdogShared {
    /// Sleeps up to `poll`; returns whether a shutdown was asked for.
    fn sleep(&self, poll: Duration) -> bool {
        let stop = self.stop.lock().unwrap_or_else(|p| p.into_inner());
        let (stop, _) = self
            .wake
            .wait_timeout_while(stop, poll, |stop| !*stop)
            .unwrap_or_else(|p| p.into_inner());
        *stop
    }

    fn now_ns(&self) -> u64 {
        self.clock.now_ns(self.origin)
    }

    /// Vents (once) if the loop has been silent longer than the timeout; returns whether
    /// the watchdog has tripped.
    fn trip_if_silent(&self) -> bool {
        if self.tripped_silence_ns.load(Ordering::Acquire) != 0 {
            return true;
        }
        let silent = self
            .now_ns()
            .saturating_sub(self.last_kick_ns.load(Ordering::Acquire));
        if silent <= self.timeout_ns {
            return false;
        }
        let mut vent = self.vent.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(vent) = vent.take() {
            self.vented.store(vent(), Ordering::Release);
            self.tripped_silence_ns
                .store(silent.max(1), Ordering::Release);
        }
        true
    }
}

impl Watchdog {
    /// Starts watching on the wall clock: `vent` runs once if no kick comes for `timeout`.
    pub fn spawn(timeout: Duration, vent: VentAction) -> std::io::Result<Self> {
        Self::spawn_on(WatchdogClock::Wall, timeout, vent)
    }

    /// Starts watching on `clock`: `vent` runs once if no kick comes for `timeout` of it.
    pub fn spawn_on(
        clock: WatchdogClock,
        timeout: Duration,
        vent: VentAction,
    ) -> std::io::Result<Self> {
        let shared = Arc::new(WatchdogShared {
            origin: Instant::now(),
            clock,
            timeout_ns: u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX),
            last_kick_ns: AtomicU64::new(0),
            tripped_silence_ns: AtomicU64::new(0),
            vented: AtomicBool::new(false),
            vent: Mutex::new(Some(vent)),
            stop: Mutex::new(false),
            wake: Condvar::new(),
        });
        // The first kick before the thread looks: the start is not silence.
        shared
            .last_kick_ns
            .store(shared.now_ns(), Ordering::Release);
        let s = Arc::clone(&shared);
        let poll = (timeout / 4).max(Duration::from_micros(200));
        let thread = std::thread::Builder::new()
            .name("pma-rig-watchdog".into())
            .spawn(move || while !s.sleep(poll) && !s.trip_if_silent() {})?;
        Ok(Self {
            shared,
            thread: Some(thread),
        })
    }

    /// The loop is alive.
    pub fn kick(&self) {
        let now = self.shared.now_ns();
        self.shared.last_kick_ns.store(now, Ordering::Release);
    }

    /// Trips now if the loop has been silent too long (the vent runs here then, unless
    /// the thread ran it already); returns the silence that tripped it, if it tripped.
    pub fn check(&self) -> Option<Duration> {
        self.shared.trip_if_silent();
        self.tripped()
    }

    /// The silence that tripped it, if it tripped.
    pub fn tripped(&self) -> Option<Duration> {
        match self.shared.tripped_silence_ns.load(Ordering::Acquire) {
            0 => None,
            ns => Some(Duration::from_nanos(ns)),
        }
    }

    /// Whether its vent succeeded.
    pub fn vented(&self) -> bool {
        self.shared.vented.load(Ordering::Acquire)
    }

    /// Stops the thread at once (its sleep is interrupted) and waits for it.
    pub fn shutdown(&mut self) {
        {
            let mut stop = self.shared.stop.lock().unwrap_or_else(|p| p.into_inner());
            *stop = true;
        }
        self.shared.wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Raised from outside the loop by something the run depends on (the log's writer thread):
/// the supervisor turns it into a fault at the next period.
#[derive(Debug, Default)]
pub struct Alarm {
    raised: AtomicBool,
    message: Mutex<Option<String>>,
}

impl Alarm {
    /// A new, quiet alarm.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Raises it with `message`; the first message is kept.
    pub fn raise(&self, message: impl Into<String>) {
        if let Ok(mut m) = self.message.lock() {
            m.get_or_insert_with(|| message.into());
        }
        self.raised.store(true, Ordering::Release);
    }

    /// Whether it was raised.
    pub fn is_raised(&self) -> bool {
        self.raised.load(Ordering::Acquire)
    }

    /// The message it was raised with.
    pub fn message(&self) -> String {
        self.message
            .lock()
            .ok()
            .and_then(|m| m.clone())
            .unwrap_or_default()
    }
}

/// Periods over which the share of missed deadlines is measured.
pub const OVERRUN_WINDOW_PERIODS: u64 = 1000;

/// Counts missed deadlines: consecutive ones in a single wait, and their share over
/// windows of [`OVERRUN_WINDOW_PERIODS`].
#[derive(Debug, Clone, Copy, Default)]
struct OverrunCounter {
    window_elapsed: u64,
    window_missed: u64,
    waited: bool,
}

impl OverrunCounter {
    /// A wait that took `elapsed` periods; the fault if a limit is passed.
    fn record<E: std::error::Error>(
        &mut self,
        elapsed: u32,
        limits: &SupervisorLimits,
    ) -> Result<(), Fault<E>> {
        let missed = elapsed.saturating_sub(1);
        // The first wake-up also pays for the activation (threads, the log's first row):
        // its misses count in the share, not as a stall of the loop.
        let first = !std::mem::replace(&mut self.waited, true);
        if !first && missed > limits.overrun_max_consecutive_periods {
            return Err(Fault::Timing {
                detail: format!(
                    "{missed} consecutive periods missed in one wake-up (limit {})",
                    limits.overrun_max_consecutive_periods
                ),
            });
        }
        self.window_elapsed += u64::from(elapsed.max(1));
        self.window_missed += u64::from(missed);
        if self.window_elapsed >= OVERRUN_WINDOW_PERIODS {
            let share = self.window_missed as f64 / self.window_elapsed as f64;
            if share > limits.overrun_max_share {
                return Err(Fault::Timing {
                    detail: format!(
                        "{} of the last {} periods missed ({:.1} %, limit {:.1} %)",
                        self.window_missed,
                        self.window_elapsed,
                        share * 100.0,
                        limits.overrun_max_share * 100.0
                    ),
                });
            }
            self.window_elapsed = 0;
            self.window_missed = 0;
        }
        Ok(())
    }
}

/// Builds the watchdog's vent action when the run starts.
pub type WatchdogFactory = Box<dyn FnOnce() -> Option<VentAction> + Send>;

/// The command the supervisor applies: clamped to `[0, max_pa]` (NaN vents), its change
/// from `last_pa` limited to `rate_max_pa_per_s` over `dt_s` (replay recomputes it from a
/// log).
pub fn limit_command(
    command_pa: f64,
    last_pa: f64,
    max_pa: f64,
    rate_max_pa_per_s: f64,
    dt_s: f64,
) -> f64 {
    let u = if command_pa.is_nan() {
        0.0
    } else {
        command_pa.clamp(0.0, max_pa)
    };
    let step = rate_max_pa_per_s * dt_s;
    u.clamp(last_pa - step, last_pa + step)
}

/// A reading or a command as channels of numbers: one muscle's position, a leg's joint
/// angles, one or four pressures.
pub trait Channels: Copy {
    /// Number of channels.
    const COUNT: usize;
    /// Channel `i`.
    fn channel(&self, i: usize) -> f64;
    /// Sets channel `i`.
    fn set_channel(&mut self, i: usize, value: f64);
    /// Every channel at zero.
    fn zeroed() -> Self;
}

impl Channels for f64 {
    const COUNT: usize = 1;
    fn zeroed() -> Self {
        0.0
    }
    fn channel(&self, _: usize) -> f64 {
        *self
    }
    fn set_channel(&mut self, _: usize, value: f64) {
        *self = value;
    }
}

impl Channels for Measurement {
    const COUNT: usize = 1;
    fn zeroed() -> Self {
        Measurement::default()
    }
    fn channel(&self, _: usize) -> f64 {
        self.position_m
    }
    fn set_channel(&mut self, _: usize, value: f64) {
        self.position_m = value;
    }
}

impl<const N: usize> Channels for [f64; N] {
    const COUNT: usize = N;
    fn zeroed() -> Self {
        [0.0; N]
    }
    fn channel(&self, i: usize) -> f64 {
        self[i]
    }
    fn set_channel(&mut self, i: usize, value: f64) {
        self[i] = value;
    }
}

/// The window a reading must stay in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadingWindow {
    /// The reading's name (`position`, `hip angle`).
    pub name: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// Lowest admissible value.
    pub min: f64,
    /// Highest admissible value.
    pub max: f64,
}

/// What a supervisor enforces. Command limits apply to every command channel; each
/// reading channel has its window.
#[derive(Debug, Clone, PartialEq)]
pub struct SupervisorLimits {
    /// Highest pressure command (Pa); commands are clamped to `[0, max]`.
    pub pressure_max_pa: f64,
    /// Fastest command change (Pa/s); faster commands are rate-limited.
    pub pressure_rate_max_pa_per_s: f64,
    /// One window per reading channel.
    pub windows: Vec<ReadingWindow>,
    /// A reading identical for this many periods is a stuck sensor (0: not checked).
    pub sensor_stuck_periods: u32,
    /// The loop silent for this many periods trips the watchdog (0: no watchdog).
    pub watchdog_periods: u32,
    /// A wake-up that misses more than this many deadlines in a row is a timing fault.
    pub overrun_max_consecutive_periods: u32,
    /// A share of missed deadlines above this over [`OVERRUN_WINDOW_PERIODS`] is a timing
    /// fault.
    pub overrun_max_share: f64,
}

/// The supervisor around `B`.
pub struct Supervised<B: Backend> {
    inner: B,
    limits: SupervisorLimits,
    last_commands: B::Command,
    last_reading_bits: Vec<u64>,
    same_readings: Vec<u32>,
    watchdog_factory: Option<WatchdogFactory>,
    watchdog_clock: WatchdogClock,
    watchdog: Option<Watchdog>,
    watchdog_vented: bool,
    alarm: Option<Arc<Alarm>>,
    overruns: OverrunCounter,
}

impl<B> Supervised<B>
where
    B: Backend,
    B::Reading: Channels,
    B::Command: Channels,
{
    /// `inner` under `limits` (one window per reading channel); `watchdog` makes the vent
    /// action of the watchdog thread when the run starts (`None`: no watchdog). Everything
    /// the supervisor needs per period is allocated here.
    pub fn new(inner: B, limits: SupervisorLimits, watchdog: Option<WatchdogFactory>) -> Self {
        let n = B::Reading::COUNT;
        Self {
            inner,
            limits,
            last_commands: B::Command::zeroed(),
            last_reading_bits: vec![f64::NAN.to_bits(); n],
            same_readings: vec![0; n],
            watchdog_factory: watchdog,
            watchdog_clock: WatchdogClock::Wall,
            watchdog: None,
            watchdog_vented: false,
            alarm: None,
            overruns: OverrunCounter::default(),
        }
    }

    /// The watchdog measures silence on `clock` instead of the wall clock (a lockstep
    /// simulation's periods).
    pub fn with_watchdog_clock(mut self, clock: WatchdogClock) -> Self {
        self.watchdog_clock = clock;
        self
    }

    /// Faults the run at the next period once `alarm` is raised (the log's writer).
    pub fn with_alarm(mut self, alarm: Arc<Alarm>) -> Self {
        self.alarm = Some(alarm);
        self
    }

    fn check_alarm(&self) -> Result<(), Fault<B::Error>> {
        match &self.alarm {
            Some(a) if a.is_raised() => Err(Fault::Log {
                message: a.message(),
            }),
            _ => Ok(()),
        }
    }

    /// The supervised backend.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// The supervised backend, given back.
    pub fn into_inner(self) -> B {
        self.inner
    }

    /// The supervised backend, to change it between runs.
    pub fn inner_mut(&mut self) -> &mut B {
        &mut self.inner
    }

    /// Whether the watchdog tripped and vented.
    pub fn watchdog_vented(&self) -> bool {
        self.watchdog_vented
    }

    fn watchdog_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.inner.period_s() * f64::from(self.limits.watchdog_periods))
    }

    fn check_watchdog(&mut self) -> Result<(), Fault<B::Error>> {
        let Some(w) = &self.watchdog else {
            return Ok(());
        };
        match w.check() {
            None => Ok(()),
            Some(silence) => {
                self.watchdog_vented = w.vented();
                Err(Fault::Stall {
                    silent_ms: silence.as_secs_f64() * 1e3,
                    timeout_ms: self.watchdog_timeout().as_secs_f64() * 1e3,
                })
            }
        }
    }

    /// Checks every reading channel: finite, inside its window, not frozen.
    fn check_reading(&mut self, r: B::Reading) -> Result<B::Reading, Fault<B::Error>> {
        for (i, w) in self
            .limits
            .windows
            .iter()
            .enumerate()
            .take(B::Reading::COUNT)
        {
            let x = r.channel(i);
            if x.is_nan() {
                return Err(Fault::SensorNan { channel: w.name });
            }
            if !(x >= w.min && x <= w.max) {
                return Err(Fault::PositionOut {
                    channel: w.name,
                    value: x,
                    min: w.min,
                    max: w.max,
                    unit: w.unit,
                });
            }
            if x.to_bits() == self.last_reading_bits[i] {
                self.same_readings[i] += 1;
            } else {
                self.same_readings[i] = 0;
                self.last_reading_bits[i] = x.to_bits();
            }
            let stuck = self.limits.sensor_stuck_periods;
            if stuck > 0 && self.same_readings[i] >= stuck {
                return Err(Fault::SensorStuck {
                    channel: w.name,
                    periods: self.same_readings[i],
                    value: x,
                });
            }
        }
        Ok(r)
    }

    /// Every command channel clamped and rate-limited from the last applied one.
    fn limit(&self, command: &B::Command, dt_s: f64) -> B::Command {
        let mut out = *command;
        for i in 0..B::Command::COUNT {
            out.set_channel(
                i,
                limit_command(
                    command.channel(i),
                    self.last_commands.channel(i),
                    self.limits.pressure_max_pa,
                    self.limits.pressure_rate_max_pa_per_s,
                    dt_s,
                ),
            );
        }
        out
    }
}

/// Read access to the supervised backend's own methods (a leg's poses, a rig's telemetry):
/// only the loop's calls go through the supervisor.
impl<B: Backend> std::ops::Deref for Supervised<B> {
    type Target = B;
    fn deref(&self) -> &B {
        &self.inner
    }
}

impl<B> Backend for Supervised<B>
where
    B: Backend,
    B::Reading: Channels,
    B::Command: Channels,
{
    type Reading = B::Reading;
    type Command = B::Command;
    type Truth = B::Truth;
    type Error = Fault<B::Error>;

    fn start(&mut self) -> Result<Started<B::Reading, B::Command>, Self::Error> {
        let started = self.inner.start().map_err(Fault::Backend)?;
        self.last_commands = started.command;
        let reading = self.check_reading(started.reading)?;
        if self.limits.watchdog_periods > 0 {
            if let Some(vent) = self.watchdog_factory.take().and_then(|f| f()) {
                self.watchdog =
                    Watchdog::spawn_on(self.watchdog_clock.clone(), self.watchdog_timeout(), vent)
                        .ok();
            }
        }
        Ok(Started { reading, ..started })
    }

    fn period_s(&self) -> f64 {
        self.inner.period_s()
    }

    fn wait(&mut self) -> Result<u32, Self::Error> {
        self.check_watchdog()?;
        self.check_alarm()?;
        let n = self.inner.wait().map_err(Fault::Backend)?;
        if let Some(w) = &self.watchdog {
            w.kick();
        }
        self.overruns.record(n, &self.limits)?;
        Ok(n)
    }

    fn read(&mut self) -> Result<B::Reading, Self::Error> {
        let r = self.inner.read();
        // A read that hung (the stall the watchdog exists for) reports the stall.
        self.check_watchdog()?;
        let m = r.map_err(Fault::Backend)?;
        self.check_reading(m)
    }

    fn write(&mut self, command: &B::Command) -> Result<B::Command, Self::Error> {
        self.check_watchdog()?;
        let u = self.limit(command, self.inner.period_s());
        let applied = self.inner.write(&u).map_err(Fault::Backend)?;
        self.last_commands = applied;
        if let Some(w) = &self.watchdog {
            w.kick();
        }
        Ok(applied)
    }

    fn truth(&self) -> B::Truth {
        self.inner.truth()
    }

    /// Vents through the backend first, then stops the watchdog: nothing delays the vent.
    fn stop(&mut self) {
        self.inner.stop();
        if let Some(mut w) = self.watchdog.take() {
            w.shutdown();
            self.watchdog_vented |= w.vented();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;
    use std::sync::atomic::AtomicU32;

    /// A muscle that reads NaN from `nan_at` on, and waits `elapsed` periods per wait;
    /// it records when it was vented.
    struct Scripted {
        period: u32,
        nan_at: u32,
        elapsed: u32,
        vented_at: Arc<Mutex<Option<Instant>>>,
        faulted_at: Option<Instant>,
    }

    impl Scripted {
        fn new(nan_at: u32, elapsed: u32) -> Self {
            Self {
                period: 0,
                nan_at,
                elapsed,
                vented_at: Arc::new(Mutex::new(None)),
                faulted_at: None,
            }
        }
    }

    impl Backend for Scripted {
        type Reading = Measurement;
        type Command = f64;
        type Truth = ();
        type Error = Infallible;
        fn start(&mut self) -> Result<Started<Measurement, f64>, Infallible> {
            Ok(Started {
                t_s: 0.0,
                reading: Measurement { position_m: 0.01 },
                command: 0.0,
            })
        }
        fn period_s(&self) -> f64 {
            0.001
        }
        fn wait(&mut self) -> Result<u32, Infallible> {
            self.period += 1;
            Ok(self.elapsed)
        }
        fn read(&mut self) -> Result<Measurement, Infallible> {
            let x = if self.period >= self.nan_at {
                self.faulted_at.get_or_insert_with(Instant::now);
                f64::NAN
            } else {
                0.01 + f64::from(self.period) * 1e-6
            };
            Ok(Measurement { position_m: x })
        }
        fn write(&mut self, u: &f64) -> Result<f64, Infallible> {
            Ok(*u)
        }
        fn truth(&self) {}
        fn stop(&mut self) {
            if let Ok(mut v) = self.vented_at.lock() {
                v.get_or_insert_with(Instant::now);
            }
        }
    }

    fn limits() -> SupervisorLimits {
        SupervisorLimits {
            pressure_max_pa: 6e5,
            pressure_rate_max_pa_per_s: 2e8,
            windows: vec![ReadingWindow {
                name: "position",
                unit: "m",
                min: -0.018,
                max: 0.045,
            }],
            sensor_stuck_periods: 0,
            watchdog_periods: 50,
            overrun_max_consecutive_periods: 10,
            overrun_max_share: 0.05,
        }
    }

    /// A watchdog that never trips within the test, with its vent counted.
    fn quiet_watchdog(timeout_periods: u32) -> (SupervisorLimits, WatchdogFactory, Arc<AtomicU32>) {
        let vents = Arc::new(AtomicU32::new(0));
        let counted = Arc::clone(&vents);
        let factory: WatchdogFactory = Box::new(move || {
            let vent: VentAction = Box::new(move || {
                counted.fetch_add(1, Ordering::SeqCst);
                true
            });
            Some(vent)
        });
        let l = SupervisorLimits {
            watchdog_periods: timeout_periods,
            ..limits()
        };
        (l, factory, vents)
    }

    /// Regression: `Supervised::stop` joined the watchdog (asleep for a quarter of its
    /// timeout) before venting, so a fault left the valve at its last command for up to
    /// 12.5 ms with the default configuration and 9 s with a long watchdog. The vent now
    /// comes first; here the watchdog sleeps 2.5 s between checks.
    #[test]
    fn a_fault_vents_before_the_watchdog_is_joined() {
        let (l, factory, vents) = quiet_watchdog(10_000);
        let backend = Scripted::new(5, 1);
        let vented_at = Arc::clone(&backend.vented_at);
        let mut rig = Supervised::new(backend, l, Some(factory));
        rig.start().expect("start");
        let mut fault = None;
        for _ in 0..10 {
            rig.wait().expect("wait");
            if let Err(f) = rig.read() {
                fault = Some(f);
                break;
            }
        }
        assert_eq!(
            fault,
            Some(Fault::SensorNan {
                channel: "position"
            })
        );
        rig.stop();
        let faulted = rig.inner().faulted_at.expect("fault seen");
        let vented = vented_at.lock().unwrap().expect("vented");
        let delay = vented.duration_since(faulted);
        // The old order took at least one watchdog poll (2.5 s here).
        assert!(
            delay < Duration::from_millis(250),
            "vented {delay:?} after the fault"
        );
        assert_eq!(vents.load(Ordering::SeqCst), 0, "the watchdog did not trip");
    }

    /// Regression: the watchdog slept through its whole poll before seeing a shutdown, so
    /// `watchdog_periods = 4294967295` hung the process for minutes. Its sleep is now
    /// interrupted by the shutdown.
    #[test]
    fn a_watchdog_with_a_long_timeout_shuts_down_at_once() {
        let mut w = Watchdog::spawn(Duration::from_secs(3600), Box::new(|| true)).expect("spawn");
        let t0 = Instant::now();
        w.shutdown();
        assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", t0.elapsed());
        assert!(w.tripped().is_none());
    }

    /// A simulated clock the test advances by hand (ns).
    fn simulated_clock() -> (WatchdogClock, Arc<AtomicU64>) {
        let ns = Arc::new(AtomicU64::new(0));
        let read = Arc::clone(&ns);
        let clock = WatchdogClock::Simulated(Arc::new(move || {
            Duration::from_nanos(read.load(Ordering::SeqCst))
        }));
        (clock, ns)
    }

    fn counted_vent() -> (VentAction, Arc<AtomicU32>) {
        let vents = Arc::new(AtomicU32::new(0));
        let counted = Arc::clone(&vents);
        let vent: VentAction = Box::new(move || {
            counted.fetch_add(1, Ordering::SeqCst);
            true
        });
        (vent, vents)
    }

    /// Regression: the watchdog of a lockstep virtual run measured silence on the wall
    /// clock, so under CPU load a run with a 10 ms watchdog faulted `stall` at random,
    /// although nothing stalls in simulated time. On a simulated clock, wall time is not
    /// silence; simulated time without a kick is.
    #[test]
    fn a_watchdog_on_a_simulated_clock_ignores_wall_time_and_trips_on_simulated_silence() {
        let (clock, ns) = simulated_clock();
        let (vent, vents) = counted_vent();
        let timeout = Duration::from_millis(10);
        let mut w = Watchdog::spawn_on(clock, timeout, vent).expect("spawn");
        // Ten timeouts of wall time, one period of simulated time: alive.
        std::thread::sleep(10 * timeout);
        ns.store(1_000_000, Ordering::SeqCst);
        assert_eq!(w.check(), None);
        w.kick();
        // A simulated hang of 0.5 s: tripped at once, vented once.
        ns.store(501_000_000, Ordering::SeqCst);
        assert_eq!(w.check(), Some(Duration::from_millis(500)));
        assert_eq!(w.check(), Some(Duration::from_millis(500)));
        w.shutdown();
        assert_eq!(vents.load(Ordering::SeqCst), 1);
        assert!(w.vented());
    }

    /// On the wall clock, the loop's own check finds a silence longer than the timeout
    /// whether or not the watchdog's thread has looked yet; the vent runs once either way.
    #[test]
    fn the_loop_finds_a_wall_clock_silence_without_waiting_for_the_watchdog_thread() {
        let (vent, vents) = counted_vent();
        let w = Watchdog::spawn(Duration::from_millis(20), vent).expect("spawn");
        std::thread::sleep(Duration::from_millis(40));
        let silence = w.check().expect("tripped");
        assert!(silence > Duration::from_millis(20), "{silence:?}");
        assert_eq!(w.check(), Some(silence));
        assert_eq!(vents.load(Ordering::SeqCst), 1);
    }

    /// Regression: a real-time run at `period_s = 1e-5` missed 160,898 deadlines and ended
    /// "completed". Missing more than the limit in a row, or too large a share, is now a
    /// timing fault that vents.
    #[test]
    fn a_loop_that_cannot_keep_time_is_a_timing_fault() {
        // 12 deadlines missed in one wake-up (limit 10); the first wake-up, which pays for
        // the activation, only counts in the share.
        let mut rig = Supervised::new(Scripted::new(u32::MAX, 13), limits(), None);
        rig.start().expect("start");
        rig.wait().expect("the first wake-up");
        let e = rig.wait().expect_err("timing fault");
        assert_eq!(e.name(), "timing");
        assert!(e.to_string().contains("12 consecutive"), "{e}");
        // Two periods each wake-up: half the deadlines missed (limit 5 %).
        let mut rig = Supervised::new(Scripted::new(u32::MAX, 2), limits(), None);
        rig.start().expect("start");
        let mut periods = 0;
        let e = loop {
            match rig.wait() {
                Ok(n) => periods += n,
                Err(e) => break e,
            }
            assert!(periods < 10_000, "no fault");
        };
        assert_eq!(e.name(), "timing");
        assert!(periods < 1000, "{periods}");
        // One missed deadline now and then is not a fault.
        let mut rig = Supervised::new(Scripted::new(u32::MAX, 1), limits(), None);
        rig.start().expect("start");
        for _ in 0..5000 {
            rig.wait().expect("keeps time");
        }
    }

    #[test]
    fn a_raised_alarm_is_a_log_fault_at_the_next_period() {
        let alarm = Alarm::new();
        let mut rig = Supervised::new(Scripted::new(u32::MAX, 1), limits(), None)
            .with_alarm(Arc::clone(&alarm));
        rig.start().expect("start");
        rig.wait().expect("quiet");
        alarm.raise("No space left on device (os error 28)");
        let e = rig.wait().expect_err("log fault");
        assert_eq!(e.name(), "log-error");
        assert!(e.to_string().contains("No space left"), "{e}");
    }
}
