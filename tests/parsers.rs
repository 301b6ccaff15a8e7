//! Every parser of a user's file fed arbitrary values and structures: the shipped files
//! mutated at random (a leaf replaced by NaN, an infinity, a huge or negative number, a
//! string, an array or a table; a key removed; an unknown key added). The result must be
//! an `Ok` that survives building what it describes, or a one-line error; never a panic,
//! an abort or an allocation beyond a bound (this binary's allocator refuses any single
//! allocation above 256 MiB, which aborts the test).
use pma_bench::{MuscleBench, PlantConfig};
use pma_control::ControllerConfig;
use pma_leg::plant::parse_muscles;
use pma_leg::scenario::{EMBEDDED_MUSCLES, EMBEDDED_SCENARIOS};
use pma_leg::{LegSim, LoadedScenario, Scenario};
use pma_rig::config::{EMBEDDED_PCI6052E, EMBEDDED_VIRTUAL};
use pma_rig::{RigConfig, VirtualDaq};
use pma_studies::sweep::Sweep;
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;

/// Refuses (null, hence an abort) any single allocation above the bound.
struct Bounded;

const MAX_ALLOCATION: usize = 256 << 20;

// SAFETY: forwards to the system allocator; refusing an allocation is allowed.
unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > MAX_ALLOCATION {
            return std::ptr::null_mut();
        }
        // SAFETY: same layout, same contract.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: allocated above with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > MAX_ALLOCATION {
            return std::ptr::null_mut();
        }
        // SAFETY: same contract as the system allocator's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Bounded = Bounded;

/// A value a user might type (or a fuzzer might find).
fn any_value() -> impl Strategy<Value = toml::Value> {
    let number = prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-1.0),
        Just(1e300),
        Just(-1e300),
        Just(1e9),
        Just(1e-12),
        any::<f64>(),
        -1e3..1e3f64,
    ]
    .prop_map(toml::Value::Float);
    let integer = prop_oneof![
        Just(i64::MAX),
        Just(i64::MIN),
        Just(0i64),
        Just(-1),
        Just(4_294_967_295),
        Just(100_000_000),
        any::<i64>(),
    ]
    .prop_map(toml::Value::Integer);
    let text = prop_oneof![
        Just(String::new()),
        Just("nan".to_owned()),
        Just("../../etc/passwd".to_owned()),
        Just("x.toml".to_owned()),
        "[a-z_@+=.0-9]{0,12}",
    ]
    .prop_map(toml::Value::String);
    let leaf = prop_oneof![
        number,
        integer,
        text,
        any::<bool>().prop_map(toml::Value::Boolean)
    ];
    leaf.prop_recursive(2, 8, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(toml::Value::Array),
            prop::collection::btree_map("[a-z_]{1,8}", inner, 0..3)
                .prop_map(|m| toml::Value::Table(m.into_iter().collect())),
        ]
    })
}

/// One change to a document.
#[derive(Debug, Clone)]
enum Mutation {
    /// Replace the leaf (or table) at this index of the walk by a value.
    Replace(usize, toml::Value),
    /// Remove the key at this index of the walk.
    Remove(usize),
    /// Add an unknown key to the table at this index of the walk.
    Add(usize, String, toml::Value),
}

fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    let one = prop_oneof![
        (any::<usize>(), any_value()).prop_map(|(i, v)| Mutation::Replace(i, v)),
        any::<usize>().prop_map(Mutation::Remove),
        (any::<usize>(), "[a-z_]{1,10}", any_value()).prop_map(|(i, k, v)| Mutation::Add(i, k, v)),
    ];
    prop::collection::vec(one, 1..4)
}

/// The paths of every key in a document, depth first (array elements as `#n`).
fn walk(v: &toml::Value, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        toml::Value::Table(t) => {
            for (k, child) in t {
                prefix.push(k.clone());
                out.push(prefix.clone());
                walk(child, prefix, out);
                prefix.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                prefix.push(format!("#{i}"));
                out.push(prefix.clone());
                walk(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn slot<'v>(root: &'v mut toml::Value, path: &[String]) -> Option<&'v mut toml::Value> {
    let mut v = root;
    for key in path {
        v = match (v, key.strip_prefix('#')) {
            (toml::Value::Array(a), Some(i)) => a.get_mut(i.parse::<usize>().ok()?)?,
            (toml::Value::Table(t), None) => t.get_mut(key)?,
            _ => return None,
        };
    }
    Some(v)
}

fn apply(text: &str, mutations: &[Mutation]) -> String {
    let mut doc: toml::Value = toml::from_str(text).expect("shipped file parses");
    for m in mutations {
        let mut paths = Vec::new();
        walk(&doc, &mut Vec::new(), &mut paths);
        if paths.is_empty() {
            break;
        }
        match m {
            Mutation::Replace(i, value) => {
                if let Some(v) = slot(&mut doc, &paths[i % paths.len()]) {
                    *v = value.clone();
                }
            }
            Mutation::Remove(i) => {
                let path = &paths[i % paths.len()];
                let (last, parent) = path.split_last().expect("non-empty path");
                match (slot(&mut doc, parent), last.strip_prefix('#')) {
                    (Some(toml::Value::Table(t)), None) => {
                        t.remove(last);
                    }
                    (Some(toml::Value::Array(a)), Some(k)) => {
                        if let Ok(k) = k.parse::<usize>() {
                            if k < a.len() {
                                a.remove(k);
                            }
                        }
                    }
                    _ => {}
                }
            }
            Mutation::Add(i, key, value) => {
                let path = &paths[i % paths.len()];
                if let Some(toml::Value::Table(t)) = slot(&mut doc, path) {
                    t.insert(key.clone(), value.clone());
                }
            }
        }
    }
    toml::to_string(&doc).unwrap_or_default()
}

fn assert_one_line(e: &dyn std::fmt::Display) {
    let s = e.to_string();
    assert!(!s.trim_end().contains('\n'), "multi-line error: {s}");
    assert!(!s.is_empty());
}

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

const PLANTS: [&str; 4] = [
    include_str!("../crates/pma-bench/models/plants/ideal.toml"),
    include_str!("../crates/pma-bench/models/plants/mismatch.toml"),
    include_str!("../crates/pma-bench/models/plants/realistic.toml"),
    include_str!("../crates/pma-bench/models/plants/realistic_known_lag.toml"),
];

const GAINS: [&str; 4] = [
    include_str!("../crates/pma-control/models/gains/aprc-ndo-paper.toml"),
    include_str!("../crates/pma-control/models/gains/pid.toml"),
    include_str!("../crates/pma-control/models/gains/psmc.toml"),
    include_str!("../crates/pma-control/models/gains/sta.toml"),
];

const SWEEPS: [&str; 4] = [
    include_str!("../crates/pma-studies/models/sweeps/shocks.toml"),
    include_str!("../crates/pma-studies/models/sweeps/fig9.toml"),
    include_str!("../crates/pma-studies/models/sweeps/monte_carlo.toml"),
    include_str!("../crates/pma-studies/models/sweeps/leg_patients.toml"),
];

proptest! {
    #![proptest_config(config())]

    #[test]
    fn plant_files_parse_into_a_plant_that_builds_or_a_one_line_error(
        which in 0..PLANTS.len(), m in mutations()
    ) {
        let text = apply(PLANTS[which], &m);
        match PlantConfig::from_toml_str(&text, "fuzz.toml") {
            Ok(plant) => {
                prop_assert!(plant.validate().is_ok());
                MuscleBench::at_rest(&plant, 0.01).map(drop).unwrap_or_else(|e| assert_one_line(&e));
            }
            Err(e) => assert_one_line(&e),
        }
    }

    #[test]
    fn gain_files_parse_into_valid_gains_or_a_one_line_error(
        which in 0..GAINS.len(), m in mutations()
    ) {
        let text = apply(GAINS[which], &m);
        match ControllerConfig::from_toml_str(&text) {
            Ok(c) => prop_assert!(c.validate().is_ok()),
            Err(e) => assert_one_line(&e),
        }
    }

    #[test]
    fn sweep_files_expand_within_bounds_or_give_a_one_line_error(
        which in 0..SWEEPS.len(), m in mutations()
    ) {
        let text = apply(SWEEPS[which], &m);
        match Sweep::from_toml_str(&text, "fuzz.toml", Path::new("models/sweeps")) {
            Ok(s) => {
                prop_assert!(!s.jobs.is_empty() && s.jobs.len() <= pma_studies::sweep::MAX_RUNS);
                for p in s.bench_points().take(3) {
                    p.resolve_plant().map(drop).unwrap_or_else(|e| assert_one_line(&e));
                }
                for j in s.jobs.iter().take(3) {
                    if let pma_studies::sweep::Job::Leg(p) = j {
                        prop_assert!(p.scenario().validate().is_ok());
                    }
                }
            }
            Err(e) => assert_one_line(&e),
        }
    }

    #[test]
    fn rig_configurations_validate_and_build_the_virtual_rig_or_give_a_one_line_error(
        which in 0..2usize, m in mutations()
    ) {
        let base = [EMBEDDED_VIRTUAL, EMBEDDED_PCI6052E][which];
        let text = apply(base, &m);
        match RigConfig::from_toml_str(&text, "fuzz.toml") {
            Ok(cfg) => {
                prop_assert!(cfg.validate().is_ok());
                if cfg.virtual_rig.is_some() {
                    VirtualDaq::new(&cfg, &[]).map(drop).unwrap_or_else(|e| assert_one_line(&e));
                }
            }
            Err(e) => assert_one_line(&e),
        }
    }

    #[test]
    fn muscle_geometry_files_parse_or_give_a_one_line_error(m in mutations()) {
        let text = apply(EMBEDDED_MUSCLES, &m);
        if let Err(e) = parse_muscles(&text, "fuzz.toml") {
            assert_one_line(&e);
        }
    }
}

proptest! {
    // Building a leg costs a rapier world: fewer cases.
    #![proptest_config(ProptestConfig { cases: 48, ..config() })]

    #[test]
    fn scenarios_and_their_patients_build_a_leg_or_give_a_one_line_error(
        which in 0..EMBEDDED_SCENARIOS.len(), m in mutations()
    ) {
        let (name, base) = EMBEDDED_SCENARIOS[which];
        let text = apply(base, &m);
        match Scenario::from_toml_str(&text, &format!("{name}.toml")) {
            Ok(scenario) => {
                prop_assert!(scenario.validate().is_ok());
                let mut loaded: LoadedScenario = Scenario::load(name).expect("embedded");
                loaded.scenario = scenario;
                match LegSim::new(&loaded) {
                    Ok(mut sim) => {
                        // A few periods: whatever the values, the run ends or fails in one line.
                        let d = 0.05f64.max(loaded.scenario.period_s);
                        if let Err(e) = sim.run(d, &mut ()) {
                            assert_one_line(&e);
                        }
                    }
                    Err(e) => assert_one_line(&e),
                }
            }
            Err(e) => assert_one_line(&e),
        }
    }
}
