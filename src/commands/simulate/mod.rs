//! `pma-exo simulate`: the gait-training simulation of the exoskeleton leg.
mod figures;
use super::{viz, RunOutput, SampleCsv};
use crate::output::{self, INTERRUPTED};
use crate::provenance::{Provenance, Seeds};
use crate::say;
use anyhow::Result;
use pma_control::{ControllerConfig, ControllerKind};
pub use pma_exo::setup::patient_name;
use pma_exo::setup::{controller_label, gain_source, LegArgs, LegRun, Mode};
use pma_exo::strides::GaitCycles;
use pma_leg::{LegReport, Scenario, TrainerSample};
use std::path::{Path, PathBuf};

/// Estimated wall time of one leg period (release build, with margin).
pub const LEG_PERIOD_S: f64 = 20e-6;

/// `simulate`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// An embedded scenario (gait_training, gait_realistic, gait_spastic, gait_spasms,
    /// gait_resistive, gait_active, gait_treadmill, gait_treadmill_spastic,
    /// gait_treadmill_unsupported, gait_treadmill_one_leg) or a scenario .toml file.
    #[arg(default_value = "gait_training")]
    scenario: String,
    /// Controller on every muscle (default: APRC-NDO with the scenario's gains).
    #[arg(long, value_name = ControllerKind::NAMES)]
    controller: Option<ControllerKind>,
    /// Gain file of the controller (default: its shipped leg gains, see crates/pma-leg/models/gains).
    #[arg(long, requires = "controller")]
    gains: Option<PathBuf>,
    /// Simulated seconds (default: the scenario's); at least two strides.
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Control mode (default: the scenario's `control.mode`): `position` (each muscle's
    /// controller tracks the reference), `impedance` (each joint a spring about the
    /// reference by co-contraction, `[control.impedance]`), `path` (a tunnel around the
    /// reference's path, `[control.path]`) or `transparent`; the last three run no
    /// --controller.
    #[arg(
        long = "mode",
        value_name = "position|impedance|admittance|path|transparent"
    )]
    control_mode: Option<Mode>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
    /// Run a treadmill scenario even if one servo-driven stride asks the joints more than
    /// 5 times the adults' moments (a belt or support its gait data does not fit: refused
    /// otherwise, before anything runs).
    #[arg(long)]
    allow_unfit: bool,
    /// Run again at half the physics step (twice `physics_substeps`) and say how much each
    /// joint's tracking figures moved (`docs/convergence.md`).
    #[arg(long)]
    check_step: bool,
    /// Draw the run into this directory: `leg.png` over time (angles over their references,
    /// tracking errors, patient torques, pressures and forces against their limits, spasms
    /// shaded; on a treadmill the ground reaction and the pelvis's height too; a long run's
    /// last four strides) and `strides.png` over the gait cycle (every leg's joints and
    /// tracking errors, on a treadmill each foot's ground reaction against the norm).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    output: RunOutput,
}

impl Default for Args {
    /// `pma-exo` without a subcommand: the default scenario.
    fn default() -> Self {
        Self {
            scenario: "gait_training".into(),
            controller: None,
            gains: None,
            duration: None,
            control_mode: None,
            yes: false,
            allow_unfit: false,
            check_step: false,
            plot: None,
            output: RunOutput::default(),
        }
    }
}

/// Runs `simulate`: loads the scenario and checks every output first, runs the loop with
/// its recorders, then draws the figures and reports.
pub fn run(a: Args) -> Result<i32> {
    let LegRun {
        loaded,
        duration_s: _,
        config,
        mut sim,
        settings,
        periods,
    } = LegRun::assemble(&leg_args(&a))?;
    let sc = &loaded.scenario;
    // The check's run is built before anything runs: a scenario at the substeps' bound is
    // refused here, not after the first run.
    let refined = a
        .check_step
        .then(|| {
            // The same scenario: its fit to the gait data was checked for the first run.
            let args = LegArgs {
                allow_unfit: true,
                ..leg_args(&a)
            };
            LegRun::assemble_at_substeps(&args, 2)
        })
        .transpose()?;
    let provenance = Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &sc.name)),
        controller: Some(controller_label(&loaded, &config)),
        gains: Some(gain_source(a.controller, a.gains.as_deref(), &loaded)),
        patient: Some(patient_name(&loaded)),
        valve: Some(sc.plant.valve_label()?),
        seeds: Seeds::of_scenario(sc),
        ..Provenance::of_this_run()
    };
    // The check costs about twice the run (twice the physics steps).
    let runs = if a.check_step { 3.0 } else { 1.0 };
    output::check_wall_time(
        "this simulation",
        runs * periods as f64,
        LEG_PERIOD_S,
        a.yes,
    )?;
    let names = sim.plant().muscle_names();
    let plot_files = a
        .plot
        .as_ref()
        .map(|dir| PlotFiles::in_dir(dir, sim.leg_count()));
    check_outputs(&a, &loaded, plot_files.as_ref())?;
    let csv = a
        .output
        .csv
        .as_deref()
        .map(|p| {
            let schema =
                TrainerSample::schema(&names, sim.leg_count(), sim.exo().ground().is_some());
            SampleCsv::create(p, &schema, TrainerSample::of, &provenance)
        })
        .transpose()?;
    let viz = viz::leg(&a.output.rerun, &sim, &rerun_meta(sc, &provenance, &config))?;
    let progress = super::Progress::new(periods);
    let bar = progress.bar.clone();
    let (trace, cycles, norm) = plot_recorders(a.plot.as_deref(), &sim, sc, periods)?;
    let stop = output::stop_flag()?;
    let settings = settings.with_stop_flag(&stop);
    let mut recorders = (csv, viz, progress, trace, cycles);
    let outcome = sim.run_until_fault(&settings, &mut recorders);
    bar.finish_and_clear();
    // A run that left physical bounds names the scenario it ran, as a load error does.
    let (mut report, fault) = outcome.map_err(|e| pma_exo::setup::in_scenario(e, &a.scenario))?;
    // A supervisor's fault fails the run; a collapse the trainer stopped is its result.
    if let Some(f) = fault.as_ref().filter(|f| f.name != "collapse") {
        let e = pma_leg::LegError::Supervisor(f.message.clone());
        return Err(pma_exo::setup::in_scenario(e, &a.scenario).into());
    }
    if let Some(refined) = refined.filter(|_| !report.interrupted) {
        report.check_step = check_step(refined, &report, &stop, &a.scenario)?;
    }
    let (csv, viz, _, trace, cycles) = recorders;
    if let (Some(files), Some(trace), Some(cycles)) = (&plot_files, trace, cycles) {
        let run = FigureRun {
            sim: &sim,
            sc,
            config: &config,
            report: &report,
            command: &provenance.command,
            names,
        };
        draw_figures(&run, files, trace, &cycles, norm)?;
    }
    let non_finite =
        (!report.finite).then(|| format!("the simulation (scenario {})", report.scenario));
    super::conclude(
        (csv, viz),
        &report,
        &provenance,
        non_finite,
        a.output.json,
        print_summary,
    )?;
    Ok(exit_status(&report))
}

/// `simulate`'s arguments as the library takes them.
fn leg_args(a: &Args) -> LegArgs<'_> {
    LegArgs {
        scenario: &a.scenario,
        controller: a.controller,
        gains: a.gains.as_deref(),
        duration_s: a.duration,
        mode: a.control_mode,
        allow_unfit: a.allow_unfit,
    }
}

/// The run again on `refined` (its physics step halved), against `first`'s figures;
/// `None` if the operator stopped it.
fn check_step(
    refined: LegRun,
    first: &LegReport,
    stop: &std::sync::atomic::AtomicBool,
    scenario: &str,
) -> Result<Option<pma_leg::metrics::StepCheckReport>> {
    let LegRun {
        loaded,
        mut sim,
        settings,
        ..
    } = refined;
    let settings = settings.with_stop_flag(stop);
    let in_file = |e| pma_exo::setup::in_scenario(e, scenario);
    let (report, fault) = sim.run_until_fault(&settings, &mut ()).map_err(in_file)?;
    if let Some(f) = fault.as_ref().filter(|f| f.name != "collapse") {
        let e = pma_leg::LegError::Supervisor(format!("at half the step: {}", f.message));
        return Err(in_file(e).into());
    }
    if report.interrupted {
        return Ok(None);
    }
    Ok(Some(pma_leg::metrics::StepCheckReport::of(
        first,
        &report,
        loaded.scenario.physics_substeps,
    )))
}

/// Every output path checked before anything runs: none of them is one of the run's inputs.
fn check_outputs(
    a: &Args,
    loaded: &pma_leg::LoadedScenario,
    plot_files: Option<&PlotFiles>,
) -> Result<()> {
    let mut outputs = a.output.files();
    if let Some(files) = plot_files {
        outputs.extend(files.legs.iter().map(|leg| ("--plot", leg.as_path())));
        outputs.push(("--plot", &files.strides));
    }
    output::refuse_input_as_output(
        &super::scenario_inputs(&a.scenario, loaded, a.gains.as_deref()),
        &outputs,
    )?;
    if let Some(dir) = &a.plot {
        output::create_dir(dir)?;
    }
    Ok(())
}

/// What the Rerun recording says about the run, in its description.
fn rerun_meta(sc: &Scenario, provenance: &Provenance, config: &ControllerConfig) -> String {
    format!(
        "# {}\n\n{}\n\n{}\n\ngait `{}` at a {} s stride; co-contraction {} bar; {} gains (mode {}):\n\n{}",
        sc.name,
        provenance.line(),
        sc.description,
        sc.gait.speed_label(),
        sc.gait.stride_period_s,
        sc.control.cocontraction_pa / 1e5,
        config.kind(),
        sc.control.mode,
        super::gains_block(config)
    )
}

/// The recorders `--plot` needs (none without it): every 10th period over time, the
/// periods after the first stride over the gait cycle, and the adults' ground reaction.
fn plot_recorders(
    plot: Option<&Path>,
    sim: &pma_leg::LegSim,
    sc: &Scenario,
    periods: u64,
) -> Result<(Option<Trace>, Option<GaitCycles>, Option<figures::NormGrf>)> {
    if plot.is_none() {
        return Ok((None, None, None));
    }
    let mut trace = Trace::with_capacity(periods, sim.leg_count());
    if let Some(g) = sim.exo().ground() {
        let n = (periods / 10 + 2) as usize;
        trace.0[0].ground = Some(crate::plot::GroundTrace {
            foot_n: (0..sim.leg_count())
                .map(|_| Vec::with_capacity(n))
                .collect(),
            other_leg_n: Vec::with_capacity(n),
            pelvis_m: Vec::with_capacity(n),
            unsupported_n: g.unsupported_weight_n(),
        });
    }
    // The same samples as the report's tracking figures: after the first stride.
    let cycles = GaitCycles::new(sim, sc.gait.stride_period_s)?;
    // The weight the belt carries, in the patient's body weights: what one foot's ground
    // reaction is compared with (the device's weight included, as on the belt).
    let belt_load_bw = sim
        .exo()
        .ground()
        .map(|g| g.unsupported_weight_n() / (g.settings().body_mass_kg * pma_model::GRAVITY_M_S2));
    Ok((Some(trace), Some(cycles), norm_grf(sc, belt_load_bw)?))
}

/// What the figures of a finished run are drawn from.
struct FigureRun<'a> {
    sim: &'a pma_leg::LegSim,
    sc: &'a Scenario,
    config: &'a ControllerConfig,
    report: &'a LegReport,
    command: &'a str,
    names: Vec<String>,
}

/// Where `--plot DIR` draws: one figure over time per leg (`leg.png` the first, the right
/// leg of a trainer; `leg_left.png` its left: issue 49 found the left leg drawn nowhere)
/// and `strides.png`.
struct PlotFiles {
    legs: Vec<PathBuf>,
    strides: PathBuf,
}

impl PlotFiles {
    fn in_dir(dir: &Path, legs: usize) -> Self {
        let names = ["leg.png", "leg_left.png"];
        Self {
            legs: names.iter().take(legs).map(|n| dir.join(n)).collect(),
            strides: dir.join("strides.png"),
        }
    }
}

/// Leg `leg`'s spasms of `report` as `leg.png` shades them: joint (0 hip, 1 knee), onset
/// and end.
fn spasms_of_leg(report: &LegReport, leg: usize, legs: usize) -> Vec<(usize, f64, f64)> {
    let left = |e: &&pma_leg::metrics::SpasmReport| e.joint.starts_with("left/");
    report
        .spasms
        .iter()
        .filter(|e| legs < 2 || left(e) == (leg == 1))
        .map(|e| {
            (
                usize::from(e.joint.ends_with("knee")),
                e.t_s,
                e.t_s + e.duration_s,
            )
        })
        .collect()
}

/// Every `leg*.png` and `strides.png` of `run`, committed together.
fn draw_figures(
    run: &FigureRun,
    files: &PlotFiles,
    mut trace: Trace,
    cycles: &GaitCycles,
    norm: Option<figures::NormGrf>,
) -> Result<()> {
    let (sc, sim, report) = (run.sc, run.sim, run.report);
    let legs = sim.leg_count();
    // One mark for the four: the lowest rating, which every force is held against.
    let rated_force_n = sim
        .muscles()
        .iter()
        .map(|m| m.rated_force_n)
        .fold(f64::INFINITY, f64::min);
    // Both legs stood on the same ground: its panels are drawn beside each.
    let ground = trace.0[0].ground.clone();
    let collapse_s = report
        .walking
        .as_ref()
        .and_then(|w| w.collapse.as_ref())
        .map(|c| c.t_s);
    for (leg, tr) in trace.0.iter_mut().enumerate() {
        tr.collapse_s = collapse_s;
        tr.muscles.clone_from(&run.names);
        tr.legs = legs;
        tr.stride_s = sc.gait.stride_period_s;
        tr.pressure_max_bar = sc.plant.valve.pressure_max_pa / 1e5;
        tr.rated_force_n = rated_force_n;
        tr.spasms = spasms_of_leg(report, leg, legs);
        tr.ground.clone_from(&ground);
    }
    crate::plot::register_font()?;
    let title = figure_title(sc, run.config);
    let mut staged = Vec::new();
    for (leg, (path, tr)) in files.legs.iter().zip(&trace.0).enumerate() {
        let leg_title = if legs > 1 {
            format!("{title} ({} leg)", pma_leg::SIDES[leg])
        } else {
            title.clone()
        };
        let file = output::stage(path, |tmp| {
            figures::leg_run(tmp, &leg_title, run.command, tr)
        })?;
        staged.push((file, path));
    }
    let figure = figures::StrideFigure {
        cycles,
        norm_grf: norm,
        treadmill: sc.treadmill.is_some(),
    };
    let title = format!("{title}, over the gait cycle");
    let strides = output::stage(&files.strides, |tmp| {
        figures::strides_run(tmp, &title, run.command, &figure)
    })?;
    staged.push((strides, &files.strides));
    // Every figure, or none: an earlier run's set is never left half replaced.
    for (file, path) in staged {
        file.commit()?;
        output::wrote(path);
    }
    Ok(())
}

/// The figures' title: the scenario and what drove the muscles.
fn figure_title(sc: &Scenario, config: &ControllerConfig) -> String {
    match sc.control.mode {
        pma_leg::ControlMode::Position => {
            format!("{}: {} on every muscle", sc.name, config.kind())
        }
        pma_leg::ControlMode::Admittance => {
            format!(
                "{}: {} on every muscle, admittance mode",
                sc.name,
                config.kind()
            )
        }
        mode => format!("{}: {mode} mode, no muscle controller", sc.name),
    }
}

/// The exit status of a finished run: interrupted, did not walk, a muscle over its
/// rating in the air, or 0 (each said on stderr).
fn exit_status(report: &LegReport) -> i32 {
    if report.interrupted {
        eprintln!(
            "interrupted after {} s: the figures and the CSV cover the run so far",
            report.duration_s
        );
        return INTERRUPTED;
    }
    match &report.walking {
        Some(v) if !v.walking => {
            eprintln!("{}", v.line());
            DID_NOT_WALK
        }
        // On the treadmill the rating is one of the walking criteria; in the air it is the
        // run's own verdict.
        Some(_) => 0,
        None => over_rating_line(report).map_or(0, |line| {
            eprintln!("{line}");
            OVER_RATING
        }),
    }
}

/// Exit status of a treadmill run that completed but in which the patient did not walk
/// (a collapse the trainer stopped, or a criterion of `pma_leg::verdict` missed).
pub const DID_NOT_WALK: i32 = 4;

/// Exit status of an in-air run that completed with a muscle pulled past its rating (the
/// treadmill's verdict holds the same criterion, [`DID_NOT_WALK`]).
pub const OVER_RATING: i32 = 5;

/// The one line an in-air run ends with when a muscle went over its rating (the same
/// bound as the treadmill's walking criterion).
fn over_rating_line(report: &LegReport) -> Option<String> {
    let max = pma_leg::WalkingCriteria::default().force_over_rating_max;
    let over = report.safety.over_rating(max);
    (!over.is_empty()).then(|| {
        format!(
            "{} muscle(s) over their rating (peak force above {max}x the rated force): {}",
            over.len(),
            over.join(", ")
        )
    })
}

/// The adult data's vertical ground reaction at the scenario's speed, scaled by the
/// body-weight support, for a treadmill on the adult reference (Fukuchi et al. 2018).
/// The adults' vertical ground reaction scaled to the belt's load (`belt_load_bw`: `(1 -
/// support)` times the patient's and the device's weight, in the patient's body weights),
/// so that it compares like with like with the run's feet, which carry the device too.
fn norm_grf(sc: &Scenario, belt_load_bw: Option<f64>) -> Result<Option<figures::NormGrf>> {
    let (Some(t), Some(norms), Some(load)) = (
        &sc.treadmill,
        pma_exo::setup::adult_norms(sc)?,
        belt_load_bw,
    ) else {
        return Ok(None);
    };
    let scaled = |v: &[f64]| v.iter().map(|x| x * load).collect();
    Ok(Some(figures::NormGrf {
        mean_bw: scaled(&norms.curves.grf_vertical_bw),
        sd_bw: scaled(&norms.sd.grf_vertical_bw),
        label: format!(
            "adults' mean (Fukuchi 2018, {:.2} m/s, {} subjects) x the belt's load, {load:.3} BW ((1 - {:.2} support) x patient and device)",
            norms.speed_m_s, norms.subjects, t.bws_fraction
        ),
    }))
}

/// Every 10th period of a leg run, for `--plot`: one trace per leg (the ground's side in
/// the first).
pub struct Trace(pub Vec<crate::plot::LegTrace>);

impl Trace {
    /// Room for a run of `periods` periods of `legs` legs.
    pub fn with_capacity(periods: u64, legs: usize) -> Self {
        let n = (periods / 10 + 2) as usize;
        let v = || Vec::with_capacity(n);
        let leg = || crate::plot::LegTrace {
            t_s: v(),
            reference_deg: [v(), v()],
            angle_deg: [v(), v()],
            pressure_bar: [v(), v(), v(), v()],
            force_n: [v(), v(), v(), v()],
            patient_nm: [v(), v()],
            interaction_nm: [v(), v()],
            cuff_force_n: [v(), v()],
            ..Default::default()
        };
        Self((0..legs.max(1)).map(|_| leg()).collect())
    }
}

impl pma_loop::Recorder<pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>> for Trace {
    /// Every 10th period: each leg's joints and muscles, every foot's ground reaction.
    fn record(
        &mut self,
        p: &pma_loop::Period<'_, pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>>,
    ) {
        if !p.index.is_multiple_of(10) {
            return;
        }
        for ((s, o), t) in p.truth.legs.iter().zip(p.output.iter()).zip(&mut self.0) {
            t.t_s.push(p.t_s);
            for (j, torque) in s.patient.total().into_iter().enumerate() {
                t.reference_deg[j].push(o.reference_rad[j].to_degrees());
                t.angle_deg[j].push(s.angle_rad[j].to_degrees());
                t.patient_nm[j].push(torque);
                t.interaction_nm[j].push(s.interaction_nm[j]);
                t.cuff_force_n[j].push(s.cuff_force_n[j]);
            }
            for (i, (p, f)) in s.pressure_pa.iter().zip(&s.force_n).enumerate() {
                t.pressure_bar[i].push(p / 1e5);
                t.force_n[i].push(*f);
            }
        }
        let t = &mut self.0[0];
        if let (Some(g), Some(r)) = (&mut t.ground, p.truth.ground) {
            for (foot, f) in g.foot_n.iter_mut().zip(r.feet.iter()) {
                foot.push(f.vertical_n);
            }
            g.other_leg_n.push(r.contralateral_n);
            g.pelvis_m.push(p.truth.pelvis_m.map_or(f64::NAN, |p| p[1]));
        }
    }
}

fn print_summary(r: &LegReport) -> Result<()> {
    say!(
        "{} ({} s simulated, {:.0}x real time)",
        r.scenario,
        r.duration_s,
        r.real_time_factor
    );
    for (name, j) in &r.joints {
        let s = &j.per_stride;
        say!(
            "  {name:5} tracking error after the first stride: RMS {} deg, max {} deg; per stride ({}): RMS median {}, 90th percentile {}, worst {} deg",
            fig(j.rms_deg, 3),
            fig(j.max_deg, 3),
            s.strides,
            fig(s.median_deg, 3),
            fig(s.p90_deg, 3),
            fig(s.max_deg, 3)
        );
    }
    for (name, m) in &r.muscles {
        say!(
            "  {name:13} pressure {:.2}..{:.2} bar, slack {:.3} s",
            m.p_min_pa / 1e5,
            m.p_max_pa / 1e5,
            m.slack_s
        );
    }
    say!(
        "  co-contraction (mean pressure): {} bar in the second stride, {} bar in the last; command variation {} bar/s",
        fig(r.cocontraction_pa.start / 1e5, 3),
        fig(r.cocontraction_pa.end / 1e5, 3),
        fig(r.command_variation_bar_per_s, 1)
    );
    print_step(r)?;
    print_patient(r)?;
    if let Some(t) = &r.treadmill {
        print_treadmill(t)?;
    }
    print_safety(&r.safety)?;
    match &r.walking {
        Some(v) => print_verdict(v)?,
        None => match over_rating_line(r) {
            Some(line) => say!("  rating: EXCEEDED, {line}"),
            None => say!("  rating: every muscle within its rating"),
        },
    }
    Ok(())
}

/// The step the figures were computed at and, with `--check-step`, how far they moved.
fn print_step(r: &LegReport) -> Result<()> {
    if let Some(s) = &r.step {
        say!(
            "  step: {} ms control period, {} physics substeps ({} ms){}",
            1e3 * s.period_s,
            s.physics_substeps,
            1e3 * s.physics_step_s,
            if s.implicit_muscle_damping {
                ", implicit muscle damping"
            } else {
                ""
            }
        );
    }
    if let Some(c) = &r.check_step {
        let moved: Vec<String> = c
            .joints
            .iter()
            .map(|(name, j)| {
                format!(
                    "{name} RMS {} deg ({:+.1} %), max {} deg ({:+.1} %)",
                    fig(j.rms_deg, 3),
                    100.0 * j.moved_rms,
                    fig(j.max_deg, 3),
                    100.0 * j.moved_max
                )
            })
            .collect();
        say!(
            "  at half the step ({} substeps): {}: {}",
            c.physics_substeps,
            moved.join(", "),
            super::step_verdict(c.converged)
        );
    }
    Ok(())
}

/// `value` with `decimals`, `-` where the run could not give it.
fn fig(value: f64, decimals: usize) -> String {
    pma_leg::metrics::figure(value, decimals)
}

/// The treadmill run's verdict: walked, or each criterion it missed.
fn print_verdict(v: &pma_leg::WalkingVerdict) -> Result<()> {
    if v.walking {
        say!(
            "  walking: yes (every foot at least {} strides, stance RMS within {} deg, belt load within {:.0} %, every muscle within {}x its rating)",
            v.strides_expected,
            v.criteria.stance_rms_max_deg,
            100.0 * v.criteria.belt_load_tolerance,
            v.criteria.force_over_rating_max
        );
    } else {
        say!("  walking: NO");
        for r in &v.reasons {
            say!("    - {r}");
        }
    }
    Ok(())
}

/// The treadmill's figures: the belt's load, the harness, then each foot's phases, ground
/// reaction, slip and heel strikes.
fn print_treadmill(t: &pma_leg::TreadmillReport) -> Result<()> {
    say!(
        "  treadmill: {} leg(s), belt {} m/s, body-weight support {:.0} % (a {} m patient, body weight BW = {:.0} N; the system weighs {:.2} BW); the belt carries {} BW on average (a virtual other leg {} BW) against {:.3} BW expected",
        t.legs,
        fig(t.belt_speed_m_s, 3),
        100.0 * t.bws_fraction,
        fig(t.height_m, 2),
        t.body_weight_n,
        t.system_weight_bw,
        fig(t.mean_belt_load_bw, 3),
        fig(t.mean_other_leg_bw, 3),
        t.expected_belt_load_bw
    );
    say!(
        "    pelvis: vertical excursion {} mm, fore-aft {} mm; the harness holds it fore-aft with {} N on average ({}..{})",
        fig(1e3 * t.pelvis_excursion_m, 1),
        fig(1e3 * t.pelvis_fore_aft_excursion_m, 1),
        fig(t.harness_fore_aft_n.mean, 0),
        fig(t.harness_fore_aft_n.min, 0),
        fig(t.harness_fore_aft_n.max, 0)
    );
    for (side, f) in &t.feet {
        say!(
            "    {side} foot: {} strides, {} scuffs in swing; vertical GRF loading peak {} BW ({}..{}), loading rate {} BW/s ({}..{}), mean {} BW; stance {} % ({}..{}) against the reference's {:.1} %; slip {} mm per stride; deepest {:.1} mm; ankle {}..{} deg",
            f.strides,
            f.scuffs,
            fig(f.peak_grf_bw.mean, 2),
            fig(f.peak_grf_bw.min, 2),
            fig(f.peak_grf_bw.max, 2),
            fig(f.loading_rate_bw_s.mean, 1),
            fig(f.loading_rate_bw_s.min, 1),
            fig(f.loading_rate_bw_s.max, 1),
            fig(f.mean_grf_bw, 3),
            fig(100.0 * f.stance_fraction.mean, 1),
            fig(100.0 * f.stance_fraction.min, 1),
            fig(100.0 * f.stance_fraction.max, 1),
            100.0 * f.reference_stance_fraction,
            fig(1e3 * f.slip_per_stride_m.mean, 1),
            f.max_penetration_mm,
            fig(f.ankle_range_deg[0], 1),
            fig(f.ankle_range_deg[1], 1)
        );
        for (joint, p) in &f.tracking {
            let Some(h) = f.heel_strikes.get(joint) else {
                continue;
            };
            say!(
                "      {joint:5} RMS error in stance {} deg, in swing {} deg; {} heel strikes: deviation {} deg (max {}), back within 1 deg after {} s (max {}; {} not within {} s), pressure rate up to {:.0} bar/s",
                fig(p.stance_rms_deg, 3),
                fig(p.swing_rms_deg, 3),
                h.count,
                fig(h.deviation_deg.mean, 2),
                fig(h.deviation_deg.max, 2),
                fig(h.recovery_s.mean, 3),
                fig(h.recovery_s.max, 3),
                h.not_recovered,
                pma_leg::metrics::HEEL_STRIKE_FOLLOW_S,
                h.peak_pressure_rate_bar_s
            );
        }
    }
    Ok(())
}

/// The patient's torques and one line per spasm (nothing for a passive limb).
fn print_patient(r: &LegReport) -> Result<()> {
    let p = &r.patient.joints;
    if p.values().all(|j| j.torque_peak_nm == 0.0) {
        return Ok(());
    }
    let each: Vec<String> = p
        .iter()
        .map(|(joint, j)| {
            format!(
                "{joint} RMS {:.2} N m (peak {:.1})",
                j.torque_rms_nm, j.torque_peak_nm
            )
        })
        .collect();
    say!("  patient torque: {}", each.join(", "));
    if let Some(e) = r.spasms.first() {
        say!(
            "  spasms (deviation and joint speed {}):",
            if e.against_baseline {
                "beyond the same run without the spasms"
            } else {
                "absolute: no baseline run"
            }
        );
    }
    for e in &r.spasms {
        let recovery = match e.recovery_s {
            Some(s) => format!("back within 1 deg {s:.2} s after its end"),
            None if e.overlapped => format!(
                "overlapped by the next {} spasm at {:.2} s",
                e.joint, e.followed_until_s
            ),
            None => format!("not back within 1 deg by {:.2} s", e.followed_until_s),
        };
        say!(
            "    at {:7.2} s: {:4} {} {:.1} N m for {:.2} s -> deviation {:.2} deg, joint speed {:.0} deg/s, pressure rate {:.0} bar/s, {recovery}",
            e.t_s,
            e.joint,
            e.direction,
            e.amplitude_nm,
            e.duration_s,
            e.peak_deviation_deg,
            e.peak_joint_speed_deg_s,
            e.peak_pressure_rate_bar_s
        );
    }
    Ok(())
}

/// Joint limits, muscle forces against their rating, valve saturation.
fn print_safety(s: &pma_leg::SafetyReport) -> Result<()> {
    let limits: Vec<String> = s
        .joints
        .iter()
        .map(|(j, l)| {
            format!(
                "{j} {:.3} s (max {:.2} deg)",
                l.time_outside_s, l.max_beyond_deg
            )
        })
        .collect();
    say!("  beyond the URDF limits: {}", limits.join(", "));
    let normal: Vec<String> = s
        .joints
        .iter()
        .map(|(j, l)| {
            format!(
                "{j} {:.3} s ({:+.1} deg)",
                l.time_beyond_normal_range_s, l.beyond_normal_range_deg
            )
        })
        .collect();
    say!(
        "  beyond the normal range of motion (AAOS; negative: the margin left): {}",
        normal.join(", ")
    );
    for (name, m) in &s.muscles {
        // Said only where a force limit ([control] force_max_of_rating) lowered a command.
        let limited = if m.force_limited_s > 0.0 {
            format!(", command at its force limit {:.2} s", m.force_limited_s)
        } else {
            String::new()
        };
        say!(
            "  {name:13} peak force {:.0} N = {:.2}x its {:.0} N rating ({}; {:.3} s above it, margin {:.0} N), valve at a limit {:.2} s, peak pressure rate {:.0} bar/s{limited}",
            m.peak_force_n,
            m.peak_over_rated,
            m.rated_force_n,
            m.rating,
            m.time_over_rated_s,
            m.margin_n,
            m.valve_saturated_s,
            m.peak_pressure_rate_bar_s
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regression_strides_png_compared_the_feet_with_the_adults_without_the_device() {
        // The feet carry the device as well as the patient: the belt's load on
        // gait_treadmill is 0.859 of the patient's weight, and the adults' curve scaled by
        // (1 - support) alone carried 0.70 of it. Scaled to the belt's load, the two feet's
        // mean ground reaction over a stride is the belt's load again.
        let loaded = Scenario::load("gait_treadmill").expect("embedded");
        let sim = pma_leg::LegSim::new(&loaded).expect("builds");
        let ground = sim.exo().ground().expect("a treadmill");
        let load_bw = ground.unsupported_weight_n()
            / (ground.settings().body_mass_kg * pma_model::GRAVITY_M_S2);
        assert!((load_bw - 0.859).abs() < 0.001, "{load_bw}");
        let norm = norm_grf(&loaded.scenario, Some(load_bw))
            .expect("norms")
            .expect("a treadmill on the adults' data");
        let mean = norm.mean_bw.iter().sum::<f64>() / norm.mean_bw.len() as f64;
        let carried = 2.0 * mean / load_bw;
        assert!(
            (carried - 1.0).abs() < 0.05,
            "two feet carry {carried} of the belt's load"
        );
        assert!(norm.label.contains("0.859 BW"), "{}", norm.label);
    }
}
