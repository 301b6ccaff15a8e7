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
    /// The RMS of each whole stride after the first, over the strides: the typical
    /// stride's error and how far the worse ones are from it. A run's RMS and max can be
    /// decided by one stride's excursion (docs/convergence.md); these are not.
    pub per_stride: StrideSpread,
}

/// The spread of a figure over whole strides (`NaN`, `null` in JSON, without one).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct StrideSpread {
    /// Whole strides after the first.
    pub strides: usize,
    /// Median over them (deg).
    pub median_deg: f64,
    /// 90th percentile (nearest rank; deg).
    pub p90_deg: f64,
    /// Largest (deg).
    pub max_deg: f64,
}

impl StrideSpread {
    /// The spread of `values` (reordered in place).
    fn of(values: &mut [f64]) -> Self {
        if values.is_empty() {
            return Self {
                strides: 0,
                median_deg: f64::NAN,
                p90_deg: f64::NAN,
                max_deg: f64::NAN,
            };
        }
        values.sort_by(f64::total_cmp);
        let n = values.len();
        let median = if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        };
        let p90 = pma_control::nearest_rank(values, 0.9);
        Self {
            strides: n,
            median_deg: median,
            p90_deg: p90,
            max_deg: values[n - 1],
        }
    }
}

/// Sums of squares of the stride under way, and the RMS of each whole stride so far
/// (sized for the run, so that recording allocates nothing).
#[derive(Debug, Clone)]
struct StrideRms {
    index: usize,
    sum_sq: [f64; 2],
    n: usize,
    done: [Vec<f64>; 2],
}

impl StrideRms {
    fn new(strides: usize) -> Self {
        Self {
            index: 1,
            sum_sq: [0.0; 2],
            n: 0,
            done: [Vec::with_capacity(strides), Vec::with_capacity(strides)],
        }
    }

    /// Adds the errors `e` (deg) of the period in stride `index` (0: the first).
    fn push(&mut self, index: usize, e: [f64; 2]) {
        if index != self.index {
            if index == self.index + 1 && self.n > 0 {
                for j in 0..2 {
                    let rms = (self.sum_sq[j] / self.n as f64).sqrt();
                    if self.done[j].len() < self.done[j].capacity() {
                        self.done[j].push(rms);
                    }
                }
            }
            self.index = index;
            self.sum_sq = [0.0; 2];
            self.n = 0;
        }
        for (sum_sq, e) in self.sum_sq.iter_mut().zip(e) {
            *sum_sq += e * e;
        }
        self.n += 1;
    }
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
    period_s: f64,
    strides: StrideRms,
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
    /// Figures for a gait of `stride_s` at `period_s` over `duration_s` (the ring buffer
    /// and the strides' figures are sized here).
    pub fn new(stride_s: f64, period_s: f64, duration_s: f64) -> Self {
        let strides = (duration_s / stride_s).ceil();
        Self {
            stride_s,
            period_s,
            strides: StrideRms::new(if strides.is_finite() {
                strides.clamp(0.0, 1e6) as usize + 1
            } else {
                0
            }),
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

    fn push_tracking(&mut self, t_s: f64, reference_rad: [f64; 2], angle_rad: [f64; 2]) {
        let mut e = [0.0; 2];
        for j in 0..2 {
            e[j] = (reference_rad[j] - angle_rad[j]).to_degrees();
            self.n[j] += 1;
            self.sum_sq[j] += e[j] * e[j];
            self.max_abs[j] = self.max_abs[j].max(e[j].abs());
        }
        // A period ending at t belongs to the stride it ends in (the first stride's own
        // periods are not recorded at all).
        let index = ((t_s / self.stride_s) - 1e-9).floor().max(0.0) as usize;
        self.strides.push(index, e);
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

    /// The RMS of joint `j` in each whole stride after the first, the one ending at the
    /// run's end included.
    fn strides_rms(&self, j: usize) -> Vec<f64> {
        let s = &self.strides;
        let mut done = s.done[j].clone();
        let stride_end = (s.index + 1) as f64 * self.stride_s;
        if s.n > 0 && self.t_s >= stride_end - 0.5 * self.period_s {
            done.push((s.sum_sq[j] / s.n as f64).sqrt());
        }
        done
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
                let per_stride = StrideSpread::of(&mut self.strides_rms(j));
                let stats = if self.n[j] > 0 {
                    JointStats {
                        rms_deg: (self.sum_sq[j] / self.n[j] as f64).sqrt(),
                        max_deg: self.max_abs[j],
                        per_stride,
                    }
                } else {
                    JointStats {
                        rms_deg: f64::NAN,
                        max_deg: f64::NAN,
                        per_stride,
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
            self.push_tracking(p.t_s, p.output.reference_rad, s.angle_rad);
        }
        for i in 0..4 {
            self.p_min[i] = self.p_min[i].min(s.pressure_pa[i]);
            self.p_max[i] = self.p_max[i].max(s.pressure_pa[i]);
            self.slack_s[i] += s.slack_s[i];
        }
        self.push_common_mode(p.t_s, &s.pressure_pa);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stride_spread_is_its_median_nearest_rank_p90_and_largest() {
        let s = StrideSpread::of(&mut [5.0, 1.0, 3.0, 2.0, 4.0, 6.0, 7.0, 8.0, 9.0, 10.0]);
        assert_eq!(
            (s.strides, s.median_deg, s.p90_deg, s.max_deg),
            (10, 5.5, 9.0, 10.0)
        );
        let one = StrideSpread::of(&mut [0.25]);
        assert_eq!(
            (one.median_deg, one.p90_deg, one.max_deg),
            (0.25, 0.25, 0.25)
        );
        assert!(StrideSpread::of(&mut []).median_deg.is_nan());
    }

    /// Two whole strides after the first, 1 deg and 3 deg throughout: each is its own RMS,
    /// the last one (ending with the run) included, the first stride in none.
    #[test]
    fn each_whole_stride_after_the_first_has_its_own_rms() {
        let mut m = LegMetrics::new(1.0, 0.25, 3.0);
        for k in 5..=12 {
            let t = k as f64 * 0.25;
            let e: f64 = if t <= 2.0 { 1.0 } else { 3.0 };
            m.push_tracking(t, [e.to_radians(), 0.0], [0.0, 0.0]);
            m.t_s = t;
        }
        let s = StrideSpread::of(&mut m.strides_rms(0));
        assert_eq!(s.strides, 2);
        assert!((s.median_deg - 2.0).abs() < 1e-12, "{s:?}");
        assert!((s.max_deg - 3.0).abs() < 1e-12, "{s:?}");
        // Half a stride more is not a whole one.
        m.push_tracking(3.25, [0.0; 2], [0.0; 2]);
        m.t_s = 3.25;
        assert_eq!(m.strides_rms(0).len(), 2);
    }
}
