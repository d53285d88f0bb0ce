//! Metamodel inference (docs/design.md §5): the linear-regression (LR) model of the paper's Eq. 6 with a bias,
//! a basic Elman RNN, and the specimen-faithful LRX, one file each (`lr.rs`, `rnn.rs`, `lrx.rs`), and the structure
//! metamodel of an N-DOF numerical substructure (`delta_arx.rs`), the reduced modal model of a large linear
//! one (`reduced_modal.rs`), and the learned models of a yielding one (`modal_hyst.rs`,
//! `floor_hysteron.rs` with its Menegotto–Pinto play `mp_play.rs`); the two modal models share Chang's
//! modal integrator (`modal_chang.rs`). Training
//! lives on the host; this is the `no_std`, allocation-free inference the firmware runs at 2048 Hz.
//!
//! Units of every feature: ground acceleration ü_g in mm/s², measured brace deformation x_fb in mm
//! (prototype scale = actuator stroke), prototype brace axial force F_fb in kN (= 1000 × load cell),
//! output x̂ = brace deformation command in mm.
//!
//! Non-finite input policy: a NaN or infinite feature (or a prediction that would overflow) is
//! *refused* with [`InputError`] and the recurrent state is left exactly as it was, so one bad sample
//! cannot poison the model forever. The caller (the supervisor) is expected to trip on the refusal;
//! if it chooses to continue, the next valid sample continues from the last good state.

pub use crate::filter::InputError;
use crate::params::ParamError;

mod delta_arx;
mod floor_hysteron;
mod lr;
mod lrx;
mod modal_chang;
mod modal_hyst;
mod mp_play;
mod reduced_modal;
mod rnn;

pub use delta_arx::*;
pub use floor_hysteron::*;
pub use lr::*;
pub use lrx::*;
pub use modal_hyst::*;
pub use mp_play::*;
pub use reduced_modal::*;
pub use rnn::*;

/// A model whose shape or values failed validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelError {
    /// A weight array has the wrong number of elements.
    Shape {
        /// Which array.
        what: &'static str,
        /// Elements required by the model's sizes.
        expected: usize,
        /// Elements supplied.
        got: usize,
    },
    /// The RNN hidden size is not in 1..=[`RNN_MAX_HIDDEN`].
    HiddenSize(usize),
    /// A value failed validation (non-finite weight, non-positive std).
    Param(ParamError),
}

impl From<ParamError> for ModelError {
    fn from(e: ParamError) -> Self {
        ModelError::Param(e)
    }
}

impl core::fmt::Display for ModelError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ModelError::Shape {
                what,
                expected,
                got,
            } => {
                write!(f, "{what} has {got} elements, expected {expected}")
            }
            ModelError::HiddenSize(h) => {
                write!(f, "hidden size {h} is not in 1..={RNN_MAX_HIDDEN}")
            }
            ModelError::Param(e) => write!(f, "{e}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ModelError {}

/// A ground acceleration to start from: a non-finite value counts as 0 (a model's `reset_at`).
pub(crate) fn start_accel_mm_s2(ground_accel_mm_s2: f64) -> f64 {
    if ground_accel_mm_s2.is_finite() {
        ground_accel_mm_s2
    } else {
        0.0
    }
}

pub(crate) fn all_finite(values: &[f64], what: &'static str) -> Result<(), ParamError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ParamError::NotFinite(what))
    }
}

pub(crate) fn shape(values: &[f64], expected: usize, what: &'static str) -> Result<(), ModelError> {
    if values.len() == expected {
        Ok(())
    } else {
        Err(ModelError::Shape {
            what,
            expected,
            got: values.len(),
        })
    }
}

#[cfg(test)]
mod tests;
