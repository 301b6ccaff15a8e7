//! Identification of one muscle, its load and its valve from a rig log (`rig excite`'s or
//! any run's): output-error fitting of eq. (1) behind a first-order valve with dead time,
//! simulated by the bench's own integrator from the logged commands, against the logged
//! position.
//!
//! What one weighed load can and cannot fix: eq. (1) with its load is homogeneous in
//! (m, f0, f1, k0, k1, b) up to gravity: scaling every force parameter by `s` (and `f0`
//! by `s f0 + (1 - s) m g`) changes only the inertia term. Only the load's inertia then
//! fixes `s`: well with a heavy load and a chirp to 3 Hz, weakly with a light one. So the
//! fit runs first with `f1` at Table I (the scale anchored), then with `f1` free from that
//! optimum; the common-scale direction is reported as the least separable.
//!
//! Steps: (1) starts at four valve time constants, each with the muscle from least
//! squares on smoothed signals (or Table I where that fits worse) and a
//! Levenberg-Marquardt output-error fit with `f1` anchored (the Jacobian by forward
//! differences); (2) the best start with `f1` free; (3) a dead-time profile (the lag split
//! between time constant and dead time, the muscle refitted at each split) and a polish of
//! every parameter; (4) intervals by a moving-block bootstrap of the residuals (1 s blocks:
//! residuals at 1 kHz are strongly correlated) through the linearised fit; they do not
//! cover a bias of the model structure; (5) validation on the held-out last quarter of the
//! log, simulated open loop from the vented rest.
use crate::StudyError;
use nalgebra::{DMatrix, DVector};
use pma_bench::{MuscleBench, PlantConfig};
use pma_control::NominalSpec;
use pma_model::{GaussianRng, LoadProfile, MuscleScale, SensorParams, ValveParams};
use serde::Serialize;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// A rig log reduced to what identification needs.
#[derive(Debug, Clone, PartialEq)]
pub struct IdLog {
    /// Where it came from (the file's path), for the messages.
    pub source: String,
    /// Control period (s).
    pub period_s: f64,
    /// The command the valve got over period `k` (Pa), after the supervisor.
    pub command_pa: Vec<f64>,
    /// The position measured at the end of period `k` (m).
    pub position_m: Vec<f64>,
    /// The position measured at the start, the muscle vented (m).
    pub start_m: f64,
    /// The rig's highest pressure (Pa).
    pub pressure_max_pa: f64,
    /// The valve's measured pressure at the end of period `k` (Pa), when the rig has the
    /// pressure channel (`[signals] pressure`).
    pub pressure_pa: Option<Vec<f64>>,
    /// The load, weighed, if the log's configuration says (`[load] mass_kg`).
    pub weighed_kg: Option<f64>,
    /// The mass added for this log (`[load] added_mass_kg`, the added-mass protocol).
    pub added_mass_kg: f64,
}

/// Shortest log identification accepts (s).
pub const MIN_LOG_S: f64 = 10.0;

/// Longest time identification accepts, over every log together (s): ten minutes of
/// excitation take about 2.5 min and 0.1 GB to fit here; `rig excite` runs 60-90 s.
pub const MAX_LOG_S: f64 = 600.0;

/// A rig's control periods (s), as `rig run` accepts them.
const PERIOD_RANGE_S: (f64, f64) = (1e-4, 1e-2);

fn log_error(path: &Path, message: impl Into<String>) -> StudyError {
    StudyError::Parse {
        what: "rig log",
        file: path.display().to_string(),
        message: message.into(),
    }
}

/// Reads a `pma-exo rig` log (written by `rig run` or `rig excite`).
pub fn read_log(path: &Path) -> Result<IdLog, StudyError> {
    let text = std::fs::read_to_string(path).map_err(|e| StudyError::Io {
        operation: "read",
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    if !text.starts_with("# pma-exo rig log") {
        return Err(log_error(
            path,
            "not a pma-exo rig log (no `# pma-exo rig log` header)",
        ));
    }
    // `key = value` of the header's configuration, in `section` (`""`: before any).
    let header_value = |section: &str, key: &str| {
        let mut current = String::new();
        text.lines()
            .take_while(|l| l.starts_with('#'))
            .filter_map(|l| l.strip_prefix("# "))
            .find_map(|l| {
                if let Some(s) = l.strip_prefix('[').and_then(|s| s.strip_suffix(']')) {
                    current = s.to_owned();
                    return None;
                }
                (current == section).then_some(())?;
                l.strip_prefix(key)?.strip_prefix(" = ")
            })
            .map(|v| v.trim().to_owned())
    };
    // A header value, checked against its range: a log's header can be edited, and a
    // nonsense period or limit would fit a nonsense plant.
    let checked = |section: &str, key: &str, (low, high): (f64, f64), range: &str| {
        let name = if section.is_empty() {
            key.to_owned()
        } else {
            format!("[{section}] {key}")
        };
        let Some(text) = header_value(section, key) else {
            return Ok(None);
        };
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() && (low..=high).contains(&v) => Ok(Some(v)),
            _ => Err(log_error(
                path,
                format!("the header's `{name} = {text}` must be {range}"),
            )),
        }
    };
    let period_s = checked("", "period_s", PERIOD_RANGE_S, "0.1 to 10 ms, as a rig's")?
        .ok_or_else(|| log_error(path, "the header has no period_s"))?;
    let pressure_max_pa = checked(
        "limits",
        "pressure_max_pa",
        (1e3, pma_model::MAX_VALVE_PRESSURE_PA),
        "0.01 to 10 bar (a proportional valve's range)",
    )?
    .ok_or_else(|| log_error(path, "the header has no [limits] pressure_max_pa"))?;
    let loads = (0.05, pma_model::MAX_LOAD_KG);
    let weighed_kg = checked("load", "mass_kg", loads, "0.05 to 600 kg")?;
    let added_mass_kg = checked(
        "load",
        "added_mass_kg",
        (0.0, pma_model::MAX_LOAD_KG),
        "0 to 600 kg",
    )?
    .unwrap_or(0.0);
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let columns: Vec<&str> = lines
        .next()
        .ok_or_else(|| log_error(path, "no column line"))?
        .split(',')
        .collect();
    let col = |name: &str| {
        columns
            .iter()
            .position(|c| *c == name)
            .ok_or_else(|| log_error(path, format!("no `{name}` column")))
    };
    let (c_cmd, c_pos, c_event) = (col("valve_cmd_pa")?, col("position_m")?, col("event")?);
    let c_pressure = col("pressure_pa").ok();
    let mut command_pa = Vec::new();
    let mut position_m = Vec::new();
    // Logged pressures; `None` once a row has none (a rig without the channel).
    let mut pressure: Option<Vec<f64>> = c_pressure.map(|_| Vec::new());
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let field = |c: usize| -> Result<f64, StudyError> {
            f.get(c)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    log_error(
                        path,
                        format!("row {}: `{}` is not a finite number", i + 1, columns[c]),
                    )
                })
        };
        if f.get(c_event).is_some_and(|e| *e == "vent") {
            break;
        }
        position_m.push(field(c_pos)?);
        command_pa.push(field(c_cmd)?);
        if let (Some(p), Some(c)) = (pressure.as_mut(), c_pressure) {
            match f.get(c).filter(|v| !v.is_empty()) {
                Some(_) => p.push(field(c)?),
                None => pressure = None,
            }
        }
    }
    if position_m.len() < 2 {
        return Err(log_error(path, "no rows"));
    }
    let start_m = position_m.remove(0);
    command_pa.pop();
    if let Some(p) = pressure.as_mut() {
        p.remove(0);
    }
    let log = IdLog {
        source: path.display().to_string(),
        period_s,
        command_pa,
        position_m,
        start_m,
        pressure_max_pa,
        pressure_pa: pressure,
        weighed_kg,
        added_mass_kg,
    };
    log.check(path)?;
    Ok(log)
}

impl IdLog {
    /// Its length (s).
    pub fn duration_s(&self) -> f64 {
        self.command_pa.len() as f64 * self.period_s
    }

    /// Refuses a log that cannot identify anything, naming what is missing.
    fn check(&self, path: &Path) -> Result<(), StudyError> {
        if self.duration_s() < MIN_LOG_S {
            return Err(log_error(
                path,
                format!(
                    "{:.1} s is too short: identification needs at least {MIN_LOG_S} s of excitation (`rig excite`)",
                    self.duration_s()
                ),
            ));
        }
        let n = self.command_pa.len() as f64;
        let mean = self.command_pa.iter().sum::<f64>() / n;
        let sd = (self
            .command_pa
            .iter()
            .map(|c| (c - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        if sd < 0.05e5 {
            return Err(log_error(
                path,
                format!(
                    "no excitation: the command varies by {:.3} bar RMS (at least 0.05 bar needed)",
                    sd / 1e5
                ),
            ));
        }
        let at_limit = self
            .command_pa
            .iter()
            .filter(|c| **c <= 0.0 || **c >= self.pressure_max_pa)
            .count() as f64;
        if at_limit > 0.5 * n {
            return Err(log_error(
                path,
                format!(
                    "saturated: the command sits at 0 or at the pressure limit {:.0} % of the time",
                    100.0 * at_limit / n
                ),
            ));
        }
        let (lo, hi) = self
            .position_m
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
        if hi - lo < 1e-3 {
            return Err(log_error(
                path,
                format!(
                    "the position moves by {:.3} mm only: the muscle did not respond",
                    (hi - lo) * 1e3
                ),
            ));
        }
        Ok(())
    }
}

/// Names of the fitted parameters, in the vector's order.
pub const PARAMETERS: [&str; 11] = [
    "f0_scale",
    "f1_scale",
    "k0_scale",
    "k1_scale",
    "b0_inflation_scale",
    "b1_inflation_scale",
    "b0_deflation_scale",
    "b1_deflation_scale",
    "valve_time_constant_s",
    "valve_dead_time_s",
    "load_mass_kg",
];

/// The fitted vector: the eight muscle scales on Table I, the valve's time constant and
/// dead time (s), the load without any added mass (kg).
type Params = [f64; 11];

const TAU: usize = 8;
const THETA: usize = 9;
const LOAD: usize = 10;
/// Muscle scales in the vector.
const MUSCLE: usize = 8;
/// Integration substeps of the fit's simulation (the bench's default).
const SUBSTEPS: u32 = 4;

/// The plant of parameters `q` with the load `load_kg`.
fn plant(q: &Params, load_kg: f64, pressure_max_pa: f64, noise_rms_m: f64) -> PlantConfig {
    PlantConfig {
        name: "identified".into(),
        description: String::new(),
        nominal: NominalSpec {
            mass_kg: load_kg,
            mode_switch_deadband_pa: pma_control::DEFAULT_MODE_SWITCH_DEADBAND_PA,
            mode_switch_fraction: pma_control::DEFAULT_MODE_SWITCH_FRACTION,
            valve_time_constant_s: q[TAU] + q[THETA],
        },
        muscle: MuscleScale {
            f0_scale: q[0],
            f1_scale: q[1],
            k0_scale: q[2],
            k1_scale: q[3],
            b0_inflation_scale: q[4],
            b1_inflation_scale: q[5],
            b0_deflation_scale: q[6],
            b1_deflation_scale: q[7],
        },
        load: LoadProfile::constant(load_kg),
        valve: valve(q, pressure_max_pa),
        sensor: SensorParams {
            noise_rms_m,
            ..SensorParams::ideal()
        },
        substeps_per_period: SUBSTEPS,
        // The fit's finite differences in the valve's lag start at 0, where the exact step
        // would take over from the substeps: one integrator keeps its Jacobian smooth.
        exact_held_pressure_step: false,
    }
}

fn valve(q: &Params, pressure_max_pa: f64) -> ValveParams {
    ValveParams {
        pressure_max_pa,
        time_constant_s: q[TAU],
        rate_limit_pa_per_s: None,
        dead_time_s: q[THETA],
        flow: None,
    }
}

/// The positions plant `q` gives for the log's commands, open loop from the vented rest
/// (`None` if the parameters are not a valid plant or the simulation leaves the finite).
fn simulate(q: &Params, log: &IdLog) -> Option<Vec<f64>> {
    simulate_from(q, log, None)
}

/// The measured state at every `window` samples: the position and its velocity, both
/// lightly smoothed (2 x 11 samples), where a windowed simulation restarts.
fn window_starts(log: &IdLog, window: usize) -> Vec<(usize, f64, f64)> {
    let x = smooth(&log.position_m, 5);
    let v = derivative(&x, log.period_s);
    (window..log.position_m.len())
        .step_by(window)
        .map(|k| (k, x[k - 1], v[k - 1]))
        .collect()
}

/// [`simulate`], restarted from the measured state at each of `starts` (sample, position,
/// velocity): the valve runs on, the load's motion is put back (multiple shooting).
fn simulate_from(
    q: &Params,
    log: &IdLog,
    starts: Option<&[(usize, f64, f64)]>,
) -> Option<Vec<f64>> {
    if q.iter().any(|v| !v.is_finite() || *v < 0.0)
        || q[..MUSCLE].iter().any(|v| *v <= 0.0)
        || q[LOAD] <= 0.0
    {
        return None;
    }
    let cfg = plant(q, q[LOAD] + log.added_mass_kg, log.pressure_max_pa, 0.0);
    let mut bench = MuscleBench::vented(&cfg).ok()?.with_substeps(SUBSTEPS);
    let mut out = Vec::with_capacity(log.command_pa.len());
    let mut next = starts.unwrap_or_default().iter().peekable();
    for (k, &c) in log.command_pa.iter().enumerate() {
        if let Some((_, x, v)) = next.next_if(|s| s.0 == k) {
            bench.set_motion(*x, *v);
        }
        bench.apply(c, log.period_s);
        let x = bench.position();
        if !x.is_finite() {
            return None;
        }
        out.push(x);
    }
    Some(out)
}

/// Which samples of every log: the first three quarters are fitted, the last held out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    Fit,
    Held,
}

impl Part {
    fn range(self, n: usize) -> std::ops::Range<usize> {
        match self {
            Part::Fit => 0..n * 3 / 4,
            Part::Held => n * 3 / 4..n,
        }
    }
}

/// The logs a fit runs against, counting the simulations it runs; once `stop` is raised
/// no simulation runs (every cost is infinite, so every search ends at once).
struct Problem<'a> {
    logs: &'a [IdLog],
    simulations: std::cell::Cell<usize>,
    stop: &'a AtomicBool,
    /// Per log, where the fit's simulation restarts from the measured state (empty: open
    /// loop throughout).
    starts: Vec<Vec<(usize, f64, f64)>>,
}

impl Problem<'_> {
    /// Residuals of `q` over `part` of every log, one after the other.
    fn residuals(&self, q: &Params, part: Part) -> Option<Vec<f64>> {
        if self.stop.load(Ordering::Relaxed) {
            return None;
        }
        let mut out = Vec::new();
        for (i, log) in self.logs.iter().enumerate() {
            self.simulations.set(self.simulations.get() + 1);
            let sim = simulate_from(q, log, self.starts.get(i).map(Vec::as_slice))?;
            out.extend(part.range(sim.len()).map(|k| sim[k] - log.position_m[k]));
        }
        Some(out)
    }

    /// RMS of those residuals; infinite for a plant that cannot be simulated.
    fn cost(&self, q: &Params, part: Part) -> f64 {
        self.residuals(q, part).map_or(f64::INFINITY, |r| rms(&r))
    }

    /// Held-out fit (%) and RMS error (m) of `q`, over every log's held-out part (each
    /// part's spread taken around its own mean).
    fn held_out(&self, q: &Params) -> (f64, f64) {
        let (mut err2, mut spread2, mut n) = (0.0, 0.0, 0usize);
        for log in self.logs {
            let sim = simulate(q, log).unwrap_or_default();
            let range = Part::Held.range(log.position_m.len());
            let held = &log.position_m[range.clone()];
            let mean = held.iter().sum::<f64>() / held.len().max(1) as f64;
            spread2 += held.iter().map(|y| (y - mean).powi(2)).sum::<f64>();
            err2 += range
                .map(|k| (sim.get(k).copied().unwrap_or(f64::NAN) - log.position_m[k]).powi(2))
                .sum::<f64>();
            n += held.len();
        }
        (
            100.0 * (1.0 - (err2 / spread2).sqrt()),
            (err2 / n.max(1) as f64).sqrt(),
        )
    }
}

fn rms(r: &[f64]) -> f64 {
    (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt()
}

/// Levenberg-Marquardt on the parameters `free` (indices into `q`), at most `iterations`
/// Jacobians. Returns the cost (RMS of the residuals) and the last Jacobian.
fn levenberg_marquardt(
    q: &mut Params,
    free: &[usize],
    problem: &Problem<'_>,
    iterations: usize,
) -> (f64, Option<DMatrix<f64>>) {
    let Some(mut r) = problem.residuals(q, Part::Fit) else {
        return (f64::INFINITY, None);
    };
    let mut cost = rms(&r);
    let mut lambda = 1e-3;
    let mut jacobian = None;
    for _ in 0..iterations {
        let n = r.len();
        let mut j = DMatrix::<f64>::zeros(n, free.len());
        for (c, &i) in free.iter().enumerate() {
            let h = step(i, q[i]);
            let mut qh = *q;
            qh[i] += h;
            let Some(rh) = problem.residuals(&qh, Part::Fit) else {
                continue;
            };
            for k in 0..n {
                j[(k, c)] = (rh[k] - r[k]) / h;
            }
        }
        let rv = DVector::from_column_slice(&r);
        let jtj = j.transpose() * &j;
        let jtr = j.transpose() * rv;
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for d in 0..free.len() {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-30);
            }
            let Some(delta) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial = *q;
            for (c, &i) in free.iter().enumerate() {
                trial[i] += delta[c];
                // The lag's parts stop at their bound, zero, instead of the step being
                // refused: an ideal valve lies on it (regression, issue 26).
                if i == TAU || i == THETA {
                    trial[i] = trial[i].max(0.0);
                }
            }
            if let Some(rt) = problem.residuals(&trial, Part::Fit) {
                let ct = rms(&rt);
                if ct < cost {
                    let gain = (cost - ct) / cost;
                    *q = trial;
                    r = rt;
                    cost = ct;
                    lambda = (lambda / 3.0).max(1e-9);
                    improved = gain > 1e-9;
                    break;
                }
            }
            lambda *= 10.0;
        }
        jacobian = Some(j);
        if !improved {
            break;
        }
    }
    (cost, jacobian)
}

/// Forward-difference step of parameter `i`.
fn step(i: usize, value: f64) -> f64 {
    match i {
        TAU => 2e-4,
        // The bench applies a dead time in whole substeps (0.25 ms at 4 substeps): a
        // smaller step would see no change.
        THETA => 5e-4,
        _ => 1e-4 * value.abs().max(1e-3),
    }
}

/// One parameter with its interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The estimate.
    pub value: f64,
    /// Lower end of the 95 % interval (block bootstrap); equal to the value for a
    /// parameter that was given, not fitted.
    pub low: f64,
    /// Upper end.
    pub high: f64,
}

/// What identification found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identified {
    /// The logs' total length (s).
    pub log_s: f64,
    /// Logs fitted together (two for the added-mass protocol).
    pub logs: usize,
    /// Samples fitted (the first three quarters of every log).
    pub fit_samples: usize,
    /// Samples held out (the last quarter of every log).
    pub held_out_samples: usize,
    /// The load without any added mass (kg): weighed, or identified (`load_source`).
    pub load_mass_kg: f64,
    /// `weighed` (given) or `added-mass` (identified from a second log with a known mass
    /// added).
    pub load_source: &'static str,
    /// Valve time constant (s).
    pub valve_time_constant_s: f64,
    /// Valve dead time (s).
    pub valve_dead_time_s: f64,
    /// Their sum, the lag the controllers are told (s).
    pub valve_lag_s: f64,
    /// `pressure channel` (fitted on the measured pressure) or `position` (output error
    /// jointly with the muscle).
    pub valve_source: &'static str,
    /// RMS of the valve fit's pressure residuals (Pa), with the pressure channel.
    pub valve_rms_error_pa: Option<f64>,
    /// The sensor's noise (m): the RMS of the residuals' white part (what is left of them
    /// after a zero-phase smoothing over 49 ms, corrected for the part of white noise the
    /// smoothing keeps), at most the residuals' RMS. What the model misses is slow; the
    /// plant file's sensor noise is this.
    pub noise_rms_m: f64,
    /// RMS of the fit's residuals (m): sensor noise plus what the model misses.
    pub residual_rms_m: f64,
    /// Held-out fit, 100 (1 - |y - y_sim| / |y - mean y|) (%).
    pub fit_percent: f64,
    /// Held-out RMS error (m).
    pub rms_error_m: f64,
    /// Condition number of the fit's Jacobian, columns scaled to unit norm.
    pub condition_number: f64,
    /// Pairs of parameters whose estimates correlate beyond 0.95 (the data cannot
    /// separate them), with the correlation.
    pub inseparable: Vec<(String, String, f64)>,
    /// Every parameter (scales on Table I; the valve's in s; the load in kg) with its
    /// interval.
    pub parameters: Vec<(String, Estimate)>,
    /// Why the force scale is what it is.
    pub force_scale: String,
    /// Simulations run by the fit (the held-out validation not counted).
    pub simulations: usize,
    /// The fit's simulations restarted from the measured state every so many seconds
    /// (multiple shooting; `None`: open loop over the whole log). Chosen only where the
    /// open-loop fit's error dwarfed the noise and the restarted one validated better.
    pub restart_s: Option<f64>,
}

impl Identified {
    /// The plant file of the result (`single --plant`, `tune --plant`, `[virtual] plant`),
    /// with the load without any added mass.
    pub fn plant_config(&self, log: &IdLog) -> PlantConfig {
        let q = self.vector();
        let mut cfg = plant(&q, q[LOAD], log.pressure_max_pa, self.noise_rms_m);
        cfg.description = format!(
            "identified from {:.0} s of log: held-out fit {:.2} %, {:.1} um RMS; valve {:.1} ms + {:.1} ms dead time ({}); load {:.3} kg ({})",
            self.log_s,
            self.fit_percent,
            self.rms_error_m * 1e6,
            self.valve_time_constant_s * 1e3,
            self.valve_dead_time_s * 1e3,
            self.valve_source,
            self.load_mass_kg,
            self.load_source,
        );
        cfg.sensor.range_min_m = -1.0;
        cfg.sensor.range_max_m = 1.0;
        cfg
    }

    /// The position the identified model gives for `log`'s commands, open loop from rest
    /// (`None` if it cannot be simulated).
    pub fn simulated_position_m(&self, log: &IdLog) -> Option<Vec<f64>> {
        simulate(&self.vector(), log)
    }

    fn vector(&self) -> Params {
        let mut q = [0.0; 11];
        for (i, (_, e)) in self.parameters.iter().enumerate().take(q.len()) {
            q[i] = e.value;
        }
        q
    }
}

/// Identifies the plant behind `log` with the load `load_kg` (weighed).
pub fn identify(log: &IdLog, load_kg: f64, seed: u64) -> Result<Identified, StudyError> {
    identify_logs(
        std::slice::from_ref(log),
        Some(load_kg),
        seed,
        &AtomicBool::new(false),
    )
}

/// An error of the identification of `logs`, naming them.
fn id_error(logs: &[IdLog], message: impl Into<String>) -> StudyError {
    let names: Vec<&str> = logs.iter().map(|l| l.source.as_str()).collect();
    StudyError::Parse {
        what: "identification of",
        file: if names.is_empty() {
            "no log".into()
        } else {
            names.join("` and `")
        },
        message: message.into(),
    }
}

/// Identifies the plant behind `logs` (one muscle, one valve): with `load_kg` the load is
/// the weighed one; without it, at least two logs with different added masses
/// (`[load] added_mass_kg`) fix it, eq. (1) then being inhomogeneous in the forces.
/// Raising `stop` (the operator's SIGINT/SIGTERM) ends it within one simulation:
/// [`StudyError::Interrupted`].
pub fn identify_logs(
    logs: &[IdLog],
    load_kg: Option<f64>,
    seed: u64,
    stop: &AtomicBool,
) -> Result<Identified, StudyError> {
    let Some(first) = logs.first() else {
        return Err(id_error(logs, "no log"));
    };
    if let Some(m) = load_kg {
        pma_model::error::within(
            "load_kg",
            m,
            0.05,
            pma_model::MAX_LOAD_KG,
            "must be 0.05 to 600 kg",
        )?;
    } else {
        let added: Vec<f64> = logs.iter().map(|l| l.added_mass_kg).collect();
        if logs.len() < 2 || added.iter().all(|m| (m - added[0]).abs() < 1e-9) {
            return Err(id_error(
                logs,
                "the load is not known: give it weighed (--load-kg, or [load] mass_kg in the rig configuration), or a second excitation with a known mass added (rig excite --added-mass-kg M)",
            ));
        }
    }
    if logs.iter().any(|l| l.period_s != first.period_s) {
        return Err(id_error(logs, "the logs have different periods"));
    }
    let total_s: f64 = logs.iter().map(IdLog::duration_s).sum();
    if total_s > MAX_LOG_S {
        return Err(id_error(
            logs,
            format!(
                "{total_s:.0} s of log: identification takes at most {MAX_LOG_S:.0} s (its cost grows with the samples; `rig excite --duration 90` is enough)"
            ),
        ));
    }
    // Open loop over the whole log first; where the model's error dwarfs the noise (an
    // ideal valve turns the damping mode on a 15 Pa step, and one such turn sends the
    // simulation off for the rest of the log: regression, issue 26), again restarting
    // from the measured state every RESTART_S, and the better held-out fit is kept (the
    // held-out quarter is simulated open loop either way).
    let open = fit_logs(logs, load_kg, seed, stop, None, None)?;
    if open.residual_rms_m <= MODEL_ERROR_RATIO * open.noise_rms_m {
        return Ok(open);
    }
    // The restarted fit's landscape is smoother; its optimum, polished open loop, is the
    // third candidate (on a 30 + 10 ms valve the open-loop fit alone stopped at a 75 um
    // residual where the truth gives the noise's 20 um).
    let window = (RESTART_S / first.period_s).round() as usize;
    let mut candidates = vec![open];
    for (window, start) in [(Some(window), None), (None, Some(()))] {
        let from = start.and_then(|()| candidates.last().map(Identified::vector));
        match fit_logs(logs, load_kg, seed, stop, window, from) {
            Ok(c) => candidates.push(c),
            Err(StudyError::Interrupted) => return Err(StudyError::Interrupted),
            Err(_) => {}
        }
    }
    let simulations = candidates.iter().map(|c| c.simulations).sum();
    let mut best = candidates
        .into_iter()
        .max_by(|a, b| a.fit_percent.total_cmp(&b.fit_percent))
        .ok_or_else(|| id_error(logs, "no fit"))?;
    best.simulations = simulations;
    Ok(best)
}

/// How far the fit's residual may exceed the sensor's noise before a fit restarted from
/// the measured state is tried too.
const MODEL_ERROR_RATIO: f64 = 2.0;

/// Interval between the restarts of that fit (s): 0.25-1 s fit an ideal valve's plant
/// within 6 %, 0.1 s is too short (the restarts' velocity errors dominate).
const RESTART_S: f64 = 0.5;

/// The fit of [`identify_logs`], its simulations restarted from the measured state every
/// `window` samples (`None`: open loop throughout), from the starts (or, with `from`,
/// from that vector alone).
fn fit_logs(
    logs: &[IdLog],
    load_kg: Option<f64>,
    seed: u64,
    stop: &AtomicBool,
    window: Option<usize>,
    from: Option<Params>,
) -> Result<Identified, StudyError> {
    let first = &logs[0];
    let shots = |logs: &[IdLog]| -> Vec<Vec<(usize, f64, f64)>> {
        logs.iter()
            .map(|l| window.map_or_else(Vec::new, |w| window_starts(l, w)))
            .collect()
    };
    let problem = Problem {
        logs,
        simulations: std::cell::Cell::new(0),
        stop,
        starts: shots(logs),
    };
    let mut q: Params = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    // Without a weighed load, the fit starts from a guess and the added mass moves it.
    q[LOAD] = load_kg.unwrap_or(START_LOADS_KG[1]);
    // With the pressure channel the valve is fitted on its own, and stays.
    let valve_fit = fit_valve(logs, stop);
    let (muscle_valve, valve_rms) = match valve_fit {
        Some((tau, theta, rms_pa)) => {
            q[TAU] = tau;
            q[THETA] = theta;
            ((0..MUSCLE).collect::<Vec<_>>(), Some(rms_pa))
        }
        None => ((0..=TAU).collect(), None),
    };
    let with_load = |mut v: Vec<usize>| {
        if load_kg.is_none() {
            v.push(LOAD);
        }
        v
    };
    // (1)-(2) Starts: at each time constant of a grid (the measured one with the pressure
    // channel), the muscle by least squares on smoothed signals (Table I where they
    // cannot tell), then output error with f1 at Table I and the load held (the force
    // scale anchored); the best of the starts goes on. The output error's landscape is
    // rough (the damping switches with the valve's direction), so one start is not
    // enough.
    // The scale's anchor: f1 at Table I and the load as weighed (or guessed); the load's
    // inertia, or the added mass, frees them later.
    let anchored: Vec<usize> = muscle_valve.iter().copied().filter(|i| *i != 1).collect();
    let taus: Vec<f64> = match valve_fit {
        Some((tau, ..)) => vec![tau],
        None => vec![5e-3, 12e-3, 25e-3, 40e-3],
    };
    // Without a weighed load the starts run on the first log alone: it fixes the plant up
    // to one common factor on the forces and the load (eq. (1) is homogeneous in them), and
    // the added mass then picks the factor (below).
    let start_logs = if load_kg.is_some() { logs } else { &logs[..1] };
    let starts = Problem {
        logs: start_logs,
        simulations: std::cell::Cell::new(0),
        stop,
        starts: shots(start_logs),
    };
    let start_at = |load: f64| {
        let mut best = f64::INFINITY;
        let mut best_q = q;
        best_q[LOAD] = load;
        let table_i = best_q;
        // Where the starts inside the range end near its bound, one more without any lag
        // from Table I: a start inside it never reached an ideal valve (regression, issue
        // 26). Only there: tried on every log, it won on a 30 + 10 ms valve and made its
        // added-mass load 10.6 % heavy; started from the best muscle behind a lag, it left
        // an ideal valve's k1 x1.7.
        let mut queue = taus.clone();
        let mut k = 0;
        while let Some(&tau) = queue.get(k) {
            k += 1;
            // Each start from the best muscle so far, at its own time constant.
            let mut t = if tau == 0.0 { table_i } else { best_q };
            t[TAU] = tau;
            if let Some(start) = least_squares_start(first, t[LOAD], t[TAU]) {
                let mut ls = t;
                ls[0] = start[0];
                ls[2..MUSCLE].copy_from_slice(&start[1..]);
                if starts.cost(&ls, Part::Fit) < starts.cost(&t, Part::Fit) {
                    t = ls;
                }
            }
            let (c, _) = levenberg_marquardt(&mut t, &anchored, &starts, 30);
            if c < best {
                best = c;
                best_q = t;
            }
            if k == taus.len() && valve_fit.is_none() && best_q[TAU] < LAG_FREE_START_S {
                queue.push(0.0);
            }
        }
        best_q
    };
    let mut cost;
    q = match (from, load_kg) {
        (Some(q0), _) => q0,
        (None, Some(m)) => start_at(m),
        (None, None) => {
            // The first log's plant for each guessed load (the anchored start holds only
            // near the load whose f1 is Table I's, so three guesses 2.7x apart), the one
            // that fits it best; then the member of its family every log agrees with, and
            // the load against f0 (which only the inertia separates).
            let (best, _) = START_LOADS_KG
                .iter()
                .map(|m| {
                    free_then_lag_split(start_at(*m), &muscle_valve, &starts, valve_fit.is_none())
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((q, f64::INFINITY));
            load_line(&common_factor(&best, &problem), &problem)
        }
    };
    problem
        .simulations
        .set(problem.simulations.get() + starts.simulations.get());
    // (3)-(4) Then f1 free too (and the load, without a weighed one): the load's inertia,
    // or the added mass, fixes the force scale; then the lag's split.
    let free = with_load(muscle_valve.clone());
    (q, cost) = free_then_lag_split(q, &free, &problem, valve_fit.is_none());
    // The final Jacobian over every fitted parameter (the dead time free too, one polish
    // step).
    let mut all = free.clone();
    if valve_fit.is_none() {
        all.push(THETA);
        all.sort_unstable();
    }
    let (c, jac) = levenberg_marquardt(&mut q, &all, &problem, 10);
    if stop.load(Ordering::Relaxed) {
        return Err(StudyError::Interrupted);
    }
    cost = cost.min(c);
    let jac =
        jac.ok_or_else(|| id_error(logs, "the model could not be simulated at the start values"))?;
    let r_fit = problem.residuals(&q, Part::Fit).unwrap_or_default();
    // (4) Intervals: moving-block bootstrap of the residuals through the linearised fit.
    let (condition_number, correlations, spread) =
        bootstrap(&jac, &r_fit, (1.0 / first.period_s).round() as usize, seed);
    let mut inseparable = Vec::new();
    for a in 0..all.len() {
        for b in a + 1..all.len() {
            let rho = correlations[(a, b)];
            if rho.abs() > 0.95 {
                inseparable.push((PARAMETERS[all[a]].into(), PARAMETERS[all[b]].into(), rho));
            }
        }
    }
    // (5) Held out.
    let noise_rms_m = white_rms(&r_fit).min(cost);
    if load_kg.is_none() {
        added_mass_seen(logs, q[LOAD], noise_rms_m)?;
    }
    let (fit_percent, rms_error_m) = problem.held_out(&q);
    let parameters = PARAMETERS
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let (lo, hi) = all
                .iter()
                .position(|j| *j == i)
                .map_or((0.0, 0.0), |c| spread[c]);
            (
                (*name).to_owned(),
                Estimate {
                    value: q[i],
                    low: (q[i] + lo).max(0.0),
                    high: q[i] + hi,
                },
            )
        })
        .collect();
    let fit_samples = logs
        .iter()
        .map(|l| Part::Fit.range(l.position_m.len()).len())
        .sum();
    let held_out_samples = logs
        .iter()
        .map(|l| Part::Held.range(l.position_m.len()).len())
        .sum();
    Ok(Identified {
        log_s: logs.iter().map(IdLog::duration_s).sum(),
        logs: logs.len(),
        fit_samples,
        held_out_samples,
        load_mass_kg: q[LOAD],
        load_source: if load_kg.is_some() {
            "weighed"
        } else {
            "added-mass"
        },
        valve_time_constant_s: q[TAU],
        valve_dead_time_s: q[THETA],
        valve_lag_s: q[TAU] + q[THETA],
        valve_source: if valve_fit.is_some() {
            "pressure channel"
        } else {
            "position"
        },
        valve_rms_error_pa: valve_rms,
        noise_rms_m,
        residual_rms_m: cost,
        fit_percent,
        rms_error_m,
        condition_number,
        inseparable,
        parameters,
        force_scale: if load_kg.is_some() {
            "f1 fitted with the rest, the force scale fixed by the weighed load's inertia alone (weakly: a common factor on every force parameter is the least determined direction, see `inseparable`); positions, the valve lag and the controllers' inversion hardly depend on it".into()
        } else {
            "the load fitted with the muscle: the known added mass makes eq. (1) inhomogeneous in the forces, which fixes their common scale through gravity".into()
        },
        simulations: problem.simulations.get(),
        restart_s: window.map(|w| w as f64 * first.period_s),
    })
}

/// From `q`, Levenberg-Marquardt on `free`, then (with `split`) the lag shared between time
/// constant and dead time at 20, 40 and 60 %, each refitted; the best and its cost.
fn free_then_lag_split(
    mut q: Params,
    free: &[usize],
    problem: &Problem<'_>,
    split: bool,
) -> (Params, f64) {
    let (mut cost, _) = levenberg_marquardt(&mut q, free, problem, 60);
    if split {
        let lag = q[TAU];
        for share in [0.2, 0.4, 0.6] {
            let mut t = q;
            t[THETA] = share * lag;
            t[TAU] = lag - t[THETA];
            let (c, _) = levenberg_marquardt(&mut t, free, problem, 20);
            if c < cost {
                cost = c;
                q = t;
            }
        }
    }
    (q, cost)
}

/// `q` with its forces and load times the common factor that fits every log best (a
/// log-spaced grid over 0.2-5, then golden section between the grid's neighbours): the
/// family a single log cannot tell apart, which the added mass does.
fn common_factor(q: &Params, problem: &Problem<'_>) -> Params {
    let scaled = |ln_f: f64| {
        let f = ln_f.exp();
        let mut t = *q;
        for v in t[..MUSCLE].iter_mut() {
            *v *= f;
        }
        t[LOAD] *= f;
        t
    };
    let cost = |ln_f: f64| problem.cost(&scaled(ln_f), Part::Fit);
    let step = 5f64.ln() / 20.0;
    let grid: Vec<f64> = (-20..=20).map(|k| f64::from(k) * step).collect();
    let Some(best) = grid
        .iter()
        .map(|u| (cost(*u), *u))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, u)| u)
    else {
        return *q;
    };
    scaled(golden_section(cost, best - step, best + step, 12).0)
}

/// `q` moved along the direction a log's statics cannot see, the load and `f0` together
/// (`f0 - m g` fixed: only the load's inertia tells them apart), to where every log fits
/// best (golden section over loads 0.05-10x the start's).
fn load_line(q: &Params, problem: &Problem<'_>) -> Params {
    let f0_n = pma_model::MuscleParams::TABLE_I.f0_n;
    let moved = |ln_m: f64| {
        let m = ln_m.exp();
        let mut t = *q;
        t[0] += (m - q[LOAD]) * pma_model::GRAVITY_M_S2 / f0_n;
        t[LOAD] = m;
        t
    };
    let cost = |ln_m: f64| problem.cost(&moved(ln_m), Part::Fit);
    let centre = q[LOAD].ln();
    let (ln_m, _) = golden_section(cost, centre + 0.05f64.ln(), centre + 10f64.ln(), 24);
    let best = moved(ln_m);
    if problem.cost(&best, Part::Fit) < problem.cost(q, Part::Fit) {
        best
    } else {
        *q
    }
}

/// Golden-section search for the minimum of `f` on `[a, b]` (unimodal there) in
/// `iterations` steps: the middle of the last bracket and `f` there.
fn golden_section(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, iterations: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iterations {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let u = 0.5 * (a + b);
    (u, f(u))
}

/// Two commands closer than this are the same (Pa): a 12-bit 0-10 V output's step is 24 Pa
/// at the virtual rig's 1 bar/V.
const SAME_COMMAND_PA: f64 = 100.0;

/// Smallest added mass, as a share of the load, that can fix it: below it the added
/// mass's effect drowns in the model's error and the fit ends on any load.
pub const MIN_ADDED_MASS_SHARE: f64 = 0.05;

/// Refuses an added-mass identification the data cannot support: logs that ran the same
/// commands with positions no further apart than the sensor's noise (the mass was not on
/// the muscle, or the same log twice), or an identified load the added mass is under
/// [`MIN_ADDED_MASS_SHARE`] of (regression, issue 26: the same data twice, 1 kg "added",
/// gave 106.8 kg at a 99.26 % fit).
fn added_mass_seen(logs: &[IdLog], load_kg: f64, noise_rms_m: f64) -> Result<(), StudyError> {
    for (i, a) in logs.iter().enumerate() {
        for b in &logs[i + 1..] {
            // The same commands, to a converter's step (one log may have been read through
            // the output converter, the other not).
            let same_commands = a.command_pa.len() == b.command_pa.len()
                && a.command_pa
                    .iter()
                    .zip(&b.command_pa)
                    .all(|(x, y)| (x - y).abs() <= SAME_COMMAND_PA);
            if a.added_mass_kg == b.added_mass_kg || !same_commands {
                continue;
            }
            let apart = rms(&a
                .position_m
                .iter()
                .zip(&b.position_m)
                .map(|(x, y)| x - y)
                .collect::<Vec<_>>());
            if apart <= 3.0 * noise_rms_m.max(1e-7) {
                return Err(id_error(
                    logs,
                    format!(
                        "the added mass is not in the data: `{}` ({} kg added) and `{}` ({} kg) ran the same commands and their positions differ by {:.1} um RMS, within three times the sensor's noise ({:.1} um); was the mass on the muscle?",
                        a.source,
                        a.added_mass_kg,
                        b.source,
                        b.added_mass_kg,
                        apart * 1e6,
                        noise_rms_m * 1e6
                    ),
                ));
            }
        }
    }
    let (lo, hi) = logs.iter().fold((f64::MAX, f64::MIN), |(lo, hi), l| {
        (lo.min(l.added_mass_kg), hi.max(l.added_mass_kg))
    });
    let added = hi - lo;
    if added < MIN_ADDED_MASS_SHARE * (load_kg + lo) {
        return Err(id_error(
            logs,
            format!(
                "the fit puts the load at {load_kg:.2} kg, of which the {added} kg added is {:.1} % only (at least {:.0} % is needed for the data to fix the load): the added mass has no visible effect; add 30-50 % of the load, or weigh it (--load-kg)",
                100.0 * added / (load_kg + lo),
                100.0 * MIN_ADDED_MASS_SHARE
            ),
        ));
    }
    Ok(())
}

/// A fit whose starts end below this lag (s) tries one more without any lag.
const LAG_FREE_START_S: f64 = 5e-3;

/// The loads a fit without a weighed one starts from (kg).
const START_LOADS_KG: [f64; 3] = [0.75, 2.0, 5.5];

/// The valve's time constant and dead time (s) and the RMS error (Pa) of a first-order
/// lag with dead time fitted to the measured pressure of every log (`None` unless every
/// log has the pressure channel): the valve simulated alone at the bench's substeps, the
/// dead time on a grid of 0.25 ms (the bench's resolution), the time constant by golden
/// section at each.
fn fit_valve(logs: &[IdLog], stop: &AtomicBool) -> Option<(f64, f64, f64)> {
    if logs.iter().any(|l| l.pressure_pa.is_none()) {
        return None;
    }
    let cost = |tau: f64, theta: f64| -> f64 {
        if stop.load(Ordering::Relaxed) {
            return f64::INFINITY;
        }
        let mut q: Params = [0.0; 11];
        q[TAU] = tau;
        q[THETA] = theta;
        let mut sum = 0.0;
        let mut n = 0usize;
        for log in logs {
            let Ok(mut v) = pma_model::Valve::new(valve(&q, log.pressure_max_pa), 0.0) else {
                return f64::INFINITY;
            };
            let h = log.period_s / f64::from(SUBSTEPS);
            for (c, m) in log.command_pa.iter().zip(log.pressure_pa.iter().flatten()) {
                v.command(*c);
                for _ in 0..SUBSTEPS {
                    v.advance(h);
                }
                sum += (v.pressure() - m).powi(2);
                n += 1;
            }
        }
        (sum / n.max(1) as f64).sqrt()
    };
    let golden = |theta: f64| -> (f64, f64) {
        // ln tau in [ln 0.2 ms, ln 300 ms], and no lag at all, the range's true bound (an
        // ideal valve came out at 0.2 ms and its muscle's k1 x2.3: regression, issue 26).
        let (u, c) = golden_section(|u| cost(u.exp(), theta), 2e-4f64.ln(), 0.3f64.ln(), 28);
        let ideal = cost(0.0, theta);
        if ideal <= c {
            (0.0, ideal)
        } else {
            (u.exp(), c)
        }
    };
    let grid = |thetas: &mut dyn Iterator<Item = f64>| {
        thetas
            .map(|theta| {
                let (tau, c) = golden(theta);
                (tau, theta, c)
            })
            .min_by(|x, y| x.2.total_cmp(&y.2))
    };
    // 1 ms steps to 60 ms, then 0.25 ms steps within a millisecond of the best.
    let (_, coarse, _) = grid(&mut (0..=60).map(|k| k as f64 * 1e-3))?;
    grid(&mut (-4..=4).map(|k| (coarse + k as f64 * 2.5e-4).max(0.0)))
}

/// A zero-phase smoothing: a centred moving average of `half * 2 + 1` samples, twice.
fn smooth(x: &[f64], half: usize) -> Vec<f64> {
    let pass = |x: &[f64]| -> Vec<f64> {
        let n = x.len();
        (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(half), (k + half + 1).min(n));
                x[a..b].iter().sum::<f64>() / (b - a) as f64
            })
            .collect()
    };
    pass(&pass(x))
}

/// Half-width of the smoothing [`white_rms`] takes off (samples).
const WHITE_HALF: usize = 12;

/// RMS of the white part of `r`: `r` less its smoothing ([`smooth`]), divided by the
/// share of a white signal's RMS that survives that (the filter's weights from its
/// impulse response: `1 - 2 w0 + sum w^2` of the variance).
fn white_rms(r: &[f64]) -> f64 {
    if r.len() < 8 * WHITE_HALF {
        return rms(r);
    }
    let s = smooth(r, WHITE_HALF);
    let high: Vec<f64> = r.iter().zip(&s).map(|(a, b)| a - b).collect();
    let mut impulse = vec![0.0; 4 * WHITE_HALF + 1];
    impulse[2 * WHITE_HALF] = 1.0;
    let w = smooth(&impulse, WHITE_HALF);
    let kept = 1.0 - 2.0 * w[2 * WHITE_HALF] + w.iter().map(|v| v * v).sum::<f64>();
    rms(&high) / kept.sqrt()
}

/// Central differences.
fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (x[b] - x[a]) / ((b - a).max(1) as f64 * dt)
        })
        .collect()
}

/// Least squares of eq. (1) on smoothed position, velocity, acceleration and the
/// pressure of a first-order valve of time constant `tau_s`, `f1` anchored at Table I:
/// `m (x'' + g) - f1 P = f0 - k0 x - k1 P x - (b0 + b1 P) x'` with the inflation or
/// deflation damping by the sign of `P'`, and `m` the load plus the log's added mass.
/// Returns the seven scales on Table I (`None` if the regression is singular or gives a
/// non-physical muscle).
fn least_squares_start(log: &IdLog, load_kg: f64, tau_s: f64) -> Option<[f64; 7]> {
    use pma_model::{MuscleParams, GRAVITY_M_S2};
    let dt = log.period_s;
    let mut p = 0.0;
    let a = if tau_s > 0.0 {
        (-dt / tau_s).exp()
    } else {
        0.0
    };
    let pressure: Vec<f64> = log
        .command_pa
        .iter()
        .map(|c| {
            p = a * p + (1.0 - a) * c;
            p
        })
        .collect();
    let half = 12;
    let x = smooth(&log.position_m, half);
    let v = derivative(&x, dt);
    let acc = smooth(&derivative(&v, dt), half);
    let ps = smooth(&pressure, half);
    let dp = derivative(&ps, dt);
    let t1 = MuscleParams::TABLE_I;
    let rows: Vec<usize> = (4 * half..x.len() - 4 * half).step_by(5).collect();
    let mut phi = DMatrix::<f64>::zeros(rows.len(), 7);
    let mut target = DVector::<f64>::zeros(rows.len());
    for (i, &k) in rows.iter().enumerate() {
        let w = if dp[k] > 0.0 { 1.0 } else { 0.0 };
        let (xk, vk, pk) = (x[k], v[k], ps[k]);
        let m = load_kg + log.added_mass_kg;
        target[i] = m * (acc[k] + GRAVITY_M_S2) - t1.f1_n_per_pa * pk;
        let row = [
            1.0,
            -xk,
            -pk * xk,
            -w * vk,
            -w * pk * vk,
            -(1.0 - w) * vk,
            -(1.0 - w) * pk * vk,
        ];
        for (c, r) in row.iter().enumerate() {
            phi[(i, c)] = *r;
        }
    }
    let reference = [
        t1.f0_n,
        t1.k0_n_per_m,
        t1.k1_n_per_m_pa,
        t1.b0_inflation_ns_per_m,
        t1.b1_inflation_ns_per_m_pa,
        t1.b0_deflation_ns_per_m,
        t1.b1_deflation_ns_per_m_pa,
    ];
    // Columns in Table I's units, so the solve sees scales near 1.
    for (c, r) in reference.iter().enumerate() {
        phi.column_mut(c).scale_mut(*r);
    }
    let solution = phi.svd(true, true).solve(&target, 1e-9).ok()?;
    let mut scales = [0.0; 7];
    for (c, s) in scales.iter_mut().enumerate() {
        // A scale the data cannot fix (far from Table I, or through zero) stays at Table I.
        *s = if solution[c].is_finite() && (0.2..=5.0).contains(&solution[c]) {
            solution[c]
        } else {
            1.0
        };
    }
    Some(scales)
}

/// Condition number of the column-scaled Jacobian, the parameters' correlations and the
/// 2.5 / 97.5 % quantiles of the parameter changes over 200 moving-block bootstrap
/// replicates of the residuals (blocks of `block` samples).
fn bootstrap(
    j: &DMatrix<f64>,
    r: &[f64],
    block: usize,
    seed: u64,
) -> (f64, DMatrix<f64>, Vec<(f64, f64)>) {
    let p = j.ncols();
    let norms: Vec<f64> = (0..p).map(|c| j.column(c).norm().max(1e-300)).collect();
    let mut js = j.clone();
    for (c, n) in norms.iter().enumerate() {
        js.column_mut(c).unscale_mut(*n);
    }
    let sv = js.clone().svd(false, false).singular_values;
    let smin = sv.iter().copied().fold(f64::MAX, f64::min);
    let smax = sv.iter().copied().fold(0.0, f64::max);
    let condition = smax / smin.max(1e-300);
    let jtj = j.transpose() * j;
    let pinv = jtj
        .clone()
        .pseudo_inverse(1e-12 * jtj.norm())
        .unwrap_or(jtj);
    let mut corr = DMatrix::<f64>::zeros(p, p);
    for a in 0..p {
        for b in 0..p {
            let d = (pinv[(a, a)] * pinv[(b, b)]).sqrt();
            corr[(a, b)] = if d > 0.0 { pinv[(a, b)] / d } else { 0.0 };
        }
    }
    let n = r.len();
    let block = block.clamp(1, n);
    let mut rng = GaussianRng::new(seed);
    let mut draws: Vec<Vec<f64>> = vec![Vec::with_capacity(200); p];
    let mut star = DVector::<f64>::zeros(n);
    for _ in 0..200 {
        let mut k = 0;
        while k < n {
            let start = (rng.uniform() * (n - block + 1) as f64) as usize;
            for i in 0..block.min(n - k) {
                star[k + i] = r[start + i];
            }
            k += block;
        }
        let delta = &pinv * (j.transpose() * &star);
        for (c, d) in draws.iter_mut().enumerate() {
            d.push(delta[c]);
        }
    }
    let quantiles = draws
        .iter_mut()
        .map(|d| {
            d.sort_by(f64::total_cmp);
            (d[4], d[194])
        })
        .collect();
    (condition, corr, quantiles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn excite_like(seconds: f64) -> Vec<f64> {
        let spec = pma_control::ExcitationSpec::steps_and_chirp(seconds, 0.5e5, 1.8e5, 1e8);
        (0..(seconds * 1e3) as usize)
            .map(|k| spec.schedule_pa(k as f64 * 1e-3))
            .collect()
    }

    /// Regression: the header's first `pressure_max_pa` is the muscle's rating; the valve's
    /// limit is the one under `[limits]`.
    #[test]
    fn the_pressure_limit_is_read_from_the_limits_section() {
        let dir = std::env::temp_dir().join(format!("pma-id-header-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("log.csv");
        let mut text = String::from(
            "# pma-exo rig log, format 2\n# begin config\n# period_s = 0.001\n\
             # [muscle]\n# pressure_max_pa = 600000.0\n# [limits]\n# pressure_max_pa = 400000.0\n\
             # end config\nt_s,period,valve_cmd_pa,position_m,event\n",
        );
        for (k, c) in excite_like(12.0).iter().enumerate() {
            let y = 0.01 + 1e-7 * c;
            text.push_str(&format!("{},{k},{c},{y},\n", k as f64 * 1e-3));
        }
        std::fs::write(&path, text).unwrap();
        let log = read_log(&path).unwrap();
        assert_eq!(log.pressure_max_pa, 4.0e5);
        assert_eq!(log.period_s, 1e-3);
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn a_noise_free_log_of_a_known_plant_gives_it_back() {
        let truth: Params = [0.9, 1.0, 1.2, 1.0, 1.2, 1.0, 1.2, 1.0, 0.015, 0.0, 2.5];
        let command_pa = excite_like(20.0);
        let mut log = IdLog {
            source: "a simulated log".into(),
            period_s: 1e-3,
            command_pa,
            position_m: Vec::new(),
            start_m: 0.0,
            pressure_max_pa: 6e5,
            pressure_pa: None,
            weighed_kg: None,
            added_mass_kg: 0.0,
        };
        let bench = MuscleBench::vented(&plant(&truth, 2.5, 6e5, 0.0)).unwrap();
        log.start_m = bench.position();
        log.position_m = simulate(&truth, &log).unwrap();
        let id = identify(&log, 2.5, 1).unwrap();
        assert!((id.valve_lag_s - 0.015).abs() < 0.1 * 0.015, "{id:?}");
        assert!(id.fit_percent > 99.0, "{id:?}");
        // Regression (issue 26): `rig commission` could not stop an identification. The
        // operator's stop, raised, ends it without a result.
        let stopped = identify_logs(&[log], Some(2.5), 1, &AtomicBool::new(true));
        assert!(
            matches!(stopped, Err(StudyError::Interrupted)),
            "{stopped:?}"
        );
    }

    /// Regression: without a weighed load, the fit started from the anchored first stage
    /// (f1 at Table I, no dead time) and ended on a light load behind a slow valve 19 %
    /// heavy (plant C of docs/commissioning.md); the first log is now fitted in full before
    /// the added mass picks the scale.
    #[test]
    fn regression_an_unweighed_light_load_behind_a_slow_valve_came_out_19_percent_heavy() {
        let truth: Params = [1.2, 1.2, 1.2, 1.2, 1.2, 1.2, 1.2, 1.2, 0.030, 0.010, 1.0];
        // `rig excite`'s range on a 6 bar rig: 0.5 bar to half the limit.
        let spec = pma_control::ExcitationSpec::steps_and_chirp(40.0, 0.5e5, 3.0e5, 1e8);
        let command_pa: Vec<f64> = (0..40_000)
            .map(|k| spec.schedule_pa(k as f64 * 1e-3))
            .collect();
        let log_with = |added_mass_kg: f64| {
            let mut log = IdLog {
                source: format!("a simulated log, {added_mass_kg} kg added"),
                period_s: 1e-3,
                command_pa: command_pa.clone(),
                position_m: Vec::new(),
                start_m: 0.0,
                pressure_max_pa: 6e5,
                pressure_pa: None,
                weighed_kg: None,
                added_mass_kg,
            };
            log.position_m = simulate(&truth, &log).unwrap();
            log
        };
        let logs = [log_with(0.0), log_with(1.0)];
        let id = identify_logs(&logs, None, 1, &AtomicBool::new(false)).unwrap();
        assert_eq!(id.load_source, "added-mass");
        // The bound: the load within 10 %.
        assert!(
            (id.load_mass_kg - 1.0).abs() < 0.10,
            "load {} kg",
            id.load_mass_kg
        );
        assert!((id.valve_lag_s - 0.040).abs() < 0.1 * 0.040, "{id:?}");
        assert!(identify_logs(&logs[..1], None, 1, &AtomicBool::new(false)).is_err());
    }
}
