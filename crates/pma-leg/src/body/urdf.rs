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

fn find_link_mut<'a>(
    robot: &'a mut urdf_rs::Robot,
    name: &str,
    file: &str,
) -> Result<&'a mut urdf_rs::Link, LegError> {
    robot
        .links
        .iter_mut()
        .find(|l| l.name == name)
        .ok_or_else(|| urdf_err(file, format!("no link named `{name}`")))
}

fn find_joint_mut<'a>(
    robot: &'a mut urdf_rs::Robot,
    name: &str,
    file: &str,
) -> Result<&'a mut urdf_rs::Joint, LegError> {
    robot
        .joints
        .iter_mut()
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

/// The patient the trainer's leg links were built for: each carries a 75 kg, 1.75 m
/// person's segment (Winter 2009, Table 4.1; `models/leg-sources.md`) beside its frame.
pub const URDF_PATIENT_MASS_KG: f64 = 75.0;

/// That patient's height (m): segment lengths and centres of mass below.
pub const URDF_PATIENT_HEIGHT_M: f64 = 1.75;

/// The axis a segment is long along, in its link's frame: its radius of gyration (Winter's,
/// about the centre of mass in the sagittal plane) holds about the two axes across it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LongAxis {
    /// Down the link (thigh, shank): the moments about X and Y.
    Z,
    /// Fore-aft (the foot): the moments about Y and Z.
    X,
}

/// One leg's human segments (Winter 2009, Table 4.1): link suffix, mass fraction of the
/// body, centre of mass from the proximal joint and radius of gyration about it (fractions
/// of the segment's length), the segment's length (fraction of the height), the axis it is
/// long along. The foot's centre of mass is its link's own (the foot link is the foot
/// alone), its length 0.152 H (Drillis and Contini, Winter Fig. 4.1).
const LEG_SEGMENTS: [(&str, f64, f64, f64, f64, LongAxis); 3] = [
    ("thigh", 0.100, 0.433, 0.323, 0.245, LongAxis::Z),
    ("shank", 0.0465, 0.433, 0.302, 0.246, LongAxis::Z),
    ("foot", 0.0145, f64::NAN, 0.475, 0.152, LongAxis::X),
];

/// The patient's leg segments scaled to `body_mass_kg` (issue 47: a 110 kg patient's legs
/// weighed what a 75 kg patient's do): each leg link of `prefixes` gains the difference
/// `fraction x (body_mass_kg - URDF_PATIENT_MASS_KG)` at the human segment's centre of
/// mass, with its radius of gyration, combined with the link about their common centre of
/// mass (parallel axes; a lighter patient removes mass the same way), the segment as long
/// as `height_m` makes it (the frame set to that height first: [`patient_height`]). The segment's own moment changes
/// about the two axes across it (the thigh's and shank's `ixx`, `iyy`; the foot's `iyy`,
/// `izz`), the shift of the centre of mass (along Z) about X and Y. A link whose inertia
/// is left no body's (a moment not positive, or one over the sum of the other two) is an
/// error naming it: rapier integrates such a link into a divergence.
pub(crate) fn patient_legs(
    raw: &mut urdf_rs::Robot,
    file: &str,
    body_mass_kg: f64,
    height_m: f64,
    prefixes: &[String],
) -> Result<(), LegError> {
    let extra = body_mass_kg - URDF_PATIENT_MASS_KG;
    if extra == 0.0 {
        return Ok(());
    }
    for prefix in prefixes {
        for (segment, fraction, com, gyration, length, long) in LEG_SEGMENTS {
            let name = format!("{prefix}{segment}");
            let link = find_link_mut(raw, &name, file)?;
            let i = &mut link.inertial;
            let length_m = length * height_m;
            let dm = fraction * extra;
            let (m1, m) = (i.mass.value, i.mass.value + dm);
            if m <= 0.0 {
                return Err(urdf_err(
                    file,
                    format!("`{name}` weighs {m1} kg: too light for a {body_mass_kg} kg patient's segment"),
                ));
            }
            let c1 = i.origin.xyz[2];
            let c2 = if com.is_nan() { c1 } else { -com * length_m };
            let c = (m1 * c1 + dm * c2) / m;
            let shift = m1 * (c1 - c).powi(2) + dm * (c2 - c).powi(2);
            let own = dm * (gyration * length_m).powi(2);
            let t = &mut i.inertia;
            t.ixx += shift;
            t.iyy += shift + own;
            match long {
                LongAxis::Z => t.ixx += own,
                LongAxis::X => t.izz += own,
            }
            i.origin.xyz[2] = c;
            i.mass.value = m;
            check_body_inertia(&name, [t.ixx, t.iyy, t.izz], body_mass_kg)
                .map_err(|why| urdf_err(file, why))?;
        }
    }
    Ok(())
}

/// A link's mass (kg), centre of mass (m, link frame) and principal moments about it (kg
/// m^2): the URDF's diagonal inertia.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Body {
    kg: f64,
    at: [f64; 3],
    moments: [f64; 3],
}

impl Body {
    fn of(link: &urdf_rs::Link) -> Self {
        let i = &link.inertial;
        let t = &i.inertia;
        Self {
            kg: i.mass.value,
            at: i.origin.xyz.0,
            moments: [t.ixx, t.iyy, t.izz],
        }
    }

    fn write_to(self, link: &mut urdf_rs::Link) {
        let i = &mut link.inertial;
        i.mass.value = self.kg;
        i.origin.xyz.0 = self.at;
        let [x, y, z] = self.moments;
        (i.inertia.ixx, i.inertia.iyy, i.inertia.izz) = (x, y, z);
    }

    /// The body stretched by `r` along the axes `axes` (an affine map of its mass
    /// distribution, mass kept): its centre of mass moves with it, and each central second
    /// moment `S_kk` along a stretched axis scales by `r^2` (`ixx = S_yy + S_zz`, ...).
    fn stretched(self, r: f64, axes: [bool; 3]) -> Body {
        let [ix, iy, iz] = self.moments;
        let mut s = [
            0.5 * (iy + iz - ix),
            0.5 * (ix + iz - iy),
            0.5 * (ix + iy - iz),
        ];
        let mut at = self.at;
        for k in 0..3 {
            if axes[k] {
                s[k] *= r * r;
                at[k] *= r;
            }
        }
        Body {
            kg: self.kg,
            at,
            moments: [s[1] + s[2], s[0] + s[2], s[0] + s[1]],
        }
    }
}

/// The trainer's legs for a patient `height_m` tall (issue 47: the frame adjusts its thigh
/// and shank lengths to the patient, as a Lokomat's orthosis does): every sagittal length
/// of each leg of `prefixes` scales by `r = height_m / URDF_PATIENT_HEIGHT_M` (Winter's
/// segments are fractions of the height: thigh 0.245 H, shank 0.246 H, foot 0.152 H, ankle
/// height 0.039 H):
/// - the knee and ankle joints move down their segments, the pelvis's standing height
///   (`pelvis_z`) with them;
/// - the thigh and shank links stretch along their length, their mass kept (the patient's
///   mass is [`patient_legs`]'s). Both parts stretch alike: the frame's telescoping bar,
///   and the URDF patient's segment, whose centre of mass (0.433 L) and radius of
///   gyration (0.302-0.323 L) are fractions of its length, which is exactly its stretch
///   along Z by `r`;
/// - the foot (the patient's alone) scales as a body, every moment by `r^2`; its contact
///   spheres keep their radius, their lowest points on the scaled sole;
/// - visuals follow.
///
/// The hips' spacing stays the frame's. `height_m` equal to the URDF's changes nothing.
pub(crate) fn patient_height(
    raw: &mut urdf_rs::Robot,
    file: &str,
    height_m: f64,
    prefixes: &[String],
) -> Result<(), LegError> {
    let r = height_m / URDF_PATIENT_HEIGHT_M;
    if r == 1.0 {
        return Ok(());
    }
    for prefix in prefixes {
        for joint in ["knee", "ankle"] {
            let name = format!("{prefix}{joint}");
            let j = find_joint_mut(raw, &name, file)?;
            j.origin.xyz[0] *= r;
            j.origin.xyz[2] *= r;
        }
        for (segment, .., long) in LEG_SEGMENTS {
            let name = format!("{prefix}{segment}");
            let link = find_link_mut(raw, &name, file)?;
            let axes = match long {
                LongAxis::Z => [false, false, true],
                LongAxis::X => [true; 3],
            };
            let scaled = Body::of(link).stretched(r, axes);
            check_body_inertia(&name, scaled.moments, URDF_PATIENT_MASS_KG)
                .map_err(|why| urdf_err(file, why))?;
            scaled.write_to(link);
            scale_shapes(link, r);
        }
    }
    find_joint_mut(raw, "pelvis_z", file)?.origin.xyz[2] *= r;
    Ok(())
}

/// A leg link's visuals and contact spheres for a leg `r` times as long: positions in the
/// sagittal plane and lengths scale; a sphere keeps its radius with its lowest point where
/// the scaled sole is.
fn scale_shapes(link: &mut urdf_rs::Link, r: f64) {
    for v in &mut link.visual {
        v.origin.xyz[0] *= r;
        v.origin.xyz[2] *= r;
        match &mut v.geometry {
            urdf_rs::Geometry::Cylinder { length, .. } => *length *= r,
            urdf_rs::Geometry::Box { size } => {
                size[0] *= r;
                size[2] *= r;
            }
            _ => {}
        }
    }
    for c in &mut link.collision {
        c.origin.xyz[0] *= r;
        if let urdf_rs::Geometry::Sphere { radius } = c.geometry {
            let sole = c.origin.xyz[2] - radius;
            c.origin.xyz[2] = sole * r + radius;
        } else {
            c.origin.xyz[2] *= r;
        }
    }
}

/// Whether a link's principal moments `[ixx, iyy, izz]` (kg m^2) are a body's: each
/// positive and none over the sum of the other two (the triangle inequality every mass
/// distribution obeys); the reason otherwise, naming the link and the patient.
fn check_body_inertia(link: &str, moments: [f64; 3], body_mass_kg: f64) -> Result<(), String> {
    let [x, y, z] = moments;
    let body =
        moments.iter().all(|m| m.is_finite() && *m > 0.0) && x <= y + z && y <= x + z && z <= x + y;
    if body {
        return Ok(());
    }
    Err(format!(
        "`{link}` with a {body_mass_kg} kg patient's segment has moments of inertia {x:.4}, {y:.4}, {z:.4} kg m^2 (ixx, iyy, izz), no body's: the link's frame is too light for that patient"
    ))
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// The trainer with a patient of `mass_kg`: each link's (mass, COM below its joint,
    /// moment about its joint's flexion axis).
    fn legs_of(mass_kg: f64) -> Vec<(String, f64, f64, f64)> {
        let mut raw = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
        let prefixes = ["right_".to_owned(), "left_".to_owned()];
        patient_legs(
            &mut raw,
            "trainer",
            mass_kg,
            URDF_PATIENT_HEIGHT_M,
            &prefixes,
        )
        .unwrap();
        let mut out = Vec::new();
        for p in &prefixes {
            for s in ["thigh", "shank", "foot"] {
                let l = raw
                    .links
                    .iter()
                    .find(|l| l.name == format!("{p}{s}"))
                    .unwrap();
                let (m, c) = (l.inertial.mass.value, l.inertial.origin.xyz[2]);
                out.push((l.name.clone(), m, c, l.inertial.inertia.iyy + m * c * c));
            }
        }
        out
    }

    /// Issue 47: a 110 kg patient's legs weighed a 75 kg patient's. Each segment gains
    /// Winter's fraction of the 35 kg more, and its moment about the joint the segment's
    /// `dm ((com L)^2 + (k L)^2)`; a 75 kg patient leaves the URDF as it is.
    #[test]
    fn regression_a_heavier_patients_legs_weighed_the_same() {
        let (base, heavy) = (legs_of(URDF_PATIENT_MASS_KG), legs_of(110.0));
        let unchanged = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
        for (name, m, c, _) in &base {
            let l = unchanged.links.iter().find(|l| &l.name == name).unwrap();
            assert_eq!((*m, *c), (l.inertial.mass.value, l.inertial.origin.xyz[2]));
        }
        for ((name, m0, _, i0), (_, m1, _, i1)) in base.iter().zip(&heavy) {
            let (_, fraction, com, k, len, _) = LEG_SEGMENTS
                .iter()
                .copied()
                .find(|s| name.ends_with(s.0))
                .unwrap();
            let dm = fraction * (110.0 - URDF_PATIENT_MASS_KG);
            assert!((m1 - m0 - dm).abs() < 1e-12, "{name}: {m0} -> {m1}");
            if !com.is_nan() {
                let l = len * URDF_PATIENT_HEIGHT_M;
                let expected = dm * ((com * l).powi(2) + (k * l).powi(2));
                assert!((i1 - i0 - expected).abs() < 1e-12, "{name}: {i0} -> {i1}");
            }
        }
        // Both legs' human part now weighs Winter's 2 x 0.161 of the patient.
        let human: f64 =
            heavy.iter().map(|l| l.1).sum::<f64>() - base.iter().map(|l| l.1).sum::<f64>();
        assert!((human - 2.0 * LEG_MASS_FRACTION * 35.0).abs() < 1e-9);
        // A patient too light for the links' frames is an error naming the link (the
        // thigh's mass goes first).
        let mut raw = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
        let e = patient_legs(
            &mut raw,
            "trainer",
            -1000.0,
            URDF_PATIENT_HEIGHT_M,
            &["right_".into()],
        )
        .unwrap_err();
        assert!(e.to_string().contains("right_thigh"), "{e}");
    }

    /// Issue 47: a 50 kg patient's simulation left physical bounds within 16 ms, put down
    /// to the feet's contact. The foot is long fore-aft (X), and its radius of gyration was
    /// taken off its `ixx` too: below 57 kg that moment went negative (-0.0018 kg m^2 at 50
    /// kg) and rapier integrated the link into a divergence. Over the range a trainer
    /// takes (15-200 kg) every link's moments are a body's, and the foot's change about Y
    /// and Z, not about its long axis.
    #[test]
    fn regression_a_light_patients_foot_had_a_negative_moment_of_inertia() {
        let base = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
        let moments = |raw: &urdf_rs::Robot, name: &str| {
            let t = &raw
                .links
                .iter()
                .find(|l| l.name == name)
                .unwrap()
                .inertial
                .inertia;
            [t.ixx, t.iyy, t.izz]
        };
        for mass_kg in [15.0, 30.0, 50.0, 55.0, 60.0, 110.0, 200.0] {
            let mut raw = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
            patient_legs(
                &mut raw,
                "trainer",
                mass_kg,
                URDF_PATIENT_HEIGHT_M,
                &["right_".into()],
            )
            .unwrap();
            for link in raw.links.iter().filter(|l| l.name.starts_with("right_")) {
                let m = moments(&raw, &link.name);
                assert!(
                    check_body_inertia(&link.name, m, mass_kg).is_ok(),
                    "{mass_kg} kg: {} {m:?}",
                    link.name
                );
            }
            let (before, after) = (moments(&base, "right_foot"), moments(&raw, "right_foot"));
            assert_eq!(before[0], after[0], "{mass_kg} kg: the foot's long axis");
            let own = 0.0145 * (mass_kg - URDF_PATIENT_MASS_KG) * (0.475 * 0.152 * 1.75f64).powi(2);
            for axis in [1, 2] {
                assert!(
                    (after[axis] - before[axis] - own).abs() < 1e-12,
                    "{mass_kg} kg: axis {axis}"
                );
            }
        }
        // What the check refuses: a negative moment, and one over the sum of the others.
        assert!(check_body_inertia("l", [-0.0018, 0.0116, 0.0174], 50.0).is_err());
        assert!(check_body_inertia("l", [0.0005, 0.0139, 0.0174], 60.0)
            .unwrap_err()
            .contains("`l` with a 60 kg patient's segment"));
    }

    /// Issue 47: the trainer's frame and the patient's legs kept the URDF's lengths whatever
    /// the patient's height. At 1.85 m the knee, the ankle and the standing pelvis move
    /// down by 1.85 / 1.75; each thigh and shank keeps its mass, its centre of mass moves
    /// with it, and its moment about its joint's flexion axis (`iyy + m c^2`) grows as a
    /// body stretched along its length does: `S_xx + r^2 (S_zz + m c^2)`, the second
    /// moments from the URDF's own. The foot scales as a body, its soles on the scaled
    /// sole (0.039 H below the ankle). The URDF's height leaves everything as it is.
    #[test]
    fn a_taller_patients_frame_and_segments_lengthen() {
        let prefixes = ["right_".to_owned(), "left_".to_owned()];
        let base = parse_urdf(EMBEDDED_TRAINER_URDF, "trainer").unwrap();
        let mut same = base.clone();
        patient_height(&mut same, "trainer", URDF_PATIENT_HEIGHT_M, &prefixes).unwrap();
        assert_eq!(format!("{same:?}"), format!("{base:?}"));
        let (h, r) = (1.85, 1.85 / URDF_PATIENT_HEIGHT_M);
        let mut tall = base.clone();
        patient_height(&mut tall, "trainer", h, &prefixes).unwrap();
        let joint_z = |raw: &urdf_rs::Robot, n: &str| {
            raw.joints.iter().find(|j| j.name == n).unwrap().origin.xyz[2]
        };
        for j in ["right_knee", "left_ankle", "pelvis_z"] {
            assert!(
                (joint_z(&tall, j) - r * joint_z(&base, j)).abs() < 1e-12,
                "{j}"
            );
        }
        // Winter's thigh, 0.245 H, within the URDF's rounding (0.429 m for 0.42875).
        assert!((-joint_z(&tall, "right_knee") / h - 0.245).abs() < 2e-4);
        let link = |raw: &urdf_rs::Robot, n: &str| {
            Body::of(raw.links.iter().find(|l| l.name == n).unwrap())
        };
        for n in ["right_thigh", "right_shank", "left_thigh", "left_shank"] {
            let (b, t) = (link(&base, n), link(&tall, n));
            let [ix, iy, iz] = b.moments;
            let (sxx, szz) = (0.5 * (iy + iz - ix), 0.5 * (ix + iy - iz));
            let c = b.at[2];
            let expected = sxx + r * r * (szz + b.kg * c * c);
            let got = t.moments[1] + t.kg * t.at[2] * t.at[2];
            assert_eq!(t.kg, b.kg, "{n}");
            assert!((t.at[2] - r * c).abs() < 1e-12, "{n}");
            assert!(
                (got - expected).abs() < 1e-12,
                "{n}: {got} against {expected}"
            );
            assert!((t.moments[2] - iz).abs() < 1e-12, "{n}: its long axis");
        }
        let (b, t) = (link(&base, "right_foot"), link(&tall, "right_foot"));
        for k in 0..3 {
            assert!((t.moments[k] - r * r * b.moments[k]).abs() < 1e-12);
        }
        let foot = tall.links.iter().find(|l| l.name == "right_foot").unwrap();
        let spheres = foot_spheres(&tall, "trainer", "right_foot").unwrap();
        assert_eq!(spheres.len(), foot.collision.len());
        for c in &foot.collision {
            let urdf_rs::Geometry::Sphere { radius } = c.geometry else {
                panic!("a foot contact is a sphere");
            };
            assert!((c.origin.xyz[2] - radius + 0.068 * r).abs() < 1e-12);
        }
        // Outside the range every link stays a body (checked as it scales).
        for h in [1.0, 2.5] {
            let mut raw = base.clone();
            patient_height(&mut raw, "trainer", h, &prefixes).unwrap();
        }
    }
}
