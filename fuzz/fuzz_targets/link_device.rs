//! Arbitrary bytes on the device's link: frames are decoded (or counted bad) and every request is
//! handled against a controller and a record store, as the firmware's `link_rx` does. Never a
//! panic; the record in force changes only on an acknowledged `RecordCommit`, the model checksum
//! only on an acknowledged `UploadLr` or `ModelCommit`, the rig compensation only on an
//! acknowledged `UploadRig`, `RigCommit` or `ModelCommit`, and the device answers every request
//! once. The first byte picks the build (LR, LRX, RNN-2 or FE + ATS, and how it rearms; bit 4: a
//! structure part, a 1-mode modal-hysteretic model), so the chunked RNN upload, every rig layout
//! and the chunked rig upload are reached.
//! An `Identify` (the session has the excitation's tables) is acknowledged only from rest, and
//! then leaves the supervisor running and the stream an identification's.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths_app::identify::FlashTables;
use rths_app::link::{handle, Effect, Rearm, Session};
use rths_app::record::RecordStore;
use rths_app::tick_cost::TickBudget;
use rths_app::Run;
use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::control::{ModalSpec, StoryLawSpec};
use rths_core::metamodel::{ModalMode, RnnScaling, RnnWeights};
use rths_core::model::{assemble, ModelSpec};
use rths_core::params::{Prototype, SpecimenScale, CONTROLLER_RATE_HZ, DT_S};
use rths_core::supervisor::Limits;
use rths_link::{DeviceMsg, FrameReader, HostMsg, ModelKind, Request, MAX_FRAME, MODEL_MAX_VALUES};

const COMPILED: [f64; 4] = [0.0, 0.01, -0.02, 0.0];
const THETA: [f64; 6] = [0.0, 0.5, 0.1, 0.0, 0.0, 0.0];
const COEFFS: [f64; 9] = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.9, -0.9, 0.0];
const LEAD: [f64; 8] = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
const W4: [f64; 4] = [0.1, -0.2, 0.3, 0.05];

/// The build's analytical part (a 2-unit RNN: its upload is 15 values, two chunks).
fn spec(kind: ModelKind) -> ModelSpec<'static> {
    match kind {
        ModelKind::Lr => ModelSpec::Lr { theta: &THETA },
        ModelKind::Lrx => ModelSpec::Lrx {
            coeffs: &COEFFS,
            k_corr_kn_per_mm: 12.0,
            k_adapt_ticks: 0.0,
            lead_weights: &LEAD,
            lead_stride: 2,
            lead_adapt_ticks: 0.0,
            specimen_dynamics: [0.0; 2],
        },
        ModelKind::Rnn => ModelSpec::Rnn {
            weights: RnnWeights {
                w_ih: &W4,
                w_hh: &W4,
                b_h: &[0.0, 0.1],
                w_ho: &[1.0, -1.0],
                b_o: 0.0,
            },
            scaling: RnnScaling {
                input_mean: [0.0; 2],
                input_std: [1.0; 2],
                output_mean: 0.0,
                output_std: 1.0,
            },
        },
        ModelKind::FeAts => ModelSpec::FeAts {
            expected_delay_s: 28.0 * DT_S,
        },
        _ => ModelSpec::StructureModal {
            model: ModalSpec {
                modes: &[ModalMode {
                    omega_rad_s: 20.0,
                    damping_ratio: 0.02,
                    ground_participation: 1.0,
                }],
                shape: &[0.7],
                specimen_dof: 0,
                specimen_k_kn_per_mm: 50.0,
                laws: &[StoryLawSpec {
                    k0_kn_per_mm: 40.0,
                    yield_force_kn: 20.0,
                    post_yield_ratio: 0.05,
                    bouc_wen: None,
                }],
                drift: &[0.7],
            },
        },
    }
}

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
    // The first byte picks the build's kind and how it rearms: 0-3 as the seeds were written (LR,
    // LR, LRX, LRX; even: once per power-up, odd: at the measured position), 4-7 the RNN and FE +
    // ATS builds.
    let first = data.first().copied().unwrap_or(0) % 8;
    let kind = match first / 2 {
        _ if data.first().copied().unwrap_or(0) & 16 != 0 => ModelKind::StructureModal,
        0 => ModelKind::Lr,
        1 => ModelKind::Lrx,
        2 => ModelKind::Rnn,
        _ => ModelKind::FeAts,
    };
    let rearm = if first % 2 == 0 {
        Rearm::OncePerPowerUp
    } else {
        Rearm::AtMeasured
    };
    let Ok((analytical, compensator)) = assemble(&spec(kind), Prototype::paper(), DT_S) else {
        return;
    };
    let mut ctl = Controller::new(cfg, analytical, compensator);
    let mut run = Run::new();
    // Bit 3 of the first byte picks the core whose tick budget the commit checks.
    let tick_budget = if data.first().copied().unwrap_or(0) & 8 == 0 {
        TickBudget::cortex_m4_168mhz(CONTROLLER_RATE_HZ)
    } else {
        TickBudget::cortex_m7_480mhz(CONTROLLER_RATE_HZ)
    };
    let mut staging = [0.0f64; MODEL_MAX_VALUES];
    let mut s =
        Session::new(0x1234_5678, tick_budget, rearm, kind, &mut staging).with_excitation(tables());
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
        let rig0 = rths_app::rig_upload::rig_checksum_of(&ctl);
        let (answer, effect) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, false);
        let req = msg.request();
        match answer {
            DeviceMsg::Ack(r) | DeviceMsg::Nack(r, _) => assert_eq!(r, req),
            DeviceMsg::Status(_) => assert_eq!(req, Request::Status),
            DeviceMsg::Holdings(h) => {
                assert_eq!(req, Request::Holdings);
                assert_eq!(h.model_checksum, s.model_checksum);
            }
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
        if !(acked
            && matches!(
                req,
                Request::UploadRig | Request::RigCommit | Request::ModelCommit
            ))
        {
            assert_eq!(
                rths_app::rig_upload::rig_checksum_of(&ctl),
                rig0,
                "{req:?} changed the rig compensation"
            );
        }
        for k in 0..store.ticks().min(64) {
            assert!(store.accel_mm_s2(k).is_finite());
        }
    }
});
