//! Why an identification did not produce a rig file: the one error of `rths identify`'s runner,
//! excitation and estimators.

/// Why an identification did not produce a rig file.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// A setting is out of range.
    #[error("invalid setting: {0}")]
    Setting(String),
    /// The supervisor tripped: the excitation was stopped and the actuator ramped to safety.
    #[error("the supervisor tripped ({reason}) at {time_s:.3} s: excitation stopped")]
    Tripped {
        /// The supervisor's fault reason.
        reason: String,
        /// Time of the trip, s.
        time_s: f64,
    },
    /// The data do not characterize the rig well enough.
    #[error("refused: {0}")]
    Refused(String),
    /// The virtual plant's configuration is invalid.
    #[error("invalid plant configuration: {0}")]
    Plant(String),
}
