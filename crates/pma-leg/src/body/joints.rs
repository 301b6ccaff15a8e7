use rapier3d::prelude::*;

/// One joint: where to read it and where to apply its torque.
#[derive(Debug, Clone, Copy)]
pub(crate) struct JointRef {
    pub(crate) handle: MultibodyJointHandle,
    pub(crate) parent: RigidBodyHandle,
    pub(crate) child: RigidBodyHandle,
    pub(crate) dof: usize,
    /// Joint axis in the child body's frame.
    pub(crate) axis_in_child: Vector,
}

/// One leg in the multibody: its actuated joints, its passive ankle (if it has one) and
/// the limits rapier enforces.
#[derive(Debug, Clone)]
pub struct LegJoints {
    /// Prefix of the leg's URDF names (`""` for a one-leg URDF, `right_`, `left_`).
    pub(crate) prefix: String,
    pub(crate) joints: [JointRef; 2],
    pub(crate) ankle: Option<JointRef>,
    pub(crate) limits_rad: [[f64; 2]; 2],
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
