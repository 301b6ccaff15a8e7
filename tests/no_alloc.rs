//! The hot loop allocates nothing: every period of the bench and of the supervised,
//! logged virtual rig runs without a single heap allocation on the loop's thread
//! (counted per thread by a global allocator, from the first period to the last).
use pma_bench::{MuscleBench, PlantConfig, RunSpec};
use pma_control::MuscleStep;
use pma_control::{ControllerKind, SineReference};
use pma_loop::{Period, Recorder, Start};
use pma_rig::{Rig, RigConfig, RunOptions};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::AtomicBool;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Counts allocations between the first period and the last.
#[derive(Default)]
struct Counter {
    at_first: Option<u64>,
    at_last: u64,
    periods: u64,
}

impl Counter {
    fn during_periods(&self) -> u64 {
        self.at_last - self.at_first.unwrap_or(self.at_last)
    }
    fn tick(&mut self) {
        let now = allocations();
        self.at_first.get_or_insert(now);
        self.at_last = now;
        self.periods += 1;
    }
}

impl Recorder<MuscleBench, MuscleStep> for Counter {
    fn record(&mut self, _: &Period<'_, MuscleBench, MuscleStep>) {
        self.tick();
    }
}

impl Recorder<Rig, MuscleStep> for Counter {
    fn start(&mut self, _: &Start<'_, Rig>) {}
    fn record(&mut self, _: &Period<'_, Rig, MuscleStep>) {
        self.tick();
    }
}

#[test]
fn the_bench_loop_allocates_nothing_per_period() {
    for kind in ControllerKind::ALL {
        for plant in ["ideal", "realistic"] {
            let mut counter = Counter::default();
            pma_bench::run_single(
                &kind.default_config(),
                &PlantConfig::preset(plant).expect("preset"),
                &SineReference::paper(),
                &RunSpec {
                    duration_s: 2.0,
                    ..RunSpec::default()
                },
                &mut counter,
            )
            .expect("run");
            assert_eq!(counter.periods, 2000);
            assert_eq!(counter.during_periods(), 0, "{kind} on {plant}");
        }
    }
}

#[test]
fn the_supervised_logged_virtual_rig_allocates_nothing_per_period() {
    let cfg = RigConfig::from_toml_str(pma_rig::config::EMBEDDED_VIRTUAL, "virtual.toml")
        .expect("config");
    let dir = std::env::temp_dir().join(format!("pma-exo-no-alloc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let mut counter = Counter::default();
    let stop = AtomicBool::new(false);
    let options = RunOptions {
        duration_s: Some(3.0),
        log_path: Some(dir.join("log.csv")),
        ..RunOptions::default()
    };
    let r = pma_rig::run::run(
        &cfg,
        std::path::Path::new("."),
        &options,
        &stop,
        &mut counter,
    )
    .expect("run");
    assert!(r.completed);
    assert_eq!(counter.periods, 3000);
    // The log's writer thread allocates as it formats rows; the loop's thread does not.
    assert_eq!(counter.during_periods(), 0);
    std::fs::remove_dir_all(dir).ok();
}

/// The leg's loop is not allocation-free: rapier3d 0.36's `PhysicsWorld::step` allocates
/// 18-25 times per 1 ms period (two substeps) in `Multibody::update_acceleration`,
/// `update_mass_matrix` and its modification tracking (traced with backtraces from this
/// allocator). What this project runs every substep beside it, the patient model, is.
#[test]
fn the_patient_model_allocates_nothing_per_substep() {
    for scenario in ["gait_spastic", "gait_spasms", "gait_resistive"] {
        let loaded = pma_leg::Scenario::load(scenario).expect("scenario");
        let sim = pma_leg::LegSim::new(&loaded).expect("sim");
        let mut patient = sim.plant().patient().expect("a patient").clone();
        let h = sim.leg().substep_s();
        let substeps = (60.0 / h) as u64;
        // As a run does: every spasm drawn before the loop.
        patient.plan(60.0);
        let before = allocations();
        let mut spasm_substeps = 0u64;
        for k in 0..substeps {
            let t = k as f64 * h;
            let a = (4.0 * t).sin();
            let tau = patient.torques(t, [0.3 * a, 0.6 + 0.5 * a], [1.2 * a, 4.0 * a]);
            if tau.spasm_nm != [0.0; 2] {
                spasm_substeps += 1;
            }
        }
        assert_eq!(allocations() - before, 0, "{scenario}");
        if scenario == "gait_spasms" {
            assert!(
                spasm_substeps > 1000,
                "{spasm_substeps} substeps in a spasm"
            );
        }
    }
}
