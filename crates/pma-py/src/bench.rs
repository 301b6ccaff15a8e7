//! `pma_exo.Bench`: the paper's muscle bench, stepped one control period at a time by a
//! controller written in Python, behind the rig's supervisor.
use crate::errors::{py_err, to_py, Latch, PmaError};
use pma_bench::{MuscleBench, PlantConfig};
use pma_control::supervisor::{Supervised, SupervisorLimits};
use pma_loop::Backend;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The virtual rig whose supervisor limits the bench takes (`models/virtual.toml` of
/// pma-rig: `pma-exo rig run`'s default).
const RIG: &str = "virtual";

/// The supervisor of a bench of `plant`: the virtual rig's rate limit and position
/// window; commands clamped to the plant's valve range; a stuck sensor only where the
/// sensor has noise (a noiseless reading repeats whenever the load rests); no watchdog
/// thread (Python sets the pace, not a clock).
fn limits(plant: &PlantConfig) -> anyhow::Result<SupervisorLimits> {
    let (rig, _) = pma_rig::config::RigConfig::load(RIG)?;
    let mut limits = rig.supervisor_limits();
    limits.pressure_max_pa = limits.pressure_max_pa.min(plant.valve.pressure_max_pa);
    if plant.sensor.noise_rms_m <= 0.0 {
        limits.sensor_stuck_periods = 0;
    }
    limits.watchdog_periods = 0;
    Ok(limits)
}

/// One pneumatic muscle lifting a load (the paper's bench, eq. 1 with Table I), stepped
/// by a controller written in Python.
///
/// Each period: ``x = bench.read()`` (the sensor, m), ``bench.write(p)`` (the pressure
/// command, Pa, held over the next period), ``bench.step()`` (one period passes; returns
/// the new reading). The rig's supervisor stands between the command and the valve: a
/// command must be a finite pressure in ``0..=pressure_max`` (else ``PmaError``) and is
/// rate-limited; a reading outside the position window, or NaN, vents the muscle and
/// raises ``SupervisorError``, after which only ``reset()`` goes on.
#[pyclass(module = "pma_exo", unsendable)]
pub struct Bench {
    plant: PlantConfig,
    position0_m: f64,
    period_s: f64,
    limits: SupervisorLimits,
    sup: Supervised<MuscleBench>,
    reading_m: f64,
    applied_pa: f64,
    periods: u64,
    fault: Latch,
}

impl Bench {
    /// A supervised bench at rest at `position0_m`, started (its first reading taken).
    fn started(
        plant: &PlantConfig,
        position0_m: f64,
        period_s: f64,
        limits: &SupervisorLimits,
    ) -> anyhow::Result<(Supervised<MuscleBench>, f64, f64)> {
        let bench = MuscleBench::at_rest(plant, position0_m)?.with_period(period_s);
        let mut sup = Supervised::new(bench, limits.clone(), None);
        let started = sup.start()?;
        Ok((sup, started.reading.position_m, started.command))
    }

    /// The latched fault, as an exception.
    fn check_fault(&self) -> PyResult<()> {
        self.fault.check("bench")
    }

    /// A fault: the muscle vented, the fault latched and raised.
    fn trip(&mut self, message: String) -> PyErr {
        self.sup.stop();
        self.fault.set(message)
    }
}

#[pymethods]
impl Bench {
    /// A bench of plant ``plant`` (a preset: ideal, mismatch, realistic,
    /// realistic_known_lag; or a plant .toml file), the load at rest at contraction
    /// ``position`` (m), stepped every ``period`` (s, 0.0001..=0.01).
    #[new]
    #[pyo3(signature = (plant = "ideal", position = 0.0, period = 1e-3))]
    fn new(plant: &str, position: f64, period: f64) -> PyResult<Self> {
        let cfg = PlantConfig::load(plant).map_err(py_err)?;
        let spec = pma_bench::RunSpec {
            period_s: period,
            duration_s: 1.0,
            ..pma_bench::RunSpec::default()
        };
        spec.validate().map_err(py_err)?;
        if !position.is_finite() {
            return Err(PmaError::new_err(format!(
                "position = {position} m is invalid: must be finite"
            )));
        }
        let limits = limits(&cfg).map_err(to_py)?;
        let (sup, reading_m, applied_pa) =
            Self::started(&cfg, position, period, &limits).map_err(to_py)?;
        Ok(Self {
            plant: cfg,
            position0_m: position,
            period_s: period,
            limits,
            sup,
            reading_m,
            applied_pa,
            periods: 0,
            fault: Latch::default(),
        })
    }

    /// Puts the load back at rest where it started, the clock at 0 and any fault cleared;
    /// returns the first reading (m).
    fn reset(&mut self) -> PyResult<f64> {
        let (sup, reading_m, applied_pa) =
            Self::started(&self.plant, self.position0_m, self.period_s, &self.limits)
                .map_err(to_py)?;
        self.sup = sup;
        self.reading_m = reading_m;
        self.applied_pa = applied_pa;
        self.periods = 0;
        self.fault.clear();
        Ok(reading_m)
    }

    /// The sensor's last reading (m): contraction, positive when the muscle is shorter
    /// than at rest.
    fn read(&self) -> PyResult<f64> {
        self.check_fault()?;
        Ok(self.reading_m)
    }

    /// Sends a pressure command (Pa gauge), held over the next period; returns it as the
    /// supervisor applied it (rate-limited). Raises ``PmaError`` for a NaN, infinite or
    /// out-of-range pressure (nothing is sent).
    fn write(&mut self, pressure: f64) -> PyResult<f64> {
        self.check_fault()?;
        let max = self.limits.pressure_max_pa;
        if !(pressure.is_finite() && (0.0..=max).contains(&pressure)) {
            return Err(PmaError::new_err(format!(
                "pressure command {pressure} Pa is invalid: must be a finite pressure within 0 to {max} Pa"
            )));
        }
        let applied = self
            .sup
            .write(&pressure)
            .map_err(|e| self.trip(e.to_string()))?;
        self.applied_pa = applied;
        Ok(applied)
    }

    /// One control period passes with the last command held; returns the new reading (m).
    /// A reading outside the supervisor's window vents the muscle and raises
    /// ``SupervisorError``.
    fn step(&mut self) -> PyResult<f64> {
        self.check_fault()?;
        self.sup.wait().map_err(|e| self.trip(e.to_string()))?;
        self.periods += 1;
        let reading = self.sup.read().map_err(|e| self.trip(e.to_string()))?;
        self.reading_m = reading.position_m;
        Ok(self.reading_m)
    }

    /// Time of the last reading (s).
    #[getter]
    fn time(&self) -> f64 {
        self.periods as f64 * self.period_s
    }

    /// The control period (s).
    #[getter]
    fn period(&self) -> f64 {
        self.period_s
    }

    /// The last command the supervisor applied (Pa).
    #[getter]
    fn command(&self) -> f64 {
        self.applied_pa
    }

    /// The plant's name.
    #[getter]
    fn plant(&self) -> String {
        self.plant.name.clone()
    }

    /// The supervisor's limits: ``pressure_max_pa``, ``pressure_rate_max_pa_per_s``,
    /// ``position_min_m``, ``position_max_m``, ``sensor_stuck_periods`` (0: unchecked).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = &self.limits;
        let d = PyDict::new(py);
        d.set_item("pressure_max_pa", l.pressure_max_pa)?;
        d.set_item("pressure_rate_max_pa_per_s", l.pressure_rate_max_pa_per_s)?;
        if let Some(w) = l.windows.first() {
            d.set_item("position_min_m", w.min)?;
            d.set_item("position_max_m", w.max)?;
        }
        d.set_item("sensor_stuck_periods", l.sensor_stuck_periods)?;
        Ok(d)
    }

    /// The true state at the last reading (what the sensor does not say):
    /// ``position_m``, ``velocity_m_s``, ``pressure_pa``, ``force_n``.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.sup.truth();
        let d = PyDict::new(py);
        d.set_item("position_m", s.position_m)?;
        d.set_item("velocity_m_s", s.velocity_m_s)?;
        d.set_item("pressure_pa", s.pressure_pa)?;
        d.set_item("force_n", s.force_n)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Bench(plant={:?}, position={}, period={}) at t = {} s",
            self.plant.name,
            self.position0_m,
            self.period_s,
            self.time()
        )
    }
}
