//! The leg's controller set as a [`Task`] of the closed loop: one muscle controller per
//! muscle, a co-contraction regulator per joint, and the gait reference.
use crate::base::{invalid, LegError, PerLeg};
use crate::body::LegInertia;
use crate::control::{
    Admittance, ControlMode, ControlSettings, ExpectedMoments, ForceLimit, ImpedanceLaw, PhaseSync,
    StanceLoad,
};
use crate::gait::{GaitReference, GaitSample, JointSample};
use crate::plant::{
    reading_angles, reading_cuff_nm, reading_pressures_pa, LegReading, MuscleActuator,
    MuscleGeometry,
};
use pma_control::{
    build_controller, CommandLimits, Controller, ControllerConfig, Diagnostics, Measurement,
    NominalModel, RefSample,
};
use pma_loop::Task;
use pma_model::DampingMode;

/// Co-contraction regulation of one joint.
///
/// Length control of both muscles fixes the joint angle, not the sum of their pressures;
/// with each muscle's observer treating its antagonist as a disturbance, the common mode
/// integrates any inconsistency between the two length references. The regulator uses
/// exactly that: it offsets both references by `delta / 2` (an interference the geometry
/// cannot satisfy), proportional to the error of the filtered common-mode pressure, so
/// the common mode follows its target instead of drifting.
#[derive(Debug, Clone, Copy)]
struct CoContraction {
    target_pa: f64,
    gain_m_per_pa: f64,
    max_m: f64,
    filter_s: f64,
    filtered_pa: f64,
}

impl CoContraction {
    fn update(&mut self, common_mode_pa: f64, dt: f64) -> f64 {
        let a = 1.0 - (-dt / self.filter_s).exp();
        self.filtered_pa += a * (common_mode_pa - self.filtered_pa);
        (self.gain_m_per_pa * (self.target_pa - self.filtered_pa)).clamp(-self.max_m, self.max_m)
    }
}

/// What one muscle's controller needs of its geometry.
#[derive(Debug, Clone, Copy)]
struct Lever {
    joint: usize,
    moment_arm_m: f64,
    contraction_at_zero_m: f64,
}

impl Lever {
    fn of(g: &MuscleGeometry, joint: usize) -> Self {
        Self {
            joint,
            moment_arm_m: g.moment_arm_m(),
            contraction_at_zero_m: g.contraction_at_zero_m,
        }
    }

    fn contraction(&self, angle_rad: f64) -> f64 {
        self.contraction_at_zero_m + self.moment_arm_m * angle_rad
    }

    /// The muscle's length reference for a joint reference, offset by `delta / 2`.
    fn reference(&self, j: &JointSample, delta_m: f64) -> RefSample {
        RefSample {
            position_m: self.contraction_at_zero_m
                + self.moment_arm_m * j.angle_rad
                + 0.5 * delta_m,
            velocity_m_s: self.moment_arm_m * j.velocity_rad_s,
            acceleration_m_s2: self.moment_arm_m * j.acceleration_rad_s2,
        }
    }
}

/// One period of a leg's controllers.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegOutput {
    /// Reference joint angles (rad), hip and knee.
    pub reference_rad: [f64; 2],
    /// Reference joint velocities (rad/s).
    pub reference_velocity_rad_s: [f64; 2],
    /// Muscle length references (m).
    pub length_ref_m: [f64; 4],
    /// Pressure commands (Pa).
    pub pressure_cmd_pa: [f64; 4],
    /// Controller states.
    pub diagnostics: [Diagnostics; 4],
    /// Whether the reference's foot is in stance (the normative cycle's timing).
    pub reference_in_stance: bool,
    /// Whether each muscle's command was lowered to its force limit
    /// (`[control] force_max_of_rating`).
    pub force_limited: [bool; 4],
}

/// The four muscle controllers, two co-contraction regulators and the gait reference.
pub struct LegControllers {
    levers: [Lever; 4],
    controllers: Vec<Box<dyn Controller>>,
    cocontraction: [CoContraction; 2],
    regulator_at_rest: CoContraction,
    gait: GaitReference,
    hold: Option<[f64; 2]>,
    commands: [f64; 4],
    /// The pressure-set modes' law (none: the muscles' controllers in charge).
    impedance: Option<ImpedanceLaw>,
    /// Admittance mode's displacement of the reference the muscles' controllers track.
    admittance: Option<Admittance>,
    /// The weight the leg carries in stance on a treadmill, which impedance and admittance
    /// modes hold.
    stance_load: Option<StanceLoad>,
    /// The moments the plan leaves to a walking patient (impedance and admittance modes).
    expected: Option<ExpectedMoments>,
    /// Whether the muscles' pressure sensors feed the controllers' observers
    /// (`control.pressure_feedback`).
    pressure_feedback: bool,
    /// The ceiling on the commands from each muscle's force (`control.force_max_of_rating`).
    force_limit: Option<ForceLimit>,
}

fn joint(g: &GaitSample, joint: usize) -> &JointSample {
    if joint == 0 {
        &g.hip
    } else {
        &g.knee
    }
}

impl LegControllers {
    /// One controller of `config` per muscle. Nominal model of each muscle: what it
    /// assumes ([`MuscleActuator::assumed`]: Table I, or its Festo map's fit), a
    /// fraction of the standing leg's joint inertia seen through the pulley (see
    /// `ControlSettings::nominal_inertia_fraction`), and the antagonist's pull at the
    /// co-contraction target as its static load. `limits_rad` bounds each joint's
    /// reference where admittance mode displaces it.
    pub(crate) fn new(
        settings: &ControlSettings,
        pressure_max_pa: f64,
        gait: GaitReference,
        muscles: &[MuscleActuator],
        inertia: &LegInertia,
        config: &ControllerConfig,
        limits_rad: [[f64; 2]; 2],
    ) -> Result<Self, LegError> {
        let limits = CommandLimits {
            min_pa: 0.0,
            max_pa: pressure_max_pa,
        };
        let joint_inertia = [inertia.hip_inertia(), inertia.knee_inertia()];
        let mut controllers = Vec::with_capacity(4);
        let mut levers = Vec::with_capacity(4);
        for m in muscles {
            let r = m.geometry.pulley_radius_m;
            let antagonist = muscles
                .iter()
                .find(|o| o.joint == m.joint && o.geometry.side != m.geometry.side)
                .ok_or_else(|| LegError::Muscle {
                    muscle: m.geometry.name.clone(),
                    message: "has no antagonist on its joint".into(),
                })?;
            let load = antagonist.assumed().force(
                settings.cocontraction_pa,
                antagonist.geometry.contraction_at_zero_m,
                0.0,
                DampingMode::Inflation,
            );
            let model = NominalModel {
                muscle: m.assumed(),
                mass_kg: settings.nominal_inertia_fraction * joint_inertia[m.joint] / (r * r),
                load_force_n: load,
                valve_time_constant_s: settings.nominal_valve_time_constant_s,
                ..NominalModel::paper()
            };
            controllers.push(build_controller(config, model, limits)?);
            levers.push(Lever::of(&m.geometry, m.joint));
        }
        let levers: [Lever; 4] = levers.try_into().map_err(|v: Vec<Lever>| {
            invalid(
                "number of muscles",
                v.len() as f64,
                "must be 4: a flexor and an extensor on hip and knee",
            )
        })?;
        let regulator = CoContraction {
            target_pa: settings.cocontraction_pa,
            gain_m_per_pa: settings.cocontraction_gain_m_per_pa,
            max_m: settings.cocontraction_max_m,
            filter_s: settings.cocontraction_filter_s,
            filtered_pa: settings.cocontraction_pa,
        };
        let mode = settings.mode;
        let impedance = mode
            .sets_pressures()
            .then(|| ImpedanceLaw::new(settings, pressure_max_pa, muscles, inertia, &gait))
            .transpose()?;
        let admittance = (mode == ControlMode::Admittance)
            .then(|| admittance_of(settings, pressure_max_pa, muscles, inertia, limits_rad))
            .transpose()?;
        Ok(Self {
            levers,
            controllers,
            cocontraction: [regulator; 2],
            regulator_at_rest: regulator,
            gait,
            hold: None,
            commands: [0.0; 4],
            impedance,
            admittance,
            stance_load: None,
            expected: None,
            pressure_feedback: settings.pressure_feedback,
            force_limit: settings
                .force_max_of_rating
                .map(|share| ForceLimit::new(muscles, share, pressure_max_pa))
                .transpose()?,
        })
    }

    /// Impedance and admittance modes hold `load` in stance (a leg on a treadmill); other
    /// modes ignore it.
    pub fn set_stance_load(&mut self, load: StanceLoad) {
        if self.admittance.is_some()
            || self
                .impedance
                .as_ref()
                .is_some_and(|law| law.mode() == ControlMode::Impedance)
        {
            self.stance_load = Some(load);
        }
    }

    /// Impedance and admittance modes leave `expected` to the patient: the torque they
    /// hold is the stance load (and the limb's dynamics) less it.
    pub fn set_expected_moments(&mut self, expected: ExpectedMoments) {
        self.expected = Some(expected);
    }

    /// What the plan holds besides the carried limb's dynamics at `t_s`, the gait at its
    /// time `clock_s`: the stance load, less the moments left to the patient while the leg
    /// follows the gait.
    fn planned_load_nm(&self, t_s: f64, clock_s: f64, angles: &[f64; 2]) -> [f64; 2] {
        let load = self.stance_load_nm(t_s, clock_s, angles);
        match (&self.expected, self.hold) {
            (Some(e), None) => {
                let m = e.torques_nm(&self.gait, clock_s, t_s);
                [load[0] - m[0], load[1] - m[1]]
            }
            _ => load,
        }
    }

    /// The torques that hold this leg's share of the weight at `t_s` (zero without a
    /// stance load): half while the start-up stands, then by the reference's phase at its
    /// time `clock_s`.
    fn stance_load_nm(&self, t_s: f64, clock_s: f64, angles: &[f64; 2]) -> [f64; 2] {
        let Some(load) = &self.stance_load else {
            return [0.0; 2];
        };
        let share = if self.walking(clock_s) {
            load.share(self.gait.phase(clock_s))
        } else {
            0.5
        };
        load.torques_nm(*angles, share, t_s)
    }

    /// Whether the leg walks at the gait's time `t_s`: neither holding a pose nor
    /// standing through a standing start-up.
    pub(crate) fn walking(&self, t_s: f64) -> bool {
        self.hold.is_none() && !self.gait.standing(t_s)
    }

    /// The pressure-set modes' law, if the leg runs in one.
    pub fn impedance(&self) -> Option<&ImpedanceLaw> {
        self.impedance.as_ref()
    }

    /// Admittance mode's displacement, if the leg runs in it.
    pub fn admittance(&self) -> Option<&Admittance> {
        self.admittance.as_ref()
    }

    /// The gait reference (also while a pose is held).
    pub fn gait(&self) -> &GaitReference {
        &self.gait
    }

    /// Replaces the gait by a constant pose (rad): the reference for a static hold.
    pub fn hold_pose(&mut self, angles: [f64; 2]) {
        self.hold = Some(angles);
    }

    /// The joint references at `t_s`.
    pub fn reference(&self, t_s: f64) -> GaitSample {
        match self.hold {
            Some(q) => GaitSample {
                hip: JointSample {
                    angle_rad: q[0],
                    ..JointSample::default()
                },
                knee: JointSample {
                    angle_rad: q[1],
                    ..JointSample::default()
                },
                ankle: JointSample::default(),
            },
            None => self.gait.sample(t_s),
        }
    }

    /// Mean command of each joint's pair (the common mode the regulators act on).
    fn common_mode_pa(&self) -> [f64; 2] {
        let mut sum = [(0.0, 0u32); 2];
        for (lever, u) in self.levers.iter().zip(self.commands) {
            sum[lever.joint].0 += u;
            sum[lever.joint].1 += 1;
        }
        sum.map(|(s, n)| s / f64::from(n.max(1)))
    }
}

impl LegControllers {
    /// Resets every controller on the measured pose and the first reference and acts on
    /// that reading at once (the leg's valves get their first command at `t_0`).
    fn start(
        &mut self,
        t_s: f64,
        reading: &LegReading,
        resting: &[f64; 4],
        period_s: f64,
    ) -> LegOutput {
        let angles = reading_angles(reading);
        self.commands = *resting;
        self.cocontraction = [self.regulator_at_rest; 2];
        if let Some(law) = &mut self.impedance {
            law.reset(*resting);
        }
        if let Some(a) = &mut self.admittance {
            a.reset();
        }
        if let Some(l) = &mut self.force_limit {
            l.reset();
        }
        let g = self.reference(t_s);
        for (lever, c) in self.levers.iter().zip(self.controllers.iter_mut()) {
            let measured = Measurement {
                position_m: lever.contraction(angles[lever.joint]),
            };
            c.reset(measured, lever.reference(joint(&g, lever.joint), 0.0));
        }
        self.update(t_s, reading, period_s)
    }

    fn update(&mut self, t_s: f64, reading: &LegReading, dt_s: f64) -> LegOutput {
        self.update_at(t_s, t_s, 1.0, reading, dt_s)
    }

    /// As `update` with the gait at its time `clock_s`, its clock running at `rate` gait
    /// seconds per second ([`crate::phase_sync`]): the reference's velocity scales by
    /// `rate`, its acceleration by `rate` squared.
    fn update_at(
        &mut self,
        t_s: f64,
        clock_s: f64,
        rate: f64,
        reading: &LegReading,
        dt_s: f64,
    ) -> LegOutput {
        let mut out = self.commands_at(t_s, clock_s, rate, reading, dt_s);
        // The force limit bounds every mode's commands, after the law that made them.
        if let Some(l) = &mut self.force_limit {
            l.apply(
                &mut out.pressure_cmd_pa,
                reading_angles(reading),
                reading_pressures_pa(reading),
                dt_s,
            );
            out.force_limited = l.bound();
        }
        self.commands = out.pressure_cmd_pa;
        out
    }

    /// The commands of the leg's mode, before the force limit.
    fn commands_at(
        &mut self,
        t_s: f64,
        clock_s: f64,
        rate: f64,
        reading: &LegReading,
        dt_s: f64,
    ) -> LegOutput {
        let angles = &reading_angles(reading);
        let g = at_rate(self.reference(clock_s), rate);
        let load = self.planned_load_nm(t_s, clock_s, angles);
        let phase =
            (self.impedance.is_some() && self.walking(clock_s)).then(|| self.gait.phase(clock_s));
        if let Some(law) = &mut self.impedance {
            let pressure_cmd_pa = law.update(&g, *angles, load, phase, dt_s);
            self.commands = pressure_cmd_pa;
            return LegOutput {
                reference_rad: [g.hip.angle_rad, g.knee.angle_rad],
                reference_velocity_rad_s: [g.hip.velocity_rad_s, g.knee.velocity_rad_s],
                length_ref_m: std::array::from_fn(|i| {
                    let lever = &self.levers[i];
                    lever.reference(joint(&g, lever.joint), 0.0).position_m
                }),
                pressure_cmd_pa,
                diagnostics: [Diagnostics::NONE; 4],
                reference_in_stance: self.hold.is_some() || self.gait.in_stance(clock_s),
                force_limited: [false; 4],
            };
        }
        let cm = self.common_mode_pa();
        let delta = [
            self.cocontraction[0].update(cm[0], dt_s),
            self.cocontraction[1].update(cm[1], dt_s),
        ];
        let mut out = LegOutput {
            reference_rad: [g.hip.angle_rad, g.knee.angle_rad],
            reference_velocity_rad_s: [g.hip.velocity_rad_s, g.knee.velocity_rad_s],
            length_ref_m: [0.0; 4],
            pressure_cmd_pa: [0.0; 4],
            diagnostics: [Diagnostics::NONE; 4],
            reference_in_stance: self.hold.is_some() || self.gait.in_stance(clock_s),
            force_limited: [false; 4],
        };
        // The tracked reference: the gait's, or admittance mode's displacement of it (the
        // outputs keep the gait's, against which every mode's tracking is measured).
        let g = match &mut self.admittance {
            Some(a) => a.update(&g, *angles, reading_cuff_nm(reading), load, dt_s),
            None => g,
        };
        for (i, (lever, c)) in self
            .levers
            .iter()
            .zip(self.controllers.iter_mut())
            .enumerate()
        {
            let r = lever.reference(joint(&g, lever.joint), delta[lever.joint]);
            let measured = Measurement {
                position_m: lever.contraction(angles[lever.joint]),
            };
            if self.pressure_feedback {
                c.pressure_sensed(reading_pressures_pa(reading)[i]);
            }
            let o = c.update(&r, &measured, dt_s);
            out.length_ref_m[i] = r.position_m;
            out.pressure_cmd_pa[i] = o.pressure_cmd_pa;
            out.diagnostics[i] = o.diagnostics;
        }
        self.commands = out.pressure_cmd_pa;
        out
    }

    fn applied(&mut self, written: &[f64; 4]) {
        for (c, u) in self.controllers.iter_mut().zip(written) {
            c.applied(*u);
        }
        if let Some(law) = &mut self.impedance {
            law.applied(*written);
        }
        self.commands = *written;
    }
}

/// `g` on a clock running at `rate` gait seconds per second.
fn at_rate(g: GaitSample, rate: f64) -> GaitSample {
    if rate == 1.0 {
        return g;
    }
    let scaled = |j: JointSample| JointSample {
        angle_rad: j.angle_rad,
        velocity_rad_s: rate * j.velocity_rad_s,
        acceleration_rad_s2: rate * rate * j.acceleration_rad_s2,
    };
    GaitSample {
        hip: scaled(g.hip),
        knee: scaled(g.knee),
        ankle: scaled(g.ankle),
    }
}

/// Admittance mode's displacement for a leg of `muscles` (its set points checked, a
/// stiffness left out taking co-contraction's default).
fn admittance_of(
    settings: &ControlSettings,
    pressure_max_pa: f64,
    muscles: &[MuscleActuator],
    inertia: &LegInertia,
    limits_rad: [[f64; 2]; 2],
) -> Result<Admittance, LegError> {
    let pairs = crate::control::MusclePair::of_leg(muscles, pressure_max_pa)?;
    Admittance::new(
        &settings.impedance,
        settings.compensation,
        &pairs,
        inertia,
        limits_rad,
    )
}

/// Every leg's controllers: the trainer's task. Each leg runs its own [`LegControllers`]
/// on its own readings; nothing passes between legs but the time.
pub struct TrainerControllers {
    legs: Vec<LegControllers>,
    /// The gait's clock, when it follows the legs' lead (none: the reference's own).
    sync: Option<PhaseSync>,
}

impl TrainerControllers {
    /// One set of controllers per leg, in leg order.
    pub fn new(legs: Vec<LegControllers>) -> Self {
        Self { legs, sync: None }
    }

    /// The legs' gait follows `sync`'s clock.
    pub fn with_phase_sync(self, sync: PhaseSync) -> Self {
        Self {
            sync: Some(sync),
            ..self
        }
    }

    /// The gait's clock, if it follows the legs' lead.
    pub fn phase_sync(&self) -> Option<&PhaseSync> {
        self.sync.as_ref()
    }

    /// Leg `leg`'s controllers.
    pub fn leg(&self, leg: usize) -> &LegControllers {
        &self.legs[leg]
    }

    /// Every leg's controllers.
    pub fn legs(&self) -> &[LegControllers] {
        &self.legs
    }

    /// The first leg's gait reference (the others are it, shifted by half strides).
    pub fn gait(&self) -> &GaitReference {
        self.legs[0].gait()
    }

    /// Replaces every leg's gait by the constant pose `angles` (rad).
    pub fn hold_pose(&mut self, angles: [f64; 2]) {
        for l in &mut self.legs {
            l.hold_pose(angles);
        }
    }
}

impl Task for TrainerControllers {
    type Reading = PerLeg<LegReading>;
    type Command = PerLeg<[f64; 4]>;
    type Output = PerLeg<LegOutput>;

    fn start(
        &mut self,
        t_s: f64,
        angles: &Self::Reading,
        resting: &Self::Command,
        period_s: f64,
    ) -> Option<Self::Output> {
        if let Some(s) = &mut self.sync {
            s.reset(t_s);
        }
        let legs = &mut self.legs;
        Some(PerLeg::from_fn(legs.len(), |i| {
            legs[i].start(t_s, &angles[i], &resting[i], period_s)
        }))
    }

    fn update(&mut self, t_s: f64, angles: &Self::Reading, dt_s: f64) -> Self::Output {
        let Some(sync) = &mut self.sync else {
            let legs = &mut self.legs;
            return PerLeg::from_fn(legs.len(), |i| legs[i].update(t_s, &angles[i], dt_s));
        };
        let (clock_s, rate) = (sync.advance(t_s), sync.rate());
        let legs = &mut self.legs;
        let out = PerLeg::from_fn(legs.len(), |i| {
            legs[i].update_at(t_s, clock_s, rate, &angles[i], dt_s)
        });
        // The lead is measured only while every leg walks (not through a standing start
        // or a held pose), against the reference's velocity at rate 1.
        if legs.iter().all(|l| l.walking(clock_s)) {
            let (mut cross, mut power) = (0.0, 0.0);
            for (o, reading) in out.iter().zip(angles.iter()) {
                let q = reading_angles(reading);
                for ((q, r), v) in q
                    .iter()
                    .zip(o.reference_rad)
                    .zip(o.reference_velocity_rad_s)
                {
                    let v = v / rate;
                    cross += (q - r) * v;
                    power += v * v;
                }
            }
            sync.observe(cross, power, dt_s);
        }
        out
    }

    fn command(output: &Self::Output) -> Self::Command {
        output.map(|o| o.pressure_cmd_pa)
    }

    fn applied(&mut self, written: &Self::Command) {
        for (l, w) in self.legs.iter_mut().zip(written.iter()) {
            l.applied(w);
        }
    }
}

/// Every muscle vented, the reference followed by nothing: the gait (or a pose) is only
/// reported, for the metrics and the logs. The limbs move under gravity and the patient.
pub struct Vented {
    gait: Option<GaitReference>,
    pose: [f64; 2],
    legs: usize,
}

impl Vented {
    /// Reports `gait` as one leg's reference.
    pub fn gait(gait: GaitReference) -> Self {
        Self {
            gait: Some(gait),
            pose: [0.0; 2],
            legs: 1,
        }
    }

    /// Reports a constant pose (rad) as one leg's reference.
    pub fn pose(pose: [f64; 2]) -> Self {
        Self {
            gait: None,
            pose,
            legs: 1,
        }
    }

    /// The same for each of `legs` legs (each leg's gait half a stride after the last).
    pub fn on_legs(self, legs: usize) -> Self {
        Self { legs, ..self }
    }

    fn output(&self, leg: usize, t_s: f64) -> LegOutput {
        let (reference_rad, reference_velocity_rad_s, reference_in_stance) = match &self.gait {
            Some(g) => {
                let g = g.for_leg(leg);
                let s = g.sample(t_s);
                (
                    [s.hip.angle_rad, s.knee.angle_rad],
                    [s.hip.velocity_rad_s, s.knee.velocity_rad_s],
                    g.in_stance(t_s),
                )
            }
            None => (self.pose, [0.0; 2], true),
        };
        LegOutput {
            reference_rad,
            reference_velocity_rad_s,
            length_ref_m: [f64::NAN; 4],
            pressure_cmd_pa: [0.0; 4],
            diagnostics: [Diagnostics::NONE; 4],
            reference_in_stance,
            force_limited: [false; 4],
        }
    }

    fn outputs(&self, t_s: f64) -> PerLeg<LegOutput> {
        PerLeg::from_fn(self.legs, |leg| self.output(leg, t_s))
    }
}

impl Task for Vented {
    type Reading = PerLeg<LegReading>;
    type Command = PerLeg<[f64; 4]>;
    type Output = PerLeg<LegOutput>;

    fn start(
        &mut self,
        t_s: f64,
        _: &Self::Reading,
        _: &Self::Command,
        _: f64,
    ) -> Option<Self::Output> {
        Some(self.outputs(t_s))
    }

    fn update(&mut self, t_s: f64, _: &Self::Reading, _: f64) -> Self::Output {
        self.outputs(t_s)
    }

    fn command(output: &Self::Output) -> Self::Command {
        output.map(|o| o.pressure_cmd_pa)
    }
}
