use crate::{CommandLimits, NominalModel, Saturation};
use pma_model::{DampingMode, GRAVITY_M_S2};

/// What every controller remembers about its own last command: the value held over the
/// coming period (the disturbance observer needs it), the damping mode its change implies,
/// and whether it was clamped (for anti-windup).
#[derive(Debug, Clone, Copy)]
pub(crate) struct CommandState {
    pub u_prev: f64,
    pub mode: DampingMode,
    pub saturation: Saturation,
}

impl CommandState {
    /// Starting from rest at `x`: the pressure that held the load there per the nominal
    /// model (the bench and the rig both start from a held, resting muscle).
    pub fn at_rest(model: &NominalModel, limits: &CommandLimits, x: f64) -> Self {
        let w = model.mass_kg * GRAVITY_M_S2;
        let u = model
            .muscle
            .static_pressure_for(w, x)
            .map_or(limits.min_pa, |p| limits.clamp(p).0);
        Self {
            u_prev: u,
            mode: DampingMode::Inflation,
            saturation: Saturation::None,
        }
    }

    /// Clamps the raw command, records saturation and damping mode, returns the command.
    pub fn apply(&mut self, limits: &CommandLimits, raw: f64) -> f64 {
        let (u, sat) = limits.clamp(raw);
        self.saturation = sat;
        self.mode = self.mode.after_change(u - self.u_prev);
        self.u_prev = u;
        u
    }
}
