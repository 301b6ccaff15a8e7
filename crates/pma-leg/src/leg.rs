//! The exoskeleton leg as a rapier multibody loaded from URDF.
use crate::config::JointSettings;
use crate::error::{one_line, LegError};
use rapier3d::prelude::*;
use rapier3d_urdf::{urdf_rs, UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};
use std::path::Path;

/// Standard gravity (m/s^2), the same as the muscle bench's.
const G: f64 = pma_model::GRAVITY_M_S2;

/// Names of the two joints the leg needs, in index order.
pub const JOINT_NAMES: [&str; 2] = ["hip", "knee"];

/// One actuated joint: where to read it and where to apply its torque.
#[derive(Debug, Clone, Copy)]
struct JointRef {
    handle: MultibodyJointHandle,
    parent: RigidBodyHandle,
    child: RigidBodyHandle,
    dof: usize,
    /// Joint axis in the child body's frame.
    axis_in_child: Vector,
}

/// Link inertia data read from the URDF (for the controllers' nominal models).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertia {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Distance of the centre of mass below the proximal joint (m).
    pub com_below_joint_m: f64,
    /// Inertia about the centre of mass around the flexion axis (kg m^2).
    pub inertia_kg_m2: f64,
}

/// Geometry the nominal models and the hand checks need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegInertia {
    /// Thigh.
    pub thigh: LinkInertia,
    /// Shank (with foot).
    pub shank: LinkInertia,
    /// Hip-to-knee distance (m).
    pub thigh_length_m: f64,
}

impl LegInertia {
    /// Inertia about the knee of the shank (kg m^2).
    pub fn knee_inertia(&self) -> f64 {
        let s = &self.shank;
        s.inertia_kg_m2 + s.mass_kg * s.com_below_joint_m.powi(2)
    }

    /// Inertia about the hip of the straight leg (kg m^2).
    pub fn hip_inertia(&self) -> f64 {
        let (t, s) = (&self.thigh, &self.shank);
        t.inertia_kg_m2
            + t.mass_kg * t.com_below_joint_m.powi(2)
            + s.inertia_kg_m2
            + s.mass_kg * (self.thigh_length_m + s.com_below_joint_m).powi(2)
    }

    /// Kinetic plus gravitational potential energy (J) of thigh and shank at flexion
    /// angles `q` (rad) and rates `qd` (rad/s), potential measured from the hip height.
    pub fn energy(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        let (t, s, l) = (&self.thigh, &self.shank, self.thigh_length_m);
        let (h, k, hd, kd) = (q[0], q[1], qd[0], qd[1]);
        let (phi, phid) = (h - k, hd - kd);
        let thigh_ke = 0.5 * (t.inertia_kg_m2 + t.mass_kg * t.com_below_joint_m.powi(2)) * hd * hd;
        let vx = l * h.cos() * hd + s.com_below_joint_m * phi.cos() * phid;
        let vz = l * h.sin() * hd + s.com_below_joint_m * phi.sin() * phid;
        let shank_ke = 0.5 * s.mass_kg * (vx * vx + vz * vz) + 0.5 * s.inertia_kg_m2 * phid * phid;
        let pe = -G
            * (t.mass_kg * t.com_below_joint_m * h.cos()
                + s.mass_kg * (l * h.cos() + s.com_below_joint_m * phi.cos()));
        thigh_ke + shank_ke + pe
    }

    /// Gravity torques (N m, flexion positive) at hip and knee flexion `(h, k)` (rad).
    pub fn gravity_torques(&self, h: f64, k: f64) -> [f64; 2] {
        let (t, s) = (&self.thigh, &self.shank);
        let shank_angle = h - k;
        let hip = -G
            * (t.mass_kg * t.com_below_joint_m * h.sin()
                + s.mass_kg
                    * (self.thigh_length_m * h.sin() + s.com_below_joint_m * shank_angle.sin()));
        let knee = G * s.mass_kg * s.com_below_joint_m * shank_angle.sin();
        [hip, knee]
    }
}

/// A visual shape of a link from the URDF, in the link's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VisualShape {
    /// Cylinder along the link's Z axis.
    Cylinder {
        /// Centre (m).
        center: [f64; 3],
        /// Radius (m).
        radius: f64,
        /// Length (m).
        length: f64,
    },
    /// Box.
    Box {
        /// Centre (m).
        center: [f64; 3],
        /// Edge lengths (m).
        size: [f64; 3],
    },
}

fn visuals_of(link: &urdf_rs::Link) -> Vec<VisualShape> {
    link.visual
        .iter()
        .filter_map(|v| {
            let c = v.origin.xyz;
            let center = [c[0], c[1], c[2]];
            match &v.geometry {
                urdf_rs::Geometry::Cylinder { radius, length } => Some(VisualShape::Cylinder {
                    center,
                    radius: *radius,
                    length: *length,
                }),
                urdf_rs::Geometry::Box { size } => Some(VisualShape::Box {
                    center,
                    size: [size[0], size[1], size[2]],
                }),
                _ => None,
            }
        })
        .collect()
}

/// The leg: a rapier world with the multibody, its two joints and the gravity along -Z.
pub struct Leg {
    world: PhysicsWorld,
    joints: [JointRef; 2],
    bodies: Vec<(String, RigidBodyHandle)>,
    visuals: Vec<Vec<VisualShape>>,
    inertia: LegInertia,
    substeps: u32,
}

fn urdf_err(file: &str, message: impl Into<String>) -> LegError {
    LegError::Urdf {
        file: file.to_owned(),
        message: message.into(),
    }
}

fn link_inertia(robot: &urdf_rs::Robot, name: &str, file: &str) -> Result<LinkInertia, LegError> {
    let link = robot
        .links
        .iter()
        .find(|l| l.name == name)
        .ok_or_else(|| urdf_err(file, format!("no link named `{name}`")))?;
    let i = &link.inertial;
    Ok(LinkInertia {
        mass_kg: i.mass.value,
        com_below_joint_m: -i.origin.xyz[2],
        inertia_kg_m2: i.inertia.iyy,
    })
}

impl Leg {
    /// Loads the URDF (text; `file` names it in errors) with the pelvis fixed, sets each
    /// joint's damping and friction explicitly, Z up, and `substeps` physics steps of
    /// `period_s / substeps` per [`Leg::step`].
    pub fn from_urdf_str(
        text: &str,
        file: &str,
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
    ) -> Result<Self, LegError> {
        let options = UrdfLoaderOptions {
            make_roots_fixed: true,
            // Nothing touches the leg (fixed pelvis, no ground) and self-contacts are off,
            // so colliders would only cost broad- and narrow-phase work (~10 % of a step).
            // Mass properties come from the URDF's <inertial> tags, not from colliders.
            create_colliders_from_collision_shapes: false,
            // A resting leg must still react to the muscles' torques at once.
            rigid_body_blueprint: RigidBodyBuilder::dynamic().can_sleep(false),
            ..Default::default()
        };
        let (robot, raw) = UrdfRobot::from_str(text, options, Path::new("."))
            .map_err(|e| urdf_err(file, one_line(&format!("{e:#}"))))?;
        let inertia = LegInertia {
            thigh: link_inertia(&raw, "thigh", file)?,
            shank: link_inertia(&raw, "shank", file)?,
            thigh_length_m: {
                let knee = raw
                    .joints
                    .iter()
                    .find(|j| j.name == "knee")
                    .ok_or_else(|| urdf_err(file, "no joint named `knee`"))?;
                -knee.origin.xyz[2]
            },
        };
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

        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, 0.0, -G as Real),
            ..Default::default()
        };
        world.integration_parameters.dt = (period_s / f64::from(substeps)) as Real;
        // rapier's default of 4 solver iterations substeps internally and recomputes the
        // multibody dynamics each time; the leg's only constraints are its two joint
        // limits, so one iteration per (explicit) substep is enough and 4x cheaper.
        world.integration_parameters.num_solver_iterations = 1;
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
        let mut refs = Vec::with_capacity(2);
        for name in JOINT_NAMES {
            let i = joint_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| urdf_err(file, format!("no joint named `{name}`")))?;
            let h = &handles.joints[i];
            let handle = h
                .joint
                .ok_or_else(|| urdf_err(file, format!("joint `{name}` could not be created")))?;
            let (mb, link_id) = world
                .multibody_joints
                .get(handle)
                .ok_or_else(|| urdf_err(file, format!("joint `{name}` is not in a multibody")))?;
            let link = mb
                .link(link_id)
                .ok_or_else(|| urdf_err(file, format!("joint `{name}` has no link")))?;
            if link.joint().ndofs() != 1 {
                return Err(urdf_err(file, format!("joint `{name}` must be revolute")));
            }
            refs.push(JointRef {
                handle,
                parent: h.link1,
                child: h.link2,
                dof: link.assembly_id(),
                axis_in_child: joint_axes[i],
            });
        }
        let mut leg = Self {
            world,
            joints: [refs[0], refs[1]],
            bodies,
            visuals,
            inertia,
            substeps,
        };
        leg.set_joint_dynamics(settings);
        Ok(leg)
    }

    /// Sets each joint's viscous damping and Coulomb friction, replacing rapier's default
    /// damping (0.1 N m s/rad per angular DOF).
    pub fn set_joint_dynamics(&mut self, settings: [JointSettings; 2]) {
        for (j, s) in self.joints.iter().zip(settings) {
            if let Some((mb, _)) = self.world.multibody_joints.get_mut(j.handle) {
                mb.damping_mut()[j.dof] = s.damping_nm_s_per_rad as Real;
                mb.frictions_mut()[j.dof] = s.friction_nm as Real;
            }
        }
    }

    /// Inertia data read from the URDF.
    pub fn inertia(&self) -> &LegInertia {
        &self.inertia
    }

    /// Joint angles `[hip, knee]` (rad, flexion positive).
    pub fn angles(&self) -> [f64; 2] {
        self.joints.map(|j| {
            self.world
                .multibody_joints
                .get(j.handle)
                .and_then(|(mb, id)| mb.link(id).map(|l| f64::from(l.joint().coords()[3])))
                .unwrap_or(f64::NAN)
        })
    }

    /// Joint velocities `[hip, knee]` (rad/s).
    pub fn velocities(&self) -> [f64; 2] {
        self.joints.map(|j| {
            self.world
                .multibody_joints
                .get(j.handle)
                .map(|(mb, _)| f64::from(mb.generalized_velocity()[j.dof]))
                .unwrap_or(f64::NAN)
        })
    }

    /// Puts the leg at `angles` (rad) with `velocities` (rad/s).
    pub fn set_state(&mut self, angles: [f64; 2], velocities: [f64; 2]) {
        let current = self.angles();
        let handle = self.joints[0].handle;
        let dofs = self.joints.map(|j| j.dof);
        if let Some((mb, _)) = self.world.multibody_joints.get_mut(handle) {
            let mut disp: Vec<Real> = vec![0.0; mb.ndofs()];
            for k in 0..2 {
                disp[dofs[k]] = (angles[k] - current[k]) as Real;
            }
            mb.apply_displacements(&disp);
            for k in 0..2 {
                mb.generalized_velocity_mut()[dofs[k]] = velocities[k] as Real;
            }
            mb.forward_kinematics(&self.world.bodies, false);
            mb.update_rigid_bodies(&mut self.world.bodies, true);
        }
    }

    /// Advances one control period with joint torques `[hip, knee]` (N m, flexion
    /// positive) held; `torques_at` gives them for each physics substep from the state at
    /// its start (the muscles' forces depend on it).
    pub fn step(&mut self, mut torques_at: impl FnMut(&Self, usize) -> [f64; 2]) {
        for sub in 0..self.substeps as usize {
            let torques = torques_at(self, sub);
            for b in [
                self.joints[0].parent,
                self.joints[0].child,
                self.joints[1].child,
            ] {
                if let Some(rb) = self.world.bodies.get_mut(b) {
                    rb.reset_torques(false);
                }
            }
            for (j, tau) in self.joints.iter().zip(torques) {
                let axis = match self.world.bodies.get(j.child) {
                    Some(rb) => rb.position().rotation * j.axis_in_child,
                    None => continue,
                };
                let t = axis * tau as Real;
                if let Some(rb) = self.world.bodies.get_mut(j.child) {
                    rb.add_torque(t, true);
                }
                if let Some(rb) = self.world.bodies.get_mut(j.parent) {
                    rb.add_torque(-t, true);
                }
            }
            self.world.step();
        }
    }

    /// Physics substeps per period.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Length of one physics substep (s).
    pub fn substep_s(&self) -> f64 {
        f64::from(self.world.integration_parameters.dt)
    }

    /// Mechanical energy of the leg (J) at its current state, from the URDF's inertial data
    /// (see [`LegInertia::energy`]).
    pub fn energy(&self) -> f64 {
        self.inertia.energy(self.angles(), self.velocities())
    }

    /// Names of the links, in the order of [`Leg::link_pose`] and [`Leg::visuals`].
    pub fn link_names(&self) -> impl Iterator<Item = &str> {
        self.bodies.iter().map(|(n, _)| n.as_str())
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
                (
                    [f64::from(t.x), f64::from(t.y), f64::from(t.z)],
                    [
                        f64::from(r.x),
                        f64::from(r.y),
                        f64::from(r.z),
                        f64::from(r.w),
                    ],
                )
            }
            None => ([f64::NAN; 3], [0.0, 0.0, 0.0, 1.0]),
        }
    }

    /// A point given in link `name`'s frame, in world coordinates (m).
    pub fn point_in_world(&self, name: &str, local: [f64; 3]) -> Option<[f64; 3]> {
        let (_, h) = self.bodies.iter().find(|(n, _)| n == name)?;
        let rb = self.world.bodies.get(*h)?;
        let p = rb.position().transform_point(Vector::new(
            local[0] as Real,
            local[1] as Real,
            local[2] as Real,
        ));
        Some([f64::from(p.x), f64::from(p.y), f64::from(p.z)])
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::EMBEDDED_URDF;

    fn leg(damping: f64, substeps: u32) -> Leg {
        let j = JointSettings {
            damping_nm_s_per_rad: damping,
            friction_nm: 0.0,
        };
        Leg::from_urdf_str(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, substeps).unwrap()
    }

    #[test]
    fn flexion_is_positive_and_gravity_pulls_the_leg_back() {
        let mut l = leg(0.0, 1);
        l.set_state([0.3, 0.4], [0.0, 0.0]);
        let a = l.angles();
        assert!(
            (a[0] - 0.3).abs() < 1e-5 && (a[1] - 0.4).abs() < 1e-5,
            "{a:?}"
        );
        // Flexed hip: the knee is in front of the hip (+X).
        let knee_x = l.link_poses().iter().find(|p| p.0 == "shank").unwrap().1[0];
        assert!(knee_x > 0.1, "knee at x = {knee_x}");
        l.step(|_, _| [0.0, 0.0]);
        let v = l.velocities();
        assert!(v[0] < 0.0, "hip falls back: {v:?}");
    }

    #[test]
    fn joint_torque_accelerates_in_its_sign() {
        let mut l = leg(0.0, 1);
        l.step(|_, _| [50.0, -20.0]);
        let v = l.velocities();
        assert!(v[0] > 0.0 && v[1] < 0.0, "{v:?}");
    }

    #[test]
    fn gravity_torques_match_the_hand_formula() {
        // Holding torques equal to minus gravity keep the leg still.
        let mut l = leg(0.0, 2);
        let q = [0.35, 0.5];
        l.set_state(q, [0.0, 0.0]);
        let g = l.inertia().gravity_torques(q[0], q[1]);
        for _ in 0..500 {
            l.step(|_, _| [-g[0], -g[1]]);
        }
        let a = l.angles();
        assert!(
            (a[0] - q[0]).abs() < 1e-3 && (a[1] - q[1]).abs() < 1e-3,
            "{a:?}"
        );
    }
}
