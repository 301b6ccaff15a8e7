//! The patient's model: the torques of the reflexes, spasms, effort and passive moments at
//! each physics substep, allocation-free once planned.
use super::settings::*;
use crate::base::LegError;
use crate::body::LegInertia;
use crate::gait::GaitReference;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// One spasm of a run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpasmEvent {
    /// Joint (0 hip, 1 knee).
    pub joint: usize,
    /// Onset (s).
    pub t_s: f64,
    /// Peak torque (N m, > 0).
    pub amplitude_nm: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// `flexor` or `extensor`.
    pub direction: SpasmDirection,
    /// Fraction of the duration spent rising.
    pub rise_fraction: f64,
}

impl SpasmEvent {
    /// End (s).
    pub fn end_s(&self) -> f64 {
        self.t_s + self.duration_s
    }

    /// Torque at `t_s` (N m, flexion positive): a `sin^2` rise over `rise_fraction` of the
    /// duration and a `cos^2` fall over the rest, continuous with its slope, zero outside.
    pub fn torque(&self, t_s: f64) -> f64 {
        let u = (t_s - self.t_s) / self.duration_s;
        if !(0.0..1.0).contains(&u) {
            return 0.0;
        }
        let r = self.rise_fraction;
        let half_pi = std::f64::consts::FRAC_PI_2;
        let shape = if u < r {
            (half_pi * u / r).sin().powi(2)
        } else {
            (half_pi * (u - r) / (1.0 - r)).cos().powi(2)
        };
        let sign = if self.direction == SpasmDirection::Extensor {
            -1.0
        } else {
            1.0
        };
        sign * self.amplitude_nm * shape
    }
}

/// The random spasms of one joint, drawn lazily in time order from their seed, so that
/// the events up to any time are the same whatever the run's length.
#[derive(Debug, Clone)]
struct SpasmSource {
    joint: usize,
    settings: SpasmSettings,
    rng: Xoshiro256PlusPlus,
    next_t_s: f64,
}

impl SpasmSource {
    fn new(joint: usize, settings: &SpasmSettings) -> Self {
        // Hip and knee draw different streams from the same seed.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(
            settings.seed ^ (0x9e37_79b9_7f4a_7c15_u64.wrapping_mul(joint as u64 + 1)),
        );
        let next_t_s = Self::gap(&mut rng, settings.rate_per_min);
        Self {
            joint,
            settings: settings.clone(),
            rng,
            next_t_s,
        }
    }

    /// Exponential inter-arrival time (s) of a Poisson process of `rate_per_min`.
    fn gap(rng: &mut Xoshiro256PlusPlus, rate_per_min: f64) -> f64 {
        if rate_per_min <= 0.0 {
            return f64::INFINITY;
        }
        let u: f64 = rng.random::<f64>();
        -(1.0 - u).ln() * 60.0 / rate_per_min
    }

    fn uniform(rng: &mut Xoshiro256PlusPlus, r: [f64; 2]) -> f64 {
        r[0] + (r[1] - r[0]) * rng.random::<f64>()
    }

    /// The next event if it starts before `until_s`.
    fn next_before(&mut self, until_s: f64) -> Option<SpasmEvent> {
        if self.next_t_s >= until_s {
            return None;
        }
        let s = &self.settings;
        let amplitude_nm = Self::uniform(&mut self.rng, s.amplitude_nm);
        let duration_s = Self::uniform(&mut self.rng, s.duration_s);
        let direction = match s.direction {
            SpasmDirection::Either if self.rng.random::<bool>() => SpasmDirection::Flexor,
            SpasmDirection::Either => SpasmDirection::Extensor,
            d => d,
        };
        let e = SpasmEvent {
            joint: self.joint,
            t_s: self.next_t_s,
            amplitude_nm,
            duration_s,
            direction,
            rise_fraction: s.rise_fraction,
        };
        self.next_t_s += Self::gap(&mut self.rng, s.rate_per_min);
        Some(e)
    }
}

/// Delayed samples of a signal at the physics substep: a ring buffer sized once.
#[derive(Debug, Clone)]
struct Delay {
    ring: Vec<f64>,
    next: usize,
}

impl Delay {
    /// A delay of `delay_s` rounded to whole substeps of `h_s`.
    fn new(delay_s: f64, h_s: f64) -> Self {
        let n = (delay_s / h_s).round() as usize;
        Self {
            ring: vec![0.0; n],
            next: 0,
        }
    }

    /// Pushes the value now and returns the one from the delay ago (0 before the start).
    fn push(&mut self, v: f64) -> f64 {
        if self.ring.is_empty() {
            return v;
        }
        let old = std::mem::replace(&mut self.ring[self.next], v);
        self.next = (self.next + 1) % self.ring.len();
        old
    }

    fn clear(&mut self) {
        self.ring.iter_mut().for_each(|v| *v = 0.0);
        self.next = 0;
    }
}

#[derive(Debug, Clone)]
struct JointPatient {
    reflex: Option<(Reflex, Delay)>,
    stiffness: Option<PassiveMoment>,
    effort: Option<EffortSettings>,
}

impl JointPatient {
    fn reflex_torque(&mut self, qd: f64) -> f64 {
        let Some((r, delay)) = &mut self.reflex else {
            return 0.0;
        };
        let w = delay.push(qd);
        -r.extensor_gain_nm_s_per_rad * (w - r.threshold_rad_s).max(0.0)
            + r.flexor_gain_nm_s_per_rad * (-w - r.threshold_rad_s).max(0.0)
    }
}

/// The torques of one substep, by part (N m, flexion positive).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PatientTorques {
    /// Stretch reflex.
    pub reflex_nm: [f64; 2],
    /// Spasms.
    pub spasm_nm: [f64; 2],
    /// Voluntary effort.
    pub effort_nm: [f64; 2],
    /// Passive stiffness.
    pub stiffness_nm: [f64; 2],
}

impl PatientTorques {
    /// The sum of the parts at each joint.
    pub fn total(&self) -> [f64; 2] {
        std::array::from_fn(|j| {
            self.reflex_nm[j] + self.spasm_nm[j] + self.effort_nm[j] + self.stiffness_nm[j]
        })
    }
}

/// A patient who walks ([`ActiveSettings`]): their own clock along the reference's shape,
/// tracked by their own joint impedance over their limb's inverse dynamics.
#[derive(Debug, Clone)]
struct Walker {
    settings: ActiveSettings,
    limb: LegInertia,
    rng: Xoshiro256PlusPlus,
    /// The reference's time they aim at now.
    clock_s: f64,
    /// Their clock's rate this stride: the reference's stride over theirs.
    rate: f64,
    last_t_s: f64,
    /// Where on their clock their next stride starts.
    next_stride_s: f64,
    reference_stride_s: f64,
    ramp_s: f64,
    /// Walking's joint moments they produce instead of their limb's inverse dynamics
    /// (N m, flexion positive, at 0, 1, ..., 100 % of their cycle; see
    /// [`crate::patient::OwnTorque::Walking`]).
    walking_nm: Option<[Vec<f64>; 2]>,
    /// The harness: the moments, computed for its walking support, follow the share the
    /// legs carry at each instant while it lowers a start's support.
    walking_support: Option<crate::ground::TreadmillSettings>,
}

impl Walker {
    fn new(settings: ActiveSettings, gait: &GaitReference, inertia: &LegInertia) -> Self {
        let mut w = Self {
            settings,
            limb: inertia.limb(),
            rng: Xoshiro256PlusPlus::seed_from_u64(settings.seed),
            clock_s: 0.0,
            rate: 1.0,
            last_t_s: 0.0,
            next_stride_s: 0.0,
            reference_stride_s: gait.stride_period_s(),
            ramp_s: gait.ramp_s(),
            walking_nm: None,
            walking_support: None,
        };
        w.reset();
        w
    }

    fn reset(&mut self) {
        self.rng = Xoshiro256PlusPlus::seed_from_u64(self.settings.seed);
        self.clock_s = 0.0;
        self.rate = 1.0;
        // Restarted where the next run starts (see `advance`).
        self.last_t_s = f64::NAN;
        self.next_stride_s = self.ramp_s;
    }

    /// Their next stride's period (s): their mean, varied by a normal draw of their CV
    /// (Box-Muller), kept within half to one and a half of the mean.
    fn draw_period(&mut self) -> f64 {
        let mean = self
            .settings
            .stride_period_s
            .unwrap_or(self.reference_stride_s);
        let (u1, u2): (f64, f64) = (self.rng.random::<f64>().max(1e-300), self.rng.random());
        let normal = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        (mean * (1.0 + self.settings.stride_cv * normal)).clamp(0.5 * mean, 1.5 * mean)
    }

    fn advance(&mut self, t_s: f64) {
        if self.last_t_s.is_nan() {
            // A run starting at `t_s`: in step with the reference there.
            self.last_t_s = t_s;
            self.clock_s = t_s;
            let strides = ((t_s - self.ramp_s) / self.reference_stride_s)
                .ceil()
                .max(0.0);
            self.next_stride_s = self.ramp_s + strides * self.reference_stride_s;
        }
        let dt = (t_s - self.last_t_s).max(0.0);
        self.last_t_s = t_s;
        // Through the start-up they move with the reference; then on their own clock.
        self.clock_s += if self.clock_s < self.ramp_s {
            dt
        } else {
            self.rate * dt
        };
        while self.clock_s >= self.next_stride_s {
            self.rate = self.reference_stride_s / self.draw_period();
            self.next_stride_s += self.reference_stride_s;
        }
    }

    /// Their torques (N m) at `t_s` with the limb at `q`, `qd`.
    fn torques(&mut self, gait: &GaitReference, t_s: f64, q: [f64; 2], qd: [f64; 2]) -> [f64; 2] {
        self.advance(t_s);
        let g = gait.sample(self.clock_s);
        let (a, r) = (self.settings.amplitude, self.rate);
        let aim = [a * g.hip.angle_rad, a * g.knee.angle_rad];
        let aim_v = [a * r * g.hip.velocity_rad_s, a * r * g.knee.velocity_rad_s];
        let aim_a = [
            a * r * r * g.hip.acceleration_rad_s2,
            a * r * r * g.knee.acceleration_rad_s2,
        ];
        let own = match &self.walking_nm {
            Some(curves) => {
                let (phase, share) = (gait.phase(self.clock_s), gait.ramp_share(self.clock_s));
                let carried = self.walking_support.map_or(1.0, |s| s.legs_share_at(t_s));
                curves
                    .each_ref()
                    .map(|c| carried * share * crate::gait::sample_cycle(c, phase))
            }
            None => self.limb.inverse_dynamics(aim, aim_v, aim_a),
        };
        let s = &self.settings;
        std::array::from_fn(|j| {
            s.strength()
                * (own[j]
                    + s.stiffness_nm_per_rad[j] * (aim[j] - q[j])
                    + s.damping_nm_s_per_rad[j] * (aim_v[j] - qd[j]))
        })
    }
}

/// The patient of a run: the resolved model, its delay lines and its spasm plan.
#[derive(Debug, Clone)]
pub struct Patient {
    joints: [JointPatient; 2],
    sources: Vec<SpasmSource>,
    /// Every spasm drawn so far, by onset.
    events: Vec<SpasmEvent>,
    planned_until_s: f64,
    /// Events before this index have ended.
    first_open: usize,
    gait: GaitReference,
    inertia: LegInertia,
    damping_nm_s_per_rad: [f64; 2],
    last: PatientTorques,
    walker: Option<Walker>,
}

impl Patient {
    /// The patient of `settings` (validated) at physics substeps of `h_s`; the effort
    /// follows `gait` through the leg's `inertia` and joint `damping_nm_s_per_rad`.
    pub fn new(
        settings: &PatientSettings,
        h_s: f64,
        gait: GaitReference,
        inertia: LegInertia,
        damping_nm_s_per_rad: [f64; 2],
    ) -> Result<Self, LegError> {
        settings.validate()?;
        let mut joints = Vec::with_capacity(2);
        let mut sources = Vec::new();
        let mut events = Vec::new();
        for (j, (name, s)) in ["hip", "knee"].iter().zip(settings.joints()).enumerate() {
            let at = format!("patient.{name}");
            let reflex = match &s.spasticity {
                Some(sp) => {
                    let r = sp.resolve(j, &format!("{at}.spasticity"))?;
                    let on = r.extensor_gain_nm_s_per_rad > 0.0 || r.flexor_gain_nm_s_per_rad > 0.0;
                    on.then(|| (r, Delay::new(r.delay_s, h_s)))
                }
                None => None,
            };
            let stiffness = match &s.stiffness {
                Some(st) => Some(st.resolve(j, &format!("{at}.stiffness"))?),
                None => None,
            };
            if let Some(sp) = &s.spasms {
                sources.push(SpasmSource::new(j, sp));
                events.extend(sp.events.iter().map(|e| SpasmEvent {
                    joint: j,
                    t_s: e.t_s,
                    amplitude_nm: e.amplitude_nm,
                    duration_s: e.duration_s,
                    direction: e.direction,
                    rise_fraction: sp.rise_fraction,
                }));
            }
            joints.push(JointPatient {
                reflex,
                stiffness,
                effort: s.effort,
            });
        }
        events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        let joints: [JointPatient; 2] = [joints.remove(0), joints.remove(0)];
        let walker = settings.active.map(|a| Walker::new(a, &gait, &inertia));
        Ok(Self {
            walker,
            joints,
            sources,
            events,
            planned_until_s: 0.0,
            first_open: 0,
            gait,
            inertia,
            damping_nm_s_per_rad,
            last: PatientTorques::default(),
        })
    }

    /// Makes an active patient produce walking's joint moments, `moments_nm` (N m, flexion
    /// positive, hip and knee at 0, 1, ..., 100 % of the cycle from initial contact), on
    /// their own clock instead of their limb's inverse dynamics; `false` (and nothing
    /// changed) for a patient who is not active. `support`: the treadmill's harness, the
    /// moments being those of its walking support (they follow the share the legs carry
    /// while it lowers a start's support); `None`: the moments as given throughout.
    pub fn walk_with_moments(
        &mut self,
        moments_nm: [Vec<f64>; 2],
        support: Option<crate::ground::TreadmillSettings>,
    ) -> bool {
        match &mut self.walker {
            Some(w) => {
                w.walking_nm = Some(moments_nm);
                w.walking_support = support;
                true
            }
            None => false,
        }
    }

    /// Draws the random spasms starting before `until_s` (allocates: call it before a run
    /// so that the loop itself does not).
    pub fn plan(&mut self, until_s: f64) {
        if until_s <= self.planned_until_s {
            return;
        }
        let mut added = false;
        for src in &mut self.sources {
            while let Some(e) = src.next_before(until_s) {
                self.events.push(e);
                added = true;
            }
        }
        if added {
            self.events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        }
        self.planned_until_s = until_s;
    }

    /// Every spasm planned so far, by onset.
    pub fn events(&self) -> &[SpasmEvent] {
        &self.events
    }

    /// Clears the delay lines (the limb at rest before `t_s`).
    pub fn reset(&mut self) {
        for j in &mut self.joints {
            if let Some((_, d)) = &mut j.reflex {
                d.clear();
            }
        }
        self.first_open = 0;
        if let Some(w) = &mut self.walker {
            w.reset();
        }
    }

    /// The reference gait's inverse-dynamics torque at `t_s` (N m): what it takes to move
    /// the leg along it, joint damping included.
    pub fn reference_torque(&self, t_s: f64) -> [f64; 2] {
        let g = self.gait.sample(t_s.max(0.0));
        let q = [g.hip.angle_rad, g.knee.angle_rad];
        let qd = [g.hip.velocity_rad_s, g.knee.velocity_rad_s];
        let qdd = [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2];
        let tau = self.inertia.inverse_dynamics(q, qd, qdd);
        std::array::from_fn(|j| tau[j] + self.damping_nm_s_per_rad[j] * qd[j])
    }

    fn spasm_torques(&mut self, t_s: f64) -> [f64; 2] {
        if t_s >= self.planned_until_s {
            // Outside a planned run (open-loop stepping): draw a few seconds ahead.
            self.plan(t_s + 10.0);
        }
        while self
            .events
            .get(self.first_open)
            .is_some_and(|e| e.end_s() <= t_s)
        {
            self.first_open += 1;
        }
        let mut tau = [0.0; 2];
        for e in self.events[self.first_open..].iter() {
            if e.t_s > t_s {
                break;
            }
            tau[e.joint] += e.torque(t_s);
        }
        tau
    }

    /// The patient's torques at `t_s` with the limb at `q` (rad) and `qd` (rad/s); call it
    /// once per physics substep (the reflex delay lines advance by one substep).
    pub fn torques(&mut self, t_s: f64, q: [f64; 2], qd: [f64; 2]) -> PatientTorques {
        let spasm_nm = self.spasm_torques(t_s);
        let wants_effort = self.joints.iter().any(|j| j.effort.is_some());
        let mut out = PatientTorques {
            spasm_nm,
            ..PatientTorques::default()
        };
        for (k, j) in self.joints.iter_mut().enumerate() {
            out.reflex_nm[k] = j.reflex_torque(qd[k]);
            out.stiffness_nm[k] = j.stiffness.map_or(0.0, |m| m.torque(q[k]));
        }
        if wants_effort {
            // One inverse-dynamics evaluation per distinct delay (usually one for both).
            let mut cached: Option<(f64, [f64; 2])> = None;
            for k in 0..2 {
                if let Some(e) = self.joints[k].effort {
                    let tau = match cached {
                        Some((d, tau)) if d == e.delay_s => tau,
                        _ => {
                            let tau = self.reference_torque(t_s - e.delay_s);
                            cached = Some((e.delay_s, tau));
                            tau
                        }
                    };
                    out.effort_nm[k] = e.fraction * tau[k];
                }
            }
        }
        if let Some(w) = &mut self.walker {
            let own = w.torques(&self.gait, t_s, q, qd);
            for (e, o) in out.effort_nm.iter_mut().zip(own) {
                *e += o;
            }
        }
        self.last = out;
        out
    }

    /// The torques of the last substep.
    pub fn last(&self) -> PatientTorques {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::super::settings::tests::spasms;
    use super::*;

    #[test]
    fn random_spasms_come_at_the_set_rate_with_both_directions_and_in_range() {
        let mut src = SpasmSource::new(1, &spasms(6.0, 3));
        let minutes = 2000.0;
        let mut n = 0u32;
        let mut flexor = 0u32;
        while let Some(e) = src.next_before(minutes * 60.0) {
            n += 1;
            flexor += u32::from(e.direction == SpasmDirection::Flexor);
            assert!((10.0..=30.0).contains(&e.amplitude_nm), "{e:?}");
            assert!((0.2..=0.8).contains(&e.duration_s), "{e:?}");
        }
        // Poisson: 12 000 expected, sd 110.
        let rate = f64::from(n) / minutes;
        assert!((rate - 6.0).abs() < 0.2, "{rate} per minute");
        let share = f64::from(flexor) / f64::from(n);
        assert!((share - 0.5).abs() < 0.03, "flexor share {share}");
    }

    #[test]
    fn a_spasm_pulse_rises_to_its_amplitude_and_falls_back_smoothly() {
        let e = SpasmEvent {
            joint: 1,
            t_s: 2.0,
            amplitude_nm: 20.0,
            duration_s: 0.5,
            direction: SpasmDirection::Extensor,
            rise_fraction: 0.3,
        };
        assert_eq!(e.torque(1.999), 0.0);
        assert_eq!(e.torque(2.5), 0.0);
        assert!((e.torque(2.15) + 20.0).abs() < 1e-9, "{}", e.torque(2.15));
        // No jump anywhere: neighbouring samples 0.1 ms apart differ by little.
        let mut t = 1.99;
        while t < 2.51 {
            assert!(
                (e.torque(t + 1e-4) - e.torque(t)).abs() < 0.05,
                "jump at {t}"
            );
            t += 1e-4;
        }
    }

    /// A limb of two uniform 5 kg bars (the walking tests do not use its dynamics).
    fn two_bars() -> LegInertia {
        let bar = crate::body::LinkInertia {
            mass_kg: 5.0,
            com_below_joint_m: 0.2,
            inertia_kg_m2: 0.05,
        };
        LegInertia {
            thigh: bar,
            shank: bar,
            thigh_length_m: 0.4,
            pelvis_pitch_rad: 0.0,
        }
    }

    /// A walking patient's effort with no impedance of their own: their moments alone.
    #[test]
    fn a_walking_patient_produces_the_moments_at_their_phase_times_their_strength() {
        let settings: crate::patient::PatientSettings = toml::from_str(
            "[active]\nstride_cv = 0.0\nstrength = 0.5\nstiffness_nm_per_rad = [0.0, 0.0]\ndamping_nm_s_per_rad = [0.0, 0.0]\nown_torque = \"walking\"\n",
        )
        .unwrap();
        let gait = GaitReference::adult(0.5, 2.0, 1.0).unwrap();
        let inertia = two_bars();
        let mut p = Patient::new(&settings, 1e-3, gait, inertia, [0.0; 2]).unwrap();
        // Hip: 0..100 N m over the cycle; knee: its negative.
        let ramp: Vec<f64> = (0..=100).map(f64::from).collect();
        let minus: Vec<f64> = ramp.iter().map(|v| -v).collect();
        assert!(p.walk_with_moments([ramp, minus], None));
        let mut t = 0.0;
        while t < 1.0 + 2.0 * 1.25 {
            p.torques(t, [0.0; 2], [0.0; 2]);
            t += 1e-3;
        }
        // At 3.5 s of 2 s strides, three quarters into the cycle: 75 N m, halved.
        let e = p.torques(t, [0.0; 2], [0.0; 2]).effort_nm;
        let want = 0.5 * 100.0 * gait.phase(t);
        assert!(
            (e[0] - want).abs() < 0.01 && (e[1] + want).abs() < 0.01,
            "{e:?} vs {want}"
        );
        assert!((want - 37.5).abs() < 0.1, "{want}");
        // A patient who is not active takes no moments.
        let passive = crate::patient::PatientSettings::default();
        let mut q = Patient::new(&passive, 1e-3, gait, inertia, [0.0; 2]).unwrap();
        assert!(!q.walk_with_moments([vec![1.0; 101], vec![1.0; 101]], None));
    }

    /// Regression (issue 28): each leg drew its own stride periods, so a person's legs
    /// drifted out of step on a two-leg trainer (the patient's hip work over 60 s, 328 J
    /// right against 120 J left at equal strength). Seen through the walking moments (a
    /// ramp over the cycle), the legs stay half a cycle apart however their strides vary.
    #[test]
    fn regression_a_walkers_two_legs_keep_half_a_stride_apart() {
        let settings: crate::patient::PatientSettings = toml::from_str(
            "[active]\nstride_cv = 0.1\nseed = 7\nstiffness_nm_per_rad = [0.0, 0.0]\ndamping_nm_s_per_rad = [0.0, 0.0]\n",
        )
        .unwrap();
        let gait = GaitReference::adult(0.5, 1.0, 1.0).unwrap();
        let inertia = two_bars();
        let ramp: Vec<f64> = (0..=100).map(f64::from).collect();
        let mut legs: Vec<Patient> = (0..2)
            .map(|leg| {
                let mut p = Patient::new(
                    &settings.for_leg(leg),
                    1e-3,
                    gait.for_leg(leg),
                    inertia,
                    [0.0; 2],
                )
                .unwrap();
                assert!(p.walk_with_moments([ramp.clone(), ramp.clone()], None));
                p
            })
            .collect();
        let mut worst: f64 = 0.0;
        for k in 0..30_000 {
            let t = f64::from(k) * 1e-3;
            let [a, b] = [0, 1].map(|l| legs[l].torques(t, [0.0; 2], [0.0; 2]).effort_nm[0]);
            // Their phases (effort / 100) half a cycle apart, away from the ramp's wrap.
            let gap = (b - a).rem_euclid(100.0);
            if t > 1.0 && (2.0..98.0).contains(&a) && (2.0..98.0).contains(&b) {
                worst = worst.max((gap - 50.0).abs());
            }
        }
        assert!(
            worst < 0.5,
            "the legs' phases drifted {worst} % of a cycle from half"
        );
    }

    #[test]
    fn the_delay_line_returns_each_value_after_its_length() {
        let mut d = Delay::new(0.003, 0.001);
        let out: Vec<f64> = (1..=6).map(|v| d.push(f64::from(v))).collect();
        assert_eq!(out, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
    }
}
