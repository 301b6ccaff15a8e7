//! The closed-loop gait simulation: the exoskeleton plant, every leg's controllers and its
//! metrics, run through the one loop of `pma-loop`.
use crate::config::{LoadedScenario, MuscleGeometry, Scenario};
use crate::control::{LegControllers, LegOutput, TrainerControllers};
use crate::error::{invalid, LegError};
use crate::exoskeleton::{Exoskeleton, Mount, JOINT_NAMES};
use crate::gait::GaitReference;
use crate::ground::{Contralateral, FootReaction};
use crate::impedance::{Compensation, ControlMode};
use crate::legs::{PerLeg, SIDES};
use crate::metrics::{LegMetrics, LegReport, OnLeg};
use crate::patient::{Patient, PatientTorques, SpasmEvent};
use crate::plant::{
    LegPlant, LegState, MuscleActuator, SupervisedLeg, TrainerState, LIMIT_OVERSHOOT_MAX_RAD,
    MUSCLES_PER_LEG,
};
use crate::safety::PatientMetrics;
use crate::stance::{FootMetrics, TrainerGroundMetrics};
use pma_control::supervisor::{ReadingWindow, Supervised, SupervisorLimits};
use pma_control::{ControllerConfig, Diagnostics};
use pma_loop::{LoopSettings, Period, Recorder, Schema, Signals};
use pma_model::{DampingMode, MuscleModel, MuscleParams, Valve};

/// What one leg's foot did in one period, on a treadmill.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FootSample {
    /// The belt's reaction on the foot.
    pub reaction: FootReaction,
    /// Whether the reference's foot is in stance.
    pub reference_stance: bool,
    /// The passive ankle's angle (rad, dorsiflexion positive; NaN for a fixed ankle).
    pub ankle_rad: f64,
    /// The orthosis's torque on the ankle (N m, dorsiflexion positive).
    pub ankle_torque_nm: f64,
}

/// One leg's channels of one period: its state at the reading and what its controllers
/// made of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegSample {
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
    /// The torque the device puts into the limb (N m, flexion positive).
    pub interaction_nm: [f64; 2],
    /// The thigh and shank cuff forces that put it there (N, forward positive).
    pub cuff_force_n: [f64; 2],
    /// Its foot on the belt, on a treadmill.
    pub foot: Option<FootSample>,
}

/// What the harness, a virtual other leg and the pelvis did in one period, on a treadmill.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroundSample {
    /// The virtual other leg's force on the pelvis (N; 0 without one).
    pub other_leg_n: f64,
    /// The harness's upward force (N).
    pub support_n: f64,
    /// The harness's fore-aft force on the pelvis (N, forward positive).
    pub harness_fore_aft_n: f64,
    /// The pelvis frame `[fore-aft, height above the belt]` (m).
    pub pelvis_m: [f64; 2],
}

/// One period of the exoskeleton as logs show it: every leg's channels, and on a
/// treadmill the harness's and the pelvis's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainerSample {
    /// Time (s).
    pub t_s: f64,
    /// Each leg's channels.
    pub legs: PerLeg<LegSample>,
    /// The harness and the pelvis, on a treadmill.
    pub ground: Option<GroundSample>,
}

impl LegSample {
    /// Leg `leg`'s view of one loop period.
    fn of(state: &TrainerState, leg: usize, output: &LegOutput, written: &[f64; 4]) -> Self {
        let s: &LegState = &state.legs[leg];
        Self {
            reference_rad: output.reference_rad,
            angle_rad: s.angle_rad,
            reference_velocity_rad_s: output.reference_velocity_rad_s,
            velocity_rad_s: s.velocity_rad_s,
            pressure_cmd_pa: *written,
            pressure_pa: s.pressure_pa,
            length_ref_m: output.length_ref_m,
            length_m: s.length_m,
            force_n: s.force_n,
            diagnostics: output.diagnostics,
            patient_nm: s.patient.total(),
            patient_parts_nm: s.patient,
            interaction_nm: s.interaction_nm,
            cuff_force_n: s.cuff_force_n,
            foot: state.ground.and_then(|g| {
                Some(FootSample {
                    reaction: *g.feet.get(leg)?,
                    reference_stance: output.reference_in_stance,
                    ankle_rad: s.ankle_rad,
                    ankle_torque_nm: s.ankle_torque_nm,
                })
            }),
        }
    }

    /// One leg's channels (after the time) for muscles named `muscles`, its foot's on a
    /// treadmill, as the CSV and Rerun show them.
    pub fn schema(muscles: &[String], treadmill: bool) -> Schema {
        let mut s = Schema::new();
        for j in JOINT_NAMES {
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
                )
                .push_part(
                    "joints",
                    j,
                    "interaction_torque_nm",
                    "device's torque on the limb (N m, flexion +)",
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
        for cuff in ["thigh_cuff", "shank_cuff"] {
            s.push_part(
                "cuffs",
                cuff,
                "force_n",
                "force on the limb (N, perpendicular to the segment, forward +)",
            );
        }
        if treadmill {
            s.channels.extend(Self::foot_schema().channels);
        }
        s
    }

    /// The foot's and the passive ankle's channels of a leg on a treadmill (after the
    /// joints' and the muscles' in [`Self::schema`]).
    pub fn foot_schema() -> Schema {
        let mut s = Schema::new();
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
            "joints",
            "ankle",
            "angle_deg",
            "angle (deg, dorsiflexion +; passive)",
        )
        .push_part(
            "joints",
            "ankle",
            "orthosis_torque_nm",
            "orthosis torque (N m, dorsiflexion +)",
        );
        s
    }

    /// Writes the leg's values in the order of [`Self::schema`].
    fn put(&self, put: &mut impl FnMut(f64)) {
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
                self.interaction_nm[j],
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
        for f in self.cuff_force_n {
            put(f);
        }
        if let Some(f) = self.foot {
            let g = f.reaction;
            let stance = g.vertical_n > crate::stance::CONTACT_THRESHOLD_N;
            for v in [
                g.vertical_n,
                g.fore_aft_n,
                f64::from(u8::from(stance)),
                f64::from(u8::from(f.reference_stance)),
                g.slip_m_s,
                g.penetration_m,
                f.ankle_rad.to_degrees(),
                f.ankle_torque_nm,
            ] {
                put(v);
            }
        }
    }
}

impl TrainerSample {
    /// The exoskeleton's view of one loop period.
    pub fn of(p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) -> Self {
        let s = p.truth;
        Self {
            t_s: p.t_s,
            legs: PerLeg::from_fn(s.legs.len(), |leg| {
                LegSample::of(s, leg, &p.output[leg], &p.written[leg])
            }),
            ground: s.ground.map(|g| GroundSample {
                other_leg_n: g.contralateral_n,
                support_n: g.support_n,
                harness_fore_aft_n: g.harness_fore_aft_n,
                pelvis_m: s.pelvis_m.unwrap_or([f64::NAN; 2]),
            }),
        }
    }

    /// The treadmill's channels of the pelvis and what holds it.
    pub fn ground_schema() -> Schema {
        let mut s = Schema::new();
        s.push_part(
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
        .push_part(
            "ground",
            "harness",
            "fore_aft_n",
            "fore-aft force on the pelvis (N, forward +)",
        )
        .push_part(
            "ground",
            "pelvis",
            "x_m",
            "fore-aft position (m, forward +)",
        )
        .push_part("ground", "pelvis", "height_m", "height above the belt (m)");
        s
    }

    /// The channels (after the time) of a trainer of `legs` legs whose muscles (one leg's)
    /// are named `muscles`, on a treadmill or not, as the CSV and Rerun show them: each
    /// leg's (prefixed by its side when there are two), then the pelvis's.
    pub fn schema(muscles: &[String], legs: usize, treadmill: bool) -> Schema {
        let leg = LegSample::schema(muscles, treadmill);
        let mut s = Schema::new();
        for side in SIDES.iter().take(legs) {
            let part = if legs > 1 {
                leg.prefixed(side)
            } else {
                leg.clone()
            };
            s.channels.extend(part.channels);
        }
        if treadmill {
            s.channels.extend(Self::ground_schema().channels);
        }
        s
    }
}

impl Signals for TrainerSample {
    fn values(&self, out: &mut [f64]) {
        let mut k = 0;
        let mut put = |v: f64| {
            out[k] = v;
            k += 1;
        };
        for leg in &self.legs {
            leg.put(&mut put);
        }
        if let Some(g) = self.ground {
            for v in [
                g.other_leg_n,
                g.support_n,
                g.harness_fore_aft_n,
                g.pelvis_m[0],
                g.pelvis_m[1],
            ] {
                put(v);
            }
        }
    }
}

/// The exoskeleton with its muscles, controllers, references and metrics.
pub struct LegSim {
    scenario: Scenario,
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
    /// every muscle, the legs standing still at rest.
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
        let sync = phase_sync(&sc)?;
        let exo = build_exo(loaded, mount)?;
        let legs = exo.leg_count();
        let patients = build_patients(&sc, &exo)?;
        let muscles = build_muscles(&sc, &loaded.muscles, legs)
            .map_err(|e| e.in_file(&loaded.muscles_source))?;
        let mut per_leg = Vec::with_capacity(legs);
        for leg in 0..legs {
            let own = &muscles[leg * MUSCLES_PER_LEG..(leg + 1) * MUSCLES_PER_LEG];
            let mut controllers =
                LegControllers::new(&sc, own, exo.inertia(), config, leg, exo.limits_rad(leg))?;
            if let Some(load) = stance_load(&sc, &exo)? {
                controllers.set_stance_load(load);
            }
            if let Some(expected) = expected_moments(&sc, leg)? {
                controllers.set_expected_moments(expected);
            }
            per_leg.push(controllers);
        }
        let limits = supervisor_limits(&sc, &exo);
        let mut plant = LegPlant::new(exo, muscles, &sc)?;
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
            Reading = PerLeg<crate::LegReading>,
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
            .map(|leg| OnLeg::new(leg, LegMetrics::new(sc.gait.stride_period_s, sc.period_s)))
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
            crate::ControlMode::Path => sc.control.path.width_deg,
            _ => crate::cooperative::TUNNEL_WIDTH_DEG,
        };
        let mut cooperation: Vec<OnLeg<crate::cooperative::CooperationMetrics>> = (0..legs)
            .map(|leg| {
                OnLeg::new(
                    leg,
                    crate::cooperative::CooperationMetrics::new(
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
        let (interrupted, fault) = match outcome.end {
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
        let ran_s = outcome.ran_s;
        let names: Vec<String> = (0..legs)
            .map(|leg| {
                self.plant
                    .leg_muscles(leg)
                    .iter()
                    .map(|m| m.geometry.name.clone())
                    .collect()
            })
            .collect::<Vec<Vec<String>>>()
            .concat();
        let mut report = LegReport::of_legs(
            &sc.name,
            ran_s,
            outcome.wall_s,
            &names[..MUSCLES_PER_LEG.min(names.len())],
            metrics.iter().map(|m| &m.inner),
            patients.iter().map(|p| (&p.inner, t0 + ran_s)),
        );
        report.interrupted = interrupted;
        report.treadmill = ground.report(feet.iter().map(|f| f.inner.report()).collect());
        report.cooperation = cooperation.iter().map(|c| c.inner.report()).collect();
        report.phase_sync = self.controllers.phase_sync().map(|s| s.report());
        let planned_s = if interrupted {
            ran_s
        } else {
            settings.duration_s()
        };
        report.walking = crate::verdict::judge(
            &report,
            planned_s,
            sc.gait.stride_period_s,
            fault.as_ref(),
            crate::verdict::WalkingCriteria::default(),
        );
        Ok((report, fault))
    }
}

/// The weight a stance leg carries on `exo`'s treadmill, when the scenario's impedance
/// settings hold it (`None` in the air or with `stance_load = false`).
fn stance_load(
    sc: &Scenario,
    exo: &Exoskeleton,
) -> Result<Option<crate::impedance::StanceLoad>, LegError> {
    let Some(ground) = exo.ground().filter(|_| sc.control.impedance.stance_load) else {
        return Ok(None);
    };
    let toe_off = sc.gait.reference()?.toe_off_phase();
    Ok(Some(crate::impedance::StanceLoad::new(
        ground.chain().clone(),
        ground.total_mass_kg(),
        *ground.settings(),
        toe_off,
    )))
}

/// Each leg's patient (empty: the passive limb). The second leg's spasms are drawn from
/// the scenario's seeds plus one, so the legs do not jerk together.
pub(crate) fn build_patients(sc: &Scenario, exo: &Exoskeleton) -> Result<Vec<Patient>, LegError> {
    if sc.patient.is_passive() {
        return Ok(Vec::new());
    }
    let gait = sc.gait.reference()?;
    let damping = [
        sc.joints.hip.damping_nm_s_per_rad,
        sc.joints.knee.damping_nm_s_per_rad,
    ];
    let walking = walking_moments(sc, &gait)?;
    (0..exo.leg_count())
        .map(|leg| {
            let settings = sc.patient.for_leg(leg);
            let mut p = Patient::new(
                &settings,
                exo.substep_s(),
                gait.for_leg(leg),
                *exo.inertia(),
                damping,
            )?;
            if let Some(m) = &walking {
                p.walk_with_moments(m.clone(), sc.treadmill);
            }
            Ok(p)
        })
        .collect()
}

/// The joint moments an active patient who walks on the belt produces
/// ([`crate::patient::OwnTorque::Walking`]): the adults' mean moments at the reference's
/// speed, flexion positive, times the body mass and the share the legs carry; `None` for
/// a patient on their limb's inverse dynamics.
fn walking_moments(
    sc: &Scenario,
    gait: &crate::gait::GaitReference,
) -> Result<Option<[Vec<f64>; 2]>, LegError> {
    let Some(active) = &sc.patient.active else {
        return Ok(None);
    };
    if active.own_torque != crate::patient::OwnTorque::Walking {
        return Ok(None);
    }
    adult_moments(
        sc,
        gait,
        [
            "patient.active.own_torque = \"walking\" needs a treadmill (its body mass and support)",
            "patient.active.own_torque = \"walking\" produces the adult data's moments",
        ],
    )
    .map(Some)
}

/// The adults' mean walking moments at the reference's speed (N m, flexion positive, at
/// 0, 1, ..., 100 % of the cycle), times the body mass and the share of the weight the
/// legs carry under constant support, as `pma-exo size` scales the moments it compares
/// with; `hints` say what needs the treadmill and the adult data.
fn adult_moments(
    sc: &Scenario,
    gait: &crate::gait::GaitReference,
    hints: [&'static str; 2],
) -> Result<[Vec<f64>; 2], LegError> {
    // Walking's moments carry a stance, which needs a belt, a body and the adult data.
    let treadmill = sc.treadmill.as_ref().ok_or_else(|| LegError::Missing {
        name: "[treadmill]".into(),
        hint: hints[0],
    })?;
    let speed = gait.data_speed_m_s().ok_or_else(|| LegError::Missing {
        name: "gait.data = \"fukuchi2018\"".into(),
        hint: hints[1],
    })?;
    let norms = crate::gait::AdultNorms::at(speed)?;
    let scale = treadmill.body_mass_kg * (1.0 - treadmill.bws_fraction);
    Ok(norms
        .flexion_torques_nm_kg()
        .map(|c| c.iter().map(|t| t * scale).collect()))
}

/// Checks, for setting `field` to `value`, that the scenario's mode yields to the patient
/// (impedance or admittance) and, if `plans` (a share of a plan left to them), that it
/// plans the limb's torque (admittance carrying the leg, not only the device).
fn yielding_mode(sc: &Scenario, field: &str, value: f64, plans: bool) -> Result<(), LegError> {
    let unsupported = |message: &str| LegError::Unsupported {
        name: field.into(),
        value: format!("{value}"),
        message: message.into(),
    };
    match sc.control.mode {
        ControlMode::Impedance => Ok(()),
        ControlMode::Admittance if !plans || sc.control.compensation == Compensation::Leg => {
            Ok(())
        }
        ControlMode::Admittance => Err(unsupported(
            "with compensation = \"device\" admittance mode plans none of the limb's torque to leave to the patient",
        )),
        _ => Err(unsupported(
            "only impedance and admittance modes yield to the patient",
        )),
    }
}

/// The gait's clock following the legs' lead (`control.impedance.phase_sync_per_s`;
/// `None` at 0).
fn phase_sync(sc: &Scenario) -> Result<Option<crate::phase_sync::PhaseSync>, LegError> {
    let (gain, integral) = (
        sc.control.impedance.phase_sync_per_s,
        sc.control.impedance.phase_sync_integral_per_s2,
    );
    if gain == 0.0 && integral == 0.0 {
        return Ok(None);
    }
    let (field, value) = if gain != 0.0 {
        ("control.impedance.phase_sync_per_s", gain)
    } else {
        ("control.impedance.phase_sync_integral_per_s2", integral)
    };
    yielding_mode(sc, field, value, false)?;
    if sc
        .treadmill
        .is_some_and(|t| t.other_leg() == Contralateral::Reference)
    {
        return Err(LegError::Unsupported {
            name: field.into(),
            value: format!("{value}"),
            message: "the virtual other leg walks on the reference's own clock: give the trainer two legs".into(),
        });
    }
    let gait = sc.gait.reference()?;
    let stride = gait.stride_period_s();
    // The reference's Σ q̇² over one stride after the start-up, every leg alike.
    let n = 200;
    let start = (gait.ramp_s() / stride).ceil() * stride;
    let mean_power = (0..n)
        .map(|k| {
            let g = gait.sample(start + k as f64 / n as f64 * stride);
            g.hip.velocity_rad_s.powi(2) + g.knee.velocity_rad_s.powi(2)
        })
        .sum::<f64>()
        / n as f64
        * sc.treadmill.map_or(1, |t| t.legs) as f64;
    crate::phase_sync::PhaseSync::new(gain, integral, stride, mean_power).map(Some)
}

/// The moments impedance or admittance mode leaves to leg `leg`'s walking patient
/// (`control.impedance.patient_moment_share`, or its `_by_leg`; `None` at 0).
fn expected_moments(
    sc: &Scenario,
    leg: usize,
) -> Result<Option<crate::impedance::ExpectedMoments>, LegError> {
    let share = sc.control.impedance.patient_moment_share(leg);
    if share == 0.0 {
        return Ok(None);
    }
    yielding_mode(sc, "control.impedance.patient_moment_share", share, true)?;
    const NEEDS_TREADMILL: &str =
        "control.impedance.patient_moment_share > 0 needs a treadmill (its body mass and support)";
    let support = sc.treadmill.ok_or_else(|| LegError::Missing {
        name: "[treadmill]".into(),
        hint: NEEDS_TREADMILL,
    })?;
    let gait = sc.gait.reference()?;
    let moments = adult_moments(
        sc,
        &gait,
        [
            NEEDS_TREADMILL,
            "control.impedance.patient_moment_share > 0 leaves the adult data's moments to the patient",
        ],
    )?;
    Ok(Some(crate::impedance::ExpectedMoments::new(
        moments, share, support,
    )))
}

/// The scenario's exoskeleton: a fixed pelvis (as `mount` says), or its treadmill, the
/// belt at the reference's speed unless the scenario gives one, a one-leg trainer's
/// virtual other leg added and the legs standing at rest on the belt.
pub(crate) fn build_exo(loaded: &LoadedScenario, mount: Mount) -> Result<Exoskeleton, LegError> {
    let sc = &loaded.scenario;
    let joints = [sc.joints.hip, sc.joints.knee];
    let Some(treadmill) = &sc.treadmill else {
        let mut exo = Exoskeleton::mounted(
            &loaded.urdf_text,
            &loaded.urdf_source,
            joints,
            sc.period_s,
            sc.physics_substeps,
            mount,
        )?;
        exo.take_start_pose(&sc.gait.reference()?);
        return Ok(exo);
    };
    if mount != Mount::default() {
        return Err(LegError::Parse {
            file: sc.name.clone(),
            message: "a treadmill scenario's leg stands on its belt: it cannot be mounted on a seat (pendulum test)".into(),
        });
    }
    let gait = sc.gait.reference()?;
    let mut exo = Exoskeleton::on_treadmill(
        &loaded.urdf_text,
        &loaded.urdf_source,
        joints,
        sc.period_s,
        sc.physics_substeps,
        treadmill,
    )?;
    if treadmill.speed_m_per_s.is_none() {
        exo.belt_at_reference_speed(&gait);
    }
    exo.ramp_belt(gait.ramp_s());
    if treadmill.other_leg() == Contralateral::Reference {
        exo.add_other_leg(gait);
    }
    exo.take_start_pose(&gait);
    exo.rest_on_belt();
    Ok(exo)
}

/// Each leg's joint errors and velocities (deg, deg/s) of every period of `origin`'s
/// simulation without its spasms, over `settings`' duration (no stop flag: it is short).
fn baseline_traces(
    origin: &(LoadedScenario, ControllerConfig, Mount),
    settings: &LoopSettings,
) -> Result<Vec<Vec<[f64; 4]>>, LegError> {
    let (loaded, config, mount) = origin;
    let mut calm = loaded.clone();
    calm.scenario.patient.hip.spasms = None;
    calm.scenario.patient.knee.spasms = None;
    let mut sim = LegSim::mounted(&calm, config, *mount)?;
    let plain = LoopSettings::new(settings.duration_s())?;
    let periods = plain.periods(sim.scenario.period_s)?;
    let mut traces: Vec<OnLeg<crate::safety::BaselineTrace>> = (0..sim.leg_count())
        .map(|leg| {
            OnLeg::new(
                leg,
                crate::safety::BaselineTrace(Vec::with_capacity(periods as usize + 1)),
            )
        })
        .collect();
    // A baseline the supervisor stops still covers its periods up to the fault.
    let _ = sim.run_until_fault(&plain, &mut traces)?;
    Ok(traces.into_iter().map(|t| t.inner.0).collect())
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

/// Full scale of a cuff torque sensor (N m): where admittance mode reads the cuffs, a
/// reading beyond it is a fault. Twice the largest interaction peak any shipped scenario
/// has shown (443 N m at the hip, the transparent leg swinging into a spasm's end of
/// range, docs/cooperative.md), so that only a broken or saturated reading trips it.
pub const CUFF_TORQUE_FULL_SCALE_NM: f64 = 1000.0;

/// What the supervisor enforces: every muscle's pressure within its valve's range and the
/// scenario's rate limit, each encoder finite and inside its joint's limits (with
/// [`LIMIT_OVERSHOOT_MAX_RAD`] to spare: rapier holds a limit to milliradians), each cuff
/// torque not NaN and, in admittance mode, the one mode whose loop reads it, within
/// [`CUFF_TORQUE_FULL_SCALE_NM`]; leg after leg. (The other modes do not stop a run on a
/// sensor they do not read: the reading is the frames' model's, meaningless on a URDF
/// whose links are lighter than the frames.)
fn supervisor_limits(sc: &Scenario, exo: &Exoskeleton) -> SupervisorLimits {
    const NAMES: [[&str; 8]; 2] = [
        [
            "hip angle",
            "knee angle",
            "hip cuff torque",
            "knee cuff torque",
            "muscle 1 pressure",
            "muscle 2 pressure",
            "muscle 3 pressure",
            "muscle 4 pressure",
        ],
        [
            "left hip angle",
            "left knee angle",
            "left hip cuff torque",
            "left knee cuff torque",
            "left muscle 1 pressure",
            "left muscle 2 pressure",
            "left muscle 3 pressure",
            "left muscle 4 pressure",
        ],
    ];
    let mut windows = Vec::with_capacity(8 * exo.leg_count());
    for leg in 0..exo.leg_count() {
        let limits = exo.limits_rad(leg);
        let names = NAMES[leg.min(1)];
        for k in 0..2 {
            let [lo, hi] = limits[k];
            windows.push(ReadingWindow {
                name: names[k],
                unit: "rad",
                min: lo - LIMIT_OVERSHOOT_MAX_RAD,
                max: hi + LIMIT_OVERSHOOT_MAX_RAD,
            });
        }
        let full_scale = if sc.control.mode == crate::ControlMode::Admittance {
            CUFF_TORQUE_FULL_SCALE_NM
        } else {
            f64::INFINITY
        };
        for name in &names[2..4] {
            windows.push(ReadingWindow {
                name,
                unit: "N m",
                min: -full_scale,
                max: full_scale,
            });
        }
        // A pressure sensor reads from vacuum to the valve's limit and 10 % beyond (a
        // reading above it: a valve stuck open or a wrong supply, as on the rig).
        for name in &names[4..] {
            windows.push(ReadingWindow {
                name,
                unit: "Pa",
                min: -pma_model::pneumatics::ATMOSPHERE_PA,
                max: 1.1 * sc.plant.valve.pressure_max_pa,
            });
        }
    }
    SupervisorLimits {
        pressure_max_pa: sc.plant.valve.pressure_max_pa,
        pressure_rate_max_pa_per_s: sc.control.pressure_rate_max_pa_per_s,
        windows,
        sensor_stuck_periods: 0,
        watchdog_periods: 0,
        overrun_max_consecutive_periods: u32::MAX,
        overrun_max_share: 1.0,
    }
}

/// Each leg's four muscles from the geometry (one leg's), leg after leg.
fn build_muscles(
    sc: &Scenario,
    geometry: &[MuscleGeometry],
    legs: usize,
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
    let flow_valve = sc.plant.flow_valve()?;
    for (index, g) in geometry.iter().enumerate() {
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
        let (model, (rated_force_n, rating)) = match (g.festo()?, scale) {
            (Some(festo), None) => (
                MuscleModel::Festo(festo),
                (
                    festo.size.rated_force_n(),
                    format!("Festo {}", festo.size.name().to_uppercase()),
                ),
            ),
            (Some(_), Some(_)) => return Err(err(
                "is a Festo muscle (`size`): plant.muscle_scale applies to Table I muscles only"
                    .into(),
            )),
            (None, scale) => {
                let params = scale.unwrap_or_default().apply(MuscleParams::TABLE_I);
                params.validate()?;
                (
                    MuscleModel::ThreeElement(params),
                    sc.plant.three_element_rating(),
                )
            }
        };
        out.push(MuscleActuator {
            geometry: g.clone(),
            leg: 0,
            index,
            joint,
            model,
            rated_force_n,
            rating,
            valve: Valve::new(sc.plant.valve_of(flow_valve.as_ref(), &model), 0.0)?,
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
    let one = out;
    let mut all = Vec::with_capacity(legs * one.len());
    for leg in 0..legs {
        all.extend(one.iter().cloned().map(|m| MuscleActuator { leg, ..m }));
    }
    Ok(all)
}
