use crate::base::{one_line, LegError, SIDES};
use crate::body::{combined, LegInertia, LinkInertia};
use crate::ground::{FootSphere, SagittalChain};
use rapier3d_urdf::{urdf_rs, UrdfLoaderOptions, UrdfRobot};
use std::path::Path;

/// The embedded leg model (`crates/pma-leg/models/exo_leg.urdf`).
pub const EMBEDDED_URDF: &str = include_str!("../../models/exo_leg.urdf");

/// The embedded trainer (`crates/pma-leg/models/exo_trainer.urdf`): the pelvis on fore-aft
/// and vertical slides, two legs with passive ankles and feet with contact spheres (a
/// one-leg treadmill keeps the right leg).
pub const EMBEDDED_TRAINER_URDF: &str = include_str!("../../models/exo_trainer.urdf");

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

pub(crate) fn visuals_of(link: &urdf_rs::Link) -> Vec<VisualShape> {
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

pub(crate) fn urdf_err(file: &str, message: impl Into<String>) -> LegError {
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

pub(crate) fn parse_urdf(text: &str, file: &str) -> Result<urdf_rs::Robot, LegError> {
    UrdfRobot::from_str(text, UrdfLoaderOptions::default(), Path::new("."))
        .map(|(_, raw)| raw)
        .map_err(|e| urdf_err(file, one_line(&format!("{e:#}"))))
}

/// The prefixes of the URDF's legs: `""` for a one-leg URDF (`hip`, `knee`), else the
/// sides it has (`right_hip` ...), in [`SIDES`] order.
pub(crate) fn leg_prefixes(raw: &urdf_rs::Robot, file: &str) -> Result<Vec<String>, LegError> {
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
pub(crate) fn keep_legs(raw: &mut urdf_rs::Robot, prefixes: &mut Vec<String>, legs: usize) {
    let dropped: Vec<String> = prefixes.drain(legs.min(prefixes.len())..).collect();
    let gone = |name: &str| dropped.iter().any(|p| !p.is_empty() && name.starts_with(p));
    raw.links.retain(|l| !gone(&l.name));
    raw.joints.retain(|j| !gone(&j.name));
}

/// The leg's `foot` link's `<collision>` spheres: the treadmill's contact geometry.
pub(crate) fn foot_spheres(
    raw: &urdf_rs::Robot,
    file: &str,
    foot: &str,
) -> Result<Vec<FootSphere>, LegError> {
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
pub(crate) fn sagittal_chain(
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

/// The leg's inertia data: thigh, and shank with the foot (if it has one, at its neutral
/// angle): the controllers' nominal models and the patient's inverse dynamics see one
/// two-link leg.
pub(crate) fn leg_inertia(
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
pub(crate) fn carried_links(raw: &urdf_rs::Robot, root: &str) -> Vec<String> {
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
pub(crate) fn patient_on_pelvis(
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
