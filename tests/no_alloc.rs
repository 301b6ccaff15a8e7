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
    /// While set, each allocation is attributed by its backtrace: rapier's own (inside its
    /// step and its bodies' change tracking) or ours.
    static CLASSIFY: Cell<bool> = const { Cell::new(false) };
    static CLASSIFYING: Cell<bool> = const { Cell::new(false) };
    static OURS: Cell<u64> = const { Cell::new(0) };
    static RAPIERS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
    let classify = CLASSIFY.try_with(Cell::get).unwrap_or(false);
    if classify && !CLASSIFYING.try_with(Cell::get).unwrap_or(true) {
        CLASSIFYING.with(|c| c.set(true));
        let trace = std::backtrace::Backtrace::force_capture().to_string();
        // By a frame's path or, where inlining left the frame its bare name, its file.
        let whose = if trace.contains("rapier3d::") || trace.contains("rapier3d/src/") {
            &RAPIERS
        } else {
            &OURS
        };
        whose.with(|c| c.set(c.get() + 1));
        CLASSIFYING.with(|c| c.set(false));
    }
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

/// What this project runs every substep inside rapier's step, the patient model, allocates
/// nothing by itself (the whole loop's test is below).
#[test]
fn the_patient_model_allocates_nothing_per_substep() {
    for scenario in ["gait_spastic", "gait_spasms", "gait_resistive"] {
        let loaded = pma_leg::Scenario::load(scenario).expect("scenario");
        let sim = pma_leg::LegSim::new(&loaded).expect("sim");
        let mut patient = sim.plant().patient().expect("a patient").clone();
        let h = sim.exo().substep_s();
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

impl Recorder<pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>> for Counter {
    fn record(
        &mut self,
        _: &Period<'_, pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>>,
    ) {
        self.tick();
    }
}

/// Attributes the allocations of the periods after the 100th to rapier or to us.
#[derive(Default)]
struct Attributing {
    periods: u64,
}

impl Recorder<pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>> for Attributing {
    fn record(
        &mut self,
        _: &Period<'_, pma_leg::SupervisedLeg, pma_leg::PerLeg<pma_leg::LegOutput>>,
    ) {
        self.periods += 1;
        if self.periods == 100 {
            CLASSIFY.with(|c| c.set(true));
        }
    }

    fn end(
        &mut self,
        _: &pma_loop::End<<pma_leg::SupervisedLeg as pma_loop::Backend>::Error>,
        _: f64,
    ) {
        CLASSIFY.with(|c| c.set(false));
    }
}

/// Regression: rapier3d 0.36's `PhysicsWorld::step` allocated 9 (in the air) to 22 (the
/// trainer) times a substep: the multibody's LU factors copied into new matrices, the energy
/// guard's vectors, the solver's generic velocities, its stage cursors and the list of
/// changed bodies. The fork (vendor/rapier3d/PATCHES.md) reuses their storage; with it the
/// whole loop allocates nothing per period.
#[test]
fn the_leg_loop_allocates_nothing_per_period() {
    // Everything in the loop (rapier's step, muscles, valves, controllers, the patient, the
    // belt, the harness, the other leg, the recorders, `simulate --plot`'s gait-cycle bins,
    // the admittance law, the walking patient, the gait's clock and the muscles' implicit
    // damping) after the first 100 periods, which size the buffers: 1.9 s of stance, swing
    // and heel strikes. An allocation is attributed by its backtrace, for the message.
    for scenario in [
        "gait_training",
        "gait_spastic",
        "gait_treadmill_spastic",
        "gait_treadmill",
    ] {
        let mut loaded = pma_leg::Scenario::load(scenario).expect("scenario");
        if scenario == "gait_treadmill" {
            follow_a_walking_patient(&mut loaded.scenario);
        } else if scenario == "gait_spastic" {
            // The in-air leg with its muscles' damping implicit, in one physics step.
            loaded.scenario.physics_substeps = 1;
            loaded.scenario.implicit_muscle_damping = true;
        }
        let mut sim = pma_leg::LegSim::new(&loaded).expect("sim");
        let mut counter = Attributing::default();
        let mut cycles = pma_exo::strides::GaitCycles::new(&sim, 0.0).expect("gait cycles");
        OURS.with(|c| c.set(0));
        RAPIERS.with(|c| c.set(0));
        let result = sim.run(2.0, &mut (&mut counter, &mut cycles));
        CLASSIFY.with(|c| c.set(false));
        result.expect("run");
        assert_eq!(counter.periods, 2000, "{scenario}");
        let ours = OURS.with(Cell::get);
        let rapiers = RAPIERS.with(Cell::get);
        assert_eq!(
            (rapiers, ours),
            (0, 0),
            "{scenario}: periods 100 to 2000 allocated (in rapier, outside it)"
        );
    }
}

/// Admittance mode with a patient who walks on their own timing, the adults' moments left
/// to them and the gait's clock following the legs (docs/cooperative.md).
fn follow_a_walking_patient(sc: &mut pma_leg::scenario::Scenario) {
    sc.control.mode = pma_leg::ControlMode::Admittance;
    let imp = &mut sc.control.impedance;
    imp.hip.stiffness_nm_per_rad = Some(300.0);
    imp.knee.stiffness_nm_per_rad = Some(300.0);
    imp.patient_moment_share = 1.0;
    imp.phase_sync_per_s = 2.0;
    imp.phase_sync_integral_per_s2 = 0.5;
    let active = toml::from_str("own_torque = \"walking\"\nseed = 1").expect("active patient");
    sc.patient.active = Some(active);
}
