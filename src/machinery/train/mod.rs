//! Offline training of the metamodels (docs/design.md §5): training data from the pure finite-element response
//! ([`data`]), the linear regression fitted by SVD least squares ([`lr`]) and the Elman RNN trained by
//! truncated BPTT with Adam ([`rnn`]), the nonlinear modal-hysteretic model by CMA-ES on FE runs of a
//! yielding structure ([`nonlinear`]). The results are written as [`crate::machinery::model_file::ModelFile`]s.

pub mod data;
pub mod lr;
pub mod lrx;
pub mod lstsq;
pub mod nonlinear;
pub mod pure;
pub mod rnn;

use rths_core::metrics::MetricError;
use rths_core::params::ParamError;

/// Why training or evaluation failed.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Invalid structural parameters or time step.
    #[error("invalid parameters: {0}")]
    Param(#[from] ParamError),
    /// A metric could not be computed (empty, non-finite or zero reference).
    #[error("metric: {0}")]
    Metric(#[from] MetricError),
    /// The ground motion is too short for the requested delay or split.
    #[error("ground motion too short: {found} steps, need at least {needed}")]
    TooShort {
        /// Steps given.
        found: usize,
        /// Steps needed.
        needed: usize,
    },
    /// The ground motion holds NaN or infinity.
    #[error("ground acceleration is not finite at step {0}")]
    NonFiniteInput(usize),
    /// A hyper-parameter is out of range.
    #[error("invalid setting: {0}")]
    Setting(String),
    /// The fit or the training diverged.
    #[error("training diverged: {0}")]
    Diverged(String),
}
