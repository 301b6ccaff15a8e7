//! The exoskeleton as a [`Backend`] of the closed loop: the rapier multibody, four muscles
//! with their valves and two joint encoders per leg.
use crate::base::{LegError, PerLeg, JOINT_NAMES, MAX_LEGS, SIDES};
use crate::body::Exoskeleton;
use crate::ground::GroundReaction;
use crate::patient::{Patient, PatientTorques};
use crate::plant::{CuffSensorSettings, MuscleActuator, PlantSettings};
use pma_loop::{Backend, Started};
use pma_model::{GaussianRng, PositionSensor, Valve};

/// Muscles per leg: a flexor and an extensor at hip and knee.
pub const MUSCLES_PER_LEG: usize = 4;

/// `name` as outputs show it on a trainer of `legs` legs: as is with one leg, prefixed by
/// the side with two (`right/hip`).
pub fn leg_label(legs: usize, leg: usize, name: &str) -> String {
    if legs > 1 {
        format!("{}/{name}", SIDES[leg])
    } else {
        name.to_owned()
    }
}

/// The exoskeleton as the loop drives it: the plant behind the safety supervisor of the
/// rig (pressure clamp and rate limit on every muscle, NaN and joint windows on every
/// encoder); a fault vents all muscles.
pub type SupervisedLeg = pma_control::Supervised<LegPlant>;

/// What a leg's sensors read each period: its two joint encoders (rad, hip then knee,
/// flexion positive) and its two cuff torque sensors (N m, the torque the device puts
/// into the limb at hip and knee, flexion positive, [`LegState::interaction_nm`] as an
/// ideal sensor reads it). Position mode and the pressure-set modes read only the angles;
/// admittance mode also the cuffs. Then the four muscles' pressure sensors (Pa gauge, in
/// the geometry file's order), which the controllers' observers read where
/// `control.pressure_feedback` is on.
pub type LegReading = [f64; 8];

/// The muscles' pressures of a leg's reading (Pa, the geometry file's order).
pub fn reading_pressures_pa(r: &LegReading) -> [f64; 4] {
    [r[4], r[5], r[6], r[7]]
}

/// The joint angles of a leg's reading (rad).
pub fn reading_angles(r: &LegReading) -> [f64; 2] {
    [r[0], r[1]]
}

/// The cuff torques of a leg's reading (N m).
pub fn reading_cuff_nm(r: &LegReading) -> [f64; 2] {
    [r[2], r[3]]
}

/// One leg's true state at a reading.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
    /// The torque the device puts into the limb through the cuffs (N m, flexion positive):
    /// the muscles' torque less the frames' own inverse dynamics, the acceleration the
    /// mean over the last period (`crate::cooperative`).
    pub interaction_nm: [f64; 2],
    /// The thigh and shank cuff forces that put `interaction_nm` into the limb (N,
    /// perpendicular to their segments, forward positive; [`crate::plant::cuff_forces_n`]).
    pub cuff_force_n: [f64; 2],
    /// The passive ankle's angle (rad, dorsiflexion positive; NaN without one).
    pub ankle_rad: f64,
    /// The orthosis's torque on the ankle (N m, dorsiflexion positive).
    pub ankle_torque_nm: f64,
}

/// The exoskeleton's true state at a reading: each leg's, and on a treadmill what the
/// belt and the harness did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainerState {
    /// Each leg's state.
    pub legs: PerLeg<LegState>,
    /// What the belt did to the feet over the last period, on a treadmill.
    pub ground: Option<GroundReaction>,
    /// Position of the pelvis frame `[fore-aft, height above the belt]` (m), on a
    /// treadmill.
    pub pelvis_m: Option<[f64; 2]>,
}

/// The exoskeleton in the closed loop: reads two encoder angles per leg, takes four
/// pressure commands per leg.
pub struct LegPlant {
    exo: Exoskeleton,
    /// Every leg's muscles, leg after leg, each leg's in the geometry file's order.
    muscles: Vec<MuscleActuator>,
    encoders: Vec<[PositionSensor; 2]>,
    period_s: f64,
    periods: u64,
    slack_s: [[f64; 4]; MAX_LEGS],
    /// Each leg's patient (empty: the passive limb).
    patients: Vec<Patient>,
    muscles_attached: bool,
    /// A load on each leg's joints (N m, flexion positive): a perturbation test's weight.
    external_nm: [[f64; 2]; MAX_LEGS],
    /// Each leg's mean joint acceleration over the last period (rad/s^2).
    acceleration: [[f64; 2]; MAX_LEGS],
    /// A sinusoidal load on one joint, beside `external_nm`.
    external_wave: Option<ExternalWave>,
    cuff_sensor: CuffSensorSettings,
    /// Each leg's cuff sensors' noise streams (hip, knee).
    cuff_noise: Vec<[GaussianRng; 2]>,
    /// Where the cuffs hold the limb.
    cuffs: crate::plant::CuffSettings,
    /// The muscles' damping at the rates each physics step ends on (see `implicit_rates`).
    implicit_damping: bool,
    /// On a treadmill, the pelvis's height when the run started (m): the collapse guard's
    /// reference.
    standing_height_m: Option<f64>,
}

/// How far the pelvis may sink below its height at the start of a run before the
/// trainer's safety counts a collapse (m): five times the 20 mm the nominal trainer's
/// pelvis moves in a stride (`simulate gait_treadmill`: 20.4 mm at four substeps; 18 mm
/// when the threshold was set, issue 46), and a third of the 284 mm a
/// collapsing patient sank (issue 46). A gait trainer's harness catches the patient
/// there: Lokomat-type body-weight support units hold a fall within a few centimetres.
pub const COLLAPSE_PELVIS_DROP_M: f64 = 0.10;

/// Leg `leg`'s joint rates at the end of a physics step of `h` s in which the muscles'
/// damping acts on them (linearly implicit Euler): `(M + h D) v1 = M v + h (tau0 +
/// tau_other - bias)`, `M` and `bias` the leg's mass matrix and its Coriolis-less-gravity
/// torques (its own rigid-body model, the pelvis fixed), `D` the pulling muscles' `r^2
/// b(P)`, `tau0` their torques at rest and `tau_other` the patient's and the loads'. With
/// the muscles' damping taken at these rates rapier's step lands on them, so the damping
/// pole (`D / M`, thousands per second) no longer limits the step. `None` while a joint is
/// within a step's travel of its limit (or held there): the limit's force, which the model
/// does not have, would make the prediction wrong, and the step stays explicit.
fn implicit_rates(
    exo: &Exoskeleton,
    muscles: &[MuscleActuator],
    leg: usize,
    tau_other: [f64; 2],
    h: f64,
) -> Option<[f64; 2]> {
    let (q, qd) = (exo.angles(leg), exo.velocities(leg));
    let near_limit = |j: usize| {
        let [lo, hi] = exo.limits_rad(leg)[j];
        let travel = (qd[j].abs() * h).max(LIMIT_MARGIN_RAD);
        q[j] - lo <= travel || hi - q[j] <= travel
    };
    if near_limit(0) || near_limit(1) {
        return None;
    }
    let (mut tau0, mut d) = ([0.0; 2], [0.0; 2]);
    for m in muscles
        .iter()
        .filter(|m| m.leg == leg && m.force_unclamped(q, qd) > 0.0)
    {
        let r = m.geometry.moment_arm_m();
        tau0[m.joint] += r * m.force_unclamped(q, [0.0; 2]);
        d[m.joint] += r * r * m.model.damping(m.valve.pressure(), m.valve.mode());
    }
    let body = exo.inertia();
    let mass = body.mass_matrix(q);
    let bias = body.inverse_dynamics(q, qd, [0.0; 2]);
    let a = [
        [mass[0][0] + h * d[0], mass[0][1]],
        [mass[1][0], mass[1][1] + h * d[1]],
    ];
    let rhs: [f64; 2] = std::array::from_fn(|i| {
        mass[i][0] * qd[0] + mass[i][1] * qd[1] + h * (tau0[i] + tau_other[i] - bias[i])
    });
    crate::base::solve_2x2(a, rhs)
}

/// Nearest a joint may come to its limit (rad) with the muscles' damping still implicit:
/// rapier's limit acts from where the step would cross it.
const LIMIT_MARGIN_RAD: f64 = 1e-3;

/// A sinusoidal load on one joint (N m, flexion positive): a frequency-response test's
/// excitation, `amplitude_nm sin(2 pi frequency_hz t)` at each substep's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExternalWave {
    /// The leg (0 right).
    pub leg: usize,
    /// The joint (0 hip, 1 knee).
    pub joint: usize,
    /// Amplitude (N m).
    pub amplitude_nm: f64,
    /// Frequency (Hz).
    pub frequency_hz: f64,
}

impl ExternalWave {
    fn torque_nm(&self, leg: usize, t_s: f64) -> [f64; 2] {
        let mut out = [0.0; 2];
        if leg == self.leg {
            out[self.joint.min(1)] =
                self.amplitude_nm * (std::f64::consts::TAU * self.frequency_hz * t_s).sin();
        }
        out
    }
}

impl LegPlant {
    /// The plant of `exo` with `muscles` under `settings`, stepped every `period_s` (the
    /// muscles' damping implicit in the joints' speeds with `implicit_damping`).
    pub(crate) fn new(
        exo: Exoskeleton,
        muscles: Vec<MuscleActuator>,
        settings: &PlantSettings,
        period_s: f64,
        implicit_damping: bool,
    ) -> Result<Self, LegError> {
        let mut encoders = Vec::with_capacity(exo.leg_count());
        for leg in 0..exo.leg_count() as u64 {
            encoders.push([
                PositionSensor::new(settings.encoder.sensor(2 * leg))?,
                PositionSensor::new(settings.encoder.sensor(2 * leg + 1))?,
            ]);
        }
        let cuffs = settings.cuffs;
        let thigh_m = exo.inertia().thigh_length_m;
        pma_model::error::within(
            "plant.cuffs.thigh_below_hip_m",
            cuffs.thigh_below_hip_m,
            crate::plant::CUFF_BELOW_JOINT_MIN_M,
            thigh_m,
            format!("must be at most the thigh's length, {thigh_m:.3} m"),
        )?;
        let cuff = settings.cuff_sensor;
        let cuff_noise = (0..exo.leg_count() as u64)
            .map(|leg| [0, 1].map(|j| GaussianRng::new(cuff.seed.wrapping_add(2 * leg + j))))
            .collect();
        Ok(Self {
            cuff_sensor: cuff,
            cuff_noise,
            cuffs,
            exo,
            muscles,
            encoders,
            period_s,
            periods: 0,
            slack_s: [[0.0; 4]; MAX_LEGS],
            patients: Vec::new(),
            muscles_attached: true,
            external_nm: [[0.0; 2]; MAX_LEGS],
            acceleration: [[0.0; 2]; MAX_LEGS],
            external_wave: None,
            implicit_damping,
            standing_height_m: None,
        })
    }

    /// Adds a sinusoidal load on one joint (none: take it off), beside the constant one.
    pub fn set_external_wave(&mut self, wave: Option<ExternalWave>) {
        self.external_wave = wave;
    }

    /// Hangs a constant load on leg `leg`'s joints (N m, flexion positive; zero to take it
    /// off): a perturbation test's weight, beside the muscles and the patient.
    pub fn set_external_torque(&mut self, leg: usize, torque_nm: [f64; 2]) {
        if let Some(t) = self.external_nm.get_mut(leg) {
            *t = torque_nm;
        }
    }

    /// Whether the muscles' cables are hooked to the joints (see `attach_muscles`).
    pub fn muscles_attached(&self) -> bool {
        self.muscles_attached
    }

    /// Puts a patient in each leg (empty: the passive limb).
    pub fn set_patients(&mut self, patients: Vec<Patient>) {
        self.patients = patients;
    }

    /// The first leg's patient, if any.
    pub fn patient(&self) -> Option<&Patient> {
        self.patients.first()
    }

    /// The first leg's patient, to plan or change it.
    pub fn patient_mut(&mut self) -> Option<&mut Patient> {
        self.patients.first_mut()
    }

    /// Every leg's patient, to plan or change them.
    pub fn patients_mut(&mut self) -> &mut [Patient] {
        &mut self.patients
    }

    /// Every leg's patient (empty for the passive limb).
    pub fn patients(&self) -> &[Patient] {
        &self.patients
    }

    /// Unhooks the muscles' cables (`false`): they pull on nothing, as for a test of the
    /// limb alone whose range the cables and the muscles' stroke would not allow.
    pub fn attach_muscles(&mut self, attached: bool) {
        self.muscles_attached = attached;
    }

    /// Mutable exoskeleton (mounting, holding a joint).
    pub fn exo_mut(&mut self) -> &mut Exoskeleton {
        &mut self.exo
    }

    /// The exoskeleton (poses, angles, energy).
    pub fn exo(&self) -> &Exoskeleton {
        &self.exo
    }

    /// Number of legs.
    pub fn leg_count(&self) -> usize {
        self.exo.leg_count()
    }

    /// Every leg's muscles, leg after leg.
    pub fn muscles(&self) -> &[MuscleActuator] {
        &self.muscles
    }

    /// Leg `leg`'s four muscles.
    pub fn leg_muscles(&self, leg: usize) -> &[MuscleActuator] {
        let at = leg * MUSCLES_PER_LEG;
        self.muscles.get(at..at + MUSCLES_PER_LEG).unwrap_or(&[])
    }

    /// One leg's muscles' names, in the geometry file's order (every leg has the same).
    pub fn muscle_names(&self) -> Vec<String> {
        self.leg_muscles(0)
            .iter()
            .map(|m| m.geometry.name.clone())
            .collect()
    }

    /// Time (s): whole periods since the plant was built.
    pub fn time(&self) -> f64 {
        self.periods as f64 * self.period_s
    }

    /// Puts leg `leg` at `angles` with `velocities` (the valves keep their pressure).
    pub fn set_state(&mut self, leg: usize, angles: [f64; 2], velocities: [f64; 2]) {
        self.exo.set_state(leg, angles, velocities);
    }

    /// Sets every valve of leg `leg` to `pressures_pa` at once (a resting state).
    pub fn set_pressures(&mut self, leg: usize, pressures_pa: [f64; 4]) -> Result<(), LegError> {
        let at = leg * MUSCLES_PER_LEG;
        for (m, p) in self.muscles[at..at + MUSCLES_PER_LEG]
            .iter_mut()
            .zip(pressures_pa)
        {
            m.valve = Valve::new(*m.valve.params(), p)?;
        }
        Ok(())
    }

    /// Vents every valve of every leg at once.
    pub fn vent_all(&mut self) -> Result<(), LegError> {
        for leg in 0..self.leg_count() {
            self.set_pressures(leg, [0.0; 4])?;
        }
        Ok(())
    }

    /// One period with the valves commanded directly (open-loop checks).
    pub fn apply(&mut self, commands_pa: PerLeg<[f64; 4]>) -> TrainerState {
        self.command(&commands_pa);
        self.advance();
        self.state()
    }

    fn command(&mut self, commands_pa: &PerLeg<[f64; 4]>) -> PerLeg<[f64; 4]> {
        for m in &mut self.muscles {
            let u = commands_pa.get(m.leg).map_or(0.0, |c| c[m.index_in_leg()]);
            m.valve.command(u);
        }
        let muscles = &self.muscles;
        PerLeg::from_fn(self.exo.leg_count(), |leg| {
            std::array::from_fn(|i| match muscles.get(leg * MUSCLES_PER_LEG + i) {
                Some(m) => m
                    .valve
                    .params()
                    .clamp(commands_pa.get(leg).map_or(0.0, |c| c[i])),
                None => f64::NAN,
            })
        })
    }

    /// Physics over one period with the valves as commanded: every substep the valves
    /// advance and each leg's muscles' and patient's torques go into rapier.
    fn advance(&mut self) {
        let muscles = &mut self.muscles;
        let patients = &mut self.patients;
        let attached = self.muscles_attached;
        let external = self.external_nm;
        let wave = self.external_wave;
        let implicit = self.implicit_damping;
        let legs = self.exo.leg_count();
        let h = self.period_s / f64::from(self.exo.substeps());
        let t0 = self.periods as f64 * self.period_s;
        let mut slack = [[0.0; 4]; MAX_LEGS];
        // Each muscle's force at the substep's start, once: the slack time and (with the
        // damping explicit) the torque read the same value.
        let mut unclamped = [[0.0; 4]; MAX_LEGS];
        let before: [[f64; 2]; MAX_LEGS] = std::array::from_fn(|leg| {
            if leg < legs {
                self.exo.velocities(leg)
            } else {
                [0.0; 2]
            }
        });
        self.exo.step(|exo, sub| {
            let t = t0 + sub as f64 * h;
            // Each leg's state once a substep, not once for each of its muscles.
            let state = PerLeg::from_fn(legs, |leg| exo.angles_and_velocities(leg));
            let angles = PerLeg::from_fn(legs, |leg| state[leg].0);
            let velocities = PerLeg::from_fn(legs, |leg| state[leg].1);
            let mut tau = PerLeg::from_fn(legs, |leg| {
                let patient = match patients.get_mut(leg) {
                    Some(p) => p.torques(t, angles[leg], velocities[leg]).total(),
                    None => [0.0; 2],
                };
                let w = wave.map_or([0.0; 2], |w| w.torque_nm(leg, t));
                [
                    patient[0] + external[leg][0] + w[0],
                    patient[1] + external[leg][1] + w[1],
                ]
            });
            for m in muscles.iter_mut() {
                let (q, qd) = (angles[m.leg], velocities[m.leg]);
                m.valve
                    .advance_at(h, m.contraction(q), m.contraction_rate(qd));
                let f = m.force_unclamped(q, qd);
                if f <= 0.0 {
                    slack[m.leg][m.index_in_leg()] += h;
                }
                unclamped[m.leg][m.index_in_leg()] = f;
            }
            if attached && implicit {
                // The rates the muscles' damping sees: the step's end.
                let rates = PerLeg::from_fn(legs, |leg| {
                    implicit_rates(exo, muscles, leg, tau[leg], h).unwrap_or(velocities[leg])
                });
                for m in muscles.iter() {
                    tau[m.leg][m.joint] += m.torque(angles[m.leg], rates[m.leg]);
                }
            } else if attached {
                // The step's start: the forces above.
                for m in muscles.iter() {
                    tau[m.leg][m.joint] += m.torque_of(unclamped[m.leg][m.index_in_leg()]);
                }
            }
            tau
        });
        self.slack_s = slack;
        for (leg, v0) in before.iter().enumerate().take(legs) {
            let v = self.exo.velocities(leg);
            self.acceleration[leg] = [
                (v[0] - v0[0]) / self.period_s,
                (v[1] - v0[1]) / self.period_s,
            ];
        }
        self.periods += 1;
    }

    fn readings(&mut self) -> PerLeg<LegReading> {
        let legs = self.exo.leg_count();
        let cuffs = PerLeg::from_fn(legs, |leg| {
            let (q, qd) = self.exo.angles_and_velocities(leg);
            self.cuff_torque_nm(leg, q, qd)
        });
        let exo = &self.exo;
        let muscles = &self.muscles;
        let encoders = &mut self.encoders;
        let (sensor, noise) = (&self.cuff_sensor, &mut self.cuff_noise);
        PerLeg::from_fn(legs, |leg| {
            let pressure = |i: usize| {
                muscles
                    .get(leg * MUSCLES_PER_LEG + i)
                    .map_or(f64::NAN, |m| m.pressure())
            };
            let q = exo.angles(leg);
            let cuff = |j: usize, rng: &mut GaussianRng| {
                let drawn = if sensor.noise_rms_nm > 0.0 {
                    sensor.noise_rms_nm * rng.standard_normal()
                } else {
                    0.0
                };
                cuffs[leg][j] + sensor.bias_nm[j] + drawn
            };
            let [hip_rng, knee_rng] = &mut noise[leg];
            [
                encoders[leg][0].measure(q[0]),
                encoders[leg][1].measure(q[1]),
                cuff(0, hip_rng),
                cuff(1, knee_rng),
                pressure(0),
                pressure(1),
                pressure(2),
                pressure(3),
            ]
        })
    }

    /// The torque the device puts into leg `leg`'s limb at angles `q` and velocities `qd`
    /// (N m): the muscles' torque less the frames' inverse dynamics, the acceleration the
    /// mean over the last period.
    fn cuff_torque_nm(&self, leg: usize, q: [f64; 2], qd: [f64; 2]) -> [f64; 2] {
        let forces = self.leg_muscles(leg).iter().map(|m| m.force(q, qd));
        self.cuff_torque_of(leg, q, qd, forces)
    }

    /// [`LegPlant::cuff_torque_nm`] from the leg's muscles' pulling forces at `q`, `qd`
    /// (N, in the leg's order), where they are known already.
    fn cuff_torque_of(
        &self,
        leg: usize,
        q: [f64; 2],
        qd: [f64; 2],
        forces_n: impl Iterator<Item = f64>,
    ) -> [f64; 2] {
        let mut muscles_nm = [0.0; 2];
        if self.muscles_attached {
            for (mm, f) in self.leg_muscles(leg).iter().zip(forces_n) {
                muscles_nm[mm.joint] += mm.geometry.moment_arm_m() * f;
            }
        }
        let frames = self
            .exo
            .inertia()
            .frames()
            .inverse_dynamics(q, qd, self.acceleration[leg]);
        [muscles_nm[0] - frames[0], muscles_nm[1] - frames[1]]
    }

    /// Leg `leg`'s true state now.
    pub fn leg_state(&self, leg: usize) -> LegState {
        let (q, qd) = self.exo.angles_and_velocities(leg);
        let m = self.leg_muscles(leg);
        let each = |f: &dyn Fn(&MuscleActuator) -> f64| -> [f64; 4] {
            std::array::from_fn(|i| m.get(i).map_or(f64::NAN, f))
        };
        let force_n = each(&|m| m.force(q, qd));
        let interaction_nm = self.cuff_torque_of(leg, q, qd, force_n.into_iter());
        LegState {
            angle_rad: q,
            velocity_rad_s: qd,
            interaction_nm,
            cuff_force_n: crate::plant::cuff_forces_n(
                interaction_nm,
                q[1],
                self.exo.inertia().thigh_length_m,
                &self.cuffs,
            ),
            pressure_pa: each(&|m| m.pressure()),
            force_n,
            length_m: each(&|m| m.contraction(q)),
            slack_s: self.slack_s[leg],
            patient: self
                .patients
                .get(leg)
                .map_or_else(PatientTorques::default, Patient::last),
            ankle_rad: self.exo.ankle(leg).map_or(f64::NAN, |a| a.0),
            ankle_torque_nm: self.exo.ankle_torque_nm(leg),
        }
    }

    /// The true state now.
    pub fn state(&self) -> TrainerState {
        TrainerState {
            legs: PerLeg::from_fn(self.exo.leg_count(), |leg| self.leg_state(leg)),
            ground: self.exo.ground_reaction(),
            pelvis_m: self.exo.pelvis_position_m(),
        }
    }

    /// Each of leg `leg`'s muscles as a segment from its anchor to its joint's pulley, in
    /// world coordinates (m), for drawing.
    pub fn muscle_segments(&self, leg: usize) -> [([f64; 3], [f64; 3]); 4] {
        let muscles = self.leg_muscles(leg);
        let joints = self.exo.leg(leg);
        std::array::from_fn(|i| {
            let Some(m) = muscles.get(i) else {
                return ([f64::NAN; 3], [f64::NAN; 3]);
            };
            let g = &m.geometry;
            let anchor = self
                .exo
                .point_in_world(&joints.link_name(&g.body_link), m.anchor_m());
            // The pulley sits on the joint axis: the origin of the joint's child link.
            let child = joints.urdf_name(if m.joint == 0 { "thigh" } else { "shank" });
            let pulley = self.exo.point_in_world(&child, [0.0, m.anchor_m()[1], 0.0]);
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
        let legs = self.exo.leg_count();
        for leg in 0..legs {
            let (q, qd) = (self.exo.angles(leg), self.exo.velocities(leg));
            let limits = self.exo.limits_rad(leg);
            for (k, name) in JOINT_NAMES.iter().enumerate() {
                if let Some(why) = left_physics(q[k], qd[k], limits[k]) {
                    return Err(LegError::LeftPhysics {
                        t_s: self.time(),
                        what: format!("the {}: {why}", leg_label(legs, leg, name)),
                    });
                }
            }
        }
        self.check_ground()
    }

    /// On a treadmill: the trainer's safety, which stops the run as a gait trainer stops
    /// its belt when the patient's pelvis sinks [`COLLAPSE_PELVIS_DROP_M`] below where it
    /// stood at the start.
    fn check_collapse(&self) -> Result<(), LegError> {
        let (Some(start), Some(z)) = (self.standing_height_m, self.exo.pelvis_height_m()) else {
            return Ok(());
        };
        let drop = start - z;
        if drop > COLLAPSE_PELVIS_DROP_M {
            let legs = self.exo.leg_count();
            let knees: Vec<String> = (0..legs)
                .map(|leg| {
                    format!(
                        "{} {:.0} deg",
                        leg_label(legs, leg, "knee"),
                        self.exo.angles(leg)[1].to_degrees()
                    )
                })
                .collect();
            return Err(LegError::Collapse {
                t_s: self.time(),
                what: format!(
                    "the pelvis sank {:.0} mm below where it stood (limit {:.0} mm; {})",
                    drop * 1e3,
                    COLLAPSE_PELVIS_DROP_M * 1e3,
                    knees.join(", ")
                ),
            });
        }
        Ok(())
    }

    /// On a treadmill: the pelvis finite and no foot deeper in the belt than its spheres
    /// are wide (Hertz contact means nothing past that: the model has failed).
    fn check_ground(&self) -> Result<(), LegError> {
        let (Some(g), Some(r)) = (self.exo.ground(), self.exo.ground_reaction()) else {
            return Ok(());
        };
        let z = self.exo.pelvis_height_m().unwrap_or(f64::NAN);
        for (leg, (foot, reaction)) in g.feet().iter().zip(r.feet.iter()).enumerate() {
            let bound_m = foot
                .spheres
                .iter()
                .map(|s| 2.0 * s.radius_m)
                .fold(0.0, f64::max);
            let what = if !(z.is_finite() && reaction.vertical_n.is_finite()) {
                Some(format!(
                    "the pelvis or the ground reaction is not finite ({z} m, {} N)",
                    reaction.vertical_n
                ))
            } else if reaction.penetration_m > bound_m {
                Some(format!(
                    "the {} is {:.1} mm into the belt (bound {:.0} mm, its spheres' diameter)",
                    leg_label(r.feet.len(), leg, "foot"),
                    reaction.penetration_m * 1e3,
                    bound_m * 1e3
                ))
            } else {
                None
            };
            if let Some(what) = what {
                return Err(LegError::LeftPhysics {
                    t_s: self.time(),
                    what,
                });
            }
        }
        Ok(())
    }
}

/// Why a joint at `q` (rad) turning at `qd` (rad/s) within `[lo, hi]` has left the
/// physics, if it has.
pub(crate) fn left_physics(q: f64, qd: f64, [lo, hi]: [f64; 2]) -> Option<String> {
    let beyond = (lo - q).max(q - hi);
    if !(q.is_finite() && qd.is_finite()) {
        Some(format!("its state is not finite ({q} rad, {qd} rad/s)"))
    } else if beyond > LIMIT_OVERSHOOT_MAX_RAD {
        Some(format!(
            "it is {beyond:.3} rad beyond its limits [{lo:.3}, {hi:.3}] rad (bound {LIMIT_OVERSHOOT_MAX_RAD} rad)"
        ))
    } else if qd.abs() > JOINT_SPEED_MAX_RAD_S {
        Some(format!(
            "it turns at {qd:.1} rad/s (bound {JOINT_SPEED_MAX_RAD_S} rad/s)"
        ))
    } else {
        None
    }
}

impl Backend for LegPlant {
    type Reading = PerLeg<LegReading>;
    type Command = PerLeg<[f64; 4]>;
    type Truth = TrainerState;
    type Error = LegError;

    /// The exoskeleton as it is (built at rest); the valves hold their pressures, the
    /// patients' reflexes start from a limb at rest.
    fn start(&mut self) -> Result<Started<Self::Reading, Self::Command>, LegError> {
        for p in &mut self.patients {
            p.reset();
        }
        let reading = self.readings();
        let state = self.state();
        self.standing_height_m = self.exo.pelvis_height_m();
        Ok(Started {
            t_s: self.time(),
            reading,
            command: state.legs.map(|l| l.pressure_pa),
        })
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn wait(&mut self) -> Result<u32, LegError> {
        self.advance();
        self.check_physics()?;
        self.check_collapse()?;
        Ok(1)
    }

    fn read(&mut self) -> Result<Self::Reading, LegError> {
        Ok(self.readings())
    }

    fn write(&mut self, commands_pa: &Self::Command) -> Result<Self::Command, LegError> {
        Ok(self.command(commands_pa))
    }

    fn truth(&self) -> TrainerState {
        self.state()
    }

    /// Vents every muscle.
    fn stop(&mut self) {
        let vent = PerLeg::splat(self.exo.leg_count(), [0.0; 4]);
        self.command(&vent);
    }
}
