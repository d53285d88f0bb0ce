//! One identification run, tick by tick: the same on the board (`rths link ... identify`, the
//! firmware's control task) and on the host (`rths identify` against the virtual rig or a board).
//!
//! The supervisor is armed and running before the first tick, exactly as for a test (its limits in
//! force; a fault trips and ramps down). Per tick: the excitation's request ([`Player`]), then
//! `Daq::read` → `Supervisor::tick(request, sample, overrun)` → `Actuator::command(decision)`. After
//! the excitation: `finish()` and ticks at 0 until `Done`; after a trip: ticks at 0 until the fault
//! ramp is at rest. Both ends are bounded by [`MAX_RAMP_S`] of ticks, so a supervisor that never
//! comes to rest cannot hold the run forever.

use crate::hal::{Actuator, Daq, Error as _, ErrorKind, Sample};
use crate::identify_excitation::{Player, Tables};
use crate::supervisor::{FaultReason, State, Supervisor};

/// Longest ramp waited for after the excitation or a trip, s: any ramp of the paper actuator's
/// stroke at the slowest end-ramp rate (±100 mm at 20 mm/s is 10 s) with a wide margin.
pub const MAX_RAMP_S: f64 = 60.0;

/// Where an identification run is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdentifyPhase {
    /// Playing the excitation.
    Excite,
    /// The excitation ended: `finish()` given, ticking at 0 until `Done`.
    Finish,
    /// Tripped: ticking at 0 while the supervisor ramps to its safe position.
    Settle,
    /// Over: done, or tripped and at rest, or the ramp bound ran out ([`IdentifySession::outcome`]).
    Ended,
}

/// How a finished run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdentifyOutcome {
    /// The excitation played and the supervisor reached `Done`.
    Done,
    /// The supervisor tripped at `tick` for `reason` (the ramp to rest was driven).
    Tripped {
        /// Why.
        reason: FaultReason,
        /// The tick of the trip.
        tick: u32,
    },
    /// The supervisor was not at rest after [`MAX_RAMP_S`] of ramp ticks: it ended in `state`.
    Unsettled {
        /// The supervisor's state at the end.
        state: State,
    },
}

/// What one tick of the run read and wrote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyTickRecord {
    /// The run's tick (0 at the first excitation tick).
    pub tick: u32,
    /// The excitation's request (0 while ramping), mm.
    pub requested_mm: f64,
    /// The supervisor's command, mm (held to the next tick).
    pub command_mm: f64,
    /// The DAQ's displacement, mm; NaN on a DAQ error.
    pub measured_mm: f64,
    /// The DAQ's force, kN; NaN on a DAQ error.
    pub force_kn: f64,
    /// The DAQ's error, if the read failed.
    pub daq_error: Option<ErrorKind>,
    /// The actuator reported an error for the command (e.g. clipped).
    pub actuator_error: bool,
    /// The supervisor's state after the tick.
    pub state: State,
}

/// An identification run's state (the supervisor is the caller's: the controller's on the board).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifySession {
    player: Player,
    phase: IdentifyPhase,
    ticks: u32,
    ramp_ticks: u32,
    max_ramp_ticks: u32,
    trip: Option<(FaultReason, u32)>,
    outcome: Option<IdentifyOutcome>,
}

impl IdentifySession {
    /// Play `player` at the tick `dt_s` (it bounds the ramps: [`MAX_RAMP_S`]); the supervisor must
    /// already be running.
    pub fn new(player: Player, dt_s: f64) -> Self {
        let max = MAX_RAMP_S / dt_s;
        let max_ramp_ticks = if max.is_finite() && max >= 1.0 {
            // Bounded above by u32::MAX (`as` saturates).
            libm::round(max) as u32
        } else {
            1
        };
        Self {
            player,
            phase: IdentifyPhase::Excite,
            ticks: 0,
            ramp_ticks: 0,
            max_ramp_ticks,
            trip: None,
            outcome: None,
        }
    }

    /// Where the run is.
    pub fn phase(&self) -> IdentifyPhase {
        self.phase
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }

    /// How the run ended (`None` while it runs).
    pub fn outcome(&self) -> Option<IdentifyOutcome> {
        self.outcome
    }

    /// The excitation's player (its tick count, rate-limited ticks).
    pub fn player(&self) -> &Player {
        &self.player
    }

    fn end(&mut self, sup: &Supervisor) -> Option<IdentifyTickRecord> {
        self.phase = IdentifyPhase::Ended;
        self.outcome = Some(match (self.trip, sup.state()) {
            (Some((reason, tick)), _) if sup.at_rest() => IdentifyOutcome::Tripped { reason, tick },
            (None, State::Done) => IdentifyOutcome::Done,
            (_, state) => IdentifyOutcome::Unsettled { state },
        });
        None
    }

    /// Run one tick on `rig` with `sup` (`overrun`: the tick came late), or `None` once the run is
    /// over (nothing read or written then).
    pub fn step<R, T>(
        &mut self,
        sup: &mut Supervisor,
        rig: &mut R,
        tables: &T,
        overrun: bool,
    ) -> Option<IdentifyTickRecord>
    where
        R: Daq + Actuator,
        T: Tables,
    {
        // Before the tick: is there one to run, and what does it request?
        let requested_mm = match self.phase {
            IdentifyPhase::Ended => return None,
            // Past the end (cannot happen: `Finish` follows the last tick) a NaN trips the
            // supervisor and nothing moves.
            IdentifyPhase::Excite => self.player.next(tables).unwrap_or(f64::NAN),
            IdentifyPhase::Finish | IdentifyPhase::Settle => {
                match sup.state() {
                    State::Done if self.trip.is_none() => return self.end(sup),
                    State::Fault(reason) => {
                        if self.trip.is_none() {
                            self.trip = Some((reason, self.ticks));
                        }
                        self.phase = IdentifyPhase::Settle;
                    }
                    _ => {}
                }
                if (self.phase == IdentifyPhase::Settle && sup.at_rest())
                    || self.ramp_ticks >= self.max_ramp_ticks
                {
                    return self.end(sup);
                }
                self.ramp_ticks += 1;
                0.0
            }
        };
        let sample: Result<Sample, ErrorKind> = Daq::read(rig).map_err(|e| e.kind());
        let d = sup.tick(requested_mm, sample, overrun);
        // The supervisor's command is finite and within the stroke; an actuator error is counted.
        let actuator_error = Actuator::command(rig, d.command_mm).is_err();
        let (measured_mm, force_kn, daq_error) = match sample {
            Ok(s) => (s.disp_mm, s.force_kn, None),
            Err(k) => (f64::NAN, f64::NAN, Some(k)),
        };
        let rec = IdentifyTickRecord {
            tick: self.ticks,
            requested_mm,
            command_mm: d.command_mm,
            measured_mm,
            force_kn,
            daq_error,
            actuator_error,
            state: d.state,
        };
        if let State::Fault(reason) = d.state {
            if self.trip.is_none() {
                self.trip = Some((reason, self.ticks));
            }
            self.phase = IdentifyPhase::Settle;
        } else if self.phase == IdentifyPhase::Excite
            && self.player.tick() >= self.player.schedule.ticks()
        {
            // The excitation ends at 0: the end ramp is immediate.
            let _ = sup.finish();
            self.phase = IdentifyPhase::Finish;
        }
        self.ticks = self.ticks.saturating_add(1);
        Some(rec)
    }
}

#[cfg(test)]
mod tests;
