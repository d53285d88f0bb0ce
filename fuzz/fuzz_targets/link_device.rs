//! Arbitrary bytes on the device's link: frames are decoded (or counted bad) and every request is
//! handled against a controller and a record store, as the firmware's `link_rx` does. Never a
//! panic; the record in force changes only on an acknowledged `RecordCommit`, the model checksum
//! only on an acknowledged `UploadLr` or `ModelCommit`, and the device answers every request once.
//! An `Identify` (the session has the excitation's tables) is acknowledged only from rest, and
//! then leaves the supervisor running and the stream an identification's.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths_app::identify::FlashTables;
use rths_app::link::{handle, Effect, Rearm, Session};
use rths_app::record::RecordStore;
use rths_app::Run;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;
use rths_link::{DeviceMsg, FrameReader, HostMsg, ModelKind, Request, MAX_FRAME};

const COMPILED: [f64; 4] = [0.0, 0.01, -0.02, 0.0];

/// The default excitation's tables, as the firmware's build script writes them (once per process).
fn tables() -> FlashTables {
    use rths_core::identify_excitation::{ExcitationConfig, StdTables};
    static T: std::sync::OnceLock<FlashTables> = std::sync::OnceLock::new();
    *T.get_or_init(|| {
        let leak = |v: &[f64]| -> &'static [u8] {
            Box::leak(
                v.iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect::<Vec<u8>>()
                    .into_boxed_slice(),
            )
        };
        match StdTables::new(&ExcitationConfig::new(rths_core::params::DT_S)) {
            Ok(t) => FlashTables::new(
                leak(&t.unit),
                leak(&t.ramp_cos),
                t.stats.peak,
                t.stats.peak_rate_per_s,
            ),
            Err(_) => FlashTables::new(&[], &[], 0.0, 0.0),
        }
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(cfg) = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    ) else {
        return;
    };
    let Ok(lr) = LrParams::new([0.0, 0.5, 0.1, 0.0, 0.0, 0.0]) else {
        return;
    };
    let mut ctl = Controller::new(cfg, Analytical::Lr(Lr::new(lr)), Compensator::None);
    let mut run = Run::new();
    // The first byte picks the build's kind (LR or LRX) and how it rearms.
    let (kind, rearm) = match data.first().copied().unwrap_or(0) % 4 {
        0 => (ModelKind::Lr, Rearm::OncePerPowerUp),
        1 => (ModelKind::Lr, Rearm::AtMeasured),
        2 => (ModelKind::Lrx, Rearm::OncePerPowerUp),
        _ => (ModelKind::Lrx, Rearm::AtMeasured),
    };
    let mut s = Session::new(0x1234_5678, true, rearm, kind).with_excitation(tables());
    let mut buf = [0.0f64; 64];
    let mut store = RecordStore::new(&COMPILED, 0.01, 31, &mut buf);
    let mut reader = FrameReader::<MAX_FRAME>::new();
    for &b in data.iter().skip(1) {
        let msg = match reader.push::<HostMsg>(b) {
            None => continue,
            Some(Err(_)) => {
                s.bad_frames = s.bad_frames.saturating_add(1);
                continue;
            }
            Some(Ok(m)) => m,
        };
        let (record0, model0) = (store.info(), s.model_checksum);
        let at_rest = ctl.supervisor().at_rest();
        let (answer, effect) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, false);
        let req = msg.request();
        match answer {
            DeviceMsg::Ack(r) | DeviceMsg::Nack(r, _) => assert_eq!(r, req),
            DeviceMsg::Status(_) => assert_eq!(req, Request::Status),
            other => panic!("{other:?} answers {req:?}"),
        }
        let acked = matches!(answer, DeviceMsg::Ack(_));
        if !(acked && req == Request::RecordCommit) {
            assert_eq!(store.info(), record0, "{req:?} changed the record");
        }
        if !(acked && matches!(req, Request::UploadLr | Request::ModelCommit)) {
            assert_eq!(s.model_checksum, model0, "{req:?} changed the model");
        }
        if acked && req == Request::Identify {
            assert!(at_rest, "an identification started under a test");
            assert!(matches!(effect, Effect::Identify(_)));
            assert!(s.identifying);
            assert_eq!(
                ctl.supervisor().state(),
                rths_core::supervisor::State::Running
            );
        } else {
            assert!(!matches!(effect, Effect::Identify(_)));
        }
        for k in 0..store.ticks().min(64) {
            assert!(store.accel_mm_s2(k).is_finite());
        }
    }
});
