//! `pma-exo single`: one controller on the single-muscle bench.
use super::{viz, RefName, RunOutput, SampleCsv};
use crate::output::{self, INTERRUPTED};
use crate::provenance::{Provenance, Seeds};
use crate::say;
use anyhow::Result;
use pma_bench::{run_single_until, Sample};
use pma_control::ControllerKind;
use pma_exo::setup::{SingleArgs, SingleRun};
use pma_loop::step::SeedSpread;
use std::path::PathBuf;

/// Estimated wall time of one bench period (release build, with margin).
const BENCH_PERIOD_S: f64 = 1e-6;

/// `single`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Controller (default: the gain file's with `--gains`, else aprc-ndo).
    #[arg(long, value_name = ControllerKind::NAMES)]
    controller: Option<ControllerKind>,
    /// Reference trajectory.
    #[arg(long, value_enum, default_value = "sine")]
    reference: RefName,
    /// Plant preset (ideal, mismatch, realistic, realistic_known_lag) or a plant .toml file.
    #[arg(long, default_value = "ideal")]
    plant: String,
    /// Simulated seconds.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    duration: f64,
    /// Gain file (TOML) for the controller.
    #[arg(long)]
    gains: Option<PathBuf>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
    /// Run again at half the integration step (twice `substeps_per_period`) and say how
    /// much the figures moved (`docs/convergence.md`).
    #[arg(long)]
    check_step: bool,
    /// Also run with the sensor noise's next N - 1 seeds (N 2 to 100) and report each
    /// figure's mean, standard deviation and range over the N runs; with --check-step at
    /// both steps, and whether the step's move stands out of the seeds' scatter (a loop
    /// that chatters has no single-run figure to converge). Needs a plant with noise.
    #[arg(long, value_name = "N")]
    seeds: Option<u32>,
    #[command(flatten)]
    output: RunOutput,
}

/// Most runs of `--seeds`.
const SEEDS_MAX: u32 = 100;

/// Each figure over runs that differ only in the sensor noise's seed.
struct SeedRuns {
    first_seed: u64,
    /// MAE, RTE, RMS.
    spreads: [SeedSpread; 3],
}

impl SeedRuns {
    /// `r` on `plant` with the sensor seeds `plant`'s, its next, ... (`n` runs); `None` if
    /// the operator stopped them.
    fn run(
        r: &SingleRun,
        plant: &pma_bench::PlantConfig,
        n: u32,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<Option<Self>> {
        let mut figures = [vec![], vec![], vec![]];
        for k in 0..n {
            let mut p = plant.clone();
            p.sensor.seed = plant.sensor.seed.wrapping_add(u64::from(k));
            let res =
                run_single_until(&r.config, &p, r.reference.as_ref(), &r.spec, stop, &mut ())?;
            if res.interrupted {
                return Ok(None);
            }
            r.check_finite(&res)?;
            let s = res.stats;
            for (f, v) in figures.iter_mut().zip([s.mae_m, s.rte_percent, s.rms_m]) {
                f.push(v);
            }
        }
        let spread =
            |v: &[f64]| SeedSpread::of(v).ok_or_else(|| anyhow::anyhow!("--seeds: no run"));
        Ok(Some(Self {
            first_seed: plant.sensor.seed,
            spreads: [
                spread(&figures[0])?,
                spread(&figures[1])?,
                spread(&figures[2])?,
            ],
        }))
    }

    fn json(&self, against: Option<&SeedRuns>) -> serde_json::Value {
        let figure = |s: &SeedSpread| serde_json::json!({"mean": s.mean, "sd": s.sd, "min": s.min, "max": s.max});
        let [mae, rte, rms] = &self.spreads;
        let mut v = serde_json::json!({
            "n": mae.n,
            "first_seed": self.first_seed,
            "mae_m": figure(mae),
            "rte_percent": figure(rte),
            "rms_m": figure(rms),
        });
        if let Some(first) = against {
            let within = |i: usize| first.spreads[i].within_scatter(&self.spreads[i]);
            v["within_scatter"] =
                serde_json::json!({"mae": within(0), "rte": within(1), "rms": within(2)});
        }
        v
    }

    fn line(&self, what: &str, against: Option<&SeedRuns>) -> String {
        let [mae, rte, _] = &self.spreads;
        let verdict = against.map_or(String::new(), |first| {
            let within = first.spreads[1].within_scatter(rte);
            format!(
                ": the mean RTE moved {:+.1} %, {} the seeds' scatter (2 standard errors: {:.3} %)",
                100.0 * (rte.mean - first.spreads[1].mean) / first.spreads[1].mean,
                if within { "within" } else { "beyond" },
                2.0 * first.spreads[1].difference_error(rte)
            )
        });
        format!(
            "  {what} over {} seeds ({}..={}): MAE {:.3e} +- {:.1e} m ({:.3e}..{:.3e}), RTE {:.3} +- {:.3} % ({:.3}..{:.3}){verdict}",
            mae.n,
            self.first_seed,
            self.first_seed.wrapping_add(mae.n as u64 - 1),
            mae.mean,
            mae.sd,
            mae.min,
            mae.max,
            rte.mean,
            rte.sd,
            rte.min,
            rte.max
        )
    }
}

/// The run's figures again at half the step, and how far each moved.
struct StepCheck {
    substeps: u32,
    stats: pma_control::TrackingStats,
    moved: [f64; 3],
}

impl StepCheck {
    /// The run of `r` again with twice its substeps (`None`: stopped by the operator).
    fn run(
        r: &SingleRun,
        first: &pma_bench::RunResult,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<Option<Self>> {
        let mut plant = r.plant.clone();
        plant.substeps_per_period *= 2;
        let res = run_single_until(
            &r.config,
            &plant,
            r.reference.as_ref(),
            &r.spec,
            stop,
            &mut (),
        )?;
        if res.interrupted {
            return Ok(None);
        }
        r.check_finite(&res)?;
        let (a, b) = (first.stats, res.stats);
        let rel = pma_loop::step::relative_move;
        Ok(Some(Self {
            substeps: plant.substeps_per_period,
            stats: b,
            moved: [
                rel(a.mae_m, b.mae_m),
                rel(a.rte_percent, b.rte_percent),
                rel(a.rms_m, b.rms_m),
            ],
        }))
    }

    fn converged(&self) -> bool {
        pma_loop::step::converged(self.moved)
    }

    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "substeps_per_period": self.substeps,
            "mae_m": self.stats.mae_m,
            "rte_percent": self.stats.rte_percent,
            "rms_m": self.stats.rms_m,
            "moved": {"mae": self.moved[0], "rte": self.moved[1], "rms": self.moved[2]},
            "tolerance": pma_loop::step::STEP_TOLERANCE,
            "converged": self.converged(),
        })
    }

    fn line(&self) -> String {
        format!(
            "  at half the step ({} substeps): MAE {:.3e} m ({:+.1} %), RTE {:.3} % ({:+.1} %), RMS {:.3e} m ({:+.1} %): {}",
            self.substeps,
            self.stats.mae_m,
            100.0 * self.moved[0],
            self.stats.rte_percent,
            100.0 * self.moved[1],
            self.stats.rms_m,
            100.0 * self.moved[2],
            super::step_verdict(self.converged())
        )
    }
}

/// Runs `single`.
pub fn run(a: Args) -> Result<i32> {
    let r = SingleRun::assemble(&SingleArgs {
        plant: &a.plant,
        controller: a.controller,
        gains: a.gains.as_deref(),
        reference: a.reference,
        duration_s: a.duration,
    })?;
    let (plant, kind, spec) = (&r.plant, r.kind, &r.spec);
    if a.check_step && plant.substeps_per_period > 500 {
        anyhow::bail!(
            "--check-step doubles the plant's substeps_per_period ({}), which allows at most 1000",
            plant.substeps_per_period
        );
    }
    let provenance = Provenance {
        plant: Some(crate::provenance::named(&a.plant, &plant.name)),
        controller: Some(kind.as_str().to_owned()),
        gains: Some(
            a.gains
                .as_ref()
                .map_or("default".to_owned(), |g| g.display().to_string()),
        ),
        seeds: if plant.sensor.noise_rms_m > 0.0 {
            Seeds::of("sensor noise", plant.sensor.seed)
        } else {
            Seeds::default()
        },
        ..Provenance::of_this_run()
    };
    if let Some(n) = a.seeds {
        if !(2..=SEEDS_MAX).contains(&n) {
            anyhow::bail!("--seeds {n} is invalid: 2 to {SEEDS_MAX} runs");
        }
        if plant.sensor.noise_rms_m <= 0.0 {
            anyhow::bail!(
                "--seeds: plant `{}` has no sensor noise, so every seed gives the same run (a longer --duration is the statistic there)",
                plant.name
            );
        }
    }
    // The check costs about twice a run (twice the substeps); every seed as much again.
    let per_setting = 1.0 + f64::from(a.seeds.unwrap_or(0));
    let runs = per_setting * if a.check_step { 3.0 } else { 1.0 };
    output::check_wall_time(
        "this run",
        runs * spec.periods()? as f64,
        BENCH_PERIOD_S,
        a.yes,
    )?;
    let mut inputs = Vec::new();
    if let Some(p) = output::input_file(&a.plant) {
        inputs.push(("plant file", p));
    }
    if let Some(g) = &a.gains {
        inputs.push(("gain file", g.as_path()));
    }
    output::refuse_input_as_output(&inputs, &a.output.files())?;
    let csv = a
        .output
        .csv
        .as_deref()
        .map(|p| SampleCsv::create(p, &Sample::schema(), Sample::of, &provenance))
        .transpose()?;
    let meta = format!(
        "# single muscle\n\n{}\n\ncontroller `{}`, reference `{}`, plant `{}`\n\n{}",
        provenance.line(),
        kind,
        r.ref_name,
        plant.name,
        super::gains_block(&r.config)
    );
    let viz = viz::bench(&a.output.rerun, "pma-exo single", spec.period_s, &meta)?;
    let stop = output::stop_flag()?;
    let mut recorders = (csv, viz);
    let res = run_single_until(
        &r.config,
        plant,
        r.reference.as_ref(),
        spec,
        &stop,
        &mut recorders,
    )?;
    let (csv, viz) = recorders;
    if let Some(c) = csv {
        c.finish()?;
    }
    // The results are printed even if the viewer failed; its error comes after them.
    let viz_result = viz::finish(viz);
    r.check_finite(&res)?;
    let s = res.stats;
    let ran_s = r.ran_s(&res);
    let check = match a.check_step && !res.interrupted {
        true => StepCheck::run(&r, &res, &stop)?,
        false => None,
    };
    let seeds = match a.seeds.filter(|_| !res.interrupted) {
        Some(n) => SeedRuns::run(&r, plant, n, &stop)?,
        None => None,
    };
    let refined_seeds = match (a.seeds, &check, &seeds) {
        (Some(n), Some(_), Some(_)) => {
            let mut refined = plant.clone();
            refined.substeps_per_period *= 2;
            SeedRuns::run(&r, &refined, n, &stop)?
        }
        _ => None,
    };
    let stopped = stop.load(std::sync::atomic::Ordering::Relaxed);
    if a.output.json {
        let mut v = r.metrics(&res);
        if let Some(c) = &check {
            v["check_step"] = c.json();
            if let Some(s) = &refined_seeds {
                v["check_step"]["seeds"] = s.json(seeds.as_ref());
            }
        }
        if let Some(s) = &seeds {
            v["seeds"] = s.json(None);
        }
        say!("{}", provenance.attach(&v)?);
    } else {
        say!(
            "{} on {} ({}, {} s): MAE {:.3e} m, IAE {:.3e} m, RTE {:.3} %, RMS {:.3e} m, {:.0}x real time",
            kind,
            plant.name,
            r.ref_name,
            ran_s,
            s.mae_m,
            s.iae_m,
            s.rte_percent,
            s.rms_m,
            res.real_time_factor
        );
        say!(
            "  step {} ms, {} substeps{}",
            1e3 * spec.period_s,
            plant.substeps_per_period,
            if plant.exact_held_pressure_step {
                ", exact where the pressure is held"
            } else {
                ""
            }
        );
        if let Some(c) = &check {
            say!("{}", c.line());
        }
        if let Some(s) = &seeds {
            say!("{}", s.line("at the step", None));
        }
        if let Some(s) = &refined_seeds {
            say!("{}", s.line("at half the step", seeds.as_ref()));
        }
        say!("  ({})", provenance.line());
    }
    viz_result?;
    if res.interrupted {
        eprintln!("interrupted after {ran_s} s: the figures and the CSV cover the run so far");
        return Ok(INTERRUPTED);
    }
    if stopped && (a.check_step || a.seeds.is_some()) {
        eprintln!("interrupted: the first run's figures are complete; the step's check or the seeds' runs were cut short and are not reported");
        return Ok(INTERRUPTED);
    }
    Ok(0)
}
