//! The command link on the firmware side: the host's requests and the telemetry stream, over any
//! board's [`LinkPort`](crate::board::LinkPort). The protocol and framing are `rths-link`'s.

use rths_core::control::Controller;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_core::supervisor::{Limits, State, Supervisor};
use rths_link::{
    DeviceMsg, Holdings, HostMsg, IdentifySample, LinkLoss, ModelKind, NackReason, RecordSource,
    RunState, Status, Telemetry, LINK_TIMEOUT_TICKS, LR_COEFFS,
};

use crate::board::LinkPort;
use crate::identify::{FlashTables, Identification};
use crate::model_upload::ModelStaging;
use crate::record::RecordStore;
use crate::tick_cost::TickBudget;
use crate::{Run, TelemetryRecord};

/// The wire state of a supervisor state.
pub fn run_state(s: State) -> RunState {
    match s {
        State::Idle => RunState::Idle,
        State::Armed => RunState::Armed,
        State::Running => RunState::Running,
        State::RampDown => RunState::RampDown,
        State::Done => RunState::Done,
        State::Fault(r) => RunState::Fault(r.code()),
    }
}

/// The checksum of the compiled-in LR model.
pub fn compiled_model_checksum(theta: &[f64; LR_COEFFS]) -> u32 {
    rths_link::model_checksum(theta, PAPER_DELAY_STEPS as u16)
}

/// Validate an uploaded LR model and swap it in whole; the old one stays on any refusal.
/// Returns the new model's checksum.
pub fn upload_lr(
    ctl: &mut Controller,
    features: u8,
    theta: &[f64; LR_COEFFS],
    delay_steps: u16,
    checksum: u32,
) -> Result<u32, NackReason> {
    use rths_core::metamodel::LrParams;
    if features as usize != LR_COEFFS {
        return Err(NackReason::Shape);
    }
    if theta.iter().any(|t| !t.is_finite()) {
        return Err(NackReason::NotFinite);
    }
    if rths_link::model_checksum(theta, delay_steps) != checksum {
        return Err(NackReason::Checksum);
    }
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    let params = LrParams::new(*theta).map_err(|_| NackReason::NotFinite)?;
    // Whatever the image's compiled-in kind: an LR model runs without a compensator, as the host's
    // `lr-online` does.
    ctl.install_lr(params).map_err(|_| NackReason::Busy)?;
    Ok(checksum)
}

/// New stroke, velocity and force limits (the other settings stay those in force). Only at rest
/// with the command at 0 mm: a new supervisor starts idle at 0 mm, so anything else would move the
/// actuator.
pub fn set_limits(
    ctl: &mut Controller,
    stroke_mm: f64,
    velocity_mm_s: f64,
    force_kn: f64,
) -> Result<(), NackReason> {
    if ![stroke_mm, velocity_mm_s, force_kn]
        .iter()
        .all(|v| v.is_finite())
    {
        return Err(NackReason::NotFinite);
    }
    let d = Limits::paper_actuator();
    let limits = Limits::new(
        stroke_mm,
        velocity_mm_s,
        force_kn,
        8,
        4,
        d.fault_ramp_rate_mm_s(),
        d.end_ramp_rate_mm_s(),
        DT_S,
    )
    .map_err(|_| NackReason::OutOfRange)?;
    let s = ctl.supervisor_mut();
    if !s.at_rest() || s.output_mm() != 0.0 {
        return Err(NackReason::Busy);
    }
    *s = Supervisor::new(limits);
    Ok(())
}

/// After an upload of a `kind` model of checksum `crc` replaced the one in force: the status
/// reports it; its rig compensation is the upload's (an LRX brings its own lead filter) or none
/// yet (another kind than before: the old kind's rig values do not apply to it).
fn model_replaced(s: &mut Session<'_>, kind: ModelKind, crc: u32) {
    if kind == ModelKind::Lrx || kind != s.model_kind {
        s.rig_source = RecordSource::Uploaded;
    }
    s.model_kind = kind;
    s.model_checksum = crc;
    s.model_source = RecordSource::Uploaded;
}

/// How the board's rig is armed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rearm {
    /// The emulated plant: it starts exactly at rest at 0 mm, as the host simulation's does, so arm
    /// there; the plant and the record play once per power-up, so a second `Arm` is refused.
    OncePerPowerUp,
    /// A real rig: after a finished run back to idle first (refused unless at rest), then arm at the
    /// measured position so that the first command does not step.
    AtMeasured,
}

/// The link's side of a session: the telemetry stream's numbering and the model in force.
#[derive(Debug)]
pub struct Session<'a> {
    /// Telemetry decimation (≥ 1): every `every`-th record is sent.
    pub every: u32,
    /// Next telemetry sequence number (= records sent in this run).
    pub seq: u32,
    /// Frames that failed COBS, CRC or decoding.
    pub bad_frames: u32,
    /// The active model's checksum.
    pub model_checksum: u32,
    /// The board's tick: an uploaded model it cannot run is refused `TickBudget`.
    pub tick_budget: TickBudget,
    /// How `Arm` arms.
    pub rearm: Rearm,
    /// The kind of the analytical part in force (reported in the status): the compiled-in one
    /// until an upload of any kind replaces it.
    pub model_kind: ModelKind,
    /// A chunked model upload in progress.
    pub model_upload: ModelStaging<'a>,
    /// A chunked rig-compensation upload in progress.
    pub rig_upload: crate::rig_upload::RigStaging,
    /// What the run in progress does if the host falls silent (chosen at arm time).
    pub link_loss: LinkLoss,
    /// The arming host's token (0: none, anyone may start).
    pub owner: u32,
    /// The identification excitation's tables (`None`: this build cannot identify).
    pub excitation: Option<FlashTables>,
    /// The stream is an identification's ([`DeviceMsg::IdentifySample`]), not a run's.
    pub identifying: bool,
    /// The model in force is the compiled-in one or an upload.
    pub model_source: RecordSource,
    /// The rig compensation in force is the compiled-in one or an upload.
    pub rig_source: RecordSource,
    /// The firmware build's identity (reported in [`Holdings`]).
    pub build_id: u32,
    /// A site's next step number (`HostMsg::SiteTarget`).
    pub site_step: u32,
}

impl<'a> Session<'a> {
    /// A session with the compiled-in model of `model_checksum`, of kind `model_kind`, on a board
    /// of `tick_budget`; chunked model uploads of any kind are staged in `staging`
    /// ([`rths_link::MODEL_MAX_VALUES`]; shorter: the longer uploads are refused `TooLong`).
    pub fn new(
        model_checksum: u32,
        tick_budget: TickBudget,
        rearm: Rearm,
        model_kind: ModelKind,
        staging: &'a mut [f64],
    ) -> Self {
        Self {
            every: 1,
            seq: 0,
            bad_frames: 0,
            model_checksum,
            tick_budget,
            rearm,
            model_kind,
            model_upload: ModelStaging::new(staging),
            rig_upload: crate::rig_upload::RigStaging::new(),
            link_loss: LinkLoss::Complete,
            owner: 0,
            excitation: None,
            identifying: false,
            model_source: RecordSource::Compiled,
            rig_source: RecordSource::Compiled,
            build_id: 0,
            site_step: 0,
        }
    }

    /// This session with the identification excitation's tables (`rths link ... identify`).
    pub fn with_excitation(mut self, tables: FlashTables) -> Self {
        self.excitation = Some(tables);
        self
    }

    /// The same session, reporting `build_id` as the firmware build's identity.
    pub fn with_build_id(self, build_id: u32) -> Self {
        Self { build_id, ..self }
    }

    /// The telemetry message of `r`, numbered, or `None` if decimation skips it.
    pub fn telemetry(&mut self, r: &TelemetryRecord) -> Option<DeviceMsg> {
        // checked_rem: `every` ≥ 1 (`Arm` refuses 0), and no panic path in the telemetry task.
        if r.tick.checked_rem(self.every) != Some(0) {
            return None;
        }
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        if self.identifying {
            return Some(DeviceMsg::IdentifySample(IdentifySample {
                seq,
                command_mm: r.command_mm,
                measured_mm: r.measured_mm,
                force_kn: r.force_kn,
            }));
        }
        Some(DeviceMsg::Telemetry(Telemetry {
            seq,
            tick: r.tick,
            state: run_state(r.state),
            command_mm: r.command_mm,
            target_mm: r.target_mm,
            measured_mm: r.measured_mm,
            force_kn: r.force_kn,
        }))
    }

    /// The message that closes an identification's stream.
    pub fn identify_ended(&self, id: &Identification) -> DeviceMsg {
        DeviceMsg::IdentifyEnded {
            state: run_state(id.state),
            ticks: id.ticks,
            samples_sent: self.seq,
            samples_dropped: id.dropped,
        }
    }

    /// The message that closes a run's stream.
    pub fn run_ended(&self, run: &Run) -> DeviceMsg {
        DeviceMsg::RunEnded {
            state: run_state(run.state),
            ticks: run.ticks,
            records_sent: self.seq,
            records_dropped: run.telemetry_dropped,
        }
    }
}

/// What a handled request asks of the firmware besides its answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Effect {
    /// Nothing.
    None,
    /// The run started: play the record from tick 0.
    Started,
    /// The identification started (the supervisor is running): play this excitation from tick 0
    /// (`crate::identify::Identification::start`) before the control task's next tick.
    Identify(rths_core::identify_excitation::Player),
}

/// Handle one request: its answer (always exactly one) and its effect. `finished`: the emulated
/// plant's run is over. Runs at the link's priority with the controller, the run and the record
/// store locked: it does no I/O (the caller sends the answer after unlocking), and its longest
/// work, a record chunk, is a copy and a CRC of [`rths_link::RECORD_CHUNK`] samples.
pub fn handle(
    msg: HostMsg,
    ctl: &mut Controller,
    run: &mut Run,
    store: &mut RecordStore<'_>,
    s: &mut Session<'_>,
    finished: bool,
) -> (DeviceMsg, Effect) {
    let req = msg.request();
    // A record is replaced only at rest: the control task plays it during a run.
    let at_rest = ctl.supervisor().at_rest();
    let result: Result<Effect, NackReason> = match msg {
        HostMsg::Status => return (DeviceMsg::Status(status(ctl, s, run, store)), Effect::None),
        HostMsg::RecordBegin {
            samples,
            dt_s,
            scale,
            checksum,
        } => store
            .begin(samples, dt_s, scale, checksum, at_rest)
            .map(|()| Effect::None),
        HostMsg::RecordChunk { seq, count, values } => store
            .chunk(seq, count, &values, at_rest)
            .map(|()| Effect::None),
        HostMsg::RecordCommit => store.commit(at_rest).map(|_| Effect::None),
        HostMsg::StreamBegin {
            samples,
            dt_s,
            scale,
            checksum,
        } => store
            .stream_begin(samples, dt_s, scale, checksum, at_rest)
            .map(|()| Effect::None),
        // Taken during a run too: the ring is the control task's only while it reads a tick.
        HostMsg::StreamChunk { seq, count, values } => {
            return match store.stream_chunk(seq, count, &values) {
                Ok(a) => (
                    DeviceMsg::StreamAck {
                        seq: a.seq,
                        next_seq: a.next_seq,
                        free: a.free,
                    },
                    Effect::None,
                ),
                Err(n) => (DeviceMsg::Nack(req, n), Effect::None),
            }
        }
        HostMsg::StreamStatus => {
            return match store.stream_status() {
                Some(st) => (DeviceMsg::StreamStatus(st), Effect::None),
                None => (DeviceMsg::Nack(req, NackReason::Sequence), Effect::None),
            }
        }
        HostMsg::ModelBegin {
            kind,
            values,
            delay_steps,
            checksum,
        } => s
            .model_upload
            .begin(kind, values, delay_steps, checksum, at_rest)
            .map(|()| Effect::None),
        HostMsg::ModelChunk { seq, count, values } => s
            .model_upload
            .chunk(seq, count, &values, at_rest)
            .map(|()| Effect::None),
        HostMsg::ModelCommit => {
            let budget = s.tick_budget;
            s.model_upload
                .commit(ctl, at_rest, &budget)
                .map(|(kind, crc)| {
                    model_replaced(s, kind, crc);
                    Effect::None
                })
        }
        HostMsg::Holdings => return (DeviceMsg::Holdings(holdings(ctl, s)), Effect::None),
        HostMsg::UploadRig {
            kind,
            count,
            values,
            checksum,
        } => {
            let part = in_force(ctl, s);
            crate::rig_upload::upload_rig(ctl, &part, kind, count, &values, checksum).map(|_| {
                s.rig_source = RecordSource::Uploaded;
                Effect::None
            })
        }
        HostMsg::RigBegin {
            kind,
            values,
            checksum,
        } => s
            .rig_upload
            .begin(s.model_kind, kind, values, checksum, at_rest)
            .map(|()| Effect::None),
        HostMsg::RigChunk { seq, count, values } => s
            .rig_upload
            .chunk(seq, count, &values, at_rest)
            .map(|()| Effect::None),
        HostMsg::RigCommit => {
            let part = in_force(ctl, s);
            s.rig_upload.commit(ctl, &part).map(|_| {
                s.rig_source = RecordSource::Uploaded;
                Effect::None
            })
        }
        HostMsg::UploadLr {
            features,
            theta,
            delay_steps,
            checksum,
        } => upload_lr(ctl, features, &theta, delay_steps, checksum).map(|crc| {
            model_replaced(s, ModelKind::Lr, crc);
            Effect::None
        }),
        HostMsg::SetLimits {
            stroke_mm,
            velocity_mm_s,
            force_kn,
        } => set_limits(ctl, stroke_mm, velocity_mm_s, force_kn).map(|()| Effect::None),
        // A streamed record plays once: its ring no longer holds its start.
        HostMsg::Arm { .. } | HostMsg::ArmWith { .. } if !store.playable() => {
            Err(NackReason::Incomplete)
        }
        HostMsg::Arm { telemetry_every } => arm_request(
            ctl,
            run,
            s,
            finished,
            telemetry_every,
            LinkLoss::Complete,
            0,
        ),
        HostMsg::ArmWith {
            telemetry_every,
            on_link_loss,
            owner,
        } => arm_request(ctl, run, s, finished, telemetry_every, on_link_loss, owner),
        HostMsg::Start => start(ctl, s, 0),
        HostMsg::StartAs { owner } => start(ctl, s, owner),
        HostMsg::Abort => {
            ctl.supervisor_mut().abort();
            Ok(Effect::None)
        }
        HostMsg::Identify { amplitude_mm } => identify_request(ctl, run, s, finished, amplitude_mm),
        HostMsg::SiteBegin {
            ticks_per_step,
            lead_weights,
            lead_stride,
        } => {
            let (may_arm, at_measured) = arm_mode(s, run, finished);
            crate::site::begin(
                ctl,
                run,
                may_arm,
                at_measured,
                ticks_per_step,
                &lead_weights,
                lead_stride,
            )
            .map(|()| {
                // The stream restarts at `seq` 0, every tick. A real rig ramps down if the host
                // falls silent; the emulated board waits for each target (its plant holds), so
                // its virtual clock is no host's silence.
                s.identifying = false;
                s.every = 1;
                s.seq = 0;
                s.site_step = 0;
                s.owner = 0;
                s.link_loss = match s.rearm {
                    Rearm::OncePerPowerUp => LinkLoss::Complete,
                    Rearm::AtMeasured => LinkLoss::RampDown,
                };
                Effect::Started
            })
        }
        HostMsg::SiteTarget { step, target_mm } => {
            crate::site::target(ctl, s.site_step, step, target_mm).map(|()| {
                s.site_step = s.site_step.wrapping_add(1);
                Effect::None
            })
        }
        HostMsg::SiteEnd { fault } => crate::site::end(ctl, fault).map(|()| Effect::None),
    };
    match result {
        Ok(e) => (DeviceMsg::Ack(req), e),
        Err(n) => (DeviceMsg::Nack(req, n), Effect::None),
    }
}

/// The part in force, as a rig compensation is checked against it.
fn in_force(ctl: &Controller, s: &Session<'_>) -> crate::rig_upload::InForce {
    crate::rig_upload::InForce {
        kind: s.model_kind,
        dims: crate::rig_upload::dims_of(ctl),
        budget: Some(s.tick_budget),
    }
}

/// Start the armed test; a test armed with an owner token starts only for that token.
fn start(ctl: &mut Controller, s: &Session<'_>, owner: u32) -> Result<Effect, NackReason> {
    if s.owner != 0 && owner != s.owner && ctl.supervisor().state() == State::Armed {
        return Err(NackReason::NotOwner);
    }
    ctl.supervisor_mut()
        .start()
        .map(|()| Effect::Started)
        .map_err(|_| NackReason::InvalidState)
}

fn arm_request(
    ctl: &mut Controller,
    run: &mut Run,
    s: &mut Session<'_>,
    finished: bool,
    telemetry_every: u16,
    on_link_loss: LinkLoss,
    owner: u32,
) -> Result<Effect, NackReason> {
    if telemetry_every == 0 {
        return Err(NackReason::OutOfRange);
    }
    arm(ctl, run, s.rearm, finished)?;
    s.identifying = false;
    s.every = u32::from(telemetry_every);
    s.seq = 0;
    s.link_loss = on_link_loss;
    s.owner = owner;
    run.restart();
    Ok(Effect::None)
}

/// Start an identification (`HostMsg::Identify`): the build must have the excitation's tables; at
/// rest; the emulated plant only before its run (it plays once per power-up); a real rig armed at
/// its measured position. The stream restarts at `seq` 0, every tick.
fn identify_request(
    ctl: &mut Controller,
    run: &mut Run,
    s: &mut Session,
    finished: bool,
    amplitude_mm: f64,
) -> Result<Effect, NackReason> {
    let tables = s.excitation.ok_or(NackReason::Unsupported)?;
    let (may_arm, at_measured) = arm_mode(s, run, finished);
    let player = crate::identify::begin(ctl, &tables, amplitude_mm, may_arm, at_measured)?;
    s.identifying = true;
    s.every = 1;
    s.seq = 0;
    s.link_loss = LinkLoss::Complete;
    s.owner = 0;
    run.restart();
    Ok(Effect::Identify(player))
}

/// How a test that starts now is armed: (it may arm: the emulated plant plays once per
/// power-up, `finished` says it has; the position to arm at: a real rig's measured one, `None`
/// for the emulated plant's 0).
fn arm_mode(s: &Session<'_>, run: &Run, finished: bool) -> (bool, Option<f64>) {
    match s.rearm {
        Rearm::OncePerPowerUp => (!finished, None),
        Rearm::AtMeasured => (true, Some(run.last_disp_mm)),
    }
}

/// The host counts as lost: the run's policy is [`LinkLoss::RampDown`] and no valid frame came
/// for more than [`LINK_TIMEOUT_TICKS`] (`now_tick`, `last_heard_tick`: a free-running tick count
/// and its value at the last valid frame).
pub fn link_lost(policy: LinkLoss, now_tick: u32, last_heard_tick: u32) -> bool {
    policy == LinkLoss::RampDown && now_tick.wrapping_sub(last_heard_tick) > LINK_TIMEOUT_TICKS
}

fn arm(ctl: &mut Controller, run: &Run, rearm: Rearm, finished: bool) -> Result<(), NackReason> {
    match rearm {
        Rearm::OncePerPowerUp => {
            if finished {
                return Err(NackReason::Unsupported);
            }
            ctl.supervisor_mut()
                .arm()
                .map_err(|_| NackReason::InvalidState)
        }
        Rearm::AtMeasured => {
            if matches!(ctl.supervisor().state(), State::Done | State::Fault(_)) {
                ctl.reset().map_err(|_| NackReason::Busy)?;
            }
            ctl.supervisor_mut()
                .arm_at(run.last_disp_mm)
                .map_err(|_| NackReason::InvalidState)
        }
    }
}

/// The status answer.
pub fn status(ctl: &Controller, s: &Session<'_>, run: &Run, store: &RecordStore<'_>) -> Status {
    let sup = ctl.supervisor();
    let l = sup.limits();
    Status {
        state: run_state(sup.state()),
        model_checksum: s.model_checksum,
        tick: run.ticks,
        records_sent: s.seq,
        records_dropped: run.telemetry_dropped,
        stroke_mm: l.stroke_mm(),
        velocity_mm_s: l.velocity_mm_s(),
        force_kn: l.force_kn(),
        bad_frames: s.bad_frames,
        model_kind: s.model_kind,
        record: store.info(),
        record_capacity: store.capacity(),
    }
}

/// The holdings answer: the model's and the rig compensation's origin and checksums, the build.
pub fn holdings(ctl: &Controller, s: &Session<'_>) -> Holdings {
    Holdings {
        model_kind: s.model_kind,
        model_source: s.model_source,
        model_checksum: s.model_checksum,
        rig_source: s.rig_source,
        rig_checksum: crate::rig_upload::rig_checksum_of(ctl),
        rate_hz: rths_core::params::CONTROL_RATE_HZ,
        build_id: s.build_id,
    }
}

/// Encode `msg` as a frame and send it (a message too long for a frame, impossible with
/// `rths-link`'s types, is dropped).
pub fn send<P: LinkPort>(port: &mut P, msg: &DeviceMsg) {
    let mut buf = [0u8; rths_link::MAX_FRAME + 1];
    if let Ok(n) = rths_link::encode(msg, &mut buf) {
        if let Some(frame) = buf.get(..n) {
            port.write_all(frame);
        }
    }
}

#[cfg(test)]
mod tests;
