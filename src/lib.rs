//! `rths` host library: ground-motion readers, analyses, training, scenarios and reports, used by the
//! `rths` binary and the integration tests.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod analysis;
pub mod benchmark;
pub mod cmd;
pub mod drive;
pub mod faults;
pub mod identify;
pub mod imported;
pub mod link_host;
pub mod model_file;
pub mod models;
pub mod motion;
pub mod nonlinear;
pub mod output;
pub mod plot;
pub mod progress;
pub mod reference;
pub mod robustness;
pub mod scenario;
pub mod site;
pub mod soak;
pub mod study;
pub mod sweep;
pub mod train;
