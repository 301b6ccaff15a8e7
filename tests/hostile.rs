//! What a careless or an adversarial user does (issue 15): outputs over inputs, outputs
//! over earlier results, absurd values, resource exhaustion, and the messages they get.
//! Each test is named after the defect it pins.
mod common;

use std::path::Path;
use std::process::{Command, Output};

fn pma_exo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run pma-exo")
}

fn temp_dir(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("hostile-{name}"))
}

/// Exit 1 (or `code`), one line on stderr containing `needle`, no panic.
fn assert_refused_with(args: &[&str], needle: &str, code: i32) {
    let out = pma_exo(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

fn assert_refused(args: &[&str], needle: &str) {
    assert_refused_with(args, needle, 1);
}

fn write(path: &Path, text: &str) -> String {
    std::fs::write(path, text).expect("write");
    path.display().to_string()
}

/// Files in `dir` other than `keep`: temporary files a command left behind.
fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

const IDEAL: &str = include_str!("../crates/pma-bench/models/plants/ideal.toml");
const TRAINING: &str = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");

/// Regression: `single --plant P --csv P`, `--gains G --csv G`, `simulate S.toml --csv
/// S.toml`, `pendulum S --csv S` and `tune --plant P --out P` destroyed their input and
/// exited 0.
#[test]
fn an_output_that_is_one_of_the_inputs_is_refused_and_the_input_kept() {
    let dir = temp_dir("same-path");
    let plant = write(&dir.join("plant.toml"), IDEAL);
    let gains = write(
        &dir.join("gains.toml"),
        include_str!("../crates/pma-control/models/gains/pid.toml"),
    );
    let scenario = write(&dir.join("scenario.toml"), TRAINING);
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["single", "--plant", &plant, "--csv", &plant], &plant),
        (
            vec![
                "single",
                "--controller",
                "pid",
                "--gains",
                &gains,
                "--csv",
                &gains,
            ],
            &gains,
        ),
        (vec!["simulate", &scenario, "--csv", &scenario], &scenario),
        (vec!["pendulum", &scenario, "--csv", &scenario], &scenario),
        (
            vec![
                "tune",
                "--controller",
                "pid",
                "--plant",
                &plant,
                "--out",
                &plant,
            ],
            &plant,
        ),
    ];
    for (args, input) in cases {
        let before = std::fs::read_to_string(input).expect("read");
        assert_refused(&args, "refusing to overwrite an input");
        assert_eq!(
            std::fs::read_to_string(input).expect("read"),
            before,
            "{args:?}"
        );
    }
    assert!(
        leftovers(&dir, &["plant.toml", "gains.toml", "scenario.toml"]).is_empty(),
        "{:?}",
        leftovers(&dir, &[])
    );
}

/// Regression: `tune --out G` over an existing gain file emptied it when the search
/// failed (an infeasible budget) or was interrupted. Results are now written beside the
/// target and renamed over it only when complete.
#[test]
fn a_failed_or_interrupted_tune_leaves_the_previous_gain_file() {
    let dir = temp_dir("tune-out");
    let g = write(&dir.join("g.toml"), "# the previous gains\n");
    let tune = [
        "tune",
        "--controller",
        "pid",
        "--population",
        "2",
        "--generations",
        "1",
        "--duration",
        "1",
        "--max-variation",
        "0.000001",
        "--out",
        &g,
    ];
    let out = pma_exo(&tune);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(&g).expect("read"),
        "# the previous gains\n"
    );
    #[cfg(unix)]
    {
        let out = common::interrupted(
            &[
                "tune",
                "--controller",
                "pid",
                "--population",
                "20",
                "--generations",
                "200",
                "--out",
                &g,
            ],
            std::time::Duration::from_millis(1500),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(130), "{err}");
        assert!(err.contains("interrupted"), "{err}");
        assert_eq!(
            std::fs::read_to_string(&g).expect("read"),
            "# the previous gains\n"
        );
    }
    assert!(
        leftovers(&dir, &["g.toml"]).is_empty(),
        "{:?}",
        leftovers(&dir, &[])
    );
}

/// Regression: `pulley_radius_m = 10` gave a hip RMS of 3.97e31 deg reported as finite;
/// spasms of 1e6-1e7 N m, a spasticity gain of 1e9 and an effort fraction of 1e6 gave an
/// infinite patient torque; all exited 0. Every physical input is now bounded.
#[test]
fn diverging_leg_inputs_are_refused_with_their_plausible_range() {
    let dir = temp_dir("diverging");
    let muscles = write(
        &dir.join("muscles.toml"),
        &include_str!("../crates/pma-leg/models/muscles.toml").replacen(
            "pulley_radius_m = 0.015",
            "pulley_radius_m = 10",
            1,
        ),
    );
    let huge_pulley = write(
        &dir.join("pulley.toml"),
        &format!("muscle_geometry = \"muscles.toml\"\n{TRAINING}"),
    );
    assert!(std::fs::read_to_string(&muscles)
        .expect("read")
        .contains("pulley_radius_m = 10"));
    assert_refused(
        &["simulate", &huge_pulley, "--duration", "4"],
        "pulley_radius_m",
    );
    let spasms = include_str!("../crates/pma-leg/models/scenarios/gait_spasms.toml");
    let patient_cases = [
        (
            "spasm",
            spasms.replacen("amplitude_nm = [10.0, 30.0]", "amplitude_nm = [10.0, 1e7]", 1),
            "amplitude_nm",
        ),
        (
            "reflex",
            format!(
                "{TRAINING}\n[patient.knee.spasticity]\npreset = \"mild\"\nextensor_gain_nm_s_per_rad = 1e9\n"
            ),
            "extensor_gain_nm_s_per_rad",
        ),
        (
            "effort",
            format!("{TRAINING}\n[patient.hip.effort]\nfraction = 1e6\n"),
            "fraction",
        ),
    ];
    for (name, text, needle) in patient_cases {
        assert!(
            text != spasms && text != TRAINING,
            "{name}: the edit did not apply"
        );
        let p = write(&dir.join(format!("{name}.toml")), &text);
        assert_refused(&["simulate", &p, "--duration", "4"], needle);
    }
}

/// Regression: a sweep with `period_s = 2.0` and `duration_s = 1.0` reported perfect
/// tracking; `period_s = 0.5` gave 83,584 %.
#[test]
fn a_degenerate_sweep_period_is_refused() {
    let dir = temp_dir("sweep-period");
    let base = include_str!("../crates/pma-studies/models/sweeps/fig9.toml");
    for (period, duration) in [("2.0", "1.0"), ("0.5", "20.0")] {
        let text = format!("period_s = {period}\n{base}").replacen(
            "duration_s = 20.0",
            &format!("duration_s = {duration}"),
            1,
        );
        let p = write(&dir.join(format!("p{period}.toml")), &text);
        let out = dir.join(format!("out{period}"));
        assert_refused(
            &["sweep", &p, "--out", out.to_str().expect("utf-8")],
            "period_s",
        );
        assert!(!out.exists(), "an output was created for a refused sweep");
    }
}

/// Regression: `dead_time_s = 1e9` and `sensor_latency_s = 1e9` aborted on a 160 TB
/// allocation; a population of 1e8 took 17 GB before the one-hour refusal; `tune
/// --population 18446744073709551615` panicked; `--threads 100000` ran for minutes.
#[test]
fn resource_exhaustion_is_refused_at_validation() {
    let dir = temp_dir("exhaustion");
    let dead = write(
        &dir.join("dead.toml"),
        &IDEAL.replace("[valve]", "[valve]\ndead_time_s = 1e9"),
    );
    assert_refused(&["single", "--plant", &dead], "dead_time_s");
    let rig = write(
        &dir.join("rig.toml"),
        &include_str!("../crates/pma-rig/models/virtual.toml")
            .replace("[virtual]", "[virtual]\nsensor_latency_s = 1e9"),
    );
    assert_refused(&["rig", "check", "--config", &rig], "sensor_latency_s");
    let mc = write(
        &dir.join("mc.toml"),
        &include_str!("../crates/pma-studies/models/sweeps/monte_carlo.toml")
            .replace("size = 200", "size = 100000000"),
    );
    let out = dir.join("mc-out");
    assert_refused(
        &["sweep", &mc, "--out", out.to_str().expect("utf-8")],
        "population.size",
    );
    assert_refused(
        &[
            "tune",
            "--controller",
            "pid",
            "--population",
            "18446744073709551615",
        ],
        "--population",
    );
    assert_refused(
        &["tune", "--controller", "pid", "--threads", "100000"],
        "--threads",
    );
}

/// Regression: messages that named the wrong thing or said nothing.
#[test]
fn messages_name_the_right_thing() {
    let dir = temp_dir("messages");
    let sweep = write(&dir.join("s.toml"), "name = 1\n");
    let out = dir.join("o");
    let o = out.to_str().expect("utf-8");
    assert_refused(&["sweep", &sweep, "--out", o], "sweep file");
    assert_refused(&["single", "--rerun-hz", "-5"], "--rerun-hz");
    assert_refused(
        &["single", "--rerun", "save=x.rrd", "--rerun-hz", "0"],
        "--rerun-hz",
    );
    assert_refused(&["pendulum", "--knee-deg", "nan"], "--knee-deg");
    let missing = dir.join("no-such-shard");
    let merged = dir.join("merged");
    assert_refused(
        &[
            "sweep",
            "merge",
            missing.to_str().expect("utf-8"),
            "--out",
            merged.to_str().expect("utf-8"),
        ],
        "no-such-shard",
    );
    assert!(
        !merged.exists(),
        "merge created its --out for a missing input"
    );
    let spasms = write(
        &dir.join("neg.toml"),
        &include_str!("../crates/pma-leg/models/scenarios/gait_spasms.toml").replacen(
            "amplitude_nm = [10.0, 30.0]",
            "amplitude_nm = [-30.0, -10.0]",
            1,
        ),
    );
    let out = pma_exo(&["simulate", &spasms, "--duration", "4"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("amplitude_nm") && !err.contains("missing"),
        "{err}"
    );
}

/// Regression (found while fixing the above): results written through a temporary file
/// renamed over the target replaced `/dev/full` itself with a regular file. Outputs onto
/// something that is not a regular file are now written straight into it.
#[cfg(unix)]
#[test]
fn an_output_onto_a_device_goes_through_it_and_never_replaces_it() {
    use std::os::unix::fs::FileTypeExt;
    let out = pma_exo(&["single", "--duration", "0.5", "--csv", "/dev/full"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/dev/full"));
    let meta = std::fs::metadata("/dev/full").expect("/dev/full");
    assert!(meta.file_type().is_char_device(), "/dev/full was replaced");
    let out = pma_exo(&["single", "--duration", "0.5", "--csv", "/dev/null"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta = std::fs::metadata("/dev/null").expect("/dev/null");
    assert!(meta.file_type().is_char_device(), "/dev/null was replaced");
}
