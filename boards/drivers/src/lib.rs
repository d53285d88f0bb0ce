//! Drivers of the real rig's I/O, generic over embedded-hal 1.0 (`SpiDevice`, `OutputPin`,
//! `InputPin`, `DelayNs`), `no_std`, allocation-free, and tested on the host with
//! `embedded-hal-mock`:
//! - [`ad7606`]: the AD7606 simultaneous-sampling 16-bit ADC (±10 V) for the displacement and force
//!   signals of the servo-controller;
//! - [`ad5754`]: the AD5754R 16-bit bipolar DAC (±10 V) for the servo-controller's command input;
//! - [`calibration`]: which channel is what, volts per mm / per kN, offsets (validated);
//! - [`rig`]: the calibrated rig as `rths_core::hal::{Daq, Actuator}` and the hardware E-stop.
//!
//! The STM32F407 board (`boards/stm32f4`) wires these to its SPI buses and pins.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod ad5754;
pub mod ad7606;
pub mod calibration;
pub mod rig;

pub use calibration::{
    ConverterCalibration, ConverterCalibrationConfig, ConverterCalibrationError, Scale,
};
pub use rig::{check_estop, ActiveLevel, EStop, Rig, RigError};
