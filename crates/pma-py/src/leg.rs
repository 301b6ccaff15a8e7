//! `pma_exo.Leg`: the exoskeleton leg (or the treadmill trainer), stepped one control
//! period at a time by a controller written in Python, behind the leg's supervisor.
use crate::errors::{py_err, to_py, Latch, PmaError};
use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pma_control::supervisor::SupervisorLimits;
use pma_leg::gait::GaitReference;
use pma_leg::plant::{reading_angles, reading_cuff_nm};
use pma_leg::{LegSim, LoadedScenario, PerLeg, Scenario, SupervisedLeg};
use pma_loop::Backend;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// How far ahead the patients' random spasms are drawn (s): a chunk at a time, as the
/// clock reaches the end of the last one.
const SPASM_PLAN_S: f64 = 10.0;

/// Muscles per leg: hip flexor, hip extensor, knee flexor, knee extensor (the scenario's
/// order, `Leg.muscles`).
const MUSCLES: usize = 4;

/// A shape as Python writes it: `(3,)`, `(2, 4)`.
fn python_shape(shape: &[usize]) -> String {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    }
}

/// A supervised leg, started: its first reading and the pressures it holds.
struct Started {
    sup: SupervisedLeg,
    reading: PerLeg<pma_leg::LegReading>,
    applied: PerLeg<[f64; MUSCLES]>,
}

/// The leg of `loaded` at rest, behind the supervisor of the CLI's runs, started.
fn start(loaded: &LoadedScenario) -> anyhow::Result<(Started, SupervisorLimits)> {
    let sim = LegSim::new(loaded)?;
    let (plant, _, limits) = sim.into_parts();
    let mut sup = SupervisedLeg::new(plant, limits.clone(), None);
    let started = sup.start()?;
    Ok((
        Started {
            sup,
            reading: started.reading,
            applied: started.command,
        },
        limits,
    ))
}

/// The exoskeleton leg of a scenario (rapier3d; a flexor and an extensor muscle on hip
/// and knee; the scenario's patient), stepped by a controller written in Python.
///
/// Each period: ``q = leg.read()`` (encoder angles, rad, shape ``(legs, 2)``: hip, knee),
/// ``leg.write(p)`` (pressures, Pa, shape ``(legs, 4)`` in the order of ``leg.muscles``;
/// ``(4,)`` for one leg), ``leg.step()``. The supervisor of ``pma-exo simulate`` stands
/// between: commands are rate-limited; an encoder past its joint's limits vents every
/// muscle and raises ``SupervisorError``, after which only ``reset()`` goes on.
#[pyclass(module = "pma_exo", unsendable)]
pub struct Leg {
    loaded: LoadedScenario,
    limits: SupervisorLimits,
    reference: GaitReference,
    muscles: Vec<String>,
    legs: usize,
    run: Started,
    periods: u64,
    planned_until_s: f64,
    fault: Latch,
}

impl Leg {
    fn period_s(&self) -> f64 {
        self.loaded.scenario.period_s
    }

    fn time_s(&self) -> f64 {
        self.periods as f64 * self.period_s()
    }

    fn check_fault(&self) -> PyResult<()> {
        self.fault.check("leg")
    }

    fn trip(&mut self, message: String) -> PyErr {
        self.run.sup.stop();
        self.fault.set(message)
    }

    /// Draws the patients' spasms of the next chunk once the clock nears the last one's
    /// end.
    fn plan_spasms(&mut self) {
        let t = self.time_s() + self.period_s();
        if t < self.planned_until_s {
            return;
        }
        self.planned_until_s = t + SPASM_PLAN_S;
        for p in self.run.sup.inner_mut().patients_mut() {
            p.plan(self.planned_until_s);
        }
    }

    /// `(legs, k)` values as a float64 array.
    fn array<'py, const K: usize>(
        &self,
        py: Python<'py>,
        values: &PerLeg<[f64; K]>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = values.iter().flatten().copied().collect();
        PyArray1::from_vec(py, flat).reshape([self.legs, K])
    }

    /// The pressures of `write`: a float64 array of shape `(legs, 4)` (or `(4,)` for one
    /// leg), or a flat sequence of floats leg after leg; every one finite and within the
    /// valve's range.
    fn pressures(&self, value: &Bound<'_, PyAny>) -> PyResult<PerLeg<[f64; MUSCLES]>> {
        let expected = if self.legs == 1 {
            format!("({}, {MUSCLES}) or ({MUSCLES},)", self.legs)
        } else {
            format!("({}, {MUSCLES})", self.legs)
        };
        let flat: Vec<f64> = if let Ok(array) = value.cast::<PyUntypedArray>() {
            let typed: PyReadonlyArrayDyn<'_, f64> = array.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "pressures must be float64 (got dtype {}): use np.asarray(p, dtype=np.float64)",
                    array.dtype()
                ))
            })?;
            let shape = typed.as_array().shape().to_vec();
            let fits = shape == [self.legs, MUSCLES] || (self.legs == 1 && shape == [MUSCLES]);
            if !fits {
                return Err(PmaError::new_err(format!(
                    "pressures have shape {}: expected {expected} (Pa, in the order of Leg.muscles)",
                    python_shape(&shape)
                )));
            }
            typed.as_array().iter().copied().collect()
        } else {
            let flat: Vec<f64> = value.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "pressures must be a float64 array of shape {expected} or a sequence of floats"
                ))
            })?;
            if flat.len() != self.legs * MUSCLES {
                return Err(PmaError::new_err(format!(
                    "{} pressures given: expected {} ({MUSCLES} per leg, in the order of Leg.muscles)",
                    flat.len(),
                    self.legs * MUSCLES
                )));
            }
            flat
        };
        let max = self.limits.pressure_max_pa;
        for (i, p) in flat.iter().enumerate() {
            if !(p.is_finite() && (0.0..=max).contains(p)) {
                return Err(PmaError::new_err(format!(
                    "pressure command {p} Pa for muscle {} of leg {} is invalid: must be a finite pressure within 0 to {max} Pa",
                    self.muscles[i % MUSCLES],
                    i / MUSCLES
                )));
            }
        }
        Ok(PerLeg::from_fn(self.legs, |leg| {
            std::array::from_fn(|m| flat[leg * MUSCLES + m])
        }))
    }
}

#[pymethods]
impl Leg {
    /// The leg of scenario ``scenario`` (an embedded name or a scenario .toml file), at
    /// rest, its valves holding the co-contraction pressures.
    #[new]
    #[pyo3(signature = (scenario = "gait_training"))]
    fn new(scenario: &str) -> PyResult<Self> {
        let loaded = Scenario::load(scenario).map_err(py_err)?;
        let reference = loaded.scenario.gait.reference().map_err(py_err)?;
        let (run, limits) = start(&loaded).map_err(to_py)?;
        let plant = run.sup.inner();
        let legs = plant.leg_count();
        let muscles = plant.muscle_names();
        let mut leg = Self {
            loaded,
            limits,
            reference,
            muscles,
            legs,
            run,
            periods: 0,
            planned_until_s: 0.0,
            fault: Latch::default(),
        };
        leg.plan_spasms();
        Ok(leg)
    }

    /// Back at rest, the clock at 0, a fault cleared; returns the first reading.
    fn reset<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (run, _) = start(&self.loaded).map_err(to_py)?;
        self.run = run;
        self.periods = 0;
        self.planned_until_s = 0.0;
        self.fault.clear();
        self.plan_spasms();
        self.array(py, &self.run.reading.map(reading_angles))
    }

    /// The encoders' last reading (rad, flexion positive): shape ``(legs, 2)``, hip and
    /// knee.
    fn read<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.check_fault()?;
        self.array(py, &self.run.reading.map(reading_angles))
    }

    /// The cuff torque sensors' last reading (N m, the torque the device puts into the
    /// limb, flexion positive): shape ``(legs, 2)``, hip and knee.
    fn cuffs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.check_fault()?;
        self.array(py, &self.run.reading.map(reading_cuff_nm))
    }

    /// Sends the pressure commands (Pa gauge), held over the next period; returns them as
    /// the supervisor applied them (rate-limited), shape ``(legs, 4)``. Raises
    /// ``TypeError`` for a non-float64 array, ``PmaError`` for a wrong shape or a NaN,
    /// infinite or out-of-range pressure (nothing is sent).
    fn write<'py>(
        &mut self,
        py: Python<'py>,
        pressures: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.check_fault()?;
        let commands = self.pressures(pressures)?;
        let applied = self
            .run
            .sup
            .write(&commands)
            .map_err(|e| self.trip(e.to_string()))?;
        self.run.applied = applied;
        self.array(py, &applied)
    }

    /// One control period passes with the commands held (the physics substeps, the
    /// patient's torques); returns the new reading, shape ``(legs, 2)``.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.check_fault()?;
        self.plan_spasms();
        self.run.sup.wait().map_err(|e| self.trip(e.to_string()))?;
        self.periods += 1;
        let reading = self.run.sup.read().map_err(|e| self.trip(e.to_string()))?;
        self.run.reading = reading;
        self.array(py, &reading.map(reading_angles))
    }

    /// The gait reference at time ``t`` (s; default: now): hip and knee angles (rad),
    /// shape ``(legs, 2)``, each leg on its own phase.
    #[pyo3(signature = (t = None))]
    fn reference<'py>(
        &self,
        py: Python<'py>,
        t: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = t.unwrap_or_else(|| self.time_s());
        let angles = PerLeg::from_fn(self.legs, |leg| {
            let s = self.reference.for_leg(leg).sample(t);
            [s.hip.angle_rad, s.knee.angle_rad]
        });
        self.array(py, &angles)
    }

    /// The true state at the last reading: ``angle_rad``, ``velocity_rad_s``,
    /// ``interaction_nm`` (the torque the device puts into the limb) and ``cuff_force_n``
    /// (the thigh and shank cuff forces that put it there; shape ``(legs, 2)``),
    /// ``pressure_pa`` and ``force_n`` (shape ``(legs, 4)``).
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.run.sup.truth();
        let d = PyDict::new(py);
        d.set_item("angle_rad", self.array(py, &s.legs.map(|l| l.angle_rad))?)?;
        d.set_item(
            "velocity_rad_s",
            self.array(py, &s.legs.map(|l| l.velocity_rad_s))?,
        )?;
        d.set_item(
            "pressure_pa",
            self.array(py, &s.legs.map(|l| l.pressure_pa))?,
        )?;
        d.set_item("force_n", self.array(py, &s.legs.map(|l| l.force_n))?)?;
        d.set_item(
            "interaction_nm",
            self.array(py, &s.legs.map(|l| l.interaction_nm))?,
        )?;
        d.set_item(
            "cuff_force_n",
            self.array(py, &s.legs.map(|l| l.cuff_force_n))?,
        )?;
        Ok(d)
    }

    /// Time of the last reading (s).
    #[getter]
    fn time(&self) -> f64 {
        self.time_s()
    }

    /// The control period (s).
    #[getter]
    fn period(&self) -> f64 {
        self.period_s()
    }

    /// Number of legs (1, or 2 on a two-legged treadmill trainer).
    #[getter]
    fn legs(&self) -> usize {
        self.legs
    }

    /// The muscles of a leg, in the order of ``write``'s columns.
    #[getter]
    fn muscles(&self) -> Vec<String> {
        self.muscles.clone()
    }

    /// The last commands as the supervisor applied them (Pa), shape ``(legs, 4)``.
    #[getter]
    fn command<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.array(py, &self.run.applied)
    }

    /// The supervisor's limits: ``pressure_max_pa``, ``pressure_rate_max_pa_per_s``,
    /// ``windows`` (each reading's name and admissible range: encoders in rad, cuff torques
    /// in N m, pressures in Pa) and ``joint_speed_max_rad_s`` (the physics' bound).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = &self.limits;
        let d = PyDict::new(py);
        d.set_item("pressure_max_pa", l.pressure_max_pa)?;
        d.set_item("pressure_rate_max_pa_per_s", l.pressure_rate_max_pa_per_s)?;
        let windows = PyDict::new(py);
        for w in &l.windows {
            windows.set_item(w.name, (w.min, w.max))?;
        }
        d.set_item("windows", windows)?;
        // Beyond it the simulation has left its physics and the run fails.
        d.set_item(
            "joint_speed_max_rad_s",
            pma_leg::plant::JOINT_SPEED_MAX_RAD_S,
        )?;
        Ok(d)
    }

    /// The scenario's name.
    #[getter]
    fn scenario(&self) -> String {
        self.loaded.scenario.name.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Leg(scenario={:?}) with {} leg(s) at t = {} s",
            self.loaded.scenario.name,
            self.legs,
            self.time_s()
        )
    }
}
