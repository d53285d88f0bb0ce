//! What is measured and reported, on the [`crate::machinery`] (never the other way round); the
//! commands ([`crate::cmd`]) run them.
//!
//! - [`scenario`]: the hybrid-simulation scenarios of the paper's frame (`rths simulate`);
//! - [`study`]: `rths reproduce`, the whole study; [`sweep`]: its specimen sweep;
//! - [`robustness`]: `rths robustness`, the Monte-Carlo study;
//! - [`benchmark`]: `rths benchmark`, the vRTHS benchmark problem;
//! - [`nonlinear`]: structure files' scenarios and `rths nonlinear-study`;
//! - [`imported_hybrid`]: an imported structure in the hybrid loop (`meta-online`);
//! - [`faults`], [`soak`]: the fault-injection matrix, the long run;
//! - [`analysis`]: `rths analyze`, the pure FE analysis.

pub mod analysis;
pub mod benchmark;
pub mod faults;
pub mod imported_hybrid;
pub mod nonlinear;
pub mod robustness;
pub mod scenario;
pub mod soak;
pub mod study;
pub mod sweep;
