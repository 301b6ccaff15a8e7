//! One module per command; what they share is here.
use anyhow::{bail, Context, Result};
use pma_control::ControllerConfig;
use std::path::{Path, PathBuf};

// The run assembly `single`, `simulate` and `pendulum` share with the Python bindings.
pub use pma_exo::setup::{check_duration, kind_of_gains, load_gains, RefName};

pub mod compare_leg;
pub mod compare_modes;
pub mod envelope;
pub mod fit_gait;
pub mod identify;
pub mod impedance;
pub mod paper;
pub mod pendulum;
pub mod rig;
pub mod simulate;
pub mod single;
pub mod size;
pub mod sweep;
pub mod tune;
pub mod valve;

/// Refuses leg runs of `periods` control periods in all estimated to take over an hour,
/// unless `yes` (the comparisons' estimate-and-refuse, as `simulate`'s).
pub fn check_leg_comparison(periods: f64, yes: bool) -> Result<()> {
    crate::output::check_wall_time("this comparison", periods, simulate::LEG_PERIOD_S, yes)
}

/// Where a control loop's run goes besides its summary: the time series to CSV, the
/// figures as JSON, the state to Rerun (`simulate`, `pendulum`, `single`).
#[derive(clap::Args, Clone, Default)]
pub struct RunOutput {
    /// Stream the time series to this CSV file (columns: docs/formats.md).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub rerun: RerunArgs,
}

impl RunOutput {
    /// The files it writes, each named by its flag (for [`crate::output::refuse_input_as_output`]).
    pub fn files(&self) -> Vec<(&'static str, &Path)> {
        let mut files: Vec<(&'static str, &Path)> = Vec::new();
        if let Some(csv) = &self.csv {
            files.push(("--csv", csv));
        }
        if let Some(rrd) = self.rerun.save_path() {
            files.push(("--rerun save", rrd));
        }
        files
    }
}

/// Where a run's state goes in Rerun (every command that runs a control loop).
#[derive(clap::Args, Clone)]
pub struct RerunArgs {
    /// Rerun: off, spawn, connect, connect=URL or save=PATH.rrd (the file after `=`).
    #[arg(
        long = "rerun",
        default_value = "off",
        value_name = "off|spawn|connect[=URL]|save=PATH.rrd",
        value_parser = rerun_mode
    )]
    pub mode: String,
    /// Log to Rerun at this rate (Hz) instead of every control period.
    #[arg(long, allow_negative_numbers = true)]
    pub rerun_hz: Option<f64>,
}

impl Default for RerunArgs {
    fn default() -> Self {
        Self {
            mode: "off".into(),
            rerun_hz: None,
        }
    }
}

/// `--rerun`'s value, checked as it is parsed: `--rerun save FILE` then says how to give
/// the file instead of failing on FILE as an unexpected argument.
fn rerun_mode(mode: &str) -> Result<String, String> {
    let with_value = |prefix: &str| mode.strip_prefix(prefix).is_some_and(|v| !v.is_empty());
    match mode {
        "off" | "spawn" | "connect" => Ok(mode.to_owned()),
        _ if with_value("save=") || with_value("connect=") => Ok(mode.to_owned()),
        "save" | "save=" => {
            Err("`save` takes its file after `=`, in one argument: --rerun save=PATH.rrd".into())
        }
        _ => Err("expected off, spawn, connect, connect=URL or save=PATH.rrd".into()),
    }
}

impl RerunArgs {
    /// The recording's file, with `save=PATH`.
    pub fn save_path(&self) -> Option<&Path> {
        self.mode.strip_prefix("save=").map(Path::new)
    }

    /// Whether anything is to be logged; warns about a rate given without a sink.
    pub fn enabled(&self) -> Result<bool> {
        if let Some(hz) = self.rerun_hz {
            if !(hz.is_finite() && hz > 0.0) {
                bail!("--rerun-hz must be a finite rate in Hz > 0 (got {hz})");
            }
        }
        let on = self.mode != "off";
        if !on && self.rerun_hz.is_some() {
            eprintln!("warning: --rerun-hz has no effect without --rerun (nothing is logged)");
        }
        if on && !cfg!(feature = "rerun") {
            bail!(
                "this pma-exo was built without Rerun support (--no-default-features): rebuild with `cargo build --release` to use --rerun {}",
                self.mode
            );
        }
        Ok(on)
    }
}

/// A Rerun recording's description of the gains: the gain file's TOML, as `--gains` reads
/// it (never Rust's debug form).
pub fn gains_block(config: &ControllerConfig) -> String {
    format!("```toml\n{}```\n", config.to_toml_string())
}

/// Most worker threads per core accepted: more only slow a run down.
const THREADS_PER_CORE_MAX: usize = 4;

/// The files a leg command reads: the scenario file, its URDF and muscle geometry, and a
/// gain file.
pub fn scenario_inputs<'a>(
    scenario: &'a str,
    loaded: &'a pma_leg::LoadedScenario,
    gains: Option<&'a Path>,
) -> Vec<(&'static str, &'a Path)> {
    let mut inputs: Vec<(&'static str, &Path)> = vec![
        ("URDF", Path::new(&loaded.urdf_source)),
        ("muscle geometry", Path::new(&loaded.muscles_source)),
    ];
    if let Some(p) = crate::output::input_file(scenario) {
        inputs.push(("scenario file", p));
    }
    if let Some(g) = gains {
        inputs.push(("gain file", g));
    }
    inputs
}

/// Streams each period's sample to a CSV file: `t_s`, then the sample's schema (one row
/// buffer, reused).
pub struct SampleCsv<F> {
    out: crate::output::CsvOut,
    row: Vec<f64>,
    sample: F,
}

impl<F> SampleCsv<F> {
    /// Creates `path` with a `# ` line naming what ran, then the header of `schema`;
    /// `sample` makes each period's sample.
    pub fn create(
        path: &Path,
        schema: &pma_loop::Schema,
        sample: F,
        provenance: &crate::provenance::Provenance,
    ) -> Result<Self> {
        let mut header = vec!["t_s".to_owned()];
        header.extend(schema.columns());
        Ok(Self {
            out: crate::output::CsvOut::create(path, &header, Some(&provenance.line()))?,
            row: vec![0.0; header.len()],
            sample,
        })
    }

    /// Completes the file, and says so.
    pub fn finish(self) -> Result<u64> {
        let path = self.out.path().to_path_buf();
        let rows = self.out.finish()?;
        crate::output::wrote(&path);
        Ok(rows)
    }
}

impl<B, O, S, F> pma_loop::Recorder<B, O> for SampleCsv<F>
where
    B: pma_loop::Backend,
    S: pma_loop::Signals,
    F: FnMut(&pma_loop::Period<'_, B, O>) -> S,
{
    fn record(&mut self, p: &pma_loop::Period<'_, B, O>) {
        let sample = (self.sample)(p);
        self.row[0] = p.t_s;
        sample.values(&mut self.row[1..]);
        self.out.row(&self.row);
    }

    /// A run that ended on a fault (a collapse the trainer stopped) closes its rows with a
    /// `# ended at T s: WHY` line.
    fn end(&mut self, end: &pma_loop::End<B::Error>, t_s: f64) {
        if let pma_loop::End::Fault { error, .. } = end {
            self.out.comment(&format!("ended at {t_s} s: {error}"));
        }
    }
}

/// Runs `f` on a rayon pool of `threads` threads (`None`: one per core).
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let max = (THREADS_PER_CORE_MAX * cores).max(8);
    match threads {
        None => Ok(f()),
        Some(0) => bail!("--threads must be at least 1"),
        Some(n) if n > max => bail!(
            "--threads {n} is more than {THREADS_PER_CORE_MAX} per core of this machine's {cores} (at most {max}): more threads than cores only slow the run"
        ),
        Some(n) => Ok(rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .context("cannot start the worker threads")?
            .install(f)),
    }
}

/// Asks `question` on the terminal; `Ok(true)` only for the answer `yes`.
pub fn answered_yes(question: &str) -> Result<bool> {
    eprint!("{question} Type yes: ");
    let mut line = String::new();
    std::io::stdin()
        .read_line(&mut line)
        .context("cannot read the answer")?;
    Ok(line.trim() == "yes")
}

/// A progress bar over a loop's periods, advanced every 1 % of the run.
pub struct Progress {
    /// The bar (clear it when the run ends).
    pub bar: indicatif::ProgressBar,
    every: u64,
}

impl Progress {
    /// A bar over `periods` periods.
    pub fn new(periods: u64) -> Self {
        Self {
            bar: crate::output::progress_bar(periods, "periods"),
            every: (periods / 100).max(1),
        }
    }
}

impl<B: pma_loop::Backend, O> pma_loop::Recorder<B, O> for Progress {
    fn record(&mut self, p: &pma_loop::Period<'_, B, O>) {
        if p.index.is_multiple_of(self.every) {
            self.bar.set_position(p.index);
        }
    }
}

/// `--physics-substeps N` within what a scenario accepts (1 to
/// [`pma_leg::scenario::PHYSICS_SUBSTEPS_MAX`]), checked before anything runs.
pub fn check_physics_substeps(n: u32) -> Result<()> {
    if !(1..=pma_leg::scenario::PHYSICS_SUBSTEPS_MAX).contains(&n) {
        anyhow::bail!(
            "--physics-substeps {n} is invalid: {}",
            physics_substeps_range()
        );
    }
    Ok(())
}

/// The values `--physics-substeps` takes, in the words its help and its error use.
pub fn physics_substeps_range() -> String {
    format!("1 to {}", pma_leg::scenario::PHYSICS_SUBSTEPS_MAX)
}

/// What `--check-step` concludes, in the summary's words.
pub fn step_verdict(converged: bool) -> &'static str {
    if converged {
        "within 2 %"
    } else {
        "moved more than 2 %: the step decides these figures (docs/convergence.md)"
    }
}

/// The end of a run with optional CSV and Rerun outputs: the CSV completed, the viewer
/// closed, a non-finite run refused (`non_finite` says what went), the report printed as
/// JSON or by `summary`, and only then the viewer's error, so a failed viewer never hides
/// the figures.
pub fn conclude<R: serde::Serialize, F>(
    (csv, viz): (Option<SampleCsv<F>>, Option<viz::Recorder>),
    report: &R,
    provenance: &crate::provenance::Provenance,
    non_finite: Option<String>,
    json: bool,
    summary: impl FnOnce(&R) -> Result<()>,
) -> Result<()> {
    if let Some(c) = csv {
        c.finish()?;
    }
    let viz_result = viz::finish(viz);
    if let Some(what) = non_finite {
        bail!("{what} went non-finite");
    }
    if json {
        crate::say!("{}", provenance.attach(report)?);
    } else {
        summary(report)?;
        crate::say!("  ({})", provenance.line());
    }
    viz_result
}

/// Rerun recorders, or nothing when the binary is built without the `rerun` feature.
#[cfg(feature = "rerun")]
pub mod viz {
    use super::RerunArgs;
    use crate::output::{self, StagedPath};
    use anyhow::{Context, Result};
    use pma_exo::viz::VizRecorder;
    use pma_loop::{Backend, End, Period, Start};

    /// A run's recording, and with `--rerun save=PATH` the file it goes to: written beside
    /// PATH and renamed onto it only when the recording is complete, so that a run that
    /// fails leaves the previous recording as it was.
    pub struct Recorder {
        // Dropped first: the Rerun stream closes its file before the staged file goes.
        rec: VizRecorder,
        file: Option<StagedPath>,
    }

    impl<B: Backend, O> pma_loop::Recorder<B, O> for Recorder
    where
        VizRecorder: pma_loop::Recorder<B, O>,
    {
        fn start(&mut self, start: &Start<'_, B>) {
            self.rec.start(start);
        }
        fn record(&mut self, period: &Period<'_, B, O>) {
            self.rec.record(period);
        }
        fn end(&mut self, end: &End<B::Error>, t_s: f64) {
            self.rec.end(end, t_s);
        }
    }

    impl Recorder {
        /// Ends the recording and, with a file, renames it onto its path.
        pub fn finish(self) -> Result<()> {
            self.rec.finish()?;
            if let Some(file) = self.file {
                let path = file.path().to_path_buf();
                file.commit()?;
                output::wrote(&path);
            }
            Ok(())
        }
    }

    /// The sink, with `save=PATH` a temporary file beside PATH to record into.
    fn open(
        args: &RerunArgs,
        app: &'static str,
        period_s: f64,
    ) -> Result<Option<(pma_viz::Viz, Option<StagedPath>)>> {
        if !args.enabled()? {
            return Ok(None);
        }
        let sink: pma_viz::Sink = args.mode.parse().context("--rerun")?;
        let (sink, file) = match sink {
            pma_viz::Sink::Save(path) => {
                let file = StagedPath::create(&path)?;
                (pma_viz::Sink::Save(file.write_path()), Some(file))
            }
            other => (other, None),
        };
        let viz = pma_exo::viz::open(&sink, app, period_s, args.rerun_hz)?;
        Ok(viz.map(|v| (v, file)))
    }

    /// The bench's (and the rig's) layout, with `meta` as the recording's description.
    pub fn bench(
        args: &RerunArgs,
        app: &'static str,
        period_s: f64,
        meta: &str,
    ) -> Result<Option<Recorder>> {
        let Some((mut v, file)) = open(args, app, period_s)? else {
            return Ok(None);
        };
        let channels = pma_exo::viz::bench_layout(&mut v, meta)?;
        Ok(Some(Recorder {
            rec: VizRecorder::new(v, channels),
            file,
        }))
    }

    /// The leg's layout.
    pub fn leg(args: &RerunArgs, sim: &pma_leg::LegSim, meta: &str) -> Result<Option<Recorder>> {
        let Some((mut v, file)) = open(args, "pma-exo simulate", sim.scenario().period_s)? else {
            return Ok(None);
        };
        let channels = pma_exo::viz::leg_layout(&mut v, sim, meta)?;
        Ok(Some(Recorder {
            rec: VizRecorder::new(v, channels),
            file,
        }))
    }

    /// The pendulum test's layout; `knee_damping_nm_s_per_rad` is the knee's damping.
    pub fn pendulum(
        args: &RerunArgs,
        sim: &pma_leg::LegSim,
        meta: &str,
        knee_damping_nm_s_per_rad: f64,
    ) -> Result<Option<Recorder>> {
        let Some((mut v, file)) = open(args, "pma-exo pendulum", sim.scenario().period_s)? else {
            return Ok(None);
        };
        let channels = pma_exo::viz::pendulum_layout(&mut v, sim, meta)?;
        Ok(Some(Recorder {
            rec: VizRecorder::pendulum(v, channels, knee_damping_nm_s_per_rad),
            file,
        }))
    }

    /// Ends the recording, if there was one.
    pub fn finish(r: Option<Recorder>) -> Result<()> {
        r.map_or(Ok(()), Recorder::finish)
    }
}

/// Without the `rerun` feature: `--rerun off` only, nothing recorded.
#[cfg(not(feature = "rerun"))]
pub mod viz {
    use super::RerunArgs;
    use anyhow::Result;
    use pma_loop::{Backend, Period};

    /// No recorder can exist.
    pub enum Recorder {}

    impl<B: Backend, O> pma_loop::Recorder<B, O> for Recorder {
        fn record(&mut self, _: &Period<'_, B, O>) {
            match *self {}
        }
    }

    /// Checks `--rerun` (an error unless `off`).
    pub fn bench(args: &RerunArgs, _: &'static str, _: f64, _: &str) -> Result<Option<Recorder>> {
        args.enabled()?;
        Ok(None)
    }

    /// Checks `--rerun` (an error unless `off`).
    pub fn leg(args: &RerunArgs, _: &pma_leg::LegSim, _: &str) -> Result<Option<Recorder>> {
        args.enabled()?;
        Ok(None)
    }

    /// Checks `--rerun` (an error unless `off`).
    pub fn pendulum(
        args: &RerunArgs,
        _: &pma_leg::LegSim,
        _: &str,
        _: f64,
    ) -> Result<Option<Recorder>> {
        args.enabled()?;
        Ok(None)
    }

    /// Nothing to finish.
    pub fn finish(r: Option<Recorder>) -> Result<()> {
        match r {
            None => Ok(()),
            Some(never) => match never {},
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pma_control::ControllerKind;

    /// Regression: `simulate`'s Rerun metadata printed the gains in Rust's debug form
    /// (`AprcNdo(AprcGains { .. })`); it is now the gain file's TOML.
    #[test]
    fn rerun_metadata_prints_the_gains_as_a_gain_file() {
        let block = gains_block(&ControllerKind::AprcNdo.default_config());
        assert!(block.starts_with("```toml\n"), "{block}");
        assert!(block.contains("controller = \"aprc-ndo\""), "{block}");
        assert!(
            !block.contains('{') && !block.contains("AprcNdo"),
            "{block}"
        );
        let back = block
            .trim_start_matches("```toml\n")
            .trim_end_matches("```\n");
        assert_eq!(
            ControllerConfig::from_toml_str(back).expect("a gain file"),
            ControllerKind::AprcNdo.default_config()
        );
    }

    /// Regression: `--rerun save` without its file was accepted by the parser and failed
    /// later (or, followed by the file, as a bare "unexpected argument").
    #[test]
    fn rerun_save_without_its_file_says_how_to_give_it() {
        assert!(rerun_mode("save").unwrap_err().contains("save=PATH.rrd"));
        assert!(rerun_mode("save=").is_err() && rerun_mode("connect=").is_err());
        for ok in [
            "off",
            "spawn",
            "connect",
            "connect=rerun+http://h:1/proxy",
            "save=x.rrd",
        ] {
            assert_eq!(rerun_mode(ok).as_deref(), Ok(ok));
        }
    }
}
