//! `rths` host library, used by the `rths` binary and the integration tests. Three layers, imports
//! running one way (`tests/layers.rs` checks it, and that no two files import from each other):
//!
//! - [`cmd`]: one module per subcommand, on top;
//! - [`studies`]: what is measured and reported (the scenarios, the study, the sweep, robustness,
//!   the vRTHS benchmark, the nonlinear study, faults, soak, the pure analysis);
//! - [`machinery`]: what the studies run on (the host's driver of core's controller, the plant's
//!   configuration and the reference, ground motions, output, figures and progress, model files,
//!   training, identification, imported and yielding structures, the experimental site); with
//!   [`link_host`], the command link to a board.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod cmd;
pub mod link_host;
pub mod machinery;
pub mod studies;
