//! Drive a rig through an excitation with the supervisor armed, recording what the controller sees.
//!
//! Generic over the core HAL ([`Daq`] + [`Actuator`]): the virtual rig, or the benchmark's rig
//! behind its converters. Each tick is the board's identification tick
//! (`rths_app::identify::identify_step`, the one the firmware's control task runs), on a
//! controller's supervisor armed and started as the board arms it (`begin_with`), driven by the
//! host's driver ([`crate::machinery::drive::identify`]): `Daq::read` → `Supervisor::tick(requested, sample,
//! overrun)` → `Actuator::command(decision)` → the caller's next tick. The excitation is only the
//! *request*: the supervisor checks it, rate limits it and, on a trip, ignores it and ramps to the
//! safe position. Nothing else of the rig is read, so a record holds only measured signals.

use rths_app::identify::{begin_with, Identification};
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::hal::{Actuator, Daq, Error};
use rths_core::identify_excitation::StdTables;
use rths_core::identify_session::IdentifyOutcome;
use rths_core::metamodel::Lr;
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;

use super::error::IdentifyError;
use super::excitation::Excitation;

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

/// The controller whose supervisor an identification runs on: `limits`, at rest. Its analytical
/// part is never stepped (an identification ticks the supervisor alone, as on the board).
fn controller(limits: Limits) -> Result<Controller, IdentifyError> {
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        limits,
    )
    .map_err(|e| IdentifyError::Setting(format!("controller: {e:?}")))?;
    Ok(Controller::new(
        config,
        Analytical::Lr(Lr::PARKED),
        Compensator::None,
    ))
}

/// Run the excitation on `rig`, calling `next_tick` after each command (on the virtual rig: advance
/// the plant; on a board: wait for the tick). Returns the record, or [`IdentifyError::Tripped`] if
/// the supervisor tripped (the excitation stops at once; the supervisor's ramp to the safe position
/// is driven to rest before returning).
pub fn run<R, A, F>(
    rig: &mut R,
    excitation: &Excitation,
    limits: Limits,
    next_tick: F,
) -> Result<IdentificationRecord, IdentifyError>
where
    R: Daq<Error = A> + Actuator<Error = A>,
    A: Error,
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
    let mut ctl = controller(limits)?;
    let player = begin_with(&mut ctl, tables.schedule, true, None)
        .map_err(|e| IdentifyError::Setting(format!("the supervisor refused to arm: {e:?}")))?;
    let mut id = Identification::new();
    id.start_at(player, dt_s);
    let mut mismatch = None;
    crate::machinery::drive::identify(&mut ctl, rig, &mut id, &tables, next_tick, |t, playing| {
        let k = t.tick as usize;
        if playing
            && k < n
            && mismatch.is_none()
            && t.target_mm.to_bits() != excitation.command_mm[k].to_bits()
        {
            mismatch = Some((k, t.target_mm));
        }
        rec.measured_mm.push(t.measured_mm);
        rec.force_kn.push(t.force_kn);
        rec.command_mm.push(t.command_mm);
    });
    if let Some((k, played)) = mismatch {
        return Err(IdentifyError::Setting(format!(
            "the excitation's tick {k} is not its settings' ({played} mm played, {} mm given)",
            excitation.command_mm[k]
        )));
    }
    rec.daq_errors = id.daq_errors as usize;
    rec.actuator_errors = id.actuator_errors as usize;
    match id.outcome() {
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
