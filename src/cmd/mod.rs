//! The subcommands of the `rths` binary, one module each.

pub mod analyze;
pub mod benchmark;
pub mod check_model;
pub mod faults;
pub mod identify;
pub mod import;
pub mod link;
pub mod nonlinear_study;
pub mod plant;
pub mod report;
pub mod reproduce;
pub mod robustness;
pub mod simulate;
pub mod simulate_imported;
pub mod site;
pub mod train;
