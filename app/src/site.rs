//! The board as an experimental site (docs/site.md): the host's `rths site` streams an outside
//! integrator's targets over the link, one per integration step; the control task's controller
//! (core's predictor-corrector as its analytical part, the rig's lead as its compensator, the
//! supervisor) imposes them tick by tick, and each step's end goes back with the DAQ's reading.
//!
//! The link's request handling (`crate::link::handle`) calls these and keeps its session's
//! bookkeeping (the stream's numbering, the expected step) itself. The telemetry task sends a
//! step's end before the step's telemetry ([`Outbox`]): the force is what the host and its
//! integrator wait for; the records of every tick follow while the integrator computes.

use rths_core::compensator::{LeadParams, LEAD_TAPS};
use rths_core::control::{Controller, SiteError};
use rths_core::predictor_corrector::{PcError, PcParams, SITE_ORDER};
use rths_core::supervisor::State;
use rths_link::{DeviceMsg, NackReason};

use crate::{Run, TelemetryRecord};

/// `SiteBegin`: at rest, the controller becomes a site of `ticks_per_step` with the lead of
/// `lead_weights` / `lead_stride` (stride 0: none), armed (`at_measured`: a real rig after a
/// finished test, at its measured position; `None`: the emulated plant, at 0) and started, the
/// run's statistics restarted. `may_arm`: the emulated plant has not run yet (`Unsupported`
/// otherwise: it plays once per power-up).
pub fn begin(
    ctl: &mut Controller,
    run: &mut Run,
    may_arm: bool,
    at_measured: Option<f64>,
    ticks_per_step: u32,
    lead_weights: &[f64; LEAD_TAPS],
    lead_stride: u16,
) -> Result<(), NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    if !may_arm {
        return Err(NackReason::Unsupported);
    }
    if lead_weights.iter().any(|w| !w.is_finite()) {
        return Err(NackReason::NotFinite);
    }
    let pc = PcParams::new(ticks_per_step, SITE_ORDER).map_err(|_| NackReason::OutOfRange)?;
    let lead = match lead_stride {
        0 => None,
        n => Some(
            LeadParams::new(*lead_weights, usize::from(n)).map_err(|_| NackReason::OutOfRange)?,
        ),
    };
    ctl.install_site(pc, lead).map_err(|_| NackReason::Busy)?;
    match at_measured {
        None => ctl.supervisor_mut().arm(),
        Some(m) => ctl.supervisor_mut().arm_at(m),
    }
    .map_err(|_| NackReason::InvalidState)?;
    ctl.supervisor_mut()
        .start()
        .map_err(|_| NackReason::InvalidState)?;
    run.restart();
    Ok(())
}

/// `SiteTarget`: the target of step `step`, which must be `expected_step` (steps numbered from 0
/// without a gap: `Sequence`); refused when the controller is no site or not running
/// (`InvalidState`), for a non-finite target (`NotFinite`), or while the previous step is under
/// way (`Busy`).
pub fn target(
    ctl: &mut Controller,
    expected_step: u32,
    step: u32,
    target_mm: f64,
) -> Result<(), NackReason> {
    if ctl.site_progress().is_none() {
        return Err(NackReason::InvalidState);
    }
    if step != expected_step {
        return Err(NackReason::Sequence);
    }
    ctl.site_target(target_mm).map_err(|e| match e {
        SiteError::NotASite | SiteError::NotRunning => NackReason::InvalidState,
        SiteError::Target(PcError::NonFinite) => NackReason::NotFinite,
        SiteError::Target(PcError::Pending) => NackReason::Busy,
    })
}

/// `SiteEnd`: the end of the test: the supervisor's end ramp to zero, or (`fault`) its emergency
/// ramp to the armed position. Refused when the controller is no site (`InvalidState`).
pub fn end(ctl: &mut Controller, fault: bool) -> Result<(), NackReason> {
    if ctl.site_progress().is_none() {
        return Err(NackReason::InvalidState);
    }
    let sup = ctl.supervisor_mut();
    if fault {
        sup.emergency_stop();
    } else if sup.state() == State::Running {
        sup.finish().map_err(|_| NackReason::InvalidState)?;
    }
    Ok(())
}

/// The emulated plant waits for the site's next target: the controller is a running site with no
/// target pending, so the control task leaves the plant where it is (as the host's virtual rig
/// waits for its client). A real rig never waits: its predictor runs.
pub fn waits(ctl: &Controller) -> bool {
    ctl.supervisor().state() == State::Running && matches!(ctl.site_progress(), Some((false, _)))
}

/// A step's end, noted by the control task: the step's number and the tick it ended at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepEnd {
    /// Step number, from 0.
    pub step: u32,
    /// The run's tick.
    pub tick: u32,
}

/// After a control tick `k`: the step that ended at it, if one did. `seen` is the count of steps
/// ended so far (the control task's; 0 at the run's first tick).
pub fn step_ended(ctl: &Controller, k: u32, seen: &mut u32) -> Option<StepEnd> {
    if k == 0 {
        *seen = 0;
    }
    let (_, done) = ctl.site_progress()?;
    if done == *seen {
        return None;
    }
    *seen = done;
    Some(StepEnd {
        step: done.wrapping_sub(1),
        tick: k,
    })
}

/// The `SiteStep` of a step that ended at the tick of record `r` (its DAQ reading).
pub fn step_message(end: StepEnd, r: &TelemetryRecord) -> DeviceMsg {
    DeviceMsg::SiteStep {
        step: end.step,
        tick: end.tick,
        measured_mm: r.measured_mm,
        force_kn: r.force_kn,
    }
}

/// The `SiteStep` of a step whose record the telemetry queue dropped: no reading (the host stops
/// on it).
fn unread_step(end: StepEnd) -> DeviceMsg {
    DeviceMsg::SiteStep {
        step: end.step,
        tick: end.tick,
        measured_mm: f64::NAN,
        force_kn: f64::NAN,
    }
}

/// The records the outbox holds at most: the control task's telemetry queue's depth.
pub const OUTBOX_RECORDS: usize = 64;

/// While a site's step runs, its records wait in the outbox up to this many; beyond, the oldest go
/// out during the step (a step longer than this many ticks), so the telemetry queue never fills.
pub const HOLD_RECORDS: usize = 48;

/// What the telemetry task sends next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outgoing {
    /// A tick's record (the session numbers it and makes it a `Telemetry`).
    Record(TelemetryRecord),
    /// A site's step end: the `SiteStep` to send, then take the step end off its queue.
    StepEnd(DeviceMsg),
}

/// The telemetry task's outbox: the records taken from the control task's queue, sent in the
/// order a site's host needs. A step's records wait while the step runs (in QEMU a record sent
/// costs the emulated UART's time, during which no tick runs; on a board, its UART's); at its
/// end the `SiteStep` with the step's last reading goes first, then the records. A fault or any
/// state but running sends the records first, as they come, so the host sees a fault before a
/// step's end. Outside a site's step (a test, an identification, a board's ticks between two
/// steps) records go out as they come.
#[derive(Debug)]
pub struct Outbox {
    held: heapless::Deque<TelemetryRecord, OUTBOX_RECORDS>,
    /// The last record handed out (a step end may come after its record went).
    last: Option<TelemetryRecord>,
}

impl Default for Outbox {
    fn default() -> Self {
        Self::new()
    }
}

impl Outbox {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            held: heapless::Deque::new(),
            last: None,
        }
    }

    /// Take record `r` from the telemetry queue; `Err(r)` when the outbox is full (leave it there).
    pub fn push(&mut self, r: TelemetryRecord) -> Result<(), TelemetryRecord> {
        self.held.push_back(r)
    }

    /// No room for another record.
    pub fn is_full(&self) -> bool {
        self.held.is_full()
    }

    /// Records held.
    pub fn len(&self) -> usize {
        self.held.len()
    }

    /// No record held.
    pub fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    fn pop(&mut self) -> Option<Outgoing> {
        let r = self.held.pop_front()?;
        self.last = Some(r);
        Some(Outgoing::Record(r))
    }

    /// What to send next, if anything: `end`, the first step end queued; `open`, a site's step is
    /// under way with its supervisor running (the control task's word after its last tick);
    /// `flush`, the run is over (send everything: a step end whose record never came goes with no
    /// reading). `None`: nothing now (held for the step's end, or a step end's record is still in
    /// the telemetry queue: the task runs again after the next tick).
    pub fn next(&mut self, end: Option<StepEnd>, open: bool, flush: bool) -> Option<Outgoing> {
        if let Some(e) = end {
            if let Some(i) = self.held.iter().position(|r| r.tick == e.tick) {
                // The step's end first, unless a record up to it is not running (a fault): the
                // host must see that first.
                let running = self
                    .held
                    .iter()
                    .take(i + 1)
                    .all(|r| r.state == State::Running);
                if running {
                    return self
                        .held
                        .iter()
                        .nth(i)
                        .map(|r| Outgoing::StepEnd(step_message(e, r)));
                }
                return self.pop();
            }
            if let Some(r) = self.last.filter(|r| r.tick == e.tick) {
                return Some(Outgoing::StepEnd(step_message(e, &r)));
            }
            let newest = self.held.back().or(self.last.as_ref()).map(|r| r.tick);
            if flush || newest.is_some_and(|t| t > e.tick) {
                // Its record was dropped (the telemetry queue was full).
                return Some(Outgoing::StepEnd(unread_step(e)));
            }
            if !self.is_full() {
                // Its record is still in the telemetry queue.
                return None;
            }
        }
        if open && !flush && self.held.len() < HOLD_RECORDS {
            return None;
        }
        self.pop()
    }
}

#[cfg(test)]
mod tests;
