//! The safety supervisor: a decorator around any single-muscle backend, between the
//! controller and the valve. It clamps and rate-limits commands; a NaN reading, a position
//! outside its window, a sensor stuck for N periods, a backend error or a loop stall (seen
//! by an independent watchdog thread, which vents on its own) vents and stops with the
//! fault named. A fault latches: the run is over.
use crate::config::Limits;
use pma_control::Measurement;
use pma_loop::{Backend, Started};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why the supervisor stopped a run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Fault<E: std::error::Error + 'static> {
    /// The reading is NaN (a broken wire, a saturated converter).
    #[error("sensor-nan: the position reading is NaN (no signal, or the converter saturated)")]
    SensorNan,
    /// The reading is outside the position window.
    #[error(
        "position-out: the muscle reads {position_m} m, outside the window {min_m}..{max_m} m"
    )]
    PositionOut {
        /// Reading (m).
        position_m: f64,
        /// Window (m).
        min_m: f64,
        /// Window (m).
        max_m: f64,
    },
    /// The reading has not changed for too long.
    #[error(
        "sensor-stuck: the position reading has not changed for {periods} periods ({position_m} m)"
    )]
    SensorStuck {
        /// Periods.
        periods: u32,
        /// The frozen reading (m).
        position_m: f64,
    },
    /// The backend (board) failed.
    #[error("daq-error: {0}")]
    Backend(#[source] E),
    /// The loop went silent; the watchdog vented.
    #[error("stall: the control loop was silent for {silent_ms:.1} ms (watchdog {timeout_ms:.1} ms); the watchdog vented")]
    Stall {
        /// Silence (ms).
        silent_ms: f64,
        /// Timeout (ms).
        timeout_ms: f64,
    },
}

impl<E: std::error::Error + 'static> Fault<E> {
    /// Short name (the `--inject` names, `fault` in the JSON and the log).
    pub fn name(&self) -> &'static str {
        match self {
            Fault::SensorNan => "sensor-nan",
            Fault::PositionOut { .. } => "position-out",
            Fault::SensorStuck { .. } => "sensor-stuck",
            Fault::Backend(_) => "daq-error",
            Fault::Stall { .. } => "stall",
        }
    }
}

/// Something that drives the valve to its safe state from any thread; returns whether the
/// write succeeded.
pub type VentAction = Box<dyn Fn() -> bool + Send + 'static>;

/// An independent thread that vents on its own when the loop stops kicking it.
pub struct Watchdog {
    shared: Arc<WatchdogShared>,
    thread: Option<std::thread::JoinHandle<()>>,
}

struct WatchdogShared {
    origin: Instant,
    last_kick_ns: AtomicU64,
    tripped_silence_ns: AtomicU64,
    vented: AtomicBool,
    stop: AtomicBool,
}

impl Watchdog {
    /// Starts watching: `vent` runs once if no kick comes for `timeout`.
    pub fn spawn(timeout: Duration, vent: VentAction) -> std::io::Result<Self> {
        let shared = Arc::new(WatchdogShared {
            origin: Instant::now(),
            last_kick_ns: AtomicU64::new(0),
            tripped_silence_ns: AtomicU64::new(0),
            vented: AtomicBool::new(false),
            stop: AtomicBool::new(false),
        });
        let s = Arc::clone(&shared);
        let poll = (timeout / 4).max(Duration::from_micros(200));
        let thread = std::thread::Builder::new()
            .name("pma-rig-watchdog".into())
            .spawn(move || loop {
                std::thread::sleep(poll);
                if s.stop.load(Ordering::Acquire) {
                    return;
                }
                let now = s.origin.elapsed().as_nanos() as u64;
                let silent = now.saturating_sub(s.last_kick_ns.load(Ordering::Acquire));
                if silent > timeout.as_nanos() as u64 {
                    let ok = vent();
                    s.vented.store(ok, Ordering::Release);
                    s.tripped_silence_ns.store(silent.max(1), Ordering::Release);
                    return;
                }
            })?;
        let w = Self {
            shared,
            thread: Some(thread),
        };
        w.kick();
        Ok(w)
    }

    /// The loop is alive.
    pub fn kick(&self) {
        let now = self.shared.origin.elapsed().as_nanos() as u64;
        self.shared.last_kick_ns.store(now, Ordering::Release);
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

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
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

/// Builds the watchdog's vent action when the run starts.
pub type WatchdogFactory = Box<dyn FnOnce() -> Option<VentAction> + Send>;

/// The supervisor around `B`.
pub struct Supervised<B> {
    inner: B,
    limits: Limits,
    period_s: f64,
    last_command_pa: f64,
    last_reading_bits: u64,
    same_readings: u32,
    watchdog_factory: Option<WatchdogFactory>,
    watchdog: Option<Watchdog>,
    watchdog_vented: bool,
}

impl<B> Supervised<B>
where
    B: Backend<Reading = Measurement, Command = f64>,
{
    /// `inner` under `limits` at `period_s`; `watchdog` makes the vent action of the
    /// watchdog thread when the run starts (`None`: no watchdog).
    pub fn new(inner: B, limits: Limits, period_s: f64, watchdog: Option<WatchdogFactory>) -> Self {
        Self {
            inner,
            limits,
            period_s,
            last_command_pa: 0.0,
            last_reading_bits: f64::NAN.to_bits(),
            same_readings: 0,
            watchdog_factory: watchdog,
            watchdog: None,
            watchdog_vented: false,
        }
    }

    /// The supervised backend.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// Whether the watchdog tripped and vented.
    pub fn watchdog_vented(&self) -> bool {
        self.watchdog_vented
    }

    fn watchdog_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.period_s * f64::from(self.limits.watchdog_periods))
    }

    fn check_watchdog(&mut self) -> Result<(), Fault<B::Error>> {
        let Some(w) = &self.watchdog else {
            return Ok(());
        };
        match w.tripped() {
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

    /// Checks a reading: finite, inside the window, not frozen.
    fn check_reading(&mut self, m: Measurement) -> Result<Measurement, Fault<B::Error>> {
        let x = m.position_m;
        if x.is_nan() {
            return Err(Fault::SensorNan);
        }
        let l = &self.limits;
        if !(x >= l.position_min_m && x <= l.position_max_m) {
            return Err(Fault::PositionOut {
                position_m: x,
                min_m: l.position_min_m,
                max_m: l.position_max_m,
            });
        }
        if x.to_bits() == self.last_reading_bits {
            self.same_readings += 1;
        } else {
            self.same_readings = 0;
            self.last_reading_bits = x.to_bits();
        }
        if l.sensor_stuck_periods > 0 && self.same_readings >= l.sensor_stuck_periods {
            return Err(Fault::SensorStuck {
                periods: self.same_readings,
                position_m: x,
            });
        }
        Ok(m)
    }

    /// Clamps to `[0, max]` (NaN vents) and limits the rate of change.
    fn limit(&self, command_pa: f64, dt_s: f64) -> f64 {
        let u = if command_pa.is_nan() {
            0.0
        } else {
            command_pa.clamp(0.0, self.limits.pressure_max_pa)
        };
        let step = self.limits.pressure_rate_max_pa_per_s * dt_s;
        u.clamp(self.last_command_pa - step, self.last_command_pa + step)
    }
}

impl<B> Backend for Supervised<B>
where
    B: Backend<Reading = Measurement, Command = f64>,
{
    type Reading = Measurement;
    type Command = f64;
    type Truth = B::Truth;
    type Error = Fault<B::Error>;

    fn start(&mut self) -> Result<Started<Measurement, f64>, Self::Error> {
        let started = self.inner.start().map_err(Fault::Backend)?;
        self.last_command_pa = started.command;
        let reading = self.check_reading(started.reading)?;
        if let Some(vent) = self.watchdog_factory.take().and_then(|f| f()) {
            self.watchdog = Watchdog::spawn(self.watchdog_timeout(), vent).ok();
        }
        Ok(Started { reading, ..started })
    }

    fn wait(&mut self, period_s: f64) -> Result<u32, Self::Error> {
        self.check_watchdog()?;
        let n = self.inner.wait(period_s).map_err(Fault::Backend)?;
        if let Some(w) = &self.watchdog {
            w.kick();
        }
        Ok(n)
    }

    fn read(&mut self) -> Result<Measurement, Self::Error> {
        let r = self.inner.read();
        // A read that hung (the stall the watchdog exists for) reports the stall.
        self.check_watchdog()?;
        let m = r.map_err(Fault::Backend)?;
        self.check_reading(m)
    }

    fn write(&mut self, command_pa: &f64) -> Result<f64, Self::Error> {
        self.check_watchdog()?;
        let u = self.limit(*command_pa, self.period_s);
        let applied = self.inner.write(&u).map_err(Fault::Backend)?;
        self.last_command_pa = applied;
        if let Some(w) = &self.watchdog {
            w.kick();
        }
        Ok(applied)
    }

    fn truth(&self) -> B::Truth {
        self.inner.truth()
    }

    /// Stops the watchdog, then vents through the backend.
    fn stop(&mut self) {
        if let Some(mut w) = self.watchdog.take() {
            w.shutdown();
            self.watchdog_vented |= w.vented();
        }
        self.inner.stop();
    }
}
