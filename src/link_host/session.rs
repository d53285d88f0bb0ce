//! A session with a device: send requests, wait for their answers, upload models, records and rig
//! compensations, arm, start and abort a test, and receive its telemetry (or an identification's
//! samples) with the sequence numbers checked.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use rths_link::{
    DeviceMsg, FrameReader, Gap, Holdings, HostMsg, ModelKind as WireModelKind, Request, RunState,
    SeqCheck, Status, StreamStatus, Telemetry, MAX_FRAME,
};

use super::error::LinkHostError;
use super::stream::StreamFeed;
use super::transport::{self, Port};
use super::wire::{
    fe_ats_messages, laid_out_messages, lrx_rig_extras, model_messages, record_messages,
    rig_messages, stream_messages, upload_message,
};
use crate::machinery::model_file::{ModelFile, ModelKind};
use rths_files::upload::LaidOut;

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
    /// A streamed record's state at the run's end (`None`: the record was held whole).
    pub stream: Option<StreamStatus>,
    /// A streamed record's chunks sent again after a loss.
    pub stream_resent: usize,
    /// The streamed record's state could not be read after the run (why).
    pub stream_status_error: Option<String>,
}

impl RecordSummary {
    /// Nothing lost: no gap, no bad frame, the device sent all it recorded and dropped none; a
    /// streamed record arrived whole, checksum matching, and no tick ran short of it.
    pub fn complete(&self) -> bool {
        self.gaps.is_empty()
            && self.bad_frames == 0
            && matches!(self.end, Some((_, _, sent, 0)) if sent as usize == self.records)
            && self.stream_status_error.is_none()
            && self
                .stream
                .is_none_or(|st| st.underrun_ticks == 0 && st.checksum_ok == Some(true))
    }
}

/// While a streamed record has chunks to send and the device can take none, ask for its room
/// this often (its ring holds seconds of record: 4,096 samples are 20 s at 200 Hz).
const STREAM_POLL: Duration = Duration::from_millis(20);

/// Chunks in flight with no answer for this long were lost (with their answers): send them again
/// (the emulated board's answers take up to ~35 ms; a real UART's a few).
const STREAM_STALL: Duration = Duration::from_millis(200);

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
    /// The streamed record whose chunks [`Self::record`] sends during the run.
    stream: Option<StreamFeed>,
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
            stream: None,
        }
    }

    /// A TCP connection (QEMU `-serial tcp:127.0.0.1:PORT,server=on`).
    pub fn tcp(addr: &str) -> Result<Self, LinkHostError> {
        Ok(Self::new(transport::tcp(addr)?))
    }

    /// A serial device at `baud`, 8N1, raw.
    pub fn serial(path: &str, baud: u32) -> Result<Self, LinkHostError> {
        Ok(Self::new(transport::serial(path, baud)?))
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
                DeviceMsg::StreamAck { .. } if req == Request::StreamChunk => break m,
                DeviceMsg::StreamStatus(_) if req == Request::StreamStatus => break m,
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
        for m in rig_messages(kind, values)? {
            self.expect_ack(&m)?;
        }
        Ok(rths_link::rig_checksum(kind, values))
    }

    /// Upload a model laid out from a lab's files (`rths_files::upload::lay_out_files`: a
    /// structure's finite elements or one of its models, or a model file), in chunks, then the
    /// rig compensation its file carries, if any. Its checksum on success.
    pub fn upload_laid_out(&mut self, laid: &LaidOut) -> Result<u32, LinkHostError> {
        let msgs = laid_out_messages(laid)?;
        for m in &msgs {
            self.expect_ack(m)?;
        }
        if let Some(v) = &laid.rig {
            self.upload_rig(laid.kind, v)?;
        }
        match msgs.first() {
            Some(HostMsg::ModelBegin { checksum, .. }) => Ok(*checksum),
            _ => Err(LinkHostError::Model("no model begin".into())),
        }
    }

    /// Make the device's analytical part its own finite elements with the ATS starting from
    /// `expected_delay_s` (a chunked upload of one value), whatever its compiled-in part. Its
    /// checksum on success.
    pub fn upload_fe_ats(&mut self, expected_delay_s: f64) -> Result<u32, LinkHostError> {
        let msgs = fe_ats_messages(expected_delay_s)?;
        for m in &msgs {
            self.expect_ack(m)?;
        }
        match msgs.first() {
            Some(HostMsg::ModelBegin { checksum, .. }) => Ok(*checksum),
            _ => Err(LinkHostError::Model("no model begin".into())),
        }
    }

    /// Upload a model of any kind, whatever the image's compiled-in part: an LR model in one
    /// `UploadLr`, another kind in chunks (`ModelBegin`, the chunks, `ModelCommit`, each
    /// acknowledged; a model the board's tick cannot run is refused at the commit, `TickBudget`).
    /// Its checksum on success.
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

    /// Stream a ground-motion record longer than the device holds (as [`Self::upload_record`]):
    /// `StreamBegin`, the chunks that fill the device's ring, `RecordCommit`; the rest go during
    /// the run, from [`Self::record`], as the ring frees up. Its checksum on success.
    pub fn stream_record(
        &mut self,
        samples_g: &[f64],
        dt_s: f64,
        scale: f64,
    ) -> Result<u32, LinkHostError> {
        let (begin, chunks) = stream_messages(samples_g, dt_s, scale)?;
        self.stream = None;
        self.expect_ack(&begin)?;
        let mut free = usize::MAX;
        let mut sent = 0;
        for m in &chunks {
            let HostMsg::StreamChunk { seq, count, .. } = *m else {
                break;
            };
            if usize::from(count) > free {
                break;
            }
            match self.request(m)? {
                DeviceMsg::StreamAck {
                    next_seq, free: f, ..
                } if next_seq == seq + 1 => {
                    free = f as usize;
                    sent += 1;
                }
                other => return Err(LinkHostError::Unexpected(Request::StreamChunk, other)),
            }
        }
        self.expect_ack(&HostMsg::RecordCommit)?;
        self.stream = Some(StreamFeed::new(chunks, sent, free));
        Ok(rths_link::record_checksum(samples_g, dt_s))
    }

    /// Where the device's streamed record stands.
    pub fn stream_status(&mut self) -> Result<StreamStatus, LinkHostError> {
        match self.request(&HostMsg::StreamStatus)? {
            DeviceMsg::StreamStatus(s) => Ok(s),
            other => Err(LinkHostError::Unexpected(Request::StreamStatus, other)),
        }
    }

    /// Stop sending a streamed record's chunks (tests: a host that falls behind).
    pub fn stop_streaming(&mut self) {
        self.stream = None;
    }

    /// Send the streamed record's chunks the device can take now; ask for its room when it can
    /// take none and nothing is in flight (every [`STREAM_POLL`]); send again what was lost.
    fn pump_stream(
        &mut self,
        quiet: &mut Instant,
        polled: &mut Instant,
    ) -> Result<(), LinkHostError> {
        let Some(mut feed) = self.stream.take() else {
            return Ok(());
        };
        if feed.in_flight() > 0 && quiet.elapsed() >= STREAM_STALL {
            feed.go_back();
            *quiet = Instant::now();
        }
        let mut result = Ok(());
        while let Some(m) = feed.due() {
            result = self.send(&m);
            if result.is_err() {
                break;
            }
        }
        if result.is_ok()
            && !feed.done()
            && feed.in_flight() == 0
            && polled.elapsed() >= STREAM_POLL
        {
            result = self.send(&HostMsg::StreamStatus);
            *polled = Instant::now();
        }
        self.stream = Some(feed);
        result
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
            stream: None,
            stream_resent: 0,
            stream_status_error: None,
        };
        let bad0 = self.bad_frames;
        let (mut heard, mut beat) = (Instant::now(), Instant::now());
        let (mut quiet, mut polled) = (Instant::now(), Instant::now());
        loop {
            if let Some(every) = self.heartbeat {
                if beat.elapsed() >= every {
                    self.send(&HostMsg::Status)?;
                    beat = Instant::now();
                }
            }
            self.pump_stream(&mut quiet, &mut polled)?;
            let mut wait = idle
                .saturating_sub(heard.elapsed())
                .min(self.heartbeat.unwrap_or(idle));
            if self.stream.as_ref().is_some_and(|f| !f.done()) {
                wait = wait.min(STREAM_POLL);
            }
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
                        warn_gap("telemetry", "record", &g);
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
                DeviceMsg::StreamAck {
                    seq,
                    next_seq,
                    free,
                } => {
                    quiet = Instant::now();
                    if let Some(f) = self.stream.as_mut() {
                        f.answered(seq, next_seq, free);
                    }
                }
                DeviceMsg::StreamStatus(st) => {
                    quiet = Instant::now();
                    if let Some(f) = self.stream.as_mut() {
                        f.status(&st);
                    }
                }
                _ => {}
            }
        }
        s.missing = seq.missing();
        s.bad_frames = self.bad_frames - bad0;
        if let Some(f) = self.stream.take() {
            s.stream_resent = f.resent();
            // Kept whatever the answer: the summary of what arrived is not lost with it.
            match self.stream_status() {
                Ok(st) => s.stream = Some(st),
                Err(e) => s.stream_status_error = Some(e.to_string()),
            }
        }
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
                        warn_gap("identification", "sample", &g);
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

/// Report a sequence gap on stderr as it is found: `what` of the stream, `unit` of its items.
fn warn_gap(what: &str, unit: &str, g: &Gap) {
    eprintln!(
        "warning: {what} gap: expected {unit} {}, got {} ({} missing)",
        g.expected,
        g.got,
        g.got.wrapping_sub(g.expected)
    );
}
