//! The `RESULT` line of an emulated run: one JSON object the integration tests and `budget.sh`
//! parse. Its fields and their formatting are a contract (the host compares `nrmse_pct` bit for
//! bit): change them only together with `tests/firmware.rs`.

use core::fmt::{self, Write};

use rths_core::params::DT_S;
use rths_core::supervisor::{Limits, State};

use crate::Run;

/// What the report needs besides the run.
#[derive(Debug, Clone, Copy)]
pub struct ReportInfo<'a> {
    /// The scenario's name (`lr-online`, `rnn-online-10`, ...).
    pub scenario: &'a str,
    /// A suffix of the scenario name (the RNN's hidden size), if any.
    pub scenario_suffix: Option<usize>,
    /// Rows of the record.
    pub record_ticks: u32,
    /// The model compiled in.
    pub model: &'a str,
    /// The injected fault's spec (`fault-inject` builds).
    pub fault_spec: Option<&'a str>,
    /// Deepest stack use and the stack available, bytes.
    pub stack: (usize, usize),
    /// DAQ errors the supervisor saw.
    pub daq_errors: u32,
    /// Samples the controller held over a DAQ error.
    pub held_samples: u32,
    /// defmt frames cut to the logger's buffer.
    pub log_frames_cut: u32,
    /// The limits in force.
    pub limits: Limits,
}

/// The run finished the record without a fault.
pub fn completed(r: &Run, record_ticks: u32) -> bool {
    r.fault_tick.is_none() && r.ticks == record_ticks
}

/// The NRMSE of the target against the reference, % of the peak reference; `None` unless the record
/// completed.
pub fn nrmse_pct(r: &Run, record_ticks: u32) -> Option<f64> {
    if completed(r, record_ticks) && r.peak_ref_mm > 0.0 && r.ticks > 0 {
        Some(100.0 * libm::sqrt(r.sum_sq / r.ticks as f64) / r.peak_ref_mm)
    } else {
        None
    }
}

/// Write the `RESULT {...}` line (no newline).
pub fn write_result<W: Write>(
    w: &mut W,
    r: &Run,
    end: State,
    info: &ReportInfo<'_>,
) -> fmt::Result {
    let lim = &info.limits;
    w.write_fmt(format_args!("RESULT {{\"scenario\":\"{}", info.scenario))?;
    if let Some(n) = info.scenario_suffix {
        w.write_fmt(format_args!("{n}"))?;
    }
    w.write_fmt(format_args!("\",\"ticks\":{},\"nrmse_pct\":", r.ticks))?;
    match nrmse_pct(r, info.record_ticks) {
        Some(x) => w.write_fmt(format_args!("{x:?}"))?,
        None => w.write_str("null")?,
    }
    w.write_fmt(format_args!(
        ",\"overruns\":{},\"faults\":{},\"instr_per_tick\":{{\"min\":{},\"mean\":{:.1},\"max\":{}}}",
        r.overruns,
        u32::from(r.fault_tick.is_some()),
        r.instr_min,
        r.instr_mean(),
        r.instr_max
    ))?;
    w.write_fmt(format_args!(
        ",\"model\":\"{}\",\"end_state\":\"{}\",\"ramp_ticks\":{},\"max_ramp_step_mm\":{:?},\"final_cmd_mm\":{:?}",
        info.model,
        match end {
            State::Done => "done",
            State::Fault(_) => "fault",
            _ => "other",
        },
        r.ramp_ticks,
        r.max_ramp_step_mm,
        r.last_cmd_mm
    ))?;
    if let (State::Fault(reason), Some(t)) = (end, r.fault_tick) {
        w.write_fmt(format_args!(
            ",\"fault_reason\":\"{}\",\"fault_tick\":{},\"cmd_before_fault_mm\":{:?},\"max_step_after_fault_mm\":{:?},\"fault_ramp_ticks\":{}",
            reason.name(),
            t,
            r.cmd_before_fault_mm,
            r.max_step_after_fault_mm,
            r.fault_ramp_ticks
        ))?;
    }
    w.write_fmt(format_args!(
        ",\"max_step_mm\":{:?},\"peak_cmd_mm\":{:?},\"command_fnv\":\"{:016x}\"",
        r.max_step_mm,
        r.peak_cmd_mm,
        r.command_fnv.finish()
    ))?;
    if let Some(spec) = info.fault_spec {
        w.write_fmt(format_args!(",\"fault\":\"{spec}\""))?;
    }
    w.write_fmt(format_args!(
        ",\"stack_bytes\":{},\"stack_avail_bytes\":{}",
        info.stack.0, info.stack.1
    ))?;
    w.write_fmt(format_args!(
        ",\"daq_errors\":{},\"held_samples\":{},\"telemetry_dropped\":{},\"log_frames_cut\":{},\"step_limits_mm\":{{\"fault\":{:?},\"end\":{:?}}}}}",
        info.daq_errors,
        info.held_samples,
        r.telemetry_dropped,
        info.log_frames_cut,
        lim.fault_step_mm(),
        lim.end_ramp_rate_mm_s() * DT_S,
    ))
}

/// Whether the run went as the build expects. A normal build must finish the record without a
/// fault or an overrun. A fault-injection build (`fault_injected`) that trips must ramp, never
/// jumping, to the safe position (where the test was armed: 0 mm); one whose fault is tolerated
/// must finish like a normal build (the test says which is expected). Either way no command ever
/// leaves the envelope.
pub fn as_expected(
    r: &Run,
    end: State,
    lim: &Limits,
    record_ticks: u32,
    fault_injected: bool,
) -> bool {
    let completed = completed(r, record_ticks);
    let envelope =
        r.max_step_mm <= lim.max_step_mm() * (1.0 + 1e-9) && r.peak_cmd_mm <= lim.stroke_mm();
    if fault_injected {
        envelope
            && match end {
                State::Fault(_) => {
                    r.max_step_after_fault_mm <= lim.fault_step_mm() * (1.0 + 1e-9)
                        && r.last_cmd_mm == 0.0
                }
                _ => completed && end == State::Done && r.last_cmd_mm == 0.0,
            }
    } else {
        completed && end == State::Done && r.overruns == 0 && r.last_cmd_mm == 0.0
    }
}

#[cfg(test)]
mod tests;
