use crate::base::{LegError, PerLeg};
use pma_model::error::within;
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
    /// Viscous friction `mu_v` (s/m) while sliding. Default 0.5 (Falisse et al. 2019).
    pub viscous_friction_s_per_m: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m2: 2.0e6,
            dissipation_s_per_m: 1.0,
            friction: 0.8,
            viscous_friction_s_per_m: 0.5,
        }
    }
}

impl ContactParams {
    pub(crate) fn validate(&self) -> Result<(), LegError> {
        within(
            "treadmill.contact.stiffness_n_per_m2",
            self.stiffness_n_per_m2,
            1e4,
            1e9,
            "must be 1e4 to 1e9 N/m^2 (from a soft pad to a hard sole; gait models use 1e6-2e6)",
        )?;
        within(
            "treadmill.contact.dissipation_s_per_m",
            self.dissipation_s_per_m,
            0.0,
            10.0,
            "must be 0 to 10 s/m (Hunt-Crossley; gait models use 1-2)",
        )?;
        within(
            "treadmill.contact.friction",
            self.friction,
            0.0,
            2.0,
            "must be 0 to 2 (shoe on belt: models use 0.7-0.9)",
        )?;
        within(
            "treadmill.contact.viscous_friction_s_per_m",
            self.viscous_friction_s_per_m,
            0.0,
            10.0,
            "must be 0 to 10 s/m (gait models use 0.5)",
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
        self.damped(
            self.hertz_coefficient(radius_m) * depth_m.powf(1.5),
            depth_rate_m_s,
        )
    }

    /// Hunt-Crossley's normal force from its elastic part `K d^{3/2}` (N), never pulling.
    fn damped(&self, elastic_n: f64, depth_rate_m_s: f64) -> f64 {
        (elastic_n * (1.0 + 1.5 * self.dissipation_s_per_m * depth_rate_m_s)).max(0.0)
    }

    /// Largest friction (N) under `normal_n` at a slip of `slip_m_s`: a sliding sphere's.
    pub fn friction_limit(&self, normal_n: f64, slip_m_s: f64) -> f64 {
        normal_n * (self.friction + self.viscous_friction_s_per_m * slip_m_s.abs())
    }

    /// Tangential stiffness (N/m) of a sphere of `radius_m` at penetration `depth_m`:
    /// Mindlin's `2 (1 - nu) / (2 - nu)` of the normal stiffness `3/2 K d^{1/2}`, `nu = 0.5`.
    pub fn tangential_stiffness(&self, radius_m: f64, depth_m: f64) -> f64 {
        mindlin(self.hertz_coefficient(radius_m), depth_m)
    }
}

/// Mindlin's tangential stiffness (N/m) from Hertz's `K` at penetration `depth_m`.
fn mindlin(hertz: f64, depth_m: f64) -> f64 {
    hertz * depth_m.max(0.0).sqrt()
}

/// One contact sphere on a foot, in the foot's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootSphere {
    /// Centre in the foot link's frame (m).
    pub center_m: [f64; 3],
    /// Radius (m).
    pub radius_m: f64,
}

/// What the belt did to one foot during one period (averaged over its substeps).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FootReaction {
    /// Vertical ground reaction force (N).
    pub vertical_n: f64,
    /// Horizontal (fore-aft) ground reaction force (N, forward positive).
    pub fore_aft_n: f64,
    /// Deepest penetration of a sphere into the belt (m; 0 out of contact).
    pub penetration_m: f64,
    /// Largest slip speed of a loaded sphere against the belt (m/s).
    pub slip_m_s: f64,
    /// The foot's fore-aft speed against the belt where it touches (m/s, forward
    /// positive): its loaded spheres' material contact points, weighted by their normal
    /// forces over the period; 0 out of contact.
    pub fore_aft_slip_m_s: f64,
    /// Spheres in contact at the end of the period.
    pub contacts: usize,
}

/// What the belt, the harness and a virtual other leg did during one period (averaged
/// over its substeps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundReaction {
    /// Each simulated foot's.
    pub feet: PerLeg<FootReaction>,
    /// Vertical force of the virtual other leg on the pelvis (N; 0 without one).
    pub contralateral_n: f64,
    /// The harness's upward force on the pelvis (N).
    pub support_n: f64,
    /// The harness's fore-aft force on the pelvis (N, forward positive).
    pub harness_fore_aft_n: f64,
    /// The belt's speed (m/s): a self-paced belt's changes.
    pub belt_speed_m_s: f64,
}

impl Default for GroundReaction {
    fn default() -> Self {
        Self {
            feet: PerLeg::one(FootReaction::default()),
            contralateral_n: 0.0,
            support_n: 0.0,
            harness_fore_aft_n: 0.0,
            belt_speed_m_s: 0.0,
        }
    }
}

impl GroundReaction {
    /// Vertical force the belt carries: every foot's and the virtual other leg's (N).
    pub fn belt_load_n(&self) -> f64 {
        self.feet.iter().map(|f| f.vertical_n).sum::<f64>() + self.contralateral_n
    }
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

/// One sphere's contact over a substep of `h_s`, from the sphere centre `c` (m) and the
/// velocity `v` (m/s) of the foot's material point at the contact: the belt is the plane
/// `z = 0` moving at `-belt_speed_m_s` along X. `stick_m` is how far the belt has sheared
/// the sphere while it sticks (m, X and Y; updated, zero out of contact). `None` out of
/// contact.
pub fn sphere_contact(
    params: &ContactParams,
    radius_m: f64,
    c: [f64; 3],
    v: [f64; 3],
    belt_speed_m_s: f64,
    (stick_m, h_s): (&mut [f64; 2], f64),
) -> Option<SphereContact> {
    let depth = radius_m - c[2];
    if depth <= 0.0 {
        *stick_m = [0.0; 2];
        return None;
    }
    let point = [c[0], c[1], c[2] - radius_m];
    // `K` and `d^{3/2}` once: they were worked out three and two times over (issue 50);
    // the same values bit for bit.
    let hertz = params.hertz_coefficient(radius_m);
    let depth_3_2 = depth.powf(1.5);
    let normal = params.damped(hertz * depth_3_2, -v[2]);
    let slip = [v[0] + belt_speed_m_s, v[1]];
    let speed = slip[0].hypot(slip[1]);
    // Sticking: a spring sheared by the slip, damped as Hunt-Crossley damps the normal
    // direction (3/2 c times the elastic force per unit of rate); the spring is Mindlin's
    // (`ContactParams::tangential_stiffness`).
    let k_t = mindlin(hertz, depth);
    let c_t = 1.5 * params.dissipation_s_per_m * hertz * depth_3_2;
    let sheared = [stick_m[0] + slip[0] * h_s, stick_m[1] + slip[1] * h_s];
    let mut f = [
        -k_t * sheared[0] - c_t * slip[0],
        -k_t * sheared[1] - c_t * slip[1],
    ];
    let limit = params.friction_limit(normal, speed);
    let magnitude = f[0].hypot(f[1]);
    if magnitude > limit {
        // Sliding: the limit against the shear, and the spring no further than it holds.
        f = [f[0] * limit / magnitude, f[1] * limit / magnitude];
        *stick_m = if k_t > 0.0 {
            [-f[0] / k_t, -f[1] / k_t]
        } else {
            [0.0; 2]
        };
    } else {
        *stick_m = sheared;
    }
    Some(SphereContact {
        force_n: [f[0], f[1], normal],
        point_m: point,
        depth_m: depth,
        slip_m_s: speed,
    })
}
