//! The exoskeleton as a rapier multibody loaded from URDF: a pelvis and one or two legs.
//!
//! One leg is a chain `hip -> thigh -> knee -> shank` (and, on a treadmill, `ankle ->
//! foot`); a URDF with one leg names its joints `hip`, `knee`, `ankle`, one with two legs
//! prefixes them `right_` and `left_` (`crates/pma-leg/models/exo_trainer.urdf`). Every
//! leg is the same code: [`LegJoints`] says where one leg's joints are, and the
//! [`Exoskeleton`] holds one per leg on its pelvis. The pelvis is fixed (the leg swings in
//! the air; [`Mount`]) or slides on a treadmill's harness ([`crate::ground`]).
use crate::config::JointSettings;
use crate::error::{one_line, LegError};
use crate::gait::{GaitReference, StartUp};
use crate::ground::{
    AnkleSettings, FootSetup, FootSphere, Ground, GroundReaction, GroundSetup, OtherLeg,
    SagittalChain, TreadmillSettings,
};
use crate::legs::{PerLeg, MAX_LEGS, SIDES};
use rapier3d::prelude::*;
use rapier3d_urdf::{urdf_rs, UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};
use std::path::Path;

/// Standard gravity (m/s^2), the same as the muscle bench's.
const G: f64 = pma_model::GRAVITY_M_S2;

/// Solver iterations of a leg with a held joint (see [`Exoskeleton::hold`]).
pub const HOLD_SOLVER_ITERATIONS: usize = 8;

/// Names of the two actuated joints of a leg, in index order (a two-leg URDF prefixes
/// them with the leg's side: `right_hip`).
pub const JOINT_NAMES: [&str; 2] = ["hip", "knee"];

/// One joint: where to read it and where to apply its torque.
#[derive(Debug, Clone, Copy)]
struct JointRef {
    handle: MultibodyJointHandle,
    parent: RigidBodyHandle,
    child: RigidBodyHandle,
    dof: usize,
    /// Joint axis in the child body's frame.
    axis_in_child: Vector,
}

/// One leg in the multibody: its actuated joints, its passive ankle (if it has one) and
/// the limits rapier enforces.
#[derive(Debug, Clone)]
pub struct LegJoints {
    /// Prefix of the leg's URDF names (`""` for a one-leg URDF, `right_`, `left_`).
    prefix: String,
    joints: [JointRef; 2],
    ankle: Option<JointRef>,
    limits_rad: [[f64; 2]; 2],
}

impl LegJoints {
    /// The URDF name of this leg's `name` (a link or a joint): `thigh` -> `right_thigh`.
    pub fn urdf_name(&self, name: &str) -> String {
        format!("{}{name}", self.prefix)
    }

    /// The URDF name of a link this leg's muscles attach to: the shared `pelvis`, or one
    /// of the leg's own links.
    pub fn link_name(&self, name: &str) -> String {
        if name == "pelvis" {
            name.to_owned()
        } else {
            self.urdf_name(name)
        }
    }
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

/// Mass of the exoskeleton's thigh frame (kg): the URDFs' stated design, an aluminium bar
/// (`models/exo_leg.urdf`, `models/exo_trainer.urdf`).
pub const FRAME_THIGH_KG: f64 = 2.0;
/// Mass of its shank frame (kg).
pub const FRAME_SHANK_KG: f64 = 1.5;
/// Where each frame's centre of mass sits below its joint (m): the middle of a 0.40 m bar.
pub const FRAME_COM_M: f64 = 0.20;

impl LinkInertia {
    /// A uniform bar of `mass_kg` whose middle is `FRAME_COM_M` below its joint.
    fn frame_bar(mass_kg: f64) -> Self {
        let length = 2.0 * FRAME_COM_M;
        Self {
            mass_kg,
            com_below_joint_m: FRAME_COM_M,
            inertia_kg_m2: mass_kg * length * length / 12.0,
        }
    }

    /// This link without `part` (both about the same joint): the rest's mass, centre and
    /// inertia about its own centre (parallel axes).
    fn without(&self, part: &LinkInertia) -> Self {
        let mass_kg = self.mass_kg - part.mass_kg;
        let com = (self.mass_kg * self.com_below_joint_m - part.mass_kg * part.com_below_joint_m)
            / mass_kg;
        let about_joint =
            |l: &LinkInertia| l.inertia_kg_m2 + l.mass_kg * l.com_below_joint_m.powi(2);
        Self {
            mass_kg,
            com_below_joint_m: com,
            inertia_kg_m2: about_joint(self) - about_joint(part) - mass_kg * com * com,
        }
    }
}

impl LegInertia {
    /// The exoskeleton's own frames on this leg's geometry (the URDFs' stated design).
    pub fn frames(&self) -> Self {
        Self {
            thigh: LinkInertia::frame_bar(FRAME_THIGH_KG),
            shank: LinkInertia::frame_bar(FRAME_SHANK_KG),
            ..*self
        }
    }

    /// The patient's limb alone: this leg without the exoskeleton's frames.
    pub fn limb(&self) -> Self {
        let frames = self.frames();
        Self {
            thigh: self.thigh.without(&frames.thigh),
            shank: self.shank.without(&frames.shank),
            ..*self
        }
    }

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

    /// The joint-space mass matrix `M(q)` (kg m^2, `[row][column]`, hip then knee) at angles
    /// `q` (rad): [`LegInertia::inverse_dynamics`]'s torques for each unit acceleration,
    /// at rest, less its torques at rest (gravity).
    pub fn mass_matrix(&self, q: [f64; 2]) -> [[f64; 2]; 2] {
        let still = self.inverse_dynamics(q, [0.0; 2], [0.0; 2]);
        let column = |j: usize| {
            let mut unit = [0.0; 2];
            unit[j] = 1.0;
            let t = self.inverse_dynamics(q, [0.0; 2], unit);
            [t[0] - still[0], t[1] - still[1]]
        };
        let (c0, c1) = (column(0), column(1));
        [[c0[0], c1[0]], [c0[1], c1[1]]]
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

fn urdf_err(file: &str, message: impl Into<String>) -> LegError {
    LegError::Urdf {
        file: file.to_owned(),
        message: message.into(),
    }
}

fn find_link<'a>(
    robot: &'a urdf_rs::Robot,
    name: &str,
    file: &str,
) -> Result<&'a urdf_rs::Link, LegError> {
    robot
        .links
        .iter()
        .find(|l| l.name == name)
        .ok_or_else(|| urdf_err(file, format!("no link named `{name}`")))
}

fn find_joint<'a>(
    robot: &'a urdf_rs::Robot,
    name: &str,
    file: &str,
) -> Result<&'a urdf_rs::Joint, LegError> {
    robot
        .joints
        .iter()
        .find(|j| j.name == name)
        .ok_or_else(|| urdf_err(file, format!("no joint named `{name}`")))
}

fn link_inertia(robot: &urdf_rs::Robot, name: &str, file: &str) -> Result<LinkInertia, LegError> {
    let i = &find_link(robot, name, file)?.inertial;
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

/// The prefixes of the URDF's legs: `""` for a one-leg URDF (`hip`, `knee`), else the
/// sides it has (`right_hip` ...), in [`SIDES`] order.
fn leg_prefixes(raw: &urdf_rs::Robot, file: &str) -> Result<Vec<String>, LegError> {
    let has = |name: &str| raw.joints.iter().any(|j| j.name == name);
    if has("hip") {
        return Ok(vec![String::new()]);
    }
    let sides: Vec<String> = SIDES
        .iter()
        .map(|s| format!("{s}_"))
        .filter(|p| has(&format!("{p}hip")))
        .collect();
    if sides.is_empty() {
        return Err(urdf_err(
            file,
            "no joint named `hip` (one leg) or `right_hip` / `left_hip` (two legs)",
        ));
    }
    Ok(sides)
}

/// Drops every link and joint of the legs after the first `legs` (their names start with
/// the leg's prefix): a one-leg treadmill on a two-leg URDF keeps its right leg.
fn keep_legs(raw: &mut urdf_rs::Robot, prefixes: &mut Vec<String>, legs: usize) {
    let dropped: Vec<String> = prefixes.drain(legs.min(prefixes.len())..).collect();
    let gone = |name: &str| dropped.iter().any(|p| !p.is_empty() && name.starts_with(p));
    raw.links.retain(|l| !gone(&l.name));
    raw.joints.retain(|j| !gone(&j.name));
}

/// The leg's `foot` link's `<collision>` spheres: the treadmill's contact geometry.
fn foot_spheres(raw: &urdf_rs::Robot, file: &str, foot: &str) -> Result<Vec<FootSphere>, LegError> {
    let link = raw.links.iter().find(|l| l.name == foot).ok_or_else(|| {
        urdf_err(
            file,
            format!(
                "no link named `{foot}`: a treadmill needs a foot (see models/exo_trainer.urdf)"
            ),
        )
    })?;
    let spheres: Vec<FootSphere> = link
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
            .any(|s| !(s.radius_m.is_finite() && s.radius_m > 0.0 && s.radius_m <= 0.1))
    {
        return Err(urdf_err(
            file,
            format!("the `{foot}` link needs <collision> spheres of radius 0 < r <= 0.1 m (its contact points)"),
        ));
    }
    Ok(spheres)
}

/// The sagittal chain pelvis -> hip -> knee -> ankle of the leg with `prefix`, for the
/// virtual other leg and the belt's speed: each joint's origin `[x, z]`, pitch and flexion
/// sense (the ankle's dorsiflexion sense; a fixed ankle turns with nothing).
fn sagittal_chain(
    raw: &urdf_rs::Robot,
    file: &str,
    prefix: &str,
    spheres: Vec<FootSphere>,
) -> Result<SagittalChain, LegError> {
    let joint = |name: &str| find_joint(raw, &format!("{prefix}{name}"), file);
    let (hip, knee, ankle) = (joint("hip")?, joint("knee")?, joint("ankle")?);
    let origin = |j: &urdf_rs::Joint| [j.origin.xyz[0], j.origin.xyz[2]];
    let sense = |j: &urdf_rs::Joint| {
        if j.joint_type == urdf_rs::JointType::Fixed {
            return Ok(0.0);
        }
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
        flexion_sign: [sense(hip)?, sense(knee)?, sense(ankle)?],
        spheres,
    })
}

/// Two bodies' masses, centres and inertias about the flexion axis as one (parallel
/// axes): the shank and a foot at its neutral angle, for the nominal models.
fn combined(parts: [(f64, [f64; 2], f64); 2]) -> (f64, [f64; 2], f64) {
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    let com: [f64; 2] =
        std::array::from_fn(|k| parts.iter().map(|p| p.0 * p.1[k]).sum::<f64>() / mass);
    let inertia = parts
        .iter()
        .map(|(m, c, i)| i + m * ((c[0] - com[0]).powi(2) + (c[1] - com[1]).powi(2)))
        .sum();
    (mass, com, inertia)
}

/// The leg's inertia data: thigh, and shank with the foot (if it has one, at its neutral
/// angle): the controllers' nominal models and the patient's inverse dynamics see one
/// two-link leg.
fn leg_inertia(
    raw: &urdf_rs::Robot,
    file: &str,
    prefix: &str,
    mount_pitch_rad: f64,
) -> Result<LegInertia, LegError> {
    let name = |n: &str| format!("{prefix}{n}");
    let knee = find_joint(raw, &name("knee"), file)?;
    let mut shank = link_inertia(raw, &name("shank"), file)?;
    let foot = raw.links.iter().find(|l| l.name == name("foot"));
    let ankle = raw.joints.iter().find(|j| j.name == name("ankle"));
    if let (Some(foot), Some(ankle)) = (foot, ankle) {
        let (o, f) = (ankle.origin.xyz, &foot.inertial);
        let (mass, com, inertia) = combined([
            (
                shank.mass_kg,
                [0.0, -shank.com_below_joint_m],
                shank.inertia_kg_m2,
            ),
            (
                f.mass.value,
                [o[0] + f.origin.xyz[0], o[2] + f.origin.xyz[2]],
                f.inertia.iyy,
            ),
        ]);
        // The combined centre lies slightly ahead of the shank's axis; the two-link model
        // keeps its distance below the knee.
        shank = LinkInertia {
            mass_kg: mass,
            com_below_joint_m: com[0].hypot(com[1]),
            inertia_kg_m2: inertia,
        };
    }
    let hip = find_joint(raw, &name("hip"), file)?;
    Ok(LegInertia {
        thigh: link_inertia(raw, &name("thigh"), file)?,
        shank,
        thigh_length_m: -knee.origin.xyz[2],
        // The mount's pitch, and the hip origin's (an anteriorly tilted pelvis frame turns
        // the thigh back: a pitch about +Y is one about -Y by its negative).
        pelvis_pitch_rad: mount_pitch_rad - hip.origin.rpy[1],
    })
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

/// Winter's (2009, Table 4.1) mass fractions of one leg's segments: thigh, leg, foot.
pub const LEG_MASS_FRACTION: f64 = 0.100 + 0.0465 + 0.0145;

/// Adds the patient's trunk (and any leg the model lacks) to the pelvis link: the body
/// mass less `legs` legs' human segments; returns the mass added (kg). The pelvis only
/// slides, so where that mass sits does not matter.
fn patient_on_pelvis(
    raw: &mut urdf_rs::Robot,
    file: &str,
    body_mass_kg: f64,
    legs: usize,
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
    let carried = body_mass_kg * (1.0 - legs as f64 * LEG_MASS_FRACTION);
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
        let mut feet = Vec::with_capacity(prefixes.len());
        for p in &prefixes {
            let link = format!("{p}foot");
            let spheres = foot_spheres(&raw, file, &link)?;
            feet.push((link, spheres));
        }
        let chain = sagittal_chain(&raw, file, &prefixes[0], feet[0].1.clone())?;
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
            [f64::from(t.x), f64::from(t.y), f64::from(t.z)]
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
        let options = UrdfLoaderOptions {
            // Pitching the fixed root pitches the whole leg about the hip axis (the URDF's
            // hip lies on the pelvis frame's Y axis), flexion-wise for a positive angle.
            shift: Pose::from_rotation(Rotation::from_axis_angle(
                -Vector::Y,
                mount.pelvis_pitch_rad as Real,
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
        };
        let robot = UrdfRobot::from_robot(raw, options, Path::new("."));
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

        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, 0.0, -G as Real),
            ..Default::default()
        };
        world.integration_parameters.dt = (period_s / f64::from(substeps)) as Real;
        // rapier's default of 4 solver iterations substeps internally and recomputes the
        // multibody dynamics each time; the leg's only constraints are its joint limits,
        // so one iteration per (explicit) substep is enough and 4x cheaper.
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
            .map_or([f64::NEG_INFINITY, f64::INFINITY], |l| {
                [f64::from(l.min), f64::from(l.max)]
            })
    }

    fn set_limits(&mut self, leg: usize, k: usize, [lo, hi]: [f64; 2]) {
        let j = self.legs[leg].joints[k];
        self.with_joint(j, |j| {
            j.data.set_limits(JointAxis::AngX, [lo as Real, hi as Real]);
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
            j.data.set_limits(JointAxis::AngX, [lo as Real, hi as Real]);
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
                    mb.damping_mut()[j.dof] = s.damping_nm_s_per_rad as Real;
                    mb.frictions_mut()[j.dof] = s.friction_nm as Real;
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
            .and_then(|(mb, id)| mb.link(id).map(|l| f64::from(l.joint().coords()[3])))
            .unwrap_or(f64::NAN)
    }

    fn rate(&self, j: JointRef) -> f64 {
        self.world
            .multibody_joints
            .get(j.handle)
            .map(|(mb, _)| f64::from(mb.generalized_velocity()[j.dof]))
            .unwrap_or(f64::NAN)
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
        Some((self.coordinate(a), self.rate(a)))
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
                disp[dofs[k]] = (angles[k] - current[k]) as Real;
                mb.generalized_velocity_mut()[dofs[k]] = velocities[k] as Real;
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
                disp[a.dof] = (to - from) as Real;
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
        let Some(axis) = self
            .world
            .bodies
            .get(j.child)
            .map(|rb| rb.position().rotation * j.axis_in_child)
        else {
            return;
        };
        let t = axis * torque_nm as Real;
        if let Some(rb) = self.world.bodies.get_mut(j.child) {
            rb.add_torque(t, true);
        }
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
                let h = f64::from(self.world.integration_parameters.dt);
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
                disp[dof] = dz_m as Real;
            }
        });
    }

    /// Position of the pelvis frame `[fore-aft, height above the belt]` (m), on a treadmill.
    pub fn pelvis_position_m(&self) -> Option<[f64; 2]> {
        let g = self.ground.as_ref()?;
        let rb = self.world.bodies.get(g.pelvis())?;
        let t = rb.translation();
        Some([f64::from(t.x), f64::from(t.z)])
    }

    /// Velocity of the pelvis frame `[fore-aft, up]` (m/s), on a treadmill.
    pub fn pelvis_velocity_m_s(&self) -> Option<[f64; 2]> {
        let g = self.ground.as_ref()?;
        let v = self.world.bodies.get(g.pelvis())?.linvel();
        Some([f64::from(v.x), f64::from(v.z)])
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
        f64::from(self.world.integration_parameters.dt)
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
        let rb = self.world.bodies.get(self.body(name)?)?;
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

    fn leg(damping: f64, substeps: u32) -> Exoskeleton {
        let j = JointSettings {
            damping_nm_s_per_rad: damping,
            friction_nm: 0.0,
        };
        Exoskeleton::from_urdf_str(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, substeps).unwrap()
    }

    #[test]
    fn flexion_is_positive_and_gravity_pulls_the_leg_back() {
        let mut l = leg(0.0, 1);
        l.set_state(0, [0.3, 0.4], [0.0, 0.0]);
        let a = l.angles(0);
        assert!(
            (a[0] - 0.3).abs() < 1e-5 && (a[1] - 0.4).abs() < 1e-5,
            "{a:?}"
        );
        // Flexed hip: the knee is in front of the hip (+X).
        let knee_x = l.link_poses().iter().find(|p| p.0 == "shank").unwrap().1[0];
        assert!(knee_x > 0.1, "knee at x = {knee_x}");
        l.step(|_, _| PerLeg::one([0.0, 0.0]));
        let v = l.velocities(0);
        assert!(v[0] < 0.0, "hip falls back: {v:?}");
    }

    #[test]
    fn joint_torque_accelerates_in_its_sign() {
        let mut l = leg(0.0, 1);
        l.step(|_, _| PerLeg::one([50.0, -20.0]));
        let v = l.velocities(0);
        assert!(v[0] > 0.0 && v[1] < 0.0, "{v:?}");
    }

    #[test]
    fn the_mass_matrix_is_symmetric_and_gives_the_kinetic_energy() {
        let body = *leg(0.0, 2).inertia();
        for (q, qd) in [
            ([0.3, 0.8], [1.2, -2.0]),
            ([-0.1, 0.0], [0.5, 0.7]),
            ([0.9, 1.3], [-1.5, 3.0]),
        ] {
            let m = body.mass_matrix(q);
            let kinetic = 0.5
                * (qd[0] * (m[0][0] * qd[0] + m[0][1] * qd[1])
                    + qd[1] * (m[1][0] * qd[0] + m[1][1] * qd[1]));
            let from_energy = body.energy(q, qd) - body.energy(q, [0.0; 2]);
            assert!((m[0][1] - m[1][0]).abs() < 1e-12, "{m:?}");
            assert!(
                (kinetic - from_energy).abs() < 1e-12 * from_energy,
                "{q:?} {qd:?}: 1/2 qd' M qd = {kinetic} J, energy's {from_energy} J"
            );
        }
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
            l.set_state(0, q, qd);
            let tau = l.inertia().inverse_dynamics(q, qd, qdd);
            l.step(|_, _| PerLeg::one(tau));
            let v = l.velocities(0);
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
        let mut l =
            Exoskeleton::mounted(EMBEDDED_URDF, "exo_leg.urdf", [j, j], 1e-3, 2, mount).unwrap();
        let i = *l.inertia();
        let g = i.gravity_torques(0.0, 0.0);
        let static_moment = G
            * (i.thigh.mass_kg * i.thigh.com_below_joint_m
                + i.shank.mass_kg * (i.thigh_length_m + i.shank.com_below_joint_m));
        assert!(
            (g[0] + static_moment).abs() < 1e-9,
            "{g:?} vs {static_moment}"
        );
        l.set_state(0, [0.1, 0.3], [0.0, 0.0]);
        let g = i.gravity_torques(0.1, 0.3);
        for _ in 0..300 {
            l.step(|_, _| PerLeg::one([-g[0], -g[1]]));
        }
        let a = l.angles(0);
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
        l.set_state(0, q, [0.0, 0.0]);
        let g = l.inertia().gravity_torques(q[0], q[1]);
        for _ in 0..500 {
            l.step(|_, _| PerLeg::one([-g[0], -g[1]]));
        }
        let a = l.angles(0);
        assert!(
            (a[0] - q[0]).abs() < 1e-3 && (a[1] - q[1]).abs() < 1e-3,
            "{a:?}"
        );
    }

    /// The rapier fork (vendor/rapier3d/PATCHES.md) computes the multibody's body
    /// Jacobians and mass matrix on each link's branch (its own and its ancestors' DOFs)
    /// only. On the two-leg trainer, moving, they must be what the full products give: each
    /// link's Jacobian times the generalized velocity is the link's velocity (rapier's own,
    /// propagated link to link), and the mass matrix is the sum over links of Jᵀ M J, the
    /// legs' cross terms zero.
    #[test]
    fn rapier_fork_branch_dynamics_equal_the_full_products_on_two_legs() {
        let t = TreadmillSettings {
            legs: 2,
            speed_m_per_s: Some(0.5),
            contralateral: Some(crate::ground::Contralateral::None),
            ..TreadmillSettings::new(0.3, 75.0)
        };
        let j = JointSettings {
            damping_nm_s_per_rad: 0.5,
            friction_nm: 0.0,
        };
        let mut e = Exoskeleton::on_treadmill(
            crate::config::EMBEDDED_TRAINER_URDF,
            "exo_trainer.urdf",
            [j, j],
            1e-3,
            1,
            &t,
        )
        .unwrap();
        e.set_state(0, [0.4, 0.7], [1.5, -2.0]);
        e.set_state(1, [-0.1, 0.2], [-0.7, 3.0]);
        for _ in 0..5 {
            e.step(|_, _| PerLeg::from_fn(2, |leg| [10.0 * leg as f64, -5.0]));
        }
        let handle = e.legs[0].joints[0].handle;
        // Each link's Jacobian at this pose against its centre of mass's finite difference
        // over the next period (semi-implicit Euler moves the pose with the new velocity).
        let coms = |e: &Exoskeleton| -> Vec<[f64; 3]> {
            let (mb, _) = e.world.multibody_joints.get(handle).unwrap();
            mb.links()
                .map(|l| {
                    let c = e.world.bodies[l.rigid_body_handle()]
                        .mass_properties()
                        .world_com;
                    [c.x, c.y, c.z].map(f64::from)
                })
                .collect()
        };
        let before = coms(&e);
        let jacobians: Vec<_> = {
            let (mb, _) = e.world.multibody_joints.get(handle).unwrap();
            (0..mb.num_links())
                .map(|i| mb.body_jacobian(i).clone())
                .collect()
        };
        e.step(|_, _| PerLeg::from_fn(2, |leg| [10.0 * leg as f64, -5.0]));
        let after = coms(&e);
        let bodies = &e.world.bodies;
        let (mb, _) = e.world.multibody_joints.get_mut(handle).unwrap();
        let n = mb.ndofs();
        assert_eq!(n, 8, "pelvis x and z, two hips, knees and ankles");
        let qd: Vec<f64> = mb
            .generalized_velocity()
            .iter()
            .map(|&v| f64::from(v))
            .collect();
        let (mut worst_velocity, mut fastest) = (0.0f64, 0.0f64);
        for (i, jac) in jacobians.iter().enumerate() {
            for r in 0..3 {
                let jv: f64 = (0..n).map(|c| f64::from(jac[(r, c)]) * qd[c]).sum();
                let moved = (after[i][r] - before[i][r]) / 1e-3;
                worst_velocity = worst_velocity.max((jv - moved).abs());
                fastest = fastest.max(moved.abs());
            }
        }
        // The mass matrix at the present pose: rapier reassembles it (dt = 0: no damping).
        mb.dof_inverse_inertia(bodies);
        let mut full = vec![vec![0.0f64; n]; n];
        for (i, link) in mb.links().enumerate() {
            let jac = mb.body_jacobian(i);
            let props = bodies[link.rigid_body_handle()].mass_properties();
            let m = props.effective_mass();
            let inertia = props.effective_angular_inertia();
            // The link's spatial inertia at its centre of mass: mass, then the world inertia.
            let i3 = [
                [inertia.m11, inertia.m12, inertia.m13],
                [inertia.m12, inertia.m22, inertia.m23],
                [inertia.m13, inertia.m23, inertia.m33],
            ];
            let mut spatial = [[0.0f64; 6]; 6];
            for (k, mass) in [m.x, m.y, m.z].into_iter().enumerate() {
                spatial[k][k] = f64::from(mass);
                for l in 0..3 {
                    spatial[3 + k][3 + l] = f64::from(i3[k][l]);
                }
            }
            for (r, row) in full.iter_mut().enumerate() {
                for (c, entry) in row.iter_mut().enumerate() {
                    for a in 0..6 {
                        for b in 0..6 {
                            *entry +=
                                f64::from(jac[(a, r)]) * spatial[a][b] * f64::from(jac[(b, c)]);
                        }
                    }
                }
            }
        }
        let lu = mb.inv_augmented_mass();
        let mut fork = lu.l() * lu.u();
        lu.p().inv_permute_rows(&mut fork);
        let scale = full.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
        let mut worst_mass = 0.0f64;
        for r in 0..n {
            for c in 0..n {
                worst_mass = worst_mass.max((f64::from(fork[(r, c)]) - full[r][c]).abs() / scale);
            }
        }
        // The hips' cross term: no link moves with both legs.
        let hips = e.legs.iter().map(|l| l.joints[0].dof).collect::<Vec<_>>();
        let cross = f64::from(fork[(hips[0], hips[1])]).abs() / scale;
        println!(
            "J qdot vs the links' finite-difference velocity: {worst_velocity:.2e} m/s (fastest {fastest:.2} m/s); mass matrix vs full sum: {worst_mass:.2e} of its largest entry ({scale:.1} kg); hips' cross term {cross:.1e}"
        );
        assert!(
            worst_velocity < 0.02 * fastest,
            "J qdot is {worst_velocity} m/s off a link's velocity"
        );
        assert!(
            worst_mass < 1e-5,
            "mass matrix {worst_mass} off the full sum"
        );
        assert!(cross < 1e-6, "the hips' cross term is {cross}");
    }
}
