//! `simulate --plot`'s view over the gait cycle (issue 27): `strides.png` through the
//! binary, and the binning behind it through the library: each leg's samples binned by its
//! own reference's phase, its mean curve within the run's reported tracking error.
use pma_exo::strides::{bin_centre, CycleCurve, GaitCycles, LegCycle, BINS};
use pma_leg::{LegReport, LegSim, Scenario};
use std::process::Command;

fn temp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pma-exo-strides-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// Width and height of a PNG (its IHDR chunk, big-endian at bytes 16 and 20).
fn png_size(png: &[u8]) -> (u32, u32) {
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&png[12..16], b"IHDR", "no IHDR first");
    let be = |i: usize| u32::from_be_bytes([png[i], png[i + 1], png[i + 2], png[i + 3]]);
    (be(16), be(20))
}

/// `simulate --plot DIR` draws `DIR/strides.png` beside `leg.png`: a column per joint (the
/// ankle and the foot's ground reaction on a treadmill), two rows per leg, a legend column.
#[test]
fn simulate_draws_every_leg_over_the_gait_cycle() {
    // 240 px of legend, 500 x 330 px a panel, 72 px of title.
    for (scenario, duration, size) in [
        ("gait_treadmill", "8", (240 + 3 * 500, 72 + 4 * 330)),
        ("gait_training", "4", (240 + 2 * 500, 72 + 2 * 330)),
    ] {
        let dir = temp(scenario);
        let out = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
            .args(["simulate", scenario, "--duration", duration, "--plot"])
            .arg(&dir)
            .output()
            .expect("run pma-exo");
        let stderr = String::from_utf8_lossy(&out.stderr);
        // Drawn whatever the verdict (exit 4: the patient did not walk within the criteria).
        assert!(
            matches!(out.status.code(), Some(0 | 4)),
            "{scenario}: {stderr}"
        );
        for file in ["leg.png", "strides.png"] {
            assert!(stderr.contains(&format!("wrote {}", dir.join(file).display())));
        }
        let png = std::fs::read(dir.join("strides.png")).expect("strides.png");
        assert_eq!(png_size(&png), size, "{scenario}");
        assert!(png.len() > 50_000, "{scenario}: {} bytes", png.len());
        std::fs::remove_dir_all(dir).ok();
    }
}

/// Runs `scenario` for `duration_s` with every leg binned after the first stride, as
/// `simulate --plot` does.
fn binned_run(scenario: &str, duration_s: f64) -> (GaitCycles, LegReport, f64) {
    let loaded = Scenario::load(scenario).expect("scenario");
    let period_s = loaded.scenario.period_s;
    let mut sim = LegSim::new(&loaded).expect("sim");
    let mut cycles =
        GaitCycles::new(&sim, loaded.scenario.gait.stride_period_s).expect("gait cycles");
    let report = sim.run(duration_s, &mut cycles).expect("run");
    (cycles, report, period_s)
}

/// The reference's lowest and highest angle (deg) of joint `joint` over bin `bin`'s
/// phases, after the start-up ramp.
fn reference_range_over_bin(leg: &LegCycle, joint: usize, bin: usize) -> (f64, f64) {
    let gait = leg.gait();
    let stride = gait.stride_period_s();
    // A time after the ramp at which this leg's cycle starts.
    let cycles_in = (gait.ramp_s() / stride).ceil() + 1.0;
    let t0 = (cycles_in - gait.phase_offset()) * stride;
    (0..=200)
        .map(|k| {
            let phase = (bin as f64 + k as f64 / 200.0) / BINS as f64;
            gait.sample(t0 + phase * stride).angles_rad()[joint].to_degrees()
        })
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// Count-weighted RMS over the bins of `a - b`.
fn weighted_rms(a: &CycleCurve, b: &CycleCurve) -> f64 {
    let (sum, n) = (0..BINS).fold((0.0, 0u64), |(s, n), bin| {
        let c = a.count(bin);
        if c == 0 {
            return (s, n);
        }
        let d = a.mean(bin) - b.mean(bin);
        (s + c as f64 * d * d, n + c)
    });
    (sum / n as f64).sqrt()
}

/// Each leg's samples sit in the bins of its own reference's phase (the reference binned
/// in a bin stays within the reference's range over that bin's phases: a sample one bin
/// off, or a leg binned on the other leg's phase, leaves it), the bins hold exactly the
/// periods after the first stride, and the mean curve tracks the binned reference within
/// the RMS tracking error the run reports (the count-weighted RMS of the bins' mean errors
/// is at most the RMS of the errors themselves); on a treadmill each foot carries weight
/// in its reference's stance and none in its swing.
#[test]
fn gait_cycle_bins_follow_each_legs_phase_and_track_within_the_reported_rms() {
    for (scenario, duration_s) in [("gait_treadmill", 8.0), ("gait_training", 4.0)] {
        let (cycles, report, period_s) = binned_run(scenario, duration_s);
        let legs = cycles.legs();
        assert_eq!(legs.len(), if scenario == "gait_treadmill" { 2 } else { 1 });
        let span = cycles.span_s();
        let periods_after = ((duration_s - span.start) / period_s).round() as u64;
        for (leg, cycle) in legs.iter().enumerate() {
            let joints = if cycle.has_ankle() { 3 } else { 2 };
            assert_eq!(cycle.has_ankle(), scenario == "gait_treadmill");
            for j in 0..joints {
                let (angle, reference) = (&cycle.angle_deg[j], &cycle.reference_deg[j]);
                let samples: u64 = (0..BINS).map(|b| angle.count(b)).sum();
                assert!(
                    samples.abs_diff(periods_after) <= 1,
                    "{scenario} leg {leg} joint {j}: {samples} samples, {periods_after} periods"
                );
                for bin in 0..BINS {
                    assert!(
                        angle.count(bin) > 0,
                        "{scenario} leg {leg}: bin {bin} empty"
                    );
                    let (lo, hi) = reference_range_over_bin(cycle, j, bin);
                    let r = reference.mean(bin);
                    assert!(
                        (lo - 1e-9..=hi + 1e-9).contains(&r),
                        "{scenario} leg {leg} joint {j} bin {bin} ({:.1} %): binned reference {r} deg outside {lo}..{hi}",
                        100.0 * bin_centre(bin)
                    );
                }
            }
            for (j, name) in ["hip", "knee"].into_iter().enumerate() {
                let key = pma_leg::plant::leg_label(legs.len(), leg, name);
                let reported = report.joints[&key].rms_deg;
                let binned = weighted_rms(&cycle.reference_deg[j], &cycle.angle_deg[j]);
                eprintln!("{scenario} {key}: binned mean error RMS {binned:.4} deg, reported RMS {reported:.4} deg");
                assert!(
                    binned > 0.0 && binned <= reported + 1e-9,
                    "{scenario} {key}: the mean curve is {binned} deg RMS off its reference, the run's RMS error {reported} deg"
                );
            }
            if scenario == "gait_treadmill" {
                let toe_off = cycle.gait().toe_off_phase();
                let mean_over = |from: f64, to: f64| {
                    let bins: Vec<usize> = (0..BINS)
                        .filter(|b| (from..to).contains(&bin_centre(*b)))
                        .collect();
                    bins.iter().map(|b| cycle.grf_bw.mean(*b)).sum::<f64>() / bins.len() as f64
                };
                let (stance, swing) = (mean_over(0.1, 0.5), mean_over(toe_off + 0.05, 0.95));
                assert!(
                    stance > 0.2 && swing < 0.05,
                    "leg {leg}: {stance} BW in mid-stance, {swing} BW in swing"
                );
            }
        }
    }
}
