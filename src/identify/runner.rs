//! Drive a rig through an excitation with the supervisor armed, recording what the controller sees.
//!
//! Generic over the core HAL ([`Daq`] + [`Actuator`]): the virtual rig here, a board over the link
//! later. Per tick, the board's identification tick (`rths_core::identify_session`):
//! `Daq::read` → `Supervisor::tick(requested, sample, overrun)` → `Actuator::command(decision)` →
//! wait for the next tick. The excitation is only the *request*: the supervisor checks it, rate
//! limits it and, on a trip, ignores it and ramps to the safe position. Nothing else of the rig is
//! read, so a record holds only measured signals.

use rths_core::hal::{Actuator, Daq};
use rths_core::identify_excitation::{Player, StdTables};
use rths_core::identify_session::{IdentifyOutcome, IdentifyPhase, IdentifySession};
use rths_core::supervisor::{Limits, Supervisor};

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

/// Run the excitation on `rig`, calling `next_tick` after each command (on the virtual rig: advance
/// the plant; on a board: wait for the tick). Each tick is core's [`IdentifySession::step`], the
/// tick the board's identification runs. Returns the record, or [`IdentifyError::Tripped`] if the
/// supervisor tripped (the excitation stops at once; the supervisor's ramp to the safe position is
/// driven to rest before returning).
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
    let tables =
        StdTables::new(&excitation.config).map_err(|e| IdentifyError::Setting(e.to_string()))?;
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
    // Idle → Armed → Running cannot fail on a fresh supervisor; the outcome is checked below
    // anyway.
    let _ = sup.arm();
    let _ = sup.start();
    let mut session = IdentifySession::new(Player::new(tables.schedule), dt_s);
    loop {
        let playing = session.phase() == IdentifyPhase::Excite;
        let Some(t) = session.step(&mut sup, rig, &tables, false) else {
            break;
        };
        let k = t.tick as usize;
        if playing && k < n && t.requested_mm.to_bits() != excitation.command_mm[k].to_bits() {
            return Err(IdentifyError::Setting(format!(
                "the excitation's tick {k} is not its settings' ({} mm played, {} mm given)",
                t.requested_mm, excitation.command_mm[k]
            )));
        }
        if t.daq_error.is_some() {
            rec.daq_errors += 1;
        }
        if t.actuator_error {
            rec.actuator_errors += 1;
        }
        rec.measured_mm.push(t.measured_mm);
        rec.force_kn.push(t.force_kn);
        rec.command_mm.push(t.command_mm);
        next_tick(rig);
    }
    match session.outcome() {
        Some(IdentifyOutcome::Done) => Ok(rec),
        Some(IdentifyOutcome::Tripped { reason, tick }) => Err(IdentifyError::Tripped {
            reason: format!("{reason:?}"),
            time_s: f64::from(tick) * dt_s,
        }),
        Some(IdentifyOutcome::Unsettled { state }) => Err(IdentifyError::Setting(format!(
            "supervisor ended in {state:?}, not Done"
        ))),
        None => Err(IdentifyError::Setting(
            "the identification ended without an outcome".into(),
        )),
    }
}
