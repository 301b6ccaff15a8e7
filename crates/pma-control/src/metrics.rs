/// Tracking metrics of eqs. (51)-(53), plus RMS.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct TrackingStats {
    /// MAE, eq. (51): `max |x_d - x|` (m).
    pub mae_m: f64,
    /// IAE, eq. (52): the *mean* of `|x_d - x|` over the samples (m), as the paper defines it.
    pub iae_m: f64,
    /// RTE, eq. (53): IAE / `x_a` x 100 (%).
    pub rte_percent: f64,
    /// Root mean square error (m).
    pub rms_m: f64,
    /// Number of samples.
    pub samples: usize,
}

/// Accumulates tracking errors sample by sample (no allocation).
#[derive(Debug, Clone, Copy, Default)]
pub struct Metrics {
    n: usize,
    sum_abs: f64,
    sum_sq: f64,
    max_abs: f64,
}

impl Metrics {
    /// Empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one sample of `x_d - x`. A NaN error poisons the result (reported as NaN).
    pub fn push(&mut self, error_m: f64) {
        let a = error_m.abs();
        self.n += 1;
        self.sum_abs += a;
        self.sum_sq += error_m * error_m;
        self.max_abs = if a.is_nan() {
            f64::NAN
        } else {
            self.max_abs.max(a)
        };
    }

    /// Final figures; `x_a_m` is the maximum running displacement of eq. (53).
    pub fn finish(&self, x_a_m: f64) -> TrackingStats {
        if self.n == 0 {
            return TrackingStats::default();
        }
        let n = self.n as f64;
        let iae = self.sum_abs / n;
        TrackingStats {
            mae_m: self.max_abs,
            iae_m: iae,
            rte_percent: iae / x_a_m * 100.0,
            rms_m: (self.sum_sq / n).sqrt(),
            samples: self.n,
        }
    }
}

/// The nearest-rank `q`-quantile of `sorted` (ascending): the smallest value with at least
/// a share `q` of them at or below it; `NaN` for no values. One definition for every
/// percentile the project reports (a sweep's p95, a leg's per-stride p90), so that two
/// reports of "the p90" cannot differ by their rounding of the rank.
pub fn nearest_rank(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        n => sorted[((q * n as f64).ceil() as usize).clamp(1, n) - 1],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_takes_the_smallest_value_covering_the_share() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];
        assert_eq!(nearest_rank(&v, 0.9), 9.0);
        assert_eq!(nearest_rank(&v, 0.91), 10.0);
        assert_eq!(nearest_rank(&v, 0.5), 5.0);
        assert_eq!(nearest_rank(&v, 0.0), 1.0);
        assert_eq!(nearest_rank(&v, 1.0), 10.0);
        assert!(nearest_rank(&[], 0.5).is_nan());
    }

    #[test]
    fn metrics_follow_eqs_51_to_53() {
        let mut m = Metrics::new();
        for e in [0.001, -0.003, 0.002, 0.0] {
            m.push(e);
        }
        let s = m.finish(0.030);
        assert_eq!(s.mae_m, 0.003);
        assert!((s.iae_m - 0.0015).abs() < 1e-15);
        assert!((s.rte_percent - 5.0).abs() < 1e-12);
        assert!((s.rms_m - (14e-6f64 / 4.0).sqrt()).abs() < 1e-15);
        assert_eq!(s.samples, 4);
    }

    #[test]
    fn nan_error_is_not_hidden() {
        let mut m = Metrics::new();
        m.push(0.001);
        m.push(f64::NAN);
        let s = m.finish(0.03);
        assert!(s.mae_m.is_nan() && s.iae_m.is_nan());
    }
}
