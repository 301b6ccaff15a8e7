//! Every file through the one output path (issue 26): the mode the umask gives, a replaced
//! file's own mode kept, nothing replaced by a run that fails, no two outputs of a command
//! (nor an input and an output) on one path, no file written unasked; provenance that names
//! files by their path, every seed and every part of the patient; and a "wrote" line for
//! every output.
use std::path::Path;
use std::process::{Command, Output};

mod common;

fn temp(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("outputs-{name}"))
}

/// `pma-exo args` in `dir` under `umask` (set in a shell, for the child only).
fn pma_exo_umask(dir: &Path, umask: &str, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("umask {umask} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run pma-exo")
}

fn pma_exo(dir: &Path, args: &[&str]) -> Output {
    pma_exo_umask(dir, "022", args)
}

fn ok(dir: &Path, args: &[&str]) -> Output {
    let out = pma_exo(dir, args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A one-line error (exit 1) containing every `needle`.
fn one_line_error(dir: &Path, args: &[&str], needles: &[&str]) {
    let out = pma_exo(dir, args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: {err}");
    }
}

/// The files of `dir` (none hidden, no leftover temporary file).
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[cfg(unix)]
fn mode(path: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path)
        .expect("metadata")
        .permissions()
        .mode()
        & 0o777
}

const BENCH_SWEEP: &str = r#"
name = "modes"
duration_s = 1.0
[[grid]]
controllers = ["pid"]
gains = ["default"]
references = ["sine"]
[grid.plants]
presets = ["ideal"]
"#;

/// Regression: every file written through a temporary file (`--csv`, `--plot`, `--out`
/// TOML/JSON/MD/PNG) was created 0600 under umask 022 while `.rrd` and `runs.jsonl` were
/// 0644: colleagues in a shared directory could not read the results. Every new file now
/// gets `0666 & !umask`, every new directory `0777 & !umask`.
#[cfg(unix)]
#[test]
fn every_output_file_gets_the_mode_the_umask_gives() {
    for (umask, file_mode, dir_mode) in [("022", 0o644, 0o755), ("027", 0o640, 0o750)] {
        let dir = temp(&format!("umask{umask}"));
        std::fs::write(dir.join("sweep.toml"), BENCH_SWEEP).expect("sweep file");
        for args in [
            &[
                "single",
                "--duration",
                "1",
                "--csv",
                "o.csv",
                "--rerun",
                "save=o.rrd",
            ][..],
            &["simulate", "--duration", "3.2", "--plot", "plots"],
            &[
                "size",
                "--strides",
                "1",
                "--closed-loop-s",
                "0",
                "--out",
                "m.toml",
                "--json",
            ],
            &["sweep", "sweep.toml", "--out", "sweep"],
        ] {
            let out = pma_exo_umask(&dir, umask, args);
            assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        }
        let files = [
            "o.csv",
            "o.rrd",
            "plots/leg.png",
            "m.toml",
            "sweep/sweep.json",
            "sweep/runs.jsonl",
            "sweep/summary.json",
            "sweep/summary.md",
            "sweep/rte.png",
        ];
        for f in files {
            assert_eq!(mode(&dir.join(f)), file_mode, "{f} under umask {umask}");
        }
        for d in ["plots", "sweep"] {
            assert_eq!(mode(&dir.join(d)), dir_mode, "{d}/ under umask {umask}");
        }
    }
}

/// An output written over an existing file keeps that file's mode (a private 0600 result
/// stays private, a group-writable one stays so), whatever the umask.
#[cfg(unix)]
#[test]
fn an_overwritten_output_keeps_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp("keep-mode");
    for (file, kept) in [("private.csv", 0o600), ("shared.csv", 0o664)] {
        let path = dir.join(file);
        std::fs::write(&path, "old").expect("old file");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(kept)).expect("chmod");
        ok(&dir, &["single", "--duration", "1", "--csv", file]);
        assert_eq!(mode(&path), kept, "{file}");
        assert!(std::fs::read_to_string(&path)
            .expect("csv")
            .contains("t_s,"));
    }
}

/// Regression: `simulate ... --rerun save=old.rrd` that failed replaced old.rrd. The
/// recording is now written beside it and renamed only when the run succeeds.
#[test]
fn a_failed_run_keeps_the_previous_rerun_recording() {
    let dir = temp("rrd-kept");
    let scenario = common::diverging_scenario(&dir);
    std::fs::write(dir.join("old.rrd"), "the previous recording").expect("old");
    let out = pma_exo(
        &dir,
        &[
            "simulate",
            &scenario,
            "--duration",
            "3.2",
            "--csv",
            "x.csv",
            "--rerun",
            "save=old.rrd",
        ],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("physical bounds"), "{}", stderr(&out));
    assert_eq!(
        std::fs::read_to_string(dir.join("old.rrd")).expect("old.rrd"),
        "the previous recording"
    );
    // Nothing else left behind: no CSV of a failed run, no temporary file.
    assert_eq!(
        listing(&dir),
        ["diverging.toml", "light_shank.urdf", "old.rrd"]
    );
}

/// Regression: `simulate --plot . --csv leg.png` exited 0 with leg.png holding the CSV,
/// and `single --csv o.csv --rerun save=o.csv` kept one of the two. Two outputs of one
/// command on one path are refused before anything is written.
#[test]
fn two_outputs_of_one_command_on_one_path_are_refused() {
    let dir = temp("out-out");
    one_line_error(
        &dir,
        &[
            "simulate",
            "--duration",
            "3.2",
            "--plot",
            ".",
            "--csv",
            "leg.png",
        ],
        &["--plot", "--csv", "leg.png", "one path"],
    );
    one_line_error(
        &dir,
        &[
            "single",
            "--duration",
            "1",
            "--csv",
            "o.csv",
            "--rerun",
            "save=./o.csv",
        ],
        &["--csv", "--rerun save", "one path"],
    );
    one_line_error(
        &dir,
        &[
            "pendulum",
            "--duration",
            "1",
            "--plot",
            ".",
            "--csv",
            "pendulum.png",
        ],
        &["--plot", "--csv", "one path"],
    );
    assert!(listing(&dir).is_empty(), "{:?}", listing(&dir));
}

/// Regression: `rig run --log x.csv --rerun save=x.csv` was refused with "x.csv exists"
/// after the recording had created x.csv. It is refused up front as two outputs on one
/// path, and nothing is written.
#[test]
fn rig_run_refuses_its_log_as_its_recording_up_front() {
    let dir = temp("rig-out-out");
    one_line_error(
        &dir,
        &[
            "rig",
            "run",
            "--duration",
            "1",
            "--log",
            "x.csv",
            "--rerun",
            "save=x.csv",
        ],
        &["--log", "--rerun save", "x.csv", "one path"],
    );
    assert!(listing(&dir).is_empty(), "{:?}", listing(&dir));
}

/// Regression: `size` without `--out` wrote `./muscles.toml` over whatever was there (in
/// crates/pma-leg/models/ it replaced the shipped geometry). It has no default output: it
/// prints the sizing and says how to write the geometry.
#[test]
fn size_without_out_writes_nothing() {
    let dir = temp("size-no-out");
    std::fs::write(dir.join("muscles.toml"), "mine").expect("a file of the user's");
    let out = ok(&dir, &["size", "--strides", "1", "--closed-loop-s", "0"]);
    assert!(stderr(&out).contains("--out"), "{}", stderr(&out));
    assert_eq!(listing(&dir), ["muscles.toml"]);
    assert_eq!(
        std::fs::read_to_string(dir.join("muscles.toml")).expect("kept"),
        "mine"
    );
    let v: serde_json::Value = serde_json::from_slice(
        &ok(
            &dir,
            &["size", "--strides", "1", "--closed-loop-s", "0", "--json"],
        )
        .stdout,
    )
    .expect("json");
    assert!(v["muscle_geometry"].is_null(), "{v}");
}

/// Regression: `--plot /nonexistent/dir` created the whole path. An output directory is
/// created one level deep, in an existing parent; a mistyped parent is an error.
#[test]
fn plot_creates_one_directory_level_not_a_tree() {
    let dir = temp("plot-dir");
    one_line_error(
        &dir,
        &["simulate", "--duration", "3.2", "--plot", "typo/plots"],
        &["typo/plots", "parent", "one directory level"],
    );
    one_line_error(
        &dir,
        &["compare-leg", "--duration", "3.2", "--out", "typo/cmp"],
        &["typo/cmp", "one directory level"],
    );
    assert!(listing(&dir).is_empty(), "{:?}", listing(&dir));
}

/// Regression: `--csv` and `--rerun save` printed no "wrote" line, unlike the other
/// outputs; and `--rerun save FILE` (a space for the `=`) failed with a bare "unexpected
/// argument". Both spellings record into FILE, and each file written is named once.
#[test]
fn csv_and_rerun_outputs_say_they_were_written() {
    let dir = temp("wrote");
    let out = ok(
        &dir,
        &[
            "single",
            "--duration",
            "1",
            "--csv",
            "o.csv",
            "--rerun",
            "save",
            "o.rrd",
            "--json",
        ],
    );
    let err = stderr(&out);
    assert_eq!(
        err.lines().collect::<Vec<_>>(),
        ["wrote o.csv", "wrote o.rrd"],
        "{err}"
    );
    assert!(std::fs::metadata(dir.join("o.rrd")).expect("rrd").len() > 0);
}

fn provenance(out: &Output) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    v["provenance"].clone()
}

/// Regression: `single --plant myplant.toml` (named "realistic" inside, 4 kg) was reported
/// as plant "realistic": a file is named by its path and its inner name.
#[test]
fn provenance_names_a_plant_file_by_its_path() {
    let dir = temp("prov-plant");
    let mut realistic = pma_bench::PlantConfig::preset("realistic").expect("preset");
    assert_eq!(realistic.name, "realistic");
    realistic.load.mass_kg = 4.0;
    let text = toml::to_string(&realistic).expect("a plant file");
    std::fs::write(dir.join("myplant.toml"), text).expect("plant");
    let p = provenance(&ok(
        &dir,
        &[
            "single",
            "--plant",
            "myplant.toml",
            "--duration",
            "1",
            "--json",
        ],
    ));
    assert_eq!(p["plant"], "myplant.toml (name \"realistic\")", "{p}");
    // Its sensor is noisy: the noise's seed is named.
    assert_eq!(p["seeds"]["sensor noise"], realistic.sensor.seed, "{p}");
    let p = provenance(&ok(
        &dir,
        &[
            "single",
            "--plant",
            "realistic",
            "--duration",
            "1",
            "--json",
        ],
    ));
    assert_eq!(p["plant"], "realistic", "{p}");
}

/// Regression: `simulate gait_realistic` reported seed null though its encoder noise is
/// seeded, and the gait_spasms patient line left out its stiffness model (anderson1999).
/// Every seed that ran and every part of the patient are named.
#[test]
fn provenance_names_every_seed_and_every_part_of_the_patient() {
    let dir = temp("prov-seeds");
    let p = provenance(&ok(
        &dir,
        &["simulate", "gait_realistic", "--duration", "3.2", "--json"],
    ));
    let sc = pma_leg::Scenario::load("gait_realistic").expect("scenario");
    assert!(sc.scenario.plant.encoder.noise_rms_rad > 0.0);
    assert_eq!(
        p["seeds"]["encoder noise"], sc.scenario.plant.encoder.seed,
        "{p}"
    );
    let p = provenance(&ok(
        &dir,
        &["simulate", "gait_spasms", "--duration", "3.2", "--json"],
    ));
    let patient = p["patient"].as_str().expect("patient");
    assert!(
        patient.contains("spasms") && patient.contains("stiffness anderson1999"),
        "{patient}"
    );
    assert!(p["seeds"]["hip spasms"].is_u64(), "{p}");
}

/// Regression: `compare-leg --scenarios gait_training,t.toml` (t.toml named gait_training
/// inside) labelled both "gait_training", and `size t.toml` wrote "recommended by `pma-exo
/// size gait_treadmill`". Each scenario is named as the command line gives it.
#[test]
fn a_scenario_file_is_named_by_its_path_not_its_inner_name() {
    let dir = temp("prov-scenario");
    let (_, training) = pma_leg::scenario::EMBEDDED_SCENARIOS
        .iter()
        .find(|(n, _)| *n == "gait_training")
        .expect("gait_training");
    std::fs::write(dir.join("t.toml"), training).expect("scenario");
    ok(
        &dir,
        &[
            "compare-leg",
            "--scenarios",
            "gait_training,t.toml",
            "--duration",
            "3.2",
            "--out",
            "cmp",
        ],
    );
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("cmp/compare-leg.json")).expect("json"),
    )
    .expect("json");
    let labels: std::collections::BTreeSet<&str> = json["rows"]
        .as_array()
        .expect("rows")
        .iter()
        .map(|r| r["scenario"].as_str().expect("scenario"))
        .collect();
    assert_eq!(labels, ["gait_training", "t.toml"].into(), "{json}");
    let md = std::fs::read_to_string(dir.join("cmp/compare-leg.md")).expect("md");
    assert!(
        md.contains("## t.toml") && md.contains("## gait_training"),
        "{md}"
    );
    assert_eq!(
        json["provenance"]["scenario"],
        "gait_training, t.toml (name \"gait_training\")"
    );
    // The treadmill scenario as a file: its muscle geometry says which file it came from.
    let (_, treadmill) = pma_leg::scenario::EMBEDDED_SCENARIOS
        .iter()
        .find(|(n, _)| *n == "gait_treadmill")
        .expect("gait_treadmill");
    std::fs::write(dir.join("tm.toml"), treadmill).expect("scenario");
    ok(
        &dir,
        &[
            "size",
            "tm.toml",
            "--strides",
            "1",
            "--closed-loop-s",
            "0",
            "--out",
            "m.toml",
        ],
    );
    let header = std::fs::read_to_string(dir.join("m.toml")).expect("geometry");
    assert!(
        header.contains(
            "recommended by `pma-exo size tm.toml --strides 1 --closed-loop-s 0 --out m.toml`"
        ),
        "{header}"
    );
}

/// Regression: `rig run --gains mypid.toml` without `--controller` failed (the
/// configuration's APRC-NDO was asked of a PID file) where `single` infers the controller
/// from the file, and once given `--controller` the provenance said "command line" without
/// the file. The file now says its controller and is named; and the rig's and the
/// excitation's logs start with the provenance line, as every CSV does.
#[test]
fn rig_run_infers_the_controller_of_its_gain_file_and_names_it() {
    let dir = temp("rig-gains");
    let pid = pma_control::ControllerKind::Pid
        .default_config()
        .to_toml_string();
    std::fs::write(dir.join("mypid.toml"), pid).expect("gains");
    let out = ok(
        &dir,
        &[
            "rig",
            "run",
            "--duration",
            "1",
            "--gains",
            "mypid.toml",
            "--log",
            "run.csv",
            "--json",
        ],
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["provenance"]["controller"], "pid", "{v}");
    assert_eq!(v["provenance"]["gains"], "mypid.toml", "{v}");
    ok(
        &dir,
        &["rig", "excite", "--duration", "2", "--out", "excite.csv"],
    );
    for (log, command) in [("run.csv", "rig run"), ("excite.csv", "rig excite")] {
        let text = std::fs::read_to_string(dir.join(log)).expect("log");
        let second = text.lines().nth(1).expect("a second header line");
        assert!(
            second.starts_with("# pma-exo ") && second.contains(&format!("`pma-exo {command} ")),
            "{log}: {second}"
        );
    }
    // The logs with their provenance line still replay and identify.
    ok(&dir, &["rig", "replay", "run.csv"]);
}

/// Regression: `pendulum --knee-deg 500` echoed 500.00000000000006 (the degrees' round
/// trip through radians).
#[test]
fn pendulum_echoes_the_knee_angle_as_given() {
    let dir = temp("pendulum-echo");
    one_line_error(
        &dir,
        &["pendulum", "--knee-deg", "500"],
        &["= 500 is invalid"],
    );
}

/// Regression: `simulate --help` sent users to crates/pma-control/models/gains/leg (the
/// leg's gain files are in crates/pma-leg/models/gains), and `sweep --help` said "a grid of
/// bench runs" (it runs leg grids too).
#[test]
fn help_names_the_leg_gains_directory_and_the_leg_grids() {
    let dir = temp("help");
    let simulate = String::from_utf8_lossy(&ok(&dir, &["simulate", "--help"]).stdout).into_owned();
    assert!(
        simulate.contains("crates/pma-leg/models/gains")
            && !simulate.contains("pma-control/models/gains/leg"),
        "{simulate}"
    );
    assert!(Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("crates/pma-leg/models/gains/pid.toml")
        .is_file());
    let sweep = String::from_utf8_lossy(&ok(&dir, &["sweep", "--help"]).stdout).into_owned();
    assert!(sweep.contains("leg runs"), "{sweep}");
}

/// Issue 49: `simulate --plot DIR` over an earlier run's figures, on a filesystem that fills
/// after the first: the first figure was already replaced when the second failed, leaving
/// one new and one old. Both are written beside their paths first and renamed together,
/// and the error is one plain line (not plotters' debug form). Needs a small tmpfs: the
/// test says so and passes where it cannot mount one (not root, no tmpfs).
#[test]
fn plots_are_replaced_together_or_not_at_all_on_a_disk_that_fills() {
    let dir = std::env::temp_dir().join(format!("pma-exo-fullplot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let d = dir.to_str().expect("utf-8");
    // 800 kB: room for gait_training's first figure (about 600 kB), not for both (1 MB).
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=800k", "tmpfs", d])
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("no tmpfs could be mounted here: the full-disk case is not checked");
        std::fs::remove_dir_all(&dir).ok();
        return;
    }
    std::fs::write(dir.join("leg.png"), "old").expect("old leg");
    std::fs::write(dir.join("strides.png"), "old").expect("old strides");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["simulate", "gait_training", "--duration", "4", "--plot", d])
        .output()
        .expect("run");
    let leg = std::fs::read_to_string(dir.join("leg.png")).unwrap_or_default();
    let strides = std::fs::read_to_string(dir.join("strides.png")).unwrap_or_default();
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .expect("dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".part"))
        .collect();
    std::process::Command::new("umount").arg(d).status().ok();
    std::fs::remove_dir_all(&dir).ok();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("No space left on device") && !err.contains("ImageError"),
        "{err}"
    );
    assert_eq!((leg.as_str(), strides.as_str()), ("old", "old"));
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// Issue 49: `--csv f1.txt/` (a path that names a directory) was found at the rename after
/// a 60 s run, which was lost. Every output path is now prepared before the run: the
/// command fails at once, in one line naming the path, and writes nothing.
#[test]
fn an_output_path_ending_in_a_slash_is_refused_before_the_run() {
    let dir = temp("slash");
    for args in [
        &["simulate", "--duration", "60", "--csv", "f1.txt/"][..],
        &["single", "--duration", "600", "--csv", "f1.txt/"][..],
    ] {
        let out = pma_exo(&dir, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            err.contains("f1.txt/") && err.contains("cannot end in"),
            "{err}"
        );
    }
    assert_eq!(std::fs::read_dir(&dir).expect("dir").count(), 0);
}
