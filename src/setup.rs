//! The runs of `single`, `simulate` and `pendulum` assembled from their arguments, shared by
//! the command line and the Python bindings (`crates/pma-py`): both check the same
//! arguments in the same order, load the same files and build the same simulation, so a
//! run from Python gives the CLI's figures and the CLI's one-line errors.
use anyhow::{bail, Context, Result};
use pma_bench::{PlantConfig, RunResult, RunSpec};
use pma_control::{ChirpReference, ControllerConfig, ControllerKind, Reference, SineReference};
use pma_leg::patient::{SpasticityPreset, SpasticitySettings};
use pma_leg::scenario::PHYSICS_SUBSTEPS_MAX;
use pma_leg::{ControlMode, LegSim, LoadedScenario, Scenario};
use pma_loop::LoopSettings;
use pma_studies::pendulum::PendulumSetup;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// The reference trajectories of the bench.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum RefName {
    /// A = 15 mm, f = 0.25 Hz, B = 15 mm.
    Sine,
    /// 0.1 -> 0.5 Hz linearly in 20 s, A = B = 15 mm.
    Chirp,
}

impl RefName {
    /// Name and trajectory.
    pub fn build(self) -> (&'static str, Box<dyn Reference>) {
        match self {
            RefName::Sine => ("sine", Box::new(SineReference::paper())),
            RefName::Chirp => ("chirp", Box::new(ChirpReference::paper())),
        }
    }
}

/// Rejects a duration that is not a finite number of seconds > 0.
pub fn check_duration(duration: f64) -> Result<()> {
    if !(duration.is_finite() && duration > 0.0) {
        bail!("--duration must be a finite number of seconds > 0 (got {duration})");
    }
    Ok(())
}

/// The controller of a gain file, or `default` without one: for `--gains` given without
/// `--controller`, the file says which controller it is.
pub fn kind_of_gains(path: Option<&Path>, default: ControllerKind) -> Result<ControllerKind> {
    let Some(path) = path else {
        return Ok(default);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read gain file `{}`", path.display()))?;
    Ok(ControllerConfig::from_toml_str(&text)
        .with_context(|| format!("gain file `{}`", path.display()))?
        .kind())
}

/// The gains of `kind`: its defaults, or a gain file (an APRC-NDO file may drive APRC, the
/// ablation, and the other way round).
pub fn load_gains(kind: ControllerKind, path: Option<&Path>) -> Result<ControllerConfig> {
    let Some(path) = path else {
        return Ok(kind.default_config());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read gain file `{}`", path.display()))?;
    let cfg = ControllerConfig::from_toml_str(&text)
        .with_context(|| format!("gain file `{}`", path.display()))?;
    let compatible = cfg.kind() == kind
        || matches!(
            (cfg.kind(), kind),
            (ControllerKind::AprcNdo, ControllerKind::Aprc)
                | (ControllerKind::Aprc, ControllerKind::AprcNdo)
        );
    if !compatible {
        return Err(pma_control::ConfigError::WrongController {
            requested: kind,
            found: cfg.kind(),
        })
        .with_context(|| format!("gain file `{}`", path.display()));
    }
    Ok(match (cfg, kind) {
        (ControllerConfig::AprcNdo(g), ControllerKind::Aprc) => ControllerConfig::Aprc(g),
        (ControllerConfig::Aprc(g), ControllerKind::AprcNdo) => ControllerConfig::AprcNdo(g),
        (c, _) => c,
    })
}

/// What `single` is asked to run.
#[derive(Clone, Copy)]
pub struct SingleArgs<'a> {
    /// Plant preset or plant file.
    pub plant: &'a str,
    /// Controller (`None`: the gain file's, else APRC-NDO).
    pub controller: Option<ControllerKind>,
    /// Gain file.
    pub gains: Option<&'a Path>,
    /// Reference trajectory.
    pub reference: RefName,
    /// Simulated seconds.
    pub duration_s: f64,
}

/// A `single` run, assembled and checked: plant, controller, reference and run length.
pub struct SingleRun {
    /// The plant.
    pub plant: PlantConfig,
    /// The controller.
    pub kind: ControllerKind,
    /// Its gains.
    pub config: ControllerConfig,
    /// The reference's name (`sine`, `chirp`).
    pub ref_name: &'static str,
    /// The reference.
    pub reference: Box<dyn Reference>,
    /// Duration and period, validated.
    pub spec: RunSpec,
}

impl SingleRun {
    /// Checks the arguments and loads the plant and gains, in the CLI's order.
    pub fn assemble(a: &SingleArgs<'_>) -> Result<Self> {
        check_duration(a.duration_s)?;
        let plant = PlantConfig::load(a.plant)?;
        let kind = match a.controller {
            Some(k) => k,
            None => kind_of_gains(a.gains, ControllerKind::AprcNdo)?,
        };
        let config = load_gains(kind, a.gains)?;
        let (ref_name, reference) = a.reference.build();
        let spec = RunSpec {
            duration_s: a.duration_s,
            ..RunSpec::default()
        };
        spec.validate()?;
        Ok(Self {
            plant,
            kind,
            config,
            ref_name,
            reference,
            spec,
        })
    }

    /// A finished run's result: an error if it went non-finite.
    pub fn check_finite(&self, res: &RunResult) -> Result<()> {
        if !res.finite {
            bail!(
                "the run went non-finite (controller {}, plant {})",
                self.kind,
                self.plant.name
            );
        }
        Ok(())
    }

    /// How long the run covered (s): the duration asked for, or the periods run before an
    /// interruption.
    pub fn ran_s(&self, res: &RunResult) -> f64 {
        if res.interrupted {
            res.periods as f64 * self.spec.period_s
        } else {
            self.spec.duration_s
        }
    }

    /// The figures of a run, as `single --json` prints them (before the provenance).
    pub fn metrics(&self, res: &RunResult) -> serde_json::Value {
        let s = res.stats;
        serde_json::json!({
            "controller": self.kind.as_str(),
            "reference": self.ref_name,
            "plant": self.plant.name,
            "duration_s": self.ran_s(res),
            "step": {
                "period_s": self.spec.period_s,
                "substeps_per_period": self.plant.substeps_per_period,
                "integration_step_s": self.spec.period_s / f64::from(self.plant.substeps_per_period),
                "exact_held_pressure_step": self.plant.exact_held_pressure_step,
            },
            "mae_m": s.mae_m,
            "iae_m": s.iae_m,
            "rte_percent": s.rte_percent,
            "rms_m": s.rms_m,
            "x_a_m": res.x_a_m,
            "command_variation_bar_per_s": res.command_variation_pa_per_s / 1e5,
            "samples": s.samples,
            "real_time_factor": res.real_time_factor,
            "interrupted": res.interrupted,
        })
    }
}

/// What `simulate` is asked to run.
#[derive(Clone, Copy)]
pub struct LegArgs<'a> {
    /// Embedded scenario name or scenario file.
    pub scenario: &'a str,
    /// Controller on every muscle (`None`: APRC-NDO with the scenario's gains).
    pub controller: Option<ControllerKind>,
    /// Gain file.
    pub gains: Option<&'a Path>,
    /// Simulated seconds (`None`: the scenario's).
    pub duration_s: Option<f64>,
    /// Control mode (`None`: the scenario's).
    pub mode: Option<Mode>,
    /// Run a treadmill whose servo-driven stride asks more than
    /// [`pma_leg::tools::DEMAND_OVER_NORM_MAX`] times the adults' moments (refused
    /// otherwise).
    pub allow_unfit: bool,
}

/// A control mode on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Robot in charge: each muscle's controller tracks its length along the reference.
    Position,
    /// Each joint a spring and damper about the reference by co-contraction
    /// (`[control.impedance]`).
    Impedance,
    /// Free inside a tunnel around the reference's path, a wall outside, support along it
    /// (`[control.path]`).
    Path,
    /// Patient in charge: only the device's own weight and the muscles' damping
    /// compensated.
    Transparent,
    /// Each joint a spring and damper about the reference by the muscles' own controllers
    /// tracking a reference the cuff torque displaces (`[control.impedance]`).
    Admittance,
}

impl Mode {
    /// The scenario's mode it selects.
    pub fn control_mode(self) -> ControlMode {
        match self {
            Mode::Position => ControlMode::Position,
            Mode::Impedance => ControlMode::Impedance,
            Mode::Path => ControlMode::Path,
            Mode::Transparent => ControlMode::Transparent,
            Mode::Admittance => ControlMode::Admittance,
        }
    }
}

/// Sets `loaded`'s control mode to `mode` (if given) and refuses a muscle controller in a
/// mode that runs none.
pub fn apply_mode(
    loaded: &mut LoadedScenario,
    mode: Option<Mode>,
    controller: Option<ControllerKind>,
) -> Result<()> {
    if let Some(m) = mode {
        loaded.scenario.control.mode = m.control_mode();
    }
    let mode = loaded.scenario.control.mode;
    if let (false, Some(k)) = (mode.runs_muscle_controllers(), controller) {
        bail!(
            "--controller {}: {mode} mode sets each pair's pressures through the valves' own pressure loops and runs no muscle controller; use --mode position to run one",
            k.as_str()
        );
    }
    Ok(())
}

/// A `simulate` run, assembled and checked: the scenario, the controllers, the simulation
/// built and the loop's length.
pub struct LegRun {
    /// The scenario and the files it came from.
    pub loaded: LoadedScenario,
    /// Simulated seconds.
    pub duration_s: f64,
    /// The controller of every muscle.
    pub config: ControllerConfig,
    /// The simulation, at rest.
    pub sim: LegSim,
    /// The loop's settings (no stop flag yet).
    pub settings: LoopSettings<'static>,
    /// Control periods of the run.
    pub periods: u64,
}

/// `e`, a leg that could not be built from scenario `arg`, naming the scenario's file where
/// the error does not already name a file.
pub fn in_scenario(e: pma_leg::LegError, arg: &str) -> pma_leg::LegError {
    use pma_leg::LegError as E;
    match e {
        E::Parse { .. } | E::InFile { .. } | E::Io { .. } | E::Urdf { .. } => e,
        _ if arg.ends_with(".toml") => e.in_file(arg),
        _ => e.in_file(&format!("{arg} (embedded scenario)")),
    }
}

impl LegRun {
    /// Checks the arguments, loads the scenario and gains and builds the simulation, in
    /// the CLI's order.
    pub fn assemble(a: &LegArgs<'_>) -> Result<Self> {
        Self::assemble_at_substeps(a, 1)
    }

    /// As [`LegRun::assemble`], with the scenario's physics substeps multiplied by
    /// `factor` (`simulate --check-step`: 2), within their bound.
    pub fn assemble_at_substeps(a: &LegArgs<'_>, factor: u32) -> Result<Self> {
        let mut loaded = Scenario::load(a.scenario)?;
        apply_mode(&mut loaded, a.mode, a.controller)?;
        if factor != 1 {
            let n = loaded.scenario.physics_substeps;
            loaded.scenario.physics_substeps = n.saturating_mul(factor);
            if loaded.scenario.physics_substeps > PHYSICS_SUBSTEPS_MAX {
                bail!(
                    "{}: --check-step takes physics_substeps from {n} to {}, over its bound of {PHYSICS_SUBSTEPS_MAX}",
                    a.scenario,
                    loaded.scenario.physics_substeps
                );
            }
        }
        let sc = &loaded.scenario;
        let duration_s = a.duration_s.unwrap_or(sc.duration_s);
        check_duration(duration_s)?;
        sc.check_run_duration(duration_s)?;
        let config = leg_config(a.controller, a.gains, &loaded)?;
        if !a.allow_unfit {
            check_fits_its_data(&loaded, a.scenario)?;
        }
        // What the scenario sets but only a built leg checks (its modes, cuffs, patient)
        // names the scenario's file as the checks at load do.
        let sim =
            LegSim::with_controller(&loaded, &config).map_err(|e| in_scenario(e, a.scenario))?;
        let settings = sim.settings(duration_s)?;
        let periods = settings.periods(sc.period_s)?;
        Ok(Self {
            loaded,
            duration_s,
            config,
            sim,
            settings,
            periods,
        })
    }
}

/// A treadmill on the adults' data must ask its joints what walking at that speed asks:
/// one servo-driven stride (as `size` measures) whose peak demand is more than
/// [`pma_leg::tools::DEMAND_OVER_NORM_MAX`] times the adults' peak moment means a belt
/// speed or support the reference does not fit, on which the trainer cannot walk; refused
/// before anything runs, in one line.
fn check_fits_its_data(loaded: &LoadedScenario, scenario: &str) -> Result<()> {
    match unfit_reason(loaded)? {
        None => Ok(()),
        Some((true, why)) => bail!("{scenario}: {why}; `pma-exo size {scenario} --closed-loop-s 0` shows the demand (--allow-unfit runs it)"),
        Some((false, why)) => bail!("{scenario}: {why}; `pma-exo size {scenario}` recommends muscles for this patient (--allow-unfit runs it)"),
    }
}

/// Why a treadmill on the adults' data cannot walk, found by one servo-driven stride
/// before it runs: `(true, why)` where the stride asks more than
/// [`pma_leg::tools::DEMAND_OVER_NORM_MAX`] times the adults' moments (the scenario does
/// not fit its data), `(false, why)` where the scenario's own muscles cannot drive it;
/// `None` if neither (or not a treadmill on the adults' data).
pub fn unfit_reason(loaded: &LoadedScenario) -> Result<Option<(bool, String)>> {
    let sc = &loaded.scenario;
    let (Some(_), Some(adults)) = (&sc.treadmill, adult_norms(sc)?) else {
        return Ok(None);
    };
    let demand = pma_leg::tools::stride_demand(loaded, 1)?;
    if let Some(why) = beyond_norms(&norm_comparison(sc, &demand, &adults)) {
        return Ok(Some((true, why)));
    }
    Ok(fitted_muscles_short(loaded, &demand).map(|why| (false, why)))
}

/// Why the scenario's own muscles cannot drive its servo-driven stride (over their rating,
/// beyond their stroke or the valve's pressure), said in one line; `None` if they can.
/// Issue 47: a 95 kg patient ran the muscles sized for 75 kg to 1.14 times their rating
/// and nothing said so before the run.
fn fitted_muscles_short(
    loaded: &LoadedScenario,
    demand: &pma_leg::tools::Demand,
) -> Option<String> {
    let sc = &loaded.scenario;
    let pairs = pma_leg::tools::fitted_pairs(
        demand,
        &loaded.muscles,
        sc.control.cocontraction_pa,
        sc.plant.valve.pressure_max_pa,
    );
    let why = pairs.iter().find_map(pma_leg::tools::FittedPair::why_not)?;
    let patient = sc.treadmill.as_ref().map_or_else(String::new, |t| {
        format!(
            " of a {:.0} kg patient at {:.0} % support",
            t.body_mass_kg,
            100.0 * t.bws_fraction
        )
    });
    Some(format!("on the servo-driven stride{patient} {why}"))
}

/// What drives the muscles of a run, as outputs name it: the controller, or the mode that
/// runs none.
pub fn controller_label(loaded: &LoadedScenario, config: &ControllerConfig) -> String {
    match loaded.scenario.control.mode {
        ControlMode::Position => config.kind().as_str().to_owned(),
        ControlMode::Admittance => format!("{} in admittance mode", config.kind().as_str()),
        mode => format!("none: {mode} mode, the pairs set by pressure"),
    }
}

/// Where `leg_config`'s gains come from: a gain file, the scenario's APRC-NDO gains (those
/// its patient's support selects, `control.gains_below_support`), or its gain set's.
pub fn gain_source(
    kind: Option<ControllerKind>,
    gains: Option<&Path>,
    loaded: &LoadedScenario,
) -> String {
    let sc = &loaded.scenario;
    let scenario = |what: &str| match sc.control.scheduled_at(sc.support()) {
        Some(s) => format!(
            "scenario ({what}, control.gains_below_support: the support is below {})",
            pma_model::error::number(s.support_fraction)
        ),
        None => format!("scenario ({what})"),
    };
    match (kind, gains) {
        (_, Some(path)) => path.display().to_string(),
        (None | Some(ControllerKind::AprcNdo), None) => scenario("APRC-NDO"),
        (Some(ControllerKind::Aprc), None) => scenario("APRC-NDO's, observer off"),
        (Some(_), None) => format!(
            "shipped {} gains ({})",
            sc.control.gain_set.as_str(),
            sc.control.gain_set.directory()
        ),
    }
}

/// The patient of a scenario, as a name: `passive`, or its parts.
pub fn patient_name(loaded: &LoadedScenario) -> String {
    let p = &loaded.scenario.patient;
    let joint = |j: &pma_leg::patient::JointPatientSettings| {
        let mut parts = Vec::new();
        if let Some(s) = &j.spasticity {
            parts.push(match s.preset {
                Some(preset) => format!("spasticity {preset:?}").to_lowercase(),
                None => "spasticity".into(),
            });
        }
        if j.spasms.is_some() {
            parts.push("spasms".into());
        }
        if j.effort.is_some() {
            parts.push("effort".into());
        }
        if let Some(s) = &j.stiffness {
            parts.push(match s.preset {
                Some(preset) => format!("stiffness {preset:?}").to_lowercase(),
                None => "stiffness".into(),
            });
        }
        if parts.is_empty() {
            "passive".into()
        } else {
            parts.join(" + ")
        }
    };
    let walks = match &p.active {
        Some(a) => {
            let strength = match a.strength_by_leg {
                Some([r, l]) => format!("strength right {r}, left {l}"),
                None => format!("strength {}", a.strength()),
            };
            format!(", walking on their own ({strength})")
        }
        None => String::new(),
    };
    format!("hip {}, knee {}{walks}", joint(&p.hip), joint(&p.knee))
}

/// The controller of every muscle: a gain file, or the scenario's gains for the controller
/// (its own APRC-NDO gains for APRC-NDO, the default, and APRC; its gain set's for the
/// others: `pma_leg::scenario::scenario_gains`). One name, one gain set.
pub fn leg_config(
    kind: Option<ControllerKind>,
    gains: Option<&Path>,
    loaded: &LoadedScenario,
) -> Result<ControllerConfig> {
    Ok(match (kind, gains) {
        // A controller named beside a gain file must be the file's (load_gains refuses
        // another); only without one does the file say which controller runs.
        (Some(k), Some(path)) => load_gains(k, Some(path))?,
        (None, Some(path)) => load_gains(
            kind_of_gains(Some(path), ControllerKind::AprcNdo)?,
            Some(path),
        )?,
        (k, None) => {
            pma_leg::scenario::scenario_gains(loaded, k.unwrap_or(ControllerKind::AprcNdo))?
        }
    })
}

/// A spasticity preset on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Spasticity {
    /// No stretch reflex.
    None,
    /// Extensor reflex gain 1.5 N m s/rad above 2.6 rad/s (flexor half), 60 ms delay.
    Mild,
    /// Gain 3.5 N m s/rad above 1.2 rad/s.
    Moderate,
    /// Gain 7.0 N m s/rad above 0.5 rad/s.
    Severe,
}

impl Spasticity {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Spasticity::None => "none",
            Spasticity::Mild => "mild",
            Spasticity::Moderate => "moderate",
            Spasticity::Severe => "severe",
        }
    }

    fn preset(self) -> SpasticityPreset {
        match self {
            Spasticity::None => SpasticityPreset::None,
            Spasticity::Mild => SpasticityPreset::Mild,
            Spasticity::Moderate => SpasticityPreset::Moderate,
            Spasticity::Severe => SpasticityPreset::Severe,
        }
    }
}

/// What `pendulum` is asked to run.
#[derive(Clone, Copy)]
pub struct PendulumArgs<'a> {
    /// Embedded scenario name or scenario file.
    pub scenario: &'a str,
    /// Knee flexion at release (deg).
    pub knee_deg: f64,
    /// Hip flexion, held (deg).
    pub hip_deg: f64,
    /// Simulated seconds.
    pub duration_s: f64,
    /// A spasticity preset at hip and knee instead of the scenario's.
    pub spasticity: Option<Spasticity>,
}

/// A pendulum test's scenario and setup, checked (before the leg is seated: the CLI
/// checks its outputs in between).
pub struct PendulumRun {
    /// The scenario, with the spasticity asked for.
    pub loaded: LoadedScenario,
    /// Hip and knee at release.
    pub setup: PendulumSetup,
    /// Simulated seconds.
    pub duration_s: f64,
}

impl PendulumRun {
    /// Checks the arguments and loads the scenario, in the CLI's order.
    pub fn load(a: &PendulumArgs<'_>) -> Result<Self> {
        check_duration(a.duration_s)?;
        for (flag, deg) in [("--knee-deg", a.knee_deg), ("--hip-deg", a.hip_deg)] {
            if !deg.is_finite() {
                bail!("{flag} must be a finite angle in degrees (got {deg})");
            }
        }
        let mut loaded = Scenario::load(a.scenario)?;
        if let Some(s) = a.spasticity {
            let preset = SpasticitySettings {
                preset: Some(s.preset()),
                ..SpasticitySettings::default()
            };
            loaded.scenario.patient.hip.spasticity = Some(preset);
            loaded.scenario.patient.knee.spasticity = Some(preset);
        }
        let setup = PendulumSetup {
            hip_rad: a.hip_deg.to_radians(),
            knee_rad: a.knee_deg.to_radians(),
        };
        Ok(Self {
            loaded,
            setup,
            duration_s: a.duration_s,
        })
    }

    /// The leg seated for the test and the loop's settings.
    pub fn seated(&self) -> Result<(LegSim, LoopSettings<'static>)> {
        let sim = pma_studies::pendulum::seated(&self.loaded, self.setup)?;
        let settings = LoopSettings::new(self.duration_s)?;
        settings.periods(self.loaded.scenario.period_s)?;
        Ok((sim, settings))
    }

    /// The knee's damping (N m s/rad), which the samples' torques need.
    pub fn knee_damping_nm_s_per_rad(&self) -> f64 {
        self.loaded.scenario.joints.knee.damping_nm_s_per_rad
    }
}

/// `size`'s arguments.
pub struct SizeArgs {
    /// Strides measured.
    pub strides: usize,
    /// Longest muscle considered (m).
    pub max_length_m: f64,
    /// Share of its rating a recommended muscle keeps free.
    pub force_margin: f64,
    /// Seconds of the closed-loop check of the recommendation (0: none).
    pub closed_loop_s: f64,
}

impl SizeArgs {
    /// Checks every argument but the scenario, before anything runs.
    pub fn check(&self) -> Result<()> {
        if !(self.max_length_m.is_finite() && (0.1..=2.0).contains(&self.max_length_m)) {
            bail!(
                "--max-length-m must be 0.1 to 2 m (the lengths searched; got {})",
                self.max_length_m
            );
        }
        let most = pma_leg::tools::FORCE_MARGIN_MAX;
        if !(self.force_margin.is_finite() && (0.0..=most).contains(&self.force_margin)) {
            bail!(
                "--force-margin must be 0 to {most} (got {})",
                self.force_margin
            );
        }
        if !(1..=50).contains(&self.strides) {
            bail!("--strides must be 1 to 50 (got {})", self.strides);
        }
        let (lo, hi) = (
            pma_leg::tools::CLOSED_LOOP_MIN_S,
            pma_leg::tools::CLOSED_LOOP_MAX_S,
        );
        if !(self.closed_loop_s == 0.0
            || (self.closed_loop_s.is_finite() && (lo..=hi).contains(&self.closed_loop_s)))
        {
            bail!(
                "--closed-loop-s must be 0 (no check) or {lo} to {hi} s (got {})",
                self.closed_loop_s
            );
        }
        Ok(())
    }
}

/// What `size` computes: the servo-driven strides, the sizing and, on the adults' data,
/// the demand beside their moments.
pub struct SizeRun {
    /// The strides' demand.
    pub demand: pma_leg::tools::Demand,
    /// Every joint's designs and the recommendation.
    pub sizing: pma_leg::tools::Sizing,
    /// The demand against the adults' moments (empty off the adults' data).
    pub norms: Vec<pma_leg::tools::NormComparison>,
    /// The adults' loading response beside the feet's (a treadmill on the adults' data).
    pub norm_loading: Option<pma_leg::tools::NormLoading>,
    /// Each closed-loop check, in order: the first of the recommendation made with the
    /// asked margin, the next of each re-sizing (empty without a check).
    pub closed_loop: Vec<pma_leg::tools::ClosedLoop>,
    /// Why no muscles are recommended for this gait, where a joint's demand is over
    /// [`pma_leg::tools::DEMAND_OVER_NORM_MAX`] times the adults' (the scenario does not
    /// fit its data); no closed-loop check runs then.
    pub beyond_norms: Option<String>,
    /// The scenario's own muscles on the same stride, per joint (Festo pairs only).
    pub fitted: Vec<pma_leg::tools::FittedPair>,
}

/// The first joint whose peak demand is beyond [`pma_leg::tools::DEMAND_OVER_NORM_MAX`]
/// times the adults' peak moment, said in one line.
fn beyond_norms(norms: &[pma_leg::tools::NormComparison]) -> Option<String> {
    let most = pma_leg::tools::DEMAND_OVER_NORM_MAX;
    norms.iter().find(|n| n.ratio() > most).map(|n| {
        format!(
            "the {} asks {:.2} N m/kg at its peak, {:.1} times the adults' {:.2} N m/kg (at most {most} times): the scenario does not fit its gait data (a belt speed the reference's stance was not fitted to, or a swing foot dragging on the belt?)",
            n.joint,
            n.peak_demand_nm_kg,
            n.ratio(),
            n.peak_normative_nm_kg
        )
    })
}

/// How much a closed-loop check that does not hold raises the margin of the next sizing
/// (`None`: it holds, or no margin can fix it). Over its allowance: by the controller's
/// share. Not walking (or faulting) under a force limit: by
/// [`pma_leg::tools::FORCE_MARGIN_STEP`], a larger muscle whose limit leaves the
/// controller more force above the servo's stride. Not walking without a limit: no margin
/// fixes it, the controller would take any larger muscle to its cap too.
fn margin_step(check: &pma_leg::tools::ClosedLoop) -> Option<f64> {
    match (check.holds, &check.why_not, check.force_max_of_rating) {
        (true, _, _) => None,
        (false, None, _) => Some(check.controller_share()),
        (false, Some(_), Some(_)) => Some(pma_leg::tools::FORCE_MARGIN_STEP),
        (false, Some(_), None) => None,
    }
}

/// Most closed-loop checks (and re-sizings) of one `size`.
pub const CLOSED_LOOP_ROUNDS: usize = 3;

impl SizeRun {
    /// Drives `loaded`'s legs along its gait and sizes their muscles as `args` say, then
    /// runs the recommendation in closed loop (unless `args.closed_loop_s` is 0): where the
    /// closed loop takes more of the rating than the margin allows, the muscles are sized
    /// again with the margin raised by the controller's share, up to
    /// [`CLOSED_LOOP_ROUNDS`] times. `stop` ends a closed-loop run early.
    pub fn of(loaded: &LoadedScenario, args: &SizeArgs, stop: &AtomicBool) -> Result<Self> {
        let demand = pma_leg::tools::stride_demand(loaded, args.strides)?;
        let adults = adult_norms(&loaded.scenario)?;
        let norms = adults
            .as_ref()
            .map_or_else(Vec::new, |n| norm_comparison(&loaded.scenario, &demand, n));
        let norm_loading = adults
            .as_ref()
            .and_then(|n| norm_loading(&loaded.scenario, n));
        let p_max = loaded.scenario.plant.valve.pressure_max_pa;
        let size =
            |margin: f64| pma_leg::tools::size_joints(&demand, p_max, args.max_length_m, margin);
        let mut sizing = size(args.force_margin);
        let beyond_norms = beyond_norms(&norms);
        let fitted = pma_leg::tools::fitted_pairs(
            &demand,
            &loaded.muscles,
            loaded.scenario.control.cocontraction_pa,
            p_max,
        );
        let mut closed_loop = Vec::new();
        let mut margin = args.force_margin;
        while args.closed_loop_s > 0.0
            && beyond_norms.is_none()
            && closed_loop.len() < CLOSED_LOOP_ROUNDS
        {
            let Some(check) = pma_leg::tools::closed_loop(
                loaded,
                &sizing,
                (args.force_margin, margin),
                args.closed_loop_s,
                stop,
            )?
            else {
                break;
            };
            let step = margin_step(&check);
            closed_loop.push(check);
            let Some(step) = step.filter(|_| !stop.load(Ordering::Relaxed)) else {
                break;
            };
            let raised = (margin + step).min(pma_leg::tools::FORCE_MARGIN_MAX);
            if raised <= margin {
                break;
            }
            margin = raised;
            sizing = size(margin);
        }
        Ok(Self {
            demand,
            sizing,
            norms,
            norm_loading,
            closed_loop,
            beyond_norms,
            fitted,
        })
    }

    /// The last closed-loop check, if any ran, and whether the recommendation holds.
    pub fn closed_loop_holds(&self) -> Option<bool> {
        self.closed_loop.last().map(|c| c.holds)
    }

    pub fn figures(&self) -> serde_json::Map<String, serde_json::Value> {
        let json = serde_json::json!({
            "servo_max_error_deg": self.demand.max_error_deg,
            "servo_raw_torque_range_nm": self.demand.raw_torque_range_nm,
            "against_norms": self.norms,
            "treadmill": self.demand.treadmill,
            "normative_loading": self.norm_loading,
            "sizing": self.sizing,
            "closed_loop": self.closed_loop,
            "beyond_norms": self.beyond_norms,
            "fitted": self.fitted,
        });
        match json {
            serde_json::Value::Object(map) => map,
            _ => serde_json::Map::new(),
        }
    }
}

/// The adult data at the reference's speed, for a scenario on the adults' gait (`None`
/// on another reference).
pub fn adult_norms(sc: &pma_leg::Scenario) -> Result<Option<pma_leg::gait::AdultNorms>> {
    let g = &sc.gait;
    let (pma_leg::gait::GaitData::Fukuchi2018, Some(speed)) = (g.data, g.speed_m_per_s) else {
        return Ok(None);
    };
    Ok(Some(pma_leg::gait::AdultNorms::at(speed)?))
}

/// The demand beside the adults' moments (`norms`).
fn norm_comparison(
    sc: &pma_leg::Scenario,
    demand: &pma_leg::tools::Demand,
    norms: &pma_leg::gait::AdultNorms,
) -> Vec<pma_leg::tools::NormComparison> {
    let (mass, bws) = sc
        .treadmill
        .map_or((75.0, 0.0), |t| (t.body_mass_kg, t.bws_fraction));
    pma_leg::tools::against_norms(demand, norms, mass, bws)
}

/// The adults' loading response (`norms`), for a treadmill scenario.
fn norm_loading(
    sc: &pma_leg::Scenario,
    norms: &pma_leg::gait::AdultNorms,
) -> Option<pma_leg::tools::NormLoading> {
    let t = sc.treadmill.as_ref()?;
    Some(pma_leg::tools::norm_loading(
        norms,
        sc.gait.stride_period_s,
        sc.period_s,
        t.bws_fraction,
    ))
}

/// A rig log for identification: refused if `rig replay` would refuse it (cut short,
/// edited, periods missing) unless `force`; on a virtual rig, each command as the valve
/// received it through the output converter (an ideal valve feels the converter's step,
/// regression of issue 26).
pub fn load_id_log(path: &std::path::Path, force: bool) -> Result<pma_studies::identify::IdLog> {
    let verified = match pma_rig::verify(path) {
        Ok(v) => Some(v),
        Err(_) if force => None,
        Err(e) => {
            return Err(anyhow::Error::new(e)
                .context("identification reads only logs it can trust (--force reads it anyway)"))
        }
    };
    let mut log = pma_studies::identify::read_log(path)?;
    if let Some(v) = verified {
        if let Some(delivered) = pma_rig::delivered_valve_pa(&v.config)? {
            for c in &mut log.command_pa {
                *c = delivered(*c);
            }
        }
    }
    Ok(log)
}

/// `fit-gait --body-speed`: the body's fore-aft speed the stance is fitted to.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum BodySpeedArg {
    /// The pelvis stands still over the belt.
    Constant,
    /// The pelvis swings as the adults' does.
    Normative,
}

impl From<BodySpeedArg> for pma_leg::tools::BodySpeed {
    fn from(a: BodySpeedArg) -> Self {
        match a {
            BodySpeedArg::Constant => Self::Constant,
            BodySpeedArg::Normative => Self::Normative,
        }
    }
}

/// `fit-gait --belt`: how the belt's speed is set on the fitted hip.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum BeltArg {
    /// Where the harness carries no mean fore-aft force.
    NoDrag,
    /// The stance contact's mean speed.
    Stance,
}

impl From<BeltArg> for pma_leg::tools::BeltRule {
    fn from(a: BeltArg) -> Self {
        match a {
            BeltArg::NoDrag => Self::NoHarnessDrag,
            BeltArg::Stance => Self::StanceMean,
        }
    }
}

/// A gait fit's figures as `fit-gait --json` prints them (without the provenance):
/// `steps`, `best`, `belt_speed_m_s`, `hip_correction` (`cos_deg`, `sin_deg`).
pub fn fit_figures(fit: &pma_leg::GaitFit) -> serde_json::Map<String, serde_json::Value> {
    let mut out = serde_json::Map::new();
    out.insert("steps".into(), serde_json::json!(fit.steps));
    out.insert("best".into(), serde_json::json!(fit.best));
    out.insert("belt_steps".into(), serde_json::json!(fit.belt_steps));
    out.insert(
        "belt_speed_m_s".into(),
        serde_json::json!(fit.belt_speed_m_s),
    );
    out.insert(
        "hip_correction".into(),
        serde_json::json!({
            "cos_deg": fit.hip_correction.cos_deg,
            "sin_deg": fit.hip_correction.sin_deg,
        }),
    );
    out
}

#[cfg(test)]
mod tests {
    use super::{in_scenario, margin_step};
    use pma_leg::tools::{ClosedLoop, ClosedLoopJoint, FORCE_MARGIN_STEP};
    use pma_leg::LegError;

    /// A closed-loop check of a sizing: one joint at `peak` (servo 0.45, allowed 0.70).
    fn check(peak: f64, why_not: Option<&str>, limit: Option<f64>) -> ClosedLoop {
        ClosedLoop {
            duration_s: 20.0,
            stated_margin: 0.4,
            force_margin: 0.4,
            force_max_of_rating: limit,
            joints: vec![ClosedLoopJoint {
                joint: "knee".into(),
                servo_peak_over_rated: 0.45,
                peak_over_rated: peak,
                allowed_over_rated: 0.7,
            }],
            walking: Some(why_not.is_none()),
            why_not: why_not.map(str::to_owned),
            holds: why_not.is_none() && peak <= 0.7,
        }
    }

    /// Issue 46 item 5: what a check that does not hold does to the next sizing. Over its
    /// allowance: the controller's share is added to the margin. Not walking under a force
    /// limit: a step, for a larger muscle whose limit leaves more force above the stride.
    /// Not walking without one: nothing (the controller takes any muscle to its cap).
    #[test]
    fn a_check_raises_the_margin_by_what_it_shows() {
        assert_eq!(margin_step(&check(0.64, None, Some(0.6))), None);
        let share = margin_step(&check(0.85, None, None)).expect("over: a share");
        assert!((share - 0.40).abs() < 1e-12, "{share}");
        assert_eq!(
            margin_step(&check(0.63, Some("the patient did not walk"), Some(0.6))),
            Some(FORCE_MARGIN_STEP)
        );
        assert_eq!(
            margin_step(&check(0.99, Some("the patient did not walk"), None)),
            None
        );
    }

    /// Issue 49 item 14: a run that left physical bounds (or a supervisor's fault) said so
    /// without naming the scenario that ran.
    #[test]
    fn regression_a_run_that_left_physics_named_no_file() {
        let left = || LegError::LeftPhysics {
            t_s: 1.5,
            what: "the right knee: 60 rad/s".into(),
        };
        let named = in_scenario(left(), "my_trainer.toml").to_string();
        assert!(
            named.starts_with("`my_trainer.toml`: the simulation left physical bounds at 1.500 s"),
            "{named}"
        );
        let embedded = in_scenario(LegError::Supervisor("timing".into()), "gait_treadmill");
        assert!(
            embedded
                .to_string()
                .starts_with("`gait_treadmill (embedded scenario)`: "),
            "{embedded}"
        );
        // A load error that already names its file is not named twice.
        let parse = LegError::Io {
            path: "x.toml".into(),
            message: "gone".into(),
        };
        assert!(!in_scenario(parse, "x.toml").to_string().starts_with('`'));
    }
}
