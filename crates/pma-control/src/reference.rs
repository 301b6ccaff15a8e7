use crate::RefSample;
use std::f64::consts::TAU;

/// A desired contraction trajectory with analytic first and second derivatives.
pub trait Reference: Send + Sync {
    /// Sample at time `t_s`.
    fn sample(&self, t_s: f64) -> RefSample;
}

/// `x_d = A sin(2 pi f t) + B`, eq. (50).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineReference {
    /// Amplitude `A` (m).
    pub amplitude_m: f64,
    /// Frequency `f` (Hz).
    pub frequency_hz: f64,
    /// Offset `B` (m).
    pub offset_m: f64,
}

impl SineReference {
    /// The paper's sine: `A = 15 mm, f = 0.25 Hz, B = 15 mm`.
    pub const fn paper() -> Self {
        Self {
            amplitude_m: 0.015,
            frequency_hz: 0.25,
            offset_m: 0.015,
        }
    }
}

impl Reference for SineReference {
    fn sample(&self, t: f64) -> RefSample {
        let w = TAU * self.frequency_hz;
        let (s, c) = (w * t).sin_cos();
        RefSample {
            position_m: self.amplitude_m * s + self.offset_m,
            velocity_m_s: self.amplitude_m * w * c,
            acceleration_m_s2: -self.amplitude_m * w * w * s,
        }
    }
}

/// Linear chirp: frequency from `f0` to `f1` over `sweep_s`, then held at `f1` with a
/// continuous phase; `x_d = A sin(phi(t)) + B`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChirpReference {
    /// Amplitude (m).
    pub amplitude_m: f64,
    /// Offset (m).
    pub offset_m: f64,
    /// Start frequency (Hz).
    pub f0_hz: f64,
    /// End frequency (Hz).
    pub f1_hz: f64,
    /// Sweep duration (s).
    pub sweep_s: f64,
}

impl ChirpReference {
    /// The paper's chirp: 0.1 to 0.5 Hz in 20 s, `A = B = 15 mm`.
    pub const fn paper() -> Self {
        Self {
            amplitude_m: 0.015,
            offset_m: 0.015,
            f0_hz: 0.1,
            f1_hz: 0.5,
            sweep_s: 20.0,
        }
    }

    /// Phase (rad), its rate (rad/s) and its acceleration (rad/s^2).
    fn phase(&self, t: f64) -> (f64, f64, f64) {
        let rate = (self.f1_hz - self.f0_hz) / self.sweep_s;
        if t <= self.sweep_s {
            (
                TAU * (self.f0_hz * t + 0.5 * rate * t * t),
                TAU * (self.f0_hz + rate * t),
                TAU * rate,
            )
        } else {
            let ts = self.sweep_s;
            let at_end = TAU * (self.f0_hz * ts + 0.5 * rate * ts * ts);
            (at_end + TAU * self.f1_hz * (t - ts), TAU * self.f1_hz, 0.0)
        }
    }
}

impl Reference for ChirpReference {
    fn sample(&self, t: f64) -> RefSample {
        let (phi, dphi, ddphi) = self.phase(t);
        let (s, c) = phi.sin_cos();
        let a = self.amplitude_m;
        RefSample {
            position_m: a * s + self.offset_m,
            velocity_m_s: a * c * dphi,
            acceleration_m_s2: -a * s * dphi * dphi + a * c * ddphi,
        }
    }
}

/// A jump: `low_m` until `up_s`, `high_m` until `down_s`, `low_m` again after (derivatives
/// zero: true steps, the shock of a reference that changes at once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpReference {
    /// Level before and after (m).
    pub low_m: f64,
    /// Level between the jumps (m).
    pub high_m: f64,
    /// Jump up (s).
    pub up_s: f64,
    /// Jump down (s); infinite for a single step.
    pub down_s: f64,
}

impl Reference for JumpReference {
    fn sample(&self, t: f64) -> RefSample {
        let high = (self.up_s..self.down_s).contains(&t);
        RefSample {
            position_m: if high { self.high_m } else { self.low_m },
            ..RefSample::default()
        }
    }
}

/// The quintic blend `s = 10 u^3 - 15 u^4 + 6 u^5` at `u` in `[0, 1]` of a blend lasting
/// `duration_s`, with its first two time derivatives: from rest to rest, no jump in
/// acceleration. Every smooth start of the workspace (the rig's reference, the gait from
/// standing) uses this one.
pub fn quintic_blend(u: f64, duration_s: f64) -> (f64, f64, f64) {
    let s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
    let ds = 30.0 * u * u * (1.0 - u) * (1.0 - u) / duration_s;
    let dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (duration_s * duration_s);
    (s, ds, dds)
}

/// A base trajectory (of the rig's reference, say).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Trajectory {
    /// Sine.
    Sine(SineReference),
    /// Chirp.
    Chirp(ChirpReference),
    /// Constant.
    Hold(f64),
}

impl Trajectory {
    /// The trajectory at `t`.
    pub fn sample(&self, t: f64) -> RefSample {
        match self {
            Trajectory::Sine(s) => s.sample(t),
            Trajectory::Chirp(c) => c.sample(t),
            Trajectory::Hold(x) => RefSample {
                position_m: *x,
                ..RefSample::default()
            },
        }
    }
}

/// A trajectory entered from the resting position `x0` with the [`quintic_blend`]
/// `s(t)`: `x_d = x0 + s (x(t) - x0)`, with analytic derivatives. A rig starts wherever its load rests; jumping to the
/// trajectory's first point would slam the muscle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothStart {
    /// The trajectory.
    pub trajectory: Trajectory,
    /// Where the blend starts (m).
    pub start_m: f64,
    /// Blend duration (s); 0 starts on the trajectory at once.
    pub ramp_s: f64,
}

impl Reference for SmoothStart {
    fn sample(&self, t: f64) -> RefSample {
        let r = self.trajectory.sample(t);
        if self.ramp_s <= 0.0 || t >= self.ramp_s {
            return r;
        }
        let (s, ds, dds) = quintic_blend((t / self.ramp_s).max(0.0), self.ramp_s);
        let gap = r.position_m - self.start_m;
        RefSample {
            position_m: self.start_m + s * gap,
            velocity_m_s: ds * gap + s * r.velocity_m_s,
            acceleration_m_s2: dds * gap + 2.0 * ds * r.velocity_m_s + s * r.acceleration_m_s2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences of position and velocity must match the analytic derivatives.
    fn check_derivatives(r: &dyn Reference, t_end: f64) {
        let h = 1e-5;
        let mut t = 0.05;
        while t < t_end {
            let (a, b, c) = (r.sample(t - h), r.sample(t), r.sample(t + h));
            let v_num = (c.position_m - a.position_m) / (2.0 * h);
            let a_num = (c.velocity_m_s - a.velocity_m_s) / (2.0 * h);
            assert!(
                (v_num - b.velocity_m_s).abs() < 1e-8,
                "t={t}: v {v_num} vs {}",
                b.velocity_m_s
            );
            assert!(
                (a_num - b.acceleration_m_s2).abs() < 1e-6,
                "t={t}: a {a_num} vs {}",
                b.acceleration_m_s2
            );
            t += 0.37;
        }
    }

    #[test]
    fn sine_derivatives_are_consistent() {
        check_derivatives(&SineReference::paper(), 20.0);
    }

    #[test]
    fn chirp_derivatives_are_consistent_through_and_after_the_sweep() {
        check_derivatives(&ChirpReference::paper(), 30.0);
    }

    #[test]
    fn chirp_instantaneous_frequency_goes_from_f0_to_f1() {
        let c = ChirpReference::paper();
        assert!((c.phase(0.0).1 / TAU - 0.1).abs() < 1e-12);
        assert!((c.phase(20.0).1 / TAU - 0.5).abs() < 1e-12);
        assert!((c.phase(10.0).1 / TAU - 0.3).abs() < 1e-12);
    }

    #[test]
    fn paper_references_span_0_to_30_mm() {
        let s = SineReference::paper();
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for k in 0..4000 {
            let x = s.sample(k as f64 * 1e-3).position_m;
            lo = lo.min(x);
            hi = hi.max(x);
        }
        assert!(lo.abs() < 1e-9 && (hi - 0.030).abs() < 1e-9);
    }

    #[test]
    fn smooth_start_derivatives_match_finite_differences() {
        let r = SmoothStart {
            trajectory: Trajectory::Sine(SineReference::paper()),
            start_m: -0.01,
            ramp_s: 2.0,
        };
        assert_eq!(r.sample(0.0).position_m, -0.01);
        assert_eq!(r.sample(0.0).velocity_m_s, 0.0);
        assert_eq!(r.sample(3.0), SineReference::paper().sample(3.0));
        let h = 1e-5;
        for &t in &[0.3, 1.0, 1.7, 1.99] {
            let (a, b, c) = (r.sample(t - h), r.sample(t), r.sample(t + h));
            let v = (c.position_m - a.position_m) / (2.0 * h);
            let acc = (c.velocity_m_s - a.velocity_m_s) / (2.0 * h);
            assert!(
                (v - b.velocity_m_s).abs() < 1e-6,
                "t {t}: {v} vs {}",
                b.velocity_m_s
            );
            assert!(
                (acc - b.acceleration_m_s2).abs() < 1e-5,
                "t {t}: {acc} vs {}",
                b.acceleration_m_s2
            );
        }
    }
}
