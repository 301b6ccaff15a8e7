//! The patient in the exoskeleton: torques the limb's own muscles and tissues put on the
//! hip and the knee. Four parts, each optional per joint (the scenario's `[patient]`):
//!
//! - **spasticity**, a velocity-dependent stretch reflex: above a threshold speed of
//!   stretch, the stretched muscle group resists with a torque proportional to the excess,
//!   after a reflex delay (Kim, Eom & Hase 2011; He, Norling & Wang 1997);
//! - **spasms**, smooth torque pulses with a rapid rise and a slower fall (Thomas & Ross
//!   1997), at seeded Poisson times or at given times;
//! - **voluntary effort**, a fraction of the torque the reference gait needs (its inverse
//!   dynamics), optionally delayed: the patient helps (positive) or resists (negative);
//! - **joint stiffness**, the passive double-exponential moment near the ends of the range
//!   (Anderson 1999, as used by Falisse et al. 2019).
//!
//! Flexion is positive at both joints; a torque is positive when it flexes. The sources and
//! the calibration of the presets are in `docs/patient.md`.

mod model;
mod settings;

pub use model::{Patient, PatientTorques, SpasmEvent};
pub use settings::*;
