//! How far a run's figures move when its integration step is halved (`--check-step`).

/// The largest relative move of a figure at half the step for it to count as converged:
/// the project's criterion for a published figure (`docs/convergence.md`).
pub const STEP_TOLERANCE: f64 = 0.02;

/// `|refined - first| / |first|`: how far a figure moved from the run at the shipped step
/// (`first`) to the one at half of it (`refined`).
pub fn relative_move(first: f64, refined: f64) -> f64 {
    (refined - first).abs() / first.abs().max(f64::MIN_POSITIVE)
}

/// Whether every move is within [`STEP_TOLERANCE`].
pub fn converged(moves: impl IntoIterator<Item = f64>) -> bool {
    moves.into_iter().all(|m| m <= STEP_TOLERANCE)
}

/// A figure over runs that differ only in their noise's seed: where a loop chatters, one
/// run's figure has no converged value, and this is what a step is judged on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedSpread {
    /// Runs.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one run).
    pub sd: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl SeedSpread {
    /// The spread of `values` (`None` if there are none).
    pub fn of(values: &[f64]) -> Option<Self> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let ss: f64 = values.iter().map(|v| (v - mean).powi(2)).sum();
        let sd = if n > 1 {
            (ss / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        let (min, max) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        Some(Self {
            n,
            mean,
            sd,
            min,
            max,
        })
    }

    /// The standard error of the difference of two means (`self`'s and `other`'s).
    pub fn difference_error(&self, other: &Self) -> f64 {
        (self.sd.powi(2) / self.n as f64 + other.sd.powi(2) / other.n as f64).sqrt()
    }

    /// Whether `other`'s mean lies within two standard errors of the difference of this
    /// one's: the step's move is then not told apart from the seeds' scatter.
    pub fn within_scatter(&self, other: &Self) -> bool {
        (other.mean - self.mean).abs() <= 2.0 * self.difference_error(other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seed_spread_is_the_sample_mean_and_deviation() {
        let a = SeedSpread::of(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!((a.n, a.mean, a.min, a.max), (4, 2.5, 1.0, 4.0));
        assert!((a.sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(SeedSpread::of(&[7.0]).unwrap().sd, 0.0);
        assert!(SeedSpread::of(&[]).is_none());
        // 2 standard errors of the difference: sqrt(2 x 5/3 / 4) = 0.913 each.
        let moved = |d: f64| SeedSpread { mean: 2.5 + d, ..a };
        assert!(a.within_scatter(&moved(1.8)));
        assert!(!a.within_scatter(&moved(1.9)));
    }

    #[test]
    fn a_move_is_relative_to_the_first_figure() {
        assert!((relative_move(2.0, 2.5) - 0.25).abs() < 1e-15);
        assert!((relative_move(-2.0, -1.5) - 0.25).abs() < 1e-15);
        assert!(converged([0.0, 0.02]));
        assert!(!converged([0.01, 0.0201]));
        assert!(!converged([relative_move(0.0, 1e-300)]));
    }
}
