use serde::{Deserialize, Serialize};

/// How a leg's joints are controlled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlMode {
    /// Robot in charge: each muscle's controller tracks its length along the reference.
    #[default]
    Position,
    /// Each joint a spring and damper about the reference, its stiffness set by the pair's
    /// co-contraction ([`ImpedanceSettings`]).
    Impedance,
    /// Path control (Duschau-Wicke et al. 2010): free inside a tunnel around the
    /// reference's path in joint space, whatever the timing; a wall outside; a supportive
    /// torque along the path ([`PathSettings`]). The pairs at their softest.
    Path,
    /// Patient in charge: no torque on the limb but what compensates the device (its
    /// weight, the muscles' own damping); the pairs at their softest.
    Transparent,
    /// Impedance through the muscles' own controllers (admittance control): each joint's
    /// reference displaced by the cuff torque the patient adds over the set stiffness
    /// (`[control.impedance]`), tracked by the muscle controllers as in position mode
    /// ([`crate::admittance`]).
    Admittance,
}

impl ControlMode {
    /// Whether the muscles' own controllers run (position mode) or the pairs are set by
    /// pressure (every other mode).
    pub fn runs_muscle_controllers(self) -> bool {
        matches!(self, Self::Position | Self::Admittance)
    }

    /// Whether the pairs' pressures are set by [`ImpedanceLaw`] (impedance, path and
    /// transparent modes), no muscle controller running.
    pub fn sets_pressures(self) -> bool {
        !self.runs_muscle_controllers()
    }
}

/// Whose weight and inertia the pressure-set modes carry besides their own law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Compensation {
    /// The whole leg, limb and frames: a passive patient is carried (default).
    #[default]
    Leg,
    /// The exoskeleton's own frames only: an active patient carries their own limb.
    Device,
}

impl std::fmt::Display for ControlMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Position => "position",
            Self::Impedance => "impedance",
            Self::Path => "path",
            Self::Transparent => "transparent",
            Self::Admittance => "admittance",
        })
    }
}
