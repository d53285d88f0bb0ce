//! The host side of the command link (`rths link`): open a serial port, a TCP socket (QEMU's serial
//! port on 127.0.0.1) or a QEMU process of our own, send requests, wait for their answers, and record
//! the telemetry stream with its sequence numbers checked. The protocol is `rths-link`'s.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rths_link::{
    DeviceMsg, FrameReader, Gap, Holdings, HostMsg, LinkError, ModelKind as WireModelKind,
    NackReason, RecordSource, Request, RunState, SeqCheck, Status, Telemetry, LR_COEFFS, MAX_FRAME,
    RECORD_CHUNK,
};

use crate::model_file::{ModelFile, ModelKind};
use rths_core::supervisor::FaultReason;

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

/// A byte stream both ways.
pub trait Port: Read + Write + Send {
    /// How long a read may block.
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()>;
}

impl Port for TcpStream {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(t))
    }
}

/// A serial port (`serialport`, built without libudev).
struct Serial(Box<dyn serialport::SerialPort>);

impl Read for Serial {
    fn read(&mut self, b: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(b)
    }
}

impl Write for Serial {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl Port for Serial {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        self.0.set_timeout(t).map_err(std::io::Error::other)
    }
}

/// How a run's telemetry ended.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordSummary {
    /// Records received.
    pub records: usize,
    /// Gaps in the sequence numbers (each one also reported as it happens).
    pub gaps: Vec<Gap>,
    /// Records missing in total.
    pub missing: u32,
    /// Frames that failed COBS, CRC or decoding on the host side.
    pub bad_frames: u32,
    /// The device's `RunEnded`: final state, ticks, records sent, records its queue dropped.
    pub end: Option<(RunState, u32, u32, u32)>,
}

impl RecordSummary {
    /// Nothing lost: no gap, no bad frame, the device sent all it recorded and dropped none.
    pub fn complete(&self) -> bool {
        self.gaps.is_empty()
            && self.bad_frames == 0
            && matches!(self.end, Some((_, _, sent, 0)) if sent as usize == self.records)
    }
}

/// A connection to a device.
pub struct Link {
    port: Box<dyn Port>,
    frames: FrameReader<{ MAX_FRAME }>,
    queue: VecDeque<DeviceMsg>,
    /// Host-side bad frames so far.
    pub bad_frames: u32,
    /// How long to wait for an answer.
    pub timeout: Duration,
    /// While recording, send a `Status` this often (the device's sign that the host is there, for a
    /// run armed with `LinkLoss::RampDown`); `None`: never (tests of a lost link).
    pub heartbeat: Option<Duration>,
    /// The token this host armed its test with ([`Self::arm_owned`]; 0: none): its `start` sends
    /// it, and the device refuses another host's start.
    pub owner: u32,
}

impl Link {
    /// Over any byte stream.
    pub fn new(port: Box<dyn Port>) -> Self {
        Self {
            port,
            frames: FrameReader::new(),
            queue: VecDeque::new(),
            bad_frames: 0,
            timeout: Duration::from_secs(10),
            heartbeat: Some(Duration::from_millis(250)),
            owner: 0,
        }
    }

    /// A TCP connection (QEMU `-serial tcp:127.0.0.1:PORT,server=on`).
    pub fn tcp(addr: &str) -> Result<Self, LinkHostError> {
        let s = TcpStream::connect(addr)?;
        s.set_nodelay(true)?;
        Ok(Self::new(Box::new(s)))
    }

    /// A serial device at `baud`, 8N1, raw.
    pub fn serial(path: &str, baud: u32) -> Result<Self, LinkHostError> {
        let p = serialport::new(path, baud)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| LinkHostError::Serial {
                path: path.to_string(),
                message: e.to_string(),
            })?;
        Ok(Self::new(Box::new(Serial(p))))
    }

    /// Send one message, after a delimiter that ends any partial frame the device may hold (bytes it
    /// received before its UART was enabled, a frame cut by a reset).
    pub fn send(&mut self, msg: &HostMsg) -> Result<(), LinkHostError> {
        let mut buf = [0u8; MAX_FRAME + 2];
        let n = rths_link::encode(msg, buf.get_mut(1..).unwrap_or(&mut []))
            .map_err(LinkHostError::Frame)?;
        self.send_raw(buf.get(..n + 1).unwrap_or(&[]))
    }

    /// Wait until the device answers a status request (it may still be booting: bytes sent before
    /// its UART is enabled are lost), asking every 250 ms, for at most `total`.
    pub fn wait_ready(&mut self, total: Duration) -> Result<Status, LinkHostError> {
        let start = Instant::now();
        while start.elapsed() < total {
            self.send(&HostMsg::Status)?;
            let until = Instant::now() + Duration::from_millis(250);
            loop {
                let left = until.saturating_duration_since(Instant::now());
                match self.recv(left) {
                    Ok(DeviceMsg::Status(s)) => {
                        // Answers to the earlier asks may follow: drop them.
                        self.drain(Duration::from_millis(100));
                        return Ok(s);
                    }
                    Ok(other) => self.queue.push_back(other),
                    Err(LinkHostError::Timeout(..)) => break,
                    Err(e) => return Err(e),
                }
                if left.is_zero() {
                    break;
                }
            }
        }
        Err(LinkHostError::Timeout(total, "device ready"))
    }

    /// Read and drop whatever status answers arrive within `t`.
    fn drain(&mut self, t: Duration) {
        let until = Instant::now() + t;
        let mut kept = VecDeque::new();
        while let Ok(m) = self.recv(until.saturating_duration_since(Instant::now())) {
            if !matches!(m, DeviceMsg::Status(_)) {
                kept.push_back(m);
            }
        }
        self.queue = kept;
    }

    /// Send bytes as they are (tests: a corrupted frame).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), LinkHostError> {
        self.port.write_all(bytes)?;
        self.port.flush()?;
        Ok(())
    }

    /// The next message from the device, waiting up to `timeout`.
    pub fn recv(&mut self, timeout: Duration) -> Result<DeviceMsg, LinkHostError> {
        if let Some(m) = self.queue.pop_front() {
            return Ok(m);
        }
        let start = Instant::now();
        let mut buf = [0u8; 4096];
        loop {
            let left = timeout.saturating_sub(start.elapsed());
            if left.is_zero() {
                return Err(LinkHostError::Timeout(timeout, "receive"));
            }
            self.port
                .set_timeout(left.min(Duration::from_millis(200)))?;
            let n = match self.port.read(&mut buf) {
                Ok(0) => {
                    return Err(LinkHostError::Io(std::io::Error::new(
                        std::io::ErrorKind::UnexpectedEof,
                        "the device closed the link",
                    )))
                }
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue
                }
                Err(e) => return Err(e.into()),
            };
            for &b in buf.get(..n).unwrap_or(&[]) {
                match self.frames.push::<DeviceMsg>(b) {
                    Some(Ok(m)) => self.queue.push_back(m),
                    Some(Err(_)) => self.bad_frames = self.bad_frames.saturating_add(1),
                    None => {}
                }
            }
            if let Some(m) = self.queue.pop_front() {
                return Ok(m);
            }
        }
    }

    /// Send a request and wait for its answer; telemetry and run ends that arrive meanwhile are kept
    /// for [`Self::record`].
    pub fn request(&mut self, msg: &HostMsg) -> Result<DeviceMsg, LinkHostError> {
        self.send(msg)?;
        let req = msg.request();
        let deadline = Instant::now() + self.timeout;
        let mut kept = VecDeque::new();
        let answer = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let m = match self.recv(left) {
                Ok(m) => m,
                Err(LinkHostError::Timeout(..)) => {
                    self.queue.extend(kept);
                    return Err(LinkHostError::Timeout(self.timeout, "answer"));
                }
                Err(e) => return Err(e),
            };
            match m {
                DeviceMsg::Ack(r) | DeviceMsg::Nack(r, _) if r == req => break m,
                DeviceMsg::Status(_) if req == Request::Status => break m,
                DeviceMsg::Holdings(_) if req == Request::Holdings => break m,
                other => kept.push_back(other),
            }
        };
        // Keep the stream's order for the recorder.
        kept.extend(self.queue.drain(..));
        self.queue = kept;
        match answer {
            DeviceMsg::Nack(r, why) => Err(LinkHostError::Refused(r, why)),
            m => Ok(m),
        }
    }

    fn expect_ack(&mut self, msg: &HostMsg) -> Result<(), LinkHostError> {
        match self.request(msg)? {
            DeviceMsg::Ack(_) => Ok(()),
            other => Err(LinkHostError::Unexpected(msg.request(), other)),
        }
    }

    /// The device's status.
    pub fn status(&mut self) -> Result<Status, LinkHostError> {
        match self.request(&HostMsg::Status)? {
            DeviceMsg::Status(s) => Ok(s),
            other => Err(LinkHostError::Unexpected(Request::Status, other)),
        }
    }

    /// What the device holds besides its status: the model's and the rig compensation's origin and
    /// checksums, the rate, the build's identity.
    pub fn holdings(&mut self) -> Result<Holdings, LinkHostError> {
        match self.request(&HostMsg::Holdings)? {
            DeviceMsg::Holdings(h) => Ok(h),
            other => Err(LinkHostError::Unexpected(Request::Holdings, other)),
        }
    }

    /// Upload a rig compensation for a device whose analytical part is `kind` (the values of
    /// [`rig_values`]); its checksum on success, the device's refusal (the compensation it had stays)
    /// as [`LinkHostError::Refused`].
    pub fn upload_rig(
        &mut self,
        kind: WireModelKind,
        values: &[f64],
    ) -> Result<u32, LinkHostError> {
        let msg = rig_message(kind, values)?;
        self.expect_ack(&msg)?;
        Ok(rths_link::rig_checksum(kind, values))
    }

    /// Upload a model: an LR model in one `UploadLr`, another kind in chunks (`ModelBegin`, the
    /// chunks, `ModelCommit`, each acknowledged; a kind the firmware does not run is refused at the
    /// begin, `Unsupported`). Its checksum on success.
    pub fn upload(&mut self, model: &ModelFile) -> Result<u32, LinkHostError> {
        if model.kind != ModelKind::Lr {
            let msgs = model_messages(model)?;
            for m in &msgs {
                self.expect_ack(m)?;
            }
            // A rig-trained LRX model's lead adaptation and specimen dynamics are not among its
            // chunked values: they follow as the rig compensation they are, so the device runs the
            // whole model (a refusal there leaves the model without them: an error, not a run).
            if let Some(v) = lrx_rig_extras(model)? {
                self.upload_rig(WireModelKind::Lrx, &v)?;
            }
            return match msgs.first() {
                Some(HostMsg::ModelBegin { checksum, .. }) => Ok(*checksum),
                _ => Err(LinkHostError::Model("no model begin".into())),
            };
        }
        let msg = upload_message(model)?;
        self.expect_ack(&msg)?;
        match msg {
            HostMsg::UploadLr { checksum, .. } => Ok(checksum),
            _ => Err(LinkHostError::Model("not an LR upload".into())),
        }
    }

    /// Upload a ground-motion record (samples in g every `dt_s`, already multiplied by `scale`,
    /// which the device keeps for its status): `RecordBegin`, the chunks, `RecordCommit`, each
    /// acknowledged. Its checksum on success; the device's refusal (the record it had stays in
    /// force) as [`LinkHostError::Refused`].
    pub fn upload_record(
        &mut self,
        samples_g: &[f64],
        dt_s: f64,
        scale: f64,
    ) -> Result<u32, LinkHostError> {
        let msgs = record_messages(samples_g, dt_s, scale)?;
        for m in &msgs {
            self.expect_ack(m)?;
        }
        Ok(rths_link::record_checksum(samples_g, dt_s))
    }

    /// New stroke, velocity and force limits.
    pub fn set_limits(
        &mut self,
        stroke_mm: f64,
        velocity_mm_s: f64,
        force_kn: f64,
    ) -> Result<(), LinkHostError> {
        self.expect_ack(&HostMsg::SetLimits {
            stroke_mm,
            velocity_mm_s,
            force_kn,
        })
    }

    /// Arm, telemetry every `telemetry_every` ticks (the run completes if the host falls silent).
    pub fn arm(&mut self, telemetry_every: u16) -> Result<(), LinkHostError> {
        self.expect_ack(&HostMsg::Arm { telemetry_every })
    }

    /// Arm, telemetry every `telemetry_every` ticks, and what the device does if the host falls
    /// silent during the run; any host may start it.
    pub fn arm_with(
        &mut self,
        telemetry_every: u16,
        on_link_loss: rths_link::LinkLoss,
    ) -> Result<(), LinkHostError> {
        self.owner = 0;
        self.expect_ack(&HostMsg::ArmWith {
            telemetry_every,
            on_link_loss,
            owner: 0,
        })
    }

    /// [`Self::arm_with`], owned by this host: a token (from the clock and the process id, never 0)
    /// that [`Self::start`] sends; the device refuses any other host's start of this test (an
    /// abort from anyone is still obeyed).
    pub fn arm_owned(
        &mut self,
        telemetry_every: u16,
        on_link_loss: rths_link::LinkLoss,
    ) -> Result<(), LinkHostError> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let owner = (nanos ^ std::process::id().rotate_left(16)).max(1);
        self.expect_ack(&HostMsg::ArmWith {
            telemetry_every,
            on_link_loss,
            owner,
        })?;
        self.owner = owner;
        Ok(())
    }

    /// Start the armed test (as its owner if this host armed it with [`Self::arm_owned`]).
    pub fn start(&mut self) -> Result<(), LinkHostError> {
        if self.owner != 0 {
            let owner = self.owner;
            return self.expect_ack(&HostMsg::StartAs { owner });
        }
        self.expect_ack(&HostMsg::Start)
    }

    /// Abort: ramp to zero.
    pub fn abort(&mut self) -> Result<(), LinkHostError> {
        self.expect_ack(&HostMsg::Abort)
    }

    /// Receive telemetry until the device's `RunEnded` (or `idle` without any message), handing each
    /// record to `sink`; the first record expected is `first_seq` (0 for a whole run). A sequence gap
    /// is reported on stderr as it is found and in the summary.
    pub fn record(
        &mut self,
        idle: Duration,
        first_seq: u32,
        mut sink: impl FnMut(&Telemetry) -> std::io::Result<()>,
    ) -> Result<RecordSummary, LinkHostError> {
        let mut seq = SeqCheck::starting_at(first_seq);
        let mut s = RecordSummary {
            records: 0,
            gaps: Vec::new(),
            missing: 0,
            bad_frames: 0,
            end: None,
        };
        let bad0 = self.bad_frames;
        let (mut heard, mut beat) = (Instant::now(), Instant::now());
        loop {
            if let Some(every) = self.heartbeat {
                if beat.elapsed() >= every {
                    self.send(&HostMsg::Status)?;
                    beat = Instant::now();
                }
            }
            let wait = idle
                .saturating_sub(heard.elapsed())
                .min(self.heartbeat.unwrap_or(idle));
            let m = match self.recv(wait) {
                Ok(m) => m,
                Err(LinkHostError::Timeout(..)) if heard.elapsed() < idle => continue,
                Err(LinkHostError::Timeout(..)) => {
                    return Err(LinkHostError::Timeout(idle, "telemetry"))
                }
                Err(e) => return Err(e),
            };
            heard = Instant::now();
            match m {
                DeviceMsg::Telemetry(t) => {
                    if let Err(g) = seq.observe(t.seq) {
                        eprintln!(
                            "warning: telemetry gap: expected record {}, got {} ({} missing)",
                            g.expected,
                            g.got,
                            g.got.wrapping_sub(g.expected)
                        );
                        s.gaps.push(g);
                    }
                    s.records += 1;
                    sink(&t)?;
                }
                DeviceMsg::RunEnded {
                    state,
                    ticks,
                    records_sent,
                    records_dropped,
                } => {
                    s.end = Some((state, ticks, records_sent, records_dropped));
                    break;
                }
                _ => {}
            }
        }
        s.missing = seq.missing();
        s.bad_frames = self.bad_frames - bad0;
        Ok(s)
    }
}

/// What an identification through the board streamed back (`rths link ... identify`).
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyStream {
    /// Command at each tick, mm (after the device's supervisor).
    pub command_mm: Vec<f64>,
    /// Measured displacement at each tick, mm.
    pub measured_mm: Vec<f64>,
    /// Measured force at each tick, kN.
    pub force_kn: Vec<f64>,
    /// Gaps in the sequence numbers (each one also reported as it happens).
    pub gaps: Vec<Gap>,
    /// Samples missing in total.
    pub missing: u32,
    /// Frames that failed COBS, CRC or decoding on the host side.
    pub bad_frames: u32,
    /// The device's `IdentifyEnded`: final state, ticks, samples sent, samples its queue dropped.
    pub end: (RunState, u32, u32, u32),
}

impl IdentifyStream {
    /// Every sample arrived: no gap, no bad frame, the device sent all its ticks and dropped none.
    pub fn complete(&self) -> bool {
        let (_, ticks, sent, dropped) = self.end;
        self.gaps.is_empty()
            && self.bad_frames == 0
            && dropped == 0
            && sent == ticks
            && sent as usize == self.command_mm.len()
    }
}

impl Link {
    /// Start an identification of peak `amplitude_mm` on the device and receive its samples until
    /// its `IdentifyEnded` (or `idle` without any message). Gaps are reported on stderr as they are
    /// found and in the result; the caller refuses an incomplete stream.
    pub fn identify(
        &mut self,
        amplitude_mm: f64,
        idle: Duration,
    ) -> Result<IdentifyStream, LinkHostError> {
        self.expect_ack(&HostMsg::Identify { amplitude_mm })?;
        let bad0 = self.bad_frames;
        let mut seq = SeqCheck::new();
        let (mut command_mm, mut measured_mm, mut force_kn) = (Vec::new(), Vec::new(), Vec::new());
        let mut gaps = Vec::new();
        let end = loop {
            match self.recv(idle) {
                Ok(DeviceMsg::IdentifySample(t)) => {
                    if let Err(g) = seq.observe(t.seq) {
                        eprintln!(
                            "warning: identification gap: expected sample {}, got {} ({} missing)",
                            g.expected,
                            g.got,
                            g.got.wrapping_sub(g.expected)
                        );
                        gaps.push(g);
                    }
                    command_mm.push(t.command_mm);
                    measured_mm.push(t.measured_mm);
                    force_kn.push(t.force_kn);
                }
                Ok(DeviceMsg::IdentifyEnded {
                    state,
                    ticks,
                    samples_sent,
                    samples_dropped,
                }) => break (state, ticks, samples_sent, samples_dropped),
                Ok(_) => {}
                Err(LinkHostError::Timeout(..)) => {
                    return Err(LinkHostError::Timeout(idle, "identification samples"))
                }
                Err(e) => return Err(e),
            }
        };
        Ok(IdentifyStream {
            command_mm,
            measured_mm,
            force_kn,
            gaps,
            missing: seq.missing(),
            bad_frames: self.bad_frames - bad0,
            end,
        })
    }
}

/// The upload message of an LR model file (validated here too: kind, 6 coefficients, finite).
pub fn upload_message(model: &ModelFile) -> Result<HostMsg, LinkHostError> {
    if model.kind != ModelKind::Lr {
        return Err(LinkHostError::Model(
            "only LR models can be uploaded over the link".into(),
        ));
    }
    let theta: [f64; LR_COEFFS] = model
        .lr
        .as_ref()
        .and_then(|w| w.theta.clone().try_into().ok())
        .ok_or_else(|| LinkHostError::Model(format!("lr.theta must have {LR_COEFFS} values")))?;
    let delay = u16::try_from(model.delay_steps)
        .map_err(|_| LinkHostError::Model("delay_steps does not fit 16 bits".into()))?;
    Ok(HostMsg::UploadLr {
        features: LR_COEFFS as u8,
        theta,
        delay_steps: delay,
        checksum: rths_link::model_checksum(&theta, delay),
    })
}

/// The messages of a record upload: `RecordBegin`, one `RecordChunk` per [`RECORD_CHUNK`] samples
/// (numbered from 0), `RecordCommit`. Checked here too (≥ 2 finite samples, a finite step and scale)
/// so that a bad file fails before anything is sent; the device checks again.
pub fn record_messages(
    samples_g: &[f64],
    dt_s: f64,
    scale: f64,
) -> Result<Vec<HostMsg>, LinkHostError> {
    if samples_g.len() < 2 {
        return Err(LinkHostError::Motion("fewer than 2 samples".into()));
    }
    if let Some(i) = samples_g.iter().position(|v| !v.is_finite()) {
        return Err(LinkHostError::Motion(format!("sample {i} is not finite")));
    }
    if !(dt_s.is_finite() && dt_s > 0.0 && scale.is_finite()) {
        return Err(LinkHostError::Motion(format!(
            "step {dt_s} s or scale {scale} is not a finite positive number"
        )));
    }
    let samples = u32::try_from(samples_g.len())
        .map_err(|_| LinkHostError::Motion("more than 2^32 samples".into()))?;
    let mut out = Vec::with_capacity(samples_g.len() / RECORD_CHUNK + 3);
    out.push(HostMsg::RecordBegin {
        samples,
        dt_s,
        scale,
        checksum: rths_link::record_checksum(samples_g, dt_s),
    });
    for (i, ch) in samples_g.chunks(RECORD_CHUNK).enumerate() {
        let mut values = [0.0; RECORD_CHUNK];
        values
            .get_mut(..ch.len())
            .ok_or_else(|| LinkHostError::Motion("chunk".into()))?
            .copy_from_slice(ch);
        out.push(HostMsg::RecordChunk {
            seq: i as u32,
            count: ch.len() as u8,
            values,
        });
    }
    out.push(HostMsg::RecordCommit);
    Ok(out)
}

/// The flat values of a model file for a chunked upload, and its wire kind: LRX in
/// `rths_link::lrx_values`' order; an RNN as `w_ih` (row-major), `w_hh` (row-major), `b_h`, `w_ho`,
/// `b_o`, `input_mean`, `input_std`, `output_mean`, `output_std` (`rths_link::rnn_value_count`'s
/// order; only an RNN build of the same hidden size takes it, others refuse it).
pub fn model_values(model: &ModelFile) -> Result<(WireModelKind, Vec<f64>), LinkHostError> {
    let missing = |what: &str| LinkHostError::Model(format!("no {what} section"));
    match model.kind {
        ModelKind::Lrx => {
            let x = model.lrx.as_ref().ok_or_else(|| missing("lrx"))?;
            let v = rths_link::lrx_values(
                &x.coeffs,
                x.k_corr_kn_per_mm,
                x.k_adapt_ticks,
                &x.lead_weights,
                x.lead_stride,
            )
            .ok_or_else(|| LinkHostError::Model("lrx: 9 coefficients and 8 lead weights".into()))?;
            Ok((WireModelKind::Lrx, v.to_vec()))
        }
        ModelKind::Rnn => {
            let r = model.rnn.as_ref().ok_or_else(|| missing("rnn"))?;
            let mut v: Vec<f64> = r.w_ih.concat();
            v.extend(r.w_hh.concat());
            v.extend(&r.b_h);
            v.extend(&r.w_ho);
            v.push(r.b_o);
            v.extend(&r.input_mean);
            v.extend(&r.input_std);
            v.push(r.output_mean);
            v.push(r.output_std);
            Ok((WireModelKind::Rnn, v))
        }
        ModelKind::Lr => Err(LinkHostError::Model(
            "an LR model goes in one UploadLr".into(),
        )),
    }
}

/// The rig-compensation values that carry an LRX model's optional lead adaptation and specimen
/// dynamics (`rths train lrx --rig`), in `rths_link::rig_values`' layout (0: absent, as the device
/// reads them), or `None` for a model without them (or not LRX).
pub fn lrx_rig_extras(model: &ModelFile) -> Result<Option<Vec<f64>>, LinkHostError> {
    let Some(x) = model.lrx.as_ref().filter(|_| model.kind == ModelKind::Lrx) else {
        return Ok(None);
    };
    let extras = [
        x.lead_adapt_ticks,
        x.specimen_mass_kn_s2_per_mm,
        x.specimen_damping_kn_s_per_mm,
    ];
    if extras.iter().all(Option::is_none) {
        return Ok(None);
    }
    let [adapt, mass, damping] = extras.map(|v| v.unwrap_or(0.0));
    rths_link::rig_values(&x.lead_weights, x.lead_stride, adapt, [mass, damping])
        .map(|v| Some(v.to_vec()))
        .ok_or_else(|| LinkHostError::Model("lrx: 8 lead weights".into()))
}

/// The messages of a chunked model upload: `ModelBegin`, the chunks of [`RECORD_CHUNK`] values,
/// `ModelCommit`.
pub fn model_messages(model: &ModelFile) -> Result<Vec<HostMsg>, LinkHostError> {
    let (kind, v) = model_values(model)?;
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(LinkHostError::Model(format!("value {i} is not finite")));
    }
    let values = u16::try_from(v.len())
        .map_err(|_| LinkHostError::Model("more than 65535 values".into()))?;
    let delay_steps = u16::try_from(model.delay_steps)
        .map_err(|_| LinkHostError::Model("delay_steps does not fit 16 bits".into()))?;
    let mut out = vec![HostMsg::ModelBegin {
        kind,
        values,
        delay_steps,
        checksum: rths_link::model_values_checksum(kind, &v, delay_steps),
    }];
    for (i, ch) in v.chunks(RECORD_CHUNK).enumerate() {
        let mut values = [0.0; RECORD_CHUNK];
        values
            .get_mut(..ch.len())
            .ok_or_else(|| LinkHostError::Model("chunk".into()))?
            .copy_from_slice(ch);
        out.push(HostMsg::ModelChunk {
            seq: i as u32,
            count: ch.len() as u8,
            values,
        });
    }
    out.push(HostMsg::ModelCommit);
    Ok(out)
}

/// The rig compensation a rig file (`rths identify`) gives a device's analytical part `kind`, in
/// `rths_link::rig_value_count`'s layout: FE + ATS: the ATS's identified initial [a0, a1, a2] (as
/// `rths simulate fe-online-ats --rig` starts from); LRX: the identified lead filter, the lead's
/// adaptation time constant `lead_adapt_ticks`, and the specimen's moving mass and damping at the
/// prototype's scale (as `rths train lrx --rig` writes them into a model). Another kind has none.
pub fn rig_values(
    rig: &crate::identify::RigFile,
    kind: WireModelKind,
    lead_adapt_ticks: f64,
) -> Result<Vec<f64>, LinkHostError> {
    match kind {
        WireModelKind::FeAts => Ok(rig.compensation.ats_initial.to_vec()),
        WireModelKind::Lrx => {
            let lead = rig
                .lead_params()
                .map_err(|e| LinkHostError::Model(format!("rig file: {e}")))?;
            let dynamics = crate::train::lrx::prototype_dynamics(&rig.specimen_fit);
            let v =
                rths_link::rig_values(lead.weights(), lead.stride(), lead_adapt_ticks, dynamics)
                    .ok_or_else(|| LinkHostError::Model("rig file: 8 lead weights".into()))?;
            Ok(v.to_vec())
        }
        WireModelKind::Lr | WireModelKind::Rnn => Err(LinkHostError::Model(format!(
            "the device runs {}, which has no rig compensation to upload",
            model_kind_name(kind)
        ))),
    }
}

/// The `UploadRig` message of a rig compensation for `kind` (its values, one frame).
pub fn rig_message(kind: WireModelKind, values: &[f64]) -> Result<HostMsg, LinkHostError> {
    if values.len() > rths_link::RIG_MAX_VALUES {
        return Err(LinkHostError::Model(format!(
            "{} rig values, a frame holds {}",
            values.len(),
            rths_link::RIG_MAX_VALUES
        )));
    }
    let mut v = [0.0; RECORD_CHUNK];
    v.get_mut(..values.len())
        .ok_or_else(|| LinkHostError::Model("rig values".into()))?
        .copy_from_slice(values);
    Ok(HostMsg::UploadRig {
        kind,
        count: values.len() as u8,
        values: v,
        checksum: rths_link::rig_checksum(kind, values),
    })
}

/// The name of a model kind as the device reports it.
pub fn model_kind_name(k: WireModelKind) -> &'static str {
    match k {
        WireModelKind::Lr => "lr",
        WireModelKind::Lrx => "lrx",
        WireModelKind::Rnn => "rnn",
        WireModelKind::FeAts => "fe-ats",
    }
}

/// The name of a record's source as the device reports it.
pub fn record_source_name(s: RecordSource) -> &'static str {
    match s {
        RecordSource::Compiled => "compiled in",
        RecordSource::Uploaded => "uploaded",
    }
}

/// What a recording is of: `# key: value` lines before the CSV header (the ground motion as given
/// and its name, the scale, the record's and the model's checksums as the device reported them, the
/// scenario, the structure...), read back by `rths report` to compute the reference.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunHeader {
    /// The fields, in order.
    pub fields: Vec<(String, String)>,
}

/// The first header line of a recording with a header.
pub const RECORDING_FORMAT: &str = "rths-recording 1";

impl RunHeader {
    /// Set `key` (replacing an earlier value).
    pub fn set(&mut self, key: &str, value: impl std::fmt::Display) {
        let v = value.to_string().replace(['\n', '\r'], " ");
        match self.fields.iter_mut().find(|(k, _)| k == key) {
            Some(f) => f.1 = v,
            None => self.fields.push((key.to_string(), v)),
        }
    }

    /// The value of `key`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// The header lines (`# format: rths-recording 1` first).
    pub fn lines(&self) -> Vec<String> {
        std::iter::once(format!("# format: {RECORDING_FORMAT}"))
            .chain(self.fields.iter().map(|(k, v)| format!("# {k}: {v}")))
            .collect()
    }
}

/// One row of a recording read back.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingRow {
    /// Record number.
    pub seq: u32,
    /// Tick from the run's start.
    pub tick: u32,
    /// State name ([`state_name`]).
    pub state: String,
    /// Command sent at this tick, mm.
    pub command_mm: f64,
    /// Target produced at this tick, mm.
    pub target_mm: f64,
    /// Measured displacement read at this tick, mm.
    pub measured_mm: f64,
    /// Measured force read at this tick, kN.
    pub force_kn: f64,
}

/// A recording (`rths link run/record --out`) read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Its header (empty for a recording without one).
    pub header: RunHeader,
    /// Its rows.
    pub rows: Vec<RecordingRow>,
}

/// Read a recording's text: optional `# key: value` lines, the [`CSV_HEADER`], the rows.
pub fn read_recording(text: &str) -> Result<Recording, LinkHostError> {
    let bad =
        |line: usize, why: String| LinkHostError::Motion(format!("recording line {line}: {why}"));
    let mut header = RunHeader::default();
    let mut lines = text.lines().enumerate();
    loop {
        let Some((i, l)) = lines.next() else {
            return Err(bad(0, "no CSV header".into()));
        };
        if let Some(kv) = l.strip_prefix('#') {
            let (k, v) = kv
                .split_once(':')
                .ok_or_else(|| bad(i + 1, format!("not `# key: value`: {l}")))?;
            let (k, v) = (k.trim(), v.trim());
            if k == "format" {
                if v != RECORDING_FORMAT {
                    return Err(bad(i + 1, format!("unknown format `{v}`")));
                }
            } else {
                header.set(k, v);
            }
            continue;
        }
        if l.trim() != CSV_HEADER {
            return Err(bad(i + 1, format!("expected the header `{CSV_HEADER}`")));
        }
        break;
    }
    let mut rows = Vec::new();
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 8 {
            return Err(bad(i + 1, format!("{} fields, expected 8", f.len())));
        }
        let num = |j: usize| -> Result<f64, LinkHostError> {
            f[j].trim()
                .parse::<f64>()
                .map_err(|e| bad(i + 1, format!("field {}: {e}", j + 1)))
        };
        let int = |j: usize| -> Result<u32, LinkHostError> {
            f[j].trim()
                .parse::<u32>()
                .map_err(|e| bad(i + 1, format!("field {}: {e}", j + 1)))
        };
        rows.push(RecordingRow {
            seq: int(0)?,
            tick: int(1)?,
            state: f[3].trim().to_string(),
            command_mm: num(4)?,
            target_mm: num(5)?,
            measured_mm: num(6)?,
            force_kn: num(7)?,
        });
    }
    Ok(Recording { header, rows })
}

/// The CSV header of a recording.
pub const CSV_HEADER: &str = "seq,tick,time_s,state,command_mm,target_mm,measured_mm,force_kn";

/// One CSV row (floats in shortest round-trip form: reading them back gives the same bits).
pub fn csv_row(t: &Telemetry) -> String {
    format!(
        "{},{},{:?},{},{:?},{:?},{:?},{:?}",
        t.seq,
        t.tick,
        t.tick as f64 * rths_core::params::DT_S,
        state_name(t.state),
        t.command_mm,
        t.target_mm,
        t.measured_mm,
        t.force_kn
    )
}

/// A state's name in the CSV and the status print.
pub fn state_name(s: RunState) -> String {
    match s {
        RunState::Idle => "idle".into(),
        RunState::Armed => "armed".into(),
        RunState::Running => "running".into(),
        RunState::RampDown => "ramp-down".into(),
        RunState::Done => "done".into(),
        RunState::Fault(c) => format!("fault-{}", fault_name(c)),
    }
}

/// The name of a fault code (`rths_core::supervisor::FaultReason`'s table); "Unknown" for a code
/// this host does not know (a newer firmware's).
pub fn fault_name(code: u8) -> &'static str {
    FaultReason::from_code(code).map_or("Unknown", FaultReason::name)
}

/// The QEMU command line of the emulated board with its link port (USART2, QEMU's second serial
/// port) connected, as a client, to `127.0.0.1:port` (the runner of `firmware/.cargo/config.toml`
/// with `-serial tcp:` after its `-serial null`).
pub fn qemu_args(elf: &Path, port: u16) -> Vec<String> {
    let serial = format!("tcp:127.0.0.1:{port}");
    [
        "-cpu",
        "cortex-m4",
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-serial",
        &serial,
        "-semihosting-config",
        "enable=on,target=native",
        "-icount",
        "shift=0,align=off,sleep=off",
        "-kernel",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([elf.display().to_string()])
    .collect()
}

/// A QEMU of our own running the link firmware, its serial port on a loopback socket.
pub struct Qemu {
    child: Child,
    /// The link to it.
    pub link: Link,
    /// Where QEMU's stdout (the semihosting RESULT line) goes.
    pub stdout_path: PathBuf,
}

impl Qemu {
    /// Start `qemu-system-arm` on `elf` (built with `--features link`), run in `dir` (its defmt.bin
    /// and stdout file go there), and accept its serial connection.
    pub fn start(elf: &Path, dir: &Path) -> Result<Self, LinkHostError> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let port = listener.local_addr()?.port();
        let stdout_path = dir.join("qemu-stdout.txt");
        let out = std::fs::File::create(&stdout_path)?;
        let mut child = Command::new("qemu-system-arm")
            .args(qemu_args(elf, port))
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| LinkHostError::Qemu(format!("cannot start qemu-system-arm: {e}")))?;
        listener.set_nonblocking(true)?;
        let start = Instant::now();
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if let Some(st) = child.try_wait()? {
                        return Err(LinkHostError::Qemu(format!("exited early: {st}")));
                    }
                    if start.elapsed() > Duration::from_secs(20) {
                        let _ = child.kill();
                        let _ = child.wait();
                        return Err(LinkHostError::Qemu("did not connect within 20 s".into()));
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => return Err(e.into()),
            }
        };
        stream.set_nonblocking(false)?;
        stream.set_nodelay(true)?;
        let mut q = Self {
            child,
            link: Link::new(Box::new(stream)),
            stdout_path,
        };
        q.link.wait_ready(Duration::from_secs(20))?;
        Ok(q)
    }

    /// What QEMU printed so far (semihosting: the CALIB and RESULT lines).
    pub fn stdout(&self) -> String {
        std::fs::read_to_string(&self.stdout_path).unwrap_or_default()
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_reads_back_and_bad_ones_are_refused() {
        let mut h = RunHeader::default();
        h.set("motion", "el-centro");
        h.set("scale", "0.5");
        h.set("scale", "0.75");
        let mut text = h.lines().join("\n");
        text.push('\n');
        text.push_str(CSV_HEADER);
        text.push_str("\n0,0,0.0,running,1.5,1.25,NaN,0.0\n\n");
        let r = read_recording(&text).unwrap();
        assert_eq!(r.header.get("scale"), Some("0.75"), "set replaces");
        assert_eq!(r.header, h);
        assert_eq!(r.rows.len(), 1);
        assert_eq!((r.rows[0].command_mm, r.rows[0].target_mm), (1.5, 1.25));
        assert!(r.rows[0].measured_mm.is_nan());
        for bad in [
            "",
            "# format: rths-recording 9\n",
            "# no colon\n",
            "seq,tick\n",
            &format!("{CSV_HEADER}\n0,0,0.0,running,1.5\n"),
            &format!("{CSV_HEADER}\n0,x,0.0,running,1.5,0,0,0\n"),
            &format!("{CSV_HEADER}\n0,0,0.0,running,one,0,0,0\n"),
        ] {
            assert!(read_recording(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn record_and_model_messages_chunk_and_check_their_input() {
        let samples: Vec<f64> = (0..25).map(|i| i as f64 * 0.01).collect();
        let m = record_messages(&samples, 0.02, 1.0).unwrap();
        assert_eq!(m.len(), 1 + 3 + 1, "begin, 12 + 12 + 1, commit");
        match m[3] {
            HostMsg::RecordChunk { seq, count, .. } => assert_eq!((seq, count), (2, 1)),
            _ => panic!("{:?}", m[3]),
        }
        assert!(record_messages(&samples[..1], 0.02, 1.0).is_err());
        assert!(record_messages(&[0.0, f64::NAN], 0.02, 1.0).is_err());
        assert!(record_messages(&samples, 0.0, 1.0).is_err());
        assert!(record_messages(&samples, 0.02, f64::INFINITY).is_err());
        let lrx = ModelFile::from_json(include_str!("../data/models/lrx.json")).unwrap();
        let m = model_messages(&lrx).unwrap();
        assert_eq!(m.len(), 1 + 2 + 1, "begin, 12 + 8 values, commit");
        let lr = ModelFile::from_json(include_str!("../data/models/lr.json")).unwrap();
        assert!(model_messages(&lr).is_err(), "LR goes in one UploadLr");
    }
}
