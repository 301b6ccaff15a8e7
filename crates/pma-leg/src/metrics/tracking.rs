//! The leg's figures: tracking after the first stride, pressures, slack time, the common
//! mode's drift and valve activity, accumulated by a [`Recorder`] without allocation.
use crate::base::JOINT_NAMES;
use crate::metrics::{LegPeriod, LegRecorder, LegReport, LegStart, PatientReport, SafetyReport};

/// Per-joint tracking figures (deg).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct JointStats {
    /// RMS tracking error after the first stride (deg).
    pub rms_deg: f64,
    /// Largest tracking error after the first stride (deg).
    pub max_deg: f64,
}

/// Per-muscle figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MuscleStats {
    /// Lowest pressure (Pa).
    pub p_min_pa: f64,
    /// Highest pressure (Pa).
    pub p_max_pa: f64,
    /// Time spent slack (s).
    pub slack_s: f64,
}

/// Mean common-mode pressure over the second stride and the last one (Pa).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CoContractionStats {
    /// Second stride.
    pub start: f64,
    /// Last stride.
    pub end: f64,
}

/// Accumulates the [`LegReport`] figures period by period.
#[derive(Debug, Clone)]
pub struct LegMetrics {
    stride_s: f64,
    n: [usize; 2],
    sum_sq: [f64; 2],
    max_abs: [f64; 2],
    p_min: [f64; 4],
    p_max: [f64; 4],
    slack_s: [f64; 4],
    cm_start: (f64, usize),
    /// Common-mode pressure of the last stride's periods (ring buffer, sized once).
    cm_ring: Vec<f64>,
    cm_next: usize,
    cm_filled: bool,
    variation: f64,
    previous: [f64; 4],
    finite: bool,
    t_s: f64,
}

impl LegMetrics {
    /// Figures for a gait of `stride_s` at `period_s` (the ring buffer is sized here).
    pub fn new(stride_s: f64, period_s: f64) -> Self {
        Self {
            stride_s,
            n: [0; 2],
            sum_sq: [0.0; 2],
            max_abs: [0.0; 2],
            p_min: [f64::INFINITY; 4],
            p_max: [f64::NEG_INFINITY; 4],
            slack_s: [0.0; 4],
            cm_start: (0.0, 0),
            cm_ring: vec![0.0; (stride_s / period_s).round().max(1.0) as usize],
            cm_next: 0,
            cm_filled: false,
            variation: 0.0,
            previous: [0.0; 4],
            finite: true,
            t_s: 0.0,
        }
    }

    fn push_tracking(&mut self, reference_rad: [f64; 2], angle_rad: [f64; 2]) {
        for j in 0..2 {
            let e = (reference_rad[j] - angle_rad[j]).to_degrees();
            self.n[j] += 1;
            self.sum_sq[j] += e * e;
            self.max_abs[j] = self.max_abs[j].max(e.abs());
        }
    }

    fn push_common_mode(&mut self, t_s: f64, pressure_pa: &[f64; 4]) {
        let cm = pressure_pa.iter().sum::<f64>() / 4.0;
        if t_s > self.stride_s && t_s <= 2.0 * self.stride_s {
            self.cm_start.0 += cm;
            self.cm_start.1 += 1;
        }
        if !self.cm_ring.is_empty() {
            self.cm_ring[self.cm_next] = cm;
            self.cm_next = (self.cm_next + 1) % self.cm_ring.len();
            self.cm_filled |= self.cm_next == 0;
        }
    }

    /// The report of the run so far.
    pub fn report(
        &self,
        scenario: &str,
        muscle_names: &[String],
        duration_s: f64,
        wall_s: f64,
    ) -> LegReport {
        let joints = JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(j, n)| {
                let stats = if self.n[j] > 0 {
                    JointStats {
                        rms_deg: (self.sum_sq[j] / self.n[j] as f64).sqrt(),
                        max_deg: self.max_abs[j],
                    }
                } else {
                    JointStats {
                        rms_deg: f64::NAN,
                        max_deg: f64::NAN,
                    }
                };
                ((*n).to_owned(), stats)
            })
            .collect();
        let muscles = muscle_names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                (
                    name.clone(),
                    MuscleStats {
                        p_min_pa: self.p_min[i],
                        p_max_pa: self.p_max[i],
                        slack_s: self.slack_s[i],
                    },
                )
            })
            .collect();
        let last = if self.cm_filled {
            &self.cm_ring[..]
        } else {
            &self.cm_ring[..self.cm_next]
        };
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        LegReport {
            scenario: scenario.to_owned(),
            duration_s,
            joints,
            muscles,
            cocontraction_pa: CoContractionStats {
                start: if self.cm_start.1 > 0 {
                    self.cm_start.0 / self.cm_start.1 as f64
                } else {
                    f64::NAN
                },
                end: mean(last),
            },
            command_variation_bar_per_s: self.variation / self.t_s.max(1e-12) / 1e5,
            finite: self.finite,
            real_time_factor: duration_s / wall_s.max(1e-12),
            interrupted: false,
            patient: PatientReport::default(),
            spasms: Vec::new(),
            safety: SafetyReport::default(),
            treadmill: None,
            cooperation: Vec::new(),
            phase_sync: None,
            walking: None,
            step: None,
            check_step: None,
        }
    }
}

impl LegRecorder for LegMetrics {
    fn start(&mut self, s: &LegStart<'_>) {
        self.previous = *s.resting;
        self.t_s = s.t_s;
    }

    /// The figures pair the state at the reading with the commands held over the period
    /// that led to it.
    fn record(&mut self, p: &LegPeriod<'_>) {
        let held = *p.held;
        self.variation += held
            .iter()
            .zip(self.previous)
            .map(|(u, prev)| (u - prev).abs())
            .sum::<f64>()
            / 4.0;
        self.previous = held;
        self.t_s = p.t_s;
        let s = p.state;
        self.finite &= s.angle_rad.iter().chain(&held).all(|v| v.is_finite());
        if p.t_s > self.stride_s {
            self.push_tracking(p.output.reference_rad, s.angle_rad);
        }
        for i in 0..4 {
            self.p_min[i] = self.p_min[i].min(s.pressure_pa[i]);
            self.p_max[i] = self.p_max[i].max(s.pressure_pa[i]);
            self.slack_s[i] += s.slack_s[i];
        }
        self.push_common_mode(p.t_s, &s.pressure_pa);
    }
}
