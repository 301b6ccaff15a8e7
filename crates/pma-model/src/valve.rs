use crate::error::{non_negative, positive, within, Invalid};
use crate::pneumatics::{FirstOrderFactor, FlowParams, FlowState, PRESSURE_STEP_MAX_S};
use crate::DampingMode;

/// Shortest command period the dead-time buffer is sized for (s). Commands sent faster
/// than this with a dead time overwrite the oldest pending command instead of allocating.
const MIN_COMMAND_PERIOD_S: f64 = 1e-4;
/// How close to a step's end a delayed command counts as arriving at it (s): a dead time
/// that is a whole number of steps arrives at a step's end despite rounding.
const DUE_TOLERANCE_S: f64 = 1e-12;

/// Highest valve pressure accepted (Pa): 10 bar.
pub const MAX_VALVE_PRESSURE_PA: f64 = 1.0e6;
/// Longest valve time constant or dead time accepted (s); the dead-time buffer is sized
/// from it.
pub const MAX_VALVE_DELAY_S: f64 = 1.0;

/// Proportional pressure valve. The paper's model feeds the command straight into the
/// muscle ([`ValveParams::ideal`]); a real valve lags, so the lag is explicit here.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ValveParams {
    /// Highest pressure the valve delivers (Pa); commands are clamped to `[0, max]`.
    pub pressure_max_pa: f64,
    /// First-order time constant (s); `0` for an instantaneous valve.
    #[cfg_attr(feature = "serde", serde(default))]
    pub time_constant_s: f64,
    /// Largest pressure rate (Pa/s); `None` for unlimited.
    #[cfg_attr(feature = "serde", serde(default))]
    pub rate_limit_pa_per_s: Option<f64>,
    /// Transport delay between command and valve response (s).
    #[cfg_attr(feature = "serde", serde(default))]
    pub dead_time_s: f64,
    /// A flow-limited valve ([`crate::pneumatics`]): the pressure a state of the muscle's
    /// air, filled and emptied through ISO 6358 orifices. Set from `[plant.pneumatics]`,
    /// never from the `[plant.valve]` table; `None`: the lag model above.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub flow: Option<FlowParams>,
}

impl ValveParams {
    /// The paper's plant: pressure equals the (clamped) command at once. 0-6 bar, the
    /// operating range of the Festo DMSP-20 muscle.
    pub const fn ideal() -> Self {
        Self {
            pressure_max_pa: 6.0e5,
            time_constant_s: 0.0,
            rate_limit_pa_per_s: None,
            dead_time_s: 0.0,
            flow: None,
        }
    }

    /// First-order lag with time constant `tau_s`.
    pub const fn with_lag(self, tau_s: f64) -> Self {
        Self {
            time_constant_s: tau_s,
            ..self
        }
    }

    /// Checks ranges: positive maximum, non-negative lag and dead time, positive rate limit.
    pub fn validate(&self) -> Result<(), Invalid> {
        positive("pressure_max_pa", self.pressure_max_pa)?;
        within(
            "pressure_max_pa",
            self.pressure_max_pa,
            0.0,
            MAX_VALVE_PRESSURE_PA,
            "must be > 0 and at most 10 bar (a Festo VPPM regulates 0-10 bar)",
        )?;
        non_negative("time_constant_s", self.time_constant_s)?;
        within(
            "time_constant_s",
            self.time_constant_s,
            0.0,
            MAX_VALVE_DELAY_S,
            "must be 0 to 1 s (a proportional valve settles in tens of milliseconds)",
        )?;
        non_negative("dead_time_s", self.dead_time_s)?;
        within(
            "dead_time_s",
            self.dead_time_s,
            0.0,
            MAX_VALVE_DELAY_S,
            "must be 0 to 1 s (a proportional valve settles in tens of milliseconds)",
        )?;
        if let Some(r) = self.rate_limit_pa_per_s {
            positive("rate_limit_pa_per_s", r)?;
        }
        Ok(())
    }

    /// Whether the output follows the command instantly.
    pub fn is_instantaneous(&self) -> bool {
        self.time_constant_s == 0.0
            && self.rate_limit_pa_per_s.is_none()
            && self.dead_time_s == 0.0
            && self.flow.is_none()
    }

    /// What this valve is, in a few words: `ideal`, `first-order lag 20 ms`, or the flow
    /// model's conductance and supply.
    pub fn describe(&self) -> String {
        if let Some(f) = &self.flow {
            return format!(
                "flow-limited (ISO 6358 C = {:.2} l/(s bar), b = {:.2}; supply {:.1} bar; transport delay {:.1} ms)",
                f.inlet_conductance_m3_s_pa / crate::pneumatics::L_PER_S_BAR,
                f.inlet_critical_ratio,
                f.supply_pa / 1e5,
                self.dead_time_s * 1e3
            );
        }
        if self.is_instantaneous() {
            return "ideal (instantaneous)".into();
        }
        let mut parts = Vec::new();
        if self.time_constant_s > 0.0 {
            parts.push(format!("first-order lag {} ms", self.time_constant_s * 1e3));
        }
        if let Some(r) = self.rate_limit_pa_per_s {
            parts.push(format!("rate limit {} bar/s", r / 1e5));
        }
        if self.dead_time_s > 0.0 {
            parts.push(format!("dead time {} ms", self.dead_time_s * 1e3));
        }
        parts.join(", ")
    }

    /// Clamps a command to the valve's range; NaN becomes 0 (vent), the safe value.
    pub fn clamp(&self, command_pa: f64) -> f64 {
        if command_pa.is_nan() {
            0.0
        } else {
            command_pa.clamp(0.0, self.pressure_max_pa)
        }
    }
}

impl Default for ValveParams {
    fn default() -> Self {
        Self::ideal()
    }
}

/// Valve state: output pressure, the damping mode its last change implies, and commands
/// still in transit through the dead time.
#[derive(Debug, Clone)]
pub struct Valve {
    params: ValveParams,
    pressure_pa: f64,
    target_pa: f64,
    set_point_pa: f64,
    mode: DampingMode,
    /// The spool's opening of a flow-limited valve (-1..1).
    opening: f64,
    clock_s: f64,
    pending: Vec<(f64, f64)>,
    pending_head: usize,
    pending_len: usize,
    /// The lag's factor `1 - exp(-h / tau)`, kept between steps: every substep has the
    /// same length, and the exponential was 14 % of a single-muscle period.
    lag: FirstOrderFactor,
    /// A flow-limited valve's spool factor over its internal step, kept alike.
    spool: FirstOrderFactor,
}

impl Valve {
    /// A valve at `initial_pa` (clamped), all buffers allocated here.
    pub fn new(params: ValveParams, initial_pa: f64) -> Result<Self, Invalid> {
        params.validate()?;
        let p = params.clamp(initial_pa);
        let capacity = (params.dead_time_s / MIN_COMMAND_PERIOD_S).ceil() as usize + 2;
        Ok(Self {
            params,
            pressure_pa: p,
            target_pa: p,
            set_point_pa: p,
            mode: DampingMode::Inflation,
            opening: 0.0,
            clock_s: 0.0,
            pending: vec![(0.0, p); capacity],
            pending_head: 0,
            pending_len: 0,
            lag: FirstOrderFactor::default(),
            spool: FirstOrderFactor::default(),
        })
    }

    /// Parameters.
    pub fn params(&self) -> &ValveParams {
        &self.params
    }

    /// Output pressure (Pa).
    pub fn pressure(&self) -> f64 {
        self.pressure_pa
    }

    /// The last set point issued (clamped), whether or not it has taken effect yet.
    pub fn set_point(&self) -> f64 {
        self.set_point_pa
    }

    /// Damping mode implied by the last pressure change.
    pub fn mode(&self) -> DampingMode {
        self.mode
    }

    /// Issues a new set point (clamped to the valve range). An instantaneous valve jumps
    /// now; otherwise the command takes effect after the dead time and the lag.
    pub fn command(&mut self, command_pa: f64) {
        let c = self.params.clamp(command_pa);
        self.set_point_pa = c;
        if self.params.dead_time_s > 0.0 {
            self.push_pending(self.clock_s + self.params.dead_time_s, c);
        } else {
            self.target_pa = c;
        }
        if self.params.is_instantaneous() {
            self.set_pressure(c);
        }
    }

    /// Advances the valve by `h_s` seconds with the current command held, the muscle at
    /// contraction `x_m` moving at `v_m_s`: a flow-limited valve fills the muscle's
    /// volume there; the lag model ignores both.
    pub fn advance_at(&mut self, h_s: f64, x_m: f64, v_m_s: f64) {
        let Some(flow) = self.params.flow else {
            return self.advance(h_s);
        };
        self.in_pieces(h_s, |valve, piece| {
            let mut state = FlowState {
                pressure_pa: valve.pressure_pa,
                opening: valve.opening,
            };
            flow.advance_remembering(
                &mut state,
                valve.target_pa,
                piece,
                (x_m, v_m_s),
                PRESSURE_STEP_MAX_S,
                &mut valve.spool,
            );
            valve.opening = state.opening;
            valve.set_pressure(state.pressure_pa);
        });
    }

    /// The spool's opening of a flow-limited valve (-1 exhaust .. 1 supply; 0 otherwise).
    pub fn opening(&self) -> f64 {
        self.opening
    }

    /// Advances the valve by `h_s` seconds with the current command held (a flow-limited
    /// valve as if the muscle rested at its nominal length: use [`Valve::advance_at`]).
    pub fn advance(&mut self, h_s: f64) {
        if self.params.flow.is_some() {
            return self.advance_at(h_s, 0.0, 0.0);
        }
        if self.params.is_instantaneous() {
            // `command` already set the pressure; nothing evolves in between.
            self.clock_s += h_s;
            return;
        }
        self.in_pieces(h_s, Self::lag_over);
    }

    /// The lag model over `h_s` toward the current target (none over `h_s = 0` but a
    /// valve without lag or rate limit reaching it).
    fn lag_over(&mut self, h_s: f64) {
        if h_s <= 0.0 && self.params.time_constant_s > 0.0 {
            return;
        }
        let target = self.target_pa;
        let mut next = if self.params.time_constant_s > 0.0 {
            let a = self.lag.at(h_s, self.params.time_constant_s);
            self.pressure_pa + a * (target - self.pressure_pa)
        } else {
            target
        };
        if let Some(r) = self.params.rate_limit_pa_per_s {
            let max_step = r * h_s;
            next = self.pressure_pa + (next - self.pressure_pa).clamp(-max_step, max_step);
        }
        self.set_pressure(next);
    }

    /// Advances the clock by `h_s`, `evolve` running over each piece of it between the
    /// instants at which a delayed command arrives: a command takes effect when its dead
    /// time is over, not at the start of the step it falls in (which shortened the dead
    /// time by up to a step, an error that moved with the step).
    fn in_pieces(&mut self, h_s: f64, mut evolve: impl FnMut(&mut Self, f64)) {
        let end = self.clock_s + h_s;
        // What is left of the step, counted down from `h_s` itself: a step no command
        // splits evolves over exactly `h_s` (not `end - clock`, which rounds differently
        // and would move every lagging valve's trajectory in its last bits).
        let mut left = h_s;
        loop {
            self.release_due_commands();
            let Some(due) = self.next_due_s().filter(|due| *due < end - DUE_TOLERANCE_S) else {
                break;
            };
            let piece = (due - self.clock_s).clamp(0.0, left);
            if piece > 0.0 {
                evolve(self, piece);
            }
            left -= piece;
            self.clock_s = due.max(self.clock_s);
        }
        if left > 0.0 {
            evolve(self, left);
        }
        self.clock_s = end;
        // A command arriving at the step's end: a valve without lag is at it already.
        if self.release_due_commands() {
            evolve(self, 0.0);
        }
    }

    /// When the oldest command in transit arrives (s), if one is.
    fn next_due_s(&self) -> Option<f64> {
        (self.pending_len > 0).then(|| self.pending[self.pending_head].0)
    }

    fn set_pressure(&mut self, p: f64) {
        self.mode = self.mode.after_change(p - self.pressure_pa);
        self.pressure_pa = p;
    }

    fn push_pending(&mut self, due_s: f64, command_pa: f64) {
        let cap = self.pending.len();
        if self.pending_len == cap {
            // Full: commands arrive faster than the buffer was sized for; the oldest one
            // has the least time left in transit, so apply it now.
            self.target_pa = self.pending[self.pending_head].1;
            self.pending_head = (self.pending_head + 1) % cap;
            self.pending_len -= 1;
        }
        let tail = (self.pending_head + self.pending_len) % cap;
        self.pending[tail] = (due_s, command_pa);
        self.pending_len += 1;
    }

    /// Makes every command whose dead time is over the target; whether there was one.
    fn release_due_commands(&mut self) -> bool {
        let cap = self.pending.len();
        let mut released = false;
        // A small tolerance so that a dead time that is a whole number of periods releases
        // the command on the period it is due, not one later through rounding.
        while self.pending_len > 0
            && self.pending[self.pending_head].0 <= self.clock_s + DUE_TOLERANCE_S
        {
            self.target_pa = self.pending[self.pending_head].1;
            self.pending_head = (self.pending_head + 1) % cap;
            self.pending_len -= 1;
            released = true;
        }
        released
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ideal_valve_follows_command_and_clamps() {
        let mut v = Valve::new(ValveParams::ideal(), 0.0).unwrap();
        v.command(2.0e5);
        assert_eq!(v.pressure(), 2.0e5);
        v.command(9.0e5);
        assert_eq!(v.pressure(), 6.0e5);
        v.command(-1.0);
        assert_eq!(v.pressure(), 0.0);
        assert_eq!(v.mode(), DampingMode::Deflation);
        v.command(f64::NAN);
        assert_eq!(v.pressure(), 0.0);
    }

    #[test]
    fn lag_matches_the_exponential_step_response() {
        let tau = 0.02;
        let mut v = Valve::new(ValveParams::ideal().with_lag(tau), 0.0).unwrap();
        v.command(1.0e5);
        let h = 1e-4;
        for _ in 0..200 {
            v.advance(h);
        }
        let exact = 1.0e5 * (1.0 - (-0.02_f64 / tau).exp());
        assert!(
            (v.pressure() - exact).abs() < 1e-6,
            "{} vs {exact}",
            v.pressure()
        );
    }

    #[test]
    fn rate_limit_bounds_the_slope() {
        let p = ValveParams {
            rate_limit_pa_per_s: Some(1.0e6),
            ..ValveParams::ideal()
        };
        let mut v = Valve::new(p, 0.0).unwrap();
        v.command(5.0e5);
        v.advance(0.1);
        assert!((v.pressure() - 1.0e5).abs() < 1e-6);
    }

    #[test]
    fn dead_time_delays_the_command() {
        let p = ValveParams {
            dead_time_s: 0.005,
            ..ValveParams::ideal()
        };
        let mut v = Valve::new(p, 0.0).unwrap();
        v.command(3.0e5);
        for _ in 0..4 {
            v.advance(0.001);
            assert_eq!(v.pressure(), 0.0);
        }
        v.advance(0.001);
        assert_eq!(v.pressure(), 3.0e5);
    }

    /// Regression: a delayed command took effect at the start of the step its dead time
    /// ended in, up to a step early (a 2.9 ms tube delay acted as 2 ms at the trainer's
    /// 1 ms step, 2.875 ms at 1/16 ms), so the loop's delay moved with the step.
    #[test]
    fn a_dead_time_is_not_shortened_by_a_coarse_step() {
        let (tau, dead) = (0.010, 0.0029);
        let p = ValveParams {
            dead_time_s: dead,
            ..ValveParams::ideal().with_lag(tau)
        };
        let exact = |t: f64| 3.0e5 * (1.0 - (-(t - dead).max(0.0) / tau).exp());
        for steps_per_ms in [1, 4, 16] {
            let h = 1e-3 / f64::from(steps_per_ms);
            let mut v = Valve::new(p, 0.0).unwrap();
            v.command(3.0e5);
            for k in 1..=10 * steps_per_ms {
                v.advance(h);
                let t = f64::from(k) * h;
                assert!(
                    (v.pressure() - exact(t)).abs() < 1e-6,
                    "{steps_per_ms} steps/ms, t = {t}: {} against {}",
                    v.pressure(),
                    exact(t)
                );
            }
        }
    }

    #[test]
    fn invalid_params_are_rejected() {
        let p = ValveParams {
            time_constant_s: -1.0,
            ..ValveParams::ideal()
        };
        assert!(Valve::new(p, 0.0).is_err());
    }
}
