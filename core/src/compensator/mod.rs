//! Actuator delay compensators of the classic FE path (docs/design.md §6): adaptive time series (ATS), Horiuchi
//! polynomial extrapolation, and none. `no_std`, allocation-free, panic-free.
//!
//! All compensators map a target displacement x_t (mm, the integrator's command) and the measured
//! displacement x_m (mm, LVDT) to the displacement u_c sent to the actuator. Inputs that are NaN or
//! infinite (and, for ATS and Horiuchi, beyond [`MAX_ABS_INPUT_MM`]) are refused with [`InputError`]
//! and leave the state untouched.
//!
//! One file per method: `ats.rs` (adaptive time series), `horiuchi.rs` (polynomial extrapolation),
//! `lead.rs` (learned lead filter), `lead_adapt.rs` (its online correction); this file holds the shared input guard and the [`Compensator`] enum.

use crate::filter::{finite, InputError};

mod ats;
mod horiuchi;
mod lead;
mod lead_adapt;

pub use ats::*;
pub use horiuchi::*;
pub use lead::*;
pub use lead_adapt::*;

/// Largest admissible |target| or |measured| displacement, mm. Far beyond any stroke (±25.4 mm); it only
/// keeps every intermediate (ẍ ≈ x·4/Δt², its square times the window) well inside f64 range, so a
/// finite accepted input always yields finite sums and a finite command.
pub const MAX_ABS_INPUT_MM: f64 = 1.0e6;

pub(crate) fn input(value: f64, what: &'static str) -> Result<f64, InputError> {
    let v = finite(value, what)?;
    if v.abs() > MAX_ABS_INPUT_MM {
        Err(InputError::OutOfRange(what))
    } else {
        Ok(v)
    }
}

/// The compensator of a run.
// Boxing the ~33 KiB ATS is not possible without an allocator; the enum lives in a static/resource.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Compensator {
    /// Command = target.
    None,
    /// Polynomial extrapolation of the target.
    Horiuchi(Horiuchi),
    /// Adaptive time series.
    Ats(Ats),
    /// Learned (fixed) lead filter.
    Lead(Lead),
}

impl Compensator {
    /// Command (mm) for this tick. Every variant refuses a non-finite or out-of-range target *or*
    /// measured displacement (even those that ignore x_m), so the supervisor sees a bad sensor the same
    /// way whatever the compensator.
    pub fn compensate(&mut self, target_mm: f64, measured_mm: f64) -> Result<f64, InputError> {
        match self {
            // Nothing to compute: only refuse what is not a number (the supervisor trips on it).
            Compensator::None => {
                finite(measured_mm, "measured_mm")?;
                finite(target_mm, "target_mm")
            }
            Compensator::Horiuchi(h) => {
                input(measured_mm, "measured_mm")?;
                h.compensate(target_mm)
            }
            Compensator::Ats(a) => a.compensate(target_mm, measured_mm),
            Compensator::Lead(l) => l.step(target_mm, measured_mm),
        }
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        match self {
            Compensator::None => {}
            Compensator::Horiuchi(h) => h.reset(),
            Compensator::Ats(a) => a.reset(),
            Compensator::Lead(l) => l.reset(),
        }
    }
}

#[cfg(test)]
mod lead_adapt_tests;
#[cfg(test)]
mod tests;
