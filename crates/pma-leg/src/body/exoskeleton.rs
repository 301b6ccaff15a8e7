//! The exoskeleton as a rapier multibody loaded from URDF: a pelvis and one or two legs.
//!
//! One leg is a chain `hip -> thigh -> knee -> shank` (and, on a treadmill, `ankle ->
//! foot`); a URDF with one leg names its joints `hip`, `knee`, `ankle`, one with two legs
//! prefixes them `right_` and `left_` (`crates/pma-leg/models/exo_trainer.urdf`). Every
//! leg is the same code: [`LegJoints`] says where one leg's joints are, and the
//! [`Exoskeleton`] holds one per leg on its pelvis. The pelvis is fixed (the leg swings in
//! the air; [`Mount`]) or slides on a treadmill's harness ([`crate::ground`]).
use crate::base::{LegError, PerLeg, MAX_LEGS};
use crate::body::{
    carried_links, foot_spheres, keep_legs, leg_inertia, leg_prefixes, parse_urdf, patient_height,
    patient_legs, patient_on_pelvis, sagittal_chain, urdf_err, visuals_of, JointRef, JointSettings,
    LegInertia, LegJoints, VisualShape, G,
};
use crate::gait::{GaitReference, StartUp};
use crate::ground::{
    AnkleSettings, FootSetup, Ground, GroundReaction, GroundSetup, OtherLeg, TreadmillSettings,
};
use rapier3d::prelude::*;
use rapier3d_urdf::{urdf_rs, UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};
use std::path::Path;

/// Solver iterations of a leg with a held joint (see [`Exoskeleton::hold`]).
pub const HOLD_SOLVER_ITERATIONS: usize = 8;

/// How the leg is mounted: the treadmill's upright pelvis, or the seat of a pendulum test.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Mount {
    /// Backward pitch of the fixed pelvis about the hip's flexion axis (rad).
    pub pelvis_pitch_rad: f64,
    /// Knee limits replacing the URDF's `[lower, upper]` (rad): the exoskeleton's stop
    /// removed for a test of the limb alone.
    pub knee_limits_rad: Option<[f64; 2]>,
}

/// The exoskeleton: a rapier world with the multibody (pelvis and legs) and gravity along
/// -Z, on a fixed pelvis or a treadmill.
pub struct Exoskeleton {
    world: PhysicsWorld,
    legs: Vec<LegJoints>,
    bodies: Vec<(String, RigidBodyHandle)>,
    visuals: Vec<Vec<VisualShape>>,
    inertia: LegInertia,
    substeps: u32,
    /// The ankles' orthosis (on a treadmill).
    ankle: Option<AnkleSettings>,
    /// Each ankle's orthosis torque at the last substep (N m, dorsiflexion positive).
    ankle_torque_nm: [f64; MAX_LEGS],
    /// The treadmill, when the legs stand on one.
    ground: Option<Ground>,
}

impl Exoskeleton {
    /// Loads a one-leg URDF (text; `file` names it in errors) with the pelvis fixed, sets
    /// each joint's damping and friction explicitly, Z up, and `substeps` physics steps of
    /// `period_s / substeps` per [`Exoskeleton::step`].
    pub fn from_urdf_str(
        text: &str,
        file: &str,
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
    ) -> Result<Self, LegError> {
        Self::mounted(text, file, settings, period_s, substeps, Mount::default())
    }

    /// As [`Exoskeleton::from_urdf_str`], mounted as `mount` says (one leg, fixed pelvis).
    pub fn mounted(
        text: &str,
        file: &str,
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
        mount: Mount,
    ) -> Result<Self, LegError> {
        let mut raw = parse_urdf(text, file)?;
        if let Some(slide) = raw
            .joints
            .iter()
            .find(|j| j.joint_type == urdf_rs::JointType::Prismatic)
        {
            return Err(urdf_err(
                file,
                format!(
                    "its pelvis slides (`{}`): a treadmill's model, which an in-air scenario cannot use (give the scenario a [treadmill] section, or use exo_leg.urdf)",
                    slide.name
                ),
            ));
        }
        let mut prefixes = leg_prefixes(&raw, file)?;
        keep_legs(&mut raw, &mut prefixes, 1);
        let mut exo = Self::build(&raw, file, &prefixes, period_s, substeps, mount)?;
        if let Some([lo, hi]) = mount.knee_limits_rad {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(urdf_err(
                    file,
                    format!("knee limits [{lo}, {hi}] rad: need finite lower < upper"),
                ));
            }
            exo.set_limits(0, 1, [lo, hi]);
        }
        exo.set_joint_dynamics(settings);
        Ok(exo)
    }

    /// As [`Exoskeleton::from_urdf_str`] for a URDF with the pelvis on a vertical slide
    /// (`pelvis_z`) and a `foot` link per leg whose `<collision>` spheres touch a belt at
    /// `z = 0`: the treadmill's first `treadmill.legs` legs (the others dropped), the
    /// patient's mass on the pelvis, the harness carrying `bws_fraction` of the weight, each
    /// foot's compliant contacts acting every substep and each ankle on its orthosis (see
    /// [`crate::ground`]). The belt runs at `treadmill.speed_m_per_s` (absent: stopped);
    /// the virtual other leg of a one-leg trainer is added by
    /// [`Exoskeleton::add_other_leg`].
    pub fn on_treadmill(
        text: &str,
        file: &str,
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
        treadmill: &TreadmillSettings,
    ) -> Result<Self, LegError> {
        treadmill.validate()?;
        let mut raw = parse_urdf(text, file)?;
        let mut prefixes = leg_prefixes(&raw, file)?;
        if prefixes.len() < treadmill.legs {
            return Err(urdf_err(
                file,
                format!(
                    "treadmill.legs = {} but the URDF has {} leg(s) (a two-leg URDF names its joints right_hip, left_hip, ...)",
                    treadmill.legs,
                    prefixes.len()
                ),
            ));
        }
        keep_legs(&mut raw, &mut prefixes, treadmill.legs);
        let height_m = treadmill.height_m.unwrap_or(super::URDF_PATIENT_HEIGHT_M);
        patient_height(&mut raw, file, height_m, &prefixes)?;
        let mut feet = Vec::with_capacity(prefixes.len());
        for p in &prefixes {
            let link = format!("{p}foot");
            let spheres = foot_spheres(&raw, file, &link)?;
            feet.push((link, spheres));
        }
        let chain = sagittal_chain(&raw, file, &prefixes[0], feet[0].1.clone())?;
        patient_legs(&mut raw, file, treadmill.body_mass_kg, height_m, &prefixes)?;
        let carried = patient_on_pelvis(&mut raw, file, treadmill.body_mass_kg, prefixes.len())?;
        let mut exo = Self::build(&raw, file, &prefixes, period_s, substeps, Mount::default())?;
        exo.set_joint_dynamics(settings);
        let handle = |exo: &Self, name: &str| {
            exo.body(name)
                .ok_or_else(|| urdf_err(file, format!("no link named `{name}`")))
        };
        let mut foot_setups = Vec::with_capacity(feet.len());
        for (link, spheres) in feet {
            foot_setups.push(FootSetup {
                body: handle(&exo, &link)?,
                link,
                spheres,
            });
        }
        let pelvis = handle(&exo, "pelvis")?;
        // What the belt and harness carry: the pelvis and everything below it (not the
        // fore-aft trolley above it, which the frame carries).
        let total_mass_kg: f64 = carried_links(&raw, "pelvis")
            .iter()
            .filter_map(|n| raw.links.iter().find(|l| &l.name == n))
            .map(|l| l.inertial.mass.value)
            .sum();
        let pelvis_at = exo.world.bodies.get(pelvis).map_or([0.0; 3], |rb| {
            let t = rb.translation();
            [t.x, t.y, t.z]
        });
        let slide = raw
            .joints
            .iter()
            .find(|j| j.name == "pelvis_x" && j.joint_type == urdf_rs::JointType::Prismatic);
        let fore_aft_at_m = slide.map(|_| pelvis_at[0]);
        // The slide's joint coordinate is 0 where the model is built.
        let fore_aft_stops_m =
            slide.map(|j| [pelvis_at[0] + j.limit.lower, pelvis_at[0] + j.limit.upper]);
        exo.ankle = Some(treadmill.ankle);
        for leg in 0..exo.legs.len() {
            if exo.legs[leg].ankle.is_some() {
                exo.set_ankle_range(leg, treadmill.ankle.range_deg.map(f64::to_radians));
            }
        }
        exo.ground = Some(Ground::new(GroundSetup {
            settings: *treadmill,
            feet: foot_setups,
            chain,
            pelvis,
            total_mass_kg,
            carried_kg: carried,
            standing_z_m: pelvis_at[2],
            fore_aft_at_m,
            fore_aft_stops_m,
        }));
        Ok(exo)
    }

    /// Makes the virtual other leg hold `pose` (rad; `None`: walk its reference again), as
    /// this leg holds one for a static check. Does nothing without one.
    pub fn hold_other_leg(&mut self, pose: Option<[f64; 2]>) {
        if let Some(g) = &mut self.ground {
            g.hold_other_leg(pose);
        }
    }

    /// Brings the belt up to speed over `ramp_s` (the gait's start-up). Does nothing
    /// without a treadmill.
    pub fn ramp_belt(&mut self, ramp_s: f64) {
        if let Some(g) = &mut self.ground {
            g.set_belt_ramp(ramp_s);
        }
    }

    /// Runs the belt at `gait`'s own speed (see [`crate::ground::reference_belt_speed`]).
    /// Does nothing without a treadmill.
    pub fn belt_at_reference_speed(&mut self, gait: &GaitReference) {
        if let Some(g) = &mut self.ground {
            let v = crate::ground::reference_belt_speed(gait, g.chain());
            g.set_belt_speed(v);
        }
    }

    /// Puts the virtual other leg under the pelvis of a one-leg trainer, walking `gait`
    /// half a stride later (see [`crate::ground::Contralateral::Reference`]). Does nothing
    /// without a treadmill.
    pub fn add_other_leg(&mut self, gait: GaitReference) {
        if let Some(g) = &mut self.ground {
            let other = OtherLeg::new(gait, g.chain().clone());
            g.set_other_leg(other);
        }
    }

    /// Lowers (or raises) the pelvis, at rest, to where the belt carries the unsupported
    /// weight: every foot's spheres (and the virtual other leg's, standing where its
    /// reference starts) pressed into the belt by their static Hunt-Crossley penetration.
    /// A run then starts from a standing equilibrium instead of a drop. Does nothing
    /// without a treadmill.
    pub fn rest_on_belt(&mut self) {
        let Some(g) = &self.ground else {
            return;
        };
        let params = g.settings().contact;
        let weight = g.unsupported_weight_n();
        let mut gaps: Vec<(f64, f64)> = Vec::new();
        for foot in g.feet() {
            for s in &foot.spheres {
                if let Some(c) = self.point_in_world(&foot.link, s.center_m) {
                    gaps.push((s.radius_m, c[2] - s.radius_m));
                }
            }
        }
        if let (Some(other), Some(z)) = (g.other_leg_pose(), self.pelvis_height_m()) {
            let chain = g.chain();
            for (i, s) in chain.spheres.iter().enumerate() {
                gaps.push((
                    s.radius_m,
                    z + chain.sphere_centre(i, [other[0], other[1], 0.0])[1] - s.radius_m,
                ));
            }
        }
        let load = |dz: f64| -> f64 {
            gaps.iter()
                .map(|&(r, gap)| params.normal_force(r, -(gap + dz), 0.0))
                .sum()
        };
        // The load grows as the pelvis sinks: bisect on the drop.
        let (mut lo, mut hi) = (-0.2, 0.2);
        if load(lo) < weight {
            return;
        }
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if load(mid) > weight {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        self.lift_pelvis(0.5 * (lo + hi));
    }

    fn build(
        raw: &urdf_rs::Robot,
        file: &str,
        prefixes: &[String],
        period_s: f64,
        substeps: u32,
        mount: Mount,
    ) -> Result<Self, LegError> {
        let robot = UrdfRobot::from_robot(raw, loader_options(mount), Path::new("."));
        let inertia = leg_inertia(raw, file, &prefixes[0], mount.pelvis_pitch_rad)?;
        // Which URDF joint and link each rapier element came from, before `robot` moves.
        let joint_names: Vec<String> = robot
            .joints
            .iter()
            .map(|j| raw.joints[j.urdf_joint_index].name.clone())
            .collect();
        let joint_axes: Vec<Vector> = robot
            .joints
            .iter()
            .map(|j| j.joint.local_frame2.rotation * Vector::X)
            .collect();
        let link_names: Vec<String> = robot
            .links
            .iter()
            .map(|l| raw.links[l.urdf_link_index].name.clone())
            .collect();
        let visuals: Vec<Vec<VisualShape>> = robot
            .links
            .iter()
            .map(|l| visuals_of(&raw.links[l.urdf_link_index]))
            .collect();

        let mut world = physics_world(period_s, substeps);
        let handles = robot.insert_using_multibody_joints(
            &mut world.bodies,
            &mut world.colliders,
            &mut world.multibody_joints,
            UrdfMultibodyOptions::DISABLE_SELF_CONTACTS,
        );
        let bodies: Vec<(String, RigidBodyHandle)> = link_names
            .into_iter()
            .zip(handles.links.iter().map(|l| l.body))
            .collect();
        // Settle the fixed root before reading DOF indices: until then the multibody may
        // still count a free root's six DOFs.
        for h in handles.joints.iter().filter_map(|j| j.joint) {
            if let Some((mb, _)) = world.multibody_joints.get_mut(h) {
                mb.forward_kinematics(&world.bodies, true);
            }
        }
        let joint_ref = |name: &str| -> Result<Option<JointRef>, LegError> {
            let Some(i) = joint_names.iter().position(|n| n == name) else {
                return Ok(None);
            };
            let h = &handles.joints[i];
            let Some(handle) = h.joint else {
                // A fixed joint (an ankle without a hinge) is no degree of freedom.
                return Ok(None);
            };
            let (mb, link_id) = world
                .multibody_joints
                .get(handle)
                .ok_or_else(|| urdf_err(file, format!("joint `{name}` is not in a multibody")))?;
            let link = mb
                .link(link_id)
                .ok_or_else(|| urdf_err(file, format!("joint `{name}` has no link")))?;
            match link.joint().ndofs() {
                0 => Ok(None),
                1 => Ok(Some(JointRef {
                    handle,
                    parent: h.link1,
                    child: h.link2,
                    dof: link.assembly_id(),
                    axis_in_child: joint_axes[i],
                })),
                _ => Err(urdf_err(file, format!("joint `{name}` must be revolute"))),
            }
        };
        let mut legs = Vec::with_capacity(prefixes.len());
        for prefix in prefixes {
            let actuated = |n: &str| {
                let name = format!("{prefix}{n}");
                joint_ref(&name)?.ok_or_else(|| {
                    urdf_err(file, format!("joint `{name}` must be a revolute joint"))
                })
            };
            legs.push(LegJoints {
                prefix: prefix.clone(),
                joints: [actuated("hip")?, actuated("knee")?],
                ankle: joint_ref(&format!("{prefix}ankle"))?,
                limits_rad: [[f64::NEG_INFINITY, f64::INFINITY]; 2],
            });
        }
        let mut exo = Self {
            world,
            legs,
            bodies,
            visuals,
            inertia,
            substeps,
            ankle: None,
            ankle_torque_nm: [0.0; MAX_LEGS],
            ground: None,
        };
        for leg in 0..exo.legs.len() {
            let joints = exo.legs[leg].joints;
            let limits = joints.map(|j| exo.read_limits(j));
            exo.legs[leg].limits_rad = limits;
        }
        Ok(exo)
    }

    fn body(&self, name: &str) -> Option<RigidBodyHandle> {
        self.bodies.iter().find(|(n, _)| n == name).map(|(_, h)| *h)
    }

    fn with_joint(&mut self, j: JointRef, f: impl FnOnce(&mut rapier3d::dynamics::MultibodyJoint)) {
        if let Some((mb, id)) = self.world.multibody_joints.get_mut(j.handle) {
            if let Some(link) = mb.link_mut(id) {
                f(&mut link.joint);
            }
        }
    }

    fn read_limits(&self, j: JointRef) -> [f64; 2] {
        self.world
            .multibody_joints
            .get(j.handle)
            .and_then(|(mb, id)| mb.link(id))
            .and_then(|l| l.joint().data.limits(JointAxis::AngX).copied())
            .map_or([f64::NEG_INFINITY, f64::INFINITY], |l| [l.min, l.max])
    }

    fn set_limits(&mut self, leg: usize, k: usize, [lo, hi]: [f64; 2]) {
        let j = self.legs[leg].joints[k];
        self.with_joint(j, |j| {
            j.data.set_limits(JointAxis::AngX, [lo, hi]);
        });
        self.legs[leg].limits_rad[k] = [lo, hi];
    }

    /// Puts the ankle's stops at `[lo, hi]` (rad) and frees it of rapier's damping and
    /// friction: the orthosis alone acts on it.
    fn set_ankle_range(&mut self, leg: usize, [lo, hi]: [f64; 2]) {
        let Some(a) = self.legs[leg].ankle else {
            return;
        };
        self.with_joint(a, |j| {
            j.data.set_limits(JointAxis::AngX, [lo, hi]);
        });
        if let Some((mb, _)) = self.world.multibody_joints.get_mut(a.handle) {
            mb.damping_mut()[a.dof] = 0.0;
            mb.frictions_mut()[a.dof] = 0.0;
        }
    }

    /// Number of legs.
    pub fn leg_count(&self) -> usize {
        self.legs.len()
    }

    /// Leg `leg`'s joints in the multibody.
    pub fn leg(&self, leg: usize) -> &LegJoints {
        &self.legs[leg]
    }

    /// Leg `leg`'s joints' `[lower, upper]` limits (rad), as rapier enforces them.
    pub fn limits_rad(&self, leg: usize) -> [[f64; 2]; 2] {
        self.legs[leg].limits_rad
    }

    /// Holds joint `k` (0 hip, 1 knee) of leg `leg` still at `angle_rad`, as a seat holds
    /// the thigh: both of its limits at that angle. (A kinematic multibody joint would do
    /// it too, but rapier 0.36 then solves the other joint's limit with the wrong
    /// dimension and panics.)
    pub fn hold(&mut self, leg: usize, k: usize, angle_rad: f64) {
        self.set_limits(leg, k, [angle_rad, angle_rad]);
        // The hold is a constraint the solver works on every substep; with one iteration
        // it bleeds ~1 % of the swing's energy per second (measured: 2.1 % over 2 s at 1,
        // 0.52 % at 4, 0.26 % at 8 iterations), so a held leg gets eight.
        self.world.integration_parameters.num_solver_iterations = HOLD_SOLVER_ITERATIONS;
    }

    /// Sets every leg's hip and knee viscous damping and Coulomb friction, replacing
    /// rapier's default damping (0.1 N m s/rad per angular DOF).
    pub fn set_joint_dynamics(&mut self, settings: [JointSettings; 2]) {
        for leg in &self.legs {
            for (j, s) in leg.joints.iter().zip(settings) {
                if let Some((mb, _)) = self.world.multibody_joints.get_mut(j.handle) {
                    mb.damping_mut()[j.dof] = s.damping_nm_s_per_rad;
                    mb.frictions_mut()[j.dof] = s.friction_nm;
                }
            }
        }
    }

    /// Inertia data of a leg read from the URDF (every leg is the same).
    pub fn inertia(&self) -> &LegInertia {
        &self.inertia
    }

    fn coordinate(&self, j: JointRef) -> f64 {
        self.world
            .multibody_joints
            .get(j.handle)
            .and_then(|(mb, id)| mb.link(id).map(|l| l.joint().coords()[3]))
            .unwrap_or(f64::NAN)
    }

    fn rate(&self, j: JointRef) -> f64 {
        self.world
            .multibody_joints
            .get(j.handle)
            .map(|(mb, _)| mb.generalized_velocity()[j.dof])
            .unwrap_or(f64::NAN)
    }

    /// Joint `j`'s coordinate (rad) and rate (rad/s) from one lookup of its multibody:
    /// the muscles and the orthoses read both at every substep.
    fn coordinate_and_rate(&self, j: JointRef) -> (f64, f64) {
        match self.world.multibody_joints.get(j.handle) {
            Some((mb, id)) => (
                mb.link(id).map_or(f64::NAN, |l| l.joint().coords()[3]),
                mb.generalized_velocity()[j.dof],
            ),
            None => (f64::NAN, f64::NAN),
        }
    }

    /// Leg `leg`'s joint angles and velocities: [`Exoskeleton::angles`] and
    /// [`Exoskeleton::velocities`] in one reading.
    pub fn angles_and_velocities(&self, leg: usize) -> ([f64; 2], [f64; 2]) {
        let [(q0, v0), (q1, v1)] = self.legs[leg].joints.map(|j| self.coordinate_and_rate(j));
        ([q0, q1], [v0, v1])
    }

    /// Leg `leg`'s joint angles `[hip, knee]` (rad, flexion positive).
    pub fn angles(&self, leg: usize) -> [f64; 2] {
        self.legs[leg].joints.map(|j| self.coordinate(j))
    }

    /// Leg `leg`'s joint velocities `[hip, knee]` (rad/s).
    pub fn velocities(&self, leg: usize) -> [f64; 2] {
        self.legs[leg].joints.map(|j| self.rate(j))
    }

    /// Every leg's joint angles (rad).
    pub fn all_angles(&self) -> PerLeg<[f64; 2]> {
        PerLeg::from_fn(self.legs.len(), |leg| self.angles(leg))
    }

    /// Leg `leg`'s ankle angle and rate (rad, rad/s; dorsiflexion positive), if its ankle
    /// turns.
    pub fn ankle(&self, leg: usize) -> Option<(f64, f64)> {
        let a = self.legs[leg].ankle?;
        Some(self.coordinate_and_rate(a))
    }

    /// The orthosis's torque on leg `leg`'s ankle at the last substep (N m, dorsiflexion
    /// positive; 0 without one).
    pub fn ankle_torque_nm(&self, leg: usize) -> f64 {
        self.ankle_torque_nm[leg]
    }

    /// Puts leg `leg` at `angles` (rad) with `velocities` (rad/s).
    pub fn set_state(&mut self, leg: usize, angles: [f64; 2], velocities: [f64; 2]) {
        let current = self.angles(leg);
        let dofs = self.legs[leg].joints.map(|j| j.dof);
        self.edit_multibody(|mb, disp| {
            for k in 0..2 {
                disp[dofs[k]] = angles[k] - current[k];
                mb.generalized_velocity_mut()[dofs[k]] = velocities[k];
            }
        });
    }

    /// Puts every leg where an in-step `gait` (the first leg's reference) starts, at rest:
    /// the gait's double-support posture, each turning ankle at the reference's angle
    /// within its stops. A standing start leaves the legs straight, as built.
    pub fn take_start_pose(&mut self, gait: &GaitReference) {
        if gait.start_up() == StartUp::Standing {
            return;
        }
        for leg in 0..self.legs.len() {
            let start = gait.for_leg(leg).sample(0.0);
            self.set_state(leg, [start.hip.angle_rad, start.knee.angle_rad], [0.0; 2]);
            let Some(a) = self.legs[leg].ankle else {
                continue;
            };
            let [lo, hi] = self.read_limits(a);
            let to = start.ankle.angle_rad.clamp(lo, hi);
            let from = self.coordinate(a);
            self.edit_multibody(|mb, disp| {
                disp[a.dof] = to - from;
                mb.generalized_velocity_mut()[a.dof] = 0.0;
            });
        }
    }

    /// Moves the multibody by the displacements `edit` writes (one per DOF; it may also set
    /// velocities), then puts its bodies where the new coordinates say.
    fn edit_multibody(&mut self, edit: impl FnOnce(&mut Multibody, &mut [Real])) {
        let handle = self.legs[0].joints[0].handle;
        if let Some((mb, _)) = self.world.multibody_joints.get_mut(handle) {
            let mut disp: Vec<Real> = vec![0.0; mb.ndofs()];
            edit(mb, &mut disp);
            mb.apply_displacements(&disp);
            mb.forward_kinematics(&self.world.bodies, false);
            mb.update_rigid_bodies(&mut self.world.bodies, true);
        }
    }

    /// Adds `torque_nm` about joint `j`'s axis to its child and the reaction to its parent.
    fn add_joint_torque(&mut self, j: JointRef, torque_nm: f64) {
        // One lookup of the child for both its axis and its torque: it runs at every
        // substep for every joint.
        let Some(rb) = self.world.bodies.get_mut(j.child) else {
            return;
        };
        let t = (rb.position().rotation * j.axis_in_child) * torque_nm;
        rb.add_torque(t, true);
        if let Some(rb) = self.world.bodies.get_mut(j.parent) {
            rb.add_torque(-t, true);
        }
    }

    /// Advances one control period with each leg's joint torques `[hip, knee]` (N m,
    /// flexion positive); `torques_at` gives them for each physics substep from the state
    /// at its start (the muscles' forces depend on it). The ankles' orthoses and the
    /// treadmill act every substep.
    pub fn step(&mut self, mut torques_at: impl FnMut(&Self, usize) -> PerLeg<[f64; 2]>) {
        for sub in 0..self.substeps as usize {
            let torques = torques_at(self, sub);
            // rapier keeps user forces and torques until they are reset: every body starts
            // the substep with none, then takes the joints' and the ground's.
            for (_, b) in &self.bodies {
                if let Some(rb) = self.world.bodies.get_mut(*b) {
                    rb.reset_forces(false);
                    rb.reset_torques(false);
                }
            }
            for (leg, tau) in torques.iter().enumerate().take(self.legs.len()) {
                let joints = self.legs[leg].joints;
                for (j, t) in joints.iter().zip(tau) {
                    self.add_joint_torque(*j, *t);
                }
            }
            self.apply_orthoses();
            if let Some(ground) = &mut self.ground {
                let h = self.world.integration_parameters.dt;
                ground.apply(&mut self.world.bodies, h);
            }
            self.world.step();
        }
        if let Some(ground) = &mut self.ground {
            ground.end_period();
        }
    }

    /// Each turning ankle's orthosis torque for this substep, from its state at the start.
    fn apply_orthoses(&mut self) {
        let Some(afo) = self.ankle else {
            return;
        };
        for leg in 0..self.legs.len() {
            let (Some(j), Some((angle, rate))) = (self.legs[leg].ankle, self.ankle(leg)) else {
                continue;
            };
            let tau = afo.torque_nm(angle, rate);
            self.ankle_torque_nm[leg] = tau;
            self.add_joint_torque(j, tau);
        }
    }

    /// What the belt did to each foot over the last period, on a treadmill.
    pub fn ground_reaction(&self) -> Option<GroundReaction> {
        self.ground.as_ref().map(Ground::reaction)
    }

    /// The treadmill's settings and the masses it put on the pelvis, on a treadmill.
    pub fn ground(&self) -> Option<&Ground> {
        self.ground.as_ref()
    }

    /// Raises the pelvis by `dz_m` on its slide (a drop test starts above the belt), at rest.
    /// Does nothing without a treadmill.
    pub fn lift_pelvis(&mut self, dz_m: f64) {
        let Some(pelvis) = self.ground.as_ref().map(Ground::pelvis) else {
            return;
        };
        let Some(link) = self
            .world
            .multibody_joints
            .rigid_body_link(pelvis)
            .map(|l| l.id)
        else {
            return;
        };
        self.edit_multibody(|mb, disp| {
            if let Some(dof) = mb.link(link).map(|l| l.assembly_id()) {
                disp[dof] = dz_m;
            }
        });
    }

    /// Position of the pelvis frame `[fore-aft, height above the belt]` (m), on a treadmill.
    pub fn pelvis_position_m(&self) -> Option<[f64; 2]> {
        let g = self.ground.as_ref()?;
        let rb = self.world.bodies.get(g.pelvis())?;
        let t = rb.translation();
        Some([t.x, t.z])
    }

    /// Velocity of the pelvis frame `[fore-aft, up]` (m/s), on a treadmill.
    pub fn pelvis_velocity_m_s(&self) -> Option<[f64; 2]> {
        let g = self.ground.as_ref()?;
        let v = self.world.bodies.get(g.pelvis())?.linvel();
        Some([v.x, v.z])
    }

    /// Height of the pelvis frame above the belt (m), on a treadmill.
    pub fn pelvis_height_m(&self) -> Option<f64> {
        self.pelvis_position_m().map(|p| p[1])
    }

    /// Physics substeps per period.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Length of one physics substep (s).
    pub fn substep_s(&self) -> f64 {
        self.world.integration_parameters.dt
    }

    /// Mechanical energy of the (first) leg on a fixed pelvis (J) at its current state,
    /// from the URDF's inertial data (see [`LegInertia::energy`]).
    pub fn energy(&self) -> f64 {
        self.inertia.energy(self.angles(0), self.velocities(0))
    }

    /// Names of the links, in the order of [`Exoskeleton::link_pose`] and
    /// [`Exoskeleton::visuals`].
    pub fn link_names(&self) -> impl Iterator<Item = &str> {
        self.bodies.iter().map(|(n, _)| n.as_str())
    }

    /// Number of links (of [`Exoskeleton::link_pose`]).
    pub fn link_count(&self) -> usize {
        self.bodies.len()
    }

    /// The URDF's visual shapes of link `i`.
    pub fn visuals(&self, i: usize) -> &[VisualShape] {
        self.visuals.get(i).map_or(&[], |v| v.as_slice())
    }

    /// World pose of link `i`: translation (m) and quaternion `[x, y, z, w]`.
    pub fn link_pose(&self, i: usize) -> ([f64; 3], [f64; 4]) {
        match self
            .bodies
            .get(i)
            .and_then(|(_, h)| self.world.bodies.get(*h))
        {
            Some(rb) => {
                let p = rb.position();
                let (t, r) = (p.translation, p.rotation);
                ([t.x, t.y, t.z], [r.x, r.y, r.z, r.w])
            }
            None => ([f64::NAN; 3], [0.0, 0.0, 0.0, 1.0]),
        }
    }

    /// A point given in link `name`'s frame, in world coordinates (m).
    pub fn point_in_world(&self, name: &str, local: [f64; 3]) -> Option<[f64; 3]> {
        let rb = self.world.bodies.get(self.body(name)?)?;
        let p = rb
            .position()
            .transform_point(Vector::new(local[0], local[1], local[2]));
        Some([p.x, p.y, p.z])
    }

    /// World pose of every link: name, translation (m) and rotation quaternion `[x, y, z, w]`.
    pub fn link_poses(&self) -> Vec<(String, [f64; 3], [f64; 4])> {
        (0..self.bodies.len())
            .map(|i| {
                let (t, q) = self.link_pose(i);
                (self.bodies[i].0.clone(), t, q)
            })
            .collect()
    }
}

/// How the URDF is loaded: the leg pitched with the pelvis, its root fixed, no colliders,
/// bodies that never sleep.
fn loader_options(mount: Mount) -> UrdfLoaderOptions {
    UrdfLoaderOptions {
        // Pitching the fixed root pitches the whole leg about the hip axis (the URDF's
        // hip lies on the pelvis frame's Y axis), flexion-wise for a positive angle.
        shift: Pose::from_rotation(Rotation::from_axis_angle(
            -Vector::Y,
            mount.pelvis_pitch_rad,
        )),
        make_roots_fixed: true,
        // Nothing touches the leg through rapier (the feet's contacts are computed
        // here) and self-contacts are off, so colliders would only cost broad- and
        // narrow-phase work (~10 % of a step). Mass properties come from the URDF's
        // <inertial> tags, not from colliders.
        create_colliders_from_collision_shapes: false,
        // A resting leg must still react to the muscles' torques at once.
        rigid_body_blueprint: RigidBodyBuilder::dynamic().can_sleep(false),
        ..Default::default()
    }
}

/// The physics world of a leg stepped every `period_s` in `substeps`: gravity down, one
/// solver iteration a substep.
fn physics_world(period_s: f64, substeps: u32) -> PhysicsWorld {
    let mut world = PhysicsWorld {
        gravity: Vector::new(0.0, 0.0, -G),
        ..Default::default()
    };
    world.integration_parameters.dt = period_s / f64::from(substeps);
    // rapier's default of 4 solver iterations substeps internally and recomputes the
    // multibody dynamics each time; the leg's only constraints are its joint limits,
    // so one iteration per (explicit) substep is enough and 4x cheaper.
    world.integration_parameters.num_solver_iterations = 1;
    world
}

#[cfg(test)]
mod tests;
