//! `rths-core`: the hardware-free mathematics of a real-time hybrid simulation (RTHS) controller.
//!
//! Everything here is `no_std` and allocation-free so that the same code runs in the host simulator,
//! in the emulated MCU and on the real board. Nothing here knows a board, RTIC or `std`.
//!
//! Units follow the prototype structure of the source study: millimetres, kilonewtons, seconds
//! (mass in kN·s²/mm). Every physical constant lives in [`params`].
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

pub mod checksum;
pub mod compensator;
pub mod control;
pub mod filter;
pub mod hal;
pub mod hysteresis;
pub mod identify_excitation;
pub mod identify_session;
pub mod integrator;
pub mod metamodel;
pub mod metrics;
pub mod model;
pub mod motion;
pub mod params;
pub mod predictor_corrector;
pub mod reference;
pub mod structure;
pub mod structure_n;
pub mod structure_nl;
pub mod supervisor;
