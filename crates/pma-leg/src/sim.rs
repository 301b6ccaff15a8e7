//! The closed-loop gait simulation: the leg plant, its controllers and its metrics, run
//! through the one loop of `pma-loop`.
use crate::config::{LoadedScenario, MuscleGeometry, Scenario};
use crate::control::{LegControllers, LegOutput};
use crate::error::{invalid, LegError};
use crate::gait::GaitReference;
use crate::ground::GroundReaction;
use crate::leg::{Leg, Mount, JOINT_NAMES};
use crate::metrics::{LegMetrics, LegReport};
use crate::patient::{Patient, PatientTorques, SpasmEvent};
use crate::plant::{LegPlant, LegState, MuscleActuator, SupervisedLeg, LIMIT_OVERSHOOT_MAX_RAD};
use crate::safety::PatientMetrics;
use crate::stance::TreadmillMetrics;
use pma_control::supervisor::{ReadingWindow, Supervised, SupervisorLimits};
use pma_control::{ControllerConfig, Diagnostics};
use pma_loop::{LoopSettings, Period, Recorder, Schema, Signals};
use pma_model::{DampingMode, MuscleModel, MuscleParams, Valve};

/// One period of the leg as logs show it: the state at the reading and what the
/// controllers made of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegSample {
    /// Time (s).
    pub t_s: f64,
    /// Reference joint angles (rad).
    pub reference_rad: [f64; 2],
    /// Joint angles (rad).
    pub angle_rad: [f64; 2],
    /// Reference joint velocities (rad/s).
    pub reference_velocity_rad_s: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// Pressure commands computed from this reading (Pa), muscle order of the geometry file.
    pub pressure_cmd_pa: [f64; 4],
    /// Pressures (Pa).
    pub pressure_pa: [f64; 4],
    /// Length references (m).
    pub length_ref_m: [f64; 4],
    /// Contractions (m).
    pub length_m: [f64; 4],
    /// Forces (N).
    pub force_n: [f64; 4],
    /// Controller states.
    pub diagnostics: [Diagnostics; 4],
    /// The patient's torque at hip and knee (N m, flexion positive), all parts.
    pub patient_nm: [f64; 2],
    /// Its parts (N m): reflex, spasm (non-zero while a spasm acts on the joint), voluntary
    /// effort, passive stiffness.
    pub patient_parts_nm: PatientTorques,
    /// On a treadmill: the belt's reaction, the pelvis's height (m) and whether the
    /// reference's foot is in stance.
    pub ground: Option<(GroundReaction, f64, bool)>,
}

impl LegSample {
    /// The leg's view of one loop period.
    pub fn of(p: &Period<'_, SupervisedLeg, LegOutput>) -> Self {
        let (s, o) = (p.truth, p.output);
        Self {
            t_s: p.t_s,
            reference_rad: o.reference_rad,
            angle_rad: s.angle_rad,
            reference_velocity_rad_s: o.reference_velocity_rad_s,
            velocity_rad_s: s.velocity_rad_s,
            pressure_cmd_pa: *p.written,
            pressure_pa: s.pressure_pa,
            length_ref_m: o.length_ref_m,
            length_m: s.length_m,
            force_n: s.force_n,
            diagnostics: o.diagnostics,
            patient_nm: s.patient.total(),
            patient_parts_nm: s.patient,
            ground: s.ground.map(|g| {
                (
                    g,
                    s.pelvis_height_m.unwrap_or(f64::NAN),
                    o.reference_in_stance,
                )
            }),
        }
    }
}

/// The joints' names, in reading order.
const JOINTS: [&str; 2] = ["hip", "knee"];

impl LegSample {
    /// The treadmill's channels alone (they follow the leg's in [`Self::schema_of`]).
    pub fn ground_schema() -> Schema {
        let mut s = Schema::new();
        Self::push_ground_schema(&mut s);
        s
    }

    /// The treadmill's channels, after the leg's: what the belt, the harness and the
    /// other leg do, and the phases.
    fn push_ground_schema(s: &mut Schema) {
        s.push_part(
            "ground",
            "foot",
            "grf_vertical_n",
            "vertical ground reaction force (N)",
        )
        .push_part(
            "ground",
            "foot",
            "grf_fore_aft_n",
            "fore-aft ground reaction force (N, forward +)",
        )
        .push_part(
            "ground",
            "foot",
            "stance",
            "in stance (1, from contact) or swing (0)",
        )
        .push_part(
            "ground",
            "foot",
            "reference_stance",
            "in the reference's stance (1) or swing (0)",
        )
        .push_part("ground", "foot", "slip_m_s", "slip on the belt (m/s)")
        .push_part(
            "ground",
            "foot",
            "penetration_m",
            "deepest sphere penetration (m)",
        )
        .push_part(
            "ground",
            "other_leg",
            "force_n",
            "(virtual) force on the pelvis (N)",
        )
        .push_part(
            "ground",
            "harness",
            "force_n",
            "body-weight support force (N)",
        )
        .push_part("ground", "pelvis", "height_m", "height above the belt (m)");
    }

    /// The leg's channels (after the time) for muscles named `muscles`, on a treadmill or
    /// not, as the CSV and Rerun show them.
    pub fn schema_of(muscles: &[String], treadmill: bool) -> Schema {
        let mut s = Self::schema(muscles);
        if treadmill {
            Self::push_ground_schema(&mut s);
        }
        s
    }

    /// The leg's channels (after the time) for muscles named `muscles`, as the CSV and
    /// Rerun show them (in the air; see [`Self::schema_of`]).
    pub fn schema(muscles: &[String]) -> Schema {
        let mut s = Schema::new();
        for j in JOINTS {
            s.push_part("joints", j, "reference_deg", "reference (deg)")
                .push_part("joints", j, "angle_deg", "angle (deg)")
                .push_part("joints", j, "error_deg", "error (deg)")
                .push_part(
                    "joints",
                    j,
                    "reference_velocity_deg_s",
                    "reference velocity (deg/s)",
                )
                .push_part("joints", j, "velocity_deg_s", "velocity (deg/s)")
                .push_part(
                    "joints",
                    j,
                    "patient_torque_nm",
                    "patient torque (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "reflex_torque_nm",
                    "patient's stretch reflex (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "spasm_torque_nm",
                    "spasm torque (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "effort_torque_nm",
                    "patient's voluntary effort (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "stiffness_torque_nm",
                    "patient's passive stiffness (N m, flexion +)",
                );
        }
        for m in muscles {
            s.push_part("muscles", m, "pressure_cmd_pa", "pressure command (Pa)")
                .push_part("muscles", m, "pressure_pa", "pressure (Pa)")
                .push_part("muscles", m, "length_ref_m", "contraction reference (m)")
                .push_part("muscles", m, "length_m", "contraction (m)")
                .push_part("muscles", m, "force_n", "force (N)")
                .push_part("muscles", m, "proxy_m", "proxy position (m)")
                .push_part("muscles", m, "s_p", "S_p (m/s)")
                .push_part("muscles", m, "s_q", "S_q (m/s)")
                .push_part("muscles", m, "gain_hat", "adaptive gain")
                .push_part(
                    "muscles",
                    m,
                    "disturbance_hat",
                    "disturbance estimate (m/s^2)",
                );
        }
        s
    }
}

impl Signals for LegSample {
    fn values(&self, out: &mut [f64]) {
        let mut k = 0;
        let mut put = |v: f64| {
            out[k] = v;
            k += 1;
        };
        for j in 0..2 {
            let (r, a) = (
                self.reference_rad[j].to_degrees(),
                self.angle_rad[j].to_degrees(),
            );
            let p = &self.patient_parts_nm;
            for v in [
                r,
                a,
                r - a,
                self.reference_velocity_rad_s[j].to_degrees(),
                self.velocity_rad_s[j].to_degrees(),
                self.patient_nm[j],
                p.reflex_nm[j],
                p.spasm_nm[j],
                p.effort_nm[j],
                p.stiffness_nm[j],
            ] {
                put(v);
            }
        }
        for i in 0..4 {
            let d = &self.diagnostics[i];
            for v in [
                self.pressure_cmd_pa[i],
                self.pressure_pa[i],
                self.length_ref_m[i],
                self.length_m[i],
                self.force_n[i],
                d.proxy_position_m,
                d.s_p,
                d.s_q,
                d.gain_hat,
                d.disturbance_hat,
            ] {
                put(v);
            }
        }
        if let Some((g, pelvis_m, reference_stance)) = self.ground {
            let stance = g.vertical_n > crate::stance::CONTACT_THRESHOLD_N;
            for v in [
                g.vertical_n,
                g.fore_aft_n,
                f64::from(u8::from(stance)),
                f64::from(u8::from(reference_stance)),
                g.slip_m_s,
                g.penetration_m,
                g.contralateral_n,
                g.support_n,
                pelvis_m,
            ] {
                put(v);
            }
        }
    }
}

/// The leg with its muscles, controllers, references and metrics.
pub struct LegSim {
    scenario: Scenario,
    plant: SupervisedLeg,
    controllers: LegControllers,
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
        let (fi, ei) = if muscles[pair[0]].geometry.side == crate::Side::Flexor {
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
    /// every muscle, the leg standing still at rest.
    pub fn new(loaded: &LoadedScenario) -> Result<Self, LegError> {
        let config = ControllerConfig::AprcNdo(loaded.scenario.control.gains);
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
        let leg = build_leg(loaded, mount)?;
        let patient = build_patient(&sc, &leg)?;
        let muscles =
            build_muscles(&sc, &loaded.muscles).map_err(|e| e.in_file(&loaded.muscles_source))?;
        let controllers = LegControllers::new(&sc, &muscles, leg.inertia(), config)?;
        let resting = resting_pressures(&muscles, sc.control.cocontraction_pa);
        let limits = supervisor_limits(&sc, leg.limits_rad());
        let mut plant = LegPlant::new(leg, muscles, &sc)?;
        plant.set_patient(patient);
        plant.set_state([0.0, 0.0], [0.0, 0.0]);
        plant.set_pressures(resting)?;
        Ok(Self {
            scenario: sc,
            plant: Supervised::new(plant, limits, None),
            controllers,
            origin: Some(Box::new((loaded.clone(), *config, mount))),
        })
    }

    /// Replaces the gait by a constant pose (rad): the reference for a static hold. On a
    /// treadmill the virtual other leg holds it too.
    pub fn hold_pose(&mut self, angles: [f64; 2]) {
        self.origin = None;
        self.controllers.hold_pose(angles);
        self.plant
            .inner_mut()
            .leg_mut()
            .hold_other_leg(Some(angles));
    }

    /// Puts the leg at `angles` with `velocities` (the muscles' valves keep their pressure).
    pub fn set_state(&mut self, angles: [f64; 2], velocities: [f64; 2]) {
        self.origin = None;
        self.plant.inner_mut().set_state(angles, velocities);
    }

    /// One period with the valves commanded directly (no controllers, no supervisor):
    /// open-loop checks.
    pub fn step_with_commands(&mut self, commands: [f64; 4]) -> LegState {
        self.origin = None;
        self.plant.inner_mut().apply(commands)
    }

    /// Vents every muscle at once and unhooks its cable: the limb moves on its own.
    pub fn release_muscles(&mut self) -> Result<(), LegError> {
        self.origin = None;
        let plant = self.plant.inner_mut();
        plant.set_pressures([0.0; 4])?;
        plant.attach_muscles(false);
        Ok(())
    }

    /// The plant, to mount or hold the leg (studies such as the pendulum test).
    pub fn plant_mut(&mut self) -> &mut LegPlant {
        self.origin = None;
        self.plant.inner_mut()
    }

    /// Runs `task` instead of the leg's controllers (the plant, its patient and
    /// `recorder` as usual).
    pub fn run_task<T, R>(
        &mut self,
        task: &mut T,
        recorder: &mut R,
        settings: &LoopSettings,
    ) -> Result<pma_loop::Outcome<std::convert::Infallible>, LegError>
    where
        T: pma_loop::Task<Reading = [f64; 2], Command = [f64; 4], Output = LegOutput>,
        R: Recorder<SupervisedLeg, LegOutput>,
    {
        let t_end = self.plant.time() + settings.duration_s();
        if let Some(p) = self.plant.inner_mut().patient_mut() {
            p.plan(t_end + self.scenario.period_s);
        }
        let outcome = pma_loop::run(&mut self.plant, task, recorder, settings)?;
        outcome.into_result().map_err(LegError::from_fault)
    }

    /// The scenario's gait reference.
    pub fn gait_reference(&self) -> Result<GaitReference, LegError> {
        let g = &self.scenario.gait;
        GaitReference::normative(g.speed, g.stride_period_s, g.ramp_s)
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The plant (leg, muscles, encoders).
    pub fn plant(&self) -> &LegPlant {
        self.plant.inner()
    }

    /// The plant, the controllers and what the supervisor enforces, apart: to run the leg
    /// behind another backend (a test's faulty encoder, say).
    pub fn into_parts(self) -> (LegPlant, LegControllers, SupervisorLimits) {
        let limits = supervisor_limits(&self.scenario, self.plant.leg().limits_rad());
        (self.plant.into_inner(), self.controllers, limits)
    }

    /// The leg (poses, angles).
    pub fn leg(&self) -> &Leg {
        self.plant.leg()
    }

    /// The muscles.
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
    pub fn run<R: Recorder<SupervisedLeg, LegOutput>>(
        &mut self,
        duration_s: f64,
        recorder: &mut R,
    ) -> Result<LegReport, LegError> {
        let settings = self.settings(duration_s)?;
        self.run_with(&settings, recorder)
    }

    /// Runs with explicit loop settings (a stop flag, say); a supervisor's fault is an
    /// error ([`LegError::Supervisor`]).
    pub fn run_with<R: Recorder<SupervisedLeg, LegOutput>>(
        &mut self,
        settings: &LoopSettings,
        recorder: &mut R,
    ) -> Result<LegReport, LegError> {
        match self.run_until_fault(settings, recorder)? {
            (report, None) => Ok(report),
            (_, Some(fault)) => Err(LegError::Supervisor(fault.message)),
        }
    }

    /// As [`LegSim::run_with`], but a run the supervisor stopped (the muscles vented) is a
    /// result: its report covers the run up to the fault, which comes with it. A failure
    /// of the simulation itself is still an error.
    pub fn run_until_fault<R: Recorder<SupervisedLeg, LegOutput>>(
        &mut self,
        settings: &LoopSettings,
        recorder: &mut R,
    ) -> Result<(LegReport, Option<LegFault>), LegError> {
        let sc = &self.scenario;
        let t0 = self.plant.time();
        let t_end = t0 + settings.duration_s();
        // Every spasm of the run is drawn now, so that the loop allocates nothing.
        let events: Vec<SpasmEvent> = match self.plant.inner_mut().patient_mut() {
            Some(p) => {
                p.plan(t_end + sc.period_s);
                p.events()
                    .iter()
                    .filter(|e| e.end_s() > t0 && e.t_s <= t_end)
                    .copied()
                    .collect()
            }
            None => Vec::new(),
        };
        // A spasm's effect is measured against the same run without the spasms (same
        // seeds, same controllers): its deviation and joint speed beyond what the gait
        // itself does there.
        let baseline = match (&self.origin, events.is_empty(), t0 == 0.0) {
            (Some(origin), false, true) => Some(baseline_trace(origin, settings)?),
            _ => None,
        };
        let sc = &self.scenario;
        let mut metrics = LegMetrics::new(sc.gait.stride_period_s, sc.period_s);
        let mut patient = PatientMetrics::new(
            &self.plant,
            &events,
            t_end,
            sc.plant.valve.pressure_max_pa,
            baseline,
        );
        let joint_of = std::array::from_fn(|i| self.plant.muscles().get(i).map_or(0, |m| m.joint));
        let mut treadmill = TreadmillMetrics::new(
            self.plant.leg(),
            self.controllers.gait(),
            joint_of,
            settings.duration_s(),
            sc.period_s,
        );
        let outcome = pma_loop::run(
            &mut self.plant,
            &mut self.controllers,
            &mut (&mut metrics, &mut patient, &mut treadmill, recorder),
            settings,
        )?;
        let (interrupted, fault) = match outcome.end {
            pma_loop::End::Completed => (false, None),
            pma_loop::End::Stopped => (true, None),
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
        let ran_s = outcome.ran_s;
        let names: Vec<String> = self
            .plant
            .muscles()
            .iter()
            .map(|m| m.geometry.name.clone())
            .collect();
        let mut report = metrics.report(&sc.name, &names, ran_s, outcome.wall_s);
        report.interrupted = interrupted;
        report.patient = patient.patient();
        report.spasms = patient.spasms(t0 + ran_s);
        report.safety = patient.safety(&names);
        report.treadmill = treadmill.map(|t| t.report());
        Ok((report, fault))
    }
}

/// The scenario's patient in `leg` (`None`: the passive limb).
pub(crate) fn build_patient(sc: &Scenario, leg: &Leg) -> Result<Option<Patient>, LegError> {
    if sc.patient.is_passive() {
        return Ok(None);
    }
    let gait = GaitReference::normative(sc.gait.speed, sc.gait.stride_period_s, sc.gait.ramp_s)?;
    Ok(Some(Patient::new(
        &sc.patient,
        leg.substep_s(),
        gait,
        *leg.inertia(),
        [
            sc.joints.hip.damping_nm_s_per_rad,
            sc.joints.knee.damping_nm_s_per_rad,
        ],
    )?))
}

/// The scenario's leg: fixed pelvis (as `mount` says), or on its treadmill, the belt at
/// the reference's speed unless the scenario gives one, the other leg added and the leg
/// standing at rest on the belt.
pub(crate) fn build_leg(loaded: &LoadedScenario, mount: Mount) -> Result<Leg, LegError> {
    let sc = &loaded.scenario;
    let joints = [sc.joints.hip, sc.joints.knee];
    let Some(treadmill) = &sc.treadmill else {
        return Leg::mounted(
            &loaded.urdf_text,
            &loaded.urdf_source,
            joints,
            sc.period_s,
            sc.physics_substeps,
            mount,
        );
    };
    if mount != Mount::default() {
        return Err(LegError::Parse {
            file: sc.name.clone(),
            message: "a treadmill scenario's leg stands on its belt: it cannot be mounted on a seat (pendulum test)".into(),
        });
    }
    let gait = GaitReference::normative(sc.gait.speed, sc.gait.stride_period_s, sc.gait.ramp_s)?;
    let mut leg = Leg::on_treadmill(
        &loaded.urdf_text,
        &loaded.urdf_source,
        joints,
        sc.period_s,
        sc.physics_substeps,
        treadmill,
    )?;
    if treadmill.speed_m_per_s.is_none() {
        leg.belt_at_reference_speed(&gait);
    }
    leg.ramp_belt(gait.ramp_s());
    if treadmill.contralateral == crate::ground::Contralateral::Reference {
        leg.add_other_leg(gait);
    }
    leg.rest_on_belt();
    Ok(leg)
}

/// The joint errors and velocities (deg, deg/s) of every period of `origin`'s simulation
/// without its spasms, over `settings`' duration (no stop flag: it is short).
fn baseline_trace(
    origin: &(LoadedScenario, ControllerConfig, Mount),
    settings: &LoopSettings,
) -> Result<Vec<[f64; 4]>, LegError> {
    let (loaded, config, mount) = origin;
    let mut calm = loaded.clone();
    calm.scenario.patient.hip.spasms = None;
    calm.scenario.patient.knee.spasms = None;
    let mut sim = LegSim::mounted(&calm, config, *mount)?;
    let plain = LoopSettings::new(settings.duration_s())?;
    let periods = plain.periods(sim.scenario.period_s)?;
    let mut trace = crate::safety::BaselineTrace(Vec::with_capacity(periods as usize + 1));
    // A baseline the supervisor stops still covers its periods up to the fault.
    let _ = sim.run_until_fault(&plain, &mut trace)?;
    Ok(trace.0)
}

/// Why the supervisor stopped a leg run (it vented every muscle).
#[derive(Debug, Clone, PartialEq)]
pub struct LegFault {
    /// Short name (`sensor-nan`, `position-out`).
    pub name: &'static str,
    /// Time of the last period that completed (s).
    pub t_s: f64,
    /// What happened, on one line.
    pub message: String,
}

/// What the leg's supervisor enforces: every muscle's pressure within its valve's range
/// and the scenario's rate limit, each encoder finite and inside its joint's limits (with
/// [`LIMIT_OVERSHOOT_MAX_RAD`] to spare: rapier holds a limit to milliradians).
fn supervisor_limits(sc: &Scenario, joint_limits_rad: [[f64; 2]; 2]) -> SupervisorLimits {
    let window = |k: usize| {
        let [lo, hi] = joint_limits_rad[k];
        ReadingWindow {
            name: ["hip angle", "knee angle"][k],
            unit: "rad",
            min: lo - LIMIT_OVERSHOOT_MAX_RAD,
            max: hi + LIMIT_OVERSHOOT_MAX_RAD,
        }
    };
    SupervisorLimits {
        pressure_max_pa: sc.plant.valve.pressure_max_pa,
        pressure_rate_max_pa_per_s: sc.control.pressure_rate_max_pa_per_s,
        windows: vec![window(0), window(1)],
        sensor_stuck_periods: 0,
        watchdog_periods: 0,
        overrun_max_consecutive_periods: u32::MAX,
        overrun_max_share: 1.0,
    }
}

fn build_muscles(
    sc: &Scenario,
    geometry: &[MuscleGeometry],
) -> Result<Vec<MuscleActuator>, LegError> {
    if geometry.len() != 4 {
        return Err(invalid(
            "number of muscles",
            geometry.len() as f64,
            "must be 4: a flexor and an extensor on hip and knee",
        ));
    }
    let links: [(&str, [&str; 2]); 2] =
        [("hip", ["pelvis", "thigh"]), ("knee", ["thigh", "shank"])];
    let mut out = Vec::with_capacity(4);
    for g in geometry {
        let err = |message: String| LegError::Muscle {
            muscle: g.name.clone(),
            message,
        };
        let joint = JOINT_NAMES
            .iter()
            .position(|n| *n == g.joint)
            .ok_or_else(|| {
                err(format!(
                    "unknown joint `{}` (the leg has hip and knee)",
                    g.joint
                ))
            })?;
        if !links[joint].1.contains(&g.body_link.as_str()) {
            return Err(err(format!(
                "unknown link `{}` for joint `{}` (expected `{}` or `{}`)",
                g.body_link, g.joint, links[joint].1[0], links[joint].1[1]
            )));
        }
        let scale = sc.plant.muscle_scale.get(&g.name).copied();
        let (model, rated_force_n) = match (g.festo()?, scale) {
            (Some(festo), None) => (MuscleModel::Festo(festo), festo.size.rated_force_n()),
            (Some(_), Some(_)) => return Err(err(
                "is a Festo muscle (`size`): plant.muscle_scale applies to Table I muscles only"
                    .into(),
            )),
            (None, scale) => {
                let params = scale.unwrap_or_default().apply(MuscleParams::TABLE_I);
                params.validate()?;
                (
                    MuscleModel::ThreeElement(params),
                    sc.plant.muscle_rated_force_n,
                )
            }
        };
        out.push(MuscleActuator {
            geometry: g.clone(),
            joint,
            model,
            rated_force_n,
            valve: Valve::new(sc.plant.valve, 0.0)?,
        });
    }
    for name in sc.plant.muscle_scale.keys() {
        if !geometry.iter().any(|g| &g.name == name) {
            return Err(LegError::Muscle {
                muscle: name.clone(),
                message: "plant.muscle_scale names a muscle the geometry does not have".into(),
            });
        }
    }
    for (j, joint_name) in JOINT_NAMES.iter().enumerate() {
        let sides: Vec<_> = out
            .iter()
            .filter(|m| m.joint == j)
            .map(|m| m.geometry.side)
            .collect();
        if sides.len() != 2 || sides[0] == sides[1] {
            return Err(invalid(
                format!("muscles on {joint_name}"),
                sides.len() as f64,
                "each joint needs exactly one flexor and one extensor",
            ));
        }
    }
    Ok(out)
}
