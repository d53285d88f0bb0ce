//! A numerical substructure the host computes (core's `std` feature only; the firmware builds
//! without it): an analytical part too large for core's fixed-size types, e.g. an imported OpenSees
//! model's sparse finite elements (`rths::machinery::imported`), held behind [`HostNumerical`] so
//! that it runs in the one [`super::Controller`] like every other part. Core knows the trait only.
//!
//! The contract is a structure part's (`super::StructureFe`'s): at tick 0 the part is at rest; at
//! tick k it completes step k with `ü_g(k)` and the specimen's force measured at the target it gave
//! at tick k − 1, and returns the next target at the interface from those known quantities only
//! (the command is sent before the force at it is measured).

use std::boxed::Box;

use super::StepError;

/// A host numerical substructure in the hybrid loop (see the module's contract). Implementations
/// never panic: a non-finite input is refused before it touches the state.
pub trait HostNumerical: core::fmt::Debug + Send {
    /// Tick k: complete step k with `ü_g(k)` (mm/s²) and the specimen's force at the interface
    /// (kN, the structure's units), return the target displacement at the interface for k + 1, mm.
    fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, StepError>;
    /// The interface's displacement at the last completed step, mm.
    fn interface_disp_mm(&self) -> f64;
    /// How many output read-outs the part has (the structure's outputs).
    fn output_count(&self) -> usize;
    /// Output `i`'s displacement at the last completed step, mm; `None` past them.
    fn output_disp_mm(&self, i: usize) -> Option<f64>;
    /// Back to rest, parameters kept.
    fn reset(&mut self);
    /// A copy (parameters and state): what [`Clone`] of a controller needs.
    fn boxed_clone(&self) -> Box<dyn HostNumerical>;
}

/// The analytical part of a host numerical substructure: a boxed [`HostNumerical`].
#[derive(Debug)]
pub struct StructureHost(Box<dyn HostNumerical>);

impl StructureHost {
    /// The part `part`.
    pub fn new(part: Box<dyn HostNumerical>) -> Self {
        Self(part)
    }

    /// The host part.
    pub fn part(&self) -> &dyn HostNumerical {
        self.0.as_ref()
    }

    pub(super) fn part_mut(&mut self) -> &mut dyn HostNumerical {
        self.0.as_mut()
    }
}

impl Clone for StructureHost {
    fn clone(&self) -> Self {
        Self(self.0.boxed_clone())
    }
}

impl PartialEq for StructureHost {
    /// The same part (one box), not equal values: a host part's matrices are not compared.
    fn eq(&self, other: &Self) -> bool {
        core::ptr::addr_eq(self.0.as_ref(), other.0.as_ref())
    }
}

#[cfg(test)]
mod tests;
