//! A ceiling on every muscle's pressure command from its force: the pressure at which the
//! muscle's datasheet model, at the measured contraction and contraction rate, pulls a
//! set share of its rating (`[control] force_max_of_rating`).
//!
//! Why a force limit and not a lower pressure cap: a muscle reaches its rating not at a
//! pressure but at a pressure *and* a state. A DMSP-20 at 5 bar pulls 0.8 of its rating
//! near its rest length and far less contracted; stretched fast under pressure its damping
//! adds half its rating again (the trainer's knee extensors in swing, issue 46: 0.94-1.00
//! of the rating over 60 s, above 0.9 of it for 0.3 % of the time). A cap low enough for
//! the worst state takes the pressure away everywhere else; the ceiling takes it away only
//! where the force would pass the limit. It is computed from what a lab knows: the
//! datasheet's muscle (not the true one of a robustness study), the encoder's angle and
//! its rate. It bounds the command; the pressure behind a valve follows within the valve's
//! lag, so the force can still pass the limit briefly (the run's peak force says by how
//! much).
use crate::base::LegError;
use crate::plant::MuscleActuator;
use pma_model::{DampingMode, MuscleModel};

/// Time constant of the encoder's differentiated angle the ceiling's damping term reads
/// (s): five periods of the 1 kHz loop, as impedance mode's velocity estimate.
pub const FORCE_LIMIT_VELOCITY_FILTER_S: f64 = 0.005;

/// One muscle as the limit sees it.
#[derive(Debug, Clone, Copy)]
struct Limited {
    model: MuscleModel,
    joint: usize,
    moment_arm_m: f64,
    contraction_at_zero_m: f64,
    force_max_n: f64,
}

/// The ceiling on one leg's four pressure commands.
#[derive(Debug, Clone)]
pub struct ForceLimit {
    muscles: [Limited; 4],
    pressure_max_pa: f64,
    velocity_rad_s: [f64; 2],
    last_rad: Option<[f64; 2]>,
    /// Whether each muscle's last command was lowered to its ceiling.
    bound: [bool; 4],
}

impl ForceLimit {
    /// The limit at `share` of each of a leg's four `muscles`' rating, for valves that
    /// reach `pressure_max_pa`. `share` must lie in (0, 1]: a limit above the rating is
    /// none.
    pub fn new(
        muscles: &[MuscleActuator],
        share: f64,
        pressure_max_pa: f64,
    ) -> Result<Self, LegError> {
        check_share(share)?;
        let limited: Vec<Limited> = muscles
            .iter()
            .map(|m| Limited {
                model: m.assumed_model(),
                joint: m.joint,
                moment_arm_m: m.geometry.moment_arm_m(),
                contraction_at_zero_m: m.geometry.contraction_at_zero_m,
                force_max_n: share * m.rated_force_n,
            })
            .collect();
        let muscles = limited.try_into().map_err(|v: Vec<Limited>| {
            crate::base::invalid(
                "number of muscles",
                v.len() as f64,
                "must be 4: a flexor and an extensor on hip and knee",
            )
        })?;
        Ok(Self {
            muscles,
            pressure_max_pa,
            velocity_rad_s: [0.0; 2],
            last_rad: None,
            bound: [false; 4],
        })
    }

    /// Restarts the velocity estimate at rest.
    pub fn reset(&mut self) {
        self.velocity_rad_s = [0.0; 2];
        self.last_rad = None;
        self.bound = [false; 4];
    }

    /// Whether each muscle's last command was lowered to its ceiling.
    pub fn bound(&self) -> [bool; 4] {
        self.bound
    }

    /// Lowers each of `commands_pa` to its muscle's ceiling at the measured angles `q_rad`
    /// and pressures `pressures_pa` (one call per period of `dt_s`). Where a pressure is
    /// already above its ceiling (the valve lags its set point while the muscle is
    /// stretched), the command goes as far below the ceiling as the pressure is above it,
    /// so that the valve vents faster the further the force has passed the limit.
    pub fn apply(
        &mut self,
        commands_pa: &mut [f64; 4],
        q_rad: [f64; 2],
        pressures_pa: [f64; 4],
        dt_s: f64,
    ) {
        self.estimate_velocity(q_rad, dt_s);
        for (i, m) in self.muscles.iter().enumerate() {
            let x = m.contraction_at_zero_m + m.moment_arm_m * q_rad[m.joint];
            let v = m.moment_arm_m * self.velocity_rad_s[m.joint];
            let ceiling = ceiling_pa(m, x, v, self.pressure_max_pa);
            let excess = (pressures_pa[i] - ceiling).max(0.0);
            let ceiling = (ceiling - excess).max(0.0);
            self.bound[i] = commands_pa[i] > ceiling;
            if self.bound[i] {
                commands_pa[i] = ceiling;
            }
        }
    }

    fn estimate_velocity(&mut self, q: [f64; 2], dt_s: f64) {
        if let Some(last) = self.last_rad {
            let a = dt_s / (FORCE_LIMIT_VELOCITY_FILTER_S + dt_s);
            for j in 0..2 {
                let raw = (q[j] - last[j]) / dt_s;
                self.velocity_rad_s[j] += a * (raw - self.velocity_rad_s[j]);
            }
        }
        self.last_rad = Some(q);
    }
}

/// `share` of `[control] force_max_of_rating` within (0, 1].
pub(crate) fn check_share(share: f64) -> Result<(), LegError> {
    pma_model::error::check(
        share > 0.0 && share <= 1.0,
        "control.force_max_of_rating",
        share,
        "must lie in (0, 1]: the share of each muscle's rating its commands may ask (a limit above the rating is none)",
    )?;
    Ok(())
}

/// The highest pressure (Pa, within `[0, pressure_max_pa]`) at which `m` at contraction
/// `x_m` and contraction rate `v_m_s` pulls at most its `force_max_n`, in the damping mode
/// that pulls more. The force is affine in the pressure (the map's or eq. (1)'s static
/// force and a damping affine in it), so two evaluations give it exactly.
fn ceiling_pa(m: &Limited, x_m: f64, v_m_s: f64, pressure_max_pa: f64) -> f64 {
    let force = |p: f64| {
        [DampingMode::Inflation, DampingMode::Deflation]
            .map(|mode| m.model.force_unclamped(p, x_m, v_m_s, mode))
            .into_iter()
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let at_max = force(pressure_max_pa);
    if at_max <= m.force_max_n {
        return pressure_max_pa;
    }
    let at_zero = force(0.0);
    let slope = (at_max - at_zero) / pressure_max_pa;
    if slope <= 0.0 {
        return 0.0;
    }
    ((m.force_max_n - at_zero) / slope).clamp(0.0, pressure_max_pa)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pma_model::festo::{DmspSize, FestoMuscle};

    fn dmsp20(rest_length_m: f64) -> Limited {
        Limited {
            model: MuscleModel::Festo(
                FestoMuscle::new(DmspSize::Dmsp20, rest_length_m).expect("a valid muscle"),
            ),
            joint: 0,
            moment_arm_m: 0.05,
            contraction_at_zero_m: 0.0,
            force_max_n: 0.9 * DmspSize::Dmsp20.rated_force_n(),
        }
    }

    #[test]
    fn the_ceiling_is_the_pressure_at_which_the_datasheet_muscle_pulls_the_limit() {
        let m = dmsp20(1.2);
        let mut interior = 0;
        for (x, v) in [(0.0, 0.0), (0.01, -0.2), (0.02, 0.1), (0.005, -0.05)] {
            let p = ceiling_pa(&m, x, v, 6e5);
            if p < 6e5 && p > 0.0 {
                interior += 1;
                let f = [DampingMode::Inflation, DampingMode::Deflation]
                    .map(|mode| m.model.force_unclamped(p, x, v, mode));
                let pulls = f[0].max(f[1]);
                assert!(
                    (pulls - m.force_max_n).abs() < 1e-6 * m.force_max_n,
                    "x {x} v {v}: {pulls} N at the ceiling {p} Pa"
                );
            }
        }
        assert!(interior >= 3, "only {interior} states bound the ceiling");
    }

    #[test]
    fn stretching_a_muscle_under_pressure_lowers_its_ceiling_and_contracting_raises_it() {
        let m = dmsp20(1.2);
        let at_rest = ceiling_pa(&m, 0.0, 0.0, 6e5);
        let stretched = ceiling_pa(&m, 0.0, -0.15, 6e5);
        let shortening = ceiling_pa(&m, 0.0, 0.15, 6e5);
        assert!(stretched < at_rest, "{stretched} against {at_rest}");
        assert!(shortening >= at_rest, "{shortening} against {at_rest}");
        // At rest length a DMSP-20 pulls its rating at about 6 bar, so 0.9 of it is
        // reached below the valve's 6 bar.
        assert!(at_rest < 6e5 && at_rest > 4e5, "{at_rest}");
    }

    #[test]
    fn a_muscle_contracted_far_enough_is_not_limited() {
        let m = dmsp20(1.2);
        assert_eq!(ceiling_pa(&m, 0.15 * 1.2, 0.0, 6e5), 6e5);
    }

    #[test]
    fn a_share_outside_zero_to_one_is_refused_naming_the_field() {
        for bad in [0.0, -0.1, 1.01, f64::NAN] {
            let e = check_share(bad).expect_err("refused").to_string();
            assert!(e.contains("control.force_max_of_rating"), "{e}");
        }
        check_share(1.0).expect("the rating itself is a limit");
    }
}
