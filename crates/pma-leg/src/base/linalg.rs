//! The one 2 x 2 linear solve the leg's two joints need (the mass matrix, its implicit
//! damping, a muscle pair's Newton step).

/// `x` with `a x = b` by Cramer's rule (`a[row][column]`); `None` where `a` is singular
/// (its determinant not finite or under 1e-30 in magnitude).
pub(crate) fn solve_2x2(a: [[f64; 2]; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    if !det.is_finite() || det.abs() < 1e-30 {
        return None;
    }
    Some([
        (b[0] * a[1][1] - a[0][1] * b[1]) / det,
        (a[0][0] * b[1] - a[1][0] * b[0]) / det,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_system_and_refuses_a_singular_one() {
        let x = solve_2x2([[2.0, 1.0], [1.0, 3.0]], [3.0, 5.0]).unwrap();
        assert!(
            (x[0] - 0.8).abs() < 1e-15 && (x[1] - 1.4).abs() < 1e-15,
            "{x:?}"
        );
        assert_eq!(solve_2x2([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]), None);
    }
}
