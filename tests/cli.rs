//! The `pma-exo` binary: JSON output, files, and one-line errors on bad input.
use std::process::Command;

mod common;
use common::Scratch;

fn pma_exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .output()
        .expect("run pma-exo")
}

/// Runs `pma-exo` and asserts it succeeded, showing its stderr if not.
fn pma_exo_ok(args: &[&str]) -> std::process::Output {
    let out = pma_exo(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
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
    let out = pma_exo_ok(&[
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
    let lib = pma_bench::run_single(
        &pma_control::ControllerKind::AprcNdo.default_config(),
        &pma_bench::PlantConfig::preset("ideal").unwrap(),
        &pma_control::SineReference::paper(),
        &pma_bench::RunSpec {
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
fn check_step_says_how_far_the_figures_move_at_half_the_step() {
    let json = |args: &[&str]| -> serde_json::Value {
        serde_json::from_slice(&pma_exo_ok(args).stdout).expect("JSON")
    };
    // APRC-NDO on the ideal plant gives the same figures at 4 and 8 substeps
    // (docs/convergence.md): converged.
    let ideal = json(&["single", "--check-step", "--json"]);
    assert_eq!(ideal["step"]["substeps_per_period"], 4);
    assert!((ideal["step"]["integration_step_s"].as_f64().unwrap() - 2.5e-4).abs() < 1e-12);
    let c = &ideal["check_step"];
    assert_eq!(c["substeps_per_period"], 8);
    assert_eq!(c["converged"], true, "{c}");
    assert!(c["moved"]["rte"].as_f64().unwrap() < 1e-3, "{c}");
    // Behind the realistic plant's 20 ms valve its RTE is 4.8 % at 4 substeps and 13.9 %
    // at 8: the step decides this one run's figure, and the run says so (over the noise's
    // seeds the means do not move: `seeds_report_each_figure_over_the_sensor_noise`).
    let lagging = json(&["single", "--plant", "realistic", "--check-step", "--json"]);
    let c = &lagging["check_step"];
    assert_eq!(c["converged"], false, "{c}");
    assert!(c["moved"]["rte"].as_f64().unwrap() > 0.5, "{c}");
    let text = pma_exo_ok(&["single", "--plant", "realistic", "--check-step"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("step 1 ms, 4 substeps"), "{text}");
    assert!(
        text.contains("at half the step (8 substeps)") && text.contains("moved more than 2 %"),
        "{text}"
    );
    // Twice the substeps must stay within the plant's own bound, checked before the run.
    let dir = temp("check-step");
    let plant = dir.join("fine.toml");
    let ideal_toml = include_str!("../crates/pma-bench/models/plants/ideal.toml");
    let fine = ideal_toml.replacen("\n[", "\nsubsteps_per_period = 600\n\n[", 1);
    std::fs::write(&plant, fine).unwrap();
    pma_exo_ok(&[
        "single",
        "--plant",
        plant.to_str().unwrap(),
        "--duration",
        "0.5",
    ]);
    assert_one_line_error(
        &["single", "--plant", plant.to_str().unwrap(), "--check-step"],
        "--check-step doubles the plant's substeps_per_period (600)",
    );
}

/// Issue 50: where a loop chatters behind a noisy sensor, one run's figure is one draw;
/// `--seeds N` reports the spread over N seeds, and the step is judged on the means.
#[test]
fn seeds_report_each_figure_over_the_sensor_noise() {
    let json = |args: &[&str]| -> serde_json::Value {
        serde_json::from_slice(&pma_exo_ok(args).stdout).expect("JSON")
    };
    let base = [
        "single",
        "--plant",
        "realistic",
        "--duration",
        "4",
        "--json",
    ];
    let v = json(&[&base[..], &["--seeds", "4", "--check-step"]].concat());
    let s = &v["seeds"];
    assert_eq!(
        (s["n"].as_u64(), s["first_seed"].as_u64()),
        (Some(4), Some(20200525))
    );
    let rte = |x: &serde_json::Value, k: &str| x["rte_percent"][k].as_f64().unwrap();
    // The first seed's run is the run's own figure; the others differ.
    let own = v["rte_percent"].as_f64().unwrap();
    assert!(rte(s, "min") <= own && own <= rte(s, "max"), "{s}");
    assert!(rte(s, "min") < rte(s, "max") && rte(s, "sd") > 0.0, "{s}");
    assert!(rte(s, "min") <= rte(s, "mean") && rte(s, "mean") <= rte(s, "max"));
    // The fourth seed's run, by hand, lies within the spread.
    let dir = temp("seeds");
    let plant = dir.join("seed.toml");
    let text = include_str!("../crates/pma-bench/models/plants/realistic.toml");
    std::fs::write(&plant, text.replace("seed = 20200525", "seed = 20200528")).unwrap();
    let other = json(&[
        "single",
        "--plant",
        plant.to_str().unwrap(),
        "--duration",
        "4",
        "--json",
    ]);
    let o = other["rte_percent"].as_f64().unwrap();
    assert!(
        rte(s, "min") <= o && o <= rte(s, "max") && o != own,
        "{o} {s}"
    );
    // At half the step, the same seeds, and whether the mean moved beyond their scatter.
    let c = &v["check_step"]["seeds"];
    assert_eq!(c["n"].as_u64(), Some(4));
    assert!(c["within_scatter"]["rte"].is_boolean(), "{c}");
    let text = pma_exo_ok(&[
        "single",
        "--plant",
        "realistic",
        "--duration",
        "4",
        "--seeds",
        "3",
        "--check-step",
    ]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("at the step over 3 seeds (20200525..=20200527)"),
        "{text}"
    );
    assert!(text.contains("the mean RTE moved"), "{text}");
    assert_one_line_error(
        &["single", "--seeds", "3"],
        "plant `ideal` has no sensor noise",
    );
    assert_one_line_error(
        &["single", "--plant", "realistic", "--seeds", "1"],
        "--seeds 1 is invalid: 2 to 100",
    );
    assert_one_line_error(
        &["single", "--plant", "realistic", "--seeds", "101"],
        "--seeds 101 is invalid",
    );
}

#[test]
fn simulate_check_step_reruns_at_half_the_physics_step() {
    let out = pma_exo_ok(&["simulate", "--duration", "8", "--check-step", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(v["step"]["physics_substeps"], 64, "{}", v["step"]);
    assert_eq!(v["step"]["implicit_muscle_damping"], false);
    let c = &v["check_step"];
    assert_eq!(c["physics_substeps"], 128, "{c}");
    let mut within = true;
    for joint in ["hip", "knee"] {
        let j = &c["joints"][joint];
        let (first, refined) = (
            v["joints"][joint]["rms_deg"].as_f64().unwrap(),
            j["rms_deg"].as_f64().unwrap(),
        );
        let moved = j["moved_rms"].as_f64().unwrap();
        assert!(
            ((refined - first).abs() / first - moved).abs() < 1e-12,
            "{joint}: {j}"
        );
        within &= moved <= 0.02 && j["moved_max"].as_f64().unwrap() <= 0.02;
    }
    assert_eq!(c["converged"], within, "{c}");
    // Twice the substeps must stay within their bound: refused before anything runs.
    let dir = temp("check-step-leg");
    let file = dir.join("fine.toml");
    let text = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml").replacen(
        "physics_substeps = 64",
        "physics_substeps = 200",
        1,
    );
    std::fs::write(&file, text).unwrap();
    assert_one_line_error(
        &["simulate", file.to_str().unwrap(), "--check-step"],
        "--check-step takes physics_substeps from 200 to 400, over its bound of 256",
    );
}

#[test]
fn single_writes_the_csv_time_series() {
    let dir = Scratch::new("cli");
    let csv = dir.join("run.csv");
    pma_exo_ok(&[
        "single",
        "--controller",
        "pid",
        "--duration",
        "0.5",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    // The first line says what ran (issue 18), then the header.
    let what = lines.next().unwrap();
    assert!(
        what.starts_with("# pma-exo ")
            && what.contains("`pma-exo single --controller pid")
            && what.contains("controller pid"),
        "{what}"
    );
    assert_eq!(
        lines.next().unwrap(),
        "t_s,reference_m,position_m,pressure_cmd_pa,pressure_pa,proxy_m,s_p,s_q,gain_hat,disturbance_hat,measured_m,force_n,velocity_estimate_m_s"
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
    let dir = Scratch::new("bad");
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
        &include_str!("../crates/pma-bench/models/plants/realistic_known_lag.toml").replace(
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

/// A group of a study's summary in results.json.
fn group<'a>(v: &'a serde_json::Value, study: &str, m: &[(&str, &str)]) -> &'a serde_json::Value {
    v[study]["groups"]
        .as_array()
        .and_then(|g| {
            g.iter()
                .find(|x| m.iter().all(|(k, want)| x[*k].as_str() == Some(*want)))
        })
        .unwrap_or_else(|| panic!("{study}: no group {m:?}"))
}

/// An event's figures in a group.
fn event<'a>(g: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    g["events"]
        .as_array()
        .and_then(|e| e.iter().find(|x| x["name"] == name))
        .unwrap_or_else(|| panic!("no event {name} in {g}"))
}

#[test]
fn paper_writes_results_report_and_plots() {
    let dir = Scratch::new("paper");
    pma_exo_ok(&["paper", "--out", dir.to_str().unwrap()]);
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
    for section in [
        "## Not in the paper: shocks",
        "## Fig. 9",
        "## Not in the paper: robustness",
    ] {
        assert!(md.contains(section), "{section}");
    }
    let pngs = [
        "robustness",
        "fig9",
        "shock_jump_mismatch",
        "shock_block_mismatch",
        "shock_impact-up_mismatch",
        "shock_impact-down_mismatch",
        "shock_jump_realistic",
        "shock_block_realistic",
        "shock_impact-up_realistic",
        "shock_impact-down_realistic",
    ];
    for p in pngs {
        let png = std::fs::read(dir.join(format!("{p}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{p}.png");
    }
    // The studies' shape: 80 shock runs, 36 Fig. 9 runs, 2400 Monte Carlo runs, all finite.
    for (study, runs) in [("shocks", 80), ("fig9", 36), ("robustness", 2400)] {
        assert_eq!(v[study]["runs"], runs, "{study}");
        for g in v[study]["groups"].as_array().unwrap() {
            assert_eq!(g["all_finite"], true, "{study}: {g}");
        }
    }
    // Shocks, measured (docs/results.md), with margins. PSMC recovers from the release
    // without overshoot, as Kikuuwe et al. claim; PID's wound-up integral overshoots.
    // PSMC's settling time is its tuning's draw (0.73 s on the old four-substep plant's
    // gains, 2.26 s on the exact step's: docs/results.md, "The ranking on the converged
    // plant"): what is asserted is that it settles within the event's 3 s window.
    let on = |c: &str, gains: &str, plant: &str, ev: &str| {
        group(
            &v,
            "shocks",
            &[
                ("controller", c),
                ("gains", gains),
                ("plant_group", plant),
                ("event", ev),
            ],
        )
    };
    let psmc = event(
        on("psmc", "equal-activity/3", "mismatch", "block"),
        "release",
    );
    assert!(psmc["overshoot_worst_m"].as_f64().unwrap() < 1e-3, "{psmc}");
    assert!(
        psmc["settling_worst_s"].as_f64().is_some_and(|s| s < 3.0),
        "{psmc}"
    );
    let pid = event(
        on("pid", "equal-activity/3", "mismatch", "block"),
        "release",
    );
    assert!(pid["overshoot_worst_m"].as_f64().unwrap() > 0.010, "{pid}");
    let aprc = event(
        on("aprc-ndo", "aprc-ndo@paper", "mismatch", "block"),
        "release",
    );
    let o = aprc["overshoot_worst_m"].as_f64().unwrap();
    assert!((0.003..0.015).contains(&o), "{aprc}");
    // Fig. 9: APRC-NDO with the paper's gains barely notices 5 kg more; NDO-SMC's default
    // gains do.
    let fig9 = |c: &str, plant: &str| {
        group(
            &v,
            "fig9",
            &[
                ("controller", c),
                ("gains", "default"),
                ("plant_group", plant),
            ],
        )["rte_median"]
            .as_f64()
            .unwrap()
    };
    assert!(fig9("aprc-ndo", "mismatch+5kg") < 1.2 * fig9("aprc-ndo", "mismatch"));
    assert!(fig9("ndo-smc", "mismatch+5kg") > 5.0 * fig9("ndo-smc", "mismatch"));
    // Robustness over 200 plants with lag and noise: gains tuned on the clean plant do not
    // carry the model-based controllers; PID and PSMC keep working.
    let mc = |c: &str, what: &str| {
        group(
            &v,
            "robustness",
            &[("controller", c), ("reference", "sine")],
        )[what]
            .as_f64()
            .unwrap()
    };
    assert!(mc("pid", "rte_median") < 1.5 && mc("psmc", "rte_p95") < 10.0);
    assert!(mc("aprc-ndo", "rte_median") > 10.0 && mc("ndo-smc", "rte_median") > 10.0);
    assert!(mc("sta", "rte_worst") > 100.0);
}

#[test]
fn simulate_prints_the_gait_metrics_as_json() {
    let out = pma_exo_ok(&["simulate", "--duration", "3.2", "--json"]);
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
        // 3.2 s is two strides of 1.6 s: the one whole stride after the first is the
        // whole of what the run's RMS covers.
        let j = &v["joints"][joint];
        let s = &j["per_stride"];
        assert_eq!(s["strides"], 1, "{j}");
        let rms = j["rms_deg"].as_f64().unwrap();
        for key in ["median_deg", "p90_deg", "max_deg"] {
            let x = s[key].as_f64().unwrap();
            assert!(
                (x - rms).abs() <= 1e-9 * rms.max(1.0),
                "{key} {x} against {rms}"
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
    let dir = Scratch::new("rrd");
    for (args, file) in [
        (vec!["simulate", "--duration", "3.2"], "leg.rrd"),
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
            "3.2",
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
            "3.2",
            "--rerun",
            "save=/tmp/x.rrd",
            "--rerun-hz",
            "0",
        ],
        "rerun-hz",
    );
    let out = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["simulate", "--duration", "3.2", "--rerun", "spawn"])
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
    let out = pma_exo_ok(&[
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

// Regressions of a newcomer's first hour (issue 11): one test per defect, named after it.

fn temp(name: &str) -> Scratch {
    Scratch::new(&format!("first-hour-{name}"))
}

#[test]
fn regression_1_a_closed_stdout_pipe_ends_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["simulate", "--duration", "3.2"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before the summary is printed, as `| true` does.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(
        !err.contains("panicked") && !err.contains("Broken pipe"),
        "{err}"
    );
}

#[test]
fn regression_2_outputs_are_opened_before_the_run() {
    // Each would run for minutes if the output were checked only afterwards.
    assert_one_line_error(
        &[
            "simulate",
            "--duration",
            "3000",
            "--csv",
            "/proc/x.csv",
            "--json",
        ],
        "/proc/x.csv",
    );
    assert_one_line_error(
        &["single", "--duration", "20000", "--csv", "/proc/x.csv"],
        "/proc/x.csv",
    );
    assert_one_line_error(
        &[
            "tune",
            "--controller",
            "pid",
            "--population",
            "40",
            "--generations",
            "400",
            "--out",
            "/proc/x.toml",
        ],
        "/proc/x.toml",
    );
    assert_one_line_error(&["paper", "--out", "/proc/x"], "/proc/x");
}

#[cfg(unix)]
#[test]
fn regression_3_the_csv_is_streamed_and_complete_after_ctrl_c() {
    let dir = temp("ctrl-c");
    let csv = dir.join("a.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args([
            "simulate",
            "--duration",
            "1000",
            "--json",
            "--csv",
            csv.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(2500));
    // SAFETY: SIGINT to our own child.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["interrupted"], true);
    let ran = v["duration_s"].as_f64().unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.ends_with('\n'), "the last row is complete");
    let mut lines = text.lines().skip_while(|l| l.starts_with('#'));
    let header = lines.next().unwrap();
    // The controllers' states are in it, as in Rerun.
    for col in [
        "hip_flexor_proxy_m",
        "knee_extensor_gain_hat",
        "hip_extensor_disturbance_hat",
        "knee_flexor_s_p",
    ] {
        assert!(
            header.split(',').any(|c| c == col),
            "{col} missing: {header}"
        );
    }
    let n = header.split(',').count();
    let rows: Vec<&str> = lines.collect();
    assert!(rows.iter().all(|r| r.split(',').count() == n));
    assert_eq!(
        rows.len() as f64,
        (ran / 1e-3).round(),
        "every period of the run so far"
    );
    assert!(rows.len() > 100, "{} rows", rows.len());
}

#[test]
fn regression_4_every_io_error_names_its_file() {
    assert_one_line_error(&["single", "--csv", "/dev/full"], "/dev/full");
    assert_one_line_error(
        &["simulate", "--duration", "3.2", "--csv", "/dev/full"],
        "/dev/full",
    );
}

#[test]
fn regression_5_clap_errors_keep_what_they_say_on_one_line() {
    assert_one_line_error(
        &["tune"],
        "--controller <aprc-ndo|aprc|psmc|ndo-smc|sta|pid>",
    );
    assert_one_line_error(
        &["single", "--reference", "square"],
        "possible values: sine, chirp",
    );
    assert_one_line_error(
        &["single", "--reference", "sin"],
        "similar value exists: 'sine'",
    );
}

#[test]
fn regression_6_degenerate_runs_are_refused() {
    assert_one_line_error(
        &["single", "--duration", "0.0001"],
        "shorter than one control period",
    );
    assert_one_line_error(&["simulate", "--duration", "1"], "two strides");
    assert_one_line_error(&["tune-leg", "--duration", "1"], "two strides");
    let dir = temp("degenerate");
    let sc = dir.join("slow.toml");
    std::fs::write(
        &sc,
        include_str!("../crates/pma-leg/models/scenarios/gait_training.toml")
            .replace("period_s = 0.001", "period_s = 100"),
    )
    .unwrap();
    assert_one_line_error(&["simulate", sc.to_str().unwrap()], "period_s");
}

#[test]
fn tune_leg_refuses_scenarios_whose_controllers_differ_before_writing() {
    let dir = temp("tune-also");
    let out = dir.join("gains.toml");
    let out_arg = out.to_str().unwrap();
    // The trainer's controller settings (gain set, co-contraction) are not the in-air leg's.
    assert_one_line_error(
        &[
            "tune-leg",
            "gait_treadmill",
            "--also",
            "gait_training",
            "--out",
            out_arg,
        ],
        "`gait_training` gives the controller other settings than `gait_treadmill`",
    );
    assert_one_line_error(
        &[
            "tune-leg",
            "gait_training",
            "--also",
            "nope",
            "--out",
            out_arg,
        ],
        "`nope`: unknown scenario",
    );
    for bad in ["0", "257", "1,0"] {
        assert_one_line_error(
            &[
                "tune-leg",
                "gait_training",
                "--physics-substeps",
                bad,
                "--out",
                out_arg,
            ],
            "--physics-substeps",
        );
    }
    assert!(!out.exists(), "a refused tuning wrote {out_arg}");
}

#[test]
fn tune_leg_at_several_steps_and_requiring_walking_records_both() {
    let dir = temp("tune-steps");
    let out = dir.join("gains.toml");
    let run = pma_exo(&[
        "tune-leg",
        "gait_training",
        "--population",
        "2",
        "--generations",
        "1",
        "--duration",
        "3.2",
        "--physics-substeps",
        "1,3",
        "--require-walking",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    // The file's command gives these gains again: the steps are part of it.
    assert!(
        text.contains("--physics-substeps 1,3 --require-walking`"),
        "{text}"
    );
    assert!(text.contains("kp_per_s2"), "{text}");
}

#[test]
fn a_patient_walking_with_the_adults_moments_needs_a_treadmill_in_one_line() {
    let dir = temp("walking");
    let sc = dir.join("walk.toml");
    // gait_active ends in its [patient.active] section.
    let text = include_str!("../crates/pma-leg/models/scenarios/gait_active.toml");
    std::fs::write(&sc, format!("{text}own_torque = \"walking\"\n")).unwrap();
    assert_one_line_error(
        &["simulate", sc.to_str().unwrap(), "--duration", "3.2"],
        "[treadmill] is missing: patient.active.own_torque",
    );
    std::fs::write(&sc, format!("{text}own_torque = \"running\"\n")).unwrap();
    assert_one_line_error(&["simulate", sc.to_str().unwrap()], "own_torque");
}

#[test]
fn regression_7_runs_of_centuries_are_refused_without_yes() {
    assert_one_line_error(&["single", "--duration", "1e12"], "--yes");
    assert_one_line_error(&["simulate", "--duration", "1e9"], "--yes");
    let dir = temp("centuries");
    let sc = dir.join("fine.toml");
    std::fs::write(
        &sc,
        include_str!("../crates/pma-leg/models/scenarios/gait_training.toml")
            .replace("period_s = 0.001", "period_s = 1e-9"),
    )
    .unwrap();
    // A period of a nanosecond is refused before the wall time is estimated (issue 15).
    assert_one_line_error(&["simulate", sc.to_str().unwrap()], "period_s");
}

#[cfg(unix)]
#[test]
fn regression_9_a_viewer_that_dies_at_start_is_a_one_line_error() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp("no-display");
    let fake = dir.join("rerun");
    std::fs::write(
        &fake,
        "#!/bin/sh\necho 'Error: no display (DISPLAY unset)' >&2\nexit 1\n",
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!(
        "{}:{}",
        dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(["single", "--duration", "1", "--rerun", "spawn"])
        .env("PATH", path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("exited") && err.contains("no display") && err.contains("save="),
        "{err}"
    );
}

#[test]
fn regression_10_no_progress_bar_when_stderr_is_not_a_terminal() {
    let out = pma_exo(&["simulate", "--duration", "8", "--json"]);
    assert!(out.status.success());
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn regression_11_help_warnings_and_file_names() {
    let help = String::from_utf8_lossy(&pma_exo(&["tune", "--help"]).stdout).to_string();
    assert!(help.contains("aprc-ndo"), "{help}");
    let out = pma_exo(&["single", "--duration", "1", "--rerun-hz", "10"]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--rerun-hz has no effect"));
    let dir = temp("names");
    let sc = dir.join("zero.toml");
    std::fs::write(
        &sc,
        include_str!("../crates/pma-leg/models/scenarios/gait_training.toml")
            .replace("period_s = 0.001", "period_s = 0"),
    )
    .unwrap();
    assert_one_line_error(&["simulate", sc.to_str().unwrap()], "zero.toml");
    let text = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    let start = text.find("[gait]").unwrap();
    let end = start + text[start..].find("\n\n").unwrap();
    let no_gait = dir.join("no_gait.toml");
    std::fs::write(&no_gait, format!("{}{}", &text[..start], &text[end..])).unwrap();
    let out = pma_exo(&["simulate", no_gait.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("missing field `gait`"), "{err}");
    let first_comment = text.lines().next().unwrap();
    assert!(
        !err.contains(first_comment.trim_start_matches('#').trim()),
        "{err}"
    );
    let gains = dir.join("bad.toml");
    std::fs::write(&gains, "controller = \"pid\"\nkp = 1\n").unwrap();
    let out = pma_exo(&[
        "single",
        "--controller",
        "pid",
        "--gains",
        gains.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("gain file").count(), 1, "{err}");
}

/// `envelope --help` said `--physics-substeps` took 1 to 100 after the bound rose to 256
/// (stop 71): every command's help that names the option's range names the bound itself.
#[test]
fn regression_12_every_physics_substeps_help_names_its_bound() {
    let bound = format!("1 to {}", pma_leg::scenario::PHYSICS_SUBSTEPS_MAX);
    for command in ["envelope", "tune-leg"] {
        let help = String::from_utf8_lossy(&pma_exo(&[command, "--help"]).stdout).to_string();
        let entry = help
            .split("\n      -")
            .find(|e| e.starts_with("-physics-substeps"))
            .expect("the option");
        let entry = entry.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(entry.contains(&bound), "{command}: {entry}");
    }
}

/// `gait_training` with `extra` appended, in a temporary file.
fn scenario_with(dir: &std::path::Path, extra: &str) -> std::path::PathBuf {
    let path = dir.join("scenario.toml");
    let base = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    std::fs::write(&path, format!("{base}\n{extra}\n")).unwrap();
    path
}

fn pendulum_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["pendulum"];
    all.extend_from_slice(args);
    all.push("--json");
    let out = pma_exo_ok(&all);
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn pendulum_without_patient_or_damping_conserves_energy() {
    let dir = temp("undamped");
    let path = dir.join("scenario.toml");
    let base = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    let undamped = base.replace("damping_nm_s_per_rad = 0.5", "damping_nm_s_per_rad = 0.0");
    assert_ne!(undamped, base);
    std::fs::write(&path, undamped).unwrap();
    let v = pendulum_json(&[
        path.to_str().unwrap(),
        "--knee-deg",
        "45",
        "--duration",
        "2",
    ]);
    let drift = v["energy_change_relative"].as_f64().unwrap();
    assert!(drift.abs() < 0.01, "energy drift {drift}");
    // Released at 45 deg from the hanging 90 deg, it swings to about 135 deg.
    let peak = v["first_peak_deg"].as_f64().unwrap();
    assert!((peak - 135.0).abs() < 2.0, "first peak {peak} deg");
}

#[test]
fn pendulum_severe_spasticity_lowers_r2() {
    let r2 = |preset: &str| {
        pendulum_json(&["--spasticity", preset])["r2"]
            .as_f64()
            .unwrap()
    };
    let (none, severe) = (r2("none"), r2("severe"));
    assert!(severe < none, "R2 severe {severe} vs none {none}");
    assert!((none - 1.678).abs() < 0.18, "healthy R2 {none}");
    // Cut short, the knee has no resting angle yet: the figures come with a warning.
    let out = pma_exo_ok(&["pendulum", "--duration", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("warning: the knee still moved"), "{err}");
    let v = pendulum_json(&["--duration", "1"]);
    assert!(v["r2"].is_null() && v["settled"] == false, "{v}");
    assert_one_line_error(&["pendulum", "--duration", "1e7"], "at most 600 s");
    assert!(pma_exo_ok(&["pendulum"]).stderr.is_empty());
}

#[test]
fn bad_patient_input_is_a_one_line_error_naming_the_field() {
    for (name, extra, field) in [
        (
            "preset.toml",
            "[patient.knee.spasticity]\npreset = \"extreme\"",
            "patient.knee.spasticity.preset",
        ),
        (
            "rate.toml",
            "[patient.hip.spasms]\nrate_per_min = -1.0",
            "patient.hip.spasms.rate_per_min",
        ),
        (
            "amplitude.toml",
            "[patient.knee.spasms]\nrate_per_min = 4.0\namplitude_nm = [30.0, 10.0]",
            "patient.knee.spasms.amplitude_nm",
        ),
        (
            "no-amplitude.toml",
            "[patient.knee.spasms]\nrate_per_min = 4.0",
            "patient.knee.spasms.amplitude_nm is missing",
        ),
        (
            "huge-rate.toml",
            "[patient.knee.spasms]\nrate_per_min = 1e9\namplitude_nm = [1.0, 2.0]",
            "patient.knee.spasms.rate_per_min",
        ),
        (
            "stiffness-rate.toml",
            "[patient.knee.stiffness]\npreset = \"anderson1999\"\nupper_per_rad = 1000.0",
            "patient.knee.stiffness.upper_per_rad",
        ),
        (
            "field.toml",
            "[patient.knee.effort]\nfracton = 0.3",
            "fracton",
        ),
    ] {
        let dir = temp(name);
        let path = scenario_with(&dir, extra);
        assert_one_line_error(&["simulate", path.to_str().unwrap()], field);
        assert_one_line_error(&["pendulum", path.to_str().unwrap()], field);
    }
}

#[test]
fn simulate_any_controller_on_a_patient_reports_spasms_and_safety() {
    let out = pma_exo(&[
        "simulate",
        "gait_spasms",
        "--controller",
        "psmc",
        "--duration",
        "8",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let spasms = v["spasms"].as_array().unwrap();
    assert!(!spasms.is_empty(), "{v}");
    for key in [
        "peak_deviation_deg",
        "peak_joint_speed_deg_s",
        "peak_pressure_rate_bar_s",
        "recovery_s",
    ] {
        assert!(spasms[0].get(key).is_some(), "{key}");
    }
    // The knee's peak patient torque is its spasm's (passive moments are ~0 in the gait).
    let knee_spasm = spasms
        .iter()
        .find(|s| s["joint"] == "knee")
        .expect("a knee spasm");
    let amplitude = knee_spasm["amplitude_nm"].as_f64().unwrap();
    let peak = v["patient"]["knee"]["torque_peak_nm"].as_f64().unwrap();
    assert!(
        amplitude >= 10.0 && (peak - amplitude).abs() < 0.5,
        "peak {peak} N m, spasm {amplitude} N m"
    );
    for j in ["hip", "knee"] {
        assert!(v["patient"][j]["torque_rms_nm"].is_number());
        assert!(v["safety"]["joints"][j]["time_outside_s"].is_number());
    }
    // Regression (issue 26.17): an eq. (1) muscle was held against a DMSP-20's 1500 N
    // though Table I's muscle pulls 2.8 times that; it is held against its own pull at the
    // valve's limit (-202 N + 0.00721 N/Pa x 6 bar), and the output says so.
    let m = &v["safety"]["muscles"]["knee_flexor"];
    let table_i = -202.0 + 0.00721 * 6.0e5;
    assert!(
        (m["rated_force_n"].as_f64().unwrap() - table_i).abs() < 1.0,
        "{m}"
    );
    assert!(m["rating"].as_str().unwrap().contains("Table I"), "{m}");
    assert!(m["peak_over_rated"].as_f64().unwrap() > 0.0);
    // Regression (issue 18): a spasm's "joint speed" was the gait's own peak speed (knee
    // 203-237 deg/s whatever the spasm) and its deviation the whole tracking error; both
    // are now measured beyond the same run without the spasms.
    assert_eq!(knee_spasm["against_baseline"], true);
    let speed = knee_spasm["peak_joint_speed_deg_s"].as_f64().unwrap();
    assert!(speed < 150.0, "knee spasm speed {speed} deg/s");
    // The summary prints a line per spasm.
    let out = pma_exo_ok(&["simulate", "gait_spasms", "--duration", "8"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("beyond the same run without the spasms"),
        "{text}"
    );
    assert_eq!(
        text.lines()
            .filter(|l| l.trim_start().starts_with("at ") && l.contains("N m for"))
            .count(),
        spasms.len(),
        "{text}"
    );
}

/// Runs `compare-leg --out DIR` with `args` and reads the JSON it wrote there.
fn compare_leg_json(dir: &std::path::Path, args: &[&str]) -> serde_json::Value {
    let mut all = vec!["compare-leg", "--out", dir.to_str().unwrap()];
    all.extend_from_slice(args);
    pma_exo_ok(&all);
    serde_json::from_str(&std::fs::read_to_string(dir.join("compare-leg.json")).unwrap()).unwrap()
}

/// Issue 28: compare-leg's mode axis: the controllers in position mode, then a row per
/// pressure-set mode, each a run of that mode (the same figures as `simulate --mode`).
#[test]
fn compare_leg_adds_a_row_per_pressure_set_mode() {
    let dir = temp("compare-leg-modes");
    let json = compare_leg_json(
        &dir,
        &[
            "--scenarios",
            "gait_spasms",
            "--modes",
            "position,impedance,transparent",
            "--duration",
            "4",
        ],
    );
    let rows = json["rows"].as_array().unwrap();
    let labels: Vec<&str> = rows
        .iter()
        .map(|r| r["controller"].as_str().unwrap())
        .collect();
    assert_eq!(
        labels,
        [
            "aprc-ndo",
            "psmc",
            "ndo-smc",
            "sta",
            "pid",
            "impedance mode",
            "transparent mode"
        ]
    );
    let out = pma_exo_ok(&[
        "simulate",
        "gait_spasms",
        "--mode",
        "impedance",
        "--duration",
        "4",
        "--json",
    ]);
    let simulated: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        rows[5]["hip_rms_deg"].as_f64().unwrap(),
        simulated["joints"]["hip"]["rms_deg"].as_f64().unwrap()
    );
    let md = std::fs::read_to_string(dir.join("compare-leg.md")).unwrap();
    assert!(md.contains("| transparent mode |"), "{md}");
    assert_one_line_error(
        &[
            "compare-leg",
            "--modes",
            "impedance,impedance",
            "--out",
            "unused",
        ],
        "`impedance` is given twice",
    );
}

#[test]
fn compare_leg_writes_one_row_per_controller_and_scenario() {
    let dir = temp("compare-leg");
    let json = compare_leg_json(
        &dir,
        &[
            "--scenarios",
            "gait_spasms,gait_resistive",
            "--duration",
            "8",
        ],
    );
    // It says what ran (issue 18).
    assert!(json["provenance"]["command"]
        .as_str()
        .unwrap()
        .starts_with("pma-exo compare-leg --out"));
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 10);
    // And the grouped bars (issue 18).
    let png = std::fs::read(dir.join("compare-leg.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(rows[0]["scenario"], "gait_spasms");
    assert_eq!(rows[0]["controller"], "aprc-ndo");
    assert_eq!(rows[9]["controller"], "pid");
    assert!(rows.iter().all(|r| r["finite"] == true));
    assert!(rows[0]["spasms"].as_u64().unwrap() > 0);
    // Regression (issue 18): a run without spasms printed 0 deviation and 0 recovery; it
    // has none, `null` in the JSON and `-` in the table.
    let calm = rows
        .iter()
        .find(|r| r["scenario"] == "gait_resistive")
        .unwrap();
    assert_eq!(calm["spasms"], 0);
    for key in [
        "spasm_mean_deviation_deg",
        "spasm_max_deviation_deg",
        "spasm_max_recovery_s",
        "spasm_peak_pressure_rate_bar_s",
    ] {
        assert!(calm[key].is_null(), "{key}: {calm}");
        assert!(rows[0][key].is_number(), "{key}: {}", rows[0]);
    }
    let md = std::fs::read_to_string(dir.join("compare-leg.md")).unwrap();
    assert!(
        md.contains("## gait_resistive") && md.contains("| sta |"),
        "{md}"
    );
    assert!(md.contains("| 0 | - / - | - | 0 / 0 | - |"), "{md}");
    assert_one_line_error(
        &["compare-leg", "--out", "/proc/x", "--duration", "8"],
        "/proc/x",
    );
}

/// `tune --robust N`: every gain set scored on N plants around the plant; the gain file
/// says how it was tuned, and the same seed gives the same file whatever the threads.
#[test]
fn a_robust_tuning_is_deterministic_and_says_how_it_was_made() {
    let dir = temp("robust");
    let run = |name: &str, threads: &str| {
        let out = dir.join(name);
        let args = [
            "tune",
            "--controller",
            "pid",
            "--plant",
            "realistic",
            "--population",
            "4",
            "--generations",
            "2",
            "--duration",
            "2",
            "--robust",
            "3",
            "--spread",
            "0.2",
            "--objective",
            "worst",
            "--threads",
            threads,
            "--out",
            out.to_str().unwrap(),
        ];
        pma_exo_ok(&args);
        std::fs::read_to_string(out).expect("gains")
    };
    let (one, two) = (run("one.toml", "1"), run("two.toml", "2"));
    assert_eq!(one, two);
    assert!(
        one.contains("--robust 3 --spread 0.2 --objective worst"),
        "{one}"
    );
    assert_one_line_error(
        &["tune", "--controller", "pid", "--robust", "0"],
        "--robust",
    );
    assert_one_line_error(
        &[
            "tune",
            "--controller",
            "pid",
            "--robust",
            "2",
            "--spread",
            "0.9",
        ],
        "spread",
    );
}

/// `tune --robust N --robust-from SWEEP`: the plants come from the sweep's population
/// ranges with the tuning's seed, never the sweep's own plants.
#[test]
fn a_robust_tuning_draws_from_a_sweeps_ranges_but_not_its_plants() {
    let dir = temp("robust-from");
    let out = dir.join("pid.toml");
    pma_exo_ok(&[
        "tune",
        "--controller",
        "pid",
        "--population",
        "3",
        "--generations",
        "1",
        "--duration",
        "2",
        "--robust",
        "2",
        "--robust-from",
        "monte_carlo",
        "--objective",
        "p90",
        "--out",
        out.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&out).expect("gains");
    assert!(
        text.contains("--robust 2 --robust-from monte_carlo --objective p90"),
        "{text}"
    );
    assert!(!text.contains("--plant"), "{text}");
    assert_one_line_error(
        &[
            "tune",
            "--controller",
            "pid",
            "--robust",
            "2",
            "--robust-from",
            "monte_carlo",
            "--seed",
            "1",
        ],
        "the very plants the sweep scores",
    );
    assert_one_line_error(
        &[
            "tune",
            "--controller",
            "pid",
            "--robust",
            "2",
            "--robust-from",
            "shocks",
        ],
        "population",
    );
}

/// `single --gains FILE` without `--controller` runs the file's controller (issue 18), and
/// the JSON says so in its provenance.
#[test]
fn single_takes_the_controller_from_the_gain_file() {
    let gains = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/pma-control/models/gains/pid.toml"
    );
    let out = pma_exo(&["single", "--gains", gains, "--duration", "0.5", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["controller"], "pid");
    assert_eq!(v["provenance"]["controller"], "pid");
    assert_eq!(v["provenance"]["gains"], gains);
    assert!(v["provenance"]["program"]
        .as_str()
        .unwrap()
        .starts_with("pma-exo "));
}

/// `simulate --plot DIR` draws the run (issue 18): a PNG in DIR, written whole.
#[test]
fn simulate_draws_the_run_when_asked() {
    let dir = temp("leg-plot");
    pma_exo_ok(&[
        "simulate",
        "gait_spasms",
        "--duration",
        "6.4",
        "--plot",
        dir.to_str().unwrap(),
    ]);
    let png = std::fs::read(dir.join("leg.png")).expect("leg.png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(png.len() > 50_000, "{} bytes", png.len());
    // Seven panels in two columns (joints, error, torques on the limb, cuff forces,
    // pressures, forces): four rows. On a treadmill, a fifth: the ground reaction and the
    // pelvis (the PNG's height, big-endian at byte 20, grows from 1700 to 2100 pixels).
    let height = |png: &[u8]| u32::from_be_bytes([png[20], png[21], png[22], png[23]]);
    assert_eq!(height(&png), 1700);
    let belt = temp("leg-plot-belt");
    // A 4 s run is judged as any other (exit 4 if the patient did not walk within the
    // criteria in its two strides): drawn either way.
    let out = pma_exo(&[
        "simulate",
        "gait_treadmill",
        "--duration",
        "4",
        "--plot",
        belt.to_str().unwrap(),
    ]);
    assert!(matches!(out.status.code(), Some(0 | 4)), "{out:?}");
    let png = std::fs::read(belt.join("leg.png")).expect("leg.png");
    assert_eq!(height(&png), 2100);
    // Issue 49 item 18: a two-legged run drew its right leg only; the left has its own
    // figure (its own joints and muscles, not the right's again), a one-legged run none.
    let left = std::fs::read(belt.join("leg_left.png")).expect("leg_left.png");
    assert_eq!(height(&left), 2100);
    assert_ne!(left, png, "the left leg's figure repeats the right's");
    assert!(!dir.join("leg_left.png").exists());
    pma_exo_ok(&[
        "pendulum",
        "--spasticity",
        "severe",
        "--duration",
        "4",
        "--plot",
        dir.to_str().unwrap(),
    ]);
    let png = std::fs::read(dir.join("pendulum.png")).expect("pendulum.png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}

/// Issue 28: impedance mode's bad input is refused before anything runs: a muscle
/// controller in a mode that runs none, a set point beyond the muscles' reach, a negative
/// stiffness, a perturbation test's bad arguments; each a one-line error naming the flag
/// or field.
#[test]
fn impedance_mode_refuses_bad_input_in_one_line() {
    assert_one_line_error(
        &[
            "simulate",
            "gait_training",
            "--mode",
            "impedance",
            "--controller",
            "psmc",
        ],
        "--controller psmc: impedance mode",
    );
    let dir = Scratch::new("impedance");
    let base = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    for (extra, needle) in [
        (
            "[control.impedance]\nhip = { stiffness_nm_per_rad = 200.0 }\n",
            "control.impedance.hip.stiffness_nm_per_rad = 200 is out of reach: the hip's muscles reach 8.4 to 10.9 N m/rad",
        ),
        (
            "[control.impedance]\nknee = { stiffness_nm_per_rad = -1.0 }\n",
            "control.impedance.knee.stiffness_nm_per_rad",
        ),
        (
            "[control.impedance]\nknee = { stiffnes_nm_per_rad = 5.0 }\n",
            "unknown field `stiffnes_nm_per_rad`",
        ),
    ] {
        let path = dir.join("bad.toml");
        std::fs::write(&path, format!("{base}\n{extra}")).unwrap();
        let p = path.to_str().unwrap();
        assert_one_line_error(&["simulate", p, "--mode", "impedance", "--duration", "4"], needle);
    }
    assert_one_line_error(
        &["impedance", "gait_training", "--settle", "-1"],
        "--settle",
    );
}

/// `impedance --json`: each joint's ranges and three perturbation tests on the leg in the
/// air, each within 10 % of its set point (the figures of docs/cooperative.md).
#[test]
fn impedance_reports_ranges_and_three_tests_per_joint() {
    let out = pma_exo_ok(&["impedance", "gait_training", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let joints = v["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 2);
    for j in joints {
        let rest = j["at_rest"].as_array().unwrap();
        assert!(rest[0].as_f64().unwrap() < rest[1].as_f64().unwrap(), "{j}");
        let probes = j["probes"].as_array().unwrap();
        assert_eq!(probes.len(), 3, "{j}");
        for p in probes {
            assert!(p["error"].as_f64().unwrap().abs() < 0.10, "{p}");
        }
    }
}

/// Issue 27's experiments are refused in one line when their input is bad: a start-up
/// hold out of range, a body speed that is neither.
#[test]
fn the_treadmill_experiments_refuse_bad_input_in_one_line() {
    let dir = Scratch::new("hold");
    let base = include_str!("../crates/pma-leg/models/scenarios/gait_treadmill.toml");
    let path = dir.join("held.toml");
    std::fs::write(&path, format!("{base}pelvis_held_until_s = -1.0\n")).unwrap();
    assert_one_line_error(
        &["size", path.to_str().unwrap()],
        "treadmill.pelvis_held_until_s",
    );
    let out = pma_exo(&["fit-gait", "--body-speed", "swinging"]);
    assert!(!out.status.success());
}

/// `compare-modes --phase-sync` adds impedance and admittance rows whose gait clock
/// follows the patient; a gain or integral out of range is refused before any run,
/// naming the option.
#[test]
fn compare_modes_adds_rows_whose_clock_follows_the_patient() {
    let args = |gain: &'static str, integral: &'static str| {
        [
            "compare-modes",
            "--scenarios",
            "gait_active",
            "--duration",
            "4",
            "--phase-sync",
            gain,
            "--phase-sync-integral",
            integral,
        ]
    };
    let mut json = args("2", "0.5").to_vec();
    json.push("--json");
    let out = pma_exo_ok(&json);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let modes: Vec<&str> = v["rows"]
        .as_array()
        .expect("rows")
        .iter()
        .map(|r| r["mode"].as_str().expect("mode"))
        .collect();
    assert_eq!(modes.len(), 8, "{modes:?}");
    assert!(
        modes[6].starts_with("impedance, clock following"),
        "{modes:?}"
    );
    assert!(
        modes[7].starts_with("admittance (APRC-NDO), clock following"),
        "{modes:?}"
    );
    assert_one_line_error(&args("25", "0"), "--phase-sync 25");
    assert_one_line_error(&args("0", "0"), "--phase-sync 0");
    assert_one_line_error(&args("2", "2"), "--phase-sync-integral 2");
    assert_one_line_error(&args("2", "-1"), "--phase-sync-integral -1");
}

/// Issue 46: the DMSP-20 behind each shipped valve fills and empties in tens of
/// milliseconds at a few hundred bar/s at most, not the 3,722 bar/s of the instantaneous
/// valve; bad valve input is one line naming the file and the field.
#[test]
fn valve_steps_a_muscle_behind_a_flow_limited_valve() {
    let out = pma_exo_ok(&["valve", "mpye-5-1-4", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let r = &v["response"];
    let rise = r["rise_10_90_s"].as_f64().expect("rise");
    let fall = r["fall_90_10_s"].as_f64().expect("fall");
    let rate = r["peak_rise_rate_pa_s"].as_f64().expect("rate");
    assert!((0.01..0.2).contains(&rise), "{v}");
    assert!(
        fall > rise,
        "exhausting to the atmosphere is slower than filling: {v}"
    );
    assert!(rate < 500e5, "{v}");
    assert!(
        (r["reached_pa"].as_f64().expect("reached") - 6e5).abs() < 1e3,
        "{v}"
    );
    // A larger valve fills faster.
    let big = pma_exo_ok(&["valve", "mpye-5-3-8", "--json"]);
    let b: serde_json::Value = serde_json::from_slice(&big.stdout).expect("json");
    assert!(
        b["response"]["rise_10_90_s"].as_f64().expect("rise") < rise,
        "{b}"
    );

    let dir = Scratch::new("valve");
    let file = |name: &str, body: &str| {
        let p = dir.join(name);
        std::fs::write(
            &p,
            format!("name = \"x\"\nsource = \"test\"\nspool_time_constant_s = 0.002\npressure_band_pa = 30000.0\n{body}"),
        )
        .expect("write");
        p.display().to_string()
    };
    let negative = file(
        "neg.toml",
        "sonic_conductance_l_per_s_bar = -1.0\ncritical_pressure_ratio = 0.23\n",
    );
    assert_one_line_error(&["valve", &negative], "sonic_conductance_l_per_s_bar");
    assert_one_line_error(&["valve", &negative], "neg.toml");
    let ratio = file(
        "b.toml",
        "sonic_conductance_l_per_s_bar = 6.0\ncritical_pressure_ratio = 1.3\n",
    );
    assert_one_line_error(&["valve", &ratio], "critical_pressure_ratio");
    assert_one_line_error(&["valve", "mpye-9"], "no such valve");
    assert_one_line_error(&["valve", "--tube-m", "0"], "tube_length_m");
}

/// Issue 49: `compare-modes`, `size --out --csv` and `compare-leg --out` (and now `envelope`) had no stop
/// handler: SIGINT or SIGTERM killed them (143), printing nothing and leaving `.part`
/// files. Each now exits 130, says what it kept (nothing), and leaves no file behind.
#[cfg(unix)]
#[test]
fn compare_modes_size_and_compare_leg_stop_on_a_signal_and_leave_nothing() {
    let cases: [(&[&str], i32); 4] = [
        (&["compare-modes", "--duration", "60"], libc::SIGTERM),
        // Issue 47's envelope, under the same rule from the start.
        (
            &[
                "envelope",
                "--out",
                "env",
                "--duration",
                "60",
                "--mass-kg",
                "75,80",
                "--support",
                "0.5,0.7,0.9",
                "--speed",
                "0.5",
                "--threads",
                "1",
            ],
            libc::SIGINT,
        ),
        (
            &[
                "size",
                "gait_treadmill",
                "--strides",
                "12",
                "--out",
                "m.toml",
                "--csv",
                "s.csv",
            ],
            libc::SIGINT,
        ),
        (
            &["compare-leg", "--out", "cmp", "--duration", "30"],
            libc::SIGTERM,
        ),
    ];
    for (i, (args, signal)) in cases.iter().enumerate() {
        let dir = temp(&format!("stop-{i}"));
        let child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
            .args(*args)
            .current_dir(&dir)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(1500));
        // SAFETY: a signal to our own child.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, *signal) }, 0);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(130), "{args:?}: {err}");
        assert!(err.contains("interrupted"), "{args:?}: {err}");
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
}

/// `simulate --controller sta --gains FILE` with a PID gain file ran PID without a word:
/// the controller named on the command line gave way to the file's. Now, as for `single`,
/// a controller beside a gain file of another is refused in one line.
#[test]
fn regression_simulate_ran_the_gain_files_controller_instead_of_the_one_named() {
    assert_one_line_error(
        &[
            "simulate",
            "gait_treadmill",
            "--controller",
            "sta",
            "--gains",
            "crates/pma-leg/models/gains/treadmill/pid.toml",
        ],
        "gain file is for `pid` but the controller requested is `sta`",
    );
}

/// Regression: an in-air run that pulled a muscle past its rating ended with exit 0 (only
/// the treadmill judged the rating). With the rating lowered under the leg's own peak
/// forces the run completes, says `rating: EXCEEDED` naming the muscles, ends with one
/// line on stderr and exits 5; at the shipped rating the same run is within it, exit 0.
#[test]
fn an_in_air_run_over_its_rating_is_a_verdict_and_exit_5() {
    let dir = Scratch::new("rating");
    let text = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    assert!(text.contains("\n[plant.valve]\n"));
    let lowered = text.replacen(
        "\n[plant.valve]\n",
        "\n[plant]\nmuscle_rated_force_n = 1500.0\n\n[plant.valve]\n",
        1,
    );
    let path = dir.join("rated-1500.toml");
    std::fs::write(&path, lowered).expect("write");
    let scenario = path.to_str().expect("utf-8 path");
    let out = pma_exo(&["simulate", scenario, "--duration", "4"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(5), "{stdout}\n{stderr}");
    assert!(stdout.contains("rating: EXCEEDED"), "{stdout}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("over their rating"), "{stderr}");
    let out = pma_exo_ok(&["simulate", "gait_training", "--duration", "4"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("rating: every muscle within its rating"),
        "{stdout}"
    );
}
