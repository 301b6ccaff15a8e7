use crate::{PlantConfig, SimError};
use pma_control::Measurement;
use pma_loop::{Backend, Started};
use pma_model::{LoadProfile, MuscleParams, PositionSensor, Valve, GRAVITY_M_S2};
use std::convert::Infallible;

/// The paper's sampling period (s): a bench's control period unless
/// [`MuscleBench::with_period`] says otherwise.
pub const PAPER_PERIOD_S: f64 = 1e-3;

/// The bench's true state at a reading: what the sensor does not tell the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchState {
    /// True contraction (m).
    pub position_m: f64,
    /// True velocity (m/s).
    pub velocity_m_s: f64,
    /// Pressure in the muscle (Pa).
    pub pressure_pa: f64,
    /// Muscle force (N).
    pub force_n: f64,
    /// Force of the obstacle on the load (N, >= 0, pushing it down).
    pub contact_force_n: f64,
    /// External force on the load (N, positive lifting).
    pub external_force_n: f64,
}

/// One muscle holding a hanging load (the paper's Fig. 3 rig):
/// `m(t) xddot = F(P, x, xdot) - m(t) g`, `F` eq. (1) clamped at zero.
///
/// Integration: with the damping pole `b/m ~ 3000 1/s` at 2 kg, explicit Euler at the
/// 1 ms control period diverges. With the exact step on (the plant file's
/// `exact_held_pressure_step`, the default), where the pressure is held over a period (an instantaneous
/// valve) and nothing else acts on the load, the muscle is a linear oscillator with
/// constant coefficients over it, and the period is one exact step ([`held_pressure_step`];
/// a load step inside the period takes effect at the next one). Otherwise (the exact step
/// off, a lagging or delayed valve, a force pulse, an obstacle, a muscle slack at either end of
/// the period) it is split into `substeps` steps of the trapezoidal rule, which is
/// A-stable and second order; since the force is affine in `(x, xdot)` for a given
/// pressure, its implicit equation is solved in closed form. Where the end-of-step force
/// would be negative the muscle is slack and the step is redone with zero force.
#[derive(Debug, Clone)]
pub struct MuscleBench {
    muscle: MuscleParams,
    load: LoadProfile,
    valve: Valve,
    sensor: PositionSensor,
    substeps: u32,
    exact: bool,
    period_s: f64,
    x: f64,
    v: f64,
    t: f64,
    disturbance: Disturbance,
    stop_m: Option<f64>,
    contact_force_n: f64,
}

/// What else acts on the load: nothing, an external force pulse, or an obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Disturbance {
    /// Nothing.
    #[default]
    None,
    /// A constant force on the load over `[start_s, start_s + duration_s)` (N, positive
    /// in the direction of contraction, i.e. lifting the load).
    ForcePulse {
        /// Start (s).
        start_s: f64,
        /// Duration (s).
        duration_s: f64,
        /// Force (N).
        force_n: f64,
    },
    /// A one-sided stop over `[start_s, start_s + duration_s)`: the load cannot contract
    /// beyond where it was at `start_s` (it is held from rising; it may still fall away).
    /// The stop is inelastic; its contact force is in [`BenchState::contact_force_n`].
    Obstacle {
        /// Start (s).
        start_s: f64,
        /// Duration (s).
        duration_s: f64,
    },
}

impl Disturbance {
    fn active(start_s: f64, duration_s: f64, t: f64) -> bool {
        t >= start_s && t < start_s + duration_s
    }

    /// External force on the load at `t` (N).
    pub fn force_n(&self, t: f64) -> f64 {
        match *self {
            Disturbance::ForcePulse {
                start_s,
                duration_s,
                force_n,
            } if Self::active(start_s, duration_s, t) => force_n,
            _ => 0.0,
        }
    }

    /// Whether an obstacle is in place at `t`.
    pub fn blocks(&self, t: f64) -> bool {
        matches!(*self, Disturbance::Obstacle { start_s, duration_s } if Self::active(start_s, duration_s, t))
    }
}

impl MuscleBench {
    /// A bench at rest at contraction `x0_m`, the valve holding the pressure that
    /// balances the initial load there.
    pub fn at_rest(cfg: &PlantConfig, x0_m: f64) -> Result<Self, SimError> {
        cfg.validate()?;
        let wrap = |source| SimError::Model {
            plant: cfg.name.clone(),
            source,
        };
        let muscle = cfg.true_muscle();
        let w = cfg.load.mass_at(0.0) * GRAVITY_M_S2;
        let p0 = muscle.static_pressure_for(w, x0_m).unwrap_or(0.0);
        Ok(Self {
            muscle,
            load: cfg.load,
            valve: Valve::new(cfg.valve, p0).map_err(wrap)?,
            sensor: PositionSensor::new(cfg.sensor).map_err(wrap)?,
            substeps: cfg.substeps_per_period,
            exact: cfg.exact_held_pressure_step,
            period_s: PAPER_PERIOD_S,
            x: x0_m,
            v: 0.0,
            t: 0.0,
            disturbance: Disturbance::None,
            stop_m: None,
            contact_force_n: 0.0,
        })
    }

    /// A bench at rest with the muscle vented: the load hangs where the unpressurised
    /// muscle holds it (a rig before its valve goes live).
    pub fn vented(cfg: &PlantConfig) -> Result<Self, SimError> {
        let w = cfg.load.mass_at(0.0) * GRAVITY_M_S2;
        let x0 = cfg
            .true_muscle()
            .static_contraction_for(w, 0.0)
            .unwrap_or(0.0);
        let mut bench = Self::at_rest(cfg, x0)?;
        bench.valve = Valve::new(cfg.valve, 0.0).map_err(|source| SimError::Model {
            plant: cfg.name.clone(),
            source,
        })?;
        Ok(bench)
    }

    /// With a disturbance (a force pulse, an obstacle) acting on the load.
    pub fn with_disturbance(mut self, disturbance: Disturbance) -> Self {
        self.disturbance = disturbance;
        self
    }

    /// With this control period (s) when it runs in the loop.
    pub fn with_period(mut self, period_s: f64) -> Self {
        self.period_s = period_s;
        self
    }

    /// Overrides the substep count (for convergence studies).
    pub fn with_substeps(mut self, substeps: u32) -> Self {
        self.substeps = substeps.max(1);
        self
    }

    /// With or without the exact step where the pressure is held (the plant file's
    /// `exact_held_pressure_step` otherwise).
    pub fn with_exact_step(mut self, exact: bool) -> Self {
        self.exact = exact;
        self
    }

    /// Velocity (m/s).
    pub fn velocity(&self) -> f64 {
        self.v
    }

    /// Muscle force at the current state (N).
    pub fn force(&self) -> f64 {
        self.muscle
            .force(self.valve.pressure(), self.x, self.v, self.valve.mode())
    }

    fn substep(&mut self, h: f64) {
        let inv_m = 1.0 / self.load.mass_at(self.t);
        let p0 = self.valve.pressure();
        self.valve.advance(h);
        let (p1, mode) = (self.valve.pressure(), self.valve.mode());
        // The damping mode belongs to the substep (the direction the pressure moves in
        // over it), so both ends of the trapezoid use it; taking the previous mode at the
        // left end makes the scheme first order wherever the pressure turns.
        let mu = &self.muscle;
        let (ext0, ext1) = (
            self.disturbance.force_n(self.t),
            self.disturbance.force_n(self.t + h),
        );
        let f_start = mu.force(p0, self.x, self.v, mode);
        let a0 = (f_start + ext0) * inv_m - GRAVITY_M_S2;
        let (c, k, b) = (
            mu.contractile_force(p1),
            mu.stiffness(p1),
            mu.damping(p1, mode),
        );
        // Trapezoid: x1 = x0 + h/2 (v0 + v1), v1 = v0 + h/2 (a0 + a1),
        // a1 = (c - k x1 - b v1)/m - g, solved for v1.
        let hh = 0.5 * h;
        let rhs = self.v
            + hh * a0
            + hh * ((c + ext1 - k * (self.x + hh * self.v)) * inv_m - GRAVITY_M_S2);
        let mut v1 = rhs / (1.0 + hh * (k * hh + b) * inv_m);
        let mut x1 = self.x + hh * (self.v + v1);
        if c - k * x1 - b * v1 < 0.0 {
            v1 = self.v + hh * (a0 + ext1 * inv_m - GRAVITY_M_S2);
            x1 = self.x + hh * (self.v + v1);
        }
        self.contact_force_n = 0.0;
        self.apply_stop(&mut x1, &mut v1, p1, ext1);
        self.x = x1;
        self.v = v1;
        self.t += h;
    }
}

impl MuscleBench {
    /// One exact step of `dt_s` where its conditions hold (see the struct's doc); `false`
    /// leaves the bench untouched for the substeps.
    fn held_step(&mut self, dt_s: f64) -> bool {
        if !self.valve.params().is_instantaneous() || self.disturbance != Disturbance::None {
            return false;
        }
        let (p, mode) = (self.valve.pressure(), self.valve.mode());
        let mu = &self.muscle;
        let m = self.load.mass_at(self.t);
        let (c, k, b) = (
            mu.contractile_force(p),
            mu.stiffness(p),
            mu.damping(p, mode),
        );
        // The equilibrium form divides by the stiffness: below 1e-6 of the step's inertia
        // (2 N/m at 2 kg and 1 ms) the substeps are the better conditioned.
        if k * dt_s * dt_s <= 1e-6 * m || b <= 0.0 || c - k * self.x - b * self.v < 0.0 {
            return false;
        }
        let x_eq = (c - m * GRAVITY_M_S2) / k;
        let (y1, v1) = held_pressure_step(self.x - x_eq, self.v, dt_s, k / m, b / m);
        let x1 = x_eq + y1;
        if c - k * x1 - b * v1 < 0.0 {
            return false;
        }
        self.valve.advance(dt_s);
        self.x = x1;
        self.v = v1;
        self.t += dt_s;
        self.contact_force_n = 0.0;
        true
    }

    /// The obstacle: set where the load is when it appears, it holds the load there
    /// (inelastic: the velocity towards it is lost) and pushes with what the muscle pulls
    /// beyond the load's weight.
    fn apply_stop(&mut self, x1: &mut f64, v1: &mut f64, p1: f64, ext1: f64) {
        if !self.disturbance.blocks(self.t) {
            self.stop_m = None;
            return;
        }
        let stop = *self.stop_m.get_or_insert(self.x);
        if *x1 > stop {
            *x1 = stop;
            *v1 = v1.min(0.0);
            let weight = self.load.mass_at(self.t) * GRAVITY_M_S2;
            let pull = self.muscle.force(p1, stop, 0.0, self.valve.mode());
            self.contact_force_n = (pull + ext1 - weight).max(0.0);
        }
    }

    /// Sensor reading at the current time (draws the sensor's noise).
    pub fn measure(&mut self) -> Measurement {
        Measurement {
            position_m: self.sensor.measure(self.x),
        }
    }

    /// Sends a pressure command and advances the bench by `dt_s` with it held (open-loop
    /// use; the closed loop goes through [`Backend`]).
    pub fn apply(&mut self, pressure_cmd_pa: f64, dt_s: f64) {
        self.valve.command(pressure_cmd_pa);
        self.advance(dt_s);
    }

    /// Sends a pressure command to the valve (clamped to its range; NaN vents).
    pub fn command(&mut self, pressure_cmd_pa: f64) {
        self.valve.command(pressure_cmd_pa);
    }

    /// Advances the bench by `dt_s` with the current command held.
    pub fn advance(&mut self, dt_s: f64) {
        if self.exact && self.held_step(dt_s) {
            return;
        }
        let h = dt_s / f64::from(self.substeps);
        for _ in 0..self.substeps {
            self.substep(h);
        }
    }

    /// Puts the load at `position_m` moving at `velocity_m_s`, the valve and the clock
    /// unchanged: a fit that restarts its simulation from the measured state at intervals
    /// (multiple shooting) so that one divergence does not spoil the rest of a log.
    pub fn set_motion(&mut self, position_m: f64, velocity_m_s: f64) {
        self.x = position_m;
        self.v = velocity_m_s;
    }

    /// True contraction (m).
    pub fn position(&self) -> f64 {
        self.x
    }

    /// True pressure in the muscle (Pa).
    pub fn pressure(&self) -> f64 {
        self.valve.pressure()
    }

    /// Bench time (s).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// The true state.
    pub fn state(&self) -> BenchState {
        BenchState {
            position_m: self.x,
            velocity_m_s: self.v,
            pressure_pa: self.valve.pressure(),
            force_n: self.force(),
            contact_force_n: self.contact_force_n,
            external_force_n: self.disturbance.force_n(self.t),
        }
    }
}

/// The exact solution after `h_s` of `y'' + 2 zeta w y' + w^2 y = 0` from `(y0, v0)`, with
/// `w2_per_s2` = `w^2` = `k / m` and `damping_per_s` = `2 zeta w` = `b / m` (both > 0):
/// the muscle at a held pressure about its equilibrium. Returns `(y(h), y'(h))`.
///
/// With `s = -b / 2m` and `q = s^2 - k/m`, `y(t) = e^(st) [C y0 + S (v0 - s y0)]` and
/// `y'(t) = e^(st) [C v0 + S (s v0 - k/m y0)]`, where `C = cosh(sqrt(q) t)` and
/// `S = sinh(sqrt(q) t) / sqrt(q)` (`cos` and `sin` for `q < 0`); near critical damping
/// (`|q| t^2 < 0.01`) their series, whose fifth terms are below 1e-13 of the first.
///
/// ```
/// use pma_bench::held_pressure_step;
/// // A lightly damped oscillator (w = 10 rad/s, b/m = 0.2 1/s) a quarter period after
/// // rest at 1: near 0, moving at about -w.
/// let w = 10.0_f64;
/// let (y, v) = held_pressure_step(1.0, 0.0, std::f64::consts::FRAC_PI_2 / w, w * w, 0.2);
/// assert!(y.abs() < 0.02 && (v + w).abs() < 0.3);
/// ```
pub fn held_pressure_step(
    y0: f64,
    v0: f64,
    h_s: f64,
    w2_per_s2: f64,
    damping_per_s: f64,
) -> (f64, f64) {
    let s = -0.5 * damping_per_s;
    let q = s * s - w2_per_s2;
    let z = q * h_s * h_s;
    // `ec` = e^(sh) C and `es` = e^(sh) S.
    let (ec, es) = if z.abs() < 1e-2 {
        let e = (s * h_s).exp();
        let c = 1.0 + z * (1.0 / 2.0 + z * (1.0 / 24.0 + z * (1.0 / 720.0 + z / 40_320.0)));
        let sh =
            h_s * (1.0 + z * (1.0 / 6.0 + z * (1.0 / 120.0 + z * (1.0 / 5040.0 + z / 362_880.0))));
        (e * c, e * sh)
    } else if q > 0.0 {
        // Overdamped (the muscle: b/m ~ 3000 1/s against k/m ~ 10^4 1/s^2): the two real
        // modes, both decaying since k > 0.
        let d = q.sqrt();
        let (slow, fast) = (((s + d) * h_s).exp(), ((s - d) * h_s).exp());
        (0.5 * (slow + fast), 0.5 * (slow - fast) / d)
    } else {
        let w = (-q).sqrt();
        let e = (s * h_s).exp();
        let (sin, cos) = (w * h_s).sin_cos();
        (e * cos, e * sin / w)
    };
    (
        ec * y0 + es * (v0 - s * y0),
        ec * v0 + es * (s * v0 - w2_per_s2 * y0),
    )
}

/// The bench in the closed loop: the valve takes the command at once (its own lag and
/// dead time apply), `wait` integrates the period, nothing can fail.
impl Backend for MuscleBench {
    type Reading = Measurement;
    type Command = f64;
    type Truth = BenchState;
    type Error = Infallible;

    /// The valve holds the pressure that balances the load where the bench was put.
    fn start(&mut self) -> Result<Started<Measurement, f64>, Infallible> {
        let reading = self.measure();
        let p0 = self.valve.pressure();
        self.valve.command(p0);
        Ok(Started {
            t_s: self.t,
            reading,
            command: p0,
        })
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn wait(&mut self) -> Result<u32, Infallible> {
        self.advance(self.period_s);
        Ok(1)
    }

    fn read(&mut self) -> Result<Measurement, Infallible> {
        Ok(self.measure())
    }

    fn write(&mut self, pressure_cmd_pa: &f64) -> Result<f64, Infallible> {
        self.valve.command(*pressure_cmd_pa);
        Ok(self.valve.params().clamp(*pressure_cmd_pa))
    }

    fn truth(&self) -> BenchState {
        self.state()
    }

    /// Vents the muscle.
    fn stop(&mut self) {
        self.valve.command(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ideal() -> PlantConfig {
        PlantConfig::preset("ideal").unwrap()
    }

    #[test]
    fn resting_bench_stays_at_rest() {
        let mut b = MuscleBench::at_rest(&ideal(), 0.02).unwrap();
        let p = b.pressure();
        for _ in 0..5000 {
            b.apply(p, 1e-3);
        }
        assert!((b.position() - 0.02).abs() < 1e-12, "{}", b.position());
    }

    #[test]
    fn pressure_step_settles_at_the_static_equilibrium() {
        let cfg = ideal();
        let mut b = MuscleBench::at_rest(&cfg, 0.0).unwrap();
        let m = cfg.true_muscle();
        let p = m.static_pressure_for(2.0 * GRAVITY_M_S2, 0.025).unwrap();
        // Slow pole k/b ~ 1.1 1/s at 1.1 bar while inflating: 30 s is ~33 time constants.
        for _ in 0..30_000 {
            b.apply(p, 1e-3);
        }
        assert!((b.position() - 0.025).abs() < 1e-9, "{}", b.position());
    }

    #[test]
    fn step_response_matches_the_analytic_overdamped_solution() {
        // Constant pressure, linear ODE m x'' + b x' + k x = c - m g: compare with the
        // closed-form solution of the two real roots.
        // The exact step, and the trapezoid it replaced at 8 substeps.
        for (bench, tolerance_m) in [
            (
                MuscleBench::at_rest(&ideal(), 0.0)
                    .unwrap()
                    .with_exact_step(true),
                1e-13,
            ),
            (
                MuscleBench::at_rest(&ideal(), 0.0)
                    .unwrap()
                    .with_exact_step(false)
                    .with_substeps(8),
                1e-8,
            ),
        ] {
            let worst = worst_against_the_overdamped_solution(bench);
            assert!(worst < tolerance_m, "worst {worst} m");
        }
    }

    fn worst_against_the_overdamped_solution(mut bench: MuscleBench) -> f64 {
        let cfg = ideal();
        let mu = cfg.true_muscle();
        let p = 0.9e5;
        bench.apply(p, 1e-3); // the first period switches the valve; from here P is constant
        let (x0, v0, t0) = (bench.position(), bench.velocity(), bench.time());
        let (m, k, b) = (
            2.0,
            mu.stiffness(p),
            mu.damping(p, pma_model::DampingMode::Inflation),
        );
        let xe = (mu.contractile_force(p) - m * GRAVITY_M_S2) / k;
        let disc = (b * b - 4.0 * m * k).sqrt();
        let (r1, r2) = ((-b + disc) / (2.0 * m), (-b - disc) / (2.0 * m));
        let (y0, dy0) = (x0 - xe, v0);
        let c2 = (dy0 - r1 * y0) / (r2 - r1);
        let c1 = y0 - c2;
        let mut worst: f64 = 0.0;
        for _ in 0..2000 {
            bench.apply(p, 1e-3);
            let t = bench.time() - t0;
            let exact = xe + c1 * (r1 * t).exp() + c2 * (r2 * t).exp();
            worst = worst.max((bench.position() - exact).abs());
        }
        worst
    }

    /// `(y, y')` after `h` by classical Runge-Kutta in `n` steps: the independent
    /// reference for the closed form.
    fn rk4(y0: f64, v0: f64, h: f64, w2: f64, c: f64, n: u32) -> (f64, f64) {
        let f = |y: f64, v: f64| (v, -w2 * y - c * v);
        let (mut y, mut v) = (y0, v0);
        let dt = h / f64::from(n);
        for _ in 0..n {
            let k1 = f(y, v);
            let k2 = f(y + 0.5 * dt * k1.0, v + 0.5 * dt * k1.1);
            let k3 = f(y + 0.5 * dt * k2.0, v + 0.5 * dt * k2.1);
            let k4 = f(y + dt * k3.0, v + dt * k3.1);
            y += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            v += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        }
        (y, v)
    }

    #[test]
    fn held_pressure_step_matches_runge_kutta_over_every_damping() {
        let w2: f64 = 9000.0;
        let critical = 2.0 * w2.sqrt();
        // The muscle (over-damped), light damping, either side of critical within and
        // beyond the series' reach, and critical itself.
        for (c, h) in [
            (3200.0, 1e-3),
            (3200.0, 1e-2),
            (20.0, 0.05),
            (critical * (1.0 + 1e-6), 1e-3),
            (critical * (1.0 - 1e-6), 1e-3),
            (critical * 1.05, 0.02),
            (critical * 0.95, 0.02),
            (critical, 0.01),
        ] {
            let (y, v) = held_pressure_step(0.01, -0.3, h, w2, c);
            let (ry, rv) = rk4(0.01, -0.3, h, w2, c, 200_000);
            assert!(
                (y - ry).abs() < 1e-13 && (v - rv).abs() < 1e-11,
                "b/m {c}, h {h}: ({y}, {v}) against ({ry}, {rv})"
            );
        }
    }

    #[test]
    fn held_pressure_step_is_continuous_where_the_series_takes_over() {
        // |q| h^2 = 0.01 at b/m = 2 sqrt(w2 +- 0.01 / h^2), h = 1 ms: just inside and outside.
        let (w2, h) = (9.0e4_f64, 1e-3);
        for sign in [1.0, -1.0] {
            let c = 2.0 * (w2 + sign * 0.01 / (h * h)).sqrt();
            // 1e-14 of b/m moves |q| h^2 by 2e-13 of itself, across the threshold whatever
            // the rounding of q, and the result by about 1e-14 of itself.
            let inside = held_pressure_step(0.01, -0.3, h, w2, c * (1.0 - sign * 1e-14));
            let outside = held_pressure_step(0.01, -0.3, h, w2, c * (1.0 + sign * 1e-14));
            let close = |a: f64, b: f64| (a - b).abs() < 1e-13 * a.abs();
            assert!(
                close(inside.0, outside.0) && close(inside.1, outside.1),
                "{inside:?} against {outside:?}"
            );
        }
    }
}
