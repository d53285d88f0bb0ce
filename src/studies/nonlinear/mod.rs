//! The scenarios of a structure file (`rths simulate --structure`) and the nonlinear scoring
//! study (`rths nonlinear-study`), on the structure machinery (`crate::machinery::structure`: the
//! yielding structure's reference, its learned model, the rig compensation; docs/nonlinear.md).

pub mod held_out;
pub mod scenario;
pub mod study;
