//! The board as an element's experimental side, over the command link (docs/site.md): the board's
//! controller is a site (`HostMsg::SiteBegin`), each target goes as a `SiteTarget`, every tick
//! comes back as telemetry and each step's end as a `SiteStep` with the DAQ's reading at it.

use std::time::{Duration, Instant};

use rths_core::compensator::LeadParams;
use rths_link::{DeviceMsg, HostMsg, RunState};

use super::experiment::{Experiment, ExperimentError, PacingStats, Reading, SiteRow};
use crate::link_host::{fault_name, Link, LinkHostError, Qemu};

/// How long a step may take on the board before the site stops the test (a whole step of the
/// slowest rate factor is far inside; the emulated board answers in milliseconds).
const STEP_TIMEOUT: Duration = Duration::from_secs(30);

/// How long the board may take to bring its actuator to rest after the end.
const END_TIMEOUT: Duration = Duration::from_secs(150);

/// The board's connection.
pub enum BoardLink {
    /// An emulated board this site started (QEMU, the link on a loopback socket).
    Qemu(Box<Qemu>),
    /// A board on a serial port.
    Port(Box<Link>),
}

impl BoardLink {
    fn link(&mut self) -> &mut Link {
        match self {
            BoardLink::Qemu(q) => &mut q.link,
            BoardLink::Port(l) => l,
        }
    }
}

/// One element on the board.
pub struct BoardExperiment {
    conn: BoardLink,
    lead: LeadParams,
    rows: Vec<SiteRow>,
    next_seq: u32,
    step: u32,
    state: RunState,
    ended: bool,
}

impl BoardExperiment {
    /// The board on `conn`, its delay compensation the rig file's identified `lead`.
    pub fn new(conn: BoardLink, lead: LeadParams) -> Self {
        Self {
            conn,
            lead,
            rows: Vec::new(),
            next_seq: 0,
            step: 0,
            state: RunState::Idle,
            ended: false,
        }
    }

    /// Keep a telemetry record; a gap in the stream is lost data, so it stops the test.
    fn keep(&mut self, t: &rths_link::Telemetry) -> Result<(), ExperimentError> {
        if t.seq != self.next_seq {
            return Err(ExperimentError::Board(format!(
                "telemetry gap: expected record {}, got {}",
                self.next_seq, t.seq
            )));
        }
        self.next_seq = t.seq.wrapping_add(1);
        self.state = t.state;
        self.rows.push(SiteRow {
            tick: t.tick,
            state: t.state,
            command_mm: t.command_mm,
            target_mm: t.target_mm,
            measured_mm: t.measured_mm,
            force_kn: t.force_kn,
        });
        Ok(())
    }

    /// Record until the board's `RunEnded` (its actuator at rest).
    fn until_ended(&mut self) {
        let deadline = Instant::now() + END_TIMEOUT;
        while !self.ended {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.conn.link().recv(left) {
                Ok(DeviceMsg::Telemetry(t)) => {
                    if let Err(e) = self.keep(&t) {
                        eprintln!("site: {e}");
                    }
                }
                Ok(DeviceMsg::RunEnded { state, .. }) => {
                    self.state = state;
                    self.ended = true;
                }
                Ok(_) => {}
                Err(e) => {
                    eprintln!("site: the board's end was not heard: {e}");
                    break;
                }
            }
        }
    }

    fn end(&mut self, fault: bool) {
        if self.ended {
            return;
        }
        if let Err(e) = self.conn.link().send(&HostMsg::SiteEnd { fault }) {
            eprintln!("site: the board's end could not be sent: {e}");
            return;
        }
        self.until_ended();
    }
}

impl Experiment for BoardExperiment {
    fn begin(&mut self, ticks_per_step: u32) -> Result<(), ExperimentError> {
        let stride = u16::try_from(self.lead.stride())
            .map_err(|_| ExperimentError::Board("the lead's stride is beyond the link's".into()))?;
        let msg = HostMsg::SiteBegin {
            ticks_per_step,
            lead_weights: *self.lead.weights(),
            lead_stride: stride,
        };
        match self.conn.link().request(&msg)? {
            DeviceMsg::Ack(_) => Ok(()),
            other => Err(LinkHostError::Unexpected(msg.request(), other).into()),
        }
    }

    fn step(&mut self, target_mm: f64) -> Result<Reading, ExperimentError> {
        let step = self.step;
        self.conn
            .link()
            .send(&HostMsg::SiteTarget { step, target_mm })?;
        let deadline = Instant::now() + STEP_TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.conn.link().recv(left)? {
                DeviceMsg::Telemetry(t) => {
                    self.keep(&t)?;
                    if let RunState::Fault(code) = t.state {
                        return Err(ExperimentError::Supervisor(fault_name(code).into()));
                    }
                }
                DeviceMsg::Nack(r, why) => return Err(LinkHostError::Refused(r, why).into()),
                DeviceMsg::SiteStep {
                    step: s,
                    measured_mm,
                    force_kn,
                    ..
                } if s == step => {
                    self.step = step.wrapping_add(1);
                    return Ok(Reading {
                        measured_mm,
                        force_kn,
                    });
                }
                DeviceMsg::SiteStep { step: s, .. } => {
                    return Err(ExperimentError::Board(format!(
                        "the end of step {s} while step {step} runs"
                    )))
                }
                DeviceMsg::RunEnded { state, .. } => {
                    self.state = state;
                    self.ended = true;
                    return Err(ExperimentError::Board(format!(
                        "the board ended the test ({})",
                        crate::link_host::state_name(state)
                    )));
                }
                _ => {}
            }
        }
    }

    fn idle_deadline(&self) -> Option<Instant> {
        // The board keeps its own time (an emulated one holds its plant between targets).
        None
    }

    fn idle_tick(&mut self) {}

    fn safe_stop(&mut self) {
        self.end(true);
    }

    fn finish(&mut self) {
        self.end(false);
    }

    fn state(&self) -> RunState {
        self.state
    }

    fn take_rows(&mut self) -> Vec<SiteRow> {
        std::mem::take(&mut self.rows)
    }

    fn pacing(&self) -> Option<PacingStats> {
        None
    }
}
