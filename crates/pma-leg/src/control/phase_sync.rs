//! The trainer's gait clock, following a patient who walks on their own timing.
//!
//! A compliant mode lets the patient move the leg, but the reference still runs on the
//! device's clock. A patient whose stride time varies (healthy adults' by about 2 %,
//! Hausdorff et al. 1996) drifts from it as a random walk, and once their phase is a tenth
//! of a stride away, their joint moments and the device's stance plan act at different
//! phases: at 300 N m/rad the walking patient of `own_torque = "walking"` loses the
//! stance after 25-40 s (docs/cooperative.md). Adapting the reference to the patient
//! from the interaction has precedent on the Lokomat (Jezernik, Colombo and Morari 2004,
//! IEEE Trans. Robotics and Automation 20(3) 574-582, adapted the whole gait pattern and
//! lowered the interaction torques by over 40 % in simulation); here only the timing is
//! adapted, by the simplest loop that does it: a phase-locked loop on the legs' measured
//! lead.
//!
//! A leg ahead of its reference by `d` seconds deviates by `e = q - q_ref ≈ d q̇_ref`, so
//! the least-squares lead over a window of about a stride is
//! `d = Σ e·q̇_ref / Σ q̇_ref·q̇_ref` (both joints of every leg, exponentially weighted), and
//! the clock runs at `1 + gain d + z`, within [`RATE_RANGE`]. The spring lets the leg lead
//! by only part `α` of the patient's lead (their own stiffness over theirs and the
//! device's), so the loop's gain on the patient's phase is `gain` times that part.
//!
//! `z` is the loop's integral, `z' = integral · d` (the phase-locked loop of type 2): a
//! patient whose cadence differs from the reference's by a constant share needs the
//! proportional loop to lag them by that share over `α gain`; at a stiff spring (small
//! `α`) that is a large part of a stride, where the legs' lead no longer grows with the
//! lag, the loop slips, and the clock takes only part of the difference (measured:
//! docs/cooperative.md). The integral takes all of it and leaves no lag. With the lead's window `W` as a
//! first-order lag, the loop's characteristic polynomial is
//! `W s³ + s² + α gain s + α integral`, stable (Routh-Hurwitz) for
//! `integral < gain / W`, whatever `α`: [`PhaseSync::new`] refuses more.
use crate::base::LegError;
use pma_model::error::{check, within};

/// The clock's rate stays within these (a stride at most 25 % shorter or longer than the
/// reference's, beyond any patient's stride-to-stride variation).
pub const RATE_RANGE: [f64; 2] = [0.8, 1.25];

/// Largest gain (1/s): at 20/s a 10 ms lead already moves the clock by 20 %.
pub const GAIN_MAX_PER_S: f64 = 20.0;

/// The trainer's gait clock and its estimate of the legs' lead.
#[derive(Debug, Clone)]
pub struct PhaseSync {
    gain_per_s: f64,
    integral_per_s2: f64,
    window_s: f64,
    /// The reference's own `Σ q̇_ref·q̇_ref`, averaged over a stride: where the weighted
    /// sum starts, so that the first periods' lead is not a ratio of two small numbers.
    mean_power: f64,
    clock_s: f64,
    rate: f64,
    /// The integral's share of the rate, `z` (within the rate range less 1).
    integral: f64,
    last_t_s: f64,
    /// Exponentially weighted `Σ e·q̇_ref` (rad²/s) and `Σ q̇_ref·q̇_ref` (rad²/s²).
    cross: f64,
    power: f64,
    /// Lowest and highest rate so far.
    rate_range: [f64; 2],
}

/// What the gait's clock did over a run (the JSON's `phase_sync`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhaseSyncReport {
    /// The loop's gain (1/s).
    pub gain_per_s: f64,
    /// The loop's integral gain (1/s²).
    pub integral_per_s2: f64,
    /// The integral's share of the rate at the end: the patient's cadence over the
    /// reference's, less 1, once the loop has locked.
    pub integral_rate: f64,
    /// Lowest and highest rate of the clock (gait seconds per second).
    pub rate_min: f64,
    /// See `rate_min`.
    pub rate_max: f64,
    /// The gait's time less the run's at the end (s): positive, the reference ran ahead.
    pub clock_offset_s: f64,
    /// The legs' estimated lead over the reference at the end (s).
    pub lead_s: f64,
}

impl PhaseSync {
    /// A clock adapting at `gain_per_s` and `integral_per_s2` to the lead averaged over
    /// `window_s` (s), for a reference whose `Σ q̇_ref·q̇_ref` over the legs' joints
    /// averages `mean_power` (rad²/s²) over a stride.
    pub fn new(
        gain_per_s: f64,
        integral_per_s2: f64,
        window_s: f64,
        mean_power: f64,
    ) -> Result<Self, LegError> {
        within(
            "control.impedance.phase_sync_per_s",
            gain_per_s,
            0.0,
            GAIN_MAX_PER_S,
            "must be 0 to 20 per second (0: the reference keeps its own clock)",
        )?;
        within(
            "gait stride period",
            window_s,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            "must be > 0 s",
        )?;
        let bound = gain_per_s / window_s;
        check(
            integral_per_s2 == 0.0 || (0.0..bound).contains(&integral_per_s2),
            "control.impedance.phase_sync_integral_per_s2",
            integral_per_s2,
            if gain_per_s > 0.0 {
                format!(
                    "must be >= 0 and below phase_sync_per_s / the stride period = {bound:.4} per s² (beyond it the clock's loop is unstable)"
                )
            } else {
                "needs phase_sync_per_s > 0 (the integral alone makes the clock's loop unstable)"
                    .into()
            },
        )?;
        let mut s = Self {
            gain_per_s,
            integral_per_s2,
            window_s,
            mean_power: mean_power.max(0.0),
            clock_s: 0.0,
            rate: 1.0,
            integral: 0.0,
            last_t_s: 0.0,
            cross: 0.0,
            power: 0.0,
            rate_range: [1.0; 2],
        };
        s.reset(0.0);
        Ok(s)
    }

    /// In step with the reference at `t_s`, nothing measured.
    pub fn reset(&mut self, t_s: f64) {
        self.clock_s = t_s;
        self.last_t_s = t_s;
        self.rate = 1.0;
        self.integral = 0.0;
        self.cross = 0.0;
        self.power = self.mean_power;
        self.rate_range = [1.0; 2];
    }

    /// The gait's time at `t_s` (the clock advanced at its present rate).
    pub fn advance(&mut self, t_s: f64) -> f64 {
        self.clock_s += self.rate * (t_s - self.last_t_s).max(0.0);
        self.last_t_s = t_s;
        self.clock_s
    }

    /// The clock's rate (gait seconds per second).
    pub fn rate(&self) -> f64 {
        self.rate
    }

    /// The estimated lead of the legs over the reference (s).
    pub fn lead_s(&self) -> f64 {
        if self.power > 1e-12 {
            self.cross / self.power
        } else {
            0.0
        }
    }

    /// Takes in one period (`dt_s`) of the legs' deviation: `cross = Σ e·q̇_ref` and
    /// `power = Σ q̇_ref·q̇_ref` over their joints, the reference's velocity at rate 1.
    pub fn observe(&mut self, cross: f64, power: f64, dt_s: f64) {
        let a = 1.0 - (-dt_s / self.window_s).exp();
        self.cross += a * (cross - self.cross);
        self.power += a * (power - self.power);
        let lead = self.lead_s();
        // Held within the rate's range, so that a long clamp winds nothing up.
        self.integral = (self.integral + self.integral_per_s2 * lead * dt_s)
            .clamp(RATE_RANGE[0] - 1.0, RATE_RANGE[1] - 1.0);
        self.rate =
            (1.0 + self.gain_per_s * lead + self.integral).clamp(RATE_RANGE[0], RATE_RANGE[1]);
        self.rate_range = [
            self.rate_range[0].min(self.rate),
            self.rate_range[1].max(self.rate),
        ];
    }

    /// What the clock did since its reset.
    pub fn report(&self) -> PhaseSyncReport {
        PhaseSyncReport {
            gain_per_s: self.gain_per_s,
            integral_per_s2: self.integral_per_s2,
            integral_rate: self.integral,
            rate_min: self.rate_range[0],
            rate_max: self.rate_range[1],
            clock_offset_s: self.clock_s - self.last_t_s,
            lead_s: self.lead_s(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A leg that leads a sine reference by a constant `d`: the estimate converges to `d`
    /// and the clock speeds up by `gain d`.
    #[test]
    fn a_constant_lead_is_estimated_and_speeds_the_clock_by_gain_times_lead() {
        let (gain, d, w, dt) = (2.0, 0.05, 1.5, 1e-3);
        let mut s = PhaseSync::new(gain, 0.0, w, 0.0).expect("valid");
        let omega = std::f64::consts::TAU / 1.5;
        for k in 0..20_000 {
            let t = k as f64 * dt;
            let (q_ref, v_ref) = ((omega * t).sin(), omega * (omega * t).cos());
            let q = (omega * (t + d)).sin();
            s.observe((q - q_ref) * v_ref, v_ref * v_ref, dt);
        }
        // sin(w(t + d)) - sin(w t) is d v_ref to first order; the second-order term
        // averages out over whole cycles.
        assert!((s.lead_s() - d).abs() < 0.02 * d, "{}", s.lead_s());
        assert!((s.rate() - (1.0 + gain * s.lead_s())).abs() < 1e-12);
        assert_eq!(s.advance(1.0), s.rate() * 1.0);
    }

    /// A huge lead moves the clock by at most the rate range.
    #[test]
    fn the_rate_stays_within_its_range() {
        let mut s = PhaseSync::new(GAIN_MAX_PER_S, 0.0, 1.0, 1.0).expect("valid");
        for _ in 0..10_000 {
            s.observe(1.0, 1.0, 1e-3);
        }
        assert_eq!(s.rate(), RATE_RANGE[1]);
        for _ in 0..10_000 {
            s.observe(-1.0, 1.0, 1e-3);
        }
        assert_eq!(s.rate(), RATE_RANGE[0]);
    }

    /// The loop of the module's doc: a patient striding at `cadence` times the
    /// reference's, a sine reference on the clock, the leg leading it by `alpha` of the
    /// patient's lead. Returns the clock after `t_end_s` and the lead's largest magnitude
    /// over the last stride.
    fn locked_to(s: &mut PhaseSync, cadence: f64, alpha: f64, t_end_s: f64) -> f64 {
        let (dt, period) = (1e-3, 1.5);
        let omega = std::f64::consts::TAU / period;
        let mut last_lead: f64 = 0.0;
        let n = (t_end_s / dt) as usize;
        for k in 1..=n {
            let t = k as f64 * dt;
            let clock = s.advance(t);
            let patient = cadence * t;
            let (q_ref, v_ref) = ((omega * clock).sin(), omega * (omega * clock).cos());
            let q = (omega * (clock + alpha * (patient - clock))).sin();
            s.observe((q - q_ref) * v_ref, v_ref * v_ref, dt);
            if t > t_end_s - period {
                last_lead = last_lead.max(s.lead_s().abs());
            }
        }
        last_lead
    }

    /// A patient 6.7 % faster (1.5 s strides on a 1.6 s reference) behind a stiff
    /// spring that shows a sixth of their lead: the proportional loop locks with a lag
    /// (lead (cadence - 1) / gain), the integral takes the cadence and leaves no lead.
    #[test]
    fn the_integral_takes_the_whole_cadence_difference_and_leaves_no_lead() {
        let (gain, cadence, alpha) = (2.0, 1.6 / 1.5, 1.0 / 6.0);
        let mut p = PhaseSync::new(gain, 0.0, 1.5, 0.0).expect("valid");
        let lead_p = locked_to(&mut p, cadence, alpha, 200.0);
        assert!((p.rate() - cadence).abs() < 1e-3, "{}", p.rate());
        let expected = (cadence - 1.0) / gain;
        assert!(
            (lead_p - expected).abs() < 0.05 * expected,
            "{lead_p} {expected}"
        );
        let mut pi = PhaseSync::new(gain, 0.5, 1.5, 0.0).expect("valid");
        let lead_pi = locked_to(&mut pi, cadence, alpha, 200.0);
        assert!((pi.rate() - cadence).abs() < 1e-3, "{}", pi.rate());
        assert!(lead_pi < 0.02 * expected, "{lead_pi}");
        assert!((pi.report().integral_rate - (cadence - 1.0)).abs() < 1e-3);
    }

    /// Routh-Hurwitz on `W s³ + s² + α gain s + α integral`: just below `gain / W` the
    /// clock's error decays, just above it grows (the bound `new` enforces).
    #[test]
    fn the_integral_bound_is_the_loops_stability_limit() {
        let (gain, w, alpha) = (2.0, 1.5, 0.5);
        let spread = |integral: f64| {
            let mut s = PhaseSync::new(gain, 0.0, w, 0.0).expect("valid");
            s.integral_per_s2 = integral;
            // A cadence 0.2 % off the reference's: the lead over the last stride of
            // 300 s against that of 40 s.
            let early = locked_to(&mut s.clone(), 1.002, alpha, 40.0);
            let late = locked_to(&mut s, 1.002, alpha, 300.0);
            late / early
        };
        let (below, above) = (spread(0.9 * gain / w), spread(1.1 * gain / w));
        assert!(below < 0.5, "{below}");
        assert!(above > 2.0, "{above}");
        let e = PhaseSync::new(gain, 1.01 * gain / w, w, 1.0).expect_err("refused");
        assert!(e.to_string().contains("phase_sync_integral_per_s2"), "{e}");
    }

    #[test]
    fn a_negative_gain_is_refused_naming_the_field() {
        let e = PhaseSync::new(-1.0, 0.0, 1.0, 1.0).expect_err("refused");
        assert!(e.to_string().contains("phase_sync_per_s"), "{e}");
    }
}
