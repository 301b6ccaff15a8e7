//! Impedance through the muscles' own controllers (admittance control): each joint's
//! reference is displaced by what the patient pushes against the device, measured at the
//! cuffs, over the joint's set stiffness, and the muscles' controllers (APRC-NDO or any
//! other) track the displaced reference as they do in position mode, their pairs'
//! co-contraction regulated as there.
//!
//! Co-contraction ([`crate::control::ImpedanceLaw`]) makes the pairs themselves the spring, with no
//! sensor but the encoders; here the spring is the law's and the muscles are stiff
//! position servos inside it, so the stiffness is not bounded by what the pairs reach,
//! and the per-muscle controllers' robustness (the observers' estimate of what the model
//! misses) works inside the impedance. The price is a torque sensor at the cuffs and a
//! loop around the patient.
//!
//! Per joint, with `e = q_c - q_ref` the displacement of the tracked reference:
//!
//! ```text
//! K e + D de/dt = u_f,    u = tau_plan - tau_cuff
//! ```
//!
//! `tau_cuff` is the torque the device puts into the limb (flexion positive, the cuff
//! sensor's reading) and `tau_plan` what the device is meant to put there: the carried
//! limb's inverse dynamics along the reference (at the measured pose, as impedance mode
//! takes gravity) and a stance leg's share of the weight when the device carries the leg
//! (`compensation = "leg"`), nothing when the patient carries their own
//! (`compensation = "device"`). So `u` is what the patient adds: a push that flexes the
//! knee moves its reference towards flexion by `u / K`. `u_f` is `u` through a first-order
//! filter (`cuff_filter_s`): the cuff reading is a period old, and without the filter a
//! stiff servo and that delay close an algebraic loop. The step is exact for `u_f` held
//! over the period, so any `K / D` is stable.
use crate::base::LegError;
use crate::body::LegInertia;
use crate::control::{Compensation, ImpedanceSettings, MusclePair};
use crate::gait::{GaitSample, JointSample};

/// Largest displacement of a joint's tracked reference from the gait's (rad, 30 deg): a
/// bound on what a stuck or saturated cuff reading can do to the leg; the URDF's limits
/// bound it again.
pub const DISPLACEMENT_MAX_RAD: f64 = std::f64::consts::FRAC_PI_6;

/// How far inside a URDF limit a displaced reference stays (rad, 2 deg): the servos
/// overshoot a reference by tenths of a degree, and a stop's impact is no compliance.
const LIMIT_MARGIN_RAD: f64 = 0.034_906_585_039_886_59;

/// One leg's admittance: the displaced reference its muscle controllers track.
#[derive(Debug, Clone)]
pub struct Admittance {
    stiffness_nm_per_rad: [f64; 2],
    damping_nm_s_per_rad: [f64; 2],
    filter_s: f64,
    /// The limb whose inverse dynamics the device is to carry (none: the patient carries
    /// it).
    carried_limb: Option<LegInertia>,
    limits_rad: [[f64; 2]; 2],
    filtered_nm: [f64; 2],
    displacement_rad: [f64; 2],
}

impl Admittance {
    /// The admittance of `settings`' set points for a leg of `inertia` whose joints move
    /// within `limits_rad` (`[lo, hi]` per joint). A joint without a stiffness set point
    /// takes co-contraction's default (the middle of what `pairs` reach at rest), so that
    /// both inner loops run the same spring unless told otherwise.
    pub fn new(
        settings: &ImpedanceSettings,
        compensation: Compensation,
        pairs: &[MusclePair; 2],
        inertia: &LegInertia,
        limits_rad: [[f64; 2]; 2],
    ) -> Result<Self, LegError> {
        settings.validate()?;
        let stiffness = |j: usize| -> Result<f64, LegError> {
            match settings.joint(j).stiffness_nm_per_rad {
                Some(k) => Ok(k),
                None => pairs[j].resolve(settings.joint(j)),
            }
        };
        let stiffness_nm_per_rad = [stiffness(0)?, stiffness(1)?];
        let inertia_kg_m2 = [inertia.hip_inertia(), inertia.knee_inertia()];
        Ok(Self::with(
            stiffness_nm_per_rad,
            [0, 1].map(|j| {
                let critical = 2.0 * (stiffness_nm_per_rad[j] * inertia_kg_m2[j]).sqrt();
                settings.joint(j).damping_nm_s_per_rad.max(critical)
            }),
            settings.cuff_filter_s,
            (compensation == Compensation::Leg).then(|| inertia.limb()),
            limits_rad,
        ))
    }

    fn with(
        stiffness_nm_per_rad: [f64; 2],
        damping_nm_s_per_rad: [f64; 2],
        filter_s: f64,
        carried_limb: Option<LegInertia>,
        limits_rad: [[f64; 2]; 2],
    ) -> Self {
        Self {
            stiffness_nm_per_rad,
            damping_nm_s_per_rad,
            filter_s,
            carried_limb,
            limits_rad,
            filtered_nm: [0.0; 2],
            displacement_rad: [0.0; 2],
        }
    }

    /// Each joint's damping (N m s/rad): the set point's, or critical damping of the
    /// leg's inertia about the joint if that is more.
    pub fn damping_nm_s_per_rad(&self) -> [f64; 2] {
        self.damping_nm_s_per_rad
    }

    /// Each joint's stiffness (N m/rad), defaults resolved.
    pub fn stiffness_nm_per_rad(&self) -> [f64; 2] {
        self.stiffness_nm_per_rad
    }

    /// Back on the gait's reference, nothing pushed.
    pub fn reset(&mut self) {
        self.filtered_nm = [0.0; 2];
        self.displacement_rad = [0.0; 2];
    }

    /// What the device is meant to put into the limb at measured angles `q` along `g`,
    /// with `load_nm` a stance leg's share of the weight (N m, per joint).
    fn plan_nm(&self, g: &GaitSample, q: [f64; 2], load_nm: [f64; 2]) -> [f64; 2] {
        let Some(limb) = &self.carried_limb else {
            return [0.0; 2];
        };
        let qd = [g.hip.velocity_rad_s, g.knee.velocity_rad_s];
        let qdd = [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2];
        let id = limb.inverse_dynamics(q, qd, qdd);
        [id[0] + load_nm[0], id[1] + load_nm[1]]
    }

    /// Takes in the cuff reading `cuff_nm` at measured angles `q` and returns `g` displaced:
    /// the reference the muscle controllers track this period.
    pub fn update(
        &mut self,
        g: &GaitSample,
        q: [f64; 2],
        cuff_nm: [f64; 2],
        load_nm: [f64; 2],
        dt_s: f64,
    ) -> GaitSample {
        let plan = self.plan_nm(g, q, load_nm);
        let a = 1.0 - (-dt_s / self.filter_s.max(f64::MIN_POSITIVE)).exp();
        let mut out = *g;
        for j in 0..2 {
            let before = self.filtered_nm[j];
            self.filtered_nm[j] += a * (plan[j] - cuff_nm[j] - before);
            let f = self.filtered_nm[j];
            let (k, d) = (self.stiffness_nm_per_rad[j], self.damping_nm_s_per_rad[j]);
            let (e, rate) = if d > 0.0 {
                let settled = f / k;
                let e = settled + (self.displacement_rad[j] - settled) * (-dt_s * k / d).exp();
                (e, (f - k * e) / d)
            } else {
                (f / k, (f - before) / (k * dt_s))
            };
            let joint = if j == 0 { &mut out.hip } else { &mut out.knee };
            let reference = joint.angle_rad;
            let [lo, hi] = self.limits_rad[j];
            let wanted = reference + e.clamp(-DISPLACEMENT_MAX_RAD, DISPLACEMENT_MAX_RAD);
            let angle = wanted.clamp(
                (lo + LIMIT_MARGIN_RAD).min(reference),
                (hi - LIMIT_MARGIN_RAD).max(reference),
            );
            let rate = if angle == reference + e { rate } else { 0.0 };
            self.displacement_rad[j] = angle - reference;
            *joint = JointSample {
                angle_rad: angle,
                velocity_rad_s: joint.velocity_rad_s + rate,
                ..*joint
            };
        }
        out
    }

    /// The present displacement of each joint's tracked reference (rad).
    pub fn displacement_rad(&self) -> [f64; 2] {
        self.displacement_rad
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WIDE: [[f64; 2]; 2] = [[-3.0, 3.0], [-3.0, 3.0]];

    /// The hip's displacement after `t_s` of a constant push `push_nm` stepped at `dt_s`.
    fn pushed(push_nm: f64, t_s: f64, dt_s: f64, a: &mut Admittance) -> f64 {
        a.reset();
        let g = GaitSample::default();
        let steps = (t_s / dt_s).round() as usize;
        for _ in 0..steps {
            a.update(&g, [0.0; 2], [-push_nm, 0.0], [0.0; 2], dt_s);
        }
        a.displacement_rad()[0]
    }

    /// A push held from rest: two first-order lags in series, the filter's `tau_f` and the
    /// spring's `D / K`: `e(t) = u/K (1 - (tau_f e^(-t/tau_f) - tau_s e^(-t/tau_s)) /
    /// (tau_f - tau_s))`. The step's error against it falls with the step (first order: the
    /// spring takes the filter's output held over a step), and the push settles at `u / K`.
    #[test]
    fn a_held_push_follows_two_lags_and_settles_at_push_over_stiffness() {
        let (k, d, tau_f, u) = (100.0, 5.0, 0.01, 5.0);
        let tau_s = d / k;
        let exact = |t: f64| {
            u / k
                * (1.0
                    - (tau_f * (-t / tau_f).exp() - tau_s * (-t / tau_s).exp()) / (tau_f - tau_s))
        };
        let mut a = Admittance::with([k, k], [d, d], tau_f, None, WIDE);
        let t = 0.05;
        let errors: Vec<f64> = [1e-3, 1e-4, 1e-5]
            .iter()
            .map(|dt| (pushed(u, t, *dt, &mut a) - exact(t)).abs())
            .collect();
        assert!(errors[0] < 0.02 * u / k, "{errors:?}");
        assert!(
            errors[1] < 0.2 * errors[0] && errors[2] < 0.2 * errors[1],
            "{errors:?}"
        );
        let settled = pushed(u, 2.0, 1e-3, &mut a);
        assert!((settled - u / k).abs() < 1e-9, "{settled}");
    }

    /// A stuck or saturated cuff reading moves the reference at most 30 deg, and never
    /// closer than 2 deg to a URDF limit.
    #[test]
    fn a_huge_push_is_bounded_by_the_displacement_limit_and_the_joint_limits() {
        let mut a = Admittance::with([10.0; 2], [1.0; 2], 0.01, None, WIDE);
        let e = pushed(1e4, 1.0, 1e-3, &mut a);
        assert!((e - DISPLACEMENT_MAX_RAD).abs() < 1e-12, "{e}");
        let limits = [[-0.2, 0.3], [-0.2, 0.3]];
        let mut a = Admittance::with([10.0; 2], [1.0; 2], 0.01, None, limits);
        let e = pushed(1e4, 1.0, 1e-3, &mut a);
        assert!((e - (0.3 - LIMIT_MARGIN_RAD)).abs() < 1e-12, "{e}");
    }
}
