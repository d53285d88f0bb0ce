//! Tests of [`crate::site`]: the site's requests through `link::handle`, the lock-step wait and
//! the step ends.

use crate::link::{handle, Effect, Rearm, Session};
use crate::record::RecordStore;
use crate::site::{step_ended, step_message, waits, StepEnd};
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
