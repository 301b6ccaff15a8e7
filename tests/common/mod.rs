//! What several test files of the binary share.
use std::path::{Path, PathBuf};

/// A test's own directory under the system's temporary one, `pma-exo-{name}-{pid}`,
/// removed when the test ends; kept and named on stderr when the test fails, since what
/// the failing run wrote is the evidence. Before it, a `cargo test --workspace` left
/// about 45 directories in the temporary directory at every run.
#[allow(dead_code)] // Not every test file that shares this module writes files.
pub struct Scratch(PathBuf);

#[allow(dead_code)]
impl Scratch {
    /// The directory, created empty (an earlier process of the same id may have left one).
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("pma-exo-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a scratch directory");
        Self(dir)
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("the failed test's files: {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Writes into `dir` a scenario whose every run leaves physical bounds at once (the
/// embedded `gait_training` on a 1 g shank at one physics step a period, which its muscles
/// throw beyond its limit within milliseconds) and returns its path. The step is set here,
/// not taken from the scenario: at 64 steps in an f64 build the light shank stays in bounds
/// for seconds or for good (docs/convergence.md, "A trial of the switch").
#[allow(dead_code)] // Not every test file that shares this module runs one.
pub fn diverging_scenario(dir: &Path) -> String {
    let shank_mass = r#"<mass value="6.075"/>"#;
    let shank_inertia = r#"ixx="0.1376" ixy="0" ixz="0" iyy="0.1376" iyz="0" izz="0.0100""#;
    let urdf = pma_leg::body::EMBEDDED_URDF;
    assert!(
        urdf.contains(shank_mass) && urdf.contains(shank_inertia),
        "the embedded URDF's shank changed: update this test's light shank"
    );
    let light = urdf
        .replace(shank_mass, r#"<mass value="0.001"/>"#)
        .replace(
            shank_inertia,
            r#"ixx="1e-7" ixy="0" ixz="0" iyy="1e-7" iyz="0" izz="1e-7""#,
        );
    std::fs::write(dir.join("light_shank.urdf"), light).expect("urdf");
    let (_, training) = pma_leg::scenario::EMBEDDED_SCENARIOS
        .iter()
        .find(|(n, _)| *n == "gait_training")
        .expect("gait_training");
    let path = dir.join("diverging.toml");
    let one_step = with_physics_substeps(training, 1);
    std::fs::write(&path, format!("urdf = \"light_shank.urdf\"\n{one_step}")).expect("scenario");
    path.display().to_string()
}

/// `scenario` with its `physics_substeps = N` line set to `n`.
fn with_physics_substeps(scenario: &str, n: u32) -> String {
    let line = scenario
        .lines()
        .find(|l| l.starts_with("physics_substeps = "))
        .expect("a scenario names its physics_substeps");
    scenario.replacen(line, &format!("physics_substeps = {n}"), 1)
}

/// The physics substeps of the tests whose long in-air runs (a minute and more) check
/// bounds, bookkeeping and verdicts, not a tracking figure: eight, the in-air default
/// before rapier went to f64 (docs/convergence.md, "The in-air default: 64 substeps in
/// double precision"). At the shipped 64 a run takes eight times the physics steps (60 s of
/// `gait_training`: 15.4 s against 2.0 s, release build): `patient` and `leg` took 630 s and
/// 273 s with them at 64, 184 s and 75 s at eight (each with other jobs on both cores).
/// Each such test has a twin at the shipped step, `#[ignore]`d: `cargo test --test patient
/// --test leg -- --ignored`.
#[allow(dead_code)] // Not every test file that shares this module runs long.
pub const LONG_RUN_SUBSTEPS: u32 = 8;

/// The embedded or file scenario `name`, at `substeps` physics steps a period (`None`: its
/// own).
#[allow(dead_code)] // Not every test file that shares this module loads a leg.
pub fn scenario_at(name: &str, substeps: Option<u32>) -> pma_leg::LoadedScenario {
    let mut loaded = pma_leg::Scenario::load(name).expect("scenario");
    if let Some(n) = substeps {
        loaded.scenario.physics_substeps = n;
    }
    loaded
}

/// Runs `pma-exo args`, sends it SIGINT `after` its start and returns what it printed and
/// how it ended (a stage taking seconds is then under way).
#[cfg(unix)]
#[allow(dead_code)] // Not every test file that shares this module signals.
pub fn interrupted(args: &[&str], after: std::time::Duration) -> std::process::Output {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    std::thread::sleep(after);
    // SAFETY: signalling our own child.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    child.wait_with_output().expect("wait")
}
