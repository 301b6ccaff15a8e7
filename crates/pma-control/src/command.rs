use crate::{CommandLimits, NominalModel, Saturation};
use pma_model::DampingMode;

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
        let u = model
            .muscle
            .static_pressure_for(model.load_force_n, x)
            .map_or(limits.min_pa, |p| limits.clamp(p).0);
        Self {
            u_prev: u,
            mode: DampingMode::Inflation,
            saturation: Saturation::None,
        }
    }

    /// Inverts the nominal model for a desired acceleration: the pressure `u` with
    /// `f(x, v; mode) + b(x, v; mode) u = accel`, clamped and recorded.
    ///
    /// The damping mode of eq. (1) depends on the sign of the pressure change that `u`
    /// itself makes, so the inversion is solved for a *consistent* mode: inflation only
    /// if `u` rises, deflation only if it falls. Using the previous period's mode instead
    /// puts an error of `(b0i - b0d) xdot` (~80 N at 20 mm/s, four times a 2 kg load's
    /// weight) on the plant every time the command turns, which destabilises APRC and STA
    /// without an observer. Where both modes are consistent the current one is kept;
    /// where neither is, the pressure is held, which is consistent by definition.
    ///
    /// While the load rises and decelerates, neither mode has a monotone solution (the
    /// inflation damping is several times the deflation one), and an exact inversion
    /// alternates between the modes with pressure jumps of ~0.5 bar at ~40 Hz. So a
    /// direction reversal is only taken when the current mode misses the required pressure
    /// by more than [`NominalModel::mode_switch_band`]; below that the pressure is held and
    /// the feedback absorbs the small acceleration error.
    pub fn invert(
        &mut self,
        limits: &CommandLimits,
        model: &NominalModel,
        x: f64,
        v: f64,
        accel: f64,
    ) -> f64 {
        let solve = |mode| (accel - model.drift(x, v, mode)) / model.safe_input_gain(x, v, mode);
        let consistent =
            |mode, u: f64| u == self.u_prev || self.mode.after_change(u - self.u_prev) == mode;
        let current = self.mode;
        let other = match current {
            DampingMode::Inflation => DampingMode::Deflation,
            DampingMode::Deflation => DampingMode::Inflation,
        };
        let u_current = solve(current);
        let raw = if consistent(current, u_current) {
            u_current
        } else {
            let u_other = solve(other);
            let band = model.mode_switch_band((u_other - u_current).abs());
            if (u_current - self.u_prev).abs() > band && consistent(other, u_other) {
                u_other
            } else {
                self.u_prev
            }
        };
        self.apply(limits, raw)
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
