use crate::{CommandLimits, NominalModel, Saturation};
use pma_model::DampingMode;

/// What every controller remembers about its own last command: the value held over the
/// coming period (the disturbance observer needs it), the damping mode its change implies,
/// and whether it was clamped (for anti-windup).
#[derive(Debug, Clone, Copy)]
pub(crate) struct CommandState {
    pub u_prev: f64,
    /// The pressure per the nominal valve (equal to `u_prev` without valve lag): what the
    /// disturbance observer takes as the input, and what the damping mode follows.
    pub pressure_hat: f64,
    pub mode: DampingMode,
    pub saturation: Saturation,
    /// The state before the last command, to redo it with what was actually applied.
    before: (f64, f64, DampingMode),
    /// The nominal valve's fraction per period used by the last command.
    alpha: f64,
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
            pressure_hat: u,
            mode: DampingMode::Inflation,
            saturation: Saturation::None,
            before: (u, u, DampingMode::Inflation),
            alpha: 1.0,
        }
    }

    /// The actuator got `applied` instead of the last command (a supervisor clamped or
    /// rate-limited it): the last command is redone with it, and the difference counts as
    /// a saturation in its direction, so that integrators and adaptive gains do not wind
    /// up against a limit they cannot see. Nothing changes when `applied` is the command.
    pub fn applied(&mut self, applied: f64) {
        if applied.to_bits() == self.u_prev.to_bits() {
            return;
        }
        let applied = if applied.is_nan() { 0.0 } else { applied };
        let (_, p_before, mode_before) = self.before;
        let p_next = if self.alpha >= 1.0 {
            applied
        } else {
            p_before + self.alpha * (applied - p_before)
        };
        self.saturation = if applied < self.u_prev {
            Saturation::High
        } else {
            Saturation::Low
        };
        self.mode = mode_before.after_change(p_next - p_before);
        self.u_prev = applied;
        self.pressure_hat = p_next;
    }

    /// A pressure sensor's reading replaces the nominal valve's estimate of the pressure
    /// the last command has made (the observer's input).
    pub fn sensed(&mut self, pressure_pa: f64) {
        if pressure_pa.is_finite() {
            self.pressure_hat = pressure_pa;
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
    ///
    /// With a nominal valve lag the result is the *pressure* wanted at the end of the
    /// period, and the command is the one that takes the nominal valve there (see
    /// [`CommandState::apply_through_valve`]).
    pub fn invert(
        &mut self,
        limits: &CommandLimits,
        model: &NominalModel,
        state: (f64, f64),
        accel: f64,
        dt: f64,
    ) -> f64 {
        let (x, v) = state;
        let solve = |mode| (accel - model.drift(x, v, mode)) / model.safe_input_gain(x, v, mode);
        let p_prev = self.pressure_hat;
        let consistent = |mode, u: f64| u == p_prev || self.mode.after_change(u - p_prev) == mode;
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
            if (u_current - p_prev).abs() > band && consistent(other, u_other) {
                u_other
            } else {
                p_prev
            }
        };
        self.apply_through_valve(limits, raw, model.valve_alpha(dt))
    }

    /// Commands the pressure `wanted` through a nominal valve that covers the fraction
    /// `alpha` of the way per period: `u = p + (wanted - p) / alpha`, clamped, and the
    /// nominal pressure advanced with the clamped command (so a clamp never winds it up).
    /// `alpha = 1` is [`CommandState::apply`].
    pub fn apply_through_valve(&mut self, limits: &CommandLimits, wanted: f64, alpha: f64) -> f64 {
        if alpha >= 1.0 {
            return self.apply(limits, wanted);
        }
        self.before = (self.u_prev, self.pressure_hat, self.mode);
        self.alpha = alpha;
        let p = self.pressure_hat;
        let (u, sat) = limits.clamp(p + (wanted - p) / alpha);
        let p_next = p + alpha * (u - p);
        self.saturation = sat;
        self.mode = self.mode.after_change(p_next - p);
        self.u_prev = u;
        self.pressure_hat = p_next;
        u
    }

    /// Clamps the raw command, records saturation and damping mode, returns the command.
    pub fn apply(&mut self, limits: &CommandLimits, raw: f64) -> f64 {
        self.before = (self.u_prev, self.pressure_hat, self.mode);
        self.alpha = 1.0;
        let (u, sat) = limits.clamp(raw);
        self.saturation = sat;
        self.mode = self.mode.after_change(u - self.u_prev);
        self.u_prev = u;
        self.pressure_hat = u;
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> CommandLimits {
        CommandLimits {
            min_pa: 0.0,
            max_pa: 6e5,
        }
    }

    /// The paper's model with a 20 ms valve, and its `alpha` at 1 kHz.
    fn lagged() -> (NominalModel, f64) {
        let model = NominalModel {
            valve_time_constant_s: 0.020,
            ..NominalModel::paper()
        };
        (model, model.valve_alpha(1e-3))
    }

    #[test]
    fn the_nominal_valve_reaches_the_wanted_pressure_in_one_period() {
        let (model, alpha) = lagged();
        assert!((alpha - (1.0 - (-0.05f64).exp())).abs() < 1e-15);
        let mut c = CommandState::at_rest(&model, &limits(), 0.0);
        let p0 = c.pressure_hat;
        let u = c.apply_through_valve(&limits(), p0 + 1000.0, alpha);
        // The command overshoots by 1/alpha so the lagged pressure lands on the target.
        assert!((u - (p0 + 1000.0 / alpha)).abs() < 1e-6);
        assert!((c.pressure_hat - (p0 + 1000.0)).abs() < 1e-9);
        assert_eq!(c.saturation, Saturation::None);
        assert_eq!(c.mode, DampingMode::Inflation);
    }

    #[test]
    fn a_clamped_command_advances_the_nominal_pressure_only_as_far_as_the_valve_goes() {
        let (model, alpha) = lagged();
        let mut c = CommandState::at_rest(&model, &limits(), 0.0);
        let p0 = c.pressure_hat;
        let u = c.apply_through_valve(&limits(), 5.9e5, alpha);
        assert_eq!(u, 6e5);
        assert_ne!(c.saturation, Saturation::None);
        assert!((c.pressure_hat - (p0 + alpha * (6e5 - p0))).abs() < 1e-9);
        // Falling: the mode follows the pressure, not the command.
        let p1 = c.pressure_hat;
        c.apply_through_valve(&limits(), p1 - 10.0, alpha);
        assert_eq!(c.mode, DampingMode::Deflation);
    }

    #[test]
    fn without_lag_the_valve_inversion_is_the_plain_clamp() {
        let model = NominalModel::paper();
        assert_eq!(model.valve_alpha(1e-3), 1.0);
        let mut a = CommandState::at_rest(&model, &limits(), 0.01);
        let mut b = a;
        for wanted in [1e5, 2.5e5, -3.0, 7e5, 3e5] {
            assert_eq!(
                a.apply_through_valve(&limits(), wanted, 1.0),
                b.apply(&limits(), wanted)
            );
            assert_eq!(a.pressure_hat, b.u_prev);
        }
    }

    #[test]
    fn a_command_the_supervisor_limited_is_remembered_as_applied() {
        let model = NominalModel::paper();
        let mut c = CommandState::at_rest(&model, &limits(), 0.01);
        let before = c;
        let u = c.apply(&limits(), before.u_prev + 2.0e5);
        assert_eq!(c.saturation, Saturation::None);
        // The valve got only half of the step: the state is as if that had been commanded,
        // and the cut counts as a saturation upwards.
        let applied = before.u_prev + 1.0e5;
        c.applied(applied);
        assert_eq!(c.u_prev, applied);
        assert_eq!(c.pressure_hat, applied);
        assert_eq!(c.saturation, Saturation::High);
        // Nothing changes when the valve got the command itself.
        let mut d = CommandState::at_rest(&model, &limits(), 0.01);
        let u2 = d.apply(&limits(), u);
        let snapshot = (d.u_prev, d.pressure_hat, d.saturation);
        d.applied(u2);
        assert_eq!(snapshot, (d.u_prev, d.pressure_hat, d.saturation));
    }
}
