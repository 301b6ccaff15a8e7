//! The exoskeleton leg: a URDF loaded into rapier3d as a multibody, a flexor and an
//! extensor pneumatic muscle on the hip and on the knee, each muscle the three-element
//! model of `pma-model` (or a Festo size as measured) driven by its own APRC-NDO from
//! `pma-control`, tracking length references derived from normative gait; the pelvis
//! fixed (the leg swings in the air) or on body-weight support with the foot on a
//! treadmill belt ([`ground`], [`stance`]).
#![warn(missing_docs)]

pub mod admittance;
pub mod config;
pub mod control;
pub mod cooperative;
pub mod demand;
mod error;
pub mod exoskeleton;
pub mod gains;
pub mod gait;
pub mod gait_fit;
pub mod ground;
pub mod impedance;
pub mod legs;
pub mod metrics;
pub mod patient;
pub mod phase_sync;
pub mod plant;
pub mod probe;
pub mod safety;
pub mod sim;
pub mod sizing;
pub mod stance;
pub mod verdict;

pub use config::{LoadedScenario, MuscleGeometry, Scenario, Side};
pub use control::{LegControllers, LegOutput, TrainerControllers, Vented};
pub use error::LegError;
pub use exoskeleton::{Exoskeleton, LegInertia, Mount, VisualShape};
pub use gait_fit::{fit_gait, GaitFit, GaitFitSettings, GaitFitStep};
pub use impedance::{ControlMode, ImpedanceLaw, ImpedanceSettings, JointImpedance, MusclePair};
pub use legs::{PerLeg, MAX_LEGS, SIDES};
pub use metrics::{JointStats, LegMetrics, LegPeriod, LegRecorder, LegReport, MuscleStats, OnLeg};
pub use patient::{Patient, PatientSettings, PatientTorques, SpasmEvent};
pub use plant::{LegPlant, LegReading, LegState, MuscleActuator, SupervisedLeg, TrainerState};
pub use safety::{PatientMetrics, PatientReport, SafetyReport, SpasmReport};
pub use sim::{
    balanced_pressures, FootSample, GroundSample, LegFault, LegSample, LegSim, TrainerSample,
};
pub use stance::{FootMetrics, FootReport, TreadmillReport};
pub use verdict::{WalkingCriteria, WalkingVerdict};
