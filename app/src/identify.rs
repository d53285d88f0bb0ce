//! Identification on the device (`rths link ... identify`): at rest, the supervisor is armed and
//! started exactly as for a test (the limits in force, faults trip and ramp down), and the control
//! task plays the identification excitation tick by tick, without the host in the loop, reading the
//! DAQ and writing the supervisor's command with core's `IdentifySession`, the tick the host's
//! `rths identify` runs. Every tick's command, displacement and force are queued for the link as an
//! `IdentifySample`.
//!
//! The excitation is `rths_core::identify_excitation`'s: one period of the unit multisine and the
//! ramp's cosines are tabulated by the firmware's build script with the same functions and the same
//! cosines as the host (192 KiB of flash at 2048 Hz; 200 lines of f64 cosines per tick would not
//! fit the Cortex-M4's tick, and the `libm` crate's cosines are not the host's to the bit), and
//! [`Player`] applies the envelope, scale and slew limit per tick.
//!
//! The host's `rths identify` runs this same tick ([`identify_step`]) against its virtual rig,
//! through its one driver (`src/machinery/drive.rs` `identify`), with the excitation's tables computed at run
//! time (any [`Tables`]) and the schedule of its settings ([`begin_with`]).

use heapless::spsc::Producer;
use rths_core::control::Controller;
use rths_core::hal::{Actuator, Daq, Error};
use rths_core::identify_excitation::{ExcitationConfig, Player, Schedule, Tables, UnitStats};
use rths_core::identify_session::{IdentifyOutcome, IdentifyPhase, IdentifySession};
use rths_core::params::DT_S;
use rths_core::supervisor::State;
use rths_link::NackReason;

use crate::TelemetryRecord;

/// The excitation's tables in flash (the firmware's build script writes them with rths-core's
/// `StdTables`, as `rths identify` computes them): f64 little-endian, with the unit period's stats.
#[derive(Debug, Clone, Copy)]
pub struct FlashTables {
    unit: &'static [u8],
    ramp: &'static [u8],
    stats: UnitStats,
}

/// f64 number `i` of little-endian `bytes` (NaN past the end: the supervisor then trips, nothing
/// moves).
fn le_f64(bytes: &[u8], i: usize) -> f64 {
    i.checked_mul(8)
        .and_then(|s| bytes.get(s..s.checked_add(8)?))
        .and_then(|s| <[u8; 8]>::try_from(s).ok())
        .map_or(f64::NAN, f64::from_le_bytes)
}

impl FlashTables {
    /// The unit period `unit` and ramp table `ramp` (8 bytes per value) and the unit period's
    /// [`UnitStats`] (computed with them at build time).
    pub const fn new(
        unit: &'static [u8],
        ramp: &'static [u8],
        peak: f64,
        peak_rate_per_s: f64,
    ) -> Self {
        Self {
            unit,
            ramp,
            stats: UnitStats {
                peak,
                peak_rate_per_s,
            },
        }
    }

    /// Samples in the period.
    pub fn period_ticks(&self) -> usize {
        self.unit.len() / 8
    }

    /// The schedule of the default excitation with peak `amplitude_mm` at the controller's tick.
    pub fn schedule(&self, amplitude_mm: f64) -> Result<Schedule, NackReason> {
        if !amplitude_mm.is_finite() {
            return Err(NackReason::NotFinite);
        }
        let mut cfg = ExcitationConfig::new(DT_S);
        cfg.amplitude_mm = amplitude_mm;
        let n = self.period_ticks();
        if n == 0 {
            return Err(NackReason::Unsupported);
        }
        let s = Schedule::new(&cfg, n, self.stats).map_err(|_| NackReason::OutOfRange)?;
        if cfg.period_ticks() != n || s.ramp_ticks() != self.ramp.len() / 8 {
            // Tables built for another rate: refuse rather than play the wrong band.
            return Err(NackReason::Rate);
        }
        Ok(s)
    }
}

impl Tables for FlashTables {
    fn unit(&self, i: usize) -> f64 {
        le_f64(self.unit, i)
    }
    fn ramp_cos(&self, j: usize) -> f64 {
        le_f64(self.ramp, j)
    }
}

/// The identification in progress (a shared resource of the control and link tasks).
#[derive(Debug, Clone, Copy)]
pub struct Identification {
    session: Option<IdentifySession>,
    /// Ticks run (= samples queued or dropped).
    pub ticks: u32,
    /// Samples the full queue dropped.
    pub dropped: u32,
    /// The supervisor's state after the last tick.
    pub state: State,
    /// Ticks whose DAQ read failed (no sample).
    pub daq_errors: u32,
    /// Ticks whose command the actuator reported an error for (e.g. clipped).
    pub actuator_errors: u32,
}

impl Default for Identification {
    fn default() -> Self {
        Self::new()
    }
}

/// What one identification tick did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyTick {
    /// The DAQ was read and a command written (the plant moves one tick).
    pub ticked: bool,
    /// The identification is over (its last tick was the previous one, or this one ended it).
    pub ended: bool,
}

impl Identification {
    /// None in progress.
    pub const fn new() -> Self {
        Self {
            session: None,
            ticks: 0,
            dropped: 0,
            state: State::Idle,
            daq_errors: 0,
            actuator_errors: 0,
        }
    }

    /// Begin playing `player` (the supervisor is already running: [`begin`]).
    pub fn start(&mut self, player: Player) {
        self.start_at(player, DT_S);
    }

    /// [`Self::start`] at the tick `dt_s` (the host's identification at another rate, e.g. the
    /// vRTHS benchmark's 4096 Hz; it bounds the ramps, `rths_core::identify_session::MAX_RAMP_S`).
    pub fn start_at(&mut self, player: Player, dt_s: f64) {
        *self = Self {
            session: Some(IdentifySession::new(player, dt_s)),
            ..Self::new()
        };
    }

    /// Where it is (`None`: none started since power-up).
    pub fn phase(&self) -> Option<IdentifyPhase> {
        self.session.as_ref().map(IdentifySession::phase)
    }

    /// An identification is under way.
    pub fn active(&self) -> bool {
        self.phase().is_some_and(|p| p != IdentifyPhase::Ended)
    }

    /// How the last one ended (`None`: none started, or still under way).
    pub fn outcome(&self) -> Option<IdentifyOutcome> {
        self.session.as_ref().and_then(IdentifySession::outcome)
    }
}

/// Check that an identification may start, and arm and start the supervisor for it; the player
/// to hand to [`Identification::start`]. At rest only (`Busy` otherwise); `may_arm`: the emulated
/// plant has not run yet (`Unsupported` otherwise: it plays once per power-up); `at_measured`: a
/// real rig, armed at `measured_mm` after any finished run.
pub fn begin(
    ctl: &mut Controller,
    tables: &FlashTables,
    amplitude_mm: f64,
    may_arm: bool,
    at_measured: Option<f64>,
) -> Result<Player, NackReason> {
    begin_with(ctl, tables.schedule(amplitude_mm)?, may_arm, at_measured)
}

/// [`begin`] with the excitation's `schedule` given (the host's, from its settings at any tick).
pub fn begin_with(
    ctl: &mut Controller,
    schedule: Schedule,
    may_arm: bool,
    at_measured: Option<f64>,
) -> Result<Player, NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    if !may_arm {
        return Err(NackReason::Unsupported);
    }
    match at_measured {
        None => ctl
            .supervisor_mut()
            .arm()
            .map_err(|_| NackReason::InvalidState)?,
        Some(m) => {
            if matches!(ctl.supervisor().state(), State::Done | State::Fault(_)) {
                ctl.reset().map_err(|_| NackReason::Busy)?;
            }
            ctl.supervisor_mut()
                .arm_at(m)
                .map_err(|_| NackReason::InvalidState)?;
        }
    }
    ctl.supervisor_mut()
        .start()
        .map_err(|_| NackReason::InvalidState)?;
    Ok(Player::new(schedule))
}

/// One tick of an identification: core's [`IdentifySession::step`] on the controller's supervisor,
/// its record queued for the link. The record's `target_mm` is the excitation's request. The
/// board's control task and the host's `rths identify` both run it.
pub fn identify_step<D, A, T>(
    id: &mut Identification,
    ctl: &mut Controller,
    daq_act: &mut D,
    producer: &mut Producer<'_, TelemetryRecord>,
    tables: &T,
    overrun: bool,
) -> IdentifyTick
where
    D: Daq<Error = A> + Actuator<Error = A>,
    A: Error,
    T: Tables,
{
    let Some(session) = id.session.as_mut() else {
        return IdentifyTick {
            ticked: false,
            ended: false,
        };
    };
    let Some(r) = session.step(ctl.supervisor_mut(), daq_act, tables, overrun) else {
        id.state = ctl.supervisor().state();
        return IdentifyTick {
            ticked: false,
            ended: true,
        };
    };
    let rec = TelemetryRecord {
        tick: r.tick,
        command_mm: r.command_mm,
        target_mm: r.requested_mm,
        measured_mm: r.measured_mm,
        force_kn: r.force_kn,
        state: r.state,
    };
    if producer.enqueue(rec).is_err() {
        id.dropped = id.dropped.saturating_add(1);
    }
    if r.daq_error.is_some() {
        id.daq_errors = id.daq_errors.saturating_add(1);
    }
    if r.actuator_error {
        id.actuator_errors = id.actuator_errors.saturating_add(1);
    }
    id.ticks = session.ticks();
    id.state = r.state;
    IdentifyTick {
        ticked: true,
        ended: false,
    }
}

#[cfg(test)]
mod tests;
