//! Sweeps through the binary: the same lines for any thread count and any sharding, a
//! killed sweep resumed losing nothing, bad files as one-line errors, and (where a Slurm
//! cluster is up, as in CI) a job array.
use std::path::Path;
use std::process::Command;

mod common;

const SMALL: &str = r#"
name = "small"
duration_s = 3.0
[[grid]]
controllers = ["aprc-ndo", "pid"]
gains = ["default"]
references = ["sine", "jump"]
[grid.plants]
presets = ["realistic"]
[[grid]]
controllers = ["psmc", "ndo-smc"]
gains = ["equal-activity/3"]
references = ["sine"]
events = ["impact-down"]
[grid.plants.population]
size = 3
seed = 7
muscle_scale = [0.8, 1.2]
load_kg = [1.0, 5.0]
valve_lag_s = [0.0, 0.03]
noise_rms_m = [0.0, 2e-5]
"#;

/// A leg grid: two controllers over the passive limb, a preset and a sampled population,
/// at two seeds, beside a bench grid in the same file.
const LEG_SMALL: &str = r#"
name = "leg_small"
duration_s = 3.2
[[grid]]
controllers = ["pid"]
gains = ["default"]
references = ["sine"]
[grid.plants]
presets = ["ideal"]
[[leg]]
scenarios = ["gait_spasms"]
controllers = ["aprc-ndo", "pid"]
gains = ["leg"]
seeds = [3, 4]
[leg.patients]
presets = ["passive", "severe"]
[leg.patients.population]
size = 2
seed = 2
spasticity = ["none", "severe"]
spasm_rate_per_min = [6.0, 12.0]
spasm_amplitude_nm = [5.0, 30.0]
effort_fraction = [-0.3, 0.3]
"#;

fn temp(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("sweep-{name}"))
}

fn pma_exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .output()
        .expect("run pma-exo")
}

fn ok(args: &[&str]) {
    let out = pma_exo(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn sorted_lines(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).expect("runs.jsonl");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let index = |l: &String| -> u64 {
        let v: serde_json::Value = serde_json::from_str(l).expect("json line");
        v["run"].as_u64().expect("run")
    };
    lines.sort_by_key(index);
    lines
}

fn write_sweep(dir: &Path, text: &str) -> String {
    let p = dir.join("sweep.toml");
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

#[test]
fn threads_and_shards_give_the_same_lines() {
    let dir = temp("determinism");
    let file = write_sweep(&dir, SMALL);
    let s = |p: &Path| p.display().to_string();
    let (one, two) = (dir.join("one"), dir.join("two"));
    ok(&["sweep", &file, "--out", &s(&one), "--threads", "1"]);
    ok(&["sweep", &file, "--out", &s(&two), "--threads", "2"]);
    let whole = sorted_lines(&one.join("runs.jsonl"));
    assert_eq!(whole.len(), 2 * 2 + 2 * 3);
    assert_eq!(whole, sorted_lines(&two.join("runs.jsonl")));
    // Two shards, merged, are the whole.
    let (a, b, merged) = (dir.join("a"), dir.join("b"), dir.join("merged"));
    ok(&["sweep", &file, "--out", &s(&a), "--shard", "1/2"]);
    ok(&["sweep", &file, "--out", &s(&b), "--shard", "2/2"]);
    let na = sorted_lines(&a.join("runs.jsonl")).len();
    assert!(na > 0 && na < whole.len(), "shard 1/2 ran {na} runs");
    ok(&["sweep", "merge", &s(&a), &s(&b), "--out", &s(&merged)]);
    let m = std::fs::read_to_string(merged.join("runs.jsonl")).expect("merged");
    assert_eq!(m.lines().map(str::to_owned).collect::<Vec<_>>(), whole);
    for f in ["summary.json", "summary.md", "rte.png"] {
        assert!(merged.join(f).exists(), "{f}");
    }
    // A merge with a shard missing says so and fails.
    let out = pma_exo(&["sweep", "merge", &s(&a), "--out", &s(&dir.join("half"))]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing"));
    // Every run's events carry their figures; the physics stayed finite.
    for line in &whole {
        let v: serde_json::Value = serde_json::from_str(line).expect("json");
        assert_eq!(v["finite"], true, "{line}");
        if v["event"] == "impact-down" || v["reference"] == "jump" {
            assert!(
                !v["events"].as_array().expect("events").is_empty(),
                "{line}"
            );
        }
    }
}

/// A leg grid shards and merges like a bench grid; its runs carry the patient they ran
/// with, the seed moves the spasms and the passive limb has none.
#[test]
fn a_leg_sweep_shards_merges_and_records_its_patients() {
    let dir = temp("leg");
    let file = write_sweep(&dir, LEG_SMALL);
    let s = |p: &Path| p.display().to_string();
    let whole = dir.join("whole");
    ok(&["sweep", &file, "--out", &s(&whole), "--threads", "2"]);
    let lines = sorted_lines(&whole.join("runs.jsonl"));
    assert_eq!(lines.len(), 1 + 2 * (2 + 2) * 2);
    let (a, b, merged) = (dir.join("a"), dir.join("b"), dir.join("merged"));
    ok(&["sweep", &file, "--out", &s(&a), "--shard", "1/2"]);
    ok(&["sweep", &file, "--out", &s(&b), "--shard", "2/2"]);
    ok(&["sweep", "merge", &s(&a), &s(&b), "--out", &s(&merged)]);
    let m = std::fs::read_to_string(merged.join("runs.jsonl")).expect("merged");
    assert_eq!(m.lines().map(str::to_owned).collect::<Vec<_>>(), lines);
    for f in ["summary.json", "summary.md", "rte.png", "leg_rms.png"] {
        assert!(merged.join(f).exists(), "{f}");
    }
    let legs: Vec<serde_json::Value> = lines
        .iter()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("json"))
        .filter(|v| v.get("patient").is_some())
        .collect();
    assert_eq!(legs.len(), 16);
    let spasms = |v: &serde_json::Value| v["spasms"].as_u64().expect("spasms");
    for v in &legs {
        assert_eq!(v["finite"], true, "{v}");
        assert_eq!(v["fault"], serde_json::Value::Null, "{v}");
        assert!(v["hip_rms_deg"].as_f64().expect("hip") < 5.0, "{v}");
        if v["patient"] == "passive" {
            assert_eq!(spasms(v), 0, "{v}");
            assert_eq!(v["spasticity"], serde_json::json!(["none", "none"]), "{v}");
        }
        if v["patient"] == "severe" {
            assert_eq!(
                v["spasticity"],
                serde_json::json!(["severe", "severe"]),
                "{v}"
            );
        }
    }
    // The same sampled patient at two seeds: its own spasticity, different spasms.
    let pick = |seed: u64| {
        legs.iter()
            .find(|v| {
                v["patient"] == "population-0" && v["controller"] == "pid" && v["seed"] == seed
            })
            .expect("population-0")
    };
    let (three, four) = (pick(3), pick(4));
    assert_eq!(three["spasticity"], four["spasticity"]);
    assert_ne!(three["knee_rms_deg"], four["knee_rms_deg"]);
    let md = std::fs::read_to_string(merged.join("summary.md")).expect("summary.md");
    assert!(
        md.contains("## Leg: scenario `gait_spasms`, patients population"),
        "{md}"
    );
}

#[cfg(unix)]
#[test]
fn a_killed_sweep_resumes_and_loses_nothing() {
    let dir = temp("resume");
    // Enough runs to kill it half way.
    let text = SMALL
        .replace("duration_s = 3.0", "duration_s = 6.0")
        .replace("size = 3", "size = 30");
    let file = write_sweep(&dir, &text);
    let (full, killed) = (dir.join("full"), dir.join("killed"));
    ok(&[
        "sweep",
        &file,
        "--out",
        &full.display().to_string(),
        "--threads",
        "2",
    ]);
    let runs = killed.join("runs.jsonl");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args([
            "sweep",
            &file,
            "--out",
            &killed.display().to_string(),
            "--threads",
            "1",
        ])
        .spawn()
        .expect("spawn");
    let t0 = std::time::Instant::now();
    while std::fs::read_to_string(&runs).map_or(0, |t| t.lines().count()) < 10 {
        assert!(t0.elapsed().as_secs() < 120, "no progress");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    let _ = child.wait();
    let partial = std::fs::read_to_string(&runs).expect("partial");
    let total = sorted_lines(&full.join("runs.jsonl")).len();
    assert!(partial.lines().count() < total, "killed too late");
    // And a torn last line, as a kill in the middle of a write leaves.
    let mut torn = partial.clone();
    if !torn.ends_with('\n') {
        torn.push('\n');
    }
    torn.push_str("{\"run\":999,\"controller\":\"pi");
    std::fs::write(&runs, torn).expect("tear");
    ok(&["sweep", &file, "--out", &killed.display().to_string()]);
    assert_eq!(sorted_lines(&runs), sorted_lines(&full.join("runs.jsonl")));
}

fn one_line_error(args: &[&str], needle: &str) {
    let out = pma_exo(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
}

#[test]
fn bad_sweeps_are_one_line_errors() {
    let dir = temp("bad");
    let out = dir.join("out").display().to_string();
    let cases = [
        (
            SMALL.replace("duration_s = 3.0", "duration_s = 3.0\nthreads = 2"),
            "threads",
        ),
        (
            SMALL.replace("\"aprc-ndo\", \"pid\"", "\"aprc-ndo\", \"lqr\""),
            "lqr",
        ),
        (
            SMALL.replace("references = [\"sine\", \"jump\"]", "references = []"),
            "references",
        ),
        (
            SMALL
                .replace("gains = [\"default\"]", "gains = [\"paper\"]")
                .replace("\"aprc-ndo\", \"pid\"", "\"pid\"")
                .replace("gains = [\"equal-activity/3\"]", "gains = [\"paper\"]"),
            "empty",
        ),
        (SMALL.replace("size = 3", "size = 0"), "population.size"),
        (
            LEG_SMALL.replace("\"passive\", \"severe\"", "\"passive\", \"agonised\""),
            "agonised",
        ),
        (
            LEG_SMALL.replace(
                "effort_fraction = [-0.3, 0.3]",
                "effort_fraction = [-0.3, 3.0]",
            ),
            "effort_fraction",
        ),
        (
            LEG_SMALL.replace("\"gait_spasms\"", "\"gait_nowhere\""),
            "gait_nowhere",
        ),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let f = dir.join(format!("bad{i}.toml"));
        std::fs::write(&f, text).expect("write");
        one_line_error(&["sweep", &f.display().to_string(), "--out", &out], needle);
    }
    let good = write_sweep(&dir, SMALL);
    one_line_error(&["sweep", &good, "--out", &out, "--shard", "3/2"], "3/2");
    one_line_error(&["sweep", &good, "--out", &out, "--shard", "0/2"], "0/2");
    one_line_error(&["sweep", "nonexistent", "--out", &out], "nonexistent");
    // Another sweep's directory is not resumed into.
    let first = dir.join("first").display().to_string();
    ok(&["sweep", &good, "--out", &first, "--shard", "1/4"]);
    one_line_error(
        &["sweep", &good, "--out", &first, "--shard", "2/4"],
        "another --out",
    );
}

/// Runs only where a Slurm cluster is up (`.ci/run` starts a one-node cluster on
/// localhost and sets `SLURM_CONF`): a job array of two shards, merged.
#[test]
fn a_slurm_job_array_runs_the_shards() {
    let Ok(conf) = std::env::var("SLURM_CONF") else {
        eprintln!("SLURM_CONF is not set: no Slurm cluster to submit to (CI starts one)");
        return;
    };
    let dir = temp("slurm");
    let file = write_sweep(&dir, SMALL);
    let bin = env!("CARGO_BIN_EXE_pma-exo");
    let script = format!(
        "#!/bin/sh\nexec {bin} sweep {file} --out {}/shard-$SLURM_ARRAY_TASK_ID --shard $((SLURM_ARRAY_TASK_ID + 1))/2 --threads 1\n",
        dir.display()
    );
    let job = dir.join("job.sh");
    std::fs::write(&job, script).expect("job");
    let out = Command::new("sbatch")
        .args(["--parsable", "--array=0-1", "-o"])
        .arg(dir.join("slurm-%A_%a.out"))
        .arg(&job)
        .env("SLURM_CONF", &conf)
        .output()
        .expect("sbatch");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let id = String::from_utf8_lossy(&out.stdout).trim().to_owned();
    let waited = Command::new("bash")
        .args([".ci/slurm-ci.sh", "wait", &id, "300"])
        .env("SLURM_CONF", &conf)
        .status()
        .expect("wait");
    assert!(waited.success(), "job {id} did not complete");
    let merged = dir.join("merged");
    ok(&[
        "sweep",
        "merge",
        &dir.join("shard-0").display().to_string(),
        &dir.join("shard-1").display().to_string(),
        "--out",
        &merged.display().to_string(),
    ]);
    let whole = dir.join("whole");
    ok(&["sweep", &file, "--out", &whole.display().to_string()]);
    assert_eq!(
        sorted_lines(&merged.join("runs.jsonl")),
        sorted_lines(&whole.join("runs.jsonl"))
    );
}

/// Regression: two sweeps into one directory both did all the work and left 2,388
/// duplicate lines. The directory is now locked for the run.
#[test]
fn a_second_sweep_into_a_busy_directory_is_refused() {
    let dir = temp("lock");
    let long = SMALL.replace("duration_s = 3.0", "duration_s = 60.0");
    let file = write_sweep(&dir, &long);
    let out = dir.join("out").display().to_string();
    let mut first = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["sweep", &file, "--out", &out, "--threads", "1"])
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    // Wait for the first to hold the lock (its manifest is written after the lock).
    let manifest = dir.join("out").join("sweep.json");
    let t0 = std::time::Instant::now();
    while !manifest.exists() && t0.elapsed() < std::time::Duration::from_secs(60) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let second = pma_exo(&["sweep", &file, "--out", &out]);
    let _ = first.kill();
    let _ = first.wait();
    let err = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{err}");
    assert!(err.contains("another `pma-exo sweep`"), "{err}");
}

/// Regression: a record appended by hand (or by another sweep) made a 36-run sweep report
/// 37 runs. Only the sweep's own run indices are accepted, once each.
#[test]
fn a_foreign_record_in_runs_jsonl_is_refused() {
    let dir = temp("foreign");
    let file = write_sweep(&dir, SMALL);
    let out = dir.join("out");
    let o = out.display().to_string();
    ok(&["sweep", &file, "--out", &o]);
    let runs = out.join("runs.jsonl");
    let text = std::fs::read_to_string(&runs).expect("runs");
    let first = text.lines().next().expect("a line");
    let mut v: serde_json::Value = serde_json::from_str(first).expect("json");
    v["run"] = serde_json::json!(10);
    std::fs::write(&runs, format!("{text}{v}\n")).expect("append");
    let again = pma_exo(&["sweep", &file, "--out", &o]);
    let err = String::from_utf8_lossy(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{err}");
    assert!(err.contains("not a record of this sweep"), "{err}");
    let merged = dir.join("merged").display().to_string();
    let m = pma_exo(&["sweep", "merge", &o, "--out", &merged]);
    assert_eq!(m.status.code(), Some(1));
}

/// A bench grid of two quick runs.
const TWO_RUNS: &str = r#"
name = "two"
duration_s = 1.0
[[grid]]
controllers = ["aprc-ndo", "pid"]
gains = ["default"]
references = ["sine"]
[grid.plants]
presets = ["ideal"]
"#;

/// Regression: a leg sweep stopped at the first run that failed (a scenario that leaves
/// physical bounds ended the whole sweep, exit 1, on every resume, naming neither run,
/// scenario nor sweep file). The run is recorded as failed with its scenario and message,
/// the others run, the summary counts it, and a resume does not run it again.
#[test]
fn a_leg_sweep_records_a_run_that_fails_and_goes_on() {
    let dir = temp("failed-run");
    let diverging = common::diverging_scenario(&dir);
    let file = write_sweep(
        &dir,
        &format!(
            "name = \"fails\"\nduration_s = 3.2\n[[leg]]\nscenarios = [\"gait_training\", \"{diverging}\", \"gait_training\"]\ncontrollers = [\"pid\"]\ngains = [\"leg\"]\n"
        ),
    );
    let out = dir.join("out");
    let o = out.display().to_string();
    let first = pma_exo(&["sweep", &file, "--out", &o]);
    let err = String::from_utf8_lossy(&first.stderr);
    assert!(first.status.success(), "{err}");
    let warning = err
        .lines()
        .find(|l| l.contains("failed"))
        .unwrap_or_else(|| panic!("no warning: {err}"));
    for needle in ["run 1", "diverging.toml", "physical bounds", "sweep.toml"] {
        assert!(warning.contains(needle), "{needle}: {warning}");
    }
    let lines = sorted_lines(&out.join("runs.jsonl"));
    assert_eq!(lines.len(), 3, "{lines:?}");
    let failed: serde_json::Value = serde_json::from_str(&lines[1]).expect("json");
    assert_eq!(failed["run"], 1);
    assert_eq!(failed["scenario"], diverging.as_str());
    assert!(
        failed["failed"]
            .as_str()
            .is_some_and(|m| m.contains("physical bounds")),
        "{failed}"
    );
    for good in [&lines[0], &lines[2]] {
        let v: serde_json::Value = serde_json::from_str(good).expect("json");
        assert_eq!(v["finite"], true, "{good}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("summary"))
            .expect("json");
    assert_eq!(summary["runs"], 3);
    assert_eq!(summary["failed"], 1);
    assert_eq!(summary["failed_runs"][0]["run"], 1);
    let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(
        md.contains("Runs that failed: 1") && md.contains("diverging.toml"),
        "{md}"
    );
    // A resume runs nothing again: the failed run is a result of the sweep.
    let again = pma_exo(&["sweep", &file, "--out", &o]);
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success(), "{err}");
    assert!(
        err.contains("0 runs now") && !err.contains("warning"),
        "{err}"
    );
    assert_eq!(sorted_lines(&out.join("runs.jsonl")), lines);
    // A merge carries it too.
    let merged = dir.join("merged").display().to_string();
    ok(&["sweep", "merge", &o, "--out", &merged]);
    assert_eq!(sorted_lines(&dir.join("merged").join("runs.jsonl")), lines);
}

/// Regression: a sweep directory kept its `.lock` file after the run. It is removed when
/// the sweep ends (a killed sweep's stale lock is still taken over, as
/// `a_killed_sweep_resumes_and_loses_nothing` shows).
#[test]
fn a_sweep_directory_keeps_no_lock_after_the_run() {
    let dir = temp("no-lock");
    let file = write_sweep(&dir, TWO_RUNS);
    let out = dir.join("out");
    ok(&["sweep", &file, "--out", &out.display().to_string()]);
    assert!(out.join("runs.jsonl").is_file());
    assert!(!out.join(".lock").exists());
}

/// Regression: `sweep merge sh1 sh2 --out sh1` rewrote its input shard. An --out that is
/// one of the shards is refused, before anything is written.
#[test]
fn sweep_merge_refuses_to_write_into_one_of_its_shards() {
    let dir = temp("merge-in-out");
    let file = write_sweep(&dir, TWO_RUNS);
    let s = |p: &Path| p.display().to_string();
    let (a, b) = (dir.join("a"), dir.join("b"));
    ok(&["sweep", &file, "--out", &s(&a), "--shard", "1/2"]);
    ok(&["sweep", &file, "--out", &s(&b), "--shard", "2/2"]);
    let before = std::fs::read_to_string(a.join("runs.jsonl")).expect("shard");
    let a_again = format!("{}/", s(&a));
    let out = pma_exo(&["sweep", "merge", &s(&a), &s(&b), "--out", &a_again]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--out") && err.contains("shard directory"),
        "{err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert_eq!(
        std::fs::read_to_string(a.join("runs.jsonl")).expect("shard"),
        before
    );
    assert!(!a.join("summary.json").exists());
}

/// Regression: `sweep merge` with a shard missing wrote a summary and then exited 1. The
/// shards are checked first, and nothing is written.
#[test]
fn sweep_merge_with_missing_shards_writes_nothing() {
    let dir = temp("merge-missing");
    let file = write_sweep(&dir, TWO_RUNS);
    let a = dir.join("a");
    ok(&[
        "sweep",
        &file,
        "--out",
        &a.display().to_string(),
        "--shard",
        "1/2",
    ]);
    let merged = dir.join("merged");
    let out = pma_exo(&[
        "sweep",
        "merge",
        &a.display().to_string(),
        "--out",
        &merged.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("missing") && err.contains("nothing written"),
        "{err}"
    );
    assert!(!merged.exists());
}

/// Issue 49: a sweep over the two-legged trainer wrote `"hip_rms_deg": null` (the joints
/// are `right/hip`, `left/hip`), then could not read its own `runs.jsonl` ("line 1 is not
/// a run record"), so neither a resumed sweep nor `sweep merge` worked. Each record now
/// has the legs' figures and each leg's, and whether the patient walked; the sweep reads
/// its lines back, resumes and merges.
#[test]
fn a_sweep_over_the_two_legged_trainer_resumes_and_merges() {
    let dir = temp("trainer");
    let file = write_sweep(
        &dir,
        "name = \"trainer\"\nduration_s = 4.0\n[[leg]]\nscenarios = [\"gait_treadmill\"]\ncontrollers = [\"pid\", \"aprc-ndo\"]\ngains = [\"leg\"]\n",
    );
    let out = dir.join("out");
    let o = out.display().to_string();
    ok(&["sweep", &file, "--out", &o]);
    let lines = sorted_lines(&out.join("runs.jsonl"));
    assert_eq!(lines.len(), 2, "{lines:?}");
    for l in &lines {
        let v: serde_json::Value = serde_json::from_str(l).expect("json");
        assert!(v["hip_rms_deg"].as_f64().is_some(), "{v}");
        let legs = v["legs"].as_object().expect("legs");
        assert_eq!(legs.len(), 2, "{v}");
        assert!(legs["left"]["knee_rms_deg"].as_f64().is_some(), "{v}");
        assert!(v["walking"].is_boolean(), "{v}");
    }
    // Resumed: nothing rerun, the lines read back.
    ok(&["sweep", &file, "--out", &o]);
    assert_eq!(sorted_lines(&out.join("runs.jsonl")), lines);
    let merged = dir.join("merged").display().to_string();
    ok(&["sweep", "merge", &o, "--out", &merged]);
    assert!(dir.join("merged/summary.json").is_file());
}
