//! `pma-exo envelope`: a treadmill scenario over body mass x support x walking speed x
//! mode, each cell walked, refused before it ran, or run and failed, with its reason
//! (issue 47); a table, a JSON and a map.
use crate::output::{self, OutFile};
use crate::plot::{title_block, DrawResult, FONT, TITLE_HEIGHT};
use crate::say;
use anyhow::{bail, Result};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use pma_exo::envelope::{self, Cell, Outcome};
use pma_exo::setup::Mode;
use pma_leg::Scenario;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// `envelope`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// A treadmill scenario on the adults' gait (embedded name or .toml file).
    #[arg(default_value = "gait_treadmill")]
    scenario: String,
    /// Body masses (kg), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "50,80,110")]
    mass_kg: Vec<f64>,
    /// Body-weight supports (fractions 0-1), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,0.25,0.5")]
    support: Vec<f64>,
    /// Walking speeds (m/s), comma-separated: the adult reference's speed; the belt runs at
    /// the scenario's own belt speed scaled by it.
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.7,0.9")]
    speed: Vec<f64>,
    /// Control modes, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "position",
        value_name = "position,impedance,admittance,path,transparent"
    )]
    modes: Vec<Mode>,
    /// The controller of every muscle, with the scenario's gains for it (default: the
    /// scenario's APRC-NDO); position and admittance modes only.
    #[arg(long, value_name = pma_control::ControllerKind::NAMES)]
    controller: Option<pma_control::ControllerKind>,
    /// A gain file every cell's controller runs with instead of the scenario's (its
    /// controller, unless --controller names it; position and admittance modes only), such
    /// as the APRC-NDO set tuned over the patients,
    /// `crates/pma-leg/models/gains/treadmill-patients/aprc-ndo.toml`.
    #[arg(long)]
    gains: Option<PathBuf>,
    /// With --gains: only cells whose support is below this fraction run the file's gains,
    /// the others the scenario's (a schedule by support: the set tuned over the patients
    /// below 0.5, the scenario's from it; docs/envelope.md).
    #[arg(long, requires = "gains")]
    gains_below_support: Option<f64>,
    // The bound comes from the constant that checks it, so the help cannot fall behind.
    #[arg(long, help = format!(
        "Physics substeps per control period in every cell (default: the scenario's; {}): \
         a finer step for the patients the shipped one cannot simulate",
        super::physics_substeps_range()
    ))]
    physics_substeps: Option<u32>,
    /// The patients' height (m, every cell; default the scenario's): the legs scale to it,
    /// and the belt with them (a taller patient walks the reference's angles at the same
    /// cadence faster).
    #[arg(long)]
    height_m: Option<f64>,
    /// Simulated seconds per cell; at least two strides.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    duration: f64,
    /// Output directory (envelope.json, envelope.md, envelope.png); without it the table
    /// is printed only.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the cells as JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: one per core); the results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// Most cells of one map.
const CELLS_MAX: usize = 2000;

/// Every value of `values` within `[low, high]`, none twice, at least one; the error names
/// the flag and its range.
fn check_axis(flag: &str, values: &[f64], (low, high): (f64, f64), what: &str) -> Result<()> {
    if values.is_empty() {
        bail!("{flag}: give at least one value");
    }
    for (i, v) in values.iter().enumerate() {
        if !(v.is_finite() && (low..=high).contains(v)) {
            bail!(
                "{flag} {} is invalid: {what}, {} to {}",
                pma_model::error::number(*v),
                pma_model::error::number(low),
                pma_model::error::number(high)
            );
        }
        if values[..i].contains(v) {
            bail!("{flag}: {} is given twice", pma_model::error::number(*v));
        }
    }
    Ok(())
}

/// Every argument checked before anything runs or is written.
fn check_args(a: &Args) -> Result<()> {
    let (m_lo, m_hi) = pma_leg::ground::BODY_MASS_RANGE_KG;
    check_axis("--mass-kg", &a.mass_kg, (m_lo, m_hi), "a patient's mass")?;
    check_axis(
        "--support",
        &a.support,
        (0.0, 1.0),
        "a fraction of the body weight",
    )?;
    check_axis(
        "--speed",
        &a.speed,
        (0.01, pma_leg::ground::BELT_SPEED_MAX_M_S),
        "a walking speed in m/s",
    )?;
    for (i, m) in a.modes.iter().enumerate() {
        if a.modes[..i].contains(m) {
            bail!("--modes: `{}` is given twice", m.control_mode());
        }
        if m.control_mode().runs_muscle_controllers() {
            continue;
        }
        let flag = match (a.controller, &a.gains) {
            (Some(k), _) => format!("--controller {}", k.as_str()),
            (None, Some(g)) => format!("--gains {}", g.display()),
            (None, None) => continue,
        };
        bail!(
            "{flag}: {} mode runs no muscle controller (give --modes position or admittance)",
            m.control_mode()
        );
    }
    if let Some(n) = a.physics_substeps {
        super::check_physics_substeps(n)?;
    }
    if let Some(s) = a.gains_below_support {
        check_axis(
            "--gains-below-support",
            &[s],
            (0.0, 1.0),
            "a fraction of the body weight",
        )?;
    }
    if let Some(h) = a.height_m {
        check_axis(
            "--height-m",
            &[h],
            pma_leg::ground::PATIENT_HEIGHT_RANGE_M,
            "the adult reference's subjects' heights (Fukuchi et al. 2018)",
        )?;
    }
    if a.modes.is_empty() {
        bail!("--modes: give at least one mode");
    }
    super::check_duration(a.duration)?;
    // The pool's size is checked before any output exists.
    super::with_threads(a.threads, || ())?;
    let cells = a.mass_kg.len() * a.support.len() * a.speed.len() * a.modes.len();
    if cells > CELLS_MAX {
        bail!("the map has {cells} cells, more than {CELLS_MAX}: give fewer values");
    }
    Ok(())
}

/// The output files in `dir`.
fn out_files(dir: &Path) -> [PathBuf; 3] {
    ["envelope.json", "envelope.md", "envelope.png"].map(|f| dir.join(f))
}

/// Runs `envelope`.
pub fn run(a: Args) -> Result<i32> {
    check_args(&a)?;
    let loaded = Scenario::load(&a.scenario)?;
    envelope::check_base(&loaded, &a.scenario)?;
    loaded.scenario.check_run_duration(a.duration)?;
    let points = envelope::points(&a.mass_kg, &a.support, &a.speed, &a.modes);
    // A gain file is read and checked before anything is written.
    let gains = a
        .gains
        .as_deref()
        .map(|g| pma_exo::setup::leg_config(a.controller, Some(g), &loaded))
        .transpose()?;
    let settings = envelope::CellSettings {
        controller: gains.map(|g| g.kind()).or(a.controller),
        gains,
        gains_below_support: a.gains_below_support,
        physics_substeps: a.physics_substeps,
        height_m: a.height_m,
    };
    // A finer step costs about as much more.
    let substeps_factor = f64::from(
        a.physics_substeps
            .unwrap_or(loaded.scenario.physics_substeps),
    ) / f64::from(loaded.scenario.physics_substeps.max(1));
    let periods =
        points.len() as f64 * a.duration / loaded.scenario.period_s * substeps_factor.max(1.0);
    output::check_wall_time(
        "this envelope",
        periods,
        super::simulate::LEG_PERIOD_S,
        a.yes,
    )?;
    let staged = match &a.out {
        Some(dir) => {
            let files = out_files(dir);
            output::refuse_input_as_output(
                &super::scenario_inputs(&a.scenario, &loaded, a.gains.as_deref()),
                &files
                    .iter()
                    .map(|p| ("--out", p.as_path()))
                    .collect::<Vec<_>>(),
            )?;
            let created = !dir.is_dir();
            output::create_dir(dir)?;
            let json = OutFile::create(&files[0])?;
            let md = OutFile::create(&files[1])?;
            Some((created, json, md))
        }
        None => None,
    };
    let stop = output::stop_flag()?;
    static DONE: AtomicUsize = AtomicUsize::new(0);
    let bar = output::follow_progress(&DONE, points.len() as u64, "cells");
    let cells: Vec<Cell> = super::with_threads(a.threads, || {
        use rayon::prelude::*;
        points
            .par_iter()
            .map(|p| {
                let cell = envelope::run_cell(&loaded, p, &settings, a.duration, &stop);
                DONE.fetch_add(1, Ordering::Relaxed);
                cell
            })
            .collect()
    })?;
    drop(bar);
    if stop.load(Ordering::Relaxed) || cells.iter().any(|c| c.outcome == Outcome::Interrupted) {
        if let (Some(dir), Some((true, ..))) = (&a.out, &staged) {
            drop(staged);
            std::fs::remove_dir(dir).ok();
        }
        eprintln!("interrupted: nothing written (a map with cells cut short maps nothing)");
        return Ok(output::INTERRUPTED);
    }
    // A schedule by support, as both the provenance and the image say it.
    let below = a.gains_below_support.map_or(String::new(), |s| {
        format!(" below {} support", pma_model::error::number(s))
    });
    let scenario_gains = match &loaded.scenario.control.gains_below_support {
        Some(s) => format!(
            "the scenario's gains (its control.gains_below_support set below {} support)",
            pma_model::error::number(s.support_fraction)
        ),
        None => "the scenario's gains".into(),
    };
    let gains_label = match &a.gains {
        None => scenario_gains.clone(),
        Some(g) if below.is_empty() => g.display().to_string(),
        Some(g) => format!("{}{below}, the scenario's from it", g.display()),
    };
    let provenance = crate::provenance::Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &loaded.scenario.name)),
        controller: Some(
            settings
                .controller
                .map_or("the scenario's, per mode".into(), |k| k.as_str().to_owned()),
        ),
        gains: Some(gains_label),
        patient: Some("passive, the mass and support of each cell".into()),
        valve: Some(loaded.scenario.plant.valve_label()?),
        ..crate::provenance::Provenance::of_this_run()
    };
    let md = format!(
        "{}\n_{}_\n",
        table(&cells, &a, &loaded.scenario.name),
        provenance.line()
    );
    // One JSON for the file and for --json.
    let json = serde_json::json!({
        "provenance": provenance,
        "duration_s": a.duration,
        "cells": cells,
    });
    if let (Some(dir), Some((_, json_file, md_file))) = (&a.out, staged) {
        let files = out_files(dir);
        let title = format!(
            "{}: where the trainer walks its patient",
            loaded.scenario.name
        );
        crate::plot::register_font()?;
        // The setting without the command line: the same map draws the same image
        // wherever it is written.
        let gains_said = match &a.gains {
            Some(g) => format!(
                "gains {}{below}",
                g.file_name()
                    .map_or_else(|| g.display().to_string(), |f| f.to_string_lossy().into())
            ),
            None => scenario_gains,
        };
        let setting = format!(
            "{} s per cell; {}; {gains_said}",
            a.duration,
            provenance.valve.as_deref().unwrap_or("-")
        );
        let png = output::stage(&files[2], |tmp| draw_map(tmp, &title, &setting, &cells, &a))?;
        json_file.finish_with(&serde_json::to_string_pretty(&json)?)?;
        md_file.finish_with(&md)?;
        png.commit()?;
        for f in &files {
            output::wrote(f);
        }
    }
    if a.json {
        say!("{}", serde_json::to_string(&json)?);
    } else {
        say!("{md}");
    }
    let failed = cells
        .iter()
        .filter(|c| matches!(c.outcome, Outcome::Failed | Outcome::Unphysical))
        .count();
    if failed > 0 {
        eprintln!(
            "{failed} of {} cells ran and did not walk or their simulation failed (their reasons in the table)",
            cells.len()
        );
        return Ok(super::simulate::DID_NOT_WALK);
    }
    Ok(0)
}

/// A figure or `-`.
fn fig(v: Option<f64>, decimals: usize) -> String {
    v.map_or("-".into(), |v| pma_leg::metrics::figure(v, decimals))
}

/// The map as a Markdown table, a row per cell, then per mode and speed the lowest
/// support at which every mass walked.
fn table(cells: &[Cell], a: &Args, name: &str) -> String {
    let mut md = format!(
        "# {name}: the envelope ({} s per cell)\n\n| mode | speed (m/s) | belt (m/s) | support | mass (kg) | outcome | stance RMS hip / knee (deg) | peak force / rating | reason |\n|---|---|---|---|---|---|---|---|---|\n",
        a.duration
    );
    for c in cells {
        let stance = c.stance_rms_deg.map_or("-".into(), |[h, k]| {
            format!("{} / {}", fig(Some(h), 2), fig(Some(k), 2))
        });
        let _ = writeln!(
            md,
            // The mass as entered ("80", "79.5"): a perturbed map's cells stay apart.
            "| {} | {:.2} | {} | {:.2} | {} | {} | {stance} | {} | {} |",
            c.mode,
            c.speed_m_s,
            fig(c.belt_m_s, 4),
            c.support,
            c.mass_kg,
            c.outcome.as_str(),
            fig(c.peak_force_over_rated, 2),
            short_reason(c).replace('|', "/")
        );
    }
    md.push_str(
        "\nLowest support from which the patient walked at every support tried above it:\n\n",
    );
    for m in &a.modes {
        let mode = m.control_mode().to_string();
        for &v in &a.speed {
            let per_mass: Vec<String> = a
                .mass_kg
                .iter()
                .map(|&kg| {
                    let lowest = envelope::lowest_support(cells, &mode, v, kg);
                    let figure = lowest.map_or("none".into(), |s| format!("{:.0} %", 100.0 * s));
                    format!("{kg} kg {figure}")
                })
                .collect();
            let _ = writeln!(md, "- {mode}, {v:.2} m/s: {}", per_mass.join(", "));
        }
    }
    md
}

/// A cell's reason as the table prints it: its first clause, without what the JSON's full
/// reason adds (the limits, the remedy, the other criteria missed: counted).
fn short_reason(c: &Cell) -> String {
    let Some(first) = c.reasons.first() else {
        return String::new();
    };
    if c.refusal == Some(envelope::Refusal::NoReference) {
        return "no adult reference at this belt speed".into();
    }
    let first = [" (limit ", ": the scenario does not fit"]
        .iter()
        .fold(first.as_str(), |text, cut| {
            text.split(cut).next().unwrap_or(text)
        });
    match c.reasons.len() {
        1 => first.to_owned(),
        n => format!("{first} (+{} more)", n - 1),
    }
}

/// The colour of an outcome on the map.
fn outcome_colour(o: Outcome) -> RGBColor {
    match o {
        Outcome::Walked => RGBColor(120, 190, 120),
        Outcome::Failed => RGBColor(220, 110, 100),
        Outcome::Unphysical => RGBColor(150, 110, 170),
        Outcome::Refused | Outcome::Interrupted => RGBColor(200, 200, 200),
    }
}

/// The map: a panel per mode (rows) and speed (columns), mass across and support up,
/// each cell coloured by its outcome and labelled with its worst stance error, its
/// collapse or its refusal.
fn draw_map(path: &Path, title: &str, setting: &str, cells: &[Cell], a: &Args) -> DrawResult {
    const PANEL: (u32, u32) = (520, 420);
    let (cols, rows) = (a.speed.len() as u32, a.modes.len() as u32);
    // Wide enough for the colours' key.
    let size = (
        (PANEL.0 * cols + 40).max(1400),
        TITLE_HEIGHT + 40 + PANEL.1 * rows,
    );
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, rest) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (key, body) = rest.split_vertically(40);
    draw_key(&key)?;
    let panels = body
        .margin(0, 0, 20, 20)
        .split_evenly((rows as usize, cols as usize));
    for (i, area) in panels.iter().enumerate() {
        let (mode, speed) = (a.modes[i / cols as usize], a.speed[i % cols as usize]);
        let mode = mode.control_mode().to_string();
        draw_panel(area, cells, &mode, speed, a)?;
    }
    root.present()?;
    Ok(())
}

/// The colours' key, in one line.
fn draw_key(area: &DrawingArea<BitMapBackend, plotters::coord::Shift>) -> DrawResult {
    let style = (FONT, 16).into_font().into_text_style(area);
    let mut x = 30;
    for (o, text) in [
        (Outcome::Walked, "walked (worst stance RMS)"),
        (Outcome::Failed, "ran and failed"),
        (Outcome::Refused, "refused before it ran"),
        (Outcome::Unphysical, "the simulation failed"),
    ] {
        area.draw(&Rectangle::new(
            [(x, 10), (x + 24, 30)],
            outcome_colour(o).filled(),
        ))?;
        area.draw_text(text, &style, (x + 32, 12))?;
        x += 330;
    }
    Ok(())
}

/// One mode at one speed: mass across, support up.
fn draw_panel(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    cells: &[Cell],
    mode: &str,
    speed: f64,
    a: &Args,
) -> DrawResult {
    let caption = format!("{mode}, {speed:.2} m/s");
    let area = area.titled(&caption, (FONT, 20))?;
    let (w, h) = area.dim_in_pixel();
    let (left, bottom) = (90i32, 50i32);
    let (nx, ny) = (a.mass_kg.len() as i32, a.support.len() as i32);
    let cw = (w as i32 - left - 10) / nx.max(1);
    let ch = (h as i32 - bottom - 10) / ny.max(1);
    let small = (FONT, 14).into_font().into_text_style(&area);
    let centred = small.pos(Pos::new(HPos::Center, VPos::Center));
    for (ix, m) in a.mass_kg.iter().enumerate() {
        for (iy, s) in a.support.iter().enumerate() {
            let Some(c) = cells.iter().find(|c| {
                c.mode == mode && c.speed_m_s == speed && c.mass_kg == *m && c.support == *s
            }) else {
                continue;
            };
            let x0 = left + ix as i32 * cw;
            let y0 = h as i32 - bottom - (iy as i32 + 1) * ch;
            area.draw(&Rectangle::new(
                [(x0 + 2, y0 + 2), (x0 + cw - 2, y0 + ch - 2)],
                outcome_colour(c.outcome).filled(),
            ))?;
            area.draw_text(&c.label(), &centred, (x0 + cw / 2, y0 + ch / 2))?;
        }
    }
    let axis = small.pos(Pos::new(HPos::Center, VPos::Top));
    for (ix, m) in a.mass_kg.iter().enumerate() {
        let x = left + ix as i32 * cw + cw / 2;
        area.draw_text(&format!("{m} kg"), &axis, (x, h as i32 - bottom + 6))?;
    }
    area.draw_text(
        "body mass",
        &axis,
        (left + nx * cw / 2, h as i32 - bottom + 26),
    )?;
    let side = small.pos(Pos::new(HPos::Right, VPos::Center));
    for (iy, s) in a.support.iter().enumerate() {
        let y = h as i32 - bottom - iy as i32 * ch - ch / 2;
        area.draw_text(&format!("{:.0} %", 100.0 * s), &side, (left - 8, y))?;
    }
    area.draw_text("support", &small, (4, 4))?;
    Ok(())
}
