//! Gain tuning with the firefly algorithm (Yang 2009), the family of the switch-mode
//! firefly algorithm the paper used. Every controller is tuned with the same optimiser,
//! the same budget and the same objective: the IAE of eq. (52) on the paper's 0.25 Hz
//! sine, optionally under a budget on command activity (see [`Objective`]). The search
//! runs in the unit cube, mapped to each gain's range (logarithmically for gains spanning
//! decades), so that one step size suits every gain.

use pma_bench::{run_single, PlantConfig, RunSpec};
use pma_control::{ControllerConfig, ControllerKind, SineReference};
use pma_model::GaussianRng;
use std::sync::atomic::{AtomicBool, Ordering};

/// Firefly algorithm settings; the budget is `population * (generations + 1)` runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FireflyOptions {
    /// Number of fireflies.
    pub population: usize,
    /// Number of generations.
    pub generations: usize,
    /// Attractiveness at distance 0.
    pub beta0: f64,
    /// Light absorption (in unit-cube distance).
    pub absorption: f64,
    /// Initial random step, decaying geometrically to a tenth over the run.
    pub alpha0: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for FireflyOptions {
    fn default() -> Self {
        Self {
            population: 20,
            generations: 40,
            beta0: 1.0,
            absorption: 1.0,
            alpha0: 0.2,
            seed: 2019,
        }
    }
}

/// Evaluates every position, in parallel on rayon's pool (the caller's `install` sets
/// its size). Each evaluation depends on its position only, so the result is the same
/// for any number of threads. Once `stop` is raised the rest are skipped (infinite cost).
fn evaluate_all(
    pos: &[Vec<f64>],
    stop: &AtomicBool,
    objective: &(impl Fn(&[f64]) -> f64 + Sync),
) -> Vec<f64> {
    use rayon::prelude::*;
    pos.par_iter()
        .map(|p| {
            if stop.load(Ordering::Relaxed) {
                f64::INFINITY
            } else {
                objective(p)
            }
        })
        .collect()
}

/// Minimises `objective` over the unit cube `[0, 1]^dims`. Returns the best point, its
/// value and the number of evaluations. The random moves are drawn in one sequence; the
/// evaluations of a generation run in parallel. Raising `stop` ends the search after the
/// evaluations under way (the caller sees the flag and discards the result).
pub fn firefly(
    dims: usize,
    opts: &FireflyOptions,
    stop: &AtomicBool,
    objective: impl Fn(&[f64]) -> f64 + Sync,
) -> (Vec<f64>, f64, usize) {
    let mut rng = GaussianRng::new(opts.seed);
    let n = opts.population.max(2);
    let mut pos: Vec<Vec<f64>> = (0..n)
        .map(|_| (0..dims).map(|_| rng.uniform()).collect())
        .collect();
    let mut cost = evaluate_all(&pos, stop, &objective);
    let mut evals = n;
    let decay = 0.1f64.powf(1.0 / opts.generations.max(1) as f64);
    let mut alpha = opts.alpha0;
    for _ in 0..opts.generations {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let snapshot = pos.clone();
        let snap_cost = cost.clone();
        for i in 0..n {
            for j in 0..n {
                if snap_cost[j] < snap_cost[i] {
                    let r2: f64 = pos[i]
                        .iter()
                        .zip(&snapshot[j])
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum();
                    let beta = opts.beta0 * (-opts.absorption * r2).exp();
                    for (d, xi) in pos[i].iter_mut().enumerate() {
                        *xi += beta * (snapshot[j][d] - *xi) + alpha * (rng.uniform() - 0.5);
                        *xi = xi.clamp(0.0, 1.0);
                    }
                }
            }
            // The brightest firefly walks randomly, so the best region is still explored.
            if snap_cost[i] <= snap_cost.iter().copied().fold(f64::INFINITY, f64::min) {
                for xi in pos[i].iter_mut() {
                    *xi = (*xi + alpha * (rng.uniform() - 0.5)).clamp(0.0, 1.0);
                }
            }
        }
        let new_cost = evaluate_all(&pos, stop, &objective);
        evals += n;
        for (i, c) in new_cost.into_iter().enumerate() {
            // Elitism per firefly: keep the better of old and new position.
            if c < cost[i] {
                cost[i] = c;
            } else {
                pos[i] = snapshot[i].clone();
            }
        }
        alpha *= decay;
    }
    let best = (0..n)
        .min_by(|&a, &b| cost[a].total_cmp(&cost[b]))
        .unwrap_or(0);
    (pos[best].clone(), cost[best], evals)
}

/// What [`tune`] minimises: the IAE of eq. (52) on the paper's sine over `duration_s`,
/// optionally subject to a budget on command activity.
///
/// Without a budget, a plant without noise or valve lag rewards ever higher gains: the
/// unconstrained optimum sits on the search box's bounds and costs 8-27 bar/s of command
/// variation, so the ranking it gives says more about the box than about the
/// controllers. With `max_variation_pa_per_s`, every controller gets the same budget
/// (mean |du/dt| of the command), the usual equal-effort comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Objective {
    /// Simulated seconds per evaluation.
    pub duration_s: f64,
    /// Budget on the command's mean |du/dt| (Pa/s); `None` for none.
    pub max_variation_pa_per_s: Option<f64>,
}

/// One evaluated gain set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// IAE on the sine (m); 1 m for a failed or non-finite run.
    pub iae_m: f64,
    /// Mean |du/dt| of the command (Pa/s).
    pub variation_pa_per_s: f64,
}

impl Score {
    /// Within the objective's budget.
    pub fn feasible(&self, objective: &Objective) -> bool {
        objective
            .max_variation_pa_per_s
            .is_none_or(|v| self.variation_pa_per_s <= v)
    }

    /// The value minimised: the IAE when feasible; otherwise 1 m (worse than any
    /// feasible run) plus the budget overshoot, so the search still descends towards it.
    pub fn cost(&self, objective: &Objective) -> f64 {
        match objective.max_variation_pa_per_s {
            Some(v) if !self.feasible(objective) => 1.0 + self.variation_pa_per_s / v,
            _ => self.iae_m,
        }
    }
}

/// Scores a gain set on the paper's sine.
pub fn sine_score(config: &ControllerConfig, plant: &PlantConfig, duration_s: f64) -> Score {
    let spec = RunSpec {
        duration_s,
        ..RunSpec::default()
    };
    match run_single(config, plant, &SineReference::paper(), &spec, &mut ()) {
        Ok(r) if r.finite && r.stats.iae_m.is_finite() => Score {
            iae_m: r.stats.iae_m,
            variation_pa_per_s: r.command_variation_pa_per_s,
        },
        _ => Score {
            iae_m: 1.0,
            variation_pa_per_s: f64::INFINITY,
        },
    }
}

/// Result of [`tune`].
#[derive(Debug, Clone, PartialEq)]
pub struct TuneResult {
    /// Best gains.
    pub config: ControllerConfig,
    /// Their score on the sine.
    pub score: Score,
    /// Whether they keep the budget (always without one).
    pub feasible: bool,
    /// Runs spent.
    pub evaluations: usize,
}

/// Tunes `kind` on `plant` for `objective`; `None` for a controller without a search
/// space.
pub fn tune(
    kind: ControllerKind,
    plant: &PlantConfig,
    opts: &FireflyOptions,
    objective: &Objective,
    stop: &AtomicBool,
) -> Option<TuneResult> {
    let dims = kind.search_space().len();
    if dims == 0 {
        return None;
    }
    let (u, _, evaluations) = firefly(dims, opts, stop, |u| {
        sine_score(&ControllerConfig::at(kind, u), plant, objective.duration_s).cost(objective)
    });
    let config = ControllerConfig::at(kind, &u);
    let score = sine_score(&config, plant, objective.duration_s);
    Some(TuneResult {
        config,
        score,
        feasible: score.feasible(objective),
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn firefly_finds_the_minimum_of_a_shifted_bowl() {
        let target = [0.3, 0.7, 0.55];
        let (x, f, evals) = firefly(
            3,
            &FireflyOptions::default(),
            &AtomicBool::new(false),
            |u| u.iter().zip(&target).map(|(a, b)| (a - b) * (a - b)).sum(),
        );
        assert_eq!(evals, 20 * 41);
        assert!(f < 1e-3, "f = {f}, x = {x:?}");
    }

    #[test]
    fn every_searched_gain_exists_by_name() {
        for kind in ControllerKind::ALL {
            let space = kind.search_space();
            assert!(!space.is_empty(), "{kind}");
            let mut c = kind.default_config();
            for spec in &space {
                assert!(c.gain_mut(spec.name).is_some(), "{kind}: {}", spec.name);
            }
            assert_eq!(
                ControllerConfig::at(kind, &vec![0.5; space.len()]).kind(),
                kind
            );
        }
    }

    #[test]
    fn the_same_seed_tunes_the_same_gains_on_one_thread_and_on_two() {
        let plant = PlantConfig::preset("mismatch").expect("preset");
        let opts = FireflyOptions {
            population: 4,
            generations: 2,
            seed: 5,
            ..FireflyOptions::default()
        };
        let objective = Objective {
            duration_s: 2.0,
            max_variation_pa_per_s: None,
        };
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| {
                    tune(
                        ControllerKind::Pid,
                        &plant,
                        &opts,
                        &objective,
                        &AtomicBool::new(false),
                    )
                })
        };
        assert_eq!(run(1), run(2));
    }
}
