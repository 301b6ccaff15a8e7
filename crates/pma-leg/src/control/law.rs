//! Impedance by co-contraction: each joint's stiffness set through its muscle pair's
//! pressure sum and its torque through their difference (Tondu and Lopez 2000; Verrelst
//! et al. 2005), the valves' own pressure loops as the inner loops.
//!
//! A muscle at constant pressure `P` is a spring in its contraction `x`: `dF/dx = -k(P)`
//! for eq. (1), the map's slope for a Festo size. On a pulley of signed arm `m` its
//! contraction is `x0 + m q`, so the pair's joint stiffness at constant pressures is
//! `K = m_f^2 k_f(P_f) + m_e^2 k_e(P_e)`, which grows with both pressures, while the torque
//! `m_f F_f + m_e F_e` grows with their difference. Each period the law solves the two
//! equations "stiffness = set point, torque at the reference pose = what the reference
//! needs" for the two pressures; the muscles then are a spring of the set stiffness about
//! the reference, by their own physics, with no position feedback: a push on the leg
//! deflects it by `torque / K` whatever the controller does within the valve's lag.
//!
//! What the torque at the reference pose holds: the rigid leg's inverse dynamics along the
//! reference, with gravity at the *measured* pose (the device's weight compensated where it
//! is, so that gravity adds no stiffness of its own), the muscles' own damping along the
//! reference's velocity (so that the damping acts about the reference), and a damping
//! feedback on the velocity error for whatever the set point asks beyond the muscles' own.
use crate::base::LegError;
use crate::body::LegInertia;
use crate::control::{
    Compensation, ControlMode, ControlSettings, ImpedanceSettings, MusclePair, PathSettings,
    StrideLearning, Tunnel, SOFT_SHARE,
};
use crate::gait::GaitSample;
use crate::plant::MuscleActuator;

/// One leg's law in every mode that sets the pairs' pressures (impedance, path,
/// transparent): two pairs, their set points and the leg's rigid model.
#[derive(Debug, Clone)]
pub struct ImpedanceLaw {
    mode: ControlMode,
    pairs: [MusclePair; 2],
    settings: ImpedanceSettings,
    path: PathSettings,
    tunnel: Option<Tunnel>,
    /// The tunnel's last nearest segment.
    tunnel_hint: usize,
    /// The model whose dynamics the law carries (the leg's or the frames').
    carried: LegInertia,
    /// Each pair's stiffness in path and transparent modes (N m/rad).
    soft_nm_per_rad: [f64; 2],
    /// Each joint's stiffness (N m/rad), defaults resolved.
    stiffness_nm_per_rad: [f64; 2],
    velocity_rad_s: [f64; 2],
    last_rad: Option<[f64; 2]>,
    commands_pa: [f64; 4],
    /// The learned feedforward (impedance mode with `[control.impedance.learning]`).
    learning: Option<StrideLearning>,
}

impl ImpedanceLaw {
    /// The law of `control`'s mode for a leg of four muscles on `gait` whose valves reach
    /// `pressure_max_pa`, each set point checked against its pair's reach.
    pub fn new(
        control: &ControlSettings,
        pressure_max_pa: f64,
        muscles: &[MuscleActuator],
        inertia: &LegInertia,
        gait: &crate::gait::GaitReference,
    ) -> Result<Self, LegError> {
        let settings = control.impedance;
        settings.validate()?;
        control.path.validate()?;
        let pairs = MusclePair::of_leg(muscles, pressure_max_pa)?;
        let stiffness_nm_per_rad = [
            pairs[0].resolve(settings.hip)?,
            pairs[1].resolve(settings.knee)?,
        ];
        let soft = |p: &MusclePair| {
            p.stiffness_range(0.0, 0.0).map_or(f64::NAN, |r| {
                r.min_nm_per_rad + SOFT_SHARE * (r.max_nm_per_rad - r.min_nm_per_rad)
            })
        };
        let carried = match control.compensation {
            Compensation::Leg => *inertia,
            Compensation::Device => inertia.frames(),
        };
        Ok(Self {
            mode: control.mode,
            pairs,
            settings,
            path: control.path,
            tunnel: (control.mode == ControlMode::Path)
                .then(|| Tunnel::new(gait, control.path.width_deg)),
            tunnel_hint: 0,
            carried,
            soft_nm_per_rad: [soft(&pairs[0]), soft(&pairs[1])],
            stiffness_nm_per_rad,
            velocity_rad_s: [0.0; 2],
            last_rad: None,
            commands_pa: [0.0; 4],
            learning: settings
                .learning
                .filter(|_| control.mode == ControlMode::Impedance)
                .map(StrideLearning::new),
        })
    }

    /// The mode the law runs.
    pub fn mode(&self) -> ControlMode {
        self.mode
    }

    /// The joints' pairs (hip, knee).
    pub fn pairs(&self) -> &[MusclePair; 2] {
        &self.pairs
    }

    /// Each joint's stiffness set point (N m/rad), defaults resolved.
    pub fn stiffness_nm_per_rad(&self) -> [f64; 2] {
        self.stiffness_nm_per_rad
    }

    /// Restarts the velocity estimate at rest, from the valves' present commands.
    pub fn reset(&mut self, commands_pa: [f64; 4]) {
        self.velocity_rad_s = [0.0; 2];
        self.last_rad = None;
        self.commands_pa = commands_pa;
    }

    /// The last commands the valves took (the damping estimate's pressures).
    pub fn applied(&mut self, commands_pa: [f64; 4]) {
        self.commands_pa = commands_pa;
    }

    fn estimate_velocity(&mut self, q: [f64; 2], dt_s: f64) {
        if let Some(last) = self.last_rad {
            let a = dt_s / (self.settings.velocity_filter_s + dt_s);
            for j in 0..2 {
                let raw = (q[j] - last[j]) / dt_s;
                self.velocity_rad_s[j] += a * (raw - self.velocity_rad_s[j]);
            }
        }
        self.last_rad = Some(q);
    }

    /// The four pressure commands (Pa, within the valve's range) for reference `g` at
    /// measured angles `q` (rad).
    /// `load_nm` is what the leg carries besides its own dynamics (a stance leg's share of
    /// the weight, [`StanceLoad`]; impedance mode only).
    /// `phase` is the leg's phase in its stride (0-1), `None` while it stands or holds a
    /// pose: the learned feedforward ([`StrideLearning`]) learns only while it walks.
    pub fn update(
        &mut self,
        g: &GaitSample,
        q: [f64; 2],
        load_nm: [f64; 2],
        phase: Option<f64>,
        dt_s: f64,
    ) -> [f64; 4] {
        self.estimate_velocity(q, dt_s);
        if self.mode != ControlMode::Impedance {
            return self.update_soft(q);
        }
        let q_ref = [g.hip.angle_rad, g.knee.angle_rad];
        let qd_ref = [g.hip.velocity_rad_s, g.knee.velocity_rad_s];
        let qdd_ref = [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2];
        let dynamics = self.carried.inverse_dynamics(q, qd_ref, qdd_ref);
        let learned = self.learned_nm(phase, [q_ref[0] - q[0], q_ref[1] - q[1]]);
        let feedforward = [0, 1].map(|j| dynamics[j] + load_nm[j] + learned[j]);
        let mut out = self.commands_pa;
        for pair in &self.pairs {
            let j = pair.joint;
            let set = self.settings.joint(j);
            let held = [
                self.commands_pa[pair.indices[0]],
                self.commands_pa[pair.indices[1]],
            ];
            let own = pair.damping(held);
            let extra = (set.damping_nm_s_per_rad - own).max(0.0);
            let torque =
                feedforward[j] + own * qd_ref[j] + extra * (qd_ref[j] - self.velocity_rad_s[j]);
            let p = pair
                .pressures_for(self.stiffness_nm_per_rad[j], torque, q_ref[j])
                .unwrap_or(held);
            for (k, &i) in pair.indices.iter().enumerate() {
                out[i] = p[k].clamp(0.0, pair.pressure_max_pa);
            }
        }
        out
    }

    /// The learned feedforward at `phase` after taking in `error_rad` (zero without
    /// learning; held, not updated, while the leg does not walk).
    fn learned_nm(&mut self, phase: Option<f64>, error_rad: [f64; 2]) -> [f64; 2] {
        let Some(l) = &mut self.learning else {
            return [0.0; 2];
        };
        match phase {
            Some(phase) => l.update(phase, error_rad, self.stiffness_nm_per_rad),
            None => {
                l.pause();
                [0.0; 2]
            }
        }
    }

    /// Path and transparent modes: the pairs at their soft stiffness, holding at the
    /// measured pose the carried model's weight, the muscles' own damping cancelled, and
    /// in path mode the tunnel's wall and the support along the path.
    fn update_soft(&mut self, q: [f64; 2]) -> [f64; 4] {
        let mut torque = self.carried.inverse_dynamics(q, [0.0; 2], [0.0; 2]);
        if let Some(t) = &self.tunnel {
            let at = t.locate_near(q, &mut self.tunnel_hint);
            let beyond = at.distance_rad - t.width_rad();
            if beyond > 0.0 && at.distance_rad > 0.0 {
                for (j, tau) in torque.iter_mut().enumerate() {
                    *tau -= self.path.wall_nm_per_rad * beyond * at.offset_rad[j] / at.distance_rad;
                }
            }
            for (j, tau) in torque.iter_mut().enumerate() {
                *tau += self.path.support_nm * at.tangent[j];
            }
        }
        let mut out = self.commands_pa;
        for pair in &self.pairs {
            let j = pair.joint;
            let held = [
                self.commands_pa[pair.indices[0]],
                self.commands_pa[pair.indices[1]],
            ];
            let tau = torque[j] + pair.damping(held) * self.velocity_rad_s[j];
            let p = pair
                .pressures_for(self.soft_nm_per_rad[j], tau, q[j])
                .unwrap_or(held);
            for (k, &i) in pair.indices.iter().enumerate() {
                out[i] = p[k].clamp(0.0, pair.pressure_max_pa);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{JointImpedance, LearningSettings, PairMuscle, StanceLoad, LEARNING_BINS};
    use pma_model::MuscleModel;
    use pma_model::MuscleParams;

    /// The trainer's stance load: 500 N on legs whose stance ends at 0.675.
    fn stance_load() -> StanceLoad {
        let loaded = crate::scenario::Scenario::load("gait_treadmill").expect("embedded");
        let exo = crate::sim::build_exo(&loaded, crate::body::Mount::default()).expect("trainer");
        let ground = exo.ground().expect("a treadmill");
        let mut support = *ground.settings();
        support.bws_fraction = 0.0;
        StanceLoad::new(
            ground.chain().clone(),
            500.0 / pma_model::GRAVITY_M_S2,
            support,
            0.675,
        )
    }

    #[test]
    fn learning_on_a_spring_converges_to_the_error_its_forgetting_leaves() {
        // A spring of stiffness K under a disturbance d(phase): e = (d - F) / K. Per phase,
        // F(i+1) = f F(i) + gain K e(i) = (f - gain) F(i) + gain d, which settles at
        // F = gain d / (1 - f + gain): the error falls to (1 - f) / (1 - f + gain) of d / K.
        let (gain, forgetting) = (0.5, 0.9);
        let k = [100.0, 20.0];
        let d = |phase: f64| {
            let w = std::f64::consts::TAU * phase;
            [10.0 * w.sin(), 5.0 * w.cos()]
        };
        let mut l = StrideLearning::new(LearningSettings { gain, forgetting });
        let periods = 1000;
        let mut sq = [[0.0; 2]; 2];
        for stride in 0..60 {
            for n in 0..periods {
                let phase = n as f64 / periods as f64;
                let x = phase * LEARNING_BINS as f64;
                let f = l.at(x);
                let e = [0, 1].map(|j| (d(phase)[j] - f[j]) / k[j]);
                l.update(phase, e, k);
                if stride == 59 {
                    for j in 0..2 {
                        sq[j][0] += e[j] * e[j];
                        sq[j][1] += (d(phase)[j] / k[j]).powi(2);
                    }
                }
            }
        }
        let expected = (1.0 - forgetting) / (1.0 - forgetting + gain);
        for (j, [e, unlearned]) in sq.iter().enumerate() {
            let ratio = (e / unlearned).sqrt();
            assert!(
                (ratio / expected - 1.0).abs() < 0.05,
                "joint {j}: error {ratio:.4} of the unlearned, expected {expected:.4}"
            );
        }
    }

    #[test]
    fn a_moment_share_out_of_range_is_refused_naming_the_leg_and_a_leg_takes_its_own() {
        let mut s = ImpedanceSettings {
            patient_moment_share: 1.5,
            ..ImpedanceSettings::default()
        };
        let e = s.validate().expect_err("refused").to_string();
        assert!(e.contains("control.impedance.patient_moment_share"), "{e}");
        s.patient_moment_share = 1.0;
        s.patient_moment_share_by_leg = Some([1.0, -0.2]);
        let e = s.validate().expect_err("refused").to_string();
        assert!(
            e.contains("patient_moment_share_by_leg[1] (left)") && !e.contains('\n'),
            "{e}"
        );
        s.patient_moment_share_by_leg = Some([1.0, 0.4]);
        assert!(s.validate().is_ok());
        assert_eq!(
            [s.patient_moment_share(0), s.patient_moment_share(1)],
            [1.0, 0.4]
        );
    }

    #[test]
    fn learning_that_would_diverge_is_refused_naming_the_field() {
        let mut s = ImpedanceSettings::default();
        for (gain, forgetting, field) in [
            (1.95, 0.9, "control.impedance.learning.gain"),
            (-0.1, 0.9, "control.impedance.learning.gain"),
            (0.5, 1.2, "control.impedance.learning.forgetting"),
        ] {
            s.learning = Some(LearningSettings { gain, forgetting });
            let e = s.validate().expect_err("refused").to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
        s.learning = Some(LearningSettings {
            gain: 1.0,
            forgetting: 0.95,
        });
        assert!(s.validate().is_ok());
    }

    #[test]
    fn the_stance_load_follows_a_start_support_as_the_harness_lowers_it() {
        // 80 % carried until 1 s, lowered to 30 % by 2 s: the legs carry 20 % of the
        // weight, then 70 %, and the harness's quintic in between.
        let mut s = stance_load();
        s.support.bws_fraction = 0.3;
        s.support.bws_start_fraction = Some(0.8);
        s.support.bws_release_s = [1.0, 2.0];
        let weight = 500.0;
        for (t_s, legs) in [(0.0, 0.2), (1.0, 0.2), (1.5, 0.45), (2.0, 0.7), (9.0, 0.7)] {
            let load = s.load_n(t_s);
            assert!((load - legs * weight).abs() < 1e-9, "{t_s} s: {load} N");
        }
    }

    #[test]
    fn the_two_legs_carry_the_whole_load_between_them_at_every_phase() {
        let s = stance_load();
        for k in 0..1000 {
            let phase = k as f64 / 1000.0;
            let (a, b) = (s.share(phase), s.share((phase + 0.5) % 1.0));
            assert!((0.0..=1.0).contains(&a), "{phase}: {a}");
            assert!((a + b - 1.0).abs() < 1e-12, "{phase}: {a} + {b}");
        }
        assert_eq!(s.share(0.3), 1.0);
        assert_eq!(s.share(0.8), 0.0);
    }

    #[test]
    fn a_stance_load_is_the_vertical_force_times_its_horizontal_lever() {
        // Each joint turns the chain below it about its centre: the vertical force's moment
        // about a joint is the force times the ankle's fore-aft distance from it.
        let s = stance_load();
        let c = &s.chain;
        let f = 0.8 * 500.0;
        for q in [[0.1, 0.1], [0.4, 0.2], [-0.05, 0.6]] {
            let tau = s.torques_nm(q, 0.8, 0.0);
            let ankle = c.ankle_centre([q[0], q[1], 0.0]);
            let hip = c.origins_m[0];
            let (sin, cos) = (c.pitch_rad[0] + c.flexion_sign[0] * q[0]).sin_cos();
            let o = c.origins_m[1];
            let knee_x = hip[0] + o[0] * cos - o[1] * sin;
            let expected = [
                -c.flexion_sign[0] * (ankle[0] - hip[0]) * f,
                -c.flexion_sign[1] * (ankle[0] - knee_x) * f,
            ];
            for j in 0..2 {
                assert!(
                    (tau[j] - expected[j]).abs() < 1e-5,
                    "{q:?}: {tau:?} vs {expected:?}"
                );
            }
        }
        assert_eq!(s.torques_nm([0.3, 0.3], 0.0, 0.0), [0.0; 2]);
    }

    /// A pair of Table I muscles on pulleys of 15 mm, 30 mm contracted at zero angle.
    fn table_i_pair() -> MusclePair {
        let muscle = |arm_m: f64| PairMuscle {
            arm_m,
            contraction_at_zero_m: 0.03,
            model: MuscleModel::ThreeElement(MuscleParams::TABLE_I),
        };
        MusclePair {
            joint: 0,
            muscles: [muscle(0.015), muscle(-0.015)],
            indices: [0, 1],
            pressure_max_pa: 6e5,
        }
    }

    #[test]
    fn an_eq1_pairs_stiffness_is_r_squared_times_the_sum_of_its_springs() {
        let pair = table_i_pair();
        let t = MuscleParams::TABLE_I;
        for (pf, pe, q) in [(1e5, 4e5, 0.0), (3e5, 3e5, 0.3), (5.5e5, 0.5e5, -0.2)] {
            let analytic = 0.015f64.powi(2) * (t.stiffness(pf) + t.stiffness(pe));
            let k = pair.stiffness([pf, pe], q);
            assert!((k / analytic - 1.0).abs() < 1e-9, "{k} against {analytic}");
        }
    }

    #[test]
    fn the_pressures_solved_give_the_stiffness_and_torque_asked() {
        let pair = table_i_pair();
        for (k, tau, q) in [(9.0, 0.0, 0.0), (10.0, 5.0, 0.2), (8.8, -4.0, -0.3)] {
            let p = pair.pressures_for(k, tau, q).expect("a solution");
            assert!((pair.stiffness(p, q) - k).abs() < 1e-6, "{p:?}");
            assert!((pair.torque(p, q) - tau).abs() < 1e-6, "{p:?}");
        }
    }

    #[test]
    fn the_stiffness_range_grows_with_the_pressure_sum_and_ends_at_the_valves_limit() {
        let pair = table_i_pair();
        let r = pair.stiffness_range(0.0, 0.0).expect("a range");
        let t = MuscleParams::TABLE_I;
        // Both at 6 bar is the stiffest; the softest has both muscles just pulling.
        let top = 2.0 * 0.015f64.powi(2) * t.stiffness(6e5);
        assert!(
            (r.max_nm_per_rad / top - 1.0).abs() < 0.01,
            "{r:?} against {top}"
        );
        assert!(r.min_nm_per_rad < r.max_nm_per_rad);
        assert!(r.min_nm_per_rad >= 2.0 * 0.015f64.powi(2) * t.k0_n_per_m);
        // A torque narrows it: one muscle has to pull harder than the other.
        let loaded = pair.stiffness_range(20.0, 0.0).expect("a range");
        assert!(loaded.max_nm_per_rad < r.max_nm_per_rad);
    }

    #[test]
    fn the_tunnel_locates_a_pose_on_and_off_the_path() {
        let gait = crate::gait::GaitReference::adult(0.5, 1.6, 1.6).unwrap();
        let tunnel = Tunnel::new(&gait, 5.0);
        let g = gait.sample(1.6 + 1.6 + 0.4);
        let on = [g.hip.angle_rad, g.knee.angle_rad];
        let at = tunnel.locate(on);
        assert!(at.distance_rad < 1e-3, "{at:?}");
        let t = at.tangent;
        assert!((t[0].hypot(t[1]) - 1.0).abs() < 1e-9);
        // Moved off along the normal by 0.05 rad: that far from the path (the path
        // bends, so no nearer than that and not much farther).
        let off = [on[0] - 0.05 * t[1], on[1] + 0.05 * t[0]];
        let d = tunnel.locate(off).distance_rad;
        assert!(d <= 0.05 + 1e-9 && d > 0.03, "{d}");
    }

    #[test]
    fn the_local_search_finds_what_the_full_scan_finds_along_a_gait() {
        let gait = crate::gait::GaitReference::adult(0.5, 1.6, 1.6).unwrap();
        let tunnel = Tunnel::new(&gait, 5.0);
        let mut hint = 0;
        for k in 0..4000 {
            // A leg a little off the path, a millisecond per step, over two strides, now
            // inside the 5-degree tunnel (0.087 rad), now beyond it.
            let g = gait.sample(3.2 + k as f64 * 1e-3);
            let off = if (k / 500) % 2 == 0 { 0.02 } else { 0.3 };
            let q = [g.hip.angle_rad + off, g.knee.angle_rad - 0.01];
            let near = tunnel.locate_near(q, &mut hint);
            let full = tunnel.locate(q);
            // Inside the tunnel, what matters is that it is inside; beyond it, the push.
            let width = tunnel.width_rad();
            assert_eq!(
                near.distance_rad <= width,
                full.distance_rad <= width,
                "step {k}"
            );
            if full.distance_rad > width {
                assert_eq!(near.offset_rad, full.offset_rad, "step {k}");
            }
        }
    }

    #[test]
    fn bad_path_settings_name_their_field() {
        for (s, field) in [
            (
                PathSettings {
                    width_deg: -1.0,
                    ..PathSettings::default()
                },
                "control.path.width_deg",
            ),
            (
                PathSettings {
                    width_deg: 45.0,
                    ..PathSettings::default()
                },
                "control.path.width_deg",
            ),
            (
                PathSettings {
                    wall_nm_per_rad: -3.0,
                    ..PathSettings::default()
                },
                "control.path.wall_nm_per_rad",
            ),
            (
                PathSettings {
                    support_nm: f64::NAN,
                    ..PathSettings::default()
                },
                "control.path.support_nm",
            ),
        ] {
            let e = s.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }

    #[test]
    fn bad_set_points_name_their_field() {
        let mut s = ImpedanceSettings::default();
        s.knee.stiffness_nm_per_rad = Some(-5.0);
        let e = s.validate().unwrap_err().to_string();
        assert!(
            e.contains("control.impedance.knee.stiffness_nm_per_rad"),
            "{e}"
        );
        let mut s = ImpedanceSettings::default();
        s.hip.damping_nm_s_per_rad = f64::NAN;
        let e = s.validate().unwrap_err().to_string();
        assert!(
            e.contains("control.impedance.hip.damping_nm_s_per_rad"),
            "{e}"
        );
        let pair = table_i_pair();
        let e = pair
            .resolve(JointImpedance {
                stiffness_nm_per_rad: Some(200.0),
                damping_nm_s_per_rad: 0.0,
            })
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control.impedance.hip.stiffness_nm_per_rad = 200 is out of reach"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}
