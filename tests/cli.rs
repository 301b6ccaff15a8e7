//! The `pma-exo` binary: JSON output, files, and one-line errors on bad input.
use std::process::Command;

fn pma_exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .output()
        .expect("run pma-exo")
}

fn assert_one_line_error(args: &[&str], needle: &str) {
    let out = pma_exo(args);
    assert!(!out.status.success(), "{args:?} succeeded");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

#[test]
fn single_prints_the_metrics_as_json() {
    let out = pma_exo(&[
        "single",
        "--controller",
        "aprc-ndo",
        "--reference",
        "sine",
        "--plant",
        "ideal",
        "--duration",
        "2",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "controller",
        "reference",
        "plant",
        "mae_m",
        "iae_m",
        "rte_percent",
        "rms_m",
        "real_time_factor",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    assert_eq!(v["controller"], "aprc-ndo");
    assert_eq!(v["plant"], "ideal");
    // The binary reports what the library computes for the same run.
    let lib = pma_sim::run_single(
        &pma_control::ControllerKind::AprcNdo.default_config(),
        &pma_sim::PlantConfig::preset("ideal").unwrap(),
        &pma_control::SineReference::paper(),
        &pma_sim::RunSpec {
            duration_s: 2.0,
            ..Default::default()
        },
        &mut (),
    )
    .unwrap();
    assert_eq!(v["iae_m"].as_f64().unwrap(), lib.stats.iae_m);
    assert_eq!(v["mae_m"].as_f64().unwrap(), lib.stats.mae_m);
    assert_eq!(v["samples"].as_u64().unwrap(), 2000);
    let rte = v["rte_percent"].as_f64().unwrap();
    assert!(
        (rte - lib.stats.iae_m / 0.030 * 100.0).abs() < 1e-9,
        "RTE {rte}"
    );
}

#[test]
fn single_writes_the_csv_time_series() {
    let dir = std::env::temp_dir().join(format!("pma-exo-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("run.csv");
    let out = pma_exo(&[
        "single",
        "--controller",
        "pid",
        "--duration",
        "0.5",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,reference_m,position_m,pressure_cmd_pa,pressure_pa,proxy_m,s_p,s_q,gain_hat,disturbance_hat"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 500);
    // PID has no proxy: NaN there, not a made-up number.
    assert!(rows[0]
        .split(',')
        .nth(5)
        .unwrap()
        .eq_ignore_ascii_case("nan"));
}

#[test]
fn bad_input_gives_one_line_errors() {
    assert_one_line_error(&["single", "--controller", "lqr"], "lqr");
    assert_one_line_error(&["single", "--duration", "-3"], "duration");
    assert_one_line_error(&["single", "--duration", "nan"], "duration");
    assert_one_line_error(&["single", "--plant", "vacuum"], "vacuum");
    let dir = std::env::temp_dir().join(format!("pma-exo-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_owned()
    };
    let f = write("unknown.toml", "controller = \"aprc-ndo\"\nkp = 1.0\n");
    assert_one_line_error(&["single", "--gains", &f], "kp");
    let f = write(
        "malformed.toml",
        "controller = \"aprc-ndo\"\nc1_per_s = = 3\n",
    );
    assert_one_line_error(&["single", "--gains", &f], "malformed.toml");
    let f = write("nan.toml", "controller = \"aprc-ndo\"\nki_per_s3 = nan\n");
    assert_one_line_error(&["single", "--gains", &f], "ki_per_s3");
    let f = write(
        "varpi.toml",
        "controller = \"aprc-ndo\"\nkp_per_s2 = 10.0\n",
    );
    assert_one_line_error(&["single", "--gains", &f], "varpi");
    let f = write("pid.toml", "controller = \"pid\"\n");
    assert_one_line_error(&["single", "--controller", "sta", "--gains", &f], "pid");
    assert_one_line_error(
        &["single", "--gains", "/nonexistent/gains.toml"],
        "gains.toml",
    );
    let f = write("plant.toml", "name = \"x\"\n");
    assert_one_line_error(&["single", "--plant", &f], "plant.toml");
    let f = write(
        "lag.toml",
        &include_str!("../models/plants/realistic_known_lag.toml").replace(
            "valve_time_constant_s = 0.020\n\n[muscle]",
            "valve_time_constant_s = -0.020\n\n[muscle]",
        ),
    );
    assert_one_line_error(&["single", "--plant", &f], "valve_time_constant_s");
    assert_one_line_error(
        &["tune", "--controller", "pid", "--max-variation", "-1"],
        "max-variation",
    );
}

#[test]
fn tune_keeps_the_activity_budget_or_says_it_cannot() {
    let small = [
        "tune",
        "--controller",
        "pid",
        "--population",
        "4",
        "--generations",
        "3",
        "--duration",
        "4",
    ];
    let out = pma_exo(&[&small[..], &["--max-variation", "3"]].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let variation: f64 = text
        .split("command variation ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no variation in the header: {text}"));
    assert!(variation <= 3.0, "{text}");
    assert!(text.contains("--max-variation 3"), "{text}");
    // The sine needs about 1 bar/s of pressure change: 0.01 cannot be met.
    assert_one_line_error(
        &[&small[..], &["--max-variation", "0.01"]].concat(),
        "budget",
    );
}

#[test]
fn paper_writes_results_report_and_plots() {
    let dir = std::env::temp_dir().join(format!("pma-exo-paper-{}", std::process::id()));
    let out = pma_exo(&["paper", "--out", dir.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    for key in [
        "table2",
        "chirp",
        "mp_sweep",
        "amplitudes",
        "load_step",
        "equal_activity",
    ] {
        assert!(v[key].as_array().is_some_and(|a| !a.is_empty()), "{key}");
        let png = std::fs::read(dir.join(format!("{key}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{key}.png");
    }
    for key in ["controller", "mae_m", "iae_m", "rte_percent"] {
        assert!(v["table2"][0].get(key).is_some(), "table2 lacks {key}");
    }
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("Table II") && md.contains("| aprc-ndo | paper |"));
}

#[test]
fn simulate_prints_the_gait_metrics_as_json() {
    let out = pma_exo(&["simulate", "--duration", "3.2", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["scenario"], "gait_training");
    assert_eq!(v["duration_s"], 3.2);
    for joint in ["hip", "knee"] {
        for key in ["rms_deg", "max_deg"] {
            assert!(
                v["joints"][joint][key].as_f64().is_some(),
                "joints.{joint}.{key} in {v}"
            );
        }
    }
    for m in ["hip_flexor", "hip_extensor", "knee_flexor", "knee_extensor"] {
        for key in ["p_min_pa", "p_max_pa", "slack_s"] {
            assert!(
                v["muscles"][m][key].as_f64().is_some(),
                "muscles.{m}.{key} in {v}"
            );
        }
    }
    assert!(
        v["cocontraction_pa"]["start"].as_f64().is_some()
            && v["cocontraction_pa"]["end"].as_f64().is_some()
    );
    assert!(v["real_time_factor"].as_f64().is_some_and(|r| r > 0.0));
}

#[test]
fn simulate_bad_input_gives_one_line_errors() {
    assert_one_line_error(
        &["simulate", "/nonexistent/scenario.toml"],
        "/nonexistent/scenario.toml",
    );
    assert_one_line_error(&["simulate", "gait_jogging"], "gait_jogging");
    assert_one_line_error(&["simulate", "--duration", "-2"], "duration");
}

#[test]
fn rerun_save_writes_an_rrd_recording_for_both_commands() {
    let dir = std::env::temp_dir().join(format!("pma-exo-rrd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (args, file) in [
        (vec!["simulate", "--duration", "0.5"], "leg.rrd"),
        (vec!["single", "--duration", "0.5"], "bench.rrd"),
    ] {
        let path = dir.join(file);
        let save = format!("save={}", path.display());
        let mut a = args.clone();
        a.extend(["--rerun", save.as_str(), "--rerun-hz", "100"]);
        let out = pma_exo(&a);
        assert!(
            out.status.success(),
            "{a:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..4], b"RRF2", "{file} is not an .rrd recording");
        assert!(bytes.len() > 1000, "{file}: {} bytes", bytes.len());
    }
}

#[test]
fn rerun_failures_are_one_line_errors_not_hangs() {
    assert_one_line_error(
        &[
            "simulate",
            "--duration",
            "0.2",
            "--rerun",
            "connect=rerun+http://127.0.0.1:1/proxy",
        ],
        "127.0.0.1:1",
    );
    assert_one_line_error(&["simulate", "--rerun", "viewer"], "viewer");
    assert_one_line_error(
        &[
            "simulate",
            "--duration",
            "0.2",
            "--rerun",
            "save=/tmp/x.rrd",
            "--rerun-hz",
            "0",
        ],
        "rerun-hz",
    );
    let out = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["simulate", "--duration", "0.2", "--rerun", "spawn"])
        .env("PATH", "/nonexistent")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("rerun-sdk==0.36.3"), "{err}");
}

/// Regression: a viewer that accepts the connection and then never reads used to hold the
/// process at exit without limit (the gRPC client flushes forever when dropped).
#[test]
fn a_stuck_viewer_is_a_warning_after_the_flush_timeout_not_a_hang() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    // Accepts and holds every connection, reads nothing.
    std::thread::spawn(move || {
        let mut held = Vec::new();
        for c in listener.incoming() {
            held.push(c);
        }
    });
    let t = std::time::Instant::now();
    let out = pma_exo(&[
        "single",
        "--duration",
        "1",
        "--json",
        "--rerun",
        &format!("connect=rerun+http://127.0.0.1:{port}/proxy"),
    ]);
    let waited = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("did not take the end of the recording"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["rte_percent"].as_f64().is_some());
    assert!(waited < 10.0 + 20.0, "held {waited} s");
}
