//! The run's statistics, updated by the control task after every tick (outside the measured
//! section) and read by the report, the link's status and its `RunEnded`.

use rths_core::checksum::Fnv1a64;
use rths_core::supervisor::State;

use crate::ONE_SECOND_TICKS;

/// Ticks the command must hold still in a fault before an emulated run is stopped (1 s).
pub const FAULT_SETTLE_TICKS: u32 = ONE_SECOND_TICKS;

/// What one tick contributes to the [`Run`].
#[derive(Debug, Clone, Copy)]
pub struct TickFacts {
    /// The tick (0 at `Start`).
    pub k: u32,
    /// The tick counts towards the run: a record row on the emulated board, any tick of a run on a
    /// real rig.
    pub counted: bool,
    /// The harness's (target − reference)² of this row and |reference|, mm², mm (emulated board).
    pub row: Option<(f64, f64)>,
    /// Instructions of the measured section.
    pub instr: u32,
    /// The command written, mm.
    pub command_mm: f64,
    /// The measured displacement, mm (NaN on a DAQ error).
    pub measured_mm: f64,
    /// Supervisor state after the tick.
    pub state: State,
    /// The tick was told it ran after an overrun.
    pub overrun: bool,
    /// Its telemetry record was queued (or none was due).
    pub queued: bool,
}

/// Statistics of the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    /// Counted ticks (see [`TickFacts::counted`]).
    pub ticks: u32,
    /// Σ (target − reference)² over the rows, mm².
    pub sum_sq: f64,
    /// max |reference|, mm.
    pub peak_ref_mm: f64,
    /// Fewest instructions of a counted tick.
    pub instr_min: u32,
    /// Most instructions of a counted tick.
    pub instr_max: u32,
    /// Σ instructions over the counted ticks.
    pub instr_sum: u64,
    /// Counted ticks with an instruction count.
    pub instr_n: u32,
    /// Ticks run after an overrun.
    pub overruns: u32,
    /// Telemetry records the full queue dropped.
    pub telemetry_dropped: u32,
    /// Supervisor state after the last tick.
    pub state: State,
    /// Tick of the first fault.
    pub fault_tick: Option<u32>,
    /// Command before the trip, mm.
    pub cmd_before_fault_mm: f64,
    /// Largest |Δcommand| per tick from the trip on, mm.
    pub max_step_after_fault_mm: f64,
    /// Ticks after the trip on which the command moved (the fault ramp).
    pub fault_ramp_ticks: u32,
    /// Ticks the command has not moved while in fault.
    pub fault_steady_ticks: u32,
    /// Ticks from `finish()` to `Done`.
    pub ramp_ticks: u32,
    /// Largest |Δcommand| per tick in the end ramp, mm.
    pub max_ramp_step_mm: f64,
    /// Last command, mm.
    pub last_cmd_mm: f64,
    /// Largest |Δcommand| per tick over the whole run, mm.
    pub max_step_mm: f64,
    /// Largest |command|, mm.
    pub peak_cmd_mm: f64,
    /// Last finite measured displacement, mm (where a real rig arms).
    pub last_disp_mm: f64,
    /// FNV-1a of the counted ticks' commands (their bits): a host run of the same controller on
    /// the same plant must give the same (tests/firmware.rs).
    pub command_fnv: Fnv1a64,
}

impl Default for Run {
    fn default() -> Self {
        Self::new()
    }
}

impl Run {
    /// Nothing run yet.
    pub const fn new() -> Self {
        Self {
            ticks: 0,
            sum_sq: 0.0,
            peak_ref_mm: 0.0,
            instr_min: u32::MAX,
            instr_max: 0,
            instr_sum: 0,
            instr_n: 0,
            overruns: 0,
            telemetry_dropped: 0,
            state: State::Idle,
            fault_tick: None,
            cmd_before_fault_mm: 0.0,
            max_step_after_fault_mm: 0.0,
            fault_ramp_ticks: 0,
            fault_steady_ticks: 0,
            ramp_ticks: 0,
            max_ramp_step_mm: 0.0,
            last_cmd_mm: 0.0,
            max_step_mm: 0.0,
            peak_cmd_mm: 0.0,
            last_disp_mm: 0.0,
            command_fnv: Fnv1a64::new(),
        }
    }

    /// A new run (after `Arm`): the statistics start over; the rig stays where it is, and so do the
    /// last command and the last measured position.
    pub fn restart(&mut self) {
        *self = Self {
            last_cmd_mm: self.last_cmd_mm,
            last_disp_mm: self.last_disp_mm,
            state: self.state,
            ..Self::new()
        };
    }

    /// Account for one tick. `true` when the supervisor task should look at the run: the first
    /// fault, a fault that has held still for [`FAULT_SETTLE_TICKS`], or the end ramp reaching
    /// `Done`.
    pub fn after_tick(&mut self, t: &TickFacts) -> bool {
        let prev_state = self.state;
        let step = libm::fabs(t.command_mm - self.last_cmd_mm);
        self.max_step_mm = self.max_step_mm.max(step);
        self.peak_cmd_mm = self.peak_cmd_mm.max(libm::fabs(t.command_mm));
        if t.counted {
            self.ticks = t.k.saturating_add(1);
            if let Some((err_sq, ref_abs)) = t.row {
                self.sum_sq += err_sq;
                self.peak_ref_mm = self.peak_ref_mm.max(ref_abs);
            }
            self.instr_min = self.instr_min.min(t.instr);
            self.instr_max = self.instr_max.max(t.instr);
            self.instr_sum += u64::from(t.instr);
            self.instr_n = self.instr_n.saturating_add(1);
            self.command_fnv.write_f64(t.command_mm);
        }
        if t.overrun {
            self.overruns = self.overruns.saturating_add(1);
        }
        if !t.queued {
            self.telemetry_dropped = self.telemetry_dropped.saturating_add(1);
        }
        if t.measured_mm.is_finite() {
            self.last_disp_mm = t.measured_mm;
        }
        let mut notify = false;
        match t.state {
            State::Fault(_) => {
                if self.fault_tick.is_none() {
                    self.fault_tick = Some(t.k);
                    self.cmd_before_fault_mm = self.last_cmd_mm;
                    notify = true;
                }
                self.max_step_after_fault_mm = self.max_step_after_fault_mm.max(step);
                if step > 0.0 {
                    self.fault_ramp_ticks = self.fault_ramp_ticks.saturating_add(1);
                }
                self.fault_steady_ticks = if step == 0.0 {
                    self.fault_steady_ticks.saturating_add(1)
                } else {
                    0
                };
                notify |= self.fault_steady_ticks == FAULT_SETTLE_TICKS;
            }
            State::RampDown | State::Done => {
                self.ramp_ticks = self.ramp_ticks.saturating_add(1);
                self.max_ramp_step_mm = self.max_ramp_step_mm.max(step);
                notify |= t.state == State::Done && prev_state != State::Done;
            }
            _ => {}
        }
        self.last_cmd_mm = t.command_mm;
        self.state = t.state;
        notify
    }

    /// The fault has held still long enough to stop an emulated run.
    pub fn fault_settled(&self) -> bool {
        self.fault_steady_ticks >= FAULT_SETTLE_TICKS
    }

    /// Mean instructions per counted tick (0 before any).
    pub fn instr_mean(&self) -> f64 {
        if self.instr_n > 0 {
            self.instr_sum as f64 / self.instr_n as f64
        } else {
            0.0
        }
    }
}
