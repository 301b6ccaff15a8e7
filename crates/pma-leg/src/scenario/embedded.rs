/// The embedded muscle geometry (`crates/pma-leg/models/muscles.toml`).
pub const EMBEDDED_MUSCLES: &str = include_str!("../../models/muscles.toml");

/// The embedded treadmill muscles (`crates/pma-leg/models/muscles_treadmill.toml`): Festo
/// sizes and pulleys from `pma-exo size gait_treadmill_spastic`.
pub const EMBEDDED_TREADMILL_MUSCLES: &str = include_str!("../../models/muscles_treadmill.toml");

/// The embedded default scenario (`crates/pma-leg/models/scenarios/gait_training.toml`).
pub const EMBEDDED_GAIT_TRAINING: &str = include_str!("../../models/scenarios/gait_training.toml");

/// The embedded realistic scenario (`crates/pma-leg/models/scenarios/gait_realistic.toml`).
pub const EMBEDDED_GAIT_REALISTIC: &str =
    include_str!("../../models/scenarios/gait_realistic.toml");

/// Every embedded scenario: name and text (`crates/pma-leg/models/scenarios/<name>.toml`).
pub const EMBEDDED_SCENARIOS: [(&str, &str); 10] = [
    ("gait_training", EMBEDDED_GAIT_TRAINING),
    ("gait_realistic", EMBEDDED_GAIT_REALISTIC),
    (
        "gait_spastic",
        include_str!("../../models/scenarios/gait_spastic.toml"),
    ),
    (
        "gait_spasms",
        include_str!("../../models/scenarios/gait_spasms.toml"),
    ),
    (
        "gait_resistive",
        include_str!("../../models/scenarios/gait_resistive.toml"),
    ),
    (
        "gait_active",
        include_str!("../../models/scenarios/gait_active.toml"),
    ),
    (
        "gait_treadmill",
        include_str!("../../models/scenarios/gait_treadmill.toml"),
    ),
    (
        "gait_treadmill_spastic",
        include_str!("../../models/scenarios/gait_treadmill_spastic.toml"),
    ),
    (
        "gait_treadmill_unsupported",
        include_str!("../../models/scenarios/gait_treadmill_unsupported.toml"),
    ),
    (
        "gait_treadmill_one_leg",
        include_str!("../../models/scenarios/gait_treadmill_one_leg.toml"),
    ),
];

/// The embedded scenarios' names, for help texts and messages.
pub const EMBEDDED_SCENARIO_NAMES: &str = "gait_training, gait_realistic, gait_spastic, gait_spasms, gait_resistive, gait_active, gait_treadmill, gait_treadmill_spastic, gait_treadmill_unsupported, gait_treadmill_one_leg";

pub(crate) fn embedded_text(name: &str) -> Option<&'static str> {
    EMBEDDED_SCENARIOS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
}
