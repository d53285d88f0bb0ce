//! The firmware's application logic, independent of any board and of RTIC, so that it is unit-tested
//! on the host (`cargo test -p rths-app`) and runs unchanged on every board.
//!
//! - [`board`]: the traits a board implements (tick timer, link port, instruction counter, E-stop,
//!   and the [`board::Board`] that names them); `boards/qemu` and `boards/stm32f4` implement them.
//! - [`control`]: the controller's work in one tick (the measured section) and its [`TelemetryRecord`].
//! - [`run`]: the run's statistics, updated once per tick.
//! - [`report`]: the `CALIB` and `RESULT` lines of the emulated board.
//! - [`link`]: the command link's request handling and telemetry stream.
//! - [`identify`]: identification through the board: the excitation played by the control task.
//! - [`model_upload`]: chunked model uploads of any kind (LRX, RNN of any size, FE + ATS),
//!   validated on the device; [`chunks`]: the chunk bookkeeping it shares with [`record`];
//!   [`tick_cost`]: whether the board's tick can run an uploaded model.
//! - [`rig_upload`]: the rig compensation upload (LRX lead and specimen dynamics, ATS start).
//! - [`site`]: the board as an experimental site (targets streamed over the link).
//! - [`record`]: the ground-motion record in force (compiled in or uploaded) and upload validation.
//!
//! The firmware binary (`firmware/src/main.rs`) is the RTIC shell around these.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod board;
pub mod chunks;
pub mod control;
pub mod identify;
pub mod link;
pub mod model_upload;
pub mod record;
pub mod report;
pub mod rig_upload;
pub mod run;
pub mod site;
pub mod tick_cost;

pub use control::{control_step, TelemetryRecord};
pub use run::Run;

/// Ticks in one second of test time (the controller rate): the fault hold that ends a faulted run,
/// and the defmt log's decimation.
pub const ONE_SECOND_TICKS: u32 = rths_core::params::CONTROL_RATE_HZ;
