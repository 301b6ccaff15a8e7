//! What the device does to the patient, and what the patient does: the figures of
//! patient-cooperative control (issue 28).
//!
//! The limb and the exoskeleton's frames move as one rigid chain here (cuffs of infinite
//! stiffness), so the torque the device puts into the limb through the cuffs is, joint by
//! joint, the muscles' torque less what moves the frames themselves: `tau_int = tau_muscles -
//! M_f(q) qdd - C_f(q, qd) qd - G_f(q)`, the frames' inverse dynamics in joint space (the
//! URDFs' stated design: aluminium bars, thigh 2.0 kg and shank 1.5 kg; [`crate::body::LegInertia::frames`]).
//! The acceleration is the true velocity's change over the control period; the plant
//! reports the torque every period ([`crate::plant::LegState::interaction_nm`]). Compliant
//! cuffs (two bodies per segment) are not modelled, and a URDF joint stop's torque is not
//! separated from the device's: a run against a stop shows its impacts in the peaks.
use crate::base::JOINT_NAMES;
use crate::control::Tunnel;
use crate::gait::GaitReference;
use crate::metrics::{LegPeriod, LegRecorder};
use serde::Serialize;
use std::collections::BTreeMap;

/// Half-width of the tunnel every run's share inside is measured against when the scenario
/// runs no path mode (deg): `[control.path] width_deg`'s default.
pub const TUNNEL_WIDTH_DEG: f64 = 5.0;

/// One cuff's force over a run.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct CuffStats {
    /// RMS of its force on the limb (N; perpendicular to the segment).
    pub force_rms_n: f64,
    /// Its largest magnitude (N).
    pub force_peak_n: f64,
}

/// One joint's interaction and work.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct InteractionStats {
    /// RMS of the torque the device puts into the limb (N m).
    pub interaction_rms_nm: f64,
    /// Its largest magnitude (N m).
    pub interaction_peak_nm: f64,
    /// Work of the patient's own torques on the joint (J).
    pub patient_work_j: f64,
    /// Work of the device's torque on the limb (J).
    pub device_work_j: f64,
}

/// One leg's cooperation figures, after the start-up ramp and a stride.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct CooperationReport {
    /// Per joint (`hip`, `knee`).
    pub joints: BTreeMap<String, InteractionStats>,
    /// Per cuff (`thigh`, `shank`): the forces that put those torques into the limb.
    pub cuffs: BTreeMap<String, CuffStats>,
    /// Strides of the leg's own kinematics measured (peaks of hip flexion).
    pub strides: usize,
    /// Their mean duration (s).
    pub stride_time_mean_s: f64,
    /// Coefficient of variation of their durations.
    pub stride_time_cv: f64,
    /// Standard deviation over strides of the peak hip flexion (deg).
    pub hip_peak_sd_deg: f64,
    /// Of the peak knee flexion (deg).
    pub knee_peak_sd_deg: f64,
    /// Share of the time the leg was within the tunnel around the reference's path.
    pub inside_tunnel_share: f64,
    /// That tunnel's half-width (deg).
    pub tunnel_width_deg: f64,
}

/// Running count, sum and sum of squares.
#[derive(Debug, Clone, Copy, Default)]
struct Moments(usize, f64, f64);

impl Moments {
    fn push(&mut self, x: f64) {
        self.0 += 1;
        self.1 += x;
        self.2 += x * x;
    }
    fn mean(&self) -> f64 {
        self.1 / self.0 as f64
    }
    fn sd(&self) -> f64 {
        if self.0 < 2 {
            return f64::NAN;
        }
        let n = self.0 as f64;
        ((self.2 - self.1 * self.1 / n) / (n - 1.0)).max(0.0).sqrt()
    }
}

/// Running sum of squares and largest magnitude of one signal.
#[derive(Debug, Clone, Copy, Default)]
struct Magnitude {
    sum_sq: f64,
    peak: f64,
}

impl Magnitude {
    fn push(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.peak = self.peak.max(x.abs());
    }
    /// RMS over `n` samples (NaN before the first).
    fn rms(&self, n: usize) -> f64 {
        if n > 0 {
            (self.sum_sq / n as f64).sqrt()
        } else {
            f64::NAN
        }
    }
}

/// `names` mapped to `value(index)`.
fn by_name<T>(names: &[&str], value: impl Fn(usize) -> T) -> BTreeMap<String, T> {
    names
        .iter()
        .enumerate()
        .map(|(i, name)| ((*name).to_owned(), value(i)))
        .collect()
}

/// Accumulates a leg's [`CooperationReport`] period by period (allocation-free).
#[derive(Debug, Clone)]
pub struct CooperationMetrics {
    from_s: f64,
    n: usize,
    /// The interaction torque at hip and knee (N m).
    interaction: [Magnitude; 2],
    /// The thigh and shank cuff forces (N).
    cuff: [Magnitude; 2],
    patient_work: [f64; 2],
    device_work: [f64; 2],
    tunnel: Tunnel,
    /// The tunnel's last nearest segment.
    tunnel_hint: usize,
    inside_s: f64,
    counted_s: f64,
    hip_mid_rad: f64,
    /// The peak of hip flexion being followed, while above the middle.
    rising: Option<f64>,
    /// The hip's previous reading (time, angle): the crossings are interpolated.
    previous_hip: Option<(f64, f64)>,
    /// When the hip last rose through the middle of its range: a stride starts there.
    last_crossing_s: Option<f64>,
    knee_max: f64,
    stride_s: Moments,
    hip_peak: Moments,
    knee_peak: Moments,
}

impl CooperationMetrics {
    /// Figures of a leg on `gait`, counted after its start-up and a stride, the tunnel
    /// `width_deg` wide.
    pub fn new(gait: &GaitReference, width_deg: f64) -> Self {
        let tunnel = Tunnel::new(gait, width_deg);
        let (lo, hi) = (0..100).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| {
            let t = gait.ramp_s() + gait.stride_period_s() * (1.0 + i as f64 / 100.0);
            let h = gait.sample(t).hip.angle_rad;
            (lo.min(h), hi.max(h))
        });
        Self {
            from_s: gait.ramp_s() + gait.stride_period_s(),
            n: 0,
            interaction: [Magnitude::default(); 2],
            cuff: [Magnitude::default(); 2],
            patient_work: [0.0; 2],
            device_work: [0.0; 2],
            tunnel,
            tunnel_hint: 0,
            inside_s: 0.0,
            counted_s: 0.0,
            hip_mid_rad: 0.5 * (lo + hi),
            rising: None,
            previous_hip: None,
            last_crossing_s: None,
            knee_max: f64::NEG_INFINITY,
            stride_s: Moments::default(),
            hip_peak: Moments::default(),
            knee_peak: Moments::default(),
        }
    }

    /// The figures so far.
    pub fn report(&self) -> CooperationReport {
        let joints = by_name(&JOINT_NAMES, |j| InteractionStats {
            interaction_rms_nm: self.interaction[j].rms(self.n),
            interaction_peak_nm: self.interaction[j].peak,
            patient_work_j: self.patient_work[j],
            device_work_j: self.device_work[j],
        });
        let cuffs = by_name(&["thigh", "shank"], |i| CuffStats {
            force_rms_n: self.cuff[i].rms(self.n),
            force_peak_n: self.cuff[i].peak,
        });
        CooperationReport {
            joints,
            cuffs,
            strides: self.stride_s.0,
            stride_time_mean_s: self.stride_s.mean(),
            stride_time_cv: self.stride_s.sd() / self.stride_s.mean(),
            hip_peak_sd_deg: self.hip_peak.sd().to_degrees(),
            knee_peak_sd_deg: self.knee_peak.sd().to_degrees(),
            inside_tunnel_share: self.inside_s / self.counted_s,
            tunnel_width_deg: self.tunnel.width_rad().to_degrees(),
        }
    }

    /// Follows the hip: a stride starts each time it rises through the middle of the
    /// reference's range (the time interpolated between readings); the peaks of hip and
    /// knee flexion are taken between two such crossings.
    fn follow_strides(&mut self, t_s: f64, q: [f64; 2]) {
        self.knee_max = self.knee_max.max(q[1]);
        let mid = self.hip_mid_rad;
        if q[0] > mid {
            self.rising = Some(self.rising.map_or(q[0], |p| p.max(q[0])));
        }
        let previous = self.previous_hip.replace((t_s, q[0]));
        let Some((t0, h0)) = previous else {
            return;
        };
        if !(h0 <= mid && q[0] > mid) {
            return;
        }
        let crossing = t0 + (t_s - t0) * (mid - h0) / (q[0] - h0);
        if let (Some(last), Some(peak)) = (self.last_crossing_s, self.rising) {
            self.stride_s.push(crossing - last);
            self.hip_peak.push(peak);
            self.knee_peak.push(self.knee_max);
        }
        self.last_crossing_s = Some(crossing);
        self.rising = Some(q[0]);
        self.knee_max = q[1];
    }
}

impl LegRecorder for CooperationMetrics {
    fn record(&mut self, p: &LegPeriod<'_>) {
        let s = p.state;
        if p.t_s < self.from_s || p.dt_s <= 0.0 {
            return;
        }
        let (q, qd) = (s.angle_rad, s.velocity_rad_s);
        let own = s.patient.total();
        self.n += 1;
        for j in 0..2 {
            let interaction = s.interaction_nm[j];
            self.interaction[j].push(interaction);
            self.patient_work[j] += own[j] * qd[j] * p.dt_s;
            self.device_work[j] += interaction * qd[j] * p.dt_s;
            self.cuff[j].push(s.cuff_force_n[j]);
        }
        self.counted_s += p.dt_s;
        let inside = self
            .tunnel
            .locate_near(q, &mut self.tunnel_hint)
            .distance_rad
            <= self.tunnel.width_rad();
        if inside {
            self.inside_s += p.dt_s;
        }
        self.follow_strides(p.t_s, q);
    }
}
