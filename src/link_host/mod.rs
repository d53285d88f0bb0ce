//! The host side of the command link (`rths link`): open a serial port, a TCP socket (QEMU's serial
//! port on 127.0.0.1) or a QEMU process of our own, send requests, wait for their answers, and record
//! the telemetry stream with its sequence numbers checked. The protocol is `rths-link`'s.
//!
//! One job a file, imports running one way (down this list):
//! - [`qemu`]: the QEMU process of the emulated board, its link on a loopback socket;
//! - [`session`]: a session with a device (requests and answers, uploads, runs, telemetry);
//! - [`stream`]: a streamed record's flow control (which chunks to send now, what again);
//! - [`wire`]: the wire layout of uploaded models, records and rig compensations, and the names of
//!   what the device reports;
//! - [`recording`]: the recording file format (`rths link run --out`, `rths report`);
//! - [`transport`]: the byte streams (TCP, serial);
//! - [`error`]: the link's errors.

pub mod error;
pub mod qemu;
pub mod recording;
pub mod session;
pub mod stream;
pub mod transport;
pub mod wire;

pub use error::LinkHostError;
pub use qemu::{qemu_args, Qemu};
pub use recording::{
    check_named_file, csv_row, first_unclean_sample, read_recording, read_recording_file,
    Recording, RecordingError, RecordingRow, RunHeader, UncleanSample, CSV_HEADER,
    MAX_NAMED_FILE_BYTES, MAX_RECORDING_BYTES, RECORDING_FORMAT,
};
pub use session::{IdentifyStream, Link, RecordSummary};
pub use transport::Port;
pub use wire::{
    fault_name, laid_out_messages, lrx_rig_extras, model_kind_name, model_messages, model_values,
    record_messages, record_source_name, rig_message, rig_messages, rig_values, state_name,
    stream_messages, structure_rig_values, upload_message,
};
