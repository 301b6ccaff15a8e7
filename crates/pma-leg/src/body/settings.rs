use serde::Deserialize;

/// Viscous damping and Coulomb friction of a joint, set explicitly in rapier (which would
/// otherwise add its own default damping and ignores URDF `<dynamics>`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSettings {
    /// Viscous damping (N m s/rad).
    pub damping_nm_s_per_rad: f64,
    /// Coulomb friction (N m).
    #[serde(default)]
    pub friction_nm: f64,
}

/// Both joints.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joints {
    /// Hip.
    pub hip: JointSettings,
    /// Knee.
    pub knee: JointSettings,
}
