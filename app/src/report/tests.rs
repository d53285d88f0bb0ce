//! Tests of [`crate::report`] and of the [`Run`] statistics it reports.

extern crate std;
use std::string::String;

use super::*;
use crate::run::{TickFacts, FAULT_SETTLE_TICKS};
use rths_core::supervisor::FaultReason;

fn facts(k: u32, cmd: f64, state: State) -> TickFacts {
    TickFacts {
        k,
        counted: true,
        row: Some((0.25, 2.0)),
        instr: 1000 + k,
        command_mm: cmd,
        measured_mm: cmd,
        state,
        overrun: false,
        queued: true,
    }
}

fn info(limits: Limits) -> ReportInfo<'static> {
    ReportInfo {
        scenario: "rnn-online-",
        scenario_suffix: Some(10),
        record_ticks: 4,
        model: "m.json",
        fault_spec: Some("nan@10s"),
        stack: (100, 2000),
        daq_errors: 1,
        held_samples: 2,
        log_frames_cut: 0,
        limits,
    }
}

#[test]
fn run_statistics() {
    let mut r = Run::new();
    assert!(!r.after_tick(&facts(0, 0.1, State::Running)));
    assert!(!r.after_tick(&facts(1, 0.3, State::Running)));
    assert!(!r.after_tick(&facts(2, 0.2, State::RampDown)));
    assert!(
        r.after_tick(&facts(3, 0.0, State::Done)),
        "Done notifies once"
    );
    assert!(!r.after_tick(&TickFacts {
        counted: false,
        ..facts(4, 0.0, State::Done)
    }));
    assert_eq!(r.ticks, 4);
    assert_eq!((r.instr_min, r.instr_max, r.instr_n), (1000, 1003, 4));
    assert_eq!(r.instr_mean(), 1001.5);
    assert_eq!(r.sum_sq, 1.0);
    assert_eq!(r.peak_ref_mm, 2.0);
    assert_eq!(r.ramp_ticks, 3);
    assert!((r.max_step_mm - 0.2).abs() < 1e-12);
    assert!((r.max_ramp_step_mm - 0.2).abs() < 1e-12);
    assert_eq!(r.peak_cmd_mm, 0.3);
    assert_eq!(nrmse_pct(&r, 4), Some(100.0 * 0.5 / 2.0));
    assert_eq!(nrmse_pct(&r, 5), None);
    assert!(as_expected(
        &r,
        State::Done,
        &Limits::paper_actuator(),
        4,
        false
    ));
}

#[test]
fn fault_statistics_and_settling() {
    let f = State::Fault(FaultReason::NonFiniteSample);
    let mut r = Run::new();
    r.after_tick(&facts(0, 1.0, State::Running));
    assert!(r.after_tick(&facts(1, 0.9, f)), "the first fault notifies");
    assert_eq!(r.fault_tick, Some(1));
    assert_eq!(r.cmd_before_fault_mm, 1.0);
    r.after_tick(&facts(2, 0.0, f));
    let mut notified = 0;
    for k in 3..3 + FAULT_SETTLE_TICKS + 5 {
        notified += u32::from(r.after_tick(&facts(k, 0.0, f)));
    }
    assert_eq!(notified, 1, "settled once");
    assert!(r.fault_settled());
    assert_eq!(r.fault_ramp_ticks, 2);
    assert_eq!(nrmse_pct(&r, r.ticks), None, "no NRMSE after a fault");
    let mut r2 = r;
    r2.telemetry_dropped = 3;
    r2.restart();
    assert_eq!(r2.ticks, 0);
    assert_eq!(r2.telemetry_dropped, 0);
    assert_eq!(r2.last_cmd_mm, 0.0);
}

#[test]
fn result_line_is_json_with_every_field() {
    let lim = Limits::paper_actuator();
    let f = State::Fault(FaultReason::Overrun);
    let mut r = Run::new();
    r.after_tick(&facts(0, 0.5, State::Running));
    r.after_tick(&facts(1, 0.25, f));
    let mut s = String::new();
    write_result(&mut s, &r, f, &info(lim)).unwrap();
    let json = s.strip_prefix("RESULT ").unwrap();
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    assert_eq!(v["scenario"], "rnn-online-10");
    assert_eq!(v["ticks"], 2);
    assert!(v["nrmse_pct"].is_null());
    assert_eq!(v["faults"], 1);
    assert_eq!(v["instr_per_tick"]["min"], 1000);
    assert_eq!(v["instr_per_tick"]["mean"], 1000.5);
    assert_eq!(v["end_state"], "fault");
    assert_eq!(v["fault_reason"], "Overrun");
    assert_eq!(v["fault_tick"], 1);
    assert_eq!(v["cmd_before_fault_mm"], 0.5);
    assert_eq!(v["fault"], "nan@10s");
    assert_eq!(v["stack_bytes"], 100);
    assert_eq!(v["daq_errors"], 1);
    assert_eq!(v["held_samples"], 2);
    assert_eq!(v["step_limits_mm"]["fault"], lim.fault_step_mm());
    assert_eq!(v["step_limits_mm"]["end"], 10.0 * DT_S);
    assert_eq!(v["final_cmd_mm"], 0.25);
    // The counted ticks' commands, FNV-1a of their bits, as a host run computes it.
    let mut fnv = rths_core::checksum::Fnv1a64::new();
    fnv.write_f64(0.5);
    fnv.write_f64(0.25);
    assert_eq!(v["command_fnv"], std::format!("{:016x}", fnv.finish()));

    // A completed run: the NRMSE in full precision, no fault fields.
    let mut r = Run::new();
    for k in 0..4 {
        r.after_tick(&facts(k, 0.0, State::Done));
    }
    let mut s = String::new();
    let plain = ReportInfo {
        scenario: "lr-online",
        scenario_suffix: None,
        fault_spec: None,
        ..info(lim)
    };
    write_result(&mut s, &r, State::Done, &plain).unwrap();
    let v: serde_json::Value = serde_json::from_str(s.strip_prefix("RESULT ").unwrap()).unwrap();
    assert_eq!(v["scenario"], "lr-online");
    assert_eq!(v["nrmse_pct"], 25.0);
    assert!(v.get("fault_reason").is_none());
    assert!(v.get("fault").is_none());
}
