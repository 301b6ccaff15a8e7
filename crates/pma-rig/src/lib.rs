//! The hardware backend: one pneumatic muscle on a DAQ rig (proportional valve on an
//! analog output, displacement sensor on an analog input), driven by the same controller
//! and the same closed loop (`pma-loop`) as the simulations, safely.
#![warn(missing_docs)]

pub mod backend;
pub mod board;
pub mod comedi;
pub mod config;
pub mod daq;
mod error;
pub mod log;
pub mod replay;
pub mod run;
pub mod timing;
pub mod virtual_daq;

pub use backend::{Pacing, RigBackend, RigTelemetry};
pub use config::RigConfig;
pub use daq::{
    AnalogChannel, Aref, ChannelName, Daq, DaqError, DigitalLine, Direction, OutputHandle,
};
pub use error::RigError;
/// The safety supervisor (pma-control's, shared with the leg).
pub use pma_control::supervisor;
pub use pma_control::supervisor::{Alarm, Fault, Supervised, Watchdog};
pub use replay::{replay, verify, ReplayReport, VerifiedLog};
pub use run::{Rig, RigReport, RunOptions};
pub use virtual_daq::{delivered_valve_pa, InjectedFault, Injection, VirtualDaq};
