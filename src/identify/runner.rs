//! Drive a rig through an excitation with the supervisor armed, recording what the controller sees.
//!
//! Generic over the core HAL ([`Daq`] + [`Actuator`]): the virtual rig here, a board over the link
//! later. Per tick, exactly as the control loop does (`rths_core::control::Controller::tick`):
//! `Daq::read` → `Supervisor::tick(requested, sample, overrun)` → `Actuator::command(decision)` →
//! wait for the next tick. The excitation is only the *request*: the supervisor checks it, rate
//! limits it and, on a trip, ignores it and ramps to the safe position. Nothing else of the rig is
//! read, so a record holds only measured signals.

use rths_core::hal::{Actuator, Daq, Error as _, ErrorKind, Sample};
use rths_core::supervisor::{FaultReason, Limits, State, Supervisor};

use super::excitation::Excitation;
use super::IdentifyError;

/// What the controller saw during an identification run, one entry per tick.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IdentificationRecord {
    /// Controller tick, s.
    pub dt_s: f64,
    /// The command sent at tick k (after the supervisor), mm; held from k to k+1.
    pub command_mm: Vec<f64>,
    /// Displacement read at tick k (before the command), mm; NaN on a DAQ error.
    pub measured_mm: Vec<f64>,
    /// Force read at tick k, kN; NaN on a DAQ error.
    pub force_kn: Vec<f64>,
    /// DAQ errors (ticks without a sample).
    pub daq_errors: usize,
    /// Commands the actuator reported an error for (e.g. clipped).
    pub actuator_errors: usize,
}

/// Longest fault ramp waited for after a trip, s (any ramp of the stroke at 20 mm/s).
const MAX_RAMP_S: f64 = 60.0;

/// Run the excitation on `rig`, calling `next_tick` after each command (on the virtual rig: advance
/// the plant; on a board: wait for the tick). Returns the record, or [`IdentifyError::Tripped`] if
/// the supervisor tripped (the excitation stops at once; the supervisor's ramp to the safe position
/// is driven to rest before returning).
pub fn run<R, F>(
    rig: &mut R,
    excitation: &Excitation,
    limits: Limits,
    mut next_tick: F,
) -> Result<IdentificationRecord, IdentifyError>
where
    R: Daq + Actuator,
    F: FnMut(&mut R),
{
    let dt_s = excitation.config.dt_s;
    let max_ramp_ticks = (MAX_RAMP_S / dt_s).round() as usize;
    let n = excitation.command_mm.len();
    let mut rec = IdentificationRecord {
        dt_s,
        command_mm: Vec::with_capacity(n),
        measured_mm: Vec::with_capacity(n),
        force_kn: Vec::with_capacity(n),
        daq_errors: 0,
        actuator_errors: 0,
    };
    let mut sup = Supervisor::new(limits);
    // Idle → Armed → Running cannot fail on a fresh supervisor; the states are checked below
    // anyway.
    let _ = sup.arm();
    let _ = sup.start();
    let mut tick =
        |rig: &mut R, sup: &mut Supervisor, requested: f64, rec: &mut IdentificationRecord| {
            let sample: Result<Sample, ErrorKind> = rig.read().map_err(|e| e.kind());
            match sample {
                Ok(s) => {
                    rec.measured_mm.push(s.disp_mm);
                    rec.force_kn.push(s.force_kn);
                }
                Err(_) => {
                    rec.daq_errors += 1;
                    rec.measured_mm.push(f64::NAN);
                    rec.force_kn.push(f64::NAN);
                }
            }
            let d = sup.tick(requested, sample, false);
            rec.command_mm.push(d.command_mm);
            if rig.command(d.command_mm).is_err() {
                rec.actuator_errors += 1;
            }
            next_tick(rig);
            d.state
        };
    let mut trip: Option<(FaultReason, f64)> = None;
    for (k, &u) in excitation.command_mm.iter().enumerate() {
        if let State::Fault(reason) = tick(rig, &mut sup, u, &mut rec) {
            trip = Some((reason, k as f64 * dt_s));
            break;
        }
    }
    if trip.is_none() {
        // The excitation ends at 0: the ramp-down is immediate; a trip during it still counts.
        let _ = sup.finish();
        for _ in 0..max_ramp_ticks {
            match sup.state() {
                State::Done => break,
                State::Fault(reason) => {
                    trip = Some((reason, rec.command_mm.len() as f64 * dt_s));
                    break;
                }
                _ => {
                    let k = rec.command_mm.len();
                    if let State::Fault(reason) = tick(rig, &mut sup, 0.0, &mut rec) {
                        trip = Some((reason, k as f64 * dt_s));
                        break;
                    }
                }
            }
        }
    }
    if let Some((reason, time_s)) = trip {
        // Drive the supervisor's fault ramp to rest (it ignores the request while faulted).
        for _ in 0..max_ramp_ticks {
            if sup.at_rest() {
                break;
            }
            tick(rig, &mut sup, 0.0, &mut rec);
        }
        return Err(IdentifyError::Tripped {
            reason: format!("{reason:?}"),
            time_s,
        });
    }
    if sup.state() != State::Done {
        return Err(IdentifyError::Setting(format!(
            "supervisor ended in {:?}, not Done",
            sup.state()
        )));
    }
    Ok(rec)
}
