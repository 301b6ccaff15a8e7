//! The one closed loop of pma-exo, shared by the single-muscle bench, the exoskeleton leg,
//! the virtual rig and the real rig.
//!
//! - A [`Backend`] is what the loop drives: a simulation that integrates, or hardware that
//!   sleeps to a deadline. It has a lifecycle (start at rest, then read / write / wait
//!   every period, and a safe [`Backend::stop`] that cannot fail) and its reads, writes
//!   and waits return errors.
//! - A [`Task`] turns readings into commands (one muscle's controller and reference, or
//!   the leg's four controllers with their regulators).
//! - A [`Recorder`] observes every period (metrics, CSV, Rerun, a progress bar); `()` is
//!   the no-op recorder, and a tuple of recorders records into each.
//!
//! One period of [`run`], after [`Backend::start`]:
//! `wait (plant advances / deadline) -> read -> truth -> task.update -> write ->
//! task.applied -> record`.
//! The backend owns the period ([`Backend::period_s`]): a simulation integrates over it,
//! hardware sleeps to its deadlines. Any error stops the loop, brings the backend to its
//! safe state and is reported in the [`Outcome`] with the period it happened in; a panic
//! in the loop stops the backend too (a guard, as it unwinds). The loop allocates nothing
//! per period and knows nothing of rapier, rerun or any DAQ.
//!
//! ```
//! use pma_loop::{run, Backend, LoopSettings, Started, Task, End};
//! use std::convert::Infallible;
//!
//! /// A first-order plant `x' = u - x`, integrated exactly over periods of 10 ms.
//! struct Lag { x: f64, u: f64 }
//! impl Backend for Lag {
//!     type Reading = f64;
//!     type Command = f64;
//!     type Truth = f64;
//!     type Error = Infallible;
//!     fn period_s(&self) -> f64 { 0.01 }
//!     fn start(&mut self) -> Result<Started<f64, f64>, Infallible> {
//!         Ok(Started { t_s: 0.0, reading: self.x, command: self.u })
//!     }
//!     fn wait(&mut self) -> Result<u32, Infallible> {
//!         self.x = self.u + (self.x - self.u) * (-self.period_s()).exp();
//!         Ok(1)
//!     }
//!     fn read(&mut self) -> Result<f64, Infallible> { Ok(self.x) }
//!     fn write(&mut self, u: &f64) -> Result<f64, Infallible> { self.u = *u; Ok(*u) }
//!     fn truth(&self) -> f64 { self.x }
//!     fn stop(&mut self) { self.u = 0.0; }
//! }
//!
//! /// Proportional control towards 1.
//! struct P;
//! impl Task for P {
//!     type Reading = f64;
//!     type Command = f64;
//!     type Output = f64;
//!     fn update(&mut self, _t: f64, x: &f64, _dt: f64) -> f64 { 1.0 + 4.0 * (1.0 - x) }
//!     fn command(out: &f64) -> f64 { *out }
//! }
//!
//! let settings = LoopSettings::new(5.0).unwrap();
//! let mut plant = Lag { x: 0.0, u: 0.0 };
//! let outcome = run(&mut plant, &mut P, &mut (), &settings).unwrap();
//! assert!(matches!(outcome.end, End::Completed));
//! assert_eq!(outcome.periods, 500);
//! assert_eq!(outcome.ran_s, 5.0);
//! assert!((plant.x - 1.0).abs() < 1e-6);
//! assert_eq!(plant.u, 0.0); // stopped: the safe state
//! ```
#![warn(missing_docs)]

mod recorder;
pub mod signals;
pub mod step;

pub use recorder::{FnRecorder, Recorder};
pub use signals::{Channel, Schema, Signals};

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use thiserror::Error;

/// What a backend hands the loop when it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Started<R, C> {
    /// Time of the start (s): the loop's time origin.
    pub t_s: f64,
    /// The reading at the start.
    pub reading: R,
    /// The command the actuators hold now (held over the first period unless the task
    /// acts at once, see [`Task::start`]).
    pub command: C,
}

/// Something the loop drives: a simulated plant, or hardware.
///
/// Lifecycle: [`start`](Backend::start) once (the plant at rest, actuators live), then
/// every period [`wait`](Backend::wait), [`read`](Backend::read),
/// [`truth`](Backend::truth), [`write`](Backend::write); finally
/// [`stop`](Backend::stop), on every exit path. The backend owns the period.
pub trait Backend {
    /// What the sensors deliver each period.
    type Reading: Copy;
    /// What the actuators take each period.
    type Command: Copy;
    /// What the backend knows beyond the reading: the true state in a simulation (for
    /// metrics and logs), raw telemetry on hardware.
    type Truth: Copy;
    /// Why a read, write or wait failed.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The control period (s): the one owner of it.
    fn period_s(&self) -> f64;
    /// Activates the backend at rest and returns the first reading.
    fn start(&mut self) -> Result<Started<Self::Reading, Self::Command>, Self::Error>;
    /// Lets one period pass with the last command held: a simulation integrates over
    /// [`period_s`](Backend::period_s), hardware sleeps to the next deadline. Returns how
    /// many periods elapsed (1, or more when deadlines were missed and skipped).
    fn wait(&mut self) -> Result<u32, Self::Error>;
    /// Reads the sensors.
    fn read(&mut self) -> Result<Self::Reading, Self::Error>;
    /// Sends a command; returns the command as applied (after the backend's clamping or
    /// a supervisor's limits).
    fn write(&mut self, command: &Self::Command) -> Result<Self::Command, Self::Error>;
    /// The state beyond the reading, at the instant of the last read.
    fn truth(&self) -> Self::Truth;
    /// Brings the actuators to their safe state (vent). Cannot fail: does what it can.
    fn stop(&mut self);
}

/// Turns readings into commands, one period at a time.
pub trait Task {
    /// Reading consumed (the backend's).
    type Reading;
    /// Command produced (the backend's).
    type Command: Copy;
    /// Everything one update produces (command, references, controller states).
    type Output;

    /// Restarts at `t_s` from the backend's first reading, the actuators holding
    /// `resting`. Returns an output only if the task acts on that reading at once; then
    /// its command is held over the first period instead of `resting`.
    fn start(
        &mut self,
        t_s: f64,
        reading: &Self::Reading,
        resting: &Self::Command,
        period_s: f64,
    ) -> Option<Self::Output> {
        let _ = (t_s, reading, resting, period_s);
        None
    }
    /// One period: the reading taken at `t_s`, `dt_s` after the previous one.
    fn update(&mut self, t_s: f64, reading: &Self::Reading, dt_s: f64) -> Self::Output;
    /// The command in an output.
    fn command(output: &Self::Output) -> Self::Command;
    /// The backend applied `written` for the last output's command (it may differ:
    /// clamped, rate-limited). Tasks whose controllers remember their commands take it.
    fn applied(&mut self, written: &Self::Command) {
        let _ = written;
    }
}

/// The start of a run as the recorders see it.
pub struct Start<'a, B: Backend> {
    /// Time of the start (s).
    pub t_s: f64,
    /// The backend's first reading.
    pub reading: &'a B::Reading,
    /// The backend's state at that reading.
    pub truth: &'a B::Truth,
    /// The command the backend held at rest.
    pub resting: &'a B::Command,
    /// The command held over the first period (the resting one, or the task's).
    pub held: &'a B::Command,
    /// The backend.
    pub backend: &'a B,
}

/// One period as the recorders see it.
pub struct Period<'a, B: Backend, O> {
    /// Period index, from 1.
    pub index: u64,
    /// Time of the reading (s).
    pub t_s: f64,
    /// Time since the previous reading (s).
    pub dt_s: f64,
    /// The reading.
    pub reading: &'a B::Reading,
    /// The backend's state at the reading.
    pub truth: &'a B::Truth,
    /// The command that was held over the period that just ended.
    pub held: &'a B::Command,
    /// The task's output.
    pub output: &'a O,
    /// The command written for the next period (as applied).
    pub written: &'a B::Command,
    /// The backend, for anything else a recorder wants to look at (poses, ...).
    pub backend: &'a B,
}

/// How a run ended.
#[derive(Debug)]
pub enum End<E> {
    /// Every period ran.
    Completed,
    /// The stop flag was raised (Ctrl-C, SIGTERM, a caller).
    Stopped,
    /// The backend failed; it was stopped (vented) at once.
    Fault {
        /// Period in which it happened (0: while starting).
        period: u64,
        /// Time (s) of the last period that completed.
        t_s: f64,
        /// The error.
        error: E,
    },
}

/// A finished run.
#[derive(Debug)]
pub struct Outcome<E> {
    /// Control periods executed (task updates).
    pub periods: u64,
    /// Periods the backend reported missed (skipped deadlines).
    pub missed_periods: u64,
    /// Time of the last reading (s).
    pub t_end_s: f64,
    /// How long the run covered (s): the duration asked for when it completed, its
    /// periods otherwise (stopped or faulted). Figures per second of run divide by it.
    pub ran_s: f64,
    /// Wall-clock time of the loop (s).
    pub wall_s: f64,
    /// How it ended.
    pub end: End<E>,
}

impl<E> Outcome<E> {
    /// `Ok(self)` unless the run ended with a fault.
    pub fn into_result(self) -> Result<Outcome<std::convert::Infallible>, E> {
        let end = match self.end {
            End::Completed => End::Completed,
            End::Stopped => End::Stopped,
            End::Fault { error, .. } => return Err(error),
        };
        Ok(Outcome {
            periods: self.periods,
            missed_periods: self.missed_periods,
            t_end_s: self.t_end_s,
            ran_s: self.ran_s,
            wall_s: self.wall_s,
            end,
        })
    }
}

/// Invalid loop settings.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SettingsError {
    /// The period is not a finite number of seconds > 0.
    #[error("period_s = {0} is invalid: must be a finite number of seconds > 0")]
    Period(f64),
    /// The duration is not finite and >= 0.
    #[error("duration = {0} s is invalid: must be a finite number of seconds > 0")]
    Duration(f64),
    /// The duration is shorter than one period.
    #[error("a duration of {duration_s} s is shorter than one control period ({period_s} s): nothing would run")]
    TooShort {
        /// Duration (s).
        duration_s: f64,
        /// Period (s).
        period_s: f64,
    },
}

/// How long the loop runs, and what can stop it early. The period is the backend's.
#[derive(Debug, Clone, Copy)]
pub struct LoopSettings<'a> {
    duration_s: f64,
    stop: Option<&'a AtomicBool>,
}

impl<'a> LoopSettings<'a> {
    /// A run of `duration_s` (finite, > 0), rounded to whole periods of the backend.
    pub fn new(duration_s: f64) -> Result<Self, SettingsError> {
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(SettingsError::Duration(duration_s));
        }
        Ok(Self {
            duration_s,
            stop: None,
        })
    }

    /// Ends the run early (as [`End::Stopped`]) once `flag` is raised.
    pub fn with_stop_flag(mut self, flag: &'a AtomicBool) -> Self {
        self.stop = Some(flag);
        self
    }

    /// Number of periods of `period_s` the run covers (its duration rounded to whole
    /// periods): at least one.
    pub fn periods(&self, period_s: f64) -> Result<u64, SettingsError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(SettingsError::Period(period_s));
        }
        let periods = (self.duration_s / period_s).round();
        if periods < 1.0 {
            return Err(SettingsError::TooShort {
                duration_s: self.duration_s,
                period_s,
            });
        }
        Ok(periods as u64)
    }

    /// The duration asked for (s).
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    fn stop_requested(&self) -> bool {
        self.stop.is_some_and(|f| f.load(Ordering::Relaxed))
    }
}

/// Stops the backend when dropped unless disarmed: a panic unwinding through the loop
/// leaves it in its safe state.
struct StopOnUnwind<'b, B: Backend> {
    backend: &'b mut B,
    armed: bool,
}

impl<B: Backend> Drop for StopOnUnwind<'_, B> {
    fn drop(&mut self) {
        if self.armed {
            self.backend.stop();
        }
    }
}

/// Runs `task` against `backend` for `settings`, with `recorder` observing every period.
///
/// The backend is stopped (its safe state) on every exit path, before the recorder hears
/// how the run ended; a panic in the loop stops it as it unwinds. Time is `t_0 + n T` with
/// `n` the periods elapsed and `T` the backend's period, so a simulation sees exactly the
/// instants `k T`. Fails before anything runs if the duration is not a period at least.
pub fn run<B, T, R>(
    backend: &mut B,
    task: &mut T,
    recorder: &mut R,
    settings: &LoopSettings,
) -> Result<Outcome<B::Error>, SettingsError>
where
    B: Backend,
    T: Task<Reading = B::Reading, Command = B::Command>,
    R: Recorder<B, T::Output>,
{
    let period_s = backend.period_s();
    let periods = settings.periods(period_s)?;
    let wall = Instant::now();
    let mut state = LoopState {
        periods: 0,
        elapsed: 0,
        t_s: 0.0,
    };
    let mut guard = StopOnUnwind {
        backend,
        armed: true,
    };
    let end = match drive(guard.backend, task, recorder, settings, periods, &mut state) {
        Ok(end) => end,
        Err((period, error)) => End::Fault {
            period,
            t_s: state.t_s,
            error,
        },
    };
    guard.armed = false;
    guard.backend.stop();
    recorder.end(&end, state.t_s);
    let ran_s = match end {
        End::Completed => settings.duration_s(),
        _ => state.periods as f64 * period_s,
    };
    Ok(Outcome {
        periods: state.periods,
        missed_periods: state.elapsed.saturating_sub(state.periods),
        t_end_s: state.t_s,
        ran_s,
        wall_s: wall.elapsed().as_secs_f64(),
        end,
    })
}

struct LoopState {
    periods: u64,
    elapsed: u64,
    t_s: f64,
}

fn drive<B, T, R>(
    backend: &mut B,
    task: &mut T,
    recorder: &mut R,
    settings: &LoopSettings,
    periods: u64,
    state: &mut LoopState,
) -> Result<End<B::Error>, (u64, B::Error)>
where
    B: Backend,
    T: Task<Reading = B::Reading, Command = B::Command>,
    R: Recorder<B, T::Output>,
{
    let period = backend.period_s();
    let started = backend.start().map_err(|e| (0, e))?;
    let t0 = started.t_s;
    state.t_s = t0;
    let truth = backend.truth();
    let mut held = match task.start(t0, &started.reading, &started.command, period) {
        Some(out) => {
            let written = backend.write(&T::command(&out)).map_err(|e| (0, e))?;
            task.applied(&written);
            written
        }
        None => started.command,
    };
    recorder.start(&Start {
        t_s: t0,
        reading: &started.reading,
        truth: &truth,
        resting: &started.command,
        held: &held,
        backend,
    });
    while state.elapsed < periods {
        if settings.stop_requested() {
            return Ok(End::Stopped);
        }
        let k = state.periods + 1;
        let n = backend.wait().map_err(|e| (k, e))?.max(1);
        let dt = f64::from(n) * period;
        state.elapsed += u64::from(n);
        let t = t0 + state.elapsed as f64 * period;
        let reading = backend.read().map_err(|e| (k, e))?;
        let truth = backend.truth();
        let output = task.update(t, &reading, dt);
        let written = backend.write(&T::command(&output)).map_err(|e| (k, e))?;
        task.applied(&written);
        state.periods += 1;
        state.t_s = t;
        recorder.record(&Period {
            index: state.periods,
            t_s: t,
            dt_s: dt,
            reading: &reading,
            truth: &truth,
            held: &held,
            output: &output,
            written: &written,
            backend,
        });
        held = written;
    }
    Ok(End::Completed)
}

#[cfg(test)]
mod tests;
