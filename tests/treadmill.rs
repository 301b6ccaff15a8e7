//! The two-leg gait trainer through the binary (issue 27): `simulate` on the belt reports
//! each foot, the pelvis and both legs' safety; `size` recommends muscles the scenario then
//! runs on; bad `[treadmill]` and `[gait]` input is a one-line error naming the field; the
//! controllers walk both legs. The physics of the trainer is checked in
//! `crates/pma-leg/tests/treadmill.rs`.
mod common;
use common::Scratch;

fn pma_exo(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .output()
        .expect("run pma-exo")
}

/// Runs `pma-exo` with `args`, asserts it succeeded, and parses its stdout as JSON.
fn json_of(args: &[&str]) -> serde_json::Value {
    let out = pma_exo(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// Runs `pma-exo` with `args`, which must end with a verdict (exit 0: walked; 4: did not),
/// and parses its stdout as JSON.
fn judged(args: &[&str]) -> serde_json::Value {
    let out = pma_exo(args);
    assert!(
        matches!(out.status.code(), Some(0 | 4)),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// Whether a judged run walked.
fn walked(v: &serde_json::Value) -> bool {
    v["walking"]["walking"].as_bool().expect("a verdict")
}

/// The trainer as it was before issue 46's real valves: the instantaneous valve at 6 bar,
/// no pressure sensors fed back (the pressure-set modes' figures were found there; behind
/// the MPYE they do not hold the patient: docs/treadmill.md).
const IDEAL_VALVE: [(&str, &str); 4] = [
    ("valve = \"mpye-5-1-4\"", "valve = \"ideal\""),
    ("pressure_max_pa = 5.0e5", "pressure_max_pa = 6.0e5"),
    ("pressure_feedback = true", "pressure_feedback = false"),
    ("gain_set = \"treadmill\"", "gain_set = \"treadmill-ideal\""),
];

/// The edit that takes the shipped force limit (`[control] force_max_of_rating`) out of a
/// treadmill scenario.
const FORCE_LIMIT_OFF: (&str, &str) = ("force_max_of_rating = 0.85\n", "");

/// `base` (a treadmill scenario's text) as the trainer was before issue 46's real valves:
/// [`IDEAL_VALVE`]'s edits and the APRC-NDO gains tuned there (the scenario's own gains, at
/// every support).
fn ideal_valve(base: &str) -> String {
    let mut text = IDEAL_VALVE.iter().fold(base.to_owned(), |t, (from, to)| {
        assert!(t.contains(from), "{from} not in the scenario");
        t.replacen(from, to, 1)
    });
    let start = text.find("[control.gains]").expect("[control.gains]");
    let end = start
        + text[start..]
            .find("estimator_bandwidth_rad_s")
            .expect("the gains' last line");
    let end = end + text[end..].find('\n').expect("a line") + 1;
    let gains: String =
        include_str!("../crates/pma-leg/models/gains/treadmill-ideal/aprc-ndo.toml")
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("controller"))
            .map(|l| format!("{l}\n"))
            .collect();
    text.replace_range(start..end, &format!("[control.gains]\n{gains}"));
    // The schedule by support came with issue 47, after the real valves: off.
    let schedule = "support_fraction = 0.5";
    assert!(text.contains(schedule), "{schedule} not in the scenario");
    text.replacen(schedule, "support_fraction = 0.0", 1)
}

fn temp_dir(name: &str) -> Scratch {
    Scratch::new(&format!("trainer-{name}"))
}

const SCENARIO: &str = include_str!("../crates/pma-leg/models/scenarios/gait_treadmill.toml");
const UNSUPPORTED: &str =
    include_str!("../crates/pma-leg/models/scenarios/gait_treadmill_unsupported.toml");

/// `gait_treadmill` in `dir` as `name`, with each `(from, to)` replaced once.
fn scenario_with(dir: &std::path::Path, name: &str, edits: &[(&str, &str)]) -> std::path::PathBuf {
    edited(SCENARIO, dir, name, edits)
}

/// `base` in `dir` as `name`, with each `(from, to)` replaced once (every `from` must be in
/// the file, so a renamed field fails here rather than testing nothing).
fn edited(
    base: &str,
    dir: &std::path::Path,
    name: &str,
    edits: &[(&str, &str)],
) -> std::path::PathBuf {
    let mut text = base.to_owned();
    for (from, to) in edits {
        assert!(text.contains(from), "{from} not in the scenario");
        text = text.replacen(from, to, 1);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `simulate` on `path`, asserts it failed with one line naming `needle`.
fn assert_refused(path: &std::path::Path, needle: &str) {
    // Past the up-front check of the demand: what the run itself refuses.
    let args = [
        "simulate",
        path.to_str().unwrap(),
        "--allow-unfit",
        "--duration",
        "4",
    ];
    let out = pma_exo(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{needle}: succeeded");
    assert_eq!(err.trim_end().lines().count(), 1, "{needle}: {err}");
    assert!(
        err.contains(needle) && !err.contains("panicked"),
        "{needle}: {err}"
    );
}

#[test]
fn simulate_two_legs_reports_each_foot_the_pelvis_and_both_legs_safety() {
    let dir = temp_dir("simulate");
    let csv = dir.join("run.csv");
    // PID, which tracks best here: APRC-NDO's gains hold both patients by chattering
    // (460 bar/s), and in its first 6.4 s the right foot's first heel strike goes
    // undetected and the ankle presses 0.23 deg into its stop (docs/treadmill.md).
    let v = json_of(&[
        "simulate",
        "gait_treadmill",
        "--controller",
        "pid",
        "--duration",
        "6.4",
        "--json",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let t = &v["treadmill"];
    assert_eq!(t["legs"].as_u64(), Some(2), "{t}");
    // The belt carries the patient less the harness's share, plus the exoskeleton; over
    // whole strides the mean is that within the trainer's vertical motion.
    let load = t["mean_belt_load_bw"].as_f64().unwrap();
    let expected = t["expected_belt_load_bw"].as_f64().unwrap();
    assert!((load / expected - 1.0).abs() < 0.03, "{load} vs {expected}");
    for side in ["right", "left"] {
        let f = &t["feet"][side];
        assert!(f["strides"].as_u64().unwrap() >= 2, "{side}: {f}");
        // Each foot's stance within 5 points of the adults' (67.5 %).
        let stance = f["stance_fraction"]["mean"].as_f64().unwrap();
        let reference = f["reference_stance_fraction"].as_f64().unwrap();
        assert!((stance - reference).abs() < 0.05, "{side}: {stance}");
        let peak = f["peak_grf_bw"]["mean"].as_f64().unwrap();
        assert!((0.5..2.0).contains(&peak), "{side}: {peak}");
        // The passive ankle stays within its orthosis's stops (+-15 deg) but for the stop's
        // give: rapier's limit is a stiff constraint, not a wall; on the fitted gait the
        // stance ankle reaches its dorsiflexion stop in terminal stance and presses 0.13
        // deg into it (0.1 before the fit).
        let [lo, hi] = [0, 1].map(|i| f["ankle_range_deg"][i].as_f64().unwrap());
        assert!(lo > -15.2 && hi < 15.2, "{side}: {lo}..{hi}");
        for j in ["hip", "knee"] {
            assert!(
                f["tracking"][j]["stance_rms_deg"].as_f64().unwrap() < 2.0,
                "{side} {j}: {f}"
            );
            let name = format!("{side}/{j}");
            assert!(
                v["joints"][&name]["rms_deg"].as_f64().unwrap() < 1.5,
                "{name}"
            );
            let l = &v["safety"]["joints"][&name];
            assert_eq!(l["time_outside_s"].as_f64(), Some(0.0), "{l}");
        }
        for m in ["hip_flexor", "hip_extensor", "knee_flexor", "knee_extensor"] {
            let s = &v["safety"]["muscles"][format!("{side}/{m}")];
            let rated = s["rated_force_n"].as_f64().unwrap();
            let peak = s["peak_force_n"].as_f64().unwrap();
            assert_eq!(s["rating"], "Festo DMSP-20", "{s}");
            assert!((s["margin_n"].as_f64().unwrap() - (rated - peak)).abs() < 1e-6);
        }
    }
    // Fore-aft the harness holds the pelvis on a stiff spring (1e5 N/m and a damper): it
    // moves with the stride, and at its extremes (at rest there) only the spring pulls, so
    // its range times the stiffness cannot exceed the harness force's range.
    let fore_aft = t["pelvis_fore_aft_excursion_m"].as_f64().unwrap();
    let h = &t["harness_fore_aft_n"];
    let spring_range_m = (h["max"].as_f64().unwrap() - h["min"].as_f64().unwrap()) / 1.0e5;
    assert!(
        fore_aft > 1e-4 && fore_aft <= spring_range_m * 1.001,
        "{fore_aft} m vs {spring_range_m} m"
    );
    // The CSV carries both feet and the pelvis.
    let text = std::fs::read_to_string(&csv).unwrap();
    let header = text.lines().nth(1).unwrap();
    for c in [
        "right_foot_grf_vertical_n",
        "left_foot_grf_vertical_n",
        "left_ankle_orthosis_torque_nm",
        "right_hip_flexor_force_n",
        "harness_fore_aft_n",
        "pelvis_x_m",
        "pelvis_height_m",
    ] {
        assert!(header.split(',').any(|h| h == c), "{c} not in {header}");
    }
}

#[test]
fn one_leg_with_a_virtual_other_leg_carries_the_same_belt_load() {
    let v = json_of(&[
        "simulate",
        "gait_treadmill_one_leg",
        "--duration",
        "6.4",
        "--json",
    ]);
    let t = &v["treadmill"];
    assert_eq!(t["legs"].as_u64(), Some(1), "{t}");
    assert!(t["feet"]["left"].is_null(), "{t}");
    // The virtual leg pushes the pelvis up for half the stride's load.
    assert!(t["mean_other_leg_bw"].as_f64().unwrap() > 0.1, "{t}");
    let stance = t["feet"]["right"]["stance_fraction"]["mean"]
        .as_f64()
        .unwrap();
    assert!((0.5..0.8).contains(&stance), "{stance}");
}

#[test]
fn bad_trainer_input_is_a_one_line_error_naming_the_field() {
    let dir = temp_dir("bad");
    let in_air = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/pma-leg/models/exo_leg.urdf"
    );
    let in_air_urdf = format!("physics_substeps = 4\nurdf = \"{in_air}\"");
    let cases: &[(&str, &str, &str)] = &[
        ("legs = 2", "legs = 3", "treadmill.legs"),
        ("legs = 2", "legs = 0", "treadmill.legs"),
        (
            "legs = 2",
            "legs = 2\ncontralateral = \"reference\"",
            "treadmill.contralateral",
        ),
        (
            "body_mass_kg = 75.0",
            "body_mass_kg = 5.0",
            "treadmill.body_mass_kg",
        ),
        (
            "speed_m_per_s = 0.4873",
            "speed_m_per_s = 12.0",
            "treadmill.speed_m_per_s",
        ),
        // Issue 47: a belt with no adult reference (recorded at 0.499 m/s only) ran and
        // the patient collapsed, exit 0.
        (
            "speed_m_per_s = 0.4873",
            "speed_m_per_s = 0.7",
            "treadmill.speed_m_per_s = 0.7 is invalid: has no adult reference",
        ),
        (
            "bws_fraction = 0.3",
            "bws_fraction = 1.5",
            "treadmill.bws_fraction",
        ),
        (
            "body_mass_kg = 75.0",
            "body_mass_kg = 75.0\n[treadmill.ankle]\nrange_deg = [5.0, 15.0]",
            "treadmill.ankle.range_deg",
        ),
        (
            "body_mass_kg = 75.0",
            "body_mass_kg = 75.0\n[treadmill.ankle]\nrest_deg = 20.0",
            "treadmill.ankle.rest_deg",
        ),
        (
            "body_mass_kg = 75.0",
            "body_mass_kg = 75.0\n[treadmill.contact]\nfriction = 1.0e6",
            "treadmill.contact.friction",
        ),
        (
            "speed_m_per_s = 0.5",
            "speed_m_per_s = 0.9",
            "gait.speed_m_per_s",
        ),
        (
            "physics_substeps = 4",
            &in_air_urdf,
            "the URDF has 1 leg(s)",
        ),
        ("legs = 2", "legs = 2\nwalking_aid = true", "walking_aid"),
        (
            "support_fraction = 0.5",
            "support_fraction = 1.2",
            "control.gains_below_support.support_fraction = 1.2 is invalid: must be in [0, 1]",
        ),
        (
            "[control.gains_below_support.gains]\n",
            "[control.gains_below_support.gains]\nkp = 1.0\n",
            "control.gains_below_support.gains",
        ),
        // An in-step start needs whole strides to start in double support.
        ("ramp_s = 1.7535\n", "ramp_s = 1.0\n", "gait.ramp_s"),
        (
            "cos_deg = [1.00503,",
            "cos_deg = [11.0,",
            "gait.hip_correction",
        ),
        (
            "cos_deg = [1.00503,",
            "cos_deg = [nan,",
            "gait.hip_correction",
        ),
        (
            "sin_deg = [0.00000,",
            "sin_deg = [0.5,",
            "gait.hip_correction.sin_deg[0]",
        ),
        (
            "sin_deg = [0.00000,",
            "sin_deg = [0.0, 1.0]\nfoo = [0.0,",
            "gait.hip_correction",
        ),
    ];
    for (i, (from, to, needle)) in cases.iter().enumerate() {
        let path = scenario_with(&dir, &format!("bad{i}.toml"), &[(from, to)]);
        assert_refused(&path, needle);
    }
}

#[test]
fn fit_gait_refuses_bad_arguments_before_any_run_in_one_line() {
    for (args, needle) in [
        (&["fit-gait", "--iterations", "0"][..], "--iterations"),
        (&["fit-gait", "--gain", "1.5"][..], "--gain"),
        (&["fit-gait", "--gain", "nan"][..], "--gain"),
        (&["fit-gait", "--strides", "0"][..], "--strides"),
        (&["fit-gait", "gait_training"][..], "treadmill"),
        (&["fit-gait", "no_such_scenario"][..], "no_such_scenario"),
    ] {
        let out = pma_exo(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}: succeeded");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.contains(needle) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn fit_gait_says_when_the_belt_without_drag_is_far_from_the_stance() {
    // At 0 % support the stance slides: the belt without drag runs far below the stance's
    // speed, and the fit says so instead of handing out that belt silently.
    let dir = temp_dir("fit_gait_slides");
    let path = scenario_with(
        &dir,
        "unsupported.toml",
        &[("bws_fraction = 0.3", "bws_fraction = 0.0")],
    );
    let out = pma_exo(&[
        "fit-gait",
        path.to_str().unwrap(),
        "--iterations",
        "1",
        "--strides",
        "1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("the stance does not move with the belt"),
        "{err}"
    );
    // The shipped scenario's does not warn (its belt is 0.9 % below the stance's).
    let shipped = pma_exo(&["fit-gait", "--iterations", "1", "--strides", "1"]);
    let err = String::from_utf8_lossy(&shipped.stderr);
    assert!(!err.contains("does not move"), "{err}");
}

#[test]
fn fit_gait_writes_the_lines_the_scenario_takes() {
    // Its output pasted into a scenario is a scenario that loads, with that belt speed.
    let dir = temp_dir("fit_gait");
    let snippet = dir.join("fit.toml");
    let out = pma_exo(&[
        "fit-gait",
        "gait_treadmill",
        "--iterations",
        "1",
        "--strides",
        "1",
        "--out",
        snippet.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&snippet).unwrap();
    let correction =
        &text[text.find("[gait.hip_correction]").unwrap()..text.find("\n\n# and in").unwrap()];
    let speed = text
        .lines()
        .find(|l| l.starts_with("speed_m_per_s"))
        .unwrap();
    let start = SCENARIO.find("[gait.hip_correction]").unwrap();
    let end = start + SCENARIO[start..].find("\n\n").unwrap();
    let spliced = format!("{}{}{}", &SCENARIO[..start], correction, &SCENARIO[end..]);
    // `edited` asserts the shipped belt's line is there: after a refit of the scenario this
    // fails instead of leaving the belt unedited.
    let path = edited(
        &spliced,
        &dir,
        "fitted.toml",
        &[("speed_m_per_s = 0.4873", speed)],
    );
    // A fit of a few iterations is not converged: its stride asks many times the adults'
    // moments, which `simulate` refuses unless told to run it, and whether it walks is not
    // this test's question (it ends with a verdict either way).
    let v = judged(&[
        "simulate",
        path.to_str().unwrap(),
        "--allow-unfit",
        "--duration",
        "4",
        "--json",
    ]);
    let belt = v["treadmill"]["belt_speed_m_s"].as_f64().unwrap();
    let written: f64 = speed.split('=').nth(1).unwrap().trim().parse().unwrap();
    assert!((belt - written).abs() < 1e-12, "{belt} vs {written}");
}

#[test]
fn size_recommends_muscles_the_two_legs_then_run_on() {
    let dir = temp_dir("size");
    let out = dir.join("m.toml");
    // The servo's sizing alone (the closed-loop check is the next test's).
    let v = json_of(&[
        "size",
        "gait_treadmill",
        "--closed-loop-s",
        "0",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["closed_loop"].as_array().unwrap().len(), 0);
    let joints = v["sizing"]["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 2);
    for j in joints {
        let d = &j["recommended"];
        assert!(d["peak_force_over_rated"].as_f64().unwrap() <= 0.9, "{j}");
        assert!(d["speed_over_useful"].as_f64().unwrap() <= 0.9, "{j}");
    }
    // The demand is compared with the adults' moments at the same speed, per joint.
    let norms = v["against_norms"].as_array().unwrap();
    assert_eq!(norms.len(), 2);
    for (n, j) in norms.iter().zip(["hip", "knee"]) {
        assert_eq!(n["joint"], j, "{n}");
        // The adults' moment over a cycle, as many points as the demand's.
        let points = n["demand_nm_kg"].as_array().unwrap().len();
        assert_eq!(points, n["normative_nm_kg"].as_array().unwrap().len());
        assert!(points >= 50, "{points}");
        assert!(n["peak_demand_nm_kg"].as_f64().unwrap() > 0.0, "{n}");
        assert!(n["peak_normative_nm_kg"].as_f64().unwrap() > 0.1, "{n}");
    }
    // The written geometry is a muscle file the scenario runs on.
    let scenario = scenario_with(
        &dir,
        "sized.toml",
        &[(
            "physics_substeps = 4",
            "physics_substeps = 4\nmuscle_geometry = \"m.toml\"",
        )],
    );
    let run = judged(&[
        "simulate",
        scenario.to_str().unwrap(),
        "--duration",
        "4",
        "--json",
    ]);
    assert!(run["finite"].as_bool().unwrap());
    // It refuses to write over what it reads.
    let again = pma_exo(&[
        "size",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success() && err.contains("refusing"), "{err}");
}

/// Issue 46 item 5: `size` runs its recommendation in closed loop. On the in-air leg the
/// controller takes more of the rating than the servo (0.75 against 0.60 at the hip), so
/// the muscles are sized again with the margin raised by that share, and the second
/// recommendation holds. The trainer holds its muscles with a force limit: the check runs
/// under it lowered to the margin (0.60 of the rating), the patient walks and every joint
/// stays within the margin plus a tenth, and the file says which limit to set; without the
/// limit, the scenario's controller takes the recommended muscles to their rating and the
/// patient does not walk: nothing is written, exit 1, one line.
#[test]
fn size_checks_its_recommendation_in_closed_loop_and_sizes_again_or_says_why_not() {
    let dir = temp_dir("size-closed-loop");
    let v = json_of(&["size", "gait_training", "--strides", "1", "--json"]);
    let checks = v["closed_loop"].as_array().unwrap();
    assert_eq!(checks.len(), 2, "{checks:?}");
    let (first, second) = (&checks[0], &checks[1]);
    // The default check is as long as the walking verdict's run: over the earlier 20 s the
    // unsupported trainer's second design held and was written, and its own 60 s run
    // collapsed at 32.11 s (docs/treadmill.md).
    for c in checks {
        assert_eq!(c["duration_s"].as_f64(), Some(60.0), "{c}");
    }
    assert!(!first["holds"].as_bool().unwrap() && first["why_not"].is_null());
    assert_eq!(first["force_margin"].as_f64().unwrap(), 0.4);
    let over = |c: &serde_json::Value| {
        c["joints"].as_array().unwrap().iter().any(|j| {
            j["peak_over_rated"].as_f64().unwrap() > j["allowed_over_rated"].as_f64().unwrap()
        })
    };
    assert!(over(first), "{first}");
    // The margin raised by the controller's share, the new design within it, and the
    // closed loop within the stated margin plus a tenth.
    let share = first["joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            j["peak_over_rated"].as_f64().unwrap() - j["servo_peak_over_rated"].as_f64().unwrap()
        })
        .fold(0.0, f64::max);
    let raised = second["force_margin"].as_f64().unwrap();
    assert!(
        (raised - (0.4 + share)).abs() < 1e-12,
        "{raised} vs {share}"
    );
    assert!(
        second["holds"].as_bool().unwrap() && !over(second),
        "{second}"
    );
    for j in second["joints"].as_array().unwrap() {
        assert!(j["servo_peak_over_rated"].as_f64().unwrap() <= 1.0 - raised + 1e-9);
        assert!(j["allowed_over_rated"].as_f64().unwrap() == 1.0 - 0.4 + 0.1);
    }
    for j in v["sizing"]["joints"].as_array().unwrap() {
        let d = &j["recommended"];
        assert!(d["peak_force_over_rated"].as_f64().unwrap() <= 1.0 - raised + 1e-9);
    }
    // The trainer's recommendation under its force limit lowered to the margin: it walks
    // within the margin, and the file says which limit to run it with.
    let out = dir.join("m.toml");
    let out_path = out.to_str().unwrap();
    // Sized on the default three strides: at the trainer's four physics substeps (stop 77
    // of issue 50) a sizing on one stride recommends DMSP-40s on which the passive patient's
    // knee misses 2 deg in all three checks (2.70, 2.37, 3.01 deg; exit 1), where at two
    // substeps that recommendation walked.
    let size = |scenario: &str| {
        pma_exo(&[
            "size",
            scenario,
            "--strides",
            "3",
            "--closed-loop-s",
            "8",
            "--out",
            out_path,
            "--json",
        ])
    };
    let run = size("gait_treadmill");
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let last = v["closed_loop"].as_array().unwrap().last().unwrap().clone();
    assert!(last["holds"].as_bool().unwrap(), "{last}");
    assert_eq!(last["walking"].as_bool(), Some(true), "{last}");
    let stated = last["stated_margin"].as_f64().unwrap();
    assert_eq!(last["force_max_of_rating"].as_f64(), Some(1.0 - stated));
    assert!(!over(&last), "{last}");
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(
        written.contains(&format!("force_max_of_rating to {:.2}", 1.0 - stated)),
        "{written}"
    );
    std::fs::remove_file(&out).unwrap();
    // Without a force limit: no walking, no file.
    let unlimited = scenario_with(&dir, "unlimited.toml", &[FORCE_LIMIT_OFF]);
    let run = size(unlimited.to_str().unwrap());
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(!out.exists());
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("does not hold in closed loop"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let checks = v["closed_loop"].as_array().unwrap();
    assert!(checks.iter().all(|c| !c["holds"].as_bool().unwrap()), "{v}");
    assert!(
        checks.iter().all(|c| c["force_max_of_rating"].is_null()),
        "{v}"
    );
    // The check that ends the sizing says why (the patient did not walk, or collapsed), and
    // the one line says the same.
    let last = checks.last().unwrap();
    let why = last["why_not"].as_str().unwrap();
    assert!(
        why.contains("did not walk") || why.contains("collapse at"),
        "{last}"
    );
    assert!(err.contains(why), "{err}");
    assert!(v["muscle_geometry"].is_null());
}

/// Issue 47 item 4: a belt the reference was not recorded at asks the joints many times
/// what walking asks (the servo-driven stride, as `size` measures it); `simulate` refuses
/// it before anything runs and `size` recommends nothing for it, each in one line naming
/// the figure; the belt the reference is fitted to runs.
#[test]
fn a_belt_the_reference_does_not_fit_is_refused_before_it_runs() {
    let dir = temp_dir("belt-unfit");
    let fast = scenario_with(
        &dir,
        "fast.toml",
        &[("speed_m_per_s = 0.4873", "speed_m_per_s = 0.55")],
    );
    let csv = dir.join("run.csv");
    let out = pma_exo(&[
        "simulate",
        fast.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("times the adults'") && err.contains("does not fit its gait data"),
        "{err}"
    );
    assert!(!csv.exists());
    let m = dir.join("m.toml");
    let out = pma_exo(&[
        "size",
        fast.to_str().unwrap(),
        "--out",
        m.to_str().unwrap(),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("no muscles are recommended"), "{err}");
    assert!(!m.exists());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let hip = &v["against_norms"][0];
    let ratio =
        hip["peak_demand_nm_kg"].as_f64().unwrap() / hip["peak_normative_nm_kg"].as_f64().unwrap();
    assert!(ratio > pma_leg::tools::DEMAND_OVER_NORM_MAX, "{ratio}");
    assert!(v["closed_loop"].as_array().unwrap().is_empty());
    // The fitted belt asks 2.3 times the adults' at the hip and runs.
    let v = json_of(&[
        "size",
        "gait_treadmill",
        "--strides",
        "1",
        "--closed-loop-s",
        "0",
        "--json",
    ]);
    assert!(v["beyond_norms"].is_null(), "{}", v["beyond_norms"]);
}

#[test]
fn the_controllers_walk_both_legs_finite_and_within_their_limits() {
    // 8 s of gait_treadmill per controller, each on its gains tuned on the two legs within
    // the muscles' rating (the 60 s figures are in docs/treadmill.md).
    // Behind the MPYE-5-1/4 valves (issue 46): every controller but PSMC holds both legs
    // up for these 8 s (no collapse), within the joints' limits and the muscles' rating;
    // whether each tracks within the verdict's 2 deg over 60 s is docs/treadmill.md's
    // table. PSMC loses the passive patient at 4.20 s on the belt refitted at two physics
    // substeps (issue 50; 9.31 s on the previous fit, 45.81 s at one substep, 5.94 s on
    // its gains before the valve's dead time was made exact): its run says so, below.
    for c in ["aprc-ndo", "psmc", "ndo-smc", "sta", "pid"] {
        let v = judged(&[
            "simulate",
            "gait_treadmill",
            "--controller",
            c,
            "--duration",
            "8",
            "--json",
        ]);
        assert!(v["finite"].as_bool().unwrap(), "{c}");
        let (rms, over) = worst_rms_and_force(&v);
        let beyond = worst(&v["safety"]["joints"], "max_beyond_deg");
        eprintln!("{c}: worst RMS {rms:.2} deg, peak force / rating {over:.2}, beyond the URDF limits {beyond:.2} deg, walked {}", walked(&v));
        if c == "psmc" {
            assert!(
                !walked(&v)
                    && v["walking"]["collapse"]["t_s"]
                        .as_f64()
                        .is_some_and(|t| t < 8.0),
                "{c}: {}",
                v["walking"]
            );
        } else {
            assert!(v["walking"]["collapse"].is_null(), "{c}: {}", v["walking"]);
        }
        assert!(beyond < 1.0, "{c}: {beyond} deg beyond a limit");
        assert!(over <= 1.0, "{c}: {over} of the rating");
    }
    // Behind the instantaneous valve, on the gains tuned there, every controller walks these
    // 8 s at the shipped step (`json_of`: exit 0) and tracked within 1.5 deg at the one
    // physics substep the gains were tuned and these figures made at (before issue 46; at
    // four substeps NDO-SMC's worst joint reads 1.76 deg).
    let dir = temp_dir("controllers-ideal");
    let ideal_text = ideal_valve(SCENARIO);
    let ideal = edited(&ideal_text, &dir, "ideal.toml", &[]);
    let one_step = edited(
        &ideal_text,
        &dir,
        "ideal-1.toml",
        &[("physics_substeps = 4", "physics_substeps = 1")],
    );
    for c in ["aprc-ndo", "psmc", "ndo-smc", "sta", "pid"] {
        let run = |path: &std::path::Path| {
            json_of(&[
                "simulate",
                path.to_str().unwrap(),
                "--controller",
                c,
                "--duration",
                "8",
                "--json",
            ])
        };
        let (_, over) = worst_rms_and_force(&run(&ideal));
        assert!(over <= 1.0, "{c}: {over} of the rating");
        let (rms, over) = worst_rms_and_force(&run(&one_step));
        assert!(over <= 1.0, "{c}: {over} of the rating at one substep");
        assert!(rms < 1.5, "{c}: {rms} deg RMS at one substep");
    }
}

/// Issue 46: the trainer's shipped force limit (`force_max_of_rating = 0.85`) keeps
/// APRC-NDO's muscles within 0.9 of their rating on both patients while they walk, at
/// pressure rates the valve delivers; without it the same 20 s take a knee extensor past
/// 0.9 (0.996 when measured).
#[test]
fn the_shipped_force_limit_keeps_aprc_ndo_within_0_9_of_the_rating_where_it_went_past() {
    let valve = json_of(&["valve", "mpye-5-1-4", "--json"]);
    let delivered_bar_s = valve["response"]["peak_rise_rate_pa_s"].as_f64().unwrap() * 1e-5;
    let peaks = |v: &serde_json::Value| {
        (
            worst(&v["safety"]["muscles"], "peak_over_rated"),
            worst(&v["safety"]["muscles"], "peak_pressure_rate_bar_s"),
        )
    };
    for scenario in ["gait_treadmill", "gait_treadmill_spastic"] {
        let v = judged(&["simulate", scenario, "--duration", "20", "--json"]);
        assert!(walked(&v), "{scenario}: {}", v["walking"]);
        let (over, rate) = peaks(&v);
        assert!(over <= 0.9, "{scenario}: {over} of the rating");
        assert!(rate <= delivered_bar_s, "{scenario}: {rate} bar/s");
    }
    let dir = temp_dir("force-limit-off");
    let unlimited = scenario_with(&dir, "unlimited.toml", &[FORCE_LIMIT_OFF]);
    let v = judged(&[
        "simulate",
        unlimited.to_str().unwrap(),
        "--duration",
        "20",
        "--json",
    ]);
    let (over, _) = peaks(&v);
    assert!(over > 0.9, "without the limit: {over} of the rating");
}

/// The largest `key` over the entries of the JSON object `o` (joints or muscles).
fn worst(o: &serde_json::Value, key: &str) -> f64 {
    o.as_object()
        .unwrap()
        .values()
        // `null` (a figure the run could not give: it collapsed within its first stride)
        // counts as NaN, which `max` skips.
        .map(|m| m[key].as_f64().unwrap_or(f64::NAN))
        .fold(0.0, f64::max)
}

/// The worst joint's RMS error (deg) and the worst muscle's peak force over its rating of
/// `simulate SCENARIO --controller C --duration S --json`.
fn worst_rms_and_force(v: &serde_json::Value) -> (f64, f64) {
    (
        worst(&v["joints"], "rms_deg"),
        worst(&v["safety"]["muscles"], "peak_over_rated"),
    )
}

#[test]
fn without_support_aprc_ndo_pid_psmc_and_sta_walk_from_an_in_step_start() {
    // gait_treadmill_unsupported: 0 % support from the first instant, started in step.
    // APRC-NDO, PID, PSMC and STA walk it (60 s in docs/treadmill.md); NDO-SMC, tuned at
    // 30 %, lets a knee buckle at about 10 s (documented, not pinned).
    // Behind the instantaneous valve, on the gains tuned there (before issue 46).
    let dir = temp_dir("unsupported-ideal");
    let ideal = edited(&ideal_valve(UNSUPPORTED), &dir, "ideal.toml", &[]);
    for c in ["aprc-ndo", "pid", "psmc", "sta"] {
        let v = json_of(&[
            "simulate",
            ideal.to_str().unwrap(),
            "--controller",
            c,
            "--duration",
            "8",
            "--json",
        ]);
        let (rms, over) = worst_rms_and_force(&v);
        eprintln!("{c}: worst RMS {rms:.2} deg, peak force / rating {over:.2}");
        assert!(v["finite"].as_bool().unwrap(), "{c}");
        assert!(rms < 1.5, "{c}: {rms} deg RMS");
        assert!(over <= 1.0, "{c}: {over} of the rating");
    }
    // Behind the MPYE-5-1/4 valves PID, and APRC-NDO on the scenario's own set, do not walk
    // the patient without support (a finding of issue 46, docs/treadmill.md): each run says
    // so, exit 4, no NaN. APRC-NDO on the set the scenario's schedule gives at 0 % support
    // walks it (issue 47; 60 s in docs/treadmill.md): these 8 s walk by the verdict.
    // NDO-SMC, tuned again on the corrected valve, walked them at two physics substeps; at
    // the four shipped since stop 77 of issue 50 its knee reads 2.05 deg over these 8 s and
    // over 60 s it collapses at 53.79 s (docs/treadmill.md): judged, not pinned either way.
    let eight_s = |c: &str| {
        judged(&[
            "simulate",
            "gait_treadmill_unsupported",
            "--controller",
            c,
            "--duration",
            "8",
            "--json",
        ])
    };
    assert!(eight_s("ndo-smc")["finite"].as_bool().unwrap(), "ndo-smc");
    let v = eight_s("aprc-ndo");
    assert!(walked(&v), "aprc-ndo: {}", v["walking"]);
    for gains in [
        &["--controller", "aprc-ndo", "--gains", OWN_GAINS][..],
        &["--controller", "pid"],
    ] {
        let args: Vec<&str> = ["simulate", "gait_treadmill_unsupported", "--duration", "8"]
            .iter()
            .chain(gains)
            .copied()
            .collect();
        let out = pma_exo(&args);
        let text = String::from_utf8_lossy(&out.stdout);
        let c = gains[1];
        assert_eq!(out.status.code(), Some(4), "{c}: {text}");
        assert!(
            text.contains("walking: NO") && !text.contains("NaN"),
            "{c}: {text}"
        );
    }
}

/// The worst joint's RMS error (deg) and muscle's peak force over its rating of `path` in
/// impedance mode for `duration_s`, the run asserted finite.
fn impedance_run(path: &std::path::Path, duration_s: &str) -> (f64, f64, bool) {
    let v = judged(&[
        "simulate",
        path.to_str().unwrap(),
        "--mode",
        "impedance",
        "--duration",
        duration_s,
        "--json",
    ]);
    assert!(v["finite"].as_bool().unwrap(), "{}", path.display());
    let (rms, force) = worst_rms_and_force(&v);
    (rms, force, walked(&v))
}

#[test]
fn impedance_mode_walks_the_passive_patient_from_85_percent_support_on_the_dmsp_20s() {
    // docs/cooperative.md: on the shipped DMSP-20s the default stiffness (the middle of each
    // pair's reach, about 64 / 16 N m/rad) walks with the stance load from 85 % support; at
    // 80 % the first swing lags and the knees sink (40 deg RMS in 8 s against 4.9).
    let dir = temp_dir("impedance-support");
    let rms_at = |support: &str| {
        let support_edit = format!("bws_fraction = {support}");
        let path = edited(
            &ideal_valve(SCENARIO),
            &dir,
            &format!("bws-{support}.toml"),
            &[("bws_fraction = 0.3", support_edit.as_str())],
        );
        impedance_run(&path, "8")
    };
    let (walks, walks_force, _) = rms_at("0.85");
    let (sinks, _, sank_walking) = rms_at("0.8");
    eprintln!("worst RMS at 85 %: {walks:.2} deg; at 80 %: {sinks:.2} deg");
    assert!(walks < 8.0, "85 %: {walks} deg RMS");
    assert!(walks_force <= 1.0, "85 %: {walks_force} of the rating");
    // At 80 % the knees sink: the trainer's safety stops the run and says so.
    assert!(!sank_walking && sinks > 5.0, "80 %: {sinks} deg RMS");
}

#[test]
fn impedance_mode_learning_the_stance_walks_the_passive_patient_down_to_30_percent() {
    // docs/cooperative.md: the harness at 60 % for five strides, lowered to 30 % over the
    // next ten; with the feedforward learned stride by stride the legs walk on (1.1 / 1.9
    // deg RMS over 60 s), without it they are lost at the start (17 / 65 deg).
    let dir = temp_dir("impedance-learning");
    let lowered = (
        "bws_fraction = 0.3",
        "bws_fraction = 0.3\nbws_start_fraction = 0.6\nbws_release_s = [8.77, 26.3]",
    );
    let learning = (
        "body_mass_kg = 75.0",
        "body_mass_kg = 75.0\n\n[control.impedance.learning]\ngain = 1.0\nforgetting = 0.95",
    );
    let ideal = ideal_valve(SCENARIO);
    let run = |name: &str, edits: &[(&str, &str)]| {
        impedance_run(&edited(&ideal, &dir, name, edits), "32")
    };
    let (learned, force, _) = run("learning.toml", &[lowered, learning]);
    let (unlearned, _, unlearned_walked) = run("without.toml", &[lowered]);
    eprintln!("worst RMS with learning {learned:.2} deg, without {unlearned:.2} deg");
    assert!(learned < 3.0, "with learning: {learned} deg RMS");
    assert!(force <= 1.0, "with learning: {force} of the rating");
    // Without it the legs are lost at the start: the trainer's safety stops the run.
    assert!(
        !unlearned_walked && unlearned > 5.0,
        "without learning: {unlearned} deg RMS"
    );
}

/// The largest fore-aft ground reaction of either foot (N) over `from_s..to_s` of a
/// `simulate --csv` file.
fn peak_fore_aft_n(csv_path: &std::path::Path, from_s: f64, to_s: f64) -> f64 {
    let mut r = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(csv_path)
        .expect("csv");
    let head = r.headers().unwrap().clone();
    let col = |name: &str| head.iter().position(|h| h == name).unwrap();
    let (t, feet) = (
        col("t_s"),
        ["right", "left"].map(|s| col(&format!("{s}_foot_grf_fore_aft_n"))),
    );
    r.records()
        .map(|row| row.unwrap())
        .filter(|row| (from_s..to_s).contains(&row[t].parse::<f64>().unwrap()))
        .flat_map(|row| feet.map(|c| row[c].parse::<f64>().unwrap().abs()))
        .fold(0.0, f64::max)
}

#[test]
fn regression_a_standing_start_up_dragged_the_feet_and_buckled_unsupported_knees() {
    // The bug this pins (behind the instantaneous valve it was found with): started
    // standing, the legs straight while the belt comes up to speed, the belt drags both
    // standing feet (up to 582 N fore-aft each); without support the stance knee's extensor
    // reached 6 bar at 0.7 s and both legs sank into a crouch under every controller. Started in step, the feet move with the belt: after the
    // first 0.1 s (the rest pose settling fore-aft, 298 N at 6 ms) the start-up's largest
    // fore-aft reaction was 103 N, and the knees walk.
    let dir = temp_dir("unsupported-start");
    // Behind the instantaneous valve, on the gains tuned there (before issue 46).
    let unsupported = ideal_valve(UNSUPPORTED);
    let in_step = edited(&unsupported, &dir, "in-step.toml", &[]);
    let standing = edited(
        &unsupported,
        &dir,
        "standing-start.toml",
        &[("start_up = \"in_step\"", "start_up = \"standing\"")],
    );
    let ramp_s = 1.7535;
    let mut seen = Vec::new();
    for (name, path) in [
        ("in step", in_step.to_str().unwrap()),
        ("standing", standing.to_str().unwrap()),
    ] {
        let csv_path = dir.join(format!("{}.csv", name.replace(' ', "-")));
        let v = judged(&[
            "simulate",
            path,
            "--controller",
            "pid",
            "--duration",
            "8",
            "--json",
            "--csv",
            csv_path.to_str().unwrap(),
        ]);
        let (rms, _) = worst_rms_and_force(&v);
        let drag = peak_fore_aft_n(&csv_path, 0.1, ramp_s);
        eprintln!(
            "pid, started {name}: worst RMS {rms:.2} deg, start-up fore-aft peak {drag:.0} N"
        );
        seen.push((rms, drag, walked(&v)));
    }
    let [(walk_rms, walk_drag, walks), (buckle_rms, buckle_drag, buckles_walking)] =
        [seen[0], seen[1]];
    assert!(walks && walk_rms < 1.5 && walk_drag < 200.0, "{seen:?}");
    // The crouch: now stopped by the trainer's safety as it happens.
    // The standing start drags the feet at least twice as hard as the in-step one before
    // the knees give (582 N over the whole start-up before issue 46; now the run stops at
    // the collapse, 258 N against 88 N in step).
    let _ = buckle_rms;
    assert!(
        !buckles_walking && buckle_drag > 2.0 * walk_drag,
        "{seen:?}"
    );
}

#[test]
fn a_foot_sunk_through_the_belt_ends_the_run() {
    // A belt 200 times softer (the softest pad allowed) lets a foot sink past its spheres' size: the contact
    // model no longer means anything, and the run fails in one line.
    let dir = temp_dir("sink");
    let path = scenario_with(
        &dir,
        "soft.toml",
        &[(
            "body_mass_kg = 75.0",
            "body_mass_kg = 75.0\n[treadmill.contact]\nstiffness_n_per_m2 = 1.0e4",
        )],
    );
    assert_refused(&path, "into the belt");
}

/// `simulate PATH --mode admittance --duration S --json`'s worst joint RMS (deg).
fn admittance_rms(path: &std::path::Path, duration_s: &str) -> (f64, bool) {
    let v = judged(&[
        "simulate",
        path.to_str().unwrap(),
        "--mode",
        "admittance",
        "--duration",
        duration_s,
        "--json",
    ]);
    assert!(v["finite"].as_bool().unwrap(), "{}", path.display());
    (worst_rms_and_force(&v).0, walked(&v))
}

#[test]
fn admittance_with_phase_sync_walks_a_patient_on_their_own_timing_which_a_fixed_clock_loses() {
    // docs/cooperative.md: the patient producing the adults' moments on their own clock
    // (stride time varying by 2 %, seed 1) at 300 N m/rad, the plan leaving them the
    // adults' moments. On the reference's own clock their phase drifts away and the legs
    // are lost at about 39 s; with the clock following the legs' lead they walk 60 s
    // within a degree.
    let dir = temp_dir("phase-sync");
    let with_sync = |gain: &str| {
        let path = dir.join(format!("sync-{gain}.toml"));
        let base = ideal_valve(SCENARIO);
        let text = format!(
            "{base}\n[control.impedance]\npatient_moment_share = 1.0\nphase_sync_per_s = {gain}\n\
             [control.impedance.hip]\nstiffness_nm_per_rad = 300.0\n\
             [control.impedance.knee]\nstiffness_nm_per_rad = 300.0\n\
             [patient.active]\nseed = 1\nown_torque = \"walking\"\n"
        );
        std::fs::write(&path, text).unwrap();
        admittance_rms(&path, "45")
    };
    let ((fixed, fixed_walked), (synced, _)) = (with_sync("0.0"), with_sync("2.0"));
    eprintln!("worst RMS over 45 s: fixed clock {fixed:.2} deg, synchronised {synced:.2} deg");
    assert!(synced < 2.0, "synchronised: {synced} deg RMS");
    // On the fixed clock the legs are lost: the trainer's safety stops the run.
    assert!(!fixed_walked, "fixed clock: {fixed} deg RMS");
}

#[test]
fn leaving_moments_or_timing_to_the_patient_is_refused_where_no_mode_yields() {
    let dir = temp_dir("yield");
    for (field, value) in [
        ("patient_moment_share", "1.0"),
        ("phase_sync_per_s", "2.0"),
        ("phase_sync_integral_per_s2", "0.5"),
    ] {
        let path = dir.join(format!("{field}.toml"));
        let text = format!("{SCENARIO}\n[control.impedance]\n{field} = {value}\n");
        std::fs::write(&path, &text).unwrap();
        // The scenario runs in position mode: nothing yields to the patient.
        assert_refused(&path, &format!("control.impedance.{field}"));
        let negative = text.replace(&format!("{field} = {value}"), &format!("{field} = -1.0"));
        std::fs::write(&path, negative).unwrap();
        assert_refused(&path, &format!("control.impedance.{field}"));
    }
    // In a mode that yields, an integral beyond the clock loop's stability bound (the
    // gain over the stride period, 2 / 1.75 per s²) is refused.
    let path = dir.join("unstable.toml");
    std::fs::write(
        &path,
        format!(
            "{}\n[control.impedance]\nphase_sync_per_s = 2.0\nphase_sync_integral_per_s2 = 1.2\n",
            SCENARIO.replace("[control]\n", "[control]\nmode = \"admittance\"\n")
        ),
    )
    .unwrap();
    assert_refused(&path, "control.impedance.phase_sync_integral_per_s2");
}

/// The APRC-NDO gains the two-leg trainer shipped with before issue 46, tuned behind an
/// instantaneous valve.
const IDEAL_VALVE_APRC_NDO: &str = "controller = \"aprc-ndo\"\nc1_per_s = 158.50604313312132\nc2_per_s2 = 25074.401950314685\nkp_per_s2 = 45663.18740199615\nki_per_s3 = 1.4235616774752866\nkd_per_s = 118.55387732701718\nkappa_per_s = 86.42181482869607\ngamma = 91.74323744394668\nproxy_mass = 4.1135834969172755\nestimator_bandwidth_rad_s = 574.8866122356712\n";

/// Issue 46: the trainer with the gains it shipped with for an instantaneous valve, behind
/// a 30 ms first-order lag: the patient's knees buckle. The trainer's safety stops the run while it happens: one line on stderr naming
/// the collapse and when, exit 4, `walking: false` with its reasons in the JSON, the CSV
/// closed by a `# ended at` line, and no `NaN` in the text summary.
#[test]
fn a_collapse_is_stopped_while_it_happens_and_said_in_one_line() {
    let dir = temp_dir("collapse");
    let path = scenario_with(
        &dir,
        "lag30.toml",
        &[
            ("valve = \"mpye-5-1-4\"", "valve = \"ideal\""),
            (
                "pressure_max_pa = 5.0e5",
                "pressure_max_pa = 5.0e5\ntime_constant_s = 0.030",
            ),
            ("pressure_feedback = true", "pressure_feedback = false"),
        ],
    );
    let p = path.to_str().unwrap();
    // The APRC-NDO gains the trainer shipped with for its instantaneous valve (756c24e).
    let gains = dir.join("ideal-valve-gains.toml");
    std::fs::write(&gains, IDEAL_VALVE_APRC_NDO).unwrap();
    let g = gains.to_str().unwrap();
    let csv = dir.join("run.csv");
    let out = pma_exo(&[
        "simulate",
        p,
        "--controller",
        "aprc-ndo",
        "--gains",
        g,
        "--duration",
        "20",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(4), "{err}\n{text}");
    let last = err.trim_end().lines().last().unwrap_or_default();
    assert!(
        last.starts_with("the patient did not walk: collapse at "),
        "{err}"
    );
    assert!(!text.contains("NaN"), "{text}");
    assert!(text.contains("walking: NO"), "{text}");
    let csv_text = std::fs::read_to_string(&csv).expect("csv");
    assert!(csv_text
        .trim_end()
        .lines()
        .last()
        .unwrap_or_default()
        .starts_with("# ended at "));
    let json = pma_exo(&[
        "simulate",
        p,
        "--controller",
        "aprc-ndo",
        "--gains",
        g,
        "--duration",
        "20",
        "--json",
    ]);
    assert_eq!(json.status.code(), Some(4));
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).expect("json");
    let w = &v["walking"];
    assert_eq!(w["walking"], false, "{w}");
    let t = w["collapse"]["t_s"].as_f64().expect("collapse time");
    assert!(t < 20.0, "{w}");
    assert!(
        v["duration_s"].as_f64().expect("duration") < 20.0,
        "the run stopped at the collapse"
    );
    assert!(!w["reasons"].as_array().expect("reasons").is_empty());
}

/// Issue 49: a fixed-length list with extra entries was accepted and the extras dropped
/// (`range_deg = [-15, 15, 999]`, an 8-entry `cos_deg`, `bws_release_s = [0, 1, 5]`,
/// `patient_moment_share_by_leg = [1.0, 0.4, 7]`, `bias_nm = [1, 2, 3]`); too short was
/// refused. Both are refused now, in one line naming the list's length.
#[test]
fn a_fixed_length_list_of_another_length_is_refused() {
    let dir = temp_dir("lengths");
    let cos = "cos_deg = [1.00503, 0.19830, -0.79576, -0.07485, -0.19289, -0.12336, -0.07280]";
    let cases: &[(&str, &str, &str)] = &[
        (
            "body_mass_kg = 75.0",
            "body_mass_kg = 75.0\n\n[treadmill.ankle]\nrange_deg = [-15, 15, 999]",
            "exactly 2",
        ),
        (
            cos,
            &format!("{}, 0.1]", cos.trim_end_matches(']')),
            "exactly 7",
        ),
        (
            "bws_fraction = 0.3",
            "bws_fraction = 0.3\nbws_start_fraction = 0.6\nbws_release_s = [0, 1, 5]",
            "exactly 2",
        ),
        (
            "[plant.pneumatics]",
            "[plant.cuff_sensor]\nbias_nm = [1, 2, 3]\n\n[plant.pneumatics]",
            "exactly 2",
        ),
        (
            "[plant.pneumatics]",
            "[plant.cuff_sensor]\nbias_nm = [1]\n\n[plant.pneumatics]",
            "exactly 2",
        ),
    ];
    for (i, (from, to, needle)) in cases.iter().enumerate() {
        let path = scenario_with(&dir, &format!("l{i}.toml"), &[(from, to)]);
        assert_refused(&path, needle);
    }
}

/// The `[plant.festo_scale.<muscle>]` tables that put each of the trainer's four muscles
/// `field` times off its datasheet.
fn festo_scaled(field: &str, factor: f64) -> String {
    ["hip_flexor", "hip_extensor", "knee_flexor", "knee_extensor"]
        .iter()
        .map(|m| format!("[plant.festo_scale.{m}]\n{field} = {factor}\n\n"))
        .collect()
}

#[test]
fn a_festo_muscle_off_its_datasheet_is_simulated_and_bad_factors_are_named() {
    let dir = temp_dir("festo-scale");
    let run = |path: &std::path::Path| {
        judged(&[
            "simulate",
            path.to_str().unwrap(),
            "--controller",
            "pid",
            "--duration",
            "8",
            "--json",
        ])
    };
    let peak_force = |v: &serde_json::Value| {
        let muscles = v["safety"]["muscles"].as_object().unwrap();
        muscles
            .values()
            .map(|m| m["peak_force_n"].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    let nominal = run(&scenario_with(&dir, "nominal.toml", &[]));
    // Four muscles 20 % stronger than their datasheet, the controllers assuming the
    // datasheet's: PID still walks the patient, the muscles pull harder at the pressures it
    // sets (995 -> 1146 N over 16 s, docs/treadmill.md), rated as the muscle bought.
    let strong_tables = festo_scaled("force_scale", 1.2) + "[plant.valve]\n";
    let strong = run(&scenario_with(
        &dir,
        "strong.toml",
        &[("[plant.valve]\n", &strong_tables)],
    ));
    assert!(walked(&strong), "{}", strong["walking"]);
    // A scaling that did not reach the plant gives 1.000 to the bit; PID closes part of
    // the 20 % (8 s: 1.15 when the valve's dead time acted a step short, 1.096 since it
    // is exact), so more than a quarter of it is what reaching the plant means here.
    let ratio = peak_force(&strong) / peak_force(&nominal);
    assert!(ratio > 1.05, "peak force {ratio} times the nominal's");
    for m in strong["safety"]["muscles"].as_object().unwrap().values() {
        assert_eq!(m["rated_force_n"], 1500.0, "{m}");
    }
    for (edit, needle) in [
        (
            festo_scaled("force_scale", 0.3),
            "plant.festo_scale.hip_flexor.force_scale = 0.3 is invalid: must be 0.5 to 1.5",
        ),
        (
            "[plant.festo_scale.knee_flexor]\nstrength = 0.9\n\n".to_owned(),
            "unknown field `strength`",
        ),
        (
            "[plant.festo_scale.ankle_flexor]\nforce_scale = 0.9\n\n".to_owned(),
            "plant.muscle_scale or plant.festo_scale names a muscle the geometry does not have",
        ),
        (
            "[plant.muscle_scale.knee_flexor]\nf1_scale = 0.9\n\n".to_owned(),
            "[plant.festo_scale.<muscle>] scales a Festo muscle",
        ),
    ] {
        let tables = edit + "[plant.valve]\n";
        let path = scenario_with(&dir, "bad.toml", &[("[plant.valve]\n", &tables)]);
        assert_refused(&path, needle);
    }
    // On a Table I muscle the Festo factors are refused, pointing to the Table I ones.
    let in_air = include_str!("../crates/pma-leg/models/scenarios/gait_training.toml");
    let path = edited(
        in_air,
        &dir,
        "in-air.toml",
        &[(
            "[plant.valve]\n",
            "[plant.festo_scale.knee_flexor]\nforce_scale = 0.9\n\n[plant.valve]\n",
        )],
    );
    assert_refused(
        &path,
        "plant.festo_scale applies to Festo muscles (`size`) only",
    );
}

/// Issue 47: a patient whose servo-driven stride the scenario's own muscles cannot drive
/// within their rating ran, and only the closed loop's verdict said so. Here the knee's
/// muscles are DMSP-10s on 38 mm pulleys (1.03 times their rating on the stride): refused
/// before anything runs, in one line naming the joint, the figure and `pma-exo size`.
#[test]
fn regression_muscles_over_their_rating_on_the_servo_stride_ran() {
    let dir = temp_dir("fitted-rating");
    let muscles = include_str!("../crates/pma-leg/models/muscles_treadmill.toml");
    let knee_small: String = muscles
        .split("[[muscles]]")
        .enumerate()
        .map(|(i, block)| {
            let block = if block.contains("joint = \"knee\"") {
                block
                    .replace("size = \"dmsp-20\"", "size = \"dmsp-10\"")
                    .replace("pulley_radius_m = 0.055", "pulley_radius_m = 0.038")
            } else {
                block.to_owned()
            };
            if i == 0 {
                block
            } else {
                format!("[[muscles]]{block}")
            }
        })
        .collect();
    assert_eq!(knee_small.matches("dmsp-10").count(), 2);
    let geometry = dir.join("knee_small.toml");
    std::fs::write(&geometry, knee_small).unwrap();
    let line = format!(
        "physics_substeps = 4\nmuscle_geometry = \"{}\"",
        geometry.display()
    );
    let path = scenario_with(&dir, "small.toml", &[("physics_substeps = 4", &line)]);
    let out = pma_exo(&["simulate", path.to_str().unwrap(), "--duration", "4"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("the knee's muscles (Festo DMSP-10, 1.200 m on 38 mm) would pull 1.0")
            && err.contains("times their rating")
            && err.contains("pma-exo size"),
        "{err}"
    );
    // `size` shows the scenario's own muscles beside its recommendation.
    let v = pma_exo(&[
        "size",
        path.to_str().unwrap(),
        "--closed-loop-s",
        "0",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&v.stdout).expect("JSON");
    let knee = &v["fitted"][1];
    assert_eq!(knee["joint"], "knee");
    assert!(
        knee["peak_force_over_rated"].as_f64().unwrap() > 1.0,
        "{knee}"
    );
    // The shipped muscles drive the shipped patient's stride at 0.59 of their rating (the
    // figure `size` designed them for, at the 6 bar they were sized with).
    let v = json_of(&["size", "gait_treadmill", "--closed-loop-s", "0", "--json"]);
    for pair in v["fitted"].as_array().unwrap() {
        let f = pair["peak_force_over_rated"].as_f64().unwrap();
        assert!((0.55..0.65).contains(&f), "{pair}");
    }
}

/// The APRC-NDO gains tuned over the trainer's patients (issue 47 item 3).
const PATIENTS_GAINS: &str = "crates/pma-leg/models/gains/treadmill-patients/aprc-ndo.toml";

/// `pma-exo envelope` with `args` then `extra`, its JSON (whatever the exit: a map with a
/// cell that did not walk exits 4).
fn envelope_json(args: &[&str], extra: &[&str]) -> serde_json::Value {
    let all: Vec<&str> = ["envelope", "--json"]
        .iter()
        .chain(args)
        .chain(extra)
        .copied()
        .collect();
    let out = pma_exo(&all);
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// The scenario's own APRC-NDO set (`[control.gains]`), which runs from 50 % support.
const OWN_GAINS: &str = "crates/pma-leg/models/gains/treadmill/aprc-ndo.toml";

/// Issue 47 item 3: the scenario's own set, tuned on the 75 kg patient, let a 90 kg patient
/// at 30 % support collapse within 4 s; the shipped schedule gives them the set tuned over
/// the patients (docs/envelope.md, "Gains that follow the patient"), which walks them
/// within 2 deg and the muscles' rating, exactly as the gain file does.
///
/// One patient's 10 s run is not the claim: in f64 the own set's 90.0 kg run fails by the
/// knee (2.003 deg) without collapsing, and over eleven patients of 89.5-90.5 kg it walks
/// two, collapses under seven, the schedule walking all eleven (docs/convergence.md, "The
/// switch carried on"). The test runs the three nearest, 89.9, 90 and 90.1 kg: the schedule
/// walks each, the own set none, and most of them collapse under it.
#[test]
fn the_schedule_walks_a_90_kg_patient_the_scenarios_own_set_loses() {
    let cells = |masses: &str, gains: &[&str]| -> Vec<serde_json::Value> {
        let args = [
            "--mass-kg",
            masses,
            "--support",
            "0.3",
            "--speed",
            "0.5",
            "--duration",
            "10",
        ];
        envelope_json(&args, gains)["cells"]
            .as_array()
            .expect("cells")
            .clone()
    };
    let masses = "89.9,90,90.1";
    let own = cells(masses, &["--gains", OWN_GAINS]);
    assert_eq!(own.len(), 3);
    assert!(own.iter().all(|c| c["outcome"] == "failed"), "{own:?}");
    let collapses = own.iter().filter(|c| c["collapse_s"].is_f64()).count();
    assert!(collapses >= 2, "{own:?}");
    let shipped = cells(masses, &[]);
    assert_eq!(shipped.len(), 3);
    for c in &shipped {
        assert_eq!(c["outcome"], "walked", "{c}");
        assert_eq!(c["gains_scheduled"], true, "{c}");
        let [hip, knee] = [0, 1].map(|j| c["stance_rms_deg"][j].as_f64().unwrap());
        assert!(hip <= 2.0 && knee <= 2.0, "{c}");
        assert!(c["peak_force_over_rated"].as_f64().unwrap() <= 1.0, "{c}");
    }
    let at_90 = shipped
        .iter()
        .find(|c| c["mass_kg"] == 90.0)
        .expect("the 90 kg cell");
    let file = cells("90", &["--gains", PATIENTS_GAINS]);
    assert_eq!(
        file[0]["stance_rms_deg"], at_90["stance_rms_deg"],
        "{}",
        file[0]
    );
}

/// Issue 47 item 3, a schedule by support on the command line: with `--gains FILE
/// --gains-below-support 0.28` a cell at 25 % runs exactly as with the file at every support,
/// and one at 30 % exactly as with the scenario's gains (there its own schedule's); each
/// cell and the provenance say which.
#[test]
fn a_schedule_by_support_runs_the_gain_file_below_it_and_the_scenarios_gains_from_it() {
    let cells = |gains: &[&str]| -> (Vec<serde_json::Value>, serde_json::Value) {
        let args = [
            "--mass-kg",
            "75",
            "--support",
            "0.25,0.3",
            "--speed",
            "0.5",
            "--duration",
            "4",
        ];
        let v = envelope_json(&args, gains);
        (
            v["cells"].as_array().unwrap().clone(),
            v["provenance"]["gains"].clone(),
        )
    };
    let (scenarios, _) = cells(&[]);
    let (file, _) = cells(&["--gains", OWN_GAINS]);
    let (scheduled, said) = cells(&["--gains", OWN_GAINS, "--gains-below-support", "0.28"]);
    let rms = |c: &serde_json::Value| c["stance_rms_deg"].clone();
    assert_eq!(rms(&scheduled[0]), rms(&file[0]), "25 %: {}", scheduled[0]);
    assert_eq!(
        rms(&scheduled[1]),
        rms(&scenarios[1]),
        "30 %: {}",
        scheduled[1]
    );
    // The two sets differ where it matters for the comparison to mean anything.
    for i in 0..2 {
        assert_ne!(rms(&file[i]), rms(&scenarios[i]), "{}", file[i]);
    }
    // Each cell says which set it ran.
    assert_eq!(scheduled[0]["gains_file"], true);
    assert!(scheduled[0].get("gains_scheduled").is_none());
    assert_eq!(scheduled[1]["gains_file"], false);
    assert_eq!(scheduled[1]["gains_scheduled"], true);
    assert!(scenarios[0].get("gains_file").is_none());
    assert_eq!(scenarios[0]["gains_scheduled"], true);
    assert!(
        said.as_str().unwrap().contains("below 0.28 support"),
        "{said}"
    );
}

/// Issue 47 item 5: `pma-exo envelope` maps a treadmill scenario's patients: each cell
/// walked, refused before it ran (with why), or ran and failed (with why); its bad
/// arguments are one-line errors naming the flag and its range.
#[test]
fn envelope_maps_walked_refused_and_failed_cells() {
    for (args, needle) in [
        (
            &["--mass-kg", "300"][..],
            "--mass-kg 300 is invalid: a patient's mass, 15 to 200",
        ),
        (&["--support", "1.2"][..], "--support 1.2 is invalid"),
        (&["--speed", "5"][..], "--speed 5 is invalid"),
        (&["--speed", "0.5,0.5"][..], "--speed: 0.5 is given twice"),
        (&["gait_training"][..], "has no [treadmill]"),
        (&["--duration", "-1"][..], "duration"),
        (&["--threads", "0"][..], "--threads must be at least 1"),
        (
            &["--physics-substeps", "0"][..],
            "--physics-substeps 0 is invalid: 1 to 256",
        ),
        (
            &["--controller", "pid", "--modes", "impedance"][..],
            "--controller pid: impedance mode runs no muscle controller",
        ),
        (
            &["--out", "Cargo.toml"][..],
            "exists and is not a directory",
        ),
        (
            &["--gains", PATIENTS_GAINS, "--modes", "impedance"][..],
            "impedance mode runs no muscle controller",
        ),
        (
            &["--gains", PATIENTS_GAINS, "--gains-below-support", "1.5"][..],
            "--gains-below-support 1.5 is invalid: a fraction of the body weight, 0 to 1",
        ),
        // A controller named beside a gain file of another used to run the file's.
        (
            &[
                "--gains",
                "crates/pma-leg/models/gains/treadmill/pid.toml",
                "--controller",
                "sta",
            ][..],
            "gain file is for `pid` but the controller requested is `sta`",
        ),
    ] {
        let mut all = vec!["envelope"];
        all.extend_from_slice(args);
        let out = pma_exo(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let dir = temp_dir("envelope");
    let out = pma_exo(&[
        "envelope",
        "--mass-kg",
        "80",
        "--support",
        "0,0.5",
        "--speed",
        "0.5,0.7",
        "--duration",
        "8",
        "--json",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let cells = v["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4);
    let cell = |support: f64, speed: f64| {
        cells
            .iter()
            .find(|c| c["support"] == support && c["speed_m_s"] == speed)
            .unwrap()
    };
    // No adult reference at 0.7 m/s: refused, whatever the support.
    for support in [0.0, 0.5] {
        let c = cell(support, 0.7);
        assert_eq!(c["outcome"], "refused", "{c}");
        assert_eq!(c["refusal"], "no_reference", "{c}");
    }
    // Without support or a foot lifter the servo-driven stride asks over 5 times the
    // adults' moments (the swing toe digs into the belt): refused, with the figure.
    let c = cell(0.0, 0.5);
    assert_eq!(c["refusal"], "beyond_norms", "{c}");
    assert!(
        c["reasons"][0]
            .as_str()
            .unwrap()
            .contains("times the adults'"),
        "{c}"
    );
    // At half the weight carried it runs, and its figures are the verdict's.
    let ran = cell(0.5, 0.5);
    assert!(
        matches!(ran["outcome"].as_str(), Some("walked" | "failed")),
        "{ran}"
    );
    let [hip, knee] = [0, 1].map(|j| ran["stance_rms_deg"][j].as_f64().unwrap());
    assert!(hip.is_finite() && knee.is_finite(), "{ran}");
    // The verdict's criteria, one way: a walked cell tracked within 2 deg and stayed within
    // the rating; a failed one says why (it may have tracked well and pulled too hard, or
    // missed a stride or the belt's load).
    let peak = ran["peak_force_over_rated"].as_f64().unwrap();
    let reasons = ran["reasons"].as_array().unwrap();
    if ran["outcome"] == "walked" {
        assert!(hip <= 2.0 && knee <= 2.0 && peak <= 1.0, "{ran}");
        assert!(reasons.is_empty(), "{ran}");
    } else {
        assert!(!reasons.is_empty(), "{ran}");
    }
    // The exit says whether a cell ran and did not walk.
    let failed = cells
        .iter()
        .any(|c| c["outcome"] == "failed" || c["outcome"] == "simulation_failed");
    assert_eq!(out.status.code(), Some(if failed { 4 } else { 0 }));
    for f in ["envelope.json", "envelope.md", "envelope.png"] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    // A 50 kg patient's cell left physical bounds within 16 ms at every step up to two
    // substeps, from a foot whose moment of inertia went negative and a servo pass damped
    // for a 75 kg leg (issue 47, docs/envelope.md). It runs at the shipped step now and at
    // four substeps, and gets its verdict.
    let light = |extra: &[&str]| -> serde_json::Value {
        let args = [
            "--mass-kg",
            "50",
            "--support",
            "0.5",
            "--speed",
            "0.5",
            "--duration",
            "4",
            "--controller",
            "pid",
        ];
        envelope_json(&args, extra)
    };
    for extra in [&[][..], &["--physics-substeps", "4"][..]] {
        let v = light(extra);
        let c = &v["cells"][0];
        assert!(
            matches!(c["outcome"].as_str(), Some("walked" | "failed")),
            "{extra:?}: {c}"
        );
        assert_eq!(v["provenance"]["controller"], "pid");
    }
}

/// Issue 47 item 1: a patient's height. The frame's thigh and shank and the patient's
/// segments take their lengths from it; at the scenario's cadence a 1.50 m and a 1.92 m
/// patient (75 kg) walk 8 s on the belt scaled with their legs (0.4873 m/s x H / 1.75).
/// A height outside the adult reference's subjects (1.47-1.92 m) is refused in one line;
/// a belt far from the one the patient's legs fit names the scaled reference speed.
#[test]
fn a_short_and_a_tall_patient_walk_on_their_own_legs() {
    let dir = temp_dir("height");
    for h in [1.50, 1.92] {
        let belt = format!("speed_m_per_s = {:.4}", 0.4873 * h / 1.75);
        let path = scenario_with(
            &dir,
            &format!("h{h}.toml"),
            &[
                (
                    "body_mass_kg = 75.0",
                    &format!("body_mass_kg = 75.0\nheight_m = {h}"),
                ),
                ("speed_m_per_s = 0.4873", &belt),
            ],
        );
        let v = judged(&[
            "simulate",
            path.to_str().unwrap(),
            "--duration",
            "8",
            "--json",
        ]);
        assert!(walked(&v), "{h} m: {}", v["walking"]);
        assert_eq!(v["treadmill"]["height_m"].as_f64(), Some(h));
    }
    let short = scenario_with(
        &dir,
        "short.toml",
        &[("body_mass_kg = 75.0", "body_mass_kg = 75.0\nheight_m = 1.2")],
    );
    assert_refused(&short, "treadmill.height_m");
    let off = scenario_with(
        &dir,
        "off.toml",
        &[
            (
                "body_mass_kg = 75.0",
                "body_mass_kg = 75.0\nheight_m = 1.47",
            ),
            ("speed_m_per_s = 0.4873", "speed_m_per_s = 0.56"),
        ],
    );
    assert_refused(&off, "0.419 m/s for a patient 1.47 m tall");
}
