//! The CLI's runs from Python: `single`, `simulate`, `pendulum`, each assembled by
//! `pma_exo::setup` exactly as the CLI assembles it.
use crate::convert::{json_to_py, Columns};
use crate::errors::{leg_err, py_err, to_py};
use pma_bench::{run_single_until, Sample};
use pma_control::ControllerKind;
use pma_exo::setup::{
    LegArgs, LegRun, PendulumArgs, PendulumRun, RefName, SingleArgs, SingleRun, SizeArgs, SizeRun,
    Spasticity,
};
use pma_leg::TrainerSample;
use pma_loop::Period;
use pma_studies::pendulum::PendulumSample;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

/// A controller's name (`aprc-ndo`, `aprc`, `psmc`, `ndo-smc`, `sta`, `pid`).
fn controller_kind(name: Option<&str>) -> PyResult<Option<ControllerKind>> {
    name.map(|n| n.parse::<ControllerKind>().map_err(py_err))
        .transpose()
}

/// A control mode by its name as on the command line (`None`: the scenario's).
fn mode_of(name: Option<&str>) -> PyResult<Option<pma_exo::setup::Mode>> {
    name.map(|n| choice("mode", n)).transpose()
}

/// A value of a choice, by its name as on the command line.
fn choice<T: clap::ValueEnum>(what: &str, name: &str) -> PyResult<T> {
    T::from_str(name, false).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value())
            .map(|v| v.get_name().to_owned())
            .collect();
        crate::PmaError::new_err(format!(
            "unknown {what} `{name}` (expected one of: {})",
            names.join(", ")
        ))
    })
}

/// The result dict: the series' columns, then `metrics`.
fn result<'py, F>(
    py: Python<'py>,
    columns: Columns<F>,
    metrics: &serde_json::Value,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    columns.into_dict(&dict)?;
    dict.set_item("metrics", json_to_py(py, metrics)?)?;
    Ok(dict)
}

/// One muscle on the paper's bench under one controller: `pma-exo single`.
///
/// Returns a dict of 1-D float64 arrays, one per period, named as the CLI's CSV columns
/// (`t_s`, `reference_m`, `position_m`, `pressure_cmd_pa`, `pressure_pa`, `proxy_m`,
/// `s_p`, `s_q`, `gain_hat`, `disturbance_hat`, `measured_m`, `force_n`,
/// `velocity_estimate_m_s`), and `metrics`: the dict `single --json` prints (without
/// its provenance).
#[pyfunction]
#[pyo3(signature = (plant = "ideal", controller = None, gains = None, reference = "sine", duration = 20.0))]
pub fn single<'py>(
    py: Python<'py>,
    plant: &str,
    controller: Option<&str>,
    gains: Option<PathBuf>,
    reference: &str,
    duration: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let r = SingleRun::assemble(&SingleArgs {
        plant,
        controller: controller_kind(controller)?,
        gains: gains.as_deref(),
        reference: choice::<RefName>("reference", reference)?,
        duration_s: duration,
    })
    .map_err(to_py)?;
    let periods = r.spec.periods().map_err(py_err)?;
    let (columns, res) = interruptible(py, "the run", |stop| {
        let mut columns = Columns::new(&Sample::schema(), Sample::of, periods);
        let res = run_single_until(
            &r.config,
            &r.plant,
            r.reference.as_ref(),
            &r.spec,
            stop,
            &mut columns,
        );
        (columns, res)
    })?;
    let res = res.map_err(py_err)?;
    r.check_finite(&res).map_err(to_py)?;
    result(py, columns, &r.metrics(&res))
}

/// Gait training on the exoskeleton leg: `pma-exo simulate`.
///
/// Returns a dict of 1-D float64 arrays named as the CLI's CSV columns (`t_s`, the
/// joints' angles and references, each muscle's pressure, command and force, the
/// patient's torques; on a treadmill the feet and the pelvis) and `metrics`: the dict
/// `simulate --json` prints (without its provenance). `mode`: `"position"` or
/// `"impedance"` (default: the scenario's), as `simulate --mode`.
#[pyfunction]
#[pyo3(signature = (scenario = "gait_training", controller = None, gains = None, duration = None, mode = None))]
pub fn simulate<'py>(
    py: Python<'py>,
    scenario: &str,
    controller: Option<&str>,
    gains: Option<PathBuf>,
    duration: Option<f64>,
    mode: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let LegRun {
        mut sim,
        settings,
        periods,
        ..
    } = LegRun::assemble(&LegArgs {
        scenario,
        controller: controller_kind(controller)?,
        gains: gains.as_deref(),
        duration_s: duration,
        mode: mode_of(mode)?,
        allow_unfit: false,
    })
    .map_err(to_py)?;
    let names = sim.plant().muscle_names();
    let schema = TrainerSample::schema(&names, sim.leg_count(), sim.exo().ground().is_some());
    let (columns, report) = interruptible(py, "the run", |stop| {
        let settings = settings.with_stop_flag(stop);
        let mut columns = Columns::new(&schema, TrainerSample::of, periods);
        let report = sim.run_until_fault(&settings, &mut columns);
        (columns, report)
    })?;
    // As the CLI: a collapse the trainer's safety stopped is a result (`walking: false`),
    // any other fault an error.
    let report = match report.map_err(leg_err)? {
        (report, None) => report,
        (report, Some(f)) if f.name == "collapse" => report,
        (_, Some(f)) => return Err(leg_err(pma_leg::LegError::Supervisor(f.message))),
    };
    if !report.finite {
        return Err(crate::PmaError::new_err(format!(
            "the simulation (scenario {}) went non-finite",
            report.scenario
        )));
    }
    let metrics = serde_json::to_value(&report).map_err(py_err)?;
    result(py, columns, &metrics)
}

/// The Wartenberg pendulum test of a scenario's patient: `pma-exo pendulum`.
///
/// The thigh horizontal, the hip held at `hip_deg`, the knee released from `knee_deg`
/// with the muscles vented. Returns the CLI's CSV columns as arrays and `metrics`: the
/// dict `pendulum --json` prints (R2, first swing, oscillations; without provenance).
#[pyfunction]
#[pyo3(signature = (scenario = "gait_training", knee_deg = 0.0, hip_deg = 0.0, duration = 10.0, spasticity = None))]
pub fn pendulum<'py>(
    py: Python<'py>,
    scenario: &str,
    knee_deg: f64,
    hip_deg: f64,
    duration: f64,
    spasticity: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let spasticity = spasticity
        .map(|s| choice::<Spasticity>("spasticity", s))
        .transpose()?;
    let run = PendulumRun::load(&PendulumArgs {
        scenario,
        knee_deg,
        hip_deg,
        duration_s: duration,
        spasticity,
    })
    .map_err(to_py)?;
    let (sim, settings) = run.seated().map_err(to_py)?;
    let damping = run.knee_damping_nm_s_per_rad();
    let periods = (duration / run.loaded.scenario.period_s) as u64;
    let setup = run.setup;
    let (columns, report) = interruptible(py, "the pendulum test", |stop| {
        let settings = settings.with_stop_flag(stop);
        let mut columns = Columns::new(
            &PendulumSample::schema(),
            move |p: &Period<'_, _, _>| PendulumSample::of(p, damping),
            periods,
        );
        let report = pma_studies::pendulum::run(sim, setup, &settings, &mut columns);
        (columns, report)
    })?;
    let report = report.map_err(leg_err)?;
    if !report.finite {
        return Err(crate::PmaError::new_err(format!(
            "the pendulum test (scenario {}) went non-finite",
            report.scenario
        )));
    }
    let metrics = serde_json::to_value(&report).map_err(py_err)?;
    result(py, columns, &metrics)
}

/// The Festo muscles and pulleys a scenario's gait needs: `pma-exo size --json`.
///
/// Drives the scenario's legs along its gait with stiff joint servos for `strides`
/// strides and sizes a DMSP pair per joint that keeps `force_margin` of its rating free,
/// then runs the recommendation for `closed_loop_s` in closed loop (0: no check; sized
/// again where the controller takes more of the rating). Returns the dict `size --json`
/// prints (without its provenance): `sizing`, `closed_loop`, `against_norms`, `treadmill`,
/// `servo_max_error_deg`, `servo_raw_torque_range_nm`.
#[pyfunction]
#[pyo3(signature = (scenario = "gait_treadmill", strides = 3, max_length_m = 2.0, force_margin = 0.4, closed_loop_s = pma_leg::tools::CLOSED_LOOP_DEFAULT_S))]
pub fn size<'py>(
    py: Python<'py>,
    scenario: &str,
    strides: usize,
    max_length_m: f64,
    force_margin: f64,
    closed_loop_s: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let args = SizeArgs {
        strides,
        max_length_m,
        force_margin,
        closed_loop_s,
    };
    args.check().map_err(to_py)?;
    let loaded = pma_leg::Scenario::load(scenario).map_err(py_err)?;
    // On a worker thread, the GIL released; a Ctrl-C stops the closed-loop check (the
    // servo-driven strides poll no flag: it is raised when they end).
    let run = interruptible(py, "the sizing", |stop| SizeRun::of(&loaded, &args, stop))?
        .map_err(to_py)?;
    json_to_py(py, &serde_json::Value::Object(run.figures()))
}

/// How often a call running on a worker thread looks for the operator's Ctrl-C.
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(20);

/// A plant from rig logs: `pma-exo identify LOG... --json`.
///
/// `logs`: one log path (`rig excite --out`, or any `rig run` log) or a list of up to 8
/// (an added-mass protocol's pair); `load_kg`: the load weighed (default the log's
/// `[load] mass_kg`, else identified from the added-mass logs); `seed`: the bootstrap's;
/// `force`: read logs `rig replay` would refuse. Returns the dict `identify --json` prints
/// (without its provenance) and `plant`: the plant file's content as a dict (what
/// `identify --out` writes; the caller decides whether its `fit_percent` suffices). The
/// fit runs on a worker thread; Ctrl-C stops it (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (logs, load_kg = None, seed = 1, force = false))]
pub fn identify<'py>(
    py: Python<'py>,
    logs: Bound<'py, PyAny>,
    load_kg: Option<f64>,
    seed: u64,
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let paths: Vec<PathBuf> = match logs.extract::<PathBuf>() {
        Ok(p) => vec![p],
        Err(_) => logs.extract::<Vec<PathBuf>>().map_err(|_| {
            crate::PmaError::new_err("logs must be a path or a list of 1 to 8 paths")
        })?,
    };
    if !(1..=8).contains(&paths.len()) {
        return Err(crate::PmaError::new_err(format!(
            "logs: {} given, 1 to 8 expected",
            paths.len()
        )));
    }
    if let Some(m) = load_kg {
        if !(m.is_finite() && m > 0.0) {
            return Err(crate::PmaError::new_err(format!(
                "load_kg = {m} must be a positive mass in kg"
            )));
        }
    }
    let read = paths
        .iter()
        .map(|p| pma_exo::setup::load_id_log(p, force))
        .collect::<anyhow::Result<Vec<_>>>()
        .map_err(to_py)?;
    let load = load_kg.or(read[0].weighed_kg);
    let id = interruptible(py, "the identification", |stop| {
        pma_studies::identify::identify_logs(&read, load, seed, stop)
    })?
    .map_err(py_err)?;
    let plant = id.plant_config(&read[0]);
    let mut figures = serde_json::to_value(&id).map_err(py_err)?;
    if let Some(o) = figures.as_object_mut() {
        o.insert(
            "plant".into(),
            serde_json::to_value(&plant).map_err(py_err)?,
        );
    }
    json_to_py(py, &figures)
}

/// Runs `work` on a worker thread while this one polls Python's signals: Ctrl-C raises
/// `stop` (which `work` polls between its steps), waits for the worker and raises
/// KeyboardInterrupt. Other Python threads run meanwhile. `what` names the work in the
/// message of a panic.
fn interruptible<T: Send>(
    py: Python<'_>,
    what: &str,
    work: impl FnOnce(&AtomicBool) -> T + Send,
) -> PyResult<T> {
    let stop = AtomicBool::new(false);
    // The worker marks its end and wakes the caller, so that a call returns when its work
    // does: sleeping out a whole poll instead added up to 20 ms to every call (a 20 s bench
    // run takes 3 ms). A panicking worker marks nothing; `is_finished` ends the wait then.
    let done = AtomicBool::new(false);
    let caller = std::thread::current();
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let out = work(&stop);
            done.store(true, std::sync::atomic::Ordering::Release);
            caller.unpark();
            out
        });
        while !(done.load(std::sync::atomic::Ordering::Acquire) || worker.is_finished()) {
            if let Err(e) = py.check_signals() {
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                let _ = worker.join();
                return Err(e);
            }
            py.detach(|| std::thread::park_timeout(SIGNAL_POLL));
        }
        worker
            .join()
            .map_err(|_| crate::PmaError::new_err(format!("{what} panicked")))
    })
}

/// A sweep's runs, in memory: `pma-exo sweep FILE --shard I/N --threads T` without its
/// directory.
///
/// `file` is a shipped sweep (`shocks`, `fig9`, `monte_carlo`, `leg_patients`) or a
/// sweep .toml file; `shard` `"I/N"` runs part I of N, as on a cluster. Returns a list of
/// dicts in run order, one per run, each a line of the CLI's `runs.jsonl` (a bench run's,
/// a leg run's, or a failed run's with `failed`), which `pandas.DataFrame` takes directly.
/// The runs do not depend on `threads` (default one per core). Ctrl-C raises
/// KeyboardInterrupt once the runs under way end.
#[pyfunction]
#[pyo3(signature = (file, shard = "1/1", threads = None))]
pub fn sweep<'py>(
    py: Python<'py>,
    file: PathBuf,
    shard: &str,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    use pma_studies::sweep::{Record, Shard};
    let file = file.to_str().ok_or_else(|| {
        crate::PmaError::new_err(format!("file: `{}` is not UTF-8", file.display()))
    })?;
    let shard: Shard = shard
        .parse()
        .map_err(|e: String| crate::PmaError::new_err(format!("shard: {e}")))?;
    if threads == Some(0) {
        return Err(crate::PmaError::new_err("threads must be at least 1"));
    }
    let sweep = pma_studies::sweep::load(file).map_err(py_err)?;
    let jobs: Vec<&pma_studies::sweep::Job> = sweep
        .jobs
        .iter()
        .filter(|j| shard.contains(j.index()))
        .collect();
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(cores).min(cores))
        .build()
        .map_err(py_err)?;
    let records = std::sync::Mutex::new(Vec::with_capacity(jobs.len()));
    let Ok(_ran) = interruptible(py, "the sweep", |stop| {
        pool.install(|| {
            pma_studies::sweep::run_jobs(&sweep, &jobs, stop, &|r: &Record| {
                records
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .push(r.clone());
                Ok::<(), std::convert::Infallible>(())
            })
        })
    })?;
    let mut records = records
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    records.sort_by_key(Record::run);
    let list = serde_json::to_value(&records).map_err(py_err)?;
    json_to_py(py, &list)
}

/// A treadmill scenario's hip made consistent with its belt: `pma-exo fit-gait --json`.
///
/// `iterations` servo-driven runs after the data's (each the start-up, a stride and
/// `strides` measured), `gain` of each speed error corrected per run, `body_speed`
/// `"constant"` or `"normative"`, `belt` `"no-drag"` (the belt where the harness carries
/// no mean fore-aft force) or `"stance"` (the stance contact's mean speed). Returns the
/// dict `fit-gait --json` prints (without its provenance): `steps`, `best`,
/// `belt_steps`, `belt_speed_m_s`, `hip_correction` (`cos_deg`, `sin_deg`). Ctrl-C
/// between runs raises KeyboardInterrupt.
#[pyfunction]
#[pyo3(signature = (scenario = "gait_treadmill", iterations = 15, gain = 0.8, strides = 3, body_speed = "constant", belt = "no-drag"))]
pub fn fit_gait<'py>(
    py: Python<'py>,
    scenario: &str,
    iterations: usize,
    gain: f64,
    strides: usize,
    body_speed: &str,
    belt: &str,
) -> PyResult<Bound<'py, PyAny>> {
    use pma_exo::setup::{BeltArg, BodySpeedArg};
    use pma_leg::tools::GaitFitSettings;
    let body_speed = choice::<BodySpeedArg>("body_speed", body_speed)?.into();
    let belt = choice::<BeltArg>("belt", belt)?.into();
    let settings = GaitFitSettings {
        iterations,
        gain,
        strides,
        body_speed,
        belt,
    };
    settings
        .validate()
        .map_err(|e| crate::PmaError::new_err(format!("--{e}")))?;
    let loaded = pma_leg::Scenario::load(scenario).map_err(py_err)?;
    let fit = interruptible(py, "the fit", |stop| {
        pma_leg::fit_gait(&loaded, &settings, || {
            stop.load(std::sync::atomic::Ordering::Relaxed)
        })
    })?
    .map_err(py_err)?;
    let figures = serde_json::Value::Object(pma_exo::setup::fit_figures(&fit));
    json_to_py(py, &figures)
}
