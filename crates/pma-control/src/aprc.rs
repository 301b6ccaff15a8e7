use crate::command::CommandState;
use crate::{
    implicit_sign_solve, CommandLimits, ControlOutput, Controller, Diagnostics,
    DisturbanceObserver, KinematicObserver, Measurement, NominalModel, RefSample, Saturation,
};

crate::gain_table! {
    /// Gains of APRC(-NDO). The defaults are the paper's (Section IV-A); `delta` and the
    /// observer bandwidth are not given there and are chosen here (see the field docs).
    pub struct AprcGains {
        /// `c1` of the sliding manifolds (3), (4) (1/s).
        c1_per_s: Positive, Log(1.0, 1e4);
        /// `c2` of the sliding manifolds (1/s^2).
        c2_per_s2: Positive, Log(1e-1, 1e5);
        /// Proxy-object coupling `Kp` of eq. (7) (1/s^2).
        kp_per_s2: Positive, Log(1e1, 1e6);
        /// Proxy-object coupling `Ki` (1/s^3).
        ki_per_s3: Positive, Log(1e0, 1e6);
        /// Proxy-object coupling `Kd` (1/s).
        kd_per_s: Positive, Log(1e0, 1e4);
        /// Disturbance observer gain `kappa` of eq. (37) (1/s); unused by plain APRC.
        kappa_per_s: Finite, Log(10.0, 2e4);
        /// Adaptation rate `gamma` of eq. (10); `0` holds the gain at `gain_initial`.
        gamma: NonNegative, Log(1e-1, 1e3);
        /// Proxy mass `m_p` of eq. (11).
        proxy_mass: Finite, Log(1e-1, 1e2);
        /// Boundary layer `delta` of eq. (10) (m/s). Not given in the paper; 0.5 mm/s (2 % of
        /// the sine reference's peak velocity) stops adaptation on measurement noise while
        /// any real proxy slip still raises the gain. At most 1 m/s: faster than the
        /// muscle moves, where the adaptation would never run.
        boundary_layer_m_s: NonNegative => At(1.0);
        /// `Gamma_hat(0)`; the paper starts from 0. At most 1e5, as `gain_max`.
        gain_initial: NonNegative => At(1e5);
        /// Projection bound `Gamma_max` on the adaptive gain (Ioannou & Sun, Robust
        /// Adaptive Control, 1996, §8.4.2): `Gamma_hat` stays in `[0, Gamma_max]`. Law (10)
        /// alone never decreases `Gamma_hat`, so noise or a valve lag that keep `|S_p|`
        /// above `delta` make it grow without bound. `0` (the default): no bound, the
        /// paper's law. At most 1e5: two decades above the largest adaptive gain any run
        /// here reached (430, docs/cooperative.md).
        gain_max: NonNegative => At(1e5);
        /// `sigma_0` of the switching sigma-modification (Ioannou & Tsakalis, IEEE TAC
        /// 31(11), 1986) added to law (10): `Gamma_hat' = gamma (|S_p| - sigma Gamma_hat)`
        /// with `sigma = 0` below `M0 = Gamma_max / 2`, rising linearly to `sigma_0` at
        /// `Gamma_max` ((m/s) per unit of gain). It pulls the gain back once it has drifted
        /// past `M0` and leaves the ideal law untouched below it. Needs `gain_max > 0`; `0`:
        /// projection only. At most 1.
        leakage_sigma: NonNegative => At(1.0);
        /// Bandwidth of the kinematic observer that supplies velocity and acceleration
        /// (rad/s). Not part of the paper (its rig differentiated position); 200 rad/s keeps
        /// the velocity lag error at 4.4 um/s on the 0.25 Hz sine (`3 jerk / omega^2`) and
        /// the velocity noise from 20 um of position noise around 2 mm/s.
        estimator_bandwidth_rad_s: Positive, Log(50.0, 1000.0);
    }
}

impl AprcGains {
    /// The paper's gain set with `m_p = 1`.
    pub const PAPER: AprcGains = AprcGains {
        c1_per_s: 177.4,
        c2_per_s2: 174.4,
        kp_per_s2: 2473.5,
        ki_per_s3: 1916.0,
        kd_per_s: 194.2,
        kappa_per_s: 15952.0,
        gamma: 10.0,
        proxy_mass: 1.0,
        boundary_layer_m_s: 5e-4,
        gain_initial: 0.0,
        gain_max: 0.0,
        leakage_sigma: 0.0,
        estimator_bandwidth_rad_s: 200.0,
    };

    /// The leakage rate `sigma` of the switching sigma-modification at `gain_hat`: `0` up
    /// to `M0 = gain_max / 2`, then linear to `leakage_sigma` at `gain_max`.
    pub fn switching_sigma(&self, gain_hat: f64) -> f64 {
        let m0 = 0.5 * self.gain_max;
        if self.gain_max <= 0.0 || gain_hat <= m0 {
            0.0
        } else {
            self.leakage_sigma * ((gain_hat - m0) / m0).min(1.0)
        }
    }

    /// `varpi = Kp c1 - Ki - Kd c2` of Theorems 1-2.
    pub fn varpi(&self) -> f64 {
        self.kp_per_s2 * self.c1_per_s - self.ki_per_s3 - self.kd_per_s * self.c2_per_s2
    }

    /// `K_c` of Theorem 1 as `[[a, b], [b, d]]`.
    pub fn k_c(&self) -> [[f64; 2]; 2] {
        let a = self.kp_per_s2 * self.c2_per_s2 + self.ki_per_s3 * self.c1_per_s;
        let b = self.ki_per_s3 + self.kd_per_s * self.c2_per_s2;
        let d = self.kp_per_s2 + self.kd_per_s * self.c1_per_s;
        [[a, b], [b, d]]
    }

    /// Whether `K_c` is positive definite (Sylvester's criterion).
    pub fn k_c_positive_definite(&self) -> bool {
        let k = self.k_c();
        k[0][0] > 0.0 && k[0][0] * k[1][1] - k[0][1] * k[1][0] > 0.0
    }
}

impl Default for AprcGains {
    fn default() -> Self {
        Self::PAPER
    }
}

/// Adaptive proxy-based robust control, eqs. (3)-(12), with the nonlinear disturbance
/// observer of eqs. (37), (43) (APRC-NDO) or without it (APRC, the ablation).
///
/// Discretisation (period `T`, everything else from the current sample): the proxy's new
/// position `xi` is the unknown; its velocity `(xi - x_p)/T`, the integrals of (4) and (7)
/// (backward Euler), `S_p` and `u_l` are all affine in `xi`, so eq. (11) with
/// `u_r = Gamma_hat sgn(S_p)` taken at the *new* `S_p` becomes
/// `A (S_p - s*) + Gamma_hat sgn(S_p) ∋ 0`, solved in closed form by
/// [`implicit_sign_solve`]. The proxy therefore sticks exactly on `S_p = 0` instead of
/// chattering around it. Then the command follows from eq. (43) with the new proxy state.
///
/// Anti-windup: while the command is clamped, `Gamma_hat` holds, and the integral
/// `∫(x_p - x)` holds whenever it would push further into the clamp.
#[derive(Debug, Clone)]
pub struct AprcNdo {
    gains: AprcGains,
    model: NominalModel,
    limits: CommandLimits,
    observer: KinematicObserver,
    ndo: Option<DisturbanceObserver>,
    xp: f64,
    vp: f64,
    int_ref_proxy: f64,
    int_ref_object: f64,
    int_proxy_object: f64,
    gain_hat: f64,
    cmd: CommandState,
}

impl AprcNdo {
    /// APRC-NDO when `with_ndo`, else APRC.
    pub fn new(
        gains: AprcGains,
        model: NominalModel,
        limits: CommandLimits,
        with_ndo: bool,
    ) -> Self {
        Self {
            gains,
            model,
            limits,
            observer: KinematicObserver::new(gains.estimator_bandwidth_rad_s),
            ndo: with_ndo.then(|| DisturbanceObserver::new(gains.kappa_per_s)),
            xp: 0.0,
            vp: 0.0,
            int_ref_proxy: 0.0,
            int_ref_object: 0.0,
            int_proxy_object: 0.0,
            gain_hat: gains.gain_initial,
            cmd: CommandState::at_rest(&model, &limits, 0.0),
        }
    }

    /// Gains in use.
    pub fn gains(&self) -> &AprcGains {
        &self.gains
    }

    /// Solves the implicit proxy step; returns the new `S_p` and the coupling `u_l`.
    fn step_proxy(&mut self, r: &RefSample, x: f64, v: f64, dt: f64) -> (f64, f64) {
        let g = &self.gains;
        let (c1, c2) = (g.c1_per_s, g.c2_per_s2);
        let (kp, ki, kd) = (g.kp_per_s2, g.ki_per_s3, g.kd_per_s);
        let hold_integral = self.cmd.saturation.blocks(ki * (self.xp - x));
        let t_int = if hold_integral { 0.0 } else { dt };
        // Everything evaluated at the candidate xi0 = previous proxy position.
        let xi0 = self.xp;
        let ip0 = self.int_ref_proxy + dt * (r.position_m - xi0);
        let e0 = self.int_proxy_object + t_int * (xi0 - x);
        let s0 = r.velocity_m_s + c1 * (r.position_m - xi0) + c2 * ip0;
        let ul0 = kp * (xi0 - x) + ki * e0 + kd * (0.0 - v);
        let d0 =
            r.acceleration_m_s2 + self.vp / dt + c1 * r.velocity_m_s + c2 * (r.position_m - xi0);
        // Slopes with respect to xi: dS_p/dxi = -sigma, du_l/dxi = lambda.
        let sigma = 1.0 / dt + c1 + c2 * dt;
        let lambda = kp + ki * t_int + kd / dt;
        let a = g.proxy_mass / dt + lambda / sigma;
        let s_star = s0 - (g.proxy_mass * d0 - ul0) / a;
        let s_p = implicit_sign_solve(s_star, a, self.gain_hat);
        let xi = xi0 - (s_p - s0) / sigma;
        self.vp = (xi - self.xp) / dt;
        self.xp = xi;
        self.int_ref_proxy += dt * (r.position_m - xi);
        self.int_proxy_object += t_int * (xi - x);
        let u_l = kp * (xi - x) + ki * self.int_proxy_object + kd * (self.vp - v);
        (s_p, u_l)
    }

    fn adapt_gain(&mut self, s_p: f64, dt: f64) {
        let g = &self.gains;
        let leak = g.switching_sigma(self.gain_hat) * self.gain_hat;
        if self.cmd.saturation == Saturation::None && s_p.abs() >= g.boundary_layer_m_s {
            self.gain_hat += dt * g.gamma * s_p.abs();
        }
        // The leak acts while the valve saturates too: it only ever lowers the gain.
        if g.gain_max > 0.0 {
            self.gain_hat = (self.gain_hat - dt * g.gamma * leak).clamp(0.0, g.gain_max);
        }
    }
}

impl Controller for AprcNdo {
    fn name(&self) -> &'static str {
        if self.ndo.is_some() {
            "aprc-ndo"
        } else {
            "aprc"
        }
    }

    fn reset(&mut self, measurement: Measurement, reference: RefSample) {
        self.observer.reset(measurement.position_m);
        if let Some(n) = self.ndo.as_mut() {
            n.reset();
        }
        self.xp = reference.position_m;
        self.vp = reference.velocity_m_s;
        self.int_ref_proxy = 0.0;
        self.int_ref_object = 0.0;
        self.int_proxy_object = 0.0;
        self.gain_hat = self.gains.gain_initial;
        self.cmd = CommandState::at_rest(&self.model, &self.limits, measurement.position_m);
    }

    fn applied(&mut self, applied_pa: f64) {
        self.cmd.applied(applied_pa);
    }

    fn pressure_sensed(&mut self, pressure_pa: f64) {
        self.cmd.sensed(pressure_pa);
    }

    fn update(&mut self, r: &RefSample, m: &Measurement, dt: f64) -> ControlOutput {
        self.observer.update(m.position_m, dt);
        let (x, v, a) = self.observer.state();
        let tau_hat = match self.ndo.as_mut() {
            Some(n) => n.update(
                &self.model,
                x,
                v,
                a,
                self.cmd.pressure_hat,
                self.cmd.mode,
                dt,
            ),
            None => 0.0,
        };
        self.int_ref_object += dt * (r.position_m - x);
        let (s_p, u_l) = self.step_proxy(r, x, v, dt);
        self.adapt_gain(s_p, dt);
        let g = &self.gains;
        // Eq. (43): everything but the drift f(x, xdot), which `invert` subtracts.
        let accel = r.acceleration_m_s2
            + g.c1_per_s * (r.velocity_m_s - v)
            + g.c2_per_s2 * (r.position_m - x)
            + u_l
            - tau_hat;
        let u = self
            .cmd
            .invert(&self.limits, &self.model, (x, v), accel, dt);
        let s_q = r.velocity_m_s - v
            + g.c1_per_s * (r.position_m - x)
            + g.c2_per_s2 * self.int_ref_object;
        ControlOutput {
            pressure_cmd_pa: u,
            diagnostics: Diagnostics {
                proxy_position_m: self.xp,
                s_p,
                s_q,
                gain_hat: self.gain_hat,
                disturbance_hat: if self.ndo.is_some() {
                    tau_hat
                } else {
                    f64::NAN
                },
                velocity_m_s: v,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adapting(gain_max: f64, leakage_sigma: f64) -> AprcNdo {
        let mut c = AprcNdo::new(
            AprcGains {
                gain_max,
                leakage_sigma,
                ..AprcGains::PAPER
            },
            NominalModel::paper(),
            CommandLimits::default(),
            true,
        );
        c.cmd.saturation = Saturation::None;
        c
    }

    /// Law (10) with a persistent `|S_p| = 1 cm/s` (noise above the dead zone) for 100 s.
    fn drive(c: &mut AprcNdo, s_p: f64, seconds: f64) {
        for _ in 0..(seconds * 1e3) as usize {
            c.adapt_gain(s_p, 1e-3);
        }
    }

    #[test]
    fn without_leakage_the_gain_drifts_without_bound_as_law_10_says() {
        let mut c = adapting(0.0, 0.0);
        drive(&mut c, 0.01, 100.0);
        // gamma |S_p| t = 10 * 0.01 * 100.
        assert!((c.gain_hat - 10.0).abs() < 1e-9, "{}", c.gain_hat);
    }

    #[test]
    fn projection_holds_the_gain_at_its_bound() {
        let mut c = adapting(5.0, 0.0);
        drive(&mut c, 0.01, 100.0);
        assert_eq!(c.gain_hat, 5.0);
    }

    #[test]
    fn switching_sigma_settles_where_the_leak_balances_the_drive_and_stops_at_m0() {
        // Equilibrium: |S_p| = sigma_0 (G / M0 - 1) G with M0 = 2.5, sigma_0 = 0.01,
        // |S_p| = 0.01: G^2 - 2.5 G - 2.5 = 0.
        let mut c = adapting(5.0, 0.01);
        drive(&mut c, 0.01, 300.0);
        let expected = (2.5 + (2.5f64 * 2.5 + 10.0).sqrt()) / 2.0;
        assert!(
            (c.gain_hat - expected).abs() < 1e-3,
            "{} vs {expected}",
            c.gain_hat
        );
        // The drive stops (|S_p| inside the dead zone): the gain leaks back to M0, no lower.
        drive(&mut c, 0.0, 2000.0);
        assert!((c.gain_hat - 2.5).abs() < 2e-3, "{}", c.gain_hat);
        assert!(c.gain_hat >= 2.5);
    }

    #[test]
    fn leakage_without_a_bound_is_refused() {
        let g = AprcGains {
            leakage_sigma: 0.01,
            ..AprcGains::PAPER
        };
        let e = crate::ControllerConfig::AprcNdo(g).validate().unwrap_err();
        assert!(e.to_string().contains("gain_max"), "{e}");
    }

    #[test]
    fn paper_gains_satisfy_theorem_conditions() {
        let g = AprcGains::PAPER;
        assert!((g.varpi() - 403_015.06).abs() < 1.0, "varpi {}", g.varpi());
        assert!(g.k_c_positive_definite());
    }

    #[test]
    fn implicit_proxy_step_satisfies_eq11_and_the_sliding_variable_definition() {
        // After a step, S_p returned must equal eq. (4) evaluated on the new proxy state,
        // and m_p dS_p/dt = -u_r + u_l must hold with u_r in Gamma sgn(S_p).
        let mut c = AprcNdo::new(
            AprcGains {
                gain_initial: 0.3,
                ..AprcGains::PAPER
            },
            NominalModel::paper(),
            CommandLimits::default(),
            true,
        );
        let r0 = RefSample {
            position_m: 0.015,
            velocity_m_s: 0.02,
            acceleration_m_s2: 0.0,
        };
        c.reset(Measurement { position_m: 0.014 }, r0);
        let dt = 1e-3;
        let r = RefSample {
            position_m: 0.01502,
            velocity_m_s: 0.0201,
            acceleration_m_s2: -0.01,
        };
        let x = 0.0141;
        let (xp0, vp0) = (c.xp, c.vp);
        let ip_before = c.int_ref_proxy;
        let (s_p, u_l) = c.step_proxy(&r, x, 0.001, dt);
        let g = c.gains;
        let s_def = r.velocity_m_s - c.vp
            + g.c1_per_s * (r.position_m - c.xp)
            + g.c2_per_s2 * c.int_ref_proxy;
        assert!((s_p - s_def).abs() < 1e-9, "{s_p} vs {s_def}");
        assert!((c.int_ref_proxy - ip_before - dt * (r.position_m - c.xp)).abs() < 1e-15);
        assert!((c.vp - (c.xp - xp0) / dt).abs() < 1e-12);
        // Discrete eq. (12) residual: m_p (xdd_d - a_p + c1 (xd_d - v_p) + c2 (x_d - x_p)) = -u_r + u_l
        let ap = (c.vp - vp0) / dt;
        let lhs = g.proxy_mass
            * (r.acceleration_m_s2 - ap
                + g.c1_per_s * (r.velocity_m_s - c.vp)
                + g.c2_per_s2 * (r.position_m - c.xp));
        let u_r = lhs - u_l; // = -(Gamma sgn S_p) must lie in [-Gamma, Gamma], equal if S_p != 0
        if s_p != 0.0 {
            assert!((u_r + 0.3 * s_p.signum()).abs() < 1e-6, "u_r {u_r}");
        } else {
            assert!(u_r.abs() <= 0.3 + 1e-9);
        }
    }
}
