//! The force limit (`[control] force_max_of_rating`, issue 46): each muscle's command
//! lowered to the pressure at which its datasheet model pulls a share of its rating.
use pma_leg::{LegReport, LegSim, Scenario};

const SECONDS: f64 = 4.0;

/// The in-air leg (instantaneous valves) with the limit at `share`, if any.
fn run(share: Option<f64>) -> LegReport {
    let mut loaded = Scenario::load("gait_training").expect("embedded");
    loaded.scenario.control.force_max_of_rating = share;
    let mut sim = LegSim::new(&loaded).expect("a valid scenario");
    sim.run(SECONDS, &mut ()).expect("a run")
}

fn peak_over_rated(r: &LegReport) -> f64 {
    r.safety
        .muscles
        .values()
        .map(|m| m.peak_over_rated)
        .fold(f64::NAN, f64::max)
}

/// Behind a valve that sets its pressure at once, the force follows the ceiling within
/// what the filtered encoder rate misses: a limit at half the unlimited peak holds every
/// muscle within 5 % of it, and it binds (the commands were lowered) where the unlimited
/// run passed it.
#[test]
fn a_force_limit_holds_every_muscle_at_its_share_of_the_rating() {
    let free = run(None);
    let unlimited = peak_over_rated(&free);
    let share = 0.5 * unlimited;
    let limited = run(Some(share));
    let peak = peak_over_rated(&limited);
    assert!(
        peak <= 1.05 * share,
        "{peak} of the rating at a limit of {share}"
    );
    assert!(unlimited > 1.05 * share, "{unlimited}");
    let bound: f64 = limited
        .safety
        .muscles
        .values()
        .map(|m| m.force_limited_s)
        .sum();
    assert!(bound > 0.0, "the limit never bound");
    assert!(free
        .safety
        .muscles
        .values()
        .all(|m| m.force_limited_s == 0.0));
}

/// A limit above every force the run asks changes nothing: the same tracking to the bit.
#[test]
fn a_force_limit_that_never_binds_changes_nothing() {
    let free = run(None);
    let unlimited = peak_over_rated(&free);
    assert!(unlimited < 0.9, "{unlimited}");
    let limited = run(Some(1.0));
    for joint in ["hip", "knee"] {
        assert_eq!(
            limited.joints[joint].rms_deg.to_bits(),
            free.joints[joint].rms_deg.to_bits(),
            "{joint}"
        );
    }
}

/// A share outside (0, 1] is refused before anything runs, naming the field.
#[test]
fn a_force_limit_outside_zero_to_one_is_refused_naming_the_field() {
    for bad in [0.0, 1.5, f64::NAN] {
        let mut loaded = Scenario::load("gait_training").expect("embedded");
        loaded.scenario.control.force_max_of_rating = Some(bad);
        let e = LegSim::new(&loaded).err().expect("refused").to_string();
        assert!(e.contains("control.force_max_of_rating"), "{e}");
    }
}
