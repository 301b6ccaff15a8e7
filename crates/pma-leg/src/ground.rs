//! The treadmill: a compliant foot on a moving belt and the pelvis on body-weight support.
//!
//! rapier's contacts are rigid and inelastic (a heel strike is a one-step impulse, and
//! contact softness is global), so the foot's contacts are computed here instead, as
//! Hunt-Crossley spheres against the belt plane with a smooth Coulomb friction, the model
//! of OpenSim's `SmoothSphereHalfSpaceForce` (Serrancoli, Falisse et al. 2019, IEEE TNSRE
//! 27(1); used by Falisse et al. 2019, J R Soc Interface 16:20190402, for predictive gait):
//! normal force `F_n = K d^{3/2} (1 + 3/2 c d')` with `K = (4/3) k^{3/2} sqrt(r)`,
//! `k = E^{2/3} / 2`, and friction `mu F_n min(v/v_t, 1)` plus `mu_v F_n v` against the slip
//! `v`. A belt moving backwards at `speed` is the plane's velocity in the slip: no moving
//! body is needed. The forces go on the foot at the contact points, so the loading rate at
//! heel strike comes from the model, not from the solver's regularisation.
use crate::error::{invalid, LegError};
use pma_model::error::{non_negative, positive, within};
use rapier3d::prelude::{Real, RigidBodyHandle, RigidBodySet, Vector};
use serde::Deserialize;

/// The compliant contact of one foot sphere with the belt.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Hertz stiffness `E` of OpenSim's smooth sphere model (N/m^2). Default 2.0e6: SCONE's
    /// two-sphere H0918 foot (opensim-org/SCONE, `scenarios/Examples/data/H0918.hfd`,
    /// stiffness 5975.21 in Hyfydy's units) converted to OpenSim's (Hyfydy user manual).
    pub stiffness_n_per_m2: f64,
    /// Hunt-Crossley dissipation `c` (s/m). Default 1.0 (H0918's damping).
    pub dissipation_s_per_m: f64,
    /// Coulomb friction coefficient of shoe on belt. Default 0.8: no measured value was
    /// found; gait models use 0.7-0.9 (Falisse et al. 2019: 0.8), and level walking needs
    /// only about 0.2 (Redfern et al. 2001, Ergonomics 44:1138).
    pub friction: f64,
    /// Viscous friction `mu_v` (s/m). Default 0.5 (Falisse et al. 2019).
    pub viscous_friction_s_per_m: f64,
    /// Slip speed below which friction grows linearly (m/s). Default 0.05: Falisse et al.
    /// use 0.2 m/s for smooth optimisation, which lets a stance foot creep at a few cm/s;
    /// 0.05 m/s keeps the creep under 1 cm/s at walking's friction demand and is stable at
    /// the leg's substeps.
    pub transition_velocity_m_s: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m2: 2.0e6,
            dissipation_s_per_m: 1.0,
            friction: 0.8,
            viscous_friction_s_per_m: 0.5,
            transition_velocity_m_s: 0.05,
        }
    }
}

impl ContactParams {
    fn validate(&self) -> Result<(), LegError> {
        positive(
            "treadmill.contact.stiffness_n_per_m2",
            self.stiffness_n_per_m2,
        )?;
        non_negative(
            "treadmill.contact.dissipation_s_per_m",
            self.dissipation_s_per_m,
        )?;
        non_negative("treadmill.contact.friction", self.friction)?;
        non_negative(
            "treadmill.contact.viscous_friction_s_per_m",
            self.viscous_friction_s_per_m,
        )?;
        positive(
            "treadmill.contact.transition_velocity_m_s",
            self.transition_velocity_m_s,
        )?;
        Ok(())
    }

    /// `K` of `F_n = K d^{3/2}` for a sphere of `radius_m` (N/m^{3/2}).
    pub fn hertz_coefficient(&self, radius_m: f64) -> f64 {
        let k = 0.5 * self.stiffness_n_per_m2.powf(2.0 / 3.0);
        4.0 / 3.0 * k * (radius_m * k).sqrt()
    }

    /// Normal force (N, pushing the foot up) at penetration `depth_m` growing at
    /// `depth_rate_m_s`: zero out of contact, never pulling.
    pub fn normal_force(&self, radius_m: f64, depth_m: f64, depth_rate_m_s: f64) -> f64 {
        if depth_m <= 0.0 {
            return 0.0;
        }
        let hertz = self.hertz_coefficient(radius_m) * depth_m.powf(1.5);
        (hertz * (1.0 + 1.5 * self.dissipation_s_per_m * depth_rate_m_s)).max(0.0)
    }

    /// Friction force magnitude (N) opposing a slip of `slip_m_s` under `normal_n`.
    pub fn friction_force(&self, normal_n: f64, slip_m_s: f64) -> f64 {
        let v = slip_m_s.abs();
        normal_n
            * (self.friction * (v / self.transition_velocity_m_s).min(1.0)
                + self.viscous_friction_s_per_m * v)
    }
}

/// How the harness holds the pelvis up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum BwsKind {
    /// A constant upward force (an actively controlled unloading system, as the Lokomat's
    /// Lokolift or a cable robot).
    #[default]
    ConstantForce,
    /// A spring (a counterweight-free harness), giving the support force at the standing
    /// pelvis height and `bws_spring_n_per_m` per metre of sinking.
    Spring,
}

/// The `[treadmill]` section of a scenario.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreadmillSettings {
    /// Belt speed (m/s, the belt's surface moves backwards).
    pub speed_m_per_s: f64,
    /// Fraction of the body weight (patient and exoskeleton) the harness carries, 0-1.
    pub bws_fraction: f64,
    /// The patient's body mass (kg): everything above the hips and the other leg rides on
    /// the pelvis.
    pub body_mass_kg: f64,
    /// Constant force (default) or spring.
    #[serde(default)]
    pub bws: BwsKind,
    /// Stiffness of a spring harness (N/m).
    #[serde(default)]
    pub bws_spring_n_per_m: f64,
    /// The foot's contact.
    #[serde(default)]
    pub contact: ContactParams,
}

impl TreadmillSettings {
    /// Checks every field; the error names it.
    pub fn validate(&self) -> Result<(), LegError> {
        non_negative("treadmill.speed_m_per_s", self.speed_m_per_s)?;
        within(
            "treadmill.bws_fraction",
            self.bws_fraction,
            0.0,
            1.0,
            "a fraction of the body weight, 0 to 1",
        )?;
        positive("treadmill.body_mass_kg", self.body_mass_kg)?;
        if self.bws == BwsKind::Spring {
            positive("treadmill.bws_spring_n_per_m", self.bws_spring_n_per_m)?;
        }
        if self.body_mass_kg > 500.0 {
            return Err(invalid(
                "treadmill.body_mass_kg",
                self.body_mass_kg,
                "a patient's mass, at most 500 kg",
            ));
        }
        self.contact.validate()
    }
}

/// One contact sphere on the foot, in the foot's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootSphere {
    /// Centre in the foot link's frame (m).
    pub center_m: [f64; 3],
    /// Radius (m).
    pub radius_m: f64,
}

/// What the belt did to the foot during one period (averaged over its substeps).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroundReaction {
    /// Vertical ground reaction force (N).
    pub vertical_n: f64,
    /// Horizontal (fore-aft) ground reaction force (N, forward positive).
    pub fore_aft_n: f64,
    /// Deepest penetration of a sphere into the belt (m; 0 out of contact).
    pub penetration_m: f64,
    /// Largest slip speed of a loaded sphere against the belt (m/s).
    pub slip_m_s: f64,
    /// Spheres in contact at the end of the period.
    pub contacts: usize,
}

/// One sphere's contact with the belt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereContact {
    /// Force on the foot (N, world frame).
    pub force_n: [f64; 3],
    /// Where it acts: the sphere's lowest point (m).
    pub point_m: [f64; 3],
    /// Penetration into the belt (m).
    pub depth_m: f64,
    /// Slip speed against the belt (m/s).
    pub slip_m_s: f64,
}

/// One sphere's contact, from the sphere centre `c` (m) and the velocity `v` (m/s) of the
/// foot's material point at the contact: the belt is the plane `z = 0` moving at `-speed`
/// along X. `None` out of contact.
pub fn sphere_contact(
    params: &ContactParams,
    radius_m: f64,
    c: [f64; 3],
    v: [f64; 3],
    belt_speed_m_s: f64,
) -> Option<SphereContact> {
    let depth = radius_m - c[2];
    if depth <= 0.0 {
        return None;
    }
    let point = [c[0], c[1], c[2] - radius_m];
    let normal = params.normal_force(radius_m, depth, -v[2]);
    let slip = [v[0] + belt_speed_m_s, v[1]];
    let speed = slip[0].hypot(slip[1]);
    let (fx, fy) = if speed > 1e-12 {
        let f = params.friction_force(normal, speed);
        (-f * slip[0] / speed, -f * slip[1] / speed)
    } else {
        (0.0, 0.0)
    };
    Some(SphereContact {
        force_n: [fx, fy, normal],
        point_m: point,
        depth_m: depth,
        slip_m_s: speed,
    })
}

/// What a treadmill is made of, fixed when the leg is built.
#[derive(Debug, Clone)]
pub(crate) struct GroundSetup {
    pub settings: TreadmillSettings,
    pub spheres: Vec<FootSphere>,
    pub foot: RigidBodyHandle,
    pub pelvis: RigidBodyHandle,
    /// Everything the belt and harness carry (kg).
    pub total_mass_kg: f64,
    /// The patient's mass on the pelvis (kg).
    pub carried_kg: f64,
    /// The pelvis's height standing (m): a spring harness's rest.
    pub standing_z_m: f64,
}

/// The treadmill acting on a leg: the belt's contacts on the foot and the harness on the
/// pelvis, applied every physics substep.
#[derive(Debug, Clone)]
pub struct Ground {
    setup: GroundSetup,
    /// This period's sums over substeps: vertical and fore-aft force (N).
    sum: [f64; 2],
    substeps: u32,
    deepest_m: f64,
    fastest_slip_m_s: f64,
    contacts: usize,
    last: GroundReaction,
}

impl Ground {
    pub(crate) fn new(setup: GroundSetup) -> Self {
        Self {
            setup,
            sum: [0.0; 2],
            substeps: 0,
            deepest_m: 0.0,
            fastest_slip_m_s: 0.0,
            contacts: 0,
            last: GroundReaction::default(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &TreadmillSettings {
        &self.setup.settings
    }

    /// Mass of everything the belt and harness carry: exoskeleton, leg and the patient's
    /// mass on the pelvis (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.setup.total_mass_kg
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

    /// The contact spheres.
    pub fn spheres(&self) -> &[FootSphere] {
        &self.setup.spheres
    }

    pub(crate) fn pelvis(&self) -> RigidBodyHandle {
        self.setup.pelvis
    }

    /// The harness's upward force (N) with the pelvis at height `z_m`.
    pub fn support_force_n(&self, z_m: f64) -> f64 {
        let weight =
            self.setup.settings.bws_fraction * self.setup.total_mass_kg * pma_model::GRAVITY_M_S2;
        match self.setup.settings.bws {
            BwsKind::ConstantForce => weight,
            BwsKind::Spring => (weight
                + self.setup.settings.bws_spring_n_per_m * (self.setup.standing_z_m - z_m))
                .max(0.0),
        }
    }

    /// Puts this substep's contact forces on the foot and the harness's on the pelvis
    /// (rapier keeps user forces until reset, so both are reset first).
    pub(crate) fn apply(&mut self, bodies: &mut RigidBodySet) {
        self.substeps += 1;
        if let Some(rb) = bodies.get_mut(self.setup.pelvis) {
            rb.reset_forces(false);
            let up = self.support_force_n(f64::from(rb.translation().z));
            rb.add_force(Vector::new(0.0, 0.0, up as Real), true);
        }
        let Some(rb) = bodies.get_mut(self.setup.foot) else {
            return;
        };
        rb.reset_forces(false);
        let pose = *rb.position();
        self.contacts = 0;
        for s in &self.setup.spheres {
            let c = pose.transform_point(vector(s.center_m));
            let contact_point = c - Vector::new(0.0, 0.0, s.radius_m as Real);
            let v = rb.velocity_at_point(contact_point);
            let Some(contact) = sphere_contact(
                &self.setup.settings.contact,
                s.radius_m,
                [c.x, c.y, c.z].map(f64::from),
                [v.x, v.y, v.z].map(f64::from),
                self.setup.settings.speed_m_per_s,
            ) else {
                continue;
            };
            let f = contact.force_n;
            rb.add_force_at_point(vector(f), vector(contact.point_m), true);
            self.sum[0] += f[2];
            self.sum[1] += f[0];
            self.deepest_m = self.deepest_m.max(contact.depth_m);
            if f[2] > 0.0 {
                self.fastest_slip_m_s = self.fastest_slip_m_s.max(contact.slip_m_s);
            }
            self.contacts += 1;
        }
    }

    /// Closes a period: its averages become [`Self::reaction`].
    pub(crate) fn end_period(&mut self) {
        let n = f64::from(self.substeps.max(1));
        self.last = GroundReaction {
            vertical_n: self.sum[0] / n,
            fore_aft_n: self.sum[1] / n,
            penetration_m: self.deepest_m,
            slip_m_s: self.fastest_slip_m_s,
            contacts: self.contacts,
        };
        self.sum = [0.0; 2];
        self.substeps = 0;
        self.deepest_m = 0.0;
        self.fastest_slip_m_s = 0.0;
    }

    /// The last period's ground reaction.
    pub fn reaction(&self) -> GroundReaction {
        self.last
    }
}

fn vector(v: [f64; 3]) -> Vector {
    Vector::new(v[0] as Real, v[1] as Real, v[2] as Real)
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
        // A foot at rest on a belt moving backwards slips forwards relative to it: the belt
        // drags it backwards.
        let c = sphere_contact(&p, 0.03, [0.0, 0.0, 0.02], [0.0; 3], 1.0).unwrap();
        let f = c.force_n;
        assert!(f[0] < 0.0 && (c.slip_m_s - 1.0).abs() < 1e-12, "{c:?}");
        assert!((-f[0] - f[2] * (0.8 + 0.5)).abs() < 1e-9, "{c:?}");
        // Moving with the belt: no friction.
        let c = sphere_contact(&p, 0.03, [0.0, 0.0, 0.02], [-1.0, 0.0, 0.0], 1.0).unwrap();
        assert_eq!(c.force_n[0], 0.0);
        assert!(sphere_contact(&p, 0.03, [0.0, 0.0, 0.031], [0.0; 3], 1.0).is_none());
    }

    #[test]
    fn bad_treadmill_input_names_the_field() {
        let ok = TreadmillSettings {
            speed_m_per_s: 0.6,
            bws_fraction: 0.3,
            body_mass_kg: 75.0,
            bws: BwsKind::ConstantForce,
            bws_spring_n_per_m: 0.0,
            contact: ContactParams::default(),
        };
        ok.validate().unwrap();
        for (bad, field) in [
            (
                TreadmillSettings {
                    speed_m_per_s: -0.5,
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
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains(field) && !e.contains('\n'), "{e}");
        }
    }
}
