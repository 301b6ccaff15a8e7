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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_move_is_relative_to_the_first_figure() {
        assert!((relative_move(2.0, 2.5) - 0.25).abs() < 1e-15);
        assert!((relative_move(-2.0, -1.5) - 0.25).abs() < 1e-15);
        assert!(converged([0.0, 0.02]));
        assert!(!converged([0.01, 0.0201]));
        assert!(!converged([relative_move(0.0, 1e-300)]));
    }
}
