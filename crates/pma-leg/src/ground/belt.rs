//! The treadmill: a compliant foot on a moving belt and the pelvis on body-weight support.
//!
//! rapier's contacts are rigid and inelastic (a heel strike is a one-step impulse, and
//! contact softness is global), so the foot's contacts are computed here instead, as
//! Hunt-Crossley spheres against the belt plane, the normal force of OpenSim's
//! `SmoothSphereHalfSpaceForce` (Serrancoli, Falisse et al. 2019, IEEE TNSRE 27(1); used by
//! Falisse et al. 2019, J R Soc Interface 16:20190402, for predictive gait):
//! `F_n = K d^{3/2} (1 + 3/2 c d')` with `K = (4/3) k^{3/2} sqrt(r)`, `k = E^{2/3} / 2`.
//!
//! Friction is elasto-plastic: while a sphere sticks, the belt shears it like a spring of
//! Mindlin's tangential stiffness of a Hertzian contact, `k_t = 2 (1 - nu) / (2 - nu) dF_n/dd`
//! (Mindlin 1949, J Appl Mech 16:259; Johnson 1985, Contact Mechanics, Sec. 7.2; `nu = 0.5`
//! for a rubber sole gives `k_t = K sqrt(d)`), damped as the normal direction is; once that
//! force would exceed `(mu + mu_v |v|) F_n` the sphere slides at that force against the slip
//! `v`. OpenSim's smooth Coulomb law `mu F_n min(v/v_t, 1)` was tried first: at the leg's
//! 0.5 ms substeps its slope `mu F_n / v_t` chattered on a loaded heel (the friction
//! alternating between about +800 and -800 N from one substep to the next, the slip at
//! 0.15 m/s where the foot was not moving), and a wider `v_t` lets a stance foot creep.
//! A belt moving backwards at `speed` is the plane's velocity in the slip: no moving body
//! is needed. The forces go on the foot at the contact points, so the loading rate at heel
//! strike comes from the model, not from the solver's regularisation.
use crate::base::PerLeg;
use crate::ground::{
    sphere_contact, BwsKind, ContactParams, FootReaction, FootSphere, GroundReaction, OtherLeg,
    SagittalChain, SphereContact, TreadmillSettings, SELF_PACED_FILTER_S, START_HOLD_N_PER_M,
};
use rapier3d::prelude::{RigidBodyHandle, RigidBodySet, Vector};

/// One foot as the treadmill sees it: its rigid body, its link and its spheres.
#[derive(Debug, Clone)]
pub struct FootSetup {
    /// The foot's body.
    pub(crate) body: RigidBodyHandle,
    /// The foot's link (`foot`, `right_foot`, ...).
    pub link: String,
    /// Its contact spheres, in the link's frame.
    pub spheres: Vec<FootSphere>,
}

/// What a treadmill is made of, fixed when the exoskeleton is built.
#[derive(Debug, Clone)]
pub(crate) struct GroundSetup {
    pub settings: TreadmillSettings,
    /// The simulated feet, leg by leg.
    pub feet: Vec<FootSetup>,
    /// The first leg's sagittal geometry (the virtual other leg is its copy).
    pub chain: SagittalChain,
    pub pelvis: RigidBodyHandle,
    /// Everything the belt and harness carry (kg).
    pub total_mass_kg: f64,
    /// The patient's mass on the pelvis (kg).
    pub carried_kg: f64,
    /// The pelvis's height standing (m): a spring harness's rest.
    pub standing_z_m: f64,
    /// Whether the pelvis slides fore-aft (`pelvis_x`), held by the harness's spring at
    /// its place when built (m, world X).
    pub fore_aft_at_m: Option<f64>,
    /// Where the pelvis frame is when its fore-aft slide is at its lower and upper limit
    /// (m, world X; `None` without a slide).
    pub fore_aft_stops_m: Option<[f64; 2]>,
}

/// One foot's contacts, summed over a period's substeps.
#[derive(Debug, Clone)]
struct FootState {
    /// Vertical and fore-aft force on the foot (N), summed over the period's substeps.
    sum: [f64; 2],
    deepest_m: f64,
    fastest_slip_m_s: f64,
    /// Sum of fore-aft slip times normal force, and of the normal forces, over the period.
    weighted_slip: [f64; 2],
    contacts: usize,
    /// This substep's contacts, sphere by sphere (sized once).
    current: Vec<Option<SphereContact>>,
    /// How far the belt has sheared each sphere while it sticks (m, X and Y).
    stick_m: Vec<[f64; 2]>,
    last: FootReaction,
}

impl FootState {
    fn new(spheres: usize) -> Self {
        Self {
            sum: [0.0; 2],
            deepest_m: 0.0,
            fastest_slip_m_s: 0.0,
            weighted_slip: [0.0; 2],
            contacts: 0,
            current: vec![None; spheres],
            stick_m: vec![[0.0; 2]; spheres],
            last: FootReaction::default(),
        }
    }

    /// The belt's contacts on `foot`'s spheres over a substep of `h_s`, the belt moving
    /// backwards at `belt_m_s`.
    fn apply(
        &mut self,
        foot: &FootSetup,
        params: &ContactParams,
        belt_m_s: f64,
        bodies: &mut RigidBodySet,
        h_s: f64,
    ) {
        let Some(rb) = bodies.get_mut(foot.body) else {
            return;
        };
        let pose = *rb.position();
        self.contacts = 0;
        for (k, s) in foot.spheres.iter().enumerate() {
            self.current[k] = None;
            let c = pose.transform_point(vector(s.center_m));
            let contact_point = c - Vector::new(0.0, 0.0, s.radius_m);
            let v = rb.velocity_at_point(contact_point);
            let Some(contact) = sphere_contact(
                params,
                s.radius_m,
                [c.x, c.y, c.z].map(f64::from),
                [v.x, v.y, v.z].map(f64::from),
                belt_m_s,
                (&mut self.stick_m[k], h_s),
            ) else {
                continue;
            };
            self.current[k] = Some(contact);
            let f = contact.force_n;
            rb.add_force_at_point(vector(f), vector(contact.point_m), true);
            self.sum[0] += f[2];
            self.sum[1] += f[0];
            self.deepest_m = self.deepest_m.max(contact.depth_m);
            if f[2] > 0.0 {
                self.fastest_slip_m_s = self.fastest_slip_m_s.max(contact.slip_m_s);
                self.weighted_slip[0] += (v.x + belt_m_s) * f[2];
                self.weighted_slip[1] += f[2];
            }
            self.contacts += 1;
        }
    }

    /// Closes a period of `n` substeps.
    fn end_period(&mut self, n: f64) {
        self.last = FootReaction {
            vertical_n: self.sum[0] / n,
            fore_aft_n: self.sum[1] / n,
            penetration_m: self.deepest_m,
            slip_m_s: self.fastest_slip_m_s,
            fore_aft_slip_m_s: if self.weighted_slip[1] > 0.0 {
                self.weighted_slip[0] / self.weighted_slip[1]
            } else {
                0.0
            },
            contacts: self.contacts,
        };
        self.sum = [0.0; 2];
        self.deepest_m = 0.0;
        self.fastest_slip_m_s = 0.0;
        self.weighted_slip = [0.0; 2];
    }

    /// Fore-aft centre of pressure of the last substep's contacts (m, world X; NaN
    /// without one).
    fn centre_of_pressure_x_m(&self) -> f64 {
        let (moment, force) = self.current.iter().flatten().fold((0.0, 0.0), |(m, f), c| {
            (m + c.point_m[0] * c.force_n[2], f + c.force_n[2])
        });
        if force > 0.0 {
            moment / force
        } else {
            f64::NAN
        }
    }
}

/// The treadmill acting on the exoskeleton: the belt's contacts on every foot, the
/// harness and a virtual other leg on the pelvis, applied every physics substep.
#[derive(Debug, Clone)]
pub struct Ground {
    setup: GroundSetup,
    other: Option<OtherLeg>,
    /// Time since the exoskeleton was built (s), advanced every substep.
    clock_s: f64,
    /// The belt comes up to speed over this long from the start (s), with the gait.
    belt_ramp_s: f64,
    feet: Vec<FootState>,
    /// This period's sums over substeps: the other leg's and the harness's vertical
    /// forces, the harness's fore-aft force (N), the belt's speed (m/s).
    sum: [f64; 4],
    substeps: u32,
    last: GroundReaction,
    /// The pelvis's low-passed fore-aft offset from its start a self-paced belt follows
    /// (m).
    pelvis_offset_m: f64,
    /// How far the belt's surface has moved backwards since the start (m).
    belt_travel_m: f64,
}

impl Ground {
    pub(crate) fn new(setup: GroundSetup) -> Self {
        let feet = setup
            .feet
            .iter()
            .map(|f| FootState::new(f.spheres.len()))
            .collect();
        Self {
            setup,
            other: None,
            clock_s: 0.0,
            belt_ramp_s: 0.0,
            feet,
            sum: [0.0; 4],
            substeps: 0,
            last: GroundReaction::default(),
            pelvis_offset_m: 0.0,
            belt_travel_m: 0.0,
        }
    }

    /// Sets the belt's speed (m/s).
    pub(crate) fn set_belt_speed(&mut self, v_m_s: f64) {
        self.setup.settings.speed_m_per_s = Some(v_m_s);
    }

    /// Brings the belt up to speed over `ramp_s` from the start, with the gait's own
    /// start-up (the same quintic): a belt at full speed under a standing leg would drag
    /// its foot away.
    pub(crate) fn set_belt_ramp(&mut self, ramp_s: f64) {
        self.belt_ramp_s = ramp_s;
    }

    /// The belt's speed at the exoskeleton's clock (m/s).
    pub fn belt_speed_now_m_s(&self) -> f64 {
        let v = self.setup.settings.belt_speed_m_s();
        if self.belt_ramp_s <= 0.0 || self.clock_s >= self.belt_ramp_s {
            return v + self.self_paced_trim_m_s();
        }
        let s = (self.clock_s / self.belt_ramp_s).max(0.0);
        v * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
    }

    /// How far the belt's surface has moved backwards since the start (m).
    pub fn belt_travel_m(&self) -> f64 {
        self.belt_travel_m
    }

    /// A self-paced belt's change of speed (m/s; 0 for a belt at constant speed): the
    /// pelvis ahead of its start speeds the belt up.
    fn self_paced_trim_m_s(&self) -> f64 {
        self.setup.settings.self_paced_gain_per_s * self.pelvis_offset_m
    }

    /// Whether a self-paced belt follows the pelvis now: after the belt's start-up and the
    /// harness's start-up hold.
    fn self_paced_now(&self) -> bool {
        let s = &self.setup.settings;
        s.self_paced_gain_per_s > 0.0
            && self.clock_s >= self.belt_ramp_s
            && self.clock_s >= s.pelvis_held_until_s
    }

    /// Puts the virtual other leg under the pelvis.
    pub(crate) fn set_other_leg(&mut self, other: OtherLeg) {
        self.other = Some(other);
    }

    /// Whether a virtual other leg shares the load.
    pub fn has_other_leg(&self) -> bool {
        self.other.is_some()
    }

    /// The simulated feet, leg by leg.
    pub fn feet(&self) -> &[FootSetup] {
        &self.setup.feet
    }

    /// Foot `leg`'s contacts at the last substep, sphere by sphere (`None` out of contact).
    pub fn sphere_contacts(&self, leg: usize) -> &[Option<SphereContact>] {
        self.feet.get(leg).map_or(&[], |f| f.current.as_slice())
    }

    /// Fore-aft centre of pressure of foot `leg`'s last substep's contacts (m, world X;
    /// NaN without one).
    pub fn centre_of_pressure_x_m(&self, leg: usize) -> f64 {
        self.feet
            .get(leg)
            .map_or(f64::NAN, FootState::centre_of_pressure_x_m)
    }

    /// The settings.
    pub fn settings(&self) -> &TreadmillSettings {
        &self.setup.settings
    }

    /// Mass of everything the belt and harness carry: exoskeleton, legs and the patient's
    /// mass on the pelvis (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.setup.total_mass_kg
    }

    /// Where the pelvis frame is at its fore-aft slide's limits (m, world X; `None`
    /// without a slide).
    pub fn fore_aft_stops_m(&self) -> Option<[f64; 2]> {
        self.setup.fore_aft_stops_m
    }

    /// The patient's mass put on the pelvis (kg).
    pub fn carried_kg(&self) -> f64 {
        self.setup.carried_kg
    }

    /// The weight the belt carries at rest: `(1 - bws_fraction) m g` (N).
    pub fn unsupported_weight_n(&self) -> f64 {
        (1.0 - self.setup.settings.bws_fraction)
            * self.setup.total_mass_kg
            * pma_model::GRAVITY_M_S2
    }

    pub(crate) fn pelvis(&self) -> RigidBodyHandle {
        self.setup.pelvis
    }

    /// The first leg's sagittal geometry.
    pub fn chain(&self) -> &SagittalChain {
        &self.setup.chain
    }

    /// The other leg's joint angles (rad) now, if there is one.
    pub fn other_leg_pose(&self) -> Option<[f64; 2]> {
        Some(self.other.as_ref()?.pose(self.clock_s))
    }

    /// Makes the other leg hold `pose` (rad) instead of walking (`None`: walk again).
    pub(crate) fn hold_other_leg(&mut self, pose: Option<[f64; 2]>) {
        if let Some(o) = &mut self.other {
            o.hold = pose;
        }
    }

    /// The share of the body weight the harness carries now: `bws_fraction`, or more
    /// while the start's support is lowered.
    pub fn support_fraction_now(&self) -> f64 {
        self.setup.settings.support_fraction_at(self.clock_s)
    }

    /// The harness's upward force (N) with the pelvis at height `z_m`.
    pub fn support_force_n(&self, z_m: f64) -> f64 {
        let weight =
            self.support_fraction_now() * self.setup.total_mass_kg * pma_model::GRAVITY_M_S2;
        match self.setup.settings.bws {
            BwsKind::ConstantForce => weight,
            BwsKind::Spring => (weight
                + self.setup.settings.bws_spring_n_per_m * (self.setup.standing_z_m - z_m))
                .max(0.0),
        }
    }

    /// Adds this substep's contact forces to every foot, and the harness's and the other
    /// leg's to the pelvis (their user forces reset by the exoskeleton at the substep's
    /// start); `h_s` is the substep's length.
    pub(crate) fn apply(&mut self, bodies: &mut RigidBodySet, h_s: f64) {
        self.substeps += 1;
        if let Some(rb) = bodies.get_mut(self.setup.pelvis) {
            let z = rb.translation().z;
            let up = self.support_force_n(z);
            let other = match &mut self.other {
                Some(o) => o.force(
                    &self.setup.settings.contact,
                    self.clock_s,
                    h_s,
                    z,
                    rb.linvel().z,
                ),
                None => 0.0,
            };
            let held = match self.setup.fore_aft_at_m {
                Some(x0) => {
                    let t = &self.setup.settings;
                    let (k, c) = if self.clock_s < t.pelvis_held_until_s {
                        START_HOLD_N_PER_M
                    } else {
                        (
                            t.pelvis_fore_aft_n_per_m,
                            t.pelvis_fore_aft_damping_n_s_per_m,
                        )
                    };
                    -k * (rb.translation().x - x0) - c * rb.linvel().x
                }
                None => 0.0,
            };
            if let (true, Some(x0)) = (self.self_paced_now(), self.setup.fore_aft_at_m) {
                let offset = rb.translation().x - x0;
                self.pelvis_offset_m += (offset - self.pelvis_offset_m) * h_s / SELF_PACED_FILTER_S;
            }
            self.sum[0] += other;
            self.sum[1] += up;
            self.sum[2] += held;
            rb.add_force(Vector::new(held, 0.0, up + other), true);
        }
        let belt = self.belt_speed_now_m_s();
        self.sum[3] += belt;
        self.belt_travel_m += belt * h_s;
        let params = self.setup.settings.contact;
        for (state, foot) in self.feet.iter_mut().zip(&self.setup.feet) {
            state.apply(foot, &params, belt, bodies, h_s);
        }
        self.clock_s += h_s;
    }

    /// Closes a period: its averages become [`Self::reaction`].
    pub(crate) fn end_period(&mut self) {
        let n = f64::from(self.substeps.max(1));
        for f in &mut self.feet {
            f.end_period(n);
        }
        let feet = &self.feet;
        self.last = GroundReaction {
            feet: PerLeg::from_fn(feet.len(), |i| feet[i].last),
            contralateral_n: self.sum[0] / n,
            support_n: self.sum[1] / n,
            harness_fore_aft_n: self.sum[2] / n,
            belt_speed_m_s: self.sum[3] / n,
        };
        self.sum = [0.0; 4];
        self.substeps = 0;
    }

    /// The last period's ground reaction.
    pub fn reaction(&self) -> GroundReaction {
        self.last
    }

    /// Time since the exoskeleton was built, as the other leg's reference sees it (s).
    pub fn clock_s(&self) -> f64 {
        self.clock_s
    }
}

fn vector(v: [f64; 3]) -> Vector {
    Vector::new(v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hertz_law_matches_opensims_smooth_sphere_constants() {
        // E = 1e6 N/m^2, r = 0.032 m (Falisse et al. 2019): k = 5000, K = 4/3 k sqrt(r k).
        let p = ContactParams {
            stiffness_n_per_m2: 1e6,
            ..ContactParams::default()
        };
        let k = p.hertz_coefficient(0.032);
        assert!((k - 4.0 / 3.0 * 5000.0 * (0.032f64 * 5000.0).sqrt()).abs() < 1e-6);
        assert_eq!(p.normal_force(0.032, -1e-3, 0.0), 0.0);
        let f = p.normal_force(0.032, 0.01, 0.0);
        assert!((f - k * 1e-3).abs() < 1e-9, "{f}");
        // Separating fast, the damping term never makes the contact pull.
        assert_eq!(p.normal_force(0.032, 0.01, -10.0), 0.0);
    }

    #[test]
    fn friction_opposes_slip_against_the_moving_belt() {
        let p = ContactParams::default();
        let h = 5e-4;
        // A foot at rest on a belt moving backwards slips forwards relative to it: the belt
        // drags it backwards, at the sliding limit.
        let mut stick = [0.0; 2];
        let c = sphere_contact(&p, 0.03, [0.0, 0.0, 0.02], [0.0; 3], 1.0, (&mut stick, h)).unwrap();
        let f = c.force_n;
        assert!(f[0] < 0.0 && (c.slip_m_s - 1.0).abs() < 1e-12, "{c:?}");
        assert!((-f[0] - f[2] * (0.8 + 0.5)).abs() < 1e-9, "{c:?}");
        // Sliding leaves the spring at what it holds.
        let k_t = p.tangential_stiffness(0.03, 0.01);
        assert!((stick[0] * k_t + f[0]).abs() < 1e-9, "{stick:?}");
        // Moving with the belt and unsheared: no friction.
        let mut stick = [0.0; 2];
        let c = sphere_contact(
            &p,
            0.03,
            [0.0, 0.0, 0.02],
            [-1.0, 0.0, 0.0],
            1.0,
            (&mut stick, h),
        )
        .unwrap();
        assert_eq!(c.force_n[0], 0.0);
        let mut stick = [0.001, 0.0];
        assert!(
            sphere_contact(&p, 0.03, [0.0, 0.0, 0.031], [0.0; 3], 1.0, (&mut stick, h)).is_none()
        );
        assert_eq!(stick, [0.0; 2], "lifting off releases the shear");
    }

    /// Issue 50: a contact works out `K` and `d^{3/2}` once, where it worked each out at
    /// every use. Its normal force and its sticking spring must stay, bit for bit, those
    /// of `normal_force` and `tangential_stiffness`.
    #[test]
    fn regression_a_contact_shares_its_hertz_terms_without_changing_a_bit() {
        let p = ContactParams::default();
        let (r, h) = (0.03, 2.5e-4);
        for (z, rate) in [(0.0299, 0.0), (0.027, 0.2), (0.02, -0.05), (0.01, 1.0)] {
            let mut stick = [2e-5, 0.0];
            let c = sphere_contact(
                &p,
                r,
                [0.0, 0.0, z],
                [-0.5, 0.0, -rate],
                0.5,
                (&mut stick, h),
            )
            .expect("in contact");
            let d = r - z;
            assert_eq!(c.force_n[2], p.normal_force(r, d, rate), "d = {d}");
            // Sticking at no slip: the spring's force at the shear it holds, with no damping.
            assert_eq!(
                c.force_n[0],
                -p.tangential_stiffness(r, d) * 2e-5,
                "d = {d}"
            );
        }
    }

    #[test]
    fn a_sticking_sphere_is_a_spring_of_mindlins_stiffness() {
        // Sheared by 1 mm at rest, below the sliding limit: the force is k_t x 1 mm, and
        // k_t is 2/3 of the normal stiffness (nu = 0.5).
        let p = ContactParams::default();
        let (r, d): (f64, f64) = (0.03, 0.01);
        let k_n = 1.5 * p.hertz_coefficient(r) * d.sqrt();
        assert!((p.tangential_stiffness(r, d) - 2.0 / 3.0 * k_n).abs() < 1e-9);
        let mut stick = [1e-3, 0.0];
        let c = sphere_contact(
            &p,
            r,
            [0.0, 0.0, r - d],
            [-0.5, 0.0, 0.0],
            0.5,
            (&mut stick, 5e-4),
        )
        .unwrap();
        assert!(
            (c.force_n[0] + p.tangential_stiffness(r, d) * 1e-3).abs() < 1e-9,
            "{c:?}"
        );
        assert!(c.force_n[0].abs() < 0.8 * c.force_n[2]);
        assert_eq!(stick, [1e-3, 0.0]);
    }

    #[test]
    fn bad_treadmill_input_names_the_field() {
        let ok = TreadmillSettings {
            speed_m_per_s: Some(0.6),
            ..TreadmillSettings::new(0.3, 75.0)
        };
        ok.validate().unwrap();
        for (bad, field) in [
            (
                TreadmillSettings {
                    height_m: Some(1.2),
                    ..ok
                },
                "treadmill.height_m",
            ),
            (
                TreadmillSettings {
                    height_m: Some(f64::NAN),
                    ..ok
                },
                "treadmill.height_m",
            ),
            (
                TreadmillSettings {
                    speed_m_per_s: Some(-0.5),
                    ..ok
                },
                "speed_m_per_s",
            ),
            (
                TreadmillSettings {
                    bws_fraction: 1.2,
                    ..ok
                },
                "bws_fraction",
            ),
            (
                TreadmillSettings {
                    body_mass_kg: f64::NAN,
                    ..ok
                },
                "body_mass_kg",
            ),
            (
                TreadmillSettings {
                    bws: BwsKind::Spring,
                    ..ok
                },
                "bws_spring_n_per_m",
            ),
            (
                TreadmillSettings {
                    self_paced_gain_per_s: -0.3,
                    ..ok
                },
                "self_paced_gain_per_s",
            ),
            (
                TreadmillSettings {
                    bws_start_fraction: Some(0.2),
                    ..ok
                },
                "bws_start_fraction",
            ),
            (
                TreadmillSettings {
                    bws_release_s: [3.0, 1.0],
                    ..ok
                },
                "bws_release_s",
            ),
            (
                TreadmillSettings {
                    bws_release_s: [-1.0, 1.0],
                    ..ok
                },
                "bws_release_s",
            ),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn the_legs_share_follows_the_support_the_harness_lowers() {
        // Walking at 30 %: while the harness carries 80 % the legs carry 0.2 / 0.7 of what
        // they carry at 30 %, after the window all of it.
        let mut s = TreadmillSettings::new(0.3, 75.0);
        s.bws_start_fraction = Some(0.8);
        s.bws_release_s = [1.0, 2.0];
        for (t_s, share) in [(0.5, 0.2 / 0.7), (1.5, 0.45 / 0.7), (3.0, 1.0)] {
            assert!((s.legs_share_at(t_s) - share).abs() < 1e-12, "{t_s} s");
        }
        s.bws_fraction = 1.0;
        assert_eq!(s.legs_share_at(0.5), 1.0);
    }

    #[test]
    fn regression_a_release_window_without_a_start_support_was_ignored() {
        let base = TreadmillSettings::new(0.0, 75.0);
        let window_alone = TreadmillSettings {
            bws_release_s: [1.0, 2.0],
            ..base
        };
        let e = window_alone.validate().unwrap_err().to_string();
        assert!(
            e.contains("treadmill.bws_release_s") && e.contains("bws_start_fraction"),
            "{e}"
        );
        let start_alone = TreadmillSettings {
            bws_start_fraction: Some(0.3),
            ..base
        };
        let e = start_alone.validate().unwrap_err().to_string();
        assert!(e.contains("treadmill.bws_start_fraction"), "{e}");
        // A start equal to the walking support changes nothing and needs no window.
        TreadmillSettings {
            bws_start_fraction: Some(0.0),
            ..base
        }
        .validate()
        .unwrap();
        TreadmillSettings {
            bws_start_fraction: Some(0.3),
            bws_release_s: [1.0, 2.0],
            ..base
        }
        .validate()
        .unwrap();
    }
}
