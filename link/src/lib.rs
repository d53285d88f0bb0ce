//! The rths command link: the messages between the host (`rths link`) and the controller board, and
//! their framing on a byte stream (a UART, QEMU's serial port on a TCP socket, a pty).
//!
//! **Frame** = COBS(postcard(message) ‖ CRC-16/IBM-SDLC(postcard bytes), little-endian) followed by a
//! `0x00` delimiter. COBS removes every zero from the frame body, so a receiver resynchronizes at the
//! next zero after any corruption or a lost byte; the CRC rejects a damaged body (a single error
//! burst of ≤ 16 bits always, anything else with probability 1 − 2⁻¹⁶); postcard is the compact
//! serde encoding (varints, f64 as 8 little-endian bytes, so floats arrive bit-exact).
//!
//! **Conversation**: the host sends a [`HostMsg`]; the device answers each one with exactly one
//! [`DeviceMsg::Ack`], [`DeviceMsg::Nack`] or [`DeviceMsg::Status`]. While a run is armed or running
//! the device also streams [`DeviceMsg::Telemetry`] records, numbered by `seq` from 0 for each run
//! with no gap; [`SeqCheck`] finds a gap (a record lost by the device's full queue or on the wire), and
//! the device counts what its queue dropped in [`Status::records_dropped`]. A run ends with one
//! [`DeviceMsg::RunEnded`].
//!
//! **Model upload** ([`HostMsg::UploadLr`]): the device accepts a model only whole: the feature count
//! must be the LR's 6, every coefficient finite, the end-to-end [`model_checksum`] must match, and the
//! controller must be at rest; otherwise it answers `Nack` and keeps the model it had.
//!
//! **Record upload** ([`HostMsg::RecordBegin`], [`HostMsg::RecordChunk`], [`HostMsg::RecordCommit`]):
//! a ground-motion record too long for one frame goes in chunks of [`RECORD_CHUNK`] samples, numbered
//! from 0, each acknowledged; the commit checks the count and the end-to-end [`record_checksum`]. The
//! device refuses the whole upload on the first bad chunk (out of order, duplicated, a NaN) and keeps
//! the record it had until a commit succeeds.
//!
//! **Record stream** ([`HostMsg::StreamBegin`], [`HostMsg::StreamChunk`], [`HostMsg::RecordCommit`],
//! [`HostMsg::StreamStatus`]): a record longer than the device holds passes through a ring of its
//! capacity during the run. The host fills the ring at rest and commits; during the run it sends
//! chunks as the ring frees up. Every chunk is answered by a [`DeviceMsg::StreamAck`] saying the
//! next chunk number the device expects and the samples it can take now (flow control: the host
//! never sends more than that, and sends a chunk again after a loss); a tick whose samples have
//! not arrived is an underrun, handled by the run's [`LinkLoss`] policy.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use serde::{Deserialize, Serialize};

pub mod layout;
pub use layout::{
    lrx_values, rig_value_count, rig_values, rnn_hidden_of, rnn_value_count, FE_ATS_VALUES,
    LRX_VALUES, MODEL_MAX_VALUES, RIG_MAX_VALUES, RNN_UPLOAD_MAX_HIDDEN,
};

/// Largest frame body (encoded, without the delimiter) either side sends or accepts, bytes.
pub const MAX_FRAME: usize = 128;

/// Number of LR coefficients (the features of `rths_core::metamodel::LR_FEATURE_NAMES`).
pub const LR_COEFFS: usize = 6;

/// The frame check: CRC-16/IBM-SDLC (X.25; poly 0x1021, reflected, init and xorout 0xFFFF).
pub const FRAME_CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_SDLC);

/// The model check: CRC-32/ISO-HDLC (the zlib/Ethernet CRC).
pub const MODEL_CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// The end-to-end checksum of an LR model: CRC-32 of the coefficients' little-endian IEEE bytes,
/// in feature order, then the delay in ticks (u16, little-endian).
pub fn model_checksum(theta: &[f64; LR_COEFFS], delay_steps: u16) -> u32 {
    let mut d = MODEL_CRC.digest();
    for t in theta {
        d.update(&t.to_le_bytes());
    }
    d.update(&delay_steps.to_le_bytes());
    d.finalize()
}

/// The end-to-end checksum of a chunked model upload: CRC-32/ISO-HDLC of the kind's wire index (one
/// byte), the values' little-endian IEEE bytes in order, then the delay in ticks (u16, LE).
pub fn model_values_checksum(kind: ModelKind, values: &[f64], delay_steps: u16) -> u32 {
    let mut d = RECORD_CRC.digest();
    d.update(&[kind as u8]);
    for v in values {
        d.update(&v.to_le_bytes());
    }
    d.update(&delay_steps.to_le_bytes());
    d.finalize()
}

/// Samples of a ground-motion record in one [`HostMsg::RecordChunk`] (a frame stays ≤ [`MAX_FRAME`]).
pub const RECORD_CHUNK: usize = 12;

/// The record check: CRC-32/ISO-HDLC, a `static` so that a running digest can be kept across chunks.
pub static RECORD_CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// The running end-to-end checksum of a ground-motion record ([`record_checksum`]), fed chunk by
/// chunk on the device as the samples arrive.
#[derive(Clone)]
pub struct RecordDigest(crc::Digest<'static, u32>);

impl Default for RecordDigest {
    fn default() -> Self {
        Self::new()
    }
}

impl RecordDigest {
    /// Nothing fed yet.
    pub fn new() -> Self {
        Self(RECORD_CRC.digest())
    }

    /// Feed samples, in order.
    pub fn update(&mut self, samples_g: &[f64]) {
        for x in samples_g {
            self.0.update(&x.to_le_bytes());
        }
    }

    /// The checksum of the samples fed and the record step `dt_s`.
    pub fn finalize(mut self, dt_s: f64) -> u32 {
        self.0.update(&dt_s.to_le_bytes());
        self.0.finalize()
    }
}

/// The end-to-end checksum of a ground-motion record: CRC-32/ISO-HDLC of its samples' (g, as sent,
/// i.e. already scaled) little-endian IEEE bytes, in order, then the step `dt_s`'s.
pub fn record_checksum(samples_g: &[f64], dt_s: f64) -> u32 {
    let mut d = RecordDigest::new();
    d.update(samples_g);
    d.finalize(dt_s)
}

/// What the host asks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum HostMsg {
    /// Answer with [`DeviceMsg::Status`].
    Status,
    /// Replace the LR model (whole, or not at all).
    UploadLr {
        /// Number of features the host's model has (must be [`LR_COEFFS`]).
        features: u8,
        /// Coefficients, in `LR_FEATURE_NAMES` order.
        theta: [f64; LR_COEFFS],
        /// The model's feedback delay, ticks.
        delay_steps: u16,
        /// [`model_checksum`] of `theta` and `delay_steps`.
        checksum: u32,
    },
    /// Replace the supervisor's stroke, velocity and force limits (only at rest with the command at
    /// 0 mm; the other interlocks keep the paper actuator's defaults).
    SetLimits {
        /// ±mm.
        stroke_mm: f64,
        /// mm/s.
        velocity_mm_s: f64,
        /// ±kN.
        force_kn: f64,
    },
    /// Arm at the measured position; telemetry every `telemetry_every` ticks (≥ 1).
    Arm {
        /// Decimation of the telemetry stream (1 = every tick).
        telemetry_every: u16,
    },
    /// Arm as [`HostMsg::Arm`] and choose what the device does if the host falls silent during
    /// the run ([`LinkLoss`]). The answer is about [`Request::Arm`].
    ArmWith {
        /// Decimation of the telemetry stream (1 = every tick).
        telemetry_every: u16,
        /// What a silence of the host longer than [`LINK_TIMEOUT_TICKS`] does to the run.
        on_link_loss: LinkLoss,
        /// The arming host's token (≠ 0): only a [`HostMsg::StartAs`] with it starts the test; 0:
        /// anyone's `Start` does.
        owner: u32,
    },
    /// Start the armed test as the host that armed it (`owner` of its [`HostMsg::ArmWith`]). The
    /// answer is about [`Request::Start`].
    StartAs {
        /// The token given at arm time.
        owner: u32,
    },
    /// Start the armed test (play the ground motion).
    Start,
    /// Stop: ramp the command to zero (end-of-test ramp).
    Abort,
    /// Begin a ground-motion record upload (replaces any upload in progress).
    RecordBegin {
        /// Samples that will follow (≥ 2, ≤ the device's capacity).
        samples: u32,
        /// Record step, s.
        dt_s: f64,
        /// The factor the host already applied to the samples (kept for the status, not applied).
        scale: f64,
        /// [`record_checksum`] of all the samples and `dt_s`.
        checksum: u32,
    },
    /// The next samples of the record being uploaded.
    RecordChunk {
        /// Chunk number, from 0, no gap.
        seq: u32,
        /// Samples used in `values` (1..=[`RECORD_CHUNK`]; only the last chunk may be short).
        count: u8,
        /// The samples, g (the first `count`).
        values: [f64; RECORD_CHUNK],
    },
    /// All chunks sent: check and make the new record the active one.
    RecordCommit,
    /// Begin a chunked model upload of any kind but LR (which goes in one [`HostMsg::UploadLr`]):
    /// its values in [`layout`]'s layout.
    ModelBegin {
        /// The kind (any image takes any kind its tick can run; an LR is refused `Unsupported`).
        kind: ModelKind,
        /// Values that will follow (one of the kind's counts: [`layout::count_fits`]).
        values: u16,
        /// The model's feedback delay, ticks.
        delay_steps: u16,
        /// [`model_values_checksum`] of the kind, values and delay.
        checksum: u32,
    },
    /// The next values of the model being uploaded.
    ModelChunk {
        /// Chunk number, from 0, no gap.
        seq: u32,
        /// Values used in `values`.
        count: u8,
        /// The values (the first `count`).
        values: [f64; RECORD_CHUNK],
    },
    /// All chunks sent: check, build the model and make it the one in force (at rest only).
    ModelCommit,
    // ---- identification through the board (issue 13, item 2) ----
    /// Characterize the rig: at rest, arm the supervisor as for a test (limits in force, faults
    /// trip and ramp down) and play the identification excitation (`rths_core::identify_excitation`,
    /// its defaults with this amplitude) from the control task, streaming every tick as an
    /// [`IdentifySample`] and ending with [`DeviceMsg::IdentifyEnded`].
    Identify {
        /// Peak command, mm (at most `rths_core::identify_excitation::MAX_AMPLITUDE_MM`).
        amplitude_mm: f64,
    },
    /// Answer with [`DeviceMsg::Holdings`]: what the device holds besides the [`Status`].
    Holdings,
    /// Replace the rig compensation the build's controller uses (whole, or not at all; at rest
    /// only): the values of [`rig_values`]' layout for `kind`.
    UploadRig {
        /// The analytical kind in force the values are for ([`ModelKind::Lrx`] or
        /// [`ModelKind::FeAts`]; a structure part's compensation has more values than a frame
        /// holds: [`HostMsg::RigBegin`]; another kind is refused `Unsupported`).
        kind: ModelKind,
        /// Values used in `values` (the kind's [`rig_value_count`]).
        count: u8,
        /// The values (the first `count`).
        values: [f64; RECORD_CHUNK],
        /// [`rig_checksum`] of the kind and the first `count` values.
        checksum: u32,
    },
    // ---- the board as an experimental site (issue 26, docs/site.md) ----
    /// Become an experimental site: at rest, make the controller's analytical part the
    /// predictor-corrector of `ticks_per_step` and its compensator the rig's lead filter, arm at
    /// rest and start; targets then come as [`HostMsg::SiteTarget`], each step's measurement goes
    /// back as [`DeviceMsg::SiteStep`] before the step's telemetry (after it on a fault).
    SiteBegin {
        /// Controller ticks per integration step (≥ 1).
        ticks_per_step: u32,
        /// The lead filter's weights (the rig file's identified lead).
        lead_weights: [f64; 8],
        /// The lead filter's tap stride, ticks (0: no lead, the command is the target).
        lead_stride: u16,
    },
    /// The target of the next integration step, the site's coordinates (mm).
    SiteTarget {
        /// Step number, from 0, no gap.
        step: u32,
        /// The target, mm.
        target_mm: f64,
    },
    /// The test is over: `fault` false, the supervisor's end ramp to zero (the analysis ended);
    /// true, its fault ramp to the armed position (the client failed).
    SiteEnd {
        /// Bring the actuator to its safe state as on a fault.
        fault: bool,
    },
    // ---- records streamed during the run (issue 27) ----
    /// Begin a streamed record (at rest; replaces any upload in progress): `samples` of any number
    /// (≥ 2, lasting at most `u32::MAX` ticks) pass through a ring of the device's capacity. The
    /// chunks that fill it follow, then [`HostMsg::RecordCommit`] makes it the record in force.
    StreamBegin {
        /// Samples the whole record has.
        samples: u32,
        /// Record step, s.
        dt_s: f64,
        /// The factor the host already applied to the samples (kept for the status, not applied).
        scale: f64,
        /// [`record_checksum`] of all the samples and `dt_s` (checked when the last one arrives).
        checksum: u32,
    },
    /// The next samples of the streamed record (at rest before its commit, or during its run),
    /// answered by a [`DeviceMsg::StreamAck`].
    StreamChunk {
        /// Chunk number, from 0, no gap.
        seq: u32,
        /// Samples used in `values` (1..=[`RECORD_CHUNK`]; only the last chunk may be short).
        count: u8,
        /// The samples, g (the first `count`).
        values: [f64; RECORD_CHUNK],
    },
    /// Answer with [`DeviceMsg::StreamStatus`]: where the streamed record stands.
    StreamStatus,
    // ---- a rig compensation in chunks (a structure part's; issue 23) ----
    /// Begin a chunked rig-compensation upload (replaces one in progress): what a rig file gives
    /// the analytical part in force, in [`rig_value_count`]'s layout, for more values than one
    /// [`HostMsg::UploadRig`] frame holds (a structure part's, [`layout::structure_rig_values`]).
    RigBegin {
        /// The analytical kind in force the values are for (another is refused `Unsupported`).
        kind: ModelKind,
        /// Values that will follow (the kind's [`rig_value_count`]).
        values: u8,
        /// [`rig_checksum`] of the kind and the values.
        checksum: u32,
    },
    /// The next values of the rig compensation being uploaded.
    RigChunk {
        /// Chunk number, from 0, no gap.
        seq: u32,
        /// Values used in `values`.
        count: u8,
        /// The values (the first `count`).
        values: [f64; RECORD_CHUNK],
    },
    /// All chunks sent: check the rig compensation and swap it in whole (at rest only).
    RigCommit,
}

/// Which request an answer is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Request {
    /// [`HostMsg::Status`].
    Status,
    /// [`HostMsg::UploadLr`].
    UploadLr,
    /// [`HostMsg::SetLimits`].
    SetLimits,
    /// [`HostMsg::Arm`].
    Arm,
    /// [`HostMsg::Start`].
    Start,
    /// [`HostMsg::Abort`].
    Abort,
    /// [`HostMsg::RecordBegin`].
    RecordBegin,
    /// [`HostMsg::RecordChunk`].
    RecordChunk,
    /// [`HostMsg::RecordCommit`].
    RecordCommit,
    /// [`HostMsg::ModelBegin`].
    ModelBegin,
    /// [`HostMsg::ModelChunk`].
    ModelChunk,
    /// [`HostMsg::ModelCommit`].
    ModelCommit,
    // ---- identification through the board ----
    /// [`HostMsg::Identify`].
    Identify,
    /// [`HostMsg::Holdings`].
    Holdings,
    /// [`HostMsg::UploadRig`].
    UploadRig,
    // ---- the board as an experimental site ----
    /// [`HostMsg::SiteBegin`].
    SiteBegin,
    /// [`HostMsg::SiteTarget`].
    SiteTarget,
    /// [`HostMsg::SiteEnd`].
    SiteEnd,
    // ---- records streamed during the run ----
    /// [`HostMsg::StreamBegin`].
    StreamBegin,
    /// [`HostMsg::StreamChunk`].
    StreamChunk,
    /// [`HostMsg::StreamStatus`].
    StreamStatus,
    // ---- a rig compensation in chunks ----
    /// [`HostMsg::RigBegin`].
    RigBegin,
    /// [`HostMsg::RigChunk`].
    RigChunk,
    /// [`HostMsg::RigCommit`].
    RigCommit,
}

impl HostMsg {
    /// The request kind.
    pub fn request(&self) -> Request {
        match self {
            Self::Status => Request::Status,
            Self::UploadLr { .. } => Request::UploadLr,
            Self::SetLimits { .. } => Request::SetLimits,
            Self::Arm { .. } | Self::ArmWith { .. } => Request::Arm,
            Self::Start | Self::StartAs { .. } => Request::Start,
            Self::Abort => Request::Abort,
            Self::RecordBegin { .. } => Request::RecordBegin,
            Self::RecordChunk { .. } => Request::RecordChunk,
            Self::RecordCommit => Request::RecordCommit,
            Self::ModelBegin { .. } => Request::ModelBegin,
            Self::ModelChunk { .. } => Request::ModelChunk,
            Self::ModelCommit => Request::ModelCommit,
            Self::Identify { .. } => Request::Identify,
            Self::Holdings => Request::Holdings,
            Self::UploadRig { .. } => Request::UploadRig,
            Self::SiteBegin { .. } => Request::SiteBegin,
            Self::SiteTarget { .. } => Request::SiteTarget,
            Self::SiteEnd { .. } => Request::SiteEnd,
            Self::StreamBegin { .. } => Request::StreamBegin,
            Self::StreamChunk { .. } => Request::StreamChunk,
            Self::StreamStatus => Request::StreamStatus,
            Self::RigBegin { .. } => Request::RigBegin,
            Self::RigChunk { .. } => Request::RigChunk,
            Self::RigCommit => Request::RigCommit,
        }
    }
}

/// Why the device refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NackReason {
    /// The model has the wrong number of features.
    Shape,
    /// A coefficient or limit is NaN or infinite.
    NotFinite,
    /// The model checksum does not match its coefficients.
    Checksum,
    /// A value is out of its allowed range (a limit ≤ 0, a decimation of 0, a different delay).
    OutOfRange,
    /// The controller is not at rest (armed, running, ramping): nothing changes under a test.
    Busy,
    /// The request is not valid in the supervisor's state (start before arm, ...).
    InvalidState,
    /// The device cannot do this (e.g. a second run on the emulated board).
    Unsupported,
    /// A record chunk out of order, duplicated or without a `RecordBegin` (the upload is dropped).
    Sequence,
    /// A commit before every sample arrived (a stream's: before its ring is full), a chunk with a
    /// bad count, or an arm with a streamed record already played (stream it again).
    Incomplete,
    /// The record is longer than the device can hold (or shorter than 2 samples).
    TooLong,
    /// The test was armed by another host (its token): only that host, or an abort, moves it.
    NotOwner,
    /// The record's step is not finite or outside the accepted range ([`RECORD_DT_MIN_S`] ..=
    /// [`RECORD_DT_MAX_S`]).
    Rate,
    /// The uploaded model cannot run in the board's tick: its estimated instructions per tick
    /// exceed what the core does in one tick (e.g. an RNN-10 on a Cortex-M4 at 2048 Hz, 104 %).
    TickBudget,
}

/// What the device does when the host falls silent during a run (no valid frame for
/// [`LINK_TIMEOUT_TICKS`]; a recording host sends a `Status` every 250 ms), and when a streamed
/// record's samples for a tick have not arrived (an underrun).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum LinkLoss {
    /// Run the test to its end (the default, and what a plain `Arm` chooses): the telemetry of the
    /// silence is lost, the test is not; a tick of an underrun plays 0 g and is counted
    /// ([`StreamStatus::underrun_ticks`]).
    Complete,
    /// Ramp the command down to zero (an abort) and end the run, at the silence's timeout or the
    /// first underrun.
    RampDown,
}

/// The host's silence that counts as a lost link, controller ticks (1 s at 2048 Hz).
pub const LINK_TIMEOUT_TICKS: u32 = 2048;

/// Shortest accepted record step, s: the controller's tick (a faster record would be decimated by
/// the interpolation, not played).
pub const RECORD_DT_MIN_S: f64 = 1.0 / 2048.0;
/// Longest accepted record step, s (strong-motion records are sampled at 0.005-0.02 s; a step this
/// long is a unit mistake, e.g. a record in ms).
pub const RECORD_DT_MAX_S: f64 = 0.1;

/// Where the active ground-motion record came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RecordSource {
    /// Compiled into the firmware.
    Compiled,
    /// Uploaded over the link.
    Uploaded,
    /// A record streamed over the link during its run ([`HostMsg::StreamBegin`]).
    Streamed,
}

/// Where a streamed record stands: the answer to [`HostMsg::StreamStatus`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct StreamStatus {
    /// It is the record in force (committed), not still filling its ring.
    pub in_force: bool,
    /// The chunk number the device expects next (= chunks accepted).
    pub next_seq: u32,
    /// Samples received so far, of [`RecordInfo::samples`].
    pub received: u32,
    /// Samples the ring can take now.
    pub free: u32,
    /// Ticks whose samples had not arrived when they were played (under [`LinkLoss::Complete`]
    /// they played 0 g; under [`LinkLoss::RampDown`] the first one ramped the run down).
    pub underrun_ticks: u32,
    /// The first such tick.
    pub first_underrun_tick: Option<u32>,
    /// Every sample arrived and the end-to-end [`record_checksum`] matched (`None`: not all
    /// arrived yet).
    pub checksum_ok: Option<bool>,
}

/// The active ground-motion record, as the status reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecordInfo {
    /// Compiled in or uploaded.
    pub source: RecordSource,
    /// Samples.
    pub samples: u32,
    /// Step, s.
    pub dt_s: f64,
    /// The scale the host applied before uploading (1 for the compiled-in record).
    pub scale: f64,
    /// Controller ticks it lasts.
    pub ticks: u32,
    /// [`record_checksum`].
    pub checksum: u32,
}

/// The kind of the analytical part the device runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ModelKind {
    /// Linear regression (`UploadLr` replaces it).
    Lr,
    /// LRX, the specimen-faithful frame metamodel.
    Lrx,
    /// Recurrent network.
    Rnn,
    /// Finite elements with ATS.
    FeAts,
    // ---- structure files (appended: the older kinds' wire codes stay) ----
    /// Finite elements (Chang) of a linear N-DOF structure's numerical part.
    StructureFe,
    /// Finite elements (Chang) of a yielding N-story structure's numerical part.
    StructureNl,
    /// The structure metamodel (delta ARX) of a dense structure (`rths train meta`).
    StructureMeta,
    /// The learned modal-hysteretic metamodel of a yielding structure (`rths train nonlinear`).
    StructureModal,
    /// The reduced-order modal model of an imported structure (`rths train meta` on it).
    StructureReduced,
    /// The learned floor-hysteron metamodel of a yielding structure (`rths train nonlinear`,
    /// issue 25; appended).
    StructureHysteron,
}

/// The supervisor's state, as sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RunState {
    /// Idle.
    Idle,
    /// Armed.
    Armed,
    /// Running.
    Running,
    /// Ramping to zero at the end of the test.
    RampDown,
    /// Done.
    Done,
    /// Faulted (the reason's wire code: `rths_core::supervisor::FaultReason::code`).
    Fault(u8),
}

/// The device's answer to [`HostMsg::Status`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Supervisor state.
    pub state: RunState,
    /// [`model_checksum`] of the active model.
    pub model_checksum: u32,
    /// Ticks done in the current run.
    pub tick: u32,
    /// Telemetry records sent in the current run.
    pub records_sent: u32,
    /// Telemetry records the device's queue dropped in the current run.
    pub records_dropped: u32,
    /// Active stroke limit, mm.
    pub stroke_mm: f64,
    /// Active velocity limit, mm/s.
    pub velocity_mm_s: f64,
    /// Active force limit, kN.
    pub force_kn: f64,
    /// Frames received with a bad COBS body, CRC or message since power-up.
    pub bad_frames: u32,
    /// The analytical part's kind.
    pub model_kind: ModelKind,
    /// The active ground-motion record.
    pub record: RecordInfo,
    /// Largest record the device can take, samples (0: no uploads).
    pub record_capacity: u32,
}

/// What the device holds besides the [`Status`] (the model's and rig compensation's origin and
/// checksums, the build): the answer to [`HostMsg::Holdings`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holdings {
    /// The analytical part's kind.
    pub model_kind: ModelKind,
    /// The model is the compiled-in one or an upload.
    pub model_source: RecordSource,
    /// The model's checksum ([`model_checksum`] for an LR, [`model_values_checksum`] for a chunked
    /// kind; 0 for the FE model, which has no weights).
    pub model_checksum: u32,
    /// The rig compensation is the compiled-in default or an [`HostMsg::UploadRig`].
    pub rig_source: RecordSource,
    /// [`rig_checksum`] of the rig compensation in force (of the compiled-in values for a build
    /// whose controller has one, else 0).
    pub rig_checksum: u32,
    /// The controller's tick rate, Hz.
    pub rate_hz: u32,
    /// The firmware build's identity: CRC-32 of its description (version, board, analytical part,
    /// rate, model source), the same for two identical builds.
    pub build_id: u32,
}

/// The end-to-end checksum of a rig-compensation upload: CRC-32/ISO-HDLC of the kind's wire index
/// (one byte), then the values' little-endian IEEE bytes in order.
pub fn rig_checksum(kind: ModelKind, values: &[f64]) -> u32 {
    let mut d = RECORD_CRC.digest();
    d.update(&[kind as u8]);
    for v in values {
        d.update(&v.to_le_bytes());
    }
    d.finalize()
}

/// One telemetry record: what the controller did at `tick`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Telemetry {
    /// Record number in this run, from 0, no gaps.
    pub seq: u32,
    /// Controller tick (0 = the first tick of the run).
    pub tick: u32,
    /// Supervisor state after the tick.
    pub state: RunState,
    /// Command sent at this tick, mm.
    pub command_mm: f64,
    /// Analytical target produced at this tick, mm.
    pub target_mm: f64,
    /// Measured displacement read at this tick, mm (NaN on a DAQ error).
    pub measured_mm: f64,
    /// Measured force read at this tick, kN (NaN on a DAQ error).
    pub force_kn: f64,
}

/// What the device says.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum DeviceMsg {
    /// The request was done.
    Ack(Request),
    /// The request was refused; nothing changed.
    Nack(Request, NackReason),
    /// The state.
    Status(Status),
    /// A telemetry record.
    Telemetry(Telemetry),
    /// The run is over (done or faulted and settled): its final state and counts.
    RunEnded {
        /// Final state.
        state: RunState,
        /// Ticks run.
        ticks: u32,
        /// Records sent (the last `seq` + 1).
        records_sent: u32,
        /// Records the device's queue dropped.
        records_dropped: u32,
    },
    // ---- identification through the board ----
    /// One tick of an identification.
    IdentifySample(IdentifySample),
    /// The identification is over: the excitation played to its end and the supervisor `Done`,
    /// or a fault tripped and the command came to rest.
    IdentifyEnded {
        /// Final supervisor state (`Done`, or the fault).
        state: RunState,
        /// Ticks run (= samples recorded).
        ticks: u32,
        /// Samples sent (the last `seq` + 1).
        samples_sent: u32,
        /// Samples the device's queue dropped.
        samples_dropped: u32,
    },
    /// The answer to [`HostMsg::Holdings`].
    Holdings(Holdings),
    // ---- the board as an experimental site ----
    /// A site's integration step ended (sent before the step's telemetry, which follows while the
    /// host's integrator computes; after it when a tick of the step is not running): the DAQ's
    /// reading at its last tick.
    SiteStep {
        /// Step number, from 0 (as its [`HostMsg::SiteTarget`]).
        step: u32,
        /// The tick the step ended at.
        tick: u32,
        /// Measured displacement, mm (NaN on a DAQ error).
        measured_mm: f64,
        /// Measured force, kN (NaN on a DAQ error).
        force_kn: f64,
    },
    // ---- records streamed during the run ----
    /// The answer to a [`HostMsg::StreamChunk`]: accepted if `next_seq` is `seq + 1`; refused (out
    /// of order, or more than the ring can take) otherwise, nothing changed.
    StreamAck {
        /// The chunk answered.
        seq: u32,
        /// The chunk number the device expects next.
        next_seq: u32,
        /// Samples the ring can take now.
        free: u32,
    },
    /// The answer to [`HostMsg::StreamStatus`].
    StreamStatus(StreamStatus),
}

/// What the controller saw at one tick of an identification: 32 bytes on the wire (postcard: tag,
/// `seq` as a 3-byte varint, three f64; CRC, COBS, delimiter), so 2048 ticks/s need 655 kbit/s, 71%
/// of a 921 600-baud UART: the device streams every tick and buffers nothing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IdentifySample {
    /// Sample number = tick of the identification, from 0, no gaps.
    pub seq: u32,
    /// Command sent at this tick (after the supervisor), mm.
    pub command_mm: f64,
    /// Measured displacement read at this tick (before the command), mm (NaN on a DAQ error).
    pub measured_mm: f64,
    /// Measured force read at this tick, kN (NaN on a DAQ error).
    pub force_kn: f64,
}

/// A framing or decoding failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkError {
    /// The message or frame does not fit the buffer.
    TooLong,
    /// The frame body is not valid COBS.
    Cobs,
    /// The frame is too short to hold a CRC, or the CRC does not match.
    Crc,
    /// The CRC matched but the bytes are not a message (or trailing bytes remain).
    Message,
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::TooLong => "frame too long",
            Self::Cobs => "bad COBS framing",
            Self::Crc => "CRC mismatch",
            Self::Message => "not a valid message",
        })
    }
}

/// Encode `msg` as one frame into `out`, delimiter included; returns the frame's length.
pub fn encode<T: Serialize>(msg: &T, out: &mut [u8]) -> Result<usize, LinkError> {
    let mut raw = [0u8; MAX_FRAME];
    let n = postcard::to_slice(msg, &mut raw)
        .map_err(|_| LinkError::TooLong)?
        .len();
    let crc = FRAME_CRC.checksum(raw.get(..n).ok_or(LinkError::TooLong)?);
    let body = raw.get_mut(..n + 2).ok_or(LinkError::TooLong)?;
    if let Some(tail) = body.get_mut(n..) {
        tail.copy_from_slice(&crc.to_le_bytes());
    }
    let limit = out.len().min(MAX_FRAME + 1);
    let dest = out
        .get_mut(..limit.saturating_sub(1))
        .ok_or(LinkError::TooLong)?;
    let m = cobs::try_encode(body, dest).map_err(|_| LinkError::TooLong)?;
    let delim = out.get_mut(m).ok_or(LinkError::TooLong)?;
    *delim = 0;
    Ok(m + 1)
}

/// COBS-decode `body` (without its delimiter) in place, returning the decoded length. Through
/// the crate's byte-at-a-time state machine (`cobs::DecoderState`) rather than its
/// `decode_in_place`, whose indexing keeps a bounds-check panic in the device's receive task: a
/// decoded byte is never ahead of the byte it came from, so writing at `n` ≤ the read index is
/// in place, and every access is checked (`get`, `get_mut`).
fn cobs_decode_in_place(body: &mut [u8]) -> Result<usize, LinkError> {
    use cobs::{DecodeResult, DecoderState};
    let mut state = DecoderState::Idle;
    let mut n = 0;
    for i in 0..=body.len() {
        // The delimiter the frame reader removed ends the frame.
        let byte = body.get(i).copied().unwrap_or(0);
        match state.feed(byte).map_err(|_| LinkError::Cobs)? {
            DecodeResult::NoData => {}
            DecodeResult::DataContinue(b) => {
                *body.get_mut(n).ok_or(LinkError::Cobs)? = b;
                n += 1;
            }
            // Complete only at the frame's end: a zero inside is not this frame.
            DecodeResult::DataComplete if i == body.len() => return Ok(n),
            DecodeResult::DataComplete => return Err(LinkError::Cobs),
        }
    }
    Err(LinkError::Cobs)
}

/// Decode one frame body (COBS bytes without the `0x00` delimiter), in place.
pub fn decode<'a, T: Deserialize<'a>>(body: &'a mut [u8]) -> Result<T, LinkError> {
    if body.len() > MAX_FRAME {
        return Err(LinkError::TooLong);
    }
    let n = cobs_decode_in_place(body)?;
    if n < 3 {
        return Err(LinkError::Crc);
    }
    let raw = body.get(..n).ok_or(LinkError::Cobs)?;
    let (payload, crc) = raw.split_at(n - 2);
    let got = u16::from_le_bytes([
        crc.first().copied().unwrap_or(0),
        crc.get(1).copied().unwrap_or(0),
    ]);
    if FRAME_CRC.checksum(payload) != got {
        return Err(LinkError::Crc);
    }
    match postcard::take_from_bytes(payload) {
        Ok((msg, [])) => Ok(msg),
        _ => Err(LinkError::Message),
    }
}

/// Collects bytes from a stream into frames.
pub struct FrameReader<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for FrameReader<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameReader<N> {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflow: false,
        }
    }

    /// Feed one byte; at a delimiter, decode the frame collected so far (an empty frame, i.e. two
    /// delimiters in a row, is skipped). A frame longer than `N` is dropped whole and reported once
    /// as [`LinkError::TooLong`] at its delimiter.
    pub fn push<T: for<'de> Deserialize<'de>>(&mut self, byte: u8) -> Option<Result<T, LinkError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            return Some(Err(LinkError::TooLong));
        }
        if len == 0 {
            return None;
        }
        let body = self.buf.get_mut(..len)?;
        Some(decode(body))
    }
}

/// Checks that telemetry sequence numbers come without a gap.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeqCheck {
    next: Option<u32>,
    missing: u32,
}

/// A gap in the telemetry: records `expected..got` never arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gap {
    /// The sequence number that should have come.
    pub expected: u32,
    /// The one that came.
    pub got: u32,
}

impl SeqCheck {
    /// Expect `seq` 0 first.
    pub fn new() -> Self {
        Self {
            next: Some(0),
            missing: 0,
        }
    }

    /// Expect `seq` `first` first (a recording that picks up a stream already under way).
    pub fn starting_at(first: u32) -> Self {
        Self {
            next: Some(first),
            missing: 0,
        }
    }

    /// Observe one record's `seq`; a gap (or a number going backwards) is returned and counted.
    pub fn observe(&mut self, seq: u32) -> Result<(), Gap> {
        let expected = self.next.unwrap_or(seq);
        self.next = Some(seq.wrapping_add(1));
        if seq == expected {
            Ok(())
        } else {
            self.missing = self
                .missing
                .saturating_add(seq.wrapping_sub(expected).min(u32::MAX / 2));
            Err(Gap { expected, got: seq })
        }
    }

    /// Records found missing so far.
    pub fn missing(&self) -> u32 {
        self.missing
    }
}

#[cfg(test)]
mod tests;
