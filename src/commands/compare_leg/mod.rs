//! `pma-exo compare-leg`: APRC-NDO, PSMC, NDO-SMC, STA and PID, each with its gains tuned
//! on `gait_training` by the same search and budget, on the patient scenarios.
mod figure;
use crate::output::OutFile;
use crate::say;
use anyhow::Result;
use pma_control::{ControllerConfig, ControllerKind};
use pma_leg::Scenario;
use pma_studies::compare::{compare, CompareRow};
use std::fmt::Write as _;
use std::path::PathBuf;

/// The controllers compared, each with the scenario's gains for it (`pma_leg::scenario::scenario_gains`).
pub const COMPARED: [ControllerKind; 5] = [
    ControllerKind::AprcNdo,
    ControllerKind::Psmc,
    ControllerKind::NdoSmc,
    ControllerKind::Sta,
    ControllerKind::Pid,
];

/// The scenarios compared by default: the passive baseline and the three patients.
pub const SCENARIOS: [&str; 4] = [
    "gait_training",
    "gait_spastic",
    "gait_spasms",
    "gait_resistive",
];

/// `compare-leg`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Output directory (compare-leg.json, compare-leg.md, compare-leg.png).
    #[arg(long, default_value = "compare-leg-out")]
    out: PathBuf,
    /// Scenarios, comma-separated (embedded names or .toml files).
    #[arg(long, value_delimiter = ',', default_values_t = SCENARIOS.map(String::from))]
    scenarios: Vec<String>,
    /// Control modes, comma-separated: `position` runs every controller; `impedance`,
    /// `path` and `transparent` add one row each (the pairs set by pressure, no muscle
    /// controller).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "position",
        value_name = "position,impedance,path,transparent,admittance"
    )]
    modes: Vec<pma_exo::setup::Mode>,
    /// Simulated seconds per run; at least two strides.
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    duration: f64,
    /// Worker threads (default: one per core); the results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// Runs `compare-leg`.
pub fn run(a: Args) -> Result<i32> {
    super::check_duration(a.duration)?;
    for (i, m) in a.modes.iter().enumerate() {
        if a.modes[..i].contains(m) {
            anyhow::bail!("--modes: `{}` is given twice", m.control_mode());
        }
    }
    let scenarios = a
        .scenarios
        .iter()
        .map(|s| Scenario::load(s))
        .collect::<Result<Vec<_>, _>>()?;
    for s in &scenarios {
        s.scenario.check_run_duration(a.duration)?;
    }
    let cases = cases(&a.scenarios, &scenarios, &a.modes)?;
    let runs: usize = cases.iter().map(|c| c.configs.len()).sum();
    let periods = cases
        .iter()
        .map(|c| c.configs.len() as f64 * a.duration / c.loaded.scenario.period_s)
        .sum::<f64>();
    super::check_leg_comparison(periods, a.yes)?;
    let mut inputs = Vec::new();
    for (arg, loaded) in a.scenarios.iter().zip(&scenarios) {
        inputs.extend(super::scenario_inputs(arg, loaded, None));
    }
    let outputs = ["compare-leg.json", "compare-leg.md", "compare-leg.png"].map(|f| a.out.join(f));
    crate::output::refuse_input_as_output(
        &inputs,
        &outputs
            .iter()
            .map(|p| ("--out", p.as_path()))
            .collect::<Vec<_>>(),
    )?;
    let created = !a.out.is_dir();
    crate::output::create_dir(&a.out)?;
    let json_file = OutFile::create(&a.out.join("compare-leg.json"))?;
    let md_file = OutFile::create(&a.out.join("compare-leg.md"))?;
    static DONE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let bar = crate::output::follow_progress(&DONE, runs as u64, "runs");
    let loaded: Vec<pma_leg::LoadedScenario> = cases.iter().map(|c| c.loaded.clone()).collect();
    let configs: Vec<Vec<ControllerConfig>> = cases.iter().map(|c| c.configs.clone()).collect();
    let stop = crate::output::stop_flag()?;
    let mut rows = super::with_threads(a.threads, || {
        compare(&loaded, &configs, a.duration, Some(&DONE), &stop)
    })??;
    drop(bar);
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        // The staged files are dropped unwritten: nothing of a partial comparison is kept,
        // and a directory this command made is removed with them.
        drop((json_file, md_file));
        if created {
            std::fs::remove_dir(&a.out).ok();
        }
        eprintln!("interrupted: nothing written (a comparison of runs cut short compares nothing)");
        return Ok(crate::output::INTERRUPTED);
    }
    // Each scenario as the command line names it (two files may carry one inner name),
    // each row by its controller or its mode. The rows come case by case, a row per
    // configuration.
    let labels = cases
        .iter()
        .flat_map(|c| c.labels.iter().map(move |l| (c.scenario, l)));
    for (row, (scenario, label)) in rows.iter_mut().zip(labels) {
        row.scenario.clone_from(scenario);
        row.controller.clone_from(label);
    }
    let provenance = crate::provenance::Provenance {
        scenario: Some(
            a.scenarios
                .iter()
                .zip(&scenarios)
                .map(|(arg, s)| crate::provenance::named(arg, &s.scenario.name))
                .collect::<Vec<_>>()
                .join(", "),
        ),
        controller: Some(compared(&a.modes)),
        gains: Some(gain_sets(&a.scenarios, &scenarios)),
        patient: Some("each scenario's".into()),
        ..crate::provenance::Provenance::of_this_run()
    };
    let md = format!("{}\n_{}_\n", report(&rows, a.duration), provenance.line());
    let json = serde_json::json!({ "provenance": provenance, "rows": rows });
    json_file.finish_with(&serde_json::to_string_pretty(&json)?)?;
    md_file.finish_with(&md)?;
    draw_bars(&a.out, &rows, &provenance.command)?;
    say!("{md}");
    say!(
        "wrote {}/compare-leg.json, compare-leg.md and compare-leg.png",
        a.out.display()
    );
    if let Some(r) = rows.iter().find(|r| !r.finite) {
        anyhow::bail!("{} on {} went non-finite", r.controller, r.scenario);
    }
    Ok(0)
}

/// `compare-leg.png`: per scenario (x) and controller (bars), the tracking, the spasms'
/// largest deviation and the valves' activity.
fn draw_bars(dir: &std::path::Path, rows: &[CompareRow], command: &str) -> Result<()> {
    let mut groups: Vec<String> = Vec::new();
    let mut members: Vec<String> = Vec::new();
    for r in rows {
        if !groups.contains(&r.scenario) {
            groups.push(r.scenario.clone());
        }
        if !members.contains(&r.controller) {
            members.push(r.controller.clone());
        }
    }
    let table = |f: &dyn Fn(&CompareRow) -> f64| -> Vec<Vec<f64>> {
        groups
            .iter()
            .map(|g| {
                members
                    .iter()
                    .map(|m| {
                        rows.iter()
                            .find(|r| &r.scenario == g && &r.controller == m)
                            .map_or(f64::NAN, f)
                    })
                    .collect()
            })
            .collect()
    };
    let ground = |f: fn(&pma_studies::compare::TreadmillRow) -> f64| {
        table(&move |r: &CompareRow| r.treadmill.as_ref().map_or(f64::NAN, f))
    };
    // A panel with nothing to show is left out (regression, issue 26: an empty spasm
    // panel with garbled ticks on the treadmill scenarios, which have no spasms).
    let panels: Vec<figure::BarPanel> = [
        ("hip RMS error (deg)", table(&|r| r.hip_rms_deg)),
        ("knee RMS error (deg)", table(&|r| r.knee_rms_deg)),
        (
            "largest spasm deviation (deg)",
            table(&|r| r.spasm_max_deviation_deg.unwrap_or(f64::NAN)),
        ),
        (
            "command variation (bar/s)",
            table(&|r| r.command_variation_bar_per_s),
        ),
        (
            "peak muscle force / rating",
            table(&|r| r.peak_force_over_rated),
        ),
        (
            "largest heel-strike deviation, hip|knee (deg)",
            ground(|t| t.heel_strike_max_deviation_deg[0].max(t.heel_strike_max_deviation_deg[1])),
        ),
        ("vertical GRF loading peak (BW)", ground(|t| t.peak_grf_bw)),
        (
            "foot slip on the belt (mm per stride)",
            ground(|t| t.slip_per_stride_m * 1e3),
        ),
    ]
    .into_iter()
    .filter(|(_, values)| values.iter().flatten().any(|v| v.is_finite()))
    .map(|(y, values)| figure::BarPanel {
        y_desc: y.to_owned(),
        values,
    })
    .collect();
    crate::plot::register_font()?;
    let path = dir.join("compare-leg.png");
    let title = match rows.iter().filter(|r| r.treadmill.is_some()).count() {
        0 => "Controllers on the leg in the air, per scenario",
        n if n == rows.len() => "Controllers on the trainer's treadmill, per scenario",
        _ => "Controllers on the leg, per scenario (in the air and on the treadmill)",
    };
    crate::output::write_via_temp(&path, |tmp| {
        figure::grouped_bars(tmp, title, command, &groups, &members, &panels)
    })
}

/// Which shipped gain set each scenario's controllers took (APRC-NDO: the scenario's own).
/// A scenario under one mode: the runs it takes and their rows' labels.
struct Case<'a> {
    /// The scenario as the command line names it.
    scenario: &'a String,
    /// The scenario, its mode set.
    loaded: pma_leg::LoadedScenario,
    /// One run per configuration (a pressure-set mode's one runs no muscle controller).
    configs: Vec<ControllerConfig>,
    /// Each run's row label: the controller, or the mode.
    labels: Vec<String>,
}

/// Every scenario under every mode, in that order.
fn cases<'a>(
    args: &'a [String],
    scenarios: &[pma_leg::LoadedScenario],
    modes: &[pma_exo::setup::Mode],
) -> Result<Vec<Case<'a>>> {
    let mut out = Vec::new();
    for (arg, s) in args.iter().zip(scenarios) {
        for &mode in modes {
            let mut loaded = s.clone();
            loaded.scenario.control.mode = mode.control_mode();
            let kinds: &[ControllerKind] = if mode.control_mode().runs_muscle_controllers() {
                &COMPARED
            } else {
                &[ControllerKind::AprcNdo]
            };
            let configs = kinds
                .iter()
                .map(|k| pma_leg::scenario::scenario_gains(&loaded, *k))
                .collect::<Result<Vec<_>, _>>()?;
            let labels = match mode {
                pma_exo::setup::Mode::Position => kinds.iter().map(|k| k.to_string()).collect(),
                pma_exo::setup::Mode::Admittance => {
                    kinds.iter().map(|k| format!("{k}, admittance")).collect()
                }
                _ => vec![format!("{} mode", mode.control_mode())],
            };
            out.push(Case {
                scenario: arg,
                loaded,
                configs,
                labels,
            });
        }
    }
    Ok(out)
}

/// What ran, for the provenance: the controllers in position mode, and the other modes.
fn compared(modes: &[pma_exo::setup::Mode]) -> String {
    let controllers = || COMPARED.iter().map(|k| k.as_str().to_owned());
    let mut what = Vec::new();
    for m in modes {
        match m {
            pma_exo::setup::Mode::Position => what.extend(controllers()),
            pma_exo::setup::Mode::Admittance => {
                what.extend(controllers().map(|k| format!("{k} in admittance mode")));
            }
            _ => what.push(format!("{} mode", m.control_mode())),
        }
    }
    what.join(",")
}

fn gain_sets(args: &[String], scenarios: &[pma_leg::LoadedScenario]) -> String {
    let each: Vec<String> = args
        .iter()
        .zip(scenarios)
        .map(|(arg, s)| {
            let set = s.scenario.control.gain_set;
            format!("{arg}: {} set ({})", set.as_str(), set.directory())
        })
        .collect();
    format!(
        "APRC-NDO the scenario's own, the others {}",
        each.join(", ")
    )
}

/// One Markdown table per scenario, and on a treadmill a second one of its gait phases.
pub fn report(rows: &[CompareRow], duration_s: f64) -> String {
    let mut md = format!(
        "# Controllers on the leg with a patient ({duration_s} s per run, each scenario's gain set, tuned with the same budget)\n"
    );
    let mut scenarios: Vec<&str> = Vec::new();
    for r in rows {
        if !scenarios.contains(&r.scenario.as_str()) {
            scenarios.push(&r.scenario);
        }
    }
    for scenario in scenarios {
        let of_it: Vec<&CompareRow> = rows.iter().filter(|r| r.scenario == scenario).collect();
        let _ = write!(
            md,
            "\n## {scenario}\n\n| controller | hip RMS (deg) | knee RMS (deg) | spasms | spasm deviation mean / max (deg) | worst recovery (s) | not recovered / overlapped | peak dp/dt in spasms (bar/s) | peak dp/dt (bar/s) | command variation (bar/s) | peak force / rating | above rating (s) | valve at a limit (s) | beyond limits (s) | beyond normal range (s) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
        );
        for r in &of_it {
            let _ = writeln!(md, "{}", patient_row(r));
        }
        if of_it.iter().any(|r| r.treadmill.is_some()) {
            let _ = write!(
                md,
                "\nOn the treadmill:\n\n| controller | hip RMS stance / swing (deg) | knee RMS stance / swing (deg) | GRF loading peak (BW) | loading rate (BW/s) | stance (reference) | slip per stride (mm) | scuffs per stride | heel-strike deviation hip / knee, max (deg) | recovery hip / knee, max (s) | not recovered hip / knee | walked |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n"
            );
            for r in &of_it {
                if let Some(t) = &r.treadmill {
                    let _ = writeln!(md, "{}", treadmill_row(&r.controller, t));
                }
            }
        }
    }
    md
}

/// A run's row of tracking, spasms and safety.
fn patient_row(r: &CompareRow) -> String {
    // `-` where there is nothing to show (no spasm, none recovered), never a 0.
    let or_dash = |v: Option<f64>, digits: usize| {
        v.map_or_else(|| "-".to_owned(), |x| format!("{x:.digits$}"))
    };
    format!(
        "| {} | {:.3} | {:.3} | {} | {} / {} | {} | {} / {} | {} | {:.0} | {:.1} | {:.2} | {:.3} | {:.2} | {:.3} | {:.3} |",
        r.controller,
        r.hip_rms_deg,
        r.knee_rms_deg,
        r.spasms,
        or_dash(r.spasm_mean_deviation_deg, 2),
        or_dash(r.spasm_max_deviation_deg, 2),
        or_dash(r.spasm_max_recovery_s, 2),
        r.spasms_unrecovered,
        r.spasms_overlapped,
        or_dash(r.spasm_peak_pressure_rate_bar_s, 0),
        r.peak_pressure_rate_bar_s,
        r.command_variation_bar_per_s,
        r.peak_force_over_rated,
        r.time_over_rated_s,
        r.valve_saturated_s,
        r.time_outside_limits_s,
        r.time_beyond_normal_range_s
    )
}

/// A run's row of gait phases on the treadmill.
fn treadmill_row(controller: &str, t: &pma_studies::compare::TreadmillRow) -> String {
    let f = pma_leg::metrics::figure;
    let pair = |v: [f64; 2], digits: usize| format!("{} / {}", f(v[0], digits), f(v[1], digits));
    format!(
        "| {controller} | {} | {} | {} | {} | {} ({}) | {} | {} | {} | {} | {} / {} | {} |",
        pair(t.hip_stance_swing_rms_deg, 3),
        pair(t.knee_stance_swing_rms_deg, 3),
        // A run without a counted stride has no loading, stance or slip: "-", never NaN.
        f(t.peak_grf_bw, 2),
        f(t.loading_rate_bw_s, 1),
        f(t.stance_fraction[0], 3),
        f(t.stance_fraction[1], 3),
        f(1e3 * t.slip_per_stride_m, 1),
        f(t.scuffs_per_stride, 2),
        pair(t.heel_strike_max_deviation_deg, 2),
        pair(t.heel_strike_max_recovery_s, 3),
        t.heel_strikes_unrecovered[0],
        t.heel_strikes_unrecovered[1],
        match (t.walking, t.collapse_s) {
            (true, _) => "yes".to_owned(),
            (false, Some(at)) => format!("no: collapse at {at:.2} s"),
            (false, None) => "no".to_owned(),
        }
    )
}
