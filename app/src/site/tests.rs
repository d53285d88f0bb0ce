//! Tests of [`crate::site`]: the site's requests through `link::handle`, the lock-step wait and
//! the step ends.

extern crate std;
use std::vec::Vec;

use crate::link::{handle, Effect, Rearm, Session};
use crate::record::RecordStore;
use crate::site::{step_ended, step_message, waits, Outbox, Outgoing, StepEnd, HOLD_RECORDS};
use crate::tick_cost::TickBudget;
use crate::{Run, TelemetryRecord};
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::hal::Sample;
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::{Limits, State};
use rths_link::{DeviceMsg, HostMsg, ModelKind, NackReason, Request};

fn controller() -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let lr = LrParams::new([0.0; 6]).unwrap();
    Controller::new(cfg, Analytical::Lr(Lr::new(lr)), Compensator::None)
}

fn begin(ticks_per_step: u32, stride: u16) -> HostMsg {
    HostMsg::SiteBegin {
        ticks_per_step,
        lead_weights: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        lead_stride: stride,
    }
}

#[test]
fn a_site_takes_its_targets_in_order_and_reports_each_step_end() {
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = Session::new(
        0,
        TickBudget::cortex_m4_168mhz(2048.0),
        Rearm::OncePerPowerUp,
        ModelKind::Lr,
        &mut [],
    );
    let mut st = RecordStore::new(&[0.0, 0.1, 0.0], 0.01, 41, &mut []);
    let mut h = |m, ctl: &mut Controller, s: &mut Session<'_>, finished| {
        handle(m, ctl, &mut run, &mut st, s, finished)
    };
    // Not a site yet.
    let t = HostMsg::SiteTarget {
        step: 0,
        target_mm: 1.0,
    };
    assert_eq!(
        h(t, &mut ctl, &mut s, false).0,
        DeviceMsg::Nack(Request::SiteTarget, NackReason::InvalidState)
    );
    for (m, why) in [
        (begin(0, 6), NackReason::OutOfRange),
        (begin(4, 9), NackReason::OutOfRange),
        (
            HostMsg::SiteBegin {
                ticks_per_step: 4,
                lead_weights: [f64::NAN; 8],
                lead_stride: 6,
            },
            NackReason::NotFinite,
        ),
    ] {
        assert_eq!(
            h(m, &mut ctl, &mut s, false).0,
            DeviceMsg::Nack(Request::SiteBegin, why)
        );
    }
    // The emulated plant has run: once per power-up.
    assert_eq!(
        h(begin(4, 6), &mut ctl, &mut s, true).0,
        DeviceMsg::Nack(Request::SiteBegin, NackReason::Unsupported)
    );
    assert_eq!(
        h(begin(4, 6), &mut ctl, &mut s, false),
        (DeviceMsg::Ack(Request::SiteBegin), Effect::Started)
    );
    assert_eq!(ctl.supervisor().state(), State::Running);
    assert!(waits(&ctl), "no target yet: the emulated plant waits");
    // Under a test a second begin is refused.
    assert_eq!(
        h(begin(4, 6), &mut ctl, &mut s, false).0,
        DeviceMsg::Nack(Request::SiteBegin, NackReason::Busy)
    );
    let target = |step, target_mm| HostMsg::SiteTarget { step, target_mm };
    assert_eq!(
        h(target(1, 1.0), &mut ctl, &mut s, false).0,
        DeviceMsg::Nack(Request::SiteTarget, NackReason::Sequence)
    );
    assert_eq!(
        h(target(0, f64::NAN), &mut ctl, &mut s, false).0,
        DeviceMsg::Nack(Request::SiteTarget, NackReason::NotFinite)
    );
    let mut seen = 0;
    let mut k = 0u32;
    for step in 0..3u32 {
        let d = 0.1 * f64::from(step + 1);
        assert_eq!(
            h(target(step, d), &mut ctl, &mut s, false).0,
            DeviceMsg::Ack(Request::SiteTarget)
        );
        assert!(!waits(&ctl));
        assert_eq!(
            h(target(step + 1, d), &mut ctl, &mut s, false).0,
            DeviceMsg::Nack(Request::SiteTarget, NackReason::Busy),
            "one target per step"
        );
        let mut ended = None;
        for _ in 0..4 {
            let out = ctl.tick(0.0, Ok(Sample::default()), false);
            assert_eq!(out.state, State::Running);
            if let Some(e) = step_ended(&ctl, k, &mut seen) {
                assert!(ended.is_none());
                ended = Some((e, out.target_mm));
            }
            k += 1;
        }
        let (e, t) = ended.expect("the step ends after its 4 ticks");
        assert_eq!(e, StepEnd { step, tick: k - 1 });
        assert_eq!(t, d, "the step ends on its target");
        assert!(waits(&ctl));
        let r = TelemetryRecord {
            tick: e.tick,
            command_mm: 0.0,
            target_mm: t,
            measured_mm: 0.25,
            force_kn: -1.5,
            state: State::Running,
        };
        assert_eq!(
            step_message(e, &r),
            DeviceMsg::SiteStep {
                step,
                tick: k - 1,
                measured_mm: 0.25,
                force_kn: -1.5
            }
        );
    }
    // The end: the supervisor's end ramp.
    assert_eq!(
        h(HostMsg::SiteEnd { fault: false }, &mut ctl, &mut s, false).0,
        DeviceMsg::Ack(Request::SiteEnd)
    );
    assert_eq!(ctl.supervisor().state(), State::RampDown);
}

#[test]
fn a_faulted_end_trips_the_supervisor() {
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = Session::new(
        0,
        TickBudget::cortex_m4_168mhz(2048.0),
        Rearm::AtMeasured,
        ModelKind::Lr,
        &mut [],
    );
    let mut st = RecordStore::new(&[0.0, 0.1, 0.0], 0.01, 41, &mut []);
    assert_eq!(
        handle(
            HostMsg::SiteEnd { fault: true },
            &mut ctl,
            &mut run,
            &mut st,
            &mut s,
            false
        )
        .0,
        DeviceMsg::Nack(Request::SiteEnd, NackReason::InvalidState)
    );
    handle(begin(2, 0), &mut ctl, &mut run, &mut st, &mut s, false);
    assert_eq!(s.link_loss, rths_link::LinkLoss::RampDown, "a real rig");
    handle(
        HostMsg::SiteEnd { fault: true },
        &mut ctl,
        &mut run,
        &mut st,
        &mut s,
        false,
    );
    assert!(matches!(ctl.supervisor().state(), State::Fault(_)));
}

fn record(tick: u32, state: State) -> TelemetryRecord {
    TelemetryRecord {
        tick,
        command_mm: f64::from(tick),
        target_mm: 0.0,
        measured_mm: 0.5 * f64::from(tick),
        force_kn: -f64::from(tick),
        state,
    }
}

/// Everything the outbox hands out now, the step ends of `ends` taken off as they go.
fn drain(o: &mut Outbox, ends: &mut Vec<StepEnd>, open: bool, flush: bool) -> Vec<Outgoing> {
    let mut out = Vec::new();
    while let Some(x) = o.next(ends.first().copied(), open, flush) {
        if let Outgoing::StepEnd(_) = x {
            ends.remove(0);
        }
        out.push(x);
    }
    out
}

#[test]
fn a_steps_end_goes_out_before_its_records_and_a_fault_after_them() {
    let mut o = Outbox::new();
    let mut ends = Vec::new();
    // A step of 4 ticks under way: its records wait.
    for k in 0..3 {
        o.push(record(k, State::Running)).unwrap();
        assert!(drain(&mut o, &mut ends, true, false).is_empty());
    }
    o.push(record(3, State::Running)).unwrap();
    ends.push(StepEnd { step: 0, tick: 3 });
    let out = drain(&mut o, &mut ends, false, false);
    assert_eq!(
        out[0],
        Outgoing::StepEnd(DeviceMsg::SiteStep {
            step: 0,
            tick: 3,
            measured_mm: 1.5,
            force_kn: -3.0
        }),
        "the step's end first, with its last tick's reading"
    );
    let ticks: Vec<u32> = out[1..]
        .iter()
        .map(|x| match x {
            Outgoing::Record(r) => r.tick,
            Outgoing::StepEnd(_) => u32::MAX,
        })
        .collect();
    assert_eq!(ticks, [0, 1, 2, 3], "then every record, in order");
    assert!(o.is_empty() && ends.is_empty());

    // A fault within the next step: its records go out as they come, the step's end after them.
    o.push(record(4, State::Running)).unwrap();
    assert!(drain(&mut o, &mut ends, true, false).is_empty());
    o.push(record(
        5,
        State::Fault(rths_core::supervisor::FaultReason::CommandVelocity),
    ))
    .unwrap();
    ends.push(StepEnd { step: 1, tick: 5 });
    let out = drain(&mut o, &mut ends, false, false);
    assert!(matches!(out[0], Outgoing::Record(r) if r.tick == 4));
    assert!(matches!(out[1], Outgoing::Record(r) if r.tick == 5));
    assert!(matches!(
        out[2],
        Outgoing::StepEnd(DeviceMsg::SiteStep {
            step: 1,
            tick: 5,
            ..
        })
    ));
    assert_eq!(out.len(), 3);
}

#[test]
fn a_long_step_sends_beyond_the_hold_and_a_lost_record_ends_its_step_unread() {
    let mut o = Outbox::new();
    let mut ends = Vec::new();
    let mut sent = Vec::new();
    // A step of 100 ticks: never more than HOLD_RECORDS wait.
    for k in 0..100 {
        o.push(record(k, State::Running)).unwrap();
        sent.extend(drain(&mut o, &mut ends, true, false));
        assert!(o.len() <= HOLD_RECORDS);
    }
    assert_eq!(sent.len(), 100 - HOLD_RECORDS + 1);
    // Its end: first, with the reading of tick 99, still held.
    ends.push(StepEnd { step: 0, tick: 99 });
    let out = drain(&mut o, &mut ends, false, false);
    assert!(matches!(
        out[0],
        Outgoing::StepEnd(DeviceMsg::SiteStep { tick: 99, force_kn, .. }) if force_kn == -99.0
    ));
    // A step end whose record the telemetry queue dropped (a later record came): no reading.
    o.push(record(101, State::Running)).unwrap();
    ends.push(StepEnd { step: 1, tick: 100 });
    let out = drain(&mut o, &mut ends, false, false);
    assert!(matches!(
        out[0],
        Outgoing::StepEnd(DeviceMsg::SiteStep { tick: 100, measured_mm, .. }) if measured_mm.is_nan()
    ));
    // A step end whose record is still in the queue: wait for it (or, at the run's end, go
    // unread).
    ends.push(StepEnd { step: 2, tick: 102 });
    assert!(drain(&mut o, &mut ends, false, false).is_empty());
    assert_eq!(ends.len(), 1);
    let out = drain(&mut o, &mut ends, false, true);
    assert!(matches!(
        out[0],
        Outgoing::StepEnd(DeviceMsg::SiteStep { tick: 102, .. })
    ));
    // Outside a site's step, records go out as they come.
    o.push(record(103, State::Running)).unwrap();
    assert_eq!(drain(&mut o, &mut ends, false, false).len(), 1);
}
