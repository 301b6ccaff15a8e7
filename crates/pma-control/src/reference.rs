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

/// A step from `initial_m` to `final_m` at `time_s` (derivatives zero: a true step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReference {
    /// Level before the step (m).
    pub initial_m: f64,
    /// Level after the step (m).
    pub final_m: f64,
    /// Step time (s).
    pub time_s: f64,
}

impl Reference for StepReference {
    fn sample(&self, t: f64) -> RefSample {
        RefSample {
            position_m: if t >= self.time_s {
                self.final_m
            } else {
                self.initial_m
            },
            ..RefSample::default()
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
}
