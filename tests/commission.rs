//! `rig commission` on the virtual rig (issue 26): it stops at every stage when the operator
//! says so, refuses every bad argument before the muscle moves, takes a configured
//! controller that faults as a result, and says what ran.
use pma_rig::config::EMBEDDED_VIRTUAL;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{mpsc, Mutex, MutexGuard};
use std::time::Duration;

/// One commissioning at a time in this test binary. A real-time rig's logs degrade when
/// its loop shares the 2 cores with another commissioning's tuning, and a degraded
/// excitation stops the command at identification (fit below 90 %) before the stage a
/// signal test is about (regression: the stage-5 SIGINT test failed in CI at 83-89 %).
fn one_at_a_time() -> MutexGuard<'static, ()> {
    static CHILD: Mutex<()> = Mutex::new(());
    // A failed test poisons the lock; the next one still runs alone.
    CHILD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn pma_exo(args: &[impl AsRef<std::ffi::OsStr>]) -> std::process::Output {
    let _alone = one_at_a_time();
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run pma-exo")
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pma-exo-commission-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// The virtual rig with the `realistic` plant and `edits` applied (each must change the
/// text), written into `dir`.
fn rig_config(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = EMBEDDED_VIRTUAL.to_owned();
    for (from, to) in [("plant = \"mismatch\"", "plant = \"realistic\"")]
        .iter()
        .chain(edits)
    {
        let edited = text.replace(from, to);
        assert_ne!(edited, text, "no `{from}` in the configuration");
        text = edited;
    }
    let path = dir.join(name);
    std::fs::write(&path, text).expect("config");
    path
}

/// A real-time virtual rig (wall-clock periods, like the real one) whose runs last
/// `duration_s`; its overrun limits at their loosest, so that a loaded 2-core machine does
/// not end a run in a timing fault before the signal arrives (the signal is tested here,
/// not the machine's timing).
fn realtime_config(dir: &Path, duration_s: u32) -> PathBuf {
    rig_config(
        dir,
        "realtime.toml",
        &[
            ("clock = \"lockstep\"", "clock = \"realtime\""),
            ("duration_s = 20.0", &format!("duration_s = {duration_s}.0")),
            (
                "watchdog_periods = 50",
                "watchdog_periods = 50\noverrun_max_consecutive_periods = 49\noverrun_max_share = 0.5",
            ),
        ],
    )
}

/// `rig commission --config CONFIG --out OUT --load-kg 2.5 EXTRA --json`.
fn commission(config: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "rig",
        "commission",
        "--config",
        &s(config),
        "--out",
        &s(out),
    ]
    .map(str::to_owned)
    .to_vec();
    if !extra.contains(&"--load-kg") {
        args.extend(["--load-kg".into(), "2.5".into()]);
    }
    args.extend(extra.iter().map(|a| (*a).to_owned()));
    args.push("--json".into());
    args
}

/// What a process said and how it ended.
struct Ended {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

/// Runs `pma-exo args`, sends `signal` `delay` after a line of its stderr contains `marker`
/// (a stage's heading; the delay lets a rig run start), and waits for it to end. A process that does not end within 10 minutes of the signal is
/// killed and fails the test (it ignored the signal).
#[cfg(unix)]
fn signal_at(args: &[String], marker: &str, delay: Duration, signal: libc::c_int) -> Ended {
    let _alone = one_at_a_time();
    let mut child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    let marker = marker.to_owned();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if line.contains(&marker) {
                let _ = tx.send(());
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let pid = child.id() as libc::pid_t;
    let signalled = rx.recv().is_ok();
    if signalled {
        std::thread::sleep(delay);
        // SAFETY: signalling our own child.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
    }
    let (done_tx, done_rx) = mpsc::channel::<()>();
    let guard = std::thread::spawn(move || {
        if done_rx.recv_timeout(Duration::from_secs(600)).is_err() {
            // SAFETY: killing our own child, which ignored the signal.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
    });
    let mut stdout = String::new();
    if let Some(mut out) = child.stdout.take() {
        std::io::Read::read_to_string(&mut out, &mut stdout).expect("stdout");
    }
    let status = child.wait().expect("wait");
    let _ = done_tx.send(());
    guard.join().expect("guard");
    let stderr = reader.join().expect("reader");
    assert!(signalled, "the stage heading never came: {stderr}");
    Ended {
        code: status.code(),
        stdout,
        stderr,
    }
}

/// The last row of a rig log: (event, fault).
fn last_row(log: &Path) -> (String, String) {
    let mut r = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(log)
        .expect("log");
    let h = r.headers().expect("headers").clone();
    let col = |n: &str| h.iter().position(|c| c == n).expect("column");
    let (event, fault) = (col("event"), col("fault"));
    let last = r
        .records()
        .map(|row| row.expect("row"))
        .last()
        .expect("a row");
    (last[event].to_owned(), last[fault].to_owned())
}

/// Asserts a commissioning the operator stopped at `stage`: exit 130, the run under way
/// (its log `running`, if one was) vented and logged as interrupted, no later stage's
/// file, no gains kept, and a report that says so (never "stopped by the supervisor").
fn assert_interrupted_at(
    ended: &Ended,
    out: &Path,
    stage: u32,
    running: Option<&str>,
    later: &[&str],
) {
    let all = format!("{}{}", ended.stdout, ended.stderr);
    assert_eq!(ended.code, Some(130), "{all}");
    let said = format!("interrupted at stage {stage} by the operator");
    assert!(ended.stderr.contains(&said), "{all}");
    let report = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(
        report.contains(&format!("Interrupted at stage {stage} by the operator")),
        "{report}"
    );
    assert!(!report.contains("stopped by the supervisor"), "{report}");
    for f in later.iter().chain(&["gains.toml"]) {
        assert!(!out.join(f).exists(), "{f} written after the stop: {all}");
    }
    let v: serde_json::Value = serde_json::from_str(&ended.stdout).expect("json");
    assert_eq!(v["interrupted_at_stage"], stage, "{v}");
    assert!(v["kept"].is_null(), "{v}");
    if let Some(log) = running {
        assert_eq!(
            last_row(&out.join(log)),
            ("vent".into(), "interrupted".into()),
            "{log}"
        );
    }
}

/// Regression: SIGINT during the run before (stage 1) ended `rig commission` with status 1
/// and an error instead of 130.
#[cfg(unix)]
#[test]
fn commission_stops_on_sigint_during_the_run_before_with_status_130() {
    let d = dir("sigint-1");
    let config = realtime_config(&d, 60);
    let out = d.join("com");
    let ended = signal_at(
        &commission(&config, &out, &[]),
        "[1/5]",
        Duration::from_secs(1),
        libc::SIGINT,
    );
    assert_interrupted_at(
        &ended,
        &out,
        1,
        Some("before.csv"),
        &["excite.csv", "plant.toml"],
    );
    std::fs::remove_dir_all(d).ok();
}

/// Regression: SIGTERM during the excitation (stage 2) ended `rig commission` with status 1.
#[cfg(unix)]
#[test]
fn commission_stops_on_sigterm_during_the_excitation_with_status_130() {
    let d = dir("sigterm-2");
    let config = realtime_config(&d, 2);
    let out = d.join("com");
    let ended = signal_at(
        &commission(&config, &out, &["--excite-duration", "120"]),
        "[2/5]",
        Duration::from_secs(1),
        libc::SIGTERM,
    );
    assert_interrupted_at(
        &ended,
        &out,
        2,
        Some("excite.csv"),
        &["plant.toml", "after-current-gains.csv"],
    );
    std::fs::remove_dir_all(d).ok();
}

/// Regression: `rig commission` ignored SIGINT and SIGTERM during identification (stage
/// 3) and went on to tune and to move the muscle again.
#[cfg(unix)]
#[test]
fn commission_stops_on_sigterm_during_identification() {
    let d = dir("sigterm-3");
    let config = rig_config(&d, "rig.toml", &[]);
    let out = d.join("com");
    let ended = signal_at(
        &commission(&config, &out, &["--excite-duration", "300"]),
        "[3/5]",
        Duration::ZERO,
        libc::SIGTERM,
    );
    assert_interrupted_at(
        &ended,
        &out,
        3,
        None,
        &["plant.toml", "after-current-gains.csv"],
    );
    assert!(out.join("excite.csv").exists());
    std::fs::remove_dir_all(d).ok();
}

/// Regression: `rig commission --generations 100000000` announced a 48,000,000 s tuning and
/// ran through SIGINT and SIGTERM (only SIGKILL stopped it), then verified on the rig.
#[cfg(unix)]
#[test]
fn commission_stops_on_sigint_during_tuning() {
    let d = dir("sigint-4");
    let config = rig_config(&d, "rig.toml", &[]);
    let out = d.join("com");
    let ended = signal_at(
        &commission(
            &config,
            &out,
            &[
                "--excite-duration",
                "20",
                "--generations",
                "100000",
                "--yes",
            ],
        ),
        "[4/5]",
        Duration::ZERO,
        libc::SIGINT,
    );
    assert_interrupted_at(&ended, &out, 4, None, &["after-current-gains.csv"]);
    assert!(out.join("plant.toml").exists());
    std::fs::remove_dir_all(d).ok();
}

/// Regression: SIGINT 2 s into stage 5 on a real-time rig: the first verification ended
/// "interrupted", then the tuned gains' run still moved the muscle, the tuned gains were
/// kept and the report called the interruption "stopped by the supervisor".
#[cfg(unix)]
#[test]
fn commission_runs_no_further_verification_after_sigint_in_stage_5() {
    let d = dir("sigint-5");
    let config = realtime_config(&d, 10);
    let out = d.join("com");
    let ended = signal_at(
        &commission(
            &config,
            &out,
            &[
                "--excite-duration",
                "20",
                "--robust",
                "1",
                "--population",
                "2",
                "--generations",
                "1",
                // What is tested is the stop in stage 5, not the identification: a loaded
                // 2-core machine degrades a real-time rig's excitation (83.1-89.1 % in
                // CI, 98.3-99.8 % idle), which the default 90 % would stop at stage 3.
                "--min-fit",
                "50",
            ],
        ),
        "[5/5]",
        Duration::from_secs(1),
        libc::SIGINT,
    );
    assert_interrupted_at(
        &ended,
        &out,
        5,
        Some("after-current-gains.csv"),
        &["after-tuned-gains.csv"],
    );
    std::fs::remove_dir_all(d).ok();
}

/// Regression: `rig commission` checked its arguments after the muscle had moved:
/// `--load-kg 0/-1/1e9/nan`, `--spread 0.6/nan` and `--excite-duration 0/nan` (reported as
/// "--duration") after one or two rig runs, `--added-mass-kg 0` after two excitations,
/// `--population/--generations` after stages 1-3 (then an allocation abort, exit 134). Each
/// is now refused in one line naming it, before stage 1, with nothing written, and the
/// tuning's bounds are `tune`'s.
#[test]
fn commission_refuses_every_bad_argument_before_the_muscle_moves() {
    let d = dir("refused");
    let config = rig_config(&d, "rig.toml", &[]);
    let out = d.join("com");
    let w = "--load-kg";
    let cases: [(&[&str], &str); 18] = [
        (&[w, "0"], "--load-kg"),
        (&[w, "2.5", "--min-fit", "101"], "--min-fit"),
        (&[w, "2.5", "--min-fit", "nan"], "--min-fit"),
        (&[w, "-1"], "--load-kg"),
        (&[w, "1e9"], "--load-kg"),
        (&[w, "nan"], "--load-kg"),
        (&[w, "2.5", "--spread", "0.6"], "--spread"),
        (&[w, "2.5", "--spread", "nan"], "--spread"),
        (&[w, "2.5", "--excite-duration", "0"], "--excite-duration"),
        (&[w, "2.5", "--excite-duration", "nan"], "--excite-duration"),
        (&[w, "2.5", "--excite-duration", "5"], "--excite-duration"),
        (&["--added-mass-kg", "0"], "--added-mass-kg"),
        (&[w, "2.5", "--population", "100000000"], "--population"),
        (
            &[w, "2.5", "--population", "18446744073709551615"],
            "--population",
        ),
        (&[w, "2.5", "--generations", "100000000"], "--generations"),
        (&[w, "2.5", "--robust", "0"], "--robust"),
        (&[w, "2.5", "--max-variation", "nan"], "--max-variation"),
        // Within the bounds, but days of tuning: refused unless --yes, as `tune` does.
        (&[w, "2.5", "--generations", "100000"], "pass --yes"),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["rig", "commission", "--config"];
        let (c, o) = (s(&config), s(&out));
        args.extend([c.as_str(), "--out", o.as_str()]);
        args.extend(extra);
        let run = pma_exo(&args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{extra:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} created the output directory");
    }
    // One definition of the search's bounds: the same refusal as `tune`'s.
    let refusal = |args: &[&str]| String::from_utf8_lossy(&pma_exo(args).stderr).into_owned();
    let (c, o) = (s(&config), s(&out));
    assert_eq!(
        refusal(&[
            "rig",
            "commission",
            "--config",
            &c,
            "--out",
            &o,
            w,
            "2.5",
            "--population",
            "10001"
        ]),
        refusal(&["tune", "--controller", "pid", "--population", "10001"])
    );
    std::fs::remove_dir_all(d).ok();
}

/// Regression: a commissioning refused at the board (a device that cannot be opened) or not
/// confirmed at the first question left an empty `--out` directory behind, and the retry
/// was refused because it existed.
#[test]
fn a_commissioning_that_never_moved_leaves_no_directory_to_block_a_retry() {
    let d = dir("no-empty-dir");
    let out = d.join("com");
    let args = [
        "rig",
        "commission",
        "--config",
        "pci6052e",
        "--out",
        &s(&out),
        "--load-kg",
        "2.5",
    ];
    // This build has no Comedi, or this machine no board: the device cannot be opened.
    let run = pma_exo(&[&args[..], &["--yes"]].concat());
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(err.contains("/dev/comedi0"), "{err}");
    assert!(!out.exists(), "{err}");
    // A real board asks first; "no" is not a confirmation.
    let mut child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn");
    std::io::Write::write_all(&mut child.stdin.take().expect("stdin"), b"no\n").expect("answer");
    let run = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(err.contains("not confirmed"), "{err}");
    assert!(!out.exists(), "{err}");
    std::fs::remove_dir_all(d).ok();
}

/// Regression: `rig excite --json` reported an RTE of 53.7 % for an open-loop excitation,
/// which tracks nothing. It reports what the excitation spanned instead.
#[test]
fn an_excitation_reports_its_span_not_a_tracking_error() {
    let d = dir("excite-span");
    let log = d.join("excite.csv");
    let run = pma_exo(&[
        "rig",
        "excite",
        "--duration",
        "20",
        "--out",
        &s(&log),
        "--json",
    ]);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).expect("json");
    for tracking in ["rte_percent", "iae_m", "mae_m"] {
        assert!(v.get(tracking).is_none(), "{tracking} in {v}");
    }
    let e = &v["excitation"];
    let num = |k: &str| e[k].as_f64().unwrap_or_else(|| panic!("{k} in {v}"));
    // The shipped rig excites from 0.5 bar to half its 6 bar limit.
    assert!(num("command_min_bar") <= 0.5, "{v}");
    assert!(num("command_max_bar") >= 2.9, "{v}");
    assert!(num("command_rms_bar") > 0.05, "{v}");
    assert!(num("position_max_mm") - num("position_min_mm") > 1.0, "{v}");
    let text = pma_exo(&[
        "rig",
        "excite",
        "--duration",
        "20",
        "--out",
        &s(&d.join("excite-2.csv")),
    ]);
    let said = String::from_utf8_lossy(&text.stdout);
    assert!(!said.contains("RTE"), "{said}");
    assert!(
        said.contains("bar RMS about their mean), position "),
        "{said}"
    );
    std::fs::remove_dir_all(d).ok();
}

/// Regression: under `--controller pid` the report labelled the run before "configured
/// gains" and nominal, while PID with its default gains had run. Every run is named by
/// what ran: the controller, where its gains came from, what it was told.
#[test]
fn the_commissioning_report_names_the_controller_and_gains_that_ran() {
    let d = dir("pid-labels");
    let config = rig_config(&d, "rig.toml", &[]);
    let out = d.join("com");
    let run = pma_exo(&commission(
        &config,
        &out,
        &[
            "--controller",
            "pid",
            "--excite-duration",
            "20",
            "--robust",
            "1",
            "--population",
            "2",
            "--generations",
            "1",
        ],
    ));
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).expect("json");
    let before = v["before"]["what"].as_str().expect("before.what");
    assert_eq!(
        before,
        "pid, its default gains (--controller; the configuration's is aprc-ndo), the configuration's nominal"
    );
    assert!(v["told"]["what"]
        .as_str()
        .expect("told.what")
        .starts_with("pid, its default gains"));
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    assert!(
        report.contains(&format!("| before (`before.csv`) | {before} |")),
        "{report}"
    );
    assert!(!report.contains("configured gains"), "{report}");
    std::fs::remove_dir_all(d).ok();
}

/// A muscle the program was not told about (the issue's: a 14 ms valve with 3 ms of dead
/// time, 3.6 kg, every Table I factor moved), on the virtual rig whose controller keeps
/// Table I, 2 kg and no lag.
const UNKNOWN_MUSCLE: &str = r#"name = "unknown"
description = "a muscle the program was not told about"
[nominal]
mass_kg = 2.0
[muscle]
f0_scale = 0.9
f1_scale = 1.1
k0_scale = 1.15
k1_scale = 0.9
b0_inflation_scale = 1.2
b1_inflation_scale = 0.8
b0_deflation_scale = 1.2
b1_deflation_scale = 0.8
[load]
mass_kg = 3.6
[valve]
pressure_max_pa = 6.0e5
time_constant_s = 0.014
dead_time_s = 0.003
[sensor]
range_min_m = -0.05
range_max_m = 0.15
"#;

/// Regression: on a muscle the program was not told about, the run before with the paper's
/// gains hit the position window and `rig commission` ended there ("the run before
/// stopped: position-out"): the case commissioning exists for. The fault is a result
/// (recorded with its time and the RTE up to it) and every stage after it runs.
#[test]
fn commission_goes_on_when_the_configured_controller_faults_before() {
    let d = dir("before-faults");
    let plant = d.join("unknown.toml");
    std::fs::write(&plant, UNKNOWN_MUSCLE).expect("plant");
    let config = rig_config(
        &d,
        "rig.toml",
        &[(
            "plant = \"realistic\"",
            &format!("plant = \"{}\"", s(&plant)),
        )],
    );
    let out = d.join("com");
    let run = pma_exo(&commission(
        &config,
        &out,
        &[
            "--load-kg",
            "3.6",
            "--excite-duration",
            "30",
            "--robust",
            "2",
            "--population",
            "4",
            "--generations",
            "1",
        ],
    ));
    let err = String::from_utf8_lossy(&run.stderr);
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).expect("json");
    let before = &v["before"];
    assert_eq!(before["fault"], "position-out", "{v}\n{err}");
    let at_s = before["faulted_at_s"].as_f64().expect("faulted_at_s");
    assert!(at_s > 2.0 && at_s < 20.0, "{at_s}");
    assert!(before["rte_percent"].as_f64().expect("rte").is_finite());
    assert!(v["rte_before_percent"].is_null(), "{v}");
    // Identification, tuning and verification ran after it.
    let lag_s = v["identified"]["valve_lag_s"].as_f64().expect("lag");
    assert!((lag_s - 0.017).abs() < 0.0017, "identified lag {lag_s} s");
    assert!(out.join("plant.toml").exists());
    assert!(v["told"]["log"].is_string(), "{v}");
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    let row = report
        .lines()
        .find(|l| l.starts_with("| before (`before.csv`)"))
        .expect("the before row");
    assert!(
        row.contains(&format!("faulted at {at_s:.1} s: `position-out`")),
        "{row}"
    );
    // On this muscle the paper's gains fault even told the identified plant, and what the
    // tuning finds may track worse: said, and nothing kept.
    if v["kept"].is_null() {
        assert_eq!(run.status.code(), Some(1), "{err}");
        assert!(err.contains("no gain set to keep"), "{err}");
        assert!(!out.join("gains.toml").exists());
    } else {
        assert_eq!(run.status.code(), Some(0), "{err}");
    }
    std::fs::remove_dir_all(d).ok();
}
