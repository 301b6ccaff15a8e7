/// Solves the set-valued equation `a (s - s_star) + g sgn(s) ∋ 0` for `s`, with `a > 0`
/// and `g >= 0`: `s = sign(s_star) max(|s_star| - g/a, 0)`.
///
/// This is the backward-Euler treatment of a signum term that Kikuuwe et al. (2010) use for
/// PSMC: where the explicit `sgn` would chatter around `s = 0`, the implicit solution
/// sticks exactly at zero while the available force `g` suffices.
///
/// ```
/// use pma_control::implicit_sign_solve;
/// assert_eq!(implicit_sign_solve(0.5, 1.0, 2.0), 0.0); // inside the dead zone: stuck
/// assert!((implicit_sign_solve(3.0, 1.0, 2.0) - 1.0).abs() < 1e-12);
/// assert!((implicit_sign_solve(-3.0, 1.0, 2.0) + 1.0).abs() < 1e-12);
/// ```
pub fn implicit_sign_solve(s_star: f64, a: f64, g: f64) -> f64 {
    let shrink = g / a;
    if s_star > shrink {
        s_star - shrink
    } else if s_star < -shrink {
        s_star + shrink
    } else {
        0.0
    }
}
