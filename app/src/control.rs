//! The controller's work in one tick, the section the timing budget measures: DAQ read, control
//! step, command write, telemetry record (docs/design.md §8).

use heapless::spsc::Producer;
use rths_core::control::{Controller, TickOutput};
use rths_core::hal::{Actuator, Daq, Error};
use rths_core::supervisor::State;

/// One telemetry record: what the controller did at a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TelemetryRecord {
    /// Tick of the run (0 at `Start`).
    pub tick: u32,
    /// Command written, mm.
    pub command_mm: f64,
    /// The analytical part's target, mm.
    pub target_mm: f64,
    /// Measured displacement, mm (NaN on a DAQ error).
    pub measured_mm: f64,
    /// Measured force, kN (NaN on a DAQ error).
    pub force_kn: f64,
    /// Supervisor state after the tick.
    pub state: State,
}

/// What one tick did.
#[derive(Debug, Clone, Copy)]
pub struct StepOutput {
    /// The controller's output.
    pub out: TickOutput,
    /// The record was queued (or none was asked for); `false`: the queue was full, it is dropped.
    pub queued: bool,
    /// The measured displacement, mm (NaN on a DAQ error).
    pub measured_mm: f64,
}

/// The controller's work in one tick: read the DAQ, tick the controller with ground acceleration
/// `ag_mm_s2`, write the command and, if `record`, queue the tick's [`TelemetryRecord`] as tick `k`.
///
/// Kept out of line so that `firmware/panic-check.sh` can walk its call graph (no panic reachable).
#[inline(never)]
pub fn control_step<D, A>(
    ctl: &mut Controller,
    daq_act: &mut D,
    producer: &mut Producer<'_, TelemetryRecord>,
    k: u32,
    ag_mm_s2: f64,
    overrun: bool,
    record: bool,
) -> StepOutput
where
    D: Daq<Error = A> + Actuator<Error = A>,
    A: Error,
{
    let sample = daq_act.read().map_err(|e| e.kind());
    let out = ctl.tick(ag_mm_s2, sample, overrun);
    // The supervisor's command is finite and within the stroke, so the actuator neither refuses nor
    // clips it; if it did, it holds the last one and the supervisor sees that in the next reading.
    let _ = daq_act.command(out.command_mm);
    let (m, f) = match sample {
        Ok(s) => (s.disp_mm, s.force_kn),
        Err(_) => (f64::NAN, f64::NAN),
    };
    let queued = !record
        || producer
            .enqueue(TelemetryRecord {
                tick: k,
                command_mm: out.command_mm,
                target_mm: out.target_mm,
                measured_mm: m,
                force_kn: f,
                state: out.state,
            })
            .is_ok();
    StepOutput {
        out,
        queued,
        measured_mm: m,
    }
}
