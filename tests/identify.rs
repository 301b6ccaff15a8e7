//! `rig excite` then `identify` on the virtual rig: the plant behind the log comes back
//! (the `realistic` preset: Table I with f0 x 0.9, k0 and b0 x 1.2, 2.5 kg, a 20 ms valve,
//! 3 um of sensor noise on 16-bit converters), and a log that cannot identify anything is
//! a one-line error. The figures over five plants are in docs/commissioning.md.
use pma_rig::config::EMBEDDED_VIRTUAL;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn pma_exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run pma-exo")
}

/// `pma_exo` that must succeed (its stderr in the failure).
fn pma_exo_ok(args: &[&str]) -> std::process::Output {
    let out = pma_exo(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("pma-exo-identify-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temp dir");
        d
    })
}

/// The virtual rig with the `realistic` plant (and the valve's pressure channel on AI 1,
/// +-10 V, when `pressure`).
fn realistic_config(pressure: bool) -> PathBuf {
    let name = if pressure {
        "realistic-rig-pressure.toml"
    } else {
        "realistic-rig.toml"
    };
    let config = dir().join(name);
    let mut text = EMBEDDED_VIRTUAL.replace("plant = \"mismatch\"", "plant = \"realistic\"");
    assert_ne!(text, EMBEDDED_VIRTUAL);
    if pressure {
        text = text.replace(
            "charge_pump = { subdevice = 2, channel = 0 }",
            "charge_pump = { subdevice = 2, channel = 0 }\npressure = { subdevice = 0, channel = 1, range = 0, aref = \"ground\" }",
        );
    }
    std::fs::write(&config, text).expect("config");
    config
}

/// A 40 s excitation of `config` into `name` (`extra` arguments appended).
fn excite(config: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let log = dir().join(name);
    let mut args = vec![
        "rig".to_owned(),
        "excite".into(),
        "--config".into(),
        config.display().to_string(),
        "--duration".into(),
        "40".into(),
        "--out".into(),
        log.display().to_string(),
    ];
    args.extend(extra.iter().map(|a| (*a).to_owned()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    pma_exo_ok(&args);
    log
}

/// A 40 s excitation of the virtual rig with the `realistic` plant, made once.
fn excite_log() -> &'static Path {
    static LOG: OnceLock<PathBuf> = OnceLock::new();
    LOG.get_or_init(|| excite(&realistic_config(false), "excite.csv", &[]))
}

/// `identify --json` on `logs` with `extra` arguments; the parsed object.
fn identify_json(logs: &[&Path], extra: &[&str], out: &str) -> serde_json::Value {
    let mut args: Vec<String> = vec!["identify".into()];
    args.extend(logs.iter().map(|l| s(l)));
    args.extend(extra.iter().map(|a| (*a).to_owned()));
    args.extend([
        "--out".into(),
        dir().join(out).display().to_string(),
        "--json".into(),
    ]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let run = pma_exo_ok(&args);
    serde_json::from_slice(&run.stdout).expect("json")
}

/// With the valve's pressure channel, the valve is fitted on the measured pressure alone
/// (the realistic rig's valve: 20 ms, no dead time) and the muscle behind it.
#[test]
fn the_pressure_channel_gives_the_valve_on_its_own() {
    let log = excite(&realistic_config(true), "excite-pressure.csv", &[]);
    let v = identify_json(&[&log], &["--load-kg", "2.5"], "identified-pressure.toml");
    assert_eq!(v["valve_source"], "pressure channel");
    let lag = v["valve_lag_s"].as_f64().expect("lag");
    assert!((lag - 0.020).abs() <= 0.02 * 0.020, "valve lag {lag} s");
    assert!(v["valve_rms_error_pa"].as_f64().expect("rms") < 1e3, "{v}");
    assert!(v["fit_percent"].as_f64().expect("fit") >= 90.0, "{v}");
    // The pressure column is logged, and a run without the channel logs it empty.
    let text = std::fs::read_to_string(excite_log()).expect("log");
    let columns = text.lines().find(|l| !l.starts_with('#')).expect("columns");
    assert!(columns.contains(",pressure_v,pressure_pa,"), "{columns}");
}

/// Without a weighed load, a second excitation with 1 kg added fixes the force scale and
/// the load (the truth: 2.5 kg); one log alone is refused, naming the ways out.
#[test]
fn an_unweighed_load_comes_from_a_second_excitation_with_a_known_added_mass() {
    let added = excite(
        &realistic_config(false),
        "excite-added.csv",
        &["--added-mass-kg", "1.0"],
    );
    let v = identify_json(&[excite_log(), &added], &[], "identified-added.toml");
    assert_eq!(v["load_source"], "added-mass");
    let load = v["load_mass_kg"].as_f64().expect("load");
    assert!(
        (load - 2.5).abs() <= 0.10 * 2.5,
        "load {load} kg against 2.5"
    );
    assert!(v["fit_percent"].as_f64().expect("fit") >= 90.0, "{v}");
    one_line_error(
        &[
            "identify",
            &s(excite_log()),
            "--out",
            &s(&dir().join("never-load.toml")),
        ],
        "the load is not known",
    );
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn identification_gives_the_realistic_rig_back() {
    let plant = dir().join("identified.toml");
    let out = pma_exo_ok(&[
        "identify",
        &s(excite_log()),
        "--load-kg",
        "2.5",
        "--out",
        &s(&plant),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let lag = v["valve_lag_s"].as_f64().expect("lag");
    assert!(
        (lag - 0.020).abs() <= 0.15 * 0.020,
        "valve lag {lag} s against 20 ms"
    );
    let fit = v["fit_percent"].as_f64().expect("fit");
    assert!(fit >= 90.0, "held-out fit {fit} %");
    let param = |name: &str| {
        v["parameters"]
            .as_array()
            .expect("parameters")
            .iter()
            .find(|p| p[0] == name)
            .map(|p| p[1]["value"].as_f64().expect("value"))
            .expect("parameter")
    };
    for (name, truth) in [
        ("f0_scale", 0.9),
        ("k0_scale", 1.2),
        ("b0_inflation_scale", 1.2),
    ] {
        let got = param(name);
        assert!(
            (got - truth).abs() <= 0.05 * truth,
            "{name} {got} against {truth}"
        );
    }
    for key in [
        "valve_time_constant_s",
        "valve_dead_time_s",
        "load_mass_kg",
        "noise_rms_m",
        "rms_error_m",
    ] {
        assert!(v[key].is_number(), "{key}");
    }
    // The plant file is one every command takes, and it tells the controllers the lag.
    let text = std::fs::read_to_string(&plant).expect("plant");
    let cfg = pma_bench::PlantConfig::from_toml_str(&text, "identified").expect("plant file");
    assert!((cfg.nominal.valve_time_constant_s - lag).abs() < 1e-12);
    assert_eq!(cfg.nominal.mass_kg, 2.5);
    pma_exo_ok(&["single", "--plant", &s(&plant), "--duration", "2"]);
}

fn one_line_error(args: &[&str], needle: &str) {
    let out = pma_exo(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
}

/// The excitation log with `edit` applied to its rows (header and comments kept).
fn edited(name: &str, edit: impl Fn(usize, &str) -> Option<String>) -> PathBuf {
    let text = std::fs::read_to_string(excite_log()).expect("log");
    let mut out = String::new();
    let mut row = 0usize;
    let mut columns_seen = false;
    for line in text.lines() {
        if line.starts_with('#') || !columns_seen {
            columns_seen |= !line.starts_with('#');
            out.push_str(line);
        } else {
            row += 1;
            match edit(row, line) {
                Some(l) => out.push_str(&l),
                None => continue,
            }
        }
        out.push('\n');
    }
    let p = dir().join(name);
    std::fs::write(&p, out).expect("write");
    p
}

#[test]
fn a_log_that_cannot_identify_anything_is_a_one_line_error() {
    let out = dir().join("never.toml");
    let o = s(&out);
    let run = |log: &Path, needle: &str| {
        one_line_error(
            &["identify", &s(log), "--load-kg", "2.5", "--out", &o],
            needle,
        );
    };
    run(
        &edited("short.csv", |k, l| (k <= 5000).then(|| l.to_owned())),
        "too short",
    );
    run(
        &edited("nan.csv", |k, l| {
            Some(if k == 777 {
                let mut f: Vec<&str> = l.split(',').collect();
                f[6] = "NaN";
                f.join(",")
            } else {
                l.to_owned()
            })
        }),
        "not a finite number",
    );
    run(
        &edited("flat.csv", |_, l| {
            let mut f: Vec<&str> = l.split(',').collect();
            if f[19] != "vent" {
                f[10] = "100000";
            }
            Some(f.join(","))
        }),
        "no excitation",
    );
    let foreign = dir().join("foreign.csv");
    std::fs::write(&foreign, "t_s,position_m\n0,0\n").expect("write");
    run(&foreign, "not a pma-exo rig log");
    one_line_error(
        &["identify", &s(excite_log()), "--load-kg", "-1", "--out", &o],
        "load_kg",
    );
    // A fit below the threshold writes nothing.
    one_line_error(
        &[
            "identify",
            &s(excite_log()),
            "--load-kg",
            "2.5",
            "--out",
            &o,
            "--min-fit",
            "99.99",
        ],
        "nothing written",
    );
    assert!(!out.exists());
    // The log is never the output.
    one_line_error(
        &[
            "identify",
            &s(excite_log()),
            "--load-kg",
            "2.5",
            "--out",
            &s(excite_log()),
        ],
        "refusing to overwrite an input",
    );
}

/// `rig commission` on the virtual rig with the `realistic` plant: every stage runs, the
/// directory holds the logs, the plant, the gains and the report, and the muscle tracks
/// better after than before; an existing directory is refused.
#[test]
fn commissioning_the_realistic_rig_improves_its_tracking() {
    excite_log();
    let config = dir().join("realistic-rig.toml");
    let out = dir().join("commission");
    let args = [
        "rig",
        "commission",
        "--config",
        &s(&config),
        "--out",
        &s(&out),
        "--load-kg",
        "2.5",
        "--excite-duration",
        "40",
        "--robust",
        "2",
        "--population",
        "4",
        "--generations",
        "1",
        "--json",
    ];
    let run = pma_exo_ok(&args);
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).expect("json");
    let before = v["rte_before_percent"].as_f64().expect("before");
    let after = v["rte_after_percent"].as_f64().expect("after");
    assert!(after < 0.5 * before, "RTE {before} % -> {after} %");
    for f in [
        "before.csv",
        "excite.csv",
        "plant.toml",
        "gains.toml",
        "report.md",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    assert!(report.contains("| f0_scale |"), "{report}");
    one_line_error(&args, "exists");
}
