use super::*;
use std::fmt;

/// A backend that logs every call and fails on request.
#[derive(Default)]
struct Dummy {
    period: f64,
    calls: Vec<String>,
    fail_read_at: Option<u64>,
    fail_start: bool,
    skip_at: Option<u64>,
    reads: u64,
    x: f64,
    stopped: u32,
}

#[derive(Debug)]
struct DummyError(&'static str);

impl fmt::Display for DummyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0)
    }
}

impl std::error::Error for DummyError {}

impl Backend for Dummy {
    type Reading = f64;
    type Command = f64;
    type Truth = u64;
    type Error = DummyError;
    fn period_s(&self) -> f64 {
        self.period
    }
    fn start(&mut self) -> Result<Started<f64, f64>, DummyError> {
        self.calls.push("start".into());
        if self.fail_start {
            return Err(DummyError("no board"));
        }
        Ok(Started {
            t_s: 10.0,
            reading: self.x,
            command: -1.0,
        })
    }
    fn wait(&mut self) -> Result<u32, DummyError> {
        self.calls.push(format!("wait {}", self.period));
        let n = if self.skip_at == Some(self.reads + 1) {
            3
        } else {
            1
        };
        Ok(n)
    }
    fn read(&mut self) -> Result<f64, DummyError> {
        self.reads += 1;
        self.calls.push("read".into());
        if self.fail_read_at == Some(self.reads) {
            return Err(DummyError("sensor"));
        }
        Ok(self.x)
    }
    fn write(&mut self, c: &f64) -> Result<f64, DummyError> {
        self.calls.push(format!("write {c}"));
        self.x = *c;
        Ok(c.min(100.0))
    }
    fn truth(&self) -> u64 {
        self.reads
    }
    fn stop(&mut self) {
        self.stopped += 1;
        self.calls.push("stop".into());
    }
}

/// Counts up: each command is the reading plus one.
struct Inc {
    acts_at_start: bool,
    dts: Vec<f64>,
}

impl Task for Inc {
    type Reading = f64;
    type Command = f64;
    type Output = f64;
    fn start(&mut self, _t: f64, x: &f64, _rest: &f64, _p: f64) -> Option<f64> {
        self.acts_at_start.then_some(*x + 1.0)
    }
    fn update(&mut self, _t: f64, x: &f64, dt: f64) -> f64 {
        self.dts.push(dt);
        *x + 1.0
    }
    fn command(out: &f64) -> f64 {
        *out
    }
}

#[derive(Default)]
struct Log {
    rows: Vec<(u64, f64, f64, f64, f64)>,
    started: Option<(f64, f64)>,
    ended: Option<(String, f64)>,
}

impl Recorder<Dummy, f64> for Log {
    fn start(&mut self, s: &Start<'_, Dummy>) {
        self.started = Some((s.t_s, *s.held));
    }
    fn record(&mut self, p: &Period<'_, Dummy, f64>) {
        self.rows
            .push((p.index, p.t_s, *p.held, *p.output, *p.written));
    }
    fn end(&mut self, end: &End<DummyError>, t: f64) {
        let what = match end {
            End::Completed => "completed".to_owned(),
            End::Stopped => "stopped".to_owned(),
            End::Fault { period, error, .. } => format!("fault {period} {error}"),
        };
        self.ended = Some((what, t));
    }
}

fn inc(acts_at_start: bool) -> Inc {
    Inc {
        acts_at_start,
        dts: Vec::new(),
    }
}

#[test]
fn a_period_is_wait_read_update_write_and_the_run_ends_stopped() {
    let mut b = Dummy {
        period: 0.5,
        ..Dummy::default()
    };
    let mut log = Log::default();
    let s = LoopSettings::new(1.0).unwrap();
    let out = run(&mut b, &mut inc(false), &mut log, &s).unwrap();
    assert!(matches!(out.end, End::Completed));
    assert_eq!(out.periods, 2);
    assert_eq!(
        b.calls,
        ["start", "wait 0.5", "read", "write 1", "wait 0.5", "read", "write 2", "stop"]
    );
    assert_eq!(log.started, Some((10.0, -1.0)));
    // Time is t0 + k T; the first period holds the backend's resting command.
    assert_eq!(
        log.rows,
        vec![(1, 10.5, -1.0, 1.0, 1.0), (2, 11.0, 1.0, 2.0, 2.0)]
    );
    assert_eq!(log.ended, Some(("completed".into(), 11.0)));
}

#[test]
fn a_task_that_acts_at_start_has_its_command_held_over_the_first_period() {
    let mut b = Dummy {
        x: 5.0,
        period: 1.0,
        ..Dummy::default()
    };
    let mut log = Log::default();
    let s = LoopSettings::new(1.0).unwrap();
    run(&mut b, &mut inc(true), &mut log, &s).unwrap();
    assert_eq!(b.calls[..3], ["start", "write 6", "wait 1"]);
    assert_eq!(log.started, Some((10.0, 6.0)));
    assert_eq!(log.rows[0].2, 6.0);
}

#[test]
fn the_written_command_is_what_the_backend_applied() {
    let mut b = Dummy {
        x: 150.0,
        period: 1.0,
        ..Dummy::default()
    };
    let mut log = Log::default();
    run(
        &mut b,
        &mut inc(false),
        &mut log,
        &LoopSettings::new(2.0).unwrap(),
    )
    .unwrap();
    assert_eq!(log.rows[0].3, 151.0);
    assert_eq!(log.rows[0].4, 100.0);
    assert_eq!(log.rows[1].2, 100.0);
}

#[test]
fn a_read_error_stops_the_backend_and_names_the_period() {
    let mut b = Dummy {
        fail_read_at: Some(3),
        period: 1.0,
        ..Dummy::default()
    };
    let mut log = Log::default();
    let out = run(
        &mut b,
        &mut inc(false),
        &mut log,
        &LoopSettings::new(10.0).unwrap(),
    )
    .unwrap();
    assert!(
        matches!(out.end, End::Fault { period: 3, .. }),
        "{:?}",
        out.end
    );
    assert_eq!(out.periods, 2);
    assert_eq!(b.stopped, 1);
    assert_eq!(b.calls.last().map(String::as_str), Some("stop"));
    assert_eq!(log.ended, Some(("fault 3 sensor".into(), 12.0)));
    assert!(out.into_result().is_err());
}

#[test]
fn a_failed_start_still_stops_the_backend() {
    let mut b = Dummy {
        fail_start: true,
        period: 1.0,
        ..Dummy::default()
    };
    let out = run(
        &mut b,
        &mut inc(false),
        &mut (),
        &LoopSettings::new(1.0).unwrap(),
    )
    .unwrap();
    assert!(matches!(out.end, End::Fault { period: 0, .. }));
    assert_eq!(out.periods, 0);
    assert_eq!(b.calls, ["start", "stop"]);
}

#[test]
fn missed_periods_are_skipped_and_the_task_sees_the_longer_dt() {
    let mut b = Dummy {
        skip_at: Some(2),
        period: 1.0,
        ..Dummy::default()
    };
    let mut task = inc(false);
    let mut log = Log::default();
    let out = run(
        &mut b,
        &mut task,
        &mut log,
        &LoopSettings::new(5.0).unwrap(),
    )
    .unwrap();
    assert_eq!(task.dts, [1.0, 3.0, 1.0]);
    assert_eq!(out.periods, 3);
    assert_eq!(out.missed_periods, 2);
    let times: Vec<f64> = log.rows.iter().map(|r| r.1).collect();
    assert_eq!(times, [11.0, 14.0, 15.0]);
}

#[test]
fn a_raised_stop_flag_ends_the_run_stopped() {
    let flag = AtomicBool::new(true);
    let mut b = Dummy {
        period: 1.0,
        ..Dummy::default()
    };
    let s = LoopSettings::new(5.0).unwrap().with_stop_flag(&flag);
    let out = run(&mut b, &mut inc(false), &mut (), &s).unwrap();
    assert!(matches!(out.end, End::Stopped));
    assert_eq!(out.periods, 0);
    assert_eq!(b.stopped, 1);
}

#[test]
fn settings_reject_what_would_not_run() {
    let tenth = LoopSettings::new(1e-4).unwrap();
    assert!(matches!(
        tenth.periods(1e-3),
        Err(SettingsError::TooShort { .. })
    ));
    assert!(LoopSettings::new(1.0).unwrap().periods(0.0).is_err());
    assert!(LoopSettings::new(1.0).unwrap().periods(f64::NAN).is_err());
    assert!(LoopSettings::new(-1.0).is_err());
    assert!(LoopSettings::new(f64::INFINITY).is_err());
    assert_eq!(
        LoopSettings::new(20.0).unwrap().periods(1e-3).unwrap(),
        20_000
    );
    // A backend whose period does not fit the duration runs nothing.
    let mut b = Dummy {
        period: 1.0,
        ..Dummy::default()
    };
    assert!(run(&mut b, &mut inc(false), &mut (), &tenth).is_err());
    assert!(b.calls.is_empty());
}

/// Regression: `run` stopped the backend only on a normal return, so only the rig (with
/// its own catch_unwind, hook and drop guard) was safe when a task panicked.
#[test]
fn a_panicking_task_still_stops_the_backend() {
    struct Panics;
    impl Task for Panics {
        type Reading = f64;
        type Command = f64;
        type Output = f64;
        fn update(&mut self, _t: f64, _x: &f64, _dt: f64) -> f64 {
            panic!("a task that panics")
        }
        fn command(out: &f64) -> f64 {
            *out
        }
    }
    let mut b = Dummy {
        period: 1.0,
        ..Dummy::default()
    };
    let s = LoopSettings::new(3.0).unwrap();
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let _ = run(&mut b, &mut Panics, &mut (), &s);
    }));
    assert!(caught.is_err());
    assert_eq!(b.stopped, 1);
    assert_eq!(b.calls.last().map(String::as_str), Some("stop"));
}

#[test]
fn the_outcome_says_how_long_the_run_covered() {
    let mut b = Dummy {
        period: 1.0,
        fail_read_at: Some(3),
        ..Dummy::default()
    };
    let out = run(
        &mut b,
        &mut inc(false),
        &mut (),
        &LoopSettings::new(10.0).unwrap(),
    )
    .unwrap();
    assert_eq!(out.ran_s, 2.0);
    let mut b = Dummy {
        period: 0.5,
        ..Dummy::default()
    };
    let out = run(
        &mut b,
        &mut inc(false),
        &mut (),
        &LoopSettings::new(2.0).unwrap(),
    )
    .unwrap();
    assert_eq!(out.ran_s, 2.0);
}
