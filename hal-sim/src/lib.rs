//! `rths-hal-sim`: the virtual RTHS plant (servo-hydraulic actuator with control-structure
//! interaction, specimen, sensors, converters, faults). `no_std` and allocation-free: it runs on the
//! host and inside the MCU for emulated tests.
//!
//! ```
//! use rths_core::hal::{Actuator, Daq};
//! use rths_hal_sim::{Preset, RigConfig, VirtualRig};
//!
//! let params = RigConfig::new(Preset::UnrCompact).build().unwrap();
//! let mut rig = VirtualRig::new(params);
//! for _ in 0..2048 {
//!     let _sample = rig.read().unwrap();
//!     rig.command(1.0).unwrap(); // mm
//!     rig.advance_tick();
//! }
//! assert!((rig.true_disp_mm() - 1.0).abs() < 0.02);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod fault;
pub mod params;
mod plant;
pub mod rig;
mod zoh;

pub use fault::{Channel, Fault, FaultKind, FaultPlan};
pub use params::{
    BoucWen, ConfigError, Drift, Integration, PlantParams, Preset, Response, RigConfig, Sensors,
    Specimen,
};
pub use rig::{SimError, VirtualRig};
