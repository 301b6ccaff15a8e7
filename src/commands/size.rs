//! `pma-exo size`: the Festo muscles and pulleys a scenario's gait needs.
use crate::output::{self, OutFile};
use crate::provenance::{Provenance, Seeds};
use crate::say;
use anyhow::Result;
use pma_exo::setup::{SizeArgs, SizeRun};
use pma_leg::tools::{muscle_geometry, muscles_toml, JointSizing, Sizing};
use pma_leg::Scenario;
use std::path::PathBuf;

/// `size`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// An embedded scenario (gait_treadmill, gait_treadmill_spastic,
    /// gait_treadmill_unsupported, or an in-air one) or a scenario .toml file: its gait,
    /// patient, body-weight support and valve.
    #[arg(default_value = "gait_treadmill")]
    scenario: String,
    /// Strides measured (after the start-up ramp and one stride).
    #[arg(long, default_value_t = 3)]
    strides: usize,
    /// Longest muscle considered (m, at most 2): up to 0.4 m fits along the thigh, longer
    /// muscles sit on the trainer's frame and pull through cables.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    max_length_m: f64,
    /// Where to write the recommended muscle geometry (nothing is written without it: no
    /// default path, so that no file is replaced unasked).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Least share of its rating a recommended muscle keeps free at the stride's peak
    /// force, 0-0.9: the room a controller's own activity takes above the servo-driven
    /// stride (docs/treadmill.md measures what that is). Pressure and speed keep 10 %.
    #[arg(long, default_value_t = pma_leg::tools::FORCE_MARGIN_MIN, allow_negative_numbers = true)]
    force_margin: f64,
    /// Seconds of the closed-loop check (0: none): the recommendation run under the
    /// scenario's controller, valves and patient; where its peak force exceeds the servo
    /// figure's margin by more than a tenth of the rating, the muscles are sized again with
    /// the margin raised by what the controller took (at most three checks). 60 s, the
    /// walking verdict's run: a marginal loop held 20 s and collapsed at 32 s
    /// (docs/treadmill.md).
    #[arg(long, default_value_t = pma_leg::tools::CLOSED_LOOP_DEFAULT_S, allow_negative_numbers = true)]
    closed_loop_s: f64,
    /// Write the servo-driven strides period by period (each leg's angles, servo torques,
    /// ground reaction, ankle, pelvis, slip and contact speed) to a CSV file.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Print the sizing as JSON instead of a summary.
    #[arg(long)]
    json: bool,
}

/// The CSV's columns, one row per leg and period.
const CSV_COLUMNS: [&str; 16] = [
    "t_s",
    "leg",
    "phase",
    "hip_deg",
    "knee_deg",
    "hip_velocity_deg_s",
    "knee_velocity_deg_s",
    "hip_torque_nm",
    "knee_torque_nm",
    "grf_vertical_n",
    "grf_fore_aft_n",
    "ankle_deg",
    "pelvis_x_m",
    "pelvis_z_m",
    "slip_m_s",
    "contact_speed_m_s",
];

/// Runs `size`.
pub fn run(a: Args) -> Result<i32> {
    let args = SizeArgs {
        strides: a.strides,
        max_length_m: a.max_length_m,
        force_margin: a.force_margin,
        closed_loop_s: a.closed_loop_s,
    };
    args.check()?;
    let loaded = Scenario::load(&a.scenario)?;
    let outputs: Vec<(&str, &std::path::Path)> = [("--out", &a.out), ("--csv", &a.csv)]
        .into_iter()
        .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
        .collect();
    output::refuse_input_as_output(
        &super::scenario_inputs(&a.scenario, &loaded, None),
        &outputs,
    )?;
    // The operator's stop before any output exists: a signal never leaves a `.part`
    // behind (the staged files are dropped unwritten), and every stage below checks it.
    let stop = output::stop_flag()?;
    let out_file = a.out.as_deref().map(OutFile::create).transpose()?;
    let sc = &loaded.scenario;
    // A servo pass or closed-loop run that left physical bounds names the scenario.
    let run = SizeRun::of(&loaded, &args, &stop).map_err(|e| match e.downcast() {
        Ok(leg) => pma_exo::setup::in_scenario(leg, &a.scenario).into(),
        Err(e) => e,
    })?;
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        eprintln!("interrupted: nothing written");
        return Ok(output::INTERRUPTED);
    }
    if let Some(path) = &a.csv {
        write_csv(path, &run.demand)?;
    }
    let (demand, sizing, norms) = (&run.demand, &run.sizing, &run.norms);
    let provenance = Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &sc.name)),
        patient: Some(super::simulate::patient_name(&loaded)),
        seeds: Seeds::of_scenario(sc),
        ..Provenance::of_this_run()
    };
    let holds = run.closed_loop_holds().unwrap_or(true) && run.beyond_norms.is_none();
    let geometry = muscle_geometry(sizing).filter(|_| holds);
    let margin = run
        .closed_loop
        .last()
        .map_or(a.force_margin, |c| c.force_margin);
    let written = match (&geometry, out_file) {
        (Some(muscles), Some(out_file)) => {
            let header = format!(
                "Muscle geometry recommended by `{}` (docs/treadmill.md).\nEach joint: the smallest Festo size that supplies the stride's torques with\n{:.0} % of its rating free, within a 25 % contraction and with 10 % of the valve's\nrange and of its useful speed to spare, then the most compact. Set the scenario's\ncontrol.cocontraction_pa to {}.\n{}{}",
                provenance.command,
                100.0 * margin,
                sizing
                    .cocontraction_pa
                    .map_or_else(|| "(none common)".to_owned(), |p| format!("{p:.4e}")),
                force_limit_line(&run.closed_loop),
                provenance.line()
            );
            out_file.finish_with(&muscles_toml(muscles, &header))?;
            a.out.as_deref()
        }
        _ => None,
    };
    if a.json {
        let mut json = run.figures();
        json.insert("provenance".into(), serde_json::to_value(&provenance)?);
        json.insert(
            "muscle_geometry".into(),
            serde_json::to_value(written.map(|p| p.display().to_string()))?,
        );
        say!("{}", serde_json::to_string(&json)?);
    } else {
        print_summary(sizing, demand, &sc.name)?;
        print_norms(norms, run.norm_loading.as_ref())?;
        print_fitted(&run.fitted)?;
        print_closed_loop(&run.closed_loop)?;
        say!("{}", provenance.line());
    }
    if let Some(why) = &run.beyond_norms {
        eprintln!("{why}: no muscles are recommended for it, nothing written");
        return Ok(1);
    }
    if let Some(last) = run.closed_loop.last().filter(|c| !c.holds) {
        eprintln!("{}", closed_loop_failure(last));
        return Ok(1);
    }
    match (geometry, written) {
        (Some(_), Some(path)) => {
            output::wrote(path);
            Ok(0)
        }
        (Some(_), None) => {
            eprintln!(
                "the recommended muscle geometry was not written: pass --out FILE to write it"
            );
            Ok(0)
        }
        (None, _) => {
            eprintln!(
                "no Festo DMSP pair up to {} m long on a pulley up to 120 mm works for every joint: nothing written",
                a.max_length_m
            );
            Ok(1)
        }
    }
}

/// The servo-driven strides, a row per leg and period (angles in degrees).
fn write_csv(path: &std::path::Path, demand: &pma_leg::tools::Demand) -> Result<()> {
    let header: Vec<String> = CSV_COLUMNS.iter().map(|c| (*c).to_owned()).collect();
    let mut csv = output::CsvOut::create(path, &header, None)?;
    for s in &demand.samples {
        csv.row(&[
            s.t_s,
            s.leg as f64,
            s.phase,
            s.angle_rad[0].to_degrees(),
            s.angle_rad[1].to_degrees(),
            s.velocity_rad_s[0].to_degrees(),
            s.velocity_rad_s[1].to_degrees(),
            s.torque_nm[0],
            s.torque_nm[1],
            s.grf_n[0],
            s.grf_n[1],
            s.ankle_rad.to_degrees(),
            s.pelvis_m[0],
            s.pelvis_m[1],
            s.slip_m_s,
            s.contact_speed_m_s,
        ]);
    }
    csv.finish()?;
    output::wrote(path);
    Ok(())
}

fn print_norms(
    norms: &[pma_leg::tools::NormComparison],
    loading: Option<&pma_leg::tools::NormLoading>,
) -> Result<()> {
    for c in norms {
        say!(
            "  {:5} over the cycle: peak demand {:.2} N m/kg against the adults' {:.2} N m/kg (Fukuchi et al. 2018); RMS difference {:.2} N m/kg, {:.2} against the moments scaled by the support",
            c.joint,
            c.peak_demand_nm_kg,
            c.peak_normative_nm_kg,
            c.rms_difference_nm_kg,
            c.rms_difference_supported_nm_kg
        );
    }
    if let Some(l) = loading {
        say!(
            "  the adults' mean ground reaction (Fukuchi et al. 2018) x the legs' share, over the reference's {:.3} s stride: loading peak {:.2} BW, {:.3} of their belt's load; loading rate {:.1} BW/s; stance {:.1} %",
            l.stride_s,
            l.peak_bw,
            l.peak_over_load,
            l.loading_rate_bw_s,
            100.0 * l.stance_fraction
        );
    }
    Ok(())
}

fn print_summary(s: &Sizing, demand: &pma_leg::tools::Demand, scenario: &str) -> Result<()> {
    say!(
        "{scenario}: what a stride asks of the joints (servos along the reference, within {:.2} / {:.2} deg at hip / knee), and the muscles that supply it",
        demand.max_error_deg[0],
        demand.max_error_deg[1]
    );
    if let Some(t) = &demand.treadmill {
        for (side, f) in &t.feet {
            say!(
                "  on the belt at {:.3} m/s with {:.0} % support, {side} foot: GRF loading peak {:.2} BW, {:.3} of the belt's load; loading rate {:.1} BW/s; stance {:.1} % (reference {:.1} %), slip {:.1} mm per stride",
                t.belt_speed_m_s,
                100.0 * t.bws_fraction,
                f.peak_grf_bw.mean,
                f.peak_grf_bw.mean / t.expected_belt_load_bw,
                f.loading_rate_bw_s.mean,
                100.0 * f.stance_fraction.mean,
                100.0 * f.reference_stance_fraction,
                1e3 * f.slip_per_stride_m.mean
            );
        }
    }
    for j in &s.joints {
        print_joint(j)?;
    }
    match s.cocontraction_pa {
        Some(p) => say!(
            "  co-contraction at which both pairs work with the widest margin: {:.2} bar",
            p / 1e5
        ),
        None => say!("  no co-contraction pressure suits both joints"),
    }
    Ok(())
}

fn print_joint(j: &JointSizing) -> Result<()> {
    say!(
        "  {:5} range {:.1}..{:.1} deg, torque {:.1}..{:.1} N m (averaged over 10 ms), up to {:.0} deg/s",
        j.joint,
        j.range_deg[0],
        j.range_deg[1],
        j.torque_nm[0],
        j.torque_nm[1],
        j.peak_speed_deg_s
    );
    for ((size, n), (_, rejected)) in j.feasible_per_size.iter().zip(&j.rejected_per_size) {
        let why: Vec<String> = rejected
            .iter()
            .map(|(r, k)| format!("{k} {}", r.as_str()))
            .collect();
        say!(
            "    {size}: {n} designs work; the others fail on {}",
            if why.is_empty() {
                "nothing".to_owned()
            } else {
                why.join(", ")
            }
        );
    }
    match &j.recommended {
        Some(d) => say!(
            "    recommended: {} {:.2} m on a {:.0} mm pulley at {:.2} bar (it works from {:.2} to {:.2} bar): peak force {:.2} of its rating, strain up to {:.1} %, speed up to {:.2} of its useful speed, pressure headroom {:.1} %",
            d.size,
            d.rest_length_m,
            1e3 * d.pulley_radius_m,
            d.cocontraction_pa / 1e5,
            j.recommended_cocontraction_range_pa.map_or(f64::NAN, |r| r[0] / 1e5),
            j.recommended_cocontraction_range_pa.map_or(f64::NAN, |r| r[1] / 1e5),
            d.peak_force_over_rated,
            100.0 * d.max_strain,
            d.speed_over_useful,
            100.0 * d.pressure_headroom
        ),
        None => say!("    no design works"),
    }
    if let Some(why) = &j.at_edge {
        say!("    at the edge of the search: {why}");
    }
    Ok(())
}

/// Each closed-loop check: the joints' peak force against the servo figure and the
/// allowance, and whether the patient walked.
/// The scenario's own muscles on the stride, beside the recommendation.
fn print_fitted(pairs: &[pma_leg::tools::FittedPair]) -> Result<()> {
    for p in pairs {
        let figure = match (p.reject, p.peak_force_over_rated, p.max_strain) {
            (None, Some(f), Some(s)) => format!(
                "peak force {f:.2} of the rating, contraction up to {:.1} %, pressures asked {}",
                100.0 * s,
                p.pressure_range_bar
                    .map_or("-".into(), |[lo, hi]| format!("{lo:.2} to {hi:.2} bar"))
            ),
            (Some(r), ..) => format!("cannot drive it ({})", r.as_str()),
            _ => "-".into(),
        };
        let verdict = p
            .why_not()
            .map_or("fits".to_owned(), |_| "does not fit".into());
        say!(
            "  the scenario's {} muscles ({}): {figure}: {verdict}",
            p.joint,
            p.muscles
        );
    }
    Ok(())
}

fn print_closed_loop(checks: &[pma_leg::tools::ClosedLoop]) -> Result<()> {
    for (i, c) in checks.iter().enumerate() {
        let joints: Vec<String> = c
            .joints
            .iter()
            .map(|j| {
                format!(
                    "{} peak force {:.2} of the rating (servo {:.2}, at most {:.2})",
                    j.joint, j.peak_over_rated, j.servo_peak_over_rated, j.allowed_over_rated
                )
            })
            .collect();
        let walked = match (c.walking, &c.why_not) {
            (_, Some(why)) => format!("; {why}"),
            (Some(true), None) => "; the patient walked".into(),
            _ => String::new(),
        };
        let limit = c.force_max_of_rating.map_or_else(String::new, |f| {
            format!(", every command held to {f:.2} of its muscle's rating")
        });
        say!(
            "  closed loop {} ({:.0} s, margin {:.2}, the scenario's controller and valves{limit}): {}{walked}: {}",
            i + 1,
            c.duration_s,
            c.force_margin,
            joints.join(", "),
            if c.holds { "holds" } else { "does not hold" }
        );
    }
    Ok(())
}

/// The header's line on the force limit the closed loop held (with its newline), or
/// nothing when no check ran.
fn force_limit_line(checks: &[pma_leg::tools::ClosedLoop]) -> String {
    checks
        .last()
        .and_then(|c| c.force_max_of_rating)
        .map_or_else(String::new, |f| {
            format!(
                "Checked in closed loop with every muscle's command held to {f:.2} of its rating: set\nthe scenario's control.force_max_of_rating to {f:.2} to stay within the margin.\n"
            )
        })
}

/// One line on why the recommendation does not hold in closed loop, and what to do.
fn closed_loop_failure(c: &pma_leg::tools::ClosedLoop) -> String {
    if let Some(why) = &c.why_not {
        return format!(
            "the recommendation does not hold in closed loop ({why}): nothing written; tune the scenario's controller for these muscles (pma-exo tune-leg) or pass --closed-loop-s 0 to size on the servo alone"
        );
    }
    let worst = c
        .joints
        .iter()
        .max_by(|a, b| {
            (a.peak_over_rated - a.allowed_over_rated)
                .total_cmp(&(b.peak_over_rated - b.allowed_over_rated))
        })
        .map_or_else(String::new, |j| {
            format!(
                "the {} peaks at {:.2} of its rating in closed loop, above {:.2}",
                j.joint, j.peak_over_rated, j.allowed_over_rated
            )
        });
    format!(
        "the recommendation does not hold in closed loop: {worst} even with the margin raised to {:.2}: nothing written; a larger valve range, a longer search (--max-length-m) or a gentler controller",
        c.force_margin
    )
}
