//! The hardware backend on the virtual rig: the shared loop, tracking, every fault path,
//! signals, panics, replay and bad configurations.
use pma_bench::{MuscleBench, PlantConfig};
use pma_control::ControllerKind;
use pma_control::{MuscleStep, MuscleTask};
use pma_loop::{FnRecorder, LoopSettings, Period};
use pma_rig::config::{ClockMode, EMBEDDED_VIRTUAL};
use pma_rig::{
    AnalogChannel, Daq, DaqError, DigitalLine, OutputHandle, Rig, RigBackend, RigConfig, RunOptions,
};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

fn virtual_config() -> RigConfig {
    RigConfig::from_toml_str(EMBEDDED_VIRTUAL, "virtual.toml").expect("embedded config")
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pma-exo-rig-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn run_virtual(cfg: &RigConfig, options: &RunOptions) -> pma_rig::RigReport {
    let stop = AtomicBool::new(false);
    pma_rig::run::run(cfg, Path::new("models/rig"), options, &stop, ()).expect("rig run")
}

/// Rows of a rig log: (period, t_s, valve_cmd_pa, event, fault).
fn log_rows(path: &Path) -> Vec<(u64, f64, f64, String, String)> {
    let mut r = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)
        .expect("log");
    let h = r.headers().expect("header").clone();
    let col = |n: &str| h.iter().position(|c| c == n).expect("column");
    let (p, t, v, e, f) = (
        col("period"),
        col("t_s"),
        col("valve_cmd_pa"),
        col("event"),
        col("fault"),
    );
    r.records()
        .map(|row| {
            let row = row.expect("row");
            (
                row[p].parse().expect("period"),
                row[t].parse().expect("t"),
                row[v].parse().expect("valve"),
                row[e].to_owned(),
                row[f].to_owned(),
            )
        })
        .collect()
}

/// The log has the activation, then every period with none missing, then the vent.
fn assert_complete_log(rows: &[(u64, f64, f64, String, String)], periods: u64, fault: &str) {
    assert_eq!(rows[0].3, "activate");
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.0, k as u64, "row {k} is period {}", row.0);
    }
    let last = rows.last().expect("rows");
    assert_eq!(last.3, "vent", "last row {last:?}");
    assert_eq!(last.2, 0.0, "the last row vents: {last:?}");
    assert_eq!(last.4, fault);
    assert_eq!(
        rows.len() as u64,
        periods + 2,
        "activation + periods + vent"
    );
}

#[test]
fn lockstep_virtual_rig_tracks_the_paper_sine_and_vents() {
    let dir = temp_dir("sine");
    let log = dir.join("log.csv");
    let r = run_virtual(
        &virtual_config(),
        &RunOptions {
            log_path: Some(log.clone()),
            ..RunOptions::default()
        },
    );
    eprintln!("{r:?}");
    assert!(r.completed && r.vented && r.fault.is_none(), "{r:?}");
    assert_eq!(r.periods, 20_000);
    assert!(r.rte_percent < 1.0, "RTE {} %", r.rte_percent);
    assert_complete_log(&log_rows(&log), 20_000, "");
    // Replay: the logged measurements, references and periods through the same controller
    // give every command bit for bit.
    let replay = pma_rig::replay(&log).expect("replay");
    assert_eq!(replay.periods, 20_000);
    assert_eq!(replay.mismatches, 0);
    assert_eq!(replay.max_abs_difference_pa, 0.0);
    std::fs::remove_dir_all(dir).ok();
}

/// Ideal converters: no quantisation, power-of-two scales (exactly invertible), no noise,
/// limits that never bind. Then the virtual rig is the bench behind volts.
fn ideal_converter_config() -> RigConfig {
    let text = EMBEDDED_VIRTUAL
        .replace("range = 9, aref", "range = 0, aref")
        .replace(
            "position_m_per_v = 0.015\n",
            "position_m_per_v = 0.015625\n",
        )
        .replace(
            "position_offset_v = 1.3333333333333333",
            "position_offset_v = 0.0",
        )
        .replace("valve_pa_per_v = 1.0e5", "valve_pa_per_v = 65536.0")
        .replace(
            "pressure_rate_max_pa_per_s = 2.0e8",
            "pressure_rate_max_pa_per_s = 3.0e8",
        )
        .replace("converter_bits = 16", "converter_bits = 0")
        .replace("sensor_noise_rms_m = 3e-6", "sensor_noise_rms_m = 0.0");
    assert_ne!(text, EMBEDDED_VIRTUAL);
    RigConfig::from_toml_str(&text, "ideal-converters.toml").expect("config")
}

#[test]
fn the_virtual_rig_and_the_bench_run_the_same_loop_command_for_command() {
    let cfg = ideal_converter_config();
    let dir = temp_dir("same-loop");
    let stop = AtomicBool::new(false);
    let mut rig_commands = Vec::new();
    let rec = FnRecorder(|p: &Period<'_, Rig, MuscleStep>| {
        rig_commands.push(p.output.control.pressure_cmd_pa)
    });
    let options = RunOptions {
        duration_s: Some(5.0),
        log_path: Some(dir.join("log.csv")),
        ..RunOptions::default()
    };
    let report = pma_rig::run::run(&cfg, Path::new("."), &options, &stop, rec).expect("run");
    assert!(report.completed, "{report:?}");

    let plant = PlantConfig::preset("mismatch").expect("preset");
    let mut bench = MuscleBench::vented(&plant).expect("bench");
    let reference = cfg.reference(bench.position());
    let controller = cfg
        .build_controller(&ControllerKind::AprcNdo.default_config())
        .expect("controller");
    let mut task = MuscleTask::new(controller, &reference);
    let mut bench_commands = Vec::new();
    let mut rec = FnRecorder(|p: &Period<'_, MuscleBench, MuscleStep>| {
        bench_commands.push(p.output.control.pressure_cmd_pa)
    });
    let settings = LoopSettings::new(5.0).expect("settings");
    pma_loop::run(&mut bench, &mut task, &mut rec, &settings).expect("a sound duration");
    assert_eq!(rig_commands.len(), 5000);
    assert_eq!(rig_commands, bench_commands);
    // And the commands did something: the load travelled the sine.
    let max = bench_commands.iter().fold(0.0f64, |m, u| m.max(*u));
    assert!(max > 1.0e5, "largest command {max} Pa");
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: with a 50 bar/s rate limit in the supervisor and the controller unaware of
/// it, APRC-NDO's observer and adaptive gain wound up against the limit until the muscle
/// left its window at 42 s (lockstep virtual rig). The loop now hands every controller
/// the command actually applied.
#[test]
fn a_rate_limit_the_controller_cannot_see_no_longer_destabilises_it() {
    let text = EMBEDDED_VIRTUAL.replace(
        "pressure_rate_max_pa_per_s = 2.0e8",
        "pressure_rate_max_pa_per_s = 5.0e6",
    );
    let cfg = RigConfig::from_toml_str(&text, "rate-limited.toml").expect("config");
    let dir = temp_dir("rate-limit");
    let r = run_virtual(
        &cfg,
        &RunOptions {
            duration_s: Some(60.0),
            log_path: Some(dir.join("log.csv")),
            ..RunOptions::default()
        },
    );
    eprintln!("{r:?}");
    assert!(r.completed && r.fault.is_none(), "{r:?}");
    assert!(r.rte_percent < 2.0, "RTE {} %", r.rte_percent);
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_raised_stop_flag_vents_at_the_next_period_and_the_log_is_complete() {
    let dir = temp_dir("stop");
    let log = dir.join("log.csv");
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let rec = FnRecorder(move |p: &Period<'_, Rig, MuscleStep>| {
        if p.index == 1000 {
            flag.store(true, Ordering::Relaxed);
        }
    });
    let options = RunOptions {
        log_path: Some(log.clone()),
        ..RunOptions::default()
    };
    let r =
        pma_rig::run::run(&virtual_config(), Path::new("."), &options, &stop, rec).expect("run");
    assert_eq!(r.periods, 1000, "{r:?}");
    assert!(r.vented && !r.completed);
    assert_eq!(r.fault.as_deref(), Some("interrupted"));
    assert_eq!(r.exit_code(), 130);
    assert_complete_log(&log_rows(&log), 1000, "interrupted");
    std::fs::remove_dir_all(dir).ok();
}

fn pma_exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run pma-exo")
}

#[test]
fn every_injected_fault_vents_names_itself_and_closes_the_log() {
    let dir = temp_dir("faults");
    for fault in [
        "sensor-nan",
        "sensor-stuck",
        "position-out",
        "daq-error",
        "stall",
        "controller-panic",
    ] {
        let log = dir.join(format!("{fault}.csv"));
        let log_s = log.display().to_string();
        let inject = format!("{fault}@3");
        let out = pma_exo(&[
            "rig",
            "run",
            "--json",
            "--duration",
            "6",
            "--inject",
            &inject,
            "--log",
            &log_s,
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{fault}: {stderr}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        assert_eq!(v["fault"], fault, "{v}");
        assert_eq!(v["vented"], true, "{v}");
        assert_eq!(v["completed"], false, "{v}");
        let periods = v["periods"].as_u64().expect("periods");
        // The fault comes at 3 s (the stuck sensor 500 periods later).
        assert!(
            (2999..=3500).contains(&periods),
            "{fault}: {periods} periods"
        );
        assert_complete_log(&log_rows(&log), periods, fault);
        if fault == "stall" {
            assert_eq!(v["watchdog_vented"], true, "{v}");
        }
    }
    std::fs::remove_dir_all(dir).ok();
}

#[cfg(unix)]
#[test]
fn sigint_to_a_realtime_run_vents_and_exits_cleanly_with_a_complete_log() {
    let dir = temp_dir("sigint");
    let log = dir.join("log.csv");
    let log_s = log.display().to_string();
    // What is tested is the signal, not the machine's timing: on a loaded 2-core CI
    // machine a default run can end in a timing fault (exit 3) before the SIGINT arrives,
    // so the overrun limits are at their loosest here.
    let config = EMBEDDED_VIRTUAL.replace(
        "watchdog_periods = 50",
        "watchdog_periods = 50\noverrun_max_consecutive_periods = 49\noverrun_max_share = 0.5",
    );
    assert_ne!(config, EMBEDDED_VIRTUAL);
    let config_path = dir.join("loose-timing.toml");
    std::fs::write(&config_path, config).expect("config");
    let config_s = config_path.display().to_string();
    let child = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args([
            "rig",
            "run",
            "--config",
            &config_s,
            "--realtime",
            "--json",
            "--duration",
            "60",
            "--log",
            &log_s,
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // SAFETY: sending SIGINT to our own child.
    let rc = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    assert_eq!(rc, 0);
    let out = child.wait_with_output().expect("wait");
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["fault"], "interrupted");
    assert_eq!(v["vented"], true);
    assert_eq!(v["clock"], "realtime");
    let periods = v["periods"].as_u64().expect("periods");
    assert!(periods > 500, "{periods} periods in 1.5 s");
    assert_complete_log(&log_rows(&log), periods, "interrupted");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn bad_configurations_are_one_line_errors_naming_the_field() {
    let dir = temp_dir("bad");
    let cases: [(&str, String, &str); 6] = [
        (
            "unknown field",
            EMBEDDED_VIRTUAL.replace("period_s = 0.001", "period_s = 0.001\nperiod_ms = 1"),
            "period_ms",
        ),
        (
            "missing channel",
            EMBEDDED_VIRTUAL.replace(
                "valve = { subdevice = 1, channel = 0, range = 1, aref = \"ground\" }\n",
                "",
            ),
            "valve",
        ),
        (
            "zero gain",
            EMBEDDED_VIRTUAL.replace("position_m_per_v = 0.015\n", "position_m_per_v = 0.0\n"),
            "calibration.position_m_per_v",
        ),
        (
            "limits inverted",
            EMBEDDED_VIRTUAL.replace("position_max_m = 0.045", "position_max_m = -0.030"),
            "limits.position_max_m",
        ),
        (
            "NaN",
            EMBEDDED_VIRTUAL.replace("pressure_max_pa = 6.0e5", "pressure_max_pa = nan"),
            "limits.pressure_max_pa",
        ),
        (
            "unknown controller",
            EMBEDDED_VIRTUAL.replace("controller = \"aprc-ndo\"", "controller = \"lqr\""),
            "control.controller",
        ),
    ];
    for (what, text, needle) in cases {
        assert_ne!(text, EMBEDDED_VIRTUAL, "{what}: the edit did not apply");
        let path = dir.join(format!("{}.toml", what.replace(' ', "_")));
        std::fs::write(&path, text).expect("write");
        let p = path.display().to_string();
        for args in [
            vec!["rig", "check", "--config", &p],
            vec!["rig", "run", "--config", &p],
        ] {
            let out = pma_exo(&args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{what}: {err}");
            assert_eq!(err.trim_end().lines().count(), 1, "{what}: {err}");
            assert!(err.contains(needle) && err.contains(&p), "{what}: {err}");
        }
    }
    std::fs::remove_dir_all(dir).ok();
}

/// A board that records every write.
#[derive(Default, Clone)]
struct Recording(Arc<Mutex<Vec<String>>>);

impl Daq for Recording {
    fn device(&self) -> &str {
        "recording"
    }
    fn check(
        &mut self,
        _: &[AnalogChannel],
        _: &[AnalogChannel],
        _: &[DigitalLine],
    ) -> Result<(), DaqError> {
        Ok(())
    }
    fn range_v(&mut self, _: &AnalogChannel, _: bool) -> Result<(f64, f64), DaqError> {
        Ok((0.0, 10.0))
    }
    fn read_analog(&mut self, _: &AnalogChannel) -> Result<f64, DaqError> {
        Ok(1.0)
    }
    fn write_analog(&mut self, c: &AnalogChannel, v: f64) -> Result<(), DaqError> {
        self.0
            .lock()
            .unwrap()
            .push(format!("ao {}/{} {v}", c.subdevice, c.channel));
        Ok(())
    }
    fn write_digital(&mut self, l: &DigitalLine, h: bool) -> Result<(), DaqError> {
        self.0
            .lock()
            .unwrap()
            .push(format!("dio {}/{} {h}", l.subdevice, l.channel));
        Ok(())
    }
    fn output_handle(&self, _: &AnalogChannel) -> Result<Box<dyn OutputHandle>, DaqError> {
        Err(DaqError::Unsupported("recording board".into()))
    }
}

/// `cfg` configured on a board that records its writes: the error, nothing written.
fn refused_before_any_write(cfg: &RigConfig) -> String {
    let daq = Recording::default();
    let writes = Arc::clone(&daq.0);
    let e = RigBackend::configure(
        cfg,
        Box::new(daq),
        pma_rig::Pacing::Realtime(std::time::Duration::from_millis(1)),
    )
    .err()
    .expect("refused");
    assert!(
        writes.lock().unwrap().is_empty(),
        "{:?}",
        writes.lock().unwrap()
    );
    e.to_string()
}

#[test]
fn nothing_reaches_the_board_before_the_configuration_is_sound() {
    let mut bad = virtual_config();
    bad.calibration.valve_pa_per_v = 0.0;
    refused_before_any_write(&bad);
    // A vent value outside the output's range is caught before the first write, too.
    let mut outside = virtual_config();
    outside.calibration.valve_offset_v = -1.0;
    let e = refused_before_any_write(&outside);
    assert!(e.contains("valve_offset_v"), "{e}");
    // A sound configuration vents first and resets the charge pump.
    let daq = Recording::default();
    let writes = Arc::clone(&daq.0);
    let mut sound = virtual_config();
    sound.virtual_rig.as_mut().expect("virtual").clock = ClockMode::Realtime;
    RigBackend::configure(
        &sound,
        Box::new(daq),
        pma_rig::Pacing::Realtime(std::time::Duration::from_millis(1)),
    )
    .expect("configure");
    assert_eq!(*writes.lock().unwrap(), ["ao 1/0 0", "dio 2/0 false"]);
}

#[test]
fn without_the_board_check_names_the_device_and_what_to_do() {
    let out = pma_exo(&["rig", "check", "--config", "pci6052e"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("/dev/comedi0") || err.contains("comedi"),
        "{err}"
    );
    assert!(
        err.contains("--features comedi") || err.contains("driver") || err.contains("permission"),
        "{err}"
    );
}

/// Writes `text` as a rig configuration in `dir` and returns its path.
fn config_file(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).expect("write");
    path.display().to_string()
}

fn assert_refused(args: &[&str], needle: &str) {
    let out = pma_exo(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

/// Regression: 10 bar on a 6-bar muscle, a window to 120 mm, the charge pump on the
/// valve's channel, the valve on an input subdevice, channel 99999, subdevice 77, range
/// 250, a negative valve scale and a 10 us period all passed `rig check`.
#[test]
fn implausible_rig_configurations_are_refused_by_rig_check() {
    let dir = temp_dir("implausible");
    let valve = "valve = { subdevice = 1, channel = 0, range = 1, aref = \"ground\" }";
    let cases: [(&str, String, &str); 10] = [
        (
            "ten bar",
            EMBEDDED_VIRTUAL.replace("pressure_max_pa = 6.0e5 ", "pressure_max_pa = 1.0e6 "),
            "limits.pressure_max_pa",
        ),
        (
            "window to 120 mm",
            EMBEDDED_VIRTUAL.replace("position_max_m = 0.045", "position_max_m = 0.120"),
            "limits.position_max_m",
        ),
        (
            "pump on the valve",
            EMBEDDED_VIRTUAL.replace(
                "charge_pump = { subdevice = 2, channel = 0 }",
                "charge_pump = { subdevice = 1, channel = 0 }",
            ),
            "signals.charge_pump",
        ),
        (
            "valve on an input",
            EMBEDDED_VIRTUAL.replace(
                valve,
                &valve.replace("subdevice = 1, channel = 0", "subdevice = 0, channel = 1"),
            ),
            "analog input",
        ),
        (
            "channel 99999",
            EMBEDDED_VIRTUAL.replace(valve, &valve.replace("channel = 0", "channel = 99999")),
            "no channel 99999",
        ),
        (
            "subdevice 77",
            EMBEDDED_VIRTUAL.replace(valve, &valve.replace("subdevice = 1", "subdevice = 77")),
            "no subdevice 77",
        ),
        (
            "range 250",
            EMBEDDED_VIRTUAL.replace(valve, &valve.replace("range = 1", "range = 250")),
            "no range 250",
        ),
        (
            "negative valve scale",
            EMBEDDED_VIRTUAL.replace("valve_pa_per_v = 1.0e5", "valve_pa_per_v = -1.0e5"),
            "calibration.valve_pa_per_v",
        ),
        (
            "period 10 us",
            EMBEDDED_VIRTUAL.replace("period_s = 0.001", "period_s = 0.00001"),
            "period_s",
        ),
        (
            "watchdog of 4294967295 periods",
            EMBEDDED_VIRTUAL.replace("watchdog_periods = 50", "watchdog_periods = 4294967295"),
            "limits.watchdog_periods",
        ),
    ];
    for (what, text, needle) in cases {
        assert_ne!(text, EMBEDDED_VIRTUAL, "{what}: the edit did not apply");
        let p = config_file(&dir, &what.replace(' ', "_"), &text);
        assert_refused(&["rig", "check", "--config", &p], needle);
    }
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: the sensor's documented span, -20..130 mm, was refused because the
/// calibration put -20 mm at -0.0000000000000002 V.
#[test]
fn the_sensors_documented_span_passes_despite_rounding() {
    let dir = temp_dir("span");
    let text = EMBEDDED_VIRTUAL
        .replace("position_min_m = -0.018", "position_min_m = -0.020")
        .replace(
            "[limits]",
            "[muscle]\npressure_max_pa = 6.0e5\nnominal_length_m = 0.6\n\n[limits]",
        )
        .replace("position_max_m = 0.045", "position_max_m = 0.130");
    let p = config_file(&dir, "span", &text);
    let out = pma_exo(&["rig", "check", "--config", &p]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: limits that switch the rig's safety off were accepted.
/// `sensor_stuck_periods = 0` (or 4294967295) silently disabled the frozen-sensor check
/// (`--inject sensor-stuck@0.5` ran to the end, exit 0, the controller blind for 2.5 s);
/// `pressure_rate_max_pa_per_s = 1e308` left the valve unlimited; a ramp, a sweep or a run
/// of 1e308 s ran until killed. Each is refused in one line naming the field, before the
/// valve is live.
#[test]
fn limits_that_switch_safety_off_are_refused() {
    let dir = temp_dir("safety-off");
    let stuck = "sensor_stuck_periods = 500";
    let rate = "pressure_rate_max_pa_per_s = 2.0e8";
    let cases: [(&str, String, &str); 8] = [
        (
            "stuck 0",
            EMBEDDED_VIRTUAL.replace(stuck, "sensor_stuck_periods = 0"),
            "limits.sensor_stuck_periods",
        ),
        (
            "stuck 1",
            EMBEDDED_VIRTUAL.replace(stuck, "sensor_stuck_periods = 1"),
            "limits.sensor_stuck_periods",
        ),
        (
            "stuck u32 max",
            EMBEDDED_VIRTUAL.replace(stuck, "sensor_stuck_periods = 4294967295"),
            "limits.sensor_stuck_periods",
        ),
        (
            "rate 1e308",
            EMBEDDED_VIRTUAL.replace(rate, "pressure_rate_max_pa_per_s = 1e308"),
            "limits.pressure_rate_max_pa_per_s: 1e308",
        ),
        (
            "rate a full flip per period",
            EMBEDDED_VIRTUAL.replace(rate, "pressure_rate_max_pa_per_s = 6.0e8"),
            "limits.pressure_rate_max_pa_per_s",
        ),
        (
            "ramp 1e308",
            EMBEDDED_VIRTUAL.replace("ramp_s = 2.0", "ramp_s = 1e308"),
            "reference.ramp_s",
        ),
        (
            "ramp of an hour",
            EMBEDDED_VIRTUAL.replace("ramp_s = 2.0", "ramp_s = 3600.0"),
            "reference.ramp_s",
        ),
        (
            "a run of 1e308 s",
            EMBEDDED_VIRTUAL.replace("duration_s = 20.0", "duration_s = 1e308"),
            "duration_s = 1e308",
        ),
    ];
    for (what, text, needle) in cases {
        assert_ne!(text, EMBEDDED_VIRTUAL, "{what}: the edit did not apply");
        let p = config_file(&dir, &what.replace(' ', "_"), &text);
        assert_refused(&["rig", "check", "--config", &p], needle);
        assert_refused(
            &["rig", "run", "--config", &p, "--inject", "sensor-stuck@0.5"],
            needle,
        );
    }
    // The limits at their edges still run, and the frozen sensor still vents (exit 3).
    let edge = EMBEDDED_VIRTUAL
        .replace(stuck, "sensor_stuck_periods = 2")
        .replace(rate, "pressure_rate_max_pa_per_s = 3.0e8");
    let p = config_file(&dir, "edge", &edge);
    let log = dir.join("edge.csv").display().to_string();
    let out = pma_exo(&[
        "rig",
        "run",
        "--config",
        &p,
        "--duration",
        "2",
        "--inject",
        "sensor-stuck@0.5",
        "--log",
        &log,
    ]);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: `rig run --controller pid --gains` with `bias_pa = 1e300` or
/// `kp_pa_per_m = 1e308` ran, exit 0, and a bias anywhere in -1e9..1e9 gave the result
/// of 0 (the bumpless start put the resting pressure into the integral). Every gain is
/// checked against the pressure limit before the valve is live; a bias with an integral
/// is refused as having no effect.
#[test]
fn gains_beyond_what_the_muscle_can_take_are_refused() {
    let dir = temp_dir("gains-bounds");
    let cases = [
        ("bias_pa = 1e300", "pid gain `bias_pa` = 1e300"),
        ("bias_pa = 50000.0", "has no effect"),
        ("kp_pa_per_m = 1e308", "pid gain `kp_pa_per_m` = 1e308"),
        ("kd_pa_s_per_m = 1e12", "pid gain `kd_pa_s_per_m`"),
        (
            "ki_pa_per_m_s = 0.0\nbias_pa = 7.0e5",
            "within the command's range",
        ),
    ];
    for (i, (line, needle)) in cases.iter().enumerate() {
        let path = dir.join(format!("g{i}.toml"));
        std::fs::write(&path, format!("controller = \"pid\"\n{line}\n")).expect("write");
        let p = path.display().to_string();
        assert_refused(
            &["rig", "run", "--controller", "pid", "--gains", &p],
            needle,
        );
    }
    // A PD with a bias inside the range runs.
    let pd = dir.join("pd.toml");
    std::fs::write(
        &pd,
        "controller = \"pid\"\nki_pa_per_m_s = 0.0\nbias_pa = 80000.0\n",
    )
    .expect("write");
    let log = dir.join("pd.csv").display().to_string();
    let out = pma_exo(&[
        "rig",
        "run",
        "--controller",
        "pid",
        "--gains",
        &pd.display().to_string(),
        "--duration",
        "3",
        "--log",
        &log,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: `--inject stall@0` and `--inject sensor-nan@25 --duration 20` ended
/// "completed", exit 0: a fault that cannot fire tests nothing.
#[test]
fn an_injection_that_cannot_fire_is_refused() {
    assert_refused(&["rig", "run", "--inject", "stall@0"], "cannot fire");
    assert_refused(
        &[
            "rig",
            "run",
            "--duration",
            "20",
            "--inject",
            "sensor-nan@25",
        ],
        "cannot fire",
    );
}

/// Regression: `--log /dev/null` ran the whole experiment and failed at the end; a log
/// over an existing file destroyed it.
#[test]
fn a_log_that_cannot_keep_the_run_is_refused_before_the_muscle_moves() {
    assert_refused(&["rig", "run", "--log", "/dev/null"], "not a regular file");
    let dir = temp_dir("existing-log");
    let old = dir.join("old.csv");
    std::fs::write(&old, "an earlier run").expect("write");
    assert_refused(
        &["rig", "run", "--log", old.to_str().expect("utf-8")],
        "never overwritten",
    );
    assert_eq!(
        std::fs::read_to_string(&old).expect("read"),
        "an earlier run"
    );
    std::fs::remove_dir_all(dir).ok();
}

/// Regression: a log with its last 5,000 rows removed, or with an edited time, period,
/// voltage, fault or header limit, replayed as "0 differ". A log now ends with a digest
/// and replay recomputes every column it can.
#[test]
fn replay_refuses_a_truncated_or_edited_log() {
    let dir = temp_dir("replay-edits");
    let log = dir.join("log.csv");
    let r = run_virtual(
        &virtual_config(),
        &RunOptions {
            duration_s: Some(8.0),
            log_path: Some(log.clone()),
            ..RunOptions::default()
        },
    );
    assert!(r.completed, "{r:?}");
    let text = std::fs::read_to_string(&log).expect("log");
    assert_eq!(pma_rig::replay(&log).expect("intact").mismatches, 0);
    let lines: Vec<&str> = text.lines().collect();
    let header_end = lines
        .iter()
        .position(|l| !l.starts_with('#'))
        .expect("columns");
    let row = header_end + 3000;
    // Columns: t_s,period,dt_s,...,position_m(6),position_v(7),...,valve_v(11),...,fault(20)
    let edit_field = |line: &str, field: usize, value: &str| -> String {
        let mut f: Vec<String> = line.split(',').map(str::to_owned).collect();
        f[field] = value.to_owned();
        f.join(",")
    };
    let with_line = |i: usize, new: String| -> String {
        let mut l: Vec<String> = lines.iter().map(|s| (*s).to_owned()).collect();
        l[i] = new;
        l.join("\n") + "\n"
    };
    let t_edited = {
        let t: f64 = lines[row].split(',').next().expect("t").parse().expect("t");
        edit_field(lines[row], 0, &format!("{}", t + 0.5))
    };
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "truncated",
            lines[..lines.len() - 5000].join("\n") + "\n",
            "truncated",
        ),
        ("time edited", with_line(row, t_edited), "digest"),
        (
            "volts edited",
            with_line(row, edit_field(lines[row], 7, "5.5")),
            "digest",
        ),
        (
            "fault edited",
            with_line(row, edit_field(lines[row], 20, "stall")),
            "digest",
        ),
        (
            "header limit edited",
            text.replace("position_max_m = 0.045", "position_max_m = 0.04"),
            "digest",
        ),
    ];
    for (what, edited, needle) in cases {
        assert_ne!(edited, text, "{what}: the edit did not apply");
        let p = dir.join(format!("{}.csv", what.replace(' ', "_")));
        std::fs::write(&p, &edited).expect("write");
        let e = pma_rig::replay(&p).expect_err(what).to_string();
        assert!(e.contains(needle), "{what}: {e}");
    }
    // An edit that recomputes the digest is still caught by the columns replay recomputes.
    let forged_row = edit_field(lines[row], 1, "77");
    let mut forged: Vec<String> = lines.iter().map(|s| (*s).to_owned()).collect();
    forged[row] = forged_row;
    let digest_line = forged.pop().expect("digest line");
    let rows = digest_line.rsplit(' ').next().expect("rows").to_owned();
    let body = forged.join("\n") + "\n";
    use sha2::Digest;
    let hex: String = sha2::Sha256::digest(body.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let p = dir.join("forged.csv");
    std::fs::write(&p, format!("{body}# sha256 {hex} rows {rows}\n")).expect("write");
    let e = pma_rig::replay(&p).expect_err("forged").to_string();
    assert!(e.contains("period"), "{e}");
    std::fs::remove_dir_all(dir).ok();
}

/// A column of a log, by name.
fn log_column(path: &Path, name: &str) -> Vec<f64> {
    let mut r = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)
        .expect("log");
    let h = r.headers().expect("header").clone();
    let c = h.iter().position(|n| n == name).expect("column");
    r.records()
        .map(|rec| rec.expect("row")[c].parse::<f64>().expect("number"))
        .collect()
}

/// `rig excite` covers its pressure range, stays inside the position window (backing off
/// before it: the window here is narrower than the muscle's travel at half pressure), is
/// logged and vented like a run, and its log replays command for command.
#[test]
fn an_excitation_spans_its_range_backs_off_before_the_window_and_replays() {
    let dir = temp_dir("excite");
    let narrow = EMBEDDED_VIRTUAL.replace("position_max_m = 0.045", "position_max_m = 0.030");
    assert_ne!(narrow, EMBEDDED_VIRTUAL);
    let config = dir.join("narrow.toml");
    std::fs::write(&config, narrow).expect("config");
    let cfg = RigConfig::from_toml_str(&std::fs::read_to_string(&config).unwrap(), "narrow")
        .expect("config");
    let spec = cfg.default_excitation(40.0);
    let log = dir.join("excite.csv");
    let out = pma_exo(&[
        "rig",
        "excite",
        "--config",
        &config.display().to_string(),
        "--duration",
        "40",
        "--out",
        &log.display().to_string(),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(out.status.code(), Some(0), "{v}");
    assert_eq!(v["controller"], "excite");
    assert_eq!(v["vented"], true);
    let position = log_column(&log, "position_m");
    let command = log_column(&log, "valve_cmd_pa");
    let highest = position.iter().copied().fold(f64::MIN, f64::max);
    assert!(highest < 0.030, "reached {highest} m");
    assert!(
        highest > spec.position_max_m,
        "never needed to back off ({highest} m)"
    );
    let (lo, hi) = command
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &c| (a.min(c), b.max(c)));
    assert!(
        lo <= spec.pressure_min_pa && hi >= 0.9 * spec.pressure_max_pa,
        "{lo}..{hi} Pa"
    );
    let replay = pma_exo(&["rig", "replay", &log.display().to_string(), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&replay.stdout).expect("json");
    assert_eq!(replay.status.code(), Some(0), "{r}");
    assert_eq!(r["mismatches"], 0);
    assert_eq!(r["controller"], "excite");
    std::fs::remove_dir_all(dir).ok();
}

/// The valve's pressure channel: logged every period; a reading above the pressure limit
/// plus 10 % (a valve stuck open, reporting the 8 bar supply) stops the run and vents,
/// naming the reading.
#[test]
fn a_pressure_reading_above_the_limit_stops_the_run_and_vents() {
    let mut cfg = virtual_config();
    cfg.signals.pressure = Some(AnalogChannel {
        subdevice: 0,
        channel: 1,
        range: 0,
        aref: pma_rig::daq::Aref::Ground,
    });
    let dir = temp_dir("pressure");
    let log = dir.join("honest.csv");
    let honest = run_virtual(
        &cfg,
        &RunOptions {
            duration_s: Some(4.0),
            log_path: Some(log.clone()),
            ..RunOptions::default()
        },
    );
    assert!(honest.completed, "{honest:?}");
    let measured = log_column(&log, "pressure_pa");
    let commanded = log_column(&log, "valve_cmd_pa");
    assert!(measured.iter().all(|p| p.is_finite()));
    // The mismatch plant's valve is ideal: the pressure read in a period is the previous
    // period's command, to the converter's 30 Pa step.
    let k = measured.len() / 2;
    assert!(
        (measured[k] - commanded[k - 1]).abs() < 100.0,
        "{} against {}",
        measured[k],
        commanded[k - 1]
    );
    let r = run_virtual(
        &cfg,
        &RunOptions {
            duration_s: Some(8.0),
            log_path: Some(dir.join("stuck-open.csv")),
            injections: vec!["pressure-high@3".parse().expect("injection")],
            ..RunOptions::default()
        },
    );
    assert_eq!(r.fault.as_deref(), Some("daq-error"), "{r:?}");
    assert!(
        r.fault_detail
            .as_deref()
            .is_some_and(|d| d.contains("the valve reports")),
        "{r:?}"
    );
    assert!(r.vented, "{r:?}");
    assert_eq!(r.periods, 2999, "{r:?}");
    std::fs::remove_dir_all(dir).ok();
}

/// The pressure channel wired on AI 0/1 with `extra` added to the calibration and its range
/// index `range`.
fn with_pressure_channel(range: u32, calibration: &str) -> String {
    let text = EMBEDDED_VIRTUAL
        .replace(
            "# pressure = { subdevice = 0, channel = 1, range = 0, aref = \"ground\" }",
            &format!(
                "pressure = {{ subdevice = 0, channel = 1, range = {range}, aref = \"ground\" }}"
            ),
        )
        .replace(
            "valve_offset_v = 0.0\n",
            &format!("valve_offset_v = 0.0\n{calibration}\n"),
        );
    assert!(
        text.contains(&format!("channel = 1, range = {range}")),
        "the channel"
    );
    text
}

/// Regression: `pressure_pa_per_v = 1e4` with the pressure channel on AI range 3 (+-1 V)
/// passed `rig check`, and every run then faulted ("the valve reports NaN bar", at period
/// 288 on the shipped virtual rig) once the muscle passed 0.1 bar, the top of the channel. The channel must read 0
/// to the limit + 10 % strictly inside its range, checked before anything is written to the
/// board; a negative scale, which hides an over-pressure, is refused too.
#[test]
fn rig_check_refuses_a_pressure_channel_that_cannot_read_the_limit() {
    let dir = temp_dir("pressure-channel");
    let narrow = with_pressure_channel(3, "pressure_pa_per_v = 1.0e4");
    let cfg = RigConfig::from_toml_str(&narrow, "narrow.toml").expect("valid as a file");
    // At configure, before anything reaches the board.
    let e = refused_before_any_write(&cfg);
    assert!(e.contains("signals.pressure"), "{e}");
    // 0 Pa at 0 V is the bottom of a unipolar range, where the converter reads NaN.
    let unipolar = with_pressure_channel(9, "");
    let cases = [
        ("range 3", narrow, "signals.pressure"),
        ("unipolar", unipolar, "signals.pressure"),
        (
            "negative scale",
            with_pressure_channel(0, "pressure_pa_per_v = -1.0e5"),
            "calibration.pressure_pa_per_v",
        ),
    ];
    for (what, text, needle) in cases {
        let p = config_file(&dir, &what.replace(' ', "_"), &text);
        assert_refused(&["rig", "check", "--config", &p], needle);
        let log = dir.join(format!("{}.csv", what.replace(' ', "_")));
        assert_refused(
            &[
                "rig",
                "run",
                "--config",
                &p,
                "--log",
                log.to_str().expect("utf-8"),
            ],
            needle,
        );
        assert!(!log.exists(), "{what}: a run started");
    }
    // The channel as the shipped file suggests it (+-10 V, the valve's scale) passes and a
    // run with it completes.
    let p = config_file(&dir, "bipolar", &with_pressure_channel(0, ""));
    let out = pma_exo(&["rig", "check", "--config", &p]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("above 6.60 bar (6.6000 V)"), "{text}");
    let log = dir.join("bipolar.csv");
    let out = pma_exo(&[
        "rig",
        "run",
        "--config",
        &p,
        "--duration",
        "3",
        "--log",
        log.to_str().expect("utf-8"),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    std::fs::remove_dir_all(dir).ok();
}

/// The shipped virtual rig at `period_s`, its watchdog at 0.2 s.
fn virtual_at_period(period_s: f64) -> String {
    let watchdog = (0.2 / period_s).round() as u32;
    // The frozen-sensor check at its 0.5 s, the rate limit at most half the range a period.
    let stuck = (0.5 / period_s).floor() as u32;
    let rate = 2.0e8f64.min(0.5 * 6.0e5 / period_s);
    let text = EMBEDDED_VIRTUAL
        .replace("period_s = 0.001", &format!("period_s = {period_s}"))
        .replace(
            "sensor_stuck_periods = 500",
            &format!("sensor_stuck_periods = {stuck}"),
        )
        .replace(
            "pressure_rate_max_pa_per_s = 2.0e8",
            &format!("pressure_rate_max_pa_per_s = {rate:e}"),
        )
        .replace(
            "watchdog_periods = 50",
            &format!(
                "watchdog_periods = {watchdog}\noverrun_max_consecutive_periods = {}",
                watchdog / 2
            ),
        );
    assert_ne!(text, EMBEDDED_VIRTUAL);
    text
}

/// Regression: `rig excite` at `period_s = 0.01` or `0.005` on the shipped virtual rig went
/// `position-out` (at 2.6 s and 29 s) despite the back-off: the lockstep plant's
/// integration step grew with the period and rang. The excitation now holds inside the
/// window at every period, its commands at the slew rate per second whatever the period.
#[test]
fn rig_excite_holds_its_back_off_at_10_and_5_ms_periods() {
    let dir = temp_dir("excite-periods");
    for period_s in [0.01, 0.005] {
        let p = config_file(&dir, &format!("p{period_s}"), &virtual_at_period(period_s));
        let log = dir.join(format!("p{period_s}.csv"));
        let out = pma_exo(&[
            "rig",
            "excite",
            "--config",
            &p,
            "--duration",
            "60",
            "--out",
            log.to_str().expect("utf-8"),
            "--json",
        ]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        assert_eq!(out.status.code(), Some(0), "{period_s} s: {v}");
        assert_eq!(v["completed"], true, "{v}");
        let highest = log_column(&log, "position_m")
            .into_iter()
            .fold(f64::MIN, f64::max);
        assert!(highest < 0.045, "{period_s} s: reached {highest} m");
    }
    std::fs::remove_dir_all(dir).ok();
}

/// A run of `config` with a recorder that holds the loop 100 ms of wall time at periods
/// 200 and 400, as a loaded machine does.
fn run_with_slow_periods(cfg: &RigConfig, log: &Path) -> pma_rig::RigReport {
    let stop = AtomicBool::new(false);
    let slow = FnRecorder(|p: &Period<'_, Rig, MuscleStep>| {
        if p.index == 200 || p.index == 400 {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    });
    let options = RunOptions {
        duration_s: Some(1.0),
        log_path: Some(log.to_path_buf()),
        ..RunOptions::default()
    };
    pma_rig::run::run(cfg, Path::new("."), &options, &stop, slow).expect("run")
}

/// Regression: under CPU load, lockstep virtual runs with a 10 ms watchdog faulted with
/// `stall` at random: the watchdog measured silence on the wall clock, where a lockstep
/// run's periods take no defined time. A lockstep run's watchdog follows the simulated
/// clock (two 100 ms holds of the loop are no stall there), while a real-time run keeps
/// the wall clock and still finds the same hold a stall; an injected (simulated) hang
/// still trips the lockstep watchdog.
#[test]
fn a_slow_period_is_no_stall_in_lockstep_but_a_stall_in_real_time() {
    let dir = temp_dir("slow-period");
    let lockstep = run_with_slow_periods(&virtual_config(), &dir.join("lockstep.csv"));
    assert!(
        lockstep.completed && lockstep.fault.is_none(),
        "{lockstep:?}"
    );
    assert_eq!(lockstep.periods, 1000);
    // What is tested is the watchdog, not the machine's timing: the overrun limits at
    // their loosest (the hold misses 100 deadlines; the watchdog sees it first).
    let text = EMBEDDED_VIRTUAL.replace(
        "watchdog_periods = 50",
        "watchdog_periods = 50\noverrun_max_consecutive_periods = 49\noverrun_max_share = 0.5",
    );
    let mut realtime = RigConfig::from_toml_str(&text, "loose-timing.toml").expect("config");
    let v = realtime.virtual_rig.as_mut().expect("virtual");
    v.clock = ClockMode::Realtime;
    realtime.realtime.fifo = false;
    let r = run_with_slow_periods(&realtime, &dir.join("realtime.csv"));
    assert_eq!(r.fault.as_deref(), Some("stall"), "{r:?}");
    assert!(r.watchdog_vented && r.vented, "{r:?}");
    let stalled = run_virtual(
        &virtual_config(),
        &RunOptions {
            duration_s: Some(1.0),
            injections: vec!["stall@0.5".parse().expect("injection")],
            log_path: Some(dir.join("injected.csv")),
            ..RunOptions::default()
        },
    );
    assert_eq!(stalled.fault.as_deref(), Some("stall"), "{stalled:?}");
    assert!(stalled.watchdog_vented, "{stalled:?}");
    assert_eq!(stalled.periods, 499, "{stalled:?}");
    std::fs::remove_dir_all(dir).ok();
}
