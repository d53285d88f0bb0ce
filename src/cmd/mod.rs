//! The subcommands of the `rths` binary, one module each.

pub mod analyze;
pub mod plant;
pub mod train;
