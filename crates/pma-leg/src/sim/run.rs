//! The closed-loop gait simulation: the exoskeleton plant, every leg's controllers and its
//! metrics, run through the one loop of `pma-loop`.
use crate::base::{LegError, LegFault, PerLeg, JOINT_NAMES};
use crate::body::{Exoskeleton, Mount};
use crate::control::{LegControllers, LegOutput, TrainerControllers};
use crate::gait::GaitReference;
use crate::metrics::{
    FootMetrics, LegMetrics, LegReport, OnLeg, PatientMetrics, TrainerGroundMetrics,
};
use crate::patient::SpasmEvent;
use crate::plant::{LegPlant, MuscleActuator, SupervisedLeg, TrainerState, MUSCLES_PER_LEG};
use crate::scenario::{LoadedScenario, Scenario};
use crate::sim::{
    baseline_traces, build_exo, build_muscles, build_patients, expected_moments, phase_sync,
    stance_load, supervisor_limits,
};
use pma_control::supervisor::{Supervised, SupervisorLimits};
use pma_control::ControllerConfig;
use pma_loop::{LoopSettings, Recorder};
use pma_model::{DampingMode, MuscleModel};

/// The exoskeleton with its muscles, controllers, references and metrics.
pub struct LegSim {
    pub(crate) scenario: Scenario,
    plant: SupervisedLeg,
    controllers: TrainerControllers,
    /// What built it, while the simulation is as built (no pose held, state set or plant
    /// touched): the spasms' baseline run is the same simulation without the spasms.
    origin: Option<Box<(LoadedScenario, ControllerConfig, Mount)>>,
}

/// Pressures `(flexor, extensor)` with equal forces at the given contractions and mean
/// `p_mean`: the pair holds a joint without gravity torque at that co-contraction.
pub fn balanced_pressures(
    f: &MuscleModel,
    x_f: f64,
    e: &MuscleModel,
    x_e: f64,
    p_mean: f64,
) -> (f64, f64) {
    // Both models are affine in the pressure at rest, F(p, x) = a + b p: solve F_f = F_e
    // with p_f + p_e = 2 p_mean.
    let affine = |m: &MuscleModel, x: f64| {
        let at = |p: f64| m.force_unclamped(p, x, 0.0, DampingMode::Inflation);
        let a = at(0.0);
        (a, (at(1e5) - a) / 1e5)
    };
    let ((af, bf), (ae, be)) = (affine(f, x_f), affine(e, x_e));
    let p_f = (ae - af + 2.0 * be * p_mean) / (bf + be);
    (p_f, 2.0 * p_mean - p_f)
}

/// Each pair at the balanced pressures of the co-contraction target, at zero angles.
fn resting_pressures(muscles: &[MuscleActuator], p_cc: f64) -> [f64; 4] {
    let mut p = [0.0; 4];
    for j in 0..JOINT_NAMES.len() {
        let pair: Vec<usize> = (0..muscles.len())
            .filter(|&i| muscles[i].joint == j)
            .collect();
        let (fi, ei) = if muscles[pair[0]].geometry.side == crate::plant::Side::Flexor {
            (pair[0], pair[1])
        } else {
            (pair[1], pair[0])
        };
        let (f, e) = (&muscles[fi], &muscles[ei]);
        let (pf, pe) = balanced_pressures(
            &f.model,
            f.geometry.contraction_at_zero_m,
            &e.model,
            e.geometry.contraction_at_zero_m,
            p_cc,
        );
        p[fi] = pf;
        p[ei] = pe;
    }
    p
}

impl LegSim {
    /// Builds the simulation of a loaded scenario with the scenario's APRC-NDO gains on
    /// every muscle (those its patient's support selects), the legs standing still at rest.
    pub fn new(loaded: &LoadedScenario) -> Result<Self, LegError> {
        let config = ControllerConfig::AprcNdo(loaded.scenario.aprc_gains());
        Self::with_controller(loaded, &config)
    }

    /// As [`LegSim::new`] with `config` on every muscle.
    pub fn with_controller(
        loaded: &LoadedScenario,
        config: &ControllerConfig,
    ) -> Result<Self, LegError> {
        Self::mounted(loaded, config, Mount::default())
    }

    /// As [`LegSim::with_controller`] with the leg mounted as `mount` says.
    pub fn mounted(
        loaded: &LoadedScenario,
        config: &ControllerConfig,
        mount: Mount,
    ) -> Result<Self, LegError> {
        let sc = loaded.scenario.clone();
        sc.validate()?;
        let sync = phase_sync(&sc)?;
        let exo = build_exo(loaded, mount)?;
        let legs = exo.leg_count();
        let patients = build_patients(&sc, &exo)?;
        let muscles = build_muscles(&sc, &loaded.muscles, legs)
            .map_err(|e| e.in_file(&loaded.muscles_source))?;
        let mut per_leg = Vec::with_capacity(legs);
        for leg in 0..legs {
            let own = &muscles[leg * MUSCLES_PER_LEG..(leg + 1) * MUSCLES_PER_LEG];
            let mut controllers = LegControllers::new(
                &sc.control,
                sc.plant.valve.pressure_max_pa,
                sc.gait.reference()?.for_leg(leg),
                own,
                exo.inertia(),
                config,
                exo.limits_rad(leg),
            )?;
            if let Some(load) = stance_load(&sc, &exo)? {
                controllers.set_stance_load(load);
            }
            if let Some(expected) = expected_moments(&sc, leg)? {
                controllers.set_expected_moments(expected);
            }
            per_leg.push(controllers);
        }
        let limits = supervisor_limits(&sc, &exo);
        let mut plant = LegPlant::new(
            exo,
            muscles,
            &sc.plant,
            sc.period_s,
            sc.implicit_muscle_damping,
        )?;
        plant.set_patients(patients);
        let gait = sc.gait.reference()?;
        for leg in 0..legs {
            let resting = resting_pressures(plant.leg_muscles(leg), sc.control.cocontraction_pa);
            let start = gait.for_leg(leg).sample(0.0);
            plant.set_state(leg, [start.hip.angle_rad, start.knee.angle_rad], [0.0; 2]);
            plant.set_pressures(leg, resting)?;
        }
        let controllers = match sync {
            Some(sync) => TrainerControllers::new(per_leg).with_phase_sync(sync),
            None => TrainerControllers::new(per_leg),
        };
        Ok(Self {
            scenario: sc,
            plant: Supervised::new(plant, limits, None),
            controllers,
            origin: Some(Box::new((loaded.clone(), *config, mount))),
        })
    }

    /// Replaces the gait by a constant pose (rad) on every leg: the reference for a static
    /// hold. On a one-leg treadmill the virtual other leg holds it too.
    pub fn hold_pose(&mut self, angles: [f64; 2]) {
        self.origin = None;
        self.controllers.hold_pose(angles);
        self.plant
            .inner_mut()
            .exo_mut()
            .hold_other_leg(Some(angles));
    }

    /// Puts every leg at `angles` with `velocities` (the muscles' valves keep their
    /// pressure).
    pub fn set_state(&mut self, angles: [f64; 2], velocities: [f64; 2]) {
        self.origin = None;
        let plant = self.plant.inner_mut();
        for leg in 0..plant.leg_count() {
            plant.set_state(leg, angles, velocities);
        }
    }

    /// One period with every leg's valves commanded to `commands` directly (no
    /// controllers, no supervisor): open-loop checks.
    pub fn step_with_commands(&mut self, commands: [f64; 4]) -> TrainerState {
        self.origin = None;
        let plant = self.plant.inner_mut();
        let all = PerLeg::splat(plant.leg_count(), commands);
        plant.apply(all)
    }

    /// Vents every muscle at once and unhooks its cable: the limbs move on their own.
    pub fn release_muscles(&mut self) -> Result<(), LegError> {
        self.origin = None;
        let plant = self.plant.inner_mut();
        plant.vent_all()?;
        plant.attach_muscles(false);
        Ok(())
    }

    /// The plant, to mount or hold the leg (studies such as the pendulum test).
    pub fn plant_mut(&mut self) -> &mut LegPlant {
        self.origin = None;
        self.plant.inner_mut()
    }

    /// Runs `task` instead of the legs' controllers (the plant, its patients and
    /// `recorder` as usual).
    pub fn run_task<T, R>(
        &mut self,
        task: &mut T,
        recorder: &mut R,
        settings: &LoopSettings,
    ) -> Result<pma_loop::Outcome<std::convert::Infallible>, LegError>
    where
        T: pma_loop::Task<
            Reading = PerLeg<crate::plant::LegReading>,
            Command = PerLeg<[f64; 4]>,
            Output = PerLeg<LegOutput>,
        >,
        R: Recorder<SupervisedLeg, PerLeg<LegOutput>>,
    {
        let t_end = self.plant.time() + settings.duration_s();
        for p in self.plant.inner_mut().patients_mut() {
            p.plan(t_end + self.scenario.period_s);
        }
        let outcome = pma_loop::run(&mut self.plant, task, recorder, settings)?;
        outcome.into_result().map_err(LegError::from_fault)
    }

    /// The scenario's gait reference (the first leg's).
    pub fn gait_reference(&self) -> Result<GaitReference, LegError> {
        self.scenario.gait.reference()
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The plant (exoskeleton, muscles, encoders).
    pub fn plant(&self) -> &LegPlant {
        self.plant.inner()
    }

    /// The plant, the controllers and what the supervisor enforces, apart: to run the legs
    /// behind another backend (a test's faulty encoder, say).
    pub fn into_parts(self) -> (LegPlant, TrainerControllers, SupervisorLimits) {
        let limits = supervisor_limits(&self.scenario, self.plant.exo());
        (self.plant.into_inner(), self.controllers, limits)
    }

    /// Every leg's controllers.
    pub fn controllers(&self) -> &TrainerControllers {
        &self.controllers
    }

    /// The exoskeleton (poses, angles).
    pub fn exo(&self) -> &Exoskeleton {
        self.plant.exo()
    }

    /// Number of legs.
    pub fn leg_count(&self) -> usize {
        self.plant.leg_count()
    }

    /// Every leg's muscles, leg after leg.
    pub fn muscles(&self) -> &[MuscleActuator] {
        self.plant.muscles()
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.plant.time()
    }

    /// The loop settings of a run of `duration_s` (at least a period of the scenario).
    pub fn settings(&self, duration_s: f64) -> Result<LoopSettings<'static>, LegError> {
        let settings = LoopSettings::new(duration_s)?;
        settings.periods(self.scenario.period_s)?;
        Ok(settings)
    }

    /// Runs for `duration_s` with `recorder` observing every period (`&mut ()` for none).
    pub fn run<R: Recorder<SupervisedLeg, PerLeg<LegOutput>>>(
        &mut self,
        duration_s: f64,
        recorder: &mut R,
    ) -> Result<LegReport, LegError> {
        let settings = self.settings(duration_s)?;
        self.run_with(&settings, recorder)
    }

    /// Runs with explicit loop settings (a stop flag, say); a supervisor's fault is an
    /// error ([`LegError::Supervisor`]).
    pub fn run_with<R: Recorder<SupervisedLeg, PerLeg<LegOutput>>>(
        &mut self,
        settings: &LoopSettings,
        recorder: &mut R,
    ) -> Result<LegReport, LegError> {
        match self.run_until_fault(settings, recorder)? {
            (report, None) => Ok(report),
            (_, Some(fault)) => Err(LegError::Supervisor(fault.message)),
        }
    }

    /// Every leg's spasm events of a run from `t0` to `t_end` (drawn now, so that the loop
    /// allocates nothing).
    fn plan_spasms(&mut self, t0: f64, t_end: f64) -> Vec<Vec<SpasmEvent>> {
        let period = self.scenario.period_s;
        self.plant
            .inner_mut()
            .patients_mut()
            .iter_mut()
            .map(|p| {
                p.plan(t_end + period);
                p.events()
                    .iter()
                    .filter(|e| e.end_s() > t0 && e.t_s <= t_end)
                    .copied()
                    .collect()
            })
            .collect()
    }

    /// As [`LegSim::run_with`], but a run the supervisor stopped (the muscles vented) is a
    /// result: its report covers the run up to the fault, which comes with it. A failure
    /// of the simulation itself is still an error.
    pub fn run_until_fault<R: Recorder<SupervisedLeg, PerLeg<LegOutput>>>(
        &mut self,
        settings: &LoopSettings,
        recorder: &mut R,
    ) -> Result<(LegReport, Option<LegFault>), LegError> {
        let t0 = self.plant.time();
        let t_end = t0 + settings.duration_s();
        let events = self.plan_spasms(t0, t_end);
        // A spasm's effect is measured against the same run without the spasms (same
        // seeds, same controllers): its deviation and joint speed beyond what the gait
        // itself does there.
        let any_spasm = events.iter().any(|e| !e.is_empty());
        let baselines = match (&self.origin, any_spasm, t0 == 0.0) {
            (Some(origin), true, true) => Some(baseline_traces(origin, settings)?),
            _ => None,
        };
        let sc = &self.scenario;
        let legs = self.plant.leg_count();
        let mut metrics: Vec<OnLeg<LegMetrics>> = (0..legs)
            .map(|leg| {
                OnLeg::new(
                    leg,
                    LegMetrics::new(sc.gait.stride_period_s, sc.period_s, settings.duration_s()),
                )
            })
            .collect();
        let mut patients: Vec<OnLeg<PatientMetrics>> = (0..legs)
            .map(|leg| {
                let baseline = baselines.as_ref().and_then(|b| b.get(leg).cloned());
                OnLeg::new(
                    leg,
                    PatientMetrics::new(
                        &self.plant,
                        leg,
                        events.get(leg).map_or(&[], |e| e.as_slice()),
                        t_end,
                        sc.plant.valve.pressure_max_pa,
                        baseline,
                    ),
                )
            })
            .collect();
        let mut feet: Vec<OnLeg<FootMetrics>> = (0..legs)
            .filter_map(|leg| {
                FootMetrics::new(
                    self.plant.exo(),
                    self.controllers.leg(leg).gait(),
                    settings.duration_s(),
                    sc.period_s,
                )
                .map(|m| OnLeg::new(leg, m))
            })
            .collect();
        let mut ground = TrainerGroundMetrics::new(self.plant.exo(), sc.gait.stride_period_s);
        let width_deg = match sc.control.mode {
            crate::control::ControlMode::Path => sc.control.path.width_deg,
            _ => crate::metrics::TUNNEL_WIDTH_DEG,
        };
        let mut cooperation: Vec<OnLeg<crate::metrics::CooperationMetrics>> = (0..legs)
            .map(|leg| {
                OnLeg::new(
                    leg,
                    crate::metrics::CooperationMetrics::new(
                        self.controllers.leg(leg).gait(),
                        width_deg,
                    ),
                )
            })
            .collect();
        let outcome = pma_loop::run(
            &mut self.plant,
            &mut self.controllers,
            &mut (
                &mut metrics,
                &mut patients,
                &mut feet,
                &mut (&mut ground, &mut cooperation),
                recorder,
            ),
            settings,
        )?;
        let (interrupted, fault) = ending(outcome.end)?;
        let ran_s = outcome.ran_s;
        let names = self.plant.muscle_names();
        let mut report = LegReport::of_legs(
            &sc.name,
            ran_s,
            outcome.wall_s,
            &names,
            metrics.iter().map(|m| &m.inner),
            patients.iter().map(|p| (&p.inner, t0 + ran_s)),
        );
        report.interrupted = interrupted;
        report.treadmill = ground.report(feet.iter().map(|f| f.inner.report()).collect());
        report.cooperation = cooperation.iter().map(|c| c.inner.report()).collect();
        report.phase_sync = self.controllers.phase_sync().map(|s| s.report());
        report.step = Some(crate::metrics::StepReport {
            period_s: sc.period_s,
            physics_substeps: sc.physics_substeps,
            physics_step_s: sc.period_s / f64::from(sc.physics_substeps.max(1)),
            implicit_muscle_damping: sc.implicit_muscle_damping,
        });
        let planned_s = if interrupted {
            ran_s
        } else {
            settings.duration_s()
        };
        report.walking = crate::metrics::judge(
            &report,
            planned_s,
            sc.gait.stride_period_s,
            fault.as_ref(),
            crate::metrics::WalkingCriteria::default(),
        );
        Ok((report, fault))
    }
}

/// How a run ended: interrupted or not, and the fault that stopped it (the trainer's
/// collapse stop and the supervisor's faults are results); a failure of the simulation
/// itself is an error.
fn ending(
    end: pma_loop::End<pma_control::Fault<LegError>>,
) -> Result<(bool, Option<LegFault>), LegError> {
    let ended = match end {
        pma_loop::End::Completed => (false, None),
        pma_loop::End::Stopped => (true, None),
        // The trainer's safety stopped a collapsing patient: a result, not a failure
        // of the simulation.
        pma_loop::End::Fault {
            error: pma_control::Fault::Backend(LegError::Collapse { t_s, what }),
            ..
        } => (
            false,
            Some(LegFault {
                name: "collapse",
                t_s,
                message: what,
            }),
        ),
        pma_loop::End::Fault {
            error: pma_control::Fault::Backend(e),
            ..
        } => return Err(e),
        pma_loop::End::Fault { error, t_s, .. } => (
            false,
            Some(LegFault {
                name: error.name(),
                t_s,
                message: error.to_string(),
            }),
        ),
    };
    Ok(ended)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;

    /// Regression: a spasm scenario's baseline (the same run without its spasms, run first)
    /// was given loop settings without the operator's stop flag, so a SIGINT or SIGTERM
    /// waited for a whole baseline run: 12-15 s of a 60 s `simulate gait_spasms` at the
    /// in-air 64 substeps, about 46 s of `compare-modes`.
    #[test]
    fn regression_a_spasm_scenarios_baseline_stops_on_the_operator_stop() {
        let loaded = Scenario::load("gait_spasms").expect("scenario");
        let sim = LegSim::new(&loaded).expect("sim");
        let origin = sim.origin.as_deref().expect("a sim built from a scenario");
        let stop = AtomicBool::new(true);
        let settings = LoopSettings::new(1.6)
            .expect("settings")
            .with_stop_flag(&stop);
        let traces = baseline_traces(origin, &settings).expect("baseline");
        assert!(
            traces.iter().all(|t| t.len() <= 1),
            "the baseline ran on after the stop: {:?} periods",
            traces.iter().map(Vec::len).collect::<Vec<_>>()
        );
    }
}
