//! The exoskeleton leg as a rapier multibody loaded from URDF.
use crate::config::JointSettings;
use crate::error::{one_line, LegError};
use crate::gait::GaitReference;
use crate::ground::{
    FootSphere, Ground, GroundReaction, GroundSetup, OtherLeg, SagittalChain, TreadmillSettings,
};
use rapier3d::prelude::*;
use rapier3d_urdf::{urdf_rs, UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};
use std::path::Path;

/// Standard gravity (m/s^2), the same as the muscle bench's.
const G: f64 = pma_model::GRAVITY_M_S2;

/// Solver iterations of a leg with a held joint (see [`Leg::hold`]).
pub const HOLD_SOLVER_ITERATIONS: usize = 8;

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
    /// Backward pitch of the fixed pelvis (rad, about the hip's flexion axis): 0 standing,
    /// pi/2 for a thigh lying horizontal at zero hip flexion (the seated pendulum test).
    pub pelvis_pitch_rad: f64,
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
        let (h, k, hd, kd) = (q[0] + self.pelvis_pitch_rad, q[1], qd[0], qd[1]);
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
        let h = h + self.pelvis_pitch_rad;
        let shank_angle = h - k;
        let hip = -G
            * (t.mass_kg * t.com_below_joint_m * h.sin()
                + s.mass_kg
                    * (self.thigh_length_m * h.sin() + s.com_below_joint_m * shank_angle.sin()));
        let knee = G * s.mass_kg * s.com_below_joint_m * shank_angle.sin();
        [hip, knee]
    }

    /// Joint torques (N m, flexion positive) that move the rigid leg with accelerations
    /// `qdd` (rad/s^2) at angles `q` (rad) and rates `qd` (rad/s): `M(q) qdd + C(q, qd) qd`
    /// minus gravity, the two-link pendulum's Lagrange equations. In absolute link angles
    /// (thigh `a = h + pitch`, shank `b = a - k`) the mass matrix is `[[A, B cos k], [B cos
    /// k, D]]` with `A = I_t + m_t c_t^2 + m_s l^2`, `B = m_s l c_s`, `D = I_s + m_s c_s^2`;
    /// the joint torques are `tau_hip = Q_a + Q_b` and `tau_knee = -Q_b` (virtual work).
    pub fn inverse_dynamics(&self, q: [f64; 2], qd: [f64; 2], qdd: [f64; 2]) -> [f64; 2] {
        let (t, s, l) = (&self.thigh, &self.shank, self.thigh_length_m);
        let a_coef = t.inertia_kg_m2 + t.mass_kg * t.com_below_joint_m.powi(2) + s.mass_kg * l * l;
        let b_coef = s.mass_kg * l * s.com_below_joint_m;
        let d_coef = self.knee_inertia();
        let k = q[1];
        let (ad, bd) = (qd[0], qd[0] - qd[1]);
        let (add, bdd) = (qdd[0], qdd[0] - qdd[1]);
        let (c, sn) = (k.cos(), k.sin());
        let gravity = self.gravity_torques(q[0], q[1]);
        let q_a = a_coef * add + b_coef * c * bdd + b_coef * sn * bd * bd;
        let q_b = b_coef * c * add + d_coef * bdd - b_coef * sn * ad * ad;
        [q_a + q_b - gravity[0], -q_b - gravity[1]]
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
    limits_rad: [[f64; 2]; 2],
    /// The treadmill, when the leg stands on one.
    ground: Option<Ground>,
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

fn parse_urdf(text: &str, file: &str) -> Result<urdf_rs::Robot, LegError> {
    UrdfRobot::from_str(text, UrdfLoaderOptions::default(), Path::new("."))
        .map(|(_, raw)| raw)
        .map_err(|e| urdf_err(file, one_line(&format!("{e:#}"))))
}

/// The `foot` link's `<collision>` spheres: the treadmill's contact geometry.
fn foot_spheres(raw: &urdf_rs::Robot, file: &str) -> Result<Vec<FootSphere>, LegError> {
    let foot = raw.links.iter().find(|l| l.name == "foot").ok_or_else(|| {
        urdf_err(
            file,
            "no link named `foot`: a treadmill needs a foot (see models/exo_leg_foot.urdf)",
        )
    })?;
    let spheres: Vec<FootSphere> = foot
        .collision
        .iter()
        .filter_map(|c| match c.geometry {
            urdf_rs::Geometry::Sphere { radius } => Some(FootSphere {
                center_m: [c.origin.xyz[0], c.origin.xyz[1], c.origin.xyz[2]],
                radius_m: radius,
            }),
            _ => None,
        })
        .collect();
    if spheres.is_empty()
        || spheres
            .iter()
            .any(|s| s.radius_m.is_nan() || s.radius_m <= 0.0)
    {
        return Err(urdf_err(
            file,
            "the `foot` link needs <collision> spheres of positive radius (its contact points)",
        ));
    }
    Ok(spheres)
}

/// The sagittal chain pelvis -> hip -> knee -> ankle of the URDF, for the virtual other
/// leg: each joint's origin `[x, z]` and the hip's and knee's flexion sense.
fn sagittal_chain(
    raw: &urdf_rs::Robot,
    file: &str,
    spheres: Vec<FootSphere>,
) -> Result<SagittalChain, LegError> {
    let joint = |name: &str| {
        raw.joints
            .iter()
            .find(|j| j.name == name)
            .ok_or_else(|| urdf_err(file, format!("no joint named `{name}`")))
    };
    let (hip, knee, ankle) = (joint("hip")?, joint("knee")?, joint("ankle")?);
    if ankle.joint_type != urdf_rs::JointType::Fixed {
        return Err(urdf_err(
            file,
            "joint `ankle` must be fixed (the treadmill leg has no ankle actuator)",
        ));
    }
    let origin = |j: &urdf_rs::Joint| [j.origin.xyz[0], j.origin.xyz[2]];
    let sense = |j: &urdf_rs::Joint| {
        let y = j.axis.xyz[1];
        if (y.abs() - 1.0).abs() > 1e-9 {
            Err(urdf_err(
                file,
                format!(
                    "joint `{}` must turn about the Y axis (sagittal plane)",
                    j.name
                ),
            ))
        } else {
            Ok(-y)
        }
    };
    // An origin's pitch about +Y is a rotation about -Y by its negative.
    let pitch = |j: &urdf_rs::Joint| -j.origin.rpy[1];
    if [hip, knee, ankle]
        .iter()
        .any(|j| j.origin.rpy[0].abs() > 1e-12 || j.origin.rpy[2].abs() > 1e-12)
    {
        return Err(urdf_err(
            file,
            "the hip, knee and ankle origins may pitch (about Y) but not roll or yaw",
        ));
    }
    Ok(SagittalChain {
        origins_m: [origin(hip), origin(knee), origin(ankle)],
        pitch_rad: [pitch(hip), pitch(knee), pitch(ankle)],
        flexion_sign: [sense(hip)?, sense(knee)?],
        spheres,
    })
}

/// Folds the `foot` link into the shank it is fixed to (an unrotated fixed `ankle`): one
/// rigid body with both masses, the inertia about their common centre (parallel axes),
/// and the foot's shapes moved into the shank's frame. A fixed joint still costs rapier a
/// multibody link (mass matrix, kinematics) every substep; the folded leg moves the same.
/// Returns the ankle's offset in the shank frame (m), or `None` (nothing folded) when the
/// ankle or either inertial frame is rotated.
fn fold_foot_into_shank(raw: &mut urdf_rs::Robot) -> Option<[f64; 3]> {
    let ankle = raw.joints.iter().position(|j| {
        j.name == "ankle"
            && j.joint_type == urdf_rs::JointType::Fixed
            && j.parent.link == "shank"
            && j.child.link == "foot"
    })?;
    let unrotated = |p: &urdf_rs::Pose| p.rpy.iter().all(|a| *a == 0.0);
    let foot_at = raw.links.iter().position(|l| l.name == "foot")?;
    let shank_at = raw.links.iter().position(|l| l.name == "shank")?;
    let (foot, shank) = (&raw.links[foot_at], &raw.links[shank_at]);
    if !unrotated(&raw.joints[ankle].origin)
        || !unrotated(&foot.inertial.origin)
        || !unrotated(&shank.inertial.origin)
    {
        return None;
    }
    let o = *raw.joints[ankle].origin.xyz;
    let body = |l: &urdf_rs::Link, offset: [f64; 3]| {
        let c = l.inertial.origin.xyz;
        let i = &l.inertial.inertia;
        (
            l.inertial.mass.value,
            [c[0] + offset[0], c[1] + offset[1], c[2] + offset[2]],
            [
                [i.ixx, i.ixy, i.ixz],
                [i.ixy, i.iyy, i.iyz],
                [i.ixz, i.iyz, i.izz],
            ],
        )
    };
    let parts = [body(shank, [0.0; 3]), body(foot, o)];
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    let com: [f64; 3] =
        std::array::from_fn(|k| parts.iter().map(|p| p.0 * p.1[k]).sum::<f64>() / mass);
    let mut inertia = [[0.0; 3]; 3];
    for (m, c, i) in parts {
        let d = [c[0] - com[0], c[1] - com[1], c[2] - com[2]];
        let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        for a in 0..3 {
            for b in 0..3 {
                let delta = if a == b { dd } else { 0.0 };
                inertia[a][b] += i[a][b] + m * (delta - d[a] * d[b]);
            }
        }
    }
    let moved = |p: &urdf_rs::Pose| {
        let mut p = p.clone();
        p.xyz = urdf_rs::Vec3([p.xyz[0] + o[0], p.xyz[1] + o[1], p.xyz[2] + o[2]]);
        p
    };
    let foot = raw.links.remove(foot_at);
    let shank = raw.links.iter_mut().find(|l| l.name == "shank")?;
    shank.inertial.mass.value = mass;
    shank.inertial.origin.xyz = urdf_rs::Vec3(com);
    let t = &mut shank.inertial.inertia;
    (t.ixx, t.ixy, t.ixz) = (inertia[0][0], inertia[0][1], inertia[0][2]);
    (t.iyy, t.iyz, t.izz) = (inertia[1][1], inertia[1][2], inertia[2][2]);
    shank.visual.extend(foot.visual.into_iter().map(|mut v| {
        v.origin = moved(&v.origin);
        v
    }));
    shank
        .collision
        .extend(foot.collision.into_iter().map(|mut c| {
            c.origin = moved(&c.origin);
            c
        }));
    raw.joints.remove(ankle);
    Some(o)
}

/// `root` and every link below it, by name.
fn carried_links(raw: &urdf_rs::Robot, root: &str) -> Vec<String> {
    let mut out = vec![root.to_owned()];
    let mut k = 0;
    while k < out.len() {
        let parent = out[k].clone();
        out.extend(
            raw.joints
                .iter()
                .filter(|j| j.parent.link == parent)
                .map(|j| j.child.link.clone()),
        );
        k += 1;
    }
    out
}

/// The hip origin's pitch about +Y (rad; 0 without a `hip` joint).
fn hip_origin_pitch(raw: &urdf_rs::Robot) -> f64 {
    raw.joints
        .iter()
        .find(|j| j.name == "hip")
        .map_or(0.0, |j| j.origin.rpy[1])
}

/// Adds the patient's trunk and other leg (the body mass less this leg's human segments,
/// Winter's fractions thigh 0.100, leg 0.0465, foot 0.0145) to the pelvis link; returns the
/// mass added (kg). The pelvis only slides vertically, so where that mass sits does not
/// matter.
fn patient_on_pelvis(
    raw: &mut urdf_rs::Robot,
    file: &str,
    body_mass_kg: f64,
) -> Result<f64, LegError> {
    if !raw
        .joints
        .iter()
        .any(|j| j.name == "pelvis_z" && j.joint_type == urdf_rs::JointType::Prismatic)
    {
        return Err(urdf_err(
            file,
            "no prismatic joint `pelvis_z`: a treadmill needs the pelvis on a vertical slide",
        ));
    }
    let pelvis = raw
        .links
        .iter_mut()
        .find(|l| l.name == "pelvis")
        .ok_or_else(|| urdf_err(file, "no link named `pelvis`"))?;
    let carried = body_mass_kg * (1.0 - 0.100 - 0.0465 - 0.0145);
    pelvis.inertial.mass.value += carried;
    Ok(carried)
}

/// How the leg is mounted: the treadmill's upright pelvis, or the seat of a pendulum test.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Mount {
    /// Backward pitch of the fixed pelvis about the hip's flexion axis (rad).
    pub pelvis_pitch_rad: f64,
    /// Knee limits replacing the URDF's `[lower, upper]` (rad): the exoskeleton's stop
    /// removed for a test of the limb alone.
    pub knee_limits_rad: Option<[f64; 2]>,
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
        Self::mounted(text, file, settings, period_s, substeps, Mount::default())
    }

    /// As [`Leg::from_urdf_str`], mounted as `mount` says.
    pub fn mounted(
        text: &str,
        file: &str,
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
        mount: Mount,
    ) -> Result<Self, LegError> {
        Self::build(
            &parse_urdf(text, file)?,
            file,
            settings,
            period_s,
            substeps,
            mount,
        )
    }

    /// As [`Leg::from_urdf_str`] for a URDF with the pelvis on a vertical slide
    /// (`pelvis_z`) and a `foot` link whose `<collision>` spheres touch a belt at `z = 0`:
    /// the patient's mass rides on the pelvis, the harness carries `bws_fraction` of the
    /// weight, and the foot's compliant contacts act every substep (see [`crate::ground`]).
    /// The belt runs at `treadmill.speed_m_per_s` (absent: stopped); the other leg is
    /// added by [`Leg::add_other_leg`].
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
        let mut spheres = foot_spheres(&raw, file)?;
        let chain = sagittal_chain(&raw, file, spheres.clone())?;
        let carried = patient_on_pelvis(&mut raw, file, treadmill.body_mass_kg)?;
        let foot_link = match fold_foot_into_shank(&mut raw) {
            Some(o) => {
                for s in &mut spheres {
                    s.center_m = std::array::from_fn(|k| s.center_m[k] + o[k]);
                }
                "shank"
            }
            None => "foot",
        };
        let mut leg = Self::build(&raw, file, settings, period_s, substeps, Mount::default())?;
        let handle = |name: &str| {
            leg.bodies
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, h)| *h)
                .ok_or_else(|| urdf_err(file, format!("no link named `{name}`")))
        };
        let (foot, pelvis) = (handle(foot_link)?, handle("pelvis")?);
        // What the belt and harness carry: the pelvis and everything below it (not the
        // fore-aft trolley above it, which the frame carries).
        let total_mass_kg: f64 = carried_links(&raw, "pelvis")
            .iter()
            .filter_map(|n| raw.links.iter().find(|l| &l.name == n))
            .map(|l| l.inertial.mass.value)
            .sum();
        let fore_aft_at_m = raw
            .joints
            .iter()
            .any(|j| j.name == "pelvis_x" && j.joint_type == urdf_rs::JointType::Prismatic)
            .then(|| {
                leg.world
                    .bodies
                    .get(pelvis)
                    .map_or(0.0, |rb| f64::from(rb.translation().x))
            });
        let standing_z_m = leg
            .world
            .bodies
            .get(pelvis)
            .map_or(0.0, |rb| f64::from(rb.translation().z));
        leg.ground = Some(Ground::new(GroundSetup {
            settings: *treadmill,
            spheres,
            chain,
            foot,
            foot_link,
            pelvis,
            total_mass_kg,
            carried_kg: carried,
            standing_z_m,
            fore_aft_at_m,
        }));
        Ok(leg)
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

    /// Puts the virtual other leg under the pelvis, walking `gait` half a stride later
    /// (see [`crate::ground::Contralateral::Reference`]). Does nothing without a treadmill.
    pub fn add_other_leg(&mut self, gait: GaitReference) {
        if let Some(g) = &mut self.ground {
            let other = OtherLeg::new(gait, g.chain().clone());
            g.set_other_leg(other);
        }
    }

    /// Lowers (or raises) the pelvis, at rest, to where the belt carries the unsupported
    /// weight: the foot's spheres (and the other leg's, standing where its reference
    /// starts) pressed into the belt by their static Hunt-Crossley penetration. A run then
    /// starts from a standing equilibrium instead of a drop. Does nothing without a
    /// treadmill.
    pub fn rest_on_belt(&mut self) {
        let Some(g) = &self.ground else {
            return;
        };
        let params = g.settings().contact;
        let weight = g.unsupported_weight_n();
        let mut gaps: Vec<(f64, f64)> = Vec::new();
        let foot = g.foot_link_name();
        for s in g.spheres() {
            if let Some(c) = self.point_in_world(foot, s.center_m) {
                gaps.push((s.radius_m, c[2] - s.radius_m));
            }
        }
        if let (Some(other), Some(z)) = (g.other_leg_pose(), self.pelvis_height_m()) {
            let chain = g.chain();
            for (i, s) in chain.spheres.iter().enumerate() {
                gaps.push((
                    s.radius_m,
                    z + chain.sphere_centre(i, other)[1] - s.radius_m,
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
        settings: [JointSettings; 2],
        period_s: f64,
        substeps: u32,
        mount: Mount,
    ) -> Result<Self, LegError> {
        let options = UrdfLoaderOptions {
            // Pitching the fixed root pitches the whole leg about the hip axis (the URDF's
            // hip lies on the pelvis frame's Y axis), flexion-wise for a positive angle.
            shift: Pose::from_rotation(Rotation::from_axis_angle(
                -Vector::Y,
                mount.pelvis_pitch_rad as Real,
            )),
            make_roots_fixed: true,
            // Nothing touches the leg (fixed pelvis, no ground) and self-contacts are off,
            // so colliders would only cost broad- and narrow-phase work (~10 % of a step).
            // Mass properties come from the URDF's <inertial> tags, not from colliders.
            create_colliders_from_collision_shapes: false,
            // A resting leg must still react to the muscles' torques at once.
            rigid_body_blueprint: RigidBodyBuilder::dynamic().can_sleep(false),
            ..Default::default()
        };
        let robot = UrdfRobot::from_robot(raw, options, Path::new("."));
        let inertia = LegInertia {
            thigh: link_inertia(raw, "thigh", file)?,
            shank: link_inertia(raw, "shank", file)?,
            thigh_length_m: {
                let knee = raw
                    .joints
                    .iter()
                    .find(|j| j.name == "knee")
                    .ok_or_else(|| urdf_err(file, "no joint named `knee`"))?;
                -knee.origin.xyz[2]
            },
            // The mount's pitch, and the hip origin's (an anteriorly tilted pelvis frame
            // turns the thigh back: a pitch about +Y is one about -Y by its negative).
            pelvis_pitch_rad: mount.pelvis_pitch_rad - hip_origin_pitch(raw),
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
            limits_rad: [[f64::NEG_INFINITY, f64::INFINITY]; 2],
            ground: None,
        };
        if let Some([lo, hi]) = mount.knee_limits_rad {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(urdf_err(
                    file,
                    format!("knee limits [{lo}, {hi}] rad: need finite lower < upper"),
                ));
            }
            leg.with_joint(1, |j| {
                j.data.set_limits(JointAxis::AngX, [lo as Real, hi as Real]);
            });
        }
        leg.limits_rad = [0, 1].map(|k| leg.read_limits(k));
        leg.set_joint_dynamics(settings);
        Ok(leg)
    }

    fn with_joint(&mut self, k: usize, f: impl FnOnce(&mut rapier3d::dynamics::MultibodyJoint)) {
        let j = self.joints[k];
        if let Some((mb, id)) = self.world.multibody_joints.get_mut(j.handle) {
            if let Some(link) = mb.link_mut(id) {
                f(&mut link.joint);
            }
        }
    }

    fn read_limits(&self, k: usize) -> [f64; 2] {
        let j = self.joints[k];
        self.world
            .multibody_joints
            .get(j.handle)
            .and_then(|(mb, id)| mb.link(id))
            .and_then(|l| l.joint().data.limits(JointAxis::AngX).copied())
            .map_or([f64::NEG_INFINITY, f64::INFINITY], |l| {
                [f64::from(l.min), f64::from(l.max)]
            })
    }

    /// Each joint's `[lower, upper]` limit (rad), as rapier enforces them.
    pub fn limits_rad(&self) -> [[f64; 2]; 2] {
        self.limits_rad
    }

    /// Holds joint `k` (0 hip, 1 knee) still at `angle_rad`, as a seat holds the thigh:
    /// both of its limits at that angle. (A kinematic multibody joint would do it too, but
    /// rapier 0.36 then solves the other joint's limit with the wrong dimension and panics.)
    pub fn hold(&mut self, k: usize, angle_rad: f64) {
        self.with_joint(k, |j| {
            j.data
                .set_limits(JointAxis::AngX, [angle_rad as Real, angle_rad as Real]);
        });
        self.limits_rad[k] = [angle_rad, angle_rad];
        // The hold is a constraint the solver works on every substep; with one iteration
        // it bleeds ~1 % of the swing's energy per second (measured: 2.1 % over 2 s at 1,
        // 0.52 % at 4, 0.26 % at 8 iterations), so a held leg gets eight.
        self.world.integration_parameters.num_solver_iterations = HOLD_SOLVER_ITERATIONS;
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
        let dofs = self.joints.map(|j| j.dof);
        self.edit_multibody(|mb, disp| {
            for k in 0..2 {
                disp[dofs[k]] = (angles[k] - current[k]) as Real;
                mb.generalized_velocity_mut()[dofs[k]] = velocities[k] as Real;
            }
        });
    }

    /// Moves the leg's multibody by the displacements `edit` writes (one per DOF; it may
    /// also set velocities), then puts its bodies where the new coordinates say.
    fn edit_multibody(&mut self, edit: impl FnOnce(&mut Multibody, &mut [Real])) {
        let handle = self.joints[0].handle;
        if let Some((mb, _)) = self.world.multibody_joints.get_mut(handle) {
            let mut disp: Vec<Real> = vec![0.0; mb.ndofs()];
            edit(mb, &mut disp);
            mb.apply_displacements(&disp);
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
            // rapier keeps user forces and torques until they are reset: every body starts
            // the substep with none, then takes the joints' and the ground's.
            for (_, b) in &self.bodies {
                if let Some(rb) = self.world.bodies.get_mut(*b) {
                    rb.reset_forces(false);
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
            if let Some(ground) = &mut self.ground {
                let h = f64::from(self.world.integration_parameters.dt);
                ground.apply(&mut self.world.bodies, h);
            }
            self.world.step();
        }
        if let Some(ground) = &mut self.ground {
            ground.end_period();
        }
    }

    /// What the belt did to the foot over the last period, on a treadmill.
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
                disp[dof] = dz_m as Real;
            }
        });
    }

    /// Height of the pelvis frame above the belt (m), on a treadmill.
    pub fn pelvis_height_m(&self) -> Option<f64> {
        let g = self.ground.as_ref()?;
        let rb = self.world.bodies.get(g.pelvis())?;
        Some(f64::from(rb.translation().z))
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

    /// Number of links (of [`Leg::link_pose`]).
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
    fn inverse_dynamics_torques_give_rapier_the_asked_accelerations() {
        // Forward dynamics (rapier) of the inverse dynamics (Lagrange, by hand): at states
        // with large Coriolis and coupling terms, one step under tau = ID(q, qd, qdd)
        // changes the velocities by qdd * h.
        let h = 1e-3;
        for (q, qd, qdd) in [
            ([0.3, 0.9], [2.0, -3.0], [5.0, -8.0]),
            ([-0.2, 0.2], [-1.5, 4.0], [-3.0, 10.0]),
            ([0.6, 1.2], [0.0, 0.0], [0.0, 0.0]),
        ] {
            let mut l = leg(0.0, 1);
            l.set_state(q, qd);
            let tau = l.inertia().inverse_dynamics(q, qd, qdd);
            l.step(|_, _| tau);
            let v = l.velocities();
            for j in 0..2 {
                let a = (v[j] - qd[j]) / h;
                assert!(
                    (a - qdd[j]).abs() < 0.02 * qdd[j].abs().max(5.0),
                    "joint {j} at q {q:?}, qd {qd:?}: asked {} rad/s^2, got {a} (tau {tau:?})",
                    qdd[j]
                );
            }
        }
    }

    #[test]
    fn a_pitched_pelvis_turns_gravity_about_the_hip() {
        // Pitched by 90 deg, the straight leg lies horizontal: the full static moment at the
        // hip, and the torques the formula gives hold it.
        let j = JointSettings {
            damping_nm_s_per_rad: 0.0,
            friction_nm: 0.0,
        };
        let mount = Mount {
            pelvis_pitch_rad: std::f64::consts::FRAC_PI_2,
            knee_limits_rad: None,
        };
        let mut l = Leg::mounted(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, 2, mount).unwrap();
        let i = *l.inertia();
        let g = i.gravity_torques(0.0, 0.0);
        let static_moment = G
            * (i.thigh.mass_kg * i.thigh.com_below_joint_m
                + i.shank.mass_kg * (i.thigh_length_m + i.shank.com_below_joint_m));
        assert!(
            (g[0] + static_moment).abs() < 1e-9,
            "{g:?} vs {static_moment}"
        );
        l.set_state([0.1, 0.3], [0.0, 0.0]);
        let g = i.gravity_torques(0.1, 0.3);
        for _ in 0..300 {
            l.step(|_, _| [-g[0], -g[1]]);
        }
        let a = l.angles();
        assert!(
            (a[0] - 0.1).abs() < 1e-3 && (a[1] - 0.3).abs() < 1e-3,
            "{a:?}"
        );
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
