//! What can go wrong on the host side of the link.

use std::time::Duration;

use rths_link::{DeviceMsg, LinkError, NackReason, Request};

/// A failure of the host side of the link.
#[derive(Debug, thiserror::Error)]
pub enum LinkHostError {
    /// Reading or writing the port failed.
    #[error("link I/O: {0}")]
    Io(#[from] std::io::Error),
    /// Opening the serial port failed.
    #[error("serial port {path}: {message}")]
    Serial {
        /// The device path.
        path: String,
        /// What the OS said.
        message: String,
    },
    /// No answer in time.
    #[error("no answer from the device within {0:?} ({1})")]
    Timeout(Duration, &'static str),
    /// The device refused the request; nothing changed on it.
    #[error("the device refused {0:?}: {1:?}")]
    Refused(Request, NackReason),
    /// The device answered something else than expected.
    #[error("unexpected answer to {0:?}: {1:?}")]
    Unexpected(Request, DeviceMsg),
    /// A frame could not be built.
    #[error("frame: {0}")]
    Frame(LinkError),
    /// The model file cannot be sent (not LR, wrong shape or delay).
    #[error("model: {0}")]
    Model(String),
    /// The ground-motion record cannot be sent (empty, not finite, too long for the protocol).
    #[error("ground motion: {0}")]
    Motion(String),
    /// QEMU could not be started or stopped early.
    #[error("qemu: {0}")]
    Qemu(String),
}
