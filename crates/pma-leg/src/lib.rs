//! The exoskeleton leg: a URDF loaded into rapier3d as a multibody, a flexor and an
//! extensor pneumatic muscle on the hip and on the knee, each muscle the three-element
//! model of `pma-model` (or a Festo size as measured) driven by its own APRC-NDO from
//! `pma-control`, tracking length references derived from normative gait; the pelvis
//! fixed (the leg swings in the air) or on body-weight support with the foot on a
//! treadmill belt ([`ground`], [`metrics`]).
//!
//! The modules are layers, each importing only from those before it in this chain (the
//! workspace's `tests/architecture.rs` reads it here and checks every import; every module
//! is in it; docs/ARCHITECTURE.md draws it): [`base`] -> [`gait`] ->
//! [`ground`] -> [`body`] -> [`patient`] -> [`plant`] -> [`control`] -> [`metrics`] ->
//! [`scenario`] -> [`sim`] -> [`tools`]. Each settings type lives beside the code that
//! reads it; the scenario is a struct of them.
#![warn(missing_docs)]

pub mod base;
pub mod body;
pub mod control;
pub mod gait;
pub mod ground;
pub mod metrics;
pub mod patient;
pub mod plant;
pub mod scenario;
pub mod sim;
pub mod tools;

pub use base::{LegError, LegFault, PerLeg, MAX_LEGS, SIDES};
pub use body::{Exoskeleton, LegInertia, Mount, VisualShape};
pub use control::{
    ControlMode, ImpedanceLaw, ImpedanceSettings, JointImpedance, LegControllers, LegOutput,
    MusclePair, TrainerControllers, Vented,
};
pub use metrics::{
    FootMetrics, FootReport, JointStats, LegMetrics, LegPeriod, LegRecorder, LegReport,
    MuscleStats, OnLeg, PatientMetrics, PatientReport, SafetyReport, SpasmReport, StrideSpread,
    TreadmillReport, WalkingCriteria, WalkingVerdict,
};
pub use patient::{Patient, PatientSettings, PatientTorques, SpasmEvent};
pub use plant::{
    LegPlant, LegReading, LegState, MuscleActuator, MuscleGeometry, Side, SupervisedLeg,
    TrainerState,
};
pub use scenario::{LoadedScenario, Scenario};
pub use sim::{balanced_pressures, FootSample, GroundSample, LegSample, LegSim, TrainerSample};
pub use tools::{fit_gait, GaitFit, GaitFitSettings, GaitFitStep};
