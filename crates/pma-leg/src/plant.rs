//! The leg as a [`Backend`] of the closed loop: rapier multibody, four muscles with their
//! valves, two joint encoders.
use crate::config::{MuscleGeometry, Scenario};
use crate::error::LegError;
use crate::ground::GroundReaction;
use crate::leg::{Leg, JOINT_NAMES};
use crate::patient::{Patient, PatientTorques};
use pma_loop::{Backend, Started};
use pma_model::{MuscleModel, PositionSensor, Valve};

/// A muscle on the leg: geometry, the true three-element model and its valve.
#[derive(Debug, Clone)]
pub struct MuscleActuator {
    /// Geometry.
    pub geometry: MuscleGeometry,
    /// Joint index (0 hip, 1 knee).
    pub joint: usize,
    /// True muscle: eq. (1), or a Festo size as measured.
    pub model: MuscleModel,
    /// Rated pulling force (N): the Festo size's, or the scenario's
    /// `plant.muscle_rated_force_n` for an eq. (1) muscle.
    pub rated_force_n: f64,
    pub(crate) valve: Valve,
}

impl MuscleActuator {
    /// The eq. (1) muscle its controller assumes: Table I for an eq. (1) muscle (its
    /// deviations from Table I are the plant's, unknown to the controller), the map's fit
    /// for a Festo muscle (its size is known).
    pub fn assumed(&self) -> pma_model::MuscleParams {
        match self.model {
            MuscleModel::ThreeElement(_) => pma_model::MuscleParams::TABLE_I,
            MuscleModel::Festo(f) => f.three_element_fit(),
        }
    }

    /// Contraction (m) at joint angles `q`.
    pub fn contraction(&self, q: [f64; 2]) -> f64 {
        self.geometry.contraction(q[self.joint])
    }

    /// Contraction rate (m/s).
    pub fn contraction_rate(&self, qd: [f64; 2]) -> f64 {
        self.geometry.moment_arm_m() * qd[self.joint]
    }

    /// Eq. (1) force without the slack clamp (N): negative means slack.
    pub fn force_unclamped(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.model.force_unclamped(
            self.valve.pressure(),
            self.contraction(q),
            self.contraction_rate(qd),
            self.valve.mode(),
        )
    }

    /// Pulling force (N).
    pub fn force(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.force_unclamped(q, qd).max(0.0)
    }

    /// Joint torque (N m, flexion positive).
    pub fn torque(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.geometry.moment_arm_m() * self.force(q, qd)
    }

    /// Muscle pressure (Pa).
    pub fn pressure(&self) -> f64 {
        self.valve.pressure()
    }

    /// The valve's last set point (Pa).
    pub fn set_point(&self) -> f64 {
        self.valve.set_point()
    }
}

/// The leg as the loop drives it: the plant behind the safety supervisor of the rig
/// (pressure clamp and rate limit on all four muscles, NaN and joint windows on the
/// encoders); a fault vents all four.
pub type SupervisedLeg = pma_control::Supervised<LegPlant>;

/// The leg's true state at a reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegState {
    /// Joint angles (rad), hip and knee.
    pub angle_rad: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// Muscle pressures (Pa), muscle order of the geometry file.
    pub pressure_pa: [f64; 4],
    /// Muscle forces (N).
    pub force_n: [f64; 4],
    /// Muscle contractions (m).
    pub length_m: [f64; 4],
    /// Time each muscle spent slack during the last period (s).
    pub slack_s: [f64; 4],
    /// The patient's torques at the last substep (N m, flexion positive).
    pub patient: PatientTorques,
    /// What the belt did to the foot over the last period, on a treadmill.
    pub ground: Option<GroundReaction>,
    /// Height of the pelvis frame above the belt (m), on a treadmill.
    pub pelvis_height_m: Option<f64>,
}

/// The leg in the closed loop: reads two encoder angles, takes four pressure commands.
pub struct LegPlant {
    leg: Leg,
    muscles: Vec<MuscleActuator>,
    encoders: [PositionSensor; 2],
    period_s: f64,
    periods: u64,
    slack_s: [f64; 4],
    patient: Option<Patient>,
    muscles_attached: bool,
}

impl LegPlant {
    pub(crate) fn new(
        leg: Leg,
        muscles: Vec<MuscleActuator>,
        scenario: &Scenario,
    ) -> Result<Self, LegError> {
        Ok(Self {
            leg,
            muscles,
            encoders: [
                PositionSensor::new(scenario.plant.encoder.sensor(0))?,
                PositionSensor::new(scenario.plant.encoder.sensor(1))?,
            ],
            period_s: scenario.period_s,
            periods: 0,
            slack_s: [0.0; 4],
            patient: None,
            muscles_attached: true,
        })
    }

    /// Puts a patient in the leg (`None`: the passive limb).
    pub fn set_patient(&mut self, patient: Option<Patient>) {
        self.patient = patient;
    }

    /// The patient, if any.
    pub fn patient(&self) -> Option<&Patient> {
        self.patient.as_ref()
    }

    /// The patient, to plan or change it.
    pub fn patient_mut(&mut self) -> Option<&mut Patient> {
        self.patient.as_mut()
    }

    /// Unhooks the muscles' cables (`false`): they pull on nothing, as for a test of the
    /// limb alone whose range the cables and the muscles' stroke would not allow.
    pub fn attach_muscles(&mut self, attached: bool) {
        self.muscles_attached = attached;
    }

    /// Mutable leg (mounting, holding a joint).
    pub fn leg_mut(&mut self) -> &mut Leg {
        &mut self.leg
    }

    /// The leg (poses, angles, energy).
    pub fn leg(&self) -> &Leg {
        &self.leg
    }

    /// The muscles, in the geometry file's order.
    pub fn muscles(&self) -> &[MuscleActuator] {
        &self.muscles
    }

    /// Time (s): whole periods since the plant was built.
    pub fn time(&self) -> f64 {
        self.periods as f64 * self.period_s
    }

    /// Puts the leg at `angles` with `velocities` (the valves keep their pressure).
    pub fn set_state(&mut self, angles: [f64; 2], velocities: [f64; 2]) {
        self.leg.set_state(angles, velocities);
    }

    /// Sets every valve to `pressures_pa` at once (a resting state).
    pub fn set_pressures(&mut self, pressures_pa: [f64; 4]) -> Result<(), LegError> {
        for (m, p) in self.muscles.iter_mut().zip(pressures_pa) {
            m.valve = Valve::new(*m.valve.params(), p)?;
        }
        Ok(())
    }

    /// One period with the valves commanded directly (open-loop checks).
    pub fn apply(&mut self, commands_pa: [f64; 4]) -> LegState {
        self.command(&commands_pa);
        self.advance();
        self.state()
    }

    fn command(&mut self, commands_pa: &[f64; 4]) -> [f64; 4] {
        for (m, u) in self.muscles.iter_mut().zip(commands_pa) {
            m.valve.command(*u);
        }
        std::array::from_fn(|i| match self.muscles.get(i) {
            Some(m) => m.valve.params().clamp(commands_pa[i]),
            None => f64::NAN,
        })
    }

    /// Physics over one period with the valves as commanded: every substep the valves
    /// advance and the muscles' torques go into rapier.
    fn advance(&mut self) {
        let muscles = &mut self.muscles;
        let patient = &mut self.patient;
        let attached = self.muscles_attached;
        let h = self.period_s / f64::from(self.leg.substeps());
        let t0 = self.periods as f64 * self.period_s;
        let mut slack = [0.0; 4];
        self.leg.step(|leg, sub| {
            let (q, qd) = (leg.angles(), leg.velocities());
            let mut tau = match patient {
                Some(p) => p.torques(t0 + sub as f64 * h, q, qd).total(),
                None => [0.0; 2],
            };
            for (i, m) in muscles.iter_mut().enumerate() {
                m.valve.advance(h);
                if m.force_unclamped(q, qd) <= 0.0 {
                    slack[i] += h;
                }
                if attached {
                    tau[m.joint] += m.torque(q, qd);
                }
            }
            tau
        });
        self.slack_s = slack;
        self.periods += 1;
    }

    fn encoder_angles(&mut self) -> [f64; 2] {
        let q = self.leg.angles();
        [
            self.encoders[0].measure(q[0]),
            self.encoders[1].measure(q[1]),
        ]
    }

    /// The true state now.
    pub fn state(&self) -> LegState {
        let (q, qd) = (self.leg.angles(), self.leg.velocities());
        let m = &self.muscles;
        let each = |f: &dyn Fn(&MuscleActuator) -> f64| -> [f64; 4] {
            std::array::from_fn(|i| m.get(i).map_or(f64::NAN, f))
        };
        LegState {
            angle_rad: q,
            velocity_rad_s: qd,
            pressure_pa: each(&|m| m.pressure()),
            force_n: each(&|m| m.force(q, qd)),
            length_m: each(&|m| m.contraction(q)),
            slack_s: self.slack_s,
            patient: self
                .patient
                .as_ref()
                .map_or_else(PatientTorques::default, Patient::last),
            ground: self.leg.ground_reaction(),
            pelvis_height_m: self.leg.pelvis_height_m(),
        }
    }

    /// Each muscle as a segment from its anchor to its joint's pulley, in world
    /// coordinates (m), for drawing.
    pub fn muscle_segments(&self) -> [([f64; 3], [f64; 3]); 4] {
        std::array::from_fn(|i| {
            let Some(m) = self.muscles.get(i) else {
                return ([f64::NAN; 3], [f64::NAN; 3]);
            };
            let g = &m.geometry;
            let anchor = self.leg.point_in_world(&g.body_link, g.anchor_m);
            // The pulley sits on the joint axis: the origin of the joint's child link.
            let child = if m.joint == 0 { "thigh" } else { "shank" };
            let pulley = self.leg.point_in_world(child, [0.0, g.anchor_m[1], 0.0]);
            (
                anchor.unwrap_or([f64::NAN; 3]),
                pulley.unwrap_or([f64::NAN; 3]),
            )
        })
    }

    /// Names of the joints, in reading order.
    pub fn joint_names(&self) -> [&'static str; 2] {
        JOINT_NAMES
    }
}

/// A joint this far beyond its URDF limit (rad) has left the physics: rapier holds its
/// limits to a few milliradians, so only a diverging simulation gets there.
pub const LIMIT_OVERSHOOT_MAX_RAD: f64 = 0.5;
/// Fastest joint speed of a physical run (rad/s): about 2900 deg/s, five times the fastest
/// knee swing of sprinting.
pub const JOINT_SPEED_MAX_RAD_S: f64 = 50.0;

impl LegPlant {
    /// Ends a run whose state left physical bounds: non-finite, a joint far beyond its
    /// limit or faster than any limb moves. Its figures would be garbage.
    fn check_physics(&self) -> Result<(), LegError> {
        let (q, qd) = (self.leg.angles(), self.leg.velocities());
        let limits = self.leg.limits_rad();
        for (k, name) in JOINT_NAMES.iter().enumerate() {
            let [lo, hi] = limits[k];
            let beyond = (lo - q[k]).max(q[k] - hi);
            let diverged = if !(q[k].is_finite() && qd[k].is_finite()) {
                Some(format!(
                    "its state is not finite ({} rad, {} rad/s)",
                    q[k], qd[k]
                ))
            } else if beyond > LIMIT_OVERSHOOT_MAX_RAD {
                Some(format!(
                    "it is {beyond:.3} rad beyond its limits [{lo:.3}, {hi:.3}] rad (bound {LIMIT_OVERSHOOT_MAX_RAD} rad)"
                ))
            } else if qd[k].abs() > JOINT_SPEED_MAX_RAD_S {
                Some(format!(
                    "it turns at {:.1} rad/s (bound {JOINT_SPEED_MAX_RAD_S} rad/s)",
                    qd[k]
                ))
            } else {
                None
            };
            if let Some(why) = diverged {
                return Err(LegError::LeftPhysics {
                    t_s: self.time(),
                    what: format!("the {name}: {why}"),
                });
            }
        }
        self.check_ground()
    }

    /// On a treadmill: the pelvis finite and the foot no deeper in the belt than its
    /// spheres are wide (Hertz contact means nothing past that: the model has failed).
    fn check_ground(&self) -> Result<(), LegError> {
        let (Some(g), Some(r)) = (self.leg.ground(), self.leg.ground_reaction()) else {
            return Ok(());
        };
        let bound_m = g
            .spheres()
            .iter()
            .map(|s| 2.0 * s.radius_m)
            .fold(0.0, f64::max);
        let z = self.leg.pelvis_height_m().unwrap_or(f64::NAN);
        let what = if !(z.is_finite() && r.vertical_n.is_finite()) {
            Some(format!(
                "the pelvis or the ground reaction is not finite ({z} m, {} N)",
                r.vertical_n
            ))
        } else if r.penetration_m > bound_m {
            Some(format!(
                "the foot is {:.1} mm into the belt (bound {:.0} mm, its spheres' diameter)",
                r.penetration_m * 1e3,
                bound_m * 1e3
            ))
        } else {
            None
        };
        match what {
            Some(what) => Err(LegError::LeftPhysics {
                t_s: self.time(),
                what,
            }),
            None => Ok(()),
        }
    }
}

impl Backend for LegPlant {
    type Reading = [f64; 2];
    type Command = [f64; 4];
    type Truth = LegState;
    type Error = LegError;

    /// The leg as it is (built at rest); the valves hold their pressures, the patient's
    /// reflexes start from a limb at rest.
    fn start(&mut self) -> Result<Started<[f64; 2], [f64; 4]>, LegError> {
        if let Some(p) = &mut self.patient {
            p.reset();
        }
        let reading = self.encoder_angles();
        Ok(Started {
            t_s: self.time(),
            reading,
            command: self.state().pressure_pa,
        })
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn wait(&mut self) -> Result<u32, LegError> {
        self.advance();
        self.check_physics()?;
        Ok(1)
    }

    fn read(&mut self) -> Result<[f64; 2], LegError> {
        Ok(self.encoder_angles())
    }

    fn write(&mut self, commands_pa: &[f64; 4]) -> Result<[f64; 4], LegError> {
        Ok(self.command(commands_pa))
    }

    fn truth(&self) -> LegState {
        self.state()
    }

    /// Vents every muscle.
    fn stop(&mut self) {
        self.command(&[0.0; 4]);
    }
}
