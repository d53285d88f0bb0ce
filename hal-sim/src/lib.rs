//! `rths-hal-sim`: the virtual RTHS plant (servo-hydraulic actuator, specimen, sensors, faults).
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
